"""``seactl robot``'s command line: options that cannot be combined, and its grouped help.

Oracles: behaviour (the exit status and the one error line, checked before any robot is
built), and click's own list of the command's options for the help's headings.
"""

from pathlib import Path

import pytest
from click.testing import CliRunner

from seactl.apps.cli import main
from seactl.apps.commands import cli
from seactl.apps.commands.robot import NOT_WITH, ONLY_WITH

ARM = str(Path(__file__).resolve().parents[1] / "examples" / "robots" / "planar_2link.urdf")

VALUES = {"--workspace": "0:0.6:2,0.8:1.6:2", "--trajectory": "path.csv", "--q0": "0.3,0.8",
          "--placement": "5,0.5", "--impedance": "1,10", "--task-step": "1,0,0",
          "--task-impulse": "0,1,0", "--plot": "map.png", "--workers": "2"}


def args_of(*flags):
    out = []
    for f in flags:
        out += [f] if f == "--mujoco-check" else [f, VALUES[f]]
    return out


PAIRS = [(a, b) for a, others in NOT_WITH for b in others]


@pytest.mark.parametrize("flag, other", PAIRS)
def test_options_not_together_are_one_line(capsys, flag, other):
    """A behaviour: each pair of the table is refused on one line naming both, exit 2."""
    assert main(["robot", "--urdf", ARM, *args_of(flag, other)]) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    assert out.err.startswith(f"error: invalid {flag} = ")
    assert out.err.rstrip().endswith(f"must be given without {other}")


@pytest.mark.parametrize("flag, view", [("--plot", "--impedance"), ("--workers", None)])
def test_map_options_need_a_map(capsys, flag, view):
    """A behaviour: ``--plot``/``--workers`` without a map are refused, also beside a task
    view (which used to ignore them)."""
    (needs,) = [n for f, n in ONLY_WITH if f == flag]
    extra = [] if view is None else args_of(view)
    assert main(["robot", "--urdf", ARM, "--space", "task", "--task", "tool",
                 *extra, *args_of(flag)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.rstrip().endswith("must be given with " + " or ".join(needs))


def test_help_groups_every_option_once():
    """Oracle: click's list of the command's options; each is under exactly one heading,
    and the example comes before the options."""
    cmd = cli.commands["robot"]
    text = CliRunner().invoke(cli, ["robot", "--help"], terminal_width=100).output
    headings = [line for line in text.splitlines() if line and not line[0].isspace()
                and line.endswith(":")]
    assert [h[:-1] for h in headings] == [t for t, _ in cmd.sections] + ["Options"]
    for p in cmd.params:
        flag = max(p.opts, key=len)
        assert text.count(f"\n  {flag} ") + text.count(f"\n  {flag}/") == 1, flag
    assert text.index("seactl robot --urdf") < text.index(headings[0])
