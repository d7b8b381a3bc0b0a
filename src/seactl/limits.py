"""Bounds from physics and from the machine.

Physical ranges of the inputs (:data:`RANGES`) and the work a command may start: every
command estimates the memory and time of what it is asked before allocating, and
:func:`check_budget` refuses with the estimate when the memory exceeds what this machine
has available, or the time exceeds :func:`time_budget_s`.

This module sits at the bottom of the layering (it imports only :mod:`seactl.errors`).
"""

from __future__ import annotations

import os

from .errors import ResourceError


def human_bytes(n: float) -> str:
    """``1.5 GiB``-style size."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"  # pragma: no cover


def human_seconds(s: float) -> str:
    """``2.5 min``-style duration."""
    if s < 120:
        return f"{s:.3g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    if s < 2 * 86400:
        return f"{s / 3600:.3g} h"
    return f"{s / 86400:.3g} days"


def available_memory_bytes() -> float:
    """Memory this process may still use: ``MemAvailable`` (Linux), else physical memory."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return 8 * 2.0**30


MEMORY_FRACTION = 0.5
"""A command may allocate at most this fraction of the available memory."""


def time_budget_s() -> float:
    """Longest estimated run a command starts: ``SEACTL_MAX_SECONDS`` or 15 minutes."""
    try:
        value = float(os.environ.get("SEACTL_MAX_SECONDS", "900"))
    except ValueError:
        value = 900.0
    return value if value > 0 else 900.0


def check_budget(what: str, *, n_bytes: float = 0.0, seconds: float = 0.0,
                 hint: str = "") -> None:
    """Refuse work estimated to need more memory than the machine has, or longer than
    :func:`time_budget_s`; the message gives the estimate, the limit and ``hint``."""
    mem = available_memory_bytes() * MEMORY_FRACTION
    if n_bytes > mem:
        raise ResourceError(f"{what} needs about {human_bytes(n_bytes)} of memory, more than "
                            f"this machine can give ({human_bytes(mem)})"
                            + (f"; {hint}" if hint else ""))
    budget = time_budget_s()
    if seconds > budget:
        raise ResourceError(f"{what} would take about {human_seconds(seconds)}, longer than "
                            f"the limit of {human_seconds(budget)} (SEACTL_MAX_SECONDS)"
                            + (f"; {hint}" if hint else ""))
