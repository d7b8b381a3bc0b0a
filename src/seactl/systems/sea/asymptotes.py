"""The impedance's asymptotes at low and high frequency."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.systems.sea.impedance import check_frequencies, check_model, check_units, extend_design


# ----------------------------------------------------------------------------- asymptotes
def low_frequency_stiffness(design: Any, model: str = "block-diagram", k_tau: Any = None
                            ) -> np.ndarray:
    """``lim_{s->0} s Z(s)`` [N m/rad]: the virtual stiffness.

    Block diagram: exactly ``K_q`` (the ``1 + beta K_tau`` factors cancel).  Paper:
    ``K_q k_tau (1/beta + K_tau) / (1 + K_tau k_tau)``.
    """
    check_model(model)
    if model == "block-diagram":
        return np.asarray(design.Kq, float)
    kt = extend_design(design, False, None, None, k_tau).k_tau
    return design.Kq * kt * (1 / design.beta + design.Ktau) / (1 + design.Ktau * kt)


def asymptote_case(design: Any) -> np.ndarray:
    """High-frequency case per design: ``"filter"`` (any filter), ``"delay"`` (no filter,
    ``T_qd > 0``) or ``"ideal"``."""
    filt = (np.asarray(design.Tf_qd) > 0) | (np.asarray(design.Tf_taud) > 0)
    return np.where(filt, "filter", np.where(np.asarray(design.T_qd) > 0, "delay", "ideal"))


def high_frequency_asymptote(design: Any, f_hz: Any, model: str = "block-diagram",
                             k_tau: Any = None) -> np.ndarray:
    """High-frequency limit of ``Z(j w)`` (complex, rotary), per design's case.

    * ideal (no delay, no filter): ``k (I_m + g B_tau B_q) / (I_m s)``;
    * delay only: ``k (I_m + g B_tau B_q e^{-T_qd s}) / (I_m s)``, which twists around
      ``k/s`` as the delay factor turns;
    * any filter: ``k / s``, the bare spring.

    ``g = beta`` for the block diagram and ``g = k_tau`` for the paper model.
    """
    check_model(model)
    f = check_frequencies(f_hz)
    s = 2j * np.pi * f
    p = extend_design(design, False, None, None, k_tau)
    g = np.asarray(design.beta if model == "block-diagram" else p.k_tau, float)

    def c(x):
        return np.asarray(x, float)[..., None]

    filt = c((np.asarray(design.Tf_qd) > 0) | (np.asarray(design.Tf_taud) > 0))
    extra = g[..., None] * c(design.Btau) * c(design.Bq) * np.exp(-s * c(design.T_qd))
    return c(design.k) * (c(design.Im) + np.where(filt > 0, 0.0, extra)) / (c(design.Im) * s)


@dataclass(frozen=True)
class Asymptotes:
    """Low- and high-frequency asymptotes of ``Z`` (or ``Z_l``), complex, batch + (F,)."""

    model: str
    f_hz: np.ndarray
    low: np.ndarray
    high: np.ndarray
    case: np.ndarray
    load: bool


def asymptotes(design: Any, f_hz: Any, *, model: str = "block-diagram", load: bool = False,
               load_inertia: Any = None, load_damping: Any = None, units: str = "rotary",
               k_tau: Any = None) -> Asymptotes:
    """The asymptotes drawn dashed on impedance plots.

    ``low = K_low / s`` (:func:`low_frequency_stiffness`); ``high`` is
    :func:`high_frequency_asymptote`, or with the load ``I_j s + b_j`` (``Z -> 0``).
    """
    check_units(units)
    f = check_frequencies(f_hz)
    s = 2j * np.pi * f
    load = load or load_inertia is not None or load_damping is not None
    p = extend_design(design, load, load_inertia, load_damping, k_tau)
    low = np.asarray(low_frequency_stiffness(design, model, k_tau), float)[..., None] / s
    if load:
        high = (np.asarray(p.Ij_load, float)[..., None] * s
                + np.asarray(p.bj_load, float)[..., None])
    else:
        high = high_frequency_asymptote(design, f, model, k_tau)
    shape = np.broadcast_shapes(low.shape, high.shape)
    low, high = np.broadcast_to(low, shape), np.broadcast_to(high, shape)
    if units == "linear":
        r2 = design.actuator.pulley_radius ** 2
        low, high = low / r2, high / r2
    return Asymptotes(model, f, low, high, asymptote_case(design), bool(load))
