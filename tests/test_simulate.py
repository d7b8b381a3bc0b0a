"""Time-domain simulation against independent routes: the paper's printed P_CL
coefficients (scipy), the block diagram's frequency response, python-control on a
separately built loop, and the Nyquist criterion."""

from __future__ import annotations

import json
from types import SimpleNamespace

import control as ct
import numpy as np
import pytest
from scipy import signal

import seactl as sc
from seactl.apps.cli import main
from seactl.base import limits
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.errors import InputError
from seactl.simulate.engine import simulate
from seactl.simulate.inputs import Friction, Sine, Step
from seactl.simulate.metrics import impulse_metrics, step_metrics
from seactl.simulate.realize import realize_tustin
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import (
    SEA_DIAGRAM,
    SEA_DIAGRAM_NO_ZERO,
    SEADesign,
    Timing,
    closed_loop,
)
from seactl.systems.sea.views import sea_impulse, sea_margins, sea_step

G14 = critically_damped_gains(UT_SEA, 14.0)


def paper_pcl(a, g, Tv, Tt, zero=True):
    """P_CL (eq. closedloop, no delays) as polynomials, multiplied through by the filters'
    denominators (Tv s + 1)(Tt s + 1): an independent route to the rational transfer."""
    P = np.polynomial.polynomial
    u = 1 + a.beta * g.Kt
    fv, ft = [1.0, Tv], [1.0, Tt]        # ascending powers
    fvt = P.polymul(fv, ft)
    base = [u * g.Kq, a.bj * u + a.bm, a.Ij * u + a.Im + a.bj * a.bm / a.k,
            (a.Ij * a.bm + a.Im * a.bj) / a.k, a.Im * a.Ij / a.k]
    den = P.polymul(fvt, base)
    den = P.polyadd(den, P.polymul(fv, [0, a.beta * g.Bt * g.Kq, a.bj * a.beta * g.Bt,
                                        a.Ij * a.beta * g.Bt]))
    den = P.polyadd(den, [0, 0, a.beta * g.Bt * g.Bq])
    den = P.polyadd(den, P.polymul(ft, [0, u * g.Bq]))
    num = P.polymul(fv, [g.Kq * u, g.Kq * (u * Tt + a.beta * g.Bt)] if zero else
                    P.polymul([g.Kq * u], ft))
    return num[::-1], den[::-1]


def gains(g):
    return SimpleNamespace(Kq=float(g.Kq), Bq=float(g.Bq), Kt=float(g.Ktau), Bt=float(g.Btau))


@pytest.mark.parametrize("zero", [True, False])
def test_delay_free_step_equals_rational_transfer(zero):
    # Oracle: scipy.signal.step of paper_pcl, the printed P_CL multiplied out as
    # polynomials.
    d = SEADesign(UT_SEA, G14, Timing(f_qd=50.0, f_taud=100.0))
    r = sea_step(d, zero=zero, t_end_s=0.3)
    num, den = paper_pcl(UT_SEA, gains(G14), float(d.Tf_qd), float(d.Tf_taud), zero)
    _, y = signal.step(signal.lti(num, den), T=r.t_s)
    assert np.max(np.abs(r.position - y)) < 1e-6
    assert r.result.stable


def test_unfiltered_step_close_to_rational_transfer():
    # Oracle: scipy.signal.step of paper_pcl without filters.
    # unfiltered derivatives are realized with a 1e-7 s roll-off
    d = SEADesign(UT_SEA, G14)
    r = sea_step(d, t_end_s=0.2)
    num, den = paper_pcl(UT_SEA, gains(G14), 0.0, 0.0)
    _, y = signal.step(signal.lti(num, den), T=r.t_s)
    assert np.max(np.abs(r.position - y)) < 1e-4


