"""Impedance benchmark: 10,000 designs x 1,000 frequencies, exact delays, both filters,
against python-control evaluating the same impedance design by design."""

from __future__ import annotations

import numpy as np

from ._harness import BenchResult, benchmark, median_time

N_DESIGNS = 10_000
N_FREQ = 1_000
N_BASELINE = 100  # designs timed for the baseline (per-design cost extrapolated)


def random_designs(n: int, seed: int = 7):
    """Random critically-damped UT-SEA designs with random delays and filters."""
    from seactl.systems.sea.actuators import UT_SEA
    from seactl.systems.sea.design import critically_damped_gains
    from seactl.systems.sea.loops import SEADesign, Timing

    rng = np.random.default_rng(seed)
    fn = rng.uniform(10.0, 60.0, n)
    gs = rng.uniform(0.5, 2.0, n)
    timing = Timing(T_tau=rng.uniform(0, 2e-3, n), T_qs=rng.uniform(0, 10e-3, n),
                    T_qd=rng.uniform(0, 3e-3, n), f_qd=rng.uniform(30, 300, n),
                    f_taud=rng.uniform(30, 300, n))
    return SEADesign(UT_SEA, critically_damped_gains(UT_SEA, fn, gs=gs), timing)


def control_parts(design, i: int):
    """python-control TransferFunctions of the rational parts of design ``i``.

    ``Z = (A + B e^{-sT_qs} + C e^{-sT_qd}) / (D + E e^{-sT_tau})``: the parts come from the
    printed coefficients with ``k_tau := beta`` (tested equal to the block diagram), split
    by setting the delay factors to 0/1; returned over the common denominator ``D``.
    """
    import control

    from seactl.diagram.blockdiagram import DesignSubset
    from seactl.systems.sea.impedance import paper_coefficients_from_factors

    p = DesignSubset(design, np.array([i]), tuple(design.shape))

    def coeffs(eqs, eqd, eT):
        N, D = paper_coefficients_from_factors(p, eqs, eqd, eT, p.beta)
        return (np.array([float(np.real(x.ravel()[0])) for x in N]),
                np.array([float(np.real(x.ravel()[0])) for x in D]))

    a, d = coeffs(0.0, 0.0, 0.0)
    b = coeffs(1.0, 0.0, 0.0)[0] - a
    c = coeffs(0.0, 1.0, 0.0)[0] - a
    e = coeffs(0.0, 0.0, 1.0)[1] - d

    def tf(num):  # ascending -> python-control's descending order
        return control.TransferFunction(num[::-1], d[::-1])

    return tf(a), tf(b), tf(c), tf(e)


def control_impedance(design, i: int, f_hz: np.ndarray) -> np.ndarray:
    """Baseline: rational parts evaluated by python-control times the exact delay factors."""
    TA, TB, TC, TE = control_parts(design, i)
    s = 2j * np.pi * f_hz
    T_qs, T_qd, T_tau = (float(np.ravel(getattr(design, n))[i]) for n in ("T_qs", "T_qd",
                                                                          "T_tau"))
    num = TA(s) + TB(s) * np.exp(-s * T_qs) + TC(s) * np.exp(-s * T_qd)
    return num / (1 + TE(s) * np.exp(-s * T_tau))


@benchmark("impedance")
def bench_impedance(repeat: int) -> BenchResult:
    from seactl.systems.sea.impedance import impedance

    d = random_designs(N_DESIGNS)
    f = np.logspace(-1, 3, N_FREQ)
    reps = max(1, min(repeat, 3))
    t_ours = median_time(lambda: impedance(d, f), reps)
    ours = impedance(d, f).z
    idx = np.linspace(0, N_DESIGNS - 1, N_BASELINE).astype(int)
    t_base = median_time(lambda: [control_impedance(d, int(i), f) for i in idx], reps)
    err = max(float(np.max(np.abs(control_impedance(d, int(i), f) / ours[i] - 1)))
              for i in idx)
    per_design = t_base / idx.size
    return BenchResult(
        "impedance", N_DESIGNS / t_ours,
        "python-control TransferFunction x exact delay factors, loop over designs",
        1.0 / per_design, err,
        note=(f"throughput in designs/s ({N_FREQ} frequencies each, exact delays, both "
              f"filters); ours: {N_DESIGNS} designs in {t_ours:.3g} s (median); baseline "
              f"timed on {idx.size} designs ({per_design * 1e3:.3g} ms/design) and "
              f"extrapolated per design; max error = largest relative difference of Z "
              f"on those designs"))
