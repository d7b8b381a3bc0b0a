"""A multi-joint SEA robot from its URDF as a seactl.System: :class:`Robot` and :func:`robot`.

The rigid body comes from pinocchio (:mod:`seactl.systems.robot.model`), the loop is one
block diagram (:mod:`seactl.systems.robot.loops`): one SEA per joint with its torque and
damping loops on the joint's embedded process, the stiffness (joint space, or task space
``J^T K_x J``) on the central process with its latency.  Every view of
:class:`seactl.System` works on it; :meth:`Robot.margins_by_break` breaks each loop of
each joint in turn.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from seactl.api.arguments import delays_by_loop, filter_cutoffs
from seactl.api.sea import SEA_LOOPS
from seactl.api.system import System
from seactl.base.validate import finite_array
from seactl.errors import InputError

SPACES = ("joint", "task")


@dataclass(frozen=True, eq=False)
class Robot(System):
    """A robot's linearized loop at ``q0`` (a single design; build it with :func:`robot`).

    Parameters
    ----------
    body : seactl.systems.robot.model.RigidBody
        Joints, ``q0``, mass matrix, damping, task Jacobian.
    actuators : tuple of SEAParams
        Per joint, the actuator with the joint's effective inertia
        (:func:`design_inertia`) and the URDF's damping as its load (what its gains were
        designed for).
    gains : tuple of Gains
        Per joint (``Kq`` is the designed joint stiffness; the loop uses ``stiffness``).
    stiffness : numpy.ndarray
        The stiffness matrix on the central process [N m/rad] (``n x n``).
    space : str
        ``"joint"`` or ``"task"``.
    fn_hz, gs : float
        The joints' design (natural frequency [Hz], gain scale).
    delays : dict
        ``"torque"``, ``"stiffness"``, ``"damping"`` -> delay [s].
    filters_hz : tuple
        ``(f_qd, f_taud)`` [Hz] or None.
    task_stiffness : tuple or None
        ``(k_x [N/m], k_r [N m/rad])`` in task space.
    urdf : str or None
        The URDF file it was built from (what :meth:`mujoco_check` compiles).
    locked : tuple
        ``(name, value)`` of each joint locked at its ``q0`` value (``joints=``); MuJoCo
        compiles them fixed.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
    ...              q0=[0.3, 0.8], fn_hz=14)                   # doctest: +SKIP
    >>> r.kind, r.n, sorted(r.margins_by_break())[:2]           # doctest: +SKIP
    ('robot', 2, ['damping.j1', 'damping.j2'])
    """

    body: Any
    actuators: tuple
    gains: tuple
    stiffness: np.ndarray
    space: str
    fn_hz: float
    gs: float
    delays: dict
    filters_hz: tuple
    task_stiffness: tuple | None
    urdf: str | None = None
    locked: tuple = ()

    kind: ClassVar[str] = "robot"
    step_unit: ClassVar[str] = "rad"
    default_step: ClassVar[float] = 0.01
    impulse_unit: ClassVar[str] = "N m s"
    default_impulse: ClassVar[float] = 0.05
    reference: ClassVar[str] = "q_des.j1"
    disturbance: ClassVar[str] = "tau_ext.j1"
    output: ClassVar[str] = "q_j.j1"
    actuation: ClassVar[str] = "i_m.j1"
    sensor: ClassVar[str] = "q_sens.j1"
    ports: ClassVar[tuple[str, ...]] = ()

    # ------------------------------------------------------------ structure
    @property
    def n(self) -> int:
        """The number of joints."""
        return self.body.n

    @property
    def loops(self) -> tuple[str, ...]:  # type: ignore[override]
        """``stiffness`` (the central process), ``torque.jN`` and ``damping.jN``."""
        return ("stiffness",) + tuple(f"{loop}.j{j + 1}" for j in range(self.n)
                                      for loop in ("torque", "damping"))

    @property
    def breaks(self) -> dict[str, str]:
        """Loop break name (``outer.j1``, ``stiffness.j1``, ``damping.j1``, ``torque.j1``,
        ...) -> the diagram's signal broken there.
        """
        from seactl.systems.robot.loops import BREAKS

        return {f"{loop}.j{j + 1}": f"{signal}.j{j + 1}" for j in range(self.n)
                for loop, signal in BREAKS.items()}

    @property
    def shape(self) -> tuple[int, ...]:
        return ()

    def __getitem__(self, idx: Any) -> Robot:
        if idx is Ellipsis or idx == ():
            return self
        raise IndexError(f"index {idx!r} of a robot (a single design)")

    @property
    def diagram(self) -> Any:
        from seactl.systems.robot.loops import robot_diagram

        return robot_diagram(self.n, self.space == "task")

    @property
    def design(self) -> Any:
        from seactl.systems.robot.loops import robot_design

        return robot_design(np.linalg.inv(self.body.mass_matrix), self.stiffness,
                            self.joint_fields(), self.delays["stiffness"])

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        out = {"stiffness": np.asarray(self.delays["stiffness"])}
        for j in range(self.n):
            out[f"torque.j{j + 1}"] = np.asarray(self.delays["torque"])
            out[f"damping.j{j + 1}"] = np.asarray(self.delays["damping"])
        return out

    @property
    def links(self) -> dict[str, str]:
        out = {"stiffness": "Kq_fb_j1j1"}
        for j in range(self.n):
            out[f"torque.j{j + 1}"] = f"tau_delay_j{j + 1}"
            out[f"damping.j{j + 1}"] = f"Bq_fb_j{j + 1}"
        return out

    @property
    def max_current_a(self) -> float:
        return float(min(a.max_current for a in self.actuators))

    @property
    def amperes_per_actuation(self) -> float:
        return 1.0

    def reference_frequency(self) -> np.ndarray:
        """The largest of the joints' SEA reference frequencies [rad/s].

        Returns
        -------
        numpy.ndarray
            A scalar [rad/s].
        """
        from seactl.systems.sea.loops import SEADesign, Timing
        from seactl.systems.sea.views import sea_reference_frequency

        return np.asarray(max(float(sea_reference_frequency(SEADesign(a, g, Timing())))
                              for a, g in zip(self.actuators, self.gains)))

    def impulse_inertia(self) -> np.ndarray:
        return np.asarray(float(self.body.mass_matrix[0, 0]))

    def labels(self) -> list[str]:
        return [f"{self.space} space, f_n={self.fn_hz:g} Hz, GS={self.gs:g}"]

    def label_columns(self, gains: bool = True) -> dict[str, Any]:
        return {"fn_hz": np.asarray(self.fn_hz), "gs": np.asarray(self.gs)}

    # ------------------------------------------------------------ the robot's own views
    def margins_by_break(self) -> dict[str, Any]:
        """The margins of every loop break, the other loops closed (exact delays, certified
        verdicts as :meth:`margins`).

        Returns
        -------
        dict
            Break name (``outer.j1``, ``stiffness.j1``, ``damping.j1``, ``torque.j1``, ...)
            -> :class:`~seactl.api.results.MarginsResult`.
        """
        from seactl.analysis.margins import default_grid, loop_margins
        from seactl.api.results import MarginsResult

        grid, design = default_grid(self.reference_frequency()), self.design
        return {name: MarginsResult(loop_margins(self.diagram.loop(signal), design, grid,
                                                 shared_forms=self._evaluated_forms),
                                    self.label_columns())
                for name, signal in self.breaks.items()}

    def impedance_matrix(self, f_hz: Any) -> np.ndarray:
        """The joint-space impedance matrix ``Z(j 2 pi f)`` felt by the links: with every
        joint's motion imposed (references 0), ``Z_jk = tau_k.j / (-s q_j.k)``, the SEA's
        joint impedance per element (the links' own inertia excluded).

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0, 1-D.

        Returns
        -------
        numpy.ndarray
            ``(len(f_hz), n, n)`` complex [N m s/rad].  Its singular values are the
            principal impedances; the smallest eigenvalue of its Hermitian part
            ``(Z + Z^H) / 2`` is negative where the loop is not passive.
        """
        f = finite_array("f_hz", f_hz, minimum=0.0, strict=True).reshape(-1)
        s = 2j * np.pi * f
        cut = tuple(f"q_j.j{k + 1}" for k in range(self.n))
        design = self.design
        z = np.empty((f.size, self.n, self.n), complex)
        for j in range(self.n):
            for k in range(self.n):
                z[:, j, k] = self.diagram.transfer(f"tau_k.j{j + 1}", f"q_j.j{k + 1}", cut)(
                    design, s) / (-s)
        return z

    def mujoco_check(self, factors: Sequence[float] = (0.8, 1.2), *, t_end_s: float = 1.0,
                      impulse: float = 1e-3, rate_hz: float = 1000.0,
                      gravity_mps2: Sequence[float] = (0.0, 0.0, -9.81)) -> Any:
        """Run the robot in MuJoCo with the central delay at multiples of its predicted
        delay margin, beside the certified verdict at each (docs/robots.md).

        MuJoCo compiles the URDF; each joint gets a rotor and a spring, gravity is
        compensated, seactl's sampled controllers tick at ``rate_hz``
        (:mod:`seactl.codegen.mujoco_robot`); an impulse of the external torque on joint
        1 starts each run at rest at ``q0``.

        Parameters
        ----------
        factors : sequence of float
            Multiples (> 0) of the central delay at the predicted crossing.
        t_end_s : float
            Simulated time of each run [s], in [0.1, 20].
        impulse : float
            The impulse on joint 1 [N m s] (small: the linear regime), > 0.
        rate_hz : float
            The controllers' rate [Hz].
        gravity_mps2 : sequence of 3 float
            Gravity in the world frame [m/s^2] (compensated).

        Returns
        -------
        seactl.api.robotcheck.MujocoCheck
            Per factor the certified verdict, MuJoCo's envelope ratio and verdict,
            ``agree``; ``agrees``, ``records()``, ``plot()``.

        Raises
        ------
        InputError
            Bad arguments, MuJoCo not installed, a URDF MuJoCo does not compile, or a
            design whose central delay margin is not finite and positive.
        """
        from seactl.api.robotcheck import run_check

        return run_check(self, factors, t_end_s, impulse, rate_hz, gravity_mps2)

    # ------------------------------------------------------------ the central process's MIMO loop
    def mimo_margins(self) -> Any:
        """The generalized Nyquist margins of the loop broken at every stiffness channel
        at once (the central process; damping and torque loops closed), exact delays.

        Returns
        -------
        seactl.api.robotnyquist.MimoMarginsResult
            The characteristic loci (eigenvalues of the ``n x n`` loop matrix on a
            frequency grid), ``phase_margin_deg`` and ``gain_margin`` (the common phase
            rotation and gain of every channel that puts a locus on -1), the crossovers,
            ``delay_margin_s`` (the extra central latency that puts a root on the
            imaginary axis), ``min_return_difference`` (smallest singular value of
            ``I + L``), ``stable`` (the certified verdict), ``records()``, ``plot()``.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
        ...              q0=[0.3, 0.8], fn_hz=14,
        ...              delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
        ...              filters_hz=(50, 100))                   # doctest: +SKIP
        >>> m = r.mimo_margins()                                  # doctest: +SKIP
        >>> round(m.phase_margin_deg, 2), round(m.delay_margin_s * 1e3, 2)  # doctest: +SKIP
        (28.65, 25.64)
        """
        from seactl.api.robotnyquist import mimo_margins

        return mimo_margins(self)

    def placement(self, central_ms: float = 5.0, embedded_ms: float = 0.5, *,
                  loops: Sequence[str] = ("stiffness", "damping")) -> Any:
        """Every placement of ``loops`` on the central process or the joints' embedded
        processes (the other loops embedded), each with its verdict and central latency
        margins.

        Parameters
        ----------
        central_ms, embedded_ms : float
            The latency of the central process and of every embedded one [ms].
        loops : sequence of str
            The loops placed, among ``stiffness``, ``damping``, ``torque``.

        Returns
        -------
        seactl.api.robotplacement.RobotPlacementResult
            Per placement ``stable``, the stiffness channels' generalized Nyquist
            ``phase_margin_deg``, ``delay_margin_s`` (the extra central latency, every
            central loop delayed alike) and ``max_central_latency_s`` (the first crossing
            from a central latency of zero); ``option(...)``, ``records()``, ``plot()``.

        Raises
        ------
        InputError
            A latency out of range, an unknown or repeated loop.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
        ...              q0=[0.3, 0.8], fn_hz=14, filters_hz=(50, 100))   # doctest: +SKIP
        >>> p = r.placement(central_ms=5, embedded_ms=0.5)                # doctest: +SKIP
        >>> p.option(stiffness="central", damping="embedded").stable      # doctest: +SKIP
        True
        """
        from seactl.api.robotplacement import robot_placement

        return robot_placement(self, central_ms, embedded_ms, tuple(loops))
    # ------------------------------------------------------------ task impedance, passivity
    def task_impedance(self, f_hz: Any, *, space: str | None = None) -> Any:
        """The impedance matrix felt at the task frame's translation, joints' references
        fixed: ``Z_x = (U_r^T J Z_q^-1 J^T U_r)^-1`` [N s/m] with ``Z_q`` the joint
        impedance (:meth:`impedance_matrix`, the links' own inertia excluded) and ``U_r``
        the ``r`` directions the joints move (docs/robots.md).

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0, 1-D.
        space : {"task", "joint"}, optional
            ``"joint"``: the same views of ``Z_q`` itself (default: task if the robot has
            a task frame).

        Returns
        -------
        seactl.api.robotimpedance.TaskImpedanceResult
            ``z``, ``principal_values``, ``directions``, ``hermitian_min``, ``passive``
            (certified on the range of ``f_hz``), ``records()``, ``plot()``.
        """
        from seactl.api.robotimpedance import task_impedance

        return task_impedance(self, f_hz, space)

    def passivity(self, f_range_hz: Any = (0.01, 1e4), *,
                  points_per_decade: int = 400) -> Any:
        """Whether the joint impedance's Hermitian part ``(Z_q + Z_q^H) / 2`` is positive
        definite over a frequency range: certified between the points of a grid
        (:mod:`seactl.certify.hermitian`), or refuted by a point; it implies the task
        impedance's passivity.

        Parameters
        ----------
        f_range_hz : (float, float)
            The range [Hz]; nothing is claimed outside it (the SEA's default).
        points_per_decade : int
            Density of the grid of the smallest eigenvalue reported (``worst_f_hz``);
            the certificate starts from every 16th point and halves as it needs.

        Returns
        -------
        seactl.api.robotimpedance.RobotPassivityResult
            ``passive``, ``proven``, ``negative_f_hz``, ``worst_f_hz``, ``hermitian_min``.
        """
        from seactl.api.robotimpedance import passivity

        return passivity(self, f_range_hz, points_per_decade)

    def task_step(self, direction: Any = (1.0, 0.0, 0.0), *, amplitude_m: float = 1e-3,
                  t_end_s: float = 2.0) -> Any:
        """The task frame's response to a step of its reference along ``direction``: the
        joints' references step by ``J^+ dx`` (continuous, exact delays).

        Parameters
        ----------
        direction : sequence of 3 float
            World-aligned (normalized).
        amplitude_m : float
            The step [m] > 0.
        t_end_s : float
            Simulated time [s], at most 20.

        Returns
        -------
        seactl.api.robottask.TaskResponseResult
            ``t_s``, ``x_m``, ``along_m``, ``stable``, ``metrics`` (of ``along_m`` divided
            by the step), ``plot()``.
        """
        from seactl.api.robottask import task_response

        return task_response(self, "step", direction, amplitude_m, t_end_s)

    def task_impulse(self, direction: Any = (1.0, 0.0, 0.0), *, amplitude_n_s: float = 0.01,
                     t_end_s: float = 2.0) -> Any:
        """The task frame's response to a force impulse at it along ``direction`` (the
        joints' external torque impulse ``J^T F``; references fixed).

        Parameters
        ----------
        direction : sequence of 3 float
            World-aligned (normalized).
        amplitude_n_s : float
            The impulse [N s] > 0.
        t_end_s : float
            Simulated time [s], at most 20.

        Returns
        -------
        seactl.api.robottask.TaskResponseResult
            As :meth:`task_step`; ``metrics`` are the peak deviation and recovery time.
        """
        from seactl.api.robottask import task_response

        return task_response(self, "impulse", direction, amplitude_n_s, t_end_s)

    # ------------------------------------------------------------ the loop's evaluated terms
    @cached_property
    def _evaluated_forms(self) -> dict:
        """The characteristic terms of this robot's loop evaluated for its design, kept
        between its loop breaks (every break's ``N`` and ``D`` are sums of the same
        terms; :func:`seactl.diagram.blockdiagram.evaluate_forms`)."""
        return {}

    def margins(self, rate_hz: Any = None) -> Any:
        """The margins of the loop broken at ``q_sens.j1`` (the break ``outer.j1`` of
        :meth:`margins_by_break`), as :meth:`seactl.System.margins`; the continuous
        loop's characteristic terms are evaluated once with the other breaks'.

        Parameters
        ----------
        rate_hz : float or dict, optional
            As :meth:`seactl.System.margins` (None: the continuous loop).

        Returns
        -------
        MarginsResult or SampledMarginsResult
            As :meth:`seactl.System.margins`.
        """
        if rate_hz is None and self.large:
            from seactl.api.robotlarge import large_margins

            return large_margins(self)
        return super().margins(rate_hz)

    # ------------------------------------------------------------ more than three joints
    @property
    def large(self) -> bool:
        """More joints than the diagram's cycles serve (:data:`MASON_JOINTS`): the
        characteristic comes joint by joint (:mod:`seactl.systems.robot.characteristic`);
        :meth:`margins` gives the verdict only (margins NaN), :meth:`mimo_margins`,
        :meth:`delay_margin` and :meth:`stability_chart` work, the views that need the
        loop's transfers (and :meth:`roots`) are refused.
        """
        from seactl.systems.robot.loops import MASON_JOINTS

        return self.n > MASON_JOINTS

    def joint_fields(self) -> list[dict[str, float]]:
        """Per joint the numbers its SEA's blocks read (as
        :func:`~seactl.systems.robot.loops.robot_design` takes them).

        Returns
        -------
        list of dict
            Per joint the field name (without the joint's suffix) -> value.
        """
        from seactl.systems.sea.loops import filter_time_constant

        f_qd, f_taud = self.filters_hz
        return [dict(Im=a.Im, bm=a.bm, k=a.k, beta=a.beta, bj=a.bj, Bq=g.Bq, Ktau=g.Ktau,
                     Btau=g.Btau, Tf_qd=filter_time_constant(f_qd),
                     Tf_taud=filter_time_constant(f_taud), T_tau=self.delays["torque"],
                     T_qd=self.delays["damping"])
                for a, g in zip(self.actuators, self.gains)]

    def delay_terms(self) -> Any:
        """As :meth:`seactl.System.delay_terms`; with more than three joints built joint by
        joint, its delays named by process (``stiffness``, ``torque``, ``damping``).

        Returns
        -------
        seactl.diagram.delayterms.DelayTerms
            The characteristic as a function of the named delays.
        """
        if not self.large:
            return super().delay_terms()
        from seactl.api.robotlarge import large_delay_terms

        return large_delay_terms(self)

    def roots(self, count: int = 6) -> Any:
        """As :meth:`seactl.System.roots`; refused with more than three joints: on the
        joint-by-joint characteristic (degree up to ``6 n``) the collocation need not
        converge and the inclusion discs take degrees below 32; the verdict and the delay
        margins come from certified counts instead.

        Parameters
        ----------
        count : int
            As :meth:`seactl.System.roots`.

        Returns
        -------
        RootsResult
            As :meth:`seactl.System.roots`.

        Raises
        ------
        InputError
            More than three moving joints (names ``joints``).
        """
        if self.large:
            from seactl.systems.robot.loops import LARGE_VIEWS, MASON_JOINTS

            raise InputError("joints", f"{self.n} moving joints",
                             f"at most {MASON_JOINTS} for roots(); with more: {LARGE_VIEWS}")
        return super().roots(count)


def design_inertia(mass_matrix: np.ndarray) -> np.ndarray:
    """Per joint the inertia its SEA is designed for: ``1 / (M^{-1})_jj`` [kg m^2], what
    the joint's spring feels when the other joints are torque-controlled (free), the
    smallest inertia it can see (``M_jj`` when the joints are decoupled)."""
    return 1.0 / np.diag(np.linalg.inv(mass_matrix))


def _actuator_map(actuators: Any, joints: Sequence[str]) -> list[Any]:
    from seactl.systems.sea.actuators import SEAParams, load_sea

    def one(spec: Any) -> Any:
        return spec if isinstance(spec, SEAParams) else load_sea(spec)

    if not isinstance(actuators, Mapping):
        a = one(actuators)
        return [a] * len(joints)
    unknown = [k for k in actuators if k not in joints]
    if unknown:
        raise InputError("actuators", unknown[0], "joint names of the URDF: " + ", ".join(joints))
    missing = [j for j in joints if j not in actuators]
    if missing:
        raise InputError("actuators", f"joint {missing[0]!r} without an actuator",
                         "an actuator (preset or TOML file) for every joint: " + ", ".join(joints))
    return [one(actuators[j]) for j in joints]


def _task_stiffness(body: Any, kq: np.ndarray, task_stiffness: Any) -> tuple[np.ndarray, tuple]:
    """``J^T diag(k_x I3, k_r I3) J`` and ``(k_x [N/m], k_r [N m/rad])``; by default
    ``k_r = k_x reach^2`` and ``k_x`` such that the largest eigenvalue is the smallest
    designed joint stiffness."""
    J = body.jacobian
    if task_stiffness is None:
        reach = body.reach_m if body.reach_m > 0 else 1.0
        w = np.diag([1.0] * 3 + [reach ** 2] * 3)
        top = float(np.linalg.eigvalsh(J.T @ w @ J).max())
        if top <= 0:
            raise InputError("task", body.frame, "a frame the joints move (its Jacobian is 0)")
        kx = float(kq.min()) / top
        kr = kx * reach ** 2
    else:
        kx, kr = (float(x) for x in finite_array("task_stiffness", task_stiffness, minimum=0.0))
    K = J.T @ np.diag([kx] * 3 + [kr] * 3) @ J
    return 0.5 * (K + K.T), (kx, kr)


def _joint_gains(actuator: Any, fn_hz: float, gs: float, joint: str) -> Any:
    """The joint's critically damped gains; an infeasible design names the joint."""
    from seactl.errors import InfeasibleDesignError
    from seactl.systems.sea.design import critically_damped_gains

    try:
        return critically_damped_gains(actuator, fn_hz, gs=gs)
    except InfeasibleDesignError as exc:
        raise InfeasibleDesignError(f"joint {joint!r} (effective inertia "
                                    f"{actuator.Ij:.4g} kg m^2): {exc}", fn_hz=exc.fn_hz,
                                    feasible_hz=exc.feasible_hz) from None


def robot(urdf: str | Path | None = None, *, model: str | None = None,
          joints: Sequence[str] | None = None, actuators: Any = "ut-sea", space: str = "joint",
          task: str | None = None, q0: Any = None, fn_hz: float = 14.0, gs: float = 1.0,
          delays_ms: Mapping[str, Any] | None = None,
          filters_hz: Sequence[Any] = (None, None),
          task_stiffness: Sequence[float] | None = None) -> Robot:
    """A robot's linearized SEA loop at ``q0``, from its URDF.

    Parameters
    ----------
    urdf : str or path, optional
        A URDF (fixed base); one SEA per moving joint, each revolute.
    model : str, optional
        Instead of ``urdf``: a robot of ``example-robot-data`` by name
        (:func:`seactl.robot_models`; ``pip install -e ".[robots]"``).
    joints : sequence of str, optional
        The moving joints (at most 7; default all); every other joint is locked at its
        ``q0`` value, its links part of the rigid body the moving joints carry.
    actuators : str or path or SEAParams or dict
        One actuator for every joint (preset name, TOML file), or joint name -> actuator.
    space : {"joint", "task"}
        Stiffness in joint space (each joint its designed ``K_q``) or in task space
        (``J^T K_x J`` of the frame ``task``).
    task : str, optional
        The task frame (required in task space).
    q0 : sequence of float, optional
        The configuration [rad] (default: zeros): with ``joints``, of the moving joints
        (in the model's order; the locked ones at 0) or of all the model's joints.
    fn_hz, gs : float
        Each joint's critically damped design (:func:`seactl.design`) for its effective
        inertia ``1 / (M(q0)^{-1})_jj`` (:func:`design_inertia`) and its URDF damping.
    delays_ms : dict, optional
        ``"torque"``, ``"stiffness"`` (the central process), ``"damping"`` [ms], the same
        for every joint.
    filters_hz : tuple
        ``(f_qd, f_taud)`` [Hz] (None: no filter).
    task_stiffness : (float, float), optional
        ``(k_x [N/m], k_r [N m/rad])`` in task space (default: see docs/robots.md).

    Returns
    -------
    Robot
        A :class:`seactl.System` of kind ``"robot"``.

    Raises
    ------
    InputError
        A missing or invalid URDF, a frame it does not have, a joint without an actuator,
        a ``q0`` of the wrong length, delays or filters out of range, an unknown model or
        joint, more than 7 moving joints.
    InfeasibleDesignError
        A joint whose actuator has no critically damped design at ``fn_hz`` (named).

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", q0=[0.3, 0.8], fn_hz=14,
    ...              delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...              filters_hz=(50, 100))                       # doctest: +SKIP
    >>> round(float(r.margins().phase_margin_deg), 2), bool(r.margins().stable)  # doctest: +SKIP
    (37.65, True)
    """
    from seactl.api.robotmodels import rigid_model
    from seactl.systems.robot.model import linearize

    if space not in SPACES:
        raise InputError("space", space, "one of " + ", ".join(SPACES))
    if space == "task" and task is None:
        raise InputError("task", None, "a frame of the URDF (task space needs one)")
    pin_model, q0, path, locked = rigid_model(urdf, model, joints, q0)
    body = linearize(pin_model, q0, task)
    inertia = design_inertia(body.mass_matrix)
    acts = [replace(a, joint_inertia=float(inertia[j]), joint_damping=float(body.damping[j]))
            for j, a in enumerate(_actuator_map(actuators, body.joints))]
    fn = float(finite_array("fn_hz", fn_hz, minimum=0.0, strict=True))
    g = float(finite_array("gs", gs, minimum=0.0, strict=True))
    gains = tuple(_joint_gains(a, fn, g, name) for a, name in zip(acts, body.joints))
    kq = np.array([float(x.Kq) for x in gains])
    if space == "joint":
        K, kxr = np.diag(kq), None
    else:
        K, kxr = _task_stiffness(body, kq, task_stiffness)
    t_tau, t_qs, t_qd = delays_by_loop(delays_ms, SEA_LOOPS, ("T_tau", "T_qs", "T_qd"))
    filters = tuple(None if f is None else float(f)
                    for f in filter_cutoffs(filters_hz, ("f_qd", "f_taud")))
    delays = {"torque": float(t_tau), "stiffness": float(t_qs), "damping": float(t_qd)}
    return Robot(body, tuple(acts), gains, K, space, fn, g, delays, filters, kxr, str(path),
                 locked)


def workspace_map(urdf: str | Path | None, configurations: Any, *, backend: str = "serial",
                  workers: int | None = None, client: Any = None, **options: Any) -> Any:
    """The same robot design at each configuration: where it loses stability.

    Parameters
    ----------
    urdf : str or path
        As :func:`robot`.
    configurations : array_like or str or path
        ``(m, n)`` joint angles [rad], one row per configuration (a grid or a trajectory),
        or a trajectory's CSV file: a header of joint names and optionally ``t_s`` [s],
        one row per sample (:func:`seactl.api.robottrajectory.read_trajectory`).
    backend : {"serial", "dask"}
        The configurations one after the other in this process, or on Dask (the sweeps'
        local cluster, or ``client``); the numbers are the same
        (:mod:`seactl.api.robotsweep`).
    workers : int, optional
        Local Dask workers (default: all cores).
    client : distributed.Client, optional
        An existing Dask client (``backend="dask"``; left open).
    **options
        The other keywords of :func:`robot` (``actuators``, ``space``, ``task``, ``fn_hz``,
        ``delays_ms``, ...); the gains are designed anew at each configuration.

    Returns
    -------
    seactl.api.robotmap.WorkspaceMap
        ``stable``, ``phase_margin_deg`` and ``delay_margin_ms`` at ``outer.j1`` per
        configuration; in task space ``max_task_stiffness_n_per_m``, the largest ``k_x``
        [N/m] the certified verdict calls stable at the given delays (``k_r / k_x`` as
        given, or ``r^2`` by default; a decade scan then bisection to a relative 1e-3,
        :func:`seactl.api.robotstiffness.search_task_stiffness`), with
        ``stiffness_intervals_n_per_m`` and ``single_flip`` (False where the verdict does
        not simply flip once); ``passive``, the certified passivity of the joint impedance
        (:meth:`Robot.passivity`); ``mimo_phase_margin_deg`` and ``mimo_delay_margin_ms``,
        every stiffness channel broken at once (:meth:`Robot.mimo_margins`); ``t_s`` of a
        trajectory file; ``worst`` (the smallest ``mimo_delay_margin_ms``, an unstable
        configuration first), ``records()``, ``plot()``.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.workspace_map("examples/robots/planar_2link.urdf",
    ...                      [[0.3, 0.8], [0.0, 1.5]], fn_hz=14)   # doctest: +SKIP
    >>> m.stable.tolist()                                          # doctest: +SKIP
    [True, True]
    """
    from seactl.api.robotmap import WorkspaceMap
    from seactl.api.robotsweep import map_configurations

    q, t_s = _configurations(urdf, configurations, options)
    rows = map_configurations(None if urdf is None else str(urdf), q, options,
                              backend=backend, workers=workers, client=client)
    col = {k: [row[k] for row in rows] for k in rows[0]}
    return WorkspaceMap(rows[0]["joints"], q, np.array(col["stable"], bool),
                        np.array(col["phase_margin_deg"], float),
                        np.array(col["delay_margin_ms"], float),
                        np.array(col["max_task_stiffness_n_per_m"], float),
                        single_flip=np.array(col["single_flip"], bool),
                        stiffness_intervals_n_per_m=tuple(col["stiffness_intervals_n_per_m"]),
                        t_s=t_s, passive=_passive_column(col["passive"]),
                        mimo_phase_margin_deg=np.array(col["mimo_phase_margin_deg"], float),
                        mimo_delay_margin_ms=np.array(col["mimo_delay_margin_ms"], float))


def _passive_column(values: list) -> np.ndarray:
    """The map's ``passive`` per configuration: bool, or None where not computed (more
    than three joints: the joint impedance needs the diagram's transfers)."""
    if any(v is None for v in values):
        return np.array(values, object)
    return np.array(values, bool)


def _moving_joints(urdf: str | Path | None, options: dict[str, Any]) -> tuple[str, ...]:
    """The names of the moving joints of the robot ``workspace_map`` builds."""
    from seactl.api.robotmodels import rigid_model

    pin_model = rigid_model(urdf, options.get("model"), options.get("joints"), None)[0]
    return tuple(pin_model.names[1:])


def _configurations(urdf: str | Path | None, configurations: Any,
                    options: dict[str, Any]) -> tuple[np.ndarray, Any]:
    """The ``(m, n)`` configurations [rad] and times [s] (None) of ``workspace_map``."""
    if isinstance(configurations, (str, Path)):
        from seactl.api.robottrajectory import read_trajectory

        return read_trajectory(configurations, list(_moving_joints(urdf, options)))
    try:
        q = np.asarray(configurations, float)
    except (TypeError, ValueError):
        q = np.empty(0)
    if q.ndim != 2 or q.shape[0] == 0 or not np.all(np.isfinite(q)):
        raise InputError("configurations", configurations,
                         "an (m, n) array of joint angles [rad], one row per configuration, "
                         "or a trajectory's CSV file")
    return q, None
