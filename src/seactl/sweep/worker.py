"""Local sweep workers: loaded before their first chunk, and deaf to Ctrl-C.

A worker needs the sweep's modules and compiled kernels. A spawned worker loads them
(numba's registries, scipy.linalg through numba's BLAS check, the kernels' cache) before
its first chunk; on a cold numba cache it compiles them. Where the platform has a fork
server (Linux, macOS), :func:`seactl.sweep.engine.local_cluster` has it import
:mod:`seactl.sweep.template`, which calls :func:`warm` once; every worker is then forked
with all of that loaded. Elsewhere (Windows) the workers spawn, and :func:`dask_setup`
warms each one as it starts.

Workers ignore SIGINT. Ctrl-C then reaches only the parent, which cancels the chunks and
closes the cluster, and no worker prints a traceback.

Warming is best effort. If it fails, each worker meets the same error on its first chunk,
and the sweep reports it there.
"""

from __future__ import annotations

import signal
import threading
import warnings
from typing import Any

_warm = False  # (inherited by forked workers)


def warm() -> None:
    """Import Dask's worker and the sweep's modules, and load the sweep's kernels (a
    two-point chunk), once per process; any error is left to the first chunk."""
    global _warm
    if _warm:
        return
    main = threading.current_thread() is threading.main_thread()
    # a fork server is in the terminal's process group: Ctrl-C while it warms must not
    # print its traceback (the parent stops the sweep)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import distributed.worker  # noqa: F401 - what every worker runs

            from seactl.sweep.evaluate import evaluate_chunk
            from seactl.sweep.spec import SweepSpec
            from seactl.systems.sea.actuators import UT_SEA

            # (not the impedance columns' path: it would load sympy in every sweep)
            evaluate_chunk(SweepSpec(UT_SEA, (("fn_hz", (12.0, 20.0)),)), 0)
            _warm = True
    except Exception:  # noqa: BLE001, S110 - reported by the first chunk instead
        pass
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def dask_setup(worker: Any) -> None:
    """Dask's worker preload: the worker ignores SIGINT, and is warmed if not forked
    warm (see the module's docstring)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    warm()
