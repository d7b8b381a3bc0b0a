"""Robustness of a design to its actuator's parameters, by sampling."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base import progress
from seactl.base.axes import ACTUATOR_AXES, ACTUATOR_FIELDS, AXES
from seactl.base.result import Renamed, Result, flat_records, json_value, new_axes
from seactl.errors import InputError
from seactl.sweep.dataset import missing_chunks, read_sweep
from seactl.sweep.engine import SweepInterrupted, SweepResult, run_sweep, summarize
from seactl.sweep.evaluate import evaluate_chunk, evaluate_points, impedance_magnitude
from seactl.sweep.spec import SweepSpec
from seactl.systems.sea.actuators import SEAParams


# ------------------------------------------------------------------ robustness
@dataclass(frozen=True)
class RobustResult(Result):
    """One design over actuator parameter uncertainty: random samples of the plant's
    parameters (:func:`parameter_robustness`).

    Parameters
    ----------
    nominal_phase_margin_deg : float
        Phase margin of the nominal actuator [deg].
    phase_margin_deg : numpy.ndarray
        One value per sample [deg] (``inf``: no crossover).
    stable : numpy.ndarray
        Stability of each sample.
    samples : dict
        Actuator axis (``Ij``, ``bm``, ``k``, ...) -> its value per sample (rotary SI).

    Attributes
    ----------
    nominal_phase_margin_deg : float
        Phase margin of the nominal actuator [deg].
    phase_margin_deg : ndarray
        One value per sample [deg] (``inf``: no crossover).
    stable : ndarray of bool
        Stability of each sample.
    samples : dict
        Actuator axis -> its value per sample, in that axis's unit (:data:`AXES`).
    n_samples : int
        Number of samples.
    p_unstable : float
        Fraction of unstable samples (the probability of instability, dimensionless).
    """

    nominal_phase_margin_deg: float
    phase_margin_deg: np.ndarray
    stable: np.ndarray
    samples: dict[str, np.ndarray]

    n = Renamed("n_samples")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.stable.size)

    @property
    def p_unstable(self) -> float:
        """Fraction of unstable samples."""
        return float(1.0 - self.stable.mean())

    def p_unstable_ci95(self) -> tuple[float, float]:
        """Wilson 95% interval of the probability of instability.

        Returns
        -------
        tuple of float
            Lower and upper end.
        """
        z, n, p = 1.959963984540054, self.n_samples, self.p_unstable
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        lo = 0.0 if p == 0 else max(0.0, centre - half)   # exact ends (no rounding residue)
        hi = 1.0 if p == 1 else min(1.0, centre + half)
        return lo, hi

    def percentiles(self, q=(1, 5, 50, 95, 99)) -> dict[str, float]:
        """Phase-margin percentiles over the stable samples.

        Parameters
        ----------
        q : sequence of float
            Percentiles.

        Returns
        -------
        dict
            ``"p<q>"`` -> phase margin [deg] (empty without a stable finite sample).
        """
        pm = self.phase_margin_deg[self.stable & np.isfinite(self.phase_margin_deg)]
        if pm.size == 0:
            return {}
        return {f"p{x:g}": float(v) for x, v in zip(q, np.percentile(pm, q))}

    def records(self) -> list[dict[str, Any]]:
        """One flat row per sample: its actuator parameters, phase margin and stability.

        Returns
        -------
        list of dict
            The sampled axes, ``phase_margin_deg``, ``stable``.
        """
        return flat_records({**self.samples, "phase_margin_deg": self.phase_margin_deg,
                             "stable": self.stable})

    def to_dict(self) -> dict[str, Any]:
        """The distribution's summary (the keys ``seactl robust --json`` prints).

        Returns
        -------
        dict
            ``n_samples``, ``nominal_phase_margin_deg``, ``p_unstable``,
            ``p_unstable_ci95``, ``phase_margin_deg_stable`` (percentiles).
        """
        return {"n_samples": self.n_samples,
                "nominal_phase_margin_deg": json_value(self.nominal_phase_margin_deg),
                "p_unstable": json_value(self.p_unstable),
                "p_unstable_ci95": [json_value(x) for x in self.p_unstable_ci95()],
                "phase_margin_deg_stable": {k: json_value(v)
                                            for k, v in self.percentiles().items()}}

    def plot(self, ax: Any = None) -> Any:
        """Histogram of the phase margin over the stable samples, nominal marked.

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
        pm = self.phase_margin_deg[self.stable & np.isfinite(self.phase_margin_deg)]
        ax.hist(pm, bins=40, color="tab:blue")
        ax.axvline(self.nominal_phase_margin_deg, color="k", ls="--", label="nominal")
        ax.set_xlabel("phase margin [deg]")
        ax.set_ylabel("stable samples")
        ax.legend(loc="best")
        return ax


