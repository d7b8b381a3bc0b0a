"""Jitter margin of the sampled loop (``System.jitter_margins(rate_hz=...)``).

Oracles: a closed-form alias sum (the partial-fraction series of ``1/sin^4``); mpmath's
``nsum`` of the alias series of the rigid and SEA plants written here from their
equations of motion; the same bound computed independently with python-control (ZOH and
Tustin discretizations), the alias sum in closed form from the plant's state space
(Poisson summation) and a dense scan (the certified peak never below it); the continuous
Kao-Lincoln margin as the period shrinks; a time-domain simulation written here (exact
plant transitions, late samples) under switching delays.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

import seactl as sc
from seactl.simulate.alias import alias_factor, alias_sum, plant_realization
from seactl.simulate.sampled_jitter import actuation_signal, jitter_samples, plant_path

RIGID = {"stiffness": 1.5, "damping": 1.5}


def _rigid():
    return sc.rigid(8, delays_ms=RIGID)


def _buffer(delay_s: float, h: float) -> int:
    """Whole-sample buffer of a delay (docs/jitter.md: usable ceil((T - h/2)/h) ticks later)."""
    return max(math.ceil((delay_s - h / 2) / h - 1e-9), 0)


def _proven_samples(g: float) -> float:
    """Largest N with sqrt(N ceil N) g <= 1 (docs/theory/sampled-jitter.md), by bisection on
    each whole-sample band (independent of seactl's closed form)."""
    best = 0.0
    for m in range(1, int(2 / g) + 3):
        lo, hi = m - 1.0, float(m)
        if math.sqrt(hi * m) * g <= 1:
            best = hi
            continue
        for _ in range(80):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if math.sqrt(mid * m) * g <= 1 else (lo, mid)
        return max(best, lo)
    return best


def test_alias_sum_double_integrator_closed_form():
    # Oracle: sum_k 1/(x+k)^4 = pi^4 (2 + cos 2 pi x) / (3 sin^4 pi x) (partial fractions of
    # pi^2 / sin^2 differentiated twice); P = 1/s^2, s_k = j (theta + 2 pi k) / h.
    h = 1e-3
    theta = np.array([0.01, 0.3, 1.0, 2.5, np.pi])
    x = theta / (2 * np.pi)
    exact = (h / (2 * np.pi)) ** 4 * np.pi**4 * (2 + np.cos(2 * np.pi * x)) \
        / (3 * np.sin(np.pi * x) ** 4)
    A, B, C = np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[1.0], [0.0]]), \
        np.array([[0.0, 1.0]])
    np.testing.assert_allclose(alias_sum(A, B, C, theta, h), exact, rtol=1e-11)
    with pytest.raises(sc.InputError, match="at most one integrator"):
        alias_factor(A, B, C, h)        # its pole at z = 1 would not cancel in g


def _sea_design():
    return sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                     filters_hz=(50, 100))


def _mp_alias(P, theta: float, h: float) -> float:
    """sum_k |P(j (theta + 2 pi k) / h)|^2 by mpmath's nsum (each side extrapolated)."""
    import mpmath as mp

    f = lambda k: abs(P(1j * (theta + 2 * mp.pi * k) / h)) ** 2  # noqa: E731
    return float(mp.nsum(f, [0, mp.inf]) + mp.nsum(f, [-mp.inf, -1]))


