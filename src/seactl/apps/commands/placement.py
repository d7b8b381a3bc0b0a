"""``seactl rigid``, ``seactl latency-map`` and ``seactl place``: where each loop should run."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.base import progress
from seactl.base.axes import AXES
from seactl.base.outputs import CSV_SUFFIXES, FIGURE_SUFFIXES, OutputSet
from seactl.errors import InputError

from .common import (
    VARIADIC,
    cli,
    console,
    echo_json,
    finite_or_none,
    json_option,
    parse_values,
    pm_text,
    units_given,
    verdict_text,
)
from .loops import loop_options, loop_place

VARIADIC.update({"--fn-rigid", "--fn-sea"})

def _ms(name: str, value: float) -> float:
    from seactl.base.limits import check_range

    return check_range(f"{name} [ms]", value, "delay_ms") * 1e-3


def _f_v(value: float | None) -> float | None:
    """``--f-v``: cut-off [Hz] > 0; ``inf`` or ``none`` means no filter."""
    if value is None or str(value).lower() in ("none", "inf"):
        return None
    from seactl.base.limits import check_range

    try:
        v = float(value)
    except ValueError:
        raise InputError("--f-v [Hz]", value, "a cut-off > 0 [Hz] or 'none'") from None
    return check_range("--f-v [Hz]", v, "filter_hz")


def load_model(spec: str, f_v: float | None = 50.0):
    """A :class:`~seactl.latency.maps.LoopModel` from a preset (``ut-linear``, ``ut-sea``) or a
    TOML file (a rigid actuator has a ``mass`` key, an SEA a ``motor_inertia`` key)."""
    from seactl.base.params import read_toml
    from seactl.latency.maps import rigid_model, sea_model
    from seactl.systems.rigid.model import RIGID_PRESETS, load_rigid
    from seactl.systems.sea.actuators import SEA_PRESETS, load_sea

    key = str(spec).lower()
    if key in RIGID_PRESETS:
        return rigid_model(load_rigid(key), f_v=f_v)
    if key in SEA_PRESETS:
        return sea_model(load_sea(key), f_qd=f_v)
    path = Path(spec)
    if path.suffix == ".toml" and path.is_file():
        data = read_toml("--actuator", spec, "a preset")
        table = data.get("actuator", data) if isinstance(data.get("actuator"), dict) else data
        if "mass" in table:
            return rigid_model(load_rigid(path), f_v=f_v)
        return sea_model(load_sea(path), f_qd=f_v)
    raise InputError("--actuator", spec, "a preset (" + ", ".join([*RIGID_PRESETS, *SEA_PRESETS])
                     + ") or an existing .toml file")


def _fmt(x: float | None, spec: str) -> str:
    return "none" if x is None else format(x, spec)


# ---------------------------------------------------------------------------- seactl rigid
def _rigid_fn(fn: tuple[str, ...], step: bool) -> np.ndarray:
    """The ``--fn`` values, checked, and the work they ask for estimated first."""
    from seactl.base.limits import BYTES_PER_DESIGN, check_budget, simulation_estimate

    fn_hz = parse_values("--fn", fn)
    if fn_hz.size == 0:
        raise InputError("--fn", "", "at least one frequency")
    AXES["fn_hz"].check(fn_hz, "--fn [Hz]")
    sim_bytes, sim_s = simulation_estimate(fn_hz.size, 1000, 1000) if step else (0.0, 0.0)
    check_budget(f"{fn_hz.size:,} rigid design(s)" + (" and their 1 s steps" if step else ""),
                 n_bytes=fn_hz.size * BYTES_PER_DESIGN + sim_bytes, seconds=sim_s,
                 hint="give fewer --fn values" + (" or --no-step" if step else ""))
    return fn_hz


def _rigid_rows(fn_hz: np.ndarray, d: Any, m: Any, dm: Any, exp: Any) -> list[dict[str, Any]]:
    """One JSON record per f_n: gains, margins, per-loop delay margins, step metrics."""
    from seactl.simulate.sampled import verdict_word

    rows = []
    for i, f in enumerate(fn_hz):
        r = {"fn_hz": float(f), "K": float(d.K[i]), "B": float(d.B[i]),
             "phase_margin_deg": finite_or_none(m.phase_margin_deg[i]),
             "crossover_hz": finite_or_none(m.crossover_hz[i]),
             "gain_margin_db": finite_or_none(m.gain_margin_db[i]),
             "delay_margin_ms": finite_or_none(m.delay_margin_ms[i]),
             "stiffness_delay_margin_ms": finite_or_none(dm.stiffness_s[i] * 1e3),
             "damping_delay_margin_ms": finite_or_none(dm.damping_s[i] * 1e3),
             "stable": bool(m.stable[i])}
        if exp is not None:
            r["step"] = {"out_of_control": bool(exp.out_of_control[0, i]),
                         "overshoot_pct": finite_or_none(exp.overshoot_pct[0, i]),
                         "settling_time_s": finite_or_none(exp.settling_time_s[0, i]),
                         "peak_force_n": float(np.max(np.abs(exp.force[0, i]))),
                         "saturated_fraction": float(exp.saturated_fraction[0, i]),
                         "buffer_ms": list(exp.delays_ms[0]),
                         "sampled_verdict": str(verdict_word(
                             exp.sampled_unstable_modes[0, i]))}
        rows.append(r)
    return rows


def _rigid_table(a: Any, rows: list[dict[str, Any]], t_s: float, t_d: float, fv: Any,
                 with_step: bool) -> Table:
    t = Table(title=f"Rigid actuator '{escape(a.name)}' (m = {a.m:g} kg, b = {a.b:g} Ns/m), "
              f"T_s = {t_s:g} ms, T_d = {t_d:g} ms, f_v = {fv or 'none'} Hz")
    cols = ["f_n [Hz]", "K [N/m]", "B [Ns/m]", "PM [deg]", "crossover [Hz]", "GM [dB]",
            "DM [ms]", "DM stiffness [ms]", "DM damping [ms]", "stable"]
    if with_step:
        cols += ["step", "sampled loop", "overshoot [%]", "settling [s]", "peak force [N]"]
    for c in cols:
        t.add_column(escape(c), justify="right")
    for r in rows:
        cells = [f"{r['fn_hz']:g}", f"{r['K']:.4g}", f"{r['B']:.4g}",
                 pm_text(r["phase_margin_deg"], r["stable"]), _fmt(r["crossover_hz"], ".2f"),
                 _fmt(r["gain_margin_db"], ".2f"), _fmt(r["delay_margin_ms"], ".2f"),
                 _fmt(r["stiffness_delay_margin_ms"], ".2f"),
                 _fmt(r["damping_delay_margin_ms"], ".2f"),
                 "yes" if r["stable"] else "[red]NO[/red]"]
        if with_step:
            s = r["step"]
            cells += ["[red]OUT OF CONTROL[/red]" if s["out_of_control"] else "ok",
                      verdict_text(s["sampled_verdict"]), _fmt(s["overshoot_pct"], ".1f"),
                      _fmt(s["settling_time_s"], ".3f"),
                      f"{s['peak_force_n']:.0f}"]
        t.add_row(*cells)
    return t


@cli.command()
@click.option("--fn", "fn", multiple=True, default=("4", "8", "12"), show_default=True,
              help="Natural frequency f_n [Hz]: values, or START:STOP:STEP.")
@click.option("--t-s", "t_s", type=float, default=1.5, show_default=True,
              help="Stiffness-feedback delay T_s [ms] (effective; 1 kHz with a 1-sample buffer "
                   "is 1.5 ms).")
@click.option("--t-d", "t_d", type=float, default=1.5, show_default=True,
              help="Damping-feedback delay T_d [ms] (effective).")
@click.option("--f-v", "f_v", default="50", show_default=True,
              help="Velocity filter cut-off [Hz], or 'none'.")
@click.option("--actuator", default="ut-linear", show_default=True,
              help="Rigid-actuator preset or TOML file.")
@click.option("--no-passive-damping", is_flag=True,
              help="Use B = 2 m w_n instead of B = 2 m w_n - b.")
@click.option("--step/--no-step", default=True, show_default=True,
              help="Also run the sampled step 0.131 -> 0.135 m (1 kHz, force saturation) with "
                   "buffers of round(T - 0.5 ms) samples.")
@json_option
def rigid(fn, t_s, t_d, f_v, actuator, no_passive_damping, step, as_json) -> None:
    """Rigid actuator: critically-damped gains, margins, per-loop delay margins, step.

    Python: sc.rigid(...).margins() and sc.rigid(...).delay_margins().

    \b
    Example (the paper's step experiment, 15 ms on the damping loop):
      seactl rigid --fn 4 8 12 --t-s 1.5 --t-d 15.5

    DM stiffness / DM damping: extra latency the stiffness (damping) loop alone
    tolerates before the closed loop goes unstable. 'none' (null): no such crossing.
    """
    from seactl.api.rigid import rigid as rigid_batch
    from seactl.systems.rigid.model import load_rigid, step_experiment

    a = load_rigid(actuator)
    fv = _f_v(f_v)
    fn_hz = _rigid_fn(fn, step)
    for name, value in (("--t-s", t_s), ("--t-d", t_d)):
        _ms(name, value)   # the range check names the flag
    with units_given():
        d = rigid_batch(fn_hz, actuator=a, delays_ms={"stiffness": t_s, "damping": t_d},
                        velocity_filter_hz=fv, passive_damping=not no_passive_damping)
    exp = None
    if step:
        buf = (max(t_s - 0.5, 0.0), max(t_d - 0.5, 0.0))
        exp = step_experiment(a, fn_hz, delays_ms=(buf,), f_v=fv,
                              passive_damping=not no_passive_damping)
    # the sampled step experiment (buffers of round(T - 0.5 ms) samples, the paper's) has no
    # public view: seactl.systems.rigid.model.step_experiment
    rows = _rigid_rows(fn_hz, d.rigid, d.margins(), d.delay_margins(), exp)
    if as_json:
        echo_json({"actuator": a.name, "T_s_ms": t_s, "T_d_ms": t_d, "f_v_hz": fv,
                   "passive_damping": not no_passive_damping,
                   "force_limit_n": a.max_force, "designs": rows})
        return
    console.print(_rigid_table(a, rows, t_s, t_d, fv, exp is not None))
    if exp is not None:
        console.print(f"step: sampled at 1 kHz, delay buffers {exp.delays_ms[0][0]:g} / "
                      f"{exp.delays_ms[0][1]:g} ms, force limit {a.max_force:.0f} N; "
                      "'out of control' = diverged or still oscillating (>5% peak-to-peak) in "
                      "the last quarter of 1 s; 'sampled loop' = the certified verdict of the "
                      "sampled loop without the force limit.")


# ---------------------------------------------------------------------- seactl latency-map
@cli.command("latency-map")
@click.option("--actuator", "actuators", multiple=True, default=("ut-linear", "ut-sea"),
              show_default=True, help="Actuator preset(s) or TOML file(s).")
@click.option("--fn-rigid", multiple=True, default=("8",), show_default=True,
              help="f_n [Hz] of the rigid-actuator phase-margin map.")
@click.option("--fn-sea", multiple=True, default=("14",), show_default=True,
              help="f_n [Hz] of the SEA phase-margin map.")
@click.option("--t-max", type=float, default=20.0, show_default=True,
              help="Largest delay on each axis [ms].")
@click.option("--t-min", type=float, default=0.5, show_default=True,
              help="Smallest delay on each axis [ms].")
@click.option("--n", "n", type=click.IntRange(2, 400), default=41, show_default=True,
              help="Grid points per axis.")
@click.option("--max-fn/--no-max-fn", default=False, show_default=True,
              help="Also map the highest stable f_n (slower).")
@click.option("--f-v", "f_v", default="50", show_default=True,
              help="Velocity filter cut-off [Hz] (f_qd for the SEA), or 'none'.")
@click.option("--plot", default=None, metavar="FILE.png|.svg|.pdf", help="Write the maps.")
@click.option("--csv", default=None, metavar="FILE", help="Write every grid point as CSV.")
@json_option
def latency_map_cmd(actuators, fn_rigid, fn_sea, t_max, t_min, n, max_fn, f_v, plot, csv,
                    as_json) -> None:
    """Phase margin over (stiffness delay, damping delay) for each actuator.

    Python: sc.latency_map(...) (one actuator and f_n).

    \b
    Example:
      seactl latency-map --n 61 --max-fn --plot maps.png --csv maps.csv

    The SEA torque loop keeps T_tau = 0.5 ms and f_taud = 100 Hz. The sensitivity
    ratio is (dPM/dT_d)/(dPM/dT_s) at the smallest delays (T_s = T_d = --t-min).
    """
    with OutputSet() as outs:
        plot_p = outs.add("--plot", plot, FIGURE_SUFFIXES)
        csv_p = outs.add("--csv", csv, CSV_SUFFIXES)
        _latency_map(actuators, fn_rigid, fn_sea, t_max, t_min, n, max_fn, f_v, outs, plot_p,
                     csv_p, as_json)


def _map_summary(model: Any, f: float, mp: Any, sens: Any, dm: Any, n: int, t_min: float,
                 t_max: float) -> dict[str, Any]:
    """The JSON record of one latency map: corners, sensitivities, per-loop delay margins."""
    return {
        "actuator": model.name, "kind": model.kind, "fn_hz": f,
        "n": n, "t_min_ms": t_min, "t_max_ms": t_max,
        "stable_fraction": float(mp.stable.mean()),
        "pm_at_min_delays_deg": finite_or_none(mp.phase_margin_deg[0, 0]),
        "pm_stiffness_max_deg": finite_or_none(mp.phase_margin_deg[-1, 0]),
        "pm_damping_max_deg": finite_or_none(mp.phase_margin_deg[0, -1]),
        "stable_stiffness_max": bool(mp.stable[-1, 0]),
        "stable_damping_max": bool(mp.stable[0, -1]),
        "dpm_dts_deg_per_ms": finite_or_none(sens.dpm_dTs_deg_per_ms),
        "dpm_dtd_deg_per_ms": finite_or_none(sens.dpm_dTd_deg_per_ms),
        "sensitivity_ratio": finite_or_none(sens.ratio),
        "stiffness_delay_margin_ms": finite_or_none(dm.stiffness_s * 1e3),
        "damping_delay_margin_ms": finite_or_none(dm.damping_s * 1e3),
    }


def _map_rows(name: str, f: float, grid: np.ndarray, mp: Any, mf: Any) -> list[list[Any]]:
    rows = []
    for i, ts in enumerate(grid):
        for j, td in enumerate(grid):
            row = [name, f, ts * 1e3, td * 1e3, finite_or_none(mp.phase_margin_deg[i, j]),
                   bool(mp.stable[i, j])]
            if mf is not None:
                row += [finite_or_none(mf.fn_hz[i, j]), str(mf.status[i, j])]
            rows.append(row)
    return rows


def _map_csv(rows: list[list[Any]], max_fn: bool) -> str:
    head = ["actuator", "fn_hz", "T_s_ms", "T_d_ms", "phase_margin_deg", "stable"]
    if max_fn:
        head += ["max_stable_fn_hz", "max_fn_status"]
    buf = io.StringIO()
    buf.write(",".join(head) + "\n")
    for r in rows:
        buf.write(",".join("none" if x is None else
                           (f"{x:.10g}" if isinstance(x, float) else str(x)) for x in r) + "\n")
    return buf.getvalue()


def _map_table(summary: list[dict[str, Any]], n: int, t_min: float, t_max: float) -> Table:
    t = Table(title=f"Latency maps: {n} x {n} grid, delays {t_min:g}..{t_max:g} ms on each loop")
    for c in ("actuator", "f_n [Hz]", "stable [%]", "PM min delays [deg]", "PM max T_s [deg]",
              "PM max T_d [deg]", "dPM/dT_s [deg/ms]", "dPM/dT_d [deg/ms]", "ratio d/s",
              "DM stiffness [ms]", "DM damping [ms]"):
        t.add_column(escape(c), justify="right" if c != "actuator" else "left")
    for s in summary:
        t.add_row(s["actuator"], f"{s['fn_hz']:g}", f"{100 * s['stable_fraction']:.1f}",
                  _fmt(s["pm_at_min_delays_deg"], ".1f"),
                  _fmt(s["pm_stiffness_max_deg"], ".1f")
                  + ("" if s["stable_stiffness_max"] else " (unstable)"),
                  _fmt(s["pm_damping_max_deg"], ".1f")
                  + ("" if s["stable_damping_max"] else " (unstable)"),
                  _fmt(s["dpm_dts_deg_per_ms"], ".3f"), _fmt(s["dpm_dtd_deg_per_ms"], ".3f"),
                  _fmt(s["sensitivity_ratio"], ".3g"),
                  _fmt(s["stiffness_delay_margin_ms"], ".2f"),
                  _fmt(s["damping_delay_margin_ms"], ".2f"))
    return t


def _latency_map(actuators, fn_rigid, fn_sea, t_max, t_min, n, max_fn, f_v, outs, plot, csv,
                 as_json) -> None:
    from seactl.latency.maps import latency_map, max_stable_fn, pm_sensitivity

    tmin, tmax = _ms("--t-min", t_min), _ms("--t-max", t_max)
    if tmax <= tmin:
        raise InputError("--t-max [ms]", t_max, f"> --t-min ({t_min:g} ms)")
    fv = _f_v(f_v)
    grid = np.linspace(tmin, tmax, n)
    maps, maxfns, summary, csv_rows = [], [], [], []
    jobs = []
    for spec in actuators:
        model = load_model(spec, fv)
        flag = "--fn-rigid" if model.kind == "rigid" else "--fn-sea"
        fns = parse_values(flag, fn_rigid if model.kind == "rigid" else fn_sea)
        if fns.size == 0:
            raise InputError(flag, "", "at least one frequency")
        jobs.append((model, AXES["fn_hz"].check(fns, f"{flag} [Hz]")))
    _check_latency_budget(jobs, n, max_fn)
    total = sum(fns.size + bool(max_fn) for _, fns in jobs)
    with progress.stage(f"latency maps ({n} x {n} grid)", total=total, unit="maps") as stage:
        for model, fns in jobs:
            mf = max_stable_fn(model, grid[:, None], grid[None, :]) if max_fn else None
            if max_fn:
                stage.advance(item=f"{model.name}: highest stable f_n")
            for f in fns:
                mp = latency_map(model, float(f), grid, grid)
                sens = pm_sensitivity(model, float(f), tmin, tmin)
                dm = model.delay_margins(model.design(float(f), tmin, tmin))
                maps.append(mp)
                if mf is not None:
                    maxfns.append((grid, grid, mf))
                summary.append(_map_summary(model, float(f), mp, sens, dm, n, t_min, t_max))
                csv_rows += _map_rows(model.name, float(f), grid, mp, mf)
                stage.advance(item=f"{model.name} at f_n = {float(f):g} Hz")
    if csv:
        outs.write(csv, _map_csv(csv_rows, max_fn))
    if plot:
        from seactl.apps.plots import latency_map_figure

        outs.figure(plot, latency_map_figure(maps, maxfns or None))
    outs.commit()
    if as_json:
        echo_json({"maps": summary, "csv": csv and str(csv), "plot": plot and str(plot)})
        return
    console.print(_map_table(summary, n, t_min, t_max))
    console.print("PM max T_s: stiffness delay at --t-max, damping at --t-min (and vice versa). "
                  "DM: extra latency each loop alone tolerates at the smallest delays.")
    for what, path in (("plot", plot), ("csv", csv)):
        if path:
            console.print(f"{what}: {escape(str(path))}")


MAP_POINT_BYTES, MAP_POINT_S = 8e3, 1e-4
"""Memory [B] and time [s] per grid point of a phase-margin map, set above what one costs."""
MAXFN_POINT_BYTES, MAXFN_POINT_S = 160e3, 3e-3
"""... and of the highest-stable-f_n map, likewise."""


def _check_latency_budget(jobs, n: int, max_fn: bool) -> None:
    from seactl.base.limits import check_budget

    maps = sum(len(fns) for _, fns in jobs)
    points = n * n
    check_budget(f"{maps:,} latency map(s) of {n} x {n} points" + (" with --max-fn" if max_fn
                                                                     else ""),
                 n_bytes=points * (MAXFN_POINT_BYTES if max_fn else MAP_POINT_BYTES),
                 seconds=points * (maps * MAP_POINT_S + (len(jobs) * MAXFN_POINT_S
                                                         if max_fn else 0.0)),
                 hint="lower --n or give fewer --fn-rigid / --fn-sea values")


# ---------------------------------------------------------------------------- seactl place
def _ms_or_none(x: float | None) -> float | None:
    return None if x is None else finite_or_none(x * 1e3)


def advice_json(a, checks: dict[str, Any] | None = None) -> dict[str, Any]:
    from seactl.latency.placement import GAIN_UNITS

    def opt(o):
        return {"placement": o.placement, "stiffness_delay_ms": o.T_s * 1e3,
                "damping_delay_ms": o.T_d * 1e3,
                "torque_delay_ms": None if o.T_inner is None else o.T_inner * 1e3,
                "max_fn_hz": None if o.fn_hz is None else finite_or_none(o.fn_hz),
                "status": o.status, "gains": {k: finite_or_none(v) for k, v in o.gains.items()},
                "gain_units": {k: GAIN_UNITS[k] for k in o.gains},
                "static_stiffness": None if o.static_stiffness is None
                else finite_or_none(o.static_stiffness),
                "phase_margin_deg": None if o.phase_margin_deg is None
                else finite_or_none(o.phase_margin_deg),
                "crossover_hz": None if o.crossover_hz is None else finite_or_none(o.crossover_hz),
                "stiffness_delay_margin_ms": _ms_or_none(o.stiffness_dm_s),
                "damping_delay_margin_ms": _ms_or_none(o.damping_dm_s),
                "latency_box_upper_ms": {k: v * 1e3 for k, v in (o.box_upper_s or {}).items()},
                "bottleneck": o.bottleneck,
                **({} if o.jitter_s is None else {
                    "jitter_ms": {k: v * 1e3 for k, v in o.jitter_s.items()},
                    "jitter_margin_ms": None if o.jitter_margin_s is None else
                    {k: finite_or_none(v * 1e3) for k, v in o.jitter_margin_s.items()},
                    "monte_carlo": (checks or {}).get(o.placement)})}

    from seactl.latency.placement import upper_bound

    return {"actuator": a.actuator, "kind": a.kind, "high_latency_ms": a.high_latency_s * 1e3,
            "low_latency_ms": a.low_latency_s * 1e3, "min_pm_deg": a.min_pm_deg,
            "latency_margin": a.latency_margin, "criterion": a.criterion,
            "stiffness_embeddable": a.stiffness_embeddable, "stiffness_unit": a.stiffness_unit,
            "recommended": a.recommended, "upper_bound": upper_bound(a.options),
            "stiffness_gain_vs_centralized": None if a.stiffness_gain_vs_centralized is None
            else finite_or_none(a.stiffness_gain_vs_centralized),
            "fraction_of_embedded": None if a.fraction_of_embedded is None
            else finite_or_none(a.fraction_of_embedded),
            "placements": [opt(o) for o in a.options], "reason": a.reason}


@cli.command()
@click.option("--high-latency", type=float, default=None,
              help="Feedback latency of the high-level (centralized) process [ms] "
                   "(default 22, or the minimum of --high-timing).")
@click.option("--low-latency", type=float, default=None,
              help="Feedback latency of the embedded process [ms] (default 0.5, or the "
                   "minimum of --low-timing).")
@click.option("--actuator", default="ut-linear", show_default=True,
              help="Preset (ut-linear, ut-sea) or TOML file.")
@click.option("--min-pm", type=float, default=45.0, show_default=True,
              help="Phase margin [deg] required at every latency of the box.")
@click.option("--latency-margin", type=float, default=0.5, show_default=True,
              help="Fraction of its latency each loop must tolerate on top of it: the box of "
                   "latencies checked runs from 0 to (1 + this) x each loop's latency.")
@click.option("--f-v", "f_v", default="50", show_default=True,
              help="Velocity filter cut-off [Hz] (f_qd for the SEA), or 'none'.")
@click.option("--stiffness-embeddable", is_flag=True,
              help="Allow the stiffness loop on the embedded process (default: it needs the "
                   "high-level process; 'embedded' is then shown for comparison only).")
@click.option("--high-timing", default=None, metavar="MODEL",
              help="Latency distribution of the high-level process [ms]: uniform:LOW:HIGH, "
                   "exp:SHIFT:MEAN, a constant, or hist:TRACE.csv (a measured trace: rows "
                   "latency_ms or latency_ms,count under an optional header, e.g. "
                   "examples/timing/trace.csv).")
@click.option("--low-timing", default=None, metavar="MODEL",
              help="Latency distribution of the embedded process [ms] (as --high-timing).")
@click.option("--high-loss", default=None, metavar="P",
              help="Message loss of the high-level process: P or ge:P_GB:P_BG[:BAD[:GOOD]].")
@click.option("--low-loss", default=None, metavar="P",
              help="Message loss of the embedded process (as --high-loss).")
@click.option("--rate", "rate_hz", type=float, default=1000.0, show_default=True,
              help="Servo rate of both processes [Hz] (loss bursts age the held value).")
@click.option("--runs", type=click.IntRange(0, 100_000), default=200, show_default=True,
              help="Monte Carlo check of each placement with timing (0: none).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Monte Carlo seed.")
@json_option
@loop_options
def place(high_latency, low_latency, actuator, min_pm, latency_margin, f_v,
          stiffness_embeddable,
          high_timing, low_timing, high_loss, low_loss, rate_hz, runs, seed,
          as_json, loop) -> None:
    """Which process should run the stiffness and damping loops?

    Python: sc.place(...); --loop: sc.load_loop(...).placements().

    \b
    Example (the mobile base: 7 ms + 15 ms centralized, 0.5 ms embedded):
      seactl place --high-latency 22 --low-latency 0.5
    With jitter and loss (a measured trace for the high-level process):
      seactl place --high-timing hist:examples/timing/trace.csv --low-timing uniform:0.5:1 \\
          --low-loss 0.01

    Placements (centralized: all loops high-level; distributed: stiffness
    high-level, damping embedded; embedded: all embedded) are ranked by a score:
    the largest critically-damped f_n such that at every f_n up to it the loop
    is stable with PM >= --min-pm for every combination of loop latencies from
    0 to (1 + --latency-margin) x the latency each loop gets (checked on a
    lattice of 4 points per doubling, upper end rounded up). A longer latency
    on any loop never raises the score, so all-embedded scores at least as high
    as the others whenever the embedded latency is the lower one. With a timing
    spec, every loop's jitter margin must also cover its process's jitter at
    every latency of the box; 'limited by' names the constraint that fails just
    above the score and where, and a Monte Carlo simulation checks each
    placement with the full latency distributions and losses. PM and DM columns
    are the nominal-latency margins at the score.
    """
    from seactl.latency.placement import advise

    if loop is not None:
        return loop_place(loop, as_json)
    for opt, latency, timing_opt in (("--high-latency", high_latency, high_timing),
                                     ("--low-latency", low_latency, low_timing)):
        if latency is not None and timing_opt is not None:
            raise InputError(opt, latency, f"given without {opt[:-8]}-timing (the smallest "
                             f"latency of {opt[:-8]}-timing is the one analysed)")
    timing = _process_timing(high_timing, low_timing, high_loss, low_loss, rate_hz)
    if timing and runs:
        _check_monte_carlo(timing, runs)
    hi = _ms("--high-latency", 22.0 if high_latency is None else high_latency)
    lo = _ms("--low-latency", 0.5 if low_latency is None else low_latency)
    if not 0 <= min_pm < 180:
        raise InputError("--min-pm [deg]", min_pm, ">= 0 and < 180")
    from seactl.latency.placement import MAX_LATENCY_MARGIN

    if not 0 <= latency_margin <= MAX_LATENCY_MARGIN:
        raise InputError("--latency-margin", latency_margin, f">= 0 and <= {MAX_LATENCY_MARGIN:g}")
    model = load_model(actuator, _f_v(f_v))
    a = advise(model, hi, lo, min_pm_deg=min_pm, stiffness_embeddable=stiffness_embeddable,
               timing=timing, latency_margin=latency_margin)
    checks = _monte_carlo_checks(model, a, timing, runs, seed)
    if as_json:
        echo_json(advice_json(a, checks))
        return
    _print_advice(a, checks)


def _process_timing(high_timing, low_timing, high_loss, low_loss, rate_hz):
    """``{"high-level": ProcessTiming, "embedded": ...}`` from the options, or None."""
    from seactl.latency.models import parse_latency, parse_loss
    from seactl.latency.placement import ProcessTiming

    if not (rate_hz > 0 and np.isfinite(rate_hz)):
        raise InputError("--rate [Hz]", rate_hz, "a finite rate > 0")
    out = {}
    for proc, lat, loss, opt in (("high-level", high_timing, high_loss, "--high"),
                                 ("embedded", low_timing, low_loss, "--low")):
        if lat is None and loss is None:
            continue
        model = parse_latency(lat, f"{opt}-timing") if lat is not None else None
        if model is None:
            raise InputError(f"{opt}-timing", None, f"a latency model with {opt}-loss")
        out[proc] = ProcessTiming(model, parse_loss(loss, f"{opt}-loss")
                                  if loss is not None else None, rate_hz)
    return out or None


def _check_monte_carlo(timing, runs: int) -> None:
    """Refuse up front a Monte Carlo check (every placement, :data:`MC_SECONDS` simulated
    at the fastest process rate) larger than the machine's memory or the time budget."""
    from seactl.base.limits import check_budget, simulation_estimate
    from seactl.latency.placement import PLACEMENTS

    steps = MC_SECONDS * max([1000.0, *(t.rate_hz for t in timing.values())])
    n_bytes, seconds = simulation_estimate(runs, steps, steps)
    check_budget(f"the Monte Carlo check ({runs:,} runs of each of {len(PLACEMENTS)} "
                 "placements)", n_bytes=n_bytes, seconds=len(PLACEMENTS) * seconds,
                 hint="lower --runs")


MC_SECONDS = 1.0
"""Simulated time of each Monte Carlo run [s]
(:func:`seactl.latency.montecarlo.verify_placement`)."""


def _monte_carlo_checks(model, advice, timing, runs, seed) -> dict[str, Any]:
    if not timing or runs == 0:
        return {}
    from seactl.latency.montecarlo import verify_placement

    out = {}
    with progress.stage(f"Monte Carlo check ({runs:,} runs each)", total=len(advice.options),
                        unit="placements") as stage:
        for o in advice.options:
            mc = verify_placement(model, o, timing, runs=runs, seed=seed, t_end_s=MC_SECONDS)
            if mc is not None:
                out[o.placement] = {"runs": runs, "seed": seed,
                                    "fraction_stable": float(mc.fraction_stable),
                                    "rms_error_mean": finite_or_none(mc.rms_error_mean),
                                    "rms_error_worst": finite_or_none(mc.rms_error_worst)}
            stage.advance(item=o.placement)
    return out


def _print_advice(a, checks: dict[str, Any]) -> None:
    from seactl.latency.placement import GAIN_UNITS

    t = Table(title=escape(f"Loop placement for '{a.actuator}': high-level "
                           f"{a.high_latency_s * 1e3:g} ms, embedded {a.low_latency_s * 1e3:g} "
                           f"ms, PM >= {a.min_pm_deg:g} deg over latencies "
                           f"0..{1 + a.latency_margin:g}x"
                           + (" (+ jitter)" if a.timing else "")))
    gnames = list(next((o.gains for o in a.options if o.gains), {}))
    cols = ["placement", "T_s [ms]", "T_d [ms]"] + (["T_tau [ms]"] if a.kind == "sea" else []) \
        + ["score f_n [Hz]"] + [f"{g} [{GAIN_UNITS[g]}]" for g in gnames] \
        + [f"stiffness [{a.stiffness_unit}]", "PM [deg]", "DM stiff. [ms]", "DM damp. [ms]",
           "limited by"]
    if a.timing:
        cols += ["MC stable [%]"]
    for c in cols:
        t.add_column(escape(c), justify="left" if c in ("placement", "limited by") else "right")
    for o in a.options:
        mark = " *" if o.placement == a.recommended else ""
        cells = [o.placement + mark, f"{o.T_s * 1e3:g}", f"{o.T_d * 1e3:g}"]
        if a.kind == "sea":
            cells.append(f"{o.T_inner * 1e3:g}")
        cells.append("none" if o.fn_hz is None else
                     f"{o.fn_hz:.3f}" + ("+" if o.status == "capped" else ""))
        cells += [f"{o.gains[g]:.4g}" if g in o.gains else "-" for g in gnames]
        cells += [_fmt(o.static_stiffness, ".4g"), _fmt(o.phase_margin_deg, ".1f"),
                  _fmt(None if o.stiffness_dm_s is None else o.stiffness_dm_s * 1e3, ".2f"),
                  _fmt(None if o.damping_dm_s is None else o.damping_dm_s * 1e3, ".2f"),
                  escape(o.bottleneck or "-")]
        if a.timing:
            mc = checks.get(o.placement)
            cells += ["-" if mc is None else f"{100 * mc['fraction_stable']:.1f}"]
        t.add_row(*cells)
    console.print(t)
    console.print(escape(a.criterion[0].upper() + a.criterion[1:] + "."))
    console.print("PM, DM: margins at the score with the nominal latencies; limited by: the "
                  "constraint that fails just above the score, and the latencies where it does.")
    console.print(escape(a.reason))
