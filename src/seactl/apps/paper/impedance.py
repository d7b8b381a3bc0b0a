"""Sections: the paper's impedance figures (Fig. impedanceFilterDelay, impedanceNaturalFreq,
loadinertia), the reference MATLAB's four delay sets, the k_tau/beta finding, the Z-region.

Every figure is drawn twice: with the ``paper`` model (the printed N_zi/D_zi, which the
published curves use) and with the ``block-diagram`` model (derived from the loop); the
caption of each says which.  Parameters the captions leave open are stated as assumptions.

Designs come from :func:`seactl.design`, impedances and margins from its methods; the
asymptotes, passivity scans, Z-region, a load inertia other than the actuator's and the
printed form with ``k_tau`` replaced have no public view, so they call
:mod:`seactl.systems.sea.impedance` on the design's ``sea`` batch.
"""

from __future__ import annotations

import numpy as np

from seactl.api.sea import Design, design
from seactl.apps.report import Claim, Context, Figure, Section, numeric_claim, pm_cell, section
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.asymptotes import (
    asymptotes,
    high_frequency_asymptote,
    low_frequency_stiffness,
)
from seactl.systems.sea.impedance import MODELS, impedance
from seactl.systems.sea.loops import closed_loop
from seactl.systems.sea.passivity import passivity
from seactl.systems.sea.zregion import excess_over_asymptotes_db, zregion

from .constants import FILTERS, TABLE_I_TIMING, design_keywords

F_HZ = np.logspace(-1, 3, 600)
F_LOW = np.array([1e-4])
F_HIGH = np.array([1e5])
NATFREQ_DELAYS = dict(t_tau_ms=1.0, t_qs_ms=10.0, t_qd_ms=1.0)
# The reference MATLAB's delay sets at f_n = 30 Hz: (label, T_tau, T_qs, T_qd) [ms].
DELAY_SETS = [("no delay", 0.0, 0.0, 0.0), ("T_qs=1, T_qd=1, T_tau=1 ms", 1.0, 1.0, 1.0),
              ("T_qs=5, T_qd=2, T_tau=1 ms", 1.0, 5.0, 2.0),
              ("T_qs=10, T_qd=3, T_tau=1 ms", 1.0, 10.0, 3.0)]
CAPTION_GAINS = {30: (293.6, 2.49, 11.71, 0.146), 20: (148.0, 1.49, 4.48, 0.097)}
# one unit of the last printed digit of each caption gain
GAIN_TOL = {30: (0.1, 0.01, 0.01, 0.001), 20: (1.0, 0.01, 0.01, 0.001)}
LOAD_INERTIAS = (0.014, 0.056, 0.224)  # UT-SEA I_j and 4x, 16x (caption gives none)
MODEL_TEXT = {"paper": "paper model (printed N_zi/D_zi with k_tau, as published)",
              "block-diagram": "block-diagram model (derived from the loop)"}
COLORS = ("tab:red", "tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:brown")


def _design(fn_hz, **timing) -> Design:
    """GS = 1 designs with delays [ms] and filters [Hz] by name (``t_qs_ms=10``)."""
    return design(fn_hz, **design_keywords(**timing))


def _delays(t_tau_ms: float, t_qs_ms: float, t_qd_ms: float) -> dict[str, float]:
    return {"t_tau_ms": t_tau_ms, "t_qs_ms": t_qs_ms, "t_qd_ms": t_qd_ms}


def _spring() -> np.ndarray:
    return UT_SEA.k / (2j * np.pi * F_HZ)


def _gain_claims(sec: Section, fn: int, figure: str) -> None:
    g = design(float(fn)).gains
    for name, unit, paper, tol in zip(("Kq", "Bq", "Ktau", "Btau"),
                                      ("Nm/rad", "Nms/rad", "A/Nm", "As/Nm"),
                                      CAPTION_GAINS[fn], GAIN_TOL[fn]):
        sec.claims.append(numeric_claim(f"{sec.id}.gains.fn{fn}.{name}", figure,
                                        f"caption: f_n = {fn} Hz gives {name} [{unit}]", paper,
                                        float(getattr(g, name)), tol))


