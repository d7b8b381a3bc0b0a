"""Each block as a batched state space: continuous canonical form and Tustin."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import Block


# ----------------------------------------------------------------------------- realization
def _coeff_matrix(coeffs: Sequence[Any], shape: tuple[int, ...], n: int) -> np.ndarray:
    return np.stack([np.broadcast_to(np.asarray(c, float), shape).reshape(n) for c in coeffs],
                    axis=1)


def _strip_leading(num: np.ndarray, den: np.ndarray, block: Block) -> tuple[np.ndarray, ...]:
    """Drop leading numerator columns that are zero for every design; check properness."""
    while num.shape[1] > den.shape[1] and np.all(num[:, 0] == 0):
        num = num[:, 1:]
    if num.shape[1] > den.shape[1] + 1:
        raise ValueError(f"block {block.name!r}: numerator degree exceeds the denominator's by "
                         "more than one; not realizable")
    return num, den


def _ccf(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, ...]:
    """Controllable canonical form of batched ``num/den`` (same length, den[:, 0] != 0)."""
    n, q1 = den.shape
    q = q1 - 1
    a = den[:, 1:] / den[:, :1]
    b = num / den[:, :1]
    D = b[:, 0]
    A = np.zeros((n, q, q))
    if q:
        A[:, 0, :] = -a
        A[:, np.arange(1, q), np.arange(q - 1)] = 1.0
    B = np.zeros((n, q))
    if q:
        B[:, 0] = 1.0
    C = b[:, 1:] - b[:, :1] * a
    return A, B, C, D


def realize_continuous(block: Block, design: Any, shape: tuple[int, ...], n: int,
                       derivative_tau_s: float = 1e-7) -> tuple[np.ndarray, ...]:
    """Batched state space ``(A, B, C, D)`` of the block's rational part (no delay).

    A vanishing leading denominator coefficient (an unfiltered derivative) is replaced
    by ``derivative_tau_s`` times the next coefficient (a far roll-off)."""
    num_c, den_c = block.coefficients(design)
    num, den = _coeff_matrix(num_c, shape, n), _coeff_matrix(den_c, shape, n)
    num, den = _strip_leading(num, den, block)
    if den.shape[1] > 1:
        zero = den[:, 0] == 0
        if zero.any():
            den = den.copy()
            den[:, 0] = np.where(zero, derivative_tau_s * np.abs(den[:, 1]), den[:, 0])
    if np.any(den[:, 0] == 0):
        raise ValueError(f"block {block.name!r}: denominator vanishes")
    if num.shape[1] > den.shape[1]:
        raise ValueError(f"block {block.name!r} is improper for some designs")
    num = np.concatenate([np.zeros((n, den.shape[1] - num.shape[1])), num], axis=1)
    return _ccf(num, den)


def _tustin_basis(q: int) -> np.ndarray:
    """Rows j = 0..q: coefficients of ``(z-1)^j (z+1)^(q-j)`` (highest power first)."""
    rows = []
    for j in range(q + 1):
        p = np.array([1.0])
        for _ in range(j):
            p = np.polymul(p, [1.0, -1.0])
        for _ in range(q - j):
            p = np.polymul(p, [1.0, 1.0])
        rows.append(p)
    return np.array(rows)


def realize_tustin(block: Block, design: Any, shape: tuple[int, ...], n: int,
                   period_s: float) -> tuple[np.ndarray, ...]:
    """Batched discrete state space of the block's rational part, bilinear transform
    ``s = (2/T)(z-1)/(z+1)`` at period ``T`` (proper even for an unfiltered derivative)."""
    num_c, den_c = block.coefficients(design)
    num, den = _coeff_matrix(num_c, shape, n), _coeff_matrix(den_c, shape, n)
    num, den = _strip_leading(num, den, block)
    q = max(num.shape[1], den.shape[1]) - 1
    pad = lambda c: np.concatenate([np.zeros((n, q + 1 - c.shape[1])), c], axis=1)  # noqa: E731
    num, den = pad(num), pad(den)
    # c(s) = sum_k c[q-j] s^j  ->  (z+1)^q c = sum_j c[q-j] (2/T)^j (z-1)^j (z+1)^(q-j)
    w = (2.0 / period_s) ** np.arange(q + 1)
    basis = _tustin_basis(q)
    num_z = (num[:, ::-1] * w) @ basis
    den_z = (den[:, ::-1] * w) @ basis
    if np.any(den_z[:, 0] == 0):
        raise ValueError(f"block {block.name!r}: Tustin denominator vanishes")
    return _ccf(num_z, den_z)
