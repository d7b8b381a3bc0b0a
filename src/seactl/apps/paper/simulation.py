"""Sections: the paper's step-response figures (Fig. ImpedanceDelay, Fig. GainScale(b),
Fig. ExperimentGS) and the impulse test (Fig. ExperimentImpulse), simulated with exact
delays (continuous) and as on the hardware (sampled), from the one block diagram.

Designs come from :func:`seactl.design`, margins and responses from its methods; the
continuous figures are of the unit step (``amplitude=1.0``: the normalized response of the
linear loop), the sampled ones of :data:`STEP_RAD`."""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.api.sea import Design, design
from seactl.apps.report import Claim, Context, Figure, Section, numeric_claim, section
from seactl.simulate.metrics import impulse_metrics

from .constants import TABLE_I_TIMING, design_keywords

FN_A = np.array([14.0, 16.0, 18.0, 20.0])
TIMING_A = dict(t_tau_ms=1.0, t_qs_ms=1.0, t_qd_ms=1.0, f_qd_hz=50.0, f_taud_hz=100.0)
T_QS_B = np.array([1.0, 5.0, 10.0, 15.0])   # ms, stiffness delay sweep (T_qd = T_tau = 1 ms)
T_QD_C = np.array([1.0, 3.0, 5.0, 7.0])     # ms, damping delay sweep (T_qs = T_tau = 1 ms)
FN_BC = 20.0
FN_SENS = np.array([12.0, 14.0, 16.0, 18.0, 20.0, 25.0, 30.0])
GS_B = np.array([0.4, 0.7, 1.0, 1.5, 2.0, 3.0])
GS_EXP = np.array([1.0, 1.5, 2.0, 2.5])
STEP_RAD = 0.01   # step size of the sampled (saturating) simulations [rad]


def _fmt_pm(pm: float, stable: bool = True) -> str:
    text = f"{pm:.2f} deg" if np.isfinite(pm) else "no crossover"
    return text if stable else f"{text} (unstable)"


def _design(fn, gs=1.0, **timing) -> Design:
    return design(fn, gs=gs, **design_keywords(**timing))


def _pm_search() -> list[tuple[str, float, float]]:
    """Candidate parameter sets of Fig. ImpedanceDelay (a): (timing label, f_n, PM)."""
    fn = np.array([12.0, 14.0, 16.0, 18.0, 20.0, 25.0, 30.0])
    timings = {
        "T_tau=T_qd=0.5, T_qs=2 ms (Table I)": (0.5, 2.0, 0.5),
        "all delays 0.5 ms": (0.5, 0.5, 0.5),
        "all delays 1 ms": (1.0, 1.0, 1.0),
        "no delays": (0.0, 0.0, 0.0),
        "T_qs=5, T_qd=2, T_tau=1 ms": (1.0, 5.0, 2.0),
        "T_qs=10, T_qd=3, T_tau=1 ms": (1.0, 10.0, 3.0),
    }
    out = []
    for label, (tt, ts, td) in timings.items():
        for filt, (fq, ft) in (("filters 50/100 Hz", (50.0, 100.0)), ("no filters", (None, None))):
            d = _design(fn, t_tau_ms=tt, t_qs_ms=ts, t_qd_ms=td, f_qd_hz=fq, f_taud_hz=ft)
            pm = d.margins().phase_margin_deg
            out.extend((f"{label}, {filt}", float(f), float(p)) for f, p in zip(fn, pm))
    return out


def delay_sensitivity(fn: np.ndarray = FN_SENS) -> dict[str, np.ndarray]:
    """Phase margin and stability versus T_qs (T_qd = T_tau = 1 ms) and versus T_qd
    (T_qs = T_tau = 1 ms), filters 50/100 Hz; arrays of shape ``(len(fn), len(T))``."""
    T = np.round(np.arange(0.0, 30.0001, 0.25), 6)
    fn_col = np.asarray(fn, float)[:, None]
    m_qs = _design(fn_col, t_tau_ms=1.0, t_qs_ms=T, t_qd_ms=1.0, f_qd_hz=50.0,
                   f_taud_hz=100.0).margins()
    m_qd = _design(fn_col, t_tau_ms=1.0, t_qs_ms=1.0, t_qd_ms=T, f_qd_hz=50.0,
                   f_taud_hz=100.0).margins()
    return {"fn": np.asarray(fn, float), "T_ms": T, "pm_qs": m_qs.phase_margin_deg,
            "stable_qs": m_qs.stable, "pm_qd": m_qd.phase_margin_deg, "stable_qd": m_qd.stable}


