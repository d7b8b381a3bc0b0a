"""A sweep's dataset on disk: Parquet parts, manifest, resume and reading."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from seactl.base.axes import AXES
from seactl.base.outputs import TEMP_TAG
from seactl.errors import InputError, OutputError
from seactl.sweep.spec import FORMAT, OUTPUTS, SweepSpec, json_float, z_column


# ------------------------------------------------------------------ dataset on disk
def part_path(out: Path, i: int) -> Path:
    return Path(out) / f"part-{i:05d}.parquet"


def write_chunk(out: Path, i: int, table: Any) -> None:
    """Write chunk ``i`` atomically (:func:`seactl.base.outputs.write_atomic_with`)."""
    import pyarrow.parquet as pq

    from seactl.base.outputs import write_atomic_with

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


def write_manifest(spec: SweepSpec, out: Path, status: str) -> None:
    from seactl.base.outputs import write_atomic

    fixed = {k: json_float(v) for k, v in spec.fixed().items()}
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
        from seactl.base.outputs import reason

        raise OutputError(out, reason(exc)) from None
    write_manifest(spec, out, "running")


def remove_sweep_files(out: Path) -> None:
    """Remove what a sweep writes into ``out`` (chunks, manifest, summary, temporaries),
    nothing else: files a user added stay."""
    for p in [*out.glob("part-*.parquet"), out / MANIFEST, out / SUMMARY,
              *out.glob(f".part-*{TEMP_TAG}*"), *out.glob(f".{MANIFEST}*"),
              *out.glob(f".{SUMMARY}*")]:
        p.unlink(missing_ok=True)


def remove_new_sweep(out: Path) -> None:
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
