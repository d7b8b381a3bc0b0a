"""Jitter margins against independent routes: closed forms, a per-frequency numerical
solve of the block diagram (numpy linear algebra on the block responses, no sympy),
python-control's FRD feedback, and the constant-delay margins (a constant extra delay is
one of the time-varying delays the bound covers, so J <= delay margin)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import control as ct
import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.latency.jitter import SEA_TAPS, peak_omega_t, sea_jitter_margins
from seactl.latency.maps import loop_delay_margins, sea_model, sea_split_diagram

TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))


def _solve_t(diagram, design, omega, tap):
    """T = L/(1+L) at ``tap`` by solving the closed-loop equations x = A(jw) x + e_tap v
    numerically at every frequency: T = 1 - x_tap / v (the tap carries v plus what the
    loop returns, -T v).  Independent of the symbolic derivation."""
    signals = list(diagram.signals)
    idx = {s: i for i, s in enumerate(signals)}
    m = len(signals)
    s = 1j * np.asarray(omega)
    A = np.zeros(np.shape(design.Kq) + s.shape + (m, m), complex)
    for b in diagram.blocks:
        A[..., idx[b.dst], idx[b.src]] += b.response(design, s)
    rhs = np.zeros(m)
    rhs[idx[tap]] = 1.0
    x = np.linalg.solve(np.eye(m) - A, np.broadcast_to(rhs, A.shape[:-1])[..., None])[..., 0]
    return 1.0 - x[..., idx[tap]]


def _dense_peak(diagram, design, tap, w_lo, w_hi, n=4000):
    """max w|T| on a dense log grid, then on a 2000-point zoom around the best point."""
    w = np.logspace(np.log10(w_lo), np.log10(w_hi), n)
    v = w * np.abs(_solve_t(diagram, design, w, tap))
    k = int(np.argmax(v))
    wz = np.linspace(w[max(k - 1, 0)], w[min(k + 1, n - 1)], 2000)
    return max(float(v[k]), float(np.max(wz * np.abs(_solve_t(diagram, design, wz, tap)))))


def test_first_order_loops_closed_form():
    # L = K/(s(tau s + 1)): w|T| = K / sqrt(1 + (K/w - tau w)^2), max K at w = sqrt(K/tau).
    loop = lambda p, s: p.K[..., None] / (s * (p.tau[..., None] * s + 1))  # noqa: E731
    p = SimpleNamespace(K=np.array([3.0, 40.0, 800.0]), tau=np.array([0.5, 0.01, 1e-4]),
                        shape=(3,))
    peak, w = peak_omega_t(loop, p, np.logspace(-2, 3, 161))
    np.testing.assert_allclose(1 / peak, 1 / p.K, rtol=1e-9)
    np.testing.assert_allclose(w, np.sqrt(p.K / p.tau), rtol=1e-3)
    # L = K/s: w|T| = K w / sqrt(w^2 + K^2) -> K only as w -> inf (grid extended upwards).
    integ = lambda p, s: p.K[..., None] / s  # noqa: E731
    peak, _ = peak_omega_t(integ, p, np.logspace(-2, 1, 61))
    np.testing.assert_allclose(peak, p.K, rtol=1e-6)


def test_table_i_14hz_against_numerical_solve_and_python_control():
    d = sc.design(14, **TABLE_I)
    j = sea_jitter_margins(d.sea)
    D = sea_split_diagram()
    # Oracle 1: per-frequency numerical solve of the diagram, dense grid.
    ref = {k: 1 / _dense_peak(D, d.sea, tap, 1.0, 1e5) for k, tap in SEA_TAPS.items()}
    for k in SEA_TAPS:
        assert getattr(j, f"{k}_s") == pytest.approx(ref[k], rel=1e-7), k
    assert j.overall_s * 1e3 == pytest.approx(8.04, abs=0.005)        # the value
    assert j.delay_margin_s * 1e3 == pytest.approx(9.45, abs=0.005)
    # Oracle 2: python-control: FRD of the exact-delay loop, closed with ct.feedback.
    f = np.logspace(-1, 4, 20001)
    L = d.to_control("frd", f_hz=f)
    T = ct.feedback(L, 1)
    w = 2 * np.pi * f
    peak = np.max(w * np.abs(T.frequency_response(w).magnitude.ravel()))
    assert j.overall_s == pytest.approx(1 / peak, rel=1e-5)


def test_batch_against_numerical_solve_and_below_delay_margins():
    d = sc.design(np.array([10.0, 14.0, 22.0, 35.0])[:, None], gs=[0.5, 1.0, 2.5],
                  delays_ms={"torque": 0.7, "stiffness": 3.0, "damping": 1.0}, filters_hz=(40, 150))
    j = sea_jitter_margins(d.sea)
    assert j.overall_s.shape == (4, 3) and j.stable.any() and (~j.stable).any()
    D = sea_split_diagram()
    for i, g in zip(*np.nonzero(j.stable)):
        one = d[i, g].sea
        for k, tap in SEA_TAPS.items():
            assert getattr(j, f"{k}_s")[i, g] == pytest.approx(
                1 / _dense_peak(D, one, tap, 0.3, 3e4, n=1500), rel=1e-6), (i, g, k)
    # Unstable designs: 0.  Stable ones: a constant delay is admissible jitter, J <= DM.
    for k in SEA_TAPS:
        assert np.all(getattr(j, f"{k}_s")[~j.stable] == 0)
    assert np.all(j.overall_s <= j.delay_margin_s * (1 + 1e-9))
    dm = loop_delay_margins(D, d.sea, sea_model().grid(d.sea), "q_s", "q_d", ("tau_sens",))
    assert np.all(j.stiffness_s <= dm.stiffness_s * (1 + 1e-9))
    assert np.all(j.damping_s <= dm.damping_s * (1 + 1e-9))


def test_api_and_cli(capsys):
    d = sc.design([12, 14], **TABLE_I)
    r = d.jitter_margins()
    assert isinstance(r, sc.JitterResult)
    rec = r.records()
    assert main(["jitter", "--fn", "12", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd",
                 "0.5", "--f-qd", "50", "--f-taud", "100", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out["designs"][0]) == ["fn_hz", "gs", "jitter_margin_ms",
                                       "stiffness_jitter_margin_ms", "damping_jitter_margin_ms",
                                       "torque_jitter_margin_ms", "delay_margin_ms"]
    for row, ref in zip(out["designs"], rec):
        assert row["jitter_margin_ms"] == pytest.approx(ref["jitter_margin_ms"])
        assert row["delay_margin_ms"] == pytest.approx(ref["delay_margin_ms"])
    assert main(["jitter", "--fn", "14", "--t-qs", "2"]) == 0
    assert "bottleneck" in capsys.readouterr().out
    assert main(["jitter", "--fn", "-3"]) == 2


def test_measured_trace_is_checked_against_the_analysed_band(tmp_path, capsys):
    """``seactl jitter --trace stiffness=FILE``: a trace of 2.5-3.5 ms (the kind seactl run
    writes) against ``[T_qs, T_qs + J]``; oracle: the jitter margin from the Python API for
    the same design, and the trace's own min and max."""
    import json

    import seactl as sc
    from seactl.apps.cli import main

    trace = tmp_path / "latency-stiffness.csv"
    trace.write_text("latency_ms\n" + "".join(f"{v}\n" for v in (2.5, 3.0, 3.5, 2.75)))
    flags = ["--fn", "14", "--t-tau", "1", "--t-qd", "1", "--f-qd", "50", "--f-taud", "100"]
    J = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
                  filters_hz=(50, 100)).jitter_margins()
    j_ms = float(np.ravel(J.stiffness_jitter_margin_s)[0]) * 1e3
    for t_qs, covered in (("2", 3.5 <= 2 + j_ms), ("3", False)):   # 2.5 < 3: below the band
        assert main(["jitter", *flags, "--t-qs", t_qs, "--trace", f"stiffness={trace}",
                     "--json"]) == 0
        (c,) = json.loads(capsys.readouterr().out)["traces"]
        assert (c["min_ms"], c["max_ms"]) == (2.5, 3.5) and c["covered"] is covered
    assert c["jitter_margin_ms"] > 0
    assert main(["jitter", "--trace", f"speed={trace}"]) == 2
    assert "--trace" in capsys.readouterr().err