def _critical(T: np.ndarray, stable: np.ndarray) -> float:
    bad = np.nonzero(~stable)[0]
    return float(T[bad[0]]) if bad.size else float("inf")


def _consistency_claim(cid: str, fig: str, what: str, sim_stable, margin_stable) -> Claim:
    sim_stable, margin_stable = np.ravel(sim_stable), np.ravel(margin_stable)
    ok = bool(np.all(sim_stable == margin_stable))
    return Claim(cid, fig, f"{what}: simulated stability agrees with the Nyquist criterion "
                 "on the exact-delay loop (sea_margins)", [bool(x) for x in margin_stable],
                 [bool(x) for x in sim_stable], "equal", "pass" if ok else "fail")


COLORS = ["tab:blue", "tab:green", "tab:orange", "magenta"]
T_END_S = 0.25


def _fn_sweep(sec: Section):
    """Panel (a): several f_n, all delays 1 ms, with (solid) and without (dashed) the zero."""
    da = _design(FN_A, **TIMING_A)
    ma = da.margins()
    ra = da.step(t_end_s=T_END_S, amplitude=1.0, zero=True)
    ra0 = da.step(t_end_s=T_END_S, amplitude=1.0, zero=False)
    curves = []
    for i, f in enumerate(FN_A):
        lab = f"f_n={f:g} Hz, PM {_fmt_pm(ma.phase_margin_deg[i])}"
        curves.append((ra.t_s, ra.position[i], lab, dict(color=COLORS[i])))
        curves.append((ra0.t_s, ra0.position[i], None, dict(color=COLORS[i], ls="--", lw=1)))
    rows = [[f"{f:g}", _fmt_pm(ma.phase_margin_deg[i]),
             f"{ra.metrics.overshoot_pct[i]:.1f}", f"{ra0.metrics.overshoot_pct[i]:.1f}",
             f"{1e3 * ra.metrics.rise_time_s[i]:.1f}", f"{1e3 * ra0.metrics.rise_time_s[i]:.1f}"]
            for i, f in enumerate(FN_A)]
    sec.tables.append(("(a) f_n sweep: phase margin and step metrics with / without the zero",
                       ["f_n [Hz]", "PM", "overshoot [%]", "overshoot, no zero [%]",
                        "rise [ms]", "rise, no zero [ms]"], rows))
    panel = {"title": "(a) f_n sweep, delays 1 ms (dashed: without the zero)",
             "ylabel": "q_j / q_des step", "curves": curves}
    return panel, ma, ra, ra0


def _delay_sweep(sec: Section, key: str, delays_ms: np.ndarray, label: str):
    """Panels (b) and (c): one delay swept at f_n = FN_BC, the other delays 1 ms."""
    timing = dict(t_tau_ms=1.0, t_qs_ms=delays_ms if key == "b" else 1.0,
                  t_qd_ms=delays_ms if key == "c" else 1.0, f_qd_hz=50.0, f_taud_hz=100.0)
    d = _design(FN_BC, **timing)
    m = d.margins()
    r = d.step(t_end_s=T_END_S, amplitude=1.0)
    curves = [(r.t_s, r.position[i], f"{label}={T:g} ms, PM {_fmt_pm(m.phase_margin_deg[i])}"
               + ("" if r.result.stable[i] else " (unstable)"), dict(color=COLORS[i]))
              for i, T in enumerate(delays_ms)]
    sec.tables.append((f"({key}) {label} sweep at f_n = {FN_BC:g} Hz",
                       [f"{label} [ms]", "PM", "stable (Nyquist)", "stable (simulation)",
                        "overshoot [%]", "settling 2% [ms]"],
                       [[f"{T:g}", _fmt_pm(m.phase_margin_deg[i], m.stable[i]),
                         "yes" if m.stable[i] else "NO", "yes" if r.result.stable[i] else "NO",
                         f"{r.metrics.overshoot_pct[i]:.1f}",
                         f"{1e3 * r.metrics.settling_time_s[i]:.0f}"]
                        for i, T in enumerate(delays_ms)]))
    panel = {"title": f"({key}) {label} sweep, f_n = {FN_BC:g} Hz, other delays 1 ms",
             "ylabel": "q_j / q_des step", "curves": curves, "ylim": (-0.2, 2.2)}
    return panel, m, r


