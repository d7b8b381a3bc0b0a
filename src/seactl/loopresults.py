"""Result objects of a user loop's views (:class:`seactl.UserLoop`): margins at every named
break (continuous and sampled), jitter margins per break, and step and impulse responses.

They carry the same methods as the built-in systems' results (``to_dict()``,
``records()``, ``plot(ax=None)``) and the same column names; what differs is that a user
loop has named breaks (one row per design and break) and signals of its own units.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._results import ResponseResult, json_array, json_value
from .impedance import ImpedanceResponse
from .margins import Margins


def _axes(ax: Any) -> Any:
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6.0, 3.6), layout="constrained")
    return ax


def _flat(x: Any, shape: tuple[int, ...]) -> np.ndarray:
    return np.ravel(np.broadcast_to(np.asarray(x), shape))


def _label_rows(labels: Mapping[str, Any], shape: tuple[int, ...]) -> list[dict[str, Any]]:
    """One dict of label columns per design (C order)."""
    cols = {k: _flat(v, shape) for k, v in labels.items()}
    n = int(np.prod(shape, dtype=int))
    return [{k: json_value(v[i]) for k, v in cols.items()} for i in range(n)]


def _plot_per_break(ax: Any, names: list[str], values: list[np.ndarray], ylabel: str) -> Any:
    """One line per break against the design index."""
    ax = _axes(ax)
    for name, v in zip(names, values):
        v = np.ravel(v).astype(float)
        ax.plot(np.arange(v.size), v, "o-", label=name)
    ax.set_xlabel("design (flattened batch)")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    return ax


@dataclass(frozen=True)
class BreakMargins:
    """Margins of one loop broken at a named signal (arrays of the design batch shape)."""

    name: str
    signal: str
    margins: Margins
    jitter_margin_s: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        """The margins as (nested) lists; NaN and infinities become ``None``.

        Returns
        -------
        dict
            ``break``, ``signal``, the margins, ``jitter_margin_ms``, ``stable`` and
            ``unstable_poles``.
        """
        m = self.margins
        return {"break": self.name, "signal": self.signal,
                "phase_margin_deg": json_array(m.phase_margin_deg),
                "crossover_hz": json_array(m.crossover_hz),
                "gain_margin_db": json_array(m.gain_margin_db),
                "phase_crossover_hz": json_array(m.phase_crossover_hz),
                "delay_margin_ms": json_array(m.delay_margin_ms),
                "jitter_margin_ms": json_array(np.asarray(self.jitter_margin_s) * 1e3),
                "stable": json_array(m.stable),
                "unstable_poles": np.asarray(m.unstable_poles).tolist()}


BREAK_COLUMNS = ("phase_margin_deg", "crossover_hz", "gain_margin_db", "phase_crossover_hz",
                 "delay_margin_ms")


@dataclass(frozen=True)
class LoopAnalysis:
    """Margins at every named break of a :class:`~seactl.UserLoop`, and its stability.

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
    labels : dict
        The label columns of :meth:`records` (the variables set to several values).
    """

    loop: str
    breaks: list[BreakMargins]
    stable: np.ndarray
    values: dict[str, np.ndarray]
    labels: dict[str, np.ndarray] = field(default_factory=dict)

    def __getitem__(self, name: str) -> BreakMargins:
        for b in self.breaks:
            if b.name == name:
                return b
        raise KeyError(name)

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready row per design and break (designs in C order, breaks in file
        order): the label columns, ``break``, ``signal``, ``phase_margin_deg``,
        ``crossover_hz``, ``gain_margin_db``, ``phase_crossover_hz``, ``delay_margin_ms``,
        ``jitter_margin_ms`` (``None`` when not computed) and ``stable`` (the whole loop).

        Returns
        -------
        list of dict
            What ``seactl analyze --loop --json`` prints as ``rows``.
        """
        shape = np.shape(self.stable)
        labels = _label_rows(self.labels, shape)
        stable = _flat(self.stable, shape)
        cols = [(b, {k: _flat(getattr(b.margins, k), shape) for k in BREAK_COLUMNS},
                 _flat(np.asarray(b.jitter_margin_s) * 1e3, shape)) for b in self.breaks]
        rows = []
        for i, lab in enumerate(labels):
            for b, c, jit in cols:
                rows.append({**lab, "break": b.name, "signal": b.signal,
                             **{k: json_value(v[i]) for k, v in c.items()},
                             "jitter_margin_ms": json_value(jit[i]),
                             "stable": bool(stable[i])})
        return rows

    def to_dict(self) -> dict[str, Any]:
        """The loop, its stability, the values and every break's margins as nested lists.

        Returns
        -------
        dict
            ``loop``, ``stable``, ``values``, ``breaks`` (:meth:`BreakMargins.to_dict`).
        """
        return {"loop": self.loop, "stable": json_array(self.stable),
                "values": {k: json_array(v) for k, v in self.values.items()},
                "breaks": [b.to_dict() for b in self.breaks]}

    def plot(self, ax: Any = None) -> Any:
        """Phase margin of every break against the design index.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        return _plot_per_break(ax, [b.name for b in self.breaks],
                               [b.margins.phase_margin_deg for b in self.breaks],
                               "phase margin [deg]")


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
        """One JSON-ready row per design and break (designs in C order): ``break`` then
        the columns of :meth:`seactl.SampledMarginsResult.records`.

        Returns
        -------
        list of dict
            Rows, designs in C order, breaks in file order within a design.
        """
        per = {name: r.records() for name, r in self.breaks.items()}
        n = len(next(iter(per.values()))) if per else 0
        return [{"break": name, **per[name][i]} for i in range(n) for name in per]

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
        return _plot_per_break(ax, list(self.breaks),
                               [r.phase_margin_deg for r in self.breaks.values()],
                               "phase margin [deg]")


@dataclass(frozen=True)
class LoopJitterResult:
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
    breaks_s : dict
        Break name -> jitter margin [s].
    delay_margins_s : dict
        Break name -> delay margin [s].
    stable : ndarray
        Closed-loop stability.
    labels : dict
        Label columns of :meth:`records`.
    """

    loop: str
    breaks_s: dict[str, np.ndarray]
    delay_margins_s: dict[str, np.ndarray]
    stable: np.ndarray
    labels: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def overall_s(self) -> np.ndarray:
        """The outermost (last) break's jitter margin [s]."""
        return self.breaks_s[list(self.breaks_s)[-1]]

    @property
    def delay_margin_s(self) -> np.ndarray:
        """The outermost break's delay margin [s]."""
        return self.delay_margins_s[list(self.delay_margins_s)[-1]]

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
        return np.asarray(self.breaks_s[name]) * 1e3

    def _columns(self) -> dict[str, np.ndarray]:
        shape = np.shape(self.stable)
        cols = {k: np.broadcast_to(np.asarray(v), shape) for k, v in self.labels.items()}
        cols["jitter_margin_ms"] = np.asarray(self.overall_s) * 1e3
        for name in self.breaks_s:
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
        ax = _plot_per_break(ax, list(self.breaks_s), [self.ms(n) for n in self.breaks_s],
                             "jitter margin [ms]")
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
    amplitude : float
        Step size, or impulse area, in the loop file's units.
    amplitude_unit : str
        Its unit (:attr:`seactl.UserLoop.step_unit` or ``impulse_unit``).
    t_s : ndarray
        Time [s].
    position : ndarray
        The output (divided by the step for steps), ``batch + (T,)``.
    outputs : dict
        Every simulated signal as simulated (not normalized).
    metrics : StepMetrics or ImpulseMetrics
        As the built-in systems' responses.
    requested_delays_s, effective_delays_s : dict
        Delayed block -> delay [s]: as asked, and as simulated (sampled: ``T_s/2 + n T_s``,
        never shorter).

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
        self._inner = response
        self.labels = labels
        self._right_roots = right_roots
        self.amplitude_unit = amplitude_unit

    kind = property(lambda self: self._inner.kind)
    mode = property(lambda self: self._inner.result.mode)
    output = property(lambda self: self._inner.output)
    amplitude = property(lambda self: self._inner.amplitude)
    t_s = property(lambda self: self._inner.t_s)
    position = property(lambda self: self._inner.position)
    current = property(lambda self: self._inner.current)
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
        seactl.verdict.TimeVerdict
            ``verdict`` (one string per design), ``warnings`` and ``evidence(i)``.
        """
        from .verdict import RECOVERY_BAND, STEP_BAND, judge

        step = self.kind == "step"
        t = self.t_s
        y = np.asarray(self.position, float).reshape(-1, t.size)
        cur = self.current
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
            ``position``, ``current`` (None without a current signal), ``requested_delays_ms``,
            ``effective_delays_ms`` (per delayed block), the metrics' fields and, sampled,
            ``sampled_verdict`` and ``sampled_unstable_modes``.
        """
        cur = self.current
        out = {"kind": self.kind, "mode": self.mode, "output": self.output,
               "amplitude": self.amplitude, "amplitude_unit": self.amplitude_unit,
               "t_s": json_array(self.t_s),
               "position": json_array(self.position),
               "current": None if cur is None else json_array(cur),
               "requested_delays_ms": {k: json_array(1e3 * np.asarray(v))
                                       for k, v in self.requested_delays_s.items()},
               "effective_delays_ms": {k: json_array(1e3 * np.asarray(v))
                                       for k, v in self.effective_delays_s.items()}}
        for name, value in vars(self.metrics).items():
            out[name] = json_array(value)
        if "sampled_verdict" in self.info:
            out["sampled_verdict"] = np.asarray(self.info["sampled_verdict"]).tolist()
            out["sampled_unstable_modes"] = json_array(self.info["sampled_unstable_modes"])
        return out

    def plot(self, ax: Any = None) -> Any:
        """The output against time, one line per design.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = _axes(ax)
        ys = np.reshape(self.position, (-1, self.t_s.size))
        for y, label in zip(ys, self.labels):
            ax.plot(self.t_s, y, label=label)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"{self.output} / step" if self.kind == "step" else self.output)
        ax.grid(True, alpha=0.3)
        if len(ys) <= 8:
            ax.legend(loc="best")
        return ax


@dataclass(frozen=True)
class LoopImpedanceResponse(ImpedanceResponse):
    """``Z(j 2 pi f)`` at a port of a user loop, in the loop file's units (force per
    velocity of the port)."""

    port: str = ""

    @property
    def unit(self) -> str:
        return "SI (port force / port velocity)"
