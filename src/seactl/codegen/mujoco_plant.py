"""MuJoCo as the plant: the sampled controllers of seactl closed around ``mj_step``.

:class:`MujocoPlant` steps a :class:`~seactl.codegen.mjcf.PlantModel` over one controller
period (the command held, ``substeps`` MuJoCo steps) and reads the sensed signals; it is
the plant process of ``seactl run --plant mujoco`` and of :func:`simulate_mujoco`, which
closes seactl's own sampled controller (:func:`seactl.simulate.discrete.control_tick`:
the same processes, rates, delay buffers and current limit as ``mode="sampled"``) around
it in one process, without messages.  MuJoCo (the ``sim`` extra) is imported when a plant
is built, never when this module is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.codegen.mjcf import PlantModel, plant_model
from seactl.errors import InputError


def import_mujoco() -> Any:
    """The ``mujoco`` module, or an :class:`InputError` saying how to install it."""
    try:
        import mujoco
    except ImportError as exc:
        raise InputError("plant", "mujoco", "the builtin plant, or install MuJoCo "
                         f"(pip install 'seactl[sim]'): {exc}") from None
    return mujoco


class MujocoPlant:
    """A MuJoCo model stepped one controller period at a time.

    Parameters
    ----------
    model : PlantModel
        The MJCF and its signal map.
    period_s : float
        The controller's base period [s]; a whole number of ``model.timestep_s``.
    sensed : sequence of str
        The sensed signals :meth:`sense` returns, in this order.
    actuation : sequence of str
        The actuation signals :meth:`advance` takes, in this order.
    inputs : sequence of str
        The physical inputs :meth:`advance` takes, in this order.
    qpos0 : array_like, optional
        The starting positions (MuJoCo's ``qpos``, default zeros): the operating point,
        the origin of the sensed signals (the diagram's signals are deviations from it).
    """

    def __init__(self, model: PlantModel, period_s: float, sensed: Sequence[str],
                 actuation: Sequence[str], inputs: Sequence[str] = (), qpos0: Any = None):
        mj = import_mujoco()
        self.mj = mj
        self.model = model
        self.m = mj.MjModel.from_xml_string(model.xml)
        self.d = mj.MjData(self.m)
        self.qpos0 = np.zeros(self.m.nq) if qpos0 is None else np.asarray(qpos0, float)
        self.d.qpos[:] = self.qpos0
        n = period_s / model.timestep_s
        if not (n >= 1 and abs(n - round(n)) <= 1e-6 * n):
            raise InputError("timestep_s [s]", model.timestep_s,
                             f"a whole fraction of the base period {period_s:g} s")
        self.substeps = int(round(n))
        self.S = np.zeros((len(sensed), self.m.nq))
        for i, s in enumerate(sensed):
            if s not in model.sensed:
                raise InputError("sensed", s, "a signal of the MuJoCo model: "
                                 + ", ".join(model.sensed))
            for joint, c in model.sensed[s]:
                self.S[i, self.m.jnt_qposadr[self.m.joint(joint).id]] += c
        self.act = [self._actuator(model.actuation, s, "actuation") for s in actuation]
        self.inp = [self._actuator(model.inputs, s, "inputs") for s in inputs]

    def _actuator(self, table: Mapping[str, tuple[str, float]], signal: str,
                  what: str) -> tuple[int, float]:
        if signal not in table:
            raise InputError(what, signal, "a signal of the MuJoCo model: " + ", ".join(table))
        name, factor = table[signal]
        return self.m.actuator(name).id, factor

    def sense(self) -> np.ndarray:
        """The sensed signals at the current time (from the starting positions)."""
        return self.S @ (self.d.qpos - self.qpos0)

    def advance(self, actuation: Sequence[float], inputs: Sequence[float] = ()) -> None:
        """Hold ``actuation`` and ``inputs`` over one period; MuJoCo clips each control to
        its range (the current limit)."""
        for (i, f), v in zip(self.act, actuation):
            self.d.ctrl[i] = f * v
        for (i, f), v in zip(self.inp, inputs):
            self.d.ctrl[i] = f * v
        for _ in range(self.substeps):
            self.mj.mj_step(self.m, self.d)

    def kick(self, impulses: Sequence[float]) -> None:
        """Impulses of the physical inputs at ``t = 0``: ``qvel += M^-1 J^T p``."""
        self.mj.mj_forward(self.m, self.d)
        f = np.zeros(self.m.nv)
        for (i, fac), p in zip(self.inp, impulses):
            f[self.m.actuator_trnid[i, 0]] += fac * p * self.m.actuator_gear[i, 0]
        dv = np.zeros(self.m.nv)
        self.mj.mj_solveM(self.m, self.d, dv.reshape(1, -1), f.reshape(1, -1))
        self.d.qvel[:] += dv


@dataclass(frozen=True)
class MujocoRun:
    """A closed-loop response on the MuJoCo plant.

    Attributes
    ----------
    t_s : ndarray
        Tick times [s] (the fastest process's period).
    outputs : dict
        Signal -> its value at each tick: plant signals read from MuJoCo, the actuation
        as commanded (before MuJoCo's clipping to the current limit).
    info : dict
        ``substeps`` per period, ``timestep_s``, ``integrator``, ``rates_hz``,
        ``effective_delays_s``.
    """

    t_s: np.ndarray
    outputs: dict[str, np.ndarray]
    info: dict[str, Any]


def plant_signals(diagram: Any) -> tuple[list[str], list[str], list[str]]:
    """The diagram's sensed signals, actuation signals and physical inputs, in the
    order of the sampled plan (sorted)."""
    plant = [b for b in diagram.blocks if b.role == "plant"]
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    plant_sig, ctrl_sig = {b.dst for b in plant}, {b.dst for b in ctrl}
    return (sorted({b.src for b in ctrl if b.src in plant_sig}),
            sorted({b.src for b in plant if b.src in ctrl_sig}),
            sorted({b.src for b in plant if b.src in diagram.inputs}))


def simulate_mujoco(diagram: Any, design: Any, inputs: Mapping[str, Any], t_end_s: float, *,
                    outputs: Sequence[str] = (), rates_hz: Any = 1000.0,
                    saturation: Mapping[str, float] | None = None, substeps: int = 10,
                    integrator: str = "RK4", timing: Any = None) -> MujocoRun:
    """Closed-loop response of one design with MuJoCo as the plant (module docstring).

    Parameters
    ----------
    diagram, design
        An SEA or rigid-actuator diagram and a single design (``System.diagram_for()``,
        ``System.design``).
    inputs : mapping
        Signal -> :class:`~seactl.simulate.inputs.Step` (references or physical inputs)
        or :class:`~seactl.simulate.inputs.Impulse` (physical inputs).
    t_end_s : float
        Simulated time [s].
    outputs : sequence of str
        Plant or controller signals to record.
    rates_hz, saturation
        As for the sampled simulation (``System.saturation()``).
    substeps : int
        MuJoCo steps per base period (the timestep is the period over ``substeps``).
    integrator : str
        MuJoCo's integrator (:data:`seactl.codegen.mjcf.INTEGRATORS`).
    timing : object, optional
        Time-varying timing of some delayed blocks, as the sampled simulation's
        (:func:`seactl.simulate.engine.simulate`: ``blocks`` and ``schedules(plan)``, e.g.
        :class:`seactl.latency.montecarlo.LinkTiming` with one run); default: the
        design's fixed delays.

    Returns
    -------
    MujocoRun
        The recorded signals per tick.
    """
    if int(np.prod(getattr(design, "shape", ()), dtype=int)) != 1:
        raise InputError("design", f"batch of shape {design.shape}", "a single design")
    if not (isinstance(substeps, (int, np.integer)) and 1 <= substeps <= 10_000):
        raise InputError("substeps", substeps, "an integer in [1, 10000]")
    plan, signals = sampled_plan(diagram, design, inputs, t_end_s, outputs, rates_hz,
                                 saturation, buffered=timing.blocks if timing else ())
    Tb = plan.base_period_s
    plant = MujocoPlant(plant_model(design, Tb / substeps, integrator), Tb, *signals)
    return close_loop(plan, plant, signals, inputs, outputs, timing=timing)


def sampled_plan(diagram: Any, design: Any, inputs: Mapping[str, Any], t_end_s: float,
                 outputs: Sequence[str], rates_hz: Any,
                 saturation: Mapping[str, float] | None, buffered: Sequence[str] = ()
                 ) -> tuple[Any, tuple]:
    """The sampled controller's plan (:func:`seactl.simulate.discrete.compile_sampled`;
    ``buffered``: the delayed blocks given a time-varying timing) and the plant's signals
    ``(sensed, actuation, inputs)`` (:func:`plant_signals`); ``outputs`` may not name a
    plant signal MuJoCo does not sense."""
    from seactl.simulate.discrete import compile_sampled

    sensed, actuation, exo = plant_signals(diagram)
    plant_only = {b.dst for b in diagram.blocks if b.role == "plant"} - set(sensed)
    for o in outputs:
        if o in plant_only:
            raise InputError("outputs", o, "a sensed, actuation or controller signal: "
                             + ", ".join(sensed + actuation))
    ctrl_out = [o for o in outputs if o not in sensed and o not in actuation]
    plan = compile_sampled(diagram, design, inputs, t_end_s, ctrl_out, rates_hz=rates_hz,
                           saturation=saturation, buffered=tuple(buffered))
    return plan, (sensed, actuation, exo)


def close_loop(plan: Any, plant: MujocoPlant, signals: tuple, inputs: Mapping[str, Any],
               outputs: Sequence[str], timing: Any = None) -> MujocoRun:
    """Run the sampled controller of ``plan`` against ``plant`` tick by tick: sense, one
    controller tick (:func:`seactl.simulate.discrete.control_tick`, with ``timing``'s
    schedules if given), hold the actuation and the physical inputs over one period of
    MuJoCo steps."""
    from seactl.simulate.discrete import control_tick, start_timed
    from seactl.simulate.inputs import Impulse

    sensed, actuation, exo = signals
    ctrl_out = [o for o in outputs if o not in sensed and o not in actuation]
    kicks = [inputs[e].area if isinstance(inputs.get(e), Impulse) else 0.0 for e in exo]
    if any(kicks):
        plant.kick(kicks)
    exo_t = [inputs[e] if e in inputs and not isinstance(inputs[e], Impulse) else None
             for e in exo]
    st, sched = start_timed(plan, timing.schedules(plan) if timing is not None else None)
    rec = {o: np.empty(plan.steps + 1) for o in outputs}
    for k in range(plan.steps + 1):
        ys = plant.sense()
        Sc, act = control_tick(plan, st, k, ys[:, None], sched)
        for o in outputs:
            if o in sensed:
                rec[o][k] = ys[sensed.index(o)]
            elif o in actuation:
                rec[o][k] = act[actuation.index(o), 0]
            else:
                rec[o][k] = Sc[plan.crow["out"].start + ctrl_out.index(o), 0]
        if k < plan.steps:
            u = [0.0 if f is None else float(np.ravel(f(np.array(plan.t_s[k])))[0])
                 for f in exo_t]
            plant.advance(act[:, 0], u)
    info = {"substeps": plant.substeps, "timestep_s": plant.model.timestep_s,
            "integrator": plant.model.integrator,
            "rates_hz": plan.info["rates_hz"],
            "effective_delays_s": {b: float(np.ravel(v)[0])
                                   for b, v in plan.info["effective_delays_s"].items()}}
    return MujocoRun(plan.t_s, rec, info)
