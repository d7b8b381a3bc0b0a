"""seactl: distributed impedance control of series elastic and rigid actuators.

Implements Zhao & Sentis, "Distributed Impedance Control of Latency-Prone Robotic Systems
with Series Elastic Actuation": the SEA cascaded loop with exact delays and filters,
critically-damped gain design, exact-delay margins, impedance, time-domain responses,
the rigid actuator, latency maps, loop placement, design-space sweeps and a mobile base.

The public API is this namespace (``__all__``); the submodules hold the implementation.

>>> import seactl as sc
>>> d = sc.design([12, 14, 16], gs=1.0, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
...               filters_hz=(50, 100))
>>> d.margins().phase_margin_deg.round(2)
array([45.13, 43.26, 40.03])
"""

import importlib
import sys
import types

# Public name -> module that defines it.  Loaded on first use (PEP 562), so ``import
# seactl`` and the command line's start-up stay fast; ``seactl.design`` etc. resolve to the
# functions even though submodules of the same names exist (see _Namespace).
_PUBLIC = {
    ".api.system": ("System",),
    ".base.result": ("Result",),
    ".api.sea": ("design", "Design", "rightmost_roots"),
    ".api.arguments": ("UnitWarning",),
    ".systems.sea.actuators": ("SEAParams", "UT_SEA", "load_sea"),
    ".systems.sea.design": ("feasible_fn_range",),
    ".api.results": ("MarginsResult", "SampledMarginsResult", "ImpedanceResult", "ResponseResult",
                  "JitterResult", "RootsResult"),
    ".api.latency": ("loop_model", "latency_map", "place", "LatencyMapResult", "PlacementResult"),
    ".api.rigid": ("rigid", "RigidBatch"),
    ".api.sampled_jitter": ("SampledJitterResult",),
    ".api.robot": ("robot", "Robot", "workspace_map"),
    ".api.robotcheck": ("MujocoCheck",),
    ".api.robotmodels": ("robot_models",),
    ".api.robotnyquist": ("MimoMarginsResult",),
    ".api.robotplacement": ("RobotPlacementResult",),
    ".api.robotimpedance": ("TaskImpedanceResult", "RobotPassivityResult"),
    ".api.robottask": ("TaskResponseResult",),
    ".api.sweeps": ("sweep", "read_sweep", "parameter_robustness"),
    ".api.mobile_base": ("compare_mobile_base", "mobile_base_params"),
    ".api.userloop": ("UserLoop",),
    ".api.delayresult": ("DelayMarginResult",),
    ".api.loopbuilder": ("load_loop", "LoopBuilder"),
    ".api.delay_system": ("delay_equation", "quasi_polynomial", "DelaySystem", "DelayEquation",
                          "QuasiPolynomialSystem"),
    ".api.ddefile": ("load_dde",),
    ".api.chartresult": ("StabilityChartResult",),
    ".errors": ("SeactlError", "InputError", "InfeasibleDesignError", "LoopFileError"),
}
_HOME = {name: module for module, names in _PUBLIC.items() for name in names}

__all__ = [
    # the one system type and the base of its results
    "System", "Result",
    # SEA designs
    "design", "Design", "SEAParams", "UT_SEA", "load_sea", "feasible_fn_range",
    "MarginsResult", "SampledMarginsResult", "ImpedanceResult", "ResponseResult",
    "JitterResult", "rightmost_roots", "RootsResult", "SampledJitterResult",
    # other systems
    "rigid", "RigidBatch", "loop_model", "latency_map", "place", "sweep", "read_sweep",
    "parameter_robustness",
    "robot", "Robot", "workspace_map", "MujocoCheck",
    "robot_models",
    "MimoMarginsResult", "RobotPlacementResult",
    "TaskImpedanceResult", "RobotPassivityResult", "TaskResponseResult",
    "compare_mobile_base", "mobile_base_params", "LatencyMapResult", "PlacementResult",
    # your own loop (loop files, docs/loops.md)
    "load_loop", "LoopBuilder", "UserLoop",
    # delay equations and quasi-polynomials typed in (docs/delay-equations.md)
    "delay_equation", "quasi_polynomial", "load_dde", "DelaySystem", "DelayEquation",
    "QuasiPolynomialSystem",
    # delay margin along a direction of the delays
    "DelayMarginResult",
    # stability charts over two delays
    "StabilityChartResult",
    # errors and warnings
    "SeactlError", "InputError", "InfeasibleDesignError", "LoopFileError", "UnitWarning",
]


class _Namespace(types.ModuleType):
    """The package module: public names load lazily, and importing a submodule that shares
    a public function's name (``seactl.design``, ``seactl.rigid``, ``seactl.sweep``) does
    not replace the function in this namespace (the submodule stays in ``sys.modules``)."""

    def __getattr__(self, name: str):
        if name == "__version__":
            return _version()
        if name not in _HOME:
            raise AttributeError(f"module 'seactl' has no attribute {name!r}")
        value = getattr(importlib.import_module(_HOME[name], __name__), name)
        super().__setattr__(name, value)
        return value

    def __setattr__(self, name: str, value) -> None:
        if name in _HOME and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(__all__))


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("seactl")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0+unknown"


sys.modules[__name__].__class__ = _Namespace
