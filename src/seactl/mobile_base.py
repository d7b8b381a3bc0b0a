"""Omnidirectional (kiwi-drive) mobile base: distributed (DOSC) versus centralized (COSC)
operational space control on simulated processors.

The base is Trikey (paper section "Distributed operational space control of a mobile
base", docs/theory/mobile-base.md): a planar rigid body with three omni wheels at 0/120/240
degrees rolling tangentially, each driven through a compliant, geared, frictional and
torque-limited drivetrain.  Two kinds of simulated processors close the loops:

* the **centralized** process (period ``central_period``) reads the wheel encoders through
  a delay of ``(1 - downlink_fraction) * round_trip + extra_delay``, runs odometry and the
  operational space controller, and sends wheel torques (and desired wheel speeds) that
  arrive ``downlink_fraction * round_trip`` later: 7 ms + 15 ms = 22 ms around the loop;
* three **embedded** processes (period ``embedded_period`` = 0.5 ms), one per wheel, that
  never talk to each other: each reads its own quantized encoder, differentiates it, adds
  its joint-space damping to the held central torque and saturates the result.

Both architectures are the same controller with different gains:

* COSC: ``F = Lambda (a_d + K_x e + D_x (v_d - v_hat))`` on the central process, ``B_q = 0``;
* DOSC: ``F = Lambda (a_d + K_x e)`` on the central process and
  ``tau_i += B_q (qdot_d,i - qdot_hat,i)`` on each embedded process, ``D_x = 0``.

``K_x`` and ``D_x`` are acceleration gains (1/s^2 = N/(m kg), 1/s = N s/(m kg)), i.e. the
Cartesian stiffness and damping divided by the task inertia ``Lambda``, as in the paper.
The same acceleration gains act on the yaw task.  DOSC damping is searched and reported
as its Cartesian equivalent ``D_x = B_q G_xx / Lambda_xx`` (``G = J_b^T J_b``), so the
two architectures share one damping axis.

The simulator is fixed-step (semi-implicit Euler, ``substeps`` per embedded period),
vectorized over a batch of gain settings: one Python loop over time, numpy over the batch.
Delays are whole embedded samples held in ring buffers (no Pade anywhere).

Examples
--------
>>> import numpy as np
>>> from seactl.mobile_base import TRIKEY, wheel_speeds
>>> np.round(wheel_speeds(TRIKEY, [0.0, 0.0, 1.0]), 4)   # pure rotation at 1 rad/s
array([2.3762, 2.3762, 2.3762])
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from importlib.resources import files
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from ._borrow import borrowed
from ._parallel import in_threads
from ._params import check, nonnegative, positive, read_toml, schema_of, validate
from .errors import InputError
from .jit import njit
from .results import Result, json_value, new_axes

ARCHS = ("cosc", "dosc")

# TOML table -> prefix of the flat field names.
_TABLES = {"body": "", "drivetrain": "", "sensing": "", "timing": "",
           "criterion": "criterion_", "tuning": "", "circle": "circle_"}


@dataclass(frozen=True)
class MobileBaseParams:
    """Validated parameters of the base, its processors, the criterion and the tuning (SI).

    The fields mirror ``presets/trikey.toml``, where each one is documented with its unit
    and marked as a robot value or a seactl assumption.  Derived quantities (geometry,
    task inertia, delays in samples) are properties.
    """

    base_mass: Annotated[float, positive("chassis mass [kg]")]
    base_yaw_inertia: Annotated[float, positive("chassis yaw inertia [kg m^2]")]
    wheel_mass: Annotated[float, nonnegative("mass of one wheel [kg]")]
    wheel_radius: Annotated[float, positive("wheel radius [m]")]
    wheel_distance: Annotated[float, positive("wheel centre to base centre [m]")]
    wheel_angles_deg: Annotated[
        tuple[float, float, float], Field(description="wheel positions [deg]")]
    wheel_spin_inertia: Annotated[float, nonnegative("wheel inertia about its axle [kg m^2]")]
    wheel_yaw_inertia: Annotated[
        float, nonnegative("wheel inertia about the vertical [kg m^2]")]
    gear_ratio: Annotated[float, positive("motor-to-wheel reduction [-]")]
    rotor_inertia: Annotated[float, positive("rotor inertia, motor side [kg m^2]")]
    viscous_friction: Annotated[float, nonnegative("wheel side [N m s/rad]")]
    coulomb_friction: Annotated[float, nonnegative("wheel side [N m]")]
    friction_velocity: Annotated[float, positive("tanh smoothing [rad/s]")]
    stiffness: Annotated[float, positive("drivetrain stiffness, wheel side [N m/rad]")]
    compliance_damping: Annotated[float, nonnegative("[N m s/rad]")]
    torque_limit: Annotated[float, positive("wheel torque limit [N m]")]
    encoder_counts: Annotated[
        int, Field(description="motor encoder counts/rev (0 = ideal)", ge=0)]
    velocity_filter_hz: Annotated[float, nonnegative("velocity filter cut-off [Hz], 0 = none")]
    embedded_period: Annotated[float, positive("embedded servo period [s]")]
    central_period: Annotated[float, positive("central servo period [s]")]
    round_trip: Annotated[float, nonnegative("central round-trip latency [s]")]
    extra_delay: Annotated[float, nonnegative("extra buffered central delay [s]")]
    downlink_fraction: Annotated[
        float, nonnegative("share of the round trip on the command path [-]", le=1)]
    substeps: Annotated[int, Field(description="physics steps per embedded period", ge=1, le=50)]
    criterion_duration: Annotated[float, positive("criterion test run [s]")]
    criterion_window: Annotated[float, positive("final window measured [s]")]
    criterion_speed: Annotated[float, positive("reference speed in x and y [m/s]")]
    criterion_oscillation_threshold: Annotated[float, positive("[m/s]")]
    criterion_vibration_threshold: Annotated[float, positive("[N m]")]
    damping_min: Annotated[float, positive("[N s/(m kg)]")]
    damping_max: Annotated[float, positive("[N s/(m kg)]")]
    kx_min: Annotated[float, positive("[N/(m kg)]")]
    kx_max: Annotated[float, positive("[N/(m kg)]")]
    grid_points: Annotated[int, Field(description="coarse search candidates", ge=3, le=400)]
    refine_points: Annotated[int, Field(description="refining search candidates", ge=0, le=400)]
    safety_factor: Annotated[float, positive("fraction of each limit used [-]", le=1)]
    circle_radius: Annotated[float, Field(description="[m]", ge=1e-3, le=20.0,
                                          allow_inf_nan=False)]
    circle_period: Annotated[float, positive("[s]")]
    circle_duration: Annotated[float, positive("[s]")]
    circle_ramp: Annotated[float, nonnegative("[s]")]
    name: str = "custom"

    def __post_init__(self) -> None:
        check(self)
        object.__setattr__(self, "wheel_angles_deg", tuple(float(a) for a in
                                                           self.wheel_angles_deg))
        a = np.sort(np.mod(self.wheel_angles_deg, 360.0))
        if not np.allclose(np.diff(np.r_[a, a[0] + 360.0]), 120.0, atol=1e-9):
            # The simulator relies on G = J^T J being rotation invariant (kiwi symmetry).
            raise InputError("wheel_angles_deg", list(self.wheel_angles_deg),
                             "three angles 120 degrees apart [deg]")
        n = self.central_period / self.embedded_period
        if abs(n - round(n)) > 1e-9:
            raise InputError("central_period", self.central_period,
                             f"a whole multiple of embedded_period = {self.embedded_period} [s]")
        if self.criterion_window >= self.criterion_duration:
            raise InputError("criterion.window", self.criterion_window,
                             f"< criterion.duration = {self.criterion_duration} [s]")
        if self.damping_max <= self.damping_min:
            raise InputError("damping_max", self.damping_max, f"> damping_min = "
                             f"{self.damping_min} [N s/(m kg)]")
        if self.kx_max <= self.kx_min:
            raise InputError("kx_max", self.kx_max, f"> kx_min = {self.kx_min} [N/(m kg)]")

    # ---------------------------------------------------------------- derived
    @property
    def alpha(self) -> np.ndarray:
        """Wheel position angles [rad], shape (3,)."""
        return np.deg2rad(np.asarray(self.wheel_angles_deg))

    @property
    def reflected_rotor_inertia(self) -> float:
        """Rotor inertia seen at the wheel, ``N^2 I_rotor`` [kg m^2]."""
        return self.rotor_inertia * self.gear_ratio**2

    @property
    def encoder_resolution(self) -> float:
        """Wheel-side angle of one encoder count [rad] (0: ideal encoder)."""
        if self.encoder_counts == 0:
            return 0.0
        return 2 * math.pi / (self.encoder_counts * self.gear_ratio)

    @property
    def central_every(self) -> int:
        """Embedded samples per central sample."""
        return int(round(self.central_period / self.embedded_period))

    @property
    def command_delay_samples(self) -> int:
        """Whole embedded samples on the central-to-wheel (command) path."""
        return int(round(self.downlink_fraction * self.round_trip / self.embedded_period))

    @property
    def measurement_delay_samples(self) -> int:
        """Whole embedded samples on the wheel-to-central (measurement) path + buffer."""
        d = (1 - self.downlink_fraction) * self.round_trip + self.extra_delay
        return int(round(d / self.embedded_period))

    @property
    def central_delay(self) -> float:
        """Total central loop delay as simulated [s] (whole samples)."""
        return (self.command_delay_samples + self.measurement_delay_samples) \
            * self.embedded_period

    @property
    def body_mass_matrix(self) -> np.ndarray:
        """Chassis and wheels as rigid bodies riding along (no wheel spin), (3, 3)."""
        m = self.base_mass + 3 * self.wheel_mass
        iz = (self.base_yaw_inertia + 3 * self.wheel_mass * self.wheel_distance**2
              + 3 * self.wheel_yaw_inertia)
        return np.diag([m, m, iz])

    def with_(self, **changes: Any) -> MobileBaseParams:
        """A validated copy with some fields changed."""
        return replace(self, **changes)


def _flatten(data: dict[str, Any]) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in data.items():
        if isinstance(value, dict):
            if key not in _TABLES:
                raise InputError(key, "[table]", "one of the tables " + ", ".join(_TABLES))
            for k, v in value.items():
                flat[_TABLES[key] + k] = v
        else:
            flat[key] = value
    return flat


def load_base(spec: str | Path = "trikey") -> MobileBaseParams:
    """Load base parameters by preset name (``trikey``) or from a TOML file.

    The file has the tables of ``presets/trikey.toml`` (``[body]``, ``[drivetrain]``,
    ``[sensing]``, ``[timing]``, ``[criterion]``, ``[tuning]``, ``[circle]``); keys left
    out keep the Trikey preset's values.

    Raises
    ------
    InputError
        Unknown preset, unreadable file, unknown key or out-of-range value.
    """
    key = str(spec)
    preset = files("seactl") / "presets" / f"{key.lower()}.toml"
    if preset.is_file():
        data = _flatten(tomllib.loads(preset.read_text()))
    else:
        path = Path(key)
        user = _flatten(read_toml("base", key, "a preset (trikey)"))
        data = _flatten(tomllib.loads((files("seactl") / "presets" / "trikey.toml")
                                      .read_text()))
        data["name"] = path.stem
        data.update(user)
    model = validate(schema_of(MobileBaseParams), data)
    return MobileBaseParams(**{f.name: getattr(model, f.name) for f in fields(MobileBaseParams)})


TRIKEY = load_base("trikey")
"""Trikey with the documented assumptions of ``presets/trikey.toml``."""


# -------------------------------------------------------------------- kinematics
def body_jacobian(p: MobileBaseParams) -> np.ndarray:
    """``J_b`` (3, 3): wheel speeds [rad/s] from body-frame velocity (v_x, v_y, omega).

    Wheel ``i`` at angle ``alpha_i`` rolls along the tangent ``(-sin a_i, cos a_i)``, so its
    rim speed is ``-sin(a_i) v_x + cos(a_i) v_y + L omega``.
    """
    a = p.alpha
    return np.stack([-np.sin(a), np.cos(a), np.full(3, p.wheel_distance)], axis=-1) \
        / p.wheel_radius


def wheel_jacobian(p: MobileBaseParams, theta) -> np.ndarray:
    """``J(theta)`` (..., 3, 3): wheel speeds from world-frame velocity (xdot, ydot, thetadot).

    ``J(theta) = J_b R(theta)^T``; ``theta`` broadcasts over leading axes.
    """
    th = np.asarray(theta, float)[..., None] + p.alpha
    L = np.broadcast_to(p.wheel_distance, th.shape)
    return np.stack([-np.sin(th), np.cos(th), L], axis=-1) / p.wheel_radius


def wheel_speeds(p: MobileBaseParams, velocity, theta=0.0) -> np.ndarray:
    """Wheel angular speeds [rad/s] for a world-frame base velocity (..., 3)."""
    J = wheel_jacobian(p, theta)
    return np.einsum("...ij,...j->...i", J, np.asarray(velocity, float))


def _rot(v: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rotate the planar part of (..., 3) vectors by theta (yaw component unchanged)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1],
                     v[..., 2]], axis=-1)


def task_inertia(p: MobileBaseParams, theta=0.0) -> np.ndarray:
    """Operational space inertia ``Lambda = (J_t A^-1 J_t^T)^-1`` of the (x, y, yaw) task.

    Joint space = the three wheel angles; ``A = J^-T M_body J^-1 + (I_spin + N^2 I_rotor) 1``
    (rigid drivetrain) and the task Jacobian is ``J_t = J^-1``, hence
    ``Lambda = M_body + (I_spin + N^2 I_rotor) J^T J``.  Shape (..., 3, 3).
    """
    J = wheel_jacobian(p, theta)
    A_w = p.wheel_spin_inertia + p.reflected_rotor_inertia
    return p.body_mass_matrix + A_w * np.einsum("...ki,...kj->...ij", J, J)


def kinetic_energy(p: MobileBaseParams, pose_rate, wheel_rates, motor_rates, theta=0.0
                   ) -> np.ndarray:
    """Kinetic energy [J] of chassis, wheels (translation, yaw, spin) and rotors."""
    v = np.asarray(pose_rate, float)
    return (0.5 * np.einsum("...i,ij,...j->...", v, p.body_mass_matrix, v)
            + 0.5 * p.wheel_spin_inertia * np.sum(np.asarray(wheel_rates) ** 2, axis=-1)
            + 0.5 * p.reflected_rotor_inertia * np.sum(np.asarray(motor_rates) ** 2, axis=-1))


def damping_to_joint(p: MobileBaseParams, d_x) -> np.ndarray:
    """Joint damping ``B_q`` [N m s/rad] whose Cartesian equivalent is ``d_x`` [N s/(m kg)]."""
    G = body_jacobian(p).T @ body_jacobian(p)
    return np.asarray(d_x, float) * task_inertia(p)[0, 0] / G[0, 0]


def joint_to_damping(p: MobileBaseParams, b_q) -> np.ndarray:
    """Cartesian-equivalent damping [N s/(m kg)] of the joint damping ``b_q`` [N m s/rad]."""
    G = body_jacobian(p).T @ body_jacobian(p)
    return np.asarray(b_q, float) * G[0, 0] / task_inertia(p)[0, 0]


# -------------------------------------------------------------------- references
@dataclass(frozen=True)
class Circle:
    """Circle reference starting at the origin at rest; the angular speed ramps in smoothly.

    ``x_d = (R cos psi - R, R sin psi, 0)``, ``psi' = omega s(t)``, ``s`` a half-cosine
    ramp over ``ramp`` seconds, then ``psi' = omega = 2 pi / period``.
    """

    radius: float
    period: float
    ramp: float = 1.0

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, float)
        w = 2 * math.pi / self.period
        tr = self.ramp
        if tr > 0:
            inr = t < tr
            psi = np.where(inr, w * (t / 2 - tr / (2 * math.pi) * np.sin(math.pi * t / tr)),
                           w * (t - tr / 2))
            dpsi = np.where(inr, w * 0.5 * (1 - np.cos(math.pi * t / tr)), w)
            ddpsi = np.where(inr, w * 0.5 * math.pi / tr * np.sin(math.pi * t / tr), 0.0)
        else:
            psi, dpsi, ddpsi = w * t, np.full_like(t, w), np.zeros_like(t)
        R = self.radius
        c, s = np.cos(psi), np.sin(psi)
        z = np.zeros_like(t)
        x = np.stack([R * c - R, R * s, z], axis=-1)
        v = np.stack([-R * s * dpsi, R * c * dpsi, z], axis=-1)
        a = np.stack([-R * s * ddpsi - R * c * dpsi**2, R * c * ddpsi - R * s * dpsi**2, z],
                     axis=-1)
        return x, v, a


def _hold(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = np.zeros(np.shape(t) + (3,))
    return z, z, z


# -------------------------------------------------------------------- simulation
@dataclass(frozen=True)
class BaseTrajectories:
    """Sampled trajectories of a batch of simulations (one row per embedded sample).

    Attributes
    ----------
    t : (n,) time [s];  x, v : (n, B, 3) true pose and world velocity;
    x_d, v_d : (n, 3) reference;  tau : (n, B, 3) wheel torques applied [N m];
    saturation : (B,) fraction of wheel-samples saturated;
    energy : (n, B) mechanical energy [J] (kinetic + compliance) when recorded, else None.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    x_d: np.ndarray
    v_d: np.ndarray
    tau: np.ndarray
    saturation: np.ndarray
    energy: np.ndarray | None = None

    def position_error(self) -> np.ndarray:
        """Planar position error norm [m], (n, B)."""
        return np.linalg.norm(self.x[..., :2] - self.x_d[:, None, :2], axis=-1)

    def velocity_error(self) -> np.ndarray:
        """Planar velocity error norm [m/s], (n, B)."""
        return np.linalg.norm(self.v[..., :2] - self.v_d[:, None, :2], axis=-1)

    def rms(self, after: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """RMS position [m] and velocity [m/s] errors over ``t >= after``, each (B,)."""
        m = self.t >= after
        return (np.sqrt(np.mean(self.position_error()[m] ** 2, axis=0)),
                np.sqrt(np.mean(self.velocity_error()[m] ** 2, axis=0)))


def _as_batch(*arrays) -> list[np.ndarray]:
    out = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float)) for a in arrays))
    if out[0].ndim != 1:
        raise InputError("gains", out[0].shape, "scalars or 1-D batches")
    return [np.ascontiguousarray(o) for o in out]


