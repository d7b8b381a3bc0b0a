"""Stability margins of loops with exact time delays, vectorized over designs.

For a loop transfer ``L(jw)`` (any :class:`~seactl.blockdiagram.Transfer`
of a block diagram), :func:`loop_margins` returns, per design:

* every gain crossover ``|L| = 1`` with its phase margin wrapped to
  (-180, 180]; the reported phase margin is the one smallest in absolute value
  (the MATLAB / python-control convention);
* the gain margin: at the phase crossovers (``L`` on the negative real axis),
  the ``1/|L|`` closest to 1 in the log sense, as python-control reports it;
* the delay margin: the smallest extra loop latency that puts ``L`` through
  -1, ``min_i ((PM_i mod 360) pi/180) / w_i`` over all crossovers;
* ``stable``: the closed loop's stability from the Nyquist criterion on the
  exact-delay loop, counting the open loop's own right-half-plane poles
  (given by the caller, e.g. from an inner loop) and poles at the origin.

Crossings are bracketed on a log grid (refined where the phase moves too fast
to unwrap reliably) and then solved on the exact function with
``scipy.optimize.elementwise.find_root``, so no result comes from
interpolation alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import elementwise

from .blockdiagram import DesignSubset, Transfer

LoopFn = Callable[[Any, np.ndarray], np.ndarray]

_TOL = {"xatol": 1e-11, "xrtol": 1e-12}


@dataclass(frozen=True)
class Crossings:
    """All crossings of a batch, flattened: ``design`` is the flat design index."""

    design: np.ndarray
    omega: np.ndarray
    value: np.ndarray  # phase margin [deg] for gain crossovers, 1/|L| for phase crossovers

    @property
    def delay_margin_s(self) -> np.ndarray:
        """For gain crossovers: the extra loop latency that puts each through -1 [s]."""
        return np.radians(np.remainder(self.value, 360.0)) / self.omega


@dataclass(frozen=True)
class Margins:
    """Stability margins for a batch of designs (arrays of the batch shape).

    Attributes
    ----------
    phase_margin_deg : phase margin [deg], ``inf`` where ``|L|`` never crosses 1.
    crossover_hz : gain-crossover frequency of that margin [Hz], NaN where none
        (see ``has_crossover``).
    gain_margin : gain margin (absolute), ``inf`` where the phase never reaches -180.
        Phase crossovers are resolved wherever ``0.05 < |L| < 20``; a gain margin
        beyond +-26 dB comes from the crossings the grid found and means "> 26 dB"
        (or "< -26 dB").
    phase_crossover_hz : frequency of that gain margin [Hz], NaN where none.
    delay_margin_s : smallest extra latency that destabilizes the loop [s];
        0 for an unstable loop, ``inf`` without crossover.
    stable : closed-loop stability (Nyquist criterion).
    unstable_poles : number of closed-loop right-half-plane poles.
    gain_crossovers, phase_crossovers : every crossing found.
    """

    phase_margin_deg: np.ndarray
    crossover_hz: np.ndarray
    gain_margin: np.ndarray
    phase_crossover_hz: np.ndarray
    delay_margin_s: np.ndarray
    stable: np.ndarray
    unstable_poles: np.ndarray
    gain_crossovers: Crossings
    phase_crossovers: Crossings

    @property
    def has_crossover(self) -> np.ndarray:
        return np.isfinite(self.phase_margin_deg)

    @property
    def gain_margin_db(self) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return 20 * np.log10(self.gain_margin)

    @property
    def delay_margin_ms(self) -> np.ndarray:
        return self.delay_margin_s * 1e3


def default_grid(scale: np.ndarray | float, decades_below: float = 1.5,
                 decades_above: float = 1.5, per_decade: int = 12) -> np.ndarray:
    """Log frequency grid [rad/s] around ``scale`` (per design: shape ``scale.shape + (F,)``)."""
    rel = np.logspace(-decades_below, decades_above,
                      int(round((decades_below + decades_above) * per_decade)) + 1)
    return np.asarray(scale, float)[..., None] * rel


def _wrap180(deg: np.ndarray) -> np.ndarray:
    """Wrap to (-180, 180]."""
    return 180.0 - np.remainder(180.0 - deg, 360.0)


def _refine(loop: LoopFn, design: Any, shape: tuple[int, ...], b: np.ndarray,
            lo: np.ndarray, hi: np.ndarray, kind: str) -> np.ndarray:
    """Solve a crossing exactly in ``log w`` inside each bracket (vectorized)."""
    if b.size == 0:
        return np.empty(0)

    def f(x, idx):
        sub = DesignSubset(design, idx.astype(np.intp), shape)
        val = loop(sub, 1j * np.exp(x)[..., None])[..., 0]
        if kind == "gain":
            return np.log(np.abs(val))
        return np.angle(-val)  # zero where L is on the negative real axis

    xl, xr = np.log(lo), np.log(hi)
    res = elementwise.find_root(f, (xl, xr), args=(b.astype(float),), tolerances=_TOL)
    x = res.x
    failed = np.nonzero(~res.success)[0]
    if failed.size:
        # The single-precision scan can flag a crossing whose bracket shows no sign change
        # in double precision (|L| within ~1e-7 of 1): re-bracket around it in double.
        n_pts = 33
        span = (xr[failed] - xl[failed])[:, None]
        xs = xl[failed][:, None] + span * np.linspace(-1.0, 2.0, n_pts)
        idx = np.repeat(b[failed].astype(float), n_pts)
        fs = f(xs.ravel(), idx).reshape(xs.shape)
        change = np.signbit(fs[:, 1:]) != np.signbit(fs[:, :-1])
        has = change.any(axis=1)
        # the sign change nearest the original bracket
        centre = np.abs(np.arange(n_pts - 1) - (n_pts - 1) / 2.0)
        k = np.argmin(np.where(change, centre, np.inf), axis=1)
        rows = np.arange(failed.size)
        lo2, hi2 = xs[rows, k], xs[rows, k + 1]
        exact = np.where(fs[rows, k] == 0, lo2, np.where(fs[rows, k + 1] == 0, hi2, np.nan))
        ok = has & np.isnan(exact)
        if ok.any():
            res2 = elementwise.find_root(f, (lo2[ok], hi2[ok]),
                                         args=(b[failed][ok].astype(float),), tolerances=_TOL)
            exact[ok] = res2.x
        # no sign change at all in double precision: a tangency; keep the closest point
        closest = xs[rows, np.argmin(np.abs(fs), axis=1)]
        x[failed] = np.where(np.isnan(exact), closest, exact)
    return np.exp(x)


def loop_margins(loop: LoopFn, design: Any, omega: np.ndarray, *,
                 open_loop_rhp_poles: np.ndarray | int = 0, max_depth: int = 9,
                 stability_only: bool = False,
                 block_cache: dict[str, np.ndarray] | None = None) -> Margins:
    """Margins and Nyquist stability of ``L`` for a batch of designs.

    Parameters
    ----------
    loop : callable
        ``loop(design, s) -> L`` with ``s`` on the last axis.
    design : object
        Design batch; attributes are arrays broadcastable to ``design.shape``.
    omega : ndarray
        Bracketing grid [rad/s], shape ``(F,)`` or ``design.shape + (F,)``;
        its first point must lie below the loop's low-frequency features.
        Grid intervals where the phase of ``L`` (where ``|L| > 0.05``) or of
        ``1 + L`` (where ``|L| > 0.5``) turns by more than 60 degrees, or where
        the step of ``log L`` exceeds the endpoints' distances (in ``log L``) to
        the unit circle or to the negative real axis (a pair of crossings could
        hide between them), are
        subdivided, recursively (``max_depth``), and the grid is extended
        upwards while ``|L| > 0.5`` at its top, so that no crossing and no
        encirclement is missed.
    open_loop_rhp_poles : int or ndarray
        Number of right-half-plane poles of ``L`` (e.g. unstable inner loop).
    stability_only : bool
        Only count encirclements (skip crossings): for inner loops.
    block_cache : dict, optional
        Shared block responses on the base grid, when ``loop`` is a block-diagram
        :class:`~seactl.blockdiagram.Transfer` (several loops of one diagram).

    Returns
    -------
    Margins

    Examples
    --------
    A pure delay integrator ``L = K e^{-sT}/s`` has phase margin
    ``90 - K T 180/pi`` degrees at ``w_c = K`` and delay margin ``pi/(2K) - T``:

    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> loop = lambda p, s: p.K[..., None] * np.exp(-s * p.T[..., None]) / s
    >>> p = SimpleNamespace(K=np.array([10.0]), T=np.array([0.05]), shape=(1,))
    >>> m = loop_margins(loop, p, default_grid(10.0))
    >>> round(float(m.phase_margin_deg[0]), 6), round(float(90 - 0.5 * 180 / np.pi), 6)
    (61.35211, 61.35211)
    >>> round(float(m.delay_margin_s[0]), 9) == round(np.pi / 20 - 0.05, 9)
    True
    """
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    omega = np.broadcast_to(np.asarray(omega, float), shape + (np.shape(omega)[-1],))
    omega = omega.reshape(n, -1)
    P = np.broadcast_to(np.asarray(open_loop_rhp_poles, int), shape).reshape(n)
    scan = _Scan(loop, design, shape, stability_only)
    L0 = scan.segments(np.arange(n), omega, max_depth, block_cache)
    # Extend upwards while the loop is still large at the top of the grid.
    top, w_top = np.abs(L0[:, -1]), omega[:, -1].copy()  # omega may be a broadcast view
    todo = np.nonzero(top > 0.5)[0]
    for _ in range(max_depth):
        if todo.size == 0:
            break
        ext = w_top[todo, None] * np.logspace(0, 2, 61)
        Lx = scan.segments(todo, ext, max_depth)
        w_top[todo] = ext[:, -1]
        todo = todo[np.abs(Lx[:, -1]) > 0.5]

    mag0 = np.abs(L0[:, :2])
    slope = -np.log(mag0[:, 1] / mag0[:, 0]) / np.log(omega[:, 1] / omega[:, 0])
    n0 = np.clip(np.round(slope), 0, None)  # poles of L at the origin
    Z = np.round(P + n0 / 2 - scan.winding(n) / np.pi).astype(int)
    stable = Z == 0
    if stability_only:
        nan = np.full(n, np.nan)
        empty = Crossings(np.empty(0, int), np.empty(0), np.empty(0))
        return Margins(*(x.reshape(shape) for x in (nan, nan, nan, nan, nan, stable, Z)),
                       gain_crossovers=empty, phase_crossovers=empty)

    b, wc = scan.solve("gain")
    Lc = scan.at(b, wc)
    pm = _wrap180(180.0 + np.degrees(np.angle(Lc)))
    bp, w180 = scan.solve("phase")
    L180 = scan.at(bp, w180)
    keep = np.real(L180) < 0
    bp, w180 = bp[keep], w180[keep]
    with np.errstate(divide="ignore"):
        gm = 1.0 / np.abs(L180[keep])

    pm_best = np.full(n, np.inf)
    wc_best = np.full(n, np.nan)
    if b.size:
        first = first_per_design(b, np.abs(pm))
        pm_best[b[first]], wc_best[b[first]] = pm[first], wc[first]
    gm_best = np.full(n, np.inf)
    w180_best = np.full(n, np.nan)
    if bp.size:
        with np.errstate(divide="ignore"):
            first = first_per_design(bp, np.abs(np.log(gm)))
        gm_best[bp[first]], w180_best[bp[first]] = gm[first], w180[first]
    gain_crossovers = Crossings(b, wc, pm)
    dm = np.full(n, np.inf)
    if b.size:
        np.minimum.at(dm, b, gain_crossovers.delay_margin_s)
    dm = np.where(stable, dm, 0.0)
    res = (pm_best, wc_best / (2 * np.pi), gm_best, w180_best / (2 * np.pi), dm, stable, Z)
    return Margins(*(x.reshape(shape) for x in res),
                   gain_crossovers=gain_crossovers, phase_crossovers=Crossings(bp, w180, gm))


class _Scan:
    """Walks grid segments of many designs, subdividing where the phase moves fast.

    Collects the winding of ``1 + L`` per segment and the brackets of gain and
    phase crossovers, to be solved exactly at the end.
    """

    def __init__(self, loop: LoopFn, design: Any, shape: tuple[int, ...], stability_only: bool):
        self.loop, self.design, self.shape = loop, design, shape
        self.stability_only = stability_only
        self.single = isinstance(loop, Transfer)
        self.wind_design: list[np.ndarray] = []
        self.wind_value: list[np.ndarray] = []
        self.brackets: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {
            "gain": [], "phase": []}

    def at(self, didx: np.ndarray, omega: np.ndarray, cache: dict | None = None,
           single: bool = False) -> np.ndarray:
        """``L(j omega)`` for designs ``didx`` (``omega`` of shape ``(n, F)`` or ``(n,)``);
        ``single``: in complex64 (enough to bracket crossings and count turns)."""
        if didx.size == 0:
            return np.empty(np.shape(omega), complex)
        w = omega if omega.ndim == 2 else omega[:, None]
        s = 1j * w.astype(np.float32) if single else 1j * w
        sub = DesignSubset(self.design, didx, self.shape)
        L = self.loop(sub, s, cache=cache) if cache is not None else self.loop(sub, s)
        L = np.broadcast_to(L, w.shape)
        return L if omega.ndim == 2 else L[:, 0]

    def segments(self, didx: np.ndarray, omega: np.ndarray, depth: int,
                 cache: dict | None = None) -> np.ndarray:
        """Scan rows of grid ``omega`` (one row per design in ``didx``); returns ``L``.

        The scan runs in single precision where the loop allows it (a block-diagram
        transfer); every reported value is then solved and evaluated in double."""
        L = self.at(didx, omega, cache, single=self.single)
        dphi = np.angle(L[:, 1:] / L[:, :-1])
        ret = 1.0 + L
        dphi_f = np.angle(ret[:, 1:] / ret[:, :-1])
        mag = np.abs(L)
        big = np.maximum(mag[:, 1:], mag[:, :-1])
        coarse = (np.abs(dphi_f) > np.pi / 3) & (big > 0.5)
        if not self.stability_only:
            coarse |= (np.abs(dphi) > np.pi / 3) & (big > 0.05)
            # A pair of crossings can hide between two samples on the same side of the unit
            # circle (or of the negative real axis) only if log L moves between them by more
            # than their distance to it, |log|L|| (or pi - |arg L|).  Comparing the step of
            # log L with the larger of the two distances never fires on a plain approach to
            # a crossing (step = difference of distances), so refinement stays local.
            logmag = np.log(mag)
            step = np.hypot(logmag[:, 1:] - logmag[:, :-1], dphi)
            to_circle = np.abs(logmag)
            same_side = (logmag[:, 1:] >= 0) == (logmag[:, :-1] >= 0)
            coarse |= same_side & (step > np.maximum(to_circle[:, 1:], to_circle[:, :-1]))
            to_axis = np.pi - np.abs(np.angle(L))
            same_half = (L.imag[:, 1:] >= 0) == (L.imag[:, :-1] >= 0)
            small = np.minimum(mag[:, 1:], mag[:, :-1])
            coarse |= (same_half & (big > 0.05) & (small < 20.0)
                       & (step > np.maximum(to_axis[:, 1:], to_axis[:, :-1])))
        if depth <= 0:
            coarse[:] = False
        fine = ~coarse
        self.wind_design.append(didx)
        self.wind_value.append(np.where(fine, dphi_f, 0.0).sum(axis=1, dtype=float))
        if not self.stability_only:
            above = mag >= 1.0
            g = fine & (above[:, 1:] != above[:, :-1])
            rg, ig = np.nonzero(g)
            self.brackets["gain"].append((didx[rg], omega[rg, ig], omega[rg, ig + 1]))
            im = L.imag
            re_cross = L.real[:, :-1] * np.abs(im[:, 1:]) + L.real[:, 1:] * np.abs(im[:, :-1])
            p = fine & ((im[:, 1:] >= 0) != (im[:, :-1] >= 0)) & (re_cross < 0)
            rp, ip = np.nonzero(p)
            self.brackets["phase"].append((didx[rp], omega[rp, ip], omega[rp, ip + 1]))
        rc, ic = np.nonzero(coarse)
        if rc.size:
            lo, hi = omega[rc, ic], omega[rc, ic + 1]
            sub = lo[:, None] * (hi / lo)[:, None] ** np.linspace(0.0, 1.0, 5)
            self.segments(didx[rc], sub, depth - 1)
        return L

    def solve(self, kind: str) -> tuple[np.ndarray, np.ndarray]:
        parts = self.brackets[kind]
        b = np.concatenate([p[0] for p in parts]) if parts else np.empty(0, int)
        if b.size == 0:
            return b, np.empty(0)
        lo = np.concatenate([p[1] for p in parts])
        hi = np.concatenate([p[2] for p in parts])
        return b, _refine(self.loop, self.design, self.shape, b, lo, hi, kind)

    def winding(self, n: int) -> np.ndarray:
        """Total phase change of ``1 + L`` [rad] per design."""
        if not self.wind_design:
            return np.zeros(n)
        return np.bincount(np.concatenate(self.wind_design),
                           weights=np.concatenate(self.wind_value), minlength=n)


def first_per_design(groups: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Index, per group, of the element with the smallest ``key`` (groups in sorted order)."""
    order = np.lexsort((key, groups))
    g = groups[order]
    return order[np.r_[True, g[1:] != g[:-1]]] if g.size else order