@pytest.mark.parametrize("zero", [True, False])
def test_delayed_sinusoid_matches_closed_loop_frequency_response(zero):
    # Oracle: the closed loop's exact-delay frequency response at the drive frequency (time
    # domain vs frequency domain; the diagram is checked against the printed P_CL in
    # test_loops.py).
    # designs (2 timings) x (3 frequencies), one batch; steady state fitted over 2 periods
    timing = Timing.from_ms(np.array([[1.0], [0.5]]), np.array([[1.0], [2.0]]),
                            np.array([[1.0], [0.5]]), 50.0, 100.0)
    d = SEADesign(UT_SEA, G14, timing)
    f = np.array([[8.0, 20.0, 60.0]]) * np.ones((2, 1))
    shape = (2, 3)
    D = SimpleNamespace(shape=shape, **{k: getattr(d, k) * np.ones(shape) for k in
                                        ("Im", "Ij", "bm", "bj", "k", "beta", "Kq", "Bq",
                                         "Ktau", "Btau", "T_tau", "T_qs", "T_qd", "Tf_qd",
                                         "Tf_taud")})
    t_end = 0.8
    res = simulate(SEA_DIAGRAM if zero else SEA_DIAGRAM_NO_ZERO, D,
                   {"q_des": lambda t: np.sin(2 * np.pi * f[..., None] * t)}, t_end,
                   outputs=("q_j",))
    t, y = res.t_s, res.outputs["q_j"]
    G = closed_loop(zero)(D, 1j * 2 * np.pi * f[..., None])[..., 0]
    for i in range(2):
        for j in range(3):
            keep = t >= t_end - 2 / f[i, j] - 1e-12
            A = np.stack([np.sin(2 * np.pi * f[i, j] * t[keep]),
                          np.cos(2 * np.pi * f[i, j] * t[keep])], axis=1)
            a, b = np.linalg.lstsq(A, y[i, j, keep], rcond=None)[0]
            assert abs((a + 1j * b) - G[i, j]) < 1e-3 * abs(G[i, j]), (i, j)


def independent_pade_loop(g, T_s, order=5):
    """The SEA loop built with python-control blocks, each delay a Pade(order)."""
    a = UT_SEA
    A = np.array([[0, 1, 0, 0], [-a.k / a.Im, -a.bm / a.Im, a.k / a.Im, 0], [0, 0, 0, 1],
                  [a.k / a.Ij, 0, -a.k / a.Ij, -a.bj / a.Ij]])
    B = np.array([[0, 0], [a.beta / a.Im, 0], [0, 0], [0, 1 / a.Ij]])
    C = np.array([[0, 0, 1, 0], [a.k, 0, -a.k, 0]])
    plant = ct.ss(A, B, C, 0, inputs=["i_m", "tau_ext"], outputs=["q_j", "tau_k"])
    wv, wt = 2 * np.pi * 50, 2 * np.pi * 100

    def delay(inp, out):
        if T_s == 0:
            return ct.ss([], [], [], [[1.0]], inputs=inp, outputs=out)
        return ct.ss(ct.tf(*ct.pade(T_s, order)), inputs=inp, outputs=out)

    Kq, Bq, Kt, Bt = (float(x) for x in (g.Kq, g.Bq, g.Ktau, g.Btau))
    blocks = [plant, delay("q_j", "q_s"), delay("q_j", "q_d"), delay("tau_k", "tau_meas"),
              ct.ss(ct.tf([-Bq * wv, 0], [1, wv]), inputs="q_d", outputs="fb_d"),
              ct.ss(ct.tf([-Kq], [1]), inputs="q_s", outputs="fb_s"),
              ct.ss(ct.tf([Kq], [1]), inputs="q_des", outputs="ref"),
              ct.summing_junction(inputs=["ref", "fb_s", "fb_d"], output="tau_des"),
              ct.summing_junction(inputs=["tau_des", "-tau_meas"], output="e"),
              ct.ss(ct.tf([Bt * wt + Kt, Kt * wt], [1, wt]), inputs="e", outputs="ipd"),
              ct.ss(ct.tf([1 / a.beta], [1]), inputs="tau_des", outputs="iff"),
              ct.summing_junction(inputs=["ipd", "iff"], output="i_m")]
    return ct.interconnect(blocks, inplist=["q_des", "tau_ext"], outlist=["q_j"])


