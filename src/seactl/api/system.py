"""The one public system type: :class:`System`, a batch of designs of one block diagram.

Every kind of system (the SEA of :func:`seactl.design`, the rigid actuator of
:func:`seactl.rigid`, a user loop of :func:`seactl.load_loop`) is a subclass that supplies
its diagram, its parameters and its defaults; the views (margins, roots, impedance,
responses, jitter margins, Monte Carlo, exports, runs, sweeps) have the same names, the
same keywords and the same result types for every system.  A view a kind of system
cannot give raises :class:`~seactl.errors.InputError` naming the system and the reason.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from seactl.api.results import (
    ImpedanceResult,
    JitterResult,
    MarginsResult,
    ResponseResult,
    RootsResult,
    SampledMarginsResult,
)
from seactl.codegen.protocol import run_doc
from seactl.errors import InputError

MODES = ("continuous", "sampled")
KINDS = ("step", "impulse")


class System:
    """A batch of designs of one block diagram, with every analysis as a method.

    A subclass supplies its diagram, parameters, labels and defaults through the class
    attributes and hooks below; every view is implemented here once, on the diagram.
    All arrays of a system share its batch ``shape``; ``system[i]`` selects designs (numpy
    indexing), ``len(system)`` is the length of the first batch axis.

    Attributes
    ----------
    kind : str
        ``"sea"``, ``"rigid"`` or ``"loop"``.
    loops : tuple of str
        The names of the delayed loops, the keys of ``delays_ms`` and of the responses'
        ``requested_delays_s`` / ``effective_delays_s``.
    step_unit : str
        Unit of a step amplitude (``"rad"``, ``"m"`` or the loop file's).
    default_step : float
        The step amplitude every front end uses unless told otherwise.
    impulse_unit : str
        Unit of an impulse amplitude (``"N m s"``, ``"N s"``).
    default_impulse : float
        The impulse :meth:`impulse` and :meth:`monte_carlo` apply unless told otherwise.
    default_t_end_s : dict
        ``"step"`` / ``"impulse"`` -> the simulated window [s] when ``t_end_s`` is None.
    reference, disturbance, output, actuation, sensor : str
        Signals of the diagram: the input a step drives, the input an impulse drives, the
        position the responses show, the actuation signal the current limit saturates, and
        where :meth:`margins` breaks the loop.
    ports : tuple of str
        The impedance ports; the first is the default of :meth:`impedance`.
    export_step : float
        The reference step of :meth:`export`'s verification [``step_unit``].
    renamed : dict
        Method -> ``{old keyword: (new keyword, conversion or None)}``: deprecated
        spellings still accepted with a :class:`DeprecationWarning`.

    Notes
    -----
    The hooks a subclass implements: ``shape``, ``__getitem__``, ``labels()``, the
    properties ``design`` (the design batch the diagram's blocks read), ``diagram``,
    ``delays_s`` (loop -> delay [s]), ``links`` (loop -> delayed block),
    ``max_current_a`` (the default current limit) and ``amperes_per_actuation`` (the
    actuation signal -> motor current [A]), and the methods ``reference_frequency()``
    (a frequency scale [rad/s] per design), ``label_columns(gains=True)`` (the per-design
    columns of the results' records), ``impulse_inertia()`` (the inertia an impulse hits,
    for the simulation's divergence bound), ``impedance_response(f_hz, port, **options)``,
    ``jitter_core()`` and ``control_transfers(name)``.  ``diagram_for(**options)`` takes
    the kind's own options of the simulated and exported diagram (the SEA's ``zero``).  A
    user loop whose views do not all come from one diagram overrides those views; a view a
    kind cannot give calls :meth:`unsupported`.

    Examples
    --------
    Every kind of system is a ``System`` with the same views:

    >>> import seactl as sc
    >>> systems = [sc.design(14), sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})]
    >>> [isinstance(s, sc.System) for s in systems]
    [True, True]
    >>> [type(s.margins()).__name__ for s in systems]
    ['MarginsResult', 'MarginsResult']
    >>> [s.step().amplitude for s in systems], [s.step_unit for s in systems]
    ([0.01, 0.004], ['rad', 'm'])
    """

    kind: ClassVar[str] = ""
    loops: ClassVar[tuple[str, ...]] = ()
    step_unit: ClassVar[str] = ""
    default_step: ClassVar[float] = 1.0
    impulse_unit: ClassVar[str] = ""
    default_impulse: ClassVar[float] = 1.0
    default_t_end_s: ClassVar[dict[str, float]] = {"step": 0.5, "impulse": 1.0}
    reference: ClassVar[str] = ""
    disturbance: ClassVar[str] = ""
    output: ClassVar[str] = ""
    actuation: ClassVar[str] = ""
    sensor: ClassVar[str] = ""
    ports: ClassVar[tuple[str, ...]] = ()
    export_step: ClassVar[float] = 0.1
    renamed: ClassVar[dict[str, dict[str, tuple[str, Callable[[Any], Any] | None]]]] = {}

    # ------------------------------------------------------------ batch structure
    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        raise NotImplementedError

    def __getitem__(self, idx: Any) -> System:
        raise NotImplementedError

    def __len__(self) -> int:
        if not self.shape:
            raise TypeError(f"len() of a single design (a {type(self).__name__} of shape ())")
        return self.shape[0]

    @property
    def size(self) -> int:
        """The number of designs in the batch."""
        return int(np.prod(self.shape))

    def labels(self) -> list[str]:
        """One short legend label per design (flattened batch).

        Returns
        -------
        list of str
            One label per design, in flattened batch order.
        """
        raise NotImplementedError

    def reshape(self, *shape: int) -> System:
        """The same designs with another batch shape.

        Parameters
        ----------
        *shape : int
            New shape (as :meth:`numpy.ndarray.reshape`).

        Returns
        -------
        System
            The same designs, of the same type, with every array reshaped.

        Examples
        --------
        >>> import numpy as np, seactl as sc
        >>> d = sc.design(np.array([12, 14, 16])[:, None], gs=[0.5, 1.0])
        >>> d.shape, d.reshape(6).shape, sc.rigid([8, 12]).reshape(2, 1).shape
        ((3, 2), (6,), (2, 1))
        """
        base = self if self.shape else self[None]
        n = base.size
        try:
            idx = np.arange(n).reshape(*shape)
        except (TypeError, ValueError):
            raise InputError("shape", shape, f"integers whose product is {n} (the number of "
                             "designs), one of them -1 at most") from None
        return base[np.unravel_index(idx, base.shape)]

    def unsupported(self, view: str, reason: str) -> InputError:
        """The error a view this kind of system cannot give raises.

        Parameters
        ----------
        view : str
            The method's name.
        reason : str
            Why, and what to use instead.

        Returns
        -------
        InputError
            Naming the system kind and the view.
        """
        return InputError(f"{type(self).__name__}.{view}", self.kind, reason)

    # ------------------------------------------------------------ hooks
    @property
    def design(self) -> Any:
        """The design batch the diagram's blocks read."""
        raise NotImplementedError

    @property
    def diagram(self) -> Any:
        """The block diagram (:class:`~seactl.diagram.blockdiagram.BlockDiagram`)."""
        raise NotImplementedError

    def diagram_for(self, **options: Any) -> Any:
        """The diagram simulated and exported with the kind's own ``options`` (none here).

        Parameters
        ----------
        **options
            Kind-specific keywords (the SEA's ``zero``).

        Returns
        -------
        seactl.diagram.blockdiagram.BlockDiagram
            The diagram.
        """
        if options:
            raise InputError("keyword", ", ".join(sorted(options)),
                             f"none beyond the documented ones for a {self.kind} system")
        return self.diagram

    def label_columns(self, gains: bool = True) -> dict[str, Any]:
        """Per-design columns (batch shape) that label the results' records.

        Parameters
        ----------
        gains : bool
            Include the controller gains.

        Returns
        -------
        dict
            Column name -> array of the batch shape.
        """
        raise NotImplementedError

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        """Loop name -> its delay [s] (batch shape).
        """
        raise NotImplementedError

    @property
    def links(self) -> dict[str, str]:
        """Loop name -> the diagram's delayed block of that loop."""
        raise NotImplementedError

    @property
    def output_unit(self) -> str:
        """The unit of :attr:`output`, :attr:`step_unit` (the output tracks the reference).
        """
        return self.step_unit

    @property
    def max_current_a(self) -> float:
        """The actuator's current limit [A] (the default of ``saturation_a``)."""
        raise NotImplementedError

    @property
    def amperes_per_actuation(self) -> float:
        """Motor current [A] per unit of the actuation signal."""
        raise NotImplementedError

    @property
    def _evaluated_forms(self) -> dict | None:
        """Characteristic terms evaluated for this design, kept between the views that
        break the loop at different signals (a kind whose breaks share many terms keeps a
        dict; None: each view evaluates its own)."""
        return None

    def reference_frequency(self) -> np.ndarray:
        """A frequency scale [rad/s] per design (the margins' and roots' grids).

        Returns
        -------
        numpy.ndarray
            Per design [rad/s].
        """
        raise NotImplementedError

    def impulse_inertia(self) -> np.ndarray:
        """The inertia (or mass) an impulse of the external load hits.

        Returns
        -------
        numpy.ndarray
            Per design, in the kind's rotary or linear unit.
        """
        raise NotImplementedError

    def impedance_response(self, f_hz: Any, port: str, **options: Any) -> Any:
        """The impedance at ``port`` (:class:`seactl.systems.sea.impedance.ImpedanceResponse`).

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0.
        port : str
            The port.
        **options
            Kind-specific keywords.

        Returns
        -------
        seactl.systems.sea.impedance.ImpedanceResponse
            The impedance.
        """
        raise self.unsupported("impedance", "a kind of system with an impedance port")

    def jitter_core(self) -> Any:
        """The jitter margins (:class:`seactl.latency.jitter.JitterMargins`).

        Returns
        -------
        seactl.latency.jitter.JitterMargins
            Per loop, of the batch shape.
        """
        raise self.unsupported("jitter_margins", "a kind of system with named loops")

    def delay_terms(self) -> Any:
        """The closed loop's characteristic quasi-polynomial as a function of the loops'
        delays (:class:`seactl.diagram.delayterms.DelayTerms`, delays named by
        :attr:`loops`): what delay margins along a direction and stability charts vary.

        Returns
        -------
        seactl.diagram.delayterms.DelayTerms
            Of the batch shape.
        """
        from seactl.diagram.delayterms import diagram_delay_terms

        diagram = self.diagram
        names = {diagram.block(block).delay: loop for loop, block in self.links.items()}
        return diagram_delay_terms(diagram.characteristic(), self.design, names)

    def control_transfers(self, name: str) -> Any:
        """Transfer name -> (transfer, divide by ``-s``) for :meth:`to_control`.

        Parameters
        ----------
        name : str
            The transfer's name.

        Returns
        -------
        tuple
            ``(transfer, divide_by_minus_s)``.
        """
        raise self.unsupported("to_control", "a kind of system with named transfers")

    # ------------------------------------------------------------ helpers
    def _legacy(self, method: str, options: dict[str, Any], **current: Any
                ) -> tuple[dict[str, Any], dict[str, Any]]:
        """The current keywords with deprecated spellings in ``options`` moved onto them (a
        :class:`DeprecationWarning` each), and the remaining options."""
        table = self.renamed.get(method, {})
        rest = dict(options)
        for old in [k for k in rest if k in table]:
            new, convert = table[old]
            value = rest.pop(old)
            if current.get(new) is not None:
                raise InputError(old, value, f"not given together with {new} (its new name)")
            warnings.warn(f"{type(self).__name__}.{method}({old}=...) is deprecated; use "
                          f"{new}=...", DeprecationWarning, stacklevel=3)
            current[new] = convert(value) if convert is not None else value
        return current, rest

    @staticmethod
    def _amplitude(value: Any, default: float, unit: str) -> float:
        a = default if value is None else value
        try:
            a = float(a)
        except (TypeError, ValueError):
            raise InputError(f"amplitude [{unit}]", value, "a finite non-zero number") from None
        if not (math.isfinite(a) and a != 0):
            raise InputError(f"amplitude [{unit}]", a, "a finite non-zero number")
        return a

    def saturation(self, saturation_a: float | None = None) -> dict[str, float]:
        """The actuation limit of the sampled loop, exports and runs.

        Parameters
        ----------
        saturation_a : float, optional
            Motor current limit [A] (default: the actuator's; ``inf``: none).

        Returns
        -------
        dict
            Actuation signal -> its symmetric limit (in the signal's unit).
        """
        sat = self.max_current_a if saturation_a is None else saturation_a
        try:
            sat = float(sat)
        except (TypeError, ValueError):
            raise InputError("saturation_a [A]", saturation_a, "> 0 (inf: no limit)") from None
        if not sat > 0:
            raise InputError("saturation_a [A]", sat, "> 0 (inf: no limit)")
        return {self.actuation: sat * self.amperes_per_actuation}

    def _check_simulation(self, mode: str, rate_hz: float, t_end_s: float) -> None:
        """Ranges, samples, memory and time of a simulation (errors name the parameters)."""
        from seactl.base.limits import check_simulation

        if mode not in MODES:
            raise InputError("mode", mode, " or ".join(MODES))
        delays = [float(np.min(np.where(np.asarray(d) > 0, d, np.inf)))
                  for d in self.delays_s.values()]
        check_simulation(self.size, mode, rate_hz, t_end_s,
                         [d for d in delays if np.isfinite(d)])

    def _t_end(self, kind: str, t_end_s: float | None) -> float:
        return self.default_t_end_s[kind] if t_end_s is None else t_end_s

    # ------------------------------------------------------------ frequency-domain views
    def margins(self, rate_hz: Any = None) -> MarginsResult | SampledMarginsResult:
        """Phase, gain and delay margins of the loop broken at :attr:`sensor`, and the
        closed loop's Nyquist stability, with exact delays.

        Parameters
        ----------
        rate_hz : float or dict, optional
            ``None`` (default): the continuous loop.  A rate [Hz] (every process), or
            ``{"embedded": ..., "high-level": ...}``: the sampled-data loop that
            ``step(mode="sampled")`` runs (Tustin controllers, whole-sample delays, the
            held plant), with a certified verdict and margins from its discrete frequency
            response up to Nyquist (:func:`seactl.simulate.sampled.sampled_margins`; the argument
            is in docs/theory/sampled.md).  A multi-rate loop gets its verdict only.

        Returns
        -------
        MarginsResult or SampledMarginsResult
            Arrays of the batch shape (``phase_margin_deg``, ``delay_margin_ms``,
            ``stable``, ...), with ``to_dict()``, ``records()`` and ``plot()``; sampled:
            also ``verdict`` and ``delay_margin_samples``.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design([12, 14, 16], delays_ms={"torque": 0.5, "stiffness": 2,
        ...                                        "damping": 0.5}, filters_hz=(50, 100))
        >>> d.margins().phase_margin_deg.round(2)
        array([45.13, 43.26, 40.03])
        >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
        >>> round(float(r.margins().phase_margin_deg), 1)
        52.6
        """
        w_ref = self.reference_frequency()
        if rate_hz is not None:
            from seactl.simulate.sampled import sampled_margins

            return SampledMarginsResult(sampled_margins(self.diagram, self.design, self.sensor,
                                                        rate_hz, w_ref), self.label_columns())
        from seactl.analysis.margins import default_grid, loop_margins

        return MarginsResult(loop_margins(self.diagram.loop(self.sensor), self.design,
                                          default_grid(w_ref),
                                          shared_forms=self._evaluated_forms),
                             self.label_columns())

    def roots(self, count: int = 6) -> RootsResult:
        """Rightmost roots of the closed loop (exact delays), per design.

        Chebyshev collocation of the delay equation gives candidates, Newton on the exact
        characteristic quasi-polynomial polishes them, the argument principle checks
        that none is missing and bounds each by a disc that holds it, multiplicity
        counted (:func:`seactl.analysis.roots.characteristic_roots`).

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
        >>> d = sc.design(15.93, gs=1.867, delays_ms={"torque": 1.99, "stiffness": 1.96,
        ...                                           "damping": 18.54})
        >>> z = complex(d.roots(count=2).roots[0])
        >>> round(z.real, 2), round(z.imag, 1), bool(d.margins().stable)
        (1.19, 747.3, False)
        """
        from seactl.analysis.roots import characteristic_roots
        from seactl.base.limits import check_roots

        check_roots(self.size, count,
                    any(np.any(np.asarray(d) > 0) for d in self.delays_s.values()))
        return RootsResult(characteristic_roots(self.diagram, self.design, count=count),
                           self.label_columns(gains=False))

    def delay_margin(self, direction: Any = None) -> Any:
        """Delay margin along a direction of the delay vector, with exact delays.

        The delays move on ``tau0 + t d / max(d)`` from the design's own ``tau0``; the
        margin is the smallest ``t >= 0`` [s] (the extra delay of the most-moved delay)
        at which a characteristic root reaches the imaginary axis: 0 if unstable at
        ``tau0``, ``inf`` if none ever does.  Frequency sweeping on the exact
        quasi-polynomial (:mod:`seactl.analysis.delay_direction`), checked by certified
        root counts along the ray (docs/theory/delay-margin.md).

        Parameters
        ----------
        direction : dict or sequence, optional
            Delay name (of :meth:`delay_terms`, the :attr:`loops`) -> weight >= 0 (absent:
            0, the delay stays), or weights in the order of ``delay_terms().names``;
            default: every delay grows alike.  The weights' ratios must be ratios of
            integers up to 16 (commensurate).

        Returns
        -------
        DelayMarginResult
            ``delay_margin_s``, ``crossing_hz``, ``crossing_delays_s``, ``stable``,
            ``verified``, ``touch`` (batch shape), ``records()``, ``to_dict()``.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
        ...               filters_hz=(50, 100))
        >>> m = d.delay_margin({"stiffness": 1})
        >>> round(float(m.delay_margin_s) * 1e3, 2), round(float(m.crossing_hz), 2)
        (15.65, 8.84)
        """
        from seactl.analysis.delay_direction import direction_margin
        from seactl.api.delayresult import DelayMarginResult

        terms = self.delay_terms()
        return DelayMarginResult(direction_margin(terms, direction), terms.names, terms.shape,
                                 self.label_columns(gains=False))

    def impedance(self, f_hz: Any, *, port: str | None = None,
                  **options: Any) -> ImpedanceResult:
        """Impedance felt at a port, ``Z(j 2 pi f) = force / velocity``, with exact delays.

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0 (the last axis of the result).
        port : str, optional
            One of :attr:`ports` (default: the first).
        **options
            The kind's own options (the SEA's ``model``, ``load``, ``units``).

        Returns
        -------
        ImpedanceResult
            ``z`` of shape ``shape + (len(f_hz),)``, ``magnitude``, ``phase_deg``, ...

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
        >>> z = r.impedance([1e-4], port="output")        # s Z -> K at low frequency
        >>> round(float(z.stiffness[..., 0].real) / float(r.gains.K), 6)
        1.0
        """
        if port is None:
            port = self.ports[0]
        if port not in self.ports:
            raise InputError("port", port, "one of " + ", ".join(self.ports))
        return ImpedanceResult(self.impedance_response(f_hz, port, **options), self.labels())

    def jitter_loops(self) -> tuple[Any, dict[str, str], Any]:
        """The split diagram, its taps and the design batch the jitter margins break.

        Returns
        -------
        tuple
            ``(diagram, taps, design)``: taps map a loop name to its signal (the same
            loops as :meth:`jitter_core`).
        """
        raise self.unsupported("jitter_margins(rate_hz=...)", "a kind of system with named "
                               "loops")

    def jitter_margins(self, rate_hz: Any = None) -> Any:
        """Jitter margins of the whole loop and of each delayed loop alone (Kao-Lincoln
        small-gain bound with exact delays; with ``rate_hz``, of the sampled loop).

        The jitter margin of a loop is the largest ``J`` such that any *time-varying*
        extra delay in ``[0, J]`` at that loop's break keeps the closed loop stable:
        ``J = 1 / max_w (w |T(jw)|)``, ``T = L/(1+L)`` the complementary sensitivity there
        (:mod:`seactl.latency.jitter`); 0 for an unstable design.

        Parameters
        ----------
        rate_hz : float, optional
            ``None`` (default): the continuous loop.  A rate [Hz]: the sampled loop that
            ``step(mode="sampled")`` runs at that rate (as :meth:`margins`), with the
            measurement at each break sampled late by a delay varying in ``[0, J]``
            (:mod:`seactl.simulate.sampled_jitter`, docs/theory/sampled-jitter.md); one rate
            for every process.

        Returns
        -------
        JitterResult or SampledJitterResult
            Arrays of the batch shape (``jitter_margin_s``, ``stiffness_jitter_margin_s``,
            ``damping_jitter_margin_s``, ``torque_jitter_margin_s`` (SEA; None for the rigid
            actuator), ``delay_margin_s``, ``stable``), with ``records()``; sampled:
            ``jitter_margin_samples``, ``rate_hz``, ``verdict`` instead of the delay margin.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
        ...               filters_hz=(50, 100))
        >>> j = d.jitter_margins()
        >>> ms = 1e3 * j.jitter_margin_s
        >>> ms.round(2), bool(1e3 * j.damping_jitter_margin_s[1] > ms[1])
        (array([11.47,  8.04]), True)
        >>> j = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).jitter_margins()
        >>> bool(j.damping_jitter_margin_s < j.stiffness_jitter_margin_s)
        True
        """
        if rate_hz is not None:
            from seactl.api.sampled_jitter import SampledJitterResult
            from seactl.simulate.sampled_jitter import sampled_jitter_margins

            diagram, taps, design = self.jitter_loops()
            return SampledJitterResult(sampled_jitter_margins(
                diagram, design, taps, rate_hz, self.reference_frequency()),
                self.label_columns(gains=False))
        return JitterResult(self.jitter_core(), self.label_columns(gains=False))

    def stability_chart(self, delays: Any, max_s: Any, *, resolution: int = 1000) -> Any:
        """Stability chart over two delays: the crossing curves and the certified number of
        right-half-plane roots in each region they bound, the other delays at the design's.

        The curves are the delays at which a root crosses the imaginary axis, computed
        exactly by frequency sweeping (each frequency's solutions on the torus by
        polynomial root finding, Newton-polished); each region's count is certified by the
        argument principle at one of its points and checked against the direction in which
        the roots cross the curves (:mod:`seactl.analysis.stability_chart`).

        Parameters
        ----------
        delays : tuple of str
            The two delays varied, among :attr:`loops` (the names of
            :meth:`delay_terms`).
        max_s : tuple of float
            The chart ``[0, max_s[0]] x [0, max_s[1]]`` [s].
        resolution : int
            Pixels per side of the raster that separates the regions (100 to 4000).

        Returns
        -------
        StabilityChartResult
            Curves, regions with their counts, the design's point, ``to_dict()``,
            ``records()`` (one per region) and ``plot()``.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
        >>> c = r.stability_chart(("stiffness", "damping"), (0.02, 0.02), resolution=200)
        >>> c.design_stable == bool(r.margins().stable), c.consistent
        (True, True)
        """
        from seactl.analysis.stability_chart import stability_chart
        from seactl.api.chartresult import StabilityChartResult, chart_arguments

        if self.size != 1:
            raise InputError("stability_chart", f"a batch of {self.size} designs",
                             "one design: select one with system[i]")
        terms = self.delay_terms()
        names, extent = chart_arguments(delays, max_s, resolution, terms.names)
        return StabilityChartResult(stability_chart(terms, names, extent, resolution),
                                    names, extent)

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
        transfer : str
            ``"loop"`` (the loop :meth:`margins` breaks), ``"closed"`` (position /
            reference) and the kind's own: SEA ``"inner"`` (torque loop), ``"impedance"``
            [N m s/rad]; rigid ``"compliance"`` (``x / F_ext`` [m/N]).
        f_hz : array_like, optional
            Frequencies of the FRD [Hz] (default: 2000 points from 0.01 Hz to 10 kHz).
        order : int
            Padé order per delay, 1 to 4 (3 matches the exact SEA loop to 2e-5 relative
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
        >>> d = sc.design(12, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
        ...               filters_hz=(50, 100))
        >>> round(float(ct.margin(d.to_control("frd"))[1]), 1)
        45.1
        """
        from seactl.api.control import to_control

        if not self.shape:
            return to_control(self.design, kind, transfer, f_hz, order, self.control_transfers)
        flat = self.reshape(self.size)
        return [to_control(flat[i].design, kind, transfer, f_hz, order,
                           self.control_transfers) for i in range(self.size)]

    # ------------------------------------------------------------ time-domain views
    def step(self, *, t_end_s: float | None = None, amplitude: float | None = None,
             mode: str = "continuous", rate_hz: float = 1000.0,
             saturation_a: float | None = None, **options: Any) -> ResponseResult:
        """Response of the position to a step of the reference.

        Parameters
        ----------
        t_end_s : float, optional
            Simulated time [s] (default :attr:`default_t_end_s` ``["step"]``).
        amplitude : float, optional
            Step size [:attr:`step_unit`] (default :attr:`default_step`).  The linear
            continuous response does not depend on it once normalized; the sampled one
            does where the current limit clips.
        mode : {"continuous", "sampled"}
            Exact continuous-time delays, or controllers sampled at ``rate_hz`` with
            whole-sample delay buffers and the current limit.
        rate_hz : float
            Controller rate of the sampled mode [Hz].
        saturation_a : float, optional
            Motor current limit [A] of the sampled mode (default: the actuator's; ``inf``:
            none).
        **options
            The kind's own options (the SEA's ``zero``).

        Returns
        -------
        ResponseResult
            ``t_s``, ``position`` (divided by the step, in both modes), ``current`` [A],
            ``amplitude`` and ``metrics`` (rise, overshoot, settling); ``verdict()``.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms={"torque": 1, "stiffness": 1, "damping": 1},
        ...               filters_hz=(50, 100))
        >>> r = d.step(t_end_s=0.4)
        >>> bool(r.metrics.stable), round(float(r.metrics.final_value), 3), r.amplitude
        (True, 1.0, 0.01)
        >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).step(t_end_s=1.0)
        >>> bool(r.metrics.stable), r.amplitude, r.amplitude_unit
        (True, 0.004, 'm')
        """
        from seactl.simulate.inputs import Step

        kw, options = self._legacy("step", options, amplitude=amplitude,
                                   saturation_a=saturation_a)
        a = self._amplitude(kw["amplitude"], self.default_step, self.step_unit)
        return self._response("step", {self.reference: Step(a)}, a, self.step_unit,
                              self._t_end("step", t_end_s), mode, rate_hz, kw["saturation_a"],
                              options, None)

    def impulse(self, *, t_end_s: float | None = None, amplitude: float | None = None,
                mode: str = "continuous", rate_hz: float = 1000.0,
                saturation_a: float | None = None, **options: Any) -> ResponseResult:
        """Response of the position to an impulse of the external load at ``t = 0``
        (reference 0).

        Parameters
        ----------
        t_end_s : float, optional
            Simulated time [s] (default :attr:`default_t_end_s` ``["impulse"]``).
        amplitude : float, optional
            The impulse [:attr:`impulse_unit`] (default :attr:`default_impulse`).
        mode : {"continuous", "sampled"}
            As :meth:`step`.
        rate_hz : float
            As :meth:`step`.
        saturation_a : float, optional
            As :meth:`step`.
        **options
            As :meth:`step`.

        Returns
        -------
        ResponseResult
            ``t_s``, ``position`` [rad or m], ``current`` [A], ``amplitude`` and
            ``metrics`` (peak deviation, recovery time); ``verdict()``.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.design(14, filters_hz=(50, 100)).impulse(t_end_s=0.5)
        >>> bool(r.metrics.stable), bool(r.metrics.recovery_time_s < 0.2), r.amplitude
        (True, True, 0.05)
        """
        from seactl.simulate.inputs import Impulse

        kw, options = self._legacy("impulse", options, amplitude=amplitude,
                                   saturation_a=saturation_a)
        a = self._amplitude(kw["amplitude"], self.default_impulse, self.impulse_unit)
        t_end = self._t_end("impulse", t_end_s)
        # bound: 1e3 times the free peak velocity times the window, never tiny
        bound = 1e3 * abs(a) / float(np.min(self.impulse_inertia())) * t_end
        return self._response("impulse", {self.disturbance: Impulse(a)}, a, self.impulse_unit,
                              t_end, mode, rate_hz, kw["saturation_a"], options, bound)

    def _response(self, kind: str, inputs: dict[str, Any], amplitude: float, unit: str,
                  t_end_s: float, mode: str, rate_hz: float, saturation_a: float | None,
                  options: dict[str, Any], bound: float | None) -> ResponseResult:
        """Simulate, normalize a step, add the sampled loop's certified verdict, judge."""
        import functools

        from seactl.analysis.margins import closed_loop_right_roots
        from seactl.simulate.engine import simulate
        from seactl.simulate.metrics import impulse_metrics, step_metrics
        from seactl.simulate.results import SEAResponse, SimResult
        from seactl.simulate.verdict import RECOVERY_BAND

        diagram = self.diagram_for(**options)
        self._check_simulation(mode, rate_hz, t_end_s)
        kw: dict[str, Any] = {}
        if mode == "sampled":
            kw = {"rates_hz": float(rate_hz), "saturation": self.saturation(saturation_a)}
        elif saturation_a is not None and not math.isinf(float(saturation_a)):
            raise InputError("saturation_a [A]", saturation_a, "used in sampled mode only")
        res = simulate(diagram, self.design, inputs, t_end_s, mode=mode,
                       outputs=(self.output, self.actuation), bound=bound, **kw)
        actuation = res.outputs[self.actuation]
        if mode == "sampled":
            self._sampled_info(res.info, diagram, rate_hz)
            limit = kw["saturation"][self.actuation]
            actuation = np.clip(actuation, -limit, limit)
            res.info["current_limit_a"] = limit / self.amperes_per_actuation
        y = res.outputs[self.output]
        y = y / amplitude if kind == "step" else y
        sim = SimResult(res.mode, res.t_s, {"q_j": y, "i_m": actuation
                                            / self.amperes_per_actuation},
                        res.stable, res.left_bounds_s, res.bound, res.info)
        metrics = (step_metrics(res.t_s, y, res.stable, res.left_bounds_s) if kind == "step"
                   else impulse_metrics(res.t_s, y, res.stable, res.left_bounds_s,
                                        RECOVERY_BAND))
        roots = functools.partial(closed_loop_right_roots, diagram, self.design,
                                  self.reference_frequency())
        return ResponseResult(SEAResponse(kind, sim, metrics), self.labels(), roots,
                              links=self.links, amplitude=amplitude, amplitude_unit=unit,
                              output=self.output, output_unit=self.output_unit)

    def _sampled_info(self, info: dict[str, Any], diagram: Any, rate_hz: float) -> None:
        """The sampled loop's certified verdict beside the response (``sampled_verdict``,
        ``sampled_unstable_modes``, ``sampled_rate``); where it is certified it replaces
        the simulation's own count (``unstable_modes``) the verdict reads."""
        from seactl.simulate.sampled import sampled_roots

        r = sampled_roots(diagram, self.design, rate_hz)
        own = np.asarray(info.get("unstable_modes", r.unstable_modes))
        info.update(sampled_verdict=r.verdict, sampled_unstable_modes=r.unstable_modes,
                    sampled_rate=r.rate_label,
                    unstable_modes=np.where(r.unstable_modes >= 0, r.unstable_modes, own))

    def monte_carlo(self, kind: str = "step", *, latency: Any = None, loss: Any = None,
                    runs: int = 100, seed: int = 0, rate_hz: float = 1000.0,
                    t_end_s: float | None = None, amplitude: float | None = None,
                    saturation_a: float | None = None, **options: Any) -> Any:
        """Sampled step or impulse responses under random latency and message loss.

        Parameters
        ----------
        kind : {"step", "impulse"}
            A step of the reference or an impulse of the external load, as :meth:`step`
            and :meth:`impulse`.
        latency : dict, optional
            Loop name (:attr:`loops`) -> latency model of :mod:`seactl.latency.models`
            (seconds), or its text form in ms (``"uniform:0.5:3"``).
        loss : dict, optional
            Loop name -> loss probability, loss model, or text (``"ge:0.01:0.3"``).
        runs : int
            Timing realizations per design.
        seed : int
            Seed (each run has its own stream: reproducible).
        rate_hz : float
            Servo rate of every process [Hz].
        t_end_s : float, optional
            Window [s] (default :attr:`default_t_end_s`).
        amplitude : float, optional
            Step [:attr:`step_unit`] or impulse [:attr:`impulse_unit`] (default
            :attr:`default_step`, :attr:`default_impulse`).
        saturation_a : float, optional
            Motor current limit [A] (default: the actuator's).
        **options
            The kind's own options (the SEA's ``zero``).

        Returns
        -------
        seactl.latency.montecarlo.MonteCarloSummary
            ``fraction_stable``, ``rms_error_mean``, ``rms_error_worst``,
            ``peak_current_worst_a``, ``worst_run`` (batch shape), per-run arrays and the
            batched simulation.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
        ...               filters_hz=(50, 100))
        >>> mc = d.monte_carlo(latency={"damping": "uniform:0.5:3"}, runs=10, t_end_s=0.3)
        >>> float(mc.fraction_stable)
        1.0
        """
        from seactl.latency.models import parse_latency, parse_loss
        from seactl.latency.montecarlo import response_monte_carlo
        from seactl.simulate.inputs import Impulse, Step

        if kind not in KINDS:
            raise InputError("kind", kind, " or ".join(repr(k) for k in KINDS))
        step = kind == "step"
        a = self._amplitude(amplitude, self.default_step if step else self.default_impulse,
                            self.step_unit if step else self.impulse_unit)
        t_end = float(self._t_end(kind, t_end_s))
        inputs = {self.reference: Step(a)} if step else {self.disturbance: Impulse(a)}
        bound = None if step else \
            1e3 * abs(a) / float(np.min(self.impulse_inertia())) * t_end
        lat = {k: parse_latency(v, f"latency {k}") if isinstance(v, str) else v
               for k, v in (latency or {}).items()}
        los = {k: parse_loss(v, f"loss {k}") if isinstance(v, str) else v
               for k, v in (loss or {}).items()}
        return response_monte_carlo(self.diagram_for(**options), self.design, kind, inputs,
                                    t_end, amplitude=a, output=self.output,
                                    actuation=self.actuation,
                                    amperes_per_unit=1.0 / self.amperes_per_actuation,
                                    latency=lat, loss=los, runs=runs, seed=seed,
                                    links=self.links, bound=bound, rate_hz=rate_hz,
                                    saturation=self.saturation(saturation_a))

    # ------------------------------------------------------------ code and runs
    def export(self, out: Any, *, lang: Any = ("c", "python", "json"),
               rates_hz: Any = 1000.0, saturation_a: float | None = None,
               verify: bool = False, emulate_latency: bool = False, real: str = "double",
               **options: Any) -> Any:
        """Write the discrete controller of each process as C99, Python and JSON.

        The sampled controller (Tustin derivatives and filters, the current limit) split
        by process, as the diagram's blocks say, in the form that runs on the robot: the
        gains, filter time constants, output limit and watchdog bound in a parameter
        struct that can be changed at run time (bumpless), a ``reset``, no dynamic memory
        (docs/export.md).

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
            Motor current limit [A] (default: the actuator's; ``inf``: none); the rigid
            actuator's force limit is ``beta`` times it.  The default of the limit
            parameter.
        verify : bool
            Compile the C (``cc -std=c99 -Wall -Wextra -Werror -pedantic``) and run it and
            the Python on a sampled step response (:attr:`export_step`) and on random
            signals against seactl's own sampled controller, before writing.
        emulate_latency : bool
            Keep the design's delays in the code as whole-sample buffers (effective delays
            ``T_s/2 + n T_s``, never shorter than requested; for bench tests).  By default
            the code holds no delay: on the robot the latency is the platform's, and the
            code equals the sampled controller with zero delays.
        real : {"double", "float"}
            Floating-point type of the C's signals and states.
        **options
            The kind's own options (the SEA's ``zero``).

        Returns
        -------
        seactl.codegen.export.ExportResult
            ``files`` written, the per-process ``controllers`` and the ``verification``
            (``max_error``: largest relative difference; ``compiler``; ``compile_s``).

        Examples
        --------
        >>> import tempfile
        >>> import seactl as sc
        >>> r = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5})
        >>> res = r.export(tempfile.mkdtemp(), lang="json")
        >>> [p.name for p in res.controllers.processes]
        ['high-level', 'embedded']
        """
        from seactl.codegen.export import export_design

        kw, options = self._legacy("export", options, saturation_a=saturation_a)
        return export_design(self.diagram_for(**options), self.design, out, languages=lang,
                             rates_hz=rates_hz, saturation=self.saturation(kw["saturation_a"]),
                             verify_export=verify, step=self.export_step,
                             emulate_latency=emulate_latency, real=real)

    @run_doc
    def run(self, *, duration_s: float = 2.0, rates_hz: Any = 1000.0,
            amplitude: float | None = None, transport: str = "zenoh",
            extra_latency_s: float = 0.0, loss: float = 0.0, seed: int = 0,
            saturation_a: float | None = None, plant: str = "builtin", latency: Any = None,
            realtime: bool = False, **options: Any) -> Any:
        """Run the exported controllers as three OS processes on loopback.

        A plant process (the plant integrated exactly at the fastest rate, or MuJoCo), the
        exported ``embedded`` and ``high-level`` controllers, messages over Zenoh (or UDP)
        on 127.0.0.1; then the measured response is compared with the sampled simulation
        replaying the measured timing of the high-level link (docs/export.md).  On the
        MuJoCo plant the measured step is also judged against the band of sampled step
        responses for the ``latency`` distribution (docs/mujoco.md).

        Parameters
        ----------
        duration_s : float
            Run time [s], 0.1 to 60.
        rates_hz : float or mapping
            As :meth:`export` (at most 5000 Hz).
        amplitude : float, optional
            Step of the reference [:attr:`step_unit`] (default :attr:`default_step`).
        {link_parameters}
        saturation_a : float, optional
            Motor current limit [A] (default: the actuator's).
        plant : {"builtin", "mujoco"}
            The plant process: seactl's exact linear plant, or the MuJoCo model of the
            actuator (:mod:`seactl.codegen.mjcf`; the ``sim`` extra; SEA and rigid only).
        latency : dict, optional
            With ``plant="mujoco"`` or ``realtime``: loop name -> latency model (as
            :meth:`monte_carlo`) of the prediction band (default: the run's measured
            latency of the high-level loop, free-running of every loop; ``{}``: the
            design's delays, one nominal response).
        realtime : bool
            Free-running processes, each on its own clock, running the exported C
            (compiled with the system's ``cc``), with timing statistics in the summary;
            default: lock-step, the exact replay check.
        **options
            The kind's own options (the SEA's ``zero``).

        Returns
        -------
        seactl.codegen.runtime.RunResult
            ``summary`` (latency per link with histograms, ``replay_max_diff``,
            ``nominal_max_diff``, ``plant``; ``latency_check``: per delayed loop across
            the link, its measured latency against its jitter margin and delay limit,
            ``"within the jitter margin"`` or ``"outside: ..."``; with MuJoCo or
            ``realtime``, ``prediction_band``: the verdict ``"within the predicted
            band"`` or ``"outside: ..."`` and its numbers), the responses and the
            latency samples.

        Examples
        --------
        >>> import seactl as sc
        >>> d = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
        ...               filters_hz=(50, 100))
        >>> res = d.run(duration_s=0.2, transport="udp")          # doctest: +SKIP
        >>> res.summary["replay_max_diff"] < 1e-9                  # doctest: +SKIP
        True
        """
        from seactl.codegen.runtime import run_distributed

        kw, options = self._legacy("run", options, amplitude=amplitude,
                                   saturation_a=saturation_a)
        a = self._amplitude(kw["amplitude"], self.default_step, self.step_unit)
        diagram, sat = self.diagram_for(**options), self.saturation(kw["saturation_a"])
        lat = None
        if plant == "mujoco" or realtime:
            from seactl.latency.band import band_latency

            if plant == "mujoco":
                from seactl.codegen.mjcf import plant_model

                plant_model(self.design)   # an SEA or a rigid actuator, before any process
            lat = band_latency(latency, self.links)
        elif latency is not None:
            raise InputError("latency", latency, "used with plant='mujoco' or realtime=True")
        res = run_distributed(diagram, self.design, saturation=sat, step=a,
                              duration_s=duration_s, rates_hz=rates_hz, transport=transport,
                              extra_latency_s=extra_latency_s, loss=loss, seed=seed,
                              plant=plant, realtime=bool(realtime))
        if plant == "mujoco" or realtime:
            from seactl.latency.band import run_band

            run_band(res, diagram, self.design, reference=self.reference, links=self.links,
                     latency=lat, rates_hz=rates_hz, saturation=sat, seed=seed)
        from seactl.api.runcheck import check_run

        check_run(self, res)
        return res

    def sweep(self, out: Any, **options: Any) -> Any:
        """Write this system's design space as a resumable Parquet table (the sweep
        engine, :func:`seactl.sweep`).

        Parameters
        ----------
        out : str or path
            Output directory.
        **options
            As :func:`seactl.sweep` for the kinds that have a sweep engine.

        Returns
        -------
        seactl.sweep.engine.SweepResult
            Where the data went, counts, timing.

        Raises
        ------
        InputError
            For a kind without a sweep engine (the rigid actuator: use
            :func:`seactl.latency_map`).
        """
        raise self.unsupported("sweep", "a kind with a sweep engine (the SEA); for this "
                               "one, seactl.latency_map maps the margins over its delays")
