"""Progress of long commands (seactl.base.progress) and the kernel compilation notes
(seactl.base.jit): what appears on stderr, in which order, and never on stdout."""

from __future__ import annotations

import io
import json

import pytest

from seactl.apps.cli import main
from seactl.base import jit, progress
from seactl.base.jit import KernelGroup, njit

KERNELS = KernelGroup("test-only", about_s=3)   # the group of the kernels defined below


def _lines(buf: io.StringIO) -> list[str]:
    return buf.getvalue().splitlines()


def test_lines_mode_counts_in_order(monkeypatch):
    # Oracle: the documented line format, one line at the start and one per step when
    # no throttling interval applies.
    monkeypatch.setattr(progress, "LINE_INTERVAL_S", 0.0)
    buf = io.StringIO()
    with progress.reporting("lines", stream=buf):
        with progress.stage("work", total=3, unit="items") as st:
            for name in ("a", "b", "c"):
                with progress.stage("inner", total=1) as inner:   # nested: no lines
                    inner.advance()
                st.advance(item=name)
        progress.note("done")
    lines = _lines(buf)
    assert lines[0] == "seactl: work (3 items)"
    assert [ln.split(" (")[0] for ln in lines[1:4]] == [
        "seactl: work 1/3 items", "seactl: work 2/3 items", "seactl: work 3/3 items"]
    assert "(a)" in lines[1] and "left" not in lines[1]   # one step: too few to tell
    assert "(b)" in lines[2] and "left" in lines[2]       # time left from two steps on
    assert "left" not in lines[3]                         # ... but not when complete
    assert lines[4] == "seactl: done"


def test_lines_mode_throttles_but_shows_the_last(monkeypatch):
    # Oracle: with a long interval only the start line and the completing step print.
    monkeypatch.setattr(progress, "LINE_INTERVAL_S", 3600.0)
    buf = io.StringIO()
    with progress.reporting("lines", stream=buf):
        with progress.stage("chunks", total=50) as st:
            for _ in range(50):
                st.advance()
    assert _lines(buf) == ["seactl: chunks (50)", "seactl: chunks 50/50"]


def test_silent_outside_reporting_and_when_off(monkeypatch, capsys):
    with progress.stage("nothing", total=2) as st:   # no reporter: silent
        st.advance(2)
    monkeypatch.setenv(progress.ENV, "off")
    buf = io.StringIO()
    with progress.reporting(stream=buf):             # auto -> the environment's "off"
        progress.note("hidden")
    assert buf.getvalue() == ""
    assert capsys.readouterr() == ("", "")
    monkeypatch.setenv(progress.ENV, "loud")
    with pytest.raises(progress.InputError, match="SEACTL_PROGRESS"):
        progress.resolve_mode()


def test_auto_mode_follows_the_stream(monkeypatch):
    monkeypatch.delenv(progress.ENV, raising=False)

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    assert progress.resolve_mode("auto", io.StringIO()) == "lines"
    assert progress.resolve_mode("auto", Tty()) == "terminal"


@njit()
def _kernel_test_only(x):  # pragma: no cover - compiled
    return x + 1


def test_first_compilation_of_a_group_is_announced_once():
    # Oracle: numba compiles on the first call (its signatures list grows), and the note
    # names the group and its expected time, once per process.
    buf = io.StringIO()
    with progress.reporting("lines", stream=buf):
        assert _kernel_test_only(1) == 2
        assert _kernel_test_only(2.5) == 3.5         # a second signature: no second note
    assert len(_kernel_test_only.signatures) == 2
    assert _lines(buf) == [
        "seactl: compiling the test-only kernels (once per installation, about 3 s)"]


def _cold_kernel(x):  # pragma: no cover - compiled in the test below
    return 2 * x


def test_is_cold_until_a_kernel_is_cached(tmp_path, monkeypatch):
    # Oracle: numba's index file (<module>.<function>-<line>.py<ver>.nbi) in the cache
    # directory after the first call.
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    k = njit(cache=True)(_cold_kernel)                 # of this module's group
    assert jit.is_cold("test-only")
    assert k(2) == 4
    assert list(tmp_path.rglob("*.nbi"))
    assert not jit.is_cold("test-only")


def test_cli_progress_on_stderr_json_clean_on_stdout(capsys, monkeypatch):
    # Oracle: stdout parses as JSON whole; the progress lines are on stderr only.
    monkeypatch.delenv(progress.ENV, raising=False)
    monkeypatch.setattr(progress, "LINE_INTERVAL_S", 0.0)
    assert main(["bench", "--only", "gain-design", "--repeat", "1", "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["benchmarks"][0]["name"] == "gain-design"
    assert "seactl:" not in out
    assert "seactl: benchmarks (1)" in err.splitlines()
    assert any(ln.startswith("seactl: benchmarks 1/1 (gain-design)") for ln in err.splitlines())


def test_reproduce_talks_without_a_terminal(tmp_path, capsys, monkeypatch):
    # Oracle: the documented non-terminal format (capsys's stderr is no terminal); nothing
    # of it on stdout.
    monkeypatch.delenv(progress.ENV, raising=False)
    assert main(["reproduce", "--only", "table-i", "--out", str(tmp_path / "rep"),
                 "--jobs", "1"]) == 0
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if not ln.startswith("seactl: compiling")]
    assert lines[:2] == ["seactl: reproducing the paper (1 sections)",
                         "seactl: reproducing the paper 1/1 sections (table-i)"]
    assert "seactl:" not in out


def test_report_warmup_compiles_the_signatures_margins_use():
    # Oracle: numba's own record of the signatures that real margins() and
    # jitter_margins() calls compiled or loaded; a kernel whose arguments changed would
    # be compiled twice on a cold cache.
    import seactl as sc
    from seactl.apps.paper.warmup import margin_signatures
    from seactl.certify import scan

    d = sc.design([12.0, 14.0], filters_hz=(50, 100),
                  delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5})
    d.margins()
    d.jitter_margins()
    for name, sig in margin_signatures().items():
        assert sig in getattr(scan, name).signatures, name
