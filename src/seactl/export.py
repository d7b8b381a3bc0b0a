"""Per-process discrete controllers of a design, exported as C99, Python and JSON.

A design runs on several processes (the block diagram's ``process`` tags: the stiffness
loop on the ``high-level`` process, torque and damping on the ``embedded`` process), each
at its own rate.  :func:`compile_processes` splits the sampled controller of
:func:`seactl.simulate.compile_sampled` into one discrete state space per process, built
with the sampled compiler's own stages (:func:`~seactl.simulate.realize_tustin` for every
block at its process's period, :func:`~seactl.simulate._assemble` for the network,
:func:`~seactl.simulate._buffers` for the whole-sample delay buffers, the same rates and
saturation), so there is one model: :func:`verify` checks the split against the plan's
controller (:func:`seactl.simulate.run_controller`).

One process, one tick (every ``period_ticks`` base ticks)::

    v = [inputs; w]            w_j = the value buffer j received buffers[j] ticks ago
    y = C x + D v              y = [outputs; sources of the buffers]
    outputs = clip(y[:no], -limits, limits)
    buffer j <- y[no + j]
    x <- A x + B v

Inputs are sampled plant signals (``q_j``, ``tau_k``), references (``q_des``) and the
messages of other processes (``tau_fb_from_high_level``: that process's contribution to
signal ``tau_fb``, held by the receiver between the sender's ticks).  Static untagged
blocks (sensors, sums, taps) are wiring, replicated into every process that needs them.
The actuation (``i_m``, ``F_des``) is output by the fastest process (``embedded`` on a
tie).  Processes run in ``schedule`` order within a base tick (senders first), which is
what the sampled simulation's simultaneous solution gives.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
import shutil
import subprocess
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .blockdiagram import Block, BlockDiagram
from .errors import InputError, OutputError, ResourceError, SeactlError
from .limits import check_range
from .outputs import OutputSet
from .results import Result, new_axes
from .simulate import (
    Step,
    _assemble,
    _buffers,
    _rates,
    _ticks,
    compile_sampled,
    realize_tustin,
    run_controller,
    run_sampled,
)

LANGUAGES = ("c", "python", "json")
FORMAT = "seactl-controller/1"
CFLAGS = ("-std=c99", "-Wall", "-Werror", "-O2")
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
    nbuf, _ = _buffers(delayed, design, shape, 1, period, ticks)
    samples = {b.name: int(nbuf[b.name][0]) // ticks[name] for b in delayed}
    buffered = [b for b in delayed if samples[b.name] > 0]
    inst = {b.name: np.ones(1) for b in blocks}
    wcol = {}
    for j, b in enumerate(buffered):
        inst[b.name] = np.zeros(1)
        wcol[b.name] = len(inject) + j
    held = {b.name: len(inject) + len(buffered) + j for j, b in enumerate(others)}
    reals = [realize_tustin(b, design, shape, 1, period[b.name]) for b in blocks]
    net = _assemble(1, signals, blocks, reals, inject, inst, wcol, held, identity_hold=False,
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
    :func:`seactl.simulate.compile_sampled`."""
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
    rates = _rates(rates_hz, processes)
    for p, r in rates.items():
        check_range(f"rates_hz [Hz] ({p})", r, "rate_hz")
    Tb, ticks = _ticks(rates)
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
    :func:`seactl.simulate.run_controller`) on the same base-tick signals."""
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


# ----------------------------------------------------------------------------- code
def _lit(x: float) -> str:
    """Exact C/Python literal of a finite double (shortest repr round-trips)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"non-finite coefficient {x!r}")
    return repr(x)


def _affine(row_c: np.ndarray, row_d: np.ndarray, xs: str, vs: str) -> str:
    """``sum c_i xs[i] + sum d_j vs[j]`` over the non-zero coefficients, as C/Python."""
    terms = [f"{_lit(c)} * {xs}[{i}]" for i, c in enumerate(row_c) if c != 0]
    terms += [f"{_lit(d)} * {vs}[{j}]" for j, d in enumerate(row_d) if d != 0]
    return " + ".join(terms) if terms else "0.0"


