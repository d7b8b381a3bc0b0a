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
>>> from seactl.actuators import UT_SEA
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
import hashlib
import json
import math
import os
import shutil
import signal
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from ._parallel import one_thread
from .actuators import SEAParams
from .axes import ACTUATOR_AXES, ACTUATOR_FIELDS, AXES, SAMPLINGS
from .errors import InputError, OutputError, Terminated
from .outputs import TEMP_TAG
from .results import Renamed, Result, flat_records, json_value, new_axes

FORMAT = "seactl-sweep/1"

TEMPLATE_MARKER = "SEACTL_SWEEP_TEMPLATE"
"""Environment variable that is ``"1"`` only while :func:`_start_worker_template` starts
the fork server: it tells :mod:`seactl._sweep_template`, imported by that server, to
prepare the workers' template (imported anywhere else, it only defines things)."""



OUTPUTS: dict[str, str] = {
    "point": "point index in the sweep's deterministic order",
    "feasible": "a critically-damped gain set with four positive gains exists",
    "Kq": "stiffness gain [N m/rad] (null: infeasible)",
    "Bq": "damping gain [N m s/rad] (null: infeasible)",
    "Ktau": "torque P gain [A/(N m)] (null: infeasible)",
    "Btau": "torque D gain [A s/(N m)] (null: infeasible)",
    "phase_margin_deg": "phase margin [deg] (inf: no gain crossover)",
    "crossover_hz": "gain crossover [Hz] (null: none)",
    "gain_margin_db": "gain margin [dB] (inf: no phase crossover)",
    "phase_crossover_hz": "phase crossover [Hz] (null: none)",
    "delay_margin_ms": "delay margin [ms] (0: unstable, inf: no crossover)",
    "stable": "closed loop stable (Nyquist; null: infeasible)",
    "unstable_poles": "closed-loop right-half-plane poles (null: infeasible)",
}


def z_column(f_hz: float) -> str:
    """Column name of the impedance magnitude at ``f_hz``."""
    return f"z_mag_{f_hz:g}hz"


