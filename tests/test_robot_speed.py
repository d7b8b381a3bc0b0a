"""A robot's loop breaks share one evaluation of the characteristic terms, and the MIMO
loop matrix evaluates its blocks together: the numbers are those of the independent paths.

Oracles: each break's certified margins computed on its own (its ``N`` and ``D`` evaluated
alone, as :meth:`seactl.System.margins` does for one break); a direct evaluation of the
characteristic quasi-polynomials written here (numpy's polynomial products term by term);
every block's own ``response`` for the loop matrix; the SEA's own diagram
(``sc.design(14)``, Table I) for a one-link robot.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")

import seactl as sc  # noqa: E402
from seactl.analysis.margins import default_grid, loop_margins  # noqa: E402
from seactl.diagram.blockdiagram import constant_gain, evaluate_forms  # noqa: E402

ARM = Path(__file__).resolve().parents[1] / "examples" / "robots" / "planar_2link.urdf"
TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))
KEYS = ("phase_margin_deg", "crossover_hz", "gain_margin", "phase_crossover_hz",
        "delay_margin_ms")


def one_link(tmp_path: Path) -> Path:
    """A 1-link URDF with the UT-SEA's joint inertia and damping (as tests/test_robot.py)."""
    a = sc.UT_SEA
    path = tmp_path / "one.urdf"
    path.write_text(f"""<?xml version="1.0"?>
<robot name="one"><link name="base"/>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="100" velocity="10"/>
<dynamics damping="{a.bj!r}"/></joint>
<link name="l1"><inertial><mass value="1"/>
<inertia ixx="1e-3" iyy="1e-3" izz="{a.Ij!r}" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>""")
    return path


def same(a: float, b: float) -> bool:
    """Equal to 1e-9 relative (both NaN, or both the same infinity, count as equal)."""
    if np.isnan(a) or np.isnan(b):
        return bool(np.isnan(a) and np.isnan(b))
    return a == b or abs(a - b) <= 1e-9 * abs(b)


@pytest.mark.parametrize("options", [dict(q0=[0.3, 0.8]),
                                     dict(q0=[0.0, 1.5], space="task", task="tool")])
def test_every_break_equals_its_own_certified_margins(options):
    """Oracle: loop_margins of each break alone (its forms evaluated without the others)."""
    r = sc.robot(ARM, fn_hz=14, **options, **TABLE_I)
    got = r.margins_by_break()
    grid = default_grid(r.reference_frequency())
    for name, signal in r.breaks.items():
        alone = loop_margins(r.diagram.loop(signal), r.design, grid)
        for key in KEYS:
            assert same(float(getattr(got[name], key)), float(getattr(alone, key))), \
                (name, key)
        assert bool(got[name].stable) == bool(alone.stable)
        assert int(got[name].unstable_poles) == int(alone.unstable_poles)
    m = r.margins()   # (after the breaks: the shared terms again)
    assert all(same(float(getattr(m, k)), float(getattr(got["outer.j1"], k))) for k in KEYS)


def test_one_link_breaks_are_the_sea_design(tmp_path):
    """Oracle: sc.design(14) with the same delays and filters (Table I: PM 43.26 deg), its
    own diagram and loop broken at the same sensor."""
    r = sc.robot(one_link(tmp_path), fn_hz=14, **TABLE_I)
    d = sc.design(14, **TABLE_I).margins()
    got = r.margins_by_break()["outer.j1"]
    assert round(float(got.phase_margin_deg), 2) == 43.26
    for key in KEYS:
        assert same(float(getattr(got, key)), float(getattr(d, key))), key


def direct(form, design, s: np.ndarray) -> np.ndarray:
    """``sum_terms coef prod_b (num_b if b in the term else den_b)(s) e^{-s sum tau}``
    over the form's dynamic blocks, each product by numpy's polymul."""
    out = np.zeros(s.shape, complex)
    dynamic = [b for b in form.diagram.blocks if constant_gain(b) is None]
    for coef, blocks in form.terms:
        p, tau = np.array([coef]), 0.0
        for b in dynamic:
            num, den = b.coefficients(design)
            p = np.polymul(p, [float(c) for c in (num if b.name in blocks else den)])
            if b.name in blocks and b.delay is not None:
                tau += float(getattr(design, b.delay))
        out += np.polyval(p, s) * np.exp(-s * tau)
    return out


def test_shared_terms_evaluate_the_forms_exactly():
    """Oracle: direct(), for a break's N and D evaluated after another break's (the shared
    terms then come from the cache)."""
    r = sc.robot(ARM, fn_hz=14, q0=[0.3, 0.8], space="task", task="tool", **TABLE_I)
    design, shared = r.design, {}
    evaluate_forms(r.diagram.return_difference("qd.j2"), design, shared)
    forms = r.diagram.return_difference("qs.j1")
    s = np.array([3j, 80j, 2.0 + 700j])
    for form, q in zip(forms, evaluate_forms(forms, design, shared)):
        want = direct(form, design, s)
        got = q(s)[0]
        assert np.allclose(got, want, rtol=1e-12, atol=0), form


def test_loop_matrix_is_the_blocks_own_responses():
    """Oracle: the loop matrix solved from every block's own ``response`` (the graph of
    the characteristic-loci module's definition), at frequencies across the band."""
    from seactl.analysis.characteristic_loci import loop_matrix

    r = sc.robot(ARM, fn_hz=14, q0=[0.3, 0.8], space="task", task="tool", **TABLE_I)
    d, design = r.diagram, r.design
    breaks = [f"qs.j{j + 1}" for j in range(2)]
    returns = [f"q_sens.j{j + 1}" for j in range(2)]
    w = np.array([0.3, 20.0, 150.0, 4000.0])
    got = loop_matrix(d, design, returns, breaks)(w)
    index = {x: i for i, x in enumerate(d.signals)}
    held = set(d.inputs) | set(breaks)
    for f, wf in enumerate(w):
        a = np.zeros((len(index),) * 2, complex)
        for b in d.blocks:
            if b.dst not in held:
                a[index[b.dst], index[b.src]] += complex(
                    np.ravel(b.response(design, np.array([1j * wf])))[0])
        rhs = np.zeros((len(index), 2))
        rhs[[index[x] for x in breaks], [0, 1]] = 1.0
        x = np.linalg.solve(np.eye(len(index)) - a, rhs)
        want = -x[[index[y] for y in returns], :]
        assert np.allclose(got[f], want, rtol=1e-12, atol=1e-14 * np.abs(want).max())
