"""A robot with only some joints moving: the others locked at their ``q0`` values.

pinocchio's ``buildReducedModel`` welds each locked joint at its value, so the rigid body the
moving joints see carries the locked links' inertia.  Locking is the constraint ``dq_l = 0``:
the kinetic energy ``dq^T M dq / 2`` restricted to it is ``dq_m^T M[m, m] dq_m / 2``, so the
reduced mass matrix is the full one's submatrix of the moving joints at the same
configuration (not a Schur complement, which would describe free, unactuated joints).

For MuJoCo, :func:`locked_urdf` writes the same robot as a URDF: each locked joint fixed at
its value, the links' visual and collision geometry dropped (meshes the compiler would need),
and the inertia of the links welded to the fixed base dropped (it never moves).
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from seactl.errors import InputError


def joint_value(model: Any, jid: int, q: np.ndarray) -> float:
    """Joint ``jid``'s coordinate in ``q``: its angle [rad] or travel [m] (an unbounded
    revolute joint stores ``(cos, sin)``)."""
    j = model.joints[jid]
    if j.nq == 2:
        return float(np.arctan2(q[j.idx_q + 1], q[j.idx_q]))
    return float(q[j.idx_q])


def _moving(model: Any, joints: Any) -> list[str]:
    names = list(model.names[1:])
    if isinstance(joints, str) or not isinstance(joints, Sequence) or len(joints) == 0:
        raise InputError("joints", joints, "a list of joint names: " + ", ".join(names))
    for name in joints:
        if name not in names:
            raise InputError("joints", name, "joint names of the URDF: " + ", ".join(names))
    if len(set(joints)) != len(joints):
        raise InputError("joints", list(joints), "distinct joint names")
    return [n for n in names if n in joints]


def _full_q(model: Any, moving: list[str], q0: Any) -> np.ndarray:
    """The full configuration: ``q0`` of every joint, or of the moving ones (the others at
    pinocchio's neutral configuration, 0 rad for a revolute joint)."""
    import pinocchio as pin

    q = np.array(pin.neutral(model), float)
    if q0 is None:
        return q
    try:
        given = np.asarray(q0, float).reshape(-1)
    except (TypeError, ValueError):
        given = np.array([np.nan])
    if given.size == model.nq and len(moving) != model.nq and np.all(np.isfinite(given)):
        return given
    if given.size != len(moving) or not np.all(np.isfinite(given)):
        raise InputError("q0", q0 if not isinstance(q0, np.ndarray) else q0.tolist(),
                         f"{len(moving)} angles [rad] of the moving joints "
                         f"({', '.join(moving)}) or {model.nq} of all the model's joints")
    for name, value in zip(moving, given):
        q[model.joints[model.getJointId(name)].idx_q] = value
    return q


def lock_joints(model: Any, joints: Sequence[str], q0: Any = None
                ) -> tuple[Any, np.ndarray, tuple[tuple[str, float], ...]]:
    """The model with only ``joints`` moving, the others locked at their ``q0`` value.

    Parameters
    ----------
    model : pinocchio.Model
        The full model.
    joints : sequence of str
        The moving joints (kept in the model's order).
    q0 : sequence of float, optional
        All the model's ``nq`` coordinates, or the moving joints' angles [rad] in the
        model's order (the others at the neutral configuration); default neutral.

    Returns
    -------
    (pinocchio.Model, numpy.ndarray, tuple)
        The reduced model, its ``q0``, and ``(name, value)`` of each locked joint.
    """
    import pinocchio as pin

    moving = _moving(model, joints)
    q = _full_q(model, moving, q0)
    locked_ids = [j for j in range(1, model.njoints) if model.names[j] not in moving]
    try:
        reduced = pin.buildReducedModel(model, locked_ids, q)
    except (ValueError, RuntimeError) as exc:
        raise InputError("joints", list(joints), f"joints pinocchio can lock the others of "
                         f"({' '.join(str(exc).split())[:200]})") from None
    q_moving = np.array([q[model.joints[model.getJointId(n)].idx_q] for n in moving])
    locked = tuple((model.names[j], joint_value(model, j, q)) for j in locked_ids)
    return reduced, q_moving, locked


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def _rpy(R: np.ndarray) -> np.ndarray:
    """URDF's roll, pitch, yaw of ``R = Rz(y) Ry(p) Rx(r)``."""
    pitch = np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0]))
    if np.hypot(R[0, 0], R[1, 0]) < 1e-12:      # gimbal lock: put the yaw in the roll
        return np.array([np.arctan2(-R[1, 2], R[1, 1]), pitch, 0.0])
    return np.array([np.arctan2(R[2, 1], R[2, 2]), pitch, np.arctan2(R[1, 0], R[0, 0])])