def test_delayed_step_close_to_pade_loop_and_not_open_loop():
    # Oracle: python-control on independent_pade_loop, built block by block with Pade(5)
    # delays.
    d = SEADesign(UT_SEA, G14, Timing.from_ms(1, 1, 1, 50, 100))
    r = sea_step(d, t_end_s=0.3)
    sys = independent_pade_loop(G14, 1e-3)
    y = ct.forced_response(sys[0, 0], r.t_s, np.ones_like(r.t_s)).outputs
    err = np.max(np.abs(r.position - y))
    assert err < 3e-4  # what remains is Pade(5)'s own error (ours is converged in dt:)
    r2 = sea_step(d, t_end_s=0.3, dt=2.5e-5, record_dt=1e-4)
    assert np.max(np.abs(r2.position - r.position)) < 2e-5
    # a delay error (e.g. 1 ms vs 2 ms) would be visible at this tolerance
    y2 = ct.forced_response(independent_pade_loop(G14, 2e-3)[0, 0], r.t_s,
                            np.ones_like(r.t_s)).outputs
    assert np.max(np.abs(r.position - y2)) > 100 * err


def test_impulse_matches_python_control():
    # Oracle: python-control's impulse response of independent_pade_loop without delays.
    d = SEADesign(UT_SEA, G14, Timing(f_qd=50.0, f_taud=100.0))
    r = sea_impulse(d, impulse_nms=0.1, t_end_s=0.3)
    full = independent_pade_loop(G14, 0.0)
    y = ct.impulse_response(full[0, 1], r.t_s).outputs * 0.1
    assert np.max(np.abs(r.position - y)) < 1e-6 * np.max(np.abs(y)) + 1e-9


def test_sampled_converges_to_continuous_with_effective_delay():
    # Oracle: the continuous simulation with the effective delay T_s/2 + n T_s; the error
    # must shrink with the rate.
    # design delay 1.5 ms = T_s/2 + n T_s exactly at these rates (n = 1, 2, 4)
    d = SEADesign(UT_SEA, G14, Timing.from_ms(1.5, 1.5, 1.5, 50, 100))
    rc = sea_step(d, t_end_s=0.25)
    errs = []
    for rate in (1000.0, 5000.0 / 3, 3000.0):
        r = sea_step(d, t_end_s=0.25, mode="sampled", rate_hz=rate, saturation_a=np.inf)
        assert np.allclose(r.result.info["effective_delays_s"]["Kq_fb"], 1.5e-3)
        errs.append(np.max(np.abs(r.position - np.interp(r.t_s, rc.t_s, rc.position))))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-4


def test_sampled_buffers_never_shorten_a_delay():
    # Oracle: n = ceil((T - T_s/2)/T_s), effective T_s/2 + n T_s, worked by hand in the
    # comments; the effective delay is the shortest realizable one >= T.
    d = SEADesign(UT_SEA, G14, Timing.from_ms(0.5, 2.0, 1.0, 50, 100))
    r = sea_step(d, t_end_s=0.05, mode="sampled")
    eff = r.result.info["effective_delays_s"]
    assert eff["tau_delay"] == pytest.approx(0.5e-3)   # (0.5 - 0.5)/1 = 0 -> 0: exact
    assert eff["Kq_fb"] == pytest.approx(2.5e-3)       # (2 - 0.5)/1 = 1.5 -> 2
    assert eff["Bq_fb"] == pytest.approx(1.5e-3)       # (1 - 0.5)/1 = 0.5 -> 1
    d = SEADesign(UT_SEA, G14, Timing.from_ms(1.0, 2.2, 1.5, 50, 100))
    r = sea_step(d, t_end_s=0.01, mode="sampled", rate_hz=500.0)   # T_s = 2 ms
    eff = r.result.info["effective_delays_s"]
    assert eff["tau_delay"] == pytest.approx(1e-3)     # (1 - 1)/2 = 0 -> 0: exact
    assert eff["Kq_fb"] == pytest.approx(3e-3)         # (2.2 - 1)/2 = 0.6 -> 1
    assert eff["Bq_fb"] == pytest.approx(3e-3)         # (1.5 - 1)/2 = 0.25 -> 1


