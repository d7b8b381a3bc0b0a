"""Generic block diagrams: derivation, loops, the on-disk expression cache."""

from types import SimpleNamespace

import numpy as np
import sympy as sp

from seactl.diagram import blockdiagram as bd
from seactl.diagram.blockdiagram import (
    EVAL_ROUNDING,
    Block,
    BlockDiagram,
    QuasiPolynomial,
    rounding_majorant,
)


def feedback_diagram():
    # y = G e, e = r - H y  =>  y/r = G / (1 + G H), loop at the sensor: G H
    return BlockDiagram("fb", [
        Block("G", "e", "y", num=lambda p: (p.k,), den=lambda p: (1.0, p.a)),
        Block("H", "y", "m", num=lambda p: (p.h,), delay="T"),
        Block("ref", "r", "e"),
        Block("neg", "m", "e", num=lambda p: (-1.0,)),
    ])


def test_transfer_and_loop_against_closed_form():
    # Oracle: the feedback loop solved by hand, y/r = G/(1 + G H) and loop G H.
    d = feedback_diagram()
    p = SimpleNamespace(k=np.array([2.0, 3.0]), a=np.array([1.0, 5.0]), h=np.array(0.5),
                        T=np.array([0.0, 0.01]))
    s = 1j * np.logspace(-1, 2, 7)
    G = p.k[:, None] / (s + p.a[:, None])
    H = p.h * np.exp(-s * p.T[:, None])
    np.testing.assert_allclose(d.transfer("y", "r")(p, s), G / (1 + G * H), rtol=1e-12)
    np.testing.assert_allclose(d.loop("m")(p, s), G * H, rtol=1e-12)
    assert d.inputs == ("r",)


def test_expression_cache_roundtrip_and_damage(tmp_path, monkeypatch):
    # Oracle: the freshly derived expression (sympy.simplify of the difference is 0) and the
    # cache directory's listing.
    monkeypatch.setenv("SEACTL_CACHE_DIR", str(tmp_path))
    d = feedback_diagram()
    bd._symbolic.cache_clear()
    fresh = bd._symbolic(d, "y", "r", (), None)
    files = list(tmp_path.glob("*.srepr"))
    assert len(files) == 1
    bd._symbolic.cache_clear()
    assert sp.simplify(bd._symbolic(d, "y", "r", (), None) - fresh) == 0
    files[0].write_text("Mul(Symbol('G'),")          # a damaged entry is derived again
    bd._symbolic.cache_clear()
    assert sp.simplify(bd._symbolic(d, "y", "r", (), None) - fresh) == 0
    # a structural change (another constant) never reuses the old entry
    d2 = BlockDiagram("fb", [*d.blocks[:3], Block("neg", "m", "e", num=lambda p: (1.0,))])
    bd._symbolic.cache_clear()
    expr2 = bd._symbolic(d2, "y", "r", (), None)
    assert sp.simplify(expr2 - fresh) != 0
    bd._symbolic.cache_clear()


def test_cache_off(tmp_path, monkeypatch):
    # Oracle: the cache directory's listing (nothing written).
    monkeypatch.setenv("SEACTL_CACHE_DIR", "off")
    bd._symbolic.cache_clear()
    bd._symbolic(feedback_diagram(), "y", "r", (), None)
    bd._symbolic.cache_clear()
    assert not list(tmp_path.iterdir())


def test_rounding_majorant_covers_the_phase_error_of_long_delays():
    # Oracle: mpmath at 50 digits on the same quasi-polynomial at the same (double) w. At
    # w tau ~ 3e4 the rounding of the phase w tau alone exceeds EVAL_ROUNDING times the
    # coefficient majorant; rounding_majorant's phase term covers it.
    import mpmath

    rng = np.random.default_rng(0)
    coeffs = rng.normal(size=(3, 1, 4))
    delays = np.array([[0.0], [0.03], [0.0123]])
    q = QuasiPolynomial(coeffs, delays)
    w = np.logspace(0, 6, 200)
    val = q(1j * w[None, :])[0]
    mpmath.mp.dps = 50
    exact = [sum(mpmath.polyval([mpmath.mpf(c) for c in coeffs[k, 0, ::-1]], 1j * mpmath.mpf(x))
                 * mpmath.exp(-1j * mpmath.mpf(x) * mpmath.mpf(delays[k, 0])) for k in range(3))
             for x in w]
    err = np.array([float(abs(mpmath.mpc(complex(v)) - e)) for v, e in zip(val, exact)])

    def at(c):
        return np.polynomial.polynomial.polyval(w, c[0])

    assert np.all(err <= EVAL_ROUNDING * at(rounding_majorant(q.abs_coeffs, delays.max(axis=0))))
    assert np.any(err > EVAL_ROUNDING * at(q.abs_coeffs))


