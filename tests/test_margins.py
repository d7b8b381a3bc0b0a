"""Margins against python-control, analytic identities and a time-domain simulation."""

from types import SimpleNamespace

import control
import numpy as np
import pytest

from seactl.analysis.margins import default_grid, loop_margins
from seactl.diagram.blockdiagram import DesignSubset
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import SEADesign, Timing, outer_loop
from seactl.systems.sea.views import sea_margins

A = UT_SEA
TABLE_I_PM = {12: 45.1, 14: 43.2, 16: 40.0, 18: 36.5, 20: 33.2}


def sea(fn, gs=1.0, ms=(0.5, 2.0, 0.5, 50.0, 100.0)):
    return SEADesign(A, critically_damped_gains(A, fn, gs=gs), Timing.from_ms(*ms))


@pytest.mark.parametrize("fn,pm", sorted(TABLE_I_PM.items()))
def test_table_i_phase_margins(fn, pm):
    # Oracle: the paper's Table I.
    assert float(sea_margins(sea(float(fn))).phase_margin_deg) == pytest.approx(pm, abs=0.1)


def test_gain_scale_0p4_gives_34_degrees():
    # Oracle: Fig. GainScale(a), ideal loop, f_n = 14 Hz
    m = sea_margins(SEADesign(A, critically_damped_gains(A, 14.0, gs=0.4)))
    assert float(m.phase_margin_deg) == pytest.approx(34.0, abs=0.1)


# Table-driven comparison with python-control on a dense FRD of the same exact-delay loop.
CASES = [
    # fn, gs, (T_tau, T_qs, T_qd [ms], f_qd, f_taud [Hz])
    (12.0, 1.0, (0.5, 2.0, 0.5, 50.0, 100.0)),
    (20.0, 1.0, (1.0, 10.0, 1.0, 50.0, 100.0)),
    (14.0, 0.5, (0.5, 5.0, 2.0, 30.0, 200.0)),
    (30.0, 2.0, (1.0, 3.0, 1.0, None, None)),
    (16.0, 1.0, (0.0, 0.0, 0.0, None, None)),
    (25.0, 1.3, (0.8, 15.0, 0.5, 80.0, 150.0)),
]


@pytest.mark.parametrize("fn,gs,ms", CASES)
def test_margins_equal_python_control_on_dense_frd(fn, gs, ms):
    # Oracle: control.stability_margins on a dense FRD of the same exact-delay loop.
    d = sea(fn, gs, ms)
    ours = sea_margins(d)
    w = np.logspace(-1, 4, 20000)
    L = outer_loop()(d, 1j * w)
    gm, pm, _sm, w180, wc, _ws = control.stability_margins(control.FRD(L, w))
    assert float(ours.phase_margin_deg) == pytest.approx(pm, abs=2e-3)
    assert float(ours.crossover_hz) * 2 * np.pi == pytest.approx(wc, rel=1e-5)
    if np.isfinite(gm):
        assert float(ours.gain_margin) == pytest.approx(gm, rel=1e-4)
        assert float(ours.phase_crossover_hz) * 2 * np.pi == pytest.approx(w180, rel=1e-5)
    else:
        assert np.isinf(ours.gain_margin)


def integrator_with_delay(K, T):
    loop = lambda p, s: p.K[..., None] * np.exp(-s * p.T[..., None]) / s  # noqa: E731
    p = SimpleNamespace(K=np.atleast_1d(np.asarray(K, float)),
                        T=np.atleast_1d(np.asarray(T, float)))
    p.shape = np.broadcast_shapes(p.K.shape, p.T.shape)
    return loop, p


def test_pure_delay_identities_vectorized():
    # Oracle: K e^{-sT}/s by hand: PM = 90 - K T deg, w_c = K, DM = pi/(2K) - T, GM = pi/(2
    # T K).
    K = np.array([1.0, 10.0, 50.0, 200.0])
    T = np.array([0.0, 0.01, 0.02, 0.005])
    loop, p = integrator_with_delay(K, T)
    m = loop_margins(loop, p, default_grid(K))
    np.testing.assert_allclose(m.phase_margin_deg, 90 - np.degrees(K * T), atol=1e-6)
    np.testing.assert_allclose(m.crossover_hz, K / (2 * np.pi), rtol=1e-9)
    np.testing.assert_allclose(m.delay_margin_s, np.pi / (2 * K) - T, rtol=1e-7)
    # phase crossover where w T = pi/2: gain margin w180 / K (none without delay)
    assert np.isinf(m.gain_margin[0])
    np.testing.assert_allclose(m.gain_margin[1:], np.pi / (2 * T[1:]) / K[1:], rtol=1e-7)
    assert m.stable.all()


def test_unstable_pure_delay_loop():
    # Oracle: K e^{-sT}/s is unstable for K T > pi/2 (analytic).
    loop, p = integrator_with_delay(10.0, 0.2)   # K T = 2 > pi/2
    m = loop_margins(loop, p, default_grid(10.0))
    assert not m.stable[0] and m.unstable_poles[0] >= 2
    assert m.phase_margin_deg[0] < 0 and m.delay_margin_s[0] == 0.0


def test_no_crossover_reported_explicitly():
    # Oracle: |L| > 1 on the whole grid by construction.
    loop, p = integrator_with_delay(1.0, 0.0)
    # grid entirely below the crossover: |L| > 1 everywhere on it
    m = loop_margins(lambda d, s: 1e-4 * loop(d, s), p, np.logspace(-6, -5, 50), max_depth=0)
    assert np.isinf(m.phase_margin_deg[0]) and np.isnan(m.crossover_hz[0])
    assert not m.has_crossover[0]


def test_delay_margin_is_the_stability_boundary():
    # Oracle: the definition of the delay margin: 2 % less extra delay is stable, 2 % more
    # is not, PM = 0 at it.
    d = sea(np.array([12.0, 16.0, 20.0]), 1.0, (0.5, 2.0, 0.5, 50.0, 100.0))
    m = sea_margins(d)
    dm = m.delay_margin_s
    # an equal extra delay on both outer-loop paths multiplies L by exp(-s tau)
    for factor, stable in ((0.98, True), (1.02, False)):
        extra = factor * dm
        t = Timing(0.0005, 0.002 + extra, 0.0005 + extra, 50.0, 100.0)
        shifted = sea_margins(SEADesign(A, d.gains, t))
        assert np.all(shifted.stable == stable)
    t = Timing(0.0005, 0.002 + dm, 0.0005 + dm, 50.0, 100.0)
    at = sea_margins(SEADesign(A, d.gains, t))
    np.testing.assert_allclose(at.phase_margin_deg, 0.0, atol=1e-6)


