"""The ``seactl`` command line.

Every command that takes a design shares the options of :func:`design_options`
(milliseconds and Hz at the CLI, SI inside).  Errors in user input print one
line (``error: ...``) without a traceback and exit with status 2.

Options listed in :data:`VARIADIC` take several values after one flag
(``--fn 12 14 16``); they are expanded to repeated flags before click parses.
"""

from __future__ import annotations

import functools
import json
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .errors import InputError, SeactlError

VARIADIC: set[str] = {"--fn", "--gs"}
"""Options that accept several space-separated values."""

# Tables stay readable when piped (rich would otherwise assume 80 columns).
console = Console(width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True)


# ------------------------------------------------------------------ value parsing
def parse_values(name: str, tokens: Sequence[str], *, log: bool = False) -> np.ndarray:
    """Numbers, or ranges ``START:STOP:STEP`` (inclusive; ``log``: ``START:STOP:N``
    log-spaced points), concatenated in the given order."""
    out: list[float] = []
    for tok in tokens:
        for part in str(tok).replace(",", " ").split():
            try:
                if ":" in part:
                    a, b, c = (float(x) for x in part.split(":"))
                    if log:
                        if a <= 0 or b <= 0 or c < 2 or c != int(c):
                            raise InputError(name, part, "START:STOP:N with START, STOP > 0 and "
                                             "an integer N >= 2")
                        out.extend(np.logspace(math.log10(a), math.log10(b), int(c)))
                    else:
                        if c <= 0 or b < a:
                            raise InputError(name, part, "START:STOP:STEP with STEP > 0 and "
                                             "STOP >= START")
                        n = int(math.floor((b - a) / c + 1e-9)) + 1
                        out.extend(a + c * np.arange(n))
                else:
                    out.append(float(part))
            except ValueError as exc:
                if isinstance(exc, InputError):
                    raise
                raise InputError(name, part, "a number or a range START:STOP:"
                                 + ("N" if log else "STEP")) from None
    return np.asarray(out, float)


def expand_variadic(argv: Sequence[str]) -> list[str]:
    """``--fn 12 14`` -> ``--fn 12 --fn 14`` for the options in :data:`VARIADIC`."""
    out: list[str] = []
    current: str | None = None
    for tok in argv:
        if tok.startswith("--"):
            name = tok.split("=", 1)[0]
            current = name if (name in VARIADIC and "=" not in tok) else None
            out.append(tok)
            if current:
                out.append("\0first")
            continue
        if current is not None:
            if out[-1] == "\0first":
                out[-1] = tok
            else:
                out.extend([current, tok])
            continue
        out.append(tok)
    return [t for t in out if t != "\0first"]


# ------------------------------------------------------------------ design options
@dataclass(frozen=True)
class DesignSpec:
    """What the shared design options describe (CLI units converted to SI)."""

    actuator: Any
    fn_hz: np.ndarray
    gs: np.ndarray
    zeta1: float
    zeta2: float
    ratio: float
    t_tau_ms: float
    t_qs_ms: float
    t_qd_ms: float
    f_qd_hz: float | None
    f_taud_hz: float | None

    def timing(self):
        from .loops import Timing

        return Timing.from_ms(self.t_tau_ms, self.t_qs_ms, self.t_qd_ms, self.f_qd_hz,
                              self.f_taud_hz)

    def designs(self, solution: int = 0):
        """The (f_n x GS) batch of designs, shape ``(len(fn), len(gs))``."""
        from .design import critically_damped_gains
        from .loops import SEADesign

        gains = critically_damped_gains(self.actuator, self.fn_hz[:, None], zeta1=self.zeta1,
                                        zeta2=self.zeta2, ratio=self.ratio,
                                        gs=self.gs[None, :], solution=solution)
        return SEADesign(self.actuator, gains, self.timing())

    def all_designs(self) -> list[Any]:
        """One design batch per valid solution index (usually just one)."""
        from .design import solve_gains

        n = int(solve_gains(self.actuator, self.fn_hz, zeta1=self.zeta1, zeta2=self.zeta2,
                            ratio=self.ratio).n_valid.min(initial=1))
        return [self.designs(i) for i in range(max(n, 1))]


