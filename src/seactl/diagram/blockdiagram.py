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
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property, lru_cache, reduce
from typing import Any

import numpy as np

from seactl.base.usercache import cache_dir
from seactl.errors import InputError

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

    @cached_property
    def _by_name(self) -> dict[str, Block]:
        return {b.name: b for b in self.blocks}

    def block(self, name: str) -> Block:
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(name) from None

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

    def characteristic(self, cut: Sequence[str] = ()) -> QuasiForm:
        """The characteristic quasi-polynomial of the diagram with the ``cut`` signals held
        at zero: ``prod_b den_b(s) * det(I - A(s))`` over the blocks' responses ``A``, a
        sum of polynomials times ``e^{-s tau}`` (see :class:`QuasiForm`)."""
        return _quasi_form(self, tuple(sorted(cut)), None)

    def return_difference(self, sensor: str, cut: Sequence[str] = ()) -> tuple[
            QuasiForm, QuasiForm]:
        """``(N, D)`` with ``L = N / D`` for :meth:`loop` ``(sensor, cut)``: ``D`` is the
        characteristic quasi-polynomial with ``sensor`` (and ``cut``) held, ``N + D`` the
        one with only ``cut`` held (``1 + L`` is their ratio, the return difference)."""
        held = tuple(sorted(set(cut) | {sensor}))
        return _quasi_form(self, tuple(sorted(cut)), held), _quasi_form(self, held, None)

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


def constant_gain(b: Block) -> float | None:
    """The block's value if it is an undelayed constant independent of the design (the
    symbolic derivation and the cycle expansion substitute such blocks by their value).

    Parameters
    ----------
    b : Block
        A block.

    Returns
    -------
    float or None
        Its constant gain, or None if it is delayed or reads the design.
    """
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


def _structure_key(diagram: BlockDiagram, output: str, input: str, cut: tuple[str, ...],
                   kind: str | None) -> str:
    """Hash of everything the symbolic solution depends on: the wiring, which blocks
    are constants (and their values), the query, and the sympy version."""
    from importlib.metadata import version  # not sympy itself: a cache hit needs no sympy

    parts = [f"v1|{version('sympy')}|{output}|{input}|{','.join(cut)}|{kind}"]
    for b in diagram.blocks:
        parts.append(f"{b.name}|{b.src}|{b.dst}|{constant_gain(b)!r}")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:32]


@lru_cache(maxsize=256)
def _symbolic(diagram: BlockDiagram, output: str, input: str, cut: tuple[str, ...],
              kind: str | None) -> Any:
    """The transfer as a sympy expression of block names, derived once and kept on disk
    (the derivation takes seconds for larger diagrams; loading it, milliseconds)."""

    key = _structure_key(diagram, output, input, cut, kind)
    expr = _cache_load(key)
    if expr is None:
        expr = _derive(diagram, output, input, cut, kind)
        _cache_store(key, expr)
    return expr


def _cache_read(name: str) -> str | None:
    """The text of disk-cache entry ``name``, or None (absent, or the cache disabled)."""
    folder = cache_dir()
    path = folder / name if folder else None
    return path.read_text() if path is not None and path.is_file() else None


def _cache_write(name: str, text: str) -> None:
    """Keep an entry on disk (atomically); a read-only home or a full disk only costs speed."""
    from seactl.base.outputs import write_atomic
    from seactl.errors import OutputError

    folder = cache_dir()
    if folder is not None:
        try:
            write_atomic(folder / name, text)
        except OutputError:
            pass


def _cache_load(key: str) -> Any:
    """A derived expression from the disk cache, or None (absent, disabled or damaged)."""
    text = _cache_read(f"{key}.srepr")
    if text is not None:
        import sympy as sp

        try:
            return sp.sympify(text)
        except (SyntaxError, TypeError, ValueError):  # a damaged entry: derive again
            pass
    return None


def _cache_store(key: str, expr: Any) -> None:
    import sympy as sp

    _cache_write(f"{key}.srepr", sp.srepr(expr))


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
        const = constant_gain(b)
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


