"""A robot's central process as a MIMO loop (Robot.mimo_margins) and the placement of its
loops (Robot.placement).

Oracles: closed-form margins of delayed integrators mixed by a constant matrix; for one
joint, the SEA's own diagram (its blocks, with a tap) broken at its
stiffness path and scanned by the certified SISO margins, and the SEA's delay margin;
for the planar 2-link arm, the delay margin by frequency sweeping of the exact
characteristic quasi-polynomial (a second method), the rightmost characteristic roots
(collocation and Newton) at the predicted delay and gain, the certified verdict on
both sides of them, and the graph determinant's ratio ``Q / Q_cut`` for ``det(I + L)``.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.errors import InputError

pytest.importorskip("pinocchio", reason="pinocchio (pip install pin) is not installed")

ARM = str(Path(__file__).resolve().parents[1] / "examples" / "robots" / "planar_2link.urdf")
TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))
Q0 = [0.0, 1.5]


def one_link(tmp_path: Path) -> Path:
    """A 1-link URDF with the UT-SEA's joint inertia about its axis and its damping."""
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


@pytest.fixture(scope="module")
def arm():
    return sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14, **TABLE_I)


@pytest.fixture(scope="module")
def arm_margins(arm):
    return arm.mimo_margins()


def _stable(r, **delays_ms) -> bool:
    return bool(replace(r, delays=dict(r.delays, **{k: 1e-3 * v for k, v in
                                                     delays_ms.items()})).margins().stable)


def test_loci_margins_of_delayed_integrators():
    """Oracle: closed form.  ``L = P diag(k_i e^{-s tau} / s) P^-1`` has the loci
    ``k_i e^{-jw tau} / (jw)``: crossover ``w = k_i``, phase margin
    ``90 deg - k_i tau``, extra delay ``(pi / 2) / k_i - tau``; phase crossover
    ``w = pi / (2 tau)`` with gain margin ``pi / (2 tau k_i)``."""
    from seactl.analysis.characteristic_loci import loci_margins

    k, tau = np.array([3.0, 20.0]), 0.01
    P = np.array([[1.0, 0.4], [-0.3, 2.0]])

    def L(w):
        lam = k[None, :] * np.exp(-1j * w[:, None] * tau) / (1j * w[:, None])
        return P @ (lam[:, :, None] * np.eye(2)) @ np.linalg.inv(P)

    m = loci_margins(L, np.logspace(-1, 4, 800))
    assert np.allclose(np.sort(m.crossover_w), k, rtol=1e-10)
    pm = np.degrees(np.pi / 2 - k * tau)
    assert m.phase_margin_deg == pytest.approx(pm.min(), rel=1e-10)
    assert m.crossover == pytest.approx(k[np.argmin(pm)], rel=1e-10)
    assert m.delay_margin_s == pytest.approx((np.pi / 2 / k - tau).min(), rel=1e-9)
    gm = np.pi / (2 * tau * k)
    assert m.gain_margin == pytest.approx(gm[np.argmin(np.abs(np.log(gm)))], rel=1e-9)
    assert m.phase_crossover == pytest.approx(np.pi / (2 * tau), rel=1e-10)


def test_one_joint_is_the_sea_stiffness_loop(tmp_path):
    """Oracle: the SEA's diagram with a tap ``q_sens -> qs`` before its stiffness block,
    broken at ``qs`` (a SISO loop of the SEA's own blocks, the certified SISO scan), and
    the SEA's delay margin along the stiffness delay."""
    from seactl.analysis.margins import default_grid, loop_margins
    from seactl.diagram.blockdiagram import Block
    from seactl.diagram.mason import CycleDiagram
    from seactl.systems.sea.loops import SEA_DIAGRAM

    blocks = [replace(b, src="qs") if b.name == "Kq_fb" else b for b in SEA_DIAGRAM.blocks]
    tapped = CycleDiagram("sea-qs-tap", blocks + [Block("qs_tap", "q_sens", "qs")])
    d = sc.design(14, **TABLE_I)
    ref = loop_margins(tapped.loop("qs"), d.design, default_grid(d.reference_frequency()))
    m = sc.robot(one_link(tmp_path), space="joint", fn_hz=14, **TABLE_I).mimo_margins()
    assert m.stable and bool(ref.stable)
    for ours, theirs in ((m.phase_margin_deg, ref.phase_margin_deg),
                         (m.crossover_hz, ref.crossover_hz),
                         (m.delay_margin_s, ref.delay_margin_s)):
        assert abs(ours - float(theirs)) <= 1e-9 * abs(float(theirs))
    if np.isfinite(ref.gain_margin):
        assert abs(m.gain_margin - float(ref.gain_margin)) <= 1e-9 * float(ref.gain_margin)
    dm = float(d.delay_margin({"stiffness": 1}).delay_margin_s)
    assert abs(m.delay_margin_s - dm) <= 1e-9 * dm


def test_return_difference_is_the_characteristic_ratio(arm, arm_margins):
    """Oracle: ``det(I + L) = Q / Q_cut``, the graph determinants of the whole loop and of
    the loop with every stiffness channel held (the generalized Nyquist identity)."""
    from seactl.analysis.characteristic_loci import loop_matrix
    from seactl.diagram.blockdiagram import evaluate_forms

    cut = [f"qs.j{j + 1}" for j in range(arm.n)]
    L = loop_matrix(arm.diagram, arm.design, [f"q_sens.j{j + 1}" for j in range(arm.n)], cut)
    w = 2 * np.pi * np.array([0.3, 3.0, 30.0, 300.0])
    q, q_cut = evaluate_forms((arm.diagram.characteristic(), arm.diagram.characteristic(cut)),
                              arm.design)
    det = np.linalg.det(np.eye(arm.n) + L(w))
    assert np.allclose(det, q(1j * w) / q_cut(1j * w), rtol=1e-9)
    # the reported loci are the eigenvalues there, and the phase margin rotates one onto -1
    wc = 2 * np.pi * arm_margins.crossover_hz
    rot = np.exp(-1j * np.radians(arm_margins.phase_margin_deg))
    assert abs(np.linalg.det(np.eye(arm.n) + rot * L(np.array([wc]))[0])) < 1e-9


