"""``seactl bench``: benchmarks against baselines measured in the same run.

A benchmark is a function tagged with :func:`benchmark` and listed in
:data:`BENCHMARKS`; it returns a
:class:`BenchResult`.  Use :func:`median_time` to time both sides (median of
``repeat`` runs, after one warm-up).  Speed is never asserted in tests.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from . import (
    core,
    impedance,
    jitter,
    loopfile,
    mobile_base,
    placement,
    robot,
    roots,
    simulate,
    sweep,
)
from ._harness import BenchResult, benchmark, median_time

__all__ = ["BENCHMARKS", "BenchResult", "benchmark", "median_time", "registered",
           "run_benchmarks"]


BENCHMARKS: tuple[Callable, ...] = (
    core.bench_gain_design, core.bench_margins, roots.bench_roots, loopfile.bench_loop_file,
    impedance.bench_impedance,
    simulate.bench_simulate, placement.bench_latency_map, sweep.bench_sweep,
    mobile_base.bench_circle, mobile_base.bench_tuning, core.bench_cli_startup,
    jitter.bench_jitter, robot.bench_robot_breaks,
)


def registered() -> dict[str, Callable]:
    """The benchmarks by name, in run order."""
    return {f.bench_name: f for f in BENCHMARKS}


def run_benchmarks(only: Iterable[str] | None = None, repeat: int = 5) -> list[dict[str, Any]]:
    """The benchmarks (all, or those in ``only``) as JSON dicts, each the median of
    ``repeat`` timed runs; progress (one step per benchmark) goes to
    :mod:`seactl.base.progress`."""
    from seactl.base import progress
    from seactl.errors import InputError

    benches = registered()
    names = list(benches)
    if only:
        unknown = set(only) - set(names)
        if unknown:
            raise InputError("only", ", ".join(sorted(unknown)), "one of " + ", ".join(names))
        names = [n for n in names if n in set(only)]
    out: list[dict[str, Any]] = []
    with progress.stage("benchmarks", total=len(names)) as stage:
        for name in names:
            progress.note(f"benchmark {name} ...")
            res = benches[name](repeat)
            for r in res if isinstance(res, list) else [res]:
                out.append(r.as_json())
            stage.advance(item=name)
    return out
