"""Inclusion discs of the roots of a quasi-polynomial, multiplicity counted.

A point where ``|Delta|`` is small says little about where a root is when roots cluster: next
to a root of multiplicity ``m`` the residual grows like ``|s - s0|^m``, so a point far from
the root can pass any residual test.  What is certain is how many roots a disc holds.  About
a disc's centre ``c``, ``Delta(c + z) = T(z) + R(z)``: ``T`` its Taylor polynomial of order
:data:`ORDER` (each term ``p_k(c + z) e^{-c tau_k} e^{-z tau_k}`` expanded), ``R`` bounded
on ``|z| = r`` by the tail of the majorizing series.  Where ``|T| > |R|`` plus a bound on the
rounding error all along the circle, ``Delta`` and ``T`` have as many roots in the disc
(Rouche's theorem), and that number is the winding of ``T`` along the circle: between two
samples an arc ``h`` apart, ``T`` moves by at most ``h sup |T'|``, so where
``|T_a| + |T_b| - h sup |T'|`` exceeds twice that bound no sample misses a turn, nor a point
where ``|T|`` falls to ``|R|``.  The expansion keeps the cancellation between the terms that
makes ``Delta`` small near a cluster, which a bound on ``|Delta'|`` from the moduli of its
terms does not.  The samples are quadrupled until every arc passes, up to
:data:`MAX_POINTS`.

:func:`inclusion_discs` gives every listed root the smallest disc on a ladder of radii
that certifiably holds a root, and groups the roots that fall in one disc into a cluster:
its centre, radius and count are the error bound of all of them.
"""

from __future__ import annotations

from math import comb, factorial

import numpy as np

from seactl.diagram.blockdiagram import QuasiPolynomial

ORDER = 32
"""Terms of the Taylor polynomial ``T`` about a disc's centre."""

MIN_POINTS = 64
"""Samples on a circle at first."""

MAX_POINTS = 1 << 14
"""Samples on a circle at most: a circle that passes this close to a root is uncertain."""

RADII = 10.0 ** -np.arange(9.0, -0.25, -0.25)
"""Ladder of disc radii, relative to the root's scale ``max(|s|, scale)``: from 1e-9 (a
simple root polished to rounding) by quarter decades to 1."""

CLUSTER_RADII = 10.0 ** -np.arange(3.0, -0.0625, -0.125)
"""Ladder of a re-centred cluster's radii, relative to its first disc's: from 1e-3 by
eighth decades to 1."""

ROUNDING = 1e-13
"""Evaluation error of ``T`` relative to the sum of the moduli of its terms."""


