"""Public entry points beyond the SEA batch: rigid actuator, latency maps, placement,
sweeps and the mobile base.

Each function is a thin, documented front to the module that does the work
(:mod:`seactl.rigid`, :mod:`seactl.latency`, :mod:`seactl.placement`,
:mod:`seactl.sweep`, :mod:`seactl.mobile_base`), with the units in its keyword names
(milliseconds for delays, hertz for frequencies) and results that have ``to_dict()``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ._results import (
    json_array,
    json_value,
)
from ._validate import finite_array
from .api import check_batch, delays_by_loop, delays_from_ms, resolve_actuator
from .errors import InputError
from .results import Result, flat_records, new_axes
from .system import System

KINDS = ("sea", "rigid")


def _jsonify(obj: Any) -> Any:
    """Dataclass dicts, tuples and arrays to JSON-ready values."""
    if isinstance(obj, dict):
        return {str(k): _jsonify(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonify(v) for v in obj]
    if isinstance(obj, (str, type(None))):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.ndarray):
        return json_array(obj) if obj.dtype.kind in "biuf" else obj.tolist()
    if isinstance(obj, (bool, int, float, np.generic)):
        return json_value(obj)
    return str(obj)


# ------------------------------------------------------------------ rigid actuator
RIGID_LOOPS = ("stiffness", "damping")
"""The rigid actuator's delayed loops, the keys of its ``delays_ms``."""


def _saturate_to_limit(saturate: bool) -> float | None:
    """The deprecated ``saturate=`` flag as ``saturation_a``: the actuator's limit, or
    none."""
    return None if saturate else math.inf


