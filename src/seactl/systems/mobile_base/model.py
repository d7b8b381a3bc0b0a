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
>>> from seactl.systems.mobile_base.kinematics import wheel_speeds
>>> from seactl.systems.mobile_base.model import TRIKEY
>>> np.round(wheel_speeds(TRIKEY, [0.0, 0.0, 1.0]), 4)   # pure rotation at 1 rad/s
array([2.3762, 2.3762, 2.3762])
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields, replace
from importlib.resources import files
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from seactl.base.params import check, nonnegative, positive, read_toml, schema_of, validate
from seactl.errors import InputError

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
