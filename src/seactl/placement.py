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

With a timing spec per process (:class:`ProcessTiming`: a latency
distribution, e.g. measured, and a loss model), each process's latency is its
nominal (smallest) latency plus a time-varying part up to its ``jitter_s``
(the distribution's 99.9 % quantile above the minimum, plus one period per
message of the 99.9 % loss burst, since the receiver holds the last value).
A placement then also needs every loop's jitter margin
(:mod:`seactl.jitter`, every other loop at its nominal delay) above the jitter
of the process running it, and, where stiffness and damping share a process
(their common measurement path), the whole outer loop's margin above it.  The
constraint with the least slack at the optimum is reported as the
``bottleneck``; :func:`seactl.timing.verify_placement` checks the result by
Monte Carlo simulation.

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
from .jitter import model_jitter_margins
from .latency import LoopModel, max_stable_fn
from .timing_models import QUANTILE

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
    jitter_s : with a timing spec, the jitter [s] each loop must tolerate (``stiffness``,
        ``damping``, ``torque``, and ``outer`` when stiffness and damping share a process).
    jitter_margin_s : the jitter margins [s] at ``fn_hz`` (same keys).
    bottleneck : the constraint with the least relative slack at ``fn_hz`` (``phase
        margin`` or ``<loop> jitter``).
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
    jitter_s: dict[str, float] | None = None
    jitter_margin_s: dict[str, float] | None = None
    bottleneck: str | None = None


@dataclass(frozen=True)
class ProcessTiming:
    """Timing of one process's feedback: a latency distribution and message loss.

    Attributes
    ----------
    latency : latency model (:mod:`seactl.timing_models`), seconds.
    loss : loss model or None.
    rate_hz : the process's servo rate [Hz] (a lost message ages the held value by one
        period).
    quantile : upper quantile of unbounded distributions (latency tail, loss bursts).
    """

    latency: Any
    loss: Any = None
    rate_hz: float = 1000.0
    quantile: float = QUANTILE

    @property
    def nominal_s(self) -> float:
        """Smallest latency [s]: the constant part."""
        return float(self.latency.lower_s)

    @property
    def jitter_s(self) -> float:
        """Largest time-varying extra delay [s] (at ``quantile``) above the nominal."""
        burst = self.loss.burst(self.quantile) if self.loss is not None else 0
        return float(self.latency.upper_s(self.quantile) - self.latency.lower_s
                     + burst / self.rate_hz)


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
    timing: dict[str, ProcessTiming] | None = None

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


def _process_of(model: LoopModel, placement: str) -> dict[str, str]:
    """Which process runs each loop in a placement."""
    hi, lo = "high-level", "embedded"
    out = {"stiffness": hi if placement in ("centralized", "distributed") else lo,
           "damping": hi if placement == "centralized" else lo}
    if model.kind == "sea":
        out["torque"] = hi if placement == "centralized" else lo
    return out


def _jitter_needs(model: LoopModel, timing: dict[str, ProcessTiming] | None
                  ) -> list[dict[str, float]] | None:
    """Per placement, the jitter [s] each loop must tolerate (0-free entries only)."""
    if not timing:
        return None
    out = []
    for p in PLACEMENTS:
        proc = _process_of(model, p)
        need = {k: timing[v].jitter_s for k, v in proc.items() if v in timing}
        if proc["stiffness"] == proc["damping"] and "stiffness" in need:
            need["outer"] = need["stiffness"]
        out.append({k: v for k, v in need.items() if v > 0})
    return out


_TAP_OF = {"outer": "overall", "stiffness": "stiffness", "damping": "damping",
           "torque": "torque"}


def _jitter_check(model: LoopModel, needs: list[dict[str, float]]):
    """``extra_ok`` for :func:`~seactl.latency.max_stable_fn`: every loop's jitter margin
    at least the jitter its process has."""
    def ok(design, margins, idx, scan_axis):
        good = np.ones(np.shape(margins.stable), bool)
        if not any(needs):
            return good
        j = model_jitter_margins(model, design, margins)
        for name in ("outer", "stiffness", "damping", "torque"):
            req = np.array([n.get(name, 0.0) for n in needs])[idx]
            if not np.any(req > 0):
                continue
            req = req[:, None] if scan_axis else req
            good &= np.asarray(getattr(j, f"{_TAP_OF[name]}_s")) >= req
        return good
    return ok


def _bottleneck(pm: float | None, min_pm: float, jm: dict[str, float],
                need: dict[str, float]) -> str:
    slack = {"phase margin": (pm / min_pm - 1) if (pm is not None and min_pm > 0)
             else np.inf}
    for k, v in need.items():
        slack[f"{k} jitter"] = jm[k] / v - 1
    return min(slack, key=slack.get)


