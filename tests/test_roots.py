"""Rightmost roots with exact delays, and the one stability verdict.

Oracles: the block diagram's own transfers evaluated at a root (``1 + L = 0``, ``P_CL``
has a pole there), python-control's ``poles`` of the loop rebuilt with a cascade of Padé
sections per delay (``control.interconnect`` of the blocks, not the quasi-polynomial),
the growth rate of a time-domain simulation, the closed-form critically-damped target
polynomial, and the independent Nyquist scan of :mod:`seactl.analysis.margins`.
"""

import json

import control as ct
import numpy as np
import pytest

import seactl as sc
from seactl.analysis.roots import characteristic_roots
from seactl.apps.cli import main
from seactl.systems.rigid.model import RIGID_DIAGRAM, UT_LINEAR, RigidDesign
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import SEA_DIAGRAM, SEADesign, Timing, closed_loop, outer_loop
from seactl.systems.sea.views import sea_margins

# The counterexample: a PM of 18 degrees was reported "stable".
COUNTER = dict(fn=15.93, gs=1.867, ms={"torque": 1.99, "stiffness": 1.96, "damping": 18.54})


def counter_design():
    return sc.design(COUNTER["fn"], gs=COUNTER["gs"], delays_ms=COUNTER["ms"])


def test_counterexample_is_unstable_with_its_root_near_747_rad_s():
    d = counter_design()
    m = d.margins()
    assert not bool(m.stable) and int(m.unstable_poles) == 2
    z = complex(d.roots(count=3).roots[0])
    # the issue quotes 1.642 +- 747.0j for these rounded parameters; the exact root of
    # the rounded design is 1.190 +- 747.33j: check it on the diagram's own transfers
    assert z.real > 0 and z.imag == pytest.approx(747.0, abs=0.5)
    assert abs(1 + outer_loop()(d.sea, np.array([z]))[0]) < 1e-8
    assert abs(closed_loop()(d.sea, np.array([z]))[0]) > 1e7
    # both gain crossovers of the narrow resonance (118.6 / 124.1 Hz) are found
    found = np.sort(m.gain_crossovers.omega) / (2 * np.pi)
    assert np.any(np.abs(found - 118.7) < 0.2) and np.any(np.abs(found - 124.2) < 0.2)


def test_delay_free_roots_are_the_critically_damped_target():
    """Zero delays: the four roots are the target's quadruple root -w_n (perturbed by
    eps^(1/4) as any quadruple root is)."""
    fn = np.array([12.0, 20.0, 40.0])
    r = sc.design(fn).roots(count=2)
    w = 2 * np.pi * fn[:, None]
    np.testing.assert_allclose(r.roots.real / w, -1.0, atol=2e-3)
    np.testing.assert_allclose(r.spectral_abscissa, -2 * np.pi * fn, rtol=2e-3)


def _region(rng, n, kind, filters):
    if kind == "damping":   # long damping delay, GS 1.5-3, f_n 10-30 Hz
        fn, gs = rng.uniform(10, 30, n), rng.uniform(1.5, 3.0, n)
        ms = (rng.uniform(0, 3, n), rng.uniform(0, 5, n), rng.uniform(5, 25, n))
    else:                   # torque delay 15-30 ms, f_n 40-80 Hz
        fn, gs = rng.uniform(40, 80, n), rng.uniform(0.5, 2.0, n)
        ms = (rng.uniform(15, 30, n), rng.uniform(0, 5, n), rng.uniform(0, 5, n))
    f = (50.0, 100.0) if filters else (None, None)
    return SEADesign(UT_SEA, critically_damped_gains(UT_SEA, fn, gs=gs), Timing.from_ms(*ms, *f))


@pytest.mark.parametrize("filters", [False, True])
@pytest.mark.parametrize("kind", ["damping", "torque"])
def test_scan_and_roots_never_disagree_in_hard_regions(kind, filters):
    """Zero disagreement between the Nyquist scan's verdict and the roots' sign, and the
    same count of unstable roots wherever the listed roots reach into the left
    half-plane (so that every unstable root is listed)."""
    rng = np.random.default_rng({"damping": 11, "torque": 12}[kind] + 2 * filters)
    d = _region(rng, 12, kind, filters)
    m = sea_margins(d)
    r = characteristic_roots(SEA_DIAGRAM, d, count=12)
    assert r.converged.all()
    np.testing.assert_array_equal(m.stable, r.spectral_abscissa < 0)
    complete = np.nanmin(r.roots.real, axis=1) < 0
    assert complete.sum() >= 6
    np.testing.assert_array_equal(m.unstable_poles[complete], r.unstable_count[complete])


