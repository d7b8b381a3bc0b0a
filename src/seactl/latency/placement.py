"""Loop-placement advisor: which process should run the stiffness and damping loops?

Given the latency of the high-level (centralized) process and of the embedded
process, :func:`advise` finds, for each placement,

* ``centralized``: every feedback loop on the high-level process (for the SEA
  this includes the torque loop);
* ``distributed``: stiffness on the high-level process, damping (and the SEA
  torque loop) embedded, the paper's proposal;
* ``embedded``: every loop on the embedded process,

its **latency-robust f_n** (:mod:`seactl.latency.box`): the largest critically-damped
``f_n`` such that at every ``f_n`` up to it and at every combination of loop latencies
from zero to ``(1 + latency_margin)`` times the latency the placement gives each loop,
the closed loop is stable with at least ``min_pm_deg`` of phase margin.  Placements are
ranked by that score, which no latency increase on any loop can raise: the phase margin
at the nominal latencies alone can (on the rigid actuator a longer stiffness delay raises
it while that loop's delay margin falls), so it is not the ranking.  With the embedded
latency at most the high-level one, every latency box of ``embedded`` lies inside that
of ``distributed``, and that inside ``centralized``'s: ``embedded`` scores at least as
high as the others, and is called the upper bound only where its score shows it
(:func:`upper_bound`; with a timing spec the processes' jitter differs between
placements).  The stiffness loop usually needs the high-level process (task-space
impedance uses the global model), so by default the recommendation is made between
``centralized`` and ``distributed``; ``stiffness_embeddable=True`` lets ``embedded``
compete.

With a timing spec per process (:class:`ProcessTiming`: a latency distribution, e.g.
measured, and a loss model), each process's latency is its nominal (smallest) latency plus
a time-varying part up to its ``jitter_s`` (the distribution's 99.9 % quantile above the
minimum, plus one period per message of the 99.9 % loss burst, since the receiver holds
the last value).  The same score then also needs, at every latency combination of the
box, every loop's jitter margin (:mod:`seactl.latency.jitter`) above the jitter of the process
running it, and, where stiffness and damping share a process (their common measurement
path), the whole outer loop's margin above it.  The constraint that fails just above the
score, and the latencies where it fails, are reported as the ``bottleneck``;
:func:`seactl.latency.montecarlo.verify_placement` checks the result by Monte Carlo simulation.

Examples
--------
>>> from seactl.latency.maps import rigid_model
>>> a = advise(rigid_model(), 22e-3, 0.5e-3)
>>> a.recommended
'distributed'
>>> round(a.option("distributed").fn_hz, 1), round(a.option("centralized").fn_hz, 2)
(9.1, 1.7)
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from seactl.base import progress
from seactl.base.validate import finite_array
from seactl.latency.box import CHUNK_DESIGNS, SECONDS_PER_POINT, RobustFn, box_size, robust_max_fn
from seactl.latency.jitter import model_jitter_margins
from seactl.latency.maps import LoopModel
from seactl.latency.models import QUANTILE

PLACEMENTS = ("centralized", "distributed", "embedded")
"""From most to least work on the high-level process (ties favour the earlier)."""

TIE_RTOL = 0.01
"""Achievable f_n within this relative distance count as equal."""

LATENCY_MARGIN = 0.5
"""Default fraction of its latency each loop must tolerate on top of it."""
GAIN_UNITS = {"K": "N/m", "B": "N s/m", "Kq": "N m/rad", "Bq": "N m s/rad",
              "Ktau": "A/(N m)", "Btau": "A s/(N m)"}
"""Unit of each gain in :attr:`PlacementOption.gains`."""
MAX_LATENCY_MARGIN = 10.0
"""Largest accepted ``latency_margin`` (the box grows with it, and so does the work)."""


def criterion_text(min_pm_deg: float, latency_margin: float, jitter: bool = False) -> str:
    """The ranking criterion in words (printed with every answer)."""
    return ("score = the largest f_n such that at every f_n up to it the closed loop is "
            f"stable with PM >= {min_pm_deg:g} deg for every combination of loop latencies "
            f"from 0 to {1 + latency_margin:g} x the latency each loop gets (checked on a "
            "latency lattice, 4 points per doubling, upper end rounded up)"
            + (", and every loop's jitter margin covers its process's jitter there"
               if jitter else "")
            + "; a longer latency on any loop never raises it")


@dataclass(frozen=True)
class PlacementOption:
    """What one placement achieves.

    Attributes
    ----------
    placement : one of :data:`PLACEMENTS`.
    T_s, T_d, T_inner : stiffness, damping and (SEA) torque-loop delays [s].
    fn_hz : the placement's score, its latency-robust ``f_n`` [Hz]
        (:mod:`seactl.latency.box`); None when even the lowest ``f_n`` fails
        (``status == "none"``).
    status : ``"ok"``, ``"none"`` or ``"capped"`` (admissible up to the scan limit).
    gains : the gains at ``fn_hz`` (model units, SI).
    static_stiffness : closed-loop stiffness near zero frequency (``stiffness_unit``).
    phase_margin_deg, crossover_hz : whole-loop margin at ``fn_hz`` and the nominal
        latencies.
    stiffness_dm_s, damping_dm_s : extra latency each loop alone still tolerates at the
        nominal latencies [s].
    jitter_s : with a timing spec, the jitter [s] each loop must tolerate (``stiffness``,
        ``damping``, ``torque``, and ``outer`` when stiffness and damping share a process).
    jitter_margin_s : the jitter margins [s] at ``fn_hz`` and the nominal latencies.
    bottleneck : the constraint that fails just above ``fn_hz`` (``unstable``, ``phase
        margin`` or ``<loop> jitter``) and the latencies where it does.
    box_upper_s : the longest latency checked on each loop (``T_s``, ``T_d``, ``T_tau``) [s].
    limit : the failing constraint as data (``constraint``, ``latencies_s``, ``fn_hz``).
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
    box_upper_s: dict[str, float] | None = None
    limit: dict[str, Any] | None = None


