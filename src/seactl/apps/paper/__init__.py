"""Report sections reproducing the paper, one module per topic, and :func:`reproduce`.

:data:`SECTIONS` is the report's table of contents: an explicit list, in reading order.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from seactl.apps.report import SectionFn, build
from seactl.errors import InputError

from . import (
    gain_design,
    impedance,
    jitter,
    mobile_base,
    physics,
    placement,
    robot_placement,
    running,
    simulation,
    sweep,
)
from .warmup import WARMUPS

SECTIONS: tuple[SectionFn, ...] = (
    gain_design.table_i,
    gain_design.feasibility,
    gain_design.gain_scale,
    impedance.filter_delay,
    impedance.natural_freq,
    impedance.load_inertia,
    impedance.delay_sets,
    impedance.ktau_finding,
    impedance.zregion_section,
    simulation.impedance_delay,
    simulation.gain_scale_step,
    simulation.experiment_gs,
    simulation.experiment_impulse,
    placement.rigid_step,
    placement.latency_maps,
    sweep.latency_sweep,
    sweep.robustness_mc,
    placement.placement_advisor,
    jitter.jitter_section,
    running.running,
    physics.physics_engine,
    mobile_base.mobile_base,
    robot_placement.robot_placement,
)


LONGEST: tuple[str, ...] = ("jitter", "mobile-base", "impedance-delay", "gain-scale",
                            "impedance-delay-sets", "placement-advisor", "latency-maps")
"""The longest sections, longest first: started first when the sections run in worker
processes (:func:`seactl.apps.report.build`'s ``first``)."""


def section_ids() -> list[str]:
    """The ids of :data:`SECTIONS`, in report order."""
    return [f.section_id for f in SECTIONS]


def reproduce(out: Path, only: Iterable[str] | None = None,
              jobs: int | None = None) -> list[dict[str, Any]]:
    """Build the paper's report into ``out`` (all sections, or those in ``only``) and return
    the claims as JSON dicts; ``jobs`` worker processes (default: one per core), which
    first compile the kernels side by side when they are not cached yet
    (:data:`~seactl.apps.paper.warmup.WARMUPS`).  Progress goes to
    :mod:`seactl.base.progress`."""
    sections = list(SECTIONS)
    if only:
        wanted = set(only)
        unknown = wanted - set(section_ids())
        if unknown:
            raise InputError("only", ", ".join(sorted(unknown)),
                             "one of " + ", ".join(section_ids()))
        sections = [f for f in sections if f.section_id in wanted]
    if jobs is None:
        jobs = os.cpu_count() or 1
    if not (isinstance(jobs, int) and 1 <= jobs <= 64):
        raise InputError("jobs", jobs, "an integer from 1 to 64")
    return build(Path(out), sections, jobs=jobs, warmups=WARMUPS, first=LONGEST)
