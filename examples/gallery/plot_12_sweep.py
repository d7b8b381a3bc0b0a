"""
A design-space sweep
====================

A grid of SEA designs (natural frequency x gain scale) evaluated in chunks into a resumable
Parquet dataset, then read back as one table. Here in this process (``workers=0``); by
default the chunks run on every core, or on a Dask cluster. Command line: ``seactl sweep
--fn 10:40:0.25 --gs 0.3:3:0.05 --t-qs 0:20:0.5 --t-qd 0.5 --out sweep.parquet``.
"""

import tempfile

import matplotlib.pyplot as plt
import numpy as np

import seactl as sc

out = tempfile.mkdtemp() + "/sweep"
res = sc.sweep(out, workers=0, chunk_size=200, fn_hz=np.arange(10, 40.1, 1.0),
               gs=np.arange(0.3, 3.01, 0.1), t_tau_ms=0.5, t_qs_ms=2, t_qd_ms=0.5,
               f_qd_hz=50, f_taud_hz=100)
print(f"{res.n_points} designs in {res.n_chunks} chunks")
t = sc.read_sweep(out)

# %%
# Phase margin over the grid (white contours: 30 and 45 degrees). Grey: unstable designs,
# whose phase margin says nothing.
fn, gs = t.column("fn_hz").to_numpy(), t.column("gs").to_numpy()
pm = np.array(t.column("phase_margin_deg").to_pylist(), float)
stable = np.array(t.column("stable").to_pylist(), bool)
print(f"{(~stable).sum()} of {stable.size} designs unstable")
F, G = np.unique(fn), np.unique(gs)                # the table is sorted f_n-major
P = np.where(stable, pm, np.nan).reshape(F.size, G.size)
fig, ax = plt.subplots(figsize=(8, 4.5))
ax.set_facecolor("0.8")
ax.grid(False)
c = ax.pcolormesh(G, F, P, shading="nearest", vmin=0, vmax=70)
ax.contour(G, F, P, levels=[30, 45], colors="w", linewidths=0.8)
ax.set_xlabel("gain scale GS")
ax.set_ylabel("f_n [Hz]")
cb = fig.colorbar(c, ax=ax, label="phase margin [deg]")