# --------------------------------------------------------------------- quasi-polynomials
@dataclass(frozen=True)
class QuasiPolynomial:
    """``Q(s) = sum_k p_k(s) e^{-s tau_k}`` for a batch of designs.

    ``coeffs`` has shape ``(K,) + batch + (n + 1,)`` (ascending powers of ``s``: entry
    ``j`` multiplies ``s^j``), ``delays`` shape ``(K,) + batch`` [s].  Term 0 is the
    undelayed one; terms may have zero delay for some designs.
    """

    coeffs: np.ndarray
    delays: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        return self.coeffs.shape[1:-1]

    def __call__(self, s: np.ndarray, derivative: bool = False) -> np.ndarray:
        """``Q(s)`` (or ``dQ/ds``) with ``s`` of shape ``batch + (F,)``."""
        if derivative:
            return self.with_derivative(s)[1]
        ex = np.exp(-s * self.delays[..., None].astype(s.real.dtype))
        c = self.coeffs.astype(s.real.dtype)[..., None, :]
        acc = c[..., -1] + 0 * s
        for j in range(c.shape[-1] - 2, -1, -1):
            acc = acc * s + c[..., j]
        return (acc * ex).sum(axis=0)

    def with_derivative(self, s: np.ndarray, second: bool = False) -> tuple[np.ndarray, ...]:
        """``(Q(s), dQ/ds)``, and ``d^2Q/ds^2`` if ``second``, in one Horner pass."""
        real = s.real.dtype
        c = self.coeffs if self.coeffs.dtype == real else self.coeffs.astype(real)
        c = c[..., None, :]
        tau = self.delays[..., None].astype(real, copy=False)
        p: Any = c[..., -1]
        dp: Any = 0.0
        d2p: Any = 0.0
        for j in range(c.shape[-1] - 2, -1, -1):
            if second:
                d2p = d2p * s + 2 * dp
            dp = dp * s + p
            p = p * s + c[..., j]
        p, dp, d2p = (np.broadcast_to(x, tau.shape[:-1] + s.shape[-1:]) if np.ndim(x) else
                      np.zeros(tau.shape[:-1] + s.shape[-1:], s.dtype) for x in (p, dp, d2p))
        ex = np.exp(-s * tau)
        out = ((p * ex).sum(axis=0), ((dp - tau * p) * ex).sum(axis=0))
        if second:
            out += (((d2p - 2 * tau * dp + tau * tau * p) * ex).sum(axis=0),)
        return out

    def take(self, idx: np.ndarray) -> QuasiPolynomial:
        """Designs ``idx`` of a flat (1-D) batch."""
        return QuasiPolynomial(self.coeffs[:, idx], self.delays[:, idx])

    def flat(self) -> QuasiPolynomial:
        """The batch flattened to one axis."""
        k, n1 = self.coeffs.shape[0], self.coeffs.shape[-1]
        return QuasiPolynomial(self.coeffs.reshape(k, -1, n1), self.delays.reshape(k, -1))

    def __add__(self, other: QuasiPolynomial) -> QuasiPolynomial:
        """The sum (undelayed terms merged into term 0)."""
        n1 = max(self.coeffs.shape[-1], other.coeffs.shape[-1])
        a, b = (pad_powers(q.coeffs, n1) for q in (self, other))
        coeffs = np.concatenate([(a[0] + b[0])[None], a[1:], b[1:]])
        return QuasiPolynomial(coeffs, np.concatenate([self.delays, other.delays[1:]]))

    @cached_property
    def degree(self) -> np.ndarray:
        """Degree of the undelayed term per design (trailing zero coefficients dropped)."""
        return _last_true(self.coeffs[0] != 0)

    @cached_property
    def delayed_degree(self) -> np.ndarray:
        """Highest degree among the delayed terms (terms ``k >= 1``) per design."""
        return _last_true((self.coeffs[1:] != 0).any(axis=0))

    @property
    def neutral(self) -> np.ndarray:
        """Per design, a delayed term has the degree of the undelayed one: a neutral (or
        advanced) delay equation, whose roots reach the imaginary axis at infinite
        frequency, so neither the certified scans nor the root finder apply."""
        return self.delayed_degree >= self.degree

    def require_retarded(self, what: str) -> None:
        """Raise :class:`~seactl.errors.InputError` where the equation is :attr:`neutral`."""
        if np.any(self.neutral):
            raise InputError(what, "a neutral delay equation",
                             "retarded: some block on every delayed feedback loop must roll "
                             "off (a strictly proper plant or a filter such as lowpass1); here "
                             "the loop passes high frequencies through its delay")

    @cached_property
    def abs_coeffs(self) -> np.ndarray:
        """``sum_k |c_kj|`` per design and power (for modulus bounds)."""
        return np.abs(self.coeffs).sum(axis=0)

    @cached_property
    def bound3_coeffs(self) -> np.ndarray:
        """Per design and power of ``w`` (ascending), the coefficients of a bound of
        ``|d^3 Q(jw)/dw^3|`` that increases with ``w >= 0``:
        ``sum_kj |c_kj| |d^3/dw^3 (w^j e^{-j w tau_k})|`` majorized term by term (product
        rule with ``|e^{-j w tau}| = 1``)."""
        from seactl.diagram.majorants import bound3  # (compiled: numba loads on first use)

        k, n1 = self.coeffs.shape[0], self.coeffs.shape[-1]
        tau = np.ascontiguousarray(self.delays, float).reshape(k, -1)
        c = bound3(np.ascontiguousarray(self.coeffs, float).reshape(k, -1, n1), tau, tau**3)
        return c.reshape(self.shape + (n1,))