def design_options(func: Callable) -> Callable:
    """Add the shared design options; the command receives ``spec: DesignSpec``."""
    opts = [
        click.option("--fn", "fn", multiple=True, default=("14",), show_default=True,
                     help="Natural frequency f_n [Hz]: values, or START:STOP:STEP."),
        click.option("--gs", "gs", multiple=True, default=("1",), show_default=True,
                     help="Gain scale GS (torque gains x GS, impedance gains / GS)."),
        click.option("--zeta1", type=float, default=1.0, show_default=True,
                     help="Damping ratio of the first pole pair."),
        click.option("--zeta2", type=float, default=1.0, show_default=True,
                     help="Damping ratio of the second pole pair."),
        click.option("--ratio", type=float, default=1.0, show_default=True,
                     help="w2 / w1 of the two pole pairs."),
        click.option("--t-tau", type=float, default=0.0, show_default=True,
                     help="Torque-feedback delay T_tau [ms]."),
        click.option("--t-qs", type=float, default=0.0, show_default=True,
                     help="Stiffness-feedback delay T_qs [ms]."),
        click.option("--t-qd", type=float, default=0.0, show_default=True,
                     help="Damping-feedback delay T_qd [ms]."),
        click.option("--f-qd", type=float, default=None,
                     help="Velocity filter cut-off f_qd [Hz] (default: no filter)."),
        click.option("--f-taud", type=float, default=None,
                     help="Torque-derivative filter cut-off f_taud [Hz] (default: no filter)."),
        click.option("--actuator", default="ut-sea", show_default=True,
                     help="Preset name or TOML file of the SEA."),
    ]

    @functools.wraps(func)
    def wrapper(*args, fn, gs, zeta1, zeta2, ratio, t_tau, t_qs, t_qd, f_qd, f_taud,
                actuator, **kwargs):
        from ._validate import finite_array
        from .actuators import load_sea

        for name, val in (("--t-tau", t_tau), ("--t-qs", t_qs), ("--t-qd", t_qd)):
            finite_array(f"{name} [ms]", val, minimum=0.0)
        for name, val in (("--f-qd", f_qd), ("--f-taud", f_taud)):
            if val is not None:
                finite_array(f"{name} [Hz]", val, minimum=0.0, strict=True)
        for name, val in (("--zeta1", zeta1), ("--zeta2", zeta2), ("--ratio", ratio)):
            finite_array(name, val, minimum=0.0, strict=True)
        fn_hz = finite_array("--fn [Hz]", parse_values("--fn", fn), minimum=0.0, strict=True)
        gs_v = finite_array("--gs", parse_values("--gs", gs), minimum=0.0, strict=True)
        if fn_hz.size == 0:
            raise InputError("--fn", "", "at least one frequency")
        spec = DesignSpec(load_sea(actuator), fn_hz, gs_v, zeta1, zeta2, ratio,
                          t_tau, t_qs, t_qd, f_qd, f_taud)
        return func(*args, spec=spec, **kwargs)

    for opt in reversed(opts):
        wrapper = opt(wrapper)
    return wrapper


def json_option(func: Callable) -> Callable:
    return click.option("--json", "as_json", is_flag=True,
                        help="Print machine-readable JSON instead of a table.")(func)


def finite_or_none(x: Any, digits: int = 10) -> float | None:
    """JSON-safe float: NaN/inf become null (the key's meaning is documented)."""
    x = float(x)
    return round(x, digits) if math.isfinite(x) else None


def echo_json(obj: Any) -> None:
    click.echo(json.dumps(obj, indent=2))


# ------------------------------------------------------------------ commands
@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="seactl")
def cli() -> None:
    """seactl: distributed impedance control of series elastic actuators."""


def gains_rows(spec: DesignSpec) -> list[dict[str, Any]]:
    """Table I rows (rotary units) with margins, one per design and valid solution: the
    public API's :meth:`seactl.MarginsResult.records` of each solution's (f_n x GS) batch."""
    from .api import Design

    rows = []
    for design in spec.all_designs():
        fn, gs = np.broadcast_arrays(spec.fn_hz[:, None], spec.gs[None, :])
        rows += Design(design, fn, gs).margins().records()
    return rows


def _fmt(x: float | None, spec: str) -> str:
    return "none" if x is None else format(x, spec)


