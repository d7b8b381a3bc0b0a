"""The rigid actuator as a seactl.System: :class:`RigidBatch` and :func:`rigid`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from seactl.api.arguments import check_batch, delays_by_loop, resolve_actuator
from seactl.api.system import System
from seactl.base.validate import finite_array
from seactl.errors import InputError

# ------------------------------------------------------------------ rigid actuator
RIGID_LOOPS = ("stiffness", "damping")
"""The rigid actuator's delayed loops, the keys of its ``delays_ms``."""


def _saturate_to_limit(saturate: bool) -> float | None:
    """The deprecated ``saturate=`` flag as ``saturation_a``: the actuator's limit, or
    none."""
    return None if saturate else math.inf


@dataclass(frozen=True, eq=False)
class RigidBatch(System):
    """A batch of critically-damped rigid-actuator designs (build with :func:`rigid`).

    The views are those of :class:`seactl.System`; the rigid actuator adds
    :meth:`delay_margins` and its force limit :attr:`max_force_n` (``beta`` times the
    current limit ``saturation_a``).

    Parameters
    ----------
    rigid : seactl.systems.rigid.model.RigidDesign
        The underlying batch (actuator, gains ``K`` [N/m], ``B`` [N s/m], delays [s]).
    fn_hz : numpy.ndarray
        Natural frequencies [Hz] the gains were designed for.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid([8, 12], delays_ms={"stiffness": 15, "damping": 1})
    >>> r.shape, r.margins().stable.tolist(), isinstance(r, sc.System)
    ((2,), [True, True], True)
    """

    rigid: Any
    fn_hz: np.ndarray

    kind: ClassVar[str] = "rigid"
    loops: ClassVar[tuple[str, ...]] = RIGID_LOOPS
    step_unit: ClassVar[str] = "m"
    default_step: ClassVar[float] = 0.004
    impulse_unit: ClassVar[str] = "N s"
    default_impulse: ClassVar[float] = 10.0
    default_t_end_s: ClassVar[dict[str, float]] = {"step": 1.0, "impulse": 1.0}
    reference: ClassVar[str] = "x_des"
    disturbance: ClassVar[str] = "F_ext"
    output: ClassVar[str] = "x"
    actuation: ClassVar[str] = "F_des"
    sensor: ClassVar[str] = "x_sens"
    ports: ClassVar[tuple[str, ...]] = ("output",)
    export_step: ClassVar[float] = 0.004
    renamed: ClassVar[dict[str, Any]] = {
        "step": {"saturate": ("saturation_a", _saturate_to_limit)},
        "export": {"saturate": ("saturation_a", _saturate_to_limit)},
        "run": {"step_m": ("amplitude", None),
                "saturate": ("saturation_a", _saturate_to_limit)}}

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        return self.rigid.shape

    @property
    def design(self) -> Any:
        """The design batch the diagram's blocks read (:attr:`rigid`)."""
        return self.rigid

    @property
    def diagram(self) -> Any:
        """The rigid actuator's block diagram (:data:`seactl.systems.rigid.model.RIGID_DIAGRAM`)."""
        from seactl.systems.rigid.model import RIGID_DIAGRAM

        return RIGID_DIAGRAM

    @property
    def actuator(self) -> Any:
        """The actuator (:class:`~seactl.systems.rigid.model.RigidParams`)."""
        return self.rigid.actuator

    @property
    def gains(self) -> Any:
        """``K`` [N/m] and ``B`` [N s/m], broadcast to the batch shape."""
        from seactl.systems.rigid.model import RigidGains

        return RigidGains(*(np.broadcast_to(x, self.shape) for x in (self.rigid.K,
                                                                     self.rigid.B)))

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        """Loop name -> delay [s]: ``stiffness`` (T_s), ``damping`` (T_d).
        """
        return {"stiffness": self.rigid.T_s, "damping": self.rigid.T_d}

    @property
    def links(self) -> dict[str, str]:
        """Loop name -> delayed block of the diagram."""
        from seactl.latency.montecarlo import MODEL_LINKS

        return MODEL_LINKS["rigid"]

    @property
    def max_current_a(self) -> float:
        """The actuator's current limit [A]."""
        return float(self.actuator.max_current)

    @property
    def max_force_n(self) -> float:
        """The actuator's force limit [N], ``beta * max_current``."""
        return float(self.actuator.max_force)

    @property
    def amperes_per_actuation(self) -> float:
        """The actuation signal is the force command: ``beta`` [N/A] per ampere."""
        return float(self.actuator.beta)

    def reference_frequency(self) -> np.ndarray:
        """The delay-free natural frequency ``sqrt(K/m)`` [rad/s] per design.

        Returns
        -------
        numpy.ndarray
            Per design [rad/s].
        """
        return self.rigid.wn

    def impulse_inertia(self) -> np.ndarray:
        """The mass ``m`` [kg] an impulse of external force hits.

        Returns
        -------
        numpy.ndarray
            Per design, in the kind's rotary or linear unit.
        """
        return np.asarray(self.rigid.m)

    def __getitem__(self, idx: Any) -> RigidBatch:
        from dataclasses import replace

        from seactl.systems.rigid.model import RigidGains

        shape = self.shape

        def pick(x: Any) -> Any:
            return None if x is None else np.broadcast_to(np.asarray(x, float), shape)[idx]

        if np.size(pick(self.fn_hz)) == 0:
            raise InputError("index", idx, "a selection of at least one design")
        g = self.rigid.gains
        sub = replace(self.rigid, gains=RigidGains(pick(g.K), pick(g.B)),
                      T_s=pick(self.rigid.T_s), T_d=pick(self.rigid.T_d),
                      f_v=pick(self.rigid.f_v))
        return RigidBatch(sub, pick(self.fn_hz))

    def label_columns(self, gains: bool = True) -> dict[str, Any]:
        """``fn_hz``, and with ``gains`` ``K`` and ``B`` (batch shape).

        Parameters
        ----------
        gains : bool
            Include the controller gains.

        Returns
        -------
        dict
            Column name -> array of the batch shape.
        """
        r = self.rigid
        return {"fn_hz": self.fn_hz, "K": r.K, "B": r.B} if gains else {"fn_hz": self.fn_hz}

    def labels(self) -> list[str]:
        """One legend label per design (flattened batch).

        Returns
        -------
        list of str
            ``"f_n=8 Hz, T_s=1.5 ms, T_d=1.5 ms"`` style labels.

        Examples
        --------
        >>> import seactl as sc
        >>> sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).labels()
        ['f_n=8 Hz, T_s=1.5 ms, T_d=1.5 ms']
        """
        r = self.rigid
        cols = [np.ravel(np.broadcast_to(x, self.shape)) for x in (self.fn_hz, r.T_s, r.T_d)]
        return [f"f_n={f:g} Hz, T_s={ts * 1e3:g} ms, T_d={td * 1e3:g} ms"
                for f, ts, td in zip(*cols)]

    # ------------------------------------------------------------ the rigid actuator's own
    def delay_margins(self) -> Any:
        """Extra latency the stiffness loop alone, the damping loop alone, and both tolerate.

        Returns
        -------
        seactl.latency.maps.LoopDelayMargins
            ``stiffness_s``, ``damping_s``, ``overall_s`` [s] and their ``ratio``.

        Examples
        --------
        >>> import seactl as sc
        >>> dm = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).delay_margins()
        >>> round(float(dm.stiffness_s) * 1e3, 2), round(float(dm.damping_s) * 1e3, 2)
        (55.47, 9.55)
        """
        from seactl.latency.maps import rigid_model

        model = rigid_model(self.rigid.actuator)
        return model.delay_margins(self.rigid)

    def impedance_response(self, f_hz: Any, port: str) -> Any:
        """``Z(j 2 pi f) = F_ext / (j 2 pi f x)`` [N s/m] felt at the output: the inverse of the
        closed-loop compliance ``x / F_ext`` (:data:`seactl.systems.rigid.model.RIGID_DIAGRAM`,
        exact
        delays) divided by ``s``; it includes the mass (:meth:`impedance`).

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0.
        port : {"output"}
            The rigid actuator's one port.

        Returns
        -------
        seactl.systems.sea.impedance.ImpedanceResponse
            The impedance [N s/m].
        """
        from seactl.systems.rigid.model import rigid_compliance
        from seactl.systems.sea.impedance import ImpedanceResponse

        f = finite_array("f_hz [Hz]", f_hz, minimum=0.0, strict=True).reshape(-1)
        s = 2j * np.pi * f
        z = 1.0 / (s * rigid_compliance()(self.rigid, s))
        return ImpedanceResponse("block-diagram", f, z, "linear", True)

    def jitter_loops(self) -> tuple[Any, dict[str, str], Any]:
        """The rigid loop model's diagram, its taps and the design batch.

        Returns
        -------
        tuple
            ``(diagram, taps, design)``, taps for the whole loop, stiffness and damping.
        """
        from seactl.latency.maps import rigid_model

        m = rigid_model(self.rigid.actuator)
        return m.diagram, {"overall": m.sensor, "stiffness": m.stiffness_tap,
                           "damping": m.damping_tap}, self.rigid

    def jitter_core(self) -> Any:
        """Jitter margins of the whole loop and the stiffness and damping loops
        (:func:`seactl.latency.jitter.model_jitter_margins` of the rigid loop model).

        Returns
        -------
        seactl.latency.jitter.JitterMargins
            Per loop, of the batch shape.
        """
        from seactl.latency.jitter import model_jitter_margins
        from seactl.latency.maps import rigid_model

        return model_jitter_margins(rigid_model(self.rigid.actuator), self.rigid)

    @staticmethod
    def control_transfers(name: str) -> Any:
        """``"loop"``, ``"closed"``, ``"compliance"`` -> (transfer, divide by ``-s``) for
        :meth:`to_control`.

        Parameters
        ----------
        name : str
            The transfer's name.

        Returns
        -------
        tuple
            ``(transfer, divide_by_minus_s)``.
        """
        from seactl.api.control import rigid_transfer

        return rigid_transfer(name)


