"""Sweeps of a loop file over its design variables, into a Parquet dataset.

``seactl sweep --loop FILE --set NAME=START:STOP:STEP ... --out DIR``: every combination of
the ranged ``--set`` values is one point; points are evaluated in chunks (one vectorized
:meth:`seactl.UserLoop.analyze` each, in this process) and written as ``part-*.parquet``
with a ``_manifest.json``, the layout :func:`seactl.read_sweep` reads.  Columns: ``point``,
the swept variables, then per break ``<break>_phase_margin_deg``, ``_crossover_hz``,
``_gain_margin_db``, ``_delay_margin_ms``, and ``stable`` (the whole loop).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .sweep import remove_sweep_files, write_chunk

FORMAT = "seactl-loop-sweep-1"


def _prepare(out: Path, overwrite: bool) -> None:
    """A new or empty directory, or (with ``overwrite``) a loop sweep seactl wrote (its
    files are removed, files a user added stay)."""
    if out.exists() and not out.is_dir():
        raise InputError("--out", str(out), "a directory path (a Parquet dataset), not a file")
    if out.is_dir() and any(out.iterdir()):
        manifest = out / "_manifest.json"
        ours = manifest.is_file() and json.loads(manifest.read_text()).get("format") == FORMAT
        if not ours:
            raise InputError("--out", str(out), "a new or empty directory, or a loop sweep "
                             "seactl wrote (with --overwrite)")
        if not overwrite:
            raise InputError("--out", str(out), "a new directory, or --overwrite to replace "
                             "this loop sweep")
        remove_sweep_files(out)
    out.mkdir(parents=True, exist_ok=True)


def _remove_partial(out: Path, created: bool) -> None:
    """After a failure: remove what this run wrote (the directory, if it created it)."""
    import shutil

    if created:
        shutil.rmtree(out, ignore_errors=True)
        return
    for p in out.glob("part-*.parquet"):
        p.unlink(missing_ok=True)


def _columns(loop: Any, a: Any, values: dict[str, np.ndarray], start: int) -> dict[str, Any]:
    n = next(iter(values.values())).size if values else 1
    cols: dict[str, Any] = {"point": np.arange(start, start + n)}
    cols.update({k: np.ravel(v) for k, v in values.items()})
    for b in a.breaks:
        m = b.margins
        for key, arr in (("phase_margin_deg", m.phase_margin_deg),
                         ("crossover_hz", m.crossover_hz), ("gain_margin_db", m.gain_margin_db),
                         ("delay_margin_ms", m.delay_margin_ms)):
            cols[f"{b.name}_{key}"] = np.broadcast_to(arr, (n,)).astype(float)
    cols["stable"] = np.broadcast_to(a.stable, (n,)).astype(bool)
    return cols


def sweep_loop(loop: Any, values: dict[str, Any], out: str | Path, *, chunk_size: int = 5000,
               overwrite: bool = False) -> dict[str, Any]:
    """Analyse ``loop`` at every combination of ``values`` (arrays broadcast together) and
    write the dataset; returns the summary (also written to ``_summary.json``)."""
    import pyarrow as pa

    from .outputs import write_atomic

    if chunk_size < 1:
        raise InputError("--chunk-size", chunk_size, ">= 1")
    arrays = dict(zip(values, np.broadcast_arrays(*(np.asarray(v, float)
                                                     for v in values.values()))))
    flat = {k: v.ravel() for k, v in arrays.items()}
    n = next(iter(flat.values())).size if flat else 1
    out = Path(out)
    if not loop.breaks:
        loop.analyze()  # raises: nothing to sweep
    loop.compiled.arrays(flat)  # every value checked before anything is written
    last = list(loop.breaks)[-1]
    created = not out.exists()
    _prepare(out, overwrite)
    t0 = time.perf_counter()
    stable, best = 0, (-np.inf, None)
    try:
        for i, start in enumerate(range(0, n, chunk_size)):
            chunk = {k: v[start:start + chunk_size] for k, v in flat.items()}
            a = loop.with_values(**chunk).analyze(jitter=False)
            cols = _columns(loop, a, chunk, start)
            write_chunk(out, i, pa.table(cols))
            stable += int(cols["stable"].sum())
            pm = np.where(cols["stable"], cols[f"{last}_phase_margin_deg"], -np.inf)
            k = int(np.argmax(pm))
            if pm[k] > best[0]:
                best = (float(pm[k]), {c: float(cols[c][k]) for c in flat})
    except BaseException:
        _remove_partial(out, created)
        raise
    seconds = time.perf_counter() - t0
    summary = {"format": FORMAT, "loop": loop.name, "file": loop.file, "n_points": n,
               "n_chunks": len(range(0, n, chunk_size)), "swept": list(flat),
               "stable": stable, "unstable": n - stable, "seconds": seconds,
               "points_per_s": n / seconds if seconds > 0 else None,
               "best_phase_margin": None if best[1] is None else
               {**best[1], f"{last}_phase_margin_deg": best[0]}}
    write_atomic(out / "_summary.json", json.dumps(summary, indent=2) + "\n")
    write_atomic(out / "_manifest.json", json.dumps(summary, indent=2) + "\n")
    return summary
