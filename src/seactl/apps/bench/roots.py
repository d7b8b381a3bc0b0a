"""Rightmost characteristic roots with exact delays, against python-control's poles of a
Padé model of the same loop."""

from __future__ import annotations

import numpy as np

from ._harness import BenchResult, benchmark, median_time


@benchmark("roots")
def bench_roots(repeat: int) -> BenchResult:
    import control

    from seactl.analysis.roots import characteristic_roots
    from seactl.api.control import to_control
    from seactl.diagram.blockdiagram import DesignSubset
    from seactl.systems.sea.loops import SEA_DIAGRAM

    from .core import random_designs

    n = 400
    _fn, d = random_designs(n)
    characteristic_roots(SEA_DIAGRAM, DesignSubset(d, np.arange(2), d.shape))  # derive once
    t_ours = median_time(lambda: characteristic_roots(SEA_DIAGRAM, d, count=6), repeat,
                         warmup=0)
    r = characteristic_roots(SEA_DIAGRAM, d, count=6)

    n_base = 20
    subs = [DesignSubset(d, np.array([i]), d.shape) for i in range(n_base)]

    class _One:  # a 0-d view of one design, as the exporter expects
        def __init__(self, sub):
            self._sub = sub

        def __getattr__(self, name):
            return getattr(self._sub, name)[0]

    def baseline():
        return [control.poles(to_control(_One(s), "pade-ss", "closed", None, 3))
                for s in subs]

    t_base = median_time(baseline, max(1, repeat // 2), warmup=0)
    poles = baseline()
    err = max(float(np.min(np.abs(p - r.roots[i, 0])) / abs(r.roots[i, 0]))
              for i, p in enumerate(poles))
    return BenchResult(
        "roots", n / t_ours, "python-control poles of a Padé-3 model", n_base / t_base, err,
        note=f"{n} designs (as the margins benchmark), 6 rightmost roots each, converged "
             f"{int(r.converged.sum())}/{n}, Chebyshev size N = {int(r.nodes.min())}-"
             f"{int(r.nodes.max())}; max_error = relative distance of our rightmost root to "
             "the nearest Padé-3 pole (the Padé model's own error)",
        max_error_text=f"{err:.2g} rel (Padé-3)")
