"""Generic block diagrams: derivation, loops, the on-disk expression cache."""

from types import SimpleNamespace

import numpy as np
import sympy as sp

from seactl import blockdiagram as bd
from seactl.blockdiagram import (
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
