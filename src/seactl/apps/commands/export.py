"""``seactl export``: the discrete controller of each process as C99, Python and JSON.

JSON: ``{"files": [...], "processes": [{"name", "rate_hz", "inputs", "outputs", "params"}],
"emulate_latency", "real", "requested_delays_s", "effective_delays_s", "emulated_delays_s",
"max_error", "target", "errors", "compiler", "compile_s"}`` (the last five null without
--verify).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.errors import InputError

from .common import DesignSpec, cli, console, design_options, echo_json, json_option
from .loops import loop_options

SYSTEMS = ("sea", "rigid")


def parse_rates(values: tuple[str, ...]) -> float | dict[str, float]:
    """``--rate HZ`` (every process) or ``--rate PROCESS=HZ`` (repeatable)."""
    if not values:
        return 1000.0
    rates: dict[str, float] = {}
    for v in values:
        name, sep, hz = v.rpartition("=")
        try:
            rate = float(hz)
        except ValueError:
            raise InputError("rates_hz [Hz]", v, "HZ or PROCESS=HZ, e.g. embedded=2000") from None
        if not sep:
            if len(values) > 1:
                raise InputError("rates_hz", v, "PROCESS=HZ when --rate is given more than once")
            return rate
        rates[name.strip()] = rate
    return rates


def _saturation(value: str | None, default: float, unit: str) -> float:
    if value is None:
        return default
    if value.strip().lower() in ("none", "inf", "off"):
        return math.inf
    try:
        sat = float(value)
    except ValueError:
        raise InputError(f"--saturation [{unit}]", value, "a limit > 0 or 'none'") from None
    if not sat > 0 or math.isnan(sat):
        raise InputError(f"--saturation [{unit}]", value, "a limit > 0 or 'none'")
    return sat


def _number(name: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(name, text, "a number, or 'none'") from None


@dataclass(frozen=True)
class SystemChoice:
    """The options of :func:`system_options`: which system, its rates and limits."""

    system: str
    rates_hz: float | dict[str, float]
    saturation: str | None
    zero: bool
    rigid_actuator: str
    t_s: float
    t_d: float
    f_v: str
    rates_given: bool = False

    def build(self, spec: DesignSpec, loop: Any = None) -> tuple[Any, ...]:
        """(diagram, design, saturation, verification step, rates) of the chosen system, or
        of a loop file (``--loop``: its diagram, values, and its processes' rates unless
        ``--rate`` is given)."""
        if loop is not None:
            return self._loop(loop)
        if spec.fn_hz.size != 1 or spec.gs.size != 1:
            raise InputError("--fn", f"{spec.fn_hz.size} x {spec.gs.size} designs",
                             "one --fn and one --gs (one design per export)")
        if self.system == "sea":
            from seactl.systems.sea.loops import sea_diagram

            lim = _saturation(self.saturation, spec.actuator.max_current, "A")
            with np.errstate(over="ignore"):   # extreme --gs: infinite gains, refused later
                design = spec.designs().sea
            return sea_diagram(self.zero), design, {"i_m": lim}, 0.1, self.rates_hz
        from seactl.systems.rigid.model import RIGID_DIAGRAM

        d = self.rigid_system(spec).rigid
        sat = _saturation(self.saturation, d.actuator.max_force, "N")
        return RIGID_DIAGRAM, d, {"F_des": sat}, 0.004, self.rates_hz

    def rigid_system(self, spec: DesignSpec) -> Any:
        """The rigid actuator of ``--fn``, ``--t-s``, ``--t-d``, ``--f-v`` (one design):
        :func:`seactl.rigid`'s :class:`~seactl.RigidBatch`."""
        from seactl.api.rigid import rigid

        fv = None if self.f_v.strip().lower() == "none" else _number("--f-v [Hz]", self.f_v)
        return rigid(float(spec.fn_hz.reshape(-1)[0]), actuator=self.rigid_actuator,
                     delays_ms={"stiffness": self.t_s, "damping": self.t_d},
                     velocity_filter_hz=fv)

    def _loop(self, loop: Any) -> tuple[Any, ...]:
        if int(np.prod(loop.shape, dtype=int)) != 1:
            raise InputError("--set", f"{int(np.prod(loop.shape))} designs",
                             "one value per variable (one design per export)")
        rates = self.rates_hz if self.rates_given else {
            name: float(p.rate_hz) for name, p in loop.processes.items()}
        return loop.diagram, loop.design, None, loop.default_step, rates


RIGID_OPTIONS = [
    click.option("--rigid-actuator", default="ut-linear", show_default=True,
                 help="Rigid actuator preset or TOML file."),
    click.option("--t-s", "t_s", type=float, default=0.0, show_default=True,
                 help="Rigid: stiffness-loop delay [ms]."),
    click.option("--t-d", "t_d", type=float, default=0.0, show_default=True,
                 help="Rigid: damping-loop delay [ms]."),
    click.option("--f-v", "f_v", default="50", show_default=True,
                 help="Rigid: velocity filter cut-off [Hz], or 'none'."),
]
"""The rigid actuator's options (``seactl export``, ``run`` and ``chart``)."""


