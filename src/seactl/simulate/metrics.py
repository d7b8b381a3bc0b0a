"""Step and impulse metrics of simulated responses."""

from __future__ import annotations

import numpy as np

from seactl.base.jit import KernelGroup, njit
from seactl.simulate.results import ImpulseMetrics, StepMetrics
from seactl.simulate.verdict import RECOVERY_BAND, STEP_BAND

KERNELS = KernelGroup("step metrics", about_s=1)
"""The group of this module's kernels (the step metrics)."""


# ----------------------------------------------------------------------------- metrics
def step_metrics(t: np.ndarray, y: np.ndarray, stable: np.ndarray | None = None,
                 left_bounds_s: np.ndarray | None = None, reference: float = 1.0,
                 band: float = STEP_BAND) -> StepMetrics:
    """Metrics of step responses ``y`` (time on the last axis) to a step of ``reference``:
    final value (mean of the last 2 %), 10-90 % rise time (interpolated), overshoot [%],
    settling time (the sample after the last one outside ``band`` of the final value;
    inf if that is the last sample) and steady-state error.  One compiled pass per
    response (:func:`_step_kernel`): the record is time-major, so numpy's passes along
    the time axis of a batch would be strided.

    Examples
    --------
    >>> t = np.linspace(0, 5, 5001)
    >>> m = step_metrics(t, 1 - np.exp(-t * 10))
    >>> round(float(m.rise_time_s), 3), round(float(m.settling_time_s), 2)  # ln 9/10, ln 50/10
    (0.22, 0.39)
    """
    y = np.asarray(y, float)
    batch = y.shape[:-1]
    stable = np.ones(batch, bool) if stable is None else np.asarray(stable)
    left = np.full(batch, np.inf) if left_bounds_s is None else np.asarray(left_bounds_s)
    out = np.empty((5,) + batch)
    # (C-ordered arrays: one compiled layout)
    _step_kernel(np.ascontiguousarray(t, float),
                 np.ascontiguousarray(y.reshape(-1, y.shape[-1]), float), float(reference),
                 float(band), max(1, y.shape[-1] // 50), out.reshape(5, -1))
    out = np.where(~stable, np.nan, out)
    return StepMetrics(*(out[k, ...] for k in range(5)), stable, left)


@njit(cache=True, error_model="numpy")
def _step_kernel(t, y, reference, band, tail, out):  # pragma: no cover - compiled
    """Rows of ``out``: rise, overshoot, settling time, steady-state error and final value
    of each row of ``y / reference`` (see :func:`step_metrics`; a NaN sample makes the
    overshoot NaN and is never outside the band, as numpy's max and comparisons do).
    Time in the outer loop: simulation records are time-major."""
    m, n = y.shape
    fin, peak, prev = np.zeros(m), np.full(m, -np.inf), np.zeros(m)
    nan, last = np.zeros(m, np.bool_), np.full(m, -1)
    cross = np.full((2, m), np.inf)
    for k in range(n - tail, n):
        for d in range(m):
            fin[d] += y[d, k] / reference / tail
    for k in range(n):
        for d in range(m):
            v = y[d, k] / reference
            r = v / fin[d]
            if r != r:
                nan[d] = True
            elif r > peak[d]:
                peak[d] = r
            if abs(v - fin[d]) > band * abs(fin[d]):
                last[d] = k
            for c, level in ((0, 0.1), (1, 0.9)):  # first reach, interpolated
                if cross[c, d] == np.inf and r >= level:
                    cross[c, d] = t[0] if k == 0 else \
                        t[k - 1] + (level - prev[d]) / (r - prev[d]) * (t[k] - t[k - 1])
            prev[d] = r
    for d in range(m):
        out[0, d] = cross[1, d] - cross[0, d]
        out[1, d] = np.nan if nan[d] else max(peak[d] - 1.0, 0.0) * 100.0
        out[2, d] = t[0] if last[d] < 0 else (np.inf if last[d] >= n - 1 else t[last[d] + 1])
        out[3, d], out[4, d] = 1.0 - fin[d], fin[d]


def impulse_metrics(t: np.ndarray, y: np.ndarray, stable: np.ndarray | None = None,
                    left_bounds_s: np.ndarray | None = None, band: float = RECOVERY_BAND
                    ) -> ImpulseMetrics:
    """Peak deviation from the initial value and recovery time (last exit from
    ``band`` x peak) of impulse responses ``y`` (time on the last axis).

    Examples
    --------
    >>> t = np.linspace(0, 2, 2001)
    >>> m = impulse_metrics(t, t * np.exp(-10 * t))
    >>> round(float(m.peak_time_s), 3), round(float(m.peak_deviation), 5)
    (0.1, 0.03679)
    """
    y = np.asarray(y, float)
    batch = y.shape[:-1]
    stable = np.ones(batch, bool) if stable is None else np.asarray(stable)
    left = np.full(batch, np.inf) if left_bounds_s is None else np.asarray(left_bounds_s)
    dev = np.abs(y - y[..., :1])
    ipk = np.argmax(dev, axis=-1)
    peak = np.take_along_axis(dev, ipk[..., None], -1)[..., 0]
    outside = dev > band * peak[..., None]
    last = y.shape[-1] - 1 - np.argmax(outside[..., ::-1], axis=-1)
    rec = np.where(last >= y.shape[-1] - 1, np.inf, t[np.minimum(last + 1, t.size - 1)])
    nan = ~stable
    f = lambda a: np.where(nan, np.nan, a)  # noqa: E731
    return ImpulseMetrics(f(peak), f(t[ipk]), f(rec), band, stable, left)
