"""The report's whole-robot section (apps/paper/robot_placement.py)."""

from __future__ import annotations

import sys

import pytest

pytest.importorskip("pinocchio")


def test_robot_section_claims_are_the_placement_ratios(tmp_path):
    # oracle: the section's ratio per configuration is the largest central latency with
    # damping embedded over that with damping central, recomputed here from the public API
    # (sc.robot(...).placement) with the section's stated settings; and the largest
    # latency is a real boundary: the certified verdict at 0.999x / 1.001x of it
    import seactl as sc
    from seactl.apps import report
    from seactl.apps.paper import robot_placement as rp

    sec = rp.robot_placement(report.Context(tmp_path))
    claims = {c.id: c for c in sec.claims}
    q = rp.CONFIGURATIONS[0]
    r = sc.robot(rp._arm(), space="task", task="tool", q0=q, fn_hz=rp.FN_HZ,
                 filters_hz=rp.FILTERS_HZ)
    p = r.placement(central_ms=rp.CENTRAL_MS, embedded_ms=rp.EMBEDDED_MS)
    emb = p.option(stiffness="central", damping="embedded")
    cen = p.option(stiffness="central", damping="central")
    ratio = emb.max_central_latency_s / cen.max_central_latency_s
    assert claims["robot.damping_embedded.q1"].our_value == pytest.approx(ratio, abs=1e-3)
    t = cen.max_central_latency_s
    for factor, stable in ((0.999, True), (1.001, False)):
        ms = 1e3 * t * factor
        r2 = sc.robot(rp._arm(), space="task", task="tool", q0=q, fn_hz=rp.FN_HZ,
                      filters_hz=rp.FILTERS_HZ,
                      delays_ms={"stiffness": ms, "damping": ms, "torque": rp.EMBEDDED_MS})
        assert bool(r2.margins().stable) is stable
    assert all(c.status == "info" for c in sec.claims)
    held = [claims[rp._claim_id(i)].note.startswith("holds")
            for i in range(len(rp.CONFIGURATIONS))]
    assert claims["robot.damping_embedded.all"].our_value == ("yes" if all(held) else "no")


def test_robot_section_without_pinocchio_is_not_computed(tmp_path, monkeypatch):
    # oracle: pinocchio made unimportable; every claim id kept, none computed ("skip")
    from seactl.apps import report
    from seactl.apps.paper import robot_placement as rp

    monkeypatch.setitem(sys.modules, "pinocchio", None)
    sec = rp.robot_placement(report.Context(tmp_path))
    assert len(sec.claims) == len(rp.CONFIGURATIONS) + 1
    assert all(c.status == "skip" and c.our_value is None for c in sec.claims)
    assert "robots" in sec.intro