@dataclass(frozen=True)
class ProcessTiming:
    """Timing of one process's feedback: a latency distribution and message loss.

    Attributes
    ----------
    latency : latency model (:mod:`seactl.latency.models`), seconds.
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
    latency_margin: float = LATENCY_MARGIN
    criterion: str = ""

    def option(self, placement: str) -> PlacementOption:
        return next(o for o in self.options if o.placement == placement)


def placement_latencies(model: LoopModel, placement: str, high: float, low: float
                        ) -> dict[str, float]:
    """The latency [s] each loop gets in a placement: ``T_s``, ``T_d`` (and ``T_tau``)."""
    proc = process_of(model, placement)
    lat = {"high-level": high, "embedded": low}
    out = {"T_s": lat[proc["stiffness"]], "T_d": lat[proc["damping"]]}
    if model.kind == "sea":
        out["T_tau"] = lat[proc["torque"]]
    return out


def _opt(x: Any) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def process_of(model: LoopModel, placement: str) -> dict[str, str]:
    """Which process runs each loop in a placement."""
    hi, lo = "high-level", "embedded"
    out = {"stiffness": hi if placement in ("centralized", "distributed") else lo,
           "damping": hi if placement == "centralized" else lo}
    if model.kind == "sea":
        out["torque"] = hi if placement == "centralized" else lo
    return out


def _jitter_need(model: LoopModel, placement: str, timing: dict[str, ProcessTiming] | None
                 ) -> dict[str, float] | None:
    """The jitter [s] each loop of a placement must tolerate (non-zero entries only)."""
    if not timing:
        return None
    proc = process_of(model, placement)
    need = {k: timing[v].jitter_s for k, v in proc.items() if v in timing}
    if proc["stiffness"] == proc["damping"] and "stiffness" in need:
        need["outer"] = need["stiffness"]
    return {k: v for k, v in need.items() if v > 0}


_TAP_OF = {"outer": "overall", "stiffness": "stiffness", "damping": "damping",
           "torque": "torque"}


def _jitter_short(model: LoopModel, design: Any, margins: Any, need: dict[str, float]
                  ) -> dict[str, np.ndarray]:
    """Per loop with a jitter need: where its jitter margin is short of it."""
    j = model_jitter_margins(model, design, margins)
    return {k: np.asarray(getattr(j, f"{_TAP_OF[k]}_s")) < v for k, v in need.items()}


def _jitter_check(model: LoopModel, need: dict[str, float]):
    """The further check of :func:`~seactl.latency.box.robust_max_fn`: every loop's
    jitter margin at least the jitter its process has."""
    def ok(design, margins):
        good = np.ones(np.shape(margins.stable), bool)
        for short in _jitter_short(model, design, margins, need).values():
            good &= ~short
        return good
    return ok


def _bottleneck(model: LoopModel, r: RobustFn, need: dict[str, float] | None) -> str | None:
    """The failing constraint in words, with the latencies where it fails."""
    if r.limit is None:
        return None
    what, lat = r.limit["constraint"], r.limit["latencies_s"]
    if what == "jitter" and need:
        d = model.design(r.limit["fn_hz"], lat["T_s"], lat["T_d"],
                         **{k: v for k, v in lat.items() if k not in ("T_s", "T_d")})
        short = _jitter_short(model, d, model.margins(d), need)
        what = next((f"{k} jitter" for k, v in short.items() if np.any(v)), "jitter")
    where = ", ".join(f"{k} = {v * 1e3:.3g} ms" for k, v in lat.items())
    return f"{what} at {where}"


def _boxes_nested(inner: dict[str, float], outer: dict[str, float]) -> bool:
    return all(inner[k] <= outer[k] for k in inner)


def evaluate_placements(model: LoopModel, high_latency_s: float, low_latency_s: float,
                        min_pm_deg: float = 45.0,
                        timing: dict[str, ProcessTiming] | None = None,
                        latency_margin: float = LATENCY_MARGIN) -> tuple[PlacementOption, ...]:
    """Every placement's score (:func:`~seactl.latency.box.robust_max_fn`), with its gains
    and nominal margins (and, with ``timing``, the jitter margins its processes need).

    Placements are scored from the least latency to the most; when a placement's latency
    box contains an already scored one's, that score caps its ``f_n`` scan."""
    from seactl.base.limits import BYTES_PER_DESIGN, RANGES, check_budget
    from seactl.errors import InputError
    from seactl.latency.box import latency_lattice_s

    lat = {p: placement_latencies(model, p, high_latency_s, low_latency_s) for p in PLACEMENTS}
    longest = RANGES["delay_ms"][1] * 1e-3
    top = latency_lattice_s((1 + latency_margin) * max(high_latency_s, low_latency_s))[-1]
    if top > longest:
        raise InputError("latency_margin", latency_margin,
                         f"such that (1 + margin) x the longest latency "
                         f"({max(high_latency_s, low_latency_s):g} s), rounded up to the "
                         f"lattice ({top:.4g} s here), is <= {longest:g} s")
    points = sum(box_size(v, latency_margin) for v in lat.values())
    check_budget(f"the placement scores ({points:,} latency combinations)",
                 n_bytes=CHUNK_DESIGNS * BYTES_PER_DESIGN, seconds=points * SECONDS_PER_POINT,
                 hint="give shorter latencies or a smaller latency margin")
    scores: dict[str, RobustFn] = {}
    with progress.stage("placement scores", total=len(PLACEMENTS),
                        unit="placements") as stage:
        for p in sorted(PLACEMENTS, key=lambda q: sum(lat[q].values())):
            scores[p] = _score(model, p, lat, scores, timing, min_pm_deg, latency_margin)
            stage.advance(item=p)
    return tuple(_option(model, p, lat[p], scores[p], _jitter_need(model, p, timing))
                 for p in PLACEMENTS)


