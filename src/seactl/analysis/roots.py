"""Rightmost characteristic roots of delayed block diagrams, with exact delays.

The closed loop of a :class:`~seactl.diagram.blockdiagram.BlockDiagram` has the characteristic
quasi-polynomial ``Delta(s) = sum_k p_k(s) e^{-s tau_k}``
(:meth:`~seactl.diagram.blockdiagram.BlockDiagram.characteristic`, derived from the diagram).
Its roots are found in three steps, for every design of a batch:

1. **Candidates** from a spectral discretization of the delay equation: ``Delta`` is
   the characteristic function of the companion-form system
   ``x' = sum_k A_k x(t - tau_k)``, whose infinitesimal generator on
   ``[-tau_max, 0]`` is collocated at ``N + 1`` Chebyshev points (Breda, Maset and
   Vermiglio, SIAM J. Sci. Comput. 27, 2005; the method of DDE-BIFTOOL and TDS-STABIL).
   Its eigenvalues approximate the rightmost roots with spectral accuracy.
2. **Polish**: each candidate is refined by Newton's method on the exact ``Delta`` and
   accepted only if ``|Delta(s)|`` is below ``1e-9`` of the sum of the moduli of its
   terms (an exact root in floating point).
3. **Convergence**: ``N`` grows (by half, from :data:`START_NODES`) until the rightmost
   roots of two successive discretizations agree to :data:`AGREE_TOL` relative, and
   **completeness** is certified: the argument principle on ``Delta(s + sigma)``
   (:func:`seactl.analysis.margins.count_right_roots`), with ``sigma`` between the last root
   listed and the next one, counts exactly the roots listed right of ``sigma``.  A
   design that never passes both by ``MAX_NODES`` is reported ``converged = False``.
4. **Error bounds**: each listed root gets an inclusion disc that certifiably holds a
   number of roots, multiplicity counted (:func:`seactl.analysis.rootdiscs.inclusion_discs`):
   a simple root a disc of about 1e-9 of its size holding one; roots that gather (a
   multiple root, which Newton and the residual test locate only to about the
   ``m``-th root of the rounding error) one disc holding all of them, reported as a
   cluster.  The stability verdict takes the real parts of those discs into account.

Designs without delay are solved as polynomials (companion eigenvalues, polished).

Examples
--------
>>> import numpy as np
>>> from seactl.systems.rigid.model import RIGID_DIAGRAM, RigidDesign, UT_LINEAR
>>> d = RigidDesign.from_fn(UT_LINEAR, 8.0, T_s=0.0, T_d=0.0, f_v=None)
>>> r = characteristic_roots(RIGID_DIAGRAM, d, count=2)
>>> np.round(r.roots / (2 * np.pi * 8.0), 6)       # critically damped: a double root
array([-1.+0.j, -1.+0.j])
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.analysis.margins import certified_right_roots, check_count_budget, count_right_roots
from seactl.analysis.rootdiscs import inclusion_discs
from seactl.base.parallel import eigvals
from seactl.diagram.blockdiagram import BlockDiagram, QuasiPolynomial, shifted
from seactl.errors import InputError

RESIDUAL_TOL = 1e-9
"""Accept a polished root when ``|Delta(s)| <= RESIDUAL_TOL * sum_k |p_k(s) e^{-s tau_k}|``."""

AGREE_TOL = 1e-7
"""Successive discretizations agree when the rightmost roots move by less than this,
relative to the design's frequency scale."""

NEGLIGIBLE_DELAY = 1e-9
"""A design whose longest delay is below this, relative to its time scale (``1 /`` the
frequency scale), gets its roots from the undelayed polynomial, polished on the exact
equation (the delay moves them by about that fraction, far below :data:`AGREE_TOL`; the
collocation would divide by it, and overflow for a delay of 1e-308 ms)."""

START_NODES = 8
"""First Chebyshev collocation size ``N``; it grows by half until the roots converge."""

MAX_NODES = 240