def _z(d: Design, model: str, k_tau: float | None = None) -> np.ndarray:
    if k_tau is None:
        return d.impedance(F_HZ, model=model).z
    return impedance(d.sea, F_HZ, model=model, k_tau=k_tau).z   # no public k_tau keyword


def _rms_db(a: np.ndarray, b: np.ndarray) -> float:
    """RMS over the log-spaced grid of the dB difference (equal weight per decade)."""
    return float(np.sqrt(np.mean((20 * np.log10(np.abs(a) / np.abs(b))) ** 2)))


def _filter_delay_figures(sec: Section, ctx: Context, ideal, filt, delayed) -> None:
    from seactl.apps.plots import impedance_bode_figure

    for model in MODELS:
        a_i = asymptotes(ideal.sea, F_HZ, model=model)
        zi = _z(ideal, model)
        cols = [
            ("(a) ideal: Z_i", [
                dict(f=F_HZ, z=zi, label="Z_i (ideal)", color="tab:red"),
                dict(f=F_HZ, z=_spring(), dashed=True, color="goldenrod", label="spring k/(jw)"),
                dict(f=F_HZ, z=a_i.low, dashed=True, color="tab:blue",
                     label="virtual stiffness K/(jw)"),
                dict(f=F_HZ, z=a_i.high, dashed=True, color="tab:red", label="high-freq. asym.")]),
            ("(b) filtering: Z_f", [
                dict(f=F_HZ, z=zi, label="Z_i", color="0.6"),
                dict(f=F_HZ, z=_z(filt, model), label="Z_f (50/100 Hz filters)",
                     color="tab:blue"),
                dict(f=F_HZ, z=_spring(), dashed=True, color="goldenrod", label="k/(jw)")]),
            ("(c) delays: Z_d", [dict(f=F_HZ, z=zi, label="Z_i", color="0.6")]
             + [dict(f=F_HZ, z=_z(d, model), label="Z_d " + lbl, color=c)
                for (lbl, d), c in zip(delayed, COLORS[1:])]
             + [dict(f=F_HZ, z=_spring(), dashed=True, color="goldenrod", label="k/(jw)")]),
        ]
        name = f"impedance_filter_delay_{model}.png"
        fig = impedance_bode_figure(cols, suptitle=f"f_n = 30 Hz, {MODEL_TEXT[model]}")
        sec.figures.append(Figure(ctx.savefig(fig, name),
                                  f"Fig. impedanceFilterDelay regenerated with the "
                                  f"{MODEL_TEXT[model]}."))


def _asymptote_claims(sec: Section, ideal, filt, delayed) -> None:
    """Low- and high-frequency asymptotes of Z in every scenario, both models."""
    both = _design(30.0, **_delays(1.0, 10.0, 3.0), **FILTERS)
    cases = {"i": ideal, "f": filt, "d": delayed, "fd": both}
    for model in MODELS:
        k_low = float(low_frequency_stiffness(ideal.sea, model))
        formula = ("K_q k_tau (1/beta + K_tau)/(1 + K_tau k_tau)" if model == "paper"
                   else "K_q")
        for c, d in cases.items():
            got = float(d.impedance(F_LOW, model=model).stiffness[0].real)
            sec.claims.append(numeric_claim(
                f"{sec.id}.low.{model}.{c}", "Fig. impedanceFilterDelay",
                f"{model}: jw Z_{c}(jw) -> {formula} as w -> 0 [Nm/rad] (value at 1e-4 Hz)",
                k_low, got, 1e-3 * k_low))
        # High-frequency asymptotes: ideal, delay-only (twist), filter-only.
        for c, d in (("i", ideal), ("d", delayed), ("f", filt)):
            z = d.impedance(F_HIGH, model=model).z[0]
            asym = high_frequency_asymptote(d.sea, F_HIGH, model)[0]
            what = {"i": "k (I_m + g B_tau B_q)/(jw I_m)",
                    "d": "k (I_m + g B_tau B_q e^{-jw T_qd})/(jw I_m) (twist around k/jw)",
                    "f": "k/(jw)"}[c]
            sec.claims.append(numeric_claim(
                f"{sec.id}.high.{model}.{c}", "Fig. impedanceFilterDelay",
                f"{model}: Z_{c}(jw) -> {what}, g = {'beta' if model != 'paper' else 'k_tau'}: "
                f"|Z / asymptote - 1| at 1e5 Hz", 0.0, float(abs(z / asym - 1)), 1e-3))


