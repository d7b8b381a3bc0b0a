"""What the explorer shows, as pure functions of the control values (no Bokeh here).

:func:`views` turns a :class:`Controls` into plain arrays and text for every view of the
page; the Bokeh callbacks only copy them into the page.  Every number comes from the
public API (:func:`seactl.design` and its ``margins``, ``to_control("frd")``,
``impedance``, ``step``, ``impulse``; :func:`seactl.loop_model` for the per-loop delay
margins, ``passivity`` for the non-passive bands, as ``seactl impedance`` reports them);
nothing is modelled twice.  The two maps are design batches of the same
API on a coarse grid, cached (:func:`pm_map`, :func:`latency_map`) so that a change of a
control recomputes only the map it moves.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from dataclasses import asdict, dataclass, field, fields, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

import seactl as sc
from seactl.errors import InputError, SeactlError
from seactl.systems.sea.actuators import SEA_PRESETS

# ------------------------------------------------------------------ controls and bounds
BOUNDS: dict[str, tuple[float, float, float]] = {
    "fn_hz": (9.5, 50.0, 0.1),
    "gs": (0.2, 5.0, 0.05),
    "zeta1": (0.3, 2.0, 0.05),
    "zeta2": (0.3, 2.0, 0.05),
    "ratio": (0.25, 4.0, 0.05),
    "t_tau_ms": (0.0, 20.0, 0.1),
    "t_qs_ms": (0.0, 20.0, 0.1),
    "t_qd_ms": (0.0, 20.0, 0.1),
    "f_qd_hz": (5.0, 1000.0, 1.0),
    "f_taud_hz": (5.0, 1000.0, 1.0),
    "rate_hz": (100.0, 10000.0, 50.0),
}
"""Slider ranges ``(start, end, step)``: inside what the CLI accepts (the library
validates every value again); ``fn_hz`` starts at the actuator's feasible bound."""

MODES = ("continuous", "sampled")
MAX_UPLOAD_BYTES = 64 * 1024
F_BODE_HZ = np.geomspace(0.1, 2000.0, 700)
"""Frequencies of the Bode, Nyquist and impedance views [Hz]."""
PASSIVITY_RANGE_HZ = (0.01, 1e4)
PM_MAP_GS = np.geomspace(0.2, 5.0, 13)
PM_MAP_N_FN = 15
LAT_MAP_MS = np.linspace(0.0, 20.0, 11)
ROOTS_COUNT = 6
"""Rightmost roots shown (a conjugate pair counts once): enough to see the dominant modes
while the slider stays responsive (``seactl bench`` times the explorer's views)."""
PM_THIN_DEG, PM_COMFORTABLE_DEG = 30.0, 60.0


@dataclass(frozen=True)
class Controls:
    """The value of every control of the page (CLI units: ms, Hz).

    ``f_qd_hz`` / ``f_taud_hz`` are ``None`` for no filter.  The default is the design
    of Table I at ``f_n = 14 Hz``.
    """

    actuator: Any = field(default_factory=lambda: sc.UT_SEA)
    fn_hz: float = 14.0
    gs: float = 1.0
    zeta1: float = 1.0
    zeta2: float = 1.0
    ratio: float = 1.0
    t_tau_ms: float = 0.5
    t_qs_ms: float = 2.0
    t_qd_ms: float = 0.5
    f_qd_hz: float | None = 50.0
    f_taud_hz: float | None = 100.0
    mode: str = "continuous"
    rate_hz: float = 1000.0

    def design(self) -> sc.Design:
        """The design these controls describe (:func:`seactl.design` validates them)."""
        if self.mode not in MODES:
            raise InputError("mode", self.mode, " or ".join(MODES))
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise InputError("rate [Hz]", self.rate_hz, "a finite rate > 0")
        return sc.design(self.fn_hz, actuator=self.actuator, gs=self.gs, zeta1=self.zeta1,
                         zeta2=self.zeta2, ratio=self.ratio,
                         delays_ms={"torque": self.t_tau_ms, "stiffness": self.t_qs_ms,
                                    "damping": self.t_qd_ms},
                         filters_hz=(self.f_qd_hz, self.f_taud_hz))

    def loop_key(self) -> tuple:
        """Everything but ``f_n``, GS and the simulation mode (the PM map's key)."""
        return (self.actuator, self.zeta1, self.zeta2, self.ratio, self.t_tau_ms,
                self.t_qs_ms, self.t_qd_ms, self.f_qd_hz, self.f_taud_hz)


