"""``seactl run``: the exported controllers as real OS processes over UDP on loopback.

JSON: the run's summary ``{"transport", "duration_s", "ticks", "rates_hz",
"extra_latency_ms", "loss", "dropped", "links": {LINK: {"count", "mean_ms", "p50_ms",
"p99_ms", "max_ms", "jitter_ms"}}, "late_commands", "tracking_rms", "replay_max_diff",
"nominal_max_diff", "final_value", "plant"}`` (with ``--plant mujoco`` also
``"plant_timestep_s"`` and ``"prediction_band"``: ``{"verdict", "within", "runs",
"ticks_outside", "max_outside", "t_worst_s", "max_width", "tolerance", "latency"}``) plus
``"files"``; with ``--realtime``, ``"mode": "realtime"``, ``"processes"``, ``"links"`` with
counts and timing, ``"missed_deadlines"``, ``"lost"``, ``"watchdog_events"`` and
``"prediction_band"``; SEA and rigid: ``"latency_check"``: ``{LOOP: {"count", "min_ms",
"p1_ms", "mean_ms", "p99_ms", "max_ms", "spread_ms", "spread_p99_p1_ms",
"design_delay_ms", "jitter_margin_ms", "sampled_jitter_margin_ms", "sampled_rate_hz",
"delay_limit_ms", "within", "verdict"}}`` (docs/export.md).
"""

from __future__ import annotations

import math
from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from seactl.api.rigid import RigidBatch
from seactl.api.sea import Design
from seactl.errors import InputError

from .common import DesignSpec, cli, console, design_options, echo_json, json_option
from .export import SystemChoice, system_options
from .loops import loop_options


def _float(name: str, text: str, lo: float, hi: float) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(name, text, f"a number in [{lo:g}, {hi:g}]") from None
    if not (math.isfinite(v) and lo <= v <= hi):
        raise InputError(name, text, f"a number in [{lo:g}, {hi:g}]")
    return v


@cli.command("run")
@design_options
@loop_options
@system_options
@click.option("--duration", default="2", show_default=True, help="Run time [s] (0.1 to 60).")
@click.option("--step", "step", default=None,
              help=f"Step of the reference: q_des [{Design.step_unit}] (SEA, default "
                   f"{Design.default_step:g}) or x_des [{RigidBatch.step_unit}] (rigid, default "
                   f"{RigidBatch.default_step:g}); --loop: the file's reference_step, else 0.01.")
@click.option("--extra-latency", default="0", show_default=True,
              help="Latency added to the high-level -> embedded link [ms].")
@click.option("--loss", default="0", show_default=True,
              help="Probability of losing a high-level -> embedded message.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the loss (an integer >= 0).")
@click.option("--transport", type=click.Choice(["zenoh", "udp"]), default="zenoh",
              show_default=True, help="Message transport (loopback only).")
@click.option("--plant", type=click.Choice(["builtin", "mujoco"]), default="builtin",
              show_default=True, help="The plant process: the exact linear plant, or the "
              "actuator's MuJoCo model (pip install 'seactl[sim]'; SEA and rigid only).")
@click.option("--latency", "latency", multiple=True, metavar="LOOP=MODEL",
              help="--plant mujoco or --realtime: latency model of a loop for the "
                   "prediction band, in ms "
                   "(e.g. stiffness=uniform:1:3; --loop: a delayed block, e.g. K_fb=1.5; "
                   "repeatable); default: the run's measured latency.")
@click.option("--realtime", is_flag=True,
              help="Free-running processes, each on its own clock, running the exported C "
                   "(default: lock-step, the exact replay check).")
@click.option("--out", default=None, type=click.Path(file_okay=False),
              help="New or empty directory for summary.json, response.csv, latency-*.csv.")
