"""The sampled controller split by process: one discrete state space per process."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.limits import check_range
from seactl.diagram.blockdiagram import Block, BlockDiagram
from seactl.errors import InputError
from seactl.simulate.discrete import (
    compile_sampled,
    delay_buffers,
    process_rates,
    run_controller,
    run_sampled,
    tick_plan,
)
from seactl.simulate.inputs import Step
from seactl.simulate.network import assemble_blocks
from seactl.simulate.realize import realize_tustin

LANGUAGES = ("c", "python", "json")
FORMAT = "seactl-controller/1"
CFLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2")
MAX_SIM_TICKS = 4000
"""The verification's step response is at most this many base ticks long."""


# ----------------------------------------------------------------------------- the split
@dataclass(frozen=True)
class ProcessController:
    """The discrete controller of one process (see the module docstring for ``step``).

    ``A`` (N, N), ``B`` (N, nv), ``C`` (no + nb, N), ``D`` (no + nb, nv) with
    ``nv = len(inputs) + len(buffers)``; ``buffers``: ``(block, samples)``, each >= 1;
    ``limits``: symmetric limit per output (``inf``: none)."""

    name: str
    rate_hz: float
    period_ticks: int
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    buffers: tuple[tuple[str, int], ...]
    limits: tuple[float, ...]
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray

    @property
    def ident(self) -> str:
        """C identifier of the process (``high-level`` -> ``high_level``)."""
        return c_ident(self.name)


@dataclass(frozen=True)
class Controllers:
    """Every process of a design: ``processes`` in ``schedule`` order (senders first)."""

    diagram: str
    base_rate_hz: float
    processes: tuple[ProcessController, ...]
    actuation: tuple[str, ...]
    sensed: tuple[str, ...]
    references: tuple[str, ...]
    parameters: dict[str, float]
    effective_delays_s: dict[str, float]
    requested_delays_s: dict[str, float]
    emulate_latency: bool = True
    """Whether the processes hold the design's delays as buffers (else zero delays)."""
    programs: tuple[Any, ...] = ()
    """The run-time form of each process (:mod:`seactl.codegen.parametric`), if built."""

    def process(self, name: str) -> ProcessController:
        for p in self.processes:
            if p.name == name:
                return p
        raise InputError("process", name, "one of " + ", ".join(self.names))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.processes)


def c_ident(name: str) -> str:
    """A C identifier for ``name`` (non-word characters become ``_``)."""
    s = re.sub(r"\W", "_", name)
    return s if s and not s[0].isdigit() else "p_" + s


def message_name(signal: str, process: str) -> str:
    """Name of the message carrying ``process``'s contribution to ``signal``."""
    return f"{signal}_from_{c_ident(process)}"


def _check_wiring(ctrl: Sequence[Block], design: Any) -> None:
    for b in ctrl:
        if b.process is None:
            num, den = b.coefficients(design)
            if b.delay is not None or len(num) > 1 or len(den) > 1:
                raise ValueError(f"block {b.name!r} has dynamics or a delay but no process; "
                                 "tag it with the process that runs it")


def _owner(rates: Mapping[str, float]) -> str:
    fastest = max(rates.values())
    tied = sorted(p for p, r in rates.items() if r == fastest)
    return "embedded" if "embedded" in tied else tied[0]


@dataclass
class _ProcNet:
    """A process's network over all controller signals, other processes' blocks held."""

    name: str
    net: Any
    mine: list[Block]
    reals: dict[str, tuple[np.ndarray, ...]]
    inst: dict[str, float]
    wcol: dict[str, int]
    hcol: dict[tuple[str, str], int]
    buffers: list[tuple[str, int]]


