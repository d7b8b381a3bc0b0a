"""Delays in seconds in loop files (``delay_s``, ``latency_s``), with no cap but the work.

The loop: a first-order process ``1 / (T s + 1)``, ``T = 100 s``, behind a 30 s dead time,
under proportional control ``Kc = 2`` (a process-control loop).  Oracles: closed forms of
``L = Kc e^{-s theta} / (T s + 1)`` (crossover ``w_c = sqrt(Kc^2 - 1) / T``, phase margin
``pi - atan(T w_c) - theta w_c``, critical dead time ``arccos(-1/Kc) / w_c``), python-
control's margin of the same exact-delay frequency response (numpy, not seactl), and the
roots ``-1/T + W_k(-(Kc/T) theta e^{theta/T}) / theta`` (Lambert W, scipy).
"""

from __future__ import annotations

import time

import control as ct
import numpy as np
import pytest
from scipy.special import lambertw

import seactl as sc
from seactl.apps.cli import main
from seactl.errors import ResourceError

KC, T, THETA = 2.0, 100.0, 30.0


def _loop(tmp_path, delay: str = 'delay_s = "theta"', latency: str = "",
          theta: float = THETA) -> str:
    path = tmp_path / "dead-time.toml"
    path.write_text(f"""name = "dead-time"
[variables]
Kc = {KC}
T = {T}
theta = {theta}
[processes.pc]
rate_hz = 10
{latency}
[[blocks]]
name = "C"
kind = "gain"
input = ["r", "-y_m"]
output = "u"
gain = "Kc"
process = "pc"
{delay}
[[blocks]]
name = "P"
kind = "plant_tf"
input = "u"
output = "y"
num = [1.0]
den = ["T", 1.0]
[[blocks]]
name = "S"
kind = "sensor"
input = "y"
output = "y_m"
[signals]
inputs = ["r"]
reference = "r"
output = "y"
[[breaks]]
name = "loop"
signal = "y_m"
""")
    return str(path)


def test_a_30_s_dead_time_matches_closed_forms_and_python_control(tmp_path):
    loop = sc.load_loop(_loop(tmp_path))
    assert loop.delays_s == {"C": pytest.approx(THETA)}
    row = loop.margins().records()[0]
    wc = np.sqrt(KC**2 - 1) / T
    pm = np.pi - np.arctan(T * wc) - THETA * wc
    assert row["loop_phase_margin_deg"] == pytest.approx(np.degrees(pm), rel=1e-9)
    # (records keep 10 decimals: 0.0027566445 Hz)
    assert row["loop_crossover_hz"] == pytest.approx(wc / (2 * np.pi), abs=1e-10)
    assert row["loop_delay_margin_ms"] == pytest.approx(1e3 * pm / wc, rel=1e-9)
    # python-control on the exact-delay frequency response, evaluated with numpy
    w = np.logspace(-4, 0, 40001)
    frd = ct.frd(KC * np.exp(-1j * w * THETA) / (1j * w * T + 1), w)
    _, pm_ct, _, wcp = ct.margin(frd)
    assert row["loop_phase_margin_deg"] == pytest.approx(pm_ct, abs=1e-3)
    assert 2 * np.pi * row["loop_crossover_hz"] == pytest.approx(wcp, rel=1e-4)
    # rightmost roots: Lambert W branches of s + 1/T + (Kc/T) e^{-s theta} = 0
    a, b = 1 / T, KC / T
    ref = np.array([-a + lambertw(-b * THETA * np.exp(a * THETA), k) / THETA
                    for k in range(-6, 7)])
    ref = ref[ref.imag >= 0]
    ref = ref[np.argsort(-ref.real)][:3]
    got = loop.roots(count=3).roots
    np.testing.assert_allclose(got, ref, rtol=1e-9)
    # the delay margin along the dead time: the closed form's critical delay, less 30 s
    m = loop.delay_margin()
    star = np.arccos(-a / b) / np.sqrt(b * b - a * a)
    assert float(m.delay_margin_s) == pytest.approx(star - THETA, rel=1e-9)


def test_seconds_milliseconds_and_process_latency_agree(tmp_path):
    # Oracle: the same loop written three ways gives the same delay, to the last bit.
    a = sc.load_loop(_loop(tmp_path, 'delay_s = "theta"')).delays_s["C"]
    b = sc.load_loop(_loop(tmp_path, 'delay_ms = "theta * 1000"')).delays_s["C"]
    c = sc.load_loop(_loop(tmp_path, 'delay_s = "process"', 'latency_s = 30')).delays_s["C"]
    d = sc.load_loop(_loop(tmp_path, 'delay_ms = "process"', 'latency_ms = 30000')
                     ).delays_s["C"]
    assert float(a) == float(b) == float(c) == float(d) == THETA


@pytest.mark.parametrize("delay, latency, field", [
    ('delay_s = 30\ndelay_ms = 30000', "", "fields 'delay_ms' and 'delay_s'"),
    ('delay_s = "process"', "latency_s = 30\nlatency_ms = 30000",
     "fields 'latency_ms' and 'latency_s'"),
    ("delay_s = -1", "", "field 'delay_s' = -1"),
    ('delay_s = "theta * 1e400"', "", "field 'delay_s'"),
])
def test_bad_delays_are_refused_naming_the_field(tmp_path, capsys, delay, latency, field):
    # Behaviour: one line, exit 2, the field (or both fields) named.
    assert main(["analyze", "--loop", _loop(tmp_path, delay, latency), "--no-jitter"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error: ") and field in err, err


def test_a_huge_delay_is_refused_up_front(tmp_path, capsys):
    # Oracle: the budget's estimate, counted by hand: a 1e12 s delay turns the phase every
    # 2 pi / 1e12 rad/s, so the certified scan needs ~1e10 points (hours) and the
    # simulation a ring of 1e12 s / 0.1 ms samples (terabytes): both refused in a second.
    path = _loop(tmp_path, theta=1e12)
    t0 = time.perf_counter()
    assert main(["analyze", "--loop", path, "--no-jitter"]) == 2
    err = capsys.readouterr().err.strip()
    assert "certified margin scan" in err and "a loop delay of 1e+12 s" in err
    loop = sc.load_loop(path)
    with pytest.raises(ResourceError, match="would take about"):
        loop.roots(count=2)
    with pytest.raises(ResourceError, match="delay buffers .* 1e\\+12 s"):
        loop.step(t_end_s=10)
    with pytest.raises(ResourceError, match="delay buffers"):
        loop.step(t_end_s=10, mode="sampled", rate_hz=10)
    assert time.perf_counter() - t0 < 10


def test_the_unit_typo_guard_stays_for_actuator_designs():
    # Behaviour (README's unit contract): an actuator design's delays_ms above 1 s is
    # taken as seconds typed as milliseconds and refused.
    with pytest.raises(sc.InputError, match="1000 ms"):
        sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2000, "damping": 0.5})
