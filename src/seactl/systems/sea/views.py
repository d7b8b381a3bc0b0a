"""The SEA's views of the generic machinery: the margins of its cascade (outer impedance
loop with the inner torque loop closed) and its step and impulse responses.

:mod:`seactl.analysis.margins` and :mod:`seactl.simulate.engine` know block diagrams, not the SEA;
this
module puts them together with the SEA's diagram (:mod:`seactl.systems.sea.loops`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from seactl.analysis.margins import Margins, default_grid, loop_margins
from seactl.errors import InputError
from seactl.simulate.engine import simulate
from seactl.simulate.inputs import Impulse, Step
from seactl.simulate.metrics import impulse_metrics, step_metrics
from seactl.simulate.results import SEAResponse, SimResult
from seactl.simulate.verdict import RECOVERY_BAND
from seactl.systems.sea.loops import outer_loop, sea_diagram

__all__ = ["sea_impulse", "sea_margins", "sea_reference_frequency", "sea_sampled_margins",
           "sea_sampled_roots", "sea_step"]


def sea_reference_frequency(design: Any) -> np.ndarray:
    """A frequency scale [rad/s] for the SEA's bracketing grid: the fourth root of the
    delay-free closed-loop constant term (= w_n for critically-damped designs), or the
    spring resonance when there is no stiffness feedback."""
    u = 1 + design.beta * design.Ktau
    c0 = u * design.k * design.Kq / (design.Im * design.Ij)
    spring = np.sqrt(design.k * (design.Im + design.Ij) / (design.Im * design.Ij))
    return np.where(c0 > 0, np.sqrt(np.sqrt(np.abs(c0))), spring)


def sea_margins(design: Any, omega: np.ndarray | None = None) -> Margins:
    """Margins of the SEA outer impedance loop (inner torque loop closed).

    The open loop's right-half-plane poles are those of the closed inner torque
    loop, counted by the Nyquist criterion on the inner loop (whose own open
    loop ``P_F C e^{-s T_tau}`` is stable), so ``stable`` is the stability of
    the whole cascaded system.

    Examples
    --------
    Table I, f_n = 12 Hz:

    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 12.0),
    ...               Timing.from_ms(0.5, 2.0, 0.5, 50.0, 100.0))
    >>> round(float(sea_margins(d).phase_margin_deg), 1)
    45.1
    """
    if omega is None:
        omega = default_grid(sea_reference_frequency(design))
    return loop_margins(outer_loop(), design, omega)


def sea_sampled_margins(design: Any, rate_hz: Any) -> Any:
    """Certified verdict and margins of the SEA loop sampled at ``rate_hz`` (a rate for
    both processes, or a mapping ``{"embedded": ..., "high-level": ...}``), broken where
    :func:`sea_margins` breaks it (``q_sens``, inner loop closed;
    :func:`seactl.simulate.sampled.sampled_margins`)."""
    from seactl.simulate.sampled import sampled_margins
    from seactl.systems.sea.loops import SEA_DIAGRAM

    return sampled_margins(SEA_DIAGRAM, design, "q_sens", rate_hz,
                           sea_reference_frequency(design))


def sea_sampled_roots(design: Any, rate_hz: Any, zero: bool = True) -> Any:
    """The sampled SEA loop's z-plane roots and certified verdict
    (:func:`seactl.simulate.sampled.sampled_roots`)."""
    from seactl.simulate.sampled import sampled_roots

    return sampled_roots(sea_diagram(zero), design, rate_hz)


def _sampled_info(res: SimResult, design: Any, rate_hz: Any, zero: bool) -> None:
    """The sampled loop's certified verdict in ``res.info`` (``sampled_verdict``,
    ``sampled_unstable_modes``, ``sampled_rate``) beside the response; where it is
    certified it also replaces the simulation's own count (``unstable_modes``) that
    :func:`seactl.simulate.verdict.judge_response` reads."""
    r = sea_sampled_roots(design, rate_hz, zero)
    res.info.update(sampled_verdict=r.verdict, sampled_unstable_modes=r.unstable_modes,
                    sampled_rate=r.rate_label)
    own = np.asarray(res.info.get("unstable_modes", r.unstable_modes))
    res.info["unstable_modes"] = np.where(r.unstable_modes >= 0, r.unstable_modes, own)


def _sea_kwargs(design, mode, rate_hz, saturation_a):
    """Sampled-mode defaults for the SEA: one rate for both processes, the actuator's
    current limit."""
    if mode != "sampled":
        if saturation_a is not None:
            raise InputError("saturation", saturation_a, "used in sampled mode only")
        return {}
    sat = design.actuator.max_current if saturation_a is None else float(saturation_a)
    if not sat > 0:
        raise InputError("saturation [A]", sat, "> 0 (inf: no limit)")
    return {"rates_hz": float(rate_hz), "saturation": {"i_m": sat}}


def sea_right_roots(design: Any, zero: bool = True) -> np.ndarray:
    """Certified count of the SEA loop's closed-loop roots with ``Re s > 0`` per design
    (the whole exact-delay diagram the continuous simulation runs; -1 where uncertain)."""
    from seactl.analysis.margins import closed_loop_right_roots

    return closed_loop_right_roots(sea_diagram(zero), design, sea_reference_frequency(design))


def sea_step(design: Any, *, zero: bool = True, mode: str = "continuous",
             rate_hz: float = 1000.0, t_end_s: float = 0.5, saturation_a: float | None = None,
             amplitude: float = 1.0, dt: float | None = None, **kwargs: Any) -> SEAResponse:
    """Step response ``q_j / q_des`` of an :class:`~seactl.systems.sea.loops.SEADesign` batch.

    Sampled mode limits the motor current to ``actuator.max_current`` unless
    ``saturation_a`` is given (``inf``: no limit).  The position is normalized by
    ``amplitude`` (rad; with saturation the response depends on it).

    Examples
    --------
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 14.0),
    ...               Timing.from_ms(1, 1, 1, 50, 100))
    >>> r = sea_step(d, t_end_s=0.4)
    >>> bool(r.result.stable), bool(abs(r.metrics.steady_state_error) < 1e-4)
    (True, True)
    """
    res = simulate(sea_diagram(zero), design, {"q_des": Step(amplitude)}, t_end_s, mode=mode,
                   outputs=("q_j", "i_m"), dt=dt, **_sea_kwargs(design, mode, rate_hz,
                                                                 saturation_a), **kwargs)
    if mode == "sampled" and not set(kwargs) - {"record_dt"}:
        _sampled_info(res, design, rate_hz, zero)
    pos = res.outputs["q_j"] / amplitude
    res = SimResult(res.mode, res.t_s, {"q_j": pos, "i_m": res.outputs["i_m"]}, res.stable,
                    res.left_bounds_s, res.bound, res.info)
    return SEAResponse("step", res, step_metrics(res.t_s, pos, res.stable, res.left_bounds_s))


def sea_impulse(design: Any, *, impulse_nms: float = 0.05, zero: bool = True,
                mode: str = "continuous", rate_hz: float = 1000.0, t_end_s: float = 1.0,
                saturation_a: float | None = None, band: float = RECOVERY_BAND,
                dt: float | None = None, **kwargs: Any) -> SEAResponse:
    """Response of ``q_j`` [rad] to an angular impulse ``impulse_nms`` [N m s] of external
    torque on the joint at ``t = 0`` (``q_des = 0``), with :class:`ImpulseMetrics`."""
    if not (math.isfinite(impulse_nms) and impulse_nms != 0):
        raise InputError("impulse [N m s]", impulse_nms, "a finite non-zero number")
    # Bound: 1e3 times the free-joint peak velocity times the window (rad), never tiny.
    ij = float(np.min(design.Ij))
    bnd = 1e3 * abs(impulse_nms) / ij * t_end_s
    res = simulate(sea_diagram(zero), design, {"tau_ext": Impulse(impulse_nms)}, t_end_s,
                   mode=mode, outputs=("q_j", "i_m"), dt=dt, bound=bnd,
                   **_sea_kwargs(design, mode, rate_hz, saturation_a), **kwargs)
    if mode == "sampled" and not set(kwargs) - {"record_dt"}:
        _sampled_info(res, design, rate_hz, zero)
    m = impulse_metrics(res.t_s, res.outputs["q_j"], res.stable, res.left_bounds_s, band)
    return SEAResponse("impulse", res, m)
