"""Importing seactl does nothing but define things; compiled kernels cache outside the sources.

Oracles: the interpreter's own state read before and after the imports (signal handlers,
``threading.enumerate()``, the child processes in ``/proc``, each numba dispatcher's
``signatures``), and the file system (where numba's index ``.nbi`` and data ``.nbc``
files appear).  Each check runs in a fresh interpreter, so nothing the test session has
already imported or compiled hides an effect.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import seactl
from seactl.base.usercache import cache_dir, numba_cache_dir

SRC = Path(seactl.__file__).parent

IMPORT_ALL = r"""
import json, os, pkgutil, signal, threading, importlib
import numpy, numba  # what every kernel module needs, loaded before the baseline

def children():
    tasks = f"/proc/{os.getpid()}/task"
    if not os.path.isdir(tasks):
        return []
    return sorted(p for t in os.listdir(tasks)
                  for p in open(f"{tasks}/{t}/children").read().split())

before = {"sigint": repr(signal.getsignal(signal.SIGINT)),
          "sigterm": repr(signal.getsignal(signal.SIGTERM)),
          "threads": sorted(t.name for t in threading.enumerate()), "children": children()}
import seactl
names = [seactl.__name__]
for info in pkgutil.walk_packages(seactl.__path__, "seactl."):
    importlib.import_module(info.name)
    names.append(info.name)
compiled = sorted(f"{m}.{a}" for m in names for a, v in vars(importlib.import_module(m)).items()
                  if isinstance(v, numba.core.dispatcher.Dispatcher) and v.signatures)
dispatchers = sum(isinstance(v, numba.core.dispatcher.Dispatcher)
                  for m in names for v in vars(importlib.import_module(m)).values())
after = {"sigint": repr(signal.getsignal(signal.SIGINT)),
         "sigterm": repr(signal.getsignal(signal.SIGTERM)),
         "threads": sorted(t.name for t in threading.enumerate()), "children": children()}
print(json.dumps({"before": before, "after": after, "modules": names,
                  "compiled": compiled, "dispatchers": dispatchers}))
"""


def _env(tmp_path: Path, **extra: str) -> dict[str, str]:
    """The test session's environment with a fresh user cache directory under ``tmp_path``
    (no ``SEACTL_CACHE_DIR``, no ``NUMBA_CACHE_DIR``) and ``extra`` on top."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("SEACTL_CACHE_DIR", "NUMBA_CACHE_DIR")}
    env.update(XDG_CACHE_HOME=str(tmp_path / "xdg"), PYTHONPATH=str(SRC.parent), **extra)
    return env


def _run(code: str, env: dict[str, str]) -> str:
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_importing_every_module_changes_nothing(tmp_path):
    # Oracle: the same process's state before and after importing every module that
    # pkgutil finds (what pytest's doctest collection does); the timeout is a backstop
    # for an import that runs work (a sweep chunk, a compilation).
    out = json.loads(_run(IMPORT_ALL, _env(tmp_path)))
    assert len(out["modules"]) > 60            # (the fork server's preload among them)
    assert out["after"] == out["before"]            # signals, threads, child processes
    assert out["dispatchers"] > 50 and out["compiled"] == []
    assert not (tmp_path / "xdg").exists()          # not even a cache directory


def _numba_files(root: Path) -> dict[str, float]:
    return {str(p): p.stat().st_mtime_ns for p in root.rglob("*.nb[ic]")}


RUN_KERNEL = "from seactl.certify.scan import np_minimum; assert np_minimum(1.0, 2.0) == 1.0"


def test_a_compiled_kernel_is_cached_in_the_user_cache_dir(tmp_path):
    # Oracle: numba's index file of the kernel that ran appears under the XDG cache
    # directory (numba names it <module>.<function>-<line>.py<version>.nbi), and no index
    # or data file in the source tree is created or rewritten.
    in_tree = _numba_files(SRC)
    _run(RUN_KERNEL, _env(tmp_path))
    cached = [p.name for p in (tmp_path / "xdg" / "seactl" / "numba").rglob("*.nbi")]
    assert any(name.startswith("scan.np_minimum-") for name in cached)
    assert _numba_files(SRC) == in_tree


def test_numba_cache_dir_and_seactl_cache_dir_are_honoured(tmp_path):
    # Oracle: the same file-system check; NUMBA_CACHE_DIR (numba's own setting) moves the
    # kernels' cache, SEACTL_CACHE_DIR=off keeps none.
    explicit = tmp_path / "numba"
    _run(RUN_KERNEL, _env(tmp_path, NUMBA_CACHE_DIR=str(explicit)))
    assert any(p.name.startswith("scan.np_minimum-") for p in explicit.rglob("*.nbi"))
    assert not (tmp_path / "xdg").exists()
    _run(RUN_KERNEL, _env(tmp_path, SEACTL_CACHE_DIR="off"))
    assert not (tmp_path / "xdg").exists()


def test_cache_directories_follow_the_xdg_convention(monkeypatch, tmp_path):
    # Oracle: the XDG base directory specification ($XDG_CACHE_HOME, else ~/.cache).
    for name in ("SEACTL_CACHE_DIR", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert cache_dir() == tmp_path / ".cache" / "seactl"
    assert numba_cache_dir() == tmp_path / ".cache" / "seactl" / "numba"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert numba_cache_dir() == tmp_path / "x" / "seactl" / "numba"
    monkeypatch.setenv("SEACTL_CACHE_DIR", str(tmp_path / "s"))
    assert (cache_dir(), numba_cache_dir()) == (tmp_path / "s", tmp_path / "s" / "numba")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "n"))
    assert numba_cache_dir() == tmp_path / "n"
    monkeypatch.setenv("SEACTL_CACHE_DIR", "off")
    assert cache_dir() is None and numba_cache_dir() == tmp_path / "n"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert numba_cache_dir() is None
