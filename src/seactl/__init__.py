"""seactl: distributed impedance control of series elastic and rigid actuators.

Implements Zhao & Sentis, "Distributed Impedance Control of Latency-Prone Robotic Systems
with Series Elastic Actuation": the SEA cascaded loop with exact delays and filters,
critically-damped gain design, exact-delay margins, impedance, time-domain responses,
the rigid actuator, latency maps, loop placement, design-space sweeps and a mobile base.

The public API is this namespace (``__all__``); the submodules hold the implementation.

>>> import seactl as sc
>>> d = sc.design([12, 14, 16], gs=1.0, delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
>>> d.margins().phase_margin_deg.round(2)
array([45.13, 43.26, 40.03])
"""

from importlib.metadata import PackageNotFoundError, version

# Submodules whose names the public functions reuse (design, rigid, sweep) are loaded
# first: the functions bound below then own those names in this namespace, and
# ``from seactl.design import ...`` keeps finding the modules in sys.modules.
from . import design as _gain_design
from . import rigid as _rigid_module  # noqa: F401
from . import sweep as _sweep_module  # noqa: F401
from ._results import ImpedanceResult, MarginsResult, ResponseResult, RootsResult
from .actuators import UT_SEA, SEAParams, load_sea
from .api import Design, UnitWarning, design, rightmost_roots
from .errors import InfeasibleDesignError, InputError, SeactlError
from .systems import (
    LatencyMapResult,
    PlacementResult,
    RigidBatch,
    compare_mobile_base,
    latency_map,
    loop_model,
    mobile_base_params,
    place,
    read_sweep,
    rigid,
    sweep,
)

feasible_fn_range = _gain_design.feasible_fn_range

try:
    __version__ = version("seactl")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

__all__ = [
    # SEA designs
    "design", "Design", "SEAParams", "UT_SEA", "load_sea", "feasible_fn_range",
    "MarginsResult", "ImpedanceResult", "ResponseResult", "rightmost_roots", "RootsResult",
    # other systems
    "rigid", "RigidBatch", "loop_model", "latency_map", "place", "sweep", "read_sweep",
    "compare_mobile_base", "mobile_base_params", "LatencyMapResult", "PlacementResult",
    # errors and warnings
    "SeactlError", "InputError", "InfeasibleDesignError", "UnitWarning",
]
