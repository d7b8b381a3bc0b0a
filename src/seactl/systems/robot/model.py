"""The rigid body of a robot from its URDF (pinocchio), linearized at a configuration.

With gravity compensated exactly (the torque ``g(q)`` added to every joint's reference),
the equations of motion ``M(q) qdd + C(q, qd) qd + B qd + g(q) = tau + g(q)`` linearize at
rest at ``q0`` to ``M(q0) dqdd + B dqd = dtau``: the Coriolis terms are quadratic in the
velocity and the gravity cancels (docs/theory/robot.md).  pinocchio is imported when a
model is loaded, never when this module is.
"""

from __future__ import annotations

import os
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from seactl.errors import InputError


@dataclass(frozen=True)
class RigidBody:
    """A robot's rigid body at ``q0``.

    Attributes
    ----------
    joints : joint names, in the model's order;  q0 : configuration [rad];
    mass_matrix : ``M(q0)`` [kg m^2];  damping : joint damping ``B`` [N m s/rad] (URDF);
    frame : the task frame or None;  jacobian : its 6 x n Jacobian at ``q0`` (linear rows
    [m/rad] then angular [rad/rad], world-aligned at the frame), or None;
    reach_m : the frame's distance from the first joint's axis origin [m] (0 without frame).
    """

    joints: tuple[str, ...]
    q0: np.ndarray
    mass_matrix: np.ndarray
    damping: np.ndarray
    frame: str | None
    jacobian: np.ndarray | None
    reach_m: float

    @property
    def n(self) -> int:
        return len(self.joints)


def pinocchio() -> Any:
    """The pinocchio module, or a one-line error saying how to install it."""
    try:
        import pinocchio as pin
    except ImportError:
        raise InputError("urdf", "pinocchio", "installed: pip install 'seactl[robots]' "
                         "(pinocchio's wheel is 'pin')") from None
    return pin


def load_model(urdf: str | Path) -> Any:
    """The pinocchio model of a URDF file of revolute joints (fixed base)."""
    model = parse_model(urdf)
    check_revolute(model, Path(urdf).name)
    return model


def parse_model(urdf: str | Path) -> Any:
    """The pinocchio model of a URDF file (fixed base), any joints."""
    pin = pinocchio()
    path = Path(urdf)
    if not path.is_file():
        raise InputError("urdf", str(urdf), "an existing URDF file")
    try:
        ElementTree.parse(path)
    except (ElementTree.ParseError, OSError) as exc:
        raise InputError("urdf", str(urdf), f"a valid URDF file (XML: {exc})") from None
    with _quiet_stderr() as said:
        try:
            model = pin.buildModelFromUrdf(str(path))
        except (ValueError, RuntimeError, OSError) as exc:
            model, error = None, exc
    if model is None:
        words = " ".join(said().split()) or str(error).strip() or type(error).__name__
        raise InputError("urdf", str(urdf), f"a valid URDF file ({words[:200]})")
    if model.nv == 0:
        raise InputError("urdf", str(urdf), "a robot with at least one moving joint")
    return model


def check_revolute(model: Any, source: str) -> None:
    """A one-line error unless every joint of ``model`` is revolute (one SEA per joint)."""
    for j in range(1, model.njoints):
        if model.joints[j].nq != 1 or model.joints[j].nv != 1 or \
                not model.joints[j].shortname().startswith("JointModelR"):
            raise InputError("urdf", f"{source}: joint {model.names[j]!r}",
                             "revolute joints only (one SEA per joint; lock the others "
                             "with joints=...); found " + model.joints[j].shortname())


@contextmanager
def _quiet_stderr():
    """Hold what the URDF parser (C++) writes to file descriptor 2; yields a function
    returning it, so a bad file gives one line of error and nothing else."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as held:
        os.dup2(held.fileno(), 2)
        text: list[str] = []
        try:
            yield lambda: "".join(text)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        held.seek(0)
        text.append(held.read().decode(errors="replace"))


def check_q0(model: Any, q0: Any) -> np.ndarray:
    """``q0`` [rad] as an array of the model's length (default: zeros)."""
    if q0 is None:
        return np.zeros(model.nq)
    try:
        q = np.asarray(q0, float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError("q0", q0, f"{model.nq} joint angles [rad]") from None
    if q.size != model.nq or not np.all(np.isfinite(q)):
        raise InputError("q0", q0 if not isinstance(q0, np.ndarray) else q0.tolist(),
                         f"{model.nq} finite joint angles [rad] "
                         f"({', '.join(model.names[1:])})")
    return q


def frame_names(model: Any) -> list[str]:
    return [f.name for f in model.frames]


def linearize(model: Any, q0: Any = None, task: str | None = None) -> RigidBody:
    """The rigid body of ``model`` at ``q0`` with the Jacobian of frame ``task``."""
    pin = pinocchio()
    q = check_q0(model, q0)
    data = model.createData()
    M = np.array(pin.crba(model, data, q)).reshape(model.nv, model.nv)
    M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
    jac, reach = None, 0.0
    if task is not None:
        if not isinstance(task, str) or not model.existFrame(task):
            names = frame_names(model)
            raise InputError("task", task, "a frame of the URDF: " + ", ".join(names[:12])
                             + (" ..." if len(names) > 12 else ""))
        fid = model.getFrameId(task)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        # (a one-joint Jacobian comes back as a vector: shaped back to 6 x n)
        jac = np.array(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
                       ).reshape(6, model.nv)
        reach = float(np.linalg.norm(data.oMf[fid].translation - data.oMi[1].translation))
    return RigidBody(tuple(model.names[1:]), q, M, np.array(model.damping, float), task,
                     jac, reach)