def simulate_sea(design, t_end=1.5, dt=2e-5):
    """Independent check: explicit fixed-step simulation of the physical equations with
    delay buffers (not derived from the block diagram). Returns q_j over time, (n, steps)."""
    p = design
    n = int(np.prod(p.shape))
    f = {k: np.broadcast_to(getattr(p, k), p.shape).reshape(n) for k in
         ("Kq", "Bq", "Ktau", "Btau", "T_tau", "T_qs", "T_qd", "Tf_qd", "Tf_taud")}
    steps = int(t_end / dt)
    lag = {k: np.maximum(np.round(f[k] / dt).astype(int), 0) for k in ("T_tau", "T_qs", "T_qd")}
    H = max(int(v.max()) for v in lag.values()) + 2
    hist_q, hist_v, hist_t = (np.zeros((H, n)) for _ in range(3))
    qm = np.zeros(n); vm = np.zeros(n); qj = np.zeros(n); vj = np.zeros(n)  # noqa: E702
    vf = np.zeros(n); ef = np.zeros(n)  # noqa: E702
    q_des = 1e-3
    cols = np.arange(n)
    out = np.empty((steps, n))
    for i in range(steps):
        tau_k = A.k * (qm - qj)
        h = i % H
        hist_q[h], hist_v[h], hist_t[h] = qj, vf, tau_k
        q_s = hist_q[(i - lag["T_qs"]) % H, cols]
        v_s = hist_v[(i - lag["T_qd"]) % H, cols]
        t_s = hist_t[(i - lag["T_tau"]) % H, cols]
        tau_des = f["Kq"] * (q_des - q_s) - f["Bq"] * v_s
        e = tau_des - t_s
        de = (e - ef) / f["Tf_taud"]            # filtered derivative s/(T s + 1) e
        i_m = tau_des / A.beta + f["Ktau"] * e + f["Btau"] * de
        am = (A.beta * i_m - A.bm * vm - tau_k) / A.Im
        aj = (tau_k - A.bj * vj) / A.Ij
        ef = ef + dt * de
        vf = vf + dt * (vj - vf) / f["Tf_qd"]
        vm, vj = vm + dt * am, vj + dt * aj
        qm, qj = qm + dt * vm, qj + dt * vj
        out[i] = qj
    return out.T / q_des


def test_nyquist_stability_agrees_with_time_domain_simulation():
    # Oracle: simulate_sea, an explicit simulation of the physical equations with delay
    # buffers.
    gs = np.array([1.0, 3.0, 1.0, 1.0])
    T_tau = np.array([0.5, 2.0, 0.5, 0.5]) * 1e-3
    T_qs = np.array([2.0, 0.0, 2.0, 2.0]) * 1e-3
    g = critically_damped_gains(A, 14.0, gs=gs)
    d0 = SEADesign(A, g, Timing(T_tau, T_qs, 0.5e-3, 50.0, 100.0))
    dm = sea_margins(d0).delay_margin_s
    # design 3: just inside its delay margin on the damping loop; design 4: beyond it
    T_qd = np.array([0.5e-3, 0.5e-3, 0.5e-3 + 0.6 * dm[2], 0.5e-3 + 1.6 * dm[3]])
    T_qs = T_qs + np.array([0, 0, 0.6 * dm[2], 1.6 * dm[3]])
    d = SEADesign(A, g, Timing(T_tau, T_qs, T_qd, 50.0, 100.0))
    m = sea_margins(d)
    # case 2 has a healthy-looking outer phase margin but an unstable inner torque loop
    assert m.phase_margin_deg[1] > 30 and m.unstable_poles[1] > 0
    y = simulate_sea(d)
    tail, early = np.abs(y[:, -5000:] - 1).max(axis=1), np.abs(y[:, 5000:10000] - 1).max(axis=1)
    sim_stable = np.isfinite(tail) & (tail < 0.5 * early + 1e-3) & (tail < 1.0)
    np.testing.assert_array_equal(m.stable, sim_stable)
    np.testing.assert_array_equal(m.stable, [True, False, True, False])


def test_subset_evaluation_matches_batch():
    # Oracle: the full batch's entries.
    d = sea(np.array([12.0, 14.0, 16.0]))
    s = 1j * np.array([5.0, 50.0])
    full = outer_loop()(d, s)
    sub = outer_loop()(DesignSubset(d, np.array([2, 0]), d.shape), s[None, :])
    np.testing.assert_allclose(sub, full[[2, 0]])


@pytest.mark.parametrize("per_decade", [12, 20, 30, 60])
def test_close_pair_of_crossings_is_found_on_any_grid(per_decade):
    """A pair of gain crossovers 2.5% apart (|L| rises just above 1 between two grid
    points) must be found whatever the grid density: compare with a brute-force scan."""
    d = SEADesign(A, critically_damped_gains(A, 38.88686974382624),
                  Timing(0.9065989727994375e-3, 7.399103319724809e-3, 2.743535449415269e-3,
                         50.0, 100.0))
    w = np.linspace(2 * np.pi * 5, 2 * np.pi * 200, 400_000)
    mag = np.abs(outer_loop()(d, 1j * w))
    idx = np.nonzero((mag[:-1] >= 1) != (mag[1:] >= 1))[0]
    assert idx.size == 3
    from seactl.systems.sea.views import sea_reference_frequency
    grid = default_grid(sea_reference_frequency(d), per_decade=per_decade)
    from seactl.systems.sea.loops import inner_loop
    inner = loop_margins(inner_loop(), d, grid, stability_only=True)
    m = loop_margins(outer_loop(), d, grid, open_loop_rhp_poles=inner.unstable_poles)
    # the brute-force grid spacing is 0.003 rad/s (2e-5 relative at the first crossing)
    np.testing.assert_allclose(np.sort(m.gain_crossovers.omega), w[idx], rtol=3e-5)


def test_compiled_scan_evaluates_the_quasi_polynomial_like_numpy():
    """The certified scan's compiled kernel (seactl.certify.scan) against the numpy Horner
    pass of QuasiPolynomial.with_derivative (oracle) on random designs and frequencies:
    Q(jw), dQ/dw = j dQ/ds and d2Q/dw2 = -d2Q/ds2, L = N / D and Delta = N + D."""
    from seactl.certify import scan as _certify

    d = sea(np.linspace(10, 40, 7), ms=(np.linspace(0.5, 3, 7), 8.0, 1.5, 50.0, 100.0))
    N, D = (f.evaluate(d).flat() for f in
            outer_loop().diagram.return_difference(outer_loop().input, outer_loop().cut))
    w = np.geomspace(0.3, 3e4, 7)
    for q in (N, D):
        ref = q.with_derivative(1j * w[:, None], second=True)
        for i in range(7):
            got = _certify._eval(_certify.descending(q.coeffs), q.delays, i, w[i], 2)
            np.testing.assert_allclose(got[0], ref[0][i, 0], rtol=1e-12)
            np.testing.assert_allclose(got[1], 1j * ref[1][i, 0], rtol=1e-12)
            np.testing.assert_allclose(got[2], -ref[2][i, 0], rtol=1e-12)
    L = _certify.loop_values(_certify.descending(N.coeffs), N.delays,
                             _certify.descending(D.coeffs), D.delays, np.arange(7), w)
    np.testing.assert_allclose(L, N(1j * w[:, None])[:, 0] / D(1j * w[:, None])[:, 0],
                               rtol=1e-12)
    delta = _certify.delta_values(_certify.descending(N.coeffs), N.delays,
                                  _certify.descending(D.coeffs), D.delays, w)
    np.testing.assert_allclose(delta, (N + D)(1j * w[:, None])[:, 0], rtol=1e-12)


