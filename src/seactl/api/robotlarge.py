"""The views of a robot of more than three joints, from its characteristic built joint by
joint (:mod:`seactl.systems.robot.characteristic`): the delay terms and the certified
verdict (the bodies of :class:`seactl.api.robot.Robot`'s views when
``n > 3``; its MIMO margins read the verdict from here, the loop matrix is numeric).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def large_delay_terms(r: Any) -> Any:
    """``det Q`` of robot ``r`` as :class:`~seactl.diagram.delayterms.DelayTerms`, delays
    ``stiffness``, ``torque``, ``damping`` (each the same on every joint)."""
    from seactl.systems.robot.characteristic import joint_terms, robot_delay_terms

    parts = [joint_terms(f) for f in r.joint_fields()]
    size = max(p.shape[-1] for p in parts)
    terms = np.stack([np.pad(p, [(0, 0)] * 3 + [(0, size - p.shape[-1])]) for p in parts])
    return robot_delay_terms(terms, r.body.mass_matrix, r.body.damping, r.stiffness,
                             r.delays)


def large_margins(r: Any) -> Any:
    """The certified verdict of robot ``r`` as a :class:`~seactl.api.results.MarginsResult`
    whose margins are NaN (a loop break's margins need its transfer)."""
    from seactl.analysis.margins import Crossings, Margins, certified_right_roots, default_grid
    from seactl.api.results import MarginsResult

    w = default_grid(r.reference_frequency())
    q = r.delay_terms().at().flat()
    count = int(certified_right_roots(q, np.atleast_1d(np.sqrt(w[0] * w[-1])))[0])
    nan = np.asarray(np.nan)
    none = Crossings(np.empty(0, int), np.empty(0), np.empty(0))
    return MarginsResult(Margins(nan, nan, nan, nan, nan, np.asarray(count == 0),
                                 np.asarray(count), none, none), r.label_columns())
