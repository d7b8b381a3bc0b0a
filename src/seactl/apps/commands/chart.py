"""``seactl chart``: the stability chart of one design over two of its delays.

JSON: ``{"system", "unit", ...}`` and :meth:`seactl.StabilityChartResult.to_dict` (delays in
seconds, frequencies in rad/s) whatever unit the chart's extent was given in.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from seactl.base.outputs import FIGURE_SUFFIXES, OutputSet
from seactl.errors import InputError

from .common import DesignSpec, cli, console, design_options, echo_json, json_option, units_given
from .dde import dde_option
from .export import RIGID_OPTIONS
from .loops import loop_options

SYSTEMS = ("sea", "rigid")


def parse_pair(flag: str, text: str | None, *, numbers: bool) -> tuple[Any, Any] | None:
    """``A,B`` -> two names (or two numbers)."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    valid = "two numbers A,B" if numbers else "two names A,B"
    if len(parts) != 2 or not all(parts):
        raise InputError(flag, text, valid)
    if not numbers:
        return parts[0], parts[1]
    try:
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(flag, text, valid) from None


def chart_extent(max_s: str | None, max_ms: str | None) -> tuple[float, float]:
    """The chart's extent [s] from ``--max-s`` or ``--max-ms`` (exactly one)."""
    if (max_s is None) == (max_ms is None):
        raise InputError("--max-s / --max-ms", "both" if max_s else "neither",
                         "one of them: the chart's extent T1,T2 in s or in ms")
    if max_s is not None:
        return parse_pair("--max-s", max_s, numbers=True)
    t = parse_pair("--max-ms", max_ms, numbers=True)
    return t[0] * 1e-3, t[1] * 1e-3


def extent_error(exc: InputError, max_s: str | None, max_ms: str | None) -> InputError:
    """A library error about the chart's extent (``max_s``, in s) re-worded for the option
    the user typed, with the value as typed and in its unit; any other error as it is."""
    flag, unit, text = ("--max-s", "s", max_s) if max_s is not None else \
        ("--max-ms", "ms", max_ms)
    if exc.field == "max_s":
        return InputError(flag, text, exc.valid.replace("[s]", f"[{unit}]"))
    if "(max_s)" in exc.valid:
        return InputError(exc.field, exc.value, exc.valid.replace("(max_s)", f"({flag})"))
    return exc


def rigid_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """``--system`` and the rigid actuator's options (as ``seactl export`` takes them)."""
    options = [
        click.option("--system", type=click.Choice(SYSTEMS), default="sea", show_default=True,
                     help="SEA (the design options) or rigid actuator (--fn, --t-s, --t-d, "
                          "--f-v)."),
        *RIGID_OPTIONS,
    ]

    @functools.wraps(func)
    def wrapper(*args, system, rigid_actuator, t_s, t_d, f_v, **kwargs):
        return func(*args, rigid=None if system == "sea" else (rigid_actuator, t_s, t_d, f_v),
                    **kwargs)

    for opt in reversed(options):
        wrapper = opt(wrapper)
    return wrapper


def chart_system(spec: DesignSpec, loop: Any, rigid: tuple | None) -> tuple[str, Any]:
    """The one design charted: ``(kind, system)`` of a loop file, the rigid actuator or the
    SEA (one more source is one more branch here)."""
    if loop is not None:
        return "loop", loop
    if spec.fn_hz.size != 1 or spec.gs.size != 1:
        raise InputError("--fn", f"{spec.fn_hz.size} x {spec.gs.size} designs",
                         "one --fn and one --gs (one design per chart)")
    if rigid is not None:
        from seactl.api.rigid import rigid as rigid_batch

        actuator, t_s, t_d, f_v = rigid
        fv = None if f_v.strip().lower() == "none" else _number("--f-v [Hz]", f_v)
        with units_given():
            return "rigid", rigid_batch(float(spec.fn_hz[0]), actuator=actuator,
                                        delays_ms={"stiffness": t_s, "damping": t_d},
                                        velocity_filter_hz=fv)
    return "sea", spec.designs()


