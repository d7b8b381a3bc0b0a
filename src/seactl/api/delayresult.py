"""The result of :meth:`seactl.System.delay_margin`: the delay margin along a direction of
the delay vector, per design."""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.base.result import Result, flat_records, json_array, json_value, new_axes

COLUMNS = ("delay_margin_s", "crossing_hz", "crossing_rad_s", "stable", "verified", "touch")


class DelayMarginResult(Result):
    """Delay margin along a direction of the delays (arrays of the batch shape).

    The delays move on ``tau0 + t d / max(d)``; the margin is the smallest ``t >= 0`` at
    which a characteristic root reaches the imaginary axis
    (:func:`seactl.analysis.delay_direction.direction_margin`).

    Parameters
    ----------
    margin : seactl.analysis.delay_direction.DirectionMargin
        The computed margins (flat batch).
    names : tuple of str
        The delays' names.
    shape : tuple of int
        The batch shape.
    labels : dict
        Per-design columns of the batch shape, repeated in :meth:`records`.

    Attributes
    ----------
    labels : dict
        The per-design label columns.
    direction : dict
        Delay name -> its weight ``d / max(d)`` (1 for the most-moved delays).
    delay_margin_s : ndarray
        Extra delay of the most-moved delay at the first root on the axis [s]; 0 where
        unstable at the design's delays, ``inf`` where no root reaches the axis, NaN where
        the count at the design's delays is uncertain.
    crossing_rad_s, crossing_hz : ndarray
        That root's frequency [rad/s] / [Hz]; NaN where none.
    crossing_delays_s : dict
        Delay name -> its value at the crossing [s] (``inf`` where the margin is).
    stable : ndarray of bool
        Certified stable at the design's delays (no root with ``Re s >= 0``).
    verified : ndarray of bool
        The certified root counts agreed: none in the right half-plane at points of
        ``[0, t*)``, some just beyond ``t*`` (or a touch).
    touch : ndarray of bool
        The root at ``t*`` touches the axis and goes back (the count beyond is still 0).

    Examples
    --------
    Growing both delays of the rigid actuator alike is the loop's own delay margin:

    >>> import seactl as sc
    >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.0})
    >>> m = r.delay_margin()
    >>> round(float(m.delay_margin_s) * 1e3, 3), round(float(r.margins().delay_margin_ms), 3)
    (9.612, 9.612)
    >>> round(float(r.delay_margin({"stiffness": 1}).delay_margin_s) * 1e3, 2)
    55.2
    """

    def __init__(self, margin: Any, names: tuple[str, ...], shape: tuple[int, ...],
                 labels: dict[str, Any]):
        self.labels = labels
        self.direction = {n: float(x) for n, x in zip(names, margin.direction)}
        self.delay_margin_s = margin.delay_margin_s.reshape(shape)
        self.crossing_rad_s = margin.crossing_rad_s.reshape(shape)
        self.crossing_hz = self.crossing_rad_s / (2 * np.pi)
        fin = np.isfinite(margin.delay_margin_s) | np.isnan(margin.delay_margin_s)
        self.crossing_delays_s = {n: np.where(fin, tau, np.inf).reshape(shape)
                                  for n, tau in zip(names, margin.delays_s)}
        self.stable = margin.stable.reshape(shape)
        self.verified = margin.verified.reshape(shape)
        self.touch = margin.touch.reshape(shape)

    def __repr__(self) -> str:
        t = np.asarray(self.delay_margin_s, float)
        return f"DelayMarginResult(delay_margin_s={t.tolist()}, direction={self.direction})"

    def _columns(self) -> dict[str, np.ndarray]:
        shape = np.shape(self.delay_margin_s)
        cols = {**self.labels, **{k: getattr(self, k) for k in COLUMNS}}
        return {k: np.broadcast_to(np.asarray(v), shape) for k, v in cols.items()}

    def to_dict(self) -> dict[str, Any]:
        """The columns as nested lists of the batch shape (NaN and infinities: ``None``),
        ``crossing_delays_s`` (name -> nested list) and ``direction``.

        Returns
        -------
        dict
            ``labels`` columns, ``delay_margin_s``, ``crossing_hz``, ``crossing_rad_s``,
            ``stable``, ``verified``, ``touch``, ``crossing_delays_s``, ``direction``.
        """
        out = super().to_dict()
        out["crossing_delays_s"] = {k: json_array(v) for k, v in
                                    self.crossing_delays_s.items()}
        out["direction"] = dict(self.direction)
        return out

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready dict per design (C order): the columns of :meth:`to_dict` and
        ``crossing_delays_s`` (name -> [s]).

        Returns
        -------
        list of dict
            The command line's rows.
        """
        rows = flat_records(self._columns())
        tau = {k: np.ravel(v) for k, v in self.crossing_delays_s.items()}
        for i, row in enumerate(rows):
            row["crossing_delays_s"] = {k: json_value(v[i]) for k, v in tau.items()}
        return rows

    def plot(self, ax: Any = None) -> Any:
        """The margin [s] per design (index order); unstable designs in red at 0.

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
        t = np.ravel(self.delay_margin_s).astype(float)
        ok = np.ravel(self.stable).astype(bool)
        i = np.arange(t.size)
        ax.plot(i[ok], t[ok], "o", color="tab:blue", label="stable")
        if (~ok).any():
            ax.plot(i[~ok], np.zeros((~ok).sum()), "x", color="tab:red", label="unstable")
        ax.set_xlabel("design")
        ax.set_ylabel("delay margin along the direction [s]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
        return ax
