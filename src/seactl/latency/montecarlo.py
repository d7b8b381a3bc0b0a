"""Sampled simulation with real timing: random latency and message loss per link.

A *link* is one delayed block of the diagram, the path a measurement takes to the
process that uses it (for the SEA: ``stiffness`` = ``Kq_fb``, ``damping`` =
``Bq_fb``, ``torque`` = ``tau_delay``).  Each message (the source signal sampled
at a base tick ``k``) gets a latency from the link's latency model
(:mod:`seactl.latency.models`: :class:`Constant`, :class:`Uniform`,
:class:`ShiftedExponential`, :class:`Empirical` from a CSV of measured
latencies) and may be lost (:class:`Bernoulli` independent loss,
:class:`GilbertElliott` bursts).  The
latency plays the role of the fixed delay ``T`` of the deterministic sampled
mode (:mod:`seactl.simulate.engine`): with zero-order hold the message is used
``n = max(ceil((T - T_s/2)/T_s), 0)`` samples after it was taken (effective delay
``T_s/2 + n T_s``, never shorter than ``T``).  At each tick the receiver uses the
newest message that has arrived (older ones arriving later are ignored) and holds
the last value when nothing new arrived.

A link whose model is deterministic (constant latency, a one-bin histogram) and
lossless is simulated exactly as the deterministic sampled mode with that
delay; the others go through per-run arrival schedules
(:func:`arrival_schedule`) in one batched simulation of ``runs x designs``.
Every run draws from its own random stream (``SeedSequence(seed).spawn``), so
results are reproducible from the seed, and run ``r`` is the same whatever the
number of runs.

Examples
--------
>>> import seactl as sc
>>> d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
...               filters_hz=(50, 100))
>>> mc = sea_monte_carlo(d.sea, latency={"damping": Uniform(0.5e-3, 3e-3)},
...                      loss={"damping": 0.05}, runs=8, seed=1, t_end_s=0.3)
>>> float(mc.fraction_stable), mc.runs
(1.0, 8)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from seactl.base import progress
from seactl.base.result import Result, flat_records, new_axes
from seactl.errors import InputError
from seactl.latency.models import (  # noqa: F401  (re-exported: the models live in timing_models)
    Bernoulli,
    Constant,
    Empirical,
    GilbertElliott,
    ShiftedExponential,
    Uniform,
    check_latency,
    check_loss,
    parse_latency,
    parse_link_specs,
    parse_loss,
)
from seactl.simulate.discrete import buffer_samples
from seactl.simulate.engine import simulate
from seactl.simulate.inputs import Impulse, Step
from seactl.simulate.results import SimResult

SEA_LINKS: dict[str, str] = {"stiffness": "Kq_fb", "damping": "Bq_fb", "torque": "tau_delay"}
"""Link names of the SEA diagram -> the delayed blocks they feed."""


# ----------------------------------------------------------------------------- schedules
def buffer_ticks(latency_s: np.ndarray, period_s: float, ticks: int = 1) -> np.ndarray:
    """Whole samples a message waits (in base ticks) for latency ``latency_s``: the rule of
    the deterministic sampled mode (:func:`seactl.simulate.discrete.buffer_samples`, never shorter
    than the latency) at the block's period ``T_s`` (``ticks`` base ticks)."""
    return buffer_samples(latency_s, period_s) * ticks


def arrival_schedule(wait_ticks: np.ndarray, lost: np.ndarray | None = None) -> np.ndarray:
    """Source tick of the message in use at each tick: the newest that has arrived.

    Parameters
    ----------
    wait_ticks : numpy.ndarray
        ``(T, N)``: ticks message ``k`` (taken at tick ``k``) waits before it can be used.
    lost : numpy.ndarray, optional
        ``(T, N)`` bool: messages that never arrive.

    Returns
    -------
    numpy.ndarray
        ``(T, N)`` int: at tick ``j`` the largest ``k`` with ``k + wait[k] <= j`` among
        messages not lost, or -1 when none has arrived yet.

    Examples
    --------
    >>> arrival_schedule(np.array([[2], [0], [0], [5], [0]]))[:, 0].tolist()
    [-1, 1, 2, 2, 4]
    """
    T, N = wait_ticks.shape
    k = np.arange(T)[:, None]
    arrive = k + wait_ticks
    ok = arrive < T
    if lost is not None:
        ok &= ~lost
    sched = np.full((T, N), -1)
    rows, cols = np.nonzero(ok)
    np.maximum.at(sched, (arrive[rows, cols], cols), rows)
    return np.maximum.accumulate(sched, axis=0)