def taylor(q: QuasiPolynomial, centre: np.ndarray, radius: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per disc (design ``i`` of the flat ``q``, centre ``c_i``, radius ``r_i``): the
    Taylor coefficients ``a_m`` (``m < ORDER``) of ``Delta(c + z)``, a bound on the
    remainder ``|Delta(c + z) - T(z)|`` on ``|z| = r``, and one on the sum of the moduli of
    the expansion's terms there (the scale of the rounding error)."""
    c = q.coeffs.astype(complex)                                 # (K, n, J) ascending
    J = c.shape[-1]
    binom = np.array([[comb(j, i) for i in range(J)] for j in range(J)], float)
    power = np.arange(J)[:, None] - np.arange(J)[None, :]        # j - i
    cpow = centre[None, :, None, None] ** np.maximum(power, 0)   # (1, n, J, J)
    shifted = np.einsum("knj,nji->kni", c, binom[None] * np.where(power >= 0, cpow[0], 0))
    with np.errstate(over="ignore", invalid="ignore"):
        e = np.exp(-centre[None, :] * q.delays)                  # (K, n)
    m = np.arange(ORDER)
    inv_fact = np.array([1.0 / factorial(k) for k in range(ORDER + J + 1)])
    series = (-q.delays[..., None]) ** m * inv_fact[:ORDER]     # (K, n, ORDER)
    a = np.zeros(centre.shape + (ORDER,), complex)
    for i in range(J):
        a[:, i:] += np.einsum("kn,kn,knm->nm", e, shifted[..., i], series[..., :ORDER - i])
    tr = q.delays * radius[None, :]                             # (K, n)
    ps = np.abs(shifted) * radius[None, :, None] ** np.arange(J)  # |p~_i| r^i
    i = np.arange(J)
    with np.errstate(over="ignore", invalid="ignore"):
        tail_i = tr[..., None] ** (ORDER - i) * inv_fact[ORDER - i] * np.exp(tr)[..., None]
        tail = (np.abs(e) * (ps * tail_i).sum(axis=-1)).sum(axis=0)
        size = (np.abs(e) * ps.sum(axis=-1) * np.exp(tr)).sum(axis=0)
    return a, tail, size


def roots_in_discs(q: QuasiPolynomial, centre: np.ndarray, radius: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Per disc ``|s - centre_i| < radius_i`` (of design ``i`` of the flat ``q``): the number
    of roots of ``q`` inside (multiplicity counted) and whether that count is certified
    (see the module's docstring); uncertain where the circle passes too close to a root."""
    n = centre.size
    count, certain = np.zeros(n, int), np.zeros(n, bool)
    a, tail, size = taylor(q, centre, radius)
    bound = tail + ROUNDING * size
    k = np.arange(1, ORDER)
    slope = (k * np.abs(a[:, 1:]) * radius[:, None] ** (k - 1)).sum(axis=1)  # sup |T'|
    todo = np.nonzero(np.isfinite(bound) & np.isfinite(slope) & (radius > 0)
                      & np.isfinite(a).all(axis=1))[0]
    points = MIN_POINTS
    while todo.size and points <= MAX_POINTS:
        z = radius[todo, None] * np.exp(2j * np.pi * np.arange(points + 1) / points)
        t = np.zeros(z.shape, complex)
        for j in range(ORDER - 1, -1, -1):
            t = t * z + a[todo, j, None]
        mag = np.abs(t)
        arc = 2 * np.pi * radius[todo] / points
        ok = np.all(mag[:, 1:] + mag[:, :-1] - (arc * slope[todo])[:, None]
                    > 2 * bound[todo, None], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            turn = np.angle(t[:, 1:] / t[:, :-1]).sum(axis=1)
        count[todo[ok]] = np.round(turn[ok] / (2 * np.pi)).astype(int)
        certain[todo[ok]] = True
        todo = todo[~ok]
        points *= 4
    return count, certain


def inclusion_discs(q: QuasiPolynomial, roots: np.ndarray, scale: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per listed root (``roots`` ``(designs, count)``, NaN where none; design ``i`` of the
    flat ``q``; ``scale`` [rad/s] per design): the centre, radius and count of the disc
    that bounds it.  Each root gets the smallest disc of :data:`RADII` around it that
    certifiably holds at least one root; a root inside the disc of a root listed before it
    (to its right) belongs to that disc instead: a cluster, then centred where it is
    tightest (:func:`_recentre`).  Radius NaN and count 0 where no disc of the ladder is
    certified."""
    B, C = roots.shape
    flat = roots.ravel()
    design = np.repeat(np.arange(B), C)
    radius = np.full(flat.size, np.nan)
    count = np.zeros(flat.size, int)
    _smallest_discs(q, design, flat, np.maximum(np.abs(flat), scale[design]), radius, count,
                    np.nonzero(np.isfinite(flat))[0])
    centre = flat.copy().reshape(B, C)
    radius, count = radius.reshape(B, C), count.reshape(B, C)
    head = np.isfinite(radius)
    for j in range(1, C):  # (entries in order: each joins the first earlier disc holding it)
        for i in range(j):
            move = head[:, i] & head[:, j] & (np.abs(roots[:, j] - roots[:, i]) <= radius[:, i])
            centre[move, j], radius[move, j], count[move, j] = \
                centre[move, i], radius[move, i], count[move, i]
            head[move, j] = False
    _recentre(q, centre, radius, count, head, scale)
    return centre, radius, count


def _smallest_discs(q: QuasiPolynomial, design: np.ndarray, centre: np.ndarray,
                    size: np.ndarray, radius: np.ndarray, count: np.ndarray,
                    todo: np.ndarray, wanted: np.ndarray | None = None,
                    ladder: np.ndarray = RADII) -> None:
    """For discs ``todo``: the smallest radius of ``ladder`` times ``size`` whose disc
    about ``centre`` certifiably holds a root (or exactly ``wanted`` roots), written into
    ``radius`` and ``count``."""
    for rel in ladder:
        if todo.size == 0:
            break
        r = rel * size[todo]
        m, ok = roots_in_discs(q.take(design[todo]), centre[todo], r)
        hit = ok & ((m > 0) if wanted is None else (m == wanted[todo]))
        radius[todo[hit]], count[todo[hit]] = r[hit], m[hit]
        todo = todo[~hit]


def _recentre(q: QuasiPolynomial, centre: np.ndarray, radius: np.ndarray,
              count: np.ndarray, head: np.ndarray, scale: np.ndarray) -> None:
    """Clusters (``head`` entries holding more than one root): centred again at the mean of
    the roots of their Taylor polynomial in the disc (a cluster's mean is well conditioned
    where each root is not), and given the smallest disc there that holds the same number
    of roots (:data:`CLUSTER_RADII`), where that is no larger; the cluster's entries
    follow (in place)."""
    rows, cols = np.nonzero(head & (count > 1))
    if rows.size == 0:
        return
    c, r, m = centre[rows, cols], radius[rows, cols], count[rows, cols]
    a, _, _ = taylor(q.take(rows), c, r)
    mean = np.array([_mean_root_inside(a[k], r[k], m[k]) for k in range(rows.size)]) + c
    new_r, new_m = np.full(rows.size, np.nan), np.zeros(rows.size, int)
    ok = np.isfinite(mean)
    _smallest_discs(q, rows, mean, r, new_r, new_m, np.nonzero(ok)[0], m, CLUSTER_RADII)
    better = np.isfinite(new_r) & (new_r <= r)
    for k in np.nonzero(better)[0]:
        same = (centre[rows[k]] == c[k]) & (radius[rows[k]] == r[k])
        centre[rows[k], same], radius[rows[k], same] = mean[k], new_r[k]


def _mean_root_inside(a: np.ndarray, r: float, m: int) -> complex:
    """Mean of the roots of ``sum_k a_k z^k`` with ``|z| < r``, NaN unless there are ``m``."""
    z = np.roots(a[::-1])
    z = z[np.abs(z) < r]
    return complex(z.mean()) if z.size == m else complex(np.nan, np.nan)
