"""CLI commands beyond the core ones in :mod:`seactl.cli`, one module per topic.

Each module imports ``cli`` (the click group) and the shared helpers from
:mod:`seactl.cli` and registers its commands with ``@cli.command()``.
"""
from . import (
    base,  # noqa: F401
    impedance,  # noqa: F401
    placement,  # noqa: F401
    simulate,  # noqa: F401
    sweep,  # noqa: F401
)
