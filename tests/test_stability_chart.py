"""``System.stability_chart``: crossing curves and certified counts over two delays.

Oracles: (a) the closed-form crossing set of ``s + a + b1 e^{-s tau1} + b2 e^{-s tau2}``
(the triangle construction of Gu, Niculescu & Chen, J. Math. Anal. Appl. 311 (2005), Sec. 3:
``a0(jw) + b1 z1 + b2 z2 = 0`` closes a triangle of sides ``|a0|, |b1|, |b2|``, whose angles
follow from the law of cosines); (b) the islands of delay-induced stability of an unstable
oscillator, located by first-order perturbation and confirmed by an independent
argument-principle count written here; (c) ``margins().stable`` and the roots of
``quasi_roots`` (Chebyshev collocation, Newton) on the crossing curves; (d) the CLI
contract (JSON keys and units, a PNG written, one-line errors with exit 2).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import seactl as sc
from seactl.analysis.crossing_curves import crossing_branches
from seactl.analysis.margins import certified_right_roots
from seactl.analysis.roots import frequency_scale, quasi_roots
from seactl.analysis.torus import TorusPolynomial, torus_solutions
from seactl.apps.cli import main
from seactl.diagram.delayterms import DelayTerms

TWO_PI = 2 * np.pi


class Equation(sc.System):
    """A one-design system given by its characteristic ``DelayTerms`` (as the delay
    equations of ``sc.delay_equation`` are)."""

    kind = "equation"
    loops = ("tau1", "tau2")
    shape = ()

    def __init__(self, coeffs, delays_s=(0.0, 0.0)):
        self._terms = DelayTerms(np.asarray(coeffs, float)[:, None, :],
                                 np.array([[0, 0], [1, 0], [0, 1]]), self.loops,
                                 np.asarray(delays_s, float)[:, None])

    def delay_terms(self):
        return self._terms


def triangle(w, a, b1, b2):
    """Gu-Niculescu-Chen: the two (theta1, theta2) = (w tau1, w tau2) mod 2 pi with
    ``jw + a + b1 e^{-j theta1} + b2 e^{-j theta2} = 0`` (NaN outside the crossing set)."""
    a0 = 1j * w + a
    r = np.abs(a0)
    with np.errstate(invalid="ignore"):
        phi1 = np.arccos((r**2 + b1**2 - b2**2) / (2 * r * b1))   # angle at the b1 side
    out = []
    for sign in (1, -1):
        u = b1 * np.exp(1j * (np.angle(-a0) + sign * phi1))     # b1 z1; then b2 z2 = -a0 - u
        out.append((np.mod(-np.angle(u / b1), TWO_PI), np.mod(-np.angle((-a0 - u) / b2),
                                                                TWO_PI)))
    return out


def angle_gap(x, y):
    d = np.mod(x - y, TWO_PI)
    return np.minimum(d, TWO_PI - d)


# ------------------------------------------------------------------ (a) closed form
A, B1, B2 = 1.0, 2.0, 1.5


def test_curve_points_are_the_closed_form_crossing_set():
    terms = Equation([[A, 1.0], [B1, 0.0], [B2, 0.0]]).delay_terms()
    tp = TorusPolynomial.of(terms, 0, 1)
    branches = crossing_branches(tp, (5.0, 5.0))
    assert branches
    for b in branches:
        th1, th2 = np.mod(b.w_rad_s * b.tau1_s, TWO_PI), np.mod(b.w_rad_s * b.tau2_s, TWO_PI)
        sols = triangle(b.w_rad_s, A, B1, B2)
        err = np.minimum(*[np.maximum(angle_gap(th1, s1), angle_gap(th2, s2))
                           for s1, s2 in sols])
        # (at the ends of the crossing set the triangle is flat and arccos ill-conditioned:
        # there the closed form itself carries ~1e-16 / sqrt(distance to the end))
        r = np.abs(1j * b.w_rad_s + A)
        flat = np.minimum(np.abs(r - abs(B1 - B2)), np.abs(r - (B1 + B2))) < 1e-6
        assert np.all(np.isfinite(err))
        assert np.max(err[~flat], initial=0) < 1e-10 and np.max(err, initial=0) < 1e-7
    # every closed-form solution is found, at frequencies across the crossing set
    # (|B1 - B2| <= |jw + A| <= B1 + B2)
    w = np.linspace(0.05, np.sqrt((B1 + B2) ** 2 - A**2) - 1e-6, 40)
    th1, th2 = torus_solutions(tp, w)
    sols = triangle(w, A, B1, B2)
    for s1, s2 in sols:
        d = np.min(np.maximum(angle_gap(th1, s1[:, None]), angle_gap(th2, s2[:, None])),
                   axis=1)
        assert np.max(d) < 1e-10
    assert (np.isfinite(th1).sum(axis=1) == 2).all()


# ------------------------------------------------------------------ (b) thin islands
EPS, B = 0.16, 0.1
MAX = 20.0


def independent_right_roots(tau1, tau2):
    """Roots of ``s^2 - EPS s + 1 + B e^{-s tau1} + B e^{-s tau2}`` with ``Re s > 0``, by the
    winding number of Delta around a rectangle that holds them all: for ``Re s >= 0`` a root
    needs ``|s - z+| |s - z-| <= 2 B`` (``|e^{-s tau}| <= 1``), with ``z+- = EPS/2 +- j
    sqrt(1 - EPS^2/4)``; for ``Im s >= 0``, ``|s - z-| >= 0.99``, so ``|s - z+| <= 0.21``:
    inside ``[0, 0.3] x [0.75, 1.25] j``.  Conjugates counted."""
    n = 4000
    t = np.linspace(0, 1, n, endpoint=False)
    x0, x1, y0, y1 = 0.0, 0.3, 0.75, 1.25
    edges = [x0 + (x1 - x0) * t + 1j * y0, x1 + 1j * (y0 + (y1 - y0) * t),
             x1 - (x1 - x0) * t + 1j * y1, x0 + 1j * (y1 - (y1 - y0) * t)]
    s = np.concatenate(edges)
    d = s**2 - EPS * s + 1 + B * np.exp(-s * tau1) + B * np.exp(-s * tau2)
    step = np.angle(np.roll(d, -1) / d)
    assert np.abs(step).max() < np.pi / 4 and np.abs(d).min() > 1e-6
    return 2 * int(round(step.sum() / TWO_PI))


def test_thin_stable_islands_found_where_a_grid_misses_them():
    # The unstable oscillator s^2 - EPS s + 1 stabilized by two delayed feedbacks: to first
    # order in B, a root near j moves by EPS/2 + B (sin tau1 + sin tau2) / 2, so the stable
    # set is a sequence of islands around tau = (3 pi/2 + 2 pi k, 3 pi/2 + 2 pi l), thin as
    # EPS approaches 2 B.  The islands with k + l <= 2 lie in [0, 20]^2.
    system = Equation([[1.0, -EPS, 1.0], [B, 0.0, 0.0], [B, 0.0, 0.0]], (0.5, 0.5))
    chart = system.stability_chart(("tau1", "tau2"), (MAX, MAX))
    assert chart.consistent and len(chart.checks) > 50
    stable = chart.region_points_s[chart.region_right_roots == 0]
    g = np.linspace(0, MAX, 40)
    grid = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    q = system.delay_terms().at(grid.T).flat()
    grid_stable = grid[certified_right_roots(q, frequency_scale(q)) == 0]
    missed = 0
    for k, el in [(0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1)]:
        centre = 1.5 * np.pi + TWO_PI * np.array([k, el])
        found = stable[np.hypot(*(stable - centre).T) < 1.2]
        assert len(found), (k, el)
        assert all(independent_right_roots(*p) == 0 for p in found)
        missed += not (np.hypot(*(grid_stable - centre).T) < 1.2).any()
    assert missed >= 1
    assert not chart.design_stable and independent_right_roots(0.5, 0.5) == 2
    # A second derivation: the same equation drawn as a block diagram, time in ms
    # (examples/loops/delayed-oscillator.toml), has the same islands, scaled by 1e-3.
    loop = sc.load_loop("examples/loops/delayed-oscillator.toml")
    ms = loop.stability_chart(("feedback1", "feedback2"), (MAX * 1e-3, MAX * 1e-3))
    islands = ms.region_points_s[ms.region_right_roots == 0] * 1e3
    assert len(islands) == len(stable)
    assert np.hypot(*(islands[:, None] - stable[None]).T).min(axis=0).max() < 0.05


# ------------------------------------------------------------------ (c) actuators
@pytest.mark.parametrize("make", [
    lambda: sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}),
    lambda: sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                      filters_hz=(50, 100)),
])
def test_actuator_chart_agrees_with_margins_and_roots(make):
    system = make()
    chart = system.stability_chart(("stiffness", "damping"), (0.02, 0.02), resolution=400)
    assert chart.design_stable == bool(system.margins().stable)
    assert chart.consistent and chart.checks
    assert {0, 2} <= set(chart.region_right_roots.tolist())
    terms = system.delay_terms()
    i1, i2 = terms.index("stiffness"), terms.index("damping")
    for c in chart.curves[:2]:
        k = len(c["w_rad_s"]) // 2
        tau = np.broadcast_to(terms.delays_s, terms.delays_s.shape).copy()
        tau[i1], tau[i2] = c["tau1_s"][k], c["tau2_s"][k]
        roots = quasi_roots(terms.at(tau), count=4).roots.ravel()
        hit = np.abs(roots - 1j * c["w_rad_s"][k]).min()
        assert hit < 1e-6 * c["w_rad_s"][k]


def test_a_batch_asks_for_one_design():
    with pytest.raises(sc.InputError, match=r"system\[i\]"):
        sc.rigid([8, 12]).stability_chart(("stiffness", "damping"), (0.02, 0.02))
    with pytest.raises(sc.InputError, match="one of"):
        sc.rigid(8).stability_chart(("stiffness", "torque"), (0.02, 0.02))
    with pytest.raises(sc.InputError, match="max_s"):
        sc.rigid(8).stability_chart(("stiffness", "damping"), (0.02, -1))


@pytest.mark.parametrize("huge_s", [1e305, 1e200, 1e9])
def test_a_chart_too_large_is_refused_up_front(huge_s):
    # Oracle: the error contract: an extent whose crossing curves would have more pieces
    # than the budget (or whose bounds overflow) is an InputError naming max_s, raised
    # before any array of that size is made.
    with pytest.raises(sc.InputError, match="a smaller chart"):
        sc.rigid(8).stability_chart(("stiffness", "damping"), (huge_s, 0.02))


def test_a_huge_extent_on_one_axis_is_refused_not_out_of_memory():
    # Oracle: the error contract. The SEA's stiffness/damping chart with a huge first extent
    # and a small second one has chains none of whose copies enter the chart along the
    # second delay while the first range of copies is enormous: that must be skipped, not
    # allocated (it was a MemoryError), and the chart refused as too large.
    with pytest.raises(sc.InputError, match="a smaller chart"):
        sc.design(14).stability_chart(("stiffness", "damping"), (1e9, 5e-3))


# ------------------------------------------------------------------ (d) command line
def test_cli_json_plot_and_errors(tmp_path, capsys):
    png = tmp_path / "chart.png"
    code = main(["chart", "--system", "rigid", "--fn", "8", "--t-s", "1.5", "--t-d", "1.5",
                 "--delays", "stiffness,damping", "--max-ms", "20,20", "--resolution", "300",
                 "--plot", str(png), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out["system"] == "rigid" and out["max_s"] == [0.02, 0.02]
    assert out["design"] == {"tau1_s": 0.0015, "tau2_s": 0.0015,
                             "right_half_plane_roots": 0, "stable": True}
    assert set(out["curves"][0]) == {"tau1_s", "tau2_s", "w_rad_s"}
    assert {r["right_half_plane_roots"] for r in out["regions"]} == {0, 2}
    for args, flag in [("--fn 14 --delays stiffness,nope --max-ms 20,20", "--delays"),
                       ("--fn 14 --delays stiffness,damping --max-ms 20", "--max-ms"),
                       ("--fn 14 16 --delays stiffness,damping --max-ms 20,20", "--fn")]:
        code = main(["chart", *args.split()])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and err.startswith(f"error: invalid {flag}")


@pytest.mark.parametrize("option, value, needle", [
    ("--max-ms", "0,5", "two finite delays > 0 [ms]"),
    ("--max-ms", "1e12,20", "a smaller chart"),
    ("--max-s", "0,1", "two finite delays > 0 [s]"),
])
def test_cli_extent_errors_name_the_option_typed_in_its_unit(capsys, option, value, needle):
    # Oracle: the error contract: a bad extent is reported on the option the user typed,
    # with the value as typed (milliseconds for --max-ms) and the range in that unit;
    # the library's name (max_s, seconds) never reaches the user of --max-ms.
    code = main(["chart", "--system", "rigid", "--fn", "8", "--t-s", "1.5", "--t-d", "1.5",
                 "--delays", "stiffness,damping", option, value])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: invalid {option} = '{value}': must be "), err
    assert needle in err
    if option == "--max-ms":
        assert "--max-s " not in err and "[s]" not in err
