import numpy as np
import pytest
from scipy.optimize import fsolve

from seactl.errors import InfeasibleDesignError, InputError
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import (
    _cubic_roots,
    characteristic_coefficients,
    critically_damped_gains,
    feasible_fn_range,
    solve_gains,
    target_polynomial,
)
from seactl.systems.sea.loops import SEADesign, closed_loop

# Table I as printed: f_n -> Kq, Bq, Ktau, Btau; tolerance half a unit of the last printed
# digit (all Table I gains happen to be rounded, not truncated)
TABLE_I = [
    (12, 65, 0.46, 1.18, 0.057),
    (14, 83, 0.76, 1.80, 0.067),
    (16, 103, 1.02, 2.56, 0.077),
    (18, 124, 1.26, 3.45, 0.087),
    (20, 148, 1.49, 4.48, 0.097),
]


@pytest.mark.parametrize("fn,Kq,Bq,Ktau,Btau", TABLE_I)
def test_table_i_gains(fn, Kq, Bq, Ktau, Btau):
    # Oracle: the paper's Table I (TABLE_I above).
    g = critically_damped_gains(UT_SEA, fn)
    assert float(g.Kq) == pytest.approx(Kq, abs=0.5)
    assert float(g.Bq) == pytest.approx(Bq, abs=0.005 + 1e-9)
    assert float(g.Ktau) == pytest.approx(Ktau, abs=0.005 + 1e-9)
    assert float(g.Btau) == pytest.approx(Btau, abs=0.0005 + 1e-9)


def test_caption_gains_at_30_hz():
    # Oracle: the gains printed in the caption of Fig. impedanceFilterDelay.
    g = critically_damped_gains(UT_SEA, 30.0)
    # one unit of each printed digit: the paper truncates some values (2.495 -> 2.49)
    assert float(g.Kq) == pytest.approx(293.6, abs=0.1)
    assert float(g.Bq) == pytest.approx(2.49, abs=0.01)
    assert float(g.Ktau) == pytest.approx(11.71, abs=0.01)
    assert float(g.Btau) == pytest.approx(0.146, abs=0.001)


@pytest.mark.parametrize("fn,zeta1,zeta2,ratio", [
    (14.0, 1.0, 1.0, 1.0), (30.0, 1.0, 1.0, 1.0), (20.0, 0.8, 1.2, 1.5), (25.0, 0.7, 0.9, 1.2),
])
def test_closed_loop_poles_are_the_requested_ones(fn, zeta1, zeta2, ratio):
    """P_CL from the block diagram (no delay, no filter) equals
    K_q (1 + beta K_tau + beta B_tau s) / (D_4 prod(s^2 + 2 zeta w s + w^2)) at random s."""
    g = critically_damped_gains(UT_SEA, fn, zeta1=zeta1, zeta2=zeta2, ratio=ratio)
    d = SEADesign(UT_SEA, g)
    rng = np.random.default_rng(0)
    s = rng.normal(size=20) * 100 + 1j * rng.normal(size=20) * 100
    w1 = 2 * np.pi * fn
    w2 = ratio * w1
    a = UT_SEA
    expected = (float(g.Kq) * (1 + a.beta * float(g.Ktau) + a.beta * float(g.Btau) * s)
                / (a.Im * a.Ij / a.k * (s**2 + 2 * zeta1 * w1 * s + w1**2)
                   * (s**2 + 2 * zeta2 * w2 * s + w2**2)))
    np.testing.assert_allclose(closed_loop()(d, s), expected, rtol=1e-8)


def test_closed_form_agrees_with_fsolve_near_the_solution():
    # Oracle: scipy.optimize.fsolve on the four gain equations, started 10 % away from our
    # solution.
    fn = 16.0
    g = critically_damped_gains(UT_SEA, fn)
    w = 2 * np.pi * fn
    target = np.array(target_polynomial(w, w, 1.0, 1.0))

    def resid(x):
        return np.array(characteristic_coefficients(UT_SEA, *np.exp(x))) / target - 1

    x0 = np.log([float(g.Kq), float(g.Bq), float(g.Ktau), float(g.Btau)]) + 0.1
    x = np.exp(fsolve(resid, x0, xtol=1e-13))
    np.testing.assert_allclose(x, [float(g.Kq), float(g.Bq), float(g.Ktau), float(g.Btau)],
                               rtol=1e-7)


