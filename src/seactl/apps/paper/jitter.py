"""Section: jitter margins of the Table I designs, the loss cost in f_n, and a Monte
Carlo check of the small-gain bound."""

from __future__ import annotations

import numpy as np

from seactl.apps.report import Claim, Context, Figure, Section, section

TABLE_I_FN = (12.0, 14.0, 16.0, 18.0, 20.0)
TABLE_I_MS = (0.5, 2.0, 0.5)              # T_tau, T_qs, T_qd [ms]
CURVE_FN = np.linspace(10.0, 30.0, 41)
RIGID_FN = (4.0, 8.0, 12.0)
MC_FN = 14.0
MC_FACTORS = (0.5, 1.0, 2.0, 4.0, 8.0)    # jitter range in multiples of the margin
MC_RUNS = 200
MC_T_END_S = 0.5
LOSS = 0.01
PM_FLOOR_DEG = 30.0


def _table_i(fn):
    from seactl.api.sea import design

    return design(fn, delays_ms=dict(zip(("torque", "stiffness", "damping"), TABLE_I_MS)),
                  filters_hz=(50.0, 100.0))


def _monte_carlo(d, jm):
    """Fraction of stable runs of impulse responses at f_n = MC_FN for uniform latency
    ``[nominal, nominal + factor x J]`` on each link (``d.monte_carlo``)."""
    from seactl.latency.models import Uniform

    nominal = {"torque": TABLE_I_MS[0] * 1e-3, "damping": TABLE_I_MS[2] * 1e-3,
               "stiffness": TABLE_I_MS[1] * 1e-3}
    out = {}
    for link in ("torque", "damping", "stiffness"):
        J = float(getattr(jm, f"{link}_jitter_margin_s"))
        out[link] = [float(d.monte_carlo(
            "impulse", latency={link: Uniform(nominal[link], nominal[link] + f * J)},
            runs=MC_RUNS, seed=0, t_end_s=MC_T_END_S).fraction_stable) for f in MC_FACTORS]
    return out


def _loss_cost():
    """Distributed SEA placement (Table I timing, PM >= floor): highest f_n without loss,
    guaranteed with 1 % loss on the embedded process, and the Monte Carlo at the lossless
    optimum.  ``sc.place`` has no process-timing keyword: the advisor's own call."""
    from seactl.latency.maps import sea_model
    from seactl.latency.models import Bernoulli, Constant
    from seactl.latency.montecarlo import verify_placement
    from seactl.latency.placement import ProcessTiming, advise

    m = sea_model()
    hi, lo = TABLE_I_MS[1] * 1e-3, TABLE_I_MS[0] * 1e-3
    a0 = advise(m, hi, lo, min_pm_deg=PM_FLOOR_DEG)
    timing = {"embedded": ProcessTiming(Constant(lo), Bernoulli(LOSS))}
    a1 = advise(m, hi, lo, min_pm_deg=PM_FLOOR_DEG, timing=timing)
    o0, o1 = a0.option("distributed"), a1.option("distributed")
    mc = verify_placement(m, o0, timing, runs=MC_RUNS, seed=0)
    return o0, o1, timing["embedded"].jitter_s, mc


