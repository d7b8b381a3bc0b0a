"""A response's figure names the system's own output and unit on its y axis."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

import seactl as sc

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _agg():
    import matplotlib

    matplotlib.use("Agg")
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def test_rigid_response_axis_is_its_position_in_metres():
    # Oracle: the rigid actuator's output is the mass position x [m] (docs/theory, the
    # rigid loop); a step is drawn relative to its size, an impulse in metres.
    r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
    assert r.step(t_end_s=0.05).plot().get_ylabel() == "x / step"
    assert r.impulse(t_end_s=0.05).plot().get_ylabel() == "x [m]"


def test_loop_file_response_axis_is_the_files_output():
    # Oracle: the file's own [signals] output, read here with tomllib; the file declares
    # no unit for it, so none is printed.
    path = ROOT / "examples" / "loops" / "rigid.toml"
    out = tomllib.loads(path.read_text())["signals"]["output"]
    loop = sc.load_loop(str(path))
    assert loop.step(t_end_s=0.05).plot().get_ylabel() == f"{out} / step"
    assert loop.impulse(t_end_s=0.05).plot().get_ylabel() == out


def test_robot_response_axis_is_its_first_joint():
    # Oracle: a robot's response is its first joint's angle, named q_j.<joint> after the
    # URDF's first actuated joint (j1 in planar_2link.urdf), in rad.
    pytest.importorskip("pinocchio")
    urdf = ROOT / "examples" / "robots" / "planar_2link.urdf"
    joints = re.findall(r'<joint name="([^"]+)" type="(\w+)"', urdf.read_text())
    first = next(name for name, kind in joints if kind != "fixed")
    rb = sc.robot(str(urdf), fn_hz=30)
    assert rb.impulse(t_end_s=0.05).plot().get_ylabel() == f"q_j.{first} [rad]"