def _from_rpy(rpy: np.ndarray) -> np.ndarray:
    x, y, z = (_rotation(np.eye(3)[i], rpy[i]) for i in range(3))
    return z @ y @ x


def _fix(joint: ElementTree.Element, value: float) -> None:
    """Make ``joint`` fixed at ``value`` (an angle, or a travel for a prismatic joint)."""
    origin = joint.find("origin")
    if origin is None:
        origin = ElementTree.SubElement(joint, "origin")
    xyz = np.array([float(x) for x in origin.get("xyz", "0 0 0").split()])
    R = _from_rpy(np.array([float(x) for x in origin.get("rpy", "0 0 0").split()]))
    axis_el = joint.find("axis")
    axis = np.array([float(x) for x in (axis_el.get("xyz", "1 0 0") if axis_el is not None
                                        else "1 0 0").split()])
    axis = axis / np.linalg.norm(axis)
    if joint.get("type") == "prismatic":
        xyz = xyz + R @ axis * value
    else:
        R = R @ _rotation(axis, value)
    origin.set("xyz", " ".join(repr(float(x)) for x in xyz))
    origin.set("rpy", " ".join(repr(float(x)) for x in _rpy(R)))
    joint.set("type", "fixed")
    for tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
        for child in joint.findall(tag):
            joint.remove(child)


def locked_urdf_text(urdf: str | Path, locked: Sequence[tuple[str, float]]) -> str:
    """The URDF with each ``(name, value)`` joint fixed at its value, no visual or
    collision geometry, and no inertia on the links welded to the base."""
    root = ElementTree.parse(urdf).getroot()
    values = dict(locked)
    for joint in root.iter("joint"):
        if joint.get("name") in values and joint.get("type") != "fixed":
            _fix(joint, values[joint.get("name")])
    welded = _welded_links(root)
    for link in root.iter("link"):
        for tag in ("visual", "collision") + (("inertial",) if link.get("name") in welded
                                              else ()):
            for child in link.findall(tag):
                link.remove(child)
    return ElementTree.tostring(root, encoding="unicode")


def _welded_links(root: ElementTree.Element) -> set[str]:
    """The links held to the (fixed) root link by fixed joints only: their inertia never
    moves, and MuJoCo needs none of it (it refuses some, a base's, that pinocchio
    accepts)."""
    children: dict[str, list[str]] = {}
    parents = set()
    for joint in root.iter("joint"):
        if joint.get("type") == "fixed":
            parent, child = joint.find("parent"), joint.find("child")
            if parent is not None and child is not None:
                children.setdefault(parent.get("link"), []).append(child.get("link"))
        child = joint.find("child")
        if child is not None:
            parents.add(child.get("link"))
    stack = [link.get("name") for link in root.iter("link") if link.get("name") not in parents]
    welded = set()
    while stack:
        name = stack.pop()
        welded.add(name)
        stack.extend(children.get(name, []))
    return welded


@contextmanager
def locked_urdf(urdf: str | Path, locked: Sequence[tuple[str, float]]) -> Iterator[str]:
    """The URDF file to compile: ``urdf`` itself when nothing is locked, else a temporary
    file of :func:`locked_urdf_text` (removed on exit)."""
    if not locked:
        yield str(urdf)
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, Path(urdf).name)
        path.write_text(locked_urdf_text(urdf, locked))
        yield str(path)
