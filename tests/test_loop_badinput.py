"""Bad input in loop files and their commands: every case an exit 2 with one line
``error: ...`` (or a seactl error from the library), never a traceback, a hang, a silently
ignored option or a silent result.

Oracles: the documented contract (docs/loops.md: options of the built-in loops are refused
with ``--loop``; README: one-line errors, exit 2), the limits of :mod:`seactl.base.limits`
counted by hand on the generated files, a factored-form evaluation of the loop transfer
(numpy, brentq) for a long chain that must still work, the definition of a Latin
hypercube, and a direct analysis of each sampled point.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.base.limits import MAX_LOOP_BLOCKS, MAX_LOOP_ORDER, MAX_NESTING, derive_seconds

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "loops"
RIGID = str(EXAMPLES / "rigid.toml")


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert "Traceback" not in err[0]
    return err[0]


def _rigid_with(tmp_path, old: str, new: str, append: str = "") -> str:
    text = Path(RIGID).read_text()
    assert old in text
    path = tmp_path / "loop.toml"
    path.write_text(text.replace(old, new, 1) + append)
    return str(path)


def chain(fs_hz, gain: float = 5.0, delay_ms: float = 1.0) -> str:
    """A loop file: gain with a delay, first-order filters in series at ``fs_hz``, plant
    1/(s + 1), unit sensor, one break."""
    t = ['name = "chain"', "[processes.cpu]", "rate_hz = 1000", "[signals]",
         'inputs = ["r"]', 'reference = "r"', 'output = "y"', "[[blocks]]", 'name = "c"',
         'kind = "gain"', 'input = ["r", "-y_m"]', 'output = "x0"', f"gain = {gain}",
         f"delay_ms = {delay_ms}"]
    for i, f in enumerate(fs_hz):
        t += ["[[blocks]]", f'name = "f{i}"', 'kind = "lowpass1"', f'input = "x{i}"',
              f'output = "x{i + 1}"', f"f_hz = {f}"]
    t += ["[[blocks]]", 'name = "p"', 'kind = "plant_tf"', f'input = "x{len(fs_hz)}"',
          'output = "y"', "num = [1]", "den = [1, 1]", "[[blocks]]", 'name = "s"',
          'kind = "sensor"', 'input = "y"', 'output = "y_m"', "[[breaks]]", 'name = "main"',
          'signal = "y_m"']
    return "\n".join(t) + "\n"


# ------------------------------------------------------------------ tracebacks
@pytest.mark.parametrize("expr, needle", [
    ("min(K)", "min() with at least 2 arguments (it has 1)"),
    ("sqrt(K, K, K)", "sqrt() with 1 argument (it has 3)"),
    ("hypot(K)", "hypot() with 2 arguments (it has 1)"),
    ("exp()", "exp() with 1 argument (it has 0)"),
])
def test_a_call_with_the_wrong_number_of_arguments_is_one_line(expr, needle, tmp_path,
                                                               capsys):
    path = _rigid_with(tmp_path, 'gain = "K"', f'gain = "{expr}"')
    assert main(["analyze", "--loop", path]) == 2
    assert f"block 'K_ref', field 'gain' = '{expr}': {needle}" in _one_line(capsys)


def test_min_and_max_take_any_number_of_arguments():
    """Oracle: Python's min and max of the same numbers."""
    from seactl.userloop.expressions import CONSTANTS, parse_expr

    env = {"a": 3.0, "b": -2.0, "c": 7.5, **CONSTANTS}
    for f, ref in (("min", min), ("max", max)):
        e = parse_expr(f"{f}(a, b, c, 4)", "x.toml", "w", ["a", "b", "c"])
        assert float(e(env)) == ref(3.0, -2.0, 7.5, 4.0)


@pytest.mark.parametrize("value, needle", [
    ("[" * 3000 + "]" * 3000, f"key 'variables.m' (line 11): arrays and tables nested at "
                              f"most {MAX_NESTING} deep"),
    ("{a=" * 3000 + "1" + "}" * 3000, "key 'variables.m' (line 11): arrays and tables"),
    ("[" * (MAX_NESTING + 1) + "]" * (MAX_NESTING + 1), "key 'variables.m' (line 11)"),
    ('"' + "1+" * 600 + '1"', "an expression of at most 1000 characters"),
    ('"' + "1+" * 40 + '1"', "an expression nested at most 32 deep"),
    ('"' + "(" * 300 + "1" + ")" * 300 + '"', "nested at most 32 deep"),
    ('"' + "-" * 900 + '1"', "an expression nested at most 32 deep"),
])
def test_deep_nesting_is_refused_naming_the_field_and_the_limit(value, needle, tmp_path,
                                                                capsys):
    """Once a RecursionError (the TOML parser, Python's parser or the evaluator)."""
    path = _rigid_with(tmp_path, "m = 256.0", f"m = {value}")
    if value.startswith('"'):  # an expression: it belongs under [parameters]
        path = _rigid_with(tmp_path, 'K = "m * (2*pi*fn)^2"', f"K = {value}")
    assert main(["analyze", "--loop", path]) == 2
    assert needle in _one_line(capsys)


