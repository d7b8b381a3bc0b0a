"""Robots of the ``example-robot-data`` package by name (``seactl robot --model NAME``).

The package (the ``robots`` extra) installs no Python module, only data: its URDFs live under
``share/example-robot-data/robots`` of its install prefix (``cmeel.prefix`` in
site-packages), found here from the distribution's own file list.  :data:`MODELS` names the
robots whose URDF pinocchio loads with revolute joints (fixed base: a legged robot's base is
held in the air), with joints and a task frame that make a small example.
"""

from __future__ import annotations

import sysconfig
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from seactl.errors import InputError

DISTRIBUTION = "example-robot-data"
DATA_DIR = ("share", "example-robot-data", "robots")
INSTALL = 'pip install -e ".[robots]"'


@dataclass(frozen=True)
class ModelEntry:
    """A robot of the package: its URDF (relative to the robots directory), an example's
    moving joints and task frame, and one line about it."""

    path: str
    joints: tuple[str, ...]
    task: str
    about: str


MODELS: dict[str, ModelEntry] = {
    "panda": ModelEntry("panda_description/urdf/panda.urdf",
                        ("panda_joint2", "panda_joint4"), "panda_hand",
                        "Franka Emika Panda arm (7 revolute joints; the fingers are locked)"),
    "ur5": ModelEntry("ur_description/urdf/ur5_robot.urdf",
                      ("shoulder_lift_joint", "elbow_joint"), "tool0",
                      "Universal Robots UR5 arm (6 revolute joints)"),
    "talos_left_arm": ModelEntry("talos_data/robots/talos_left_arm.urdf",
                                 ("arm_left_2_joint", "arm_left_4_joint"),
                                 "gripper_left_base_link", "TALOS humanoid's left arm"),
    "anymal": ModelEntry("anymal_b_simple_description/robots/anymal.urdf",
                         ("LF_HAA", "LF_HFE", "LF_KFE"), "LF_FOOT",
                         "ANYmal B quadruped, base fixed (a leg in the air)"),
    "solo12": ModelEntry("solo_description/robots/solo12.urdf",
                         ("FL_HAA", "FL_HFE", "FL_KFE"), "FL_FOOT",
                         "Solo12 quadruped, base fixed (a leg in the air)"),
}
"""Model name -> its entry."""


def data_root() -> Path | None:
    """The package's robots directory, or None when it is not installed."""
    try:
        dist = metadata.distribution(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        dist = None
    for f in (dist.files or []) if dist is not None else []:
        parts = f.parts
        for i in range(len(parts) - len(DATA_DIR) + 1):
            if parts[i:i + len(DATA_DIR)] == DATA_DIR:
                return Path(dist.locate_file(Path(*parts[:i + len(DATA_DIR)])))
    for key in ("purelib", "platlib"):
        candidate = Path(sysconfig.get_paths()[key], "cmeel.prefix", *DATA_DIR)
        if candidate.is_dir():
            return candidate
    return None


def model_names(root: Path | None = None) -> list[str]:
    """The names of :data:`MODELS` whose URDF is installed (under ``root``, default
    :func:`data_root`)."""
    root = data_root() if root is None else Path(root)
    if root is None:
        return []
    return [name for name, e in MODELS.items() if (root / e.path).is_file()]


def model_urdf(name: str, root: Path | None = None) -> Path:
    """The URDF file of model ``name``; a one-line error names the valid models or how to
    install them."""
    root = data_root() if root is None else Path(root)
    if root is None:
        raise InputError("model", name, f"a robot of example-robot-data, installed: {INSTALL}")
    entry = MODELS.get(name)
    if entry is None or not (root / entry.path).is_file():
        names = model_names(root)
        raise InputError("model", name, "one of " + (", ".join(names) or "(none installed)"))
    return root / entry.path
