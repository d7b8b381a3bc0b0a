"""Design-space sweeps: chunked, resumable, on local cores or a Dask cluster.

A :class:`SweepSpec` describes a set of SEA designs: a Cartesian grid, or
random / Latin-hypercube samples, over any design option (``fn_hz``, ``gs``,
``zeta1``, ``zeta2``, ``ratio``, ``t_tau_ms``, ``t_qs_ms``, ``t_qd_ms``,
``f_qd_hz``, ``f_taud_hz``) and over the actuator parameters (``Im``, ``Ij``,
``bm``, ``bj``, ``k``, ``beta``, rotary SI units).  An axis with one value is
fixed; in the sampling modes an axis with several values is the interval
``[min, max]``.

Points have a deterministic order (grid: C order over the axes in the order of
:data:`AXES`; samples: chunk by chunk from a seed), and chunk ``i`` holds points
``[i*C, (i+1)*C)``.  A chunk's points are generated from the spec alone (the
grid is never materialized), evaluated with the vectorized gain design and
margins, and written as one Parquet file ``part-NNNNN.parquet`` (temporary
name, then ``os.replace``) into the output directory, next to
``_manifest.json`` (the spec and its hash) and ``_summary.json``.  Finished
chunks survive any interruption; :func:`run_sweep` with ``resume=True``
computes only the missing ones and refuses a directory made by another spec.

Semantics of actuator axes: the controller gains are always designed for the
*nominal* actuator (``spec.actuator``, the controller does not know the real
plant) and the loop is evaluated with the perturbed plant parameters.  An
``f_n`` with no critically-damped gain set is an *infeasible* row
(``feasible = False``, gains and margins null), never a crash.

Examples
--------
>>> from seactl.systems.sea.actuators import UT_SEA
>>> spec = SweepSpec(UT_SEA, axes=(("fn_hz", (8.0, 12.0, 14.0)), ("t_qs_ms", (0.0, 2.0))),
...                  chunk_size=4)
>>> spec.n_points, spec.n_chunks
(6, 2)
>>> t = evaluate_chunk(spec, 0)[0]
>>> t.column("feasible").to_pylist()       # 8 Hz is below the feasible f_n range
[False, False, True, True]
>>> [round(x, 1) for x in t.column("phase_margin_deg").to_pylist()[2:]]
[54.4, 48.7]
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from seactl.base import progress
from seactl.base.result import Result, json_value, new_axes
from seactl.errors import InputError, Terminated
from seactl.sweep.dataset import (
    SUMMARY,
    check_output,
    missing_chunks,
    part_path,
    prepare_output,
    remove_new_sweep,
    write_manifest,
)
from seactl.sweep.evaluate import (
    batches,
    chunk_summary,
    evaluate_and_write,
    evaluate_chunk,
    summary_columns,
    write_part,
)
from seactl.sweep.spec import TEMPLATE_MARKER, SweepSpec


# ------------------------------------------------------------------ execution
@dataclass(frozen=True)
class SweepResult(Result):
    """Outcome of :func:`run_sweep`: where the data went, counts and timing.

    Attributes
    ----------
    out : pathlib.Path
        The dataset's directory (read it with :func:`read_sweep`).
    spec_hash : str
        Hash of the sweep's specification (a resumed sweep must match it).
    n_points, n_chunks : int
        Design points and chunks of the whole sweep.
    chunks_computed, points_computed : int
        Chunks and points computed by this run (the rest were there already).
    seconds : float
        Wall time of this run [s].
    workers : int
        Worker processes (0: this process).
    worker_peak_rss_mb : float
        Largest resident set of a worker [MB].
    worker_cpu_seconds, parent_cpu_seconds : float
        CPU time of the workers and of this process [s].
    summary : dict
        Counts of feasible and stable points, a sample of phase margins (``pm_sample``,
        [deg]) and the best point.
    points_per_s : float
        Points computed per second of wall time.
    """

    out: Path
    spec_hash: str
    n_points: int
    n_chunks: int
    chunks_computed: int
    points_computed: int
    seconds: float
    workers: int
    worker_peak_rss_mb: float
    worker_cpu_seconds: float = 0.0
    summary: dict[str, Any] = field(default_factory=dict)
    parent_cpu_seconds: float = 0.0
    """CPU time of this process over ``seconds``, every thread: the progress bar, the
    client, and for a local cluster its scheduler and nannies (``workers=0``: the chunks)."""

    @property
    def points_per_s(self) -> float:
        """Points computed in this run per second of wall time (start-up included)."""
        return self.points_computed / self.seconds if self.seconds > 0 else float("nan")

    def records(self) -> list[dict[str, Any]]:
        """One flat row: the counts and timing of this run.

        Returns
        -------
        list of dict
            ``out`` and every count and time above (not ``summary``).
        """
        keys = ("spec_hash", "n_points", "n_chunks", "chunks_computed", "points_computed",
                "seconds", "workers", "worker_peak_rss_mb", "worker_cpu_seconds",
                "parent_cpu_seconds", "points_per_s")
        return [{"out": str(self.out), **{k: json_value(getattr(self, k)) for k in keys}}]

    def to_dict(self) -> dict[str, Any]:
        """The row of :meth:`records` with the summary's counts.

        Returns
        -------
        dict
            As :meth:`records`, plus ``n``, ``feasible`` and ``stable`` points.
        """
        counts = {k: json_value(self.summary[k]) for k in ("n", "feasible", "stable")
                  if k in self.summary}
        return {**self.records()[0], **counts}

    def plot(self, ax: Any = None) -> Any:
        """Histogram of the phase margin over the stable points (the summary's sample).

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
        pm = np.asarray(self.summary.get("pm_sample", []), float)
        ax.hist(pm[np.isfinite(pm)], bins=40, color="tab:blue")
        ax.set_xlabel("phase margin [deg]")
        ax.set_ylabel("stable points")
        return ax


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM: ``terminated``) during a sweep; finished chunks are kept
    (``done`` of ``total``)."""

    def __init__(self, out: Path, done: int, total: int, terminated: bool = False):
        self.out, self.done, self.total = out, done, total
        self.terminated = terminated
        super().__init__(f"{'terminated' if terminated else 'interrupted'}: {done} of "
                         f"{total} chunks are on disk in {out}; rerun the same command with "
                         "--resume to finish")


@contextlib.contextmanager
def uninterrupted():
    """Ctrl-C and SIGTERM ignored meanwhile (in the main thread): closing the workers is
    not cut short by a second Ctrl-C, which would leave them and their files behind."""
    if not _main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT,
                                                                    signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


SCHEDULER_HTTP = {"dashboard_address": "127.0.0.1:0"}
"""``scheduler_kwargs`` of a local cluster: the scheduler's HTTP server (its health and
metrics routes, started even without a dashboard) on loopback at a free port, not on
Dask's default 8787, which another cluster on the machine may hold."""


