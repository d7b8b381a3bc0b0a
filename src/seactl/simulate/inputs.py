"""Exogenous inputs of a simulation: step, sine, impulse, and joint friction."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


# ----------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class Step:
    """Step of ``amplitude`` at ``t0_s`` (default 0)."""

    amplitude: float = 1.0
    t0_s: float = 0.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return np.where(t >= self.t0_s, self.amplitude, 0.0)

    @property
    def scale(self) -> float:
        return abs(self.amplitude)


@dataclass(frozen=True)
class Sine:
    """``amplitude sin(2 pi freq_hz t + phase_rad)`` for ``t >= 0``."""

    amplitude: float
    freq_hz: float
    phase_rad: float = 0.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return self.amplitude * np.sin(2 * np.pi * self.freq_hz * t + self.phase_rad)

    @property
    def scale(self) -> float:
        return abs(self.amplitude)


@dataclass(frozen=True)
class Impulse:
    """Dirac impulse of ``area`` at ``t = 0`` (applied exactly, as a state jump)."""

    area: float = 1.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return np.zeros_like(t)

    @property
    def scale(self) -> float:
        return abs(self.area)


@dataclass(frozen=True)
class Friction:
    """Coulomb plus viscous friction ``-(coulomb sign(v) + viscous v)`` added to the plant
    signal ``signal`` (a torque sum), ``v`` the time derivative of plant signal ``velocity_of``
    (a position; sampled mode only)."""

    signal: str
    velocity_of: str
    coulomb: float = 0.0
    viscous: float = 0.0
