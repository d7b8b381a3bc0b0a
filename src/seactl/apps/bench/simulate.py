"""Simulation benchmark: exact-delay continuous step of the UT-SEA (single design and a
batch of 1,000) against python-control ``forced_response`` on a Pade(5) version of the
same loop, built independently from python-control blocks."""

from __future__ import annotations

import os

import numpy as np

from ._harness import BenchResult, benchmark, median_time

T_END = 0.5
DELAY = 1e-3


def pade_loop(actuator, gains, delay_s: float, order: int = 5, f_qd: float = 50.0,
              f_taud: float = 100.0):
    """The SEA loop (q_des -> q_j) from python-control blocks, each delay a Pade(order)."""
    import control as ct

    a = actuator
    A = np.array([[0, 1, 0, 0], [-a.k / a.Im, -a.bm / a.Im, a.k / a.Im, 0], [0, 0, 0, 1],
                  [a.k / a.Ij, 0, -a.k / a.Ij, -a.bj / a.Ij]])
    B = np.array([[0], [a.beta / a.Im], [0], [0]])  # (tau_ext is zero in a step)
    C = np.array([[0, 0, 1, 0], [a.k, 0, -a.k, 0]])
    plant = ct.ss(A, B, C, 0, inputs=["i_m"], outputs=["q_j", "tau_k"])
    wv, wt = 2 * np.pi * f_qd, 2 * np.pi * f_taud
    Kq, Bq, Kt, Bt = (float(x) for x in (gains.Kq, gains.Bq, gains.Ktau, gains.Btau))

    def delay(inp, out):
        return ct.ss(ct.tf(*ct.pade(delay_s, order)), inputs=inp, outputs=out)

    blocks = [plant, delay("q_j", "q_s"), delay("q_j", "q_d"), delay("tau_k", "tau_meas"),
              ct.ss(ct.tf([-Bq * wv, 0], [1, wv]), inputs="q_d", outputs="fb_d"),
              ct.ss(ct.tf([-Kq], [1]), inputs="q_s", outputs="fb_s"),
              ct.ss(ct.tf([Kq], [1]), inputs="q_des", outputs="ref"),
              ct.summing_junction(inputs=["ref", "fb_s", "fb_d"], output="tau_des"),
              ct.summing_junction(inputs=["tau_des", "-tau_meas"], output="e"),
              ct.ss(ct.tf([Bt * wt + Kt, Kt * wt], [1, wt]), inputs="e", outputs="ipd"),
              ct.ss(ct.tf([1 / a.beta], [1]), inputs="tau_des", outputs="iff"),
              ct.summing_junction(inputs=["ipd", "iff"], output="i_m")]
    return ct.interconnect(blocks, inplist=["q_des"], outlist=["q_j"])


@benchmark("simulate")
def bench_simulate(repeat: int) -> list[BenchResult]:
    import control as ct

    from seactl.systems.sea.actuators import UT_SEA
    from seactl.systems.sea.design import critically_damped_gains
    from seactl.systems.sea.loops import SEADesign, Timing
    from seactl.systems.sea.views import sea_step

    timing = Timing.from_ms(1.0, 1.0, 1.0, 50.0, 100.0)
    one = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 14.0), timing)
    fn = np.linspace(12.0, 20.0, 1000)
    batch = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, fn), timing)

    t_one = median_time(lambda: sea_step(one, t_end_s=T_END), repeat)
    t_batch = median_time(lambda: sea_step(batch, t_end_s=T_END), repeat)

    ours = sea_step(one, t_end_s=T_END)
    sys = pade_loop(UT_SEA, one.gains, DELAY)
    t = ours.t_s
    u = np.ones_like(t)
    t_base = median_time(lambda: ct.forced_response(sys, t, u), repeat)
    y = np.asarray(ct.forced_response(sys, t, u).outputs).ravel()
    pade_err = float(np.max(np.abs(y - ours.position)))
    # the batch against the baseline on a few of its designs (error of Pade vs exact)
    rb = sea_step(batch, t_end_s=T_END)
    errs = []
    for i in (0, 499, 999):
        yb = ct.forced_response(pade_loop(UT_SEA, batch.gains[i], DELAY), t, u).outputs
        errs.append(float(np.max(np.abs(np.ravel(yb) - rb.position[i]))))
    base_rate = T_END / t_base
    note = (f"UT-SEA step, f_n 14 Hz (batch: 12-20 Hz), all delays 1 ms, filters 50/100 Hz, "
            f"{T_END:g} s simulated at dt = 0.1 ms with exact delays; baseline python-control "
            f"forced_response on the loop with Pade(5) delays ({sys.nstates} states); "
            "max error = Pade result vs exact-delay simulation (normalized step)")
    return [
        BenchResult("simulate-step-single", T_END / t_one, "python-control forced_response, "
                    "Pade(5)", base_rate, pade_err, note),
        BenchResult("simulate-step-batch1000", 1000 * T_END / t_batch,
                    "python-control forced_response, Pade(5), per design", base_rate,
                    max(errs), "throughput = design-seconds simulated per wall second, the "
                    f"batch split over {os.cpu_count()} threads (one per core; the baseline "
                    "uses one); " + note),
    ]