def test_compiled_evaluation_with_more_delay_terms_than_a_phasor_call():
    """The kernels compute delay phasors four at a time (seactl.certify.vecmath.cis4): random
    quasi-polynomials with 5 terms in N and 4 in D (three and two calls) against the
    numpy Horner pass (oracle), through the single evaluation (derivatives), the pair
    (loop_values, delta_values) and the scan's point (N, D and their derivatives' moduli)."""
    from seactl.certify import scan as _certify
    from seactl.diagram.blockdiagram import QuasiPolynomial

    rng = np.random.default_rng(5)
    n = 6

    def random_q(terms, powers):
        delays = rng.uniform(1e-3, 2e-2, (terms, n))
        delays[0] = 0.0  # (undelayed first, as the diagrams give them)
        delays[2, :2] = 0.0  # (a term without delay for some designs)
        return QuasiPolynomial(rng.normal(size=(terms, n, powers)), delays)

    N, D = random_q(5, 3), random_q(4, 6)
    w = rng.uniform(0.5, 400.0, n)
    arrays = (*(_certify.descending(q.coeffs) for q in (N, D)),)
    Nc, Dc = arrays
    for q, c in ((N, Nc), (D, Dc)):
        ref = q.with_derivative(1j * w[:, None], second=True)
        got = _certify.derivatives(c, q.delays, np.arange(n), w)
        for k, sign in enumerate((1, 1j, -1)):
            np.testing.assert_allclose(got[:, k], sign * ref[k][:, 0], rtol=1e-12)
    L = _certify.loop_values(Nc, N.delays, Dc, D.delays, np.arange(n), w)
    np.testing.assert_allclose(L, N(1j * w[:, None])[:, 0] / D(1j * w[:, None])[:, 0],
                               rtol=1e-12)
    np.testing.assert_allclose(_certify.delta_values(Nc, N.delays, Dc, D.delays, w),
                               (N + D)(1j * w[:, None])[:, 0], rtol=1e-12)
    P = np.empty((1, _certify._F))
    bounds = np.zeros((n, 3, 1))
    refN, refD = (q.with_derivative(1j * w[:, None], second=True) for q in (N, D))
    for i in range(n):
        _certify._point(P, 0, w[i], Nc, N.delays, Dc, D.delays, bounds, i)
        np.testing.assert_allclose(P[0, _certify.RE_N] + 1j * P[0, _certify.IM_N],
                                   refN[0][i, 0], rtol=1e-12)
        np.testing.assert_allclose(P[0, _certify.RE_D] + 1j * P[0, _certify.IM_D],
                                   refD[0][i, 0], rtol=1e-12)
        np.testing.assert_allclose(P[0, [_certify.A_DN, _certify.A_DD, _certify.CN,
                                         _certify.CD]],
                                   np.abs([refN[1][i, 0], refD[1][i, 0], refN[2][i, 0],
                                           refD[2][i, 0]]), rtol=1e-12)


