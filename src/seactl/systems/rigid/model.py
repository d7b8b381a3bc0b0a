"""Rigid actuator with distributed impedance control (docs/theory/delays.md).

Plant ``1/(m s^2 + b s)`` driven by a force command; controller::

    F = K (x_des - e^{-T_s s} x) - B Q(s) s e^{-T_d s} x,   Q = 1/(T_f s + 1)

with the stiffness feedback on the high-level process (delay ``T_s``) and the
damping feedback on the embedded process (delay ``T_d``).  *Monolithic*
placements run both loops on one process (``T_s = T_d``); *distributed* ones
give each loop its own delay.

The loop is written once, as :data:`RIGID_DIAGRAM` (a
:class:`~seactl.diagram.blockdiagram.BlockDiagram`); margins use the generic
:func:`seactl.analysis.margins.loop_margins`.  The position measurement is split into
two taps, ``x_s`` (read by the stiffness block) and ``x_d`` (read by the
damping block), so that each loop can be broken on its own
(:mod:`seactl.latency.maps`).

Gains are critically damped ignoring delays: ``K = m w_n^2`` and
``B = 2 m w_n - b`` (``passive_damping=False``: ``B = 2 m w_n``).

Examples
--------
>>> d = RigidDesign.from_fn(UT_LINEAR, 8.0, T_s=1.5e-3, T_d=1.5e-3)
>>> round(float(d.K)), round(float(d.B))
(646814, 24486)
>>> m = rigid_margins(d)
>>> bool(m.stable), round(float(m.phase_margin_deg), 1)
(True, 69.4)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np

from seactl.analysis.margins import Margins, default_grid, loop_margins
from seactl.base.params import check, load_params, nonnegative, positive
from seactl.base.validate import finite_array
from seactl.diagram.blockdiagram import Block, BlockDiagram, DesignBatch, Transfer
from seactl.errors import InfeasibleDesignError, InputError
from seactl.simulate.engine import simulate
from seactl.simulate.inputs import Step
from seactl.simulate.metrics import step_metrics
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.loops import filter_time_constant


# ------------------------------------------------------------------ parameters
@dataclass(frozen=True)
class RigidParams:
    """Immutable, validated rigid (stiff drivetrain) linear actuator, SI units.

    Attributes
    ----------
    mass : float
        Effective output mass ``m`` [kg].
    damping : float
        Passive damping ``b`` [N s/m].
    current_to_force : float
        ``beta``: motor current to output force [N/A].
    max_current : float
        Motor current limit [A]; the force limit is ``beta * max_current``.

    Examples
    --------
    >>> round(UT_LINEAR.max_force)
    6243
    >>> try:
    ...     RigidParams(mass=-1.0, damping=0.0, current_to_force=1.0)
    ... except InputError as exc:
    ...     print(exc)
    invalid mass = -1.0: must be > 0 and finite [kg]
    """

    mass: Annotated[float, positive("effective output mass m [kg]")]
    damping: Annotated[float, nonnegative("passive damping b [N s/m]")]
    current_to_force: Annotated[float, positive("beta, motor current to force [N/A]")]
    max_current: Annotated[float, positive("motor current limit [A]")] = 30.0
    name: str = "custom"

    def __post_init__(self) -> None:
        check(self)

    @property
    def m(self) -> float:
        return self.mass

    @property
    def b(self) -> float:
        return self.damping

    @property
    def beta(self) -> float:
        return self.current_to_force

    @property
    def max_force(self) -> float:
        """Force limit [N] = ``beta * max_current``."""
        return self.current_to_force * self.max_current


UT_LINEAR = RigidParams(
    mass=256.0, damping=1250.0,
    # same drivetrain as the UT-SEA: beta = eta N k_tau = 208.1 N/A (docs/theory/units.md)
    current_to_force=UT_SEA.current_to_torque / UT_SEA.pulley_radius,
    max_current=30.0, name="ut-linear")
"""The UT linear actuator of the paper's step experiment (m = 256 kg, b = 1250 N s/m)."""

RIGID_PRESETS: dict[str, RigidParams] = {"ut-linear": UT_LINEAR}


def load_rigid(spec: str | Path) -> RigidParams:
    """Load a rigid actuator by preset name (``ut-linear``) or from a TOML file.

    The TOML file holds the fields of :class:`RigidParams` at top level (or
    under an ``[actuator]`` table), SI units::

        name = "my-actuator"
        mass = 256.0               # kg
        damping = 1250.0           # N s/m
        current_to_force = 208.1   # N/A
        max_current = 30.0         # A

    Raises
    ------
    InputError
        Unknown preset, unreadable file, unknown key or out-of-range value.

    Examples
    --------
    >>> load_rigid("ut-linear").mass
    256.0
    """
    return load_params(spec, RIGID_PRESETS, RigidParams)