@pytest.mark.parametrize("rate_hz", [1000.0, 16000.0])
def test_alias_closed_form_matches_mpmath_nsum(rate_hz):
    # Oracle: mpmath's nsum of the alias series, the plants written here from their
    # equations of motion (rigid: 1/(m s^2 + b s); SEA: motor and load inertias joined by
    # the spring, load position beta k / Delta and spring torque beta k (Ij s^2 + bj s) /
    # Delta, Delta = (Im s^2 + bm s + k)(Ij s^2 + bj s + k) - k^2).  Both the sum and
    # |z - 1|^2 times it as the closed-form row W (integrator cancelled) to 1e-10.
    import mpmath as mp

    mp.mp.dps = 30
    h = 1.0 / rate_hz
    p = _rigid().rigid
    m, b = float(p.m), float(p.b)
    a = _sea_design().jitter_loops()[2].actuator
    from seactl.systems.rigid.model import RIGID_DIAGRAM

    Im, Ij, bm, bj, k, beta = (float(getattr(a, n)) for n in ("Im", "Ij", "bm", "bj", "k",
                                                              "beta"))
    delta = lambda s: (Im * s**2 + bm * s + k) * (Ij * s**2 + bj * s + k) - k**2  # noqa
    sea_diagram, _taps, sea = _sea_design().jitter_loops()
    cases = [(RIGID_DIAGRAM, p, "x_sens", lambda s: 1 / (m * s**2 + b * s)),
             (sea_diagram, sea, "q_sens", lambda s: beta * k / delta(s)),
             (sea_diagram, sea, "tau_sens", lambda s: beta * k * (Ij * s**2 + bj * s)
              / delta(s))]
    theta = np.array([0.002, 0.05, 0.4, 2.0, np.pi])
    for diagram, design, tap, P in cases:
        act = actuation_signal(diagram)
        A, B, C, D = (x[0] for x in plant_realization(plant_path(diagram, design, tap),
                                                      design, tap, act))
        assert D[0, 0] == 0.0
        ref = np.array([_mp_alias(P, t, h) for t in theta])
        np.testing.assert_allclose(alias_sum(A, B, C, theta, h), ref, rtol=1e-10)
        Aw, Bw, Cw, Dw = alias_factor(A, B, C, h)
        z = np.exp(1j * theta)[:, None, None]
        Wz = Cw @ np.linalg.solve(z * np.eye(Aw.shape[0]) - Aw, np.broadcast_to(
            Bw, theta.shape + Bw.shape)) + Dw
        w2, want = np.sum(np.abs(Wz[:, 0, :]) ** 2, axis=-1), \
            np.abs(np.exp(1j * theta) - 1) ** 2 * ref
        # W's rounding is relative to its size in the loop's band (where g peaks); far
        # above it W is many orders smaller and only its absolute error, a 1e-10 of the
        # band's size, matters for the peak
        band = want >= 1e-6 * want.max()
        np.testing.assert_allclose(w2[band], want[band], rtol=1e-10)
        np.testing.assert_allclose(w2, want, rtol=0, atol=1e-10 * want.max())


def _rigid_gain(rate_hz: float):
    """g(theta) of the rigid actuator's whole loop, computed here: python-control's ZOH
    plant and Tustin filter, whole-sample buffers, the alias sum in closed form from the
    plant's state space (Poisson summation)."""
    import control

    p = _rigid().rigid
    m, b, K, B, Tf = (float(getattr(p, k)) for k in ("m", "b", "K", "B", "Tf_v"))
    h = 1.0 / rate_hz
    ns, nd = _buffer(float(p.T_s), h), _buffer(float(p.T_d), h)
    Pz = control.c2d(control.tf([1.0], [m, b, 0.0]), h, "zoh")
    Bz = control.c2d(control.tf([B, 0.0], [Tf, 1.0]), h, "tustin")
    # closed-form alias sum: sum_k |P(s_k)|^2 = h C (zI - Phi)^-1 Q (zI - Phi)^-H C^T
    A = np.array([[0.0, 1.0], [0.0, -b / m]])
    Bc = np.array([[0.0], [1.0 / m]])
    V = expm(np.block([[-A, Bc @ Bc.T], [np.zeros((2, 2)), A.T]]) * h)
    Phi = V[2:, 2:].T
    Q = Phi @ V[:2, 2:]
    C = np.array([[1.0, 0.0]])

    def g(theta):
        z = np.exp(1j * np.atleast_1d(theta))
        Cz = K * z**-ns + np.asarray(Bz(z)) * z**-nd
        M = Cz / (1 + np.asarray(Pz(z)) * Cz)
        R = np.linalg.solve(np.swapaxes(z[:, None, None] * np.eye(2) - Phi, -1, -2),
                            np.broadcast_to(C.T, (z.size, 2, 1)))[..., 0]  # (zI - Phi)^-T C^T
        alias = h * np.einsum("fi,ij,fj->f", R, Q, R.conj()).real
        return np.abs(z - 1) * np.abs(M) * np.sqrt(alias)

    return g


def _rigid_bound(rate_hz: float) -> float:
    """The sampled jitter margin [samples] of the rigid actuator's whole loop: a dense
    scan of :func:`_rigid_gain` with local refinement."""
    from scipy.optimize import minimize_scalar

    g = _rigid_gain(rate_hz)
    grid = np.pi * np.logspace(-5, 0, 20001)
    vals = g(grid)
    i = int(np.argmax(vals))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = minimize_scalar(lambda t: -float(g(t)[0]), bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-12})
    return _proven_samples(max(vals[i], -res.fun))


