"""The sampled-data loop's certified verdict, z-plane roots and margins (seactl.simulate.sampled).

Oracles: characteristic polynomials derived by hand for simple held loops (roots counted
with numpy.roots), python-control's ``c2d(..., 'zoh')`` / ``'tustin'`` and ``feedback``
on the rigid loop (closed-loop poles and ``margin``), matrices of known spectrum for the
certificate, and the simulation of the same loop for the 27.5 Hz tutorial design.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import seactl as sc
from seactl.base.limits import check_sampled_analysis
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.errors import InputError
from seactl.simulate.sampled import sampled_margins, sampled_roots, schur_count

RATE = 1000.0
T = 1.0 / RATE


def _loop(pd: bool) -> BlockDiagram:
    """r -> e = r - delayed y; u = C e; plant integrator 1/s (``pd`` False, C = K) or first
    order 1/(tau s + 1) with PD control C = Kp + Kd s (``pd`` True)."""
    ctrl = Block("pd", "e", "u", num=lambda p: (p.Kd, p.Kp)) if pd else \
        Block("p", "e", "u", num=lambda p: (p.K,))
    plant = Block("plant", "u", "y", den=lambda p: (p.tau, 1.0) if pd else (1.0, 0.0),
                  role="plant")
    return BlockDiagram("test", [
        Block("ref", "r", "e"), Block("sensor", "y", "y_sens", role="sensor"),
        Block("fb", "y_sens", "e", num=lambda p: (-1.0,), delay="T"), ctrl, plant])


def _count_outside(coeffs) -> int:
    return int(np.sum(np.abs(np.roots(coeffs)) > 1))


@pytest.mark.parametrize("n", [0, 1, 2, 4])
@pytest.mark.parametrize("rel", [0.97, 1.03])
def test_held_integrator_with_whole_sample_delay_matches_hand_polynomial(n, rel):
    # Oracle: by hand.  ZOH on 1/s: x[k+1] = x[k] + T u[k]; the sensor samples x at the
    # tick, the buffer gives y[k-n] (requested delay T/2 + nT, realized exactly), so
    # u[k] = -K x[k-n] and x[k+1] = x[k] - K T x[k-n]: z^(n+1) - z^n + K T = 0.  Its
    # stability boundary is K T = 2 sin(pi / (2 (2n + 1))) (the root on |z| = 1 at
    # z = e^{+-j pi/(2n+1)}); designs 3 % either side.
    a = rel * 2 * np.sin(np.pi / (2 * (2 * n + 1)))
    d = SimpleNamespace(K=np.array(a / T), T=np.array(T / 2 + n * T), shape=())
    r = sampled_roots(_loop(False), d, RATE)
    expected = _count_outside([1.0, -1.0] + [0.0] * (n - 1) + [a] if n else [1.0, a - 1.0])
    assert int(r.unstable_modes) == expected == (0 if rel < 1 else 2 if n else 1)
    # every root of the polynomial is an eigenvalue of the map (the rest are 0)
    lam = np.sort(np.abs(r.z))[::-1][:n + 1]
    coeffs = [1.0, -1.0] + [0.0] * (n - 1) + [a] if n else [1.0, a - 1.0]
    np.testing.assert_allclose(lam, np.sort(np.abs(np.roots(coeffs)))[::-1], rtol=1e-9)


# boundaries found on the hand polynomial: Kd = 5.3386e-3 at Kp = 3, Kp = 11.447 at
# Kd = 2e-3; each case 3 % from one
@pytest.mark.parametrize("Kp, Kd, expected", [(3.0, 0.97 * 5.3386e-3, 0),
                                              (3.0, 1.03 * 5.3386e-3, 2),
                                              (0.97 * 11.447, 0.002, 0),
                                              (1.03 * 11.447, 0.002, 2)])
def test_held_first_order_plant_with_pd_matches_hand_polynomial(Kp, Kd, expected):
    # Oracle: by hand.  ZOH on 1/(tau s + 1): y[k+1] = p y[k] + (1 - p) u[k], p = e^{-T/tau};
    # Tustin PD C(z) = Kp + Kd (2/T)(z - 1)/(z + 1); one sample of buffer (requested 1.5 T):
    # U = -C(z) z^-1 Y.  So z (z - p)(z + 1) + (1 - p)(Kp (z + 1) + Kd (2/T)(z - 1)) = 0,
    # roots counted with numpy.roots; the cases sit near the boundaries in Kd and Kp.
    tau = 0.01
    p = np.exp(-T / tau)
    d = SimpleNamespace(Kp=np.array(Kp), Kd=np.array(Kd), tau=np.array(tau),
                        T=np.array(1.5 * T), shape=())
    poly = np.polyadd(np.polymul([1.0, -p, 0.0], [1.0, 1.0]),
                      (1 - p) * np.array([0.0, Kp + 2 * Kd / T, Kp - 2 * Kd / T]))
    r = sampled_roots(_loop(True), d, RATE)
    assert int(r.unstable_modes) == _count_outside(poly) == expected


def _rigid_case(ms_s: float, ms_d: float):
    from seactl.systems.rigid.model import UT_LINEAR, RigidDesign

    return RigidDesign.from_fn(UT_LINEAR, np.array([8.0, 12.0, 20.0]), T_s=ms_s * 1e-3,
                               T_d=ms_d * 1e-3, f_v=100.0)


@pytest.mark.filterwarnings("ignore:stability_margins")
@pytest.mark.parametrize("ms_s, ms_d, ns, nd", [(0.0, 0.0, 0, 0), (1.5, 3.5, 1, 3)])
def test_rigid_loop_poles_and_margins_match_python_control(ms_s, ms_d, ns, nd):
    # Oracle: python-control builds the same sampled loop independently: the plant
    # 1/(m s^2 + b s) discretized with c2d(..., 'zoh'), the damping path B s/(Tf s + 1)
    # with c2d(..., 'tustin'), whole-sample delays z^-n (T/2 + nT requested, so
    # n = ns, nd), unity negative feedback; its closed-loop poles and margin().
    import control as ct

    from seactl.systems.rigid.model import RIGID_DIAGRAM

    des = _rigid_case(ms_s, ms_d)
    r = sampled_roots(RIGID_DIAGRAM, des, RATE)
    m = sampled_margins(RIGID_DIAGRAM, des, "x_sens", RATE, des.wn)
    zinv = ct.tf([1.0], [1.0, 0.0], T)
    for i in range(3):
        a, K, B = des.actuator, float(des.K[i]), float(des.B[i])
        tf_v = 1 / (2 * np.pi * 100.0)
        P = ct.c2d(ct.tf([1.0], [a.m, a.b, 0.0]), T, "zoh")
        Cd = ct.c2d(ct.tf([B, 0.0], [tf_v, 1.0]), T, "tustin")
        C = K * zinv**ns + Cd * zinv**nd if (ns or nd) else K + Cd
        L = P * C
        poles = np.sort(np.abs(ct.poles(ct.feedback(L, 1))))[::-1]
        ours = np.sort(np.abs(r.z[i]))[::-1][:poles.size]
        np.testing.assert_allclose(ours, poles, rtol=1e-6, atol=1e-9)
        assert int(r.unstable_modes[i]) == int(np.sum(poles > 1))
        gm, pm, wpc, wgc = ct.margin(L)
        assert m.phase_margin_deg[i] == pytest.approx(pm, abs=1e-4)
        assert 2 * np.pi * m.crossover_hz[i] == pytest.approx(wgc, rel=1e-5)
        assert m.gain_margin[i] == pytest.approx(gm, rel=1e-4)


def test_certificate_counts_known_spectra_and_refuses_the_unit_circle():
    # Oracle: matrices built from a chosen spectrum by a random similarity.
    rng = np.random.default_rng(1)
    V = rng.normal(size=(4, 4))
    spectra = [(0.999, 0.5, -0.9, 0.1), (1.001, 0.5, -0.9, 0.1), (1.2, -1.5, 0.3, 0.0),
               (1.0, 0.5, 0.2, 0.1)]
    M = np.stack([V @ np.diag(s) @ np.linalg.inv(V) for s in spectra])
    count, radius = schur_count(M)
    assert count.tolist() == [0, 1, 2, -1]
    assert np.all(radius[:3] > 0) and radius[3] == 0


def test_tutorial_design_unstable_at_27_5_hz_matches_its_simulation():
    # Oracle: the simulation of the same loop (no saturation) diverges, and the
    # continuous verdict of the same design (certified scan) is stable.
    d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
    m = d.margins(rate_hz=27.5)
    assert bool(d.margins().stable) and str(m.verdict) == "unstable"
    r = d.step(mode="sampled", rate_hz=27.5, t_end_s=2.0, saturation_a=float("inf"))
    assert not bool(r.result.stable)
    assert r.to_dict()["sampled_verdict"] == "unstable"


def test_sampled_margins_approach_the_continuous_ones_with_matching_effective_delays():
    # Oracle: the continuous loop of the paper's effective-delay model.  With requested
    # delays T/2 + nT (realized exactly) the sampled loop at 10 kHz differs from the
    # continuous one only by Tustin warping and the hold's higher harmonics.
    d = sc.design(14, delays_ms={"torque": 0.55, "stiffness": 2.05, "damping": 0.55},
                  filters_hz=(50, 100))
    c, s = d.margins(), d.margins(rate_hz=10_000)
    assert float(s.phase_margin_deg) == pytest.approx(float(c.phase_margin_deg), abs=0.05)
    assert float(s.crossover_hz) == pytest.approx(float(c.crossover_hz), rel=1e-3)
    assert float(s.delay_margin_s) == pytest.approx(float(c.delay_margin_s), rel=1e-2)
    assert int(s.delay_margin_samples) == int(np.ceil(float(s.delay_margin_s) * 1e4) - 1)


def test_rate_none_is_the_continuous_result_and_multi_rate_gives_verdict_only():
    # Oracle: the continuous analysis itself (sea_margins), bit for bit.
    from seactl.systems.sea.views import sea_margins

    d = sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
    assert np.array_equal(d.margins(rate_hz=None).phase_margin_deg,
                          sea_margins(d.sea).phase_margin_deg)
    m = d.margins(rate_hz={"embedded": 1000.0, "high-level": 250.0})
    assert m.verdict.tolist() == ["stable", "stable"] and "multi-rate" in m.reason
    assert np.all(np.isnan(m.phase_margin_deg))


def test_too_large_analyses_are_refused_up_front():
    # Oracle: the documented limits (SAMPLED_MAX_STATES, SEACTL_MAX_SECONDS).
    with pytest.raises(InputError, match="states"):
        d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 100, "damping": 0.5})
        d.margins(rate_hz=50_000)
    with pytest.raises(InputError, match="estimate"):
        check_sampled_analysis(10**9, 50, 1200, 10)
    for bad in (5.0, "1000", True, [1000.0], {"embedded": 1000.0}):
        with pytest.raises(InputError, match="rate"):
            sc.design(14).margins(rate_hz=bad)


def cli_run(args, capsys, code=0):
    from seactl.apps.cli import main

    got = main(args)
    out, err = capsys.readouterr()
    assert got == code, err
    return SimpleNamespace(stdout=out, stderr=err)


def test_cli_gains_roots_jitter_step_show_the_sampled_verdict(capsys):
    # Oracle: the API's sampled margins of the same design (the CLI prints them), and
    # the verdict words of the issue.
    args = ["--fn", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50",
            "--f-taud", "100"]
    api = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                    filters_hz=(50, 100)).margins(rate_hz=27.5)
    out = json.loads(cli_run(["gains", *args, "--rate", "27.5", "--json"], capsys).stdout)
    assert out[0]["sampled"]["verdict"] == "unstable"
    assert out[0]["sampled"]["phase_margin_deg"] == pytest.approx(
        float(api.phase_margin_deg), abs=1e-9)
    text = cli_run(["gains", *args, "--rate", "27.5"], capsys).stdout
    assert "stable in continuous time, UNSTABLE sampled at 27.5 Hz" in text
    roots = json.loads(cli_run(["roots", *args, "--rate", "27.5", "--json"], capsys).stdout)
    z = roots["sampled"][0]["roots"][0]
    assert z["abs"] > 1 and roots["sampled"][0]["verdict"] == "unstable"
    assert z["s_rad_per_s"]["re"] == pytest.approx(np.log(z["abs"]) * 27.5, rel=1e-9)
    jit = json.loads(cli_run(["jitter", *args, "--rate", "1000", "--json"], capsys).stdout)
    assert jit["designs"][0]["sampled"]["verdict"] == "stable"
    step = json.loads(cli_run(["step", *args, "--mode", "sampled", "--rate", "27.5",
                               "--t-end", "1", "--json"], capsys).stdout)
    assert step["sampled_loop"]["text"].startswith(
        "stable in continuous time, UNSTABLE sampled at 27.5 Hz")
    bad = cli_run(["gains", *args, "--rate", "5"], capsys, code=2)
    assert bad.stderr.startswith("error:") and "--rate" in bad.stderr


def test_loop_file_of_the_paper_sea_gives_the_design_api_sampled_margins():
    # Oracle: a second, independent description of the same loop (examples/loops/
    # paper-sea.toml, compiled from TOML) broken at its "outer" break must give the
    # sampled margins of sc.design's diagram at the file's rates (1 kHz).
    loop = sc.load_loop(Path(__file__).resolve().parents[1] / "examples" / "loops"
                        / "paper-sea.toml")
    m = loop.margins(rate_hz={})
    d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100)).margins(rate_hz=1000)
    assert set(m) == set(loop.breaks)
    for key in ("phase_margin_deg", "crossover_hz", "gain_margin", "delay_margin_s"):
        assert float(getattr(m["outer"], key)) == pytest.approx(float(getattr(d, key)),
                                                                rel=1e-9)
    assert str(m["outer"].verdict) == str(m["torque"].verdict) == "stable"
    assert loop.margins().breaks[0].name == "torque"     # rate_hz None: the continuous loop


def _python_control_sea_poles(d, ns: int) -> np.ndarray:
    """|closed-loop poles| of the SEA loop sampled at 1 kHz, built with python-control
    alone: the motor/spring/load state space from the physics (docs/theory/loop.md),
    c2d(..., 'zoh'); the filtered derivatives c2d(..., 'tustin'); the stiffness path
    delayed by z^-ns; the controller wired as the paper's Fig. ControlBlock."""
    import control as ct

    a, g = d.actuator, d.gains
    k, Im, Ij = a.k, a.Im, a.Ij
    A = np.array([[0, 1, 0, 0], [-k / Im, -a.bm / Im, k / Im, 0], [0, 0, 0, 1],
                  [k / Ij, 0, -k / Ij, -a.bj / Ij]])
    B = np.array([[0], [a.beta / Im], [0], [0]])
    C = np.array([[k, 0, -k, 0], [0, 0, 1, 0]])
    P = ct.c2d(ct.ss(A, B, C, 0, inputs="i_m", outputs=["tau_k", "q_j"]), T, "zoh")
    zi = ct.tf([1.0], [1.0, 0.0], T)
    D1 = ct.c2d(ct.tf([float(g.Bq), 0.0], [1 / (2 * np.pi * 50), 1.0]), T, "tustin")
    D2 = ct.c2d(ct.tf([float(g.Btau), 0.0], [1 / (2 * np.pi * 100), 1.0]), T, "tustin")
    parts = [P, ct.ss(-(float(g.Kq) * zi**ns + D1), inputs="q_j", outputs="tau_des"),
             ct.ss(ct.tf([1.0], [1.0], T), inputs="tau_k", outputs="tau_meas"),
             ct.summing_junction(["tau_des", "-tau_meas"], "e", dt=T),
             ct.ss(float(g.Ktau) + D2, inputs="e", outputs="u_fb"),
             ct.ss(ct.tf([1 / a.beta], [1.0], T), inputs="tau_des", outputs="u_ff"),
             ct.summing_junction(["u_fb", "u_ff"], "i_m", dt=T)]
    cl = ct.interconnect(parts, inplist=["i_m"], outlist=["q_j"], check_unused=False)
    return np.sort(np.abs(ct.poles(cl)))[::-1]


