"""Public entry points beyond the SEA batch: rigid actuator, latency maps, placement,
sweeps and the mobile base.

Each function is a thin, documented front to the module that does the work
(:mod:`seactl.systems.rigid.model`, :mod:`seactl.latency.maps`, :mod:`seactl.latency.placement`,
:mod:`seactl.sweep.engine`, :mod:`seactl.systems.mobile_base.model`), with the units in its keyword
names
(milliseconds for delays, hertz for frequencies) and results that have ``to_dict()``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seactl.api.arguments import check_batch, delays_from_ms, resolve_actuator
from seactl.api.results import (
    json_array,
    json_value,
)
from seactl.base.result import Result, flat_records, new_axes
from seactl.errors import InputError

KINDS = ("sea", "rigid")


def jsonify(obj: Any) -> Any:
    """Dataclass dicts, tuples and arrays to JSON-ready values."""
    if isinstance(obj, dict):
        return {str(k): jsonify(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonify(v) for v in obj]
    if isinstance(obj, (str, type(None))):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.ndarray):
        return json_array(obj) if obj.dtype.kind in "biuf" else obj.tolist()
    if isinstance(obj, (bool, int, float, np.generic)):
        return json_value(obj)
    return str(obj)


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
    seactl.latency.maps.LoopModel
        The model.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.loop_model("rigid").name
    'ut-linear'
    """
    from seactl.latency.maps import rigid_model, sea_model

    if kind not in KINDS:
        raise InputError("kind", kind, " or ".join(KINDS))
    if kind == "rigid":
        from seactl.systems.rigid.model import RigidParams, load_rigid

        act = None if actuator is None else resolve_actuator(actuator, load_rigid, RigidParams)
        return rigid_model(act, f_v=filters_hz[0])
    from seactl.systems.sea.actuators import SEAParams, load_sea

    act = None if actuator is None else resolve_actuator(actuator, load_sea, SEAParams)
    (t_tau,) = delays_from_ms((torque_delay_ms,), ("T_tau",))
    return sea_model(act, T_tau=float(t_tau), f_qd=filters_hz[0], f_taud=filters_hz[1])


@dataclass(frozen=True)
class LatencyMapResult(Result):
    """Phase margin and stability over (stiffness delay, damping delay) at one ``f_n``.

    Parameters
    ----------
    map : seactl.latency.maps.LatencyMap
        The computed map; arrays indexed ``[i_stiffness, i_damping]``.

    Attributes
    ----------
    map : seactl.latency.maps.LatencyMap
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
    from seactl.latency.maps import latency_map as compute

    return LatencyMapResult(compute(model, float(fn_hz), np.ravel(ts), np.ravel(td)))


# ------------------------------------------------------------------ placement
@dataclass(frozen=True)
class PlacementResult(Result):
    """Which loop to run on which processor (see :func:`place`).

    Parameters
    ----------
    advice : seactl.latency.placement.Advice
        The advisor's answer: ``recommended``, ``options`` per placement, ``reason``.

    Attributes
    ----------
    advice : seactl.latency.placement.Advice
        The advisor's answer, every field.
    recommended : str or None
        ``"centralized"``, ``"distributed"``, ``"embedded"`` or None.
    options : tuple of seactl.latency.placement.PlacementOption
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
        """What each placement achieves (:class:`seactl.latency.placement.PlacementOption`)."""
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
            Every field of :class:`seactl.latency.placement.Advice`.
        """
        return jsonify(asdict(self.advice))

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
        ``"high-level"`` / ``"embedded"`` -> :class:`seactl.latency.placement.ProcessTiming`
        (latency distribution and loss): the nominal latency replaces the constant one and
        every loop's jitter margin must cover its process's jitter.
    latency_margin : float
        Fraction of its latency each loop must tolerate on top of it: placements are
        ranked by the largest ``f_n`` that is stable with ``min_pm_deg`` for every loop
        latency from 0 to ``1 + latency_margin`` times its own
        (:mod:`seactl.latency.box`); a longer latency never raises that score.

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
    from seactl.latency.placement import advise

    return PlacementResult(advise(model, float(high), float(low), min_pm_deg=min_pm_deg,
                                  stiffness_embeddable=stiffness_embeddable, timing=timing,
                                  latency_margin=latency_margin))
