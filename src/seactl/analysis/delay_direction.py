"""Delay margin along a direction of the delay vector, by frequency sweeping.

The delays move on the ray ``tau(t) = tau0 + t d / max(d)``, ``t >= 0`` [s]; the margin is
the smallest ``t`` at which a characteristic root reaches the imaginary axis.  The
direction must be commensurate (``d / max(d) = n / L``, integers ``n_i`` and ``L`` at most
:data:`MAX_DENOMINATOR`): with ``h = t / L`` every term's delay is
``c_j + k_j h`` (``c_j = E_j . tau0`` fixed, ``k_j = E_j . n`` a non-negative integer), so
on the axis ``Delta(jw; t) = P_w(z) = sum_k a_k(jw) z^k`` with ``z = exp(-j w h)``: a
polynomial in ``z`` whose coefficients hold the fixed delays exactly.  A root on the axis
at ``jw`` is a root of ``P_w`` with ``|z| = 1``; its angle ``theta`` gives the delays
``h = (-theta mod 2 pi) / w + 2 pi m / w`` (the frequency sweeping test of Chen, Gu and
Nett, Syst. Control Lett. 26, 1995).

Soundness (docs/theory/delay-margin.md): beyond the Cauchy radius ``R`` of
:func:`seactl.certify.cauchy.cauchy_bound` the undelayed term dominates all the others
together, so no root lies on the axis above ``R`` whatever the delays (the equation is
retarded); at ``w = 0`` ``Delta(0)`` does not depend on the delays, and a root there is a
root at ``t = 0`` (the count at ``t = 0`` refuses it).  On ``(0, R]`` the roots of
``P_w`` are continuous in ``w``: a crossing of the unit circle changes the number of
roots inside between two grid points, or (a touch) makes ``min ||z| - 1|`` small at a
grid point; each such place starts Newton on the two real equations ``P_w(e^{j theta}) =
0`` in ``(w, theta)``, on the exact quasi-polynomial.  What the grid can miss is a pair
of crossings closer together than its step whose roots stay away from the circle at the
grid points; so the result checks itself with certified root counts
(:func:`seactl.analysis.margins.certified_right_roots`): none in the right half-plane at
``t = 0`` and at :data:`CHECK_FRACTIONS` of ``[0, t*)``, some just beyond ``t*`` (none:
a touch, reported).  A design that fails is swept again on a denser grid, then reported
``verified = False``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from math import lcm
from typing import Any

import numpy as np

from seactl.analysis.margins import certified_right_roots
from seactl.analysis.roots import frequency_scale
from seactl.base.limits import check_budget
from seactl.certify.cauchy import cauchy_bound
from seactl.diagram.delayterms import DelayTerms
from seactl.errors import InputError

MAX_DENOMINATOR = 16
"""Largest integer in the ratios of a direction's weights (``1:2``, ``3:16``)."""

POINTS_PER_DECADE = 200
"""Sweep grid: points per decade (logarithmic part)."""

TURN_POINTS = 32
"""Sweep grid: points per turn of the longest fixed delay's phase (linear part)."""

DENSER = 4
"""How much denser the second sweep of a design that failed its checks is."""

NEAR = 0.1
"""A local minimum of ``min_i ||z_i| - 1|`` below this starts Newton (a touch)."""

CHECK_FRACTIONS = (0.0, 0.25, 0.5, 0.75, 0.95)
"""Points of ``[0, t*)``, as fractions of the margin, whose root count must be 0."""

BEYOND = 1e-3
"""The count just beyond the margin is taken at ``t* (1 + BEYOND)``."""

POINT_SECONDS = (1e-5, 1e-6, 1e-7)
"""Estimated time per grid point and design: a constant, per term (``J``) and per cubed
degree ``K`` of ``P_w`` (its companion eigenvalues), rounded up: for refusing work up
front."""

CHUNK_BYTES = 64e6
"""Memory of the grid points evaluated at once (their companion matrices)."""

NEWTON_STEPS = 60


@dataclass(frozen=True)
class DirectionMargin:
    """Delay margin along a direction, per design (flat batch).

    Attributes
    ----------
    delay_margin_s : numpy.ndarray
        ``t*`` [s] (extra delay of the most-moved delay); 0 where unstable at ``t = 0``,
        ``inf`` where no root reaches the axis; NaN where the count at ``t = 0`` is
        uncertain.
    crossing_rad_s : numpy.ndarray
        Frequency of the root on the axis at ``t*`` [rad/s]; NaN where none.
    delays_s : numpy.ndarray
        ``(D, B)``: the delays at the crossing [s] (``tau0 + t* d / max(d)``).
    stable, verified, touch : numpy.ndarray of bool
        Certified stable at ``t = 0``; the checks passed; the root only touches the axis.
    direction : numpy.ndarray
        ``d / max(d)``.
    """

    delay_margin_s: np.ndarray
    crossing_rad_s: np.ndarray
    delays_s: np.ndarray
    stable: np.ndarray
    verified: np.ndarray
    touch: np.ndarray
    direction: np.ndarray


