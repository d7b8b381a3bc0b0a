"""``seactl export``: the per-process controllers in C99 and Python equal seactl's own
sampled controller.

Oracles: (1) the controller of the sampled plan, stepped by
:func:`seactl.simulate.discrete.run_controller` -- itself checked against the actuation
:func:`seactl.simulate.discrete.run_sampled` applied in a closed-loop simulation; (2) for the
high-level process, the hand-derived law ``-Kq q_j[k - n]`` with ``n`` the whole-sample
buffer of the module docstring of :mod:`seactl.simulate.engine`; (3) the compiled C is run as a
separate program through its CSV harness.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.codegen import controllers as export_split
from seactl.codegen import export as ex
from seactl.codegen.parametric import compile_export
from seactl.systems.rigid.model import RIGID_DIAGRAM
from seactl.systems.sea.loops import sea_diagram

TARGET = 1e-9
CC = ex.find_compiler()
NO_CC = "no C compiler (cc, gcc or clang) on PATH: the C part of the export is not checked"
SPLIT = {"embedded": 2000.0, "high-level": 500.0}


def _sea(delays_ms, filters_hz, zero=True):
    named = dict(zip(("torque", "stiffness", "damping"), delays_ms))
    return sea_diagram(zero), sc.design(14, delays_ms=named, filters_hz=filters_hz).sea, \
        {"i_m": 30.0}, 0.1


def _rigid(delays_ms):
    d = sc.rigid(8, delays_ms=dict(zip(("stiffness", "damping"), delays_ms))).rigid
    return RIGID_DIAGRAM, d, {"F_des": d.actuator.max_force}, 0.004


CASES = {
    "sea-filters-delays-split-rates": (_sea((1, 2, 1), (50, 100)), SPLIT),
    "sea-no-filters-delays": (_sea((0.5, 2, 0.5), (None, None)), 1000.0),
    "sea-no-zero-odd-delays": (_sea((1.3, 3.7, 2.2), (80, 150), zero=False), SPLIT),
    "rigid-delays": (_rigid((1.5, 15.5)), 1000.0),
    "rigid-split-rates": (_rigid((2, 1)), SPLIT),
}
MUST_HOLD = 1e-12
"""issue 40: the exported controller equals the sampled simulation to 1e-12 (double)."""


@pytest.mark.parametrize("emulate", [False, True], ids=["no-latency", "emulated"])
@pytest.mark.parametrize("case", ["sea-filters-delays-split-rates", "rigid-split-rates"])
def test_export_equals_the_sampled_simulation(case, emulate):
    """Oracle (1), the sampled simulation of the library (independent code from the
    generated C and Python): without emulated latency, the simulation of the design with
    zero delays; with it, the simulation with the design's effective delays (whole-sample
    buffers, never shorter than requested)."""
    (diagram, design, sat, step), rates = CASES[case]
    ctl, used = compile_export(diagram, design, rates, sat, emulate_latency=emulate)
    buffers = [n for p in ctl.processes for _b, n in p.buffers]
    assert bool(buffers) == emulate          # every case has a delay over one tick
    if not emulate:
        assert all(float(getattr(used, b.delay)) == 0.0 for b in diagram.blocks if b.delay)
    for block, eff in ctl.effective_delays_s.items():
        assert eff >= ctl.requested_delays_s[block] - 1e-15
    langs = ("c", "python") if CC else ("python",)
    v = ex.verify(diagram, used, ctl, rates_hz=rates, saturation=sat, languages=langs,
                  step=step, t_end_s=0.2, random_ticks=400)
    assert set(v.errors) == {f"{lang}/{sig}" for lang in langs
                             for sig in ("simulation", "random")}
    assert v.max_error <= MUST_HOLD, v.errors
    if not CC:
        pytest.skip(NO_CC)
    assert v.compiler and v.compile_s > 0


@pytest.mark.parametrize("case", ["sea-no-filters-delays", "sea-no-zero-odd-delays",
                                  "rigid-delays"])
def test_emulated_latency_python_equals_the_sampled_controller(case):
    """Odd delays, unfiltered derivatives, one rate: the Python export (same algorithm as
    the C) against oracle (1) with the design's effective delays."""
    (diagram, design, sat, step), rates = CASES[case]
    ctl, used = compile_export(diagram, design, rates, sat, emulate_latency=True)
    v = ex.verify(diagram, used, ctl, rates_hz=rates, saturation=sat, languages=("python",),
                  step=step, t_end_s=0.2, random_ticks=400)
    assert v.max_error <= MUST_HOLD, v.errors


