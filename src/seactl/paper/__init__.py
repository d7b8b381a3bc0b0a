"""Report sections reproducing the paper, one module per topic.

Importing this package registers every section with :mod:`seactl.report`.
"""

from . import (
    base,  # noqa: F401
    gain_design,  # noqa: F401
    impedance,  # noqa: F401
    placement,  # noqa: F401
    simulation,  # noqa: F401
    sweep,  # noqa: F401
)
