"""``seactl roots``: rightmost closed-loop roots of SEA designs, with exact delays."""

from __future__ import annotations

from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from .common import (
    DesignSpec,
    cli,
    console,
    design_options,
    echo_json,
    json_option,
    rate_option,
    verdict_text,
)
from .dde import dde_option
from .loops import loop_options


def roots_rows(spec: DesignSpec, count: int) -> list[dict[str, Any]]:
    """One record per design and valid gain solution: ``fn_hz``, ``gs``,
    ``spectral_abscissa`` [1/s], ``roots`` ``[{"re", "im", "radius", "count"}, ...]``
    [rad/s], ``clusters``, ``complete``, ``stable``, ``uncertain`` and
    ``right_half_plane_roots`` (:meth:`seactl.api.sea.RootsResult.records`)."""
    rows = []
    for d in spec.all_designs():
        rows += d.roots(count=count).records()
    return rows


def _root_text(z: dict[str, Any]) -> str:
    re_, im = z["re"], z["im"]
    text = f"{re_:.4g}" if im == 0 else f"{re_:.4g} ± {im:.4g}j"
    return f"[red]{escape(text)}[/red]" if re_ > 0 else escape(text)


def _cluster_text(c: dict[str, Any]) -> str:
    text = (f"cluster of {c['count']} within {c['radius']:.3g} of "
            + _root_text(c) + f" (re {c['re_min']:.4g} to {c['re_max']:.4g})")
    return f"[yellow]{text}[/yellow]" if c["re_max"] >= 0 else text


def _roots_text(r: dict[str, Any]) -> str:
    """Simple roots one by one; the roots of a cluster as its disc, once."""
    parts = [_root_text(z) for z in r["roots"] if z["count"] <= 1]
    return ", ".join([_cluster_text(c) for c in r["clusters"]] + parts)


def _verdict_text(r: dict[str, Any]) -> str:
    if r["uncertain"]:
        return "[yellow]uncertain[/yellow]"
    return "yes" if r["stable"] else "[red]NO[/red]"


def sampled_root_rows(spec: DesignSpec, count: int, rate_hz: float) -> list[dict[str, Any]]:
    """Per design, the sampled loop's ``count`` largest z-plane roots (one tick of
    ``1/rate_hz``): ``z`` ``{"re", "im"}``, ``abs``, the equivalent ``s = ln(z)/T``
    ``{"re", "im"}`` [rad/s], with the certified ``verdict`` and ``unstable_modes``."""
    from seactl.systems.sea.views import sea_sampled_roots

    rows = []
    for d in spec.all_designs():
        # the public Design.roots() has no sampled form (rate_hz) yet: the core call
        r = sea_sampled_roots(d.sea, rate_hz)
        z = r.z.reshape(-1, r.z.shape[-1])
        s = r.s.reshape(z.shape)
        for i, (f, g) in enumerate((f, g) for f in spec.fn_hz for g in spec.gs):
            keep = [j for j in range(z.shape[1]) if z[i, j].imag >= 0][:count]
            rows.append({"fn_hz": float(f), "gs": float(g), "rate_hz": rate_hz,
                         "period_s": r.period_s,
                         "verdict": str(r.verdict.flat[i]),
                         "unstable_modes": int(r.unstable_modes.flat[i]),
                         "roots": [{"z": {"re": float(z[i, j].real), "im": float(z[i, j].imag)},
                                    "abs": float(abs(z[i, j])),
                                    "s_rad_per_s": {"re": float(s[i, j].real),
                                                    "im": float(s[i, j].imag)}}
                                   for j in keep]})
    return rows


def _z_text(z: dict[str, Any]) -> str:
    re_, im = z["z"]["re"], z["z"]["im"]
    text = f"{re_:.4g}" if im == 0 else f"{re_:.4g} ± {im:.4g}j"
    text += f" (|z| {z['abs']:.6f})"
    return f"[red]{escape(text)}[/red]" if z["abs"] > 1 else escape(text)


@cli.command()
@design_options
@click.option("--count", type=click.IntRange(1, 50), default=6, show_default=True,
              help="Roots per design (a conjugate pair counts once).")
