"""``seactl robot --impedance / --task-step / --task-impulse``: a robot's task impedance,
certified passivity and task-space responses (tables or JSON)."""

from __future__ import annotations

import dataclasses
from typing import Any

from rich.markup import escape
from rich.table import Table

from seactl.errors import InputError

from .common import console, echo_json, finite_or_none


def _numbers(option: str, text: str, count: int | None, what: str) -> list[float]:
    """Comma-separated finite numbers: ``count`` of them, not all 0 (a direction), or
    else (``count`` None) all > 0 (frequencies)."""
    import math

    try:
        x = [float(v) for v in text.split(",")]
    except ValueError:
        x = []
    ok = bool(x) and all(math.isfinite(v) for v in x) and (
        any(v != 0 for v in x) and len(x) == count if count else all(v > 0 for v in x))
    if not ok:
        raise InputError(option, text, what)
    return x


def task_views(r: Any, impedance: str | None, step: str | None, impulse: str | None,
               as_json: bool) -> None:
    """Print (or echo as JSON) the views asked for, through the public API."""
    out: dict[str, Any] = {}
    if impedance is not None:
        f = _numbers("--impedance [Hz]", impedance, None,
                     "frequencies > 0 [Hz], comma-separated, e.g. 1,10,100")
        z = r.task_impedance(f)
        p = r.passivity()
        out["impedance"] = {"space": z.space, "unit": z.unit, "rows": z.records()}
        out["passivity"] = {k: finite_or_none(v) if isinstance(v, float) else v
                            for k, v in p.records()[0].items()}
    for kind, text in (("step", step), ("impulse", impulse)):
        if text is None:
            continue
        d = _numbers(f"--task-{kind}", text, 3, "a direction X,Y,Z, not all 0, e.g. 1,0,0")
        res = r.task_step(d) if kind == "step" else r.task_impulse(d)
        m = {f.name: finite_or_none(getattr(res.metrics, f.name))
             for f in dataclasses.fields(res.metrics)
             if f.name not in ("left_bounds_s", "stable", "band")}
        out[f"task_{kind}"] = {"direction": res.direction.tolist(),
                               "amplitude": res.amplitude,
                               "amplitude_unit": res.amplitude_unit,
                               "stable": res.stable, "metrics": m,
                               "final_along_m": float(res.along_m[-1])}
    if as_json:
        echo_json(out)
        return
    _print(out)


def _print(out: dict[str, Any]) -> None:
    if "impedance" in out:
        imp = out["impedance"]
        keys = [k for k in imp["rows"][0] if k.startswith("principal_")]
        t = Table(title=f"{imp['space']} impedance, principal values [{imp['unit']}]")
        for col in ["f [Hz]"] + [k.replace("_", " ") for k in keys] + ["min eig of Herm. part"]:
            t.add_column(escape(col))
        for row in imp["rows"]:
            t.add_row(f"{row['f_hz']:.4g}", *(f"{row[k]:.4g}" for k in keys),
                      f"{row['hermitian_min']:.4g}")
        console.print(t)
        p = out["passivity"]
        verdict = ("passive" if p["passive"] else
                   "[red]not passive[/red]" if p["proven"] else "[red]not proven[/red]")
        neg = p["negative_f_hz"]
        console.print(f"joint impedance on {p['f_min_hz']:g}-{p['f_max_hz']:g} Hz: {verdict}"
                      + ("" if neg is None else f" (negative at {neg:.4g} Hz)")
                      + f"; smallest eigenvalue {p['hermitian_min']:.4g} N m s/rad at "
                        f"{p['worst_f_hz']:.4g} Hz")
    for kind in ("step", "impulse"):
        if f"task_{kind}" not in out:
            continue
        r = out[f"task_{kind}"]
        m = r["metrics"]
        g = {k: "none" if v is None else format(v, ".4g") for k, v in m.items()}
        text = (f"rise {g['rise_time_s']} s, overshoot {g['overshoot_pct']} %, settling "
                f"{g['settling_time_s']} s" if kind == "step" else
                f"peak {g['peak_deviation']} m at {g['peak_time_s']} s, recovery "
                f"{g['recovery_time_s']} s")
        console.print(f"task {kind} {r['amplitude']:g} {r['amplitude_unit']} along "
                      f"{r['direction']}: {'stable' if r['stable'] else '[red]UNSTABLE[/red]'}"
                      f"; {text}; final {1e3 * r['final_along_m']:.4g} mm")
