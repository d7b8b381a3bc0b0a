"""Robots by name (example-robot-data) and joints locked at q0 (seactl.robot(model=,
joints=)).

No test needs example-robot-data: the model lookup runs on a fake data root laid out like the
package.  Oracles: locking is the constraint dq_locked = 0, so the reduced mass matrix is the
full one's submatrix of the moving joints (the kinetic energy restricted to the constraint);
and a hand-written URDF whose locked joint is a fixed joint at the same angle, merged by
pinocchio's URDF parser (a second derivation of the same rigid body).
"""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.systems.robot import catalog

pin = pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")

ARMS = Path(__file__).resolve().parents[1] / "examples" / "robots"
THREE = ARMS / "planar_3link.urdf"


@pytest.fixture
def fake_root(tmp_path, monkeypatch):
    """A robots directory laid out like example-robot-data's, holding only "ur5" (a copy
    of the planar 3-link arm)."""
    root = tmp_path / "share" / "example-robot-data" / "robots"
    target = root / catalog.MODELS["ur5"].path
    target.parent.mkdir(parents=True)
    shutil.copy(THREE, target)
    monkeypatch.setattr(catalog, "data_root", lambda: root)
    return root


def mujoco_mass_matrix(urdf, q):
    """MuJoCo's joint-space mass matrix of the URDF file at ``q``."""
    import mujoco as mj

    m = mj.MjModel.from_xml_path(str(urdf))
    d = mj.MjData(m)
    d.qpos[:] = q
    mj.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    try:
        mj.mj_fullM(m, d, M)            # MuJoCo >= 4
    except TypeError:
        mj.mj_fullM(m, M, d.qM)         # MuJoCo 3
    return M


def crba(model, q):
    M = np.array(pin.crba(model, model.createData(), np.asarray(q, float)))
    return np.triu(M) + np.triu(M, 1).T


def fixed_j3(tmp_path: Path, angle: float) -> Path:
    """The 3-link arm with j3 written by hand as a fixed joint rotated by ``angle`` about
    its axis z."""
    text = THREE.read_text().replace(
        '<joint name="j3" type="revolute">', '<joint name="j3" type="fixed">').replace(
        '<origin xyz="0.2 0 0"/>', f'<origin xyz="0.2 0 0" rpy="0 0 {angle!r}"/>')
    path = tmp_path / "two.urdf"
    path.write_text(text)
    return path


def test_model_lookup_on_a_fake_data_root(fake_root):
    """A behaviour: only the installed models are listed; the name loads its URDF."""
    assert list(sc.robot_models()) == ["ur5"]
    r = sc.robot(model="ur5", joints=["j1", "j2"], q0=[0.3, 0.8])
    assert Path(r.urdf) == fake_root / catalog.MODELS["ur5"].path
    assert r.body.joints == ("j1", "j2") and r.locked == (("j3", 0.0),)


def test_locked_joint_mass_matrix(tmp_path):
    """Oracles: M_full[moving, moving] at the same q, and pinocchio's crba on the
    hand-written 2-link URDF (j3 fixed at 0.7 rad, its link merged by the parser)."""
    q = [0.3, 0.8, 0.7]
    r = sc.robot(THREE, joints=["j1", "j2"], q0=q, space="task", task="tool")
    full = pin.buildModelFromUrdf(str(THREE))
    np.testing.assert_allclose(r.body.mass_matrix, crba(full, q)[:2, :2], rtol=1e-12)
    two = pin.buildModelFromUrdf(str(fixed_j3(tmp_path, 0.7)))
    np.testing.assert_allclose(r.body.mass_matrix, crba(two, q[:2]), rtol=1e-12)
    alone = sc.robot(fixed_j3(tmp_path, 0.7), q0=q[:2], space="task", task="tool")
    np.testing.assert_allclose(r.body.jacobian, alone.body.jacobian, atol=1e-12)
    np.testing.assert_allclose(r.stiffness, alone.stiffness, rtol=1e-12)


