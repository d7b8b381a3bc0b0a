"""``seactl run``: the exported controllers as real OS processes over UDP on loopback.

Three processes, each a ``python -m seactl.runtime ROLE CONFIG`` child:

``plant``
    The clock.  Every base period it integrates the SEA over the period that just ended
    (exactly, zero-order hold, the sampled simulation's plant matrices) with the current
    command computed for it, samples ``q_j`` and ``tau_k`` and sends them to the other
    two processes.  The plant and the embedded process are one actuator and its drive:
    when the command is not there at the tick, the plant waits for it (a late command,
    counted; the simulated physics does not move meanwhile) rather than apply a stale
    one, so the run stays comparable with the simulation.
``embedded``
    The exported ``embedded.py``: on each sample, one ``step`` with the newest stiffness
    message, and the current command back to the plant.
``high-level``
    The exported ``high_level.py`` at its rate; its message goes to ``embedded`` through
    an optional injected latency and loss.

Every message carries its tick and send time (``time.monotonic``, one clock for all
processes on a machine); every receiver logs its receive time.  The parent creates the
sockets (bound to 127.0.0.1 only) and hands them to the children, bounds the run time,
and terminates every child on exit, on Ctrl-C and when any child fails; a child that
hears nothing for ``PEER_TIMEOUT_S`` ends with an error (lost peer).

The prediction replays the run in the sampled simulation: the stiffness link is driven
by the measured arrival schedule (which central message the embedded process used at
each tick), so measured and simulated responses differ only if the model is wrong.
"""

from __future__ import annotations

import heapq
import json
import math
import random
import select
import socket
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

SENSE, CENTRAL, ACT, STOP = 0, 1, 2, 3
HEADER = struct.Struct("<Bqd")
PEER_TIMEOUT_S = 2.0
ROLES = ("plant", "embedded", "high-level")


def pack(kind: int, tick: int, values: Any = (), sent: float | None = None) -> bytes:
    """A message: kind, tick, send time (now unless given), values."""
    vals = [float(v) for v in values]
    t = time.monotonic() if sent is None else sent
    return HEADER.pack(kind, tick, t) + struct.pack(f"<{len(vals)}d", *vals)


def unpack(data: bytes) -> tuple[int, int, float, tuple[float, ...]]:
    kind, tick, sent = HEADER.unpack_from(data)
    n = (len(data) - HEADER.size) // 8
    return kind, tick, sent, struct.unpack_from(f"<{n}d", data, HEADER.size)


class LostPeer(RuntimeError):
    pass


def _recv(sock: socket.socket, timeout_s: float) -> bytes | None:
    ready, _, _ = select.select([sock], [], [], max(timeout_s, 0.0))
    return sock.recv(4096) if ready else None


def _timeout(cfg: dict[str, Any]) -> float:
    """Silence that means a lost peer (longer before the plant's clock starts)."""
    return max(PEER_TIMEOUT_S, cfg["t0"] - time.monotonic() + PEER_TIMEOUT_S)


def _load_class(path: Path, name: str) -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"_seactl_run_{path.stem}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return getattr(mod, name)()