@pytest.mark.parametrize("t_qs_ms, ns, unstable", [(9.5, 9, 0), (10.5, 10, 0), (11.5, 11, 2)])
def test_sea_loop_poles_match_python_control_near_the_boundary(t_qs_ms, ns, unstable):
    # Oracle: python-control's own discretization and interconnection of the SEA loop
    # (_python_control_sea_poles).  f_n = 30 Hz is stable in continuous time up to
    # T_qs = 10.52 ms; at 1 kHz the requested T_qs = T/2 + nT is realized exactly, and
    # 10.5 ms leaves the dominant pair 1.3e-4 inside the unit circle.
    from seactl.systems.sea.loops import SEA_DIAGRAM

    d = sc.design(30, delays_ms={"torque": 0.5, "stiffness": t_qs_ms, "damping": 0.5},
                  filters_hz=(50, 100))
    r = sampled_roots(SEA_DIAGRAM, d.sea, RATE)
    poles = _python_control_sea_poles(d, ns)
    ours = np.sort(np.abs(r.z))[::-1]
    np.testing.assert_allclose(ours[:poles.size], poles, atol=1e-8)
    assert np.all(ours[poles.size:] < 1e-8)
    assert int(r.unstable_modes) == int(np.sum(poles > 1)) == unstable


@pytest.mark.parametrize("t_qs_ms", [8.0, 12.0])
def test_multi_rate_verdict_matches_the_lifted_map_over_the_buffers(t_qs_ms):
    # Oracle: simulate.lifted_map, a second construction of the same loop's map (over a
    # multiple of the slow period covering every buffer, buffers as ring slots), whose
    # eigenvalues are those of the period map raised to the ratio of the periods.
    from seactl.simulate.discrete import compile_sampled
    from seactl.simulate.inputs import Step
    from seactl.simulate.period import lifted_map
    from seactl.systems.sea.loops import SEA_DIAGRAM

    d = sc.design(30, delays_ms={"torque": 0.5, "stiffness": t_qs_ms, "damping": 0.5},
                  filters_hz=(50, 100))
    rates = {"embedded": 1000.0, "high-level": 250.0}
    r = sampled_roots(SEA_DIAGRAM, d.sea, rates)
    plan = compile_sampled(SEA_DIAGRAM, d.sea, {"q_des": Step(1.0)}, 0.01, ("q_j",),
                           rates_hz=rates)
    M, period = lifted_map(plan)
    lam = np.sort(np.abs(np.linalg.eigvals(M[0])))[::-1]
    m = round(period / r.period_s)
    np.testing.assert_allclose(lam[:6], np.abs(r.z[:6]) ** m, rtol=1e-7)
    assert int(r.unstable_modes) == int(np.sum(lam > 1)) == (0 if t_qs_ms < 10 else 2)


