"""What the explorer shows for a loop file, as pure functions of its controls (no Bokeh).

A loop file (TOML, ``docs/loops.md``) is loaded with :func:`seactl.load_loop`; its
``[variables]`` become sliders and every view is a call of the :class:`seactl.UserLoop`
API at the slider values, as ``seactl analyze --loop FILE --set NAME=VALUE`` and
``seactl step --loop ...`` compute them: margins at every break (``margins()``), Bode
and Nyquist of the outermost break (``loop_transfer``), the first port's impedance
(``impedance``), the rightmost roots (``roots``), step and impulse (continuous, or
sampled at the file's process rates) and the jitter margins (``jitter_margins``).
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

import seactl as sc
from seactl.errors import InputError, LoopFileError, SeactlError

from .model import (
    MAX_UPLOAD_BYTES,
    MODES,
    PASSIVITY_RANGE_HZ,
    num_text,
    roots_views,
    run_stages,
    sampled_words,
)

RECORD_DT_S = 5e-4
"""Recording interval of a continuous loop response: the one ``seactl step --loop``
uses, so that the metrics are the command line's."""
BODE_POINTS = 700
PASSIVITY_POINTS_PER_DECADE = 200
SLIDER_STEPS = 50
"""A variable's slider moves by ``|value| / SLIDER_STEPS`` from ``value / 10`` to
``10 value`` (a decade each way): the file's value is on the grid (45 steps from the
start)."""


@dataclass(frozen=True)
class LoopControls:
    """A loop file at slider values: the loaded loop, the name the command line gives its
    file, the variables' values (only those moved off the file's) and the mode."""

    loop: Any
    file_name: str
    values: tuple[tuple[str, float], ...] = ()
    mode: str = "continuous"

    def system(self) -> sc.UserLoop:
        """The loop at these values (:meth:`seactl.UserLoop.with_values` validates them)."""
        if self.mode not in MODES:
            raise InputError("mode", self.mode, " or ".join(MODES))
        return self.loop.with_values(**dict(self.values)) if self.values else self.loop


def loop_from_upload(filename: str, content: bytes) -> tuple[sc.UserLoop, str]:
    """An uploaded loop file, validated by :func:`seactl.load_loop`.

    Returns
    -------
    (UserLoop, str)
        The loop and its file name (as the copied command line names it).

    Raises
    ------
    InputError
        Too large, or the loader's :class:`~seactl.errors.LoopFileError` (not TOML, an
        unknown block kind, a missing signal ...: the message names the field).
    """
    name = Path(str(filename or "loop.toml")).name
    if len(content) > MAX_UPLOAD_BYTES:
        raise InputError("loop file", name, f"at most {MAX_UPLOAD_BYTES // 1024} kB")
    stem = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in Path(name).stem)
    name = f"{stem or 'loop'}.toml"
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / name
        path.write_bytes(content)
        try:
            loop = sc.load_loop(path)
        except SeactlError as exc:  # name the user's file, not the temporary copy
            raise SeactlError(str(exc).replace(str(path), name) + _hint(content)) from None
    return check_loop(sc.UserLoop(replace(loop.compiled, file=name))), name