def _score(model: LoopModel, p: str, lat: dict[str, dict[str, float]],
           scores: dict[str, RobustFn], timing: dict[str, ProcessTiming] | None,
           min_pm_deg: float, latency_margin: float) -> RobustFn:
    """Placement ``p``'s score, its ``f_n`` scan capped by the placements already scored
    (``scores``) whose latency box it contains."""
    need = _jitter_need(model, p, timing)
    inside = [r for q, r in scores.items() if _boxes_nested(lat[q], lat[p])
              and (need or {}) == (_jitter_need(model, q, timing) or {})]
    tight = min(inside, key=lambda r: -1.0 if r.status == "none" else r.fn_hz,
                default=None)
    cap_hz = None if tight is None else (model.fn_limits[0] if tight.status == "none"
                                         else tight.fn_hz)
    r = robust_max_fn(model, lat[p], min_pm_deg=min_pm_deg, latency_margin=latency_margin,
                      check=_jitter_check(model, need) if need else None,
                      check_name="jitter", fn_hi=cap_hz)
    if tight is not None and r.status == "capped":   # what fails above the inner box's
        r = replace(r, status=tight.status, limit=tight.limit)  # score fails here too
    return r


def _option(model: LoopModel, placement: str, lat: dict[str, float], r: RobustFn,
            need: dict[str, float] | None) -> PlacementOption:
    """One placement's row: the score, and the design's nominal margins at it."""
    extra = {k: v for k, v in lat.items() if k not in ("T_s", "T_d")}
    t_inner = extra.get("T_tau")
    bottleneck = _bottleneck(model, r, need)
    if r.status == "none":
        return PlacementOption(placement, lat["T_s"], lat["T_d"], t_inner, None, "none", {},
                               None, None, None, None, None, need, None, bottleneck,
                               r.box_upper_s, r.limit)
    d = model.design(r.fn_hz, lat["T_s"], lat["T_d"], **extra)
    m = model.margins(d)
    dm = model.delay_margins(d)
    if model.kind == "rigid":
        gains = {"K": float(d.K), "B": float(d.B)}
    else:
        gains = {k: float(getattr(d, k)) for k in ("Kq", "Bq", "Ktau", "Btau")}
    jm = None
    if need is not None:
        j = model_jitter_margins(model, d, m)
        jm = {k: float(getattr(j, f"{t}_s")) for k, t in _TAP_OF.items()
              if getattr(j, f"{t}_s") is not None}
    return PlacementOption(placement, lat["T_s"], lat["T_d"], t_inner, r.fn_hz, r.status,
                           gains, _opt(model.static_stiffness(d)), _opt(m.phase_margin_deg),
                           _opt(m.crossover_hz), _opt(dm.stiffness_s), _opt(dm.damping_s),
                           need, jm, bottleneck, r.box_upper_s, r.limit)


