"""The blocks' network assembled into one batched state space; its numerics."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.jit import KernelGroup, njit
from seactl.base.parallel import stacked
from seactl.diagram.blockdiagram import Block
from seactl.errors import SeactlError
from seactl.simulate.inputs import Impulse

KERNELS = KernelGroup("matrix balancing", about_s=1)
"""The group of this module's kernels (the batched balancing)."""


# ----------------------------------------------------------------------------- network
@dataclass
class BlockNet:
    """A batched linear network ``x+ = A x + B v``, ``S = C x + D v`` over ``signals``."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_slices: dict[str, slice]


def assemble_blocks(n: int, signals: Sequence[str], blocks: Sequence[Block],
              reals: Sequence[tuple[np.ndarray, ...]], inject: Sequence[str],
              inst: Mapping[str, np.ndarray], wcol: Mapping[str, int],
              held: Mapping[str, int] = {}, identity_hold: bool = True,
              nv: int | None = None) -> BlockNet:
    """Assemble the network.  Inputs ``v`` are: one column per ``inject`` signal (added to
    it), delayed-input columns ``wcol[block]`` (weight ``1 - inst[block]``), held-output
    columns ``held[block]`` (the block's output is the column; its state is frozen)."""
    idx = {s: i for i, s in enumerate(signals)}
    m = len(signals)
    nv = len(inject) + len(wcol) + len(held) if nv is None else nv
    slices, off = {}, 0
    for b, (A, *_rest) in zip(blocks, reals):
        slices[b.name] = slice(off, off + A.shape[1])
        off += A.shape[1]
    N = off
    P = np.zeros((n, m, m))
    Q = np.zeros((n, m, N))
    R = np.zeros((n, m, nv))
    for j, s in enumerate(inject):
        R[:, idx[s], j] += 1.0
    for b, (_A, _B, C, D) in zip(blocks, reals):
        d, sl = idx[b.dst], slices[b.name]
        if b.name in held:
            R[:, d, held[b.name]] += 1.0
            continue
        z = inst[b.name]
        Q[:, d, sl] += C
        P[:, d, idx[b.src]] += D * z
        if b.name in wcol:
            R[:, d, wcol[b.name]] += D * (1.0 - z)
    try:
        M = stacked(np.linalg.inv, np.eye(m)[None] - P)
    except np.linalg.LinAlgError:
        raise SeactlError("the loop's instantaneous (algebraic) feedback is singular in "
                          "floating point for these parameters: the gains or plant values "
                          "are too extreme to simulate") from None
    Cs, Ds = M @ Q, M @ R
    Ax = np.zeros((n, N, N))
    Bx = np.zeros((n, N, nv))
    for b, (A, B, _C, _D) in zip(blocks, reals):
        sl = slices[b.name]
        if b.name in held:
            if identity_hold:
                Ax[:, sl, sl] = np.eye(A.shape[1])
            continue
        z = inst[b.name]
        s = idx[b.src]
        Ax[:, sl, sl] += A
        Ax[:, sl, :] += B[:, :, None] * (z[:, None, None] * Cs[:, None, s, :])
        Bx[:, sl, :] += B[:, :, None] * (z[:, None, None] * Ds[:, None, s, :])
        if b.name in wcol:
            Bx[:, sl, wcol[b.name]] += B * (1.0 - z)[:, None]
    return BlockNet(Ax, Bx, Cs, Ds, slices)


_PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
           129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
           40840800.0, 960960.0, 16380.0, 182.0, 1.0)


_MAX_SQUARINGS = 12


def balance_batched(A: np.ndarray, sweeps: int = 40) -> np.ndarray:
    """Powers of two ``d`` (shape ``(..., N)``) that balance each matrix of a stack:
    ``A * d[..., None, :] / d[..., :, None]`` (that is ``D^-1 A D``) has off-diagonal row
    and column 1-norms within a factor of about 2 of each other (Parlett and Reinsch, the
    scaling of LAPACK's ``gebal``; one index at a time, compiled, over the stack).

    Powers of two make the similarity exact in floating point.  Rows or columns that are
    zero off the diagonal, or not finite, are left alone.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[-1e7, 1e-5], [1e13, -10.0]])
    >>> d = balance_batched(A)
    >>> B = A * d[None, :] / d[:, None]
    >>> bool(np.all((abs(B[0, 1]) / abs(B[1, 0]) > 0.25) & (abs(B[0, 1]) / abs(B[1, 0]) < 4)))
    True
    """
    A = np.asarray(A, float)
    n = A.shape[-1]
    with np.errstate(invalid="ignore"):
        W = np.where(np.isfinite(A), np.abs(A), 0.0) * (1.0 - np.eye(n))
    d = np.ones(A.shape[:-1])
    _balance_kernel(W.reshape(-1, n, n), d.reshape(-1, n), sweeps)
    return d


@njit(cache=True, nogil=True)
def _balance_kernel(W, d, sweeps):  # pragma: no cover - compiled
    # W: |A| off the diagonal, rescaled in place to |D^-1 A D|; scaling index i by f
    # multiplies its column by f and divides its row by f
    for k in range(W.shape[0]):
        n = W.shape[1]
        for _ in range(sweeps):
            changed = False
            for i in range(n):
                c = 0.0
                r = 0.0
                for j in range(n):
                    c += W[k, j, i]
                    r += W[k, i, j]
                if not (c > 0.0 and r > 0.0):
                    continue
                f = 2.0 ** np.round(0.5 * np.log2(r / c))
                if c * f + r / f < 0.95 * (c + r):
                    for j in range(n):
                        W[k, j, i] *= f
                        W[k, i, j] /= f
                    d[k, i] *= f
                    changed = True
            if not changed:
                break