def _banner(ctl: Controllers, proc: ProcessController, comment: str) -> str:
    lines = [f"Generated by seactl export ({FORMAT}); do not edit.",
             f"Process {proc.name!r} of the {ctl.diagram!r} diagram: call step() at "
             f"{proc.rate_hz:g} Hz (every {proc.period_ticks} base tick(s) of "
             f"{ctl.base_rate_hz:g} Hz).",
             "Inputs: " + ", ".join(proc.inputs) + ".",
             "Outputs: " + ", ".join(proc.outputs) + ".",
             "Design: " + ", ".join(f"{k}={v:.6g}" for k, v in ctl.parameters.items()) + "."]
    if proc.buffers:
        lines.append("Delay buffers [samples of this process]: "
                     + ", ".join(f"{b}={n}" for b, n in proc.buffers) + ".")
    if comment == "c":
        return "/*\n" + "".join(f" * {ln}\n" for ln in lines) + " */\n"
    return "".join(f"# {ln}\n" for ln in lines)


def c_header(ctl: Controllers, proc: ProcessController) -> str:
    """``<process>.h``: the state, inputs and outputs structs and the two functions."""
    p, P = proc.ident, proc.ident.upper()
    n = proc.A.shape[0]
    state = [f"    double x[{n}];"] if n else []
    for j, (blk, nb) in enumerate(proc.buffers):
        state += [f"    double buf{j}[{nb}]; /* {blk} */", f"    int head{j};"]
    if not state:
        state = ["    char unused; /* no state */"]
    ins = [f"    double {c_ident(s)};" for s in proc.inputs] or ["    char unused;"]
    outs = [f"    double {c_ident(s)};" for s in proc.outputs]
    return (_banner(ctl, proc, "c") + f"#ifndef SEACTL_{P}_H\n#define SEACTL_{P}_H\n\n"
            f"#define {P}_RATE_HZ {_lit(proc.rate_hz)}\n\n"
            "typedef struct {\n" + "\n".join(state) + f"\n}} {p}_state;\n\n"
            "typedef struct {\n" + "\n".join(ins) + f"\n}} {p}_inputs;\n\n"
            "typedef struct {\n" + "\n".join(outs) + f"\n}} {p}_outputs;\n\n"
            f"void {p}_init({p}_state *s);\n"
            f"void {p}_step({p}_state *s, const {p}_inputs *in, {p}_outputs *out);\n\n"
            f"#endif /* SEACTL_{P}_H */\n")


def _c_step_body(proc: ProcessController) -> list[str]:
    n, no, ni = proc.A.shape[0], len(proc.outputs), len(proc.inputs)
    nv = ni + len(proc.buffers)
    body = [f"    double v[{max(nv, 1)}];", f"    double y[{no + len(proc.buffers)}];"]
    if n:
        body.append(f"    double xn[{n}];")
    body += [f"    v[{j}] = in->{c_ident(s)};" for j, s in enumerate(proc.inputs)]
    body += [f"    v[{ni + j}] = s->buf{j}[s->head{j}];" for j in range(len(proc.buffers))]
    if not nv:
        body.append("    v[0] = 0.0;")
    body += [f"    y[{i}] = {_affine(proc.C[i], proc.D[i], 's->x', 'v')};"
             for i in range(proc.C.shape[0])]
    for i, (name, lim) in enumerate(zip(proc.outputs, proc.limits)):
        if math.isfinite(lim):
            body.append(f"    y[{i}] = y[{i}] > {_lit(lim)} ? {_lit(lim)} : "
                        f"(y[{i}] < {_lit(-lim)} ? {_lit(-lim)} : y[{i}]);")
        body.append(f"    out->{c_ident(name)} = y[{i}];")
    for j, (_b, nb) in enumerate(proc.buffers):
        body += [f"    s->buf{j}[s->head{j}] = y[{no + j}];",
                 f"    s->head{j} = (s->head{j} + 1) % {nb};"]
    body += [f"    xn[{i}] = {_affine(proc.A[i], proc.B[i], 's->x', 'v')};" for i in range(n)]
    body += [f"    s->x[{i}] = xn[{i}];" for i in range(n)]
    if not (n or proc.buffers):
        body.append("    (void)s;")
    return body