# ------------------------------------------------------------------ spec
@dataclass(frozen=True)
class SweepSpec:
    """What to sweep; everything a chunk needs to regenerate its points.

    Parameters
    ----------
    actuator : SEAParams
        Nominal actuator (gains are designed for it; also the default plant).
    axes : tuple of (name, values)
        Per axis of :data:`AXES`: its values (grid), or the interval spanned by
        them (sampling modes).  Unlisted axes keep their default.
    sampling : {"grid", "random", "lhs"}
    n_samples : int
        Number of points for ``random`` / ``lhs``.
    seed : int
        Seed of the sampling modes (chunk ``i`` draws from ``(seed, i)``).
    chunk_size : int
        Points per chunk (bounds memory: a chunk's arrays grow with it; ``seactl bench``
        reports the peak of a default chunk).
    z_freqs_hz : tuple of float
        Frequencies [Hz] at which to report the impedance magnitude ``|Z|``.
    """

    actuator: SEAParams
    axes: tuple[tuple[str, tuple[float, ...]], ...] = ()
    sampling: str = "grid"
    n_samples: int = 0
    seed: int = 0
    chunk_size: int = 5_000
    z_freqs_hz: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.sampling not in SAMPLINGS:
            raise InputError("sampling", self.sampling, "one of " + ", ".join(SAMPLINGS))
        if int(self.chunk_size) != self.chunk_size or self.chunk_size < 1:
            raise InputError("chunk_size", self.chunk_size, "an integer >= 1")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise InputError("seed", self.seed, "an integer >= 0")
        if self.sampling != "grid" and (int(self.n_samples) != self.n_samples
                                        or self.n_samples < 1):
            raise InputError("n_samples", self.n_samples, f"an integer >= 1 for sampling "
                             f"{self.sampling!r}")
        norm: dict[str, tuple[float, ...]] = {}
        for name, values in self.axes:
            if name not in AXES:
                raise InputError("axis", name, "one of " + ", ".join(AXES))
            if name in norm:
                raise InputError(name, name, "given once")
            vals = tuple(float(v) for v in np.ravel(values))
            if not vals:
                raise InputError(name, "", "at least one value")
            _check_axis(name, np.asarray(vals))
            norm[name] = vals
        from .limits import check_range

        for f in self.z_freqs_hz:
            check_range("z_freqs_hz [Hz]", f, "freq_hz")
        # canonical order (AXES order) so that equal sweeps hash equally
        object.__setattr__(self, "axes", tuple((n, norm[n]) for n in AXES if n in norm))
        object.__setattr__(self, "z_freqs_hz", tuple(float(f) for f in self.z_freqs_hz))

    # ---- derived structure
    @property
    def swept(self) -> tuple[tuple[str, tuple[float, ...]], ...]:
        """Axes with more than one value (columns of the dataset)."""
        return tuple((n, v) for n, v in self.axes if len(v) > 1)

    def fixed(self) -> dict[str, float]:
        """Value of every axis that does not vary."""
        given = dict(self.axes)
        out = {}
        for name, info in AXES.items():
            if name in given and len(given[name]) > 1:
                continue
            if name in given:
                out[name] = given[name][0]
            elif info.default is not None:
                out[name] = info.default
            else:
                out[name] = float(getattr(self.actuator, ACTUATOR_FIELDS[name]))
        return out

    @property
    def grid_shape(self) -> tuple[int, ...]:
        return tuple(len(v) for _, v in self.swept)

    @property
    def n_points(self) -> int:
        if self.sampling == "grid":
            return int(np.prod(self.grid_shape, dtype=np.int64))
        return int(self.n_samples)

    @property
    def n_chunks(self) -> int:
        return -(-self.n_points // self.chunk_size)

    def chunk_range(self, i: int) -> tuple[int, int]:
        start = i * self.chunk_size
        return start, min(start + self.chunk_size, self.n_points)

    # ---- identity
    def as_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT, "seactl": _seactl_version(),
            "actuator": asdict(self.actuator), "sampling": self.sampling,
            "n_samples": self.n_samples if self.sampling != "grid" else None,
            "seed": self.seed if self.sampling != "grid" else None,
            "chunk_size": self.chunk_size,
            "axes": {n: [_json_float(x) for x in v] for n, v in self.axes},
            "z_freqs_hz": list(self.z_freqs_hz),
        }

    @cached_property
    def hash(self) -> str:
        """SHA-256 of :meth:`as_json` (computed once: it travels with the spec to the
        workers, which stamp it on every chunk)."""
        text = json.dumps(self.as_json(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    # ---- points
    def points(self, start: int, stop: int, chunk: int | None = None) -> dict[str, np.ndarray]:
        """Values of the swept axes for points ``[start, stop)``.

        For the sampling modes ``[start, stop)`` must be chunk ``chunk``'s range
        (samples are drawn per chunk)."""
        swept = self.swept
        n = stop - start
        if self.sampling == "grid":
            if not swept:
                return {}
            multi = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.grid_shape)
            return {name: np.asarray(vals)[m] for (name, vals), m in zip(swept, multi)}
        if chunk is None or self.chunk_range(chunk) != (start, stop):
            raise ValueError("sampled points are generated per chunk")
        d = len(swept)
        rng = np.random.default_rng([self.seed, chunk])
        if d == 0:
            return {}
        if self.sampling == "random":
            u = rng.random((n, d))
        else:
            from scipy.stats import qmc

            u = qmc.LatinHypercube(d, rng=rng).random(n)
        out = {}
        for k, (name, vals) in enumerate(swept):
            lo, hi = min(vals), max(vals)
            out[name] = lo + (hi - lo) * u[:, k]
        return out


@lru_cache(maxsize=1)
def _seactl_version() -> str:
    """The installed seactl's version (read from its metadata once per process: each read
    parses the package's metadata file)."""
    from importlib.metadata import version

    return version("seactl")


def _json_float(x: float) -> float | str:
    return x if math.isfinite(x) else repr(x)


def _check_axis(name: str, vals: np.ndarray) -> None:
    AXES[name].check(vals, f"{name} [{AXES[name].unit}]" if AXES[name].unit else name)


# ------------------------------------------------------------------ evaluation
def impedance_magnitude(design: Any, f_hz: np.ndarray) -> np.ndarray:
    """``|Z(j 2 pi f)|`` [N m s/rad] of the SEA, ``Z = tau_k / (-s q_j)`` with the joint
    motion imposed (``q_des = 0``), from :data:`~seactl.loops.SEA_DIAGRAM`.

    Examples
    --------
    The static stiffness is ``K_q`` (docs/theory/ktau-beta.md): ``|Z| w -> K_q``.

    >>> from seactl.actuators import UT_SEA
    >>> from seactl.design import critically_damped_gains
    >>> from seactl.loops import SEADesign
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 30.0))
    >>> f = 1e-4
    >>> z = impedance_magnitude(d, np.array([f]))[0]
    >>> bool(abs(z * 2 * np.pi * f / d.gains.Kq - 1) < 1e-6)
    True
    """
    from .impedance import impedance

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
    from .design import solve_gains
    from .loops import SEADesign, Timing
    from .sea import sea_margins

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
        out_rows.append((i, *_written(spec, out, i, table), stats))
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


def _written(spec: SweepSpec, out: Path, i: int, table: Any) -> tuple[int, dict[str, Any]]:
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


# ------------------------------------------------------------------ dataset on disk
def part_path(out: Path, i: int) -> Path:
    return Path(out) / f"part-{i:05d}.parquet"


def write_chunk(out: Path, i: int, table: Any) -> None:
    """Write chunk ``i`` atomically (:func:`seactl.outputs.write_atomic_with`)."""
    import pyarrow.parquet as pq

    from .outputs import write_atomic_with

    write_atomic_with(part_path(out, i), lambda tmp: pq.write_table(table, tmp))


def _chunk_done(spec: SweepSpec, out: Path, i: int) -> bool:
    p = part_path(out, i)
    if not p.is_file():
        return False
    import pyarrow.parquet as pq

    try:
        meta = pq.read_metadata(p)
    except Exception:  # unreadable: recompute
        return False
    start, stop = spec.chunk_range(i)
    return meta.num_rows == stop - start


def missing_chunks(spec: SweepSpec, out: Path) -> list[int]:
    """Chunks without a complete part file in ``out``."""
    return [i for i in range(spec.n_chunks) if not _chunk_done(spec, out, i)]


def _write_manifest(spec: SweepSpec, out: Path, status: str) -> None:
    from .outputs import write_atomic

    fixed = {k: _json_float(v) for k, v in spec.fixed().items()}
    units = {n: AXES[n].unit for n in AXES}
    manifest = {
        "format": FORMAT, "spec_hash": spec.hash, "status": status,
        "n_points": spec.n_points, "n_chunks": spec.n_chunks, "chunk_size": spec.chunk_size,
        "swept_axes": [n for n, _ in spec.swept], "fixed": fixed, "units": units,
        "columns": {**OUTPUTS, **{z_column(f): f"|Z| at {f:g} Hz [N m s/rad] (null: "
                                  "infeasible)" for f in spec.z_freqs_hz}},
        "spec": spec.as_json(),
    }
    write_atomic(out / "_manifest.json", json.dumps(manifest, indent=2) + "\n")


MANIFEST = "_manifest.json"
SUMMARY = "_summary.json"


def read_manifest(out: Path) -> dict[str, Any]:
    """The manifest of the sweep in ``out``; a one-line error saying how to recover when it
    is unreadable."""
    path = Path(out) / MANIFEST
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict):
            raise ValueError("not a JSON object")
        return data
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError("out", str(out), f"a sweep with a readable {MANIFEST} (it is corrupt:"
                         f" {str(exc).splitlines()[0][:80]}); rerun with --overwrite to start "
                         "this sweep again, or choose a new --out") from None
    except OSError as exc:
        raise InputError("out", str(out), f"a sweep with a readable {MANIFEST} "
                         f"({exc.strerror or exc})") from None