def fn_range_hz(c: Controls) -> tuple[float, float]:
    """The f_n slider's range: the actuator's feasible bound (rounded up) to 50 Hz."""
    return _fn_range(c.actuator, c.zeta1, c.zeta2, c.ratio)


@lru_cache(maxsize=64)
def _fn_range(actuator: Any, zeta1: float, zeta2: float, ratio: float) -> tuple[float, float]:
    ranges = sc.feasible_fn_range(actuator, zeta1=zeta1, zeta2=zeta2, ratio=ratio)
    lo, hi = ranges[0] if ranges else BOUNDS["fn_hz"][:2]
    start = math.ceil(lo * 10.0 + 1e-9) / 10.0
    return start, float(max(min(hi, 200.0, max(BOUNDS["fn_hz"][1], 3 * start)), start + 1.0))


# ------------------------------------------------------------------ uploads
def actuator_from_upload(filename: str, content: bytes) -> tuple[Any, dict[str, Any]]:
    """An uploaded TOML file: an actuator (as ``--actuator FILE``) or a design exported
    by the explorer (``[actuator]`` and ``[design]`` tables).

    Returns
    -------
    (SEAParams, dict)
        The validated actuator and the control values of a ``[design]`` table (empty
        for an actuator file).

    Raises
    ------
    InputError
        Too large, not UTF-8, not TOML, unknown key or value out of range (the
        library's own message, as ``--actuator FILE`` prints it).
    """
    import tomllib

    name = Path(str(filename or "uploaded.toml")).name
    if len(content) > MAX_UPLOAD_BYTES:
        raise InputError("actuator file", name, f"at most {MAX_UPLOAD_BYTES // 1024} kB")
    try:
        data = tomllib.loads(content.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError("actuator file", name, f"a UTF-8 TOML file ({exc})") from None
    if "blocks" in data:
        raise InputError("actuator file", name, "an actuator or an exported design; this "
                         "is a loop file ([[blocks]]): load it with the loop file control")
    has_design = isinstance(data.get("design"), dict)
    design = data.pop("design") if has_design else {}
    design.pop("actuator", None)
    table = data.get("actuator") if isinstance(data.get("actuator"), dict) else data
    with tempfile.TemporaryDirectory() as tmp:
        stem = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in Path(name).stem)
        path = Path(tmp) / f"{stem or 'uploaded'}.toml"
        path.write_bytes(toml_text({"actuator": table}).encode() if has_design else content)
        actuator = sc.load_sea(path)
    known = {f.name for f in fields(Controls)} - {"actuator"}
    unknown = sorted(set(design) - known)
    if unknown:
        raise InputError(f"[design].{unknown[0]}", design[unknown[0]],
                         "one of the known keys (" + ", ".join(sorted(known)) + ")")
    return actuator, design


def controls_from_table(base: Controls, actuator: Any, table: dict[str, Any]) -> Controls:
    """``base`` with the actuator and the values of an uploaded ``[design]`` table."""
    values = {k: (None if v == "none" else v) for k, v in table.items()}
    c = replace(base, actuator=actuator, **values)
    c.design()  # validate now: a bad file is refused as a whole
    return c


# ------------------------------------------------------------------ exports
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if v is None:
        return '"none"'
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def toml_text(tables: dict[str, dict[str, Any]]) -> str:
    """Flat tables of numbers and strings as TOML (what the exports need, no more)."""
    out = []
    for name, table in tables.items():
        out.append(f"[{name}]")
        for k, v in table.items():
            if not isinstance(v, (bool, str, int, float, type(None))):
                raise InputError(f"{name}.{k}", v, "a number or a string")
            out.append(f"{k} = {_toml_value(v)}")
        out.append("")
    return "\n".join(out)


