"""The API reference: one page per topic, every public name on exactly one of them.

Oracle: ``seactl.__all__`` (the public namespace) against the autodoc directives of the
pages under ``docs/api/``, and the toctree of ``docs/api.md`` against the files there. The
examples under ``examples/gallery/`` use the public API only (``import seactl as sc``).
"""

from __future__ import annotations

import ast
import re
from collections import Counter
from pathlib import Path

import seactl as sc

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api"
TOPICS = ("systems", "analysis", "simulation", "timing", "export", "sweeps", "results")
DIRECTIVE = re.compile(r"^\.\. (currentmodule|auto(?:class|function|exception|data))::\s*(\S+)")


def documented(path: Path) -> list[str]:
    """Names of ``seactl`` documented by autodoc directives of one page."""
    module, names = None, []
    for line in path.read_text().splitlines():
        m = DIRECTIVE.match(line.strip())
        if m is None:
            continue
        if m.group(1) == "currentmodule":
            module = m.group(2)
        elif module == "seactl":
            names.append(m.group(2))
    return names


def toctree(path: Path) -> list[str]:
    text = path.read_text()
    block = text[text.index("```{toctree}"):]
    block = block[:block.index("```", 3)]
    return [ln.strip() for ln in block.splitlines()[1:] if ln.strip() and ":" not in ln]


def test_every_public_name_is_on_exactly_one_api_page():
    pages = {p.stem: documented(p) for p in sorted(API.glob("*.md"))}
    counts = Counter(n for names in pages.values() for n in names)
    assert sorted(counts) == sorted(sc.__all__), "documented names differ from seactl.__all__"
    twice = {n: [p for p, names in pages.items() if n in names] for n, c in counts.items() if c > 1}
    assert twice == {}, f"documented on more than one page: {twice}"


def test_no_page_outside_the_api_reference_documents_a_public_name():
    # A second autodoc entry elsewhere would make two targets for one name.
    others = [p for p in (ROOT / "docs").rglob("*.md")
              if API not in p.parents and "_build" not in p.parts]
    assert {str(p.relative_to(ROOT)): documented(p) for p in others if documented(p)} == {}


def test_the_reference_has_one_page_per_topic_in_its_toctree():
    entries = toctree(ROOT / "docs" / "api.md")
    assert sorted(entries) == sorted(f"api/{p.stem}" for p in API.glob("*.md"))
    assert set(TOPICS) <= {e.removeprefix("api/") for e in entries}


def test_gallery_examples_use_the_public_api_only():
    scripts = sorted((ROOT / "examples" / "gallery").glob("plot_*.py"))
    assert len(scripts) >= 10
    for script in scripts:
        tree = ast.parse(script.read_text())
        imports = [(a.name, a.asname) for node in ast.walk(tree)
                   if isinstance(node, ast.Import) for a in node.names]
        froms = [node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
        assert ("seactl", "sc") in imports, script.name
        assert not [n for n, _ in imports if n.startswith("seactl.")], script.name
        assert not [m for m in froms if m and m.startswith("seactl")], script.name
        assert ast.get_docstring(tree), f"{script.name}: no title and description"
