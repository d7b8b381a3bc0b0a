"""``seactl run``: the exported controllers as real OS processes on loopback.

Three processes, each a ``python -m seactl.codegen.runtime ROLE CONFIG`` child, for an SEA or a
rigid actuator (any diagram :func:`seactl.codegen.controllers.compile_processes` splits into a
``high-level`` and an ``embedded`` process):

``plant``
    The clock.  Every base period it integrates the actuator over the period that just
    ended (exactly, zero-order hold, the sampled simulation's plant matrices; or, with
    ``plant="mujoco"``, MuJoCo stepping the model of :mod:`seactl.codegen.mjcf`) with the
    command computed for it, samples the sensed signals and sends them to the other two
    processes.  The plant and the embedded process are one actuator and its drive: when
    the command is not there at the tick, the plant waits for it (a late command,
    counted; the simulated physics does not move meanwhile) rather than apply a stale
    one, so the run stays comparable with the simulation.
``embedded``
    The exported ``embedded.py``: on each sample, one ``step`` with the newest message of
    the high-level process, and the actuation back to the plant.  Until the first
    message arrives it holds the message the high-level process computes at rest (its
    output for the initial state and the reference), as a drive would be initialized.
``high-level``
    The exported ``high_level.py`` at its rate; its message goes to ``embedded`` through
    an optional injected latency and loss.

Transports (loopback only): **Zenoh** (the default; the middleware of ROS 2's rmw_zenoh),
each process a peer listening on ``tcp/127.0.0.1:PORT`` with scouting off, connected to
the others' explicit endpoints; or plain **UDP** datagrams between sockets the parent
binds to 127.0.0.1.  Every message carries its tick and send time (``time.monotonic``,
one clock for all processes on a machine); every receiver logs its receive time.  The
parent bounds the run time and terminates every child on exit, on Ctrl-C and when any
child fails; a child that hears nothing for ``PEER_TIMEOUT_S`` ends with an error (lost
peer).

The prediction replays the run in the sampled simulation: the high-level link is driven
by the measured arrival schedule (which high-level message the embedded process used at
each tick), so measured and simulated responses differ only if the model is wrong.

``realtime=True`` runs the same three processes free instead (:mod:`seactl.codegen.realtime`:
each on its own clock, the controllers being the exported C compiled per run,
:mod:`seactl.codegen.cbinding`); its summary holds the timing statistics
(:mod:`seactl.codegen.rtstats`) and no replay.
"""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from seactl.base.result import Result, json_value, new_axes
from seactl.codegen.processes import run_embedded, run_high_level, run_plant
from seactl.codegen.protocol import ROLES, STARTUP_TIMEOUT_S, TRANSPORTS, LostPeer
from seactl.codegen.realtime import link_key, prepare_rt
from seactl.codegen.rtstats import LINK_ROLES
from seactl.codegen.transports import UdpLink, ZenohLink, handshake, load_controller_class


