"""The analysis results of the public API: margins, sampled margins, impedance,
responses, jitter margins and roots of a system's design batch.

Each is a :class:`~seactl.base.result.Result` built on the object the core module computed:
every array is an explicit attribute documented in the class's ``Attributes`` section,
with its unit in its name, and the JSON of ``to_dict()`` / ``records()`` uses the same
names (seconds ``<stem>_s`` written as milliseconds ``<stem>_ms``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.base.result import Renamed, Result, flat_records, json_array, json_value, new_axes

__all__ = ["ImpedanceResult", "JitterResult", "MarginsResult", "ResponseResult",
           "RootsResult", "SampledMarginsResult", "json_array", "json_value"]


MARGIN_COLUMNS = ("phase_margin_deg", "crossover_hz", "gain_margin_db", "delay_margin_ms",
                  "stable")


def _field(core: str, name: str, doc: str) -> property:
    """A read-only attribute: ``name`` of the core object held in ``self.<core>``."""

    def read(self: Any) -> Any:
        return getattr(getattr(self, core), name)

    read.__doc__ = doc
    return property(read, doc=doc)


def _batch_columns(labels: dict[str, Any], values: dict[str, Any], shape: tuple[int, ...]
                   ) -> dict[str, np.ndarray]:
    """Label columns then value columns, each broadcast to the batch ``shape``."""
    cols = {**labels, **values}
    return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}


class MarginsResult(Result):
    """Stability margins of a design batch (arrays of the batch shape).

    Parameters
    ----------
    margins : seactl.analysis.margins.Margins
        The computed margins.
    labels : dict
        Per-design columns (e.g. ``fn_hz``, ``gs`` and gains) of the batch shape, repeated
        in :meth:`records` and :meth:`to_dict`.

    Attributes
    ----------
    labels : dict
        The per-design label columns.
    phase_margin_deg : ndarray
        Phase margin [deg]; ``inf`` where ``|L|`` never crosses 1.
    crossover_hz : ndarray
        Gain-crossover frequency of that margin [Hz]; NaN where none.
    gain_margin_db : ndarray
        Gain margin [dB]; ``inf`` where the phase never reaches -180 deg.
    gain_margin : ndarray
        The same as an absolute ratio (dimensionless, as python-control's ``gm``).
    phase_crossover_hz : ndarray
        Frequency of that gain margin [Hz]; NaN where none.
    delay_margin_s, delay_margin_ms : ndarray
        Smallest extra loop latency that destabilizes the loop [s] / [ms]; 0 when
        unstable, ``inf`` without crossover.
    stable : ndarray of bool
        Closed-loop stability (Nyquist criterion).
    unstable_poles : ndarray of int
        Number of closed-loop right-half-plane poles.
    has_crossover : ndarray of bool
        Whether ``|L|`` crosses 1.
    gain_crossovers, phase_crossovers : seactl.analysis.margins.Crossings
        Every crossing found, flattened (``design``, ``omega`` [rad/s], ``value``).

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...               filters_hz=(50, 100)).margins()
    >>> round(m.records()[1]["phase_margin_deg"], 2), m.to_dict()["stable"]
    (43.26, [True, True])
    """

    def __init__(self, margins: Any, labels: dict[str, Any]):
        self._margins = margins
        self.labels = labels

    phase_margin_deg = _field("_margins", "phase_margin_deg", "Phase margin [deg].")
    crossover_hz = _field("_margins", "crossover_hz", "Gain-crossover frequency [Hz].")
    gain_margin = _field("_margins", "gain_margin", "Gain margin (absolute ratio).")
    gain_margin_db = _field("_margins", "gain_margin_db", "Gain margin [dB].")
    phase_crossover_hz = _field("_margins", "phase_crossover_hz",
                                "Phase-crossover frequency [Hz].")
    delay_margin_s = _field("_margins", "delay_margin_s", "Delay margin [s].")
    delay_margin_ms = _field("_margins", "delay_margin_ms", "Delay margin [ms].")
    stable = _field("_margins", "stable", "Closed-loop stability (Nyquist).")
    unstable_poles = _field("_margins", "unstable_poles",
                            "Number of closed-loop right-half-plane poles.")
    has_crossover = _field("_margins", "has_crossover", "Whether ``|L|`` crosses 1.")
    gain_crossovers = _field("_margins", "gain_crossovers", "Every gain crossover found.")
    phase_crossovers = _field("_margins", "phase_crossovers", "Every phase crossover found.")

    def __repr__(self) -> str:
        pm = np.round(np.asarray(self.phase_margin_deg, float), 2)
        return f"MarginsResult(phase_margin_deg={pm.tolist()}, stable=" \
               f"{np.asarray(self.stable).tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        return _batch_columns(self.labels, {k: getattr(self, k) for k in MARGIN_COLUMNS},
                              np.shape(self.phase_margin_deg))

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape; NaN/inf become ``None``.

        Returns
        -------
        dict
            ``labels`` columns then ``phase_margin_deg``, ``crossover_hz``,
            ``gain_margin_db``, ``delay_margin_ms``, ``stable``.
        """
        return super().to_dict()

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design, in C order of the batch (the CLI's rows).

        Returns
        -------
        list of dict
            Keys as in :meth:`to_dict`; a value that is not finite (a margin that does
            not exist, or is infinite) is ``None``.
        """
        return super().records()

    def plot(self, ax: Any = None, x: str = "fn_hz") -> Any:
        """Phase margin against a label column (default ``fn_hz``); unstable designs in red.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).
        x : str
            Label column on the horizontal axis.

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        return plot_phase_margins(new_axes(ax), self._columns(), x, "unstable", line=True)