def simulate(p: MobileBaseParams, kx, dx, bq, *, reference=None, duration: float,
             push: float = 0.0, record_energy: bool = False) -> BaseTrajectories:
    """Simulate a batch of gain settings on the sampled multi-rate base.

    Parameters
    ----------
    p : MobileBaseParams
    kx : array_like, (B,) or scalar
        Cartesian stiffness (acceleration gain) [N/(m kg)] on the central process.
    dx : array_like
        Cartesian damping (acceleration gain) [N s/(m kg)] on the central process (COSC).
    bq : array_like
        Joint damping [N m s/rad] on each embedded process (DOSC).
    reference : callable ``t -> (x_d, v_d, a_d)`` or None (hold the start pose).
    duration : float
        Simulated time [s].
    push : float
        Initial chassis velocity [m/s] in x and in y (and ``3 push`` rad/s in yaw).
    record_energy : bool
        Also record the mechanical energy (for tests).

    Examples
    --------
    >>> from seactl.mobile_base import TRIKEY, simulate
    >>> r = simulate(TRIKEY, 0.0, 0.0, 0.0, duration=0.1)   # no gains, at rest: stays at rest
    >>> float(abs(r.x).max())
    0.0
    """
    kx, dx, bq = _as_batch(kx, dx, bq)
    for name, arr in (("kx", kx), ("dx", dx), ("bq", bq)):
        if not np.all(np.isfinite(arr)) or np.any(arr < 0):
            raise InputError(name, arr[~(np.isfinite(arr) & (arr >= 0))][0].item(),
                             ">= 0 and finite")
    if not (duration > 0 and math.isfinite(duration)):
        raise InputError("duration", duration, "> 0 [s]")
    Te = p.embedded_period
    n = int(round(duration / Te))
    ref = reference or _hold
    t = np.arange(n) * Te
    x_d, v_d, _ = (np.asarray(r, float) for r in ref(t))
    # The reference is a known trajectory: the central process compares the odometry with
    # the reference at the (time-stamped) measurement time and previews the feedforward
    # (acceleration, wheel speeds) for the time the command reaches the wheels.  Row j of
    # the extended reference is time (j - d_meas) Te, clamped at 0.
    d_meas, d_cmd = p.measurement_delay_samples, p.command_delay_samples
    t_ext = np.maximum(np.arange(-d_meas, n + d_cmd) * Te, 0.0)
    ref_ext = np.stack([np.broadcast_to(np.asarray(r, float), (t_ext.size, 3))
                        for r in ref(t_ext)])
    B = kx.size
    V0 = np.zeros((B, 3))
    V0[:, :2] = push
    V0[:, 2] = 3.0 * push
    out = np.empty((7 if record_energy else 3, n, B, 3))   # x, v, tau (, PHI, QM, WM, -)
    sat = np.zeros(B)
    c, mats, gains = _constants(p), _matrices(p), np.stack([kx, dx, bq])
    # the batch over one thread per core (the compiled kernel releases the GIL)
    in_threads(lambda k: _simulate_batch(c, mats, gains[:, k], ref_ext, V0[k], out[:, :, k],
                                         sat[k]), B, min_per_thread=2)
    if not np.all(np.isfinite(out[0])):
        raise FloatingPointError("base simulation diverged to non-finite values")
    es = None
    if record_energy:
        X, V, PHI, QM, WM = out[0], out[1], out[3], out[4], out[5]
        es = kinetic_energy(p, V, _wheel_rates(V, X, p.alpha, p.wheel_radius,
                                               p.wheel_distance), WM) \
            + 0.5 * p.stiffness * np.sum((QM - PHI) ** 2, axis=-1)
    return BaseTrajectories(t, out[0], out[1], x_d, v_d, out[2], sat / (3 * n), es)