def test_saturation_limits_current():
    # Oracle: the limit given, the unsaturated run (saturation must slow the rise) and
    # P_CL(0) = 1.
    d = SEADesign(UT_SEA, G14, Timing.from_ms(0.5, 0.5, 0.5, 50, 100))
    free = sea_step(d, t_end_s=0.3, mode="sampled", saturation_a=np.inf, amplitude=0.1)
    lim = sea_step(d, t_end_s=0.3, mode="sampled", saturation_a=5.0, amplitude=0.1)
    assert np.max(np.abs(free.current)) > 20
    assert np.max(np.abs(lim.current)) <= 5.0 + 1e-12
    assert lim.result.info["peak_actuation"]["i_m"] <= 5.0 + 1e-12
    assert lim.metrics.rise_time_s > 1.5 * free.metrics.rise_time_s
    assert lim.result.stable and abs(lim.metrics.steady_state_error) < 1e-3


def test_unstable_designs_reported_like_nyquist():
    # Oracle: the Nyquist verdicts of sea_margins.
    timing = Timing.from_ms(1.0, 1.0, np.array([1.0, 5.0, 8.0, 12.0]), 50, 100)
    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 20.0), timing)
    ny = sea_margins(d).stable
    assert ny.tolist() == [True, True, False, False]
    r = sea_step(d, t_end_s=1.0)
    assert r.result.stable.tolist() == ny.tolist()
    assert np.all(np.isfinite(r.position))
    assert np.isnan(r.metrics.overshoot_pct[~ny]).all()
    # a violently unstable one leaves the bounds, with the time it did
    d2 = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 20.0, gs=4.0),
                   Timing.from_ms(3.0, 1.0, 1.0, 50, 100))
    r2 = sea_step(d2, t_end_s=1.0)
    assert not r2.result.stable
    assert 0 < r2.result.left_bounds_s < 1.0
    assert np.all(np.isfinite(r2.position))


def test_tustin_block_matches_scipy():
    # Oracle: scipy.signal.cont2discrete (bilinear) and the Tustin substitution by hand.
    b = Block("f", "u", "y", num=lambda p: (p.B, 0.0), den=lambda p: (p.T, 1.0))
    p = SimpleNamespace(B=np.array([2.0, 3.0]), T=np.array([0.003, 0.0]))
    A, Bm, C, D = realize_tustin(b, p, (2,), 2, 1e-3)
    z = np.exp(1j * np.array([0.1, 1.0, 2.5]))
    ref0 = signal.cont2discrete(([p.B[0], 0.0], [p.T[0], 1.0]), 1e-3, method="bilinear")
    refs = [np.polyval(np.ravel(ref0[0]), z) / np.polyval(np.ravel(ref0[1]), z),
            p.B[1] * 2e3 * (z - 1) / (z + 1)]  # unfiltered: s -> (2/T)(z-1)/(z+1) by hand
    for i in range(2):
        for zk, want in zip(z, refs[i]):
            ours = C[i] @ np.linalg.solve(zk * np.eye(A.shape[1]) - A[i], Bm[i]) + D[i]
            assert abs(ours - want) < 1e-9 * max(1.0, abs(want))


def test_multirate_and_friction_and_quantization():
    # Oracle: the single-rate run for equal rates; the effective delay worked by hand; a
    # larger b_m for viscous friction; the static Coulomb band; whole encoder counts.
    d = SEADesign(UT_SEA, G14, Timing.from_ms(0.5, 2.0, 0.5, 50, 100))
    from seactl.systems.sea.loops import SEA_DIAGRAM as D

    base = simulate(D, d, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j",),
                    rates_hz={"embedded": 1000.0, "high-level": 1000.0})
    same = simulate(D, d, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j",),
                    rates_hz=1000.0)
    assert np.array_equal(base.outputs["q_j"], same.outputs["q_j"])
    slow = simulate(D, d, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j",),
                    rates_hz={"embedded": 1000.0, "high-level": 250.0})
    assert slow.info["effective_delays_s"]["Kq_fb"] == pytest.approx(2e-3)
    assert slow.stable and not np.allclose(slow.outputs["q_j"], base.outputs["q_j"])
    with pytest.raises(InputError):
        simulate(D, d, {"q_des": Step()}, 0.1, mode="sampled", rates_hz={"embedded": 1000.0,
                                                                          "high-level": 300.0})
    # viscous friction on the motor equals a larger motor damping b_m
    c = 0.5
    fr = simulate(D, d, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j",),
                  rates_hz=1000.0, friction=Friction("tau_net_m", "q_m", viscous=c),
                  friction_substeps=20)
    from dataclasses import replace

    d2 = SEADesign(replace(UT_SEA, motor_damping=UT_SEA.motor_damping + c), G14, d.timing)
    ref = simulate(D, d2, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j",),
                   rates_hz=1000.0)
    assert np.max(np.abs(fr.outputs["q_j"] - ref.outputs["q_j"])) < 2e-3 * 0.01
    # Coulomb friction on the motor makes it stall short of the target, inside the band
    # where the static motor torque Kq e (1 + beta Ktau) is below the Coulomb level
    fc = 10.0
    cf = simulate(D, d, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j",),
                  rates_hz=1000.0, friction=Friction("tau_net_m", "q_m", coulomb=fc))
    err = 0.01 - cf.outputs["q_j"][-1]
    assert 1e-5 < abs(err) <= fc / (float(G14.Kq) * (1 + UT_SEA.beta * float(G14.Ktau)))
    # quantization: the sampled joint angle is a whole number of encoder counts
    q = 2 * np.pi / 4096
    qz = simulate(D, d, {"q_des": Step(0.01)}, 0.3, mode="sampled", outputs=("q_j", "q_sens"),
                  rates_hz=1000.0, quantization={"q_j": q})
    k = qz.outputs["q_sens"] / q
    assert np.allclose(k, np.round(k))


