"""Loop files: user-defined control loops, compiled onto the one block diagram.

A loop file (TOML, docs/loops.md) or a :class:`seactl.LoopBuilder` describes a loop as
named blocks between named signals, with design variables, processes, loop-break points
and impedance ports.  This module validates that description (pydantic for the shape,
then the structure: connections, properness, algebraic loops, unbroken controller loops,
processes) and compiles it into a :class:`~seactl.diagram.blockdiagram.BlockDiagram` plus a
:class:`LoopDesign` batch, so every view of :mod:`seactl.diagram.blockdiagram` (transfers, loops
with exact delays), :mod:`seactl.analysis.margins` and :mod:`seactl.simulate.engine` applies
unchanged.

Blocks are SISO edges ``output += G(s) e^{-s T} input``; a signal is the sum of the blocks
that feed it.  ``input`` may be a list of signed signals (``["q_des", "-q_meas"]``): a
summing junction in front of the block.  Numeric fields take numbers or expressions of
the design variables (:func:`parse_expr`: ``"m * (2*pi*fn)^2"``), evaluated with numpy, so
a variable given as an array makes a batch of designs.
"""

from __future__ import annotations

import keyword
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import ValidationError

from seactl.base.limits import (
    MAX_LOOP_NAMES,
)
from seactl.base.validate import float_array
from seactl.diagram.blockdiagram import Block, BlockDiagram, DesignBatch
from seactl.errors import LoopFileError
from seactl.userloop.expressions import CONSTANTS, FUNCTIONS, NAME_RE, Expr, parse_expr
from seactl.userloop.schema import (
    ANY,
    COMMON_BLOCK_KEYS,
    GE0,
    GT0,
    KINDS,
    BlockModel,
    Kind,
    LoopFileModel,
    SignalsModel,
    check_nesting,
    check_size,
    known_keys,
    validation_error,
)


# ------------------------------------------------------------------ compiled loops
@dataclass(frozen=True)
class Edge:
    """One edge of the compiled diagram, with how its coefficients are computed."""

    name: str
    block: str
    src: str
    dst: str
    role: str
    process: str | None
    coeffs: Callable[[dict[str, Any]], tuple[list[Any], list[Any]]] | None
    const: float | None = None
    delay_ms: Expr | str | None = None
    derivative: bool = False
    internal: bool = False  # a DOB's own loop (1/(1-Q): stable, one pole at the origin)


@dataclass(frozen=True, eq=False)
class LoopDesign(DesignBatch):
    """A batch of designs of a compiled loop: one array per block coefficient and delay
    (``<edge>__n<i>``, ``<edge>__d<i>``, ``<edge>__T`` [s]) plus the variables' values."""

    arrays: dict[str, Any]

    def _fields(self) -> dict[str, Any]:
        return self.arrays


def signed(token: str, file: str, where: str) -> tuple[float, str]:
    """``"-x"`` -> ``(-1, "x")``; ``"x"`` / ``"+x"`` -> ``(1, "x")``."""
    tok = token.strip()
    sign = -1.0 if tok.startswith("-") else 1.0
    name = tok.lstrip("+-").strip()
    if not NAME_RE.match(name) or "__" in name:
        raise LoopFileError(file, where, token, "a signal name (letters, digits, _; starting "
                            "with a letter; no '__'), optionally signed: '-x'")
    return sign, name


def check_name(name: str, file: str, what: str) -> str:
    if not isinstance(name, str) or not NAME_RE.match(name) or "__" in name \
            or keyword.iskeyword(name) or name in CONSTANTS or name in FUNCTIONS:
        raise LoopFileError(file, what, name, "a name of letters, digits and _ starting with a "
                            "letter (no '__', no Python keyword, not pi, e or a function)")
    return name


