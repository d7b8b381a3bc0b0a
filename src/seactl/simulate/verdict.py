"""Honest verdicts on time-domain responses: settled, not settled, unstable, limit cycle,
saturated, each with its evidence.

A simulation's ``stable`` flag (bounded and decaying) cannot tell a loop that chatters at
the current limit from one that settles: a sampled controller with unfiltered derivatives
rings at the Nyquist frequency with the current bouncing between the limits while the
joint barely moves.  :func:`judge` reads the recorded signals and decides, in this order:

``unstable``
    the output left the simulation's bound, or the deviation from the target grows: its
    envelope (maximum per segment, five segments over the judged window) fits an
    exponential whose growth over the judged window exceeds a factor 2, and it ends
    outside the band; or, when the caller gives it, the loop's certified count of
    closed-loop roots in the right half-plane is not 0 (a slowly growing or weakly
    excited mode that the simulated window cannot show is still unstable); for a sampled
    loop the count is of the lifted map's eigenvalues outside the unit circle
    (:func:`seactl.simulate.period.sampled_unstable_modes`);
``limit cycle``
    a sustained oscillation: in the last quarter of the window the oscillation (signal
    minus its linear trend) of the position exceeds the band, or that of the current
    exceeds 10 % of the current limit (of the peak current without a limit), and it is not
    decaying (its amplitude, from the last two quarters, would keep 90 % over the window);
``saturated``
    the actuation reached its limit (the response then depends on the step size, and
    linear metrics such as the overshoot do not describe it);
``not settled``
    the final deviation (largest in the last 5 % of the window) is outside the band;
``settled``
    otherwise.

The judged window is the second half of the response before it left the bound.  Evidence
per design: ``growth_rate_per_s`` (fitted exponential rate of the deviation envelope),
``oscillation_hz`` (dominant frequency of the oscillating signal, from its spectrum),
``oscillation_amplitude`` (relative to the scale; current in A), ``saturated_fraction``,
``final_deviation`` (relative to the scale).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.validate import finite_array
from seactl.errors import InputError

VERDICTS = ("settled", "not settled", "unstable", "limit cycle", "saturated")
SEGMENTS = 5
"""Segments of the judged window for the envelope fit."""
GROWTH_FACTOR = 2.0
"""Envelope growth over the judged window that counts as divergence."""
SUSTAINED = 0.9
"""An oscillation keeping this fraction of its amplitude over the judged window (its decay
measured from the last two quarters) is sustained."""
CURRENT_FRACTION = 0.1
"""Current oscillation, as a fraction of the limit, that counts as a limit cycle."""
SATURATED_FRACTION = 0.0
"""Fraction of the time at the limit above which the response is ``saturated``: any."""
STEP_BAND = 0.02
"""Settling band of a step (2 % of the step), as in the settling-time metric."""
RECOVERY_BAND = 0.05
"""Recovery band of an impulse response (5 % of its peak deviation)."""


@dataclass(frozen=True)
class TimeVerdict:
    """Verdicts and their evidence, flattened over the batch (one entry per design)."""

    verdict: list[str]
    growth_rate_per_s: np.ndarray
    oscillation_hz: np.ndarray
    oscillation_amplitude: np.ndarray
    oscillating_signal: list[str]
    saturated_fraction: np.ndarray
    final_deviation: np.ndarray
    warnings: list[list[str]]
    right_half_plane_roots: np.ndarray  # certified count, -1 where not given

    def evidence(self, i: int) -> dict[str, Any]:
        """JSON-ready evidence of design ``i`` (NaN/inf as ``None``)."""

        def num(x: float) -> float | None:
            return round(float(x), 6) if np.isfinite(x) else None

        return {"growth_rate_per_s": num(self.growth_rate_per_s[i]),
                "oscillation_hz": num(self.oscillation_hz[i]),
                "oscillation_amplitude": num(self.oscillation_amplitude[i]),
                "oscillating_signal": self.oscillating_signal[i] or None,
                "saturated_fraction": num(self.saturated_fraction[i]),
                "final_deviation": num(self.final_deviation[i]),
                "right_half_plane_roots": (int(self.right_half_plane_roots[i])
                                           if self.right_half_plane_roots[i] >= 0 else None)}


def _window(t: np.ndarray, left: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end time of the judged window per design: the second half of the part
    before the response left the bound."""
    end = np.minimum(np.where(np.isfinite(left), left, t[-1]), t[-1])
    return t[0] + 0.5 * (end - t[0]), end


def _segment_max(t: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 k: int) -> tuple[np.ndarray, np.ndarray]:
    """Max |x| and centre time of segment ``k`` of ``SEGMENTS`` in ``[lo, hi]``."""
    a = lo + (hi - lo) * k / SEGMENTS
    b = lo + (hi - lo) * (k + 1) / SEGMENTS
    mask = (t[None, :] >= a[:, None]) & (t[None, :] <= b[:, None])
    return np.where(mask, np.abs(x), 0.0).max(axis=-1), 0.5 * (a + b)


