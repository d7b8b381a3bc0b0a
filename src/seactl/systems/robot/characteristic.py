"""A robot's characteristic quasi-polynomial from each joint's own loop: :func:`joint_terms`
and :func:`robot_delay_terms`, without enumerating the whole diagram's cycles.

With joint ``j``'s motion ``q_j`` imposed, its SEA (torque and damping loops on its
embedded process) gives from the one-joint diagram a local graph determinant ``d_j`` and
numerators ``y_j``, ``h_j``: ``tau_k.j = (h_j u_j - y_j q_j) / d_j``, ``u_j`` what the
central process adds to the joint's torque command (``-sum_k K_jk e^{-s T_qs} q_k``).
With the rigid body ``(M s^2 + B s) q = tau_k + tau_ext`` the closed loop's characteristic
is ``det Q`` with

    Q = diag(d) (M s^2 + B s) + diag(y) + diag(h) K z_s,   z_s = e^{-s T_qs},

a polynomial in ``s`` and the three delay factors ``z_s``, ``z_t = e^{-s T_tau}``,
``z_d = e^{-s T_qd}`` (each of degree at most ``n``).  Its coefficient of every delay
monomial comes from the values of ``det Q`` on a grid of roots of unity in ``(z_s, z_t,
z_d)`` (a discrete Fourier transform, well conditioned), each an ``n x n`` determinant of
polynomials in ``s`` expanded exactly (minors over column subsets, no division, no
sampling of ``s``).  It is the whole diagram's quasi-polynomial times ``det M``
(docs/theory/robot.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.diagram.delayterms import DelayTerms

PROCESSES = ("stiffness", "torque", "damping")
"""The delays of :func:`robot_delay_terms`, named by process (equal across joints)."""
_ATTRS = {"T_tau_j1": 1, "T_qd_j1": 2}
"""The one-joint diagram's delay attributes -> their axis among :data:`PROCESSES`."""


def _local_design(fields: dict[str, float]) -> Any:
    """The one-joint diagram's design: the joint's SEA, a unit stiffness, no central
    delay (the stiffness enters through ``h``; the rigid body through ``Q``)."""
    from seactl.systems.robot.loops import robot_design

    return robot_design(np.ones((1, 1)), np.ones((1, 1)), [fields], 0.0)


def _grouped(form: Any, design: Any) -> np.ndarray:
    """A local form as ``(2, 2, L)`` coefficients (ascending powers of ``s``) of
    ``z_t^a z_d^b``, divided by the ``s^2`` of the rigid body's two integrators (every
    one-joint form carries their denominators)."""
    keys, coeffs = form.grouped(design)
    out = np.zeros((2, 2, coeffs.shape[-1]))
    for key, c in zip(keys, coeffs):
        idx = [0, 0]
        for a in key:
            idx[_ATTRS[a] - 1] += 1
        out[tuple(idx)] += c
    if np.any(out[..., :2] != 0.0):
        raise ArithmeticError("a joint's local form without the factor s^2")
    return out[..., 2:]


def joint_terms(fields: dict[str, float]) -> np.ndarray:
    """``(d, y, h)`` of one joint as ``(3, 2, 2, L)``: per ``z_t^a z_d^b`` the ascending
    coefficients in ``s`` (the joint's fields as :func:`~seactl.systems.robot.loops.robot_design`
    takes them)."""
    from seactl.systems.robot.loops import robot_diagram

    diagram, design = robot_diagram(1, False), _local_design(fields)
    cut = ("q_j.j1", "qs.j1", "vel.j1")
    num_y, den = diagram.transfer_forms("tau_k.j1", "q_j.j1", cut)
    num_h, den_h = diagram.transfer_forms("tau_k.j1", "q_des.j1", cut)
    d, d2 = _grouped(den, design), _grouped(den_h, design)
    if not np.allclose(d, d2, rtol=1e-12, atol=0.0):
        raise ArithmeticError("a joint's two transfers with different determinants")
    parts = [d, -_grouped(num_y, design), _grouped(num_h, design)]
    size = max(p.shape[-1] for p in parts)
    return np.stack([np.pad(p, ((0, 0), (0, 0), (0, size - p.shape[-1]))) for p in parts])