def test_long_torque_delay_counts_every_unstable_root():
    """f_n 70 Hz, T_tau 25 ms: once reported stable with PM -30 degrees."""
    d = sc.design(70.0, delays_ms={"torque": 25.0, "stiffness": 0.5, "damping": 0.5})
    m, r = d.margins(), d.roots(count=30)
    assert not bool(m.stable)
    assert int(m.unstable_poles) == int(r.unstable_count) >= 12


def _pade_cascade(T, sections, order=3):
    if T <= 0:
        return ct.ss(ct.tf([1.0], [1.0]))
    one = ct.ss(ct.tf(*ct.pade(T / sections, order)))
    out = one
    for _ in range(sections - 1):
        out = ct.series(out, one)
    return out


def pade_poles(diagram, design, sections=24):
    """Closed-loop poles of the diagram with every delay replaced by ``sections``
    third-order Padé sections: ``control.interconnect`` of the blocks and a summing
    junction per signal."""
    systems, feeders = [], {}
    for b in diagram.blocks:
        num, den = b.coefficients(design)
        g = ct.ss(ct.tf([float(c) for c in num], [float(c) for c in den]))
        if b.delay is not None:
            g = ct.series(_pade_cascade(float(getattr(design, b.delay)), sections), g)
        systems.append(ct.ss(g, inputs=b.src, outputs=f"{b.name}_out", name=b.name))
        feeders.setdefault(b.dst, []).append(f"{b.name}_out")
    for sig, outs in feeders.items():
        systems.append(ct.summing_junction(inputs=outs, output=sig, name=f"sum_{sig}"))
    inputs = [s for s in diagram.inputs]
    sysc = ct.interconnect(systems, inplist=inputs, outlist=[diagram.blocks[-1].dst],
                           inputs=inputs, outputs=["y"])
    return ct.poles(sysc)


@pytest.mark.parametrize("case", ["rigid", "sea"])
def test_roots_match_a_high_order_pade_cascade(case):
    if case == "rigid":
        diagram = RIGID_DIAGRAM
        design = RigidDesign.from_fn(UT_LINEAR, 12.0, T_s=1.5e-3, T_d=15.5e-3, f_v=50.0)
    else:  # python-control needs proper blocks: the derivatives filtered
        diagram = SEA_DIAGRAM
        design = sc.design(COUNTER["fn"], gs=COUNTER["gs"], delays_ms=COUNTER["ms"],
                           filters_hz=(150.0, 300.0)).sea
    ours = np.ravel(characteristic_roots(diagram, design, count=3).roots)
    poles = pade_poles(diagram, design)
    for z in ours:
        nearest = poles[np.argmin(np.abs(poles - z))]
        assert abs(nearest - z) < 1e-3 * abs(z), (z, nearest)
    # nothing to the right of our rightmost root among the Pade poles
    assert poles.real.max() == pytest.approx(ours[0].real, abs=1e-3 * abs(ours[0]))


def test_growth_rate_matches_a_simulation():
    """Delays on the simulator's 50 us grid (no rounding of the delay buffers)."""
    from seactl.systems.sea.views import sea_step

    d = sc.design(COUNTER["fn"], gs=COUNTER["gs"], delays_ms={"torque": 2.0, "stiffness": 2.0,
                                                              "damping": 18.5})
    sigma = float(d.roots(count=1).spectral_abscissa)
    r = sea_step(d.sea, t_end_s=2.2, dt=5e-5)
    y, t = np.ravel(r.position) - 1.0, r.t_s
    early = np.abs(y[(t >= 0.9) & (t < 1.1)]).max()
    late = np.abs(y[(t >= 1.9) & (t < 2.1)]).max()
    assert np.log(late / early) == pytest.approx(sigma, rel=0.03)
    assert sigma > 0 and not bool(d.margins().stable)