@pytest.mark.parametrize("rate_hz", [1000.0, 4000.0])
def test_rigid_bound_matches_independent_computation(rate_hz):
    # Oracle: _rigid_bound (python-control + closed-form alias sum + dense scan).
    j = _rigid().jitter_margins(rate_hz=rate_hz)
    assert j.records()[0]["verdict"] == "stable"
    np.testing.assert_allclose(float(j.jitter_margin_samples), _rigid_bound(rate_hz),
                               rtol=1e-5)
    assert float(j.jitter_margin_s) == pytest.approx(float(j.jitter_margin_samples) / rate_hz)


def _scan_peaks(system, rate_hz: float) -> tuple[dict, dict]:
    """Per loop: the reported g and its brute-force scan on 1e5 angles, g evaluated by
    another route: the sampled margins' frequency response (folded registers,
    ``sampled.broken_responses``) times the alias sum in closed form (checked against
    mpmath above)."""
    from seactl.simulate.sampled import broken_responses
    from seactl.simulate.sampled_jitter import sampled_jitter_margins

    diagram, taps, design = system.jitter_loops()
    j = sampled_jitter_margins(diagram, design, taps, rate_hz, system.reference_frequency())
    act = actuation_signal(diagram)
    theta = np.pi * np.r_[np.logspace(-6, 0, 50_000), np.linspace(0, 1, 50_000)[1:]]
    scans = {}
    for name, tap in taps.items():
        A, B, C, _ = (x[0] for x in plant_realization(plant_path(diagram, design, tap),
                                                      design, tap, act))
        respond, h = broken_responses(diagram, design, tap, rate_hz, act)
        L, G = respond(np.array([0]), theta[None, :])
        scans[name] = float(np.max(np.abs(np.exp(1j * theta) - 1) * np.abs(G[0] / (1 + L[0]))
                                   * np.sqrt(alias_sum(A, B, C, theta, h))))
    return {k: float(v) for k, v in j.peak.items()}, scans


@pytest.mark.parametrize("rate_hz", [1000.0, pytest.param(16000.0, marks=pytest.mark.slow)])
def test_peak_never_below_dense_scan_rigid(rate_hz):
    # Oracle: _scan_peaks.  The reported g is an upper bound: never below the scan's
    # largest value, and tight (within 1e-7 of it).
    peaks, scans = _scan_peaks(_rigid(), rate_hz)
    for name in scans:
        assert scans[name] <= peaks[name] <= scans[name] * (1 + 1e-7), name


@pytest.mark.slow
def test_peak_never_below_dense_scan_sea():
    # Oracle: _scan_peaks, every loop of the SEA design at 4 kHz.
    peaks, scans = _scan_peaks(_sea_design(), 4000.0)
    for name in scans:
        assert scans[name] <= peaks[name] <= scans[name] * (1 + 1e-7), name


def test_discrete_peak_bounds_random_systems():
    # Oracle: a 1e5-point scan of ||C (zI - A)^-1 B + D|| (numpy solves); stable random
    # systems with poles up to 0.999 from the circle.
    from seactl.certify.hinf import discrete_gain, discrete_peak

    rng = np.random.default_rng(1)
    theta = np.linspace(0, np.pi, 100_001)
    for radius in (0.9, 0.97, 0.999):
        A = rng.normal(size=(8, 8))
        A *= radius / np.max(np.abs(np.linalg.eigvals(A)))
        B, C, D = rng.normal(size=(8, 3)), rng.normal(size=(1, 8)), rng.normal(size=(1, 3))
        up, _th, lo = discrete_peak(A, B, C, D)
        scan = discrete_gain(A, B, C, D, theta).max()
        assert lo <= up and scan <= up <= scan * (1 + 1e-4)


def test_sampled_margin_tends_to_continuous():
    # Oracle: the continuous Kao-Lincoln margin (certified).  Expected law: O(h), from
    # the buffers' effective delay (within h/2 + h of the continuous one) and the whole-
    # sample rounding of the sqrt(N ceil N) factor (< 1 sample): |J_h - J| <= 1.5 h.
    from seactl.simulate.sampled_jitter import sampled_jitter_margins
    from seactl.systems.rigid.model import RIGID_DIAGRAM

    r = _rigid()
    jc = float(r.jitter_margins().jitter_margin_s)
    errors = []
    for rate in (1000.0, 4000.0, 16000.0, 64000.0):
        js = float(sampled_jitter_margins(RIGID_DIAGRAM, r.rigid, {"overall": "x_sens"}, rate,
                                          r.reference_frequency()).margin_s["overall"])
        errors.append(abs(js - jc))
        assert errors[-1] <= 1.5 / rate
    assert all(a > b for a, b in zip(errors, errors[1:]))
    assert errors[-1] / jc < 2e-3