_DELAY_SEP = "+"


def _structure(diagram: BlockDiagram, cut: tuple[str, ...], minus: tuple[str, ...] | None):
    """Terms of ``det(I - A)`` (held: ``cut``), minus the one with ``minus`` held if given,
    expanded in block symbols: ``[(coef, blocks), ...]``; kept on disk as JSON (a cache
    hit needs no sympy: worker processes and the command line start faster)."""
    name = _structure_key(diagram, "", "", cut, f"terms|{minus and ','.join(minus)}") + ".json"
    text = _cache_read(name)
    if text is not None:
        try:
            return [(float(c), tuple(b)) for c, b in json.loads(text)]
        except (ValueError, TypeError):  # a damaged entry: derive again
            pass
    terms = _expand_terms(diagram, cut, minus)
    _cache_write(name, json.dumps(terms))
    return terms


def _expand_terms(diagram: BlockDiagram, cut: tuple[str, ...], minus: tuple[str, ...] | None):
    import sympy as sp

    expr = _determinant(diagram, cut)
    if minus is not None:
        expr = sp.expand(expr - _determinant(diagram, minus))
    names = sorted(str(x) for x in expr.free_symbols)
    if not names:
        return [(float(expr), ())] if expr != 0 else []
    poly = sp.Poly(expr, *[sp.Symbol(n) for n in names])
    terms = []
    for exps, coef in poly.terms():
        if any(e > 1 for e in exps):
            raise ValueError(f"diagram {diagram.name!r}: a block appears twice in a loop term")
        terms.append((float(coef), tuple(n for n, e in zip(names, exps) if e)))
    return terms


@lru_cache(maxsize=64)
def _quasi_form(diagram: BlockDiagram, cut: tuple[str, ...], minus: tuple[str, ...] | None
                ) -> QuasiForm:
    return QuasiForm(diagram, _structure(diagram, cut, minus))


