"""A process's controller in the form that runs on the robot: blocks and run-time parameters.

:func:`program` turns one process of :func:`seactl.codegen.controllers.compile_processes`
into a :class:`Program`: the process's blocks (its own and the static wiring it needs),
each a rational transfer function whose continuous coefficients are expressions of named
parameters (the design's own attributes: ``Kq``, ``Bq``, ``Tf_qd``, ... for the SEA;
each block coefficient ``<edge>__n<i>`` / ``<edge>__d<i>`` for a loop file), plus the output
limits and the watchdog bound.  The generated C and Python compute, whenever the
parameters are set, every block's bilinear (Tustin) discretization at the process's
period and the solution of the process's network of sums, then step:

    w_b = (u_b - sum_i az_b[i] w_b[k-i]) / az_b[0]      (the block's own state history)
    y_b = sum_i bz_b[i] w_b[k-i]                        (direct form II)
    signals = (I - F)^-1 r                              (F: the blocks' feedthrough)

The state of a block is the history of its input filtered by its denominator (in the
units of the block's input), so a parameter change keeps every state and only moves the
coefficients (the bumpless update of docs/export.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy

from seactl.codegen.controllers import Controllers, ProcessController, c_ident, message_name
from seactl.diagram.blockdiagram import Block, BlockDiagram

WATCHDOG_PERIODS = 3
"""Default watchdog bound: this many periods of the slowest command sender."""


@dataclass(frozen=True)
class ProgramBlock:
    """One block: ``dst += num(s)/den(s) src`` (``src`` read ``buffer`` samples late).

    ``num``, ``den``: ``order + 1`` coefficients each (highest power of ``s`` first), each
    an expression tree of parameters (:func:`render` prints it)."""

    name: str
    src: int
    dst: int
    order: int
    buffer: int
    num: tuple[Any, ...]
    den: tuple[Any, ...]
    message: int
    """Index of the message output this block's output is summed into (-1: none)."""


@dataclass(frozen=True)
class Program:
    """Everything the generated C and Python of one process need."""

    name: str
    ident: str
    rate_hz: float
    period_ticks: int
    signals: tuple[str, ...]
    inputs: tuple[str, ...]
    input_signal: tuple[int, ...]
    outputs: tuple[str, ...]
    output_signal: tuple[int, ...]
    """Signal index of each actuation output (-1: a message, the sum of its blocks)."""
    limits: tuple[tuple[str, float] | None, ...]
    """Per output: the limit parameter's name and default (None: no limit, a message)."""
    blocks: tuple[ProgramBlock, ...]
    parameters: dict[str, float]
    commands: tuple[str, ...]
    """Inputs the watchdog guards (references and messages)."""
    watchdog_ticks: int

    @property
    def max_order(self) -> int:
        return max((b.order for b in self.blocks), default=0)


class _Symbols:
    """A design whose attributes are sympy symbols (the names it records)."""

    def __init__(self, design: Any, names: Sequence[str]) -> None:
        self._design, self._names, self.used = design, set(names), set()

    def __getattr__(self, name: str) -> Any:
        if name in self._names:
            self.used.add(name)
            return sympy.Symbol(name)
        return getattr(self._design, name)


def _fields(design: Any) -> dict[str, Any]:
    f = getattr(design, "_fields", None)
    return {k: v for k, v in (f() if f else {}).items() if v is not None}


def _printable(expr: Any) -> bool:
    try:
        render(expr, str, repr)
    except ValueError:
        return False
    return True