def test_cubic_roots_match_numpy_roots():
    # Oracle: numpy.roots.
    rng = np.random.default_rng(3)
    c = rng.normal(size=(50, 4))
    ours = _cubic_roots(c[:, 0], c[:, 1], c[:, 2], c[:, 3])
    ref = np.array([np.roots(row) for row in c])
    # every numpy root has one of ours next to it (order of conjugate pairs is arbitrary)
    dist = np.abs(ref[:, :, None] - ours[:, None, :]).min(axis=-1)
    assert np.all(dist <= 1e-8 * (1 + np.abs(ref)))


def test_vectorized_over_fn_and_gs():
    """Oracle: every entry of the broadcast batch computed alone by a scalar call (the
    batch must not mix its axes); GS itself is checked against Fig. GainScale(a) in
    test_margins.py and the printed gains at GS = 1 above."""
    fn, gs = np.array([12.0, 14.0, 16.0]), np.array([0.5, 1.0, 2.0])
    g = critically_damped_gains(UT_SEA, fn[:, None], gs=gs)
    assert g.Kq.shape == (3, 3)
    for i, j in np.ndindex(3, 3):
        one = critically_damped_gains(UT_SEA, fn[i], gs=gs[j])
        for name in ("Kq", "Bq", "Ktau", "Btau"):
            assert getattr(g, name)[i, j] == pytest.approx(float(getattr(one, name)),
                                                           rel=1e-12), (name, i, j)


def test_infeasible_fn_reports_range():
    # Oracle: docs/theory/gain-design.md (about 9.5 Hz) and the bound's defining property
    # (B_q crosses zero there), probed on both sides.
    with pytest.raises(InfeasibleDesignError) as exc:
        critically_damped_gains(UT_SEA, 8.0)
    assert "f_n = 8 Hz" in str(exc.value)
    assert "9.45" in str(exc.value)
    lo = feasible_fn_range(UT_SEA)[0][0]
    assert lo == pytest.approx(9.5, abs=0.1)   # docs/theory/gain-design.md
    # the boundary is where B_q crosses zero: just above it the solution is valid, below not
    above, below = solve_gains(UT_SEA, [lo * (1 + 1e-5), lo * (1 - 1e-5)]).n_valid
    assert above >= 1 and below == 0
    sol = solve_gains(UT_SEA, lo * (1 + 1e-4))
    j = int(np.argmax(sol.valid))
    assert 0 < sol.Bq[j] < 1e-3


def test_infeasible_batch_reports_the_failing_designs_range():
    """With zeta1 per design, the range given is the failing design's, not the first
    design's.  Oracle: feasible_fn_range for each zeta1 alone (10 Hz is feasible at
    zeta1 = 1, not at 0.3)."""
    lo_03 = feasible_fn_range(UT_SEA, zeta1=0.3)[0][0]
    assert feasible_fn_range(UT_SEA)[0][0] < 10.0 < lo_03
    with pytest.raises(InfeasibleDesignError) as exc:
        critically_damped_gains(UT_SEA, np.array([10.0, 10.0]), zeta1=np.array([1.0, 0.3]))
    assert "zeta1=0.3" in str(exc.value)
    assert exc.value.feasible_hz[0][0] == pytest.approx(lo_03)


def test_never_returns_non_solutions():
    # Oracle: the residual of the gain equations at every returned solution (a property of
    # the solver) and the sign of the gains.
    fn = np.linspace(1.0, 300.0, 2000)
    s = solve_gains(UT_SEA, fn)
    for lhs, rhs in zip(characteristic_coefficients(UT_SEA, s.Kq, s.Bq, s.Ktau, s.Btau),
                        target_polynomial(2 * np.pi * fn, 2 * np.pi * fn, 1.0, 1.0)):
        rel = np.abs(lhs - rhs[:, None]) / rhs[:, None]
        assert np.all(rel[s.valid] < 1e-9)
    assert np.all(s.Kq[s.valid] > 0) and np.all(s.Bq[s.valid] > 0)


@pytest.mark.parametrize("kw", [dict(fn_hz=0.0), dict(fn_hz=float("nan")), dict(fn_hz=-3.0),
                                dict(fn_hz=14.0, zeta1=0.0), dict(fn_hz=14.0, ratio=-1.0)])
def test_bad_design_inputs(kw):
    # Oracle: the error contract (InputError naming the parameter).
    with pytest.raises(InputError):
        critically_damped_gains(UT_SEA, **kw)
    with pytest.raises(InputError, match="gs"):
        critically_damped_gains(UT_SEA, 14.0, gs=0.0)