@json_option
def run(spec: DesignSpec, loop: Any, system: SystemChoice, duration: str, step: str | None,
        extra_latency: str, loss: str, seed: int, transport: str, plant: str,
        latency: tuple[str, ...], realtime: bool, out: str | None, as_json: bool) -> None:
    """Run the design's controllers as three processes (plant, embedded, high-level).

    Python: sc.design(...).run(), sc.rigid(...).run(), sc.load_loop(...).run().

    \b
    The plant integrates the actuator at the fastest rate; the embedded and high-level
    processes run the exported Python controllers; messages go over Zenoh (or UDP) on
    127.0.0.1.  Reports each link's measured latency, the tracking error, and the
    response against the sampled simulation replaying the measured link timing.  With
    --plant mujoco, MuJoCo integrates the actuator's model and the measured step is
    judged against the band of sampled responses for the latency (docs/mujoco.md).
      seactl run --fn 14 --t-tau 1 --t-qs 2 --t-qd 1 --f-qd 50 --f-taud 100 --duration 2
      seactl run --system rigid --fn 8 --t-s 1.5 --t-d 1.5 --transport udp
      seactl run --fn 14 --t-qs 2 --f-qd 50 --f-taud 100 --plant mujoco --transport udp

    \b
    --realtime: every process on its own clock at its rate, never waiting for another;
    the controllers are the exported C (compiled with cc); reports period jitter, missed
    deadlines, latency, stale and lost messages and watchdog events.
      seactl run --fn 14 --t-tau 1 --t-qs 2 --t-qd 1 --rate embedded=1000 \\
          --rate high-level=500 --duration 10 --realtime
    """
    from seactl.codegen.export import check_export_dir, write_export
    from seactl.codegen.runtime import RUN_MARKER, run_files

    api, options = _api_system(spec, system, loop, plant)
    unit = api.step_unit
    amplitude = api.default_step if step is None else \
        _float(f"--step [{unit}]", step, 1e-6, 1.0)
    band = _band_latency(plant, latency, realtime)
    if out is not None:
        check_export_dir(out, RUN_MARKER, "a run")
    res = api.run(
        duration_s=_float("--duration [s]", duration, 0.1, 60), amplitude=amplitude,
        extra_latency_s=_float("--extra-latency [ms]", extra_latency, 0, 1000) / 1e3,
        loss=_float("--loss", loss, 0.0, 0.99), seed=seed, transport=transport,
        realtime=realtime, latency=band, **options)
    files = write_export(run_files(res), out, RUN_MARKER, "a run") if out else []
    key = "amplitude" if loop is not None else f"amplitude_{unit}"
    if as_json:
        echo_json(res.summary | {key: amplitude, "files": [str(f) for f in files]})
        return
    if realtime:
        _print_realtime(res.summary, amplitude, unit, transport, files)
        _print_checks(res.summary)
        return
    s = res.summary
    t = Table(title=f"seactl run ({s['system']}): step {amplitude:g} {unit}, "
              f"{s['duration_s']:g} s over {transport}, rates "
              + ", ".join(f"{k} {v:g} Hz" for k, v in s["rates_hz"].items()))
    for col in ("link", "messages", "mean [ms]", "p50 [ms]", "p99 [ms]", "max [ms]"):
        t.add_column(escape(col))
    for link, st in s["links"].items():
        if st["count"]:
            t.add_row(escape(link), str(st["count"]), f"{st['mean_ms']:.3f}",
                      f"{st['p50_ms']:.3f}", f"{st['p99_ms']:.3f}", f"{st['max_ms']:.3f}")
    console.print(t)
    console.print(f"tracking RMS error {s['tracking_rms']:.3g} {unit}; final value "
                  f"{s['final_value']:.4f} of the step; dropped {s['dropped']}, late commands "
                  f"{s['late_commands']}")
    console.print(f"measured vs sampled simulation replaying the measured link timing: "
                  f"max diff {s['replay_max_diff']:.2e} of the step; vs the nominal "
                  f"simulation (design delays): {s['nominal_max_diff']:.2e}")
    _print_checks(s)
    if files:
        console.print("files: " + escape(", ".join(str(f) for f in files)))


def _api_system(spec: DesignSpec, system: SystemChoice, loop: Any, plant: str
                ) -> tuple[Any, dict[str, Any]]:
    """The :class:`seactl.System` that runs (the SEA's design, the rigid actuator or the
    loop file; one design) and the keywords of its ``run`` from the options."""
    _, _, sat, _, rates = system.build(spec, loop)   # one design, the options checked
    if loop is not None:
        return loop, {"rates_hz": rates}
    if system.system == "sea":
        return spec.designs(), {"rates_hz": rates, "saturation_a": sat["i_m"],
                                "plant": plant, "zero": system.zero}
    rig = system.rigid_system(spec)
    return rig, {"rates_hz": rates, "saturation_a": sat["F_des"] / rig.amperes_per_actuation,
                 "plant": plant}


