"""Benchmarks of the mobile-base simulator: a 10 s circle and a full tuning procedure."""

from __future__ import annotations

import time

import numpy as np

from ._harness import BenchResult, benchmark, median_time


@benchmark("base-circle")
def bench_circle(repeat: int) -> BenchResult:
    """One 10 s circle (one gain setting), sampled multi-rate simulator versus scipy
    ``solve_ivp`` (LSODA) on the same continuous dynamics without sampling.

    Both use the ideal configuration (no quantization, zero delays, central = embedded
    period) so that the trajectories are comparable; ``max_error`` is the largest pose
    difference [m].  The default (22 ms, quantized) configuration costs the same per step.
    """
    from scipy.integrate import solve_ivp

    from seactl.systems.mobile_base import baseline as mb_baseline
    from seactl.systems.mobile_base import model as mb
    from seactl.systems.mobile_base import simulation as mb_simulation

    p = mb.TRIKEY.with_(encoder_counts=0, round_trip=0.0, extra_delay=0.0,
                        central_period=mb.TRIKEY.embedded_period)
    circle = mb_simulation.Circle(p.circle_radius, p.circle_period, p.circle_ramp)
    kx, dx = 100.0, 20.0
    ours = mb_simulation.simulate(p, kx, dx, 0.0, reference=circle, duration=10.0)
    f = mb_baseline.continuous_rhs(p, kx, dx, 0.0, circle)

    def baseline():
        return solve_ivp(f, (0.0, ours.t[-1]), np.zeros(18), t_eval=ours.t, rtol=1e-7,
                         atol=1e-10, method="LSODA")

    sol = baseline()
    err = float(np.max(np.abs(sol.y[:3].T - ours.x[:, 0])))
    t_ours = median_time(lambda: mb_simulation.simulate(p, kx, dx, 0.0, reference=circle,
                                             duration=10.0), repeat)
    t_base = median_time(baseline, max(1, min(repeat, 3)))
    batch = 64
    t_batch = median_time(lambda: mb_simulation.simulate(p, np.full(batch, kx), dx, 0.0,
                                              reference=circle, duration=10.0), 1)
    return BenchResult("base-circle", 1.0 / t_ours, "scipy solve_ivp (LSODA), continuous",
                       1.0 / t_base, err,
                       note=f"10 s circles per second; ours {t_ours:.2f} s, solve_ivp "
                            f"{t_base:.2f} s; a batch of {batch} gain settings in one call "
                            f"takes {t_batch:.2f} s ({batch / t_batch:.3g} circles/s). "
                            "max_error: pose difference (m) of the two (ideal) models.")


@benchmark("base-tuning")
def bench_tuning(repeat: int) -> BenchResult:
    """The full tuning procedure (both architectures, searches + circle) versus the same
    candidates simulated one at a time (estimated: one unbatched criterion run x count)."""
    from seactl.systems.mobile_base import model as mb
    from seactl.systems.mobile_base import tuning as mb_tuning

    p = mb.TRIKEY
    n = max(1, min(repeat, 2))            # each run takes seconds
    comp = mb_tuning.tune(p)
    t_tune = median_time(lambda: mb_tuning.tune(p), n, warmup=0)
    candidates = sum(r.damping_search.gains.size + r.kx_search.gains.size
                     for r in comp.results.values())
    t0 = time.perf_counter()
    mb_tuning.criterion_test(p, 100.0, 0.0, 1.0)
    t_one = time.perf_counter() - t0
    t_loop = t_one * candidates
    return BenchResult("base-tuning", 1.0 / t_tune, "one candidate per simulation (est.)",
                       1.0 / t_loop, 0.0,
                       note=f"full tunings per second; one tuning {t_tune:.2f} s "
                            f"({candidates} candidates in 4 batched simulations + the circle); "
                            f"unbatched estimate {t_loop:.1f} s = {candidates} x "
                            f"{t_one:.2f} s", max_error_text="n/a")
