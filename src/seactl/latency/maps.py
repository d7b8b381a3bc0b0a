"""Where latency hurts: per-loop delay margins and latency maps, rigid actuator and SEA.

The paper's central claim is that stability is far more sensitive to latency
in the damping loop than in the stiffness loop.  This module measures that,
on the block diagrams themselves:

* :func:`loop_delay_margins`: the smallest *extra* latency on only the
  stiffness loop (resp. only the damping loop) that destabilizes the closed
  loop.  The diagram's position measurement is split into one tap per loop
  (``x_s``/``x_d`` for the rigid actuator; :func:`sea_split_diagram` for the
  SEA, ``q_s``/``q_d``), the loop is broken at that tap with every other loop
  closed, and the delay margin of that loop transfer is exact: an extra delay
  ``tau`` on the stiffness path multiplies exactly that loop by ``e^{-s tau}``.
  The broken loop's own right-half-plane poles (those of the system with the
  path cut) are counted by Nyquist, closing the remaining loops one at a time.
* :func:`latency_map`: phase margin and stability over a grid of (stiffness
  delay, damping delay), one batched margin computation.
* :func:`max_stable_fn`: the highest ``f_n`` before the first instability (or
  before the phase margin drops below a floor), scanned as a batch axis and
  refined by vectorized bisection.
* :func:`pm_sensitivity`: ``d PM / d T_s``, ``d PM / d T_d`` and their ratio.

An actuator is described by a :class:`LoopModel` (:func:`rigid_model`,
:func:`sea_model`) that maps ``(f_n, T_s, T_d)`` to a design batch.

Examples
--------
>>> from seactl.systems.rigid.model import RigidDesign, UT_LINEAR
>>> d = RigidDesign.from_fn(UT_LINEAR, 8.0, T_s=1.5e-3, T_d=1.5e-3, f_v=50.0)
>>> dm = loop_delay_margins(rigid_model().diagram, d, rigid_model().grid(d),
...                         "x_s", "x_d")
>>> round(float(dm.stiffness_s) * 1e3, 2), round(float(dm.damping_s) * 1e3, 2)
(55.47, 9.55)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np

from seactl.analysis.margins import Margins, default_grid, first_per_design, loop_margins
from seactl.diagram.blockdiagram import BlockDiagram

# ------------------------------------------------------------------ per-loop delay margins


@dataclass(frozen=True)
class LoopDelayMargins:
    """Per-loop delay margins of a design batch (arrays of the batch shape).

    Attributes
    ----------
    stiffness_s : extra latency on the stiffness loop alone that destabilizes [s]
        (``inf``: no amount does; 0: already unstable).
    damping_s : the same for the damping loop alone [s].
    overall_s : extra latency on both loops together (the whole loop's delay margin) [s].
    stable : closed-loop stability of the nominal design.
    stiffness_crossover_hz, damping_crossover_hz : frequency at which the broken loop
        reaches -1 once that delay is added [Hz] (NaN without crossover).
    """

    stiffness_s: np.ndarray
    damping_s: np.ndarray
    overall_s: np.ndarray
    stable: np.ndarray
    stiffness_crossover_hz: np.ndarray
    damping_crossover_hz: np.ndarray

    @property
    def ratio(self) -> np.ndarray:
        """How many times more latency the stiffness loop tolerates than the damping loop."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.stiffness_s / self.damping_s


def unstable_poles(diagram: BlockDiagram, design: Any, omega: np.ndarray,
                   order: Sequence[str], held: Sequence[str] = ()) -> np.ndarray:
    """Closed-loop right-half-plane roots with the ``held`` signals cut (the loops broken
    at ``order`` closed), counted on the diagram's characteristic quasi-polynomial by
    :func:`~seactl.analysis.margins.certified_margins`."""
    shape = tuple(getattr(design, "shape", ()))
    if not order:
        return np.zeros(shape, int)
    m = loop_margins(diagram.loop(order[0], cut=tuple(sorted(held))), design, omega,
                     stability_only=True)
    return np.broadcast_to(np.asarray(m.unstable_poles), shape)


def path_margins(diagram: BlockDiagram, design: Any, omega: np.ndarray, path: str,
                 others: Sequence[str]) -> Margins:
    """Margins of the loop broken at tap ``path`` with every loop in ``others`` closed
    (``others`` lists the remaining breakable loops, innermost first)."""
    return loop_margins(diagram.loop(path), design, omega)


def loop_delay_margins(diagram: BlockDiagram, design: Any, omega: np.ndarray,
                       stiffness_tap: str, damping_tap: str, inner: Sequence[str] = (),
                       sensor: str | None = None) -> LoopDelayMargins:
    """Delay margin of the stiffness loop alone, of the damping loop alone, and of both.

    Parameters
    ----------
    diagram : BlockDiagram
        A diagram whose stiffness and damping blocks read separate taps.
    design, omega
        Design batch and bracketing grid (as for :func:`~seactl.analysis.margins.loop_margins`).
    stiffness_tap, damping_tap : str
        The signals the stiffness and damping blocks read.
    inner : sequence of str
        Loops inside both (e.g. the SEA torque loop ``tau_sens``), innermost first.
    sensor : str, optional
        The common measurement feeding both taps (whole-loop delay margin); default:
        the source of the stiffness tap's feeding block.
    """
    inner = tuple(inner)
    ms = path_margins(diagram, design, omega, stiffness_tap, inner + (damping_tap,))
    md = path_margins(diagram, design, omega, damping_tap, inner + (stiffness_tap,))
    if sensor is None:
        sensor = next(b.src for b in diagram.blocks if b.dst == stiffness_tap)
    mo = loop_margins(diagram.loop(sensor), design, omega)
    return LoopDelayMargins(ms.delay_margin_s, md.delay_margin_s, mo.delay_margin_s, mo.stable,
                            _dm_crossover(ms), _dm_crossover(md))


def _dm_crossover(m: Margins) -> np.ndarray:
    """Crossover frequency [Hz] of the crossing that sets the delay margin."""
    shape = m.stable.shape
    n = int(np.prod(shape, dtype=int))
    out = np.full(n, np.nan)
    c = m.gain_crossovers
    if c.design.size:
        first = first_per_design(c.design, c.delay_margin_s)
        out[c.design[first]] = c.omega[first] / (2 * np.pi)
    return out.reshape(shape)


@lru_cache(maxsize=1)
def sea_split_diagram() -> BlockDiagram:
    """:data:`~seactl.systems.sea.loops.SEA_DIAGRAM` with the joint measurement split into a
    stiffness tap ``q_s`` (read by ``Kq_fb``) and a damping tap ``q_d`` (read by
    ``Bq_fb``); every block is the SEA diagram's own."""
    from seactl.diagram.blockdiagram import Block
    from seactl.systems.sea.loops import SEA_DIAGRAM

    blocks = []
    for b in SEA_DIAGRAM.blocks:
        if b.name == "Kq_fb":
            b = replace(b, src="q_s")
        elif b.name == "Bq_fb":
            b = replace(b, src="q_d")
        blocks.append(b)
    blocks += [Block("s_tap", "q_sens", "q_s"), Block("d_tap", "q_sens", "q_d")]
    return BlockDiagram("sea-split", blocks)


# ------------------------------------------------------------------ actuator models
@dataclass(frozen=True)
class LoopModel:
    """How an actuator's designs, loops and margins are built from ``(f_n, T_s, T_d)``.

    Attributes
    ----------
    kind : ``"rigid"`` or ``"sea"``.
    actuator : the parameter set (:class:`~seactl.systems.rigid.model.RigidParams` or
        :class:`~seactl.systems.sea.actuators.SEAParams`).
    diagram : the split diagram (one tap per loop).
    stiffness_tap, damping_tap, sensor : signal names; ``inner``: inner loops.
    compliance : (output, input) of the compliance transfer, for the static stiffness.
    stiffness_unit : unit of the stiffness gain.
    options : keyword options of the design factory (filters, torque-loop delay, ...).
    """

    kind: str
    actuator: Any
    diagram: BlockDiagram
    stiffness_tap: str
    damping_tap: str
    sensor: str
    inner: tuple[str, ...]
    compliance: tuple[str, str]
    stiffness_unit: str
    fn_limits: tuple[float, float]
    factory: Callable[..., Any] = field(repr=False)
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.actuator.name

    def design(self, fn_hz, T_s, T_d, **overrides) -> Any:
        """Design batch for ``f_n`` [Hz] and delays [s] (broadcast together)."""
        return self.factory(self.actuator, fn_hz, T_s, T_d, **{**self.options, **overrides})

    def grid(self, design: Any) -> np.ndarray:
        if self.kind == "rigid":
            return default_grid(design.wn)
        from seactl.systems.sea.views import sea_reference_frequency

        return default_grid(sea_reference_frequency(design))

    def margins(self, design: Any, stability_only: bool = False) -> Margins:
        """Whole-loop margins with correct closed-loop stability."""
        omega = self.grid(design)
        return loop_margins(self.diagram.loop(self.sensor), design, omega,
                            stability_only=stability_only)

    def delay_margins(self, design: Any) -> LoopDelayMargins:
        return loop_delay_margins(self.diagram, design, self.grid(design), self.stiffness_tap,
                                  self.damping_tap, self.inner, self.sensor)

    def stiffness_gain(self, design: Any) -> np.ndarray:
        return design.K if self.kind == "rigid" else design.Kq

    def damping_gain(self, design: Any) -> np.ndarray:
        return design.B if self.kind == "rigid" else design.Bq

    def static_stiffness(self, design: Any) -> np.ndarray:
        """Closed-loop stiffness near zero frequency, from the diagram's compliance."""
        from seactl.systems.rigid.model import static_stiffness

        out, inp = self.compliance
        T = self.diagram.transfer(out, inp)
        scale = self.grid(design)[..., self.grid(design).shape[-1] // 2]
        return static_stiffness(design, T, scale)


def _rigid_factory(actuator, fn_hz, T_s, T_d, *, f_v=50.0, passive_damping=True):
    from seactl.systems.rigid.model import RigidDesign

    return RigidDesign.from_fn(actuator, fn_hz, T_s=T_s, T_d=T_d, f_v=f_v,
                               passive_damping=passive_damping)


def _sea_factory(actuator, fn_hz, T_s, T_d, *, T_tau=0.5e-3, f_qd=50.0, f_taud=100.0):
    from seactl.systems.sea.design import critically_damped_gains
    from seactl.systems.sea.loops import SEADesign, Timing

    return SEADesign(actuator, critically_damped_gains(actuator, fn_hz),
                     Timing(T_tau, T_s, T_d, f_qd, f_taud))


def rigid_model(actuator: Any = None, *, f_v: float | None = 50.0,
                passive_damping: bool = True) -> LoopModel:
    """The rigid actuator (default :data:`~seactl.systems.rigid.model.UT_LINEAR`), velocity filter
    ``f_v`` [Hz] (None: no filter)."""
    from seactl.systems.rigid.model import RIGID_DIAGRAM, UT_LINEAR, min_feasible_fn

    a = UT_LINEAR if actuator is None else actuator
    lo = max(1.001 * min_feasible_fn(a, passive_damping), 0.1)
    return LoopModel("rigid", a, RIGID_DIAGRAM, "x_s", "x_d", "x_sens", (), ("x", "F_ext"),
                     "N/m", (lo, 200.0), _rigid_factory,
                     {"f_v": f_v, "passive_damping": passive_damping})


def sea_model(actuator: Any = None, *, T_tau: float = 0.5e-3, f_qd: float | None = 50.0,
              f_taud: float | None = 100.0) -> LoopModel:
    """The SEA (default :data:`~seactl.systems.sea.actuators.UT_SEA`) with the torque loop delayed
    by
    ``T_tau`` [s] and Table I's filters; ``T_s``/``T_d`` are ``T_qs``/``T_qd``."""
    from seactl.systems.sea.actuators import UT_SEA
    from seactl.systems.sea.design import feasible_fn_range

    a = UT_SEA if actuator is None else actuator
    ranges = feasible_fn_range(a)
    lo = 1.0001 * ranges[0][0] if ranges else 1.0
    hi = min(ranges[0][1], 200.0) if ranges else 200.0
    return LoopModel("sea", a, sea_split_diagram(), "q_s", "q_d", "q_sens", ("tau_sens",),
                     ("q_j", "tau_ext"), "N m/rad", (lo, hi), _sea_factory,
                     {"T_tau": T_tau, "f_qd": f_qd, "f_taud": f_taud})


# ------------------------------------------------------------------ latency maps
@dataclass(frozen=True)
class LatencyMap:
    """Phase margin and stability over (stiffness delay, damping delay) at one ``f_n``.

    Arrays are indexed ``[i_s, i_d]`` (stiffness delay ``T_s[i_s]``, damping
    delay ``T_d[i_d]``, both [s]).  ``phase_margin_deg`` is ``inf`` where the
    loop never crosses 1 (not the case for these loops).
    """

    actuator: str
    kind: str
    fn_hz: float
    T_s: np.ndarray
    T_d: np.ndarray
    phase_margin_deg: np.ndarray
    stable: np.ndarray
    crossover_hz: np.ndarray


def latency_map(model: LoopModel, fn_hz: float, T_s: np.ndarray, T_d: np.ndarray
                ) -> LatencyMap:
    """Whole-loop phase margin and Nyquist stability on the grid ``T_s x T_d`` [s]."""
    T_s, T_d = np.asarray(T_s, float), np.asarray(T_d, float)
    d = model.design(fn_hz, T_s[:, None], T_d[None, :])
    m = model.margins(d)
    return LatencyMap(model.name, model.kind, float(fn_hz), T_s, T_d, m.phase_margin_deg,
                      m.stable, m.crossover_hz)


@dataclass(frozen=True)
class MaxFn:
    """Highest ``f_n`` [Hz] before the first failure of the criterion, per grid point.

    ``fn_hz`` is the last passing frequency found (bracket width ``< rtol``);
    ``status``: ``"ok"``, ``"none"`` (fails already at ``fn_lo``: ``fn_hz`` is NaN and
    means *no stable f_n*), or ``"capped"`` (passes up to ``fn_hi``: ``fn_hz = fn_hi``).
    """

    fn_hz: np.ndarray
    status: np.ndarray
    fn_lo: float
    fn_hi: float
    min_pm_deg: float | None


def max_stable_fn(model: LoopModel, T_s, T_d, *, min_pm_deg: float | None = None,
                  fn_lo: float | None = None, fn_hi: float | None = None, n_scan: int = 32,
                  rtol: float = 1e-4, extra_ok: Callable[..., np.ndarray] | None = None,
                  **overrides) -> MaxFn:
    """Highest ``f_n`` that keeps the closed loop stable (and, with ``min_pm_deg``, the
    phase margin at least that), for every ``(T_s, T_d)`` (broadcast) [s].

    ``extra_ok(design, margins, idx, scan_axis)`` (optional) adds a criterion, e.g. jitter
    margins: ``idx`` are the flat grid points being evaluated (``scan_axis``: the designs
    have a trailing ``f_n`` axis).

    ``f_n`` is scanned on ``n_scan`` log-spaced values in ``[fn_lo, fn_hi]`` as a
    batch axis; the first failing value brackets the boundary, refined by bisection
    (all grid points at once) to ``rtol``.  The answer is the top of the first passing
    range: an isolated stable pocket above a first instability is not counted.
    """
    lo = model.fn_limits[0] if fn_lo is None else fn_lo
    hi = model.fn_limits[1] if fn_hi is None else fn_hi
    # array-valued overrides (e.g. a torque-loop delay per point) broadcast with T_s, T_d
    per_point = {k: v for k, v in overrides.items() if np.ndim(v) > 0}
    fixed = {k: v for k, v in overrides.items() if k not in per_point}
    arrays = np.broadcast_arrays(np.asarray(T_s, float), np.asarray(T_d, float),
                                 *(np.asarray(v, float) for v in per_point.values()))
    shape = arrays[0].shape
    flat = [x.reshape(-1) for x in arrays]

    def ok(fn: np.ndarray, idx: np.ndarray, scan_axis: bool) -> np.ndarray:
        vals = [x[idx][:, None] if scan_axis else x[idx] for x in flat]
        extra = dict(zip(per_point, vals[2:]))
        d = model.design(fn, vals[0], vals[1], **fixed, **extra)
        m = model.margins(d, stability_only=min_pm_deg is None)
        good = m.stable
        if min_pm_deg is not None:
            good = good & (m.phase_margin_deg >= min_pm_deg)
        if extra_ok is not None:
            good = good & extra_ok(d, m, idx, scan_axis)
        return good

    n = flat[0].size
    scan = np.geomspace(lo, hi, n_scan)
    good = ok(scan, np.arange(n), True)                       # (n, n_scan)
    first_bad = np.where(good.all(axis=-1), n_scan, np.argmax(~good, axis=-1))
    none = first_bad == 0
    capped = first_bad == n_scan
    idx = np.nonzero(~none & ~capped)[0]
    a = np.full(n, lo)
    if idx.size:
        a_f, b_f = scan[first_bad[idx] - 1], scan[first_bad[idx]]   # passing, failing ends
        n_iter = int(np.ceil(np.log2(np.log(scan[1] / scan[0]) / np.log1p(rtol)))) + 1
        for _ in range(max(n_iter, 1)):
            mid = np.sqrt(a_f * b_f)
            g = ok(mid, idx, False)
            a_f, b_f = np.where(g, mid, a_f), np.where(g, b_f, mid)
        a[idx] = a_f
    none, capped, a = none.reshape(shape), capped.reshape(shape), a.reshape(shape)
    fn = np.where(none, np.nan, np.where(capped, hi, a))
    status = np.where(none, "none", np.where(capped, "capped", "ok"))
    return MaxFn(fn, status, float(lo), float(hi), min_pm_deg)


# ------------------------------------------------------------------ sensitivity
@dataclass(frozen=True)
class PMSensitivity:
    """Slopes of the phase margin [deg/ms] with respect to each loop's delay."""

    fn_hz: np.ndarray
    dpm_dTs_deg_per_ms: np.ndarray
    dpm_dTd_deg_per_ms: np.ndarray

    @property
    def ratio(self) -> np.ndarray:
        """``(d PM / d T_d) / (d PM / d T_s)``: how much more the damping delay costs."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.dpm_dTd_deg_per_ms / self.dpm_dTs_deg_per_ms


def pm_sensitivity(model: LoopModel, fn_hz, T_s, T_d, h: float = 1e-5) -> PMSensitivity:
    """Central differences (step ``h`` [s]) of the exact-delay phase margin.

    A useful identity: moving both delays together delays the whole loop, which
    lowers the margin by exactly ``w_c`` rad per second of delay, so
    ``dPM/dT_s + dPM/dT_d = -w_c 180/pi`` deg/s when ``T_s = T_d``.
    """
    fn = np.asarray(fn_hz, float)
    dts = np.array([h, -h, 0.0, 0.0])
    dtd = np.array([0.0, 0.0, h, -h])
    d = model.design(fn[..., None], np.asarray(T_s, float)[..., None] + dts,
                     np.asarray(T_d, float)[..., None] + dtd)
    pm = model.margins(d).phase_margin_deg
    ds = (pm[..., 0] - pm[..., 1]) / (2 * h) * 1e-3
    dd = (pm[..., 2] - pm[..., 3]) / (2 * h) * 1e-3
    return PMSensitivity(fn, ds, dd)
