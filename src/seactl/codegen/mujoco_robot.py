"""A robot in MuJoCo: its URDF compiled by MuJoCo, an SEA on every joint, seactl's sampled
controllers closed around ``mj_step`` (docs/robots.md, "In MuJoCo").

The model (:func:`robot_mjcf`)
    MuJoCo compiles the URDF (its own inertias, its joint damping and ranges).  Each joint
    gets a rotor: a body on its own hinge in the world frame (inertia ``I_m`` about the
    hinge, damping ``b_m``; the rotor's kinetic coupling to the links neglected, as the
    linear model does), and a fixed tendon of length ``q_m - q_j``, stiffness ``k`` and
    rest length 0, the series spring.  The motor is an actuator on the rotor whose control
    is the current [A] (gear ``beta``, range ``+-max_current``); the external torque an
    unlimited actuator on the joint.  Gravity is compensated exactly on every link by
    MuJoCo's ``gravcomp`` (the generalized gravity ``g(q)`` applied as a passive force at
    every stage of the integrator), which is what the linearization at ``q0`` assumes
    (:mod:`seactl.systems.robot.model`).  Contacts are disabled.
The run (:func:`simulate_robot_mujoco`)
    The robot's diagram is compiled as for ``mode="sampled"`` (processes at their rates,
    the central process's latency as whole-sample delay buffers, the current limit) and
    its controller ticks against MuJoCo (:func:`seactl.codegen.mujoco_plant.close_loop`).
    The plant starts at rest at ``q0`` (each rotor at its joint's angle: the springs
    relaxed); the diagram's signals are deviations from it.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from seactl.codegen.mjcf import INTEGRATORS, PlantModel
from seactl.codegen.mujoco_plant import (
    MujocoPlant,
    MujocoRun,
    close_loop,
    import_mujoco,
    sampled_plan,
)
from seactl.errors import InputError

GRAVITY_MPS2 = (0.0, 0.0, -9.81)
"""MuJoCo's default gravity [m/s^2] (world frame)."""


def _urdf_mjcf(urdf: str | Path) -> ElementTree.Element:
    """The URDF as MuJoCo compiles it, saved back as MJCF (an XML tree) with the compiled
    model's numbers at full precision (:func:`_exact`)."""
    mj = import_mujoco()
    try:
        model = mj.MjModel.from_xml_path(str(urdf))
    except ValueError as exc:
        raise InputError("urdf", str(urdf), f"a URDF MuJoCo compiles ({exc})") from None
    fd, path = tempfile.mkstemp(suffix=".xml")
    os.close(fd)
    try:
        mj.mj_saveLastXML(path, model)
        root = ElementTree.parse(path).getroot()
    finally:
        os.unlink(path)
    _exact(root, model)
    return root


def _exact(root: ElementTree.Element, model: Any) -> None:
    """Write the compiled bodies' placements and inertias and the joints' axes, positions
    and damping at full precision: MuJoCo's XML writer keeps 6 significant digits (a
    fused body's centre of mass would move by 1e-6 relative)."""
    def vec(x: Any) -> str:
        return " ".join(repr(float(v)) for v in np.ravel(x))

    for body in root.find("worldbody").iter("body"):
        b = model.body(body.get("name")).id
        body.set("pos", vec(model.body_pos[b]))
        body.set("quat", vec(model.body_quat[b]))
        inertial = body.find("inertial")
        if inertial is not None:
            inertial.attrib.update(pos=vec(model.body_ipos[b]), quat=vec(model.body_iquat[b]),
                                   mass=vec(model.body_mass[b]),
                                   diaginertia=vec(model.body_inertia[b]))
        for joint in body.findall("joint"):
            j = model.joint(joint.get("name")).id
            joint.attrib.update(pos=vec(model.jnt_pos[j]), axis=vec(model.jnt_axis[j]),
                                damping=vec(model.dof_damping[model.jnt_dofadr[j]]))


def _sub(parent: ElementTree.Element, tag: str, **attrs: Any) -> ElementTree.Element:
    return ElementTree.SubElement(parent, tag, {k: str(v) for k, v in attrs.items()})


def _option(root: ElementTree.Element, timestep_s: float, integrator: str,
            gravity: Sequence[float]) -> None:
    if integrator not in INTEGRATORS:
        raise InputError("integrator", integrator, " or ".join(INTEGRATORS))
    if not (np.isfinite(timestep_s) and 0 < timestep_s <= 0.01):
        raise InputError("timestep_s [s]", timestep_s, "in (0, 0.01]")
    g = np.asarray(gravity, float).reshape(-1)
    if g.size != 3 or not np.all(np.isfinite(g)):
        raise InputError("gravity_mps2", list(gravity), "3 finite numbers [m/s^2]")
    for old in root.findall("option"):
        root.remove(old)
    opt = ElementTree.Element("option", {"timestep": repr(float(timestep_s)),
                                         "integrator": integrator,
                                         "gravity": " ".join(repr(float(x)) for x in g)})
    _sub(opt, "flag", contact="disable")
    root.insert(1, opt)


