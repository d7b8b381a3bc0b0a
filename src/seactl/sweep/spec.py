"""What a sweep covers: axes, sampling and the points of each chunk."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass
from functools import cached_property, lru_cache
from typing import Any

import numpy as np

from seactl.base.axes import ACTUATOR_FIELDS, AXES, SAMPLINGS
from seactl.errors import InputError
from seactl.systems.sea.actuators import SEAParams

FORMAT = "seactl-sweep/1"

TEMPLATE_MARKER = "SEACTL_SWEEP_TEMPLATE"
"""Environment variable that is ``"1"`` only while :func:`start_worker_template` starts
the fork server: it tells :mod:`seactl.sweep.template`, imported by that server, to
prepare the workers' template (imported anywhere else, it only defines things)."""



OUTPUTS: dict[str, str] = {
    "point": "point index in the sweep's deterministic order",
    "feasible": "a critically-damped gain set with four positive gains exists",
    "Kq": "stiffness gain [N m/rad] (null: infeasible)",
    "Bq": "damping gain [N m s/rad] (null: infeasible)",
    "Ktau": "torque P gain [A/(N m)] (null: infeasible)",
    "Btau": "torque D gain [A s/(N m)] (null: infeasible)",
    "phase_margin_deg": "phase margin [deg] (inf: no gain crossover)",
    "crossover_hz": "gain crossover [Hz] (null: none)",
    "gain_margin_db": "gain margin [dB] (inf: no phase crossover)",
    "phase_crossover_hz": "phase crossover [Hz] (null: none)",
    "delay_margin_ms": "delay margin [ms] (0: unstable, inf: no crossover)",
    "stable": "closed loop stable (Nyquist; null: infeasible)",
    "unstable_poles": "closed-loop right-half-plane poles (null: infeasible)",
}


def z_column(f_hz: float) -> str:
    """Column name of the impedance magnitude at ``f_hz``."""
    return f"z_mag_{f_hz:g}hz"