def test_metrics_on_known_responses():
    # Oracle: analytic responses: overshoot exp(-pi z/sqrt(1-z^2)), settling near 4/(z w_n),
    # the peak of e^-t - e^-2t at ln 2 (0.25).
    t = np.linspace(0, 3, 30001)
    wn, z = 10.0, 0.5
    y = 1 - np.exp(-z * wn * t) * (np.cos(wn * np.sqrt(1 - z**2) * t)
                                    + z / np.sqrt(1 - z**2) * np.sin(wn * np.sqrt(1 - z**2) * t))
    m = step_metrics(t, y)
    assert m.overshoot_pct == pytest.approx(100 * np.exp(-np.pi * z / np.sqrt(1 - z**2)), rel=1e-4)
    # second-order 2 % settling: last exit of the envelope-bounded response, within the
    # classical 4/(z wn) estimate
    assert 0.5 * 4 / (z * wn) < m.settling_time_s < 1.2 * 4 / (z * wn)
    im = impulse_metrics(t, np.exp(-t) - np.exp(-2 * t), band=0.05)
    assert im.peak_time_s == pytest.approx(np.log(2), abs=1e-4)
    assert im.peak_deviation == pytest.approx(0.25, abs=1e-8)


def _metrics_by_hand(t, y, band=0.02):
    """One response at a time, as the definitions read (the oracle of the compiled pass)."""
    fin = float(np.mean(y[-max(1, y.size // 50):]))
    r = y / fin if fin != 0 else np.full(y.size, np.nan)

    def reach(level):
        for k in range(y.size):
            if r[k] >= level:
                return t[0] if k == 0 else np.interp(level, [r[k - 1], r[k]], [t[k - 1], t[k]])
        return np.inf

    out = [i for i in range(y.size) if abs(y[i] - fin) > band * abs(fin)]
    settle = t[0] if not out else (np.inf if out[-1] == y.size - 1 else t[out[-1] + 1])
    over = np.nan if np.isnan(r).any() else max(np.max(r) - 1, 0) * 100
    return reach(0.9) - reach(0.1), over, settle, 1 - fin, fin


def test_compiled_step_metrics_equal_the_definitions():
    """Hard responses (negative and tiny final values, noise that crosses the levels many
    times, a NaN tail, still outside the band at the end, a time-major batch view as the
    simulator returns it) against a per-response evaluation of the definitions."""
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 801)
    ys = [1 - np.exp(-40 * t), -3 * (1 - np.exp(-9 * t) * np.cos(60 * t)),
          1e-9 * (1 - np.exp(-20 * t)) + rng.normal(0, 2e-11, t.size),
          np.clip(1 - np.exp(-30 * t), 0, 1) + rng.normal(0, 0.05, t.size),
          1 - np.exp(-2 * t), np.where(t < 0.6, 1 - np.exp(-30 * t), np.nan)]
    batch = np.ascontiguousarray(np.array(ys).T).T  # time-major storage
    m = step_metrics(t, batch)
    for i, y in enumerate(ys):
        ref = _metrics_by_hand(t, y)
        got = (m.rise_time_s[i], m.overshoot_pct[i], m.settling_time_s[i],
               m.steady_state_error[i], m.final_value[i])
        np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12, equal_nan=True)


def test_bad_input():
    # Oracle: the error contract (InputError naming the parameter).
    d = SEADesign(UT_SEA, G14)
    with pytest.raises(InputError, match="mode"):
        sea_step(d, mode="fast")
    with pytest.raises(InputError, match="t_end"):
        sea_step(d, t_end_s=-1)
    with pytest.raises(InputError, match="inputs"):
        simulate(SEA_DIAGRAM, d, {"nope": Step()}, 0.1)
    with pytest.raises(InputError, match="saturation"):
        sea_step(d, saturation_a=5.0)


def test_generic_diagram_sine():
    """Integrator K/s with a 20 ms delay in the feedback, simulated with a 2 Hz sine.
    Oracle: the closed loop solved by hand, G = K / (s + K e^{-sT}), not the diagram's own
    transfer."""
    d = BlockDiagram("lag", [
        Block("ref", "r", "e"), Block("fb", "y", "e", num=lambda p: (-1.0,), delay="T"),
        Block("ctrl", "e", "u", num=lambda p: (p.K,)),
        Block("plant", "u", "y", den=lambda p: (1.0, 0.0), role="plant")])
    p = SimpleNamespace(K=np.array(10.0), T=np.array(0.02), shape=())
    res = simulate(d, p, {"r": Sine(1.0, 2.0)}, 3.0, outputs=("y",), dt=1e-3)
    t, y = res.t_s, res.outputs["y"]
    keep = t >= 2.0
    A = np.stack([np.sin(4 * np.pi * t[keep]), np.cos(4 * np.pi * t[keep])], axis=1)
    a, b = np.linalg.lstsq(A, y[keep], rcond=None)[0]
    s = 1j * 4 * np.pi
    G = 10.0 / (s + 10.0 * np.exp(-s * 0.02))
    assert abs(a + 1j * b - G) < 1e-3 * abs(G)


def test_cli_step_and_impulse(tmp_path, capsys):
    # Oracle: P_CL(0) = 1 (final value), 301 samples for 0.3 s at 1 kHz, the CLI error
    # contract.  The delays are realizable at 1 kHz (T_s/2 + n T_s): sampled = requested.
    png, csvf = tmp_path / "s.png", tmp_path / "s.csv"
    assert main(["step", "--fn", "14", "--t-tau", "0.5", "--t-qs", "1.5", "--t-qd", "0.5", "--f-qd",
                 "50", "--f-taud", "100", "--gs", "2", "--mode", "sampled", "--t-end", "0.3",
                 "--plot", str(png), "--csv", str(csvf), "--json", "--full"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["mode"] == "sampled" and out["stable"] is True
    assert len(out["t_s"]) == len(out["position"]) == 301
    out_full = out
    assert abs(out["position"][-1] - 1) < 1e-2
    assert out["metrics"]["overshoot_pct"] > 10
    assert png.stat().st_size > 1000 and csvf.read_text().startswith("t_s,")
    assert main(["step", "--fn", "14", "16", "--json", "--t-end", "0.2"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["runs"]) == 2 and out["mode"] == "continuous"
    # without --full a summary: the time series' lengths, not the series (oracle: the
    # same command with --full, and the run above: one sample per ms for 0.3 s)
    assert main(["step", "--fn", "14", "--t-tau", "0.5", "--t-qs", "1.5", "--t-qd", "0.5",
                 "--f-qd", "50", "--f-taud", "100", "--gs", "2", "--mode", "sampled",
                 "--t-end", "0.3", "--json"]) == 0
    short = json.loads(capsys.readouterr().out)
    assert short["omitted"] == {"t_s": 301, "position": 301}
    assert "t_s" not in short and "position" not in short
    assert {k: v for k, v in out_full.items() if k not in ("t_s", "position")} \
        == {k: v for k, v in short.items() if k != "omitted"}
    assert main(["step", "--fn", "14", "16", "--json", "--t-end", "0.2"]) == 0
    many = json.loads(capsys.readouterr().out)
    n = round(0.2 / limits.RECORD_DT_S) + 1   # continuous mode: one sample per RECORD_DT_S
    assert [r["omitted"] for r in many["runs"]] == [{"position": n}] * 2
    assert many["omitted"] == {"t_s": n}
    assert main(["impulse", "--fn", "14", "--json", "--t-end", "0.5"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["metrics"]["peak_deviation_rad"] > 0 and out["metrics"]["recovery_time_s"] < 0.3
    assert main(["step", "--saturation", "5"]) == 2
    assert main(["step", "--mode", "sampled", "--saturation", "-1"]) == 2
    assert main(["step", "--t-end", "0"]) == 2


def test_expm_batched_matches_scipy():
    # Oracle: scipy.linalg.expm.
    from scipy.linalg import expm

    from seactl.simulate.network import expm_batched

    rng = np.random.default_rng(0)
    A = rng.normal(size=(50, 7, 7)) * np.logspace(-3, 2.5, 50)[:, None, None]
    A[0] = 0.0
    E = expm_batched(A)
    for i in range(50):
        ref = expm(A[i])
        assert np.max(np.abs(E[i] - ref)) <= 1e-10 * max(1.0, np.max(np.abs(ref)))


def _augmented_matrices(monkeypatch, design, **kw):
    """The matrices the continuous simulation of ``design`` exponentiates."""
    from seactl.simulate import network as sim_network

    seen, expm = [], sim_network.expm_batched
    monkeypatch.setattr(sim_network, "expm_batched", lambda M: (seen.append(M.copy()), expm(M))[1])
    sea_step(design, t_end_s=0.01, **kw)
    return seen[0][0]


@pytest.mark.parametrize("gs, ms", [(1.0, (0.5, 2.0, 0.5, 50.0, 100.0)),  # Table I
                                    (3.0, (0.1, 0.1, 0.1, 2000.0, 5000.0)),
                                    (0.5, (0.0, 3.0, 0.0, 20.0, 1000.0))])
def test_expm_batched_is_accurate_entry_by_entry_on_a_loops_matrices(monkeypatch, gs, ms):
    """A loop's augmented matrices span many decades (fast filters next to a slow
    mechanism): plain scaling and squaring lost the small entries entirely (relative
    errors up to 5e10 on Table I).  Oracle: mpmath's expm at 50 digits."""
    import mpmath

    from seactl.simulate.network import expm_batched

    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 14.0, gs=gs), Timing.from_ms(*ms))
    M = _augmented_matrices(monkeypatch, d)
    with mpmath.workdps(50):
        ref = np.array(mpmath.expm(mpmath.matrix(M.tolist())).tolist(), dtype=float)
    E = expm_batched(M[None])[0]
    nz = ref != 0
    assert np.max(np.abs(E[~nz]), initial=0.0) <= 1e-15 * np.max(np.abs(ref))
    assert np.max(np.abs(E[nz] - ref[nz]) / np.abs(ref[nz])) < 1e-12


def test_a_batch_split_over_threads_is_the_one_thread_result(monkeypatch):
    """Large batches run the compiled kernel in one thread per core on contiguous parts
    of the batch.  Oracle: the same batch in one thread, bit for bit (each design's
    arithmetic is independent of the others), on 240 designs of which the long-delay
    ones leave the bounds at different times (the record then held)."""
    from seactl.base import parallel as _parallel

    rng = np.random.default_rng(5)
    fn = rng.uniform(10.0, 30.0, 240)
    t_tau = np.where(np.arange(240) % 3 == 0, 5.0, 0.5)  # a third unstable
    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, fn),
                  Timing.from_ms(t_tau, 5.0, 0.5, 50.0, 100.0))
    monkeypatch.setattr(_parallel, "THREADS", 1)
    one = sea_step(d, t_end_s=0.4)
    monkeypatch.setattr(_parallel, "THREADS", 3)
    parts = sea_step(d, t_end_s=0.4)
    one, parts = one.result, parts.result
    assert np.isfinite(one.left_bounds_s).sum() > 20 and np.isinf(one.left_bounds_s).sum() > 100
    np.testing.assert_array_equal(parts.outputs["q_j"], one.outputs["q_j"])
    np.testing.assert_array_equal(parts.left_bounds_s, one.left_bounds_s)
    np.testing.assert_array_equal(parts.stable, one.stable)


@pytest.mark.parametrize("mode", ["continuous", "sampled"])
def test_a_simulation_larger_than_the_machine_is_refused_up_front(mode, monkeypatch):
    # Oracle: limits.simulation_estimate against a machine given 1 GiB: 400 designs over
    # 0.5 s at a 0.01 ms step (or a 100 kHz servo rate) need about 4 GB, so the library
    # call (not only the command line) is refused before it allocates, naming the step.
    import time

    from seactl.base import limits
    from seactl.errors import ResourceError

    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 2.0**30)
    n = 400
    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, np.linspace(15, 40, n)),
                  Timing.from_ms(0.5, 2.0, 0.01))
    start = time.perf_counter()
    with pytest.raises(ResourceError, match="simulating 400 design") as err:
        sea_step(d, t_end_s=0.5, mode=mode, rate_hz=1e5)
    assert time.perf_counter() - start < 5.0
    assert "50,000 steps" in str(err.value)


