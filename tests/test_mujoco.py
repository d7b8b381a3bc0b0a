"""MuJoCo as the plant (seactl.codegen.mjcf, seactl.codegen.mujoco_plant).

Oracles: the actuator parameters read back from MuJoCo's compiled model; the SEA's linear
plant of docs/theory/loop.md written here as a 4-state system and solved exactly with
scipy's matrix exponential; seactl's sampled simulation (the plant discretized exactly,
the same sampled controller); the continuous response of ``System.step()``; the
integrator orders (RK4: error / 2^4 when the step halves; zero-order hold: error / 2 when
the sample period halves); and the rightmost characteristic root of ``System.roots()``
for the growth and decay of the MuJoCo runs on either side of the delay margin.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg

import seactl as sc
from seactl.simulate.engine import simulate
from seactl.simulate.inputs import Step

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is not installed (pip install "
                             "'seactl[sim]')")

from seactl.codegen.mjcf import plant_model  # noqa: E402
from seactl.codegen.mujoco_plant import MujocoPlant, simulate_mujoco  # noqa: E402

UT = sc.design(14).design.actuator


def test_the_model_holds_the_parameters():
    # oracle: the SEA's parameters, read back from MuJoCo's compiled model
    model = plant_model(sc.design(14).design)
    m = mujoco.MjModel.from_xml_string(model.xml)
    rotor, load = m.body("rotor").id, m.body("load").id
    assert m.body_inertia[rotor, 2] == UT.Im and m.body_inertia[load, 2] == UT.Ij
    assert m.dof_damping[m.joint("motor").dofadr[0]] == UT.bm
    assert m.dof_damping[m.joint("joint").dofadr[0]] == UT.bj
    assert m.tendon_stiffness[0] == UT.k
    assert m.actuator_gear[m.actuator("motor").id, 0] == UT.beta
    assert m.actuator_ctrlrange[m.actuator("motor").id].tolist() == [-UT.max_current,
                                                                      UT.max_current]


def _linear_sea(i_a: float, t_s: np.ndarray) -> np.ndarray:
    """(q_j, tau_k) of the linear plant at rest under a constant current: exact solution
    of I_m q_m'' + b_m q_m' = beta i - k (q_m - q_j), I_j q_j'' + b_j q_j' = k (q_m - q_j)."""
    a = UT
    A = np.array([[0, 1, 0, 0],
                  [-a.k / a.Im, -a.bm / a.Im, a.k / a.Im, 0],
                  [0, 0, 0, 1],
                  [a.k / a.Ij, 0, -a.k / a.Ij, -a.bj / a.Ij]])
    b = np.array([0, a.beta * i_a / a.Im, 0, 0])
    M = np.zeros((5, 5))
    M[:4, :4], M[:4, 4] = A, b
    x = np.array([scipy.linalg.expm(M * t)[:4, 4] for t in t_s])
    return np.stack([x[:, 2], a.k * (x[:, 0] - x[:, 2])], axis=1)


def _open_loop(i_a: float, period_s: float, substeps: int, ticks: int) -> np.ndarray:
    model = plant_model(sc.design(14).design, period_s / substeps)
    plant = MujocoPlant(model, period_s, ["q_j", "tau_k"], ["i_m"])
    y = [plant.sense()]
    for _ in range(ticks):
        plant.advance([i_a])
        y.append(plant.sense())
    return np.array(y)


def test_sea_plant_is_the_linear_model_to_rk4_accuracy():
    # oracle: the exact solution of the linear plant; RK4's order (halving h: / 16)
    Ts, ticks = 1e-3, 100
    exact = _linear_sea(1.0, np.arange(ticks + 1) * Ts)
    scale = np.max(np.abs(exact), axis=0)
    err = [np.max(np.abs(_open_loop(1.0, Ts, n, ticks) - exact) / scale) for n in (2, 4)]
    assert err[1] < 2e-6
    assert 12 < err[0] / err[1] < 20


def test_current_limit_clips_the_motor():
    # oracle: the linear plant driven at the current limit (30 A) for a 100 A command
    Ts, ticks = 1e-3, 50
    exact = _linear_sea(UT.max_current, np.arange(ticks + 1) * Ts)
    y = _open_loop(100.0, Ts, 10, ticks)
    assert np.max(np.abs(y - exact) / np.max(np.abs(exact), axis=0)) < 1e-6


def _step_error(system, substeps, rate_hz=1000.0, t_end_s=0.3):
    """Largest difference, relative to the step, between the MuJoCo closed loop and the
    sampled simulation (exact plant, the same controller) at ``rate_hz``."""
    a, kw = system.default_step, {"rates_hz": rate_hz, "saturation": system.saturation()}
    inputs = {system.reference: Step(a)}
    ref = simulate(system.diagram_for(), system.design, inputs, t_end_s, mode="sampled",
                   outputs=(system.output,), **kw)
    run = simulate_mujoco(system.diagram_for(), system.design, inputs, t_end_s,
                          outputs=(system.output,), substeps=substeps, **kw)
    return np.max(np.abs(run.outputs[system.output] - np.ravel(ref.outputs[system.output])))/a


@pytest.mark.parametrize("system, bound", [
    (sc.design(14, filters_hz=(50, 100)), 1e-6),
    (sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}), 1e-11)])
def test_closed_loop_step_matches_the_sampled_simulation(system, bound):
    # oracle: seactl's sampled simulation (the same controller, the plant exact); RK4's
    # order: two and four MuJoCo steps per 1 ms period differ by 2^4
    e2, e4 = _step_error(system, 2), _step_error(system, 4)
    assert e2 < bound
    assert 12 < e2 / e4 < 20


def test_impulse_of_the_external_torque_matches_the_sampled_simulation():
    # oracle: the sampled simulation's impulse (a jump of the load's velocity); RK4's order
    from seactl.simulate.inputs import Impulse

    d = sc.design(14, filters_hz=(50, 100))
    inputs, kw = {"tau_ext": Impulse(0.05)}, {"rates_hz": 1000.0, "saturation": d.saturation()}
    ref = np.ravel(simulate(d.diagram_for(), d.design, inputs, 0.3, mode="sampled",
                            outputs=("q_j",), **kw).outputs["q_j"])
    err = [np.max(np.abs(simulate_mujoco(d.diagram_for(), d.design, inputs, 0.3,
                                         outputs=("q_j",), substeps=n, **kw).outputs["q_j"]
                         - ref)) / np.max(np.abs(ref)) for n in (2, 4)]
    assert err[0] < 1e-6 and 12 < err[0] / err[1] < 20


def test_closed_loop_converges_to_the_continuous_step():
    # oracle: System.step() (continuous, zero delays); sampling adds half a period of
    # delay, so the difference is first order in the period: / 2 from 2 kHz to 4 kHz (a
    # 1 mrad step: the current stays far below its limit, the responses are linear)
    d = sc.design(14, filters_hz=(50, 100))
    cont = d.step(t_end_s=0.3)
    diff = []
    for rate in (2000.0, 4000.0):
        run = simulate_mujoco(d.diagram_for(), d.design, {"q_des": Step(1e-3)}, 0.3,
                              outputs=("q_j",), rates_hz=rate, saturation=d.saturation(),
                              substeps=2)
        q = np.interp(run.t_s, cont.t_s, np.ravel(cont.position))
        diff.append(np.max(np.abs(run.outputs["q_j"] / 1e-3 - q)))
    assert diff[1] < 0.01
    assert 1.6 < diff[0] / diff[1] < 2.5


def _envelope_rate(x: float) -> tuple[float, float]:
    """A design whose outer-loop delays are ``x`` times the delay margin of the same design
    without delays: the growth rate [1/s] of the MuJoCo step's envelope (peak error in
    0.2-0.4 s against 0.4-0.6 s) and the rightmost root's real part."""
    dm = float(sc.design(20, filters_hz=(50, 100)).margins().delay_margin_ms)
    d = sc.design(20, delays_ms={"stiffness": x * dm, "damping": x * dm}, filters_hz=(50, 100))
    run = simulate_mujoco(d.diagram_for(), d.design, {"q_des": Step(1e-3)}, 0.6,
                          outputs=("q_j",), rates_hz=5000.0, saturation=d.saturation(),
                          substeps=2)
    e = np.abs(run.outputs["q_j"] / 1e-3 - 1)
    w1, w2 = (run.t_s >= 0.2) & (run.t_s < 0.4), run.t_s >= 0.4
    return float(np.log(e[w2].max() / e[w1].max()) / 0.2), float(d.roots().spectral_abscissa)