def _simulate(rate_hz: float, delays: np.ndarray, steps: int) -> np.ndarray:
    """The sampled rigid loop written here: exact transitions of 1/(m s^2 + b s) under a
    held force, the position sampled late by delays[:, k] (a delay in [0, J] on the
    sensor signal, x(t_k - d_k)), whole-sample buffers and the Tustin velocity filter.
    Returns |x| per run and step (runs = rows of ``delays``, a 1 mm initial offset)."""
    p = _rigid().rigid
    m, b, K, B, Tf = (float(getattr(p, k)) for k in ("m", "b", "K", "B", "Tf_v"))
    h = 1.0 / rate_hz
    ns, nd = _buffer(float(p.T_s), h), _buffer(float(p.T_d), h)
    A = np.array([[0.0, 1.0], [0.0, -b / m]])
    Bc = np.array([0.0, 1.0 / m])

    def trans(tau):  # state and input maps over tau
        E = expm(np.block([[A, Bc[:, None]], [np.zeros((1, 3))]]) * tau)
        return E[:2, :2], E[:2, 2]

    Phi, Gam = trans(h)
    runs = delays.shape[0]
    hist = int(np.ceil(delays.max() / h)) + 2
    X = np.zeros((hist, runs, 2))        # states at past ticks (newest last)
    U = np.zeros((hist, runs))           # forces held from those ticks
    X[:, :, 0] = 1e-3
    ys = np.zeros((max(ns, nd) + 1, runs))
    e_prev = np.zeros(runs)
    v_prev = np.zeros(runs)
    cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    out = np.zeros((runs, steps))
    for k in range(steps):
        x_now = X[-1]
        y = np.empty(runs)
        for d in np.unique(delays[:, k]):
            sel = delays[:, k] == d
            back = int(np.ceil(d / h - 1e-12))
            tau = back * h - d
            if tau not in cache:
                cache[tau] = trans(tau)
            F, G = cache[tau]
            xs = X[-1 - back, sel] @ F.T + U[-1 - back, sel, None] * G
            y[sel] = xs[:, 0]
        ys = np.roll(ys, 1, axis=0)
        ys[0] = y
        e = ys[nd]
        v = (2 * B * (e - e_prev) - (h - 2 * Tf) * v_prev) / (2 * Tf + h)
        e_prev, v_prev = e, v
        u = -K * ys[ns] - v
        U[-1] = u
        x_next = x_now @ Phi.T + u[:, None] * Gam
        X = np.roll(X, -1, axis=0)
        U = np.roll(U, -1, axis=0)
        X[-1] = x_next
        out[:, k] = np.abs(x_next[:, 0])
    return out


def test_monte_carlo_below_margin_stays_bounded_and_above_diverges():
    # Oracle: the simulation above (independent of seactl's sampled engine).  Below the
    # margin (sufficient): random {0, J} delays and square waves switching at 0.5-4 times
    # the peak frequency of the bound, every run decays.  Well above it (1.3 x the delay
    # margin, a constant delay being one admitted pattern), the loop diverges.
    rate = 1000.0
    r = _rigid()
    j = r.jitter_margins(rate_hz=rate)
    J = 0.95 * float(j.jitter_margin_s)
    steps = 3000
    rng = np.random.default_rng(0)
    rand = rng.integers(0, 2, (40, steps)) * J
    f_pk = float(j.peak_hz["overall"])
    t = np.arange(steps) / rate
    square = np.array([(np.sin(2 * np.pi * c * f_pk * t + ph) > 0) * J
                       for c in (0.5, 1.0, 2.0, 4.0) for ph in (0.0, 1.0, 2.0)])
    below = _simulate(rate, np.vstack([rand, square]), steps)
    assert np.all(below[:, -300:].max(axis=1) < 1e-4)      # decayed from 1 mm
    dm = float(r.margins().delay_margin_s)
    above = _simulate(rate, np.full((1, steps), 1.3 * dm), steps)
    assert above[0, -300:].max() > 1e-1                       # grown from 1 mm