@dataclass(frozen=True, eq=False)
class RigidBatch(System):
    """A batch of critically-damped rigid-actuator designs (build with :func:`rigid`).

    The views are those of :class:`seactl.System`; the rigid actuator adds
    :meth:`delay_margins` and its force limit :attr:`max_force_n` (``beta`` times the
    current limit ``saturation_a``).

    Parameters
    ----------
    rigid : seactl.rigid.RigidDesign
        The underlying batch (actuator, gains ``K`` [N/m], ``B`` [N s/m], delays [s]).
    fn_hz : numpy.ndarray
        Natural frequencies [Hz] the gains were designed for.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid([8, 12], delays_ms={"stiffness": 15, "damping": 1})
    >>> r.shape, r.margins().stable.tolist(), isinstance(r, sc.System)
    ((2,), [True, True], True)
    """

    rigid: Any
    fn_hz: np.ndarray

    kind: ClassVar[str] = "rigid"
    loops: ClassVar[tuple[str, ...]] = RIGID_LOOPS
    step_unit: ClassVar[str] = "m"
    default_step: ClassVar[float] = 0.004
    impulse_unit: ClassVar[str] = "N s"
    default_impulse: ClassVar[float] = 10.0
    default_t_end_s: ClassVar[dict[str, float]] = {"step": 1.0, "impulse": 1.0}
    reference: ClassVar[str] = "x_des"
    disturbance: ClassVar[str] = "F_ext"
    output: ClassVar[str] = "x"
    actuation: ClassVar[str] = "F_des"
    sensor: ClassVar[str] = "x_sens"
    ports: ClassVar[tuple[str, ...]] = ("output",)
    export_step: ClassVar[float] = 0.004
    renamed: ClassVar[dict[str, Any]] = {
        "step": {"saturate": ("saturation_a", _saturate_to_limit)},
        "export": {"saturate": ("saturation_a", _saturate_to_limit)},
        "run": {"step_m": ("amplitude", None),
                "saturate": ("saturation_a", _saturate_to_limit)}}

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        return self.rigid.shape

    @property
    def design(self) -> Any:
        """The design batch the diagram's blocks read (:attr:`rigid`)."""
        return self.rigid

    @property
    def diagram(self) -> Any:
        """The rigid actuator's block diagram (:data:`seactl.rigid.RIGID_DIAGRAM`)."""
        from .rigid import RIGID_DIAGRAM

        return RIGID_DIAGRAM

    @property
    def actuator(self) -> Any:
        """The actuator (:class:`~seactl.rigid.RigidParams`)."""
        return self.rigid.actuator

    @property
    def gains(self) -> Any:
        """``K`` [N/m] and ``B`` [N s/m], broadcast to the batch shape."""
        from .rigid import RigidGains

        return RigidGains(*(np.broadcast_to(x, self.shape) for x in (self.rigid.K,
                                                                     self.rigid.B)))

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        """Loop name -> delay [s]: ``stiffness`` (T_s), ``damping`` (T_d).
        """
        return {"stiffness": self.rigid.T_s, "damping": self.rigid.T_d}

    @property
    def links(self) -> dict[str, str]:
        """Loop name -> delayed block of the diagram."""
        from .timing import MODEL_LINKS

        return MODEL_LINKS["rigid"]

    @property
    def max_current_a(self) -> float:
        """The actuator's current limit [A]."""
        return float(self.actuator.max_current)

    @property
    def max_force_n(self) -> float:
        """The actuator's force limit [N], ``beta * max_current``."""
        return float(self.actuator.max_force)

    @property
    def amperes_per_actuation(self) -> float:
        """The actuation signal is the force command: ``beta`` [N/A] per ampere."""
        return float(self.actuator.beta)

    def reference_frequency(self) -> np.ndarray:
        """The delay-free natural frequency ``sqrt(K/m)`` [rad/s] per design.

        Returns
        -------
        numpy.ndarray
            Per design [rad/s].
        """
        return self.rigid.wn

    def impulse_inertia(self) -> np.ndarray:
        """The mass ``m`` [kg] an impulse of external force hits.

        Returns
        -------
        numpy.ndarray
            Per design, in the kind's rotary or linear unit.
        """
        return np.asarray(self.rigid.m)

    def __getitem__(self, idx: Any) -> RigidBatch:
        from dataclasses import replace

        from .rigid import RigidGains

        shape = self.shape

        def pick(x: Any) -> Any:
            return None if x is None else np.broadcast_to(np.asarray(x, float), shape)[idx]

        if np.size(pick(self.fn_hz)) == 0:
            raise InputError("index", idx, "a selection of at least one design")
        g = self.rigid.gains
        sub = replace(self.rigid, gains=RigidGains(pick(g.K), pick(g.B)),
                      T_s=pick(self.rigid.T_s), T_d=pick(self.rigid.T_d),
                      f_v=pick(self.rigid.f_v))
        return RigidBatch(sub, pick(self.fn_hz))

    def label_columns(self, gains: bool = True) -> dict[str, Any]:
        """``fn_hz``, and with ``gains`` ``K`` and ``B`` (batch shape).

        Parameters
        ----------
        gains : bool
            Include the controller gains.

        Returns
        -------
        dict
            Column name -> array of the batch shape.
        """
        r = self.rigid
        return {"fn_hz": self.fn_hz, "K": r.K, "B": r.B} if gains else {"fn_hz": self.fn_hz}

    def labels(self) -> list[str]:
        """One legend label per design (flattened batch).

        Returns
        -------
        list of str
            ``"f_n=8 Hz, T_s=1.5 ms, T_d=1.5 ms"`` style labels.

        Examples
        --------
        >>> import seactl as sc
        >>> sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).labels()
        ['f_n=8 Hz, T_s=1.5 ms, T_d=1.5 ms']
        """
        r = self.rigid
        cols = [np.ravel(np.broadcast_to(x, self.shape)) for x in (self.fn_hz, r.T_s, r.T_d)]
        return [f"f_n={f:g} Hz, T_s={ts * 1e3:g} ms, T_d={td * 1e3:g} ms"
                for f, ts, td in zip(*cols)]

    # ------------------------------------------------------------ the rigid actuator's own
    def delay_margins(self) -> Any:
        """Extra latency the stiffness loop alone, the damping loop alone, and both tolerate.

        Returns
        -------
        seactl.latency.LoopDelayMargins
            ``stiffness_s``, ``damping_s``, ``overall_s`` [s] and their ``ratio``.

        Examples
        --------
        >>> import seactl as sc
        >>> dm = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).delay_margins()
        >>> round(float(dm.stiffness_s) * 1e3, 2), round(float(dm.damping_s) * 1e3, 2)
        (55.47, 9.55)
        """
        from .latency import rigid_model

        model = rigid_model(self.rigid.actuator)
        return model.delay_margins(self.rigid)

    def impedance_response(self, f_hz: Any, port: str) -> Any:
        """``Z(j 2 pi f) = F_ext / (j 2 pi f x)`` [N s/m] felt at the output: the inverse of the
        closed-loop compliance ``x / F_ext`` (:data:`seactl.rigid.RIGID_DIAGRAM`, exact
        delays) divided by ``s``; it includes the mass (:meth:`impedance`).

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0.
        port : {"output"}
            The rigid actuator's one port.

        Returns
        -------
        seactl.impedance.ImpedanceResponse
            The impedance [N s/m].
        """
        from .impedance import ImpedanceResponse
        from .rigid import rigid_compliance

        f = finite_array("f_hz [Hz]", f_hz, minimum=0.0, strict=True).reshape(-1)
        s = 2j * np.pi * f
        z = 1.0 / (s * rigid_compliance()(self.rigid, s))
        return ImpedanceResponse("block-diagram", f, z, "linear", True)

    def jitter_core(self) -> Any:
        """Jitter margins of the whole loop and the stiffness and damping loops
        (:func:`seactl.jitter.model_jitter_margins` of the rigid loop model).

        Returns
        -------
        seactl.jitter.JitterMargins
            Per loop, of the batch shape.
        """
        from .jitter import model_jitter_margins
        from .latency import rigid_model

        return model_jitter_margins(rigid_model(self.rigid.actuator), self.rigid)

    @staticmethod
    def control_transfers(name: str) -> Any:
        """``"loop"``, ``"closed"``, ``"compliance"`` -> (transfer, divide by ``-s``) for
        :meth:`to_control`.

        Parameters
        ----------
        name : str
            The transfer's name.

        Returns
        -------
        tuple
            ``(transfer, divide_by_minus_s)``.
        """
        from ._export import rigid_transfer

        return rigid_transfer(name)


