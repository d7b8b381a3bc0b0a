"""Free-running processes of ``seactl run --realtime``.

Every process (plant, embedded, high-level) ticks on its own clock at its own rate: tick
``k`` is due at ``t0 + k T`` on ``CLOCK_MONOTONIC`` (absolute ``clock_nanosleep`` on
Linux, so a late tick does not shift the ones after it), and no process ever waits for
another's message.  At each tick a process takes every message that has arrived, uses
the newest sample of each link (zero-order hold), runs its step and sends its outputs.

Each message carries the sender's sequence number on that link and its send time.  A
receiver counts, per link: received samples, lost ones (sequence gaps, and at the end
the sequence numbers the sender's final STOP says were sent and never came), reordered
ones (a sample older than the newest: counted as received, no longer as lost), stale
ticks (no new sample since the previous tick) and the latency of each sample it used
(send to the tick that first used it).  A process sleeps between its ticks, so it
takes its messages at its ticks; a receive time between ticks is not observed.  So
``received + lost = sent`` on every link, by construction of the counts rather than
assumed.

The controllers are the exported C (:mod:`seactl.codegen.cbinding`); ``fresh`` for the
watchdog is "a new sample arrived on every message link since the previous tick".
"""

from __future__ import annotations

import heapq
import math
import random
import time
from typing import Any

import numpy as np

from seactl.codegen.protocol import (
    ACT,
    CENTRAL,
    HELLO,
    PEER_TIMEOUT_S,
    ROLES,
    SENSE,
    START,
    STOP,
    LostPeer,
    pack,
    unpack,
)

LINKS = {SENSE: "plant->{role}", CENTRAL: "high-level->embedded", ACT: "embedded->plant"}
"""Message kind -> the link it travels (``{role}``: the receiver)."""
SENDS = {"plant": ((SENSE, "embedded"), (SENSE, "high-level")),
         "embedded": ((ACT, "plant"),), "high-level": ((CENTRAL, "embedded"),)}
"""What each process sends every tick, to whom."""
RECEIVES = {"plant": (ACT,), "embedded": (SENSE, CENTRAL), "high-level": (SENSE,)}


# ----------------------------------------------------------------------------- clock
class Clock:
    """Deadlines ``t0 + k T`` on the monotonic clock, slept to with absolute
    ``clock_nanosleep`` (Linux) or ``time.sleep`` of the remaining time."""

    def __init__(self, t0_s: float, rate_hz: float):
        self.t0_ns = int(round(t0_s * 1e9))
        self.period_ns = int(round(1e9 / rate_hz))
        self._abs = _absolute_sleep()

    def deadline_s(self, k: int) -> float:
        return (self.t0_ns + k * self.period_ns) * 1e-9

    def sleep_until_ns(self, t_ns: int) -> None:
        if self._abs is not None:
            self._abs(t_ns)
            return
        while (left := t_ns - time.monotonic_ns()) > 0:
            time.sleep(left * 1e-9)

    def sleep_until_tick(self, k: int) -> None:
        self.sleep_until_ns(self.t0_ns + k * self.period_ns)


