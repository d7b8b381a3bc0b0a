"""Section: the paper's conclusion (damping next to the joint, stiffness on the central
process) for a whole robot.  The planar 2-link arm of ``examples/robots`` in task space
(the tool frame) at a few configurations, each placement of its stiffness and damping on
a central process of 5 ms or on the joints' embedded processes of 0.5 ms
(:meth:`seactl.api.robot.Robot.placement`): the certified verdict, the generalized
Nyquist phase margin of the stiffness channels, and the largest central latency.
Without pinocchio (the ``robots`` extra) or the repository's examples the section says
so."""

from __future__ import annotations

from pathlib import Path

from seactl.apps.report import Claim, Context, Section, section

CONFIGURATIONS = ((0.3, 0.8), (0.0, 1.5), (-0.5, 2.2))
"""The arm's configurations [rad]."""
FN_HZ = 14.0
FILTERS_HZ = (50.0, 100.0)
CENTRAL_MS = 5.0
EMBEDDED_MS = 0.5
TITLE = "A whole robot: damping next to the joint, stiffness central"
SID = "robot-placement"
CLAIM_TEXT = ("With damping on the joints' embedded processes the planar arm tolerates a "
              "longer central latency than with damping central too, stable at {c:g} ms "
              "(q0 = {q})")
ALL_TEXT = "The paper's conclusion holds for the planar 2-link arm at every configuration"


def _claim_id(i: int) -> str:
    return f"robot.damping_embedded.q{i + 1}"


def _arm() -> Path:
    """The planar 2-link arm of the repository's examples."""
    import seactl

    return Path(seactl.__file__).resolve().parents[2] / "examples" / "robots" / \
        "planar_2link.urdf"


def _skipped(reason: str) -> Section:
    sec = Section(SID, TITLE, intro="This section needs " + reason + ".")
    for i, q in enumerate(CONFIGURATIONS):
        sec.claims.append(Claim(_claim_id(i), SID, CLAIM_TEXT.format(c=CENTRAL_MS, q=q),
                                None, None, None, "skip", "not computed: " + reason))
    sec.claims.append(Claim("robot.damping_embedded.all", SID, ALL_TEXT, None, None, None,
                            "skip", "not computed: " + reason))
    return sec


def _row(q: tuple[float, float], o) -> list[str]:
    lat = "inf" if o.max_central_latency_s == float("inf") else \
        f"{1e3 * o.max_central_latency_s:.2f}"
    return [f"({q[0]:g}, {q[1]:g})", o.processes["stiffness"], o.processes["damping"],
            "stable" if o.stable else "UNSTABLE", f"{o.phase_margin_deg:.2f}", lat]


def _claim(i: int, q: tuple[float, float], dist, cen) -> tuple[Claim, bool]:
    ratio = dist.max_central_latency_s / cen.max_central_latency_s
    ok = bool(dist.stable and ratio > 1)
    return Claim(_claim_id(i), SID, CLAIM_TEXT.format(c=CENTRAL_MS, q=q), "not in the paper",
                 round(ratio, 3), "ratio > 1 and stable", "info",
                 f"{'holds' if ok else 'does not hold'}: largest central latency "
                 f"{1e3 * dist.max_central_latency_s:.2f} ms with "
                 f"damping embedded, {1e3 * cen.max_central_latency_s:.2f} ms with damping "
                 "central"), ok


@section(81, SID)
def robot_placement(ctx: Context) -> Section:
    import seactl as sc
    from seactl.errors import InputError
    from seactl.systems.robot.model import pinocchio

    try:
        pinocchio()
    except InputError:
        return _skipped("pinocchio, which is not installed here: install seactl with its "
                        "robots extra (pip install '.[robots]') and run seactl reproduce "
                        "again")
    if not _arm().is_file():
        return _skipped("the repository's examples/robots (run seactl reproduce from an "
                        "editable install of the repository)")
    rows, claims, held = [], [], []
    for i, q in enumerate(CONFIGURATIONS):
        r = sc.robot(_arm(), space="task", task="tool", q0=q, fn_hz=FN_HZ,
                     filters_hz=FILTERS_HZ)
        p = r.placement(central_ms=CENTRAL_MS, embedded_ms=EMBEDDED_MS)
        rows += [_row(q, o) for o in p.options]
        claim, ok = _claim(i, q, p.option(stiffness="central", damping="embedded"),
                           p.option(stiffness="central", damping="central"))
        claims.append(claim)
        held.append(ok)
    claims.append(Claim("robot.damping_embedded.all", SID, ALL_TEXT, "not in the paper",
                        "yes" if all(held) else "no", "every configuration", "info",
                        "a finding beyond the paper (a whole robot), not a claim it prints"))
    sec = Section(SID, TITLE, intro=(
        "The paper runs the stiffness on the central process and the damping next to each "
        "joint. For a whole robot the loops are coupled through the rigid body, so a "
        "single loop break says little (docs/robots.md); here the planar 2-link arm "
        "(examples/robots, task-space stiffness at the tool, each joint's SEA the UT-SEA "
        f"designed at f_n = {FN_HZ:g} Hz for its apparent inertia, filters "
        f"{FILTERS_HZ[0]:g} and {FILTERS_HZ[1]:g} Hz, torque loops embedded) is analysed "
        f"with its central process at {CENTRAL_MS:g} ms and embedded processes at "
        f"{EMBEDDED_MS:g} ms, each of stiffness and damping on either. The largest central "
        "latency is the first delay, from zero, at which a characteristic root reaches the "
        "imaginary axis with every central loop delayed alike; the phase margin is the "
        "generalized Nyquist margin of the stiffness channels broken together."))
    sec.tables.append((
        f"Placements of the planar arm (central {CENTRAL_MS:g} ms, embedded "
        f"{EMBEDDED_MS:g} ms)",
        ["q0 [rad]", "stiffness", "damping", f"verdict at {CENTRAL_MS:g} ms",
         "MIMO PM [deg]", "largest central latency [ms]"], rows))
    sec.claims.extend(claims)
    return sec
