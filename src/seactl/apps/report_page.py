"""The report's page: the words, the summary, the verdict per section and the HTML.

The first screen answers "does the paper hold?": how many claims were checked and how many
are reproduced, do not hold as printed, or are findings; the verdict of every section; and
every claim that does not hold, with its reason.  Below it each section keeps its prose,
figures and tables; its claims sit in a collapsed table linked from its figures, so the page
stays short while every claim is still in it.

A claim's ``status`` stays ``pass`` / ``fail`` / ``info`` in ``claims.json`` (a machine
field); people read the words of :data:`WORDS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

WORDS = {"pass": "reproduced", "fail": "does not hold as printed", "info": "finding",
         "skip": "not computed"}
"""What each claim status means, in the words people read (the report, the summary line)."""


def count_words(counts: dict[str, int]) -> dict[str, str]:
    """``{status: "3 reproduced" | "1 does not hold as printed" | "2 findings" |
    "4 not computed"}``."""
    fail = "does not hold as printed" if counts.get("fail", 0) == 1 else \
        "do not hold as printed"
    info = "finding" if counts.get("info", 0) == 1 else "findings"
    words = {"pass": "reproduced", "fail": fail, "info": info, "skip": "not computed"}
    return {s: f"{counts.get(s, 0)} {w}" for s, w in words.items()}


def counts_phrase(counts: dict[str, int]) -> str:
    """``"3 reproduced, 8 do not hold as printed"``: the non-zero counts, in status order."""
    words = count_words(counts)
    return ", ".join(words[s] for s in WORDS if counts.get(s, 0)) or "none"


def summary_line(claims: Sequence[dict[str, Any]], reasons: str = "") -> str:
    """``"142 claims of the paper checked: 105 reproduced, 18 do not hold as printed,
    19 findings"`` for a list of claims (``claims.json``'s dicts); ``reasons`` (e.g.
    ``" (reasons in the report)"``) follows the count of claims that do not hold.  Claims
    not computed here (``skip``) are not checked: they follow, counted apart
    (``"; 4 not computed"``)."""
    counts = status_counts(claims)
    w = count_words(counts)
    checked = len(claims) - counts["skip"]
    noun = "claim" if checked == 1 else "claims"
    line = (f"{checked} {noun} of the paper checked: {w['pass']}, {w['fail']}{reasons}, "
            f"{w['info']}")
    return line + (f"; {w['skip']}" if counts["skip"] else "")


def status_counts(claims: Sequence[dict[str, Any]]) -> dict[str, int]:
    """How many claims have each status (every status present, possibly 0)."""
    counts = dict.fromkeys(WORDS, 0)
    for c in claims:
        counts[c["status"]] += 1
    return counts


@dataclass(frozen=True)
class SectionVerdict:
    """A section's line in the verdict table: its claims counted by status."""

    id: str
    title: str
    counts: dict[str, int]

    @property
    def status(self) -> str:
        """``fail`` if any claim does not hold, else ``pass`` if any is reproduced, else
        ``info`` (findings only), else ``skip`` (none computed), else ``none`` (a
        section without claims)."""
        for s in ("fail", "pass", "info", "skip"):
            if self.counts[s]:
                return s
        return "none"

    @property
    def label(self) -> str:
        """The verdict in words (the coloured cell of the table)."""
        return {"fail": "not as printed", "pass": "reproduced", "info": "findings",
                "skip": "not computed", "none": "no claims"}[self.status]


def section_verdicts(sections: Sequence[Any]) -> list[SectionVerdict]:
    """The verdict of every section (objects with ``id``, ``title`` and ``claims``)."""
    return [SectionVerdict(s.id, s.title, status_counts([{"status": c.status}
                                                         for c in s.claims]))
            for s in sections]


def is_numeric(v: Any) -> bool:
    """A number (not a boolean): shown right-aligned on one line; anything else wraps."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def unit_of(claim: str) -> str:
    """The unit in a claim's trailing brackets (``"... PM [deg]"`` -> ``"deg"``)."""
    claim = claim.rstrip()
    return claim[claim.rindex("[") + 1:-1] if claim.endswith("]") and "[" in claim else ""


def format_value(v: Any, tol: Any = None, unit: str = "") -> str:
    """A claim value for people: numbers rounded to one digit finer than the tolerance (else
    4 significant digits) with the unit, yes/no for booleans, lists and dicts spelled out."""
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        if isinstance(v, float) and not math.isfinite(v):
            return str(v)
        if isinstance(tol, (int, float)) and not isinstance(tol, bool) and tol > 0:
            digits = max(0, 1 - math.floor(math.log10(tol)))
            text = f"{v:.{min(digits, 6)}f}"
        else:
            text = f"{v:.4g}"
        return f"{text} {unit}".rstrip()
    if isinstance(v, (list, tuple)):
        if v and all(isinstance(x, bool) for x in v):
            return f"{sum(v)} of {len(v)} yes"
        return ", ".join(format_value(x, tol) for x in v) + (f" {unit}" if unit else "")
    if isinstance(v, dict):
        return "; ".join(f"{k.replace('_', ' ')}: {format_value(x, tol)}" for k, x in v.items())
    return str(v)


def one_line(note: str, limit: int = 180) -> str:
    """The first sentence of a note, cut to ``limit`` characters."""
    return shorten(note.split(". ")[0].strip(), limit)


def shorten(text: str, limit: int) -> str:
    """``text`` cut to at most ``limit`` characters at a word's end, an ellipsis marking
    the cut."""
    if len(text) <= limit:
        return text
    cut = text[:limit]
    if " " in cut[limit // 2:]:
        cut = cut[:cut.rindex(" ")]
    return cut[:limit - 1].rstrip(" ,;:(") + "\u2026"


def render_html(sections: Sequence[Any], claims: Sequence[dict[str, Any]], version: str
                ) -> str:
    """The report's ``index.html`` for built sections (:class:`seactl.apps.report.Section`)
    and their claims as ``claims.json`` holds them; ``version`` is seactl's."""
    from jinja2 import Environment, PackageLoader, select_autoescape

    env = Environment(loader=PackageLoader("seactl", "templates"),
                      autoescape=select_autoescape(["html"]), trim_blocks=True,
                      lstrip_blocks=True)
    env.filters.update(value=lambda c, key: format_value(c[key], c.get("tolerance"),
                                                         unit_of(c["claim"])),
                       one_line=one_line, phrase=counts_phrase,
                       shorten=shorten)
    env.tests["numeric"] = is_numeric
    by_section = {s.id: [c.as_json() for c in s.claims] for s in sections}
    flagged = {st: [c | {"section_id": sid} for sid, cs in by_section.items() for c in cs
                    if c["status"] == st] for st in ("fail", "info")}
    counts = status_counts(claims)
    return env.get_template("report.html").render(
        sections=sections, verdicts={v.id: v for v in section_verdicts(sections)},
        claims=claims, checked=len(claims) - counts["skip"], counts=counts,
        words=count_words(counts), by_section=by_section,
        not_holding=flagged["fail"], findings=flagged["info"], status_words=WORDS,
        version=version)
