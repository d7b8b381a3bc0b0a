"""The sampled loop's map over one period: its stability and modes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from seactl.base.parallel import eigvals
from seactl.errors import InputError
from seactl.simulate.discrete import (
    UNIT_CIRCLE_TOL,
    SampledPlan,
    SampledState,
    advance_plant,
    control_tick,
    sense_outputs,
)


def lifted_map(plan: SampledPlan, designs: slice = slice(None)) -> tuple[np.ndarray, float]:
    """The sampled loop's state map over ``m`` base ticks, ``(n, S, S)``, and that period
    ``m T`` [s], with ``m`` a multiple of the slowest process's period and of the delay
    buffers' length.

    The state is everything a tick carries over: plant states, the held actuation,
    controller states, held outputs of slow blocks and the delay buffers.  Each column is
    the run loop itself (:func:`sense_outputs`, :func:`control_tick`, :func:`advance_plant`) started
    from one unit state with no input, no saturation and no quantization: the linear
    loop the simulation runs while no limit is reached.  Without friction only;
    ``designs`` selects part of the batch.
    """
    if plan.friction:
        raise InputError("friction", "given", "a loop without friction (it is not linear)")
    nbuf = plan.nbuf[:, designs]
    m = _lifted_ticks(plan, nbuf)
    n = nbuf.shape[1]
    S = _lifted_size(plan, nbuf)

    def rep(a):  # per-design arrays (batch last), one copy per unit state
        return np.repeat(a[..., designs], S, axis=-1)

    probe = replace(
        plan, t_s=np.arange(m + 1) * plan.base_period_s, Hp=rep(plan.Hp), CDp=rep(plan.CDp),
        ABc=[rep(a) for a in plan.ABc], CDc=[rep(a) for a in plan.CDc],
        HOLD=[[rep(a) for a in row] for row in plan.HOLD],
        plant_inputs=np.zeros((m * plan.substeps + 1,) + plan.plant_inputs.shape[1:2] + (1,)),
        ctrl_inputs=np.zeros((m + 1,) + plan.ctrl_inputs.shape[1:2] + (1,)),
        x0=np.zeros((plan.x0.shape[0], n * S)), nbuf=np.repeat(nbuf, S, axis=-1),
        limit=np.full_like(plan.limit, np.inf))
    st = SampledState.start(probe, m)
    slots = _read_slots(plan, nbuf)
    unit = np.tile(np.eye(S), (1, n))       # column j: design j // S, unit state j % S
    _lifted_state(probe, st, slots, unit)
    for k in range(m):
        Sp = sense_outputs(probe, st, k)
        st.act = control_tick(probe, st, k, Sp[probe.prow["sensed"]], None)[1]
        advance_plant(probe, st, k)
    M = _lifted_state(probe, st, slots).reshape(S, n, S).transpose(1, 0, 2)
    return M, m * plan.base_period_s


def _lifted_ticks(plan: SampledPlan, nbuf: np.ndarray) -> int:
    """Ticks of the lifted map: a multiple of the slowest period covering the buffers."""
    L = int(nbuf.max(initial=0)) + 2
    return -(-L // plan.phases) * plan.phases


def _read_slots(plan: SampledPlan, nbuf: np.ndarray) -> np.ndarray:
    """Buffer slots ``(m, links)`` that are read before they are overwritten in a lifted
    period: slot ``s`` holds the value of tick ``s - m`` and link ``l`` reads it at tick
    ``s - m + nbuf``.  The others never matter (their columns of the map are zero), so the
    state leaves them out; the largest buffer of the batch decides, per link."""
    m = _lifted_ticks(plan, nbuf)
    return np.arange(m)[:, None] >= m - nbuf.max(axis=1, initial=0)[None, :]


def _lifted_size(plan: SampledPlan, nbuf: np.ndarray) -> int:
    """Length of the carried-over state (:func:`_lifted_state`)."""
    sizes = [plan.zp["x"], plan.zp["act"], plan.zc["x"], plan.zc["held"]]
    return sum(sl.stop - sl.start for sl in sizes) + int(_read_slots(plan, nbuf).sum())


def _lifted_state(plan: SampledPlan, st: SampledState, slots: np.ndarray,
                  set_to: np.ndarray | None = None) -> np.ndarray:
    """The carried-over state (the buffers' ``slots`` only) packed as rows ``(S, columns)``;
    with ``set_to``, set it."""
    parts = [(st.zp, plan.zp["x"]), (st.act, slice(None)), (st.zc, plan.zc["x"]),
             (st.zc, plan.zc["held"])]
    if set_to is not None:
        i = 0
        for arr, sl in parts:
            k = arr[sl].shape[0]
            arr[sl] = set_to[i:i + k]
            i += k
        st.ring[slots] = set_to[i:]
    return np.concatenate([arr[sl] for arr, sl in parts] + [st.ring[slots]], axis=0)


def period_map(plan: SampledPlan, designs: slice = slice(None), inputs: bool = False
               ) -> tuple[np.ndarray, ...]:
    """The sampled loop as a discrete-time state space over one period of its slowest
    process (``plan.phases`` base ticks; one tick when every process runs at one rate).

    The state ``x`` (length ``S``) is what a tick carries over: plant states, the held
    actuation, controller states, held outputs of slow blocks, then per delayed block the
    source values of the last ``J`` ticks (``J`` its longest buffer in the batch; a shift
    register, newest first).  Each column is the run loop itself (:func:`sense_outputs`,
    :func:`control_tick`, :func:`advance_plant`) started from one unit state, with no
    saturation and no quantization, as in :func:`lifted_map`.  Returns ``(A, period_s)``
    with ``A`` of shape ``(n, S, S)``; with ``inputs`` (one-rate loops only) also the
    exogenous controller inputs (``plan.info["controller_inputs"]``) and the recorded
    outputs (``plan.order``) at the period's first tick: ``(A, B, C, D, period_s)`` with
    ``x+ = A x + B u``, ``y = C x + D u``.  Without friction only.
    """
    if plan.friction:
        raise InputError("friction", "given", "a loop without friction (it is not linear)")
    P = plan.phases
    if inputs and P != 1:
        raise InputError("rates_hz", plan.info["rates_hz"], "one rate for every process "
                         "(a multi-rate loop is periodic, not time-invariant)")
    nbuf = plan.nbuf[:, designs]
    n = nbuf.shape[1]
    J = nbuf.max(axis=1, initial=0)
    parts = [plan.zp["x"], plan.zp["act"], plan.zc["x"], plan.zc["held"]]
    S0 = sum(sl.stop - sl.start for sl in parts)
    S = S0 + int(J.sum())
    nu = (plan.zc["uc"].stop - plan.zc["uc"].start) if inputs else 0
    K = S + nu
    L = int(J.max(initial=0)) + P + 1

    def rep(a):  # per-design arrays (batch last), one copy per probe column
        return np.repeat(a[..., designs], K, axis=-1)

    cin = np.zeros((P + 1, plan.ctrl_inputs.shape[1], n * K))
    if nu:
        cin[0][:, (np.arange(n)[:, None] * K + S + np.arange(nu)).ravel()] = \
            np.tile(np.eye(nu), (1, n))
    probe = replace(
        plan, t_s=np.arange(P + 1) * plan.base_period_s, Hp=rep(plan.Hp), CDp=rep(plan.CDp),
        ABc=[rep(a) for a in plan.ABc], CDc=[rep(a) for a in plan.CDc],
        HOLD=[[rep(a) for a in row] for row in plan.HOLD],
        plant_inputs=np.zeros((P * plan.substeps + 1,) + plan.plant_inputs.shape[1:2] + (1,)),
        ctrl_inputs=cin, x0=np.zeros((plan.x0.shape[0], n * K)),
        nbuf=np.repeat(nbuf, K, axis=-1), limit=np.full_like(plan.limit, np.inf))
    st = SampledState.start(probe, L)
    unit = np.tile(np.eye(S, K), (1, n))   # column j: design j // K, unit state j % K
    _shift_state(probe, st, J, 0, unit)
    y = None
    for k in range(P):
        Sp = sense_outputs(probe, st, k)
        Sc, st.act = control_tick(probe, st, k, Sp[probe.prow["sensed"]], None)
        if k == 0:
            y = np.concatenate([Sp[probe.prow["out"]], Sc[probe.crow["out"]]], axis=0)
        advance_plant(probe, st, k)
    M = _shift_state(probe, st, J, P).reshape(S, n, K).transpose(1, 0, 2)
    period = P * plan.base_period_s
    if not inputs:
        return M, period
    Y = y.reshape(-1, n, K).transpose(1, 0, 2)
    return M[..., :S], M[..., S:], Y[..., :S], Y[..., S:], period


def _shift_state(plan: SampledPlan, st: SampledState, J: np.ndarray, k: int,
                 set_to: np.ndarray | None = None) -> np.ndarray:
    """The state of :func:`period_map` before tick ``k``, rows ``(S, columns)``: the
    carried-over vectors, then per link the source values of ticks ``k-1 .. k-J`` (ring
    slot ``(k - j) % L``); with ``set_to``, set it."""
    parts = [(st.zp, plan.zp["x"]), (st.act, slice(None)), (st.zc, plan.zc["x"]),
             (st.zc, plan.zc["held"])]
    L = st.ring.shape[0]
    regs = [(j, int(J[j])) for j in range(len(J))]
    if set_to is not None:
        i = 0
        for arr, sl in parts:
            m = arr[sl].shape[0]
            arr[sl] = set_to[i:i + m]
            i += m
        for link, depth in regs:
            for j in range(1, depth + 1):
                st.ring[(k - j) % L, link] = set_to[i]
                i += 1
    out = [arr[sl] for arr, sl in parts]
    out += [st.ring[(k - j) % L, link][None] for link, depth in regs
            for j in range(1, depth + 1)]
    return np.concatenate(out, axis=0)


def sampled_unstable_modes(plan: SampledPlan) -> np.ndarray:
    """Per design, the number of the lifted map's eigenvalues outside the unit circle
    (:func:`lifted_map`): 0 means the linear sampled loop is stable, ``k > 0`` that ``k``
    modes grow (however slowly), -1 undecided (an eigenvalue within
    :data:`UNIT_CIRCLE_TOL` of the circle, not finite, a loop with friction, or a batch
    whose maps would take more than a few seconds: designs x S^3 > 1e9).

    Continuous-time counterpart: the right half-plane of ``s = ln(lambda) / (m T)``.

    Examples
    --------
    >>> import numpy as np
    >>> from seactl.systems.sea.actuators import UT_SEA
    >>> from seactl.systems.sea.design import critically_damped_gains
    >>> from seactl.systems.sea.loops import SEADesign, Timing, sea_diagram
    >>> from seactl.simulate.discrete import compile_sampled
    >>> from seactl.simulate.inputs import Step
    >>> from seactl.simulate.discrete import compile_sampled
    >>> from seactl.simulate.inputs import Step
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, np.array([30.05, 30.2])),
    ...               Timing.from_ms(0.5, 10.5, 0.5, 50, 100))
    >>> plan = compile_sampled(sea_diagram(True), d, {"q_des": Step(1.0)}, 0.1, ("q_j",))
    >>> sampled_unstable_modes(plan).tolist()
    [0, 2]
    """
    n = plan.x0.shape[1]
    S = _lifted_size(plan, plan.nbuf)
    if plan.friction or n * float(S) ** 3 > _LIFTED_WORK:
        return np.full(n, -1)
    chunk = max(1, _LIFTED_COLUMNS // S)
    return np.concatenate([_unstable_modes(plan, slice(i, i + chunk))
                           for i in range(0, n, chunk)])


_LIFTED_COLUMNS = 20_000
"""Designs x unit states probed at once (bounds the probe's memory to tens of MB)."""
_LIFTED_WORK = 1e9
"""Designs x S^3 above which the count is not attempted (-1): a bound on one call's
eigenvalue work (S = 45 for a 30 ms buffer at 1 kHz: 11,000 designs; S = 1000, a 1 s
buffer: none)."""


def _unstable_modes(plan: SampledPlan, designs: slice) -> np.ndarray:
    with np.errstate(all="ignore"):
        M = lifted_map(plan, designs)[0]
        ok = np.all(np.isfinite(M), axis=(1, 2))
        lam = np.abs(eigvals(np.where(ok[:, None, None], M, 0.0)))
    near = np.any(np.abs(lam - 1.0) <= UNIT_CIRCLE_TOL, axis=1) | ~ok
    return np.where(near, -1, np.sum(lam > 1.0, axis=1))