# ----------------------------------------------------------------------------- plant
def run_plant(cfg: dict[str, Any], sock: socket.socket) -> dict[str, np.ndarray]:
    m = np.load(cfg["plant_npz"])
    Hx, Ha, Cx, Ca = m["Hx"], m["Ha"], m["Cx"], m["Ca"]
    Tb, K = 1.0 / cfg["base_rate_hz"], int(cfg["ticks"])
    peers = [("127.0.0.1", cfg["ports"][r]) for r in ("embedded", "high-level")]
    x = np.zeros(Hx.shape[0])
    act, act_tick = np.zeros(Ha.shape[1]), -1
    q = np.full(K + 1, np.nan)
    used = np.full(K + 1, -2)
    recv = []
    late = 0
    t0 = cfg["t0"]
    for k in range(K + 1):
        # the tick's time; then, the drive's command for the period just ended (a command
        # not there at the tick is late: counted, and waited for up to PEER_TIMEOUT_S)
        give_up = None
        while True:
            now = time.monotonic()
            wait = t0 + k * Tb - now
            if wait <= 0:
                if k == 0 or act_tick >= k - 1:
                    break
                if give_up is None:
                    give_up = now + PEER_TIMEOUT_S
                    late += 1
                wait = give_up - now
                if wait <= 0:
                    raise LostPeer("plant: no command from the embedded process for 2 s")
            data = _recv(sock, wait)
            if data:
                kind, tick, t_s, vals = unpack(data)
                recv.append((tick, t_s, time.monotonic()))
                if kind == ACT and tick > act_tick:
                    act, act_tick = np.array(vals), tick
        if k > 0:
            used[k - 1] = act_tick   # the command applied over [k-1, k]
            x = Hx @ x + Ha @ act
        y = Cx @ x + Ca @ act
        q[k] = y[cfg["q_row"]]
        msg = pack(SENSE, k, y[:cfg["n_sensed"]])
        for p in peers:
            sock.sendto(msg, p)
    for p in peers:
        sock.sendto(pack(STOP, K), p)
    return {"q": q, "act_used": used, "recv": np.array(recv).reshape(-1, 3),
            "late": np.array(late)}


# ----------------------------------------------------------------------------- controllers
def run_embedded(cfg: dict[str, Any], sock: socket.socket) -> dict[str, np.ndarray]:
    ctl = _load_class(Path(cfg["export_dir"]) / "embedded.py", "Embedded")
    plant = ("127.0.0.1", cfg["ports"]["plant"])
    K, every = int(cfg["ticks"]), int(cfg["period_ticks"]["embedded"])
    hl, hl_tick = 0.0, -1
    used = np.full(K + 1, -1)
    sense_lat, central = [], []
    while True:
        data = _recv(sock, _timeout(cfg))
        if data is None:
            raise LostPeer("embedded: no message for 2 s (a peer is gone)")
        now = time.monotonic()
        kind, tick, t_s, vals = unpack(data)
        if kind == STOP:
            break
        if kind == CENTRAL:
            central.append((tick, t_s, now))
            if tick > hl_tick:
                hl, hl_tick = vals[0], tick
        elif kind == SENSE:
            sense_lat.append((tick, t_s, now))
            if tick % every == 0:
                u = {"q_j": vals[0], "tau_k": vals[1], "q_des": cfg["step"],
                     "tau_fb_from_high_level": hl}
                out = ctl.step({n: u[n] for n in ctl.INPUTS})
                sock.sendto(pack(ACT, tick, [out[n] for n in ctl.OUTPUTS]), plant)
                used[tick] = hl_tick
    return {"central_used": used, "sense": np.array(sense_lat).reshape(-1, 3),
            "central": np.array(central).reshape(-1, 3)}


def run_high_level(cfg: dict[str, Any], sock: socket.socket) -> dict[str, np.ndarray]:
    ctl = _load_class(Path(cfg["export_dir"]) / "high_level.py", "HighLevel")
    emb = ("127.0.0.1", cfg["ports"]["embedded"])
    every = int(cfg["period_ticks"]["high-level"])
    extra, loss = float(cfg["extra_latency_s"]), float(cfg["loss"])
    rng = random.Random(cfg["seed"])
    queue: list[tuple[float, int, float, float]] = []
    sense_lat, dropped = [], 0
    while True:
        limit = _timeout(cfg)
        due = queue[0][0] - time.monotonic() if queue else limit
        data = _recv(sock, min(due, limit))
        while queue and queue[0][0] <= time.monotonic():
            _t, tick, value, made = heapq.heappop(queue)
            sock.sendto(pack(CENTRAL, tick, [value], sent=made), emb)   # injected: counted
        if data is None:
            if due < limit:
                continue
            raise LostPeer("high-level: no message for 2 s (a peer is gone)")
        kind, tick, t_s, vals = unpack(data)
        if kind == STOP:
            break
        sense_lat.append((tick, t_s, time.monotonic()))
        if kind == SENSE and tick % every == 0:
            out = ctl.step({"q_j": vals[0]})
            if rng.random() < loss:
                dropped += 1
                continue
            now = time.monotonic()
            heapq.heappush(queue, (now + extra, tick, out[ctl.OUTPUTS[0]], now))
    return {"sense": np.array(sense_lat).reshape(-1, 3), "dropped": np.array(dropped)}