# ------------------------------------------------------------------ Fig. impedanceFilterDelay
@section(40, "impedance-filter-delay")
def filter_delay(ctx: Context) -> Section:
    sec = Section("impedance-filter-delay",
                  "Fig. impedanceFilterDelay: impedance with delays and filtering (f_n = 30 Hz)",
                  intro="Critically-damped gains at f_n = 30 Hz, UT-SEA, rotary units "
                        "(|Z| in dB re 1 N m s/rad). (a) ideal SEA with the physical spring "
                        "k/(jw) and the virtual-stiffness asymptote; (b) filtering only "
                        "(f_qd = 50 Hz, f_taud = 100 Hz); (c) delays only, the reference "
                        "MATLAB's delay sets. Assumption: the caption gives no filter or delay "
                        "values for this figure; the filters are those of Table I and "
                        "Fig. impedanceNaturalFreq.")
    _gain_claims(sec, 30, "Fig. impedanceFilterDelay")
    ideal = _design(30.0)
    filt = _design(30.0, **FILTERS)
    delayed = [(lbl, _design(30.0, **_delays(tt, ts, td))) for lbl, tt, ts, td in DELAY_SETS[1:]]
    _filter_delay_figures(sec, ctx, ideal, filt, delayed)
    _asymptote_claims(sec, ideal, filt, delayed[-1][1])
    # The twist: |jw Z_d / k| sweeps [|1 - x|, 1 + x], x = g B_tau B_q / I_m.
    fw = np.linspace(1e5, 1.05e5, 4001)
    d = delayed[-1][1]
    for model in MODELS:
        g = UT_SEA.beta if model == "block-diagram" else UT_SEA.motor_torque_constant
        x = float(g * d.sea.Btau * d.sea.Bq / d.sea.Im)
        r = np.abs(2j * np.pi * fw * d.impedance(fw, model=model).z / UT_SEA.k)
        sec.claims.append(numeric_claim(
            f"{sec.id}.twist.{model}", "Fig. impedanceFilterDelay",
            f"{model}: with delays only, |Z_d| twists around k/(jw): max |jw Z_d / k| over "
            f"100-105 kHz -> 1 + g B_tau B_q / I_m", 1 + x, float(r.max()), 1e-2 * (1 + x)))
    s = ideal.sea
    sec.notes.append("With the block diagram the high-frequency factor g B_tau B_q / I_m is "
                     f"{UT_SEA.beta * s.Btau * s.Bq / s.Im:.3g} (g = beta), so "
                     "without filters the ideal and delayed impedances sit about 19 dB above "
                     "the spring at high frequency and the delay twist is large; with the "
                     "printed form (g = k_tau) the factor is "
                     f"{UT_SEA.motor_torque_constant * s.Btau * s.Bq / s.Im:.3g} "
                     "and the curves hug k/(jw), as the paper describes.")
    return sec


# ------------------------------------------------------------------ Fig. impedanceNaturalFreq
NATFREQ_FN = (12.0, 16.0, 20.0, 25.0, 30.0)


