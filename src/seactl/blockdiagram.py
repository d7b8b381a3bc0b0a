"""Linear block diagrams with exact transport delays.

A :class:`BlockDiagram` is a signal-flow graph: named signals, and SISO
blocks ``dst += G(s) e^{-s T} src`` where ``G`` is a rational function whose
coefficients are computed from a *design* (any object with array-valued
attributes, broadcast together as a batch).  Each signal is the sum of the
blocks that feed it; signals fed by nothing are exogenous inputs.

From the one description every view is derived:

* :meth:`BlockDiagram.transfer` gives any input-to-output transfer function,
  optionally with signals *cut* (made exogenous, e.g. to impose the joint
  motion for an impedance, or to open a loop).  The transfer is solved once
  symbolically in terms of the block responses (sympy, cached) and then
  evaluated numerically for arrays of frequencies and batches of designs.
* :meth:`BlockDiagram.loop` gives the loop transfer function ``L`` seen when
  a sensor signal is broken (``L = -returned / injected``).
* The blocks' num/den/delay data is what a time-domain simulator discretizes.

Frequencies are the last array axis; design batches occupy the leading axes.

Examples
--------
A unity-feedback integrator with a 10 ms delay, ``L = e^{-0.01 s}/s``:

>>> import numpy as np
>>> from types import SimpleNamespace
>>> d = BlockDiagram("integrator", [
...     Block("ctrl", "e", "u", num=lambda p: (p.K,), den=lambda p: (1.0, 0.0),
...           delay="T"),
...     Block("ref", "r", "e"),
...     Block("fb", "y", "e", num=lambda p: (-1.0,)),
...     Block("plant", "u", "y"),
... ])
>>> p = SimpleNamespace(K=np.array(2.0), T=np.array(0.01))
>>> s = 1j * np.array([2.0])
>>> complex(np.round(d.loop("y")(p, s)[0], 6)) == complex(
...     np.round(2 * np.exp(-0.01 * s[0]) / s[0], 6))
True
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any

import numpy as np

Coeffs = Callable[[Any], Sequence[Any]]


def _one(_p: Any) -> tuple[float]:
    return (1.0,)


@dataclass(frozen=True)
class Block:
    """One edge of the diagram: ``dst += num(s)/den(s) * exp(-s*delay) * src``.

    Parameters
    ----------
    name : str
        Unique block name (a symbol in derived expressions).
    src, dst : str
        Input and output signal names.
    num, den : callable
        ``f(design) -> sequence`` of polynomial coefficients in ``s``,
        highest power first; entries may be arrays (a batch of designs).
    delay : str, optional
        Name of the design attribute holding the transport delay [s].
    role : str
        ``"plant"`` (physics) or ``"controller"`` (runs on a processor).
    process : str, optional
        For controller blocks, which processor runs it (e.g. ``"embedded"``,
        ``"high-level"``); used by sampled simulations.
    """

    name: str
    src: str
    dst: str
    num: Coeffs = _one
    den: Coeffs = _one
    delay: str | None = None
    role: str = "controller"
    process: str | None = None

    def coefficients(self, design: Any, dtype: Any = float
                     ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Numerator and denominator coefficient arrays for ``design``."""
        num = [np.asarray(c, dtype=dtype) for c in self.num(design)]
        den = [np.asarray(c, dtype=dtype) for c in self.den(design)]
        return num, den

    def response(self, design: Any, s: np.ndarray) -> np.ndarray:
        """``G(s) exp(-s T)`` for a batch of designs; ``s`` varies on the last axis.

        The precision follows ``s`` (complex64 ``s`` gives a single-precision result)."""
        real = np.float32 if s.dtype == np.complex64 else float
        num, den = self.coefficients(design, real)
        if len(den) > 1:
            out = horner(num, s) / horner(den, s)
        else:
            out = horner(num, s) / den[0][..., None]
        if self.delay is not None:
            delay = np.asarray(getattr(design, self.delay), dtype=real)
            out = out * _delay_factor(s, delay[..., None])
        return out


def _delay_factor(s: np.ndarray, delay: np.ndarray) -> np.ndarray:
    """``exp(-s T)``; on the imaginary axis as ``cos(w T) - j sin(w T)`` (real
    transcendentals, several times faster than the complex exponential)."""
    if np.any(s.real):
        return np.exp(-s * delay)
    x = np.broadcast_to(s.imag * delay, np.broadcast_shapes(s.shape, delay.shape))
    out = np.empty(x.shape, s.dtype)
    out.real = np.cos(x)
    out.imag = -np.sin(x)
    return out


def horner(coeffs: Sequence[np.ndarray], s: np.ndarray) -> np.ndarray:
    """Evaluate a polynomial with array coefficients (highest power first)."""
    if len(coeffs) == 1:
        return np.asarray(coeffs[0])[..., None] + 0j  # broadcasts against s later
    acc = np.asarray(coeffs[0])[..., None] * s + np.asarray(coeffs[1])[..., None]
    for c in coeffs[2:]:
        acc = acc * s + np.asarray(c)[..., None]
    return acc


