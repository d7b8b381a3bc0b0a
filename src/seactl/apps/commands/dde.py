"""``--dde FILE.toml``: a delay equation or quasi-polynomial file (docs/delay-equations.md)
instead of a built-in design, for ``seactl roots``, ``chart`` and ``delay-margin``;
``--set NAME=VALUE`` overrides its named delays [s] (a range ``START:STOP:STEP`` or
``a,b,c`` is a batch axis)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click
import numpy as np

from seactl.errors import InputError

from .loops import parse_sets

DDE_OPTIONS = frozenset({"count", "as_json", "dde_file", "sets", "delays", "max_s", "max_ms",
                         "resolution", "plot", "direction"})
"""The options (click parameter names) that apply with ``--dde`` (in ``seactl roots``,
``chart`` and ``delay-margin``)."""


def _refuse_other_options() -> None:
    from click.core import ParameterSource

    ctx = click.get_current_context()
    for p in ctx.command.params:
        if p.name not in DDE_OPTIONS and ctx.get_parameter_source(p.name) in (
                ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT):
            raise InputError(max(p.opts, key=len), "given", "absent with --dde (the file "
                             "defines the equation; override its delays with --set)")


def load(path: str, sets: tuple[str, ...]) -> Any:
    """The file's system (:func:`seactl.load_dde`) with ``--set`` delays [s]."""
    import seactl as sc
    from seactl.base.limits import BYTES_PER_DESIGN, check_budget

    values = parse_sets(sets)
    n = int(np.prod([np.size(v) for v in values.values()], dtype=float)) if values else 1
    check_budget(f"{n:,} delay values of the equation", n_bytes=n * BYTES_PER_DESIGN,
                 hint="give fewer --set values")
    return sc.load_dde(path, **values)


def dde_option(func: Callable) -> Callable:
    """Add ``--dde FILE`` above :func:`~.loops.loop_options` (whose ``--set`` it shares):
    the command receives ``dde`` (a :class:`~seactl.DelaySystem` or None)."""

    @functools.wraps(func)
    def wrapper(*args, dde_file, loop_file, sets, **kwargs):
        if dde_file is None:
            return func(*args, loop_file=loop_file, sets=sets, dde=None, **kwargs)
        if loop_file:
            raise InputError("--dde", dde_file, "absent with --loop (one system at a time)")
        _refuse_other_options()
        return func(*args, loop_file=None, sets=(), dde=load(dde_file, sets), **kwargs)

    return click.option("--dde", "dde_file", default=None, metavar="FILE.toml",
                        type=click.Path(dir_okay=False),
                        help="A delay equation or quasi-polynomial file "
                             "(docs/delay-equations.md); --set NAME=VALUE overrides its "
                             "delays [s].")(wrapper)