@section(41, "impedance-natural-freq")
def natural_freq(ctx: Context) -> Section:
    from seactl.apps.plots import impedance_bode_figure

    sec = Section("impedance-natural-freq",
                  "Fig. impedanceNaturalFreq: impedance for several natural frequencies",
                  intro="f_n = " + ", ".join(f"{f:g}" for f in NATFREQ_FN) + " Hz (GS = 1). "
                        "(a) delays T_qd = T_tau = 1 ms, T_qs = 10 ms; (b) filters "
                        "f_qd = 50 Hz, f_taud = 100 Hz; (c) both; each against the ideal "
                        "impedance (thin grey). The f_n values are our choice (the caption "
                        "does not list them).")
    fn = np.array(NATFREQ_FN)
    ideal = _design(fn)
    td = _design(fn, **NATFREQ_DELAYS)
    tf = _design(fn, **FILTERS)
    tb = _design(fn, **NATFREQ_DELAYS, **FILTERS)
    rows = []
    mb = tb.margins()
    for model in MODELS:
        zi, zd, zf, zb = (_z(x, model) for x in (ideal, td, tf, tb))
        cols = []
        for title, zz in (("(a) delays", zd), ("(b) filters", zf), ("(c) delays + filters",
                                                                   zb)):
            curves = [dict(f=F_HZ, z=zi[k], color="0.7", lw=0.8,
                           label="ideal" if k == 0 else None) for k in range(len(fn))]
            curves += [dict(f=F_HZ, z=zz[k], color=c, label=f"f_n = {f:g} Hz")
                       for k, (f, c) in enumerate(zip(fn, COLORS))]
            cols.append((title, curves))
        fig = impedance_bode_figure(cols, suptitle=MODEL_TEXT[model])
        sec.figures.append(Figure(ctx.savefig(fig, f"impedance_natural_freq_{model}.png"),
                                  f"Fig. impedanceNaturalFreq regenerated with the "
                                  f"{MODEL_TEXT[model]}."))
        dd = [_rms_db(zd[k], zi[k]) for k in range(len(fn))]
        ff = [_rms_db(zf[k], zi[k]) for k in range(len(fn))]
        for k, f in enumerate(fn):
            rows.append([model, f"{f:g}", f"{dd[k]:.2f}", f"{ff[k]:.2f}",
                         "yes" if mb.stable[k] else "NO",
                         pm_cell(mb.phase_margin_deg[k], mb.stable[k])])
        holds = all(a > b for a, b in zip(dd, ff))
        sec.claims.append(Claim(
            f"{sec.id}.delay_vs_filter.{model}", "Fig. impedanceNaturalFreq",
            f"{model}: delays affect the impedance more than filtering (RMS dB deviation from "
            "the ideal over 0.1-1000 Hz, every f_n)", "delays > filters",
            f"delays {min(dd):.2f}-{max(dd):.2f} dB, filters {min(ff):.2f}-{max(ff):.2f} dB",
            "all f_n", "pass" if holds else "fail",
            "" if holds else "not with the block diagram: without filters its unfiltered "
                             "torque derivative raises the high-frequency impedance by the "
                             "factor 1 + beta B_tau B_q / I_m (up to ~19 dB above k/jw); the "
                             "filters remove it (Z_f -> k/jw), so at high f_n filtering moves "
                             "|Z| more than these delays. It holds for the printed form, "
                             "where that factor is 1 + k_tau B_tau B_q / I_m ~ 1."))
        klow = np.asarray(low_frequency_stiffness(ideal.sea, model))
        mag_low = np.abs(zb[:, 0])
        inc = bool(np.all(np.diff(klow) > 0) and np.all(np.diff(mag_low) > 0))
        sec.claims.append(Claim(
            f"{sec.id}.higher_fn.{model}", "Fig. impedanceNaturalFreq",
            f"{model}: a higher f_n gives a higher impedance (low-frequency stiffness and |Z| "
            "at 0.1 Hz increase with f_n)", "increasing",
            ", ".join(f"{k:.4g}" for k in klow) + " Nm/rad", "monotonic",
            "pass" if inc else "fail"))
    sec.tables.append(("Deviation from the ideal impedance (RMS of the dB difference over "
                       "0.1-1000 Hz, log grid) and stability with delays + filters",
                       ["model", "f_n [Hz]", "delays [dB]", "filters [dB]",
                        "stable (delays + filters)", "PM [deg]"], rows))
    if not np.all(mb.stable):
        bad = ", ".join(f"{f:g}" for f, s in zip(fn, mb.stable) if not s)
        sec.notes.append(f"With T_qs = 10 ms the cascaded loop is unstable at f_n = {bad} Hz "
                         "(Nyquist, exact delays): those curves are drawn as the paper does, "
                         "but an unstable loop has no physical impedance.")
    return sec


