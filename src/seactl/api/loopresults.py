"""Result objects of a user loop's views (:class:`seactl.UserLoop`): the sampled loop's
margins at every named break, jitter margins per break, step and impulse responses and
the impedance at a port.

They carry the same methods as the built-in systems' results (``to_dict()``,
``records()``, ``plot(ax=None)``) and the same column names; a user loop has named breaks
(per-break columns ``<break>_...``) and signals in its own units.  The continuous
margins are a :class:`LoopAnalysis`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from seactl.analysis.margins import Margins
from seactl.api.results import ImpedanceResult, ResponseResult, json_array, json_value
from seactl.base.result import Renamed, Result, flat_records, new_axes
from seactl.systems.sea.impedance import ImpedanceResponse


def _flat(x: Any, shape: tuple[int, ...]) -> np.ndarray:
    return np.ravel(np.broadcast_to(np.asarray(x), shape))


def plot_per_break(ax: Any, names: list[str], values: list[np.ndarray], ylabel: str) -> Any:
    """One line per break against the design index (a new figure if ``ax`` is None)."""
    ax = new_axes(ax)
    for name, v in zip(names, values):
        v = np.ravel(v).astype(float)
        ax.plot(np.arange(v.size), v, "o-", label=name)
    ax.set_xlabel("design (flattened batch)")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    return ax


SAMPLED_BREAK_COLUMNS = ("phase_margin_deg", "crossover_hz", "gain_margin_db",
                         "phase_crossover_hz", "delay_margin_ms", "delay_margin_samples",
                         "jitter_margin_ms", "jitter_margin_samples")
"""The per-break columns of :meth:`LoopSampledMargins.records`."""


class LoopSampledMargins(Mapping):
    """Certified verdict and margins of a user loop sampled at its process rates, per
    break: a mapping break name -> :class:`~seactl.SampledMarginsResult` (one verdict,
    the whole loop's), with :meth:`records`, :meth:`to_dict` and :meth:`plot`.

    Parameters
    ----------
    loop : str
        The loop's name.
    breaks : dict
        Break name -> :class:`~seactl.SampledMarginsResult` (label columns included).
    """

    def __init__(self, loop: str, breaks: dict[str, Any]):
        self.loop = loop
        self.breaks = dict(breaks)

    def __getitem__(self, name: str) -> Any:
        return self.breaks[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.breaks)

    def __len__(self) -> int:
        return len(self.breaks)

    def __repr__(self) -> str:
        return f"LoopSampledMargins(loop={self.loop!r}, breaks={list(self.breaks)})"

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready row per design (C order): the label columns, ``rate_hz``,
        ``verdict``, ``unstable_modes`` and ``stable`` (the whole loop's), then per break
        ``<b>`` the margins of :meth:`seactl.SampledMarginsResult.records` as
        ``<b>_phase_margin_deg``, ``<b>_delay_margin_ms``, ...

        Returns
        -------
        list of dict
            Rows, designs in C order.
        """
        per = {name: r.records() for name, r in self.breaks.items()}
        if not per:
            return []
        first = next(iter(per.values()))
        rows = []
        for i, row in enumerate(first):
            out = {k: v for k, v in row.items() if k not in SAMPLED_BREAK_COLUMNS}
            for name, recs in per.items():
                out.update({f"{name}_{k}": v for k, v in recs[i].items()
                            if k in SAMPLED_BREAK_COLUMNS})
            rows.append(out)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """``{"loop": ..., "breaks": {name: SampledMarginsResult.to_dict()}}``.

        Returns
        -------
        dict
            JSON-ready.
        """
        return {"loop": self.loop,
                "breaks": {name: r.to_dict() for name, r in self.breaks.items()}}

    def plot(self, ax: Any = None) -> Any:
        """Phase margin of every break of the sampled loop against the design index.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        return plot_per_break(ax, list(self.breaks),
                               [r.phase_margin_deg for r in self.breaks.values()],
                               "phase margin [deg]")


@dataclass(frozen=True)
class LoopJitterResult(Result):
    """Jitter margins of a user loop at every named break (arrays of the batch shape).

    The jitter margin at a break is the largest ``J`` such that any time-varying extra
    delay in ``[0, J]`` there keeps the closed loop stable (Kao-Lincoln small-gain bound,
    sufficient); 0 for an unstable design.  The columns mirror
    :class:`~seactl.JitterResult`: ``jitter_margin_ms`` is the outermost (last) break's,
    ``<break>_jitter_margin_ms`` each break's, ``delay_margin_ms`` the outermost break's.

    Attributes
    ----------
    loop : str
        The loop's name.
    break_jitter_margins_s : dict
        Break name -> jitter margin [s].
    break_delay_margins_s : dict
        Break name -> delay margin [s].
    jitter_margin_s : ndarray
        The outermost (last) break's jitter margin [s].
    delay_margin_s : ndarray
        The outermost break's delay margin [s].
    stable : ndarray
        Closed-loop stability.
    labels : dict
        Label columns of :meth:`records`.
    """

    loop: str
    break_jitter_margins_s: dict[str, np.ndarray]
    break_delay_margins_s: dict[str, np.ndarray]
    stable: np.ndarray
    labels: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def jitter_margin_s(self) -> np.ndarray:
        """The outermost (last) break's jitter margin [s]."""
        return self.break_jitter_margins_s[list(self.break_jitter_margins_s)[-1]]

    @property
    def delay_margin_s(self) -> np.ndarray:
        """The outermost break's delay margin [s]."""
        return self.break_delay_margins_s[list(self.break_delay_margins_s)[-1]]

    def ms(self, name: str) -> np.ndarray:
        """A break's jitter margin [ms].

        Parameters
        ----------
        name : str
            A break name.

        Returns
        -------
        ndarray
            Batch shape.
        """
        return np.asarray(self.break_jitter_margins_s[name]) * 1e3

    def _columns(self) -> dict[str, np.ndarray]:
        shape = np.shape(self.stable)
        cols = {k: np.broadcast_to(np.asarray(v), shape) for k, v in self.labels.items()}
        cols["jitter_margin_ms"] = np.asarray(self.jitter_margin_s) * 1e3
        for name in self.break_jitter_margins_s:
            cols[f"{name}_jitter_margin_ms"] = self.ms(name)
        cols["delay_margin_ms"] = np.asarray(self.delay_margin_s) * 1e3
        cols["stable"] = self.stable
        return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design (C order).

        Returns
        -------
        list of dict
            The label columns, ``jitter_margin_ms``, ``<break>_jitter_margin_ms``,
            ``delay_margin_ms``, ``stable``.
        """
        cols = {k: np.ravel(v) for k, v in self._columns().items()}
        n = cols["stable"].size
        return [{k: json_value(v[i]) for k, v in cols.items()} for i in range(n)]

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape.

        Returns
        -------
        dict
            The columns of :meth:`records`.
        """
        return {k: json_array(v) for k, v in self._columns().items()}

    def plot(self, ax: Any = None) -> Any:
        """Every break's jitter margin against the design index, log scale.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        names = list(self.break_jitter_margins_s)
        ax = plot_per_break(ax, names, [self.ms(n) for n in names], "jitter margin [ms]")
        ax.set_yscale("log")
        return ax


@dataclass(frozen=True)
class UserLoopResponse:
    """A simulated response of a user loop with its metrics: ``position`` is the output
    signal (normalized to the step for steps, in its own unit for impulses), ``current``
    the input of the loop's ``current_to_torque`` block when it has exactly one (else
    None)."""

    kind: str
    result: Any
    metrics: Any
    output: str
    amplitude: float
    current_signal: str | None = None

    @property
    def t_s(self) -> np.ndarray:
        return self.result.t_s

    @property
    def position(self) -> np.ndarray:
        y = self.result.outputs[self.output]
        return y / self.amplitude if self.kind == "step" else y

    @property
    def current(self) -> np.ndarray | None:
        return None if self.current_signal is None else self.result.outputs[self.current_signal]


class LoopResponseResult(ResponseResult):
    """A user loop's step or impulse response (:class:`~seactl.ResponseResult` with the
    loop's signal names).

    Attributes
    ----------
    kind, mode : str
        ``"step"`` or ``"impulse"``; ``"continuous"`` or ``"sampled"``.
    output : str
        The output signal.
    output_unit : str
        ``""``: a loop file declares no unit for its output.
    amplitude : float
        Step size, or impulse area, in the loop file's units.
    amplitude_unit : str
        Its unit (:attr:`seactl.UserLoop.step_unit` or ``impulse_unit``).
    t_s : ndarray
        Time [s].
    position : ndarray
        The output (divided by the step for steps), ``batch + (T,)``.
    current_a : ndarray or None
        The input of the loop's ``current_to_torque`` block (its unit is the loop
        file's), if it has exactly one.
    outputs : dict
        Every simulated signal as simulated (not normalized).
    metrics : StepMetrics or ImpulseMetrics
        As the built-in systems' responses.
    requested_delays_s, effective_delays_s : dict
        Delayed block -> delay [s]: as asked, and as simulated (sampled: ``T_s/2 + n T_s``,
        never shorter).
    result : seactl.simulate.results.SimResult
        The simulation itself.
    stable : ndarray
        Whether each simulated response stayed bounded and decayed.
    left_bounds_s : ndarray
        Per design, the time a diverging response left its bound [s] (NaN: never).
    info : dict
        The simulation's details (delays, sampled verdict, ...).

    Parameters
    ----------
    response : UserLoopResponse
        The simulation and its metrics.
    labels : list of str
        One legend label per design.
    right_roots : callable
        The certified count of right-half-plane roots per design (continuous mode).
    amplitude_unit : str
        The unit of ``amplitude``.
    """

    def __init__(self, response: UserLoopResponse, labels: list[str], right_roots: Any,
                 amplitude_unit: str = ""):
        self._inner = self._response = response
        self._links = None
        self.labels = labels
        self._right_roots = right_roots
        self.amplitude_unit = amplitude_unit
        self.output_unit = ""   # a loop file names its output, not the output's unit

    kind = property(lambda self: self._inner.kind)
    mode = property(lambda self: self._inner.result.mode)
    output = property(lambda self: self._inner.output)
    amplitude = property(lambda self: self._inner.amplitude)
    t_s = property(lambda self: self._inner.t_s)
    position = property(lambda self: self._inner.position)
    current_a = property(lambda self: self._inner.current)
    current = Renamed("current_a")
    metrics = property(lambda self: self._inner.metrics)
    result = property(lambda self: self._inner.result)
    outputs = property(lambda self: self._inner.result.outputs)
    stable = property(lambda self: self._inner.result.stable)
    left_bounds_s = property(lambda self: self._inner.result.left_bounds_s)
    info = property(lambda self: self._inner.result.info)

    @property
    def requested_delays_s(self) -> dict[str, np.ndarray]:
        """Delayed block -> the delay asked for [s]."""
        return dict(self.info.get("requested_delays_s", {}))

    @property
    def effective_delays_s(self) -> dict[str, np.ndarray]:
        """Delayed block -> the delay simulated [s] (sampled: ``T_s/2 + n T_s``, never
        shorter than asked)."""
        return dict(self.info.get("effective_delays_s", {}))

    def __repr__(self) -> str:
        return f"LoopResponseResult(kind={self.kind!r}, mode={self.mode!r}, " \
               f"output={self.output!r}, shape={np.shape(self.position)})"

    def verdict(self, band: float | None = None) -> Any:
        """Settled, not settled, unstable, limit cycle or saturated per design, with the
        evidence, as :meth:`seactl.ResponseResult.verdict` (certified root count in
        continuous mode; the sampled loop's certified count of growing modes in sampled
        mode).

        Parameters
        ----------
        band : float, optional
            Settling band relative to the step (default 0.02), or recovery band relative
            to the impulse's peak deviation (default 0.05).

        Returns
        -------
        seactl.simulate.verdict.TimeVerdict
            ``verdict`` (one string per design), ``warnings`` and ``evidence(i)``.
        """
        from seactl.simulate.verdict import RECOVERY_BAND, STEP_BAND, judge

        step = self.kind == "step"
        t = self.t_s
        y = np.asarray(self.position, float).reshape(-1, t.size)
        cur = self.current_a
        rhp = (self.info.get("unstable_modes") if self.mode == "sampled"
               else self._right_roots())
        return judge(t, y, target=1.0 if step else 0.0,
                     scale=1.0 if step else np.abs(y).max(-1),
                     band=(STEP_BAND if step else RECOVERY_BAND) if band is None else band,
                     left_bounds_s=self.left_bounds_s,
                     current=None if cur is None else np.asarray(cur, float).reshape(y.shape),
                     saturated_fraction=self.info.get("saturated_fraction"),
                     right_half_plane_roots=rhp)

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design (C order): ``label``, ``stable`` (the window
        stayed bounded and decayed), ``verdict`` and the metrics' fields.

        Returns
        -------
        list of dict
            A value that is not finite is ``None``.
        """
        shape = np.shape(self.stable)
        metrics = {k: _flat(v, shape) for k, v in vars(self.metrics).items()}
        verdict = self.verdict().verdict
        stable = _flat(self.stable, shape)
        return [{"label": label, "stable": bool(stable[i]), "verdict": verdict[i],
                 **{k: json_value(v[i]) for k, v in metrics.items()}}
                for i, label in enumerate(self.labels)]

    def to_dict(self) -> dict[str, Any]:
        """Time, the output, the current (if any) and every metric as nested lists.

        Returns
        -------
        dict
            ``kind``, ``mode``, ``output``, ``amplitude``, ``amplitude_unit``, ``t_s``,
            ``position``, ``current_a`` (None without a current signal),
            ``requested_delays_ms``,
            ``effective_delays_ms`` (per delayed block), the metrics' fields and, sampled,
            ``sampled_verdict`` and ``sampled_unstable_modes``.
        """
        out = super().to_dict()
        # the output's name after the mode; the amplitude as given, in the file's unit
        head = {"kind": out.pop("kind"), "mode": out.pop("mode"), "output": self.output,
                "amplitude": self.amplitude}
        del out["amplitude"]
        return head | out