def rigid(fn_hz: Any, *, actuator: Any = "ut-linear", delays_ms: Mapping[str, Any] | None = None,
          velocity_filter_hz: float | None = 50.0, passive_damping: bool = True) -> RigidBatch:
    """Critically-damped rigid-actuator designs ``K = m w_n^2``, ``B = 2 m w_n - b``.

    Parameters
    ----------
    fn_hz : array_like
        Natural frequency [Hz].
    actuator : str or path or RigidParams
        Preset (``"ut-linear"``), TOML file or :class:`~seactl.rigid.RigidParams`.
    delays_ms : dict, optional
        Loop name -> delay [ms] (array_like): ``"stiffness"`` (``T_s``), ``"damping"``
        (``T_d``); a loop not named has no delay.  The positional ``(T_s, T_d)`` is
        deprecated.
    velocity_filter_hz : float or None
        Cut-off of the first-order velocity filter [Hz]; None: no filter.
    passive_damping : bool
        Subtract the actuator's own damping ``b`` from ``B``.

    Returns
    -------
    RigidBatch
        The batch, of the broadcast shape of ``fn_hz`` and the delays.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid(12, delays_ms={"stiffness": 1, "damping": 15})
    >>> bool(r.margins().stable)                # 15 ms on the damping loop: unstable
    False
    >>> bool(sc.rigid(12, delays_ms={"stiffness": 15, "damping": 1}).margins().stable)
    True
    """
    from .rigid import RigidDesign, RigidParams, load_rigid

    act = resolve_actuator(actuator, load_rigid, RigidParams)
    fn = finite_array("fn_hz [Hz]", fn_hz, minimum=0.0, strict=True, nonempty=True)
    t_s, t_d = delays_by_loop(delays_ms, RIGID_LOOPS, ("T_s", "T_d"))
    check_batch(fn_hz=fn, delays_ms=(np.asarray(t_s) * 1e3, np.asarray(t_d) * 1e3))
    d = RigidDesign.from_fn(act, fn, T_s=t_s, T_d=t_d, f_v=velocity_filter_hz,
                            passive_damping=passive_damping)
    if 0 in d.shape:
        raise InputError("fn_hz, delays_ms, velocity_filter_hz", f"a batch of shape "
                         f"{d.shape}", "arrays with at least one value")
    return RigidBatch(d, np.broadcast_to(fn, d.shape))