def actuator_option(actuator: Any) -> str:
    """``--actuator`` value: the preset name, or the TOML file the user uploaded."""
    if SEA_PRESETS.get(actuator.name.lower()) == actuator:
        return actuator.name
    return f"{actuator.name}.toml"


def command_line(c: Controls) -> str:
    """The ``seactl gains`` and ``seactl step`` commands that reproduce this design: the
    step with the page's amplitude (:attr:`seactl.Design.default_step`) and window."""
    def num(x: float) -> str:
        return f"{x:.10g}"

    opts = [f"--actuator {actuator_option(c.actuator)}", f"--fn {num(c.fn_hz)}",
            f"--gs {num(c.gs)}"]
    opts += [f"--{k} {num(getattr(c, k))}" for k in ("zeta1", "zeta2", "ratio")
             if getattr(c, k) != 1.0]
    opts += [f"--t-tau {num(c.t_tau_ms)}", f"--t-qs {num(c.t_qs_ms)}",
             f"--t-qd {num(c.t_qd_ms)}"]
    opts += [f"--{k} {num(v)}" for k, v in (("f-qd", c.f_qd_hz), ("f-taud", c.f_taud_hz))
             if v is not None]
    sim = (f" --amplitude {num(sc.Design.default_step)} --t-end {num(t_end_s(c.fn_hz))}"
           + (f" --mode sampled --rate {num(c.rate_hz)}" if c.mode == "sampled" else ""))
    return f"seactl gains {' '.join(opts)}\nseactl step {' '.join(opts)}{sim}"


def controls_table(c: Controls) -> dict[str, Any]:
    """The controls as a flat table (the ``[design]`` of the TOML export)."""
    out = {k: v for k, v in asdict(c).items() if k != "actuator"}
    return {"actuator": actuator_option(c.actuator), **out}


def exports(c: Controls, results: dict[str, Any]) -> dict[str, str]:
    """TOML and JSON of the design (re-uploadable) and the equivalent command line."""
    act = {"name": c.actuator.name, **{k: v for k, v in asdict(c.actuator).items()
                                        if k != "name"}}
    numbers = {k: v for k, v in results.items() if not isinstance(v, str)}
    toml = ("# seactl explore: design (upload it again to restore every control)\n"
            + toml_text({"design": controls_table(c), "actuator": act, "results": numbers}))
    doc = {"design": controls_table(c), "actuator": act, "results": results,
           "command": command_line(c).splitlines()}
    return {"toml": toml, "json": json.dumps(doc, indent=2), "command": command_line(c)}


# ------------------------------------------------------------------ maps (cached)
def _edges(centers: np.ndarray, log: bool = False) -> np.ndarray:
    """Cell edges around sorted centers (geometric means on a log axis)."""
    x = np.log(centers) if log else np.asarray(centers, float)
    mid = 0.5 * (x[1:] + x[:-1])
    e = np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])
    return np.exp(e) if log else e


def _cells(x: np.ndarray, y: np.ndarray, pm: np.ndarray, log_y: bool = False
           ) -> dict[str, np.ndarray]:
    """Quads of a map ``pm[i_x, i_y]``; unstable cells are NaN (drawn grey)."""
    ex, ey = _edges(x), _edges(y, log_y)
    ix, iy = np.meshgrid(np.arange(x.size), np.arange(y.size), indexing="ij")
    return {"left": ex[ix].ravel(), "right": ex[ix + 1].ravel(), "bottom": ey[iy].ravel(),
            "top": ey[iy + 1].ravel(), "x": x[ix].ravel(), "y": y[iy].ravel(),
            "pm": pm.ravel()}


@lru_cache(maxsize=32)
def pm_map(key: tuple) -> dict[str, np.ndarray]:
    """Phase margin over (f_n, GS) for every other control fixed (``Controls.loop_key``);
    NaN where the closed loop is unstable.  One :func:`seactl.design` batch."""
    act, z1, z2, ratio, t_tau, t_qs, t_qd, f_qd, f_taud = key
    lo, hi = _fn_range(act, z1, z2, ratio)
    fn = np.linspace(lo, hi, PM_MAP_N_FN)
    d = sc.design(fn[:, None], actuator=act, gs=PM_MAP_GS[None, :], zeta1=z1, zeta2=z2,
                  ratio=ratio, delays_ms={"torque": t_tau, "stiffness": t_qs,
                                          "damping": t_qd}, filters_hz=(f_qd, f_taud))
    m = d.margins()
    return _cells(fn, PM_MAP_GS, np.where(m.stable, m.phase_margin_deg, np.nan), log_y=True)


