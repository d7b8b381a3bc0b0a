"""The CLI end to end: Table I, JSON keys, bad input (exit 2, no traceback)."""

import json
import subprocess
import sys

import pytest

from seactl.cli import expand_variadic, main, parse_values
from seactl.errors import InputError

TABLE_I = "--fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100"
KEYS = {"fn_hz", "gs", "Kq", "Bq", "Ktau", "Btau", "phase_margin_deg", "crossover_hz",
        "gain_margin_db", "delay_margin_ms", "stable", "spectral_abscissa"}


def run(args, capsys):
    code = main(args.split())
    out, err = capsys.readouterr()
    return code, out, err


def test_gains_prints_table_i(capsys):
    code, out, _ = run("gains " + TABLE_I, capsys)
    assert code == 0
    for text in ("65.17", "0.458", "1.180", "45.13", "83.17", "43.26", "33.19"):
        assert text in out


def test_gains_json_has_exactly_the_keys(capsys):
    code, out, _ = run("gains --json " + TABLE_I, capsys)
    assert code == 0
    rows = json.loads(out)
    assert [r["fn_hz"] for r in rows] == [12, 14, 16, 18, 20]
    assert all(set(r) == KEYS for r in rows)
    pms = [r["phase_margin_deg"] for r in rows]
    assert pms == pytest.approx([45.1, 43.2, 40.0, 36.5, 33.2], abs=0.1)
    assert all(r["stable"] for r in rows)


def test_ranges_and_gs_grid(capsys):
    code, out, _ = run("gains --json --fn 10:20:5 --gs 0.5 2", capsys)
    rows = json.loads(out)
    assert code == 0 and len(rows) == 6
    assert {(r["fn_hz"], r["gs"]) for r in rows} == {(f, g) for f in (10, 15, 20)
                                                      for g in (0.5, 2.0)}
    # ideal loop: no phase crossover -> gain margin null (documented), never NaN
    assert "NaN" not in out


@pytest.mark.parametrize("args,needle", [
    ("gains --fn 8", "feasible: f_n >= 9.45"),
    ("gains --t-qs -1", "--t-qs [ms] = -1.0"),
    ("gains --f-qd 0", "--f-qd [Hz] = 0.0"),
    ("gains --fn abc", "--fn = 'abc'"),
    ("gains --fn 20:10:1", "STOP >= START"),
    ("gains --gs 0", "--gs = 0.0"),
    ("gains --actuator nope", "actuator = 'nope'"),
    ("gains --zeta1 -1", "--zeta1 = -1.0"),
])
def test_bad_input_exits_2_with_a_clear_message(args, needle, capsys):
    code, out, err = run(args, capsys)
    assert code == 2
    assert needle in err.replace("\n", " ")
    assert "Traceback" not in err + out


def test_bad_toml_actuator(tmp_path, capsys):
    f = tmp_path / "a.toml"
    f.write_text("motor_inertia = 0.2\njoint_inertia = 0.01\nmotor_damping = 1\n"
                 "joint_damping = 0.1\nspring_stiffness = 0\ncurrent_to_torque = 5\n")
    code, _, err = run(f"gains --actuator {f}", capsys)
    assert code == 2 and "spring_stiffness = 0" in err


def test_console_script_exit_code_and_no_traceback():
    res = subprocess.run([sys.executable, "-c", "from seactl.cli import run; run()",
                          "gains", "--fn", "8"], capture_output=True, text=True)
    assert res.returncode == 2
    assert "Traceback" not in res.stderr and "9.45" in res.stderr


def test_value_parsing():
    assert list(parse_values("--fn", ["10:12:1", "15"])) == [10, 11, 12, 15]
    assert parse_values("--freq", ["1:100:3"], log=True) == pytest.approx([1, 10, 100])
    with pytest.raises(InputError):
        parse_values("--freq", ["0:100:3"], log=True)
    assert expand_variadic(["gains", "--fn", "1", "2", "--gs", "3", "--json"]) == [
        "gains", "--fn", "1", "--fn", "2", "--gs", "3", "--json"]
