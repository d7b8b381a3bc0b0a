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