# ----------------------------------------------------------------------------- parent
@dataclass(frozen=True)
class RunResult:
    """A distributed run: per-link latency samples [s], the measured and replayed
    responses, and the summary numbers (``summary``, JSON-ready)."""

    t_s: np.ndarray
    q_measured: np.ndarray
    q_replay: np.ndarray
    q_nominal: np.ndarray
    latency_s: dict[str, np.ndarray]
    summary: dict[str, Any]


def _plant_matrices(plan: Any) -> dict[str, np.ndarray]:
    """``x+ = Hx x + Ha a`` over one base period and the sensed rows ``Cx x + Ca a``."""
    H, CD = plan.Hp[..., 0], plan.CDp[..., 0]
    zp = plan.zp
    na = zp["act"].stop - zp["act"].start
    nxt = zp["next"].start
    x = zp["x"]
    return {"Hx": H[:, x], "Ha": H[:, zp["act"]] + H[:, nxt:nxt + na],
            "Cx": CD[plan.prow["sensed"], x], "Ca": CD[plan.prow["sensed"], zp["act"]]}


class _Replay:
    """Timing for :func:`seactl.simulate.simulate`: the stiffness link as measured."""

    blocks = ("Kq_fb",)

    def __init__(self, sched: np.ndarray):
        self.sched = sched

    def schedules(self, plan: Any) -> dict[str, np.ndarray]:
        return {"Kq_fb": self.sched[:, None]}


def _spawn(cfg: dict[str, Any], run_dir: Path, socks: dict[str, socket.socket]) -> None:
    """Start the three children; wait; on any failure, stop them all and raise."""
    from .errors import SeactlError

    path = run_dir / "config.json"
    path.write_text(json.dumps(cfg))
    procs: dict[str, subprocess.Popen] = {}
    deadline = cfg["t0"] + cfg["ticks"] / cfg["base_rate_hz"] + 20.0
    try:
        for role in ROLES:
            fd = socks[role].fileno()
            procs[role] = subprocess.Popen([sys.executable, "-m", "seactl.runtime", role,
                                            str(path)], pass_fds=(fd,), stdout=subprocess.DEVNULL,
                                           stderr=subprocess.PIPE, text=True)
        while any(p.poll() is None for p in procs.values()):
            bad = [r for r, p in procs.items() if p.poll() not in (None, 0)]
            if bad:
                err = (procs[bad[0]].stderr.read().strip().splitlines() or ["no message"])[-1]
                raise SeactlError(f"run: process {bad[0]!r} failed: {err}")
            if time.monotonic() > deadline:
                raise SeactlError("run: the processes did not finish in time")
            time.sleep(0.05)
        bad = [r for r, p in procs.items() if p.returncode != 0]
        if bad:
            err = (procs[bad[0]].stderr.read().strip().splitlines() or ["no message"])[-1]
            raise SeactlError(f"run: process {bad[0]!r} failed: {err}")
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.terminate()
        for p in procs.values():
            try:
                p.wait(timeout=3)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
            if p.stderr:
                p.stderr.close()


