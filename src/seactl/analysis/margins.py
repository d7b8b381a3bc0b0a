"""Stability margins of loops with exact time delays, vectorized over designs.

For a loop transfer ``L(jw)`` (any :class:`~seactl.diagram.blockdiagram.Transfer`
of a block diagram), :func:`loop_margins` returns, per design:

* every gain crossover ``|L| = 1`` with its phase margin wrapped to
  (-180, 180]; the reported phase margin is the one smallest in absolute value
  (the MATLAB / python-control convention);
* the gain margin: at the phase crossovers (``L`` on the negative real axis),
  the ``1/|L|`` closest to 1 in the log sense, as python-control reports it, whatever
  its size (within +-234 dB, :data:`BAND_SCANS`; without delay, any);
* the delay margin: the smallest extra loop latency that puts ``L`` through
  -1, ``min_i ((PM_i mod 360) pi/180) / w_i`` over all crossovers;
* ``stable``: the closed loop's stability from the Nyquist criterion on the
  exact-delay loop, counting the open loop's own right-half-plane poles
  (given by the caller, e.g. from an inner loop) and poles at the origin.

A loop of a block diagram is scanned by :func:`certified_margins`: a grid bounded by
the loop's delays, bisected until derivative bounds prove that no root, encirclement or
crossing lies unseen between samples, with the closed loop's right-half-plane roots
counted on its characteristic quasi-polynomial (the soundness argument:
docs/theory/certified-scan.md).  Opaque loop callables keep a heuristic grid scan.  Crossings are
then solved on the exact function with ``scipy.optimize.elementwise.find_root``, so no
result comes from interpolation alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.limits import check_budget
from seactl.base.parallel import in_threads
from seactl.base.validate import finite_array
from seactl.certify import scan as _certify
from seactl.certify.cauchy import cauchy_bound
from seactl.diagram.blockdiagram import (
    BlockDiagram,
    DesignSubset,
    QuasiPolynomial,
    Transfer,
    columnwise,
    evaluate_forms,
    padded_sum,
    rounding_majorant,
)
from seactl.errors import ResourceError

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
        Phase crossovers are resolved wherever ``0.05 < |L| < 20``; a design with none
        there is scanned again with the band widened :data:`BAND_STEP`-fold at both ends,
        up to :data:`BAND_SCANS` times, until one lies in it, so every gain margin
        within +-234 dB is the one closest to 0 dB, and ``inf`` means no phase crossover
        with ``|L|`` within ``0.05 / 3000^3`` to ``20 * 3000^3`` (except where such a scan
        would exceed :data:`MAX_EVALUATIONS` base points or is not certified: the
        crossovers found before stand).  A loop of a block diagram without delay has
        finitely many phase crossovers, all found whatever their size
        (:func:`_rational_phase_crossovers`): ``inf`` means none.
    phase_crossover_hz : frequency of that gain margin [Hz], NaN where none.
    delay_margin_s : smallest extra latency that destabilizes the loop [s];
        0 for an unstable loop, ``inf`` without crossover.
    stable : closed-loop stability (Nyquist criterion).
    unstable_poles : number of closed-loop right-half-plane poles.
    gain_crossovers, phase_crossovers : every crossing found (per design, the phase
        crossovers of its last scan).
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


def _subset_loop(loop: LoopFn, design: Any, shape: tuple[int, ...]
                 ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``L(j w)`` at one frequency per listed design (flat indices) of an opaque loop."""

    def at(idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        sub = DesignSubset(design, idx.astype(np.intp), shape)
        return loop(sub, 1j * w[..., None])[..., 0]

    return at


def _crossing_fn(loop_at: Callable[[np.ndarray, np.ndarray], np.ndarray], kind: str
                 ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``f(x, idx)``: ``log |L|`` (gain) or ``arg(-L)`` (phase) at ``w = e^x`` of the flat
    designs ``idx``, zero at the crossing."""
    def f(x, idx):
        val = loop_at(idx.astype(np.intp), np.exp(x))
        if kind == "gain":
            return np.log(np.abs(val))
        return np.angle(-val)  # zero where L is on the negative real axis
    return f


def _refine(loop_at: Callable[[np.ndarray, np.ndarray], np.ndarray], b: np.ndarray,
            lo: np.ndarray, hi: np.ndarray, kind: str) -> np.ndarray:
    """Solve a crossing exactly in ``log w`` inside each bracket (vectorized);
    ``loop_at(idx, w)`` is ``L(j w)`` of the flat designs ``idx``."""
    if b.size == 0:
        return np.empty(0)
    from scipy.optimize import elementwise  # (lazily: a quarter second to import)

    f = _crossing_fn(loop_at, kind)
    res = elementwise.find_root(f, (np.log(lo), np.log(hi)), args=(b.astype(float),),
                                tolerances=_TOL)
    x = res.x
    failed = np.nonzero(~res.success)[0]
    if failed.size:
        x[failed] = _rebracket(f, b[failed], np.log(lo[failed]), np.log(hi[failed]))
    return np.exp(x)


def _rebracket(f: Callable[[np.ndarray, np.ndarray], np.ndarray], b: np.ndarray,
               xl: np.ndarray, xr: np.ndarray) -> np.ndarray:
    """Crossings whose bracket ``[xl, xr]`` (in ``log w``) shows no sign change when
    evaluated again (``|L|`` within rounding of 1): the sign change nearest the bracket
    on a grid three times as wide, solved; a tangency without any keeps the point where
    ``|f|`` is smallest."""
    from scipy.optimize import elementwise

    n_pts = 33
    xs = xl[:, None] + (xr - xl)[:, None] * np.linspace(-1.0, 2.0, n_pts)
    fs = f(xs.ravel(), np.repeat(b.astype(float), n_pts)).reshape(xs.shape)
    change = np.signbit(fs[:, 1:]) != np.signbit(fs[:, :-1])
    has = change.any(axis=1)
    centre = np.abs(np.arange(n_pts - 1) - (n_pts - 1) / 2.0)
    k = np.argmin(np.where(change, centre, np.inf), axis=1)
    rows = np.arange(b.size)
    lo2, hi2 = xs[rows, k], xs[rows, k + 1]
    exact = np.where(fs[rows, k] == 0, lo2, np.where(fs[rows, k + 1] == 0, hi2, np.nan))
    ok = has & np.isnan(exact)
    if ok.any():
        res = elementwise.find_root(f, (lo2[ok], hi2[ok]), args=(b[ok].astype(float),),
                                    tolerances=_TOL)
        exact[ok] = res.x
    closest = xs[rows, np.argmin(np.abs(fs), axis=1)]
    return np.where(np.isnan(exact), closest, exact)


def loop_margins(loop: LoopFn, design: Any, omega: np.ndarray, *,
                 open_loop_rhp_poles: np.ndarray | int = 0, max_depth: int = 9,
                 stability_only: bool = False,
                 block_cache: dict[str, np.ndarray] | None = None,
                 shared_forms: dict | None = None) -> Margins:
    """Margins and Nyquist stability of ``L`` for a batch of designs.

    A loop of a block diagram (``diagram.loop(sensor, cut)``, a
    :class:`~seactl.diagram.blockdiagram.Transfer`) is scanned by :func:`certified_margins`,
    which cannot skip a crossing or an encirclement and counts the closed loop's
    right-half-plane roots from the diagram's characteristic quasi-polynomial; ``omega``
    then only sets the frequency scale and ``open_loop_rhp_poles`` is not needed.
    Any other callable is scanned heuristically on ``omega`` (:func:`_heuristic_margins`).

    Parameters
    ----------
    loop : callable
        ``loop(design, s) -> L`` with ``s`` on the last axis, or a block-diagram loop.
    design : object
        Design batch; attributes are arrays broadcastable to ``design.shape``.
    omega : ndarray
        Grid [rad/s], shape ``(F,)`` or ``design.shape + (F,)``.  For an opaque
        callable its first point must lie below the loop's low-frequency features;
        intervals where the phase of ``L`` or ``1 + L`` turns by more than 60 degrees
        (or where ``log L`` moves by more than its distance to the unit circle or the
        negative real axis) are subdivided up to ``max_depth`` times.
    open_loop_rhp_poles : int or ndarray
        Opaque callables only: right-half-plane poles of ``L``.
    stability_only : bool
        Only the stability verdict (skip crossings).
    block_cache : dict, optional
        Opaque path only: shared block responses on the base grid.
    shared_forms : dict, optional
        Block-diagram loops only: kept by the caller between loops of the same diagram
        and design, whose characteristic terms are then evaluated once
        (:func:`~seactl.diagram.blockdiagram.evaluate_forms`).

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
    if isinstance(loop, Transfer) and loop.kind == "loop":
        w = np.asarray(omega, float)
        scale = np.sqrt(w[..., 0] * w[..., -1]) if w[..., 0].all() else w[..., -1] / 30.0
        return certified_margins(loop, design, scale, stability_only=stability_only,
                                 shared_forms=shared_forms)
    return _heuristic_margins(loop, design, omega, open_loop_rhp_poles, max_depth,
                              stability_only, block_cache)


def _heuristic_margins(loop: LoopFn, design: Any, omega: np.ndarray,
                       open_loop_rhp_poles: np.ndarray | int, max_depth: int,
                       stability_only: bool, block_cache: dict | None) -> Margins:
    """The grid scan of an opaque loop callable (see :func:`loop_margins`)."""
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    omega = np.broadcast_to(np.asarray(omega, float), shape + (np.shape(omega)[-1],))
    omega = omega.reshape(n, -1)
    P = np.broadcast_to(np.asarray(open_loop_rhp_poles, int), shape).reshape(n)
    scan = _Scan(loop, design, shape, stability_only)
    L0 = scan.segments(np.arange(n), omega, max_depth, block_cache)
    _extend_upwards(scan, L0, omega, max_depth)
    mag0 = np.abs(L0[:, :2])
    slope = -np.log(mag0[:, 1] / mag0[:, 0]) / np.log(omega[:, 1] / omega[:, 0])
    n0 = np.clip(np.round(slope), 0, None)  # poles of L at the origin
    Z = np.round(P + n0 / 2 - scan.winding(n) / np.pi).astype(int)
    if stability_only:
        return _stability_only(shape, Z == 0, Z)
    at = _subset_loop(loop, design, shape)
    phase = _far_phase_scan(loop, design, shape, omega, max_depth, scan.solve("phase"), at)
    return _assemble(shape, Z == 0, Z, scan.solve("gain"), phase, at)


def _far_phase_scan(loop: LoopFn, design: Any, shape: tuple[int, ...], omega: np.ndarray,
                    max_depth: int, phase: tuple[np.ndarray, np.ndarray],
                    at: Callable[[np.ndarray, np.ndarray], np.ndarray]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phase crossovers ``(design, w, L)`` of the grid scan of an opaque loop; designs with
    none in the band ``0.05 < |L| < 20`` are scanned again for phase crossings, the band
    widened as in :func:`_far_phase_crossovers` until one lies in it: the grid refined
    wherever ``|L|`` is in the band, extended upwards while ``|L|`` at its top is above
    the band's low end; their crossovers are those of their last scan."""
    b, w = phase
    L = at(b, w) if b.size else np.empty(0, complex)
    inside = (L.real < 0) & (np.abs(L) > _certify.BAND_LO) & (np.abs(L) < _certify.BAND_HI)
    todo = np.setdiff1d(np.arange(omega.shape[0]), b[inside])
    if todo.size == 0:
        return b, w, L
    for k in range(1, BAND_SCANS + 1):
        if todo.size == 0:
            break
        band = (_certify.BAND_LO / BAND_STEP ** k, _certify.BAND_HI * BAND_STEP ** k)
        scan = _Scan(loop, design, shape, False, band)
        L0 = scan.segments(todo, omega[todo], max_depth)
        _extend_upwards(scan, L0, omega[todo], max_depth, band[0], todo)
        sb, sw = scan.solve("phase")
        Ls = at(sb, sw) if sb.size else np.empty(0, complex)
        b, w, L = _replace_designs((b, w, L), todo, (sb, sw, Ls))
        inside = (Ls.real < 0) & (np.abs(Ls) > band[0]) & (np.abs(Ls) < band[1])
        todo = np.setdiff1d(todo, sb[inside])
    order = np.argsort(b, kind="stable")
    return b[order], w[order], L[order]


def _extend_upwards(scan: _Scan, L0: np.ndarray, omega: np.ndarray, max_depth: int,
                    level: float = 0.5, designs: np.ndarray | None = None) -> None:
    """Scan above the grid while ``|L|`` at its top is above ``level``; ``designs``: the
    designs of the rows of ``L0`` and ``omega`` (default: row ``i`` is design ``i``)."""
    top, w_top = np.abs(L0[:, -1]), omega[:, -1].copy()  # omega may be a broadcast view
    todo = np.nonzero(top > level)[0]
    for _ in range(max_depth):
        if todo.size == 0:
            break
        ext = w_top[todo, None] * np.logspace(0, 2, 61)
        Lx = scan.segments(todo if designs is None else designs[todo], ext, max_depth)
        w_top[todo] = ext[:, -1]
        todo = todo[np.abs(Lx[:, -1]) > level]


def _stability_only(shape: tuple[int, ...], stable: np.ndarray, Z: np.ndarray) -> Margins:
    n = int(np.prod(shape, dtype=int))
    nan = np.full(n, np.nan)
    empty = Crossings(np.empty(0, int), np.empty(0), np.empty(0))
    return Margins(*(x.reshape(shape) for x in (nan, nan, nan, nan, nan, stable, Z)),
                   gain_crossovers=empty, phase_crossovers=empty)


def _assemble(shape: tuple[int, ...], stable: np.ndarray, Z: np.ndarray,
              gain: tuple[np.ndarray, np.ndarray],
              phase: tuple[np.ndarray, np.ndarray, np.ndarray],
              at: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Margins:
    """Margins from the solved crossings ``(design index, omega)`` of every design (the
    phase crossovers with ``L`` there)."""
    n = int(np.prod(shape, dtype=int))
    b, wc = gain
    pm = _wrap180(180.0 + np.degrees(np.angle(at(b, wc)))) if b.size else np.empty(0)
    bp, w180, L180 = phase
    keep = np.real(L180) < 0
    bp, w180 = bp[keep], w180[keep]
    with np.errstate(divide="ignore"):
        gm = 1.0 / np.abs(L180[keep])
    pm_best, wc_best = _best(n, b, pm, wc, np.abs(pm))
    with np.errstate(divide="ignore"):
        gm_best, w180_best = _best(n, bp, gm, w180, np.abs(np.log(gm)))
    gain_crossovers = Crossings(b, wc, pm)
    dm = np.full(n, np.inf)
    if b.size:
        np.minimum.at(dm, b, gain_crossovers.delay_margin_s)
    dm = np.where(stable, dm, 0.0)
    res = (pm_best, wc_best / (2 * np.pi), gm_best, w180_best / (2 * np.pi), dm, stable, Z)
    return Margins(*(x.reshape(shape) for x in res),
                   gain_crossovers=gain_crossovers, phase_crossovers=Crossings(bp, w180, gm))


def _best(n: int, groups: np.ndarray, value: np.ndarray, omega: np.ndarray,
          key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per design, the value (default inf) and frequency (default NaN) of the smallest key."""
    best, w = np.full(n, np.inf), np.full(n, np.nan)
    if groups.size:
        first = first_per_design(groups, key)
        best[groups[first]], w[groups[first]] = value[first], omega[first]
    return best, w


# ----------------------------------------------------------------- the certified scan
TURN_FRACTION = 1.0 / 2.0
"""Base grid: no loop delay turns the phase by more than this fraction of a turn per step."""

PER_DECADE = 4
"""Base grid: points per decade at low frequency."""

MAX_BISECTIONS = _certify.MAX_BISECTIONS
"""Depth of bisection of a base-grid interval: its parts are then a few ulps of ``w`` wide
(a root of ``Delta`` or a tangency is what is left at that depth)."""

MAX_EVALUATIONS = _certify.MAX_EVALUATIONS
"""Per design: beyond this many bisections the scan stops refining that design (what it
has is kept; a design whose count or crossings are then not certified is uncertain, never
stable)."""

def _scan_radius(N: QuasiPolynomial, D: QuasiPolynomial, delta: QuasiPolynomial,
                 stability_only: bool, grid_count: Callable[[np.ndarray], np.ndarray],
                 band: tuple[float, float] = (_certify.BAND_LO, _certify.BAND_HI)
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per design, the ``R`` of step 4 of docs/theory/certified-scan.md, and whether the
    crossings beyond it are unresolved.  Beyond ``R`` the leading term of ``Delta``
    dominates and (crossings wanted) ``|L|`` stays off 1 and off the band's phase
    crossovers: ``|L| < lo`` for a strictly proper loop (``|N| < lo |D|``),
    ``|L| > hi`` for an improper one, and for a biproper one ``|L - L_inf| < eps``,
    ``L_inf`` the (real) ratio of the leading coefficients, ``eps`` half its distance to
    the unit circle and to the phase crossovers in the band.  Unresolved: ``eps = 0``
    (``|L_inf| = 1``, or ``L_inf`` on the negative real axis in the band), or ``R`` so far
    out that the base grid would exceed the evaluation budget (``grid_count``);
    ``delta = N + D``; ``band``: ``(lo, hi)``, the band of ``|L|`` whose phase crossings
    are wanted."""
    if stability_only:
        return cauchy_bound(delta), np.zeros(delta.degree.size, bool)
    lo, hi = band
    n = delta.degree
    nl, dl = _lead(N, n), _lead(D, n)
    aN, aD = N.abs_coeffs, D.abs_coeffs
    # Delta dominates beyond this radius, and a strictly proper L has |N| < lo |D| there
    top = cauchy_bound(delta, padded_sum(aN / lo, aD))
    unresolved = np.zeros(n.size, bool)
    i = np.nonzero((nl != 0) & (dl == 0))[0]  # improper: |N| > hi |D|
    if i.size:
        top[i] = np.maximum(top[i], cauchy_bound(
            N.take(i), padded_sum(aN[i], aD[i] / (1.0 / hi))))
    i = np.nonzero((nl != 0) & (dl != 0))[0]  # biproper: |N - L_inf D| < eps |D|
    if i.size:
        l_inf = nl[i] / dl[i]
        mag = np.abs(l_inf)
        off_axis = np.where(l_inf > 0, l_inf, np.maximum(lo - mag, mag - hi).clip(0.0))
        eps = np.minimum(0.5 * np.minimum(np.abs(mag - 1.0), off_axis), 1.0)
        safe = np.where(eps > 0, eps, 1.0)[:, None]
        major = padded_sum(aN[i] / safe, (mag[:, None] / safe + 1.0) * aD[i])
        wanted = top.copy()
        wanted[i] = np.maximum(top[i], cauchy_bound(D.take(i), major))
        bad = (eps == 0) | (grid_count(wanted)[i] > MAX_EVALUATIONS)
        unresolved[i[bad]] = True
        top[i[~bad]] = wanted[i[~bad]]
    return top, unresolved


def _lead(q: QuasiPolynomial, n: np.ndarray) -> np.ndarray:
    """Coefficient of ``s^n`` in ``q``'s undelayed term, per design."""
    c = q.coeffs[0]
    return np.where(n < c.shape[-1], c[np.arange(n.size), np.minimum(n, c.shape[-1] - 1)], 0.0)


def _base_grid(w_ref: np.ndarray, tau_max: np.ndarray, top: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per design, the base grid's start, linear step and end (the points themselves are
    made in the scan, :func:`seactl.certify.scan.grid_point`): 0, then ``PER_DECADE`` points
    per decade from ``0.01 w_ref`` on, steps never longer than ``TURN_FRACTION`` of a turn
    of the longest delay, to ``top`` (at least a decade above the start)."""
    w_lo = 0.01 * np.asarray(w_ref, float)
    with np.errstate(divide="ignore", over="ignore"):  # (no delay, or 1e-311 s: no limit)
        step = 2 * np.pi * TURN_FRACTION / np.asarray(tau_max, float)
    return w_lo, step, np.maximum(top, 10.0 * w_lo)


def _base_grid_count(w_ref: np.ndarray, tau_max: np.ndarray, top: np.ndarray) -> np.ndarray:
    """Points of :func:`_base_grid` per design (float: inf where ``top`` is; at most one
    too many)."""
    w_lo, step, top = _base_grid(w_ref, tau_max, top)
    ratio = 10.0 ** (1.0 / PER_DECADE)
    with np.errstate(divide="ignore", invalid="ignore"):
        # logarithmic up to where the next step would exceed the linear one
        w_lin = np.clip(step / (ratio - 1.0), w_lo, top)
        n_log = np.ceil(PER_DECADE * np.log10(w_lin / w_lo))
        n_lin = np.where(top > w_lin, np.ceil((top - w_lin) / step), 0.0)
    return n_log + n_lin + 2


BASE_POINT_SECONDS = 1.5e-6
"""Time of one base-grid point in the scan, its share of bisections included: an
estimate rounded up, for refusing work up front."""


def _check_grid_budget(count: np.ndarray, tau_max: np.ndarray, top: np.ndarray) -> None:
    """Refuse up front a scan that would take longer than the time budget
    (:func:`seactl.base.limits.check_budget`; its points are made as it goes, so memory does
    not grow with them): a long delay turns the phase once per ``2 pi / tau`` up to the
    scan's radius, which a very fast pole (a filter's cut-off at MHz) puts far out."""
    count = np.where(np.isnan(top), 0.0, count)  # no grid: not scanned, uncertain
    total = float(count.sum())
    i = int(np.argmax(count))
    if not (np.isfinite(top[i]) and np.isfinite(count[i])):
        raise ResourceError("the certified margin scan has no finite frequency range: the "
                            "loop's characteristic polynomial has coefficients that overflow "
                            "or vanish in double precision (so no bound on its roots); give "
                            "the loop a lower order or values of more moderate magnitude")
    check_budget(f"the certified margin scan ({total:.3g} frequency points)",
                 seconds=total * BASE_POINT_SECONDS,
                 hint=f"its largest design needs {count[i]:.3g}: a loop delay of "
                      f"{tau_max[i]:.3g} s turns the phase every "
                      f"{2 * np.pi / max(tau_max[i], 1e-300):.3g} rad/s up to {top[i]:.3g} "
                      "rad/s, where the loop's fastest pole lies; slow the fastest block "
                      "(a filter's cut-off) or shorten the delay")


def _solve_brackets(parts: list, loop_at: Callable[[np.ndarray, np.ndarray], np.ndarray],
                    kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Designs and refined frequencies of the crossings bracketed in ``parts`` (lists of
    ``(design, w_lo, w_hi)`` arrays)."""
    b = np.concatenate([p[0] for p in parts]) if parts else np.empty(0, int)
    if b.size == 0:
        return b, np.empty(0)
    lo = np.concatenate([p[1] for p in parts])
    hi = np.concatenate([p[2] for p in parts])
    return b, _refine(loop_at, b, lo, hi, kind)


class _CertifiedScan:
    """Certifies every base-grid interval by bisection (compiled: :mod:`seactl.certify.scan`;
    see :func:`certified_margins`); keeps the winding of ``Delta`` and the brackets."""

    def __init__(self, N: QuasiPolynomial, D: QuasiPolynomial, stability_only: bool,
                 band: tuple[float, float] = (_certify.BAND_LO, _certify.BAND_HI)):
        self.N, self.D = N, D
        self.stability_only = stability_only
        self.band = band  # the band of |L| whose phase crossings are certified
        self.winding = np.zeros(N.shape[0])
        self.uncertain = np.zeros(N.shape[0], bool)
        # L = 0: no crossing to certify (a sum of moduli is 0 only where all are)
        self.no_loop = ~columnwise(np.logical_or, N.abs_coeffs != 0)
        self.rows = np.empty((0, _certify.ROW))  # brackets (see _certify.scan)
        self.top = np.full(N.shape[0], np.nan)  # where each design's scan ends
        self.arrays = (*_certify.compact(N), *_certify.compact(D))

    def run(self, w_ref: np.ndarray, tau_max: np.ndarray, top: np.ndarray) -> None:
        """Scan each design's base grid (:func:`_base_grid`) up to ``top``; refused up
        front beyond the time budget (:func:`_check_grid_budget`)."""
        _check_grid_budget(_base_grid_count(w_ref, tau_max, top), tau_max, top)
        n = self.winding.size
        major = rounding_majorant(padded_sum(self.N.abs_coeffs, self.D.abs_coeffs), tau_max)
        w_lo, step, top = (np.broadcast_to(x, (n,)).astype(float)
                           for x in _base_grid(w_ref, tau_max, top))
        # (no finite grid: not scanned, and uncertain)
        bad = ~((0 < w_lo) & (w_lo < top) & (top < np.inf) & (step > 0))
        w_lo[bad], step[bad], top[bad] = 1.0, np.inf, 10.0
        self.top = top  # (where the scan ends: Stepan's tail is taken there)
        args = (*self.arrays, _certify.bound_table(major, self.N.bound3_coeffs,
                                                   self.D.bound3_coeffs),
                w_lo, PER_DECADE, step, top, self.stability_only, self.no_loop,
                _certify.band_table(np.full(n, self.band[0]), np.full(n, self.band[1])))

        def part(k: slice) -> np.ndarray:
            out = np.empty((16 * (k.stop - k.start) + 64, _certify.ROW))  # a few per design
            while True:
                self.winding[k], self.uncertain[k] = 0.0, False
                count = _certify.scan(*args, self.winding, self.uncertain, out, k.start, k.stop)
                if count <= out.shape[0]:
                    return out[:count]
                out = np.empty((count, _certify.ROW))  # more brackets than room: once more

        self.rows = np.concatenate(in_threads(part, n, min_per_thread=32))
        if bad.any():  # (a stand-in grid: no crossings)
            self.rows = self.rows[~bad[self.rows[:, 0].astype(int)]]
        self.uncertain |= bad

    def delta_at(self, w: np.ndarray) -> np.ndarray:
        """``Delta(jw) = N(jw) + D(jw)`` of every design at its ``w``."""
        return _certify.delta_values(*self.arrays, np.asarray(w, float))

    def loop_at(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        return _certify.loop_values(*self.arrays, np.asarray(idx, np.intp),
                                    np.asarray(w, float))

    def solve(self, kind: str) -> tuple[np.ndarray, np.ndarray]:
        """Designs and frequencies of the crossings: compiled safeguarded Newton on each
        bracket, :func:`_rebracket` where its ends no longer bracket."""
        code = _certify.GAIN if kind == "gain" else _certify.PHASE
        k = self.rows[:, 1]  # (compared, not taken modulo TOUCH: a float % costs more)
        rows = self.rows[(k == code) | (k == code + _certify.TOUCH)]
        b, x = rows[:, 0].astype(int), np.empty(len(rows))
        touch = rows[:, 1] != code  # (a point: its frequency is the touch)
        brackets, xb = rows, x  # (the usual case, no touch: no copies)
        if touch.any():
            x[touch] = np.log(rows[touch, 2])
            brackets, xb = rows[~touch], np.empty(int((~touch).sum()))
        in_threads(lambda k: _certify.refine(*self.arrays, brackets[k], _TOL["xatol"],
                                             _TOL["xrtol"], xb[k]), len(xb), min_per_thread=256)
        if xb is not x:
            x[~touch] = xb
        failed = np.nonzero(np.isnan(x))[0]
        if failed.size:
            x[failed] = _rebracket(_crossing_fn(self.loop_at, kind), b[failed],
                                   np.log(rows[failed, 2]), np.log(rows[failed, 3]))
        return b, np.exp(x)


def certified_margins(loop: Transfer, design: Any, w_ref: np.ndarray | float, *,
                      stability_only: bool = False, shared_forms: dict | None = None
                      ) -> Margins:
    """Margins and stability of a block-diagram loop by a scan that cannot skip.

    The loop ``L = diagram.loop(sensor, cut)`` is ``N / D`` with ``D`` the diagram's
    characteristic quasi-polynomial with ``sensor`` held and ``N + D = Delta`` the one
    of the closed loop (:meth:`~seactl.diagram.blockdiagram.BlockDiagram.return_difference`):
    every term is a polynomial ``p_k(s)`` times ``e^{-s tau_k}``, with known
    coefficients.  The scan bounds the derivatives of ``N``, ``D`` and ``Delta`` from
    their coefficients and delays, starts from a base grid up to the Cauchy bound ``R``
    (:func:`cauchy_bound`), and bisects each interval until a certificate shows that no
    root, gain or phase crossing, or extra turn of ``Delta`` can hide in it; beyond ``R``
    the leading term decides.  Stability is then counted from the winding of ``Delta``
    (Stepan's formula).  A tangency counts as a crossing and a root on the axis as not
    stable, so neither makes a margin larger or a design stable.  The argument step by
    step: docs/theory/certified-scan.md.

    Crossings are bracketed on certified intervals (the first interval, from ``w = 0``,
    is bisected until its part next to 0 is certified free of crossings) and solved on the
    exact ``N / D`` by Newton's method kept inside the bracket (compiled,
    :func:`seactl.certify.scan.refine`; two or three evaluations per crossing).

    Parameters
    ----------
    loop : Transfer
        ``diagram.loop(sensor, cut)``.
    design : object
        Design batch of that diagram.
    w_ref : array_like
        Frequency scale [rad/s] per design (start of the logarithmic part of the grid).
    stability_only : bool
        Only count roots (skip crossings).
    shared_forms : dict, optional
        As :func:`loop_margins`'s.

    Returns
    -------
    Margins
        ``unstable_poles`` is ``Z``, the closed loop's roots in the right half-plane.
    """
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    N, D = evaluate_forms(loop.diagram.return_difference(loop.input, loop.cut), design,
                          shared_forms)
    delta = N + D
    delta.require_retarded(f"loop of {loop.diagram.name!r} broken at {loop.input!r}")
    tau_max = np.concatenate([N.delays, D.delays]).max(axis=0)
    w_ref = np.broadcast_to(finite_array("w_ref [rad/s]", w_ref, minimum=0.0, strict=True),
                            shape).reshape(n)
    top, unresolved = _scan_radius(N, D, delta, stability_only,
                                   lambda top: _base_grid_count(w_ref, tau_max, top))
    scan = _CertifiedScan(N, D, stability_only)
    scan.run(w_ref, tau_max, top)
    Z, uncertain = _stepan_count(delta, scan)
    Z = np.maximum(Z, 1 * (uncertain & (Z == 0)))
    stable = (Z == 0) & ~uncertain & ~scan.uncertain & ~unresolved
    if stability_only:
        return _stability_only(shape, stable, Z)
    phase = _far_phase_crossovers(scan.solve("phase"), N, D, delta, (w_ref, tau_max),
                                  scan.loop_at, scan.uncertain | unresolved | scan.no_loop)
    return _assemble(shape, stable, Z, scan.solve("gain"), phase, scan.loop_at)


BAND_STEP = 3000.0
"""Each further scan for the phase crossovers of a design without one in the band
``0.05 < |L| < 20`` widens the band by this factor at both ends (69.5 dB)."""

BAND_SCANS = 3
"""Further scans at most: phase crossovers are resolved down to
``|L| = 0.05 / 3000^3`` (a gain margin of 234.6 dB) and up to ``20 * 3000^3``."""


def _far_phase_crossovers(phase: tuple[np.ndarray, np.ndarray], N: QuasiPolynomial,
                          D: QuasiPolynomial, delta: QuasiPolynomial,
                          grid: tuple[np.ndarray, np.ndarray],
                          loop_at: Callable[[np.ndarray, np.ndarray], np.ndarray],
                          skip: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phase crossovers ``(design, w, L)`` of every design: those of the first scan, except
    for designs (not ``skip``) with none in the band ``0.05 < |L| < 20``, which are
    scanned again with the band widened :data:`BAND_STEP`-fold at both ends, up to
    :data:`BAND_SCANS` times, until one lies in it; their crossovers are then those of
    their last certified scan.  Every crossover in a scan's band is certified and beyond
    its radius ``|L|`` stays outside the band (:func:`_scan_radius`), so the crossover in
    the band closest to ``|L| = 1`` in the log sense is the gain margin.  A design whose
    scan would exceed :data:`MAX_EVALUATIONS` base points, or is not certified, keeps
    what it has.  ``grid``: ``(w_ref, tau_max)`` per design."""
    b, w = phase
    L = loop_at(b, w) if b.size else np.empty(0, complex)
    inside = (L.real < 0) & (np.abs(L) > _certify.BAND_LO) & (np.abs(L) < _certify.BAND_HI)
    done = skip.copy()
    done[b[inside]] = True
    todo = np.nonzero(~done)[0]
    if todo.size == 0:
        return b, w, L
    for k in range(1, BAND_SCANS + 1):
        if todo.size == 0:
            break
        band = (_certify.BAND_LO / BAND_STEP ** k, _certify.BAND_HI * BAND_STEP ** k)
        w_ref, tau_max = (x[todo] for x in grid)
        count = lambda t, w_ref=w_ref, tau_max=tau_max: _base_grid_count(w_ref, tau_max, t)  # noqa: E731
        top, unresolved = _scan_radius(N.take(todo), D.take(todo), delta.take(todo), False,
                                       count, band)
        fits = ~unresolved & (_base_grid_count(w_ref, tau_max, top) <= MAX_EVALUATIONS)
        todo, w_ref, tau_max, top = todo[fits], w_ref[fits], tau_max[fits], top[fits]
        if todo.size == 0:
            break
        scan = _CertifiedScan(N.take(todo), D.take(todo), False, band)
        scan.run(w_ref, tau_max, top)
        sb, sw = scan.solve("phase")
        certain = ~scan.uncertain[sb]
        sb, sw = todo[sb[certain]], sw[certain]
        redone = todo[~scan.uncertain]
        Ls = loop_at(sb, sw) if sb.size else np.empty(0, complex)
        b, w, L = _replace_designs((b, w, L), redone, (sb, sw, Ls))
        inside = (Ls.real < 0) & (np.abs(Ls) > band[0]) & (np.abs(Ls) < band[1])
        found = np.zeros(skip.size, bool)
        found[sb[inside]] = True
        todo = redone[~found[redone]]
    b, w, L = _rational_phase_crossovers((b, w, L), N, D, grid, loop_at, todo)
    order = np.argsort(b, kind="stable")
    return b[order], w[order], L[order]


def _rational_phase_crossovers(phase: tuple[np.ndarray, np.ndarray, np.ndarray],
                               N: QuasiPolynomial, D: QuasiPolynomial,
                               grid: tuple[np.ndarray, np.ndarray],
                               loop_at: Callable[[np.ndarray, np.ndarray], np.ndarray],
                               todo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phase crossovers ``(design, w, L)``, those of the designs ``todo`` that have no delay
    replaced by all there are: ``L = N / D`` is on the real axis only where the polynomial
    ``Im(N(jw) conj D(jw))`` vanishes, so none lies beyond its roots' bound
    (:func:`_phase_polynomial_radius`), and a scan up to it certifying phase crossings of
    any ``|L|`` finds them all (none: the gain margin is ``inf``)."""
    w_ref, tau_max = grid
    todo = todo[tau_max[todo] == 0]
    if todo.size == 0:
        return phase
    top = _phase_polynomial_radius(N.take(todo), D.take(todo))
    fits = np.isfinite(top) & (_base_grid_count(w_ref[todo], tau_max[todo], top)
                               <= MAX_EVALUATIONS)
    todo, top = todo[fits], top[fits]
    if todo.size == 0:
        return phase
    scan = _CertifiedScan(N.take(todo), D.take(todo), False, (0.0, np.inf))
    scan.run(w_ref[todo], tau_max[todo], top)
    sb, sw = scan.solve("phase")
    certain = ~scan.uncertain[sb]
    sb, sw = todo[sb[certain]], sw[certain]
    Ls = loop_at(sb, sw) if sb.size else np.empty(0, complex)
    return _replace_designs(phase, todo[~scan.uncertain], (sb, sw, Ls))


def _phase_polynomial_radius(N: QuasiPolynomial, D: QuasiPolynomial) -> np.ndarray:
    """Per design of a loop ``N / D`` without delay, 1 % beyond Fujiwara's bound on the
    positive roots of ``p(w) = Im(N(jw) conj D(jw)) = sum_m p_m w^m``; ``inf`` where every
    coefficient is within its rounding error of 0 (``L`` real at every frequency).  The
    coefficients are exact sums of ``+-n_j d_k`` (``j + k = m``, the sign from
    ``Im(j^(j+k)) (-1)^k``); one within its rounding error of 0 is taken as 0."""
    n, d = N.coeffs.sum(axis=0), D.coeffs.sum(axis=0)      # (designs, powers) ascending
    size = n.shape[-1] + d.shape[-1] - 1
    p, mag = np.zeros((n.shape[0], size)), np.zeros((n.shape[0], size))
    for j in range(n.shape[-1]):
        for k in range(d.shape[-1]):
            sign = (-1) ** k * (0, 1, 0, -1)[(j + k) % 4]
            if sign:
                p[:, j + k] += sign * n[:, j] * d[:, k]
                mag[:, j + k] += np.abs(n[:, j] * d[:, k])
    p = np.where(np.abs(p) > 8 * np.finfo(float).eps * size * mag, p, 0.0)
    nonzero = p != 0
    top_m = np.where(nonzero.any(axis=1), size - 1 - np.argmax(nonzero[:, ::-1], axis=1), -1)
    rows = np.arange(p.shape[0])
    lead = np.abs(p[rows, np.maximum(top_m, 0)])
    m = np.arange(size)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(m < top_m[:, None],
                         (np.abs(p) / lead[:, None]) ** (1.0 / (top_m[:, None] - m)), 0.0)
    bound = 2.0 * ratio.max(axis=1, initial=0.0)
    return np.where(top_m > 0, 1.01 * bound, np.inf)


def _replace_designs(old: tuple[np.ndarray, ...], designs: np.ndarray,
                     new: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """Crossings ``(design, ...)``: those of ``old`` except ``designs``'s, then ``new``."""
    keep = ~np.isin(old[0], designs)
    return tuple(np.concatenate([o[keep], x]) for o, x in zip(old, new))


def _stepan_count(delta: QuasiPolynomial, scan: _CertifiedScan
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Right-half-plane roots from the winding of ``Delta`` on ``[0, top]`` plus the tail
    beyond ``top`` (step 6 of docs/theory/certified-scan.md), ``top`` where the scan ended:
    the Cauchy radius, or a decade above the grid's start where that is further out (the
    tail taken at the radius then counted the turn between the two twice, up to a root's
    worth); ``Delta(j top)`` from the scan's compiled evaluation
    (:meth:`_CertifiedScan.delta_at`: a seventh of the time of numpy's)."""
    n, top = delta.degree, scan.top
    rows = np.arange(n.size)
    lead = delta.coeffs[0, rows, n]
    tail = -np.angle(scan.delta_at(top) / (lead * (1j * top) ** n))
    z = n / 2.0 - (scan.winding + tail) / np.pi
    Z = np.round(z).astype(int)
    return Z, np.abs(z - Z) > 0.25


class _Scan:
    """Walks grid segments of many designs, subdividing where the phase moves fast.

    Collects the winding of ``1 + L`` per segment and the brackets of gain and
    phase crossovers, to be solved exactly at the end.
    """

    def __init__(self, loop: LoopFn, design: Any, shape: tuple[int, ...], stability_only: bool,
                 band: tuple[float, float] = (_certify.BAND_LO, _certify.BAND_HI)):
        self.loop, self.design, self.shape = loop, design, shape
        self.stability_only = stability_only
        self.band = band  # the band of |L| where phase crossings are looked for
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
            coarse |= (np.abs(dphi) > np.pi / 3) & (big > self.band[0])
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
            coarse |= (same_half & (big > self.band[0]) & (small < self.band[1])
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
        return _solve_brackets(self.brackets[kind],
                               _subset_loop(self.loop, self.design, self.shape), kind)

    def winding(self, n: int) -> np.ndarray:
        """Total phase change of ``1 + L`` [rad] per design."""
        if not self.wind_design:
            return np.zeros(n)
        return np.bincount(np.concatenate(self.wind_design),
                           weights=np.concatenate(self.wind_value), minlength=n)


def first_per_design(groups: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Index, per group, of the element with the smallest ``key`` (groups in sorted order;
    ties and NaN keys: the first)."""
    if groups.size and (groups[1:] >= groups[:-1]).all():  # (the usual case: linear time)
        start = np.flatnonzero(np.r_[True, groups[1:] != groups[:-1]])
        low = np.fmin.reduceat(key, start)
        at = np.repeat(low, np.diff(np.r_[start, groups.size]))
        first = np.minimum.reduceat(np.where(key == at, np.arange(key.size), key.size), start)
        return np.where(first < key.size, first, start)
    order = np.lexsort((key, groups))
    g = groups[order]
    return order[np.r_[True, g[1:] != g[:-1]]] if g.size else order


# --------------------------------------------------------------------------- SEA


def count_right_roots(q: QuasiPolynomial, w_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roots of a flat retarded quasi-polynomial with ``Re s > 0`` (multiplicity and
    conjugates counted), by the certified scan of :func:`certified_margins`
    (docs/theory/certified-scan.md, steps 2-4 and 6); and whether the count is certain
    (``False`` when a root lies on the axis)."""
    zero = QuasiPolynomial(np.zeros_like(q.coeffs[:1]), np.zeros_like(q.delays[:1]))
    scan = _CertifiedScan(q, zero, stability_only=True)
    top = cauchy_bound(q)
    scan.run(np.asarray(w_ref, float), q.delays.max(axis=0), top)
    Z, odd = _stepan_count(q, scan)
    return Z, ~odd & ~scan.uncertain


def check_count_budget(q: QuasiPolynomial, w_ref: np.ndarray) -> None:
    """Refuse up front, before other work, a :func:`count_right_roots` of the flat ``q``
    whose scan would exceed the time budget: its grid grows with the longest delay (one
    step per half turn of its phase up to the Cauchy radius)."""
    tau = q.delays.max(axis=0)
    top = cauchy_bound(q)
    ok = np.isfinite(top)  # (the others: left to the count itself, which says why)
    if ok.any():
        w = np.broadcast_to(np.asarray(w_ref, float), top.shape)[ok]
        _check_grid_budget(_base_grid_count(w, tau[ok], top[ok]), tau[ok], top[ok])


def closed_loop_right_roots(diagram: BlockDiagram, design: Any, w_ref: Any) -> np.ndarray:
    """Closed-loop roots with ``Re s > 0`` of a whole block diagram, per design (batch
    shape): :func:`count_right_roots` on its characteristic quasi-polynomial
    (:meth:`~seactl.diagram.blockdiagram.BlockDiagram.characteristic`), ``w_ref`` [rad/s] its
    frequency scale; -1 where no count can be certified (a root on the imaginary axis, a
    neutral delay equation).

    Examples
    --------
    ``y' = -a y(t - T)`` closed around an integrator is stable while ``a T < pi/2``:

    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> from seactl.diagram.blockdiagram import Block, BlockDiagram
    >>> g = BlockDiagram("lag", [Block("int", "u", "y", den=lambda p: (1.0, 0.0)),
    ...                          Block("fb", "y", "u", num=lambda p: (-p.a,), delay="T")])
    >>> p = SimpleNamespace(a=np.array([1.0, 2.0]), T=np.array([1.0, 1.0]), shape=(2,))
    >>> closed_loop_right_roots(g, p, 1.0).tolist()
    [0, 2]
    """
    shape = tuple(getattr(design, "shape", ()))
    q = diagram.characteristic().evaluate(design).flat()
    w = np.broadcast_to(np.asarray(w_ref, float), shape).reshape(q.shape[0])
    return certified_right_roots(q, w).reshape(shape)


def certified_right_roots(q: QuasiPolynomial, w_ref: np.ndarray) -> np.ndarray:
    """:func:`count_right_roots` of a flat quasi-polynomial, -1 where the count is not
    certain (a root on the axis) and everywhere if it is neutral."""
    if np.any(q.neutral):
        return np.full(q.shape[0], -1)
    Z, certain = count_right_roots(q, w_ref)
    return np.where(certain, Z, -1)
