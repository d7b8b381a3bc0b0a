"""The result of ``System.jitter_margins(rate_hz=...)``: jitter margins of the sampled loop."""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.base.result import Result, flat_records, json_array

LOOPS = ("overall", "stiffness", "damping", "torque")
"""The loops, as in :class:`seactl.JitterResult` (``overall``: the whole outer loop)."""


def _prefix(loop: str) -> str:
    return "" if loop == "overall" else f"{loop}_"


class SampledJitterResult(Result):
    """Jitter margins of the sampled loop at one rate (arrays of the batch shape).

    The jitter margin of a loop is the largest ``J`` such that the measurement at its break
    may be sampled late by any delay varying in ``[0, J]`` from sample to sample and the
    sampled loop stays stable (the sampled-data Kao-Lincoln bound of
    :mod:`seactl.simulate.sampled_jitter`, sufficient; docs/theory/sampled-jitter.md).

    Parameters
    ----------
    jitter : seactl.simulate.sampled_jitter.SampledJitter
        The computed margins.
    labels : dict
        Per-design columns (``fn_hz``, ``gs``) of the batch shape.

    Attributes
    ----------
    labels : dict
        The per-design label columns.
    jitter_margin_s : ndarray
        Whole outer loop's jitter margin [s] (0 where the sampled loop is unstable, NaN where
        its verdict is uncertain); JSON ``jitter_margin_ms``.
    jitter_margin_samples : ndarray
        The same in sampling periods (real).
    stiffness_jitter_margin_s, damping_jitter_margin_s, torque_jitter_margin_s : ndarray
        The same for each loop alone [s] (torque: None without a torque loop); JSON also
        ``*_jitter_margin_samples``.
    peak_hz : dict
        Loop -> frequency [Hz] where the bound's gain peaks.
    rate_hz : float
        The sampling rate [Hz].
    period_s : float
        The sampling period [s].
    unstable_modes : ndarray of int
        Certified modes of the sampled loop outside the unit circle (-1: uncertain).
    verdict : ndarray of str
        ``"stable"``, ``"unstable"`` or ``"uncertain"``.
    stable : ndarray of bool
        ``unstable_modes == 0``.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
    >>> j = r.jitter_margins(rate_hz=4000)
    >>> rec = j.records()[0]
    >>> rec["verdict"], round(rec["jitter_margin_ms"], 1), round(rec["jitter_margin_samples"])
    ('stable', 7.2, 29)
    """

    def __init__(self, jitter: Any, labels: dict[str, Any]):
        self._j = jitter
        self.labels = labels

    def _margin(self, loop: str, unit: str) -> np.ndarray | None:
        table = self._j.margin_s if unit == "s" else self._j.samples
        return table.get(loop)

    @property
    def jitter_margin_s(self) -> np.ndarray:
        """Whole outer loop's jitter margin [s]."""
        return self._margin("overall", "s")

    @property
    def jitter_margin_samples(self) -> np.ndarray:
        """Whole outer loop's jitter margin [sampling periods]."""
        return self._margin("overall", "samples")

    @property
    def stiffness_jitter_margin_s(self) -> np.ndarray:
        """Stiffness loop's jitter margin [s]."""
        return self._margin("stiffness", "s")

    @property
    def damping_jitter_margin_s(self) -> np.ndarray:
        """Damping loop's jitter margin [s]."""
        return self._margin("damping", "s")

    @property
    def torque_jitter_margin_s(self) -> np.ndarray | None:
        """Torque loop's jitter margin [s] (None without one)."""
        return self._margin("torque", "s")

    @property
    def peak_hz(self) -> dict[str, np.ndarray]:
        """Loop -> frequency [Hz] where the bound's gain peaks."""
        return dict(self._j.peak_hz)

    @property
    def rate_hz(self) -> float:
        """The sampling rate [Hz]."""
        return 1.0 / self._j.period_s

    @property
    def period_s(self) -> float:
        """The sampling period [s]."""
        return self._j.period_s

    @property
    def unstable_modes(self) -> np.ndarray:
        """Certified modes outside the unit circle (-1: uncertain)."""
        return self._j.unstable_modes

    @property
    def stable(self) -> np.ndarray:
        """Whether the sampled loop is certified stable."""
        return self._j.stable

    @property
    def verdict(self) -> np.ndarray:
        """``"stable"``, ``"unstable"`` or ``"uncertain"`` per design."""
        c = np.asarray(self.unstable_modes)
        return np.where(c == 0, "stable", np.where(c > 0, "unstable", "uncertain"))

    def __repr__(self) -> str:
        j = np.round(np.asarray(self.jitter_margin_s, float) * 1e3, 3)
        return f"SampledJitterResult(rate_hz={self.rate_hz:g}, jitter_margin_ms={j.tolist()})"

    def _columns(self) -> dict[str, np.ndarray]:
        shape = np.shape(self.jitter_margin_s)
        vals: dict[str, Any] = {"rate_hz": self.rate_hz, "verdict": self.verdict}
        for loop in LOOPS:
            if loop in self._j.margin_s:
                p = _prefix(loop)
                vals[f"{p}jitter_margin_ms"] = np.asarray(self._margin(loop, "s")) * 1e3
                vals[f"{p}jitter_margin_samples"] = self._margin(loop, "samples")
        vals["stable"] = self.stable
        cols = {**self.labels, **vals}
        return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}

    def to_dict(self) -> dict[str, Any]:
        """Every column as a (nested) list of the batch shape; NaN/inf become ``None``.

        Returns
        -------
        dict
            ``labels`` columns, ``rate_hz``, ``verdict``, ``jitter_margin_ms`` and
            ``jitter_margin_samples`` per loop (``stiffness_``, ``damping_``, ``torque_``
            prefixed), ``stable``.
        """
        return {k: (np.asarray(v).tolist() if k == "verdict" else json_array(v))
                for k, v in self._columns().items()}

    def records(self) -> list[dict[str, Any]]:
        """One flat JSON-ready dict per design, in C order of the batch.

        Returns
        -------
        list of dict
            The keys of :meth:`to_dict`, one value each (the verdict a word).
        """
        rows = flat_records({k: v for k, v in self._columns().items() if k != "verdict"})
        for r, v in zip(rows, np.ravel(self.verdict)):
            r["verdict"] = str(v)
        return rows

    def plot(self, ax: Any = None) -> Any:
        """Bars of each loop's sampled jitter margin [ms], one group per design.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw on (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes.
        """
        from seactl.base.result import new_axes

        ax = new_axes(ax)
        loops = {"whole loop": self.jitter_margin_s, "stiffness": self.stiffness_jitter_margin_s,
                 "damping": self.damping_jitter_margin_s, "torque": self.torque_jitter_margin_s}
        loops = {k: np.ravel(v) * 1e3 for k, v in loops.items() if v is not None}
        n = len(next(iter(loops.values())))
        width = 0.8 / len(loops)
        for i, (name, ms) in enumerate(loops.items()):
            ax.bar(np.arange(n) + i * width, ms, width, label=name)
        ax.set_xticks(np.arange(n) + 0.4 - width / 2, [str(i) for i in range(n)])
        ax.set_xlabel("design")
        ax.set_ylabel(f"jitter margin at {self.rate_hz:g} Hz [ms]")
        ax.legend()
        return ax