def parameter_order(variables: Mapping[str, Any], parameters: Mapping[str, Any], file: str
                    ) -> dict[str, Expr]:
    """Parse ``parameters`` (expressions of variables and other parameters) and order them so
    each comes after the names it uses; a cycle or an unknown name is an error."""
    for name in [*variables, *parameters]:
        check_name(name, file, f"variable or parameter name {name!r}")
    both = set(variables) & set(parameters)
    if both:
        raise LoopFileError(file, f"parameter {sorted(both)[0]!r}", None,
                            "defined both as a variable and as a parameter")
    known = [*variables, *parameters]
    parsed = {n: parse_expr(v, file, f"parameter {n!r}", known) for n, v in parameters.items()}
    order: dict[str, Expr] = {}
    pending = dict(parsed)
    while pending:
        ready = [n for n, e in pending.items() if not (e.names & set(pending))]
        if not ready:
            raise LoopFileError(file, f"parameter {sorted(pending)[0]!r}", None,
                                "circular definition among parameters " + ", ".join(
                                    sorted(pending)))
        for n in ready:
            order[n] = pending.pop(n)
    return order


# ------------------------------------------------------------------ blocks
@dataclass(frozen=True)
class Delay:
    """A block's delay as the file gives it: the expression and its field, ``delay_ms``
    (milliseconds) or ``delay_s`` (seconds); called, the delay [ms]."""

    expr: Expr
    field: str

    def __call__(self, env: Mapping[str, Any]) -> np.ndarray:
        value = self.expr(env)
        return value * 1e3 if self.field == "delay_s" else value


@dataclass(frozen=True)
class BlockSpec:
    """A validated user block: its kind, signed inputs and parsed parameters;
    ``delay_ms`` is its :class:`Delay`, ``"process"`` or None, ``delay_field`` the field
    that gave it."""

    name: str
    kind: str
    inputs: tuple[tuple[float, str], ...]
    output: str
    measurement: str | None
    process: str | None
    delay_ms: Delay | str | None
    params: dict[str, Any]
    delay_field: str = "delay_ms"

    @property
    def role(self) -> str:
        return KINDS[self.kind].role


def _param(kind: Kind, key: str, value: Any, file: str, where: str, known: Sequence[str]
           ) -> Any:
    check = kind.params[key][1]
    if check == "list":
        if not isinstance(value, list) or not value:
            raise LoopFileError(file, where, value, "a non-empty list of coefficients "
                                "(highest power of s first)")
        return [parse_expr(v, file, f"{where}[{i}]", known) for i, v in enumerate(value)]
    if check == "int":
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 4:
            raise LoopFileError(file, where, value, "an integer from 1 to 4")
        return value
    return parse_expr(value, file, where, known)


def parse_block(data: Mapping[str, Any], file: str, known: Sequence[str],
                processes: Mapping[str, Any], default_process: str | None) -> BlockSpec:
    """Validate one block table (kind, fields, signals, process, delay) into a BlockSpec."""
    try:
        bm = BlockModel.model_validate(dict(data))
    except ValidationError as exc:
        raise validation_error(exc, file, {"blocks": [data]}) from None
    name = check_name(bm.name, file, "block name")
    label = f"block {name!r}"
    if bm.kind not in KINDS:
        raise LoopFileError(file, f"{label}, field 'kind'", bm.kind, "one of " + ", ".join(KINDS))
    kind = KINDS[bm.kind]
    extra = dict(bm.model_extra or {})
    for key in extra:
        if key not in kind.params:
            raise LoopFileError(file, f"{label}, field {key!r}", extra[key],
                                f"a field of kind {bm.kind!r}: " + ", ".join(
                                    [*kind.params, *sorted(COMMON_BLOCK_KEYS - {'name', 'kind'})]))
    params = {}
    for key, (default, _check) in kind.params.items():
        if key not in extra and default is None:
            raise LoopFileError(file, f"{label}, field {key!r}", None,
                                f"required for kind {bm.kind!r} ({kind.doc})")
        params[key] = _param(kind, key, extra.get(key, default), file, f"{label}, field {key!r}",
                             known)
    raw = [bm.input] if isinstance(bm.input, str) else list(bm.input)
    if not raw:
        raise LoopFileError(file, f"{label}, field 'input'", raw, "at least one signal")
    inputs = tuple(signed(t, file, f"{label}, field 'input'") for t in raw)
    _, output = signed(bm.output, file, f"{label}, field 'output'")
    if bm.output.strip().startswith(("-", "+")):
        raise LoopFileError(file, f"{label}, field 'output'", bm.output, "an unsigned signal")
    meas = None
    if bm.kind == "dob":
        if bm.measurement is None:
            raise LoopFileError(file, f"{label}, field 'measurement'", None,
                                "required for kind 'dob' (the measured plant output)")
        meas = signed(bm.measurement, file, f"{label}, field 'measurement'")[1]
    elif bm.measurement is not None:
        raise LoopFileError(file, f"{label}, field 'measurement'", bm.measurement,
                            "used only by kind 'dob'")
    process = _block_process(bm, kind, label, file, processes, default_process)
    delay, field = _block_delay(bm, kind, label, file, known, process)
    return BlockSpec(name, bm.kind, inputs, output, meas, process, delay, params, field)


