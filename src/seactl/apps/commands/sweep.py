"""``seactl sweep`` (design-space sweeps on local cores or a Dask cluster) and
``seactl robust`` (Monte Carlo over actuator parameter uncertainty)."""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path
from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.base import progress
from seactl.base.axes import ACTUATOR_AXES, AXES, DESIGN_AXES, SAMPLINGS
from seactl.base.outputs import FIGURE_SUFFIXES, OutputSet
from seactl.errors import InputError, ResourceError

from .common import (
    VARIADIC,
    axis_option,
    cli,
    console,
    echo_json,
    err_console,
    finite_or_none,
    parse_values,
)

VARIADIC.add("--z-freq")

_FILTERS = ("f_qd_hz", "f_taud_hz")

LARGE_SWEEP_POINTS = 1e8
"""Sweeps above this many points run only with ``--yes``."""
POINTS_PER_CORE_S = 20_000.0
"""Sweep throughput per core used for the estimate (the default design options)."""
PARQUET_BYTES_PER_POINT = 60.0
"""Dataset size per point used for the estimate (Parquet, the default columns)."""
LOOP_POINTS_PER_S = 3000.0
"""Loop-sweep throughput used for the estimate (in process; the rigid example's loop, one
of the fastest: an estimate on the short side)."""


def parse_axis(actuator: Any, name: str, tokens: tuple[str, ...], *, sampling: str,
               unc_points: int) -> tuple[float, ...] | None:
    """Values of axis ``name`` from CLI tokens: numbers, ``START:STOP:STEP`` ranges,
    comma lists; ``P%`` (actuator axes) = nominal +/- P% (``unc_points`` values on a
    grid, the interval otherwise); ``none`` (filters) = no filter."""
    if not tokens:
        return None
    info = AXES[name]
    out: list[float] = []
    for tok in tokens:
        for part in str(tok).replace(",", " ").split():
            if part.endswith("%"):
                if name not in ACTUATOR_AXES:
                    raise InputError(info.option, part, "numbers or START:STOP:STEP (a "
                                     "relative P% applies to actuator parameters only)")
                try:
                    pct = float(part[:-1])
                except ValueError:
                    raise InputError(info.option, part, "P% with a number P") from None
                from seactl.sweep.robustness import relative_interval

                lo, hi = relative_interval(actuator, name, pct)
                if pct == 0:
                    out.append(lo)
                elif sampling == "grid":
                    out.extend(np.linspace(lo, hi, unc_points))
                else:
                    out.extend((lo, hi))
            elif name in _FILTERS and part.lower() in ("none", "inf"):
                out.append(math.inf)
            else:
                out.extend(parse_values(info.option, [part]))
    return tuple(out)


def _axis_options(func):
    for name, info in reversed(AXES.items()):
        unit = f" [{info.unit}]" if info.unit else ""
        extra = {"f_qd_hz": " 'none': no filter.", "f_taud_hz": " 'none': no filter."}.get(
            name, " Or P% (+/- around the actuator's value)." if name in ACTUATOR_AXES else "")
        default = ("actuator's" if info.default is None else
                   "none" if math.isinf(info.default) else f"{info.default:g}")
        func = click.option(info.option, name, multiple=True,
                            help=f"{info.description}{unit}: values, START:STOP:STEP or "
                                 f"a,b,c.{extra} Default: {default}.")(func)
    return func


def _spec_from_options(opts: dict[str, Any], *, actuator: str, sampling: str, n_samples: int,
                       seed: int, chunk_size: int, unc_points: int, z_freq: tuple[str, ...]):
    from seactl.sweep.spec import SweepSpec
    from seactl.systems.sea.actuators import load_sea

    act = load_sea(actuator)
    axes = []
    for name in AXES:
        vals = parse_axis(act, name, opts.get(name, ()), sampling=sampling,
                          unc_points=unc_points)
        if vals is not None:
            axes.append((name, vals))
    zf = tuple(parse_values("--z-freq", z_freq)) if z_freq else ()
    return SweepSpec(act, tuple(axes), sampling=sampling, n_samples=n_samples or 0, seed=seed,
                     chunk_size=chunk_size, z_freqs_hz=zf)


@cli.command()
@_axis_options
@click.option("--actuator", default="ut-sea", show_default=True,
              help="Nominal SEA (preset or TOML): gains are designed for it.")
@click.option("--sample", "sampling", type=click.Choice(SAMPLINGS), default="grid",
              show_default=True, help="Cartesian grid, or uniform random / Latin-hypercube "
              "samples over the intervals the axes span.")