@pytest.mark.skipif(CC is None, reason=NO_CC)
def test_float_export_agrees_to_single_precision():
    """--real float: the C in single precision against oracle (1); measured about 1e-5
    of the peak (the SEA's filtered derivatives at 2 kHz), bound 1e-4 (TARGETS)."""
    (diagram, design, sat, step), rates = CASES["sea-filters-delays-split-rates"]
    ctl, used = compile_export(diagram, design, rates, sat)
    v = ex.verify(diagram, used, ctl, rates_hz=rates, saturation=sat, languages=("c",),
                  step=step, t_end_s=0.2, random_ticks=400, real="float")
    assert v.target == ex.TARGETS["float"]
    assert 1e-9 < v.max_error <= ex.TARGETS["float"], v.errors   # float, not double


def test_reference_is_the_closed_loop_simulation():
    """run_controller on the recorded plant signals gives the actuation run_sampled
    applied (one tick later: zero-order hold), saturation included."""
    diagram, design, sat, _ = _sea((1, 2, 1), (50, 100))[0:4]
    ctl = export_split.compile_processes(diagram, design, SPLIT, sat)
    base, applied = export_split.simulation_signals(diagram, design, ctl, 0.3, SPLIT, sat, 0.1)
    ref = export_split.reference_actuation(diagram, design, ctl, base, SPLIT, sat)
    assert np.max(np.abs(ref)) == pytest.approx(30.0)          # the step saturates at first
    np.testing.assert_allclose(ref[:-1], applied[1:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(export_split.run_schedule(ctl, base), ref, rtol=0, atol=1e-11)


def test_high_level_is_the_delayed_stiffness():
    """T_qs = 2.5 ms at 1 kHz: n = (2.5 - 0.5) / 1 = 2 samples, output -Kq q_j[k - 2]."""
    d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2.5, "damping": 0.5},
                  filters_hz=(50, 100))
    ctl = export_split.compile_processes(sea_diagram(), d.sea, 1000.0, {"i_m": 30.0})
    hl = ctl.process("high-level")
    assert hl.inputs == ("q_j",) and hl.buffers == (("Kq_fb", 2),) and hl.A.size == 0
    q = np.random.default_rng(3).standard_normal(50)
    y = export_split.run_process(hl, q[:, None])[:, 0]
    kq = float(d.gains.Kq)
    np.testing.assert_allclose(y, -kq * np.concatenate([[0.0, 0.0], q[:-2]]), rtol=1e-14)
    assert ctl.effective_delays_s["Kq_fb"] == pytest.approx(2.5e-3)


def test_processes_and_schedule():
    """The diagram's split: stiffness on high-level (sent to embedded), the actuation from
    the fastest process; senders run first."""
    d = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1}, filters_hz=(50, 100))
    ctl = export_split.compile_processes(sea_diagram(), d.sea, SPLIT, {"i_m": 30.0})
    assert ctl.names == ("high-level", "embedded")
    emb = ctl.process("embedded")
    assert emb.outputs == ("i_m",) and "tau_fb_from_high_level" in emb.inputs
    assert (emb.rate_hz, emb.period_ticks, ctl.process("high-level").period_ticks) == \
        (2000.0, 1, 4)
    with pytest.raises(sc.InputError, match="single design"):
        export_split.compile_processes(sea_diagram(), sc.design([12, 14]).sea)


