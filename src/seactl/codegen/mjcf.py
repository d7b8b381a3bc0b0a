"""MuJoCo models (MJCF) of the SEA test bed and of the rigid actuator, from their parameters.

The models are the linear plants of the block diagrams (``docs/theory/loop.md``), built
from MuJoCo's own elements so that a physics engine, not seactl's state space, integrates
them (docs/mujoco.md):

SEA test bed (rotary joint space)
    Two bodies on coaxial hinges about the vertical axis: the motor rotor (inertia ``I_m``
    about its hinge, joint damping ``b_m``) and the joint/load (``I_j``, ``b_j``).  The
    series spring is a fixed tendon of length ``q_m - q_j`` with stiffness ``k`` and rest
    length 0: its force ``-k (q_m - q_j)`` acts as ``-tau_k`` on the motor and ``+tau_k``
    on the joint.  The motor is an actuator whose control is the current ``i_m`` [A],
    gear ``beta`` [N m/A], control range ``+-max_current``; the external torque is a
    second, unlimited actuator on the joint.
Rigid actuator
    One body of mass ``m`` on a horizontal slide joint with damping ``b``; the drive is an
    actuator whose control is the current [A], gear ``beta`` [N/A], range
    ``+-max_current``; the external force is an unlimited actuator.

Gravity and contacts are disabled (a horizontal test bed; every centre of mass lies on
its joint's axis), so each joint sees exactly the diagram's ``I s^2 + b s`` and the
spring.  :class:`PlantModel` also says how the controller's signals map onto the model:
a sensed signal is a sum of joint positions times coefficients, an actuation signal sets
an actuator's control times a factor (the rigid actuator's force command ``F_des`` is
``beta`` times the current).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.errors import InputError

INTEGRATORS = ("RK4", "Euler", "implicit", "implicitfast")
"""MuJoCo's integrators (MJCF spelling); RK4 is the default of :func:`plant_model`."""


@dataclass(frozen=True)
class PlantModel:
    """An MJCF plant and the map from the diagram's plant signals onto it.

    Attributes
    ----------
    name : str
        ``"sea"`` or ``"rigid"``.
    xml : str
        The MJCF document.
    sensed : dict
        Diagram signal -> ``((joint, coefficient), ...)``: the signal is the sum of the
        joints' positions times the coefficients (``tau_k = k q_m - k q_j``).
    actuation : dict
        Diagram actuation signal -> ``(actuator, factor)``: the actuator's control is the
        signal times the factor (its unit is the ampere).
    inputs : dict
        Diagram physical input (``tau_ext``, ``F_ext``) -> ``(actuator, factor)``.
    timestep_s : float
        MuJoCo's integration step [s].
    integrator : str
        MuJoCo's integrator.
    """

    name: str
    xml: str
    sensed: dict[str, tuple[tuple[str, float], ...]]
    actuation: dict[str, tuple[str, float]]
    inputs: dict[str, tuple[str, float]]
    timestep_s: float
    integrator: str

    def to_dict(self) -> dict[str, Any]:
        """The model as JSON-ready values (what a run's plant process reads)."""
        return {"name": self.name, "xml": self.xml,
                "sensed": {s: [list(t) for t in v] for s, v in self.sensed.items()},
                "actuation": {s: list(v) for s, v in self.actuation.items()},
                "inputs": {s: list(v) for s, v in self.inputs.items()},
                "timestep_s": self.timestep_s, "integrator": self.integrator}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PlantModel:
        """Inverse of :meth:`to_dict`."""
        return cls(d["name"], d["xml"],
                   {s: tuple((j, float(c)) for j, c in v) for s, v in d["sensed"].items()},
                   {s: (a, float(f)) for s, (a, f) in d["actuation"].items()},
                   {s: (a, float(f)) for s, (a, f) in d["inputs"].items()},
                   float(d["timestep_s"]), d["integrator"])


def _num(x: Any) -> str:
    """A parameter as an exact decimal (a single design: the first of a batch)."""
    return repr(float(np.ravel(np.asarray(x, float))[0]))


def _option(timestep_s: float, integrator: str) -> str:
    if integrator not in INTEGRATORS:
        raise InputError("integrator", integrator, " or ".join(INTEGRATORS))
    if not (np.isfinite(timestep_s) and 0 < timestep_s <= 0.01):
        raise InputError("timestep_s [s]", timestep_s, "in (0, 0.01]")
    return (f'  <option timestep="{timestep_s!r}" integrator="{integrator}">\n'
            '    <flag contact="disable" gravity="disable"/>\n  </option>\n')