@click.option("--n", "n_samples", type=int, default=None,
              help="Number of points for --sample random/lhs.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Sampling seed (an integer >= 0).")
@click.option("--chunk-size", type=int, default=5_000, show_default=True,
              help="Points per chunk (one Parquet file each; about 5 kB per point at peak).")
@click.option("--unc-points", type=click.IntRange(2, 101), default=3, show_default=True,
              help="Grid values per P% actuator uncertainty.")
@click.option("--z-freq", multiple=True,
              help="Also report |Z| [N m s/rad] at these frequencies [Hz].")
@click.option("--out", required=True, type=click.Path(),
              help="Output directory (Parquet dataset: part-*.parquet, _manifest.json, "
                   "_summary.json).")
@click.option("--resume", is_flag=True, help="Complete an interrupted sweep of the same spec.")
@click.option("--overwrite", is_flag=True, help="Replace an existing sweep in --out.")
@click.option("--workers", type=int, default=None,
              help="Local worker processes (default: all cores; 0: in this process).")
@click.option("--scheduler", default=None,
              help="Run on an existing Dask cluster: scheduler address tcp://HOST:PORT.")
@click.option("--plot", "plot_axes", default=None, metavar="X,Y",
              help="Draw a heatmap of --plot-z over two swept axes (column names, e.g. "
                   "fn_hz,t_qs_ms).")
@click.option("--plot-z", default="phase_margin_deg", show_default=True,
              help="Output column to plot.")
@click.option("--plot-reduce", type=click.Choice(["min", "max", "mean"]), default="min",
              show_default=True, help="Reduction over the other swept axes.")
@click.option("--plot-file", default=None, metavar="FILE.png|.svg|.pdf",
              help="Figure file (default: OUT/_plot-Z-X-Y.png).")
@click.option("--yes", is_flag=True,
              help=f"Run a sweep of more than {LARGE_SWEEP_POINTS:.0e} points.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--loop", "loop_file", default=None, metavar="FILE.toml",
              type=click.Path(dir_okay=False),
              help="Sweep a loop file (docs/loops.md) over its variables given with --set.")
@click.option("--set", "sets", multiple=True, metavar="NAME=VALUES",
              help="With --loop: a variable and its values (number, a,b,c or "
                   "START:STOP:STEP); every combination is a point.")
