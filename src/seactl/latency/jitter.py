"""Jitter margins: how much *time-varying* extra latency each loop tolerates.

Kao and Lincoln (2004, "Simple stability criteria for systems with time-varying
delays", Automatica 40) give a small-gain condition: a loop that is stable with
its nominal (constant, exact) delays stays stable for any extra delay that
varies arbitrarily in time within ``[0, delta]`` if

    ``|T(jw)| < 1 / (delta w)``   for every ``w > 0``,

where ``T = L / (1 + L)`` is the complementary sensitivity of the loop broken
where the varying delay acts.  The **jitter margin** is the largest such
``delta``::

    J = 1 / max_w (w |T(jw)|)      (0 for an unstable nominal loop).

It is sufficient, not necessary, and never larger than the delay margin for a
constant extra delay (a constant delay is one of the admitted variations);
e.g. Table I at 14 Hz: 8.04 ms against 9.45 ms for the whole outer loop.

The loops are broken at the taps of the split SEA diagram
(:func:`seactl.latency.maps.sea_split_diagram`): the whole outer loop (``q_sens``,
jitter on the joint measurement seen by both impedance loops), the stiffness
loop (``q_s``), the damping loop (``q_d``) and the torque loop (``tau_sens``),
every other loop closed.  ``T`` is derived from the block diagram with exact
delays, for a batch of designs at once: a log-frequency scan (single
precision) brackets every local maximum of ``w |T|`` within a factor 2 of the
scan's largest, and each is refined in double precision on the exact function
(three zooms on a 9-point sub-grid, each to a quarter of the bracket, then a
parabolic vertex): the bracket shrinks 64-fold, to 0.2 % in ``w``, and the peak
value is exact to about 1e-9 relative.  For a block-diagram loop the result is then
proven an upper bound over every ``w >= 0`` (:mod:`seactl.certify.supremum`), which also finds
a sharp peak the scan stepped over; ``inf`` (no margin) where it cannot be proven.

Examples
--------
A loop ``L = K / (s (tau s + 1))`` has ``max w |T| = K`` (at ``w = sqrt(K/tau)``),
so its jitter margin is ``1/K`` whatever ``tau``:

>>> import numpy as np
>>> from types import SimpleNamespace
>>> loop = lambda p, s: p.K[..., None] / (s * (p.tau[..., None] * s + 1))
>>> p = SimpleNamespace(K=np.array([10.0, 50.0]), tau=np.array([0.01, 0.2]), shape=(2,))
>>> peak, w = peak_omega_t(loop, p, np.logspace(-2, 4, 121))
>>> np.round(1 / peak, 9).tolist(), np.round(w ** 2 * p.tau, 4).tolist()
([0.1, 0.02], [10.0, 50.0])
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.analysis.margins import default_grid
from seactl.base import progress
from seactl.diagram.blockdiagram import DesignSubset, Transfer, evaluate_forms
from seactl.latency.maps import LoopModel, sea_split_diagram
from seactl.systems.sea.views import sea_margins, sea_reference_frequency

LoopFn = Callable[[Any, np.ndarray], np.ndarray]

SEA_TAPS: dict[str, str] = {"overall": "q_sens", "stiffness": "q_s", "damping": "q_d",
                            "torque": "tau_sens"}
"""Where each loop of the split SEA diagram is broken."""

CANDIDATE_RATIO = 0.5
"""Local maxima of the scan above this fraction of its largest are refined."""



def _omega_t(loop: LoopFn, design: Any, s: np.ndarray, cache: dict | None = None
             ) -> np.ndarray:
    """``w |T(jw)|`` with ``T = L/(1+L)``, ``s = jw`` on the last axis."""
    L = loop(design, s, cache=cache) if cache is not None else loop(design, s)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        T = L / (1.0 + L)
    return np.abs(s.imag) * np.abs(T)


def _scan(loop: LoopFn, design: Any, omega: np.ndarray, cache: dict | None,
          max_extend: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """``w |T|`` on the grid for a flat batch, extended upwards (x100 per round) for designs
    whose largest value sits at the top of the grid.  Returns the grid (NaN-padded where
    not extended) and the values (-inf there)."""
    n = omega.shape[0]
    single = isinstance(loop, Transfer)
    s = 1j * omega.astype(np.float32) if single else 1j * omega
    v = np.broadcast_to(_omega_t(loop, design, s, cache), omega.shape).astype(float)
    grids, values = [omega], [v]
    todo = np.nonzero(np.argmax(v, axis=1) == omega.shape[1] - 1)[0]
    top = omega[:, -1].copy()
    for _ in range(max_extend):
        if todo.size == 0:
            break
        ext = top[todo, None] * np.logspace(0, 2, 41)[1:]
        sub = DesignSubset(design, todo, (n,))
        se = 1j * ext.astype(np.float32) if single else 1j * ext
        ve = np.broadcast_to(_omega_t(loop, sub, se), ext.shape).astype(float)
        wg = np.full((n, ext.shape[1]), np.nan)
        vg = np.full((n, ext.shape[1]), -np.inf)
        wg[todo], vg[todo] = ext, ve
        grids.append(wg)
        values.append(vg)
        top[todo] = ext[:, -1]
        todo = todo[np.argmax(ve, axis=1) == ext.shape[1] - 1]
    return np.concatenate(grids, axis=1), np.concatenate(values, axis=1)


def peak_omega_t(loop: LoopFn, design: Any, omega: np.ndarray,
                 cache: dict | None = None, prove: Any = True
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Largest ``w |T(jw)|`` over ``w > 0`` and where it is reached, for a design batch.

    Parameters
    ----------
    loop : callable
        ``loop(design, s) -> L`` (e.g. a block-diagram
        :class:`~seactl.diagram.blockdiagram.Transfer`), ``s`` on the last axis.
    design : object
        Design batch (attributes broadcast to ``design.shape``).
    omega : numpy.ndarray
        Scan grid [rad/s], shape ``(F,)`` or ``design.shape + (F,)``, log-spaced, starting
        below the loop's bandwidth; it is extended upwards while the maximum is at its top.
    cache : dict, optional
        Shared block responses on ``omega`` (several loops of one diagram).
    prove : bool or array of bool, optional
        Designs whose peak is proven (block-diagram loops; default all); the others keep
        the scan's value (e.g. unstable designs, whose jitter margin is 0 anyway).

    Returns
    -------
    peak : numpy.ndarray
        ``max_w w |T(jw)|`` [1/s], batch shape (``1 / peak`` is the jitter margin [s]).
    omega_peak : numpy.ndarray
        Where it is reached [rad/s] (the grid's top when the supremum is approached only as
        ``w -> inf``).
    """
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    omega = np.broadcast_to(np.asarray(omega, float), shape + (np.shape(omega)[-1],))
    flat = DesignSubset(design, np.arange(n), shape)
    w, v = _scan(loop, flat, omega.reshape(n, -1), cache)
    best = np.argmax(v, axis=1)
    rows = np.arange(n)
    peak, wpk = v[rows, best].copy(), w[rows, best].copy()
    # Interior local maxima within CANDIDATE_RATIO of the largest: three-point brackets.
    mid = (v[:, 1:-1] >= v[:, :-2]) & (v[:, 1:-1] >= v[:, 2:]) & (v[:, 1:-1] > v[:, :-2]) \
        & (v[:, 1:-1] >= CANDIDATE_RATIO * peak[:, None]) & np.isfinite(v[:, 2:])
    b, i = np.nonzero(mid)
    if b.size:
        x, fx = _refine(loop, design, shape, b, w[b, i], w[b, i + 1], w[b, i + 2])
        better = fx > peak[b]
        order = np.argsort(fx)  # ascending: the largest per design is written last
        sel = order[better[order]]
        peak[b[sel]], wpk[b[sel]] = fx[sel], x[sel]
    todo = np.nonzero(np.broadcast_to(np.asarray(prove, bool), shape).reshape(n))[0]
    if isinstance(loop, Transfer) and loop.kind == "loop" and todo.size:
        g = omega.reshape(n, -1)[todo]
        peak[todo], wpk[todo] = _proven_peak(loop, DesignSubset(design, todo, shape),
                                             np.sqrt(g[:, 0] * g[:, -1]), peak[todo],
                                             wpk[todo])
    return peak.reshape(shape), wpk.reshape(shape)


