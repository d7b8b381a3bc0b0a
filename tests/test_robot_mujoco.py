"""The planar 2-link arm in MuJoCo against seactl's linear predictions (issue 41, item 3).

MuJoCo integrates the nonlinear rigid body of the URDF as MuJoCo compiles it (Coriolis and
centrifugal terms, the mass matrix moving with ``q``), gravity in the arm's plane
compensated by MuJoCo's ``gravcomp``, each SEA a rotor and a tendon spring; seactl's own
sampled controllers tick against it (seactl.codegen.mujoco_robot).

Oracles: the sampled linear response (``Robot.step(mode="sampled")``: the same
controllers on the exactly discretized linear plant) near ``q0``, with the nonlinearity's
second order (halving the step halves the relative error); pinocchio's generalized gravity
for the compensation; the certified verdict (``margins().stable``, checked against the
rightmost roots and the sampled loop's period map) on both sides of the predicted delay
margin of the central process.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import seactl as sc

pin = pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")
mujoco = pytest.importorskip("mujoco", reason="MuJoCo (pip install mujoco) is not installed")

from seactl.codegen.mujoco_robot import robot_mjcf, simulate_robot_mujoco  # noqa: E402
from seactl.simulate.engine import simulate  # noqa: E402
from seactl.simulate.inputs import Step  # noqa: E402
from seactl.simulate.sampled import sampled_roots  # noqa: E402

ARM = Path(__file__).resolve().parents[1] / "examples" / "robots" / "planar_2link.urdf"
GRAVITY = (0.0, -9.81, 0.0)  # in the arm's plane: every joint carries gravity
DELAYS_MS = {"torque": 0.5, "stiffness": 2, "damping": 0.5}
FILTERS_HZ = (50, 100)
CONFIGURATIONS = ([0.3, 0.8], [0.0, 1.5], [-0.5, 2.2])


def arm(q0, stiffness_ms=2.0):
    return sc.robot(ARM, q0=q0, fn_hz=20, delays_ms=dict(DELAYS_MS, stiffness=stiffness_ms),
                    filters_hz=FILTERS_HZ)


def run(r, inputs, t_end_s, outputs=("q_j.j1", "q_j.j2", "i_m.j1", "i_m.j2")):
    limits = {f"i_m.j{j + 1}": float(a.max_current) for j, a in enumerate(r.actuators)}
    return simulate_robot_mujoco(ARM, r.body, r.actuators, r.diagram, r.design, inputs,
                                 t_end_s, outputs=outputs, saturation=limits,
                                 gravity_mps2=GRAVITY)


def test_gravity_compensation_is_pinocchios_generalized_gravity():
    """Oracle: pinocchio's computeGeneralizedGravity of the same URDF (a second rigid-body
    library) equals the force MuJoCo's gravcomp applies, off the arm's rest pose."""
    r = arm([0.3, 0.8])
    plant = robot_mjcf(ARM, r.body.joints, r.actuators, gravity_mps2=GRAVITY)
    m = mujoco.MjModel.from_xml_string(plant.xml)
    d = mujoco.MjData(m)
    model = pin.buildModelFromUrdf(str(ARM))
    model.gravity.linear = np.array(GRAVITY)
    for q in ([0.3, 0.8], [-1.0, 2.0]):
        for name, v in zip(r.body.joints, q):
            d.qpos[m.jnt_qposadr[m.joint(name).id]] = v
        mujoco.mj_forward(m, d)
        got = [d.qfrc_gravcomp[m.jnt_dofadr[m.joint(name).id]] for name in r.body.joints]
        want = pin.computeGeneralizedGravity(model, model.createData(), np.array(q))
        assert np.allclose(got, want, rtol=1e-9, atol=1e-12)
        assert np.max(np.abs(want)) > 1.0  # gravity is really carried


def step_errors(r, amplitude):
    """Largest |MuJoCo - linear| of each joint's response to a step of joint 1's
    reference over 0.4 s, over the step: joint 1 against Robot.step(mode="sampled"),
    joint 2 (moved through the coupling) against the same sampled simulation."""
    mj = run(r, {"q_des.j1": Step(amplitude)}, 0.4)
    lin = r.step(t_end_s=0.4, amplitude=amplitude, mode="sampled", rate_hz=1000.0)
    both = simulate(r.diagram, r.design, {"q_des.j1": Step(amplitude)}, 0.4, mode="sampled",
                    outputs=("q_j.j2",), rates_hz=1000.0, saturation=r.saturation())
    assert np.allclose(mj.t_s, lin.t_s)
    # no current reaches its limit: the loop is linear but for the rigid body
    assert np.max(np.abs(mj.outputs["i_m.j1"])) < r.actuators[0].max_current
    q2 = both.outputs["q_j.j2"].ravel()
    assert np.max(np.abs(q2)) > 0.5 * amplitude  # joint 2 really moves
    return np.array([np.max(np.abs(mj.outputs["q_j.j1"] / amplitude - lin.position)),
                     np.max(np.abs(mj.outputs["q_j.j2"] - q2)) / amplitude])


def test_small_step_agrees_with_the_linear_prediction_to_second_order():
    """Oracle: the sampled linear response (Robot.step(mode="sampled")); the rigid body's
    nonlinearity is second order (velocity products, M(q) moving with q), so the relative
    error is proportional to the step: at most 2/rad times it on each joint, and halving
    the step halves it."""
    r = arm([0.3, 0.8])
    a = 2e-4  # [rad]: the current peaks at 4.9 A, far below its 30 A limit
    e1, e2 = step_errors(r, a), step_errors(r, a / 2)
    assert np.all(e1 < 2.0 * a) and np.all(e2 < 2.0 * a / 2)
    assert np.all((0.4 < e2 / e1) & (e2 / e1 < 0.6))


def window_peak(t_s, y, start_s, stop_s):
    return float(np.abs(y[(t_s >= start_s) & (t_s < stop_s)]).max())


@pytest.mark.parametrize("q0", CONFIGURATIONS)
def test_mujoco_agrees_with_the_verdict_across_the_delay_margin(q0):
    """Oracle: the certified verdict at 0.8x and 1.2x of the central process's predicted
    delay margin (System.delay_margin along the stiffness delay), itself checked against
    the rightmost roots and the sampled loop's period map at 1 kHz; MuJoCo's response to
    an impulse on joint 1 (Robot.mujoco_check's runs, read here on their own) decays
    below the margin and grows above it."""
    r = arm(q0)
    margin = r.delay_margin({"stiffness": 1})
    assert bool(margin.verified)
    check = r.mujoco_check((0.8, 1.2), t_end_s=1.0, gravity_mps2=GRAVITY)
    assert check.delay_margin_s == pytest.approx(float(margin.crossing_delays_s["stiffness"]))
    assert check.stable.tolist() == [True, False]
    for factor, stable, y in zip(check.factors, check.stable, check.q_j1_rad):
        d = arm(q0, factor * check.delay_margin_s * 1e3)
        assert bool(d.roots(count=3).spectral_abscissa < 0) is bool(stable)
        assert sampled_roots(d.diagram, d.design, 1000.0).verdict == (
            "stable" if stable else "unstable")
        ratio = (window_peak(check.t_s, y, 0.8, 1.01)
                 / window_peak(check.t_s, y, 0.2, 0.4))
        assert (ratio < 0.8) if stable else (ratio > 1.25), (factor, ratio)
        assert np.max(np.abs(y)) < 0.01  # [rad]: small, near q0
    assert check.agrees


def test_mujoco_check_refuses_bad_arguments():
    """A behaviour: InputError naming the argument, before any run."""
    r = arm([0.3, 0.8])
    for kw, field in ((dict(factors=[]), "factors"), (dict(factors=[0.8, -1]), "factors"),
                      (dict(t_end_s=50.0), "t_end_s"), (dict(impulse=0.0), "impulse")):
        with pytest.raises(sc.InputError, match=field):
            r.mujoco_check(**kw)


def test_cli_mujoco_check_is_the_api(capsys):
    """Oracle: the API (Robot.mujoco_check) on the same robot: the CLI prints its records."""
    import json

    from seactl.apps.cli import main

    argv = ["robot", "--urdf", str(ARM), "--q0", "0,1.5", "--fn", "20", "--t-tau", "0.5",
            "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50", "--f-taud", "100",
            "--mujoco-check", "--json"]
    assert main(argv) == 0
    got = json.loads(capsys.readouterr().out)["mujoco_check"]
    want = arm([0.0, 1.5]).mujoco_check().records()
    assert [r["agree"] for r in got] == [True, True]
    assert got == want


def test_cli_mujoco_check_without_mujoco_is_one_line(capsys, monkeypatch):
    """A behaviour: without MuJoCo, one line saying how to install it, exit 2."""
    import sys

    from seactl.apps.cli import main

    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco -> ImportError
    assert main(["robot", "--urdf", str(ARM), "--q0", "0,1.5", "--fn", "20",
                 "--mujoco-check"]) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    assert out.err.startswith("error: ") and "seactl[sim]" in out.err