def _expressions(block: Block, sym: _Symbols, design: Any) -> tuple[list[Any], list[Any]]:
    """The block's coefficients as expressions of the design's parameters; a coefficient
    the generated code cannot compute (a function of a parameter) is fixed at its value,
    and so is every coefficient of a block whose coefficients are not arithmetic."""
    try:
        with np.errstate(all="ignore"):
            num = [sympy.sympify(c) for c in block.num(sym)]
            den = [sympy.sympify(c) for c in block.den(sym)]
    except (TypeError, AttributeError, ValueError, sympy.SympifyError):
        num_c, den_c = block.coefficients(design)
        return ([sympy.Float(float(np.ravel(c)[0])) for c in num_c],
                [sympy.Float(float(np.ravel(c)[0])) for c in den_c])
    values = {sympy.Symbol(k): float(np.ravel(getattr(design, k))[0]) for k in sym.used}
    fix = lambda e: e if _printable(e) else sympy.Float(float(e.subs(values)))  # noqa: E731
    return [fix(e) for e in num], [fix(e) for e in den]


def _traced(block: Block, sym: _Symbols, design: Any) -> tuple[list[Any], list[Any]]:
    """The block's coefficients as expressions; padded to one order (leading numerator
    zeros dropped first, as the sampled compiler does)."""
    num, den = _expressions(block, sym, design)
    while len(num) > len(den) and num[0] == 0:
        num = num[1:]
    if len(num) > len(den) + 1:
        raise ValueError(f"block {block.name!r}: numerator degree exceeds the "
                         "denominator's by more than one; not realizable")
    q = max(len(num), len(den)) - 1
    zero = sympy.Integer(0)
    return [zero] * (q + 1 - len(num)) + num, [zero] * (q + 1 - len(den)) + den


def program(diagram: BlockDiagram, design: Any, ctl: Controllers, proc: ProcessController
            ) -> Program:
    """The run-time form of ``proc`` (one process of ``ctl``, compiled from ``design``)."""
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    mine = {b.name for b in ctrl if b.process == proc.name}
    local = [b for b in ctrl if b.process in (proc.name, None)]
    msg_in = {message_name(b.dst, b.process): b.dst for b in ctrl
              if b.process not in (proc.name, None)}
    buffers = dict(proc.buffers)
    need_sig: list[str] = []
    need_blk: set[str] = set()

    def need(sig: str) -> None:
        if sig in need_sig:
            return
        need_sig.append(sig)
        for b in local:
            if b.dst == sig and b.name not in need_blk:
                need_blk.add(b.name)
                need(b.src)

    outs_sig = []
    for out in proc.outputs:
        if out in ctl.actuation:
            need(out)
            outs_sig.append(out)
            continue
        outs_sig.append(None)
        for b in local:
            if b.name in mine and message_name(b.dst, proc.name) == out:
                need_blk.add(b.name)
                need(b.src)
    for name in proc.inputs:
        need(msg_in.get(name, name))
    for b in local:   # a message block's own destination (its sum is the message)
        if b.name in need_blk and b.dst not in need_sig:
            need_sig.append(b.dst)
    signals = tuple(need_sig)
    idx = {s: i for i, s in enumerate(signals)}
    fields = _fields(design)
    sym = _Symbols(design, list(fields))
    blocks = []
    for b in local:
        if b.name not in need_blk:
            continue
        num, den = _traced(b, sym, design)
        msg = next((j for j, o in enumerate(proc.outputs)
                    if b.name in mine and o == message_name(b.dst, proc.name)), -1)
        blocks.append(ProgramBlock(b.name, idx[b.src], idx[b.dst], len(den) - 1,
                                   buffers.get(b.name, 0), tuple(num), tuple(den), msg))
    used = set().union(*(e.free_symbols for b in blocks for e in (*b.num, *b.den)))
    params = {k: float(np.ravel(fields[k])[0]) for k in fields if sympy.Symbol(k) in used}
    limits = tuple((f"limit_{c_ident(o)}", lim) if s is not None else None
                   for o, s, lim in zip(proc.outputs, outs_sig, proc.limits))
    commands = tuple(n for n in proc.inputs if n in msg_in or n in ctl.references)
    return Program(proc.name, proc.ident, proc.rate_hz, proc.period_ticks, signals,
                   tuple(proc.inputs), tuple(idx[msg_in.get(n, n)] for n in proc.inputs),
                   tuple(proc.outputs), tuple(-1 if s is None else idx[s] for s in outs_sig),
                   limits, tuple(blocks), params, commands,
                   _watchdog_default(ctl, proc, commands, msg_in))