def growth_rate(t: np.ndarray, dev: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Least-squares exponential rate [1/s] of the envelope of ``dev`` over ``[lo, hi]``."""
    amps, times = zip(*(_segment_max(t, dev, lo, hi, k) for k in range(SEGMENTS)))
    logs = np.log(np.maximum(np.stack(amps, -1), 1e-300))
    tc = np.stack(times, -1)
    tc = tc - tc.mean(-1, keepdims=True)
    den = (tc ** 2).sum(-1)
    return np.where(den > 0, (tc * (logs - logs.mean(-1, keepdims=True))).sum(-1)
                    / np.where(den > 0, den, 1.0), 0.0)


def _detrended(t: np.ndarray, x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``x`` minus its least-squares line over ``mask`` (zero outside it)."""
    w = mask.astype(float)
    n = np.maximum(w.sum(-1, keepdims=True), 1.0)
    tm = (w * t).sum(-1, keepdims=True) / n
    xm = (w * x).sum(-1, keepdims=True) / n
    tt = t - tm
    slope = (w * tt * (x - xm)).sum(-1, keepdims=True) / np.maximum(
        (w * tt ** 2).sum(-1, keepdims=True), 1e-300)
    return np.where(mask, x - xm - slope * tt, 0.0)


def oscillation(t: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Amplitude of the oscillation of ``x`` in the last quarter of ``[lo, hi]``, whether
    it is sustained (see :data:`SUSTAINED`), and its dominant frequency [Hz] over
    ``[lo, hi]``."""
    mid = lo + 0.5 * (hi - lo)
    q3 = lo + 0.75 * (hi - lo)
    tb = t[None, :]
    last = (tb >= q3[:, None]) & (tb <= hi[:, None])
    prev = (tb >= mid[:, None]) & (tb < q3[:, None])
    a_last = np.abs(_detrended(tb, x, last)).max(-1)
    a_prev = np.abs(_detrended(tb, x, prev)).max(-1)
    ratio = a_last / np.maximum(a_prev, 1e-300)
    sustained = np.log(np.maximum(ratio, 1e-300)) * 4 >= np.log(SUSTAINED)
    judged = (tb >= lo[:, None]) & (tb <= hi[:, None])
    r = _detrended(tb, x, judged)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    spec = np.abs(np.fft.rfft(r, axis=-1))
    spec[:, 0] = 0.0
    freq = np.fft.rfftfreq(t.size, dt)[np.argmax(spec, axis=-1)]
    return a_last, sustained, freq


def judge(t: Any, y: Any, *, target: float, scale: Any, band: float,
          left_bounds_s: Any = None, current: Any = None, current_limit: float = np.inf,
          saturated_fraction: Any = None, right_half_plane_roots: Any = None
          ) -> TimeVerdict:
    """Judge responses ``y`` (batch x time) against ``target``; see the module docstring.

    ``scale`` (per design or scalar) makes deviations relative (the step size, or the
    peak deviation of an impulse response); ``band`` is the settling band relative to it.
    ``right_half_plane_roots`` (per design): the simulated loop's certified count of
    unstable closed-loop roots, where known (e.g.
    :attr:`seactl.analysis.margins.Margins.unstable_poles`
    of the same exact-delay loop); any root there makes the verdict ``unstable``.
    """
    band = _band(band)
    t = np.asarray(t, float)
    y = np.asarray(y, float).reshape(-1, t.size)
    b = y.shape[0]
    scale = np.broadcast_to(np.asarray(scale, float), (b,)).copy()
    scale[~(scale > 0) | ~np.isfinite(scale)] = 1.0
    left = (np.full(b, np.inf) if left_bounds_s is None
            else np.asarray(left_bounds_s, float).reshape(b))
    sat = (np.zeros(b) if saturated_fraction is None
           else np.asarray(saturated_fraction, float).reshape(b))
    lo, hi = _window(t, left)
    dev = (y - target) / scale[:, None]
    rate = growth_rate(t, dev, lo, hi)
    final = np.abs(np.where(t[None, :] >= (t[-1] - 0.05 * (t[-1] - t[0])), dev, 0.0)).max(-1)
    end_amp = _segment_max(t, dev, lo, hi, SEGMENTS - 1)[0]
    growing = (rate * (hi - lo) > np.log(GROWTH_FACTOR)) & (end_amp > band)
    rhp = np.full(b, -1) if right_half_plane_roots is None else \
        _root_counts(right_half_plane_roots, b)
    unstable = np.isfinite(left) | growing | (rhp > 0)
    a_y, r_y, f_y = oscillation(t, dev, lo, hi)
    seen_y = a_y > band
    cycle = seen_y & r_y
    amp, freq = np.where(seen_y, a_y, np.nan), np.where(seen_y, f_y, np.nan)
    signal = np.where(seen_y, "position", "")
    if current is not None:
        i = np.asarray(current, float).reshape(b, t.size)
        ref = current_limit if np.isfinite(current_limit) else np.abs(i).max(-1)
        a_i, r_i, f_i = oscillation(t, i, lo, hi)
        seen_i = (a_i > CURRENT_FRACTION * ref) & ~cycle
        cycle_i = seen_i & r_i
        take = cycle_i | (seen_i & ~seen_y)
        amp, freq = np.where(take, a_i, amp), np.where(take, f_i, freq)
        signal = np.where(take, "current", signal)
        cycle |= cycle_i
    verdict = np.select([unstable, cycle, sat > SATURATED_FRACTION, final > band],
                        ["unstable", "limit cycle", "saturated", "not settled"], "settled")
    v = TimeVerdict([str(x) for x in verdict], rate, freq, amp, [str(s) for s in signal], sat,
                    final, [], rhp)
    v.warnings.extend(_warnings(v, k, left[k], band) for k in range(b))
    return v


def _band(value: Any) -> float:
    """The settling band, a fraction of the scale in (0, 1] (NaN would judge everything
    settled)."""
    valid = "a number > 0 and <= 1 (a fraction of the scale)"
    try:
        band = float(value)
    except (TypeError, ValueError):
        raise InputError("band", value, valid) from None
    if not 0 < band <= 1:
        raise InputError("band", band, valid)
    return band


def _root_counts(value: Any, b: int) -> np.ndarray:
    """``right_half_plane_roots`` as ``b`` integers, each a count >= 0 or -1 (unknown)."""
    arr = finite_array("right_half_plane_roots", value, minimum=-1.0)
    arr = arr.reshape(b) if arr.size == b else np.broadcast_to(arr, (b,))
    odd = (arr != np.round(arr)) | (arr > 1e9)
    if odd.any():
        raise InputError("right_half_plane_roots", float(arr[odd][0]),
                         "whole counts from 0 to 1e9, or -1 where unknown")
    return arr.astype(int)


def _warnings(v: TimeVerdict, k: int, left: float, band: float) -> list[str]:
    """The plain-language evidence of design ``k`` (printed and put in JSON alike)."""
    out = []
    verdict = v.verdict[k]
    if np.isfinite(left):
        out.append(f"unstable: the response left the simulation bound at {left:.3f} s")
    elif verdict == "unstable" and v.right_half_plane_roots[k] > 0:
        out.append(f"unstable: {v.right_half_plane_roots[k]} closed-loop root(s) in the right "
                   "half-plane (certified); the deviation grows at "
                   f"{v.growth_rate_per_s[k]:.3g} /s over the simulated window")
    elif verdict == "unstable":
        out.append(f"unstable: the deviation grows at {v.growth_rate_per_s[k]:.3g} /s")
    if np.isfinite(v.oscillation_hz[k]):
        unit = " A" if v.oscillating_signal[k] == "current" else " (relative)"
        what = ("limit cycle: sustained oscillation" if verdict == "limit cycle" else
                "oscillation")
        out.append(f"{what} of the {v.oscillating_signal[k]} at {v.oscillation_hz[k]:.4g} Hz, "
                   f"amplitude {v.oscillation_amplitude[k]:.3g}{unit} at the end")
    if v.saturated_fraction[k] > SATURATED_FRACTION:
        out.append(f"saturated: the current was at its limit {v.saturated_fraction[k]:.1%} of "
                   "the time (the response depends on the step size; linear metrics do not "
                   "describe it)")
    if verdict != "settled" and v.final_deviation[k] > band:
        out.append(f"not settled: final deviation {v.final_deviation[k]:.3g} of the scale "
                   f"(band {band:g}; envelope growth rate {v.growth_rate_per_s[k]:.3g} /s)")
    return out


def judge_response(resp: Any, band: float, right_half_plane_roots: Any = None
                   ) -> TimeVerdict:
    """:func:`judge` on a :class:`seactl.simulate.results.SEAResponse` (step: target 1 of the
    normalized position, scale 1; impulse: target 0, scale the peak deviation; the current
    limit [A] is ``info["current_limit_a"]``, else the ``i_m`` saturation).  Without
    ``right_half_plane_roots``, a sampled simulation's own count of growing modes
    (``info["unstable_modes"]``, :func:`seactl.simulate.period.sampled_unstable_modes`) is used."""
    res = resp.result
    t = res.t_s
    y = np.asarray(resp.position, float).reshape(-1, t.size)
    cur = resp.current_a if hasattr(resp, "current_a") else resp.current  # result or core
    cur = np.asarray(cur, float).reshape(-1, t.size)
    info = res.info or {}
    if right_half_plane_roots is None:
        right_half_plane_roots = info.get("unstable_modes")
    limit = float(info.get("current_limit_a",
                            (info.get("saturation") or {}).get("i_m", np.inf)))
    step = resp.kind == "step"
    return judge(t, y, target=1.0 if step else 0.0,
                 scale=1.0 if step else np.abs(y).max(-1), band=band,
                 left_bounds_s=res.left_bounds_s, current=cur, current_limit=limit,
                 saturated_fraction=info.get("saturated_fraction"),
                 right_half_plane_roots=right_half_plane_roots)
