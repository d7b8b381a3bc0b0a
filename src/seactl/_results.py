"""Result objects of the public API: the computed arrays plus ``to_dict`` and ``plot``.

Each result wraps the object the core module computed (attribute access is forwarded to
it, so ``d.margins().phase_margin_deg`` is the core array) and adds a JSON-ready
``to_dict()`` and a ``plot(ax=None)`` that imports matplotlib only when called.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def json_value(x: Any, digits: int = 10) -> Any:
    """A JSON-safe scalar: NaN and infinities become ``None``, numpy scalars Python ones."""
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    x = float(x)
    return round(x, digits) if math.isfinite(x) else None


def json_array(a: Any) -> Any:
    """A nested list of JSON-safe values (a scalar for a 0-d array)."""
    arr = np.asarray(a)
    if arr.ndim == 0:
        return json_value(arr[()])
    return [json_array(x) for x in arr]


def _axes(ax: Any) -> Any:
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6.0, 3.6), layout="constrained")
    return ax


class _Wrapped:
    """Forward unknown attributes to ``self._inner`` (the core result)."""

    _inner: Any

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._inner, name)

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(dir(self._inner)))


MARGIN_COLUMNS = ("phase_margin_deg", "crossover_hz", "gain_margin_db", "delay_margin_ms",
                  "stable")


class _Columns(_Wrapped):
    """A result whose ``_columns()`` are arrays of the batch shape (labels, then values)."""

    def _columns(self) -> dict[str, np.ndarray]:  # pragma: no cover - abstract
        raise NotImplementedError

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design, in C order of the batch (the CLI's rows).

        Returns
        -------
        list of dict
            Keys as in :meth:`to_dict`; a value that is not finite (a margin that does
            not exist, or is infinite) is ``None``.
        """
        cols = {k: np.ravel(v) for k, v in self._columns().items()}
        n = len(next(iter(cols.values())))
        return [{k: json_value(v[i]) for k, v in cols.items()} for i in range(n)]