@dataclass(frozen=True)
class _Tiled:
    """``runs`` copies of a design batch: shape ``(runs,) + design.shape``; attribute
    overrides (fixed delays of deterministic links) are broadcast too."""

    design: Any
    runs: int
    overrides: dict[str, float] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.runs,) + tuple(getattr(self.design, "shape", ()))

    def __getattr__(self, name: str) -> np.ndarray:
        if name.startswith("_") or name in ("design", "runs", "overrides"):
            raise AttributeError(name)
        value = self.overrides[name] if name in self.overrides else getattr(self.design, name)
        return np.broadcast_to(np.asarray(value, float), self.shape)


def _link_blocks(diagram: Any, links: Mapping[str, str], names: Sequence[str]
                 ) -> dict[str, Any]:
    delayed = {b.name: b for b in diagram.blocks if b.delay is not None}
    out = {}
    for name in names:
        block = links.get(name, name)
        if block not in delayed:
            raise InputError("link", name, "one of " + ", ".join([*links, *delayed]))
        out[name] = delayed[block]
    return out


class LinkTiming:
    """Random timing of some delayed blocks, for :func:`seactl.simulate.engine.simulate`
    (``timing=``): ``blocks`` to drive, and :meth:`schedules` for a compiled plan.

    Parameters
    ----------
    blocks : dict
        Link name -> delayed :class:`~seactl.diagram.blockdiagram.Block`.
    latency, loss : dict
        Link name -> model (links without a latency model keep the design's delay).
    runs : int
        Realizations; the plan's batch is ``(runs,) + design.shape``.
    seed : int
        Seed of the per-run random streams.
    """

    def __init__(self, blocks: Mapping[str, Any], latency: Mapping[str, Any],
                 loss: Mapping[str, Any], runs: int, seed: int):
        self.links = dict(blocks)
        self.latency, self.loss = dict(latency), dict(loss)
        self.runs, self.seed = int(runs), int(seed)
        self.loss_fraction: dict[str, float] = {}

    @property
    def blocks(self) -> list[str]:
        return [b.name for b in self.links.values()]

    def schedules(self, plan: Any) -> dict[str, np.ndarray]:
        """Per-block arrival schedules ``(T, runs * n)`` for ``plan``."""
        T, runs = plan.steps + 1, self.runs
        n = plan.x0.shape[1] // runs
        streams = [np.random.default_rng(s)
                   for s in np.random.SeedSequence(self.seed).spawn(runs)]
        rates = plan.info["rates_hz"]
        delays = plan.info["effective_delays_s"]
        out = {}
        for name, b in self.links.items():
            ticks = int(round(max(rates.values()) / rates[b.process])) \
                if b.process in rates else 1
            lat = self.latency.get(name)
            if lat is None:  # loss only: the design's own (effective) delay
                eff = np.asarray(delays[b.name], float).reshape(runs, n)
                lat_s = np.broadcast_to(eff[None], (T, runs, n))
            else:
                lat_s = np.stack([lat.sample(g, (T, n)) for g in streams], axis=1)
            lost = np.zeros((T, runs, n), bool)
            if name in self.loss:
                lost = np.stack([self.loss[name].sample(g, (T, n)) for g in streams], axis=1)
            period = plan.base_period_s * ticks
            wait = buffer_ticks(lat_s, period, ticks).reshape(T, runs * n)
            out[b.name] = arrival_schedule(wait, lost.reshape(T, runs * n))
            self.loss_fraction[name] = float(lost.mean())
        return out


