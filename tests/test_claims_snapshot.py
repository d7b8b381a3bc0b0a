"""The whole report under test: every claim of ``seactl reproduce`` against a committed snapshot.

Oracle: ``tests/data/claims_snapshot.json``, a reviewed earlier run.  A claim whose status
changes, whose value moves by more than its own tolerance, or that appears or disappears makes
this test fail, so a change to margins, simulation or design that flips a paper claim is a
reviewed change.  The whole report is a slow test (``pytest -m slow``); the default run
compares the report's first sections.  After reviewing a change, refresh the snapshot with
(the option selects the slow tests too)::

    .venv/bin/python -m pytest tests/test_claims_snapshot.py --update-claims-snapshot
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

SNAPSHOT = Path(__file__).parent / "data" / "claims_snapshot.json"
REL_TOL = 1e-6  # for claims whose tolerance is a relation, not a number


def _snapshot_of(claims: list[dict]) -> list[dict]:
    keep = ("id", "status", "our_value", "tolerance")
    return [{k: c[k] for k in keep} for c in claims]


def _decimals(x) -> int:
    """Decimals ``x`` prints with (26.03 -> 2); 99 for an int or a full-precision float."""
    text = repr(x)
    if not isinstance(x, float) or "e" in text or len(text.split(".")[1]) > 6:
        return 99
    return len(text.split(".")[1])


def _last_digit(ours, snap) -> float:
    """One unit in the last decimal of a rounded claim value (26.03 vs 26.04 -> 0.01).

    Claim values are rounded for the report, so a change of 1e-5 (another scipy version)
    can move a rounded value by a whole unit of its last digit; that is not a reviewed change.
    """
    return 1.000001 * 10.0 ** -max(_decimals(ours), _decimals(snap))


def _close(ours, snap, tol) -> bool:
    """Values equal within ``tol`` (numbers), element-wise for lists and dicts."""
    if isinstance(snap, list) and isinstance(ours, list):
        return len(ours) == len(snap) and all(_close(a, b, tol) for a, b in zip(ours, snap))
    if isinstance(snap, dict) and isinstance(ours, dict):
        return ours.keys() == snap.keys() and all(_close(ours[k], snap[k], tol) for k in snap)
    if isinstance(snap, (int, float)) and isinstance(ours, (int, float)) \
            and not isinstance(snap, bool):
        if isinstance(tol, (int, float)) and not isinstance(tol, bool) and tol > 0:
            return abs(ours - snap) <= tol
        return math.isclose(ours, snap, rel_tol=REL_TOL, abs_tol=_last_digit(ours, snap))
    return ours == snap


def _problems(current: list[dict], snapshot: list[dict]) -> list[str]:
    """What changed from ``snapshot`` to ``current`` (claims as :func:`_snapshot_of`)."""
    snap = {c["id"]: c for c in snapshot}
    now = {c["id"]: c for c in current}
    problems = [f"{i}: new claim" for i in sorted(now.keys() - snap.keys())]
    problems += [f"{i}: claim disappeared" for i in sorted(snap.keys() - now.keys())]
    for i in sorted(now.keys() & snap.keys()):
        a, b = now[i], snap[i]
        if a["status"] != b["status"]:
            problems.append(f"{i}: status {b['status']} -> {a['status']}")
        elif not _close(a["our_value"], b["our_value"], b["tolerance"]):
            problems.append(f"{i}: value {b['our_value']!r} -> {a['our_value']!r} "
                            f"(tolerance {b['tolerance']!r})")
    return problems


@pytest.mark.slow
def test_claims_match_snapshot(full_report, request):
    claims = json.loads((full_report / "claims.json").read_text())
    current = _snapshot_of(claims)
    if request.config.getoption("--update-claims-snapshot"):
        SNAPSHOT.write_text(json.dumps(current, indent=1, sort_keys=True) + "\n")
        pytest.skip(f"snapshot rewritten: {SNAPSHOT}")
    problems = _problems(current, json.loads(SNAPSHOT.read_text()))
    assert not problems, "claims changed (review, then --update-claims-snapshot):\n" + \
        "\n".join(problems)


def test_first_sections_match_snapshot(first_sections_report):
    # The same comparison on the report's first sections (conftest.first_sections_report),
    # against the snapshot's claims of those sections (their ids' first component).
    current = _snapshot_of(json.loads((first_sections_report / "claims.json").read_text()))
    prefixes = {c["id"].split(".")[0] for c in current}
    snapshot = [c for c in json.loads(SNAPSHOT.read_text()) if c["id"].split(".")[0] in prefixes]
    assert len(current) >= 20
    problems = _problems(current, snapshot)
    assert not problems, "claims changed (review, then --update-claims-snapshot):\n" + \
        "\n".join(problems)


def _html_lists_every_claim_and_figure(report: Path) -> list[str]:
    """Oracle: claims.json and the figures directory of the same run; the figures."""
    html = (report / "index.html").read_text()
    claims = json.loads((report / "claims.json").read_text())
    assert claims and all(c["id"] in html for c in claims)
    figures = sorted(p.name for p in (report / "figures").iterdir())
    assert all(f"figures/{name}" in html for name in figures)
    return figures


@pytest.mark.slow
def test_report_html_lists_every_claim_and_figure(full_report):
    assert _html_lists_every_claim_and_figure(full_report)


def test_first_sections_html_lists_every_claim_and_figure(first_sections_report):
    _html_lists_every_claim_and_figure(first_sections_report)


@pytest.mark.parametrize("ours, snap, same", [
    (26.04, 26.03, True),          # a rounded value's last digit flipped
    (26.05, 26.03, False),         # two units: a real change
    (4.0, 3.0, False), (4, 3, False),
    (0.123456789, 0.123456788, True),   # full precision: relative 1e-6
    (0.1234567, 0.1234577, False),
])
def test_a_rounded_value_may_move_one_unit_of_its_last_digit(ours, snap, same):
    assert _close(ours, snap, "relation") is same
