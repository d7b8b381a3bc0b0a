"""A workspace map's configurations, one after the other or on Dask:
:func:`map_configurations` (behind :func:`seactl.workspace_map`).

Each configuration is one task, :func:`evaluate_configuration`: the robot designed and
linearized there, its margins, and in task space the stiffness search
(:func:`seactl.api.robotstiffness.search_task_stiffness`).  The same function runs in
either backend, so both give the same numbers.

With ``backend="dask"`` the configurations go to a local cluster started as the sweeps
start theirs (:func:`seactl.sweep.engine.local_cluster`: single-threaded worker
processes, forked warm), or to a given ``client``.  The first configuration to finish is
timed (in this process, or from submission on Dask); the rest are refused, before they
run, when that time, times the configurations left, divided by the workers, exceeds the
time budget (:func:`seactl.base.limits.check_budget`).

Cost per process: the robot's loop (:func:`seactl.systems.robot.loops.robot_diagram`) and
its characteristic terms are built once per process on first use and cached there.  Every
Dask worker therefore builds them once, side by side with the others, before its first
configuration, and this process builds none: the wall time pays one build, as in the
serial backend (docs/robots.md, "Cost").
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from seactl.base import progress
from seactl.errors import InputError

BACKENDS = ("serial", "dask")


def evaluate_configuration(urdf: str | None, q0: Sequence[float], options: dict[str, Any]
                           ) -> dict[str, Any]:
    """One configuration of a workspace map: the robot at ``q0`` and its numbers.

    Parameters
    ----------
    urdf : str
        The URDF file.
    q0 : sequence of float
        The configuration [rad].
    options : dict
        The other keywords of :func:`seactl.robot`.

    Returns
    -------
    dict
        ``stable``, ``phase_margin_deg``, ``delay_margin_ms`` (at ``outer.j1``),
        ``mimo_phase_margin_deg`` and ``mimo_delay_margin_ms`` (every stiffness channel
        broken at once, :meth:`seactl.api.robot.Robot.mimo_margins`), ``passive``; in task
        space ``max_task_stiffness_n_per_m``, ``stiffness_intervals_n_per_m`` and
        ``single_flip`` (:class:`seactl.api.robotstiffness.StiffnessSearch`), else NaN,
        ``()`` and True.
    """
    import seactl as sc
    from seactl.api.robotstiffness import search_task_stiffness
    from seactl.errors import InfeasibleDesignError

    try:
        r = sc.robot(urdf, q0=list(q0), **options)
    except InfeasibleDesignError as exc:   # (which configuration of the map)
        angles = ", ".join(f"{x:.4g}" for x in q0)
        raise InfeasibleDesignError(f"at q = ({angles}) rad, {exc}", fn_hz=exc.fn_hz,
                                    feasible_hz=exc.feasible_hz) from None
    m = r.margins()
    row = {"joints": tuple(r.body.joints), "stable": bool(m.stable),
           "phase_margin_deg": float(m.phase_margin_deg),
           "delay_margin_ms": float(m.delay_margin_ms),
           "max_task_stiffness_n_per_m": float("nan"),
           "stiffness_intervals_n_per_m": (), "single_flip": True,
           "passive": None if r.large else bool(r.passivity().passive)}
    mimo = r.mimo_margins()
    row.update(mimo_phase_margin_deg=float(mimo.phase_margin_deg),
               mimo_delay_margin_ms=1e3 * float(mimo.delay_margin_s))
    if r.space == "task":
        s = search_task_stiffness(r)
        row.update(max_task_stiffness_n_per_m=s.kx_max_n_per_m,
                   stiffness_intervals_n_per_m=s.intervals_n_per_m,
                   single_flip=s.single_flip)
    return row


def map_configurations(urdf: str | None, q: np.ndarray, options: dict[str, Any], *,
                       backend: str = "serial", workers: int | None = None,
                       client: Any = None) -> list[dict[str, Any]]:
    """:func:`evaluate_configuration` at each row of ``q``, in order.

    Parameters
    ----------
    urdf : str
        The URDF file.
    q : numpy.ndarray
        ``(m, n)`` configurations [rad].
    options : dict
        The other keywords of :func:`seactl.robot`.
    backend : {"serial", "dask"}
        In this process, or on Dask.
    workers : int, optional
        Local Dask workers (default: all cores); ignored with ``client``.
    client : distributed.Client, optional
        An existing Dask client (left open).

    Returns
    -------
    list of dict
        One row per configuration.

    Raises
    ------
    InputError
        An unknown backend, or workers below 1.
    ResourceError
        The configurations would take longer than the time budget.
    """
    if backend not in BACKENDS:
        raise InputError("backend", backend, "one of " + ", ".join(BACKENDS))
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise InputError("workers", workers, "a whole number >= 1")
    with progress.stage("workspace map", total=len(q), unit="configurations") as bar:
        if backend == "dask":
            return _on_dask(urdf, q, options, workers, client, bar.advance)
        rows = []
        for i, row in enumerate(q):
            t0 = time.perf_counter()
            rows.append(evaluate_configuration(urdf, row, options))
            bar.advance()
            if i == 0:
                _check_time(time.perf_counter() - t0, len(q) - 1, 1)
        return rows


def _check_time(first_s: float, left: int, n_workers: int) -> None:
    """Refuse the configurations ``left`` if, each as long as the first, they exceed the
    time budget."""
    from seactl.base.limits import check_budget

    check_budget(f"{left:,} more configurations of the workspace map (the first took "
                 f"{first_s:.3g} s)", seconds=first_s * left / max(n_workers, 1),
                 hint="fewer configurations, or more workers (backend='dask')")


def _on_dask(urdf: str | None, q: np.ndarray, options: dict[str, Any], workers: int | None,
             client: Any, advance: Callable[[], None]) -> list[dict[str, Any]]:
    """The rows of ``q`` on Dask (a local cluster unless ``client``), in order.  No
    retries: an error of a configuration is the same on every try (Dask reschedules the
    tasks of a worker that dies by itself)."""
    import shutil
    import tempfile

    from distributed import Client, as_completed

    from seactl.sweep.engine import local_cluster, uninterrupted

    own_cluster = own_client = scratch = None
    try:
        if client is None:
            scratch = tempfile.mkdtemp(prefix="seactl-map-")
            own_cluster = local_cluster(workers or os.cpu_count() or 1, scratch)
            own_client = client = Client(own_cluster)
        n_workers = len(client.scheduler_info(n_workers=-1)["workers"])
        t0 = time.perf_counter()
        futures = [client.submit(evaluate_configuration, urdf, row.tolist(), options,
                                 pure=False) for row in q]
        index = {f.key: i for i, f in enumerate(futures)}
        rows: list[Any] = [None] * len(futures)
        try:
            for done, (fut, row) in enumerate(as_completed(futures, with_results=True)):
                rows[index[fut.key]] = row
                advance()
                if done == 0:
                    _check_time(time.perf_counter() - t0, len(q) - 1, n_workers)
        except BaseException:
            client.cancel(futures)
            raise
        return rows
    finally:
        with uninterrupted():   # (a second Ctrl-C must not cut the close short)
            if own_client is not None:
                own_client.close()
                own_cluster.close()
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
