"""A run's measured latency of each delayed loop against the design's margins.

Per delayed loop whose command crosses the high-level -> embedded link, the measured
latency (``RunResult.block_latency_s``) is summarized and set against two numbers of the
design, both computed with the loop's break at the design's delays:

- its *jitter margin* ``J`` (``System.jitter_margins()``, and the sampled loop's at the
  high-level rate): the loop stays stable for any latency varying from sample to sample
  over an interval of that width above the design's delay.  The measured *spread*
  (max - min) is checked against ``J``;
- its *delay limit*, the loop's delay at which a root reaches the imaginary axis, the
  other delays at the design's (the design's delay plus ``System.delay_margin({loop: 1})``):
  the measured largest latency is checked against it.

The verdict is ``"within the jitter margin"`` when the spread is at most every jitter
margin and the largest latency below the delay limit; else ``"outside: ..."`` naming each
condition that failed, with its numbers.  It is a check of the run against the design's
analysis, not a new proof: the margins are the design's, at its delays.
"""

from __future__ import annotations

from typing import Any

import numpy as np

WITHIN = "within the jitter margin"
"""The verdict of a loop whose measured latency meets its margins."""


def _ms(v: float | None) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v) * 1e3


def loop_latency_check(latency_s: Any, *, design_delay_s: float, jitter_margin_s: float,
                       delay_limit_s: float, sampled_jitter_margin_s: float | None = None,
                       sampled_rate_hz: float | None = None) -> dict[str, Any]:
    """One loop's measured latency against its margins (module docstring).

    Parameters
    ----------
    latency_s : array_like
        The loop's measured latencies [s] (at least one).
    design_delay_s : float
        The loop's delay in the design [s].
    jitter_margin_s : float
        The loop's jitter margin of the continuous loop [s].
    delay_limit_s : float
        The loop's delay at which the design loses stability [s] (``inf``: never).
    sampled_jitter_margin_s, sampled_rate_hz : float, optional
        The sampled loop's jitter margin [s] and its rate [Hz].

    Returns
    -------
    dict
        ``count``, ``min_ms``, ``p1_ms``, ``mean_ms``, ``p99_ms``, ``max_ms``,
        ``spread_ms`` (max - min), ``spread_p99_p1_ms``, ``design_delay_ms``,
        ``jitter_margin_ms``, ``sampled_jitter_margin_ms``, ``sampled_rate_hz``,
        ``delay_limit_ms`` (None: no limit), ``within`` and ``verdict``.

    Examples
    --------
    >>> c = loop_latency_check([2e-3, 2.5e-3, 6e-3], design_delay_s=2e-3,
    ...                        jitter_margin_s=3e-3, delay_limit_s=18e-3)
    >>> c["verdict"]
    'outside: spread 4 ms > jitter margin 3 ms'
    """
    ms = np.asarray(latency_s, float) * 1e3
    p1, p99 = np.percentile(ms, [1, 99])
    spread = float(ms.max() - ms.min())
    out = {"count": int(ms.size), "min_ms": float(ms.min()), "p1_ms": float(p1),
           "mean_ms": float(ms.mean()), "p99_ms": float(p99), "max_ms": float(ms.max()),
           "spread_ms": spread, "spread_p99_p1_ms": float(p99 - p1),
           "design_delay_ms": _ms(design_delay_s), "jitter_margin_ms": _ms(jitter_margin_s),
           "sampled_jitter_margin_ms": _ms(sampled_jitter_margin_s),
           "sampled_rate_hz": None if sampled_rate_hz is None else float(sampled_rate_hz),
           "delay_limit_ms": _ms(delay_limit_s)}
    failed = []
    for key, name in (("jitter_margin_ms", "jitter margin"),
                      ("sampled_jitter_margin_ms", f"sampled jitter margin at "
                                                   f"{out['sampled_rate_hz'] or 0:g} Hz")):
        if out[key] is not None and spread > out[key]:
            failed.append(f"spread {spread:.4g} ms > {name} {out[key]:.4g} ms")
    if out["delay_limit_ms"] is not None and out["max_ms"] >= out["delay_limit_ms"]:
        failed.append(f"max latency {out['max_ms']:.4g} ms >= delay limit "
                      f"{out['delay_limit_ms']:.4g} ms")
    out["within"] = not failed
    out["verdict"] = WITHIN if not failed else "outside: " + "; ".join(failed)
    return out


def run_latency_check(block_latency_s: dict[str, Any], links: dict[str, str],
                      margins: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The check of every delayed loop with a measured latency.

    Parameters
    ----------
    block_latency_s : dict
        Delayed block -> measured latencies [s] (``RunResult.block_latency_s``).
    links : dict
        Loop name -> delayed block (``System.links``).
    margins : dict
        Loop name -> the keyword arguments of :func:`loop_latency_check` but the latency.

    Returns
    -------
    dict
        Loop name -> its check, for the loops with a measured latency and margins.
    """
    return {loop: loop_latency_check(block_latency_s[b], **margins[loop])
            for loop, b in links.items()
            if loop in margins and np.size(block_latency_s.get(b, ())) > 0}