def test_locking_a_middle_joint_keeps_the_model_order():
    """Oracle: M_full[[0, 2], [0, 2]]; q0 of the moving joints alone locks j2 at 0."""
    full = pin.buildModelFromUrdf(str(THREE))
    r = sc.robot(THREE, joints=["j3", "j1"], q0=[0.3, 0.0, -0.4], fn_hz=20)
    assert r.body.joints == ("j1", "j3") and r.locked == (("j2", 0.0),)
    np.testing.assert_allclose(r.body.mass_matrix,
                               crba(full, [0.3, 0.0, -0.4])[np.ix_([0, 2], [0, 2])],
                               rtol=1e-12)
    short = sc.robot(THREE, joints=["j3", "j1"], q0=[0.3, -0.4], fn_hz=20)
    np.testing.assert_array_equal(short.body.mass_matrix, r.body.mass_matrix)


def test_locked_urdf_for_mujoco_is_the_reduced_body():
    """Oracle: MuJoCo's mass matrix (mj_fullM) of the URDF it compiles for a locked robot
    (j2 fixed at 0.9 rad, no geometry) against pinocchio's full crba submatrix."""
    pytest.importorskip("mujoco")
    from seactl.systems.robot.reduce import locked_urdf

    r = sc.robot(THREE, joints=["j1", "j3"], q0=[0.2, 0.9, -0.5], fn_hz=30)
    with locked_urdf(r.urdf, r.locked) as path:
        assert [j.get("name") for j in ElementTree.parse(path).iter("joint")
                if j.get("type") != "fixed"] == ["j1", "j3"]
        M = mujoco_mass_matrix(path, [0.2, -0.5])
    full = crba(pin.buildModelFromUrdf(str(THREE)), [0.2, 0.9, -0.5])
    np.testing.assert_allclose(M, full[np.ix_([0, 2], [0, 2])], rtol=1e-6)


def chain(tmp_path: Path, n: int) -> Path:
    """The 3-link arm with ``n - 3`` more revolute joints, each carrying a small link
    between link3 and the tool."""
    text = THREE.read_text()
    extra, parent = "", "link3"
    for i in range(4, n + 1):
        extra += (f'<joint name="j{i}" type="revolute"><parent link="{parent}"/>'
                  f'<child link="link{i}"/><origin xyz="0.1 0 0"/><axis xyz="0 0 1"/>'
                  '<limit lower="-3" upper="3" effort="100" velocity="10"/></joint>'
                  f'<link name="link{i}"><inertial><mass value="0.1"/><inertia ixx="1e-4" '
                  'iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>')
        parent = f"link{i}"
    text = text.replace('<joint name="tool_joint" type="fixed">\n    <parent link="link3"/>',
                        extra + '<joint name="tool_joint" type="fixed">\n    <parent link="'
                        + parent + '"/>')
    path = tmp_path / f"chain{n}.urdf"
    path.write_text(text)
    return path


def test_more_than_seven_moving_joints_are_refused(tmp_path):
    """A behaviour: 8 moving joints are refused up front (field joints, range named);
    choosing 7 of them builds the robot."""
    with pytest.raises(sc.InputError) as info:
        sc.robot(chain(tmp_path, 8))
    assert info.value.field == "joints" and "at most 7 moving joints" in info.value.valid
    seven = [f"j{i}" for i in range(1, 8)]
    assert sc.robot(chain(tmp_path, 8), joints=seven, fn_hz=400).n == 7