# ------------------------------------------------------------------ latency maps
def loop_model(kind: str = "sea", actuator: Any = None, *, torque_delay_ms: float = 0.5,
               filters_hz: Sequence[Any] = (50.0, 100.0)) -> Any:
    """How designs of one actuator depend on ``(f_n, T_s, T_d)`` (for maps and placement).

    Parameters
    ----------
    kind : {"sea", "rigid"}
        SEA (stiffness ``K_q``, damping ``B_q`` around a torque loop) or rigid actuator.
    actuator : str or path or parameters, optional
        Default: the UT-SEA, or the UT linear actuator for ``"rigid"``.
    torque_delay_ms : float
        SEA only: torque-loop delay [ms].
    filters_hz : tuple
        SEA: ``(f_qd, f_taud)`` [Hz]; rigid: only the first (velocity filter) is used.

    Returns
    -------
    seactl.latency.LoopModel
        The model.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.loop_model("rigid").name
    'ut-linear'
    """
    from .latency import rigid_model, sea_model

    if kind not in KINDS:
        raise InputError("kind", kind, " or ".join(KINDS))
    if kind == "rigid":
        from .rigid import RigidParams, load_rigid

        act = None if actuator is None else resolve_actuator(actuator, load_rigid, RigidParams)
        return rigid_model(act, f_v=filters_hz[0])
    from .actuators import SEAParams, load_sea

    act = None if actuator is None else resolve_actuator(actuator, load_sea, SEAParams)
    (t_tau,) = delays_from_ms((torque_delay_ms,), ("T_tau",))
    return sea_model(act, T_tau=float(t_tau), f_qd=filters_hz[0], f_taud=filters_hz[1])