@dataclass(frozen=True)
class BlockDiagram:
    """A named signal-flow graph of :class:`Block` objects."""

    name: str
    blocks: tuple[Block, ...] | list[Block]

    def __post_init__(self) -> None:
        object.__setattr__(self, "blocks", tuple(self.blocks))
        names = [b.name for b in self.blocks]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate block names in diagram {self.name!r}")

    @cached_property
    def signals(self) -> tuple[str, ...]:
        seen: dict[str, None] = {}
        for b in self.blocks:
            seen.setdefault(b.src)
            seen.setdefault(b.dst)
        return tuple(seen)

    @cached_property
    def inputs(self) -> tuple[str, ...]:
        """Signals no block feeds: the diagram's exogenous inputs."""
        fed = {b.dst for b in self.blocks}
        return tuple(s for s in self.signals if s not in fed)

    def block(self, name: str) -> Block:
        for b in self.blocks:
            if b.name == name:
                return b
        raise KeyError(name)

    def without(self, *names: str) -> BlockDiagram:
        """A copy with the named blocks removed (structural variants)."""
        missing = set(names) - {b.name for b in self.blocks}
        if missing:
            raise KeyError(f"no blocks {sorted(missing)} in diagram {self.name!r}")
        return BlockDiagram(self.name, [b for b in self.blocks if b.name not in names])

    # ------------------------------------------------------------------ views
    def transfer(self, output: str, input: str, cut: Sequence[str] = ()) -> Transfer:
        """Transfer function ``output / input`` with the ``cut`` signals held at zero
        (or driven, if ``input`` is among them): their feeding blocks are ignored."""
        return Transfer(self, output, input, tuple(cut), None)

    def loop(self, sensor: str, cut: Sequence[str] = ()) -> Transfer:
        """Loop transfer ``L`` broken at signal ``sensor``: inject at ``sensor``,
        measure what the blocks feeding ``sensor`` return, ``L = -returned/injected``.
        Other ``cut`` signals are held at zero (their loops stay open)."""
        return Transfer(self, sensor, sensor, tuple(cut), "loop")


