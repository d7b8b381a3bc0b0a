"""The margin kernel's four-lane functions (seactl.certify.vecmath: cis4, atan2_4, V4 and its sqrt).

Oracle: mpmath's sine, cosine and arctangent at 120 bits; for the square root, the scalar
one (both correctly rounded).  The bound asserted, 4 ulps, is
the one glibc states for its vector functions; the scan's rounding allowance assumes it
(seactl.diagram.blockdiagram.EVAL_ROUNDING).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from numba import njit

from seactl.certify.scan import _mag, _mag4
from seactl.certify.vecmath import (
    all_within,
    atan2_4,
    atan2_v4,
    cis4,
    cis_v4,
    lane,
    sqrt_v4,
    v4,
    with_lane,
)


@njit
def _cis_all(x):
    """cis4 over ``x`` (length a multiple of 4): cosines and sines."""
    out = np.empty((2, x.size))
    for i in range(0, x.size, 4):
        r = cis4(x[i], x[i + 1], x[i + 2], x[i + 3])
        for j in range(4):
            out[0, i + j], out[1, i + j] = r[j], r[4 + j]
    return out


@njit
def _atan2_all(y, x):
    out = np.empty(x.size)
    for i in range(0, x.size, 4):
        r = atan2_4(y[i], y[i + 1], y[i + 2], y[i + 3], x[i], x[i + 1], x[i + 2], x[i + 3])
        for j in range(4):
            out[i + j] = r[j]
    return out


def _ulps(got: np.ndarray, x: np.ndarray, fn) -> np.ndarray:
    with mpmath.workprec(120):
        ref = [fn(mpmath.mpf(float(v))) for v in x]
        return np.array([float(abs(mpmath.mpf(float(g)) - r)) / math.ulp(float(r))
                         for g, r in zip(got, ref)])


@pytest.mark.parametrize("lo, hi", [(0.0, 2.0), (0.0, 1e3), (-1e5, 1e5)])
def test_phasors_within_glibcs_stated_error(lo, hi):
    """4,000 random phases per range (the scan's ``w tau`` reach 1e3 rad and more):
    every cosine and sine within 4 ulps of the 120-bit values."""
    x = np.random.default_rng(7).uniform(lo, hi, 4000)
    cos_, sin_ = _cis_all(x)
    assert _ulps(cos_, x, mpmath.cos).max() <= 4.0
    assert _ulps(sin_, x, mpmath.sin).max() <= 4.0


def test_arctangents_within_glibcs_stated_error():
    """4,000 random points in all four quadrants, moduli from 1e-6 to 1e6 (``arg L`` and
    the chords' turns): within 4 ulps of the 120-bit values."""
    rng = np.random.default_rng(9)
    y, x = (rng.normal(size=4000) * 10.0 ** rng.uniform(-6, 6, 4000) for _ in range(2))
    got = _atan2_all(y, x)
    with mpmath.workprec(120):
        ref = [mpmath.atan2(mpmath.mpf(float(a)), mpmath.mpf(float(b))) for a, b in zip(y, x)]
        ulps = [float(abs(mpmath.mpf(float(g)) - r)) / math.ulp(float(r))
                for g, r in zip(got, ref)]
    assert max(ulps) <= 4.0


def test_small_phases_keep_their_relative_accuracy():
    """Phases from 1e-12 to 1e-2 (a low frequency times a short delay): the sine within
    4 ulps of itself, not of 1."""
    x = 10.0 ** np.random.default_rng(3).uniform(-12, -2, 2000)
    assert _ulps(_cis_all(x)[1], x, mpmath.sin).max() <= 4.0


def test_a_lane_does_not_depend_on_its_neighbours():
    """The margin scan evaluates N's and D's phasors in one call and the crossing solver
    a design's N alone: a phase must give the same bits in any lane, next to any others."""
    rng = np.random.default_rng(11)
    x = rng.uniform(-50, 50, 4000)
    base = _cis_all(x)
    for shift in (1, 2, 3):
        moved = _cis_all(np.roll(x, shift))
        np.testing.assert_array_equal(np.roll(base, shift, axis=1), moved)


def test_special_values():
    """Phase 0 gives exactly (1, 0), NaN and infinities NaN; the arctangent's signed
    zeros and axes are the scalar function's (``arg L`` on the negative real axis is
    compared with +-pi)."""
    cos_, sin_ = _cis_all(np.array([0.0, np.nan, np.inf, -np.inf]))
    assert (cos_[0], sin_[0]) == (1.0, 0.0)
    assert np.isnan(cos_[1:]).all() and np.isnan(sin_[1:]).all()
    y = np.array([0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 0.0, np.nan])
    x = np.array([-1.0, -1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0])
    got, ref = _atan2_all(y, x), np.arctan2(y, x)
    np.testing.assert_array_equal(got[:7], ref[:7])
    assert np.array_equal(np.signbit(got[:7]), np.signbit(ref[:7])) and np.isnan(got[7])


@njit
def _sqrt_all(x):
    out = np.empty(x.size)
    for i in range(0, x.size, 4):
        r = sqrt_v4(v4(x[i], x[i + 1], x[i + 2], x[i + 3]))
        out[i], out[i + 1], out[i + 2], out[i + 3] = lane(r, 0), lane(r, 1), lane(r, 2), lane(r, 3)
    return out


@njit
def _moduli(z):
    """The scan's moduli four at a time (_certify._mag4) and one at a time (_mag)."""
    out = np.empty((2, z.size))
    for i in range(0, z.size, 4):
        out[0, i], out[0, i + 1], out[0, i + 2], out[0, i + 3] = \
            _mag4(z[i], z[i + 1], z[i + 2], z[i + 3])
        for j in range(4):
            out[1, i + j] = _mag(z[i + j])
    return out


def test_four_square_roots_are_the_scalar_ones():
    """sqrt_v4 is IEEE's correctly rounded square root: numpy's bits over forty decades,
    with 0, -0, infinities, NaN and a negative number."""
    rng = np.random.default_rng(3)
    x = np.concatenate([10.0 ** rng.uniform(-300, 300, 3992),
                        [0.0, -0.0, np.inf, np.nan, -1.0, 5e-324, 1.7e308, 2.0]])
    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal(_sqrt_all(x), np.sqrt(x))


def test_four_moduli_are_the_scalar_ones():
    """The scan's point takes eleven moduli four at a time (_mag4): the same bits as
    _mag's one at a time, whichever path each takes (a sum of squares near the fast
    path's limits, 1e-290 and 1e290, sends all four to _mag), with zeros, subnormals,
    infinities and NaN among them."""
    rng = np.random.default_rng(4)
    n = 8000
    mag = 10.0 ** rng.uniform(-160, 160, n)
    z = mag * np.exp(1j * rng.uniform(-np.pi, np.pi, n))
    special = np.array([0, 1e-145, 1e145, 7e-146, 1.1e145, 5e-324, np.inf, np.nan,
                        complex(np.nan, np.inf), complex(3.0, 4.0), complex(-0.0, 1e-200),
                        complex(1e150, 1e150)])
    z[rng.choice(n, 800, replace=False)] = rng.choice(special, 800)
    got = _moduli(z)
    np.testing.assert_array_equal(got[0], got[1])
    with np.errstate(invalid="ignore"):  # (and |z| to an ulp or two)
        np.testing.assert_allclose(got[1], np.abs(z), rtol=4.5e-16)


@njit
def _v4_ops(a, b):
    """Each V4 operation over 4-lane slices of ``a`` and ``b``, back to arrays."""
    out = np.empty((10, a.size))
    for i in range(0, a.size, 4):
        x = v4(a[i], a[i + 1], a[i + 2], a[i + 3])
        y = v4(b[i], b[i + 1], b[i + 2], b[i + 3])
        c, s = cis_v4(x)
        rows = (x + y, x - y, x * y, x / y, -x, 2.0 * x - b[i], sqrt_v4(x * x + y * y), c,
                atan2_v4(y, x), with_lane(x, i // 4 % 4, b[i + 1]))
        for r in range(10):
            for k in range(4):
                out[r, i + k] = lane(rows[r], k)
    return out


def test_four_lane_values_are_the_scalar_operations_bits():
    """The V4 type that evaluates the base grid's points four at a time: each of its
    operations gives, lane by lane, numpy's bits for the same scalar operation (the
    correctly rounded IEEE ones; the cosine and arctangent the lane functions' of
    cis4 and atan2_4); on 4,000 pairs over 600 decades with zeros of both signs, NaN,
    infinities and subnormals; ``all_within`` is the lanes' strict bounds, ``with_lane``
    replaces one lane and keeps the others."""
    rng = np.random.default_rng(13)
    a, b = (rng.normal(size=4000) * 10.0 ** rng.uniform(-300, 300, 4000) for _ in range(2))
    a[:8] = [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, 1.0]
    b[:8] = [-0.0, 0.0, 1.0, np.inf, 2.0, 3.0, np.nan, -0.0]
    got = _v4_ops(a, b)
    with np.errstate(all="ignore"):
        ref = (a + b, a - b, a * b, a / b, -a, 2.0 * a - np.repeat(b[::4], 4),
               np.sqrt(a * a + b * b))
    for g, r in zip(got, ref):
        np.testing.assert_array_equal(g.view(np.int64)[~np.isnan(r)],
                                      r.view(np.int64)[~np.isnan(r)])
        assert np.isnan(g[np.isnan(r)]).all()
    np.testing.assert_array_equal(got[7], _cis_all(a)[0])
    np.testing.assert_array_equal(got[8], _atan2_all(b, a))
    replaced = a.copy()
    at = np.arange(0, a.size, 4)
    replaced[at + at // 4 % 4] = b[at + 1]
    np.testing.assert_array_equal(got[9], replaced)
    assert [_within(np.array(x)) for x in ([1.0, 2, 3, 4], [1.0, 2, 3, 5], [0.5, 2, 3, 4],
                                           [1.5, np.nan, 3, 4])] == [True, False, False, False]


@njit
def _within(x):
    return all_within(v4(x[0], x[1], x[2], x[3]), 0.5, 5.0)