# A design whose torque loop has two peaks of w |T|: a sharp one at 24.8 Hz and a broad
# one at 100.6 Hz, half as high; the scan's samples of the sharp one were below half of
# the broad one, so it reported the broad one (0.168 ms, twice the true margin).
MISSED = dict(fn=34.18107122581371,
              delays_ms={"torque": 0.6815216590974069, "stiffness": 8.493127627673957,
                         "damping": 1.0745445570933905},
              filters_hz=(50, 100))


def test_a_sharp_peak_between_scan_points_is_found():
    # Oracle: the diagram's linear equations solved per frequency (_solve_t) on 40,001
    # points from 24.7 to 24.9 Hz, and _dense_peak's scan from 50 to 300 Hz.
    d = sc.design(MISSED["fn"], delays_ms=MISSED["delays_ms"], filters_hz=MISSED["filters_hz"])
    j = sea_jitter_margins(d.sea)
    w = 2 * np.pi * np.linspace(24.7, 24.9, 40_001)
    D = sea_split_diagram()
    sharp = np.max(w * np.abs(_solve_t(D, d.sea, w, "tau_sens")))
    broad = _dense_peak(D, d.sea, "tau_sens", 2 * np.pi * 50, 2 * np.pi * 300)
    assert sharp > 1.9 * broad
    assert float(j.torque_s) == pytest.approx(1 / sharp, rel=1e-7)
    assert float(j.torque_s) <= 1 / sharp  # the guarantee's side
    assert float(j.peak_hz["torque"]) == pytest.approx(24.806, abs=1e-3)


