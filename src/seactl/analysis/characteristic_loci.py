"""Generalized Nyquist margins of a loop broken at several signals at once.

Breaking a diagram at ``n`` signals ``x_1 .. x_n`` together (each held, then driven)
gives the loop matrix ``L(s)``: ``L_jk = -`` the response at the block feeding ``x_j`` to
a drive at ``x_k``.  Its return difference satisfies
``det(I + L(s)) = Q(s) / Q_cut(s)``, the closed loop's characteristic quasi-polynomial
over the one with the ``n`` signals held (the multivariable form of the return
difference; :func:`loop_matrix` solves the signal-flow graph for ``L``).  The
eigenvalues of ``L(jw)``, the characteristic loci, are the generalized Nyquist plot:
``det(I + L) = prod_i (1 + lambda_i)``, so the closed loop gains a root on the imaginary
axis exactly where a locus passes through -1.

A common factor on every channel, ``c L``, multiplies every locus by ``c``; so

* the phase margin is the smallest common phase rotation ``e^{-j phi}`` that puts a
  locus on -1: at every crossover ``|lambda_i(jw)| = 1`` the margin
  ``180 + arg(lambda_i)`` wrapped to (-180, 180], the one smallest in absolute value
  reported (the SISO convention of :mod:`seactl.analysis.margins`);
* the gain margin is the common gain that does: at every phase crossover (a locus on
  the negative real axis) ``1 / |lambda_i|``, the one closest to 1 in the log sense;
* a delay ``e^{-s t}`` on every channel (a process's latency, when every broken path
  runs through it) rotates every locus by ``-w t``: the delay margin is
  ``min_i ((PM_i mod 360) pi / 180) / w_i`` over the crossovers;
* the smallest singular value of ``I + L(jw)`` over frequency is the distance of the
  return difference from singularity: a perturbation ``L -> L + Delta`` with
  ``sigma_max(Delta) < sigma_min(I + L)`` at every frequency cannot put a root on the
  axis.

Crossings are bracketed on a dense logarithmic grid by sign changes of ``|lambda| - 1``
(crossovers) and ``Im lambda`` (the real axis) along each locus, continued from one
frequency to the next by least total distance, and of their products over the loci
(symmetric in the eigenvalues, so independent of the continuation where two loci come
close), then solved on the exact loop matrix (Brent's method).  A locus touching the
unit circle between two grid points without crossing it is not seen; the stability
verdict does not come from here but from the certified count of the characteristic
quasi-polynomial's roots.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

MatrixFn = Callable[[np.ndarray], np.ndarray]
"""Frequencies ``w`` [rad/s], shape ``(F,)`` -> ``L(jw)``, shape ``(F, n, n)``."""

_XTOL = 1e-14
_CHUNK = 256
_ENUMERATED = 5


def loop_matrix(diagram: Any, design: Any, returns: Sequence[str], breaks: Sequence[str]
                ) -> MatrixFn:
    """The loop matrix of ``diagram`` broken at the signals ``breaks`` together.

    At each frequency the signal-flow graph is solved numerically: with ``A(s)`` the
    blocks' responses (``A[dst, src]``, exact delays) and the exogenous inputs and the
    broken signals held, ``(I - A) x = e_k`` drives break ``k`` alone, and what returns
    is read at ``returns``; no transfer is derived, so the cost grows with the number of
    signals, not with the number of the diagram's cycles.

    Parameters
    ----------
    diagram : seactl.diagram.blockdiagram.BlockDiagram
        The diagram (a single design).
    design : DesignBatch
        The numbers its blocks read.
    returns : sequence of str
        Per break ``x_j``, the signal of the block that feeds ``x_j`` through a unit gain
        (what comes back to the break).
    breaks : sequence of str
        The broken signals, held and driven one at a time.

    Returns
    -------
    callable
        ``w`` [rad/s] -> ``L(jw)`` of shape ``(F, n, n)``, ``L_jk = -returns_j / breaks_k``.
    """
    index = {name: i for i, name in enumerate(diagram.signals)}
    held = set(diagram.inputs) | set(breaks)
    edges = [b for b in diagram.blocks if b.dst not in held]
    size = len(index)
    cell = np.array([index[b.dst] * size + index[b.src] for b in edges], dtype=np.intp)
    response = _responses(edges, design)
    drive = np.zeros((size, len(breaks)))
    drive[[index[x] for x in breaks], np.arange(len(breaks))] = 1.0
    rows = [index[y] for y in returns]

    def at(w: np.ndarray) -> np.ndarray:
        w = np.asarray(w, float).reshape(-1)
        out = np.empty((w.size, len(returns), len(breaks)), complex)
        for lo in range(0, w.size, _CHUNK):
            part = w[lo:lo + _CHUNK]
            a = np.zeros((part.size, size * size), complex)
            np.add.at(a, (slice(None), cell), response(part).T)
            x = np.linalg.solve(np.eye(size) - a.reshape(-1, size, size),
                                np.broadcast_to(drive, (part.size,) + drive.shape))
            out[lo:lo + _CHUNK] = -x[:, rows, :]
        return out
    return at


def _responses(blocks: Sequence[Any], design: Any) -> Callable[[np.ndarray], np.ndarray]:
    """``w`` [rad/s] ``(F,)`` -> every block's response at ``jw``, ``(len(blocks), F)``
    (a single design): the blocks' coefficients read once, their polynomials evaluated
    together (Horner, highest power first, zeros in front of the shorter ones) and their
    delays as ``cos(w T) - j sin(w T)``."""
    def stacked(polys: list[list[float]]) -> np.ndarray:
        out = np.zeros((len(polys), max(len(p) for p in polys)))
        for i, p in enumerate(polys):
            out[i, out.shape[1] - len(p):] = p
        return out

    coeffs = [b.coefficients(design) for b in blocks]
    num = stacked([[float(c) for c in n] for n, _ in coeffs])
    den = stacked([[float(c) for c in d] for _, d in coeffs])
    tau = np.array([0.0 if b.delay is None else float(getattr(design, b.delay))
                    for b in blocks])

    def horner(c: np.ndarray, s: np.ndarray) -> np.ndarray:
        acc = np.broadcast_to(c[:, :1], (c.shape[0], s.size)).astype(complex)
        for k in range(1, c.shape[1]):
            acc = acc * s + c[:, k:k + 1]
        return acc

    def at(w: np.ndarray) -> np.ndarray:
        s = 1j * w
        phase = tau[:, None] * w
        return horner(num, s) / horner(den, s) * (np.cos(phase) - 1j * np.sin(phase))
    return at


@dataclass(frozen=True)
class LociMargins:
    """Generalized Nyquist margins (see the module docstring); angles in degrees, gains
    absolute, frequencies in rad/s, delays in s.

    ``crossover_w``/``crossover_pm_deg``: every gain crossover and its phase margin;
    ``phase_w``/``phase_gain``: every phase crossover and ``1 / |lambda|`` there;
    ``phase_margin_deg``, ``crossover``: the margin smallest in absolute value (``inf``,
    NaN without crossover); ``gain_margin``, ``phase_crossover``; ``delay_margin_s``,
    ``delay_crossing``: the smallest extra common delay and its crossover;
    ``min_return``, ``min_return_w``: the smallest singular value of ``I + L`` (the grid's,
    refined between its neighbours);
    ``omega``, ``loci``: the grid and the eigenvalues there, ``(F, n)``, each column
    continued from the previous frequency by nearest assignment.
    """

    omega: np.ndarray
    loci: np.ndarray
    crossover_w: np.ndarray
    crossover_pm_deg: np.ndarray
    phase_w: np.ndarray
    phase_gain: np.ndarray
    min_return: float
    min_return_w: float

    def _best_pm(self) -> int | None:
        if self.crossover_w.size == 0:
            return None
        return int(np.argmin(np.abs(self.crossover_pm_deg)))

    @property
    def phase_margin_deg(self) -> float:
        i = self._best_pm()
        return float("inf") if i is None else float(self.crossover_pm_deg[i])

    @property
    def crossover(self) -> float:
        i = self._best_pm()
        return float("nan") if i is None else float(self.crossover_w[i])

    @property
    def gain_margin(self) -> float:
        if self.phase_w.size == 0:
            return float("inf")
        return float(self.phase_gain[np.argmin(np.abs(np.log(self.phase_gain)))])

    @property
    def phase_crossover(self) -> float:
        if self.phase_w.size == 0:
            return float("nan")
        return float(self.phase_w[np.argmin(np.abs(np.log(self.phase_gain)))])

    @property
    def _delays(self) -> np.ndarray:
        return np.radians(np.remainder(self.crossover_pm_deg, 360.0)) / self.crossover_w

    @property
    def delay_margin_s(self) -> float:
        return float(self._delays.min()) if self.crossover_w.size else float("inf")

    @property
    def delay_crossing(self) -> float:
        return float(self.crossover_w[np.argmin(self._delays)]) if self.crossover_w.size \
            else float("nan")


def _eig(matrix_at: MatrixFn, w: float) -> np.ndarray:
    return np.linalg.eigvals(matrix_at(np.array([w])))[0]


def _sign_changes(f: np.ndarray) -> np.ndarray:
    """Indices ``i`` where ``f`` changes sign between ``i`` and ``i + 1``."""
    s = np.sign(f)
    return np.flatnonzero(s[:-1] * s[1:] < 0)


def _modulus(lam: np.ndarray) -> Any:
    return np.abs(lam) - 1.0


def _imag(lam: np.ndarray) -> Any:
    return lam.imag


def _continued(lam: np.ndarray) -> np.ndarray:
    """The eigenvalues reordered so that each column moves least between frequencies
    (the permutation of least total distance: among all of them for a few loci, else by
    the assignment algorithm)."""
    from scipy.optimize import linear_sum_assignment

    n = lam.shape[1]
    perms = np.array(list(itertools.permutations(range(n)))) if n <= _ENUMERATED else None
    rows = np.arange(n)
    out = lam.copy()
    for i in range(1, len(out)):
        cost = np.abs(out[i - 1][:, None] - out[i][None, :])
        best = perms[np.argmin(cost[rows, perms].sum(axis=1))] if perms is not None \
            else linear_sum_assignment(cost)[1]
        out[i] = out[i][best]
    return out


def _root(matrix_at: MatrixFn, fn: Callable[[np.ndarray], Any], a: float, b: float,
          value: Callable[[np.ndarray, float], float],
          select: Callable[[np.ndarray, float], complex]) -> tuple[float, complex] | None:
    """Where ``value(eigenvalues, w)`` changes sign in ``[a, b]`` (Brent), and the
    eigenvalue ``select`` chooses there; None if ``fn`` of it is not 0 (the sign change
    was a jump between eigenvalues)."""
    from scipy.optimize import brentq

    def g(w: float) -> float:
        return float(value(_eig(matrix_at, w), w))

    if g(a) * g(b) >= 0:
        return None
    w = float(brentq(g, a, b, xtol=_XTOL * b, rtol=4 * np.finfo(float).eps))
    z = select(_eig(matrix_at, w), w)
    return (w, z) if abs(fn(z)) <= 1e-6 * max(1.0, abs(z)) else None


def _crossings(matrix_at: MatrixFn, omega: np.ndarray, loci: np.ndarray,
               fn: Callable[[np.ndarray], Any], wanted: Callable[[np.ndarray], Any]
               ) -> list[tuple[float, complex]]:
    """Every frequency where a locus has ``fn = 0`` (among brackets whose end values
    are ``wanted``), and the locus there: bracketed by sign changes of ``fn`` along each
    continued locus (loci crossing at once) and of ``prod_i fn(lambda_i)`` (an
    order-free check where the continuation swaps loci)."""
    found, seen = [], set()
    for col in range(loci.shape[1]):
        for i in _sign_changes(fn(loci[:, col])):
            a, b, za, zb = omega[i], omega[i + 1], loci[i, col], loci[i + 1, col]
            seen.add(i)
            if not (wanted(za) or wanted(zb)):
                continue

            def near(lam: np.ndarray, w: float, a=a, b=b, za=za, zb=zb) -> complex:
                guess = za + (zb - za) * (w - a) / (b - a)
                return complex(lam[np.argmin(np.abs(lam - guess))])
            found.append(_root(matrix_at, fn, a, b, lambda lam, w, near=near:
                               fn(near(lam, w)), near))
    for i in _sign_changes(np.prod(fn(loci), axis=1)):
        if i in seen or not np.any(wanted(loci[i])):
            continue
        found.append(_root(matrix_at, fn, omega[i], omega[i + 1],
                           lambda lam, w: np.prod(fn(lam)),
                           lambda lam, w: complex(lam[np.argmin(np.abs(fn(lam)))])))
    out: list[tuple[float, complex]] = []
    for w, z in sorted((x for x in found if x is not None), key=lambda x: x[0]):
        if not any(abs(w - v) <= 1e-9 * w and abs(z - y) <= 1e-6 * max(1.0, abs(y))
                   for v, y in out):
            out.append((w, z))
    return out


def loci_margins(matrix_at: MatrixFn, omega: np.ndarray) -> LociMargins:
    """The generalized Nyquist margins of the loop matrix ``matrix_at`` (see the module
    docstring).

    Parameters
    ----------
    matrix_at : callable
        ``w`` [rad/s] -> ``L(jw)`` ``(F, n, n)`` (:func:`loop_matrix`).
    omega : numpy.ndarray
        The increasing grid [rad/s] the crossings are bracketed on.

    Returns
    -------
    LociMargins
    """
    omega = np.asarray(omega, float)
    L = matrix_at(omega)
    loci = _continued(np.linalg.eigvals(L))
    gain = _crossings(matrix_at, omega, loci, _modulus, lambda z: np.ones(np.shape(z), bool))
    cpm = [180.0 - np.remainder(-np.degrees(np.angle(z)), 360.0) for _, z in gain]
    phase = [(w, z) for w, z in _crossings(matrix_at, omega, loci, _imag,
                                           lambda z: np.real(z) < 0) if z.real < 0]
    sv_min, sv_w = _smallest_return(matrix_at, omega, L)
    return LociMargins(omega, loci, np.array([w for w, _ in gain]), np.array(cpm),
                       np.array([w for w, _ in phase]),
                       np.array([1.0 / abs(z) for _, z in phase]), sv_min, sv_w)


def _smallest_return(matrix_at: MatrixFn, omega: np.ndarray, L: np.ndarray
                     ) -> tuple[float, float]:
    """The smallest singular value of ``I + L(jw)`` and where: the grid's smallest,
    refined between its neighbours (bounded Brent)."""
    from scipy.optimize import minimize_scalar

    eye = np.eye(L.shape[-1])

    def sigma(w: float) -> float:
        return float(np.linalg.svd(eye + matrix_at(np.array([w]))[0], compute_uv=False)[-1])

    sv = np.linalg.svd(eye + L, compute_uv=False)[:, -1]
    k = int(np.argmin(sv))
    lo, hi = omega[max(k - 1, 0)], omega[min(k + 1, omega.size - 1)]
    best = minimize_scalar(sigma, bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-10 * hi})
    if best.success and best.fun < sv[k]:
        return float(best.fun), float(best.x)
    return float(sv[k]), float(omega[k])
