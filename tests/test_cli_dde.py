"""``seactl roots --dde FILE``: the table (units), JSON (the API's records), ``--set`` batches
and one-line errors with exit 2.

Oracles: ``sc.load_dde(FILE).roots(count=)`` for the same file (every front end goes through
the public API), the Lambert W value W_0(-1) (mpmath) for the scalar example, and the CLI
error contract.
"""

from __future__ import annotations

import json
from pathlib import Path

import mpmath
import pytest

import seactl as sc
from seactl.apps.cli import main
from tables import table_columns, unitless_numeric_columns

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _in_repo(monkeypatch):
    monkeypatch.chdir(ROOT)


def test_json_equals_the_api_and_lambert_w(capsys):
    # Oracle: the API's records for the same file; W_0(-1) (mpmath) for s + e^{-s}.
    assert main(["roots", "--dde", "examples/dde/lambert.toml", "--count", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    api = sc.load_dde("examples/dde/lambert.toml").roots(count=3).records()
    assert out["designs"] == json.loads(json.dumps(api))
    assert out["kind"] == "quasi-polynomial" and out["delays"] == ["tau1"]
    w0 = complex(mpmath.lambertw(-1, 0))
    z = out["designs"][0]["roots"][0]
    assert abs(z["re"] - w0.real) < 1e-9 and abs(z["im"] - w0.imag) < 1e-9


def test_set_makes_a_batch_and_the_table_has_units(capsys):
    # Oracle: the API with the same delays; the table's headers (every number has its unit).
    assert main(["roots", "--dde", "examples/dde/gkc-2x2.toml", "--set", "tau=6,6.3"]) == 0
    text = capsys.readouterr().out
    assert not unitless_numeric_columns(text)
    cols = dict(table_columns(text))
    assert cols["tau [s]"] == ["6", "6.3"]
    ref = sc.load_dde("examples/dde/gkc-2x2.toml", tau=[6.0, 6.3]).roots(count=6)
    assert cols["RHP roots"] == [str(n) for n in ref.right_half_plane_roots.tolist()]
    assert cols["stable"] == ["yes", "NO"]


@pytest.mark.parametrize("args, needle", [
    (["--dde", "examples/dde/lambert.toml", "--fn", "12"], "--fn"),
    (["--dde", "examples/dde/lambert.toml", "--set", "tau7=1"], "tau7"),
    (["--dde", "examples/dde/lambert.toml", "--set", "tau1=-1"], ">= 0"),
    (["--dde", "missing.toml"], "missing.toml"),
    (["--dde", "examples/dde/lambert.toml", "--loop", "examples/loops/paper-sea.toml"],
     "--loop"),
])
def test_bad_input_exits_2_on_one_line(args, needle, capsys):
    # Oracle: the CLI error contract (exit 2, one line naming the value, no traceback).
    assert main(["roots", *args]) == 2
    out, err = capsys.readouterr()
    assert needle in err and err.startswith("error: ") and len(err.strip().splitlines()) == 1
    assert "Traceback" not in out + err