@pytest.mark.parametrize("x", [0.8, 1.2])
def test_stability_either_side_of_the_delay_margin(x):
    # oracle: the margins' delay margin (0.8x stable, 1.2x not) and the rightmost root:
    # the MuJoCo envelope decays or grows at its real part (within 25%)
    rate, sigma = _envelope_rate(x)
    assert (sigma < 0) == (x < 1)
    assert np.sign(rate) == np.sign(sigma)
    assert abs(rate - sigma) < 0.25 * abs(sigma)


def test_importing_the_plant_does_not_import_mujoco():
    # oracle: sys.modules of a fresh interpreter
    code = ("import sys, seactl, seactl.codegen.mujoco_plant, seactl.codegen.mjcf; "
            "print('mujoco' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_band_verdicts():
    # oracle: a band built by hand; the measured step leaves it by 0.2 at the last tick
    from seactl.latency.band import compare_band

    t = np.arange(4) * 1e-3
    lo, hi = np.array([0, 0.2, 0.8, 0.9]), np.array([0, 0.4, 1.0, 1.0])
    assert compare_band(t, np.array([0, 0.3, 0.9, 0.95]), lo, hi, 10).within
    v = compare_band(t, np.array([0, 0.3, 0.9, 1.2]), lo, hi, 10, tolerance=0.0)
    assert not v.within and v.ticks_outside == 1 and v.t_worst_s == 3e-3
    assert v.max_outside == pytest.approx(0.2) and v.verdict.startswith("outside: 1 of 4")


def test_mujoco_step_inside_and_outside_the_monte_carlo_band():
    # oracle: the band of System.monte_carlo's machinery around the MuJoCo step of the
    # same design holds it when the latency distribution covers the design's delay, and
    # does not when every latency is twice as long
    from seactl.latency.band import step_band
    from seactl.latency.models import Uniform

    d = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
                  filters_hz=(50, 100))
    kw = {"rates_hz": 1000.0, "saturation": d.saturation()}
    run = simulate_mujoco(d.diagram_for(), d.design, {"q_des": Step(0.01)}, 0.3,
                          outputs=("q_j",), substeps=10, **kw)
    band = {"step": 0.01, "reference": "q_des", "output": "q_j", "links": d.links, **kw}
    inside = step_band(d.diagram_for(), d.design, run.t_s, run.outputs["q_j"],
                       latency={"stiffness": Uniform(1e-3, 3e-3)}, **band)
    outside = step_band(d.diagram_for(), d.design, run.t_s, run.outputs["q_j"],
                        latency={"stiffness": Uniform(4e-3, 6e-3)}, **band)
    assert inside.within and inside.max_width > 0.01
    assert not outside.within and outside.max_outside > 0.05