def advise(model: LoopModel, high_latency_s: float, low_latency_s: float, *,
           min_pm_deg: float = 45.0, stiffness_embeddable: bool = False,
           timing: dict[str, ProcessTiming] | None = None,
           latency_margin: float = LATENCY_MARGIN) -> Advice:
    """Compare the three placements by their score and recommend one.

    Parameters
    ----------
    model : LoopModel
        :func:`~seactl.latency.maps.rigid_model` or :func:`~seactl.latency.maps.sea_model`.
    high_latency_s, low_latency_s : float
        Feedback latency of the high-level and of the embedded process [s].
    min_pm_deg : float
        Phase margin [deg] required at every latency of the box.
    stiffness_embeddable : bool
        Whether the stiffness loop may run embedded (otherwise ``embedded`` is only
        reported for comparison).
    timing : dict, optional
        ``"high-level"`` and/or ``"embedded"`` -> :class:`ProcessTiming`; its nominal
        latency replaces ``high_latency_s`` / ``low_latency_s`` and its jitter must stay
        within the jitter margins.
    latency_margin : float
        Fraction of its latency each loop must tolerate on top of it (the box's upper end
        is ``1 + latency_margin`` times the latency).

    The score is :func:`criterion_text`; the recommendation is the allowed placement with
    the highest score (ties within :data:`TIE_RTOL` favour more work on the high-level
    process); ``None`` when no allowed placement admits any ``f_n``.
    """
    timing, high_latency_s, low_latency_s = _nominal(timing, high_latency_s, low_latency_s)
    high = float(finite_array("high latency [s]", high_latency_s, minimum=0.0))
    low = float(finite_array("low latency [s]", low_latency_s, minimum=0.0))
    pm = float(finite_array("min phase margin [deg]", min_pm_deg, minimum=0.0))
    margin = float(finite_array("latency_margin", latency_margin, minimum=0.0))
    from seactl.errors import InputError

    if pm >= 180:
        raise InputError("min phase margin [deg]", pm, "< 180")
    if margin > MAX_LATENCY_MARGIN:
        raise InputError("latency_margin", margin, f"<= {MAX_LATENCY_MARGIN:g}")
    options = evaluate_placements(model, high, low, pm, timing, margin)
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
    crit = criterion_text(pm, margin, bool(timing))
    reason = _reason(model, options, best, gain, frac, high, low, pm, stiffness_embeddable)
    return Advice(model.name, model.kind, high, low, pm, stiffness_embeddable,
                  model.stiffness_unit, options, None if best is None else best.placement,
                  gain, frac, reason, timing, margin, crit)