def c_source(ctl: Controllers, proc: ProcessController) -> str:
    """``<process>.c``: ``init`` zeroes the state, ``step`` runs one tick (no allocation,
    no library calls)."""
    p = proc.ident
    init = []
    if proc.A.shape[0]:
        init += [f"    for (i = 0; i < {proc.A.shape[0]}; ++i) s->x[i] = 0.0;"]
    for j, (_b, nb) in enumerate(proc.buffers):
        init += [f"    for (i = 0; i < {nb}; ++i) s->buf{j}[i] = 0.0;", f"    s->head{j} = 0;"]
    decl = ["    int i;"] if init else ["    (void)s;"]
    return (_banner(ctl, proc, "c") + f'#include "{p}.h"\n\n'
            f"void {p}_init({p}_state *s)\n{{\n" + "\n".join(decl + init) + "\n}\n\n"
            f"void {p}_step({p}_state *s, const {p}_inputs *in, {p}_outputs *out)\n{{\n"
            + "\n".join(_c_step_body(proc)) + "\n}\n")


def c_main(ctl: Controllers, proc: ProcessController) -> str:
    """``<process>_main.c``: reads CSV inputs (a header line, then one tick per line) on
    stdin, writes CSV outputs (``%.17g``) on stdout."""
    p = proc.ident
    parse = []
    for s in proc.inputs:
        parse += [f"        in.{c_ident(s)} = strtod(c, &end);",
                  "        if (end == c) { fprintf(stderr, \"bad number on line %ld\\n\", "
                  "line_no); return 2; }",
                  "        c = end; if (*c == ',') ++c;"]
    fmt = ",".join(["%.17g"] * len(proc.outputs))
    args = ", ".join(f"out.{c_ident(s)}" for s in proc.outputs)
    return (f"/* CSV harness of {p}.c, generated by seactl export. */\n"
            "#include <stdio.h>\n#include <stdlib.h>\n" f'#include "{p}.h"\n\n'
            "int main(void)\n{\n    char line[4096];\n    long line_no = 1;\n"
            f"    static {p}_state s; /* static: long delay buffers stay off the stack */\n"
            f"    {p}_inputs in;\n    {p}_outputs out;\n"
            f"    {p}_init(&s);\n"
            "    if (!fgets(line, sizeof line, stdin)) return 1; /* header */\n"
            f'    printf("{",".join(proc.outputs)}\\n");\n'
            "    while (fgets(line, sizeof line, stdin)) {\n"
            "        char *c = line, *end;\n        ++line_no;\n        (void)end;\n"
            + "\n".join(parse) + ("\n" if parse else "")
            + f"        {p}_step(&s, &in, &out);\n"
            f'        printf("{fmt}\\n", {args});\n'
            "    }\n    return 0;\n}\n")


def _py_matrix(m: np.ndarray) -> str:
    rows = ", ".join("[" + ", ".join(_lit(v) for v in r) + "]" for r in m)
    return f"np.array([{rows}], dtype=float).reshape({m.shape[0]}, {m.shape[1]})"


def python_class_name(proc: ProcessController) -> str:
    return "".join(w[:1].upper() + w[1:] for w in proc.ident.split("_") if w) or "Process"


