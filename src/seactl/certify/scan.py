"""Compiled kernel of the certified scan (:func:`seactl.analysis.margins.certified_margins`).

The scan is a per-design bisection of a few dozen intervals, each a handful of scalar
operations on two small quasi-polynomials: in numpy the temporaries of every pass cost more
than the arithmetic, so the per-design loop is compiled (numba, cached on disk), and so is
the solution of the crossings it brackets (:func:`refine`).  Each design's intervals are
refined depth-first from its base grid; the soundness argument and the tolerances are
those of :func:`seactl.analysis.margins.certified_margins` (docs/theory/certified-scan.md).
"""

from __future__ import annotations

import math

import numpy as np

from seactl.base.borrow import borrowed
from seactl.base.jit import KernelGroup, njit
from seactl.certify.vecmath import (
    all_within,
    atan2_4,
    atan2_v4,
    cis4,
    cis_v4,
    lane,
    splat,
    sqrt_v4,
    v4,
    with_lane,
)
from seactl.diagram.blockdiagram import EVAL_ROUNDING

KERNELS = KernelGroup("margin", about_s=80)
"""The group of this module's kernels (the certified margin scan)."""

# Limits (documented in seactl.analysis.margins, which re-exports them).
MAX_BISECTIONS = 48
MAX_EVALUATIONS = 1 << 16
ROUNDING = EVAL_ROUNDING
"""Evaluation error of ``Q(jw)`` relative to :func:`seactl.diagram.blockdiagram.rounding_majorant`
(the first row of the scan's ``bounds``, :func:`bound_table`)."""
BAND_LO, BAND_HI = 0.05, 20.0
"""The band of ``|L|`` whose phase crossings the first scan certifies (:func:`band_table`)."""

GAIN, PHASE = 0, 1
TOUCH = 2
"""Added to a bracket's kind: the interval is at the bisection limit and its path may
touch the level without crossing it (a tangency); solved as a crossing at its nearer end."""


@njit(cache=True, inline="always")
def _eval(coeffs, delays, d, w, order):  # pragma: no cover - compiled
    """``Q(jw)``, ``dQ(jw)/dw`` and ``d^2 Q(jw)/dw^2`` of design ``d`` (derivatives above
    ``order`` left 0); ``coeffs`` in descending powers (:func:`descending`)."""
    return _eval_pair(coeffs, delays, coeffs, delays, 0, d, w, order)[:3]


@njit(cache=True, inline="always")
def _eval_pair(Nc, Nt, Dc, Dt, kd, d, w, order):  # pragma: no cover - compiled
    """:func:`_eval` of ``N`` and of the first ``kd`` terms of ``D``: their delay phasors
    four at a time (:func:`seactl.certify.vecmath.cis4`: two vector calls for the SEA loop's
    three delays instead of six scalar ones)."""
    kn = Nc.shape[0]
    if kn + kd <= 4:  # (one group: straight-line code, no loop over groups)
        cos_, sin_ = _phasors(Nt, Dt, kn, kd, d, w, 0)
        N, dN, d2N = _terms(Nc, Nt, 0, kn, 0, d, w, order, cos_, sin_)
        D, dD, d2D = _terms(Dc, Dt, 0, kd, kn, d, w, order, cos_, sin_)
        return N, dN, d2N, D, dD, d2D
    N = dN = d2N = D = dD = d2D = 0j
    for k0 in range(0, kn + kd, 4):
        cos_, sin_ = _phasors(Nt, Dt, kn, kd, d, w, k0)
        a, b, c = _terms(Nc, Nt, k0, min(kn, k0 + 4), -k0, d, w, order, cos_, sin_)
        N, dN, d2N = N + a, dN + b, d2N + c
        a, b, c = _terms(Dc, Dt, max(kn, k0) - kn, min(kn + kd, k0 + 4) - kn, kn - k0,
                         d, w, order, cos_, sin_)
        D, dD, d2D = D + a, dD + b, d2D + c
    return N, dN, d2N, D, dD, d2D


@njit(cache=True, inline="always")
def _terms(coeffs, delays, lo, hi, off, d, w, order, cos_, sin_):  # pragma: no cover
    """Terms ``lo`` to ``hi - 1`` of a quasi-polynomial (:func:`_eval`), term ``k``'s
    phasor at ``k + off`` in ``cos_``, ``sin_``."""
    qr = qi = d1r = d1i = d2r = d2i = 0.0
    for k in range(lo, hi):
        tau = delays[k, d]
        er, ei = (cos_[k + off], -sin_[k + off]) if tau != 0 else (1.0, 0.0)
        pr, pi_ = coeffs[k, d, 0], 0.0
        dpr = dpi = d2pr = d2pi = 0.0
        for j in range(1, coeffs.shape[2]):   # x <- x s + y, s = jw: (-Im x w, Re x w) + y
            if order >= 2:
                d2pr, d2pi = -d2pi * w + 2 * dpr, d2pr * w + 2 * dpi
            if order >= 1:
                dpr, dpi = -dpi * w + pr, dpr * w + pi_
            pr, pi_ = -pi_ * w + coeffs[k, d, j], pr * w
        # Q += p e;  dQ/ds += (p' - tau p) e;  d2Q/ds2 += (p'' - 2 tau p' + tau^2 p) e
        qr += pr * er - pi_ * ei
        qi += pr * ei + pi_ * er
        if order >= 1:
            ar, ai = dpr - tau * pr, dpi - tau * pi_
            d1r += ar * er - ai * ei
            d1i += ar * ei + ai * er
        if order >= 2:
            br = d2pr - 2 * tau * dpr + tau * tau * pr
            bi = d2pi - 2 * tau * dpi + tau * tau * pi_
            d2r += br * er - bi * ei
            d2i += br * ei + bi * er
    # d/dw = j d/ds
    return complex(qr, qi), complex(-d1i, d1r), complex(-d2r, -d2i)


@njit(cache=True, inline="always")
def _phasors(Nt, Dt, kn, kd, d, w, k0):  # pragma: no cover - compiled
    """Cosines and sines of ``w tau`` for terms ``k0`` to ``k0 + 3`` of ``N`` followed by
    ``D`` (0 past the last)."""
    c0, c1, c2, c3, s0, s1, s2, s3 = cis4(
        _phase(Nt, Dt, kn, kd, d, w, k0), _phase(Nt, Dt, kn, kd, d, w, k0 + 1),
        _phase(Nt, Dt, kn, kd, d, w, k0 + 2), _phase(Nt, Dt, kn, kd, d, w, k0 + 3))
    return (c0, c1, c2, c3), (s0, s1, s2, s3)