def _fn_sweep_claims(sec: Section, ma, ra, ra0) -> None:
    inc = bool(np.all(np.diff(ra.metrics.overshoot_pct) > 0))
    sec.claims.append(Claim("impdelay.a.overshoot_grows_with_fn", "Fig. ImpedanceDelay",
                            "(a) a larger f_n leads to a larger overshoot", "yes",
                            [round(float(x), 2) for x in ra.metrics.overshoot_pct], "increasing",
                            "pass" if inc else "fail",
                            "" if inc else "with delays of 1 ms and the 50/100 Hz filters the "
                            "overshoot (caused by the zero) decreases with f_n; it grows with "
                            "f_n only with larger delays (table below), which would then not "
                            "give the caption's 36.4 degrees"))
    more = bool(np.all(ra.metrics.overshoot_pct > ra0.metrics.overshoot_pct))
    sec.claims.append(Claim("impdelay.a.zero_adds_overshoot", "Fig. ImpedanceDelay",
                            "(a) the zero of P_CL induces (extra) overshoot",
                            "yes", [round(float(a - b), 2) for a, b in
                                    zip(ra.metrics.overshoot_pct, ra0.metrics.overshoot_pct)],
                            "> 0 for every f_n", "pass" if more else "fail",
                            "values: overshoot with minus without the zero [percentage points]"))
    smallest = bool(np.argmin(ma.phase_margin_deg) == len(FN_A) - 1)
    sec.claims.append(numeric_claim(
        "impdelay.a.pm_largest_fn", "Fig. ImpedanceDelay",
        f"(a) the largest f_n ({FN_A[-1]:g} Hz, delays 1 ms, filters 50/100 Hz) has a 36.4 degree "
        "phase margin, the smallest of the four", 36.4, float(ma.phase_margin_deg[-1]), 0.1,
        "" if smallest else "it is not the smallest of the four"))


def _pm36_source(sec: Section) -> None:
    """Which candidate parameter sets give the caption's 36.4 degrees."""
    matches = [(lab, f, p) for lab, f, p in _pm_search() if 36.4 <= p < 36.5]
    sec.tables.append(("Which parameter sets give the caption's 36.4 degrees (PM in [36.4, 36.5), "
                       "i.e. 36.4 when truncated as Table I's 43.2 is)",
                       ["timing, filters", "f_n [Hz]", "PM [deg]"],
                       [[lab, f"{f:g}", f"{p:.3f}"] for lab, f, p in matches]))
    sec.claims.append(Claim(
        "impdelay.a.pm36.4_source", "Fig. ImpedanceDelay",
        "parameter sets (of a candidate grid) whose largest-f_n margin is 36.4 degrees",
        36.4, [f"{lab}, f_n={f:g} Hz: {p:.3f}" for lab, f, p in matches], "[36.4, 36.5)", "info",
        "only f_n = 20 Hz with the 50/100 Hz filters and short delays (all 0.5 or 1 ms, or none) "
        "gives 36.4x; Table I's timing gives 36.53 at 18 Hz (36.5) and 33.19 at 20 Hz. So the "
        "caption's magenta curve is most likely f_n = 20 Hz with filters 50/100 Hz and delays "
        "of at most 1 ms" if any(f == 20.0 for _l, f, _p in matches) else
        "no candidate set gives 36.4x"))


SENS_RANGE_MS = (0.0, 30.0)
"""Delays scanned for the stability intervals [ms]; grid step :data:`SENS_STEP_MS`."""
SENS_STEP_MS = 0.05
SENS_NOMINAL_MS = 1.0            # the other delays, and the operating point of the sweep


def sensitivity_intervals(fn: np.ndarray = FN_SENS) -> dict[float, dict[str, list]]:
    """Per f_n: the stable intervals [ms] of T_qs (T_qd = T_tau = 1 ms) and of T_qd
    (T_qs = T_tau = 1 ms), filters 50/100 Hz (:func:`seactl.analysis.delay_intervals`)."""
    from seactl.analysis.delay_intervals import stability_intervals

    grid = np.round(np.arange(SENS_RANGE_MS[0], SENS_RANGE_MS[1] + 1e-9, SENS_STEP_MS), 9)
    out = {}
    for f in np.asarray(fn, float):
        res = {}
        for name, key in (("T_qs", "t_qs_ms"), ("T_qd", "t_qd_ms")):
            def stable(T_s, key=key, f=f):
                timing = {"t_tau_ms": 1.0, "t_qs_ms": 1.0, "t_qd_ms": 1.0,
                          key: np.asarray(T_s) * 1e3}
                return _design(f, **timing, f_qd_hz=50.0, f_taud_hz=100.0).margins().stable
            iv = stability_intervals(stable, grid * 1e-3, tol_s=1e-7)
            res[name] = [(lo * 1e3, hi * 1e3) for lo, hi in iv]
        out[float(f)] = res
    return out


