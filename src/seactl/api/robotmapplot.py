"""The figure of a workspace map: :func:`plot_workspace_map`.

A map of two joints on a full grid is a heat map over ``(q1, q2)``; any other map (a
trajectory, more joints) is a curve along the time or the sample index.  Both mark the
unstable configurations, the configurations whose stiffness search saw the verdict flip
more than once, and the worst configuration.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.base.result import new_axes
from seactl.errors import InputError

QUANTITIES = {"max_task_stiffness_n_per_m": "largest task stiffness k_x [N/m]",
              "mimo_delay_margin_ms": "central delay margin [ms]",
              "mimo_phase_margin_deg": "MIMO phase margin [deg]",
              "phase_margin_deg": "phase margin at outer.j1 [deg]"}
"""The values a map can draw -> their axis label."""


def grid_axes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The two axes of a 2-joint grid in C order (first joint slowest), or None if ``q``
    is not one."""
    if q.shape[1] != 2:
        return None
    a, b = np.unique(q[:, 0]), np.unique(q[:, 1])
    if a.size * b.size != q.shape[0] or a.size < 2 or b.size < 2:
        return None
    grid = np.stack(np.meshgrid(a, b, indexing="ij"), -1).reshape(-1, 2)
    return (a, b) if np.array_equal(grid, q) else None


def default_quantity(m: Any) -> str:
    """The largest task stiffness where the map has it (task space), else the central
    delay margin (the phase margin at ``outer.j1`` for a map without MIMO margins)."""
    k = np.asarray(m.max_task_stiffness_n_per_m, float)
    if not np.all(np.isnan(k)):
        return "max_task_stiffness_n_per_m"
    return "phase_margin_deg" if m.mimo_delay_margin_ms is None else "mimo_delay_margin_ms"


def marked(m: Any, quantity: str) -> int:
    """The configuration marked: the smallest value of ``quantity`` (an unstable
    configuration first; for the central delay margin, ``m.worst``)."""
    if quantity == "mimo_delay_margin_ms":
        return int(m.worst)
    k = np.where(m.stable, np.nan_to_num(np.asarray(getattr(m, quantity), float),
                                         nan=np.inf), -np.inf)
    return int(np.argmin(k))


def plot_workspace_map(m: Any, ax: Any = None, quantity: str | None = None) -> Any:
    """Draw the map ``m`` (:class:`seactl.api.robotmap.WorkspaceMap`).

    Parameters
    ----------
    m : WorkspaceMap
        The map.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new figure).
    quantity : str, optional
        A key of :data:`QUANTITIES` (default: :func:`default_quantity`).

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on.
    """
    quantity = default_quantity(m) if quantity is None else quantity
    if quantity not in QUANTITIES or getattr(m, quantity) is None:
        raise InputError("quantity", quantity, "one of " + ", ".join(
            q for q in QUANTITIES if getattr(m, q) is not None))
    values = np.asarray(getattr(m, quantity), float)
    if quantity == "max_task_stiffness_n_per_m" and np.all(np.isnan(values)):
        raise InputError("quantity", quantity, "phase_margin_deg in joint space (the "
                         "largest task stiffness is a task-space value)")
    ax = new_axes(ax)
    axes = grid_axes(m.q0_rad)
    if axes is not None:
        xy = (m.q0_rad[:, 0], m.q0_rad[:, 1])
        _heat(ax, m, axes, values, quantity)
    else:
        x = np.arange(len(values)) if m.t_s is None else np.asarray(m.t_s, float)
        xy = (x, np.where(np.isfinite(values), values, np.nan))
        _curve(ax, m, x, values, quantity)
    what = "lowest k_x" if quantity == "max_task_stiffness_n_per_m" else "worst"
    _marks(ax, m, xy, marked(m, quantity), what)
    ax.legend(loc="best", fontsize="small")
    return ax


def _heat(ax: Any, m: Any, axes: tuple[np.ndarray, np.ndarray], values: np.ndarray,
          quantity: str) -> None:
    """The heat map of ``values`` over the grid (log colours for the stiffness)."""
    from matplotlib.colors import LogNorm

    a, b = axes
    z = values.reshape(a.size, b.size).T
    z = np.where(np.isfinite(z) & ((z > 0) | (quantity != "max_task_stiffness_n_per_m")),
                 z, np.nan)
    stiff = quantity == "max_task_stiffness_n_per_m" and np.any(np.isfinite(z))
    norm = LogNorm(np.nanmin(z), np.nanmax(z)) if stiff else None
    mesh = ax.pcolormesh(a, b, z, shading="nearest", cmap="viridis", norm=norm)
    ax.figure.colorbar(mesh, ax=ax, label=QUANTITIES[quantity])
    ax.set_xlabel(f"{m.joints[0]} [rad]")
    ax.set_ylabel(f"{m.joints[1]} [rad]")


def _curve(ax: Any, m: Any, x: np.ndarray, values: np.ndarray, quantity: str) -> None:
    """``values`` along the samples."""
    ax.plot(x, np.where(np.isfinite(values), values, np.nan), "o-", ms=3,
            label=QUANTITIES[quantity].split(" [")[0])
    if quantity == "max_task_stiffness_n_per_m":
        ax.set_yscale("log")
    ax.set_xlabel("t [s]" if m.t_s is not None else "configuration (sample index)")
    ax.set_ylabel(QUANTITIES[quantity])


def _marks(ax: Any, m: Any, xy: tuple[np.ndarray, np.ndarray], worst: int, what: str
           ) -> None:
    """Unstable configurations, multiple flips, and the worst configuration."""
    x, y = (np.asarray(v, float) for v in xy)
    bad = ~np.asarray(m.stable, bool)
    if bad.any():
        yb = np.where(np.isfinite(y[bad]), y[bad], np.nanmin(y) if np.any(np.isfinite(y))
                      else 0.0)
        ax.plot(x[bad], yb, "x", color="red", ms=8, mew=2, ls="none", label="unstable")
    flips = ~np.asarray(m.single_flip if m.single_flip is not None else
                        np.ones(len(x), bool), bool)
    if flips.any():
        ax.plot(x[flips], y[flips], "s", mfc="none", mec="orange", ms=10, mew=1.5,
                ls="none", label="verdict flips more than once in k_x")
    ax.plot([x[worst]], [y[worst] if np.isfinite(y[worst]) else np.nanmin(y)], "*",
            color="white", mec="black", ms=16, ls="none",
            label=f"{what}: configuration {worst + 1}")