# ----------------------------------------------------------------------------- parent
@dataclass(frozen=True)
class RunResult(Result):
    """A distributed run: per-link latency samples, the measured and replayed responses,
    and the summary numbers.

    Parameters
    ----------
    t_s : numpy.ndarray
        Base-tick times [s].
    q_measured, q_replay, q_nominal : numpy.ndarray
        The output measured on the plant process, simulated with the measured link timing,
        and simulated with the design's delays.
    latency_s : dict
        Link -> its latency samples [s].
    summary : dict
        JSON-ready summary (what ``seactl run --json`` prints).
    block_latency_s : dict
        Delayed block -> the measured latency of its loop [s]: lock-step, the blocks of
        the high-level process, half a base period plus the age of the message in use per
        tick; free-running, every controller's delayed block, the sum of the send-to-use
        latencies of the links the loop crosses
        (:func:`seactl.codegen.rtstats.loop_latency_s`).

    Attributes
    ----------
    t_s : ndarray
        Base-tick times [s].
    q_measured, q_replay, q_nominal : ndarray
        The system's output (``summary["output"]``) in its own unit (rad: SEA, m: rigid
        actuator): measured, replayed with the measured timing, simulated nominally.
    latency_s : dict
        Link -> its latency samples [s].
    summary : dict
        JSON-ready summary: transport, rates, per-link latency statistics [ms], tracking
        and replay differences.
    block_latency_s : dict
        Delayed block -> its loop's measured latency [s].
    """

    t_s: np.ndarray
    q_measured: np.ndarray
    q_replay: np.ndarray
    q_nominal: np.ndarray
    latency_s: dict[str, np.ndarray]
    summary: dict[str, Any]
    block_latency_s: dict[str, np.ndarray] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The summary (what ``seactl run --json`` prints, without the file list).

        Returns
        -------
        dict
            JSON-ready summary.
        """
        return dict(self.summary)

    def records(self) -> list[dict[str, Any]]:
        """One flat row per link: its latency statistics [ms].

        Returns
        -------
        list of dict
            ``link``, ``count``, ``mean_ms``, ``p50_ms``, ``p99_ms``, ``max_ms``,
            ``jitter_ms``; free-running: ``link``, ``sent``, ``received``, ``lost``,
            ``reordered``, ``stale_ticks`` and the send-to-use latency's ``count``,
            ``mean_ms``, ``p50_ms``, ``p99_ms``, ``max_ms``, ``min_ms``.
        """
        rows = []
        for link, stats in self.summary.get("links", {}).items():
            flat = {k: v for k, v in stats.items() if k not in ("histogram", "latency")}
            rows.append({"link": link, **{k: json_value(v) for k, v in
                                          (flat | stats.get("latency", {})).items()}})
        return rows

    def plot(self, ax: Any = None) -> Any:
        """The measured response against both simulations.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        t_ms = self.t_s * 1e3
        ax.plot(t_ms, self.q_measured, label="measured", lw=2)
        if np.any(np.isfinite(self.q_replay)):   # none for a free-running run
            ax.plot(t_ms, self.q_replay, "--", label="simulated, measured timing")
        ax.plot(t_ms, self.q_nominal, ":", label="simulated, design delays")
        ax.set_xlabel("time [ms]")
        ax.set_ylabel(str(self.summary.get("output", "output")))
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
        return ax


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
    """Timing for :func:`seactl.simulate.engine.simulate`: the high-level links as measured."""

    def __init__(self, scheds: dict[str, np.ndarray]):
        self.blocks = tuple(scheds)
        self.scheds = scheds

    def schedules(self, plan: Any) -> dict[str, np.ndarray]:
        return {b: s[:, None] for b, s in self.scheds.items()}


def _free_tcp_ports(n: int) -> list[int]:
    """Ports the kernel just had free on 127.0.0.1 (Zenoh binds them itself)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_STREAM) for _ in range(n)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def _spawn(cfg: dict[str, Any], run_dir: Path, fds: tuple[int, ...], on_start: Any) -> None:
    """Start the three children; wait; on any failure, stop them all and raise."""
    from seactl.errors import SeactlError

    path = run_dir / "config.json"
    path.write_text(json.dumps(cfg))
    procs: dict[str, subprocess.Popen] = {}
    deadline = time.monotonic() + STARTUP_TIMEOUT_S + cfg["ticks"] / cfg["base_rate_hz"] + 20.0

    def failure(role: str) -> SeactlError:
        rc = procs[role].returncode
        last = f"ended by signal {-rc}" if rc < 0 else f"exit status {rc}, no message"
        err = (procs[role].stderr.read().strip().splitlines() or [last])[-1]
        return SeactlError(f"run: process {role!r} failed ({cfg['transport']}): {err}")

    try:
        for role in ROLES:
            procs[role] = subprocess.Popen([sys.executable, "-m", "seactl.codegen.runtime", role,
                                            str(path)], pass_fds=fds, stdout=subprocess.DEVNULL,
                                           stderr=subprocess.PIPE, text=True)
        if on_start is not None:
            on_start({r: p.pid for r, p in procs.items()})
        while any(p.poll() is None for p in procs.values()):
            bad = [r for r, p in procs.items() if p.poll() not in (None, 0)]
            if bad:
                raise failure(bad[0])
            if time.monotonic() > deadline:
                raise SeactlError("run: the processes did not finish in time")
            time.sleep(0.05)
        bad = [r for r, p in procs.items() if p.returncode != 0]
        if bad:
            raise failure(bad[0])
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


def _stats_ms(lat_s: np.ndarray) -> dict[str, Any]:
    """Summary of a link's latencies, with a histogram (``edges_ms``, ``counts``)."""
    ms = np.asarray(lat_s) * 1e3
    if ms.size == 0:
        return {"count": 0}
    counts, edges = np.histogram(ms, bins=20 if ms.max() > ms.min() else 1)
    return {"count": int(ms.size), "mean_ms": float(ms.mean()),
            "p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max()), "jitter_ms": float(ms.std()),
            "histogram": {"edges_ms": [float(e) for e in edges],
                          "counts": [int(c) for c in counts]}}