def check_output(spec: SweepSpec, out: Path, *, resume: bool, overwrite: bool) -> None:
    """Check, without writing anything, that ``out`` may receive this sweep.

    Raises
    ------
    InputError
        ``resume`` and ``overwrite`` together; ``out`` holds a sweep of another spec, or
        exists without ``resume`` / ``overwrite``, or is a non-sweep directory, or its
        manifest is corrupt (without ``overwrite``).
    OutputError
        ``out`` or its parent cannot be created.
    """
    if not os.fspath(out).strip():
        raise InputError("out", os.fspath(out), "a directory path")
    out = Path(out)
    if resume and overwrite:
        raise InputError("overwrite", True, "False with resume=True (resume completes a sweep,"
                         " overwrite restarts it: choose one)")
    if out.exists() and not out.is_dir():
        raise InputError("out", str(out), "a directory path (a Parquet dataset), not a file")
    if out.is_dir() and any(out.iterdir()):
        if not (out / MANIFEST).is_file():
            raise InputError("out", str(out), "a new or empty directory, or a seactl sweep "
                             f"(this directory has no {MANIFEST})")
        if overwrite:
            return
        old = read_manifest(out)
        if old.get("spec_hash") != spec.hash:
            diff = _spec_diff(old.get("spec", {}), spec.as_json())
            raise InputError(
                "out", str(out),
                "a new directory or --overwrite: it holds a different sweep (spec hash "
                f"{str(old.get('spec_hash'))[:12]} vs {spec.hash[:12]}; differs in: "
                f"{', '.join(diff) or 'format'}); results of different specs are never mixed")
        if not resume:
            raise InputError("out", str(out), "a new directory, or --resume to complete this "
                             "sweep (same spec), or --overwrite to restart it")
        return
    parent = out.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(out, f"{parent} is not a writable directory")


