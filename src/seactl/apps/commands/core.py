"""The core commands: ``gains``, ``reproduce`` and ``bench``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from seactl.apps.report_page import summary_line
from seactl.errors import InputError

from .common import (
    SAMPLED_KEYS,
    DesignSpec,
    cli,
    console,
    design_options,
    echo_json,
    json_option,
    pm_text,
    rate_option,
    sampled_callout,
    verdict_text,
)


def gains_rows(spec: DesignSpec, rate_hz: float | None = None) -> list[dict[str, Any]]:
    """Table I rows (rotary units) with margins, one per design and valid solution: the
    public API's :meth:`seactl.MarginsResult.records` of each solution's (f_n x GS) batch,
    plus the closed loop's ``spectral_abscissa`` [1/s] (:meth:`seactl.Design.roots`), and
    with ``rate_hz`` the sampled loop's (:data:`SAMPLED_KEYS` under ``"sampled"``)."""
    rows = []
    for d in spec.all_designs():
        recs = d.margins().records()
        for rec, root in zip(recs, d.roots(count=1).records()):
            rec["spectral_abscissa"] = root["spectral_abscissa"]
        if rate_hz is not None:
            for rec, sm in zip(recs, d.margins(rate_hz=rate_hz).records()):
                rec["sampled"] = {k: sm[k] for k in SAMPLED_KEYS}
        rows += recs
    return rows


def _fmt(x: float | None, spec: str) -> str:
    return "none" if x is None else format(x, spec)


@cli.command()
@design_options
@rate_option
@json_option
def gains(spec: DesignSpec, rate_hz: float | None, as_json: bool) -> None:
    """Critically-damped gains (Table I units) with phase, gain and delay margins.

    Python: sc.design(...).margins() (abscissa: .roots(count=1); --rate: .margins(rate_hz=...)).

    \b
    Example (the paper's Table I):
      seactl gains --fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100

    A margin printed as 'none' (null in JSON) means the loop has no such crossing:
    no gain crossover (phase and delay margin), or no phase crossover (gain margin;
    every phase crossover with a gain margin within +-234 dB is resolved, and without
    delays every one).
    An unstable design's PM is marked '(unstable)' (JSON keeps the number and
    "stable": false).  'abscissa' is the largest real part of the closed-loop roots
    [1/s]: negative when stable, and then the slowest decay rate.

    With --rate, the loop sampled at that rate too (JSON "sampled": rate_hz, verdict,
    unstable_modes, phase_margin_deg, crossover_hz, gain_margin_db, phase_crossover_hz,
    delay_margin_ms, delay_margin_samples): its verdict is certified on the loop's
    one-tick map (docs/theory/sampled.md); its margins come from the discrete frequency
    response up to Nyquist; its delay margin is the extra delay the phase margin allows,
    and delay_margin_samples the whole extra samples.
    """
    rows = gains_rows(spec, rate_hz)
    if as_json:
        echo_json(rows)
        return
    t = Table(title=f"Critically-damped gains, actuator '{spec.actuator.name}' "
              f"(T_tau={spec.t_tau_ms:g} ms, T_qs={spec.t_qs_ms:g} ms, T_qd={spec.t_qd_ms:g} ms,"
              f" f_qd={spec.f_qd_hz or 'none'} Hz, f_taud={spec.f_taud_hz or 'none'} Hz)")
    cols = ["f_n [Hz]", "GS", "Kq [Nm/rad]", "Bq [Nms/rad]", "Ktau [A/Nm]", "Btau [As/Nm]",
            "PM [deg]", "crossover [Hz]", "GM [dB]", "DM [ms]", "abscissa [1/s]", "stable"]
    if rate_hz is not None:
        cols += ["sPM [deg]", "sGM [dB]", "sDM [ms]", "sampled"]
    for col in cols:
        t.add_column(escape(col), justify="right")
    for r in rows:
        cells = [f"{r['fn_hz']:g}", f"{r['gs']:g}", f"{r['Kq']:.2f}", f"{r['Bq']:.3f}",
                 f"{r['Ktau']:.3f}", f"{r['Btau']:.4f}",
                 pm_text(r["phase_margin_deg"], r["stable"]),
                 _fmt(r["crossover_hz"], ".2f"), _fmt(r["gain_margin_db"], ".2f"),
                 _fmt(r["delay_margin_ms"], ".3f"), _fmt(r["spectral_abscissa"], ".2f"),
                 "yes" if r["stable"] else "[red]NO[/red]"]
        if rate_hz is not None:
            sm = r["sampled"]
            cells += [pm_text(sm["phase_margin_deg"], sm["verdict"] == "stable"),
                      _fmt(sm["gain_margin_db"], ".2f"), _fmt(sm["delay_margin_ms"], ".3f"),
                      verdict_text(sm["verdict"])]
        t.add_row(*cells)
    console.print(t)
    if rate_hz is not None:
        console.print(f"sPM, sGM, sDM, sampled: the loop sampled at {rate_hz:g} Hz (verdict "
                      "certified; sDM is the extra delay its phase margins allow).",
                      highlight=False)
        for line in sampled_callout(rows):
            console.print(escape(line), highlight=False)