def expm_batched(A: np.ndarray) -> np.ndarray:
    """Matrix exponential of a stack ``(..., N, N)``: balancing (:func:`balance_batched`),
    then scaling and squaring with the degree-13 Pade approximant (Higham 2005), each
    matrix scaled by its own power of two.

    Balancing first matters for a loop's augmented matrices, whose entries span many
    decades (a fast roll-off next to a slow mechanism): without it the squarings lose up
    to seven digits of a Table I loop's step response, and tiny entries entirely.

    All work is stacked numpy (``matmul``/``solve``), which avoids per-matrix library
    calls (``scipy.linalg.expm`` loops over the stack: one call, and one round of
    multithreaded BLAS, per small matrix).
    Matrices needing more than 12 squarings are handed to :func:`scipy.linalg.expm`.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.linalg import expm
    >>> A = np.array([[[0.0, 1.0], [-4.0, -0.4]], [[-30.0, 2.0], [0.0, -1e3]]])
    >>> bool(np.allclose(expm_batched(A), expm(A), rtol=1e-12, atol=1e-14))
    True
    """
    A = np.asarray(A, float)
    d = balance_batched(A)
    A = A0 = A * d[..., None, :] / d[..., :, None]
    b = _PADE13
    norm = np.max(np.sum(np.abs(A), axis=-2), axis=-1)
    with np.errstate(divide="ignore"):
        s = np.maximum(0, np.ceil(np.log2(norm / 5.371920351148152))).astype(int)
    s = np.where(norm > 0, s, 0)
    A = A / (2.0 ** s)[..., None, None]
    eye = np.broadcast_to(np.eye(A.shape[-1]), A.shape)
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2)
             + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * eye)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 \
        + b[0] * eye
    R = np.linalg.solve(V - U, V + U)
    hard = s > _MAX_SQUARINGS
    s = np.where(hard, 0, s)
    for k in range(int(s.max(initial=0))):
        more = k < s
        R[more] = R[more] @ R[more]
    if hard.any():
        # Badly scaled (stiff, strongly non-normal) matrices, e.g. an unfiltered derivative's
        # fast roll-off: many squarings would amplify rounding; scipy's expm (Al-Mohy and
        # Higham 2009) bounds the squarings with norm estimates of powers.
        from scipy.linalg import expm

        R[hard] = expm(np.asarray(A0)[hard])
    return R * d[..., :, None] / d[..., None, :]


def foh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact discretization for inputs linear over a step: ``x1 = F x0 + G0 v0 + G1 v1``."""
    n, N, _ = A.shape
    nv = B.shape[2]
    M = np.zeros((n, N + 2 * nv, N + 2 * nv))
    M[:, :N, :N] = A * h
    M[:, :N, N:N + nv] = B * h
    M[:, N:N + nv, N + nv:] = np.eye(nv)
    # (a violently unstable loop, e.g. a negative derivative gain on a micro-inertia,
    # overflows e^{A h}: its simulation leaves the bounds at the first step)
    with np.errstate(over="ignore", invalid="ignore"):
        E = expm_batched(M)
        G1, G2 = E[:, :N, N:N + nv], E[:, :N, N + nv:]
        return E[:, :N, :N], G1 - G2, G2


def delay_attr(design: Any, block: Block, shape: tuple[int, ...], n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(getattr(design, block.delay), float), shape).reshape(n)


def input_values(inputs: Mapping[str, Any], names: Sequence[str], t: np.ndarray,
                  shape: tuple[int, ...], n: int) -> np.ndarray:
    """Exogenous input values, shape ``(T, len(names), n)`` (or ``(T, len(names), 1)``
    when no input depends on the design)."""
    vals = []
    for name in names:
        f = inputs.get(name)
        val = np.zeros(t.shape) if f is None else np.asarray(f(t), float)
        if val.ndim <= 1:
            vals.append(np.broadcast_to(val, t.shape)[:, None])
        else:
            vals.append(np.broadcast_to(val, shape + t.shape).reshape(n, t.size).T)
    if not vals:
        return np.zeros((t.size, 0, 1))
    nb = max(v.shape[1] for v in vals)
    return np.stack([np.broadcast_to(v, (t.size, nb)) for v in vals], axis=1)


def impulse_vector(inputs: Mapping[str, Any], names: Sequence[str]) -> np.ndarray:
    return np.array([inputs[nm].area if isinstance(inputs.get(nm), Impulse) else 0.0
                     for nm in names])


def default_bound(inputs: Mapping[str, Any]) -> float:
    scales = [getattr(f, "scale", 0.0) for f in inputs.values()]
    return 1e3 * max([s for s in scales if s > 0] or [1.0])


def growing(y: np.ndarray, scale: float) -> np.ndarray:
    """Responses not decaying at the end of the window (slow divergence, or a sustained
    oscillation such as a limit cycle bounded by saturation): the deviation from the final
    mean over the last fifth of the window is above 0.9x that over the previous fifth and
    above 1e-3 x the input scale."""
    T = y.shape[-1]
    a, b = y[..., T - 2 * (T // 5):T - T // 5], y[..., T - T // 5:]
    mean = b.mean(axis=-1, keepdims=True)
    ea = np.max(np.abs(a - mean), axis=-1)
    eb = np.max(np.abs(b - mean), axis=-1)
    return (eb > 0.9 * ea) & (eb > 1e-3 * scale)