@dataclass(frozen=True)
class LoopImpedanceResponse(ImpedanceResponse):
    """``Z(j 2 pi f)`` at a port of a user loop, in the loop file's units (force per
    velocity of the port)."""

    @property
    def unit(self) -> str:
        return "SI (port force / port velocity)"


class LoopImpedanceResult(ImpedanceResult):
    """The impedance at a port of a user loop (:class:`~seactl.ImpedanceResult` with the
    port's name).

    Attributes
    ----------
    port : str
        The port's name.
    labels : list of str
        One legend label per design.
    f_hz : ndarray
        Frequencies [Hz] (the last axis of the arrays below).
    z : complex ndarray
        Impedance ``sign * force / (s position)``, batch shape + ``(F,)``, in :attr:`unit`.
    magnitude : ndarray
        ``|Z|`` in :attr:`unit`.
    magnitude_db : ndarray
        ``20 log10 |Z|`` [dB re 1 :attr:`unit`].
    phase_deg : ndarray
        Phase of ``Z`` [deg], unwrapped along frequency.
    stiffness : complex ndarray
        ``s Z(s)`` (its real part at low frequency is the port's stiffness).
    unit : str
        Unit of ``Z`` (the loop file's force over velocity).
    units : str
        As :class:`~seactl.ImpedanceResult`.
    model : str
        ``"block-diagram"``.
    load : bool
        Whether a load is included.

    Parameters
    ----------
    response : LoopImpedanceResponse
        The computed impedance.
    labels : list of str
        One legend label per design.
    port : str
        The port's name.
    """

    def __init__(self, response: LoopImpedanceResponse, labels: list[str], port: str):
        super().__init__(response, labels)
        self.port = port

    def to_dict(self) -> dict[str, Any]:
        """As :meth:`seactl.ImpedanceResult.to_dict`, with the ``port``.

        Returns
        -------
        dict
            ``port``, ``model``, ``unit``, ``load``, ``f_hz``, ``magnitude``,
            ``phase_deg``.
        """
        return {"port": self.port, **super().to_dict()}


