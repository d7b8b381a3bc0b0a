"""The ``seactl`` commands, one module per topic, on the click group of :mod:`.common`.

Importing this package attaches every command to :data:`cli`; :mod:`seactl.apps.cli` is the
entry point and the only importer of this package.
"""
from . import (
    chart,  # noqa: F401
    core,  # noqa: F401
    delay_margin,  # noqa: F401
    explore,  # noqa: F401
    export,  # noqa: F401
    impedance,  # noqa: F401
    jitter,  # noqa: F401
    loops,  # noqa: F401
    mobile_base,  # noqa: F401
    placement,  # noqa: F401
    robot,  # noqa: F401
    roots,  # noqa: F401
    run,  # noqa: F401
    simulate,  # noqa: F401
    sweep,  # noqa: F401
)
from .common import cli

__all__ = ["cli"]