@section(73, "jitter")
def jitter_section(ctx: Context) -> Section:
    from seactl.apps.plots import jitter_figure

    sec = Section(
        "jitter", "Jitter: time-varying latency and message loss",
        intro="The paper models each loop's latency as a constant delay. On a bus or a "
              "network it varies from cycle to cycle and messages are lost. The jitter margin "
              "of a loop (Kao and Lincoln 2004) is the largest J such that ANY time-varying "
              "extra delay in [0, J] keeps the loop stable: J = 1 / max_w (w |T(jw)|), T the "
              "complementary sensitivity of the loop broken at that tap, every other loop "
              "closed, exact nominal delays (seactl.latency.jitter). It is a sufficient bound, and "
              "never above the margin for a constant extra delay. Table I timing (T_tau = "
              "0.5, T_qs = 2, T_qd = 0.5 ms, filters 50 / 100 Hz). The Monte Carlo runs are "
              f"sampled at 1 kHz ({MC_RUNS} runs per point, impulse of 0.05 N m s, "
              f"{MC_T_END_S:g} s), each link's latency uniform in [nominal, nominal + k J]; "
              "the receiver uses the newest message that has arrived and holds it.")
    _table_claims(sec)
    _rigid_claim(sec)
    _loss_claims(sec)
    curve = _table_i(CURVE_FN).jitter_margins()
    mc = _monte_carlo(_table_i(MC_FN), _table_i(MC_FN).jitter_margins())
    inside = all(fr[0] == 1.0 and fr[1] == 1.0 for fr in mc.values())
    sec.claims.append(Claim(
        "jitter.mc.inside_margin_stable", "Jitter (issue 14)",
        f"Monte Carlo at f_n = {MC_FN:g} Hz: every run stays stable with the latency varying "
        "within the jitter margin of its link (k = 0.5 and 1)", "100 %",
        {k: [round(100 * x, 1) for x in v] for k, v in mc.items()}, "100 % at k <= 1",
        "pass" if inside else "fail",
        "stable runs [%] at k = " + ", ".join(f"{k:g}" for k in MC_FACTORS)
        + ": the bound is conservative (the newest-message rule keeps the average age low), "
          "the torque link is the first to lose runs."))
    loops = {"overall": curve.jitter_margin_s, "stiffness": curve.stiffness_jitter_margin_s,
             "damping": curve.damping_jitter_margin_s, "torque": curve.torque_jitter_margin_s}
    fig = jitter_figure(CURVE_FN, {k: np.asarray(v) * 1e3 for k, v in loops.items()},
                        np.asarray(curve.delay_margin_s) * 1e3, MC_FACTORS, mc,
                        title="UT-SEA, Table I timing")
    sec.figures.append(Figure(ctx.savefig(fig, "jitter_margins.png"),
                              "Left: jitter margins of each loop and the outer loop's "
                              "constant-delay margin against f_n. Right: stable Monte Carlo "
                              f"runs at f_n = {MC_FN:g} Hz against the latency range of one "
                              "link, in multiples of its jitter margin (dotted: the bound)."))
    return sec


def _table_claims(sec: Section) -> None:
    """Table I jitter margins, with the claims read from them."""
    d = _table_i(TABLE_I_FN)
    j = d.jitter_margins()
    rows = []
    for i, f in enumerate(TABLE_I_FN):
        rows.append([f"{f:g}"] + [f"{1e3 * float(getattr(j, k + 'jitter_margin_s')[i]):.3f}"
                                  for k in ("", "stiffness_", "damping_", "torque_")]
                    + [f"{1e3 * float(j.delay_margin_s[i]):.3f}", str(j.bottleneck[i])])
    sec.tables.append(("UT-SEA, Table I timing: jitter margins [ms]", [
        "f_n [Hz]", "outer loop", "stiffness loop", "damping loop", "torque loop",
        "delay margin (outer, constant)", "smallest single loop"], rows))
    i14 = TABLE_I_FN.index(14.0)
    sec.claims.append(Claim(
        "jitter.sea.outer_fn14", "Jitter (issue 14)",
        "UT-SEA, f_n = 14 Hz, Table I timing: jitter margin of the whole outer loop [ms]",
        "-", round(1e3 * float(j.jitter_margin_s[i14]), 4), "-", "info",
        f"against a constant-delay margin of {1e3 * float(j.delay_margin_s[i14]):.3f} ms"))
    below = bool(np.all(j.jitter_margin_s <= j.delay_margin_s * (1 + 1e-9)))
    sec.claims.append(Claim(
        "jitter.sea.below_delay_margin", "Jitter (issue 14)",
        "the outer loop's jitter margin never exceeds its constant-delay margin (a constant "
        "delay is one of the admitted variations)", "J <= DM",
        [round(1e3 * float(x), 3) for x in j.jitter_margin_s], "J <= DM at every Table I f_n",
        "pass" if below else "fail"))
    first = [f for i, f in enumerate(TABLE_I_FN) if j.damping_jitter_margin_s[i]
             < j.stiffness_jitter_margin_s[i]]
    torque = j.torque_jitter_margin_s
    sec.claims.append(Claim(
        "jitter.sea.damping_first", "Jitter (issue 14)",
        "UT-SEA: f_n of Table I at which the damping loop tolerates less jitter than the "
        "stiffness loop (it fails first on a jittery process)", "-",
        [float(f) for f in first], "-", "info",
        "stiffness / damping jitter margins: " + ", ".join(
            f"{f:g} Hz: {1e3 * a:.2f} / {1e3 * b:.2f} ms"
            for f, a, b in zip(TABLE_I_FN, j.stiffness_jitter_margin_s,
                               j.damping_jitter_margin_s))
        + f". Every loop's margin is above the torque loop's ({1e3 * float(torque[0]):.2f}"
          f"..{1e3 * float(torque[-1]):.2f} ms): jitter on the 0.5 ms torque path is the "
          "first to break the SEA."))


