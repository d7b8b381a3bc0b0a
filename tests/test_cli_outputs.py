"""What the command line prints for people: the claims in words, units in table headers.

Oracles: the report's own claims.json (the statuses the summary line counts), and the
rendered tables' headers (every numeric column names its unit; the slower commands' tables
are checked by tests/test_readme.py, which runs them from the quick start).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from seactl.apps.cli import main
from seactl.apps.commands.core import claims_summary
from tables import table_columns, unitless_numeric_columns


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


def test_every_number_in_a_table_has_its_unit(capsys, monkeypatch, tmp_path):
    # Oracle: the tables as printed; a numeric column without a unit in its header (and
    # not a gain scale, ratio, count or index) fails.  The parser is checked on a
    # header without a unit first, so the test can fail.
    bad = "┏━━━┳━━━┓\n┃ K ┃ B [Ns/m] ┃\n┡━━━╇━━━┩\n│ 1.5e+03 │ 2 │\n└───┴───┘\n"
    assert unitless_numeric_columns(bad) == ["K"]
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    problems = []
    for args in [*TABLES, ["export", "--fn", "14", "--out", str(tmp_path / "ctl")]]:
        assert main(args) == 0, args
        text = capsys.readouterr().out
        assert table_columns(text), args
        problems += [f"{' '.join(args[:3])}: {h}" for h in unitless_numeric_columns(text)]
    assert not problems, problems