def _iv_text(ivs: list[tuple[float, float]]) -> str:
    return ", ".join(f"[{lo:.4g}, {hi:.4g}]" for lo, hi in ivs) or "none"


def _sensitivity_rows() -> tuple[list[list[str]], dict[float, tuple]]:
    """Per f_n: stable intervals of each delay, and which delay the operating point
    (every delay 1 ms) tolerates less growth of."""
    from seactl.analysis.delay_intervals import interval_containing

    ivs = sensitivity_intervals()
    s = delay_sensitivity()
    T = s["T_ms"]
    i1, i2 = int(np.argmin(np.abs(T - 1.0))), int(np.argmin(np.abs(T - 2.0)))
    rows, holds = [], {}
    for k, f in enumerate(s["fn"]):
        iq = interval_containing(ivs[float(f)]["T_qs"], SENS_NOMINAL_MS)
        idd = interval_containing(ivs[float(f)]["T_qd"], SENS_NOMINAL_MS)
        dq = float(s["pm_qs"][k, i2] - s["pm_qs"][k, i1])
        dd = float(s["pm_qd"][k, i2] - s["pm_qd"][k, i1])
        verdict = None if iq is None or idd is None else bool(idd[1] < iq[1])
        holds[float(f)] = (verdict, iq, idd, dq, dd)
        rows.append([f"{f:g}", _iv_text(ivs[float(f)]["T_qs"]), _iv_text(ivs[float(f)]["T_qd"]),
                     f"{dq:.2f}", f"{dd:.2f}",
                     "no verdict (unstable at 1 ms)" if verdict is None else
                     ("yes" if verdict else "no")])
    return rows, holds


def _upper(iv) -> float | None:
    return None if iv is None else round(float(iv[1]), 4)


def _sensitivity(sec: Section) -> None:
    rows, holds = _sensitivity_rows()
    lo, hi = SENS_RANGE_MS
    sec.tables.append((f"Delay sensitivity per f_n (other delays 1 ms, filters 50/100 Hz): "
                       f"the delays in {lo:g}-{hi:g} ms where the loop is stable (Nyquist, "
                       f"exact delays; {SENS_STEP_MS:g} ms grid, boundaries bisected to "
                       "1e-4 ms; an interval ending at 30 ms ends with the range). 'More "
                       "critical': the stable interval through the 1 ms operating point ends "
                       "at a shorter damping delay than stiffness delay. dPM: phase-margin "
                       "change from 1 to 2 ms (it can jump where the crossover moves to "
                       "another frequency)",
                       ["f_n [Hz]", "stable T_qs [ms]", "stable T_qd [ms]",
                        "dPM T_qs 1->2 ms [deg]", "dPM T_qd 1->2 ms [deg]",
                        "damping delay more critical"], rows))
    ok, iq, idd, dq, dd = holds[FN_BC]
    sec.claims.append(Claim(
        "impdelay.damping_delay_more_sensitive", "Fig. ImpedanceDelay",
        "SEA stability is more sensitive to damping delays than to stiffness delays "
        f"(f_n = {FN_BC:g} Hz, as in panels (b), (c))",
        "stable T_qd interval through 1 ms ends before the T_qs one",
        {"stable_T_qs_upper_ms": _upper(iq), "stable_T_qd_upper_ms": _upper(idd),
         "dPM_1to2ms_T_qs_deg": round(dq, 3), "dPM_1to2ms_T_qd_deg": round(dd, 3)},
        f"strict, delays {lo:g}-{hi:g} ms", "pass" if ok else "fail"))
    fails = [f for f, v in holds.items() if v[0] is not True]
    sec.claims.append(Claim(
        "impdelay.damping_delay_more_sensitive.all_fn", "Fig. ImpedanceDelay",
        "the same claim at every f_n of " + ", ".join(f"{f:g}" for f in FN_SENS) + " Hz",
        "holds at every f_n", {f"{f:g}": v[0] for f, v in holds.items()},
        f"stable intervals, delays {lo:g}-{hi:g} ms", "pass" if not fails else "fail",
        "" if not fails else "does not hold at f_n = " + ", ".join(
            f"{f:g}" + (" (unstable at the 1 ms operating point)" if holds[f][0] is None
                        else "") for f in fails) + " Hz"))