def _constants(p: MobileBaseParams) -> np.ndarray:
    """The scalars the kernel reads, in the order :func:`_simulate_batch` unpacks them."""
    Te, fv = p.embedded_period, p.velocity_filter_hz
    Tc = p.central_every * Te
    a_e = 1.0 if fv == 0 else 1.0 - math.exp(-2 * math.pi * fv * Te)
    a_c = 1.0 if fv == 0 else 1.0 - math.exp(-2 * math.pi * fv * Tc)
    return np.array([p.substeps, p.central_every, p.measurement_delay_samples,
                     p.command_delay_samples, Te, Tc, a_e, a_c, p.encoder_resolution,
                     p.wheel_radius, p.wheel_distance, p.stiffness, p.compliance_damping,
                     p.reflected_rotor_inertia, p.wheel_spin_inertia, p.viscous_friction,
                     p.coulomb_friction, p.friction_velocity, p.torque_limit], float)


def _matrices(p: MobileBaseParams) -> np.ndarray:
    """``J_b``, ``J_b^-1``, ``Lambda`` and rows (diag M^-1, alpha), shape (4, 3, 3)."""
    Jb = body_jacobian(p)
    M = p.body_mass_matrix + p.wheel_spin_inertia * (Jb.T @ Jb)
    rows = np.stack([1.0 / np.diag(M), p.alpha, np.zeros(3)])   # M diagonal (kiwi layout)
    return np.stack([Jb, np.linalg.inv(Jb), task_inertia(p), rows])


