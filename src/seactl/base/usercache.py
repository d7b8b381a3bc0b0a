"""Where seactl keeps what it derives or compiles between runs: the user's cache directory.

One directory holds both kinds of entry: derived block-diagram expressions
(:mod:`seactl.diagram.blockdiagram`) at its top, the compiled kernels' numba cache in its ``numba``
folder (:mod:`seactl.base.jit`).  ``SEACTL_CACHE_DIR`` moves the directory and
``SEACTL_CACHE_DIR=off`` disables both caches; otherwise it is ``seactl`` in the XDG cache
directory (``$XDG_CACHE_HOME``, by default ``~/.cache``).  An explicit ``NUMBA_CACHE_DIR``
(numba's own setting) takes precedence for the compiled kernels.  Nothing is ever written
next to the package's sources.

The paths are read from the environment when asked for, and nothing here creates them: a
cache's writer creates its directory when it first stores an entry.
"""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path | None:
    """seactl's cache directory, or None when ``SEACTL_CACHE_DIR=off``."""
    env = os.environ.get("SEACTL_CACHE_DIR")
    if env == "off":
        return None
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "seactl"


def numba_cache_dir() -> Path | None:
    """Where the compiled kernels are cached: ``NUMBA_CACHE_DIR`` if set, else the
    ``numba`` folder of :func:`cache_dir` (None when that is off)."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env:
        return Path(env)
    base = cache_dir()
    return None if base is None else base / "numba"