def test_rigid_roots_and_verdict_agree():
    """15 ms on the damping loop loses f_n = 8 and 12 Hz; on the stiffness loop it does
    not (the README's rigid-actuator finding)."""
    r = sc.rigid(np.array([8.0, 12.0])[:, None], delays_ms={"stiffness": np.array([1.0, 15.0]),
                                                            "damping": np.array([15.0, 1.0])})
    roots, m = r.roots(count=2), r.margins()
    np.testing.assert_array_equal(m.stable, roots.spectral_abscissa < 0)
    np.testing.assert_array_equal(m.stable, [[False, True], [False, True]])


def test_roots_cli_json(capsys):
    code = main(["roots", "--fn", "15.93", "14", "--gs", "1.867", "--t-tau", "1.99",
                 "--t-qs", "1.96", "--t-qd", "18.54", "--count", "4", "--json"])
    assert code in (0, None)
    out = json.loads(capsys.readouterr().out)
    rows = out["designs"]
    assert [r["fn_hz"] for r in rows] == [15.93, 14.0]
    for r in rows:
        assert set(r) == {"fn_hz", "gs", "spectral_abscissa", "roots", "clusters", "complete",
                          "stable", "uncertain", "right_half_plane_roots"}
        # simple roots: each its own disc holding one root, no cluster
        assert r["clusters"] == [] and all(z["count"] == 1 for z in r["roots"])
        assert r["complete"] and r["stable"] is (r["right_half_plane_roots"] == 0)
        re_ = [z["re"] for z in r["roots"]]
        assert re_ == sorted(re_, reverse=True) and all(z["im"] >= 0 for z in r["roots"])
        assert r["spectral_abscissa"] == re_[0]
    assert rows[0]["spectral_abscissa"] > 0 > rows[1]["spectral_abscissa"]


def test_gains_table_marks_unstable_pm(capsys):
    main(["gains", "--fn", "15.93", "--gs", "1.867", "--t-tau", "1.99", "--t-qs", "1.96",
          "--t-qd", "18.54"])
    assert "(unstable)" in capsys.readouterr().out
    main(["gains", "--fn", "15.93", "--gs", "1.867", "--t-tau", "1.99", "--t-qs", "1.96",
          "--t-qd", "18.54", "--json"])
    row = json.loads(capsys.readouterr().out)[0]
    assert row["stable"] is False and isinstance(row["phase_margin_deg"], float)
    assert row["spectral_abscissa"] > 0


def test_a_negligible_delay_gives_the_undelayed_roots():
    """A delay of 1e-308 ms (the collocation would divide by it) is below NEGLIGIBLE_DELAY
    of the time scale: oracle, the roots of the same design without it (the polished
    roots of the undelayed polynomial)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sc.UnitWarning)
        tiny = sc.design(14.0, delays_ms={"stiffness": 1e-308}).roots(4)
    none = sc.design(14.0).roots(4)
    assert bool(tiny.converged)
    np.testing.assert_allclose(tiny.roots, none.roots, rtol=1e-12)


def test_a_short_delay_keeps_its_root_cluster():
    # Oracle: the poles of python-control's closed loop with a Pade(4) delay (exact to
    # far below the tolerance for a 1e-9 s delay). The critically damped design has a
    # quadruple root at -188.5; a 1e-6 ms damping delay splits it into two pairs. The
    # far-left roots of the delay (|s| ~ 1e11) once merged the second pair into the
    # first (duplicates were judged relative to the largest root).
    import control as ct

    with pytest.warns(UserWarning, match="below 1 us"):
        d = sc.design([30.0], delays_ms={"torque": 0.0, "stiffness": 0.0, "damping": 1e-6})
    r = d.roots(count=2)
    got = np.sort_complex(np.ravel(r.roots))
    p = ct.poles(d[0].to_control("pade", transfer="closed", order=4))
    ref = np.sort_complex(p[(np.abs(p + 188.5) < 20) & (p.imag > 0)])
    assert ref.size == 2
    np.testing.assert_allclose(got, ref, rtol=1e-6)
    assert bool(r.stable[0]) and int(r.right_half_plane_roots[0]) == 0
