"""The run's wire protocol: roles, peers, message packing, timeouts."""

from __future__ import annotations

import struct
import time
from typing import Any

SENSE, CENTRAL, ACT, STOP, HELLO, START = 0, 1, 2, 3, 4, 5
HEADER = struct.Struct("<Bqd")
PEER_TIMEOUT_S = 2.0
POLL_S = 50e-6
"""Zenoh: how often a process looks for a new message while none is waiting."""
STARTUP_TIMEOUT_S = 30.0
"""Longest start-up (imports, sessions, every link proven by a message) before the run."""
ROLES = ("plant", "embedded", "high-level")
TRANSPORTS = ("zenoh", "udp")
PEERS = {"plant": (), "embedded": ("plant",), "high-level": ("plant", "embedded")}
"""Zenoh: whom each process connects to (the others listen): no cycle, so no process
waits for one that waits for it."""


def pack(kind: int, tick: int, values: Any = (), sent: float | None = None) -> bytes:
    """A message: kind, tick, send time (now unless given), values."""
    vals = [float(v) for v in values]
    t = time.monotonic() if sent is None else sent
    return HEADER.pack(kind, tick, t) + struct.pack(f"<{len(vals)}d", *vals)


def unpack(data: bytes) -> tuple[int, int, float, tuple[float, ...]]:
    kind, tick, sent = HEADER.unpack_from(data)
    n = (len(data) - HEADER.size) // 8
    return kind, tick, sent, struct.unpack_from(f"<{n}d", data, HEADER.size)


LINK_PARAMETERS = """transport : {"zenoh", "udp"}
    Message transport (loopback only).
extra_latency_s : float
    Latency [s] injected on the high-level -> embedded link (0 to 1).
loss : float
    Probability of losing a high-level -> embedded message (0 to 0.99).
seed : int
    Seed of the losses."""
"""The parameters every ``run`` method shares, documented once (:func:`run_doc`)."""


def run_doc(method: Any) -> Any:
    """Put :data:`LINK_PARAMETERS` where ``method``'s docstring says ``{link_parameters}``
    (a method's docstring: indented by eight spaces)."""
    text = "\n".join(("        " + line) if line else line
                     for line in LINK_PARAMETERS.splitlines())
    method.__doc__ = method.__doc__.replace("        {link_parameters}", text)
    return method


class LostPeer(RuntimeError):
    pass
