"""Certified supremum of ``w |N(jw)| / |Delta(jw)|`` over ``w >= 0``.

The jitter margin ``1 / max_w w |T(jw)|`` (:mod:`seactl.latency.jitter`, ``T = L / (1 + L) =
N / Delta`` for ``L = N / D``, ``Delta = N + D``) is a guarantee only if the maximum is not
underestimated, and a scan can step over a sharp peak.  Given the scan's peak ``P``, this
module proves ``w |N| / |Delta| <= P (1 + EPS)`` for every ``w >= 0``, raising ``P`` where
it meets a larger value:

* beyond ``R`` the leading term of ``Delta`` dominates ``Delta``'s other terms and
  ``w |N| / P`` together (a Cauchy bound, :func:`seactl.certify.cauchy.cauchy_bound`; it needs
  ``w N`` of lower degree than ``Delta``);
* on each interval ``[wa, wb]`` of ``[0, R]``, ``sup |N| <= max(|N(wa)|, |N(wb)|) + h^2/8
  sup |N''|`` (``N`` stays that close to its chord) or the first-order bound from
  ``sup |N'|``, and ``inf |Delta|`` is bounded below the same ways (the chord's distance to
  0 less the tube), with the sups of the derivatives from their values at the ends and
  :attr:`~seactl.diagram.blockdiagram.QuasiPolynomial.bound3_coeffs`, and the rounding of
  :func:`~seactl.diagram.blockdiagram.rounding_majorant`; an interval is certified when
  ``wb sup |N| / inf |Delta| <= P (1 + EPS)``, else bisected (breadth first, every design
  at once).
"""

from __future__ import annotations

import math

import numpy as np

from seactl.base.jit import KernelGroup, njit
from seactl.base.parallel import chunk_size, map_in_threads
from seactl.certify.cauchy import cauchy_bound
from seactl.certify.realpart import bisect
from seactl.certify.scan import compact, derivatives, horner_row, np_maximum, np_minimum
from seactl.diagram.blockdiagram import (
    EVAL_ROUNDING,
    QuasiPolynomial,
    padded_sum,
    rounding_majorant,
)

KERNELS = KernelGroup("jitter peak", about_s=2)
"""The group of this module's kernels (the jitter peak)."""

EPS = 1e-9
"""Relative slack of the proven bound over the largest value found."""
MAX_DEPTH = 40
"""Bisections of a base interval before a design is left unproven."""
MAX_OPEN = 512
"""Uncertified intervals of one design in one round beyond which it is left unproven."""
PER_DECADE = 8
TURN_FRACTION = 0.25
"""Base grid: ``PER_DECADE`` points per decade from ``1e-3 w_ref``, steps of at most this
fraction of a turn of the longest delay, to ``R``."""
MAX_BASE = 20_000
"""Base-grid points of one design (more: unproven)."""
CHUNK_POINTS = 200_000
"""Points evaluated at once (designs in chunks: memory stays bounded)."""

# columns of a point's data
_W, _G, _N0, _N1, _N2, _DR, _DI, _D1, _D2 = range(9)


