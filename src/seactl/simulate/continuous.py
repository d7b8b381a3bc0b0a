"""The continuous mode: exact delays, fixed step, compiled run loop."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.jit import KernelGroup, njit
from seactl.base.limits import check_budget, check_delay_buffers, simulation_estimate
from seactl.base.parallel import in_threads
from seactl.diagram.blockdiagram import BlockDiagram
from seactl.errors import InputError
from seactl.simulate.network import assemble_blocks, delay_attr, foh, impulse_vector, input_values
from seactl.simulate.realize import realize_continuous
from seactl.simulate.results import Layout, RunOutputs, batch_last

KERNELS = KernelGroup("simulation", about_s=8)
"""The group of this module's kernels (the continuous simulation)."""


# ----------------------------------------------------------------------------- continuous
@dataclass(frozen=True)
class ContinuousPlan:
    """A diagram compiled for the continuous run loop (batch on the last axis).

    ``H = [F G0 G1]`` advances ``z = [x; v_i; v_{i+1}]`` (layout ``z``; each ``v`` has the
    layout ``v``: exogenous inputs, then delayed block inputs); ``CD`` gives the signal rows
    of layout ``rows`` (the delayed blocks' sources, then the recorded outputs) from
    ``[x; v_i]``.  Delay buffers read ``whole`` steps back, interpolated by ``frac``."""

    t_s: np.ndarray
    dt_s: float
    every: int
    outputs: tuple[str, ...]
    H: np.ndarray
    CD: np.ndarray
    inputs: np.ndarray
    x0: np.ndarray
    z: Layout
    v: Layout
    rows: Layout
    whole: np.ndarray
    frac: np.ndarray
    ring_len: int
    delays_s: dict[str, np.ndarray]
    shape: tuple[int, ...]

    @property
    def steps(self) -> int:
        return self.t_s.size - 1


def _continuous_step(delays: Mapping[str, np.ndarray], dt: float | None) -> float:
    positive = [d[d > 0] for d in delays.values()]
    min_pos = min([float(p.min()) for p in positive if p.size] or [np.inf])
    if dt is None:
        dt = min(1e-4, min_pos)
    dt = float(dt)
    if not (dt > 0 and math.isfinite(dt)):
        raise InputError("dt", dt, "a finite step > 0 [s]")
    if dt > min_pos * (1 + 1e-9):
        raise InputError("dt", dt, f"<= the smallest positive delay ({min_pos:g} s)")
    return dt


def check_size(n: int, steps: int, recorded: int, hint: str) -> None:
    """Refuse up front a simulation larger than the machine (the command line checks its
    own options first, with their names; this guards every other caller)."""
    n_bytes, seconds = simulation_estimate(n, steps, recorded)
    check_budget(f"simulating {n:,} design(s) over {steps:,} steps", n_bytes=n_bytes,
                 seconds=seconds, hint=hint)


def compile_continuous(diagram: BlockDiagram, design: Any, inputs: Mapping[str, Any],
                       t_end_s: float, outputs: Sequence[str], *, dt: float | None = None,
                       record_dt: float | None = None,
                       derivative_tau_s: float = 1e-7) -> ContinuousPlan:
    """Compile ``diagram`` for :func:`run_continuous` (see :func:`simulate`)."""
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    blocks = list(diagram.blocks)
    delayed = [b for b in blocks if b.delay is not None]
    delays = {b.name: delay_attr(design, b, shape, n) for b in delayed}
    dt = _continuous_step(delays, dt)
    steps = int(math.ceil(t_end_s / dt - 1e-9))
    every = 1 if record_dt is None else max(1, int(round(record_dt / dt)))
    check_size(n, steps, steps // every + 1, f"the continuous step is {dt:.3g} s (the "
                "smallest positive delay, at most 0.1 ms): give a coarser record_dt, a "
                "shorter t_end_s, or fewer designs")
    longest = max((float(np.max(d)) for d in delays.values()), default=0.0)
    check_delay_buffers(n, len(delayed), longest / dt, dt)
    reals = [realize_continuous(b, design, shape, n, derivative_tau_s) for b in blocks]
    exo = list(diagram.inputs)
    inst = {b.name: np.ones(n) for b in blocks}
    wcol = {}
    for j, b in enumerate(delayed):
        inst[b.name] = (delays[b.name] == 0).astype(float)
        wcol[b.name] = len(exo) + j
    signals = list(diagram.signals)
    net = assemble_blocks(n, signals, blocks, reals, exo, inst, wcol)
    F, G0, G1 = foh(net.A, net.B, dt)
    idx = {s: i for i, s in enumerate(signals)}
    rows = [idx[b.src] for b in delayed] + [idx[o] for o in outputs]
    Cr, Dr = net.C[:, rows, :], net.D[:, rows, :]
    nd, ne, N = len(delayed), len(exo), F.shape[1]
    v = Layout.of(exo=ne, delayed=nd)
    # Delay buffers: position of t - T in steps, split into whole steps and a fraction.
    mpos = np.stack([delays[b.name] / dt for b in delayed], axis=1) if nd else np.zeros((n, 0))
    mint = np.floor(mpos + 1e-9)
    frac = np.clip(mpos - mint, 0.0, 1.0)
    frac[frac < 1e-9] = 0.0
    mint = mint.astype(int)
    t = np.arange(steps + 1) * dt
    x0 = np.zeros((N, n))
    imp = impulse_vector(inputs, exo)
    if np.any(imp):
        # A Dirac on an input: x(0+) = B_u * area, valid if it feeds no signal we read.
        cols = np.nonzero(imp)[0]
        if np.any(np.abs(Dr[:, :, cols]) > 0):
            raise InputError("inputs", ", ".join(exo[c] for c in cols),
                             "an impulse only on inputs that reach the outputs and delay "
                             "buffers through dynamics (no direct feed-through)")
        x0 = np.einsum("nij,j->in", net.B[:, :, cols], imp[cols])
    return ContinuousPlan(
        t, dt, every, tuple(outputs), batch_last(np.concatenate([F, G0, G1], axis=2)),
        batch_last(np.concatenate([Cr, Dr], axis=2)), input_values(inputs, exo, t, shape, n),
        x0, Layout.of(x=N, v0=v.size, v1=v.size), v, Layout.of(src=nd, out=len(outputs)),
        mint.T.copy(), frac.T.copy(), int(mint.max(initial=0)) + 3, delays, shape)


