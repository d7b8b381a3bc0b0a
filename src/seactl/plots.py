"""Figures (matplotlib, no display needed). Result objects stay separate from plotting."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def gain_scale_figure(fn: np.ndarray, gs: np.ndarray, pm: np.ndarray):
    """Phase margin versus GS, one curve per f_n, with each maximum marked."""
    fig, ax = plt.subplots(figsize=(7, 4.2))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(fn)))
    for f, row, c in zip(fn, pm, colors):
        ax.plot(gs, row, color=c, label=f"$f_n$ = {f:g} Hz")
        j = int(np.nanargmax(row))
        ax.plot(gs[j], row[j], "o", color=c, ms=4)
    ax.axvline(1.0, color="k", ls="--", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("gain scale GS")
    ax.set_ylabel("phase margin [deg]")
    ax.set_title("Ideal SEA loop: phase margin vs gain scale")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return fig



def sweep_map_figure(m: dict, title: str = ""):
    """Heatmap (with contours) of a sweep output over two axes (:func:`seactl.sweep.sweep_map`);
    grey: no feasible design; red line: stability boundary (half the designs of a cell stable)."""
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    x, y, z = m["x"], m["y"], np.ma.masked_invalid(m["z"])
    ax.set_facecolor("0.85")
    finite = np.isfinite(m["z"])
    if finite.any():
        lo, hi = np.nanpercentile(m["z"][finite], [1, 99])
        mesh = ax.pcolormesh(x, y, z, shading="nearest", cmap="viridis", vmin=lo, vmax=hi)
        cb = fig.colorbar(mesh, ax=ax)
        cb.set_label(f"{m['z_name']} ({m['reduce']} per cell)")
        if x.size > 2 and y.size > 2 and np.ptp(z[finite]) > 0:
            cs = ax.contour(x, y, z, levels=8, colors="white", linewidths=0.6)
            ax.clabel(cs, fontsize=7, fmt="%.3g")
    frac = m["stable_fraction"]
    if x.size > 1 and y.size > 1 and np.nanmin(frac) < 0.5 < np.nanmax(frac):
        ax.contour(x, y, np.nan_to_num(frac, nan=1.0), levels=[0.5], colors="red",
                   linewidths=1.6)
        ax.plot([], [], color="red", label="stability boundary")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel(m["x_name"])
    ax.set_ylabel(m["y_name"])
    ax.set_title(title or f"{m['z_name']} over {m['x_name']} x {m['y_name']}")
    return fig


def robust_histogram_figure(pm: np.ndarray, stable: np.ndarray, nominal_pm: float,
                            title: str = ""):
    """Histogram of the phase margin over Monte Carlo samples (stable ones), with the
    nominal margin and the share of unstable samples."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ok = stable & np.isfinite(pm)
    if ok.any():
        ax.hist(pm[ok], bins=min(60, max(10, int(np.sqrt(ok.sum())))), color="tab:blue",
                alpha=0.8, label=f"stable samples ({ok.sum()})")
    ax.axvline(nominal_pm, color="k", ls="--", lw=1.2, label=f"nominal {nominal_pm:.2f} deg")
    n_bad = int((~stable).sum())
    ax.set_xlabel("phase margin [deg]")
    ax.set_ylabel("samples")
    ax.set_title(title or "Phase margin under actuator parameter uncertainty")
    ax.text(0.02, 0.95, f"unstable: {n_bad} of {stable.size} "
            f"({100.0 * n_bad / max(stable.size, 1):.2f}%)", transform=ax.transAxes,
            va="top", fontsize=9, color="tab:red" if n_bad else "k")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(True, alpha=0.3)
    return fig
