"""Timing models of a feedback link: latency distributions and message loss.

Latency models (seconds): :class:`Constant`, :class:`Uniform`,
:class:`ShiftedExponential` and :class:`Empirical` (a histogram, e.g. measured
latencies from a CSV); loss models: :class:`Bernoulli` (independent) and
:class:`GilbertElliott` (bursts).  Each draws samples from a numpy ``Generator``
and states its support, so the same model drives a Monte Carlo simulation
(:mod:`seactl.latency.montecarlo`) and a jitter-margin check (:mod:`seactl.latency.placement`):
a latency in ``[lower_s, upper_s(q)]`` is a nominal delay ``lower_s`` plus a
time-varying part of at most ``upper_s(q) - lower_s``, and a run of lost
messages (the receiver holding the last value) ages the value in use by one
period per lost message.  :func:`parse_latency` and :func:`parse_loss` read the
text forms the command line uses (milliseconds).

Examples
--------
>>> m = parse_latency("uniform:0.5:3")
>>> m, round(m.lower_s * 1e3, 3), round(m.upper_s() * 1e3, 3)
(Uniform(low_s=0.0005, high_s=0.003), 0.5, 3.0)
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seactl.base.outputs import note_input, reason
from seactl.errors import InputError

QUANTILE = 0.999
"""Default quantile taken as the upper end of an unbounded latency or loss-burst
distribution."""


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

    @property
    def lower_s(self) -> float:
        return float(self.latency_s)

    def upper_s(self, q: float = QUANTILE) -> float:
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

    @property
    def lower_s(self) -> float:
        return float(self.low_s)

    def upper_s(self, q: float = QUANTILE) -> float:
        return float(self.high_s)


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

    @property
    def lower_s(self) -> float:
        return float(self.shift_s)

    def upper_s(self, q: float = QUANTILE) -> float:
        """The ``q`` quantile (the tail is unbounded)."""
        return float(self.shift_s - self.scale_s * math.log1p(-q))


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

    @property
    def lower_s(self) -> float:
        return float(min(self.values_s))

    def upper_s(self, q: float = QUANTILE) -> float:
        """The smallest value with at least ``q`` of the weight at or below it."""
        v = np.asarray(self.values_s, float)
        order = np.argsort(v)
        c = np.cumsum(np.asarray(self.weights, float)[order])
        return float(v[order][np.searchsorted(c, q * c[-1] * (1 - 1e-12))])

    @classmethod
    def from_csv(cls, path: str | Path, field: str = "latency CSV") -> Empirical:
        """Read measured latencies [ms]: one column (one sample per row) or two
        (``latency_ms, count``: a histogram).  A first row that is not numbers is a header
        and names the columns (:data:`TRACE_COLUMNS`; ``latency_ms`` required); ``field``
        names the argument in errors."""
        vals, cnt = read_trace(Path(path), field)
        if np.any(vals < 0) or np.any(vals > 1000) or np.any(cnt < 0) or cnt.sum() <= 0:
            raise InputError(field, str(path), "latencies in [0, 1000] ms and counts >= 0 "
                             "with a positive total")
        uniq, inv = np.unique(vals, return_inverse=True)
        w = np.bincount(inv, weights=cnt)
        keep = w > 0
        return cls(tuple(uniq[keep] * 1e-3), tuple(w[keep]), str(path))


TRACE_COLUMNS = ("latency_ms", "count")
"""Columns a latency trace's header may name (``count``: a histogram's weights)."""


def _trace_text(path: Path, field: str) -> str:
    if not path.is_file():
        raise InputError(field, str(path), "an existing file")
    note_input(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(field, str(path), f"a readable file ({reason(exc)})") from None
    try:
        if b"\0" in data:
            raise UnicodeDecodeError("utf-8", data, 0, 1, "NUL byte")
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(field, str(path), "a UTF-8 text file (CSV); this file is binary "
                         "or UTF-16") from None


def _columns(path: Path, field: str, header: list[str]) -> list[int]:
    """Positions of ``latency_ms`` and (if named) ``count`` in ``header``."""
    names = [h.lower() for h in header]
    if "latency_ms" not in names or len(set(names)) != len(names) \
            or not set(names) <= set(TRACE_COLUMNS):
        raise InputError(field, f"{path}: header {','.join(header)}", "a header naming "
                         "the column latency_ms and optionally count (nothing else)")
    return [names.index(c) for c in TRACE_COLUMNS if c in names]


def read_trace(path: Path, field: str = "latency CSV") -> tuple[np.ndarray, np.ndarray]:
    """(latencies [ms], counts) of a trace file (:meth:`Empirical.from_csv`); every value
    finite, every row with the same columns."""
    rows = [(i + 1, cells) for i, raw in enumerate(csv.reader(_trace_text(path, field)
                                                              .splitlines()))
            if (cells := [c.strip() for c in raw if c.strip()])]
    cols: list[int] | None = None
    if rows:
        try:
            [float(c) for c in rows[0][1]]
        except ValueError:
            cols = _columns(path, field, rows[0][1])
            width = len(rows[0][1])
            rows = rows[1:]
    if cols is None:
        width = len(rows[0][1]) if rows else 1
        cols = list(range(width)) if width <= 2 else []
    if not rows or not cols:
        raise InputError(field, str(path), "one column (latency_ms) or two (latency_ms, "
                         "count), with at least one latency")
    table = np.empty((len(rows), len(cols)))
    for k, (line, cells) in enumerate(rows):
        try:
            if len(cells) != width:
                raise ValueError
            table[k] = [float(cells[c]) for c in cols]
        except ValueError:
            raise InputError(field, f"{path}:{line}", f"{width} number(s) per row") from None
        if not np.all(np.isfinite(table[k])):
            raise InputError(field, f"{path}:{line}", "finite numbers (no NaN or inf)")
    return table[:, 0], (table[:, 1] if len(cols) == 2 else np.ones(len(rows)))


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

    def burst(self, q: float = QUANTILE) -> int:
        """Consecutive losses not exceeded with probability ``q`` (``p^m <= 1 - q``)."""
        if self.p <= 0:
            return 0
        if self.p >= 1:
            raise InputError("loss", self.p, "< 1 for a bounded burst")
        return max(0, math.ceil(math.log(1 - q) / math.log(self.p) - 1e-9))


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

    def burst(self, q: float = QUANTILE) -> int:
        """Consecutive losses not exceeded with probability ``q``: a bad spell lasts ``m``
        messages or more with probability ``(1 - p_bg)^(m-1)`` (losing each with
        ``loss_bad``); conservative: every message of the spell lost."""
        if self.rate <= 0:
            return 0
        stay = max(1 - self.p_bg, self.loss_good)
        if stay >= 1:
            raise InputError("loss p_bg", self.p_bg, "> 0 for a bounded burst")
        if stay <= 0:
            return 1
        return 1 + max(0, math.ceil(math.log(1 - q) / math.log(stay) - 1e-9))


def _check_probability(name: str, p: float) -> float:
    p = float(p)
    if not (0.0 <= p <= 1.0):
        raise InputError(name, p, "a probability in [0, 1]")
    return p


def check_latency(link: str, model: Any) -> None:
    for name, v in vars(model).items():
        if name.endswith("_s") and not isinstance(v, tuple):
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise InputError(f"latency {link} {name}", v, "in [0, 1] s")
    if isinstance(model, Uniform) and model.high_s < model.low_s:
        raise InputError(f"latency {link}", model, "low_s <= high_s")


def check_loss(link: str, model: Any) -> Any:
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
        model = Empirical.from_csv(rest, field)
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
    check_latency(field, model)
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
        return check_loss(field, model)
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


