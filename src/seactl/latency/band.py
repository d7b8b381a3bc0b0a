"""A measured step against the band the analysis predicts for a latency distribution.

The band is the envelope (lowest and highest value at each tick) of the sampled step
responses of :func:`seactl.latency.montecarlo.timed_simulation` (the machinery of
``System.monte_carlo``) with the given latency models per loop; loops without a model
keep the design's delays, so with no model at all the band is the one nominal response.
A run whose Monte Carlo realization diverged leaves the band open from then on.  The
measured step is *within the predicted band* when every tick lies inside it, widened by
``tolerance`` (relative to the step) for what the band does not model: the plant's
integration (MuJoCo) and rounding.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.errors import InputError
from seactl.latency.montecarlo import timed_simulation
from seactl.simulate.inputs import Step

BAND_TOLERANCE = 1e-3
"""Default widening of the band, relative to the step."""


@dataclass(frozen=True)
class BandVerdict:
    """A measured step response against the predicted band (a run's summary holds its
    :meth:`to_dict` under ``prediction_band``).

    Attributes
    ----------
    verdict : str
        ``"within the predicted band"`` or ``"outside: ..."`` with the worst tick.
    within : bool
        Every tick inside the widened band.
    runs : int
        Monte Carlo realizations of the band.
    ticks_outside : int
        Ticks outside the widened band.
    max_outside : float
        Largest distance outside the band, relative to the step (0 when within).
    t_worst_s : float
        Time of that tick [s] (NaN when within).
    max_width : float
        Largest width of the band, relative to the step.
    tolerance : float
        The widening, relative to the step.
    """

    verdict: str
    within: bool
    runs: int
    ticks_outside: int
    max_outside: float
    t_worst_s: float
    max_width: float
    tolerance: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields (what a run's summary holds under ``prediction_band``).

        Returns
        -------
        dict
            The attributes by name.
        """
        return {"verdict": self.verdict, "within": bool(self.within), "runs": int(self.runs),
                "ticks_outside": int(self.ticks_outside),
                "max_outside": float(self.max_outside),
                "t_worst_s": None if np.isnan(self.t_worst_s) else float(self.t_worst_s),
                "max_width": float(self.max_width), "tolerance": float(self.tolerance)}


def compare_band(t_s: np.ndarray, measured: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 runs: int, tolerance: float = BAND_TOLERANCE) -> BandVerdict:
    """Judge ``measured`` (relative to the step) against the band ``[lo, hi]`` (same ticks).

    Parameters
    ----------
    t_s, measured, lo, hi : numpy.ndarray
        Tick times [s], the measured response and the band's edges (relative to the step).
    runs : int
        Realizations behind the band.
    tolerance : float
        Widening of the band, relative to the step.

    Returns
    -------
    BandVerdict

    Examples
    --------
    >>> t = np.arange(3) * 1e-3
    >>> compare_band(t, np.array([0, 0.5, 1.2]), np.zeros(3), np.ones(3), 5).verdict
    'outside: 1 of 3 ticks, worst 0.199 of the step above the band at t = 2 ms'
    """
    out = np.maximum(lo - tolerance - measured, measured - hi - tolerance)
    out = np.where(np.isnan(measured), np.inf, out)
    bad = out > 0
    width = float(np.max(np.where(np.isfinite(hi - lo), hi - lo, 0.0), initial=0.0))
    if not bad.any():
        return BandVerdict("within the predicted band", True, runs, 0, 0.0, float("nan"),
                           width, tolerance)
    i = int(np.argmax(out))
    side = "above" if measured[i] > hi[i] else "below"
    verdict = (f"outside: {int(bad.sum())} of {bad.size} ticks, worst {out[i]:.3g} of the "
               f"step {side} the band at t = {t_s[i] * 1e3:.4g} ms")
    return BandVerdict(verdict, False, runs, int(bad.sum()), float(out[i]), float(t_s[i]),
                       width, tolerance)


def step_band(diagram: Any, design: Any, t_s: np.ndarray, measured: np.ndarray, *,
              step: float, reference: str, output: str, links: Mapping[str, str],
              latency: Mapping[str, Any] | None = None, runs: int = 50, seed: int = 0,
              rates_hz: Any = 1000.0, saturation: Mapping[str, float] | None = None,
              tolerance: float = BAND_TOLERANCE) -> BandVerdict:
    """The band of ``runs`` sampled step responses under ``latency`` and the verdict on the
    measured step (module docstring).

    Parameters
    ----------
    diagram, design
        The system's diagram and design (one design).
    t_s, measured : numpy.ndarray
        The measured ticks [s] and output (in the output's unit, not normalized).
    step : float
        The reference step.
    reference, output : str
        The stepped reference and the measured output.
    links : mapping
        Loop name -> delayed block (``System.links``).
    latency : mapping, optional
        Loop name -> latency model (seconds) of :mod:`seactl.latency.models`.
    runs, seed : int
        Realizations and seed (one run when every latency is deterministic).
    rates_hz, saturation
        As for the sampled simulation.
    tolerance : float
        Widening of the band, relative to the step.

    Returns
    -------
    BandVerdict
    """
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise InputError("tolerance", tolerance, ">= 0 (relative to the step)")
    latency = dict(latency or {})
    if all(m.deterministic for m in latency.values()):
        runs = 1
    t_s = np.asarray(t_s, float)
    res = timed_simulation(diagram, design, {reference: Step(step)}, float(t_s[-1]),
                           latency=latency, runs=runs, seed=seed, links=links,
                           rates_hz=rates_hz, saturation=saturation, outputs=(output,),
                           bound=1e3 * abs(step))
    y = np.reshape(res.outputs[output], (runs, -1)) / step
    y = np.array([np.interp(t_s, res.t_s, r) for r in y])
    with np.errstate(invalid="ignore"):
        open_ = np.isnan(y).any(axis=0)
        lo = np.where(open_, -np.inf, np.nanmin(np.where(np.isnan(y), np.inf, y), axis=0))
        hi = np.where(open_, np.inf, np.nanmax(np.where(np.isnan(y), -np.inf, y), axis=0))
    return compare_band(t_s, np.asarray(measured, float) / step, lo, hi, runs, tolerance)