@dataclass(frozen=True)
class Transfer:
    """A transfer function of a :class:`BlockDiagram`, callable as ``T(design, s)``."""

    diagram: BlockDiagram
    output: str
    input: str
    cut: tuple[str, ...]
    kind: str | None

    @cached_property
    def _compiled(self) -> tuple[Callable[..., np.ndarray], tuple[Block, ...]]:
        return _compile(self.diagram, self.output, self.input, self.cut, self.kind)

    @property
    def blocks(self) -> tuple[Block, ...]:
        """The blocks the transfer depends on."""
        return self._compiled[1]

    def expression(self) -> Any:
        """The symbolic expression in block names (sympy)."""
        return _symbolic(self.diagram, self.output, self.input, self.cut, self.kind)

    def __call__(self, design: Any, s: np.ndarray | complex,
                 cache: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """Evaluate at complex frequencies ``s`` (last axis) for a design batch.

        ``cache`` (block name -> response) lets several transfers of the same diagram
        share block evaluations for the same ``design`` and ``s``."""
        func, blocks = self._compiled
        s = np.asarray(s)
        if s.dtype != np.complex64:
            s = s.astype(complex)
        if s.ndim == 0:
            s = s[None]
        if cache is None:
            values = [b.response(design, s) for b in blocks]
        else:
            values = []
            for b in blocks:
                if b.name not in cache:
                    cache[b.name] = b.response(design, s)
                values.append(cache[b.name])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            out = func(*values)
        return np.broadcast_to(out, np.broadcast_shapes(*(v.shape for v in values))) \
            if np.ndim(out) == 0 else out


class _NoDesign:
    def __getattr__(self, name: str):
        raise AttributeError(name)


def _constant_gain(b: Block) -> float | None:
    """The block's value if it is an undelayed constant independent of the design."""
    if b.delay is not None:
        return None
    try:
        num, den = b.num(_NoDesign()), b.den(_NoDesign())
    except AttributeError:
        return None
    if len(num) == 1 and len(den) == 1 and all(isinstance(c, (int, float)) for c in (*num, *den)):
        return float(num[0]) / float(den[0])
    return None


class DesignBatch:
    """Mixin for (frozen dataclass) design batches: :meth:`_fields` names the arrays the
    diagram's blocks read; they are broadcast together once and served as attributes,
    with the common batch shape as ``shape``."""

    def _fields(self) -> dict[str, Any]:
        raise NotImplementedError

    @cached_property
    def _arrays(self) -> dict[str, np.ndarray]:
        raw = self._fields()
        arrays = np.broadcast_arrays(*(np.asarray(v, float) for v in raw.values()))
        return dict(zip(raw, arrays, strict=True))

    def __getattr__(self, name: str) -> np.ndarray:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._arrays[name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def shape(self) -> tuple[int, ...]:
        return next(iter(self._arrays.values())).shape


class DesignSubset:
    """Elements ``idx`` of a flattened design batch, with the same attribute access."""

    def __init__(self, design: Any, idx: np.ndarray, shape: tuple[int, ...]):
        self._design, self._idx, self._shape = design, idx, shape

    @property
    def shape(self) -> tuple[int, ...]:
        return (int(np.size(self._idx)),)

    def __getattr__(self, name: str) -> np.ndarray:
        if name.startswith("_"):
            raise AttributeError(name)
        value = np.broadcast_to(np.asarray(getattr(self._design, name)), self._shape)
        return value.reshape(-1)[self._idx]


def _cache_dir() -> Path | None:
    """Where derived expressions persist between runs (``SEACTL_CACHE_DIR``; ``off``
    disables)."""
    env = os.environ.get("SEACTL_CACHE_DIR")
    if env == "off":
        return None
    base = Path(env) if env else Path(os.environ.get("XDG_CACHE_HOME",
                                                      Path.home() / ".cache")) / "seactl"
    return base


def _structure_key(diagram: BlockDiagram, output: str, input: str, cut: tuple[str, ...],
                   kind: str | None) -> str:
    """Hash of everything the symbolic solution depends on: the wiring, which blocks
    are constants (and their values), the query, and the sympy version."""
    import sympy as sp

    parts = [f"v1|{sp.__version__}|{output}|{input}|{','.join(cut)}|{kind}"]
    for b in diagram.blocks:
        parts.append(f"{b.name}|{b.src}|{b.dst}|{_constant_gain(b)!r}")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:32]


@lru_cache(maxsize=256)
def _symbolic(diagram: BlockDiagram, output: str, input: str, cut: tuple[str, ...],
              kind: str | None) -> Any:
    """The transfer as a sympy expression of block names, derived once and kept on disk
    (the derivation takes seconds for larger diagrams; loading it, milliseconds)."""
    import sympy as sp

    folder = _cache_dir()
    path = folder / f"{_structure_key(diagram, output, input, cut, kind)}.srepr" \
        if folder else None
    if path is not None and path.is_file():
        try:
            return sp.sympify(path.read_text())
        except (SyntaxError, TypeError, ValueError):  # a damaged entry: derive again
            pass
    expr = _derive(diagram, output, input, cut, kind)
    if path is not None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(sp.srepr(expr))
            os.replace(tmp, path)
        except OSError:  # read-only home, full disk: the cache is only an optimization
            pass
    return expr


def _derive(diagram: BlockDiagram, output: str, input: str, cut: tuple[str, ...],
            kind: str | None) -> Any:
    import sympy as sp

    if kind == "loop":
        held = set(cut) | {input}
        ret = "__return__"
        # The sensor becomes an input; what fed it now feeds a virtual return signal.
        edges = [(b.name, b.src, ret if b.dst == input else b.dst) for b in diagram.blocks]
        target = ret
    else:
        held = set(cut)
        edges = [(b.name, b.src, b.dst) for b in diagram.blocks]
        target = output
    signals = {e[1] for e in edges} | {e[2] for e in edges}
    for name in (input, target):
        if name not in signals:
            raise KeyError(f"signal {name!r} not in diagram {diagram.name!r}")
    exogenous = (set(diagram.inputs) | held) - ({ret} if kind == "loop" else set())
    unknowns = sorted(signals - exogenous)
    index = {n: i for i, n in enumerate(unknowns)}
    # Constant undelayed blocks (sums, sensors, sign changes) need no evaluation.
    sym = {}
    for b in diagram.blocks:
        const = _constant_gain(b)
        sym[b.name] = sp.Symbol(b.name) if const is None else sp.nsimplify(const)
    A = sp.eye(len(unknowns))
    rhs = sp.zeros(len(unknowns), 1)
    for name, src, dst in edges:
        if dst in exogenous:
            continue
        if src in index:
            A[index[dst], index[src]] -= sym[name]
        elif src == input:
            rhs[index[dst]] += sym[name]
    if target == input:
        expr = sp.Integer(1)
    elif target not in index:
        expr = sp.Integer(0)
    else:
        # Cramer's rule on the (sparse) graph determinant: one ratio of determinants.
        col = index[target]
        Ai = A.copy()
        Ai[:, col] = rhs
        expr = sp.cancel(Ai.det(method="berkowitz") / A.det(method="berkowitz"))
    if kind == "loop":
        expr = -expr
    return sp.factor(expr)


@lru_cache(maxsize=256)
def _compile(diagram: BlockDiagram, output: str, input: str, cut: tuple[str, ...],
             kind: str | None) -> tuple[Callable[..., np.ndarray], tuple[Block, ...]]:
    import sympy as sp

    expr = _symbolic(diagram, output, input, cut, kind)
    used = sorted(str(x) for x in expr.free_symbols)
    blocks = tuple(diagram.block(n) for n in used)
    func = sp.lambdify([sp.Symbol(n) for n in used], expr, modules="numpy", cse=True)
    return func, blocks
