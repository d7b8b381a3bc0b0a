"""The continuous-time baseline of the base."""

from __future__ import annotations

import numpy as np

from seactl.systems.mobile_base.kinematics import body_jacobian, rotate, task_inertia
from seactl.systems.mobile_base.model import MobileBaseParams
from seactl.systems.mobile_base.simulation import hold_pose


# -------------------------------------------------------------------- continuous baseline
def continuous_rhs(p: MobileBaseParams, kx: float, dx: float, bq: float, reference=None):
    """Right-hand side ``f(t, y)`` of the same plant with a continuous, delay-free,
    sensor-perfect controller (no sampling, quantization or saturation): the baseline for
    ``scipy.integrate.solve_ivp``.  ``y`` = (X, V, PHI, QM, WM, X_hat), 18 states; the
    odometry ``X_hat`` integrates the motor rates, as the sampled odometry does.
    """
    Jb = body_jacobian(p)
    Jb_inv = np.linalg.inv(Jb)
    Lam = task_inertia(p)
    M_inv = 1.0 / np.diag(p.body_mass_matrix + p.wheel_spin_inertia * (Jb.T @ Jb))
    ref = reference or hold_pose
    Ir = p.reflected_rotor_inertia

    def f(t: float, y: np.ndarray) -> np.ndarray:
        X, V, PHI, QM, WM, Xh = y.reshape(6, 3)
        xd, vd, ad = (np.asarray(r)[0] for r in ref(np.array([t])))
        th = Xh[2]
        v_hat = rotate((WM @ Jb_inv.T)[None], th)[0]          # odometry from motor rates
        F = Lam @ (ad + kx * (xd - Xh) + dx * (vd - v_hat))
        qd_d = rotate(vd[None], -th)[0] @ Jb.T
        tau = rotate(F[None], -th)[0] @ Jb_inv + bq * (qd_d - WM)
        s, co = np.sin(X[2] + p.alpha), np.cos(X[2] + p.alpha)
        phid = (-s * V[0] + co * V[1] + p.wheel_distance * V[2]) / p.wheel_radius
        tk = p.stiffness * (QM - PHI) + p.compliance_damping * (WM - phid)
        dWM = (tau - tk - p.viscous_friction * WM
               - p.coulomb_friction * np.tanh(WM / p.friction_velocity)) / Ir
        tq = tk - p.wheel_spin_inertia * V[2] * (-co * V[0] - s * V[1]) / p.wheel_radius
        Fb = np.array([-(s * tq).sum(), (co * tq).sum(), p.wheel_distance * tq.sum()]) \
            / p.wheel_radius
        return np.concatenate([V, Fb * M_inv, phid, WM, dWM, v_hat])

    return f
