"""Statistics of a free-running run (``seactl run --realtime``) from its process logs.

Per process: ticks run, deadlines missed (skipped), the period jitter (each actual period
between two ticks minus its nominal length) and the wake-up lateness (tick start minus
its deadline), and the watchdog.  Per link: the counts (sent, received, lost, reordered,
stale ticks) and the latency from send to use.
Times in milliseconds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.codegen.realtime import link_key

LINK_ROLES = {"plant->embedded": "embedded", "plant->high-level": "high-level",
              "high-level->embedded": "embedded", "embedded->plant": "plant"}
"""Each link and the process that receives it (and logs it)."""


def distribution_ms(values_s: np.ndarray) -> dict[str, Any]:
    """``count``, ``mean_ms``, ``p50_ms``, ``p99_ms``, ``max_ms`` (and ``min_ms``) of
    samples in seconds; only ``count`` for none."""
    ms = np.asarray(values_s, dtype=float) * 1e3
    if ms.size == 0:
        return {"count": 0}
    return {"count": int(ms.size), "mean_ms": float(ms.mean()),
            "p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max()), "min_ms": float(ms.min())}


def process_stats(log: dict[str, np.ndarray]) -> dict[str, Any]:
    """One process's timing and watchdog."""
    tick, wake = log["tick"], log["wake_s"]
    T, t0 = float(log["period_s"]), float(log["deadline0_s"])
    deadlines = int(log["deadlines"])
    jitter = np.diff(wake) - np.diff(tick) * T
    out = {"rate_hz": 1.0 / T, "deadlines": deadlines, "ticks": int(tick.size),
           "missed_deadlines": deadlines - int(tick.size),
           "period_jitter": distribution_ms(jitter),
           "wake_lateness": distribution_ms(wake - (t0 + tick * T)),
           "compute": distribution_ms(log["done_s"] - wake)}
    if "watchdog" in log:
        w = np.asarray(log["watchdog"])[tick].astype(int)
        out["watchdog_ticks"] = int(w.sum())
        out["watchdog_events"] = int(np.sum(np.diff(np.concatenate(([0], w))) == 1))
        out["binding"] = str(log["binding"])
    return out


def link_stats(log: dict[str, np.ndarray], link: str) -> dict[str, Any]:
    """One link's counts and timing, from its receiver's log."""
    key = link_key(link)
    sent, received, lost, reordered, stale = (int(v) for v in log[key + "counts"])
    return {"sent": sent, "received": received, "lost": lost, "reordered": reordered,
            "stale_ticks": stale, "latency": distribution_ms(log[key + "use_s"])}


def realtime_summary(logs: dict[str, dict[str, np.ndarray]]) -> dict[str, Any]:
    """``processes`` and ``links`` of the run's JSON, and the run's totals."""
    procs = {role: process_stats(log) for role, log in logs.items()}
    links = {link: link_stats(logs[role], link) for link, role in LINK_ROLES.items()}
    return {"processes": procs, "links": links,
            "missed_deadlines": sum(p["missed_deadlines"] for p in procs.values()),
            "lost": sum(v["lost"] for v in links.values()),
            "watchdog_events": sum(p.get("watchdog_events", 0) for p in procs.values()),
            "dropped": int(logs["high-level"]["dropped"])}


LOOP_HOPS = {"high-level": ("plant->high-level", "high-level->embedded", "embedded->plant"),
             "embedded": ("plant->embedded", "embedded->plant")}
"""The links a loop closed on each controller process crosses, plant to plant."""


def loop_latency_s(lat_s: dict[str, np.ndarray], process: str) -> np.ndarray:
    """The measured latency [s] of a loop closed on ``process``: the sum of the
    send-to-use latencies of the links it crosses (:data:`LOOP_HOPS`), paired in time
    order (each link's samples taken at the same fractions of the run, as many as the
    fewest); empty when a link has none."""
    hops = [np.asarray(lat_s[h], float) for h in LOOP_HOPS.get(process, ())]
    n = min((h.size for h in hops), default=0)
    if n == 0:
        return np.empty(0)
    return sum(h[(np.arange(n) * h.size) // n] for h in hops)
