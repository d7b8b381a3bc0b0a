"""CLI commands beyond the core ones in :mod:`seactl.cli`, one module per topic.

Each module imports ``cli`` (the click group) and the shared helpers from
:mod:`seactl.cli` and registers its commands with ``@cli.command()``.
"""
from . import impedance  # noqa: F401
from . import sweep  # noqa: F401
from . import placement  # noqa: F401
from . import base  # noqa: F401
from . import simulate  # noqa: F401
