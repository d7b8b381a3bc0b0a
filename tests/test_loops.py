"""The block diagram against the paper's printed formulas (independent derivations)."""

import numpy as np
import pytest

from seactl.errors import InputError
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import (
    SEADesign,
    Timing,
    closed_loop,
    force_plant,
    inner_loop,
    outer_loop,
    torque_closed_loop,
)

A = UT_SEA
RNG = np.random.default_rng(42)
S = 1j * 2 * np.pi * np.logspace(-1, 3, 40) + RNG.normal(size=40)


def design(fn=16.0, gs=1.0, timing=Timing.from_ms(0.7, 3.0, 1.1, 45.0, 120.0)):
    return SEADesign(A, critically_damped_gains(A, fn, gs=gs), timing)


def paper_terms(d, s):
    """Building blocks exactly as printed in the paper (eqs. PF, P_CF, filters)."""
    r = (A.Ij * s**2 + A.bj * s) / (A.Ij * s**2 + A.bj * s + A.k)
    PF = A.beta * r * A.k / (A.Im * s**2 + A.bm * s + r * A.k)
    Qt = 1 / (d.Tf_taud * s + 1)
    Qv = 1 / (d.Tf_qd * s + 1)
    C = d.Ktau + d.Btau * Qt * s
    et, eqs, eqd = (np.exp(-s * T) for T in (d.T_tau, d.T_qs, d.T_qd))
    PC = PF * (1 / A.beta + C) / (1 + PF * C * et)
    PL = 1 / (A.Ij * s**2 + A.bj * s)
    return PF, PC, PL, C, Qt, Qv, et, eqs, eqd


def test_force_plant_equals_paper_pf():
    # Oracle: P_F as printed (paper_terms).
    d = design()
    PF = paper_terms(d, S)[0]
    np.testing.assert_allclose(force_plant()(d, S), PF, rtol=1e-9)


def test_torque_loop_and_outer_loop_equal_paper_composition():
    # Oracle: the paper's composition of P_F, C, P_L and the delays (paper_terms).
    d = design()
    PF, PC, PL, C, Qt, Qv, et, eqs, eqd = paper_terms(d, S)
    np.testing.assert_allclose(torque_closed_loop()(d, S), PC, rtol=1e-9)
    np.testing.assert_allclose(inner_loop()(d, S), PF * C * et, rtol=1e-9)
    L = PC * PL * (eqd * d.Bq * Qv * S + eqs * d.Kq)
    np.testing.assert_allclose(outer_loop()(d, S), L, rtol=1e-9)


def test_closed_loop_equals_printed_coefficient_form():
    """eq. closedloop with its printed D_i (delays and filters inside the coefficients)."""
    d = design()
    s = S
    _, _, _, _, Qt, Qv, et, eqs, eqd = paper_terms(d, s)
    b, Kq, Bq, Kt, Bt = A.beta, d.Kq, d.Bq, d.Ktau, d.Btau
    D4 = A.Im * A.Ij / A.k
    D3 = (A.Ij * A.bm + A.Im * A.bj) / A.k + A.Ij * b * Bt * Qt * et
    D2 = (A.Ij * (1 + et * b * Kt) + A.Im + A.bj * b * Bt * Qt * et + b * Bt * Bq * eqd * Qv * Qt
          + A.bj * A.bm / A.k)
    D1 = A.bj * (1 + et * b * Kt) + A.bm + b * Bt * Qt * Kq * eqs + eqd * (1 + b * Kt) * Bq * Qv
    D0 = eqs * (1 + b * Kt) * Kq
    den = D4 * s**4 + D3 * s**3 + D2 * s**2 + D1 * s + D0
    np.testing.assert_allclose(closed_loop()(d, s), Kq * (1 + b * Kt + b * Bt * Qt * s) / den,
                               rtol=1e-8)
    # Without the torque-derivative zero (the authors' H_CL, docs/theory/loop.md)
    np.testing.assert_allclose(closed_loop(zero=False)(d, s), Kq * (1 + b * Kt) / den, rtol=1e-8)


def test_batches_broadcast_like_single_designs():
    # Oracle: each design of the batch evaluated alone.
    fn = np.array([12.0, 18.0, 25.0])
    tq = np.array([[0.0], [4.0]])
    batch = SEADesign(A, critically_damped_gains(A, fn), Timing.from_ms(0.5, tq, 1.0, 50, 100))
    out = outer_loop()(batch, S)
    assert out.shape == (2, 3, S.size)
    for i, t in enumerate(tq[:, 0]):
        for j, f in enumerate(fn):
            one = SEADesign(A, critically_damped_gains(A, f), Timing.from_ms(0.5, t, 1.0, 50, 100))
            np.testing.assert_allclose(out[i, j], outer_loop()(one, S), rtol=1e-12)


def test_no_filter_means_unit_filter():
    # Oracle: the documented equivalence: f = inf and None both mean no filter.
    d_inf = design(timing=Timing(0.001, 0.002, 0.001, np.inf, np.inf))
    d_none = design(timing=Timing(0.001, 0.002, 0.001, None, None))
    np.testing.assert_allclose(outer_loop()(d_inf, S), outer_loop()(d_none, S), rtol=1e-12)


@pytest.mark.parametrize("kw,field", [
    (dict(T_qs=-0.001), "T_qs"), (dict(T_tau=float("nan")), "T_tau"),
    (dict(f_qd=0.0), "f_qd"), (dict(f_taud=-5.0), "f_taud"), (dict(T_qd=np.inf), "T_qd"),
])
def test_bad_timing(kw, field):
    # Oracle: the error contract (InputError naming the parameter).
    with pytest.raises(InputError, match=field):
        Timing(**kw)
