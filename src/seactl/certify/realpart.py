"""Certified sign of ``Re Z(jw)`` on a frequency interval, ``Z = N / (jw D) + b``.

The passivity verdict (:func:`seactl.systems.sea.passivity.passivity`) scans ``Re Z`` on a dense
grid,
which cannot see a band narrower than its spacing.  Where the scan finds none, this module
proves it: ``w |D|^2 Re Z = f(w) = Im(N conj(D)) + b w |D|^2`` has the sign of ``Re Z``,
and an interval ``[wa, wb]`` is certified where ``f > 0`` throughout: ``f`` stays above
its chord less ``h^2/8 sup |f''|``, or ``f'`` keeps its sign (the minimum is at an end).
``sup |f''|`` comes from sups of ``|N|``, ``|N'|``, ``|N''|`` (and ``D``'s), each from its
values at the ends and a bound of the next derivative (the third from
:attr:`seactl.diagram.blockdiagram.QuasiPolynomial.bound3_coeffs`), as in the certified margin
scan.  Intervals that are not certified are bisected, breadth first over every design at
once; one whose point has ``Re Z < 0`` is a band the scan missed.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from seactl.base.parallel import chunk_size, map_in_threads
from seactl.certify.scan import compact, derivatives, horner_rows
from seactl.diagram.blockdiagram import EVAL_ROUNDING, QuasiPolynomial, rounding_majorant

MAX_DEPTH = 40
"""Bisections of a base interval; a design whose intervals are not all certified by then
(``Re Z`` touching 0) is left unproven."""
MAX_OPEN = 256
"""Uncertified intervals of one design in one round of bisection: more (``Re Z`` close to
0 over a whole range, as for a lossless design) and it is left unproven.  A touch point
keeps two or so open per round, so a design costs at most ``MAX_DEPTH * MAX_OPEN``
evaluations beyond its grid."""
CHUNK_POINTS = 200_000
"""Points evaluated at once (designs are certified in chunks of about this many grid
points: memory stays bounded)."""

# columns of a point's data
_W, _F, _DF, _N0, _N1, _N2, _D0, _D1, _D2, _NEG = range(10)


def rows_at(c: np.ndarray, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Polynomials ``c[idx]`` (rows, ascending powers) at ``w`` (one per row; compiled,
    the operations of numpy's ``polyval``: 12 % of the jitter proofs went to its strided
    passes and to the rows' copies)."""
    return horner_rows(np.ascontiguousarray(c, float), np.asarray(idx, np.intp),
                       np.asarray(w, float))


def bisect(d: np.ndarray, pa: np.ndarray, pb: np.ndarray, points: Callable, unresolved:
           np.ndarray, max_open: int, *extra: np.ndarray) -> tuple[np.ndarray, ...]:
    """Halve the intervals of designs ``d`` between the points ``pa``, ``pb`` (rows whose
    column 0 is the frequency; ``points(d, w)`` makes the midpoints): ``(d, pa, pb,
    *extra)`` of the halves.  A design with more than ``max_open`` intervals is marked in
    ``unresolved`` and dropped."""
    keep = ~(np.bincount(d, minlength=unresolved.size)[d] > max_open)
    unresolved[d[~keep]] = True
    d, pa, pb, *extra = (x[keep] for x in (d, pa, pb, *extra))
    mid = points(d, 0.5 * (pa[:, 0] + pb[:, 0]))
    return (np.concatenate([d, d]), np.concatenate([pa, mid]), np.concatenate([mid, pb]),
            *(np.concatenate([x, x]) for x in extra))


def _points(arrays: tuple, b: np.ndarray, idx: np.ndarray, w: np.ndarray, tol: float
            ) -> np.ndarray:
    """Per point ``(idx[i], w[i])``: ``w``, ``f``, ``f'``, ``|N|``, ``|N'|``, ``|N''|``,
    ``|D|``, ``|D'|``, ``|D''|`` and whether ``Re Z < -tol |Z|`` there (derivatives in
    ``w``; ``arrays``: :func:`seactl.certify.scan.compact` of ``N`` and ``D``)."""
    idx = np.ascontiguousarray(idx, np.intp)
    w = np.ascontiguousarray(w, float)
    n0, n1, n2 = derivatives(*arrays[0], idx, w).T
    d0, d1, d2 = derivatives(*arrays[1], idx, w).T
    bi = b[idx]
    dd = (d0 * d0.conj()).real
    f = (n0 * d0.conj()).imag + bi * w * dd
    df = (n1 * d0.conj() + n0 * d1.conj()).imag + bi * (dd + 2 * w * (d1 * d0.conj()).real)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = n0 / (1j * w * d0) + bi
    neg = z.real < -tol * np.abs(z)
    return np.stack([w, f, df, *(np.abs(x) for x in (n0, n1, n2, d0, d1, d2)), neg], axis=1)