def check_band_latency(latency: Mapping[str, Any] | None, links: Mapping[str, str]) -> None:
    """Refuse a latency model of a loop the system does not have (before a run starts)."""
    for k in latency or {}:
        if k not in links and k not in links.values():
            raise InputError("latency", k, "a loop: " + ", ".join(links))


def band_latency(latency: Mapping[str, Any] | None, links: Mapping[str, str]
                 ) -> dict[str, Any] | None:
    """A run's ``latency`` argument as models: text parsed
    (:func:`~seactl.latency.models.parse_latency`, milliseconds), every loop checked
    (:func:`check_band_latency`); None stays None (the run's measured latency)."""
    from seactl.latency.models import parse_latency

    if latency is None:
        return None
    if not isinstance(latency, Mapping):
        raise InputError("latency", latency, "a mapping: loop -> latency model")
    lat = {k: parse_latency(v, f"latency {k}") if isinstance(v, str) else v
           for k, v in latency.items()}
    check_band_latency(lat, links)
    return lat


def measured_latency(res: Any, links: Mapping[str, str]) -> dict[str, Any]:
    """The run's measured latency of the high-level loop as an
    :class:`~seactl.latency.models.Empirical` model, when the system has that loop.

    The run records, per tick, the age of the high-level message in use (``latency_s
    ["stiffness"]``: half a period plus the age, from the first message on).  Each
    message's own wait is the tick it was first in use less its tick (a message
    superseded before use waited as long as the one that superseded it), half a period
    added: what :func:`~seactl.latency.montecarlo.buffer_ticks` turns back into that
    wait.  A free-running run (:func:`realtime_latency`) has its own."""
    from seactl.latency.models import Empirical

    if res.summary.get("mode") == "realtime":
        return realtime_latency(res, links)
    lat = np.asarray(res.latency_s.get("stiffness", ()), float)
    if "stiffness" not in links or lat.size == 0:
        return {}
    Tb = float(res.t_s[1] - res.t_s[0])
    k = np.arange(res.t_s.size - lat.size, res.t_s.size)
    src = k - np.round(lat / Tb - 0.5).astype(int)          # the message in use per tick
    msgs = np.arange(src.min(), src.max() + 1)
    first = k[np.searchsorted(np.maximum.accumulate(src), msgs)]
    v, n = np.unique(Tb / 2 + (first - msgs) * Tb, return_counts=True)
    return {"stiffness": Empirical(tuple(v.tolist()), tuple(n.astype(float).tolist()),
                                   "the run")}


def realtime_latency(res: Any, links: Mapping[str, str]) -> dict[str, Any]:
    """A free-running run's latency per loop: the exported C holds no analysis latency,
    so a loop's latency is the platform's, the sum of the send-to-use latencies of the
    links it crosses (``res.block_latency_s``), rounded to whole base ticks, half a base
    period added (the convention of :func:`measured_latency`); a loop without a
    measurement has none (:class:`~seactl.latency.models.Constant` 0)."""
    from seactl.latency.models import Constant, Empirical

    Tb = float(res.t_s[1] - res.t_s[0])
    out: dict[str, Any] = {}
    for loop, block in links.items():
        use = np.asarray(res.block_latency_s.get(block, ()), float)
        if use.size == 0:
            out[loop] = Constant(0.0)
            continue
        v, n = np.unique(Tb / 2 + np.round(use / Tb) * Tb, return_counts=True)
        out[loop] = Empirical(tuple(v.tolist()), tuple(n.astype(float).tolist()), "the run")
    return out


def _describe(model: Any) -> str:
    v = getattr(model, "values_s", None)
    if v is None or len(v) <= 4:
        return str(model)
    return f"measured: {len(v)} values, {1e3 * min(v):.4g} to {1e3 * max(v):.4g} ms"


def run_band(res: Any, diagram: Any, design: Any, *, reference: str,
             links: Mapping[str, str], latency: Mapping[str, Any] | None = None,
             rates_hz: Any = 1000.0, saturation: Mapping[str, float] | None = None,
             runs: int = 200, seed: int = 0) -> BandVerdict:
    """:func:`step_band` of a run (:class:`~seactl.codegen.runtime.RunResult`): its
    measured output against the band for ``latency`` (default: the run's own measured
    latency, :func:`measured_latency`); the verdict goes into ``res.summary`` under
    ``prediction_band`` (with ``latency``: each loop's model)."""
    s = res.summary
    latency = measured_latency(res, links) if latency is None else dict(latency)
    v = step_band(diagram, design, res.t_s, res.q_measured, step=s["step"],
                  reference=reference, output=s["output"], links=links, latency=latency,
                  runs=runs, seed=seed, rates_hz=rates_hz, saturation=saturation)
    s["prediction_band"] = v.to_dict() | {
        "latency": {k: _describe(m) for k, m in latency.items()} or "design"}
    return v
