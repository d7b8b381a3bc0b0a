"""``seactl jitter``: how much time-varying latency each loop of a design tolerates."""

from __future__ import annotations

from typing import Any

import click
import numpy as np
from rich.markup import escape
from rich.table import Table

from seactl.errors import InputError

from .common import (
    SAMPLED_KEYS,
    DesignSpec,
    cli,
    console,
    design_options,
    echo_json,
    json_option,
    rate_option,
    sampled_callout,
    verdict_text,
)
from .loops import loop_options

LINKS = {"stiffness": "t_qs_ms", "damping": "t_qd_ms", "torque": "t_tau_ms"}

JSON_KEYS = ("fn_hz", "gs", "jitter_margin_ms", "stiffness_jitter_margin_ms",
             "damping_jitter_margin_ms", "torque_jitter_margin_ms", "delay_margin_ms")


def jitter_rows(spec: DesignSpec) -> list[dict[str, Any]]:
    """One row per (f_n, GS) design: the public API's :meth:`seactl.JitterResult.records`
    (:data:`JSON_KEYS` and ``stable``)."""
    return spec.designs().jitter_margins().records()


def _ms(x: float | None, stable: bool) -> str:
    if not stable:
        return "[red]unstable[/red]"
    if x == 0:  # (stable, but no bound of w |T| could be proven)
        return "[yellow]0 (not proven)[/yellow]"
    return "inf" if x is None else f"{x:.3f}"


def _sampled_ms(sj: dict[str, Any], prefix: str) -> str:
    """A sampled jitter margin [ms] with its samples, or the verdict that stands for it."""
    if f"{prefix}jitter_margin_ms" not in sj:
        return "-"
    if sj["verdict"] != "stable":
        return verdict_text(sj["verdict"])
    return f"{sj[f'{prefix}jitter_margin_ms']:.3f} ({sj[f'{prefix}jitter_margin_samples']:.1f})"


def parse_traces(tokens: tuple[str, ...]) -> dict[str, Any]:
    """``LINK=FILE.csv`` (a measured latency trace, e.g. ``seactl run``'s
    ``latency-stiffness.csv``) -> :class:`~seactl.latency.models.Empirical` per link."""
    from seactl.latency.models import Empirical

    out = {}
    for tok in tokens:
        link, sep, path = tok.partition("=")
        if not sep or link.strip() not in LINKS:
            raise InputError("--trace", tok, "LINK=FILE.csv with LINK one of "
                             + ", ".join(LINKS))
        out[link.strip()] = Empirical.from_csv(path.strip(), f"--trace {link.strip()}")
    return out


def trace_checks(spec: DesignSpec, rows: list[dict[str, Any]], traces: dict[str, Any]
                 ) -> list[dict[str, Any]]:
    """Per design and traced link: the measured latencies against the analysed band
    ``[T, T + J]`` (``T`` the design's delay of the link, ``J`` its jitter margin)."""
    out = []
    for r in rows:
        for link, emp in traces.items():
            nominal = float(getattr(spec, LINKS[link]))
            lo, hi = emp.lower_s * 1e3, max(emp.values_s) * 1e3
            margin = r[f"{link}_jitter_margin_ms"]
            band_hi = np.inf if margin is None else nominal + margin
            covered = bool(r["stable"] and lo >= nominal - 1e-9 and hi <= band_hi + 1e-9)
            out.append({"fn_hz": r["fn_hz"], "gs": r["gs"], "link": link,
                        "min_ms": lo, "max_ms": hi, "analysed_ms": nominal,
                        "jitter_margin_ms": margin, "stable": bool(r["stable"]),
                        "covered": covered})
    return out


@cli.command()
@design_options
@click.option("--trace", "traces", multiple=True, metavar="LINK=FILE.csv",
              help="A measured latency trace of a link (stiffness, damping or torque; e.g. "
                   "seactl run's latency-stiffness.csv): checked against [T, T + J].")