def _check_run(duration_s: float, extra_latency_s: float, loss: float, step: float,
               transport: str, seed: int) -> None:
    from seactl.errors import InputError

    for name, v, lo, hi in (("duration_s", duration_s, 0.1, 60.0),
                            ("extra_latency_s", extra_latency_s, 0.0, 1.0),
                            ("loss", loss, 0.0, 0.99), ("step", abs(step), 1e-6, 1.0)):
        if not (math.isfinite(v) and lo <= v <= hi):
            raise InputError(name, v, f"in [{lo:g}, {hi:g}]")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError("seed", seed, "an integer >= 0")
    if transport not in TRANSPORTS:
        raise InputError("transport", transport, " or ".join(TRANSPORTS))
    if transport == "zenoh":
        try:
            import zenoh  # noqa: F401
        except ImportError as exc:
            raise InputError("transport", transport, f"udp (Zenoh is not importable: {exc})"
                             ) from None


def run_distributed(diagram: Any, design: Any, *, saturation: dict[str, float] | None,
                    step: float, duration_s: float = 2.0,
                    rates_hz: dict[str, float] | float = 1000.0, extra_latency_s: float = 0.0,
                    loss: float = 0.0, seed: int = 0, transport: str = "zenoh",
                    plant: str = "builtin", on_start: Any = None,
                    realtime: bool = False) -> RunResult:
    """Run a design's exported controllers as three OS processes on loopback for
    ``duration_s`` and compare with the sampled simulation (module doc).

    ``diagram``/``design``/``saturation``: as for
    :func:`seactl.codegen.controllers.compile_processes`;
    ``step``: the reference step (rad or m); ``plant``: ``"builtin"`` (the exact linear
    plant) or ``"mujoco"`` (:mod:`seactl.codegen.mjcf`, :data:`MUJOCO_TIMESTEP_S`);
    ``on_start(pids)`` is called with the children's process ids once they are started.
    ``realtime``: free-running processes running the exported C
    (:mod:`seactl.codegen.realtime`) instead of the lock-step replay check."""
    from seactl.base.limits import MIN_SAMPLES
    from seactl.codegen.parametric import compile_export
    from seactl.codegen.source import export_files
    from seactl.errors import InputError
    from seactl.simulate.discrete import compile_sampled

    _check_run(duration_s, extra_latency_s, loss, step, transport, seed)
    if plant not in PLANTS:
        raise InputError("plant", plant, " or ".join(PLANTS))
    # lock-step replay of the analysis model: the processes emulate the design's latency;
    # free-running: the code that would be flashed, the latency is the platform's
    ctl, _ = compile_export(diagram, design, rates_hz, saturation,
                            emulate_latency=not realtime)
    if set(ctl.names) != {"embedded", "high-level"}:
        raise InputError("processes", ", ".join(ctl.names), "exactly embedded and high-level "
                         "(seactl run's layout: plant, embedded, high-level)")
    if ctl.base_rate_hz > 5000:
        raise InputError("rates_hz", ctl.base_rate_hz, "<= 5000 Hz for a run (Python processes)")
    Tb = 1.0 / ctl.base_rate_hz
    K = int(round(duration_s / Tb))
    if K < MIN_SAMPLES:
        raise InputError("duration_s", duration_s, f"at least {MIN_SAMPLES} ticks of the "
                         f"fastest process ({MIN_SAMPLES / ctl.base_rate_hz:g} s at "
                         f"{ctl.base_rate_hz:g} Hz)")
    plan = compile_sampled(diagram, design, {}, Tb, (), rates_hz=rates_hz, saturation=saturation)
    with tempfile.TemporaryDirectory(prefix="seactl-run-") as tmp:
        run_dir = Path(tmp)
        (run_dir / "export").mkdir()
        langs = ("python", "c") if realtime else ("python",)
        for name, text in export_files(ctl, langs).items():
            (run_dir / "export" / name).write_text(text)
        np.savez(run_dir / "plant.npz", **_plant_matrices(plan))
        mj = _mujoco_model(design, Tb, run_dir) if plant == "mujoco" else {}
        cfg = {"base_rate_hz": ctl.base_rate_hz, "ticks": K, "step": float(step),
               "period_ticks": {p.name: p.period_ticks for p in ctl.processes},
               "plant_npz": str(run_dir / "plant.npz"), "export_dir": str(run_dir / "export"),
               "run_dir": str(run_dir), "sensed": list(ctl.sensed),
               "references": list(ctl.references), "actuation": list(ctl.actuation),
               "message": _message_at_rest(run_dir / "export", ctl, step),
               "extra_latency_s": float(extra_latency_s), "loss": float(loss),
               "seed": int(seed), "transport": transport, "run_id": run_dir.name[-8:],
               "plant": plant, **mj, "realtime": bool(realtime)}
        if realtime:
            cfg |= _realtime_config(ctl, run_dir / "export", duration_s)
        _start(cfg, run_dir, on_start)
        logs = {r: dict(np.load(run_dir / f"log-{r}.npz")) for r in ROLES}
    injected = {"transport": transport, "extra_latency_ms": extra_latency_s * 1e3,
                "loss": loss}
    if realtime:
        res = analyse_realtime(diagram, design, ctl, logs, step, saturation, rates_hz,
                               injected | {"compiler": cfg["rt_compiler"]})
    else:
        res = analyse_run(diagram, design, ctl, logs, K, step, saturation, rates_hz, injected)
    res.summary["plant"] = plant
    if mj:
        res.summary["plant_timestep_s"] = mj["plant_timestep_s"]
    return res


