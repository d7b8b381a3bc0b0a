"""Every command's --help names the Python call it makes, and that call exists.

Oracle: the public namespace itself (``seactl.__all__`` and the methods of the classes the
named constructors return), not a copy of the help text.
"""

import importlib
import re

import click
import pytest
from click.testing import CliRunner

import seactl as sc
from seactl.apps.commands import cli

RETURNS = {"design": sc.Design, "rigid": sc.RigidBatch, "load_loop": sc.UserLoop}
"""The class each public constructor returns (what ``sc.NAME(...).method()`` calls)."""

# The pairs issue 37 names: a command whose name differs from its method must say it.
METHOD_OF = {"gains": "sc.design(...).margins()", "jitter": ".jitter_margins()",
             "roots": ".roots(", "step": ".step(", "impulse": ".impulse()",
             "impedance": ".impedance(", "export": ".export(", "run": ".run()",
             "sweep": "sc.sweep(", "rigid": "sc.rigid(...).margins()"}


def commands(group=cli, prefix=""):
    for name, cmd in sorted(group.commands.items()):
        if isinstance(cmd, click.Group):
            yield from commands(cmd, f"{prefix}{name} ")
        else:
            yield f"{prefix}{name}", cmd


def python_line(name):
    out = CliRunner().invoke(cli, [*name.split(), "--help"], terminal_width=100).output
    text = " ".join(out.split())   # click re-wraps paragraphs
    found = re.search(r"Python: (.*?)(?:\. [A-Z(\\]|\.$|$)", text)
    assert found, f"`seactl {name} --help` does not say which Python call it makes"
    return found.group(1)


def calls(line):
    """``(receiver, name)`` for each call in ``line``: ``("sc", "design")``,
    ``(sc.Design, "margins")`` (a chained or listed method of the last constructor), or
    ``("seactl.sweep.engine", "monte_carlo")``."""
    out, receiver = [], None
    for m in re.finditer(r"(\bsc|\bseactl(?:\.\w+)+)?\.(\w+)\(", line):
        module, name = m.group(1), m.group(2)
        if module == "sc":
            out.append(("sc", name))
            receiver = RETURNS.get(name)
        elif module:
            out.append((module, name))
        elif receiver is not None:
            out.append((receiver, name))
    return out


@pytest.mark.parametrize("name", [n for n, _ in commands()])
def test_every_command_names_an_existing_api_call(name):
    line = python_line(name)
    found = calls(line)
    assert found, f"seactl {name}: no call in {line!r}"
    for receiver, attr in found:
        if receiver == "sc":
            assert attr in sc.__all__, f"seactl {name}: sc.{attr} is not public"
        elif isinstance(receiver, str):
            assert callable(getattr(importlib.import_module(receiver), attr, None)), \
                f"seactl {name}: {receiver}.{attr} does not exist"
        else:
            assert callable(getattr(receiver, attr, None)), \
                f"seactl {name}: {receiver.__name__}.{attr} does not exist"


@pytest.mark.parametrize("name, call", sorted(METHOD_OF.items()))
def test_commands_name_their_method(name, call):
    assert call in python_line(name)


def test_the_walk_sees_every_registered_command():
    # oracle: the click group's own listing, as `seactl --help` prints it
    listed = CliRunner().invoke(cli, ["--help"], terminal_width=200).output
    names = {n for n, _ in commands()}
    for n in cli.commands:
        assert n in listed and n in names
