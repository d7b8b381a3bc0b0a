"""The aliased plant in closed form: ``sum_k |P(j (theta + 2 pi k) / h)|^2`` for a
continuous plant ``P(s) = C (sI - A)^-1 B`` (strictly proper).

Write ``t = n h + tau`` (``0 <= tau < h``) in the impulse response: for ``z = e^{j theta}``
not an eigenvalue of ``Phi = e^{A h}`` and ``w_k = (theta + 2 pi k) / h``,

    ``P(j w_k) = C z (zI - Phi)^-1 b_k``,   ``b_k = int_0^h e^{A tau} B e^{-j w_k tau} dtau``,

an algebraic identity (``b_k = (A - j w_k)^-1 (Phi / z - I) B``), so it holds with
integrators too.  The ``b_k`` are the Fourier coefficients of ``e^{A tau} B e^{-j theta
tau / h}`` on ``[0, h)``, and Parseval sums their squares exactly:

    ``sum_k |P(j w_k)|^2 = h C (zI - Phi)^-1 Q (zI - Phi)^-H C^T``,
    ``Q = int_0^h e^{A tau} B B^T e^{A^T tau} dtau``   (Van Loan's exponential).

No series is truncated.  The jitter bound needs ``|z - 1|^2`` times this sum, whose pole
at ``z = 1`` (a simple integrator of ``P``) cancels: :func:`alias_factor` splits the zero
eigenvalue off ``A`` (ordered Schur form, states balanced first) and returns a
realization with the poles ``e^{lambda h}`` of the other modes only.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.linalg import expm, matrix_balance, schur

from seactl.diagram.blockdiagram import BlockDiagram
from seactl.errors import InputError
from seactl.simulate.realize import realize_continuous

__all__ = ["ZERO_TOL", "plant_realization", "time_scaled", "alias_sum", "alias_factor",
           "integrators"]

ZERO_TOL = 1e-9
"""An eigenvalue of ``A`` with ``|lambda| <= ZERO_TOL ||A||_1`` is an integrator (exact
zero in exact arithmetic: the plant blocks' ``s`` factors)."""


def plant_realization(path: BlockDiagram, design: Any, tap: str, act: str
                      ) -> tuple[np.ndarray, ...]:
    """Batched continuous ``(A, B, C, D)`` (flat batch first) of ``path`` (plant blocks and
    static sensor chain) from ``act`` to ``tap``.

    The static couplings between signals are solved by their finite series
    ``(I - P)^-1 = sum_i P^i`` (the network is acyclic: ``P`` is nilpotent), which keeps
    the structural zeros exact: a rounding-level coupling left by a general solve would
    lower the plant's relative degree and dominate its alias tail."""
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    blocks = list(path.blocks)
    reals = [realize_continuous(b, design, shape, n) for b in blocks]
    signals = sorted({b.dst for b in blocks} | {b.src for b in blocks})
    idx, m = {s: i for i, s in enumerate(signals)}, len(signals)
    sizes = np.cumsum([0] + [r[0].shape[1] for r in reals])
    P, Q, R = np.zeros((n, m, m)), np.zeros((n, m, sizes[-1])), np.zeros((n, m, 1))
    R[:, idx[act], 0] = 1.0
    for b, (_A, _B, Cb, Db), lo, hi in zip(blocks, reals, sizes[:-1], sizes[1:]):
        Q[:, idx[b.dst], lo:hi] += Cb
        P[:, idx[b.dst], idx[b.src]] += Db
    Ms, term = np.eye(m) + 0 * P, np.eye(m) + 0 * P
    for _ in range(m):
        term = term @ P
        if not term.any():
            break
        Ms = Ms + term
    else:
        raise InputError("diagram", path.name, "plant and sensor blocks without an "
                         "algebraic loop")
    Cs, Ds = Ms @ Q, Ms @ R
    A, B = np.zeros((n, sizes[-1], sizes[-1])), np.zeros((n, sizes[-1], 1))
    for b, (Ab, Bb, _C, _D), lo, hi in zip(blocks, reals, sizes[:-1], sizes[1:]):
        A[:, lo:hi, lo:hi] += Ab
        A[:, lo:hi, :] += Bb[:, :, None] * Cs[:, None, idx[b.src], :]
        B[:, lo:hi, :] += Bb[:, :, None] * Ds[:, None, idx[b.src], :]
    i = idx[tap]
    return A, B, Cs[:, i:i + 1, :], Ds[:, i:i + 1, :]


def time_scaled(A: np.ndarray, B: np.ndarray, C: np.ndarray, h: float
                ) -> tuple[np.ndarray, ...]:
    """The same plant with each state scaled (by a power of two: exact) to the size it
    reaches over one period from a unit input, ``|e^{A h} B|`` (twice, the second from
    the first's coordinates).  In these coordinates the response's components are all of
    order one, so the exponentials' normwise rounding is relative for each of them (a
    position two integrations down a chain is otherwise lost below the velocity's)."""
    d = np.ones(A.shape[0])
    for _ in range(2):
        As, Bs = A * d[None, :] / d[:, None], B / d[:, None]
        v = np.abs(expm(As * h) @ Bs)[:, 0] + np.abs(Bs[:, 0])
        v = np.maximum(v, 1e-30 * v.max())
        d = d * 2.0 ** np.round(np.log2(v))
    return A * d[None, :] / d[:, None], B / d[:, None], C * d[None, :]


def _van_loan(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Phi, Q)``: ``e^{A h}`` and ``int_0^h e^{A t} B B^T e^{A^T t} dt``."""
    N = A.shape[0]
    V = expm(np.block([[-A, B @ B.T], [np.zeros((N, N)), A.T]]) * h)
    Phi = V[N:, N:].T
    Q = Phi @ V[:N, N:]
    return Phi, (Q + Q.T) / 2


def alias_sum(A: np.ndarray, B: np.ndarray, C: np.ndarray, theta: np.ndarray, h: float
              ) -> np.ndarray:
    """``sum_k |P(j (theta + 2 pi k) / h)|^2`` at each ``theta`` (one plant), exactly (up to
    rounding): ``h C (zI - Phi)^-1 Q (zI - Phi)^-H C^T``.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[-2.0]]); B = C = np.array([[1.0]])   # 1/(s + 2), h = 1: the sum
    >>> float(alias_sum(A, B, C, np.array([0.0]), 1.0)[0])  # is coth(1)/4 at theta = 0
    0.3282...
    """
    A, B, C = time_scaled(A, B, C, h)
    Phi, Q = _van_loan(A, B, h)
    z = np.exp(1j * np.atleast_1d(theta))[:, None, None]
    R = np.linalg.solve(np.swapaxes(z * np.eye(A.shape[0]) - Phi, -1, -2),
                        np.broadcast_to(C.T, z.shape[:1] + C.T.shape))[..., 0]
    return h * np.einsum("fi,ij,fj->f", R, Q, R.conj()).real


def integrators(A: np.ndarray) -> int:
    """The number of zero eigenvalues of ``A`` (within :data:`ZERO_TOL`)."""
    lam = np.linalg.eigvals(A)
    return int(np.sum(np.abs(lam) <= ZERO_TOL * max(np.linalg.norm(A, 1), 1e-300)))


def _schur_zero_first(A: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``(T, Z)``: ``A = Z T Z^T``, ``Z`` orthogonal, ``T`` block upper triangular with its
    ``m`` zero eigenvalues first (ordered real Schur form; that block set to exact 0)."""
    tol = ZERO_TOL * max(np.linalg.norm(A, 1), 1e-300)
    T, Z, _ = schur(A, output="real", sort=lambda re, im: np.hypot(re, im) <= tol)
    T[:, :m] = 0.0
    return T, Z