def ray_direction(direction: Any, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, int]:
    """The direction ``d / max(d)`` and its integer steps: ``(dhat, n, L)`` with
    ``dhat = n / L``.

    Parameters
    ----------
    direction : None, mapping or sequence
        ``None``: every delay grows alike; name -> weight (absent names: 0); or weights
        in the order of ``names``.  Weights >= 0, not all 0, in ratios of integers up to
        :data:`MAX_DENOMINATOR`.
    names : sequence of str
        The delays' names.

    Returns
    -------
    tuple
        ``dhat`` (float), ``n`` (int) of length ``len(names)``, and ``L``.
    """
    if not names:
        raise InputError("direction", direction, "a system with delays (this one has none)")
    if direction is None:
        d = np.ones(len(names))
    elif isinstance(direction, Mapping):
        bad = [k for k in direction if k not in names]
        if bad:
            raise InputError("direction", bad[0], "a delay name: one of " + ", ".join(names))
        d = np.array([float(direction.get(k, 0.0)) for k in names])
    else:
        d = np.asarray(direction, float).ravel()
        if d.size != len(names):
            raise InputError("direction", list(d), f"{len(names)} weights, in the order "
                             + ", ".join(names))
    if not (np.all(np.isfinite(d)) and np.all(d >= 0) and np.any(d > 0)):
        raise InputError("direction", d.tolist(), "finite weights >= 0, not all 0")
    dhat = d / d.max()
    fr = [Fraction(float(x)).limit_denominator(MAX_DENOMINATOR) for x in dhat]
    if any(abs(float(f) - x) > 1e-9 for f, x in zip(fr, dhat)):
        raise InputError("direction", d.tolist(),
                         f"commensurate weights, in ratios of integers up to "
                         f"{MAX_DENOMINATOR} (e.g. 1,2 or 3,16); round the weights to such "
                         "ratios")
    L = lcm(*(f.denominator for f in fr))
    n = np.array([f.numerator * (L // f.denominator) for f in fr], int)
    return n / L, n, L


def direction_margin(terms: DelayTerms, direction: Any = None) -> DirectionMargin:
    """The delay margin of every design of ``terms`` along ``direction``.

    Parameters
    ----------
    terms : DelayTerms
        The characteristic as a function of the delays (any batch shape; flattened here).
    direction : None, mapping or sequence
        As :func:`ray_direction`.

    Returns
    -------
    DirectionMargin
        Per design of the flattened batch.
    """
    dhat, n, L = ray_direction(direction, terms.names)
    B = int(np.prod(terms.shape))
    J, n1 = terms.coeffs.shape[0], terms.coeffs.shape[-1]
    flat = DelayTerms(terms.coeffs.reshape(J, B, n1), terms.exponents, terms.names,
                      np.broadcast_to(terms.delays_s, (len(terms.names),) + terms.shape)
                      .reshape(-1, B))
    q0 = flat.at()
    q0.require_retarded("delay_margin")
    ray = _Ray(flat, n, L, dhat)
    t = np.full(B, np.inf)
    w = np.full(B, np.nan)
    counted = _counts(ray, np.zeros((1, B)))[0]
    stable = counted == 0
    todo = np.nonzero(stable)[0]
    verified = np.zeros(B, bool)
    touch = np.zeros(B, bool)
    for density in (1, DENSER):
        if todo.size == 0:
            break
        t[todo], w[todo] = ray.sweep(todo, density)
        ok, touch[todo] = ray.check(todo, t[todo])
        verified[todo] = ok
        todo = todo[~ok]
    t = np.where(stable, t, np.where(counted < 0, np.nan, 0.0))
    w = np.where(stable & np.isfinite(t), w, np.nan)
    tau = flat.delays_s + np.where(np.isfinite(t), t, np.nan) * dhat[:, None]
    return DirectionMargin(t, w, tau, stable, verified & stable, touch & stable, dhat)


class _Ray:
    """The characteristic on the ray ``tau0 + L h dhat``: terms with fixed delays ``c``
    and integer powers ``k`` of ``z = exp(-s h)``."""

    def __init__(self, terms: DelayTerms, n: np.ndarray, L: int, dhat: np.ndarray):
        self.terms, self.L, self.dhat = terms, L, dhat
        self.k = terms.exponents @ n
        self.K = int(self.k.max())
        q0 = terms.at()
        self.c = q0.delays
        self.w_ref = frequency_scale(q0)
        self.w_max = cauchy_bound(q0)

    def grid(self, idx: np.ndarray, density: int) -> np.ndarray:
        """``(len(idx), W)``: logarithmic from ``1e-4 w_ref`` then linear (a step of
        ``1 / TURN_POINTS`` turn of the longest fixed delay) to the Cauchy radius; rows
        padded with their last point."""
        w_lo = 1e-4 * self.w_ref[idx]
        w_hi = np.maximum(self.w_max[idx], 10 * w_lo)
        per = POINTS_PER_DECADE * density
        ratio = 10.0 ** (1.0 / per)
        c_max = self.c[:, idx].max(axis=0)
        with np.errstate(divide="ignore"):
            step = np.where(c_max > 0, 2 * np.pi / (TURN_POINTS * density * c_max), np.inf)
        w_lin = np.clip(step / (ratio - 1.0), w_lo, w_hi)
        n_log = np.ceil(per * np.log10(w_lin / w_lo))
        n_lin = np.where(w_hi > w_lin, np.ceil((w_hi - w_lin) / np.where(
            np.isfinite(step), step, 1.0)), 0.0)
        W = float((n_log + n_lin).max()) + 2
        check_budget(f"the delay-margin sweep ({idx.size} design(s) x {W:,.4g} frequencies)",
                     seconds=idx.size * W * float(np.dot(POINT_SECONDS, (
                         1.0, len(self.k), float(self.K) ** 3))),
                     n_bytes=CHUNK_BYTES + 16.0 * idx.size * W,
                     hint="a long fixed delay turns the phase often up to the roots' "
                          "bound; shorten the delays that do not move")
        W = int(W)
        i = np.arange(W)[None, :]
        w = np.where(i <= n_log[:, None], w_lo[:, None] * ratio ** i,
                     w_lin[:, None] + (i - n_log[:, None]) * np.where(
                         np.isfinite(step), step, 0.0)[:, None])
        return np.minimum(w, w_hi[:, None])

    def coefficients(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``a_k(jw)``, ``(K + 1,) + w.shape`` (rows of ``w``: designs ``idx``)."""
        s = 1j * w
        cf = self.terms.coeffs[:, idx][:, :, None, :]
        p = cf[..., -1] + 0 * s
        for j in range(cf.shape[-1] - 2, -1, -1):
            p = p * s + cf[..., j]
        p = p * np.exp(-s * self.c[:, idx][:, :, None])
        a = np.zeros((self.K + 1,) + w.shape, complex)
        for k in np.unique(self.k):
            a[k] = p[self.k == k].sum(axis=0)
        return a

    def sweep(self, idx: np.ndarray, density: int) -> tuple[np.ndarray, np.ndarray]:
        """Per design ``idx``, the smallest ``t`` of a crossing and its frequency."""
        t = np.full(idx.size, np.inf)
        w_at = np.full(idx.size, np.nan)
        if self.K == 0:
            return t, w_at
        w = self.grid(idx, density)
        starts = []
        cols = max(1, int(CHUNK_BYTES / (16.0 * (self.K**2 + self.K + len(self.k)) * idx.size)))
        for lo in range(0, w.shape[1], cols):
            sl = slice(max(lo - 1, 0), lo + cols + 1)
            starts.append(_candidates(self.coefficients(idx, w[:, sl]), w[:, sl]))
        rows = np.concatenate([s[0] for s in starts])
        w0 = np.concatenate([s[1] for s in starts])
        th0 = np.concatenate([s[2] for s in starts])
        wc, th, ok = self.newton(idx[rows], w0, th0)
        ok &= (wc > 0) & (wc <= 1.01 * self.w_max[idx[rows]])
        rows, wc, th = rows[ok], wc[ok], th[ok]
        tc = self.L * np.mod(-th, 2 * np.pi) / wc
        order = np.lexsort((tc, rows))
        rows, tc, wc = rows[order], tc[order], wc[order]
        first = np.r_[True, rows[1:] != rows[:-1]] if rows.size else np.zeros(0, bool)
        t[rows[first]], w_at[rows[first]] = tc[first], wc[first]
        return t, w_at

    def newton(self, design: np.ndarray, w: np.ndarray, th: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Newton on ``Re, Im P_w(e^{j theta}) = 0`` in ``(w, theta)``; converged where the
        residual is at rounding level of the terms' moduli."""
        cf = self.terms.coeffs[:, design]
        c, k = self.c[:, design], self.k[:, None]
        for _ in range(NEWTON_STEPS):
            F, Fw, Ft, M = _residual(cf, c, k, w, th)
            det = Fw.real * Ft.imag - Ft.real * Fw.imag
            with np.errstate(divide="ignore", invalid="ignore"):
                dw = (F.real * Ft.imag - Ft.real * F.imag) / det
                dt = (Fw.real * F.imag - F.real * Fw.imag) / det
            dw = np.where(np.isfinite(dw), np.clip(dw, -0.5 * w, 0.5 * w), 0.0)
            dt = np.where(np.isfinite(dt), np.clip(dt, -0.5, 0.5), 0.0)
            w, th = w - dw, th - dt
        F, _, _, M = _residual(cf, c, k, w, th)
        return w, th, np.abs(F) <= 1e-9 * M

    def check(self, idx: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Certified counts along the ray: 0 at :data:`CHECK_FRACTIONS` of ``t`` (for an
        infinite ``t``, at 1 to 10^5 periods of ``w_ref``, all 0), > 0 beyond (0: a touch)."""
        finite = np.isfinite(t)
        frac = np.array(CHECK_FRACTIONS + (1 + BEYOND,))[:, None]
        far = np.r_[0.0, 10.0 ** np.arange(frac.size - 1)][:, None] \
            * (2 * np.pi * self.L / self.w_ref[idx])
        pts = np.where(finite, frac * np.where(finite, t, 0.0), far)
        full = np.zeros((pts.shape[0], self.terms.delays_s.shape[1]))
        full[:, idx] = pts
        counts = _counts(self, full)[:, idx]
        before = np.all(counts[:-1] == 0, axis=0)
        beyond = counts[-1]
        ok = before & np.where(finite, beyond >= 0, beyond == 0)
        return ok, finite & (beyond == 0)



def _residual(cf: np.ndarray, c: np.ndarray, k: np.ndarray, w: np.ndarray, th: np.ndarray
              ) -> tuple[np.ndarray, ...]:
    """``P_w(e^{j theta})``, its derivatives in ``w`` and ``theta``, and the sum of the
    terms' moduli, per candidate."""
    s = 1j * w
    p = cf[..., -1] + 0 * s
    dp = np.zeros_like(p)
    for j in range(cf.shape[-1] - 2, -1, -1):
        dp = dp * s + p
        p = p * s + cf[..., j]
    e = np.exp(-s * c + 1j * k * th)
    F = (p * e).sum(axis=0)
    Fw = (1j * (dp - c * p) * e).sum(axis=0)
    Ft = (1j * k * p * e).sum(axis=0)
    return F, Fw, Ft, np.abs(p).sum(axis=0)


def _candidates(a: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, ...]:
    """Newton starts ``(row, w, theta)`` from the roots of ``P_w`` on the grid: both ends
    of an interval where the number of roots inside the unit circle changes, and local
    minima of ``min ||z| - 1|`` below :data:`NEAR`; theta is the angle of the root
    closest to the circle."""
    z = _polynomial_roots(a)
    gap = np.abs(np.abs(z) - 1.0)
    near = np.argmin(gap, axis=-1)
    g = np.take_along_axis(gap, near[..., None], -1)[..., 0]
    th = np.angle(np.take_along_axis(z, near[..., None], -1)[..., 0])
    inside = (np.abs(z) < 1).sum(axis=-1)
    change = np.zeros(w.shape, bool)
    step = inside[:, 1:] != inside[:, :-1]
    change[:, 1:] |= step
    change[:, :-1] |= step
    dip = np.zeros(w.shape, bool)
    dip[:, 1:-1] = (g[:, 1:-1] <= g[:, :-2]) & (g[:, 1:-1] <= g[:, 2:]) & (g[:, 1:-1] < NEAR)
    r, i = np.nonzero(change | dip)
    return r, w[r, i], th[r, i]


def _polynomial_roots(a: np.ndarray) -> np.ndarray:
    """Roots of ``sum_k a[k] z^k`` per grid point: ``a.shape[1:] + (K,)`` (companion
    eigenvalues; a vanishing leading coefficient puts roots far out)."""
    K = a.shape[0] - 1
    scale = np.abs(a).max(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    lead = a[K] / scale
    lead = np.where(np.abs(lead) < 1e-13, 1e-13, lead)
    monic = np.moveaxis(a[:K] / scale, 0, -1) / lead[..., None]
    comp = np.zeros(monic.shape[:-1] + (K, K), complex)
    comp[..., 0, :] = -monic[..., ::-1]
    if K > 1:
        comp[..., np.arange(1, K), np.arange(K - 1)] = 1.0
    return np.linalg.eigvals(comp)


def _counts(ray: _Ray, t: np.ndarray) -> np.ndarray:
    """Certified right-half-plane counts at ``t`` (``(P, B)`` [s]) along the ray: ``(P, B)``,
    -1 where uncertain."""
    tau = ray.terms.delays_s[:, None, :] + t[None] * ray.dhat[:, None, None]
    tt = ray.terms
    q = DelayTerms(tt.coeffs[:, None], tt.exponents, tt.names, tt.delays_s).at(tau).flat()
    return certified_right_roots(q, frequency_scale(q)).reshape(t.shape)
