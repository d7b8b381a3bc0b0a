"""``seactl step`` and ``seactl impulse``: time-domain responses of SEA designs.

Both take the design options of ``seactl gains`` (every f_n x GS combination is
simulated in one vectorized batch) and::

    --mode continuous|sampled   exact-delay continuous loop, or the loop as it runs on the
                                robot (Tustin controllers at --rate, ZOH, whole-sample delay
                                buffers, current saturation)
    --rate HZ                   servo rate of both processes (sampled mode)
    --no-zero                   torque derivative on the feedback only (no zero in P_CL)
    --t-end S                   simulated time
    --saturation A              motor current limit (sampled mode; default: the actuator's,
                                'none' for no limit)
    --plot FILE, --csv FILE, --json
    --latency LINK=MODEL        random latency of a link (stiffness, damping, torque) in ms:
                                2, uniform:LOW:HIGH, exp:SHIFT:MEAN, hist:FILE.csv
    --loss LINK=P               message loss: a probability, or ge:P_GB:P_BG[:BAD[:GOOD]]
    --runs N, --seed S          Monte Carlo over N timing realizations (sampled mode)

With --latency, --loss or --runs the command runs a Monte Carlo (seactl.latency.montecarlo) and
prints
per design the fraction of stable runs, the RMS tracking error (mean and worst of the
stable runs), the largest current and the worst run; JSON ``{"mode", "runs", "seed",
"latency", "loss", "designs": [{"fn_hz", "gs", "fraction_stable", "rms_error_mean",
"rms_error_worst", "peak_current_worst_a", "worst_run"}]}``.

JSON for one design: ``{"mode", "stable", "verdict", "evidence", "metrics", "warnings",
"omitted", ...}``; for several designs: ``{"mode", "warnings", "runs": [{"fn_hz", "gs",
"stable", "verdict", "evidence", "warnings", "metrics", "omitted", ...}]}``.  The time series
``t_s`` and ``position`` are printed with ``--full`` (``--csv FILE`` writes them); without
it ``omitted`` gives their lengths.
``verdict`` is one of settled, not settled, unstable, limit cycle, saturated
(:mod:`seactl.simulate.verdict`; a loop with growing modes, ``evidence.right_half_plane_roots``,
is unstable however slowly they grow: in continuous mode the certified count of
right-half-plane roots, in sampled mode the eigenvalues of the loop's map over a period
outside the unit circle, without saturation and quantization); ``stable`` is
false for unstable and limit cycle.  The top-level
``warnings`` are the lines the table prints after ``warning:``.  In sampled mode each run
also has ``sampled_loop`` (``verdict``, ``unstable_modes``, ``continuous_stable``, ``text``):
the certified verdict of the simulated loop without saturation, printed under the table.
Metrics that do not exist (unstable response, never settled) are ``null``.
"""

from __future__ import annotations

import csv
import functools
import io
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.api.sea import Design
from seactl.base import limits
from seactl.base.limits import check_range
from seactl.base.outputs import CSV_SUFFIXES, FIGURE_SUFFIXES, OutputSet
from seactl.errors import InputError
from seactl.simulate.verdict import STEP_BAND, judge_response

from .common import (
    DesignSpec,
    cli,
    console,
    design_options,
    echo_json,
    finite_or_none,
    full_option,
    sampled_loop_lines,
    series_json,
)
from .loops import loop_options, loop_response

BAD = ("unstable", "limit cycle")
"""Verdicts under which a response is not called stable."""


def _parse_saturation(value: str | None) -> float | None:
    if value is None:
        return None
    if value.strip().lower() in ("none", "inf", "off"):
        return math.inf
    try:
        sat = float(value)
    except ValueError:
        raise InputError("--saturation [A]", value, "a current > 0 or 'none'") from None
    if not (sat > 0) or math.isnan(sat):
        raise InputError("--saturation [A]", value, "a current > 0 or 'none'")
    return sat