def python_source(ctl: Controllers, proc: ProcessController) -> str:
    """``<process>.py``: a numpy class with ``init()`` and ``step(inputs) -> outputs``."""
    lims = ", ".join("math.inf" if not math.isfinite(v) else _lit(v) for v in proc.limits)
    return (_banner(ctl, proc, "py") + "import math\n\nimport numpy as np\n\n\n"
            f"class {python_class_name(proc)}:\n"
            f'    """Process {proc.name!r}: ``step(inputs) -> outputs`` at RATE_HZ."""\n\n'
            f"    RATE_HZ = {_lit(proc.rate_hz)}\n"
            f"    INPUTS = {tuple(proc.inputs)!r}\n    OUTPUTS = {tuple(proc.outputs)!r}\n"
            f"    BUFFERS = {tuple(n for _b, n in proc.buffers)!r}\n"
            f"    LIMITS = ({lims}{',' if len(proc.limits) == 1 else ''})\n"
            f"    A = {_py_matrix(proc.A)}\n    B = {_py_matrix(proc.B)}\n"
            f"    C = {_py_matrix(proc.C)}\n    D = {_py_matrix(proc.D)}\n\n"
            "    def __init__(self):\n        self.init()\n\n"
            "    def init(self):\n"
            "        self.x = np.zeros(self.A.shape[0])\n"
            "        self.buf = [np.zeros(n) for n in self.BUFFERS]\n"
            "        self.head = [0] * len(self.BUFFERS)\n\n"
            "    def step(self, inputs):\n"
            '        """One tick: ``inputs`` maps every name of INPUTS to a float."""\n'
            "        v = np.array([float(inputs[n]) for n in self.INPUTS]\n"
            "                     + [b[h] for b, h in zip(self.buf, self.head)])\n"
            "        y = self.C @ self.x + self.D @ v\n"
            "        no = len(self.OUTPUTS)\n"
            "        for j, b in enumerate(self.buf):\n"
            "            b[self.head[j]] = y[no + j]\n"
            "            self.head[j] = (self.head[j] + 1) % b.size\n"
            "        self.x = self.A @ self.x + self.B @ v\n"
            "        return {n: min(max(float(y[i]), -lim), lim)\n"
            "                for i, (n, lim) in enumerate(zip(self.OUTPUTS, self.LIMITS))}\n")


def to_json(ctl: Controllers) -> dict[str, Any]:
    """The coefficients and the wiring of every process (JSON-ready)."""
    fin = lambda v: v if math.isfinite(v) else None  # noqa: E731
    procs = [{"name": p.name, "ident": p.ident, "rate_hz": p.rate_hz,
              "period_ticks": p.period_ticks, "inputs": list(p.inputs),
              "outputs": list(p.outputs), "limits": [fin(v) for v in p.limits],
              "buffers": [{"block": b, "samples": n} for b, n in p.buffers],
              "A": p.A.tolist(), "B": p.B.tolist(), "C": p.C.tolist(), "D": p.D.tolist()}
             for p in ctl.processes]
    return {"format": FORMAT, "diagram": ctl.diagram, "base_rate_hz": ctl.base_rate_hz,
            "schedule": list(ctl.names), "actuation": list(ctl.actuation),
            "sensed": list(ctl.sensed), "references": list(ctl.references),
            "parameters": ctl.parameters, "requested_delays_s": ctl.requested_delays_s,
            "effective_delays_s": ctl.effective_delays_s,
            "step": "v = [inputs, buffer values (oldest)]; y = C x + D v; outputs = "
                    "clip(y[:len(outputs)], -limits, limits); buffer j <- y[len(outputs)+j]; "
                    "x <- A x + B v",
            "processes": procs}


def export_files(ctl: Controllers, languages: Sequence[str] = LANGUAGES) -> dict[str, str]:
    """File name -> contents of the export in ``languages`` (``c``, ``python``, ``json``)."""
    langs = check_languages(languages)
    files: dict[str, str] = {}
    for proc in ctl.processes:
        if "c" in langs:
            files[f"{proc.ident}.h"] = c_header(ctl, proc)
            files[f"{proc.ident}.c"] = c_source(ctl, proc)
            files[f"{proc.ident}_main.c"] = c_main(ctl, proc)
        if "python" in langs:
            files[f"{proc.ident}.py"] = python_source(ctl, proc)
    if "json" in langs:
        files["controller.json"] = json.dumps(to_json(ctl), indent=1) + "\n"
    return files


def check_languages(languages: Sequence[str] | str) -> tuple[str, ...]:
    if isinstance(languages, str):
        languages = [s.strip() for s in languages.split(",")]
    langs = tuple(dict.fromkeys(s.strip().lower() for s in languages if s.strip()))
    bad = [s for s in langs if s not in LANGUAGES]
    if bad or not langs:
        raise InputError("lang", ",".join(languages), "a comma-separated subset of "
                         + ",".join(LANGUAGES))
    return langs


