"""Loop-placement advisor: which process should run the stiffness and damping loops?

Given the latency of the high-level (centralized) process and of the embedded
process, :func:`advise` finds, for each placement,

* ``centralized``: every feedback loop on the high-level process (for the SEA
  this includes the torque loop);
* ``distributed``: stiffness on the high-level process, damping (and the SEA
  torque loop) embedded, the paper's proposal;
* ``embedded``: every loop on the embedded process,

the highest critically-damped ``f_n`` whose closed loop is stable with at
least ``min_pm_deg`` of phase margin (every lower ``f_n`` too), with its gains
and closed-loop static stiffness.  The stiffness loop usually needs the
high-level process (task-space impedance uses the global model), so by default
the recommendation is made between ``centralized`` and ``distributed``, and
``embedded`` is reported as the upper bound; ``stiffness_embeddable=True``
lets it compete.

Examples
--------
>>> from seactl.latency import rigid_model
>>> a = advise(rigid_model(), 22e-3, 0.5e-3)
>>> a.recommended
'distributed'
>>> round(a.option("distributed").fn_hz, 1), round(a.option("centralized").fn_hz, 2)
(14.9, 2.33)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validate import finite_array
from .latency import LoopModel, max_stable_fn

PLACEMENTS = ("centralized", "distributed", "embedded")
"""From most to least work on the high-level process (ties favour the earlier)."""

TIE_RTOL = 0.01
"""Achievable f_n within this relative distance count as equal."""


@dataclass(frozen=True)
class PlacementOption:
    """What one placement achieves.

    Attributes
    ----------
    placement : one of :data:`PLACEMENTS`.
    T_s, T_d, T_inner : stiffness, damping and (SEA) torque-loop delays [s].
    fn_hz : highest admissible ``f_n`` [Hz]; None when even the lowest ``f_n``
        scanned fails (``status == "none"``).
    status : ``"ok"``, ``"none"`` or ``"capped"`` (admissible up to the scan limit).
    gains : the gains at ``fn_hz`` (model units, SI).
    static_stiffness : closed-loop stiffness near zero frequency (``stiffness_unit``).
    phase_margin_deg, crossover_hz : whole-loop margin at ``fn_hz``.
    stiffness_dm_s, damping_dm_s : extra latency each loop alone still tolerates [s].
    """

    placement: str
    T_s: float
    T_d: float
    T_inner: float | None
    fn_hz: float | None
    status: str
    gains: dict[str, float]
    static_stiffness: float | None
    phase_margin_deg: float | None
    crossover_hz: float | None
    stiffness_dm_s: float | None
    damping_dm_s: float | None


@dataclass(frozen=True)
class Advice:
    """The advisor's answer (see :func:`advise`)."""

    actuator: str
    kind: str
    high_latency_s: float
    low_latency_s: float
    min_pm_deg: float
    stiffness_embeddable: bool
    stiffness_unit: str
    options: tuple[PlacementOption, ...]
    recommended: str | None
    stiffness_gain_vs_centralized: float | None
    fraction_of_embedded: float | None
    reason: str

    def option(self, placement: str) -> PlacementOption:
        return next(o for o in self.options if o.placement == placement)


def _delays(model: LoopModel, placement: str, high: float, low: float
            ) -> tuple[float, float, dict[str, Any]]:
    """Stiffness delay, damping delay and design overrides of a placement."""
    ts = high if placement in ("centralized", "distributed") else low
    td = high if placement == "centralized" else low
    extra = {}
    if model.kind == "sea":
        extra["T_tau"] = high if placement == "centralized" else low
    return ts, td, extra


def _opt(x: Any) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def evaluate_placements(model: LoopModel, high_latency_s: float, low_latency_s: float,
                        min_pm_deg: float = 45.0) -> tuple[PlacementOption, ...]:
    """Highest admissible ``f_n`` of every placement (one batched search), with its gains
    and margins."""
    plan = [_delays(model, p, high_latency_s, low_latency_s) for p in PLACEMENTS]
    ts = np.array([p[0] for p in plan])
    td = np.array([p[1] for p in plan])
    extra = {k: np.array([p[2][k] for p in plan]) for k in plan[0][2]}
    res = max_stable_fn(model, ts, td, min_pm_deg=min_pm_deg, **extra)
    out = []
    for i, placement in enumerate(PLACEMENTS):
        t_inner = float(extra["T_tau"][i]) if "T_tau" in extra else None
        status = str(res.status[i])
        if status == "none":
            out.append(PlacementOption(placement, float(ts[i]), float(td[i]), t_inner, None,
                                       status, {}, None, None, None, None, None))
            continue
        fn = float(res.fn_hz[i])
        d = model.design(fn, ts[i], td[i], **{k: v[i] for k, v in extra.items()})
        m = model.margins(d)
        dm = model.delay_margins(d)
        if model.kind == "rigid":
            gains = {"K": float(d.K), "B": float(d.B)}
        else:
            gains = {k: float(getattr(d, k)) for k in ("Kq", "Bq", "Ktau", "Btau")}
        out.append(PlacementOption(placement, float(ts[i]), float(td[i]), t_inner, fn, status,
                                   gains, _opt(model.static_stiffness(d)),
                                   _opt(m.phase_margin_deg), _opt(m.crossover_hz),
                                   _opt(dm.stiffness_s), _opt(dm.damping_s)))
    return tuple(out)


