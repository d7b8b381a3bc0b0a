"""Progress of long work: named stages with counts, shown on stderr.

Library code reports through the *current reporter*, which is silent unless a front end
turns one on with :func:`reporting` (the command line does, for every command)::

    with progress.stage("latency map", total=len(cells), unit="cells") as st:
        for cell in cells:
            ...
            st.advance()
    progress.note("compiling the margin kernels (once per installation, about 40 s)")

Three ways to show it (:data:`MODES`):

``terminal``
    a rich bar per stage (description, counts, elapsed time, time left), redrawn in place;
``lines``
    plain lines ``seactl: <stage> ...``: one when a stage starts, then its counts with the
    time left at most every :data:`LINE_INTERVAL_S` seconds and when it completes (for
    the outermost open stage only: the stages inside it would repeat for every step);
``off``
    nothing.

:func:`reporting`'s default ``mode="auto"`` is the environment variable ``SEACTL_PROGRESS``
(``off``, ``lines`` or ``terminal``) if set, else ``terminal`` when stderr is a terminal and
``lines`` otherwise: ``SEACTL_PROGRESS=off`` silences every command.  Progress
never goes to stdout: a command's ``--json`` output stays clean.  The reporter is one per
process (worker threads may advance a stage; worker processes report through their parent).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any, TextIO

from seactl.errors import InputError

MODES = ("auto", "terminal", "lines", "off")
"""What :func:`reporting` accepts."""
ENV = "SEACTL_PROGRESS"
"""The environment variable that sets :func:`reporting`'s ``auto`` mode."""
LINE_INTERVAL_S = 2.0
"""Least time between two count lines of one stage in ``lines`` mode."""
PREFIX = "seactl: "


def duration_text(seconds: float) -> str:
    """A duration for people: ``"40 s"``, ``"2 min 5 s"``, ``"1 min"``.

    Examples
    --------
    >>> duration_text(39.6), duration_text(125), duration_text(60)
    ('40 s', '2 min 5 s', '1 min')
    """
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    return f"{s // 60} min" + (f" {s % 60} s" if s % 60 else "")


class Stage:
    """One stage of work: ``total`` steps (None: not counted) of ``unit``, expected to take
    ``expected_s`` seconds if known (else the time left follows the pace of the steps);
    ended by leaving its ``with`` block."""

    def __init__(self, reporter: Reporter, name: str, total: int | None, unit: str,
                 expected_s: float | None = None):
        self.reporter, self.name, self.total, self.unit = reporter, name, total, unit
        self.expected_s = expected_s
        self.done = 0
        self.started = time.monotonic()

    def advance(self, n: int = 1, item: str | None = None) -> None:
        """``n`` more steps done; ``item`` names the last (shown beside the counts)."""
        with self.reporter.lock:
            self.done += n
            self.reporter.advanced(self, item)

    def left_s(self) -> float | None:
        """Time left: of ``expected_s``, else at the mean pace so far (None until a tenth
        of the steps, and at least two, are done)."""
        elapsed = time.monotonic() - self.started
        if self.expected_s is not None:
            return max(self.expected_s - elapsed, 0.0)
        if not self.total or self.done < max(2, self.total / 10):   # (too few to tell)
            return None
        return elapsed / self.done * (self.total - self.done)

    def __enter__(self) -> Stage:
        return self

    def __exit__(self, *exc: Any) -> None:
        with self.reporter.lock:
            self.reporter.ended(self)


class Reporter:
    """The silent reporter (the default); subclasses show the stages."""

    mode = "off"

    def __init__(self) -> None:
        self.lock = threading.RLock()

    def stage(self, name: str, total: int | None = None, unit: str = "",
              expected_s: float | None = None) -> Stage:
        """A new stage, shown from now on (use it as a context manager)."""
        st = Stage(self, name, None if total is None else int(total), unit, expected_s)
        with self.lock:
            self.started(st)
        return st

    def note(self, text: str) -> None:
        """One message (a line of its own)."""

    def started(self, st: Stage) -> None:
        pass

    def advanced(self, st: Stage, item: str | None) -> None:
        pass

    def ended(self, st: Stage) -> None:
        pass

    def close(self) -> None:
        pass


