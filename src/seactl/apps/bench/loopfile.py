"""Loop-file benchmark: the paper's SEA loop as a loop file vs the built-in loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._harness import BenchResult, benchmark, median_time

# The example ships with the source tree; an installed seactl builds the same loop in code.
_EXAMPLE = Path(__file__).resolve().parents[4] / "examples" / "loops" / "paper-sea.toml"


def _designs(n: int, seed: int = 1):
    """``n`` UT-SEA designs (f_n 10-40 Hz, T_qs 0-20 ms, T_tau = T_qd 0.5-1 ms, 50/100 Hz
    filters): the built-in batch and the same values as loop-file overrides."""
    from seactl.systems.sea.actuators import UT_SEA
    from seactl.systems.sea.design import critically_damped_gains
    from seactl.systems.sea.loops import SEADesign, Timing

    rng = np.random.default_rng(seed)
    fn = rng.uniform(10.0, 40.0, n)
    t_qs, t_emb = rng.uniform(0.0, 20.0, n), rng.uniform(0.5, 1.0, n)
    g = critically_damped_gains(UT_SEA, fn)
    builtin = SEADesign(UT_SEA, g, Timing.from_ms(t_emb, t_qs, t_emb, 50.0, 100.0))
    values = {"Kq": g.Kq, "Bq": g.Bq, "Ktau": g.Ktau, "Btau": g.Btau}
    return builtin, values, {"embedded": t_emb, "high-level": t_qs}


def _paper_loop():
    from seactl.api.loopbuilder import load_loop

    if not _EXAMPLE.is_file():
        raise FileNotFoundError(f"{_EXAMPLE} (run seactl bench from a source checkout)")
    return load_loop(_EXAMPLE)


@benchmark("loop-file")
def bench_loop_file(repeat: int) -> BenchResult:
    from seactl.systems.sea.views import sea_margins
    from seactl.userloop.analysis import break_margins

    builtin, values, latency = _designs(10_000)
    loop = _paper_loop().with_values(**values).with_latencies(**latency)
    omega = loop.grid()

    def ours():
        return break_margins(loop.compiled, loop.design, omega, "q_sens", ["tau_sens"])

    ours()  # first derivation (sympy, then cached)
    sea_margins(builtin)
    t_ours = median_time(ours, repeat)
    t_base = median_time(lambda: sea_margins(builtin), repeat)
    m, ref = ours(), sea_margins(builtin)
    err = float(np.nanmax(np.abs(m.phase_margin_deg - ref.phase_margin_deg)))
    same = bool(np.all(m.stable == ref.stable))
    return BenchResult(
        "loop-file", 10_000 / t_ours, "built-in SEA loop (sea_margins)", 10_000 / t_base, err,
        note="examples/loops/paper-sea.toml with 10,000 (gains, T_qs, T_tau = T_qd) value "
             "sets, outer-loop margins after the first derivation; max |PM difference| vs "
             f"the built-in loop {err:.2g} deg, stability verdicts identical: {same}",
        max_error_text=f"{err:.2g} deg")
