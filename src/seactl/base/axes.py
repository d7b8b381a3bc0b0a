"""The design axes: one table of every quantity a design is built from.

Each :class:`AxisInfo` names a quantity once: its parameter name (used by the library and as
the column of sweep results), its command-line flag, unit, default and valid range.  The
shared design options of every command (:func:`seactl.apps.commands.common.design_options`),
the sweep axes (:mod:`seactl.sweep.engine`) and the CLI's translation of library errors into
flags are all generated from :data:`AXES`.

Examples
--------
>>> from seactl.base.axes import AXES
>>> AXES["t_qs_ms"].option, AXES["t_qs_ms"].unit
('--t-qs', 'ms')
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from seactl.errors import InputError


@dataclass(frozen=True)
class AxisInfo:
    """A design quantity: parameter name, CLI flag, unit, default (``None``: from the
    actuator), smallest valid value (exclusive when ``strict``), and whether ``inf`` is
    allowed (filters: no filter)."""

    name: str
    option: str
    unit: str
    default: float | None
    minimum: float = 0.0
    strict: bool = True
    description: str = ""
    allow_inf: bool = False
    maximum: float = math.inf

    @property
    def label(self) -> str:
        """The flag with its unit, as error messages at the command line show it."""
        return self.option + (f" [{self.unit}]" if self.unit else "")

    def check(self, values, label: str | None = None) -> np.ndarray:
        """``values`` as a float array, or :class:`InputError` naming ``label`` (default:
        the parameter name), the first bad value and the valid range."""
        vals = np.asarray(values, float)
        label = label or self.name
        if np.isnan(vals).any():
            raise InputError(label, float("nan"), "a number")
        bad_inf = np.isinf(vals) & ~(self.allow_inf & (vals > 0))
        if bad_inf.any():
            raise InputError(label, float(vals[bad_inf][0]), "finite")
        low = vals <= self.minimum if self.strict else vals < self.minimum
        if low.any():
            raise InputError(label, float(vals[low][0]),
                             f"{'>' if self.strict else '>='} {self.minimum:g}"
                             + (" (inf: no filter)" if self.allow_inf else ""))
        high = np.isfinite(vals) & (vals > self.maximum)
        if high.any():
            raise InputError(label, float(vals[high][0]), f"<= {self.maximum:g} {self.unit}")
        return vals


MAX_DELAY_MS = 1000.0
"""Largest delay accepted anywhere [ms]; larger values are almost surely a unit slip."""

_DELAY = dict(strict=False, maximum=MAX_DELAY_MS)
_FILTER = dict(allow_inf=True, minimum=1e-3, maximum=1e6)
_FN = dict(minimum=1e-3, strict=False, maximum=1000.0)
_GS = dict(minimum=1e-3, strict=False, maximum=1000.0)
_FACTOR = dict(minimum=1e-2, strict=False, maximum=100.0)
"""Ranges of f_n [Hz], GS and the damping/pole ratios: values outside overflow the gains
(1e-308 divides to inf) and describe no physical joint controller."""
"""Filter cut-offs: above 1 mHz (lower ones overflow the filter's state), up to 1 MHz."""


def _axis(name, option, unit, default, description, **kw) -> AxisInfo:
    return AxisInfo(name, option, unit, default, description=description, **kw)


AXES: dict[str, AxisInfo] = {a.name: a for a in (
    _axis("fn_hz", "--fn", "Hz", 14.0, "natural frequency f_n", **_FN),
    _axis("gs", "--gs", "", 1.0, "gain scale GS (torque gains x GS, impedance gains / GS)",
          **_GS),
    _axis("zeta1", "--zeta1", "", 1.0, "damping ratio of the first pole pair", **_FACTOR),
    _axis("zeta2", "--zeta2", "", 1.0, "damping ratio of the second pole pair", **_FACTOR),
    _axis("ratio", "--ratio", "", 1.0, "ratio w2 / w1 of the two pole pairs", **_FACTOR),
    _axis("t_tau_ms", "--t-tau", "ms", 0.0, "torque-feedback delay T_tau", **_DELAY),
    _axis("t_qs_ms", "--t-qs", "ms", 0.0, "stiffness-feedback delay T_qs", **_DELAY),
    _axis("t_qd_ms", "--t-qd", "ms", 0.0, "damping-feedback delay T_qd", **_DELAY),
    _axis("f_qd_hz", "--f-qd", "Hz", math.inf, "velocity filter cut-off f_qd",
          **_FILTER),
    _axis("f_taud_hz", "--f-taud", "Hz", math.inf, "torque-derivative filter cut-off f_taud",
          **_FILTER),
    _axis("Im", "--im", "kg m^2", None, "motor inertia (plant)"),
    _axis("Ij", "--ij", "kg m^2", None, "joint inertia (plant)"),
    _axis("bm", "--bm", "N m s/rad", None, "motor damping (plant)", strict=False),
    _axis("bj", "--bj", "N m s/rad", None, "joint damping (plant)", strict=False),
    _axis("k", "--k", "N m/rad", None, "spring stiffness (plant)"),
    _axis("beta", "--beta", "N m/A", None, "current to torque (plant)"),
)}
"""Every design axis, in canonical order (the order of sweep columns)."""

DESIGN_AXES = tuple(AXES)[:10]
"""The controller axes (gain design, delays, filters) shared by every design command."""

ACTUATOR_AXES = tuple(AXES)[10:]
"""The plant axes, paper symbols of :class:`~seactl.systems.sea.actuators.SEAParams` fields."""

ACTUATOR_FIELDS = dict(Im="motor_inertia", Ij="joint_inertia", bm="motor_damping",
                       bj="joint_damping", k="spring_stiffness", beta="current_to_torque")
"""Plant axis -> :class:`~seactl.systems.sea.actuators.SEAParams` field."""

SAMPLINGS = ("grid", "random", "lhs")
"""How a sweep samples its axes: Cartesian grid, uniform random, Latin hypercube."""
