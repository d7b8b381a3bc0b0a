"""What a simulation returns: the result, its metrics, the layout of packed vectors."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from seactl.base.result import Result, flat_records, json_array, new_axes


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SimResult(Result):
    """Simulated responses of a batch of designs.

    Parameters
    ----------
    mode : str
        ``"continuous"`` or ``"sampled"``.
    t_s : numpy.ndarray
        Sample times [s], shape ``(T,)``.
    outputs : dict
        Signal name -> array of shape ``batch + (T,)``.
    stable : numpy.ndarray
        ``batch`` bool.
    left_bounds_s : numpy.ndarray
        Time [s] an output first left ``bound``.
    bound : float
        The divergence bound used.
    info : dict, optional
        Details.

    Attributes
    ----------
    mode : str
        ``"continuous"`` or ``"sampled"``.
    t_s : ndarray
        Sample times [s], shape ``(T,)``.
    outputs : dict
        Signal name -> array of shape ``batch + (T,)``, each in its signal's unit.
    stable : ndarray of bool
        ``batch``: stayed within ``bound`` and decaying at the end of the window.
    left_bounds_s : ndarray
        Time [s] an output first left ``bound`` (``inf`` if never).
    bound : float
        The divergence bound used (in the outputs' units).
    info : dict
        Details (step, rates, requested and effective delays per delayed block [s]:
        ``requested_delays_s``, ``effective_delays_s``; equal in continuous mode, the
        whole-sample buffers' ``T_s/2 + n T_s >= T`` in sampled mode, ...).
    """

    mode: str
    t_s: np.ndarray
    outputs: dict[str, np.ndarray]
    stable: np.ndarray
    left_bounds_s: np.ndarray
    bound: float
    info: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Time, every output, boundedness and exit times as nested lists.

        Returns
        -------
        dict
            ``mode``, ``t_s``, ``outputs`` (signal -> nested list), ``stable``,
            ``left_bounds_s``, ``bound``.
        """
        return {"mode": self.mode, "t_s": json_array(self.t_s),
                "outputs": {k: json_array(v) for k, v in self.outputs.items()},
                "stable": json_array(self.stable), "left_bounds_s": json_array(self.left_bounds_s),
                "bound": self.bound}

    def records(self) -> list[dict[str, Any]]:
        """One row per design (flattened batch): boundedness and exit time.

        Returns
        -------
        list of dict
            ``stable``, ``left_bounds_s``.
        """
        return flat_records({"stable": self.stable, "left_bounds_s": self.left_bounds_s})

    def plot(self, ax: Any = None, output: str | None = None) -> Any:
        """One output against time (default: the first), one line per design.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).
        output : str, optional
            Signal name (a key of :attr:`outputs`).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        name = output if output is not None else next(iter(self.outputs))
        for y in np.reshape(self.outputs[name], (-1, self.t_s.size)):
            ax.plot(self.t_s, y)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
        return ax


@dataclass(frozen=True)
class StepMetrics:
    """Step-response metrics (arrays of the batch shape; responses normalized to the step).

    ``rise_time_s``: 10 % to 90 % of the final value; ``overshoot_pct``: peak above the
    final value [% of the final value]; ``settling_time_s``: last time outside a 2 % band
    around the final value (``inf`` if still outside at the end); ``steady_state_error``:
    ``1 - final`` (final = mean of the last 2 % of the window).  Unstable designs get NaN
    metrics (their ``stable`` flag is False and ``left_bounds_s`` says when they left).
    """

    rise_time_s: np.ndarray
    overshoot_pct: np.ndarray
    settling_time_s: np.ndarray
    steady_state_error: np.ndarray
    final_value: np.ndarray
    stable: np.ndarray
    left_bounds_s: np.ndarray


@dataclass(frozen=True)
class ImpulseMetrics:
    """Impulse-disturbance metrics (arrays of the batch shape).

    ``peak_deviation``: largest ``|y - y(0)|`` (output units); ``peak_time_s``: when;
    ``recovery_time_s``: last time ``|y - y(0)|`` exceeds ``band`` times the peak (``inf``
    if it has not recovered by the end).  NaN for unstable designs.
    """

    peak_deviation: np.ndarray
    peak_time_s: np.ndarray
    recovery_time_s: np.ndarray
    band: float
    stable: np.ndarray
    left_bounds_s: np.ndarray


@dataclass(frozen=True)
class Layout:
    """Named consecutive slices of a packed vector (states, inputs, ... of one batch).

    Examples
    --------
    >>> lay = Layout.of(x=3, u=2)
    >>> lay["u"], lay.size
    (slice(3, 5, None), 5)
    """

    parts: tuple[tuple[str, int], ...]

    @classmethod
    def of(cls, **sizes: int) -> Layout:
        return cls(tuple((k, int(v)) for k, v in sizes.items()))

    @cached_property
    def _slices(self) -> dict[str, slice]:
        out, off = {}, 0
        for name, size in self.parts:
            out[name] = slice(off, off + size)
            off += size
        return out

    def __getitem__(self, name: str) -> slice:
        return self._slices[name]

    def upto(self, name: str) -> slice:
        """From the start up to the end of part ``name``."""
        return slice(0, self._slices[name].stop)

    @property
    def size(self) -> int:
        return sum(s for _, s in self.parts)


@dataclass(frozen=True)
class RunOutputs:
    """What a run loop returns: flat-batch outputs ``(n, T)``, exit times, details."""

    t_s: np.ndarray
    outputs: dict[str, np.ndarray]
    left_bounds_s: np.ndarray
    info: dict[str, Any]


def batch_last(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.moveaxis(a, 0, -1))


# ----------------------------------------------------------------------------- SEA helpers
@dataclass(frozen=True)
class SEAResponse:
    """A simulated SEA response with its metrics (``metrics`` is a :class:`StepMetrics`
    or :class:`ImpulseMetrics`); ``position`` is ``q_j`` (normalized to the step for steps,
    in rad for impulses) of shape ``batch + (T,)``; ``current`` is ``i_m`` [A]."""

    kind: str
    result: SimResult
    metrics: StepMetrics | ImpulseMetrics

    @property
    def t_s(self) -> np.ndarray:
        return self.result.t_s

    @property
    def position(self) -> np.ndarray:
        return self.result.outputs["q_j"]

    @property
    def current(self) -> np.ndarray:
        return self.result.outputs["i_m"]
