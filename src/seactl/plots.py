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
