"""A Cauchy bound of a quasi-polynomial's roots: beyond it the leading term dominates.

Shared by the certified margin scan (:mod:`seactl.analysis.margins`) and the jitter peak's proof
(:mod:`seactl.certify.supremum`).
"""

from __future__ import annotations

import numpy as np

from seactl.certify import scan as _certify
from seactl.diagram.blockdiagram import QuasiPolynomial, columnwise


def cauchy_bound(q: QuasiPolynomial, majorant: np.ndarray | None = None,
                 lead: np.ndarray | None = None) -> np.ndarray:
    """Per design of a flat retarded quasi-polynomial, an ``R`` with
    ``|a_n| w^n > sum_{j<n} (sum_k |c_kj|) w^j`` for every ``w > R``: beyond it the
    leading term dominates every other term together, so ``Q`` has no root with
    ``Re s >= 0`` and ``|s| > R``, and ``Q(jw) / (a_n (jw)^n)`` stays in the disc
    ``|z - 1| < 1``.  Newton from Fujiwara's bound on the polynomial
    ``|a_n| x^n - sum_j c_j x^j``, whose only positive root is the tightest such ``R``.
    ``majorant`` replaces ``c_j`` by larger coefficients (e.g. ``N``'s and ``D``'s apart;
    none above ``n``), ``lead`` ``|a_n|`` by a smaller positive one."""
    n = q.degree
    rows = np.arange(n.size)
    lead = np.abs(q.coeffs[0, rows, n]) if lead is None else lead
    c = (q.abs_coeffs if majorant is None else majorant).copy()
    c[rows, n] = -lead
    j = np.arange(c.shape[-1])
    below = j[None, :] < n[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        fuji = np.where(below, (np.abs(c) / lead[:, None]) ** (1.0 / (n[:, None] - j)), 0.0)
    start = 2.0 * columnwise(np.maximum, fuji) + 1e-300
    best = _certify.cauchy_newton(np.ascontiguousarray(c), start)
    # At R itself the dominance holds only by rounding (a root with |s| = R on the axis,
    # e.g. (s^2 + 100)(s + 1), sits there): 1 % beyond it the margin is solid.
    return 1.01 * best
