"""``seactl roots``: rightmost closed-loop roots of SEA designs, with exact delays."""

from __future__ import annotations

from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from ._common import DesignSpec, cli, console, design_options, echo_json, json_option


def roots_rows(spec: DesignSpec, count: int) -> list[dict[str, Any]]:
    """One record per design and valid gain solution: ``fn_hz``, ``gs``,
    ``spectral_abscissa`` [1/s], ``roots`` ``[{"re", "im", "radius", "count"}, ...]``
    [rad/s], ``clusters``, ``complete``, ``stable``, ``uncertain`` and
    ``right_half_plane_roots`` (:meth:`seactl.api.RootsResult.records`)."""
    from ..api import Design

    rows = []
    for design in spec.all_designs():
        fn, gs = np.broadcast_arrays(spec.fn_hz[:, None], spec.gs[None, :])
        rows += Design(design, fn, gs).roots(count=count).records()
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


@cli.command()
@design_options
@click.option("--count", type=click.IntRange(1, 50), default=6, show_default=True,
              help="Roots per design (a conjugate pair counts once).")
@json_option
def roots(spec: DesignSpec, count: int, as_json: bool) -> None:
    """Rightmost closed-loop roots [rad/s] with exact delays, and the spectral abscissa.

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
    """
    rows = roots_rows(spec, count)
    if as_json:
        echo_json({"designs": rows})
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
    if not all(r["complete"] for r in rows):
        console.print("incomplete: the discretizations did not agree, or the argument "
                      "principle counted roots the list does not hold; 'stable' is the "
                      "certified count of right-half-plane roots either way.", highlight=False)
