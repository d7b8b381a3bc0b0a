"""``seactl analyze --loop FILE`` and the ``--loop``/``--set`` options of ``impedance``,
``step``, ``impulse`` and ``place``: every view on a user-defined loop file.

``--set NAME=VALUE`` overrides a design variable or parameter of the file; a value may be a
range ``START:STOP:STEP`` (or ``a,b,c``), and each ranged ``--set`` is one axis of a design
batch (their outer product), so ``analyze --set fn=10:40:2`` is a sweep over ``fn``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.errors import InputError

from .common import (
    IMPEDANCE_SERIES,
    cli,
    console,
    echo_json,
    finite_or_none,
    parse_values,
    sampled_loop_lines,
    series_json,
)


def parse_sets(tokens: tuple[str, ...]) -> dict[str, Any]:
    """``NAME=VALUE`` tokens -> values; each multi-valued one gets its own batch axis."""
    out: dict[str, Any] = {}
    ranged = []
    for tok in tokens:
        name, sep, val = tok.partition("=")
        if not sep or not name.strip():
            raise InputError("--set", tok, "NAME=VALUE (a number, a,b,c or START:STOP:STEP)")
        vals = parse_values(f"--set {name.strip()}", [val])
        if vals.size == 0:
            raise InputError(f"--set {name.strip()}", val, "at least one value")
        out[name.strip()] = vals
        if vals.size > 1:
            ranged.append(name.strip())
    for i, name in enumerate(ranged):
        out[name] = out[name].reshape((-1,) + (1,) * (len(ranged) - 1 - i))
    return {k: (float(v[0]) if v.size == 1 else v) for k, v in out.items()}


def load(path: str, sets: tuple[str, ...]):
    from seactl.api.loopbuilder import load_loop
    from seactl.base.limits import BYTES_PER_DESIGN, check_budget

    values = parse_sets(sets)
    n = int(np.prod([np.size(v) for v in values.values()], dtype=float)) if values else 1
    check_budget(f"{n:,} designs of the loop", n_bytes=n * BYTES_PER_DESIGN,
                 hint="give fewer --set values (or use seactl sweep --loop, in chunks)")
    return load_loop(path, **values)


def loop_options(func: Callable) -> Callable:
    """Add ``--loop FILE`` and ``--set NAME=VALUE``; the command receives ``loop`` (a
    :class:`~seactl.UserLoop` or None)."""

    @functools.wraps(func)
    def wrapper(*args, loop_file, sets, **kwargs):
        if sets and not loop_file:
            raise InputError("--set", sets[0], "used with --loop FILE or --dde FILE")
        if loop_file:
            _refuse_sea_options()
        return func(*args, loop=load(loop_file, sets) if loop_file else None, **kwargs)

    wrapper = click.option("--set", "sets", multiple=True, metavar="NAME=VALUE",
                           help="Override a variable or parameter of the --loop file "
                                "(VALUE: number, a,b,c or START:STOP:STEP).")(wrapper)
    return click.option("--loop", "loop_file", default=None, metavar="FILE.toml",
                        type=click.Path(dir_okay=False),
                        help="A loop file (docs/loops.md) instead of the built-in SEA "
                             "design options.")(wrapper)


LOOP_OPTIONS: dict[str, frozenset[str]] = {
    "step": frozenset({"amplitude", "mode", "t_end", "plot", "csv_path", "as_json", "full"}),
    "impulse": frozenset({"impulse_nms", "band", "mode", "t_end", "plot", "csv_path",
                          "as_json", "full"}),
    "impedance": frozenset({"freq", "port", "plot", "csv", "as_json", "full"}),
    "export": frozenset({"out", "lang", "rates_hz", "emulate_latency", "real", "verify", "cc",
                         "as_json"}),
    "run": frozenset({"rates_hz", "duration", "step", "extra_latency", "loss", "seed",
                      "transport", "realtime", "latency", "out", "as_json"}),
    "place": frozenset({"as_json"}),
    "jitter": frozenset({"as_json"}),
    "roots": frozenset({"count", "as_json"}),
    "delay-margin": frozenset({"direction", "as_json"}),
    "chart": frozenset({"delays", "max_s", "max_ms", "resolution", "plot", "as_json"}),
}
"""Per command, the options (click parameter names) that apply to a loop file; every other
option of the command describes a built-in loop (its design, actuator, rate, Monte Carlo)
and is refused with ``--loop``."""


def _refuse_sea_options() -> None:
    """Refuse, in one line, an option the user gave (on the command line, not by default)
    that does not apply to a loop file (:data:`LOOP_OPTIONS`)."""
    from click.core import ParameterSource

    ctx = click.get_current_context()
    applies = LOOP_OPTIONS.get(ctx.command.name or "", frozenset()) | {"loop_file", "sets"}
    for p in ctx.command.params:
        if p.name not in applies and ctx.get_parameter_source(p.name) in (
                ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT):
            raise InputError(max(p.opts, key=len), "given", "absent with --loop (the loop "
                             "file defines the structure, its values and each process's "
                             "rate; override them with --set)")


def _varied(loop: Any) -> dict[str, np.ndarray]:
    """The variables set to several values, broadcast to the batch shape."""
    return {k: np.broadcast_to(np.asarray(v, float), loop.shape)
            for k, v in loop.values.items() if np.size(v) > 1}


def _labels(loop: Any) -> list[dict[str, float]]:
    varied = _varied(loop)
    n = int(np.prod(loop.shape, dtype=int))
    return [{k: float(v.reshape(-1)[i]) for k, v in varied.items()} for i in range(n)]


def _item(x: Any, i: int) -> float | None:
    return finite_or_none(np.asarray(x).reshape(-1)[i])


def _fmt(x: Any, spec: str) -> str:
    return "none" if x is None else format(x, spec)


@cli.command()
@click.option("--loop", "loop_file", required=True, metavar="FILE.toml",
              type=click.Path(dir_okay=False), help="The loop file (docs/loops.md).")
@click.option("--set", "sets", multiple=True, metavar="NAME=VALUE",
              help="Override a variable or parameter (VALUE: number, a,b,c or "
                   "START:STOP:STEP; ranges make a sweep).")
@click.option("--no-jitter", is_flag=True, help="Skip the jitter margins.")
@click.option("--plot", "plot", default=None, metavar="FILE.png|.svg|.pdf",
              help="Write a Bode plot of the loop at every break.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def analyze(loop_file: str, sets: tuple[str, ...], no_jitter: bool, plot: str | None,
            as_json: bool) -> None:
    """Margins at every named break of a loop file, delay and jitter margins per loop,
    stability of the whole loop.

    Python: sc.load_loop(FILE).analyze().

    \b
    Example (the paper's Table I loop at f_n = 14 Hz, written as a loop file):
      seactl analyze --loop examples/loops/paper-sea.toml
      seactl analyze --loop examples/loops/rigid.toml --set fn=4:16:2
    """
    from seactl.base.outputs import FIGURE_SUFFIXES, OutputSet

    with OutputSet() as outs:
        plot_p = outs.add("--plot", plot, FIGURE_SUFFIXES)
        loop = load(loop_file, sets)
        a = loop.analyze(jitter=not no_jitter)
        if plot_p:
            outs.figure(plot_p, _bode(loop, a))
        outs.commit()
    labels = _labels(loop)
    rows = []
    for i, lab in enumerate(labels):
        for b in a.breaks:
            m = b.margins
            g = functools.partial(_item, i=i)
            rows.append({**lab, "break": b.name, "signal": b.signal,
                         "phase_margin_deg": g(m.phase_margin_deg),
                         "crossover_hz": g(m.crossover_hz),
                         "gain_margin_db": g(m.gain_margin_db),
                         "phase_crossover_hz": g(m.phase_crossover_hz),
                         "delay_margin_ms": g(m.delay_margin_ms),
                         "jitter_margin_ms": None if no_jitter else g(b.jitter_margin_s * 1e3),
                         "stable": bool(np.asarray(a.stable).reshape(-1)[i])})
    if as_json:
        echo_json({"loop": loop.name, "file": loop_file, "set": {k: np.asarray(v).ravel()
                                                                   .tolist() for k, v in
                                                                   loop.values.items()},
                   "rows": rows})
        return
    t = Table(title=escape(f"Loop '{loop.name}' ({loop_file}): margins at each break, "
                           "other loops closed"))
    varied = list(_varied(loop))
    for c in [*varied, "break", "signal", "PM [deg]", "crossover [Hz]", "GM [dB]",
              "DM [ms]", "jitter [ms]", "stable"]:
        t.add_column(escape(c), justify="left" if c in ("break", "signal") else "right")
    for r in rows:
        t.add_row(*[f"{r[k]:g}" for k in varied], r["break"], r["signal"],
                  _fmt(r["phase_margin_deg"], ".2f"), _fmt(r["crossover_hz"], ".2f"),
                  _fmt(r["gain_margin_db"], ".2f"), _fmt(r["delay_margin_ms"], ".3f"),
                  "0 (not proven)" if r["stable"] and r["jitter_margin_ms"] == 0 else
                  _fmt(r["jitter_margin_ms"], ".3f"), "yes" if r["stable"] else "[red]NO[/red]")
    console.print(t)
    console.print("DM: extra latency at the break that destabilizes; jitter: Kao-Lincoln "
                  "bound on a time-varying extra delay there; 'none': no such crossing.",
                  highlight=False)


def _write_outputs(outs: Any, plot: Any, csv_path: Any, fig_fn: Callable[[], Any],
                   header: list[str], rows: list[list[Any]]) -> None:
    """Plot and CSV files of a loop view, through the command's output set."""
    if csv_path:
        lines = [",".join(header)]
        lines += [",".join(f"{x:.10g}" if isinstance(x, float) else str(x) for x in r)
                  for r in rows]
        outs.write(csv_path, "\n".join(lines) + "\n")
    if plot:
        outs.figure(plot, fig_fn())
    outs.commit()


def _bode(loop: Any, a: Any):
    """Bode figure of every break's loop transfer (one curve per design, up to 12)."""
    from seactl.apps.plots import loop_bode_figure
    from seactl.base.limits import FREQ_BYTES_PER_POINT, check_budget

    n = int(np.prod(loop.shape, dtype=float))
    check_budget(f"a Bode plot of {n:,} design(s)", n_bytes=n * 600 * FREQ_BYTES_PER_POINT,
                 hint="give fewer --set values with --plot (it draws the first 12)")
    om = loop.grid()
    f = np.logspace(np.log10(om[0] / (2 * np.pi)), np.log10(om[-1] / (2 * np.pi)), 600)
    labels = _labels(loop)[:12]
    names = [" ".join(f"{k}={v:g}" for k, v in lab.items()) for lab in labels]
    cols = []
    for b in a.breaks:
        L = loop.loop_transfer(b.name)(loop.design, 2j * np.pi * f).reshape(-1, f.size)
        fc = np.asarray(b.margins.crossover_hz).reshape(-1)[:12]
        cols.append((f"break '{b.name}' ({b.signal})", list(zip(names, L[:12])),
                     [float(x) for x in fc if np.isfinite(x)]))
    return loop_bode_figure(f, cols, suptitle=f"loop '{loop.name}': L at each break, other "
                            "loops closed")


def loop_impedance(loop: Any, f: np.ndarray, port: str | None, as_json: bool, outs: Any,
                   plot: Any = None, csv_path: Any = None) -> None:
    """``seactl impedance --loop``: Z at a port over ``f``."""
    from seactl.base.limits import FREQ_BYTES_PER_POINT, check_budget

    n = int(np.prod(loop.shape, dtype=float))
    check_budget(f"{n:,} design(s) of the loop at {f.size:,} frequencies",
                 n_bytes=n * f.size * FREQ_BYTES_PER_POINT,
                 hint="give fewer --freq points or fewer --set values")
    res = loop.impedance(f, port=port)
    name = res.port
    labels = _labels(loop)
    zf = res.z.reshape(len(labels), f.size)
    phase = np.reshape(res.phase_deg, zf.shape)
    names = [" ".join(f"{k}={v:g}" for k, v in lab.items()) or loop.name for lab in labels]

    def fig():
        from seactl.apps.plots import impedance_bode_figure

        curves = [{"f": f, "z": zf[i], "label": names[i]} for i in range(len(labels))]
        return impedance_bode_figure([(f"{loop.name}: port {name}", curves)], unit="SI")

    _write_outputs(outs, plot, csv_path, fig, ["design", "f_hz", "re", "im", "magnitude",
                                         "phase_deg"],
                   [[names[i], float(fk), float(zf[i, k].real), float(zf[i, k].imag),
                     float(abs(zf[i, k])), float(phase[i, k])]
                    for i in range(len(labels)) for k, fk in enumerate(f)])
    stable = loop.margins().stable if loop.breaks else None
    out = []
    for i, lab in enumerate(labels):
        out.append({**lab, "loop": loop.name, "port": name, "f_hz": f.tolist(),
                    "magnitude": [finite_or_none(x) for x in np.abs(zf[i])],
                    "magnitude_db": [finite_or_none(x) for x in 20 * np.log10(np.abs(zf[i]))],
                    "phase_deg": [finite_or_none(x) for x in phase[i]],
                    "real": [finite_or_none(x) for x in zf[i].real],
                    "stable": None if stable is None else bool(np.asarray(stable)
                                                                .reshape(-1)[i])})
    if as_json:
        echo_json(series_json(out[0] if len(out) == 1 else out, IMPEDANCE_SERIES))
        return
    for r in out:
        t = Table(title=escape(f"Impedance of loop '{loop.name}' at port '{name}' "
                               + " ".join(f"{k}={v:g}" for k, v in r.items()
                                          if isinstance(v, float))))
        for c in ("f [Hz]", "|Z| [SI]", "|Z| [dB re 1 SI]", "phase [deg]", "Re Z [SI]"):
            t.add_column(escape(c), justify="right")
        step = max(1, f.size // 25)
        for k in range(0, f.size, step):
            t.add_row(f"{f[k]:.4g}", f"{r['magnitude'][k]:.5g}", f"{r['magnitude_db'][k]:.2f}",
                      f"{r['phase_deg'][k]:.2f}", f"{r['real'][k]:.4g}")
        console.print(t)


METRIC_HEADERS = {"rise_time_s": "rise [s]", "overshoot_pct": "overshoot [%]",
                  "settling_time_s": "settling [s]", "steady_state_error": "ss error [of step]",
                  "peak_deviation": "peak deviation [output's unit]",
                  "peak_time_s": "peak at [s]", "recovery_time_s": "recovery [s]"}
"""Table headers, with units, of a loop response's metrics."""


def loop_response(loop: Any, kind: str, mode: str, t_end: float, size: float | None,
                  as_json: bool, outs: Any, plot: Any = None, csv_path: Any = None,
                  band: float | None = None) -> None:
    """``seactl step|impulse --loop``: :meth:`seactl.UserLoop.step` or ``impulse`` (each
    process at its rate in sampled mode); ``size`` None: the loop's default step or
    impulse; ``band``: the impulse's recovery band (default 0.05)."""
    from seactl.base import limits

    delays = [float(np.max(v)) for k, v in loop.design._arrays.items() if k.endswith("__T")]
    limits.check_simulation(int(np.prod(loop.shape, dtype=int)), mode,
                            max(p.rate_hz for p in loop.processes.values()), t_end, delays,
                            record_dt_s=5e-4, t_end_name="--t-end [s]",
                            rate_name="rate_hz (the loop file's fastest process)",
                            hint="shorten --t-end or give fewer --set values")
    rec = 5e-4 if mode == "continuous" else None
    if kind == "step":
        res = loop.step(t_end_s=t_end, mode=mode, amplitude=size, record_dt=rec)
        keys = ("rise_time_s", "overshoot_pct", "settling_time_s", "steady_state_error")
    else:
        res = loop.impulse(t_end_s=t_end, mode=mode, amplitude=size, record_dt=rec, band=band)
        keys = ("peak_deviation", "peak_time_s", "recovery_time_s")
    out_name, size = res.output, res.amplitude
    y = res.outputs[out_name]
    m = res.metrics
    labels = _labels(loop)
    yf = y.reshape(len(labels), -1)
    names = [" ".join(f"{k}={v:g}" for k, v in lab.items()) or loop.name for lab in labels]

    def fig():
        from seactl.apps.plots import response_figure

        return response_figure(res.t_s, yf, names, title=f"{loop.name}: {kind} ({mode})",
                               ylabel=out_name,
                               unstable=[not s for s in res.stable.reshape(-1)])

    _write_outputs(outs, plot, csv_path, fig, ["t_s", *names],
                   [[float(t), *map(float, yf[:, k])] for k, t in enumerate(res.t_s)])
    req, eff = ({k: np.asarray(v).reshape(-1).tolist() for k, v in d.items()}
                for d in (res.requested_delays_s, res.effective_delays_s))
    v = res.verdict(band)
    runs = [{**lab, "stable": bool(res.stable.reshape(-1)[i])
             and v.verdict[i] not in ("unstable", "limit cycle"),
             "verdict": v.verdict[i], "evidence": v.evidence(i), "warnings": v.warnings[i],
             "metrics": {k: finite_or_none(np.asarray(getattr(m, k)).reshape(-1)[i])
                         for k in keys},
             out_name: [round(float(v), 12) for v in yf[i]]} for i, lab in enumerate(labels)]
    lines = sampled_loop_lines(res.info, runs, loop.roots(count=1).right_half_plane_roots,
                               names) if "sampled_verdict" in res.info else []
    warnings = [(" ".join(f"{k}={x:g}" for k, x in lab.items()) + ": " if lab else "") + w
                for lab, r in zip(labels, runs) for w in r["warnings"]]
    common = {"loop": loop.name, "mode": mode, "output": out_name, kind == "step" and
              "amplitude" or "area": size, "step_unit": loop.step_unit,
              "requested_delays_s": req, "effective_delays_s": eff,
              "rates_hz": res.info.get("rates_hz"), "warnings": warnings}
    if kind != "step":
        del common["step_unit"]
    if as_json:
        t = [round(float(v), 9) for v in res.t_s]
        one = {k: x for k, x in runs[0].items() if k != "warnings"}
        echo_json(series_json({**common, "t_s": t, **one} if len(runs) == 1 else
                              {**common, "t_s": t, "runs": runs}, ("t_s", out_name)))
        return
    amp = f", step {size:g} {loop.step_unit}" if kind == "step" else f", area {size:g}"
    tab = Table(title=escape(f"{kind.capitalize()} response of loop '{loop.name}' "
                             f"({mode}{amp}), output {out_name}"))
    varied = list(_varied(loop))
    for c in [*varied, "verdict", *(METRIC_HEADERS[k] for k in keys)]:
        tab.add_column(escape(c), justify="right")
    for r in runs:
        tab.add_row(*[f"{r[k]:g}" for k in varied],
                    r["verdict"] if r["verdict"] == "settled" else f"[red]{r['verdict']}[/red]",
                    *[_fmt(r["metrics"][k], ".4g") for k in keys])
    console.print(tab)
    if mode == "sampled" and eff:
        console.print(escape("delays [ms], requested -> simulated (T_s/2 + whole samples, "
                             "never shorter): " + "; ".join(
                                 f"{k} {_ms_list(req.get(k, v))} -> {_ms_list(v)}"
                                 for k, v in eff.items())), highlight=False)
    for line in lines:
        console.print(escape(f"sampled loop: {line}"), highlight=False)
    for w in warnings:
        console.print(escape(f"warning: {w}"), highlight=False)


def _ms_list(delays_s: list[float]) -> str:
    """Delays [s] of a batch as milliseconds, each distinct value once."""
    return ", ".join(f"{1e3 * x:g}" for x in dict.fromkeys(delays_s))


def loop_place(loop: Any, as_json: bool) -> None:
    """``seactl place --loop``: every placement of the movable blocks, ranked."""
    p = loop.placements()
    rows = p.records()
    if as_json:
        echo_json({"loop": loop.name, "latency_ms": p.latency_ms, "options": rows})
        return
    t = Table(title=escape(f"Placements of loop '{loop.name}' (latency: " + ", ".join(
        f"{k} {v:g} ms" for k, v in p.latency_ms.items()) + "); best first"))
    names = [b.name for b in p.analysis.breaks]
    for c in ["#", *p.blocks, "stable", *[f"PM {n} [deg]" for n in names],
              *[f"DM {n} [ms]" for n in names]]:
        t.add_column(escape(c), justify="right")
    for r in rows:
        t.add_row(str(r["rank"]), *[r["placement"][b] for b in p.blocks],
                  "yes" if r["stable"] else "[red]NO[/red]",
                  *[_fmt(r[n]["phase_margin_deg"], ".2f") for n in names],
                  *[_fmt(r[n]["delay_margin_ms"], ".3f") for n in names])
    console.print(t)