def _timing_options(mode: str, latency: tuple[str, ...], loss: tuple[str, ...],
                    runs: int | None, seed: int) -> dict[str, Any] | None:
    """Monte Carlo options, or None when none is given."""
    from seactl.latency.models import parse_latency, parse_link_specs, parse_loss

    if not latency and not loss and runs is None:
        return None
    if mode != "sampled":
        raise InputError("--mode", mode, "'sampled' with --latency, --loss or --runs")
    if runs is not None and not 1 <= runs <= 100_000:
        raise InputError("--runs", runs, "an integer in [1, 100000]")
    return {"latency": parse_link_specs(latency, parse_latency, "--latency"),
            "loss": parse_link_specs(loss, parse_loss, "--loss"),
            "runs": 100 if runs is None else runs, "seed": seed,
            "text": {"latency": dict(x.split("=", 1) for x in latency),
                     "loss": dict(x.split("=", 1) for x in loss)}}


def _monte_carlo(spec: DesignSpec, kind: str, timing: dict[str, Any], outs: OutputSet,
                 plot: Path | None, csv_path: Path | None, as_json: bool, title: str,
                 **kwargs: Any) -> None:
    """Run and print a Monte Carlo over timing realizations (``seactl.latency.montecarlo``)."""
    from seactl.errors import InputError as _IE

    if csv_path:
        raise _IE("--csv", csv_path, "not used with --latency/--loss/--runs (use --json)")
    try:
        mc = spec.designs().monte_carlo(kind, latency=timing["latency"], loss=timing["loss"],
                                        runs=timing["runs"], seed=timing["seed"], **kwargs)
    except _IE as exc:
        if exc.field == "link":
            raise _IE("--latency/--loss link", exc.value, exc.valid) from None
        raise
    rows = [{"fn_hz": f, "gs": g, **r} for (f, g), r in zip(_labels(spec), mc.records())]
    if plot:
        from seactl.apps.plots import response_figure

        pos = mc.result.outputs["q_j"].reshape(mc.runs, len(rows), -1)[:50, 0]
        norm = kwargs.get("amplitude", 1.0) if kind == "step" else 1.0
        fig = response_figure(mc.result.t_s, pos / norm, [f"run {i}" for i in range(len(pos))],
                              title=title, ylabel="joint position" + (" / step" if kind ==
                                                                      "step" else " [rad]"),
                              unstable=[not s for s in mc.stable.reshape(mc.runs, -1)[:50, 0]])
        outs.figure(plot, fig, dpi=110)
    outs.commit()
    if as_json:
        amp = {"amplitude_rad": kwargs["amplitude"]} if kind == "step" else \
            {"impulse_nms": kwargs["amplitude"]}
        echo_json({"mode": "sampled", "kind": kind, **amp, "runs": mc.runs,
                   "seed": timing["seed"], **timing["text"], "designs": rows})
        return
    tab = Table(title=escape(f"{title}: {mc.runs} timing realizations, seed {timing['seed']}"))
    err = "[of step]" if kind == "step" else "[rad]"
    for c in ("f_n [Hz]", "GS", "stable runs [%]", f"RMS error mean {err}",
              f"RMS error worst {err}", "peak |i_m| [A]", "worst run"):
        tab.add_column(escape(c), justify="right")
    for r in rows:
        def fmt(x, spec=".3g"):
            return "none" if x is None else format(x, spec)
        tab.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", f"{100 * r['fraction_stable']:.1f}",
                    fmt(r["rms_error_mean"]), fmt(r["rms_error_worst"]),
                    fmt(r["peak_current_worst_a"], ".2f"), str(r["worst_run"]))
    console.print(tab)
    console.print(escape("RMS error: " + ("q_j/step - 1" if kind == "step" else "q_j")
                         + " over the window, stable runs only; links: " + ", ".join(
                             f"{k} latency {v} ms" for k, v in timing["text"]["latency"].items())
                         + (" " if timing["text"]["loss"] else "") + ", ".join(
                             f"{k} loss {v}" for k, v in timing["text"]["loss"].items())),
                  highlight=False)