def _overshoot_trend(sec: Section) -> None:
    """Overshoot versus f_n for several delay sets: the trend of panel (a) depends on them."""
    fn = np.array([12.0, 14.0, 16.0, 18.0, 20.0, 25.0, 30.0])
    cases = [("all 1 ms, filters 50/100", 1, 1, 1, 50), ("Table I timing", 0.5, 2, 0.5, 50),
             ("all 1 ms, no filters", 1, 1, 1, np.inf), ("T_qs=5, T_qd=2, T_tau=1 ms", 1, 5, 2, 50),
             ("T_qs=10, T_qd=3, T_tau=1 ms", 1, 10, 3, 50)]
    arr = np.array([c[1:] for c in cases], float)
    ro = _design(fn[None, :], t_tau_ms=arr[:, :1], t_qs_ms=arr[:, 1:2], t_qd_ms=arr[:, 2:3],
                 f_qd_hz=arr[:, 3:4], f_taud_hz=2 * arr[:, 3:4]
                 ).step(t_end_s=T_END_S, amplitude=1.0)
    sec.tables.append(("Overshoot [%] versus f_n (with the zero) for several delay sets: the "
                       "trend of panel (a) depends on the delays",
                       ["delays, filters"] + [f"{f:g} Hz" for f in fn],
                       [[c[0]] + [f"{x:.1f}" if ro.result.stable[i, j] else "unstable"
                                  for j, x in enumerate(ro.metrics.overshoot_pct[i])]
                        for i, c in enumerate(cases)]))


@section(40, "impedance-delay")
def impedance_delay(ctx: Context) -> Section:
    from seactl.apps.plots import panels_figure

    sec = Section("impedance-delay", "Fig. ImpedanceDelay: step responses affected by delays",
                  intro="Continuous-time simulations with exact transport delays (delay buffers, "
                        "exact integration between 0.1 ms steps), derived from the SEA block "
                        "diagram. The caption gives no parameters; this reconstruction uses "
                        "filters f_qd = 50 Hz, f_taud = 100 Hz and, in (a), all delays 1 ms and "
                        f"f_n = {', '.join(f'{f:g}' for f in FN_A)} Hz (the choice is explained "
                        "below by the caption's 36.4 degree margin); (b) sweeps T_qs and (c) "
                        f"sweeps T_qd at f_n = {FN_BC:g} Hz with the other delays 1 ms. "
                        "Each legend gives the phase margin of the curve (outer loop, inner "
                        "loop closed, exact delays).")
    panel_a, ma, ra, ra0 = _fn_sweep(sec)
    panel_b, mb, rb = _delay_sweep(sec, "b", T_QS_B, "T_qs")
    panel_c, mc, rc = _delay_sweep(sec, "c", T_QD_C, "T_qd")
    fig = panels_figure([panel_a, panel_b, panel_c], ncols=3, figsize=(15, 4.4))
    sec.figures.append(Figure(ctx.savefig(fig, "impedance_delay.png"),
                              "Fig. ImpedanceDelay reconstructed: (a) f_n sweep with (solid) and "
                              "without (dashed) the torque-derivative zero; (b) stiffness-delay "
                              "and (c) damping-delay sweeps. Phase margins in the legends."))
    sec.claims.append(_consistency_claim(
        "impdelay.sim_vs_nyquist", "Fig. ImpedanceDelay", "panels (a)-(c)",
        np.concatenate([ra.result.stable, rb.result.stable, rc.result.stable]),
        np.concatenate([ma.stable, mb.stable, mc.stable])))
    _fn_sweep_claims(sec, ma, ra, ra0)
    _pm36_source(sec)
    _sensitivity(sec)
    _overshoot_trend(sec)
    return sec