# The per-sample loop is compiled (numba, cached on disk): thousands of samples of a few
# scalar operations each, where numpy's per-call overhead would outweigh the arithmetic.
@njit(cache=True, nogil=True)
def _simulate_batch(c, mats, gains, ref, V0, out, sat):  # pragma: no cover - compiled
    """The multi-rate base, one batch element at a time.

    ``c``: :func:`_constants`; ``mats``: :func:`_matrices`; ``gains``: rows kx, dx, bq;
    ``ref``: x, v, a of the extended reference; ``out``: x, v, tau (and PHI, QM, WM when
    it has 7 rows) per sample, written in place; ``sat``: saturated wheel-samples.
    """
    d_meas, d_cmd = int(c[2]), int(c[3])
    for b in range(out.shape[2]):
        X, V, PHI, QM = np.zeros(3), V0[b].copy(), np.zeros(3), np.zeros(3)
        WM = np.array(_mv(mats[0], V0[b]))         # drivetrain moving with the wheels
        meas = np.zeros((d_meas + 1, 3))           # ring of encoder readings (wheel side)
        cmd = np.zeros((d_cmd + 1, 6))             # ring of central outputs (tau, qdot_d)
        central = np.zeros((3, 3))                 # pose_hat, prev_c, vel_c
        work = np.zeros((7, 3))                    # prev_e, vel_e, q; _integrate's scratch
        _simulate_one(c, mats, gains, ref, out, sat, b, X, V, PHI, QM, WM, meas, cmd, central,
                      work)