def local_cluster(workers: int, scratch: str | None = None):
    """One single-threaded worker process per core (dashboard, profiler off; the
    scheduler's HTTP server as :data:`SCHEDULER_HTTP`), forked from
    a warm template where the platform allows (:func:`start_worker_template`), with their
    files in ``scratch`` (default: Dask's ``dask-scratch-space`` in the temporary directory,
    which Dask leaves behind).

    Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536`` in its workers (to return
    memory to the OS); with the margin kernel's many short-lived arrays of a few MB
    that turns the chunk's allocations into page faults.  The workers here keep glibc's
    default, adaptive thresholds; memory stays bounded by the chunk size."""
    import logging

    import dask
    from distributed import LocalCluster

    environ = worker_environ()
    method = start_worker_template(environ)
    # Ctrl-C while the cluster starts would leave it half built (tracebacks from Dask's
    # exit handler and the workers).  Spawned workers inherit an ignored SIGINT (it
    # survives exec), so there it is ignored; forked workers ignore it from the template,
    # so there it is noted and acted on once the cluster is up (a fraction of a second).
    interrupted: list[int] = []
    handler = signal.SIG_IGN if method == "spawn" else lambda *_: interrupted.append(1)
    previous = signal.signal(signal.SIGINT, handler) if _main_thread() else None
    try:
        # no statistical profiler sampling every worker's stack every 10 ms, no GIL
        # sampling every 1 ms (where gilknocker is installed), health ticks and memory
        # checks once a second (a chunk's memory is bounded): nobody reads them without a
        # dashboard, and each runs in every process, the parent's scheduler and nannies
        # included, taking time from the chunks.  Logs: a failed chunk reaches the caller
        # as its exception; after Ctrl-C a worker's heartbeat can meet the closing
        # scheduler and log an ERROR with its traceback
        with dask.config.set({"distributed.nanny.pre-spawn-environ": environ,
                              "distributed.worker.multiprocessing-method": method,
                              "distributed.worker.profile.enabled": False,
                              "distributed.admin.system-monitor.gil.enabled": False,
                              "distributed.worker.memory.monitor-interval": "1s",
                              "distributed.admin.tick.interval": "1s",
                              "distributed.admin.system-monitor.interval": "2s",
                              **({} if scratch is None else {"temporary-directory": scratch})}):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, scheduler_kwargs=SCHEDULER_HTTP,
                                   silence_logs=logging.CRITICAL,
                                   preload=["seactl.sweep.worker"])
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if interrupted:
        cluster.close()
        raise KeyboardInterrupt
    return cluster