def run_continuous(plan: ContinuousPlan, bound: float) -> RunOutputs:
    """Step a :class:`ContinuousPlan` in time (compiled: :func:`_continuous_kernel`)."""
    p, z, v = plan, plan.z, plan.v
    n = p.H.shape[-1]
    nd = v["delayed"].stop - v["delayed"].start
    rec_t = np.full((p.steps // p.every + 1, len(p.outputs), n), np.nan)  # time first
    left = np.full(n, np.inf)

    def run(k: slice) -> None:
        own = (lambda a: np.ascontiguousarray(a[..., k])) if k != slice(0, n) else \
            np.ascontiguousarray
        inputs = p.inputs if p.inputs.shape[-1] == 1 else own(p.inputs)
        _continuous_kernel(own(p.H), own(p.CD), np.ascontiguousarray(inputs), own(p.x0),
                           own(p.whole).astype(np.int64), own(p.frac).astype(float),
                           p.ring_len, z["x"].stop, v["exo"].stop, nd, p.steps, p.every,
                           p.t_s, float(bound), rec_t, left, k.start)

    in_threads(run, n, min_per_thread=64)
    # (outputs, designs, time) as a view: a copy of a large batch's record costs a
    # quarter of the run
    rec = fill_diverged(rec_t.transpose(1, 2, 0), left)
    delays = {k: d.reshape(p.shape) for k, d in p.delays_s.items()}
    info = {"dt_s": p.dt_s, "record_dt_s": p.dt_s * p.every,
            "requested_delays_s": delays, "effective_delays_s": delays}
    return RunOutputs(p.t_s[::p.every], {o: rec[j] for j, o in enumerate(p.outputs)}, left, info)


@njit(cache=True, nogil=True)
def _continuous_kernel(H, CD, inputs, x0, whole, frac, ring_len, nx, ne, nd, steps, every,
                       t, bound, rec_t, left, k0):  # pragma: no cover - compiled
    """Every step: ``S = CD [x; v_i]`` gives the delayed blocks' sources (into the ring
    buffer) and the outputs; ``v`` holds the exogenous inputs and the buffers read
    ``whole`` steps back, interpolated by ``frac``; ``x <- H [x; v_i; v_{i+1}]``.  The
    batch is the innermost (contiguous) axis, so the products vectorize over designs.  A
    design whose first output leaves ``bound`` is recorded no further (``left``) and
    restarted from zero (its numbers no longer matter; zeros keep them finite).  The
    designs are columns ``k0`` on of ``rec_t`` and ``left`` (whole arrays: one compiled
    layout however the batch is split over threads).  Compiled: thousands of steps of
    small products, where numpy's per-call overhead and temporaries would outweigh the
    arithmetic."""
    n, nv = H.shape[2], ne + nd
    nrow = CD.shape[0]
    zb = np.zeros((nx + 2 * nv, n))
    zb[:nx] = x0
    ring = np.zeros((ring_len, max(nd, 1), n))
    S = np.zeros((nrow, n))
    xn = np.zeros((nx, n))
    alive = np.ones(n, np.bool_)
    # every design with the same buffer positions: rows read at once (a bool and an int,
    # not the literals True and 0: numba compiles _fill_inputs once, not per literal)
    same = nd >= 0
    for d in range(nd):
        for k in range(1, n):
            if whole[d, k] != whole[d, 0]:
                same = False
    _fill_inputs(zb, nx, inputs, np.int64(0), ne, nd, ring, whole, frac, same)
    cd_cols = _nonzero_columns(CD, nx + nv)
    h_cols = _nonzero_columns(H, nx + 2 * nv)
    for i in range(steps + 1):
        _product(CD, zb, cd_cols, S)
        for d in range(nd):
            for k in range(n):
                ring[i % ring_len, d, k] = S[d, k]
        for k in range(n):
            if alive[k] and not abs(S[nd, k]) <= bound:
                alive[k] = False
                left[k0 + k] = t[i]
                zb[:, k] = 0.0
                ring[:, :, k] = 0.0
        if i % every == 0:
            for o in range(nrow - nd):
                for k in range(n):
                    if alive[k]:
                        rec_t[i // every, o, k0 + k] = S[nd + o, k]
        if i == steps:
            break
        _fill_inputs(zb, nx + nv, inputs, i + 1, ne, nd, ring, whole, frac, same)
        _product(H, zb, h_cols, xn)
        for r in range(nx):
            for k in range(n):
                zb[r, k] = xn[r, k]
        for r in range(nx, nx + nv):
            for k in range(n):
                zb[r, k] = zb[r + nv, k]


@njit(cache=True)
def _nonzero_columns(M, ncol):  # pragma: no cover - compiled
    """Per row of ``M`` (rows, cols, batch), the columns non-zero for some design, padded
    with -1: the products skip the structural zeros of the block diagram."""
    cols = np.full((M.shape[0], ncol), -1, np.int64)
    for r in range(M.shape[0]):
        m = 0
        for j in range(ncol):
            for k in range(M.shape[2]):
                if M[r, j, k] != 0.0:
                    cols[r, m] = j
                    m += 1
                    break
    return cols


@njit(cache=True)
def _product(M, zb, cols, out):  # pragma: no cover - compiled
    """``out[r, k] = sum_j M[r, j, k] zb[j, k]`` over the non-zero columns ``cols[r]``
    (one matrix per design, batch last).  A batch of a few designs sums in a register
    (through memory, each term would wait for the last one's store); a larger one
    vectorizes over the batch."""
    n = M.shape[2]
    for r in range(M.shape[0]):
        if n < 4:
            for k in range(n):
                acc = 0.0
                for m in range(cols.shape[1]):
                    j = cols[r, m]
                    if j < 0:
                        break
                    acc += M[r, j, k] * zb[j, k]
                out[r, k] = acc
            continue
        for k in range(M.shape[2]):
            out[r, k] = 0.0
        for m in range(cols.shape[1]):
            j = cols[r, m]
            if j < 0:
                break
            for k in range(M.shape[2]):
                out[r, k] += M[r, j, k] * zb[j, k]


@njit(cache=True)
def _fill_inputs(zb, at, inputs, i, ne, nd, ring, whole, frac, same):  # pragma: no cover
    """``v`` of step ``i`` into ``zb[at:]``: exogenous inputs, then the delayed blocks'
    inputs read from the ring buffer (linear interpolation between whole steps); ``same``:
    every design reads the same slots."""
    n, L = zb.shape[1], ring.shape[0]
    for e in range(ne):
        if inputs.shape[2] == 1:
            zb[at + e] = inputs[i, e, 0]
        else:
            zb[at + e] = inputs[i, e]
    now, before = i % L, (i - 1) % L
    for d in range(nd):
        if same:
            ia, ib = (now - whole[d, 0]) % L, (before - whole[d, 0]) % L
            for k in range(n):
                a = ring[ia, d, k]
                zb[at + ne + d, k] = a + frac[d, k] * (ring[ib, d, k] - a)
            continue
        for k in range(n):
            ia, ib = now - whole[d, k], before - whole[d, k]   # whole < L: one wrap at most
            a = ring[ia + L if ia < 0 else ia, d, k]
            b = ring[ib + L if ib < 0 else ib, d, k]
            zb[at + ne + d, k] = a + frac[d, k] * (b - a)


def fill_diverged(rec: np.ndarray, left: np.ndarray) -> np.ndarray:
    """After a design leaves the bounds its record is held at the last in-bound value
    (plots stay finite; ``left_bounds_s`` says where the data stops meaning anything)."""
    if not np.isfinite(left).any():
        return rec
    out = rec.copy()
    for j in range(out.shape[0]):
        r = out[j]
        bad = np.isnan(r)
        if bad.any():
            last = np.where(~bad, np.arange(r.shape[1]), 0)
            np.maximum.accumulate(last, axis=1, out=last)
            r[:] = np.take_along_axis(np.nan_to_num(r), last, axis=1)
    return out
