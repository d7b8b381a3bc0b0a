"""``seactl jitter``: how much time-varying latency each loop of a design tolerates."""

from __future__ import annotations

from typing import Any

import numpy as np
from rich.markup import escape
from rich.table import Table

from ._common import DesignSpec, cli, console, design_options, echo_json, json_option

JSON_KEYS = ("fn_hz", "gs", "jitter_margin_ms", "stiffness_jitter_margin_ms",
             "damping_jitter_margin_ms", "torque_jitter_margin_ms", "delay_margin_ms")


def jitter_rows(spec: DesignSpec) -> list[dict[str, Any]]:
    """One row per (f_n, GS) design: the public API's :meth:`seactl.JitterResult.records`
    (:data:`JSON_KEYS` and ``stable``)."""
    from ..api import Design

    fn, gs = np.broadcast_arrays(spec.fn_hz[:, None], spec.gs[None, :])
    return Design(spec.designs(), fn, gs).jitter_margins().records()


def _ms(x: float | None, stable: bool) -> str:
    if not stable:
        return "[red]unstable[/red]"
    return "inf" if x is None else f"{x:.3f}"


@cli.command()
@design_options
@json_option
def jitter(spec: DesignSpec, as_json: bool) -> None:
    """Jitter margins [ms]: the largest time-varying extra delay in [0, J] that each loop
    is guaranteed to tolerate (Kao-Lincoln small-gain bound, exact delays), next to the
    whole outer loop's margin for a constant extra delay.

    \b
    Example (Table I):
      seactl jitter --fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100
    """
    rows = jitter_rows(spec)
    if as_json:
        echo_json({"designs": [{k: r[k] for k in JSON_KEYS} for r in rows]})
        return
    t = Table(title=escape(f"Jitter margins [ms], actuator '{spec.actuator.name}' "
                           f"(T_tau={spec.t_tau_ms:g} ms, T_qs={spec.t_qs_ms:g} ms, "
                           f"T_qd={spec.t_qd_ms:g} ms)"))
    for col in ("f_n [Hz]", "GS", "outer loop", "stiffness", "damping", "torque",
                "delay margin", "bottleneck"):
        t.add_column(escape(col), justify="right")
    for r in rows:
        stable = bool(r["stable"])
        loops = {k: r[f"{k}_jitter_margin_ms"] for k in ("stiffness", "damping", "torque")}
        finite = {k: v for k, v in loops.items() if v is not None}
        worst = min(finite, key=finite.get) if finite and stable else "-"
        t.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", _ms(r["jitter_margin_ms"], stable),
                  *(_ms(v, stable) for v in loops.values()),
                  _ms(r["delay_margin_ms"], stable), worst)
    console.print(t)
    console.print("A loop stays stable under any latency variation within its jitter margin "
                  "(sufficient, not necessary); the delay margin is for a constant extra "
                  "delay.", highlight=False)
