"""Stability crossing curves of a characteristic equation with two delays.

The delays ``(tau1, tau2)`` for which ``Delta(s; tau)`` has a root ``s = jw`` on the
imaginary axis (the D-subdivision boundaries; Gu, Niculescu & Chen, J. Math. Anal. Appl.
311, 2005).  For each frequency ``w`` the solutions ``(theta1, theta2)`` on the torus
(:func:`seactl.analysis.torus.torus_solutions`) give the points ``tau_i = (theta_i + 2 pi
k_i) / w``.  Frequencies run over ``[w_lo, w_hi]``, bounds outside which no crossing lies in
the chart (:func:`frequency_bounds`); the grid is refined until consecutive solutions are
matched one to one (a first-order prediction along ``w``), each step moves a curve by at
most :data:`STEP` of the chart, and every interval where solutions appear or vanish (the
curves' turning points) is bisected to a relative width of :data:`END_WIDTH`; where the
resultant has a root near the unit circle, steps are at most :data:`NEAR_STEP` relative
(where a short crossing interval may lie between two frequencies).  Matched solutions
form chains; each chain's copies ``(k1, k2)`` that enter the chart are the branches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seactl.analysis.torus import TWO_PI, TorusPolynomial, angle_distance, torus_solutions
from seactl.errors import InputError

STEP = 0.004
"""Largest move of a curve between two frequencies, as a fraction of the chart's sides."""
NEAR_CIRCLE = 0.05
"""Where the resultant has a root this close to the unit circle but no solution lies on
it, the grid is refined to :data:`NEAR_STEP` (a short crossing interval between two
frequencies passes close to the circle there)."""
NEAR_STEP = 1e-3
END_WIDTH = 1e-11
"""Relative width to which an interval where solutions appear or vanish is bisected."""
START_POINTS = 256
MAX_POINTS = 200_000
MAX_PASSES = 60
MAX_COPIES = 20_000


@dataclass(frozen=True)
class Branch:
    """One crossing curve in the chart: ``tau1_s``, ``tau2_s`` [s] and the crossing
    frequency ``w_rad_s`` [rad/s] along it (its end points may lie just outside the
    chart, so that the curve reaches the chart's edge)."""

    tau1_s: np.ndarray
    tau2_s: np.ndarray
    w_rad_s: np.ndarray


def frequency_bounds(tp: TorusPolynomial, max_s: tuple[float, float]) -> tuple[float, float]:
    """``(w_lo, w_hi)`` [rad/s]: no crossing of the chart ``[0, T1] x [0, T2]`` has a
    frequency outside.  Above ``w_hi`` the undelayed term's modulus exceeds the sum of the
    others' (Cauchy-type bound, one sign change); below ``w_lo`` every ``Delta(jw; tau)``
    with ``tau`` in the chart stays within ``|Delta(0)|`` of ``Delta(0)`` (each term moves by
    at most ``sum_i |c_ji| w^i + |p_j(0)| w tau_j``)."""
    c = tp.coeffs
    undelayed = (tp.a == 0) & (tp.b == 0) & (tp.fixed_s == 0)
    p0 = c[undelayed].sum(axis=0)
    if not np.any(p0):
        raise InputError("delay terms", "no undelayed term", "a retarded equation")
    n = int(np.nonzero(p0)[0].max())
    others = np.abs(c[~undelayed]).sum(axis=0)
    if np.any(others[n:] != 0):
        raise InputError("delay terms", "a neutral equation", "retarded: the delayed terms "
                         "of lower degree in s than the undelayed one")
    g = -(np.abs(p0) + others)[:n + 1]
    g[n] = abs(p0[n])
    w_hi = _positive_root(g) * (1 + 1e-9)
    dc = np.abs(c[:, 1:]).sum(axis=0)
    tau = tp.a * max_s[0] + tp.b * max_s[1] + tp.fixed_s
    h = np.concatenate([[-abs(c[:, 0].sum())], dc])
    with np.errstate(over="ignore"):
        h[1] += float(np.abs(c[:, 0]) @ tau)
    if not np.all(np.isfinite(h)):
        raise InputError("max_s", max_s, "a smaller chart: its delays times the terms' "
                         "coefficients overflow")
    if abs(c[:, 0].sum()) == 0:
        raise InputError("delay terms", "a root at s = 0 for every delay",
                         "a characteristic equation with Delta(0) != 0")
    w_lo = _positive_root(h) * (1 - 1e-9)
    return float(w_lo), float(max(w_hi, w_lo))


