"""Robots of more than three joints: the characteristic built joint by joint
(seactl.systems.robot.characteristic) against the whole diagram's graph determinant
(Mason, the CycleDiagram) where both exist, and on a 4-link arm against the root at the
margin and the generalized Nyquist loci of the numeric loop matrix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from seactl.analysis.delay_direction import direction_margin
from seactl.analysis.margins import certified_right_roots
from seactl.analysis.roots import frequency_scale, quasi_roots
from seactl.api.robotlarge import large_delay_terms
from seactl.apps.cli import main

pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")

ROBOTS = Path(__file__).resolve().parents[1] / "examples" / "robots"
DELAYS_MS = {"torque": 0.5, "stiffness": 2, "damping": 0.5}
FOUR = dict(q0=[0.3, 0.8, -0.5, 0.4], fn_hz=60, filters_hz=(200, 400))
FOUR_DELAYS_MS = {"torque": 0.1, "stiffness": 1, "damping": 0.1}


def _verdict(terms) -> int:
    q = terms.at().flat()
    return int(certified_right_roots(q, frequency_scale(q))[0])


@pytest.mark.parametrize("urdf,q0,space,fn_hz,joints", [
    ("planar_2link.urdf", [0.3], "joint", 14, ["j1"]),
    ("planar_2link.urdf", [0.3, 0.8], "joint", 14, None),
    ("planar_2link.urdf", [0.3, 0.8], "task", 14, None),
    ("planar_3link.urdf", [0.3, 0.8, -0.5], "task", 50, None),
    ("planar_3link.urdf", [0.3, 0.8, -0.5], "joint", 50, None),
])
def test_joint_by_joint_is_the_diagrams_determinant(urdf, q0, space, fn_hz, joints):
    """Oracle: the Mason graph determinant of the whole robot diagram (its cycles), at
    random complex s.  The only factor between them is det(M)^-1: the diagram carries the
    rigid body as its inverse mass matrix (the Minv blocks), Q as M itself.  The certified
    verdicts, the central delay margins and the rightmost roots of both agree."""
    r = sc.robot(ROBOTS / urdf, q0=q0, joints=joints, space=space, task="tool",
                 fn_hz=fn_hz, delays_ms=DELAYS_MS, filters_hz=(50, 100))
    mason, ours = r.delay_terms(), large_delay_terms(r)
    rng = np.random.default_rng(7)
    s = (rng.normal(size=8) * 300 + 1j * rng.normal(size=8) * 3000)[None]
    ratio = mason.at().flat()(s) / ours.at().flat()(s)
    np.testing.assert_allclose(ratio * np.linalg.det(r.body.mass_matrix), 1.0, rtol=1e-9)
    assert _verdict(mason) == _verdict(ours)
    a = direction_margin(mason, {"stiffness": 1}).delay_margin_s
    b = direction_margin(ours, {"stiffness": 1}).delay_margin_s
    np.testing.assert_allclose(b, a, rtol=1e-9)
    roots = [quasi_roots(t.at(), count=2).roots for t in (mason, ours)]
    np.testing.assert_allclose(roots[1], roots[0], rtol=1e-8)


@pytest.fixture(scope="module")
def four():
    return sc.robot(ROBOTS / "planar_4link.urdf", delays_ms=FOUR_DELAYS_MS, **FOUR)


def test_four_links_flip_at_the_central_delay_margin(four):
    """Oracles: the certified verdict flips between 0.999x and 1.001x of the central delay
    margin; at the margin Newton's iteration on the characteristic from near the crossing
    converges to a root on the imaginary axis at the crossing frequency; the generalized
    Nyquist loci of the numeric loop matrix (no characteristic) cross -1 at the same
    frequency and extra latency."""
    assert four.large and four.n == 4
    dm = four.delay_margin({"stiffness": 1})
    extra, hz = float(dm.delay_margin_s), float(dm.crossing_hz)
    assert 0 < extra < 1

    def at(factor):
        d = dict(FOUR_DELAYS_MS, stiffness=FOUR_DELAYS_MS["stiffness"] + 1e3 * factor * extra)
        return sc.robot(ROBOTS / "planar_4link.urdf", delays_ms=d, **FOUR)

    assert bool(at(0.999).margins().stable) and not bool(at(1.001).margins().stable)
    q = at(1.0).delay_terms().at().flat()
    root = np.array([[2j * np.pi * hz * (1 + 1e-3)]])  # (Newton from near the crossing)
    for _ in range(30):
        root = root - q(root) / q(root, derivative=True)
    assert abs(root.real[0, 0]) < 1e-6 * abs(root.imag[0, 0])
    np.testing.assert_allclose(root.imag[0, 0], 2 * np.pi * hz, rtol=1e-6)
    m = four.mimo_margins()
    assert m.stable
    np.testing.assert_allclose([m.delay_margin_s, m.delay_crossing_hz], [extra, hz], rtol=1e-6)


def test_four_links_refuse_the_transfer_views(four):
    """A behaviour: views that need the loop's transfers are refused naming `joints` and
    the views that work; margins() gives the verdict with its margins NaN."""
    m = four.margins()
    assert bool(m.stable) and np.isnan(m.phase_margin_deg)
    for view in (four.margins_by_break, lambda: four.impedance_matrix([1.0]), four.roots):
        with pytest.raises(sc.InputError) as info:
            view()
        assert info.value.field == "joints" and "mimo_margins()" in info.value.valid


def test_cli_four_links(capsys):
    """A behaviour: `seactl robot` on 4 joints prints the verdict, a note instead of the
    per-break table, and the MIMO row (its delay margin the API's)."""
    args = ["robot", "--urdf", str(ROBOTS / "planar_4link.urdf"), "--q0", "0.3,0.8,-0.5,0.4",
            "--fn", "60", "--t-tau", "0.1", "--t-qs", "1", "--t-qd", "0.1", "--f-qd", "200",
            "--f-taud", "400", "--json"]
    assert main(args) == 0
    import json

    rec = json.loads(capsys.readouterr().out)
    assert rec["stable"] is True and rec["breaks"] == {}
    dm = sc.robot(ROBOTS / "planar_4link.urdf", delays_ms=FOUR_DELAYS_MS,
                  **FOUR).delay_margin({"stiffness": 1})
    np.testing.assert_allclose(rec["mimo"]["delay_margin_ms"], 1e3 * float(dm.delay_margin_s),
                               rtol=1e-6)


@pytest.mark.slow
def test_panda_seven_joints():
    """Oracle: the Panda's 7 joints (example-robot-data): the central delay margin from the
    characteristic built joint by joint equals the extra latency at which the generalized
    Nyquist loci of the numeric loop matrix cross -1."""
    if "panda" not in sc.robot_models():
        pytest.skip("example-robot-data is not installed")
    r = sc.robot(model="panda", joints=[f"panda_joint{i}" for i in range(1, 8)],
                 q0=[0, -0.5, 0, -2, 0, 1.5, 0.8], fn_hz=14, delays_ms=FOUR_DELAYS_MS,
                 filters_hz=(200, 400))
    dm = r.delay_margin({"stiffness": 1})
    m = r.mimo_margins()
    assert m.stable
    np.testing.assert_allclose([m.delay_margin_s, m.delay_crossing_hz],
                               [float(dm.delay_margin_s), float(dm.crossing_hz)], rtol=1e-6)


def test_workspace_map_of_a_four_joint_arm():
    # oracle: each row of the map is the robot built at that configuration by sc.robot
    # (its certified verdict and its MIMO central delay margin); passivity, which needs
    # the diagram's transfers, is None (not computed), and the CLI table says n/a
    arm = ROBOTS / "planar_4link.urdf"
    opts = dict(fn_hz=60, delays_ms=FOUR_DELAYS_MS, filters_hz=(200, 400))
    q = [FOUR["q0"], [0.2, 0.9, -0.4, 0.5]]
    m = sc.workspace_map(arm, q, **opts)
    for i, row in enumerate(q):
        r = sc.robot(arm, q0=row, **opts)
        assert bool(m.stable[i]) == bool(r.margins().stable)
        assert m.mimo_delay_margin_ms[i] == pytest.approx(
            1e3 * float(r.mimo_margins().delay_margin_s), rel=1e-9)
    assert list(m.passive) == [None, None]
