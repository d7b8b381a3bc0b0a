"""Section: distributed (DOSC) versus centralized (COSC) operational space control of the
Trikey mobile base, simulated (paper section "Distributed operational space control of a
mobile base", docs/theory/mobile-base.md)."""

from __future__ import annotations

import math

from seactl.api.mobile_base import compare_mobile_base, mobile_base_params
from seactl.apps.report import Claim, Context, Figure, Section, section
from seactl.systems.mobile_base import model as mb
from seactl.systems.mobile_base import tuning as mb_tuning

PAPER = {"cosc_kx": 30.0, "dosc_kx": 140.0, "ratio": 4.7, "pos_red": (62.0, 65.0),
         "vel_red": (45.0, 67.0)}

# (label, changes to the preset): the modelled effects the limits depend on.
SENSITIVITY = (
    ("preset (2000 counts/rev, 1500 N m/rad, 15 ms buffer)", {}),
    ("ideal encoder (no quantization)", {"encoder_counts": 0}),
    ("coarse encoder (500 counts/rev)", {"encoder_counts": 500}),
    ("stiff drivetrain (x10 stiffness, same damping ratio)",
     {"stiffness": 15000.0, "compliance_damping": 1.0 * math.sqrt(10)}),
    ("soft drivetrain (x0.3 stiffness, same damping ratio)",
     {"stiffness": 450.0, "compliance_damping": 1.0 * math.sqrt(0.3)}),
    ("no extra delay (7 ms round trip only)", {"extra_delay": 0.0}),
    ("30 ms extra delay (37 ms total)", {"extra_delay": 0.030}),
)


def _in(x: float, lo_hi: tuple[float, float]) -> bool:
    return lo_hi[0] <= x <= lo_hi[1]


def _intro(p: mb.MobileBaseParams) -> str:
    return (
        "Trikey (32.7 kg chassis, 1.192 kg m^2, three omni wheels of 0.101 m at 0.24 m, "
        "0/120/240 deg) with compliant, geared, frictional, torque-limited wheel "
        "drivetrains, quantized motor encoders and velocities by differencing. The "
        "centralized process (1 kHz) closes its loops through 7 ms round trip + 15 ms "
        "buffer = 22 ms (3.5 ms on the command path, the rest on the measurements); each "
        "wheel's embedded process runs at 0.5 ms and never talks to the others. COSC: "
        "Cartesian stiffness and damping centralized; DOSC: Cartesian stiffness "
        "centralized, joint damping on the embedded processes. The paper's tuning "
        "procedure is automated with one criterion for both: over the last "
        f"{p.criterion_window:g} s of a {p.criterion_duration:g} s run driving at "
        f"{p.criterion_speed:g} m/s in x and y from rest, the base 'vibrates or "
        "oscillates' when the RMS of the detrended chassis velocity exceeds "
        f"{p.criterion_oscillation_threshold * 1e3:g} mm/s or the RMS detrended wheel "
        f"torque ripple exceeds {p.criterion_vibration_threshold:g} N m. (1) K_x = 0, "
        "damping raised until it fires; (2) damping at "
        f"{p.safety_factor:g} x its limit, K_x raised until it fires; (3) a circle "
        f"(R = {p.circle_radius:g} m, period {p.circle_period:g} s, {p.circle_ramp:g} s "
        f"ramp-in, {p.circle_duration:g} s) tracked with K_x at {p.safety_factor:g} x its "
        "limit. Searches: a log grid of "
        f"{p.grid_points} candidates refined by {p.refine_points} linear ones, all "
        "candidates of both architectures in one batched simulation; fixed step "
        f"{p.embedded_period / p.substeps * 1e3:g} ms (semi-implicit Euler, "
        f"{p.substeps} per 0.5 ms sample). Every value the robot's description does not "
        "give (gear ratio, motor, friction, compliance, encoder, circle) is a documented "
        "assumption in presets/trikey.toml.")


