"""SEA impedance ``Z(s) = tau_k / (-s q_j)``: models, load, asymptotes, passivity, Z-region.

Two models are available and every result says which one it used:

``"block-diagram"`` (default)
    Derived from :data:`seactl.systems.sea.loops.SEA_DIAGRAM` with the joint angle ``q_j``
    imposed (cut) and ``q_des = 0``: ``Z = (tau_k/q_j) / (-s)``.  Exact delays
    and both first-order filters.  Its static stiffness ``lim s Z`` is exactly
    ``K_q``, and with every gain at zero it is the bare spring ``k/s``.
``"paper"``
    The paper's printed coefficients ``N_zi``/``D_zi`` (eq. SEA_impedance),
    with the motor torque constant ``k_tau`` (``actuator.motor_torque_constant``,
    rotary N m/A) where the paper prints it.  It equals the block diagram only
    when ``k_tau`` is replaced by ``beta`` (docs/theory/ktau-beta.md); its
    low-frequency stiffness is ``K_q k_tau (1/beta + K_tau) / (1 + K_tau k_tau)``.
    Kept to reproduce the published curves.

Units: ``Z`` relates torque to joint velocity, N m s/rad in rotary joint space
(default); ``units="linear"`` divides by ``r^2`` (pulley radius) to give N s/m.
Frequencies are the last axis, design batches the leading axes.

Examples
--------
>>> from seactl.systems.sea.actuators import UT_SEA
>>> from seactl.systems.sea.design import critically_damped_gains
>>> from seactl.systems.sea.loops import SEADesign
>>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 30.0))
>>> r = impedance(d, [1e-4])
>>> r.model, round(float(r.stiffness[0].real), 1)        # s Z(s) -> K_q at low frequency
('block-diagram', 293.6)
>>> round(float(impedance(d, [1e-4], model="paper").stiffness[0].real), 1)
72.9
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np

from seactl.base.parallel import chunk_size, map_in_threads
from seactl.base.validate import float_array
from seactl.diagram.blockdiagram import (
    Block,
    BlockDiagram,
    DesignSubset,
    QuasiForm,
    Transfer,
)
from seactl.errors import InputError

MODELS = ("block-diagram", "paper")
UNITS = {"rotary": "N m s/rad", "linear": "N s/m"}
_CHUNK_POINTS = 1_000_000  # design x frequency points evaluated at once (bounds memory)


# ----------------------------------------------------------------------------- views
@cache
def impedance_transfer() -> Transfer:
    """``tau_k / q_j`` with ``q_j`` imposed (cut) and ``q_des = 0``; ``Z = -T/s``."""
    from seactl.systems.sea.loops import SEA_DIAGRAM

    return SEA_DIAGRAM.transfer("tau_k", "q_j", cut=("q_j",))


@cache
def impedance_forms() -> tuple[QuasiForm, QuasiForm]:
    """``(N, D)`` with ``Z = N / (s D)`` (no load): the diagram with ``q_j`` imposed by a
    unit block from ``tau_k`` in place of the load, broken at ``q_j``, has the loop
    ``N / D = -tau_k / q_j``
    (:meth:`~seactl.diagram.blockdiagram.BlockDiagram.return_difference`)."""
    from seactl.systems.sea.loops import SEA_DIAGRAM

    blocks = [b for b in SEA_DIAGRAM.blocks if b.dst != "q_j"]
    imposed = Block("imposed_q_j", "tau_k", "q_j", role="plant")
    return BlockDiagram("sea-q_j-imposed", [*blocks, imposed]).return_difference("q_j")


@cache
def compliance_transfer() -> Transfer:
    """``q_j / tau_ext`` of the loaded joint (loop closed): equals ``1/(s Z_l)``."""
    from seactl.systems.sea.loops import SEA_DIAGRAM

    return SEA_DIAGRAM.transfer("q_j", "tau_ext")


class _Extended:
    """A design batch with extra broadcast attributes (load, k_tau), same attribute access."""

    def __init__(self, design: Any, **extra: Any):
        self._design = design
        arrays = {k: np.asarray(v, float) for k, v in extra.items()}
        self._shape = np.broadcast_shapes(tuple(getattr(design, "shape", ())),
                                          *(a.shape for a in arrays.values()))
        self._extra = arrays

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        if name in self._extra:
            return self._extra[name]
        return getattr(self._design, name)

    @property
    def shape(self) -> tuple[int, ...]:
        return self._shape


def check_model(model: str) -> str:
    if model not in MODELS:
        raise InputError("model", model, " or ".join(MODELS))
    return model


def check_units(units: str) -> str:
    if units not in UNITS:
        raise InputError("units", units, " or ".join(UNITS))
    return units


def check_frequencies(f_hz: Any, name: str = "f_hz") -> np.ndarray:
    f = float_array(name, f_hz)
    if f.ndim == 0:
        f = f[None]
    if f.size == 0:
        raise InputError(name, "[]", "at least one frequency [Hz]")
    bad = ~np.isfinite(f) | (f <= 0)
    if bad.any():
        raise InputError(name, float(f[bad].flat[0]), "finite frequencies > 0 [Hz]")
    return f


def extend_design(design: Any, load: bool, load_inertia: Any, load_damping: Any,
            k_tau: Any) -> _Extended:
    extra: dict[str, Any] = {}
    if load:
        Ij = design.Ij if load_inertia is None else load_inertia
        bj = design.bj if load_damping is None else load_damping
        for name, v in (("load_inertia", Ij), ("load_damping", bj)):
            a = np.asarray(v, float)
            if not np.all(np.isfinite(a)) or np.any(a < 0):
                raise InputError(name, float(a[~(np.isfinite(a) & (a >= 0))].flat[0]),
                                 "finite and >= 0")
        extra.update(Ij_load=Ij, bj_load=bj)
    if k_tau is None:
        k_tau = getattr(getattr(design, "actuator", None), "motor_torque_constant", np.nan)
    a = np.asarray(k_tau, float)
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise InputError("k_tau", float(np.ravel(a)[0]), "finite and > 0 [N m/A]")
    extra["k_tau"] = a
    return _Extended(design, **extra)


# ----------------------------------------------------------------------------- paper model
def paper_coefficients(design: Any, s: np.ndarray, k_tau: Any = None
                       ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The printed ``N_z0..N_z4`` and ``D_z0..D_z5`` at complex frequencies ``s``.

    The delay factors ``e^{-T s}`` sit inside the coefficients as printed, so each
    coefficient has the batch shape plus the frequency axis.  ``T_fv``/``T_ftau`` are the
    filter time constants ``1/(2 pi f_c)`` (0 without filter).  ``k_tau`` defaults to
    ``design.k_tau`` or ``design.actuator.motor_torque_constant``.
    """
    p = design
    if k_tau is None:
        k_tau = getattr(p, "k_tau", None)
        if k_tau is None:
            k_tau = p.actuator.motor_torque_constant
    s = np.asarray(s, complex)

    def c(x):
        return np.asarray(x, float)[..., None]

    eqs, eqd, eT = (np.exp(-s * c(T)) for T in (p.T_qs, p.T_qd, p.T_tau))
    return paper_coefficients_from_factors(p, eqs, eqd, eT, k_tau)


