"""A robot's certified verdicts against MuJoCo across its central delay margin:
:class:`MujocoCheck` (:meth:`seactl.Robot.mujoco_check`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.result import Result, new_axes
from seactl.errors import InputError


@dataclass(frozen=True, eq=False)
class MujocoCheck(Result):
    """The robot run in MuJoCo with the central process's delay at multiples of its
    predicted delay margin, beside the certified verdict at each.

    MuJoCo's verdict reads joint 1's response to an impulse of the external torque: its
    peak over the last fifth of the run over its peak over ``[0.2, 0.4)`` of it (the
    ``envelope_ratio``), below 1 decaying (stable), above 1 growing.

    Parameters
    ----------
    delay_margin_s, crossing_hz, factors, central_delay_s, stable : float or ndarray
        As the attributes.
    spectral_abscissa_per_s, envelope_ratio, growth_rate_per_s : ndarray
        As the attributes.
    mujoco_stable, agree, t_s, q_j1_rad : ndarray
        As the attributes.

    Attributes
    ----------
    delay_margin_s : float
        The central delay at which the predicted crossing happens [s] (the design's own
        delay plus :meth:`seactl.System.delay_margin` along ``stiffness``).
    crossing_hz : float
        The frequency of that crossing [Hz].
    factors : numpy.ndarray
        The multiples of ``delay_margin_s`` run, ``(k,)``.
    central_delay_s : numpy.ndarray
        The central delay of each run [s] (the sampled loop rounds it to whole samples).
    stable : numpy.ndarray of bool
        The certified verdict at each delay (exact delays, :meth:`seactl.System.margins`).
    spectral_abscissa_per_s : numpy.ndarray
        The rightmost root's real part at each delay [1/s].
    envelope_ratio : numpy.ndarray
        MuJoCo's late over early peak (see above), unitless.
    growth_rate_per_s : numpy.ndarray
        ``log(envelope_ratio)`` over the time between the windows [1/s]: an estimate of
        the spectral abscissa.
    mujoco_stable : numpy.ndarray of bool
        ``envelope_ratio < 1``.
    agree : numpy.ndarray of bool
        ``stable == mujoco_stable``.
    t_s : numpy.ndarray
        The runs' tick times [s].
    q_j1_rad : numpy.ndarray
        Joint 1's deviation from ``q0`` in each run [rad], ``(k, len(t_s))``.
    agrees : bool
        Every run agrees with its certified verdict.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", q0=[0.0, 1.5], fn_hz=20,
    ...              delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...              filters_hz=(50, 100))                       # doctest: +SKIP
    >>> c = r.mujoco_check(gravity_mps2=(0, -9.81, 0))          # doctest: +SKIP
    >>> c.agrees, c.stable.tolist(), round(c.delay_margin_s * 1e3, 2)  # doctest: +SKIP
    (True, [True, False], 15.39)
    """

    delay_margin_s: float
    crossing_hz: float
    factors: np.ndarray
    central_delay_s: np.ndarray
    stable: np.ndarray
    spectral_abscissa_per_s: np.ndarray
    envelope_ratio: np.ndarray
    growth_rate_per_s: np.ndarray
    mujoco_stable: np.ndarray
    agree: np.ndarray
    t_s: np.ndarray
    q_j1_rad: np.ndarray

    @property
    def agrees(self) -> bool:
        """Every run agrees with its certified verdict."""
        return bool(np.all(self.agree))

    def _columns(self) -> dict[str, Any]:
        k = self.factors.shape
        return {"factor": self.factors,
                "delay_margin_s": np.full(k, self.delay_margin_s),
                "central_delay_s": self.central_delay_s, "stable": self.stable,
                "spectral_abscissa_per_s": self.spectral_abscissa_per_s,
                "envelope_ratio": self.envelope_ratio,
                "growth_rate_per_s": self.growth_rate_per_s,
                "mujoco_stable": self.mujoco_stable, "agree": self.agree}

    def plot(self, ax: Any = None) -> Any:
        """Joint 1's deviation (absolute, log scale) in each run.

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
        for f, d, y, s in zip(self.factors, self.central_delay_s, self.q_j1_rad,
                              self.stable):
            a = np.abs(y)
            ax.semilogy(self.t_s, np.where(a > 0, a, np.nan),
                        label=f"{f:g} x margin: {1e3 * d:.3g} ms "
                              f"({'stable' if s else 'unstable'} certified)")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("|q_j1 - q0| [rad] (MuJoCo)")
        ax.legend()
        return ax