def test_delay_margin_is_where_the_verdict_flips(arm, arm_margins):
    """Oracles: the delay margin by frequency sweeping of the quasi-polynomial; a root on
    the imaginary axis at the crossing (rightmost roots); the certified verdict just
    below and above."""
    m = arm_margins
    dm = float(arm.delay_margin({"stiffness": 1}).delay_margin_s)
    assert m.stable and abs(m.delay_margin_s - dm) <= 1e-9 * dm
    t_star = 1e3 * (arm.delays["stiffness"] + m.delay_margin_s)
    z = replace(arm, delays=dict(arm.delays, stiffness=1e-3 * t_star)).roots(count=2).roots[0]
    assert abs(z.real) < 1e-6 * abs(z.imag)
    assert abs(abs(z.imag) - 2 * np.pi * m.delay_crossing_hz) < 1e-6 * abs(z.imag)
    assert _stable(arm, stiffness=0.999 * t_star) and not _stable(arm, stiffness=1.001 * t_star)


def test_gain_margin_is_where_a_common_gain_flips_the_verdict(arm, arm_margins):
    """Oracle: the stiffness matrix (every channel's gain) scaled by the gain margin puts
    a characteristic root on the imaginary axis at the phase crossover; the certified
    verdict flips across it."""
    g = arm_margins.gain_margin
    assert 1 < g < np.inf

    def scaled(f):
        return replace(arm, stiffness=arm.stiffness * f)
    z = scaled(g).roots(count=2).roots[0]
    assert abs(z.real) < 1e-6 * abs(z.imag)
    assert abs(abs(z.imag) - 2 * np.pi * arm_margins.phase_crossover_hz) < 1e-6 * abs(z.imag)
    assert scaled(0.999 * g).margins().stable and not scaled(1.001 * g).margins().stable


def test_smallest_return_difference_is_the_minimum(arm, arm_margins):
    """Oracle: brute force, the smallest singular value of ``I + L`` on a grid 10 times
    finer than the analysis's, over the same span."""
    from seactl.analysis.characteristic_loci import loop_matrix

    L = loop_matrix(arm.diagram, arm.design, [f"q_sens.j{j + 1}" for j in range(arm.n)],
                    [f"qs.j{j + 1}" for j in range(arm.n)])
    f = arm_margins.frequency_hz
    w = 2 * np.pi * np.geomspace(f[0], f[-1], 10 * f.size)
    sv = np.linalg.svd(np.eye(arm.n) + L(w), compute_uv=False)[:, -1]
    assert arm_margins.min_return_difference <= sv.min() + 1e-12
    assert arm_margins.min_return_difference >= sv.min() - 1e-6
    assert arm_margins.min_return_difference_hz == pytest.approx(
        w[np.argmin(sv)] / (2 * np.pi), rel=2e-3)


def test_placement_margins(arm):
    """Oracles: the MIMO delay margin of the same delays (characteristic loci) for the
    stiffness-only central process; the certified verdict on both sides of the largest
    central latency when damping is central too."""
    p = arm.placement(central_ms=5, embedded_ms=0.5)
    assert len(p.options) == 4 and all(o.stable for o in p.options)
    dist = p.option(stiffness="central", damping="embedded")
    ref = sc.robot(ARM, space="task", task="tool", q0=Q0, fn_hz=14, filters_hz=(50, 100),
                   delays_ms={"torque": 0.5, "stiffness": 5, "damping": 0.5}).mimo_margins()
    assert abs(dist.delay_margin_s - ref.delay_margin_s) <= 1e-9 * ref.delay_margin_s
    assert abs(dist.max_central_latency_s - 5e-3 - dist.delay_margin_s) < 1e-12
    cen = p.option(stiffness="central", damping="central")
    top = 1e3 * cen.max_central_latency_s
    base = dict(torque=0.5)
    assert _stable(arm, stiffness=0.999 * top, damping=0.999 * top, **base)
    assert not _stable(arm, stiffness=1.001 * top, damping=1.001 * top, **base)
    # the paper's conclusion on this arm: the damping belongs next to the joint
    assert dist.max_central_latency_s > cen.max_central_latency_s
    assert p.option(stiffness="embedded", damping="embedded").delay_margin_s == np.inf
    for bad in (dict(loops=("speed",)), dict(central_ms=-1.0), dict(loops=())):
        with pytest.raises(InputError):
            arm.placement(**bad)


def test_cli_mimo_and_placement_are_the_api(capsys, arm_margins):
    """Oracle: the public API on the same arguments; bad input: one line, exit 2."""
    args = ["robot", "--urdf", ARM, "--space", "task", "--task", "tool", "--q0", "0,1.5",
            "--fn", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50",
            "--f-taud", "100"]
    assert main(args + ["--mimo", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)["mimo"]
    assert rec["phase_margin_deg"] == pytest.approx(arm_margins.phase_margin_deg, rel=1e-9)
    assert rec["delay_margin_ms"] == pytest.approx(1e3 * arm_margins.delay_margin_s, rel=1e-9)
    assert main(args + ["--mimo"]) == 0
    out = capsys.readouterr().out
    assert "generalized Nyquist" in out and f"{arm_margins.phase_margin_deg:.2f}" in out
    assert main(args + ["--placement", "5,x"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "--placement" in err and "\n" not in err
