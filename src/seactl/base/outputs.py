"""Output files: checked before any work is done, written through temporary siblings and
renamed into place, all files of one command as a set.

Every command that writes files (``--csv``, ``--plot``, ``--plot-file``...) opens an
:class:`OutputSet`, registers each path with :meth:`OutputSet.add` *before* computing
(the path is checked and a temporary sibling is created, which proves the directory is
writable), writes the contents into the temporaries, and calls :meth:`OutputSet.commit`
at the end, which renames them all into place.  On any error or interruption before the
commit, every temporary is removed: nothing is left behind.  Every ``OSError`` becomes
:class:`~seactl.errors.OutputError` (``cannot write PATH: reason``).  Files get the
permissions of the user's umask (``0666 & ~umask``), like any file a program creates.

Two outputs are refused although the rename could replace them: a file the command reads
(while a command of the command line runs, :func:`command_inputs`, every input file is
noted with :func:`note_input` when it is read; an output naming one is refused, at
:meth:`OutputSet.add` and again at the commit), and a read-only file (the rename needs
only the directory's permission, so the file's own mode is checked).

This module sits at the bottom of the layering (it imports only :mod:`seactl.errors`).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from seactl.errors import InputError, OutputError

FIGURE_SUFFIXES = (".png", ".svg", ".pdf")
"""Figure formats (the suffix chooses the format, and the bytes follow it)."""
CSV_SUFFIXES = (".csv", ".txt")
"""Suffixes of ``--csv`` files (comma-separated text either way)."""
TEMP_TAG = ".seactl-tmp-"
"""Part of the name of every temporary sibling (``.NAME.seactl-tmp-XXXX.SUFFIX``)."""


def umask() -> int:
    """The process's umask (read without changing it for longer than one call)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def reason(exc: OSError) -> str:
    """The human part of an ``OSError`` (``"permission denied"``)."""
    text = exc.strerror or str(exc) or type(exc).__name__
    return text[:1].lower() + text[1:]


_INPUTS: set[Path] | None = None
"""The files the running command has read (resolved paths); ``None`` outside a command of
the command line (:func:`command_inputs`), where nothing is recorded."""


def note_input(path: str | os.PathLike) -> None:
    """Record that ``path`` is read as an input: no output of this command may replace it."""
    if _INPUTS is None:
        return
    try:
        _INPUTS.add(Path(path).resolve())
    except (OSError, RuntimeError):  # an unresolvable path cannot be an output either
        pass


@contextlib.contextmanager
def command_inputs() -> Iterator[None]:
    """Record the input files read meanwhile (one command of the command line)."""
    global _INPUTS
    previous, _INPUTS = _INPUTS, set()
    try:
        yield
    finally:
        _INPUTS = previous


def check_not_input(path: str | os.PathLike) -> None:
    """Refuse an output that is one of the command's input files, or a directory holding
    one (:class:`~seactl.errors.OutputError`)."""
    try:
        p = Path(path).resolve()
    except (OSError, RuntimeError):
        return
    for inp in _INPUTS or ():
        if inp == p or p in inp.parents:
            what = "is" if inp == p else f"holds {inp.name}, which is"
            raise OutputError(path, f"it {what} an input of this command (choose another "
                              "output name)")


def check_writable(path: Path) -> None:
    """Refuse replacing an existing file that is read-only (its mode has no write bit, or
    this user may not write it): the rename into place would bypass that permission."""
    try:
        st = path.stat()
    except OSError:
        return
    if not st.st_mode & 0o222 or not os.access(path, os.W_OK):
        raise OutputError(path, "the file is read-only (make it writable or choose another "
                          "name)")


def check_file_path(option: str, path: str | os.PathLike, suffixes: Sequence[str]) -> Path:
    """Check that ``path`` can be written as a new or replaced regular file.

    Raises :class:`~seactl.errors.InputError` (naming ``option``) for an empty name or an
    unknown suffix, :class:`~seactl.errors.OutputError` when the path is a directory or
    another non-regular file, or its directory does not exist.
    """
    text = os.fspath(path)
    if not text.strip():
        raise InputError(option, text, "a file name")
    p = Path(text)
    if suffixes and p.suffix.lower() not in suffixes:
        raise InputError(option, text, "a file name ending in " + ", ".join(suffixes))
    if p.is_dir():
        raise OutputError(p, "is a directory")
    if p.exists() and not p.is_file():
        raise OutputError(p, "exists and is not a regular file")
    check_writable(p)
    check_not_input(p)
    parent = p.parent
    if not parent.exists():
        raise OutputError(p, f"the directory {parent} does not exist")
    if not parent.is_dir():
        raise OutputError(p, f"{parent} is not a directory")
    return p