@dataclass(frozen=True)
class LatencyMapResult(Result):
    """Phase margin and stability over (stiffness delay, damping delay) at one ``f_n``.

    Parameters
    ----------
    map : seactl.latency.LatencyMap
        The computed map; arrays indexed ``[i_stiffness, i_damping]``.

    Attributes
    ----------
    map : seactl.latency.LatencyMap
        The computed map.
    actuator : str
        The actuator's name.
    kind : str
        ``"sea"`` or ``"rigid"``.
    fn_hz : float
        Natural frequency of the design [Hz].
    stiffness_delay_s, damping_delay_s : ndarray
        The grid's axes [s] (JSON ``stiffness_delay_ms``, ``damping_delay_ms``).
    phase_margin_deg : ndarray
        Whole-loop phase margin [deg], ``[i_stiffness, i_damping]``.
    crossover_hz : ndarray
        Its crossover frequency [Hz].
    stable : ndarray of bool
        Nyquist stability.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.latency_map(14, [0, 5, 10], [0, 1], torque_delay_ms=0.5)
    >>> m.to_dict()["damping_delay_ms"], m.phase_margin_deg.shape
    ([0.0, 1.0], (3, 2))
    """

    map: Any

    @property
    def actuator(self) -> str:
        """The actuator's name."""
        return self.map.actuator

    @property
    def kind(self) -> str:
        """``sea`` or ``rigid``."""
        return self.map.kind

    @property
    def fn_hz(self) -> float:
        """Natural frequency of the design [Hz]."""
        return self.map.fn_hz

    @property
    def stiffness_delay_s(self) -> np.ndarray:
        """Stiffness-loop delays [s] (rows)."""
        return self.map.T_s

    @property
    def damping_delay_s(self) -> np.ndarray:
        """Damping-loop delays [s] (columns)."""
        return self.map.T_d

    @property
    def phase_margin_deg(self) -> np.ndarray:
        """Whole-loop phase margin [deg]."""
        return self.map.phase_margin_deg

    @property
    def crossover_hz(self) -> np.ndarray:
        """Gain-crossover frequency [Hz]."""
        return self.map.crossover_hz

    @property
    def stable(self) -> np.ndarray:
        """Nyquist stability."""
        return self.map.stable

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready row per grid point (stiffness delay major).

        Returns
        -------
        list of dict
            ``stiffness_delay_ms``, ``damping_delay_ms``, ``phase_margin_deg``,
            ``crossover_hz``, ``stable``.
        """
        ts, td = np.meshgrid(self.stiffness_delay_s, self.damping_delay_s, indexing="ij")
        return flat_records({"stiffness_delay_ms": ts * 1e3, "damping_delay_ms": td * 1e3,
                             "phase_margin_deg": self.phase_margin_deg,
                             "crossover_hz": self.crossover_hz, "stable": self.stable})

    def to_dict(self) -> dict[str, Any]:
        """The map as JSON-ready lists (delays in ms).

        Returns
        -------
        dict
            ``actuator``, ``fn_hz``, ``stiffness_delay_ms``, ``damping_delay_ms``,
            ``phase_margin_deg``, ``stable``.
        """
        m = self.map
        return {"actuator": m.actuator, "kind": m.kind, "fn_hz": m.fn_hz,
                "stiffness_delay_ms": json_array(m.T_s * 1e3),
                "damping_delay_ms": json_array(m.T_d * 1e3),
                "phase_margin_deg": json_array(m.phase_margin_deg),
                "stable": json_array(m.stable)}

    def plot(self, ax: Any = None) -> Any:
        """Phase-margin contours over the two delays; unstable region hatched.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        m = self.map
        x, y = m.T_d * 1e3, m.T_s * 1e3
        pm = np.where(m.stable, m.phase_margin_deg, np.nan)
        cs = ax.contourf(x, y, pm, levels=12, cmap="viridis")
        ax.figure.colorbar(cs, ax=ax, label="phase margin [deg]")
        if (~m.stable).any():
            ax.contourf(x, y, (~m.stable).astype(float), levels=[0.5, 1.5], colors="none",
                        hatches=["//"])
        ax.set_xlabel("damping-loop delay [ms]")
        ax.set_ylabel("stiffness-loop delay [ms]")
        ax.set_title(f"{m.actuator}, f_n = {m.fn_hz:g} Hz")
        return ax


