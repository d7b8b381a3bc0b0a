"""Serve the explorer with Bokeh's Tornado server on one address and port."""

from __future__ import annotations

import functools
import ipaddress
import webbrowser
from collections.abc import Callable
from typing import Any

from seactl.errors import InputError

LOOPBACK_NAMES = ("localhost",)


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and addresses in 127.0.0.0/8 or ``::1``."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def url(host: str, port: int) -> str:
    """The page's address (IPv6 literals bracketed)."""
    h = host.strip("[]")
    return f"http://{'[' + h + ']' if ':' in h else h}:{port}/"


def check_port_free(host: str, port: int) -> None:
    """Refuse (:class:`InputError` naming ``--port``) a port another program listens on,
    by binding it as the server will (``SO_REUSEADDR``): before anything slow is loaded."""
    import socket

    try:
        infos = socket.getaddrinfo(host.strip("[]"), port, type=socket.SOCK_STREAM,
                                   flags=socket.AI_PASSIVE)
    except OSError as exc:
        raise InputError("--host", host, f"an address of this machine ({exc})") from None
    for family, kind, proto, _, address in infos:
        with socket.socket(family, kind, proto) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                probe.bind(address)
            except OSError as exc:
                raise InputError("--port", port, f"a free port on {host} "
                                 f"({exc.strerror})") from None


def serve(host: str, port: int, *, open_browser: bool = True,
          announce: Callable[[str], None] = print, loop: tuple[Any, str] | None = None,
          robot: tuple[Any, Any] | None = None) -> None:
    """Bind, warm the caches, then serve until interrupted (Ctrl+C or SIGTERM: the
    ``KeyboardInterrupt`` propagates once the server is stopped).  ``loop``: a loop file
    every new page starts with, ``(UserLoop, file name)``; ``robot``: serve the robot
    page instead, ``(RobotControls, RobotInfo)`` (:func:`~seactl.apps.explore.robotmodel.
    start_controls`).

    Websocket connections are accepted only from pages served under ``host:port``
    (and ``localhost:port`` on a loopback address), Bokeh's cross-origin check.
    """
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    from . import loopmodel
    from .model import Controls, views

    origins = [f"{host}:{port}"] + ([f"localhost:{port}", f"127.0.0.1:{port}"]
                                    if is_loopback(host) else [])
    try:
        page = (functools.partial(_sea_page, loop=loop) if robot is None
                else functools.partial(_robot_page, start=robot))
        server = Server({"/": Application(FunctionHandler(page))}, address=host,
                        port=port, allow_websocket_origin=origins, num_procs=1)
    except OSError as exc:
        raise InputError("--port", port, f"a free port on {host} ({exc.strerror})") from None
    if robot is not None:
        from . import robotmodel

        robotmodel.safe_views(robot[0])  # compiles and caches the robot's diagram
    else:
        views(Controls())  # the first evaluation loads the derived loop, not a user
    if loop is not None:
        loopmodel.views(loopmodel.LoopControls(*loop))
    server.start()
    announce(f"seactl explore: serving on {url(host, port)} (Ctrl+C stops)")
    if open_browser:
        server.io_loop.add_callback(webbrowser.open, url(host, port))
    try:
        server.io_loop.start()   # until Ctrl-C or SIGTERM (the caller's exit status)
    finally:
        server.stop()


def _robot_page(doc: Any, start: tuple[Any, Any]) -> None:
    from .robotapp import make_robot_document

    make_robot_document(doc, start)


def _sea_page(doc: Any, loop: tuple[Any, str] | None) -> None:
    from .app import make_document
    from .robotapp import open_uploaded_robot

    make_document(doc, loop=loop, robot_page=open_uploaded_robot)