@cli.command()
@design_options
@json_option
def gains(spec: DesignSpec, as_json: bool) -> None:
    """Critically-damped gains (Table I units) with phase, gain and delay margins.

    \b
    Example (the paper's Table I):
      seactl gains --fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100

    A margin printed as 'none' (null in JSON) means the loop has no such crossing:
    no gain crossover (phase and delay margin), or no phase crossover (gain margin).
    """
    rows = gains_rows(spec)
    if as_json:
        echo_json(rows)
        return
    t = Table(title=f"Critically-damped gains, actuator '{spec.actuator.name}' "
              f"(T_tau={spec.t_tau_ms:g} ms, T_qs={spec.t_qs_ms:g} ms, T_qd={spec.t_qd_ms:g} ms,"
              f" f_qd={spec.f_qd_hz or 'none'} Hz, f_taud={spec.f_taud_hz or 'none'} Hz)")
    for col in ("f_n [Hz]", "GS", "Kq [Nm/rad]", "Bq [Nms/rad]", "Ktau [A/Nm]", "Btau [As/Nm]",
                "PM [deg]", "crossover [Hz]", "GM [dB]", "DM [ms]", "stable"):
        t.add_column(escape(col), justify="right")
    for r in rows:
        t.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", f"{r['Kq']:.2f}", f"{r['Bq']:.3f}",
                  f"{r['Ktau']:.3f}", f"{r['Btau']:.4f}", _fmt(r["phase_margin_deg"], ".2f"),
                  _fmt(r["crossover_hz"], ".2f"), _fmt(r["gain_margin_db"], ".2f"),
                  _fmt(r["delay_margin_ms"], ".3f"),
                  "yes" if r["stable"] else "[red]NO[/red]")
    console.print(t)


@cli.command()
@click.option("--out", "out", default="seactl-report", show_default=True,
              type=click.Path(file_okay=False), help="Report directory.")
@click.option("--only", multiple=True, help="Only the named section(s) (ids).")
def reproduce(out: str, only: tuple[str, ...]) -> None:
    """Regenerate every table, figure and numeric claim of the paper into a report."""
    from .report import reproduce as run

    summary = run(Path(out), only=only or None, console=err_console)
    counts = {s: sum(1 for c in summary if c["status"] == s) for s in ("pass", "fail", "info")}
    console.print(f"report: {Path(out) / 'index.html'}  claims: {counts['pass']} pass, "
                  f"{counts['fail']} fail, {counts['info']} info")


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print the results as JSON.")
@click.option("--only", multiple=True, help="Only the named benchmark(s).")
@click.option("--repeat", type=click.IntRange(1, 50), default=5, show_default=True,
              help="Timed repetitions (the median is reported).")
def bench(as_json: bool, only: tuple[str, ...], repeat: int) -> None:
    """Benchmarks with throughput and the ratio to a baseline measured in the same run."""
    from .bench import run_benchmarks

    results = run_benchmarks(only=only or None, repeat=repeat,
                             console=None if as_json else err_console)
    if as_json:
        echo_json({"benchmarks": results})
        return
    t = Table(title="seactl benchmarks (medians; ratio = ours / baseline throughput)")
    for col in ("name", "throughput/s", "baseline", "baseline/s", "ratio", "max error"):
        t.add_column(col, justify="right" if col != "name" and col != "baseline" else "left")
    for r in results:
        t.add_row(r["name"], f"{r['throughput_per_s']:.4g}", r["baseline"],
                  f"{r['baseline_throughput_per_s']:.4g}", f"{r['ratio']:.3g}",
                  r.get("max_error_text") or f"{r['max_error']:.3g}")
    console.print(t)
    for r in results:
        if r.get("note"):
            console.print(f"- {r['name']}: {r['note']}")


# ------------------------------------------------------------------ entry point
def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point: returns the exit status (2 for bad input)."""
    args = expand_variadic(list(sys.argv[1:] if argv is None else argv))
    try:
        cli.main(args=args, prog_name="seactl", standalone_mode=False)
    except SeactlError as exc:
        err_console.print(f"[bold red]error:[/bold red] {escape(str(exc))}", highlight=False,
                          soft_wrap=True)
        return 2
    except click.exceptions.Abort:
        err_console.print("aborted")
        return 130
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except click.exceptions.Exit as exc:
        return exc.exit_code
    return 0


def run() -> None:  # pragma: no cover - console script
    sys.exit(main())


# Topic commands register themselves on import.
from . import commands  # noqa: E402,F401