def _polymul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched product of ascending coefficient arrays (last axis)."""
    out = np.zeros(np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
                   + (a.shape[-1] + b.shape[-1] - 1,), complex)
    for i in range(a.shape[-1]):
        out[..., i:i + b.shape[-1]] += a[..., i:i + 1] * b
    return out


def _add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    size = max(a.shape[-1], b.shape[-1])
    pad = [(0, 0)] * (a.ndim - 1)
    return (np.pad(a, pad + [(0, size - a.shape[-1])])
            + np.pad(b, [(0, 0)] * (b.ndim - 1) + [(0, size - b.shape[-1])]))


def polynomial_det(q: np.ndarray) -> np.ndarray:
    """The determinant of ``q`` (``batch + (n, n, L)``, ascending polynomial entries),
    expanded exactly: the minors of the first ``k`` rows on every subset of ``k`` columns,
    each from the ``k - 1`` row minors (Laplace along row ``k``; ``n 2^n`` products)."""
    n = q.shape[-2]
    minors = {0: np.ones(q.shape[:-3] + (1,), complex)}
    for k in range(n):
        nxt: dict[int, np.ndarray] = {}
        for mask, m in minors.items():
            for c in range(n):
                if mask >> c & 1:
                    continue
                sign = -1.0 if bin(mask >> c).count("1") % 2 else 1.0
                term = sign * _polymul(q[..., k, c, :], m)
                key = mask | 1 << c
                nxt[key] = term if key not in nxt else _add(nxt[key], term)
        minors = nxt
    return minors[(1 << n) - 1]


def _on_grid(terms: np.ndarray, zt: np.ndarray, zd: np.ndarray) -> np.ndarray:
    """``(d, y, h)`` of every joint at each ``(z_t, z_d)``: ``(n, 3, Nt, Nd, L)``."""
    pt = np.stack([np.ones_like(zt), zt])  # (2, Nt): z_t^a
    pd = np.stack([np.ones_like(zd), zd])
    return np.einsum("jxabl,at,bu->jxtul", terms.astype(complex), pt, pd)


def characteristic_matrix(terms: np.ndarray, mass: np.ndarray, damping: np.ndarray,
                          stiffness: np.ndarray, zs: np.ndarray, zt: np.ndarray,
                          zd: np.ndarray) -> np.ndarray:
    """``Q`` at each ``(z_s, z_t, z_d)`` of the grid: ``(Ns, Nt, Nd, n, n, L)``."""
    n = mass.shape[0]
    g = _on_grid(terms, zt, zd)  # (n, 3, Nt, Nd, L)
    size = g.shape[-1] + 2
    body = np.zeros((n, n, 3))
    body[..., 2] = mass
    body[..., 1] = np.diag(damping)
    d, y, h = (np.pad(g[:, i], [(0, 0)] * 3 + [(0, size - g.shape[-1])]) for i in range(3))
    q = np.einsum("jtul,jkm->tujklm", d, body)  # d_j (M_jk s^2 + B_jk s): degrees add
    prod = np.zeros(q.shape[:-2] + (size,), complex)
    for m in range(3):
        prod[..., m:] += q[..., :size - m, m]
    eye = np.eye(n)
    prod = prod + np.einsum("jtul,jk->tujkl", y, eye)
    hk = np.einsum("jtul,jk->tujkl", h, stiffness)
    return prod[None] + zs[:, None, None, None, None, None] * hk[None]


def robot_delay_terms(terms: np.ndarray, mass: np.ndarray, damping: np.ndarray,
                      stiffness: np.ndarray, delays_s: dict[str, float]) -> DelayTerms:
    """The robot's characteristic as :class:`DelayTerms` (delays named by process).

    Parameters
    ----------
    terms : numpy.ndarray
        Per joint :func:`joint_terms`, stacked: ``(n, 3, 2, 2, L)``.
    mass : numpy.ndarray
        ``M(q0)`` [kg m^2] (``n x n``).
    damping : numpy.ndarray
        The joints' viscous damping [N m s/rad] (``n``).
    stiffness : numpy.ndarray
        ``K`` on the central process [N m/rad] (``n x n``).
    delays_s : dict
        ``"stiffness"``, ``"torque"``, ``"damping"`` -> delay [s].

    Returns
    -------
    DelayTerms
        ``det Q`` per monomial ``z_s^a z_t^b z_d^c`` (exponents ``(a, b, c)``).
    """
    n = mass.shape[0]
    z = np.exp(2j * np.pi * np.arange(n + 1) / (n + 1))
    values = polynomial_det(characteristic_matrix(terms, mass, damping, stiffness, z, z, z))
    coeffs = np.fft.fftn(values, axes=(0, 1, 2)) / (n + 1) ** 3
    floor = 64 * np.finfo(float).eps * np.abs(values).max(axis=(0, 1, 2))
    coeffs = np.where(np.abs(coeffs) > floor, coeffs.real, 0.0)
    grid = np.indices((n + 1,) * 3).reshape(3, -1).T
    flat = coeffs.reshape(-1, coeffs.shape[-1])
    keep = np.any(flat != 0.0, axis=-1)
    keep[0] = True
    tau = np.array([float(delays_s[p]) for p in PROCESSES])
    return DelayTerms(flat[keep], grid[keep], PROCESSES, tau)
