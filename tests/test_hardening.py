"""Hardening: seactl never destroys what it did not write, click's errors use seactl's one-line
format, and inputs that once crashed the core are handled.

Oracles: the file system before and after (bytes and listings), click's own exit status for
usage errors, and the documented error contract (one line ``error: ...``, exit 2).
"""

from __future__ import annotations

import pytest

from seactl.apps.cli import main
from seactl.errors import OutputError


def _stderr_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("error: ") and "Traceback" not in err[0]
    return err[0]


def test_reproduce_refuses_a_users_directory_and_leaves_it_untouched(tmp_path, capsys):
    user = tmp_path / "mydocs"
    user.mkdir()
    (user / "thesis.tex").write_text("precious")
    assert main(["reproduce", "--out", str(user), "--only", "feasibility"]) == 2
    assert "mydocs" in _stderr_line(capsys)
    assert sorted(p.name for p in user.iterdir()) == ["thesis.tex"]
    assert (user / "thesis.tex").read_text() == "precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mydocs"]  # no temp leftovers


def test_reproduce_refuses_a_file_and_the_working_directory(tmp_path, capsys, monkeypatch):
    f = tmp_path / "notes.txt"
    f.write_text("keep")
    assert main(["reproduce", "--out", str(f), "--only", "feasibility"]) == 2
    _stderr_line(capsys)
    assert f.read_text() == "keep"
    monkeypatch.chdir(tmp_path)
    for out in ("", "."):
        assert main(["reproduce", "--out", out, "--only", "feasibility"]) == 2
        _stderr_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_reproduce_replaces_its_own_report_and_fills_an_empty_directory(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["reproduce", "--out", str(empty), "--only", "feasibility"]) == 0
    assert (empty / "claims.json").is_file() and (empty / ".seactl-report").is_file()
    assert main(["reproduce", "--out", str(empty), "--only", "feasibility"]) == 0
    assert (empty / "index.html").stat().st_mode & 0o777 == 0o666 & ~_umask()
    assert empty.stat().st_mode & 0o777 == 0o777 & ~_umask()


def _umask() -> int:
    import os

    mask = os.umask(0)
    os.umask(mask)
    return mask


@pytest.mark.parametrize("argv, needle", [
    (["gains", "--t-qs", "2ms"], "'--t-qs'"),
    (["gains", "--fnn", "3"], "Did you mean '--fn'"),
    (["step", "--mode", "foo"], "'--mode'"),
    (["nosuch"], "nosuch"),
    (["gains", "--t-qs"], "--t-qs"),
])
def test_click_errors_are_one_line_exit_2(argv, needle, capsys):
    assert main(argv) == 2
    assert needle in _stderr_line(capsys)


@pytest.mark.parametrize("argv", [["gains", "--zeta2", "7", "--json"],
                                  ["gains", "--ratio", "100", "--json"]])
def test_extreme_pole_placement_does_not_crash(argv, capsys):
    """Once a write into a broadcast (read-only) view in the margin scan."""
    assert main(argv) in (0, 2)
    assert "Traceback" not in capsys.readouterr().err


# ------------------------------------------------------------------ outputs as a set
def _listing(root) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.mark.parametrize("argv", [
    ["step", "--csv", "s.csv", "--plot", "s.txt"],
    ["impedance", "--fn", "30", "--csv", "z.csv", "--plot", "/proc/x.png"],
    ["zregion", "--fn", "14", "--csv", "z.csv", "--plot", "nodir/z.png"],
    ["latency-map", "--n", "3", "--csv", "m.csv", "--plot", "."],
    ["step", "--csv", "s.csv", "--plot", "s.png", "--t-end", "1e-9"],
])
def test_a_bad_output_or_input_leaves_no_file(argv, tmp_path, monkeypatch, capsys):
    """Oracle: the directory listing before and after (empty)."""
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    _stderr_line(capsys)
    assert _listing(tmp_path) == []


def test_a_failure_while_writing_removes_every_output(tmp_path, monkeypatch, capsys):
    """The CSV is written, then saving the figure fails: neither file is left."""
    import seactl.base.outputs

    def boom(fig, tmp, fmt, dpi):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(seactl.base.outputs, "save_figure_to", boom)
    monkeypatch.chdir(tmp_path)
    assert main(["step", "--csv", "s.csv", "--plot", "s.png"]) == 2
    assert _stderr_line(capsys) == "error: cannot write s.png: no space left on device"
    assert _listing(tmp_path) == []