class MarginsResult(_Columns):
    """Stability margins of a design batch (arrays of the batch shape).

    Every attribute of :class:`seactl.margins.Margins` is available
    (``phase_margin_deg``, ``crossover_hz``, ``gain_margin``, ``gain_margin_db``,
    ``delay_margin_s``, ``delay_margin_ms``, ``stable``, ``unstable_poles``, ...).

    Parameters
    ----------
    margins : seactl.margins.Margins
        The computed margins.
    labels : dict
        Per-design columns (e.g. ``fn_hz``, ``gs`` and gains) of the batch shape, repeated
        in :meth:`records` and :meth:`to_dict`.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                      filters_hz=(50, 100)).margins()
    >>> round(m.records()[1]["phase_margin_deg"], 2), m.to_dict()["stable"]
    (43.26, [True, True])
    """

    def __init__(self, margins: Any, labels: dict[str, Any]):
        self._inner = margins
        self.labels = labels

    def __repr__(self) -> str:
        pm = np.round(np.asarray(self._inner.phase_margin_deg, float), 2)
        return f"MarginsResult(phase_margin_deg={pm.tolist()}, stable=" \
               f"{np.asarray(self._inner.stable).tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        cols = dict(self.labels)
        for name in MARGIN_COLUMNS:
            cols[name] = getattr(self._inner, name)
        shape = np.shape(self._inner.phase_margin_deg)
        return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape; NaN/inf become ``None``.

        Returns
        -------
        dict
            ``labels`` columns then ``phase_margin_deg``, ``crossover_hz``,
            ``gain_margin_db``, ``delay_margin_ms``, ``stable``.
        """
        return {k: json_array(v) for k, v in self._columns().items()}

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
        ax = _axes(ax)
        cols = self._columns()
        xs = np.ravel(cols[x]) if x in cols else np.arange(np.size(cols["stable"]))
        pm = np.ravel(cols["phase_margin_deg"]).astype(float)
        ok = np.ravel(cols["stable"]).astype(bool)
        order = np.argsort(xs, kind="stable")
        ax.plot(xs[order], pm[order], "-", color="0.6", lw=1)
        ax.plot(xs[ok], pm[ok], "o", color="tab:blue", label="stable")
        if (~ok).any():
            ax.plot(xs[~ok], pm[~ok], "x", color="tab:red", label="unstable")
        ax.set_xlabel(x)
        ax.set_ylabel("phase margin [deg]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
        return ax


SAMPLED_COLUMNS = ("rate_hz", "verdict", "unstable_modes", "phase_margin_deg", "crossover_hz",
                   "gain_margin_db", "phase_crossover_hz", "delay_margin_ms",
                   "delay_margin_samples", "jitter_margin_ms", "jitter_margin_samples",
                   "stable")


class SampledMarginsResult(_Columns):
    """Certified verdict and margins of the sampled-data loop at its process rates
    (:func:`seactl.sampled.sampled_margins`; arrays of the batch shape).

    Every attribute of :class:`seactl.sampled.SampledMargins` is available
    (``verdict``: stable / unstable / uncertain, ``unstable_modes`` (-1 uncertain),
    ``phase_margin_deg``, ``crossover_hz`` up to Nyquist, ``gain_margin_db``,
    ``delay_margin_ms``, ``delay_margin_samples``, ``reason`` when margins are NaN).
    ``rate_hz`` in :meth:`records` is the base (fastest) rate.

    Parameters
    ----------
    margins : seactl.sampled.SampledMargins
        The computed verdict and margins.
    labels : dict
        Per-design columns (e.g. ``fn_hz``, ``gs`` and gains) of the batch shape.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                      filters_hz=(50, 100)).margins(rate_hz=1000)
    >>> r = m.records()[0]
    >>> r["verdict"], round(r["phase_margin_deg"], 1), r["delay_margin_samples"]
    ('stable', 42.0, 9)
    """

    def __init__(self, margins: Any, labels: dict[str, Any]):
        self._inner = margins
        self.labels = labels

    def __repr__(self) -> str:
        pm = np.round(np.asarray(self._inner.phase_margin_deg, float), 2)
        return f"SampledMarginsResult(rate={self._inner.rate_label!r}, phase_margin_deg=" \
               f"{pm.tolist()}, verdict={np.asarray(self._inner.verdict).tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        m = self._inner
        cols = dict(self.labels)
        cols["rate_hz"] = max(m.rates_hz.values())
        for name in SAMPLED_COLUMNS[1:]:
            cols[name] = getattr(m, name)
        shape = np.shape(m.phase_margin_deg)
        return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}

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
        out.update(rates_hz=dict(self._inner.rates_hz), period_s=self._inner.period_s,
                   reason=self._inner.reason)
        return out


class ImpedanceResult(_Wrapped):
    """Impedance ``Z(j 2 pi f)`` of a design batch.

    Every attribute of :class:`seactl.impedance.ImpedanceResponse` is available (``z``,
    ``f_hz``, ``magnitude``, ``magnitude_db``, ``phase_deg``, ``stiffness``, ``unit``).

    Parameters
    ----------
    response : seactl.impedance.ImpedanceResponse
        The computed impedance.
    labels : list of str
        One legend label per design (flattened batch).

    Examples
    --------
    >>> import seactl as sc
    >>> z = sc.design([12, 30]).impedance([1.0, 10.0, 100.0])
    >>> z.z.shape, z.unit
    ((2, 3), 'N m s/rad')
    """

    def __init__(self, response: Any, labels: list[str]):
        self._inner = response
        self.labels = labels

    def __repr__(self) -> str:
        r = self._inner
        return f"ImpedanceResult(model={r.model!r}, unit={r.unit!r}, shape={r.z.shape})"

    def to_dict(self) -> dict[str, Any]:
        """Frequencies, magnitude [unit] and phase [deg] as nested lists.

        Returns
        -------
        dict
            ``model``, ``unit``, ``load``, ``f_hz``, ``magnitude``, ``phase_deg``.
        """
        r = self._inner
        return {"model": r.model, "unit": r.unit, "load": r.load, "f_hz": json_array(r.f_hz),
                "magnitude": json_array(r.magnitude), "phase_deg": json_array(r.phase_deg)}

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
        ax = _axes(ax)
        r = self._inner
        mags = np.reshape(r.magnitude, (-1, r.f_hz.size))
        for mag, label in zip(mags, self.labels):
            ax.loglog(r.f_hz, mag, label=label)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"|Z| [{r.unit}]")
        ax.grid(True, which="both", alpha=0.3)
        if len(mags) <= 8:
            ax.legend(loc="best")
        return ax


class ResponseResult(_Wrapped):
    """A simulated step or impulse response with its metrics.

    Every attribute of :class:`seactl.simulate.SEAResponse` is available (``t_s``,
    ``position``, ``current``, ``metrics``, ``result``).

    Parameters
    ----------
    response : seactl.simulate.SEAResponse
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

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.design([14, 20], filters_hz=(50, 100)).step(t_end_s=0.3)
    >>> r.position.shape[0], sorted(r.to_dict())[:3]
    (2, ['amplitude', 'amplitude_unit', 'current'])
    """

    def __init__(self, response: Any, labels: list[str], right_roots: Any = None,
                 links: Any = None, amplitude: float | None = None, amplitude_unit: str = ""):
        self._inner = response
        self.labels = labels
        self._right_roots = right_roots
        self._links = dict(links) if links is not None else None
        self.amplitude = amplitude
        self.amplitude_unit = amplitude_unit

    def _delays(self, key: str) -> dict[str, np.ndarray]:
        info = self._inner.result.info.get(key, {})
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
        map over one period (:func:`seactl.simulate.sampled_unstable_modes`).
        ``metrics.stable`` only says the simulated response stayed bounded and decayed.

        Parameters
        ----------
        band : float, optional
            Settling band relative to the scale (default 0.02 for a step, the metrics'
            recovery band for an impulse).

        Returns
        -------
        seactl.verdict.TimeVerdict
            ``verdict`` (one string per design), ``warnings`` and ``evidence(i)``.

        Examples
        --------
        Two designs either side of the stability boundary (10.5217 ms): the window
        cannot tell them apart, the certified count can.

        >>> import seactl as sc
        >>> d = sc.design(30, delays_ms={"torque": 0.5, "stiffness": [10.5, 10.53],
                                         "damping": 0.5}, filters_hz=(50, 100))
        >>> v = d.step().verdict()
        >>> v.verdict, [v.evidence(i)["right_half_plane_roots"] for i in range(2)]
        (['not settled', 'unstable'], [0, 2])
        """
        from .verdict import STEP_BAND, judge_response

        r = self._inner
        if band is None:
            band = STEP_BAND if r.kind == "step" else r.metrics.band
        roots = self._right_roots() if (self._right_roots is not None
                                        and r.result.mode == "continuous") else None
        return judge_response(r, band, roots)

    def __repr__(self) -> str:
        r = self._inner
        return f"ResponseResult(kind={r.kind!r}, mode={r.result.mode!r}, " \
               f"shape={r.position.shape})"

    def to_dict(self) -> dict[str, Any]:
        """Time, position, current and every metric as nested lists.

        Returns
        -------
        dict
            ``kind``, ``mode``, ``amplitude``, ``amplitude_unit``, ``t_s``, ``position``,
            ``current``, ``requested_delays_ms``, ``effective_delays_ms`` (per loop),
            ``stable`` and the metrics' fields (e.g. ``overshoot_pct``).
        """
        r = self._inner
        out = {"kind": r.kind, "mode": r.result.mode,
               "amplitude": None if self.amplitude is None else json_value(self.amplitude),
               "amplitude_unit": self.amplitude_unit, "t_s": json_array(r.t_s),
               "position": json_array(r.position), "current": json_array(r.current),
               "requested_delays_ms": {k: json_array(1e3 * np.asarray(v))
                                       for k, v in self.requested_delays_s.items()},
               "effective_delays_ms": {k: json_array(1e3 * np.asarray(v))
                                       for k, v in self.effective_delays_s.items()}}
        for name, value in vars(r.metrics).items():
            out[name] = json_array(value)
        info = r.result.info
        if "sampled_verdict" in info:   # the sampled loop's certified verdict
            out["sampled_verdict"] = np.asarray(info["sampled_verdict"]).tolist()
            out["sampled_unstable_modes"] = json_array(info["sampled_unstable_modes"])
        return out

    def plot(self, ax: Any = None) -> Any:
        """Joint position against time, one line per design.

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
        r = self._inner
        ys = np.reshape(r.position, (-1, r.t_s.size))
        for y, label in zip(ys, self.labels):
            ax.plot(r.t_s, y, label=label)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("q_j / step" if r.kind == "step" else "q_j [rad]")
        ax.grid(True, alpha=0.3)
        if len(ys) <= 8:
            ax.legend(loc="best")
        return ax


JITTER_COLUMNS = {"jitter_margin_ms": "overall", "stiffness_jitter_margin_ms": "stiffness",
                  "damping_jitter_margin_ms": "damping", "torque_jitter_margin_ms": "torque"}


class JitterResult(_Columns):
    """Jitter margins of a design batch (arrays of the batch shape).

    Every attribute of :class:`seactl.jitter.JitterMargins` is available (``overall_s``,
    ``stiffness_s``, ``damping_s``, ``torque_s``, ``peak_hz``, ``delay_margin_s``,
    ``stable``, ``bottleneck``, ``ms(loop)``).  The jitter margin of a loop is the largest
    ``J`` such that any time-varying extra delay in ``[0, J]`` keeps the loop stable
    (Kao-Lincoln small-gain bound, sufficient).

    Parameters
    ----------
    margins : seactl.jitter.JitterMargins
        The computed margins.
    labels : dict
        Per-design columns (``fn_hz``, ``gs``) of the batch shape.

    Examples
    --------
    >>> import seactl as sc
    >>> j = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                      filters_hz=(50, 100)).jitter_margins()
    >>> r = j.records()[0]
    >>> round(r["jitter_margin_ms"], 2), round(r["delay_margin_ms"], 2)
    (8.04, 9.45)
    """

    def __init__(self, margins: Any, labels: dict[str, Any]):
        self._inner = margins
        self.labels = labels

    def __repr__(self) -> str:
        j = np.round(np.asarray(self._inner.overall_s, float) * 1e3, 3)
        return f"JitterResult(jitter_margin_ms={j.tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        cols = dict(self.labels)
        for name, loop in JITTER_COLUMNS.items():
            if getattr(self._inner, f"{loop}_s") is not None:
                cols[name] = self._inner.ms(loop)
        cols["delay_margin_ms"] = np.asarray(self._inner.delay_margin_s) * 1e3
        cols["stable"] = self._inner.stable
        shape = np.shape(self._inner.overall_s)
        return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape.

        Returns
        -------
        dict
            ``labels`` columns, ``jitter_margin_ms`` (whole outer loop),
            ``stiffness_jitter_margin_ms``, ``damping_jitter_margin_ms``,
            ``torque_jitter_margin_ms``, ``delay_margin_ms``, ``stable``.
        """
        return {k: json_array(v) for k, v in self._columns().items()}

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
        ax = _axes(ax)
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


