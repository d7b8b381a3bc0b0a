"""``seactl jitter --loop FILE``: a loop file's jitter margins at each named break."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import seactl as sc
from seactl.apps.cli import main

RIGID = Path(__file__).resolve().parents[1] / "examples" / "loops" / "rigid.toml"


def test_cli_loop_jitter_is_the_apis_and_the_built_in_rigid_actuators(capsys):
    # Oracle 1: the public API on the same file and values (UserLoop.jitter_margins),
    # record for record.  Oracle 2: rigid.toml is the built-in rigid loop written as a
    # file (its header: seactl rigid --fn 8 --t-s 1.5 --t-d 1.5 --f-v 50), so at fn = 8
    # its stiffness and damping breaks' margins and the whole loop's are those the
    # built-in diagram gives (sc.rigid(...).jitter_margins(), a second derivation).
    assert main(["jitter", "--loop", str(RIGID), "--set", "fn=6,8", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    api = sc.load_loop(str(RIGID), fn=[6.0, 8.0]).jitter_margins()
    assert out == {"loop": "rigid", "designs": api.records()}
    at8 = out["designs"][1]
    assert at8["fn"] == 8.0
    ref = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5},
                   velocity_filter_hz=50).jitter_margins().records()[0]
    for key in ("jitter_margin_ms", "stiffness_jitter_margin_ms", "damping_jitter_margin_ms",
                "delay_margin_ms"):
        assert at8[key] == pytest.approx(ref[key], rel=1e-8), key
    assert at8["position_jitter_margin_ms"] == at8["jitter_margin_ms"]   # the last break


def test_cli_loop_jitter_table_and_refused_options(capsys):
    # Oracle: the table shows every named break of the file (stiffness, damping,
    # position); options of the built-in SEA are refused on one line.
    assert main(["jitter", "--loop", str(RIGID)]) == 0
    text = capsys.readouterr().out
    assert all(f"{b} [ms]" in text for b in ("stiffness", "damping", "position"))
    assert main(["jitter", "--loop", str(RIGID), "--rate", "1000"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: invalid --rate") and err.count("\n") == 1
