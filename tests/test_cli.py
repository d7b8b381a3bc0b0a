"""The CLI end to end: Table I, JSON keys, bad input (exit 2, no traceback)."""

import json
import subprocess
import sys

import pytest

from seactl.apps.cli import expand_variadic, main, parse_values
from seactl.errors import InputError

TABLE_I = "--fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100"
KEYS = {"fn_hz", "gs", "Kq", "Bq", "Ktau", "Btau", "phase_margin_deg", "crossover_hz",
        "gain_margin_db", "delay_margin_ms", "stable", "spectral_abscissa"}


def run(args, capsys):
    code = main(args.split())
    out, err = capsys.readouterr()
    return code, out, err


# The paper's Table I: f_n -> K_q, B_q, K_tau, B_tau, PM, and half a unit of each printed digit
PRINTED = {12: (65, 0.46, 1.18, 0.057, 45.1), 14: (83, 0.76, 1.80, 0.067, 43.2),
           16: (103, 1.02, 2.56, 0.077, 40.0), 18: (124, 1.26, 3.45, 0.087, 36.5),
           20: (148, 1.49, 4.48, 0.097, 33.2)}
HALF_DIGIT = (0.5, 0.005, 0.005, 0.0005, 0.1)   # PM: the paper truncates (43.26 -> 43.2)


def test_gains_prints_table_i(capsys):
    """Oracle: the paper's Table I, read back from the printed table's cells."""
    code, out, _ = run("gains " + TABLE_I, capsys)
    assert code == 0
    header = next(line for line in out.splitlines() if "Kq" in line and "PM" in line)
    names = [c.split("[")[0].strip() for c in header.strip().strip("┃").split("┃")]
    rows = [dict(zip(names, (c.strip() for c in line.strip().strip("│").split("│"))))
            for line in out.splitlines() if line.startswith("│")]
    assert [float(r["f_n"]) for r in rows] == sorted(PRINTED)
    for r in rows:
        shown = [r[k] for k in ("Kq", "Bq", "Ktau", "Btau", "PM")]
        for text, paper, half in zip(shown, PRINTED[int(float(r["f_n"]))], HALF_DIGIT):
            display = 0.5 * 10.0 ** -len(text.partition(".")[2])   # rounding of the cell
            assert float(text) == pytest.approx(paper, abs=half + display + 1e-9), (r, text)


def test_gains_json_has_exactly_the_keys(capsys):
    # Oracle: the documented JSON keys and the paper's Table I phase margins.
    code, out, _ = run("gains --json " + TABLE_I, capsys)
    assert code == 0
    rows = json.loads(out)
    assert [r["fn_hz"] for r in rows] == [12, 14, 16, 18, 20]
    assert all(set(r) == KEYS for r in rows)
    pms = [r["phase_margin_deg"] for r in rows]
    assert pms == pytest.approx([45.1, 43.2, 40.0, 36.5, 33.2], abs=0.1)
    assert all(r["stable"] for r in rows)


def test_ranges_and_gs_grid(capsys):
    # Oracle: the START:STOP:STEP grid expanded by hand, (10, 15, 20) x (0.5, 2).
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
    # Oracle: the CLI error contract (exit 2, one message naming the flag, value and valid
    # range, no traceback).
    code, out, err = run(args, capsys)
    assert code == 2
    assert needle in err.replace("\n", " ")
    assert "Traceback" not in err + out


def test_bad_toml_actuator(tmp_path, capsys):
    # Oracle: the CLI error contract, naming the bad field of the file.
    f = tmp_path / "a.toml"
    f.write_text("motor_inertia = 0.2\njoint_inertia = 0.01\nmotor_damping = 1\n"
                 "joint_damping = 0.1\nspring_stiffness = 0\ncurrent_to_torque = 5\n")
    code, _, err = run(f"gains --actuator {f}", capsys)
    assert code == 2 and "spring_stiffness = 0" in err


def test_console_script_exit_code_and_no_traceback():
    # Oracle: the exit status and stderr of a real subprocess.
    res = subprocess.run([sys.executable, "-c", "from seactl.apps.cli import run; run()",
                          "gains", "--fn", "8"], capture_output=True, text=True)
    assert res.returncode == 2
    assert "Traceback" not in res.stderr and "9.45" in res.stderr


def test_value_parsing():
    # Oracle: the ranges expanded by hand.
    assert list(parse_values("--fn", ["10:12:1", "15"])) == [10, 11, 12, 15]
    assert parse_values("--freq", ["1:100:3"], log=True) == pytest.approx([1, 10, 100])
    with pytest.raises(InputError):
        parse_values("--freq", ["0:100:3"], log=True)
    assert expand_variadic(["gains", "--fn", "1", "2", "--gs", "3", "--json"]) == [
        "gains", "--fn", "1", "--fn", "2", "--gs", "3", "--json"]


def test_library_errors_name_parameters_and_cli_names_flags(tmp_path, capsys):
    """The library names its parameter; the command line re-words it as the typed flag."""
    from seactl.apps.paper import reproduce
    from seactl.errors import InputError

    with pytest.raises(InputError) as info:
        reproduce(tmp_path / "r", only=["nope"])
    assert info.value.field == "only"
    assert main(["reproduce", "--only", "nope", "--out", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err.startswith("error: invalid --only = 'nope'")
    assert not (tmp_path / "r").exists()