# ------------------------------------------------------------------ Fig. loadinertia
@section(42, "impedance-load")
def load_inertia(ctx: Context) -> Section:
    from seactl.apps.plots import impedance_bode_figure

    sec = Section("impedance-load", "Fig. loadinertia: impedance with three load inertias",
                  intro="f_n = 20 Hz (gains designed for the UT-SEA joint inertia), "
                        "b_j = 0.1 Nms/rad, load inertias I_j = "
                        + ", ".join(f"{x:g}" for x in LOAD_INERTIAS) + " kg m^2, "
                        "Z_l = Z + I_j s + b_j. Assumptions (the caption gives neither): the "
                        "three inertias (UT-SEA I_j, 4x and 16x) and the delays/filters "
                        "(T_qd = T_tau = 1 ms, T_qs = 10 ms, f_qd = 50 Hz, f_taud = 100 Hz, "
                        "as in Fig. impedanceNaturalFreq). Spike = largest rise of |Z_l| above "
                        "the envelope of its asymptotes.")
    _gain_claims(sec, 20, "Fig. loadinertia")
    d = _design(20.0, **NATFREQ_DELAYS, **FILTERS).sea   # load inertias: no public keyword
    ij = np.array(LOAD_INERTIAS)
    rows = []
    for model in MODELS:
        r = impedance(d, F_HZ, model=model, load_inertia=ij, load_damping=0.1)
        a = asymptotes(d, F_HZ, model=model, load_inertia=ij, load_damping=0.1)
        spike = excess_over_asymptotes_db(r, a).max(axis=-1)
        curves = []
        for k, (x, c) in enumerate(zip(ij, COLORS)):
            curves.append(dict(f=F_HZ, z=r.z[k], color=c, label=f"I_j = {x:g} kg m^2"))
            curves.append(dict(f=F_HZ, z=a.high[k], color=c, dashed=True,
                               label="I_j jw + b_j" if k == 0 else None))
        curves.append(dict(f=F_HZ, z=a.low[0], color="k", dashed=True,
                           label="low-freq. asymptote K/(jw)"))
        fig = impedance_bode_figure([("Z_l = Z + I_j s + b_j", curves)],
                                    suptitle=f"f_n = 20 Hz, {MODEL_TEXT[model]}", col_width=8)
        sec.figures.append(Figure(ctx.savefig(fig, f"impedance_load_{model}.png"),
                                  f"Fig. loadinertia regenerated with the {MODEL_TEXT[model]}; "
                                  "dashed: asymptotes."))
        dec = bool(np.all(np.diff(spike) < 0))
        sec.claims.append(Claim(
            f"{sec.id}.spike.{model}", "Fig. loadinertia",
            f"{model}: the larger the load inertia, the smaller the spike", "decreasing",
            ", ".join(f"{s:.2f}" for s in spike) + " dB", "monotonic",
            "pass" if dec else "fail"))
        zh = impedance(d, F_HIGH, model=model, load_inertia=ij, load_damping=0.1).z[:, 0]
        ah = ij * 2j * np.pi * F_HIGH[0] + 0.1
        sec.claims.append(numeric_claim(
            f"{sec.id}.high.{model}", "Fig. loadinertia",
            f"{model}: Z_l -> I_j jw + b_j at high frequency: max |Z_l/(I_j jw + b_j) - 1| at "
            "1e5 Hz", 0.0, float(np.max(np.abs(zh / ah - 1))), 1e-3))
        rows += [[model, f"{x:g}", f"{s:.2f}"] for x, s in zip(ij, spike)]
    sec.tables.append(("Spike above the asymptote envelope", ["model", "I_j [kg m^2]",
                                                              "spike [dB]"], rows))
    return sec


