"""numba's ``njit`` with its on-disk cache in the user's cache directory.

``njit(cache=True)`` keeps a kernel's compiled code in a ``__pycache__`` next to its source
file; seactl's kernels use :func:`njit` from here instead, which keeps it in
:func:`seactl.base.usercache.numba_cache_dir` (an installed package's source tree may be read-only
or shared, and is no place for per-machine code).  numba fixes a kernel's cache location
when the decorator runs, so the locator below computes the path then, from the environment
alone; the directory itself is created when the first compiled kernel is saved.  An
unwritable cache directory costs a compilation per process, nothing else.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numba
from numba.core.caching import CompileResultCacheImpl, FunctionCache, UserProvidedCacheLocator

from seactl.base.usercache import numba_cache_dir


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
        return dispatcher

    return decorate
