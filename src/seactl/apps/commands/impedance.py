"""``seactl impedance`` and ``seactl zregion``: SEA impedance, passivity and the Z-region."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.base.limits import FREQ_BYTES_PER_POINT, check_budget, check_range
from seactl.base.outputs import CSV_SUFFIXES, FIGURE_SUFFIXES, OutputSet
from seactl.errors import InputError

from .common import (
    IMPEDANCE_SERIES,
    VARIADIC,
    DesignSpec,
    cli,
    console,
    design_options,
    echo_json,
    finite_or_none,
    full_option,
    json_option,
    parse_values,
    series_json,
)
from .loops import loop_impedance, loop_options

VARIADIC.add("--freq")

def _freq(tokens: tuple[str, ...]) -> np.ndarray:
    f = parse_values("--freq", tokens, log=True)
    if f.size == 0:
        raise InputError("--freq", "", "at least one frequency [Hz]")
    bad = ~np.isfinite(f) | (f <= 0)
    if bad.any():
        raise InputError("--freq [Hz]", float(f[bad][0]), "finite frequencies > 0")
    for x in (f.min(), f.max()):
        check_range("--freq [Hz]", x, "freq_hz")
    return f


def _budget(spec: DesignSpec, f: np.ndarray) -> np.ndarray:
    n = spec.fn_hz.size * spec.gs.size
    check_budget(f"{n:,} design(s) at {f.size:,} frequencies",
                 n_bytes=n * f.size * FREQ_BYTES_PER_POINT,
                 hint="give fewer --freq points or fewer designs")
    return f


def _csv_text(header: list[str], rows: list[list[Any]]) -> str:
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    for r in rows:
        buf.write(",".join(f"{x:.10g}" if isinstance(x, float) else str(x) for x in r) + "\n")
    return buf.getvalue()


def _outputs(outs: OutputSet, plot: str | None, csv: str | None) -> tuple[Path | None, ...]:
    return outs.add("--plot", plot, FIGURE_SUFFIXES), outs.add("--csv", csv, CSV_SUFFIXES)


_MODEL = click.option("--model", type=click.Choice(["block-diagram", "paper"]),
                      default="block-diagram", show_default=True,
                      help="block-diagram (derived from the loop) or paper (printed N_zi/D_zi, "
                           "with k_tau where the paper prints it).")
_LOAD = click.option("--load", is_flag=True,
                     help="Add the joint inertia and damping: Z_l = Z + I_j s + b_j.")
_PLOT = click.option("--plot", "plot", default=None, metavar="FILE.png|.svg",
                     help="Write a Bode plot (magnitude and phase) to this file.")
_CSV = click.option("--csv", "csv", default=None, metavar="FILE", help="Write values as CSV.")
_UNITS = click.option("--units", type=click.Choice(["rotary", "linear"]), default="rotary",
                      show_default=True,
                      help="rotary: N m s/rad; linear: N s/m (divided by the pulley radius^2).")


def _timing_text(spec: DesignSpec) -> str:
    filt = ", ".join(f"{n}={v:g} Hz" for n, v in (("f_qd", spec.f_qd_hz),
                                                  ("f_taud", spec.f_taud_hz)) if v)
    return (f"T_tau={spec.t_tau_ms:g} ms, T_qs={spec.t_qs_ms:g} ms, T_qd={spec.t_qd_ms:g} ms, "
            + (filt or "no filters"))


@cli.command()
@design_options
@click.option("--freq", "freq", multiple=True, default=("0.1:1000:401",), show_default=True,
              help="Frequencies [Hz]: values, or START:STOP:N log-spaced points.")
@_MODEL
@_LOAD
@_UNITS
@_PLOT
@_CSV
@json_option
@full_option
@click.option("--port", default=None, help="Impedance port of the --loop file (default: its "
              "first).")
@loop_options
def impedance(spec: DesignSpec, freq: tuple[str, ...], model: str, load: bool, units: str,
              plot: str | None, csv: str | None, as_json: bool, port: str | None,
              loop: Any) -> None:
    """SEA impedance Z(jw) = tau_j / (-jw q_j) with exact delays and filters.

    Python: sc.design(...).impedance(f_hz, model=..., load=..., units=...); --loop:
    sc.load_loop(...).impedance(f_hz, port).

    Reports the low-frequency virtual stiffness, the high-frequency asymptote, stability
    and the bands where Re Z < 0 (non-passive: the actuator can inject energy into its
    environment), scanned densely over the --freq range with exact band edges; "passive"
    is proven between the scan's points ("not proven" where Re Z touches 0).

    \b
    Example:
      seactl impedance --fn 30 --t-tau 1 --t-qs 10 --t-qd 3 --plot z.png
    """
    if loop is None and port is not None:
        raise InputError("--port", port, "used with --loop FILE")
    with OutputSet() as outs:
        if loop is not None:
            return loop_impedance(loop, _freq(freq), port, as_json, outs,
                                  *_outputs(outs, plot, csv))
        f = _budget(spec, _freq(freq))
        plot_p, csv_p = _outputs(outs, plot, csv)
        if loop is not None:
            return loop_impedance(loop, f, port, as_json, outs, plot_p, csv_p)
        if port is not None:
            raise InputError("--port", port, "used with --loop FILE")
        _impedance(spec, f, model, load, units, plot_p, csv_p, outs, as_json)


def _impedance(spec: DesignSpec, f: np.ndarray, model: str, load: bool, units: str,
               plot: Path | None, csv: Path | None, outs: OutputSet, as_json: bool) -> None:
    from seactl.systems.sea.asymptotes import asymptote_case, asymptotes, low_frequency_stiffness
    from seactl.systems.sea.impedance import UNITS
    from seactl.systems.sea.passivity import passivity, scan_range

    d = spec.designs()
    resp = d.impedance(f, model=model, load=load, units=units)
    stable = d.margins().stable
    # no public view gives the asymptotes, the passivity proof or the low-frequency
    # stiffness (a Design.passivity() is wanted): the impedance module's functions
    designs = d.sea
    asym = asymptotes(designs, f, model=model, load=load, units=units)
    pas = passivity(designs, scan_range(f), model=model, load=load)
    k_low = np.broadcast_to(low_frequency_stiffness(designs, model), designs.shape)
    case = np.broadcast_to(asymptote_case(designs), designs.shape)
    unit = UNITS[units]
    scale = 1.0 if units == "rotary" else spec.actuator.pulley_radius ** -2
    g = designs.gains
    mag, mag_db, phase = resp.magnitude, resp.magnitude_db, resp.phase_deg  # (once: whole arrays)
    out: list[dict[str, Any]] = []
    for i, fn in enumerate(spec.fn_hz):
        for j, gs in enumerate(spec.gs):
            idx = (i, j)
            bands = pas.bands_hz[idx]
            out.append({
                "model": model, "units": units, "unit": unit, "load": load,
                "fn_hz": float(fn), "gs": float(gs),
                "gains": {k: float(np.broadcast_to(getattr(g, k), designs.shape)[idx])
                          for k in ("Kq", "Bq", "Ktau", "Btau")},
                "stable": bool(stable[idx]),
                "low_frequency_stiffness": float(k_low[idx]) * scale,
                "high_frequency_case": "load" if load else str(case[idx]),
                "f_hz": [float(x) for x in f],
                "magnitude": [finite_or_none(x) for x in mag[idx]],
                "magnitude_db": [finite_or_none(x) for x in mag_db[idx]],
                "phase_deg": [finite_or_none(x) for x in phase[idx]],
                "passive": bool(pas.passive[idx]),
                "passivity_proven": bool(pas.proven[idx]),
                "non_passive_bands_hz": [[float(a), float(b)] for a, b in bands],
                "passivity_range_hz": list(pas.f_range_hz),
            })
    if csv:
        outs.write(csv, _impedance_csv(out, f, resp.z.reshape(len(out), f.size), unit))
    if plot:
        outs.figure(plot, _impedance_plot(spec, designs, resp, asym, model, load, unit))
    outs.commit()
    if as_json:
        echo_json(series_json(out[0] if len(out) == 1 else out, IMPEDANCE_SERIES))
        return
    _print_impedance(spec, out, f, resp, asym, pas, model, load, unit)


def _passive_text(r: dict[str, Any]) -> str:
    """The table's passivity cell: proven yes/no, the paper model's scan-only yes, or not
    proven (Re Z touching 0)."""
    if r["passive"]:
        return "yes" if r["passivity_proven"] else "yes (scan only)"
    return "[yellow]no[/yellow]" if r["passivity_proven"] else "[yellow]not proven[/yellow]"


def _impedance_csv(out: list[dict[str, Any]], f: np.ndarray, zf: np.ndarray, unit: str) -> str:
    """One row per design and frequency: |Z|, dB, phase, real and imaginary parts."""
    rows = []
    for n, r in enumerate(out):
        for k, fk in enumerate(f):
            zk = zf[n, k]
            rows.append([r["fn_hz"], r["gs"], float(fk), float(abs(zk)),
                         float(20 * np.log10(abs(zk))), float(r["phase_deg"][k]),
                         float(zk.real), float(zk.imag)])
    return _csv_text(["fn_hz", "gs", "f_hz", f"magnitude [{unit}]", "magnitude_db",
                      "phase_deg", f"re [{unit}]", f"im [{unit}]"], rows)


def _print_impedance(spec: DesignSpec, out: list[dict[str, Any]], f: np.ndarray, resp: Any,
                     asym: Any, pas: Any, model: str, load: bool, unit: str) -> None:
    """The summary table (one row per design) and, for one design, Z at each frequency."""
    from seactl.systems.sea.zregion import excess_over_asymptotes_db

    t = Table(title=f"SEA impedance, model '{model}'{' with load' if load else ''}, actuator "
              f"'{spec.actuator.name}' ({_timing_text(spec)}); passivity scanned over "
              f"{pas.f_range_hz[0]:g}-{pas.f_range_hz[1]:g} Hz")
    for col in ("f_n [Hz]", "GS", "K low [Nm/rad]", "high-freq case",
                "max |Z| over asymptotes [dB]", "at [Hz]", "stable", "passive",
                "non-passive bands [Hz]"):
        t.add_column(escape(col), justify="right" if col != "non-passive bands [Hz]" else "left")
    excess = excess_over_asymptotes_db(resp, asym).reshape(-1, f.size)
    for n, r in enumerate(out):
        db = excess[n]
        kmax = int(np.argmax(db))
        bands = r["non_passive_bands_hz"]
        btxt = ", ".join(f"{a:.4g}-{b:.4g}" for a, b in bands[:4]) + (
            f" (+{len(bands) - 4} more)" if len(bands) > 4 else "")
        t.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", f"{r['low_frequency_stiffness']:.4g}",
                  r["high_frequency_case"], f"{db[kmax]:.2f}", f"{f[kmax]:.4g}",
                  "yes" if r["stable"] else "[red]NO[/red]",
                  _passive_text(r), btxt or "none")
    console.print(t)
    console.print(f"|Z| in dB re 1 {unit}; the impedance of an unstable design is not "
                  "physically meaningful." if not all(r["stable"] for r in out) else
                  f"|Z| in dB re 1 {unit}.")
    if len(out) == 1 and f.size <= 30:
        v = Table(title="Z(j 2 pi f)")
        for col in ("f [Hz]", f"|Z| [{unit}]", "|Z| [dB]", "phase [deg]", f"Re Z [{unit}]"):
            v.add_column(escape(col), justify="right")
        for k, fk in enumerate(f):
            v.add_row(f"{fk:.4g}", f"{resp.magnitude.flat[k]:.5g}",
                      f"{resp.magnitude_db.flat[k]:.2f}", f"{resp.phase_deg.flat[k]:.2f}",
                      f"{resp.z.flat[k].real:.4g}")
        console.print(v)


def _impedance_plot(spec: DesignSpec, designs: Any, resp: Any, asym: Any, model: str,
                    load: bool, unit: str):
    import matplotlib.pyplot as plt

    from seactl.apps.plots import impedance_bode_figure

    f = resp.f_hz
    n = int(np.prod(designs.shape))
    colors = plt.cm.viridis(np.linspace(0, 0.85, n)) if n > 1 else ["tab:red"]
    z = resp.z.reshape(n, f.size)
    lo = asym.low.reshape(n, f.size)
    hi = asym.high.reshape(n, f.size)
    curves = []
    labels = [f"f_n={fn:g} Hz, GS={gs:g}" for fn in spec.fn_hz for gs in spec.gs]
    for k in range(n):
        lbl = labels[k] if n > 1 else ("Z_l" if load else "Z")
        curves.append(dict(f=f, z=z[k], label=lbl, color=colors[k]))
    for k in range(n):
        curves.append(dict(f=f, z=lo[k], dashed=True, color=colors[k] if n > 1 else "tab:blue",
                           label="low-freq. asymptote K/(jw)" if k == 0 else None))
        curves.append(dict(f=f, z=hi[k], dashed=True, color=colors[k] if n > 1 else "tab:green",
                           label=("high-freq. asymptote I_j jw + b_j" if load else
                                  "high-freq. asymptote") if k == 0 else None))
    r2 = 1.0 if unit == "N m s/rad" else spec.actuator.pulley_radius ** 2
    spring = spec.actuator.k / (2j * np.pi * f) / r2
    curves.append(dict(f=f, z=spring, dashed=True, color="goldenrod", label="spring k/(jw)"))
    title = (f"SEA impedance ({model} model{', with load' if load else ''}), "
             f"{_timing_text(spec)}")
    if n == 1:
        g = designs.gains
        title += (f"\nf_n={spec.fn_hz[0]:g} Hz, GS={spec.gs[0]:g}: Kq={float(g.Kq.flat[0]):.4g},"
                  f" Bq={float(g.Bq.flat[0]):.4g}, Ktau={float(g.Ktau.flat[0]):.4g}, "
                  f"Btau={float(g.Btau.flat[0]):.4g}")
    return impedance_bode_figure([("", curves)], suptitle=title, unit=unit, col_width=8.5)


@cli.command()
@design_options
@click.option("--freq", "freq", multiple=True, default=("0.1:1000:201",), show_default=True,
              help="Frequencies [Hz]: values, or START:STOP:N log-spaced points.")
@_MODEL
@_LOAD
@click.option("--min-pm", type=float, default=30.0, show_default=True,
              help="Admissible designs: stable with at least this phase margin [deg].")
@click.option("--passive", "require_passive", is_flag=True,
              help="Admissible designs must also be passive (Re Z >= 0) over --freq's range.")
@click.option("--threshold-db", type=float, default=6.0, show_default=True,
              help="Z-depth: frequency range over which the Z-width stays >= this [dB].")
@_PLOT
@_CSV
@json_option
@full_option
def zregion(spec: DesignSpec, freq: tuple[str, ...], model: str, load: bool, min_pm: float,
            require_passive: bool, threshold_db: float, plot: str | None, csv: str | None,
            as_json: bool) -> None:
    """Z-region of an f_n x GS design range: Z-width (admissible |Z| range per frequency)
    and Z-depth (frequency range where the width stays above a threshold).

    Python: seactl.systems.sea.zregion.zregion(sc.design(...).sea, f_hz) (no method of sc.Design).

    Definition (this project's; the original is not public): docs/zregion.md.

    \b
    Example:
      seactl zregion --fn 10:40:2 --gs 0.5:2:0.1 --t-tau 0.5 --t-qs 2 --t-qd 0.5 \\
                     --f-qd 50 --f-taud 100 --plot zregion.png
    """
    with OutputSet() as outs:
        plot_p, csv_p = _outputs(outs, plot, csv)
        _zregion(spec, _budget(spec, _freq(freq)), model, load, min_pm, require_passive,
                 threshold_db, plot_p, csv_p, outs, as_json)


ZREGION_SERIES = ("f_hz", "z_min", "z_max", "width_db", "z_min_design", "z_max_design")
"""The long arrays of the Z-region's JSON, one value per frequency."""


def _zregion(spec: DesignSpec, f: np.ndarray, model: str, load: bool, min_pm: float,
             require_passive: bool, threshold_db: float, plot: Path | None,
             csv: Path | None, outs: OutputSet, as_json: bool) -> None:
    from seactl.systems.sea.impedance import UNITS
    from seactl.systems.sea.zregion import zregion as compute

    # no public Z-region view (sc has none): the impedance module's function
    designs = spec.designs().sea
    reg = compute(designs, f, min_pm_deg=min_pm, require_passive=require_passive,
                  threshold_db=threshold_db, model=model, load=load)
    unit = UNITS["rotary"]
    fn_flat = np.repeat(spec.fn_hz, len(spec.gs))
    gs_flat = np.tile(spec.gs, len(spec.fn_hz))
    out = {
        "model": model, "unit": unit, "load": load, "min_pm_deg": min_pm,
        "require_passive": require_passive, "threshold_db": threshold_db,
        "n_designs": int(reg.admissible.size), "n_admissible": reg.n_admissible,
        "depth_hz": list(reg.depth_hz) if reg.depth_hz else None,
        "depth_decades": reg.depth_decades,
        "f_hz": [float(x) for x in f],
        "z_min": [float(x) for x in reg.z_min], "z_max": [float(x) for x in reg.z_max],
        "width_db": [float(x) for x in reg.width_db],
        "z_min_design": [{"fn_hz": float(fn_flat[i]), "gs": float(gs_flat[i])}
                         for i in reg.argmin],
        "z_max_design": [{"fn_hz": float(fn_flat[i]), "gs": float(gs_flat[i])}
                         for i in reg.argmax],
        "designs": [{"fn_hz": float(fn), "gs": float(gs),
                     "phase_margin_deg": finite_or_none(reg.phase_margin_deg[i, j]),
                     "stable": bool(reg.stable[i, j]), "passive": bool(reg.passive[i, j]),
                     "admissible": bool(reg.admissible[i, j])}
                    for i, fn in enumerate(spec.fn_hz) for j, gs in enumerate(spec.gs)],
    }
    if csv:
        rows = [[float(fk), float(reg.z_min[k]), float(reg.z_max[k]), float(reg.width_db[k])]
                for k, fk in enumerate(f)]
        outs.write(csv, _csv_text(["f_hz", f"z_min [{unit}]", f"z_max [{unit}]", "width_db"],
                                  rows))
    if plot:
        from seactl.apps.plots import zregion_figure

        fig = zregion_figure(reg, spec.fn_hz, spec.gs, spring=spec.actuator.k / (2j * np.pi * f))
        fig.suptitle(f"Z-region, {_timing_text(spec)}", fontsize=10, y=1.02)
        outs.figure(plot, fig)
    outs.commit()
    if as_json:
        echo_json(series_json(out, ZREGION_SERIES))
        return
    depth = (f"{reg.depth_hz[0]:.4g} - {reg.depth_hz[1]:.4g} Hz ({reg.depth_decades:.3f} "
             f"decades)" if reg.depth_hz else f"empty (width < {threshold_db:g} dB at "
             f"{f.min():g} Hz)")
    console.print(f"Z-region ({model} model{', with load' if load else ''}; "
                  f"{_timing_text(spec)})")
    console.print(f"admissible designs: {reg.n_admissible} of {reg.admissible.size} "
                  f"(stable, PM >= {min_pm:g} deg{', passive' if require_passive else ''})")
    console.print(f"Z-depth (width >= {threshold_db:g} dB): {depth}")
    t = Table(title="Z-width at selected frequencies")
    for col in ("f [Hz]", f"min |Z| [{unit}]", f"max |Z| [{unit}]", "Z-width [dB]"):
        t.add_column(escape(col), justify="right")
    sel = np.unique(np.linspace(0, f.size - 1, min(f.size, 11)).round().astype(int))
    for k in sel:
        t.add_row(f"{f[k]:.4g}", f"{reg.z_min[k]:.4g}", f"{reg.z_max[k]:.4g}",
                  f"{reg.width_db[k]:.2f}")
    console.print(t)
