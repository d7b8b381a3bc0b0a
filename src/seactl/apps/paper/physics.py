"""Section: from analysis to a physics engine.  The SEA test bed as a MuJoCo model
(:mod:`seactl.codegen.mjcf`) closed in one process around seactl's sampled controller
(:func:`seactl.codegen.mujoco_plant.simulate_mujoco`: no processes, deterministic): its
step on either side of the predicted delay margin against the rightmost characteristic
root, and its step against the band of sampled responses that ``monte_carlo`` predicts
for a latency distribution.  Without MuJoCo (the ``sim`` extra) the section says so."""

from __future__ import annotations

import numpy as np

from seactl.apps.report import Claim, Context, Figure, Section, section

MARGIN_FN_HZ = 20.0
FILTERS_HZ = (50.0, 100.0)
FACTORS = (0.8, 1.2)                # outer-loop delays in multiples of the delay margin
MARGIN_RATE_HZ = 5000.0
MARGIN_T_END_S = 0.6
MARGIN_STEP_RAD = 1e-3
BAND_FN_HZ = 14.0
BAND_DELAYS_MS = {"torque": 1.0, "stiffness": 2.0, "damping": 1.0}
BAND_STEP_RAD = 0.01
BAND_T_END_S = 0.3
BAND_RUNS = 50
BAND_LATENCY_MS = {"inside": (1.0, 3.0), "outside": (4.0, 6.0)}   # stiffness, uniform
STEP_LATENCY_MS = (1.0, 3.0)        # the MuJoCo step's own stiffness latency, uniform
STEP_SEED = 1                       # its realization (the bands draw from seed 0)
TITLE = "From analysis to a physics engine"
CLAIMS = {
    "physics.margin_below": "At 0.8 x the predicted delay margin the MuJoCo step's error "
                            "decays, at the rate of the rightmost characteristic root",
    "physics.margin_above": "At 1.2 x the predicted delay margin the MuJoCo step's error "
                            "grows, at the rate of the rightmost characteristic root",
    "physics.band_inside": "A MuJoCo step whose stiffness latency varies uniformly in 1-3 "
                           "ms lies in the band monte_carlo predicts for that distribution",
    "physics.band_outside": "The same MuJoCo step leaves the band predicted for a "
                            "stiffness latency uniform in 4-6 ms",
}


def _envelope(x: float, dm_ms: float):
    """The MuJoCo step of the design whose stiffness and damping delays are ``x`` times
    ``dm_ms``: (t [s], |error| / step, growth rate of the error's envelope [1/s], the
    rightmost root's real part [1/s])."""
    import seactl as sc
    from seactl.codegen.mujoco_plant import simulate_mujoco
    from seactl.simulate.inputs import Step

    d = sc.design(MARGIN_FN_HZ, delays_ms={"stiffness": x * dm_ms, "damping": x * dm_ms},
                  filters_hz=FILTERS_HZ)
    run = simulate_mujoco(d.diagram_for(), d.design, {"q_des": Step(MARGIN_STEP_RAD)},
                          MARGIN_T_END_S, outputs=("q_j",), rates_hz=MARGIN_RATE_HZ,
                          saturation=d.saturation(), substeps=2)
    e = np.abs(run.outputs["q_j"] / MARGIN_STEP_RAD - 1)
    w1, w2 = (run.t_s >= 0.2) & (run.t_s < 0.4), run.t_s >= 0.4
    rate = float(np.log(e[w2].max() / e[w1].max()) / 0.2)
    return run.t_s, e, rate, float(d.roots().spectral_abscissa)


def _timing(d):
    """One realization (seed :data:`STEP_SEED`) of the stiffness latency
    :data:`STEP_LATENCY_MS` for the MuJoCo step."""
    from seactl.latency.models import Uniform
    from seactl.latency.montecarlo import LinkTiming

    block = next(b for b in d.diagram_for().blocks if b.name == d.links["stiffness"])
    lat = Uniform(STEP_LATENCY_MS[0] * 1e-3, STEP_LATENCY_MS[1] * 1e-3)
    return LinkTiming({"stiffness": block}, {"stiffness": lat}, {}, 1, STEP_SEED)


