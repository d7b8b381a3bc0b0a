"""The README's two commands are the project's contract; CI runs the second one verbatim.

Oracle: README.md and .ci/run as committed (the tests compare their lines).
"""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def readme_commands():
    lines = ROOT.joinpath("README.md").read_text().splitlines()
    assert lines[0] == "```sh"
    end = lines.index("```", 1)
    return lines[1:end]


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
    lines = ROOT.joinpath("README.md").read_text().splitlines()
    start = lines.index("## Documentation")
    cmd = next(line for line in lines[start:] if "sphinx-build" in line)
    assert "-W" in cmd.split()
    assert cmd in ROOT.joinpath(".ci", "run").read_text().splitlines()