def evaluate_placements(model: LoopModel, high_latency_s: float, low_latency_s: float,
                        min_pm_deg: float = 45.0,
                        timing: dict[str, ProcessTiming] | None = None
                        ) -> tuple[PlacementOption, ...]:
    """Highest admissible ``f_n`` of every placement (one batched search), with its gains
    and margins (and, with ``timing``, the jitter margins each process's jitter needs)."""
    plan = [_delays(model, p, high_latency_s, low_latency_s) for p in PLACEMENTS]
    ts = np.array([p[0] for p in plan])
    td = np.array([p[1] for p in plan])
    extra = {k: np.array([p[2][k] for p in plan]) for k in plan[0][2]}
    needs = _jitter_needs(model, timing)
    res = max_stable_fn(model, ts, td, min_pm_deg=min_pm_deg, **extra,
                        extra_ok=_jitter_check(model, needs) if needs else None)
    out = []
    for i, placement in enumerate(PLACEMENTS):
        t_inner = float(extra["T_tau"][i]) if "T_tau" in extra else None
        status = str(res.status[i])
        if status == "none":
            out.append(PlacementOption(placement, float(ts[i]), float(td[i]), t_inner, None,
                                       status, {}, None, None, None, None, None,
                                       needs[i] if needs else None))
            continue
        fn = float(res.fn_hz[i])
        d = model.design(fn, ts[i], td[i], **{k: v[i] for k, v in extra.items()})
        m = model.margins(d)
        dm = model.delay_margins(d)
        if model.kind == "rigid":
            gains = {"K": float(d.K), "B": float(d.B)}
        else:
            gains = {k: float(getattr(d, k)) for k in ("Kq", "Bq", "Ktau", "Btau")}
        jm = bottleneck = None
        if needs is not None:
            j = model_jitter_margins(model, d, m)
            jm = {k: float(getattr(j, f"{t}_s")) for k, t in _TAP_OF.items()
                  if getattr(j, f"{t}_s") is not None}
            bottleneck = _bottleneck(_opt(m.phase_margin_deg), min_pm_deg, jm, needs[i])
        out.append(PlacementOption(placement, float(ts[i]), float(td[i]), t_inner, fn, status,
                                   gains, _opt(model.static_stiffness(d)),
                                   _opt(m.phase_margin_deg), _opt(m.crossover_hz),
                                   _opt(dm.stiffness_s), _opt(dm.damping_s),
                                   needs[i] if needs else None, jm, bottleneck))
    return tuple(out)


def advise(model: LoopModel, high_latency_s: float, low_latency_s: float, *,
           min_pm_deg: float = 45.0, stiffness_embeddable: bool = False,
           timing: dict[str, ProcessTiming] | None = None) -> Advice:
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
    timing : dict, optional
        ``"high-level"`` and/or ``"embedded"`` -> :class:`ProcessTiming`; its nominal
        latency replaces ``high_latency_s`` / ``low_latency_s`` and its jitter must stay
        within the jitter margins.

    The recommendation is the allowed placement with the highest admissible
    ``f_n`` (ties within :data:`TIE_RTOL` favour more work on the high-level
    process); ``None`` when no allowed placement admits any ``f_n``.
    """
    timing, high_latency_s, low_latency_s = _nominal(timing, high_latency_s, low_latency_s)
    high = float(finite_array("high latency [s]", high_latency_s, minimum=0.0))
    low = float(finite_array("low latency [s]", low_latency_s, minimum=0.0))
    pm = float(finite_array("min phase margin [deg]", min_pm_deg, minimum=0.0))
    if pm >= 180:
        from .errors import InputError

        raise InputError("min phase margin [deg]", pm, "< 180")
    options = evaluate_placements(model, high, low, pm, timing)
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
    if timing and best is not None and best.bottleneck:
        reason += (f" With the processes' jitter, the bottleneck at the recommended f_n is the "
                   f"{best.bottleneck}" + _jitter_text(best) + ".")
    return Advice(model.name, model.kind, high, low, pm, stiffness_embeddable,
                  model.stiffness_unit, options, None if best is None else best.placement,
                  gain, frac, reason, timing)


def _jitter_text(o: PlacementOption) -> str:
    parts = [f"{k} {o.jitter_margin_s[k] * 1e3:.3g} ms for {v * 1e3:.3g} ms of jitter"
             for k, v in (o.jitter_s or {}).items()]
    return (" (jitter margins: " + "; ".join(parts) + ")") if parts else ""


def _nominal(timing: dict[str, ProcessTiming] | None, high_s: float, low_s: float
             ) -> tuple[dict[str, ProcessTiming] | None, float, float]:
    """Drop empty entries; the processes' nominal latencies replace the constant ones."""
    timing = {k: v for k, v in (timing or {}).items() if v is not None} or None
    for key in timing or {}:
        if key not in ("high-level", "embedded"):
            from .errors import InputError

            raise InputError("timing", key, "'high-level' or 'embedded'")
    if timing and "high-level" in timing:
        high_s = timing["high-level"].nominal_s
    if timing and "embedded" in timing:
        low_s = timing["embedded"].nominal_s
    return timing, high_s, low_s


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