def _positive_root(g: np.ndarray) -> float:
    """The positive root of ``sum_i g_i w^i`` (ascending) with one sign change
    (``g_0 <= 0``, the top coefficient > 0)."""
    g = np.trim_zeros(g, "b")
    r = np.roots(g[::-1])
    r = r[(np.abs(r.imag) <= 1e-9 * np.abs(r)) & (r.real > 0)].real
    return float(r.max(initial=0.0))


def _pad(x: np.ndarray, m: int) -> np.ndarray:
    return np.pad(x, ((0, 0), (0, m - x.shape[1])), constant_values=np.nan)


def _velocity(tp: TorusPolynomial, w: np.ndarray, th1: np.ndarray, th2: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """``d theta / d w`` along the solutions (implicit function theorem; 0 where the
    Jacobian is singular, a turning point)."""
    c, dc = tp.grid(w), tp.grid(w, derivative=True)
    t1, t2 = np.nan_to_num(th1), np.nan_to_num(th2)
    _, d1, d2 = tp.evaluate(c, t1, t2)
    Pw = tp.evaluate(dc, t1, t2)[0]
    det = d1.real * d2.imag - d2.real * d1.imag
    with np.errstate(divide="ignore", invalid="ignore"):
        v1 = -(Pw.real * d2.imag - d2.real * Pw.imag) / det
        v2 = -(d1.real * Pw.imag - Pw.real * d1.imag) / det
    return np.nan_to_num(v1, posinf=0, neginf=0), np.nan_to_num(v2, posinf=0, neginf=0)


def match(w: np.ndarray, th1: np.ndarray, th2: np.ndarray, v1: np.ndarray, v2: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """For each step ``i -> i+1``, the solution of ``i+1`` continuing each solution of
    ``i`` (``(F-1, M)``, -1 if none) and whether the step is matched one to one."""
    dw = np.diff(w)[:, None, None]
    p1 = th1[:-1, :, None] + 0.5 * (v1[:-1, :, None] + v1[1:, None, :]) * dw
    p2 = th2[:-1, :, None] + 0.5 * (v2[:-1, :, None] + v2[1:, None, :]) * dw
    d = np.maximum(angle_distance(p1 - th1[1:, None, :]), angle_distance(p2 - th2[1:, None, :]))
    d = np.where(np.isnan(d), np.inf, d)
    nxt = d.argmin(axis=2)
    prv = d.argmin(axis=1)
    best = np.take_along_axis(d, nxt[..., None], axis=2)[..., 0]
    second = np.sort(d, axis=2)[..., 1] if d.shape[2] > 1 else np.full(best.shape, np.inf)
    live = np.isfinite(best)
    mutual = np.take_along_axis(prv, nxt, axis=1) == np.arange(d.shape[1])
    clear = best <= 0.25 * np.minimum(second, np.pi)
    ok = ~live | (mutual & clear)
    count_a = np.isfinite(th1[:-1]).sum(axis=1)
    count_b = np.isfinite(th1[1:]).sum(axis=1)
    one_to_one = ok.all(axis=1) & (count_a == count_b)
    return np.where(live & ok, nxt, -1), one_to_one


def _too_long(w: np.ndarray, th1: np.ndarray, th2: np.ndarray, nxt: np.ndarray,
              max_s: tuple[float, float]) -> np.ndarray:
    """Steps that move some curve by more than :data:`STEP` of the chart."""
    j = np.where(nxt >= 0, nxt, 0)
    dth1 = angle_distance(np.take_along_axis(th1[1:], j, axis=1) - th1[:-1])
    dth2 = angle_distance(np.take_along_axis(th2[1:], j, axis=1) - th2[:-1])
    wm = w[1:, None]
    rel = np.diff(w)[:, None] / wm
    move = np.maximum(dth1 / (wm * max_s[0]), dth2 / (wm * max_s[1])) + rel
    return (np.where(nxt >= 0, move, 0.0) > STEP).any(axis=1)


def sweep(tp: TorusPolynomial, max_s: tuple[float, float]) -> tuple[np.ndarray, ...]:
    """The refined frequency grid and its solutions: ``w (F,)``, ``th1, th2 (F, M)`` and
    the matches ``nxt (F-1, M)``; an empty grid when no crossing lies in the chart."""
    w_lo, w_hi = frequency_bounds(tp, max_s)
    if not w_hi > w_lo:
        return np.zeros(0), np.zeros((0, 1)), np.zeros((0, 1)), np.zeros((0, 1), int)
    w = np.linspace(w_lo, w_hi, START_POINTS)
    th1, th2, near = torus_solutions(tp, w, gap=True)
    for _ in range(MAX_PASSES):
        v1, v2 = _velocity(tp, w, th1, th2)
        nxt, one = match(w, th1, th2, v1, v2)
        bad = ~one | _too_long(w, th1, th2, nxt, max_s)
        bad &= np.diff(w) > END_WIDTH * w[1:]
        close = np.minimum(near[:-1], near[1:]) < NEAR_CIRCLE
        bad |= close & (np.diff(w) > NEAR_STEP * w[1:])
        if not bad.any():
            return w, th1, th2, nxt
        if w.size + bad.sum() > MAX_POINTS:
            break
        new = 0.5 * (w[:-1] + w[1:])[bad]
        n1, n2, n3 = torus_solutions(tp, new, gap=True)
        m = max(th1.shape[1], n1.shape[1])
        w = np.concatenate([w, new])
        order = np.argsort(w, kind="stable")
        w = w[order]
        near = np.concatenate([near, n3])[order]
        th1 = np.concatenate([_pad(th1, m), _pad(n1, m)])[order]
        th2 = np.concatenate([_pad(th2, m), _pad(n2, m)])[order]
    raise InputError("stability chart", "crossing curves not resolved within "
                     f"{MAX_POINTS:,} frequencies", "a smaller chart (max_s) or a system "
                     "whose crossing curves are not degenerate")


def chains(nxt: np.ndarray, live: np.ndarray) -> np.ndarray:
    """``(F, M)`` chain ids: a chain follows one solution from frequency to frequency
    through the matches (-1 where there is no solution)."""
    F, M = live.shape
    ids = np.full((F, M), -1)
    count = 0
    for i in range(F):
        fresh = live[i] & (ids[i] < 0)
        ids[i, fresh] = count + np.arange(fresh.sum())
        count += int(fresh.sum())
        if i + 1 < F:
            j = nxt[i]
            go = (j >= 0) & live[i]
            ids[i + 1, j[go]] = ids[i, go]
    return ids


def crossing_branches(tp: TorusPolynomial, max_s: tuple[float, float]) -> list[Branch]:
    """Every crossing curve inside ``[0, T1] x [0, T2]`` (``max_s`` [s])."""
    w, th1, th2, nxt = sweep(tp, max_s)
    if w.size == 0:
        return []
    live = np.isfinite(th1)
    ids = chains(nxt, live)
    fi, mi = np.nonzero(ids >= 0)
    order = np.lexsort((fi, ids[fi, mi]))
    fi, mi = fi[order], mi[order]
    cut = np.flatnonzero(np.diff(ids[fi, mi])) + 1
    out: list[Branch] = []
    for f, m in zip(np.split(fi, cut), np.split(mi, cut)):
        out += _copies(w[f], np.unwrap(th1[f, m]), np.unwrap(th2[f, m]), max_s, len(out))
    return out


def _copies(w: np.ndarray, u1: np.ndarray, u2: np.ndarray, max_s: tuple[float, float],
            done: int) -> list[Branch]:
    """The copies ``tau_i = (u_i + 2 pi k_i) / w`` of one chain that enter the chart, cut
    into the runs of points inside (each run with one point beyond either end)."""
    lo = (np.ceil((-u1).min() / TWO_PI), np.ceil((-u2).min() / TWO_PI))
    hi = (np.floor((w * max_s[0] - u1).max() / TWO_PI),
          np.floor((w * max_s[1] - u2).max() / TWO_PI))
    count = max(hi[0] - lo[0] + 1, 0.0) * max(hi[1] - lo[1] + 1, 0.0)  # (before any array)
    if count == 0:  # (no copy enters: one range may still be huge, the other empty)
        return []
    if not done + count <= MAX_COPIES:
        raise InputError("max_s", max_s, "a smaller chart: its crossing curves have more than "
                         f"{MAX_COPIES:,} pieces")
    k1, k2 = np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1)
    out = []
    for a in k1:
        t1 = (u1 + TWO_PI * a) / w
        for b in k2:
            t2 = (u2 + TWO_PI * b) / w
            inside = (t1 >= 0) & (t1 <= max_s[0]) & (t2 >= 0) & (t2 <= max_s[1])
            if not inside.any():
                continue
            grown = inside.copy()
            grown[1:] |= inside[:-1]
            grown[:-1] |= inside[1:]
            edges = np.flatnonzero(np.diff(np.concatenate([[0], grown.astype(int), [0]])))
            for s, e in zip(edges[::2], edges[1::2]):
                out.append(Branch(t1[s:e], t2[s:e], w[s:e]))
    return out
