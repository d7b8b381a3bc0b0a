"""A robot's task impedance, its certified passivity and its task-space step and impulse.

Oracles: the built-in SEA design (its own diagram, derived symbolically) for a one-link
robot; a second derivation of the joint impedance from each joint's SEA impedance (with
every joint's motion imposed the stiffness path is feed-forward, so ``Z_q`` is affine in
the stiffness matrix: ``diag(Z_j(K=0)) + diag(Z_j(K=1) - Z_j(K=0)) K``); the congruence
``J^-T Z_q J^-1`` for a square Jacobian; a dense-grid smallest eigenvalue of that second
derivation on designs within 0.5 % of the passivity boundary (the boundary from the
low-frequency limit: the delayed stiffness adds ``-K T`` to the Hermitian part, so
``T* = min eig(Herm Z(0), K)``); the geometry of a stretched arm; the analytic final value of
a stiffness-held step and the impulse-momentum identity ``J M^-1 J^T F = v(0+)``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.errors import InputError

pin = pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")

ARM = Path(__file__).resolve().parents[1] / "examples" / "robots" / "planar_2link.urdf"
TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))
Q0 = [0.3, 0.8]


def one_link(tmp_path: Path) -> Path:
    """The 1-link URDF of tests/test_robot.py (the UT-SEA's joint inertia and damping),
    its tool 0.1 m from the axis."""
    from test_robot import one_link as make

    return make(tmp_path)


def sea_joint_impedance(r, f_hz):
    """The second derivation of ``Z_q`` from each joint's SEA impedance (module doc)."""
    from seactl.systems.sea.impedance import impedance
    from seactl.systems.sea.loops import SEADesign, Timing

    d, f_qd, f_taud = r.delays, *r.filters_hz
    timing = Timing(T_tau=d["torque"], T_qs=d["stiffness"], T_qd=d["damping"], f_qd=f_qd,
                    f_taud=f_taud)

    def z(j, kq):
        g = replace(r.gains[j], Kq=kq)
        return impedance(SEADesign(r.actuators[j], g, timing), f_hz).z

    a = np.stack([z(j, 0.0) for j in range(r.n)], -1)            # (F, n)
    b = np.stack([z(j, 1.0) for j in range(r.n)], -1) - a
    return a[:, :, None] * np.eye(r.n) + b[:, :, None] * r.stiffness


def test_one_link_impedance_and_passivity_are_the_sea(tmp_path):
    """Oracle: sc.design(14)'s impedance and passivity verdict (Table I: not passive,
    band 65-136 Hz; without delays and filters: passive), and ``Z_x = Z_q / r^2`` for a
    tool at radius r = 0.1 m."""
    f = np.array([0.5, 5.0, 50.0, 500.0])
    for kw in (TABLE_I, {}):
        r = sc.robot(one_link(tmp_path), space="task", task="tool", fn_hz=14, **kw)
        d = sc.design(14, **kw)
        zq = r.task_impedance(f, space="joint").z[:, 0, 0]
        assert np.all(np.abs(zq - d.impedance(f).z) <= 1e-9 * np.abs(d.impedance(f).z))
        zx = r.task_impedance(f)
        assert zx.unit == "N s/m" and zx.z.shape == (4, 1, 1)
        assert np.allclose(zx.z[:, 0, 0], zq / 0.1 ** 2, rtol=1e-9, atol=0)
        p, pd = r.passivity(), d.passivity()
        assert p.passive == bool(pd.passive) and p.proven
        if not p.passive:   # the refuting frequency lies in the SEA's own band
            lo, hi = pd.bands_hz[()][0]
            assert lo <= p.negative_f_hz <= hi


def test_task_impedance_is_the_joint_seas_coupled_by_k():
    """Oracle: the second derivation of Z_q, and J^-T Z_q J^-1 in world x, y."""
    r = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14, **TABLE_I)
    f = np.logspace(-1, 3, 9)
    zq = sea_joint_impedance(r, f)
    mine = r.impedance_matrix(f)
    assert np.max(np.abs(mine - zq)) <= 1e-9 * np.max(np.abs(zq))
    t = r.task_impedance(f)
    B = t.basis                                                  # (3, 2), in the x-y plane
    world = B[:2] @ t.z @ B[:2].T
    Jinv = np.linalg.inv(r.body.jacobian[:2])
    expect = Jinv.T @ zq @ Jinv
    assert np.max(np.abs(world - expect)) <= 1e-8 * np.max(np.abs(expect))
    # principal values: the singular values; directions: unit vectors with z Z v = s u
    assert np.allclose(t.principal_values, np.linalg.svd(expect, compute_uv=False),
                       rtol=1e-8)
    assert np.allclose(np.linalg.norm(t.directions, axis=1), 1.0)


