"""``seactl delay-margin``: the delay margin along a direction of the delay vector, for SEA
designs or a loop file."""

from __future__ import annotations

from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from seactl.errors import InputError

from .common import DesignSpec, cli, console, design_options, echo_json, json_option
from .dde import dde_option
from .loops import loop_options


def parse_direction(text: str | None) -> dict[str, float] | None:
    """``NAME=W,NAME=W`` -> ``{name: weight}`` (None: every delay grows alike)."""
    if text is None:
        return None
    out: dict[str, float] = {}
    for tok in text.split(","):
        name, sep, val = tok.partition("=")
        try:
            out[name.strip()] = float(val) if sep and name.strip() else float("nan")
        except ValueError:
            out[name.strip()] = float("nan")
        if out[name.strip()] != out[name.strip()]:
            raise InputError("--direction", tok, "NAME=WEIGHT pairs separated by commas, "
                             "e.g. stiffness=1,damping=2")
    return out


def _fmt(x: Any, spec: str = ".6g") -> str:
    return "none" if x is None else format(x, spec)


def _margin_text(r: dict[str, Any]) -> str:
    if not r["stable"]:
        return "[red]unstable[/red]" if r["delay_margin_s"] == 0 else "[yellow]uncertain" \
                                                                      "[/yellow]"
    t = r["delay_margin_s"]
    text = "inf (no crossing)" if t is None else f"{t:.6g}"
    if r["touch"]:
        text += " (touch)"
    return text if r["verified"] else f"{text} [yellow](not verified)[/yellow]"


@cli.command("delay-margin")
@design_options
@click.option("--direction", default=None, metavar="NAME=W,NAME=W",
              help="Weights >= 0 of the delays that grow (absent: stay), in ratios of "
                   "integers up to 16; default: every delay grows alike.  SEA: torque, "
                   "stiffness, damping; a loop file: its delay names.")
@json_option
@dde_option
@loop_options
def delay_margin(spec: DesignSpec, direction: str | None, as_json: bool, loop: Any,
                 dde: Any) -> None:
    """Delay margin along a direction of the delays, with exact delays.

    Python: sc.design(...).delay_margin(direction); sc.load_loop(FILE).delay_margin(direction);
    sc.load_dde(FILE).delay_margin(direction).

    \b
    Examples:
      seactl delay-margin --fn 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --direction stiffness=1
      seactl delay-margin --loop examples/loops/rigid.toml --direction K_fb=1,B_fb=2
      seactl delay-margin --dde examples/dde/gkc-2x2.toml

    The delays move from the design's own along tau0 + t d / max(d); the margin t [s] is
    the extra delay of the most-moved delay when a closed-loop root first reaches the
    imaginary axis (0: unstable already; inf: never), with that root's frequency and
    the delays then.  Frequency sweeping on the exact characteristic, checked by
    certified root counts along the way (docs/theory/delay-margin.md); 'not verified':
    the checks disagreed, 'touch': the root touches the axis and goes back.
    """
    weights = parse_direction(direction)
    if dde is not None:
        systems, title = [dde], f"{dde.kind} '{dde.title}'"
    elif loop is not None:
        systems, title = [loop], f"loop '{loop.name}' ({loop.file})"
    else:
        systems = spec.all_designs()
        title = (f"actuator '{spec.actuator.name}' (T_tau={spec.t_tau_ms:g} ms, "
                 f"T_qs={spec.t_qs_ms:g} ms, T_qd={spec.t_qd_ms:g} ms)")
    results = [s.delay_margin(weights) for s in systems]
    rows = [row for r in results for row in r.records()]
    if as_json:
        echo_json({"direction": results[0].direction, "designs": rows})
        return
    names = list(results[0].direction)
    labels = list(results[0].labels)
    dirs = ", ".join(f"{n} x{w:g}" for n, w in results[0].direction.items() if w > 0)
    t = Table(title=escape(f"Delay margin along ({dirs}) of {title}"))
    for col in (*labels, "margin [s]", "crossing [Hz]",
                *(f"{n} at crossing [s]" for n in names)):
        t.add_column(escape(col), justify="right")
    for r in rows:
        t.add_row(*[_fmt(r[k], "g") for k in labels], _margin_text(r), _fmt(r["crossing_hz"]),
                  *(_fmt(r["crossing_delays_s"][n]) for n in names))
    console.print(t)