def _figures(sec: Section, ctx: Context, comp: mb_tuning.MobileBaseComparison) -> None:
    from seactl.apps.plots import base_animation, base_tracking_figure

    sec.figures.append(Figure(ctx.savefig(base_tracking_figure(
        comp, {"cosc": PAPER["cosc_kx"], "dosc": PAPER["dosc_kx"]}), "base.png"),
        "Top: the circle tracked by both architectures (errors magnified 50x), position and "
        "velocity error norms over time. Bottom: the two gain searches (criterion values "
        "divided by their thresholds; vertical lines: the limits found) and the maximum K_x "
        "beside the paper's hardware values."))
    base_animation(comp, ctx.figures_dir / "base.gif", fps=10, seconds=comp.params.circle_period)
    sec.figures.append(Figure("base.gif", "COSC (left) and DOSC (right) tracking the circle "
                              "(one period, real time; the cross is the reference)."))


def _results_table(comp: mb_tuning.MobileBaseComparison):
    c, d = comp.results["cosc"], comp.results["dosc"]
    return (
        "Results beside the paper (acceleration gains: damping in N s/(m kg), DOSC as the "
        "Cartesian equivalent of its joint damping; K_x in N/(m kg))",
        ["quantity", "COSC (seactl)", "DOSC (seactl)", "seactl", "paper"],
        [["maximum damping", f"{c.max_damping:.4g}", f"{d.max_damping:.4g} "
          f"({d.max_joint_damping:.3g} N m s/rad)", "", "not published"],
         ["maximum K_x", f"{c.max_kx:.4g}", f"{d.max_kx:.4g}", "",
          f"{PAPER['cosc_kx']:g} / {PAPER['dosc_kx']:g}"],
         ["K_x ratio DOSC/COSC", "", "", f"{comp.kx_ratio:.3g}", f"{PAPER['ratio']:g}"],
         ["tracking K_x", f"{c.kx:.4g}", f"{d.kx:.4g}", "", "not published"],
         ["RMS position error [mm]", f"{c.rms_position_m * 1e3:.4g}",
          f"{d.rms_position_m * 1e3:.4g}", f"-{comp.position_rms_reduction_pct:.3g}%",
          "-62 to -65%"],
         ["RMS velocity error [mm/s]", f"{c.rms_velocity_mps * 1e3:.4g}",
          f"{d.rms_velocity_mps * 1e3:.4g}", f"-{comp.velocity_rms_reduction_pct:.3g}%",
          "-45 to -67%"]])


def _limit(r, key: str) -> str:
    """A limit, marked '>=' when the search never fired."""
    srch = r.damping_search if key == "max_damping" else r.kx_search
    return ("" if srch.reached else ">= ") + f"{getattr(r, key):.3g}"


def _sensitivity_table(comp: mb_tuning.MobileBaseComparison) -> tuple[tuple, list[float]]:
    """The limits under each model variant of :data:`SENSITIVITY`, and their K_x ratios."""
    rows, ratios = [], []
    for label, changes in SENSITIVITY:
        # Coarser searches than the main run keep the report quick (limits within ~10%).
        q = comp.params.with_(grid_points=16, refine_points=6, **changes)
        s = comp if not changes else compare_mobile_base(q, track=False)
        sc, sd = s.results["cosc"], s.results["dosc"]
        ratios.append(s.kx_ratio)
        rows.append([label, f"{q.central_delay * 1e3:g}", _limit(sc, "max_damping"),
                     _limit(sc, "max_kx"), _limit(sd, "max_damping"), _limit(sd, "max_kx"),
                     ("" if sd.kx_search.reached else ">= ") + f"{s.kx_ratio:.3g}"])
    table = ("Sensitivity of the limits to the modelled effects (tuning steps 1-2; "
             "'>=': no candidate fired up to the top of the search range)",
             ["model", "central delay [ms]", "COSC max damping", "COSC max K_x",
              "DOSC max damping", "DOSC max K_x", "K_x ratio"], rows)
    return table, ratios


