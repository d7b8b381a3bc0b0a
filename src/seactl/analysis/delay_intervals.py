"""Stability intervals in one delay: the set of delays in a range where a loop is stable.

One threshold ("the first unstable delay") misdescribes loops whose stability is not an
interval starting at zero: a loop can be unstable without delay and stable from a small
delay on, or regain stability above a first unstable range.  :func:`stability_intervals`
returns every stable interval of a scanned range: the stability verdict on a grid of
delays, then each boundary between a stable and an unstable grid point refined by
bisection (all boundaries at once) to ``tol_s``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def stability_intervals(stable_at: Callable[[np.ndarray], np.ndarray], grid_s: np.ndarray,
                        tol_s: float = 1e-7) -> list[tuple[float, float]]:
    """Stable intervals ``[(lo, hi), ...]`` [s] of the delays in ``[grid_s[0], grid_s[-1]]``.

    ``stable_at(T)`` returns the stability verdict (bool array) for an array of delays
    ``T`` [s].  An interval that reaches an end of the grid ends there (the range's end,
    not a boundary).  Stability changes between two grid points closer than the grid step
    can be missed; within one step the boundary is bisected to ``tol_s``.
    """
    grid = np.asarray(grid_s, float)
    s = np.asarray(stable_at(grid), bool)
    change = np.nonzero(s[1:] != s[:-1])[0]
    a, b = grid[change], grid[change + 1]       # a boundary lies in (a, b)
    left_stable = s[change]
    while change.size and np.max(b - a) > tol_s:
        mid = 0.5 * (a + b)
        sm = np.asarray(stable_at(mid), bool)
        same = sm == left_stable
        a, b = np.where(same, mid, a), np.where(same, b, mid)
    edges = 0.5 * (a + b)
    out, start = [], grid[0] if s[0] else None
    for e, ls in zip(edges, left_stable):
        if ls:
            out.append((float(start), float(e)))
            start = None
        else:
            start = e
    if start is not None:
        out.append((float(start), float(grid[-1])))
    return out


def interval_containing(intervals: list[tuple[float, float]], t_s: float
                        ) -> tuple[float, float] | None:
    """The stable interval that contains ``t_s``, or None (unstable there)."""
    return next(((lo, hi) for lo, hi in intervals if lo <= t_s <= hi), None)