@lru_cache(maxsize=32)
def latency_map(key: tuple) -> dict[str, np.ndarray]:
    """Phase margin over (damping delay T_qd across, stiffness delay T_qs up) [ms] of this
    design, everything else fixed; at GS = 1 and zeta = ratio = 1 it is
    :func:`seactl.latency_map`.  One :func:`seactl.design` batch."""
    act, fn, gs, z1, z2, ratio, t_tau, f_qd, f_taud = key
    ms = LAT_MAP_MS
    # broadcast first: sc.design's delays_ms check wants equal shapes inside its tuple
    delays = tuple(np.broadcast_arrays(np.asarray(t_tau, float), ms[:, None], ms[None, :]))
    d = sc.design(fn, actuator=act, gs=gs, zeta1=z1, zeta2=z2, ratio=ratio,
                  delays_ms=dict(zip(("torque", "stiffness", "damping"), delays)),
                  filters_hz=(f_qd, f_taud))
    m = d.margins()  # [i_qs, i_qd] -> transpose to [i_qd (x), i_qs (y)]
    return _cells(ms, ms, np.where(m.stable, m.phase_margin_deg, np.nan).T)


def _latency_key(c: Controls) -> tuple:
    return (c.actuator, c.fn_hz, c.gs, c.zeta1, c.zeta2, c.ratio, c.t_tau_ms, c.f_qd_hz,
            c.f_taud_hz)


# ------------------------------------------------------------------ views
def loop_views(d: sc.Design) -> dict[str, dict[str, np.ndarray]]:
    """Bode and Nyquist of the outer loop ``L`` (exact delays, python-control FRD)."""
    frd = d.to_control("frd", transfer="loop", f_hz=F_BODE_HZ)
    loop = np.asarray(frd.frequency_response(frd.omega).complex).reshape(-1)
    phase = np.degrees(np.unwrap(np.angle(loop)))
    phase -= 360.0 * np.round((phase[0] - np.degrees(np.angle(loop[0]))) / 360.0)
    near = np.abs(loop) <= 20.0  # the Nyquist view shows |L| <= 20 (the -1 point's region)
    re, im = np.where(near, loop.real, np.nan), np.where(near, loop.imag, np.nan)
    return {"bode": {"f_hz": F_BODE_HZ, "mag_db": 20 * np.log10(np.abs(loop)),
                     "phase_deg": phase},
            "nyquist": {"re": np.concatenate([re, [np.nan], re[::-1]]),
                        "im": np.concatenate([im, [np.nan], -im[::-1]])}}


def impedance_views(d: sc.Design) -> dict[str, Any]:
    """|Z(jw)| of both models, the non-passive bands of the block-diagram model and its
    passivity verdict (:meth:`seactl.Design.passivity`: proven where "passive")."""
    bd = d.impedance(F_BODE_HZ)
    paper = d.impedance(F_BODE_HZ, model="paper")
    p = d.passivity(PASSIVITY_RANGE_HZ)
    bands = np.asarray(p.bands_hz[()], float).reshape(-1, 2)
    return {"impedance": {"f_hz": F_BODE_HZ, "block_diagram": bd.magnitude.reshape(-1),
                          "paper": paper.magnitude.reshape(-1)},
            "bands": {"left": bands[:, 0], "right": bands[:, 1]},
            "unit": bd.unit, "passive": bool(np.reshape(p.passive, -1)[0])}


def t_end_s(fn_hz: float) -> float:
    """Simulated time: 1.5 periods of f_n, within [0.08, 0.5] s (a critically-damped
    design settles within about one period), as the command line writes it."""
    return number(float(np.clip(1.5 / fn_hz, 0.08, 0.5)))


