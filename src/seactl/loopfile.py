"""Loop files: user-defined control loops, compiled onto the one block diagram.

A loop file (TOML, docs/loops.md) or a :class:`seactl.LoopBuilder` describes a loop as
named blocks between named signals, with design variables, processes, loop-break points
and impedance ports.  This module validates that description (pydantic for the shape,
then the structure: connections, properness, algebraic loops, unbroken controller loops,
processes) and compiles it into a :class:`~seactl.blockdiagram.BlockDiagram` plus a
:class:`LoopDesign` batch, so every view of :mod:`seactl.blockdiagram` (transfers, loops
with exact delays), :mod:`seactl.margins` and :mod:`seactl.simulate` applies unchanged.

Blocks are SISO edges ``output += G(s) e^{-s T} input``; a signal is the sum of the blocks
that feed it.  ``input`` may be a list of signed signals (``["q_des", "-q_meas"]``): a
summing junction in front of the block.  Numeric fields take numbers or expressions of
the design variables (:func:`parse_expr`: ``"m * (2*pi*fn)^2"``), evaluated with numpy, so
a variable given as an array makes a batch of designs.
"""

from __future__ import annotations

import ast
import functools
import keyword
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from ._validate import float_array
from .blockdiagram import Block, BlockDiagram, DesignBatch
from .errors import LoopFileError
from .limits import (
    MAX_EXPR_CHARS,
    MAX_EXPR_DEPTH,
    MAX_LOOP_BLOCKS,
    MAX_LOOP_NAMES,
    MAX_LOOP_ORDER,
    MAX_LOOP_SIGNALS,
    MAX_NESTING,
    RANGES,
    derive_seconds,
    human_seconds,
)

# ------------------------------------------------------------------ expressions
FUNCTIONS: dict[str, Callable[..., Any]] = {
    "sqrt": np.sqrt, "exp": np.exp, "log": np.log, "log10": np.log10, "sin": np.sin,
    "cos": np.cos, "tan": np.tan, "atan": np.arctan, "abs": np.abs,
    "min": lambda *a: functools.reduce(np.minimum, a),
    "max": lambda *a: functools.reduce(np.maximum, a), "hypot": np.hypot}
"""Functions an expression may call."""

ARITY: dict[str, tuple[int, int | None]] = {
    **{f: (1, 1) for f in FUNCTIONS}, "min": (2, None), "max": (2, None), "hypot": (2, 2)}
"""Each function's fewest and most arguments (``None``: any number)."""

CONSTANTS = {"pi": math.pi, "e": math.e}
"""Names every expression knows."""

_BINOPS = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
           ast.Div: np.true_divide, ast.Pow: np.power}
_ALLOWED = ("numbers, names, + - * / ^ ** ( ) and the functions "
            + ", ".join(FUNCTIONS))
NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class Expr:
    """A parsed numeric field: a number, or an arithmetic expression of names."""

    text: str
    tree: Any
    names: frozenset[str]

    def __call__(self, env: Mapping[str, Any]) -> np.ndarray:
        with np.errstate(all="ignore"):
            return np.asarray(_eval(self.tree, env), float)