def _proven_peak(loop: Transfer, design: Any, w_ref: np.ndarray, peak: np.ndarray,
                 w_peak: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The scan's peak made a proven upper bound of ``w |T|`` over every ``w >= 0``
    (:func:`seactl.certify.supremum.certify_peak`, raising it where a sharper peak is met), and
    ``inf`` where none can be proven (a neutral loop, the scan's budget): then no jitter
    margin is guaranteed."""
    from seactl.certify.supremum import certify_peak

    N, D = evaluate_forms(loop.diagram.return_difference(loop.input, loop.cut), design)
    delta = N + D
    out, w_peak = np.full(peak.shape, np.inf), np.array(w_peak, float)
    i = np.nonzero(~delta.neutral)[0]  # (a neutral design leaves the others proven)
    if i.size:
        bound, w_peak[i], proven = certify_peak(N.take(i), delta.take(i), w_ref[i], peak[i],
                                                w_peak[i])
        out[i] = np.where(proven, bound, np.inf)
    zero = (N.coeffs == 0).all(axis=(0, 2))  # T = 0: no peak
    return np.where(zero, 0.0, out), w_peak


def _refine(loop: LoopFn, design: Any, shape: tuple[int, ...], b: np.ndarray,
            w1: np.ndarray, w2: np.ndarray, w3: np.ndarray, passes: int = 3,
            points: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """Maximize ``w |T|`` in ``log w`` inside each bracket, in double precision: ``passes``
    zooms on a sub-grid of ``points`` (each keeps the two intervals around the best point,
    a quarter of the bracket), then the vertex of the parabola through the last best point
    and its neighbours (kept only if it improves)."""
    sub = DesignSubset(design, b.astype(np.intp), shape)
    lo, hi = np.log(w1), np.log(w3)
    frac = np.linspace(0.0, 1.0, points)
    rows = np.arange(b.size)
    for _ in range(passes):
        x = lo[:, None] + (hi - lo)[:, None] * frac
        fx = np.broadcast_to(_omega_t(loop, sub, 1j * np.exp(x)), x.shape)
        k = np.clip(np.argmax(fx, axis=1), 1, points - 2)
        lo, hi = x[rows, k - 1], x[rows, k + 1]
    f0, f1, f2 = fx[rows, k - 1], fx[rows, k], fx[rows, k + 1]
    h = x[rows, k] - lo
    with np.errstate(divide="ignore", invalid="ignore"):
        step = 0.5 * h * (f0 - f2) / (f0 - 2 * f1 + f2)
    xv = x[rows, k] + np.where(np.isfinite(step) & (np.abs(step) < h), step, 0.0)
    fv = np.broadcast_to(_omega_t(loop, sub, 1j * np.exp(xv)[:, None]), xv[:, None].shape)[:, 0]
    best = np.max(fx, axis=1)
    wbest = np.exp(x[rows, np.argmax(fx, axis=1)])
    use = fv > best
    return np.where(use, np.exp(xv), wbest), np.where(use, fv, best)


def jitter_margin_s(peak: np.ndarray, stable: np.ndarray | bool = True) -> np.ndarray:
    """``1 / peak`` [s] (``inf`` where ``peak == 0``), 0 where the nominal loop is
    unstable."""
    with np.errstate(divide="ignore"):
        j = np.where(np.asarray(peak) > 0, 1.0 / np.asarray(peak), np.inf)
    return np.where(stable, j, 0.0)


@dataclass(frozen=True)
class JitterMargins:
    """Jitter margins of a design batch (arrays of the batch shape, seconds).

    Attributes
    ----------
    overall_s : time-varying extra delay in ``[0, J]`` on the joint measurement (both
        impedance loops) that the whole outer loop is guaranteed to tolerate.
    stiffness_s, damping_s, torque_s : the same for the stiffness, damping and torque
        loops alone (every other loop closed, nominal delays).
    peak_hz : loop name -> frequency [Hz] where ``w |T|`` peaks.
    delay_margin_s : the whole outer loop's margin for a *constant* extra delay.
    stable : nominal closed-loop stability (margins are 0 where False).
    """

    overall_s: np.ndarray
    stiffness_s: np.ndarray
    damping_s: np.ndarray
    torque_s: np.ndarray | None
    peak_hz: dict[str, np.ndarray]
    delay_margin_s: np.ndarray
    stable: np.ndarray

    def ms(self, loop: str) -> np.ndarray:
        """Jitter margin [ms] of ``loop`` (``overall``, ``stiffness``, ``damping``,
        ``torque``)."""
        return np.asarray(getattr(self, f"{loop}_s")) * 1e3

    @property
    def bottleneck(self) -> np.ndarray:
        """Per design, the single loop with the smallest jitter margin."""
        names = [k for k in ("stiffness", "damping", "torque") if getattr(self, f"{k}_s")
                 is not None]
        stack = np.stack([np.asarray(getattr(self, f"{k}_s"), float) for k in names])
        return np.asarray(names, dtype=object)[np.argmin(stack, axis=0)]


def loop_jitter_margins(diagram_loops: Mapping[str, Transfer], design: Any, omega: np.ndarray,
                        stable: np.ndarray, delay_margin_s: np.ndarray) -> JitterMargins:
    """Jitter margins of the named loops (``overall``, ``stiffness``, ``damping`` and
    optionally ``torque``) of one diagram, sharing block evaluations on the scan grid."""
    cache: dict[str, np.ndarray] = {}
    peaks, where = {}, {}
    with progress.stage("jitter margins", total=len(diagram_loops), unit="loops") as stage:
        for name, loop in diagram_loops.items():  # (unstable: no margin, nothing to prove)
            peaks[name], where[name] = peak_omega_t(loop, design, omega, cache, prove=stable)
            stage.advance(item=name)
    jm = {k: jitter_margin_s(p, stable) for k, p in peaks.items()}
    return JitterMargins(jm["overall"], jm["stiffness"], jm["damping"], jm.get("torque"),
                         {k: w / (2 * np.pi) for k, w in where.items()},
                         np.asarray(delay_margin_s), np.asarray(stable))


def sea_jitter_grid(design: Any) -> np.ndarray:
    """Scan grid [rad/s] for SEA jitter margins: 1.5 decades below to 3 above the design's
    reference frequency, 32 points per decade."""
    return default_grid(sea_reference_frequency(design), 1.5, 3.0, 32)


def sea_jitter_margins(design: Any, omega: np.ndarray | None = None) -> JitterMargins:
    """Jitter margins of the SEA's outer, stiffness, damping and torque loops.

    Parameters
    ----------
    design : seactl.systems.sea.loops.SEADesign
        A batch of SEA designs.
    omega : numpy.ndarray, optional
        Scan grid [rad/s] (default :func:`sea_jitter_grid`).

    Returns
    -------
    JitterMargins
        With the nominal stability and the outer loop's delay margin of
        :func:`seactl.systems.sea.views.sea_margins`.

    Examples
    --------
    Table I, f_n = 14 Hz:

    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 14.0),
    ...               Timing.from_ms(0.5, 2.0, 0.5, 50.0, 100.0))
    >>> j = sea_jitter_margins(d)
    >>> round(float(j.ms("overall")), 2), round(float(j.delay_margin_s) * 1e3, 2)
    (8.04, 9.45)
    """
    m = sea_margins(design)
    if omega is None:
        omega = sea_jitter_grid(design)
    diagram = sea_split_diagram()
    loops = {k: diagram.loop(tap) for k, tap in SEA_TAPS.items()}
    return loop_jitter_margins(loops, design, omega, m.stable, m.delay_margin_s)


def model_jitter_margins(model: LoopModel, design: Any, margins: Any = None) -> JitterMargins:
    """Jitter margins of a :class:`~seactl.latency.maps.LoopModel`'s loops (rigid or SEA):
    the whole loop at its sensor, the stiffness and damping taps, and its inner loops
    (the SEA torque loop).  ``margins``: the design's whole-loop margins if already known
    (stability and delay margin are taken from them)."""
    m = model.margins(design) if margins is None else margins
    loops = {"overall": model.diagram.loop(model.sensor),
             "stiffness": model.diagram.loop(model.stiffness_tap),
             "damping": model.diagram.loop(model.damping_tap)}
    if model.inner:
        loops["torque"] = model.diagram.loop(model.inner[0])
    omega = model.grid(design)
    omega = np.asarray(omega)[..., :1] * np.logspace(0, 4.5, 145)
    return loop_jitter_margins(loops, design, omega, m.stable, m.delay_margin_s)
