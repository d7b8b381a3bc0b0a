"""Delay equations and quasi-polynomials typed in (``sc.delay_equation``, ``sc.quasi_polynomial``).

Each test names its oracle: Lambert W values (mpmath), published critical delays recomputed
here from the crossing conditions with mpmath, Hayes' exact stability region of the scalar
equation, numpy's determinant of the characteristic matrix, and the same systems one by one.
"""

from __future__ import annotations

import time

import mpmath
import numpy as np
import pytest

import seactl as sc

# Published critical delays of 2x2 equations x'(t) = A0 x(t) + A1 x(t - tau): the smallest
# delay at which a root reaches the imaginary axis, as printed (and its printed decimals).
PUBLISHED = [
    {  # Gu, Kharitonov & Chen, Stability of Time-Delay Systems (Birkhauser 2003), the
       # two-state example of the delay-dependent LMI chapters: delay margin 6.1725.
        "source": "Gu-Kharitonov-Chen 2003, two-state example",
        "a0": [[-2.0, 0.0], [0.0, -0.9]], "a1": [[-1.0, 0.0], [-1.0, -1.0]],
        "critical_delay_s": 6.1725, "decimals": 4, "rhp_below": 0, "rhp_above": 2,
    },
    {  # Gu, Kharitonov & Chen 2003, Example (x'' - 0.1 x' + 2 x = x(t - tau) in state
       # form): stable exactly for 0.10017 < tau < 1.71785; its first crossing.
        "source": "Gu-Kharitonov-Chen 2003, delay-interval example",
        "a0": [[0.0, 1.0], [-2.0, 0.1]], "a1": [[0.0, 0.0], [1.0, 0.0]],
        "critical_delay_s": 0.10017, "decimals": 5, "rhp_below": 2, "rhp_above": 0,
    },
]
GKC_UPPER_S = 1.71785  # the same example's upper end of its stable interval, as printed


def crossings(a0, a1, w_max=5.0, grid=500):
    """Oracle (independent of seactl): every ``(tau, w)`` with a root ``s = j w`` of
    ``det(s I - A0 - A1 z) = 0``, ``z = e^{-s tau}``.  For 2x2 matrices the determinant is
    ``s^2 - s (tr A0 + z tr A1) + det(A0 + z A1)``, a quadratic in ``z`` at each ``s``;
    a crossing is a frequency where one of its roots has ``|z| = 1`` (bracketed on a grid,
    refined by mpmath at 30 digits), and ``tau = -arg z / w`` (mod ``2 pi / w``)."""
    with mpmath.workdps(30):
        return _crossings(a0, a1, w_max, grid)


def _crossings(a0, a1, w_max, grid):
    A0, A1 = mpmath.matrix(a0), mpmath.matrix(a1)
    mixed = A0[0, 0] * A1[1, 1] + A1[0, 0] * A0[1, 1] - A0[0, 1] * A1[1, 0] \
        - A1[0, 1] * A0[1, 0]
    tr0, tr1 = A0[0, 0] + A0[1, 1], A1[0, 0] + A1[1, 1]

    def zs(w):
        s = 1j * mpmath.mpf(w)
        c2, c1, c0 = mpmath.det(A1), mixed - s * tr1, s * s - s * tr0 + mpmath.det(A0)
        if abs(c2) == 0:
            return [-c0 / c1]
        d = mpmath.sqrt(c1 * c1 - 4 * c2 * c0)
        return [(-c1 + d) / (2 * c2), (-c1 - d) / (2 * c2)]

    out = []
    ws = np.linspace(1e-6, w_max, grid)
    for i in range(len(zs(1.0))):
        f = [float(abs(zs(w)[i]) - 1) for w in ws]
        for k in np.nonzero(np.sign(f[:-1]) != np.sign(f[1:]))[0]:
            w = mpmath.findroot(lambda x, i=i: abs(zs(x)[i]) - 1, (ws[k], ws[k + 1]),
                                solver="anderson")
            if abs(abs(zs(w)[i]) - 1) > 1e-20:  # (a jump of the square root's branch)
                continue
            tau = mpmath.fmod(-mpmath.arg(zs(w)[i]) + 2 * mpmath.pi, 2 * mpmath.pi) / w
            out.append((float(tau), float(w)))
    return sorted(out)


