"""Section: from design to running controller.  A Table I-like design exported and run as
three OS processes over Zenoh on this machine; the measured link latencies, and the
measured step response against the sampled simulation (replayed and nominal)."""

from __future__ import annotations

import numpy as np

from seactl.apps.report import Claim, Context, Figure, Section, section

FN_HZ = 14.0
DELAYS_MS = (1.0, 2.0, 1.0)                     # T_tau, T_qs, T_qd
FILTERS_HZ = (50.0, 100.0)
RATES_HZ = {"embedded": 2000.0, "high-level": 500.0}
DURATION_S = 1.0
STEP_RAD = 0.01
REPLAY_TOL = 1e-9                               # of the step
LINKS = ("plant->embedded", "plant->high-level", "high-level->embedded", "embedded->plant")


def _figures(ctx: Context, res) -> list[Figure]:
    from seactl.apps.plots import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, 4, figsize=(13, 2.6), sharey=False)
    for ax, link in zip(axes, LINKS):
        ms = res.latency_s[link] * 1e3
        ax.hist(ms, bins=40, color="tab:blue")
        ax.set_yscale("log")
        ax.set_title(link, fontsize=9)
        ax.set_xlabel("latency [ms]")
    axes[0].set_ylabel("messages")
    hist = ctx.savefig(fig, "running_latency.png")
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 3.2))
    t_ms = res.t_s * 1e3
    ax.plot(t_ms, res.q_measured / STEP_RAD, label="measured (3 processes)", lw=2.5)
    ax.plot(t_ms, res.q_replay / STEP_RAD, "--", label="simulation, measured link timing")
    ax.plot(t_ms, res.q_nominal / STEP_RAD, ":", label="simulation, design delays")
    ax.set_xlim(0, 300)
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("q_j / step")
    ax.legend(fontsize=8)
    bx.semilogy(t_ms, np.abs(res.q_measured - res.q_replay) / STEP_RAD + 1e-18,
                label="measured - replay")
    bx.semilogy(t_ms, np.abs(res.q_measured - res.q_nominal) / STEP_RAD + 1e-18,
                label="measured - nominal")
    bx.set_xlabel("t [ms]")
    bx.set_ylabel("|difference| / step")
    bx.legend(fontsize=8)
    resp = ctx.savefig(fig, "running_step.png")
    return [Figure(hist, "Latency of every message between the three processes (Zenoh on "
                         "loopback, 1 s at 2 kHz / 500 Hz; log counts)."),
            Figure(resp, "Step of q_des (0.01 rad): the response the plant process measured, "
                         "the sampled simulation replaying the measured timing of the "
                         "stiffness link, and the simulation with the design's delays; "
                         "right: their differences.")]


def _ms(v: float | None) -> str:
    return "none" if v is None else f"{v:.3f}"


def _not_run(reason: str) -> Section:
    sec = Section("running", "From design to running controller",
                  intro="The three-process run could not be made on this machine: " + reason)
    for cid, text in (("running-replay", "The running processes reproduce the simulation"),
                      ("running-delivery", "Every message of the run was delivered")):
        sec.claims.append(Claim(cid, "running", text, None, None, None, "fail",
                                "the run did not take place (see the section)"))
    return sec


@section(78, "running")
def running(ctx: Context) -> Section:
    import seactl as sc
    from seactl.errors import SeactlError

    d = sc.design(FN_HZ, delays_ms=dict(zip(("torque", "stiffness", "damping"), DELAYS_MS)),
                  filters_hz=FILTERS_HZ)
    try:
        res = d.run(duration_s=DURATION_S, rates_hz=RATES_HZ, amplitude=STEP_RAD)
    except SeactlError as exc:   # the machine could not run it: say so, keep the report
        return _not_run(str(exc))
    s = res.summary
    sec = Section(
        "running", "From design to running controller",
        intro=(
            "The design of f_n = 14 Hz (delays T_tau, T_qs, T_qd = 1, 2, 1 ms; filters 50 and "
            "100 Hz) is exported as one controller per process (`seactl export`) and run as "
            "three operating-system processes on this machine (`seactl run`): a plant process "
            "that integrates the SEA exactly at 2 kHz, the embedded controller (torque and "
            "damping) at 2 kHz and the high-level controller (stiffness) at 500 Hz, talking "
            "over Zenoh on loopback. Every message is time-stamped when sent and when "
            "received. The measured response is compared with seactl's sampled simulation "
            "twice: replaying which stiffness message the embedded process actually used at "
            "each tick, and with the delays the design was analysed with."))
    rows = [[link, str(st["count"]), f"{st['mean_ms']:.3f}", f"{st['p50_ms']:.3f}",
             f"{st['p99_ms']:.3f}", f"{st['max_ms']:.3f}"]
            for link, st in s["links"].items() if st["count"]]
    sec.tables.append(("Measured latency per link (this run; the stiffness row is the age "
                       "of the stiffness message when used, in the sense of the analysis)",
                       ["link", "messages", "mean [ms]", "median [ms]", "p99 [ms]",
                        "max [ms]"], rows))
    checks = s.get("latency_check", {})
    if checks:
        sec.tables.append((
            "Measured latency of each loop across the link against the design's margins "
            "(spread = max - min; the sampled jitter margin at the loop's process rate)",
            ["loop", "design delay [ms]", "mean [ms]", "max [ms]", "spread [ms]",
             "jitter margin [ms]", "sampled jitter margin [ms]", "delay limit [ms]",
             "verdict"],
            [[loop] + [_ms(c[k]) for k in ("design_delay_ms", "mean_ms", "max_ms", "spread_ms",
                                           "jitter_margin_ms", "sampled_jitter_margin_ms",
                                           "delay_limit_ms")] + [c["verdict"]]
             for loop, c in checks.items()]))
    sec.figures.extend(_figures(ctx, res))
    ok = s["replay_max_diff"] <= REPLAY_TOL
    sec.claims.append(Claim(
        "running-replay", "running",
        "The three running processes do what the sampled simulation predicts when it is "
        "given the link timing they measured (largest difference <= 1e-9 of the step)",
        None, bool(ok), REPLAY_TOL, "pass" if ok else "fail",
        "" if ok else "the running controllers differ from the model: see the table"))
    links = s["links"]
    delivered = all(links[k]["count"] == s["ticks"] for k in ("plant->embedded",
                                                             "plant->high-level"))
    delivered = bool(delivered and s["dropped"] == 0 and s["stale_commands"] == 0)
    sec.claims.append(Claim(
        "running-delivery", "running",
        "Every sample reached both controllers, no stiffness message was lost and the plant "
        "never applied a stale drive command", None, delivered, None,
        "pass" if delivered else "fail",
        "" if delivered else "messages were lost or late: see the table"))
    sec.notes.append(
        f"This run: measured and replayed responses differ by at most "
        f"{s['replay_max_diff']:.1e} of the step, measured and nominal by "
        f"{s['nominal_max_diff']:.1e}; {s['late_commands']} of {s['ticks'] - 1} drive "
        f"commands reached the plant after their tick (the plant waits for them), "
        f"{s['dropped']} stiffness messages were lost. The replay agreeing to rounding means "
        "the exported code, the transport and the plant integration add nothing the model "
        "does not have: the analysis describes the running system once it is told the "
        "latency the system really has. The nominal difference is that latency: the "
        "stiffness message's age varies with when it arrives relative to the 2 kHz ticks "
        "(see the stiffness row), so the measured latency distribution, not one number, is "
        "what to analyse (`seactl step --mode sampled --latency stiffness=hist:FILE`, "
        "`seactl place --high-timing hist:FILE`, the jitter margins).")
    return sec