@section(41, "gain-scale-step")
def gain_scale_step(ctx: Context) -> Section:
    from seactl.apps.plots import panels_figure

    sec = Section("gain-scale-step", "Fig. GainScale(b): step responses over the gain scale",
                  intro=f"f_n = 14 Hz, ideal loop (no delays, no filters, as the paper says), "
                        f"continuous simulation, GS = {', '.join(f'{g:g}' for g in GS_B)}. "
                        "Unfiltered derivatives are realized with a 1.6 MHz roll-off.")
    d = _design(14.0, gs=GS_B)
    m = d.margins()
    r = d.step(t_end_s=0.3, amplitude=1.0)
    colors = plt_colors(len(GS_B))
    curves = [(r.t_s, r.position[i], f"GS={g:g}, PM {_fmt_pm(m.phase_margin_deg[i])}",
               dict(color=colors[i], ls="-" if g >= 1 else "--")) for i, g in enumerate(GS_B)]
    fig = panels_figure([{"title": "f_n = 14 Hz, ideal loop", "ylabel": "q_j / q_des step",
                          "curves": curves}], figsize=(7.5, 4.5))
    sec.figures.append(Figure(ctx.savefig(fig, "gain_scale_step.png"),
                              "Fig. GainScale(b) reconstructed: step responses for several GS "
                              "(dashed: GS < 1)."))
    mt = r.metrics
    exact = exact_overshoots_pct(14.0, GS_B)
    sec.tables.append(("Step metrics per GS (overshoot: exact peak of the continuous, "
                       "delay-free closed loop; rise and settling: the simulation)",
                       ["GS", "PM", "rise [ms]", "overshoot [%]", "settling 2% [ms]"],
                       [[f"{g:g}", _fmt_pm(m.phase_margin_deg[i]),
                         f"{1e3 * mt.rise_time_s[i]:.1f}", f"{exact[i]:.3f}",
                         f"{1e3 * mt.settling_time_s[i]:.0f}"] for i, g in enumerate(GS_B)]))
    above = GS_B >= 1
    ov, rt = exact[above], mt.rise_time_s[above]
    ok = bool(np.all(np.diff(ov) > 0))
    sec.claims.append(Claim("gainscale_b.overshoot_gs_gt1", "Fig. GainScale(b)",
                            "GS > 1: a larger overshoot as GS grows", "increasing",
                            [round(float(x), 3) for x in ov], "strictly increasing over "
                            "GS = 1, 1.5, 2, 3", "pass" if ok else "fail",
                            "overshoot [%] of the continuous delay-free loop (no filters), "
                            "from the exact peak of its step response (seactl.analysis.step_peak: "
                            "matrix exponential of a balanced realization, Brent between "
                            "samples)"))
    ok = bool(np.all(np.diff(rt) > 0))
    sec.claims.append(Claim("gainscale_b.rise_gs_gt1", "Fig. GainScale(b)",
                            "GS > 1: a slower rise as GS grows", "increasing",
                            [round(float(1e3 * x), 2) for x in rt], "strictly increasing [ms]",
                            "pass" if ok else "fail"))
    i04 = int(np.argmin(np.abs(GS_B - 0.4)))
    sec.claims.append(Claim("gainscale_b.gs0.4", "Fig. GainScale(b)",
                            "GS < 1 (0.4): an over-damped response with distortions",
                            "over-damped, distorted",
                            {"overshoot_pct": round(float(exact[i04]), 3),
                             "rise_ms": round(float(1e3 * mt.rise_time_s[i04]), 2),
                             "pm_deg": round(float(m.phase_margin_deg[i04]), 2)},
                            "qualitative", "info",
                            "read the figure: compare the GS = 0.4 curve's shape with GS = 1"))
    return sec


def exact_overshoots_pct(fn_hz: float, gs: np.ndarray) -> np.ndarray:
    """Overshoot [%] of the ideal (delay-free, unfiltered) loop's step response per GS,
    from the exact peak of the continuous response (:func:`seactl.analysis.step_peak.step_peak`)."""
    from seactl.analysis.step_peak import step_peak
    from seactl.api.sea import design

    systems = design(fn_hz, gs=np.asarray(gs, float)).to_control("pade-ss", transfer="closed")
    return np.array([step_peak(s.A, s.B, s.C, s.D, 0.3).overshoot_pct for s in systems])


def plt_colors(n: int):
    import matplotlib.pyplot as plt

    return plt.cm.viridis(np.linspace(0, 0.9, n))


