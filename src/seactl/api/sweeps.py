"""Design-space sweeps of the public API: :func:`sweep`, :func:`read_sweep` and
:func:`parameter_robustness` (one design over random actuator parameters)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from seactl.api.arguments import resolve_actuator


# ------------------------------------------------------------------ sweeps
def sweep(out: str | Path, *, actuator: Any = "ut-sea", sampling: str = "grid",
          n_samples: int = 0, seed: int = 0, chunk_size: int = 5000,
          z_freqs_hz: Sequence[float] = (), workers: int | None = None,
          scheduler: str | None = None, client: Any = None, resume: bool = False,
          overwrite: bool = False, **axes: Any) -> Any:
    """Sweep the SEA design space into a resumable Parquet dataset.

    Parameters
    ----------
    out : str or path
        Output directory (created; refused if it holds something else).
    actuator : str or path or SEAParams
        Nominal actuator.
    sampling : {"grid", "random", "lhs"}
        Cartesian grid, or ``n_samples`` random / Latin-hypercube points in the axes'
        ranges.
    n_samples, seed : int
        Sample count and seed of the sampling modes.
    chunk_size : int
        Points per chunk (one Parquet file each).
    z_freqs_hz : sequence of float
        Frequencies [Hz] at which to store ``|Z|``.
    workers : int, optional
        Local Dask worker processes (default: all cores; 0: in this process).
    scheduler : str, optional
        Address of a Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    client : distributed.Client, optional
        An existing Dask client.
    resume, overwrite : bool
        Finish an interrupted sweep / replace a previous one.
    **axes : array_like
        Values per axis, units in the names: ``fn_hz``, ``gs``, ``zeta1``, ``zeta2``,
        ``ratio``, ``t_tau_ms``, ``t_qs_ms``, ``t_qd_ms``, ``f_qd_hz``, ``f_taud_hz`` and
        plant parameters ``Im``, ``Ij``, ``bm``, ``bj``, ``k``, ``beta`` (rotary SI).

    Returns
    -------
    seactl.sweep.engine.SweepResult
        Where the data went, counts, timing; read it with :func:`read_sweep`.

    Examples
    --------
    >>> import tempfile, seactl as sc
    >>> out = tempfile.mkdtemp() + "/s"
    >>> res = sc.sweep(out, fn_hz=[12, 14, 16], t_qs_ms=[0, 2], workers=0)
    >>> res.n_points, len(sc.read_sweep(out))
    (6, 6)
    """
    from seactl.sweep.engine import run_sweep

    spec = _spec(actuator, axes, sampling=sampling, n_samples=n_samples, seed=seed,
                 chunk_size=chunk_size, z_freqs_hz=tuple(z_freqs_hz))
    return run_sweep(spec, out, resume=resume, overwrite=overwrite, workers=workers,
                     scheduler=scheduler, client=client)


def _spec(actuator: Any, axes: dict[str, Any], **options: Any) -> Any:
    """The sweep spec of a nominal ``actuator`` and the values of each axis."""
    from seactl.sweep.spec import SweepSpec
    from seactl.systems.sea.actuators import SEAParams, load_sea

    act = resolve_actuator(actuator, load_sea, SEAParams)
    return SweepSpec(act, axes=tuple((k, tuple(np.ravel(v))) for k, v in axes.items()),
                     **options)


def read_sweep(out: str | Path, columns: Sequence[str] | None = None) -> Any:
    """Read a sweep dataset as one table sorted by point index.

    Parameters
    ----------
    out : str or path
        The sweep's output directory.
    columns : sequence of str, optional
        Columns to read (default: all).

    Returns
    -------
    pyarrow.Table
        One row per design point; ``.to_pandas()`` if pandas is installed.

    Examples
    --------
    >>> import tempfile, seactl as sc
    >>> out = tempfile.mkdtemp() + "/s"
    >>> _ = sc.sweep(out, fn_hz=[12, 14], workers=0)
    >>> [round(x, 2) for x in sc.read_sweep(out).column("phase_margin_deg").to_pylist()]
    [54.37, 55.51]
    """
    from seactl.sweep.dataset import read_sweep as read

    return read(out, columns)


def parameter_robustness(*, actuator: Any = "ut-sea", n_samples: int = 2000, seed: int = 0,
                         chunk_size: int = 5000, **axes: Any) -> Any:
    """One design's phase margin over random actuator parameters (``seactl robust``).

    The gains are designed for the nominal ``actuator``; each sample draws the plant
    parameters given as intervals uniformly in them, and the loop's margins are computed
    with the nominal gains on the sampled plant.  ("Monte Carlo" elsewhere in seactl means
    random latency and loss: :meth:`System.monte_carlo`.)

    Parameters
    ----------
    actuator : str or path or SEAParams
        Nominal actuator.
    n_samples, seed : int
        Number of random samples and their seed.
    chunk_size : int
        Samples evaluated per batch.
    **axes : array_like
        The design: one value each of ``fn_hz``, ``gs``, ``t_tau_ms``, ``t_qs_ms``,
        ``t_qd_ms``, ``f_qd_hz``, ``f_taud_hz`` (units in the names); the uncertain plant
        parameters (``Im``, ``Ij``, ``bm``, ``bj``, ``k``, ``beta``, rotary SI) as
        ``(low, high)`` intervals.

    Returns
    -------
    seactl.sweep.robustness.RobustResult
        The nominal phase margin, the phase margin and stability of each sample, the
        sampled parameters, ``p_unstable`` and its Wilson interval ``p_unstable_ci95()``.

    Examples
    --------
    >>> import seactl as sc
    >>> k = sc.UT_SEA.spring_stiffness
    >>> r = sc.parameter_robustness(fn_hz=14, t_qs_ms=2, k=(0.8 * k, 1.2 * k),
    ...                             n_samples=200, seed=1)
    >>> r.n_samples, round(r.nominal_phase_margin_deg, 2)
    (200, 49.69)
    """
    from seactl.sweep.robustness import parameter_robustness as evaluate

    return evaluate(_spec(actuator, axes, sampling="random", n_samples=n_samples, seed=seed,
                          chunk_size=chunk_size))