@pytest.mark.parametrize("delays", [(0, 0, 0), (0.3, 0.5, 0.2)])
def test_zero_and_sub_tick_delays_export_exactly(delays, tmp_path):
    """With delays under one tick the embedded process uses the high-level message of the
    same tick (senders first).  The assembled wiring's rounding (1e-19 of a gain) once
    read as a dependency the other way, and the export refused every design without a
    stiffness delay over one tick.  Oracle: the sampled controller (verify, 1e-9)."""
    d = sc.design(30, delays_ms=dict(zip(("torque", "stiffness", "damping"), delays)))
    ctl = export_split.compile_processes(sea_diagram(), d.sea, 1000.0, {"i_m": 30.0})
    assert ctl.names == ("high-level", "embedded")
    assert "tau_fb_from_high_level" in ctl.process("embedded").inputs
    assert not any(n.endswith("_from_embedded") for n in ctl.process("high-level").inputs)
    res = d.export(tmp_path / "ctl", lang=("python",), verify=True)
    assert res.verification.max_error <= TARGET


def test_processes_that_need_each_other_within_a_tick_are_refused_clearly():
    """Two processes that do need each other's output within one tick cannot run apart:
    the scheduler's finding becomes an InputError with the delays and the ticks."""
    with pytest.raises(ValueError, match="each other within one tick"):
        export_split._schedule({"embedded": {"high-level"}, "high-level": {"embedded"}})
    d = sc.design(30, delays_ms={"torque": 0, "stiffness": 0.5, "damping": 0}).sea
    ctrl = [b for b in sea_diagram().blocks if b.role != "plant"]
    err = export_split._cyclic(ctrl, d, {"embedded": 1000.0, "high-level": 500.0}, ValueError("x"))
    assert isinstance(err, sc.InputError) and err.value["T_qs"] == "0.5 ms"
    assert "high-level 2 ms" in str(err)


def _load(path, cls):
    spec = importlib.util.spec_from_file_location("exported_" + path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return getattr(mod, cls)()


def test_cli_end_to_end(tmp_path, capsys):
    out = tmp_path / "ctl"
    args = ["export", "--fn", "14", "--t-tau", "1", "--t-qs", "2", "--t-qd", "1", "--f-qd",
            "50", "--f-taud", "100", "--rate", "embedded=2000", "--rate", "high-level=500",
            "--out", str(out), "--json"] + (["--verify"] if CC else [])
    assert main(args) == 0
    res = json.loads(capsys.readouterr().out)
    names = {p.split("/")[-1] for p in res["files"]}
    assert names == {"high_level.h", "high_level.c", "high_level_main.c", "high_level.py",
                     "embedded.h", "embedded.c", "embedded_main.c", "embedded.py",
                     "controller.json", ".seactl-export"}
    assert {p.name for p in out.iterdir()} == names
    if CC:
        assert res["max_error"] <= TARGET and res["compiler"]
    # the written files, not only the verification's copies: Python and C on random input
    doc = json.loads((out / "controller.json").read_text())
    emb = next(p for p in doc["processes"] if p["name"] == "embedded")
    u = np.random.default_rng(5).standard_normal((300, len(emb["inputs"]))) * 0.05
    d14 = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
                    filters_hz=(50, 100))
    # the default export holds no latency: the zero-delay design's sampled controller
    ctl, _ = compile_export(sea_diagram(), d14.sea, SPLIT, {"i_m": 30.0})
    assert doc["emulate_latency"] is False and not ctl.process("embedded").buffers
    ref = export_split.run_process(ctl.process("embedded"), u)
    obj = _load(out / "embedded.py", "Embedded")
    y = np.array([[obj.step(dict(zip(obj.INPUTS, row)))["i_m"]] for row in u])
    assert export_split.relative_error(y, ref) <= TARGET
    if not CC:
        pytest.skip(NO_CC)
    subprocess.run([CC, *export_split.CFLAGS, "embedded.c", "embedded_main.c", "-o", "emb"],
                   cwd=out,
                   check=True)
    csv = ",".join(emb["inputs"]) + "\n" + "".join(",".join(repr(float(v)) for v in r) + "\n"
                                                    for r in u)
    text = subprocess.run([str(out / "emb")], input=csv, capture_output=True, text=True,
                          check=True).stdout
    y_c = np.loadtxt(text.splitlines()[1:], delimiter=",").reshape(-1, 1)
    assert export_split.relative_error(y_c, ref) <= TARGET


