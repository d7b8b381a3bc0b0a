"""Threads over a batch of designs.

The compiled kernels (the continuous simulation, the certified margin scan) and numpy's
batched linear algebra release the GIL, so a large batch runs in one thread per core, each
thread on its own contiguous part of the batch; designs are independent, so the result is
the one-thread result bit for bit.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from seactl.errors import InputError

THREADS: int | None = None
"""Threads per batch (None: the environment variable ``SEACTL_THREADS``, or one per
core).  :func:`one_thread` pins it where processes already run one per core (the sweep's
workers, the report's sections)."""


def threads() -> int:
    """Threads a batch may use (:data:`THREADS`)."""
    if THREADS:
        return THREADS
    env = os.environ.get("SEACTL_THREADS", "").strip()
    if not env:
        return os.cpu_count() or 1
    if not env.isdigit() or int(env) < 1:
        raise InputError("SEACTL_THREADS", env, "a whole number >= 1 (threads per batch)")
    return int(env)


def parts(n: int, min_per_thread: int) -> list[slice]:
    """Contiguous parts of a batch of ``n`` designs, one per thread, each at least
    ``min_per_thread`` designs (below that, starting a thread costs more than it saves)."""
    k = max(1, min(threads(), n // max(min_per_thread, 1)))
    edges = np.linspace(0, n, k + 1).round().astype(int)
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def in_threads(run: Callable[[slice], Any], n: int, min_per_thread: int) -> list[Any]:
    """``[run(part) for part in parts(n, min_per_thread)]``, the parts in threads."""
    ps = parts(n, min_per_thread)
    if len(ps) == 1:
        return [run(ps[0])]
    with ThreadPoolExecutor(len(ps)) as pool:
        return [f.result() for f in [pool.submit(run, p) for p in ps]]


def map_in_threads(run: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
    """``[run(x) for x in items]``, the items (independent chunks of work) split over one
    thread per core, each thread on its own contiguous share, in order."""
    return [r for part in in_threads(lambda k: [run(x) for x in items[k]], len(items), 1)
            for r in part]


def chunk_size(total: int, most: int) -> int:
    """A chunk length of at most ``most`` (memory) that still gives every thread a chunk
    of ``total``."""
    return max(1, min(most, -(-int(total) // threads())))


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Batches in the calling thread only, within the block."""
    global THREADS
    saved, THREADS = THREADS, 1
    try:
        yield
    finally:
        THREADS = saved


def stacked(fn: Callable[[np.ndarray], np.ndarray], A: np.ndarray,
            min_per_thread: int = 4) -> np.ndarray:
    """``fn`` (a numpy ``linalg`` function of a stack of matrices, such as
    ``np.linalg.eigvals`` or ``np.linalg.inv``) with the stack split over one thread per
    core and LAPACK on one thread per call (for many small problems its own threads only
    contend), the same result bit for bit (LAPACK solves each matrix alone).  A single
    matrix goes to ``fn`` as it is.

    Examples
    --------
    >>> import numpy as np
    >>> stacked(np.linalg.inv, np.array([[[2.0, 0.0], [0.0, 4.0]]])).tolist()
    [[[0.5, 0.0], [0.0, 0.25]]]
    """
    A = np.asarray(A)
    if A.ndim < 3:  # one matrix
        return fn(A)
    with single_threaded_blas():
        out = in_threads(lambda k: fn(A[k]), len(A), min_per_thread)
    return out[0] if len(out) == 1 else np.concatenate(out)


def eigvals(A: np.ndarray, min_per_thread: int = 4) -> np.ndarray:
    """``np.linalg.eigvals`` of a stack of matrices (leading axis), in threads
    (:func:`stacked`).

    Examples
    --------
    >>> import numpy as np
    >>> eigvals(np.array([[[2.0, 0.0], [0.0, 3.0]], [[0.0, 1.0], [-1.0, 0.0]]])).tolist()
    [[(2+0j), (3+0j)], [1j, -1j]]
    """
    return stacked(np.linalg.eigvals, A, min_per_thread)


@lru_cache(maxsize=1)
def _openblas() -> tuple[Any, Any] | None:
    """numpy's bundled OpenBLAS thread get/set functions, if it has them."""
    libs = Path(np.__file__).parent.parent / "numpy.libs"
    for path in sorted(libs.glob("libscipy_openblas*.so")) + sorted(libs.glob("libopenblas*.so")):
        try:
            lib = ctypes.CDLL(str(path))
        except OSError:
            continue
        for get, set_ in (("scipy_openblas_get_num_threads64_",
                           "scipy_openblas_set_num_threads64_"),
                          ("openblas_get_num_threads", "openblas_set_num_threads")):
            if hasattr(lib, get) and hasattr(lib, set_):
                return getattr(lib, get), getattr(lib, set_)
    return None


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run LAPACK on one thread inside the block (no-op without numpy's OpenBLAS)."""
    funcs = _openblas()
    if funcs is None:
        yield
        return
    get, set_ = funcs
    before = int(get())
    set_(1)
    try:
        yield
    finally:
        set_(before)