@pytest.mark.parametrize("seed", [0, 1])
def test_jitter_margins_never_exceed_a_dense_scan(seed):
    # Oracle: _dense_peak (per-frequency solve, 4000 log points and a zoom) for each loop
    # of 8 broad designs (delays up to 6 ms): the proven margin is never above the
    # dense scan's and agrees with it within the scan's resolution.
    rng = np.random.default_rng(seed)
    n = 8
    fn = rng.uniform(15, 45, n)
    delays = np.stack([rng.uniform(0, 1, n), rng.uniform(0, 6, n), rng.uniform(0, 2, n)], 1)
    loops = ("torque", "stiffness", "damping")
    j = sea_jitter_margins(sc.design(fn, delays_ms=dict(zip(loops, delays.T)),
                                     filters_hz=(50, 100)).sea)
    D = sea_split_diagram()
    assert j.stable.sum() >= 4
    for i in np.nonzero(j.stable)[0]:
        one = sc.design(fn[i], delays_ms=dict(zip(loops, delays[i])), filters_hz=(50, 100)).sea
        for k, tap in SEA_TAPS.items():
            ref = 1 / _dense_peak(D, one, tap, 1.0, 1e5)
            got = float(getattr(j, f"{k}_s")[i])
            assert got <= ref * (1 + 1e-9), (k, i)
            assert got == pytest.approx(ref, rel=1e-4), (k, i)


def test_a_supremum_at_infinite_frequency_is_bounded_by_its_limit():
    # Oracle: the per-frequency solve at 1e7 rad/s, where w |T| of the unfiltered torque
    # loop (relative degree 1) has reached its limit to 3e-5: the proven margin is that
    # limit's inverse less the documented 1 % (TAIL_SLACK).
    from seactl.certify.supremum import TAIL_SLACK

    d = sc.design([30.0])
    j = sea_jitter_margins(d.sea)
    limit = float(1e7 * np.abs(_solve_t(sea_split_diagram(), sc.design(30.0).sea,
                                        np.array([1e7]), "tau_sens"))[0])
    assert float(j.torque_s[0]) == pytest.approx(1 / ((1 + TAIL_SLACK) * limit), rel=1e-4)


def test_cli_marks_an_unproven_jitter_margin(capsys, monkeypatch):
    # Oracle: the documented contract: a stable design whose bound cannot be proven
    # (forced here: every proof fails) shows "0 (not proven)", not a number.
    import seactl.certify.supremum as S

    monkeypatch.setattr(S, "MAX_BASE", 1)
    assert main(["jitter", "--fn", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5",
                 "--f-qd", "50", "--f-taud", "100"]) == 0
    out = capsys.readouterr().out
    assert out.count("0 (not proven)") == 4


def test_a_neutral_design_leaves_the_others_of_its_batch_proven(monkeypatch):
    # Oracle: each design's proven peak computed alone.  A design whose loop is a neutral
    # delay equation (forced here: no built-in SEA loop is one) has no proven peak (inf,
    # so no jitter margin); it once took every other design of its batch with it.
    from seactl.diagram.blockdiagram import QuasiPolynomial
    from seactl.latency.jitter import sea_jitter_grid

    d = sc.design([12.0, 16.0], **TABLE_I).sea
    omega = sea_jitter_grid(d)
    loops = {k: sea_split_diagram().loop(tap) for k, tap in SEA_TAPS.items()}
    alone = {k: peak_omega_t(loop, sc.design(12.0, **TABLE_I).sea, omega[0])[0]
             for k, loop in loops.items()}
    real = QuasiPolynomial.neutral.fget
    monkeypatch.setattr(QuasiPolynomial, "neutral", property(
        lambda q: real(q) | (np.arange(q.coeffs.shape[1]) == 1)))
    for k, loop in loops.items():
        peak = peak_omega_t(loop, d, omega)[0]
        assert peak[0] == pytest.approx(float(alone[k]), rel=1e-12), k
        assert np.isfinite(alone[k]) and peak[1] == np.inf, k