def test_sampled_jitter_margin_tends_to_kao_lincoln():
    # Oracle: the continuous Kao-Lincoln jitter margin of the same outer loop
    # (seactl.latency.jitter,
    # its peak proven); the sampled bound T / max |e^{jwT} - 1| |T(e^{jwT})| tends to it as
    # the rate grows (|e^{jwT} - 1| / T -> w, effective delays -> requested ones).
    d = sc.design([12, 16, 20], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
    cont = d.jitter_margins().jitter_margin_s * 1e3
    s = d.margins(rate_hz=10_000)
    np.testing.assert_allclose(s.jitter_margin_ms, cont, rtol=5e-3)
    assert np.all(s.jitter_margin_samples == np.ceil(s.jitter_margin_ms * 10 - 1e-9) - 1)


def test_loop_file_sampled_step_carries_the_certified_verdict(capsys):
    # Oracle: the loop's own sampled margins (UserLoop.margins at the file's rates) and its
    # continuous certified count, one design each side of the stability boundary.
    path = Path(__file__).resolve().parents[1] / "examples" / "loops" / "paper-sea.toml"
    out = json.loads(cli_run(["step", "--loop", str(path), "--mode", "sampled", "--set",
                              "T_high=2,30", "--json"], capsys).stdout)
    loop = sc.load_loop(path).with_values(T_high=[2.0, 30.0])
    expected = np.ravel(loop.margins(rate_hz={})["outer"].verdict).tolist()
    got = [r["sampled_loop"]["verdict"] for r in out["runs"]]
    assert got == expected == ["stable", "unstable"]
    assert [r["sampled_loop"]["continuous_stable"] for r in out["runs"]] == [True, False]