@pytest.mark.parametrize("case", PUBLISHED, ids=[c["source"] for c in PUBLISHED])
def test_published_critical_delay(case):
    # Oracle: the crossing conditions solved with mpmath (crossings above), which must
    # match the printed figure to its printed digits (within one unit of the last: the
    # figures are printed rounded or truncated); then seactl's roots at that delay.
    tau, w = crossings(case["a0"], case["a1"])[0]
    assert abs(tau - case["critical_delay_s"]) < 10.0 ** -case["decimals"]
    sys = sc.delay_equation(case["a0"], terms=[(case["a1"], tau)])
    z = sys.roots(count=2).roots[0]
    assert abs(z.real) < 1e-8 and abs(z.imag - w) < 1e-8
    below_above = sys.with_delays(tau1=[tau - 0.01, tau + 0.01]).roots(count=2)
    assert below_above.right_half_plane_roots.tolist() == [case["rhp_below"],
                                                            case["rhp_above"]]


def test_gkc_stable_interval_upper_end():
    # Oracle: the same mpmath crossings; the published stable interval ends at 1.71785.
    case = PUBLISHED[1]
    tau, w = crossings(case["a0"], case["a1"])[1]
    assert abs(tau - GKC_UPPER_S) < 1e-5
    r = sc.delay_equation(case["a0"], terms=[(case["a1"], [tau - 0.01, tau + 0.01])])
    assert r.roots(count=2).right_half_plane_roots.tolist() == [0, 2]


def test_delay_margin_closed_form_of_the_triangular_example():
    # Oracle: a second derivation of the first published case: det = (s + 2 + z)(s + 0.9 +
    # z); only |j w + 0.9| = 1 can cross, at w = sqrt(0.19), tau = (pi - atan(w / 0.9)) / w.
    w = mpmath.sqrt(mpmath.mpf("0.19"))
    tau = (mpmath.pi - mpmath.atan(w / mpmath.mpf("0.9"))) / w
    got, w_got = crossings(PUBLISHED[0]["a0"], PUBLISHED[0]["a1"])[0]
    assert abs(got - float(tau)) < 1e-12 and abs(w_got - float(w)) < 1e-12


def test_roots_of_s_plus_exp_are_lambert_w():
    # Oracle: s e^s = -1, so the roots of s + e^{-s} are W_k(-1) (mpmath.lambertw), k = 0..7
    # in the upper half-plane (their conjugates are W_{-k-1}(-1)).
    lam = np.array([complex(mpmath.lambertw(-1, k)) for k in range(8)])
    for sys in (sc.delay_equation(0.0, terms=[(-1.0, 1.0)]),
                sc.quasi_polynomial([1, 0], terms=[([1], 1.0)]),
                sc.load_dde("examples/dde/lambert.toml")):
        r = sys.roots(count=8)
        np.testing.assert_allclose(r.roots, lam, rtol=0, atol=1e-10)
        assert bool(r.stable) and int(r.right_half_plane_roots) == 0


def test_long_delay_counts_match_lambert_w():
    # Oracle: roots of s + e^{-s tau} are W_k(-tau) / tau; with tau = 1000 s (no cap on
    # delays) those with Re W_k(-tau) > 0 are the right-half-plane roots (mpmath).
    tau = 1000.0
    expected = sum(mpmath.re(mpmath.lambertw(-tau, k)) > 0 for k in range(-400, 400))
    r = sc.delay_equation(0.0, terms=[(-1.0, tau)]).roots(count=1)
    assert int(r.right_half_plane_roots) == expected > 300