def prepare_output(spec: SweepSpec, out: Path, *, resume: bool, overwrite: bool) -> None:
    """Create ``out`` or check it belongs to the same sweep (``resume``), then write the
    manifest (status ``running``); see :func:`check_output` for the errors."""
    out = Path(out)
    check_output(spec, out, resume=resume, overwrite=overwrite)
    try:
        if overwrite and (out / MANIFEST).is_file():
            remove_sweep_files(out)
        out.mkdir(parents=True, exist_ok=True)
        for stale in out.glob(f".part-*{TEMP_TAG}*"):   # left by a killed writer
            stale.unlink(missing_ok=True)
    except OSError as exc:
        from .outputs import reason

        raise OutputError(out, reason(exc)) from None
    _write_manifest(spec, out, "running")


def remove_sweep_files(out: Path) -> None:
    """Remove what a sweep writes into ``out`` (chunks, manifest, summary, temporaries),
    nothing else: files a user added stay."""
    for p in [*out.glob("part-*.parquet"), out / MANIFEST, out / SUMMARY,
              *out.glob(f".part-*{TEMP_TAG}*"), *out.glob(f".{MANIFEST}*"),
              *out.glob(f".{SUMMARY}*")]:
        p.unlink(missing_ok=True)


def _remove_new_sweep(out: Path) -> None:
    """Undo :func:`prepare_output` on a directory it created (no chunk was written)."""
    for p in [out / MANIFEST, *out.glob(f".part-*{TEMP_TAG}*"), *out.glob(f".{MANIFEST}*")]:
        p.unlink(missing_ok=True)
    try:
        out.rmdir()
    except OSError:
        pass


def _spec_diff(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    keys = sorted(set(a) | set(b))
    out = []
    for k in keys:
        if isinstance(a.get(k), dict) and isinstance(b.get(k), dict) and k == "axes":
            out += [f"axis {n}" for n in sorted(set(a[k]) | set(b[k]))
                    if a[k].get(n) != b[k].get(n)]
        elif a.get(k) != b.get(k):
            out.append(k)
    return out


def read_sweep(out: Path | str, columns: Iterable[str] | None = None):
    """The sweep dataset in ``out`` as one Arrow table sorted by ``point``."""
    import pyarrow.parquet as pq

    parts = sorted(Path(out).glob("part-*.parquet")) if os.fspath(out).strip() else []
    if not parts:
        raise InputError("out", str(out), "a directory holding sweep results")
    cols = None if columns is None else list(dict.fromkeys(["point", *columns]))
    import pyarrow as pa

    return pa.concat_tables([pq.read_table(p, columns=cols) for p in parts]).sort_by("point")


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
def _uninterrupted():
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


def _local_cluster(workers: int, scratch: str | None = None):
    """One single-threaded worker process per core (dashboard, profiler off), forked from
    a warm template where the platform allows (:func:`_start_worker_template`), with their
    files in ``scratch`` (default: Dask's ``dask-scratch-space`` in the temporary directory,
    which Dask leaves behind).

    Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536`` in its workers (to return
    memory to the OS); with the margin kernel's many short-lived arrays of a few MB
    that turns the chunk's allocations into page faults.  The workers here keep glibc's
    default, adaptive thresholds; memory stays bounded by the chunk size."""
    import logging

    import dask
    from distributed import LocalCluster

    environ = _worker_environ()
    method = _start_worker_template(environ)
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
                                   dashboard_address=None, silence_logs=logging.CRITICAL,
                                   preload=["seactl._sweep_worker"])
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if interrupted:
        cluster.close()
        raise KeyboardInterrupt
    return cluster