def _points(arrays: tuple, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per point ``(idx[i], w[i])``: ``w``, ``w |N| / |Delta|``, ``|N|``, ``|N'|``,
    ``|N''|``, ``Delta`` (real, imaginary), ``|Delta'|``, ``|Delta''|`` (``arrays``: the
    compiled evaluation's, :func:`seactl.certify.scan.compact` of ``N`` and ``Delta``)."""
    idx = np.ascontiguousarray(idx, np.intp)
    w = np.ascontiguousarray(w, float)
    n0, n1, n2 = np.abs(derivatives(*arrays[0], idx, w)).T
    d0, d1, d2 = derivatives(*arrays[1], idx, w).T
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(n0 > 0, w * n0 / np.abs(d0), 0.0)
    return np.stack([w, g, n0, n1, n2, d0.real, d0.imag, np.abs(d1), np.abs(d2)], axis=1)


def _upper(N: QuasiPolynomial, Delta: QuasiPolynomial, majors: tuple, d: np.ndarray,
           pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """Upper bounds of ``(w |N| / |Delta|)^2`` on the intervals (inf where ``Delta`` may
    vanish): the smaller of ``(wb sup |N| / inf |Delta|)^2`` and, second order, the larger
    end value plus ``h^2/8 sup |(u/v)''|`` with ``u = w^2 |N|^2``, ``v = |Delta|^2``
    (compiled, :func:`_upper_rows`: one pass over the intervals instead of numpy's
    temporaries)."""
    f8 = lambda x: np.ascontiguousarray(x, float)  # noqa: E731
    return _upper_rows(f8(pa), f8(pb), np.asarray(d, np.intp), f8(N.bound3_coeffs),
                       f8(Delta.bound3_coeffs), f8(majors[0]), f8(majors[1]),
                       _gap(pa, pb))


def _gap(pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """Distance from 0 to the chord between ``Delta(wa)`` and ``Delta(wb)`` (numpy: its
    complex modulus is not ``hypot``'s to the last bit, and the proof's bits stay those
    it had)."""
    a = pa[:, _DR] + 1j * pa[:, _DI]
    e = pb[:, _DR] + 1j * pb[:, _DI] - a
    e2 = np.abs(e) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(e2 > 0, np.clip(-(a.real * e.real + a.imag * e.imag) / e2, 0, 1), 0.0)
    return np.abs(a + t * e)


@njit(cache=True, nogil=True, error_model="numpy")
def _upper_rows(pa, pb, d, b3N, b3D, majN, majD, gap):  # pragma: no cover - compiled
    """:func:`_upper` row by row, in the operations and order of its numpy form (the same
    bits: ``tests/test_jitter.py``)."""
    out = np.empty(d.size)
    for i in range(d.size):
        h, W = pb[i, _W] - pa[i, _W], pb[i, _W]
        # sups of |Q'| and |Q''| from the ends and the third-derivative bound
        C = 0.5 * (pa[i, _N2] + pb[i, _N2] + h * horner_row(b3N, d[i], W))
        S = 0.5 * (pa[i, _N1] + pb[i, _N1] + h * C)
        CD = 0.5 * (pa[i, _D2] + pb[i, _D2] + h * horner_row(b3D, d[i], W))
        SD = 0.5 * (pa[i, _D1] + pb[i, _D1] + h * CD)
        errN = EVAL_ROUNDING * horner_row(majN, d[i], W)
        errD = EVAL_ROUNDING * horner_row(majD, d[i], W)
        aD, bD = math.hypot(pa[i, _DR], pa[i, _DI]), math.hypot(pb[i, _DR], pb[i, _DI])
        X = np_minimum(0.5 * (pa[i, _N0] + pb[i, _N0] + h * S),
                       np_maximum(pa[i, _N0], pb[i, _N0]) + 0.125 * h * h * C) + errN
        Y = np_minimum(0.5 * (aD + bD + h * SD), np_maximum(aD, bD) + 0.125 * h * h * CD) + errD
        m = np_maximum(0.5 * (aD + bD - h * SD), gap[i] - 0.125 * h * h * CD) - errD
        # sups of u, u', u'' and v', v'' (v >= m^2)
        u0, u1 = (W * X) ** 2, 2 * W * X * (X + W * S)
        u2 = 2 * X * X + 8 * W * X * S + 2 * W * W * (S * S + X * C)
        v1, v2 = 2 * Y * SD, 2 * (SD * SD + Y * CD)
        m2 = m * m
        curv = u2 / m2 + (2 * u1 * v1 + u0 * v2) / (m2 * m2) + 2 * u0 * v1 * v1 / (m2 * m2 * m2)
        # the ends' values, their rounding included
        ends = np_maximum(pa[i, _W] * (pa[i, _N0] + errN) / (aD - errD),
                          W * (pb[i, _N0] + errN) / (bD - errD))
        if not (aD > errD and bD > errD):
            ends = np.inf
        second = ends * ends + 0.125 * h * h * curv
        out[i] = np_minimum(u0 / m2, second) if m > 0 else np.inf
    return out


TAIL_SLACK = 1e-2
"""Where ``w |T|`` tends to a constant ``c`` as ``w -> inf`` (``T`` of relative degree 1),
the bound is at least ``c (1 + TAIL_SLACK)``: the tail is then bounded beyond a finite
``R`` (at 0.1 % the proofs of unfiltered torque loops, whose supremum is that limit, need
several hundred points each and some exceed :data:`MAX_OPEN`)."""


def _tail_radius(N: QuasiPolynomial, Delta: QuasiPolynomial, peak: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per design ``(R, P)``: ``w |N| / |Delta| < P`` beyond ``R``, ``P`` the ``peak``
    or, where ``w N`` has the degree ``n`` of ``Delta``, at least ``(1 + TAIL_SLACK)``
    times the limit ``c = b / |a_n|`` (``b``: ``N``'s coefficients of ``s^(n-1)``):
    ``(P |a_n| - b) w^n`` dominates the rest (Cauchy bound).  ``R`` is inf where ``w N``
    has a higher degree (``w |T|`` unbounded)."""

    n, rows = Delta.degree, np.arange(peak.size)
    deg = np.maximum(N.degree, N.delayed_degree) + 1
    aN = padded_sum(np.zeros_like(Delta.abs_coeffs), N.abs_coeffs)
    aN = np.concatenate([np.zeros(aN.shape[:-1] + (1,)), aN], axis=-1)  # w |N|
    lead = np.abs(Delta.coeffs[0, rows, n])
    b = aN[rows, np.minimum(n, aN.shape[-1] - 1)] * (deg == n)
    peak = np.where(deg == n, np.maximum(peak, (1 + TAIL_SLACK) * b / lead), peak)
    aN[rows, np.minimum(n, aN.shape[-1] - 1)] = 0.0
    r = np.full(peak.shape, np.inf)
    i = np.nonzero(deg <= n)[0]
    if i.size:
        major = padded_sum(Delta.abs_coeffs[i], aN[i] / peak[i, None])
        r[i] = cauchy_bound(Delta.take(i), major[:, :Delta.abs_coeffs.shape[-1]],
                            lead[i] - b[i] / peak[i])
    return r, peak


def _base(w_ref: np.ndarray, tau: np.ndarray, top: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Base grids, flat: ``(count, design, w)`` with each design's points 0, then
    ``PER_DECADE`` per decade from ``1e-3 w_ref`` until a step would exceed
    ``TURN_FRACTION`` of a turn of the longest delay, then such steps, to ``top``; none for
    a design that would need more than :data:`MAX_BASE` (``count`` 0)."""
    lo = 1e-3 * w_ref
    r = np.maximum(top, 10 * lo)
    k = np.maximum(1, np.ceil(PER_DECADE * np.log10(r / lo))).astype(int)
    ratio = (r / lo) ** (1.0 / k)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        step = np.where(tau > 0, 2 * np.pi * TURN_FRACTION / tau, np.inf)
        first = np.ceil(np.log(step / (lo * (ratio - 1))) / np.log(ratio))
    i_lin = np.clip(np.nan_to_num(first, nan=0.0, posinf=1e9), 0, k).astype(int)
    w_lin = lo * ratio ** i_lin
    with np.errstate(invalid="ignore"):
        m = np.where(i_lin < k, np.ceil((r - w_lin) / step), 0).astype(int)
    count = np.where(i_lin + 2 + m <= MAX_BASE, i_lin + 2 + m, 0)  # (0: too many, unproven)
    design = np.repeat(np.arange(w_ref.size), count)
    j = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) - 1
    jl, d = j - i_lin[design], design
    w = np.where(jl <= 0, lo[d] * ratio[d] ** np.minimum(j, i_lin[d]),
                 np.minimum(w_lin[d] + jl * np.where(np.isfinite(step[d]), step[d], 0), r[d]))
    return count, design, np.where(j < 0, 0.0, w)


def certify_peak(N: QuasiPolynomial, Delta: QuasiPolynomial, w_ref: np.ndarray,
                 peak: np.ndarray, w_peak: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per design of the flat ``N``, ``Delta`` (a scan found ``peak`` at ``w_peak``):
    ``(bound, w_peak, proven)``, ``bound >= w |N| / |Delta|`` for every ``w >= 0`` where
    proven (``P (1 + EPS)``, ``P`` the largest value found, at ``w_peak``)."""
    n = N.shape[0]
    peak, w_peak = np.array(peak, float), np.array(w_peak, float)
    tau = np.concatenate([N.delays, Delta.delays]).max(axis=0)
    ok = (peak > 0) & np.isfinite(peak)
    top, floor = _tail_radius(N, Delta, np.where(ok, peak, 1.0))
    tail = ok & (floor > peak)  # the supremum may be approached as w -> inf
    peak[tail], w_peak[tail] = floor[tail], top[tail]
    idx = np.nonzero(np.isfinite(top) & ok)[0]
    count, design, w = _base(w_ref[idx], tau[idx], top[idx])
    design = idx[design]
    majors = rounding_majorant(N.abs_coeffs, tau), rounding_majorant(Delta.abs_coeffs, tau)
    arrays = compact(N), compact(Delta)
    proven = np.zeros(n, bool)
    starts = np.cumsum(count) - count
    # chunks of whole designs of about CHUNK_POINTS base points, at least one per thread
    # (chunks are independent: each writes its own designs' peaks; numpy releases the GIL)
    new = np.nonzero(np.diff(starts // chunk_size(count.sum(), CHUNK_POINTS)))[0] + 1
    bounds = np.concatenate([[0], starts[new], [count.sum()]]).astype(int)
    chunks = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    for done in map_in_threads(lambda c: _certify(N, Delta, arrays, majors, design[c], w[c],
                                                  peak, w_peak), chunks):
        proven |= done
    return peak * (1 + EPS), w_peak, proven


def _certify(N: QuasiPolynomial, Delta: QuasiPolynomial, arrays: tuple, majors: tuple,
             d: np.ndarray, w: np.ndarray, peak: np.ndarray, w_peak: np.ndarray) -> np.ndarray:
    """Branch and bound on the base grids ``w`` of designs ``d`` (flat, each design's
    points together); raises ``peak``, ``w_peak`` in place; a mask of the designs whose
    bound is proven."""
    p = _points(arrays, d, w)
    pair = d[:-1] == d[1:]
    pa, pb, d = p[:-1][pair], p[1:][pair], d[:-1][pair]
    failed = np.zeros(N.shape[0], bool)
    seen = np.zeros(N.shape[0], bool)
    seen[d] = True
    for depth in range(MAX_DEPTH + 1):
        for q in (pa, pb):  # a larger value than the scan's: the new peak
            up = q[:, _G] > peak[d]
            if up.any():
                j = np.nonzero(up)[0]
                j = j[np.argsort(q[j, _G])]  # ascending: the largest is written last
                peak[d[j]], w_peak[d[j]] = q[j, _G], q[j, _W]
        todo = ~(_upper(N, Delta, majors, d, pa, pb) <= (peak[d] * (1 + EPS)) ** 2)
        if depth == MAX_DEPTH or not todo.any():
            failed[d[todo]] = True
            break
        d, pa, pb = bisect(d[todo], pa[todo], pb[todo], lambda i, w: _points(arrays, i, w),
                           failed, MAX_OPEN)
    return seen & ~failed
