"""Robot benchmark: the certified margins of every loop break of the planar 2-link arm
(``Robot.margins_by_break``: the loop's characteristic terms evaluated once for all its
breaks) against the same certified scan of each break with its terms evaluated on its own,
at configurations along the arm's elbow."""

from __future__ import annotations

from importlib.util import find_spec
from pathlib import Path

import numpy as np

from ._harness import BenchResult, benchmark, median_time

ELBOW_RAD = (0.6, 2.2)   # the elbow angles of the configurations
N_CONFIGURATIONS = 6
KEYS = ("phase_margin_deg", "crossover_hz", "gain_margin", "delay_margin_ms")


def _arm() -> Path:
    """The planar 2-link arm of the repository's examples."""
    import seactl

    return Path(seactl.__file__).resolve().parents[2] / "examples" / "robots" / \
        "planar_2link.urdf"


def _robots() -> list:
    """The arm in task space at each configuration (Table I's delays and filters)."""
    import seactl as sc

    urdf = _arm()
    return [sc.robot(urdf, q0=[0.3, float(e)], fn_hz=14, space="task", task="tool",
                     delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                     filters_hz=(50, 100))
            for e in np.linspace(*ELBOW_RAD, N_CONFIGURATIONS)]


def _alone(r) -> dict:
    """Every break's certified margins, its characteristic terms evaluated on their own."""
    from seactl.analysis.margins import default_grid, loop_margins

    grid, design = default_grid(r.reference_frequency()), r.design
    return {name: loop_margins(r.diagram.loop(signal), design, grid)
            for name, signal in r.breaks.items()}


def _largest_difference(ours: list[dict], theirs: list[dict]) -> float:
    """Largest relative difference of the finite margins (dimensionless)."""
    err = 0.0
    for a, b in zip(ours, theirs):
        for name in a:
            for key in KEYS:
                x, y = float(getattr(a[name], key)), float(getattr(b[name], key))
                if np.isfinite(x) and np.isfinite(y) and y != 0:
                    err = max(err, abs(x - y) / abs(y))
                elif not (x == y or (np.isnan(x) and np.isnan(y))):
                    err = float("inf")
    return err


@benchmark("robot-breaks")
def bench_robot_breaks(repeat: int) -> BenchResult:
    if find_spec("pinocchio") is None or not _arm().is_file():
        return BenchResult("robot-breaks", float("nan"), "each break's terms on their own",
                           float("nan"), float("nan"),
                           note="skipped: it needs pinocchio (pip install -e \".[robots]\")"
                                " and the repository's examples/robots")
    _robots()[0].margins_by_break()   # (the loop's derivation, once per process)
    n_breaks = N_CONFIGURATIONS * len(_robots()[0].breaks)
    t_ours = median_time(lambda: [r.margins_by_break() for r in _robots()], repeat)
    t_base = median_time(lambda: [_alone(r) for r in _robots()], repeat)
    err = _largest_difference([r.margins_by_break() for r in _robots()],
                              [_alone(r) for r in _robots()])
    return BenchResult(
        "robot-breaks", n_breaks / t_ours,
        "the same certified scan per break, its terms evaluated on their own",
        n_breaks / t_base, err,
        note=f"planar 2-link arm in task space, {N_CONFIGURATIONS} configurations (elbow "
             f"{ELBOW_RAD[0]:g} to {ELBOW_RAD[1]:g} rad), {n_breaks} loop breaks in "
             f"{t_ours:.3f} s (median of {repeat}, the robots built in each run on both "
             "sides); max error = largest relative difference of PM, crossover, GM and "
             "delay margin. Throughput in loop breaks/s.")
