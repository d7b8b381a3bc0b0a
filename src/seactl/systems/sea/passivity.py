"""Passivity of the SEA's impedance: a dense scan made certain between its points."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import (
    DesignSubset,
    evaluate_forms,
)
from seactl.errors import InputError
from seactl.systems.sea.impedance import (
    check_model,
    extend_design,
    impedance_forms,
    z_chunked,
    z_raw,
)


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
    proven between its points (:mod:`seactl.certify.realpart`: bounds of the quasi-polynomials'
    derivatives, bisection), and a band narrower than the spacing is found there if it
    exists; a design for which neither can be shown (``Re Z`` touching 0) is
    "not proven" and not passive.  With delays and no filter ``Re Z`` changes sign
    forever as ``w`` grows (the twist around ``k/s``), so the answer depends on the
    range; it is always stated.

    Examples
    --------
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEADesign, Timing
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, 30.0), Timing.from_ms(1, 10, 3))
    >>> bool(passivity(d, (0.1, 1000)).passive)
    False
    """
    from scipy.optimize import elementwise

    check_model(model)
    lo, hi = (float(x) for x in f_range_hz)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise InputError("f_range_hz", (lo, hi), "0 < lo < hi, finite [Hz]")
    load = load or load_inertia is not None or load_damping is not None
    p = extend_design(design, load, load_inertia, load_damping, k_tau)
    shape = p.shape
    n = int(np.prod(shape, dtype=int))
    npts = max(2, int(np.ceil(np.log10(hi / lo) * points_per_decade)) + 1)
    f = np.logspace(np.log10(lo), np.log10(hi), npts)
    z = z_chunked(p, 2j * np.pi * f, model, load).reshape(n, npts)
    tol = 1e-9
    neg = z.real < -tol * np.abs(z)  # relative: a lossless k/s must not count

    def g(x, idx):
        sub = DesignSubset(p, idx.astype(np.intp), shape)
        zz = z_raw(sub, 2j * np.pi * np.exp(x)[..., None], model, load)[..., 0]
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
    """:func:`seactl.certify.realpart.certify_positive` for the block-diagram ``Z`` of the
    designs ``p`` between the points ``w`` [rad/s]."""
    from seactl.certify.realpart import certify_positive

    N, D = evaluate_forms(impedance_forms(), p)
    n = N.shape[0]
    b = np.broadcast_to(np.asarray(p.bj_load, float), p.shape).reshape(n) if load \
        else np.zeros(n)
    return certify_positive(N, D, b, w, tol)


def scan_range(f_hz: np.ndarray) -> tuple[float, float]:
    """The passivity scan range of a frequency grid: ``(min, max)`` (widened by 0.1 % each
    side when the grid is a single frequency)."""
    lo, hi = float(np.min(f_hz)), float(np.max(f_hz))
    return (lo, hi) if hi > lo else (lo / 1.001, hi * 1.001)