@njit(cache=True, nogil=True)
def _simulate_one(c, mats, gains, ref, out, sat, b, X, V, PHI, QM, WM, meas, cmd, central,
                  work):  # pragma: no cover - compiled
    """Batch element ``b`` of :func:`_simulate_batch`, its arrays borrowed
    (:mod:`seactl._borrow`: no reference counting of the arrays passed at every step)."""
    mats, gains, ref, out, sat = borrowed(mats), borrowed(gains), borrowed(ref), \
        borrowed(out), borrowed(sat)
    X, V, PHI, QM, WM = borrowed(X), borrowed(V), borrowed(PHI), borrowed(QM), borrowed(WM)
    meas, cmd, central, work = borrowed(meas), borrowed(cmd), borrowed(central), borrowed(work)
    substeps, m_c, d_meas, d_cmd = int(c[0]), int(c[1]), int(c[2]), int(c[3])
    Te, Tc, a_e, a_c, res, r, L = c[4], c[5], c[6], c[7], c[8], c[9], c[10]
    kd, cd, Ir, I_sp, bv, tc, vf, tau_max = c[11], c[12], c[13], c[14], c[15], c[16], \
        c[17], c[18]
    dt = Te / substeps
    prev_e, vel_e, q = work[0], work[1], work[2]
    held = np.zeros(6)
    for k in range(out.shape[1]):
        for i in range(3):
            out[0, k, b, i], out[1, k, b, i] = X[i], V[i]
            if out.shape[0] == 7:
                out[3, k, b, i], out[4, k, b, i], out[5, k, b, i] = PHI[i], QM[i], WM[i]
        for i in range(3):
            q[i] = QM[i] if res == 0 else np.floor(QM[i] / res + 0.5) * res
        meas[k % (d_meas + 1)] = q
        if k % m_c == 0:
            m = (k - d_meas) % (d_meas + 1)
            qc = (meas[m, 0], meas[m, 1], meas[m, 2]) if k >= d_meas else (0.0, 0.0, 0.0)
            _central_command(k, qc, central, mats, gains[0, b], gains[1, b], ref,
                             d_meas + d_cmd, Tc, a_c, held)
        cmd[k % (d_cmd + 1)] = held
        row = (k - d_cmd) % (d_cmd + 1)
        for i in range(3):   # embedded process: differenced, filtered velocity; damping
            if k > 0:
                vel_e[i] += a_e * ((q[i] - prev_e[i]) / Te - vel_e[i])
            prev_e[i] = q[i]
            cm, cm_v = (cmd[row, i], cmd[row, 3 + i]) if k >= d_cmd else (0.0, 0.0)
            tau = cm + gains[2, b] * (cm_v - vel_e[i])
            if abs(tau) > tau_max:
                sat[b] += 1
            out[2, k, b, i] = min(max(tau, -tau_max), tau_max)
        _integrate(X, V, PHI, QM, WM, out[2, k, b], mats[3], substeps, dt, r, L, kd, cd,
                   Ir, I_sp, bv, tc, vf, work[3:])


@njit(cache=True)
def _rot3(v, th):  # pragma: no cover - compiled
    """``v`` turned by ``th`` about z; 3-vectors are tuples here (no allocation)."""
    c, s = np.cos(th), np.sin(th)
    return c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]


@njit(cache=True)
def _mv(M, v):  # pragma: no cover - compiled
    """``M @ v`` for 3x3 ``M`` (no BLAS call for three terms)."""
    return (M[0, 0] * v[0] + M[0, 1] * v[1] + M[0, 2] * v[2],
            M[1, 0] * v[0] + M[1, 1] * v[1] + M[1, 2] * v[2],
            M[2, 0] * v[0] + M[2, 1] * v[1] + M[2, 2] * v[2])


@njit(cache=True)
def _mtv(M, v):  # pragma: no cover - compiled
    """``M.T @ v`` for 3x3 ``M``."""
    return (M[0, 0] * v[0] + M[1, 0] * v[1] + M[2, 0] * v[2],
            M[0, 1] * v[0] + M[1, 1] * v[1] + M[2, 1] * v[2],
            M[0, 2] * v[0] + M[1, 2] * v[1] + M[2, 2] * v[2])


@njit(cache=True)
def _central_command(k, qc, state, mats, kx, dx, ref, ahead, Tc, a_c,
                     held):  # pragma: no cover - compiled
    """Odometry and the operational space law of the central process: wheel torques
    ``J^-T F`` and desired wheel speeds into ``held`` (6,) from the (delayed) encoder
    reading ``qc``."""
    Jb, Jb_inv, Lam = mats[0], mats[1], mats[2]
    pose_hat, prev_c, vel_c = state[0], state[1], state[2]
    dq = (qc[0] - prev_c[0], qc[1] - prev_c[1], qc[2] - prev_c[2])
    body = _mv(Jb_inv, dq)                        # body-frame displacement since last sample
    turn = _rot3(body, pose_hat[2] + 0.5 * body[2])
    for i in range(3):
        prev_c[i] = qc[i]
        pose_hat[i] += turn[i]
        vel_c[i] += a_c * (dq[i] / Tc - vel_c[i])
    v_hat = _rot3(_mv(Jb_inv, vel_c), pose_hat[2])
    ka = k + ahead                                # row of the arrival time
    err = (ref[0, k, 0] - pose_hat[0], ref[0, k, 1] - pose_hat[1], ref[0, k, 2] - pose_hat[2])
    err = (err[0], err[1], np.arctan2(np.sin(err[2]), np.cos(err[2])))
    acc = (ref[2, ka, 0] + kx * err[0] + dx * (ref[1, k, 0] - v_hat[0]),
           ref[2, ka, 1] + kx * err[1] + dx * (ref[1, k, 1] - v_hat[1]),
           ref[2, ka, 2] + kx * err[2] + dx * (ref[1, k, 2] - v_hat[2]))
    F = _mv(Lam, acc)
    th = pose_hat[2]
    held[0], held[1], held[2] = _mtv(Jb_inv, _rot3(F, -th))
    held[3], held[4], held[5] = _mv(Jb, _rot3(ref[1, ka], -th))


