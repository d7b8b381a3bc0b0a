"""A run's measured latency against the design's margins (seactl.latency.runcheck,
seactl.api.runcheck) and the report section "From analysis to a physics engine".

Oracles: latencies and margins typed here (the verdict's conditions by hand); the system's
own ``jitter_margins()`` (continuous and sampled) and ``delay_margin()`` for the same
design; the rightmost characteristic root (``System.roots()``) on either side of the
delay limit; the latency injected into the run; MuJoCo absent (``sys.modules``).
"""

from __future__ import annotations

import json
import re
import sys

import numpy as np
import pytest

import seactl as sc
from seactl.latency.runcheck import WITHIN, loop_latency_check

DELAYS_MS = {"torque": 1.0, "stiffness": 2.0, "damping": 1.0}


def _design(**delays_ms):
    return sc.design(14, delays_ms=DELAYS_MS | delays_ms, filters_hz=(50, 100))


def test_loop_check_conditions_by_hand():
    # oracle: the conditions worked by hand on five latencies (2, 2, 3, 4, 7 ms): spread
    # 5 ms; mean 3.6 ms
    lat = np.array([2, 2, 3, 4, 7]) * 1e-3
    ok = loop_latency_check(lat, design_delay_s=2e-3, jitter_margin_s=6e-3,
                            delay_limit_s=8e-3, sampled_jitter_margin_s=5e-3,
                            sampled_rate_hz=1000.0)
    assert ok["verdict"] == WITHIN and ok["within"]
    assert ok["spread_ms"] == pytest.approx(5.0) and ok["mean_ms"] == pytest.approx(3.6)
    assert ok["min_ms"] == pytest.approx(2.0) and ok["max_ms"] == pytest.approx(7.0)
    c = loop_latency_check(lat, design_delay_s=2e-3, jitter_margin_s=6e-3,
                           delay_limit_s=8e-3, sampled_jitter_margin_s=4e-3,
                           sampled_rate_hz=1000.0)
    assert c["verdict"] == "outside: spread 5 ms > sampled jitter margin at 1000 Hz 4 ms"
    c = loop_latency_check(lat, design_delay_s=2e-3, jitter_margin_s=4.5e-3,
                           delay_limit_s=7e-3)
    assert c["verdict"] == ("outside: spread 5 ms > jitter margin 4.5 ms; max latency 7 ms "
                            ">= delay limit 7 ms") and not c["within"]
    inf = loop_latency_check(lat, design_delay_s=2e-3, jitter_margin_s=6e-3,
                             delay_limit_s=np.inf)
    assert inf["delay_limit_ms"] is None and inf["within"]


@pytest.fixture(scope="module")
def lockstep():
    d = _design()
    return d, d.run(duration_s=0.3, transport="udp",
                    rates_hz={"embedded": 1000.0, "high-level": 500.0})


def test_run_check_uses_the_designs_margins(lockstep):
    # oracle: the same design's jitter_margins() (continuous, and sampled at the
    # high-level process's 500 Hz) and delay_margin along the stiffness delay; the delay
    # limit checked by the rightmost root just below and above it
    d, res = lockstep
    c = res.summary["latency_check"]["stiffness"]
    assert set(res.summary["latency_check"]) == {"stiffness"}   # the loop across the link
    assert c["jitter_margin_ms"] == pytest.approx(
        1e3 * float(d.jitter_margins().stiffness_jitter_margin_s), rel=1e-12)
    assert c["sampled_rate_hz"] == 500.0
    assert c["sampled_jitter_margin_ms"] == pytest.approx(
        1e3 * float(d.jitter_margins(rate_hz=500.0).stiffness_jitter_margin_s), rel=1e-12)
    limit = c["delay_limit_ms"]
    assert c["design_delay_ms"] == 2.0 and limit > 2.0
    for x, stable in ((0.99, True), (1.01, False)):
        sigma = float(_design(stiffness=x * limit).roots().spectral_abscissa)
        assert (sigma < 0) == stable, (x, sigma)
    # the measured latency is the run's own: the age of the stiffness message in use
    lat_ms = 1e3 * res.latency_s["stiffness"]
    assert c["max_ms"] == pytest.approx(lat_ms.max()) and c["min_ms"] == pytest.approx(
        lat_ms.min())
    assert c["spread_ms"] == pytest.approx(lat_ms.max() - lat_ms.min())
    assert c["verdict"] == WITHIN
    assert json.dumps(res.summary)   # JSON-ready