# ----------------------------------------------------------------------------- files
MARKER = ".seactl-export"
"""File that marks a directory as an export seactl wrote (its files may be replaced)."""


def check_export_dir(out: str | os.PathLike, marker: str = MARKER,
                     what: str = "an export") -> Path:
    """Refuse ``out`` unless it is absent, an empty directory, or ``what`` seactl wrote
    (a directory holding ``marker``)."""
    if not os.fspath(out).strip():
        raise InputError("out", os.fspath(out), "a directory name")
    out = Path(out)
    if out.exists():
        if not out.is_dir():
            raise OutputError(out, "exists and is not a directory")
        if any(out.iterdir()) and not (out / marker).is_file():
            raise OutputError(out, f"the directory is not empty and is not {what} seactl "
                              "wrote (choose a new or empty directory)")
    elif not out.parent.is_dir():
        raise OutputError(out, f"the directory {out.parent} does not exist")
    return out


def listed_files(out: Path, marker: str = MARKER) -> set[str]:
    """The files seactl wrote into ``out`` (listed by its ``marker``; none without one)."""
    try:
        return set((out / marker).read_text(errors="replace").splitlines()[1:])
    except OSError:
        return set()


def write_export(files: Mapping[str, str], out: str | os.PathLike, marker: str = MARKER,
                 what: str = "an export") -> list[Path]:
    """Write ``files`` into ``out`` as a set (temporaries renamed at the end), with the
    marker file; returns the paths written (the marker last)."""
    out = check_export_dir(out, marker, what)
    created = not out.exists()
    earlier = listed_files(out, marker)
    for name in files:
        if name not in earlier and (out / name).exists():
            raise OutputError(out / name, f"it exists and {what} seactl wrote there does not "
                              "list it (move it out or choose another directory)")
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(out, exc.strerror or str(exc)) from None
    still = sorted(n for n in earlier if n not in files and (out / n).is_file())
    try:
        with OutputSet() as outs:
            paths = [outs.add("out", out / name) for name in [*files, marker]]
            for path, name in zip(paths, files):
                outs.write(path, files[name])
            outs.write(paths[-1], "written by seactl; seactl may replace the files it "
                       "lists\n" + "".join(f"{n}\n" for n in [*files, *still]))
            outs.commit()
    except BaseException:
        if created:
            try:
                out.rmdir()  # only if nothing is left in it
            except OSError:
                pass
        raise
    return paths


# ----------------------------------------------------------------------------- verify
@dataclass(frozen=True)
class Verification:
    """Largest relative difference of each exported implementation from seactl's sampled
    controller (``errors``: ``"python/simulation"``, ``"c/random"``, ...), the compiler
    and the time it took to compile every process [s]."""

    max_error: float
    errors: dict[str, float]
    compiler: str | None
    compile_s: float | None
    ticks: dict[str, int]


def find_compiler(cc: str | None = None) -> str | None:
    """Path of the C compiler ``cc`` (None if absent), or the first of ``$CC``, ``cc``,
    ``gcc``, ``clang`` found."""
    if cc:
        return shutil.which(cc)
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and (path := shutil.which(name)):
            return path
    return None


