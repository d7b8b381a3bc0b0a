"""Bounds from physics and from the machine.

Physical ranges of the inputs (:data:`RANGES`) and the work a command may start: every
command estimates the memory and time of what it is asked before allocating, and
:func:`check_budget` refuses with the estimate when the memory exceeds what this machine
has available, or the time exceeds :func:`time_budget_s`.

This module sits at the bottom of the layering (it imports :mod:`seactl.errors` and
:mod:`seactl.base.axes`).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from seactl.base.axes import AXES
from seactl.errors import ResourceError


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
    # (memory read only when there is some to check: /proc/meminfo is a file read)
    mem = available_memory_bytes() * MEMORY_FRACTION if n_bytes > 0 else 0.0
    if n_bytes > mem:
        raise ResourceError(f"{what} needs about {human_bytes(n_bytes)} of memory, more than "
                            f"this machine can give ({human_bytes(mem)})"
                            + (f"; {hint}" if hint else ""))
    budget = time_budget_s()
    if seconds > budget:
        raise ResourceError(f"{what} would take about {human_seconds(seconds)}, longer than "
                            f"the limit of {human_seconds(budget)} (SEACTL_MAX_SECONDS)"
                            + (f"; {hint}" if hint else ""))


# ------------------------------------------------------------------ physical ranges
def _axis_range(name: str, what: str) -> tuple[float, float, str]:
    info = AXES[name]
    return info.minimum, info.maximum, what


RANGES: dict[str, tuple[float, float, str]] = {
    "delay_ms": _axis_range("t_qs_ms", "a feedback delay of a servo loop: 0 to 1 s"),
    "fn_hz": _axis_range("fn_hz", "a closed-loop natural frequency of a joint: 1 mHz to "
                         "1 kHz"),
    "filter_hz": _axis_range("f_qd_hz", "a filter cut-off: above 1 mHz, up to 1 MHz"),
    "amplitude_rad": (0.0, 100.0, "a step size: its magnitude above 0, up to 100 rad"),
    "impulse_nms": (0.0, 1e3, "an angular impulse: its magnitude above 0, up to 1000 N m s"),
    "rate_hz": (10.0, 1e6, "a servo rate: 10 Hz to 1 MHz"),
    "t_end_s": (0.0, 60.0, "a simulated time: above 0, up to 60 s"),
    "freq_hz": (1e-6, 1e7, "an analysis frequency: 1 uHz to 10 MHz (at lower ones Z(jw) "
                "of the integrating loop is 0/0 in floating point)"),
}
"""Documented input ranges of the quantities that are not design axes, and of the delays,
natural frequencies and filters of the rigid-actuator and placement commands (taken from
:data:`seactl.base.axes.AXES`, where the design axes keep theirs): (low, high, what) with ``low``
exclusive for frequencies and times and inclusive for delays."""

MIN_SAMPLES = 20
"""A simulation records at least this many samples (``t_end`` x rate)."""
MAX_VALUES = 1_000_000
"""Most values one list or range option may expand to (``--fn``, ``--freq``, ...)."""


def check_range(name: str, value: float, kind: str) -> float:
    """``value`` inside ``RANGES[kind]``, else :class:`~seactl.errors.InputError` naming
    ``name`` (the parameter in the library, the flag at the command line)."""
    from seactl.errors import InputError

    lo, hi, what = RANGES[kind]
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(name, value, f"a number (no units: the name says them), {what}"
                         ) from None
    inclusive = kind in ("delay_ms", "rate_hz", "fn_hz", "freq_hz")
    ok = (lo <= v <= hi) if inclusive else (lo < v <= hi)
    if math.isnan(v) or not ok:
        raise InputError(name, v, f"{'>=' if inclusive else '>'} {lo:g} and <= {hi:g} "
                         f"({what})")
    return v


# ------------------------------------------------------------------ estimates
BYTES_PER_DESIGN = 27e3
"""Peak memory of one design's gains and margins, an upper bound for refusing work up
front (above the sweep's peak per point, which ``seactl bench`` reports)."""
SIM_SECONDS_PER_STEP = 40e-6
"""Time of one simulation step, plus :data:`SIM_SECONDS_PER_DESIGN_STEP` per design:
estimates rounded up, for refusing work up front."""
SIM_SECONDS_PER_DESIGN_STEP = 3e-6
SIM_BYTES_PER_SAMPLE = 200.0
"""Memory per design and recorded sample: the recorded signals and their JSON text."""
FREQ_BYTES_PER_POINT = 640.0
"""Memory per design and frequency of an impedance evaluation (complex temporaries)."""


def simulation_estimate(n_designs: float, steps: float, recorded: float
                        ) -> tuple[float, float]:
    """(bytes, seconds) of a time-domain simulation of ``n_designs`` over ``steps``."""
    seconds = steps * (SIM_SECONDS_PER_STEP + SIM_SECONDS_PER_DESIGN_STEP * n_designs)
    return n_designs * recorded * SIM_BYTES_PER_SAMPLE, seconds


def check_count(name: str, text: str, n: float) -> int:
    """A list or range expanding to ``n`` values: at most :data:`MAX_VALUES`."""
    from seactl.errors import InputError

    if not math.isfinite(n) or n > MAX_VALUES:
        size = f"{n:.3g} values, {human_bytes(8 * n)}" if math.isfinite(n) else "unbounded"
        raise InputError(name, text, f"at most {MAX_VALUES:.0e} values (this is {size})")
    return int(n)


RECORD_DT_S = 5e-4
"""Recording interval of the command line's continuous simulations [s]."""


def check_simulation(n_designs: int, mode: str, rate_hz: float, t_end_s: float,
                     delays_s: list[float], *, record_dt_s: float | None = None,
                     rate_name: str = "rate_hz", t_end_name: str = "t_end_s",
                     hint: str = "shorten t_end_s, lower rate_hz, or simulate fewer designs"
                     ) -> None:
    """Check a simulation before it allocates: the rate and duration in their ranges, at
    least :data:`MIN_SAMPLES` recorded samples, and memory and time within the machine's.

    The continuous mode steps at ``min(0.1 ms, smallest positive delay)`` and records every
    ``record_dt_s`` (every step when ``None``); the sampled mode steps at ``1/rate_hz``.
    """
    from seactl.errors import InputError

    check_range(t_end_name, t_end_s, "t_end_s")
    if mode == "sampled":
        check_range(rate_name, rate_hz, "rate_hz")
        steps = recorded = t_end_s * rate_hz
        need = f"{t_end_name} x {rate_name} >= {MIN_SAMPLES}"
    else:
        dt = min([1e-4, *(d for d in delays_s if d > 0)])
        steps = t_end_s / dt
        rec = max(dt, record_dt_s or dt)
        recorded = t_end_s / rec
        need = f"{t_end_name} >= {MIN_SAMPLES} x {rec * 1e3:g} ms (the recording step)"
    if recorded < MIN_SAMPLES:
        raise InputError(t_end_name, t_end_s, f"long enough to record {MIN_SAMPLES} samples "
                         f"({need})")
    n_bytes, seconds = simulation_estimate(n_designs, steps, recorded)
    check_budget(f"simulating {n_designs:,} design(s) over {steps:,.4g} steps",
                 n_bytes=n_bytes, seconds=seconds,
                 hint=hint + ("" if mode == "sampled" else " (the continuous mode steps at "
                              "min(0.1 ms, the smallest positive delay))"))


def check_delay_buffers(n_designs: int, n_delayed: int, samples: float, step_s: float) -> None:
    """Refuse up front delay buffers larger than the machine's memory: a simulation keeps,
    per delayed block and design, a ring of the longest delay's ``samples`` steps of
    ``step_s`` [s] (8 bytes each), so the memory grows with the delay's length."""
    n_bytes = 8.0 * n_designs * max(n_delayed, 1) * (float(samples) + 3.0)
    check_budget(f"the simulation's delay buffers ({float(samples):,.4g} steps of "
                 f"{step_s:.3g} s hold its longest delay, {float(samples) * step_s:.4g} s)",
                 n_bytes=n_bytes, hint="shorten the longest delay, simulate fewer designs, "
                                       "or (sampled) lower the rate")


SAMPLED_SECONDS_PER_STATE3 = 1e-7
"""Time per design and cubed state of the sampled loop's verdict (period map,
eigenvalues, Stein certificate), and per frequency of its margin scan
(:mod:`seactl.simulate.sampled`); rounded up."""
SAMPLED_MAX_STATES = 2000
"""Largest period-map state of a sampled-loop analysis (a 2 s buffer at 1 kHz)."""


def check_sampled_analysis(n_designs: int, states: int, frequencies: int = 0,
                           reduced: int = 0, rate_hz: float | None = None) -> None:
    """Refuse a sampled-loop analysis whose work, ``n S^3`` for the verdict plus
    ``n x frequencies x r^3`` for the margins (``r`` the reduced system of
    :mod:`seactl.simulate.sampled`), exceeds :func:`time_budget_s`, or whose state is longer than
    :data:`SAMPLED_MAX_STATES`, with the estimate."""
    from seactl.errors import InputError

    if states > SAMPLED_MAX_STATES:
        raise InputError("rate_hz", rate_hz,
                         f"a rate giving a sampled loop of at most {SAMPLED_MAX_STATES} states "
                         f"(with these delays it has {states}: each delay buffer holds "
                         "rate x delay samples); lower the rate or the delays")
    per = (float(states) ** 3 + frequencies * float(reduced) ** 3) * SAMPLED_SECONDS_PER_STATE3
    seconds = n_designs * per
    if seconds > time_budget_s():
        most = max(1, int(time_budget_s() / per))
        raise InputError("designs", n_designs,
                         f"at most {most:,} designs for a sampled-loop analysis with "
                         f"{states} states{' and its margins' if frequencies else ''} "
                         f"(estimate {human_seconds(seconds)}, limit "
                         f"{human_seconds(time_budget_s())}, SEACTL_MAX_SECONDS)")


# ------------------------------------------------------------------ loop files
MAX_LOOP_BLOCKS = 64
"""Most blocks a loop file may declare (the examples use 7 to 14)."""
MAX_LOOP_SIGNALS = 80
"""Most signals of a compiled loop (a block's signed inputs and a disturbance observer add
internal ones; the examples have 8 to 17): its transfers are derived symbolically, at a
cost that grows as the cube of this count (:data:`DERIVE_SECONDS_PER_SIGNAL3`)."""
DERIVE_SECONDS_PER_SIGNAL3 = 2.5e-5
"""Time to derive a loop's transfers, per signal cubed (fitted on chains of filters, the
simplest structure: a lower bound for denser loops)."""
MAX_LOOP_ORDER = 32
"""Highest order of a loop (the sum over its blocks of the larger of numerator and
denominator degree; the examples: 3 to 10).  Its characteristic quasi-polynomial is
evaluated from expanded coefficients in double precision, which blurs clustered roots as
the order grows (the limit keeps a margin below the lowest order at which a chain of equal
filters is judged wrongly) and overflows near order 100."""
MAX_LOOP_NAMES = 256
"""Most variables and parameters of a loop file (ordering the parameters grows as the
cube of their count)."""
MAX_LOOP_FILE_BYTES = 1 << 20
"""Largest loop file read (a loop at every other limit fits in a few dozen kB)."""
MAX_EXPR_CHARS = 1000
"""Longest expression of a loop file, in characters."""
MAX_EXPR_DEPTH = 32
"""Deepest nesting of an expression (operators, parentheses and calls)."""
MAX_NESTING = 16
"""Deepest nesting of a loop file's arrays and tables (the examples: 2)."""


def derive_seconds(n_signals: int) -> float:
    """Estimated time to derive the transfers of a loop of ``n_signals`` signals [s]."""
    return DERIVE_SECONDS_PER_SIGNAL3 * float(n_signals) ** 3


MAX_ROOTS = 50
"""Most rightmost roots asked per design (``count``; a conjugate pair counts once)."""
ROOTS_SECONDS_PER_DESIGN = 1e-3
"""Upper bound of the time per design of the roots without a delay (companion
eigenvalues) and of reporting them."""
ROOTS_SECONDS_PER_ROOT = 8e-3
"""Upper bound of the time per design and root asked of a delayed design (the
collocation grows until the roots converge)."""


def check_roots(n_designs: int, count: Any, delayed: bool, hint: str = "ask for fewer "
                "designs or roots") -> int:
    """``count`` an integer in [1, :data:`MAX_ROOTS`], and the time for ``n_designs``
    designs within :func:`time_budget_s`; returns ``count``."""
    from seactl.errors import InputError

    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) \
            or not 1 <= count <= MAX_ROOTS:
        raise InputError("count", count, f"an integer in [1, {MAX_ROOTS}] (roots per design)")
    seconds = n_designs * (ROOTS_SECONDS_PER_DESIGN + delayed * ROOTS_SECONDS_PER_ROOT
                           * int(count))
    check_budget(f"{count} root(s) of each of {n_designs:,} design(s)", seconds=seconds,
                 hint=hint)
    return int(count)