def _process_net(name: str, ctrl: Sequence[Block], design: Any, signals: Sequence[str],
                 inject: Sequence[str], Tb: float, ticks: Mapping[str, int],
                 shape: tuple[int, ...] = ()) -> _ProcNet:
    """The sampled compiler's stages for one process (batch of one design)."""
    mine = [b for b in ctrl if b.process == name]
    wiring = [b for b in ctrl if b.process is None]
    others = [b for b in ctrl if b.process not in (name, None)]
    blocks = mine + wiring + others
    period = {b.name: Tb * ticks.get(b.process, 1) for b in blocks}
    delayed = [b for b in mine if b.delay is not None]
    nbuf, _ = delay_buffers(delayed, design, shape, 1, period, ticks)
    samples = {b.name: int(nbuf[b.name][0]) // ticks[name] for b in delayed}
    buffered = [b for b in delayed if samples[b.name] > 0]
    inst = {b.name: np.ones(1) for b in blocks}
    wcol = {}
    for j, b in enumerate(buffered):
        inst[b.name] = np.zeros(1)
        wcol[b.name] = len(inject) + j
    held = {b.name: len(inject) + len(buffered) + j for j, b in enumerate(others)}
    reals = [realize_tustin(b, design, shape, 1, period[b.name]) for b in blocks]
    net = assemble_blocks(1, signals, blocks, reals, inject, inst, wcol, held, identity_hold=False,
                    nv=len(inject) + len(buffered) + len(others))
    hcol = {}
    for b in others:
        hcol.setdefault((b.process, b.dst), held[b.name])
    return _ProcNet(name, net, mine, {b.name: r for b, r in zip(blocks, reals)},
                    {b: float(z[0]) for b, z in inst.items()}, wcol, hcol,
                    [(b.name, samples[b.name]) for b in buffered])


def _message_rows(pn: _ProcNet, idx: Mapping[str, int], signal: str
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Rows giving the sum of ``pn``'s own blocks writing ``signal``: ``C_b x_b + D_b u_b``."""
    net = pn.net
    Cy = np.zeros(net.C.shape[2])
    Dy = np.zeros(net.D.shape[2])
    for b in pn.mine:
        if b.dst != signal:
            continue
        _A, _B, C, D = pn.reals[b.name]
        z, s = pn.inst[b.name], idx[b.src]
        Cy += z * D[0] * net.C[0, s]
        Cy[net.state_slices[b.name]] += C[0]
        Dy += z * D[0] * net.D[0, s]
        if b.name in pn.wcol:
            Dy[pn.wcol[b.name]] += D[0] * (1 - z)
    return Cy, Dy


def _rows(pn: _ProcNet, idx: Mapping[str, int], outs: Sequence[tuple[str, str]],
          ctrl: Sequence[Block]) -> tuple[np.ndarray, np.ndarray]:
    """Output rows (``("act", signal)`` or ``("msg", signal)``), then buffer sources."""
    net = pn.net
    src = {b.name: b.src for b in ctrl}
    Cr, Dr = [], []
    for kind, sig in outs:
        if kind == "act":
            Cr.append(net.C[0, idx[sig]])
            Dr.append(net.D[0, idx[sig]])
        else:
            c, d = _message_rows(pn, idx, sig)
            Cr.append(c)
            Dr.append(d)
    for blk, _n in pn.buffers:
        Cr.append(net.C[0, idx[src[blk]]])
        Dr.append(net.D[0, idx[src[blk]]])
    N, nv = net.C.shape[2], net.D.shape[2]
    return (np.array(Cr).reshape(len(Cr), N), np.array(Dr).reshape(len(Dr), nv))


def _state_cols(pn: _ProcNet) -> np.ndarray:
    sl = [np.arange(pn.net.state_slices[b.name].start, pn.net.state_slices[b.name].stop)
          for b in pn.mine]
    return np.concatenate(sl).astype(int) if sl else np.zeros(0, int)


def _dependencies(pn: _ProcNet, outs: Sequence[tuple[str, str]], idx: Mapping[str, int],
                  ctrl: Sequence[Block]) -> np.ndarray:
    """Which input columns the process's outputs, buffers and states depend on."""
    C, D = _rows(pn, idx, outs, ctrl)
    xs = _state_cols(pn)
    used = _nonzero_cols(D)
    if xs.size:
        used |= _nonzero_cols(pn.net.B[0][xs])
    return used


def _nonzero_cols(M: np.ndarray, rel: float = 1e-12) -> np.ndarray:
    """Columns with an entry above ``rel`` of its row's largest: the wiring is solved
    numerically, and its rounding (1e-19 of a gain) is no dependency (it made two
    processes look as if each needed the other's output within the tick)."""
    A = np.abs(M)
    return np.any(A > rel * A.max(axis=1, keepdims=True, initial=0.0), axis=0)


def _schedule(deps: Mapping[str, set[str]]) -> list[str]:
    order: list[str] = []
    left = dict(deps)
    while left:
        ready = sorted(p for p, d in left.items() if d <= set(order))
        if not ready:
            raise ValueError("the processes depend on each other within one tick: "
                             + ", ".join(sorted(left)))
        order += ready
        for p in ready:
            del left[p]
    return order


def compile_processes(diagram: BlockDiagram, design: Any,
                      rates_hz: Mapping[str, float] | float = 1000.0,
                      saturation: Mapping[str, float] | None = None) -> Controllers:
    """Split the sampled controller of ``diagram`` for ``design`` (one design) by process.

    ``rates_hz`` and ``saturation`` mean what they mean for
    :func:`seactl.simulate.discrete.compile_sampled`."""
    shape = tuple(getattr(design, "shape", ()))
    if int(np.prod(shape, dtype=int)) != 1:
        raise InputError("design", f"batch of shape {shape}", "a single design")
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    _check_wiring(ctrl, design)
    processes = sorted({b.process for b in ctrl if b.process is not None}) or ["embedded"]
    if isinstance(rates_hz, Mapping):
        for name in rates_hz:
            if name not in processes:
                raise InputError("rates_hz", name, "a process of the diagram: "
                                 + ", ".join(processes))
    rates = process_rates(rates_hz, processes)
    for p, r in rates.items():
        check_range(f"rates_hz [Hz] ({p})", r, "rate_hz")
    Tb, ticks = tick_plan(rates)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        # non-finite coefficients (extreme filters) are refused below, not warned about
        return _compile(diagram, design, ctrl, processes, rates, Tb, ticks, saturation, shape)


def _compile(diagram: BlockDiagram, design: Any, ctrl: Sequence[Block], processes: list[str],
             rates: dict[str, float], Tb: float, ticks: dict[str, int],
             saturation: Mapping[str, float] | None, shape: tuple[int, ...]) -> Controllers:
    # the same plant/controller interface as the sampled plan (signals, actuation, limits)
    plan = compile_sampled(diagram, design, {}, Tb, (), rates_hz=rates, saturation=saturation)
    plant_sig = {b.dst for b in diagram.blocks if b.role == "plant"}
    sensed = sorted({b.src for b in ctrl if b.src in plant_sig})
    exo = sorted({b.src for b in ctrl if b.src in diagram.inputs})
    inject = sensed + exo
    signals = sorted({b.dst for b in ctrl} | set(inject))
    idx = {s: i for i, s in enumerate(signals)}
    nets = {p: _process_net(p, ctrl, design, signals, inject, Tb, ticks, shape)
            for p in processes}
    owner = _owner(rates)
    limit = dict(zip(plan.actuation, plan.limit[:, 0]))
    outs = {p: ([("act", a) for a in plan.actuation] if p == owner else []) for p in processes}
    deps = _message_fixpoint(nets, outs, idx, ctrl)
    try:
        order = _schedule(deps)
    except ValueError as exc:
        raise _cyclic(ctrl, design, rates, exc) from None
    procs = [_finish(nets[p], outs[p], idx, ctrl, inject, rates[p], ticks[p], limit)
             for p in order]
    for proc in procs:
        if not all(np.all(np.isfinite(m)) for m in (proc.A, proc.B, proc.C, proc.D)):
            raise InputError("design", f"process {proc.name!r}", "gains, filters and rates "
                             "whose discrete coefficients are finite (an extreme filter "
                             "cut-off overflows the Tustin transform)")
    params = {k: float(np.ravel(v)[0]) for k, v in _fields(design).items()}
    eff = {b: float(np.ravel(v)[0]) for b, v in plan.info["effective_delays_s"].items()}
    req = {b.name: float(np.ravel(getattr(design, b.delay))[0]) for b in ctrl if b.delay}
    return Controllers(diagram.name, 1.0 / Tb, tuple(procs), tuple(plan.actuation),
                       tuple(sensed), tuple(exo), params, eff, req)


def _cyclic(ctrl: Sequence[Block], design: Any, rates: Mapping[str, float],
            exc: ValueError) -> InputError:
    """Processes that need each other's output within one tick cannot run apart (the
    sampled simulation solves them together; real processes exchange messages): the
    delays between them must give each message at least a tick."""
    delays = {b.delay: f"{1e3 * float(np.ravel(getattr(design, b.delay))[0]):g} ms"
              for b in ctrl if b.delay and b.process is not None}
    ticks = ", ".join(f"{p} {1e3 / r:g} ms" for p, r in sorted(rates.items()))
    return InputError("delays", delays, f"delays that give every message between the "
                      f"processes at least one tick of its sender ({ticks}): {exc}; "
                      "lengthen the delay of the link between them or raise the rates")


def _fields(design: Any) -> dict[str, Any]:
    f = getattr(design, "_fields", None)
    return {k: v for k, v in (f() if f else {}).items() if v is not None}


def _message_fixpoint(nets: Mapping[str, _ProcNet], outs: dict[str, list[tuple[str, str]]],
                      idx: Mapping[str, int], ctrl: Sequence[Block]) -> dict[str, set[str]]:
    """Add the messages other processes need (until nothing changes); who needs whom."""
    deps = {p: set() for p in nets}
    changed = True
    while changed:
        changed = False
        for q, pn in nets.items():
            used = _dependencies(pn, outs[q], idx, ctrl)
            for (p, sig), col in pn.hcol.items():
                if used[col]:
                    deps[q].add(p)
                    if ("msg", sig) not in outs[p]:
                        outs[p].append(("msg", sig))
                        changed = True
    return deps


def _finish(pn: _ProcNet, outs: Sequence[tuple[str, str]], idx: Mapping[str, int],
            ctrl: Sequence[Block], inject: Sequence[str], rate_hz: float, ticks: int,
            limit: Mapping[str, float]) -> ProcessController:
    """Select the process's states and used inputs; name inputs and outputs."""
    C, D = _rows(pn, idx, outs, ctrl)
    xs = _state_cols(pn)
    used = _dependencies(pn, outs, idx, ctrl)
    ni = len(inject)
    names, cols = [], []
    for j, s in enumerate(inject):
        if used[j]:
            names.append(s)
            cols.append(j)
    for (p, sig), col in sorted(pn.hcol.items()):
        if used[col]:
            names.append(message_name(sig, p))
            cols.append(col)
    cols += [ni + j for j in range(len(pn.buffers))]
    A = pn.net.A[0][np.ix_(xs, xs)]
    B = pn.net.B[0][xs][:, cols]
    out_names = [sig if kind == "act" else message_name(sig, pn.name) for kind, sig in outs]
    lims = [float(limit.get(sig, math.inf)) if kind == "act" else math.inf
            for kind, sig in outs]
    return ProcessController(pn.name, float(rate_hz), int(ticks), tuple(names),
                             tuple(out_names), tuple(pn.buffers), tuple(lims), A, B,
                             C[:, xs], D[:, cols])


# ----------------------------------------------------------------------------- running
def run_process(proc: ProcessController, inputs: np.ndarray) -> np.ndarray:
    """Step ``proc`` over ``inputs`` (one row per tick, columns ``proc.inputs``); returns
    the outputs per tick.  The matrices as compiled (the Python export runs the same)."""
    no = len(proc.outputs)
    x = np.zeros(proc.A.shape[0])
    rings = [np.zeros(n) for _b, n in proc.buffers]
    heads = [0] * len(rings)
    out = np.empty((inputs.shape[0], no))
    lim = np.array(proc.limits)
    for k, u in enumerate(inputs):
        v = np.concatenate([u, [r[h] for r, h in zip(rings, heads)]])
        y = proc.C @ x + proc.D @ v
        out[k] = np.clip(y[:no], -lim, lim)
        for j, r in enumerate(rings):
            r[heads[j]] = y[no + j]
            heads[j] = (heads[j] + 1) % r.size
        x = proc.A @ x + proc.B @ v
    return out


def schedule_inputs(ctl: Controllers, proc: ProcessController, base: Mapping[str, np.ndarray],
                    sent: Mapping[str, tuple[int, np.ndarray, tuple[str, ...]]]) -> np.ndarray:
    """Inputs of ``proc`` at its ticks: plant signals and references from ``base`` (one
    value per base tick), messages held from the senders' outputs ``sent``
    (process -> (period ticks, outputs per tick, output names))."""
    T = len(next(iter(base.values())))
    k = np.arange(0, T, proc.period_ticks)
    cols = []
    for name in proc.inputs:
        if name in base:
            cols.append(np.asarray(base[name])[k])
            continue
        for per, y, names in sent.values():
            if name in names:
                cols.append(y[k // per, names.index(name)])
                break
        else:
            raise ValueError(f"no sender of {name!r}")
    return np.array(cols).T.reshape(k.size, len(proc.inputs))


def run_schedule(ctl: Controllers, base: Mapping[str, np.ndarray], runner: Any = None
                 ) -> np.ndarray:
    """Run every process at its rate (schedule order) on base-tick signals ``base``; the
    actuation per base tick ``(T, len(actuation))``.  ``runner(proc, inputs)`` runs one
    process (default :func:`run_process`)."""
    runner = runner or run_process
    sent: dict[str, tuple[int, np.ndarray, tuple[str, ...]]] = {}
    for proc in ctl.processes:
        y = runner(proc, schedule_inputs(ctl, proc, base, sent))
        sent[proc.name] = (proc.period_ticks, np.asarray(y), proc.outputs)
    T = len(next(iter(base.values())))
    act = np.empty((T, len(ctl.actuation)))
    for a_i, a in enumerate(ctl.actuation):
        for per, y, names in sent.values():
            if a in names:
                act[:, a_i] = y[np.arange(T) // per, names.index(a)]
    return act


# ----------------------------------------------------------------------------- reference
def _held(values: np.ndarray, Tb: float) -> Any:
    values = np.asarray(values, float)
    return lambda t: values[np.minimum(np.round(np.asarray(t) / Tb).astype(int),
                                       values.size - 1)]


def reference_actuation(diagram: BlockDiagram, design: Any, ctl: Controllers,
                        base: Mapping[str, np.ndarray],
                        rates_hz: Mapping[str, float] | float,
                        saturation: Mapping[str, float] | None) -> np.ndarray:
    """seactl's own sampled controller (the plan of :func:`compile_sampled`, stepped by
    :func:`seactl.simulate.discrete.run_controller`) on the same base-tick signals."""
    T = len(next(iter(base.values())))
    Tb = 1.0 / ctl.base_rate_hz
    inputs = {r: _held(base[r], Tb) for r in ctl.references}
    plan = compile_sampled(diagram, design, inputs, (T - 1) * Tb, (), rates_hz=rates_hz,
                           saturation=saturation)
    if plan.steps + 1 != T:
        raise ValueError("tick count mismatch")
    ys = np.stack([np.asarray(base[s], float) for s in ctl.sensed], axis=1)[:, :, None]
    return run_controller(plan, ys)[:, :, 0]


def simulation_signals(diagram: BlockDiagram, design: Any, ctl: Controllers,
                       t_end_s: float, rates_hz: Mapping[str, float] | float,
                       saturation: Mapping[str, float] | None,
                       step: float) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Signals the controller receives in a sampled step response (a step of ``step`` on
    every reference), and the actuation the simulation applied after each tick."""
    inputs = {r: Step(step) for r in ctl.references}
    outs = tuple(ctl.sensed) + tuple(a for a in ctl.actuation if a not in ctl.sensed)
    plan = compile_sampled(diagram, design, inputs, t_end_s, outs, rates_hz=rates_hz,
                           saturation=saturation)
    res = run_sampled(plan, bound=1e3 * max(abs(step), 1e-12))
    base = {s: np.ravel(res.outputs[s]) for s in ctl.sensed}
    for r in ctl.references:
        base[r] = np.full(plan.steps + 1, float(step))
    applied = np.stack([np.ravel(res.outputs[a]) for a in ctl.actuation], axis=1)
    return base, applied


def random_signals(ctl: Controllers, ticks: int, seed: int = 0,
                   scale: float = 1.0) -> dict[str, np.ndarray]:
    """Independent normal signals (``scale`` standard deviation) for every input."""
    rng = np.random.default_rng(seed)
    return {s: scale * rng.standard_normal(ticks) for s in ctl.sensed + ctl.references}


def relative_error(y: np.ndarray, ref: np.ndarray) -> float:
    """Largest difference per actuation signal over that signal's peak, largest of all."""
    y, ref = np.asarray(y, float), np.asarray(ref, float)
    peak = np.maximum(np.max(np.abs(ref), axis=0), 1e-300)
    return float(np.max(np.max(np.abs(y - ref), axis=0) / peak, initial=0.0))