@rate_option
@json_option
@loop_options
def jitter(spec: DesignSpec, traces: tuple[str, ...], rate_hz: float | None,
           as_json: bool, loop: Any) -> None:
    """Jitter margins [ms]: the largest time-varying extra delay in [0, J] that each loop
    is guaranteed to tolerate (Kao-Lincoln small-gain bound, exact delays), next to the
    whole outer loop's margin for a constant extra delay.

    Python: sc.design(...).jitter_margins() (--rate: .margins(rate_hz=...));
    sc.load_loop(FILE).jitter_margins() for --loop (each named break of the file).

    \b
    Example (Table I):
      seactl jitter --fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100
      seactl jitter --loop examples/loops/rigid.toml --set fn=6,8,10

    With --rate, the loop sampled at that rate beside them: its certified verdict and
    delay margin (JSON "sampled": .margins(rate_hz=...)) and each loop's jitter margin when
    the measurement is sampled late by a delay varying in [0, J] (JSON "sampled_jitter":
    .jitter_margins(rate_hz=...), in ms and in samples; sampled-data small-gain bound with
    the aliased plant, docs/theory/sampled-jitter.md).
    """
    if loop is not None:
        loop_jitter(loop, as_json)
        return
    measured = parse_traces(traces)
    rows = jitter_rows(spec)
    checks = trace_checks(spec, rows, measured)
    keys = JSON_KEYS
    if rate_hz is not None:
        designs = spec.designs()
        for r, sm, sj in zip(rows, designs.margins(rate_hz).records(),
                             designs.jitter_margins(rate_hz=rate_hz).records()):
            r["sampled"] = {k: sm[k] for k in SAMPLED_KEYS}
            r["sampled_jitter"] = {k: v for k, v in sj.items() if k not in ("fn_hz", "gs")}
        keys = JSON_KEYS + ("sampled", "sampled_jitter")
    if as_json:
        echo_json({"designs": [{k: r[k] for k in keys} for r in rows]}
                  | ({"traces": checks} if checks else {}))
        return
    t = Table(title=escape(f"Jitter margins [ms], actuator '{spec.actuator.name}' "
                           f"(T_tau={spec.t_tau_ms:g} ms, T_qs={spec.t_qs_ms:g} ms, "
                           f"T_qd={spec.t_qd_ms:g} ms)"))
    cols = ["f_n [Hz]", "GS", "outer loop [ms]", "stiffness [ms]", "damping [ms]",
            "torque [ms]", "delay margin [ms]", "bottleneck"] + (
        [f"sampled {rate_hz:g} Hz"] + [f"sampled {k} [ms] (samples)" for k in
                                       ("outer loop", "stiffness", "damping", "torque")]
        + ["sampled DM [ms]"]
        if rate_hz else [])
    for col in cols:
        t.add_column(escape(col), justify="right")
    for r in rows:
        stable = bool(r["stable"])
        loops = {k: r[f"{k}_jitter_margin_ms"] for k in ("stiffness", "damping", "torque")}
        finite = {k: v for k, v in loops.items() if v is not None}
        worst = min(finite, key=finite.get) if finite and stable else "-"
        extra = []
        if rate_hz is not None:
            sm, sj = r["sampled"], r["sampled_jitter"]
            ok = sm["verdict"] == "stable"
            extra = [verdict_text(sm["verdict"]),
                     *(_sampled_ms(sj, p) for p in ("", "stiffness_", "damping_", "torque_")),
                     _ms(sm["delay_margin_ms"], ok)]
        t.add_row(f"{r['fn_hz']:g}", f"{r['gs']:g}", _ms(r["jitter_margin_ms"], stable),
                  *(_ms(v, stable) for v in loops.values()),
                  _ms(r["delay_margin_ms"], stable), worst, *extra)
    console.print(t)
    if rate_hz is not None:
        for line in sampled_callout(rows):
            console.print(escape(line), highlight=False)
        console.print(f"Sampled at {rate_hz:g} Hz: each loop stays stable when its measurement "
                      "is sampled late by any delay varying in [0, J] (J in ms, samples in "
                      "brackets; docs/theory/sampled-jitter.md).", highlight=False)
    console.print("A loop stays stable under any latency variation within its jitter margin "
                  "(sufficient, not necessary); the delay margin is for a constant extra "
                  "delay.", highlight=False)
    for c in checks:
        verdict = "covered by the analysis" if c["covered"] else "[red]NOT covered[/red]"
        if not c["stable"]:
            console.print(f"f_n {c['fn_hz']:g} Hz, {c['link']}: the design is [red]unstable"
                          "[/red] at its own delays: no latency is covered", highlight=False)
            continue
        console.print(f"f_n {c['fn_hz']:g} Hz, {c['link']}: measured {c['min_ms']:.3f} to "
                      f"{c['max_ms']:.3f} ms, analysed {c['analysed_ms']:g} ms + jitter "
                      f"margin {_ms(c['jitter_margin_ms'], True)} ms: {verdict}"
                      + ("" if c["covered"] else f" (analyse with the trace's minimum, "
                         f"--{LINKS[c['link']][:-3].replace('_', '-')} "
                         f"{c['min_ms']:.3g}, and compare the spread)"), highlight=False)


def loop_jitter(loop: Any, as_json: bool) -> None:
    """A loop file's jitter margins per design and named break
    (:meth:`seactl.UserLoop.jitter_margins`), as JSON or a table."""
    res = loop.jitter_margins()
    rows = res.records()
    if as_json:
        echo_json({"loop": res.loop, "designs": rows})
        return
    breaks = list(res.break_jitter_margins_s)
    labels = [k for k in rows[0] if k not in _loop_keys(breaks)] if rows else []
    t = Table(title=escape(f"Jitter margins [ms] of loop file '{res.loop}' at each named "
                           "break"))
    for col in [*labels, *(f"{b} [ms]" for b in breaks), f"delay margin at {breaks[-1]} [ms]",
                "stable"]:
        t.add_column(escape(col), justify="right")
    for r in rows:
        stable = bool(r["stable"])
        t.add_row(*(f"{r[k]:g}" if isinstance(r[k], float) else escape(str(r[k]))
                    for k in labels),
                  *(_ms(r[f"{b}_jitter_margin_ms"], stable) for b in breaks),
                  _ms(r["delay_margin_ms"], stable), "yes" if stable else "[red]no[/red]")
    console.print(t)
    console.print(f"The last break ({escape(breaks[-1])}) is the whole loop's "
                  "(jitter_margin_ms in JSON); a loop stays stable under any latency "
                  "variation within its jitter margin there (sufficient, not necessary); "
                  "the delay margin is for a constant extra delay.", highlight=False)


def _loop_keys(breaks: list[str]) -> set[str]:
    """The columns of a loop's jitter records that are not labels."""
    return {"jitter_margin_ms", "delay_margin_ms", "stable",
            *(f"{b}_jitter_margin_ms" for b in breaks)}