@pytest.mark.slow  # (compiles its own kernel around _point and _points4: tens of seconds)
def test_base_grid_points_four_at_a_time_are_the_single_points_bits():
    """The scan evaluates its base grid four points at a time (vector operations across
    the points, ``_certify._points4``): every column of every row the bits of the single
    point (``_point``, itself checked against numpy above), batches of 1 to 4 points.
    Oracle: ``_point`` on the benchmark's SEA loop (2,000 designs) and on random
    quasi-polynomials with 5 and 4 terms (grouped phasors), frequencies over 8 decades,
    a zero frequency and coefficients with NaN and infinities among them."""
    from numba import njit

    from seactl.apps.bench.core import random_designs
    from seactl.certify import scan as _certify
    from seactl.certify.vecmath import v4
    from seactl.diagram.blockdiagram import QuasiPolynomial, padded_sum, rounding_majorant

    point, points4 = _certify._point, _certify._points4

    @njit(error_model="numpy")  # (the kernels' division semantics, inlined here)
    def both_ways(P1, P4, ws, Nc, Nt, Dc, Dt, bounds):
        for d in range(ws.shape[0]):
            for k in range(4):
                point(P1, 4 * d + k, ws[d, k], Nc, Nt, Dc, Dt, bounds, d)
            count = 1 + d % 4  # (a batch of 1 to 4 points, the spare lanes repeating one)
            w = v4(ws[d, 0], ws[d, min(1, count - 1)], ws[d, min(2, count - 1)],
                   ws[d, min(3, count - 1)])
            points4(P4, 4 * d, count, w, Nc, Nt, Dc, Dt, bounds, d)

    rng = np.random.default_rng(23)
    _, d = random_designs(2000, seed=3)
    loop = outer_loop()
    sea = (f.evaluate(d).flat() for f in loop.diagram.return_difference(loop.input, loop.cut))
    n = 300
    delays = rng.uniform(1e-3, 2e-2, (9, n))
    delays[[0, 5]] = 0.0
    c = rng.normal(size=(9, n, 6)) * 10.0 ** rng.uniform(-3, 3, (9, n, 1))
    c.flat[rng.integers(0, c.size, 20)] = [np.nan, np.inf, -np.inf, 0.0] * 5
    rand = QuasiPolynomial(c[:5], delays[:5]), QuasiPolynomial(c[5:, :, :4], delays[5:])
    for N, D in (tuple(sea), rand):
        m = N.shape[0]
        tau = np.concatenate([N.delays, D.delays]).max(axis=0)
        bounds = _certify.bound_table(rounding_majorant(padded_sum(N.abs_coeffs, D.abs_coeffs),
                                                        tau), N.bound3_coeffs, D.bound3_coeffs)
        ws = 10.0 ** rng.uniform(-2, 6, (m, 4))
        ws[0, 0] = 0.0
        P1, P4 = (np.full((4 * m, _certify._F), -1.0) for _ in range(2))
        both_ways(P1, P4, ws, *_certify.compact(N), *_certify.compact(D), bounds)
        filled = (np.arange(4 * m) % 4) < 1 + (np.arange(4 * m) // 4) % 4
        np.testing.assert_array_equal(P4[filled].view(np.int64), P1[filled].view(np.int64))
        assert (P4[~filled] == -1.0).all()


@pytest.mark.parametrize("delay_s", [0.0, 0.01])
def test_a_root_on_the_axis_is_never_counted_certain(delay_s):
    """Oracle: by construction Q(s) = (s^2 + 100)(s + 1) + 0 * e^{-s tau} has roots
    +-10j on the imaginary axis; bisection cannot certify the interval around w = 10,
    so the count is reported uncertain (a design with it is never called stable), while
    Q(s) = (s + 1)^3 + 0.5 e^{-s tau} (roots in the left half-plane) is certain, Z = 0."""
    from seactl.analysis.margins import count_right_roots
    from seactl.diagram.blockdiagram import QuasiPolynomial

    def q(undelayed, delayed):
        c = np.array([undelayed, delayed], float)[:, None, :]
        return QuasiPolynomial(c, np.array([[0.0], [delay_s]]))

    Z, certain = count_right_roots(q([100, 100, 1, 1], [0, 0, 0, 0]), np.array([10.0]))
    assert not certain[0]
    Z, certain = count_right_roots(q([1, 3, 3, 1], [0.5, 0, 0, 0]), np.array([1.0]))
    assert certain[0] and Z[0] == 0


def test_the_root_count_takes_its_tail_where_the_scan_ends():
    """Stepan's count adds the winding of ``Delta`` up to where the scan's grid ends and
    the tail beyond it; the grid ends at the Cauchy radius ``R`` or, where the frequency
    scale puts its start a decade above ``R``, further out (the tail was taken at ``R``
    all the same, which counted the turn between the two twice: 405 of 30,000 such counts
    came out uncertain).  Oracles: for ``s^2 + 0.0488 s + 15.7 + 5.42 e^{-0.0437 s}``, the
    winding of ``Delta`` unwrapped by numpy on 4 million points up to ``1e4 R`` (two roots
    right of the axis); for 400 random quasi-polynomials with lightly damped or unstable
    pairs and up to four delays, the count whose grid ends at ``R`` itself."""
    from seactl.analysis.margins import cauchy_bound, count_right_roots
    from seactl.diagram.blockdiagram import QuasiPolynomial

    c = np.array([[[15.70403196, 0.04881618, 1.0]], [[5.42092207, 0.0, 0.0]]])
    q = QuasiPolynomial(c, np.array([[0.0], [0.04370939237311953]]))
    R = cauchy_bound(q)[0]
    w = np.linspace(0.0, 1e4 * R, 4_000_001)
    phase = np.unwrap(np.angle(q(1j * w[None, :])[0]))
    tail = -np.angle(q(1j * w[None, -1:])[0, 0] / (1j * w[-1]) ** 2)
    assert round(1.0 - (phase[-1] - phase[0] + tail) / np.pi) == 2
    for scale in (1.0, 100.0, 1000.0):
        Z, certain = count_right_roots(q, np.array([scale * R]))
        assert certain[0] and Z[0] == 2, scale

    rng = np.random.default_rng(7)
    n, deg = 400, 4
    c = np.zeros((4, n, deg + 1))
    for i in range(n):
        wn, zeta = 10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-3, 0) * rng.choice([1, -1])
        pair = [1, 2 * zeta * wn, wn * wn]
        c[0, i] = np.polymul(pair, np.poly(-10 ** rng.uniform(-2, 1, 2)))[::-1]
    c[1:, :, :deg] = rng.normal(size=(3, n, deg)) * 10 ** rng.uniform(-2, 0.5, (3, n, deg))
    q = QuasiPolynomial(c, np.r_[np.zeros((1, n)), rng.uniform(0, 0.3, (3, n))])
    R = cauchy_bound(q)
    Z_ref, certain_ref = count_right_roots(q, R)  # (the grid from 0.01 R ends at R)
    assert certain_ref.sum() > 350 and Z_ref.max() >= 2
    for f in (1.02, 1.3, 5.0):  # the grid's end f R beyond the radius
        Z, certain = count_right_roots(q, 10 * f * R)
        np.testing.assert_array_equal(certain[certain_ref], True)
        np.testing.assert_array_equal(Z[certain_ref], Z_ref[certain_ref])


@pytest.mark.parametrize("fn,ms", [
    # |L| near 1: the phase dips 0.5-2.3 deg below -180 between crossings 3-6 Hz apart
    (23.952, (0.9177, np.array([13.05, 13.1, 13.2, 13.3, 13.5]), 1.3246, 50.0, 100.0)),
    # |L| = 0.23, far from 1, so only the phase certificate asks for these intervals to
    # be bisected: dips of 0.39, 0.49, 0.60 deg
    (38.59, (0.5925, np.array([7.81, 7.815, 7.82]), 1.76, 50.0, 100.0)),
])
def test_grazing_phase_crossings_are_found(fn, ms):
    """Hard designs: pairs of phase crossovers whose phase between them dips below
    -180 deg by less than a degree.  Oracle: a brute-force scan of 200,000 points for
    the crossings, and 1/|L| there for the gain margin."""
    d = sea(fn, ms=ms)
    w = 2 * np.pi * np.linspace(5.0, 100.0, 200_000)
    L = outer_loop()(d, 1j * w)
    ph = np.angle(-L)
    m = sea_margins(d)
    for i in range(ms[1].size):
        cross = np.nonzero((np.signbit(ph[i, 1:]) != np.signbit(ph[i, :-1]))
                           & (L[i, 1:].real < 0))[0]
        assert cross.size >= 2
        mine = m.phase_crossovers.omega[m.phase_crossovers.design == i]
        # (grid spacing 0.003 rad/s, 3e-5 of the first crossing)
        np.testing.assert_allclose(np.sort(mine[mine < w[-1]]), w[cross], rtol=1e-4)
        gm = 1 / np.abs(L[i, cross])
        assert m.gain_margin[i] == pytest.approx(gm[np.argmin(np.abs(np.log(gm)))], rel=1e-4)


@pytest.mark.parametrize("T_qs_ms,crosses", [(12.933073537599071, True),
                                              (12.933070608731416, False)])
def test_a_phase_that_touches_minus_180_is_resolved_without_tolerance(T_qs_ms, crosses):
    """Hard designs: T_qs tuned so that the phase's extremum near 16.09 Hz, at |L| = 0.88,
    goes 1e-7 rad (6e-6 deg) beyond -180 deg (two crossovers 0.011 Hz apart) or stops
    1e-7 rad short of it.  The scan once accepted such a pair as hidden within a
    tolerance and reported the gain margin of the next crossover, 1.93 instead of 1.14 (a
    design of this family with a 0.022 deg dip turned up among random ones).  Oracle: a
    brute-force scan (1e-6 Hz steps around the extremum) for the crossings, and 1/|L|
    there for the gain margin."""
    d = sea(23.952070321569646, ms=(0.9177374392596417, np.array([T_qs_ms]),
                                    1.3246488009392563, 50.0, 100.0))
    w = 2 * np.pi * np.concatenate([np.linspace(5.0, 15.9, 100_000),
                                    np.linspace(15.9, 16.3, 400_001)[1:],
                                    np.linspace(16.3, 100.0, 100_000)[1:]])
    L = outer_loop()(d, 1j * w)[0]
    ph = np.angle(-L)
    cross = np.nonzero((np.signbit(ph[1:]) != np.signbit(ph[:-1])) & (L[1:].real < 0))[0]
    near = (w[cross] > 2 * np.pi * 15.9) & (w[cross] < 2 * np.pi * 16.3)
    assert near.sum() == (2 if crosses else 0)  # the oracle sees the design as intended
    t = ph[cross] / (ph[cross] - ph[cross + 1])  # (linear between the samples)
    m = sea_margins(d)
    mine = m.phase_crossovers.omega
    np.testing.assert_allclose(np.sort(mine[mine < w[-1]]),
                               w[cross] + t * (w[cross + 1] - w[cross]), rtol=1e-7)
    gm = 1 / ((1 - t) * np.abs(L[cross]) + t * np.abs(L[cross + 1]))
    assert m.gain_margin[0] == pytest.approx(gm[np.argmin(np.abs(np.log(gm)))], rel=1e-6)