@njit(cache=True)
def _integrate(X, V, PHI, QM, WM, tau, rows, substeps, dt, r, L, kd, cd, Ir, I_sp, bv, tc,
               vf, scratch):  # pragma: no cover - compiled
    """One embedded period under wheel torques ``tau``, in place: ``substeps``
    semi-implicit Euler steps of the chassis, the wheels and the compliant drivetrains
    (``scratch``: three rows of 3)."""
    M_inv, alpha = rows[0], rows[1]
    s, co, tq = scratch[0], scratch[1], scratch[2]
    for _ in range(substeps):
        for i in range(3):
            s[i], co[i] = np.sin(X[2] + alpha[i]), np.cos(X[2] + alpha[i])
            phid = (-s[i] * V[0] + co[i] * V[1] + L * V[2]) / r
            tk = kd * (QM[i] - PHI[i]) + cd * (WM[i] - phid)
            WM[i] = WM[i] + dt / Ir * (tau[i] - tk - bv * WM[i] - tc * np.tanh(WM[i] / vf))
            # Wheel spin inertia rides on the non-holonomic constraint phidot = J(theta)
            # xdot: the gyroscopic term -I_spin J^T Jdot xdot (Lagrange-d'Alembert) couples
            # x and y while the base turns.  (The rotors get theirs through the compliance.)
            tq[i] = tk - I_sp * V[2] * (-co[i] * V[0] - s[i] * V[1]) / r
        F0 = -(s[0] * tq[0] + s[1] * tq[1] + s[2] * tq[2]) / r
        F1 = (co[0] * tq[0] + co[1] * tq[1] + co[2] * tq[2]) / r
        F2 = L * (tq[0] + tq[1] + tq[2]) / r
        V[0] += dt * F0 * M_inv[0]
        V[1] += dt * F1 * M_inv[1]
        V[2] += dt * F2 * M_inv[2]
        for j in range(3):
            X[j] += dt * V[j]
        for i in range(3):
            PHI[i] += dt * (-s[i] * V[0] + co[i] * V[1] + L * V[2]) / r
            QM[i] += dt * WM[i]


def _wheel_rates(V, X, alpha, r, L):
    th = X[..., 2:3] + alpha
    return (-np.sin(th) * V[..., 0:1] + np.cos(th) * V[..., 1:2] + L * V[..., 2:3]) / r


# -------------------------------------------------------------------- criterion
@dataclass(frozen=True)
class Vibration:
    """The measurable "vibrates or oscillates" criterion of one batch of test runs.

    Over the final ``criterion_window`` seconds of a :func:`criterion_test` run,
    ``oscillation`` is the RMS of the chassis velocity (x, y and ``L * yaw rate``) after
    removing a straight-line fit per component (so a slow drift or creep does not count),
    and ``vibration`` the RMS of the wheel torque ripple (torques minus a straight-line fit
    per wheel, RMS over the wheels): the drivetrain buzz an operator hears and feels. The
    base *vibrates* when either exceeds its threshold (``criterion_oscillation_threshold``
    [m/s], ``criterion_vibration_threshold`` [N m]); the same test and thresholds are used
    for both architectures.
    """

    oscillation: np.ndarray
    vibration: np.ndarray
    fired: np.ndarray


def vibration_criterion(p: MobileBaseParams, result: BaseTrajectories) -> Vibration:
    """Evaluate :class:`Vibration` on a :func:`criterion_test` :class:`BaseTrajectories`."""
    m = result.t >= result.t[-1] - p.criterion_window + 1e-12
    t = result.t[m]
    v = result.v[m].copy()                                 # (n, B, 3)
    v[..., 2] *= p.wheel_distance
    tc = t - t.mean()

    def detrend(y: np.ndarray) -> np.ndarray:
        slope = np.einsum("n,nbc->bc", tc, y) / np.sum(tc**2)
        return y - y.mean(axis=0) - tc[:, None, None] * slope

    osc = np.sqrt(np.mean(np.sum(detrend(v) ** 2, axis=-1), axis=0))
    vib = np.sqrt(np.mean(detrend(result.tau[m]) ** 2, axis=(0, 2)))
    fired = (osc > p.criterion_oscillation_threshold) | (vib > p.criterion_vibration_threshold)
    return Vibration(osc, vib, fired)


@dataclass(frozen=True)
class Drive:
    """Constant-velocity reference ``x_d = (s t, s t, 0)`` used by the criterion test runs.

    Driving keeps the encoders counting, so quantization noise excites the loops all the
    time, as the floor and the operator's hand do on the real robot.
    """

    speed: float

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, float)
        z = np.zeros_like(t)
        s = self.speed
        return (np.stack([s * t, s * t, z], axis=-1),
                np.stack([z + s, z + s, z], axis=-1), np.zeros(t.shape + (3,)))


def criterion_test(p: MobileBaseParams, kx, dx, bq) -> Vibration:
    """Start at rest, drive at ``criterion_speed`` and evaluate the criterion, batched."""
    r = simulate(p, kx, dx, bq, reference=Drive(p.criterion_speed),
                 duration=p.criterion_duration)
    return vibration_criterion(p, r)


# -------------------------------------------------------------------- tuning procedure
@dataclass(frozen=True)
class Search:
    """One gain search: every candidate tried (sorted), whether it fired, and the limit.

    ``limit`` is the largest candidate below the first one that fired; ``reached`` is False
    when no candidate fired (the limit is then the top of the range, a lower bound), and
    ``limit`` is 0 when even the smallest candidate fired.
    """

    gains: np.ndarray
    fired: np.ndarray
    oscillation: np.ndarray
    vibration: np.ndarray
    limit: float
    reached: bool


def _limit(g: np.ndarray, fired: np.ndarray) -> tuple[float, float | None]:
    """(largest gain below the first firing one, first firing gain or None)."""
    idx = np.flatnonzero(fired)
    if idx.size == 0:
        return float(g[-1]), None
    i = idx[0]
    return (float(g[i - 1]) if i > 0 else 0.0), float(g[i])