def _kx_claims(comp: mb_tuning.MobileBaseComparison, ratios: list[float]) -> list[Claim]:
    c, d = comp.results["cosc"], comp.results["dosc"]
    higher = d.max_kx > c.max_kx
    always = all(r > 1 for r in ratios)
    ratio_ok = abs(comp.kx_ratio - PAPER["ratio"]) <= 1.0
    claims = [
        Claim("base.dosc_higher_kx", S, "DOSC attains a higher maximum Cartesian stiffness "
              "than COSC", "yes", "yes" if higher else "no", "DOSC > COSC",
              "pass" if higher else "fail"),
        Claim("base.dosc_higher_kx_all_models", S, "the DOSC advantage holds for every model "
              "variant of the sensitivity table", "yes", "yes" if always else "no",
              "ratio > 1 in every row", "pass" if always else "fail",
              f"ratios {min(ratios):.3g} to {max(ratios):.3g}"),
        Claim("base.kx_ratio", S, "DOSC/COSC maximum K_x ratio (140 / 30)", PAPER["ratio"],
              comp.kx_ratio, 1.0, "pass" if ratio_ok else "fail",
              "" if ratio_ok else
              f"the ratio depends on unpublished hardware (sensitivity table: {min(ratios):.3g}"
              f" to {max(ratios):.3g}); the model reproduces the direction and size order, "
              "not 4.7")]
    for key, paper in (("cosc", PAPER["cosc_kx"]), ("dosc", PAPER["dosc_kx"])):
        claims.append(Claim(
            f"base.max_kx.{key}", S, f"maximum K_x of {key.upper()} [N/(m kg)]", paper,
            comp.results[key].max_kx, "n/a", "info",
            "absolute limits are hardware measurements (sensor noise, backlash, compliance); "
            "ours follow from the preset's assumed drivetrain and encoder"))
    return claims


def _tracking_claims(comp: mb_tuning.MobileBaseComparison) -> list[Claim]:
    claims = []
    for cid, name, ours, rng in (
            ("base.position_rms_reduction", "position", comp.position_rms_reduction_pct,
             PAPER["pos_red"]),
            ("base.velocity_rms_reduction", "velocity", comp.velocity_rms_reduction_pct,
             PAPER["vel_red"])):
        claims.append(Claim(
            cid + ".sign", S, f"DOSC reduces the RMS {name} tracking error", "yes",
            "yes" if ours > 0 else "no", "reduction > 0", "pass" if ours > 0 else "fail"))
        ok = _in(ours, rng)
        claims.append(Claim(
            cid, S, f"RMS {name} error reduction [%]", list(rng), ours, "within range",
            "pass" if ok else "fail",
            "" if ok else "our reduction follows from our K_x ratio (the steady error "
            "against friction scales like 1/K_x); the paper's circle, gains and friction are "
            "not published"))
    return claims


NOTES = (
    "Why COSC is limited in the model: delayed velocity feedback destabilizes the "
    "drivetrain's compliance mode (about 30 Hz, lightly damped) long before the rigid-"
    "body limit D T < pi/2 (71 N s/(m kg) at 22 ms): the COSC damping limit stays near "
    "10-12 N s/(m kg) even without the 15 ms buffer, and with little damping the delayed "
    "stiffness loop runs out of phase margin. DOSC's damping is limited instead by "
    "encoder quantization amplified by differencing at 0.5 ms (torque ripple), and its "
    "higher damping carries a higher K_x through the same 22 ms.",
    "Not reproduced: the absolute limits (ours are several times the paper's 30 and 140) "
    "and hence the exact ratio and error reductions. docs/theory/mobile-base.md: an ideal "
    "rigid model keeps ample phase margin at both of the paper's gains, so the robot's "
    "limits came from effects whose values are not published (sensor noise, gearbox "
    "backlash and compliance, roller vibration, a human judging 'vibrating'). The "
    "sensitivity table shows the ratio moving with the assumed encoder resolution, "
    "drivetrain stiffness and delay; the tests check the criterion against the analytic "
    "delay limit on a rigid base and the simulator against solve_ivp.")

S = "Mobile base"


@section(80, "mobile-base")
def mobile_base(ctx: Context) -> Section:
    p = mobile_base_params("trikey")
    comp = compare_mobile_base(p)
    sec = Section("mobile-base", "Mobile base: distributed (DOSC) vs centralized (COSC) OSC, "
                  "simulated", intro=_intro(p))
    _figures(sec, ctx, comp)
    sec.tables.append(_results_table(comp))
    table, ratios = _sensitivity_table(comp)
    sec.tables.append(table)
    sec.claims.extend(_kx_claims(comp, ratios))
    sec.claims.extend(_tracking_claims(comp))
    sec.notes.append(
        "Reproduced: moving the damping from the 22 ms centralized loop to the 0.5 ms "
        "embedded processes raises the usable damping and, with it, the Cartesian stiffness "
        f"(x{comp.kx_ratio:.3g} here, x4.7 on the robot), and cuts both RMS tracking errors. "
        + NOTES[0])
    sec.notes.append(NOTES[1])
    return sec