def system_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """``--system``, ``--rate``, ``--saturation``, ``--no-zero`` and the rigid actuator's
    options (``export`` and ``run``), passed to the command as one ``system``."""
    options = [
        click.option("--system", type=click.Choice(SYSTEMS), default="sea", show_default=True,
                     help="SEA (the design options) or rigid actuator (--fn, --t-s, --t-d, "
                          "--f-v)."),
        click.option("--rate", "rates_hz", multiple=True,
                     help="HZ for every process, or PROCESS=HZ (repeat), e.g. --rate "
                          "embedded=2000 --rate high-level=500 [default: 1000]."),
        click.option("--saturation", default=None,
                     help="Actuation limit: A (SEA current) or N (rigid force); 'none' for no "
                          "limit [default: the actuator's]."),
        click.option("--no-zero", is_flag=True,
                     help="SEA: torque derivative on the feedback only."),
        *RIGID_OPTIONS,
    ]

    @functools.wraps(func)
    def wrapper(*args: Any, system: str, rates_hz: tuple[str, ...], saturation: str | None,
                no_zero: bool, rigid_actuator: str, t_s: float, t_d: float, f_v: str,
                **kwargs: Any) -> Any:
        choice = SystemChoice(system, parse_rates(rates_hz), saturation, not no_zero,
                              rigid_actuator, t_s, t_d, f_v, bool(rates_hz))
        return func(*args, system=choice, **kwargs)

    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper


@cli.command("export")
@design_options
@loop_options
@click.option("--out", required=True, type=click.Path(file_okay=False),
              help="New or empty directory (or an earlier export) for the files.")
@click.option("--lang", default="c,python,json", show_default=True,
              help="Comma-separated: c (<process>.h/.c + CSV harness), python, json.")
@system_options
@click.option("--emulate-latency", is_flag=True,
              help="Keep the design's delays as buffers in the code (bench tests); by "
                   "default the code holds none: on the robot the latency is the platform's.")
@click.option("--real", type=click.Choice(("double", "float")), default="double",
              show_default=True, help="Floating-point type of the C.")
@click.option("--verify", is_flag=True,
              help="Compile the C (cc -std=c99 -Wall -Wextra -Werror -pedantic) and run it "
                   "and the Python against seactl's sampled controller before writing.")
@click.option("--cc", default=None, help="C compiler for --verify [default: $CC, cc, gcc].")
@json_option
def export(spec: DesignSpec, loop: Any, out: str, lang: str, system: SystemChoice,
           emulate_latency: bool, real: str, verify: bool, cc: str | None,
           as_json: bool) -> None:
    """Write the discrete controller of each process (C99, Python, JSON).

    Python: sc.design(...).export(out), sc.rigid(...).export(out),
    sc.load_loop(...).export(out).

    \b
    The sampled controller of the design split by process, each at its own rate:
    stiffness on 'high-level', torque and damping on 'embedded' (docs/export.md);
    gains, filters, output limit and watchdog in a run-time parameter struct; no delay
    buffers unless --emulate-latency.
    Example:
      seactl export --fn 14 --t-tau 1 --t-qs 2 --t-qd 1 --f-qd 50 --f-taud 100 \\
          --rate embedded=2000 --rate high-level=500 --out ctl --verify
    """
    from seactl.codegen.export import check_export_dir, export_design
    from seactl.codegen.source import check_languages

    langs = check_languages(lang)
    check_export_dir(out)
    diagram, design, sat, step, rates = system.build(spec, loop)
    res = export_design(diagram, design, out, languages=langs, rates_hz=rates,
                        saturation=sat, verify_export=verify, cc=cc, step=step,
                        emulate_latency=emulate_latency, real=real)
    if as_json:
        echo_json(res.to_dict())
        return
    _print(res)


def _print(res: Any) -> None:
    t = Table(title="Exported processes (schedule order)")
    for col in ("process", "rate [Hz]", "inputs", "outputs", "states", "delay buffers"):
        t.add_column(escape(col))
    for p in res.controllers.processes:
        t.add_row(escape(p.name), f"{p.rate_hz:g}", escape(", ".join(p.inputs)),
                  escape(", ".join(p.outputs)), str(p.A.shape[0]),
                  escape(", ".join(f"{b}: {n}" for b, n in p.buffers) or "none"))
    console.print(t)
    console.print("files: " + escape(", ".join(str(f) for f in res.files)))
    ctl = res.controllers
    delays = ", ".join(f"{b} {ctl.requested_delays_s[b] * 1e3:g} -> {e * 1e3:g}"
                       for b, e in ctl.effective_delays_s.items())
    if ctl.emulate_latency and delays:
        console.print(escape("latency emulated by buffers, requested -> effective (T_s/2 + "
                             "n T_s, never shorter) [ms]: " + delays))
    elif delays:
        console.print(escape("no latency in the code (the platform's is the design's; "
                             "--emulate-latency to emulate it); design delays requested -> "
                             "effective when sampled [ms]: " + delays))
    v = res.verification
    if v is not None:
        detail = ", ".join(f"{k} {e:.2e}" for k, e in v.errors.items())
        console.print(f"verified ({res.real}): largest relative difference {v.max_error:.2e} "
                      f"(target {v.target:g}; {escape(detail)}); compiled with "
                      f"{escape(v.compiler)} in {v.compile_s:.2f} s")