def rigid(fn_hz: Any, *, actuator: Any = "ut-linear", delays_ms: Mapping[str, Any] | None = None,
          velocity_filter_hz: float | None = 50.0, passive_damping: bool = True) -> RigidBatch:
    """Critically-damped rigid-actuator designs ``K = m w_n^2``, ``B = 2 m w_n - b``.

    Parameters
    ----------
    fn_hz : array_like
        Natural frequency [Hz].
    actuator : str or path or RigidParams
        Preset (``"ut-linear"``), TOML file or :class:`~seactl.systems.rigid.model.RigidParams`.
    delays_ms : dict, optional
        Loop name -> delay [ms] (array_like): ``"stiffness"`` (``T_s``), ``"damping"``
        (``T_d``); a loop not named has no delay.  The positional ``(T_s, T_d)`` is
        deprecated.
    velocity_filter_hz : float or None
        Cut-off of the first-order velocity filter [Hz]; None: no filter.
    passive_damping : bool
        Subtract the actuator's own damping ``b`` from ``B``.

    Returns
    -------
    RigidBatch
        The batch, of the broadcast shape of ``fn_hz`` and the delays.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid(12, delays_ms={"stiffness": 1, "damping": 15})
    >>> bool(r.margins().stable)                # 15 ms on the damping loop: unstable
    False
    >>> bool(sc.rigid(12, delays_ms={"stiffness": 15, "damping": 1}).margins().stable)
    True
    """
    from seactl.systems.rigid.model import RigidDesign, RigidParams, load_rigid

    act = resolve_actuator(actuator, load_rigid, RigidParams)
    fn = finite_array("fn_hz [Hz]", fn_hz, minimum=0.0, strict=True, nonempty=True)
    t_s, t_d = delays_by_loop(delays_ms, RIGID_LOOPS, ("T_s", "T_d"))
    check_batch(fn_hz=fn, delays_ms=(np.asarray(t_s) * 1e3, np.asarray(t_d) * 1e3))
    d = RigidDesign.from_fn(act, fn, T_s=t_s, T_d=t_d, f_v=velocity_filter_hz,
                            passive_damping=passive_damping)
    if 0 in d.shape:
        raise InputError("fn_hz, delays_ms, velocity_filter_hz", f"a batch of shape "
                         f"{d.shape}", "arrays with at least one value")
    return RigidBatch(d, np.broadcast_to(fn, d.shape))