def worker_environ() -> dict[str, str]:
    """Dask's environment for its workers, without ``MALLOC_TRIM_THRESHOLD_``
    (:func:`local_cluster`)."""
    import dask

    return {k: str(v) for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ",
                                                   default={}) or {}).items()
            if k != "MALLOC_TRIM_THRESHOLD_"}


def start_worker_template(environ: dict[str, str]) -> str:
    """Start the template that local workers fork from, and wait until it is ready; the
    start method to give Dask.

    ``"forkserver"``: multiprocessing's fork server is started (once per process), with
    :data:`TEMPLATE_MARKER` in its environment, and imports :mod:`seactl.sweep.template`,
    which then loads the sweep's modules and kernels.
    Every worker forked from it starts with them loaded.  ``"spawn"``: the platform
    has no fork server (Windows).

    A spawned worker imports and loads the kernels before its first chunk, and its
    interpreter's exit lengthens the cluster's close; a forked worker does neither; the
    server itself starts once per process (``seactl bench``'s sweep figures include it).

    The server gets the workers' environment ``environ`` (:func:`worker_environ`, which
    the nanny also sets before each worker), so its BLAS starts no threads to fork.  A fork server
    already running in this process is used as it is: if other code started it without
    the template, each worker warms itself as it starts (its Dask preload,
    :func:`seactl.sweep.worker.dask_setup`)."""
    import multiprocessing
    from multiprocessing import forkserver

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return "spawn"
    import dask
    from distributed.utils import get_mp_context

    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()  # Dask sets its own preload list once per process: before ours
    multiprocessing.set_forkserver_preload(["seactl.sweep.template"])
    os.environ.update(environ)
    os.environ[TEMPLATE_MARKER] = "1"  # (the server copies this process's environment)
    try:
        forkserver.ensure_running()
    finally:
        os.environ.pop(TEMPLATE_MARKER, None)
    # wait until it has warmed (at once if it has): here Ctrl-C still stops cleanly
    ready = multiprocessing.get_context("forkserver").Process(target=os.getpid)
    ready.start()
    ready.join()
    return "forkserver"


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def run_sweep(spec: SweepSpec, out: Path | str, *, resume: bool = False,
              overwrite: bool = False, workers: int | None = None,
              scheduler: str | None = None, client: Any = None,
              _on_chunk: Callable[[int], None] | None = None) -> SweepResult:
    """Run (or complete, with ``resume``) a sweep into the Parquet dataset ``out``.

    Parameters
    ----------
    workers : int, optional
        Local Dask worker processes (default: all cores); ``0`` evaluates the
        chunks one after the other in this process, without Dask.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://HOST:PORT``); seactl must
        be importable on its workers.  Results come back to this process, which
        writes them, so workers need no shared filesystem.
    client : distributed.Client, optional
        Use this client (and leave it open).

    Progress (the chunks written) goes to :mod:`seactl.base.progress`.  Chunks are
    submitted to Dask with ``retries=2`` and written as they complete; on Ctrl-C the
    pending ones are cancelled and :class:`SweepInterrupted` is raised, every written
    chunk staying on disk.
    """
    if not os.fspath(out).strip():
        raise InputError("out", os.fspath(out), "a directory path")
    out = Path(out)
    if workers is not None and workers < 0:
        raise InputError("workers", workers, ">= 0 (0: in this process)")
    check_output(spec, out, resume=resume, overwrite=overwrite)
    own_client = None
    if client is None and scheduler is not None:   # reachable before anything is written
        own_client = client = _connect(scheduler)
    new_dir = not out.exists() or overwrite or not any(out.iterdir())
    try:
        prepare_output(spec, out, resume=resume, overwrite=overwrite)
        progress.note(f"sweep: {spec.n_points:,} points in {spec.n_chunks:,} chunks of "
                      f"{spec.chunk_size:,} -> {out}" + (f" on {scheduler}" if scheduler else ""))
        return _run(spec, out, workers, client, own_client, _on_chunk)
    except BaseException as exc:
        if new_dir and not isinstance(exc, KeyboardInterrupt) and out.is_dir() \
                and not any(out.glob("part-*.parquet")):
            remove_new_sweep(out)
        raise
    finally:
        if own_client is not None:
            own_client.close()