def hayes_boundary(a):
    """Oracle: Hayes (1950) for x' = a x + b x(t - 1), a < 1: stable iff -b > a and
    b > -w / sin w with w in (0, pi) solving a = w cot w (mpmath)."""
    w = mpmath.findroot(lambda x: x * mpmath.cot(x) - a, (1e-9, mpmath.pi - 1e-9),
                        solver="bisect")
    return float(-w / mpmath.sin(w))


@pytest.mark.parametrize("a", [-2.0, 0.0, 0.7])
def test_hayes_stability_region(a):
    # Oracle: Hayes' region: the curve (2 roots cross) and the line a + b = 0 (1 crosses).
    b_curve = hayes_boundary(a)
    bs = [b_curve - 0.02, b_curve + 0.02, -a - 0.02, -a + 0.02]
    counts = [int(sc.delay_equation(a, terms=[(b, 1.0)]).roots(count=1)
                  .right_half_plane_roots) for b in bs]
    assert counts == [2, 0, 0, 1]


def test_hayes_no_stability_beyond_a_equal_one():
    # Oracle: Hayes: a >= 1 is unstable for every b (tau = 1); and time scaling: the region
    # in (a tau, b tau), here with tau = 2 s.
    for b in (-0.5, -1.5, -3.0):
        assert int(sc.delay_equation(1.2, terms=[(b, 1.0)]).roots(count=1)
                   .right_half_plane_roots) > 0
    b_curve = hayes_boundary(0.0) / 2
    r = sc.delay_equation(0.0, terms=[(b, 2.0) for b in [b_curve + 0.01]]).roots(count=1)
    assert int(r.right_half_plane_roots) == 0


def test_expansion_equals_numpy_det():
    # Oracle: numpy's determinant of s I - A0 - sum_k A_k e^{-s h_k} at random complex s
    # (a second derivation), with delays that are sums of named delays.
    rng = np.random.default_rng(3)
    a0, a1, a2, a3 = (rng.standard_normal((3, 3)) for _ in range(4))
    tau = {"tau1": 0.37, "tau2": 1.1}
    sys = sc.delay_equation(a0, terms=[(a1, "tau1"), (a2, "tau1 + tau2"), (a3, "2*tau1")],
                            delays_s=tau)
    q = sys.characteristic.at()
    h = [tau["tau1"], tau["tau1"] + tau["tau2"], 2 * tau["tau1"]]
    s = rng.standard_normal(6) * 3 + 1j * rng.standard_normal(6) * 5
    ref = [np.linalg.det(x * np.eye(3) - a0 - sum(a * np.exp(-x * d) for a, d in
                                                   zip((a1, a2, a3), h))) for x in s]
    np.testing.assert_allclose(q(s), ref, rtol=1e-12)
    e = sys.characteristic.exponents
    assert e[0].tolist() == [0, 0] and len({tuple(r) for r in e.tolist()}) == len(e)
    assert [6, 0] in e.tolist() and [3, 3] in e.tolist()  # (2 tau1)^3, (tau1 + tau2)^3


def test_quasi_polynomial_equals_its_terms():
    # Oracle: the sum typed in, evaluated term by term with numpy.polyval.
    tau = {"tau1": 0.4, "tau2": 1.5}
    q = sc.quasi_polynomial([1, 1, 1], terms=[([0.5, 0], "tau1"), ([0.2], "tau1 + tau2"),
                                              ([0.3], "tau1")], delays_s=tau)
    s = np.array([0.3 + 2j, -1 + 0.5j])
    ref = (np.polyval([1, 1, 1], s) + np.polyval([0.5, 0.3], s) * np.exp(-s * 0.4)
           + 0.2 * np.exp(-s * 1.9))
    np.testing.assert_allclose(q.characteristic.at()(s), ref, rtol=1e-14)
    assert q.characteristic.exponents.tolist() == [[0, 0], [1, 0], [1, 1]]