@pytest.mark.parametrize("system", [
    sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1}, filters_hz=(50, 100)),
    pytest.param(sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}),
                 marks=pytest.mark.slow)])
def test_run_on_the_mujoco_plant(system):
    # oracle: the replay of the measured timing on the exact linear plant (the difference
    # is MuJoCo's RK4 error, 1e-4 s steps) and the band for the run's measured latency
    # (drawn independently per message, so a run's own stalls may leave it by a little:
    # bounded at 1% of the step, the timing itself is not deterministic)
    res = system.run(duration_s=0.3, transport="udp", plant="mujoco")
    s = res.summary
    assert s["plant"] == "mujoco" and s["plant_timestep_s"] == 1e-4
    assert s["replay_max_diff"] < 1e-8
    band = s["prediction_band"]
    assert band["within"] == (band["verdict"] == "within the predicted band")
    assert band["max_outside"] < 0.01 and band["runs"] in (1, 200)   # 1: one latency


def test_run_refuses_a_band_without_mujoco():
    with pytest.raises(sc.InputError, match="latency"):
        sc.design(14).run(duration_s=0.3, transport="udp", latency={"stiffness": "uniform:1:3"})


@pytest.mark.parametrize("args, needle", [
    (["--latency", "stiffness=uniform:1:3"], "--plant mujoco or --realtime only"),
    (["--plant", "mujoco", "--latency", "speed=uniform:1:3"], "stiffness, damping, torque"),
    (["--plant", "mujoco", "--latency", "stiffness=bogus"], "--latency")])
def test_cli_band_bad_input(args, needle, capsys):
    # oracle: the CLI's contract (one line, exit 2), before any process starts
    from seactl.apps.cli import main

    assert main(["run", "--fn", "14", "--transport", "udp", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err


def test_mujoco_step_with_a_latency_distribution_is_the_timed_simulation():
    # oracle: seactl's sampled simulation of the same timing realization (the same seed:
    # the same arrival schedule of the stiffness messages), the plant exact; MuJoCo's RK4
    # at 1e-4 s adds no more than 1e-8 of the step
    from seactl.latency.models import Uniform
    from seactl.latency.montecarlo import LinkTiming, timed_simulation

    d = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
                  filters_hz=(50, 100))
    dg, lat = d.diagram_for(), {"stiffness": Uniform(1e-3, 3e-3)}
    block = next(b for b in dg.blocks if b.name == d.links["stiffness"])
    kw = {"rates_hz": 1000.0, "saturation": d.saturation(), "outputs": ("q_j",)}
    run = simulate_mujoco(dg, d.design, {"q_des": Step(0.01)}, 0.3, substeps=10,
                          timing=LinkTiming({"stiffness": block}, lat, {}, 1, 3), **kw)
    ref = timed_simulation(dg, d.design, {"q_des": Step(0.01)}, 0.3, latency=lat, runs=1,
                           seed=3, links=d.links, **kw)
    fixed = simulate_mujoco(dg, d.design, {"q_des": Step(0.01)}, 0.3, substeps=10, **kw)
    assert np.max(np.abs(run.outputs["q_j"] - np.ravel(ref.outputs["q_j"]))) < 1e-8 * 0.01
    assert np.max(np.abs(run.outputs["q_j"] - fixed.outputs["q_j"])) > 1e-3 * 0.01