PLANTS = ("builtin", "mujoco")
"""The plants of a run: seactl's exact linear plant, or MuJoCo (the ``sim`` extra)."""

MUJOCO_TIMESTEP_S = 1e-4
"""MuJoCo's largest integration step in a run [s] (RK4; a whole fraction of the period)."""


def _mujoco_model(design: Any, period_s: float, run_dir: Path) -> dict[str, Any]:
    """Write the MuJoCo plant of ``design`` for the plant process; its config entries."""
    from seactl.codegen.mjcf import plant_model
    from seactl.codegen.mujoco_plant import import_mujoco

    import_mujoco()   # refuse before any process starts when MuJoCo is missing
    h = period_s / max(1, math.ceil(period_s / MUJOCO_TIMESTEP_S - 1e-9))
    path = run_dir / "plant-mujoco.json"
    path.write_text(json.dumps(plant_model(design, h).to_dict()))
    return {"plant_model": str(path), "plant_timestep_s": h}


def _realtime_config(ctl: Any, build: Path, duration_s: float) -> dict[str, Any]:
    """Each controller's C compiled into a shared library in ``build``; each process's
    rate and number of deadlines."""
    from seactl.codegen.cbinding import build_library
    from seactl.codegen.export import find_compiler
    from seactl.errors import ResourceError

    cc = find_compiler()
    if cc is None:
        raise ResourceError("no C compiler found (looked for $CC, cc, gcc, clang): "
                            "run --realtime runs the exported C")
    progs = {p.name: p for p in ctl.programs}
    rates = {p.name: p.rate_hz for p in ctl.processes} | {"plant": ctl.base_rate_hz}
    return {"rt_rates_hz": rates,
            "rt_ticks": {r: int(round(duration_s * f)) for r, f in rates.items()},
            "rt_lib": {n: str(build_library(build, p, cc)) for n, p in progs.items()},
            "rt_ident": {n: p.ident for n, p in progs.items()},
            "rt_inputs": {n: list(p.inputs) for n, p in progs.items()},
            "rt_outputs": {n: list(p.outputs) for n, p in progs.items()},
            "rt_compiler": cc}


