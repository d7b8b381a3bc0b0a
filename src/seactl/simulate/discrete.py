"""The sampled mode: processes at their rates, whole-sample delay buffers."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.limits import check_delay_buffers
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.errors import InputError
from seactl.simulate.continuous import check_size, fill_diverged
from seactl.simulate.inputs import Friction
from seactl.simulate.network import (
    BlockNet,
    assemble_blocks,
    delay_attr,
    foh,
    impulse_vector,
    input_values,
)
from seactl.simulate.realize import realize_continuous, realize_tustin
from seactl.simulate.results import Layout, RunOutputs, batch_last


# ----------------------------------------------------------------------------- sampled
def process_rates(rates_hz, processes) -> dict[str, float]:
    if isinstance(rates_hz, Mapping):
        missing = [p for p in processes if p not in rates_hz]
        if missing:
            raise InputError("rates_hz", dict(rates_hz), "a rate for every process: "
                             + ", ".join(processes))
        rates = {p: float(rates_hz[p]) for p in processes}
    else:
        rates = {p: float(rates_hz) for p in processes}
    for p, r in rates.items():
        if not (math.isfinite(r) and r > 0):
            raise InputError(f"rate ({p})", r, "a finite rate > 0 [Hz]")
    return rates


def tick_plan(rates: Mapping[str, float]) -> tuple[float, dict[str, int]]:
    """Base period [s] (fastest rate) and each process's period in base ticks."""
    base = max(rates.values())
    ticks = {}
    for p, r in rates.items():
        k = base / r
        if abs(k - round(k)) > 1e-9:
            raise InputError(f"rate ({p})", r,
                             f"an integer divisor of the fastest rate {base:g} Hz")
        ticks[p] = int(round(k))
    return 1.0 / base, ticks


@dataclass(frozen=True)
class _PlantNet:
    """The continuous plant: its network, the signals it injects and exposes."""

    net: BlockNet
    index: dict[str, int]
    actuation: list[str]
    exo: list[str]
    sensed: list[str]


def _plant_network(diagram: BlockDiagram, design: Any, shape: tuple[int, ...], n: int,
                   saturation: Mapping[str, float], quantization: Mapping[str, float],
                   friction: Friction | None) -> _PlantNet:
    """Plant network: injections = actuation signals, exogenous physical inputs, friction."""
    plant = [b for b in diagram.blocks if b.role == "plant"]
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    if not plant:
        raise ValueError(f"diagram {diagram.name!r} has no plant blocks")
    if any(b.delay is not None for b in plant):
        raise ValueError("sampled mode: delays on plant blocks are not supported")
    plant_sig = {b.dst for b in plant}
    ctrl_sig = {b.dst for b in ctrl}
    actuation = sorted({b.src for b in plant if b.src in ctrl_sig})
    for s in saturation:
        if s not in actuation:
            raise InputError("saturation", s, "an actuation signal: " + ", ".join(actuation))
    p_exo = sorted({b.src for b in plant if b.src in diagram.inputs})
    p_inject = actuation + p_exo + ([friction.signal] if friction else [])
    p_signals = sorted(plant_sig | set(p_inject))
    p_reals = [realize_continuous(b, design, shape, n) for b in plant]
    pnet = assemble_blocks(n, p_signals, plant, p_reals, p_inject,
                     {b.name: np.ones(n) for b in plant}, {})
    sensed = sorted({b.src for b in ctrl if b.src in plant_sig})
    for s in quantization:
        if s not in sensed:
            raise InputError("quantization", s, "a sampled plant signal: " + ", ".join(sensed))
    return _PlantNet(pnet, {s: i for i, s in enumerate(p_signals)}, actuation, p_exo, sensed)


