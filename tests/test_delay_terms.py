"""``System.delay_terms``: the characteristic as a function of named delays.

Oracle: the diagram's own characteristic quasi-polynomial (``QuasiForm.evaluate``), evaluated
at the same points; and, for the rigid actuator, the delays moved: the terms must follow the
exponents (term delays are sums of the loops' delays).
"""

import numpy as np
import pytest

import seactl as sc

SYSTEMS = [
    lambda: sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                      filters_hz=(50, 100)),
    lambda: sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.0}),
    lambda: sc.load_loop("examples/loops/paper-sea.toml"),
]


@pytest.mark.parametrize("make", SYSTEMS)
def test_delay_terms_equal_the_characteristic(make):
    s = make()
    t = s.delay_terms()
    assert t.names == s.loops or set(t.names) == set(s.loops)
    for name in t.names:
        np.testing.assert_allclose(t.delays_s[t.index(name)], s.delays_s[name], rtol=0)
    q = t.at()
    ref = s.diagram.characteristic().evaluate(s.design)
    pts = np.array([0.5 + 30j, -2 + 400j, 10 + 3000j])
    z = np.broadcast_to(pts, q.shape + (3,))
    np.testing.assert_allclose(q(z), ref(z), rtol=1e-12)


def test_moved_delays_follow_the_exponents():
    base = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.0})
    moved = sc.rigid(8, delays_ms={"stiffness": 2.5, "damping": 0.25})
    t = base.delay_terms()
    tau = np.array([{"stiffness": 2.5e-3, "damping": 0.25e-3}[n] for n in t.names])
    q = t.at(tau)
    ref = moved.diagram.characteristic().evaluate(moved.design)
    z = np.array([1 + 50j, 3 + 700j])
    np.testing.assert_allclose(q(z), ref(z), rtol=1e-12)
    with pytest.raises(sc.InputError):
        t.index("torque")