def test_batches_equal_one_by_one():
    # Oracle: the same equations built one delay pair at a time.
    a0, a1, a2 = [[0.0, 1.0], [-1.0, -0.5]], [[0, 0], [-0.5, 0]], [[0, 0], [0, -0.3]]
    t1, t2 = np.array([0.5, 1.0, 1.5])[:, None], np.array([0.2, 2.0])
    batch = sc.delay_equation(a0, terms=[(a1, t1), (a2, t2)])
    assert batch.shape == (3, 2) and batch[1].shape == (2,) and batch.loops == ("tau1", "tau2")
    r = batch.roots(count=3)
    for i, j in np.ndindex(3, 2):
        one = sc.delay_equation(a0, terms=[(a1, t1[i, 0]), (a2, t2[j])]).roots(count=3)
        np.testing.assert_allclose(r.roots[i, j], one.roots, rtol=1e-12)
        assert r.right_half_plane_roots[i, j] == one.right_half_plane_roots
    assert r.records()[3]["tau1_s"] == 1.0 and r.records()[3]["tau2_s"] == 2.0


def test_system_structure_and_refused_views():
    # Oracle: the documented structure; views of a block diagram raise the seactl error
    # naming the view.
    d = sc.load_dde("examples/dde/two-delays.toml")
    assert isinstance(d, sc.System) and d.kind == "dde" and d.links == {"tau1": "tau1",
                                                                        "tau2": "tau2"}
    assert d.delays_s["tau2"] == 0.5 and d.delay_terms().names == d.loops
    assert np.all(d.reference_frequency() > 0) and "tau1=1 s" in d.labels()[0]
    assert "DelayEquation(2x2" in repr(d)
    for view, call in [("margins", d.margins), ("impedance", lambda: d.impedance([1.0])),
                       ("step", d.step), ("export", lambda: d.export("x")),
                       ("run", d.run)]:
        with pytest.raises(sc.InputError, match=view):
            call()


@pytest.mark.parametrize("make, match", [
    (lambda: sc.quasi_polynomial([1, 0], terms=[([0.5, 0], 1.0)]), "neutral"),
    (lambda: sc.delay_equation([[1, 2, 3]]), "square"),
    (lambda: sc.delay_equation(np.eye(2), terms=[(np.eye(3), 1.0)]), "2 x 2"),
    (lambda: sc.delay_equation(0.0, terms=[(1.0, -1.0)]), ">= 0"),
    (lambda: sc.delay_equation(0.0, terms=[(1.0, "tau9")], delays_s={"tau1": 1}), "names"),
    (lambda: sc.delay_equation(0.0, terms=[(1.0, "tau1 - tau2")], delays_s={"tau1": 1}),
     "sum of named delays"),
    (lambda: sc.delay_equation(0.0, terms=[(1.0, 1.0)], names=["a", "b"]), "one per term"),
    (lambda: sc.quasi_polynomial([3.0]), "degree >= 1"),
    (lambda: sc.delay_equation(np.eye(41)), "at most 40"),
    (lambda: sc.quasi_polynomial([1, 1e300, 0]), "root scale"),
    (lambda: sc.delay_equation(-1.0, terms=[(0.5, [1.0, 2.0]), (0.2, [1.0, 2.0, 3.0])]),
     "broadcast"),
    (lambda: sc.quasi_polynomial([1, 0, 0], terms=[([1e-300], 1e-3)]), "root scale"),
])
def test_bad_input_is_refused(make, match):
    # Oracle: the documented valid ranges, named in the error.
    with pytest.raises(sc.InputError, match=match):
        make()


def test_delay_far_beyond_the_time_scale_refused():
    # Oracle: MAX_DELAY_RATIO: s + e^{-s tau} has root scale 1 rad/s; tau = 1e9 s puts a
    # root every 2 pi 1e-9 rad/s along the axis, refused before any work.
    with pytest.raises(sc.SeactlError, match="time scale"):
        sc.delay_equation(0.0, terms=[(-1.0, 1e9)]).roots(count=1)