def buffer_samples(delay_s: Any, period_s: float) -> np.ndarray:
    """Whole samples ``n >= 0`` a delayed signal waits so that its effective delay
    ``T_s/2 + n T_s`` (zero-order hold plus buffer) is the shortest realizable one that is not
    shorter than ``delay_s``: ``n = max(ceil((T - T_s/2)/T_s), 0)``.

    A request within ``1e-9`` of a sample of a realizable delay counts as that delay, so
    that ``T = 1.5 ms`` at 1 kHz is one sample, not two, despite rounding in ``T``.

    >>> buffer_samples(np.array([0.0, 0.5e-3, 1e-3, 1.5e-3, 2.2e-3]), 1e-3).tolist()
    [0, 0, 1, 1, 2]
    """
    T = np.asarray(delay_s, float)
    return np.maximum(np.ceil((T - period_s / 2) / period_s - 1e-9), 0).astype(int)


def delay_buffers(delayed: Sequence[Block], design: Any, shape: tuple[int, ...], n: int,
             period: Mapping[str, float], ticks: Mapping[str, int]
             ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Whole-sample buffer lengths [base ticks] and effective delays [s] of delayed blocks
    (refused up front if the buffers would not fit in memory)."""
    nbuf, eff = {}, {}
    for b in delayed:
        T = delay_attr(design, b, shape, n)
        Ts = period[b.name]
        tick = ticks.get(b.process, 1)
        check_delay_buffers(n, len(delayed), float(np.max(T, initial=0.0)) / Ts * tick,
                            Ts / tick)
        nb = buffer_samples(T, Ts)
        nbuf[b.name] = nb * ticks.get(b.process, 1)  # in base ticks
        eff[b.name] = (Ts / 2 + nb * Ts).reshape(shape)
    return nbuf, eff


@dataclass(frozen=True)
class _CtrlNets:
    """Controller networks, one per phase of the slowest process's period."""

    nets: list[BlockNet]
    hold_rows: list[list[tuple[np.ndarray, np.ndarray]]]
    index: dict[str, int]
    exo: list[str]
    delayed: list[Block]
    slow: list[Block]
    nbuf: dict[str, np.ndarray]
    eff: dict[str, np.ndarray]
    period: dict[str, float]


def _controller_networks(diagram: BlockDiagram, design: Any, shape: tuple[int, ...], n: int,
                         sensed: Sequence[str], Tb: float, ticks: Mapping[str, int],
                         buffered: Sequence[str] = ()) -> _CtrlNets:
    """Injections = sampled plant signals, exogenous inputs, delayed inputs (buffers), held
    outputs of slower processes.  ``buffered``: delayed blocks always read their buffer (no
    instantaneous path even for a zero-sample buffer; time-varying latency)."""
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    period = {b.name: Tb * ticks.get(b.process, 1) for b in ctrl}
    c_exo = sorted({b.src for b in ctrl if b.src in diagram.inputs})
    c_inject = list(sensed) + c_exo
    c_signals = sorted({b.dst for b in ctrl} | set(c_inject))
    cidx = {s: i for i, s in enumerate(c_signals)}
    delayed = [b for b in ctrl if b.delay is not None]
    nbuf, eff = delay_buffers(delayed, design, shape, n, period, ticks)
    inst = {b.name: np.ones(n) for b in ctrl}
    wcol = {}
    for j, b in enumerate(delayed):
        inst[b.name] = np.zeros(n) if b.name in buffered else \
            (nbuf[b.name] == 0).astype(float)
        wcol[b.name] = len(c_inject) + j
    slow = [b for b in ctrl if ticks.get(b.process, 1) > 1]
    hcol = {b.name: len(c_inject) + len(delayed) + j for j, b in enumerate(slow)}
    c_reals = [realize_tustin(b, design, shape, n, period[b.name]) for b in ctrl]
    lcm = math.lcm(*[ticks.get(b.process, 1) for b in ctrl]) if ctrl else 1
    nets = []
    for r in range(lcm):
        held = {b.name: hcol[b.name] for b in slow if r % ticks[b.process] != 0}
        nets.append(assemble_blocks(n, c_signals, ctrl, c_reals, c_inject, inst, wcol, held,
                              nv=len(c_inject) + len(delayed) + len(slow)))

    # Held outputs of slow blocks, evaluated when they run: y_b = C_b x_b + D_b u_b.
    def block_out_rows(net: BlockNet, b: Block) -> tuple[np.ndarray, np.ndarray]:
        _A, _B, C, D = c_reals[ctrl.index(b)]
        z = inst[b.name]
        s = cidx[b.src]
        Cy = z[:, None] * D[:, None] * net.C[:, s, :]
        Cy[:, net.state_slices[b.name]] += C
        Dy = (z * D)[:, None] * net.D[:, s, :]
        if b.name in wcol:
            Dy[:, wcol[b.name]] += D * (1 - z)
        return Cy, Dy

    hold_rows = [[block_out_rows(net, b) for b in slow] for net in nets]
    return _CtrlNets(nets, hold_rows, cidx, c_exo, delayed, slow, nbuf, eff, period)


@dataclass(frozen=True)
class SampledPlan:
    """A diagram compiled for the sampled run loop (batch on the last axis).

    Packed vectors, each with a :class:`Layout`:

    * plant ``zp`` (``zp``): states ``x``, then the inputs at ``t`` (``act`` actuation,
      ``exo`` physical inputs, ``fric`` friction force) and at ``t + h`` (``next``);
      ``Hp = [F G0 G1]`` advances ``x`` by a (sub-)step ``h``; ``CDp`` gives the plant rows
      of layout ``prow`` (``sensed``, then recorded plant ``out``) from ``zp[upto fric]``;
    * controller ``zc`` (``zc``): states ``x``, sampled plant signals ``ys``, exogenous
      inputs ``uc``, delayed inputs ``w`` (buffers), held outputs of slow blocks ``held``;
      per phase ``r`` of the slowest period, ``ABc[r]`` updates ``x`` and ``CDc[r]`` gives
      the rows of layout ``crow`` (``src`` delayed sources, ``act``, recorded ``out``).
    """

    t_s: np.ndarray
    base_period_s: float
    substeps: int
    outputs: tuple[str, ...]
    order: tuple[str, ...]
    zp: Layout
    zc: Layout
    prow: Layout
    crow: Layout
    Hp: np.ndarray
    CDp: np.ndarray
    ABc: list[np.ndarray]
    CDc: list[np.ndarray]
    HOLD: list[list[np.ndarray]]
    slow_ticks: tuple[int, ...]
    plant_inputs: np.ndarray
    ctrl_inputs: np.ndarray
    x0: np.ndarray
    nbuf: np.ndarray
    limit: np.ndarray
    quantum: np.ndarray
    friction: Friction | None
    VEL: np.ndarray | None
    shape: tuple[int, ...]
    info: dict[str, Any]
    actuation: tuple[str, ...]
    links: tuple[str, ...]

    @property
    def steps(self) -> int:
        return self.t_s.size - 1

    @property
    def phases(self) -> int:
        return len(self.CDc)


def _friction_rows(pn: _PlantNet, friction: Friction | None) -> np.ndarray | None:
    """Batch-last rows giving the velocity of ``friction.velocity_of`` from ``[x; v]``."""
    if not friction:
        return None
    for s in (friction.signal, friction.velocity_of):
        if s not in pn.index:
            raise InputError("friction", s, "a plant signal")
    vrow = pn.index[friction.velocity_of]
    if np.any(pn.net.D[:, vrow, :] != 0):
        raise InputError("friction.velocity_of", friction.velocity_of,
                         "a plant signal without direct feed-through (a position)")
    C = pn.net.C[:, vrow]
    return batch_last(np.concatenate([np.einsum("nk,nkj->nj", C, pn.net.A),
                                       np.einsum("nk,nkv->nv", C, pn.net.B)], axis=1))


def _sampled_layout(pn: _PlantNet, cn: _CtrlNets, n_plant: int, friction: Friction | None,
                    outputs: Sequence[str]) -> tuple[Any, ...]:
    """Layouts of the packed plant/controller vectors and of the rows read each tick."""
    for o in outputs:
        if o not in pn.index and o not in cn.index:
            raise InputError("outputs", o, "a plant or controller signal")
    rec_p = [o for o in outputs if o in pn.index]
    rec_c = [o for o in outputs if o not in pn.index]
    na, ne, nf = len(pn.actuation), len(pn.exo), 1 if friction else 0
    zp = Layout.of(x=n_plant, act=na, exo=ne, fric=nf, next=na + ne + nf)
    nd, Nc = len(cn.delayed), cn.nets[0].A.shape[1]
    zc = Layout.of(x=Nc, ys=len(pn.sensed), uc=len(cn.exo), w=nd, held=len(cn.slow))
    prows = [pn.index[s] for s in pn.sensed] + [pn.index[o] for o in rec_p]
    crows = [cn.index[b.src] for b in cn.delayed] + [cn.index[s] for s in pn.actuation] + \
        [cn.index[o] for o in rec_c]
    return (zp, zc, Layout.of(sensed=len(pn.sensed), out=len(rec_p)),
            Layout.of(src=nd, act=na, out=len(rec_c)), prows, crows, tuple(rec_p + rec_c))


def compile_sampled(diagram: BlockDiagram, design: Any, inputs: Mapping[str, Any],
                    t_end_s: float, outputs: Sequence[str], *,
                    rates_hz: Mapping[str, float] | float = 1000.0,
                    saturation: Mapping[str, float] | None = None,
                    quantization: Mapping[str, float] | None = None,
                    friction: Friction | None = None, friction_substeps: int = 10,
                    buffered: Sequence[str] = ()) -> SampledPlan:
    """Compile ``diagram`` for :func:`run_sampled` (see :func:`simulate`); ``buffered``
    names delayed blocks whose input always comes through their buffer (timing links)."""
    saturation, quantization = dict(saturation or {}), dict(quantization or {})
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    processes = sorted({b.process for b in ctrl if b.process is not None}) or ["embedded"]
    rates = process_rates(rates_hz, processes)
    Tb, ticks = tick_plan(rates)
    pn = _plant_network(diagram, design, shape, n, saturation, quantization, friction)
    cn = _controller_networks(diagram, design, shape, n, pn.sensed, Tb, ticks, buffered)
    nsub = max(1, int(friction_substeps)) if friction else 1
    h = Tb / nsub
    F, G0, G1 = foh(pn.net.A, pn.net.B, h)
    VEL = _friction_rows(pn, friction)
    steps = int(math.ceil(t_end_s / Tb - 1e-9))
    check_size(n, steps * nsub, steps + 1, "lower the rates, shorten t_end_s, or simulate "
                "fewer designs")
    t = np.arange(steps + 1) * Tb
    if np.any(impulse_vector(inputs, cn.exo)):
        raise InputError("inputs", "impulse", "impulses only on physical (plant) inputs")
    zp, zc, prow, crow, prows, crows, order = _sampled_layout(pn, cn, F.shape[1], friction,
                                                              outputs)
    na = len(pn.actuation)
    x0 = np.zeros((zp.size, n))
    imp = impulse_vector(inputs, pn.exo)
    if np.any(imp):
        cols = na + np.nonzero(imp)[0]
        x0[zp["x"]] = np.einsum("nij,j->in", pn.net.B[:, :, cols], imp[cols - na])
    requested = {b.name: delay_attr(design, b, shape, n).reshape(shape) for b in cn.delayed}
    info = {"rates_hz": rates, "base_period_s": Tb, "requested_delays_s": requested,
            "effective_delays_s": cn.eff, "controller_inputs": tuple(cn.exo),
            "buffer_samples": {b: v.reshape(shape) for b, v in cn.nbuf.items()},
            "saturation": dict(saturation), "friction_step_s": h if friction else None}
    return SampledPlan(
        t, Tb, nsub, tuple(outputs), order, zp, zc, prow, crow,
        batch_last(np.concatenate([F, G0, G1], axis=2)),
        batch_last(np.concatenate([pn.net.C[:, prows], pn.net.D[:, prows]], axis=2)),
        [batch_last(np.concatenate([nt.A, nt.B], axis=2)) for nt in cn.nets],
        [batch_last(np.concatenate([nt.C[:, crows], nt.D[:, crows]], axis=2))
         for nt in cn.nets],
        [[batch_last(np.concatenate([cy, dy], axis=1)) for cy, dy in hr]
         for hr in cn.hold_rows],
        tuple(ticks[b.process] for b in cn.slow),
        input_values(inputs, pn.exo, np.arange(steps * nsub + 1) * h, shape, n),
        input_values(inputs, cn.exo, t, shape, n), x0,
        np.stack([cn.nbuf[b.name] for b in cn.delayed]) if cn.delayed else
        np.zeros((0, n), int),
        np.array([saturation.get(s, np.inf) for s in pn.actuation])[:, None],
        np.array([quantization.get(s, 0.0) for s in pn.sensed])[:, None],
        friction, VEL, shape, info, tuple(pn.actuation), tuple(b.name for b in cn.delayed))


@dataclass
class SampledState:
    """Mutable state of a sampled run (batch on the last axis)."""

    zp: np.ndarray
    zc: np.ndarray
    ring: np.ndarray
    act: np.ndarray
    fric: np.ndarray
    rec: np.ndarray
    left: np.ndarray
    alive: np.ndarray
    peak_act: np.ndarray
    sat_ticks: np.ndarray
    held: np.ndarray | None = None

    @classmethod
    def start(cls, plan: SampledPlan, ring_len: int) -> SampledState:
        n = plan.x0.shape[1]
        na = plan.zp["act"].stop - plan.zp["act"].start
        nf = plan.zp["fric"].stop - plan.zp["fric"].start
        nd = plan.zc["w"].stop - plan.zc["w"].start
        return cls(plan.x0.copy(), np.zeros((plan.zc.size, n)), np.zeros((ring_len, nd, n)),
                   np.zeros((na, n)), np.zeros((nf, n)),
                   np.zeros((len(plan.outputs), n, plan.steps + 1)), np.full(n, np.inf),
                   np.ones(n, bool), np.zeros((na, n)), np.zeros(n, int))


def _check_schedule(plan: SampledPlan, timing: Mapping[str, np.ndarray]) -> dict[int, np.ndarray]:
    """Validate a per-link schedule: link -> source tick used at each tick ``(T, n)``."""
    n = plan.x0.shape[1]
    out = {}
    for name, sched in timing.items():
        if name not in plan.links:
            raise InputError("timing", name, "a delayed block: " + ", ".join(plan.links))
        sched = np.asarray(sched)
        if sched.shape != (plan.steps + 1, n):
            raise InputError(f"timing[{name}] shape", sched.shape, f"{(plan.steps + 1, n)}")
        k = np.arange(plan.steps + 1)[:, None]
        if np.any(sched > k) or np.any(np.diff(sched, axis=0) < 0):
            raise InputError(f"timing[{name}]", "schedule", "non-decreasing source ticks "
                             "no later than the tick that uses them")
        j = plan.links.index(name)
        col = plan.zc["w"].start + j
        src = plan.crow["src"].start + j
        if any(np.any(cd[src, col] != 0) for cd in plan.CDc):
            raise InputError("timing", name, "a delayed block whose source does not depend "
                             "instantly on its own output")
        out[j] = sched
    return out


def _oldest_arrival(sched: Mapping[int, np.ndarray] | None) -> int:
    """Largest age [ticks] of a message when it arrives (how long buffers must be)."""
    age = 0
    for s in (sched or {}).values():
        prev = np.vstack([np.full((1, s.shape[1]), -1), s[:-1]])
        k = np.arange(s.shape[0])[:, None]
        age = max(age, int(np.max(np.where(s > prev, k - s, 0), initial=0)))
    return age


def _read_fixed(plan: SampledPlan, st: SampledState, k: int) -> np.ndarray:
    """Delayed inputs from whole-sample buffers: the source value ``nbuf`` ticks ago."""
    L, nd, n = st.ring.shape
    flat = st.ring.reshape(-1)
    return flat[((k - plan.nbuf) % L) * (nd * n) + np.arange(nd * n).reshape(nd, n)]


def _read_timed(plan: SampledPlan, st: SampledState, k: int,
                sched: Mapping[int, np.ndarray]) -> np.ndarray:
    """Fixed buffers, except links with a schedule: the newest message that has arrived
    (its source tick), or the last value held when nothing new arrived."""
    w = _read_fixed(plan, st, k)
    L = st.ring.shape[0]
    cols = np.arange(st.ring.shape[2])
    for j, s in sched.items():
        src = s[k]
        new = src > (s[k - 1] if k else -1)
        st.held[j] = np.where(new, st.ring[src % L, j, cols], st.held[j])
        w[j] = st.held[j]
    return w


def control_tick(plan: SampledPlan, st: SampledState, k: int, ys: np.ndarray,
             sched: Mapping[int, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """One controller tick: returns the controller rows and the (clipped) actuation."""
    zc, lay, r = st.zc, plan.zc, k % plan.phases
    L = st.ring.shape[0]
    zc[lay["ys"]] = ys
    zc[lay["uc"]] = plan.ctrl_inputs[k]
    nd = st.ring.shape[1]
    if sched:
        # sources first (they do not depend on the scheduled inputs), then what arrived
        st.ring[k % L] = np.einsum("rkn,kn->rn", plan.CDc[r], zc)[plan.crow["src"]]
        zc[lay["w"]] = _read_timed(plan, st, k, sched)
    elif nd:
        zc[lay["w"]] = _read_fixed(plan, st, k)
    Sc = np.einsum("rkn,kn->rn", plan.CDc[r], zc)
    if nd and not sched:
        # whole-sample buffers hold each source's value at this tick
        st.ring[k % L] = Sc[plan.crow["src"]]
    raw = Sc[plan.crow["act"]]
    new_act = np.clip(raw, -plan.limit, plan.limit)
    st.sat_ticks += np.any(np.abs(raw) > plan.limit, axis=0)
    h0 = lay["held"].start
    for j, tk in enumerate(plan.slow_ticks):
        if k % tk == 0:
            zc[h0 + j] = np.einsum("kn,kn->n", plan.HOLD[r][j], zc)
    zc[lay["x"]] = np.einsum("ijn,jn->in", plan.ABc[r], zc)
    return Sc, new_act


def sense_outputs(plan: SampledPlan, st: SampledState, k: int) -> np.ndarray:
    """Plant rows at tick ``k`` (actuation held from the previous tick)."""
    zp, lay = st.zp, plan.zp
    zp[lay["act"]] = st.act
    zp[lay["exo"]] = plan.plant_inputs[k * plan.substeps]
    zp[lay["fric"]] = st.fric
    return np.einsum("rkn,kn->rn", plan.CDp, zp[lay.upto("fric")])


def _quantize(plan: SampledPlan, ys: np.ndarray) -> np.ndarray:
    q = plan.quantum
    if not np.any(q > 0):
        return ys
    return np.where(q > 0, np.round(ys / np.where(q > 0, q, 1.0)) * q, ys)


def advance_plant(plan: SampledPlan, st: SampledState, k: int) -> None:
    """Integrate the plant over one base period (sub-steps with friction held)."""
    zp, lay, fr = st.zp, plan.zp, plan.friction
    nxt = zp[lay["next"]]
    na = lay["act"].stop - lay["act"].start
    ne = lay["exo"].stop - lay["exo"].start
    for sub in range(plan.substeps):
        i = k * plan.substeps + sub
        zp[lay["act"]] = st.act
        zp[lay["exo"]] = plan.plant_inputs[i]
        if fr:
            zp[lay["fric"]] = st.fric
            vel = np.einsum("kn,kn->n", plan.VEL, zp[lay.upto("fric")])
            st.fric = -(fr.coulomb * np.sign(vel) + fr.viscous * vel)[None, :]
            zp[lay["fric"]] = st.fric
        nxt[:] = zp[lay["act"].start:lay["fric"].stop]
        nxt[na:na + ne] = plan.plant_inputs[i + 1]
        zp[lay["x"]] = np.einsum("ijn,jn->in", plan.Hp, zp)


def _check_bounds(plan: SampledPlan, st: SampledState, k: int, y: np.ndarray,
                  bound: float) -> None:
    """Out of bounds, or controller states running away (e.g. wind-up of a marginal mode)."""
    i_first = plan.order.index(plan.outputs[0])
    xc = st.zc[plan.zc["x"]]
    bad = st.alive & ~((np.abs(y[i_first]) <= bound)
                       & (np.max(np.abs(xc), axis=0, initial=0.0) <= 1e100))
    if bad.any():
        st.left[bad] = plan.t_s[k]
        st.alive &= ~bad
    st.rec[:, :, k] = np.where(st.alive, y, np.nan)


def start_timed(plan: SampledPlan, timing: Mapping[str, np.ndarray] | None = None
                ) -> tuple[SampledState, dict[int, np.ndarray] | None]:
    """The state at rest and the checked schedules of ``timing`` (as :func:`run_sampled`'s),
    for a loop that calls :func:`control_tick` itself."""
    sched = _check_schedule(plan, timing) if timing else None
    ring_len = max(int(plan.nbuf.max(initial=0)), _oldest_arrival(sched)) + 2
    st = SampledState.start(plan, ring_len)
    if sched:
        st.held = np.zeros(st.ring.shape[1:])
    return st, sched


def run_sampled(plan: SampledPlan, bound: float,
                timing: Mapping[str, np.ndarray] | None = None) -> RunOutputs:
    """Step a :class:`SampledPlan` tick by tick.

    ``timing`` (optional) maps delayed blocks (``plan.links``, compiled with
    ``buffered=``) to the source tick each tick uses, shape ``(T, n)`` (-1: nothing has
    arrived yet); between arrivals the receiver holds the last value."""
    st, sched = start_timed(plan, timing)
    for k in range(plan.steps + 1):
        Sp = sense_outputs(plan, st, k)
        Sc, new_act = control_tick(plan, st, k, _quantize(plan, Sp[plan.prow["sensed"]]), sched)
        y = np.concatenate([Sp[plan.prow["out"]], Sc[plan.crow["out"]]], axis=0)
        _check_bounds(plan, st, k, y, bound)
        if k == plan.steps:
            break
        st.act = np.where(st.alive, new_act, 0.0)
        st.peak_act = np.maximum(st.peak_act, np.abs(st.act))
        advance_plant(plan, st, k)
        if not st.alive.all():
            st.zp[:, ~st.alive] = 0.0
            st.zc[:, ~st.alive] = 0.0
            st.ring[:, :, ~st.alive] = 0.0
    return _sampled_result(plan, st)


UNIT_CIRCLE_TOL = 1e-6
"""Eigenvalues of the lifted map with ``| |lambda| - 1 | <= UNIT_CIRCLE_TOL`` make the count
unknown (-1): a growth or decay slower than about 1e-3 /s at 1 kHz is not decided."""


def run_controller(plan: SampledPlan, sensed: np.ndarray) -> np.ndarray:
    """Drive the plan's controller alone (open loop) with given sampled plant signals.

    ``sensed`` has shape ``(T, len(sensed signals), n)`` (``plan.steps + 1`` ticks, the
    signals in the order of ``plan.prow["sensed"]``); the exogenous controller inputs are
    those the plan was compiled with.  Returns the actuation each tick computes (after
    saturation), shape ``(T, len(plan.actuation), n)``: what :func:`run_sampled` applies
    from that tick on.  This is the reference of :mod:`seactl.codegen.export`."""
    sensed = np.asarray(sensed, float)
    ring_len = int(plan.nbuf.max(initial=0)) + 2
    st = SampledState.start(plan, ring_len)
    out = np.empty((plan.steps + 1, len(plan.actuation), plan.x0.shape[1]))
    for k in range(plan.steps + 1):
        out[k] = control_tick(plan, st, k, sensed[k], None)[1]
    return out


def _sampled_result(plan: SampledPlan, st: SampledState) -> RunOutputs:
    rec = {o: st.rec[plan.order.index(o)] for o in plan.outputs}
    peak_act = st.peak_act.T
    recs = fill_diverged(np.stack([rec[o] for o in plan.outputs]), st.left)
    info = {k: v for k, v in plan.info.items() if k != "friction_step_s"}
    info["peak_actuation"] = {s: peak_act[:, j].reshape(plan.shape)
                              for j, s in enumerate(plan.actuation)}
    info["saturated_fraction"] = (st.sat_ticks / (plan.steps + 1)).reshape(plan.shape)
    info["friction_step_s"] = plan.info["friction_step_s"]
    return RunOutputs(plan.t_s, {o: recs[j] for j, o in enumerate(plan.outputs)}, st.left, info)
