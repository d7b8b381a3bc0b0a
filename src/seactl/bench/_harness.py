"""What every benchmark uses: the result record, the tag and the timer."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
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


def benchmark(name: str) -> Callable:
    """Tag ``func(repeat) -> BenchResult | list[BenchResult]`` with its name; the list of
    benchmarks is :data:`seactl.bench.BENCHMARKS`."""

    def deco(func):
        func.bench_name = name
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
