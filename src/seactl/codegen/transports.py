"""Message transports between processes: Zenoh and UDP on loopback."""

from __future__ import annotations

import json
import select
import socket
import time
from pathlib import Path
from typing import Any

from seactl.codegen.protocol import (
    HELLO,
    PEER_TIMEOUT_S,
    PEERS,
    POLL_S,
    ROLES,
    START,
    STARTUP_TIMEOUT_S,
    LostPeer,
    pack,
    unpack,
)


# ----------------------------------------------------------------------------- transports
class UdpLink:
    """Datagrams between sockets bound to 127.0.0.1 (the parent binds them)."""

    def __init__(self, cfg: dict[str, Any], role: str):
        self.sock = socket.socket(fileno=cfg["fds"][role])
        self.peers = {r: ("127.0.0.1", port) for r, port in cfg["ports"].items()}

    def send(self, to: str, data: bytes) -> None:
        self.sock.sendto(data, self.peers[to])

    def recv(self, timeout_s: float) -> tuple[bytes, float] | None:
        """A message and its receive time, or None after ``timeout_s``."""
        ready, _, _ = select.select([self.sock], [], [], max(timeout_s, 0.0))
        return (self.sock.recv(4096), time.monotonic()) if ready else None

    def close(self) -> None:
        self.sock.close()


def zenoh_config(cfg: dict[str, Any], role: str) -> Any:
    """A peer listening on its loopback port only, connected to ``PEERS[role]``, with
    multicast and gossip scouting off (nothing is discovered or announced)."""
    import zenoh

    conf = zenoh.Config()
    ep = {r: f"tcp/127.0.0.1:{port}" for r, port in cfg["ports"].items()}
    for key, value in (("mode", "peer"), ("listen/endpoints", [ep[role]]),
                       ("connect/endpoints", [ep[r] for r in PEERS[role]]),
                       ("scouting/multicast/enabled", False),
                       ("scouting/gossip/enabled", False)):
        conf.insert_json5(key, json.dumps(value))
    return conf


class ZenohLink:
    """A Zenoh session: one key per receiving process (``seactl/run/<run>/<role>``)."""

    def __init__(self, cfg: dict[str, Any], role: str):
        import zenoh

        self.session = zenoh.open(zenoh_config(cfg, role))
        key = f"seactl/run/{cfg['run_id']}/"
        # Samples wait in Zenoh's own channel and are polled (``try_recv`` never blocks):
        # blocking calls into Zenoh hold the GIL, and a Python callback on Zenoh's thread
        # or a blocking ``recv`` in a thread can hang a process that also publishes.
        self.sub = self.session.declare_subscriber(key + role)
        # reliable, never dropped when the queue is full (a lost sample would stall the
        # plant), and sent at once rather than batched (latency is what is measured)
        self.pubs = {r: self.session.declare_publisher(
            key + r, congestion_control=zenoh.CongestionControl.BLOCK,
            reliability=zenoh.Reliability.RELIABLE, express=True)
            for r in ROLES if r != role}

    def send(self, to: str, data: bytes) -> None:
        self.pubs[to].put(data)

    def recv(self, timeout_s: float) -> tuple[bytes, float] | None:
        end = time.monotonic() + max(timeout_s, 0.0)
        while True:
            sample = self.sub.try_recv()
            now = time.monotonic()
            if sample is not None:
                return sample.payload.to_bytes(), now
            if now >= end:
                return None
            time.sleep(min(POLL_S, end - now))

    def close(self) -> None:
        self.session.close()


def peer_timeout_s(cfg: dict[str, Any]) -> float:
    """Silence that means a lost peer (longer before the plant's clock starts)."""
    return max(PEER_TIMEOUT_S, cfg["t0"] - time.monotonic() + PEER_TIMEOUT_S)


def load_controller_class(path: Path, name: str) -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"_seactl_run_{path.stem}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return getattr(mod, name)()


def handshake(cfg: dict[str, Any], role: str, link: Any) -> None:
    """Prove every link before the clock starts: each process says HELLO to the others
    every 20 ms (flagged *ready* once it has heard all of them); when the plant has heard
    both controllers ready it sends START with the common start time ``t0`` (set in
    ``cfg``).  A message that arrives proves its path works (for Zenoh, that the sender
    knows the receiver's subscription), so no sample of the run is lost to start-up."""
    index = ROLES.index(role)
    others = [r for r in ROLES if r != role]
    heard: dict[int, float] = {}
    give_up = time.monotonic() + STARTUP_TIMEOUT_S
    next_hello = 0.0
    while True:
        now = time.monotonic()
        if now > give_up:
            raise LostPeer(f"{role}: the other processes did not all answer during start-up")
        if role == "plant" and len(heard) == 2 and all(heard.values()):
            t0 = now + 0.1
            for r in others:
                link.send(r, pack(START, 0, [t0]))
            cfg["t0"] = t0
            return
        if now >= next_hello:
            ready = float(len(heard) == len(others))
            for r in others:
                link.send(r, pack(HELLO, 0, [index, ready]))
            next_hello = now + 0.02
        got = link.recv(min(next_hello - now, 0.02))
        if got is None:
            continue
        kind, _tick, _sent, vals = unpack(got[0])
        if kind == START:
            cfg["t0"] = vals[0]
            return
        if kind == HELLO:
            heard[int(vals[0])] = bool(vals[1])
