"""Generic block diagrams: derivation, loops, the on-disk expression cache."""

from types import SimpleNamespace

import numpy as np
import sympy as sp

from seactl import blockdiagram as bd
from seactl.blockdiagram import Block, BlockDiagram


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
