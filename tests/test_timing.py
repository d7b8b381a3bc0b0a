"""Sampled simulation with random latency and loss against independent facts: a scalar
Python re-implementation of hold-last-value on a one-state loop, brute-force arrival
schedules, the deterministic sampled mode (constant latency, one-bin histogram, zero
loss), the Gilbert-Elliott chain's stationary loss rate, and the jitter margins
(Kao-Lincoln: inside them every run must stay stable)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.errors import InputError
from seactl.latency.montecarlo import (
    Bernoulli,
    Constant,
    Empirical,
    GilbertElliott,
    ShiftedExponential,
    Uniform,
    arrival_schedule,
    parse_latency,
    parse_loss,
    sea_monte_carlo,
)
from seactl.simulate.engine import simulate
from seactl.simulate.inputs import Step
from seactl.systems.sea.views import sea_step

TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))


def _brute_schedule(wait, lost):
    T, N = wait.shape
    out = np.full((T, N), -1)
    for c in range(N):
        for j in range(T):
            arrived = [k for k in range(j + 1) if k + wait[k, c] <= j and not lost[k, c]]
            out[j, c] = max(arrived) if arrived else -1
    return out


def test_arrival_schedule_matches_brute_force():
    rng = np.random.default_rng(5)
    wait = rng.integers(0, 6, (60, 4))
    lost = rng.random((60, 4)) < 0.3
    np.testing.assert_array_equal(arrival_schedule(wait, lost), _brute_schedule(wait, lost))


class _Given:
    """A timing object handing simulate() a fixed schedule for block 'fb'."""

    blocks = ["fb"]

    def __init__(self, sched):
        self.sched = sched

    def schedules(self, plan):
        return {"fb": self.sched}


def test_hold_last_value_against_scalar_loop():
    # y' = u, u = K (r - y_used): exact ZOH step y+ = y + Ts u; y_used = y at the source tick
    # of the newest arrived message (held; 0 before the first).  Oracle: a Python loop.
    d = BlockDiagram("int", [
        Block("ref", "r", "e"), Block("fb", "y", "e", num=lambda p: (-1.0,), delay="T",
                                      process="embedded"),
        Block("ctrl", "e", "u", num=lambda p: (p.K,)),
        Block("plant", "u", "y", den=lambda p: (1.0, 0.0), role="plant")])
    p = SimpleNamespace(K=np.array([40.0, 120.0]), T=np.array([2e-3, 2e-3]), shape=(2,))
    rng = np.random.default_rng(2)
    T_steps = 301
    wait = rng.integers(0, 5, (T_steps, 2))
    lost = rng.random((T_steps, 2)) < 0.25
    sched = arrival_schedule(wait, lost)
    res = simulate(d, p, {"r": Step()}, 0.3, mode="sampled", outputs=("y",), rates_hz=1000.0,
                   timing=_Given(sched))
    Ts = 1e-3
    for c in range(2):
        y = np.zeros(T_steps)
        for k in range(T_steps - 1):
            used = y[sched[k, c]] if sched[k, c] >= 0 else 0.0
            y[k + 1] = y[k] + Ts * p.K[c] * (1.0 - used)
        np.testing.assert_allclose(res.outputs["y"][c], y, rtol=0, atol=1e-12)


def test_deterministic_latency_equals_fixed_delay_sampled_run():
    d5 = sc.design([14, 18], delays_ms={"torque": 0.5, "stiffness": 5, "damping": 0.5},
                   filters_hz=(50, 100))
    d2 = sc.design([14, 18], **TABLE_I)
    ref = sea_step(d2.sea, mode="sampled", amplitude=0.01)
    for model in (Constant(2e-3), Empirical((2e-3,), (7.0,))):
        mc = sea_monte_carlo(d5.sea, latency={"stiffness": model}, runs=2, amplitude=0.01)
        q = mc.result.outputs["q_j"] / 0.01
        assert np.array_equal(q, np.broadcast_to(ref.position, q.shape))
    # random latency that always rounds up to the same whole samples (2.5 ms at 1 kHz) goes
    # through the arrival schedules and must still equal the fixed 2.5 ms run bit for bit
    d15 = sc.design([14, 18], delays_ms={"torque": 0.5, "stiffness": 2.5, "damping": 0.5},
                    filters_hz=(50, 100))
    ref15 = sea_step(d15.sea, mode="sampled", amplitude=0.01)
    mc = sea_monte_carlo(d2.sea, latency={"stiffness": Uniform(1.55e-3, 1.95e-3)}, runs=3,
                         amplitude=0.01)
    q = mc.result.outputs["q_j"] / 0.01
    assert np.array_equal(q, np.broadcast_to(ref15.position, q.shape))
    # a zero-sample link (torque, 0.5 ms) is then read through its buffer: same to rounding
    mc = sea_monte_carlo(d2.sea, latency={"torque": Uniform(0.1e-3, 0.5e-3)}, runs=2,
                         amplitude=0.01)
    np.testing.assert_allclose(mc.result.outputs["q_j"] / 0.01,
                               np.broadcast_to(ref.position, (2, 2, ref.position.shape[-1])),
                               atol=1e-12)


def test_one_bin_histogram_csv_equals_constant(tmp_path):
    f = tmp_path / "lat.csv"
    f.write_text("latency_ms,count\n3.0,120\n")
    assert parse_latency(f"hist:{f}") == Empirical((3e-3,), (120.0,), str(f))
    d = sc.design(14, **TABLE_I)
    a = sea_monte_carlo(d.sea, latency={"damping": parse_latency(f"hist:{f}")}, runs=2)
    b = sea_monte_carlo(d.sea, latency={"damping": Constant(3e-3)}, runs=2)
    assert np.array_equal(a.result.outputs["q_j"], b.result.outputs["q_j"])


def test_zero_loss_equals_no_loss_and_seed_reproducible():
    d = sc.design([14, 16], **TABLE_I)
    lat = {"damping": ShiftedExponential(0.5e-3, 1e-3)}
    a = sea_monte_carlo(d.sea, latency=lat, runs=6, seed=4)
    b = sea_monte_carlo(d.sea, latency=lat, loss={"damping": 0.0}, runs=6, seed=4)
    c = sea_monte_carlo(d.sea, latency=lat, runs=6, seed=4)
    e = sea_monte_carlo(d.sea, latency=lat, runs=3, seed=4)
    f = sea_monte_carlo(d.sea, latency=lat, runs=6, seed=5)
    assert np.array_equal(a.result.outputs["q_j"], b.result.outputs["q_j"])
    assert np.array_equal(a.result.outputs["q_j"], c.result.outputs["q_j"])
    assert np.array_equal(a.result.outputs["q_j"][:3], e.result.outputs["q_j"])  # per-run
    assert not np.array_equal(a.result.outputs["q_j"], f.result.outputs["q_j"])


def test_gilbert_elliott_stationary_loss_rate_and_bursts():
    # Two-state chain: P(bad) = p_gb / (p_gb + p_bg), bursts of mean length 1 / p_bg.
    ge = GilbertElliott(0.02, 0.25)
    lost = ge.sample(np.random.default_rng(0), (200_000, 4))
    assert lost.mean() == pytest.approx(0.02 / 0.27, rel=0.05)
    x = lost[:, 0].astype(int)
    starts = np.sum((x[1:] == 1) & (x[:-1] == 0))
    assert x.sum() / starts == pytest.approx(4.0, rel=0.1)
    assert Bernoulli(0.3).sample(np.random.default_rng(1), (100_000,)).mean() == \
        pytest.approx(0.3, abs=0.01)


def test_jitter_inside_margin_always_stable_far_beyond_not():
    # Kao-Lincoln: an extra delay varying in [0, J] keeps the loop stable (J = the torque
    # loop's jitter margin).  Far beyond it (6 J) some realizations go unstable.
    d = sc.design(14, **TABLE_I)
    J = float(d.jitter_margins().torque_jitter_margin_s)
    inside = sea_monte_carlo(d.sea, "impulse", latency={"torque": Uniform(0.5e-3,
                                                                          0.5e-3 + 0.5 * J)},
                             runs=100, seed=0)
    assert inside.fraction_stable == 1.0
    beyond = sea_monte_carlo(d.sea, "impulse", latency={"torque": Uniform(0.5e-3,
                                                                          0.5e-3 + 6 * J)},
                             runs=100, seed=0)
    assert 0 < beyond.fraction_stable < 1
    assert not beyond.stable[beyond.worst_run[()]]


def test_parsers_and_errors():
    assert parse_latency("2") == Constant(2e-3)
    assert parse_latency("exp:0.5:1") == ShiftedExponential(0.5e-3, 1e-3)
    assert parse_loss("0.1") == Bernoulli(0.1)
    assert parse_loss("ge:0.01:0.2:0.9") == GilbertElliott(0.01, 0.2, 0.9)
    for bad in ("uniform:3", "uniform:3:1", "exp:a:1", "2000", "-1"):
        with pytest.raises(InputError):
            parse_latency(bad)
    for bad in ("1.5", "ge:0.1", "x"):
        with pytest.raises(InputError):
            parse_loss(bad)
    with pytest.raises(InputError):
        sea_monte_carlo(sc.design(14).sea, latency={"elbow": Constant(1e-3)}, runs=1)
    for seed in (-1, 1.5, True):  # (numpy's SeedSequence once raised ValueError on -1)
        with pytest.raises(InputError, match="seed"):
            sea_monte_carlo(sc.design(14).sea, latency={"damping": Constant(1e-3)},
                            runs=1, seed=seed)


def test_cli_monte_carlo(capsys, tmp_path):
    args = ["step", "--fn", "14", "16", "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5",
            "--f-qd", "50", "--f-taud", "100", "--mode", "sampled", "--latency",
            "damping=uniform:0.5:3", "--loss", "damping=0.05", "--runs", "20", "--seed", "1"]
    assert main(args + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["runs"] == 20 and [r["fn_hz"] for r in out["designs"]] == [14.0, 16.0]
    assert set(out["designs"][0]) >= {"fraction_stable", "rms_error_mean", "rms_error_worst",
                                      "peak_current_worst_a", "worst_run"}
    assert main(args + ["--plot", str(tmp_path / "mc.png")]) == 0
    assert (tmp_path / "mc.png").is_file()
    assert main(["impulse", "--mode", "sampled", "--loss", "torque=ge:0.01:0.3", "--runs",
                 "5"]) == 0
    capsys.readouterr()
    assert main(["step", "--latency", "damping=1"]) == 2          # continuous mode
    assert main(["step", "--mode", "sampled", "--latency", "elbow=1"]) == 2
    assert main(["step", "--mode", "sampled", "--loss", "damping=2"]) == 2
    assert "error:" in capsys.readouterr().err


def test_multirate_schedule_in_slow_process_ticks():
    # High-level process at 500 Hz, embedded at 2 kHz: a stiffness latency in [1.2, 2.9] ms
    # always waits one 2 ms period (effective 3 ms), the fixed-delay run with T_qs = 3 ms.
    from seactl.latency.montecarlo import timed_simulation
    from seactl.systems.sea.loops import sea_diagram

    rates = {"embedded": 2000.0, "high-level": 500.0}
    d = sc.design([14, 16], delays_ms={"torque": 0.5, "stiffness": 3.0, "damping": 0.5},
                  filters_hz=(50, 100))
    kw = dict(rates_hz=rates, outputs=("q_j",), saturation={"i_m": 30.0})
    ref = simulate(sea_diagram(), d.sea, {"q_des": Step(0.01)}, 0.3, mode="sampled", **kw)
    res = timed_simulation(sea_diagram(), d.sea, {"q_des": Step(0.01)}, 0.3,
                           latency={"stiffness": Uniform(1.2e-3, 2.9e-3)}, runs=2,
                           links={"stiffness": "Kq_fb"}, **kw)
    assert np.array_equal(res.outputs["q_j"], np.broadcast_to(ref.outputs["q_j"],
                                                              res.outputs["q_j"].shape))
