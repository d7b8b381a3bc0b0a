"""Where :func:`seactl.robot` gets its rigid body: a URDF file or a robot of
``example-robot-data`` by name, with only some joints moving (:func:`rigid_model`), and the
list of those robots (:func:`robot_models`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from seactl.errors import InputError

MAX_JOINTS = 7
"""The most moving joints :func:`seactl.robot` accepts: beyond 3 the characteristic comes
from each joint's own loop (:mod:`seactl.systems.robot.characteristic`), whose
determinant grows as ``n 2^n`` polynomial products on ``(n + 1)^3`` points."""


def robot_models() -> dict[str, dict[str, Any]]:
    """The robots of ``example-robot-data`` that :func:`seactl.robot` loads by name.

    Returns
    -------
    dict
        Name -> ``{"urdf": path, "joints": [...], "task": frame, "about": text}``: an
        example's moving joints and task frame.  Empty when the package is not installed
        (``pip install -e ".[robots]"``).

    Examples
    --------
    >>> import seactl as sc
    >>> sorted(sc.robot_models())[:2]                             # doctest: +SKIP
    ['anymal', 'anymal_c']
    """
    from seactl.systems.robot.catalog import MODELS, data_root, model_names

    root = data_root()
    return {name: {"urdf": str(root / MODELS[name].path), "joints": list(MODELS[name].joints),
                   "task": MODELS[name].task, "about": MODELS[name].about}
            for name in model_names(root)}


def _source(urdf: Any, model: Any) -> Path:
    from seactl.systems.robot.catalog import model_urdf

    if (urdf is None) == (model is None):
        raise InputError("urdf", urdf, "a URDF file, or model=NAME instead (not both)")
    if model is not None:
        if not isinstance(model, str):
            raise InputError("model", model, "a model name (seactl.robot_models())")
        return model_urdf(model)
    return Path(urdf)


def rigid_model(urdf: Any, model: Any, joints: Sequence[str] | None, q0: Any
                ) -> tuple[Any, Any, Path, tuple[tuple[str, float], ...]]:
    """The pinocchio model of the moving joints, their ``q0``, the URDF file and the locked
    joints ``(name, value)`` (:func:`seactl.systems.robot.reduce.lock_joints`).

    Raises
    ------
    InputError
        Both or neither of ``urdf`` and ``model``, an unknown model or joint, a moving joint
        that is not revolute, more than :data:`MAX_JOINTS` moving joints.
    """
    from seactl.systems.robot.model import check_revolute, parse_model
    from seactl.systems.robot.reduce import lock_joints

    path = _source(urdf, model)
    full = parse_model(path)
    if joints is None:
        moving, q, locked = full, q0, ()
    else:
        moving, q, locked = lock_joints(full, joints, q0)
    if moving.nv > MAX_JOINTS:
        names = ", ".join(moving.names[1:])
        raise InputError("joints", f"{moving.nv} moving joints ({names})",
                         f"at most {MAX_JOINTS} moving joints; choose them with joints=[...] "
                         "(--joints), the others are locked at q0")
    check_revolute(moving, path.name)
    return moving, q, path, locked