def latency_map(fn_hz: float, stiffness_delays_ms: Any, damping_delays_ms: Any, *,
                kind: str = "sea", actuator: Any = None, torque_delay_ms: float = 0.5,
                filters_hz: Sequence[Any] = (50.0, 100.0)) -> LatencyMapResult:
    """Phase margin and Nyquist stability on a grid of (stiffness delay, damping delay).

    Parameters
    ----------
    fn_hz : float
        Natural frequency [Hz] of the (critically-damped) design.
    stiffness_delays_ms, damping_delays_ms : array_like
        The grid's axes [ms].
    kind : {"sea", "rigid"}
        Actuator kind.
    actuator : str or path or parameters, optional
        As for :func:`loop_model`.
    torque_delay_ms : float
        SEA only: torque-loop delay [ms].
    filters_hz : tuple
        SEA: ``(f_qd, f_taud)`` [Hz]; rigid: the velocity filter first.

    Returns
    -------
    LatencyMapResult
        ``phase_margin_deg[i, j]`` at stiffness delay ``i`` and damping delay ``j``.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.latency_map(12, [1, 15], [1, 15], kind="rigid")
    >>> m.stable.tolist()                     # rows: stiffness delay, columns: damping
    [[True, False], [True, False]]
    """
    model = loop_model(kind, actuator, torque_delay_ms=torque_delay_ms, filters_hz=filters_hz)
    ts = delays_from_ms((stiffness_delays_ms,), ("stiffness_delays",))[0]
    td = delays_from_ms((damping_delays_ms,), ("damping_delays",))[0]
    check_batch(stiffness_delays_ms=ts.ravel() * 1e3,
                damping_delays_ms=td.ravel()[:, None] * 1e3)
    from .latency import latency_map as compute

    return LatencyMapResult(compute(model, float(fn_hz), np.ravel(ts), np.ravel(td)))