def _search(p: MobileBaseParams, archs: tuple[str, ...], which: str, lo: float, hi: float,
            fixed: dict[str, np.ndarray]) -> dict[str, Search]:
    """Coarse log grid then a linear refinement, all architectures in one batch each."""
    def run(grids: dict[str, np.ndarray]) -> dict[str, Vibration]:
        kx, dx, bq, owner = [], [], [], []
        for a in grids:
            g = grids[a]
            d_op = fixed.get(a, 0.0)
            if which == "damping":
                kx.append(np.zeros_like(g))
                dx.append(g if a == "cosc" else np.zeros_like(g))
                bq.append(damping_to_joint(p, g) if a == "dosc" else np.zeros_like(g))
            else:
                kx.append(g)
                dx.append(np.full_like(g, d_op if a == "cosc" else 0.0))
                bq.append(np.full_like(g, float(damping_to_joint(p, d_op)) if a == "dosc"
                                       else 0.0))
            owner += [a] * g.size
        vib = criterion_test(p, np.concatenate(kx), np.concatenate(dx), np.concatenate(bq))
        owner_a = np.asarray(owner)
        return {a: Vibration(vib.oscillation[owner_a == a], vib.vibration[owner_a == a],
                             vib.fired[owner_a == a]) for a in grids}

    grids = {a: np.geomspace(lo, hi, p.grid_points) for a in archs}
    first = run(grids)
    refine: dict[str, np.ndarray] = {}
    for a in archs:
        ok, bad = _limit(grids[a], first[a].fired)
        if bad is not None and p.refine_points > 0:
            refine[a] = np.linspace(ok if ok > 0 else bad / 10, bad, p.refine_points + 2)[1:-1]
    second = run(refine) if refine else {}
    out = {}
    for a in archs:
        g = grids[a]
        osc, vib, fired = first[a].oscillation, first[a].vibration, first[a].fired
        if a in second:
            g = np.r_[g, refine[a]]
            osc = np.r_[osc, second[a].oscillation]
            vib = np.r_[vib, second[a].vibration]
            fired = np.r_[fired, second[a].fired]
        order = np.argsort(g, kind="stable")
        g, osc, vib, fired = g[order], osc[order], vib[order], fired[order]
        lim, bad = _limit(g, fired)
        out[a] = Search(g, fired, osc, vib, lim, bad is not None)
    return out