@section(42, "experiment-gs")
def experiment_gs(ctx: Context) -> Section:
    from seactl.apps.plots import panels_figure

    timing = dict(t_tau_ms=1.0, t_qs_ms=1.0, t_qd_ms=1.0, f_qd_hz=50.0, f_taud_hz=100.0)
    sec = Section("experiment-gs", "Fig. ExperimentGS: step responses over GS, both modes",
                  intro="f_n = 14 Hz, all delays 1 ms, filters 50/100 Hz, GS = "
                        f"{', '.join(f'{g:g}' for g in GS_EXP)}. Continuous: exact 1 ms delays. "
                        f"Sampled: Tustin controllers, ZOH, {STEP_RAD:g} rad step, 30 A current "
                        "limit. Whole-sample buffers give effective delays T_s/2 + n T_s, the "
                        "shortest realizable ones not shorter than the requested 1 ms: ")
    d = _design(14.0, gs=GS_EXP, **timing)
    m = d.margins()
    rc = d.step(t_end_s=0.4, amplitude=STEP_RAD)
    rs = d.step(t_end_s=0.4, mode="sampled", rate_hz=1000.0, amplitude=STEP_RAD)
    r15 = d.step(t_end_s=0.4, mode="sampled", rate_hz=1500.0, amplitude=STEP_RAD)
    sec.intro += "; ".join(f"{rate}: {_delays_text(r)}" for rate, r in (
        ("at 1 kHz (the paper's rate)", rs), ("at 1.5 kHz", r15))) + "."
    colors = plt_colors(len(GS_EXP))
    curves = []
    for i, g in enumerate(GS_EXP):
        curves.append((rc.t_s, rc.position[i], f"GS={g:g} continuous (PM "
                       f"{_fmt_pm(m.phase_margin_deg[i])})", dict(color=colors[i])))
        curves.append((rs.t_s, rs.position[i], "sampled 1 kHz" if i == 0 else None,
                       dict(color=colors[i], ls="--", lw=1)))
        curves.append((r15.t_s, r15.position[i], "sampled 1.5 kHz" if i == 0 else None,
                       dict(color=colors[i], ls=":", lw=1.5)))
    fig = panels_figure([{"title": "f_n = 14 Hz, delays 1 ms (solid continuous, dashed sampled "
                                    "1 kHz, dotted sampled 1.5 kHz)",
                          "ylabel": "q_j / q_des step", "curves": curves}], figsize=(8, 4.8))
    sec.figures.append(Figure(ctx.savefig(fig, "experiment_gs.png"),
                              "Fig. ExperimentGS reconstructed (simulation side): continuous and "
                              "sampled step responses overlaid."))
    rows = []
    for i, g in enumerate(GS_EXP):
        row = [f"{g:g}", _fmt_pm(m.phase_margin_deg[i])]
        for r in (rc, rs, r15):
            word = _verdicts(r)[i]
            row += [f"{1e3 * r.metrics.rise_time_s[i]:.1f}", f"{r.metrics.overshoot_pct[i]:.1f}"
                    + ("" if word == "stable" else f" ({word})")]
        rows.append(row)
    sec.intro += (" A sampled response is marked with its loop's certified verdict "
                  "(seactl.simulate.sampled) where that loop is not stable.")
    sec.tables.append(("Rise time [ms] and overshoot [%] per mode",
                       ["GS", "PM (1 ms)", "rise cont.", "overshoot cont.", "rise 1 kHz",
                        "overshoot 1 kHz", "rise 1.5 kHz", "overshoot 1.5 kHz"], rows))
    for key, r in (("continuous", rc), ("sampled_1khz", rs), ("sampled_1.5khz", r15)):
        stable = _verdicts(r) == "stable"
        ov = r.metrics.overshoot_pct[stable]
        rt = r.metrics.rise_time_s[stable]
        ok = bool(stable[0] and np.all(np.diff(ov) > 0) and np.all(np.diff(rt) > 0))
        note = "" if stable.all() else (
            "not stable at GS = " + ", ".join(f"{g:g}" for g in GS_EXP[~stable])
            + (" (the sampled loop's certified verdict)" if key != "continuous" else "")
            + "; compared over the stable ones")
        sec.claims.append(Claim(
            f"experimentgs.{key}", "Fig. ExperimentGS",
            f"GS > 1: a larger GS slows the rise and increases the overshoot ({key})",
            "increasing", {"rise_ms": [round(float(1e3 * x), 2) for x in rt],
                           "overshoot_pct": [round(float(x), 2) for x in ov]},
            "both strictly increasing in GS", "pass" if ok else "fail", note))
    sec.claims.append(_consistency_claim("experimentgs.sim_vs_nyquist", "Fig. ExperimentGS",
                                         "continuous, 1 ms delays", rc.result.stable, m.stable))
    return sec


