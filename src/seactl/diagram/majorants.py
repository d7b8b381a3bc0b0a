"""Compiled coefficients of the third-derivative majorant of quasi-polynomials
(:attr:`seactl.diagram.blockdiagram.QuasiPolynomial.bound3_coeffs`).

In numpy the majorant takes some twenty passes over ``(terms, designs, powers)`` arrays,
each a fresh temporary; one compiled pass does the same operations in the same order (numpy's
sum over terms adds them one after another from the first; ``tau**2`` is a product, and
``tau**3`` comes from numpy, whose power is not libm's to the bit), so the coefficients
are numpy's to the bit.
"""

from __future__ import annotations

import numpy as np

from seactl.base.jit import KernelGroup, njit

KERNELS = KernelGroup("derivative bound", about_s=1)
"""The group of this module's kernels (the derivative majorant)."""


@njit(cache=True, nogil=True, error_model="numpy")
def bound3(coeffs, delays, cubes):  # pragma: no cover - compiled
    """Per design (axis 1 of ``coeffs``, ascending powers last; ``delays``: terms x
    designs, ``cubes`` numpy's ``delays**3``), the coefficients (ascending powers of ``w``)
    of ``sum_kj |c_kj| |d^3/dw^3 (w^j e^{-j w tau_k})|`` majorized term by term:
    ``sum_i C(3, i) j!/(j - i)! w^(j - i) tau_k^(3 - i)``."""
    K, n, P = coeffs.shape
    out = np.empty((n, P))
    s = np.empty((4, P))  # sum_k |c_kj| tau_k^m, m = 3, 2, 1, 0
    for d in range(n):
        for j in range(P):
            for k in range(K):
                a, tau = abs(coeffs[k, d, j]), delays[k, d]
                x3, x2, x1 = a * cubes[k, d], a * (tau * tau), a * tau
                if k == 0:
                    s[0, j], s[1, j], s[2, j], s[3, j] = x3, x2, x1, a
                else:
                    s[0, j], s[1, j], s[2, j], s[3, j] = \
                        s[0, j] + x3, s[1, j] + x2, s[2, j] + x1, s[3, j] + a
        for j in range(P):
            c = s[0, j]
            if j + 1 < P:
                c = c + 3.0 * (s[1, j + 1] * (j + 1))
            if j + 2 < P:
                c = c + 3.0 * (s[2, j + 2] * (j + 2) * (j + 1))
            if j + 3 < P:
                c = c + s[3, j + 3] * (j + 3) * (j + 2) * (j + 1)
            out[d, j] = c
    return out
