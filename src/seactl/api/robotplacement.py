"""Where each loop of a robot may run: :class:`RobotPlacementResult`
(:meth:`seactl.api.robot.Robot.placement`).

Each placement puts every one of the placed loops (``stiffness``, ``damping``, and
optionally ``torque``) of every joint on the central process, with its latency, or on
the joints' embedded processes, with theirs; the loops not placed stay embedded.  Per
placement: the certified verdict, the generalized Nyquist phase margin of the
stiffness channels (:mod:`seactl.api.robotnyquist`), the central delay margin (the extra
latency of the central process, every loop on it delayed alike, that puts a root on the
imaginary axis: :meth:`seactl.System.delay_margin` along those loops) and the largest
central latency, the first crossing from a central latency of zero.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from seactl.base.result import Result, json_value, new_axes
from seactl.errors import InputError

PLACED = ("stiffness", "damping", "torque")
"""The loops a placement may move (per joint; the robot's ``delays`` keys)."""
PROCESSES = ("central", "embedded")


@dataclass(frozen=True)
class RobotPlacementOption:
    """One placement: ``processes`` (loop -> ``"central"`` or ``"embedded"``), the
    certified verdict ``stable``, the stiffness channels' generalized Nyquist
    ``phase_margin_deg`` [deg], the central ``delay_margin_s`` [s] and
    ``max_central_latency_s`` [s] (``inf`` when nothing runs centrally or no crossing)."""

    processes: dict
    stable: bool
    phase_margin_deg: float
    delay_margin_s: float
    max_central_latency_s: float

    def record(self) -> dict[str, Any]:
        """The option as a flat JSON-ready dict (latencies in ms)."""
        return {**self.processes, "stable": self.stable,
                "phase_margin_deg": json_value(self.phase_margin_deg),
                "delay_margin_ms": json_value(1e3 * self.delay_margin_s),
                "max_central_latency_ms": json_value(1e3 * self.max_central_latency_s)}


@dataclass(frozen=True, eq=False)
class RobotPlacementResult(Result):
    """Every placement of the robot's loops on the central and embedded processes.

    Parameters
    ----------
    joints, central_latency_s, embedded_latency_s, options : tuple or float
        As the attributes.

    Attributes
    ----------
    joints : tuple of str
        The joint names.
    central_latency_s, embedded_latency_s : float
        The processes' latencies [s].
    options : tuple of RobotPlacementOption
        One per placement, the most central first: ``processes``, ``stable``,
        ``phase_margin_deg``, ``delay_margin_s``, ``max_central_latency_s``.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
    ...              q0=[0.0, 1.5], fn_hz=14, filters_hz=(50, 100))   # doctest: +SKIP
    >>> p = r.placement(central_ms=5, embedded_ms=0.5)                # doctest: +SKIP
    >>> [round(o.max_central_latency_s * 1e3, 1) for o in p.options[:2]]  # doctest: +SKIP
    [8.1, 33.4]
    """

    joints: tuple
    central_latency_s: float
    embedded_latency_s: float
    options: tuple

    def option(self, **processes: str) -> RobotPlacementOption:
        """The option with these processes (``stiffness="central", damping="embedded"``).

        Parameters
        ----------
        **processes : str
            Loop -> ``"central"`` or ``"embedded"``; loops not given match any.

        Returns
        -------
        RobotPlacementOption
            The first option that matches.

        Raises
        ------
        InputError
            No option matches.
        """
        for o in self.options:
            if all(o.processes.get(k) == v for k, v in processes.items()):
                return o
        raise InputError("processes", processes, "placed loops (" + ", ".join(
            self.options[0].processes) + ") -> central or embedded")

    def to_dict(self) -> dict[str, Any]:
        return {"joints": list(self.joints),
                "central_latency_ms": 1e3 * self.central_latency_s,
                "embedded_latency_ms": 1e3 * self.embedded_latency_s,
                "options": self.records()}

    def records(self) -> list[dict[str, Any]]:
        return [o.record() for o in self.options]

    def plot(self, ax: Any = None) -> Any:
        """The largest central latency of each placement (stable ones in colour).

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
        labels = [", ".join(f"{k} {v[0]}" for k, v in o.processes.items())
                  for o in self.options]
        y = [1e3 * o.max_central_latency_s for o in self.options]
        ax.barh(labels, np.where(np.isfinite(y), y, np.nan),
                color=["tab:blue" if o.stable else "tab:red" for o in self.options])
        ax.axvline(1e3 * self.central_latency_s, color="k", lw=0.8)
        ax.set_xlabel("largest central latency [ms]")
        return ax


def _assignments(loops: tuple[str, ...]) -> list[dict[str, str]]:
    out = []
    for combo in itertools.product(PROCESSES, repeat=len(loops)):
        out.append(dict(zip(loops, combo)))
    return sorted(out, key=lambda p: -sum(v == "central" for v in p.values()))


def _placed(r: Any, processes: dict[str, str], central_s: float, embedded_s: float) -> Any:
    delays = {loop: embedded_s for loop in PLACED}
    delays.update({loop: central_s if p == "central" else embedded_s
                   for loop, p in processes.items()})
    return replace(r, delays=delays)


def _central_direction(r: Any, processes: dict[str, str]) -> dict[str, float]:
    central = {loop for loop, p in processes.items() if p == "central"}
    return {name: 1.0 for name in r.delay_terms().names if name.split(".")[0] in central}


def _option(r: Any, processes: dict[str, str], central_s: float, embedded_s: float
            ) -> RobotPlacementOption:
    from seactl.api.robotnyquist import mimo_margins

    placed = _placed(r, processes, central_s, embedded_s)
    m = mimo_margins(placed)
    direction = _central_direction(r, processes)
    if not direction:
        return RobotPlacementOption(processes, m.stable, m.phase_margin_deg, np.inf, np.inf)
    dm = float(placed.delay_margin(direction).delay_margin_s)
    top = float(_placed(r, processes, 0.0, embedded_s).delay_margin(direction).delay_margin_s)
    return RobotPlacementOption(processes, m.stable, m.phase_margin_deg, dm, top)


def robot_placement(r: Any, central_ms: float, embedded_ms: float,
                    loops: tuple[str, ...] = ("stiffness", "damping")) -> RobotPlacementResult:
    """The body of :meth:`seactl.api.robot.Robot.placement` (arguments there)."""
    from seactl.base.limits import check_range

    central = check_range("central_ms", central_ms, "delay_ms") * 1e-3
    embedded = check_range("embedded_ms", embedded_ms, "delay_ms") * 1e-3
    loops = tuple(loops) if not isinstance(loops, str) else (loops,)
    bad = [x for x in loops if x not in PLACED]
    if bad or not loops or len(set(loops)) != len(loops):
        raise InputError("loops", list(loops), "distinct loops among " + ", ".join(PLACED))
    options = tuple(_option(r, p, central, embedded) for p in _assignments(loops))
    return RobotPlacementResult(tuple(r.body.joints), central, embedded, options)
