"""The ``seactl`` command line: the entry point over the commands of :mod:`seactl.commands`.

Every command that takes a design shares the options of
:func:`seactl.commands._common.design_options` (milliseconds and Hz at the CLI, SI
inside).  Errors in user input print one line (``error: ...``) without a traceback and
exit with status 2.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import click
from rich.markup import escape

from .commands import cli
from .commands._common import err_console, expand_variadic, parse_values
from .errors import SeactlError

__all__ = ["cli", "expand_variadic", "main", "parse_values", "run"]


# ------------------------------------------------------------------ entry point
def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point: returns the exit status (2 for bad input)."""
    args = expand_variadic(list(sys.argv[1:] if argv is None else argv))
    try:
        status = cli.main(args=args, prog_name="seactl", standalone_mode=False)
    except SeactlError as exc:
        err_console.print(f"[bold red]error:[/bold red] {escape(str(exc))}", highlight=False,
                          soft_wrap=True)
        return 2
    except click.exceptions.Abort:
        err_console.print("interrupted")
        return 130
    except click.ClickException as exc:  # click's own usage errors: the same one line
        message = " ".join(exc.format_message().split())
        err_console.print(f"[bold red]error:[/bold red] {escape(message)}", highlight=False,
                          soft_wrap=True)
        return 2
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except OSError as exc:  # a last net: the commands turn their own into OutputError
        from .outputs import reason

        where = f"cannot write {exc.filename}: " if exc.filename else ""
        _error(where + reason(exc))
        return 2
    except MemoryError:
        _error("out of memory; ask for fewer designs, frequencies or time steps")
        return 2
    return status if isinstance(status, int) else 0   # click.exceptions.Exit's status


def _error(message: str) -> None:
    err_console.print(f"[bold red]error:[/bold red] {escape(message)}", highlight=False,
                      soft_wrap=True)


def run() -> None:  # pragma: no cover - console script
    sys.exit(main())

