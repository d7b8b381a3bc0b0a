"""The largest task stiffness a robot's certified verdict allows, and the check of the
assumption behind it: :func:`search_task_stiffness`, :func:`search_stiffness`.

The search scales the task stiffness ``K_x`` (and ``k_r`` with it) by a factor ``f``.  A
coarse scan at ``f = 10^k`` over the whole span first records the verdict at each decade;
every change of verdict between neighbours is then narrowed by geometric bisection.  The
largest stiffness is the top of the highest stable stretch.  The usual picture (stable
below one stiffness, unstable above) is *assumed* by a plain bisection; here it is checked:
:attr:`StiffnessSearch.single_flip` is False when the scan sees anything else (a second
change, or unstable below and stable above), and :attr:`StiffnessSearch.intervals_n_per_m`
lists every stable stretch.  Changes of verdict closer together than a decade can hide
between two scan points.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

STIFFNESS_RTOL = 1e-3
"""The relative width of the last bracket of each change of verdict."""
SCAN_PER_DECADE = 1
"""Scan points per decade of the scale factor."""


@dataclass(frozen=True)
class StiffnessSearch:
    """Where the certified verdict is stable along the task stiffness ``k_x``.

    Attributes
    ----------
    kx_max_n_per_m : float
        The top of the highest stable stretch [N/m]; ``inf`` if stable at the top of the
        span, 0 if unstable everywhere scanned.
    intervals_n_per_m : tuple of (float, float)
        Every stable stretch ``(low, high)`` [N/m], low to high; ``low`` 0 if stable at
        the bottom of the span, ``high`` inf if stable at its top.
    single_flip : bool
        The scan saw stable below one ``k_x`` and unstable above it (or one verdict
        throughout): the assumption of a plain bisection holds.
    evaluations : int
        Certified verdicts computed.
    """

    kx_max_n_per_m: float
    intervals_n_per_m: tuple
    single_flip: bool
    evaluations: int


def scaled_task_stiffness(r: Any, factor: float) -> Any:
    """The robot with its task stiffness ``K_x`` times ``factor`` (``J^T K_x J`` is linear
    in ``K_x``)."""
    kx, kr = r.task_stiffness
    return replace(r, stiffness=r.stiffness * factor, task_stiffness=(kx * factor, kr * factor))


def scan_factors(span: float) -> np.ndarray:
    """The scan's scale factors: ``10^k`` per :data:`SCAN_PER_DECADE`, covering
    ``[1 / span, span]``."""
    k = math.ceil(math.log10(span) * SCAN_PER_DECADE - 1e-9)
    return 10.0 ** (np.arange(-k, k + 1) / SCAN_PER_DECADE)


def search_stiffness(stable: Callable[[float], bool], span: float = 1e6,
                     rtol: float = STIFFNESS_RTOL) -> tuple[float, tuple, bool]:
    """Scan and bisect a verdict ``stable(f)`` of a scale factor ``f`` (the logic of
    :func:`search_task_stiffness`, on any predicate).

    Parameters
    ----------
    stable : callable
        ``f -> bool``.
    span : float
        The scan covers ``[1 / span, span]``.
    rtol : float
        Relative width of the last bracket of each change.

    Returns
    -------
    (float, tuple, bool)
        The top factor of the highest stable stretch (``inf``: stable at the top; 0: none),
        the stable stretches as factor pairs (``0`` / ``inf`` at open ends), and whether the
        verdict flips at most once, from stable to unstable.
    """
    factors = scan_factors(span)
    verdict = [bool(stable(float(f))) for f in factors]
    changes = [i for i in range(len(factors) - 1) if verdict[i] != verdict[i + 1]]
    edges = [_bisect(stable, float(factors[i]), float(factors[i + 1]), verdict[i], rtol)
             for i in changes]
    stretches, start = [], 0.0 if verdict[0] else math.nan
    for i, edge in zip(changes, edges):
        if verdict[i]:
            stretches.append((start, edge))
        else:
            start = edge
    if verdict[-1]:
        stretches.append((start, math.inf))
    top = stretches[-1][1] if stretches else 0.0
    single = not changes or (len(changes) == 1 and verdict[0])
    return top, tuple(stretches), single


def _bisect(stable: Callable[[float], bool], lo: float, hi: float, lo_stable: bool,
            rtol: float) -> float:
    """The stable end of ``[lo, hi]`` (where the verdict differs, ``lo_stable`` at ``lo``)
    narrowed by geometric bisection to ``hi / lo <= 1 + rtol``."""
    while hi / lo > 1.0 + rtol:
        mid = math.sqrt(lo * hi)
        if bool(stable(mid)) == lo_stable:
            lo = mid
        else:
            hi = mid
    return lo if lo_stable else hi


def search_task_stiffness(r: Any, rtol: float = STIFFNESS_RTOL, span: float = 1e6
                          ) -> StiffnessSearch:
    """Where the robot's certified verdict (``margins().stable``) is stable along its
    translational task stiffness ``k_x``, ``k_r / k_x`` kept as in ``r``.

    Parameters
    ----------
    r : seactl.api.robot.Robot
        A task-space robot.
    rtol : float
        Relative tolerance of each change of verdict.
    span : float
        The scan covers ``[k_x / span, k_x span]``.

    Returns
    -------
    StiffnessSearch
        The largest stable ``k_x``, every stable stretch, and whether the verdict flips
        once (see the module's docstring).
    """
    count = [0]

    def stable(f: float) -> bool:
        count[0] += 1
        return bool(scaled_task_stiffness(r, f).margins().stable)

    kx = float(r.task_stiffness[0])
    top, stretches, single = search_stiffness(stable, span, rtol)
    return StiffnessSearch(top * kx, tuple((a * kx, b * kx) for a, b in stretches), single,
                           count[0])