def test_unstable_gives_zero_and_multirate_is_refused():
    # Oracle: the sampled verdict (certified): delays beyond the delay margin are unstable.
    r = sc.rigid(8, delays_ms={"stiffness": 12, "damping": 12})
    j = r.jitter_margins(rate_hz=1000)
    assert j.records()[0]["verdict"] == "unstable"
    assert float(j.jitter_margin_s) == 0.0 and float(j.jitter_margin_samples) == 0.0
    with pytest.raises(sc.InputError, match="one rate for every process"):
        _rigid().jitter_margins(rate_hz={"high-level": 250, "embedded": 1000})


def test_tap_behind_dynamics_is_refused():
    # F_des is fed by the controller's delayed, filtered blocks: no sampling instant there.
    from seactl.systems.rigid.model import RIGID_DIAGRAM

    with pytest.raises(sc.InputError, match="static sensor blocks"):
        plant_path(RIGID_DIAGRAM, _rigid().rigid, "F_des")


def test_jitter_samples_whole_numbers_and_below_one():
    # Oracle: _proven_samples (bisection on sqrt(N ceil N) g <= 1).
    for g in (0.25, 0.3, 0.9, 1.0, 2.0, 1 / 7.4):
        assert float(jitter_samples(g)) == pytest.approx(_proven_samples(g), abs=1e-9)


@pytest.mark.slow
def test_sea_records_and_loops():
    # Oracle: the continuous result's loops; each sampled margin within 1.5 h of it at 4 kHz
    # (the law of test_sampled_margin_tends_to_continuous).
    d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
    rec = d.jitter_margins(rate_hz=4000).records()[0]
    cont = d.jitter_margins().records()[0]
    assert rec["verdict"] == "stable" and rec["rate_hz"] == 4000.0
    for key in ("jitter_margin_ms", "stiffness_jitter_margin_ms", "damping_jitter_margin_ms",
                "torque_jitter_margin_ms"):
        assert abs(rec[key] - cont[key]) <= 1.5 * 0.25
        assert rec[key.replace("_ms", "_samples")] == pytest.approx(rec[key] * 4)


DESIGN = ["--fn", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50",
          "--f-taud", "100"]


@pytest.mark.slow
def test_cli_rate_prints_the_api_values(capsys):
    # Oracle: the public API on the same design (every front end goes through it).
    import json

    from seactl.apps.cli import main

    assert main(["jitter", *DESIGN, "--rate", "2000", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)["designs"][0]
    d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
    api = d.jitter_margins(rate_hz=2000).records()[0]
    assert row["sampled_jitter"] == {k: v for k, v in api.items() if k not in ("fn_hz", "gs")}
    assert row["jitter_margin_ms"] == pytest.approx(d.jitter_margins().records()[0][
        "jitter_margin_ms"])
    assert main(["jitter", *DESIGN, "--rate", "2000"]) == 0
    assert f"{api['stiffness_jitter_margin_ms']:.3f}" in capsys.readouterr().out


def test_cli_bad_rate_is_one_line(capsys):
    # A rate out of range: one line naming the flag, exit 2 (the CLI's error contract).
    from seactl.apps.cli import main

    assert main(["jitter", "--fn", "14", "--rate", "-5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "--rate" in err[0]


def test_loop_file_rate_is_refused_cleanly():
    # A loop file has continuous jitter margins only: a rate is a seactl error, not a crash.
    from pathlib import Path

    loop = sc.load_loop(Path(__file__).resolve().parents[1] / "examples/loops/rigid.toml")
    with pytest.raises(sc.InputError):
        loop.jitter_margins(rate_hz=1000)


def test_plot_draws_one_bar_per_loop_and_design():
    # Oracle: the records (one bar per loop and design, heights the margins in ms).
    import matplotlib

    matplotlib.use("Agg")
    r = sc.rigid([6, 8], delays_ms={"stiffness": 1.5, "damping": 1.5}).jitter_margins(
        rate_hz=2000)
    ax = r.plot()
    heights = sorted(p.get_height() for p in ax.patches)
    expected = sorted(1e3 * float(v) for a in (r.jitter_margin_s, r.stiffness_jitter_margin_s,
                                               r.damping_jitter_margin_s) for v in a)
    np.testing.assert_allclose(heights, expected)