@pytest.mark.parametrize("w_ref", [1.0, 1.3])
def test_a_phase_tangent_to_minus_180_counts_as_a_crossover(w_ref):
    """L(jw) = -0.5 + 0.1 j w (w^2 - 1)^2 (N = -0.5 + 0.1 s + 0.2 s^3 + 0.1 s^5, D = 1)
    touches the negative real axis at w = 1 without crossing it: no bound tells that from
    a pair of crossings, so the bisection ends at its limit there and the touch counts as
    a phase crossover (a gain margin of 2, never "none").  Oracle: the formula (Im L >= 0,
    zero only at w = 1, where L = -0.5); with and without w = 1 on the base grid."""
    from seactl.analysis import margins as M
    from seactl.diagram.blockdiagram import QuasiPolynomial

    N = QuasiPolynomial(np.array([[[-0.5, 0.1, 0, 0.2, 0, 0.1]]]), np.zeros((1, 1)))
    D = QuasiPolynomial(np.array([[[1.0, 0, 0, 0, 0, 0]]]), np.zeros((1, 1)))
    w = np.linspace(0.5, 5, 90_001)  # (the formula's other zero, w = 0, left out)
    L = N(1j * w[:, None])[:, 0] / D(1j * w[:, None])[:, 0]
    assert L.imag.min() >= 0 and w[np.argmin(L.imag)] == pytest.approx(1.0, abs=1e-4)
    scan = M._CertifiedScan(N, D, False)
    top = M.cauchy_bound(N + D, M.padded_sum(20 * N.abs_coeffs, D.abs_coeffs))
    scan.run(np.array([w_ref]), np.zeros(1), top)
    b, w180 = scan.solve("phase")
    assert b.tolist() == [0] and w180[0] == pytest.approx(1.0, rel=1e-12)
    assert scan.loop_at(b, w180)[0] == pytest.approx(-0.5, rel=1e-12)
    assert not scan.uncertain[0]


def test_compiled_row_polynomials_are_numpys_polyval_bit_for_bit():
    """The proofs' bound polynomials (seactl.certify.scan.horner_rows, per row and point).
    Oracle: numpy's polyval on the same rows, the same bits (infinite and NaN points
    included)."""
    from numpy.polynomial.polynomial import polyval

    from seactl.certify.scan import horner_rows

    rng = np.random.default_rng(23)
    for powers in (1, 3, 8):
        c = rng.normal(size=(50, powers)) * 10.0 ** rng.uniform(-6, 6, (50, powers))
        idx = rng.integers(0, 50, 4000)
        w = 10.0 ** rng.uniform(-3, 5, 4000)
        w[:3] = np.inf, np.nan, 0.0
        with np.errstate(all="ignore"):
            ref = polyval(w, c[idx].T, tensor=False)
        np.testing.assert_array_equal(horner_rows(c, idx, w), ref)


def test_cauchy_bound_is_the_tightest_dominance_radius():
    """Beyond ``R`` the leading term outweighs all others together, and ``R / 1.01`` is
    never below the one positive root of ``|a_n| x^n - sum_{j<n} c_j x^j``
    (``c_j = sum_k |c_kj|``), the tightest such radius, nor above Fujiwara's bound where
    its Newton iteration starts (at most twice the root).  Oracle: numpy's polynomial
    roots, on 400 random quasi-polynomials of degree 1 to 7 with three delay terms and
    coefficients spread over ten decades; of degree 2 to 5 the 8 Newton steps come within
    1e-6 of the root (of degree 1 and 6-7 they may stop further above it: a longer grid,
    never a skipped root)."""
    from seactl.analysis import margins as M
    from seactl.diagram.blockdiagram import QuasiPolynomial

    rng = np.random.default_rng(17)
    n_designs, powers = 400, 8
    coeffs = rng.normal(size=(3, n_designs, powers)) * 10.0 ** rng.uniform(-5, 5, (3, 1, powers))
    degree = rng.integers(1, powers, n_designs)
    coeffs[:, np.arange(powers)[None, :] > degree[:, None]] = 0.0
    coeffs[1:, np.arange(n_designs), degree] = 0.0  # (retarded: delayed terms lower)
    q = QuasiPolynomial(coeffs, rng.uniform(0.0, 0.01, (3, n_designs)))
    R = M.cauchy_bound(q)
    c = np.abs(coeffs).sum(axis=0)
    excess = np.empty(n_designs)
    for i in range(n_designs):
        p = -c[i, :degree[i] + 1].copy()
        p[-1] = abs(coeffs[0, i, degree[i]])
        positive = [r.real for r in np.roots(p[::-1]) if abs(r.imag) < 1e-9 and r.real > 0]
        assert len(positive) == 1
        excess[i] = R[i] / (1.01 * positive[0]) - 1
    assert excess.min() >= -1e-12 and excess.max() <= 1 + 1e-12
    mid = (degree >= 2) & (degree <= 5)
    assert mid.sum() > 200 and excess[mid].max() < 1e-6


@pytest.mark.parametrize("a,b,gap", [
    (3 + 4j, 3 + 4j, 5.0),        # a point
    (1 - 1j, 1 + 1j, 1.0),        # foot of the perpendicular inside the segment
    (2 + 1j, 5 + 1j, np.sqrt(5)),  # the nearer end
    (-1 - 1j, 1 + 1j, 0.0),       # through 0
    (1e-200 + 1j, 1e-200 - 1j, 1e-200),  # (no underflow)
])
def test_chord_gap_is_the_distance_from_zero_to_the_segment(a, b, gap):
    """The tube certificate's distance; oracle: elementary geometry."""
    from seactl.certify import scan as _certify

    assert _certify._gap(a.real, a.imag, b.real, b.imag) == pytest.approx(gap, rel=1e-12)
    assert _certify._gap(b.real, b.imag, a.real, a.imag) == pytest.approx(gap, rel=1e-12)


