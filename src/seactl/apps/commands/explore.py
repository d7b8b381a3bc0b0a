"""``seactl explore``: the interactive explorer in the browser (Bokeh server)."""

from __future__ import annotations

import sys

import click

from seactl.errors import InputError, SeactlError

from .common import cli


def check_address(host: str, port: int, allow_remote: bool) -> None:
    """Refuse a port outside 1-65535, and a non-loopback host without ``--allow-remote``."""
    from seactl.apps.explore.server import is_loopback

    if not 1 <= port <= 65535:
        raise InputError("--port", port, "an integer in [1, 65535]")
    if not allow_remote and not is_loopback(host):
        raise InputError("--host", host, "a loopback address (127.0.0.1, ::1, localhost); "
                         "pass --allow-remote to serve other machines (no authentication)")


@cli.command()
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on (loopback only unless --allow-remote).")
@click.option("--port", type=int, default=5006, show_default=True, help="Port to listen on.")
@click.option("--no-browser", is_flag=True, help="Do not open a browser tab.")
@click.option("--allow-remote", is_flag=True,
              help="Allow a non-loopback --host: anyone who reaches it can use the app.")
@click.option("--loop", "loop_file", default=None, metavar="FILE.toml",
              type=click.Path(dir_okay=False),
              help="Start with this loop file (docs/loops.md): its variables as sliders.")
def explore(host: str, port: int, no_browser: bool, allow_remote: bool,
            loop_file: str | None) -> None:
    """Tune one SEA design by hand in the browser; every view updates live.

    Python: seactl.apps.explore.model.views(...) (its numbers: sc.design(...).margins(), .roots(),
    .impedance(), .step(), .impulse(), .jitter_margins()).

    \b
    Controls: actuator (preset or uploaded TOML), f_n, GS, zeta1/zeta2/ratio, the three
    delays, both filters, continuous or sampled at a rate; or a loop file (uploaded, or
    --loop FILE) whose variables become sliders. Views: a verdict badge, Bode (magnitude
    above phase) and Nyquist of the outer loop with its margins, Z(jw) with its
    non-passive bands, step and impulse responses, PM over (f_n, GS) and over the two
    delays. Export the design as TOML/JSON, copy the equivalent seactl command line.

    \b
    Needs the app extra (Bokeh): from the clone, .venv/bin/pip install -e ".[app]"
    """
    from seactl.apps.explore.server import check_port_free

    check_address(host, port, allow_remote)
    loop = None
    if loop_file is not None:
        import seactl as sc
        from seactl.apps.explore.loopmodel import check_loop

        loop = (check_loop(sc.load_loop(loop_file)), loop_file)
    check_port_free(host, port)
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise SeactlError(f"seactl explore needs Bokeh, the app extra: from the clone, "
                          f"{sys.executable} -m pip install -e \".[app]\"") from None
    from seactl.apps.explore.server import serve

    serve(host, port, open_browser=not no_browser, announce=click.echo, loop=loop)