# ------------------------------------------------------------------ gains and designs
@dataclass(frozen=True)
class RigidGains:
    """Impedance gains of the rigid actuator (arrays broadcast as a batch).

    Attributes
    ----------
    K : stiffness gain [N/m];  B : damping gain [N s/m].
    """

    K: np.ndarray
    B: np.ndarray

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, finite_array(f.name, getattr(self, f.name),
                                                           minimum=0.0))

    @property
    def shape(self) -> tuple[int, ...]:
        return np.broadcast_shapes(np.shape(self.K), np.shape(self.B))


def min_feasible_fn(actuator: RigidParams, passive_damping: bool = True) -> float:
    """Lowest ``f_n`` [Hz] with a positive damping gain (``2 m w_n > b``), 0 without the
    ``-b`` term."""
    return actuator.b / (4 * math.pi * actuator.m) if passive_damping else 0.0


def rigid_gains(actuator: RigidParams, fn_hz, *, passive_damping: bool = True) -> RigidGains:
    """Critically-damped gains ``K = m w_n^2``, ``B = 2 m w_n - b`` (delays ignored).

    Parameters
    ----------
    actuator : RigidParams
    fn_hz : array_like
        Closed-loop natural frequency ``f_n`` [Hz].
    passive_damping : bool
        Subtract the passive damping ``b`` from ``B`` (default).  ``False`` gives
        ``B = 2 m w_n`` (the closed loop is then over-damped by ``b``).

    Raises
    ------
    InfeasibleDesignError
        If ``B`` would be zero or negative (``f_n <= b / (4 pi m)``).

    Examples
    --------
    >>> g = rigid_gains(UT_LINEAR, 12.0)
    >>> round(float(g.K)), round(float(g.B))
    (1455332, 37354)
    >>> try:
    ...     rigid_gains(UT_LINEAR, 0.2)
    ... except InfeasibleDesignError as exc:
    ...     print(exc.feasible_hz[0][0])
    0.388...
    """
    fn = finite_array("fn [Hz]", fn_hz, minimum=0.0, strict=True)
    a = actuator
    wn = 2 * np.pi * fn
    B = 2 * a.m * wn - (a.b if passive_damping else 0.0)
    bad = B <= 0
    if bad.any():
        lo = min_feasible_fn(a, passive_damping)
        what = ", ".join(f"{f:g}" for f in np.unique(fn[bad])[:6])
        raise InfeasibleDesignError(
            f"no positive damping gain B = 2 m w_n - b exists for f_n = {what} Hz on actuator "
            f"'{a.name}'; feasible: f_n > {lo:.4g} Hz", fn_hz=np.unique(fn[bad]),
            feasible_hz=[(lo, math.inf)])
    return RigidGains(a.m * wn**2, B)


@dataclass(frozen=True)
class RigidDesign(DesignBatch):
    """A batch of rigid-actuator designs: actuator, gains, delays, velocity filter.

    Attributes used by :data:`RIGID_DIAGRAM` are arrays of the common batch shape:
    ``m``, ``b``, ``K``, ``B``, ``T_s`` (stiffness delay [s]), ``T_d`` (damping
    delay [s]) and ``Tf_v`` (velocity-filter time constant [s], 0 = no filter).

    Parameters
    ----------
    actuator : RigidParams
    gains : RigidGains
    T_s, T_d : array_like
        Stiffness- and damping-feedback delays [s].
    f_v : array_like or None
        Velocity filter cut-off ``Q = 2 pi f_v / (s + 2 pi f_v)`` [Hz]; None: no filter.
    """

    actuator: RigidParams
    gains: RigidGains
    T_s: Any = 0.0
    T_d: Any = 0.0
    f_v: Any = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_s", finite_array("T_s [s]", self.T_s, minimum=0.0))
        object.__setattr__(self, "T_d", finite_array("T_d [s]", self.T_d, minimum=0.0))
        if self.f_v is not None:
            object.__setattr__(self, "f_v", finite_array("f_v [Hz]", self.f_v, minimum=0.0,
                                                         strict=True, allow_inf=True))

    @classmethod
    def from_fn(cls, actuator: RigidParams, fn_hz, *, T_s=0.0, T_d=0.0, f_v=None,
                passive_damping: bool = True) -> RigidDesign:
        """Critically-damped design(s) for ``f_n`` [Hz] (see :func:`rigid_gains`)."""
        return cls(actuator, rigid_gains(actuator, fn_hz, passive_damping=passive_damping),
                   T_s, T_d, f_v)

    def _fields(self) -> dict[str, Any]:
        a, g = self.actuator, self.gains
        return dict(m=a.m, b=a.b, K=g.K, B=g.B, T_s=self.T_s, T_d=self.T_d,
                    Tf_v=filter_time_constant(self.f_v, "f_v [Hz]"))

    @property
    def wn(self) -> np.ndarray:
        """Delay-free natural frequency ``sqrt(K/m)`` [rad/s]."""
        return np.sqrt(self.K / self.m)

    def with_delays(self, T_s=None, T_d=None) -> RigidDesign:
        """Same design with other delays [s] (``None`` keeps the current one)."""
        return replace(self, T_s=self.T_s if T_s is None else T_s,
                       T_d=self.T_d if T_d is None else T_d)


