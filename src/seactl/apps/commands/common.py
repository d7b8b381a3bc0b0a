"""What every ``seactl`` command shares: the click group, the design options (milliseconds
and Hz at the command line, SI inside), value parsing, console and JSON output.

Options listed in :data:`VARIADIC` take several values after one flag
(``--fn 12 14 16``); they are expanded to repeated flags before click parses.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import sys
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import click
import numpy as np
from rich.console import Console

from seactl.base.axes import AXES, DESIGN_AXES
from seactl.base.limits import BYTES_PER_DESIGN, check_budget, check_count
from seactl.errors import InputError

VARIADIC: set[str] = {"--fn", "--gs"}
"""Options that accept several space-separated values."""

# Tables stay readable when piped (rich would otherwise assume 80 columns).
console = Console(width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True)


# ------------------------------------------------------------------ value parsing
def parse_values(name: str, tokens: Sequence[str], *, log: bool = False) -> np.ndarray:
    """Numbers, or ranges ``START:STOP:STEP`` (inclusive; ``log``: ``START:STOP:N``
    log-spaced points), concatenated in the given order."""
    out: list[np.ndarray] = []
    total = 0
    for tok in tokens:
        for part in str(tok).replace(",", " ").split():
            try:
                values = _range(name, part, log) if ":" in part else np.array([float(part)])
            except ValueError as exc:
                if isinstance(exc, InputError):
                    raise
                raise InputError(name, part, "a number or a range START:STOP:"
                                 + ("N" if log else "STEP")) from None
            total = check_count(name, part, total + values.size)
            out.append(values)
    return np.concatenate(out) if out else np.zeros(0)


def _range(name: str, part: str, log: bool) -> np.ndarray:
    """``START:STOP:STEP`` (or ``START:STOP:N`` log-spaced), its size checked first."""
    a, b, c = (float(x) for x in part.split(":"))
    if not all(math.isfinite(x) for x in (a, b, c)):
        raise InputError(name, part, "a range of finite numbers")
    if log:
        if a <= 0 or b <= 0 or c < 2 or c != int(c):
            raise InputError(name, part, "START:STOP:N with START, STOP > 0 and an integer "
                             "N >= 2")
        return np.logspace(math.log10(a), math.log10(b), check_count(name, part, c))
    if c <= 0 or b < a:
        raise InputError(name, part, "START:STOP:STEP with STEP > 0 and STOP >= START")
    steps = (b - a) / c
    n = check_count(name, part, math.floor(steps + 1e-9) + 1 if math.isfinite(steps) else steps)
    return a + c * np.arange(n)


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
@contextlib.contextmanager
def units_given() -> Iterator[None]:
    """Build systems with the public API without its unit warnings: the flags name their
    unit (``--t-qs [ms]``), so a small delay is not a unit slip."""
    from seactl.api.arguments import UnitWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        yield


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

    def designs(self, solution: int = 0):
        """The (f_n x GS) batch of designs, shape ``(len(fn), len(gs))``: the public
        :func:`seactl.design` (:class:`seactl.Design`) with these options."""
        from seactl.api.sea import design

        with units_given():
            return design(self.fn_hz[:, None], actuator=self.actuator, gs=self.gs[None, :],
                          zeta1=self.zeta1, zeta2=self.zeta2, ratio=self.ratio,
                          delays_ms={"torque": self.t_tau_ms, "stiffness": self.t_qs_ms,
                                     "damping": self.t_qd_ms},
                          filters_hz=(self.f_qd_hz, self.f_taud_hz), solution=solution)

    def all_designs(self) -> list[Any]:
        """One :class:`seactl.Design` batch per valid solution index (usually just one)."""
        from seactl.systems.sea.design import solve_gains

        n = int(solve_gains(self.actuator, self.fn_hz, zeta1=self.zeta1, zeta2=self.zeta2,
                            ratio=self.ratio).n_valid.min(initial=1))
        return [self.designs(i) for i in range(max(n, 1))]


def axis_option(name: str, *, multiple: bool = False, help_extra: str = "") -> Callable:
    """The click option of design axis ``name`` (:data:`seactl.base.axes.AXES`), passed to the
    command under the axis name (``t_qs_ms``); ``multiple`` takes values and ranges."""
    info = AXES[name]
    unit = f" [{info.unit}]" if info.unit else ""
    what = info.description[:1].upper() + info.description[1:] + unit
    if multiple:
        return click.option(info.option, name, multiple=True, default=(f"{info.default:g}",),
                            show_default=True, help=f"{what}: values, or START:STOP:STEP."
                            + help_extra)
    if info.allow_inf:
        return click.option(info.option, name, type=float, default=None,
                            help=f"{what} (default: no filter).{help_extra}")
    return click.option(info.option, name, type=float, default=info.default,
                        show_default=True, help=f"{what}.{help_extra}")


MULTI_AXES = ("fn_hz", "gs")
"""Design axes that take several values at once (a batch of designs)."""


def design_options(func: Callable) -> Callable:
    """Add the shared design options (one per axis of :data:`seactl.base.axes.DESIGN_AXES`, plus
    ``--actuator``); the command receives ``spec: DesignSpec``."""

    @functools.wraps(func)
    def wrapper(*args, actuator, **kwargs):
        from seactl.systems.sea.actuators import load_sea

        values = {}
        for name in DESIGN_AXES:
            raw = kwargs.pop(name)
            info = AXES[name]
            if name in MULTI_AXES:
                raw = parse_values(info.option, raw)
                if raw.size == 0:
                    raise InputError(info.option, "", "at least one value")
            values[name] = raw if raw is None else info.check(raw, info.label)
        n = values["fn_hz"].size * values["gs"].size
        check_budget(f"{n:,} designs (--fn x --gs)", n_bytes=n * BYTES_PER_DESIGN,
                     hint="give fewer --fn or --gs values")
        spec = DesignSpec(load_sea(actuator), **{n: _scalar(v) for n, v in values.items()})
        return func(*args, spec=spec, **kwargs)

    wrapper = click.option("--actuator", default="ut-sea", show_default=True,
                           help="Preset name or TOML file of the SEA.")(wrapper)
    for name in reversed(DESIGN_AXES):
        wrapper = axis_option(name, multiple=name in MULTI_AXES)(wrapper)
    return wrapper


def _scalar(v: Any) -> Any:
    return v if v is None or np.ndim(v) else float(v)


def rate_option(func: Callable) -> Callable:
    """``--rate HZ``: also analyse the sampled-data loop at that servo rate; the command
    receives ``rate_hz`` (None without the option), checked against its range."""

    @functools.wraps(func)
    def wrapper(*args, rate_hz, **kwargs):
        if rate_hz is not None:
            from seactl.base.limits import check_range

            check_range("--rate [Hz]", rate_hz, "rate_hz")
        return func(*args, rate_hz=rate_hz, **kwargs)

    return click.option(
        "--rate", "rate_hz", type=float, default=None,
        help="Also analyse the loop sampled at this servo rate [Hz] (both processes), as "
             "step --mode sampled runs it: Tustin controllers, whole-sample delays, the held "
             "plant; certified verdict (stable, unstable, uncertain) and margins up to "
             "Nyquist.")(wrapper)


SAMPLED_KEYS = ("rate_hz", "verdict", "unstable_modes", "phase_margin_deg", "crossover_hz",
                "gain_margin_db", "phase_crossover_hz", "delay_margin_ms",
                "delay_margin_samples", "jitter_margin_ms", "jitter_margin_samples")
"""JSON keys of the sampled loop (``"sampled": {...}`` beside the continuous values)."""


def sampled_callout(rows: Sequence[dict[str, Any]], stable_key: str = "stable") -> list[str]:
    """One line per design whose sampled verdict differs from the continuous one, or is
    uncertain (:func:`seactl.simulate.sampled.sampled_verdict_text`)."""
    from seactl.simulate.sampled import sampled_verdict_text

    out = []
    for r in rows:
        sm = r["sampled"]
        if sm["verdict"] == "stable" and r[stable_key]:
            continue
        out.append(f"f_n={r['fn_hz']:g} Hz, GS={r.get('gs', 1):g}: " + sampled_verdict_text(
            bool(r[stable_key]), sm["verdict"], sm["unstable_modes"], f"{sm['rate_hz']:g} Hz"))
    return out


def sampled_loop_lines(info: dict[str, Any], runs: list[dict[str, Any]],
                       continuous: Any, labels: Sequence[str]) -> list[str]:
    """Sampled mode: the simulated loop's certified verdict per run (``"sampled_loop"``:
    ``verdict``, ``unstable_modes``, ``continuous_stable``, ``text``) and the lines printed
    under the table, one per design, beside the continuous certified count ``continuous``
    (-1 unknown): a design stable in continuous time and not sampled is called out."""
    from seactl.simulate.sampled import sampled_verdict_text

    if "sampled_verdict" not in info:
        return []
    cont = np.ravel(continuous)
    verdicts = np.ravel(info["sampled_verdict"])
    modes = np.ravel(info["sampled_unstable_modes"])
    lines = []
    for i, r in enumerate(runs):
        c = None if cont[i] < 0 else bool(cont[i] == 0)
        text = sampled_verdict_text(c, str(verdicts[i]), int(modes[i]), info["sampled_rate"])
        r["sampled_loop"] = {"verdict": str(verdicts[i]), "unstable_modes": int(modes[i]),
                             "continuous_stable": c, "text": text}
        lines.append(f"{labels[i]}: {text}")
    return lines


def verdict_text(verdict: str) -> str:
    """A sampled verdict for a table cell (red unless stable)."""
    return verdict if verdict == "stable" else f"[red]{verdict}[/red]"


def json_option(func: Callable) -> Callable:
    return click.option("--json", "as_json", is_flag=True,
                        help="Print machine-readable JSON instead of a table.")(func)


def finite_or_none(x: Any, digits: int = 10) -> float | None:
    """JSON-safe float: NaN/inf become null (the key's meaning is documented)."""
    x = float(x)
    return round(x, digits) if math.isfinite(x) else None


def pm_text(pm_deg: float | None, stable: bool, spec: str = ".2f") -> str:
    """A phase margin for a table: an unstable design's is marked, whatever its sign
    (the margin of one crossover says nothing once a closed-loop root is unstable)."""
    text = "none" if pm_deg is None else format(pm_deg, spec)
    return text if stable else f"[red]{text} (unstable)[/red]"


def echo_json(obj: Any) -> None:
    click.echo(json.dumps(obj, indent=2))


_FULL = "seactl.full"


def _remember_full(ctx: click.Context, param: click.Parameter, value: bool) -> bool:
    ctx.meta[_FULL] = value
    return value


def full_option(func: Callable) -> Callable:
    """``--full``: the JSON of a response also holds its long arrays (read by
    :func:`series_json`)."""
    return click.option(
        "--full", is_flag=True, expose_value=False, callback=_remember_full,
        help="With --json: also print the long arrays (time series, frequency grid). "
             "Without it the JSON is a summary and 'omitted' gives each array's length; "
             "--csv FILE writes them to a file.")(func)


IMPEDANCE_SERIES = ("f_hz", "magnitude", "magnitude_db", "phase_deg", "real")
"""The long arrays of an impedance's JSON, one value per frequency."""


def series_json(obj: Any, keys: Iterable[str]) -> Any:
    """``obj`` (a dict, a list of dicts, or a dict with ``runs``) as ``--json`` prints it:
    without the long arrays named in ``keys`` unless ``--full`` was given, each dropped
    array's length under ``omitted``."""
    ctx = click.get_current_context(silent=True)
    if ctx is not None and ctx.meta.get(_FULL):
        return obj
    keys = tuple(keys)
    if isinstance(obj, list):
        return [series_json(o, keys) for o in obj]
    out = {k: v for k, v in obj.items() if k not in keys}
    if isinstance(out.get("runs"), list):
        out["runs"] = [series_json(r, keys) for r in out["runs"]]
    omitted = {k: len(obj[k]) for k in keys if isinstance(obj.get(k), list)}
    if omitted:
        out["omitted"] = omitted
    return out


# ------------------------------------------------------------------ commands
class Interrupted(Exception):
    """Ctrl-C or SIGTERM (``interrupt``, a ``KeyboardInterrupt``) during a command, carried
    to :func:`seactl.apps.cli.main` as is."""

    def __init__(self, interrupt: KeyboardInterrupt):
        super().__init__(str(interrupt))
        self.interrupt = interrupt


class _Command(click.Command):
    """A command whose library errors are re-worded for the command line: an
    :class:`InputError` naming a parameter (``t_qs_ms``, ``out``) names the flag the user
    typed instead (``--t-qs [ms]``, ``--out``). ``sections`` (heading, parameter names)
    groups the options of ``--help`` under headings; the others follow under "Options"."""

    def __init__(self, *args: Any, sections: Sequence[tuple[str, Sequence[str]]] = (),
                 **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.sections = tuple(sections)

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        if not self.sections:
            return super().format_options(ctx, formatter)
        rows = {p.name: p.get_help_record(ctx) for p in self.get_params(ctx)}
        placed = {name for _, names in self.sections for name in names}
        groups = [*self.sections, ("Options", [n for n in rows if n not in placed])]
        # one column width under every heading; a longer option's help starts below it
        width = max(len(r[0]) for r in rows.values() if r is not None and len(r[0]) <= 26)
        for title, names in groups:
            records = [(rows[n][0].ljust(width), rows[n][1]) for n in names
                       if rows.get(n) is not None]
            if records:
                with formatter.section(title):
                    formatter.write_dl(records, col_max=width)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:   # past click's handler (it prints a blank line)
            raise Interrupted(exc) from exc
        except InputError as exc:
            flag = flag_for(ctx.command, exc.field)
            if flag is not None:
                exc.field = flag
                exc.args = (f"invalid {flag} = {exc.value!r}: must be {exc.valid}",)
            raise


def flag_for(command: click.Command, field: str) -> str | None:
    """The flag (with the axis unit, if any) of ``command`` whose parameter is ``field``."""
    name = str(field).split(" [")[0]
    name = {"z_freqs_hz": "z_freq", "duration_s": "duration"}.get(name, name)  # API names
    for param in command.params:
        if isinstance(param, click.Option) and param.name == name:
            unit = AXES[name].unit if name in AXES else ""
            return max(param.opts, key=len) + (f" [{unit}]" if unit else "")
    return None


class _Group(click.Group):
    command_class = _Command


@click.group(context_settings={"help_option_names": ["-h", "--help"]}, cls=_Group)
@click.version_option(package_name="seactl")
def cli() -> None:
    """seactl: distributed impedance control of series elastic actuators."""