def _nominal(timing: dict[str, ProcessTiming] | None, high_s: float, low_s: float
             ) -> tuple[dict[str, ProcessTiming] | None, float, float]:
    """Drop empty entries; the processes' nominal latencies replace the constant ones."""
    timing = {k: v for k, v in (timing or {}).items() if v is not None} or None
    for key in timing or {}:
        if key not in ("high-level", "embedded"):
            from seactl.errors import InputError

            raise InputError("timing", key, "'high-level' or 'embedded'")
    if timing and "high-level" in timing:
        high_s = timing["high-level"].nominal_s
    if timing and "embedded" in timing:
        low_s = timing["embedded"].nominal_s
    return timing, high_s, low_s


def upper_bound(options: tuple[PlacementOption, ...]) -> str | None:
    """The placement whose score no other placement's exceeds, if ``embedded`` is one
    (None otherwise: then no placement is called an upper bound)."""
    emb = next(o for o in options if o.placement == "embedded")
    scores = [o.fn_hz for o in options if o.fn_hz is not None]
    if emb.fn_hz is not None and all(emb.fn_hz >= f for f in scores):
        return "embedded"
    return None


def _desc(o: PlacementOption, pm: float, unit: str) -> str:
    if o.fn_hz is None:
        return f"{o.placement}: no f_n qualifies ({o.bottleneck} already at the lowest f_n)"
    cap = " (scan limit)" if o.status == "capped" else ""
    return (f"{o.placement}: score {o.fn_hz:.4g} Hz{cap}, static stiffness "
            f"{o.static_stiffness:.4g} {unit}"
            + (f", limited by {o.bottleneck}" if o.bottleneck else ""))


def _versus_embedded(frac: float, emb: PlacementOption, bound: bool) -> str:
    """The recommended placement's static stiffness against all-embedded's: a fraction of
    it when all-embedded scores at least as high, otherwise a ratio and the constraint that
    holds all-embedded lower (with timing, the jitter of the one process running every loop;
    or an embedded latency longer than the high-level one)."""
    if frac <= 1:
        return (f"It reaches {100 * frac:.3g} % of the static stiffness of running every loop "
                "embedded" + (" (the upper bound: no placement scores higher)" if bound
                              else "") + ". ")
    why = f" (all-embedded is limited by {emb.bottleneck})" if emb.bottleneck else ""
    return (f"It reaches {frac:.3g}x the static stiffness of running every loop embedded, "
            f"which scores lower here{why}. ")


def _reason(model, options, best, gain, frac, high, low, pm, embeddable) -> str:
    cen, dist, emb = options
    lines = [_desc(o, pm, model.stiffness_unit) for o in options]
    if best is None:
        return "No allowed placement qualifies at any f_n. " + "; ".join(lines) + "."
    text = (f"Recommended: {best.placement} (high-level latency {high * 1e3:g} ms, embedded "
            f"{low * 1e3:g} ms). ")
    if best.placement != "centralized":
        if cen.fn_hz is None:
            text += "All-centralized qualifies at no f_n. "
        else:
            text += (f"It raises the achievable stiffness {gain:.3g}x over all-centralized "
                     f"(score {cen.fn_hz:.3g} -> {best.fn_hz:.3g} Hz). ")
    else:
        text += "Moving the damping loop to the embedded process gains nothing here. "
    if frac is not None and not embeddable:
        text += _versus_embedded(frac, emb, upper_bound(options) == "embedded")
    if dist.stiffness_dm_s is not None and dist.damping_dm_s is not None:
        text += (f"At the distributed score and its nominal latencies the stiffness loop "
                 f"tolerates {dist.stiffness_dm_s * 1e3:.3g} ms more latency, the damping "
                 f"loop {dist.damping_dm_s * 1e3:.3g} ms. ")
    return text + "Details: " + "; ".join(lines) + "."
