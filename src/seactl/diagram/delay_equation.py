"""Characteristics of delay equations and quasi-polynomials typed in directly.

The retarded delay equation ``x'(t) = A_0 x(t) + sum_k A_k x(t - h_k)``, each delay ``h_k``
a sum of named delays ``E_k . tau``, has the characteristic
``det(s I - A_0 - sum_k A_k z^{E_k})`` with ``z_d = e^{-s tau_d}``.  It is expanded
exactly: the float entries are taken as the rationals they are, the determinant is the
characteristic polynomial in ``s`` of ``A_0 + sum_k A_k z^{E_k}`` over the polynomials in
``z`` with rational coefficients (the division-free Berkowitz algorithm of sympy's
``DomainMatrix.charpoly``), and each coefficient is rounded to a float once.  The result
is a :class:`~seactl.diagram.delayterms.DelayTerms` whose exponent rows count how many
times each delay multiplies (``tau1 + tau2``, ``2 tau1``).

Examples
--------
``x' = -x(t - tau)``: the characteristic is ``s + e^{-s tau}``:

>>> import numpy as np
>>> c, e = equation_characteristic(np.zeros((1, 1)), [np.ones((1, 1)) * -1], np.array([[1]]))
>>> c.tolist(), e.tolist()
([[0.0, 1.0], [1.0, 0.0]], [[0], [1]])
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction

import numpy as np

from seactl.base.limits import check_budget
from seactl.errors import InputError

EXPANSION_SECONDS = 6e-6
"""Estimated time [s] of the exact expansion per ``n^4`` times the number of its possible
delay terms (rounded up, for refusing a large one up front)."""

MAX_ORDER = 40
"""Largest state dimension ``n`` of a delay equation."""


def possible_terms(n: int, exponents: np.ndarray) -> int:
    """Upper bound on the number of distinct delay monomials of an ``n x n`` equation's
    characteristic: the monomials of degree at most ``n`` in the distinct term delays."""
    k = len({tuple(r) for r in np.asarray(exponents).tolist()})
    return math.comb(n + k, k)


def check_expansion(n: int, exponents: np.ndarray) -> None:
    """Refuse up front an expansion estimated to take longer than the time budget."""
    if n > MAX_ORDER:
        raise InputError("a0", f"{n} x {n}", f"a square matrix of size at most {MAX_ORDER}")
    j = possible_terms(n, exponents)
    check_budget(f"the exact expansion of the {n} x {n} characteristic determinant "
                 f"(up to {j:,} delay terms)", seconds=EXPANSION_SECONDS * n**4 * j,
                 hint="give fewer delayed terms or a smaller matrix")


def _rational(x: float):
    import sympy as sp

    f = Fraction(float(x))
    return sp.QQ(f.numerator, f.denominator)


def equation_characteristic(a0: np.ndarray, mats: Sequence[np.ndarray],
                            exponents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``det(s I - A_0 - sum_k A_k z^{E_k})`` expanded exactly.

    Parameters
    ----------
    a0 : numpy.ndarray
        ``(n, n)`` finite floats.
    mats : sequence of numpy.ndarray
        The ``A_k``, each ``(n, n)``.
    exponents : numpy.ndarray
        ``(K, D)`` non-negative integers: term ``k``'s delay is ``E_k . tau``.

    Returns
    -------
    tuple of numpy.ndarray
        ``coeffs (J, n + 1)`` (ascending powers of ``s``) and ``exponents (J, D)``: row 0
        the undelayed term, no two rows equal, no zero term kept.
    """
    import sympy as sp
    from sympy.polys.matrices import DomainMatrix

    n, d = a0.shape[0], exponents.shape[1]
    check_expansion(n, exponents)
    zs = sp.symbols(f"z1:{d + 1}") if d else (sp.Symbol("z1"),)
    ring = sp.QQ[zs]
    gens = ring.gens
    monos = [ring.one] * len(mats)
    for k, row in enumerate(exponents):
        for g, e in zip(gens, row):
            monos[k] = monos[k] * g ** int(e)
    rows = [[ring.convert(_rational(a0[i, j])) + sum(
        (ring.convert(_rational(a[i, j])) * m for a, m in zip(mats, monos) if a[i, j] != 0),
        ring.zero) for j in range(n)] for i in range(n)]
    cp = DomainMatrix(rows, (n, n), ring).charpoly()  # highest power of s first
    return _collect(cp, n, d)


def _collect(cp: Sequence, n: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficient polynomials in ``z`` (highest power of ``s`` first) -> ``(coeffs,
    exponents)``, undelayed row first."""
    table: dict[tuple[int, ...], np.ndarray] = {(0,) * d: np.zeros(n + 1)}
    for p, c in enumerate(cp):
        for mono, value in c.terms():
            key = tuple(int(e) for e in mono[:d])
            table.setdefault(key, np.zeros(n + 1))[n - p] += _float(value)
    keys = [(0,) * d] + sorted(k for k in table if any(k) and np.any(table[k] != 0))
    return (np.array([table[k] for k in keys]),
            np.array(keys, int).reshape(len(keys), d))


def _float(value) -> float:
    """A rational coefficient rounded to a float (``inf`` beyond the float range: refused
    by the caller's magnitude check)."""
    try:
        return float(Fraction(int(value.numerator), int(value.denominator)))
    except OverflowError:
        return math.inf if int(value.numerator) > 0 else -math.inf


def merge_terms(polys: Sequence[np.ndarray], exponents: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``sum_k p_k(s) z^{E_k}`` with equal exponent rows merged, zero terms dropped.

    Parameters
    ----------
    polys : sequence of numpy.ndarray
        Ascending coefficients of ``p_k``; ``p_0`` undelayed (its row of ``exponents`` is
        zero), all of length ``n + 1``.
    exponents : numpy.ndarray
        ``(K, D)`` non-negative integers.

    Returns
    -------
    tuple of numpy.ndarray
        ``coeffs (J, n + 1)`` and ``exponents (J, D)``, row 0 undelayed.
    """
    d = exponents.shape[1]
    table: dict[tuple[int, ...], np.ndarray] = {(0,) * d: np.zeros(len(polys[0]))}
    for p, row in zip(polys, exponents):
        key = tuple(int(e) for e in row)
        table[key] = table.get(key, 0) + np.asarray(p, float)
    keys = [(0,) * d] + [k for k in table if any(k) and np.any(table[k] != 0)]
    return (np.array([table[k] for k in keys]),
            np.array(keys, int).reshape(len(keys), d))