def plot_phase_margins(ax: Any, cols: dict[str, Any], x: str, bad: str,
                       line: bool = False) -> Any:
    """Phase margin against the label column ``x`` (the design index if absent): stable
    designs as blue dots, the others as red crosses labelled ``bad``; ``line`` joins the
    points in order of ``x``."""
    xs = np.ravel(cols[x]) if x in cols else np.arange(np.size(cols["stable"]))
    pm = np.ravel(cols["phase_margin_deg"]).astype(float)
    ok = np.ravel(cols["stable"]).astype(bool)
    if line:
        order = np.argsort(xs, kind="stable")
        ax.plot(xs[order], pm[order], "-", color="0.6", lw=1)
    ax.plot(xs[ok], pm[ok], "o", color="tab:blue", label="stable")
    if (~ok).any():
        ax.plot(xs[~ok], pm[~ok], "x", color="tab:red", label=bad)
    ax.set_xlabel(x)
    ax.set_ylabel("phase margin [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    return ax


SAMPLED_COLUMNS = ("rate_hz", "verdict", "unstable_modes", "phase_margin_deg", "crossover_hz",
                   "gain_margin_db", "phase_crossover_hz", "delay_margin_ms",
                   "delay_margin_samples", "jitter_margin_ms", "jitter_margin_samples",
                   "stable")


class SampledMarginsResult(Result):
    """Certified verdict and margins of the sampled-data loop at its process rates
    (:func:`seactl.simulate.sampled.sampled_margins`; arrays of the batch shape).

    Parameters
    ----------
    margins : seactl.simulate.sampled.SampledMargins
        The computed verdict and margins.
    labels : dict
        Per-design columns (e.g. ``fn_hz``, ``gs`` and gains) of the batch shape.

    Attributes
    ----------
    labels : dict
        The per-design label columns.
    verdict : ndarray of str
        ``"stable"``, ``"unstable"`` or ``"uncertain"`` (certified).
    unstable_modes : ndarray of int
        Eigenvalues of the loop's map over one period outside the unit circle (-1:
        uncertain).
    radius : ndarray
        Spectral radius of that map (dimensionless).
    stable : ndarray of bool
        ``unstable_modes == 0``.
    phase_margin_deg, crossover_hz : ndarray
        Phase margin [deg] and its crossover [Hz] (up to Nyquist).
    gain_margin_db, gain_margin : ndarray
        Gain margin [dB] and as an absolute ratio.
    phase_crossover_hz : ndarray
        Frequency of that gain margin [Hz].
    delay_margin_s, delay_margin_ms : ndarray
        Extra continuous loop delay the phase margins allow [s] / [ms].
    delay_margin_samples : ndarray of int
        Whole extra samples of delay the loop tolerates (-1 when unstable).
    jitter_margin_s, jitter_margin_ms : ndarray
        Time-varying extra delay the loop tolerates (small-gain bound) [s] / [ms].
    jitter_margin_samples : ndarray of int
        The same in whole samples.
    rate_hz : float
        The base (fastest) process rate [Hz].
    rates_hz : dict
        Process -> rate [Hz].
    period_s : float
        Period of the loop's map [s].
    rate_label : str
        The rates in words (``"embedded 1000 Hz, high-level 250 Hz"``).
    reason : str or None
        Why margins are NaN (a multi-rate loop), else None.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...               filters_hz=(50, 100)).margins(rate_hz=1000)
    >>> r = m.records()[0]
    >>> r["verdict"], round(r["phase_margin_deg"], 1), r["delay_margin_samples"]
    ('stable', 42.0, 9)
    """

    def __init__(self, margins: Any, labels: dict[str, Any]):
        self._margins = margins
        self.labels = labels

    verdict = _field("_margins", "verdict", "Certified verdict per design.")
    unstable_modes = _field("_margins", "unstable_modes",
                            "Modes outside the unit circle (-1: uncertain).")
    radius = _field("_margins", "radius", "Spectral radius of the period map.")
    stable = _field("_margins", "stable", "Whether no mode is unstable.")
    phase_margin_deg = _field("_margins", "phase_margin_deg", "Phase margin [deg].")
    crossover_hz = _field("_margins", "crossover_hz", "Gain-crossover frequency [Hz].")
    gain_margin = _field("_margins", "gain_margin", "Gain margin (absolute ratio).")
    gain_margin_db = _field("_margins", "gain_margin_db", "Gain margin [dB].")
    phase_crossover_hz = _field("_margins", "phase_crossover_hz",
                                "Phase-crossover frequency [Hz].")
    delay_margin_s = _field("_margins", "delay_margin_s", "Delay margin [s].")
    delay_margin_ms = _field("_margins", "delay_margin_ms", "Delay margin [ms].")
    delay_margin_samples = _field("_margins", "delay_margin_samples",
                                  "Delay margin in whole samples.")
    jitter_margin_s = _field("_margins", "jitter_margin_s", "Jitter margin [s].")
    jitter_margin_ms = _field("_margins", "jitter_margin_ms", "Jitter margin [ms].")
    jitter_margin_samples = _field("_margins", "jitter_margin_samples",
                                   "Jitter margin in whole samples.")
    rates_hz = _field("_margins", "rates_hz", "Process -> rate [Hz].")
    period_s = _field("_margins", "period_s", "Period of the loop's map [s].")
    rate_label = _field("_margins", "rate_label", "The rates in words.")
    reason = _field("_margins", "reason", "Why margins are NaN, else None.")

    @property
    def rate_hz(self) -> float:
        """The base (fastest) process rate [Hz]."""
        return max(self.rates_hz.values())

    def __repr__(self) -> str:
        pm = np.round(np.asarray(self.phase_margin_deg, float), 2)
        return f"SampledMarginsResult(rate={self.rate_label!r}, phase_margin_deg=" \
               f"{pm.tolist()}, verdict={np.asarray(self.verdict).tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        return _batch_columns(self.labels, {k: getattr(self, k) for k in SAMPLED_COLUMNS},
                              np.shape(self.phase_margin_deg))

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design, in C order of the batch.

        Returns
        -------
        list of dict
            Keys as in :meth:`to_dict`; the verdict a word, ``delay_margin_samples`` an
            integer, a value that is not finite ``None``.
        """
        cols = {k: np.ravel(v) for k, v in self._columns().items()}
        n = len(cols["verdict"])

        def value(k: str, x: Any) -> Any:
            if k == "verdict":
                return str(x)
            if k in ("delay_margin_samples", "jitter_margin_samples") and np.isfinite(x):
                return int(x)
            return json_value(x)

        return [{k: value(k, v[i]) for k, v in cols.items()} for i in range(n)]

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape; NaN/inf become ``None``.

        Returns
        -------
        dict
            ``labels`` columns, then ``rate_hz``, ``verdict``, ``unstable_modes`` and the
            margins, plus ``rates_hz``, ``period_s`` and ``reason``.
        """
        out = {k: (np.asarray(v).tolist() if k == "verdict" else json_array(v))
               for k, v in self._columns().items()}
        out.update(rates_hz=dict(self.rates_hz), period_s=self.period_s, reason=self.reason)
        return out

    def plot(self, ax: Any = None, x: str = "fn_hz") -> Any:
        """Phase margin against a label column; designs not certified stable in red.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).
        x : str
            Label column on the horizontal axis.

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = plot_phase_margins(new_axes(ax), self._columns(), x, "not certified stable")
        ax.set_title(f"sampled at {self.rate_label}")
        return ax


class ImpedanceResult(Result):
    """Impedance ``Z(j 2 pi f)`` of a design batch.

    Parameters
    ----------
    response : seactl.systems.sea.impedance.ImpedanceResponse
        The computed impedance.
    labels : list of str
        One legend label per design (flattened batch).

    Attributes
    ----------
    labels : list of str
        One legend label per design.
    f_hz : ndarray
        Frequencies [Hz] (the last axis of the arrays below).
    z : complex ndarray
        Impedance, batch shape + ``(F,)``, in :attr:`unit`.
    magnitude : ndarray
        ``|Z|`` in :attr:`unit`.
    magnitude_db : ndarray
        ``20 log10 |Z|`` [dB re 1 :attr:`unit`].
    phase_deg : ndarray
        Phase of ``Z`` [deg], unwrapped along frequency.
    stiffness : complex ndarray
        ``s Z(s)``, in :attr:`unit` times rad/s (its real part at low frequency is the
        virtual stiffness).
    unit : str
        Unit of ``Z`` (``"N m s/rad"`` or ``"N s/m"``).
    units : str
        ``"rotary"`` or ``"linear"``.
    model : str
        ``"block-diagram"`` or ``"paper"``.
    load : bool
        Whether the joint inertia and damping are included.

    Examples
    --------
    >>> import seactl as sc
    >>> z = sc.design([12, 30]).impedance([1.0, 10.0, 100.0])
    >>> z.z.shape, z.unit
    ((2, 3), 'N m s/rad')
    """

    def __init__(self, response: Any, labels: list[str]):
        self._response = response
        self.labels = labels

    f_hz = _field("_response", "f_hz", "Frequencies [Hz].")
    z = _field("_response", "z", "Complex impedance in ``unit``.")
    magnitude = _field("_response", "magnitude", "``|Z|`` in ``unit``.")
    magnitude_db = _field("_response", "magnitude_db", "``20 log10 |Z|`` [dB].")
    phase_deg = _field("_response", "phase_deg", "Phase of ``Z`` [deg], unwrapped.")
    stiffness = _field("_response", "stiffness", "``s Z(s)`` (complex).")
    unit = _field("_response", "unit", "Unit of ``Z``.")
    units = _field("_response", "units", "``rotary`` or ``linear``.")
    model = _field("_response", "model", "``block-diagram`` or ``paper``.")
    load = _field("_response", "load", "Whether the load is included.")

    def __repr__(self) -> str:
        return f"ImpedanceResult(model={self.model!r}, unit={self.unit!r}, " \
               f"shape={self.z.shape})"

    def to_dict(self) -> dict[str, Any]:
        """Frequencies, magnitude [unit] and phase [deg] as nested lists.

        Returns
        -------
        dict
            ``model``, ``unit``, ``load``, ``f_hz``, ``magnitude``, ``phase_deg``.
        """
        return {"model": self.model, "unit": self.unit, "load": self.load,
                "f_hz": json_array(self.f_hz), "magnitude": json_array(self.magnitude),
                "phase_deg": json_array(self.phase_deg)}

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready row per design and frequency (designs in C order, then
        frequencies).

        Returns
        -------
        list of dict
            ``design`` (flat index), ``f_hz``, ``magnitude`` [unit], ``phase_deg``.
        """
        f = np.asarray(self.f_hz)
        mag = np.reshape(self.magnitude, (-1, f.size))
        ph = np.reshape(self.phase_deg, (-1, f.size))
        design = np.repeat(np.arange(mag.shape[0]), f.size)
        return flat_records({"design": design, "f_hz": np.tile(f, mag.shape[0]),
                             "magnitude": mag.ravel(), "phase_deg": ph.ravel()})

    def plot(self, ax: Any = None) -> Any:
        """Magnitude ``|Z|`` against frequency, log-log, one line per design.

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
        mags = np.reshape(self.magnitude, (-1, self.f_hz.size))
        for mag, label in zip(mags, self.labels):
            ax.loglog(self.f_hz, mag, label=label)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"|Z| [{self.unit}]")
        ax.grid(True, which="both", alpha=0.3)
        if len(mags) <= 8:
            ax.legend(loc="best")
        return ax


class ResponseResult(Result):
    """A simulated step or impulse response with its metrics.

    Parameters
    ----------
    response : seactl.simulate.results.SEAResponse
        The simulated response.
    labels : list of str
        One legend label per design (flattened batch).
    right_roots : callable, optional
        Returns the simulated loop's certified count of right-half-plane roots per design
        (continuous mode; used by :meth:`verdict`).
    links : mapping, optional
        Loop name -> delayed block name (e.g. ``{"stiffness": "Kq_fb"}``): the keys of
        :attr:`requested_delays_s` and :attr:`effective_delays_s` (default: block names).
    amplitude : float, optional
        The step or impulse applied, in ``amplitude_unit`` (``"rad"`` or ``"m"`` for a
        step, ``"N m s"`` or ``"N s"`` for an impulse).
    amplitude_unit : str
        Its unit.
    output : str
        The output signal (the system's ``output``: ``"q_j"``, ``"x"``, ...).
    output_unit : str
        Its unit (``""``: not known).

    Attributes
    ----------
    labels : list of str
        One legend label per design.
    amplitude : float or None
        The step or impulse applied, in ``amplitude_unit``.
    amplitude_unit : str
        Its unit.
    output, output_unit : str
        The output signal and its unit (the axis of :meth:`plot`).
    kind : str
        ``"step"`` or ``"impulse"``.
    mode : str
        ``"continuous"`` or ``"sampled"``.
    t_s : ndarray
        Sample times [s], shape ``(T,)``.
    position : ndarray
        The output position, batch shape + ``(T,)``: relative to the step amplitude for a
        step, in the system's position unit (rad or m) for an impulse.
    current_a : ndarray
        Motor current [A], batch shape + ``(T,)`` (SEA; the actuation for other systems).
    metrics : seactl.simulate.results.StepMetrics or seactl.simulate.results.ImpulseMetrics
        Rise, overshoot and settling (step) or peak and recovery (impulse); every field
        is also a key of :meth:`to_dict`.
    result : seactl.simulate.results.SimResult
        The simulation itself (all outputs, boundedness, details in ``info``).
    requested_delays_s, effective_delays_s : dict
        Per loop, the delay asked for and the delay simulated [s].

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.design([14, 20], filters_hz=(50, 100)).step(t_end_s=0.3)
    >>> r.position.shape[0], sorted(r.to_dict())[:3]
    (2, ['amplitude', 'amplitude_unit', 'current_a'])
    """

    def __init__(self, response: Any, labels: list[str], right_roots: Any = None,
                 links: Any = None, amplitude: float | None = None, amplitude_unit: str = "",
                 output: str = "output", output_unit: str = ""):
        self._response = response
        self.labels = labels
        self._right_roots = right_roots
        self._links = dict(links) if links is not None else None
        self.amplitude = amplitude
        self.amplitude_unit = amplitude_unit
        self.output = output
        self.output_unit = output_unit

    kind = _field("_response", "kind", "``step`` or ``impulse``.")
    t_s = _field("_response", "t_s", "Sample times [s].")
    position = _field("_response", "position", "Output position (relative for a step).")
    current_a = _field("_response", "current", "Motor current [A].")
    metrics = _field("_response", "metrics", "The response's metrics.")
    result = _field("_response", "result", "The simulation itself.")
    current = Renamed("current_a")

    @property
    def mode(self) -> str:
        """``continuous`` or ``sampled``."""
        return self.result.mode

    def _delays(self, key: str) -> dict[str, np.ndarray]:
        info = self.result.info.get(key, {})
        if self._links is None:
            return dict(info)
        return {loop: info[block] for loop, block in self._links.items() if block in info}

    @property
    def requested_delays_s(self) -> dict[str, np.ndarray]:
        """Per loop, the delay asked for [s] (batch shape)."""
        return self._delays("requested_delays_s")

    @property
    def effective_delays_s(self) -> dict[str, np.ndarray]:
        """Per loop, the delay the simulated loop has [s]: the requested one in continuous
        mode; in sampled mode the hold's half period plus whole-sample buffers,
        ``T_s/2 + n T_s``, the shortest realizable delay not shorter than the request.
        """
        return self._delays("effective_delays_s")

    def verdict(self, band: float | None = None) -> Any:
        """Settled, not settled, unstable, limit cycle or saturated, per design, with the
        evidence (what ``seactl step`` and ``seactl impulse`` print).

        A loop with growing modes is unstable however slowly they grow and whatever the
        simulated window shows: in continuous mode by the certified count of closed-loop
        roots in the right half-plane, in sampled mode by the eigenvalues of the loop's
        map over one period (:func:`seactl.simulate.period.sampled_unstable_modes`).
        ``metrics.stable`` only says the simulated response stayed bounded and decayed.

        Parameters
        ----------
        band : float, optional
            Settling band relative to the scale (default 0.02 for a step, the metrics'
            recovery band for an impulse).

        Returns
        -------
        seactl.simulate.verdict.TimeVerdict
            ``verdict`` (one string per design), ``warnings`` and ``evidence(i)``.

        Examples
        --------
        Two designs either side of the stability boundary (10.5217 ms): the window
        cannot tell them apart, the certified count can.

        >>> import seactl as sc
        >>> d = sc.design(30, delays_ms={"torque": 0.5, "stiffness": [10.5, 10.53],
        ...                              "damping": 0.5}, filters_hz=(50, 100))
        >>> v = d.step().verdict()
        >>> v.verdict, [v.evidence(i)["right_half_plane_roots"] for i in range(2)]
        (['not settled', 'unstable'], [0, 2])
        """
        from seactl.simulate.verdict import STEP_BAND, judge_response

        r = self._response
        if band is None:
            band = STEP_BAND if r.kind == "step" else r.metrics.band
        roots = self._right_roots() if (self._right_roots is not None
                                        and self.mode == "continuous") else None
        return judge_response(r, band, roots)

    def __repr__(self) -> str:
        return f"ResponseResult(kind={self.kind!r}, mode={self.mode!r}, " \
               f"shape={self.position.shape})"

    def _metric_columns(self) -> dict[str, Any]:
        return dict(vars(self.metrics))

    def to_dict(self) -> dict[str, Any]:
        """Time, position, current and every metric as nested lists.

        Returns
        -------
        dict
            ``kind``, ``mode``, ``amplitude``, ``amplitude_unit``, ``t_s``, ``position``,
            ``current_a``, ``requested_delays_ms``, ``effective_delays_ms`` (per loop),
            ``stable`` and the metrics' fields (e.g. ``overshoot_pct``).
        """
        out = {"kind": self.kind, "mode": self.mode,
               "amplitude": None if self.amplitude is None else json_value(self.amplitude),
               "amplitude_unit": self.amplitude_unit, "t_s": json_array(self.t_s),
               "position": json_array(self.position),
               "current_a": None if self.current_a is None else json_array(self.current_a),
               "requested_delays_ms": {k: json_array(1e3 * np.asarray(v))
                                       for k, v in self.requested_delays_s.items()},
               "effective_delays_ms": {k: json_array(1e3 * np.asarray(v))
                                       for k, v in self.effective_delays_s.items()}}
        for name, value in self._metric_columns().items():
            out[name] = json_array(value)
        info = self.result.info
        if "sampled_verdict" in info:   # the sampled loop's certified verdict
            out["sampled_verdict"] = np.asarray(info["sampled_verdict"]).tolist()
            out["sampled_unstable_modes"] = json_array(info["sampled_unstable_modes"])
        return out

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict of metrics per design, in C order of the batch.

        Returns
        -------
        list of dict
            ``label``, then the metrics' fields (``stable``, ``left_bounds_s`` and e.g.
            ``overshoot_pct``, ``settling_time_s``); the time series are in
            :meth:`to_dict`.
        """
        shape = np.shape(self.position)[:-1]
        cols = {k: np.broadcast_to(np.asarray(v), shape)
                for k, v in self._metric_columns().items()}
        rows = flat_records(cols)
        return [{"label": label, **row} for label, row in zip(self.labels, rows)]

    def plot(self, ax: Any = None) -> Any:
        """The output against time, one line per design: relative to the step
        (``"x / step"``), or in its unit for an impulse (``"x [m]"``).

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
        ys = np.reshape(self.position, (-1, self.t_s.size))
        for y, label in zip(ys, self.labels):
            ax.plot(self.t_s, y, label=label)
        ax.set_xlabel("time [s]")
        unit = f" [{self.output_unit}]" if self.output_unit else ""
        ax.set_ylabel(f"{self.output} / step" if self.kind == "step" else self.output + unit)
        ax.grid(True, alpha=0.3)
        if len(ys) <= 8:
            ax.legend(loc="best")
        return ax


JITTER_COLUMNS = {"jitter_margin_ms": "jitter_margin_s",
                  "stiffness_jitter_margin_ms": "stiffness_jitter_margin_s",
                  "damping_jitter_margin_ms": "damping_jitter_margin_s",
                  "torque_jitter_margin_ms": "torque_jitter_margin_s"}
"""JSON key [ms] -> attribute [s] of :class:`JitterResult`."""

_JITTER_LOOPS = {"overall": "jitter_margin_s", "stiffness": "stiffness_jitter_margin_s",
                 "damping": "damping_jitter_margin_s", "torque": "torque_jitter_margin_s"}


class JitterResult(Result):
    """Jitter margins of a design batch (arrays of the batch shape).

    The jitter margin of a loop is the largest ``J`` such that any time-varying extra
    delay in ``[0, J]`` keeps the loop stable (Kao-Lincoln small-gain bound, sufficient).

    Parameters
    ----------
    margins : seactl.latency.jitter.JitterMargins
        The computed margins.
    labels : dict
        Per-design columns (``fn_hz``, ``gs``) of the batch shape.

    Attributes
    ----------
    labels : dict
        The per-design label columns.
    jitter_margin_s : ndarray
        Jitter margin of the whole outer loop (the joint measurement of both impedance
        loops) [s]; JSON ``jitter_margin_ms``.
    stiffness_jitter_margin_s, damping_jitter_margin_s : ndarray
        The same for the stiffness and the damping loop alone [s] (every other loop
        closed, nominal delays).
    torque_jitter_margin_s : ndarray or None
        The same for the SEA's torque loop [s]; None for a system without one.
    delay_margin_s : ndarray
        The whole outer loop's margin for a constant extra delay [s].
    peak_hz : dict
        Loop name (``overall``, ``stiffness``, ...) -> frequency [Hz] where ``w |T|``
        peaks.
    stable : ndarray of bool
        Nominal closed-loop stability (margins are 0 where False).
    bottleneck : ndarray of str
        Per design, the single loop with the smallest jitter margin.

    Examples
    --------
    >>> import seactl as sc
    >>> j = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...               filters_hz=(50, 100)).jitter_margins()
    >>> r = j.records()[0]
    >>> round(r["jitter_margin_ms"], 2), round(r["delay_margin_ms"], 2)
    (8.04, 9.45)
    >>> round(float(j.jitter_margin_s) * 1e3, 2) == round(r["jitter_margin_ms"], 2)
    True
    """

    def __init__(self, margins: Any, labels: dict[str, Any]):
        self._margins = margins
        self.labels = labels

    jitter_margin_s = _field("_margins", "overall_s", "Whole outer loop's jitter margin [s].")
    stiffness_jitter_margin_s = _field("_margins", "stiffness_s",
                                       "Stiffness loop's jitter margin [s].")
    damping_jitter_margin_s = _field("_margins", "damping_s",
                                     "Damping loop's jitter margin [s].")
    torque_jitter_margin_s = _field("_margins", "torque_s",
                                    "Torque loop's jitter margin [s] (None without one).")
    delay_margin_s = _field("_margins", "delay_margin_s", "Outer loop's delay margin [s].")
    peak_hz = _field("_margins", "peak_hz", "Loop -> frequency [Hz] of the peak.")
    stable = _field("_margins", "stable", "Nominal closed-loop stability.")
    bottleneck = _field("_margins", "bottleneck", "Loop with the smallest margin.")
    overall_s = Renamed("jitter_margin_s")
    stiffness_s = Renamed("stiffness_jitter_margin_s")
    damping_s = Renamed("damping_jitter_margin_s")
    torque_s = Renamed("torque_jitter_margin_s")

    def ms(self, loop: str) -> np.ndarray:
        """Deprecated: the jitter margin [ms] of ``loop``; use the ``*_jitter_margin_s``
        attributes.

        Parameters
        ----------
        loop : {"overall", "stiffness", "damping", "torque"}
            The loop.

        Returns
        -------
        numpy.ndarray
            Its jitter margin [ms].
        """
        import warnings

        warnings.warn(f"JitterResult.ms({loop!r}) is deprecated; use "
                      f".{_JITTER_LOOPS.get(loop, loop)} (x 1e3)", DeprecationWarning,
                      stacklevel=2)
        return np.asarray(getattr(self, _JITTER_LOOPS[loop])) * 1e3

    def __repr__(self) -> str:
        j = np.round(np.asarray(self.jitter_margin_s, float) * 1e3, 3)
        return f"JitterResult(jitter_margin_ms={j.tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        vals = {key: np.asarray(getattr(self, name)) * 1e3
                for key, name in JITTER_COLUMNS.items() if getattr(self, name) is not None}
        vals["delay_margin_ms"] = np.asarray(self.delay_margin_s) * 1e3
        vals["stable"] = self.stable
        return _batch_columns(self.labels, vals, np.shape(self.jitter_margin_s))

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape.

        Returns
        -------
        dict
            ``labels`` columns, ``jitter_margin_ms`` (whole outer loop),
            ``stiffness_jitter_margin_ms``, ``damping_jitter_margin_ms``,
            ``torque_jitter_margin_ms``, ``delay_margin_ms``, ``stable``.
        """
        return super().to_dict()

    def plot(self, ax: Any = None, x: str = "fn_hz") -> Any:
        """Jitter margins of every loop and the delay margin against a label column.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).
        x : str
            Label column on the horizontal axis.

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        cols = {k: np.ravel(v) for k, v in self._columns().items()}
        xs = cols[x] if x in cols else np.arange(cols["stable"].size)
        order = np.argsort(xs, kind="stable")
        for name in (*JITTER_COLUMNS, "delay_margin_ms"):
            if name in cols:
                ax.plot(xs[order], cols[name][order], "o-" if name != "delay_margin_ms"
                        else "k--", label=name.replace("_ms", ""))
        ax.set_xlabel(x)
        ax.set_ylabel("margin [ms]")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="best", fontsize=8)
        return ax


def _root_records(roots: np.ndarray, centre: np.ndarray, radius: np.ndarray,
                  count: np.ndarray) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """One design's roots ``{"re", "im", "radius", "count"}`` and clusters (the discs
    holding more than one root, once each, with their real-part interval)."""
    rows, clusters, seen = [], [], set()
    for z, c, r, m in zip(roots, centre, radius, count):
        if not np.isfinite(z):
            continue
        rows.append({"re": json_value(z.real), "im": json_value(z.imag),
                     "radius": json_value(r), "count": int(m)})
        if m > 1 and (c, r) not in seen:
            seen.add((c, r))
            clusters.append({"re": json_value(c.real), "im": json_value(c.imag),
                             "radius": json_value(r), "count": int(m),
                             "re_min": json_value(c.real - r), "re_max": json_value(c.real + r)})
    return rows, clusters


class RootsResult(Result):
    """Rightmost characteristic roots of a design batch.

    Roots are points of the complex ``s``-plane in rad/s (real parts in 1/s), named as
    python-control names a system's ``poles()``.

    Parameters
    ----------
    roots : seactl.analysis.roots.Roots
        The computed roots.
    labels : dict
        Per-design columns (e.g. ``fn_hz``, ``gs``) of the batch shape.

    Attributes
    ----------
    labels : dict
        The per-design label columns.
    roots : complex ndarray
        Roots [rad/s], shape ``batch + (count,)``, by decreasing real part, one of each
        conjugate pair (``imag >= 0``); NaN where fewer were found.
    spectral_abscissa : ndarray
        Largest real part of all roots [1/s] (negative: stable, and the decay rate).
    stable : ndarray of bool
        No root in the closed right half-plane by the certified count.
    uncertain : ndarray of bool
        No verdict: the count is not certain, or a root's disc reaches across the axis.
    right_half_plane_roots : ndarray of int
        Certified count of roots with ``Re s > 0`` (-1 where no count is certain).
    unstable_count : ndarray of int
        Listed roots with ``Re s > 0``, conjugates counted.
    converged, complete : ndarray of bool
        The list is complete (discretizations agreed, the argument principle found no
        other root right of them); ``complete`` is the name in :meth:`records`.
    nodes : ndarray of int
        Chebyshev collocation size the roots converged at (0: no delay).
    cluster_centre, cluster_radius : ndarray
        Per listed root, the certified disc [rad/s] holding it (its error bound).
    cluster_count : ndarray of int
        Roots in that disc, multiplicity counted.
    real_interval : tuple of ndarray
        Per listed root, the bounds [1/s] of the real parts in its disc.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...               filters_hz=(50, 100)).roots(count=2)
    >>> round(r.records()[0]["spectral_abscissa"], 2), len(r.records()[0]["roots"])
    (-39.85, 2)
    """

    def __init__(self, roots: Any, labels: dict[str, Any]):
        self._roots = roots
        self.labels = labels

    roots = _field("_roots", "roots", "Rightmost roots [rad/s].")
    spectral_abscissa = _field("_roots", "spectral_abscissa", "Largest real part [1/s].")
    stable = _field("_roots", "stable", "Certified stability.")
    uncertain = _field("_roots", "uncertain", "Whether no verdict is certain.")
    right_half_plane_roots = _field("_roots", "right_half_plane_roots",
                                    "Certified count of right-half-plane roots.")
    unstable_count = _field("_roots", "unstable_count",
                            "Listed roots with positive real part, conjugates counted.")
    converged = _field("_roots", "converged", "Whether the list is complete.")
    complete = _field("_roots", "converged", "Whether the list is complete (``converged``).")
    nodes = _field("_roots", "nodes", "Collocation size the roots converged at.")
    cluster_centre = _field("_roots", "cluster_centre", "Centre of each root's disc.")
    cluster_radius = _field("_roots", "cluster_radius", "Radius of each root's disc.")
    cluster_count = _field("_roots", "cluster_count", "Roots in each root's disc.")
    real_interval = _field("_roots", "real_interval", "Real-part bounds of each disc.")

    def __repr__(self) -> str:
        a = np.round(np.asarray(self.spectral_abscissa, float), 3)
        return f"RootsResult(spectral_abscissa={a.tolist()})"

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design (C order): the label columns,
        ``spectral_abscissa`` [1/s] and ``roots``, a list of ``{"re", "im"}`` [rad/s]
        sorted by decreasing real part (conjugates once, ``im >= 0``); ``complete`` (no
        root is missing from the list: the discretizations agreed and the argument
        principle found no other), ``stable``, ``uncertain`` (no verdict: the count is not
        certain, or a root's disc reaches across the imaginary axis) and
        ``right_half_plane_roots`` (the certified count, None where uncertain).  Each root
        also has ``radius`` [rad/s] and ``count``: the disc about ``(re, im)`` of that
        radius holds ``count`` roots (1: a simple root); ``clusters`` lists the discs
        holding more than one root, ``{"re", "im", "radius", "count", "re_min",
        "re_max"}`` (centre and radius [rad/s], the real-part interval [1/s]): the error
        bound of the roots listed in it.

        Returns
        -------
        list of dict
            The CLI's ``designs`` rows.
        """
        r = self
        shape = np.shape(r.spectral_abscissa)
        cols = {k: np.ravel(np.broadcast_to(np.asarray(v), shape)) for k, v in
                self.labels.items()}
        absc = np.ravel(r.spectral_abscissa)
        roots = np.reshape(r.roots, (absc.size, -1))
        conv, stable = np.ravel(r.converged), np.ravel(r.stable)
        uncertain = np.ravel(r.uncertain)
        rhp = np.ravel(r.right_half_plane_roots)
        discs = [np.reshape(x, roots.shape) for x in
                 (r.cluster_centre, r.cluster_radius, r.cluster_count)]
        out = []
        for i in range(absc.size):
            row = {k: json_value(v[i]) for k, v in cols.items()}
            row["spectral_abscissa"] = json_value(absc[i])
            row["roots"], row["clusters"] = _root_records(roots[i], *(x[i] for x in discs))
            row["complete"] = bool(conv[i])
            row["stable"] = bool(stable[i])
            row["uncertain"] = bool(uncertain[i])
            row["right_half_plane_roots"] = int(rhp[i]) if rhp[i] >= 0 else None
            out.append(row)
        return out

    def to_dict(self) -> dict[str, Any]:
        """``{"designs": records()}``.

        Returns
        -------
        dict
            As printed by ``seactl roots --json``.
        """
        return {"designs": self.records()}

    def plot(self, ax: Any = None) -> Any:
        """The roots in the complex plane [rad/s], one marker set per design.

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
        roots = np.reshape(self.roots, (-1, np.shape(self.roots)[-1]))
        for z in roots:
            z = z[np.isfinite(z)]
            ax.plot(np.r_[z.real, z.real], np.r_[z.imag, -z.imag], "x")
        ax.axvline(0.0, color="0.5", lw=1)
        ax.set_xlabel("Re s [1/s]")
        ax.set_ylabel("Im s [rad/s]")
        ax.grid(True, alpha=0.3)
        return ax