@dataclass(frozen=True)
class Roots:
    """Rightmost characteristic roots of a design batch.

    Attributes
    ----------
    roots : complex ndarray, shape ``batch + (count,)``
        Roots [rad/s] sorted by decreasing real part, one of each conjugate pair
        (``imag >= 0``); NaN where fewer were found.  A root of a cluster (see
        ``cluster_count``) is listed at the cluster's centre: no point of it is better
        known than its disc.
    spectral_abscissa : ndarray
        Largest real part of all roots [1/s] (negative: stable, and the decay rate).
    nodes : ndarray
        Chebyshev collocation size ``N`` the roots converged at (0: no delay).
    converged : ndarray of bool
        The rightmost roots agreed between two discretizations, the argument principle
        found no other root right of them, and each has an inclusion disc; where False
        the list may miss roots.
    right_half_plane_roots : ndarray of int
        Roots with ``Re s > 0`` by the argument principle on the whole right half-plane
        (:func:`seactl.analysis.margins.count_right_roots`; conjugates counted), whether or not
        the list is complete; -1 where no count is certain (a root on the axis).
    cluster_centre, cluster_radius : ndarray, shape ``batch + (count,)``
        Per listed root, the disc ``|s - centre| <= radius`` [rad/s] that holds it: its
        error bound, certified by the argument principle on the disc's circle
        (:func:`seactl.analysis.rootdiscs.inclusion_discs`).  Roots listed in one disc (a multiple
        root or a tight cluster, which no point locates better) share it.  NaN where no
        disc is certified.
    cluster_count : ndarray of int, shape ``batch + (count,)``
        Roots in that disc, multiplicity counted (1: a simple root; 0 where none).
    """

    roots: np.ndarray
    spectral_abscissa: np.ndarray
    nodes: np.ndarray
    converged: np.ndarray
    right_half_plane_roots: np.ndarray
    cluster_centre: np.ndarray
    cluster_radius: np.ndarray
    cluster_count: np.ndarray

    @property
    def real_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """Per listed root, the bounds [1/s] of the real parts in its disc:
        ``centre.real -+ radius`` (NaN where no disc is certified)."""
        c, r = self.cluster_centre.real, self.cluster_radius
        return c - r, c + r

    @property
    def uncertain(self) -> np.ndarray:
        """No verdict: the right-half-plane count is not certain (a root on the axis), or
        it is 0 and a listed root's disc reaches across the imaginary axis."""
        lo, hi = self.real_interval
        with np.errstate(invalid="ignore"):
            across = ((lo <= 0) & (hi >= 0)).any(axis=-1)
        return (self.right_half_plane_roots < 0) | ((self.right_half_plane_roots == 0) & across)

    @property
    def stable(self) -> np.ndarray:
        """No root in the closed right half-plane by the certified count (not by the roots
        listed, which may be incomplete where not ``converged``), and no listed root's
        disc reaching the imaginary axis (:attr:`uncertain`)."""
        return (self.right_half_plane_roots == 0) & ~self.uncertain

    @property
    def unstable_count(self) -> np.ndarray:
        """Roots with positive real part, conjugates counted twice (among those listed)."""
        r = self.roots
        return np.where(r.real > 0, np.where(r.imag > 0, 2, 1), 0).sum(axis=-1)


def characteristic_roots(diagram: BlockDiagram, design: Any, *, count: int = 6,
                         cut: Sequence[str] = ()) -> Roots:
    """The ``count`` rightmost roots of the diagram's closed loop, per design.

    Parameters
    ----------
    diagram : BlockDiagram
        The loop (e.g. :data:`seactl.systems.sea.loops.SEA_DIAGRAM`,
        :data:`seactl.systems.rigid.model.RIGID_DIAGRAM`).
    design : object
        Design batch of that diagram.
    count : int
        How many roots (conjugate pairs counted once) per design.
    cut : sequence of str
        Signals held at zero (loops left open).

    Returns
    -------
    Roots
    """
    q = diagram.characteristic(tuple(cut)).evaluate(design)
    return quasi_roots(q, count=count, what=f"closed loop of {diagram.name!r}")


