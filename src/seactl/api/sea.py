"""The SEA design batch of the public API: :func:`design` and :class:`Design`.

A :class:`Design` is a thin view of :class:`seactl.systems.sea.loops.SEADesign` (actuator, gains,
timing, broadcast as a batch) that remembers how it was designed (``fn_hz``, ``gs``, ...)
and exposes every analysis as a method.  Nothing is modelled here: margins, impedance,
responses and exports all come from the one block diagram of :mod:`seactl.systems.sea.loops`.

Units are in the keyword names: ``delays_ms`` in milliseconds, ``filters_hz`` and
``fn_hz`` in hertz, ``t_end_s`` in seconds.  Values outside the range a unit makes
plausible are refused (a delay above 1000 ms) or warned about (a non-zero delay below
1 microsecond, which is what seconds passed as milliseconds look like).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from seactl.api.arguments import check_batch, delays_by_loop, filter_cutoffs, resolve_actuator
from seactl.api.results import RootsResult
from seactl.api.system import System
from seactl.base.validate import finite_array
from seactl.errors import InputError
from seactl.systems.sea.loops import Gains, SEADesign, Timing

SEA_LOOPS = ("torque", "stiffness", "damping")
"""The SEA's delayed loops, the keys of its ``delays_ms``."""


@dataclass(frozen=True, eq=False)
class Design(System):
    """A batch of critically-damped SEA designs, with every analysis as a method.

    Build it with :func:`design`.  All arrays share the batch ``shape`` (numpy
    broadcasting of ``fn_hz``, ``gs`` and the delays); ``d[i]`` selects designs.  The
    views are those of :class:`seactl.System`; the SEA adds the keyword ``zero`` (torque
    derivative on the whole error, the default, or on feedback only) to the simulated and
    exported views, and ``model``, ``load``, ``units`` to :meth:`impedance`.

    Parameters
    ----------
    sea : seactl.systems.sea.loops.SEADesign
        The underlying batch (actuator, gains, timing) the block diagram evaluates.
    fn_hz, gs : numpy.ndarray
        Natural frequency [Hz] and gain scale the gains were designed for.

    Attributes
    ----------
    actuator : seactl.systems.sea.actuators.SEAParams
        The actuator.
    gains : seactl.systems.sea.loops.Gains
        ``Kq`` [N m/rad], ``Bq`` [N m s/rad], ``Ktau`` [A/(N m)], ``Btau`` [A s/(N m)].
    timing : seactl.systems.sea.loops.Timing
        Delays [s] and filter cut-offs [Hz].
    shape : tuple of int
        The batch shape.

    Examples
    --------
    >>> import seactl as sc
    >>> d = sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...               filters_hz=(50, 100))
    >>> d.shape, round(float(d[1].gains.Kq), 2), isinstance(d, sc.System)
    ((2,), 83.17, True)
    """

    sea: SEADesign
    fn_hz: np.ndarray
    gs: np.ndarray

    kind: ClassVar[str] = "sea"
    loops: ClassVar[tuple[str, ...]] = SEA_LOOPS
    step_unit: ClassVar[str] = "rad"
    default_step: ClassVar[float] = 0.01
    impulse_unit: ClassVar[str] = "N m s"
    default_impulse: ClassVar[float] = 0.05
    default_t_end_s: ClassVar[dict[str, float]] = {"step": 0.5, "impulse": 1.0}
    reference: ClassVar[str] = "q_des"
    disturbance: ClassVar[str] = "tau_ext"
    output: ClassVar[str] = "q_j"
    actuation: ClassVar[str] = "i_m"
    sensor: ClassVar[str] = "q_sens"
    ports: ClassVar[tuple[str, ...]] = ("joint",)
    export_step: ClassVar[float] = 0.1
    renamed: ClassVar[dict[str, Any]] = {"run": {"step_rad": ("amplitude", None)},
                                         "impulse": {"impulse_nms": ("amplitude", None)}}

    # ------------------------------------------------------------ structure
    @property
    def actuator(self) -> Any:
        """The actuator (:class:`~seactl.systems.sea.actuators.SEAParams`)."""
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

    @property
    def design(self) -> SEADesign:
        """The design batch the diagram's blocks read (:attr:`sea`)."""
        return self.sea

    @property
    def diagram(self) -> Any:
        """The SEA's block diagram (:data:`seactl.systems.sea.loops.SEA_DIAGRAM`)."""
        from seactl.systems.sea.loops import SEA_DIAGRAM

        return SEA_DIAGRAM

    def diagram_for(self, zero: bool = True, **options: Any) -> Any:
        """The diagram with the torque derivative on the whole error (``zero``, default) or on
        feedback only.

        Parameters
        ----------
        zero : bool
            Torque derivative on the whole error (default) or on feedback only.
        **options
            Other kind-specific keywords (none).

        Returns
        -------
        seactl.diagram.blockdiagram.BlockDiagram
            The SEA's diagram.
        """
        from seactl.systems.sea.loops import sea_diagram

        super().diagram_for(**options)
        return sea_diagram(bool(zero))

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        """Loop name -> delay [s]: ``torque`` (T_tau), ``stiffness`` (T_qs), ``damping`` (T_qd).
        """
        t = self.timing
        return {"torque": t.T_tau, "stiffness": t.T_qs, "damping": t.T_qd}

    @property
    def links(self) -> dict[str, str]:
        """Loop name -> delayed block of the diagram."""
        from seactl.latency.montecarlo import SEA_LINKS

        return SEA_LINKS

    @property
    def max_current_a(self) -> float:
        """The actuator's current limit [A]."""
        return float(self.actuator.max_current)

    @property
    def amperes_per_actuation(self) -> float:
        """The actuation signal is the motor current ``i_m`` [A]."""
        return 1.0

    def reference_frequency(self) -> np.ndarray:
        """The delay-free closed loop's natural frequency [rad/s] per design
        (:func:`seactl.systems.sea.views.sea_reference_frequency`).

        Returns
        -------
        numpy.ndarray
            Per design [rad/s].
        """
        from seactl.systems.sea.views import sea_reference_frequency

        return sea_reference_frequency(self.sea)

    def impulse_inertia(self) -> np.ndarray:
        """The joint inertia ``I_j`` [kg m^2] an impulse of external torque hits.

        Returns
        -------
        numpy.ndarray
            Per design, in the kind's rotary or linear unit.
        """
        return np.asarray(self.sea.Ij)

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
        ms = {k: np.round(np.asarray(v) * 1e3, 4).tolist() for k, v in self.delays_s.items()}
        t = self.timing
        return (f"Design(actuator={self.actuator.name!r}, shape={self.shape}, "
                f"fn_hz={np.asarray(self.fn_hz).tolist()}, gs={np.asarray(self.gs).tolist()}, "
                f"delays_ms={ms}, filters_hz=({_filter_repr(t.f_qd)}, "
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

    def label_columns(self, gains: bool = True) -> dict[str, Any]:
        """``fn_hz`` and ``gs``, and with ``gains`` the four gains (batch shape).

        Parameters
        ----------
        gains : bool
            Include the controller gains.

        Returns
        -------
        dict
            Column name -> array of the batch shape.
        """
        cols = {"fn_hz": self.fn_hz, "gs": self.gs}
        if gains:
            g = self.gains
            cols.update(Kq=g.Kq, Bq=g.Bq, Ktau=g.Ktau, Btau=g.Btau)
        return cols

    # ------------------------------------------------------------ the SEA's own views
    def impedance_response(self, f_hz: Any, port: str, *, model: str = "block-diagram",
                           load: bool = False, units: str = "rotary") -> Any:
        """The joint's impedance ``Z = tau_k / (-j 2 pi f q_j)`` (:meth:`impedance`).

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0.
        port : {"joint"}
            The SEA's one port.
        model : {"block-diagram", "paper"}
            The block diagram (default) or the paper's printed formula.
        load : bool
            Include the joint inertia and damping (``Z_l = Z + I_j s + b_j``).
        units : {"rotary", "linear"}
            N m s/rad (default) or N s/m.

        Returns
        -------
        seactl.systems.sea.impedance.ImpedanceResponse
            The response.

        Examples
        --------
        >>> import seactl as sc
        >>> z = sc.design(30).impedance([1e-3])
        >>> round(float(z.stiffness[0].real), 1)        # s Z -> K_q at low frequency
        293.6
        """
        from seactl.systems.sea.impedance import impedance

        return impedance(self.sea, f_hz, model=model, load=load, units=units)

    def passivity(self, f_range_hz: tuple[float, float] = (0.01, 1e4), *,
                  model: str = "block-diagram", load: bool = False) -> Any:
        """Whether the joint's impedance is passive (``Re Z >= 0``) over a frequency range,
        and the bands where it is not, as ``seactl impedance`` reports them
        (:func:`seactl.systems.sea.passivity.passivity`: a dense scan, exact band edges,
        and for the block diagram a proof of ``Re Z > 0`` between the scan's points).

        Parameters
        ----------
        f_range_hz : (float, float)
            The range [Hz]; nothing is claimed outside it.
        model : {"block-diagram", "paper"}
            As :meth:`impedance_response`.
        load : bool
            Include the joint inertia and damping.

        Returns
        -------
        seactl.systems.sea.passivity.Passivity
            ``passive`` and ``proven`` (batch shape), ``bands_hz`` (per design, ``(n, 2)``
            [Hz]).

        Examples
        --------
        >>> import seactl as sc
        >>> p = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
        ...               filters_hz=(50, 100)).passivity()
        >>> bool(p.passive), [round(float(x)) for x in p.bands_hz[()][0]]
        (False, [65, 136])
        """
        from seactl.systems.sea.passivity import passivity

        return passivity(self.sea, f_range_hz, model=model, load=load)

    def jitter_loops(self) -> tuple[Any, dict[str, str], Any]:
        """The split SEA diagram, its taps and the design batch.

        Returns
        -------
        tuple
            ``(diagram, taps, design)``, the taps of :data:`seactl.latency.jitter.SEA_TAPS`.
        """
        from seactl.latency.jitter import SEA_TAPS
        from seactl.latency.maps import sea_split_diagram

        return sea_split_diagram(), dict(SEA_TAPS), self.sea

    def jitter_core(self) -> Any:
        """Jitter margins of the outer, stiffness, damping and torque loops
        (:func:`seactl.latency.jitter.sea_jitter_margins`).

        Returns
        -------
        seactl.latency.jitter.JitterMargins
            Per loop, of the batch shape.
        """
        from seactl.latency.jitter import sea_jitter_margins

        return sea_jitter_margins(self.sea)

    @staticmethod
    def control_transfers(name: str) -> Any:
        """``"loop"``, ``"inner"``, ``"closed"``, ``"impedance"`` -> (transfer, divide by
        ``-s``) for :meth:`to_control`.

        Parameters
        ----------
        name : str
            The transfer's name.

        Returns
        -------
        tuple
            ``(transfer, divide_by_minus_s)``.
        """
        from seactl.api.control import sea_transfer

        return sea_transfer(name)

    def sweep(self, out: Any, **options: Any) -> Any:
        """The sweep engine (:func:`seactl.sweep`) over the given axes around this design:
        the axes not given keep this design's values.

        Parameters
        ----------
        out : str or path
            Output directory.
        **options
            As :func:`seactl.sweep`: axes (``fn_hz``, ``gs``, ``t_qs_ms``, ..., ``zeta1``,
            ...) and options (``workers``, ``sampling``, ...); the actuator is this
            design's.  ``fn_hz``, ``gs``, the three delays and the two filters default to
            this design's; ``zeta1``, ``zeta2``, ``ratio`` to 1.

        Returns
        -------
        seactl.sweep.engine.SweepResult
            Where the data went, counts, timing; read it with :func:`seactl.read_sweep`.

        Raises
        ------
        InputError
            A batch of several designs (sweep around one, ``d[i]``), or ``actuator``.

        Examples
        --------
        >>> import tempfile, seactl as sc
        >>> out = tempfile.mkdtemp() + "/s"
        >>> res = sc.design(14).sweep(out, fn_hz=[12, 14], workers=0)
        >>> [round(x, 2) for x in sc.read_sweep(out).column("phase_margin_deg").to_pylist()]
        [54.37, 55.51]
        """
        from seactl.api.sweeps import sweep

        if self.shape:
            raise InputError("design", f"a batch of shape {self.shape}", "a single design "
                             "(d[i]): its values are those of the axes not swept")
        if "actuator" in options:
            raise InputError("actuator", options["actuator"], "not given: a design's sweep "
                             "uses its own actuator")
        t = self.timing
        here = {"fn_hz": self.fn_hz, "gs": self.gs, "t_tau_ms": t.T_tau * 1e3,
                "t_qs_ms": t.T_qs * 1e3, "t_qd_ms": t.T_qd * 1e3,
                "f_qd_hz": np.inf if t.f_qd is None else t.f_qd,
                "f_taud_hz": np.inf if t.f_taud is None else t.f_taud}
        axes = {k: [float(v)] for k, v in here.items() if k not in options}
        return sweep(out, actuator=self.actuator, **axes, **options)


def _filter_repr(f: Any) -> Any:
    return None if f is None else np.asarray(f).tolist()


def design(fn_hz: Any, *, actuator: Any = "ut-sea", gs: Any = 1.0, zeta1: Any = 1.0,
           zeta2: Any = 1.0, ratio: Any = 1.0, delays_ms: Mapping[str, Any] | None = None,
           filters_hz: Sequence[Any] = (None, None), solution: int = 0) -> Design:
    """Critically-damped SEA designs for natural frequencies ``fn_hz``.

    The four gains come from the closed-form solution of the critically-damped
    equations (:func:`seactl.systems.sea.design.critically_damped_gains`), then the gain scale
    ``gs`` multiplies the torque gains and divides the impedance gains.

    Parameters
    ----------
    fn_hz : array_like
        Natural frequency ``f_n`` [Hz] of the target closed loop.
    actuator : str or path or SEAParams
        Preset name (``"ut-sea"``), TOML file, or an
        :class:`~seactl.systems.sea.actuators.SEAParams`.
    gs : array_like
        Gain scale GS (broadcast with ``fn_hz``; use ``np.array(fn)[:, None]`` and a row of
        ``gs`` for a grid).
    zeta1, zeta2 : float
        Damping ratios of the two target pole pairs.
    ratio : float
        ``w2 / w1`` of the two pole pairs.
    delays_ms : dict, optional
        Loop name -> delay [ms] in [0, 1000] (array_like): ``"torque"`` (torque feedback,
        ``T_tau``), ``"stiffness"`` (``T_qs``), ``"damping"`` (``T_qd``); a loop not named
        has no delay.  The positional tuple ``(T_tau, T_qs, T_qd)`` is deprecated.
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
    >>> d = sc.design([12, 14, 16], gs=1.0, filters_hz=(50, 100),
    ...               delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5})
    >>> d.margins().phase_margin_deg.round(2)
    array([45.13, 43.26, 40.03])
    >>> d.gains.Kq.round(2)
    array([ 65.17,  83.17, 102.9 ])
    """
    from seactl.systems.sea.actuators import SEAParams, load_sea
    from seactl.systems.sea.design import critically_damped_gains

    act = resolve_actuator(actuator, load_sea, SEAParams)
    fn = finite_array("fn_hz [Hz]", fn_hz, minimum=0.0, strict=True, nonempty=True)
    g = finite_array("gs", gs, minimum=0.0, strict=True, nonempty=True)
    t_tau, t_qs, t_qd = delays_by_loop(delays_ms, SEA_LOOPS, ("T_tau", "T_qs", "T_qd"))
    f_qd, f_taud = filter_cutoffs(filters_hz, ("f_qd", "f_taud"))
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
    system : System
        From :func:`seactl.design`, :func:`seactl.rigid` or :func:`seactl.load_loop`.
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
    >>> r = sc.rightmost_roots(sc.rigid(12, delays_ms={"stiffness": 1, "damping": 15}),
    ...                        count=1)
    >>> bool(r.spectral_abscissa > 0)            # 15 ms on the damping loop: unstable
    True
    """
    if not callable(getattr(system, "roots", None)):
        raise InputError("system", type(system).__name__, "a design batch from sc.design or "
                         "sc.rigid")
    return system.roots(count=count)