def test_large_expansion_refused_up_front(monkeypatch):
    # Oracle: the time budget (SEACTL_MAX_SECONDS): a 12 x 12 equation with 4 delays has up
    # to C(16, 4) = 1820 delay terms, refused at once instead of expanding for a minute.
    monkeypatch.setenv("SEACTL_MAX_SECONDS", "1")
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    with pytest.raises(sc.SeactlError, match="1,820 delay terms"):
        sc.delay_equation(rng.standard_normal((12, 12)),
                          terms=[(rng.standard_normal((12, 12)), 1.0 + k) for k in range(4)])
    assert time.perf_counter() - start < 0.5


def test_high_order_roots_refused_up_front():
    # Oracle: the time budget: the collocation of an order-40 characteristic (matrices up
    # to 9,640 square) is refused before any eigenvalue is computed.
    q = sc.quasi_polynomial(np.r_[1.0, np.zeros(40)], terms=[([1.0], 1.0)])
    start = time.perf_counter()
    with pytest.raises(sc.SeactlError, match="order 40"):
        q.roots(count=1)
    assert time.perf_counter() - start < 0.5


def test_dde_file_errors_name_the_field(tmp_path):
    # Oracle: the file format's documented fields and ranges.
    cases = {'a0 = 0.0\n[[term]]\na = -1.0\n': "exactly one of delay_s",
             'p0 = [1.0, 0.0]\n[[term]]\na = 1.0\ndelay_s = 1.0\n': "term #1",
             'a0 = 0.0\nb0 = 1\n': "unknown key",
             'a0 = 0.0\n[[term]]\na = 1.0\ndelay_s = -2.0\n': "greater than or equal",
             'a0 = 0.0\np0 = [1.0, 0.0]\n': "exactly one of a0"}
    for text, match in cases.items():
        path = tmp_path / "bad.toml"
        path.write_text(text)
        with pytest.raises(sc.LoopFileError, match=match):
            sc.load_dde(path)


@pytest.mark.parametrize("case", PUBLISHED, ids=[c["source"] for c in PUBLISHED])
def test_published_delay_margin_end_to_end(case):
    # Oracle: the crossings solved with mpmath above (which match the printed figures).
    # The first example is stable from tau = 0 up to its critical delay; the second is
    # stable only between its two crossings, so its margin from a delay inside that
    # interval is the distance to the upper end.
    taus = [t for t, _ in crossings(case["a0"], case["a1"])]
    start = 0.0 if case["rhp_below"] == 0 else 0.5 * (taus[0] + taus[1])
    end = taus[0] if case["rhp_below"] == 0 else taus[1]
    m = sc.delay_equation(case["a0"], terms=[(case["a1"], start)]).delay_margin()
    assert bool(m.stable) and bool(m.verified)
    assert abs(float(m.delay_margin_s) - (end - start)) < 1e-8
    if case["rhp_below"] == 2:  # below the first crossing: unstable, margin 0
        m0 = sc.delay_equation(case["a0"], terms=[(case["a1"], 0.5 * taus[0])]).delay_margin()
        assert not bool(m0.stable) and float(m0.delay_margin_s) == 0.0


def test_chart_and_delay_margin_agree_on_a_two_delay_equation():
    # Oracle: two independent constructions of the same crossing: the delay margin's
    # sweep along a ray (a polynomial in one exponential) and the chart's curves (a
    # resultant over the torus); the margin's crossing point must lie on a chart branch
    # (to the chart's sampling of the branch) and flip the chart's certified region count.
    s = sc.load_dde("examples/dde/two-delays.toml")
    m = s.delay_margin({"tau2": 1.0})
    hit = np.array([m.crossing_delays_s["tau1"], m.crossing_delays_s["tau2"]], float).ravel()
    c = s.stability_chart(("tau1", "tau2"), (10.0, 10.0), resolution=400)
    pts = np.concatenate([np.column_stack([b["tau1_s"], b["tau2_s"]]) for b in c.curves])
    assert np.min(np.hypot(*(pts - hit).T)) < 0.01
    below = s.with_delays(tau2=hit[1] - 0.05).roots(count=2).right_half_plane_roots
    above = s.with_delays(tau2=hit[1] + 0.05).roots(count=2).right_half_plane_roots
    assert int(below) == 0 and int(above) == 2