def test_outputs_honour_suffix_and_umask(tmp_path, monkeypatch, capsys):
    """Oracles: the SVG's XML header, the PDF magic bytes, and 0666 & ~umask."""
    monkeypatch.chdir(tmp_path)
    assert main(["robust", "--ij", "20%", "--n", "50", "--plot", "h.svg", "--json"]) == 0
    assert (tmp_path / "h.svg").read_bytes().startswith(b"<?xml")
    assert main(["step", "--plot", "s.pdf", "--csv", "s.csv", "--json"]) == 0
    assert (tmp_path / "s.pdf").read_bytes().startswith(b"%PDF")
    for name in ("h.svg", "s.pdf", "s.csv"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~_umask()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.svg", "s.csv", "s.pdf"]


@pytest.mark.parametrize("arg, reason", [("adir.csv", "is a directory"),
                                        ("fifo.csv", "not a regular file"),
                                        ("nodir/x.csv", "does not exist")])
def test_output_path_errors_name_the_path(arg, reason, tmp_path, monkeypatch, capsys):
    import os

    monkeypatch.chdir(tmp_path)
    (tmp_path / "adir.csv").mkdir()
    os.mkfifo(tmp_path / "fifo.csv")   # replacing a special file would be data loss
    assert main(["step", "--csv", arg]) == 2
    line = _stderr_line(capsys)
    assert line.startswith(f"error: cannot write {arg}") and reason in line


# ------------------------------------------------------------------ bounds
@pytest.mark.parametrize("argv, needles", [
    (["step", "--mode", "sampled", "--rate", "1e9"], ["--rate", "1 MHz"]),
    # every step is recorded (as sc.design(...).step() does): 1e-6 ms exceeds the memory,
    # 1e-5 ms only the time
    (["step", "--t-qs", "1e-6"], ["needs about", "GiB"]),
    (["step", "--t-qs", "1e-5"], ["would take about", "SEACTL_MAX_SECONDS"]),
    (["gains", "--fn", "10:1e7:1e-3"], ["--fn", "1e+10 values", "GiB"]),
    (["impedance", "--freq", "1:10:1e10"], ["--freq", "1e+10 values"]),
    (["gains", "--fn", "10:inf:1"], ["--fn", "finite"]),
    (["place", "--high-latency", "1e9"], ["--high-latency", "1000"]),
    (["step", "--mode", "sampled", "--rate", "10", "--t-end", "1"], ["20 samples"]),
    (["sweep", "--fn", "10:40:0.001", "--gs", "0.1:3:0.001", "--t-qs", "0:20:0.5", "--out", "b"],
     ["3.57e+09 points", "--yes"]),
])
def test_bounds_refuse_with_the_estimate(argv, needles, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    line = _stderr_line(capsys)
    for needle in needles:
        assert needle in line
    assert _listing(tmp_path) == []


def test_library_errors_name_the_parameter():
    from seactl.base.limits import check_range
    from seactl.errors import InputError
    from seactl.sweep.spec import SweepSpec

    with pytest.raises(InputError, match="^invalid rate_hz = "):
        check_range("rate_hz", 1e9, "rate_hz")
    with pytest.raises(InputError, match="^invalid seed = -1"):
        SweepSpec(sc_actuator(), (("fn_hz", (14.0,)),), sampling="random", n_samples=5,
                  seed=-1)


def sc_actuator():
    from seactl.systems.sea.actuators import load_sea

    return load_sea("ut-sea")


# ------------------------------------------------------------------ sweeps
def test_sweep_refuses_resume_with_overwrite_and_explains_a_corrupt_manifest(
        tmp_path, capsys):
    out = tmp_path / "sw"
    base = ["sweep", "--fn", "14", "--out", str(out), "--workers", "0", "--quiet"]
    assert main([*base, "--resume", "--overwrite"]) == 2
    assert "--overwrite" in _stderr_line(capsys) and not out.exists()
    assert main([*base, "--json"]) == 0 and capsys.readouterr()
    (out / "_manifest.json").write_text("{corrupt")
    assert main(base) == 2
    line = _stderr_line(capsys)
    assert "corrupt" in line and "--overwrite" in line
    assert main([*base, "--overwrite", "--json"]) == 0
    assert '"status": "complete"' in (out / "_manifest.json").read_text()


@pytest.mark.parametrize("extra", [["--scheduler", "tcp//nowhere"],
                                   ["--sample", "random", "--n", "5", "--seed", "-1"]])
def test_sweep_leaves_nothing_for_a_bad_scheduler_or_seed(extra, tmp_path, capsys):
    assert main(["sweep", "--fn", "14", "--out", str(tmp_path / "sw"), "--workers", "0",
                 *extra]) == 2
    _stderr_line(capsys)
    assert _listing(tmp_path) == []


def test_sweep_ctrl_c_prints_one_line_and_keeps_finished_chunks(tmp_path, monkeypatch,
                                                               capsys):
    """Ctrl-C arrives while the third chunk is computed (in process)."""
    import importlib

    sw = importlib.import_module("seactl.sweep.engine")   # the module (seactl.sweep is a function)
    real = sw.evaluate_chunk
    calls = []

    def interrupted(spec, i):
        calls.append(i)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(spec, i)

    monkeypatch.setattr(sw, "evaluate_chunk", interrupted)
    out = tmp_path / "sw"
    assert main(["sweep", "--fn", "12:20:1", "--chunk-size", "2", "--out", str(out),
                 "--workers", "0", "--quiet"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("interrupted: 2 of 5 chunks")
    assert sorted(p.name for p in out.glob("part-*")) == ["part-00000.parquet",
                                                          "part-00001.parquet"]


def test_binary_actuator_toml_is_one_line(tmp_path, capsys):
    f = tmp_path / "bin.toml"
    f.write_bytes(bytes(range(256)))
    for cmd in (["gains"], ["place"], ["sweep", "--out", str(tmp_path / "o")]):
        assert main([*cmd, "--actuator", str(f)]) == 2
        assert "binary" in _stderr_line(capsys)


# ------------------------------------------------------------------ data loss
def _trace(path, text="latency_ms\n1.0\n2.0\n3.0\n"):
    path.write_text(text)
    return path


def test_an_output_naming_an_input_is_refused(tmp_path, monkeypatch, capsys):
    """Oracle: the trace's bytes before and after, and the listing (no temporary left)."""
    monkeypatch.chdir(tmp_path)
    trace = _trace(tmp_path / "trace.csv")
    before = trace.read_bytes()
    assert main(["step", "--mode", "sampled", "--t-end", "0.1", "--latency",
                 "stiffness=hist:trace.csv", "--csv", "trace.csv"]) == 2
    line = _stderr_line(capsys)
    assert "trace.csv" in line and "input" in line
    assert trace.read_bytes() == before and _listing(tmp_path) == ["trace.csv"]


def test_inputs_are_recorded_only_during_a_command(tmp_path):
    """In a Python session each call is its own command: a trace read by one call may be
    written by a later one.  Oracle: the bytes written."""
    from seactl.base.outputs import command_inputs, write_atomic
    from seactl.latency.models import Empirical

    trace = _trace(tmp_path / "trace.csv")
    Empirical.from_csv(trace)
    write_atomic(trace, "latency_ms\n4.0\n")
    assert trace.read_text() == "latency_ms\n4.0\n"
    with command_inputs(), pytest.raises(OutputError, match="an input of this command"):
        Empirical.from_csv(trace)
        write_atomic(trace, "latency_ms\n5.0\n")
    assert trace.read_text() == "latency_ms\n4.0\n"


def test_a_read_only_output_is_not_replaced(tmp_path, monkeypatch, capsys):
    """The rename into place needs only the directory's permission (even root's): the
    file's own mode (0444) decides.  Oracle: its bytes and mode after."""
    monkeypatch.chdir(tmp_path)
    f = tmp_path / "s.csv"
    f.write_text("mine")
    f.chmod(0o444)
    assert main(["step", "--t-end", "0.05", "--csv", "s.csv"]) == 2
    assert "read-only" in _stderr_line(capsys)
    assert f.read_text() == "mine" and f.stat().st_mode & 0o777 == 0o444
    assert _listing(tmp_path) == ["s.csv"]


def test_a_report_holding_a_users_file_is_not_replaced(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["reproduce", "--out", str(out), "--only", "feasibility"]) == 0
    capsys.readouterr()
    (out / "notes.txt").write_text("mine")
    (out / "figures" / "sketch.png").write_bytes(b"mine")
    before = _listing(out)
    assert main(["reproduce", "--out", str(out), "--only", "feasibility"]) == 2
    line = _stderr_line(capsys)
    assert "figures/sketch.png and 1 more" in line and "did not write" in line
    assert _listing(out) == before and (out / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]   # no temporary left


def test_an_export_keeps_a_users_files(tmp_path, capsys):
    out = tmp_path / "ctl"
    base = ["export", "--out", str(out), "--fn", "14"]
    assert main([*base, "--lang", "python"]) == 0
    (out / "notes.txt").write_text("mine")
    (out / "controller.json").write_text("mine")   # a name only the JSON export writes
    capsys.readouterr()
    assert main([*base, "--lang", "json"]) == 2
    assert "controller.json" in _stderr_line(capsys)
    assert main([*base, "--lang", "python"]) == 0       # replaces only what it listed
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "controller.json").read_text() == "mine"


def test_sweep_overwrite_keeps_a_users_files(tmp_path, capsys):
    out = tmp_path / "sw"
    base = ["sweep", "--fn", "12,14", "--out", str(out), "--workers", "0", "--quiet", "--json"]
    assert main(base) == 0
    (out / "notes.txt").write_text("mine")
    assert main([*base, "--gs", "1,2", "--overwrite"]) == 0
    assert (out / "notes.txt").read_text() == "mine"
    assert len(sc_read_sweep(out)) == 4   # the new sweep's 2 x 2 points, not the old 2


def test_loop_sweep_overwrite_keeps_a_users_files(tmp_path, capsys):
    from pathlib import Path

    loop = str(Path(__file__).parents[1] / "examples" / "loops" / "rigid.toml")
    out = tmp_path / "sw"
    base = ["sweep", "--loop", loop, "--out", str(out), "--json"]
    assert main([*base, "--set", "fn=4,8"]) == 0
    (out / "notes.txt").write_text("mine")
    assert main([*base, "--set", "fn=4,8,12", "--overwrite"]) == 0
    assert (out / "notes.txt").read_text() == "mine"
    assert len(sc_read_sweep(out)) == 3


def sc_read_sweep(out):
    import seactl as sc

    return sc.read_sweep(out)


@pytest.mark.parametrize("argv", [
    ["export", "--out", ""], ["run", "--out", "", "--duration", "0.2"],
    ["reproduce", "--out", "", "--only", "feasibility"],
    ["sweep", "--fn", "14", "--workers", "0", "--out", ""]])
def test_an_empty_output_path_is_refused(argv, tmp_path, monkeypatch, capsys):
    """``Path("")`` is the working directory; the empty name is refused instead.  Oracle:
    the (empty) working directory after."""
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert "--out" in _stderr_line(capsys)
    assert _listing(tmp_path) == []


# ------------------------------------------------------------------ unbounded work
@pytest.mark.parametrize("argv, needles", [
    (["place", "--runs", "10000", "--high-timing", "uniform:1:3"],
     ["Monte Carlo", "10,000 runs", "would take about", "--runs"]),
    (["roots", "--fn", "10:100:0.01", "--t-qs", "1"], ["9,001 design(s)", "would take"]),
])
def test_long_work_is_refused_up_front(argv, needles, monkeypatch, capsys):
    """Oracle: the estimates of seactl.base.limits against a 30 s budget (10,000 runs x 1000
    steps x 3 placements at 3 us per design and step is 90 s; 9,001 delayed designs at
    6 roots x 8 ms is 441 s)."""
    monkeypatch.setenv("SEACTL_MAX_SECONDS", "30")
    assert main(argv) == 2
    line = _stderr_line(capsys)
    for needle in needles:
        assert needle in line


def test_roots_count_is_bounded_before_any_allocation():
    import seactl as sc

    with pytest.raises(sc.InputError, match=r"^invalid count = 1000000000: must be an "
                                            r"integer in \[1, 50\]"):
        sc.design(14).roots(count=10**9)


def test_explore_refuses_a_busy_port_before_loading_the_server(capsys):
    """Oracle: the port, held by a listening socket of this test."""
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["explore", "--port", str(port), "--no-browser"]) == 2
    line = _stderr_line(capsys)
    assert f"--port = {port}" in line and "free port" in line


# ------------------------------------------------------------------ latency traces
@pytest.mark.parametrize("content, needle", [
    (bytes(range(256)), "binary or UTF-16"),
    ("latency_ms\n1\n2\n".encode("utf-16"), "binary or UTF-16"),
    (b"latency_ms,count\n1,3\n2,nan\n", "finite"),
    (b"latency_ms,count\n1,3\n2,inf\n", "finite"),
    (b"latency_ms\n1\nnan\n2\n", "finite"),
    (b"tick,latency_ms\n100,1\n200,2\n", "header"),
    (b"1,2,3\n", "one column"),
])
def test_bad_latency_traces_are_one_line(content, needle, tmp_path, capsys):
    f = tmp_path / "trace.csv"
    f.write_bytes(content)
    for argv in (["jitter", "--trace", f"stiffness={f}"],
                 ["step", "--mode", "sampled", "--t-end", "0.1", "--latency",
                  f"stiffness=hist:{f}"]):
        assert main(argv) == 2
        line = _stderr_line(capsys)
        assert needle in line and "trace.csv" in line


def test_a_trace_is_read_by_its_header(tmp_path):
    """Oracle: the file's columns by hand (count first, then latency_ms)."""
    from seactl.latency.models import Empirical

    f = tmp_path / "h.csv"
    f.write_text("count,latency_ms\n5,1.0\n1,2.0\n")
    e = Empirical.from_csv(f)
    assert e.values_s == (1e-3, 2e-3) and e.weights == (5.0, 1.0)


def test_an_unreadable_trace_says_so(tmp_path, monkeypatch, capsys):
    """(Simulated: root reads a 0000 file.)  The message is about reading, not writing."""
    from pathlib import Path

    f = _trace(tmp_path / "trace.csv")

    def denied(self):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_bytes", denied)
    assert main(["jitter", "--trace", f"stiffness={f}"]) == 2
    line = _stderr_line(capsys)
    assert "readable file (permission denied)" in line and "cannot write" not in line


# ------------------------------------------------------------------ conflicts, ranges
@pytest.mark.parametrize("argv, needle", [
    (["place", "--high-timing", "22", "--high-latency", "5"], "--high-latency"),
    (["place", "--low-timing", "1", "--low-latency", "5"], "--low-latency"),
    (["run", "--rate", "10", "--duration", "0.1"], "--duration"),
    (["run", "--seed", "-1"], "--seed"),
])
def test_conflicts_and_degenerate_runs_are_refused(argv, needle, capsys):
    assert main(argv) == 2
    assert needle in _stderr_line(capsys)


@pytest.mark.parametrize("call, field", [
    (lambda sc: sc.design([]), "fn_hz [Hz]"),
    (lambda sc: sc.design(14, gs=[]), "gs"),
    (lambda sc: sc.design([14, 15], gs=[1, 2, 3]), "gs"),
    (lambda sc: sc.design("abc"), "fn_hz [Hz]"),
    (lambda sc: sc.design([14, 15])[0:0], "index"),
    (lambda sc: sc.rigid([]), "fn_hz [Hz]"),
    (lambda sc: sc.latency_map(14, [], [1]), "stiffness_delays [ms]"),
    (lambda sc: sc.rightmost_roots("ut-sea"), "system"),
    (lambda sc: sc.feasible_fn_range("nosuch"), "actuator"),
    (lambda sc: sc.read_sweep(""), "out"),
    (lambda sc: sc.sweep("/nonexistent-dir/x", fn_hz=[14], chunk_size=0), "chunk_size"),
    (lambda sc: sc.sweep("/nonexistent-dir/x", fn_hz=[float("nan")]), "fn_hz [Hz]"),
    (lambda sc: sc.sweep("/nonexistent-dir/x", fn_hz=[14], sampling="lhs"), "n_samples"),
])
def test_api_misuse_names_the_argument(call, field):
    """Once numpy's own errors (an empty reduction, argmax of an empty sequence, an
    attribute of a string) or the command line's flags; now the caller's keyword."""
    import seactl as sc

    with pytest.raises(sc.InputError) as info:
        call(sc)
    assert info.value.field == field


@pytest.mark.parametrize("field, value", [("motor_inertia", "1e308"),
                                          ("joint_inertia", "1e200"),
                                          ("current_to_torque", "1e-100")])
def test_extreme_actuator_values_spill_no_warning(field, value, tmp_path, capsys):
    """Once numpy's overflow warnings, then a traceback or a one-line error."""
    import warnings

    values = {"motor_inertia": "0.225", "joint_inertia": "0.014", "motor_damping": "1.375",
              "joint_damping": "0.1", "spring_stiffness": "218.75",
              "current_to_torque": "5.2", field: value}
    f = tmp_path / "big.toml"
    f.write_text("".join(f"{k} = {v}\n" for k, v in values.items()))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for cmd in (["gains"], ["step", "--t-end", "0.1"], ["jitter"]):
            assert main([*cmd, "--actuator", str(f)]) == 2
            assert field in _stderr_line(capsys)


def test_the_gain_design_overflows_quietly():
    """An actuator at the largest accepted inertia and stiffness, at a natural frequency
    the design cannot reach: infeasible, with no numpy warning on the way."""
    import warnings

    import seactl as sc

    act = sc.SEAParams(1e4, 1e-300, 0.0, 0.0, 1e9, 1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(sc.SeactlError):
            sc.design(1000.0, actuator=act)


# ------------------------------------------------------------------ signals
def _seactl(args, **kw):
    import signal
    import subprocess
    import sys

    return subprocess.Popen([sys.executable, "-c", "from seactl.apps.cli import run; run()",
                             *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                                        signal.SIG_DFL),
                            **kw)


def _children(pid: int) -> list[int]:
    from pathlib import Path

    return [int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit()
            and _ppid(p) == pid]


def _ppid(proc_dir) -> int:
    try:
        return int(proc_dir.joinpath("stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return -1


def _alive(pid: int) -> bool:
    from pathlib import Path

    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not __import__("os").path.isdir("/proc") or not hasattr(
    __import__("signal"), "SIGTERM"), reason="needs /proc and SIGTERM")
def test_sigterm_stops_a_runs_processes_and_removes_its_files(tmp_path):
    """SIGTERM takes Ctrl-C's path (status 143 instead of 130).  Oracles: the children's
    /proc entries and the (private) temporary directory."""
    import os
    import signal
    import time

    env = dict(os.environ, TMPDIR=str(tmp_path))
    proc = _seactl(["run", "--duration", "60", "--transport", "udp"], env=env)
    deadline = time.monotonic() + 120
    while len(kids := _children(proc.pid)) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(kids) == 3, "the run did not start its processes"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert (proc.returncode, err) == (143, "terminated\n")
    deadline = time.monotonic() + 10
    while any(map(_alive, kids)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(map(_alive, kids)) and list(tmp_path.iterdir()) == []


def test_ctrl_c_while_the_commands_load_is_one_line():
    """A KeyboardInterrupt raised by the import of click (what Ctrl-C in the first half
    second does) is caught by the entry point: status 130, one line, no traceback."""
    import subprocess
    import sys

    code = ("import sys\n"
            "class Stop:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'click':\n"
            "            raise KeyboardInterrupt\n"
            "sys.meta_path.insert(0, Stop())\n"
            "from seactl.apps.cli import run\n"
            "run()\n")
    res = subprocess.run([sys.executable, "-c", code, "gains"], capture_output=True,
                         text=True, timeout=60)
    assert (res.returncode, res.stderr, res.stdout) == (130, "interrupted\n", "")


def test_closing_a_sweeps_workers_ignores_a_second_ctrl_c():
    """Oracle: the signal delivered inside the block raises nothing, and the handler
    before it is back after it."""
    import importlib
    import os
    import signal

    sw = importlib.import_module("seactl.sweep.engine")
    before = signal.getsignal(signal.SIGINT)
    with sw.uninterrupted():
        os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before


def test_a_sweep_on_local_workers_leaves_no_temporary_directory(tmp_path, monkeypatch,
                                                                capsys):
    """Dask's workers keep their files in a directory the sweep removes after them.
    Oracle: the (private) temporary directory's listing after the sweep."""
    import tempfile

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    assert main(["sweep", "--fn", "12,14", "--out", str(tmp_path / "sw"), "--workers", "1",
                 "--quiet", "--json"]) == 0
    assert [p.name for p in tmp.iterdir() if not p.name.startswith("pymp-")] == []


def test_a_report_marker_without_a_list_stands_for_the_reports_files(tmp_path):
    """A report written before the marker listed its files: its fixed names and figures
    may be replaced, anything else refuses.  Oracle: the names written by hand."""
    from seactl.apps.report import check_report_dir
    from seactl.errors import OutputError

    rep = tmp_path / "rep"
    (rep / "figures").mkdir(parents=True)
    for name in (".seactl-report", "index.html", "claims.json", "figures/a.png"):
        (rep / name).write_text("x")
    check_report_dir(rep)
    (rep / "figures" / "mine.svg").write_text("mine")
    with pytest.raises(OutputError, match="figures/mine.svg, which seactl did not write"):
        check_report_dir(rep)