def _stats_ms(lat_s: np.ndarray) -> dict[str, float | int]:
    ms = np.asarray(lat_s) * 1e3
    if ms.size == 0:
        return {"count": 0}
    return {"count": int(ms.size), "mean_ms": float(ms.mean()),
            "p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max()), "jitter_ms": float(ms.std())}


def run_distributed(design: Any, *, duration_s: float = 2.0,
                    rates_hz: dict[str, float] | float = 1000.0, step: float = 0.01,
                    saturation_a: float | None = None, extra_latency_s: float = 0.0,
                    loss: float = 0.0, seed: int = 0, zero: bool = True,
                    startup_s: float = 3.0) -> RunResult:
    """Run the SEA design's exported controllers as three OS processes over UDP on
    loopback for ``duration_s`` and compare with the sampled simulation (module doc)."""
    from .errors import InputError
    from .export import compile_processes, export_files
    from .loops import sea_diagram
    from .simulate import compile_sampled

    for name, v, lo, hi in (("duration_s", duration_s, 0.1, 60.0),
                            ("extra_latency_s", extra_latency_s, 0.0, 1.0),
                            ("loss", loss, 0.0, 0.99), ("step", abs(step), 1e-6, 1.0)):
        if not (math.isfinite(v) and lo <= v <= hi):
            raise InputError(name, v, f"in [{lo:g}, {hi:g}]")
    diagram = sea_diagram(zero)
    sat = {"i_m": design.actuator.max_current if saturation_a is None else saturation_a}
    ctl = compile_processes(diagram, design, rates_hz, sat)
    Tb = 1.0 / ctl.base_rate_hz
    if ctl.base_rate_hz > 5000:
        raise InputError("rates_hz", ctl.base_rate_hz, "<= 5000 Hz for a run (Python processes)")
    K = int(round(duration_s / Tb))
    plan = compile_sampled(diagram, design, {}, Tb, (), rates_hz=rates_hz, saturation=sat)
    with tempfile.TemporaryDirectory(prefix="seactl-run-") as tmp:
        run_dir = Path(tmp)
        (run_dir / "export").mkdir()
        for name, text in export_files(ctl, ("python",)).items():
            (run_dir / "export" / name).write_text(text)
        np.savez(run_dir / "plant.npz", **_plant_matrices(plan))
        socks = {r: socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for r in ROLES}
        try:
            for s in socks.values():
                s.bind(("127.0.0.1", 0))
            cfg = {"base_rate_hz": ctl.base_rate_hz, "ticks": K, "step": float(step),
                   "period_ticks": {p.name: p.period_ticks for p in ctl.processes},
                   "ports": {r: s.getsockname()[1] for r, s in socks.items()},
                   "fds": {r: s.fileno() for r, s in socks.items()},
                   "plant_npz": str(run_dir / "plant.npz"), "export_dir": str(run_dir / "export"),
                   "run_dir": str(run_dir), "q_row": list(ctl.sensed).index("q_j"),
                   "n_sensed": len(ctl.sensed), "extra_latency_s": float(extra_latency_s),
                   "loss": float(loss), "seed": int(seed), "t0": time.monotonic() + startup_s}
            _spawn(cfg, run_dir, socks)
        finally:
            for s in socks.values():
                s.close()
        logs = {r: dict(np.load(run_dir / f"log-{r}.npz")) for r in ROLES}
    return _analyse(diagram, design, ctl, logs, K, step, sat, rates_hz,
                    {"extra_latency_ms": extra_latency_s * 1e3, "loss": loss})


def _analyse(diagram: Any, design: Any, ctl: Any, logs: dict[str, dict[str, np.ndarray]],
             K: int, step: float, sat: dict[str, float], rates_hz: Any,
             injected: dict[str, float]) -> RunResult:
    """Latency per link, tracking error, and the replayed and nominal simulations."""
    from .simulate import Step, simulate

    Tb = 1.0 / ctl.base_rate_hz
    hl = ctl.process("high-level")
    n_c = dict(hl.buffers).get("Kq_fb", 0) * hl.period_ticks
    used = logs["embedded"]["central_used"]
    sched = np.where(used >= 0, np.maximum(used - n_c, -1), -1)
    sched = np.maximum.accumulate(sched)
    t_end = K * Tb
    base = {p: ctl.base_rate_hz for p in ctl.names}
    rep = simulate(diagram, design, {"q_des": Step(step)}, t_end, mode="sampled",
                   outputs=("q_j",), rates_hz=base, saturation=sat, timing=_Replay(sched))
    nom = simulate(diagram, design, {"q_des": Step(step)}, t_end, mode="sampled",
                   outputs=("q_j",), rates_hz=rates_hz, saturation=sat)
    q = logs["plant"]["q"]
    q_rep, q_nom = np.ravel(rep.outputs["q_j"]), np.ravel(nom.outputs["q_j"])
    lat = {"plant->embedded": logs["embedded"]["sense"],
           "plant->high-level": logs["high-level"]["sense"],
           "high-level->embedded": logs["embedded"]["central"],
           "embedded->plant": logs["plant"]["recv"]}
    lat_s = {k: (v[:, 2] - v[:, 1]) for k, v in lat.items()}
    k = np.arange(K + 1)
    age = np.where(sched >= 0, k - sched, np.nan)
    lat_s["stiffness"] = (Tb / 2 + age[np.isfinite(age)] * Tb)
    act_used = logs["plant"]["act_used"][:K]
    summary = {
        "transport": "udp", "duration_s": K * Tb, "ticks": K + 1,
        "rates_hz": {p.name: p.rate_hz for p in ctl.processes}, **injected,
        "dropped": int(logs["high-level"]["dropped"]),
        "links": {name: _stats_ms(v) for name, v in lat_s.items()},
        "late_commands": int(logs["plant"]["late"]),
        "stale_commands": int(np.sum(act_used != k[:K])),
        "tracking_rms": float(np.sqrt(np.mean((q - step) ** 2))),
        "replay_max_diff": float(np.max(np.abs(q - q_rep)) / abs(step)),
        "nominal_max_diff": float(np.max(np.abs(q - q_nom)) / abs(step)),
        "final_value": float(q[-1] / step),
    }
    return RunResult(k * Tb, q, q_rep, q_nom, lat_s, summary)


RUN_MARKER = ".seactl-run"


def link_file(link: str) -> str:
    """``latency-plant-to-embedded.csv`` for link ``plant->embedded``."""
    return "latency-" + link.replace("->", "-to-") + ".csv"


def run_files(res: RunResult) -> dict[str, str]:
    """``summary.json``, ``response.csv`` and one ``latency-*.csv`` per link (one column
    ``latency_ms``: readable by ``seactl step --latency LINK=hist:FILE``)."""
    files = {"summary.json": json.dumps(res.summary, indent=1) + "\n"}
    rows = "".join(f"{t!r},{a!r},{b!r},{c!r}\n" for t, a, b, c in
                   zip(res.t_s.tolist(), res.q_measured.tolist(), res.q_replay.tolist(),
                       res.q_nominal.tolist()))
    files["response.csv"] = "t_s,q_measured_rad,q_replay_rad,q_nominal_rad\n" + rows
    for link, lat in res.latency_s.items():
        files[link_file(link)] = "latency_ms\n" + "".join(f"{v * 1e3!r}\n" for v in lat.tolist())
    return files


def worker_main(role: str, config: str) -> int:
    cfg = json.loads(Path(config).read_text())
    sock = socket.socket(fileno=cfg["fds"][role])
    run = {"plant": run_plant, "embedded": run_embedded, "high-level": run_high_level}[role]
    try:
        logs = run(cfg, sock)
    except LostPeer as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    finally:
        sock.close()
    np.savez(Path(cfg["run_dir"]) / f"log-{role}.npz", **logs)
    return 0


if __name__ == "__main__":
    sys.exit(worker_main(sys.argv[1], sys.argv[2]))
