"""Supremum over the unit circle of ``||F(e^{j theta})||_2`` for a stable discrete-time
``F(z) = C (zI - A)^-1 B + D`` with one output (its H-infinity norm), by level sets.

``gamma > ||D||`` is a singular value of ``F`` at some point of the unit circle iff the
Hamiltonian matrix of the bilinear image ``F_c(s) = F((1 + s)/(1 - s))`` has an eigenvalue
on the imaginary axis (Boyd, Balakrishnan and Kabamba 1989; ``s = j w`` maps to
``theta = 2 atan w``).  So a level ``gamma`` whose matrix has no imaginary eigenvalue is
an upper bound of the supremum (``F`` is continuous on the circle and below ``gamma`` at
one point), and a level that has them yields the frequencies where ``||F||`` crosses it;
the largest value between them raises the lower bound (Bruinsma and Steinbuch 1990,
quadratically convergent).  :func:`discrete_peak` stops at the first level ``(1 + 2 rtol)``
times the largest value found that has no imaginary eigenvalue: the supremum lies
between the two, exactly so in exact arithmetic.

Rounding: the test runs on the balanced matrix (the norm the eigensolver's backward
error is relative to); an eigenvalue counts as imaginary within :data:`AXIS_TOL` of the
axis, far above that error, so a crossing is not lost to rounding; one counted so
without a crossing only costs evaluations (and, when the level cannot be cleared, a
wider level).  A level that clears is then checked on :data:`CHECK_POINTS` angles: a value
above it (an eigenvalue misjudged all the same) restarts the search from there.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.linalg import matrix_balance

__all__ = ["AXIS_TOL", "CHECK_POINTS", "discrete_gain", "discrete_peak"]

AXIS_TOL = 1e-5
"""An eigenvalue ``lam`` with ``|Re lam| <= AXIS_TOL (|lam| + 1e-6 ||H||)`` is on the axis
(``H`` balanced)."""
CHECK_POINTS = 256
"""Angles (log- and linearly spaced) where a cleared level is checked."""
MAX_LEVELS = 60
"""Levels tried before giving up (the bound is then ``inf``)."""


def discrete_gain(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
                  theta: np.ndarray) -> np.ndarray:
    """``||C (e^{j theta} I - A)^-1 B + D||_2`` at each ``theta`` (one system, one output)."""
    theta = np.atleast_1d(np.asarray(theta, float))
    out = np.empty(theta.size)
    for lo in range(0, theta.size, 128):
        z = np.exp(1j * theta[lo:lo + 128])[:, None, None]
        X = np.linalg.solve(z * np.eye(A.shape[0]) - A, np.broadcast_to(B, z.shape[:1] + B.shape))
        out[lo:lo + 128] = np.linalg.norm((C @ X + D)[:, 0, :], axis=-1)
    return out


def _bilinear(A, B, C, D):
    """``F_c(s) = F((1 + s)/(1 - s))`` as ``(Ac, Bc, Cc, Dc)`` (``A`` without eigenvalue -1)."""
    n = A.shape[0]
    inv = np.linalg.inv(np.eye(n) + A)
    r2 = np.sqrt(2.0)
    return inv @ (A - np.eye(n)), r2 * inv @ B, r2 * C @ inv, D - C @ inv @ B


def _crossings(sys_c: tuple, gamma: float) -> np.ndarray:
    """Angles in ``[0, pi]`` of the Hamiltonian's (near-)imaginary eigenvalues at ``gamma``."""
    Ac, Bc, Cc, Dc = sys_c
    Ri = np.linalg.inv(gamma**2 * np.eye(Bc.shape[1]) - Dc.T @ Dc)
    Ah = Ac + Bc @ Ri @ Dc.T @ Cc
    H = np.block([[Ah, Bc @ Ri @ Bc.T],
                  [-Cc.T @ (np.eye(Cc.shape[0]) + Dc @ Ri @ Dc.T) @ Cc, -Ah.T]])
    H, _ = matrix_balance(H)
    lam = np.linalg.eigvals(H)
    on = np.abs(lam.real) <= AXIS_TOL * (np.abs(lam) + 1e-6 * np.linalg.norm(H, 1))
    return np.unique(2 * np.arctan(np.abs(lam.imag[on])))