def test_a_number_beyond_the_floating_point_range_is_one_line(tmp_path, capsys):
    """TOML integers are unbounded; float(10**400) once raised OverflowError."""
    path = _rigid_with(tmp_path, 'gain = "K"', "gain = 1" + "0" * 400)
    assert main(["analyze", "--loop", path]) == 2
    assert "a number within the floating-point range" in _one_line(capsys)


def test_deep_dotted_tables_are_refused(tmp_path, capsys):
    path = _rigid_with(tmp_path, "x", "x", "\n[" + ".".join(["a"] * 5000) + "]\nx = 1\n")
    assert main(["analyze", "--loop", path]) == 2
    assert f"key 'a.a.a.a.a.a.a.a.a.a.a.a.a.a.a.a.a': arrays and tables nested at most " \
           f"{MAX_NESTING} deep" in _one_line(capsys)


@pytest.mark.parametrize("line, needle", [
    ("f_max_hz = 1e308", "analysis.f_max_hz = 1e+308: input should be less than or equal "
                         "to 10000000"),
    ("f_min_hz = 1e-308", "analysis.f_min_hz = 1e-308: input should be greater than or "
                          "equal to 0.000001"),
])
def test_an_analysis_range_beyond_the_documented_one_is_refused(line, needle, tmp_path,
                                                                capsys):
    """Once an OverflowError (2 pi 1e308 = inf points); the range is limits.RANGES'."""
    path = _rigid_with(tmp_path, "x", "x", f"\n[analysis]\n{line}\n")
    assert main(["analyze", "--loop", path]) == 2
    assert needle in _one_line(capsys)


# ------------------------------------------------------------------ unbounded work
def test_a_long_chain_is_refused_up_front_with_an_estimate(tmp_path, capsys):
    """300 filters in series: 303 blocks by hand count, refused before any derivation."""
    path = tmp_path / "chain.toml"
    path.write_text(chain([200.0] * 300))
    t0 = time.perf_counter()
    assert main(["analyze", "--loop", str(path)]) == 2
    assert time.perf_counter() - t0 < 10
    line = _one_line(capsys)
    assert f"at most {MAX_LOOP_BLOCKS} blocks (this loop has 303" in line
    assert f"about {derive_seconds(303) / 60:.3g} min" in line


def test_a_high_order_loop_is_refused_with_its_order(tmp_path, capsys):
    """40 first-order filters and a first-order plant: order 41 by hand."""
    path = tmp_path / "chain.toml"
    path.write_text(chain([200.0] * 40))
    assert main(["analyze", "--loop", str(path)]) == 2
    assert f"a loop of order at most {MAX_LOOP_ORDER} (this one has order 41" in \
        _one_line(capsys)


def test_a_chain_at_the_order_limit_is_analysed_exactly(tmp_path):
    """31 first-order filters spread over four decades, the plant: order 32 (the limit).
    Oracle: L evaluated in factored form, its crossover by brentq."""
    from scipy.optimize import brentq

    fs = [10.0 ** (k % 4 + 1) for k in range(31)]
    path = tmp_path / "chain.toml"
    path.write_text(chain(fs))

    def L(w):
        s = 1j * w
        filters = np.prod([s / (2 * np.pi * f) + 1 for f in fs], axis=0)
        return 5.0 * np.exp(-1e-3 * s) / (s + 1) / filters

    wc = brentq(lambda w: abs(L(w)) - 1, 1e-3, 1e3, xtol=1e-14)
    phase = np.unwrap(np.angle(L(np.linspace(1e-4, wc, 20001))))[-1]
    m = sc.load_loop(path).analyze(jitter=False)["main"].margins
    assert float(m.crossover_hz) == pytest.approx(wc / (2 * np.pi), rel=1e-9)
    assert float(m.phase_margin_deg) == pytest.approx(180 + np.degrees(phase), abs=1e-8)
    assert bool(m.stable)