@dataclass(frozen=True)
class QuasiForm:
    """A characteristic quasi-polynomial of a diagram, structurally: every term of
    ``prod_b den_b(s) det(I - A(s))`` is a coefficient times the numerators of the blocks
    on its loops, the denominators of all other non-constant blocks and the product of
    their delays.  :meth:`evaluate` turns it into a :class:`QuasiPolynomial` for a design
    batch (undelayed terms first)."""

    diagram: BlockDiagram
    terms: list

    def __hash__(self) -> int:
        return id(self)

    @cached_property
    def dynamic(self) -> tuple[Block, ...]:
        """Blocks that are not design-independent constants (their denominators multiply)."""
        return tuple(b for b in self.diagram.blocks if constant_gain(b) is None)

    @cached_property
    def _terms(self) -> list[tuple[float, frozenset, tuple[str, ...]]]:
        """Per term: its coefficient, its blocks and the sorted names of their delays."""
        block = self.diagram.block
        return [(coef, frozenset(blocks),
                 tuple(sorted(block(n).delay for n in blocks if block(n).delay is not None)))
                for coef, blocks in self.terms]

    def evaluate(self, design: Any, shared: dict | None = None) -> QuasiPolynomial:
        """The quasi-polynomial of ``design``; ``shared``: a dict kept between the
        forms of one diagram evaluated for the same design (a loop's ``N`` and ``D``),
        whose blocks' coefficients and partial products they then compute once."""
        shape = tuple(getattr(design, "shape", ()))
        keys, coeffs = self.grouped(design, shared)
        delays = np.stack([np.broadcast_to(sum((np.asarray(getattr(design, d), float)
                                                for d in k), np.zeros(shape)), shape)
                           for k in keys])
        return QuasiPolynomial(coeffs, delays)

    def grouped(self, design: Any, shared: dict | None = None
                ) -> tuple[list[tuple[str, ...]], np.ndarray]:
        """The terms of ``design`` grouped by their delays: ``(keys, coeffs)``, ``keys[k]``
        the sorted names of the design's delay attributes whose sum delays term ``k``
        (``()`` first: the undelayed term), ``coeffs`` of shape
        ``(len(keys),) + batch + (n + 1,)`` as :class:`QuasiPolynomial`'s."""
        shape = tuple(getattr(design, "shape", ()))
        shared = {} if shared is None else shared
        # (powers first while multiplying: each power's coefficients are contiguous)
        factors: dict[tuple[str, bool], np.ndarray] = shared.setdefault("factors", {})
        for b in self.dynamic:
            if (b.name, True) in factors:
                continue
            num, den = b.coefficients(design)
            factors[b.name, True] = _powers_first(num, shape)
            if len(den) > 1 or np.any(np.asarray(den[0]) != 1):  # (1: nothing to multiply)
                factors[b.name, False] = _powers_first(den, shape)
        groups: dict[tuple[str, ...], np.ndarray] = {}
        # a term's product depends only on its blocks: computed once per design (the
        # forms of one diagram share most of their terms)
        leaves: dict[frozenset, np.ndarray] = shared.setdefault("terms", {})
        for coef, blocks, delays in self._terms:
            poly = leaves.get(blocks)
            if poly is None:
                poly = leaves[blocks] = self._product(blocks, factors, shared, shape)
            poly = coef * poly
            groups[delays] = poly if delays not in groups else _polyadd(groups[delays], poly)
        keys = sorted(groups, key=lambda k: (len(k), k))
        if not keys or keys[0] != ():
            keys.insert(0, ())
            groups[()] = np.zeros((1,) + shape)
        n1 = max(g.shape[0] for g in groups.values())
        coeffs = np.zeros((len(keys),) + shape + (n1,))  # (terms, designs, powers)
        for i, k in enumerate(keys):  # (+ 0: no -0 coefficients, as a sum always gave)
            np.add(np.moveaxis(groups[k], 0, -1), 0.0, out=coeffs[i, ..., :groups[k].shape[0]])
        return keys, coeffs

    def _product(self, blocks: frozenset, factors: dict, shared: dict,
                 shape: tuple[int, ...]) -> np.ndarray:
        """The product of a term's factors (the numerators of ``blocks``, the
        denominators of the other dynamic blocks), from a tree of partial products shared
        by the terms: each node keyed by its parent node and its last factor (node 0:
        the empty product)."""
        products: dict[tuple, tuple[int, np.ndarray]] = shared.setdefault("products", {})
        poly, node = np.ones((1,) + shape), 0
        for b in self.dynamic:
            f = (b.name, b.name in blocks)
            if f not in factors:
                continue
            hit = products.get((node, f))
            if hit is None:
                hit = (len(products) + 1,
                       factors[f] if node == 0 else _polymul(poly, factors[f]))
                products[node, f] = hit
            node, poly = hit
        return poly


def evaluate_forms(forms: Sequence[QuasiForm], design: Any, shared: dict | None = None
                   ) -> tuple[QuasiPolynomial, ...]:
    """Each of ``forms`` (of one diagram, e.g. a loop's ``N`` and ``D``) for ``design``,
    flat, sharing their blocks' coefficients and partial products, which are freed on
    return (held any longer, they would add to the peak memory of what follows) unless
    the caller passes ``shared`` (a dict it keeps for more forms of the same design)."""
    shared = {} if shared is None else shared
    return tuple(f.evaluate(design, shared).flat() for f in forms)


def _powers_first(coeffs: Sequence[np.ndarray], shape: tuple[int, ...]) -> np.ndarray:
    """Coefficients (descending powers, each broadcastable to ``shape``) as one array of
    ascending powers on the first axis (filled by assignment, which broadcasts, rather
    than through ``broadcast_to`` and ``stack``, which cost a lone design more)."""
    out = np.empty((len(coeffs),) + shape)
    for i, c in enumerate(coeffs[::-1]):
        out[i] = c
    return out


def _polymul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of two polynomials with ascending powers on the first axis."""
    if b.shape[0] == 1:
        return a * b
    out = np.zeros((a.shape[0] + b.shape[0] - 1,) + np.broadcast_shapes(a.shape[1:], b.shape[1:]))
    for i in range(a.shape[0]):
        out[i:i + b.shape[0]] += a[i] * b
    return out


def _polyadd(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Sum of two polynomials with ascending powers on the first axis."""
    return padded_sum(a, b, axis=0)


def _last_true(mask: np.ndarray) -> np.ndarray:
    """Index of the last ``True`` along the last axis (-1 where none), a few powers one
    column at a time (cheaper than numpy's reduction over a short last axis)."""
    last = np.full(mask.shape[:-1], -1)
    for j in range(mask.shape[-1]):
        last = np.where(mask[..., j], j, last)
    return last