class LineReporter(Reporter):
    """Plain lines on a stream (:data:`PREFIX` first)."""

    mode = "lines"

    def __init__(self, stream: TextIO):
        super().__init__()
        self.stream = stream
        self.last: dict[int, float] = {}   # the shown stages' last line
        self.open = 0

    def write(self, text: str) -> None:
        with contextlib.suppress(OSError, ValueError):  # (a closed pipe stops nothing)
            self.stream.write(PREFIX + text + "\n")
            self.stream.flush()

    def note(self, text: str) -> None:
        self.write(text)

    def started(self, st: Stage) -> None:
        self.open += 1
        if self.open > 1:
            return
        self.last[id(st)] = time.monotonic()
        count = f"{st.total} {st.unit}".strip() if st.total else ""
        if count:   # "name (12 maps)", or "name (41 x 41 grid), 2 maps"
            count = f", {count}" if st.name.endswith(")") else f" ({count})"
        self.write(f"{st.name}{count}")

    def advanced(self, st: Stage, item: str | None) -> None:
        now = time.monotonic()
        if id(st) not in self.last or (
                st.done != st.total and now - self.last[id(st)] < LINE_INTERVAL_S):
            return
        self.last[id(st)] = now
        counts = f"{st.done}/{st.total}" if st.total else f"{st.done}"
        left = st.left_s()
        tail = f", about {duration_text(left)} left" if left and st.done != st.total else ""
        self.write(f"{st.name} {counts}{' ' + st.unit if st.unit else ''}"
                   f"{' (' + item + ')' if item else ''}{tail}")

    def ended(self, st: Stage) -> None:
        self.open -= 1
        self.last.pop(id(st), None)


class TerminalReporter(Reporter):
    """rich bars on stderr, drawn while a stage is open and removed when it ends."""

    mode = "terminal"

    def __init__(self, console: Any = None):
        super().__init__()
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.bars = Progress(TextColumn("{task.description}"), BarColumn(),
                             MofNCompleteColumn(), TimeElapsedColumn(), TimeRemainingColumn(),
                             console=console or Console(stderr=True), transient=True,
                             redirect_stdout=False, redirect_stderr=False)
        self.tasks: dict[int, Any] = {}

    def note(self, text: str) -> None:
        self.bars.console.print(text, highlight=False, markup=False)

    def started(self, st: Stage) -> None:
        if not self.tasks:
            self.bars.start()
        self.tasks[id(st)] = self.bars.add_task(_escape(st.name), total=st.total)

    def advanced(self, st: Stage, item: str | None) -> None:
        desc = st.name + (f" ({item})" if item else "")
        self.bars.update(self.tasks[id(st)], advance=0, completed=st.done,
                         description=_escape(desc))

    def ended(self, st: Stage) -> None:
        task = self.tasks.pop(id(st), None)
        if task is not None:
            self.bars.remove_task(task)
        if not self.tasks:   # (no bar left: the command's own output follows undisturbed)
            self.bars.stop()

    def close(self) -> None:
        self.bars.stop()


def _escape(text: str) -> str:
    from rich.markup import escape

    return escape(text)


_current: Reporter = Reporter()


def current() -> Reporter:
    """The reporter in force (silent unless inside :func:`reporting`)."""
    return _current


def stage(name: str, total: int | None = None, unit: str = "",
          expected_s: float | None = None) -> Stage:
    """A stage of the current reporter (:meth:`Reporter.stage`)."""
    return _current.stage(name, total, unit, expected_s)


def note(text: str) -> None:
    """A message on the current reporter (:meth:`Reporter.note`)."""
    _current.note(text)


def resolve_mode(mode: str = "auto", stream: TextIO | None = None) -> str:
    """The mode :func:`reporting` uses: ``mode``, where ``auto`` is ``SEACTL_PROGRESS`` if
    set, else ``terminal`` when ``stream`` (default stderr) is a terminal and ``lines``
    otherwise."""
    if mode not in MODES:
        raise InputError("mode", mode, "one of " + ", ".join(MODES))
    env = os.environ.get(ENV, "").strip().lower()
    if mode == "auto" and env:
        if env not in MODES:
            raise InputError(ENV, env, "one of " + ", ".join(MODES))
        mode = env
    if mode == "auto":
        stream = sys.stderr if stream is None else stream
        isatty = getattr(stream, "isatty", lambda: False)
        mode = "terminal" if isatty() else "lines"
    return mode


@contextlib.contextmanager
def reporting(mode: str = "auto", stream: TextIO | None = None) -> Iterator[Reporter]:
    """Show progress inside the block (``mode``: one of :data:`MODES`,
    :func:`resolve_mode`); ``stream`` (default stderr) for ``lines``."""
    global _current
    mode = resolve_mode(mode, stream)
    stream = sys.stderr if stream is None else stream
    rep = (TerminalReporter() if mode == "terminal" else
           LineReporter(stream) if mode == "lines" else Reporter())
    saved, _current = _current, rep
    try:
        yield rep
    finally:
        _current = saved
        rep.close()
