"""The result of :meth:`seactl.System.stability_chart`: a stability chart over two delays."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from seactl.base.result import Result, json_array, new_axes
from seactl.errors import InputError

RESOLUTION = (100, 4000)
"""The raster's pixels per side: the range accepted."""
THIN_MARK = 100
"""Stable regions of fewer raster pixels are marked in :meth:`StabilityChartResult.plot`."""


def chart_arguments(delays: Any, max_s: Any, resolution: Any, names: tuple[str, ...]
                    ) -> tuple[tuple[str, str], tuple[float, float]]:
    """``delays`` (two distinct names among ``names``) and ``max_s`` (two finite delays > 0
    [s]) checked; :class:`~seactl.errors.InputError` naming the argument otherwise."""
    if isinstance(delays, str) or len(tuple(delays)) != 2:
        raise InputError("delays", delays, "two delay names among " + ", ".join(names))
    d = tuple(str(x) for x in delays)
    for x in d:
        if x not in names:
            raise InputError("delays", x, "one of " + ", ".join(names))
    if d[0] == d[1]:
        raise InputError("delays", delays, "two different delays")
    try:
        t = tuple(float(x) for x in max_s)
    except (TypeError, ValueError):
        raise InputError("max_s", max_s, "two delays > 0 [s]") from None
    if len(t) != 2 or not all(math.isfinite(x) and x > 0 for x in t):
        raise InputError("max_s", max_s, "two finite delays > 0 [s]")
    if (isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer))
            or not RESOLUTION[0] <= resolution <= RESOLUTION[1]):
        raise InputError("resolution", resolution, f"an integer from {RESOLUTION[0]} to "
                         f"{RESOLUTION[1]} (pixels per side)")
    return (d[0], d[1]), (t[0], t[1])