def columnwise(ufunc: np.ufunc, a: np.ndarray) -> np.ndarray:
    """``ufunc.reduce(a, axis=-1)`` for a few columns, one column at a time (numpy's
    reduction over a short last axis costs more); for idempotent ``ufunc``
    (``maximum``, ``minimum``, ``logical_or``, ...), whose result does not depend on the
    order (the first column enters twice: a new array of the reduction's type)."""
    columns = np.moveaxis(a, -1, 0)
    return reduce(ufunc, columns, columns[0])


def pad_powers(x: np.ndarray, n: int, axis: int = -1) -> np.ndarray:
    """Coefficients ``x`` (ascending powers along ``axis``) with zeros up to length ``n``
    (a copy; faster than ``np.pad`` on these small arrays)."""
    axis %= x.ndim
    out = np.zeros(x.shape[:axis] + (n,) + x.shape[axis + 1:])
    out[(slice(None),) * axis + (slice(0, x.shape[axis]),)] = x
    return out


EVAL_ROUNDING = 1e-13
"""Error of ``Q(jw)`` evaluated in double precision (Horner, the exponential: within
4 ulps, :mod:`seactl.certify.vecmath`), relative to ``sum_kj |c_kj| w^j``: a few dozen ulps,
with room (:func:`rounding_majorant` adds that of the phase ``w tau``)."""
_PHASE_ULP = 1.2e-16  # half an ulp, relative: the error of fl(w tau)


def rounding_majorant(abs_coeffs: np.ndarray, tau_max: np.ndarray) -> np.ndarray:
    """Coefficients (ascending powers of ``w``, per design) of ``m(w)`` with
    ``|fl(Q(jw)) - Q(jw)| <= EVAL_ROUNDING m(w)`` for a quasi-polynomial with
    ``abs_coeffs`` (``sum_k |c_kj|``) and delays up to ``tau_max``: each term's
    exponential is off by at most the rounding of its phase ``w tau``, which grows with
    ``w``, so ``m = (1 + w tau_max _PHASE_ULP / EVAL_ROUNDING) sum_kj |c_kj| w^j``."""
    a = np.asarray(abs_coeffs, float)
    c = np.asarray(tau_max, float)[..., None] * (_PHASE_ULP / EVAL_ROUNDING)
    return padded_sum(a, np.concatenate([np.zeros(a.shape[:-1] + (1,)), c * a], axis=-1))


def padded_sum(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """Sum of two coefficient arrays (ascending powers along ``axis``) of different lengths."""
    n = max(a.shape[axis], b.shape[axis])
    return (a if a.shape[axis] == n else pad_powers(a, n, axis)) + \
        (b if b.shape[axis] == n else pad_powers(b, n, axis))


@lru_cache(maxsize=64)
def _determinant(diagram: BlockDiagram, held: tuple[str, ...]) -> Any:
    """``det(I - A)`` of the diagram with the ``held`` signals exogenous, in block symbols
    (constant blocks substituted), expanded; cached on disk like :func:`_symbolic`."""
    import sympy as sp

    key = _structure_key(diagram, "", "", held, "det")
    cached = _cache_load(key)
    if cached is not None:
        return cached
    exogenous = set(diagram.inputs) | set(held)
    unknowns = sorted(set(diagram.signals) - exogenous)
    index = {n: i for i, n in enumerate(unknowns)}
    A = sp.eye(len(unknowns))
    for b in diagram.blocks:
        if b.dst in index and b.src in index:
            const = constant_gain(b)
            A[index[b.dst], index[b.src]] -= sp.Symbol(b.name) if const is None \
                else sp.nsimplify(const)
    expr = sp.expand(A.det(method="berkowitz"))
    _cache_store(key, expr)
    return expr


def shifted(q: QuasiPolynomial, sigma: np.ndarray) -> QuasiPolynomial:
    """``Q(s + sigma)`` per design (Taylor shift of each polynomial, ``e^{-sigma tau}``
    folded into it): its right-half-plane roots are ``Q``'s roots right of ``sigma``."""
    from math import comb

    n1 = q.coeffs.shape[-1]
    sig = np.asarray(sigma, float)[None, :, None]
    binom = np.array([[comb(j, i) if j >= i else 0 for j in range(n1)] for i in range(n1)],
                     float)
    out = np.zeros_like(q.coeffs)
    for i in range(n1):
        j = np.arange(i, n1)
        out[..., i] = (q.coeffs[..., j] * binom[i, j] * sig ** (j - i)).sum(axis=-1)
    out *= np.exp(-np.asarray(sigma, float)[None, :, None] * q.delays[..., None])
    return QuasiPolynomial(out, q.delays)