class RootsResult(_Wrapped):
    """Rightmost characteristic roots of a design batch.

    Every attribute of :class:`seactl.roots.Roots` is available (``roots`` [rad/s] of
    shape ``batch + (count,)``, ``spectral_abscissa`` [1/s], ``stable``, ``uncertain``,
    ``nodes``, ``converged``; each root's error bound: ``cluster_centre`` and
    ``cluster_radius`` [rad/s], ``cluster_count``, ``real_interval`` [1/s]).

    Parameters
    ----------
    roots : seactl.roots.Roots
        The computed roots.
    labels : dict
        Per-design columns (e.g. ``fn_hz``, ``gs``) of the batch shape.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                      filters_hz=(50, 100)).roots(count=2)
    >>> round(r.records()[0]["spectral_abscissa"], 2), len(r.records()[0]["roots"])
    (-39.85, 2)
    """

    def __init__(self, roots: Any, labels: dict[str, Any]):
        self._inner = roots
        self.labels = labels

    def __repr__(self) -> str:
        a = np.round(np.asarray(self._inner.spectral_abscissa, float), 3)
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
        r = self._inner
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
        ax = _axes(ax)
        roots = np.reshape(self._inner.roots, (-1, np.shape(self._inner.roots)[-1]))
        for z in roots:
            z = z[np.isfinite(z)]
            ax.plot(np.r_[z.real, z.real], np.r_[z.imag, -z.imag], "x")
        ax.axvline(0.0, color="0.5", lw=1)
        ax.set_xlabel("Re s [1/s]")
        ax.set_ylabel("Im s [rad/s]")
        ax.grid(True, alpha=0.3)
        return ax
