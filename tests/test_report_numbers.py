"""The report's numbers computed exactly: the GS optimum, the exact step peak, stability
intervals in a delay, and fsolve's failures per formulation.

Oracles: a dense scan (GS optimum), mpmath's matrix exponential at 40 digits (step peak),
a dense delay grid (stability intervals), and the closed-form gains (fsolve)."""

import mpmath as mp
import numpy as np
import pytest

import seactl as sc
from seactl.analysis.delay_intervals import interval_containing, stability_intervals
from seactl.analysis.step_peak import step_peak, step_value
from seactl.apps.paper.gain_design import gs_optimum
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import SEADesign, Timing
from seactl.systems.sea.views import sea_margins


def test_gs_optimum_at_10hz_is_inside_the_range_on_a_cliff():
    # Oracle: a dense scan (step 1e-4) of GS 0.15-0.5 of the ideal loop's phase margin.
    gs = np.round(np.arange(0.15, 0.5, 1e-4), 6)
    pm = sea_margins(SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 10.0, gs=gs)))
    pm = pm.phase_margin_deg
    j = int(np.nanargmax(pm))
    o = gs_optimum(10.0)
    assert o.pm_deg >= pm[j] - 1e-6
    assert abs(o.gs - gs[j]) < 0.01 and 0.2 < o.gs < 0.3      # not the old scan's edge 0.3
    below = pm[np.argmin(np.abs(gs - 0.20))]
    assert below < o.pm_deg - 40                                 # the cliff: 13.3 deg at 0.20
    assert o.plateau[0] <= o.gs <= o.plateau[1] and o.outside[0] < o.pm_deg - 20


def _mp_step(ss, t):
    A, B, C, D = ss.A, ss.B, ss.C, ss.D
    n = A.shape[0]
    M = mp.zeros(n + 1, n + 1)
    for i in range(n):
        for k in range(n):
            M[i, k] = mp.mpf(A[i, k])
        M[i, n] = mp.mpf(B[i, 0])
    E = mp.expm(M * mp.mpf(t))
    return float(sum(mp.mpf(C[0, i]) * E[i, n] for i in range(n)) + mp.mpf(D[0, 0]))


def test_step_peak_matches_mpmath_at_gs_2_and_3():
    # Oracle: mpmath's 40-digit matrix exponential of the same system at the peak time, and
    # at +-0.2 ms (the peak is the largest of the three).
    mp.mp.dps = 40
    systems = sc.design(14.0, gs=[2.0, 3.0]).to_control("pade-ss", transfer="closed")
    for ss, want in zip(systems, (25.94, 31.05)):
        p = step_peak(ss.A, ss.B, ss.C, ss.D, 0.3)
        exact = _mp_step(ss, p.t_s)
        assert p.value == pytest.approx(exact, abs=1e-9)
        assert exact >= max(_mp_step(ss, p.t_s - 2e-4), _mp_step(ss, p.t_s + 2e-4))
        assert p.overshoot_pct == pytest.approx(want, abs=0.005)
        assert step_value(ss.A, ss.B, ss.C, ss.D, p.t_s) == pytest.approx(exact, abs=1e-9)


def test_stability_intervals_of_the_30hz_damping_delay():
    # Oracle: the verdict on a dense grid (0.01 ms): stable exactly inside the intervals,
    # and the 30 Hz design unstable at T_qd = 0, stable from about 0.08 ms to about 3.3 ms.
    g = critically_damped_gains(UT_SEA, 30.0)

    def stable(T_s):
        t = Timing.from_ms(1.0, 1.0, np.asarray(T_s) * 1e3, 50.0, 100.0)
        return sea_margins(SEADesign(UT_SEA, g, t)).stable

    iv = stability_intervals(stable, np.arange(0.0, 10.0001, 0.05) * 1e-3)
    dense = np.arange(0.0, 10.0, 0.01) * 1e-3
    s = stable(dense)
    inside = np.array([any(lo <= t <= hi for lo, hi in iv) for t in dense])
    assert np.array_equal(inside, s)
    assert not s[0]
    lo, hi = interval_containing(iv, 1e-3)
    assert 0 < lo < 0.25e-3 and 3e-3 < hi < 3.5e-3
    assert interval_containing(iv, 0.0) is None


def test_fsolve_fails_far_more_in_log_space_than_in_plain_unknowns():
    # Oracle: the closed-form gains (seactl.systems.sea.design.solve_gains) at every converged
    # point;
    # the two formulations' failure counts differ.
    from seactl.apps.bench.core import fsolve_gains

    fn = np.linspace(10.0, 200.0, 20)
    fails = {}
    for form in ("log", "plain"):
        fails[form] = 0
        for f in fn:
            g, ok = fsolve_gains(UT_SEA, f, formulation=form)
            if not ok:
                fails[form] += 1
                continue
            ref = critically_damped_gains(UT_SEA, f)
            assert np.allclose(g, [ref.Kq, ref.Bq, ref.Ktau, ref.Btau], rtol=1e-5)
    assert fails["plain"] < fails["log"]


def test_non_passive_bands_recur_above_the_report_scan():
    # Oracle: python-control's FRD of the same exact-delay impedance on a dense 1-10 kHz grid
    # (runs of Re Z < 0), against the passivity scan's bands that end above 1 kHz.
    from seactl.systems.sea.passivity import passivity

    tt, ts, td = 1.0, 10.0, 3.0                      # the report's 10/3/1 ms set, no filters
    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 30.0), Timing.from_ms(tt, ts, td))
    bands = [b for b in passivity(d, (0.1, 10_000.0)).bands_hz[()] if b[1] > 1000.0]
    f = np.linspace(1000.0, 10_000.0, 180_001)
    d = sc.design(30.0, delays_ms={"torque": tt, "stiffness": ts, "damping": td})
    frd = d.to_control("frd", transfer="impedance", f_hz=f)
    neg = np.real(np.squeeze(frd.frdata)) < 0
    runs = int(np.sum(neg[1:] & ~neg[:-1]) + neg[0])
    assert len(bands) == runs and runs > 20
