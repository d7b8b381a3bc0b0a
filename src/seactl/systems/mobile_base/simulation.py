"""The base simulated with its distributed controllers."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from seactl.base.borrow import borrowed
from seactl.base.jit import KernelGroup, njit
from seactl.base.parallel import in_threads
from seactl.errors import InputError
from seactl.systems.mobile_base.kinematics import body_jacobian, kinetic_energy, task_inertia
from seactl.systems.mobile_base.model import MobileBaseParams

KERNELS = KernelGroup("mobile base", about_s=6)
"""The group of this module's kernels (the mobile base simulation)."""


# -------------------------------------------------------------------- references
@dataclass(frozen=True)
class Circle:
    """Circle reference starting at the origin at rest; the angular speed ramps in smoothly.

    ``x_d = (R cos psi - R, R sin psi, 0)``, ``psi' = omega s(t)``, ``s`` a half-cosine
    ramp over ``ramp`` seconds, then ``psi' = omega = 2 pi / period``.
    """

    radius: float
    period: float
    ramp: float = 1.0

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, float)
        w = 2 * math.pi / self.period
        tr = self.ramp
        if tr > 0:
            inr = t < tr
            psi = np.where(inr, w * (t / 2 - tr / (2 * math.pi) * np.sin(math.pi * t / tr)),
                           w * (t - tr / 2))
            dpsi = np.where(inr, w * 0.5 * (1 - np.cos(math.pi * t / tr)), w)
            ddpsi = np.where(inr, w * 0.5 * math.pi / tr * np.sin(math.pi * t / tr), 0.0)
        else:
            psi, dpsi, ddpsi = w * t, np.full_like(t, w), np.zeros_like(t)
        R = self.radius
        c, s = np.cos(psi), np.sin(psi)
        z = np.zeros_like(t)
        x = np.stack([R * c - R, R * s, z], axis=-1)
        v = np.stack([-R * s * dpsi, R * c * dpsi, z], axis=-1)
        a = np.stack([-R * s * ddpsi - R * c * dpsi**2, R * c * ddpsi - R * s * dpsi**2, z],
                     axis=-1)
        return x, v, a


