"""Latency-robust ``f_n``: the largest ``f_n`` admissible over a box of loop latencies.

A placement gives each loop a latency ``T_i`` (stiffness, damping and, for the SEA, the
torque loop).  Its score is the largest critically-damped ``f_n`` such that at every
``f_n`` from the model's lowest up to it, and at **every** combination of loop latencies
``T'`` with ``0 <= T'_i <= (1 + latency_margin) T_i``, the closed loop is stable with a
phase margin of at least ``min_pm_deg`` (and, optionally, passes a further check such as
jitter margins).  Each loop therefore tolerates any shorter latency and
``latency_margin`` (a fraction) more than it gets.

Because the box of a loop's latencies only grows when that latency grows, the score can
never rise when any loop's latency rises: it is monotone by construction, which the
phase margin at the nominal latencies alone is not (a delay on the rigid actuator's
stiffness loop can raise the phase margin while the loop's delay margin falls).

The box is checked at the points of a fixed latency lattice: 0 and
:data:`LATTICE_BASE_S` times powers of :data:`LATTICE_RATIO`, each axis up to the first
lattice point at or above its upper end (rounded up, so the longest latency checked is
never shorter than the one asked for).  The lattice does not depend on the latencies,
so a larger box holds every point of a smaller one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

LATTICE_BASE_S = 0.1e-3
"""Smallest non-zero latency of the lattice [s]."""
LATTICE_RATIO = 2.0 ** (1.0 / 4.0)
"""Ratio between neighbouring non-zero lattice latencies (four points per doubling)."""
CHUNK_DESIGNS = 20_000
"""Designs evaluated in one batch (bounds the memory of one margin computation)."""
SECONDS_PER_POINT = 1e-3
"""Estimated time per latency combination of a score (some 50 margin evaluations), for
refusing work up front."""


def latency_lattice_s(upper_s: float) -> np.ndarray:
    """Lattice latencies [s] covering ``[0, upper_s]``: 0, the lattice points below
    ``upper_s`` and the first one at or above it."""
    upper_s = float(upper_s)
    if upper_s <= 0:
        return np.zeros(1)
    k_top = int(np.ceil(np.log(max(upper_s, LATTICE_BASE_S) / LATTICE_BASE_S)
                        / np.log(LATTICE_RATIO) - 1e-9))
    pts = LATTICE_BASE_S * LATTICE_RATIO ** np.arange(k_top + 1)
    if pts[-1] < upper_s:                     # guard against rounding in the log
        pts = np.append(pts, pts[-1] * LATTICE_RATIO)
    return np.concatenate([[0.0], pts])


@dataclass(frozen=True)
class RobustFn:
    """Latency-robust ``f_n`` of one placement.

    Attributes
    ----------
    fn_hz : the score [Hz]: NaN when already the lowest ``f_n`` fails (``status ==
        "none"``), the scan limit when nothing fails up to it (``"capped"``).
    status : ``"ok"``, ``"none"`` or ``"capped"``.
    box_upper_s : the upper end of each loop's latency range, lattice-rounded [s].
    n_points : number of latency combinations checked.
    limit : what fails just above ``fn_hz`` (or at the lowest ``f_n``): ``constraint``
        (``"unstable"``, ``"phase margin"`` or the name of the further check), the
        ``latencies_s`` where it fails and the failing ``fn_hz``; None when capped.
    """

    fn_hz: float
    status: str
    box_upper_s: dict[str, float]
    n_points: int
    limit: dict[str, Any] | None


def box_size(latencies_s: dict[str, float], latency_margin: float) -> int:
    """Number of latency combinations :func:`robust_max_fn` checks."""
    n = 1
    for t in latencies_s.values():
        n *= latency_lattice_s((1.0 + latency_margin) * float(t)).size
    return n


def box_points(latencies_s: dict[str, float], latency_margin: float) -> dict[str, np.ndarray]:
    """Every lattice combination of the box, flattened: name -> latencies [s]."""
    axes = [latency_lattice_s((1.0 + latency_margin) * float(t)) for t in latencies_s.values()]
    mesh = np.meshgrid(*axes, indexing="ij")
    return {k: m.reshape(-1) for k, m in zip(latencies_s, mesh)}


Check = Callable[[Any, Any], np.ndarray]
"""``check(design, margins) -> bool array``: a further criterion at each design."""


def _failures(model: Any, fn: np.ndarray, pts: dict[str, np.ndarray], min_pm_deg: float,
              check: Check | None) -> np.ndarray:
    """Failure code per (f_n, point): 0 ok, 1 unstable, 2 phase margin, 3 ``check``."""
    fn = np.asarray(fn, float)
    n = next(iter(pts.values())).size
    out = np.zeros((fn.size, n), np.int8)
    step = max(1, CHUNK_DESIGNS // max(fn.size, 1))
    for a in range(0, n, step):
        sl = {k: v[None, a:a + step] for k, v in pts.items()}
        ts, td = sl.pop("T_s"), sl.pop("T_d")
        d = model.design(fn[:, None], ts, td, **sl)
        m = model.margins(d)
        code = np.where(~m.stable, 1, np.where(m.phase_margin_deg < min_pm_deg, 2, 0))
        if check is not None:
            code = np.where((code == 0) & ~np.asarray(check(d, m), bool), 3, code)
        out[:, a:a + step] = code
    return out


_CODE = {1: "unstable", 2: "phase margin"}


def _limit(codes: np.ndarray, pts: dict[str, np.ndarray], check_name: str, fn_hz: float
           ) -> dict[str, Any]:
    """The first failing latency combination (the constraint and where it fails)."""
    j = int(np.argmax(codes != 0))
    return {"constraint": _CODE.get(int(codes[j]), check_name),
            "latencies_s": {k: float(v[j]) for k, v in pts.items()}, "fn_hz": float(fn_hz)}


def robust_max_fn(model: Any, latencies_s: dict[str, float], *, min_pm_deg: float,
                  latency_margin: float, check: Check | None = None,
                  check_name: str = "check", fn_hi: float | None = None, n_scan: int = 32,
                  rtol: float = 1e-4) -> RobustFn:
    """The latency-robust ``f_n`` of one placement (see the module docstring).

    ``latencies_s``: ``{"T_s": .., "T_d": ..}`` plus ``"T_tau"`` for the SEA [s].  ``f_n``
    is scanned on ``n_scan`` log-spaced values from the model's lowest to ``fn_hi``
    (default the model's highest), in ascending batches until the first failure, then
    bisected to ``rtol``; the answer is the top of the first passing range.  A longer
    latency adds lattice points, so it fails at every ``f_n`` where the shorter one fails:
    its first failing scan value is no later and, in a shared bracket, the bisection ends
    no higher.
    """
    lo = float(model.fn_limits[0])
    hi = float(model.fn_limits[1] if fn_hi is None else fn_hi)
    pts = box_points(latencies_s, latency_margin)
    upper = {k: float(v.max()) for k, v in pts.items()}
    n = next(iter(pts.values())).size

    def codes(fn):
        return _failures(model, fn, pts, min_pm_deg, check)

    first = codes(np.array([lo]))[0]
    if np.any(first):
        return RobustFn(float("nan"), "none", upper, n, _limit(first, pts, check_name, lo))
    if hi <= lo:
        return RobustFn(lo, "capped", upper, n, None)
    scan = np.geomspace(lo, hi, n_scan)
    a_f = b_f = last = None
    for s in range(1, n_scan, 4):
        fs = scan[s:s + 4]
        cs = codes(fs)
        bad = np.any(cs != 0, axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            a_f, b_f, last = scan[s + k - 1], fs[k], cs[k]
            break
    if a_f is None:
        return RobustFn(hi, "capped", upper, n, None)
    while b_f / a_f > 1 + rtol:
        mid = np.sqrt(a_f * b_f)
        c = codes(np.array([mid]))[0]
        if np.any(c):
            b_f, last = mid, c
        else:
            a_f = mid
    return RobustFn(float(a_f), "ok", upper, n, _limit(last, pts, check_name, b_f))
