"""Latency-map benchmarks: a 200 x 200 (stiffness delay, damping delay) phase-margin map per
actuator, against python-control ``stability_margins`` on an FRD of the same exact-delay loop,
one grid point at a time."""

from __future__ import annotations

import time
import warnings

import numpy as np

from ._harness import BenchResult, benchmark, median_time

N = 200                  # grid points per axis
T_RANGE = (0.5e-3, 20e-3)
SUBSET = 40              # baseline grid points actually timed (then extrapolated)
FRD_POINTS = 2000


def _baseline(model, fn_hz: float, ts: np.ndarray, td: np.ndarray) -> tuple[float, np.ndarray]:
    """python-control, per grid point: exact-delay loop on a dense log grid -> FRD ->
    stability_margins.  Returns (seconds per point, phase margins)."""
    import control as ct

    loop = model.diagram.loop(model.sensor)
    pms = np.empty(ts.size)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, (a, b) in enumerate(zip(ts, td)):
            d = model.design(fn_hz, a, b)
            wn = float(model.grid(d)[..., model.grid(d).shape[-1] // 2])
            w = np.geomspace(wn / 100, wn * 100, FRD_POINTS)
            L = np.asarray(loop(d, 1j * w)).reshape(-1)
            _gm, pm, *_ = ct.stability_margins(ct.frd(L, w))
            pms[i] = pm
    return (time.perf_counter() - t0) / ts.size, pms


def _run(model, fn_hz: float, repeat: int) -> BenchResult:
    from seactl.latency.maps import latency_map

    grid = np.linspace(*T_RANGE, N)
    t_ours = median_time(lambda: latency_map(model, fn_hz, grid, grid), repeat)
    mp = latency_map(model, fn_hz, grid, grid)
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, N, SUBSET), rng.integers(0, N, SUBSET)
    per_point, pms = _baseline(model, fn_hz, grid[i], grid[j])
    ours = mp.phase_margin_deg[i, j]
    both = np.isfinite(pms) & np.isfinite(ours)
    err = float(np.max(np.abs(ours[both] - pms[both]))) if both.any() else float("nan")
    return BenchResult(
        f"latency-map-{model.name}", N * N / t_ours,
        f"python-control FRD ({FRD_POINTS} pts) + stability_margins per point",
        1.0 / per_point, err,
        note=f"{N}x{N} map ({T_RANGE[0] * 1e3:g}-{T_RANGE[1] * 1e3:g} ms on each loop, "
             f"f_n = {fn_hz:g} Hz) in {t_ours:.2f} s (median of {repeat}); baseline timed on "
             f"{SUBSET} random grid points ({per_point * 1e3:.1f} ms each) and extrapolated to "
             f"{N * N * per_point:.0f} s for the full grid; max error = largest |PM difference| "
             f"(deg) on those points. Throughput in grid points/s. python-control gives no "
             "closed-loop stability for loops with unstable inner loops; ours does (Nyquist).")


@benchmark("latency-map")
def bench_latency_map(repeat: int) -> list[BenchResult]:
    from seactl.latency.maps import rigid_model, sea_model

    r = max(1, min(repeat, 3))   # each run maps 40,000 designs
    return [_run(rigid_model(), 8.0, r), _run(sea_model(), 14.0, r)]