def _run(spec: SweepSpec, out: Path, workers: int | None, client: Any, own_client: Any,
         _on_chunk: Callable[[int], None] | None) -> SweepResult:
    todo = missing_chunks(spec, out)
    own_cluster = scratch = None
    t0, c0 = time.perf_counter(), time.process_time()
    peak = 0.0
    done = spec.n_chunks - len(todo)
    n_workers = 0
    computed = points = 0
    cpu = 0.0
    parts: dict[int, dict[str, Any]] = {}
    try:
        with progress.stage("sweep", total=spec.n_chunks, unit="chunks") as bar:
            bar.advance(done)

            def finish(i: int, rows: int, part: dict[str, Any], stats: dict[str, float]
                       ) -> None:
                """Chunk ``i`` is on disk with ``rows`` rows (``part``: its share of the
                summary)."""
                nonlocal peak, computed, points, cpu
                parts[i] = part
                cpu += stats["cpu_seconds"]
                points += rows
                peak = max(peak, stats["peak_rss_mb"])
                computed += 1
                bar.advance()
                if _on_chunk is not None:
                    _on_chunk(i)

            if todo and workers == 0 and client is None:
                for i in todo:
                    table, stats = evaluate_chunk(spec, i)
                    finish(i, *write_part(spec, out, i, table), stats)
            elif todo:
                from distributed import Client

                if client is None:
                    scratch = tempfile.mkdtemp(prefix="seactl-sweep-")
                    own_cluster = local_cluster(workers or os.cpu_count() or 1, scratch)
                    own_client = client = Client(own_cluster)
                n_workers = len(client.scheduler_info(n_workers=-1)["workers"])
                _on_dask(spec, out, todo, client, finish, n_workers)
    except KeyboardInterrupt as exc:
        have = spec.n_chunks - len(missing_chunks(spec, out))
        raise SweepInterrupted(out, have, spec.n_chunks, isinstance(exc, Terminated)) from None
    finally:
        with uninterrupted():
            if own_cluster is not None:
                own_client.close()
                own_cluster.close()
            if scratch is not None:   # the workers' files (removed after they stopped)
                shutil.rmtree(scratch, ignore_errors=True)
    summary = summarize(spec, out, parts)
    seconds, parent_cpu = time.perf_counter() - t0, time.process_time() - c0
    summary["run"] = {"chunks_computed": computed, "seconds": round(seconds, 3),
                      "workers": n_workers, "worker_peak_rss_mb": round(peak, 1),
                      "worker_cpu_seconds": round(cpu, 3),
                      "parent_cpu_seconds": round(parent_cpu, 3)}
    from seactl.base.outputs import write_atomic

    write_atomic(out / SUMMARY, json.dumps(summary, indent=2) + "\n")
    write_manifest(spec, out, "complete")
    return SweepResult(out, spec.hash, spec.n_points, spec.n_chunks, computed, points, seconds,
                       n_workers, peak, cpu, summary, parent_cpu_seconds=parent_cpu)