def _block_process(bm: BlockModel, kind: Kind, label: str, file: str,
                   processes: Mapping[str, Any], default_process: str | None) -> str | None:
    if kind.role == "plant":
        if bm.process is not None:
            raise LoopFileError(file, f"{label}, field 'process'", bm.process,
                                "absent: physical blocks run on no process")
        return None
    process = bm.process or default_process or (next(iter(processes))
                                                if len(processes) == 1 else None)
    if process is None and kind.role == "controller":
        raise LoopFileError(file, f"{label}, field 'process'", None,
                            "a process: " + (", ".join(processes) if processes else
                                             "declare one under [processes.NAME]")
                            + " (or set default_process)")
    if process is not None and process not in processes:
        raise LoopFileError(file, f"{label}, field 'process'", process,
                            "a declared process: " + (", ".join(processes) or "none declared"))
    return process


def _block_delay(bm: BlockModel, kind: Kind, label: str, file: str, known: Sequence[str],
                 process: str | None) -> tuple[Delay | str | None, str]:
    """The block's delay (``delay_ms`` or ``delay_s``, not both) and the field giving it."""
    if bm.delay_ms is not None and bm.delay_s is not None:
        raise LoopFileError(file, f"{label}, fields 'delay_ms' and 'delay_s'",
                            f"{bm.delay_ms!r} and {bm.delay_s!r}",
                            "one of the two (milliseconds or seconds)")
    field = "delay_s" if bm.delay_s is not None else "delay_ms"
    value = getattr(bm, field)
    if value is None:
        if bm.kind == "delay":
            raise LoopFileError(file, f"{label}, field 'delay_ms' or 'delay_s'", None,
                                "required for kind 'delay' (milliseconds or seconds)")
        return None, field
    if kind.role == "plant":
        raise LoopFileError(file, f"{label}, field {field!r}", value,
                            "absent: delays belong to controller and sensor blocks")
    if value == "process":
        if process is None:
            raise LoopFileError(file, f"{label}, field {field!r}", "process",
                                f"a block on a process ({field} = 'process' takes its latency)")
        return "process", field
    return Delay(parse_expr(value, file, f"{label}, field {field!r}", known), field), field


def _polymul(a: Sequence[Any], b: Sequence[Any]) -> list[Any]:
    out: list[Any] = [0.0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] = out[i + j] + np.multiply(x, y)
    return out


def _q_filter(v: dict[str, Any]) -> tuple[list[Any], list[Any]]:
    """Binomial Q-filter ``1 / (tau s + 1)^n``."""
    den: list[Any] = [1.0]
    for _ in range(int(v["q_order"])):
        den = _polymul(den, [1.0 / (2 * np.pi * v["q_hz"]), 1.0])
    return [1.0], den


def _dob_inverse(v: dict[str, Any]) -> tuple[list[Any], list[Any]]:
    qn, qd = _q_filter(v)
    return _polymul(qn, v["nominal_den"]), _polymul(qd, v["nominal_num"])


def _dob_q(v: dict[str, Any]) -> tuple[list[Any], list[Any]]:
    qn, qd = _q_filter(v)
    return [-c for c in qn], qd