def sweep(actuator, sampling, n_samples, seed, chunk_size, unc_points, z_freq, out, resume,
          overwrite, workers, scheduler, plot_axes, plot_z, plot_reduce, plot_file, yes, quiet,
          as_json, loop_file, sets, **axes) -> None:
    """Sweep the design space: gains, margins (and |Z|) for every point, as Parquet.

    Python: sc.sweep(...).

    \b
    Any design option takes values, START:STOP:STEP ranges or comma lists; actuator
    parameters (--im --ij --bm --bj --k --beta, rotary SI) also take P% for the
    nominal value +/- P%. Gains are designed for the nominal actuator and the
    loop is evaluated on the perturbed plant. Points without a critically-damped
    gain set are reported as infeasible rows.

    \b
    Examples:
      seactl sweep --fn 10:40:0.25 --gs 0.3:3:0.05 --t-qs 0:20:0.5 --t-qd 0.5 --out sweep.parquet
      seactl sweep ... --out sweep.parquet --resume          # after Ctrl-C: missing chunks only
      seactl sweep ... --scheduler tcp://10.0.0.5:8786       # on a Dask cluster
      seactl sweep --fn 14 --ij 20% --bm 20% --k 20% --sample lhs --n 100000 --out mc.parquet

    Runs on local worker processes (all cores) unless --workers or --scheduler
    say otherwise; Dask schedules the chunks and retries failed ones.
    """
    if loop_file is not None or sets:
        return _loop_sweep(loop_file, sets, out, chunk_size, overwrite, as_json, sampling,
                           n_samples, seed, yes)
    if sampling != "grid" and n_samples is None:
        raise InputError("--n", None, f"given with --sample {sampling} (number of points)")
    if not out.strip():
        raise InputError("--out", out, "a directory path")
    if resume and overwrite:
        raise InputError("--overwrite", "with --resume", "used alone (--resume completes a "
                         "sweep, --overwrite restarts it: choose one)")
    spec = _spec_from_options(axes, actuator=actuator, sampling=sampling,
                              n_samples=n_samples or 0, seed=seed, chunk_size=chunk_size,
                              unc_points=unc_points, z_freq=z_freq)
    plot_xy = _parse_plot_axes(plot_axes, spec) if plot_axes else None
    _check_size(spec, yes)
    from seactl.base.limits import BYTES_PER_DESIGN, check_budget

    check_budget(f"a chunk of {spec.chunk_size:,} points per worker",
                 n_bytes=spec.chunk_size * BYTES_PER_DESIGN * (os.cpu_count() or 1)
                 if workers != 0 else spec.chunk_size * BYTES_PER_DESIGN,
                 hint="lower --chunk-size")
    with OutputSet() as outs:
        fig_file = outs.add("--plot-file", plot_file, FIGURE_SUFFIXES)
        res = _run(spec, out, resume, overwrite, workers, scheduler, quiet)
        fig_path = None
        if plot_xy:
            fig_path = _plot(Path(out), plot_xy, plot_z, plot_reduce, outs, fig_file)
    s = res.summary
    if as_json:
        echo_json({**s, "out": str(out), "figure": fig_path,
                   "points_per_s": finite_or_none(res.points_per_s)})
        return
    t = Table(title=f"sweep {escape(str(out))} (spec {res.spec_hash[:12]})")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    for k, name in (("n_points", "points"), ("feasible", "feasible [points]"),
                    ("infeasible", "infeasible [points]"), ("stable", "stable [points]"),
                    ("unstable", "unstable [points]")):
        t.add_row(escape(name), f"{s[k]:,}")
    for k, v in (s["phase_margin_deg_stable"] or {}).items():
        t.add_row(escape(f"PM of stable designs, {k} [deg]"), f"{v:.3f}")
    run = s["run"]
    t.add_row("chunks computed this run", f"{run['chunks_computed']} of {res.n_chunks}")
    t.add_row(escape("wall time [s]"), f"{run['seconds']:.2f}")
    if res.points_computed:
        t.add_row(escape("throughput [points/s]"), f"{res.points_per_s:,.0f}")
        t.add_row(escape("workers [processes]"),
                  "in process" if not run["workers"] else str(run["workers"]))
        t.add_row(escape("peak RSS per worker [MB]"), f"{run['worker_peak_rss_mb']:.0f}")
        if run["workers"]:   # (in process, the chunks are this process's CPU time)
            t.add_row(escape("CPU time: workers / this process [s]"),
                      f"{run['worker_cpu_seconds']:.2f} / {run['parent_cpu_seconds']:.2f}")
    console.print(t)
    if s["best_phase_margin"]:
        best = ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                         for k, v in s["best_phase_margin"].items())
        console.print(f"largest phase margin among stable designs: {escape(best)}")
    if fig_path:
        console.print(f"figure: {escape(fig_path)}")


def _check_size(spec, yes: bool) -> None:
    check_points(spec.n_points, yes)


def check_points(n: float, yes: bool, points_per_s: float | None = None) -> None:
    """Refuse a sweep of more than :data:`LARGE_SWEEP_POINTS` points without ``--yes``,
    with its estimated time (on every core, or in this process at ``points_per_s``) and
    dataset size."""
    if n <= LARGE_SWEEP_POINTS or yes:
        return
    from seactl.base.limits import human_bytes, human_seconds

    cores = os.cpu_count() or 1
    where = (f"{human_seconds(n / (POINTS_PER_CORE_S * cores))} on {cores} cores"
             if points_per_s is None else f"{human_seconds(n / points_per_s)} in this process")
    raise ResourceError(f"the sweep has {n:.3g} points (more than {LARGE_SWEEP_POINTS:.0e}): "
                        f"about {where} and {human_bytes(n * PARQUET_BYTES_PER_POINT)} of "
                        "Parquet; add --yes to run it")


def _run(spec, out: str, resume: bool, overwrite: bool, workers, scheduler, quiet: bool):
    from seactl.sweep.engine import SweepInterrupted, run_sweep

    try:  # errors naming out, scheduler, ... read as flags (commands.common._Command)
        with progress.reporting("off") if quiet else contextlib.nullcontext():
            return run_sweep(spec, Path(out), resume=resume, overwrite=overwrite,
                             workers=workers, scheduler=scheduler)
    except SweepInterrupted as exc:
        err_console.print(f"[yellow]{escape(str(exc))}[/yellow]", highlight=False,
                          soft_wrap=True)
        raise click.exceptions.Exit(143 if exc.terminated else 130) from None


LOOP_SWEEP_OPTIONS = frozenset({"loop_file", "sets", "sampling", "n_samples", "seed",
                                "chunk_size", "out", "overwrite", "yes", "quiet", "as_json"})