def _print_checks(s: dict[str, Any]) -> None:
    """The latency check per loop and the prediction band's verdict."""
    checks = s.get("latency_check") or {}
    if checks:
        t = Table(title="measured latency per delayed loop vs the design's margins")
        for col in ("loop", "design delay [ms]", "mean [ms]", "max [ms]", "spread [ms]",
                    "p99-p1 [ms]", "jitter margin [ms]", "sampled jitter margin [ms]",
                    "delay limit [ms]", "within"):
            t.add_column(escape(col))
        for loop, c in checks.items():
            t.add_row(escape(loop), *(_num(c[k]) for k in (
                "design_delay_ms", "mean_ms", "max_ms", "spread_ms", "spread_p99_p1_ms",
                "jitter_margin_ms", "sampled_jitter_margin_ms", "delay_limit_ms")),
                "yes" if c["within"] else "no")
        console.print(t)
        for loop, c in checks.items():
            console.print(f"{escape(loop)}: {escape(c['verdict'])}")
    if "prediction_band" in s:
        b = s["prediction_band"]
        plant = (f"MuJoCo plant (step {s['plant_timestep_s']:g} s)"
                 if "plant_timestep_s" in s else "free-running run")
        what = f"the band of {b['runs']} sampled responses" if "runs" in b else "the band"
        console.print(f"{plant}: measured step vs {what}: {escape(b['verdict'])}")


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def _band_latency(plant: str, items: tuple[str, ...], realtime: bool
                  ) -> dict[str, Any] | None:
    """``--latency`` items as latency models (None: the run's measured latency; the
    system's ``run`` checks each loop)."""
    from seactl.latency.models import parse_latency, parse_link_specs

    if plant != "mujoco" and not realtime:
        if items:
            raise InputError("--latency", items[0], "used with --plant mujoco or "
                             "--realtime only")
        return None
    return parse_link_specs(items, parse_latency, "--latency") if items else None


def _ms(d: dict[str, Any], key: str) -> str:
    return f"{d[key]:.3f}" if d.get("count") else "-"


def _print_realtime(s: dict[str, Any], amplitude: float, unit: str, transport: str,
                    files: list[Any]) -> None:
    """The free-running run's process and link tables."""
    title = (f"seactl run --realtime ({s['system']}): step {amplitude:g} {unit}, "
             f"{s['duration_s']:g} s over {transport}, exported C")
    t = Table(title=title)
    for col in ("process", "rate [Hz]", "ticks", "missed deadlines", "jitter mean [ms]",
                "jitter p99 [ms]", "jitter max [ms]", "watchdog events", "watchdog ticks"):
        t.add_column(escape(col))
    for name, p in s["processes"].items():
        j = p["period_jitter"]
        t.add_row(escape(name), f"{p['rate_hz']:g}", str(p["ticks"]),
                  str(p["missed_deadlines"]), _ms(j, "mean_ms"), _ms(j, "p99_ms"),
                  _ms(j, "max_ms"), str(p.get("watchdog_events", "-")),
                  str(p.get("watchdog_ticks", "-")))
    console.print(t)
    t = Table()
    for col in ("link", "sent", "received", "lost", "stale ticks", "latency mean [ms]",
                "latency p99 [ms]", "latency max [ms]"):
        t.add_column(escape(col))
    for link, v in s["links"].items():
        lat = v["latency"]
        t.add_row(escape(link), str(v["sent"]), str(v["received"]), str(v["lost"]),
                  str(v["stale_ticks"]), _ms(lat, "mean_ms"), _ms(lat, "p99_ms"),
                  _ms(lat, "max_ms"))
    console.print(t)
    console.print(f"tracking RMS error {s['tracking_rms']:.3g} {unit}; final value "
                  f"{s['final_value']:.4f} of the step; vs the nominal simulation (design "
                  f"delays): max diff {s['nominal_max_diff']:.2e} of the step; injected "
                  f"losses {s['dropped']}")
    if files:
        console.print("files: " + escape(", ".join(str(f) for f in files)))