# ------------------------------------------------------------------ delay sets
@section(43, "impedance-delay-sets")
def delay_sets(ctx: Context) -> Section:
    from seactl.apps.plots import impedance_bode_figure

    sec = Section("impedance-delay-sets",
                  "The reference MATLAB's four delay sets at f_n = 30 Hz",
                  intro="No filters (assumption), GS = 1. Passivity is scanned over "
                        "0.1-1000 Hz (Re Z < 0: the actuator can inject energy).")
    base = _design(30.0)
    ds = [(lbl, _design(30.0, **_delays(tt, ts, td))) for lbl, tt, ts, td in DELAY_SETS]
    cols = []
    rows = []
    for model in MODELS:
        curves = [dict(f=F_HZ, z=_z(d, model), label=lbl, color=c)
                  for (lbl, d), c in zip(ds, COLORS)]
        curves.append(dict(f=F_HZ, z=_spring(), dashed=True, color="goldenrod", label="k/(jw)"))
        cols.append((MODEL_TEXT[model].split(" (")[0], curves))
    fig = impedance_bode_figure(cols, suptitle="f_n = 30 Hz, four delay sets")
    sec.figures.append(Figure(ctx.savefig(fig, "impedance_delay_sets.png"),
                              " | ".join(f"{side}: {MODEL_TEXT[m]}" for side, m in
                                         zip(("left", "right"), MODELS)) + "."))
    for lbl, d in ds:
        m = d.margins()
        for model in MODELS:
            p = passivity(d.sea, (0.1, 1000.0), model=model)
            b = p.bands_hz[()]
            rows.append([lbl, model, "yes" if m.stable else "NO",
                         pm_cell(float(m.phase_margin_deg), bool(m.stable)),
                         "yes" if p.passive else "no",
                         ", ".join(f"{x:.3g}-{y:.3g}" for x, y in b[:4])
                         + (" ..." if len(b) > 4 else "") or "none"])
    sec.tables.append(("Stability (cascaded loop) and passivity per delay set",
                       ["delays", "model", "stable", "PM [deg]", "passive 0.1-1000 Hz",
                        "non-passive bands [Hz]"], rows))
    recur = []
    for lbl, d in ds[1:]:
        above = [b for b in passivity(d.sea, (0.1, 10_000.0)).bands_hz[()] if b[1] > 1000.0]
        recur.append(f"{lbl}: {len(above)} bands between 1 and 10 kHz")
    sec.notes.append("The table's bands are those of the 0.1-1000 Hz scan. Without filters "
                     "they recur above it: the same scan to 10 kHz finds " + "; ".join(recur)
                     + " (the delays make Re Z periodic in frequency).")
    ideal_p = passivity(ds[0][1].sea, (0.1, 1000.0)).passive
    sec.claims.append(Claim(
        f"{sec.id}.delays_break_passivity", "Impedance analysis",
        "block diagram: the delay-free design is passive over 0.1-1000 Hz, every delayed set "
        "is not",
        "finding", f"ideal passive: {bool(ideal_p)}; delayed passive: "
        + ", ".join(str(bool(passivity(d.sea, (0.1, 1000.0)).passive)) for _, d in ds[1:]),
        "", "info"))
    _passivity_causes(sec, base, ds[1:])
    return sec


def _passivity_causes(sec: Section, base: Design, delayed: list) -> None:
    """Which cause applies to which delay set: low-frequency non-passivity needs
    ``K_q T_qs > B_q`` (``Re Z(0) ~ B_q - K_q T_qs`` plus small ``b_m``, ``T_tau`` and
    ``T_qd`` terms); otherwise the non-passive bands lie at high frequency."""
    kq, bq = float(base.gains.Kq), float(base.gains.Bq)
    causes, where = [], {}
    for lbl, d in delayed:
        bands = passivity(d.sea, (0.1, 1000.0)).bands_hz[()]
        low = any(a < 1.0 for a, _ in bands)
        span = ", ".join(f"{a:.3g}-{b:.3g}" for a, b in bands)
        t_qs = float(d.timing.T_qs)
        where[lbl] = "low frequency" if low else "high frequency only"
        causes.append(f"{lbl}: K_q T_qs = {kq * t_qs:.2f} {'>' if kq * t_qs > bq else '<'} "
                      f"B_q = {bq:.2f}, non-passive at {span} Hz")
    sec.claims.append(Claim(
        f"{sec.id}.passivity_cause", "Impedance analysis",
        "the stiffness delay makes the SEA non-passive at low frequency only when "
        "K_q T_qs > B_q; the other delayed sets are non-passive at high frequency only",
        "finding", where, "", "info", "Per delay set: " + "; ".join(causes) + "."))
    low = {}
    for t_ms in (8.0, 9.0):
        d = _design(30.0, t_qs_ms=t_ms)
        low[t_ms] = not any(a < 1.0 for a, _ in passivity(d.sea, (0.1, 1000.0)).bands_hz[()])
    ok = low[8.0] and not low[9.0]
    sec.claims.append(Claim(
        f"{sec.id}.low_freq_threshold", "Impedance analysis",
        f"f_n = 30 Hz, no other delay: passive at low frequency with T_qs = 8 ms, not with "
        f"9 ms (threshold B_q / K_q = {1e3 * bq / kq:.2f} ms)", "8 ms yes, 9 ms no",
        f"8 ms {'yes' if low[8.0] else 'no'}, 9 ms {'yes' if low[9.0] else 'no'}", "",
        "pass" if ok else "fail"))


