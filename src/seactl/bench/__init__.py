"""``seactl bench``: benchmarks against baselines measured in the same run.

A benchmark is a function registered with :func:`benchmark`; it returns a
:class:`BenchResult`.  Use :func:`median_time` to time both sides (median of
``repeat`` runs, after one warm-up).  Speed is never asserted in tests.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True)
class BenchResult:
    name: str
    throughput_per_s: float
    baseline: str
    baseline_throughput_per_s: float
    max_error: float
    note: str = ""
    max_error_text: str = ""

    @property
    def ratio(self) -> float:
        return self.throughput_per_s / self.baseline_throughput_per_s

    def as_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["ratio"] = self.ratio
        return d


_BENCHMARKS: dict[str, Callable[[int], BenchResult | list[BenchResult]]] = {}


def benchmark(name: str) -> Callable:
    """Register ``func(repeat) -> BenchResult | list[BenchResult]`` under ``name``."""

    def deco(func):
        _BENCHMARKS[name] = func
        return func

    return deco


def median_time(func: Callable[[], Any], repeat: int, warmup: int = 1) -> float:
    """Median wall time [s] of ``func()`` over ``repeat`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        func()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        func()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def registered() -> dict[str, Callable]:
    from . import (
        base,  # noqa: F401
        core,  # noqa: F401 - registration side effects
        impedance,  # noqa: F401
        placement,  # noqa: F401
        simulate,  # noqa: F401
        sweep,  # noqa: F401
    )

    return dict(_BENCHMARKS)


def run_benchmarks(only: Iterable[str] | None = None, repeat: int = 5,
                   console: Any = None) -> list[dict[str, Any]]:
    from ..errors import InputError

    benches = registered()
    names = list(benches)
    if only:
        unknown = set(only) - set(names)
        if unknown:
            raise InputError("--only", ", ".join(sorted(unknown)), "one of " + ", ".join(names))
        names = [n for n in names if n in set(only)]
    out: list[dict[str, Any]] = []
    for name in names:
        if console is not None:
            console.print(f"running {name} ...")
        res = benches[name](repeat)
        for r in res if isinstance(res, list) else [res]:
            out.append(r.as_json())
    return out