@njit(cache=True, inline="always")
def _phase(Nt, Dt, kn, kd, d, w, k):  # pragma: no cover - compiled
    if k < kn:
        return w * Nt[k, d]
    return w * Dt[k - kn, d] if k < kn + kd else 0.0


@njit(cache=True, inline="always")
def _bounds(B, d, w):  # pragma: no cover - compiled
    """The three polynomials ``B[d]`` (:func:`bound_table`) at ``w``, by Horner in one
    loop (three loops took 4 % more of the scan)."""
    a0, a1, a2 = B[d, 0, 0], B[d, 1, 0], B[d, 2, 0]
    for j in range(1, B.shape[2]):
        a0 = a0 * w + B[d, 0, j]
        a1 = a1 * w + B[d, 1, j]
        a2 = a2 * w + B[d, 2, j]
    return a0, a1, a2


def bound_table(major: np.ndarray, b3N: np.ndarray, b3D: np.ndarray) -> np.ndarray:
    """The scan's bounds per design (``(designs, 3, powers)``, :func:`descending`, the
    shorter ones led by zeros, which leave Horner's values as they are): the rounding
    majorant of ``N`` and ``D`` together (:func:`seactl.diagram.blockdiagram.rounding_majorant`)
    and the third-derivative bounds of ``N`` and of ``D``
    (:attr:`~seactl.diagram.blockdiagram.QuasiPolynomial.bound3_coeffs`), all ascending."""
    parts = (major, b3N, b3D)
    n = max(x.shape[-1] for x in parts)
    out = np.zeros((major.shape[0], 3, n))  # (one pass per part, no padded copies)
    for i, x in enumerate(parts):
        out[:, i, n - x.shape[-1]:] = x[:, ::-1]
    return out