def parse_expr(value: Any, file: str, where: str, known: Sequence[str] | None = None
               ) -> Expr:
    """Parse a number or an expression string (``^`` is the power, as ``**``).

    Only numbers, names, ``+ - * / ^ **``, parentheses and :data:`FUNCTIONS` are
    accepted (the syntax tree is checked against that whitelist; nothing is executed).
    ``known`` (if given) lists the names it may use besides :data:`CONSTANTS`.

    Examples
    --------
    >>> e = parse_expr("m * (2*pi*fn)^2", "f.toml", "parameter 'Kq'", ["m", "fn"])
    >>> round(float(e({"m": 0.014, "fn": 14.0, **CONSTANTS})), 4)
    108.3288
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise LoopFileError(file, where, value, "a number or an expression string")
    if not isinstance(value, str):
        number = _number(value)
        if number is None or math.isnan(number):  # inf passes: "no filter" for filter_hz
            raise LoopFileError(file, where, value, "a number within the floating-point "
                                "range")
        return Expr(repr(number), ast.Constant(number), frozenset())
    if len(value) > MAX_EXPR_CHARS:
        raise LoopFileError(file, where, value[:40] + "...", f"an expression of at most "
                            f"{MAX_EXPR_CHARS} characters (this one has {len(value)})")
    try:
        tree = ast.parse(value.replace("^", "**").strip(), mode="eval").body
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        raise LoopFileError(file, where, value, "an expression of " + _ALLOWED
                            + f", nested at most {MAX_EXPR_DEPTH} deep") from None
    if _depth(tree) > MAX_EXPR_DEPTH:
        raise LoopFileError(file, where, value, f"an expression nested at most "
                            f"{MAX_EXPR_DEPTH} deep (operators, parentheses and calls)")
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            if not (isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS
                    and not node.keywords):
                raise LoopFileError(file, where, value, "calls only to " + ", ".join(FUNCTIONS))
            _check_arity(node, value, file, where)
        elif isinstance(node, ast.Name):
            names.add(node.id)
        elif isinstance(node, ast.Constant):
            if _number(node.value) is None:
                raise LoopFileError(file, where, value, "an expression of " + _ALLOWED
                                    + " (numbers within the floating-point range)")
        elif not isinstance(node, (ast.BinOp, ast.UnaryOp, ast.Load, ast.UAdd, ast.USub,
                                   *(_BINOPS))):
            raise LoopFileError(file, where, value, f"an expression of {_ALLOWED} "
                                f"(found {type(node).__name__})")
    calls = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call)}
    names = {n for n in names if n not in calls or _is_operand(tree, n)} - set(CONSTANTS)
    if known is not None:
        unknown = sorted(names - set(known))
        if unknown:
            raise LoopFileError(file, where, value, f"unknown name {unknown[0]!r}; known: "
                                + ", ".join([*known, *CONSTANTS]))
    return Expr(value, tree, frozenset(names))


def _number(value: Any) -> float | None:
    """``value`` as a float, or None if it is no number (a bool, a string) or too large."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        return float(value)
    except OverflowError:
        return None