def paper_coefficients_from_factors(p: Any, eqs: Any, eqd: Any, eT: Any, k_tau: Any
                                    ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The printed coefficients with the delay factors ``e^{-T_qs s}``, ``e^{-T_qd s}``,
    ``e^{-T_tau s}`` given explicitly (arrays broadcasting against batch + (F,); e.g. 0/1 to
    split the coefficients into their rational parts)."""

    def c(x):
        return np.asarray(x, float)[..., None]

    Im, bm, k, beta = c(p.Im), c(p.bm), c(p.k), c(p.beta)
    Kq, Bq, Kt, Bt = c(p.Kq), c(p.Bq), c(p.Ktau), c(p.Btau)
    Tv, Tt, kt = c(p.Tf_qd), c(p.Tf_taud), c(k_tau)
    N4 = Im * Tt * Tv * beta * k
    N3 = beta * k * (Im * (Tt + Tv) + Tt * Tv * bm)
    N2 = (Im * beta * k + beta * k * bm * (Tt + Tv)
          + k * kt * (Tt + beta * (Bt + Kt * Tt)) * (Bq * eqd + Kq * Tv * eqs))
    N1 = (bm * beta * k + Bq * k * kt * (1 + Kt * beta) * eqd
          + Kq * k * kt * (Tv + Tt + beta * (Bt + Kt * (Tt + Tv))) * eqs)
    N0 = Kq * k * kt * eqs * (1 + Kt * beta)
    D5 = Im * Tt * Tv * beta
    D4 = Im * beta * (Tv + Tt) + Tv * Tt * beta * bm
    D3 = beta * Im + beta * bm * (Tt + Tv) + Tv * k * beta * (Tt + kt * (Bt + Kt * Tt) * eT)
    D2 = beta * (bm + Tt * k + k * kt * (Bt + Kt * Tt) * eT) + Tv * beta * k * (1 + Kt * kt * eT)
    D1 = beta * k * (1 + Kt * kt * eT)
    D0 = np.zeros_like(D1)
    shape = np.broadcast_shapes(*(np.shape(x) for x in (N0, N1, N2, N3, N4, D1, D2, D3, D4,
                                                         D5)))
    N = [np.broadcast_to(x, shape) for x in (N0, N1, N2, N3, N4)]
    D = [np.broadcast_to(x, shape) for x in (D0, D1, D2, D3, D4, D5)]
    return N, D


def _paper_z(p: Any, s: np.ndarray) -> np.ndarray:
    N, D = paper_coefficients(p, s)
    num = sum(c * s**i for i, c in enumerate(N))
    den = sum(c * s**i for i, c in enumerate(D))
    return num / den


# ----------------------------------------------------------------------------- evaluation
def z_raw(p: Any, s: np.ndarray, model: str, load: bool) -> np.ndarray:
    """Rotary ``Z`` (or ``Z_l``) for a design-like ``p`` at ``s`` (last axis)."""
    if model == "paper":
        z = _paper_z(p, s)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            z = impedance_transfer()(p, s) / (-s)
    if load:
        z = z + np.asarray(p.Ij_load, float)[..., None] * s + np.asarray(p.bj_load,
                                                                         float)[..., None]
    return z


def z_chunked(p: _Extended, s: np.ndarray, model: str, load: bool) -> np.ndarray:
    shape = p.shape
    n = int(np.prod(shape, dtype=int))
    if s.ndim != 1 or n * s.size <= _CHUNK_POINTS or n <= 1:
        z = z_raw(p, s, model, load)
        return np.broadcast_to(z, shape + (s.shape[-1],)) if z.shape[:-1] != shape else z
    out = np.empty((n, s.size), complex)
    step = chunk_size(n, _CHUNK_POINTS // s.size)  # (at least a chunk per thread)

    def chunk(idx: np.ndarray) -> None:  # chunks of designs (vectorized inside), bounds memory
        out[idx] = z_raw(DesignSubset(p, idx, shape), s, model, load)

    # one design first: whatever the model derives on first use (sympy, its disk cache) is
    # derived once, in this thread; then the chunks in threads (numpy releases the GIL)
    z_raw(DesignSubset(p, np.arange(1), shape), s[:1], model, load)
    map_in_threads(chunk, [np.arange(a, min(n, a + step)) for a in range(0, n, step)])
    return out.reshape(shape + (s.size,))


@dataclass(frozen=True)
class ImpedanceResponse:
    """``Z(j 2 pi f)`` for a batch of designs.

    Attributes
    ----------
    model : ``"block-diagram"`` or ``"paper"``.
    f_hz : frequencies [Hz] (last axis of ``z``).
    z : complex impedance, batch shape + ``(F,)``, in ``unit``.
    units : ``"rotary"`` (N m s/rad) or ``"linear"`` (N s/m).
    load : whether the joint inertia and damping are included (``Z_l``).
    """

    model: str
    f_hz: np.ndarray
    z: np.ndarray
    units: str
    load: bool

    @property
    def unit(self) -> str:
        return UNITS[self.units]

    @property
    def magnitude(self) -> np.ndarray:
        return np.abs(self.z)

    @property
    def magnitude_db(self) -> np.ndarray:
        """``20 log10 |Z|`` (dB re 1 unit)."""
        with np.errstate(divide="ignore"):
            return 20 * np.log10(np.abs(self.z))

    @property
    def phase_deg(self) -> np.ndarray:
        """Phase [deg], unwrapped along frequency from the first point (in (-180, 180])."""
        return np.degrees(np.unwrap(np.angle(self.z), axis=-1))

    @property
    def stiffness(self) -> np.ndarray:
        """``s Z(s)`` (complex; its real part at low frequency is the virtual stiffness)."""
        return 2j * np.pi * self.f_hz * self.z


def impedance(design: Any, f_hz: Any, *, model: str = "block-diagram", load: bool = False,
              load_inertia: Any = None, load_damping: Any = None, units: str = "rotary",
              k_tau: Any = None) -> ImpedanceResponse:
    """SEA impedance at frequencies ``f_hz`` [Hz] for a design batch.

    Parameters
    ----------
    design : SEADesign
        Batch of designs (actuator, gains, timing).
    f_hz : array_like
        Frequencies [Hz] > 0 (last axis).
    model : {"block-diagram", "paper"}
        See the module docstring.
    load : bool
        Add the joint inertia and damping: ``Z_l = Z + I_j s + b_j``.
    load_inertia, load_damping : array_like, optional
        Override ``I_j`` [kg m^2] / ``b_j`` [N m s/rad] (broadcast with the batch).
    units : {"rotary", "linear"}
        Rotary N m s/rad, or linear N s/m (divided by the pulley radius squared).
    k_tau : array_like, optional
        Motor torque constant [N m/A] of the ``paper`` model (default: the actuator's).
    """
    check_model(model)
    check_units(units)
    f = check_frequencies(f_hz)
    load = load or load_inertia is not None or load_damping is not None
    p = extend_design(design, load, load_inertia, load_damping, k_tau)
    s = 2j * np.pi * f
    z = z_chunked(p, s, model, load)
    if units == "linear":
        z = z / design.actuator.pulley_radius ** 2
    return ImpedanceResponse(model, f, z, units, bool(load))


def loaded_impedance_from_compliance(design: Any, f_hz: Any) -> np.ndarray:
    """``Z_l = 1 / (s * q_j/tau_ext)`` from the closed diagram (a second route to ``Z_l``)."""
    f = check_frequencies(f_hz)
    s = 2j * np.pi * f
    return 1.0 / (s * compliance_transfer()(design, s))
