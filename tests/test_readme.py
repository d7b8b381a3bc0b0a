"""The README works as typed.

Its two opening commands are the project's contract (CI runs the second one verbatim); every
line of its quick start and its Python section runs as typed, in a directory that holds what
a fresh clone holds.

Oracle: README.md and .ci/run as committed (the tests compare their lines), and for the
quick start and the Python section the exit status, stderr and printed values of the lines
themselves, run through the shell and the venv's Python (and every numeric column of the
tables they print names its unit: tests/tables.py).

The directory the lines run in (`readme_clone`) is a temporary one holding a symlink to the
repository's ``examples/`` and one named ``.venv`` to the virtual environment running the
tests (``sys.prefix``), so ``.venv/bin/seactl`` and ``.venv/bin/python`` are that venv's.
In CI that venv is fresh: ``.ci/run`` makes it with the README's own second command on a
clean clone.  The lines run two at a time (CI has two cores), each with its own output
files, none depending on another's.  ``seactl explore`` serves until stopped: its line runs
until the page answers, then gets Ctrl-C (SIGINT), which must end it with status 130; the
environment's ``BROWSER=true`` makes its "open a browser" a no-op.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
import time
import urllib.request
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tables import unitless_numeric_columns

ROOT = Path(__file__).resolve().parents[1]
README = ROOT.joinpath("README.md").read_text().splitlines()
BAD_STDERR = re.compile(r"Traceback|\w+Warning\b|^warning", re.MULTILINE)
"""What stderr must not hold: a traceback or a Python warning."""


def readme_commands():
    assert README[0] == "```sh"
    end = README.index("```", 1)
    return README[1:end]


def section_block(title: str, lang: str) -> list[str]:
    """The lines of the first ```lang block after the heading ``title``."""
    start = README.index(f"```{lang}", README.index(title))
    return README[start + 1:README.index("```", start + 1)]


def quick_start() -> list[str]:
    """The quick start's command lines, continuation lines joined as the shell joins them."""
    lines, cur = [], ""
    for raw in section_block("## Quick start", "sh"):
        cur += raw[:-1] if raw.endswith("\\") else raw
        if not raw.endswith("\\"):
            lines.append(cur)
            cur = ""
    assert not cur
    return lines


def test_readme_opens_with_exactly_two_commands():
    cmds = readme_commands()
    assert len(cmds) == 2
    assert cmds[0].endswith("seactl reproduce")
    assert "pytest" in cmds[1]


def test_ci_runs_the_readme_test_command():
    ci = ROOT.joinpath(".ci", "run").read_text().splitlines()
    assert readme_commands()[1] in ci


def test_ci_builds_the_docs_with_the_readme_command():
    # The README's "Documentation" section names the one command that builds the site.
    start = README.index("## Documentation")
    cmd = next(line for line in README[start:] if "sphinx-build" in line)
    assert "-W" in cmd.split()
    assert cmd in ROOT.joinpath(".ci", "run").read_text().splitlines()


def test_readme_commands_name_the_venv():
    # Every command of every ```sh block runs the venv's own programs: no bare seactl,
    # pip, python or pytest, which on many machines are not the venv's.
    blocks = [i for i, line in enumerate(README) if line == "```sh"]
    for i in blocks:
        for line in README[i + 1:README.index("```", i + 1)]:
            words = shlex.split(line.split("  #")[0].rstrip("\\"), comments=True)
            for j, w in enumerate(words):
                if w in ("seactl", "pip", "python", "pytest", "sphinx-build", "ruff"):
                    assert j > 0 and words[j - 1] == "-m", line


@pytest.fixture(scope="module")
def readme_clone(tmp_path_factory):
    venv = Path(sys.prefix)
    if not (venv / "bin" / "seactl").exists():
        pytest.skip(f"the tests do not run in a virtual environment with seactl ({venv})")
    clone = tmp_path_factory.mktemp("clone")
    (clone / "examples").symlink_to(ROOT / "examples")
    (clone / ".venv").symlink_to(venv)
    return clone


def _env() -> dict[str, str]:
    env = dict(os.environ, BROWSER="true", COLUMNS="120")
    env.pop("PYTHONWARNINGS", None)
    return env


def _serve_until_up(line: str, cwd: Path) -> tuple[int, str]:
    """Run a server line until its page answers, then Ctrl-C it: (exit status, stderr)."""
    proc = subprocess.Popen(["bash", "-c", f"exec {line}"], cwd=cwd, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = "http://127.0.0.1:5006/"
    direct = urllib.request.build_opener(urllib.request.ProxyHandler({}))
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                with direct.open(url, timeout=5) as page:
                    if page.status == 200:
                        break
            except OSError:
                time.sleep(0.5)
        else:
            proc.kill()
            out, err = proc.communicate()
            return -1, f"no page at {url}: {err}"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        return proc.returncode, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def _run_line(line: str, cwd: Path) -> str | None:
    """Run one quick-start line as typed; what is wrong with it, or None."""
    t0 = time.monotonic()
    if line.startswith(".venv/bin/seactl explore"):
        rc, err = _serve_until_up(line.split("  #")[0], cwd)
        want, out = 130, ""
    else:
        res = subprocess.run(["bash", "-c", line], cwd=cwd, env=_env(), capture_output=True,
                             text=True, timeout=900)
        rc, err, out = res.returncode, res.stderr, res.stdout
        want = 2 if "# exits 2" in line else 0
    took = time.monotonic() - t0
    print(f"{took:6.1f} s  {line}")
    if rc != want:
        return f"exit {rc}, not {want}: {line}\n{err}"
    if want == 2 and not re.fullmatch(r"error: [^\n]+\n", err):
        return f"not one 'error:' line on stderr: {line}\n{err}"
    if want != 2 and BAD_STDERR.search(err):
        return f"traceback or warning on stderr: {line}\n{err}"
    if unitless_numeric_columns(out):
        return f"numbers without a unit in {unitless_numeric_columns(out)}: {line}"
    return None


@pytest.mark.slow
def test_every_quick_start_line_runs_as_typed(readme_clone):
    lines = quick_start()
    assert len(lines) >= 20 and all(line.startswith(".venv/bin/seactl ") for line in lines)
    with ThreadPoolExecutor(max_workers=2) as pool:
        problems = [p for p in pool.map(lambda line: _run_line(line, readme_clone), lines)
                    if p]
    assert not problems, "\n\n".join(problems)


@pytest.mark.slow
def test_the_python_section_runs_as_typed_and_prints_what_it_says(readme_clone):
    # Typed into the venv's Python line by line (the interactive interpreter reading the
    # block from its input): each expression line whose comment shows a value must print
    # exactly that value.
    block = section_block("## Python API", "python")
    res = subprocess.run([".venv/bin/python", "-q", "-i"], cwd=readme_clone, env=_env(),
                         input="\n".join(block) + "\n", capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stderr
    assert not BAD_STDERR.search(res.stderr), res.stderr
    shown = [line.split("#", 1)[1].strip() for line in block
             if "#" in line and not line.startswith((" ", "import"))
             and "=" not in line.split("#", 1)[0]]
    assert shown, "no value shown in the Python section"
    assert res.stdout.split("\n")[:len(shown)] == shown