def test_cut_crossings_add_up_to_the_principal_turns():
    """The scan's winding counts crossings of the negative real axis instead of taking an
    arctangent per point; oracle: the principal turn from ``a`` to ``b`` (difference of
    numpy's ``angle`` wrapped to ``[-pi, pi]``), on 20,000 random pairs whose turn is
    under half a turn by at least 1e-6 (as certified intervals' are), and on pairs on
    the real axis with either sign of zero (where atan2's convention decides)."""
    from seactl.certify import scan as _certify

    rng = np.random.default_rng(11)
    a = rng.normal(size=20_000) + 1j * rng.normal(size=20_000)
    turn = rng.uniform(-np.pi + 1e-6, np.pi - 1e-6, a.size)
    b = a * np.exp(1j * turn) * rng.uniform(0.01, 100.0, a.size)
    axis = np.array([complex(re, im) for re in (-2.0, -1e-300, 3.0) for im in (0.0, -0.0)]
                    + [-1 + 1e-300j, -1 - 1e-300j])
    pairs = [(x, y) for x, y in zip(a, b)] + [(x, y) for x in axis for y in axis]
    pairs += [(x, y) for x in axis for y in (-1 + 1j, -1 - 1j, 1 + 1j, 1 - 1j)]
    pairs += [(y, x) for x, y in pairs[-len(axis) * 4:]]
    assert sum(_certify._cut_turns(x.real, x.imag, y.real, y.imag) != 0 for x, y in pairs) > 2000
    for x, y in pairs:
        d = np.arctan2(y.imag, y.real) - np.arctan2(x.imag, x.real)
        principal = d - 2 * np.pi * np.round(d / (2 * np.pi))
        c = _certify._cut_turns(x.real, x.imag, y.real, y.imag)
        assert d + 2 * np.pi * c == pytest.approx(principal, abs=1e-12), (x, y)


def test_compiled_crossing_solver_agrees_with_scipy():
    """The certified scan solves its brackets by a compiled safeguarded Newton; oracle:
    scipy's bracketing solver (Chandrupatla, ``elementwise.find_root``) on the same
    brackets and the same loop values."""
    from seactl.analysis import margins as M
    from seactl.apps.bench.core import random_designs

    _, d = random_designs(300, seed=7)
    loop = outer_loop()
    N, D = (f.evaluate(d).flat() for f in loop.diagram.return_difference(loop.input, loop.cut))
    scan = M._CertifiedScan(N, D, False)
    top = M.cauchy_bound(N + D, M.padded_sum(N.abs_coeffs, D.abs_coeffs))
    tau = np.concatenate([N.delays, D.delays]).max(axis=0)
    scan.run(np.full(300, 100.0), tau, top)
    for kind, code in (("gain", 0), ("phase", 1)):
        rows = scan.rows[scan.rows[:, 1] == code]
        assert len(rows) > 100
        b, w = scan.solve(kind)
        ref = M._refine(scan.loop_at, rows[:, 0].astype(int), rows[:, 2], rows[:, 3], kind)
        np.testing.assert_array_equal(b, rows[:, 0])
        np.testing.assert_allclose(w, ref, rtol=1e-10)


def test_tube_turn_contains_the_turn_of_every_path_in_the_tube():
    """The phase certificate's lemma: a path within ``r`` of the chord between its ends
    (``r = h^2/8 sup |Q''|``), the chord ``g > r`` away from 0, turns by no more than the
    chord's span widened by ``asin(r/g)``.  Oracle: 4,000 random smooth paths (a quadratic
    plus a fast oscillation, so ``sup |Q''|`` has a closed form), their turn unwrapped
    on 20,001 points; paths whose tube may reach 0 get no bound."""
    from seactl.certify import scan as _certify

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 20_001)
    bounded = 0
    for _ in range(4000):
        p = rng.normal(size=(4, 2)) @ np.array([1.0, 1j])
        k = rng.uniform(0.5, 12.0)
        p[1:] *= rng.uniform(0.01, 3.0)
        p[0] *= rng.uniform(1.0, 4.0)
        q = p[0] + p[1] * t + p[2] * t**2 + p[3] * np.sin(k * t)
        r = 0.125 * (2 * abs(p[2]) + abs(p[3]) * k * k)  # h = 1
        g = _certify._gap(q[0].real, q[0].imag, q[-1].real, q[-1].imag)
        lo, hi = _certify._tube_turn(q[0].real, q[0].imag, q[-1].real, q[-1].imag, g, r)
        if not g > r:
            assert (lo, hi) == (-np.inf, np.inf)
            continue
        bounded += 1
        turn = np.unwrap(np.angle(q / q[0]))
        assert lo <= turn.min() + 1e-12 and turn.max() - 1e-12 <= hi
    assert bounded > 1000


@pytest.mark.parametrize("kind,num,num_delayed,den", [
    # coefficients ascending; the delayed part of N has delay 3 ms
    ("strictly proper", [40.0, 3.0], [5.0, 0.0], [0.0, 2.0, 0.05, 1e-4]),
    ("biproper", [2.0, 0.9999], [0.5, 0.0], [1.0, 1.0]),
    ("biproper, negative", [-1e4, -30.0], [100.0, 0.0], [1.0, 1.0]),
    ("improper", [2.0, 3.0, 1.0], [1.0, 0.0, 0.0], [10.0, 1.0, 0.0]),
])
def test_beyond_the_scan_radius_no_crossing_is_possible(kind, num, num_delayed, den):
    """Step 4 of the certified scan: beyond its radius ``R`` the loop is off the unit
    circle and off the band's phase crossovers (strictly proper: ``|L| < 0.05``,
    improper: ``|L| > 20``, biproper: ``|L - L_inf| < eps``), and ``Delta``'s leading
    term dominates.  A biproper ``L = (0.9999 s + 2)/(s + 1)`` once had its gain crossover
    at 122 rad/s beyond ``R`` (20 rad/s, a radius for ``|L| < 0.05``) and was reported
    with no crossover and an infinite delay margin (true: 25.6 ms).  Oracle: ``L`` and
    ``Delta`` evaluated on 20,001 points from ``R`` to ``10^4 R``."""
    from seactl.analysis import margins as M
    from seactl.diagram.blockdiagram import QuasiPolynomial

    def qp(terms, delays):
        width = max(len(t) for t in terms)
        c = np.array([np.pad(t, (0, width - len(t))) for t in terms], float)[:, None, :]
        return QuasiPolynomial(c, np.array(delays, float)[:, None])

    N, D = qp([num, num_delayed], [0.0, 3e-3]), qp([den], [0.0])
    top, unresolved = M._scan_radius(N, D, N + D, False, lambda r: np.zeros_like(r))
    assert not unresolved[0]
    s = 1j * top[0] * np.logspace(0, 4, 20_001)[None, :]
    L = N(s)[0] / D(s)[0]
    on_circle = np.diff(np.sign(np.abs(L) - 1.0)) != 0
    in_band = (np.abs(L) > 0.05) & (np.abs(L) < 20)
    on_axis = np.diff(np.sign(L.imag)) != 0
    assert not on_circle.any()
    assert not (on_axis & (L.real[1:] < 0) & in_band[1:]).any()
    delta = N + D
    n = int(delta.degree[0])
    lead = delta.coeffs[0, 0, n] * s[0] ** n
    assert np.all(np.abs(delta(s)[0] - lead) < np.abs(lead))


