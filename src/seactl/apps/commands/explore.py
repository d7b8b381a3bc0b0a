"""``seactl explore``: the interactive explorer in the browser (Bokeh server)."""

from __future__ import annotations

import sys
from typing import Any

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
@click.option("--robot", "robot_urdf", default=None, metavar="FILE.urdf",
              help="Explore this robot instead (docs/explore.md, \"Robots\").")
@click.option("--actuators", default=None,
              help="With --robot: SEA preset or TOML file for every joint, or "
                   "JOINT=PRESET|FILE,... [default: ut-sea]")
@click.option("--space", type=click.Choice(["joint", "task"]), default=None,
              help="With --robot: the first stiffness space [default: joint].")
@click.option("--task", default=None,
              help="With --robot: task frame (default: the URDF's last link).")
@click.option("--q0", default=None,
              help="With --robot: first configuration [rad], comma-separated (default 0).")
def explore(host: str, port: int, no_browser: bool, allow_remote: bool,
            loop_file: str | None, robot_urdf: str | None = None,
            actuators: str | None = None, space: str | None = None, task: str | None = None,
            q0: str | None = None) -> None:
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
    --robot FILE.urdf: a robot page instead (sc.robot): a slider per joint angle, f_n,
    the three delays, joint or task space and the task frame; the certified verdict,
    margins per loop break, the impedance's principal values, the step of joint 1, and
    a workspace map over two joints on request (sc.workspace_map).

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
    robot = _robot_start(robot_urdf, loop_file, actuators, space, task, q0)
    check_port_free(host, port)
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise SeactlError(f"seactl explore needs Bokeh, the app extra: from the clone, "
                          f"{sys.executable} -m pip install -e \".[app]\"") from None
    from seactl.apps.explore.server import serve

    serve(host, port, open_browser=not no_browser, announce=click.echo, loop=loop,
          robot=robot)


def _robot_start(urdf: str | None, loop_file: str | None, actuators: str | None,
                 space: str | None, task: str | None, q0: str | None) -> Any:
    """The robot page's first controls, checked now (a bad URDF, frame, actuator or
    ``--q0`` is a one-line error before the server starts); None without ``--robot``."""
    if urdf is None:
        for flag, value in (("--actuators", actuators), ("--space", space),
                            ("--task", task), ("--q0", q0)):
            if value is not None:
                raise InputError(flag, value, "given with --robot")
        return None
    if loop_file is not None:
        raise InputError("--robot", urdf, "given without --loop (one page at a time)")
    from seactl.apps.explore.robotmodel import q_from_text, start_controls

    return start_controls(urdf, actuators=actuators or "ut-sea", space=space or "joint",
                          task=task, q_rad=q_from_text(q0))
