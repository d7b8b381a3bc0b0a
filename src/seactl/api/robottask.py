"""A robot's task-space step and impulse: :class:`TaskResponseResult` (the method
:meth:`~seactl.api.robot.Robot.task_response`).

A step of the task reference ``dx`` moves the joints' references by ``J^+ dx`` (the
linearization at ``q0``, ``J`` the task frame's translational Jacobian); a force impulse
``F`` at the task frame is the joints' external torque impulse ``J^T F``.  The output is
the task frame's displacement ``J q``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.result import Result, new_axes
from seactl.base.validate import finite_array
from seactl.errors import InputError

KINDS = ("step", "impulse")
DEFAULT_AMPLITUDE = {"step": 0.001, "impulse": 0.01}
"""A 1 mm step; a 0.01 N s impulse."""
UNITS = {"step": "m", "impulse": "N s"}
MAX_T_END_S = 20.0


@dataclass(frozen=True, eq=False)
class TaskResponseResult(Result):
    """The task frame's translation after a step of the task reference or a force impulse
    at the task frame (continuous, exact delays).

    Parameters
    ----------
    kind, direction, amplitude, amplitude_unit, t_s, x_m, along_m : object
        As the attributes.
    q_rad, stable, metrics : object
        As the attributes.

    Attributes
    ----------
    kind : str
        ``"step"`` or ``"impulse"``.
    direction : numpy.ndarray
        ``(3,)`` unit vector of the step or the force (world-aligned).
    amplitude : float
        The step [m] or the impulse [N s] (``amplitude_unit``).
    amplitude_unit : str
        ``m`` or ``N s``.
    t_s : numpy.ndarray
        Times [s], ``(T,)``.
    x_m : numpy.ndarray
        ``(3, T)``: the task frame's displacement ``J q`` [m].
    along_m : numpy.ndarray
        ``(T,)``: its component along ``direction`` [m].
    q_rad : numpy.ndarray
        ``(n, T)``: the joints' displacements [rad].
    stable : bool
        The simulation stayed bounded and did not grow at the end.
    metrics : StepMetrics or ImpulseMetrics
        Of ``along_m`` (divided by the step for a step): rise, overshoot, settling; or
        peak deviation and recovery time.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
    ...              q0=[0.3, 0.8], fn_hz=14)                          # doctest: +SKIP
    >>> s = r.task_step((1, 0, 0), amplitude_m=1e-3, t_end_s=8.0)      # doctest: +SKIP
    >>> s.stable, round(float(s.along_m[-1]) * 1e3, 4)                 # doctest: +SKIP
    (True, 1.0)
    """

    kind: str
    direction: np.ndarray
    amplitude: float
    amplitude_unit: str
    t_s: np.ndarray
    x_m: np.ndarray
    along_m: np.ndarray
    q_rad: np.ndarray
    stable: bool
    metrics: Any

    def _columns(self) -> dict[str, Any]:
        return {"t_s": self.t_s, "x_m": self.x_m[0], "y_m": self.x_m[1], "z_m": self.x_m[2],
                "along_m": self.along_m}

    def plot(self, ax: Any = None) -> Any:
        """The displacement along ``direction`` against time.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        ax.plot(self.t_s, self.along_m * 1e3, label=f"task {self.kind}")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("displacement along the direction [mm]")
        ax.legend()
        return ax


def _direction(direction: Any) -> np.ndarray:
    d = finite_array("direction", direction).reshape(-1)
    if d.size != 3 or not np.linalg.norm(d) > 0:
        raise InputError("direction", direction, "3 numbers, not all 0 (x, y, z)")
    return d / np.linalg.norm(d)


def task_response(r: Any, kind: str = "step", direction: Any = (1.0, 0.0, 0.0),
                  amplitude: float | None = None, t_end_s: float = 2.0) -> TaskResponseResult:
    """:meth:`seactl.api.robot.Robot.task_response` (its documentation)."""
    from seactl.simulate.engine import simulate
    from seactl.simulate.inputs import Impulse, Step
    from seactl.simulate.metrics import impulse_metrics, step_metrics
    from seactl.simulate.verdict import RECOVERY_BAND

    if kind not in KINDS:
        raise InputError("kind", kind, " or ".join(KINDS))
    if r.body.jacobian is None:
        raise InputError("task", None, "a robot with a task frame (sc.robot(..., task=FRAME))")
    d = _direction(direction)
    a = DEFAULT_AMPLITUDE[kind] if amplitude is None else float(
        finite_array("amplitude", amplitude, minimum=0.0, strict=True))
    t_end = float(finite_array("t_end_s", t_end_s, minimum=0.0, strict=True))
    if t_end > MAX_T_END_S:
        raise InputError("t_end_s", t_end_s, f"(0, {MAX_T_END_S:g}] s")
    J = np.asarray(r.body.jacobian, float)[:3]
    outputs = tuple(f"q_j.j{k + 1}" for k in range(r.n))
    if kind == "step":
        dq = np.linalg.pinv(J) @ (a * d)
        inputs = {f"q_des.j{k + 1}": Step(float(dq[k])) for k in range(r.n)}
        bound = None
    else:
        tau = J.T @ (a * d)
        inputs = {f"tau_ext.j{k + 1}": Impulse(float(tau[k])) for k in range(r.n)}
        qd0 = np.linalg.solve(r.body.mass_matrix, tau)
        bound = 1e3 * float(np.max(np.abs(qd0))) * t_end + 1e-12
    res = simulate(r.diagram, r.design, inputs, t_end, mode="continuous", outputs=outputs,
                   bound=bound)
    q = np.stack([np.asarray(res.outputs[o], float).reshape(-1) for o in outputs])
    x = J @ q
    along = d @ x
    stable = bool(np.all(res.stable))
    left = np.asarray(res.left_bounds_s).reshape(())
    metrics = (step_metrics(res.t_s, along / a, np.asarray(stable), left) if kind == "step"
               else impulse_metrics(res.t_s, along, np.asarray(stable), left, RECOVERY_BAND))
    return TaskResponseResult(kind, d, a, UNITS[kind], np.asarray(res.t_s), x, along, q,
                              stable, metrics)
