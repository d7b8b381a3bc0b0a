"""Jitter benchmarks: jitter margins of a 10,000-design batch against python-control (FRD
of the exact-delay loop, ``feedback``, maximum of ``w |T|`` on a dense grid, one design at a
time), and a 1,000-run Monte Carlo of 1 s sampled steps against the same runs one by one."""

from __future__ import annotations

import numpy as np

from ._harness import BenchResult, benchmark, median_time

N_DESIGNS = 10_000
N_BASELINE = 40
MC_RUNS = 1000
MC_BASELINE_RUNS = 20


def _batch():
    import seactl as sc

    fn = np.linspace(12.0, 40.0, 100)[:, None]
    gs = np.linspace(0.5, 2.0, N_DESIGNS // 100)
    return sc.design(fn, gs=gs, delays_ms={"torque": 0.5, "stiffness": 2.0, "damping": 0.5},
                     filters_hz=(50, 100))


def _control_jitter(d, f_hz: np.ndarray) -> float:
    """Outer-loop jitter margin [s] from python-control on a dense grid."""
    import control as ct

    L = d.to_control("frd", f_hz=f_hz)
    w = 2 * np.pi * f_hz
    T = ct.feedback(L, 1).frequency_response(w).magnitude.ravel()
    return 1.0 / float(np.max(w * T))


@benchmark("jitter")
def bench_jitter(repeat: int) -> list[BenchResult]:
    from seactl.latency.jitter import sea_jitter_margins
    from seactl.latency.models import Bernoulli, Uniform
    from seactl.latency.montecarlo import sea_monte_carlo

    d = _batch()
    t_ours = median_time(lambda: sea_jitter_margins(d.sea), max(1, repeat // 2))
    ours = sea_jitter_margins(d.sea)
    flat = d.reshape(N_DESIGNS)
    pick = np.linspace(0, N_DESIGNS - 1, N_BASELINE).astype(int)
    f = np.logspace(-1, 4, 20001)
    _control_jitter(flat[int(pick[0])], f)  # (python-control's first call, not timed)
    t_base = median_time(lambda: [_control_jitter(flat[int(i)], f) for i in pick[:10]], 1,
                         warmup=0) / 10
    o = np.ravel(ours.overall_s)
    err = 0.0
    for i in pick:
        if ours.stable.ravel()[i]:
            err = max(err, abs(_control_jitter(flat[int(i)], f) / o[i] - 1))
    out = [BenchResult(
        "jitter-margins", N_DESIGNS / t_ours, "python-control FRD, 20k-point grid",
        1.0 / t_base, err,
        note=f"4 loop breaks (outer, stiffness, damping, torque) + nominal stability and delay "
             f"margin per design; baseline: outer loop only; max_error = largest relative "
             f"difference of the outer-loop margin over {N_BASELINE} designs",
        max_error_text=f"{err:.1g} rel")]
    one = d[0, 0].sea
    lat, loss = {"damping": Uniform(0.5e-3, 3e-3)}, {"damping": Bernoulli(0.01)}

    def mc(runs, seed=0):
        return sea_monte_carlo(one, latency=lat, loss=loss, runs=runs, seed=seed, t_end_s=1.0)

    t_mc = median_time(lambda: mc(MC_RUNS), max(1, repeat // 2))
    t_seq = median_time(lambda: [mc(1, s) for s in range(MC_BASELINE_RUNS)], 1, warmup=0)
    # run r draws from its own stream: run 0 of the batch is the single run of the same seed
    q_batch = mc(MC_BASELINE_RUNS).result.outputs["q_j"][0]
    q_one = mc(1).result.outputs["q_j"][0]
    err_mc = float(np.max(np.abs(q_batch - q_one)) / np.max(np.abs(q_one)))
    out.append(BenchResult(
        "monte-carlo", MC_RUNS / t_mc, "one run per call", MC_BASELINE_RUNS / t_seq, err_mc,
        note=f"runs/s: {MC_RUNS} runs of a 1 s step at 1 kHz (UT-SEA 14 Hz, damping link "
             f"uniform 0.5-3 ms + 1 % loss) in {t_mc:.2f} s; max_error = run 0 of the batch "
             "against the same run alone",
        max_error_text=f"{err_mc:.1g} rel"))
    return out
