"""``seactl robot --mimo`` and ``--placement``: the central process's MIMO loop and the
placement of each loop, their JSON and tables."""

from __future__ import annotations

from typing import Any

from rich.markup import escape
from rich.table import Table

from seactl.errors import InputError

from .common import console, pm_text


def parse_placement(text: str) -> tuple[float, float]:
    """``CENTRAL_MS,EMBEDDED_MS`` -> the two latencies [ms] (ranges checked by the API)."""
    try:
        central, embedded = (float(x) for x in text.split(","))
    except ValueError:
        raise InputError("--placement [ms]", text, "the central and the embedded latency "
                         "[ms], comma-separated, e.g. 5,0.5") from None
    return central, embedded


def mimo_record(r: Any) -> dict[str, Any]:
    """The JSON of ``--mimo``: :meth:`seactl.api.robot.Robot.mimo_margins`'s record and
    every crossover."""
    m = r.mimo_margins()
    rec = m.records()[0]
    rec["crossovers_hz"] = [float(x) for x in m.crossovers_hz]
    rec["crossover_margins_deg"] = [float(x) for x in m.crossover_margins_deg]
    return rec


def placement_record(r: Any, text: str) -> dict[str, Any]:
    """The JSON of ``--placement``: :meth:`seactl.api.robot.Robot.placement`'s dict."""
    central, embedded = parse_placement(text)
    try:
        return r.placement(central, embedded).to_dict()
    except InputError as exc:
        if exc.field not in ("central_ms", "embedded_ms"):
            raise
        raise InputError("--placement [ms]", text, exc.valid) from None


def _num(x: float | None, spec: str = ".4g") -> str:
    return "none" if x is None else format(x, spec)


def print_mimo(rec: dict[str, Any]) -> None:
    """The ``--mimo`` table: one row, the loop broken at every stiffness channel."""
    t = Table(title="central process: every stiffness channel broken at once "
                    "(generalized Nyquist)")
    for col in ("PM [deg]", "crossover [Hz]", "GM [dB]", "phase crossover [Hz]",
                "delay margin [ms]", "min sigma(I+L)"):
        t.add_column(escape(col))
    t.add_row(pm_text(rec["phase_margin_deg"], rec["stable"]), _num(rec["crossover_hz"]),
              _num(rec["gain_margin_db"]), _num(rec["phase_crossover_hz"]),
              _num(rec["delay_margin_ms"]), _num(rec["min_return_difference"]))
    console.print(t)


def print_placement(rec: dict[str, Any]) -> None:
    """The ``--placement`` table: one row per placement."""
    t = Table(title=f"placement: central {rec['central_latency_ms']:g} ms, embedded "
                    f"{rec['embedded_latency_ms']:g} ms")
    loops = [k for k in rec["options"][0] if k not in (
        "stable", "phase_margin_deg", "delay_margin_ms", "max_central_latency_ms")]
    for col in loops + ["verdict", "PM MIMO [deg]", "central delay margin [ms]",
                        "max central latency [ms]"]:
        t.add_column(escape(col))
    for o in rec["options"]:
        t.add_row(*(o[k] for k in loops), "stable" if o["stable"] else "[red]UNSTABLE[/red]",
                  pm_text(o["phase_margin_deg"], o["stable"]),
                  _num(o["delay_margin_ms"]) if o["delay_margin_ms"] is not None else "inf",
                  _num(o["max_central_latency_ms"]) if o["max_central_latency_ms"]
                  is not None else "inf")
    console.print(t)