def sim_options(func: Callable) -> Callable:
    """Options shared by ``step`` and ``impulse``."""
    opts = [
        click.option("--mode", type=click.Choice(["continuous", "sampled"]),
                     default="continuous", show_default=True,
                     help="Exact-delay continuous loop, or sampled as on the hardware."),
        click.option("--rate", "rate_hz", type=float, default=1000.0, show_default=True,
                     help="Servo rate [Hz] of the controllers (sampled mode)."),
        click.option("--no-zero", is_flag=True,
                     help="Torque derivative on the feedback only (no zero in P_CL)."),
        click.option("--t-end", "t_end", type=float, default=None,
                     help="Simulated time [s] (default 0.5 for steps, 1 for impulses)."),
        click.option("--saturation", default=None,
                     help="Motor current limit [A] in sampled mode (default: the actuator's "
                          "max_current; 'none': no limit)."),
        click.option("--plot", "plot", default=None, metavar="FILE.png|.svg|.pdf",
                     help="Write a figure of the responses (format from the suffix)."),
        click.option("--csv", "csv_path", default=None, metavar="FILE.csv",
                     help="Write the responses as CSV (t_s, one column per design)."),
        click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table."),
        full_option,
        click.option("--latency", "latency", multiple=True, metavar="LINK=MODEL",
                     help="Random latency [ms] of a link (stiffness, damping, torque): 2, "
                          "uniform:LOW:HIGH, exp:SHIFT:MEAN or hist:FILE.csv (a measured "
                          "trace: rows latency_ms or latency_ms,count; sampled mode)."),
        click.option("--loss", "loss", multiple=True, metavar="LINK=P",
                     help="Message loss of a link: a probability or ge:P_GB:P_BG[:BAD[:GOOD]] "
                          "(Gilbert-Elliott); the receiver holds the last value."),
        click.option("--runs", type=int, default=None,
                     help="Monte Carlo realizations per design (default 100 with --latency "
                          "or --loss)."),
        click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
                     help="Seed of the Monte Carlo."),
    ]

    @functools.wraps(func)
    def wrapper(*args, mode, rate_hz, no_zero, t_end, saturation, plot, csv_path, latency,
                loss, runs, seed, **kwargs):
        check_range("--rate [Hz]", rate_hz, "rate_hz")
        if t_end is not None:
            check_range("--t-end [s]", t_end, "t_end_s")
        sat = _parse_saturation(saturation)
        if sat is not None and mode != "sampled":
            raise InputError("--saturation", saturation, "used with --mode sampled only")
        timing = _timing_options(mode, latency, loss, runs, seed)
        with OutputSet() as outs:
            plot_p = outs.add("--plot", plot, FIGURE_SUFFIXES)
            csv_p = outs.add("--csv", csv_path, CSV_SUFFIXES)
            return func(*args, mode=mode, rate_hz=rate_hz, zero=not no_zero, t_end=t_end,
                        saturation=sat, outs=outs, plot=plot_p, csv_path=csv_p,
                        timing=timing, **kwargs)

    for opt in reversed(opts):
        wrapper = opt(wrapper)
    return wrapper


def check_simulation(spec: DesignSpec, mode: str, rate_hz: float, t_end_s: float) -> None:
    """Enough samples to judge the response, and memory and time within the machine's
    (every step recorded, as the library's ``step`` and ``impulse`` record it)."""
    limits.check_simulation(
        spec.fn_hz.size * spec.gs.size, mode, rate_hz, t_end_s,
        [d * 1e-3 for d in (spec.t_tau_ms, spec.t_qs_ms, spec.t_qd_ms)],
        rate_name="--rate [Hz]", t_end_name="--t-end [s]",
        hint="shorten --t-end, lower --rate, or give fewer designs")


SERIES = ("t_s", "position")
"""The long arrays of a response's JSON (printed with ``--full``)."""


def _labels(spec: DesignSpec) -> list[tuple[float, float]]:
    return [(float(f), float(g)) for f in spec.fn_hz for g in spec.gs]


def _metrics_json(m: Any, i: int) -> dict[str, Any]:
    from seactl.simulate.results import StepMetrics

    if isinstance(m, StepMetrics):
        return {"rise_time_s": finite_or_none(m.rise_time_s.flat[i]),
                "overshoot_pct": finite_or_none(m.overshoot_pct.flat[i]),
                "settling_time_s": finite_or_none(m.settling_time_s.flat[i]),
                "steady_state_error": finite_or_none(m.steady_state_error.flat[i])}
    return {"peak_deviation_rad": finite_or_none(m.peak_deviation.flat[i]),
            "peak_deviation_deg": finite_or_none(np.degrees(m.peak_deviation.flat[i])),
            "peak_time_s": finite_or_none(m.peak_time_s.flat[i]),
            "recovery_time_s": finite_or_none(m.recovery_time_s.flat[i]),
            "recovery_band": m.band}


