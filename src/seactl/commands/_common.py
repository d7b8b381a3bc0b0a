"""What every ``seactl`` command shares: the click group, the design options (milliseconds
and Hz at the command line, SI inside), value parsing, console and JSON output.

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
from typing import Any

import click
import numpy as np
from rich.console import Console

from ..errors import InputError

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
        from ..loops import Timing

        return Timing.from_ms(self.t_tau_ms, self.t_qs_ms, self.t_qd_ms, self.f_qd_hz,
                              self.f_taud_hz)

    def designs(self, solution: int = 0):
        """The (f_n x GS) batch of designs, shape ``(len(fn), len(gs))``."""
        from ..design import critically_damped_gains
        from ..loops import SEADesign

        gains = critically_damped_gains(self.actuator, self.fn_hz[:, None], zeta1=self.zeta1,
                                        zeta2=self.zeta2, ratio=self.ratio,
                                        gs=self.gs[None, :], solution=solution)
        return SEADesign(self.actuator, gains, self.timing())

    def all_designs(self) -> list[Any]:
        """One design batch per valid solution index (usually just one)."""
        from ..design import solve_gains

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
        from .._validate import finite_array
        from ..actuators import load_sea

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


def pm_text(pm_deg: float | None, stable: bool, spec: str = ".2f") -> str:
    """A phase margin for a table: an unstable design's is marked, whatever its sign
    (the margin of one crossover says nothing once a closed-loop root is unstable)."""
    text = "none" if pm_deg is None else format(pm_deg, spec)
    return text if stable else f"[red]{text} (unstable)[/red]"


def echo_json(obj: Any) -> None:
    click.echo(json.dumps(obj, indent=2))


# ------------------------------------------------------------------ commands
@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="seactl")
def cli() -> None:
    """seactl: distributed impedance control of series elastic actuators."""
