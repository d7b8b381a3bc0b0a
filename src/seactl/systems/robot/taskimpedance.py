"""A robot's impedance at its joints and at its task frame, and its certified passivity.

The joint impedance ``Z_q(s)`` (``n x n``, N m s/rad) is the torque the springs return to a
motion imposed on every joint, references fixed: ``Z_q[j, k] = tau_k.j / (-s q_j.k)``
(:meth:`seactl.api.robot.Robot.impedance_matrix`), the links' own inertia excluded as in
the SEA's impedance.  At the task frame, with the translational Jacobian ``J`` (``3 x n``)
and its singular value decomposition ``J = U S V^T`` of rank ``r``, the hand's admittance
``J Z_q^-1 J^T`` restricted to the span ``U_r`` of the directions the joints move is
invertible; its inverse is the task impedance ``Z_x = (U_r^T J Z_q^-1 J^T U_r)^-1``
(``r x r``, N s/m) in the basis ``U_r`` (docs/theory/robot.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np

RANK_RTOL = 1e-9
"""Singular values of ``J`` below this times the largest are taken as 0 (a singular
configuration loses those directions)."""


def joint_forms(diagram: Any, n: int) -> tuple[list[list[Any]], Any]:
    """``(N, D)`` forms with ``Z_q[j, k] = N[j][k] / (-s D)`` (every ``q_j`` cut: one
    denominator for all entries)."""
    cut = tuple(f"q_j.j{k + 1}" for k in range(n))
    N, D = [], None
    for j in range(n):
        row = []
        for k in range(n):
            num, den = diagram.transfer_forms(f"tau_k.j{j + 1}", f"q_j.j{k + 1}", cut)
            if D is not None and _terms(den) != _terms(D):  # pragma: no cover
                raise RuntimeError("the joint impedance's entries differ in denominator")
            D = den
            row.append(num)
        N.append(row)
    return N, D


def _terms(form: Any) -> dict:
    return {blocks: c for c, blocks in form.terms}


def task_basis(jacobian: np.ndarray) -> np.ndarray:
    """``U_r``: an orthonormal basis (``3 x r``) of the translations the joints make."""
    U, S, _ = np.linalg.svd(np.asarray(jacobian, float)[:3])
    r = int(np.sum(S > RANK_RTOL * max(float(S[0]) if S.size else 0.0, 1e-300)))
    return U[:, :r]


def task_impedance_matrix(z_q: np.ndarray, jacobian: np.ndarray, basis: np.ndarray
                          ) -> np.ndarray:
    """``Z_x = (U_r^T J Z_q^-1 J^T U_r)^-1`` per frequency: ``(F, r, r)``."""
    Jr = basis.T @ np.asarray(jacobian, float)[:3]
    y = Jr @ np.linalg.solve(z_q, np.broadcast_to(Jr.T, z_q.shape[:1] + Jr.T.shape))
    return np.linalg.inv(y)


def principal(z: np.ndarray, basis: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """Singular values ``(F, r)`` (largest first) and the matching right singular vectors
    as columns ``(F, m, r)``: the velocity directions that meet each principal impedance,
    mapped to task coordinates by ``basis`` (``m x r``) if given."""
    _, s, vh = np.linalg.svd(z)
    v = np.conj(np.swapaxes(vh, -1, -2))
    return s, (v if basis is None else basis @ v)


def hermitian_min(z: np.ndarray) -> np.ndarray:
    """The smallest eigenvalue of ``(Z + Z^H) / 2`` per frequency."""
    return np.linalg.eigvalsh(0.5 * (z + np.conj(np.swapaxes(z, -1, -2))))[..., 0]


def joint_quasi(diagram: Any, design: Any, n: int) -> tuple[list[list[Any]], Any]:
    """The quasi-polynomials ``(N, D)`` of :func:`joint_forms` for one design."""
    from seactl.diagram.blockdiagram import evaluate_forms

    forms, dform = joint_forms(diagram, n)
    D = evaluate_forms((dform,), design)[0]
    return [[evaluate_forms((f,), design)[0] for f in row] for row in forms], D


def joint_impedance(N: list[list[Any]], D: Any, f_hz: np.ndarray) -> np.ndarray:
    """``Z_q = N / (-s D)`` at ``s = j 2 pi f``: ``(F, n, n)``."""
    s = (2j * np.pi * np.asarray(f_hz, float)).reshape(1, -1)
    d = -s * D(s)
    return np.stack([np.stack([q(s) / d for q in row], -1) for row in N], -2)[0]


def certify_passive(N: list[list[Any]], D: Any, f_range_hz: tuple[float, float],
                    every: int = 16, points_per_decade: int = 400) -> Any:
    """:func:`seactl.certify.hermitian.certify_hermitian` of the joint impedance
    (:func:`joint_quasi`) on ``f_range_hz``, from base points every ``every`` of a grid of
    ``points_per_decade``."""
    from seactl.certify.hermitian import certify_hermitian

    lo, hi = f_range_hz
    npts = max(2, int(np.ceil(np.log10(hi / lo) * points_per_decade / every)) + 1)
    return certify_hermitian(N, D, 2 * np.pi * np.logspace(np.log10(lo), np.log10(hi), npts))
