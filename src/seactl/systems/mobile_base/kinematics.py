"""The base's kinematics: wheel geometry and task-space inertia."""

from __future__ import annotations

import numpy as np

from seactl.systems.mobile_base.model import MobileBaseParams


# -------------------------------------------------------------------- kinematics
def body_jacobian(p: MobileBaseParams) -> np.ndarray:
    """``J_b`` (3, 3): wheel speeds [rad/s] from body-frame velocity (v_x, v_y, omega).

    Wheel ``i`` at angle ``alpha_i`` rolls along the tangent ``(-sin a_i, cos a_i)``, so its
    rim speed is ``-sin(a_i) v_x + cos(a_i) v_y + L omega``.
    """
    a = p.alpha
    return np.stack([-np.sin(a), np.cos(a), np.full(3, p.wheel_distance)], axis=-1) \
        / p.wheel_radius


def wheel_jacobian(p: MobileBaseParams, theta) -> np.ndarray:
    """``J(theta)`` (..., 3, 3): wheel speeds from world-frame velocity (xdot, ydot, thetadot).

    ``J(theta) = J_b R(theta)^T``; ``theta`` broadcasts over leading axes.
    """
    th = np.asarray(theta, float)[..., None] + p.alpha
    L = np.broadcast_to(p.wheel_distance, th.shape)
    return np.stack([-np.sin(th), np.cos(th), L], axis=-1) / p.wheel_radius


def wheel_speeds(p: MobileBaseParams, velocity, theta=0.0) -> np.ndarray:
    """Wheel angular speeds [rad/s] for a world-frame base velocity (..., 3)."""
    J = wheel_jacobian(p, theta)
    return np.einsum("...ij,...j->...i", J, np.asarray(velocity, float))


def rotate(v: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rotate the planar part of (..., 3) vectors by theta (yaw component unchanged)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1],
                     v[..., 2]], axis=-1)


def task_inertia(p: MobileBaseParams, theta=0.0) -> np.ndarray:
    """Operational space inertia ``Lambda = (J_t A^-1 J_t^T)^-1`` of the (x, y, yaw) task.

    Joint space = the three wheel angles; ``A = J^-T M_body J^-1 + (I_spin + N^2 I_rotor) 1``
    (rigid drivetrain) and the task Jacobian is ``J_t = J^-1``, hence
    ``Lambda = M_body + (I_spin + N^2 I_rotor) J^T J``.  Shape (..., 3, 3).
    """
    J = wheel_jacobian(p, theta)
    A_w = p.wheel_spin_inertia + p.reflected_rotor_inertia
    return p.body_mass_matrix + A_w * np.einsum("...ki,...kj->...ij", J, J)


def kinetic_energy(p: MobileBaseParams, pose_rate, wheel_rates, motor_rates, theta=0.0
                   ) -> np.ndarray:
    """Kinetic energy [J] of chassis, wheels (translation, yaw, spin) and rotors."""
    v = np.asarray(pose_rate, float)
    return (0.5 * np.einsum("...i,ij,...j->...", v, p.body_mass_matrix, v)
            + 0.5 * p.wheel_spin_inertia * np.sum(np.asarray(wheel_rates) ** 2, axis=-1)
            + 0.5 * p.reflected_rotor_inertia * np.sum(np.asarray(motor_rates) ** 2, axis=-1))


def damping_to_joint(p: MobileBaseParams, d_x) -> np.ndarray:
    """Joint damping ``B_q`` [N m s/rad] whose Cartesian equivalent is ``d_x`` [N s/(m kg)]."""
    G = body_jacobian(p).T @ body_jacobian(p)
    return np.asarray(d_x, float) * task_inertia(p)[0, 0] / G[0, 0]


def joint_to_damping(p: MobileBaseParams, b_q) -> np.ndarray:
    """Cartesian-equivalent damping [N s/(m kg)] of the joint damping ``b_q`` [N m s/rad]."""
    G = body_jacobian(p).T @ body_jacobian(p)
    return np.asarray(b_q, float) * G[0, 0] / task_inertia(p)[0, 0]