def _number(flag: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(flag, text, "a number, or 'none'") from None


@cli.command()
@design_options
@rigid_options
@click.option("--delays", "delays", required=True, metavar="NAME1,NAME2",
              help="The two delays varied (the system's loop names, e.g. stiffness,damping).")
@click.option("--max-s", "max_s", default=None, metavar="T1,T2",
              help="The chart's extent [s] on each axis.")
@click.option("--max-ms", "max_ms", default=None, metavar="T1,T2",
              help="The chart's extent [ms] on each axis.")
@click.option("--resolution", type=int, default=1000, show_default=True,
              help="Pixels per side of the raster that separates the regions (100-4000).")
@click.option("--plot", "plot", default=None, metavar="FILE.png|.svg|.pdf",
              help="Write the chart: stable regions shaded, crossing curves, the design.")
@json_option
@dde_option
@loop_options
def chart(spec: DesignSpec, rigid: tuple | None, delays: str, max_s: str | None,
          max_ms: str | None, resolution: int, plot: str | None, as_json: bool,
          loop: Any, dde: Any) -> None:
    """Stability chart over two delays: the crossing curves (delays where a root crosses
    the imaginary axis) and the certified number of right-half-plane roots in each region
    they bound; the other delays stay at the design's.

    Python: sc.design(...).stability_chart(delays=(NAME1, NAME2), max_s=(T1, T2)), and the
    same on sc.rigid(...), sc.load_loop(FILE) and sc.load_dde(FILE).

    \b
    Examples:
      seactl chart --fn 14 --delays stiffness,damping --max-ms 20,20 --plot chart.png
      seactl chart --system rigid --fn 8 --t-s 1.5 --t-d 1.5 --delays stiffness,damping \\
        --max-ms 20,20
      seactl chart --loop examples/loops/paper-sea.toml --delays Kq_fb,Bq_fb \\
        --max-s 0.02,0.02 --json
      seactl chart --dde examples/dde/two-delays.toml --delays tau1,tau2 --max-s 10,10

    The curves are computed exactly (frequency sweeping: every solution on the torus of
    each frequency by polynomial root finding, Newton-polished); each region's count is
    certified by the argument principle at one point and checked against the direction
    in which roots cross the curves (an inconsistency is reported, never hidden).
    """
    with OutputSet() as outs:
        plot_p = outs.add("--plot", plot, FIGURE_SUFFIXES)
        names = parse_pair("--delays", delays, numbers=False)
        extent = chart_extent(max_s, max_ms)
        kind, system = ("dde", dde) if dde is not None else chart_system(spec, loop, rigid)
        try:
            result = system.stability_chart(names, extent, resolution=resolution)
        except InputError as exc:
            raise extent_error(exc, max_s, max_ms) from None
        if plot_p:
            from seactl.apps.plots import pyplot

            pyplot()
            outs.figure(plot_p, result.plot().figure)
        outs.commit()
    unit = "s" if max_s is not None else "ms"
    if as_json:
        echo_json({"system": kind, "unit": unit} | result.to_dict())
        return
    _print_chart(result, kind, unit)


def _print_chart(result: Any, kind: str, unit: str) -> None:
    """The regions as a table, then the design's verdict and the checks."""
    k = 1.0 if unit == "s" else 1e3
    d1, d2 = result.delays
    t = Table(title=escape(f"Stability chart of the {kind} system over {d1} x {d2} "
                           f"(0-{result.max_s[0] * k:g} x 0-{result.max_s[1] * k:g} {unit})"))
    for col in (f"{d1} [{unit}]", f"{d2} [{unit}]", "RHP roots", "stable", "size [px]"):
        t.add_column(escape(col), justify="right")
    for r in result.records():
        n = r["right_half_plane_roots"]
        t.add_row(f"{r['tau1_s'] * k:.4g}", f"{r['tau2_s'] * k:.4g}",
                  "uncertain" if n < 0 else str(n), "yes" if r["stable"] else "[red]no[/red]",
                  str(r["pixels"]))
    console.print(t)
    p = result.design_point_s * k
    n = result.design_right_roots
    console.print(f"design ({d1} {p[0]:.4g} {unit}, {d2} {p[1]:.4g} {unit}): "
                  + ("stable" if result.design_stable else
                     f"[red]unstable[/red] ({'uncertain' if n < 0 else n} RHP roots)")
                  + f"; {len(result.curves)} curve branches; "
                  + (f"{len(result.checks)} crossing-direction checks agree" if result.consistent
                     else f"[red]{sum(not c['consistent'] for c in result.checks)} of "
                          f"{len(result.checks)} crossing-direction checks disagree[/red]"),
                  highlight=False)