def test_too_many_parameters_and_a_huge_file_are_refused_up_front(tmp_path, capsys):
    """A chain of 3,000 parameters (their ordering grows as the cube of the count) and a
    2 MiB file; rigid.toml's 6 names by hand count, plus 3,000."""
    chain_ = "".join(f'P{i} = "P{i - 1} + 1"\n' for i in range(1, 3000)) + 'P0 = "m"\n'
    path = _rigid_with(tmp_path, "[parameters]\n", "[parameters]\n" + chain_)
    t0 = time.perf_counter()
    assert main(["analyze", "--loop", path]) == 2
    assert time.perf_counter() - t0 < 10
    assert "at most 256 names (this loop has 3006)" in _one_line(capsys)
    path = _rigid_with(tmp_path, "x", "x", "#" * (2 << 20))
    assert main(["analyze", "--loop", path]) == 2
    assert "a loop file of at most 1 MiB (this one has 2 MiB)" in _one_line(capsys)


def test_a_huge_loop_impedance_is_refused_with_its_estimate(capsys):
    """9,901 designs x 1e6 frequencies x 640 B (limits.FREQ_BYTES_PER_POINT) = 5.76 TiB."""
    t0 = time.perf_counter()
    assert main(["impedance", "--loop", RIGID, "--set", "fn=1:100:0.01", "--freq",
                 "1:1000:1000000"]) == 2
    assert time.perf_counter() - t0 < 10
    assert "9,901 design(s) of the loop at 1,000,000 frequencies needs about 5.76 TiB" in \
        _one_line(capsys)


def test_overflowing_coefficients_are_named_not_a_pole_at_inf(tmp_path, capsys):
    path = tmp_path / "huge.toml"
    path.write_text(chain([200.0], gain=1e300).replace("den = [1, 1]", "den = [1e-300, 1]"))
    assert main(["analyze", "--loop", str(path)]) == 2
    line = _one_line(capsys)
    assert "coefficients that overflow" in line and "inf rad/s" not in line


# ------------------------------------------------------------------ silent results
@pytest.mark.parametrize("f", [np.nan, -1.0, 0.0, np.inf, [1.0, np.nan], "2ms", [],
                               [[1.0, -2.0]]])
def test_impedance_at_an_invalid_frequency_names_f_hz(f):
    loop = sc.load_loop(RIGID)
    with pytest.raises(sc.InputError) as exc:
        loop.impedance(f)
    assert exc.value.field == "f_hz"


@pytest.mark.parametrize("f", [0.0, -1.0, np.nan])
def test_frequency_response_at_an_invalid_frequency_names_f_hz(f):
    """At s = 0 the loop's free integrator makes every transfer 0/0 (NaN)."""
    with pytest.raises(sc.InputError) as exc:
        sc.load_loop(RIGID).frequency_response("x", "x_des", f)
    assert exc.value.field == "f_hz"


