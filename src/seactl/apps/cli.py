"""The ``seactl`` command line: the entry point over the commands of :mod:`seactl.apps.commands`.

Every command that takes a design shares the options of
:func:`seactl.apps.commands.common.design_options` (milliseconds and Hz at the CLI, SI
inside).  Errors in user input print one line (``error: ...``) without a traceback and
exit with status 2.  Long work shows its progress on stderr (:mod:`seactl.base.progress`;
``SEACTL_PROGRESS=off`` silences it).

Interruptions: Ctrl-C exits with status 130 and SIGTERM with 143 (128 + the signal), each
after one line on stderr and the same clean-up (child processes stopped, temporary files
removed): :func:`run` turns SIGTERM into :class:`~seactl.errors.Terminated`, a
``KeyboardInterrupt``.  This module imports nothing heavy before :func:`main` runs, so an
interruption while the commands load is caught too.
"""

from __future__ import annotations

import sys

__all__ = ["main", "run"]   # and, loaded with the commands: cli, expand_variadic, parse_values

INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT)."""
TERMINATED = 143
"""Exit status after SIGTERM (128 + SIGTERM)."""


def __getattr__(name: str) -> object:
    """``cli``, ``expand_variadic`` and ``parse_values`` load with the commands."""
    if name in ("cli", "expand_variadic", "parse_values"):
        from seactl.apps import commands
        from seactl.apps.commands import common

        return commands.cli if name == "cli" else getattr(common, name)
    raise AttributeError(f"module 'seactl.apps.cli' has no attribute {name!r}")


# ------------------------------------------------------------------ entry point
def main(argv: list[str] | tuple[str, ...] | None = None) -> int:
    """Console entry point: returns the exit status (2 for bad input, 130 after Ctrl-C,
    143 after SIGTERM)."""
    try:
        return _main(argv)
    except KeyboardInterrupt as exc:   # outside click: while loading, or while reporting
        return _interrupted(exc)


def _main(argv: list[str] | tuple[str, ...] | None) -> int:
    import click

    from seactl.apps.commands import cli
    from seactl.apps.commands.common import Interrupted, expand_variadic
    from seactl.base import progress
    from seactl.base.outputs import command_inputs
    from seactl.errors import SeactlError

    args = expand_variadic(list(sys.argv[1:] if argv is None else argv))
    try:
        with command_inputs(), progress.reporting():
            status = cli.main(args=args, prog_name="seactl", standalone_mode=False)
    except SeactlError as exc:
        _error(str(exc))
        return 2
    except Interrupted as exc:
        return _interrupted(exc.interrupt)
    except click.exceptions.Abort as exc:   # click's form of a KeyboardInterrupt
        return _interrupted(exc.__context__ or exc)
    except click.ClickException as exc:  # click's own usage errors: the same one line
        _error(" ".join(exc.format_message().split()))
        return 2
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except OSError as exc:  # a last net: the commands name their own files
        from seactl.base.outputs import reason

        _error((f"{exc.filename}: " if exc.filename else "") + reason(exc))
        return 2
    except MemoryError:
        _error("out of memory; ask for fewer designs, frequencies or time steps")
        return 2
    return status if isinstance(status, int) else 0   # click.exceptions.Exit's status


def _interrupted(exc: BaseException) -> int:
    """One line for an interruption; its exit status."""
    from seactl.errors import Terminated

    terminated = isinstance(exc, Terminated)
    print("terminated" if terminated else "interrupted", file=sys.stderr)  # (plain: the
    return TERMINATED if terminated else INTERRUPTED  # interruption may be mid-import)


def _error(message: str) -> None:
    from rich.markup import escape

    from seactl.apps.commands.common import err_console

    err_console.print(f"[bold red]error:[/bold red] {escape(message)}", highlight=False,
                      soft_wrap=True)


def _on_sigterm(signum: int, frame: object) -> None:
    from seactl.errors import Terminated

    raise Terminated


def run() -> None:  # pragma: no cover - console script (tested in a subprocess)
    """The ``seactl`` script: SIGTERM handled like Ctrl-C, and once :func:`main` has
    returned, neither interrupts the interpreter's exit (its status stays).  Imports
    happen inside, where an interruption is caught."""
    status = INTERRUPTED
    try:
        import signal

        signal.signal(signal.SIGTERM, _on_sigterm)
        status = main()
    except KeyboardInterrupt as exc:  # before main's handlers, or at the very end
        status = _interrupted(exc)
    finally:
        import signal

        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_IGN)
    sys.exit(status)