def _message_at_rest(export_dir: Path, ctl: Any, step: float) -> dict[str, float]:
    """The high-level's first message with the plant at rest (sensed signals zero), which
    the embedded process holds until a real message arrives."""
    hl = load_controller_class(export_dir / "high_level.py", "HighLevel")
    refs = set(ctl.references)
    out = hl.step({n: float(step) if n in refs else 0.0 for n in hl.INPUTS})
    return {n: float(out[n]) for n in hl.OUTPUTS}


def _start(cfg: dict[str, Any], run_dir: Path, on_start: Any) -> None:
    """Bind the transport's endpoints on 127.0.0.1, start the clock, run the children."""
    socks: list[socket.socket] = []
    try:
        if cfg["transport"] == "udp":
            socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in ROLES]
            for s in socks:
                s.bind(("127.0.0.1", 0))
            cfg["ports"] = {r: s.getsockname()[1] for r, s in zip(ROLES, socks)}
            cfg["fds"] = {r: s.fileno() for r, s in zip(ROLES, socks)}
        else:
            cfg["ports"] = dict(zip(ROLES, _free_tcp_ports(len(ROLES))))
        _spawn(cfg, run_dir, tuple(s.fileno() for s in socks), on_start)
    finally:
        for s in socks:
            s.close()


def analyse_run(diagram: Any, design: Any, ctl: Any, logs: dict[str, dict[str, np.ndarray]],
             K: int, step: float, sat: dict[str, float], rates_hz: Any,
             injected: dict[str, Any]) -> RunResult:
    """Latency per link, tracking error, and the replayed and nominal simulations."""
    from seactl.simulate.engine import simulate
    from seactl.simulate.inputs import Step

    Tb = 1.0 / ctl.base_rate_hz
    hl = ctl.process("high-level")
    # the high-level's delayed blocks carry the link: their source tick is the message's
    # tick less their own buffer
    links = [b.name for b in diagram.blocks if b.process == "high-level" and b.delay]
    used = logs["embedded"]["central_used"]
    scheds = {}
    for b in links:
        n_c = dict(hl.buffers).get(b, 0) * hl.period_ticks
        scheds[b] = np.maximum.accumulate(np.where(used >= 0, np.maximum(used - n_c, -1), -1))
    t_end = K * Tb
    ref = ctl.references[0]
    base = {p: ctl.base_rate_hz for p in ctl.names}
    out = ctl.sensed[0]
    rep = simulate(diagram, design, {ref: Step(step)}, t_end, mode="sampled", outputs=(out,),
                   rates_hz=base, saturation=sat, timing=_Replay(scheds))
    nom = simulate(diagram, design, {ref: Step(step)}, t_end, mode="sampled", outputs=(out,),
                   rates_hz=rates_hz, saturation=sat)
    q = logs["plant"]["q"]
    q_rep, q_nom = np.ravel(rep.outputs[out]), np.ravel(nom.outputs[out])
    lat = {"plant->embedded": logs["embedded"]["sense"],
           "plant->high-level": logs["high-level"]["sense"],
           "high-level->embedded": logs["embedded"]["central"],
           "embedded->plant": logs["plant"]["recv"]}
    lat_s = {k: (v[:, 2] - v[:, 1]) for k, v in lat.items()}
    k = np.arange(K + 1)
    sched = scheds[links[0]] if links else np.where(used >= 0, used, -1)
    age = np.where(sched >= 0, k - sched, np.nan)
    lat_s["stiffness"] = (Tb / 2 + age[np.isfinite(age)] * Tb)
    block_lat = {}
    for b in links:
        age_b = np.where(scheds[b] >= 0, k - scheds[b], np.nan)
        block_lat[b] = Tb / 2 + age_b[np.isfinite(age_b)] * Tb
    act_used = logs["plant"]["act_used"][:K]
    summary = {
        "transport": injected["transport"], "system": diagram.name, "duration_s": K * Tb,
        "ticks": K + 1, "rates_hz": {p.name: p.rate_hz for p in ctl.processes},
        "output": out, "step": float(step),
        "extra_latency_ms": injected["extra_latency_ms"], "loss": injected["loss"],
        "dropped": int(logs["high-level"]["dropped"]),
        "links": {name: _stats_ms(v) for name, v in lat_s.items()},
        "late_commands": int(logs["plant"]["late"]),
        "stale_commands": int(np.sum(act_used != k[:K])),
        "tracking_rms": float(np.sqrt(np.mean((q - step) ** 2))),
        "replay_max_diff": float(np.max(np.abs(q - q_rep)) / abs(step)),
        "nominal_max_diff": float(np.max(np.abs(q - q_nom)) / abs(step)),
        "final_value": float(q[-1] / step),
    }
    return RunResult(k * Tb, q, q_rep, q_nom, lat_s, summary, block_lat)


