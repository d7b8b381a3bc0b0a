"""The sampled-data loop's own verdict, z-plane roots and margins.

The loop is the one ``simulate(..., mode="sampled")`` runs (:mod:`seactl.simulate.engine`):
controllers discretized with Tustin at their process rates, whole-sample delay buffers
(:func:`~seactl.simulate.discrete.buffer_samples`), the continuous plant under a zero-order hold.
Its state map over one period of the slowest process (:func:`~seactl.simulate.period.period_map`,
one tick when all processes share a rate) is a matrix ``A``; the closed loop is stable
when every eigenvalue of ``A`` lies inside the unit circle.

* **Verdict** (:func:`schur_count`): the number of eigenvalues outside the unit circle is
  *certified* by the discrete inertia theorem: a symmetric ``H`` with
  ``H - A^T H A`` positive definite has as many negative eigenvalues as ``A`` has
  eigenvalues outside the unit circle.  ``H`` is computed, the inequality is checked
  with a rigorous floating-point bound on its residual, and the certificate is kept only
  if it holds for every map within a radius of ``A`` well above the rounding of ``A``
  itself; otherwise the verdict is "uncertain" (docs/theory/sampled.md).
* **Margins** (:func:`sampled_margins`, one-rate loops): from the discrete frequency
  response ``L(e^{j w T})`` at a loop break, ``0 < w <= pi/T`` (up to Nyquist).  The
  delay margin ``PM / w_c`` is the continuous extra delay the phase margin allows (exact
  for extra whole samples, ``z^{-k} = e^{-j k w T}``, first order for a fraction of a
  sample); ``delay_margin_samples`` is the number of whole extra samples the loop
  tolerates; the jitter margin bounds a delay varying by whole samples there.  A
  multi-rate loop is periodic, not time-invariant, and has no such frequency response:
  its margins are NaN and ``reason`` says so (the verdict stands).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from seactl.base.limits import check_range, check_sampled_analysis
from seactl.base.parallel import eigvals
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.errors import InputError
from seactl.simulate.discrete import compile_sampled
from seactl.simulate.network import balance_batched
from seactl.simulate.period import period_map

__all__ = ["SampledMargins", "SampledRoots", "schur_count", "sampled_margins",
           "sampled_roots", "broken_responses", "sampled_verdict_text", "rate_text", "verdict_word"]

MAP_TOLERANCE = 64
"""The certificate must hold for every map within ``MAP_TOLERANCE S u ||A||_F`` of the
computed one (``u`` the unit roundoff, ``S`` the state length; in balanced coordinates):
the map's entries are sums of ``S`` products of the plan's matrices, themselves computed
to a few ``u`` (matrix exponential, Tustin coefficients, network solves), so this radius
covers the rounding between the computed map and the exact map of the plan."""

FREQUENCIES = 1200
"""Frequencies per design of the margin scan (log-spaced up to Nyquist)."""

_U = np.finfo(float).eps / 2


def _gamma(k: int) -> float:
    """Higham's ``gamma_k = k u / (1 - k u)``: the relative error bound of a sum or dot
    product of ``k`` terms in floating point."""
    return k * _U / (1 - k * _U)


# ----------------------------------------------------------------------------- verdict
def _stein_eig(M: np.ndarray) -> np.ndarray:
    """``H`` with ``H - M^T H M = I`` from the eigen-decomposition ``M = V diag(l) V^-1``:
    ``H = V^-T G V^-1``, ``G_ij = (V^T V)_ij / (1 - l_i l_j)`` (batched; checked later)."""
    with np.errstate(all="ignore"):
        lam, V = np.linalg.eig(M)
        W = np.linalg.inv(V)
        G = np.swapaxes(V, -1, -2) @ V / (1 - lam[..., :, None] * lam[..., None, :])
        H = (np.swapaxes(W, -1, -2) @ G @ W).real
    return (H + np.swapaxes(H, -1, -2)) / 2


def _stein_scipy(M: np.ndarray) -> np.ndarray:
    """The same ``H`` by scipy's Stein solver, one map (the eigen route's fallback)."""
    from scipy.linalg import solve_discrete_lyapunov

    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            H = solve_discrete_lyapunov(M.T, np.eye(M.shape[0]))
        except (np.linalg.LinAlgError, ValueError):
            return np.full(M.shape, np.nan)
    return (H + H.T) / 2


def _certify(M: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per map, ``(count, radius)``: the certified number of eigenvalues of ``M`` outside
    the unit circle (-1: not certified) and the Frobenius radius around ``M`` the count
    holds for.  See :func:`schur_count`."""
    S = M.shape[-1]
    with np.errstate(all="ignore"):
        MT = np.swapaxes(M, -1, -2)
        R = H - MT @ H @ M - np.eye(S)
        aM, aH = np.abs(M), np.abs(H)
        err = _gamma(2 * S + 2) * (np.swapaxes(aM, -1, -2) @ aH @ aM + aH + np.eye(S))
        r = (np.linalg.norm(R, axis=(-2, -1)) + np.linalg.norm(err, axis=(-2, -1))) \
            * (1 + 1e-6)
        nH = np.linalg.norm(H, axis=(-2, -1))
        nM = np.linalg.norm(M, axis=(-2, -1))
        mu = np.linalg.eigvalsh(np.where(np.isfinite(H).all(axis=(-2, -1))[..., None, None],
                                         H, 0.0))
        # (M+E)^T H (M+E) moves by at most 2|E||H||M| + |E|^2 |H| (2-norms <= Frobenius)
        radius = np.sqrt(nM**2 + np.maximum(1 - r, 0) / nH) - nM
    ok = (np.isfinite(r) & (r < 1) & np.isfinite(nH)
          & (np.min(np.abs(mu), axis=-1) > 100 * S * _U * nH)
          & (radius > MAP_TOLERANCE * S * _U * np.maximum(nM, 1.0)))
    count = np.where(ok, np.sum(mu < 0, axis=-1), -1)
    return count, np.where(ok, radius, 0.0)


