"""``seactl delay-margin``: JSON and table for SEA designs and loop files, bad input.

Oracles: the certified loop-break delay margin of ``seactl gains --json`` and of the
rigid actuator's ``margins()`` (growing every delay of the broken loop alike is the same
thing), and the CLI error contract (exit 2, one line).
"""

import json

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main

SEA = "--fn 12 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100"


def run(args, capsys):
    code = main(args.split())
    out, err = capsys.readouterr()
    return code, out, err


def test_sea_json_is_the_loop_break_delay_margin(capsys):
    # Oracle: `seactl gains --json` delay_margin_ms (Nyquist scan of the loop broken at
    # the joint sensor, which holds the stiffness and damping delays, not the torque one).
    code, out, _ = run(f"delay-margin {SEA} --direction stiffness=1,damping=1 --json", capsys)
    assert code == 0
    got = json.loads(out)
    assert got["direction"] == {"stiffness": 1.0, "damping": 1.0, "torque": 0.0}
    code, out, _ = run(f"gains {SEA} --json", capsys)
    ref = [r["delay_margin_ms"] for r in json.loads(out)]
    np.testing.assert_allclose([1e3 * r["delay_margin_s"] for r in got["designs"]], ref,
                               rtol=1e-7)
    assert all(r["verified"] and r["stable"] for r in got["designs"])


def test_loop_file_table_has_units_and_the_rigid_margin(capsys):
    # Oracle: sc.rigid's certified loop-break delay margin for the same loop (the loop
    # file's header says it is `seactl rigid --fn 8 --t-s 1.5 --t-d 1.5 --f-v 50`).
    code, out, _ = run("delay-margin --loop examples/loops/rigid.toml --direction "
                       "K_fb=1,B_fb=1 --json", capsys)
    assert code == 0
    row = json.loads(out)["designs"][0]
    ref = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}, velocity_filter_hz=50).margins()
    assert 1e3 * row["delay_margin_s"] == pytest.approx(float(ref.delay_margin_ms), rel=1e-7)
    code, out, _ = run("delay-margin --loop examples/loops/rigid.toml --direction K_fb=1",
                       capsys)
    assert code == 0 and "margin [s]" in out and "crossing [Hz]" in out
    assert "K_fb at crossing [s]" in out


@pytest.mark.parametrize("args, needle", [
    ("delay-margin --fn 14 --direction stiffness", "NAME=WEIGHT"),
    ("delay-margin --fn 14 --direction stiff=1", "one of stiffness, damping, torque"),
    ("delay-margin --fn 14 --direction stiffness=1,damping=1.4142", "commensurate"),
    ("delay-margin --fn 14 --direction stiffness=-1", ">= 0"),
    ("delay-margin --loop examples/loops/rigid.toml --fn 14", "--fn"),
])
def test_bad_input_exits_2_on_one_line(args, needle, capsys):
    # Oracle: the CLI error contract.
    code, out, err = run(args, capsys)
    assert code == 2 and needle in err
    assert err.count("\n") == 1 and err.startswith("error: ") and "Traceback" not in err