# ------------------------------------------------------------------ spec
@dataclass(frozen=True)
class SweepSpec:
    """What to sweep; everything a chunk needs to regenerate its points.

    Parameters
    ----------
    actuator : SEAParams
        Nominal actuator (gains are designed for it; also the default plant).
    axes : tuple of (name, values)
        Per axis of :data:`AXES`: its values (grid), or the interval spanned by
        them (sampling modes).  Unlisted axes keep their default.
    sampling : {"grid", "random", "lhs"}
    n_samples : int
        Number of points for ``random`` / ``lhs``.
    seed : int
        Seed of the sampling modes (chunk ``i`` draws from ``(seed, i)``).
    chunk_size : int
        Points per chunk (bounds memory: a chunk's arrays grow with it; ``seactl bench``
        reports the peak of a default chunk).
    z_freqs_hz : tuple of float
        Frequencies [Hz] at which to report the impedance magnitude ``|Z|``.
    """

    actuator: SEAParams
    axes: tuple[tuple[str, tuple[float, ...]], ...] = ()
    sampling: str = "grid"
    n_samples: int = 0
    seed: int = 0
    chunk_size: int = 5_000
    z_freqs_hz: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.sampling not in SAMPLINGS:
            raise InputError("sampling", self.sampling, "one of " + ", ".join(SAMPLINGS))
        if int(self.chunk_size) != self.chunk_size or self.chunk_size < 1:
            raise InputError("chunk_size", self.chunk_size, "an integer >= 1")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise InputError("seed", self.seed, "an integer >= 0")
        if self.sampling != "grid" and (int(self.n_samples) != self.n_samples
                                        or self.n_samples < 1):
            raise InputError("n_samples", self.n_samples, f"an integer >= 1 for sampling "
                             f"{self.sampling!r}")
        norm: dict[str, tuple[float, ...]] = {}
        for name, values in self.axes:
            if name not in AXES:
                raise InputError("axis", name, "one of " + ", ".join(AXES))
            if name in norm:
                raise InputError(name, name, "given once")
            vals = tuple(float(v) for v in np.ravel(values))
            if not vals:
                raise InputError(name, "", "at least one value")
            _check_axis(name, np.asarray(vals))
            norm[name] = vals
        from seactl.base.limits import check_range

        for f in self.z_freqs_hz:
            check_range("z_freqs_hz [Hz]", f, "freq_hz")
        # canonical order (AXES order) so that equal sweeps hash equally
        object.__setattr__(self, "axes", tuple((n, norm[n]) for n in AXES if n in norm))
        object.__setattr__(self, "z_freqs_hz", tuple(float(f) for f in self.z_freqs_hz))

    # ---- derived structure
    @property
    def swept(self) -> tuple[tuple[str, tuple[float, ...]], ...]:
        """Axes with more than one value (columns of the dataset)."""
        return tuple((n, v) for n, v in self.axes if len(v) > 1)

    def fixed(self) -> dict[str, float]:
        """Value of every axis that does not vary."""
        given = dict(self.axes)
        out = {}
        for name, info in AXES.items():
            if name in given and len(given[name]) > 1:
                continue
            if name in given:
                out[name] = given[name][0]
            elif info.default is not None:
                out[name] = info.default
            else:
                out[name] = float(getattr(self.actuator, ACTUATOR_FIELDS[name]))
        return out

    @property
    def grid_shape(self) -> tuple[int, ...]:
        return tuple(len(v) for _, v in self.swept)

    @property
    def n_points(self) -> int:
        if self.sampling == "grid":
            return int(np.prod(self.grid_shape, dtype=np.int64))
        return int(self.n_samples)

    @property
    def n_chunks(self) -> int:
        return -(-self.n_points // self.chunk_size)

    def chunk_range(self, i: int) -> tuple[int, int]:
        start = i * self.chunk_size
        return start, min(start + self.chunk_size, self.n_points)

    # ---- identity
    def as_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT, "seactl": _seactl_version(),
            "actuator": asdict(self.actuator), "sampling": self.sampling,
            "n_samples": self.n_samples if self.sampling != "grid" else None,
            "seed": self.seed if self.sampling != "grid" else None,
            "chunk_size": self.chunk_size,
            "axes": {n: [json_float(x) for x in v] for n, v in self.axes},
            "z_freqs_hz": list(self.z_freqs_hz),
        }

    @cached_property
    def hash(self) -> str:
        """SHA-256 of :meth:`as_json` (computed once: it travels with the spec to the
        workers, which stamp it on every chunk)."""
        text = json.dumps(self.as_json(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    # ---- points
    def points(self, start: int, stop: int, chunk: int | None = None) -> dict[str, np.ndarray]:
        """Values of the swept axes for points ``[start, stop)``.

        For the sampling modes ``[start, stop)`` must be chunk ``chunk``'s range
        (samples are drawn per chunk)."""
        swept = self.swept
        n = stop - start
        if self.sampling == "grid":
            if not swept:
                return {}
            multi = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.grid_shape)
            return {name: np.asarray(vals)[m] for (name, vals), m in zip(swept, multi)}
        if chunk is None or self.chunk_range(chunk) != (start, stop):
            raise ValueError("sampled points are generated per chunk")
        d = len(swept)
        rng = np.random.default_rng([self.seed, chunk])
        if d == 0:
            return {}
        if self.sampling == "random":
            u = rng.random((n, d))
        else:
            from scipy.stats import qmc

            u = qmc.LatinHypercube(d, rng=rng).random(n)
        out = {}
        for k, (name, vals) in enumerate(swept):
            lo, hi = min(vals), max(vals)
            out[name] = lo + (hi - lo) * u[:, k]
        return out


@lru_cache(maxsize=1)
def _seactl_version() -> str:
    """The installed seactl's version (read from its metadata once per process: each read
    parses the package's metadata file)."""
    from importlib.metadata import version

    return version("seactl")


def json_float(x: float) -> float | str:
    return x if math.isfinite(x) else repr(x)


def _check_axis(name: str, vals: np.ndarray) -> None:
    AXES[name].check(vals, f"{name} [{AXES[name].unit}]" if AXES[name].unit else name)