def timed_simulation(diagram: Any, design: Any, inputs: Mapping[str, Any], t_end_s: float, *,
                     latency: Mapping[str, Any] | None = None,
                     loss: Mapping[str, Any] | None = None, runs: int = 1, seed: int = 0,
                     links: Mapping[str, str] | None = None, **kwargs: Any) -> SimResult:
    """Sampled simulation of ``runs`` random timing realizations of every design.

    Parameters
    ----------
    diagram, design, inputs, t_end_s
        As for :func:`seactl.simulate.engine.simulate` (sampled mode).
    latency : mapping
        Link -> latency model (:class:`Constant`, :class:`Uniform`,
        :class:`ShiftedExponential`, :class:`Empirical`); other links keep the design's
        fixed delay.
    loss : mapping
        Link -> loss model (:class:`Bernoulli`, :class:`GilbertElliott`, or a probability).
    runs : int
        Realizations per design (the batch becomes ``(runs,) + design.shape``).
    seed : int
        Seed of the per-run random streams.
    links : mapping, optional
        Friendly link names -> delayed block names (e.g. :data:`SEA_LINKS`); block names
        are always accepted.
    **kwargs
        ``rates_hz``, ``saturation``, ``outputs``, ``bound``, ... of the sampled mode.

    Returns
    -------
    SimResult
        Outputs of shape ``(runs,) + design.shape + (T,)``; ``info["timing"]`` gives the
        realized loss fraction per link and the links simulated with a fixed delay.
    """
    latency, loss, links = dict(latency or {}), dict(loss or {}), dict(links or {})
    if not (isinstance(runs, (int, np.integer)) and 1 <= runs <= 100_000):
        raise InputError("runs", runs, "an integer in [1, 100000]")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError("seed", seed, "an integer >= 0")
    blocks = _link_blocks(diagram, links, sorted(set(latency) | set(loss)))
    for name, model in latency.items():
        check_latency(name, model)
    loss = {k: check_loss(k, v) for k, v in loss.items()}
    # Deterministic, lossless links: the deterministic sampled mode with that delay.
    fixed = {k: float(m.mean_s) for k, m in latency.items()
             if m.deterministic and (k not in loss or loss[k].rate == 0)}
    tiled = _Tiled(design, int(runs), {blocks[k].delay: v for k, v in fixed.items()})
    timed = {k: b for k, b in blocks.items() if k not in fixed}
    spec = LinkTiming(timed, {k: latency[k] for k in timed if k in latency},
                      {k: loss[k] for k in timed if k in loss}, runs, seed) if timed else None
    res = simulate(diagram, tiled, inputs, t_end_s, mode="sampled", timing=spec, **kwargs)
    info = dict(res.info)
    info["timing"] = {"loss_fraction": spec.loss_fraction if spec else {},
                      "fixed_delays_s": fixed, "runs": int(runs), "seed": int(seed)}
    return SimResult(res.mode, res.t_s, res.outputs, res.stable, res.left_bounds_s, res.bound,
                     info)


