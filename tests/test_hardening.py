"""Hardening: seactl never destroys what it did not write, click's errors use seactl's one-line
format, and inputs that once crashed the core are handled.

Oracles: the file system before and after (bytes and listings), click's own exit status for
usage errors, and the documented error contract (one line ``error: ...``, exit 2).
"""

from __future__ import annotations

import pytest

from seactl.cli import main


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
    import seactl.outputs

    def boom(fig, tmp, fmt, dpi):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(seactl.outputs, "save_figure_to", boom)
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
    (["step", "--t-qs", "1e-6"], ["would take about", "SEACTL_MAX_SECONDS"]),
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
    from seactl.errors import InputError
    from seactl.limits import check_range
    from seactl.sweep import SweepSpec

    with pytest.raises(InputError, match="^invalid rate_hz = "):
        check_range("rate_hz", 1e9, "rate_hz")
    with pytest.raises(InputError, match="^invalid seed = -1"):
        SweepSpec(sc_actuator(), (("fn_hz", (14.0,)),), sampling="random", n_samples=5,
                  seed=-1)


def sc_actuator():
    from seactl.actuators import load_sea

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

    sw = importlib.import_module("seactl.sweep")   # the module (seactl.sweep is a function)
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
