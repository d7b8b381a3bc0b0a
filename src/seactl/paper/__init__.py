"""Report sections reproducing the paper, one module per topic.

Importing this package registers every section with :mod:`seactl.report`.
"""

from . import gain_design  # noqa: F401
from . import impedance  # noqa: F401
from . import sweep  # noqa: F401
from . import placement  # noqa: F401
from . import base  # noqa: F401
from . import simulation  # noqa: F401