def envelope(t_s: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """``(ratio, rate_per_s)``: the peak of ``|y|`` over the last fifth of the run over its
    peak over ``[0.2, 0.4)`` of it, and its logarithm over the time between them."""
    T = float(t_s[-1])
    a = np.abs(y)
    early = a[(t_s >= 0.2 * T) & (t_s < 0.4 * T)].max()
    late = a[t_s >= 0.8 * T].max()
    ratio = float(late / early) if early > 0 else np.inf
    return ratio, float(np.log(ratio) / (0.6 * T))


def _check_args(factors: Any, t_end_s: float, impulse: float, rate_hz: float) -> np.ndarray:
    from seactl.base.validate import finite_array

    f = finite_array("factors", factors, minimum=0.0, strict=True,
                     nonempty=True).reshape(-1)
    t = finite_array("t_end_s [s]", t_end_s, minimum=0.1)
    if t.size != 1 or float(t) > 20.0:
        raise InputError("t_end_s [s]", t_end_s, "one number in [0.1, 20]")
    finite_array("impulse [N m s]", impulse, minimum=0.0, strict=True)
    finite_array("rate_hz [Hz]", rate_hz, minimum=0.0, strict=True)
    return f


def run_check(robot: Any, factors: Any, t_end_s: float, impulse: float, rate_hz: float,
                 gravity_mps2: Any) -> MujocoCheck:
    """:meth:`seactl.Robot.mujoco_check` (its docstring)."""
    from dataclasses import replace

    from seactl.codegen.mujoco_robot import simulate_robot_mujoco
    from seactl.simulate.inputs import Impulse
    from seactl.systems.robot.reduce import locked_urdf

    f = _check_args(factors, t_end_s, impulse, rate_hz)
    try:
        import mujoco  # noqa: F401
    except ImportError:
        raise InputError("mujoco_check", "mujoco", "MuJoCo installed: pip install "
                         "'seactl[sim]'") from None
    if robot.urdf is None:
        raise InputError("urdf", None, "a robot built by seactl.robot from a URDF file")
    margin = robot.delay_margin({"stiffness": 1})
    t_star = float(np.ravel(margin.crossing_delays_s["stiffness"])[0])
    if not (np.isfinite(t_star) and float(np.ravel(margin.delay_margin_s)[0]) > 0):
        raise InputError("central delay", f"margin {float(margin.delay_margin_s):g} s",
                         "a design stable at its delays whose central delay margin is finite")
    limits = {f"i_m.j{j + 1}": float(a.max_current) for j, a in enumerate(robot.actuators)}
    rows, runs = [], []
    with locked_urdf(robot.urdf, robot.locked) as urdf:  # locked joints compiled fixed
        for factor in f:
            r = replace(robot, delays=dict(robot.delays, stiffness=float(factor) * t_star))
            run = simulate_robot_mujoco(urdf, r.body, r.actuators, r.diagram, r.design,
                                        {"tau_ext.j1": Impulse(float(impulse))}, float(t_end_s),
                                        outputs=("q_j.j1",), rates_hz=float(rate_hz),
                                        saturation=limits, gravity_mps2=gravity_mps2)
            ratio, rate = envelope(run.t_s, run.outputs["q_j.j1"])
            rows.append((float(factor) * t_star, bool(r.margins().stable),
                         float(r.roots(count=3).spectral_abscissa), ratio, rate))
            runs.append(run.outputs["q_j.j1"])
    d, stable, sa, ratio, rate = (np.array(c) for c in zip(*rows))
    return MujocoCheck(t_star, float(np.ravel(margin.crossing_hz)[0]), f, d, stable, sa,
                       ratio, rate, ratio < 1, stable == (ratio < 1), run.t_s,
                       np.array(runs))