def _depth(tree: Any) -> int:
    """Nesting depth of a syntax tree (iterative: a deep one must not exhaust the stack)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        stack.extend((child, d + 1) for child in ast.iter_child_nodes(node)
                     if not isinstance(child, (ast.Load, ast.operator, ast.unaryop)))
    return deepest


def _check_arity(node: ast.Call, value: str, file: str, where: str) -> None:
    name = node.func.id  # type: ignore[attr-defined]
    lo, hi = ARITY[name]
    n = len(node.args)
    if n < lo or (hi is not None and n > hi) or any(isinstance(a, ast.Starred)
                                                      for a in node.args):
        count = f"{lo}" if lo == hi else f"at least {lo}" if hi is None else f"{lo} to {hi}"
        raise LoopFileError(file, where, value, f"{name}() with {count} argument"
                            f"{'' if lo == hi == 1 else 's'} (it has {n})")


def _is_operand(tree: Any, name: str) -> bool:
    """Whether ``name`` appears other than as a called function."""
    funcs = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
    return any(isinstance(n, ast.Name) and n.id == name and id(n) not in funcs
               for n in ast.walk(tree))


def _eval(node: Any, env: Mapping[str, Any]) -> Any:
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return env[node.id] if node.id in env else CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval(node.left, env), _eval(node.right, env))
    if isinstance(node, ast.UnaryOp):
        val = _eval(node.operand, env)
        return -val if isinstance(node.op, ast.USub) else val
    return FUNCTIONS[node.func.id](*(_eval(a, env) for a in node.args))


# ------------------------------------------------------------------ block kinds
@dataclass(frozen=True)
class Kind:
    """A block kind: role, parameters (name -> (default or None if required, check)) and
    its transfer ``tf(values) -> (num, den)`` (coefficients highest power first)."""

    role: str
    params: dict[str, tuple[Any, str]]
    tf: Callable[[dict[str, Any]], tuple[list[Any], list[Any]]]
    doc: str
    derivative: bool = False  # numerator one degree above the denominator allowed


def _tc(f_hz: Any) -> Any:
    """Time constant 1/(2 pi f) [s]; inf -> 0 (no filter)."""
    return np.where(np.isinf(f_hz), 0.0, 1.0 / (2 * np.pi * np.asarray(f_hz, float)))


def _pid(v: dict[str, Any]) -> tuple[list[Any], list[Any]]:
    tf = _tc(v["filter_hz"])
    return ([v["kp"] * tf + v["kd"], v["kp"] + v["ki"] * tf, v["ki"]], [tf, 1.0, 0.0])


def _w(v: dict[str, Any], key: str = "f_hz") -> Any:
    return 2 * np.pi * v[key]


_R, _P, _N, _A = "required", "> 0", ">= 0", "any"
KINDS: dict[str, Kind] = {
    # physics (role plant)
    "inertia": Kind("plant", {"inertia": (None, _P), "damping": (0.0, _N)},
                    lambda v: ([1.0], [v["inertia"], v["damping"], 0.0]),
                    "position = torque / (inertia s^2 + damping s)"),
    "load": Kind("plant", {"inertia": (None, _P), "damping": (0.0, _N), "stiffness": (0.0, _N)},
                 lambda v: ([1.0], [v["inertia"], v["damping"], v["stiffness"]]),
                 "position = torque / (inertia s^2 + damping s + stiffness)"),
    "spring": Kind("plant", {"stiffness": (None, _P)}, lambda v: ([v["stiffness"]], [1.0]),
                   "torque = stiffness * deflection"),
    "damper": Kind("plant", {"damping": (None, _N)}, lambda v: ([v["damping"], 0.0], [0.0, 1.0]),
                   "torque = damping * s * deflection", derivative=True),
    "plant_tf": Kind("plant", {"num": (None, "list"), "den": (None, "list")},
                     lambda v: (list(v["num"]), list(v["den"])), "num(s) / den(s), proper"),
    "current_to_torque": Kind("plant", {"constant": (None, _P)},
                              lambda v: ([v["constant"]], [1.0]), "torque = constant * current"),
    # controllers (role controller) and sensors
    "gain": Kind("controller", {"gain": (None, _A)}, lambda v: ([v["gain"]], [1.0]), "gain"),
    "sum": Kind("controller", {}, lambda v: ([1.0], [1.0]), "sum of the signed inputs"),
    "delay": Kind("controller", {}, lambda v: ([1.0], [1.0]), "pure delay (delay_ms)"),
    "sensor": Kind("sensor", {"gain": (1.0, _A)}, lambda v: ([v["gain"]], [1.0]),
                   "measurement of a plant signal"),
    "pd": Kind("controller", {"kp": (0.0, _A), "kd": (0.0, _A), "filter_hz": (math.inf, _P)},
               lambda v: ([v["kp"] * _tc(v["filter_hz"]) + v["kd"], v["kp"]],
                          [_tc(v["filter_hz"]), 1.0]),
               "kp + kd s / (s/(2 pi filter_hz) + 1)", derivative=True),
    "pid": Kind("controller", {"kp": (0.0, _A), "ki": (0.0, _A), "kd": (0.0, _A),
                               "filter_hz": (math.inf, _P)}, _pid,
                "kp + ki/s + kd s / (s/(2 pi filter_hz) + 1)", derivative=True),
    "lowpass1": Kind("controller", {"f_hz": (None, _P), "gain": (1.0, _A)},
                     lambda v: ([v["gain"]], [1.0 / _w(v), 1.0]), "gain / (s/(2 pi f_hz) + 1)"),
    "lowpass2": Kind("controller", {"f_hz": (None, _P), "zeta": (math.sqrt(0.5), _P),
                                    "gain": (1.0, _A)},
                     lambda v: ([v["gain"] * _w(v) ** 2], [1.0, 2 * v["zeta"] * _w(v),
                                                           _w(v) ** 2]),
                     "gain w^2 / (s^2 + 2 zeta w s + w^2), w = 2 pi f_hz"),
    "notch": Kind("controller", {"f_hz": (None, _P), "zeta_num": (0.0, _N),
                                 "zeta_den": (0.5, _P)},
                  lambda v: ([1.0, 2 * v["zeta_num"] * _w(v), _w(v) ** 2],
                             [1.0, 2 * v["zeta_den"] * _w(v), _w(v) ** 2]),
                  "(s^2 + 2 zeta_num w s + w^2) / (s^2 + 2 zeta_den w s + w^2)"),
    "leadlag": Kind("controller", {"gain": (1.0, _A), "zero_hz": (None, _P),
                                   "pole_hz": (None, _P)},
                    lambda v: ([v["gain"] / _w(v, "zero_hz"), v["gain"]],
                               [1.0 / _w(v, "pole_hz"), 1.0]),
                    "gain (s/(2 pi zero_hz) + 1) / (s/(2 pi pole_hz) + 1)"),
    "tf": Kind("controller", {"num": (None, "list"), "den": (None, "list")},
               lambda v: (list(v["num"]), list(v["den"])), "num(s) / den(s), proper"),
    "dob": Kind("controller", {"nominal_num": (None, "list"), "nominal_den": (None, "list"),
                               "q_hz": (None, _P), "q_order": (2, "int")},
                lambda v: ([1.0], [1.0]),
                "u = input - Q (Pn^-1 measurement - u), Q = 1/(s/(2 pi q_hz) + 1)^q_order"),
}
"""The block library (docs/loops.md lists each kind's fields)."""

_COMMON = {"name", "kind", "input", "output", "process", "delay_ms", "measurement",
           "description"}


# ------------------------------------------------------------------ file schema
class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ProcessModel(_Model):
    rate_hz: float = Field(1000.0, gt=0, allow_inf_nan=False, description="rate [Hz]")
    latency_ms: float | str = Field(0.0, description="latency of a block with delay_ms = "
                                    "'process' [ms]: number or expression")


class BreakModel(_Model):
    name: str
    signal: str
    description: str = ""


class PortModel(_Model):
    name: str
    position: str
    force: str
    sign: float = Field(-1.0, description="Z = sign * force / (s position)")


class SignalsModel(_Model):
    inputs: list[str] = []
    reference: str | None = None
    disturbance: str | None = None
    output: str | None = None
    reference_step: float | None = Field(None, allow_inf_nan=False, description="the "
                                         "default step of the reference (its unit)")
    reference_unit: str | None = Field(None, max_length=40, description="the unit of the "
                                       "reference, e.g. rad or m")

    @field_validator("reference_step")
    @classmethod
    def _nonzero_step(cls, v: float | None) -> float | None:
        if v is not None and v == 0:
            raise ValueError("a non-zero step")
        return v


class AnalysisModel(_Model):
    f_min_hz: float | None = Field(None, ge=RANGES["freq_hz"][0], le=RANGES["freq_hz"][1],
                                   allow_inf_nan=False)
    f_max_hz: float | None = Field(None, ge=RANGES["freq_hz"][0], le=RANGES["freq_hz"][1],
                                   allow_inf_nan=False)


class BlockModel(BaseModel):
    model_config = ConfigDict(extra="allow")

    name: str
    kind: str
    input: str | list[str]
    output: str
    process: str | None = None
    delay_ms: float | str | None = None
    measurement: str | None = None
    description: str = ""


class LoopFileModel(_Model):
    name: str = "loop"
    description: str = ""
    default_process: str | None = None
    variables: dict[str, float] = {}
    parameters: dict[str, float | str] = {}
    processes: dict[str, ProcessModel] = {}
    blocks: list[BlockModel] = Field(min_length=1)
    breaks: list[BreakModel] = []
    ports: list[PortModel] = []
    signals: SignalsModel = SignalsModel()
    analysis: AnalysisModel = AnalysisModel()


def validation_error(exc: ValidationError, file: str, data: Mapping[str, Any]) -> LoopFileError:
    """The first pydantic error as a :class:`LoopFileError` naming block and field."""
    err = exc.errors()[0]
    loc = list(err["loc"])
    where = ".".join(str(p) for p in loc)
    if len(loc) >= 2 and loc[0] in ("blocks", "breaks", "ports") and isinstance(loc[1], int):
        items = data.get(loc[0]) or []
        item = items[loc[1]] if loc[1] < len(items) and isinstance(items[loc[1]], dict) else {}
        label = f"{loc[0][:-1]} {item.get('name', '#' + str(loc[1] + 1))!r}"
        where = label + (f", field {'.'.join(str(p) for p in loc[2:])!r}" if loc[2:] else "")
    elif loc and loc[0] == "variables" and len(loc) > 1:
        where = f"variable {loc[1]!r}"
    if err["type"] == "missing":
        return LoopFileError(file, where, None, "required field missing")
    if err["type"] == "extra_forbidden":
        return LoopFileError(file, where, err.get("input"), "unknown key")
    if loc and loc[0] == "variables":
        return LoopFileError(file, where, err.get("input"),
                             "a number (expressions go under [parameters])")
    return LoopFileError(file, where, err.get("input"), err["msg"].lower())


def _known_keys(model: type[BaseModel], loc: Sequence[Any]) -> str:
    """The keys valid where an unknown key was found (for the error message)."""
    fields = model.model_fields
    for part in loc[:-1]:
        info = fields.get(str(part)) if isinstance(part, str) else None
        ann = getattr(info, "annotation", None) if info is not None else None
        sub = next((a for a in getattr(ann, "__args__", (ann,)) if isinstance(a, type)
                    and issubclass(a, BaseModel)), None)
        if sub is None:
            continue
        fields = sub.model_fields
    return ", ".join(fields)


# ------------------------------------------------------------------ size
_TOML_STRINGS = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:\\.|[^"\\\n])*"'
                           r"|'[^'\n]*'|#[^\n]*")
_TOML_KEY = re.compile(r"^\s*([^=\s\[\]{}][^=\n]*?)\s*=", re.M)


def check_toml_nesting(text: str, file: str) -> None:
    """Refuse TOML text whose arrays or inline tables nest deeper than
    :data:`~seactl.limits.MAX_NESTING` (before parsing it: the parser recurses), naming
    the key where it happens."""
    bare = _TOML_STRINGS.sub(lambda m: "\n" * m.group().count("\n") or "s", text)
    depth, key, table = 0, "", ""
    for lineno, line in enumerate(bare.splitlines(), 1):
        if depth == 0:
            head = line.strip()
            if head.startswith("["):
                table = head.strip("[] ")
                continue
            m = _TOML_KEY.match(line)
            key = (f"{table}." if table else "") + (m.group(1).strip() if m else "")
        for ch in line:
            depth += 1 if ch in "[{" else -1 if ch in "]}" else 0
            if depth > MAX_NESTING:
                raise LoopFileError(file, f"key {key!r} (line {lineno})", None,
                                    f"arrays and tables nested at most {MAX_NESTING} deep")
        depth = max(depth, 0)


def check_nesting(data: Any, file: str) -> None:
    """Refuse loop tables (as parsed, or collected by a builder) nested deeper than
    :data:`~seactl.limits.MAX_NESTING`, naming the path (iterative: no recursion)."""
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    while stack:
        node, path, d = stack.pop()
        if d > MAX_NESTING:
            shown = path if len(path) <= 60 else path[:57] + "..."
            raise LoopFileError(file, f"key {shown!r}", None,
                                f"arrays and tables nested at most {MAX_NESTING} deep")
        if isinstance(node, Mapping):
            stack.extend((v, f"{path}.{k}" if path else str(k), d + 1) for k, v in node.items())
        elif isinstance(node, (list, tuple)):
            stack.extend((v, f"{path}[{i}]", d + 1) for i, v in enumerate(node))


def check_size(file: str, n_blocks: int, n_signals: int = 0, order: int = 0) -> None:
    """Refuse a loop larger than :mod:`seactl.limits` allows, with the estimate: more
    blocks or signals than :data:`~seactl.limits.MAX_LOOP_BLOCKS` /
    :data:`~seactl.limits.MAX_LOOP_SIGNALS` (the symbolic derivation grows as the cube
    of the signals) or an order above :data:`~seactl.limits.MAX_LOOP_ORDER`."""
    if n_blocks > MAX_LOOP_BLOCKS or n_signals > MAX_LOOP_SIGNALS:
        what, n, lim = (("blocks", n_blocks, MAX_LOOP_BLOCKS) if n_blocks > MAX_LOOP_BLOCKS
                        else ("signals", n_signals, MAX_LOOP_SIGNALS))
        n_sig = max(n_signals, n_blocks)
        raise LoopFileError(file, "[[blocks]]", None, f"at most {lim} {what} (this loop has "
                            f"{n}: deriving its transfers would take about "
                            f"{human_seconds(derive_seconds(n_sig))} or more, growing as the "
                            "cube of its signals)")
    if order > MAX_LOOP_ORDER:
        raise LoopFileError(file, "[[blocks]]", None, f"a loop of order at most "
                            f"{MAX_LOOP_ORDER} (this one has order {order}, the sum of its "
                            "blocks' orders: its characteristic polynomial's coefficients "
                            "would lose its roots in double precision, and overflow near "
                            "order 100)")


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
class BlockSpec:
    """A validated user block: its kind, signed inputs and parsed parameters."""

    name: str
    kind: str
    inputs: tuple[tuple[float, str], ...]
    output: str
    measurement: str | None
    process: str | None
    delay_ms: Expr | str | None
    params: dict[str, Any]

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
                                    [*kind.params, *sorted(_COMMON - {'name', 'kind'})]))
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
    delay = _block_delay(bm, kind, label, file, known, process)
    return BlockSpec(name, bm.kind, inputs, output, meas, process, delay, params)


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
                 process: str | None) -> Expr | str | None:
    if bm.delay_ms is None:
        if bm.kind == "delay":
            raise LoopFileError(file, f"{label}, field 'delay_ms'", None,
                                "required for kind 'delay' (milliseconds)")
        return None
    if kind.role == "plant":
        raise LoopFileError(file, f"{label}, field 'delay_ms'", bm.delay_ms,
                            "absent: delays belong to controller and sensor blocks")
    if bm.delay_ms == "process":
        if process is None:
            raise LoopFileError(file, f"{label}, field 'delay_ms'", "process",
                                "a block on a process (delay_ms = 'process' takes its latency)")
        return "process"
    return parse_expr(bm.delay_ms, file, f"{label}, field 'delay_ms'", known)


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
_RANGE_OK = {_P: lambda v: v > 0, _N: lambda v: v >= 0, _A: lambda v: np.isfinite(v)}


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
                                        "finite" if check in (_A, "list") else f"{check} "
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
                    if not np.all((ms >= 0) & (ms <= 1000)):
                        raise LoopFileError(self.file, f"block {b.name!r}, field 'delay_ms'",
                                            float(np.min(ms)) if np.any(ms < 0) else
                                            float(np.max(ms)), ">= 0 and <= 1000 ms")
                    out[f"{e.name}__T"] = ms / 1e3
        return out

    def latencies(self, env: Mapping[str, Any], latency_ms: Mapping[str, Any] | None = None
                  ) -> dict[str, np.ndarray]:
        """Each process's latency [ms] (its expression evaluated, or the override)."""
        out = {}
        for p, m in self.model.processes.items():
            expr = parse_expr(m.latency_ms, self.file, f"process {p!r}, field 'latency_ms'",
                              self.names)
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
                                + _known_keys(LoopFileModel, exc.errors()[0]["loc"]))
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
