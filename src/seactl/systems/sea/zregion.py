"""The Z-region: the impedances reachable over a design grid."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.errors import InfeasibleDesignError, InputError
from seactl.systems.sea.asymptotes import Asymptotes
from seactl.systems.sea.impedance import (
    ImpedanceResponse,
    check_frequencies,
    check_model,
    impedance,
)
from seactl.systems.sea.passivity import passivity, scan_range


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
    from seactl.systems.sea.views import sea_margins

    check_model(model)
    f = check_frequencies(f_hz)
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
