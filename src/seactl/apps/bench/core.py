"""Core benchmarks: gain designs (vs scipy fsolve) and phase margins (vs python-control)."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from ._harness import BenchResult, benchmark, median_time

# Initial guess of the authors' MATLAB (linear units Kq, Bq, Ktau, Btau, solved in log space).
MATLAB_X0 = np.log([1e4, 1e3, 1.0, 0.1])


def fsolve_gains(actuator, fn_hz: float, x0: np.ndarray = MATLAB_X0, formulation: str = "log"):
    """The baseline: scipy.optimize.fsolve on the four equations (linear units), from the
    MATLAB initial guess.  ``formulation``: ``"log"``, the unknowns are the logarithms of
    the gains (the MATLAB script's); ``"plain"``, the unknowns are the gains themselves
    (started from ``exp(x0)``).  Returns (rotary gains, converged)."""
    from scipy.optimize import fsolve

    from seactl.systems.sea.design import characteristic_coefficients, target_polynomial

    lin = actuator.linear()
    r = actuator.pulley_radius
    w = 2 * np.pi * fn_hz
    target = np.array(target_polynomial(w, w, 1.0, 1.0))

    class _Lin:  # the same actuator in linear units, for the same equations
        Im, Ij = lin["motor_inertia"], lin["joint_inertia"]
        bm, bj = lin["motor_damping"], lin["joint_damping"]
        k, beta = lin["spring_stiffness"], lin["current_to_force"]

    gains = np.exp if formulation == "log" else np.asarray

    def resid(x):
        Kq, Bq, Kt, Bt = gains(x)
        return np.array(characteristic_coefficients(_Lin, Kq, Bq, Kt, Bt)) / target - 1.0

    start = x0 if formulation == "log" else np.exp(x0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        x, _info, ier, _msg = fsolve(resid, start, full_output=True)
    ok = ier == 1 and np.max(np.abs(resid(x))) < 1e-6
    Kq, Bq, Kt, Bt = gains(x)
    return (Kq * r**2, Bq * r**2, Kt / r, Bt / r), bool(ok)


@benchmark("gain-design")
def bench_gain_design(repeat: int) -> BenchResult:
    from seactl.systems.sea.actuators import UT_SEA
    from seactl.systems.sea.design import solve_gains

    fn = np.linspace(10.0, 200.0, 1_000_000)
    t_ours = median_time(lambda: solve_gains(UT_SEA, fn), repeat)
    sols = solve_gains(UT_SEA, fn)
    ref_idx = np.argmax(sols.valid, axis=-1)

    sub = np.linspace(10.0, 200.0, 191)
    t_base = median_time(lambda: [fsolve_gains(UT_SEA, f) for f in sub], max(1, repeat // 2))
    failures, err = 0, 0.0
    ours_sub = solve_gains(UT_SEA, sub)
    for i, f in enumerate(sub):
        g, ok = fsolve_gains(UT_SEA, f)
        if not ok:
            failures += 1
            continue
        j = int(np.argmax(ours_sub.valid[i]))
        mine = np.array([ours_sub.Kq[i, j], ours_sub.Bq[i, j], ours_sub.Ktau[i, j],
                         ours_sub.Btau[i, j]])
        err = max(err, float(np.max(np.abs(np.array(g) - mine) / np.abs(mine))))
    assert np.all(sols.valid[np.arange(fn.size), ref_idx])
    plain = sum(not fsolve_gains(UT_SEA, f, formulation="plain")[1] for f in sub)
    return BenchResult(
        "gain-design", fn.size / t_ours, "scipy fsolve (MATLAB x0)", sub.size / t_base, err,
        note=f"fsolve from the MATLAB initial guess, unknowns the log-gains (the MATLAB "
             f"script's formulation), failed to converge for {failures}/{sub.size} f_n in "
             f"[10, 200] Hz ({100 * failures / sub.size:.0f}%); the same fsolve with the gains "
             f"themselves as unknowns failed for {plain}/{sub.size}; max_error = max relative "
             "gain difference where it converged",
        max_error_text=f"{err:.2g} rel")


def _dense_reference_pm(loop, design, fn_hz: np.ndarray, n: int = 200_000) -> np.ndarray:
    """Phase margin from a very dense log grid (linear interpolation of log|L|)."""
    from seactl.diagram.blockdiagram import DesignSubset

    out = np.empty(fn_hz.size)
    w = 2 * np.pi * np.logspace(-1, 3, n)
    for i in range(fn_hz.size):  # reference only: a loop is fine here
        L = loop(DesignSubset(design, np.array([i]), design.shape), 1j * w)[0]
        lm = np.log(np.abs(L))
        idx = np.nonzero((lm[:-1] >= 0) != (lm[1:] >= 0))[0]
        t = lm[idx] / (lm[idx] - lm[idx + 1])
        ph = np.unwrap(np.angle(L))
        pm = 180 - np.remainder(180 - (180 + np.degrees(ph[idx] + t * (ph[idx + 1] - ph[idx]))),
                                360)
        out[i] = pm[np.argmin(np.abs(pm))] if pm.size else np.inf
    return out


def random_designs(n: int, seed: int = 1):
    """A reproducible batch of UT-SEA designs with delays and filters."""
    from seactl.systems.sea.actuators import UT_SEA
    from seactl.systems.sea.design import critically_damped_gains
    from seactl.systems.sea.loops import SEADesign, Timing

    rng = np.random.default_rng(seed)
    fn = rng.uniform(10.0, 40.0, n)
    timing = Timing.from_ms(rng.uniform(0.5, 1.0, n), rng.uniform(0.0, 20.0, n),
                            rng.uniform(0.5, 3.0, n), 50.0, 100.0)
    return fn, SEADesign(UT_SEA, critically_damped_gains(UT_SEA, fn), timing)


@benchmark("margins")
def bench_margins(repeat: int) -> BenchResult:
    import control

    from seactl.base.parallel import one_thread
    from seactl.certify.vecmath import vector_functions
    from seactl.diagram.blockdiagram import DesignSubset
    from seactl.systems.sea.loops import outer_loop
    from seactl.systems.sea.views import sea_margins

    fn, d = random_designs(10_000)
    sea_margins(d)  # compile once (symbolic derivation is cached)
    with one_thread():  # the rate per core
        t_ours = median_time(lambda: sea_margins(d), repeat)
    t_all = median_time(lambda: sea_margins(d), repeat)  # one thread per core
    m = sea_margins(d)

    loop = outer_loop()
    n_base = 20
    w = 2 * np.pi * np.logspace(-1, 3, 2000)
    frds = [control.FRD(loop(DesignSubset(d, np.array([i]), d.shape), 1j * w)[0], w)
            for i in range(n_base)]

    def baseline():
        return [control.stability_margins(f)[1] for f in frds]

    t_base = median_time(baseline, max(1, repeat // 2), warmup=0)
    pm_pc = np.array(baseline())
    ref = _dense_reference_pm(loop, DesignSubset(d, np.arange(n_base), d.shape),
                              fn[:n_base])
    err_ours = float(np.max(np.abs(m.phase_margin_deg[:n_base] - ref)))
    err_pc = float(np.max(np.abs(pm_pc - ref)))
    return BenchResult(
        "margins", d.shape[0] / t_ours, "python-control stability_margins, 2000-pt FRD",
        n_base / t_base, err_ours,
        note=f"10,000 designs with delays (T_qs 0-20 ms) and 50/100 Hz filters, one core "
             f"(one thread per core, as the library runs by default: "
             f"{d.shape[0] / t_all:.3g} designs/s on {os.cpu_count()} cores); "
             f"baseline timed on {n_base} designs. Max |PM error| vs a 200,000-point reference "
             f"grid: seactl {err_ours:.2g} deg, python-control {err_pc:.2g} deg; from "
             f"libmvec (AVX2): {', '.join(vector_functions()) or 'none'}",
        max_error_text=f"{err_ours:.2g} deg (python-control {err_pc:.2g})")


@benchmark("cli-startup")
def bench_cli_startup(repeat: int) -> BenchResult:
    """``seactl --help`` in a fresh interpreter against ``import control`` (python-control)
    in a fresh interpreter: what a user pays before anything is computed."""
    import subprocess
    import sys

    def start(code: str) -> Callable[[], Any]:
        return lambda: subprocess.run([sys.executable, "-c", code], check=True,
                                      capture_output=True)

    t_ours = median_time(start("from seactl.apps.cli import main; main(['--help'])"), repeat)
    t_base = median_time(start("import control"), repeat)
    return BenchResult("cli-startup", 1.0 / t_ours, "python -c 'import control'", 1.0 / t_base,
                       0.0, note=f"seactl --help: {t_ours * 1e3:.0f} ms (target < 300 ms)",
                       max_error_text="n/a (start-up time)")
