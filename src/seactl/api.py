"""The SEA design batch of the public API: :func:`design` and :class:`Design`.

A :class:`Design` is a thin view of :class:`seactl.loops.SEADesign` (actuator, gains,
timing, broadcast as a batch) that remembers how it was designed (``fn_hz``, ``gs``, ...)
and exposes every analysis as a method.  Nothing is modelled here: margins, impedance,
responses and exports all come from the one block diagram of :mod:`seactl.loops`.

Units are in the keyword names: ``delays_ms`` in milliseconds, ``filters_hz`` and
``fn_hz`` in hertz, ``t_end_s`` in seconds.  Values outside the range a unit makes
plausible are refused (a delay above 1000 ms) or warned about (a non-zero delay below
1 microsecond, which is what seconds passed as milliseconds look like).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from ._results import (
    ImpedanceResult,
    JitterResult,
    MarginsResult,
    ResponseResult,
    RootsResult,
    SampledMarginsResult,
)
from ._validate import finite_array
from .axes import MAX_DELAY_MS
from .errors import InputError
from .loops import Gains, SEADesign, Timing
from .runtime import run_doc

SUSPICIOUS_DELAY_MS = 1e-3
"""Non-zero delays below this [ms] (1 us) trigger a :class:`UnitWarning`."""


class UnitWarning(UserWarning):
    """A value is legal but looks like it was given in another unit.

    Examples
    --------
    >>> import warnings, seactl as sc
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = sc.design(14, delays_ms=(0.0005, 0.002, 0.0005))   # seconds, not ms
    >>> caught[0].category.__name__
    'UnitWarning'
    """


def delays_from_ms(delays_ms: Sequence[Any], names: Sequence[str]) -> list[np.ndarray]:
    """Check a tuple of delays in milliseconds and return them in seconds.

    Parameters
    ----------
    delays_ms : sequence of array_like
        One delay [ms] per name (arrays broadcast as a batch).
    names : sequence of str
        Names of the delays, for error messages.

    Returns
    -------
    list of numpy.ndarray
        The delays in seconds.

    Raises
    ------
    InputError
        Wrong length, negative, non-finite or above :data:`MAX_DELAY_MS`.

    Examples
    --------
    >>> [float(x) for x in delays_from_ms((0.5, 2), ("T_s", "T_d"))]
    [0.0005, 0.002]
    """
    # not np.ndim(delays_ms): the delays may have different shapes (a batch grid)
    if isinstance(delays_ms, (str, bytes)) or not isinstance(delays_ms, (Sequence, np.ndarray)) \
            or len(delays_ms) != len(names):
        raise InputError("delays_ms", delays_ms,
                         f"a sequence of {len(names)} delays ({', '.join(names)}) [ms]")
    out = []
    for name, value in zip(names, delays_ms):
        v = finite_array(f"{name} [ms]", value, minimum=0.0, nonempty=True)
        if np.any(v > MAX_DELAY_MS):
            raise InputError(f"{name} [ms]", float(v[v > MAX_DELAY_MS].flat[0]),
                             f"<= {MAX_DELAY_MS:g} ms (delays_ms takes milliseconds)")
        if np.any((v > 0) & (v < SUSPICIOUS_DELAY_MS)):
            warnings.warn(f"{name} = {float(v[(v > 0) & (v < SUSPICIOUS_DELAY_MS)].flat[0])!r}"
                          " ms is below 1 us; delays_ms takes milliseconds (0.5 means 0.5 ms)",
                          UnitWarning, stacklevel=3)
        out.append(v / 1e3)
    return out


def _filters(filters_hz: Sequence[Any], names: Sequence[str]) -> list[Any]:
    if isinstance(filters_hz, (str, bytes)) or not isinstance(filters_hz, (Sequence, np.ndarray)) \
            or len(filters_hz) != len(names):
        raise InputError("filters_hz", filters_hz,
                         f"a sequence of {len(names)} cut-offs ({', '.join(names)}) [Hz], "
                         "None for no filter")
    return [None if f is None else finite_array(f"{n} [Hz]", f, minimum=0.0, strict=True,
                                                allow_inf=True, nonempty=True)
            for n, f in zip(names, filters_hz)]


def check_batch(**arguments: Any) -> tuple[int, ...]:
    """The broadcast shape of the arguments' arrays (an argument holding several, such as
    ``delays_ms``, gives each), or :class:`InputError` naming the first argument that does
    not broadcast with those before it, or that has no value (a batch without designs)."""
    shape: tuple[int, ...] = ()
    for name, value in arguments.items():
        parts = value if isinstance(value, tuple) else (value,)
        for part in (v for v in parts if v is not None):
            try:
                part = np.asarray(part, dtype=float)
            except (TypeError, ValueError):
                raise InputError(name, _plain(value), "a number or an array of numbers "
                                 "(not ragged)") from None
            if np.size(part) == 0:
                raise InputError(name, _plain(value), "at least one value (a batch of "
                                 "designs is never empty)")
            try:
                shape = np.broadcast_shapes(shape, np.shape(part))
            except ValueError:
                raise InputError(name, _plain(value), f"an array that broadcasts with the "
                                 f"shape {shape} of the arguments before it") from None
    return shape


def _plain(value: Any) -> Any:
    if isinstance(value, tuple):
        return tuple(_plain(v) for v in value)
    return value.tolist() if isinstance(value, (np.ndarray, np.generic)) else value


def resolve_actuator(actuator: Any, loader: Any, cls: type) -> Any:
    """An actuator object as is, or a preset name / TOML path loaded by ``loader``."""
    return actuator if isinstance(actuator, cls) else loader(actuator)


@dataclass(frozen=True, eq=False)
class Design:
    """A batch of critically-damped SEA designs, with every analysis as a method.

    Build it with :func:`design`.  All arrays share the batch ``shape`` (numpy
    broadcasting of ``fn_hz``, ``gs`` and the delays); ``d[i]`` selects designs.

    Parameters
    ----------
    sea : seactl.loops.SEADesign
        The underlying batch (actuator, gains, timing) the block diagram evaluates.
    fn_hz, gs : numpy.ndarray
        Natural frequency [Hz] and gain scale the gains were designed for.

    Attributes
    ----------
    actuator : seactl.actuators.SEAParams
        The actuator.
    gains : seactl.loops.Gains
        ``Kq`` [N m/rad], ``Bq`` [N m s/rad], ``Ktau`` [A/(N m)], ``Btau`` [A s/(N m)].
    timing : seactl.loops.Timing
        Delays [s] and filter cut-offs [Hz].
    shape : tuple of int
        The batch shape.

    Examples
    --------
    >>> import seactl as sc
    >>> d = sc.design([12, 14], delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
    >>> d.shape, round(float(d[1].gains.Kq), 2)
    ((2,), 83.17)
    """

    default_step: ClassVar[float] = 0.01
    step_unit: ClassVar[str] = "rad"
    sea: SEADesign
    fn_hz: np.ndarray
    gs: np.ndarray

    # ------------------------------------------------------------ structure
    @property
    def actuator(self) -> Any:
        """The actuator (:class:`~seactl.actuators.SEAParams`)."""
        return self.sea.actuator

    @property
    def gains(self) -> Gains:
        """The controller gains, broadcast to the batch shape."""
        g = self.sea.gains
        return Gains(*(np.broadcast_to(getattr(g, f.name), self.shape) for f in fields(g)))

    @property
    def timing(self) -> Timing:
        """Delays [s] and filter cut-offs [Hz]."""
        return self.sea.timing

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        return self.sea.shape

    def __len__(self) -> int:
        if not self.shape:
            raise TypeError("len() of a single design")
        return self.shape[0]

    def __getitem__(self, idx: Any) -> Design:
        shape = self.shape
        if not shape and not (idx is None or idx is Ellipsis
                              or (isinstance(idx, tuple) and idx == ())):
            raise IndexError(f"index {idx!r} of a single design (its shape is (); "
                             "d[()] is the design itself)")

        def pick(x: Any) -> Any:
            return None if x is None else np.broadcast_to(np.asarray(x, float), shape)[idx]

        if np.size(pick(self.fn_hz)) == 0:
            raise InputError("index", idx, "a selection of at least one design")
        t = self.timing
        timing = Timing(pick(t.T_tau), pick(t.T_qs), pick(t.T_qd), pick(t.f_qd),
                        pick(t.f_taud))
        return Design(SEADesign(self.actuator, self.gains[idx], timing), pick(self.fn_hz),
                      pick(self.gs))

    def __repr__(self) -> str:
        t = self.timing
        ms = [np.round(np.asarray(x) * 1e3, 4).tolist() for x in (t.T_tau, t.T_qs, t.T_qd)]
        return (f"Design(actuator={self.actuator.name!r}, shape={self.shape}, "
                f"fn_hz={np.asarray(self.fn_hz).tolist()}, gs={np.asarray(self.gs).tolist()}, "
                f"delays_ms={tuple(ms)}, filters_hz=({_filter_repr(t.f_qd)}, "
                f"{_filter_repr(t.f_taud)}))")

    def labels(self) -> list[str]:
        """One short label per design (flattened batch), for legends.

        Returns
        -------
        list of str
            ``"f_n=12 Hz, GS=1"`` style labels.

        Examples
        --------
        >>> import seactl as sc
        >>> sc.design([12, 14]).labels()
        ['f_n=12 Hz, GS=1', 'f_n=14 Hz, GS=1']
        """
        fn = np.ravel(np.broadcast_to(self.fn_hz, self.shape))
        gs = np.ravel(np.broadcast_to(self.gs, self.shape))
        return [f"f_n={f:g} Hz, GS={g:g}" for f, g in zip(fn, gs)]

    def _label_columns(self) -> dict[str, np.ndarray]:
        g = self.gains
        return {"fn_hz": self.fn_hz, "gs": self.gs, "Kq": g.Kq, "Bq": g.Bq, "Ktau": g.Ktau,
                "Btau": g.Btau}

    # ------------------------------------------------------------ analyses
    def margins(self, rate_hz: Any = None) -> MarginsResult | SampledMarginsResult:
        """Phase, gain and delay margins of the outer loop, and closed-loop stability.

        The loop is the outer impedance loop with the inner torque loop closed and exact
        delays; stability is the Nyquist criterion of the whole cascade
        (:func:`seactl.sea.sea_margins`).

        Parameters
        ----------
        rate_hz : float or dict, optional
            ``None`` (default): the continuous loop.  A rate [Hz] (both processes), or
            ``{"embedded": ..., "high-level": ...}``: the sampled-data loop that
            ``step(mode="sampled")`` runs (Tustin controllers, whole-sample delays, the
            held plant), with a certified verdict and margins from its discrete frequency
            response up to Nyquist (:func:`seactl.sea.sea_sampled_margins`; the argument is
            in docs/theory/sampled.md).  A multi-rate loop gets its verdict only.

        Returns
        -------
        MarginsResult or SampledMarginsResult
            Arrays of the batch shape (``phase_margin_deg``, ``delay_margin_ms``,
            ``stable``, ...), with ``to_dict()``, ``records()`` and ``plot()``; sampled:
            also ``verdict`` and ``delay_margin_samples``.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design([12, 14, 16], delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
        >>> d.margins().phase_margin_deg.round(2)
        array([45.13, 43.26, 40.03])
        """
        if rate_hz is not None:
            from .sea import sea_sampled_margins

            return SampledMarginsResult(sea_sampled_margins(self.sea, rate_hz),
                                        self._label_columns())
        from .sea import sea_margins

        return MarginsResult(sea_margins(self.sea), self._label_columns())

    def jitter_margins(self) -> JitterResult:
        """Jitter margins of the whole outer loop and of the stiffness, damping and torque
        loops (Kao-Lincoln small-gain bound with exact delays).

        The jitter margin of a loop is the largest ``J`` such that any *time-varying*
        extra delay in ``[0, J]`` at that loop's break keeps the closed loop stable:
        ``J = 1 / max_w (w |T(jw)|)``, ``T = L/(1+L)`` the complementary sensitivity there
        (:mod:`seactl.jitter`); 0 for an unstable design.

        Returns
        -------
        JitterResult
            Arrays of the batch shape (``overall_s``, ``stiffness_s``, ``damping_s``,
            ``torque_s``, ``delay_margin_s``, ``stable``), with ``records()``.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design([12, 14], delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
        >>> j = d.jitter_margins()
        >>> j.ms("overall").round(2), bool(j.ms("damping")[1] > j.ms("overall")[1])
        (array([11.47,  8.04]), True)
        """
        from .jitter import sea_jitter_margins

        return JitterResult(sea_jitter_margins(self.sea),
                            {"fn_hz": self.fn_hz, "gs": self.gs})

    def roots(self, count: int = 6) -> RootsResult:
        """Rightmost roots of the closed loop (exact delays), per design.

        Chebyshev collocation of the delay equation gives candidates, Newton on the exact
        characteristic quasi-polynomial polishes them, the argument principle checks
        that none is missing and bounds each by a disc that holds it, multiplicity
        counted (:func:`seactl.roots.characteristic_roots`).

        Parameters
        ----------
        count : int
            Roots per design (a conjugate pair counts once).

        Returns
        -------
        RootsResult
            ``roots`` [rad/s] of shape ``shape + (count,)`` sorted by decreasing real part,
            ``spectral_abscissa`` [1/s], each root's disc (``cluster_centre``,
            ``cluster_radius`` [rad/s], ``cluster_count``; ``real_interval`` [1/s]),
            ``stable``, ``uncertain``, ``records()``.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(15.93, gs=1.867, delays_ms=(1.99, 1.96, 18.54))
        >>> r = d.roots(count=2)
        >>> z = complex(r.roots[0])
        >>> round(z.real, 2), round(z.imag, 1), bool(d.margins().stable)
        (1.19, 747.3, False)
        """
        from .limits import check_roots
        from .loops import SEA_DIAGRAM
        from .roots import characteristic_roots

        t = self.timing
        check_roots(int(np.prod(self.shape)), count,
                    any(np.any(np.asarray(x) > 0) for x in (t.T_tau, t.T_qs, t.T_qd)))
        return RootsResult(characteristic_roots(SEA_DIAGRAM, self.sea, count=count),
                           {"fn_hz": self.fn_hz, "gs": self.gs})

    def impedance(self, f_hz: Any, *, model: str = "block-diagram", load: bool = False,
                  units: str = "rotary") -> ImpedanceResult:
        """Impedance ``Z(j 2 pi f) = tau_k / (-j 2 pi f q_j)`` at frequencies ``f_hz``.

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0 (the last axis of the result).
        model : {"block-diagram", "paper"}
            The block diagram (default) or the paper's printed formula.
        load : bool
            Include the joint inertia and damping (``Z_l = Z + I_j s + b_j``).
        units : {"rotary", "linear"}
            N m s/rad (default) or N s/m.

        Returns
        -------
        ImpedanceResult
            ``z`` of shape ``shape + (len(f_hz),)``, ``magnitude``, ``phase_deg``, ...

        Examples
        --------
        >>> import seactl as sc
        >>> z = sc.design(30).impedance([1e-3])
        >>> round(float(z.stiffness[0].real), 1)        # s Z -> K_q at low frequency
        293.6
        """
        from .impedance import impedance

        return ImpedanceResult(impedance(self.sea, f_hz, model=model, load=load, units=units),
                               self.labels())

    def step(self, *, t_end_s: float = 0.5, mode: str = "continuous", rate_hz: float = 1000.0,
             saturation_a: float | None = None, zero: bool = True,
             amplitude: float = 1.0) -> ResponseResult:
        """Response of the joint angle ``q_j`` to a unit step of ``q_des``.

        Parameters
        ----------
        t_end_s : float
            Simulated time [s].
        mode : {"continuous", "sampled"}
            Exact continuous-time delays, or controllers sampled at ``rate_hz`` with
            whole-sample delay buffers and current saturation.
        rate_hz : float
            Controller rate of the sampled mode [Hz].
        saturation_a : float, optional
            Current limit [A] of the sampled mode (default: the actuator's).
        zero : bool
            Torque derivative on the whole error (default) or on feedback only.
        amplitude : float
            Step size [rad] (``position`` is divided by it; it matters where the current
            limit clips; the front ends use :attr:`default_step`).

        Returns
        -------
        ResponseResult
            ``t_s``, ``position`` (normalized to the step), ``current`` and ``metrics``
            (rise, overshoot, settling).

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.design(14, delays_ms=(1, 1, 1), filters_hz=(50, 100)).step(t_end_s=0.4)
        >>> bool(r.metrics.stable), round(float(r.metrics.final_value), 3)
        (True, 1.0)
        """
        from .sea import sea_right_roots, sea_step
        from .timing import SEA_LINKS

        self._check_simulation(mode, rate_hz, t_end_s)
        return ResponseResult(sea_step(self.sea, zero=zero, mode=mode, rate_hz=rate_hz,
                                       t_end_s=t_end_s, saturation_a=saturation_a,
                                       amplitude=amplitude),
                              self.labels(), functools.partial(sea_right_roots, self.sea, zero),
                              links=SEA_LINKS)

    def _check_simulation(self, mode: str, rate_hz: float, t_end_s: float) -> None:
        """Ranges, samples, memory and time of a simulation (errors name the parameters)."""
        from .limits import check_simulation

        t = self.sea.timing
        delays = [float(np.min(np.where(np.asarray(d) > 0, d, np.inf)))
                  for d in (t.T_tau, t.T_qs, t.T_qd)]
        check_simulation(int(np.prod(self.shape)), mode, rate_hz, t_end_s,
                         [d for d in delays if np.isfinite(d)])

    def impulse(self, *, impulse_nms: float = 0.05, t_end_s: float = 1.0,
                mode: str = "continuous", rate_hz: float = 1000.0,
                saturation_a: float | None = None) -> ResponseResult:
        """Response of ``q_j`` [rad] to an impulse of external joint torque at ``t = 0``.

        Parameters
        ----------
        impulse_nms : float
            Angular impulse [N m s].
        t_end_s : float
            Simulated time [s].
        mode : {"continuous", "sampled"}
            See :meth:`step`.
        rate_hz : float
            Controller rate of the sampled mode [Hz].
        saturation_a : float, optional
            Current limit [A] of the sampled mode (default: the actuator's).

        Returns
        -------
        ResponseResult
            ``t_s``, ``position`` [rad], ``current`` [A] and ``metrics`` (peak deviation,
            recovery time).

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.design(14, filters_hz=(50, 100)).impulse(t_end_s=0.5)
        >>> bool(r.metrics.stable), bool(r.metrics.recovery_time_s < 0.2)
        (True, True)
        """
        from .sea import sea_impulse, sea_right_roots
        from .timing import SEA_LINKS

        self._check_simulation(mode, rate_hz, t_end_s)
        return ResponseResult(sea_impulse(self.sea, impulse_nms=impulse_nms, mode=mode,
                                          rate_hz=rate_hz, t_end_s=t_end_s,
                                          saturation_a=saturation_a), self.labels(),
                              functools.partial(sea_right_roots, self.sea, True),
                              links=SEA_LINKS)

    def monte_carlo(self, kind: str = "step", *, latency: Any = None, loss: Any = None,
                    runs: int = 100, seed: int = 0, rate_hz: float = 1000.0,
                    t_end_s: float | None = None) -> Any:
        """Sampled step or impulse responses under random latency and message loss.

        Parameters
        ----------
        kind : {"step", "impulse"}
            Step of 0.01 rad on ``q_des``, or 0.05 N m s impulse of external torque.
        latency : dict, optional
            Link (``"stiffness"``, ``"damping"``, ``"torque"``) -> latency model of
            :mod:`seactl.timing_models` (seconds), or its text form in ms
            (``"uniform:0.5:3"``).
        loss : dict, optional
            Link -> loss probability, loss model, or text (``"ge:0.01:0.3"``).
        runs : int
            Timing realizations per design.
        seed : int
            Seed (each run has its own stream: reproducible).
        rate_hz : float
            Servo rate of both processes [Hz].
        t_end_s : float, optional
            Window [s] (default 0.5 for steps, 1 for impulses).

        Returns
        -------
        seactl.timing.MonteCarloSummary
            ``fraction_stable``, ``rms_error_mean``, ``rms_error_worst``,
            ``peak_current_worst_a``, ``worst_run`` (batch shape), per-run arrays and the
            batched simulation.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
        >>> mc = d.monte_carlo(latency={"damping": "uniform:0.5:3"}, runs=10, t_end_s=0.3)
        >>> float(mc.fraction_stable)
        1.0
        """
        from .timing import sea_monte_carlo
        from .timing_models import parse_latency, parse_loss

        lat = {k: parse_latency(v, f"latency {k}") if isinstance(v, str) else v
               for k, v in (latency or {}).items()}
        los = {k: parse_loss(v, f"loss {k}") if isinstance(v, str) else v
               for k, v in (loss or {}).items()}
        return sea_monte_carlo(self.sea, kind, latency=lat, loss=los, runs=runs, seed=seed,
                               rate_hz=rate_hz, t_end_s=t_end_s)

    def to_control(self, kind: str = "frd", *, transfer: str = "loop", f_hz: Any = None,
                   order: int = 3) -> Any:
        """Export to python-control: exact-delay frequency response or a Padé model.

        Parameters
        ----------
        kind : {"frd", "pade", "pade-ss"}
            ``"frd"``: a :class:`control.FrequencyResponseData` of the exact-delay
            transfer at ``f_hz``; ``"pade"``: a :class:`control.TransferFunction` with
            every delay replaced by its Padé approximant of ``order``; ``"pade-ss"``: the
            same as a :class:`control.StateSpace`.
        transfer : {"loop", "inner", "closed", "impedance"}
            Outer loop ``L`` (inner loop closed), inner torque loop, closed loop
            ``q_j / q_des``, or impedance ``Z`` [N m s/rad].
        f_hz : array_like, optional
            Frequencies of the FRD [Hz] (default: 2000 points from 0.01 Hz to 10 kHz).
        order : int
            Padé order per delay, 1 to 4 (3 matches the exact loop to 2e-5 relative
            between 1 and 100 Hz at Table I's delays; higher orders are ill-conditioned
            as polynomials).

        Returns
        -------
        control.FrequencyResponseData or control.TransferFunction or control.StateSpace
            For a single design; a list of them (flattened batch order) for a batch.

        Examples
        --------
        >>> import control as ct
        >>> import seactl as sc
        >>> d = sc.design(12, delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
        >>> L = d.to_control("frd")
        >>> gm, pm, wg, wp = ct.margin(L)
        >>> round(float(pm), 1)
        45.1
        """
        from ._export import to_control

        if not self.shape:
            return to_control(self.sea, kind, transfer, f_hz, order)
        n = int(np.prod(self.shape))
        flat = self.reshape(n)
        return [to_control(flat[i].sea, kind, transfer, f_hz, order) for i in range(n)]

    def export(self, out: Any, *, lang: Any = ("c", "python", "json"),
               rates_hz: Any = 1000.0, saturation_a: float | None = None, zero: bool = True,
               verify: bool = False) -> Any:
        """Write the discrete controller of each process as C99, Python and JSON.

        The sampled controller (Tustin derivatives and filters, whole-sample delay buffers,
        current saturation) split by process: the stiffness loop on ``high-level``, torque
        and damping on ``embedded`` (docs/export.md).

        Parameters
        ----------
        out : str or path
            A new or empty directory (or one an earlier export wrote).
        lang : sequence of str or str
            Any of ``"c"`` (``<process>.h/.c`` and a CSV harness ``<process>_main.c``),
            ``"python"`` (``<process>.py``) and ``"json"`` (``controller.json``).
        rates_hz : float or mapping
            Rate of every process [Hz], or ``{"embedded": 2000, "high-level": 500}``
            (each an integer divisor of the fastest).
        saturation_a : float, optional
            Current limit [A] (default: the actuator's; ``inf``: none).
        zero : bool
            Torque derivative on the whole error (default) or on feedback only.
        verify : bool
            Compile the C (``cc -std=c99 -Wall -Werror``) and run it and the Python on a
            sampled step response and on random signals against seactl's own sampled
            controller, before writing.

        Returns
        -------
        seactl.export.ExportResult
            ``files`` written, the per-process ``controllers`` and the ``verification``
            (``max_error``: largest relative difference; ``compiler``; ``compile_s``).

        Examples
        --------
        >>> import tempfile
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms=(1, 2, 1), filters_hz=(50, 100))
        >>> res = d.export(tempfile.mkdtemp(), lang="python,json")
        >>> sorted(p.name for p in res.files)
        ['.seactl-export', 'controller.json', 'embedded.py', 'high_level.py']
        >>> res.controllers.process("high-level").outputs
        ('tau_fb_from_high_level',)
        """
        from .export import export_design
        from .loops import sea_diagram

        return export_design(sea_diagram(zero), self.sea, out, languages=lang,
                             rates_hz=rates_hz, saturation=self._current_limit(saturation_a),
                             verify_export=verify, step=0.1)

    def _current_limit(self, saturation_a: float | None) -> dict[str, float]:
        """The current limit of ``export`` and ``run`` (default: the actuator's)."""
        sat = self.actuator.max_current if saturation_a is None else float(saturation_a)
        if not sat > 0:
            raise InputError("saturation_a [A]", sat, "> 0 (inf: no limit)")
        return {"i_m": sat}

    @run_doc
    def run(self, *, duration_s: float = 2.0, rates_hz: Any = 1000.0, step_rad: float = 0.01,
            transport: str = "zenoh", extra_latency_s: float = 0.0, loss: float = 0.0,
            seed: int = 0, saturation_a: float | None = None, zero: bool = True) -> Any:
        """Run the exported controllers as three OS processes on loopback.

        A plant process (the SEA integrated exactly at the fastest rate), the exported
        ``embedded`` and ``high-level`` controllers, messages over Zenoh (or UDP) on
        127.0.0.1; then the measured response is compared with the sampled simulation
        replaying the measured timing of the high-level link (docs/export.md).

        Parameters
        ----------
        duration_s : float
            Run time [s], 0.1 to 60.
        rates_hz : float or mapping
            As :meth:`export` (at most 5000 Hz).
        step_rad : float
            Step of ``q_des`` [rad].
        {link_parameters}
        saturation_a : float, optional
            Current limit [A] (default: the actuator's).
        zero : bool
            As :meth:`export`.

        Returns
        -------
        seactl.runtime.RunResult
            ``summary`` (latency per link with histograms, ``replay_max_diff``,
            ``nominal_max_diff``, ...), the responses and the latency samples.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms=(1, 2, 1), filters_hz=(50, 100))
        >>> res = d.run(duration_s=0.2, transport="udp")          # doctest: +SKIP
        >>> res.summary["replay_max_diff"] < 1e-9                  # doctest: +SKIP
        True
        """
        from .loops import sea_diagram
        from .runtime import run_distributed

        return run_distributed(sea_diagram(zero), self.sea,
                               saturation=self._current_limit(saturation_a),
                               step=step_rad, duration_s=duration_s, rates_hz=rates_hz,
                               transport=transport, extra_latency_s=extra_latency_s,
                               loss=loss, seed=seed)

    def reshape(self, *shape: int) -> Design:
        """The same designs with another batch shape.

        Parameters
        ----------
        *shape : int
            New shape (as :meth:`numpy.ndarray.reshape`).

        Returns
        -------
        Design
            The same designs with every array reshaped.

        Examples
        --------
        >>> import numpy as np, seactl as sc
        >>> d = sc.design(np.array([12, 14, 16])[:, None], gs=[0.5, 1.0])
        >>> d.shape, d.reshape(6).shape
        ((3, 2), (6,))
        """
        base = self if self.shape else self[None]
        n = int(np.prod(base.shape))
        try:
            idx = np.arange(n).reshape(*shape)
        except (TypeError, ValueError):
            raise InputError("shape", shape, f"integers whose product is {n} (the number of "
                             "designs), one of them -1 at most") from None
        return base[np.unravel_index(idx, base.shape)]


def _filter_repr(f: Any) -> Any:
    return None if f is None else np.asarray(f).tolist()


def design(fn_hz: Any, *, actuator: Any = "ut-sea", gs: Any = 1.0, zeta1: Any = 1.0,
           zeta2: Any = 1.0, ratio: Any = 1.0, delays_ms: Sequence[Any] = (0.0, 0.0, 0.0),
           filters_hz: Sequence[Any] = (None, None), solution: int = 0) -> Design:
    """Critically-damped SEA designs for natural frequencies ``fn_hz``.

    The four gains come from the closed-form solution of the critically-damped
    equations (:func:`seactl.design.critically_damped_gains`), then the gain scale
    ``gs`` multiplies the torque gains and divides the impedance gains.

    Parameters
    ----------
    fn_hz : array_like
        Natural frequency ``f_n`` [Hz] of the target closed loop.
    actuator : str or path or SEAParams
        Preset name (``"ut-sea"``), TOML file, or an :class:`~seactl.actuators.SEAParams`.
    gs : array_like
        Gain scale GS (broadcast with ``fn_hz``; use ``np.array(fn)[:, None]`` and a row of
        ``gs`` for a grid).
    zeta1, zeta2 : float
        Damping ratios of the two target pole pairs.
    ratio : float
        ``w2 / w1`` of the two pole pairs.
    delays_ms : tuple of array_like
        ``(T_tau, T_qs, T_qd)``: torque-feedback, stiffness-feedback and damping-feedback
        delays [ms], each in [0, 1000].
    filters_hz : tuple
        ``(f_qd, f_taud)``: velocity-filter and torque-derivative-filter cut-offs [Hz];
        ``None`` means no filter.
    solution : int
        Which gain solution when several exist (sorted by increasing ``K_tau``).

    Returns
    -------
    Design
        The batch, of the broadcast shape of ``fn_hz``, ``gs`` and the delays.

    Raises
    ------
    InputError
        A value outside its range; the message names the field, the value, the unit.
    InfeasibleDesignError
        No gain set with four positive gains exists (the message gives the feasible
        ``f_n`` range, ``f_n >= 9.456 Hz`` for the UT-SEA).

    Examples
    --------
    Table I of the paper:

    >>> import seactl as sc
    >>> d = sc.design([12, 14, 16], gs=1.0, delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
    >>> d.margins().phase_margin_deg.round(2)
    array([45.13, 43.26, 40.03])
    >>> d.gains.Kq.round(2)
    array([ 65.17,  83.17, 102.9 ])
    """
    from .actuators import SEAParams, load_sea
    from .design import critically_damped_gains

    act = resolve_actuator(actuator, load_sea, SEAParams)
    fn = finite_array("fn_hz [Hz]", fn_hz, minimum=0.0, strict=True, nonempty=True)
    g = finite_array("gs", gs, minimum=0.0, strict=True, nonempty=True)
    t_tau, t_qs, t_qd = delays_from_ms(delays_ms, ("T_tau", "T_qs", "T_qd"))
    f_qd, f_taud = _filters(filters_hz, ("f_qd", "f_taud"))
    check_batch(fn_hz=fn, gs=g, zeta1=zeta1, zeta2=zeta2, ratio=ratio,
                delays_ms=tuple(np.asarray(t) * 1e3 for t in (t_tau, t_qs, t_qd)),
                filters_hz=(f_qd, f_taud))
    fn_b, g_b = np.broadcast_arrays(fn, g)
    gains = critically_damped_gains(act, fn_b, zeta1=zeta1, zeta2=zeta2, ratio=ratio, gs=g_b,
                                    solution=solution)
    sea = SEADesign(act, gains, Timing(t_tau, t_qs, t_qd, f_qd, f_taud))
    shape = sea.shape
    if 0 in shape:
        raise InputError("fn_hz, gs, zeta1, zeta2, ratio, delays_ms, filters_hz",
                         f"a batch of shape {shape}", "arrays with at least one value")
    return Design(sea, np.broadcast_to(fn_b, shape), np.broadcast_to(g_b, shape))


def rightmost_roots(system: Any, count: int = 6) -> RootsResult:
    """Rightmost closed-loop roots of an SEA or rigid design batch, with exact delays.

    Parameters
    ----------
    system : Design or RigidBatch
        From :func:`seactl.design` or :func:`seactl.rigid`.
    count : int
        Roots per design (a conjugate pair counts once).

    Returns
    -------
    RootsResult
        ``roots`` [rad/s], ``spectral_abscissa`` [1/s] (negative: stable; its magnitude
        is the slowest decay rate), ``records()``.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rightmost_roots(sc.rigid(12, delays_ms=(1, 15)), count=1)
    >>> bool(r.spectral_abscissa > 0)            # 15 ms on the damping loop: unstable
    True
    """
    if not callable(getattr(system, "roots", None)):
        raise InputError("system", type(system).__name__, "a design batch from sc.design or "
                         "sc.rigid")
    return system.roots(count=count)