def boundary_ms() -> float:
    """The central delay [ms] at which the 2-link arm's task-space design (no filters)
    stops being passive at low frequency: ``Z ~ K / (jw) + C`` with the delayed stiffness
    ``K e^{-jwT} / (jw) ~ K / (jw) - K T``, so ``Herm C - K T`` loses definiteness at the
    smallest generalized eigenvalue of ``(Herm C, K)``."""
    from scipy.linalg import eigh

    r = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14)
    z = sea_joint_impedance(r, [1e-4])[0]
    return 1e3 * float(eigh(0.5 * (z + z.conj().T).real, r.stiffness, eigvals_only=True)[0])


@pytest.mark.parametrize("factor", [0.995, 1.005, None])
def test_passivity_verdict_near_the_boundary(factor):
    """Oracle: the dense-grid smallest eigenvalue of the Hermitian part of the second
    derivation (2000 points per decade), on designs 0.5 % either side of the analytic
    boundary (:func:`boundary_ms`), and Table I (not passive in mid band)."""
    delays = ({"stiffness": boundary_ms() * factor} if factor else TABLE_I["delays_ms"])
    filters = (None, None) if factor else TABLE_I["filters_hz"]
    r = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14, delays_ms=delays,
                 filters_hz=filters)
    f = np.logspace(-2, 4, 12001)
    zq = sea_joint_impedance(r, f)
    lam = np.linalg.eigvalsh(0.5 * (zq + np.conj(np.swapaxes(zq, 1, 2))))[:, 0]
    p = r.passivity()
    assert p.proven
    assert p.passive == bool(lam.min() > 0)
    if factor:
        assert p.passive == (factor < 1)
    if not p.passive:
        zn = sea_joint_impedance(r, [p.negative_f_hz])[0]
        assert np.linalg.eigvalsh(0.5 * (zn + zn.conj().T))[0] < 0
    # the reported worst point: the 400-per-decade grid's, of the second derivation too
    g = f[::5]
    assert p.worst_f_hz == pytest.approx(g[np.argmin(lam[::5])], rel=1e-12)
    assert p.hermitian_min == pytest.approx(lam[::5].min(), rel=1e-7, abs=1e-9)


def test_stretched_arm_task_impedance_is_tangential():
    """Oracle: geometry. Stretched (q2 = 0) the joints move the tool only perpendicular to
    the arm: rank 1, the basis orthogonal to the tool's position, and ``Z_x`` the scalar
    ``1 / (u^T J Z_q^-1 J^T u)``."""
    r = sc.robot(ARM, space="task", task="tool", q0=[0.3, 0.0], fn_hz=30)
    t = r.task_impedance([1.0, 10.0])
    assert t.z.shape == (2, 1, 1)
    radial = np.array([np.cos(0.3), np.sin(0.3), 0.0])   # the arm's direction in x, y
    u = t.basis[:, 0]
    assert abs(u @ radial) < 1e-9 and abs(np.linalg.norm(u) - 1) < 1e-12
    J = r.body.jacobian[:3]
    y = np.array([u @ J @ np.linalg.solve(zq, J.T @ u) for zq in r.impedance_matrix([1, 10])])
    assert np.allclose(t.z[:, 0, 0], 1 / y, rtol=1e-9)


def test_task_step_one_link_is_r_times_the_sea_step(tmp_path):
    """Oracle: sc.design(14).step() (normalized): the tool at r = 0.1 m moves r q."""
    r = sc.robot(one_link(tmp_path), space="task", task="tool", fn_hz=14, **TABLE_I)
    s = r.task_step((0, 1, 0), amplitude_m=1e-3, t_end_s=0.3)
    sd = sc.design(14, **TABLE_I).step(t_end_s=0.3)
    assert np.max(np.abs(s.along_m / 1e-3 - np.asarray(sd.position))) <= 1e-9
    assert np.allclose(s.x_m[1], 0.1 * s.q_rad[0], rtol=1e-12, atol=0)


