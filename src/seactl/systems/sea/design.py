"""Critically-damped gain design of the SEA cascaded controller (eq. nonlinearEqs).

The delay- and filter-free closed-loop denominator of ``P_CL`` is matched to
``(s^2 + 2 zeta1 w1 s + w1^2)(s^2 + 2 zeta2 w2 s + w2^2)`` with
``w1 = 2 pi f_n`` and ``w2 = ratio * w1``.  The four equations have a closed
form (docs/theory/gain-design.md): the first gives ``B_tau`` directly; with
``u = 1 + beta K_tau`` the fourth gives ``K_q = c/u``, the second makes ``B_q``
linear in ``u``, and the third becomes a cubic in ``u``.  All roots are taken,
each candidate is substituted back into the four original equations, and only
solutions with four positive gains that satisfy them are returned.  No initial
guess, no iteration, vectorized over ``f_n`` (and zeta/ratio).

Examples
--------
>>> from seactl.systems.sea.actuators import UT_SEA
>>> g = critically_damped_gains(UT_SEA, 14.0)
>>> [round(float(x), 3) for x in (g.Kq, g.Bq, g.Ktau, g.Btau)]
[83.172, 0.755, 1.8, 0.067]
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from seactl.base.validate import finite_array
from seactl.errors import InfeasibleDesignError, InputError
from seactl.systems.sea.actuators import SEAParams, load_sea
from seactl.systems.sea.loops import Gains


def target_polynomial(w1, w2, zeta1, zeta2) -> tuple[np.ndarray, ...]:
    """Coefficients ``a3, a2, a1, a0`` of the monic target quartic."""
    a3 = 2 * zeta1 * w1 + 2 * zeta2 * w2
    a2 = w1**2 + w2**2 + 4 * zeta1 * zeta2 * w1 * w2
    a1 = 2 * zeta1 * w1 * w2**2 + 2 * zeta2 * w2 * w1**2
    a0 = w1**2 * w2**2
    return a3, a2, a1, a0


def characteristic_coefficients(a: SEAParams, Kq, Bq, Ktau, Btau) -> tuple[np.ndarray, ...]:
    """Left-hand sides of eq. nonlinearEqs: the delay-free closed-loop quartic
    ``D(s)/D_4`` of ``P_CL`` (coefficients of s^3, s^2, s^1, s^0)."""
    M = a.Im * a.Ij
    u = 1 + a.beta * np.asarray(Ktau)
    c3 = (a.Ij * a.bm + a.Im * a.bj + a.Ij * a.beta * Btau * a.k) / M
    c2 = (a.k * (a.Ij * u + a.Im + a.beta * Btau * (a.bj + Bq)) + a.bj * a.bm) / M
    c1 = (a.k * (a.bj + Bq) * u + a.k * (a.bm + a.beta * Btau * Kq)) / M
    c0 = u * a.k * Kq / M
    return c3, c2, c1, c0


def _cubic_roots(c3, c2, c1, c0) -> np.ndarray:
    """All three complex roots of ``c3 u^3 + c2 u^2 + c1 u + c0`` (vectorized Cardano,
    polished by Newton steps on the original cubic); shape ``(..., 3)``."""
    a, b, c = (np.asarray(x, complex) / c3 for x in (c2, c1, c0))
    p = b - a * a / 3
    q = 2 * a**3 / 27 - a * b / 3 + c
    disc = np.sqrt(q * q / 4 + p**3 / 27)
    # choose the sign that avoids cancellation
    w = np.where(np.abs(-q / 2 + disc) >= np.abs(-q / 2 - disc), -q / 2 + disc, -q / 2 - disc)
    C = w ** (1 / 3)
    rot = np.exp(2j * np.pi * np.arange(3) / 3)
    Ck = C[..., None] * rot
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(np.abs(Ck) > 0, Ck - p[..., None] / (3 * Ck), 0)
    u = t - a[..., None] / 3
    for _ in range(2):
        f = ((u + a[..., None]) * u + b[..., None]) * u + c[..., None]
        df = (3 * u + 2 * a[..., None]) * u + b[..., None]
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(df != 0, f / df, 0)
        u = u - step
    return u


@dataclass(frozen=True)
class GainSolutions:
    """Every candidate solution of the gain equations (last axis: up to 3).

    ``valid`` marks the real solutions with four positive gains that satisfy
    the four equations to 1e-9 relative.
    """

    fn_hz: np.ndarray
    Kq: np.ndarray
    Bq: np.ndarray
    Ktau: np.ndarray
    Btau: np.ndarray
    valid: np.ndarray

    @property
    def n_valid(self) -> np.ndarray:
        return self.valid.sum(axis=-1)

    def pick(self, solution: int = 0) -> Gains:
        """Valid solution number ``solution`` of each design, sorted by increasing
        ``K_tau`` (each design must have one: see :func:`critically_damped_gains`)."""
        key = np.where(self.valid, self.Ktau, np.inf)
        order = np.argsort(key, axis=-1)[..., solution:solution + 1]

        def pick(x):
            return np.take_along_axis(x, order, axis=-1)[..., 0]

        return Gains(pick(self.Kq), pick(self.Bq), pick(self.Ktau), pick(self.Btau))

    def rows(self, mask: np.ndarray) -> GainSolutions:
        """The designs of a flat batch where ``mask`` holds."""
        return GainSolutions(*(getattr(self, f.name)[mask] for f in fields(self)))


def solve_gains(actuator: SEAParams, fn_hz, *, zeta1=1.0, zeta2=1.0,
                ratio=1.0) -> GainSolutions:
    """All solutions of the critically-damped gain equations, vectorized.

    Parameters
    ----------
    actuator : SEAParams
    fn_hz : array_like
        Natural frequency ``f_n`` [Hz] (``w1 = 2 pi f_n``).
    zeta1, zeta2 : array_like
        Damping ratios of the two second-order factors (paper: 1).
    ratio : array_like
        ``w2 / w1`` (paper: 1).
    """
    fn = finite_array("fn [Hz]", fn_hz, minimum=0.0, strict=True)
    z1 = finite_array("zeta1", zeta1, minimum=0.0, strict=True)
    z2 = finite_array("zeta2", zeta2, minimum=0.0, strict=True)
    rt = finite_array("ratio", ratio, minimum=0.0, strict=True)
    fn, z1, z2, rt = np.broadcast_arrays(fn, z1, z2, rt)
    a = actuator
    w1 = 2 * np.pi * fn
    a3, a2, a1, a0 = target_polynomial(w1, rt * w1, z1, z2)
    # (an overflow of extreme parameters gives non-finite gains, which are not valid)
    with np.errstate(all="ignore"):
        M = a.Im * a.Ij
        Btau = (a3 * M - a.Ij * a.bm - a.Im * a.bj) / (a.Ij * a.beta * a.k)
        c = a0 * M / a.k                                   # Kq = c / u
        # second equation: Bq = al0 + al1 u
        al1 = -a.Ij / (a.beta * Btau)
        al0 = (a2 * M - a.bj * a.bm - a.k * a.Im) / (a.k * a.beta * Btau) - a.bj
        # third equation times u: al1 u^3 + (al0 + bj) u^2 + (bm - a1 M/k) u + beta Btau c = 0
        roots = _cubic_roots(al1, al0 + a.bj, a.bm - a1 * M / a.k, a.beta * Btau * c)
        u = roots.real
        real = np.abs(roots.imag) <= 1e-9 * (1 + np.abs(roots.real))
        Kq = c[..., None] / u
        Bq = al0[..., None] + al1[..., None] * u
        Ktau = (u - 1) / a.beta
        Bt = np.broadcast_to(Btau[..., None], u.shape)
        lhs = characteristic_coefficients(a, Kq, Bq, Ktau, Bt)
        rhs = (a3, a2, a1, a0)
        resid = np.zeros(u.shape)
        for l_, r_ in zip(lhs, rhs):
            resid = np.maximum(resid, np.abs(l_ - r_[..., None]) / np.abs(r_[..., None]))
    positive = (Kq > 0) & (Bq > 0) & (Ktau > 0) & (Bt > 0)
    finite = np.isfinite(Kq) & np.isfinite(Bq) & np.isfinite(Ktau) & np.isfinite(Bt)
    valid = real & positive & (resid < 1e-9) & np.isfinite(u) & finite
    return GainSolutions(fn, Kq, Bq, Ktau, Bt, valid)


def feasible_fn_range(actuator: SEAParams, *, zeta1=1.0, zeta2=1.0, ratio=1.0,
                      lo_hz: float = 1e-2, hi_hz: float = 1e5) -> list[tuple[float, float]]:
    """Intervals of ``f_n`` [Hz] for which a critically-damped gain set exists.

    A gain set counts when all four gains are positive and satisfy the four
    equations.  The intervals are found on a log grid and their ends refined by
    bisection to 1e-6 relative.

    Parameters
    ----------
    actuator : SEAParams or str or path
        The actuator, a preset name (``"ut-sea"``) or a TOML file.
    zeta1, zeta2 : float
        Damping ratios of the two target pole pairs.
    ratio : float
        ``w2 / w1`` of the two pole pairs.
    lo_hz, hi_hz : float
        Frequency range searched [Hz].

    Returns
    -------
    list of tuple of float
        ``(start, end)`` intervals [Hz]; ``end == hi_hz`` means unbounded above.

    Examples
    --------
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> [(round(a, 3), b) for a, b in feasible_fn_range(UT_SEA)]
    [(9.456, 100000.0)]
    """
    if not isinstance(actuator, SEAParams):
        actuator = load_sea(actuator)
    for name, v in (("zeta1", zeta1), ("zeta2", zeta2), ("ratio", ratio), ("lo_hz", lo_hz),
                    ("hi_hz", hi_hz)):
        if finite_array(name, v, minimum=0.0, strict=True).ndim:
            raise InputError(name, v, "one number > 0 (the range of one pole placement)")
    if not lo_hz < hi_hz:
        raise InputError("hi_hz", hi_hz, f"> lo_hz ({lo_hz:g} Hz)")
    grid = np.logspace(np.log10(lo_hz), np.log10(hi_hz), 4001)
    ok = solve_gains(actuator, grid, zeta1=zeta1, zeta2=zeta2, ratio=ratio).n_valid > 0
    edges = np.nonzero(ok[1:] != ok[:-1])[0]
    lo, hi = grid[edges], grid[edges + 1]
    ok_lo = ok[edges]
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        ok_mid = solve_gains(actuator, mid, zeta1=zeta1, zeta2=zeta2, ratio=ratio).n_valid > 0
        same = ok_mid == ok_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    bounds = np.where(ok_lo, lo, hi)  # the feasible side of each boundary
    starts = ([lo_hz] if ok[0] else []) + [b for b, o in zip(bounds, ok_lo) if not o]
    ends = [b for b, o in zip(bounds, ok_lo) if o] + ([hi_hz] if ok[-1] else [])
    return [(float(s), float(e)) for s, e in zip(starts, ends)]


def _describe(ranges: list[tuple[float, float]], hi_hz: float = 1e5) -> str:
    if not ranges:
        return "no f_n between 0.01 Hz and 100 kHz is feasible"
    parts = []
    for s, e in ranges:
        parts.append(f"f_n >= {s:.4g} Hz" if e >= hi_hz else f"{s:.4g} Hz <= f_n <= {e:.4g} Hz")
    return "feasible: " + " or ".join(parts)


def critically_damped_gains(actuator: SEAParams, fn_hz, *, zeta1=1.0, zeta2=1.0, ratio=1.0,
                            gs=1.0, solution: int = 0) -> Gains:
    """Nominal gains for each ``f_n`` (Algorithm 1), scaled by the gain scale ``gs``.

    Where several valid solutions exist, ``solution`` picks one (sorted by
    increasing ``K_tau``); see :func:`solve_gains` for all of them.

    Raises
    ------
    InfeasibleDesignError
        If some ``f_n`` has no solution with four positive gains; the message
        gives the feasible ``f_n`` range of the actuator.
    """
    sols = solve_gains(actuator, fn_hz, zeta1=zeta1, zeta2=zeta2, ratio=ratio)
    bad = sols.n_valid <= solution
    if bad.any():
        bad_fn = np.unique(np.broadcast_to(sols.fn_hz, bad.shape)[bad])
        # the range is the first failing design's (zeta1, zeta2, ratio may differ per design)
        first = np.unravel_index(np.argmax(bad), bad.shape)
        z1, z2, r = (float(np.broadcast_to(x, bad.shape)[first]) for x in (zeta1, zeta2, ratio))
        ranges = feasible_fn_range(actuator, zeta1=z1, zeta2=z2, ratio=r)
        what = ", ".join(f"{f:g}" for f in bad_fn[:6]) + (" ..." if bad_fn.size > 6 else "")
        which = "" if solution == 0 else f" (solution {solution} asks for {solution + 1} of them)"
        raise InfeasibleDesignError(
            f"no critically-damped gain set with four positive gains exists for f_n = {what} Hz "
            f"on actuator '{actuator.name}'{which} ({'the first: ' if bad.sum() > 1 else ''}"
            f"zeta1={z1:g}, zeta2={z2:g}, ratio={r:g}); {_describe(ranges)}",
            fn_hz=bad_fn, feasible_hz=ranges)
    return sols.pick(solution).scaled(gs)