def analyse_realtime(diagram: Any, design: Any, ctl: Any,
                     logs: dict[str, dict[str, np.ndarray]], step: float, sat: dict[str, float],
                     rates_hz: Any, injected: dict[str, Any]) -> RunResult:
    """A free-running run: its timing statistics, tracking error and the nominal
    simulation (no replay: the timing is not reproducible)."""
    from seactl.codegen.rtstats import LOOP_HOPS, loop_latency_s, realtime_summary
    from seactl.simulate.engine import simulate
    from seactl.simulate.inputs import Step

    Tb = 1.0 / ctl.base_rate_hz
    q = logs["plant"]["q"]
    ok = np.isfinite(q)
    k = np.arange(q.size)
    q = np.interp(k, k[ok], q[ok]) if ok.any() else q   # skipped ticks: interpolated
    out, ref = ctl.sensed[0], ctl.references[0]
    nom = simulate(diagram, design, {ref: Step(step)}, (q.size - 1) * Tb, mode="sampled",
                   outputs=(out,), rates_hz=rates_hz, saturation=sat)
    q_nom = np.ravel(nom.outputs[out])[:q.size]
    rt = realtime_summary(logs)
    lat_s = {link: logs[role][link_key(link) + "use_s"]
             for link, role in LINK_ROLES.items()}
    summary = {
        "mode": "realtime", "transport": injected["transport"], "system": diagram.name,
        "duration_s": q.size * Tb, "ticks": int(q.size),
        "rates_hz": {p.name: p.rate_hz for p in ctl.processes}, "output": out,
        "step": float(step), "extra_latency_ms": injected["extra_latency_ms"],
        "loss": injected["loss"], "controller": "exported C", "compiler": injected["compiler"],
        **rt,
        "tracking_rms": float(np.sqrt(np.mean((q - step) ** 2))),
        "replay_max_diff": None,
        "nominal_max_diff": float(np.max(np.abs(q - q_nom)) / abs(step)),
        "final_value": float(q[-1] / step),
    }
    block_lat = {b.name: loop_latency_s(lat_s, b.process) for b in diagram.blocks
                 if b.delay and b.process in LOOP_HOPS}
    return RunResult(k * Tb, q, np.full(q.size, np.nan), q_nom, lat_s, summary, block_lat)


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


def _fine_timer() -> None:
    """Linux: sleeps end within microseconds instead of the default 50 us timer slack
    (the processes poll and sleep between messages)."""
    try:
        import ctypes

        ctypes.CDLL(None).prctl(29, 1000, 0, 0, 0)   # PR_SET_TIMERSLACK, 1 us
    except (OSError, AttributeError):  # not Linux: the default slack
        pass


def worker_main(role: str, config: str) -> int:
    _fine_timer()
    cfg = json.loads(Path(config).read_text())
    run = {"plant": run_plant, "embedded": run_embedded, "high-level": run_high_level}[role]
    if cfg.get("realtime"):   # loaded (the controller's library) before the clock starts
        job = prepare_rt(cfg, role)
        run = lambda cfg, link: job(link)  # noqa: E731
    try:
        link = (UdpLink if cfg["transport"] == "udp" else ZenohLink)(cfg, role)
    except Exception as exc:  # e.g. a Zenoh endpoint taken meanwhile
        print(f"error: cannot open the {cfg['transport']} link: {exc}", file=sys.stderr)
        return 3
    try:
        handshake(cfg, role, link)
        logs = run(cfg, link)
    except LostPeer as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 3
    finally:
        link.close()
    np.savez(Path(cfg["run_dir"]) / f"log-{role}.npz", **logs)
    return 0


if __name__ == "__main__":
    sys.exit(worker_main(sys.argv[1], sys.argv[2]))