# ------------------------------------------------------------------ placement
@dataclass(frozen=True)
class PlacementResult(Result):
    """Which loop to run on which processor (see :func:`place`).

    Parameters
    ----------
    advice : seactl.placement.Advice
        The advisor's answer: ``recommended``, ``options`` per placement, ``reason``.

    Attributes
    ----------
    advice : seactl.placement.Advice
        The advisor's answer, every field.
    recommended : str or None
        ``"centralized"``, ``"distributed"``, ``"embedded"`` or None.
    options : tuple of seactl.placement.PlacementOption
        What each placement achieves.
    reason : str
        Why the recommendation.

    Examples
    --------
    >>> import seactl as sc
    >>> p = sc.place(22, 0.5)
    >>> [o["placement"] for o in p.to_dict()["options"]]
    ['centralized', 'distributed', 'embedded']
    >>> [r["placement"] for r in p.records()] == [o.placement for o in p.options]
    True
    """

    advice: Any

    @property
    def recommended(self) -> str | None:
        """``"centralized"``, ``"distributed"``, ``"embedded"`` or None."""
        return self.advice.recommended

    @property
    def options(self) -> tuple[Any, ...]:
        """What each placement achieves (:class:`seactl.placement.PlacementOption`)."""
        return self.advice.options

    @property
    def reason(self) -> str:
        """Why the recommendation."""
        return self.advice.reason

    def to_dict(self) -> dict[str, Any]:
        """The advice as JSON-ready values (delays in seconds, as in the advice).

        Returns
        -------
        dict
            Every field of :class:`seactl.placement.Advice`.
        """
        return _jsonify(asdict(self.advice))

    def records(self) -> list[dict[str, Any]]:
        """One flat JSON-ready row per placement option (delays in seconds).

        Returns
        -------
        list of dict
            ``placement``, ``status``, ``fn_hz`` (the score), ``stiffness_delay_s``,
            ``damping_delay_s``, ``phase_margin_deg``, ``crossover_hz``,
            ``stiffness_delay_margin_s``, ``damping_delay_margin_s``, ``bottleneck`` and
            ``recommended``.
        """
        return [{"placement": o.placement, "status": o.status, "fn_hz": json_value(o.fn_hz),
                 "stiffness_delay_s": json_value(o.T_s), "damping_delay_s": json_value(o.T_d),
                 "phase_margin_deg": json_value(o.phase_margin_deg),
                 "crossover_hz": json_value(o.crossover_hz),
                 "stiffness_delay_margin_s": json_value(o.stiffness_dm_s),
                 "damping_delay_margin_s": json_value(o.damping_dm_s),
                 "bottleneck": o.bottleneck, "recommended": o.placement == self.recommended}
                for o in self.options]

    def plot(self, ax: Any = None) -> Any:
        """Each placement's score, its latency-robust ``f_n`` [Hz]; the recommended one
        highlighted.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        names = [o.placement for o in self.options]
        scores = [o.fn_hz if o.fn_hz is not None else 0.0 for o in self.options]
        colors = ["tab:green" if n == self.recommended else "0.6" for n in names]
        ax.bar(names, scores, color=colors)
        ax.set_ylabel("latency-robust f_n [Hz]")
        ax.grid(True, axis="y", alpha=0.3)
        return ax


def place(high_latency_ms: float, low_latency_ms: float, *, kind: str = "rigid",
          actuator: Any = None, min_pm_deg: float = 45.0,
          stiffness_embeddable: bool = False, timing: Any = None,
          latency_margin: float = 0.5) -> PlacementResult:
    """Recommend where the stiffness and damping loops should run.

    Parameters
    ----------
    high_latency_ms, low_latency_ms : float
        Feedback latency of the high-level and of the embedded process [ms].
    kind : {"rigid", "sea"}
        Actuator kind (see :func:`loop_model`).
    actuator : str or path or parameters, optional
        Default: the UT linear actuator (rigid) or the UT-SEA.
    min_pm_deg : float
        Whole-loop phase margin [deg] required at every latency of the box.
    stiffness_embeddable : bool
        Whether the stiffness loop may run on the embedded process too.
    timing : dict, optional
        ``"high-level"`` / ``"embedded"`` -> :class:`seactl.placement.ProcessTiming`
        (latency distribution and loss): the nominal latency replaces the constant one and
        every loop's jitter margin must cover its process's jitter.
    latency_margin : float
        Fraction of its latency each loop must tolerate on top of it: placements are
        ranked by the largest ``f_n`` that is stable with ``min_pm_deg`` for every loop
        latency from 0 to ``1 + latency_margin`` times its own
        (:mod:`seactl.latency_box`); a longer latency never raises that score.

    Returns
    -------
    PlacementResult
        ``recommended`` and, per placement, its score ``f_n``, gains and bottleneck.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.place(22, 0.5).recommended
    'distributed'
    """
    model = loop_model(kind, actuator)
    high, low = delays_from_ms((high_latency_ms, low_latency_ms), ("high latency",
                                                                    "low latency"))
    from .placement import advise

    return PlacementResult(advise(model, float(high), float(low), min_pm_deg=min_pm_deg,
                                  stiffness_embeddable=stiffness_embeddable, timing=timing,
                                  latency_margin=latency_margin))


# ------------------------------------------------------------------ sweeps
def sweep(out: str | Path, *, actuator: Any = "ut-sea", sampling: str = "grid",
          n_samples: int = 0, seed: int = 0, chunk_size: int = 5000,
          z_freqs_hz: Sequence[float] = (), workers: int | None = None,
          scheduler: str | None = None, client: Any = None, resume: bool = False,
          overwrite: bool = False, **axes: Any) -> Any:
    """Sweep the SEA design space into a resumable Parquet dataset.

    Parameters
    ----------
    out : str or path
        Output directory (created; refused if it holds something else).
    actuator : str or path or SEAParams
        Nominal actuator.
    sampling : {"grid", "random", "lhs"}
        Cartesian grid, or ``n_samples`` random / Latin-hypercube points in the axes'
        ranges.
    n_samples, seed : int
        Sample count and seed of the sampling modes.
    chunk_size : int
        Points per chunk (one Parquet file each).
    z_freqs_hz : sequence of float
        Frequencies [Hz] at which to store ``|Z|``.
    workers : int, optional
        Local Dask worker processes (default: all cores; 0: in this process).
    scheduler : str, optional
        Address of a Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    client : distributed.Client, optional
        An existing Dask client.
    resume, overwrite : bool
        Finish an interrupted sweep / replace a previous one.
    **axes : array_like
        Values per axis, units in the names: ``fn_hz``, ``gs``, ``zeta1``, ``zeta2``,
        ``ratio``, ``t_tau_ms``, ``t_qs_ms``, ``t_qd_ms``, ``f_qd_hz``, ``f_taud_hz`` and
        plant parameters ``Im``, ``Ij``, ``bm``, ``bj``, ``k``, ``beta`` (rotary SI).

    Returns
    -------
    seactl.sweep.SweepResult
        Where the data went, counts, timing; read it with :func:`read_sweep`.

    Examples
    --------
    >>> import tempfile, seactl as sc
    >>> out = tempfile.mkdtemp() + "/s"
    >>> res = sc.sweep(out, fn_hz=[12, 14, 16], t_qs_ms=[0, 2], workers=0)
    >>> res.n_points, len(sc.read_sweep(out))
    (6, 6)
    """
    from .actuators import SEAParams, load_sea
    from .sweep import SweepSpec, run_sweep

    act = resolve_actuator(actuator, load_sea, SEAParams)
    spec = SweepSpec(act, axes=tuple((k, tuple(np.ravel(v))) for k, v in axes.items()),
                     sampling=sampling, n_samples=n_samples, seed=seed, chunk_size=chunk_size,
                     z_freqs_hz=tuple(z_freqs_hz))
    return run_sweep(spec, out, resume=resume, overwrite=overwrite, workers=workers,
                     scheduler=scheduler, client=client)


def read_sweep(out: str | Path, columns: Sequence[str] | None = None) -> Any:
    """Read a sweep dataset as one table sorted by point index.

    Parameters
    ----------
    out : str or path
        The sweep's output directory.
    columns : sequence of str, optional
        Columns to read (default: all).

    Returns
    -------
    pyarrow.Table
        One row per design point; ``.to_pandas()`` if pandas is installed.

    Examples
    --------
    >>> import tempfile, seactl as sc
    >>> out = tempfile.mkdtemp() + "/s"
    >>> _ = sc.sweep(out, fn_hz=[12, 14], workers=0)
    >>> [round(x, 2) for x in sc.read_sweep(out).column("phase_margin_deg").to_pylist()]
    [54.37, 55.51]
    """
    from .sweep import read_sweep as read

    return read(out, columns)


# ------------------------------------------------------------------ mobile base
def compare_mobile_base(params: Any = "trikey", *, archs: Sequence[str] = ("cosc", "dosc"),
                track: bool = True) -> Any:
    """Tune the omnidirectional base's controllers, centralized (COSC) vs distributed (DOSC).

    Runs the paper's procedure: raise damping until the base vibrates, then stiffness,
    then track a circle at a safety factor of both limits.

    Parameters
    ----------
    params : str or path or MobileBaseParams
        Preset (``"trikey"``), TOML file, or :class:`~seactl.mobile_base.MobileBaseParams`.
    archs : sequence of {"cosc", "dosc"}
        Architectures to tune.
    track : bool
        Also simulate the circle tracking (RMS errors).

    Returns
    -------
    seactl.mobile_base.MobileBaseComparison
        Per architecture: damping and stiffness limits, gains, RMS tracking errors;
        ``kx_ratio`` DOSC/COSC.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.mobile_base_params().name
    'trikey'
    >>> c = sc.compare_mobile_base()                    # doctest: +SKIP
    >>> round(c.kx_ratio, 1)                    # doctest: +SKIP
    6.4
    """
    from .mobile_base import tune

    return tune(mobile_base_params(params), tuple(archs), track=track)


def mobile_base_params(params: Any = "trikey") -> Any:
    """The mobile base's parameters: a preset name, a TOML file, or the object itself.

    Parameters
    ----------
    params : str or path or MobileBaseParams
        ``"trikey"`` (default), a TOML file, or a :class:`~seactl.mobile_base.MobileBaseParams`.

    Returns
    -------
    seactl.mobile_base.MobileBaseParams
        Validated parameters.

    Examples
    --------
    >>> import seactl as sc
    >>> round(sc.mobile_base_params().base_mass, 1)
    32.7
    """
    from .mobile_base import MobileBaseParams, load_base

    return resolve_actuator(params, load_base, MobileBaseParams)