def _hint(content: bytes) -> str:
    """A hint for an actuator or design file given to the loop file control."""
    import tomllib

    try:
        data = tomllib.loads(content.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        return ""
    if "blocks" not in data and ("actuator" in data or "motor_inertia" in data):
        return " (this is an actuator or design file: upload it beside 'actuator')"
    return ""


def check_loop(loop: sc.UserLoop) -> sc.UserLoop:
    """``loop``, if the page can show it: it needs a break (the margins and the loop
    views are taken at breaks).

    Raises
    ------
    LoopFileError
        The file declares no ``[[breaks]]``.
    """
    if not loop.breaks:
        raise LoopFileError(loop.file, "[[breaks]]", None, "at least one break: the "
                            "explorer shows the loop's margins at its breaks")
    return loop


def variable_sliders(loop: sc.UserLoop) -> dict[str, tuple[float, float, float, float]]:
    """Variable -> ``(start, end, step, value)`` of its slider (see :data:`SLIDER_STEPS`)."""
    out = {}
    for name, value in loop.compiled.model.variables.items():
        v = float(value)
        if v == 0.0:
            out[name] = (0.0, 1.0, 0.01, 0.0)
            continue
        lo, hi = sorted((v / 10.0, 10.0 * v))
        out[name] = (lo, hi, abs(v) / SLIDER_STEPS, v)
    return out


def t_end_s(spectral_abscissa_per_s: float | None) -> float:
    """The responses' window: eight time constants of the slowest closed-loop root,
    0.1 s to 1 s (0.5 s, the API's default, for a loop that does not decay or before the
    roots are known); three significant digits (as the command line writes it)."""
    sa = spectral_abscissa_per_s
    if sa is None or not sa < 0:
        return 0.5
    return float(f"{float(np.clip(8.0 / -sa, 0.1, 1.0)):.3g}")


def command_line(c: LoopControls, t_end: float) -> str:
    """``seactl analyze`` and ``seactl step`` on the loop file with the moved variables
    (``--set``), the page's amplitude, window and mode (sampled: the file's rates)."""
    sets = "".join(f" --set {k}={v:.10g}" for k, v in c.values)
    head = f"--loop {c.file_name}{sets}"
    amp = c.loop.default_step
    mode = " --mode sampled" if c.mode == "sampled" else ""
    return (f"seactl analyze {head}\n"
            f"seactl step {head} --amplitude {amp:.10g} --t-end {t_end:.10g}{mode}")


# ------------------------------------------------------------------ views
def _one(x: Any) -> float | None:
    v = float(np.reshape(x, -1)[0])
    return v if math.isfinite(v) else None


def frequencies_hz(loop: sc.UserLoop, n: int = BODE_POINTS) -> np.ndarray:
    """The Bode grid: the range of the margin scan (:meth:`seactl.UserLoop.grid`)."""
    om = loop.grid()
    return np.geomspace(om[0] / (2 * np.pi), om[-1] / (2 * np.pi), n)


def bode_views(loop: sc.UserLoop, outer: str) -> dict[str, Any]:
    """Bode and Nyquist of the loop broken at its outermost break (exact delays)."""
    f = frequencies_hz(loop)
    L = np.reshape(loop.loop_transfer(outer)(loop.design, 2j * np.pi * f), -1)
    phase = np.degrees(np.unwrap(np.angle(L)))
    phase -= 360.0 * np.ceil((phase[0] - 90.0) / 360.0)  # lowest frequency in (-270, 90]
    near = np.abs(L) <= 20.0
    re, im = np.where(near, L.real, np.nan), np.where(near, L.imag, np.nan)
    return {"bode": {"f_hz": f, "mag_db": 20 * np.log10(np.abs(L)), "phase_deg": phase},
            "nyquist": {"re": np.concatenate([re, [np.nan], re[::-1]]),
                        "im": np.concatenate([im, [np.nan], -im[::-1]])}}


def impedance_views(loop: sc.UserLoop) -> dict[str, Any]:
    """|Z| at the first port, and where ``Re Z < 0`` on a dense scan from 0.01 Hz to
    10 kHz (``passive`` None without a port).  A point with ``Re Z < 0`` proves "not
    passive"; "passive" is the scan's (not certified between its points)."""
    empty = {"impedance": {"f_hz": [], "block_diagram": [], "paper": []},
             "bands": {"left": [], "right": []}, "passive": None, "port": None}
    if not loop.ports:
        return empty
    lo, hi = PASSIVITY_RANGE_HZ
    f = np.geomspace(lo, hi, int(PASSIVITY_POINTS_PER_DECADE * math.log10(hi / lo)) + 1)
    res = loop.impedance(f)
    z = np.reshape(res.z, -1)
    neg = z.real < -1e-9 * np.abs(z)
    edges = np.flatnonzero(np.diff(np.r_[0, neg.astype(int), 0]))
    starts, ends = edges[::2], edges[1::2] - 1
    return {"impedance": {"f_hz": f, "block_diagram": np.abs(z), "paper": np.full(f.size, np.nan)},
            "bands": {"left": f[starts], "right": f[ends]},
            "passive": not bool(neg.any()), "port": res.port}


def margin_results(c: LoopControls, loop: sc.UserLoop, a: Any, passive: Any
                   ) -> dict[str, Any]:
    """Margins at every break (the rows ``seactl analyze --loop --json`` prints), the
    outermost break's under the SEA page's keys, the whole loop's stability."""
    breaks = []
    for b in a.breaks:
        m = b.margins
        breaks.append({"break": b.name, "signal": b.signal,
                       "phase_margin_deg": _one(m.phase_margin_deg),
                       "crossover_hz": _one(m.crossover_hz),
                       "gain_margin_db": _one(m.gain_margin_db),
                       "phase_crossover_hz": _one(m.phase_crossover_hz),
                       "delay_margin_ms": _one(m.delay_margin_ms)})
    outer = breaks[-1]
    return {"kind": "loop", "loop": loop.name, "file": c.file_name, "mode": c.mode,
            "values": {k: float(np.reshape(v, -1)[0]) for k, v in loop.environment().items()
                       if k in loop.compiled.model.variables},
            "breaks": breaks, "outer_break": outer["break"],
            **{k: outer[k] for k in ("phase_margin_deg", "crossover_hz", "gain_margin_db",
                                     "phase_crossover_hz", "delay_margin_ms")},
            "stable": bool(np.reshape(a.stable, -1)[0]), "passive": passive}


def fast_views(c: LoopControls, acc: dict[str, Any] | None = None) -> dict[str, Any]:
    """Stage 1: margins at every break, Bode, Nyquist, impedance."""
    loop = c.system()
    a = loop.margins()
    out: dict[str, Any] = {"design": loop, **bode_views(loop, list(loop.breaks)[-1]),
                           **impedance_views(loop)}
    out["bands_array"] = np.column_stack([out["bands"]["left"], out["bands"]["right"]])
    r = margin_results(c, loop, a, out["passive"])
    r["port"] = out["port"]
    r["t_end_s"] = t_end_s(None)
    r["verdict"] = verdict(r)
    out["results"] = r
    out["exports"] = exports(c, r)
    return out


def exports(c: LoopControls, r: dict[str, Any]) -> dict[str, str]:
    """The JSON of the page (TOML: the loop file itself) and the command line."""
    import json

    from seactl.api.results import json_value

    cmd = command_line(c, r["t_end_s"])
    doc = {"loop": r["loop"], "file": c.file_name, "set": dict(c.values),
           "results": {k: json_value(v) if isinstance(v, float) else v
                       for k, v in r.items()}, "command": cmd.splitlines()}
    return {"toml": "", "json": json.dumps(doc, indent=2, default=str), "command": cmd}


def _with_results(c: LoopControls, acc: dict[str, Any], extra: dict[str, Any]
                  ) -> dict[str, Any]:
    r = {**acc["results"], **extra}
    r["verdict"] = verdict(r)
    return {"results": r, "exports": exports(c, r)}


def roots_stage(c: LoopControls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 2: the rightmost roots of the whole loop."""
    out = roots_views(acc["design"])
    n = out["roots_numbers"]
    return {**out, **_with_results(c, acc, {**n, "t_end_s": t_end_s(
        n["spectral_abscissa_per_s"])})}


def response_stage(c: LoopControls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 3: step (normalized) and impulse (if the file declares a disturbance), as
    ``seactl step --loop`` runs them (same window, recording interval, mode)."""
    loop = acc["design"]
    t_end = acc["results"]["t_end_s"]
    kw = {"t_end_s": t_end, "mode": c.mode,
          "record_dt": RECORD_DT_S if c.mode == "continuous" else None}
    st = loop.step(**kw)
    sm = st.metrics
    extra: dict[str, Any] = {
        "step_amplitude": float(st.amplitude), "step_unit": loop.step_unit,
        "step_verdict": st.verdict().verdict[0],
        "step_rise_ms": _ms(sm.rise_time_s), "step_overshoot_pct": _one(sm.overshoot_pct),
        "step_settling_ms": _ms(sm.settling_time_s)}
    info = st.info or {}
    if "sampled_verdict" in info:
        extra.update(sampled_verdict=str(np.ravel(info["sampled_verdict"])[0]),
                     sampled_unstable_modes=int(np.ravel(info["sampled_unstable_modes"])[0]),
                     sampled_rate=info["sampled_rate"])
    out: dict[str, Any] = {"step": {"t_ms": st.t_s * 1e3, "y": np.reshape(st.position, -1)}}
    if loop.compiled.model.signals.disturbance is not None:
        im = loop.impulse(**kw)
        out["impulse"] = {"t_ms": im.t_s * 1e3, "y": np.reshape(im.position, -1)}
        extra["impulse_peak"] = _one(im.metrics.peak_deviation)
    else:
        out["impulse"] = {"t_ms": [], "y": []}
    return {**out, **_with_results(c, acc, extra)}


def robustness_stage(c: LoopControls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 4: the jitter margin at every break (:meth:`seactl.UserLoop.jitter_margins`)."""
    j = acc["design"].jitter_margins()
    extra = {f"{name}_jitter_margin_ms": _ms(v) for name, v in
             j.break_jitter_margins_s.items()}
    return _with_results(c, acc, extra)


def _ms(x: Any) -> float | None:
    v = _one(x)
    return None if v is None else v * 1e3


STAGES = (fast_views, roots_stage, response_stage, robustness_stage)
STAGE_NAMES = ("margins and loop views", "roots", "responses", "jitter margins")


def views(c: LoopControls) -> dict[str, Any]:
    """Everything the page shows for the loop controls ``c``: the stages, merged."""
    return run_stages(STAGES, c)


def verdict(r: dict[str, Any]) -> str:
    """The loop's results in words (sentences for the keys ``r`` has so far)."""
    words = [f"Loop '{r['loop']}': {'stable' if r['stable'] else 'UNSTABLE'} in "
             "continuous time (every break closed, exact delays)."]
    for b in r["breaks"]:
        jit = r.get(f"{b['break']}_jitter_margin_ms", "...")
        words.append(f"Break '{b['break']}': PM {num_text(b['phase_margin_deg'], '.1f', ' deg')} "
                     f"at {num_text(b['crossover_hz'], '.3g', ' Hz')}, delay margin "
                     f"{num_text(b['delay_margin_ms'], '.3g', ' ms')}"
                     + ("" if jit == "..." else f", jitter margin {num_text(jit, '.3g', ' ms')}")
                     + ".")
    words += sampled_words(r)
    if r.get("step_overshoot_pct") is not None:
        words.append(f"Step of {r['step_amplitude']:g} {r['step_unit']}: "
                     f"{r['step_overshoot_pct']:.1f} % overshoot, settles (2 %) in "
                     f"{num_text(r['step_settling_ms'], '.0f', ' ms')}; verdict "
                     f"{r['step_verdict']}.")
    if r["passive"] is None:
        words.append("No [[ports]] in the file: no impedance view.")
    elif r["passive"]:
        words.append("Z(jw) at the first port: Re Z >= 0 at every point of the scan from "
                     "0.01 Hz to 10 kHz (a scan, not a proof).")
    else:
        words.append("Z(jw) at the first port is not passive (Re Z < 0 in the shaded bands).")
    return " ".join(words)
