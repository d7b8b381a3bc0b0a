"""The house: layers that import only downwards, no private names across modules, no import
circles, no plotting on import.

Oracle: the import statements themselves, read with :mod:`ast` (every ``import`` counts,
module level or inside a function, since a deferred import is still a dependency), and the
layer table :data:`LAYERS`, which docs/architecture.md shows row for row.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import seactl

SRC = Path(seactl.__file__).parent
DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"

LAYERS = [
    ("foundations", ("seactl.errors", "seactl.base")),
    ("diagram", ("seactl.diagram",)),
    ("certify", ("seactl.certify",)),
    ("analysis", ("seactl.analysis",)),
    ("simulate", ("seactl.simulate",)),
    ("systems", ("seactl.systems",)),
    ("codegen", ("seactl.codegen",)),
    ("latency", ("seactl.latency",)),
    ("userloop", ("seactl.userloop",)),
    ("sweep", ("seactl.sweep",)),
    ("api", ("seactl.api", "seactl")),
    ("apps", ("seactl.apps",)),
]
"""The layers, lowest first: a module may import its own layer and the layers before it.
``seactl`` itself (the package's ``__init__``, the public namespace) belongs to the API."""


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
    code = ("import sys, seactl, seactl.apps.cli; "
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_public_functions_keep_their_names_after_use():
    """A public function named like a submodule must survive the submodule's first import."""
    code = ("import seactl as sc, types; "
            "import seactl.systems.mobile_base.model, seactl.systems.rigid.model, "
            "seactl.sweep.engine, seactl.systems.sea.design; "
            "print([n for n in sc.__all__ if isinstance(getattr(sc, n), types.ModuleType)])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def layer_of(module: str) -> int:
    """Index in :data:`LAYERS` of the layer holding ``module`` (longest package prefix)."""
    best, depth = -1, -1
    for i, (_, packages) in enumerate(LAYERS):
        for pkg in packages:
            exact = pkg == "seactl"
            if (module == pkg or (not exact and module.startswith(pkg + "."))) \
                    and pkg.count(".") > depth:
                best, depth = i, pkg.count(".")
    return best


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    return sorted(f"{a} ({LAYERS[layer_of(a)][0]}) imports {b} ({LAYERS[layer_of(b)][0]})"
                  for a, targets in graph.items() for b in targets
                  if layer_of(b) > layer_of(a))


def test_every_module_is_in_one_layer():
    # Oracle: the module files on disk against the layer table.
    assert [_module_name(p) for p in SRC.rglob("*.py") if layer_of(_module_name(p)) < 0] == []


def test_layer_checker_finds_a_planted_upward_import():
    # Oracle: a hand-built graph with one import from the analysis layer up to the API.
    graph = {"seactl.analysis.margins": {"seactl.api.results", "seactl.base.limits"}}
    assert upward_imports(graph) == ["seactl.analysis.margins (analysis) imports "
                                     "seactl.api.results (api)"]


def test_no_module_imports_a_layer_above_its_own():
    # Oracle: the import statements read with ast, against LAYERS.
    assert upward_imports(import_graph()) == []


def private_imports() -> list[str]:
    """Every ``from seactl.x import _name``: a private name imported by another module."""
    out = []
    for path in SRC.rglob("*.py"):
        name = _module_name(path)
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom) or node.module == "__future__":
                continue
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("seactl"):
                out += [f"{name} imports {target}.{a.name}" for a in node.names
                        if a.name.startswith("_")]
    return sorted(out)


def test_private_import_finder_finds_one(tmp_path):
    # Oracle: the hand-written statement itself.
    tree = ast.parse("from seactl.simulate.engine import _ticks, simulate")
    node = tree.body[0]
    assert [a.name for a in node.names if a.name.startswith("_")] == ["_ticks"]


def test_no_private_names_across_modules():
    # Oracle: the import statements read with ast; a name two modules share is public in
    # the lower one.
    assert private_imports() == []


def test_architecture_page_shows_the_layer_table():
    # Oracle: the layer table above against the table in docs/architecture.md (its rows in
    # order: layer name, then its packages).
    rows = [line.split("|")[1:3] for line in DOC.read_text().splitlines()
            if line.startswith("| ") and not line.startswith("| layer")]
    shown = [(name.strip(), tuple(p.strip(" `") for p in pkgs.split(",")))
             for name, pkgs in rows]
    assert shown == [(name, pkgs) for name, pkgs in LAYERS]
