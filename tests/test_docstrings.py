"""Every public name has a valid numpydoc docstring (as python-control's docstring test).

Oracle: ``numpydoc.validate``, the numpydoc project's own validator.  Names in
``seactl.__all__`` must also carry an Examples section; pytest's ``--doctest-modules``
(see ``pyproject.toml``) runs those examples, so they are checked against the code.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import numpydoc.validate as numpydoc_validate
import pytest

import seactl as sc

# Checks not enforced: summary on the quotes' line (GL01), See Also (SA01), extended
# summary (ES01), wording rules for summaries/descriptions (SS03, SS05, SS06, PR08, PR09,
# RT04, RT05), and a docstring on every member (GL08: private helpers may have none).
IGNORED = {"GL01", "SA01", "ES01", "SS03", "SS05", "SS06", "PR08", "PR09", "RT04", "RT05",
           "GL08"}


def _public_objects() -> list[tuple[str, object]]:
    return [(n, getattr(sc, n)) for n in sc.__all__
            if inspect.isclass(getattr(sc, n)) or inspect.isfunction(getattr(sc, n))]


def _members() -> list[str]:
    out = []
    for _, obj in _public_objects():
        if inspect.isclass(obj) and obj.__module__.startswith("seactl"):
            for m, f in vars(obj).items():
                if not m.startswith("_") and (inspect.isfunction(f) or isinstance(f, property)):
                    out.append(f"{obj.__module__}.{obj.__qualname__}.{m}")
    return out


def _errors(path: str, ignored: set[str]) -> list[tuple[str, str]]:
    return [(c, m) for c, m in numpydoc_validate.validate(path)["errors"] if c not in ignored]


@pytest.mark.parametrize("name,obj", _public_objects(), ids=[n for n, _ in _public_objects()])
def test_public_docstring(name, obj):
    path = f"{obj.__module__}.{obj.__qualname__}"
    assert _errors(path, IGNORED) == [], path


@pytest.mark.parametrize("path", _members())
def test_member_docstring(path):
    # Methods and properties: every numpydoc section that exists must be valid; examples
    # are required on the public names themselves (their class's example covers members).
    assert _errors(path, IGNORED | {"EX01"}) == [], path


def test_all_names_exist_and_are_not_shadowed_by_submodules():
    # `sc.design`, `sc.rigid`, `sc.sweep` reuse submodule names: after importing every
    # submodule, each public name must still be the function/class, not a module.
    for info in pkgutil.walk_packages(sc.__path__, "seactl."):
        importlib.import_module(info.name)
    for name in sc.__all__:
        assert not inspect.ismodule(getattr(sc, name)), name
    assert len(set(sc.__all__)) == len(sc.__all__)