def relative_interval(actuator: SEAParams, name: str, percent: float) -> tuple[float, float]:
    """``nominal * (1 -/+ percent/100)`` of actuator axis ``name``."""
    if not (0 <= percent < 100):
        raise InputError(AXES[name].option, f"{percent:g}%", "a relative uncertainty in "
                         "[0%, 100%)")
    nom = float(getattr(actuator, ACTUATOR_FIELDS[name]))
    return nom * (1 - percent / 100), nom * (1 + percent / 100)


def parameter_robustness(spec: SweepSpec) -> RobustResult:
    """Evaluate a random-sampling spec chunk by chunk in this process.

    ``spec`` fixes one design (``f_n``, GS, delays, filters) and samples the
    plant parameters of its swept actuator axes uniformly in their intervals;
    the nominal phase margin is that of the unperturbed actuator.  ("Monte Carlo" in
    seactl means random latency and loss, :mod:`seactl.latency.montecarlo`.)

    Parameters
    ----------
    spec : SweepSpec
        ``sampling="random"``; only actuator axes swept.

    Returns
    -------
    RobustResult
        Phase margin and stability per sample, and the nominal phase margin.
    """
    if spec.sampling != "random":
        raise InputError("sampling", spec.sampling, "random for a parameter-robustness "
                         "analysis")
    bad = [n for n, _ in spec.swept if n not in ACTUATOR_AXES]
    if bad:
        raise InputError(AXES[bad[0]].option, "several values", "a single value (the "
                         "analysis varies actuator parameters of one design)")
    pm, st = [], []
    samples: dict[str, list[np.ndarray]] = {n: [] for n, _ in spec.swept}
    with progress.stage(f"parameter robustness ({spec.n_points:,} samples)",
                        total=spec.n_chunks, unit="chunks") as stage:
        for i in range(spec.n_chunks):
            t, _ = evaluate_chunk(spec, i)
            feas = t.column("feasible").to_numpy()
            if not feas.all():
                raise InputError("--fn", spec.fixed()["fn_hz"], "a feasible f_n for the "
                                 "nominal actuator")
            pm.append(t.column("phase_margin_deg").to_numpy())
            st.append(t.column("stable").to_numpy(zero_copy_only=False).astype(bool))
            for name in samples:
                samples[name].append(t.column(name).to_numpy())
            stage.advance()
    nominal = SweepSpec(spec.actuator, tuple((n, v) for n, v in spec.axes
                                             if n not in ACTUATOR_AXES))
    t0, _ = evaluate_chunk(nominal, 0)
    return RobustResult(float(t0.column("phase_margin_deg")[0].as_py()), np.concatenate(pm),
                        np.concatenate(st), {k: np.concatenate(v) for k, v in samples.items()})


def monte_carlo(spec: SweepSpec) -> RobustResult:
    """Deprecated name of :func:`parameter_robustness`.

    Parameters
    ----------
    spec : SweepSpec
        As for :func:`parameter_robustness`.

    Returns
    -------
    RobustResult
        As for :func:`parameter_robustness`.
    """
    import warnings

    warnings.warn("monte_carlo is deprecated; use parameter_robustness (Monte Carlo means "
                  "random latency and loss: seactl.latency.montecarlo)", DeprecationWarning,
                  stacklevel=2)
    return parameter_robustness(spec)


__all__ = [
    "AXES", "RobustResult", "SweepInterrupted", "SweepResult", "SweepSpec",
    "evaluate_chunk", "evaluate_points", "impedance_magnitude", "missing_chunks",
    "monte_carlo", "parameter_robustness", "read_sweep", "relative_interval", "run_sweep",
    "summarize",
]