def number(x: float) -> float:
    """A value as the command line writes it (10 significant digits) and reads it back,
    so that the page computes what the copied command computes."""
    return float(f"{x:.10g}")


def response_views(d: sc.Design, c: Controls) -> dict[str, Any]:
    """Step (normalized; of :attr:`seactl.Design.default_step`, as ``seactl step``) and
    impulse (q_j in degrees) responses with their metrics."""
    kw = {"t_end_s": t_end_s(c.fn_hz), "mode": c.mode, "rate_hz": c.rate_hz}
    amplitude = type(d).default_step
    st, im = d.step(amplitude=amplitude, **kw), d.impulse(**kw)
    return {"step": {"t_ms": st.t_s * 1e3, "y": np.reshape(st.position, -1)},
            "step_amplitude_rad": amplitude,
            # the current limit acts in sampled mode only: its verdict says if it clips
            "step_verdict": st.verdict().verdict[0] if c.mode == "sampled" else None,
            "impulse": {"t_ms": im.t_s * 1e3, "y": np.degrees(np.reshape(im.position, -1))},
            "step_metrics": st.metrics, "impulse_metrics": im.metrics,
            "requested_delays_ms": {k: float(v) * 1e3 for k, v in st.requested_delays_s.items()},
            "effective_delays_ms": {k: float(v) * 1e3 for k, v in st.effective_delays_s.items()},
            "info": st.result.info}


def _ms(x: Any) -> float | None:
    x = float(x)
    return x * 1e3 if math.isfinite(x) else None


def margin_results(d: sc.Design, loop: Any, bands: np.ndarray, passive: bool
                   ) -> dict[str, Any]:
    """The first half of the results panel: gains and margins of the outer loop, and the
    impedance's passivity verdict."""
    from seactl.api.results import json_value

    rec = loop.records()[0]
    out = {k: rec[k] for k in ("fn_hz", "gs", "Kq", "Bq", "Ktau", "Btau",
                               "phase_margin_deg", "crossover_hz", "gain_margin_db",
                               "delay_margin_ms", "stable")}
    out.update(phase_crossover_hz=json_value(loop.phase_crossover_hz),
               unstable_poles=int(loop.unstable_poles), passive=passive)
    out["verdict"] = verdict(out, bands)
    return out


def response_results(resp: dict[str, Any]) -> dict[str, Any]:
    """The step's and impulse's metrics for the results panel."""
    from seactl.api.results import json_value

    sm, im = resp["step_metrics"], resp["impulse_metrics"]
    info = resp.get("info") or {}
    sampled = {}
    if "sampled_verdict" in info:   # the sampled loop's certified verdict
        sampled = {"sampled_verdict": str(np.ravel(info["sampled_verdict"])[0]),
                   "sampled_unstable_modes": int(np.ravel(info["sampled_unstable_modes"])[0]),
                   "sampled_rate": info["sampled_rate"]}
    return {**sampled,
        "step_amplitude_rad": resp["step_amplitude_rad"],
        **({"step_verdict": resp["step_verdict"]} if resp["step_verdict"] else {}),
        "step_rise_ms": json_value(_ms(sm.rise_time_s) or math.nan),
        "step_overshoot_pct": json_value(sm.overshoot_pct),
        "step_settling_ms": json_value(_ms(sm.settling_time_s) or math.nan),
        "impulse_peak_deg": json_value(np.degrees(im.peak_deviation)),
        "impulse_recovery_ms": json_value(_ms(im.recovery_time_s) or math.nan),
        **{f"{k}_requested_delay_ms": v for k, v in resp["requested_delays_ms"].items()},
        **{f"{k}_effective_delay_ms": v for k, v in resp["effective_delays_ms"].items()},
    }