def alias_factor(A: np.ndarray, B: np.ndarray, C: np.ndarray, h: float
                 ) -> tuple[np.ndarray, ...]:
    """A realization ``(Aw, Bw, Cw, Dw)`` of the row ``W(z)`` with
    ``||W(e^{j theta})||^2 = |e^{j theta} - 1|^2 sum_k |P(j (theta + 2 pi k) / h)|^2``,
    the eigenvalues of ``Aw`` being ``e^{lambda h}`` over the nonzero eigenvalues of ``A``.

    ``|z - 1|^2 h C (zI - Phi)^-1 Q (...)^H C^T = ||W||^2`` with ``W = sqrt(h) (z - 1) C
    (zI - Phi)^-1 L``, ``L L^T = Q``.  In Schur coordinates with the integrator first,
    ``Phi = [[1, f], [0, Phi_r]]`` and ``(z - 1)(zI - Phi)^-1 = [[1, f R], [0, I + (Phi_r -
    I) R]]``, ``R = (zI - Phi_r)^-1``: so ``W = sqrt(h) (C L + (C (Phi - I))_r R L_r)``, the
    pole at ``1`` gone (the states balanced, then an orthogonal change of basis: no
    ill-conditioned split of ``P`` into ``c/s`` and the rest, whose terms would cancel at
    high frequency).  Refuses a plant with more than one integrator (its pole at ``1``
    would not cancel)."""
    m = integrators(A)
    if m > 1:
        raise InputError("plant", f"{m} integrators", "a plant with at most one integrator "
                         "(passive damping) for the sampled jitter margin")
    _, (d, _p) = matrix_balance(A, permute=False, separate=True)
    A, B, C = A * d[None, :] / d[:, None], B / d[:, None], C * d[None, :]
    T, Z = _schur_zero_first(A, m)
    Bt, Ct = Z.T @ B, C @ Z
    _, Q = _van_loan(T, Bt, h)
    lam, V = np.linalg.eigh(Q)
    L = V * np.sqrt(np.clip(lam, 0.0, None))
    N = T.shape[0]
    # Phi - I = T int_0^h e^{T t} dt (no cancellation for small h)
    E = expm(np.block([[T, np.eye(N)], [np.zeros((N, 2 * N))]]) * h)
    Phi, PmI = E[:N, :N], T @ E[:N, N:]
    rh = np.sqrt(h)
    return Phi[m:, m:], L[m:, :], rh * (Ct @ PmI)[:, m:], rh * Ct @ L
