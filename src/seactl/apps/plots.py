"""Figures (matplotlib, no display needed). Result objects stay separate from plotting."""

from __future__ import annotations

import numpy as np


def pyplot():
    """matplotlib.pyplot on the Agg backend, imported on first use so that ``import seactl``
    and ``seactl --help`` stay free of matplotlib."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def gain_scale_figure(fn: np.ndarray, gs: np.ndarray, pm: np.ndarray):
    """Phase margin versus GS, one curve per f_n, with each maximum marked."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(fn)))
    for f, row, c in zip(fn, pm, colors):
        ax.plot(gs, row, color=c, label=f"$f_n$ = {f:g} Hz")
        j = int(np.nanargmax(row))
        ax.plot(gs[j], row[j], "o", color=c, ms=4)
    ax.axvline(1.0, color="k", ls="--", lw=0.8)
    ax.set_xscale("log")
    ticks = [t for t in (0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0) if gs.min() <= t <= gs.max()]
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.minorticks_off()
    ax.set_xlabel("gain scale GS")
    ax.set_ylabel("phase margin [deg]")
    ax.set_title("Ideal SEA loop: phase margin vs gain scale")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return fig


# ---------------------------------------------------------------------------------- impedance
def impedance_bode_figure(columns, *, suptitle: str | None = None, unit: str = "N m s/rad",
                          col_width: float = 4.6):
    """Bode magnitude (dB) and unwrapped phase (deg) of impedances, one column per panel.

    ``columns``: list of ``(title, curves)``; each curve is a dict with ``f`` [Hz], ``z``
    (complex), ``label`` and optional ``color``, ``dashed`` (asymptotes and references:
    drawn dashed and excluded from the axis limits), ``lw``.
    """
    plt = pyplot()
    n = len(columns)
    fig, axes = plt.subplots(2, n, figsize=(col_width * n, 6.2), sharex="col", squeeze=False,
                             gridspec_kw={"height_ratios": [1.6, 1]})
    for j, (title, curves) in enumerate(columns):
        am, ap = axes[0, j], axes[1, j]
        lo, hi = np.inf, -np.inf
        for c in curves:
            f, z = np.asarray(c["f"]), np.asarray(c["z"])
            db = 20 * np.log10(np.abs(z))
            ph = np.degrees(np.unwrap(np.angle(z)))
            ls = "--" if c.get("dashed") else "-"
            lw = c.get("lw", 1.0 if c.get("dashed") else 1.6)
            am.semilogx(f, db, ls=ls, lw=lw, color=c.get("color"), label=c.get("label"))
            ap.semilogx(f, ph, ls=ls, lw=lw, color=c.get("color"))
            if not c.get("dashed"):
                lo, hi = min(lo, float(np.nanmin(db))), max(hi, float(np.nanmax(db)))
        if np.isfinite(lo):
            am.set_ylim(lo - 8, hi + 8)
        am.set_title(title, fontsize=10)
        am.grid(True, which="both", alpha=0.3)
        ap.grid(True, which="both", alpha=0.3)
        ap.set_xlabel("frequency [Hz]")
        if j == 0:
            am.set_ylabel(f"|Z| [dB re 1 {unit}]")
            ap.set_ylabel("phase of Z [deg]")
        am.legend(fontsize=7, loc="best")
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    fig.tight_layout()
    return fig