# ------------------------------------------------------------------ the block diagram
def _rigid_blocks() -> list[Block]:
    ctrl, plant = "controller", "plant"
    return [
        Block("K_ref", "x_des", "F_des", num=lambda p: (p.K,), role=ctrl, process="high-level"),
        Block("x_sensor", "x", "x_sens", role="sensor"),
        # one tap per loop, so each loop can be broken alone
        Block("s_tap", "x_sens", "x_s", role=ctrl),
        Block("d_tap", "x_sens", "x_d", role=ctrl),
        Block("K_fb", "x_s", "F_des", num=lambda p: (-p.K,), delay="T_s", role=ctrl,
              process="high-level"),
        Block("B_fb", "x_d", "F_des", num=lambda p: (-p.B, 0.0), den=lambda p: (p.Tf_v, 1.0),
              delay="T_d", role=ctrl, process="embedded"),
        # physics: the force command is the actuator force (saturated in simulations)
        Block("drive", "F_des", "F_net", role=plant),
        Block("ext_load", "F_ext", "F_net", role=plant),
        Block("mass", "F_net", "x", den=lambda p: (p.m, p.b, 0.0), role=plant),
    ]


RIGID_DIAGRAM = BlockDiagram("rigid", _rigid_blocks())
"""The rigid actuator loop.  Signals: inputs ``x_des`` [m], ``F_ext`` [N]; ``F_des``
force command, ``F_net``, ``x`` position, sensor ``x_sens`` and its taps ``x_s``
(stiffness) and ``x_d`` (damping)."""


def rigid_loop() -> Transfer:
    """Whole loop ``L = (K e^{-T_s s} + B Q s e^{-T_d s}) / (m s^2 + b s)``."""
    return RIGID_DIAGRAM.loop("x_sens")


def rigid_closed_loop() -> Transfer:
    """Position response ``x / x_des``."""
    return RIGID_DIAGRAM.transfer("x", "x_des")


def rigid_compliance() -> Transfer:
    """Compliance ``x / F_ext`` (its inverse is the closed-loop stiffness)."""
    return RIGID_DIAGRAM.transfer("x", "F_ext")


def rigid_grid(design: RigidDesign) -> np.ndarray:
    """Bracketing grid [rad/s] around each design's ``w_n`` (four decades)."""
    return default_grid(design.wn)


def rigid_margins(design: RigidDesign, omega: np.ndarray | None = None) -> Margins:
    """Phase/gain/delay margins and Nyquist stability of the whole rigid loop (the open
    loop is stable: poles at 0 and ``-b/m``)."""
    return loop_margins(rigid_loop(), design, rigid_grid(design) if omega is None else omega)


def static_stiffness(design: Any, compliance: Transfer, scale: np.ndarray) -> np.ndarray:
    """Closed-loop stiffness at (nearly) zero frequency: ``1/|compliance(j 1e-6 scale)|``."""
    c = compliance(design, 1j * 1e-6 * np.asarray(scale, float)[..., None])[..., 0]
    with np.errstate(divide="ignore"):
        return 1.0 / np.abs(c)


# ------------------------------------------------------------------ the step experiment
PAPER_DELAYS_MS = ((1.0, 1.0), (15.0, 1.0), (1.0, 15.0), (15.0, 15.0))
"""The four (stiffness, damping) buffer delays [ms] of the paper's step experiment."""