def test_third_derivative_majorant():
    """QuasiPolynomial.bound3_coeffs (compiled, seactl.diagram.majorants) on random
    quasi-polynomials with 1-4 terms, up to degree 8, batch shapes (), (5,) and (3, 4):
    (a) the polynomial equals the definition summed term by term in Python,
    sum_kji |c_kj| C(3, i) j!/(j - i)! w^(j - i) tau_k^(3 - i) (oracle), at random w;
    (b) it bounds |d^3 Q(jw)/dw^3|, taken as the central difference of the numpy Horner
    pass's second derivative (a second oracle), at 200 frequencies."""
    from math import comb, factorial

    from numpy.polynomial.polynomial import polyval

    rng = np.random.default_rng(8)
    for K, shape, P in [(1, (), 1), (2, (5,), 3), (3, (3, 4), 7), (4, (5,), 9)]:
        size = (K,) + shape + (P,)
        c = rng.standard_normal(size) * 10.0 ** rng.uniform(-3, 3, size)
        tau = rng.uniform(0.0, 0.02, (K,) + shape)
        tau[0] = 0.0
        q = QuasiPolynomial(c, tau)
        b3 = q.bound3_coeffs
        assert b3.shape == shape + (P,)
        flat_c, flat_t, flat_b = c.reshape(K, -1, P), tau.reshape(K, -1), b3.reshape(-1, P)
        w = rng.uniform(0.0, 300.0, flat_b.shape[0])
        ref = [sum(abs(flat_c[k, d, j]) * comb(3, i) * factorial(j) / factorial(j - i)
                   * w[d] ** (j - i) * flat_t[k, d] ** (3 - i)
                   for k in range(K) for j in range(P) for i in range(min(3, j) + 1))
               for d in range(w.size)]
        got = [polyval(w[d], flat_b[d]) for d in range(w.size)]
        np.testing.assert_allclose(got, ref, rtol=1e-12)
        w = np.linspace(0.1, 300.0, 200)
        h = 1e-4 * w
        s = np.broadcast_to(1j * np.stack([w + h, w - h]), shape + (2, w.size))
        d2 = q.with_derivative(s.reshape(shape + (-1,)), second=True)[2]
        d2 = d2.reshape(shape + (2, w.size))
        third = np.abs(d2[..., 0, :] - d2[..., 1, :]) / (2 * h)
        bound = polyval(w, b3[..., None, :].reshape(-1, P).T, tensor=True).reshape(
            shape + (w.size,))
        assert np.all(third <= 1.000001 * bound + 1e-9 * np.abs(d2).max())


def test_forms_share_blocks_and_products_bit_for_bit():
    """A loop's N and D evaluated together (blockdiagram.evaluate_forms, sharing their
    blocks' coefficients and partial products, as the margins, jitter and passivity
    proofs do) equal each evaluated alone, bit for bit (oracle: the unshared evaluation),
    on the SEA loop and the impedance forms."""
    from seactl.apps.bench.core import random_designs
    from seactl.diagram.blockdiagram import evaluate_forms
    from seactl.systems.sea.impedance import impedance_forms
    from seactl.systems.sea.loops import outer_loop

    _, d = random_designs(50, seed=3)
    loop = outer_loop()
    for forms in (loop.diagram.return_difference(loop.input, loop.cut), impedance_forms()):
        for a, f in zip(evaluate_forms(forms, d), forms):
            b = f.evaluate(d).flat()
            np.testing.assert_array_equal(a.coeffs, b.coeffs)
            np.testing.assert_array_equal(a.delays, b.delays)


def test_degrees_and_columnwise_reductions_by_definition():
    """``degree``, ``delayed_degree`` (the last nonzero power, column by column) and
    :func:`~seactl.diagram.blockdiagram.columnwise`.  Oracle: the definitions, element by element
    in Python, on random sparse coefficients (batch shapes (7,) and (3, 4); rows all zero,
    NaN and inf among them) and numpy's reductions over the last axis."""
    from seactl.diagram.blockdiagram import QuasiPolynomial, columnwise

    rng = np.random.default_rng(11)
    for shape in ((7,), (3, 4)):
        for powers in (1, 3, 8):
            c = rng.normal(size=(3, *shape, powers)) * (rng.random((3, *shape, powers)) < 0.4)
            c.flat[rng.integers(0, c.size, 3)] = [np.nan, np.inf, -np.inf]
            q = QuasiPolynomial(c, rng.uniform(0, 0.01, (3, *shape)))

            def last(rows, powers=powers):
                return max((j for j in range(powers) if any(r[j] != 0 for r in rows)),
                           default=-1)
            for idx in np.ndindex(shape):
                assert q.degree[idx] == last([c[0][idx]])
                assert q.delayed_degree[idx] == last([c[k][idx] for k in (1, 2)])
            for ufunc in (np.maximum, np.minimum, np.logical_or):
                np.testing.assert_array_equal(columnwise(ufunc, c), ufunc.reduce(c, axis=-1))