class StabilityChartResult(Result):
    """Crossing curves and certified right-half-plane root counts over two delays.

    Parameters
    ----------
    chart : seactl.analysis.stability_chart.Chart
        What :func:`seactl.analysis.stability_chart.stability_chart` computed.
    delays : tuple of str
        The two delays varied.
    max_s : tuple of float
        The chart's extent [s].

    Attributes
    ----------
    delays : tuple of str
        The two delays varied (``tau1``, ``tau2``), named as in the system's ``loops``.
    max_s : tuple of float
        The chart ``[0, max_s[0]] x [0, max_s[1]]`` [s].
    curves : list of dict
        One dict per branch of a crossing curve: ``tau1_s``, ``tau2_s`` [s] and
        ``w_rad_s`` [rad/s] (the frequency of the root ``jw`` on the imaginary axis there),
        arrays along the branch; its end points may lie just outside the chart.
    region_points_s : numpy.ndarray
        ``(R, 2)``: one point [s] of each region, the farthest from the curves on the raster.
    region_right_roots : numpy.ndarray
        ``(R,)`` int: the certified number of right-half-plane roots in each region
        (multiplicity and conjugates counted); -1 where no count is certain.
    region_pixels : numpy.ndarray
        ``(R,)`` int: each region's size on the raster [pixels].
    labels : numpy.ndarray
        ``(n, n)`` int: the region of each raster pixel (row: ``tau2``, column: ``tau1``;
        -1 on a curve).
    design_point_s : numpy.ndarray
        ``(2,)``: the design's own delays [s].
    design_right_roots : int
        The certified count at the design's delays (-1: not certain).
    design_stable : bool
        That count is 0.
    checks : list of dict
        Crossing-direction checks at points of the curves: ``tau1_s``, ``tau2_s``,
        ``w_rad_s``, ``expected_change`` (``2 sign(d Re s / d tau . n)``),
        ``observed_change`` (the counts' difference across the curve) and ``consistent``.
    consistent : bool
        Every check agrees.
    stable_mask : numpy.ndarray
        ``(n, n)`` bool: the raster pixels in a region with a certified count of 0.

    Examples
    --------
    >>> import seactl as sc
    >>> c = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).stability_chart(
    ...     ("stiffness", "damping"), (0.02, 0.02), resolution=400)
    >>> sorted(r["right_half_plane_roots"] for r in c.records()), c.design_stable
    ([0, 2], True)
    """

    def __init__(self, chart: Any, delays: tuple[str, str], max_s: tuple[float, float]):
        self.delays = tuple(delays)
        self.max_s = tuple(float(t) for t in max_s)
        self.curves = [{"tau1_s": b.tau1_s, "tau2_s": b.tau2_s, "w_rad_s": b.w_rad_s}
                       for b in chart.branches]
        self.region_points_s = chart.points_s
        self.region_right_roots = np.asarray(chart.counts, int)
        self.region_pixels = np.asarray(chart.pixels, int)
        self.labels = chart.labels
        self.design_point_s = chart.design_s
        self.design_right_roots = int(chart.design_count)
        self.design_stable = self.design_right_roots == 0
        self.checks = chart.checks
        self.consistent = all(c["consistent"] for c in self.checks)

    def __repr__(self) -> str:
        stable = int((self.region_right_roots == 0).sum())
        return (f"StabilityChartResult({self.delays[0]!r} x {self.delays[1]!r}, "
                f"{len(self.curves)} curve branches, {len(self.region_right_roots)} regions "
                f"({stable} stable), design {'stable' if self.design_stable else 'unstable'})")

    @property
    def stable_mask(self) -> np.ndarray:
        """``(n, n)`` bool: the raster pixels in a region with a certified count of 0."""
        ok = np.concatenate([self.region_right_roots == 0, [False]])
        return ok[self.labels]

    def records(self) -> list[dict[str, Any]]:
        """One record per region: ``tau1_s``, ``tau2_s`` (its point [s]),
        ``right_half_plane_roots``, ``stable`` and ``pixels``.

        Returns
        -------
        list of dict
            JSON-ready, one per region.
        """
        return [{"tau1_s": float(p[0]), "tau2_s": float(p[1]),
                 "right_half_plane_roots": int(c), "stable": bool(c == 0), "pixels": int(n)}
                for p, c, n in zip(self.region_points_s, self.region_right_roots,
                                   self.region_pixels)]

    def to_dict(self) -> dict[str, Any]:
        """The chart as JSON-ready values (delays [s], frequencies [rad/s]).

        Returns
        -------
        dict
            ``delays``, ``max_s``, ``design`` (``tau1_s``, ``tau2_s``,
            ``right_half_plane_roots``, ``stable``), ``curves`` (per branch ``tau1_s``,
            ``tau2_s``, ``w_rad_s``), ``regions`` (:meth:`records`), ``checks`` and
            ``consistent``.
        """
        return {"delays": list(self.delays), "max_s": list(self.max_s),
                "design": {"tau1_s": float(self.design_point_s[0]),
                           "tau2_s": float(self.design_point_s[1]),
                           "right_half_plane_roots": self.design_right_roots,
                           "stable": self.design_stable},
                "curves": [{k: json_array(v) for k, v in c.items()} for c in self.curves],
                "regions": self.records(), "checks": self.checks,
                "consistent": self.consistent}

    def plot(self, ax: Any = None) -> Any:
        """The stable regions shaded (a diamond marks each one too thin to see), the
        crossing curves and the design's point.

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
        scale, unit = (1e3, "ms") if max(self.max_s) < 1 else (1.0, "s")
        ext = (0, self.max_s[0] * scale, 0, self.max_s[1] * scale)
        shade = np.where(self.stable_mask, 1.0, np.nan)
        ax.imshow(shade, origin="lower", extent=ext, aspect="auto", cmap="Greens", vmin=0,
                  vmax=1.6, interpolation="nearest")
        for c in self.curves:
            ax.plot(c["tau1_s"] * scale, c["tau2_s"] * scale, color="C3", lw=0.9)
        thin = (self.region_right_roots == 0) & (self.region_pixels < THIN_MARK)
        if thin.any():
            p = self.region_points_s[thin] * scale
            ax.plot(p[:, 0], p[:, 1], "D", color="C2", ms=4, ls="none",
                    label="thin stable region")
        ax.plot(self.design_point_s[0] * scale, self.design_point_s[1] * scale,
                marker="o" if self.design_stable else "x", color="k", ls="none",
                label="design (" + ("stable" if self.design_stable else "unstable") + ")")
        ax.set_xlim(ext[0], ext[1])
        ax.set_ylim(ext[2], ext[3])
        ax.set_xlabel(f"{self.delays[0]} delay [{unit}]")
        ax.set_ylabel(f"{self.delays[1]} delay [{unit}]")
        ax.set_title("stable regions (shaded) and crossing curves")
        ax.legend(loc="upper right", fontsize="small")
        return ax