@dataclass(frozen=True)
class StepExperiment:
    """Sampled step responses of the rigid actuator (see :func:`step_experiment`).

    Arrays are indexed ``[delay combination, f_n, time]`` (or without the time axis).

    Attributes
    ----------
    t_s : sample times [s].
    position : response normalized to the step (0 before, 1 at the target).
    force : commanded force [N] (after saturation where enabled).
    fn_hz : natural frequencies [Hz];  delays_ms : (stiffness, damping) buffer delays [ms].
    effective_delays_s : (stiffness, damping) effective delays ``T_s/2 + n T_s`` [s], per
        combination (what the continuous-time margins use).
    saturated_fraction : fraction of samples at the force limit.
    residual_pp : peak-to-peak of the normalized response over the last quarter of the
        window (a limit cycle under saturation keeps this large).
    out_of_control : the simulator saw divergence, or ``residual_pp > residual_tol``.
    linear_stable, linear_pm_deg : Nyquist stability and phase margin of the
        continuous loop with the effective delays (no saturation).
    overshoot_pct, settling_time_s : of the in-control runs (NaN otherwise).
    sampled_unstable_modes : the simulated loop's certified count of modes outside the unit
        circle (:func:`seactl.simulate.sampled.sampled_roots`, no saturation; -1 uncertain).
    """

    t_s: np.ndarray
    position: np.ndarray
    force: np.ndarray
    fn_hz: np.ndarray
    delays_ms: tuple[tuple[float, float], ...]
    effective_delays_s: np.ndarray
    saturated_fraction: np.ndarray
    residual_pp: np.ndarray
    residual_tol: float
    out_of_control: np.ndarray
    linear_stable: np.ndarray
    linear_pm_deg: np.ndarray
    overshoot_pct: np.ndarray
    settling_time_s: np.ndarray
    force_limit_n: float | None
    rate_hz: float
    sampled_unstable_modes: np.ndarray | None = None

    def panel_label(self, k: int) -> str:
        ts, td = self.delays_ms[k]
        return f"stiffness {ts:g} ms, damping {td:g} ms"


def step_experiment(actuator: RigidParams = UT_LINEAR, fn_hz=(4.0, 8.0, 12.0), *,
                    delays_ms=PAPER_DELAYS_MS, f_v: float | None = 50.0,
                    passive_damping: bool = True, rate_hz: float = 1000.0,
                    x_from_m: float = 0.131, x_to_m: float = 0.135, t_end_s: float = 1.0,
                    saturate: bool = True, residual_tol: float = 0.05) -> StepExperiment:
    """Replica of the paper's step experiment (sampled controllers, delay buffers).

    Both loops run at ``rate_hz`` on the sampled simulator of :mod:`seactl.simulate.engine` on
    :data:`RIGID_DIAGRAM` (Tustin-discretized derivative filter, zero-order hold on the
    force, position sampled every tick).  A delay of ``n`` ms is a buffer of ``n`` samples
    at 1 kHz, so the effective delay is ``n + 0.5`` ms (``T_d = T_s/2 + T_e``).  The step is
    ``x_from_m -> x_to_m``; the plant is linear, so the response is simulated in deviation
    from ``x_from_m`` and normalized to 0..1.  With ``saturate`` the force command is
    clipped at ``beta * max_current``.
    """
    fn = finite_array("fn [Hz]", fn_hz, minimum=0.0, strict=True).reshape(-1)
    rate = float(finite_array("rate [Hz]", rate_hz, minimum=0.0, strict=True))
    dl = np.asarray(delays_ms, float).reshape(-1, 2)
    finite_array("delays [ms]", dl, minimum=0.0)
    step = float(x_to_m) - float(x_from_m)
    if step == 0 or not math.isfinite(step):
        raise InputError("step [m]", step, "a finite, nonzero displacement")
    # the paper's delays count buffer samples: pass the effective delay of that buffer,
    # T_s/2 + n T_s (never shorter than the request), which the simulator maps back to n
    period = 1.0 / rate
    eff = np.round(dl * 1e-3 / period) * period + period / 2
    d = RigidDesign.from_fn(actuator, fn[None, :], T_s=eff[:, :1], T_d=eff[:, 1:],
                            f_v=f_v, passive_damping=passive_damping)
    limit = actuator.max_force if saturate else None
    res = simulate(RIGID_DIAGRAM, d, {"x_des": Step(step)}, t_end_s=t_end_s,
                   mode="sampled", rates_hz=rate, outputs=("x", "F_des"),
                   saturation={"F_des": limit} if saturate else None)
    t_s, x, force = res.t_s, res.outputs["x"], res.outputs["F_des"]
    y = x / step
    if saturate:
        force = np.clip(force, -limit, limit)
        sat = np.mean(np.abs(force) >= limit * (1 - 1e-9), axis=-1)
    else:
        sat = np.zeros(d.shape)
    tail = y[..., -max(2, y.shape[-1] // 4):]
    resid = np.where(np.isfinite(tail).all(axis=-1), np.ptp(tail, axis=-1), np.inf)
    ooc = ~res.stable | (resid > residual_tol)
    met = step_metrics(t_s, y, ~ooc, res.left_bounds_s)
    lin = rigid_margins(d)
    from seactl.simulate.sampled import sampled_roots

    sampled = sampled_roots(RIGID_DIAGRAM, d, rate).unstable_modes
    return StepExperiment(t_s, y, force, fn, tuple(map(tuple, dl.tolist())), eff, sat,
                          resid, residual_tol, ooc, lin.stable, lin.phase_margin_deg,
                          met.overshoot_pct, met.settling_time_s, limit, rate, sampled)

