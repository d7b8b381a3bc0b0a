"""A multi-joint SEA robot from its URDF (seactl.robot).

Oracles: the built-in SEA design (its own diagram, derived symbolically) for a one-link
robot; sympy's determinant for the cycle terms; a finite-difference linearization of
pinocchio's forward dynamics (ABA) for the planar arms' plant; the rightmost roots
(collocation and Newton, a second method) for the certified Nyquist verdicts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main

pin = pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")

ARMS = Path(__file__).resolve().parents[1] / "examples" / "robots"
TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))


def one_link(tmp_path: Path) -> Path:
    """A 1-link URDF whose inertia about the axis and joint damping are the UT-SEA's
    joint inertia and damping (the link's mass sits on the axis)."""
    a = sc.UT_SEA
    path = tmp_path / "one.urdf"
    path.write_text(f"""<?xml version="1.0"?>
<robot name="one"><link name="base"/>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="100" velocity="10"/>
<dynamics damping="{a.bj!r}"/></joint>
<link name="l1"><inertial><mass value="1"/>
<inertia ixx="1e-3" iyy="1e-3" izz="{a.Ij!r}" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="tool_joint" type="fixed"><parent link="l1"/><child link="tool"/>
<origin xyz="0.1 0 0"/></joint><link name="tool"/>
</robot>""")
    return path


def test_one_link_robot_is_the_sea_design(tmp_path):
    """Oracle: sc.design(14) with the same delays and filters (Table I: PM 43.26 deg)."""
    r = sc.robot(one_link(tmp_path), actuators="ut-sea", space="joint", fn_hz=14, **TABLE_I)
    d = sc.design(14, **TABLE_I)
    mr, md = r.margins(), d.margins()
    assert round(float(mr.phase_margin_deg), 2) == 43.26
    for key in ("phase_margin_deg", "crossover_hz", "gain_margin", "delay_margin_ms"):
        a, b = float(getattr(mr, key)), float(getattr(md, key))
        assert abs(a - b) <= 1e-9 * abs(b), key
    assert bool(mr.stable) and bool(md.stable)
    zr, zd = r.roots(count=4).roots, d.roots(count=4).roots
    assert np.all(np.abs(zr - zd) <= 1e-9 * np.abs(zd))
    sr, sd = r.step(t_end_s=0.3), d.step(t_end_s=0.3)
    assert np.max(np.abs(sr.position - sd.position)) <= 1e-9
    f = np.array([0.5, 5.0, 50.0, 500.0])
    zr, zd = r.impedance_matrix(f)[:, 0, 0], d.impedance(f).z
    assert np.all(np.abs(zr - zd) <= 1e-9 * np.abs(zd))
    ir, id_ = r.impulse(t_end_s=0.3), d.impulse(t_end_s=0.3)
    assert np.max(np.abs(ir.position - id_.position)) <= 1e-9 * np.max(np.abs(id_.position))
    # the delay terms: the same quasi-polynomial up to a constant factor (the SEA's load
    # block carries I_j, the robot's M^-1 gain 1 / I_j)
    qr, qd = r.delay_terms().at(r.delay_terms().delays_s), d.delay_terms().at(
        d.delay_terms().delays_s)
    s = np.array([3j, 100j, 2.0 + 700j])
    ratio = qr(s) / qd(s)
    assert np.allclose(ratio, ratio[0], rtol=1e-9)
    # the task-space robot of one joint: J^T K_x J is the designed K_q itself (default k_x)
    rt = sc.robot(one_link(tmp_path), space="task", task="tool", fn_hz=14, **TABLE_I)
    assert abs(float(rt.stiffness[0, 0]) - float(d.gains.Kq)) <= 1e-9 * float(d.gains.Kq)


def test_cycle_terms_are_the_symbolic_determinant():
    """Oracle: the sympy expansion of det(I - A) of the SEA diagram (its disk cache)."""
    from seactl.diagram.mason import CycleDiagram
    from seactl.systems.sea.loops import SEA_DIAGRAM

    def terms(form):
        return {b: round(c, 12) for c, b in form.terms}

    cyc = CycleDiagram("sea-cycles", SEA_DIAGRAM.blocks)
    assert terms(cyc.characteristic()) == terms(SEA_DIAGRAM.characteristic())
    for sensor in ("q_sens", "tau_sens"):
        for a, b in zip(cyc.return_difference(sensor), SEA_DIAGRAM.return_difference(sensor)):
            assert terms(a) == terms(b)


def fd_plant(urdf: Path, q0: np.ndarray, s: complex) -> np.ndarray:
    """``q / tau`` at ``s`` from central differences of pinocchio's ABA with gravity in
    the arm's plane, compensated (``tau = g(q) + u - B v``)."""
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity.linear = np.array([0.0, -9.81, 0.0])
    data = model.createData()
    n, B = model.nv, np.diag(model.damping)

    def qdd(q, v, u):
        g = pin.computeGeneralizedGravity(model, data, q)
        return pin.aba(model, data, q, v, g + u - B @ v).copy()

    h, z = 1e-6, np.zeros(n)
    cols = [[], [], []]
    for i in range(n):
        e = np.eye(n)[i] * h
        cols[0].append((qdd(q0 + e, z, z) - qdd(q0 - e, z, z)) / (2 * h))
        cols[1].append((qdd(q0, e, z) - qdd(q0, -e, z)) / (2 * h))
        cols[2].append((qdd(q0, z, e) - qdd(q0, z, -e)) / (2 * h))
    Aq, Av, Bu = (np.array(c).T for c in cols)
    return np.linalg.solve(s * s * np.eye(n) - s * Av - Aq, Bu)


@pytest.mark.parametrize("name, q0", [("planar_2link", [0.3, 0.8]),
                                      ("planar_3link", [0.3, 0.6, -0.4])])
def test_planar_plant_matches_finite_differences_of_aba(name, q0):
    """Oracle: fd_plant. The diagram's q_j.jl / tau_ext.jk with the springs cut."""
    urdf = ARMS / f"{name}.urdf"
    r = sc.robot(urdf, q0=q0, fn_hz=40)
    n = r.n
    cut = tuple(f"tau_k.j{k + 1}" for k in range(n))
    for s in (2j * np.pi * 3.0, 1.0 + 2j * np.pi * 40.0):
        fd = fd_plant(urdf, np.array(q0), s)
        got = np.array([[complex(r.diagram.transfer(f"q_j.j{l_ + 1}", f"tau_ext.j{k + 1}",
                                                    cut)(r.design, s)[0])
                         for k in range(n)] for l_ in range(n)])
        assert np.allclose(got, fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max())


def mujoco_plant(urdf: Path, q0: np.ndarray, s: complex) -> np.ndarray:
    """``q / tau`` at ``s`` from central differences of MuJoCo's forward dynamics of the
    URDF as MuJoCo compiles it (its own inertias, its passive joint damping), gravity in
    the arm's plane, compensated with MuJoCo's bias force at rest."""
    mujoco = pytest.importorskip("mujoco", reason="MuJoCo is not installed")
    model = mujoco.MjModel.from_xml_path(str(urdf))
    model.opt.gravity[:] = (0.0, -9.81, 0.0)
    data = mujoco.MjData(model)
    n = model.nv

    def qacc(q, v, u):
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = q, 0.0, 0.0
        mujoco.mj_forward(model, data)
        gravity = data.qfrc_bias.copy()
        data.qvel[:], data.qfrc_applied[:] = v, gravity + u
        mujoco.mj_forward(model, data)
        return data.qacc.copy()

    h, z = 1e-6, np.zeros(n)
    cols = [[], [], []]
    for i in range(n):
        e = np.eye(n)[i] * h
        cols[0].append((qacc(q0 + e, z, z) - qacc(q0 - e, z, z)) / (2 * h))
        cols[1].append((qacc(q0, e, z) - qacc(q0, -e, z)) / (2 * h))
        cols[2].append((qacc(q0, z, e) - qacc(q0, z, -e)) / (2 * h))
    Aq, Av, Bu = (np.array(c).T for c in cols)
    return np.linalg.solve(s * s * np.eye(n) - s * Av - Aq, Bu)


@pytest.mark.parametrize("name, q0", [("planar_2link", [0.3, 0.8]),
                                      ("planar_3link", [0.3, 0.6, -0.4])])
def test_planar_plant_matches_finite_differences_of_mujoco(name, q0):
    """Oracle: mujoco_plant (issue 41: the linearized loop against MuJoCo's model)."""
    urdf = ARMS / f"{name}.urdf"
    r = sc.robot(urdf, q0=q0, fn_hz=40)
    cut = tuple(f"tau_k.j{k + 1}" for k in range(r.n))
    for s in (2j * np.pi * 3.0, 1.0 + 2j * np.pi * 40.0):
        fd = mujoco_plant(urdf, np.array(q0), s)
        got = np.array([[complex(r.diagram.transfer(f"q_j.j{l_ + 1}", f"tau_ext.j{k + 1}",
                                                    cut)(r.design, s)[0])
                         for k in range(r.n)] for l_ in range(r.n)])
        assert np.allclose(got, fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max())


@pytest.mark.parametrize("q0, t_qs_ms", [([0.3, 0.8], 2.0), ([0.0, 1.5], 2.0),
                                         ([0.3, 0.8], 30.0)])
def test_planar_arm_certified_verdict_agrees_with_its_roots(q0, t_qs_ms):
    """Oracle: the sign of the spectral abscissa (collocation + Newton on the same
    characteristic quasi-polynomial; a second method)."""
    delays = dict(TABLE_I["delays_ms"], stiffness=t_qs_ms)
    r = sc.robot(ARMS / "planar_2link.urdf", q0=q0, fn_hz=14, delays_ms=delays,
                 filters_hz=(50, 100))
    m, roots = r.margins(), r.roots(count=3)
    assert not bool(roots.uncertain)
    assert bool(m.stable) == bool(roots.spectral_abscissa < 0)
    breaks = r.margins_by_break()
    assert set(breaks) == {f"{loop}.j{j}" for j in (1, 2)
                           for loop in ("outer", "stiffness", "damping", "torque")}
    # every break sees the same closed loop: one verdict
    assert {bool(b.stable) for b in breaks.values()} == {bool(m.stable)}


def test_impedance_matrix_low_frequency_is_the_stiffness():
    """Oracle: s Z -> K (the stiffness matrix) as s -> 0 (the torque loops track, the
    damping vanishes with s): a closed-form limit of the loop."""
    r = sc.robot(ARMS / "planar_2link.urdf", space="task", task="tool", q0=[0.3, 0.8],
                 fn_hz=14, **TABLE_I)
    f = 1e-5
    z = r.impedance_matrix([f])[0]
    assert np.allclose((2j * np.pi * f * z).real, r.stiffness, rtol=1e-4)
    assert np.allclose(z, z.T, rtol=1e-6)  # reciprocal: M, K, J^T K_x J symmetric


def test_task_stiffness_is_jt_kx_j():
    """Oracle: J from pinocchio directly; the default k_x puts the largest eigenvalue of
    J^T K_x J at the smallest designed joint stiffness."""
    q0 = [0.3, 0.8]
    r = sc.robot(ARMS / "planar_2link.urdf", space="task", task="tool", q0=q0, fn_hz=14)
    model = pin.buildModelFromUrdf(str(ARMS / "planar_2link.urdf"))
    data = model.createData()
    J = pin.computeFrameJacobian(model, data, np.array(q0), model.getFrameId("tool"),
                                 pin.LOCAL_WORLD_ALIGNED)
    kx, kr = r.task_stiffness
    K = J.T @ np.diag([kx] * 3 + [kr] * 3) @ J
    assert np.allclose(r.stiffness, K, rtol=1e-12)
    kq = min(float(g.Kq) for g in r.gains)
    assert abs(np.linalg.eigvalsh(K).max() - kq) <= 1e-9 * kq


@pytest.mark.parametrize("args, start", [
    (["--urdf", "{tmp}/missing.urdf"], "error: invalid --urdf = "),
    (["--urdf", "{tmp}/bad.urdf"], "error: invalid --urdf = "),
    (["--urdf", "{tmp}/nolimit.urdf"], "error: invalid --urdf = "),
    (["--urdf", "{arm}", "--space", "task", "--task", "hand"], "error: invalid --task = 'hand'"),
    (["--urdf", "{arm}", "--space", "task"], "error: invalid --task = None"),
    (["--urdf", "{arm}", "--actuators", "j1=ut-sea"], "error: invalid --actuators = "),
    (["--urdf", "{arm}", "--q0", "1,2,3"], "error: invalid --q0 = "),
    (["--urdf", "{arm}", "--workspace", "0:1:2"], "error: invalid --workspace [rad] = "),
    (["--urdf", "{arm}", "--workspace", "0:1:2,0:1"], "error: invalid --workspace [rad] = "),
    (["--urdf", "{arm}", "--workspace", "0:1:0,0:1:2"], "error: invalid --workspace [rad] = "),
])
def test_bad_robots_give_one_line(tmp_path, capsys, args, start):
    """A behaviour: one line `error: ...` naming the flag, exit 2, nothing else."""
    (tmp_path / "bad.urdf").write_text("<robot")
    (tmp_path / "nolimit.urdf").write_text(
        '<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
        '<parent link="a"/><child link="b"/></joint></robot>')
    argv = ["robot"] + [a.format(tmp=tmp_path, arm=ARMS / "planar_2link.urdf") for a in args]
    assert main(argv) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.startswith(start) and out.err.count("\n") == 1


def test_api_errors_name_the_field(tmp_path):
    """A behaviour: the library's InputError names the field the user spelled."""
    with pytest.raises(sc.InputError) as info:
        sc.robot(ARMS / "planar_2link.urdf", actuators={"j1": "ut-sea"})
    assert info.value.field == "actuators" and "j2" in str(info.value)
    with pytest.raises(sc.InputError) as info:
        sc.robot(ARMS / "planar_2link.urdf", space="task", task="nope")
    assert info.value.field == "task" and "tool" in info.value.valid


def test_cli_json_is_the_api(capsys):
    """Oracle: the public API on the same arguments (a front end shows the library's
    numbers)."""
    urdf = str(ARMS / "planar_2link.urdf")
    assert main(["robot", "--urdf", urdf, "--q0", "0.3,0.8", "--fn", "14", "--t-tau", "0.5",
                 "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50", "--f-taud", "100",
                 "--json"]) == 0
    import json

    rec = json.loads(capsys.readouterr().out)
    r = sc.robot(urdf, q0=[0.3, 0.8], fn_hz=14, **TABLE_I)
    assert rec["breaks"]["outer.j1"]["phase_margin_deg"] == pytest.approx(
        float(r.margins().phase_margin_deg), rel=1e-9)
    assert rec["stable"] is True and rec["spectral_abscissa_per_s"] < 0


def test_workspace_map_is_each_configuration(tmp_path):
    """Oracle: sc.robot at each configuration alone; the worst is the unstable one."""
    q = [[0.3, 0.8], [0.0, 1.5]]
    delays = dict(TABLE_I["delays_ms"], stiffness=18.0)  # between the two delay margins
    m = sc.workspace_map(ARMS / "planar_2link.urdf", q, fn_hz=14, delays_ms=delays,
                         filters_hz=(50, 100))
    for i, row in enumerate(q):
        alone = sc.robot(ARMS / "planar_2link.urdf", q0=row, fn_hz=14, delays_ms=delays,
                         filters_hz=(50, 100)).margins()
        assert bool(m.stable[i]) == bool(alone.stable)
        assert m.phase_margin_deg[i] == float(alone.phase_margin_deg)
    assert m.records()[0]["j1_rad"] == 0.3
    assert m.stable.tolist() == [False, True] and m.worst == 0
    with pytest.raises(sc.InputError):
        sc.workspace_map(ARMS / "planar_2link.urdf", [0.3, 0.8])


def test_workspace_map_largest_task_stiffness():
    """Oracle: the certified verdict of sc.robot built directly with task_stiffness=(k_x,
    k_x r^2) just below (stable) and just above (unstable) the returned k_x."""
    urdf, q = ARMS / "planar_2link.urdf", [[0.3, 0.8], [0.0, 1.5]]
    opts = dict(space="task", task="tool", fn_hz=14, **TABLE_I)
    m = sc.workspace_map(urdf, q, **opts)
    for i, row in enumerate(q):
        k = float(m.max_task_stiffness_n_per_m[i])
        reach = sc.robot(urdf, q0=row, **opts).body.reach_m
        verdict = [bool(sc.robot(urdf, q0=row, task_stiffness=(f * k, f * k * reach ** 2),
                                 **opts).margins().stable) for f in (1 - 1e-3, 1 + 2e-3)]
        assert verdict == [True, False], (row, k)
    assert m.records()[1]["max_task_stiffness_n_per_m"] == pytest.approx(
        m.max_task_stiffness_n_per_m[1], rel=1e-9)
    joint = sc.workspace_map(urdf, q[:1], fn_hz=14, **TABLE_I)
    assert np.isnan(joint.max_task_stiffness_n_per_m[0])


def test_cli_workspace_is_the_api(capsys):
    """Oracle: sc.workspace_map on the grid written out here (itertools.product, the
    first joint slowest)."""
    import itertools
    import json

    urdf = str(ARMS / "planar_2link.urdf")
    assert main(["robot", "--urdf", urdf, "--space", "task", "--task", "tool", "--fn", "14",
                 "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50",
                 "--f-taud", "100", "--workspace", "0:0.3:2,0.8:1.5:2", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    grid = [list(q) for q in itertools.product([0.0, 0.3], [0.8, 1.5])]
    m = sc.workspace_map(urdf, grid, space="task", task="tool", fn_hz=14, **TABLE_I)
    rows = rec["configurations"]
    assert [[r["j1_rad"], r["j2_rad"]] for r in rows] == grid and rec["worst"] == m.worst
    for r, k in zip(rows, m.max_task_stiffness_n_per_m):
        assert r["max_task_stiffness_n_per_m"] == pytest.approx(k, rel=1e-9)
    assert main(["robot", "--urdf", urdf, "--workspace", "0:0:1,0.8:0.8:1"]) == 0
    out = capsys.readouterr().out
    assert "max k_x [N/m]" in out and "delay margin [ms]" in out