def block_edges(b: BlockSpec) -> list[Edge]:
    """The diagram edges of one user block (a junction in front of signed or several
    inputs; a disturbance observer expands into its four edges)."""
    role, proc = b.role, b.process
    edges: list[Edge] = []
    src = b.inputs[0][1]
    if len(b.inputs) > 1 or b.inputs[0][0] != 1.0:
        src = f"{b.name}__in"
        for i, (sign, sig) in enumerate(b.inputs):
            edges.append(Edge(f"{b.name}__in{i}", b.name, sig, src, role, proc, None, sign))
    kind = KINDS[b.kind]
    if b.kind == "dob":
        dhat = f"{b.name}__dhat"
        edges += [Edge(f"{b.name}__cmd", b.name, src, b.output, role, proc, None, 1.0),
                  Edge(f"{b.name}__inv", b.name, b.measurement, dhat, role, proc, _dob_inverse,
                       delay_ms=b.delay_ms),
                  Edge(f"{b.name}__q", b.name, b.output, dhat, role, proc, _dob_q,
                       internal=True),
                  Edge(f"{b.name}__fb", b.name, dhat, b.output, role, proc, None, -1.0)]
        return edges
    edges.append(Edge(b.name, b.name, src, b.output, role, proc, kind.tf, delay_ms=b.delay_ms,
                      derivative=kind.derivative))
    return edges


# ------------------------------------------------------------------ the compiled loop
_RANGE_OK = {GT0: lambda v: v > 0, GE0: lambda v: v >= 0, ANY: lambda v: np.isfinite(v)}


