"""Test oracle: a minimal sampled simulation of the rigid loop, written independently of
:mod:`seactl.simulate.engine` (exact ZOH discretization of the plant, explicit delay buffers)."""

import numpy as np
from scipy.signal import cont2discrete


def simulate_rigid_sampled(design, step_m: float, *, t_end_s: float = 1.0,
                           rate_hz: float = 1000.0, force_limit: float | None = None
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimal sampled simulation of the rigid loop, independent of :mod:`seactl.simulate.engine`.

    The plant ``1/(m s^2 + b s)`` is discretized exactly under a zero-order hold
    (:func:`scipy.signal.cont2discrete`).  Every tick ``k`` the position is sampled, the
    stiffness term reads it ``n_s`` ticks old and the damping term ``n_d`` ticks old
    (``n = round((T - T_s/2)/T_s)``, the effective-delay convention ``T = T_s/2 + n T_s``),
    the velocity filter ``B s/(T_f s + 1)`` is the Tustin transform, and the force
    ``K (x_des - x[k-n_s]) - B v[k]`` is clipped to ``force_limit`` and held for one period.
    Kept as a cross-check of the generic simulator (tests compare the two).

    Returns
    -------
    t_s, x, force : times [s] ``(N,)``; position and applied force ``design.shape + (N,)``.
    """
    T = 1.0 / rate_hz
    n_steps = int(round(t_end_s * rate_hz)) + 1
    shape = design.shape
    m, b = float(design.actuator.m), float(design.actuator.b)
    Ad, Bd, *_ = cont2discrete((np.array([[0.0, 1.0], [0.0, -b / m]]),
                                np.array([[0.0], [1.0 / m]]), np.eye(2), np.zeros((2, 1))),
                               T, method="zoh")
    flat = lambda a: np.broadcast_to(a, shape).reshape(-1)  # noqa: E731
    K, B, Tf = flat(design.K), flat(design.B), flat(design.Tf_v)
    n_s = np.maximum(np.floor((flat(design.T_s) - T / 2) / T + 0.5 + 1e-9), 0).astype(int)
    n_d = np.maximum(np.floor((flat(design.T_d) - T / 2) / T + 0.5 + 1e-9), 0).astype(int)
    nb = K.size
    a = 2 * Tf / T                       # Tustin: (a+1) v_k + (1-a) v_{k-1} = 2/T (u_k - u_{k-1})
    hist = np.zeros((nb, n_steps + 1))   # sampled positions, hist[:, k + 1] = x_k (x_{-1} = 0)
    state = np.zeros((nb, 2))
    v_prev = np.zeros(nb)
    u_prev = np.zeros(nb)
    x_out = np.zeros((nb, n_steps))
    f_out = np.zeros((nb, n_steps))
    rows = np.arange(nb)
    for k in range(n_steps):
        xk = state[:, 0]
        hist[:, k + 1] = xk
        xs = hist[rows, np.maximum(k - n_s, -1) + 1]
        ud = hist[rows, np.maximum(k - n_d, -1) + 1]
        v = ((2 / T) * (ud - u_prev) - (1 - a) * v_prev) / (a + 1)
        v_prev, u_prev = v, ud
        f = K * (step_m - xs) - B * v
        if force_limit is not None:
            f = np.clip(f, -force_limit, force_limit)
        x_out[:, k], f_out[:, k] = xk, f
        state = state @ Ad.T + f[:, None] * Bd[:, 0]
        if not np.all(np.isfinite(state)):
            state = np.nan_to_num(state, nan=0.0, posinf=1e300, neginf=-1e300)
    t = np.arange(n_steps) * T
    return t, x_out.reshape(shape + (n_steps,)), f_out.reshape(shape + (n_steps,))
