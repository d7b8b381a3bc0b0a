"""Time-domain simulation of block diagrams with exact delays: continuous and sampled.

The simulator is *compiled from the block diagram* (:mod:`seactl.diagram.blockdiagram`),
the same description every frequency-domain view is derived from, so the time
and frequency domains cannot drift apart.  Any diagram works (the SEA loop of
:mod:`seactl.systems.sea.loops`, a rigid actuator, ...), with any design object whose
attributes are arrays broadcast to ``design.shape``; the whole batch is
simulated in one vectorized call (batch axis first, one Python loop over time
steps only).

Compilation
-----------
Each block ``num(s)/den(s) e^{-sT}`` is realized in controllable canonical
form (batched over designs).  Signals are sums of block outputs, so the
undelayed part of the diagram is one linear-algebraic system solved once per
design (``(I - P)^{-1}``, the feed-through network), which leaves a batched
state space ``x' = A x + B v``, ``S = C x + D v`` whose inputs ``v`` are the
exogenous inputs and the *delayed* block inputs.  Delayed inputs are read from
delay buffers holding the past values of their source signals.

Each mode is a compile step returning a plan (:class:`ContinuousPlan`,
:class:`SampledPlan`: batched matrices plus a :class:`Layout` naming the slices
of every packed vector) and a run loop over time steps (:func:`run_continuous`,
:func:`run_sampled`); :func:`simulate` does both.

Modes
-----
``continuous``
    Fixed step ``dt`` (default ``min(1e-4 s, smallest positive delay)``).  The
    linear part is integrated *exactly* between steps for inputs linear over a
    step (first-order hold, batched matrix exponential of an augmented matrix,
    :func:`expm_batched`); delayed inputs are linearly interpolated
    in the buffers (exact when the delays are multiples of ``dt``, second order
    otherwise).  Without delays a step response is exact to rounding.  An
    unfiltered derivative (a denominator whose leading coefficient is 0, e.g.
    ``Tf_qd = 0``) is improper and has no state-space realization; it is
    realized with leading coefficient ``derivative_tau_s`` (default 1e-7 s) times
    the next one, i.e. a roll-off at 1.6 MHz, far above any loop dynamics.  Such a
    derivative's output is a difference of nearly equal numbers, so a loop with
    unfiltered derivatives carries rounding of about 1e-5 of its response (the
    overshoot of Fig. GainScale(b) moves by 0.003 points between BLAS kernels);
    with filters the rounding is about 1e-14.
``sampled``
    What runs on the robot.  Blocks with ``role="plant"`` form a continuous
    plant integrated exactly (zero-order hold on the actuation signals,
    first-order hold on exogenous physical inputs) between ticks.  Controller
    and sensor blocks run in discrete time: each controller block belonging to
    a process runs at that process's rate (``rates_hz``, default 1 kHz for
    all) with its output held between its updates; derivatives and filters are
    discretized with the bilinear (Tustin) transform ``s = 2/T (z-1)/(z+1)``
    (which keeps unfiltered derivatives proper).  Sensors sample the plant at
    the tick, the actuation is computed at once and held (zero-order hold), so
    every feedback path sees ``T_s/2`` of effective delay; a block with delay
    ``T`` reads a buffer ``n = max(ceil((T - T_s/2)/T_s), 0)`` samples old
    (:func:`buffer_samples`), so that the effective delay ``T_s/2 + n T_s`` of the paper
    is the shortest realizable one that is not shorter than ``T`` (e.g. 1 ms at 1 kHz gives
    1.5 ms, at 500 Hz or 2 kHz exactly 1 ms); a delay is never shortened.  The effective
    delays used are returned in :attr:`SimResult.info`.  Optional: saturation of actuation signals
    (``saturation``), quantization of sampled plant signals (``quantization``)
    and Coulomb plus viscous friction (:class:`Friction`), integrated with a
    fixed sub-step ``T_s / friction_substeps`` with the friction force held
    over each sub-step.  All off unless given.

Inputs are :class:`Step`, :class:`Sine`, :class:`Impulse` (a Dirac at ``t = 0``,
applied exactly as a state jump) or any callable ``f(t) -> values``.
A design whose first recorded output leaves ``bound`` is reported unstable with the
time it left (its states are then frozen, so there is never an overflow or a
NaN); a response not decaying at the end of the window (slow divergence, or a
limit cycle bounded by saturation) is also reported unstable (``left_bounds_s``
stays ``inf`` for it).

Use for another diagram (e.g. a rigid actuator)::

    res = simulate(RIGID_DIAGRAM, design, {"x_des": Step(0.004)}, t_end_s=0.5,
                   mode="sampled", rates_hz={"embedded": 1000, "high-level": 1000},
                   outputs=("x",), saturation={"i_m": 30.0})

Examples
--------
A unity-feedback integrator ``1/s`` with gain 10 (closed loop ``10/(s+10)``):

>>> import numpy as np
>>> from types import SimpleNamespace
>>> from seactl.diagram.blockdiagram import Block, BlockDiagram
>>> from seactl.simulate.inputs import Step
>>> from seactl.simulate.inputs import Step
>>> d = BlockDiagram("int", [
...     Block("ref", "r", "e"), Block("fb", "y", "e", num=lambda p: (-1.0,)),
...     Block("ctrl", "e", "u", num=lambda p: (p.K,)),
...     Block("plant", "u", "y", den=lambda p: (1.0, 0.0), role="plant")])
>>> p = SimpleNamespace(K=np.array([10.0, 20.0]), shape=(2,))
>>> res = simulate(d, p, {"r": Step()}, t_end_s=0.1, outputs=("y",), dt=1e-3)
>>> y = res.outputs["y"]
>>> bool(np.allclose(y[:, -1], 1 - np.exp(-p.K * 0.1), atol=1e-12))
True
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import BlockDiagram
from seactl.errors import InputError
from seactl.simulate.continuous import compile_continuous, run_continuous
from seactl.simulate.discrete import compile_sampled, run_sampled
from seactl.simulate.inputs import Friction
from seactl.simulate.network import default_bound, growing
from seactl.simulate.period import sampled_unstable_modes
from seactl.simulate.results import SimResult

MODES = ("continuous", "sampled")


# ----------------------------------------------------------------------------- simulate
def simulate(diagram: BlockDiagram, design: Any, inputs: Mapping[str, Any], t_end_s: float, *,
             mode: str = "continuous", outputs: Sequence[str] = (), dt: float | None = None,
             record_dt: float | None = None, rates_hz: Mapping[str, float] | float = 1000.0,
             saturation: Mapping[str, float] | None = None,
             quantization: Mapping[str, float] | None = None, friction: Friction | None = None,
             friction_substeps: int = 10, bound: float | None = None,
             derivative_tau_s: float = 1e-7, timing: Any = None) -> SimResult:
    """Simulate ``diagram`` for a batch of designs (see the module docstring).

    Parameters
    ----------
    diagram : BlockDiagram
    design : object
        Attributes used by the blocks (arrays broadcast to ``design.shape``).
    inputs : mapping
        Exogenous signal name -> :class:`Step`, :class:`Sine`, :class:`Impulse` or
        ``f(t) -> values`` (broadcast to ``design.shape + t.shape``); missing inputs are 0.
    t_end_s : float
        Simulated duration [s].
    mode : ``"continuous"`` or ``"sampled"``.
    outputs : signal names to record (default: every signal fed only by plant blocks).
    dt : continuous step [s] (default ``min(1e-4, smallest positive delay)``).
    record_dt : recording interval [s] (continuous; default ``dt``, rounded to a multiple).
    rates_hz : servo rate [Hz] per process (a number: every process), sampled mode.
    saturation : actuation signal -> symmetric limit (sampled mode).
    quantization : sampled plant signal -> quantum (sampled mode).
    friction : :class:`Friction` (sampled mode), sub-step ``T_s/friction_substeps``.
    bound : divergence bound on the first recorded output (default 1e3 x the largest input
        scale); the first output is also the one checked for growth at the end.
    derivative_tau_s : roll-off of unfiltered derivatives in continuous mode [s].
    timing : object, optional
        Time-varying latency and message loss (sampled mode; see :mod:`seactl.latency.montecarlo`):
        ``timing.blocks`` names the delayed blocks it drives (compiled to always read
        their buffers) and ``timing.schedules(plan)`` returns, per block, the source tick
        each tick uses (see :func:`run_sampled`).

    Returns
    -------
    SimResult
    """
    t_end_s, outputs = _check_args(diagram, inputs, mode, t_end_s, outputs)
    shape = tuple(getattr(design, "shape", ()))
    bound = default_bound(inputs) if bound is None else float(bound)
    if mode == "continuous":
        if saturation or quantization or friction or timing is not None:
            raise InputError("mode", mode, "'sampled' for saturation, quantization, friction "
                             "or timing")
        plan = compile_continuous(diagram, design, inputs, t_end_s, outputs, dt=dt,
                                  record_dt=record_dt, derivative_tau_s=derivative_tau_s)
        res = run_continuous(plan, bound)
    else:
        plan = compile_sampled(diagram, design, inputs, t_end_s, outputs, rates_hz=rates_hz,
                               saturation=saturation, quantization=quantization,
                               friction=friction, friction_substeps=friction_substeps,
                               buffered=timing.blocks if timing is not None else ())
        res = run_sampled(plan, bound, timing.schedules(plan) if timing is not None else None)
        if timing is None:  # time-varying timing has no fixed lifted map
            res.info["unstable_modes"] = sampled_unstable_modes(plan).reshape(shape)
    scale = max(bound / 1e3, 1e-300)
    grow = growing(res.outputs[outputs[0]], scale)
    stable = np.isinf(res.left_bounds_s) & ~grow
    out = {o: res.outputs[o].reshape(shape + (res.t_s.size,)) for o in outputs}
    return SimResult(mode, res.t_s, out, stable.reshape(shape), res.left_bounds_s.reshape(shape),
                     bound, res.info)


def _check_args(diagram: BlockDiagram, inputs: Mapping[str, Any], mode: str, t_end_s: float,
                outputs: Sequence[str]) -> tuple[float, tuple[str, ...]]:
    """Validate mode, duration and input names; the outputs to record (default: plant
    signals)."""
    if mode not in MODES:
        raise InputError("mode", mode, " or ".join(MODES))
    from seactl.base.limits import check_range

    t_end_s = check_range("t_end_s", t_end_s, "t_end_s")
    unknown = set(inputs) - set(diagram.inputs)
    if unknown:
        raise InputError("inputs", ", ".join(sorted(unknown)),
                         "exogenous signals of the diagram: " + ", ".join(diagram.inputs))
    plant_signals = {b.dst for b in diagram.blocks if b.role == "plant"}
    if not outputs:
        outputs = tuple(s for s in diagram.signals if s in plant_signals)
    for o in outputs:
        if o not in diagram.signals:
            raise InputError("outputs", o, "signals of the diagram: " + ", ".join(diagram.signals))
    return t_end_s, tuple(outputs)