# ------------------------------------------------------------------ k_tau vs beta
@section(44, "impedance-ktau")
def ktau_finding(ctx: Context) -> Section:
    from seactl.apps.plots import impedance_bode_figure

    sec = Section("impedance-ktau",
                  "Finding: the printed impedance formula uses k_tau where its block diagram "
                  "has beta",
                  intro="docs/theory/ktau-beta.md. The printed N_zi/D_zi equal the block "
                        "diagram's impedance only after replacing k_tau by beta. With k_tau "
                        f"= {UT_SEA.motor_torque_constant} N m/A (rotary; 1.104 N/A linear) "
                        f"and beta = {UT_SEA.beta:.4g} N m/A (208.1 N/A linear) the printed "
                        "low-frequency stiffness is about a quarter of K_q, while the block "
                        "diagram's is exactly K_q, consistent with P_CL(0) = 1.")
    fn = np.array([12.0, 20.0, 30.0])
    timings = [{}, _delays(1.0, 10.0, 3.0), FILTERS, TABLE_I_TIMING]
    err = 0.0
    for t in timings:
        d = _design(fn, **t)
        zb = d.impedance(F_HZ).z
        zp = _z(d, "paper", k_tau=UT_SEA.beta)
        err = max(err, float(np.max(np.abs(zp / zb - 1))))
    sec.claims.append(numeric_claim(
        f"{sec.id}.equal_with_beta", "Impedance transfer function",
        "printed N_zi/D_zi with k_tau := beta equal the block diagram (max relative difference "
        "over f_n = 12/20/30 Hz, four timing sets, 0.1-1000 Hz)", 0.0, err, 1e-9))
    d30 = _design(30.0)
    kp = float(low_frequency_stiffness(d30.sea, "paper"))
    sec.claims.append(numeric_claim(
        f"{sec.id}.low_paper", "Impedance transfer function",
        "printed form: low-frequency stiffness at f_n = 30 Hz [Nm/rad] "
        "(docs/theory/ktau-beta.md: 72.9)",
        72.9, kp, 0.05))
    kb = float(d30.impedance(F_LOW).stiffness[0].real)
    sec.claims.append(numeric_claim(
        f"{sec.id}.low_block", "Impedance transfer function",
        "block diagram: low-frequency stiffness at f_n = 30 Hz equals K_q = 293.6 Nm/rad",
        293.6, kb, 0.05))
    pcl0 = complex(closed_loop()(d30.sea, np.array([1e-9j]))[0])
    sec.claims.append(numeric_claim(
        f"{sec.id}.pcl0", "Impedance transfer function",
        "P_CL(0) = 1 (static tracking), consistent with a static stiffness of exactly K_q",
        1.0, abs(pcl0), 1e-6))
    sec.claims.append(Claim(
        f"{sec.id}.finding", "Impedance transfer function",
        "the paper's Z(s) is consistent with its own block diagram", "yes (implied)",
        f"no: printed form gives {kp:.1f} Nm/rad static stiffness vs K_q = {kb:.1f} Nm/rad; "
        f"they agree only with k_tau replaced by beta (max rel. diff. {err:.1e})", "",
        "info", "a finding, not a pass/fail check: the published curves use the printed form; "
                "seactl defaults to the block diagram and offers --model paper"))
    cols = []
    for title, t in (("ideal", {}), ("T_qs=10, T_qd=3, T_tau=1 ms", _delays(1.0, 10.0, 3.0))):
        d = _design(30.0, **t)
        cols.append((f"f_n = 30 Hz, {title}", [
            dict(f=F_HZ, z=_z(d, "block-diagram"), color="tab:blue",
                 label="block diagram"),
            dict(f=F_HZ, z=_z(d, "paper"), color="tab:red", label="printed, k_tau"),
            dict(f=F_HZ, z=_z(d, "paper", k_tau=UT_SEA.beta), color="k", dashed=True,
                 label="printed, k_tau := beta"),
            dict(f=F_HZ, z=_spring(), dashed=True, color="goldenrod", label="k/(jw)")]))
    fig = impedance_bode_figure(cols, suptitle="Printed formula vs block diagram")
    sec.figures.append(Figure(ctx.savefig(fig, "impedance_ktau.png"),
                              "The printed formula with k_tau := beta (black dashed) lies on the "
                              "block diagram (blue); with k_tau (red) it is softer at low "
                              "frequency by the factor k_tau (1/beta + K_tau)/(1 + K_tau k_tau)."))
    return sec