def jsonable(x: Any) -> Any:
    a = np.asarray(x)
    if a.dtype == bool:
        return a.tolist()
    if a.ndim == 0:
        v = float(a)
        return round(v, 12) if np.isfinite(v) else None
    return [jsonable(v) for v in a]


@dataclass(frozen=True)
class BreakMargins:
    """Margins of one loop broken at a named signal (arrays of the design batch shape)."""

    name: str
    signal: str
    margins: Margins
    jitter_margin_s: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        m = self.margins
        return {"break": self.name, "signal": self.signal,
                "phase_margin_deg": jsonable(m.phase_margin_deg),
                "crossover_hz": jsonable(m.crossover_hz),
                "gain_margin_db": jsonable(m.gain_margin_db),
                "phase_crossover_hz": jsonable(m.phase_crossover_hz),
                "delay_margin_ms": jsonable(m.delay_margin_ms),
                "jitter_margin_ms": jsonable(self.jitter_margin_s * 1e3),
                "stable": jsonable(m.stable), "unstable_poles": m.unstable_poles.tolist()}


@dataclass(frozen=True)
class LoopAnalysis(Result):
    """Margins at every named break of a :class:`UserLoop`, and its stability.

    Attributes
    ----------
    loop : str
        The loop's name.
    breaks : list of BreakMargins
        One per ``[[breaks]]`` entry, in file order.
    stable : ndarray
        Closed-loop stability (Nyquist on the exact-delay loops: no closed-loop root of
        the characteristic quasi-polynomial in the right half plane).
    values : dict
        The design variables and parameters the batch was evaluated at.
    """

    loop: str
    breaks: list[BreakMargins]
    stable: np.ndarray
    values: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> BreakMargins:
        for b in self.breaks:
            if b.name == name:
                return b
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """The loop's name, stability, values and every break's margins.

        Returns
        -------
        dict
            ``loop``, ``stable``, ``values``, ``breaks`` (one dict per break).
        """
        return {"loop": self.loop, "stable": jsonable(self.stable),
                "values": {k: jsonable(v) for k, v in self.values.items()},
                "breaks": [b.to_dict() for b in self.breaks]}

    def records(self) -> list[dict[str, Any]]:
        """One flat row per design (C order): its values, stability and, per break
        ``<b>``, ``<b>_phase_margin_deg``, ``<b>_crossover_hz``, ``<b>_delay_margin_ms``
        and ``<b>_jitter_margin_ms``.

        Returns
        -------
        list of dict
            JSON-ready rows.
        """
        cols: dict[str, Any] = dict(self.values)
        cols["stable"] = self.stable
        for b in self.breaks:
            m = b.margins
            cols.update({f"{b.name}_phase_margin_deg": m.phase_margin_deg,
                         f"{b.name}_crossover_hz": m.crossover_hz,
                         f"{b.name}_delay_margin_ms": m.delay_margin_ms,
                         f"{b.name}_jitter_margin_ms": np.asarray(b.jitter_margin_s) * 1e3})
        return flat_records(cols)

    def plot(self, ax: Any = None) -> Any:
        """Phase margin at every break against the design index.

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
        for b in self.breaks:
            pm = np.ravel(b.margins.phase_margin_deg)
            ax.plot(np.arange(pm.size), pm, "o-", label=b.name)
        ax.set_xlabel("design")
        ax.set_ylabel("phase margin [deg]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
        return ax


@dataclass(frozen=True)
class Placements(Result):
    """Placements of the movable blocks on the processes, ranked (best first).

    Attributes
    ----------
    blocks : list of str
        The movable blocks (``delay_ms = "process"``).
    latency_ms : dict
        Process -> latency [ms] used.
    options : list of dict
        Block -> process, ranked.
    analysis : LoopAnalysis
        Margins of every option (batch axis in the original, unranked order).
    order : ndarray
        Ranked option -> index into ``analysis``.
    """

    blocks: list[str]
    latency_ms: dict[str, float]
    options: list[dict[str, str]]
    analysis: LoopAnalysis
    order: np.ndarray

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready row per option, best first.

        Returns
        -------
        list of dict
            ``rank``, ``placement`` (block -> process), ``stable`` and, per break, its
            ``phase_margin_deg``, ``crossover_hz`` and ``delay_margin_ms``.
        """
        rows = []
        for rank, (opt, i) in enumerate(zip(self.options, self.order)):
            row: dict[str, Any] = {"rank": rank + 1, "placement": opt,
                                   "stable": bool(self.analysis.stable[i])}
            for b in self.analysis.breaks:
                m = b.margins
                row[b.name] = {"phase_margin_deg": json_value(m.phase_margin_deg[i]),
                               "crossover_hz": json_value(m.crossover_hz[i]),
                               "delay_margin_ms": json_value(m.delay_margin_ms[i])}
            rows.append(row)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """The movable blocks, latencies and ranked options.

        Returns
        -------
        dict
            ``blocks``, ``latency_ms``, ``options`` (:meth:`records`).
        """
        return {"blocks": list(self.blocks), "latency_ms": dict(self.latency_ms),
                "options": self.records()}

    def plot(self, ax: Any = None) -> Any:
        """Each ranked option's smallest phase margin over the breaks.

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
        pm = np.min([np.ravel(b.margins.phase_margin_deg)[self.order]
                     for b in self.analysis.breaks], axis=0)
        ax.bar(np.arange(1, pm.size + 1), pm)
        ax.set_xlabel("rank")
        ax.set_ylabel("smallest phase margin [deg]")
        return ax