def robustness_results(d: sc.Design) -> dict[str, Any]:
    """Delay margins of the stiffness and damping loops alone (:func:`seactl.loop_model`,
    the diagram with one tap per loop) and the jitter margins (``d.jitter_margins()``)."""
    from seactl.api.results import json_value

    dm = sc.loop_model("sea", d.actuator).delay_margins(d.sea)
    jm = d.jitter_margins()
    out = {"stiffness_delay_margin_ms": json_value(dm.stiffness_s * 1e3),
           "damping_delay_margin_ms": json_value(dm.damping_s * 1e3)}
    for loop, jitter_s in (("overall", jm.jitter_margin_s),
                           ("stiffness", jm.stiffness_jitter_margin_s),
                           ("damping", jm.damping_jitter_margin_s),
                           ("torque", jm.torque_jitter_margin_s)):
        out[f"{loop}_jitter_margin_ms"] = json_value(np.asarray(jitter_s) * 1e3)
    return out


def sampled_words(r: dict[str, Any]) -> list[str]:
    """The sentence on the sampled loop's verdict, once that stage has computed it."""
    if r.get("sampled_verdict") is None:
        return []
    from seactl.simulate.sampled import sampled_verdict_text

    return ["The loop as simulated: " + sampled_verdict_text(
        bool(r["stable"]), r["sampled_verdict"], r["sampled_unstable_modes"],
        r["sampled_rate"]) + "."]


def num_text(x: Any, fmt: str = ".3g", unit: str = "") -> str:
    return "none" if x is None else f"{x:{fmt}}{unit}"


def verdict(r: dict[str, Any], bands: np.ndarray) -> str:
    """The results in words (sentences for the keys ``r`` has so far)."""
    if not r["stable"]:
        words = [f"Unstable: the closed loop has {r['unstable_poles']} right-half-plane "
                 "pole(s). Lower f_n or GS, or shorten the delays (see the latency map)."]
        if r.get("spectral_abscissa_per_s") is not None:
            words.append(_roots_words(r))
        if r.get("sampled_verdict") is not None:
            from seactl.simulate.sampled import sampled_verdict_text

            words.append("The loop as simulated: " + sampled_verdict_text(
                False, r["sampled_verdict"], r["sampled_unstable_modes"],
                r["sampled_rate"]) + ".")
        return " ".join(words)
    pm = r["phase_margin_deg"]
    grade = ("no gain crossover" if pm is None else "thin" if pm < PM_THIN_DEG
             else "adequate" if pm < PM_COMFORTABLE_DEG else "comfortable")
    words = [f"Stable, {grade} phase margin ({num_text(pm, '.1f', ' deg')} at "
             f"{num_text(r['crossover_hz'], '.3g', ' Hz')}); it tolerates "
             f"{num_text(r['delay_margin_ms'], '.3g', ' ms')} more latency on the whole loop."]
    if "damping_delay_margin_ms" in r:
        ds, dd = r["stiffness_delay_margin_ms"], r["damping_delay_margin_ms"]
        words.append(f"The stiffness loop alone tolerates {num_text(ds, '.3g', ' ms')}, "
                     f"the damping loop alone {num_text(dd, '.3g', ' ms')}.")
        if ds is not None and dd is not None and dd < ds:
            words.append("The damping loop is the latency-critical one: run it on the "
                         "low-latency processor.")
    if "overall_jitter_margin_ms" in r:
        words.append(f"Latency that varies in time is tolerated up to "
                     f"{num_text(r['overall_jitter_margin_ms'], '.3g', ' ms')} on the joint "
                     f"measurement and {num_text(r['torque_jitter_margin_ms'], '.3g', ' ms')} in "
                     "the torque loop (jitter margins, a sufficient bound).")
    if r.get("spectral_abscissa_per_s") is not None:
        words.append(_roots_words(r))
    if r["passive"]:
        words.append("Z(jw) is passive from 0.01 Hz to 10 kHz (proven).")
    elif bands.shape[0] == 0:
        words.append("Z(jw) touches Re Z = 0 between 0.01 Hz and 10 kHz: passivity is not "
                     "proven.")
    else:
        b = ", ".join(f"{lo:.3g}-{hi:.3g} Hz" for lo, hi in bands[:3])
        words.append(f"Z(jw) is not passive in {b}{' ...' if bands.shape[0] > 3 else ''} "
                     "(the actuator can inject energy there).")
    words += sampled_words(r)
    if r.get("step_overshoot_pct") is not None:
        words.append(f"Step of {r['step_amplitude_rad']:g} rad: "
                     f"{r['step_overshoot_pct']:.1f} % overshoot, settles (2 %) in "
                     f"{num_text(r['step_settling_ms'], '.0f', ' ms')}.")
    if r.get("step_verdict") not in (None, "settled"):
        words.append(f"The sampled step's verdict: {r['step_verdict']}"
                     + (" (the motor current is at its limit for much of it)."
                        if r["step_verdict"] == "saturated" else "."))
    words += _lengthened_words(r)
    return " ".join(words)