def compile_c(build: Path, proc: ProcessController, cc: str) -> Path:
    """Compile ``<process>.c`` and its harness in ``build`` with ``cc -std=c99 -Wall
    -Werror``; the executable."""
    exe = build / f"{proc.ident}_harness"
    cmd = [cc, *CFLAGS, f"{proc.ident}.c", f"{proc.ident}_main.c", "-o", exe.name]
    try:
        res = subprocess.run(cmd, cwd=build, capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise SeactlError(f"cannot run the C compiler {cc}: {exc}") from None
    if res.returncode != 0:
        first = (res.stderr.strip().splitlines() or ["no message"])[0]
        raise SeactlError(f"the C compiler rejected the export of {proc.name!r}: {first}")
    return exe


def _c_runner(exes: Mapping[str, Path]) -> Any:
    def run(proc: ProcessController, inputs: np.ndarray) -> np.ndarray:
        text = ",".join(proc.inputs) + "\n" + "".join(
            ",".join(repr(float(v)) for v in row) + "\n" for row in inputs)
        res = subprocess.run([str(exes[proc.name])], input=text, capture_output=True,
                             text=True, timeout=120)
        if res.returncode != 0:
            raise SeactlError(f"the C harness of {proc.name!r} failed: {res.stderr.strip()}")
        rows = res.stdout.strip().splitlines()[1:]
        return np.array([[float(v) for v in r.split(",")] for r in rows]).reshape(
            len(rows), len(proc.outputs))
    return run


def _python_runner(build: Path) -> Any:
    def run(proc: ProcessController, inputs: np.ndarray) -> np.ndarray:
        spec = importlib.util.spec_from_file_location(f"_seactl_export_{proc.ident}",
                                                      build / f"{proc.ident}.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        obj = getattr(mod, python_class_name(proc))()
        out = [obj.step(dict(zip(proc.inputs, row))) for row in inputs]
        return np.array([[o[n] for n in proc.outputs] for o in out]).reshape(
            len(out), len(proc.outputs))
    return run


def _random_scale(diagram: BlockDiagram, design: Any, ctl: Controllers, rates: Any,
                  saturation: Mapping[str, float] | None) -> float:
    """Input scale keeping the raw actuation at half its limit (saturation then rare)."""
    lims = [v for v in (saturation or {}).values() if math.isfinite(v)]
    if not lims:
        return 1.0
    base = random_signals(ctl, 400, seed=1)
    peak = np.max(np.abs(reference_actuation(diagram, design, ctl, base, rates, None)))
    return min(1.0, 0.5 * min(lims) / peak) if peak > 0 else 1.0


def verify(diagram: BlockDiagram, design: Any, ctl: Controllers, *,
           rates_hz: Mapping[str, float] | float, saturation: Mapping[str, float] | None,
           languages: Sequence[str] = ("c", "python"), cc: str | None = None,
           t_end_s: float = 0.5, random_ticks: int = 2000, seed: int = 0,
           step: float = 0.1) -> Verification:
    """Run the exported code on the signals of a sampled step response and on random
    signals, against seactl's own sampled controller (:func:`reference_actuation`)."""
    compiler = find_compiler(cc) if "c" in languages else None
    if "c" in languages and compiler is None:
        raise ResourceError(f"no C compiler found (looked for {cc or '$CC, cc, gcc, clang'}):"
                            " install one, or leave out --verify")
    t_end_s = min(t_end_s, MAX_SIM_TICKS / ctl.base_rate_hz)
    sim, _applied = simulation_signals(diagram, design, ctl, t_end_s, rates_hz, saturation,
                                       step)
    scale = _random_scale(diagram, design, ctl, rates_hz, saturation)
    cases = {"simulation": sim, "random": random_signals(ctl, random_ticks, seed, scale)}
    refs = {k: reference_actuation(diagram, design, ctl, b, rates_hz, saturation)
            for k, b in cases.items()}
    errors: dict[str, float] = {}
    compile_s = None
    with tempfile.TemporaryDirectory(prefix="seactl-export-") as tmp:
        build = Path(tmp)
        for name, text in export_files(ctl, ("c", "python")).items():
            (build / name).write_text(text)
        runners = {}
        if "python" in languages:
            runners["python"] = _python_runner(build)
        if compiler:
            t0 = time.perf_counter()
            exes = {p.name: compile_c(build, p, compiler) for p in ctl.processes}
            compile_s = time.perf_counter() - t0
            runners["c"] = _c_runner(exes)
        for lang, runner in runners.items():
            for case, base in cases.items():
                y = run_schedule(ctl, base, runner)
                errors[f"{lang}/{case}"] = relative_error(y, refs[case])
    return Verification(max(errors.values(), default=0.0), errors, compiler, compile_s,
                        {k: len(next(iter(b.values()))) for k, b in cases.items()})


# ----------------------------------------------------------------------------- one call
@dataclass(frozen=True)
class ExportResult(Result):
    """What an export wrote, the per-process controllers and, with ``verify``, how far the
    exported code is from seactl's own sampled controller.

    Parameters
    ----------
    files : list of pathlib.Path
        The files written, the marker last.
    controllers : Controllers
        The per-process discrete controllers.
    verification : Verification or None
        The verification, when asked for.

    Attributes
    ----------
    files : list of pathlib.Path
        The files written, the marker last.
    controllers : Controllers
        The per-process discrete controllers.
    verification : Verification or None
        The verification, when asked for.
    processes : tuple of ProcessController
        The processes, senders first.
    max_error : float or None
        Largest relative difference of any implementation (dimensionless; None unverified).
    errors : dict or None
        ``"<language>/<signals>"`` -> relative difference.
    compiler : str or None
        The C compiler used.
    compile_s : float or None
        Time to compile every process [s].
    """

    files: list[Path]
    controllers: Controllers
    verification: Verification | None

    @property
    def processes(self) -> tuple[ProcessController, ...]:
        """The processes, senders first."""
        return self.controllers.processes

    @property
    def max_error(self) -> float | None:
        """Largest relative difference of any implementation (None unverified)."""
        return None if self.verification is None else self.verification.max_error

    @property
    def errors(self) -> dict[str, float] | None:
        """Implementation and signals -> relative difference (None unverified)."""
        return None if self.verification is None else self.verification.errors

    @property
    def compiler(self) -> str | None:
        """The C compiler used (None: none)."""
        return None if self.verification is None else self.verification.compiler

    @property
    def compile_s(self) -> float | None:
        """Time to compile every process [s] (None: nothing compiled)."""
        return None if self.verification is None else self.verification.compile_s

    def to_dict(self) -> dict[str, Any]:
        """The files, the processes and the verification as JSON-ready values.

        Returns
        -------
        dict
            ``files``, ``processes`` (``name``, ``rate_hz``, ``inputs``, ``outputs``),
            ``max_error``, ``errors``, ``compiler``, ``compile_s``.
        """
        return {"files": [str(p) for p in self.files],
                "processes": [{"name": p.name, "rate_hz": p.rate_hz, "inputs": list(p.inputs),
                               "outputs": list(p.outputs)} for p in self.processes],
                "max_error": self.max_error, "errors": self.errors,
                "compiler": self.compiler, "compile_s": self.compile_s}

    def records(self) -> list[dict[str, Any]]:
        """One flat row per process.

        Returns
        -------
        list of dict
            ``name``, ``rate_hz``, ``inputs`` and ``outputs`` (comma-separated signal
            names).
        """
        return [{"name": p.name, "rate_hz": p.rate_hz, "inputs": ",".join(p.inputs),
                 "outputs": ",".join(p.outputs)} for p in self.processes]

    def plot(self, ax: Any = None) -> Any:
        """The verification's relative errors per implementation (log scale), or each
        process's rate when the export was not verified.

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
        if self.errors:
            names = list(self.errors)
            ax.bar(names, [max(v, 1e-17) for v in self.errors.values()], color="tab:blue")
            ax.set_yscale("log")
            ax.set_ylabel("relative error")
        else:
            ax.bar([p.name for p in self.processes], [p.rate_hz for p in self.processes])
            ax.set_ylabel("rate [Hz]")
        ax.grid(True, axis="y", alpha=0.3)
        return ax


def export_design(diagram: BlockDiagram, design: Any, out: str | os.PathLike, *,
                  languages: Sequence[str] | str = LANGUAGES,
                  rates_hz: Mapping[str, float] | float = 1000.0,
                  saturation: Mapping[str, float] | None = None, verify_export: bool = False,
                  cc: str | None = None, step: float = 0.1) -> ExportResult:
    """Compile, optionally verify (before anything is written), and write an export.

    ``step``: the reference step of the verification's sampled simulation."""
    langs = check_languages(languages)
    out = check_export_dir(out)
    ctl = compile_processes(diagram, design, rates_hz, saturation)
    ver = None
    if verify_export:
        ver = verify(diagram, design, ctl, rates_hz=rates_hz, saturation=saturation,
                     languages=("c", "python"), cc=cc, step=step)
    files = write_export(export_files(ctl, langs), out)
    return ExportResult(files, ctl, ver)