def _right_roots(spec: DesignSpec, mode: str, zero: bool) -> np.ndarray | None:
    """The simulated loop's certified count of unstable closed-loop roots (continuous
    mode: the same exact-delay loop); ``None`` in sampled mode, whose simulation counts its
    own growing modes (:func:`seactl.simulate.verdict.judge_response` reads them)."""
    if mode != "continuous":
        return None
    from seactl.systems.sea.views import sea_right_roots

    return sea_right_roots(spec.designs().sea, zero)


def _output(spec: DesignSpec, resp: Any, mode: str, zero: bool, extra: dict[str, Any],
            outs: OutputSet, plot: Path | None, csv_path: Path | None, as_json: bool,
            title: str, ylabel: str) -> None:
    from seactl.apps.plots import response_figure

    res, m = resp.result, resp.metrics
    labels = _labels(spec)
    # metrics and verdicts from every step (the library's); the curves printed every
    # RECORD_DT_S in continuous mode
    every = max(1, round(limits.RECORD_DT_S / res.info["dt_s"])) if mode == "continuous" else 1
    pos = resp.position.reshape(len(labels), -1)[:, ::every]
    cur_all = (resp.current_a if hasattr(resp, "current_a") else resp.current
               ).reshape(len(labels), -1)
    cur = cur_all[:, ::every]
    stable = res.stable.reshape(-1)
    left = res.left_bounds_s.reshape(-1)
    t = res.t_s[::every]
    names = [f"fn={f:g}Hz gs={g:g}" for f, g in labels]
    if csv_path:
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(["t_s"] + names)
        for k in range(t.size):
            w.writerow([f"{t[k]:.9g}"] + [f"{pos[i, k]:.9g}" for i in range(len(labels))])
        outs.write(csv_path, buf.getvalue())
    if plot:
        fig = response_figure(t, pos, names, title=title, ylabel=ylabel,
                              current=cur if mode == "sampled" else None,
                              unstable=[not s for s in stable])
        outs.figure(plot, fig, dpi=110)
    outs.commit()
    verdict = judge_response(resp, STEP_BAND if resp.kind == "step" else m.band,
                             _right_roots(spec, mode, zero))
    runs = []
    for i, (f, g) in enumerate(labels):
        runs.append({"fn_hz": f, "gs": g, "position": [round(float(x), 9) for x in pos[i]],
                     "stable": bool(stable[i]) and verdict.verdict[i] not in BAD,
                     "verdict": verdict.verdict[i], "evidence": verdict.evidence(i),
                     "warnings": verdict.warnings[i],
                     "left_bounds_s": finite_or_none(left[i]),
                     "peak_current_a": finite_or_none(np.max(np.abs(cur_all[i]))),
                     "metrics": _metrics_json(m, i)})
    loop_lines = _sampled_loop(spec, res, runs, zero)
    warnings = [f"f_n={r['fn_hz']:g} Hz, GS={r['gs']:g}: {w}" for r in runs
                for w in r["warnings"]] + _notes(spec, mode, extra)
    common = {"mode": mode, "zero": zero, **extra, "warnings": warnings}
    if as_json:
        t_list = [round(float(x), 9) for x in t]
        if len(runs) == 1:
            one = {k: v for k, v in runs[0].items() if k != "warnings"}
            echo_json(series_json({**common, "t_s": t_list, **one}, SERIES))
        else:
            echo_json(series_json({**common, "t_s": t_list, "runs": runs}, SERIES))
        return
    tab = Table(title=escape(title))
    step = resp.kind == "step"
    cols = ["f_n [Hz]", "GS", "verdict"] + (
        ["rise [ms]", "overshoot [%]", "settling 2% [ms]", "ss error [of step]"] if step else
        ["peak [deg]", "peak at [ms]", f"recovery {m.band:.0%} [ms]"]) + ["peak |i_m| [A]"]
    for c in cols:
        tab.add_column(escape(c), justify="right")

    def ms(x: float | None) -> str:
        return "none" if x is None else f"{1e3 * x:.1f}"

    for r in runs:
        mt = r["metrics"]
        st = r["verdict"] if r["verdict"] == "settled" else f"[red]{r['verdict']}[/red]"
        vals = ([ms(mt["rise_time_s"]), "none" if mt["overshoot_pct"] is None else
                 f"{mt['overshoot_pct']:.2f}", ms(mt["settling_time_s"]),
                 "none" if mt["steady_state_error"] is None else
                 f"{mt['steady_state_error']:.2e}"] if step else
                ["none" if mt["peak_deviation_deg"] is None else f"{mt['peak_deviation_deg']:.3f}",
                 ms(mt["peak_time_s"]), ms(mt["recovery_time_s"])])
        tab.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", st, *vals,
                    "none" if r["peak_current_a"] is None else f"{r['peak_current_a']:.2f}")
    console.print(tab)
    req, eff = extra.get("requested_delays_ms", {}), extra.get("effective_delays_ms", {})
    if eff and mode == "sampled":
        console.print(escape(
            f"delays [ms], requested -> simulated at {extra['rate_hz']:g} Hz (T_s/2 + whole "
            "samples, never shorter): " + ", ".join(f"{k} {req.get(k, v):g} -> {v:g}"
                                                    for k, v in eff.items())), highlight=False)
    elif eff:
        console.print(escape("delays [ms] (exact): " + ", ".join(
            f"{k} {v:g}" for k, v in eff.items())), highlight=False)
    for line in loop_lines:
        console.print(escape(f"sampled loop: {line}"), highlight=False)
    for w in warnings:
        console.print(escape(f"warning: {w}"), highlight=False)