def _watchdog_default(ctl: Controllers, proc: ProcessController, commands: Sequence[str],
                      msg_in: Mapping[str, str]) -> int:
    """``WATCHDOG_PERIODS`` periods of the slowest sender of a command (this process's
    own period for references); 0 (off) without commands."""
    if not commands:
        return 0
    ratios = [1]
    for p in ctl.processes:
        if any(message_name(msg_in[n], p.name) == n for n in commands if n in msg_in):
            ratios.append(math.ceil(p.period_ticks / proc.period_ticks))
    return WATCHDOG_PERIODS * max(ratios)


def programs(diagram: BlockDiagram, design: Any, ctl: Controllers) -> tuple[Program, ...]:
    """:func:`program` of every process of ``ctl``, in schedule order."""
    return tuple(program(diagram, design, ctl, p) for p in ctl.processes)


# ----------------------------------------------------------------------------- printing
def render(expr: Any, symbol: Callable[[str], str], literal: Callable[[float], str]) -> str:
    """``expr`` (sums, products, integer powers of parameters and numbers) as C or Python
    text: ``symbol(name)`` for a parameter, ``literal(x)`` for a number."""
    e = sympy.sympify(expr)
    if e.is_Symbol:
        return symbol(e.name)
    if e.is_Number:
        x = float(e)
        return f"({literal(x)})" if x < 0 else literal(x)
    args = [render(a, symbol, literal) for a in e.args]
    if e.is_Add:
        return "(" + " + ".join(args) + ")"
    if e.is_Mul:
        return "(" + " * ".join(args) + ")"
    if e.is_Pow and e.exp.is_Integer and int(e.exp) != 0:
        n = int(e.exp)
        prod = " * ".join([args[0]] * abs(n))
        return f"({prod})" if n > 0 else f"({literal(1.0)} / ({prod}))"
    raise ValueError(f"cannot export the coefficient {e} (only sums, products and integer "
                     "powers of parameters)")


# ----------------------------------------------------------------------------- compile
class _NoDelay:
    """``design`` with the named delays zero (the latency is the platform's)."""

    def __init__(self, design: Any, names: Sequence[str]) -> None:
        self._design, self._names = design, set(names)

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._design, name)
        return np.zeros_like(np.asarray(value, float)) if name in self._names else value


def without_delays(diagram: BlockDiagram, design: Any) -> Any:
    """``design`` with every controller delay of ``diagram`` zero."""
    names = [b.delay for b in diagram.blocks if b.delay and b.role != "plant"]
    return _NoDelay(design, names)


def compile_export(diagram: BlockDiagram, design: Any,
                   rates_hz: Mapping[str, float] | float = 1000.0,
                   saturation: Mapping[str, float] | None = None,
                   emulate_latency: bool = False) -> tuple[Controllers, Any]:
    """The per-process controllers with their run-time :class:`Program` s, and the design
    they were compiled from: without ``emulate_latency``, ``design`` with zero delays (no
    buffer), the requested and effective delays of ``design`` still recorded."""
    from dataclasses import replace

    from seactl.codegen.controllers import compile_processes

    ctl = compile_processes(diagram, design, rates_hz, saturation)
    used = design
    if not emulate_latency:
        used = without_delays(diagram, design)
        ctl = replace(compile_processes(diagram, used, rates_hz, saturation),
                      parameters=ctl.parameters, effective_delays_s=ctl.effective_delays_s,
                      requested_delays_s=ctl.requested_delays_s)
    ctl = replace(ctl, emulate_latency=emulate_latency)
    return replace(ctl, programs=programs(diagram, used, ctl)), used