def test_buffer_samples_is_the_shortest_realizable_delay_not_below_the_request():
    # Oracle: the definition, by enumeration: of the realizable delays T_s/2 + n T_s
    # (n = 0, 1, ...), the smallest one >= T.
    from seactl.simulate.discrete import buffer_samples

    rng = np.random.default_rng(3)
    for Ts in (1e-3, 2e-3, 1 / 1500, 1 / 27.5):
        T = np.concatenate([rng.uniform(0, 20 * Ts, 400), Ts / 2 + np.arange(12) * Ts])
        n = buffer_samples(T, Ts)
        realizable = Ts / 2 + np.arange(40) * Ts
        ref = np.array([np.nonzero(realizable >= t - 1e-9 * Ts)[0][0] for t in T])
        assert np.array_equal(n, ref)
        assert np.all(Ts / 2 + n * Ts >= T - 1e-12)


def test_requested_and_effective_delays_side_by_side(capsys):
    # Oracle: n = ceil((T - T_s/2)/T_s) by hand: at 1 kHz 1 -> 1.5, 2.2 -> 2.5, 0.5 -> 0.5 ms;
    # continuous mode runs the requested delays exactly.
    d = sc.design(14, delays_ms={"torque": 1.0, "stiffness": 2.2, "damping": 0.5},
                  filters_hz=(50, 100))
    r = d.step(mode="sampled", t_end_s=0.05)
    req = {k: float(v) * 1e3 for k, v in r.requested_delays_s.items()}
    eff = {k: float(v) * 1e3 for k, v in r.effective_delays_s.items()}
    assert req == pytest.approx({"torque": 1.0, "stiffness": 2.2, "damping": 0.5})
    assert eff == pytest.approx({"torque": 1.5, "stiffness": 2.5, "damping": 0.5})
    assert r.to_dict()["effective_delays_ms"]["stiffness"] == pytest.approx(2.5)
    c = d.step(t_end_s=0.05)
    assert {k: float(v) for k, v in c.effective_delays_s.items()} == \
        pytest.approx({k: float(v) for k, v in c.requested_delays_s.items()})
    assert main(["step", "--fn", "14", "--t-tau", "1", "--t-qs", "2.2", "--t-qd", "0.5",
                 "--f-qd", "50", "--f-taud", "100", "--mode", "sampled", "--t-end", "0.05",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["requested_delays_ms"] == pytest.approx(req)
    assert out["effective_delays_ms"] == pytest.approx(eff)
    assert any("torque 1 -> 1.5" in w and "stiffness 2.2 -> 2.5" in w for w in out["warnings"])
    assert main(["step", "--fn", "14", "--t-tau", "1", "--t-qs", "2.2", "--t-qd", "0.5",
                 "--mode", "sampled", "--t-end", "0.05"]) == 0
    text = capsys.readouterr().out
    assert "requested -> simulated at 1000 Hz" in text and "damping 0.5 -> 0.5" in text
