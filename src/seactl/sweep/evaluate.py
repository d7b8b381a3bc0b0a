"""One chunk of a sweep evaluated: designs, margins, impedance, responses."""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from seactl.base.axes import ACTUATOR_AXES, ACTUATOR_FIELDS
from seactl.base.parallel import one_thread
from seactl.sweep.dataset import write_chunk
from seactl.sweep.spec import OUTPUTS, SweepSpec, z_column


# ------------------------------------------------------------------ evaluation
def impedance_magnitude(design: Any, f_hz: np.ndarray) -> np.ndarray:
    """``|Z(j 2 pi f)|`` [N m s/rad] of the SEA, ``Z = tau_k / (-s q_j)`` with the joint
    motion imposed (``q_des = 0``), from :data:`~seactl.systems.sea.loops.SEA_DIAGRAM`.

    Examples
    --------
    The static stiffness is ``K_q`` (docs/theory/ktau-beta.md): ``|Z| w -> K_q``.

    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEADesign
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 30.0))
    >>> f = 1e-4
    >>> z = impedance_magnitude(d, np.array([f]))[0]
    >>> bool(abs(z * 2 * np.pi * f / d.gains.Kq - 1) < 1e-6)
    True
    """
    from seactl.systems.sea.impedance import impedance

    return impedance(design, f_hz).magnitude


def evaluate_points(spec: SweepSpec, values: dict[str, np.ndarray], n: int
                    ) -> dict[str, np.ndarray]:
    """Gains, margins (and ``|Z|``) for ``n`` points whose swept axes are ``values``.

    Returns numpy columns; rows that are infeasible hold NaN in the float outputs
    and the ``feasible`` mask says so (converted to nulls by :func:`to_table`).

    The same gains, margins and ``|Z|`` as ``sc.design(...).margins()`` and
    ``.impedance()``, but built from the core: :func:`seactl.design` refuses a batch with
    one infeasible point (here masked) and takes no actuator-parameter axes, and a chunk is
    the hot path of the sweep (no per-design objects)."""
    from seactl.systems.sea.design import solve_gains
    from seactl.systems.sea.loops import SEADesign, Timing
    from seactl.systems.sea.views import sea_margins

    fixed = spec.fixed()

    def col(name: str) -> np.ndarray:
        return np.broadcast_to(np.asarray(values.get(name, fixed.get(name)), float), (n,))

    a = spec.actuator
    design_kw = dict(zeta1=col("zeta1"), zeta2=col("zeta2"), ratio=col("ratio"))
    sols = solve_gains(a, col("fn_hz"), **design_kw)
    ok = sols.n_valid > 0
    out: dict[str, np.ndarray] = {"feasible": ok}
    nan = np.full(n, np.nan)
    if ok.any():
        gains = sols.rows(ok).pick().scaled(col("gs")[ok])
        timing = Timing.from_ms(col("t_tau_ms")[ok], col("t_qs_ms")[ok], col("t_qd_ms")[ok],
                                col("f_qd_hz")[ok], col("f_taud_hz")[ok])
        plant: Any = a
        if any(name in dict(spec.axes) for name in ACTUATOR_AXES):
            plant = a.batch(**{ACTUATOR_FIELDS[n]: col(n)[ok] for n in ACTUATOR_AXES})
        design = SEADesign(plant, gains, timing)
        m = sea_margins(design)
        res = {"Kq": gains.Kq, "Bq": gains.Bq, "Ktau": gains.Ktau, "Btau": gains.Btau,
               "phase_margin_deg": m.phase_margin_deg, "crossover_hz": m.crossover_hz,
               "gain_margin_db": m.gain_margin_db, "phase_crossover_hz": m.phase_crossover_hz,
               "delay_margin_ms": m.delay_margin_ms, "stable": m.stable.astype(float),
               "unstable_poles": m.unstable_poles.astype(float)}
        if spec.z_freqs_hz:
            z = impedance_magnitude(design, np.asarray(spec.z_freqs_hz))
            z = np.broadcast_to(z, (int(ok.sum()), len(spec.z_freqs_hz)))
            for j, f in enumerate(spec.z_freqs_hz):
                res[z_column(f)] = z[:, j]
        for key, v in res.items():
            full = nan.copy()
            full[ok] = v
            out[key] = full
    else:
        for key in list(OUTPUTS)[2:] + [z_column(f) for f in spec.z_freqs_hz]:
            out[key] = nan.copy()
    return out


def schema(spec: SweepSpec):
    """The Arrow schema of a sweep's chunks (with the spec hash as metadata)."""
    import pyarrow as pa

    cols = [pa.field("point", pa.int64(), nullable=False)]
    cols += [pa.field(name, pa.float64(), nullable=False) for name, _ in spec.swept]
    cols.append(pa.field("feasible", pa.bool_(), nullable=False))
    for name in list(OUTPUTS)[2:]:
        typ = {"stable": pa.bool_(), "unstable_poles": pa.int32()}.get(name, pa.float64())
        cols.append(pa.field(name, typ))
    cols += [pa.field(z_column(f), pa.float64()) for f in spec.z_freqs_hz]
    return pa.schema(cols, metadata={"seactl_spec_hash": spec.hash})