def test_injected_latency_beyond_the_margin_is_outside(capsys):
    # oracle: 20 ms injected on the high-level -> embedded link; the loop's delay limit
    # (the API's delay_margin along the stiffness delay of the same design, 18 ms) is
    # below 20 ms + the design's 2 ms: the check must fail on the delay limit
    from seactl.apps.cli import main

    assert main(["run", "--fn", "14", "--t-tau", "1", "--t-qs", "2", "--t-qd", "1",
                 "--f-qd", "50", "--f-taud", "100", "--transport", "udp", "--duration",
                 "0.3", "--extra-latency", "20", "--json"]) in (0, None)
    c = json.loads(capsys.readouterr().out)["latency_check"]["stiffness"]
    dm = _design().delay_margin({"stiffness": 1}).records()[0]["delay_margin_s"]
    assert c["delay_limit_ms"] == pytest.approx(2.0 + 1e3 * dm, rel=1e-12)
    assert c["max_ms"] >= 22.0 > c["delay_limit_ms"]
    assert not c["within"] and c["verdict"].startswith("outside: ")
    assert "delay limit" in c["verdict"]


# ----------------------------------------------------------------------------- report
def test_physics_section_renders(tmp_path, capsys):
    # oracle: the delay margin's meaning (0.8 x: the step's error decays, 1.2 x: grows)
    # and the band's construction (a distribution covering the design's 2 ms holds the
    # MuJoCo step, one from 4 to 6 ms does not)
    pytest.importorskip("mujoco")
    from seactl.apps.cli import main

    out = tmp_path / "rep"
    assert main(["reproduce", "--out", str(out), "--only", "physics-engine",
                 "--jobs", "1"]) == 0
    by_id = {c["id"]: c for c in json.loads((out / "claims.json").read_text())}
    assert by_id["physics.margin_below"]["our_value"] < 0
    assert by_id["physics.margin_above"]["our_value"] > 0
    assert by_id["physics.band_inside"]["our_value"] is True
    assert by_id["physics.band_outside"]["our_value"] is False
    assert all(by_id[k]["status"] == "info" for k in by_id)
    assert (out / "figures" / "physics_engine.png").stat().st_size > 1000
    assert "From analysis to a physics engine" in (out / "index.html").read_text()


def test_physics_section_without_mujoco(tmp_path, monkeypatch, capsys):
    # oracle: MuJoCo made unimportable; the section says how to install it and keeps its
    # claim ids, none computed; the report counts them apart from the claims checked
    # (its 4 claims: physics.CLAIMS), in the printed summary and on the page
    from seactl.apps import report
    from seactl.apps.paper import physics

    monkeypatch.setitem(sys.modules, "mujoco", None)
    sec = physics.physics_engine(report.Context(tmp_path))
    assert [c.id for c in sec.claims] == list(physics.CLAIMS)
    assert all(c.status == "skip" and c.our_value is None for c in sec.claims)
    assert "pip install '.[sim]'" in sec.intro and not sec.figures
    from seactl.apps.cli import main

    out = tmp_path / "rep"
    capsys.readouterr()
    assert main(["reproduce", "--out", str(out), "--only", "physics-engine",
                 "--jobs", "1"]) == 0
    claims = json.loads((out / "claims.json").read_text())
    assert [c["id"] for c in claims] == list(physics.CLAIMS)
    n = len(physics.CLAIMS)
    line = (f"0 claims of the paper checked: 0 reproduced, 0 do not hold as printed "
            f"(reasons in the report), 0 findings; {n} not computed")
    assert line in " ".join(capsys.readouterr().out.split())
    html = (out / "index.html").read_text()
    assert "install" in html
    head = html[html.index('id="summary-line">'):].split("</p>")[0]
    text = " ".join(re.sub(r"<[^>]+>", "", head.split(">", 1)[1]).split())
    assert text == (f"0 claims of the paper checked: 0 reproduced, 0 do not hold as printed, "
                    f"0 findings; {n} not computed.")