@dataclass(frozen=True)
class ArchResult(Result):
    """The tuning procedure's outcome for one architecture (gains as acceleration gains).

    Parameters
    ----------
    arch : str
        ``"cosc"`` or ``"dosc"``.
    max_damping, max_joint_damping, max_kx, damping, kx : float
        The limits found and the gains used (see Attributes).
    damping_search, kx_search : Search
        The two searches.
    rms_position_m, rms_velocity_mps : float
        RMS tracking errors of the circle [m], [m/s].
    saturation : float
        Fraction of wheel-samples saturated while tracking.

    Attributes
    ----------
    arch : str
        ``"cosc"`` or ``"dosc"``.
    max_damping : float
        Damping limit, an acceleration gain [N s/(m kg)] (DOSC: the Cartesian
        equivalent of ``max_joint_damping``).
    max_joint_damping : float
        DOSC's joint damping limit [N m s/rad].
    max_kx : float
        Stiffness limit found with the damping at ``damping``, an acceleration gain
        [N/(m kg)].
    damping : float
        The damping used: safety factor x ``max_damping`` [N s/(m kg)].
    kx : float
        The stiffness tracking the circle: safety factor x ``max_kx`` [N/(m kg)].
    damping_search, kx_search : Search
        Every candidate of the two searches.
    rms_position_m, rms_velocity_mps : float
        RMS tracking errors of the circle [m], [m/s] (NaN without tracking).
    saturation : float
        Fraction of wheel-samples saturated while tracking.
    """

    arch: str
    max_damping: float
    max_joint_damping: float
    max_kx: float
    damping: float
    kx: float
    damping_search: Search
    kx_search: Search
    rms_position_m: float
    rms_velocity_mps: float
    saturation: float

    def records(self) -> list[dict[str, Any]]:
        """One flat row: the limits, gains and tracking errors.

        Returns
        -------
        list of dict
            ``arch`` and every scalar attribute.
        """
        return [{"arch": self.arch, **{k: json_value(getattr(self, k)) for k in ARCH_COLUMNS}}]

    def to_dict(self) -> dict[str, Any]:
        """The row of :meth:`records`.

        Returns
        -------
        dict
            ``arch`` and every scalar attribute.
        """
        return self.records()[0]

    def plot(self, ax: Any = None) -> Any:
        """The vibration measure of every candidate of both searches.

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
        for name, srch in (("damping", self.damping_search), ("kx", self.kx_search)):
            ax.loglog(srch.gains, np.maximum(srch.vibration, 1e-18), "o-", label=name)
            ax.axvline(srch.limit, ls=":", color="0.5")
        ax.set_xlabel("gain")
        ax.set_ylabel("vibration")
        ax.set_title(self.arch.upper())
        ax.legend(loc="best")
        return ax


ARCH_COLUMNS = ("max_damping", "max_joint_damping", "max_kx", "damping", "kx",
                "rms_position_m", "rms_velocity_mps", "saturation")
"""The scalar attributes of :class:`ArchResult` (its records' columns after ``arch``)."""


@dataclass(frozen=True)
class MobileBaseComparison(Result):
    """COSC versus DOSC: limits, tracking errors and the paper's ratios.

    Parameters
    ----------
    params : MobileBaseParams
        The base.
    results : dict
        Architecture -> :class:`ArchResult`.
    circle : Circle
        The tracked reference.
    track : BaseTrajectories, optional
        The circle-tracking simulation (one trajectory per architecture).

    Attributes
    ----------
    params : MobileBaseParams
        The base.
    results : dict
        Architecture -> :class:`ArchResult`.
    circle : Circle
        The tracked reference.
    track : BaseTrajectories or None
        The circle-tracking simulation.
    kx_ratio : float
        ``max_kx(DOSC) / max_kx(COSC)`` (dimensionless).
    position_rms_reduction_pct, velocity_rms_reduction_pct : float
        How much smaller DOSC's RMS errors are than COSC's [%].
    """

    params: MobileBaseParams
    results: dict[str, ArchResult]
    circle: Circle
    track: BaseTrajectories | None = field(default=None, repr=False)

    @property
    def kx_ratio(self) -> float:
        """``max_kx(DOSC) / max_kx(COSC)`` (inf when COSC's limit is 0)."""
        c, d = self.results["cosc"].max_kx, self.results["dosc"].max_kx
        return d / c if c > 0 else math.inf

    def _reduction(self, key: str) -> float:
        c = getattr(self.results["cosc"], key)
        d = getattr(self.results["dosc"], key)
        return 100.0 * (1.0 - d / c) if c > 0 else math.nan   # nan: COSC tracks exactly

    @property
    def position_rms_reduction_pct(self) -> float:
        """How much smaller DOSC's RMS position error is than COSC's [%]."""
        return self._reduction("rms_position_m")

    @property
    def velocity_rms_reduction_pct(self) -> float:
        """How much smaller DOSC's RMS velocity error is than COSC's [%]."""
        return self._reduction("rms_velocity_mps")

    def records(self) -> list[dict[str, Any]]:
        """One flat row per architecture.

        Returns
        -------
        list of dict
            As :meth:`ArchResult.records`.
        """
        return [row for r in self.results.values() for row in r.records()]

    def to_dict(self) -> dict[str, Any]:
        """The rows and the ratios as JSON-ready values.

        Returns
        -------
        dict
            ``base`` (the parameter set's name), ``archs`` (:meth:`records`),
            ``kx_ratio``, ``position_rms_reduction_pct``, ``velocity_rms_reduction_pct``
            (None where not computed).
        """
        both = {"cosc", "dosc"} <= set(self.results)
        return {"base": self.params.name, "archs": self.records(),
                "kx_ratio": json_value(self.kx_ratio) if both else None,
                "position_rms_reduction_pct":
                    json_value(self.position_rms_reduction_pct) if both else None,
                "velocity_rms_reduction_pct":
                    json_value(self.velocity_rms_reduction_pct) if both else None}

    def plot(self, ax: Any = None) -> Any:
        """The tracked circle per architecture (with tracking), else the stiffness limits.

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
        if self.track is None:
            ax.bar([a.upper() for a in self.results], [r.max_kx for r in self.results.values()])
            ax.set_ylabel("stiffness limit K_x [N/(m kg)]")
            return ax
        tr = self.track
        ax.plot(tr.x_d[:, 0], tr.x_d[:, 1], "k:", label="reference")
        for i, a in enumerate(self.results):
            ax.plot(tr.x[:, i, 0], tr.x[:, i, 1], label=a.upper())
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal")
        ax.legend(loc="best")
        return ax


def tune(p: MobileBaseParams = TRIKEY, archs: tuple[str, ...] = ARCHS, *, track: bool = True
         ) -> MobileBaseComparison:
    """Run the paper's tuning procedure, automated, for the given architectures.

    1. ``K_x = 0``: raise the damping (COSC: Cartesian on the central process; DOSC: joint
       damping on the embedded processes) until :func:`vibration_criterion` fires.
    2. Damping at ``safety_factor`` x its limit: raise ``K_x`` until the criterion fires.
    3. Track the circle with ``K_x`` at ``safety_factor`` x its limit; RMS errors after the
       ramp-in.

    Each search is a log-spaced grid (``grid_points``) refined linearly (``refine_points``)
    between the last quiet and the first firing candidate, every candidate of every
    architecture in one batched simulation.
    """
    for a in archs:
        if a not in ARCHS:
            raise InputError("arch", a, "cosc, dosc or both")
    archs = tuple(a for a in ARCHS if a in archs)
    sf = p.safety_factor
    dsearch = _search(p, archs, "damping", p.damping_min, p.damping_max, {})
    d_op = {a: sf * dsearch[a].limit for a in archs}
    ksearch = _search(p, archs, "kx", p.kx_min, p.kx_max, d_op)
    circle = Circle(p.circle_radius, p.circle_period, p.circle_ramp)
    k_op = {a: sf * ksearch[a].limit for a in archs}
    res = None
    rms_p = {a: math.nan for a in archs}
    rms_v = dict(rms_p)
    sat = dict(rms_p)
    if track:
        kx = np.array([k_op[a] for a in archs])
        dx = np.array([d_op[a] if a == "cosc" else 0.0 for a in archs])
        bq = np.array([float(damping_to_joint(p, d_op[a])) if a == "dosc" else 0.0
                       for a in archs])
        res = simulate(p, kx, dx, bq, reference=circle, duration=p.circle_duration)
        ep, ev = res.rms(after=p.circle_ramp)
        for i, a in enumerate(archs):
            rms_p[a], rms_v[a], sat[a] = float(ep[i]), float(ev[i]), float(res.saturation[i])
    results = {a: ArchResult(a, dsearch[a].limit, float(damping_to_joint(p, dsearch[a].limit)),
                             ksearch[a].limit, d_op[a], k_op[a], dsearch[a], ksearch[a],
                             rms_p[a], rms_v[a], sat[a]) for a in archs}
    return MobileBaseComparison(p, results, circle, res)


# -------------------------------------------------------------------- continuous baseline
def continuous_rhs(p: MobileBaseParams, kx: float, dx: float, bq: float, reference=None):
    """Right-hand side ``f(t, y)`` of the same plant with a continuous, delay-free,
    sensor-perfect controller (no sampling, quantization or saturation): the baseline for
    ``scipy.integrate.solve_ivp``.  ``y`` = (X, V, PHI, QM, WM, X_hat), 18 states; the
    odometry ``X_hat`` integrates the motor rates, as the sampled odometry does.
    """
    Jb = body_jacobian(p)
    Jb_inv = np.linalg.inv(Jb)
    Lam = task_inertia(p)
    M_inv = 1.0 / np.diag(p.body_mass_matrix + p.wheel_spin_inertia * (Jb.T @ Jb))
    ref = reference or _hold
    Ir = p.reflected_rotor_inertia

    def f(t: float, y: np.ndarray) -> np.ndarray:
        X, V, PHI, QM, WM, Xh = y.reshape(6, 3)
        xd, vd, ad = (np.asarray(r)[0] for r in ref(np.array([t])))
        th = Xh[2]
        v_hat = _rot((WM @ Jb_inv.T)[None], th)[0]          # odometry from motor rates
        F = Lam @ (ad + kx * (xd - Xh) + dx * (vd - v_hat))
        qd_d = _rot(vd[None], -th)[0] @ Jb.T
        tau = _rot(F[None], -th)[0] @ Jb_inv + bq * (qd_d - WM)
        s, co = np.sin(X[2] + p.alpha), np.cos(X[2] + p.alpha)
        phid = (-s * V[0] + co * V[1] + p.wheel_distance * V[2]) / p.wheel_radius
        tk = p.stiffness * (QM - PHI) + p.compliance_damping * (WM - phid)
        dWM = (tau - tk - p.viscous_friction * WM
               - p.coulomb_friction * np.tanh(WM / p.friction_velocity)) / Ir
        tq = tk - p.wheel_spin_inertia * V[2] * (-co * V[0] - s * V[1]) / p.wheel_radius
        Fb = np.array([-(s * tq).sum(), (co * tq).sum(), p.wheel_distance * tq.sum()]) \
            / p.wheel_radius
        return np.concatenate([V, Fb * M_inv, phid, WM, dWM, v_hat])

    return f