def hold_pose(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = np.zeros(np.shape(t) + (3,))
    return z, z, z


# -------------------------------------------------------------------- simulation
@dataclass(frozen=True)
class BaseTrajectories:
    """Sampled trajectories of a batch of simulations (one row per embedded sample).

    Attributes
    ----------
    t : (n,) time [s];  x, v : (n, B, 3) true pose and world velocity;
    x_d, v_d : (n, 3) reference;  tau : (n, B, 3) wheel torques applied [N m];
    saturation : (B,) fraction of wheel-samples saturated;
    energy : (n, B) mechanical energy [J] (kinetic + compliance) when recorded, else None.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    x_d: np.ndarray
    v_d: np.ndarray
    tau: np.ndarray
    saturation: np.ndarray
    energy: np.ndarray | None = None

    def position_error(self) -> np.ndarray:
        """Planar position error norm [m], (n, B)."""
        return np.linalg.norm(self.x[..., :2] - self.x_d[:, None, :2], axis=-1)

    def velocity_error(self) -> np.ndarray:
        """Planar velocity error norm [m/s], (n, B)."""
        return np.linalg.norm(self.v[..., :2] - self.v_d[:, None, :2], axis=-1)

    def rms(self, after: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """RMS position [m] and velocity [m/s] errors over ``t >= after``, each (B,)."""
        m = self.t >= after
        return (np.sqrt(np.mean(self.position_error()[m] ** 2, axis=0)),
                np.sqrt(np.mean(self.velocity_error()[m] ** 2, axis=0)))


def _as_batch(*arrays) -> list[np.ndarray]:
    out = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float)) for a in arrays))
    if out[0].ndim != 1:
        raise InputError("gains", out[0].shape, "scalars or 1-D batches")
    return [np.ascontiguousarray(o) for o in out]


def simulate(p: MobileBaseParams, kx, dx, bq, *, reference=None, duration: float,
             push: float = 0.0, record_energy: bool = False) -> BaseTrajectories:
    """Simulate a batch of gain settings on the sampled multi-rate base.

    Parameters
    ----------
    p : MobileBaseParams
    kx : array_like, (B,) or scalar
        Cartesian stiffness (acceleration gain) [N/(m kg)] on the central process.
    dx : array_like
        Cartesian damping (acceleration gain) [N s/(m kg)] on the central process (COSC).
    bq : array_like
        Joint damping [N m s/rad] on each embedded process (DOSC).
    reference : callable ``t -> (x_d, v_d, a_d)`` or None (hold the start pose).
    duration : float
        Simulated time [s].
    push : float
        Initial chassis velocity [m/s] in x and in y (and ``3 push`` rad/s in yaw).
    record_energy : bool
        Also record the mechanical energy (for tests).

    Examples
    --------
    >>> from seactl.systems.mobile_base.simulation import simulate
    >>> from seactl.systems.mobile_base.model import TRIKEY
    >>> r = simulate(TRIKEY, 0.0, 0.0, 0.0, duration=0.1)   # no gains, at rest: stays at rest
    >>> float(abs(r.x).max())
    0.0
    """
    kx, dx, bq = _as_batch(kx, dx, bq)
    for name, arr in (("kx", kx), ("dx", dx), ("bq", bq)):
        if not np.all(np.isfinite(arr)) or np.any(arr < 0):
            raise InputError(name, arr[~(np.isfinite(arr) & (arr >= 0))][0].item(),
                             ">= 0 and finite")
    if not (duration > 0 and math.isfinite(duration)):
        raise InputError("duration", duration, "> 0 [s]")
    Te = p.embedded_period
    n = int(round(duration / Te))
    ref = reference or hold_pose
    t = np.arange(n) * Te
    x_d, v_d, _ = (np.asarray(r, float) for r in ref(t))
    # The reference is a known trajectory: the central process compares the odometry with
    # the reference at the (time-stamped) measurement time and previews the feedforward
    # (acceleration, wheel speeds) for the time the command reaches the wheels.  Row j of
    # the extended reference is time (j - d_meas) Te, clamped at 0.
    d_meas, d_cmd = p.measurement_delay_samples, p.command_delay_samples
    t_ext = np.maximum(np.arange(-d_meas, n + d_cmd) * Te, 0.0)
    ref_ext = np.stack([np.broadcast_to(np.asarray(r, float), (t_ext.size, 3))
                        for r in ref(t_ext)])
    B = kx.size
    V0 = np.zeros((B, 3))
    V0[:, :2] = push
    V0[:, 2] = 3.0 * push
    out = np.empty((7 if record_energy else 3, n, B, 3))   # x, v, tau (, PHI, QM, WM, -)
    sat = np.zeros(B)
    c, mats, gains = _constants(p), _matrices(p), np.stack([kx, dx, bq])
    # the batch over one thread per core (the compiled kernel releases the GIL)
    in_threads(lambda k: _simulate_batch(c, mats, gains, ref_ext, V0, out, sat, k.start,
                                         k.stop), B, min_per_thread=2)
    if not np.all(np.isfinite(out[0])):
        raise FloatingPointError("base simulation diverged to non-finite values")
    es = None
    if record_energy:
        X, V, PHI, QM, WM = out[0], out[1], out[3], out[4], out[5]
        es = kinetic_energy(p, V, _wheel_rates(V, X, p.alpha, p.wheel_radius,
                                               p.wheel_distance), WM) \
            + 0.5 * p.stiffness * np.sum((QM - PHI) ** 2, axis=-1)
    return BaseTrajectories(t, out[0], out[1], x_d, v_d, out[2], sat / (3 * n), es)


def _constants(p: MobileBaseParams) -> np.ndarray:
    """The scalars the kernel reads, in the order :func:`_simulate_batch` unpacks them."""
    Te, fv = p.embedded_period, p.velocity_filter_hz
    Tc = p.central_every * Te
    a_e = 1.0 if fv == 0 else 1.0 - math.exp(-2 * math.pi * fv * Te)
    a_c = 1.0 if fv == 0 else 1.0 - math.exp(-2 * math.pi * fv * Tc)
    return np.array([p.substeps, p.central_every, p.measurement_delay_samples,
                     p.command_delay_samples, Te, Tc, a_e, a_c, p.encoder_resolution,
                     p.wheel_radius, p.wheel_distance, p.stiffness, p.compliance_damping,
                     p.reflected_rotor_inertia, p.wheel_spin_inertia, p.viscous_friction,
                     p.coulomb_friction, p.friction_velocity, p.torque_limit], float)


def _matrices(p: MobileBaseParams) -> np.ndarray:
    """``J_b``, ``J_b^-1``, ``Lambda`` and rows (diag M^-1, alpha), shape (4, 3, 3)."""
    Jb = body_jacobian(p)
    M = p.body_mass_matrix + p.wheel_spin_inertia * (Jb.T @ Jb)
    rows = np.stack([1.0 / np.diag(M), p.alpha, np.zeros(3)])   # M diagonal (kiwi layout)
    return np.stack([Jb, np.linalg.inv(Jb), task_inertia(p), rows])


# The per-sample loop is compiled (numba, cached on disk): thousands of samples of a few
# scalar operations each, where numpy's per-call overhead would outweigh the arithmetic.
@njit(cache=True, nogil=True)
def _simulate_batch(c, mats, gains, ref, V0, out, sat, b0, b1):  # pragma: no cover
    """The multi-rate base, batch elements ``b0`` to ``b1 - 1`` one at a time (whole
    arrays: one compiled layout however the batch is split over threads).

    ``c``: :func:`_constants`; ``mats``: :func:`_matrices`; ``gains``: rows kx, dx, bq;
    ``ref``: x, v, a of the extended reference; ``out``: x, v, tau (and PHI, QM, WM when
    it has 7 rows) per sample, written in place; ``sat``: saturated wheel-samples.
    """
    d_meas, d_cmd = int(c[2]), int(c[3])
    for b in range(b0, b1):
        X, V, PHI, QM = np.zeros(3), V0[b].copy(), np.zeros(3), np.zeros(3)
        WM = np.array(_mv(mats[0], V0[b]))         # drivetrain moving with the wheels
        meas = np.zeros((d_meas + 1, 3))           # ring of encoder readings (wheel side)
        cmd = np.zeros((d_cmd + 1, 6))             # ring of central outputs (tau, qdot_d)
        central = np.zeros((3, 3))                 # pose_hat, prev_c, vel_c
        work = np.zeros((7, 3))                    # prev_e, vel_e, q; _integrate's scratch
        _simulate_one(c, mats, gains, ref, out, sat, b, X, V, PHI, QM, WM, meas, cmd, central,
                      work)


@njit(cache=True, nogil=True)
def _simulate_one(c, mats, gains, ref, out, sat, b, X, V, PHI, QM, WM, meas, cmd, central,
                  work):  # pragma: no cover - compiled
    """Batch element ``b`` of :func:`_simulate_batch`, its arrays borrowed
    (:mod:`seactl.base.borrow`: no reference counting of the arrays passed at every step)."""
    mats, gains, ref, out, sat = borrowed(mats), borrowed(gains), borrowed(ref), \
        borrowed(out), borrowed(sat)
    X, V, PHI, QM, WM = borrowed(X), borrowed(V), borrowed(PHI), borrowed(QM), borrowed(WM)
    meas, cmd, central, work = borrowed(meas), borrowed(cmd), borrowed(central), borrowed(work)
    substeps, m_c, d_meas, d_cmd = int(c[0]), int(c[1]), int(c[2]), int(c[3])
    Te, Tc, a_e, a_c, res, r, L = c[4], c[5], c[6], c[7], c[8], c[9], c[10]
    kd, cd, Ir, I_sp, bv, tc, vf, tau_max = c[11], c[12], c[13], c[14], c[15], c[16], \
        c[17], c[18]
    dt = Te / substeps
    prev_e, vel_e, q = work[0], work[1], work[2]
    held = np.zeros(6)
    for k in range(out.shape[1]):
        for i in range(3):
            out[0, k, b, i], out[1, k, b, i] = X[i], V[i]
            if out.shape[0] == 7:
                out[3, k, b, i], out[4, k, b, i], out[5, k, b, i] = PHI[i], QM[i], WM[i]
        for i in range(3):
            q[i] = QM[i] if res == 0 else np.floor(QM[i] / res + 0.5) * res
        meas[k % (d_meas + 1)] = q
        if k % m_c == 0:
            m = (k - d_meas) % (d_meas + 1)
            qc = (meas[m, 0], meas[m, 1], meas[m, 2]) if k >= d_meas else (0.0, 0.0, 0.0)
            _central_command(k, qc, central, mats, gains[0, b], gains[1, b], ref,
                             d_meas + d_cmd, Tc, a_c, held)
        cmd[k % (d_cmd + 1)] = held
        row = (k - d_cmd) % (d_cmd + 1)
        for i in range(3):   # embedded process: differenced, filtered velocity; damping
            if k > 0:
                vel_e[i] += a_e * ((q[i] - prev_e[i]) / Te - vel_e[i])
            prev_e[i] = q[i]
            cm, cm_v = (cmd[row, i], cmd[row, 3 + i]) if k >= d_cmd else (0.0, 0.0)
            tau = cm + gains[2, b] * (cm_v - vel_e[i])
            if abs(tau) > tau_max:
                sat[b] += 1
            out[2, k, b, i] = min(max(tau, -tau_max), tau_max)
        _integrate(X, V, PHI, QM, WM, out[2, k, b], mats[3], substeps, dt, r, L, kd, cd,
                   Ir, I_sp, bv, tc, vf, work[3:])


@njit(cache=True)
def _rot3(v, th):  # pragma: no cover - compiled
    """``v`` turned by ``th`` about z; 3-vectors are tuples here (no allocation)."""
    c, s = np.cos(th), np.sin(th)
    return c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]


@njit(cache=True)
def _mv(M, v):  # pragma: no cover - compiled
    """``M @ v`` for 3x3 ``M`` (no BLAS call for three terms)."""
    return (M[0, 0] * v[0] + M[0, 1] * v[1] + M[0, 2] * v[2],
            M[1, 0] * v[0] + M[1, 1] * v[1] + M[1, 2] * v[2],
            M[2, 0] * v[0] + M[2, 1] * v[1] + M[2, 2] * v[2])


@njit(cache=True)
def _mtv(M, v):  # pragma: no cover - compiled
    """``M.T @ v`` for 3x3 ``M``."""
    return (M[0, 0] * v[0] + M[1, 0] * v[1] + M[2, 0] * v[2],
            M[0, 1] * v[0] + M[1, 1] * v[1] + M[2, 1] * v[2],
            M[0, 2] * v[0] + M[1, 2] * v[1] + M[2, 2] * v[2])


@njit(cache=True)
def _central_command(k, qc, state, mats, kx, dx, ref, ahead, Tc, a_c,
                     held):  # pragma: no cover - compiled
    """Odometry and the operational space law of the central process: wheel torques
    ``J^-T F`` and desired wheel speeds into ``held`` (6,) from the (delayed) encoder
    reading ``qc``."""
    Jb, Jb_inv, Lam = mats[0], mats[1], mats[2]
    pose_hat, prev_c, vel_c = state[0], state[1], state[2]
    dq = (qc[0] - prev_c[0], qc[1] - prev_c[1], qc[2] - prev_c[2])
    body = _mv(Jb_inv, dq)                        # body-frame displacement since last sample
    turn = _rot3(body, pose_hat[2] + 0.5 * body[2])
    for i in range(3):
        prev_c[i] = qc[i]
        pose_hat[i] += turn[i]
        vel_c[i] += a_c * (dq[i] / Tc - vel_c[i])
    v_hat = _rot3(_mv(Jb_inv, vel_c), pose_hat[2])
    ka = k + ahead                                # row of the arrival time
    err = (ref[0, k, 0] - pose_hat[0], ref[0, k, 1] - pose_hat[1], ref[0, k, 2] - pose_hat[2])
    err = (err[0], err[1], np.arctan2(np.sin(err[2]), np.cos(err[2])))
    acc = (ref[2, ka, 0] + kx * err[0] + dx * (ref[1, k, 0] - v_hat[0]),
           ref[2, ka, 1] + kx * err[1] + dx * (ref[1, k, 1] - v_hat[1]),
           ref[2, ka, 2] + kx * err[2] + dx * (ref[1, k, 2] - v_hat[2]))
    F = _mv(Lam, acc)
    th = pose_hat[2]
    held[0], held[1], held[2] = _mtv(Jb_inv, _rot3(F, -th))
    held[3], held[4], held[5] = _mv(Jb, _rot3(ref[1, ka], -th))


@njit(cache=True)
def _integrate(X, V, PHI, QM, WM, tau, rows, substeps, dt, r, L, kd, cd, Ir, I_sp, bv, tc,
               vf, scratch):  # pragma: no cover - compiled
    """One embedded period under wheel torques ``tau``, in place: ``substeps``
    semi-implicit Euler steps of the chassis, the wheels and the compliant drivetrains
    (``scratch``: three rows of 3)."""
    M_inv, alpha = rows[0], rows[1]
    s, co, tq = scratch[0], scratch[1], scratch[2]
    for _ in range(substeps):
        for i in range(3):
            s[i], co[i] = np.sin(X[2] + alpha[i]), np.cos(X[2] + alpha[i])
            phid = (-s[i] * V[0] + co[i] * V[1] + L * V[2]) / r
            tk = kd * (QM[i] - PHI[i]) + cd * (WM[i] - phid)
            WM[i] = WM[i] + dt / Ir * (tau[i] - tk - bv * WM[i] - tc * np.tanh(WM[i] / vf))
            # Wheel spin inertia rides on the non-holonomic constraint phidot = J(theta)
            # xdot: the gyroscopic term -I_spin J^T Jdot xdot (Lagrange-d'Alembert) couples
            # x and y while the base turns.  (The rotors get theirs through the compliance.)
            tq[i] = tk - I_sp * V[2] * (-co[i] * V[0] - s[i] * V[1]) / r
        F0 = -(s[0] * tq[0] + s[1] * tq[1] + s[2] * tq[2]) / r
        F1 = (co[0] * tq[0] + co[1] * tq[1] + co[2] * tq[2]) / r
        F2 = L * (tq[0] + tq[1] + tq[2]) / r
        V[0] += dt * F0 * M_inv[0]
        V[1] += dt * F1 * M_inv[1]
        V[2] += dt * F2 * M_inv[2]
        for j in range(3):
            X[j] += dt * V[j]
        for i in range(3):
            PHI[i] += dt * (-s[i] * V[0] + co[i] * V[1] + L * V[2]) / r
            QM[i] += dt * WM[i]


def _wheel_rates(V, X, alpha, r, L):
    th = X[..., 2:3] + alpha
    return (-np.sin(th) * V[..., 0:1] + np.cos(th) * V[..., 1:2] + L * V[..., 2:3]) / r