def sea_mjcf(actuator: Any, timestep_s: float = 1e-4, integrator: str = "RK4") -> PlantModel:
    """The SEA test bed (module docstring) for an SEA's parameters.

    Parameters
    ----------
    actuator : seactl.systems.sea.actuators.SEAParams
        Rotary joint-space parameters (a batch: its first element).
    timestep_s : float
        Integration step [s].
    integrator : str
        One of :data:`INTEGRATORS`.

    Returns
    -------
    PlantModel
        Sensed ``q_j`` and ``tau_k``, actuation ``i_m``, input ``tau_ext``.
    """
    a = actuator
    im, ij, k = _num(a.Im), _num(a.Ij), _num(a.k)
    xml = (f'<mujoco model="seactl-sea-{a.name}">\n' + _option(timestep_s, integrator)
           + "  <worldbody>\n"
           f'    <body name="rotor">\n'
           f'      <inertial pos="0 0 0" mass="1" diaginertia="{im} {im} {im}"/>\n'
           f'      <joint name="motor" type="hinge" axis="0 0 1" damping="{_num(a.bm)}"/>\n'
           '      <geom type="cylinder" size="0.04 0.01" contype="0" conaffinity="0"/>\n'
           "    </body>\n"
           f'    <body name="load" pos="0 0 0.05">\n'
           f'      <inertial pos="0 0 0" mass="1" diaginertia="{ij} {ij} {ij}"/>\n'
           f'      <joint name="joint" type="hinge" axis="0 0 1" damping="{_num(a.bj)}"/>\n'
           '      <geom type="box" size="0.1 0.01 0.01" pos="0.1 0 0" '
           'contype="0" conaffinity="0"/>\n'
           "    </body>\n  </worldbody>\n"
           "  <tendon>\n"
           f'    <fixed name="spring" stiffness="{k}" springlength="0">\n'
           '      <joint joint="motor" coef="1"/>\n      <joint joint="joint" coef="-1"/>\n'
           "    </fixed>\n  </tendon>\n"
           "  <actuator>\n"
           f'    <motor name="motor" joint="motor" gear="{_num(a.beta)}" ctrllimited="true" '
           f'ctrlrange="-{_num(a.max_current)} {_num(a.max_current)}"/>\n'
           '    <motor name="tau_ext" joint="joint" gear="1" ctrllimited="false"/>\n'
           "  </actuator>\n"
           "  <sensor>\n"
           '    <jointpos name="q_j" joint="joint"/>\n'
           '    <jointpos name="q_m" joint="motor"/>\n'
           '    <tendonpos name="spring_deflection" tendon="spring"/>\n'
           "  </sensor>\n</mujoco>\n")
    kf = float(_num(a.k))
    return PlantModel("sea", xml, {"q_j": (("joint", 1.0),),
                                   "tau_k": (("motor", kf), ("joint", -kf))},
                      {"i_m": ("motor", 1.0)}, {"tau_ext": ("tau_ext", 1.0)},
                      float(timestep_s), integrator)


def rigid_mjcf(actuator: Any, timestep_s: float = 1e-4, integrator: str = "RK4") -> PlantModel:
    """The rigid actuator (module docstring) for its parameters.

    Parameters
    ----------
    actuator : seactl.systems.rigid.model.RigidParams
        Mass, damping, current-to-force and current limit.
    timestep_s : float
        Integration step [s].
    integrator : str
        One of :data:`INTEGRATORS`.

    Returns
    -------
    PlantModel
        Sensed ``x``, actuation ``F_des`` (control = ``F_des / beta`` [A]), input ``F_ext``.
    """
    a = actuator
    m = _num(a.m)
    xml = (f'<mujoco model="seactl-rigid-{a.name}">\n' + _option(timestep_s, integrator)
           + "  <worldbody>\n"
           '    <body name="output">\n'
           f'      <inertial pos="0 0 0" mass="{m}" diaginertia="1 1 1"/>\n'
           f'      <joint name="x" type="slide" axis="1 0 0" damping="{_num(a.b)}"/>\n'
           '      <geom type="box" size="0.05 0.05 0.05" contype="0" '
           'conaffinity="0"/>\n'
           "    </body>\n  </worldbody>\n"
           "  <actuator>\n"
           f'    <motor name="drive" joint="x" gear="{_num(a.beta)}" ctrllimited="true" '
           f'ctrlrange="-{_num(a.max_current)} {_num(a.max_current)}"/>\n'
           '    <motor name="F_ext" joint="x" gear="1" ctrllimited="false"/>\n'
           "  </actuator>\n"
           '  <sensor>\n    <jointpos name="x" joint="x"/>\n  </sensor>\n</mujoco>\n')
    return PlantModel("rigid", xml, {"x": (("x", 1.0),)},
                      {"F_des": ("drive", 1.0 / float(_num(a.beta)))},
                      {"F_ext": ("F_ext", 1.0)}, float(timestep_s), integrator)


def plant_model(design: Any, timestep_s: float = 1e-4, integrator: str = "RK4") -> PlantModel:
    """The MuJoCo plant of a design's actuator: an SEA or a rigid actuator.

    Parameters
    ----------
    design : SEADesign or RigidDesign
        The design batch of :attr:`seactl.System.design` (its actuator is used).
    timestep_s : float
        Integration step [s].
    integrator : str
        One of :data:`INTEGRATORS`.

    Returns
    -------
    PlantModel
        The model and its signal map.

    Raises
    ------
    InputError
        For any other kind of system (a loop file has no physical model).

    Examples
    --------
    >>> import seactl as sc
    >>> m = plant_model(sc.design(14).design)
    >>> sorted(m.sensed), m.actuation
    (['q_j', 'tau_k'], {'i_m': ('motor', 1.0)})
    """
    from seactl.systems.rigid.model import RigidParams
    from seactl.systems.sea.actuators import SEAParams

    act = getattr(design, "actuator", None)
    if isinstance(act, SEAParams):
        return sea_mjcf(act, timestep_s, integrator)
    if isinstance(act, RigidParams):
        return rigid_mjcf(act, timestep_s, integrator)
    raise InputError("plant", "mujoco", "an SEA or a rigid actuator (a loop file has no "
                     "physical model to build)")
