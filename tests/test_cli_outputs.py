"""What the command line prints for people: the claims in words, units in table headers.

Oracles: the report's own claims.json (the statuses the summary line counts), and the
rendered tables' headers (every numeric column names its unit).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from seactl.apps.cli import main
from seactl.apps.commands.core import claims_summary


def test_reproduce_ends_with_the_claims_in_words(tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["reproduce", "--only", "table-i", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.strip().splitlines()[-1]
    claims = json.loads((out / "claims.json").read_text())
    claims = claims["claims"] if isinstance(claims, dict) else claims
    n = {s: sum(c["status"] == s for c in claims) for s in ("pass", "fail", "info")}
    m = re.fullmatch(r"(\d+) claims? of the paper checked: (\d+) reproduced, (\d+) do(?:es)? "
                     r"not hold as printed \(reasons in the report\), (\d+) findings?", printed)
    assert m, printed
    assert [int(g) for g in m.groups()] == [len(claims), n["pass"], n["fail"], n["info"]]
    assert not re.search(r"\b(pass|fail|info)\b", printed)


def test_claims_summary_counts_each_status_in_words():
    # Oracle: the counts of the claims given, in the agreed words, singular where one.
    one = [{"status": "fail"}]
    assert claims_summary(one) == ("1 claim of the paper checked: 0 reproduced, 1 does not "
                                   "hold as printed (reasons in the report), 0 findings")
    many = [{"status": s} for s in ["pass"] * 3 + ["fail"] * 2 + ["info"]]
    assert claims_summary(many) == ("6 claims of the paper checked: 3 reproduced, 2 do not "
                                    "hold as printed (reasons in the report), 1 finding")


NUMBER = re.compile(r"[-+]?(\d[\d,]*\.?\d*|\.\d+)(e[-+]?\d+)?")
DIMENSIONLESS = {"GS", "ratio", "ratio d/s", "worst run", "messages", "points"}
"""Numeric columns whose numbers have no unit: gain scales, ratios, counts, run indices."""


def table_columns(text: str) -> list[tuple[str, list[str]]]:
    """(header, body cells) of every column of every table rich drew in ``text``."""
    cols: list[tuple[str, list[str]]] = []
    head: list[list[str]] = []
    body: list[list[str]] = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("┃"):
            head.append([c.strip() for c in s.strip("┃").split("┃")])
        elif s.startswith("│") and head:
            body.append([c.strip() for c in s.strip("│").split("│")])
        elif s.startswith("└") and head:
            for j in range(len(head[0])):
                cols.append((" ".join(h[j] for h in head if h[j]),
                             [r[j] for r in body if len(r) == len(head[0]) and r[j]]))
            head, body = [], []
    return cols


def _numeric(cell: str) -> bool:
    return bool(NUMBER.fullmatch(cell.split(" (")[0]))


def _named(header: str) -> bool:
    return ("[" in header or header in DIMENSIONLESS
            or bool(re.search(r"_(hz|s|ms|deg|db|rad|m)$", header)))


def unitless_numeric_columns(text: str) -> list[str]:
    """Numeric columns without a unit; in a quantity / value table, the quantities whose
    value is a number without one."""
    cols = table_columns(text)
    bad = []
    for k, (h, cells) in enumerate(cols):
        if h == "value" and k and cols[k - 1][0] == "quantity":
            bad += [q for q, v in zip(cols[k - 1][1], cells)
                    if _numeric(v) and not _named(q) and not q.startswith("P(")]
        elif any(_numeric(c) for c in cells) and not _named(h):
            bad.append(h)
    return bad


DESIGN = ["--fn", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50",
          "--f-taud", "100"]
TABLES = [
    ["gains", *DESIGN, "--rate", "27.5"], ["jitter", *DESIGN, "--rate", "500"],
    ["roots", *DESIGN], ["rigid", "--fn", "8", "--t-s", "15", "--t-d", "1"],
    ["step", *DESIGN, "--mode", "sampled"], ["impulse", "--fn", "14", "--mode", "sampled"],
    ["step", *DESIGN, "--mode", "sampled", "--latency", "torque=uniform:0.5:3", "--runs", "20"],
    ["robust", "--fn", "14", "--k", "20%", "--n", "50"],
    ["impedance", "--fn", "30", "--freq", "1", "10", "100"],
    ["zregion", "--fn", "12", "16", "--gs", "1", "--freq", "0.1:1000:21"],
    ["analyze", "--loop", "examples/loops/paper-sea.toml"],
    ["step", "--loop", "examples/loops/sea-dob.toml", "--set", "q_hz=5,10"],
    ["impulse", "--loop", "examples/loops/paper-sea.toml"],
    ["impedance", "--loop", "examples/loops/paper-sea.toml", "--freq", "1", "10"],
]


def test_every_number_in_a_table_has_its_unit(capsys, monkeypatch):
    # Oracle: the tables as printed; a numeric column without a unit in its header (and
    # not a gain scale, ratio, count or index) fails.  The parser is checked on a
    # header without a unit first, so the test can fail.
    bad = "┏━━━┳━━━┓\n┃ K ┃ B [Ns/m] ┃\n┡━━━╇━━━┩\n│ 1.5e+03 │ 2 │\n└───┴───┘\n"
    assert unitless_numeric_columns(bad) == ["K"]
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    problems = []
    for args in TABLES:
        assert main(args) == 0, args
        text = capsys.readouterr().out
        assert table_columns(text), args
        problems += [f"{' '.join(args[:3])}: {h}" for h in unitless_numeric_columns(text)]
    assert not problems, problems


@pytest.mark.slow
def test_every_number_in_the_slower_tables_has_its_unit(capsys, monkeypatch, tmp_path):
    # As above, for the commands of tens of seconds (placement, maps, base, sweep, run).
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    problems = []
    for args in (["place", "--high-latency", "22", "--low-latency", "0.5"],
                 ["place", "--high-timing", "hist:examples/timing/trace.csv", "--low-timing",
                  "uniform:0.5:1", "--runs", "20"],
                 ["latency-map"], ["base", "--arch", "both"],
                 ["sweep", "--fn", "10:20:5", "--gs", "1", "--out", str(tmp_path / "sw"),
                  "--workers", "1", "--quiet"],
                 ["run", "--fn", "14", "--f-qd", "50", "--f-taud", "100", "--duration", "0.2"]):
        assert main(args) == 0, args
        text = capsys.readouterr().out
        assert table_columns(text), args
        problems += [f"{' '.join(args[:3])}: {h}" for h in unitless_numeric_columns(text)]
    assert not problems, problems