def band_table(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Per design, the band ``lo < |L| < hi`` whose phase crossings the scan certifies
    (outside it, an interval may hold phase crossings unseen), as rows
    ``(lo, hi, log lo, log hi)``: the logarithms taken once, not per interval."""
    lo, hi = (np.asarray(x, float) for x in np.broadcast_arrays(lo, hi))
    with np.errstate(divide="ignore"):
        return np.ascontiguousarray(np.stack([lo, hi, np.log(lo), np.log(hi)], axis=-1))


def descending(c: np.ndarray) -> np.ndarray:
    """Coefficients (last axis: ascending powers) in the kernels' order, descending: the
    Horner loops then count up from 0, and an index LLVM can prove non-negative skips
    numba's negative-index check (5 % of the scan)."""
    return np.ascontiguousarray(c[..., ::-1], float)


def compact(q) -> tuple[np.ndarray, np.ndarray]:
    """A flat quasi-polynomial's coefficients (:func:`descending`) and delays without the
    terms and powers that are zero in every design (the compiled evaluation's loops are
    over both)."""
    k = q.coeffs.shape[0]
    terms = (q.coeffs.reshape(k, -1) != 0).any(axis=1)
    terms[0] |= not terms.any()
    # (a sum of moduli is 0 only where all are: one reduction instead of numpy's any()
    # over the designs' few powers)
    powers = np.nonzero(q.abs_coeffs.reshape(-1, q.coeffs.shape[-1]).sum(axis=0) != 0)[0]
    top = powers[-1] + 1 if powers.size else 1
    return descending(q.coeffs[terms, :, :top]), np.ascontiguousarray(q.delays[terms], float)


@njit(cache=True, nogil=True)
def derivatives(coeffs, delays, idx, w):  # pragma: no cover - compiled
    """``Q(jw)``, ``dQ(jw)/dw``, ``d^2 Q(jw)/dw^2`` of designs ``idx`` at ``w`` (pairwise;
    :func:`compact` arrays): shape ``(len(w), 3)``."""
    out = np.empty((w.size, 3), np.complex128)
    for i in range(w.size):
        out[i, 0], out[i, 1], out[i, 2] = _eval(coeffs, delays, idx[i], w[i], 2)
    return out


# Per point, what the certificates of its two intervals need (computed once; B3N, B3D:
# the third-derivative bounds at the point, used by the interval it ends):
W, CN, CD, A_DELTA, A_DDELTA, A_N, A_D, A_DN, A_DD, RE_G, IM_G, LOG_L, ARG_L, RE_L, \
    IM_L, F_N, F_D, RE_N, IM_N, RE_D, IM_D, A_D2DELTA, ERR, B3N, B3D = range(25)
_F = 25


@njit(cache=True, error_model="numpy", inline="always")
def _point(P, i, w, Nc, Nt, Dc, Dt, bounds, d):  # pragma: no cover - compiled
    """Evaluate ``N`` and ``D`` of design ``d`` at ``w`` into row ``i`` of ``P``, with the
    bounds of their third derivatives on ``[0, w]`` (:func:`bound_table`); ``|Delta|`` is
    stored less its rounding bound (:data:`ROUNDING` times the table's majorant), so that
    rounding noise next to a root never certifies."""
    N, dN, d2N, D, dD, d2D = _eval_pair(Nc, Nt, Dc, Dt, Dc.shape[0], d, w, 2)
    delta, d2delta = N + D, d2N + d2D
    aN, aD, adN, adD = _mag4(N, D, dN, dD)
    P[i, CN], P[i, CD], adelta, P[i, A_DDELTA] = _mag4(d2N, d2D, delta, dN + dD)
    # |Q'' Q - Q'^2| = |(log Q)''| |Q|^2, with the cancellation of its two terms
    P[i, A_D2DELTA], P[i, F_N], P[i, F_D], _ = _mag4(d2delta, d2N * N - dN * dN,
                                                    d2D * D - dD * dD, d2delta)
    L = _div(N, D)
    P[i, W] = w
    major, P[i, B3N], P[i, B3D] = _bounds(bounds, d, w)
    P[i, ERR] = ROUNDING * major
    P[i, A_DELTA] = max(adelta - P[i, ERR], 0.0)
    P[i, RE_N], P[i, IM_N], P[i, RE_D], P[i, IM_D] = N.real, N.imag, D.real, D.imag
    P[i, A_N], P[i, A_D], P[i, A_DN], P[i, A_DD] = aN, aD, adN, adD
    # its real part drives log |L|, its imaginary part arg L
    g = _dlog(N, dN, D, dD)
    P[i, RE_G], P[i, IM_G] = g.real, g.imag
    P[i, LOG_L], P[i, RE_L], P[i, IM_L] = np.log(aN / aD), L.real, L.imag
    P[i, ARG_L] = atan2_4(L.imag, 0.0, 0.0, 0.0, L.real, 1.0, 1.0, 1.0)[0]  # (_vecmath)


@njit(cache=True, error_model="numpy", inline="always")
def _points4(P, i, count, w, Nc, Nt, Dc, Dt, bounds, d):  # pragma: no cover - compiled
    """:func:`_point` at the four frequencies of the V4 ``w`` into rows ``i`` to
    ``i + count - 1`` of ``P``, bit for bit: the same operations in the same order, four
    lanes at once (:class:`seactl.certify.vecmath.V4`) where they are arithmetic, lane by lane
    where they branch (divisions, logarithms); the base grid, which knows its points
    ahead, takes them four at a time."""
    Nr, Ni, dNr, dNi, d2Nr, d2Ni, Dr, Di, dDr, dDi, d2Dr, d2Di = _eval_pair4(Nc, Nt, Dc, Dt, d, w)
    aN, aD, adN, adD = _mag_v4(Nr, Ni), _mag_v4(Dr, Di), _mag_v4(dNr, dNi), _mag_v4(dDr, dDi)
    cN, cD = _mag_v4(d2Nr, d2Ni), _mag_v4(d2Dr, d2Di)
    adelta, addelta = _mag_v4(Nr + Dr, Ni + Di), _mag_v4(dNr + dDr, dNi + dDi)
    ad2delta = _mag_v4(d2Nr + d2Dr, d2Ni + d2Di)
    fNr, fNi = _cmul_v4(d2Nr, d2Ni, Nr, Ni)
    gNr, gNi = _cmul_v4(dNr, dNi, dNr, dNi)
    fDr, fDi = _cmul_v4(d2Dr, d2Di, Dr, Di)
    gDr, gDi = _cmul_v4(dDr, dDi, dDr, dDi)
    fN, fD = _mag_v4(fNr - gNr, fNi - gNi), _mag_v4(fDr - gDr, fDi - gDi)
    major, b3N, b3D = _bounds4(bounds, d, w)
    err = ROUNDING * major
    margin = adelta - err
    # (log L)' = (N' D - D' N) / (N D) and L = N / D: divided lane by lane
    ar, ai = _cmul_v4(dNr, dNi, Dr, Di)
    br, bi = _cmul_v4(dDr, dDi, Nr, Ni)
    nr, ni = _cmul_v4(Nr, Ni, Dr, Di)
    ratio = aN / aD
    Lr, Li = Dr, Di  # (lanes past count: any finite values)
    for k in range(count):
        L = _div(complex(lane(Nr, k), lane(Ni, k)), complex(lane(Dr, k), lane(Di, k)))
        g = _div(complex(lane(ar, k) - lane(br, k), lane(ai, k) - lane(bi, k)),
                 complex(lane(nr, k), lane(ni, k)))
        r = i + k
        P[r, RE_L], P[r, IM_L], P[r, RE_G], P[r, IM_G] = L.real, L.imag, g.real, g.imag
        P[r, LOG_L] = np.log(lane(ratio, k))
        P[r, A_DELTA] = max(lane(margin, k), 0.0)
        Lr, Li = with_lane(Lr, k, L.real), with_lane(Li, k, L.imag)
    arg = atan2_v4(Li, Lr)
    for k in range(count):
        r = i + k
        P[r, W], P[r, ARG_L], P[r, ERR] = lane(w, k), lane(arg, k), lane(err, k)
        P[r, CN], P[r, CD], P[r, A_DDELTA] = lane(cN, k), lane(cD, k), lane(addelta, k)
        P[r, A_D2DELTA], P[r, F_N], P[r, F_D] = lane(ad2delta, k), lane(fN, k), lane(fD, k)
        P[r, B3N], P[r, B3D] = lane(b3N, k), lane(b3D, k)
        P[r, RE_N], P[r, IM_N], P[r, RE_D], P[r, IM_D] = \
            lane(Nr, k), lane(Ni, k), lane(Dr, k), lane(Di, k)
        P[r, A_N], P[r, A_D], P[r, A_DN], P[r, A_DD] = \
            lane(aN, k), lane(aD, k), lane(adN, k), lane(adD, k)


@njit(cache=True, inline="always")
def _eval_pair4(Nc, Nt, Dc, Dt, d, w):  # pragma: no cover - compiled
    """:func:`_eval_pair` (order 2, all of ``D``) at the V4 ``w``, its terms grouped as
    there (the sums' order, hence their bits): real and imaginary parts of ``N``,
    ``N'``, ``N''``, then ``D``'s."""
    kn, kd = Nc.shape[0], Dc.shape[0]
    if kn + kd <= 4:
        return _terms4(Nc, Nt, 0, kn, d, w) + _terms4(Dc, Dt, 0, kd, d, w)
    z = splat(0.0)
    Nr = Ni = dNr = dNi = d2Nr = d2Ni = Dr = Di = dDr = dDi = d2Dr = d2Di = z
    for k0 in range(0, kn + kd, 4):
        a = _terms4(Nc, Nt, k0, min(kn, k0 + 4), d, w)
        Nr, Ni, dNr, dNi, d2Nr, d2Ni = Nr + a[0], Ni + a[1], dNr + a[2], dNi + a[3], \
            d2Nr + a[4], d2Ni + a[5]
        b = _terms4(Dc, Dt, max(kn, k0) - kn, min(kn + kd, k0 + 4) - kn, d, w)
        Dr, Di, dDr, dDi, d2Dr, d2Di = Dr + b[0], Di + b[1], dDr + b[2], dDi + b[3], \
            d2Dr + b[4], d2Di + b[5]
    return Nr, Ni, dNr, dNi, d2Nr, d2Ni, Dr, Di, dDr, dDi, d2Dr, d2Di


@njit(cache=True, inline="always")
def _terms4(coeffs, delays, lo, hi, d, w):  # pragma: no cover - compiled
    """:func:`_terms` (order 2) at the V4 ``w``: ``Re, Im`` of ``Q``, ``dQ/dw``,
    ``d^2 Q/dw^2``."""
    z = splat(0.0)
    qr = qi = d1r = d1i = d2r = d2i = z
    for k in range(lo, hi):
        tau = delays[k, d]
        er, ei = splat(1.0), z
        if tau != 0:
            c, s = cis_v4(w * tau)
            er, ei = c, -s
        pr, pi_ = splat(coeffs[k, d, 0]), z
        dpr = dpi = d2pr = d2pi = z
        for j in range(1, coeffs.shape[2]):
            d2pr, d2pi = -d2pi * w + 2 * dpr, d2pr * w + 2 * dpi
            dpr, dpi = -dpi * w + pr, dpr * w + pi_
            pr, pi_ = -pi_ * w + coeffs[k, d, j], pr * w
        qr += pr * er - pi_ * ei
        qi += pr * ei + pi_ * er
        ar, ai = dpr - tau * pr, dpi - tau * pi_
        d1r += ar * er - ai * ei
        d1i += ar * ei + ai * er
        br = d2pr - 2 * tau * dpr + tau * tau * pr
        bi = d2pi - 2 * tau * dpi + tau * tau * pi_
        d2r += br * er - bi * ei
        d2i += br * ei + bi * er
    return qr, qi, -d1i, d1r, -d2r, -d2i


@njit(cache=True, inline="always")
def _bounds4(B, d, w):  # pragma: no cover - compiled
    """:func:`_bounds` at the V4 ``w``."""
    a0, a1, a2 = splat(B[d, 0, 0]), splat(B[d, 1, 0]), splat(B[d, 2, 0])
    for j in range(1, B.shape[2]):
        a0 = a0 * w + B[d, 0, j]
        a1 = a1 * w + B[d, 1, j]
        a2 = a2 * w + B[d, 2, j]
    return a0, a1, a2


@njit(cache=True, inline="always")
def _cmul_v4(ar, ai, br, bi):  # pragma: no cover - compiled
    """numba's complex product (CPython's) of V4 parts."""
    return ar * br - ai * bi, ar * bi + ai * br


@njit(cache=True, inline="always")
def _mag_v4(re, im):  # pragma: no cover - compiled
    """:func:`_mag` lane by lane, the square roots in one vector instruction
    (:func:`seactl.certify.vecmath.sqrt_v4`) where every sum of squares is safe:
    ``1e-290 < |z|^2 < 1e290`` puts ``max(|Re|, |Im|)`` in :func:`_mag`'s range, so the
    bits are :func:`_mag`'s (which takes the rest, NaN too)."""
    s = re * re + im * im
    if all_within(s, 1e-290, 1e290):
        return sqrt_v4(s)
    return v4(_mag(complex(lane(re, 0), lane(im, 0))), _mag(complex(lane(re, 1), lane(im, 1))),
              _mag(complex(lane(re, 2), lane(im, 2))), _mag(complex(lane(re, 3), lane(im, 3))))


@njit(cache=True, error_model="numpy")
def _dlog(N, dN, D, dD):  # pragma: no cover - compiled
    """``(log L)' = N'/N - D'/D`` over one division."""
    return _div(dN * D - dD * N, N * D)


@njit(cache=True, inline="always")
def _mag4(z0, z1, z2, z3):  # pragma: no cover - compiled
    """:func:`_mag_v4` of four complex numbers (a point's eleven moduli, four at a time),
    its range test on the four scalar sums rather than on :func:`_mag_v4`'s vectors."""
    s0 = z0.real * z0.real + z0.imag * z0.imag
    s1 = z1.real * z1.real + z1.imag * z1.imag
    s2 = z2.real * z2.real + z2.imag * z2.imag
    s3 = z3.real * z3.real + z3.imag * z3.imag
    if (1e-290 < s0 < 1e290) & (1e-290 < s1 < 1e290) & (1e-290 < s2 < 1e290) & \
            (1e-290 < s3 < 1e290):
        m = sqrt_v4(v4(s0, s1, s2, s3))
        return lane(m, 0), lane(m, 1), lane(m, 2), lane(m, 3)
    return _mag(z0), _mag(z1), _mag(z2), _mag(z3)


@njit(cache=True)
def _mag(z):  # pragma: no cover - compiled
    """``|z|``: the square root of the squares where they cannot overflow or underflow
    (cheaper than ``hypot``, which scales to avoid them), ``hypot`` elsewhere."""
    m = max(abs(z.real), abs(z.imag))
    if 1e-150 < m < 1e150:
        return math.sqrt(z.real * z.real + z.imag * z.imag)
    return math.hypot(z.real, z.imag)


@njit(cache=True)
def _sup(h, fa, fb, bound):  # pragma: no cover - compiled
    return 0.5 * (fa + fb + h * bound)


@njit(cache=True, error_model="numpy")
def _div(a, b):  # pragma: no cover - compiled
    """``a / b``, with numpy's inf/nan instead of an exception when ``b == 0``."""
    if b == 0:
        return complex(a.real / 0.0, a.imag / 0.0)
    return a / b


@njit(cache=True, error_model="numpy", inline="always")
def _certified(P, a, b, bN, bD, stability_only, no_loop, final, band):  # pragma: no cover
    """``(Delta certified, no unseen gain crossing, no unseen phase crossing)`` for the
    interval between the points in rows ``a`` and ``b`` of ``P`` (step 3 of
    docs/theory/certified-scan.md); ``band``: the design's row of
    :func:`band_table`, the band of ``|L|`` whose phase crossings are certified.  The
    points are passed as row numbers, not as rows: each row view costs numba an atomic
    reference count (the scan spent 20 % of its time in them).  Unless ``final`` (the
    interval cannot be bisected further), the first certificate that fails ends the work:
    the interval is bisected anyway."""
    h = P[b, W] - P[a, W]
    cN = _sup(h, P[a, CN], P[b, CN], bN)  # sup |N''|, |D''|
    cD = _sup(h, P[a, CD], P[b, CD], bD)
    # Delta's path is shorter than a way around 0, or stays in a tube around the chord
    # between its ends (at most h^2/8 sup |Delta''| away) that misses 0: a convex set
    # without 0, so the turn is the principal one
    err = max(P[a, ERR], P[b, ERR])
    ok = h * _sup(h, P[a, A_DDELTA], P[b, A_DDELTA], cN + cD) < P[a, A_DELTA] + P[b, A_DELTA] \
        or _gap(P[a, RE_N] + P[a, RE_D], P[a, IM_N] + P[a, IM_D],
                P[b, RE_N] + P[b, RE_D], P[b, IM_N] + P[b, IM_D]) > \
        0.125 * h * h * _sup(h, P[a, A_D2DELTA], P[b, A_D2DELTA], bN + bD) + err
    if stability_only or no_loop:  # (L = 0: no crossing to certify)
        return ok, True, True
    if not (ok or final):
        return False, False, False
    sN, sD = _sup(h, P[a, A_DN], P[b, A_DN], cN), _sup(h, P[a, A_DD], P[b, A_DD], cD)
    # N and D stay within rN, rD of the chords between their ends (rounding included)
    rN, rD = 0.125 * h * h * cN + err, 0.125 * h * h * cD + err
    gN = _gap(P[a, RE_N], P[a, IM_N], P[b, RE_N], P[b, IM_N])
    gD = _gap(P[a, RE_D], P[a, IM_D], P[b, RE_D], P[b, IM_D])
    # bounds of |N|, |D|: from the ends and sup |Q'|, or from the chord's tube; where
    # |N| and |D| are apart on the whole interval, |L| stays on one side of 1 (and of
    # the band)
    mN, mD = max(0.5 * (P[a, A_N] + P[b, A_N] - h * sN), gN - rN), \
        max(0.5 * (P[a, A_D] + P[b, A_D] - h * sD), gD - rD)
    xN, xD = min(0.5 * (P[a, A_N] + P[b, A_N] + h * sN), max(P[a, A_N], P[b, A_N]) + rN), \
        min(0.5 * (P[a, A_D] + P[b, A_D] + h * sD), max(P[a, A_D], P[b, A_D]) + rD)
    # outside the band throughout: |N|, |D| apart (no gain crossing) and no phase
    # crossing that matters; decided before the paths' lengths, which it spares
    if xN < band[0] * mD or mN > band[1] * xD:
        return ok, True, True
    # sup |Q'' Q - Q'^2| from its ends and (Q'' Q - Q'^2)' = Q''' Q - Q'' Q'
    fN = _sup(h, P[a, F_N], P[b, F_N], bN * xN + cN * sN)
    fD = _sup(h, P[a, F_D], P[b, F_D], bD * xD + cD * sD)
    gain_len, phase_len, hc = _log_lengths(h, P, a, b, cN, cD, sN, sD, mN, mD, fN, fD)
    bow = 0.125 * h * hc
    fa, fb = P[a, LOG_L], P[b, LOG_L]
    pa, pb = P[a, ARG_L], P[b, ARG_L]
    to_axis = 2 * np.pi - abs(pa) - abs(pb)
    same = (fa >= 0) == (fb >= 0)
    # a path that may cross and come back must be long enough, or bend far enough from
    # the chord between the ends (at most bow), or turn back; or |N|, |D| stay apart
    gain_ok = gain_len < abs(fa) + abs(fb) or mN > xD or mD > xN or \
        (same and min(abs(fa), abs(fb)) > bow) or _monotone(P[a, RE_G], P[b, RE_G], hc)
    if not (gain_ok or final):
        return ok, False, False
    # outside the band on the whole interval by the path of log |L| (a NaN anywhere
    # leaves it relevant)
    relevant = not ((fa + gain_len < band[2] and fb + gain_len < band[2]) or
                    (fa - gain_len > band[3] and fb - gain_len > band[3]))
    # (arg L monotone over less than half a turn: on_axis sees its one crossing, if any;
    # the tube, with its four inverse trigonometric functions, is tried last)
    phase_ok = (not relevant) or (phase_len < to_axis) or \
        (phase_len < np.pi and _monotone(P[a, IM_G], P[b, IM_G], hc)) or \
        (not _on_axis(P, a, b) and phase_len < np.pi and _chord_max(pa, pb) + bow < np.pi) or \
        _tube_misses_axis(P, a, b, gN, rN, gD, rD)
    return ok, gain_ok, phase_ok


@njit(cache=True, error_model="numpy")
def _tube_misses_axis(P, a, b, gN, rN, gD, rD):  # pragma: no cover - compiled
    """``arg L = arg N - arg D`` stays off the negative real axis between the points in
    rows ``a`` and ``b``: each of ``N``, ``D`` stays in the tube of radius ``r`` around the
    chord between its ends, whose distance to 0 is ``g`` (a convex set without 0), so its
    argument stays within the chord's angular span widened by ``asin(r / g)``."""
    if not (gN > rN and gD > rD):  # (a tube around 0: any turn)
        return False
    # the range holds arg L at the start widened by asin(r/g) >= r/g on each side: where
    # that alone reaches the axis, the turns are not needed (1 % of the scan)
    if not abs(P[a, ARG_L]) + rN / gN + rD / gD < np.pi:
        return False
    yN, xN = _chord_turn_args(P[a, RE_N], P[a, IM_N], P[b, RE_N], P[b, IM_N])
    yD, xD = _chord_turn_args(P[a, RE_D], P[a, IM_D], P[b, RE_D], P[b, IM_D])
    turnN, turnD, _, _ = atan2_4(yN, yD, 0.0, 0.0, xN, xD, 1.0, 1.0)  # (both in one call)
    loN, hiN = _widened(turnN, gN, rN)
    loD, hiD = _widened(turnD, gD, rD)
    pa = P[a, ARG_L]
    return pa + loN - hiD > -np.pi and pa + hiN - loD < np.pi


@njit(cache=True, error_model="numpy")
def _tube_turn(ar, ai, br, bi, g, r):  # pragma: no cover - compiled
    """Range of the continuous change of ``arg z`` from ``a`` along a path that stays
    within ``r`` of the chord from ``a`` to ``b`` (``g``: the chord's distance to 0)."""
    y, x = _chord_turn_args(ar, ai, br, bi)
    return _widened(atan2_4(y, 0.0, 0.0, 0.0, x, 1.0, 1.0, 1.0)[0], g, r)


@njit(cache=True, inline="always")
def _chord_turn_args(ar, ai, br, bi):  # pragma: no cover - compiled
    """atan2's arguments for the turn from ``a`` to ``b``: ``Im`` and ``Re`` of
    ``b conj(a)``."""
    return ar * bi - ai * br, ar * br + ai * bi


@njit(cache=True, error_model="numpy")
def _widened(turn, g, r):  # pragma: no cover - compiled
    """The chord's span ``[min(0, turn), max(0, turn)]`` widened by ``asin(r / g)``; any
    turn unless ``g > r``."""
    if not g > r:
        return -np.inf, np.inf
    widen = math.asin(r / g)
    return min(0.0, turn) - widen, max(0.0, turn) + widen


@njit(cache=True, error_model="numpy")
def _log_lengths(h, P, a, b, cN, cD, sN, sD, mN, mD, fN, fD):  # pragma: no cover - compiled
    """Bounds of the paths of ``log |L|`` and ``arg L`` between the points in rows ``a``
    and ``b``: ``h`` times bounds of ``|Re (log L)'|`` and ``|Im (log L)'|`` from their
    values at the ends and
    ``|(log L)''| <= |N''|/m_N + (|N'|/m_N)^2 + |D''|/m_D + (|D'|/m_D)^2`` (sups ``cN``,
    ``sN``, ``cD``, ``sD``; ``m`` lower bounds of ``|N|``, ``|D|``).  Infinite where ``N``
    or ``D`` may vanish; each polynomial's term is also bounded by
    ``sup |Q'' Q - Q'^2| / m_Q^2``, which keeps the cancellation between its two parts
    and is the smaller one near a pole or zero of the loop.  Third: ``h`` times that
    bound."""
    if not (mN > 0 and mD > 0):
        return np.inf, np.inf, np.inf
    curv = min(cN / mN + (sN / mN) ** 2, fN / (mN * mN)) + \
        min(cD / mD + (sD / mD) ** 2, fD / (mD * mD))
    return (h * _sup(h, abs(P[a, RE_G]), abs(P[b, RE_G]), curv),
            h * _sup(h, abs(P[a, IM_G]), abs(P[b, IM_G]), curv), h * curv)


@njit(cache=True)
def _gap(ar, ai, br, bi):  # pragma: no cover - compiled
    """Distance from 0 to the segment between the complex numbers ``a`` and ``b``."""
    er, ei = br - ar, bi - ai
    e2 = er * er + ei * ei
    t = 0.0 if not e2 > 0 else min(max(-(ar * er + ai * ei) / e2, 0.0), 1.0)
    return _mag(complex(ar + t * er, ai + t * ei))


@njit(cache=True)
def _monotone(ga, gb, hc):  # pragma: no cover - compiled
    """A derivative ``ga``, ``gb`` at the ends, changing by at most ``hc`` over the
    interval, keeps its sign throughout: the function crosses any level at most once."""
    return ((ga > 0) == (gb > 0)) and abs(ga) + abs(gb) > hc


@njit(cache=True)
def _chord_max(pa, pb):  # pragma: no cover - compiled
    """Largest ``|arg L|`` on the chord from ``pa`` to the continuation of ``pb`` (the
    change of ``arg L`` between them being known to be under ``pi``)."""
    turn = pb - pa
    turn -= 2 * np.pi * np.round(turn / (2 * np.pi))
    return max(abs(pa), abs(pa + turn))


@njit(cache=True)
def _on_axis(P, a, b):  # pragma: no cover - compiled
    """``L`` crosses the negative real axis between the points."""
    return ((P[a, IM_L] >= 0) != (P[b, IM_L] >= 0)) and \
        (P[a, RE_L] * abs(P[b, IM_L]) + P[b, RE_L] * abs(P[a, IM_L]) < 0)


@njit(cache=True)
def _collect(P, a, b):  # pragma: no cover - compiled
    """Crossings of the negative real axis by ``Delta`` between the points in rows ``a``
    and ``b`` (:func:`_cut_turns`), and whether the interval brackets a gain crossing and
    a phase crossing (above ``w = 0``)."""
    cut = _cut_turns(P[a, RE_N] + P[a, RE_D], P[a, IM_N] + P[a, IM_D],
                     P[b, RE_N] + P[b, RE_D], P[b, IM_N] + P[b, IM_D])
    if P[a, W] <= 0:
        return cut, False, False
    return cut, (P[a, LOG_L] >= 0) != (P[b, LOG_L] >= 0), _on_axis(P, a, b)


@njit(cache=True)
def _cut_turns(ar, ai, br, bi):  # pragma: no cover - compiled
    """``c`` with ``arg b - arg a + 2 pi c`` the principal turn from ``a`` to ``b`` (in
    ``[-pi, pi]``; ``arg``: atan2's, in ``(-pi, pi]``): 1 where the short way from ``a`` to
    ``b`` crosses the negative real axis counterclockwise, -1 clockwise, else 0.  The short
    way sweeps a convex sector, which holds the axis exactly when the chord crosses it; on
    the axis itself (``Im = 0``, atan2's signed zeros decide) from the arguments.  Summed
    over a design's intervals, with the arguments at its first and last point, it gives
    the winding with two arctangents instead of one per point."""
    if ai == 0 or bi == 0:
        return -np.round((math.atan2(bi, br) - math.atan2(ai, ar)) / (2 * np.pi))
    if (ai > 0) == (bi > 0) or not ar * abs(bi) + br * abs(ai) < 0:
        return 0.0
    return 1.0 if ai > 0 else -1.0


@njit(cache=True)
def _brackets(out, nout, d, P, a, b, crossing, certified, kind):  # pragma: no cover - compiled
    """Append the bracket of a crossing of ``kind`` between the points in rows ``a`` and
    ``b``; at the bisection limit, where the interval could not be certified free of a pair of
    crossings (a path that touches the level), a touch at its end nearer the level."""
    if crossing:
        return _append(out, nout, d, kind, P, a, b)
    if certified or P[a, W] <= 0:  # (crossings are counted above w = 0)
        return nout
    near = a if abs(_crossing_value(P, a, kind)) <= abs(_crossing_value(P, b, kind)) else b
    return _append(out, nout, d, kind + TOUCH, P, near, near)


ROW = 8
"""Columns of a bracket row (:func:`_append`)."""


@njit(cache=True)
def _append(out, nout, d, kind, P, a, b):  # pragma: no cover - compiled
    """Bracket row: design, kind, the ends' frequencies, crossing functions and their
    derivatives in ``log w``."""
    if nout < out.shape[0]:
        out[nout, 0], out[nout, 1], out[nout, 2], out[nout, 3] = d, kind, P[a, W], P[b, W]
        out[nout, 4] = _crossing_value(P, a, kind)
        out[nout, 5] = _crossing_value(P, b, kind)
        g = RE_G if kind % TOUCH == GAIN else IM_G
        out[nout, 6], out[nout, 7] = P[a, W] * P[a, g], P[b, W] * P[b, g]
    return nout + 1


@njit(cache=True)
def _crossing_value(P, i, kind):  # pragma: no cover - compiled
    """The function whose sign change is the crossing: ``log |L|`` for a gain crossover,
    ``arg(-L)`` for a phase crossover (zero on the negative real axis)."""
    return P[i, LOG_L] if kind % TOUCH == GAIN else math.atan2(-P[i, IM_L], -P[i, RE_L])


@njit(cache=True)
def decade_powers(per_decade, count=256):  # pragma: no cover - compiled
    """``10^(k / per_decade)`` for ``k < count``: the base grid's log points, computed once
    per scan instead of once per point and design (a ``pow`` call each)."""
    out = np.empty(count)
    for k in range(count):
        out[k] = 10.0 ** (k / per_decade)
    return out


@njit(cache=True)
def _decade_power(k, per_decade, powers):  # pragma: no cover - compiled
    """``10^(k / per_decade)``, from ``powers`` (:func:`decade_powers`) where it has it: the
    same ``pow`` call either way."""
    return powers[k] if k < powers.size else 10.0 ** (k / per_decade)


@njit(cache=True)
def grid_point(w_lo, per_decade, powers, step, top, k, base, m):  # pragma: no cover
    """Point ``k`` of a base grid from ``w_lo`` to ``top``: ``per_decade`` points per
    decade, ``w_lo 10^(k / per_decade)`` (exact decades; ``powers``:
    :func:`decade_powers`), until that step would exceed
    ``step``; from the last such point ``base`` on, ``base + m step``.  Returns the point
    (``top`` once reached) and the next ``(k, base, m)``; ``m = 0``: still logarithmic,
    and ``base``, if not 0, is point ``k`` (computed by the previous call: one power per
    point instead of two)."""
    if m == 0:
        w = base if base > 0 else w_lo * _decade_power(k, per_decade, powers)
        nxt = w_lo * _decade_power(k + 1, per_decade, powers)
        if nxt - w <= step:
            return min(w, top), k + 1, nxt, 0
        return min(w, top), k, w, 1
    return min(base + m * step, top), k, base, m + 1


@njit(cache=True, nogil=True)
def scan(Nc, Nt, Dc, Dt, bounds, w_lo, per_decade, step, top, stability_only,
         no_loop, band, winding, uncertain, out, d0, d1):  # pragma: no cover - compiled
    """Certify the base-grid intervals of designs ``d0`` to ``d1 - 1`` (design ``d``'s
    points are 0 and :func:`grid_point` from ``w_lo[d]`` to ``top[d]``), bisecting
    depth-first; ``bounds``: :func:`bound_table`; ``band``: :func:`band_table`.  Writes
    ``winding`` and ``uncertain`` per design and the brackets into ``out`` (rows: design,
    kind, w_lo, w_hi, the crossing function at both, :func:`_crossing_value`, and its
    derivative in ``log w`` at both); returns the number of brackets (more than
    ``len(out)``: call again with room).  Needs ``0 < w_lo < top < inf`` and ``step > 0``.
    """
    cap = MAX_EVALUATIONS + 2 * MAX_BISECTIONS + 2
    P = np.empty((cap + 4, _F))      # the interval stack's points (rows 1-4: a batch)
    stack = np.empty((MAX_BISECTIONS + 2, 3), np.int64)  # (left, right, depth)
    return _scan(Nc, Nt, Dc, Dt, bounds, w_lo, per_decade, step, top, stability_only,
                 no_loop, band, winding, uncertain, out, d0, d1, P, stack,
                 decade_powers(per_decade), np.empty(4))


@njit(cache=True, nogil=True, error_model="numpy")
def _scan(Nc, Nt, Dc, Dt, bounds, w_lo, per_decade, step, top, stability_only,
          no_loop, band, winding, uncertain, out, d0, d1, P, stack, powers,
          ws):  # pragma: no cover - compiled
    """:func:`scan` with its work arrays ``P``, ``stack`` and ``ws``; every array borrowed
    (:mod:`seactl.base.borrow`: no reference counting in the per-point loop).  The base grid's
    points are evaluated four at a time (:func:`_points4`) into rows 1 to 4 of ``P``."""
    Nc, Nt, Dc, Dt, bounds = borrowed(Nc), borrowed(Nt), borrowed(Dc), borrowed(Dt), \
        borrowed(bounds)
    w_lo, step, top, no_loop = borrowed(w_lo), borrowed(step), borrowed(top), borrowed(no_loop)
    band = borrowed(band)
    winding, uncertain, out = borrowed(winding), borrowed(uncertain), borrowed(out)
    P, stack, powers, ws = borrowed(P), borrowed(stack), borrowed(powers), borrowed(ws)
    batch = 1
    nout = 0
    for d in range(w_lo.size):
        if not d0 <= d < d1:  # (a loop from 0 keeps d provably >= 0: indexing twice as fast)
            continue
        evals = 0
        _point(P, 0, 0.0, Nc, Nt, Dc, Dt, bounds, d)
        winding[d] -= _delta_arg(P, 0)   # (plus 2 pi per cut crossing, plus the last arg)
        k, base, m, w = 0, 0.0, 0, 0.0
        filled = used = 0
        while w < top[d]:
            if used == filled:  # the next (up to) four points of the base grid
                filled, used, x = 0, 0, w
                while filled < 4 and x < top[d]:
                    x, k, base, m = grid_point(w_lo[d], per_decade, powers, step[d], top[d],
                                               k, base, m)
                    ws[filled] = x
                    filled += 1
                for j in range(filled, 4):  # (spare lanes: a copy of the last point)
                    ws[j] = x
                _points4(P, batch, filled, v4(ws[0], ws[1], ws[2], ws[3]), Nc, Nt, Dc, Dt,
                         bounds, d)
            # the base interval is [point 0, a batch row]; its bisection points from row 5
            right = batch + used
            used += 1
            w = P[right, W]
            stack[0, 0], stack[0, 1], stack[0, 2] = 0, right, 0
            sp, free = 1, 5
            while sp > 0:
                sp -= 1
                ia, ib, depth = stack[sp, 0], stack[sp, 1], stack[sp, 2]
                wa, wb = P[ia, W], P[ib, W]
                final = depth >= MAX_BISECTIONS or evals >= MAX_EVALUATIONS
                ok, gain_ok, phase_ok = _certified(P, ia, ib, P[ib, B3N],
                                                   P[ib, B3D], stability_only,
                                                   no_loop[d], final, band[d])
                if not (ok and gain_ok and phase_ok or final):
                    _point(P, free, 0.5 * (wa + wb), Nc, Nt, Dc, Dt, bounds, d)
                    evals += 1
                    # right half below the left one: the left is certified first
                    stack[sp, 0], stack[sp, 1], stack[sp, 2] = free, ib, depth + 1
                    stack[sp + 1, 0], stack[sp + 1, 1], stack[sp + 1, 2] = ia, free, depth + 1
                    sp += 2
                    free += 1
                    continue
                # out of evaluations: neither the count nor the crossings are certified
                if not ok or ((not (gain_ok and phase_ok)) and depth < MAX_BISECTIONS):
                    uncertain[d] = True
                cut, gain, phase = _collect(P, ia, ib)
                winding[d] += 2 * np.pi * cut
                if not stability_only:
                    nout = _brackets(out, nout, d, P, ia, ib, gain, gain_ok, GAIN)
                    nout = _brackets(out, nout, d, P, ia, ib, phase, phase_ok, PHASE)
            for c in range(_F):  # (a row copy, no view: see _certified)
                P[0, c] = P[right, c]
        winding[d] += _delta_arg(P, 0)
    return nout


@njit(cache=True)
def _delta_arg(P, i):  # pragma: no cover - compiled
    """``arg Delta`` at the point in row ``i``."""
    return math.atan2(P[i, IM_N] + P[i, IM_D], P[i, RE_N] + P[i, RE_D])


@njit(cache=True)
def loop_values(Nc, Nt, Dc, Dt, idx, w):  # pragma: no cover - compiled
    """``L(jw) = N(jw) / D(jw)`` of designs ``idx`` at frequencies ``w`` (pairwise)."""
    out = np.empty(w.size, np.complex128)
    for i in range(w.size):
        N, _, _, D, _, _ = _eval_pair(Nc, Nt, Dc, Dt, Dc.shape[0], idx[i], w[i], 0)
        out[i] = _div(N, D)
    return out


@njit(cache=True)
def delta_values(Nc, Nt, Dc, Dt, w):  # pragma: no cover - compiled
    """``N(jw) + D(jw)`` of each design ``d`` at ``w[d]``."""
    out = np.empty(w.size, np.complex128)
    for d in range(w.size):
        N, _, _, D, _, _ = _eval_pair(Nc, Nt, Dc, Dt, Dc.shape[0], d, w[d], 0)
        out[d] = N + D
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def horner_rows(c, idx, w):  # pragma: no cover - compiled
    """Row ``idx[i]`` of ``c`` (ascending powers) at ``w[i]``, by Horner in numpy
    ``polyval``'s operations and order (the same bits)."""
    out = np.empty(w.size)
    for i in range(w.size):
        out[i] = horner_row(c, idx[i], w[i])
    return out


@njit(cache=True)
def horner_row(c, r, x):  # pragma: no cover - compiled
    """Row ``r`` of ``c`` at ``x`` (:func:`horner_rows`)."""
    acc = c[r, c.shape[1] - 1] + x * 0.0
    for j in range(c.shape[1] - 2, -1, -1):
        acc = c[r, j] + acc * x
    return acc


@njit(cache=True, nogil=True, error_model="numpy")
def cauchy_newton(c, x):  # pragma: no cover - compiled
    """Per design (row of ``c``, ascending powers), the smallest of 8 Newton iterates from
    ``x`` on ``-sum_j c_j w^j`` (by Horner) where it is positive
    (:func:`seactl.certify.cauchy.cauchy_bound`; one compiled pass instead of some hundred numpy
    operations, a ninth of a lone design's margins)."""
    best = x.copy()
    for d in range(x.size):
        xd, bd = x[d], x[d]
        for _ in range(8):
            g, dg = -c[d, c.shape[1] - 1], 0.0
            for j in range(c.shape[1] - 2, -1, -1):
                dg = dg * xd + g
                g = g * xd + -c[d, j]
            if g > 0:
                bd = np_minimum(bd, xd)
            xd = xd - g / dg if dg > 0 else bd
        best[d] = bd
    return best


@njit(cache=True)
def np_minimum(a, b):  # pragma: no cover - compiled
    """numpy's ``minimum``: NaN if either is."""
    if a != a or b != b:
        return a + b
    return a if a <= b else b


@njit(cache=True)
def np_maximum(a, b):  # pragma: no cover - compiled
    """numpy's ``maximum``: NaN if either is."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@njit(cache=True, error_model="numpy")
def _crossing_at(Nc, Nt, Dc, Dt, d, kind, x):  # pragma: no cover - compiled
    """:func:`_crossing_value` at ``w = e^x`` and its derivative in ``x``."""
    w = math.exp(x)
    N, dN, _, D, dD, _ = _eval_pair(Nc, Nt, Dc, Dt, Dc.shape[0], d, w, 1)
    g = _dlog(N, dN, D, dD)
    if kind == GAIN:
        return np.log(_mag(N) / _mag(D)), w * g.real
    L = _div(N, D)
    return math.atan2(-L.imag, -L.real), w * g.imag


@njit(cache=True, error_model="numpy")
def _hermite_root(xl, xr, fl, fr, dl, dr):  # pragma: no cover - compiled
    """A start for Newton's method on a bracket whose end values ``fl``, ``fr`` have
    opposite signs: the root in ``(xl, xr)`` of the cubic matching them and the slopes
    ``dl``, ``dr`` (Newton's method on the cubic kept inside the bracket by bisection, to
    ``1e-6`` of the bracket: the cubic models the function no closer, and Newton's
    method on the function takes it from there; a tighter tolerance only adds steps,
    up to the iteration limit where rounding stalls them); without finite slopes, the
    regula falsi point."""
    h = xr - xl
    t = fl / (fl - fr)
    ml, mr = dl * h, dr * h
    if not (abs(ml) < np.inf and abs(mr) < np.inf):
        return xl + t * h
    lo, hi, neg = 0.0, 1.0, fl < 0
    for _ in range(40):
        t2 = t * t
        p = (2 * t2 * t - 3 * t2 + 1) * fl + (t2 * t - 2 * t2 + t) * ml + \
            (3 * t2 - 2 * t2 * t) * fr + (t2 * t - t2) * mr
        if p == 0:
            break
        if (p < 0) == neg:
            lo = t
        else:
            hi = t
        dp = (6 * t2 - 6 * t) * (fl - fr) + (3 * t2 - 4 * t + 1) * ml + (3 * t2 - 2 * t) * mr
        nt = t - p / dp
        if not lo < nt < hi:  # (NaN too)
            nt = 0.5 * (lo + hi)
        if abs(nt - t) < 1e-6:
            t = nt
            break
        t = nt
    return xl + t * h


@njit(cache=True, error_model="numpy", nogil=True)
def refine(Nc, Nt, Dc, Dt, rows, xatol, xrtol, x):  # pragma: no cover - compiled
    """Solve each bracket of ``rows`` (as :func:`scan` writes them) in ``x = log w`` by
    Newton's method kept inside the bracket (bisection when a step would leave it), to
    ``xatol + xrtol |x|``.  Writes ``x``; NaN where the ends' signs do not bracket."""
    Nc, Nt, Dc, Dt = borrowed(Nc), borrowed(Nt), borrowed(Dc), borrowed(Dt)  # (_borrow)
    for i in range(rows.shape[0]):
        d, kind = int(rows[i, 0]), int(rows[i, 1])
        xl, xr, fl, fr = math.log(rows[i, 2]), math.log(rows[i, 3]), rows[i, 4], rows[i, 5]
        x[i] = xl if fl == 0 else xr if fr == 0 else np.nan
        if not ((fl < 0) != (fr < 0)) or fl == 0 or fr == 0 or fl != fl or fr != fr:
            continue
        xi = _hermite_root(xl, xr, fl, fr, rows[i, 6], rows[i, 7])
        for _ in range(200):
            f, df = _crossing_at(Nc, Nt, Dc, Dt, d, kind, xi)
            if f == 0:
                break
            if (f < 0) == (fl < 0):
                xl, fl = xi, f
            else:
                xr = xi
            step, tol = f / df, xatol + xrtol * abs(xi)
            if abs(step) <= tol:  # converged (xi may be an end of the bracket by now)
                xi -= step
                break
            xi -= step
            if not (xl < xi < xr):  # (also NaN) a step out of the bracket: bisect
                xi = 0.5 * (xl + xr)
                if xr - xl <= tol:
                    break
        x[i] = xi