def _verdicts(r: Any) -> np.ndarray:
    """Per design, "stable", "unstable" or "uncertain": the sampled loop's certified verdict
    for a sampled response, the simulated window's for a continuous one."""
    info = r.result.info
    if "sampled_verdict" in info:
        return np.asarray(info["sampled_verdict"]).reshape(-1)
    return np.where(np.asarray(r.result.stable).reshape(-1), "stable", "unstable")


def _delays_text(r: Any) -> str:
    """A sampled response's delays per loop, requested -> effective [ms]."""
    from seactl.latency.montecarlo import SEA_LINKS

    info = r.result.info
    return ", ".join(f"{loop} {1e3 * float(np.max(info['requested_delays_s'][b])):g} -> "
                     f"{1e3 * float(np.max(info['effective_delays_s'][b])):g} ms"
                     for loop, b in SEA_LINKS.items())


@section(43, "experiment-impulse")
def experiment_impulse(ctx: Context) -> Section:
    from seactl.apps.plots import panels_figure

    timing = TABLE_I_TIMING
    d = _design(14.0, **timing)
    unit = d.impulse(amplitude=1.0, t_end_s=1.0)
    J = float(np.radians(2.5) / unit.metrics.peak_deviation)
    rc = d.impulse(amplitude=J, t_end_s=1.0)
    rs = d.impulse(amplitude=J, t_end_s=1.0, mode="sampled")
    sec = Section("experiment-impulse", "Fig. ExperimentImpulse: impulse disturbance",
                  intro="f_n = 14 Hz gains (Table I), Table I delays and filters, an angular "
                        "impulse of external torque on the joint at t = 0 (q_des = 0). The "
                        "ball's mass and lever arm are not published; the impulse is chosen so "
                        f"that the continuous model's peak deviation is the caption's 2.5 "
                        f"degrees: J = {J:.4f} N m s (a perfectly inelastic 20 cm drop, "
                        f"v = 1.98 m/s, means m r = {J / np.sqrt(2 * 9.81 * 0.2):.4f} kg m). "
                        "Recovery time: last exit from a band of 5 % of the peak deviation. "
                        "Sampled at 1 kHz, delays requested -> effective (T_s/2 + whole "
                        f"samples, never shorter): {_delays_text(rs)}.")
    curves = [(rc.t_s, np.degrees(rc.position), "continuous", dict(color="tab:blue")),
              (rs.t_s, np.degrees(rs.position), "sampled 1 kHz, 30 A",
               dict(color="tab:red", ls="--"))]
    fig = panels_figure([{"title": f"impulse {J:.3f} N m s, f_n = 14 Hz", "ylabel":
                          "joint angle [deg]", "curves": curves, "xlim": (0, 0.5)}],
                        figsize=(7.5, 4.2))
    sec.figures.append(Figure(ctx.savefig(fig, "experiment_impulse.png"),
                              "Impulse response (continuous and sampled)."))
    rows = []
    for name, r in (("continuous", rc), ("sampled 1 kHz", rs)):
        mt = r.metrics
        b2 = float(impulse_metrics(r.t_s, r.position, band=0.02).recovery_time_s)
        rows.append([name, str(_verdicts(r)[0]), f"{np.degrees(float(mt.peak_deviation)):.3f}",
                     f"{1e3 * float(mt.peak_time_s):.1f}", f"{1e3 * float(mt.recovery_time_s):.0f}",
                     f"{1e3 * b2:.0f}", f"{float(np.max(np.abs(r.current))):.2f}"])
    sec.tables.append(("Impulse metrics", ["mode", "loop verdict", "peak [deg]", "peak at [ms]",
                                           "recovery 5 % [ms]", "recovery 2 % [ms]",
                                           "peak |i_m| [A]"], rows))
    rec = float(rs.metrics.recovery_time_s)
    sec.claims.append(Claim("impulse.recovers_within_0.3s", "Fig. ExperimentImpulse",
                            "the arm recovers to its initial position within 0.3 s", 0.3,
                            round(rec, 4), "<= 0.3 s", "pass" if rec <= 0.3 else "fail",
                            "sampled model, 5 % band"))
    sec.claims.append(numeric_claim(
        "impulse.recovery_about_0.3s", "Fig. ExperimentImpulse",
        "the actuator recovers after approximately 0.3 s (sampled model, 5 % band)", 0.3, rec,
        0.1, f"the model recovers in {rec:.3f} s, several times faster than the experiment: the "
             "model has no ball contact dynamics, friction or the hardware's reaction-force "
             "spring arrangement" if abs(rec - 0.3) > 0.1 else ""))
    return sec
