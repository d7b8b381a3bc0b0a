"""``seactl roots --dde FILE``: the table (units), JSON (the API's records), ``--set`` batches
and one-line errors with exit 2.

Oracles: ``sc.load_dde(FILE).roots(count=)`` for the same file (every front end goes through
the public API), the Lambert W value W_0(-1) (mpmath) for the scalar example, and the CLI
error contract.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import mpmath
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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
    assert out["kind"] == "quasi-polynomial" and out["loops"] == ["tau1"]
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


DDE_NUM = ["0.0", "-1.0", "1.0", "0.5", "-2.5", "1e-300", "1e300", "-1e300", "1e6", "3"]
DDE_DELAYS = ["0.0", "1e-300", "0.001", "1.0", "30.0", "1000.0", "1e6", "1e300", "-1.0"]
DDE_SETS = ["1", "0", "-1", "nan", "inf", "1e300", "0:2:0.5", "x", "1,2,3", "1e-300"]


@st.composite
def dde_file(draw) -> str:
    """A random delay-equation or quasi-polynomial file: sizes 1-3, one or two terms, edge
    values, delays from 0 to 1e300 s (and a negative one), sums of named delays."""
    num, delay = st.sampled_from(DDE_NUM), st.sampled_from(DDE_DELAYS)
    if draw(st.booleans()):
        n = draw(st.integers(1, 3))

        def mat():
            return "[" + ", ".join("[" + ", ".join(draw(num) for _ in range(n)) + "]"
                                   for _ in range(n)) + "]"
        text, key = f"a0 = {mat()}\n", "a"
        coeff = mat
    else:
        rest = ", ".join(draw(num) for _ in range(draw(st.integers(0, 3))))
        text, key = f"p0 = [1.0, {rest}]\n", "p"

        def coeff():
            return "[" + ", ".join(draw(num) for _ in range(draw(st.integers(1, 3)))) + "]"
    named = draw(st.booleans())
    if named:
        text += f"[delays_s]\ntau1 = {draw(delay)}\ntau2 = {draw(delay)}\n"
    for _ in range(draw(st.integers(1, 2))):
        text += f"[[term]]\n{key} = {coeff()}\n"
        text += (f'delay = "{draw(st.sampled_from(["tau1", "tau1 + tau2", "2*tau2", "tau3"]))}"\n'
                 if named else f"delay_s = {draw(delay)}\n")
    return text


def _check_dde_vector(monkeypatch, text, extra, sets):
    from test_fuzz import check_vector

    monkeypatch.setenv("SEACTL_MAX_SECONDS", "10")
    with tempfile.TemporaryDirectory(prefix="seactl-dde-") as tmp:
        path = Path(tmp) / "eq.toml"
        path.write_text(text)
        args = ["roots", "--dde", str(path), *extra]
        for k, v in enumerate(sets):
            args += ["--set", f"tau{k + 1}={v}"]
        check_vector(args)


VECTORS = (dde_file(), st.sampled_from([[], ["--json"], ["--count", "3"]]),
           st.lists(st.sampled_from(DDE_SETS), max_size=2))


@settings(max_examples=15, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(*VECTORS)
def test_fuzz_dde_files_quick(monkeypatch, text, extra, sets):
    """A few random delay-equation files (deterministic) through ``seactl roots --dde``:
    the command-line contract of tests/test_fuzz.py (exit 0 or 2, one line, no traceback
    or warning, time bound)."""
    _check_dde_vector(monkeypatch, text, extra, sets)


@pytest.mark.fuzz
@settings(max_examples=1000, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(*VECTORS)
def test_fuzz_dde_files(monkeypatch, text, extra, sets):
    """The same with 1000 random files (``pytest -m fuzz``)."""
    _check_dde_vector(monkeypatch, text, extra, sets)


def test_chart_and_delay_margin_take_a_dde_file(capsys, tmp_path):
    # Oracle: the API on the same file (sc.load_dde(...).delay_margin() and
    # .stability_chart(...)); a design option beside --dde is refused in one line.
    path = "examples/dde/gkc-2x2.toml"
    assert main(["delay-margin", "--dde", path, "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["designs"][0]
    assert got["delay_margin_s"] == pytest.approx(
        float(sc.load_dde(path).delay_margin().delay_margin_s), rel=1e-9)  # (JSON: 10 digits)
    two = "examples/dde/two-delays.toml"
    png = tmp_path / "chart.png"
    assert main(["chart", "--dde", two, "--delays", "tau1,tau2", "--max-s", "10,10",
                 "--resolution", "300", "--plot", str(png), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ref = sc.load_dde(two).stability_chart(("tau1", "tau2"), (10, 10), resolution=300)
    assert out["system"] == "dde" and out["design"]["stable"] == bool(ref.design_stable)
    assert png.stat().st_size > 0
    assert main(["chart", "--dde", two, "--delays", "tau1,tau2", "--max-s", "1,1",
                 "--fn", "3"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "--fn" in err