def _certified(N: QuasiPolynomial, D: QuasiPolynomial, b: np.ndarray,
               majors: tuple[np.ndarray, np.ndarray], d: np.ndarray, pa: np.ndarray,
               pb: np.ndarray) -> np.ndarray:
    """Intervals (design ``d``, ends ``pa``, ``pb``: rows of :func:`_points`) on which
    ``f > 0`` is proven."""
    h, wb, bd = pb[:, _W] - pa[:, _W], pb[:, _W], b[d]

    def sups(c0: int, bound3: np.ndarray) -> tuple[np.ndarray, ...]:
        c = 0.5 * (pa[:, c0 + 2] + pb[:, c0 + 2] + h * rows_at(bound3, d, wb))
        s = 0.5 * (pa[:, c0 + 1] + pb[:, c0 + 1] + h * c)
        return 0.5 * (pa[:, c0] + pb[:, c0] + h * s), s, c

    xN, sN, cN = sups(_N0, N.bound3_coeffs)
    xD, sD, cD = sups(_D0, D.bound3_coeffs)
    # |f''| <= |N'' D| + 2 |N' D'| + |N D''| + b |(w |D|^2)''|
    m = cN * xD + 2 * sN * sD + xN * cD + bd * (4 * sD * xD + 2 * wb * (sD * sD + cD * xD))
    majD = rows_at(majors[1], d, wb)
    err = EVAL_ROUNDING * (3 * rows_at(majors[0], d, wb) * majD + 4 * bd * wb * majD * majD)
    fa, fb, ga, gb = pa[:, _F], pb[:, _F], pa[:, _DF], pb[:, _DF]
    chord = np.minimum(fa, fb) - 0.125 * h * h * m > err
    monotone = ((ga > 0) == (gb > 0)) & (np.abs(ga) + np.abs(gb) > h * m)
    return (fa > err) & (fb > err) & (chord | monotone)


def certify_positive(N: QuasiPolynomial, D: QuasiPolynomial, b: np.ndarray,
                     w_grid: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_certify_chunk` on chunks of designs of about :data:`CHUNK_POINTS` points,
    at least one per thread, in one thread per core (numpy releases the GIL)."""
    n = N.shape[0]
    if n == 0:
        return np.zeros(0, bool), np.zeros((0, w_grid.size - 1))
    step = chunk_size(n, CHUNK_POINTS // w_grid.size)
    parts = map_in_threads(lambda c: _certify_chunk(N.take(c), D.take(c), b[c], w_grid, tol),
                           [np.arange(a, min(n, a + step)) for a in range(0, n, step)])
    return (np.concatenate([p[0] for p in parts]),
            np.concatenate([p[1] for p in parts]).reshape(n, w_grid.size - 1))


def _certify_chunk(N: QuasiPolynomial, D: QuasiPolynomial, b: np.ndarray,
                   w_grid: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Per design of the flat ``N``, ``D`` (``Z = N / (jw D) + b``), whether
    ``Re Z(jw) > 0`` is proven on ``[w_grid[0], w_grid[-1]]`` (rad/s), and the first
    frequency per base interval of ``w_grid`` found with ``Re Z < -tol |Z|`` (NaN:
    none; shape ``(designs, len(w_grid) - 1)``).  Designs with such a point are not
    proven; neither are those left with uncertified intervals at the limits."""
    n, k = N.shape[0], w_grid.size - 1
    tau = np.concatenate([N.delays, D.delays]).max(axis=0)
    majors = rounding_majorant(N.abs_coeffs, tau), rounding_majorant(D.abs_coeffs, tau)
    arrays = compact(N), compact(D)
    found = np.full((n, k), np.nan)
    d = np.repeat(np.arange(n), w_grid.size)
    grid = _points(arrays, b, d, np.tile(w_grid, n), tol).reshape(n, w_grid.size, -1)
    pa, pb = grid[:, :-1].reshape(n * k, -1), grid[:, 1:].reshape(n * k, -1)
    d, base = np.repeat(np.arange(n), k), np.tile(np.arange(k), n)
    open_ = np.zeros(n, bool)  # designs left with an uncertified interval
    for depth in range(MAX_DEPTH + 1):
        neg = (pa[:, _NEG] > 0) | (pb[:, _NEG] > 0)
        first = neg & np.isnan(found[d, base])
        found[d[first], base[first]] = np.where(pa[first, _NEG] > 0, pa[first, _W],
                                                pb[first, _W])
        todo = ~neg & ~_certified(N, D, b, majors, d, pa, pb) & np.isnan(found[d, base])
        if depth == MAX_DEPTH or not todo.any():
            open_[d[todo]] = True
            break
        d, pa, pb, base = bisect(d[todo], pa[todo], pb[todo],
                                 lambda i, w: _points(arrays, b, i, w, tol), open_, MAX_OPEN,
                                 base[todo])
    proven = ~open_ & np.isnan(found).all(axis=1)
    return proven, found
