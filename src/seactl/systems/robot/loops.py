"""The linearized multi-joint SEA loop, written once as a block diagram.

Per joint ``j`` (signals suffixed ``.jN``, blocks ``_jN``) the blocks of the SEA's loop
(:mod:`seactl.systems.sea.loops`): the torque loop and the damping loop on the joint's
embedded process, the motor and the spring.  The joint's load is the robot's rigid body,
linearized at ``q0`` with gravity compensated (docs/theory/robot.md)::

    p.j      = tau_net.j / s              (the generalized momentum M(q0) qd)
    vel.j   += Minv_jk p.k                (the inverse mass matrix as constant gains)
    q_j      = vel.j / s
    tau_net.j = tau_k.j + tau_ext.j - b_j vel.j

(the momentum is integrated before the mass matrix is inverted, so an external torque
reaches every other signal through an integrator: no direct feed-through)

The stiffness acts on the central process with one latency ``T_qs``:
``tau_fb.j -= sum_k K_jk e^{-s T_qs} qs.k`` (``K`` diagonal in joint space, ``J^T K_x J``
in task space), ``tau_ref.j = sum_k K_jk q_des.k``.  The joint's sensor ``q_sens.j`` feeds
the stiffness through ``qs.j`` and the damping through ``qd.j``, so each loop can be
broken alone: ``q_sens.jN`` (the SEA's outer loop), ``qs.jN`` (stiffness),
``qd.jN`` (damping), ``tau_sens.jN`` (torque).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import Block, DesignBatch
from seactl.diagram.mason import CycleDiagram
from seactl.errors import InputError

MASON_JOINTS = 3
"""The most joints whose diagram's transfers come from its cycles (their number grows too
fast beyond: :class:`LargeRobotDiagram`)."""
LARGE_VIEWS = ("margins() (its verdict), mimo_margins(), delay_margin(), "
               "stability_chart(), placement(), step(), impulse(), mujoco_check(), "
               "margins(rate_hz=...)")
"""The views of a robot with more joints (from :mod:`seactl.systems.robot.characteristic`)."""

BREAKS = {"outer": "q_sens", "stiffness": "qs", "damping": "qd", "torque": "tau_sens"}
"""Loop -> the signal (per joint) where it is broken."""


def joint_tag(j: int) -> str:
    """The suffix of joint ``j`` (0-based) in signal names: ``.j1``, ``.j2``, ..."""
    return f".j{j + 1}"


def block_tag(j: int) -> str:
    """The suffix of joint ``j`` in block and design-field names (identifiers): ``_j1``."""
    return f"_j{j + 1}"


def _field(name: str, j: int):
    key = name + block_tag(j)
    return lambda p: getattr(p, key)


def _joint_blocks(j: int) -> list[Block]:
    """Joint ``j``'s SEA blocks except the stiffness and the load (as the SEA's loop)."""
    t, b, ctrl, plant = joint_tag(j), block_tag(j), "controller", "plant"

    def f(name):
        return _field(name, j)

    return [
        Block("ref_sum" + b, "tau_ref" + t, "tau_des" + t, role=ctrl),
        Block("q_sensor" + b, "q_j" + t, "q_sens" + t, role="sensor"),
        Block("qs_tap" + b, "q_sens" + t, "qs" + t, role=ctrl),
        Block("qd_tap" + b, "q_sens" + t, "qd" + t, role=ctrl),
        Block("Bq_fb" + b, "qd" + t, "tau_fb" + t, num=lambda p: (-f("Bq")(p), 0.0),
              den=lambda p: (f("Tf_qd")(p), 1.0), delay="T_qd" + b, role=ctrl,
              process="embedded" + t),
        Block("fb_sum" + b, "tau_fb" + t, "tau_des" + t, role=ctrl),
        Block("tau_sensor" + b, "tau_k" + t, "tau_sens" + t, role="sensor"),
        Block("tau_delay" + b, "tau_sens" + t, "tau_meas" + t, delay="T_tau" + b, role=ctrl,
              process="embedded" + t),
        Block("ff" + b, "tau_des" + t, "i_m" + t, num=lambda p: (1.0 / f("beta")(p),),
              role=ctrl, process="embedded" + t),
        Block("ep_des" + b, "tau_des" + t, "e_p" + t, role=ctrl),
        Block("ep_fb" + b, "tau_meas" + t, "e_p" + t, num=lambda p: (-1.0,), role=ctrl),
        Block("ed_des" + b, "tau_des" + t, "e_d" + t, role=ctrl),
        Block("ed_tau" + b, "tau_meas" + t, "e_d" + t, num=lambda p: (-1.0,), role=ctrl),
        Block("Ktau" + b, "e_p" + t, "i_m" + t, num=lambda p: (f("Ktau")(p),), role=ctrl,
              process="embedded" + t),
        Block("Btau" + b, "e_d" + t, "i_m" + t, num=lambda p: (f("Btau")(p), 0.0),
              den=lambda p: (f("Tf_taud")(p), 1.0), role=ctrl, process="embedded" + t),
        Block("beta" + b, "i_m" + t, "tau_m" + t, num=lambda p: (f("beta")(p),), role=plant),
        Block("motor_drive" + b, "tau_m" + t, "tau_net_m" + t, role=plant),
        Block("spring_reaction" + b, "tau_k" + t, "tau_net_m" + t, num=lambda p: (-1.0,),
              role=plant),
        Block("motor" + b, "tau_net_m" + t, "q_m" + t,
              den=lambda p: (f("Im")(p), f("bm")(p), 0.0), role=plant),
        Block("spring_m" + b, "q_m" + t, "tau_k" + t, num=lambda p: (f("k")(p),), role=plant),
        Block("spring_j" + b, "q_j" + t, "tau_k" + t, num=lambda p: (-f("k")(p),),
              role=plant),
        Block("spring_load" + b, "tau_k" + t, "tau_net" + t, role=plant),
        Block("ext_load" + b, "tau_ext" + t, "tau_net" + t, role=plant),
        Block("joint_damping" + b, "vel" + t, "tau_net" + t, num=lambda p: (-f("bj")(p),),
              role=plant),
        Block("momentum" + b, "tau_net" + t, "p" + t, den=lambda p: (1.0, 0.0),
              role=plant),
        Block("integrate_vel" + b, "vel" + t, "q_j" + t, den=lambda p: (1.0, 0.0),
              role=plant),
    ]


def _pair_blocks(j: int, k: int, coupled: bool) -> list[Block]:
    """The gains from joint ``k`` to joint ``j``: ``Minv_jk`` (the rigid body: momentum to
    velocity), and the
    stiffness ``K_jk`` (reference and feedback on the central process), where
    ``coupled`` (the off-diagonal ones of a task-space stiffness)."""
    tj, tk, jk = joint_tag(j), joint_tag(k), f"{block_tag(j)}{block_tag(k)[1:]}"
    out = [Block("Minv" + jk, "p" + tk, "vel" + tj,
                 num=lambda p, n="Minv" + jk: (getattr(p, n),),
                 role="plant")]
    if j == k or coupled:
        out += [
            Block("Kq_ref" + jk, "q_des" + tk, "tau_ref" + tj,
                  num=lambda p, n="K" + jk: (getattr(p, n),), role="controller"),
            Block("Kq_fb" + jk, "qs" + tk, "tau_fb" + tj,
                  num=lambda p, n="K" + jk: (-getattr(p, n),), delay="T_qs",
                  role="controller", process="high-level"),
        ]
    return out


@dataclass(frozen=True)
class LargeRobotDiagram(CycleDiagram):
    """The diagram of a robot of more than :data:`MASON_JOINTS` joints: its blocks and
    their numeric responses (the loop matrix) serve; a transfer or characteristic derived
    from its cycles is refused (too many), naming the views that work."""

    def _refuse(self, *_: Any, **__: Any) -> Any:
        n = sum(1 for b in self.blocks if b.name.startswith("momentum_"))
        raise InputError("joints", f"{n} moving joints",
                         f"at most {MASON_JOINTS} for this view (it needs the loop's transfers, "
                         f"from its diagram's cycles); with more: {LARGE_VIEWS}")

    characteristic = return_difference = transfer_forms = _refuse


@lru_cache(maxsize=16)
def robot_diagram(n: int, coupled: bool) -> CycleDiagram:
    """The diagram of an ``n``-joint robot; ``coupled``: a full stiffness matrix (task
    space), else a diagonal one (joint space)."""
    blocks: list[Block] = []
    for j in range(n):
        blocks += _joint_blocks(j)
    for j in range(n):
        for k in range(n):
            blocks += _pair_blocks(j, k, coupled)
    cls = CycleDiagram if n <= MASON_JOINTS else LargeRobotDiagram
    return cls(f"robot-{n}{'-task' if coupled else ''}", blocks)


@dataclass(frozen=True, eq=False)
class RobotDesign(DesignBatch):
    """The numbers the robot diagram's blocks read: per joint ``j`` the actuator
    (``Im_jN``, ``bm_jN``, ``k_jN``, ``beta_jN``), the load damping ``bj_jN``, the gains
    (``Bq_jN``, ``Ktau_jN``, ``Btau_jN``), delays ``T_tau_jN``, ``T_qd_jN`` [s] and filter
    time constants; per pair the inverse mass matrix ``Minv_jNkM`` and the stiffness
    ``K_jNkM``; the central process's delay ``T_qs`` [s]."""

    values: tuple[tuple[str, Any], ...]

    def _fields(self) -> dict[str, object]:
        return dict(self.values)


def robot_design(minv: np.ndarray, stiffness: np.ndarray, joints: list[dict[str, float]],
                 t_qs_s: float) -> RobotDesign:
    """The design of the diagram from the inverse mass matrix ``minv``, the stiffness
    matrix [N m/rad] and per joint a dict of the fields above (without suffix)."""
    n = len(joints)
    values: dict[str, Any] = {"T_qs": float(t_qs_s)}
    for j, fields_ in enumerate(joints):
        for name, v in fields_.items():
            values[name + block_tag(j)] = float(v)
        for k in range(n):
            jk = f"{block_tag(j)}{block_tag(k)[1:]}"
            values["Minv" + jk] = float(minv[j, k])
            values["K" + jk] = float(stiffness[j, k])
    return RobotDesign(tuple(values.items()))