def _deflate(M: np.ndarray) -> np.ndarray:
    """``M`` with the states that never act on the next state (a zero column, e.g. the
    held actuation the next tick overwrites, or buffer slots no one reads) decoupled: their
    rows and columns set to 0.  With column ``j`` zero, ``M`` is block triangular after a
    permutation, so the spectrum is the rest's plus a 0 for ``j``, as after decoupling;
    repeated while new zero columns appear."""
    M = M.copy()
    gone = np.zeros(M.shape[:-1], bool)
    for _ in range(M.shape[-1]):
        new = np.all(M == 0, axis=-2) & ~gone
        if not new.any():
            break
        gone |= new
        M[gone[..., :, None] & np.ones(M.shape, bool)] = 0.0
    return M


def schur_count(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Certified number of eigenvalues outside the unit circle of each map ``M (n, S, S)``.

    The discrete inertia theorem (Stein's equation; Lancaster & Tismenetsky, *The Theory of
    Matrices*, sec. 13.2): if ``H = H^T`` and ``H - M^T H M`` is positive definite, ``M``
    has no eigenvalue on the unit circle and as many outside it as ``H`` has negative
    eigenvalues.  ``H`` solves ``H - M^T H M = I`` (eigen-decomposition, scipy's solver
    where that fails the check); the residual ``R`` is bounded rigorously (its computed
    norm plus Higham's ``gamma`` bound on the rounding of ``M^T H M``); ``||R|| < 1`` proves
    the inequality, the signs of ``H``'s eigenvalues are kept only above their rounding
    bound, and the inequality must survive every perturbation of ``M`` up to
    ``MAP_TOLERANCE S u ||M||_F``.  Returns ``(count, radius)`` per map: ``count = -1`` where
    no certificate was found ("uncertain"), ``radius`` the Frobenius distance from ``M``
    within which every map has the same count.

    Examples
    --------
    >>> import numpy as np
    >>> M = np.array([[[0.5, 1.0], [0.0, -0.9]], [[1.2, 0.0], [0.3, 0.1]]])
    >>> schur_count(M)[0].tolist()
    [0, 1]
    """
    M = _deflate(np.asarray(M, float))
    d = balance_batched(M)      # powers of two: an exact similarity
    M = M * d[..., None, :] / d[..., :, None]
    count, radius = _certify(M, _stein_eig(M))
    for i in np.flatnonzero(count < 0):
        if np.all(np.isfinite(M[i])):
            c, r = _certify(M[i:i + 1], _stein_scipy(M[i])[None])
            count[i], radius[i] = c[0], r[0]
    return count, radius


def verdict_word(count: Any) -> np.ndarray:
    """``"stable"`` (0), ``"unstable"`` (> 0) or ``"uncertain"`` (-1), per design."""
    c = np.asarray(count)
    return np.where(c == 0, "stable", np.where(c > 0, "unstable", "uncertain"))


# ----------------------------------------------------------------------------- the plan
def _rate(name: str, value: Any) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise InputError(name, value, "a rate [Hz] or a mapping process -> rate [Hz]")
    return check_range(name, value, "rate_hz")


def _rates_of(rates_hz: Any) -> dict[str, float] | float:
    """``rates_hz`` checked: a number, or a mapping process -> rate, each in range."""
    if isinstance(rates_hz, Mapping):
        return {str(p): _rate(f"rate_hz ({p})", r) for p, r in rates_hz.items()}
    return _rate("rate_hz", rates_hz)


def _plan(diagram: BlockDiagram, design: Any, rates_hz: Any, outputs: tuple[str, ...]) -> Any:
    return compile_sampled(diagram, design, {}, 1e-6, outputs, rates_hz=_rates_of(rates_hz))


def _plant_output(diagram: BlockDiagram) -> str:
    return next(b.dst for b in diagram.blocks if b.role == "plant")


def _core_size(plan: Any) -> int:
    """States of the period map before the delay registers (:func:`period_map`)."""
    return sum(sl.stop - sl.start for sl in (plan.zp["x"], plan.zp["act"], plan.zc["x"],
                                             plan.zc["held"]))


def _maps(plan: Any, inputs: bool) -> tuple[np.ndarray, ...]:
    """:func:`period_map` over the batch in chunks (the probe's memory stays bounded)."""
    n = plan.x0.shape[1]
    J = plan.nbuf.max(axis=1, initial=0)
    S = _core_size(plan) + int(J.sum())
    check_sampled_analysis(n, S, FREQUENCIES if inputs else 0,
                           _core_size(plan) + int(np.count_nonzero(J)),
                           1.0 / plan.base_period_s)
    chunk = max(1, 20_000 // (S + 2))
    parts = [period_map(plan, slice(i, i + chunk), inputs) for i in range(0, n, chunk)]
    out = [np.concatenate([p[j] for p in parts]) for j in range(len(parts[0]) - 1)]
    return (*out, parts[0][-1])


@dataclass(frozen=True)
class SampledRoots:
    """The sampled loop's characteristic roots per design (batch shape first).

    Attributes
    ----------
    z : eigenvalues of the period map, sorted by decreasing ``|z|`` (``shape + (S,)``).
    period_s : the map's period [s] (one tick when all processes share a rate).
    unstable_modes : certified count outside the unit circle, -1 uncertain.
    radius : Frobenius radius around the map within which the count holds.
    rates_hz : the process rates.
    """

    z: np.ndarray
    period_s: float
    unstable_modes: np.ndarray
    radius: np.ndarray
    rates_hz: dict[str, float]

    @property
    def s(self) -> np.ndarray:
        """Equivalent continuous roots ``ln(z) / period`` [1/s] (principal branch)."""
        with np.errstate(divide="ignore"):
            return np.log(self.z.astype(complex)) / self.period_s

    @property
    def verdict(self) -> np.ndarray:
        return verdict_word(self.unstable_modes)

    @property
    def spectral_radius(self) -> np.ndarray:
        return np.abs(self.z[..., 0])

    @property
    def rate_label(self) -> str:
        return rate_text(self.rates_hz)


def sampled_roots(diagram: BlockDiagram, design: Any, rates_hz: Any) -> SampledRoots:
    """Eigenvalues of the sampled loop's period map with the certified verdict.

    Examples
    --------
    >>> import numpy as np
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEA_DIAGRAM, SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, np.array([30.05, 30.2])),
    ...               Timing.from_ms(0.5, 10.5, 0.5, 50, 100))
    >>> r = sampled_roots(SEA_DIAGRAM, d, 1000.0)
    >>> r.verdict.tolist(), r.unstable_modes.tolist()
    (['stable', 'unstable'], [0, 2])
    """
    shape = tuple(getattr(design, "shape", ()))
    plan = _plan(diagram, design, rates_hz, (_plant_output(diagram),))
    A, period = _maps(plan, False)
    count, radius = schur_count(A)
    with np.errstate(all="ignore"):
        ok = np.all(np.isfinite(A), axis=(1, 2))
        z = eigvals(np.where(ok[:, None, None], A, 0.0))
    z = np.where(ok[:, None], z, np.nan)
    z = np.take_along_axis(z, np.argsort(-np.abs(z), axis=-1, kind="stable"), axis=-1)
    # the eigenvalues must agree with the certificate, or the verdict stays open
    agree = np.sum(np.abs(z) > 1, axis=-1) == count
    count = np.where(agree, count, -1)
    return SampledRoots(z.reshape(shape + z.shape[-1:]), period, count.reshape(shape),
                        np.where(agree, radius, 0.0).reshape(shape), dict(plan.info["rates_hz"]))


# ----------------------------------------------------------------------------- margins
@dataclass(frozen=True)
class SampledMargins:
    """Margins and certified verdict of the sampled loop (arrays of the batch shape).

    Attributes
    ----------
    phase_margin_deg, crossover_hz : phase margin at the gain crossover (``|L| = 1``)
        smallest in absolute value, and its frequency (``<=`` Nyquist); ``inf``/NaN
        without crossover.
    gain_margin, phase_crossover_hz : ``1/|L|`` at the phase crossover (``L`` real
        negative, Nyquist included) closest to 1 in the log sense; ``inf``/NaN without.
    delay_margin_s : ``min (PM mod 360) / w_c`` over the gain crossovers [s]: the extra
        continuous loop delay the phase margins allow (exact for whole samples); 0 when
        the loop is unstable, ``inf`` without crossover.
    delay_margin_samples : whole extra samples of delay the loop tolerates
        (``ceil(delay_margin_s / T) - 1``; -1 when unstable).
    jitter_margin_s, jitter_margin_samples : a time-varying extra delay of ``0 .. N``
        whole samples at the break keeps the loop stable for ``N < 1/g``,
        ``g = max |e^{j w T} - 1| |L/(1+L)|`` (small gain: the delay's deviation from the
        undelayed signal is at most ``N`` times the signal's one-step differences);
        ``jitter_margin_samples`` is the largest such ``N`` and ``jitter_margin_s = T/g``
        the bound in seconds (0 / -1 when unstable).  ``g`` is scanned (the grid, then
        finer around its peak), not proven.
    unstable_modes, radius : the certified verdict (:func:`schur_count`).
    stable : ``unstable_modes == 0``.
    rates_hz, period_s : process rates and the period of the map.
    reason : why margins are NaN (a multi-rate loop), else None.
    """

    phase_margin_deg: np.ndarray
    crossover_hz: np.ndarray
    gain_margin: np.ndarray
    phase_crossover_hz: np.ndarray
    delay_margin_s: np.ndarray
    delay_margin_samples: np.ndarray
    jitter_margin_s: np.ndarray
    jitter_margin_samples: np.ndarray
    unstable_modes: np.ndarray
    radius: np.ndarray
    rates_hz: dict[str, float]
    period_s: float
    reason: str | None = None

    @property
    def stable(self) -> np.ndarray:
        return np.asarray(self.unstable_modes) == 0

    @property
    def verdict(self) -> np.ndarray:
        return verdict_word(self.unstable_modes)

    @property
    def gain_margin_db(self) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return 20 * np.log10(self.gain_margin)

    @property
    def delay_margin_ms(self) -> np.ndarray:
        return self.delay_margin_s * 1e3

    @property
    def jitter_margin_ms(self) -> np.ndarray:
        return self.jitter_margin_s * 1e3

    @property
    def rate_label(self) -> str:
        """``27.5 Hz`` or ``embedded 1000 Hz, high-level 250 Hz``."""
        return rate_text(self.rates_hz)


def broken(diagram: BlockDiagram, sensor: str) -> tuple[BlockDiagram, str, str]:
    """``diagram`` broken at ``sensor`` for the sampled loop: the blocks feeding it feed a
    new signal (returned) and a new input drives ``sensor`` (injected).  Returns the
    diagram and the names ``(injected, returned)``; closing ``injected = returned`` gives
    the original loop, ``L = -returned/injected`` (as :meth:`BlockDiagram.loop`)."""
    feeding = [b for b in diagram.blocks if b.dst == sensor]
    if not feeding or any(b.role == "plant" for b in feeding):
        raise InputError("sensor", sensor, "a signal fed by controller or sensor blocks")
    inj, ret = f"{sensor}__injected", f"{sensor}__returned"
    blocks = [replace(b, dst=ret) if b.dst == sensor else b for b in diagram.blocks]
    blocks.append(Block(f"{sensor}__break", inj, sensor, role=feeding[0].role,
                        process=feeding[0].process))
    return BlockDiagram(diagram.name, blocks), inj, ret


@dataclass(frozen=True)
class _OpenLoop:
    """The broken loop's one-tick state space ``x+ = A x + B u``, ``y = C x + D u`` whose
    state ends with shift registers (per delayed block, ``depth`` past source values,
    newest first; :func:`period_map`), kept as the core rows and the register columns so
    that ``L(z)`` costs a system of the core size plus one unknown per register chain."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    core: int
    depth: np.ndarray

    def take(self, rows: np.ndarray) -> _OpenLoop:
        return _OpenLoop(self.A[rows], self.B[rows], self.C[rows], self.D[rows], self.core,
                         self.depth)

    def response(self, theta: np.ndarray) -> np.ndarray:
        """``L(e^{j theta}) = -(C (zI - A)^-1 B + D)`` per design (theta ``(n, F)``).

        A register ``j`` of chain ``l`` holds ``z^-j s_l``, ``s_l`` the chain's source:
        the unknowns are the core state and the sources, and the register columns of
        ``A`` and ``C`` fold into polynomials in ``z^-1`` (an exact rewriting)."""
        c, A = self.core, self.A
        chains = [(int(a), int(a + d)) for a, d in zip(c + np.cumsum(self.depth) - self.depth,
                                                       self.depth) if d > 0]
        rows = np.r_[np.arange(c), [a for a, _ in chains]].astype(int)
        m = rows.size
        zi = np.exp(-1j * theta)[..., None, None]             # (n, F, 1, 1)
        M = np.zeros(theta.shape + (m, m), complex)
        M[..., :c, :c] = -A[:, None, :c, :c]
        M[..., :c, :c] += np.eye(c) / zi
        M[..., c:, :c] = -A[:, None, rows[c:], :c]
        M[..., c:, c:] = np.eye(m - c)
        yc = np.zeros(theta.shape + (1, m), complex)
        yc[..., :c] = self.C[:, None, :, :c]
        for k, (a, b) in enumerate(chains):
            p = zi ** np.arange(1, b - a + 1)[..., :]         # (n, F, 1, depth)
            M[..., :, c + k] -= np.einsum("nrj,nfj->nfr", A[:, rows, a:b], p[..., 0, :])
            yc[..., 0, c + k] = np.einsum("nj,nfj->nf", self.C[:, 0, a:b], p[..., 0, :])
        rhs = np.broadcast_to(self.B[:, None, rows, :], theta.shape + (m, 1))
        x = np.linalg.solve(M, rhs)
        return -((yc @ x)[..., 0, 0] + self.D[:, None, 0, 0])


def _bisect(f, lo: np.ndarray, hi: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Roots of ``f(rows, theta)`` bracketed by ``[lo, hi]`` (sign change), batched."""
    flo = f(rows, lo)
    for _ in range(52):
        mid = 0.5 * (lo + hi)
        fm = f(rows, mid)
        left = np.sign(fm) == np.sign(flo)
        lo, flo = np.where(left, mid, lo), np.where(left, fm, flo)
        hi = np.where(left, hi, mid)
    return 0.5 * (lo + hi)


def _crossings(Lg: np.ndarray, theta: np.ndarray, at) -> tuple[np.ndarray, ...]:
    """All gain and phase crossovers on the grid, refined: (design, theta, L) each."""
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.log(np.abs(Lg))
    gi, gj = np.nonzero(np.sign(g[:, :-1]) * np.sign(g[:, 1:]) < 0)
    wg = _bisect(lambda r, t: np.log(np.abs(at(r, t))), theta[gi, gj], theta[gi, gj + 1], gi)
    im = Lg.imag
    pi_, pj = np.nonzero((np.sign(im[:, :-1]) * np.sign(im[:, 1:]) < 0)
                         & ((Lg.real[:, :-1] < 0) | (Lg.real[:, 1:] < 0)))
    wp = _bisect(lambda r, t: at(r, t).imag, theta[pi_, pj], theta[pi_, pj + 1], pi_)
    Lp = at(pi_, wp)
    keep = Lp.real < 0
    pi_, wp, Lp = pi_[keep], wp[keep], Lp[keep]
    last = Lg[:, -1]    # Nyquist: L is real there
    ny = np.flatnonzero(last.real < 0)
    return (gi, wg, at(gi, wg), np.concatenate([pi_, ny]),
            np.concatenate([wp, theta[ny, -1]]), np.concatenate([Lp, last[ny].real + 0j]))


def _pick(n: int, rows: np.ndarray, key: np.ndarray, value: np.ndarray, theta: np.ndarray,
          empty: float) -> tuple[np.ndarray, np.ndarray]:
    """Per design, the value and theta of the crossing with the smallest key."""
    best = np.full(n, empty)
    th = np.full(n, np.nan)
    if rows.size:
        order = np.lexsort((key, rows))
        first = np.ones(order.size, bool)
        first[1:] = rows[order][1:] != rows[order][:-1]
        sel = order[first]
        best[rows[sel]] = value[sel]
        th[rows[sel]] = theta[sel]
    return best, th


def _margins_from(ol: _OpenLoop, T: float, theta_lo: np.ndarray) -> tuple[np.ndarray, ...]:
    n = ol.A.shape[0]
    u = np.linspace(0.0, 1.0, FREQUENCIES)
    lo = np.minimum(theta_lo, 1e-3 * np.pi)[:, None]
    theta = lo * (np.pi / lo) ** u
    theta[:, -1] = np.pi

    def at(rows, t):
        return ol.take(rows).response(t[:, None])[:, 0] if rows.size else \
            np.zeros(0, complex)

    Lg = ol.response(theta)
    gi, wg, Lgc, pi_, wp, Lpc = _crossings(Lg, theta, at)
    pm = 180.0 + np.degrees(np.angle(Lgc))
    pm = np.where(pm > 180.0, pm - 360.0, pm)   # wrapped to (-180, 180]
    pm_best, wg_best = _pick(n, gi, np.abs(pm), pm, wg, np.inf)
    dm_each = np.radians(np.remainder(pm, 360.0)) / (wg / T)
    dm, _ = _pick(n, gi, dm_each, dm_each, wg, np.inf)
    gm_each = 1.0 / np.abs(Lpc)
    gm, wp_best = _pick(n, pi_, np.abs(np.log(gm_each)), gm_each, wp, np.inf)
    return (pm_best, wg_best / (2 * np.pi * T), gm, wp_best / (2 * np.pi * T), dm,
            _jitter_peak(ol, Lg, theta))


def _jitter_peak(ol: _OpenLoop, Lg: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``max |e^{j theta} - 1| |L/(1+L)|`` per design: the grid's largest point, then a
    101-point scan of the two grid intervals around it."""
    with np.errstate(all="ignore"):
        g = np.abs(np.exp(1j * theta) - 1) * np.abs(Lg / (1 + Lg))
    i = np.clip(np.nanargmax(np.where(np.isfinite(g), g, -1.0), axis=1), 1,
                theta.shape[1] - 2)
    rows = np.arange(theta.shape[0])
    fine = np.linspace(theta[rows, i - 1], theta[rows, i + 1], 101, axis=1)
    Lf = ol.response(fine)
    with np.errstate(all="ignore"):
        gf = np.abs(np.exp(1j * fine) - 1) * np.abs(Lf / (1 + Lf))
    return np.maximum(np.nanmax(g, axis=1), np.nanmax(gf, axis=1))


def sampled_margins(diagram: BlockDiagram, design: Any, sensor: str, rates_hz: Any,
                    w_ref: Any) -> SampledMargins:
    """Certified verdict and margins of the sampled loop broken at ``sensor``.

    ``w_ref`` [rad/s] (per design) sets the low end of the frequency scan (a hundredth of
    it); the scan ends at Nyquist of the base rate.

    Examples
    --------
    >>> import numpy as np
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEA_DIAGRAM, SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 14.0),
    ...               Timing.from_ms(0.5, 2.0, 0.5, 50, 100))
    >>> m = sampled_margins(SEA_DIAGRAM, d, "q_sens", 1000.0, 2 * np.pi * 14)
    >>> str(m.verdict), round(float(m.phase_margin_deg), 1)
    ('stable', 42.0)
    """
    shape = tuple(getattr(design, "shape", ()))
    roots = sampled_roots(diagram, design, rates_hz)
    count, radius = roots.unstable_modes, roots.radius
    rates = roots.rates_hz
    nan = np.full(shape, np.nan)
    if len(set(rates.values())) > 1:
        return SampledMargins(nan, nan, nan, nan, nan, nan, nan, nan, count, radius,
                              rates, roots.period_s, "multi-rate loop: periodic, not "
                              "time-invariant, so it has no frequency response; verdict only")
    cut, inj, ret = broken(diagram, sensor)
    plan = _plan(cut, design, rates_hz, (ret,))
    A, B, C, D, T = _maps(plan, True)
    col = plan.info["controller_inputs"].index(inj)
    n = A.shape[0]
    w = np.broadcast_to(np.asarray(w_ref, float), shape).reshape(n)
    ol = _OpenLoop(A, B[..., col:col + 1], C, D[..., col:col + 1], _core_size(plan),
                   plan.nbuf.max(axis=1, initial=0))
    pm, fc, gm, fp, dm, peak = _margins_from(ol, T, w * T / 100)
    flat = count.reshape(n)
    dm = np.where(flat == 0, dm, np.where(flat > 0, 0.0, np.nan))
    with np.errstate(invalid="ignore", divide="ignore"):
        samples = np.where(np.isfinite(dm) & (dm > 0), np.ceil(dm / T - 1e-9) - 1,
                           np.where(np.isinf(dm), np.inf, -1.0))
        jit_n = np.where(flat == 0, np.ceil(1 / peak - 1e-9) - 1,
                         np.where(flat > 0, -1.0, np.nan))
    jit = np.where(flat == 0, T / peak, np.where(flat > 0, 0.0, np.nan))
    return SampledMargins(*(a.reshape(shape) for a in (pm, fc, gm, fp, dm, samples, jit,
                                                        jit_n)),
                          count, radius, rates, T)


def broken_responses(diagram: BlockDiagram, design: Any, sensor: str, rates_hz: Any,
                     signal: str) -> tuple[Any, float]:
    """The one-rate sampled loop broken at ``sensor`` (:func:`broken`), as a function of the
    frequency: ``respond(rows, theta) -> (L, G)`` with ``L(e^{j theta})`` the loop transfer
    and ``G(e^{j theta})`` the transfer from the injected signal to the controller signal
    ``signal`` (e.g. the actuation), the loop still open; ``rows`` index the flat batch and
    ``theta`` is ``(rows, F)`` [rad/sample].  Returns ``(respond, period_s)``."""
    cut, inj, ret = broken(diagram, sensor)
    plan = _plan(cut, design, rates_hz, (ret, signal))
    A, B, C, D, T = _maps(plan, True)
    col = plan.info["controller_inputs"].index(inj)
    B, D = B[..., col:col + 1], D[..., col:col + 1]
    core, depth = _core_size(plan), plan.nbuf.max(axis=1, initial=0)
    ir, ia = plan.order.index(ret), plan.order.index(signal)
    ol_r = _OpenLoop(A, B, C[:, ir:ir + 1], D[:, ir:ir + 1], core, depth)
    ol_a = _OpenLoop(A, B, C[:, ia:ia + 1], D[:, ia:ia + 1], core, depth)

    def respond(rows: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return ol_r.take(rows).response(theta), -ol_a.take(rows).response(theta)

    return respond, T


def sampled_verdict_text(continuous_stable: bool | None, verdict: str, modes: int,
                         rate: str) -> str:
    """One sentence comparing the continuous and sampled verdicts of one design, calling
    out a design stable in continuous time and not at its rate (``continuous_stable``
    None: the continuous verdict is not known, only the sampled one is stated).

    Examples
    --------
    >>> sampled_verdict_text(True, "unstable", 2, "27.5 Hz")
    'stable in continuous time, UNSTABLE sampled at 27.5 Hz (2 modes outside the unit circle)'
    """
    cont = None if continuous_stable is None else \
        ("stable" if continuous_stable else "unstable")
    head = "" if cont is None else f"{cont} in continuous time, "
    if verdict == "unstable":
        word = "UNSTABLE" if cont == "stable" else "unstable"
        tail = f"{modes} mode{'s' if modes != 1 else ''} outside the unit circle"
    elif verdict == "uncertain":
        word, tail = "uncertain", "a mode too close to the unit circle to certify"
    else:
        word = "STABLE" if cont == "unstable" else "stable"
        tail = "certified"
    return f"{head}{word} sampled at {rate} ({tail})"


def rate_text(rates: Mapping[str, float] | float) -> str:
    """Rates for messages: ``1000 Hz`` or ``embedded 1000 Hz, high-level 250 Hz``."""
    if not isinstance(rates, Mapping):
        return f"{float(rates):g} Hz"
    if len(set(rates.values())) == 1:
        return f"{next(iter(rates.values())):g} Hz"
    return ", ".join(f"{p} {v:g} Hz" for p, v in rates.items())