def _worker_environ() -> dict[str, str]:
    """Dask's environment for its workers, without ``MALLOC_TRIM_THRESHOLD_``
    (:func:`_local_cluster`)."""
    import dask

    return {k: str(v) for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ",
                                                   default={}) or {}).items()
            if k != "MALLOC_TRIM_THRESHOLD_"}


def _start_worker_template(environ: dict[str, str]) -> str:
    """Start the template that local workers fork from, and wait until it is ready; the
    start method to give Dask.

    ``"forkserver"``: multiprocessing's fork server is started (once per process), with
    :data:`TEMPLATE_MARKER` in its environment, and imports :mod:`seactl._sweep_template`,
    which then loads the sweep's modules and kernels.
    Every worker forked from it starts with them loaded.  ``"spawn"``: the platform
    has no fork server (Windows).

    A spawned worker imports and loads the kernels before its first chunk, and its
    interpreter's exit lengthens the cluster's close; a forked worker does neither; the
    server itself starts once per process (``seactl bench``'s sweep figures include it).

    The server gets the workers' environment ``environ`` (:func:`_worker_environ`, which
    the nanny also sets before each worker), so its BLAS starts no threads to fork.  A fork server
    already running in this process is used as it is: if other code started it without
    the template, each worker warms itself as it starts (its Dask preload,
    :func:`seactl._sweep_worker.dask_setup`)."""
    import multiprocessing
    from multiprocessing import forkserver

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return "spawn"
    import dask
    from distributed.utils import get_mp_context

    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()  # Dask sets its own preload list once per process: before ours
    multiprocessing.set_forkserver_preload(["seactl._sweep_template"])
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
              scheduler: str | None = None, client: Any = None, console: Any = None,
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
    console : rich.console.Console, optional
        Where to draw the progress bar (none if ``None``).

    Chunks are submitted to Dask with ``retries=2`` and written as they
    complete; on Ctrl-C the pending ones are cancelled and
    :class:`SweepInterrupted` is raised, every written chunk staying on disk.
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
        if console is not None:
            from rich.markup import escape

            console.print(f"sweep: {spec.n_points:,} points in {spec.n_chunks:,} chunks of "
                          f"{spec.chunk_size:,} -> {escape(str(out))}"
                          + (f" on {escape(scheduler)}" if scheduler else ""))
        return _run(spec, out, workers, client, own_client, console, _on_chunk)
    except BaseException as exc:
        if new_dir and not isinstance(exc, KeyboardInterrupt) and out.is_dir() \
                and not any(out.glob("part-*.parquet")):
            _remove_new_sweep(out)
        raise
    finally:
        if own_client is not None:
            own_client.close()


def _progress(console: Any) -> Any:
    """The sweep's progress bar on ``console``; ``None`` without a console (rich's progress
    is then not even imported)."""
    if console is None:
        return None
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("[bold]sweep"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("chunks"), TimeElapsedColumn(), TimeRemainingColumn(),
                    console=console, transient=False)