@rate_option
@json_option
@dde_option
@loop_options
def roots(spec: DesignSpec, count: int, rate_hz: float | None, as_json: bool,
          loop: Any, dde: Any) -> None:
    """Rightmost closed-loop roots [rad/s] with exact delays, and the spectral abscissa.

    Python: sc.design(...).roots(count=...).

    \b
    Example (a design the phase margin alone calls safe):
      seactl roots --fn 15.93 --gs 1.867 --t-tau 1.99 --t-qs 1.96 --t-qd 18.54

    Roots come from a Chebyshev collocation of the delay equation, each polished by
    Newton on the exact characteristic equation; the argument principle confirms that
    none lies to the right of those listed (a list it cannot confirm is marked
    incomplete), and counts the right-half-plane roots behind "stable".  Sorted by
    decreasing real part; a conjugate pair is listed once (im >= 0).  A positive real
    part is an unstable root.  Each root's error bound is a disc that the argument
    principle shows to hold it (JSON: "radius" [rad/s] and "count", the roots in the
    disc); roots that gather in one disc (a multiple root) are shown as that cluster,
    with its count and the interval of its real parts.  'uncertain': no verdict, as a
    cluster's interval reaches across the imaginary axis or a root lies on it.

    With --rate, also the sampled loop's roots: the eigenvalues z of its one-tick map
    (largest |z| first; |z| > 1 grows), with the equivalent s = ln(z)/T [rad/s] in JSON
    ("sampled": [{"rate_hz", "period_s", "verdict", "unstable_modes", "roots": [{"z",
    "abs", "s_rad_per_s"}]}]); the verdict is certified (docs/theory/sampled.md).

    With --loop FILE, the roots of the loop file's whole diagram (every break closed),
    as sc.load_loop(FILE).roots(count=) gives them (JSON: "loop", "file", "designs").

    With --dde FILE, the roots of a delay equation or quasi-polynomial file
    (docs/delay-equations.md), as sc.load_dde(FILE).roots(count=) gives them; --set
    NAME=VALUE sets a named delay [s] (JSON: "kind", "title", "file", "loops": the delay
    names, "designs").
    """
    if dde is not None:
        return _dde_roots(dde, count, as_json)
    if loop is not None:
        return _loop_roots(loop, count, as_json)
    rows = roots_rows(spec, count)
    srows = sampled_root_rows(spec, count, rate_hz) if rate_hz is not None else None
    if as_json:
        echo_json({"designs": rows} | ({"sampled": srows} if srows is not None else {}))
        return
    t = Table(title=f"Rightmost closed-loop roots \\[rad/s], actuator '{spec.actuator.name}' "
              f"(T_tau={spec.t_tau_ms:g} ms, T_qs={spec.t_qs_ms:g} ms, T_qd={spec.t_qd_ms:g} ms,"
              f" f_qd={spec.f_qd_hz or 'none'} Hz, f_taud={spec.f_taud_hz or 'none'} Hz)")
    for col in ("f_n [Hz]", "GS", "abscissa [1/s]", "stable", "roots"):
        t.add_column(escape(col), justify="left" if col == "roots" else "right")
    for r in rows:
        a = r["spectral_abscissa"]
        t.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", "none" if a is None else f"{a:.4g}",
                  _verdict_text(r), _roots_text(r)
                  + ("" if r["complete"] else " [yellow](incomplete: roots may be missing)"
                     "[/yellow]"))
    console.print(t)
    if srows is not None:
        ts = Table(title=f"Sampled loop at {rate_hz:g} Hz: roots z of its one-tick map "
                   "(|z| > 1 grows; s = ln(z)/T in --json)")
        for col in ("f_n [Hz]", "GS", "verdict", "roots z"):
            ts.add_column(escape(col), justify="left" if col == "roots z" else "right")
        for r in srows:
            ts.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", verdict_text(r["verdict"]),
                       ", ".join(_z_text(z) for z in r["roots"]))
        console.print(ts)
    if not all(r["complete"] for r in rows):
        console.print("incomplete: the discretizations did not agree, or the argument "
                      "principle counted roots the list does not hold; 'stable' is the "
                      "certified count of right-half-plane roots either way.", highlight=False)


def _loop_roots(loop: Any, count: int, as_json: bool) -> None:
    """``seactl roots --loop``: :meth:`seactl.UserLoop.roots`, one row per design."""
    rows = loop.roots(count=count).records()
    if as_json:
        echo_json({"loop": loop.name, "file": loop.file, "designs": rows})
        return
    varied = list(loop.label_columns())
    t = Table(title=escape(f"Rightmost closed-loop roots [rad/s] of loop '{loop.name}' "
                           f"({loop.file})"))
    for col in (*varied, "abscissa [1/s]", "stable", "roots"):
        t.add_column(escape(col), justify="left" if col == "roots" else "right")
    for r in rows:
        a = r["spectral_abscissa"]
        t.add_row(*[f"{r[k]:g}" for k in varied], "none" if a is None else f"{a:.4g}",
                  _verdict_text(r), _roots_text(r)
                  + ("" if r["complete"] else " [yellow](incomplete: roots may be missing)"
                     "[/yellow]"))
    console.print(t)


def _dde_roots(system: Any, count: int, as_json: bool) -> None:
    """``seactl roots --dde``: :meth:`seactl.DelaySystem.roots`, one row per design."""
    rows = system.roots(count=count).records()
    if as_json:
        echo_json({"kind": system.kind, "title": system.title, "file": system.file,
                   "loops": list(system.loops), "designs": rows})
        return
    cols = list(system.label_columns())
    title = f" '{system.title}'" if system.title else ""
    t = Table(title=escape(f"Rightmost roots [rad/s] of the {system.kind}{title} "
                           f"({system.file})"))
    for col in cols:
        t.add_column(escape(f"{col[:-2]} [s]"), justify="right")
    for col in ("abscissa [1/s]", "stable", "RHP roots", "roots"):
        t.add_column(escape(col), justify="left" if col == "roots" else "right")
    for r in rows:
        a, n = r["spectral_abscissa"], r["right_half_plane_roots"]
        t.add_row(*[f"{r[k]:g}" for k in cols], "none" if a is None else f"{a:.4g}",
                  _verdict_text(r), "?" if n is None else str(n), _roots_text(r)
                  + ("" if r["complete"] else " [yellow](incomplete: roots may be missing)"
                     "[/yellow]"))
    console.print(t)
