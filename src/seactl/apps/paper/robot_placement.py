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


def _row(q: tuple[float, float], emb, cen) -> list[str]:
    """One configuration: damping central, then embedded (stiffness central in both)."""
    def ms(o) -> str:
        t = o.max_central_latency_s
        return "inf" if t == float("inf") else f"{1e3 * t:.2f}"

    def verdict(o) -> str:
        return "stable" if o.stable else "UNSTABLE"

    return [f"({q[0]:g}, {q[1]:g})", f"{verdict(cen)}, {cen.phase_margin_deg:.2f}",
            f"{verdict(emb)}, {emb.phase_margin_deg:.2f}", ms(cen), ms(emb)]


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
        emb = p.option(stiffness="central", damping="embedded")
        cen = p.option(stiffness="central", damping="central")
        rows.append(_row(q, emb, cen))
        claim, ok = _claim(i, q, emb, cen)
        claims.append(claim)
        held.append(ok)
    claims.append(Claim("robot.damping_embedded.all", SID, ALL_TEXT, "not in the paper",
                        "yes" if all(held) else "no", "every configuration", "info",
                        "a finding beyond the paper (a whole robot), not a claim it prints"))
    sec = Section(SID, TITLE, intro=(
        f"The planar 2-link arm (examples/robots; task-space stiffness at the tool, UT-SEAs "
        f"at {FN_HZ:g} Hz, filters {FILTERS_HZ[0]:g}/{FILTERS_HZ[1]:g} Hz), stiffness on a "
        f"{CENTRAL_MS:g} ms central process, damping central too or embedded "
        f"({EMBEDDED_MS:g} ms). Largest central latency: the first at which a root reaches "
        "the imaginary axis; PM: generalized Nyquist, the stiffness channels broken "
        "together (docs/robots.md)."))
    sec.tables.append((
        f"Stiffness central: damping central or embedded (at {CENTRAL_MS:g} ms central)",
        ["q0 [rad]", "damping central: verdict, MIMO PM [deg]",
         "damping embedded: verdict, MIMO PM [deg]",
         "largest central latency, damping central [ms]",
         "largest central latency, damping embedded [ms]"], rows))
    sec.claims.extend(claims)
    return sec
