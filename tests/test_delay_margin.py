"""``System.delay_margin``: the delay margin along a direction of the delay vector.

Each test names its oracle: the loop-break delay margin of the certified Nyquist scan
(``margins()``), closed forms, a published two-by-two example solved again with mpmath,
a bisection on the certified right-half-plane root count, and the designs one by one.
"""

import math

import mpmath
import numpy as np
import pytest

import seactl as sc
from seactl.analysis.margins import certified_right_roots
from seactl.analysis.roots import frequency_scale
from seactl.diagram.delayterms import DelayTerms


def test_equal_growth_at_the_loop_break_is_the_loops_delay_margin():
    # Oracle: margins().delay_margin_ms, the certified Nyquist scan of the loop broken at
    # the sensor.  Every path of that loop holds exactly one of the delays moved here, so
    # adding t to each of them is adding t at the break: the rigid actuator's two loops;
    # the SEA's stiffness and damping loops (its torque loop is inside, not on the break).
    r = sc.rigid([6, 8, 12], delays_ms={"stiffness": 1.5, "damping": 1.0})
    np.testing.assert_allclose(1e3 * r.delay_margin().delay_margin_s,
                               r.margins().delay_margin_ms, rtol=1e-8)
    d = sc.design([12, 14, 16], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
    m = d.delay_margin({"stiffness": 1, "damping": 1})
    np.testing.assert_allclose(1e3 * m.delay_margin_s, d.margins().delay_margin_ms,
                               rtol=1e-8)
    assert m.verified.all() and m.stable.all() and not m.touch.any()
    # the crossing is a root on the axis: the characteristic vanishes there
    t = d.delay_terms()
    tau = np.stack([m.crossing_delays_s[n] for n in t.names])
    q = t.at(tau)
    s = 1j * m.crossing_rad_s[:, None]
    assert np.all(np.abs(q(s)) <= 1e-8 * np.abs(q.coeffs).sum(axis=(0, -1))[:, None]
                  * np.maximum(1, np.abs(s)) ** (q.coeffs.shape[-1] - 1))


def test_each_break_of_the_paper_loop_file():
    # Oracle: the loop file's certified delay margin at each break (analyze()): the torque
    # break's loop holds only the torque delay, the outer break's loop the stiffness and
    # damping delays, once on each path (the torque loop closed inside it).
    loop = sc.load_loop("examples/loops/paper-sea.toml")
    breaks = {b.name: float(b.margins.delay_margin_s)
              for b in loop.analyze(jitter=False).breaks}
    torque = loop.delay_margin({"tau_delay": 1})
    outer = loop.delay_margin({"Kq_fb": 1, "Bq_fb": 1})
    assert float(torque.delay_margin_s) == pytest.approx(breaks["torque"], rel=1e-9)
    assert float(outer.delay_margin_s) == pytest.approx(breaks["outer"], rel=1e-9)


def _scalar(a, b, tau0):
    """``s + a + b e^{-s tau}`` as DelayTerms, a batch over ``a`` and ``b``."""
    a, b, tau0 = (np.asarray(x, float) for x in (a, b, tau0))
    coeffs = np.stack([np.stack([a, np.ones_like(a)], -1),
                       np.stack([b, np.zeros_like(b)], -1)])
    return DelayTerms(coeffs, np.array([[0], [1]]), ("tau",), tau0[None])


def test_scalar_equation_closed_form():
    # Oracle: s + a + b e^{-s tau} with b > |a| is stable for tau < arccos(-a/b) /
    # sqrt(b^2 - a^2) (the root crosses at w = sqrt(b^2 - a^2)); with a > b it is
    # stable for every delay (no crossing).
    from seactl.analysis.delay_direction import direction_margin

    a = np.array([0.5, 0.0, -0.5, 0.5, 2.0])
    b = np.array([1.0, 1.0, 1.0, 1.0, 1.0])
    tau0 = np.array([0.0, 0.0, 0.0, 1.0, 0.0])
    m = direction_margin(_scalar(a, b, tau0))
    w = np.sqrt(np.maximum(b**2 - a**2, 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        star = np.where(b > np.abs(a), np.arccos(-a / b) / w, np.inf)
    np.testing.assert_allclose(m.delay_margin_s, star - tau0, rtol=1e-10)
    np.testing.assert_allclose(m.crossing_rad_s[:4], w[:4], rtol=1e-10)
    assert np.isnan(m.crossing_rad_s[4]) and m.verified.all()


def test_gu_kharitonov_chen_two_by_two():
    # Source: Gu, Kharitonov & Chen, Stability of Time-Delay Systems (Birkhauser 2003),
    # the two-by-two benchmark x' = A0 x + A1 x(t - tau), A0 = diag(-2, -0.9),
    # A1 = [[-1, 0], [-1, -1]], whose analytic delay margin 6.1725 is the reference of
    # the delay-dependent LMI literature.  Oracles: that value, and the crossing
    # equations solved with mpmath.
    A0 = np.diag([-2.0, -0.9])
    A1 = np.array([[-1.0, 0.0], [-1.0, -1.0]])
    # det(sI - A0 - A1 z) expanded by hand, z = e^{-s tau}:
    #   (s + 2 + z)(s + 0.9 + z) = (1.8 + 2.9 s + s^2) + (2.9 + 2 s) z + z^2
    coeffs = np.array([[1.8, 2.9, 1.0], [2.9, 2.0, 0.0], [1.0, 0.0, 0.0]])
    for s, z in [(0.3 + 2j, 0.7 - 0.1j), (-1 + 0.5j, 2 + 1j)]:  # the expansion is right
        ref = np.linalg.det(s * np.eye(2) - A0 - A1 * z)
        assert abs(sum(np.polyval(c[::-1], s) * z**k for k, c in enumerate(coeffs)) - ref) \
            < 1e-12
    t = DelayTerms(coeffs, np.array([[0], [1], [2]]), ("tau",), np.array([0.0]))
    from seactl.analysis.delay_direction import direction_margin

    m = direction_margin(t)
    # the factor s + 0.9 + e^{-s tau} crosses: jw + 0.9 + e^{-j w tau} = 0
    mpmath.mp.dps = 30
    w, tau = mpmath.findroot(
        lambda w, tau: [mpmath.re(1j * w + 0.9 + mpmath.exp(-1j * w * tau)),
                        mpmath.im(1j * w + 0.9 + mpmath.exp(-1j * w * tau))], (0.4, 6.0))
    assert abs(float(m.delay_margin_s[0]) - float(tau)) < 1e-8
    assert abs(float(m.crossing_rad_s[0]) - float(w)) < 1e-8
    assert 6.1725 <= float(m.delay_margin_s[0]) < 6.1726  # quoted truncated to 4 decimals
    assert bool(m.verified[0])


def _count(terms, tau):
    """Certified count at delays ``tau`` (``(D, P)``) of a single design's terms."""
    one = DelayTerms(terms.coeffs[:, None], terms.exponents, terms.names, terms.delays_s)
    q = one.at(tau).flat()
    return certified_right_roots(q, frequency_scale(q))


def test_two_delay_direction_matches_a_bisection_on_the_root_count():
    # Oracle: a second method, the certified right-half-plane root count along the ray
    # tau0 + t (1/2, 1) (damping moves twice as fast as stiffness): the first t of a
    # coarse grid where the count is positive, then bisection to 1e-9 s.
    r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.0})
    m = r.delay_margin({"stiffness": 1, "damping": 2})
    assert m.direction == {"stiffness": 0.5, "damping": 1.0}
    t = r.delay_terms()
    tau0 = t.delays_s
    dhat = np.array([{"stiffness": 0.5, "damping": 1.0}[n] for n in t.names])
    grid = np.linspace(0.0, 0.05, 51)
    counts = _count(t, tau0[:, None] + grid[None, :] * dhat[:, None])
    assert counts[0] == 0
    first = int(np.argmax(counts > 0))
    lo, hi = grid[first - 1], grid[first]
    while hi - lo > 1e-9:
        mid = 0.5 * (lo + hi)
        if _count(t, (tau0 + mid * dhat)[:, None])[0] == 0:
            lo = mid
        else:
            hi = mid
    assert abs(float(m.delay_margin_s) - 0.5 * (lo + hi)) < 2e-9
    np.testing.assert_allclose(m.crossing_delays_s["stiffness"],
                               tau0[t.index("stiffness")] + 0.5 * float(m.delay_margin_s))


def test_a_batch_equals_its_designs_one_by_one():
    # Oracle: the same designs built and analysed one at a time.
    kw = {"delays_ms": {"torque": 0.5, "stiffness": 2, "damping": 0.5}, "filters_hz": (50, 100)}
    direction = {"torque": 1, "damping": 2}
    batch = sc.design([12, 14, 16], **kw).delay_margin(direction)
    for i, fn in enumerate([12, 14, 16]):
        one = sc.design(fn, **kw).delay_margin(direction)
        assert float(one.delay_margin_s) == pytest.approx(batch.delay_margin_s[i], rel=1e-12)
        assert float(one.crossing_hz) == pytest.approx(batch.crossing_hz[i], rel=1e-12)
    rows = batch.records()
    assert [r["fn_hz"] for r in rows] == [12.0, 14.0, 16.0]
    assert set(rows[0]["crossing_delays_s"]) == {"stiffness", "damping", "torque"}


def test_unstable_design_has_margin_zero():
    # Oracle: the certified root count of roots() (this design is unstable at its delays).
    d = sc.design(15.93, gs=1.867, delays_ms={"torque": 1.99, "stiffness": 1.96,
                                              "damping": 18.54})
    assert not bool(d.roots(count=1).stable)
    m = d.delay_margin()
    assert float(m.delay_margin_s) == 0.0 and not bool(m.stable)
    assert math.isnan(float(m.crossing_hz))


@pytest.mark.parametrize("direction, match", [
    ({"stiffness": 1, "damping": math.sqrt(2)}, "commensurate"),
    ({"bogus": 1}, "stiffness"),
    ({"stiffness": -1}, ">= 0"),
    ({"stiffness": 0}, "not all 0"),
    ([1.0], "2 weights"),
])
def test_bad_directions_are_refused(direction, match):
    # Behaviour: each bad direction raises an InputError that says what is valid.
    r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.0})
    with pytest.raises(sc.InputError, match=match):
        r.delay_margin(direction)