def _sampled_loop(spec: DesignSpec, res: Any, runs: list[dict[str, Any]], zero: bool
                  ) -> list[str]:
    """Sampled mode: the loop's certified verdict beside each run (``"sampled_loop"``)
    and the lines the table prints (:func:`.common.sampled_loop_lines`)."""
    if "sampled_verdict" not in res.info:
        return []
    from seactl.systems.sea.views import sea_right_roots

    return sampled_loop_lines(res.info, runs, sea_right_roots(spec.designs().sea, zero),
                              [f"f_n={r['fn_hz']:g} Hz, GS={r['gs']:g}" for r in runs])


def _notes(spec: DesignSpec, mode: str, extra: dict[str, Any]) -> list[str]:
    """Warnings that apply to the whole command (printed and in JSON alike)."""
    notes = []
    req, eff = extra.get("requested_delays_ms", {}), extra.get("effective_delays_ms", {})
    if mode == "sampled" and (spec.f_qd_hz is None or spec.f_taud_hz is None):
        notes.append("an unfiltered derivative discretized with Tustin rings at the Nyquist "
                     "frequency (pole at z = -1); give --f-qd and --f-taud for a realistic "
                     "sampled controller")
    if mode == "sampled" and eff:
        off = [f"{k} {req[k]:g} -> {v:g}" for k, v in eff.items()
               if k in req and abs(req[k] - v) > 1e-9]
        if off:
            notes.append("at this rate the whole-sample buffers lengthen delays to the next "
                         "realizable T_s/2 + n T_s: " + ", ".join(off) + " ms")
    return notes


def _delays_ms(res: Any, key: str) -> dict[str, float]:
    """Per SEA loop (torque, stiffness, damping), the largest delay of the batch [ms]."""
    from seactl.latency.montecarlo import SEA_LINKS

    info = res.info.get(key, {})
    return {loop: round(float(np.max(info[b])) * 1e3, 9) for loop, b in SEA_LINKS.items()
            if b in info}


def _extra(res: Any, mode: str, rate_hz: float, saturation: float | None) -> dict[str, Any]:
    out: dict[str, Any] = {"requested_delays_ms": _delays_ms(res, "requested_delays_s"),
                           "effective_delays_ms": _delays_ms(res, "effective_delays_s")}
    if mode == "sampled":
        sat = res.info["saturation"].get("i_m", math.inf)
        out.update({"rate_hz": rate_hz, "saturation_a": finite_or_none(sat)})
    else:
        out["dt_s"] = res.info["dt_s"]
    return out


@cli.command()
@design_options
@click.option("--amplitude", type=float, default=Design.default_step, show_default=True,
              help=f"Step size [{Design.step_unit}] (responses are normalized by it; it matters "
                   "only with saturation).")