@pytest.mark.parametrize("args,start", [
    (["--model", "nope"], "error: invalid --model = 'nope': must be one of ur5"),
    (["--model", "ur5", "--joints", "j1,j9"], "error: invalid --joints = 'j9': must be "),
    (["--model", "ur5", "--urdf", "{three}"], "error: invalid --urdf = "),
    ([], "error: invalid --urdf = None: must be a URDF file, or --model"),
    (["--urdf", "{eight}"], "error: invalid --joints = '8 moving joints"),
    (["--model", "ur5", "--joints", "j1,j2", "--q0", "1,2,3,4"], "error: invalid --q0 "),
])
def test_model_errors_give_one_line(fake_root, tmp_path, capsys, args, start):
    """A behaviour: one line `error: ...` naming the flag, exit 2, nothing else."""
    argv = ["robot"] + [a.format(three=THREE, eight=chain(tmp_path, 8)) for a in args]
    assert main(argv) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.startswith(start) and out.err.count("\n") == 1


def test_missing_package_says_how_to_install(monkeypatch):
    """A behaviour: without example-robot-data the error gives the install command."""
    monkeypatch.setattr(catalog, "data_root", lambda: None)
    with pytest.raises(sc.InputError, match=r'pip install -e "\.\[robots\]"'):
        sc.robot(model="panda", joints=["panda_joint2"])
    assert sc.robot_models() == {}


@pytest.mark.skipif(not sc.robot_models(), reason="example-robot-data is not installed")
def test_real_models_load_their_example_joints():
    """Oracle: each installed model's reduced mass matrix is its full crba's submatrix,
    and MuJoCo's of the URDF it compiles (example-robot-data, not needed by CI)."""
    from seactl.systems.robot.reduce import locked_urdf

    for name, entry in sc.robot_models().items():
        r = sc.robot(model=name, joints=entry["joints"], space="task", task=entry["task"],
                     fn_hz=100)
        full = pin.buildModelFromUrdf(entry["urdf"])
        idx = [full.joints[full.getJointId(j)].idx_v for j in r.body.joints]
        q = np.array(pin.neutral(full))
        np.testing.assert_allclose(r.body.mass_matrix, crba(full, q)[np.ix_(idx, idx)],
                                   rtol=1e-9, err_msg=name)
        if importlib.util.find_spec("mujoco") is None:
            continue
        with locked_urdf(r.urdf, r.locked) as path:
            np.testing.assert_allclose(mujoco_mass_matrix(path, r.body.q0),
                                       r.body.mass_matrix, rtol=1e-9, atol=1e-12,
                                       err_msg=name)


def test_workspace_of_a_model(fake_root, capsys):
    """Oracle: sc.robot on the model at each configuration of the grid (the front end
    shows the library's numbers)."""
    import json

    assert main(["robot", "--model", "ur5", "--joints", "j1,j2", "--fn", "14",
                 "--workspace", "0:0:1,0.8:1.6:2", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["configurations"]
    for row in rows:
        m = sc.robot(model="ur5", joints=["j1", "j2"], q0=[row["j1_rad"], row["j2_rad"]],
                     fn_hz=14).margins()
        assert row["stable"] == bool(m.stable)
        assert row["phase_margin_deg"] == pytest.approx(float(m.phase_margin_deg), rel=1e-12)


def test_data_root_from_the_distribution_files(tmp_path, monkeypatch):
    """A behaviour: the robots directory comes from the distribution's file list (where
    pip put it), else from the cmeel prefix in site-packages, else None."""
    from importlib import metadata
    from pathlib import PurePosixPath

    class Dist:
        files = [PurePosixPath("x.dist-info/RECORD"),
                 PurePosixPath("cmeel.prefix/share/example-robot-data/robots/a/b.urdf")]

        def locate_file(self, path):
            return tmp_path / "site" / path

    monkeypatch.setattr(metadata, "distribution", lambda name: Dist())
    assert catalog.data_root() == tmp_path / "site/cmeel.prefix/share/example-robot-data/robots"

    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "distribution", missing)
    monkeypatch.setattr(catalog.sysconfig, "get_paths",
                        lambda: {"purelib": str(tmp_path), "platlib": str(tmp_path)})
    assert catalog.data_root() is None
    prefix = tmp_path / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
    prefix.mkdir(parents=True)
    assert catalog.data_root() == prefix