"""The options of ``sweep`` that apply with ``--loop`` (it runs in this process, without
progress bar, impedance columns, plots or resumption): the others are refused."""


def _given(name: str) -> bool:
    """Whether the user gave option ``name`` (not its default)."""
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source(name) in (
        ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT)


def _refuse_built_in_options() -> None:
    ctx = click.get_current_context()
    for p in ctx.command.params:
        if p.name not in LOOP_SWEEP_OPTIONS and _given(p.name):
            raise InputError(max(p.opts, key=len), "given", "absent with --loop (a loop "
                             "sweep runs in this process over the file's variables given "
                             "with --set; it has no " + ("plots" if "plot" in p.name else
                                                         "such option") + ")")


def _loop_sweep(loop_file, sets, out, chunk_size, overwrite, as_json, sampling, n_samples,
                seed, yes) -> None:
    """``seactl sweep --loop FILE --set ...``: in-process, one vectorized batch per chunk."""
    from seactl.api.loopbuilder import load_loop
    from seactl.base.limits import BYTES_PER_DESIGN, check_budget
    from seactl.sweep.loops import LoopPoints, sweep_loop

    from .loops import parse_sets

    if loop_file is None:
        raise InputError("--set", sets[0], "used with --loop FILE")
    _refuse_built_in_options()
    if sampling != "grid" and n_samples is None:
        raise InputError("--n", None, f"given with --sample {sampling} (number of points)")
    if sampling == "grid" and (n_samples is not None or _given("seed")):
        raise InputError("--n" if n_samples is not None else "--seed", "given", "absent with "
                         "--sample grid (every combination of the --set values is a point)")
    if not out.strip():
        raise InputError("--out", out, "a directory path")
    values = parse_sets(sets)
    points = LoopPoints(values, sampling, n_samples or 0, seed)
    check_points(points.n_points, yes, LOOP_POINTS_PER_S)
    check_budget(f"a chunk of {chunk_size:,} points", n_bytes=chunk_size * BYTES_PER_DESIGN,
                 hint="lower --chunk-size")
    loop = load_loop(loop_file)
    res = sweep_loop(loop, values, out, chunk_size=chunk_size, overwrite=overwrite,
                     sampling=sampling, n_samples=n_samples or 0, seed=seed)
    if as_json:
        echo_json({**res, "out": str(out)})
        return
    console.print(escape(f"loop sweep of '{res['loop']}': {res['n_points']:,} points, "
                         f"{res['stable']:,} stable, {res['points_per_s'] or 0:,.0f} points/s "
                         f"-> {out}"), highlight=False)
    if res["best_phase_margin"]:
        console.print(escape("largest outer phase margin among stable points: " + ", ".join(
            f"{k}={v:.6g}" for k, v in res["best_phase_margin"].items())), highlight=False)


def _parse_plot_axes(text: str, spec) -> tuple[str, str]:
    parts = [p.strip() for p in text.split(",") if p.strip()]
    swept = [n for n, _ in spec.swept]
    if len(parts) != 2:
        raise InputError("--plot", text, "two swept axes X,Y (of: " + ", ".join(swept) + ")")
    for p in parts:
        if p not in swept:
            raise InputError("--plot", p, "a swept axis (one of: " + (", ".join(swept) or
                             "none: sweep at least two axes") + ")")
    return parts[0], parts[1]


def _plot(out: Path, xy: tuple[str, str], z: str, reduce: str, outs: OutputSet,
          plot_file: Path | None) -> str:
    from seactl.apps.plots import save_figure, sweep_map_figure
    from seactl.sweep.maps import sweep_map

    m = sweep_map(out, xy[0], xy[1], z, reduce)
    fig = sweep_map_figure(m)
    if plot_file is None:
        path = out / f"_plot-{z}-{xy[0]}-{xy[1]}.png"
        save_figure(fig, path)
        return str(path)
    outs.figure(plot_file, fig)
    outs.commit()
    return str(plot_file)


# ------------------------------------------------------------------ robust
def _robust_options(func):
    """One design (single values of the design axes), the nominal actuator and the
    uncertain plant parameters, all from :data:`seactl.base.axes.AXES`."""
    for name in reversed(ACTUATOR_AXES):
        info = AXES[name]
        func = click.option(info.option, name, default=None,
                            help=f"Uncertainty of the {info.description}: P% or LO,HI "
                                 f"[{info.unit}].")(func)
    func = click.option("--actuator", default="ut-sea", show_default=True,
                        help="Nominal SEA (preset or TOML).")(func)
    for name in reversed(DESIGN_AXES):
        func = axis_option(name)(func)
    return func