def test_task_step_final_value_and_impulse_momentum():
    """Oracles: the stiffness holds the reference (K q = K J^+ dx, so J q -> dx); the hand's
    velocity right after a force impulse F is J M^-1 J^T F (M from pinocchio's CRBA)."""
    r = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14, **TABLE_I)
    d = np.array([0.6, -0.8, 0.0])
    s = r.task_step(d, amplitude_m=2e-3, t_end_s=8.0)
    assert s.stable
    assert np.allclose(s.x_m[:, -1], 2e-3 * d, rtol=0, atol=1e-7)
    model = pin.buildModelFromUrdf(str(ARM))
    M = pin.crba(model, model.createData(), np.array(Q0))
    M = np.triu(M) + np.triu(M, 1).T
    J = r.body.jacobian[:3]
    v0 = J @ np.linalg.solve(M, J.T @ (0.01 * d))
    i = r.task_impulse(d, amplitude_n_s=0.01, t_end_s=0.5)
    k = 5   # x(t) = v0 t + O(t^2): the slope over the first samples
    slope = i.x_m[:, k] / i.t_s[k]
    assert np.allclose(slope, v0, rtol=2e-3, atol=2e-3 * np.max(np.abs(v0)))


def test_workspace_passive_is_each_configuration():
    """Oracle: Robot.passivity() of the same design at each configuration alone."""
    q = [[0.3, 0.8], [0.0, 1.5]]
    opts = dict(space="task", task="tool", fn_hz=14, delays_ms={"stiffness": 2})
    m = sc.workspace_map(ARM, q, **opts)
    alone = [sc.robot(ARM, q0=row, **opts).passivity().passive for row in q]
    assert m.passive.tolist() == alone
    assert [row["passive"] for row in m.records()] == alone


def test_cli_impedance_json_is_the_api(capsys):
    import json

    args = ["robot", "--urdf", str(ARM), "--space", "task", "--task", "tool", "--q0",
            "0.3,0.8", "--fn", "14", "--t-qs", "2"]
    assert main(args + ["--impedance", "1,10", "--task-step", "1,0,0", "--json"]) in (0, None)
    out = json.loads(capsys.readouterr().out)
    r = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14, delays_ms={"stiffness": 2})
    t = r.task_impedance([1, 10])
    assert [row["principal_1"] for row in out["impedance"]["rows"]] == pytest.approx(
        t.principal_values[:, 0].tolist(), rel=1e-9)
    assert out["passivity"]["passive"] == r.passivity().passive
    assert out["task_step"]["final_along_m"] == pytest.approx(
        float(r.task_step((1, 0, 0)).along_m[-1]), rel=1e-9)


@pytest.mark.parametrize("extra", [["--impedance", "1,x"], ["--task-step", "1,0"],
                                   ["--task-impulse", "0,0,0"], ["--impedance", "-1"],
                                   ["--impedance", "1", "--mujoco-check"]])
def test_cli_bad_input_is_one_line(capsys, extra):
    """A behaviour: one line `error: ...` naming the option, exit 2, nothing else."""
    args = ["robot", "--urdf", str(ARM), "--space", "task", "--task", "tool", "--q0",
            "0.3,0.8", "--fn", "14"]
    assert main(args + extra) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    assert out.err.startswith("error: invalid " + extra[0]) or (
        len(extra) == 3 and out.err.startswith("error: invalid --impedance/"))


def test_api_errors_name_the_field():
    r = sc.robot(ARM, q0=Q0, fn_hz=14)                         # no task frame
    for call, field in ((lambda: r.task_impedance([1.0], space="task"), "space"),
                        (lambda: r.task_step((1, 0, 0)), "task"),
                        (lambda: r.passivity((10, 1)), "f_range_hz"),
                        (lambda: r.passivity((10,)), "f_range_hz")):
        with pytest.raises(InputError) as exc:
            call()
        assert exc.value.field == field
    rt = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14)
    with pytest.raises(InputError):
        rt.task_impulse((0, 0, 0))
