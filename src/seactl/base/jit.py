"""numba's ``njit`` with its on-disk cache in the user's cache directory.

``njit(cache=True)`` keeps a kernel's compiled code in a ``__pycache__`` next to its source
file; seactl's kernels use :func:`njit` from here instead, which keeps it in
:func:`seactl.base.usercache.numba_cache_dir` (an installed package's source tree may be read-only
or shared, and is no place for per-machine code).  numba fixes a kernel's cache location
when the decorator runs, so the locator below computes the path then, from the environment
alone; the directory itself is created when the first compiled kernel is saved.  An
unwritable cache directory costs a compilation per process, nothing else.

Kernels come in named groups (a module's :class:`KernelGroup`, its ``KERNELS`` global) so a
cold cache can be announced before a group compiles: the first compilation of a group's
kernel in the process (numba's ``numba:compile`` event, which fires
only on a cache miss) puts one note on the current progress reporter
(:mod:`seactl.base.progress`): ``compiling the margin kernels (once per installation, about
40 s)``.  :func:`is_cold` tells, without compiling, whether a group has nothing cached.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numba
from numba.core import event
from numba.core.caching import CompileResultCacheImpl, FunctionCache, UserProvidedCacheLocator

from seactl.base import progress
from seactl.base.usercache import numba_cache_dir


@dataclass(frozen=True)
class KernelGroup:
    """The kernels of one concern, compiled together: ``name`` as said to people (``margin``
    -> "the margin kernels") and ``about_s``, the time their compilation takes on one core
    of an idle machine of the kind the project runs on (an order of magnitude for people)."""

    name: str
    about_s: float

    def message(self) -> str:
        return (f"compiling the {self.name} kernels (once per installation, "
                f"about {progress.duration_text(self.about_s)})")


GROUPS: dict[str, list[Any]] = {}
"""Each group's dispatchers (by group name), as decorated."""
_BY_NAME: dict[str, KernelGroup] = {}


class UserCacheLocator(UserProvidedCacheLocator):
    """numba's locator for a user-provided directory, rooted at
    :func:`~seactl.base.usercache.numba_cache_dir` (numba's own layout below it: one folder per
    source directory), and touching no file until a kernel is saved."""

    def __init__(self, py_func: Callable, py_file: str, root: str):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(root, self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self) -> str:
        return self._cache_path

    @classmethod
    def from_function(cls, py_func: Callable, py_file: str) -> UserCacheLocator | None:
        root = numba_cache_dir()
        if root is None or not os.path.exists(py_file):
            return None
        return cls(py_func, py_file, str(root))


class _UserCacheImpl(CompileResultCacheImpl):
    _locator_classes = [UserCacheLocator]


class UserFunctionCache(FunctionCache):
    """A kernel's on-disk cache under :class:`UserCacheLocator`."""

    _impl_class = _UserCacheImpl

    def has_entries(self) -> bool:
        """Whether the cache holds compiled code for the kernel's current source."""
        try:
            return bool(self._cache_file._load_index())
        except (OSError, EOFError, ValueError):
            return False

    def save_overload(self, sig: Any, data: Any) -> None:
        try:
            super().save_overload(sig, data)
        except OSError:  # an unwritable cache: compiled again by the next process
            pass


def njit(**options: Any) -> Callable[[Callable], Any]:
    """``numba.njit(**options)``; with ``cache=True``, the cache is a
    :class:`UserFunctionCache` (none at all when ``SEACTL_CACHE_DIR=off``)."""
    cache = options.pop("cache", False)

    def decorate(func: Callable) -> Any:
        dispatcher = numba.njit(**options)(func)
        if cache and numba_cache_dir() is not None:
            # what Dispatcher.enable_caching does, with this module's cache class
            dispatcher._cache = UserFunctionCache(func)
        group = func.__globals__.get("KERNELS")
        if isinstance(group, KernelGroup):
            dispatcher.seactl_group = group
            _BY_NAME.setdefault(group.name, group)
            GROUPS.setdefault(group.name, []).append(dispatcher)
            _listen()
        return dispatcher

    return decorate


def kernel_group(name: str) -> KernelGroup:
    """The group ``name`` (its kernel module imported)."""
    return _BY_NAME[name]


def is_cold(name: str) -> bool:
    """Whether no kernel of group ``name`` (its module imported) has its compiled code in
    the cache for the current sources (then the group's first use compiles it all)."""
    caches = [d._cache for d in GROUPS.get(name, ())]
    return not any(isinstance(c, UserFunctionCache) and c.has_entries() for c in caches)


class _Announcer(event.Listener):
    """Puts a group's :meth:`KernelGroup.message` on the progress reporter when its first
    kernel starts compiling in this process."""

    def __init__(self) -> None:
        self.said: set[str] = set()

    def on_start(self, ev: event.Event) -> None:
        group = getattr(ev.data["dispatcher"], "seactl_group", None)
        if group is not None and group.name not in self.said:
            self.said.add(group.name)
            progress.note(group.message())

    def on_end(self, ev: event.Event) -> None:
        pass


_ANNOUNCER = _Announcer()


def _listen() -> None:
    """Let :class:`_Announcer` hear numba's compilations (once)."""
    if not getattr(_ANNOUNCER, "registered", False):
        event.register("numba:compile", _ANNOUNCER)
        _ANNOUNCER.registered = True


def said(names: Any) -> None:
    """Count the groups ``names`` as announced (their compilation was said elsewhere)."""
    _ANNOUNCER.said.update(names)