# --------------------------------------------------------------------------- SEA
def sea_reference_frequency(design: Any) -> np.ndarray:
    """A frequency scale [rad/s] for the SEA's bracketing grid: the fourth root of the
    delay-free closed-loop constant term (= w_n for critically-damped designs), or the
    spring resonance when there is no stiffness feedback."""
    u = 1 + design.beta * design.Ktau
    c0 = u * design.k * design.Kq / (design.Im * design.Ij)
    spring = np.sqrt(design.k * (design.Im + design.Ij) / (design.Im * design.Ij))
    return np.where(c0 > 0, np.sqrt(np.sqrt(np.abs(c0))), spring)


def sea_margins(design: Any, omega: np.ndarray | None = None) -> Margins:
    """Margins of the SEA outer impedance loop (inner torque loop closed).

    The open loop's right-half-plane poles are those of the closed inner torque
    loop, counted by the Nyquist criterion on the inner loop (whose own open
    loop ``P_F C e^{-s T_tau}`` is stable), so ``stable`` is the stability of
    the whole cascaded system.

    Examples
    --------
    Table I, f_n = 12 Hz:

    >>> from seactl.actuators import UT_SEA
    >>> from seactl.design import critically_damped_gains
    >>> from seactl.loops import SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 12.0),
    ...               Timing.from_ms(0.5, 2.0, 0.5, 50.0, 100.0))
    >>> round(float(sea_margins(d).phase_margin_deg), 1)
    45.1
    """
    from .loops import inner_loop, outer_loop

    if omega is None:
        omega = default_grid(sea_reference_frequency(design))
    cache: dict[str, np.ndarray] = {}  # the inner loop's blocks are shared with the outer's
    inner = loop_margins(inner_loop(), design, omega, stability_only=True, block_cache=cache)
    return loop_margins(outer_loop(), design, omega, open_loop_rhp_poles=inner.unstable_poles,
                        block_cache=cache)