@cli.command()
@click.option("--out", "out", default="seactl-report", show_default=True,
              type=click.Path(file_okay=False), help="Report directory.")
@click.option("--only", multiple=True, help="Only the named section(s) (ids).")
@click.option("--jobs", type=click.IntRange(1, 64), default=None,
              help="Worker processes for the sections [default: one per core].")
def reproduce(out: str, only: tuple[str, ...], jobs: int | None) -> None:
    """Regenerate every table, figure and numeric claim of the paper into a report.

    Ends with the claims in words: reproduced, do not hold as printed (the report says
    why), findings, and apart those not computed here (claims.json keeps the status
    pass / fail / info / skip).  Exits 0 when the
    report was written, whatever the claims' verdicts.

    Python: seactl.apps.paper.reproduce(out).
    """
    from seactl.apps.paper import reproduce as run

    if not out.strip():   # (Path("") is the working directory)
        raise InputError("--out", out, "a directory name")
    summary = run(Path(out), only=only or None, jobs=jobs)
    console.print(f"report: {Path(out) / 'index.html'}", highlight=False)
    console.print(claims_summary(summary), highlight=False)


def claims_summary(claims: list[dict[str, Any]]) -> str:
    """The claims in the report's words (:data:`~seactl.apps.report_page.WORDS`): ``pass`` is
    reproduced, ``fail`` does not hold as printed (the report gives the reason), ``info`` is a
    finding (nothing to compare), ``skip`` is not computed here (counted apart)."""
    return summary_line(claims, reasons=" (reasons in the report)")


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print the results as JSON.")
@click.option("--only", multiple=True, help="Only the named benchmark(s).")
@click.option("--repeat", type=click.IntRange(1, 50), default=5, show_default=True,
              help="Timed repetitions (the median is reported).")
def bench(as_json: bool, only: tuple[str, ...], repeat: int) -> None:
    """Benchmarks with throughput and the ratio to a baseline measured in the same run.

    Python: seactl.apps.bench.run_benchmarks(...).
    """
    from seactl.apps.bench import run_benchmarks

    results = run_benchmarks(only=only or None, repeat=repeat)
    if as_json:
        echo_json({"benchmarks": results})
        return
    t = Table(title="seactl benchmarks (medians; throughput in work units per second, each "
              "benchmark's unit in its note; ratio = ours / baseline)")
    for col in ("name", "throughput [1/s]", "baseline", "baseline [1/s]", "ratio",
                "max error [relative, or as stated]"):
        t.add_column(escape(col), justify="left" if col in ("name", "baseline") else "right")
    for r in results:
        t.add_row(r["name"], f"{r['throughput_per_s']:.4g}", r["baseline"],
                  f"{r['baseline_throughput_per_s']:.4g}", f"{r['ratio']:.3g}",
                  r.get("max_error_text") or f"{r['max_error']:.3g}")
    console.print(t)
    for r in results:
        if r.get("note"):
            console.print(f"- {r['name']}: {r['note']}")
