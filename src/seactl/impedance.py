"""SEA impedance ``Z(s) = tau_k / (-s q_j)``: models, load, asymptotes, passivity, Z-region.

Two models are available and every result says which one it used:

``"block-diagram"`` (default)
    Derived from :data:`seactl.loops.SEA_DIAGRAM` with the joint angle ``q_j``
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
>>> from seactl.actuators import UT_SEA
>>> from seactl.design import critically_damped_gains
>>> from seactl.loops import SEADesign
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

from ._parallel import chunk_size, map_in_threads
from ._validate import float_array
from .blockdiagram import (
    Block,
    BlockDiagram,
    DesignSubset,
    QuasiForm,
    Transfer,
    evaluate_forms,
)
from .errors import InfeasibleDesignError, InputError

MODELS = ("block-diagram", "paper")
UNITS = {"rotary": "N m s/rad", "linear": "N s/m"}
_CHUNK_POINTS = 1_000_000  # design x frequency points evaluated at once (bounds memory)


# ----------------------------------------------------------------------------- views
@cache
def impedance_transfer() -> Transfer:
    """``tau_k / q_j`` with ``q_j`` imposed (cut) and ``q_des = 0``; ``Z = -T/s``."""
    from .loops import SEA_DIAGRAM

    return SEA_DIAGRAM.transfer("tau_k", "q_j", cut=("q_j",))


@cache
def _impedance_forms() -> tuple[QuasiForm, QuasiForm]:
    """``(N, D)`` with ``Z = N / (s D)`` (no load): the diagram with ``q_j`` imposed by a
    unit block from ``tau_k`` in place of the load, broken at ``q_j``, has the loop
    ``N / D = -tau_k / q_j`` (:meth:`~seactl.blockdiagram.BlockDiagram.return_difference`)."""
    from .loops import SEA_DIAGRAM

    blocks = [b for b in SEA_DIAGRAM.blocks if b.dst != "q_j"]
    imposed = Block("imposed_q_j", "tau_k", "q_j", role="plant")
    return BlockDiagram("sea-q_j-imposed", [*blocks, imposed]).return_difference("q_j")


@cache
def compliance_transfer() -> Transfer:
    """``q_j / tau_ext`` of the loaded joint (loop closed): equals ``1/(s Z_l)``."""
    from .loops import SEA_DIAGRAM

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


def _check_model(model: str) -> str:
    if model not in MODELS:
        raise InputError("model", model, " or ".join(MODELS))
    return model


def _check_units(units: str) -> str:
    if units not in UNITS:
        raise InputError("units", units, " or ".join(UNITS))
    return units


def _check_freq(f_hz: Any, name: str = "f_hz") -> np.ndarray:
    f = float_array(name, f_hz)
    if f.ndim == 0:
        f = f[None]
    if f.size == 0:
        raise InputError(name, "[]", "at least one frequency [Hz]")
    bad = ~np.isfinite(f) | (f <= 0)
    if bad.any():
        raise InputError(name, float(f[bad].flat[0]), "finite frequencies > 0 [Hz]")
    return f


def _extend(design: Any, load: bool, load_inertia: Any, load_damping: Any,
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
def _z_raw(p: Any, s: np.ndarray, model: str, load: bool) -> np.ndarray:
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


def _z_chunked(p: _Extended, s: np.ndarray, model: str, load: bool) -> np.ndarray:
    shape = p.shape
    n = int(np.prod(shape, dtype=int))
    if s.ndim != 1 or n * s.size <= _CHUNK_POINTS or n <= 1:
        z = _z_raw(p, s, model, load)
        return np.broadcast_to(z, shape + (s.shape[-1],)) if z.shape[:-1] != shape else z
    out = np.empty((n, s.size), complex)
    step = chunk_size(n, _CHUNK_POINTS // s.size)  # (at least a chunk per thread)

    def chunk(idx: np.ndarray) -> None:  # chunks of designs (vectorized inside), bounds memory
        out[idx] = _z_raw(DesignSubset(p, idx, shape), s, model, load)

    # one design first: whatever the model derives on first use (sympy, its disk cache) is
    # derived once, in this thread; then the chunks in threads (numpy releases the GIL)
    _z_raw(DesignSubset(p, np.arange(1), shape), s[:1], model, load)
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
    _check_model(model)
    _check_units(units)
    f = _check_freq(f_hz)
    load = load or load_inertia is not None or load_damping is not None
    p = _extend(design, load, load_inertia, load_damping, k_tau)
    s = 2j * np.pi * f
    z = _z_chunked(p, s, model, load)
    if units == "linear":
        z = z / design.actuator.pulley_radius ** 2
    return ImpedanceResponse(model, f, z, units, bool(load))


def loaded_impedance_from_compliance(design: Any, f_hz: Any) -> np.ndarray:
    """``Z_l = 1 / (s * q_j/tau_ext)`` from the closed diagram (a second route to ``Z_l``)."""
    f = _check_freq(f_hz)
    s = 2j * np.pi * f
    return 1.0 / (s * compliance_transfer()(design, s))


# ----------------------------------------------------------------------------- asymptotes
def low_frequency_stiffness(design: Any, model: str = "block-diagram", k_tau: Any = None
                            ) -> np.ndarray:
    """``lim_{s->0} s Z(s)`` [N m/rad]: the virtual stiffness.

    Block diagram: exactly ``K_q`` (the ``1 + beta K_tau`` factors cancel).  Paper:
    ``K_q k_tau (1/beta + K_tau) / (1 + K_tau k_tau)``.
    """
    _check_model(model)
    if model == "block-diagram":
        return np.asarray(design.Kq, float)
    kt = _extend(design, False, None, None, k_tau).k_tau
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
    _check_model(model)
    f = _check_freq(f_hz)
    s = 2j * np.pi * f
    p = _extend(design, False, None, None, k_tau)
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
    _check_units(units)
    f = _check_freq(f_hz)
    s = 2j * np.pi * f
    load = load or load_inertia is not None or load_damping is not None
    p = _extend(design, load, load_inertia, load_damping, k_tau)
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


# ----------------------------------------------------------------------------- passivity
@dataclass(frozen=True)
class Passivity:
    """Where ``Re Z(j w) < 0`` (the actuator injects energy into its environment).

    Attributes
    ----------
    model : model used.
    f_range_hz : (lo, hi) scanned range [Hz]; nothing is claimed outside it.
    passive : bool array (batch shape): ``Re Z > 0`` on the whole range, proven
        (block-diagram model; the paper model's is the scan's).
    bands_hz : object array (batch shape) of ``(n, 2)`` float arrays ``[lo, hi]`` [Hz].
    points_per_decade : scan density; edges are then solved exactly (root finding).
    proven : bool array (batch shape): the verdict is proven, "not passive" by a
        frequency with ``Re Z < 0``, "passive" by the certificate.  False where neither
        could be shown (``Re Z`` touching 0, the paper model's "passive"): such a design
        is not ``passive``, and its ``bands_hz`` may be empty.
    """

    model: str
    f_range_hz: tuple[float, float]
    passive: np.ndarray
    bands_hz: np.ndarray
    points_per_decade: int
    load: bool
    proven: np.ndarray


CERTIFY_EVERY = 16
"""The passivity certificate starts from every this many points of the scan's grid."""


def passivity(design: Any, f_range_hz: tuple[float, float] = (0.01, 1e4), *,
              model: str = "block-diagram", load: bool = False, load_inertia: Any = None,
              load_damping: Any = None, k_tau: Any = None,
              points_per_decade: int = 400) -> Passivity:
    """Non-passive bands of ``Z`` (or ``Z_l``) inside ``f_range_hz``.

    ``Re Z`` is scanned on a log grid; every sign change is then solved on the exact
    function (``scipy.optimize.elementwise.find_root`` in log frequency), so band edges
    are exact to ~1e-10 relative.  Where the scan finds no band, ``Re Z > 0`` is then
    proven between its points (:mod:`seactl._realpart`: bounds of the quasi-polynomials'
    derivatives, bisection), and a band narrower than the spacing is found there if it
    exists; a design for which neither can be shown (``Re Z`` touching 0) is
    "not proven" and not passive.  With delays and no filter ``Re Z`` changes sign
    forever as ``w`` grows (the twist around ``k/s``), so the answer depends on the
    range; it is always stated.

    Examples
    --------
    >>> from seactl.actuators import UT_SEA
    >>> from seactl.design import critically_damped_gains
    >>> from seactl.loops import SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 30.0), Timing.from_ms(1, 10, 3))
    >>> bool(passivity(d, (0.1, 1000)).passive)
    False
    """
    from scipy.optimize import elementwise

    _check_model(model)
    lo, hi = (float(x) for x in f_range_hz)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise InputError("f_range_hz", (lo, hi), "0 < lo < hi, finite [Hz]")
    load = load or load_inertia is not None or load_damping is not None
    p = _extend(design, load, load_inertia, load_damping, k_tau)
    shape = p.shape
    n = int(np.prod(shape, dtype=int))
    npts = max(2, int(np.ceil(np.log10(hi / lo) * points_per_decade)) + 1)
    f = np.logspace(np.log10(lo), np.log10(hi), npts)
    z = _z_chunked(p, 2j * np.pi * f, model, load).reshape(n, npts)
    tol = 1e-9
    neg = z.real < -tol * np.abs(z)  # relative: a lossless k/s must not count

    def g(x, idx):
        sub = DesignSubset(p, idx.astype(np.intp), shape)
        zz = _z_raw(sub, 2j * np.pi * np.exp(x)[..., None], model, load)[..., 0]
        return zz.real / np.abs(zz) + tol

    di, fi = np.nonzero(neg[:, 1:] != neg[:, :-1])
    # brackets of band edges: (design, lo, hi [Hz], whether a band starts there)
    bd, blo, bhi, bstart = di, f[fi], f[fi + 1], ~neg[di, fi]
    passive = ~neg.any(axis=1)
    proven = ~passive  # (a band is proven by its points)
    if model == "block-diagram" and passive.any():
        i = np.nonzero(passive)[0]
        fc = f[np.unique(np.r_[0:npts:CERTIFY_EVERY, npts - 1])]  # (it bisects as needed)
        ok, found = _prove_passive(DesignSubset(p, i, shape), 2 * np.pi * fc, load, tol)
        passive[i], proven[i] = ok, ok | ~np.isnan(found).all(axis=1)
        # a band between grid points k and k + 1: edges on each side of the point found
        j, k = np.nonzero(~np.isnan(found))
        w = found[j, k] / (2 * np.pi)
        bd, blo, bhi = (np.concatenate(x) for x in ((bd, i[j], i[j]), (blo, fc[k], w),
                                                    (bhi, w, fc[k + 1])))
        bstart = np.concatenate([bstart, np.ones(j.size, bool), np.zeros(j.size, bool)])
    edges = np.empty(0)
    if bd.size:
        res = elementwise.find_root(g, (np.log(blo), np.log(bhi)), args=(bd.astype(float),),
                                    tolerances={"xatol": 1e-12, "xrtol": 1e-12})
        edges = np.where(res.success, np.exp(res.x), np.sqrt(blo * bhi))
    bands = np.empty(n, object)
    for i in range(n):  # assembling per-design band lists (not a hot loop: edges are few)
        mine = bd == i
        starts, ends = list(edges[mine & bstart]), list(edges[mine & ~bstart])
        if neg[i, 0]:
            starts.insert(0, lo)
        if neg[i, -1]:
            ends.append(hi)
        bands[i] = np.array(sorted(zip(sorted(starts), sorted(ends))), float).reshape(-1, 2)
    return Passivity(model, (lo, hi), passive.reshape(shape), bands.reshape(shape),
                     int(points_per_decade), bool(load), proven.reshape(shape))


def _prove_passive(p: Any, w: np.ndarray, load: bool, tol: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`seactl._realpart.certify_positive` for the block-diagram ``Z`` of the
    designs ``p`` between the points ``w`` [rad/s]."""
    from ._realpart import certify_positive

    N, D = evaluate_forms(_impedance_forms(), p)
    n = N.shape[0]
    b = np.broadcast_to(np.asarray(p.bj_load, float), p.shape).reshape(n) if load \
        else np.zeros(n)
    return certify_positive(N, D, b, w, tol)


def scan_range(f_hz: np.ndarray) -> tuple[float, float]:
    """The passivity scan range of a frequency grid: ``(min, max)`` (widened by 0.1 % each
    side when the grid is a single frequency)."""
    lo, hi = float(np.min(f_hz)), float(np.max(f_hz))
    return (lo, hi) if hi > lo else (lo / 1.001, hi * 1.001)


# ----------------------------------------------------------------------------- Z-region
@dataclass(frozen=True)
class ZRegion:
    """Z-region of a design set (definition in ``docs/zregion.md``).

    Attributes
    ----------
    model : model used.
    f_hz : frequency grid [Hz].
    z_min, z_max : smallest / largest ``|Z|`` over the admissible designs, per frequency.
    width_db : Z-width ``20 log10(z_max / z_min)`` [dB], per frequency.
    threshold_db : width threshold defining the Z-depth.
    depth_hz : ``(f_lo, f_hi)``: the band starting at the lowest frequency where the width
        stays >= threshold (``f_hi`` interpolated in log f), or ``None`` if the width is
        below threshold already at ``f_hz[0]``.
    depth_decades : ``log10(f_hi / f_lo)`` (0 when ``depth_hz`` is None).
    admissible, stable, passive : bool arrays (batch shape).
    phase_margin_deg : outer-loop phase margin (batch shape).
    min_pm_deg, require_passive : the admissibility rule used.
    argmin, argmax : flat index of the design attaining ``z_min``/``z_max`` per frequency.
    magnitude : ``|Z|`` of every design, batch + (F,).
    """

    model: str
    f_hz: np.ndarray
    z_min: np.ndarray
    z_max: np.ndarray
    width_db: np.ndarray
    threshold_db: float
    depth_hz: tuple[float, float] | None
    depth_decades: float
    admissible: np.ndarray
    stable: np.ndarray
    passive: np.ndarray
    phase_margin_deg: np.ndarray
    min_pm_deg: float
    require_passive: bool
    load: bool
    argmin: np.ndarray
    argmax: np.ndarray
    magnitude: np.ndarray

    @property
    def n_admissible(self) -> int:
        return int(self.admissible.sum())


def zregion(designs: Any, f_hz: Any, *, min_pm_deg: float = 30.0,
            require_passive: bool = False, threshold_db: float = 6.0,
            model: str = "block-diagram", load: bool = False) -> ZRegion:
    """Z-width and Z-depth of a design batch (e.g. an f_n x GS grid).

    A design is admissible when its cascaded loop is stable (Nyquist, exact delays) with
    an outer-loop phase margin >= ``min_pm_deg`` and, if ``require_passive``, when
    ``Re Z >= 0`` over the whole frequency grid's range.  Raises
    :class:`~seactl.errors.InfeasibleDesignError` when no design is admissible.
    """
    from .sea import sea_margins

    _check_model(model)
    f = _check_freq(f_hz)
    for name, v in (("min_pm_deg", min_pm_deg), ("threshold_db", threshold_db)):
        if not np.isfinite(v):
            raise InputError(name, v, "a finite number")
    if threshold_db <= 0:
        raise InputError("threshold_db", threshold_db, "> 0 [dB]")
    shape = tuple(designs.shape)
    m = sea_margins(designs)
    stable = np.asarray(m.stable, bool)
    pm = np.asarray(m.phase_margin_deg, float)
    ok = stable & (pm >= min_pm_deg)
    pas = passivity(designs, scan_range(f), model=model, load=load).passive
    if require_passive:
        ok = ok & pas
    n_total = int(np.prod(shape, dtype=int))
    if not ok.any():
        rule = f"stable with phase margin >= {min_pm_deg:g} deg" + (
            " and passive" if require_passive else "")
        raise InfeasibleDesignError(
            f"no admissible design: 0 of {n_total} designs are {rule} "
            f"(best phase margin {np.nanmax(np.where(stable, pm, -np.inf)):.3g} deg among "
            f"{int(stable.sum())} stable)")
    mag = impedance(designs, f, model=model, load=load).magnitude.reshape(n_total, f.size)
    flat_ok = ok.reshape(-1)
    big = np.where(flat_ok[:, None], mag, -np.inf)
    small = np.where(flat_ok[:, None], mag, np.inf)
    imax, imin = np.argmax(big, axis=0), np.argmin(small, axis=0)
    zmax, zmin = mag[imax, np.arange(f.size)], mag[imin, np.arange(f.size)]
    width = 20 * np.log10(zmax / zmin)
    depth, dec = _depth(f, width, threshold_db)
    return ZRegion(model, f, zmin, zmax, width, float(threshold_db), depth, dec, ok, stable,
                   pas, pm, float(min_pm_deg), bool(require_passive), bool(load), imin, imax,
                   mag.reshape(shape + (f.size,)))


def _depth(f: np.ndarray, width: np.ndarray, thr: float) -> tuple[tuple[float, float] | None,
                                                                   float]:
    order = np.argsort(f)
    f, width = f[order], width[order]
    below = np.nonzero(width < thr)[0]
    if below.size and below[0] == 0:
        return None, 0.0
    if not below.size:
        return (float(f[0]), float(f[-1])), float(np.log10(f[-1] / f[0]))
    j = below[0]  # first grid point under the threshold; interpolate in log f
    x0, x1 = np.log10(f[j - 1]), np.log10(f[j])
    t = (width[j - 1] - thr) / (width[j - 1] - width[j])
    hi = float(10 ** (x0 + t * (x1 - x0)))
    return (float(f[0]), hi), float(np.log10(hi / f[0]))


def excess_over_asymptotes_db(resp: ImpedanceResponse, asym: Asymptotes) -> np.ndarray:
    """``20 log10(|Z| / max(|low|, |high|))`` [dB] per frequency: how far ``|Z|`` rises above
    the envelope of its asymptotes (the mid-frequency "spike"; <= 0 where it stays under)."""
    env = np.maximum(np.abs(asym.low), np.abs(asym.high))
    return 20 * np.log10(np.abs(resp.z) / env)
