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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seactl.errors import InputError
from seactl.sweep.dataset import remove_sweep_files, write_chunk

FORMAT = "seactl-loop-sweep-1"


def _prepare(out: Path, overwrite: bool) -> None:
    """A new or empty directory, or (with ``overwrite``) a loop sweep seactl wrote (its
    files are removed, files a user added stay)."""
    if out.exists() and not out.is_dir():
        raise InputError("out", str(out), "a directory path (a Parquet dataset), not a file")
    if out.is_dir() and any(out.iterdir()):
        manifest = out / "_manifest.json"
        ours = manifest.is_file() and json.loads(manifest.read_text()).get("format") == FORMAT
        if not ours:
            raise InputError("out", str(out), "a new or empty directory, or a loop sweep "
                             "seactl wrote (with overwrite=True, --overwrite)")
        if not overwrite:
            raise InputError("out", str(out), "a new directory, or overwrite=True "
                             "(--overwrite) to replace this loop sweep")
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


SAMPLINGS = ("grid", "random", "lhs")
"""How the points are chosen: every combination of the values, or ``n_samples`` uniform
random / Latin-hypercube points over the interval each multi-valued variable spans."""


@dataclass(frozen=True)
class LoopPoints:
    """The points of a loop sweep, generated chunk by chunk (memory bounded by a chunk,
    whatever the number of points)."""

    values: dict[str, Any]
    sampling: str = "grid"
    n_samples: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.sampling not in SAMPLINGS:
            raise InputError("sampling", self.sampling, "one of " + ", ".join(SAMPLINGS))
        if self.sampling != "grid" and (isinstance(self.n_samples, bool) or
                                        int(self.n_samples) != self.n_samples or
                                        self.n_samples < 1):
            raise InputError("n_samples", self.n_samples, f"an integer >= 1 (the number "
                             f"of {self.sampling} points)")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise InputError("seed", self.seed, "an integer >= 0")
        try:
            np.broadcast_shapes(*(np.shape(v) for v in self.values.values()))
        except ValueError:
            raise InputError("values", {k: np.shape(v) for k, v in self.values.items()},
                             "arrays that broadcast together") from None

    @property
    def shape(self) -> tuple[int, ...]:
        return np.broadcast_shapes(*(np.shape(v) for v in self.values.values()))

    @property
    def n_points(self) -> int:
        if self.sampling != "grid":
            return int(self.n_samples)
        return int(np.prod(self.shape, dtype=float))

    def chunk(self, i: int, start: int, stop: int) -> dict[str, np.ndarray]:
        """The values of points ``[start, stop)`` (chunk ``i``; samples are drawn per
        chunk from the seed ``(seed, i)``)."""
        if self.sampling == "grid":
            shape = self.shape
            if shape == ():
                return {k: np.full(stop - start, float(v)) for k, v in self.values.items()}
            idx = np.unravel_index(np.arange(start, stop, dtype=np.int64), shape)
            return {k: np.broadcast_to(np.asarray(v, float), shape)[idx]
                    for k, v in self.values.items()}
        varied = [k for k, v in self.values.items() if np.size(v) > 1]
        rng = np.random.default_rng([int(self.seed), i])
        n = stop - start
        if self.sampling == "random" or not varied:
            u = rng.random((n, len(varied)))
        else:
            from scipy.stats import qmc

            u = qmc.LatinHypercube(len(varied), rng=rng).random(n)
        out = {k: np.full(n, float(np.ravel(v)[0])) for k, v in self.values.items()
               if k not in varied}
        for j, k in enumerate(varied):
            lo, hi = float(np.min(self.values[k])), float(np.max(self.values[k]))
            out[k] = lo + (hi - lo) * u[:, j]
        return out


def sweep_loop(loop: Any, values: dict[str, Any], out: str | Path, *, chunk_size: int = 5000,
               overwrite: bool = False, sampling: str = "grid", n_samples: int = 0,
               seed: int = 0) -> dict[str, Any]:
    """Analyse ``loop`` at every combination of ``values`` (arrays broadcast together), or
    at ``n_samples`` random / Latin-hypercube points over the interval each multi-valued
    variable spans (``sampling``), and write the dataset; returns the summary (also
    written to ``_summary.json``)."""
    import pyarrow as pa

    from seactl.base.outputs import write_atomic

    if isinstance(chunk_size, bool) or int(chunk_size) != chunk_size or chunk_size < 1:
        raise InputError("chunk_size", chunk_size, "an integer >= 1")
    if not str(out).strip():
        raise InputError("out", str(out), "a directory path (not empty)")
    points = LoopPoints(dict(values), sampling, n_samples, seed)
    n = points.n_points
    out = Path(out)
    if not loop.breaks:
        loop.analyze()  # raises: nothing to sweep
    for k, v in values.items():  # every value checked before anything is written
        loop.compiled.arrays({**{j: np.ravel(w)[0] for j, w in values.items()},
                              k: np.ravel(np.asarray(v, float))})
    last = list(loop.breaks)[-1]
    created = not out.exists()
    _prepare(out, overwrite)
    t0 = time.perf_counter()
    stable, best = 0, (-np.inf, None)
    try:
        for i, start in enumerate(range(0, n, chunk_size)):
            chunk = points.chunk(i, start, min(start + chunk_size, n))
            a = loop.with_values(**chunk).analyze(jitter=False)
            cols = _columns(loop, a, chunk, start)
            write_chunk(out, i, pa.table(cols))
            stable += int(cols["stable"].sum())
            pm = np.where(cols["stable"], cols[f"{last}_phase_margin_deg"], -np.inf)
            k = int(np.argmax(pm))
            if pm[k] > best[0]:
                best = (float(pm[k]), {c: float(cols[c][k]) for c in chunk})
    except BaseException:
        _remove_partial(out, created)
        raise
    seconds = time.perf_counter() - t0
    summary = {"format": FORMAT, "loop": loop.name, "file": loop.file, "n_points": n,
               "n_chunks": len(range(0, n, chunk_size)), "swept": list(values),
               "sampling": sampling, "n_samples": n_samples if sampling != "grid" else None,
               "seed": seed if sampling != "grid" else None,
               "stable": stable, "unstable": n - stable, "seconds": seconds,
               "points_per_s": n / seconds if seconds > 0 else None,
               "best_phase_margin": None if best[1] is None else
               {**best[1], f"{last}_phase_margin_deg": best[0]}}
    write_atomic(out / "_summary.json", json.dumps(summary, indent=2) + "\n")
    write_atomic(out / "_manifest.json", json.dumps(summary, indent=2) + "\n")
    return summary
