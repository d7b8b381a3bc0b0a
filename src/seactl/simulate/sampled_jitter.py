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

``g`` is scanned, not proven: 1200 log-spaced points of ``theta`` up to Nyquist, every
local maximum within half of the largest refined by three zooms; the alias sum takes
``|k| <= ALIAS_TERMS`` terms and bounds the rest by the decay ``|P_y| ~ |w|^-r`` seen at
its end.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import BlockDiagram, DesignSubset
from seactl.errors import InputError
from seactl.simulate.sampled import FREQUENCIES, broken_responses, rate_text, sampled_roots

__all__ = ["ALIAS_TERMS", "SampledJitter", "alias_sum", "plant_path", "jitter_samples",
           "sampled_jitter_margins", "actuation_signal"]

ALIAS_TERMS = 64
"""Aliases ``k = -64 .. 64`` summed exactly; the rest is bounded from their decay."""


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


def alias_sum(plant: Any, design: Any, theta: np.ndarray, period_s: float) -> np.ndarray:
    """``sum_k |P(j (theta + 2 pi k) / h)|^2`` over every integer ``k`` for a flat batch
    (``theta`` of shape ``(n, F)``): ``|k| <= ALIAS_TERMS`` exactly, the two tails as
    ``|P_K|^2 K / (2r - 1)`` with ``r`` the decay exponent between ``K/2`` and ``K``
    (``inf`` where ``|P|`` does not decay faster than ``|w|^-0.75``)."""
    K = ALIAS_TERMS
    k = np.arange(-K, K + 1)
    s = 1j * (theta[..., None] + 2 * np.pi * k) / period_s
    P = np.abs(np.broadcast_to(plant(design, s.reshape(theta.shape[0], -1)),
                               (theta.shape[0], s[0].size)).reshape(s.shape))
    total = np.sum(P**2, axis=-1)
    for end, half in ((0, K // 2), (-1, -K // 2 - 1)):
        ratio = np.abs(s[..., end] / s[..., half])
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.log(P[..., half] / P[..., end]) / np.log(ratio)
            tail = P[..., end] ** 2 * K / (2 * r - 1)
        total = total + np.where(r > 0.75, tail, np.where(P[..., end] == 0, 0.0, np.inf))
    return total


def _gain(respond: Any, plant: Any, design: Any, rows: np.ndarray, theta: np.ndarray,
          period_s: float) -> np.ndarray:
    """``|z - 1| |G/(1 + L)| P_alias`` on ``theta`` (rows of the flat batch)."""
    L, G = respond(rows, theta)
    alias = alias_sum(plant, design.take(rows), theta, period_s)
    with np.errstate(all="ignore"):
        g = np.abs(np.exp(1j * theta) - 1) * np.abs(G / (1 + L)) * np.sqrt(alias)
    return np.where(np.isnan(g), np.inf, g)


class _Flat:
    """A design batch seen flat, with row subsets (``take``)."""

    def __init__(self, design: Any, shape: tuple[int, ...]):
        self.design, self.shape = design, shape

    def take(self, rows: np.ndarray) -> Any:
        return DesignSubset(self.design, np.asarray(rows, np.intp), self.shape)


def _peak(respond: Any, plant: Any, flat: _Flat, n: int, period_s: float,
          theta_lo: np.ndarray, passes: int = 3, points: int = 9
          ) -> tuple[np.ndarray, np.ndarray]:
    """Largest ``g(theta)`` over ``(0, pi]`` per design and where: the log-spaced scan, then
    every local maximum within half of the largest zoomed ``passes`` times on ``points``
    sub-points (each zoom keeps the two intervals around its best point)."""
    u = np.linspace(0.0, 1.0, FREQUENCIES)
    lo = np.minimum(theta_lo, 1e-3 * np.pi)[:, None]
    theta = lo * (np.pi / lo) ** u
    theta[:, -1] = np.pi
    rows = np.arange(n)
    g = _gain(respond, plant, flat, rows, theta, period_s)
    best = np.argmax(g, axis=1)
    peak, where = g[rows, best], theta[rows, best]
    gi = g[:, 1:-1]
    b, i = np.nonzero((gi >= g[:, :-2]) & (gi >= g[:, 2:]) & (gi >= 0.5 * peak[:, None])
                      & np.isfinite(gi))
    if b.size:
        a, c = np.log(theta[b, i]), np.log(theta[b, i + 2])
        frac = np.linspace(0.0, 1.0, points)
        sub = np.arange(b.size)
        for _ in range(passes):
            x = a[:, None] + (c - a)[:, None] * frac
            fx = _gain(respond, plant, flat, b, np.exp(x), period_s)
            k = np.clip(np.argmax(fx, axis=1), 1, points - 2)
            a, c = x[sub, k - 1], x[sub, k + 1]
            top, wtop = fx[sub, np.argmax(fx, axis=1)], np.exp(x[sub, np.argmax(fx, axis=1)])
            order = np.argsort(top)   # ascending: the largest per design is written last
            up = order[top[order] > peak[b[order]]]
            peak[b[up]], where[b[up]] = top[up], wtop[up]
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
    peak : loop -> ``g`` (dimensionless).
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

    ``w_ref`` [rad/s] sets the scan's low end (a hundredth of it).  A multi-rate loop is
    refused: it is periodic, so the frequency-domain bound does not apply.

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
    w = np.broadcast_to(np.asarray(w_ref, float), shape).reshape(n)
    flat = _Flat(design, shape)
    out: dict[str, dict[str, np.ndarray]] = {"margin_s": {}, "samples": {}, "peak": {},
                                             "peak_hz": {}}
    T = roots.period_s
    for name, tap in taps.items():
        plant = plant_path(diagram, design, tap).transfer(tap, act)
        respond, T = broken_responses(diagram, design, tap, rates_hz, act)
        peak, theta = _peak(respond, plant, flat, n, T, w * T / 100)
        N = np.where(count == 0, jitter_samples(peak), np.where(count > 0, 0.0, np.nan))
        for key, v in (("margin_s", N * T), ("samples", N), ("peak", peak),
                       ("peak_hz", theta / (2 * np.pi * T))):
            out[key][name] = v.reshape(shape)
    return SampledJitter(out["margin_s"], out["samples"], out["peak"], out["peak_hz"],
                         roots.unstable_modes, dict(roots.rates_hz), T)