def _local(client: Any) -> bool:
    """A client of a LocalCluster: its workers share this machine's filesystem."""
    from distributed import LocalCluster

    return isinstance(getattr(client, "cluster", None), LocalCluster)


def _on_dask(spec: SweepSpec, out: Path, todo: list[int], client: Any,
             finish: Callable[..., None], n_workers: int) -> None:
    """Submit the chunks ``todo`` and ``finish`` each as it completes; the workers of a
    local cluster share this filesystem and write their own chunks (in :func:`batches`),
    others send their tables here, a chunk per task.  Any failure or Ctrl-C cancels the
    rest (chunks already written stay, for ``resume``)."""
    from distributed import as_completed

    local = _local(client)
    groups = batches(todo, n_workers) if local else [[i] for i in todo]
    futures = {}
    tag = spec.hash[:12]
    for g in groups:
        key = f"seactl-sweep-{tag}-{g[0]:06d}-{g[-1]:06d}"
        fut = (client.submit(evaluate_and_write, spec, g, out, retries=2, pure=False, key=key)
               if local else
               client.submit(evaluate_chunk, spec, g[0], retries=2, pure=False, key=key))
        futures[fut.key] = (g, fut)
    try:
        for fut, result in as_completed([f for _, f in futures.values()], with_results=True):
            g, _ = futures.pop(fut.key)
            if local:
                for row in result:
                    finish(*row)
            else:
                table, stats = result
                finish(g[0], *write_part(spec, out, g[0], table), stats)
            del result
    except BaseException:
        client.cancel([f for _, f in futures.values()])
        raise


def _connect(address: str):
    from distributed import Client

    if not address.startswith(("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")):
        raise InputError("scheduler", address, "a Dask scheduler address such as "
                         "tcp://HOST:PORT")
    try:
        return Client(address, timeout="10s")
    except (OSError, ValueError, TypeError) as exc:
        raise InputError("scheduler", address, f"a reachable Dask scheduler ({exc})") from None


def summarize(spec: SweepSpec, out: Path, parts: dict[int, dict[str, Any]] | None = None
              ) -> dict[str, Any]:
    """Counts and phase-margin statistics of a complete sweep, from each chunk's share
    (:func:`chunk_summary`): from ``parts`` where given (the chunks of this run), else read
    part by part (bounded memory) from ``out``."""
    import pyarrow.parquet as pq

    n = n_feas = n_stable = 0
    pm_all: list[np.ndarray] = []
    best: dict[str, Any] | None = None
    for i in range(spec.n_chunks):
        part = (parts or {}).get(i)
        if part is None:
            part = chunk_summary(spec, pq.read_table(part_path(out, i),
                                                     columns=summary_columns(spec)))
        n, n_feas, n_stable = n + part["n"], n_feas + part["feasible"], n_stable + part["stable"]
        pm_all.append(part["pm_sample"])
        if part["best"] is not None and (best is None or part["best"]["phase_margin_deg"] >
                                         best["phase_margin_deg"]):
            best = part["best"]
    pms = np.concatenate(pm_all) if pm_all else np.empty(0)
    pms = pms[np.isfinite(pms)]
    stats = None
    if pms.size:
        q = np.percentile(pms, [0, 5, 50, 95, 100])
        stats = dict(zip(("min", "p5", "median", "p95", "max"), (round(float(x), 6) for x in q)))
    return {"spec_hash": spec.hash, "n_points": n, "feasible": n_feas,
            "infeasible": n - n_feas, "stable": n_stable, "unstable": n_feas - n_stable,
            "phase_margin_deg_stable": stats, "best_phase_margin": best}