def _lengthened_words(r: dict[str, Any]) -> list[str]:
    """The delays a sampled response ran with, where whole samples lengthened them."""
    moved = [f"{k} {r[f'{k}_requested_delay_ms']:.3g} -> {r[f'{k}_effective_delay_ms']:.3g} ms"
             for k in ("stiffness", "damping", "torque") if f"{k}_effective_delay_ms" in r
             and abs(r[f"{k}_effective_delay_ms"] - r[f"{k}_requested_delay_ms"]) > 1e-9]
    if not moved:
        return []
    return ["The sampled responses run with whole-sample delays T_s/2 + n T_s, never shorter "
            "than requested: " + ", ".join(moved) + "."]


def _roots_words(r: dict[str, Any]) -> str:
    """The rightmost roots in words: decay rate (or growth) and frequency."""
    sa, f = r["spectral_abscissa_per_s"], r["rightmost_root_hz"]
    if sa < 0:
        how = f"oscillates at {f:.3g} Hz" if f > 0 else "is real (no oscillation)"
        return (f"The rightmost closed-loop root decays at {-sa:.3g} 1/s (time constant "
                f"{1e3 / -sa:.3g} ms) and {how}.")
    return f"A closed-loop root grows at {sa:.3g} 1/s, oscillating at {f:.3g} Hz."


def fast_views(c: Controls, acc: dict[str, Any] | None = None) -> dict[str, Any]:
    """Stage 1 (a few ms): margins, Bode, Nyquist, impedance, first results.

    Raises
    ------
    SeactlError
        A value outside its range, or no feasible gain set (the message says which).
    """
    d = c.design()
    loop = d.margins()
    out: dict[str, Any] = {"design": d, **loop_views(d), **impedance_views(d)}
    out["bands_array"] = np.column_stack([out["bands"]["left"], out["bands"]["right"]])
    out["results"] = margin_results(d, loop, out["bands_array"], out["passive"])
    out["exports"] = exports(c, out["results"])
    return out


def roots_views(d: sc.Design) -> dict[str, Any]:
    """The rightmost roots of the closed loop (``d.roots``, exact delays) in the complex
    plane [rad/s], conjugates mirrored, and the plot's ranges (the imaginary axis kept in
    view)."""
    r = d.roots(count=ROOTS_COUNT)
    z = np.reshape(r.roots, -1)
    z = z[np.isfinite(z)]
    pts = np.concatenate([z, np.conj(z[z.imag > 0])])
    abscissa = float(np.reshape(r.spectral_abscissa, -1)[0])
    lo, hi = min(float(pts.real.min(initial=0.0)), 0.0), max(float(pts.real.max(initial=0.0)), 0.0)
    pad = 0.12 * (hi - lo) or 1.0
    y_max = max(1.15 * float(np.abs(pts.imag).max(initial=0.0)), 0.5 * (hi - lo), 1.0)
    rightmost = z[0] if z.size else complex(math.nan, math.nan)
    return {
        "roots": {"re": pts.real, "im": pts.imag, "f_hz": pts.imag / (2 * np.pi),
                  "zeta": -pts.real / np.maximum(np.abs(pts), 1e-300)},
        "roots_range": {"x": (lo - pad, hi + pad), "y": (-y_max, y_max)},
        "roots_result": r,
        "roots_numbers": {"spectral_abscissa_per_s": abscissa,
                          "rightmost_root_hz": float(abs(rightmost.imag)) / (2 * np.pi),
                          "roots_converged": bool(np.all(r.converged))},
    }