def _check_grid(start: np.ndarray | None) -> np.ndarray:
    half = CHECK_POINTS // 2
    grid = [np.pi * np.logspace(-6, 0, half), np.linspace(0, np.pi, half)]
    if start is not None:
        s = np.asarray(start, float).ravel()
        grid.append(np.clip(s[:, None] * np.linspace(0.5, 2.0, 32), 0, np.pi).ravel())
    return np.unique(np.concatenate(grid))


def _polish(gain: Callable, probe: np.ndarray, vals: np.ndarray) -> tuple[float, float]:
    """The largest value near the best few probes: each maximized (bounded Brent) between
    its neighbours."""
    from scipy.optimize import minimize_scalar

    order = np.argsort(probe)
    probe, vals = probe[order], vals[order]
    best = int(np.argmax(vals))
    th, val = float(probe[best]), float(vals[best])
    for i in np.argsort(vals)[::-1][:3]:
        lo, hi = probe[max(i - 1, 0)], probe[min(i + 1, probe.size - 1)]
        if hi <= lo:
            continue
        r = minimize_scalar(lambda t: -float(gain(np.array([t]))[0]), bounds=(lo, hi),
                            method="bounded", options={"xatol": 1e-12 * max(hi, 1e-300)})
        if -r.fun > val:
            th, val = float(r.x), float(-r.fun)
    return th, val


def discrete_peak(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
                  rtol: float = 1e-9, start: np.ndarray | None = None,
                  gain: Callable[[np.ndarray], np.ndarray] | None = None
                  ) -> tuple[float, float, float]:
    """``(upper, theta, lower)``: ``||F(e^{j theta'})|| <= upper`` for every ``theta'``,
    ``||F(e^{j theta})|| = lower``, ``upper / lower - 1`` about ``2 rtol`` (more where
    the level had to be widened).  ``A`` must be Schur stable; ``start``: angles [rad]
    near which to look first; ``gain``: a faster evaluation of ``||F(e^{j theta})||``
    (default :func:`discrete_gain`).  ``upper`` is ``inf`` if no level is cleared.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[0.5]]); B = np.array([[1.0]]); C = np.array([[1.0]])
    >>> up, th, lo = discrete_peak(A, B, C, np.zeros((1, 1)))   # 1/(z - 0.5): 2 at z = 1
    >>> round(lo, 12), th, bool(2 <= up <= 2 * (1 + 3e-9))
    (2.0, 0.0, True)
    """
    if gain is None:
        gain = lambda th: discrete_gain(A, B, C, D, th)  # noqa: E731
    eig = np.linalg.eigvals(A)
    theta = np.unique(np.r_[0.0, np.pi, np.abs(np.angle(eig[np.abs(eig) > 0.5])),
                            np.linspace(0, np.pi, 65),
                            [] if start is None else np.asarray(start, float).ravel()])
    vals = gain(theta)
    i = int(np.argmax(vals))
    lower, where = float(vals[i]), float(theta[i])
    if lower == 0.0:
        return 0.0, where, 0.0
    sys_c = _bilinear(A, B, C, D)
    step, checked = 2 * rtol, False
    for _ in range(MAX_LEVELS):
        gamma = lower * (1 + step)
        cross = _crossings(sys_c, gamma)
        if cross.size == 0 and checked:
            return gamma, where, lower
        if cross.size == 0:
            probe, checked = _check_grid(start), True
        else:
            probe = np.r_[cross, 0.5 * (cross[1:] + cross[:-1])]
        vals = gain(probe)
        th, val = _polish(gain, probe, vals)
        if val > lower * (1 + rtol):
            lower, where, step = val, th, 2 * rtol
        elif cross.size:
            # eigenvalues counted on the axis without a crossing there: widen the level
            if val > lower:
                lower, where = val, th
            step *= 2
    return np.inf, where, lower
