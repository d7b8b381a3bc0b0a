"""The SEA cascaded impedance/torque loop, written once as a block diagram.

Signals (rotary joint space, SI): ``q_des`` reference, ``tau_ext`` external
torque on the joint, ``q_j``/``q_m`` joint and motor angles, ``tau_k`` spring
torque, ``i_m`` motor current, ``tau_des`` desired torque (= ``tau_ref`` +
``tau_fb``), ``e_p``/``e_d`` torque errors seen by the P and D terms, and the
sensor signals ``q_sens``/``tau_sens`` where the outer and inner loops are
broken for margins.

The physics are primitives (motor, spring, load) rather than the paper's
lumped ``P_F``, so that the same diagram also yields the impedance (joint
motion imposed) and disturbance responses.  Tests check that the derived
``tau_k/i_m`` equals the paper's ``P_F`` and that ``P_CL`` equals its printed
coefficient form.

Controller (paper Fig. ControlBlock)::

    tau_des = Kq (q_des - e^{-T_qs s} q_j) - Bq e^{-T_qd s} Q_qd s q_j
    i_m     = tau_des / beta + Ktau e_p + Btau Q_taud s e_d
    e_p     = tau_des - e^{-T_tau s} tau_k
    e_d     = tau_des - e^{-T_tau s} tau_k  (derivative on the whole error: P_CL has the zero)
    e_d     = tau_fb - e^{-T_tau s} tau_k  (``zero=False``: derivative not on the reference)
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from seactl.base.validate import finite_array
from seactl.diagram.blockdiagram import Block, BlockDiagram, DesignBatch, Transfer
from seactl.errors import InputError
from seactl.systems.sea.actuators import SEAParams


def filter_time_constant(f_hz, name: str = "filter cut-off [Hz]") -> np.ndarray:
    """First-order filter time constant 1/(2 pi f_c) [s]; no filter (None/inf) -> 0."""
    if f_hz is None:
        return np.asarray(0.0)
    f = finite_array(name, f_hz, minimum=0.0, strict=True, allow_inf=True)
    with np.errstate(over="ignore"):
        tc = 1.0 / (2 * np.pi * f)
    if not np.all(np.isfinite(tc)):
        raise InputError(name, float(f[~np.isfinite(tc)].flat[0]) if f.ndim else float(f),
                         "a cut-off whose time constant 1/(2 pi f) is a finite number")
    return tc


@dataclass(frozen=True)
class Gains:
    """Controller gains, rotary SI units (arrays broadcast as a batch).

    Attributes
    ----------
    Kq : stiffness gain [N m/rad];  Bq : damping gain [N m s/rad];
    Ktau : torque P gain [A/(N m)];  Btau : torque D gain [A s/(N m)].
    """

    Kq: np.ndarray
    Bq: np.ndarray
    Ktau: np.ndarray
    Btau: np.ndarray

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, finite_array(f.name, getattr(self, f.name),
                                                           minimum=0.0))

    def scaled(self, gs) -> Gains:
        """Apply the gain scale GS (Definition 1): torque gains x GS, impedance gains / GS."""
        gs = finite_array("gs", gs, minimum=0.0, strict=True)
        return Gains(self.Kq / gs, self.Bq / gs, self.Ktau * gs, self.Btau * gs)

    def __getitem__(self, idx) -> Gains:
        return Gains(*(np.broadcast_to(getattr(self, f.name), self.shape)[idx]
                       for f in fields(self)))

    @property
    def shape(self) -> tuple[int, ...]:
        return np.broadcast_shapes(*(np.shape(getattr(self, f.name)) for f in fields(self)))


MAX_DELAY_S = 1.0
"""Largest loop delay :class:`Timing` accepts [s] (larger values are unit slips)."""


@dataclass(frozen=True)
class Timing:
    """Loop latencies [s] and filter cut-offs [Hz] (``None``/inf: no filter).

    Delays are in **seconds** and at most :data:`MAX_DELAY_S`; a larger value (``2.0``
    meant as 2 ms) raises :class:`~seactl.errors.InputError`.  :meth:`from_ms` and
    :func:`seactl.design` take milliseconds.

    Attributes
    ----------
    T_tau : torque-feedback delay;  T_qs : stiffness-feedback delay;
    T_qd : damping-feedback delay;  f_qd : velocity filter cut-off;
    f_taud : torque-derivative filter cut-off.
    """

    T_tau: float | np.ndarray = 0.0
    T_qs: float | np.ndarray = 0.0
    T_qd: float | np.ndarray = 0.0
    f_qd: float | np.ndarray | None = None
    f_taud: float | np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("T_tau", "T_qs", "T_qd"):
            value = finite_array(name + " [s]", getattr(self, name), minimum=0.0)
            if np.any(value > MAX_DELAY_S):
                # Timing takes seconds: 2.0 here is two seconds, almost surely meant as 2 ms.
                raise InputError(name + " [s]", float(value[value > MAX_DELAY_S].flat[0]),
                                 f"<= {MAX_DELAY_S:g} s (Timing takes seconds; use "
                                 "Timing.from_ms or seactl.design(delays_ms=...) for ms)")
            object.__setattr__(self, name, value)
        for name in ("f_qd", "f_taud"):
            val = getattr(self, name)
            if val is not None:
                object.__setattr__(self, name, finite_array(name, val, minimum=0.0, strict=True,
                                                            allow_inf=True))

    @classmethod
    def from_ms(cls, t_tau_ms=0.0, t_qs_ms=0.0, t_qd_ms=0.0, f_qd_hz=None, f_taud_hz=None):
        """CLI units: delays in milliseconds, cut-offs in Hz."""
        for name, v in (("t_tau", t_tau_ms), ("t_qs", t_qs_ms), ("t_qd", t_qd_ms)):
            finite_array(name + " [ms]", v, minimum=0.0)
        return cls(np.asarray(t_tau_ms, float) / 1e3, np.asarray(t_qs_ms, float) / 1e3,
                   np.asarray(t_qd_ms, float) / 1e3, f_qd_hz, f_taud_hz)


@dataclass(frozen=True)
class SEADesign(DesignBatch):
    """A batch of SEA designs: actuator, gains and timing broadcast together.

    The attributes used by the block diagram are arrays of the common batch
    shape (``Im``, ``Ij``, ``bm``, ``bj``, ``k``, ``beta``, gains, delays and
    filter time constants ``Tf_qd``, ``Tf_taud`` [s]).
    """

    actuator: SEAParams
    gains: Gains
    timing: Timing = Timing()

    def _fields(self) -> dict[str, object]:
        a, g, t = self.actuator, self.gains, self.timing
        return dict(Im=a.Im, Ij=a.Ij, bm=a.bm, bj=a.bj, k=a.k, beta=a.beta,
                    Kq=g.Kq, Bq=g.Bq, Ktau=g.Ktau, Btau=g.Btau,
                    T_tau=t.T_tau, T_qs=t.T_qs, T_qd=t.T_qd,
                    Tf_qd=filter_time_constant(t.f_qd), Tf_taud=filter_time_constant(t.f_taud))

    def with_timing(self, timing: Timing) -> SEADesign:
        return replace(self, timing=timing)


def _sea_blocks(zero: bool = True) -> list[Block]:
    ctrl, plant = "controller", "plant"
    # The torque derivative acts on the whole error tau_des - tau_meas (P_CL has the zero),
    # or only on its feedback part tau_fb - tau_meas (no zero; docs/theory/loop.md).
    derivative_input = Block("ed_des", "tau_des", "e_d", role=ctrl) if zero else \
        Block("ed_fb", "tau_fb", "e_d", role=ctrl)
    return [
        # outer impedance loop (stiffness on the high-level process, damping embedded)
        Block("Kq_ref", "q_des", "tau_ref", num=lambda p: (p.Kq,), role=ctrl),
        Block("ref_sum", "tau_ref", "tau_des", role=ctrl),
        Block("q_sensor", "q_j", "q_sens", role="sensor"),
        Block("Kq_fb", "q_sens", "tau_fb", num=lambda p: (-p.Kq,), delay="T_qs", role=ctrl,
              process="high-level"),
        Block("Bq_fb", "q_sens", "tau_fb", num=lambda p: (-p.Bq, 0.0),
              den=lambda p: (p.Tf_qd, 1.0), delay="T_qd", role=ctrl,
              process="embedded"),
        Block("fb_sum", "tau_fb", "tau_des", role=ctrl),
        # inner torque loop (the torque measurement reaches the embedded process after T_tau)
        Block("tau_sensor", "tau_k", "tau_sens", role="sensor"),
        Block("tau_delay", "tau_sens", "tau_meas", delay="T_tau", role=ctrl, process="embedded"),
        Block("ff", "tau_des", "i_m", num=lambda p: (1.0 / p.beta,), role=ctrl,
              process="embedded"),
        Block("ep_des", "tau_des", "e_p", role=ctrl),
        Block("ep_fb", "tau_meas", "e_p", num=lambda p: (-1.0,), role=ctrl),
        derivative_input,
        Block("ed_tau", "tau_meas", "e_d", num=lambda p: (-1.0,), role=ctrl),
        Block("Ktau", "e_p", "i_m", num=lambda p: (p.Ktau,), role=ctrl, process="embedded"),
        Block("Btau", "e_d", "i_m", num=lambda p: (p.Btau, 0.0),
              den=lambda p: (p.Tf_taud, 1.0), role=ctrl, process="embedded"),
        # physics: motor, spring, load
        Block("beta", "i_m", "tau_m", num=lambda p: (p.beta,), role=plant),
        Block("motor_drive", "tau_m", "tau_net_m", role=plant),
        Block("spring_reaction", "tau_k", "tau_net_m", num=lambda p: (-1.0,), role=plant),
        Block("motor", "tau_net_m", "q_m", den=lambda p: (p.Im, p.bm, 0.0), role=plant),
        Block("spring_m", "q_m", "tau_k", num=lambda p: (p.k,), role=plant),
        Block("spring_j", "q_j", "tau_k", num=lambda p: (-p.k,), role=plant),
        Block("spring_load", "tau_k", "tau_net_j", role=plant),
        Block("ext_load", "tau_ext", "tau_net_j", role=plant),
        Block("load", "tau_net_j", "q_j", den=lambda p: (p.Ij, p.bj, 0.0), role=plant),
    ]


SEA_DIAGRAM = BlockDiagram("sea", _sea_blocks(zero=True))
"""The SEA loop with the torque-derivative acting on the reference (P_CL has the zero)."""

SEA_DIAGRAM_NO_ZERO = BlockDiagram("sea-no-zero", _sea_blocks(zero=False))
"""Variant: the torque derivative acts on feedback only (no zero in P_CL)."""


def sea_diagram(zero: bool = True) -> BlockDiagram:
    return SEA_DIAGRAM if zero else SEA_DIAGRAM_NO_ZERO


# Views derived from the one diagram -------------------------------------------------------
def outer_loop() -> Transfer:
    """Outer impedance loop ``L = P_C P_L (B_q Q_qd s e^{-sT_qd} + K_q e^{-sT_qs})``
    with the inner torque loop closed (docs/theory/loop.md)."""
    return SEA_DIAGRAM.loop("q_sens")


def inner_loop() -> Transfer:
    """Inner torque loop ``P_F C e^{-s T_tau}`` with the outer loop open."""
    return SEA_DIAGRAM.loop("tau_sens", cut=("q_sens",))


def closed_loop(zero: bool = True) -> Transfer:
    """Closed loop ``P_CL = q_j / q_des``."""
    return sea_diagram(zero).transfer("q_j", "q_des")


def force_plant() -> Transfer:
    """``P_F = tau_k / i_m`` with both loops open (the paper's eq. PF)."""
    return SEA_DIAGRAM.transfer("tau_k", "i_m", cut=("i_m", "q_sens", "tau_sens"))


def torque_closed_loop() -> Transfer:
    """``P_C = tau_k / tau_des`` with the inner loop closed, outer loop open."""
    return SEA_DIAGRAM.transfer("tau_k", "tau_des", cut=("tau_des", "q_sens"))