def to_table(spec: SweepSpec, start: int, values: dict[str, np.ndarray],
             res: dict[str, np.ndarray]):
    """Arrow table of one chunk; outputs of infeasible rows and missing crossings
    (NaN in ``res``) become nulls."""
    import pyarrow as pa

    sch = schema(spec)
    n = len(res["feasible"])
    arrays = []
    for f in sch:
        if f.name == "point":
            arrays.append(pa.array(np.arange(start, start + n, dtype=np.int64)))
        elif f.name in values:
            arrays.append(pa.array(np.asarray(values[f.name], float)))
        elif f.name == "feasible":
            arrays.append(pa.array(res["feasible"]))
        else:
            v = res[f.name]
            mask = np.isnan(v)
            if f.type == pa.float64():
                arrays.append(pa.array(v, mask=mask))
            else:
                filled = np.where(mask, 0, v).astype(f.type.to_pandas_dtype())
                arrays.append(pa.array(filled, type=f.type, mask=mask))
    return pa.Table.from_arrays(arrays, schema=sch)


def evaluate_chunk(spec: SweepSpec, i: int) -> tuple[Any, dict[str, float]]:
    """Compute chunk ``i``: returns its Arrow table and stats (wall and CPU seconds, the
    evaluating process's peak RSS in MB).  Runs on Dask workers."""
    t0, c0 = time.perf_counter(), time.process_time()
    start, stop = spec.chunk_range(i)
    values = spec.points(start, stop, chunk=i)
    with one_thread():  # (the workers already run one per core)
        res = evaluate_points(spec, values, stop - start)
    table = to_table(spec, start, values, res)
    return table, {"seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0,
                   "peak_rss_mb": _peak_rss_mb(), "pid": os.getpid()}


def evaluate_and_write(spec: SweepSpec, chunks: Sequence[int], out: Path
                       ) -> list[tuple[int, int, dict[str, Any], dict[str, float]]]:
    """Compute ``chunks`` one by one, each written to its part file where it was computed
    (local workers: the parent then only counts, instead of receiving and writing every
    table); ``(chunk, rows, its share of the summary, stats)`` of each."""
    out_rows = []
    for i in chunks:
        table, stats = evaluate_chunk(spec, i)
        out_rows.append((i, *write_part(spec, out, i, table), stats))
    return out_rows


def batches(todo: Sequence[int], workers: int, largest: int = 8) -> list[list[int]]:
    """``todo`` in consecutive batches, one task each: up to ``largest`` chunks while many
    remain (fewer tasks for the scheduler, which spends CPU on each), shrinking to
    single chunks at the end so that no worker waits long for another's last batch."""
    out, at = [], 0
    while at < len(todo):
        k = max(1, min(largest, (len(todo) - at) // (4 * max(workers, 1))))
        out.append(list(todo[at:at + k]))
        at += k
    return out


def write_part(spec: SweepSpec, out: Path, i: int, table: Any) -> tuple[int, dict[str, Any]]:
    """Write chunk ``i``'s table; its row count and its share of the summary
    (:func:`chunk_summary`, from the table in memory: the summary then reads no part back)."""
    write_chunk(out, i, table)
    return table.num_rows, chunk_summary(spec, table)


def _peak_rss_mb() -> float:
    """This process's peak resident memory [MB].  On Linux the high-water mark of its own
    address space (``VmHWM``): ``ru_maxrss`` also counts the parent's memory at the fork
    that started the process (kept across ``exec``), so a worker spawned by a large
    process would report the parent's size."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:  # pragma: no cover - not Linux
        pass
    try:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    except (ImportError, AttributeError):  # pragma: no cover - not on Linux/macOS
        return float("nan")


def summary_columns(spec: SweepSpec) -> list[str]:
    return ["point", "feasible", "stable", "phase_margin_deg", *[n for n, _ in spec.swept]]


def chunk_summary(spec: SweepSpec, table: Any) -> dict[str, Any]:
    """One chunk's share of :func:`summarize`: its counts, its stable points' phase margins
    (every one for sweeps up to 1e6 points, else strided: a bounded sample for the
    percentiles) and its best stable point."""
    feas = table.column("feasible").to_numpy()
    stable = table.column("stable").to_numpy(zero_copy_only=False)
    stable = np.where(feas, stable, False).astype(bool)
    pm = table.column("phase_margin_deg").to_numpy(zero_copy_only=False)
    best = None
    finite = stable & np.isfinite(pm)
    if finite.any():
        j = int(np.argmax(np.where(finite, pm, -np.inf)))
        best = {c: table.column(c)[j].as_py() for c in summary_columns(spec) if c != "stable"}
    return {"n": table.num_rows, "feasible": int(feas.sum()), "stable": int(stable.sum()),
            "pm_sample": pm[stable][::max(1, spec.n_points // 1_000_000)], "best": best}
