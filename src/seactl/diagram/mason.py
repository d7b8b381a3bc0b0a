"""Characteristic quasi-polynomials and transfers of a block diagram without sympy.

For a signal-flow graph the determinant ``det(I - A)`` is the graph determinant of
Mason's gain formula: the sum, over every set of vertex-disjoint cycles, of
``(-1)^(number of cycles)`` times the product of the cycles' block gains.  Each block
is one edge, so every term is a product of distinct blocks: exactly the terms the
symbolic expansion of :class:`~seactl.diagram.blockdiagram.BlockDiagram` gives, found by
enumerating cycles instead of expanding a determinant (whose symbolic cost grows too fast
for diagrams of several coupled loops).  A transfer ``y / u`` is ``N / D`` with ``D`` the
graph determinant and ``N`` the determinant terms that use a probe edge ``y -> u``.

:class:`CycleDiagram` is a :class:`~seactl.diagram.blockdiagram.BlockDiagram` whose
characteristic, return differences, loops and transfers come from these terms; every view
built on them (margins, certified verdicts, roots, delay terms) works unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import (
    BlockDiagram,
    QuasiForm,
    Transfer,
    constant_gain,
    evaluate_forms,
)

PROBE = "__probe__"


def _cycles(edges: dict[str, list[tuple[str, float | str]]]) -> list[tuple[int, list]]:
    """Every simple cycle as ``(node bit mask, [gain, ...])`` (one entry per choice of
    parallel edges); ``edges[src]`` lists ``(dst, gain)``, ``gain`` a block name or a
    constant.  Each cycle is found once, from its first node in a fixed order."""
    nodes = sorted(edges.keys() | {d for v in edges.values() for d, _ in v})
    order = {n: i for i, n in enumerate(nodes)}
    out: list[tuple[int, list]] = []

    def walk(start: int, node: str, mask: int, gains: list) -> None:
        for dst, gain in edges.get(node, ()):
            i = order[dst]
            if i == start:
                out.append((mask, gains + [gain]))
            elif i > start and not mask >> i & 1:
                walk(start, dst, mask | 1 << i, gains + [gain])

    for node in nodes:
        walk(order[node], node, 1 << order[node], [])
    return out


def graph_determinant(edges: dict[str, list[tuple[str, float | str]]]
                      ) -> dict[frozenset, float]:
    """``det(I - A)`` as ``{frozenset of block names: coefficient}``."""
    names: dict[str, int] = {}
    cycles = []
    for mask, gains in _cycles(edges):
        bits = 0
        for g in gains:
            if isinstance(g, str):
                bits |= 1 << names.setdefault(g, len(names))
        cycles.append((mask, bits, -float(np.prod([g for g in gains
                                                   if not isinstance(g, str)]))))
    by_bits: dict[int, float] = {}

    def add(i: int, used: int, blocks: int, coef: float) -> None:
        by_bits[blocks] = by_bits.get(blocks, 0.0) + coef
        for k in range(i, len(cycles)):
            mask, b, c = cycles[k]
            if not mask & used:
                add(k + 1, used | mask, blocks | b, coef * c)

    add(0, 0, 0, 1.0)
    index = list(names)
    return {frozenset(index[i] for i in range(len(index)) if bits >> i & 1): v
            for bits, v in by_bits.items() if v != 0.0}


def _edges(diagram: BlockDiagram, held: set[str], extra: Sequence[tuple[str, str, str]] = ()
           ) -> dict[str, list]:
    out: dict[str, list] = {}
    for b in diagram.blocks:
        if b.dst in held:
            continue
        const = constant_gain(b)
        out.setdefault(b.src, []).append((b.dst, b.name if const is None else const))
    for name, src, dst in extra:
        out.setdefault(src, []).append((dst, name))
    return out


def _as_terms(terms: dict[frozenset, float]) -> list:
    return [(c, tuple(sorted(b))) for b, c in sorted(terms.items(), key=lambda t: sorted(t[0]))]


@dataclass(frozen=True)
class CycleDiagram(BlockDiagram):
    """A block diagram whose derived views come from its cycles (no sympy)."""

    def _held(self, cut: Sequence[str]) -> set[str]:
        return set(self.inputs) | set(cut)

    def _determinant(self, cut: tuple[str, ...]) -> dict[frozenset, float]:
        return _memo(self, ("det", cut), lambda: graph_determinant(
            _edges(self, self._held(cut))))

    def characteristic(self, cut: Sequence[str] = ()) -> QuasiForm:
        cut = tuple(sorted(cut))
        return _memo(self, ("char", cut), lambda: QuasiForm(self, _as_terms(
            self._determinant(cut))))

    def return_difference(self, sensor: str, cut: Sequence[str] = ()) -> tuple[
            QuasiForm, QuasiForm]:
        cut, held = tuple(sorted(cut)), tuple(sorted(set(cut) | {sensor}))

        def build():
            full, part = self._determinant(cut), self._determinant(held)
            diff = dict(full)
            for k, v in part.items():
                diff[k] = diff.get(k, 0.0) - v
            diff = {k: v for k, v in diff.items() if v != 0.0}
            return QuasiForm(self, _as_terms(diff)), QuasiForm(self, _as_terms(part))
        return _memo(self, ("rd", cut, sensor), build)

    def loop(self, sensor: str, cut: Sequence[str] = ()) -> Transfer:
        return CycleTransfer(self, sensor, sensor, tuple(cut), "loop")

    def transfer(self, output: str, input: str, cut: Sequence[str] = ()) -> Transfer:
        return CycleTransfer(self, output, input, tuple(cut), None)

    def transfer_forms(self, output: str, input: str, cut: tuple[str, ...]
                       ) -> tuple[QuasiForm, QuasiForm]:
        """``(N, D)`` with ``output / input = N / D`` (``input`` exogenous or cut)."""
        def build():
            held = self._held(cut) | {input}
            det = graph_determinant(_edges(self, held, [(PROBE, output, input)]))
            num = {k - {PROBE}: -v for k, v in det.items() if PROBE in k}
            den = {k: v for k, v in det.items() if PROBE not in k}
            return QuasiForm(self, _as_terms(num)), QuasiForm(self, _as_terms(den))
        return _memo(self, ("tf", output, input, cut), build)


_MEMO: dict[tuple, Any] = {}


def _memo(diagram: CycleDiagram, key: tuple, build):
    full = (id(diagram),) + key
    if full not in _MEMO:
        _MEMO[full] = (diagram, build())  # (the diagram kept alive: its id stays unique)
    return _MEMO[full][1]


@dataclass(frozen=True)
class CycleTransfer(Transfer):
    """A transfer of a :class:`CycleDiagram`: ``N(s) / D(s)`` from its cycle terms."""

    @cached_property
    def forms(self) -> tuple[QuasiForm, QuasiForm]:
        d = self.diagram
        if self.kind == "loop":
            return d.return_difference(self.input, self.cut)
        return d.transfer_forms(self.output, self.input, self.cut)

    @property
    def blocks(self) -> tuple:
        return self.diagram.blocks

    def expression(self) -> Any:
        raise NotImplementedError("a CycleDiagram's transfers are numeric (N / D)")

    def __call__(self, design: Any, s: np.ndarray | complex,
                 cache: dict[str, np.ndarray] | None = None) -> np.ndarray:
        s = np.asarray(s)
        s = s.astype(complex) if s.dtype != np.complex64 else s
        if s.ndim == 0:
            s = s[None]
        shape = tuple(getattr(design, "shape", ()))
        N, D = evaluate_forms(self.forms, design)
        s_flat = np.broadcast_to(s, shape + s.shape[-1:]).reshape(-1, s.shape[-1])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            out = N(s_flat) / D(s_flat)
        return out.reshape(shape + s.shape[-1:])