def robot_mjcf(urdf: str | Path, joints: Sequence[str], actuators: Sequence[Any], *,
               timestep_s: float = 1e-4, integrator: str = "RK4",
               gravity_mps2: Sequence[float] = GRAVITY_MPS2) -> PlantModel:
    """The robot of ``urdf`` with an SEA on each joint (module docstring).

    Parameters
    ----------
    urdf : str or path
        The robot's URDF (revolute joints).
    joints : sequence of str
        The joints, in the diagram's order (``.j1``, ``.j2``, ...).
    actuators : sequence of SEAParams
        Per joint its actuator (rotor inertia, damping, spring, gear, current limit).
    timestep_s : float
        MuJoCo's step [s].
    integrator : str
        One of :data:`seactl.codegen.mjcf.INTEGRATORS`.
    gravity_mps2 : sequence of 3 float
        Gravity in the world frame [m/s^2] (compensated on every link).

    Returns
    -------
    PlantModel
        Sensed ``q_j.jN`` and ``tau_k.jN``, actuation ``i_m.jN``, inputs ``tau_ext.jN``.
    """
    root = _urdf_mjcf(urdf)
    _option(root, timestep_s, integrator, gravity_mps2)
    world = root.find("worldbody")
    names = {j.get("name") for j in world.iter("joint")}
    for body in world.iter("body"):
        body.set("gravcomp", "1")
    tendon, act = _sub(root, "tendon"), _sub(root, "actuator")
    sensed, actuation, inputs = {}, {}, {}
    for i, (name, a) in enumerate(zip(joints, actuators)):
        if name not in names:
            raise InputError("joints", name, "joints of the URDF: " + ", ".join(sorted(names)))
        tag, im, k = f".j{i + 1}", float(a.Im), float(a.k)
        rotor = _sub(world, "body", name=f"rotor_{name}", pos=f"0 0 {-0.1 * (i + 1)!r}")
        _sub(rotor, "inertial", pos="0 0 0", mass="1", diaginertia=f"{im!r} {im!r} {im!r}")
        _sub(rotor, "joint", name=f"rotor_{name}", type="hinge", axis="0 0 1",
             damping=repr(float(a.bm)))
        spring = _sub(tendon, "fixed", name=f"spring_{name}", stiffness=repr(k),
                      springlength="0")
        _sub(spring, "joint", joint=f"rotor_{name}", coef="1")
        _sub(spring, "joint", joint=name, coef="-1")
        amax = float(a.max_current)
        _sub(act, "motor", name=f"motor_{name}", joint=f"rotor_{name}",
             gear=repr(float(a.beta)), ctrllimited="true", ctrlrange=f"{-amax!r} {amax!r}")
        _sub(act, "motor", name=f"tau_ext_{name}", joint=name, gear="1", ctrllimited="false")
        sensed["q_j" + tag] = ((name, 1.0),)
        sensed["tau_k" + tag] = ((f"rotor_{name}", k), (name, -k))
        actuation["i_m" + tag] = (f"motor_{name}", 1.0)
        inputs["tau_ext" + tag] = (f"tau_ext_{name}", 1.0)
    root.set("model", f"seactl-robot-{root.get('model', 'robot')}")
    xml = ElementTree.tostring(root, encoding="unicode")
    return PlantModel("robot", xml, sensed, actuation, inputs, float(timestep_s), integrator)


def start_positions(plant: PlantModel, joints: Sequence[str], q0: Sequence[float]) -> np.ndarray:
    """MuJoCo's ``qpos`` at rest at ``q0``: each joint and its rotor at ``q0``."""
    mj = import_mujoco()
    m = mj.MjModel.from_xml_string(plant.xml)
    qpos = np.zeros(m.nq)
    for name, q in zip(joints, q0):
        for j in (name, f"rotor_{name}"):
            qpos[m.jnt_qposadr[m.joint(j).id]] = float(q)
    return qpos


def simulate_robot_mujoco(urdf: str | Path, body: Any, actuators: Sequence[Any], diagram: Any,
                          design: Any, inputs: Mapping[str, Any], t_end_s: float, *,
                          outputs: Sequence[str] = (), rates_hz: Any = 1000.0,
                          saturation: Mapping[str, float] | None = None, substeps: int = 10,
                          integrator: str = "RK4",
                          gravity_mps2: Sequence[float] = GRAVITY_MPS2) -> MujocoRun:
    """Closed-loop response of a robot with MuJoCo as the plant (module docstring).

    Parameters
    ----------
    urdf : str or path
        The robot's URDF.
    body : seactl.systems.robot.model.RigidBody
        Its joints and ``q0`` (:attr:`seactl.Robot.body`).
    actuators : sequence of SEAParams
        Per joint (:attr:`seactl.Robot.actuators`).
    diagram, design
        The robot's diagram and design (:attr:`seactl.Robot.diagram`, ``.design``).
    inputs : mapping
        Signal -> :class:`~seactl.simulate.inputs.Step` or ``Impulse`` (``q_des.jN``,
        ``tau_ext.jN``), deviations from ``q0``.
    t_end_s : float
        Simulated time [s].
    outputs : sequence of str
        Sensed, actuation or controller signals to record (``q_j.jN`` is the deviation
        from ``q0`` [rad]).
    rates_hz, saturation
        As for the sampled simulation (:meth:`seactl.System.saturation`).
    substeps : int
        MuJoCo steps per base period.
    integrator : str
        MuJoCo's integrator.
    gravity_mps2 : sequence of 3 float
        Gravity in the world frame [m/s^2], compensated.

    Returns
    -------
    MujocoRun
        The recorded signals per tick.
    """
    if not (isinstance(substeps, (int, np.integer)) and 1 <= substeps <= 10_000):
        raise InputError("substeps", substeps, "an integer in [1, 10000]")
    plan, signals = sampled_plan(diagram, design, inputs, t_end_s, outputs, rates_hz,
                                 saturation)
    Tb = plan.base_period_s
    model = robot_mjcf(urdf, body.joints, actuators, timestep_s=Tb / substeps,
                       integrator=integrator, gravity_mps2=gravity_mps2)
    plant = MujocoPlant(model, Tb, *signals,
                        qpos0=start_positions(model, body.joints, body.q0))
    return close_loop(plan, plant, signals, inputs, outputs)
