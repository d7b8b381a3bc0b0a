"""Certified sign of the Hermitian part of a matrix impedance on a frequency interval.

``Z(jw) = N(jw) / (-jw D(jw))`` is an ``n x n`` matrix of quasi-polynomials ``N_jk`` over
one denominator ``D``.  For ``w > 0`` and ``D(jw) != 0`` the Hermitian matrix
``P(w) = w |D|^2 (Z + Z^H) / 2 = (G + G^H) / 2`` with ``G = j N conj(D)`` has the
eigenvalue signs of ``(Z + Z^H) / 2`` (a positive multiple), and ``G`` is entire in ``w``.

An interval ``[a, b]`` is certified positive definite when
``(lam(a) + lam(b) - h L) / 2 > err``, ``lam`` the smallest eigenvalue of ``P``,
``h = b - a`` and ``L`` a bound of ``||P'||_2`` on the interval: by Weyl's inequality
``lam(w) >= lam(a) - (w - a) L`` and ``lam(w) >= lam(b) - (b - w) L``, whose larger one is
at least their mean.  ``||P'||_2 <= ||G'||_F`` and ``|G'_jk| <= |N'_jk| |D| + |N_jk| |D'|``;
each factor's sup on the interval comes from its values at the ends and the sup of its
derivative (``sup |g| <= (|g(a)| + |g(b)| + h sup |g'|) / 2``), down to the third
derivative's bound :attr:`~seactl.diagram.blockdiagram.QuasiPolynomial.bound3_coeffs`
(increasing in ``w``: taken at ``b``).  ``err`` bounds the evaluation's rounding
(:func:`~seactl.diagram.blockdiagram.rounding_majorant`) and the eigenvalue solver's.
Intervals not certified are halved, breadth first; a point with
``lam < -tol ||P||_F`` proves the matrix is not positive semidefinite there.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.certify.scan import compact, derivatives
from seactl.diagram.blockdiagram import EVAL_ROUNDING, QuasiPolynomial, rounding_majorant

MAX_DEPTH = 40
"""Halvings of a base interval before it is left unproven (the matrix touching
singular)."""
MAX_OPEN = 4096
"""Uncertified intervals in one round of halving: more and the verdict is left unproven."""


@dataclass(frozen=True)
class HermitianCertificate:
    """The outcome of :func:`certify_hermitian`.

    Attributes
    ----------
    positive : bool
        ``(Z + Z^H) / 2`` is proven positive definite on the whole range.
    proven : bool
        The verdict is proven: positive by the certificate, or not by a point found with a
        negative eigenvalue.
    negative_w : float
        A frequency [rad/s] with a negative eigenvalue (NaN if none was found).
    evaluations : int
        Points evaluated (grid and halvings).
    """

    positive: bool
    proven: bool
    negative_w: float
    evaluations: int


class _Matrix:
    """``N`` (``n x n`` flat quasi-polynomials, one design each) and ``D``, evaluated with
    the sups the certificate needs."""

    def __init__(self, N: list[list[QuasiPolynomial]], D: QuasiPolynomial):
        self.n = len(N)
        self.qs = [q.flat() for row in N for q in row] + [D.flat()]
        self.arrays = [compact(q) for q in self.qs]
        self.b3 = [_row(q.bound3_coeffs) for q in self.qs]
        self.major = [_row(rounding_majorant(q.abs_coeffs, q.delays.max(axis=0)))
                      for q in self.qs]
        # (the rounding of a derivative: each term's own, times at most degree / w + tau)
        self.dmajor = [(q.coeffs.shape[-1], float(np.max(q.delays))) for q in self.qs]

    def point(self, w: np.ndarray) -> dict[str, np.ndarray]:
        """Per point: ``v`` (each entry of ``N`` then ``D`` with its first and second
        derivatives in ``w``), ``P``, ``P'``, ``lam`` and the rounding bounds of ``P``
        and ``P'`` (spectral norm)."""
        n, w = self.n, np.ascontiguousarray(w, float)
        idx = np.zeros(w.size, np.intp)
        v = np.stack([derivatives(*a, idx, w) for a in self.arrays], axis=1)
        N, D = v[:, :-1].reshape(-1, n, n, 3), v[:, -1]
        Dc = D.conj()[:, None, None]
        P = _herm(1j * N[..., 0] * Dc[..., 0])
        P1 = _herm(1j * (N[..., 1] * Dc[..., 0] + N[..., 0] * Dc[..., 1]))
        mN = np.stack([np.polynomial.polynomial.polyval(w, m) for m in self.major[:-1]], 1)
        mD = np.polynomial.polynomial.polyval(w, self.major[-1])
        eps = 64 * n * np.finfo(float).eps
        err = 3 * EVAL_ROUNDING * np.sqrt(((mN * mD[:, None]) ** 2).sum(axis=1)) \
            + eps * _fro(P)
        grow = np.array([k / w + tau for k, tau in self.dmajor]).T  # (points, entries)
        err1 = 3 * EVAL_ROUNDING * np.sqrt(((mN * mD[:, None] * (grow[:, :-1] + grow[:, -1:]))
                                            ** 2).sum(axis=1)) + eps * _fro(P1)
        return dict(w=w, v=v, P=P, P1=P1, lam=np.linalg.eigvalsh(P)[:, 0], err=err,
                    err1=err1, scale=_fro(N[..., 0]) * np.abs(D[:, 0]))

    def sups(self, va: np.ndarray, vb: np.ndarray, wb: np.ndarray, h: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of ``||P'||_2`` and ``||P''||_2`` on each interval."""
        b3 = np.stack([np.polynomial.polynomial.polyval(wb, c) for c in self.b3], 1)
        s2 = 0.5 * (np.abs(va[..., 2]) + np.abs(vb[..., 2]) + h[:, None] * b3)
        s1 = 0.5 * (np.abs(va[..., 1]) + np.abs(vb[..., 1]) + h[:, None] * s2)
        s0 = 0.5 * (np.abs(va[..., 0]) + np.abs(vb[..., 0]) + h[:, None] * s1)
        g1 = s1[:, :-1] * s0[:, -1:] + s0[:, :-1] * s1[:, -1:]
        g2 = s2[:, :-1] * s0[:, -1:] + 2 * s1[:, :-1] * s1[:, -1:] + s0[:, :-1] * s2[:, -1:]
        return np.sqrt((g1 ** 2).sum(axis=1)), np.sqrt((g2 ** 2).sum(axis=1))

    def lower(self, a: dict[str, np.ndarray], b: dict[str, np.ndarray]
              ) -> tuple[np.ndarray, np.ndarray]:
        """A lower bound of ``lam`` on each interval ``[a, b]`` and its rounding bound: the
        best of the first-order bound and the second-order ones from either end."""
        h = b["w"] - a["w"]
        S1, S2 = self.sups(a["v"], b["v"], b["w"], h)
        first = 0.5 * (a["lam"] + b["lam"] - h * S1)
        ext_a = np.linalg.eigvalsh(a["P"] + h[:, None, None] * a["P1"])[:, 0]
        ext_b = np.linalg.eigvalsh(b["P"] - h[:, None, None] * b["P1"])[:, 0]
        # (lam of P + t P' is concave in t: its minimum on [0, h] is at an end)
        second = np.maximum(np.minimum(a["lam"], ext_a), np.minimum(b["lam"], ext_b)) \
            - 0.5 * h * h * S2
        err = np.maximum(a["err"] + h * a["err1"], b["err"] + h * b["err1"])
        return np.maximum(first, second), err


def certify_hermitian(N: list[list[QuasiPolynomial]], D: QuasiPolynomial,
                      w_grid: np.ndarray, tol: float = 1e-9) -> HermitianCertificate:
    """Whether ``(Z + Z^H) / 2`` is positive definite on ``[w_grid[0], w_grid[-1]]``
    [rad/s] (``w_grid[0] > 0``), ``Z = N / (-jw D)`` (one design).

    Parameters
    ----------
    N : list of list of QuasiPolynomial
        ``n x n`` numerators (each of one design).
    D : QuasiPolynomial
        Their common denominator.
    w_grid : numpy.ndarray
        Increasing base points [rad/s].
    tol : float
        A point is negative where ``lam < -tol ||N||_F |D|``.

    Returns
    -------
    HermitianCertificate
        ``positive``, ``proven``, ``negative_w``, ``evaluations``.
    """
    m = _Matrix(N, D)
    pts = m.point(np.asarray(w_grid, float))
    count = pts["w"].size
    a, b = _take(pts, slice(0, -1)), _take(pts, slice(1, None))
    for depth in range(MAX_DEPTH + 1):
        neg = np.r_[a["lam"] < -tol * a["scale"], b["lam"] < -tol * b["scale"]]
        if neg.any():
            return HermitianCertificate(False, True, float(np.r_[a["w"], b["w"]][neg][0]),
                                        count)
        low, err = m.lower(a, b)
        todo = ~((a["lam"] > a["err"]) & (b["lam"] > b["err"]) & (low > err))
        if not todo.any():
            return HermitianCertificate(True, True, float("nan"), count)
        if depth == MAX_DEPTH or todo.sum() > MAX_OPEN:
            return HermitianCertificate(False, False, float("nan"), count)
        a, b = _take(a, todo), _take(b, todo)
        mid = m.point(0.5 * (a["w"] + b["w"]))
        count += mid["w"].size
        a, b = _join(a, mid), _join(mid, b)
    return HermitianCertificate(False, False, float("nan"), count)  # pragma: no cover


def _take(p: dict[str, np.ndarray], idx: Any) -> dict[str, np.ndarray]:
    return {k: x[idx] for k, x in p.items()}


def _join(p: dict[str, np.ndarray], q: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: np.concatenate([p[k], q[k]]) for k in p}


def _herm(G: np.ndarray) -> np.ndarray:
    return 0.5 * (G + np.conj(np.swapaxes(G, -1, -2)))


def _fro(X: np.ndarray) -> np.ndarray:
    return np.sqrt((np.abs(X) ** 2).sum(axis=(-1, -2)))


def _row(c: np.ndarray) -> np.ndarray:
    """The coefficients of the one design of a flat batch."""
    return np.asarray(c, float).reshape(-1, np.shape(c)[-1])[0]
