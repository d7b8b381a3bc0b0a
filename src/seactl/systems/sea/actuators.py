"""Actuator parameter sets: the series elastic actuator (SEA) and its presets.

All fields are SI and expressed in the *rotary joint space* of the paper's
Table II (kg m^2, N m s/rad, N m/rad, N m/A).  The UT-SEA is a linear
ball-screw actuator driving a joint through a pulley of radius ``r``; its
linear-space equivalent (kg, N s/m, N/m, N/A) is available through
:meth:`SEAParams.linear`.  The critically-damped gain equations and every
loop are invariant under this change of units, so gains computed in either
space agree once converted (Kq r^2, Bq r^2, Ktau / r, Btau / r).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np

from seactl.base.params import check, check_values, load_params, nonnegative, positive


@dataclass(frozen=True)
class SEAParams:
    """Immutable, validated SEA parameters in rotary joint space (SI units).

    Out-of-range values raise :class:`~seactl.errors.InputError` naming the field,
    the value and the unit.  The bounds are far beyond any joint actuator (up to 10^15 kg m^2,
    10^9 N m/rad, ...; ``beta`` from 10^-9 N m/A): outside them the gain design and the
    loop's coefficients overflow.

    Parameters
    ----------
    motor_inertia : float
        Reflected motor inertia ``I_m`` [kg m^2].
    joint_inertia : float
        Joint-side inertia ``I_j`` [kg m^2].
    motor_damping : float
        Reflected motor damping ``b_m`` [N m s/rad].
    joint_damping : float
        Joint damping ``b_j`` [N m s/rad].
    spring_stiffness : float
        Series spring stiffness ``k`` [N m/rad].
    current_to_torque : float
        ``beta = eta N k_tau r``: motor current to joint torque [N m/A].
    motor_torque_constant : float
        Motor torque constant ``k_tau`` [N m/A] (only used by the paper's
        printed impedance formula).
    pulley_radius : float
        Joint pulley radius ``r`` [m], for the linear-space view.
    max_current : float
        Motor current limit [A].
    name : str
        Name shown in tables and reports.

    Examples
    --------
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> round(UT_SEA.current_to_torque / UT_SEA.pulley_radius, 1)   # beta in N/A
    208.1
    >>> UT_SEA.linear()["motor_inertia"]
    360.0
    """

    motor_inertia: Annotated[float, positive("reflected motor inertia I_m [kg m^2]",
                                             le=1e15)]
    joint_inertia: Annotated[float, positive("joint (load side) inertia I_j [kg m^2]",
                                             le=1e15)]
    motor_damping: Annotated[float, nonnegative("reflected motor damping b_m [N m s/rad]",
                                                le=1e6)]
    joint_damping: Annotated[float, nonnegative("joint damping b_j [N m s/rad]", le=1e6)]
    spring_stiffness: Annotated[float, positive("spring stiffness k [N m/rad]", le=1e9)]
    current_to_torque: Annotated[float, positive("beta = eta N k_tau r, current to joint "
                                                 "torque [N m/A]", ge=1e-9, le=1e6)]
    motor_torque_constant: Annotated[float, positive("motor torque constant k_tau "
                                                     "[N m/A]", le=1e3)] = 0.0276
    pulley_radius: Annotated[float, positive("joint pulley radius r [m], for the "
                                             "linear-space view", le=10.0)] = 0.025
    max_current: Annotated[float, positive("motor current limit [A]", le=1e5)] = 30.0
    name: str = "custom"

    def __post_init__(self) -> None:
        check(self)

    # Paper symbols, for readable equations.
    @property
    def Im(self) -> float:  # noqa: N802 - paper notation
        return self.motor_inertia

    @property
    def Ij(self) -> float:  # noqa: N802
        return self.joint_inertia

    @property
    def bm(self) -> float:
        return self.motor_damping

    @property
    def bj(self) -> float:
        return self.joint_damping

    @property
    def k(self) -> float:
        return self.spring_stiffness

    @property
    def beta(self) -> float:
        return self.current_to_torque

    def batch(self, **arrays: Any) -> SEAParams:
        """A copy whose named fields hold arrays: a batch of plants on the leading axes.

        Every element is validated against the same bounds as a single actuator (the
        extremes of each array are checked).

        Parameters
        ----------
        **arrays : array_like
            Field name to values, e.g. ``motor_inertia=[0.2, 0.25]``.

        Returns
        -------
        SEAParams
            Same type; the block diagram and the gain design broadcast over its arrays.

        Examples
        --------
        >>> b = UT_SEA.batch(joint_inertia=[0.01, 0.02])
        >>> b.Ij.tolist(), b.k
        ([0.01, 0.02], 218.75000000000003)
        """
        values = asdict(self) | {k: np.asarray(v, float) for k, v in arrays.items()}
        for extreme in (np.min, np.max):
            check_values(type(self), {k: float(extreme(v)) if isinstance(v, np.ndarray) else v
                                      for k, v in values.items()})
        obj = object.__new__(type(self))
        for k, v in values.items():
            object.__setattr__(obj, k, v)
        return obj

    def linear(self) -> dict[str, float]:
        """The same actuator in linear (pushrod) space: kg, N s/m, N/m, N/A.

        Returns
        -------
        dict of str to float
            Inertias [kg], dampings [N s/m], stiffness [N/m] and ``current_to_force``
            [N/A], each the rotary value divided by ``r^2`` (``r`` for the last).

        Examples
        --------
        >>> round(UT_SEA.linear()["spring_stiffness"])
        350000
        """
        r = self.pulley_radius
        return {
            "motor_inertia": self.motor_inertia / r**2,
            "joint_inertia": self.joint_inertia / r**2,
            "motor_damping": self.motor_damping / r**2,
            "joint_damping": self.joint_damping / r**2,
            "spring_stiffness": self.spring_stiffness / r**2,
            "current_to_force": self.current_to_torque / r,
        }

    @classmethod
    def from_linear(cls, *, motor_mass: float, joint_mass: float, motor_damping: float,
                    joint_damping: float, spring_stiffness: float, current_to_force: float,
                    pulley_radius: float, **extra: Any) -> SEAParams:
        """Build from linear-space values (kg, N s/m, N/m, N/A) and the pulley radius [m]."""
        r = pulley_radius
        return cls(motor_inertia=motor_mass * r**2, joint_inertia=joint_mass * r**2,
                   motor_damping=motor_damping * r**2, joint_damping=joint_damping * r**2,
                   spring_stiffness=spring_stiffness * r**2,
                   current_to_torque=current_to_force * r, pulley_radius=r, **extra)


def _ut_sea() -> SEAParams:
    # Table II and docs/theory/units.md: linear-space values with r = 0.025 m.
    n_gear = 2 * math.pi * 4 / 0.003          # pulley reduction 4, ball-screw lead 3 mm/rev
    beta_lin = 0.9 * n_gear * 0.0276          # eta N k_tau = 208.1 N/A
    return SEAParams.from_linear(motor_mass=360.0, joint_mass=22.4, motor_damping=2200.0,
                                 joint_damping=160.0, spring_stiffness=350000.0,
                                 current_to_force=beta_lin, pulley_radius=0.025,
                                 motor_torque_constant=0.0276, max_current=30.0,
                                 name="ut-sea")


UT_SEA = _ut_sea()
"""The UT-SEA of the paper (Table II), in rotary joint space."""

SEA_PRESETS: dict[str, SEAParams] = {"ut-sea": UT_SEA}


def load_sea(spec: str | Path) -> SEAParams:
    """Load an SEA by preset name (``ut-sea``) or from a TOML file.

    The TOML file holds the fields of :class:`SEAParams` at top level (or
    under an ``[actuator]`` table), in rotary SI units::

        name = "my-sea"
        motor_inertia = 0.225      # kg m^2
        joint_inertia = 0.014      # kg m^2
        motor_damping = 1.375      # N m s/rad
        joint_damping = 0.1        # N m s/rad
        spring_stiffness = 218.75  # N m/rad
        current_to_torque = 5.2    # N m/A

    Parameters
    ----------
    spec : str or path
        A preset name (case-insensitive) or the path of a ``.toml`` file.

    Returns
    -------
    SEAParams
        The validated actuator.

    Raises
    ------
    InputError
        Unknown preset, unreadable file, unknown key or out-of-range value.

    Examples
    --------
    >>> round(load_sea("UT-SEA").spring_stiffness, 2)
    218.75
    """
    return load_params(spec, SEA_PRESETS, SEAParams)
