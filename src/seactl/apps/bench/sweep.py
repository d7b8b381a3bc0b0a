"""Benchmark of ``seactl sweep``: a 1,000,000-point margin sweep on local Dask workers.

Reports (target: 1e6 points in under 60 s on two cores, start-up included; the
workers' CPU time at least 1.8 of the two cores over the run on started workers):

* ``sweep-1e6``: points per second of the whole run as a fresh process makes it (the
  workers' template start, cluster start, computing, writing Parquet, cluster close)
  on 2 local worker processes, against
  the same points computed one by one (scalar gain design + margins per
  point, measured on a sample).  ``max_error``: largest phase-margin
  difference [deg] between the dataset and the one-by-one results.
* ``sweep-scaling``: the same sweep on 2 workers against 1 worker, on started workers
  (``max_error``: largest difference between the two datasets).  The workers fork from
  a template that has loaded the sweep's modules and kernels (``seactl.sweep.template``),
  started once per process; its start, and the cluster's start and close, are reported
  apart in the note, with the whole runs' speed-up.  Where the platform cannot fork
  (Windows) each worker loads them on its first chunk, inside the timing.

The grid is f_n (100 values, 10-40 Hz) x GS (100 values, 0.3-3) x T_qs
(0-20 ms), Table I's other delays and filters.  ``SEACTL_BENCH_SWEEP_POINTS``
sets a smaller size (e.g. 100000) for a quick look; the default is 1e6 (sizes round up
to whole T_qs planes of 10,000 points).
The peak memory of one chunk is measured with ``tracemalloc`` in this process,
and the workers' peak resident set size is reported by the sweep itself, as are the
workers' CPU time (their chunks') and this process's (the parent: client, scheduler and
nannies), each also as a share of the wall time of the run on started workers.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from ._harness import BenchResult, benchmark

_ONE_BY_ONE = 120  # points of the scalar baseline


def bench_spec(n_points: int, chunk_size: int = 5000):
    from seactl.sweep.spec import SweepSpec
    from seactl.systems.sea.actuators import UT_SEA

    n_tqs = max(1, -(-n_points // 10_000))
    axes = (("fn_hz", tuple(np.linspace(10.0, 40.0, 100))),
            ("gs", tuple(np.linspace(0.3, 3.0, 100))),
            ("t_tau_ms", (0.5,)), ("t_qs_ms", tuple(np.linspace(0.0, 20.0, n_tqs))),
            ("t_qd_ms", (0.5,)), ("f_qd_hz", (50.0,)), ("f_taud_hz", (100.0,)))
    return SweepSpec(UT_SEA, axes, chunk_size=chunk_size)


def _template_start_s() -> float:
    """Seconds until the workers' template is started and ready to fork (a few ms once
    done in this process; :func:`seactl.sweep.engine.start_worker_template`)."""
    from seactl.sweep.engine import start_worker_template, worker_environ

    t0 = time.perf_counter()
    start_worker_template(worker_environ())
    return time.perf_counter() - t0


def _timed_run(spec, workers: int, root: Path) -> tuple[float, float, float, object]:
    """Wall time of a whole run (LocalCluster start and close included), the start-up
    part, and the run on the started workers alone (where they spawn instead of forking
    from the template, their imports included)."""
    from distributed import Client

    from seactl.sweep.engine import local_cluster, run_sweep

    out = root / f"w{workers}"
    t0 = time.perf_counter()
    cluster = local_cluster(workers)
    try:
        with Client(cluster) as client:
            client.wait_for_workers(workers)
            startup = time.perf_counter() - t0
            res = run_sweep(spec, out, client=client)
            on_workers = time.perf_counter() - t0 - startup
    finally:
        cluster.close()
    return time.perf_counter() - t0, startup, on_workers, res


def _cpu_note(res, seconds: float) -> str:
    """The workers' and the parent's CPU time over the ``seconds`` of a run on started
    workers: a parent near one core, or workers short of their count, is a bottleneck."""
    return (f"CPU over the {seconds:.2f} s on started workers: workers "
            f"{res.worker_cpu_seconds:.2f} s ({res.worker_cpu_seconds / seconds:.2f} cores busy "
            f"of {res.workers}), parent (client, scheduler, nannies) "
            f"{res.parent_cpu_seconds:.2f} s ({res.parent_cpu_seconds / seconds:.2f} of a core, "
            f"{res.parent_cpu_seconds / res.worker_cpu_seconds:.1%} of the workers')")


def _one_by_one(spec, points: np.ndarray) -> tuple[float, np.ndarray]:
    """Seconds per point and phase margins of ``points`` computed one at a time."""
    from seactl.systems.sea.design import critically_damped_gains
    from seactl.systems.sea.loops import SEADesign, Timing
    from seactl.systems.sea.views import sea_margins

    fixed = spec.fixed()
    vals = {n: np.asarray(v) for n, v in spec.swept}
    multi = np.unravel_index(points, spec.grid_shape)
    rows = [{n: float(vals[n][m[i]]) for (n, _), m in zip(spec.swept, multi)}
            for i in range(points.size)]
    pm = np.empty(points.size)

    def run():
        for i, r in enumerate(rows):
            p = {**fixed, **r}
            g = critically_damped_gains(spec.actuator, p["fn_hz"], gs=p["gs"])
            t = Timing.from_ms(p["t_tau_ms"], p["t_qs_ms"], p["t_qd_ms"], p["f_qd_hz"],
                               p["f_taud_hz"])
            pm[i] = float(sea_margins(SEADesign(spec.actuator, g, t)).phase_margin_deg)

    run()  # warm-up (symbolic derivation cached)
    t0 = time.perf_counter()
    run()
    return (time.perf_counter() - t0) / points.size, pm


def chunk_peak_memory_mb(spec) -> float:
    """Peak traced allocation [MB] while evaluating chunk 0 in this process."""
    from seactl.sweep.evaluate import evaluate_chunk

    evaluate_chunk(spec, 0)  # warm caches so only the chunk's arrays are traced
    tracemalloc.start()
    try:
        evaluate_chunk(spec, 0)
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


@benchmark("sweep")
def bench_sweep(repeat: int) -> list[BenchResult]:
    import pyarrow.parquet as pq

    from seactl.sweep.dataset import read_sweep

    n = int(os.environ.get("SEACTL_BENCH_SWEEP_POINTS", "1000000"))
    spec = bench_spec(n)
    root = Path(tempfile.mkdtemp(prefix="seactl-bench-sweep-"))
    try:
        mem_mb = chunk_peak_memory_mb(spec)
        template = _template_start_s()
        wall, startup, r2, res = _timed_run(spec, 2, root)
        # baseline: a sample of the same points, one by one
        rng = np.random.default_rng(0)
        pts = np.sort(rng.choice(spec.n_points, size=min(_ONE_BY_ONE, spec.n_points),
                                 replace=False))
        per_point, pm_ref = _one_by_one(spec, pts)
        chunk_of = pts // spec.chunk_size
        pm_sweep = np.empty(pts.size)
        for c in np.unique(chunk_of):
            t = pq.read_table(root / "w2" / f"part-{c:05d}.parquet",
                              columns=["point", "phase_margin_deg"])
            idx = pts[chunk_of == c] - c * spec.chunk_size
            pm_sweep[chunk_of == c] = t.column("phase_margin_deg").to_numpy()[idx]
        err = float(np.max(np.abs(pm_sweep - pm_ref)))
        rss = res.worker_peak_rss_mb
        cpu_rate = spec.n_points / res.worker_cpu_seconds
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        fresh = template + wall  # what a fresh process (the command line) takes
        main = BenchResult(
            "sweep-1e6" if n == 1_000_000 else f"sweep-{n}", spec.n_points / fresh,
            "same points one by one (scalar design + margins)", 1.0 / per_point, err,
            note=(f"{spec.n_points:,} points, 2 local worker processes: {fresh:.1f} s wall "
                  f"including {template:.1f} s for the workers' template and {startup:.1f} s "
                  f"cluster start (target < 60 s: {'met' if fresh < 60 else 'NOT met'}; load "
                  f"average {load:.1f} on {os.cpu_count()} cores); workers' CPU time "
                  f"{res.worker_cpu_seconds:.1f} s = {cpu_rate:,.0f} points per CPU-second, "
                  f"i.e. {res.worker_cpu_seconds / fresh:.2f} workers busy on average over the "
                  f"wall time (on 2 idle cores: about "
                  f"{template + startup + res.worker_cpu_seconds / 2:.0f} s); "
                  f"{_cpu_note(res, r2)}; {res.n_chunks} "
                  f"chunks of {spec.chunk_size}; peak traced memory of one chunk {mem_mb:.0f} MB "
                  f"({1e3 * mem_mb / spec.chunk_size:.1f} kB/point), worker peak RSS "
                  f"{rss:.0f} MB; single run (repeat ignored); max_error in PM degrees over "
                  f"{pts.size} sampled points"))
        w1, s1, r1, res1 = _timed_run(spec, 1, root)
        a, b = read_sweep(root / "w1"), read_sweep(root / "w2")
        diff = 0.0 if a.equals(b) else float(np.nanmax(np.abs(
            np.asarray(a.column("phase_margin_deg")) - np.asarray(b.column("phase_margin_deg")))))
        scaling = BenchResult(
            "sweep-scaling", spec.n_points / r2, "1 worker", spec.n_points / r1, diff,
            note=(f"{spec.n_points:,} points on started workers: 1 worker {r1:.2f} s, 2 "
                  f"workers {r2:.2f} s (speed-up {r1 / r2:.2f}); 1 worker: {_cpu_note(res1, r1)}; "
                  "whole runs with the "
                  f"cluster's start and close: {w1:.1f} s and {wall:.1f} s (speed-up "
                  f"{w1 / wall:.2f}; start-up {s1:.1f} / {startup:.1f} s), plus "
                  f"{template:.1f} s once per process for the workers' template; "
                  "max_error: 0 means identical datasets"))
        return [main, scaling]
    finally:
        shutil.rmtree(root, ignore_errors=True)
