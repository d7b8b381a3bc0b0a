"""What every benchmark uses: the result record, the tag and the timer."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from seactl.base.result import Result, new_axes


@dataclass(frozen=True)
class BenchResult(Result):
    """One benchmark against its baseline.

    Attributes
    ----------
    name : str
        The benchmark.
    throughput_per_s : float
        Work units per second, ours.
    baseline : str
        What it is compared with.
    baseline_throughput_per_s : float
        Work units per second, the baseline.
    max_error : float
        Largest relative difference from the baseline's answer (dimensionless).
    note, max_error_text : str
        Remarks, and the error in words where a number does not say it.
    ratio : float
        ``throughput_per_s / baseline_throughput_per_s``.
    """

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

    def to_dict(self) -> dict[str, Any]:
        """Every field and the ratio.

        Returns
        -------
        dict
            As :meth:`as_json`.
        """
        return self.as_json()

    def records(self) -> list[dict[str, Any]]:
        """The one row of :meth:`to_dict`.

        Returns
        -------
        list of dict
            ``[to_dict()]``.
        """
        return [self.as_json()]

    def plot(self, ax: Any = None) -> Any:
        """Our throughput next to the baseline's.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        ax.bar(["seactl", self.baseline[:30]],
               [self.throughput_per_s, self.baseline_throughput_per_s])
        ax.set_yscale("log")
        ax.set_ylabel("throughput [1/s]")
        ax.set_title(self.name)
        return ax


def benchmark(name: str) -> Callable:
    """Tag ``func(repeat) -> BenchResult | list[BenchResult]`` with its name; the list of
    benchmarks is :data:`seactl.apps.bench.BENCHMARKS`."""

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
