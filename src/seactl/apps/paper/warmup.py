"""The report's kernels compiled side by side: :data:`WARMUPS` for
:func:`seactl.apps.report.build`.

On a cold kernel cache, report workers that start their sections at once would each compile
the same kernels (the margin scan first of all); instead each warm-up below compiles its own
share of the kernel groups (:mod:`seactl.base.jit`) in its own worker.  The margin scan's
main kernel is by far the longest to compile, so the first warm-up compiles it alone (with
the argument types :func:`seactl.analysis.margins.certified_margins` gives it,
:data:`MARGIN_SIGNATURES`), while the second compiles the scan's other entry points and the
simulation kernels, then runs the mobile base's section, which needs no margin kernel.  A
kernel a warm-up misses is compiled by the first section that needs it, as without
warm-ups.
"""

from __future__ import annotations

from typing import Any

from seactl.apps.report import KernelWarmup

_TIMING = {"delays_ms": {"torque": 0.5, "stiffness": 2.0, "damping": 0.5},
           "filters_hz": (50.0, 100.0)}


def margin_signatures() -> dict[str, tuple[Any, ...]]:
    """The argument types of the margin scan's entry points (:mod:`seactl.certify.scan`)
    as the certified margins call them: C-ordered float64 arrays (coefficients 3-D,
    delays 2-D), int64 indices and counts."""
    from numba import types as t

    a3, a2, a1 = t.float64[:, :, ::1], t.float64[:, ::1], t.float64[::1]
    i1, b1 = t.int64[::1], t.boolean[::1]
    return {"scan": (a3, a2, a3, a2, a3, a1, t.int64, a1, a1, t.boolean, b1, a2, a1, b1, a2,
                     t.int64, t.int64),
            "derivatives": (a3, a2, i1, a1),
            "loop_values": (a3, a2, a3, a2, i1, a1),
            "delta_values": (a3, a2, a3, a2, a1),
            "refine": (a3, a2, a3, a2, a2, t.float64, t.float64, a1)}


def _compile(names: tuple[str, ...]) -> None:
    """Compile the scan's entry points ``names`` for :func:`margin_signatures` (a kernel
    whose arguments have changed is left to its first use)."""
    from numba.core.errors import NumbaError

    from seactl.certify import scan

    sigs = margin_signatures()
    for name in names:
        try:
            getattr(scan, name).compile(sigs[name])
        except (NumbaError, TypeError):
            pass


def margin_kernels() -> None:
    """The certified scan's main kernel, then what margins and jitter margins still need
    (the jitter peak's supremum, the derivative bound)."""
    from seactl.api.sea import design

    _compile(("scan",))
    d = design([12.0, 14.0], **_TIMING)
    d.margins()
    d.jitter_margins()


def simulation_kernels() -> None:
    """The scan's other entry points, the continuous simulation, its step metrics, and the
    mobile base's simulation."""
    from seactl.api.mobile_base import mobile_base_params
    from seactl.api.sea import design
    from seactl.systems.mobile_base.simulation import simulate

    _compile(("derivatives", "loop_values", "delta_values", "refine"))
    design([12.0, 14.0], **_TIMING).step(t_end_s=0.05, amplitude=1.0)
    simulate(mobile_base_params(), [100.0, 200.0], [10.0, 20.0], [0.5, 1.0], duration=0.05)


WARMUPS: tuple[KernelWarmup, ...] = (
    KernelWarmup(("margin", "derivative bound", "jitter peak"),
                 ("seactl.certify.scan", "seactl.diagram.majorants", "seactl.certify.supremum"),
                 margin_kernels),
    KernelWarmup(("margin", "simulation", "matrix balancing", "step metrics", "mobile base"),
                 ("seactl.certify.scan", "seactl.simulate.continuous", "seactl.simulate.network",
                  "seactl.simulate.metrics", "seactl.systems.mobile_base.simulation"),
                 simulation_kernels, sections=("mobile-base",)),
)
"""The kernels in two shares of about equal compile time, each compiled in one worker."""