# ----------------------------------------------------------------------------- SEA
@dataclass(frozen=True)
class MonteCarloSummary(Result):
    """Monte Carlo over timing realizations (random latency and loss) of a batch of
    designs.

    Parameters
    ----------
    kind : str
        ``"step"`` or ``"impulse"``.
    runs : int
        Realizations per design.
    stable : numpy.ndarray
        ``(runs,) + shape`` bool, per run.
    rms_error : numpy.ndarray
        ``(runs,) + shape``: RMS tracking error over the window.
    peak_current_a : numpy.ndarray
        ``(runs,) + shape``: largest motor current [A].
    result : seactl.simulate.results.SimResult
        The batched simulation.

    Attributes
    ----------
    kind : str
        ``"step"`` or ``"impulse"``.
    runs : int
        Realizations per design.
    stable : ndarray of bool
        ``(runs,) + shape``, per run.
    rms_error : ndarray
        ``(runs,) + shape``: RMS tracking error over the window, relative to the step
        (position / step - 1) for a step, in the position's unit (rad or m) for an
        impulse; NaN for unstable runs.
    peak_current_a : ndarray
        ``(runs,) + shape``: largest motor current [A] (NaN if unstable).
    fraction_stable : ndarray
        ``shape``: fraction of runs that stayed stable.
    rms_error_mean, rms_error_worst : ndarray
        ``shape``: mean and worst RMS error of stable runs (unit of ``rms_error``).
    peak_current_worst_a : ndarray
        ``shape``: largest current of stable runs [A].
    worst_run : ndarray of int
        ``shape``: index of the worst run (an unstable one first, else the largest RMS
        error).
    result : seactl.simulate.results.SimResult
        The batched simulation.
    """

    kind: str
    runs: int
    stable: np.ndarray
    rms_error: np.ndarray
    peak_current_a: np.ndarray
    result: SimResult = field(repr=False)

    @property
    def fraction_stable(self) -> np.ndarray:
        """Fraction of runs that stayed stable, per design."""
        return self.stable.mean(axis=0)

    @property
    def rms_error_mean(self) -> np.ndarray:
        """Mean RMS error of the stable runs, per design."""
        with np.errstate(invalid="ignore"):
            return np.nanmean(np.where(self.stable, self.rms_error, np.nan), axis=0) \
                if self.stable.any() else np.full(self.stable.shape[1:], np.nan)

    @property
    def rms_error_worst(self) -> np.ndarray:
        """Worst RMS error of the stable runs, per design."""
        e = np.where(self.stable, self.rms_error, -np.inf)
        return np.where(self.stable.any(axis=0), e.max(axis=0), np.nan)

    @property
    def peak_current_worst_a(self) -> np.ndarray:
        """Largest current of the stable runs [A], per design."""
        c = np.where(self.stable, self.peak_current_a, -np.inf)
        return np.where(self.stable.any(axis=0), c.max(axis=0), np.nan)

    @property
    def worst_run(self) -> np.ndarray:
        """Index of the worst run, per design."""
        key = np.where(self.stable, self.rms_error, np.inf)
        return np.argmax(key, axis=0)

    def _columns(self) -> dict[str, Any]:
        return {"fraction_stable": self.fraction_stable, "rms_error_mean": self.rms_error_mean,
                "rms_error_worst": self.rms_error_worst,
                "peak_current_worst_a": self.peak_current_worst_a,
                "worst_run": self.worst_run}

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready summary per design (flattened batch).

        Returns
        -------
        list of dict
            ``fraction_stable``, ``rms_error_mean``, ``rms_error_worst``,
            ``peak_current_worst_a``, ``worst_run``.
        """
        return flat_records(self._columns())

    def to_dict(self) -> dict[str, Any]:
        """The per-design summary as nested lists of the batch shape, with ``kind`` and
        ``runs``.

        Returns
        -------
        dict
            ``kind``, ``runs`` and the keys of :meth:`records`.
        """
        return {"kind": self.kind, "runs": int(self.runs), **super().to_dict()}

    def plot(self, ax: Any = None) -> Any:
        """Distribution of the RMS error over the stable runs, one histogram per design.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        err = np.reshape(self.rms_error, (self.runs, -1))
        ok = np.reshape(self.stable, (self.runs, -1))
        for i in range(err.shape[1]):
            ax.hist(err[ok[:, i], i], bins=30, alpha=0.6, label=f"design {i}")
        ax.set_xlabel("RMS error" + (" / step" if self.kind == "step" else ""))
        ax.set_ylabel("runs")
        if err.shape[1] <= 8:
            ax.legend(loc="best")
        return ax


def sea_monte_carlo(design: Any, kind: str = "step", *, latency: Mapping[str, Any] | None = None,
                    loss: Mapping[str, Any] | None = None, runs: int = 100, seed: int = 0,
                    rate_hz: float = 1000.0, t_end_s: float | None = None, zero: bool = True,
                    saturation_a: float | None = None, amplitude: float = 0.01,
                    impulse_nms: float = 0.05) -> MonteCarloSummary:
    """Monte Carlo of SEA step or impulse responses under random latency and loss.

    Parameters
    ----------
    design : seactl.systems.sea.loops.SEADesign
        Design batch.
    kind : {"step", "impulse"}
        Step of ``amplitude`` [rad] on ``q_des``, or impulse ``impulse_nms`` [N m s] of
        external joint torque.
    latency, loss : mapping
        Per link (``stiffness``, ``damping``, ``torque``, see :data:`SEA_LINKS`).
    runs, seed : int
        Realizations per design and the seed.
    rate_hz : float
        Servo rate of both processes [Hz].
    t_end_s : float, optional
        Window [s] (default 0.5 for steps, 1 for impulses).
    zero : bool
        Torque derivative on the whole error (default).
    saturation_a : float, optional
        Current limit [A] (default: the actuator's).
    amplitude, impulse_nms : float
        Step size [rad], impulse [N m s].

    Returns
    -------
    MonteCarloSummary
    """
    from seactl.systems.sea.loops import sea_diagram

    if kind not in ("step", "impulse"):
        raise InputError("kind", kind, "'step' or 'impulse'")
    t_end_s = (0.5 if kind == "step" else 1.0) if t_end_s is None else float(t_end_s)
    sat = design.actuator.max_current if saturation_a is None else float(saturation_a)
    if kind == "step":
        inputs, bound = {"q_des": Step(amplitude)}, None
    else:
        inputs = {"tau_ext": Impulse(impulse_nms)}
        bound = 1e3 * abs(impulse_nms) / float(np.min(design.Ij)) * t_end_s
    return response_monte_carlo(sea_diagram(zero), design, kind, inputs, t_end_s,
                                amplitude=amplitude, output="q_j", actuation="i_m",
                                latency=latency, loss=loss, runs=runs, seed=seed,
                                links=SEA_LINKS, bound=bound, rate_hz=rate_hz,
                                saturation={"i_m": sat})


def response_monte_carlo(diagram: Any, design: Any, kind: str, inputs: Mapping[str, Any],
                         t_end_s: float, *, amplitude: float, output: str, actuation: str,
                         amperes_per_unit: float = 1.0, latency: Mapping[str, Any] | None,
                         loss: Mapping[str, Any] | None, runs: int, seed: int,
                         links: Mapping[str, str], bound: float | None, rate_hz: float,
                         saturation: Mapping[str, float]) -> MonteCarloSummary:
    """Monte Carlo of the step (``amplitude`` of the reference in ``inputs``) or impulse
    responses of any diagram under random latency and loss (:func:`timed_simulation`):
    the RMS error of ``output`` (normalized by ``amplitude`` for a step) and the peak of
    ``actuation`` times ``amperes_per_unit`` (the current [A])."""
    with progress.stage(f"Monte Carlo: {int(runs):,} runs of the {kind} response"):
        res = timed_simulation(diagram, design, inputs, t_end_s, latency=latency, loss=loss,
                               runs=runs, seed=seed, links=links, bound=bound,
                               rates_hz=float(rate_hz), saturation=saturation,
                               outputs=(output, actuation))
    q = res.outputs[output]
    err = q / amplitude - 1.0 if kind == "step" else q
    rms = np.sqrt(np.mean(err ** 2, axis=-1))
    peak = np.max(np.abs(res.outputs[actuation]), axis=-1) * amperes_per_unit
    return MonteCarloSummary(kind, int(runs), res.stable, np.where(res.stable, rms, np.nan),
                             np.where(res.stable, peak, np.nan), res)


# ----------------------------------------------------------------------------- placement
MODEL_LINKS: dict[str, dict[str, str]] = {
    "sea": SEA_LINKS, "rigid": {"stiffness": "K_fb", "damping": "B_fb"}}
"""Loop names -> delayed blocks, per :class:`~seactl.latency.maps.LoopModel` kind."""


def verify_placement(model: Any, option: Any, timing: Mapping[str, Any], *, runs: int = 200,
                     seed: int = 0, t_end_s: float = 1.0) -> MonteCarloSummary | None:
    """Monte Carlo check of a placement at its recommended ``f_n``: every loop's link gets
    the latency distribution and loss of the process that runs it (a unit reference step,
    linear, no saturation).

    Parameters
    ----------
    model : seactl.latency.maps.LoopModel
        The actuator model the advice was computed for.
    option : seactl.latency.placement.PlacementOption
        One placement of the advice (``None`` is returned if it has no ``f_n``).
    timing : mapping
        ``"high-level"`` / ``"embedded"`` -> :class:`~seactl.latency.placement.ProcessTiming`.
    runs, seed : int
        Realizations and seed.
    t_end_s : float
        Simulated time [s].

    Returns
    -------
    MonteCarloSummary or None
    """
    from seactl.latency.placement import process_of

    if option.fn_hz is None:
        return None
    extra = {"T_tau": option.T_inner} if model.kind == "sea" else {}
    design = model.design(option.fn_hz, option.T_s, option.T_d, **extra)
    proc = process_of(model, option.placement)
    latency = {k: timing[p].latency for k, p in proc.items() if p in timing}
    loss = {k: timing[p].loss for k, p in proc.items()
            if p in timing and timing[p].loss is not None}
    rates = {p: float(timing[p].rate_hz) if p in timing else 1000.0
             for p in ("high-level", "embedded")}
    ref = next(s for s in model.diagram.inputs if s != model.compliance[1])
    out = model.compliance[0]
    res = timed_simulation(model.diagram, design, {ref: Step(1.0)}, t_end_s, latency=latency,
                           loss=loss, runs=runs, seed=seed, links=MODEL_LINKS[model.kind],
                           rates_hz=rates, outputs=(out,))
    err = res.outputs[out] - 1.0
    rms = np.sqrt(np.mean(err ** 2, axis=-1))
    nan = np.full(res.stable.shape, np.nan)
    return MonteCarloSummary("step", int(runs), res.stable, np.where(res.stable, rms, np.nan),
                             nan, res)
