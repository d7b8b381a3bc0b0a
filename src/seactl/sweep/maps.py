"""Sweep results as maps over two axes, for plots."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from seactl.errors import InputError
from seactl.sweep.dataset import read_manifest, read_sweep


# ------------------------------------------------------------------ maps for plots
def sweep_map(out: Path | str, x: str, y: str, z: str = "phase_margin_deg",
              reduce: str = "min", bins: int = 40) -> dict[str, Any]:
    """``z`` over the two axes ``x`` and ``y`` of the sweep in ``out``.

    Grid sweeps keep their axis values; sampled sweeps are binned (``bins`` per
    axis).  Points sharing a cell (other swept axes) are reduced with ``min``,
    ``max`` or ``mean`` over their feasible points (``min`` of a margin is the
    worst case).  Returns ``x``, ``y`` (cell centres), ``z`` (shape
    ``(len(y), len(x))``, NaN where no feasible point) and ``stable_fraction``.
    """
    out = Path(out)
    manifest = read_manifest(out)
    swept = manifest["swept_axes"]
    for opt, name in (("--plot", x), ("--plot", y)):
        if name not in swept:
            raise InputError(opt, name, "one of the swept axes (" + ", ".join(swept) + ")")
    if x == y:
        raise InputError("--plot", f"{x},{y}", "two different axes")
    cols = set(manifest["columns"]) - {"point", "feasible"}
    if z not in cols:
        raise InputError("--plot-z", z, "one of " + ", ".join(sorted(cols)))
    if reduce not in ("min", "max", "mean"):
        raise InputError("--plot-reduce", reduce, "min, max or mean")
    t = read_sweep(out, [x, y, z, "feasible", "stable"])
    feas = t.column("feasible").to_numpy()
    xv, yv = (t.column(c).to_numpy()[feas] for c in (x, y))
    zv = np.asarray(t.column(z).to_numpy(zero_copy_only=False), float)[feas]
    st = np.asarray(t.column("stable").to_numpy(zero_copy_only=False), float)[feas]

    def cells(v: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
        if manifest["spec"]["sampling"] == "grid":
            grid = np.asarray(manifest["spec"]["axes"][name], float)
            centres = np.unique(grid)
            return centres, np.searchsorted(centres, v)
        lo, hi = float(np.min(v)), float(np.max(v))
        edges = np.linspace(lo, hi, bins + 1)
        return 0.5 * (edges[1:] + edges[:-1]), np.clip(np.searchsorted(edges, v, "right") - 1,
                                                       0, bins - 1)

    xc, ix = cells(xv, x)
    yc, iy = cells(yv, y)
    flat = iy * xc.size + ix
    size = xc.size * yc.size
    count = np.bincount(flat, minlength=size).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = ~np.isnan(zv)
        n_ok = np.bincount(flat[ok], minlength=size)
        if reduce == "mean":
            zs = np.bincount(flat[ok], zv[ok], minlength=size) / n_ok
        else:
            zs = np.full(size, np.inf if reduce == "min" else -np.inf)
            (np.minimum if reduce == "min" else np.maximum).at(zs, flat[ok], zv[ok])
        zs[n_ok == 0] = np.nan
        frac = np.bincount(flat, st, minlength=size) / count
    return {"x": xc, "y": yc, "z": zs.reshape(yc.size, xc.size),
            "stable_fraction": frac.reshape(yc.size, xc.size), "x_name": x, "y_name": y,
            "z_name": z, "reduce": reduce, "n_points": int(t.num_rows)}
