"""A user loop's margins at its named breaks: open-loop poles, grids, jitter margins."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from seactl.analysis.margins import Margins, loop_margins
from seactl.base.parallel import eigvals
from seactl.diagram.blockdiagram import Transfer
from seactl.errors import LoopFileError
from seactl.userloop.loopfile import CompiledLoop, has_loop


def break_margins(compiled: CompiledLoop, design: Any, omega: np.ndarray, signal: str,
                  others: Sequence[str]) -> Margins:
    """Margins of the loop broken at ``signal`` with the ``others`` closed.

    The certified scan of a block-diagram loop counts the closed loop's right-half-plane
    roots from its characteristic quasi-polynomial, so the open loop's right-half-plane
    poles (:func:`_broken_rhp_poles`) are needed only where the loop vanishes (a gain set
    to 0: no crossing, and the closed loop is the open one); they are computed only then,
    since they cost state-space eigenvalues and a stability scan per inner break."""
    diagram = compiled.diagram
    shape = tuple(design.shape)
    cache: dict[str, np.ndarray] = {}  # block responses on the grid, shared by the loops
    loop = diagram.loop(signal)
    zero = _vanishes(loop, design)
    certified = isinstance(loop, Transfer) and loop.kind == "loop"
    P = 0 if certified and not zero.any() else _broken_rhp_poles(compiled, design, omega,
                                                                  signal, others, cache)
    with np.errstate(all="ignore"):
        m = loop_margins(loop, design, omega, open_loop_rhp_poles=P, block_cache=cache)
    if not zero.any():
        return m
    P = np.broadcast_to(np.asarray(P), shape)
    pick = lambda a, v: np.where(zero, v, a)  # noqa: E731
    return replace(m, phase_margin_deg=pick(m.phase_margin_deg, np.inf),
                   crossover_hz=pick(m.crossover_hz, np.nan),
                   gain_margin=pick(m.gain_margin, np.inf),
                   phase_crossover_hz=pick(m.phase_crossover_hz, np.nan),
                   delay_margin_s=pick(m.delay_margin_s, np.where(P == 0, np.inf, 0.0)),
                   stable=pick(m.stable, P == 0), unstable_poles=pick(m.unstable_poles, P))


def _broken_rhp_poles(compiled: CompiledLoop, design: Any, omega: np.ndarray, signal: str,
                      others: Sequence[str], cache: dict[str, np.ndarray]) -> np.ndarray | int:
    """Right-half-plane poles of the system with ``signal`` cut: the poles of the system
    with every break cut (:func:`open_loop_rhp_poles`), then Nyquist closing the
    ``others`` one at a time (inner first), each with the later ones cut; a break that
    closes no loop under the current cuts is skipped."""
    diagram = compiled.diagram
    shape = tuple(design.shape)
    P: np.ndarray | int = open_loop_rhp_poles(compiled, design)
    for i, sig in enumerate(others):
        cut = tuple(sorted(set(others[i + 1:]) | {signal}))
        if has_loop(compiled.edges, sig, cut):
            loop = diagram.loop(sig, cut=cut)
            zero = _vanishes(loop, design)
            with np.errstate(all="ignore"):
                Pn = loop_margins(loop, design, omega, open_loop_rhp_poles=P,
                                  stability_only=True, block_cache=cache).unstable_poles
            P = np.where(zero, np.broadcast_to(P, shape), Pn)
    return P


def open_loop_rhp_poles(compiled: CompiledLoop, design: Any) -> np.ndarray:
    """Right-half-plane poles of the loop with every break cut, per design.

    With every break cut no loop through a controller remains (checked when the loop is
    compiled), so what is left (the physics, a DOB's own loop) has no delay in a loop: its
    poles are the eigenvalues of its state-space realization (the simulator's, with delays
    on loop-free paths dropped since they move no pole).  Poles at the origin (free
    inertias, integrators; within ``max(1e-4, 1e-6 |largest|)`` rad/s of it) are not
    counted; the margin scan counts them."""
    from seactl.simulate.network import assemble_blocks
    from seactl.simulate.realize import realize_continuous

    breaks = set(compiled.breaks_signals)
    blocks = [b for b in compiled.diagram.blocks if b.dst not in breaks]
    shape = tuple(design.shape)
    n = int(np.prod(shape, dtype=int))
    if not blocks:
        return np.zeros(shape, int)
    signals = sorted({b.src for b in blocks} | {b.dst for b in blocks})
    reals = [realize_continuous(b, design, shape, n) for b in blocks]
    if sum(r[0].shape[1] for r in reals) == 0:
        return np.zeros(shape, int)
    net = assemble_blocks(n, signals, blocks, reals, [], {b.name: np.ones(n) for b in blocks}, {})
    if not np.all(np.isfinite(net.A)):
        raise LoopFileError(compiled.file, "values", None, "values whose plant has a finite "
                            "state-space realization (a coefficient ratio overflows: an "
                            "inertia, stiffness or leading coefficient near 0 or 1e308)")
    ev = eigvals(net.A)
    mag = np.abs(ev)
    # A multiple pole at the origin splits numerically (+-1e-7 for a double one): poles
    # within max(1e-4, 1e-6 |largest pole|) rad/s of the origin are taken to be on it.
    origin = mag < np.maximum(1e-4, 1e-6 * mag.max(axis=-1, keepdims=True))
    rhp = (ev.real > 1e-9 * np.maximum(1.0, mag)) & ~origin
    return rhp.sum(axis=-1).reshape(shape)


def _vanishes(loop: Any, design: Any) -> np.ndarray:
    """Per design: the loop transfer is identically zero, i.e. its numerator ``N``
    (``L = N / D``, :meth:`~seactl.diagram.blockdiagram.BlockDiagram.return_difference`) once its
    terms of equal delay are merged: exponentials of distinct delays are independent over
    the polynomials.  (Its coefficients, not the response on a grid: no frequency grid to
    evaluate.)"""
    N = loop.diagram.return_difference(loop.input, loop.cut)[0].evaluate(design).flat()
    same = (N.delays[:, None] == N.delays[None, :]).astype(float)  # (term, term, design)
    merged = np.einsum("jkn,knp->jnp", same, N.coeffs)
    return (merged == 0).all(axis=(0, 2)).reshape(tuple(design.shape))


def _roots_magnitudes(coeffs: Sequence[Any], shape: tuple[int, ...]) -> np.ndarray:
    """Magnitudes of the non-zero roots of a batch of polynomials (companion matrices)."""
    n = int(np.prod(shape, dtype=int))
    C = np.stack([np.broadcast_to(np.asarray(c, float), shape).reshape(n) for c in coeffs], 1)
    out = []
    nz = C != 0
    lead = np.where(nz.any(axis=1), np.argmax(nz, axis=1), C.shape[1])
    for j in np.unique(lead):
        rows = C[lead == j, j:]
        q = rows.shape[1] - 1
        if q < 1:
            continue
        comp = np.zeros((rows.shape[0], q, q))
        with np.errstate(over="ignore"):
            comp[:, 0, :] = -rows[:, 1:] / rows[:, :1]
        comp[:, np.arange(1, q), np.arange(q - 1)] = 1.0
        comp = comp[np.isfinite(comp).all(axis=(1, 2))]  # roots beyond double range: none
        if comp.shape[0]:
            out.append(np.abs(eigvals(comp)).ravel())
    mags = np.concatenate(out) if out else np.empty(0)
    return mags[np.isfinite(mags) & (mags > 1e-12)]


def characteristic_frequencies(compiled: CompiledLoop, design: Any) -> np.ndarray:
    """Every block pole and zero magnitude, and spring resonance estimates
    ``sqrt(k / J_max)``, ``sqrt(2 k / J_min)`` [rad/s], over the batch (finite, > 0)."""
    shape = tuple(design.shape)
    arr = design._arrays
    mags = []
    for e in compiled.edges:
        if e.coeffs is None:
            continue
        for x in "nd":
            k = 0
            coeffs = []
            while f"{e.name}__{x}{k}" in arr:
                coeffs.append(arr[f"{e.name}__{x}{k}"])
                k += 1
            mags.append(_roots_magnitudes(coeffs, shape))
    springs = [arr[f"{b.name}__n0"] for b in compiled.blocks if b.kind == "spring"]
    masses = [arr[f"{b.name}__d0"] for b in compiled.blocks if b.kind in ("inertia", "load")]
    if springs and masses:
        k_all = np.concatenate([np.ravel(np.abs(k)) for k in springs])
        j_all = np.concatenate([np.ravel(np.abs(j)) for j in masses])
        mags.append(np.sqrt([k_all.min() / j_all.max(), 2 * k_all.max() / j_all.min()]))
    allm = np.concatenate(mags) if mags else np.empty(0)
    return allm[np.isfinite(allm) & (allm > 0)]


def characteristic_range(compiled: CompiledLoop, design: Any) -> tuple[float, float]:
    """Slowest and fastest :func:`characteristic_frequencies` [rad/s] (1 to 1000 rad/s when
    there are none: a loop of gains and integrators)."""
    allm = characteristic_frequencies(compiled, design)
    if allm.size == 0:
        return 1.0, 1e3
    return float(allm.min()), float(allm.max())


def jitter_grid(compiled: CompiledLoop, design: Any, omega: np.ndarray,
                per_decade: int = 48, max_marks: int = 4000) -> np.ndarray:
    """The jitter scan's grid: ``omega``'s range at ``per_decade`` points, plus every
    characteristic frequency (and 0.2 % either side) when the batch has at most
    ``max_marks`` of them, so that a lightly damped resonance (a narrow peak of
    ``w |T|``) is not stepped over."""
    n = int(np.ceil(per_decade * np.log10(omega[-1] / omega[0]))) + 1
    w = np.logspace(np.log10(omega[0]), np.log10(omega[-1]), n)
    marks = np.unique(characteristic_frequencies(compiled, design))
    if 0 < marks.size <= max_marks:
        marks = marks[(marks > omega[0]) & (marks < omega[-1])]
        w = np.unique(np.concatenate([w, marks, marks * 0.998, marks * 1.002]))
    return w


def extend_down(loop: Any, design: Any, omega: np.ndarray, max_decades: int = 6
                 ) -> np.ndarray:
    """Prepend decades while some design's loop is below 2 at the grid's bottom and still
    growing towards lower frequencies (an integrating loop may cross 1 further down)."""
    for _ in range(max_decades):
        w0 = omega[0]
        with np.errstate(all="ignore"):  # (a constant loop's response has no axes)
            m = np.broadcast_to(np.abs(loop(design, 1j * np.array([w0 / 10, w0]))),
                                tuple(design.shape) + (2,))
        if not np.any((m[..., 1] < 2) & (m[..., 0] > 1.5 * m[..., 1])):
            break
        omega = np.concatenate([np.logspace(np.log10(w0 / 10), np.log10(w0), 13)[:-1], omega])
    return omega


def jitter_margin(loop: Any, design: Any, omega: np.ndarray) -> np.ndarray:
    """Kao-Lincoln jitter margin ``1 / max_w (w |L/(1+L)|)`` [s] per design, with the
    peak search of :func:`seactl.latency.jitter.peak_omega_t` (the built-in loops' own)."""
    from seactl.latency.jitter import peak_omega_t

    with np.errstate(all="ignore"):
        peak, _ = peak_omega_t(loop, design, omega)
    with np.errstate(divide="ignore"):
        return np.where(peak > 0, 1.0 / peak, np.inf)
