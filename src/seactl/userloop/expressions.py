"""Expressions of a loop file: parsed once, evaluated on a design batch."""

from __future__ import annotations

import ast
import functools
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.limits import (
    MAX_EXPR_CHARS,
    MAX_EXPR_DEPTH,
)
from seactl.errors import LoopFileError

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