@sim_options
@loop_options
def step(spec: DesignSpec, amplitude: float, mode: str, rate_hz: float, zero: bool,
         t_end: float | None, saturation: float | None, outs: OutputSet,
         plot: Path | None, csv_path: Path | None, as_json: bool,
         timing: dict[str, Any] | None, loop: Any) -> None:
    """Step response of the joint position to a position reference step.

    Python: sc.design(...).step(amplitude=...) (default step: sc.Design.default_step).

    \b
    Example (the paper's Fig. ExperimentGS conditions):
      seactl step --fn 14 --t-tau 1 --t-qs 1 --t-qd 1 --f-qd 50 --f-taud 100 --gs 2 \\
          --mode sampled --plot s.png
    """
    check_range("--amplitude [rad]", abs(amplitude), "amplitude_rad")
    check_simulation(spec, mode, rate_hz, t_end or 0.5)
    if loop is not None:  # without --amplitude: the loop's default step (its file's)
        given = click.get_current_context().get_parameter_source("amplitude") \
            != click.core.ParameterSource.DEFAULT
        return loop_response(loop, "step", mode, t_end or 0.5, amplitude if given else None,
                             as_json, outs, plot, csv_path)
    if timing is not None:
        return _monte_carlo(spec, "step", timing, outs, plot, csv_path, as_json,
                            f"Step response to {amplitude:g} {Design.step_unit} (sampled, "
                            f"{rate_hz:g} Hz)", rate_hz=rate_hz,
                            t_end_s=t_end or 0.5, zero=zero, saturation_a=saturation,
                            amplitude=amplitude)
    resp = spec.designs().step(t_end_s=t_end or 0.5, amplitude=amplitude, mode=mode,
                               rate_hz=rate_hz, saturation_a=saturation, zero=zero)
    extra = _extra(resp.result, mode, rate_hz, saturation) | {"amplitude_rad": amplitude}
    title = (f"Step response to {amplitude:g} {Design.step_unit} ({mode}"
             f"{f', {rate_hz:g} Hz' if mode == 'sampled' else ''}, "
             f"{'with' if zero else 'without'} the torque-derivative zero)")
    _output(spec, resp, mode, zero, extra, outs, plot, csv_path, as_json, title,
            "joint position / step size")


@cli.command()
@design_options
@click.option("--impulse", "impulse_nms", type=float, default=0.05, show_default=True,
              help="Angular impulse of external torque on the joint [N m s] at t = 0.")
@click.option("--band", type=float, default=0.05, show_default=True,
              help="Recovery band, as a fraction of the peak deviation.")
@sim_options
@loop_options
def impulse(spec: DesignSpec, impulse_nms: float, band: float, mode: str, rate_hz: float,
            zero: bool, t_end: float | None, saturation: float | None, outs: OutputSet,
            plot: Path | None, csv_path: Path | None, as_json: bool,
            timing: dict[str, Any] | None, loop: Any) -> None:
    """Joint position after an impulse of external torque (q_des = 0), e.g. a ball hitting
    the arm (Fig. ExperimentImpulse). Position in rad; recovery = last exit from the band.

    Python: sc.design(...).impulse().

    \b
    Example:
      seactl impulse --fn 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100 \\
          --mode sampled --plot i.png
    """
    from seactl.systems.sea.views import sea_impulse

    if not (0 < band < 1):
        raise InputError("--band", band, "a fraction in (0, 1)")
    check_range("--impulse [N m s]", abs(impulse_nms), "impulse_nms")
    check_simulation(spec, mode, rate_hz, t_end or 1.0)
    if loop is not None:
        return loop_response(loop, "impulse", mode, t_end or 1.0, impulse_nms, as_json, outs,
                             plot, csv_path, band=band)
    if timing is not None:
        return _monte_carlo(spec, "impulse", timing, outs, plot, csv_path, as_json,
                            f"Impulse response, {impulse_nms:g} N m s (sampled, {rate_hz:g} Hz)",
                            rate_hz=rate_hz, t_end_s=t_end or 1.0, zero=zero,
                            saturation_a=saturation, amplitude=impulse_nms)
    # Design.impulse has no band keyword (the recovery band): the core call it makes
    design = spec.designs().sea
    resp = sea_impulse(design, impulse_nms=impulse_nms, zero=zero, mode=mode, rate_hz=rate_hz,
                       t_end_s=t_end or 1.0, saturation_a=saturation, band=band)
    extra = _extra(resp.result, mode, rate_hz, saturation) | {"impulse_nms": impulse_nms}
    title = (f"Impulse response, {impulse_nms:g} N m s ({mode}"
             f"{f', {rate_hz:g} Hz' if mode == 'sampled' else ''})")
    _output(spec, resp, mode, zero, extra, outs, plot, csv_path, as_json, title,
            "joint position [rad]")
