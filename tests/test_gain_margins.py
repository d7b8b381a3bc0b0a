"""Gain margins of every size: python-control's margin table, a dense scan of the SEA loop,
and the analytic phase crossovers of a delayed integrator."""

from types import SimpleNamespace

import control
import numpy as np
import pytest
from scipy.optimize import brentq

from seactl.analysis.margins import default_grid, loop_margins
from seactl.apps.cli import main
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import SEADesign, Timing, outer_loop
from seactl.systems.sea.views import sea_margins


def rational_loop(num, den):
    """``L = num(s) / den(s)`` (descending coefficients) closed by unit negative feedback:
    as a block diagram (the certified scan) and as an opaque callable (the grid scan)."""
    diagram = BlockDiagram("tf", [Block("plant", "u", "y", num=lambda p: tuple(num),
                                        den=lambda p: tuple(den)),
                                  Block("fb", "y", "u", num=lambda p: (-1.0,))])
    opaque = lambda p, s: np.polyval(num, s) / np.polyval(den, s)  # noqa: E731
    return diagram.loop("y"), opaque


# python-control's margin table, control/tests/margin_test.py (fixture `tsys`) of the
# repository python-control/python-control: 0.01 (10 - s) / ((2 + s)(1 + s)), gain margin
# 300 (49.54 dB) at 5.6569 rad/s; 1 / (1 + s) and 3 (10 + s) / (2 + s), which have no phase
# crossover.  Then, on the certified path (a loop without delay: every phase crossover),
# two far beyond 234 dB: 1e-13 / (s + 1)^3 (278 dB at sqrt 3) and
# 1e-20 / (s (s + 1)(s + 2)(s + 3)) (420 dB at 1 rad/s).
PC_CASES = [([-0.01, 0.1], [1.0, 3.0, 2.0]), ([1.0], [1.0, 1.0]), ([3.0, 30.0], [1.0, 2.0])]
FAR = [([1e-13], [1.0, 3.0, 3.0, 1.0]), ([1e-20], [1.0, 6.0, 11.0, 6.0, 0.0])]
CASES = [(n, d, path) for n, d in PC_CASES for path in ("certified", "opaque")] + \
    [(n, d, "certified") for n, d in FAR]


@pytest.mark.parametrize("num,den,path", CASES)
def test_python_control_margin_table(num, den, path):
    # Oracle: control.stability_margins on the same transfer function.
    gm, _pm, _sm, w180, _wc, _ws = control.stability_margins(control.tf(num, den))
    certified, opaque = rational_loop(num, den)
    p = SimpleNamespace(shape=(1,))
    m = loop_margins(certified if path == "certified" else opaque, p, default_grid(1.0))
    if np.isfinite(gm):
        assert float(m.gain_margin[0]) == pytest.approx(gm, rel=1e-9)
        assert float(m.phase_crossover_hz[0]) * 2 * np.pi == pytest.approx(w180, rel=1e-9)
    else:
        assert np.isinf(m.gain_margin[0]) and m.phase_crossovers.design.size == 0


def dense_phase_crossovers(loop, design, w_lo, w_hi, n=400_000):
    """Oracle: every sign change of Im L with Re L < 0 on a dense log grid, each solved by
    brentq on Im L; returns the frequencies [rad/s] and |L| there."""
    at = lambda x: np.reshape(loop(design, 1j * np.atleast_1d(x)), -1)  # noqa: E731
    w = np.logspace(np.log10(w_lo), np.log10(w_hi), n)
    L = at(w)
    i = np.nonzero((np.signbit(L.imag[1:]) != np.signbit(L.imag[:-1]))
                   & (L.real[1:] + L.real[:-1] < 0))[0]
    roots = np.array([brentq(lambda x: at(x)[0].imag, w[k], w[k + 1], xtol=1e-14,
                             rtol=1e-15) for k in i])
    return roots, np.abs(at(roots))


def test_sea_gain_margin_beyond_26_db_equals_a_dense_scan():
    # Oracle: a dense scan of the same exact-delay loop (400,000 points over 6 decades,
    # crossings solved by brentq); and the figures of issue 36 (47.33 dB at 329.65 Hz).
    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 14.0), Timing.from_ms(0.05, 0.05, 0.05))
    m = sea_margins(d)
    w, mag = dense_phase_crossovers(outer_loop(), d, 1.0, 1e6)
    best = np.argmin(np.abs(np.log(mag)))
    assert float(m.gain_margin) == pytest.approx(1 / mag[best], rel=1e-8)
    assert float(m.phase_crossover_hz) * 2 * np.pi == pytest.approx(w[best], rel=1e-8)
    assert float(m.gain_margin_db) == pytest.approx(47.33, abs=0.005)
    assert float(m.phase_crossover_hz) == pytest.approx(329.65, abs=0.005)
    # every crossover the scan reports is one of the oracle's
    found = m.phase_crossovers.omega
    assert np.all(np.min(np.abs(found[:, None] / w[None, :] - 1), axis=1) < 1e-8)


def delayed_integrator(K, T):
    """``L = K e^{-sT} / s`` as a block diagram: an integrator closed by a delayed gain."""
    g = BlockDiagram("lag", [Block("int", "u", "y", den=lambda p: (1.0, 0.0)),
                             Block("fb", "y", "u", num=lambda p: (-p.K,), delay="T")])
    p = SimpleNamespace(K=np.asarray(K, float), T=np.asarray(T, float), shape=np.shape(K))
    return g.loop("y"), p


@pytest.mark.parametrize("K,listed", [(0.01, 4), (1e-4, 1), (0.3, 1)])
def test_several_phase_crossovers_the_one_closest_to_0_db_is_reported(K, listed):
    # Oracle: by hand, K e^{-jwT}/(jw) is on the negative real axis at
    # w_k = (pi/2 + 2 pi k)/T, where 1/|L| = w_k / K; the smallest is k = 0.  Listed: at
    # least those with |L| in the band of the design's last scan: 0.05 < |L| for K = 0.3,
    # 0.05 / 3000 < |L| (the band widened once) for K = 0.01 and 1e-4.
    T = 1.0
    loop, p = delayed_integrator(np.array([K]), np.array([T]))
    m = loop_margins(loop, p, default_grid(1.0))
    assert float(m.gain_margin[0]) == pytest.approx(np.pi / (2 * K * T), rel=1e-9)
    assert float(m.phase_crossover_hz[0]) * 2 * np.pi == pytest.approx(np.pi / 2, rel=1e-9)
    found = m.phase_crossovers
    k = np.round((found.omega * T - np.pi / 2) / (2 * np.pi))
    w_k = (np.pi / 2 + 2 * np.pi * k) / T
    assert found.omega == pytest.approx(w_k, rel=1e-9)  # each listed one is a w_k
    assert found.value == pytest.approx(w_k / K, rel=1e-9)
    assert set(range(listed)) <= set(k.astype(int).tolist())


def test_gains_prints_a_gain_margin_of_47_db(capsys):
    # Oracle: the dense scan of test_sea_gain_margin_beyond_26_db_equals_a_dense_scan
    # (47.327 dB); the table and the JSON say the same.
    import json
    args = ["gains", "--fn", "14", "--t-tau", "0.05", "--t-qs", "0.05", "--t-qd", "0.05"]
    assert main(args + ["--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert row["gain_margin_db"] == pytest.approx(47.327, abs=1e-3)
    assert main(args) == 0
    assert "47.33" in capsys.readouterr().out
