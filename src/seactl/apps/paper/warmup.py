"""The report's kernels compiled side by side: :data:`WARMUPS` for
:func:`seactl.apps.report.build`.

On a cold kernel cache, report workers that start their sections at once would each compile
the same kernels (the margin scan first of all); instead each warm-up below compiles one
disjoint set of kernel groups (:mod:`seactl.base.jit`) in its own worker, by running a small
case of the computations the sections run, with the same argument types.  A kernel a
warm-up misses is compiled by the first section that needs it, as without warm-ups.
"""

from __future__ import annotations

from seactl.apps.report import KernelWarmup

_TIMING = {"delays_ms": {"torque": 0.5, "stiffness": 2.0, "damping": 0.5},
           "filters_hz": (50.0, 100.0)}


def margin_kernels() -> None:
    """The certified scan (margins, stability) and the jitter peak's supremum."""
    from seactl.api.sea import design

    d = design([12.0, 14.0], **_TIMING)
    d.margins()
    d.jitter_margins()


def simulation_kernels() -> None:
    """The continuous simulation, its step metrics, and the mobile base's simulation."""
    from seactl.api.mobile_base import mobile_base_params
    from seactl.api.sea import design
    from seactl.systems.mobile_base.simulation import simulate

    design([12.0, 14.0], **_TIMING).step(t_end_s=0.05, amplitude=1.0)
    simulate(mobile_base_params(), [100.0, 200.0], [10.0, 20.0], [0.5, 1.0], duration=0.05)


WARMUPS: tuple[KernelWarmup, ...] = (
    KernelWarmup(("margin", "derivative bound", "jitter peak"),
                 ("seactl.certify.scan", "seactl.diagram.majorants", "seactl.certify.supremum"),
                 margin_kernels),
    KernelWarmup(("simulation", "step metrics", "mobile base"),
                 ("seactl.simulate.continuous", "seactl.simulate.metrics",
                  "seactl.systems.mobile_base.simulation"),
                 simulation_kernels),
)
"""Disjoint kernel sets, each compiled in one worker."""