def test_margins_split_over_threads_are_the_one_thread_margins(monkeypatch):
    """A batch is scanned in one thread per core, each on its own designs.  Oracle: the
    same batch in one thread, bit for bit, crossings included (400 random designs, delays
    up to 20 ms)."""
    from seactl.apps.bench.core import random_designs
    from seactl.base import parallel as _parallel

    _, d = random_designs(400, seed=11)
    monkeypatch.setattr(_parallel, "THREADS", 1)
    one = sea_margins(d)
    monkeypatch.setattr(_parallel, "THREADS", 3)
    assert len(_parallel.parts(400, 32)) == 3
    parts = sea_margins(d)
    for name in ("phase_margin_deg", "crossover_hz", "gain_margin", "delay_margin_s",
                 "stable", "unstable_poles"):
        np.testing.assert_array_equal(getattr(parts, name), getattr(one, name))
    for c in ("gain_crossovers", "phase_crossovers"):
        np.testing.assert_array_equal(getattr(parts, c).design, getattr(one, c).design)
        np.testing.assert_array_equal(getattr(parts, c).omega, getattr(one, c).omega)


def test_threads_follow_seactl_threads_and_refuse_a_bad_value(monkeypatch, capsys):
    """``SEACTL_THREADS`` caps the threads of a batch; a bad value is one error naming it.
    Oracle: the parts of a 1000-design batch, and the CLI's exit status and line."""
    from seactl.apps.cli import main
    from seactl.base import parallel as _parallel
    from seactl.errors import InputError

    monkeypatch.setattr(_parallel, "THREADS", None)
    monkeypatch.setenv("SEACTL_THREADS", "1")
    assert _parallel.parts(1000, 32) == [slice(0, 1000)]
    monkeypatch.setenv("SEACTL_THREADS", "4")
    assert len(_parallel.parts(1000, 32)) == 4 and len(_parallel.parts(100, 32)) == 3
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv("SEACTL_THREADS", bad)
        with pytest.raises(InputError, match="SEACTL_THREADS"):
            _parallel.parts(1000, 32)
    assert main(["latency-map", "--n", "12"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: invalid SEACTL_THREADS = '-1'") and "\n" not in err


@pytest.mark.parametrize("seed", range(4))
def test_first_per_design_is_the_minimum_of_a_stable_sort(seed):
    """The linear-time path (sorted groups) and the general one pick, per group, the
    index of the smallest key, the first among equal ones (0.0 and -0.0 equal), NaN only
    where the group has nothing else.  Oracle: numpy's stable lexsort."""
    from seactl.analysis.margins import first_per_design

    rng = np.random.default_rng(seed)
    for _ in range(500):
        n = int(rng.integers(0, 30))
        groups = rng.integers(0, 6, n)
        if seed % 2 == 0:
            groups = np.sort(groups)
        key = rng.choice([0.0, -0.0, 1.0, 2.0, np.nan, np.inf, -np.inf], n)
        order = np.lexsort((key, groups))
        g = groups[order]
        expected = order[np.r_[True, g[1:] != g[:-1]]] if n else order
        np.testing.assert_array_equal(first_per_design(groups, key), expected)


@pytest.mark.parametrize("w_lo,tau,top", [(0.1, 0.0, 1e4), (0.5, 0.02, 3000.0),
                                          (2.0, 1e-3, 1e7), (1.0, 0.5, 11.0)])
def test_the_base_grid_keeps_its_spacing(w_lo, tau, top):
    """The scan's base grid: 0, then increasing points from ``w_lo`` to ``top`` whose
    ratio never exceeds ``10^(1 / PER_DECADE)`` and whose steps never exceed
    ``TURN_FRACTION`` of a turn of the delay; the count
    estimate used for budgets is exact or one too many.  Oracle: the two rules, checked
    point by point; and the same points, bit for bit, from a table of 8 powers (the rest
    computed) as from the full table."""
    from seactl.analysis import margins as M
    from seactl.certify import scan as _certify

    w_lo_, step, top_ = (float(x[0]) for x in M._base_grid(np.array([100 * w_lo]),
                                                           np.array([tau]), np.array([top])))

    def grid(powers):
        k, base, m, w, pts = 0, 0.0, 0, 0.0, [0.0]
        while w < top_:
            w, k, base, m = _certify.grid_point(w_lo_, M.PER_DECADE, powers, step, top_, k,
                                                base, m)
            pts.append(w)
        return pts

    pts = grid(_certify.decade_powers(M.PER_DECADE))
    assert grid(_certify.decade_powers(M.PER_DECADE, 8)) == pts
    p = np.array(pts[1:])
    assert p[0] == w_lo and p[-1] == top and (np.diff(p) > 0).all()
    ratio_ok = p[1:] / p[:-1] <= 10 ** (1 / M.PER_DECADE) * (1 + 1e-12)
    step_ok = np.diff(p) <= 2 * np.pi * M.TURN_FRACTION / tau * (1 + 1e-12) if tau else True
    assert (ratio_ok & step_ok).all()
    count = M._base_grid_count(np.array([100 * w_lo]), np.array([tau]), np.array([top]))[0]
    assert count - len(pts) in (0, 1)


def test_the_newton_start_is_the_root_of_the_hermite_cubic():
    """The crossing solver starts from the root of the cubic matching a bracket's end
    values and slopes; on a cubic with one root in the bracket that is the root itself.
    Oracle: numpy's polynomial roots; without slopes (NaN), the regula falsi point."""
    from seactl.certify.scan import _hermite_root

    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(2000):
        c = rng.normal(size=4)
        xl, xr = sorted(rng.uniform(-2, 2, 2))
        f, df = np.poly1d(c), np.poly1d(c).deriv()
        inside = [r.real for r in np.roots(c) if abs(r.imag) < 1e-12 and xl < r.real < xr]
        if len(inside) != 1 or f(xl) * f(xr) >= 0:
            continue
        x = _hermite_root(xl, xr, f(xl), f(xr), df(xl), df(xr))
        assert xl < x < xr
        if abs(df(inside[0])) > 0.1 * np.abs(c).sum():  # (a well-conditioned root)
            assert x == pytest.approx(inside[0], abs=1e-9)
            checked += 1
    assert checked > 300
    x = _hermite_root(0.0, 2.0, -1.0, 3.0, np.nan, np.nan)
    assert x == pytest.approx(0.5, abs=1e-15)


def test_a_design_without_a_usable_grid_is_never_stable():
    """A design whose base grid cannot be made (here a NaN radius) is not reported: it is
    uncertain, so never stable, and has no crossing, while its twin in the batch is
    scanned as usual; a frequency scale that is not positive is refused by name.  Oracle:
    ``L = 2 / (s (s + 1))``, whose gain crossover solves ``w^4 + w^2 = 4`` (1.25 rad/s),
    and Table I's 12 Hz design (PM 45.1 deg)."""
    from seactl.analysis import margins as M
    from seactl.diagram.blockdiagram import QuasiPolynomial
    from seactl.errors import InputError

    N = QuasiPolynomial(np.array([[[2.0, 0, 0], [2.0, 0, 0]]]), np.zeros((1, 2)))
    D = QuasiPolynomial(np.array([[[0.0, 1, 1], [0.0, 1, 1]]]), np.zeros((1, 2)))
    scan = M._CertifiedScan(N, D, False)
    scan.run(np.full(2, 1.0), np.zeros(2), np.array([100.0, np.nan]))
    assert scan.uncertain.tolist() == [False, True]
    b, wc = scan.solve("gain")
    assert b.tolist() == [0] and wc[0] == pytest.approx(np.sqrt((np.sqrt(17) - 1) / 2))
    loop = outer_loop()
    assert float(M.certified_margins(loop, sea(12.0), 100.0).phase_margin_deg) == \
        pytest.approx(45.1, abs=0.1)
    for w_ref in (0.0, np.nan):
        with pytest.raises(InputError, match="w_ref"):
            M.certified_margins(loop, sea(12.0), w_ref)


def test_closed_loop_right_roots_equal_the_nyquist_count():
    # Oracle: two derivations of the same count on 600 broad SEA designs (most of them
    # unstable): Nyquist on the outer loop plus the inner loop's own right-half-plane
    # roots (sea_margins), and the whole diagram's characteristic quasi-polynomial.
    from seactl.analysis.margins import closed_loop_right_roots
    from seactl.systems.sea.loops import SEA_DIAGRAM
    from seactl.systems.sea.views import sea_reference_frequency

    rng = np.random.default_rng(4)
    n = 600
    t = Timing.from_ms(rng.uniform(0, 3, n), rng.uniform(0, 25, n), rng.uniform(0, 8, n),
                       rng.uniform(10, 300, n), rng.uniform(10, 400, n))
    d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, rng.uniform(13, 60, n),
                                                  gs=rng.uniform(0.3, 3, n)), t)
    z = closed_loop_right_roots(SEA_DIAGRAM, d, sea_reference_frequency(d))
    m = sea_margins(d)
    assert np.all(z >= 0) and 100 < int((z > 0).sum()) < n
    np.testing.assert_array_equal(z, m.unstable_poles)