def test_cli_never_touches_other_files(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    assert main(["export", "--fn", "14", "--out", str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "not empty" in err
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    # an export may be replaced by another; --lang json writes only the JSON (+ marker)
    out = tmp_path / "ctl"
    assert main(["export", "--system", "rigid", "--fn", "8", "--out", str(out),
                 "--lang", "json"]) == 0
    assert main(["export", "--system", "rigid", "--fn", "8", "--t-s", "2", "--out", str(out),
                 "--lang", "json"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".seactl-export", "controller.json"]
    doc = json.loads((out / "controller.json").read_text())
    assert doc["parameters"]["T_s"] == pytest.approx(2e-3)


@pytest.mark.parametrize("args, needle", [
    (["--lang", "rust"], "--lang"),
    (["--rate", "embedded=abc"], "--rate"),
    (["--rate", "embedded=3000", "--rate", "high-level=1000", "--rate", "x=1"], "rate"),
    (["--fn", "12", "14"], "one --fn"),
    (["--verify", "--cc", "no-such-compiler-xyz"], "no C compiler"),
    (["--real", "quad"], "--real"),
])
def test_cli_bad_input_one_line_exit_2(tmp_path, capsys, args, needle):
    out = tmp_path / "ctl"
    full = ["export", "--out", str(out)] + (["--fn", "14"] if "--fn" not in args else []) + args
    assert main(full) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err
    assert not out.exists()


@pytest.mark.parametrize("name, emulate", [("sea-velocity", False), ("two-mass-notch", False),
                                           ("sea-dob", True)])
def test_loop_file_export_equals_its_sampled_controller(tmp_path, capsys, name, emulate):
    """``seactl export --loop FILE --verify``: a user loop with three processes at their own
    rates (sea-velocity: 500 Hz / 1 kHz / 10 kHz), a one-process drive loop, and a
    disturbance observer (an algebraic loop inside the embedded process, solved by the
    network inverse); the exported C and Python against oracle (1) with zero delays, or
    with the file's effective delays under --emulate-latency."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "loops" / f"{name}.toml"
    args = ["export", "--loop", str(path), "--out", str(tmp_path / "x"), "--json"]
    args += ["--emulate-latency"] if emulate else []
    assert main(args + (["--verify"] if CC else ["--lang", "python,json"])) == 0
    res = json.loads(capsys.readouterr().out)
    loop = sc.load_loop(path)
    assert [p["name"] for p in res["processes"]] and \
        {p["name"] for p in res["processes"]} == set(loop.processes)
    rates = {p["name"]: p["rate_hz"] for p in res["processes"]}
    assert rates == {n: p.rate_hz for n, p in loop.processes.items()}
    assert res["emulate_latency"] is emulate
    assert bool(res["emulated_delays_s"]) is emulate
    if CC:
        assert res["max_error"] <= MUST_HOLD
    api = loop.export(tmp_path / "api", lang="json", emulate_latency=emulate)  # the API
    assert [p.name for p in api.controllers.processes] == [p["name"] for p in res["processes"]]
    doc = json.loads((tmp_path / "api" / "controller.json").read_text())
    assert doc["emulate_latency"] is emulate and doc["real"] == "double"
    assert api.to_dict()["emulated_delays_s"] == res["emulated_delays_s"]