def _absolute_sleep() -> Any:
    """``sleep(t_ns)`` to an absolute ``CLOCK_MONOTONIC`` time, or None off Linux."""
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        nanosleep = libc.clock_nanosleep
    except (OSError, AttributeError):
        return None

    class Timespec(ctypes.Structure):
        _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]

    def sleep(t_ns: int) -> None:
        ts = Timespec(t_ns // 1_000_000_000, t_ns % 1_000_000_000)
        while nanosleep(1, 1, ctypes.byref(ts), None) == 4:   # MONOTONIC, ABSTIME; EINTR
            pass
    return sleep


# ----------------------------------------------------------------------------- links
class Inbox:
    """The receiving end of one link: the newest sample and the link's counts."""

    def __init__(self, default: list[float]):
        self.values, self.newest, self.sent_s, self.new = list(default), -1, math.nan, False
        self.received = self.lost = self.reordered = self.stale = 0
        self.sent: int | None = None
        self.use_s: list[float] = []

    def put(self, seq: int, sent_s: float, values: Any) -> None:
        self.received += 1
        if seq > self.newest:
            self.lost += seq - self.newest - 1
            self.newest, self.sent_s, self.values, self.new = seq, sent_s, list(values), True
        else:
            self.reordered += 1
            self.lost -= 1

    def take(self, now_s: float) -> bool:
        """At a tick: True (and the sample's latency logged) if a new sample came since
        the previous tick, else a stale tick."""
        if self.new:
            self.use_s.append(now_s - self.sent_s)
            self.new = False
            return True
        self.stale += 1
        return False

    def close(self, sent: int) -> None:
        """The sender's STOP: ``sent`` samples were sent; the missing tail is lost."""
        self.sent = sent
        if sent - 1 > self.newest:
            self.lost += sent - 1 - self.newest
            self.newest = sent - 1

    def log(self, prefix: str) -> dict[str, np.ndarray]:
        return {prefix + "counts": np.array([self.sent if self.sent is not None else -1,
                                             self.received, self.lost, self.reordered,
                                             self.stale]),
                prefix + "use_s": np.array(self.use_s)}


class Outbox:
    """The sending end of a process: sequence numbers per link, injected latency and
    loss (the high-level link's ``extra_latency_s`` and ``loss``)."""

    def __init__(self, link: Any, cfg: dict[str, Any], role: str):
        self.link, self.role = link, role
        self.seq = {to: 0 for _kind, to in SENDS[role]}
        self.extra = float(cfg["extra_latency_s"]) if role == "high-level" else 0.0
        self.loss = float(cfg["loss"]) if role == "high-level" else 0.0
        self.rng = random.Random(cfg["seed"])
        self.queue: list[tuple[float, int, str, bytes]] = []
        self.dropped = 0

    def send(self, kind: int, to: str, values: Any) -> None:
        seq = self.seq[to]
        self.seq[to] = seq + 1
        if self.loss and self.rng.random() < self.loss:
            self.dropped += 1
            return
        data = pack(kind, seq, values)
        if self.extra:
            heapq.heappush(self.queue, (time.monotonic() + self.extra, seq, to, data))
        else:
            self.link.send(to, data)

    def flush(self, until_s: float, clock: Clock) -> None:
        """Send the delayed messages due before ``until_s``, each at its time."""
        while self.queue and self.queue[0][0] < until_s:
            due, _seq, to, data = heapq.heappop(self.queue)
            clock.sleep_until_ns(int(due * 1e9))
            self.link.send(to, data)

    def stop(self) -> None:
        for _due, _seq, to, data in sorted(self.queue):
            self.link.send(to, data)
        self.queue = []
        for to, n in self.seq.items():
            self.link.send(to, pack(STOP, n, [ROLES.index(self.role)]))


def drain(link: Any, inboxes: dict[int, Inbox], stops: set[int]) -> None:
    """Take every message waiting (never blocks); the links whose STOP came go in
    ``stops``."""
    while (got := link.recv(0.0)) is not None:
        kind, seq, sent_s, vals = unpack(got[0])
        if kind in inboxes:
            inboxes[kind].put(seq, sent_s, vals)
        elif kind == STOP:
            sender = ROLES[int(vals[0])]
            inboxes[_kind_from(sender)].close(seq)
            stops.add(_kind_from(sender))
        elif kind not in (HELLO, START):
            raise LostPeer(f"unexpected message kind {kind}")


def _kind_from(sender: str) -> int:
    return {"plant": SENSE, "embedded": ACT, "high-level": CENTRAL}[sender]


# ----------------------------------------------------------------------------- loop
def free_run(cfg: dict[str, Any], link: Any, role: str, tick: Any,
             defaults: dict[int, list[float]]) -> dict[str, np.ndarray]:
    """Tick ``role`` on its clock for the run's duration, then exchange STOPs.

    ``tick(k, now_s, inboxes, outbox)`` does the process's work at deadline ``k``.  A
    tick that ends after later deadlines have passed skips them (missed deadlines: the
    next tick is the latest deadline passed), so the process keeps its phase instead of
    running a burst of late ticks; ``ticks run + deadlines missed = deadlines``."""
    rate = float(cfg["rt_rates_hz"][role])
    n = int(cfg["rt_ticks"][role])
    clock = Clock(cfg["t0"], rate)
    inboxes = {kind: Inbox(defaults.get(kind, [])) for kind in RECEIVES[role]}
    outbox = Outbox(link, cfg, role)
    index, wake, done = [], [], []
    stops: set[int] = set()
    k = 0
    while k < n:
        outbox.flush(clock.deadline_s(k), clock)
        clock.sleep_until_tick(k)
        now = time.monotonic()
        drain(link, inboxes, stops)
        tick(k, time.monotonic(), inboxes, outbox)   # the samples' use time: after drain
        index.append(k)
        wake.append(now)
        done.append(time.monotonic())
        k = max(k + 1, (time.monotonic_ns() - clock.t0_ns) // clock.period_ns)
    outbox.stop()
    give_up = time.monotonic() + PEER_TIMEOUT_S
    while len(stops) < len(inboxes):
        if time.monotonic() > give_up:
            raise LostPeer(f"{role}: no end of run from every peer within 2 s")
        drain(link, inboxes, stops)
        time.sleep(1e-3)
    logs = {"tick": np.array(index, dtype=np.int64), "wake_s": np.array(wake),
            "done_s": np.array(done), "deadline0_s": np.array(clock.deadline_s(0)),
            "period_s": np.array(clock.period_ns * 1e-9), "deadlines": np.array(n),
            "dropped": np.array(outbox.dropped)}
    for kind, box in inboxes.items():
        logs |= box.log(link_key(LINKS[kind].format(role=role)))
    return logs


def link_key(link: str) -> str:
    """The log keys' prefix of a link: ``plant_to_embedded.`` for ``plant->embedded``."""
    return link.replace("->", "_to_").replace("-", "_") + "."


# ----------------------------------------------------------------------------- processes
def plant_stepper(cfg: dict[str, Any]) -> Any:
    """The plant as one function ``step(act, periods) -> sensed``: advance ``periods``
    base periods with the command applied at the previous call (nothing before the
    first), apply ``act`` from now on, and return the sensed signals; the built-in plant
    (:class:`seactl.codegen.processes.MatrixPlant`) or MuJoCo (``cfg["plant"]``)."""
    from seactl.codegen.processes import make_plant

    plant = make_plant(cfg)
    state: dict[str, Any] = {"act": None}

    def step(act: np.ndarray, periods: int) -> np.ndarray:
        for _ in range(periods if state["act"] is not None else 0):
            plant.advance(state["act"])
        state["act"] = act
        return plant.sense(act)
    return step


def plant_rt(cfg: dict[str, Any]) -> Any:
    """The plant process, ready to run (``run(link) -> logs``) once the clock is set: at
    the base rate, the newest command (held), one plant step, the samples out."""
    plant = plant_stepper(cfg)
    n_sensed = len(cfg["sensed"])
    q = np.full(int(cfg["rt_ticks"]["plant"]), np.nan)
    last = [0]

    def tick(k: int, now: float, inboxes: dict[int, Inbox], outbox: Outbox) -> None:
        box = inboxes[ACT]
        box.take(now)
        y = plant(np.array(box.values), k - last[0])
        last[0] = k
        q[k] = y[0]
        vals = [float(v) for v in y[:n_sensed]]
        outbox.send(SENSE, "embedded", vals)
        outbox.send(SENSE, "high-level", vals)

    def run(link: Any) -> dict[str, np.ndarray]:
        logs = free_run(cfg, link, "plant", tick, {ACT: [0.0] * len(cfg["actuation"])})
        return logs | {"q": q}
    return run


def controller_rt(cfg: dict[str, Any], role: str) -> Any:
    """A controller process, ready to run (``run(link) -> logs``; the library is loaded
    before the clock starts): the exported C at its rate on the newest samples."""
    from seactl.codegen.cbinding import CController

    names_in, names_out = cfg["rt_inputs"][role], cfg["rt_outputs"][role]
    ctl = CController(cfg["rt_lib"][role], cfg["rt_ident"][role], len(names_in),
                      len(names_out))
    msg_names = list(cfg["message"])
    refs = {r: cfg["step"] for r in cfg["references"]}
    watchdog = np.zeros(int(cfg["rt_ticks"][role]), dtype=np.int8)
    if role == "embedded":
        sends, pick = (ACT, "plant"), [names_out.index(a) for a in cfg["actuation"]]
    else:
        sends, pick = (CENTRAL, "embedded"), list(range(len(names_out)))

    def tick(k: int, now: float, inboxes: dict[int, Inbox], outbox: Outbox) -> None:
        sensed = inboxes[SENSE]
        sensed.take(now)
        u = dict(zip(cfg["sensed"], sensed.values)) | refs
        fresh = True
        if CENTRAL in inboxes:
            fresh = inboxes[CENTRAL].take(now)
            u |= dict(zip(msg_names, inboxes[CENTRAL].values))
        out, watchdog[k] = ctl.step([u[n] for n in names_in], fresh)
        outbox.send(sends[0], sends[1], [out[i] for i in pick])

    defaults = {SENSE: [0.0] * len(cfg["sensed"]), CENTRAL: list(cfg["message"].values())}

    def run(link: Any) -> dict[str, np.ndarray]:
        logs = free_run(cfg, link, role, tick, defaults)
        return logs | {"watchdog": watchdog, "binding": np.array(ctl.binding)}
    return run


def prepare_rt(cfg: dict[str, Any], role: str) -> Any:
    """Process ``role`` of a free-running run, loaded and ready: ``run(link) -> logs``."""
    return plant_rt(cfg) if role == "plant" else controller_rt(cfg, role)