def _rigid_claim(sec: Section) -> None:
    from seactl.api.rigid import rigid
    from seactl.latency.jitter import model_jitter_margins
    from seactl.latency.maps import rigid_model

    rd = rigid(np.array(RIGID_FN), delays_ms={"stiffness": 1.5, "damping": 1.5},
               velocity_filter_hz=50.0)
    # RigidBatch has no jitter_margins() on this branch: the per-loop model's
    rj = model_jitter_margins(rigid_model(), rd.rigid)
    ok = bool(np.all(rj.damping_s < rj.stiffness_s))
    sec.claims.append(Claim(
        "jitter.rigid.damping_first", "Jitter (issue 14)",
        "rigid actuator (f_n = 4, 8, 12 Hz, 1.5 ms on both loops): the damping loop tolerates "
        "far less jitter than the stiffness loop, as for constant delays",
        "damping << stiffness", [round(float(a / b), 3) for a, b in
                                 zip(rj.stiffness_s, rj.damping_s)],
        "stiffness / damping jitter margin > 1 for every f_n", "pass" if ok else "fail",
        ", ".join(f"{f:g} Hz: {1e3 * a:.1f} / {1e3 * b:.2f} ms"
                  for f, a, b in zip(RIGID_FN, rj.stiffness_s, rj.damping_s))))


def _loss_claims(sec: Section) -> None:
    from seactl.latency.models import Bernoulli

    o0, o1, jit, mc = _loss_cost()
    drop = None if (o0.fn_hz is None or o1.fn_hz is None) else 1 - o1.fn_hz / o0.fn_hz
    sec.claims.append(Claim(
        "jitter.loss1pct.fn", "Jitter (issue 14)",
        f"UT-SEA, distributed placement, Table I timing: the advisor's score (PM >= "
        f"{PM_FLOOR_DEG:g} deg for every loop latency from 0 to 1.5x its own) without loss, "
        f"and with the jitter margins covering {100 * LOSS:g} % loss on the embedded process "
        "[Hz]", "-",
        [None if o.fn_hz is None else round(o.fn_hz, 3) for o in (o0, o1)], "-", "info",
        (f"{100 * LOSS:g} % independent loss: bursts of up to "
         f"{Bernoulli(LOSS).burst()} messages at the 99.9 % level, i.e. {jit * 1e3:g} ms of held "
         f"value at 1 kHz on the torque and damping paths; the guaranteed f_n drops by "
         f"{100 * drop:.0f} % (bottleneck: {o1.bottleneck}). " if drop is not None else "")
        + (f"The Monte Carlo at the lossless optimum ({o0.fn_hz:.2f} Hz) with that loss "
           f"keeps {100 * float(mc.fraction_stable):.1f} % of {mc.runs} runs stable: the "
           "guaranteed figure is conservative." if mc is not None else "")))