def loop_bode_figure(f_hz, columns, *, suptitle: str | None = None):
    """Bode plot of loop transfers broken at named points, one column per break.

    ``columns``: list of ``(title, curves, crossings)``; each curve is ``(label, L)`` with
    ``L`` complex on ``f_hz``; ``crossings`` lists gain-crossover frequencies [Hz] to mark.
    """
    plt = pyplot()
    n = len(columns)
    fig, axes = plt.subplots(2, n, figsize=(4.6 * n, 6.2), sharex="col", squeeze=False,
                             gridspec_kw={"height_ratios": [1.4, 1]})
    for j, (title, curves, crossings) in enumerate(columns):
        am, ap = axes[0, j], axes[1, j]
        for label, L in curves:
            am.semilogx(f_hz, 20 * np.log10(np.abs(L)), lw=1.4, label=label)
            ap.semilogx(f_hz, np.degrees(np.unwrap(np.angle(L))), lw=1.4)
        am.axhline(0.0, color="k", lw=0.7)
        for fc in crossings:
            am.axvline(fc, color="0.5", ls="--", lw=0.7)
            ap.axvline(fc, color="0.5", ls="--", lw=0.7)
        am.set_title(title, fontsize=10)
        am.grid(True, which="both", alpha=0.3)
        ap.grid(True, which="both", alpha=0.3)
        ap.set_xlabel("frequency [Hz]")
        if j == 0:
            am.set_ylabel("|L| [dB]")
            ap.set_ylabel("phase of L [deg]")
        if any(label for label, _ in curves):
            am.legend(fontsize=7)
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    fig.tight_layout()
    return fig


def zregion_figure(region, fn_hz, gs, *, spring=None, unit: str = "N m s/rad"):
    """Z-region: admissible |Z| envelope, Z-width with the Z-depth, admissible design map."""
    plt = pyplot()
    f = region.f_hz
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4),
                             gridspec_kw={"width_ratios": [1.3, 1.0, 0.9]})
    ax = axes[0]
    mag = region.magnitude.reshape(-1, f.size)
    for row in mag[region.admissible.reshape(-1)]:
        ax.semilogx(f, 20 * np.log10(row), color="0.75", lw=0.5)
    ax.fill_between(f, 20 * np.log10(region.z_min), 20 * np.log10(region.z_max),
                    color="tab:blue", alpha=0.25, label="Z-region (admissible envelope)")
    ax.semilogx(f, 20 * np.log10(region.z_max), color="tab:blue", lw=1.4)
    ax.semilogx(f, 20 * np.log10(region.z_min), color="tab:blue", lw=1.4)
    if spring is not None:
        ax.semilogx(f, 20 * np.log10(np.abs(spring)), "k--", lw=1, label="spring k/(jw)")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"|Z| [dB re 1 {unit}]")
    ax.set_title(f"{region.n_admissible} admissible designs ({region.model})", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1]
    ax.semilogx(f, region.width_db, color="tab:blue")
    ax.axhline(region.threshold_db, color="k", ls=":", lw=1,
               label=f"threshold {region.threshold_db:g} dB")
    if region.depth_hz is not None:
        ax.axvspan(*region.depth_hz, color="tab:green", alpha=0.15,
                   label=f"Z-depth {region.depth_hz[0]:.3g}-{region.depth_hz[1]:.3g} Hz "
                         f"({region.depth_decades:.2f} dec)")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("Z-width [dB]")
    ax.set_title("Z-width = 20 log10(max|Z| / min|Z|)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[2]
    pm = np.where(region.stable, region.phase_margin_deg, np.nan)
    im = ax.pcolormesh(np.asarray(gs), np.asarray(fn_hz), pm, cmap="viridis", shading="nearest")
    fig.colorbar(im, ax=ax, label="phase margin [deg] (blank: unstable)")
    yy, xx = np.nonzero(~region.admissible)
    ax.plot(np.asarray(gs)[xx], np.asarray(fn_hz)[yy], "x", color="r", ms=4,
            label="not admissible")
    ax.set_xlabel("gain scale GS")
    ax.set_ylabel("f_n [Hz]")
    ax.set_title(f"admissible: PM >= {region.min_pm_deg:g} deg"
                 + (", passive" if region.require_passive else ""), fontsize=10)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    return fig


def sweep_map_figure(m: dict, title: str = ""):
    """Heatmap (with contours) of a sweep output over two axes
    (:func:`seactl.sweep.maps.sweep_map`);
    grey: no feasible design; red line: stability boundary of the cells' designs."""
    plt = pyplot()
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
    # worst case (min): the boundary of "every design of the cell stable"; best case (max):
    # of "some design stable"; mean: half of them
    frac = m["stable_fraction"]
    level, what = {"min": (1 - 1e-9, "all"), "max": (1e-9, "some")}.get(m["reduce"],
                                                                        (0.5, "half"))
    if x.size > 1 and y.size > 1 and np.nanmin(frac) < level < np.nanmax(frac):
        ax.contour(x, y, np.nan_to_num(frac, nan=1.0), levels=[level], colors="red",
                   linewidths=1.6)
        ax.plot([], [], color="red", label=f"stability boundary ({what} designs of a "
                "cell stable)")
    if (~np.isfinite(m["z"])).any():
        ax.fill_between([], [], color="0.85", label="no feasible design")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=7)
    ax.set_xlabel(m["x_name"])
    ax.set_ylabel(m["y_name"])
    ax.set_title(title or f"{m['z_name']} over {m['x_name']} x {m['y_name']}")
    return fig