@dataclass(frozen=True, eq=False)
class CompiledLoop:
    """A validated loop: its diagram and how each design's arrays are computed."""

    file: str
    model: LoopFileModel
    variables: dict[str, float]
    parameters: dict[str, Expr]
    blocks: tuple[BlockSpec, ...]
    edges: tuple[Edge, ...]
    diagram: BlockDiagram

    @property
    def names(self) -> list[str]:
        return [*self.variables, *self.parameters]

    @property
    def breaks_signals(self) -> list[str]:
        return [b.signal for b in self.model.breaks]

    def environment(self, values: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Variables (overridden by ``values``) and parameters, evaluated in order; an
        override of a parameter replaces its expression."""
        unknown = sorted(set(values) - set(self.names))
        if unknown:
            raise LoopFileError(self.file, f"--set {unknown[0]}", None,
                                "a variable or parameter of the loop: " + ", ".join(self.names))
        given = {n: float_array(n, v) for n, v in values.items()}
        for n, v in given.items():
            if v.size == 0:
                raise LoopFileError(self.file, f"--set {n}", None, "at least one value")
        try:
            np.broadcast_shapes(*(v.shape for v in given.values()))
        except ValueError:
            raise LoopFileError(self.file, "--set", {n: v.shape for n, v in given.items()},
                                "values whose shapes broadcast together") from None
        env: dict[str, np.ndarray] = {}
        for n, v in self.variables.items():
            env[n] = given.get(n, np.asarray(v, float))
        for n, e in self.parameters.items():
            env[n] = given[n] if n in given else e(env)
        for n, v in env.items():
            if not np.all(np.isfinite(v)):
                raise LoopFileError(self.file, f"variable or parameter {n!r}",
                                    float(v[~np.isfinite(v)].flat[0]) if v.ndim else float(v),
                                    "a finite value")
        return env

    def block_values(self, b: BlockSpec, env: Mapping[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, p in b.params.items():
            check = KINDS[b.kind].params[key][1]
            if check == "int":
                out[key] = p
                continue
            vals = [e(env) for e in p] if check == "list" else [p(env)]
            for v in vals:
                ok = np.isfinite(v) | ((key == "filter_hz") & (v == np.inf))
                ok &= _RANGE_OK[check](v) if check in _RANGE_OK else True
                if not np.all(ok):
                    bad = float(np.asarray(v)[~np.asarray(ok)].flat[0]) if np.ndim(v) \
                        else float(v)
                    raise LoopFileError(self.file, f"block {b.name!r}, field {key!r}", bad,
                                        "finite" if check in (ANY, "list") else f"{check} "
                                        "and finite")
            out[key] = vals if check == "list" else vals[0]
        return out

    def arrays(self, values: Mapping[str, Any] = {},
               latency_ms: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Every block coefficient and delay for the designs ``values`` describe;
        ``latency_ms`` overrides the processes' latencies (placements)."""
        env = self.environment(values)
        lat = self.latencies(env, latency_ms)
        out: dict[str, Any] = {f"var__{n}": v for n, v in env.items()}
        for b in self.blocks:
            vals = self.block_values(b, env)
            for e in (x for x in self.edges if x.block == b.name):
                if e.coeffs is not None:
                    num, den = e.coeffs(vals)
                    out.update({f"{e.name}__n{i}": c for i, c in enumerate(num)})
                    out.update({f"{e.name}__d{i}": c for i, c in enumerate(den)})
                if e.delay_ms is not None:
                    ms = np.asarray(lat[b.process] if e.delay_ms == "process"
                                    else e.delay_ms(env), float)
                    ok = (ms >= 0) & np.isfinite(ms)
                    if not np.all(ok):
                        unit = 1e-3 if b.delay_field == "delay_s" else 1.0
                        raise LoopFileError(self.file, f"block {b.name!r}, field "
                                            f"{b.delay_field!r}", float(ms[~ok].flat[0]) * unit,
                                            ">= 0 and finite")
                    out[f"{e.name}__T"] = ms / 1e3
        return out

    def latencies(self, env: Mapping[str, Any], latency_ms: Mapping[str, Any] | None = None
                  ) -> dict[str, np.ndarray]:
        """Each process's latency [ms] (its expression evaluated, or the override)."""
        out = {}
        for p, m in self.model.processes.items():
            if m.latency_ms is not None and m.latency_s is not None:
                raise LoopFileError(self.file, f"process {p!r}, fields 'latency_ms' and "
                                    "'latency_s'", f"{m.latency_ms!r} and {m.latency_s!r}",
                                    "one of the two (milliseconds or seconds)")
            field = "latency_s" if m.latency_s is not None else "latency_ms"
            expr = Delay(parse_expr(getattr(m, field) or 0.0, self.file,
                                    f"process {p!r}, field {field!r}", self.names),
                         "delay_s" if field == "latency_s" else "delay_ms")
            given = (latency_ms or {}).get(p)
            out[p] = expr(env) if given is None else float_array(f"latency_ms {p}", given)
            if out[p].size == 0:
                raise LoopFileError(self.file, f"process {p!r}, latency", None,
                                    "at least one value")
        return out

    def design(self, values: Mapping[str, Any] = {},
               latency_ms: Mapping[str, Any] | None = None) -> LoopDesign:
        return LoopDesign(self.arrays(values, latency_ms))


def _diagram_block(e: Edge, n_num: int, n_den: int) -> Block:
    if e.coeffs is None:
        c = float(e.const)
        return Block(e.name, e.src, e.dst, num=lambda p, c=c: (c,), role=e.role,
                     process=e.process)
    num = tuple(f"{e.name}__n{i}" for i in range(n_num))
    den = tuple(f"{e.name}__d{i}" for i in range(n_den))
    return Block(e.name, e.src, e.dst,
                 num=lambda p, k=num: tuple(getattr(p, a) for a in k),
                 den=lambda p, k=den: tuple(getattr(p, a) for a in k),
                 delay=f"{e.name}__T" if e.delay_ms is not None else None,
                 role=e.role, process=e.process)


def degree(coeffs: Sequence[Any]) -> int:
    """Polynomial degree over a batch: the first coefficient non-zero in any design."""
    for i, c in enumerate(coeffs):
        if np.any(np.asarray(c) != 0):
            return len(coeffs) - 1 - i
    return -1


def compile_loop(data: Mapping[str, Any], file: str) -> CompiledLoop:
    """Validate a loop description (the TOML tables, or what a builder collected) and
    compile it onto a block diagram.

    Raises
    ------
    LoopFileError
        Naming the file, the block and field (or variable, break, port), the value and
        what is valid.
    """
    check_nesting(data, file)
    if isinstance(data.get("blocks"), list):
        check_size(file, len(data["blocks"]))
    names = sum(len(data[k]) for k in ("variables", "parameters")
                if isinstance(data.get(k), Mapping))
    if names > MAX_LOOP_NAMES:
        raise LoopFileError(file, "[variables] and [parameters]", None, f"at most "
                            f"{MAX_LOOP_NAMES} names (this loop has {names})")
    try:
        model = LoopFileModel.model_validate(dict(data))
    except ValidationError as exc:
        err = validation_error(exc, file, data)
        if exc.errors()[0]["type"] == "extra_forbidden":
            err = LoopFileError(file, err.where, err.value, "unknown key; valid here: "
                                + known_keys(LoopFileModel, exc.errors()[0]["loc"]))
        raise err from None
    for p in model.processes:
        check_name(p.replace("-", "_"), file, f"process name {p!r}")
    params = parameter_order(model.variables, model.parameters, file)
    known = [*model.variables, *params]
    blocks, seen = [], set()
    for raw in data["blocks"]:
        b = parse_block(raw, file, known, model.processes, model.default_process)
        if b.name in seen:
            raise LoopFileError(file, f"block {b.name!r}", None, "duplicate block name")
        seen.add(b.name)
        blocks.append(b)
    edges = tuple(e for b in blocks for e in block_edges(b))
    check_size(file, len(blocks), len({e.src for e in edges} | {e.dst for e in edges}))
    proto = CompiledLoop(file, model, dict(model.variables), params, tuple(blocks), edges,
                         BlockDiagram(model.name, []))
    nominal = proto.arrays()
    sizes = {e.name: tuple(sum(1 for k in nominal if re.fullmatch(rf"{e.name}__{x}\d+", k))
                           for x in "nd") for e in edges}
    check_size(file, len(blocks), order=sum(max(sizes[e.name]) - 1 for e in edges
                                            if e.coeffs is not None))
    diagram = BlockDiagram(model.name, [_diagram_block(e, *sizes[e.name]) for e in edges])
    loop = CompiledLoop(file, model, dict(model.variables), params, tuple(blocks), edges,
                        diagram)
    check_structure(loop, nominal)
    return loop


# ------------------------------------------------------------------ structure
def _path(edges: Sequence[Edge], start: str, goal: str) -> list[Edge] | None:
    """Edges of a shortest path from signal ``start`` to ``goal`` (``[]`` if equal)."""
    adj: dict[str, list[Edge]] = {}
    for e in edges:
        adj.setdefault(e.src, []).append(e)
    prev: dict[str, Edge | None] = {start: None}
    queue = [start]
    while queue:
        s = queue.pop(0)
        if s == goal:
            out = []
            while prev[s] is not None:
                out.append(prev[s])
                s = prev[s].src
            return out[::-1]
        for e in adj.get(s, ()):
            if e.dst not in prev:
                prev[e.dst] = e
                queue.append(e.dst)
    return None


def has_loop(edges: Sequence[Edge], signal: str, cut: Sequence[str] = ()) -> bool:
    """Whether anything ``signal`` feeds comes back to it with the ``cut`` signals held."""
    kept = [e for e in edges if e.dst not in cut]
    return any(_path(kept, signal, e.src) is not None for e in kept if e.dst == signal)


def _cycle(edges: Sequence[Edge]) -> list[Edge] | None:
    for e in edges:
        p = _path(edges, e.dst, e.src)
        if p is not None:
            return [e, *p]
    return None


def _blocks_text(cycle: Sequence[Edge]) -> str:
    names = list(dict.fromkeys(e.block for e in cycle))
    return "blocks " + " -> ".join(names)


def _check_connections(loop: CompiledLoop) -> set[str]:
    file, declared = loop.file, loop.model.signals.inputs
    fed = {}
    for e in loop.edges:
        fed.setdefault(e.dst, e)
    for s in declared:
        if s in fed:
            raise LoopFileError(file, "[signals] inputs", s, "exogenous signals only; it is "
                                f"fed by block {fed[s].block!r}")
    for e in loop.edges:
        if e.src not in fed and e.src not in declared:
            field = "measurement" if e.name.endswith("__inv") else "input"
            raise LoopFileError(file, f"block {e.block!r}, field {field!r}", e.src,
                                "a connected signal: it is fed by no block (unconnected "
                                "input); connect it or list it in [signals] inputs")
    return set(fed)


def _direct_edges(loop: CompiledLoop, nominal: Mapping[str, Any]) -> list[Edge]:
    """Check properness; return the edges that pass their input through instantly."""
    direct = []
    for e in loop.edges:
        feedthrough = True
        if e.coeffs is not None:
            num = [v for k, v in nominal.items() if re.fullmatch(rf"{e.name}__n\d+", k)]
            den = [v for k, v in nominal.items() if re.fullmatch(rf"{e.name}__d\d+", k)]
            dn, dd = degree(num), degree(den)
            if dd < 0:
                raise LoopFileError(loop.file, f"block {e.block!r}", None,
                                    "a non-zero denominator")
            if dn > dd + (1 if e.derivative else 0):
                raise LoopFileError(loop.file, f"block {e.block!r}", None,
                                    f"a proper transfer: numerator degree {dn} > denominator "
                                    f"degree {dd} (improper)")
            feedthrough = dn >= dd
        delayed = e.delay_ms is not None and np.all(nominal[f"{e.name}__T"] > 0)
        if feedthrough and not delayed:
            direct.append(e)
    return direct


def check_structure(loop: CompiledLoop, nominal: Mapping[str, Any]) -> None:
    """Connections, properness, algebraic loops, breaks on every controller loop, ports,
    signals (each a :class:`LoopFileError` naming the blocks involved)."""
    file, m = loop.file, loop.model
    fed = _check_connections(loop)
    cyc = _cycle(_direct_edges(loop, nominal))
    if cyc:
        raise LoopFileError(file, _blocks_text(cyc), None, "an algebraic loop: every block "
                            "on it passes its input through instantly (no dynamics, no delay)")
    breaks = {b.signal for b in m.breaks}
    cut = [e for e in loop.edges if e.dst not in breaks and not e.internal]
    for e in cut:
        p = _path(cut, e.dst, e.src) if e.role != "plant" else None
        if p is not None:
            sigs = [x for x in dict.fromkeys([e.dst] + [x.dst for x in p]) if "__" not in x]
            raise LoopFileError(file, _blocks_text([e, *p]), None, "a feedback loop without a "
                                "break point: add a [[breaks]] entry on one of its signals ("
                                + ", ".join(sigs) + ")")
    _check_named(m.breaks, "break", file)
    for b in m.breaks:
        if b.signal not in fed:
            raise LoopFileError(file, f"break {b.name!r}, field 'signal'", b.signal,
                                "a signal fed by a block")
        if not has_loop(loop.edges, b.signal):
            raise LoopFileError(file, f"break {b.name!r}, field 'signal'", b.signal,
                                "a signal on a feedback loop (nothing it feeds comes back)")
    _check_named(m.ports, "port", file)
    signals = set(loop.diagram.signals)
    for p in m.ports:
        if p.position not in fed:
            raise LoopFileError(file, f"port {p.name!r}, field 'position'", p.position,
                                "a signal fed by a block (the imposed motion)")
        if p.force not in signals:
            raise LoopFileError(file, f"port {p.name!r}, field 'force'", p.force,
                                "a signal of the loop")
        if p.sign not in (-1.0, 1.0):
            raise LoopFileError(file, f"port {p.name!r}, field 'sign'", p.sign, "-1 or 1")
    _check_signals(m.signals, signals, file)


def _check_named(items: Sequence[Any], what: str, file: str) -> None:
    seen = set()
    for it in items:
        check_name(it.name, file, f"{what} name")
        if it.name in seen:
            raise LoopFileError(file, f"{what} {it.name!r}", None, f"a unique {what} name")
        seen.add(it.name)


def _check_signals(sig: SignalsModel, signals: set[str], file: str) -> None:
    for key in ("reference", "disturbance"):
        val = getattr(sig, key)
        if val is not None and val not in sig.inputs:
            raise LoopFileError(file, f"[signals] {key}", val,
                                "one of [signals] inputs: " + ", ".join(sig.inputs))
    if sig.output is not None and sig.output not in signals:
        raise LoopFileError(file, "[signals] output", sig.output, "a signal of the loop")