# ------------------------------------------------------------------ ignored options
@pytest.mark.parametrize("argv, flag", [
    (["step", "--fn", "20"], "--fn"), (["step", "--t-qs", "1"], "--t-qs"),
    (["step", "--f-qd", "50"], "--f-qd"), (["step", "--rate", "500"], "--rate"),
    (["step", "--mode", "sampled", "--runs", "3"], "--runs"), (["impulse", "--fn", "20"], "--fn"),
    (["impulse", "--mode", "sampled", "--saturation", "1"], "--saturation"),
    (["impedance", "--t-qs", "2"], "--t-qs"), (["impedance", "--units", "linear"], "--units"),
    (["impedance", "--model", "paper"], "--model"),
    (["export", "--out", "ex", "--fn", "20"], "--fn"),
    (["export", "--out", "ex", "--system", "rigid"], "--system"),
    (["export", "--out", "ex", "--saturation", "1"], "--saturation"),
    (["place", "--high-latency", "5"], "--high-latency"),
    (["run", "--fn", "20"], "--fn"),
])
def test_an_option_of_the_built_in_loops_is_refused_with_loop(argv, flag, tmp_path, capsys,
                                                              monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--loop", RIGID]) == 2
    assert _one_line(capsys).startswith(f"error: invalid {flag} = 'given': must be absent "
                                        "with --loop")
    assert list(tmp_path.iterdir()) == []


def test_impulse_band_applies_to_a_loop(capsys):
    """Oracle: the recovery time recomputed from the printed response (last sample
    outside band x peak deviation, then the next sample)."""
    got = {}
    for band in ("0.05", "0.3"):
        assert main(["impulse", "--loop", RIGID, "--band", band, "--json", "--full"]) == 0
        out = json.loads(capsys.readouterr().out)
        y, t = np.asarray(out["x"]), np.asarray(out["t_s"])
        dev = np.abs(y - y[0])
        last = np.nonzero(dev > float(band) * dev.max())[0][-1]
        got[band] = out["metrics"]["recovery_time_s"]
        assert t[last] <= got[band] <= t[last + 1]
    assert got["0.3"] < got["0.05"]


# ------------------------------------------------------------------ sweep --loop
def test_a_huge_loop_sweep_needs_yes(tmp_path, capsys, monkeypatch):
    """1e6 x 1000 points = 1e9 > 1e8, as for built-in sweeps; nothing written."""
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "--loop", RIGID, "--set", "fn=1:1e6:1", "--set",
                 "f_v=1:1000:1", "--out", "sw"]) == 2
    line = _one_line(capsys)
    assert "the sweep has 1e+09 points" in line and "add --yes" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("extra, flag", [
    (["--out", ""], "--out"), (["--out", "sw", "--scheduler", "tcp://x:1"], "--scheduler"),
    (["--out", "sw", "--workers", "2"], "--workers"), (["--out", "sw", "--plot", "fn,f_v"],
                                                       "--plot"),
    (["--out", "sw", "--z-freq", "10"], "--z-freq"), (["--out", "sw", "--resume"], "--resume"),
    (["--out", "sw", "--fn", "14"], "--fn"), (["--out", "sw", "--plot-file", "p.png"],
                                              "--plot-file"),
    (["--out", "sw", "--n", "5"], "--n"), (["--out", "sw", "--seed", "3"], "--seed"),
])
def test_a_loop_sweep_refuses_what_it_cannot_do(extra, flag, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "--loop", RIGID, "--set", "fn=4,8", *extra]) == 2
    assert _one_line(capsys).startswith(f"error: invalid {flag} = ")
    assert list(tmp_path.iterdir()) == []


def test_a_latin_hypercube_loop_sweep(tmp_path, capsys):
    """--sample lhs --n 5: one point per fifth of each interval (the definition of a Latin
    hypercube), each analysed as the loop at that point (oracle: load_loop at those
    values); the same seed draws the same points, another seed others."""
    args = ["sweep", "--loop", RIGID, "--set", "fn=4,12", "--set", "f_v=20:80:30",
            "--sample", "lhs", "--n", "5", "--json"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_points"] == 5 and summary["sampling"] == "lhs"
    t = sc.read_sweep(tmp_path / "a").to_pydict()
    for name, (lo, hi) in (("fn", (4, 12)), ("f_v", (20, 80))):
        v = np.asarray(t[name])
        assert sorted(np.floor((v - lo) / (hi - lo) * 5).astype(int)) == [0, 1, 2, 3, 4]
    ref = sc.load_loop(RIGID, fn=np.array(t["fn"]), f_v=np.array(t["f_v"])).analyze(
        jitter=False)["position"].margins
    np.testing.assert_allclose(t["position_phase_margin_deg"], ref.phase_margin_deg,
                               atol=1e-9)
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert main([*args, "--seed", "1", "--out", str(tmp_path / "c")]) == 0
    capsys.readouterr()
    b, c = (sc.read_sweep(tmp_path / x).to_pydict()["fn"] for x in "bc")
    assert b == t["fn"] and c != t["fn"]


def test_a_loop_sweep_without_ranges_is_one_point(tmp_path, capsys):
    """Once a 0-d index error (found by tests/test_userloop.py's fuzz).  Oracle: the loop
    analysed at the file's values."""
    assert main(["sweep", "--loop", RIGID, "--set", "fn=6", "--out", str(tmp_path / "a"),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_points"] == 1
    t = sc.read_sweep(tmp_path / "a").to_pydict()
    ref = sc.load_loop(RIGID, fn=6.0).analyze(jitter=False)["position"].margins
    assert t["position_phase_margin_deg"] == pytest.approx([float(ref.phase_margin_deg)],
                                                           abs=1e-9)


def test_an_empty_loop_path_is_refused_not_a_built_in_sweep(tmp_path, capsys, monkeypatch):
    """--loop '' once started a built-in sweep (found by tests/test_userloop.py's fuzz)."""
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "--loop", "", "--out", "out"]) == 2
    assert "an existing .toml loop file" in _one_line(capsys)
    assert list(tmp_path.iterdir()) == []