def _run(spec: SweepSpec, out: Path, workers: int | None, client: Any, own_client: Any,
         console: Any, _on_chunk: Callable[[int], None] | None) -> SweepResult:
    import contextlib

    todo = missing_chunks(spec, out)
    own_cluster = scratch = None
    t0, c0 = time.perf_counter(), time.process_time()
    peak = 0.0
    done = spec.n_chunks - len(todo)
    n_workers = 0
    progress = _progress(console)
    computed = points = 0
    cpu = 0.0
    parts: dict[int, dict[str, Any]] = {}
    try:
        with progress or contextlib.nullcontext():
            if progress is not None:
                task = progress.add_task("sweep", total=spec.n_chunks, completed=done)

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
                if progress is not None:
                    progress.advance(task)
                if _on_chunk is not None:
                    _on_chunk(i)

            if todo and workers == 0 and client is None:
                for i in todo:
                    table, stats = evaluate_chunk(spec, i)
                    finish(i, *_written(spec, out, i, table), stats)
            elif todo:
                from distributed import Client

                if client is None:
                    scratch = tempfile.mkdtemp(prefix="seactl-sweep-")
                    own_cluster = _local_cluster(workers or os.cpu_count() or 1, scratch)
                    own_client = client = Client(own_cluster)
                n_workers = len(client.scheduler_info(n_workers=-1)["workers"])
                _on_dask(spec, out, todo, client, finish, n_workers)
    except KeyboardInterrupt as exc:
        have = spec.n_chunks - len(missing_chunks(spec, out))
        raise SweepInterrupted(out, have, spec.n_chunks, isinstance(exc, Terminated)) from None
    finally:
        with _uninterrupted():
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
    from .outputs import write_atomic

    write_atomic(out / SUMMARY, json.dumps(summary, indent=2) + "\n")
    _write_manifest(spec, out, "complete")
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
                finish(g[0], *_written(spec, out, g[0], table), stats)
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
                                                     columns=_summary_columns(spec)))
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