def robust_histogram_figure(pm: np.ndarray, stable: np.ndarray, nominal_pm: float,
                            title: str = ""):
    """Histogram of the phase margin over Monte Carlo samples (stable ones), with the
    nominal margin and the share of unstable samples."""
    plt = pyplot()
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


# ----------------------------------------------------------------------------- loop placement
def latency_map_figure(maps, maxfn=None, title: str = ""):
    """Phase-margin maps over (damping delay, stiffness delay), one row per actuator.

    ``maps``: list of :class:`seactl.latency.maps.LatencyMap`; ``maxfn``: optional list
    (same order) of ``(T_s [s], T_d [s], MaxFn)`` drawn in a second column.  The thick
    black line is the stability boundary; unstable points are hatched.
    """
    plt = pyplot()
    ncol = 2 if maxfn else 1
    fig, axes = plt.subplots(len(maps), ncol, figsize=(5.6 * ncol, 4.4 * len(maps)),
                             squeeze=False)
    levels = np.arange(-90, 91, 15)
    for i, mp in enumerate(maps):
        ax = axes[i, 0]
        td, ts = mp.T_d * 1e3, mp.T_s * 1e3
        pm = np.clip(np.where(np.isfinite(mp.phase_margin_deg), mp.phase_margin_deg, 90),
                     -90, 90)
        cf = ax.contourf(td, ts, pm, levels=levels, cmap="RdYlGn", extend="both")
        cs = ax.contour(td, ts, pm, levels=[0, 15, 30, 45, 60], colors="k", linewidths=0.6)
        ax.clabel(cs, fmt="%g", fontsize=7)
        st = mp.stable.astype(float)
        if 0 < st.mean() < 1:
            ax.contour(td, ts, st, levels=[0.5], colors="k", linewidths=2.2)
            ax.contourf(td, ts, st, levels=[-0.5, 0.5], colors="none", hatches=["//"])
        fig.colorbar(cf, ax=ax, label="phase margin [deg]")
        ax.set_xlabel("damping-loop delay $T_d$ [ms]")
        ax.set_ylabel("stiffness-loop delay $T_s$ [ms]")
        ax.set_title(f"{mp.actuator}: phase margin, $f_n$ = {mp.fn_hz:g} Hz", fontsize=10)
        ax.plot([td[0], min(td[-1], ts[-1])], [ts[0], min(td[-1], ts[-1])], "k:", lw=0.8)
        ax.set_xlim(td[0], td[-1])
        ax.set_ylim(ts[0], ts[-1])
        if maxfn:
            T_s, T_d, res = maxfn[i]
            ax = axes[i, 1]
            f = np.where(np.isnan(res.fn_hz), 0.0, res.fn_hz)
            cf = ax.contourf(T_d * 1e3, T_s * 1e3, f, levels=20, cmap="viridis")
            cs = ax.contour(T_d * 1e3, T_s * 1e3, f, levels=8, colors="w", linewidths=0.6)
            ax.clabel(cs, fmt="%.3g", fontsize=7)
            fig.colorbar(cf, ax=ax, label="max stable $f_n$ [Hz]")
            ax.set_xlabel("damping-loop delay $T_d$ [ms]")
            ax.set_ylabel("stiffness-loop delay $T_s$ [ms]")
            crit = ("stable" if res.min_pm_deg is None
                    else f"PM $\\geq$ {res.min_pm_deg:g} deg")
            ax.set_title(f"{mp.actuator}: highest $f_n$ keeping the loop {crit}", fontsize=10)
            none = np.isnan(res.fn_hz)
            if none.any():
                ax.contourf(T_d * 1e3, T_s * 1e3, none.astype(float), levels=[0.5, 1.5],
                            colors="none", hatches=["xx"])
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def step_experiment_figure(t, y, panels, fn_hz, unstable, saturated, title: str = ""):
    """Four-panel normalized step responses: ``y[panel, fn, time]``; ``panels`` are
    labels; unstable runs are drawn dashed and marked in the legend."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharex=True, sharey=True)
    colors = plt.cm.plasma(np.linspace(0.05, 0.8, len(fn_hz)))
    for k, ax in enumerate(axes.ravel()):
        for j, (f, c) in enumerate(zip(fn_hz, colors)):
            tag = " UNSTABLE" if unstable[k, j] else ""
            tag += " (sat.)" if saturated[k, j] else ""
            ax.plot(t[: y.shape[-1]], np.clip(y[k, j], -1.0, 3.0), color=c,
                    ls="--" if unstable[k, j] else "-", lw=1.2,
                    label=f"$f_n$ = {f:g} Hz{tag}")
        ax.axhline(1.0, color="k", lw=0.6, ls=":")
        ax.set_title(f"({'abcd'[k]}) {panels[k]}", fontsize=10)
        ax.set_ylim(-1.0, 3.0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    for ax in axes[:, 0]:
        ax.set_ylabel("normalized position")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------- mobile base
# (seactl.systems.mobile_base.model)
_BASE_COLORS = {"cosc": "tab:red", "dosc": "tab:blue"}


def base_tracking_figure(comparison, paper_kx: dict | None = None):
    """COSC vs DOSC: circle paths, errors over time, the two gain searches, the limits."""
    plt = pyplot()
    p = comparison.params
    res = comparison.track
    archs = list(comparison.results)
    fig, axs = plt.subplots(2, 3, figsize=(14, 8.2))
    ax = axs[0, 0]
    ax.plot(res.x_d[:, 0], res.x_d[:, 1], "k--", lw=1, label="reference")
    mag = 50.0   # errors are millimetres on a half-metre circle: magnify them to be seen
    for i, a in enumerate(archs):
        path = res.x_d[:, :2] + mag * (res.x[:, i, :2] - res.x_d[:, :2])
        ax.plot(path[:, 0], path[:, 1], color=_BASE_COLORS[a], lw=1.0, label=a.upper())
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"circle tracked (errors magnified x{mag:g})")
    ax.legend(fontsize=8)
    for ax, err, unit, name in ((axs[0, 1], res.position_error() * 1e3, "mm", "position"),
                                (axs[0, 2], res.velocity_error() * 1e3, "mm/s", "velocity")):
        for i, a in enumerate(archs):
            r = comparison.results[a]
            rms = (r.rms_position_m if name == "position" else r.rms_velocity_mps) * 1e3
            ax.plot(res.t, err[:, i], color=_BASE_COLORS[a], lw=0.8,
                    label=f"{a.upper()} (RMS {rms:.3g} {unit})")
        ax.axvline(p.circle_ramp, color="k", lw=0.6, ls=":")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"{name} error [{unit}]")
        ax.set_title(f"{name} error (RMS after the {p.circle_ramp:g} s ramp)")
        ax.set_yscale("log")
        ax.set_ylim(bottom=np.nanmax(err) * 1e-3)
        ax.legend(fontsize=8)
    for ax, key, label, unit in ((axs[1, 0], "damping_search", "damping", "N s/(m kg)"),
                                 (axs[1, 1], "kx_search", "stiffness $K_x$", "N/(m kg)")):
        for a in archs:
            s = getattr(comparison.results[a], key)
            c = _BASE_COLORS[a]
            ax.plot(s.gains, s.oscillation / p.criterion_oscillation_threshold, "o-", ms=3,
                    color=c, lw=1, label=f"{a.upper()} oscillation")
            ax.plot(s.gains, s.vibration / p.criterion_vibration_threshold, "s--", ms=3,
                    color=c, lw=0.8, alpha=0.6, label=f"{a.upper()} torque ripple")
            if s.limit > 0:
                ax.axvline(s.limit, color=c, lw=1.5, alpha=0.5)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{label} [{unit}]")
        ax.set_ylabel("criterion / threshold")
        step = "1, $K_x$ = 0" if key == "damping_search" else "2, damping at safety x limit"
        ax.set_title(f"gain search, step {step}")
        ax.legend(fontsize=7)
    ax = axs[1, 2]
    w = 0.38
    xs = np.arange(len(archs))
    ax.bar(xs - w / 2, [comparison.results[a].max_kx for a in archs], w,
           color=[_BASE_COLORS[a] for a in archs], label="seactl (model)")
    if paper_kx:
        ax.bar(xs + w / 2, [paper_kx.get(a, np.nan) for a in archs], w, color="0.6",
               label="paper (hardware)")
    ax.set_xticks(xs, [a.upper() for a in archs])
    ax.set_yscale("log")
    ax.set_ylabel("maximum $K_x$ [N/(m kg)]")
    ax.set_title("maximum Cartesian stiffness")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def base_animation(comparison, path, fps: int = 12, seconds: float | None = None) -> None:
    """Animated GIF of the bases tracking the circle side by side.

    The axes, titles and reference are drawn once; each frame restores that background and
    draws only the moving artists (blitting), then Pillow assembles the GIF on one shared
    palette.  A full redraw per frame spent most of its time laying out the same text.
    """
    plt = pyplot()
    from PIL import Image

    res = comparison.track
    T = res.t[-1] if seconds is None else min(seconds, res.t[-1])
    idx = np.searchsorted(res.t, np.arange(0.0, T, 1.0 / fps))
    fig, artists, draw = _base_animation_figure(comparison)
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    frames = []
    for k in idx:
        canvas.restore_region(background)
        for artist in draw(k):
            artist.axes.draw_artist(artist)
        frames.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3].copy()))
    plt.close(fig)
    palette = frames[-1].quantize(colors=64)
    images = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    images[0].save(str(path), save_all=True, append_images=images[1:],
                   duration=int(round(1000 / fps)), loop=0)


def _base_animation_figure(comparison):
    """The static figure of :func:`base_animation`, its moving artists, and a function that
    moves them to sample ``k`` (returns the artists to draw)."""
    plt = pyplot()
    p, res = comparison.params, comparison.track
    archs = list(comparison.results)
    thin = max(1, res.t.size // 2000)      # at most ~2000 points per line
    fig, axs = plt.subplots(1, len(archs), figsize=(4.2 * len(archs), 4.2), squeeze=False,
                            dpi=80)
    R, a_w, L = p.circle_radius, p.alpha, p.wheel_distance
    artists = []
    for ax, (i, a) in zip(axs[0], enumerate(archs)):
        ax.plot(res.x_d[::thin, 0], res.x_d[::thin, 1], "k--", lw=0.8)
        ax.set_xlim(-2 * R - 0.4, 0.4)
        ax.set_ylim(-R - 0.4, R + 0.4)
        ax.set_aspect("equal")
        r = comparison.results[a]
        ax.set_title(f"{a.upper()}: K_x = {r.kx:.3g} N/(m kg)\nRMS error "
                     f"{r.rms_position_m * 1e3:.3g} mm", fontsize=9)
        body, = ax.fill([], [], color=_BASE_COLORS[a], alpha=0.35, animated=True)
        wheels, = ax.plot([], [], "k-", lw=3, solid_capstyle="butt", animated=True)
        trace, = ax.plot([], [], color=_BASE_COLORS[a], lw=1, animated=True)
        target, = ax.plot([], [], "kx", ms=6, animated=True)
        artists.append((i, body, wheels, trace, target))

    def draw(k):
        out = []
        for i, body, wheels, trace, target in artists:
            x, y, th = res.x[k, i]
            pts = np.stack([x + L * np.cos(a_w + th), y + L * np.sin(a_w + th)], axis=-1)
            body.set_xy(pts)
            seg = []
            for (px, py), ang in zip(pts, a_w + th):
                d = 0.06 * np.array([-np.sin(ang), np.cos(ang)])
                seg += [[px - d[0], py - d[1]], [px + d[0], py + d[1]], [np.nan, np.nan]]
            seg = np.asarray(seg)
            wheels.set_data(seg[:, 0], seg[:, 1])
            trace.set_data(res.x[:k + 1:thin, i, 0], res.x[:k + 1:thin, i, 1])
            target.set_data([res.x_d[k, 0]], [res.x_d[k, 1]])
            out += [trace, body, wheels, target]
        return out

    return fig, artists, draw


# --- time-domain responses (seactl.simulate.engine)
# -------------------------------------------------
MAX_LEGEND = 12
"""Most curves a response figure labels in a legend."""


def response_figure(t, y, labels, *, title="", ylabel="", current=None, unstable=None):
    """Responses ``y[k, T]`` versus time, one curve per label; with ``current`` (same
    shape, [A]) a second panel shows the motor current. Unstable curves are dashed."""
    plt = pyplot()
    rows = 2 if current is not None else 1
    fig, axes = plt.subplots(rows, 1, figsize=(7.5, 4.2 * rows if rows == 1 else 6.5),
                             sharex=True, squeeze=False)
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(len(labels), 1)))
    unstable = unstable or [False] * len(labels)
    for k, (lab, c) in enumerate(zip(labels, colors)):
        ls = "--" if unstable[k] else "-"
        axes[0, 0].plot(t, y[k], color=c, ls=ls,
                        label=lab + (" (unstable)" if unstable[k] else ""))
        if current is not None:
            axes[1, 0].plot(t, current[k], color=c, ls=ls)
    axes[0, 0].set_ylabel(ylabel)
    axes[0, 0].set_title(title, fontsize=10)
    if len(labels) <= MAX_LEGEND:
        axes[0, 0].legend(fontsize=8)
    else:   # a legend this long would not fit the figure (and tight_layout gives up)
        axes[0, 0].text(0.99, 0.02, f"{len(labels)} curves", transform=axes[0, 0].transAxes,
                        ha="right", va="bottom", fontsize=8)
    if current is not None:
        axes[1, 0].set_ylabel("motor current [A]")
    axes[-1, 0].set_xlabel("time [s]")
    for ax in axes[:, 0]:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def panels_figure(panels, *, ncols=None, figsize=None):
    """Several response panels side by side.  ``panels``: list of dicts with ``title``,
    ``ylabel``, ``curves`` = list of ``(t, y, label, style_kwargs)`` and optional ``xlim``."""
    plt = pyplot()
    n = len(panels)
    ncols = ncols or n
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=figsize or (4.6 * ncols, 3.8 * nrows),
                             squeeze=False)
    for ax, p in zip(axes.flat, panels):
        for t, y, lab, kw in p["curves"]:
            ax.plot(t, y, label=lab, **kw)
        ax.set_title(p.get("title", ""), fontsize=9)
        ax.set_ylabel(p.get("ylabel", ""))
        ax.set_xlabel("time [s]")
        if "xlim" in p:
            ax.set_xlim(*p["xlim"])
        if "ylim" in p:
            ax.set_ylim(*p["ylim"])
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig


def latency_sensitivity_figure(fn_hz, t_qs_ms, t_qd_ms, pm, stable, mark=None):
    """Phase margin over (T_qd, T_qs), one panel per f_n (``pm[k, i_qs, i_qd]``), with the
    stability boundary (red) and an optional marked point ``(T_qs, T_qd)``.

    Axes as in :func:`latency_map_figure`: damping delay across, stiffness delay up."""
    plt = pyplot()
    n = len(fn_hz)
    cols = 2 if n > 1 else 1
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.0 * rows), squeeze=False,
                             sharex=True, sharey=True)
    finite = np.isfinite(pm) & stable
    lo, hi = (np.percentile(pm[finite], [1, 99]) if finite.any() else (0.0, 1.0))
    for k, ax in enumerate(axes.flat):
        if k >= n:
            ax.axis("off")
            continue
        z = np.ma.masked_invalid(np.where(stable[k], pm[k], np.nan))
        mesh = ax.pcolormesh(t_qd_ms, t_qs_ms, z, shading="nearest", cmap="viridis",
                             vmin=max(lo, 0.0), vmax=hi)
        ax.set_facecolor("0.8")
        cs = ax.contour(t_qd_ms, t_qs_ms, np.where(stable[k], pm[k], np.nan),
                        levels=[10, 20, 30, 40], colors="white", linewidths=0.7)
        ax.clabel(cs, fontsize=7, fmt="%g°")
        s = stable[k].astype(float)
        if 0 < s.min() < 1 or (s.min() == 0 < s.max()):
            ax.contour(t_qd_ms, t_qs_ms, s, levels=[0.5], colors="red", linewidths=1.6)
        if mark is not None:
            ax.plot(mark[1], mark[0], "w*", ms=9, mec="k")
        ax.set_title(f"$f_n$ = {fn_hz[k]:g} Hz")
        if k % cols == 0:
            ax.set_ylabel("stiffness delay $T_{qs}$ [ms]")
        if k >= n - cols:
            ax.set_xlabel("damping delay $T_{qd}$ [ms]")
    fig.colorbar(mesh, ax=axes, label="phase margin [deg] (grey: unstable)", shrink=0.85)
    fig.suptitle("SEA phase margin over stiffness and damping latency (red: stability "
                 "boundary)")
    return fig


FIGURE_FORMATS = ("png", "svg", "pdf")


def save_figure(fig, path, dpi: int = 120) -> None:
    """Write ``fig`` to ``path`` atomically (temporary sibling + rename) and close it; the
    format follows the suffix (png, svg or pdf)."""
    from pathlib import Path

    from seactl.base.outputs import save_figure_to, write_atomic_with
    from seactl.errors import InputError

    path = Path(path)
    fmt = path.suffix[1:].lower()
    if fmt not in FIGURE_FORMATS:
        pyplot().close(fig)
        raise InputError("--plot", str(path), "a file name ending in ." +
                         ", .".join(FIGURE_FORMATS))
    write_atomic_with(path, lambda tmp: save_figure_to(fig, tmp, fmt, dpi))


def jitter_figure(fn_hz, margins_ms: dict, delay_margin_ms, factors, fractions: dict,
                  title: str = ""):
    """Left: jitter margins [ms] of each loop and the whole-loop delay margin against f_n.
    Right: fraction of Monte Carlo runs that stay stable against the jitter range, in
    multiples of each link's jitter margin (the bound guarantees 100 % up to 1)."""
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(11.0, 4.0), layout="constrained")
    colors = dict(zip(["overall", "stiffness", "damping", "torque"],
                      ["tab:blue", "tab:orange", "tab:green", "tab:red"]))
    for name, v in margins_ms.items():
        a.plot(fn_hz, v, "o-", ms=3, color=colors.get(name), label=f"{name} loop")
    a.plot(fn_hz, delay_margin_ms, "k--", label="delay margin (constant), outer loop")
    a.set_yscale("log")
    a.set_xlabel("f_n [Hz]")
    a.set_ylabel("margin [ms]")
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)
    for name, fr in fractions.items():
        b.plot(factors, 100 * np.asarray(fr), "o-", color=colors.get(name),
               label=f"{name} link")
    b.axvline(1.0, color="k", lw=0.8, ls=":")
    b.set_xlabel("latency range above nominal / jitter margin")
    b.set_ylabel("stable runs [%]")
    b.set_ylim(-5, 105)
    b.grid(True, alpha=0.3)
    b.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig
