"""Sampled simulation with real timing: random latency and message loss per link.

A *link* is one delayed block of the diagram, the path a measurement takes to the
process that uses it (for the SEA: ``stiffness`` = ``Kq_fb``, ``damping`` =
``Bq_fb``, ``torque`` = ``tau_delay``).  Each message (the source signal sampled
at a base tick ``k``) gets a latency from the link's :class:`LatencyModel`
(:class:`Constant`, :class:`Uniform`, :class:`ShiftedExponential`,
:class:`Empirical` from a CSV of measured latencies) and may be lost
(:class:`Bernoulli` independent loss, :class:`GilbertElliott` bursts).  The
latency plays the role of the fixed delay ``T`` of the deterministic sampled
mode (:mod:`seactl.simulate`): with zero-order hold the message is used
``n = round((T - T_s/2)/T_s)`` samples after it was taken (effective delay
``T_s/2 + n T_s``).  At each tick the receiver uses the newest message that has
arrived (older ones arriving later are ignored) and holds the last value when
nothing new arrived.

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
>>> d = sc.design(14, delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
>>> mc = sea_monte_carlo(d.sea, latency={"damping": Uniform(0.5e-3, 3e-3)},
...                      loss={"damping": 0.05}, runs=8, seed=1, t_end_s=0.3)
>>> float(mc.fraction_stable), mc.runs
(1.0, 8)
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .simulate import Impulse, SimResult, Step, simulate

SEA_LINKS: dict[str, str] = {"stiffness": "Kq_fb", "damping": "Bq_fb", "torque": "tau_delay"}
"""Link names of the SEA diagram -> the delayed blocks they feed."""


# ----------------------------------------------------------------------------- latency
@dataclass(frozen=True)
class Constant:
    """Every message takes ``latency_s`` [s]."""

    latency_s: float

    deterministic = True

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        return np.full(size, float(self.latency_s))

    @property
    def mean_s(self) -> float:
        return float(self.latency_s)


@dataclass(frozen=True)
class Uniform:
    """Latency uniform in ``[low_s, high_s]`` [s]."""

    low_s: float
    high_s: float

    deterministic = False

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        return rng.uniform(self.low_s, self.high_s, size)

    @property
    def mean_s(self) -> float:
        return 0.5 * (self.low_s + self.high_s)


@dataclass(frozen=True)
class ShiftedExponential:
    """``shift_s`` plus an exponential tail of mean ``scale_s`` [s] (queueing delays)."""

    shift_s: float
    scale_s: float

    deterministic = False

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        return self.shift_s + rng.exponential(self.scale_s, size)

    @property
    def mean_s(self) -> float:
        return self.shift_s + self.scale_s


@dataclass(frozen=True)
class Empirical:
    """Latencies drawn from a histogram: ``values_s`` [s] with ``weights`` (counts)."""

    values_s: tuple[float, ...]
    weights: tuple[float, ...]
    source: str = ""

    @property
    def deterministic(self) -> bool:
        return len(self.values_s) == 1

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        v = np.asarray(self.values_s, float)
        if v.size == 1:
            return np.full(size, v[0])
        p = np.asarray(self.weights, float)
        return v[rng.choice(v.size, size=size, p=p / p.sum())]

    @property
    def mean_s(self) -> float:
        return float(np.average(self.values_s, weights=self.weights))

    @classmethod
    def from_csv(cls, path: str | Path) -> Empirical:
        """Read measured latencies [ms]: one column (one sample per row) or two
        (``latency_ms, count``: a histogram); a non-numeric first row is a header."""
        rows = _read_rows(Path(path))
        ncol = {len(r) for r in rows}
        if ncol not in ({1}, {2}):
            raise InputError("latency CSV", str(path), "one column (latency_ms) or two "
                             "(latency_ms, count) in every row")
        vals = np.array([r[0] for r in rows])
        cnt = np.array([r[1] for r in rows]) if ncol == {2} else np.ones(vals.size)
        if np.any(vals < 0) or np.any(vals > 1000) or np.any(cnt < 0) or cnt.sum() <= 0:
            raise InputError("latency CSV", str(path), "latencies in [0, 1000] ms and "
                             "counts >= 0 with a positive total")
        uniq, inv = np.unique(vals, return_inverse=True)
        w = np.bincount(inv, weights=cnt)
        keep = w > 0
        return cls(tuple(uniq[keep] * 1e-3), tuple(w[keep]), str(path))


def _read_rows(path: Path) -> list[list[float]]:
    if not path.is_file():
        raise InputError("latency CSV", str(path), "an existing file")
    rows: list[list[float]] = []
    with path.open(newline="") as fh:
        for i, raw in enumerate(csv.reader(fh)):
            cells = [c.strip() for c in raw if c.strip()]
            if not cells:
                continue
            try:
                rows.append([float(c) for c in cells])
            except ValueError:
                if i == 0:
                    continue  # header
                raise InputError("latency CSV", f"{path}:{i + 1}", "numbers") from None
    if not rows:
        raise InputError("latency CSV", str(path), "at least one latency")
    return rows


# ----------------------------------------------------------------------------- loss
@dataclass(frozen=True)
class Bernoulli:
    """Each message is lost independently with probability ``p``."""

    p: float

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        return rng.random(size) < self.p

    @property
    def rate(self) -> float:
        return float(self.p)


@dataclass(frozen=True)
class GilbertElliott:
    """Bursty loss: a two-state Markov chain (good -> bad with ``p_gb``, bad -> good with
    ``p_bg`` per message) losing messages with ``loss_bad`` in the bad state and
    ``loss_good`` in the good one; it starts in its stationary distribution."""

    p_gb: float
    p_bg: float
    loss_bad: float = 1.0
    loss_good: float = 0.0

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        u = rng.random((2,) + size)
        bad = np.empty(size, bool)
        bad[0] = u[0, 0] < self.pi_bad
        for k in range(1, size[0]):
            bad[k] = np.where(bad[k - 1], u[0, k] >= self.p_bg, u[0, k] < self.p_gb)
        return u[1] < np.where(bad, self.loss_bad, self.loss_good)

    @property
    def pi_bad(self) -> float:
        s = self.p_gb + self.p_bg
        return self.p_gb / s if s > 0 else 0.0

    @property
    def rate(self) -> float:
        return self.pi_bad * self.loss_bad + (1 - self.pi_bad) * self.loss_good


def _check_probability(name: str, p: float) -> float:
    p = float(p)
    if not (0.0 <= p <= 1.0):
        raise InputError(name, p, "a probability in [0, 1]")
    return p


def _check_latency(link: str, model: Any) -> None:
    for name, v in vars(model).items():
        if name.endswith("_s") and not isinstance(v, tuple):
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise InputError(f"latency {link} {name}", v, "in [0, 1] s")
    if isinstance(model, Uniform) and model.high_s < model.low_s:
        raise InputError(f"latency {link}", model, "low_s <= high_s")


def _check_loss(link: str, model: Any) -> Any:
    if isinstance(model, (int, float)):
        model = Bernoulli(float(model))
    for name, v in vars(model).items():
        _check_probability(f"loss {link} {name}", v)
    return model


# ----------------------------------------------------------------------------- text specs
def _numbers(field: str, text: str, parts: Sequence[str], n_min: int, n_max: int,
             valid: str) -> list[float]:
    if not (n_min <= len(parts) <= n_max):
        raise InputError(field, text, valid)
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise InputError(field, text, valid) from None
    if not all(math.isfinite(v) for v in vals):
        raise InputError(field, text, valid)
    return vals


def parse_latency(text: str, field: str = "latency") -> Any:
    """A latency model from text, in milliseconds: ``2`` or ``const:2``,
    ``uniform:LOW:HIGH``, ``exp:SHIFT:MEAN`` (shifted exponential), ``hist:FILE.csv``
    (:meth:`Empirical.from_csv`).

    Examples
    --------
    >>> parse_latency("uniform:0.5:3")
    Uniform(low_s=0.0005, high_s=0.003)
    """
    kind, _, rest = str(text).strip().partition(":")
    kind = kind.lower()
    valid = "MS, const:MS, uniform:LOW:HIGH, exp:SHIFT:MEAN (ms) or hist:FILE.csv"
    if kind in ("hist", "csv", "empirical"):
        model = Empirical.from_csv(rest)
    elif kind in ("const", "constant") or not rest:
        v = _numbers(field, text, [rest if rest else kind], 1, 1, valid)
        model = Constant(v[0] * 1e-3)
    elif kind == "uniform":
        lo, hi = _numbers(field, text, rest.split(":"), 2, 2, valid)
        model = Uniform(lo * 1e-3, hi * 1e-3)
    elif kind in ("exp", "shifted-exp", "exponential"):
        sh, mean = _numbers(field, text, rest.split(":"), 2, 2, valid)
        model = ShiftedExponential(sh * 1e-3, mean * 1e-3)
    else:
        raise InputError(field, text, valid)
    _check_latency(field, model)
    return model


def parse_loss(text: str, field: str = "loss") -> Any:
    """A loss model from text: a probability ``P`` (independent loss) or
    ``ge:P_GB:P_BG[:LOSS_BAD[:LOSS_GOOD]]`` (Gilbert-Elliott bursts).

    Examples
    --------
    >>> round(parse_loss("ge:0.01:0.2").rate, 4)
    0.0476
    """
    kind, _, rest = str(text).strip().partition(":")
    valid = "a probability P in [0, 1] or ge:P_GB:P_BG[:LOSS_BAD[:LOSS_GOOD]]"
    if kind.lower() in ("ge", "gilbert", "gilbert-elliott"):
        model = GilbertElliott(*_numbers(field, text, rest.split(":"), 2, 4, valid))
    else:
        model = Bernoulli(_numbers(field, text, [kind] if not rest else [], 1, 1, valid)[0])
    try:
        return _check_loss(field, model)
    except InputError:
        raise InputError(field, text, valid) from None


def parse_link_specs(items: Sequence[str], parse: Any, field: str) -> dict[str, Any]:
    """``LINK=SPEC`` items (``--latency damping=uniform:0.5:3``) -> {link: model}."""
    out = {}
    for item in items:
        link, eq, spec = str(item).partition("=")
        if not eq or not link.strip() or not spec.strip():
            raise InputError(field, item, "LINK=SPEC, e.g. damping=uniform:0.5:3")
        if link.strip() in out:
            raise InputError(field, item, "one spec per link")
        out[link.strip()] = parse(spec, f"{field} {link.strip()}")
    return out


# ----------------------------------------------------------------------------- schedules
def buffer_ticks(latency_s: np.ndarray, period_s: float, ticks: int = 1) -> np.ndarray:
    """Whole samples a message waits (in base ticks) for latency ``latency_s``: the rule of
    the deterministic sampled mode, ``max(round((T - T_s/2)/T_s), 0)`` ties to the shorter,
    at the block's period ``T_s`` (``ticks`` base ticks)."""
    nb = np.maximum(np.ceil((latency_s - period_s / 2) / period_s - 0.5 - 1e-9), 0)
    return nb.astype(int) * ticks


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
    """Random timing of some delayed blocks, for :func:`seactl.simulate.simulate`
    (``timing=``): ``blocks`` to drive, and :meth:`schedules` for a compiled plan.

    Parameters
    ----------
    blocks : dict
        Link name -> delayed :class:`~seactl.blockdiagram.Block`.
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
        As for :func:`seactl.simulate.simulate` (sampled mode).
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
    blocks = _link_blocks(diagram, links, sorted(set(latency) | set(loss)))
    for name, model in latency.items():
        _check_latency(name, model)
    loss = {k: _check_loss(k, v) for k, v in loss.items()}
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
class MonteCarloSummary:
    """Monte Carlo over timing realizations of a batch of SEA designs.

    Attributes
    ----------
    kind : ``"step"`` or ``"impulse"``.
    runs : realizations per design.
    stable : ``(runs,) + shape`` bool, per run.
    rms_error : ``(runs,) + shape``: RMS tracking error over the window (step: ``q_j`` /
        step - 1; impulse: ``q_j`` [rad]); NaN for unstable runs.
    peak_current_a : ``(runs,) + shape``: largest ``|i_m|`` [A] (NaN if unstable).
    fraction_stable : ``shape``: fraction of runs that stayed stable.
    rms_error_mean, rms_error_worst : ``shape``: mean and worst RMS error of stable runs.
    peak_current_worst_a : ``shape``: largest current of stable runs [A].
    worst_run : ``shape``: index of the worst run (an unstable one first, else the largest
        RMS error).
    result : the batched :class:`~seactl.simulate.SimResult`.
    """

    kind: str
    runs: int
    stable: np.ndarray
    rms_error: np.ndarray
    peak_current_a: np.ndarray
    result: SimResult = field(repr=False)

    @property
    def fraction_stable(self) -> np.ndarray:
        return self.stable.mean(axis=0)

    @property
    def rms_error_mean(self) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            return np.nanmean(np.where(self.stable, self.rms_error, np.nan), axis=0) \
                if self.stable.any() else np.full(self.stable.shape[1:], np.nan)

    @property
    def rms_error_worst(self) -> np.ndarray:
        e = np.where(self.stable, self.rms_error, -np.inf)
        return np.where(self.stable.any(axis=0), e.max(axis=0), np.nan)

    @property
    def peak_current_worst_a(self) -> np.ndarray:
        c = np.where(self.stable, self.peak_current_a, -np.inf)
        return np.where(self.stable.any(axis=0), c.max(axis=0), np.nan)

    @property
    def worst_run(self) -> np.ndarray:
        key = np.where(self.stable, self.rms_error, np.inf)
        return np.argmax(key, axis=0)

    def records(self) -> list[dict[str, Any]]:
        """One JSON-ready summary per design (flattened batch)."""
        from ._results import json_value

        cols = {"fraction_stable": self.fraction_stable, "rms_error_mean": self.rms_error_mean,
                "rms_error_worst": self.rms_error_worst,
                "peak_current_worst_a": self.peak_current_worst_a,
                "worst_run": self.worst_run}
        flat = {k: np.ravel(v) for k, v in cols.items()}
        n = flat["worst_run"].size
        return [{k: json_value(v[i]) for k, v in flat.items()} for i in range(n)]


def sea_monte_carlo(design: Any, kind: str = "step", *, latency: Mapping[str, Any] | None = None,
                    loss: Mapping[str, Any] | None = None, runs: int = 100, seed: int = 0,
                    rate_hz: float = 1000.0, t_end_s: float | None = None, zero: bool = True,
                    saturation_a: float | None = None, amplitude: float = 0.01,
                    impulse_nms: float = 0.05) -> MonteCarloSummary:
    """Monte Carlo of SEA step or impulse responses under random latency and loss.

    Parameters
    ----------
    design : seactl.loops.SEADesign
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
    from .loops import sea_diagram

    if kind not in ("step", "impulse"):
        raise InputError("kind", kind, "'step' or 'impulse'")
    t_end_s = (0.5 if kind == "step" else 1.0) if t_end_s is None else float(t_end_s)
    sat = design.actuator.max_current if saturation_a is None else float(saturation_a)
    if kind == "step":
        inputs, bound = {"q_des": Step(amplitude)}, None
    else:
        inputs = {"tau_ext": Impulse(impulse_nms)}
        bound = 1e3 * abs(impulse_nms) / float(np.min(design.Ij)) * t_end_s
    res = timed_simulation(sea_diagram(zero), design, inputs, t_end_s, latency=latency,
                           loss=loss, runs=runs, seed=seed, links=SEA_LINKS, bound=bound,
                           rates_hz=float(rate_hz), saturation={"i_m": sat},
                           outputs=("q_j", "i_m"))
    q = res.outputs["q_j"]
    err = q / amplitude - 1.0 if kind == "step" else q
    rms = np.sqrt(np.mean(err ** 2, axis=-1))
    peak = np.max(np.abs(res.outputs["i_m"]), axis=-1)
    return MonteCarloSummary(kind, int(runs), res.stable, np.where(res.stable, rms, np.nan),
                             np.where(res.stable, peak, np.nan), res)