@cli.command()
@_robust_options
@click.option("--n", "n_samples", type=click.IntRange(10, 10_000_000), default=2000,
              show_default=True, help="Monte Carlo samples.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--plot", "plot_file", default=None, metavar="FILE.png|.svg|.pdf",
              help="Write the phase-margin histogram (format from the suffix).")
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
def robust(actuator, n_samples, seed, plot_file, as_json, **axes) -> None:
    """Monte Carlo of one design over actuator parameter uncertainty.

    Python: sc.parameter_robustness(...).

    \b
    The gains are designed for the nominal actuator; each sample draws the plant's
    parameters uniformly in their intervals (P% = nominal +/- P%). Reports the
    phase-margin distribution and the probability of instability (Wilson 95%).

    \b
    Example:
      seactl robust --fn 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100 \\
          --ij 20% --bm 20% --k 20% --n 5000 --plot pm_hist.png

    The same samples, on Dask and stored as Parquet:
    seactl sweep --sample random --n N --seed S with the same options.
    """
    import seactl as sc

    fn, gs = axes["fn_hz"], axes["gs"]
    opts = {n: ("none" if axes[n] is None else str(axes[n]),) for n in DESIGN_AXES}
    given = {n: axes[n] for n in ACTUATOR_AXES if axes[n] is not None}
    if not given:
        raise InputError("--ij/--bm/--k/...", None, "at least one uncertain actuator "
                         "parameter, e.g. --ij 20%")
    for name, v in given.items():
        opts[name] = (v,)
    from seactl.base.limits import BYTES_PER_DESIGN, check_budget

    check_budget(f"a Monte Carlo of {n_samples:,} samples", n_bytes=n_samples * BYTES_PER_DESIGN,
                 hint="lower --n")
    spec = _spec_from_options(opts, actuator=actuator, sampling="random", n_samples=n_samples,
                              seed=seed, chunk_size=5_000, unc_points=3, z_freq=())
    for name in given:
        if len(dict(spec.axes)[name]) < 2 or np.ptp(dict(spec.axes)[name]) == 0:
            raise InputError(AXES[name].option, given[name], "an interval: P% with P > 0 or "
                             "two values LO,HI")
    with OutputSet() as outs:
        fig_file = outs.add("--plot", plot_file, FIGURE_SUFFIXES)
        r = sc.parameter_robustness(actuator=spec.actuator, n_samples=n_samples, seed=seed,
                                    chunk_size=spec.chunk_size, **dict(spec.axes))
        fig_path = None
        if fig_file:
            from seactl.apps.plots import robust_histogram_figure

            unc_text = ", ".join(f"{n} " + (f"±{v}" if v.endswith("%") else v)
                                 for n, v in given.items())
            fig = robust_histogram_figure(r.phase_margin_deg, r.stable,
                                          r.nominal_phase_margin_deg,
                                          f"f_n = {fn:g} Hz, GS = {gs:g}: {unc_text} "
                                          f"({r.n_samples} samples)")
            outs.figure(fig_file, fig)
            outs.commit()
            fig_path = str(fig_file)
    lo, hi = r.p_unstable_ci95()
    pct = r.percentiles()
    res = {"n_samples": r.n_samples, "nominal_phase_margin_deg": finite_or_none(
               r.nominal_phase_margin_deg),
           "p_unstable": finite_or_none(r.p_unstable),
           "p_unstable_ci95": [finite_or_none(lo), finite_or_none(hi)],
           "phase_margin_deg_stable": {k: finite_or_none(v) for k, v in pct.items()},
           "intervals": {n: [finite_or_none(min(dict(spec.axes)[n])),
                             finite_or_none(max(dict(spec.axes)[n]))] for n in given},
           "figure": fig_path}
    if as_json:
        echo_json(res)
        return
    t = Table(title=f"Monte Carlo, f_n = {fn:g} Hz, GS = {gs:g}, {r.n_samples} samples")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    for n, (a, b) in res["intervals"].items():
        t.add_row(escape(f"{n} interval [{AXES[n].unit}]"), f"{a:.6g} .. {b:.6g}")
    t.add_row(escape("nominal PM [deg]"), f"{r.nominal_phase_margin_deg:.3f}")
    for k, v in pct.items():
        t.add_row(escape(f"PM {k} (stable samples) [deg]"), f"{v:.3f}")
    t.add_row("P(unstable)", f"{r.p_unstable:.4f} (95%: {lo:.4f} .. {hi:.4f})")
    console.print(t)
    if fig_path:
        console.print(f"figure: {escape(fig_path)}")