def advise(model: LoopModel, high_latency_s: float, low_latency_s: float, *,
           min_pm_deg: float = 45.0, stiffness_embeddable: bool = False) -> Advice:
    """Compare the three placements and recommend one.

    Parameters
    ----------
    model : LoopModel
        :func:`~seactl.latency.rigid_model` or :func:`~seactl.latency.sea_model`.
    high_latency_s, low_latency_s : float
        Feedback latency of the high-level and of the embedded process [s].
    min_pm_deg : float
        Required whole-loop phase margin [deg].
    stiffness_embeddable : bool
        Whether the stiffness loop may run embedded (otherwise ``embedded`` is only
        reported as the upper bound).

    The recommendation is the allowed placement with the highest admissible
    ``f_n`` (ties within :data:`TIE_RTOL` favour more work on the high-level
    process); ``None`` when no allowed placement admits any ``f_n``.
    """
    high = float(finite_array("high latency [s]", high_latency_s, minimum=0.0))
    low = float(finite_array("low latency [s]", low_latency_s, minimum=0.0))
    pm = float(finite_array("min phase margin [deg]", min_pm_deg, minimum=0.0))
    if pm >= 180:
        from .errors import InputError

        raise InputError("min phase margin [deg]", pm, "< 180")
    options = evaluate_placements(model, high, low, pm)
    allowed = [o for o in options if stiffness_embeddable or o.placement != "embedded"]
    feasible = [o for o in allowed if o.fn_hz is not None]
    best = None
    for o in feasible:   # in PLACEMENTS order: strictly better by more than TIE_RTOL wins
        if best is None or o.fn_hz > best.fn_hz * (1 + TIE_RTOL):
            best = o
    cen, emb = options[0], options[2]
    gain = frac = None
    if best is not None and cen.static_stiffness and best.static_stiffness:
        gain = best.static_stiffness / cen.static_stiffness
    if best is not None and emb.static_stiffness and best.static_stiffness:
        frac = best.static_stiffness / emb.static_stiffness
    reason = _reason(model, options, best, gain, frac, high, low, pm, stiffness_embeddable)
    return Advice(model.name, model.kind, high, low, pm, stiffness_embeddable,
                  model.stiffness_unit, options, None if best is None else best.placement,
                  gain, frac, reason)


def _reason(model, options, best, gain, frac, high, low, pm, embeddable) -> str:
    cen, dist, emb = options
    unit = model.stiffness_unit

    def desc(o: PlacementOption) -> str:
        if o.fn_hz is None:
            return f"{o.placement}: no f_n keeps the loop stable with PM >= {pm:g} deg"
        cap = " (scan limit)" if o.status == "capped" else ""
        return (f"{o.placement}: f_n up to {o.fn_hz:.3g} Hz{cap}, static stiffness "
                f"{o.static_stiffness:.4g} {unit}")

    lines = [desc(o) for o in options]
    if best is None:
        return f"No allowed placement reaches PM >= {pm:g} deg at any f_n. " + "; ".join(lines)
    text = (f"Recommended: {best.placement} (high-level latency {high * 1e3:g} ms, embedded "
            f"{low * 1e3:g} ms, PM >= {pm:g} deg). ")
    if best.placement != "centralized":
        if cen.fn_hz is None:
            text += "The centralized loop cannot meet the margin at any f_n. "
        else:
            text += (f"It raises the achievable stiffness {gain:.3g}x over all-centralized "
                     f"(f_n {cen.fn_hz:.3g} -> {best.fn_hz:.3g} Hz). ")
    else:
        text += "Moving the damping loop to the embedded process gains nothing here. "
    if frac is not None and not embeddable:
        text += (f"It reaches {100 * frac:.3g}% of the stiffness of running every loop "
                 "embedded (the upper bound, if the stiffness loop could leave the "
                 "high-level process). ")
    if dist.stiffness_dm_s is not None and dist.damping_dm_s is not None:
        text += (f"At the distributed optimum the stiffness loop tolerates "
                 f"{dist.stiffness_dm_s * 1e3:.3g} ms more latency, the damping loop "
                 f"{dist.damping_dm_s * 1e3:.3g} ms. ")
    return text + "Details: " + "; ".join(lines) + "."
