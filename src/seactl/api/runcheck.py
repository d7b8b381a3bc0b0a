"""A run's measured latency against the system's margins (``summary["latency_check"]``).

The margins of each delayed loop are the system's own (:meth:`seactl.System.jitter_margins`,
with and without the high-level rate, and :meth:`seactl.System.delay_margin` along the
loop); the verdict is :func:`seactl.latency.runcheck.loop_latency_check`'s.  Kinds whose
jitter margins are not per loop (loop files) get no check.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.errors import SeactlError
from seactl.latency.runcheck import run_latency_check


def _per_loop(result: Any, loop: str) -> float | None:
    v = getattr(result, f"{loop}_jitter_margin_s", None)
    return None if v is None else float(np.ravel(v)[0])


def _sampled(system: Any, rate_hz: float | None) -> Any:
    try:
        return None if rate_hz is None else system.jitter_margins(rate_hz=rate_hz)
    except SeactlError:   # a rate the sampled loop's margin cannot be had at
        return None


def loop_margins(system: Any, rates_hz: dict[str, float | None]) -> dict[str, Any]:
    """Loop -> ``design_delay_s``, ``jitter_margin_s``, ``delay_limit_s`` and the sampled
    jitter margin at the loop's rate (``rates_hz``: loop -> rate of its process; None
    when the sampled loop's margin cannot be had)."""
    cont = system.jitter_margins()
    sampled = {r: _sampled(system, r) for r in set(rates_hz.values())}
    terms = system.delay_terms()
    out = {}
    for loop, rate in rates_hz.items():
        j = _per_loop(cont, loop)
        if j is None:
            continue
        dm = system.delay_margin({loop: 1}).records()[0]["delay_margin_s"]
        tau = float(np.ravel(terms.delays_s[terms.index(loop)])[0])
        smp = sampled[rate]
        out[loop] = {"design_delay_s": tau, "jitter_margin_s": j,
                     "delay_limit_s": tau + (np.inf if dm is None else float(dm)),
                     "sampled_jitter_margin_s": None if smp is None else _per_loop(smp, loop),
                     "sampled_rate_hz": None if smp is None else float(rate)}
    return out


def check_run(system: Any, res: Any) -> dict[str, Any]:
    """Put each delayed loop's check into ``res.summary["latency_check"]`` and return it.

    Parameters
    ----------
    system : seactl.System
        The system that ran (one design).
    res : seactl.codegen.runtime.RunResult
        The run.

    Returns
    -------
    dict
        Loop name -> its check (:func:`seactl.latency.runcheck.loop_latency_check`).
    """
    blocks = res.block_latency_s
    process = {b.name: b.process for b in system.diagram_for().blocks}
    rates = res.summary.get("rates_hz", {})
    loops = {loop: rates.get(process.get(b)) for loop, b in system.links.items()
             if np.size(blocks.get(b, ())) > 0}
    checks = run_latency_check(blocks, system.links, loop_margins(system, loops))
    res.summary["latency_check"] = checks
    return checks
