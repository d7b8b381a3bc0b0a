"""Jitter margin of the sampled loop: a continuous-time delay varying in ``[0, J]``.

The loop is the one ``step(mode="sampled")`` runs at one rate ``1/h`` (Tustin controllers,
whole-sample delay buffers, the continuous plant ``P`` under a zero-order hold).  At a
loop's break (a measurement tap fed, through unit sensor blocks, by a plant signal ``y``)
the sample the controller reads is taken late by ``d_k`` in ``[0, J]``, varying from
sample to sample: ``y(t_k - d_k)`` instead of ``y(t_k)``.  With ``z = e^{j theta}``,
``theta = w h``, the loop is guaranteed stable if

    ``sqrt(N ceil(N)) g < 1``,   ``g = max_theta |z - 1| |M(z)| P_alias(theta)``,
    ``J = N h``,

where ``M = G / (1 + L)`` is the discrete transfer from an additive error at the tap to
the actuation ``u`` (every loop closed; ``L`` the loop transfer at the break, ``G`` the
open path tap -> ``u``) and ``P_alias(theta)^2 = sum_k |P_y(j (theta + 2 pi k) / h)|^2``
aliases the continuous plant from ``u`` to ``y``.  This is the sampled-data small-gain
argument of Kao and Lincoln (2004) and Cervin et al. (2004, "The jitter margin and its
application in the design of real-time control systems", RTCSA; there the delay is on the
actuation, which for a single-loop controller gives the same ``g``).  Its derivation,
the ``sqrt(N ceil(N))`` factor (equal to ``N`` at whole samples, where it is the published
``N g < 1``) and the limit ``J -> 1 / max_w w |T(jw)|`` as ``h -> 0`` are in
docs/theory/sampled-jitter.md.

``g`` is computed exactly, not scanned: ``|z - 1| P_alias`` is ``||W(z)||`` for a
rational row ``W`` in closed form (the alias series summed by Parseval, no truncation;
the integrator's pole at ``z = 1`` cancelled; :mod:`seactl.simulate.alias`), so
``g(theta) = ||M(z) W(z)||`` on the unit circle with ``M W`` a stable discrete-time
system, and ``g``'s maximum is its H-infinity norm, bracketed by level sets
(:func:`seactl.certify.hinf.discrete_peak`: a level with no crossing of the circle is an
upper bound) to a relative ``2 PEAK_RTOL``, more only where rounding made a level look
crossed.  The reported ``g`` is the upper end: the margin computed from it is never
above the one the exact ``g`` gives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.certify.hinf import discrete_gain, discrete_peak
from seactl.diagram.blockdiagram import BlockDiagram
from seactl.errors import InputError
from seactl.simulate.alias import alias_factor, plant_realization
from seactl.simulate.discrete import compile_sampled
from seactl.simulate.period import period_map
from seactl.simulate.sampled import broken, broken_responses, rate_text, sampled_roots

__all__ = ["PEAK_RTOL", "SampledJitter", "gain_system", "plant_path", "jitter_samples",
           "sampled_jitter_margins", "actuation_signal"]

PEAK_RTOL = 1e-9
"""The reported ``g`` is an upper bound of the true one, within about ``2 PEAK_RTOL``."""


def actuation_signal(diagram: BlockDiagram) -> str:
    """The one signal a controller block sends to the plant (the held actuation)."""
    ctrl = {b.dst for b in diagram.blocks if b.role != "plant"}
    acts = sorted({b.src for b in diagram.blocks if b.role == "plant" and b.src in ctrl})
    if len(acts) != 1:
        raise InputError("diagram", diagram.name, "a loop with one actuation signal (has "
                         + (", ".join(acts) or "none") + ")")
    return acts[0]


def plant_path(diagram: BlockDiagram, design: Any, tap: str) -> BlockDiagram:
    """The plant blocks and the chain of static sensor blocks (no delay, no dynamics) that
    carries a plant signal to ``tap``: the continuous path from the actuation to the tap.
    Refuses any other tap: jitter there is not on when the plant is sampled."""
    plant = [b for b in diagram.blocks if b.role == "plant"]
    plant_out = {b.dst for b in plant}
    chain, sig = [], tap
    while sig not in plant_out:
        feeding = [b for b in diagram.blocks if b.dst == sig]
        static = len(feeding) == 1 and feeding[0].delay is None and all(
            len(c) == 1 for c in feeding[0].coefficients(design))
        if not static:
            raise InputError("tap", tap, "a plant signal seen through static sensor blocks")
        chain.append(feeding[0])
        sig = feeding[0].src
    return BlockDiagram(f"{diagram.name}-plant-{tap}", plant + chain)


def _closed_loop(plan: Any, row: int, inj: str, ret: str, act: str
                 ) -> tuple[np.ndarray, ...]:
    """``M = G / (1 + L)`` of one design as a state space: the broken loop's one-tick map
    (injection -> return and -> actuation) closed by ``injected = returned + e``."""
    A, B, C, D, _ = period_map(plan, slice(row, row + 1), True)
    col = plan.info["controller_inputs"].index(inj)
    ir, ia = plan.order.index(ret), plan.order.index(act)
    A, B, C, D = A[0], B[0][:, col:col + 1], C[0], D[0][:, col:col + 1]
    k = 1.0 / (1.0 - D[ir, 0])
    Cr, Ca = C[ir:ir + 1], C[ia:ia + 1]
    return A + k * B @ Cr, k * B, Ca + k * D[ia, 0] * Cr, k * D[ia:ia + 1]


def gain_system(M: tuple[np.ndarray, ...], W: tuple[np.ndarray, ...]
                ) -> tuple[np.ndarray, ...]:
    """``F = M W`` in series (``W`` a row: its inputs are ``F``'s), so that
    ``||F(e^{j theta})|| = g(theta)`` when ``||W||^2 = |z - 1|^2 P_alias^2``."""
    Am, Bm, Cm, Dm = M
    Aw, Bw, Cw, Dw = W
    A = np.block([[Aw, np.zeros((Aw.shape[0], Am.shape[0]))], [Bm @ Cw, Am]])
    return A, np.vstack([Bw, Bm @ Dw]), np.hstack([Dm @ Cw, Cm]), Dm @ Dw


def _peak(plan: Any, names: tuple[str, str, str], plant: tuple[np.ndarray, ...],
          period_s: float, rows: np.ndarray, start: np.ndarray, respond: Any
          ) -> tuple[np.ndarray, np.ndarray]:
    """Per design, an upper bound of ``g`` over ``0 < theta <= pi`` (above it by at most a
    relative ``2 PEAK_RTOL``) and where ``g`` comes that close: NaN outside ``rows`` (the
    designs whose map is stable: the level-set test needs it), inf where the plant has a
    feedthrough to the tap (the alias series diverges)."""
    peak, where = np.full(start.size, np.nan), np.full(start.size, np.nan)
    Ap, Bp, Cp, Dp = plant
    for i in rows:
        if Dp[i, 0, 0] != 0.0:
            peak[i], where[i] = np.inf, np.pi
            continue
        W = alias_factor(Ap[i], Bp[i], Cp[i], period_s)
        F = gain_system(_closed_loop(plan, int(i), *names), W)

        def gain(theta, i=i, W=W):   # |M| from the folded registers, ||W|| small
            L, G = respond(np.array([i]), theta[None, :])
            return np.abs(G[0] / (1 + L[0])) * discrete_gain(*W, theta)

        peak[i], where[i], _ = discrete_peak(*F, rtol=PEAK_RTOL, start=start[i:i + 1],
                                             gain=gain)
    return peak, where


def jitter_samples(peak: Any) -> np.ndarray:
    """The largest ``N`` with ``sqrt(N ceil(N)) peak <= 1``: with ``x = 1/peak``,
    ``max(floor(x), x^2 / (floor(x) + 1))`` (``x`` itself at whole ``x``; within one
    sample below ``x`` from ``x >= 1``; ``x^2`` below one sample); ``inf`` for ``peak = 0``.

    Examples
    --------
    >>> jitter_samples([0.25, 0.3, 2.0]).tolist()
    [4.0, 3.0, 0.25]
    """
    with np.errstate(divide="ignore"):
        x = 1.0 / np.asarray(peak, float)
    f = np.floor(x)
    with np.errstate(invalid="ignore"):
        return np.where(np.isinf(x), np.inf, np.maximum(f, x**2 / (f + 1)))


@dataclass(frozen=True)
class SampledJitter:
    """Jitter margins of the sampled loop per named loop (arrays of the batch shape).

    Attributes
    ----------
    margin_s : loop -> ``J = N h`` [s] (0 where the sampled loop is unstable, NaN where its
        verdict is uncertain).
    samples : loop -> ``N`` (real; :func:`jitter_samples`).
    peak : loop -> ``g`` (dimensionless; an upper bound, about ``2e-9`` above; NaN
        where the sampled map is not stable).
    peak_hz : loop -> where ``g`` peaks [Hz].
    unstable_modes : the certified verdict of the sampled loop (-1: uncertain).
    rates_hz, period_s : the process rates and the sampling period [s].
    """

    margin_s: dict[str, np.ndarray]
    samples: dict[str, np.ndarray]
    peak: dict[str, np.ndarray]
    peak_hz: dict[str, np.ndarray]
    unstable_modes: np.ndarray
    rates_hz: dict[str, float]
    period_s: float

    @property
    def stable(self) -> np.ndarray:
        return np.asarray(self.unstable_modes) == 0


def sampled_jitter_margins(diagram: BlockDiagram, design: Any, taps: Mapping[str, str],
                           rates_hz: Any, w_ref: Any) -> SampledJitter:
    """Jitter margins of the sampled loop broken at each tap (loop name -> signal).

    ``w_ref`` [rad/s] (the loop's bandwidth) is where the peak's search evaluates first.
    A multi-rate loop is refused: it is periodic, so the frequency-domain bound does not
    apply.

    Examples
    --------
    >>> import numpy as np
    >>> from seactl.systems.rigid.model import RIGID_DIAGRAM
    >>> import seactl as sc
    >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
    >>> j = sampled_jitter_margins(RIGID_DIAGRAM, r.rigid, {"overall": "x_sens"}, 4000.0,
    ...                            2 * np.pi * 8)
    >>> bool(j.stable), round(float(j.margin_s["overall"]) * 1e3, 1)
    (True, 7.2)
    """
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    roots = sampled_roots(diagram, design, rates_hz)
    if len(set(roots.rates_hz.values())) > 1:
        raise InputError("rate_hz", rate_text(roots.rates_hz), "one rate for every process "
                         "(a multi-rate loop is periodic: the jitter margin's frequency-"
                         "domain bound does not apply)")
    act = actuation_signal(diagram)
    count = roots.unstable_modes.reshape(n)
    # the bound needs a stable map: certified, or (verdict uncertain) computed inside
    stable = np.flatnonzero((count == 0) | ((count < 0)
                                            & (roots.spectral_radius.reshape(n) < 1)))
    w = np.broadcast_to(np.asarray(w_ref, float), shape).reshape(n)
    out: dict[str, dict[str, np.ndarray]] = {"margin_s": {}, "samples": {}, "peak": {},
                                             "peak_hz": {}}
    T = roots.period_s
    for name, tap in taps.items():
        plant = plant_realization(plant_path(diagram, design, tap), design, tap, act)
        cut, inj, ret = broken(diagram, tap)
        plan = compile_sampled(cut, design, {}, 1e-6, (ret, act),
                               rates_hz=dict(roots.rates_hz))
        respond, _ = broken_responses(diagram, design, tap, rates_hz, act)
        peak, theta = _peak(plan, (inj, ret, act), plant, T, stable, w * T, respond)
        N = np.where(count == 0, jitter_samples(peak), np.where(count > 0, 0.0, np.nan))
        for key, v in (("margin_s", N * T), ("samples", N), ("peak", peak),
                       ("peak_hz", theta / (2 * np.pi * T))):
            out[key][name] = v.reshape(shape)
    return SampledJitter(out["margin_s"], out["samples"], out["peak"], out["peak_hz"],
                         roots.unstable_modes, dict(roots.rates_hz), T)