def roots_stage(c: Controls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 2: the rightmost roots and the spectral abscissa."""
    out = roots_views(acc["design"])
    return {**out, **_with_results(c, acc, out["roots_numbers"])}


def _with_results(c: Controls, acc: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    r = {**acc["results"], **extra}
    r["verdict"] = verdict(r, acc["bands_array"])
    return {"results": r, "exports": exports(c, r)}


def response_stage(c: Controls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 3: step and impulse responses and their metrics."""
    resp = response_views(acc["design"], c)
    return {"step": resp["step"], "impulse": resp["impulse"],
            **_with_results(c, acc, response_results(resp))}


def map_stage(c: Controls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 4: the two maps (cached: only the one the change moved is computed)."""
    return {"pm_map": pm_map(c.loop_key()), "latency_map": latency_map(_latency_key(c)),
            **_with_results(c, acc, {})}


def robustness_stage(c: Controls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 5: per-loop delay margins and jitter margins."""
    return _with_results(c, acc, robustness_results(acc["design"]))


STAGES = (fast_views, roots_stage, response_stage, map_stage, robustness_stage)
"""The page updates in these steps, each pushed as soon as it is computed."""
STAGE_NAMES = ("margins and loop views", "roots", "responses", "maps",
               "delay and jitter margins")


def views(c: Controls) -> dict[str, Any]:
    """Everything the page shows for the controls ``c`` (the callbacks' pure core): the
    :data:`STAGES` in order, merged."""
    return run_stages(STAGES, c)


def run_stages(stages: Any, c: Any) -> dict[str, Any]:
    """The results of ``stages`` run in order on the controls ``c`` (each sees what the
    earlier ones computed), merged, with the time they took as ``compute_ms``."""
    t0 = time.perf_counter()
    acc: dict[str, Any] = {}
    for stage in stages:
        acc.update(stage(c, acc))
    acc["compute_ms"] = (time.perf_counter() - t0) * 1e3
    return acc


def safe(func: Any, *args: Any) -> tuple[dict[str, Any] | None, str | None]:
    """``func(*args)``, or ``(None, message)`` for input the library refuses."""
    try:
        return func(*args), None
    except SeactlError as exc:
        return None, str(exc)


def safe_views(c: Controls) -> tuple[dict[str, Any] | None, str | None]:
    """:func:`views`, or ``(None, message)`` for input the library refuses."""
    return safe(views, c)


# ------------------------------------------------------------------ verdict badge
BADGE_COLOURS = {"good": "#1b7f3b", "warn": "#c76b00", "bad": "#b00020", "none": "#666666"}
STEP_WORDS = {"saturated": "warn", "limit cycle": "bad", "unstable": "bad"}
"""A step verdict that overrides "stable" on the badge, and its colour."""


def badges(r: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The verdict badge: ``(id, text, colour key)`` for the loop the page runs and for
    its impedance.

    The first is the library's verdict of that loop: sampled at the chosen rate (the
    certified ``sampled_verdict``) in sampled mode, else the continuous loop's Nyquist
    count (``stable``); a stable loop whose step verdict is ``saturated``, ``limit cycle``
    or ``unstable`` shows that verdict (an uncertain one only the last two).  The second
    is ``passive`` / ``not passive`` (``passive`` None: the loop has no impedance port; a
    loop file's "passive" is its scan's, marked "scanned").
    """
    sampled = r.get("sampled_verdict")
    if sampled is not None:
        word, where = sampled, f"sampled at {r['sampled_rate']}"
    else:
        word, where = ("stable" if r["stable"] else "unstable"), "continuous"
    tone = {"stable": "good", "unstable": "bad"}.get(word, "warn")
    step = r.get("step_verdict")
    if step in STEP_WORDS and word != "unstable" and (word == "stable"
                                                      or STEP_WORDS[step] == "bad"):
        word, tone = step, STEP_WORDS[step]
    passive = r.get("passive")
    scanned = " (scanned)" if r.get("kind") == "loop" else ""
    ptext, ptone = (("no impedance port", "none") if passive is None else
                    (f"passive{scanned}", "good") if passive else ("not passive", "warn"))
    return [("badge-stability", f"{word} ({where})", tone), ("badge-passivity", ptext, ptone)]
