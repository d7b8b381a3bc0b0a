"""``seactl run --loop FILE`` goes through :meth:`seactl.UserLoop.run`, whose free-running
run judges the measured step against the band of the file's own reference and output.

The loop file is ``examples/loops/rigid.toml``: no SEA signal or loop name in it (its
reference is ``x_des``, its output ``x``, its delayed blocks ``K_fb`` and ``B_fb``).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.codegen.export import find_compiler

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")
LOOPS = Path(__file__).resolve().parents[1] / "examples" / "loops"
RIGID = LOOPS / "rigid.toml"


@needs_cc
def test_cli_prints_what_the_loops_run_computes(monkeypatch, capsys):
    # Oracle 1: the CLI's JSON is the summary UserLoop.run returned (spied), number for
    # number.  Oracle 2: with each loop's latency a constant equal to the file's delay
    # (1.5 ms on both processes), the band is one response, the sampled simulation with
    # the design's delays; the run's nominal_max_diff compares the measured step with
    # that same response computed separately (seactl.simulate.engine.simulate), so the
    # band's worst excess is nominal_max_diff less the tolerance (or 0 within it).
    runs = []
    original = sc.UserLoop.run

    def spy(self, **kw):
        res = original(self, **kw)
        runs.append(res)
        return res

    monkeypatch.setattr(sc.UserLoop, "run", spy)
    code = main(["run", "--loop", str(RIGID), "--realtime", "--duration", "0.3",
                 "--transport", "udp", "--latency", "K_fb=1.5", "--latency", "B_fb=1.5",
                 "--json"])
    assert code in (0, None)
    printed = json.loads(capsys.readouterr().out)
    assert len(runs) == 1
    api = json.loads(json.dumps(runs[0].summary))
    assert {k: v for k, v in printed.items() if k not in ("amplitude", "files")} == api
    assert printed["amplitude"] == 0.004                  # the file's reference_step [m]
    band = api["prediction_band"]
    assert set(band["latency"]) == {"K_fb", "B_fb"}       # the file's loops, not the SEA's
    assert band["runs"] == 1 and band["max_width"] == 0.0
    excess = max(0.0, api["nominal_max_diff"] - band["tolerance"])
    assert band["max_outside"] == pytest.approx(excess, rel=1e-9, abs=1e-12)
    assert band["within"] == (excess == 0.0)


@needs_cc
def test_a_loop_without_a_reference_says_the_band_is_not_computed(tmp_path):
    # Oracle: the file declares no [signals] reference, so there is no signal to step
    # in the band's simulations; the result says so instead of picking one.
    text = RIGID.read_text().replace('reference = "x_des"\n', "")
    assert 'reference = "x_des"' not in text
    path = tmp_path / "no-reference.toml"
    path.write_text(text)
    res = sc.load_loop(str(path)).run(duration_s=0.2, transport="udp", realtime=True)
    band = res.summary["prediction_band"]
    assert band["within"] is None
    assert band["verdict"] == "not computed: the loop file declares no [signals] reference"


def test_latency_without_realtime_is_refused():
    # Oracle: the error contract (the band exists only for a free-running run).
    with pytest.raises(sc.InputError, match="realtime"):
        sc.load_loop(str(RIGID)).run(duration_s=0.2, latency={"K_fb": "1.5"})