def _upper_numpy(b3N, b3D, majors, d, pa, pb):
    """The proof's interval bound written with numpy passes (its form before it was
    compiled), the oracle of the next test."""
    from numpy.polynomial.polynomial import polyval

    from seactl.diagram.blockdiagram import EVAL_ROUNDING

    W_, N0, N1, DR, DI, D1 = 0, 2, 3, 5, 6, 7  # (columns; N1 + 1, D1 + 1: the second derivatives)
    h, W = pb[:, W_] - pa[:, W_], pb[:, W_]
    at = lambda c: polyval(W, c[d].T, tensor=False)  # noqa: E731

    def sups(c0, bound3):
        c = 0.5 * (pa[:, c0 + 1] + pb[:, c0 + 1] + h * at(bound3))
        return 0.5 * (pa[:, c0] + pb[:, c0] + h * c), c

    S, C = sups(N1, b3N)
    SD, CD = sups(D1, b3D)
    errN, errD = (EVAL_ROUNDING * at(m) for m in majors)
    aD, bD = np.hypot(pa[:, DR], pa[:, DI]), np.hypot(pb[:, DR], pb[:, DI])
    a = pa[:, DR] + 1j * pa[:, DI]
    e = pb[:, DR] + 1j * pb[:, DI] - a
    e2 = np.abs(e) ** 2
    t = np.where(e2 > 0, np.clip(-(a.real * e.real + a.imag * e.imag) / e2, 0, 1), 0.0)
    gap = np.abs(a + t * e)
    X = np.minimum(0.5 * (pa[:, N0] + pb[:, N0] + h * S),
                   np.maximum(pa[:, N0], pb[:, N0]) + 0.125 * h * h * C) + errN
    Y = np.minimum(0.5 * (aD + bD + h * SD), np.maximum(aD, bD) + 0.125 * h * h * CD) + errD
    m = np.maximum(0.5 * (aD + bD - h * SD), gap - 0.125 * h * h * CD) - errD
    u0, u1 = (W * X) ** 2, 2 * W * X * (X + W * S)
    u2 = 2 * X * X + 8 * W * X * S + 2 * W * W * (S * S + X * C)
    v1, v2 = 2 * Y * SD, 2 * (SD * SD + Y * CD)
    m2 = m * m
    curv = u2 / m2 + (2 * u1 * v1 + u0 * v2) / (m2 * m2) + 2 * u0 * v1 * v1 / (m2 * m2 * m2)
    ends = np.maximum(pa[:, W_] * (pa[:, N0] + errN) / (aD - errD),
                      W * (pb[:, N0] + errN) / (bD - errD))
    ends = np.where((aD > errD) & (bD > errD), ends, np.inf)
    second = ends * ends + 0.125 * h * h * curv
    return np.where(m > 0, np.minimum(u0 / m2, second), np.inf)


def test_compiled_interval_bound_is_the_numpy_form_bit_for_bit():
    """The supremum proof's bound per interval (seactl.certify.supremum._upper_rows, compiled)
    against its numpy form (oracle, above): the same bits on 20,000 random intervals with
    values over twenty decades, zeros, infinities and NaN among them."""
    from types import SimpleNamespace as NS

    from seactl.certify import supremum as _supremum

    rng = np.random.default_rng(29)
    n, designs = 20_000, 40
    pa = np.abs(rng.normal(size=(n, 9))) * 10.0 ** rng.uniform(-10, 10, (n, 9))
    pb = np.abs(rng.normal(size=(n, 9))) * 10.0 ** rng.uniform(-10, 10, (n, 9))
    pa[:, 5:7] *= rng.choice([-1.0, 1.0], (n, 2))  # (Delta's real and imaginary parts)
    pb[:, 5:7] *= rng.choice([-1.0, 1.0], (n, 2))
    pb[:, 0] = pa[:, 0] * (1 + rng.uniform(1e-9, 1.0, n))
    for p in (pa, pb):
        rows = rng.integers(0, n, 300)
        p[rows, rng.integers(1, 9, 300)] = rng.choice([0.0, -0.0, np.inf, np.nan], 300)
    b3N, b3D, mN, mD = (np.abs(rng.normal(size=(designs, k))) for k in (4, 6, 5, 7))
    d = rng.integers(0, designs, n)
    with np.errstate(all="ignore"):  # (the infinities and NaN planted above)
        ref = _upper_numpy(b3N, b3D, (mN, mD), d, pa, pb)
        got = _supremum._upper(NS(bound3_coeffs=b3N), NS(bound3_coeffs=b3D), (mN, mD), d,
                               pa, pb)
    assert np.isfinite(ref).sum() > 5000 and np.isinf(ref).sum() > 100
    np.testing.assert_array_equal(got, ref)
