"""The house: no import circles between seactl's modules, no plotting on import.

Oracle: the import statements themselves, read with :mod:`ast` (every ``import`` counts,
module level or inside a function, since a deferred import is still a dependency).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import seactl

SRC = Path(seactl.__file__).parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Edges ``a -> b``: module ``a`` imports seactl module ``b`` (a package's ``__init__``
    counts only when a name is imported from it that is not a submodule)."""
    paths = {_module_name(p): p for p in SRC.rglob("*.py")}
    graph: dict[str, set[str]] = defaultdict(set)
    for name, path in paths.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[:len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                subs = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in paths]
                graph[name].update(subs)
                if len(subs) < len(node.names) and target in paths:
                    graph[name].add(target)
            elif isinstance(node, ast.Import):
                graph[name].update(a.name for a in node.names if a.name in paths)
        graph[name].discard(name)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_planted_cycle():
    # Oracle: a hand-built graph with one known cycle.
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circles():
    # Oracle: the import statements read with ast (module docstring).
    assert cycles(import_graph()) == []


def test_command_line_and_import_do_not_load_matplotlib():
    # Oracle: sys.modules of a fresh interpreter.
    # The command line starts fast (seactl bench cli-startup): heavy libraries load only
    # inside the commands that use them (bokeh: seactl explore, the app extra).
    heavy = ("matplotlib", "dask", "distributed", "scipy", "pydantic", "sympy", "control",
             "bokeh", "selenium")
    code = ("import sys, seactl, seactl.cli; "
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_public_functions_keep_their_names_after_use():
    """A public function named like a submodule must survive the submodule's first import."""
    code = ("import seactl as sc, types; "
            "import seactl.mobile_base, seactl.rigid, seactl.sweep, seactl.design; "
            "print([n for n in sc.__all__ if isinstance(getattr(sc, n), types.ModuleType)])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