def _band(latency_ms: tuple[float, float], run, d):
    """The band of :data:`BAND_RUNS` sampled steps for a uniform stiffness latency and
    the verdict on the MuJoCo step ``run``: (lo, hi, BandVerdict)."""
    from seactl.latency.band import compare_band
    from seactl.latency.models import Uniform
    from seactl.latency.montecarlo import timed_simulation
    from seactl.simulate.inputs import Step

    lat = {"stiffness": Uniform(latency_ms[0] * 1e-3, latency_ms[1] * 1e-3)}
    res = timed_simulation(d.diagram_for(), d.design, {"q_des": Step(BAND_STEP_RAD)},
                           BAND_T_END_S, latency=lat, runs=BAND_RUNS, seed=0, links=d.links,
                           rates_hz=1000.0, saturation=d.saturation(), outputs=("q_j",),
                           bound=1e3 * BAND_STEP_RAD)
    y = np.reshape(res.outputs["q_j"], (BAND_RUNS, -1)) / BAND_STEP_RAD
    y = np.array([np.interp(run.t_s, res.t_s, r) for r in y])
    lo, hi = y.min(axis=0), y.max(axis=0)
    return lo, hi, compare_band(run.t_s, run.outputs["q_j"] / BAND_STEP_RAD, lo, hi,
                                BAND_RUNS)


def _figure(ctx: Context, run, bands, margins) -> Figure:
    from seactl.apps.plots import pyplot

    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 3.4))
    t_ms = run.t_s * 1e3
    for (name, (lo, hi, _)), color in zip(bands.items(), ("tab:green", "tab:red")):
        a, b = BAND_LATENCY_MS[name]
        ax.fill_between(t_ms, lo, hi, color=color, alpha=0.3,
                        label=f"band, stiffness latency {a:g}-{b:g} ms")
    ax.plot(t_ms, run.outputs["q_j"] / BAND_STEP_RAD, "k", lw=1.2,
            label="MuJoCo step, stiffness latency 1-3 ms")
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("q_j / step")
    ax.legend(fontsize=8)
    for x, (t_s, e, _, sigma) in margins.items():
        line, = bx.semilogy(t_s * 1e3, e + 1e-16, lw=1, label=f"MuJoCo, {x:g} x margin")
        i = np.argmax(t_s >= 0.2)
        bx.semilogy(t_s[i:] * 1e3, e[i:].max() * np.exp(sigma * (t_s[i:] - t_s[i])), "--",
                    color=line.get_color(), lw=1, label=f"exp({sigma:.3g} t), rightmost root")
    bx.set_xlabel("t [ms]")
    bx.set_ylabel("|q_j / step - 1|")
    bx.legend(fontsize=7)
    name = ctx.savefig(fig, "physics_engine.png")
    return Figure(name, "Left: the MuJoCo SEA test bed's step (f_n = 14 Hz, 1 kHz, the "
                        "stiffness latency drawn uniformly in 1-3 ms per message) in the "
                        "bands of 50 sampled steps for two stiffness latency "
                        "distributions. Right: its step error at f_n = 20 Hz with the outer "
                        "loops' delays at 0.8 and 1.2 x the predicted delay margin (5 kHz), "
                        "against the growth of the rightmost characteristic root.")


def _skipped(reason: str) -> Section:
    sec = Section("physics-engine", TITLE, intro=(
        "This section needs MuJoCo, which is not installed here: install seactl with "
        "its sim extra (pip install '.[sim]') and run seactl reproduce again. " + reason))
    for cid, text in CLAIMS.items():
        sec.claims.append(Claim(cid, "physics-engine", text, None, None, None, "skip",
                                "not computed: MuJoCo is not installed (pip install "
                                "'.[sim]')"))
    return sec


