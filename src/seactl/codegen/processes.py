"""The plant and controller processes of seactl run."""

from __future__ import annotations

import heapq
import json
import random
import time
from pathlib import Path
from typing import Any

import numpy as np

from seactl.codegen.protocol import (
    ACT,
    CENTRAL,
    PEER_TIMEOUT_S,
    SENSE,
    STOP,
    LostPeer,
    pack,
    unpack,
)
from seactl.codegen.transports import load_controller_class, peer_timeout_s


# ----------------------------------------------------------------------------- plant
class MatrixPlant:
    """The builtin plant: ``x+ = Hx x + Ha a`` over one base period, sensed ``Cx x + Ca a``
    (the sampled simulation's exact zero-order-hold matrices)."""

    def __init__(self, npz: str):
        m = np.load(npz)
        self.Hx, self.Ha, self.Cx, self.Ca = m["Hx"], m["Ha"], m["Cx"], m["Ca"]
        self.x = np.zeros(self.Hx.shape[0])

    def advance(self, act: np.ndarray) -> None:
        self.x = self.Hx @ self.x + self.Ha @ act

    def sense(self, act: np.ndarray) -> np.ndarray:
        return self.Cx @ self.x + self.Ca @ act


class MujocoPlantProcess:
    """``--plant mujoco``: the model of :mod:`seactl.codegen.mjcf` stepped by MuJoCo."""

    def __init__(self, cfg: dict[str, Any]):
        from seactl.codegen.mjcf import PlantModel
        from seactl.codegen.mujoco_plant import MujocoPlant

        model = PlantModel.from_dict(json.loads(Path(cfg["plant_model"]).read_text()))
        self.plant = MujocoPlant(model, 1.0 / cfg["base_rate_hz"], cfg["sensed"],
                                 cfg["actuation"])

    def advance(self, act: np.ndarray) -> None:
        self.plant.advance(act)

    def sense(self, act: np.ndarray) -> np.ndarray:
        return self.plant.sense()


def make_plant(cfg: dict[str, Any]) -> MatrixPlant | MujocoPlantProcess:
    """The run's plant (``cfg["plant"]``: ``"builtin"`` or ``"mujoco"``), at rest."""
    return MujocoPlantProcess(cfg) if cfg.get("plant") == "mujoco" else \
        MatrixPlant(cfg["plant_npz"])


def run_plant(cfg: dict[str, Any], link: Any) -> dict[str, np.ndarray]:
    plant = make_plant(cfg)
    Tb, K = 1.0 / cfg["base_rate_hz"], int(cfg["ticks"])
    act, act_tick = np.zeros(len(cfg["actuation"])), -1
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
                    raise LostPeer(f"plant: no command from the embedded process for 2 s "
                                   f"(tick {k}, last command for tick {act_tick})")
            got = link.recv(wait)
            if got:
                kind, tick, t_s, vals = unpack(got[0])
                if kind != ACT:
                    continue  # a late start-up HELLO
                recv.append((tick, t_s, got[1]))
                if tick > act_tick:
                    act, act_tick = np.array(vals), tick
        if k > 0:
            used[k - 1] = act_tick   # the command applied over [k-1, k]
            plant.advance(act)
        y = plant.sense(act)
        q[k] = y[0]   # the first sensed signal: the output analyse_run compares
        msg = pack(SENSE, k, y[:len(cfg["sensed"])])
        for r in ("embedded", "high-level"):
            link.send(r, msg)
    for r in ("embedded", "high-level"):
        link.send(r, pack(STOP, K))
    return {"q": q, "act_used": used, "recv": np.array(recv).reshape(-1, 3),
            "late": np.array(late)}


# ----------------------------------------------------------------------------- controllers
def _inputs(cfg: dict[str, Any], ctl: Any, sensed: tuple[float, ...],
            held: dict[str, float]) -> dict[str, float]:
    """A controller's inputs by name: sensed signals, references (the step), messages."""
    u = dict(zip(cfg["sensed"], sensed)) | {r: cfg["step"] for r in cfg["references"]}
    return {n: u[n] if n in u else held[n] for n in ctl.INPUTS}


def run_embedded(cfg: dict[str, Any], link: Any) -> dict[str, np.ndarray]:
    ctl = load_controller_class(Path(cfg["export_dir"]) / "embedded.py", "Embedded")
    K, every = int(cfg["ticks"]), int(cfg["period_ticks"]["embedded"])
    names = list(cfg["message"])
    held, hl_tick = dict(cfg["message"]), -1   # the high-level's message at rest
    used = np.full(K + 1, -1)
    sense_lat, central = [], []
    while True:
        got = link.recv(peer_timeout_s(cfg))
        if got is None:
            raise LostPeer(f"embedded: no message for 2 s (a peer is gone; last sample "
                           f"{sense_lat[-1][0] if sense_lat else None})")
        kind, tick, t_s, vals = unpack(got[0])
        if kind == STOP:
            break
        if kind == CENTRAL:
            central.append((tick, t_s, got[1]))
            if tick > hl_tick:
                held, hl_tick = dict(zip(names, vals)), tick
        elif kind == SENSE:
            sense_lat.append((tick, t_s, got[1]))
            if tick % every == 0:
                out = ctl.step(_inputs(cfg, ctl, vals, held))
                link.send("plant", pack(ACT, tick, [out[n] for n in cfg["actuation"]]))
                used[tick] = hl_tick
    return {"central_used": used, "sense": np.array(sense_lat).reshape(-1, 3),
            "central": np.array(central).reshape(-1, 3)}


def run_high_level(cfg: dict[str, Any], link: Any) -> dict[str, np.ndarray]:
    ctl = load_controller_class(Path(cfg["export_dir"]) / "high_level.py", "HighLevel")
    every = int(cfg["period_ticks"]["high-level"])
    extra, loss = float(cfg["extra_latency_s"]), float(cfg["loss"])
    rng = random.Random(cfg["seed"])
    queue: list[tuple[float, int, list[float], float]] = []
    sense_lat, dropped = [], 0
    while True:
        limit = peer_timeout_s(cfg)
        due = queue[0][0] - time.monotonic() if queue else limit
        got = link.recv(min(due, limit))
        while queue and queue[0][0] <= time.monotonic():
            _t, tick, values, made = heapq.heappop(queue)
            link.send("embedded", pack(CENTRAL, tick, values, sent=made))   # injected
        if got is None:
            if due < limit:
                continue
            raise LostPeer("high-level: no message for 2 s (a peer is gone)")
        kind, tick, t_s, vals = unpack(got[0])
        if kind == STOP:
            break
        if kind != SENSE:
            continue  # a late start-up HELLO
        sense_lat.append((tick, t_s, got[1]))
        if tick % every == 0:
            out = ctl.step(_inputs(cfg, ctl, vals, {}))
            if rng.random() < loss:
                dropped += 1
                continue
            now = time.monotonic()
            heapq.heappush(queue, (now + extra, tick, [out[n] for n in cfg["message"]], now))
    return {"sense": np.array(sense_lat).reshape(-1, 3), "dropped": np.array(dropped)}