def quasi_roots(q: QuasiPolynomial, *, count: int = 6, what: str = "quasi-polynomial"
                ) -> Roots:
    """The ``count`` rightmost roots of a retarded quasi-polynomial, per design.

    Parameters
    ----------
    q : QuasiPolynomial
        Of any batch shape (the shape of the result).
    count : int
        How many roots (conjugate pairs counted once) per design.
    what : str
        What ``q`` is, for the error raised when it is neutral.

    Returns
    -------
    Roots
        As :func:`characteristic_roots`.
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise InputError("count", count, "an integer >= 1 (roots per design)")
    shape = q.shape
    q = q.flat()
    q.require_retarded(what)
    n = q.shape[0]
    out = np.full((n, count), np.nan + 0j)
    nodes, ok = np.zeros(n, int), np.zeros(n, bool)
    scale = frequency_scale(q)
    check_count_budget(q, scale)
    delayed = q.delays.max(axis=0) * scale > NEGLIGIBLE_DELAY
    for deg, dl in {(int(a), bool(b)) for a, b in zip(q.degree, delayed)}:
        idx = np.nonzero((q.degree == deg) & (delayed == dl))[0]
        sub = q.take(idx)
        if not dl:
            r, nd, conv = _polynomial_roots(sub, deg, count), 0, True
        else:
            r, nd, conv = _delay_roots(sub, deg, count, scale[idx])
        out[idx], nodes[idx], ok[idx] = r, nd, conv
    centre, radius, size = inclusion_discs(q, out, scale)
    ok &= ~(np.isfinite(out) & np.isnan(radius)).any(axis=1)
    # (a conjugate-symmetric cluster's centre: on the axis, its imaginary part rounding)
    centre = np.where(np.abs(centre.imag) <= 1e-10 * np.abs(centre), centre.real + 0j, centre)
    centre = np.where(centre.imag < 0, np.conj(centre), centre)
    out = np.where(size > 1, centre, out)  # (a cluster's points locate none of its roots)
    order = np.argsort(np.where(np.isfinite(out), -out.real, np.inf), axis=1, kind="stable")
    out, centre, radius, size = (np.take_along_axis(x, order, axis=1)
                                 for x in (out, centre, radius, size))
    absc = np.nanmax(out.real, axis=1, initial=-np.inf)
    per_root = shape + (count,)
    return Roots(out.reshape(per_root), absc.reshape(shape), nodes.reshape(shape),
                 ok.reshape(shape), certified_right_roots(q, scale).reshape(shape),
                 centre.reshape(per_root), radius.reshape(per_root), size.reshape(per_root))


def frequency_scale(q: QuasiPolynomial) -> np.ndarray:
    """Fujiwara-type root scale ``max_j (sum_k |c_kj| / |a_n|)^{1/(n-j)}`` [rad/s].

    Parameters
    ----------
    q : QuasiPolynomial
        A flat (1-D) batch.

    Returns
    -------
    numpy.ndarray
        Per design [rad/s], at least 1e-12: the scale of the grids of
        :func:`seactl.analysis.margins.certified_right_roots` and of the root finder.
    """
    n = q.degree
    rows = np.arange(n.size)
    lead = np.abs(q.coeffs[0, rows, n])
    j = np.arange(q.coeffs.shape[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(j < n[:, None], (q.abs_coeffs / lead[:, None]) ** (1.0 / (n[:, None] - j)),
                     0.0)
    return np.maximum(r.max(axis=1), 1e-12)


def _monic(q: QuasiPolynomial, n: int, scale: np.ndarray) -> np.ndarray:
    """Coefficients in ``z = s / scale``, divided by the leading one: ``(B, K, n)``."""
    c = q.coeffs[..., : n + 1] * scale[None, :, None] ** np.arange(n + 1)
    c = c / c[0, :, n][None, :, None]
    return np.moveaxis(c[..., :n], 0, 1)


def _polynomial_roots(q: QuasiPolynomial, n: int, count: int) -> np.ndarray:
    """Undelayed designs: the roots of ``sum_k p_k`` (companion eigenvalues, polished)."""
    scale = frequency_scale(q)
    c = _monic(q, n, scale).sum(axis=1)
    comp = np.zeros((c.shape[0], n, n))
    comp[:, np.arange(n - 1), np.arange(1, n)] = 1.0
    comp[:, -1, :] = -c
    cand = eigvals(comp) * scale[:, None]
    return _select(q, _polish(q, cand), count, distinct=False)


def _generator(c: np.ndarray, tau: np.ndarray, N: int) -> np.ndarray:
    """Chebyshev collocation of the infinitesimal generator, ``(B, n(N+1), n(N+1))``.

    ``c``: monic companion coefficients ``(B, K, n)``; ``tau``: scaled delays ``(B, K)``.
    State ``u_j`` at nodes ``theta_j = tau_max (x_j - 1) / 2``, ``x_j = cos(j pi / N)``;
    rows ``j >= 1`` differentiate the interpolant, row block 0 is the equation."""
    B, K, n = c.shape
    tmax = tau.max(axis=1)
    x = np.cos(np.pi * np.arange(N + 1) / N)
    Dm = _cheb_diff(x)
    M = n * (N + 1)
    A = np.zeros((B, M, M))
    eye = np.eye(n)
    blocks = (2.0 / tmax)[:, None, None, None, None] * Dm[None, 1:, None, :, None] * eye[
        None, None, :, None, :]
    A[:, n:, :] = blocks.reshape(B, N * n, M)
    A[:, np.arange(n - 1), np.arange(1, n)] = 1.0
    ell = _lagrange(x, 1.0 - 2.0 * tau / tmax[:, None])  # (B, K, N+1)
    A[:, n - 1, :] = -np.einsum("bkl,bkm->blm", ell, c).reshape(B, M)
    return A


def _cheb_diff(x: np.ndarray) -> np.ndarray:
    """Chebyshev differentiation matrix on the extremal points ``x`` (Trefethen)."""
    N = x.size - 1
    w = np.ones(N + 1)
    w[0] = w[-1] = 2.0
    w *= (-1.0) ** np.arange(N + 1)
    dx = x[:, None] - x[None, :] + np.eye(N + 1)
    D = np.outer(w, 1.0 / w) / dx
    D -= np.diag(D.sum(axis=1))
    return D


def _lagrange(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Barycentric Lagrange basis on the Chebyshev extremal points at ``t`` (any shape)."""
    N = x.size - 1
    w = (-1.0) ** np.arange(N + 1)
    w[0] *= 0.5
    w[-1] *= 0.5
    diff = t[..., None] - x
    hit = np.isclose(diff, 0.0, atol=1e-14)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = w / diff
        ell = terms / terms.sum(axis=-1, keepdims=True)
    on_node = hit.any(axis=-1, keepdims=True)
    return np.where(on_node, hit.astype(float), ell)