def _summary_columns(spec: SweepSpec) -> list[str]:
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
        best = {c: table.column(c)[j].as_py() for c in _summary_columns(spec) if c != "stable"}
    return {"n": table.num_rows, "feasible": int(feas.sum()), "stable": int(stable.sum()),
            "pm_sample": pm[stable][::max(1, spec.n_points // 1_000_000)], "best": best}


# ------------------------------------------------------------------ robustness
@dataclass(frozen=True)
class RobustResult(Result):
    """One design over actuator parameter uncertainty: random samples of the plant's
    parameters (:func:`parameter_robustness`).

    Parameters
    ----------
    nominal_phase_margin_deg : float
        Phase margin of the nominal actuator [deg].
    phase_margin_deg : numpy.ndarray
        One value per sample [deg] (``inf``: no crossover).
    stable : numpy.ndarray
        Stability of each sample.
    samples : dict
        Actuator axis (``Ij``, ``bm``, ``k``, ...) -> its value per sample (rotary SI).

    Attributes
    ----------
    nominal_phase_margin_deg : float
        Phase margin of the nominal actuator [deg].
    phase_margin_deg : ndarray
        One value per sample [deg] (``inf``: no crossover).
    stable : ndarray of bool
        Stability of each sample.
    samples : dict
        Actuator axis -> its value per sample, in that axis's unit (:data:`AXES`).
    n_samples : int
        Number of samples.
    p_unstable : float
        Fraction of unstable samples (the probability of instability, dimensionless).
    """

    nominal_phase_margin_deg: float
    phase_margin_deg: np.ndarray
    stable: np.ndarray
    samples: dict[str, np.ndarray]

    n = Renamed("n_samples")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.stable.size)

    @property
    def p_unstable(self) -> float:
        """Fraction of unstable samples."""
        return float(1.0 - self.stable.mean())

    def p_unstable_ci95(self) -> tuple[float, float]:
        """Wilson 95% interval of the probability of instability.

        Returns
        -------
        tuple of float
            Lower and upper end.
        """
        z, n, p = 1.959963984540054, self.n_samples, self.p_unstable
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        lo = 0.0 if p == 0 else max(0.0, centre - half)   # exact ends (no rounding residue)
        hi = 1.0 if p == 1 else min(1.0, centre + half)
        return lo, hi

    def percentiles(self, q=(1, 5, 50, 95, 99)) -> dict[str, float]:
        """Phase-margin percentiles over the stable samples.

        Parameters
        ----------
        q : sequence of float
            Percentiles.

        Returns
        -------
        dict
            ``"p<q>"`` -> phase margin [deg] (empty without a stable finite sample).
        """
        pm = self.phase_margin_deg[self.stable & np.isfinite(self.phase_margin_deg)]
        if pm.size == 0:
            return {}
        return {f"p{x:g}": float(v) for x, v in zip(q, np.percentile(pm, q))}

    def records(self) -> list[dict[str, Any]]:
        """One flat row per sample: its actuator parameters, phase margin and stability.

        Returns
        -------
        list of dict
            The sampled axes, ``phase_margin_deg``, ``stable``.
        """
        return flat_records({**self.samples, "phase_margin_deg": self.phase_margin_deg,
                             "stable": self.stable})

    def to_dict(self) -> dict[str, Any]:
        """The distribution's summary (the keys ``seactl robust --json`` prints).

        Returns
        -------
        dict
            ``n_samples``, ``nominal_phase_margin_deg``, ``p_unstable``,
            ``p_unstable_ci95``, ``phase_margin_deg_stable`` (percentiles).
        """
        return {"n_samples": self.n_samples,
                "nominal_phase_margin_deg": json_value(self.nominal_phase_margin_deg),
                "p_unstable": json_value(self.p_unstable),
                "p_unstable_ci95": [json_value(x) for x in self.p_unstable_ci95()],
                "phase_margin_deg_stable": {k: json_value(v)
                                            for k, v in self.percentiles().items()}}

    def plot(self, ax: Any = None) -> Any:
        """Histogram of the phase margin over the stable samples, nominal marked.

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
        pm = self.phase_margin_deg[self.stable & np.isfinite(self.phase_margin_deg)]
        ax.hist(pm, bins=40, color="tab:blue")
        ax.axvline(self.nominal_phase_margin_deg, color="k", ls="--", label="nominal")
        ax.set_xlabel("phase margin [deg]")
        ax.set_ylabel("stable samples")
        ax.legend(loc="best")
        return ax


def relative_interval(actuator: SEAParams, name: str, percent: float) -> tuple[float, float]:
    """``nominal * (1 -/+ percent/100)`` of actuator axis ``name``."""
    if not (0 <= percent < 100):
        raise InputError(AXES[name].option, f"{percent:g}%", "a relative uncertainty in "
                         "[0%, 100%)")
    nom = float(getattr(actuator, ACTUATOR_FIELDS[name]))
    return nom * (1 - percent / 100), nom * (1 + percent / 100)


def parameter_robustness(spec: SweepSpec) -> RobustResult:
    """Evaluate a random-sampling spec chunk by chunk in this process.

    ``spec`` fixes one design (``f_n``, GS, delays, filters) and samples the
    plant parameters of its swept actuator axes uniformly in their intervals;
    the nominal phase margin is that of the unperturbed actuator.  ("Monte Carlo" in
    seactl means random latency and loss, :mod:`seactl.timing`.)

    Parameters
    ----------
    spec : SweepSpec
        ``sampling="random"``; only actuator axes swept.

    Returns
    -------
    RobustResult
        Phase margin and stability per sample, and the nominal phase margin.
    """
    if spec.sampling != "random":
        raise InputError("sampling", spec.sampling, "random for a parameter-robustness "
                         "analysis")
    bad = [n for n, _ in spec.swept if n not in ACTUATOR_AXES]
    if bad:
        raise InputError(AXES[bad[0]].option, "several values", "a single value (the "
                         "analysis varies actuator parameters of one design)")
    pm, st = [], []
    samples: dict[str, list[np.ndarray]] = {n: [] for n, _ in spec.swept}
    for i in range(spec.n_chunks):
        t, _ = evaluate_chunk(spec, i)
        feas = t.column("feasible").to_numpy()
        if not feas.all():
            raise InputError("--fn", spec.fixed()["fn_hz"], "a feasible f_n for the nominal "
                             "actuator")
        pm.append(t.column("phase_margin_deg").to_numpy())
        st.append(t.column("stable").to_numpy(zero_copy_only=False).astype(bool))
        for name in samples:
            samples[name].append(t.column(name).to_numpy())
    nominal = SweepSpec(spec.actuator, tuple((n, v) for n, v in spec.axes
                                             if n not in ACTUATOR_AXES))
    t0, _ = evaluate_chunk(nominal, 0)
    return RobustResult(float(t0.column("phase_margin_deg")[0].as_py()), np.concatenate(pm),
                        np.concatenate(st), {k: np.concatenate(v) for k, v in samples.items()})


def monte_carlo(spec: SweepSpec) -> RobustResult:
    """Deprecated name of :func:`parameter_robustness`.

    Parameters
    ----------
    spec : SweepSpec
        As for :func:`parameter_robustness`.

    Returns
    -------
    RobustResult
        As for :func:`parameter_robustness`.
    """
    import warnings

    warnings.warn("seactl.sweep.monte_carlo is deprecated; use "
                  "seactl.sweep.parameter_robustness (Monte Carlo means random latency and "
                  "loss: seactl.timing)", DeprecationWarning, stacklevel=2)
    return parameter_robustness(spec)


__all__ = [
    "AXES", "RobustResult", "SweepInterrupted", "SweepResult", "SweepSpec",
    "evaluate_chunk", "evaluate_points", "impedance_magnitude", "missing_chunks",
    "monte_carlo", "parameter_robustness", "read_sweep", "relative_interval", "run_sweep",
    "summarize",
]


# ------------------------------------------------------------------ maps for plots
def sweep_map(out: Path | str, x: str, y: str, z: str = "phase_margin_deg",
              reduce: str = "min", bins: int = 40) -> dict[str, Any]:
    """``z`` over the two axes ``x`` and ``y`` of the sweep in ``out``.

    Grid sweeps keep their axis values; sampled sweeps are binned (``bins`` per
    axis).  Points sharing a cell (other swept axes) are reduced with ``min``,
    ``max`` or ``mean`` over their feasible points (``min`` of a margin is the
    worst case).  Returns ``x``, ``y`` (cell centres), ``z`` (shape
    ``(len(y), len(x))``, NaN where no feasible point) and ``stable_fraction``.
    """
    out = Path(out)
    manifest = read_manifest(out)
    swept = manifest["swept_axes"]
    for opt, name in (("--plot", x), ("--plot", y)):
        if name not in swept:
            raise InputError(opt, name, "one of the swept axes (" + ", ".join(swept) + ")")
    if x == y:
        raise InputError("--plot", f"{x},{y}", "two different axes")
    cols = set(manifest["columns"]) - {"point", "feasible"}
    if z not in cols:
        raise InputError("--plot-z", z, "one of " + ", ".join(sorted(cols)))
    if reduce not in ("min", "max", "mean"):
        raise InputError("--plot-reduce", reduce, "min, max or mean")
    t = read_sweep(out, [x, y, z, "feasible", "stable"])
    feas = t.column("feasible").to_numpy()
    xv, yv = (t.column(c).to_numpy()[feas] for c in (x, y))
    zv = np.asarray(t.column(z).to_numpy(zero_copy_only=False), float)[feas]
    st = np.asarray(t.column("stable").to_numpy(zero_copy_only=False), float)[feas]

    def cells(v: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
        if manifest["spec"]["sampling"] == "grid":
            grid = np.asarray(manifest["spec"]["axes"][name], float)
            centres = np.unique(grid)
            return centres, np.searchsorted(centres, v)
        lo, hi = float(np.min(v)), float(np.max(v))
        edges = np.linspace(lo, hi, bins + 1)
        return 0.5 * (edges[1:] + edges[:-1]), np.clip(np.searchsorted(edges, v, "right") - 1,
                                                       0, bins - 1)

    xc, ix = cells(xv, x)
    yc, iy = cells(yv, y)
    flat = iy * xc.size + ix
    size = xc.size * yc.size
    count = np.bincount(flat, minlength=size).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = ~np.isnan(zv)
        n_ok = np.bincount(flat[ok], minlength=size)
        if reduce == "mean":
            zs = np.bincount(flat[ok], zv[ok], minlength=size) / n_ok
        else:
            zs = np.full(size, np.inf if reduce == "min" else -np.inf)
            (np.minimum if reduce == "min" else np.maximum).at(zs, flat[ok], zv[ok])
        zs[n_ok == 0] = np.nan
        frac = np.bincount(flat, st, minlength=size) / count
    return {"x": xc, "y": yc, "z": zs.reshape(yc.size, xc.size),
            "stable_fraction": frac.reshape(yc.size, xc.size), "x_name": x, "y_name": y,
            "z_name": z, "reduce": reduce, "n_points": int(t.num_rows)}