def _temp_sibling(path: Path) -> Path:
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{TEMP_TAG}", suffix=path.suffix,
                                   dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise OutputError(path, reason(exc)) from None
    return Path(tmp)


def _publish(tmp: Path, path: Path) -> None:
    check_writable(path)
    check_not_input(path)
    os.chmod(tmp, 0o666 & ~umask())
    os.replace(tmp, path)


def write_atomic_with(path: str | os.PathLike, writer: Callable[[Path], Any]) -> None:
    """Let ``writer(tmp)`` write a temporary sibling of ``path``, then rename it into place
    (missing parent directories are created).  ``OSError`` -> :class:`OutputError`."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(path, reason(exc)) from None
    tmp = _temp_sibling(path)
    try:
        writer(tmp)
        _publish(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(path, reason(exc)) from None
        raise


def _bytes(data: str | bytes) -> bytes:
    return data.encode() if isinstance(data, str) else data


def write_atomic(path: str | os.PathLike, data: str | bytes) -> None:
    """Write ``data`` to ``path`` through a temporary sibling and a rename."""
    write_atomic_with(path, lambda tmp: tmp.write_bytes(_bytes(data)))


def save_figure_to(fig: Any, tmp: Path, fmt: str, dpi: int) -> None:
    """``fig.savefig`` in format ``fmt`` (``png``, ``svg``, ``pdf``) and close the figure."""
    import matplotlib.pyplot as plt

    try:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format=fmt)
    finally:
        plt.close(fig)


class OutputSet:
    """The output files of one command, checked up front and written as a set.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with OutputSet() as outs:
    ...     csv = outs.add("--csv", d / "a.csv", CSV_SUFFIXES)
    ...     outs.write(csv, "x\\n1\\n")
    ...     outs.commit()
    >>> sorted(p.name for p in d.iterdir())
    ['a.csv']
    """

    def __init__(self) -> None:
        self._temps: dict[Path, Path] = {}

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.discard()

    def add(self, option: str, path: str | os.PathLike | None,
            suffixes: Sequence[str] = ()) -> Path | None:
        """Check ``path`` and reserve a temporary sibling (``None`` passes through)."""
        if path is None:
            return None
        p = check_file_path(option, path, suffixes)
        key = p.absolute()
        if any(k.absolute() == key for k in self._temps):
            raise InputError(option, os.fspath(path), "a path not used by another output")
        self._temps[p] = _temp_sibling(p)
        return p

    def temp(self, path: Path) -> Path:
        """The temporary file that becomes ``path`` at :meth:`commit`."""
        return self._temps[Path(path)]

    def write_with(self, path: Path, writer: Callable[[Path], Any]) -> None:
        """Let ``writer(tmp)`` fill the temporary of ``path``."""
        try:
            writer(self.temp(path))
        except OSError as exc:
            if isinstance(exc, OutputError):
                raise
            raise OutputError(path, reason(exc)) from None

    def write(self, path: Path, data: str | bytes) -> None:
        """Fill the temporary of ``path`` with ``data``."""
        self.write_with(path, lambda tmp: tmp.write_bytes(_bytes(data)))

    def figure(self, path: Path, fig: Any, dpi: int = 120) -> None:
        """Save ``fig`` into the temporary of ``path`` in the format of its suffix."""
        fmt = Path(path).suffix[1:].lower()
        self.write_with(path, lambda tmp: save_figure_to(fig, tmp, fmt, dpi))

    def commit(self) -> None:
        """Rename every temporary into place (none if any of the paths became read-only
        or an input meanwhile)."""
        try:
            for path in self._temps:
                check_writable(path)
                check_not_input(path)
        except OutputError:
            self.discard()
            raise
        for path, tmp in list(self._temps.items()):
            try:
                _publish(tmp, path)
            except OSError as exc:
                self.discard()
                if isinstance(exc, OutputError):
                    raise
                raise OutputError(path, reason(exc)) from None
            del self._temps[path]

    def discard(self) -> None:
        """Remove every temporary not yet committed."""
        for tmp in self._temps.values():
            try:
                tmp.unlink(missing_ok=True)
            except OSError:
                pass
        self._temps.clear()