def _delay_roots(q: QuasiPolynomial, n: int, count: int, scale: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grow ``N`` until the rightmost polished roots of two discretizations agree and
    the argument principle finds no other root right of them."""
    c = _monic(q, n, scale)
    tau = (q.delays * scale).T
    B = scale.size
    N = START_NODES
    prev = _select(q, _polish(q, _igd_candidates(c, tau, N, scale)), count + 1)
    done, nodes = np.zeros(B, bool), np.full(B, N)
    result = prev.copy()
    while True:
        N_next = int(4 * np.ceil(1.5 * N / 4))
        todo = np.nonzero(~done)[0]
        if N_next > MAX_NODES or todo.size == 0:
            break
        sub = q.take(todo)
        cur = _select(sub, _polish(sub, _igd_candidates(c[todo], tau[todo], N_next,
                                                        scale[todo])), count + 1)
        agree = _agree(prev[todo, :count], cur[:, :count], scale[todo])
        agree[agree] = _complete(sub.take(np.nonzero(agree)[0]), cur[agree], count,
                                 scale[todo][agree])
        result[todo], nodes[todo] = cur, N_next
        done[todo[agree]] = True
        prev[todo] = cur
        N = N_next
    return result[:, :count], nodes, done


def _complete(q: QuasiPolynomial, found: np.ndarray, count: int, scale: np.ndarray
              ) -> np.ndarray:
    """The roots found right of a line ``Re s = sigma`` between the ``count``-th and the
    next one are all there are: the certified count of
    :func:`seactl.analysis.margins.count_right_roots`
    on ``Delta(s + sigma)`` (multiplicity and conjugates counted) equals theirs."""
    if found.shape[0] == 0:
        return np.zeros(0, bool)
    re = found.real
    last = _last_finite(re[:, :count])
    nxt = re[:, count]
    sigma = np.where(np.isfinite(nxt), 0.5 * (last + nxt), last - 0.05 * scale)
    sigma = np.where(np.isfinite(sigma), sigma, -0.05 * scale)
    mult = np.where(found.imag > 0, 2, 1)
    expected = np.where(np.isfinite(re) & (re > sigma[:, None]), mult, 0).sum(axis=1)
    with np.errstate(over="ignore", invalid="ignore"):
        q = shifted(q, sigma)
    # (e^{-sigma tau} overflows for a delay of millions of time constants: not confirmed)
    ok = np.isfinite(q.coeffs).all(axis=(0, 2))
    Z, certain = np.zeros(ok.size, int), np.zeros(ok.size, bool)
    if ok.any():
        Z[ok], certain[ok] = count_right_roots(q.take(np.nonzero(ok)[0]), scale[ok])
    return certain & (Z == expected)


def _last_finite(re: np.ndarray) -> np.ndarray:
    """The smallest finite real part per row (NaN if none)."""
    with np.errstate(invalid="ignore"):
        m = np.where(np.isfinite(re), re, np.inf).min(axis=1)
    return np.where(np.isfinite(m), m, np.nan)


def _igd_candidates(c: np.ndarray, tau: np.ndarray, N: int, scale: np.ndarray) -> np.ndarray:
    ev = eigvals(_generator(c, tau, N)) * scale[:, None]
    return np.where(ev.imag >= -1e-9 * np.abs(ev), ev, np.nan)


def _agree(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> np.ndarray:
    both = np.isfinite(a) & np.isfinite(b)
    same_set = (np.isfinite(a) == np.isfinite(b)).all(axis=1)
    close = np.where(both, np.abs(a - b) <= AGREE_TOL * scale[:, None], True).all(axis=1)
    return same_set & close


def _polish(q: QuasiPolynomial, s: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Newton on the exact ``Delta``, each candidate until its step is below 1e-14 of it
    (converged ones leave the batch: most converge in a few steps, spurious ones never);
    NaN where the residual test fails."""
    s = np.where(np.isfinite(s), s, 0.0)
    flat, design = s.ravel().copy(), np.repeat(np.arange(s.shape[0]), s.shape[1])
    active = np.arange(flat.size)
    for _ in range(iterations):
        # (a candidate far in the left half-plane overflows e^{-s tau}: it fails the
        # residual test below and is dropped)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            f, df = q.take(design[active]).with_derivative(flat[active, None])
            step = np.where(df != 0, f / df, 0.0)[:, 0]
        flat[active] -= np.where(np.isfinite(step), step, 0.0)
        active = active[~(np.abs(step) <= 1e-14 * np.maximum(np.abs(flat[active]), 1.0))]
        if active.size == 0:
            break
    s = flat.reshape(s.shape)
    with np.errstate(over="ignore", invalid="ignore"):
        f = q(s)
        size = _term_size(q, s)
        ok = np.isfinite(f) & np.isfinite(size) & (np.abs(f) <= RESIDUAL_TOL * size)
    return np.where(ok & np.isfinite(s), s, np.nan)


def _term_size(q: QuasiPolynomial, s: np.ndarray) -> np.ndarray:
    """``sum_kj |c_kj| |s|^j |e^{-s tau_k}|``: the scale of ``Delta``'s terms at ``s``."""
    a = np.abs(s)
    c = np.abs(q.coeffs)[..., None, :]
    acc = c[..., -1] + 0 * a
    for j in range(c.shape[-1] - 2, -1, -1):
        acc = acc * a + c[..., j]
    return (acc * np.exp(-s.real * q.delays[..., None])).sum(axis=0)


def _select(q: QuasiPolynomial, s: np.ndarray, count: int, distinct: bool = True
            ) -> np.ndarray:
    """Roots with ``imag >= 0``, the ``count`` rightmost per design, NaN-padded;
    ``distinct``: candidates that polished to the same root count once (the
    discretization's spurious eigenvalues); otherwise only conjugates are dropped."""
    if not distinct:  # all polynomial roots: keep one of each conjugate pair
        s = np.where(s.imag < -1e-10 * np.abs(s), np.nan, s)
    s = np.where(s.imag < 0, np.conj(s), s)
    s = np.where(np.abs(s.imag) <= 1e-10 * np.abs(s), s.real + 0j, s)
    key = np.where(np.isfinite(s), -s.real, np.inf)
    order = np.argsort(key, axis=1, kind="stable")
    s = np.take_along_axis(s, order, axis=1)
    keep = np.isfinite(s)
    if distinct:  # greedy over the candidates, vectorized over designs: one kept
        # candidate per cluster (relative to the root itself: far-left roots of a short
        # delay, 1e11 away, must not merge a cluster near the origin)
        tol = 1e-7 * np.maximum(1.0, np.abs(s))
        for j in range(1, s.shape[1]):
            near = np.abs(s[:, j:j + 1] - s[:, :j]) <= tol[:, j:j + 1]
            keep[:, j] &= ~(near & keep[:, :j]).any(axis=1)
    keep &= np.cumsum(keep, axis=1) <= count
    out = np.full((s.shape[0], count), np.nan + 0j)
    rows, cols = np.nonzero(keep)
    out[rows, np.cumsum(keep, axis=1)[rows, cols] - 1] = s[rows, cols]
    return out