# ------------------------------------------------------------------ Z-region
ZR_FN = np.arange(10.0, 40.01, 2.0)
ZR_GS = np.round(np.arange(0.5, 2.001, 0.1), 10)
ZR_F = np.logspace(-1, 3, 201)


@section(45, "zregion")
def zregion_section(ctx: Context) -> Section:
    from seactl.apps.plots import zregion_figure

    sec = Section("zregion", "Z-region: Z-width and Z-depth over an f_n x GS range",
                  intro="This project's definition (docs/zregion.md; the original is not "
                        "public). Designs: f_n = 10-40 Hz (step 2), GS = 0.5-2 (step 0.1), "
                        "Table I timing (T_tau = T_qd = 0.5 ms, T_qs = 2 ms, f_qd = 50 Hz, "
                        "f_taud = 100 Hz), block-diagram model. Admissible: stable with phase "
                        "margin >= 30 deg. Z-width = 20 log10(max |Z| / min |Z|) over the "
                        "admissible designs; Z-depth = band from 0.1 Hz where the width stays "
                        ">= 6 dB.")
    designs = design(ZR_FN[:, None], gs=ZR_GS[None, :], **design_keywords(**TABLE_I_TIMING))
    g, d = designs.gains, designs.sea   # the Z-region has no public view
    reg = zregion(d, ZR_F, min_pm_deg=30.0, threshold_db=6.0)
    fig = zregion_figure(reg, ZR_FN, ZR_GS, spring=UT_SEA.k / (2j * np.pi * ZR_F))
    sec.figures.append(Figure(ctx.savefig(fig, "zregion.png"),
                              "Left: |Z| of every admissible design (grey) and the envelope; "
                              "middle: Z-width and Z-depth; right: phase margin over the "
                              "design range, crosses = not admissible."))
    kq = np.asarray(g.Kq)[reg.admissible]
    expected = 20 * np.log10(kq.max() / kq.min())
    reg_low = zregion(d, np.array([1e-3]), min_pm_deg=30.0)
    sec.claims.append(numeric_claim(
        "zregion.width_low", "Z-region",
        "Z-width at low frequency = 20 log10(max K_q / min K_q) over the admissible designs "
        "[dB] (value at 1e-3 Hz)", float(expected), float(reg_low.width_db[0]), 0.01))
    reg_hi = zregion(d, np.array([1e5]), min_pm_deg=30.0)
    sec.claims.append(numeric_claim(
        "zregion.width_high", "Z-region",
        "with filters every design tends to the spring k/(jw): Z-width -> 0 dB (at 1e5 Hz)",
        0.0, float(reg_hi.width_db[0]), 0.05))
    depth = (f"{reg.depth_hz[0]:.3g}-{reg.depth_hz[1]:.4g} Hz ({reg.depth_decades:.3f} decades)"
             if reg.depth_hz else "empty")
    sec.claims.append(Claim("zregion.depth", "Z-region",
                            "Z-depth (width >= 6 dB), PM >= 30 deg", "not in the paper",
                            depth, "", "info"))
    n_pas = int((reg.passive & reg.admissible).sum())
    sec.claims.append(Claim("zregion.passive", "Z-region",
                            "admissible designs that are also passive over 0.1-1000 Hz",
                            "not in the paper", f"{n_pas} of {reg.n_admissible}", "", "info",
                            "with a 2 ms stiffness delay Re Z < 0 at low frequency "
                            "(-K_q sin(w T_qs)/w), so requiring passivity empties the set"
                            if n_pas == 0 else ""))
    sec.tables.append(("Z-width at selected frequencies", ["f [Hz]", "min |Z|", "max |Z|",
                                                           "width [dB]"],
                       [[f"{ZR_F[k]:.3g}", f"{reg.z_min[k]:.4g}", f"{reg.z_max[k]:.4g}",
                         f"{reg.width_db[k]:.2f}"] for k in range(0, ZR_F.size, 25)]))
    return sec