@section(79, "physics-engine")
def physics_engine(ctx: Context) -> Section:
    import seactl as sc
    from seactl.codegen.mujoco_plant import import_mujoco, simulate_mujoco
    from seactl.errors import InputError
    from seactl.simulate.inputs import Step

    try:
        import_mujoco()
    except InputError as exc:
        return _skipped(str(exc.valid).split(": ", 1)[-1])
    dm_ms = float(sc.design(MARGIN_FN_HZ, filters_hz=FILTERS_HZ).margins().delay_margin_ms)
    margins = {x: _envelope(x, dm_ms) for x in FACTORS}
    d = sc.design(BAND_FN_HZ, delays_ms=BAND_DELAYS_MS, filters_hz=FILTERS_HZ)
    run = simulate_mujoco(d.diagram_for(), d.design, {"q_des": Step(BAND_STEP_RAD)},
                          BAND_T_END_S, outputs=("q_j",), rates_hz=1000.0,
                          saturation=d.saturation(), substeps=10, timing=_timing(d))
    bands = {name: _band(lat, run, d) for name, lat in BAND_LATENCY_MS.items()}
    sec = Section("physics-engine", TITLE, intro=(
        "The SEA test bed generated as a MuJoCo model from the actuator's parameters (rotor "
        "and joint as bodies coupled by a spring, damping, the current limit; "
        "docs/mujoco.md) is closed around seactl's own sampled controller in one process, "
        "so the runs are deterministic. Two predictions of the continuous analysis are "
        f"put to it. The delay margin: the design of f_n = {MARGIN_FN_HZ:g} Hz without "
        f"delays has a delay margin of {dm_ms:.3f} ms; with its stiffness and damping "
        "delays at 0.8 and 1.2 times that, the step's error in MuJoCo decays or grows, "
        "and the rate is the real part of the rightmost characteristic root. The band: "
        "a MuJoCo step whose stiffness latency is drawn per message from a distribution "
        "(uniform in 1-3 ms, one realization) lies in the band of the sampled steps "
        "`monte_carlo` draws for that distribution, and not in the band of another."))
    sec.tables.append((
        "MuJoCo step on either side of the predicted delay margin (error envelope's growth "
        "rate from 0.2-0.4 s to 0.4-0.6 s)",
        ["outer-loop delays [ms]", "x margin", "envelope rate [1/s]",
         "rightmost root real part [1/s]"],
        [[f"{x * dm_ms:.3f}", f"{x:g}", f"{m[2]:.3g}", f"{m[3]:.3g}"]
         for x, m in margins.items()]))
    sec.tables.append((
        f"MuJoCo step (f_n = {BAND_FN_HZ:g} Hz, delays 1/x/1 ms, 1 kHz; stiffness latency x "
        f"uniform in 1-3 ms) against the band of {BAND_RUNS} sampled steps",
        ["band's stiffness latency [ms]", "band max width [of the step]", "verdict"],
        [[f"uniform {BAND_LATENCY_MS[n][0]:g}-{BAND_LATENCY_MS[n][1]:g}",
          f"{v.max_width:.3g}", v.verdict] for n, (_, _, v) in bands.items()]))
    sec.figures.append(_figure(ctx, run, bands, margins))
    for x, cid in zip(FACTORS, ("physics.margin_below", "physics.margin_above")):
        rate, sigma = margins[x][2], margins[x][3]
        sec.claims.append(Claim(cid, "physics-engine", CLAIMS[cid], None,
                                round(rate, 2), None, "info",
                                f"envelope rate {rate:.3g} 1/s; rightmost root's real part "
                                f"{sigma:.3g} 1/s"))
    for name in BAND_LATENCY_MS:
        cid, v = f"physics.band_{name}", bands[name][2]
        sec.claims.append(Claim(cid, "physics-engine", CLAIMS[cid], None, bool(v.within),
                                None, "info", v.verdict))
    return sec