def _threaded_cases():
    """(name, run) pairs: each run returns a dict of arrays computed in threads."""
    from seactl.analysis.roots import characteristic_roots
    from seactl.apps.bench.impedance import random_designs as imp_designs
    from seactl.latency.jitter import sea_jitter_margins
    from seactl.systems.mobile_base.model import TRIKEY
    from seactl.systems.mobile_base.simulation import simulate
    from seactl.systems.sea import impedance as imp
    from seactl.systems.sea import passivity as imp_passivity
    from seactl.systems.sea.loops import SEA_DIAGRAM

    d = imp_designs(24, seed=3)

    def impedance(monkeypatch):
        monkeypatch.setattr(imp, "_CHUNK_POINTS", 2000)  # 24 designs x 500 frequencies: 6 chunks
        return {"z": imp.impedance(d, np.logspace(-1, 3, 500)).z}

    def passivity(monkeypatch):
        p = imp_passivity.passivity(d, points_per_decade=50)
        return {"passive": p.passive, "proven": p.proven}

    def jitter(monkeypatch):
        j = sea_jitter_margins(d)
        return {k: getattr(j, k) for k in ("overall_s", "stiffness_s", "damping_s", "stable")}

    def roots(monkeypatch):
        r = characteristic_roots(SEA_DIAGRAM, d, count=4)
        return {"roots": r.roots, "nodes": r.nodes}

    def base(monkeypatch):
        r = simulate(TRIKEY, np.linspace(20, 80, 6), np.linspace(5, 15, 6), 0.3, duration=0.3)
        return {"x": r.x, "tau": r.tau}

    def eigenvalues(monkeypatch):
        from seactl.base.parallel import eigvals, stacked
        A = np.random.default_rng(5).normal(size=(40, 9, 9))
        return {"ev": eigvals(A), "numpy": np.linalg.eigvals(A),
                "inv": stacked(np.linalg.inv, A), "numpy_inv": np.linalg.inv(A)}

    return [impedance, passivity, jitter, roots, base, eigenvalues]


@pytest.mark.parametrize("run", _threaded_cases(), ids=lambda f: f.__name__)
def test_threaded_batches_are_the_one_thread_results(run, monkeypatch):
    """Impedance chunks, the jitter and passivity proofs' chunks, the roots' eigenvalues,
    the mobile base's batch and batched eigenvalues and inverses run in one thread per
    core.  Oracle: the same call in one thread (and numpy's own eigenvalues and
    inverses), bit for bit."""
    from seactl.base import parallel as _parallel

    monkeypatch.setattr(_parallel, "THREADS", 1)
    one = run(monkeypatch)
    monkeypatch.setattr(_parallel, "THREADS", 3)
    many = run(monkeypatch)
    for k in one:
        np.testing.assert_array_equal(many[k], one[k])
    if "numpy" in one:
        np.testing.assert_array_equal(many["ev"], one["numpy"])
        np.testing.assert_array_equal(many["inv"], one["numpy_inv"])


def test_borrowed_views_are_their_arrays():
    """``seactl.base.borrow.borrowed`` (the compiled kernels' arrays without reference counts):
    the view has its array's data, shape and strides, so a helper writing through it
    writes the array, for a contiguous, a strided and a 3-d array.  Oracle: numpy's own
    arithmetic on copies of the same arrays."""
    from numba import njit

    from seactl.base.borrow import borrowed

    @njit
    def scale(v, k):
        for i in range(v.shape[0]):
            v[i] *= k

    @njit
    def kernel(a, b, c):
        a, b, c = borrowed(a), borrowed(b), borrowed(c)
        scale(a, 2.0)
        scale(b, 3.0)
        c[1, 2, 3] += a.sum() + b.sum()
        return a.shape[0], b.strides[0], c.shape

    rng = np.random.default_rng(2)
    a, whole, c = rng.normal(size=7), rng.normal(size=20), rng.normal(size=(2, 3, 4))
    b = whole[::3]
    a0, b0, c0 = a.copy(), b.copy(), c.copy()
    assert kernel(a, b, c) == (7, b.strides[0], (2, 3, 4))
    np.testing.assert_array_equal(a, 2 * a0)
    np.testing.assert_array_equal(b, 3 * b0)
    c0[1, 2, 3] += (2 * a0).sum() + (3 * b0).sum()
    np.testing.assert_allclose(c, c0, rtol=1e-15)
