"""``seactl run``: the exported controllers as three OS processes on loopback (Zenoh, UDP).

Oracles: the sampled simulation replaying the measured stiffness-link schedule (the same
model the export is verified against; it must reproduce the measured response to
rounding when every drive command arrived in time), message counts known from the rate and
duration, the operating system's process table (nothing left running), and
:class:`seactl.latency.models.Empirical` reading the latency trace back.
"""

from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.codegen import runtime
from seactl.latency.models import Empirical

FLAGS = ["--fn", "14", "--t-tau", "1", "--t-qs", "2", "--t-qd", "1", "--f-qd", "50",
         "--f-taud", "100"]


def _children() -> list[int]:
    """Live (non-zombie) processes whose parent is this test process."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(stat[1]) == os.getpid() and stat[0] != "Z":
                out.append(int(d.name))
    return out


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to list processes")
@pytest.mark.parametrize("transport", ["zenoh", "udp"])
def test_run_end_to_end(tmp_path, capsys, transport):
    before = set(_children())
    out = tmp_path / "run"
    t0 = time.monotonic()
    code = main(["run", *FLAGS, "--duration", "1", "--rate", "embedded=2000", "--rate",
                 "high-level=500", "--out", str(out), "--json", "--transport", transport])
    wall = time.monotonic() - t0
    assert code == 0
    s = json.loads(capsys.readouterr().out)
    assert s["transport"] == transport
    assert set(_children()) <= before                  # every child has exited
    assert wall < 30
    links = s["links"]
    # 2001 samples at 2 kHz to each controller process; 501 high-level messages at 500 Hz
    # (the last ones may arrive after the embedded process has stopped: one on an idle
    # machine, two seen with another job on the second core; what arrived in time is what
    # the replay below uses, message by message)
    assert links["plant->embedded"]["count"] == 2001
    assert links["plant->high-level"]["count"] == 2001
    assert 495 <= links["high-level->embedded"]["count"] <= 501
    assert links["embedded->plant"]["count"] >= 2000
    assert s["dropped"] == 0 and s["final_value"] == pytest.approx(1.0, abs=0.02)
    # stated band: the replay reproduces the measured response to rounding (the plant
    # waits for late commands instead of applying stale ones)
    assert s["stale_commands"] == 0
    assert s["replay_max_diff"] <= 1e-9, s
    names = {p.name for p in out.iterdir()}
    assert {"summary.json", "response.csv", "latency-stiffness.csv", ".seactl-run"} <= names
    emp = Empirical.from_csv(out / "latency-stiffness.csv")
    assert emp.mean_s * 1e3 == pytest.approx(links["stiffness"]["mean_ms"], rel=1e-9)
    resp = np.loadtxt(out / "response.csv", delimiter=",", skiprows=1)
    assert resp.shape == (2001, 4)


def test_lost_peer_ends_the_worker(monkeypatch, tmp_path):
    """A controller process that hears nothing ends with a clear error (exit 3)."""
    from seactl.codegen import processes, transports

    monkeypatch.setattr(transports, "PEER_TIMEOUT_S", 0.2)
    monkeypatch.setattr(processes, "PEER_TIMEOUT_S", 0.2)
    d = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1}, filters_hz=(50, 100))
    (tmp_path / "export").mkdir()
    d.export(tmp_path / "export", lang="python")
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    cfg = {"export_dir": str(tmp_path / "export"), "ports": {"plant": 9}, "ticks": 10,
           "period_ticks": {"embedded": 1}, "step": 0.01, "t0": time.monotonic(),
           "fds": {"embedded": sock.fileno()}, "message": {"tau_fb_from_high_level": 0.0}}
    link = runtime.UdpLink(cfg, "embedded")
    with pytest.raises(runtime.LostPeer, match="peer"):
        runtime.run_embedded(cfg, link)
    link.close()


def _sockets(pid: int) -> list[tuple[str, str, str]]:
    """(protocol, local address, state) of the sockets process ``pid`` holds, from /proc."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    for proto in ("tcp", "tcp6", "udp", "udp6"):
        for line in Path(f"/proc/{pid}/net/{proto}").read_text().splitlines()[1:]:
            f = line.split()
            if f[9] in inodes:
                found.append((proto, f[1], f[3]))
    return found


def _is_loopback(addr: str) -> bool:
    ip = addr.split(":")[0]
    if len(ip) == 8:                                   # IPv4, little-endian hex
        return ip == "0100007F"
    return ip in ("00000000000000000000000001000000",)  # ::1


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to read sockets")
@pytest.mark.parametrize("transport", ["zenoh", "udp"])
def test_rigid_run_listens_on_loopback_only(transport):
    """The rigid actuator's run from the Python API; while it runs, every socket the three
    processes hold (TCP listening or connected, UDP bound) is on 127.0.0.1 (oracle: the
    kernel's socket tables in /proc); the replay reproduces the measured response."""
    import threading

    seen: list[tuple[str, str, str]] = []

    def watch(pids):
        def poll():
            end = time.monotonic() + 3.5
            while time.monotonic() < end:
                for pid in pids.values():
                    try:
                        seen.extend(_sockets(pid))
                    except OSError:
                        pass
                time.sleep(0.2)
        threading.Thread(target=poll, daemon=True).start()

    from seactl.systems.rigid.model import RIGID_DIAGRAM

    rig = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).rigid
    res = runtime.run_distributed(RIGID_DIAGRAM, rig, saturation={"F_des": rig.actuator.max_force},
                                  step=0.004, duration_s=1.0, transport=transport,
                                  on_start=watch)
    s = res.summary
    assert s["system"] == "rigid" and s["output"] == "x"
    assert s["links"]["high-level->embedded"]["count"] >= 990
    assert s["replay_max_diff"] <= 1e-9 and s["final_value"] == pytest.approx(1.0, abs=0.02)
    assert seen, "no socket seen"
    listening = [x for x in seen if x[0].startswith("udp") or x[2] == "0A"]
    assert listening and all(_is_loopback(a) for _, a, _ in seen), sorted(set(seen))


def test_python_api_runs_both_systems():
    """Design.run and RigidBatch.run (public API): message counts known from the rate and
    the duration; the replay reproduces the measured response."""
    sea = sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
                    filters_hz=(50, 100)).run(duration_s=0.3, transport="udp")
    rig = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).run(duration_s=0.3,
                                                                        transport="udp")
    for res, out in ((sea, "q_j"), (rig, "x")):
        s = res.summary
        assert s["output"] == out and s["links"]["plant->embedded"]["count"] == 301
        assert s["replay_max_diff"] <= 1e-9
        hist = s["links"]["plant->embedded"]["histogram"]
        assert sum(hist["counts"]) == 301 and len(hist["edges_ms"]) == len(hist["counts"]) + 1


@pytest.mark.parametrize("args, needle", [
    (["--duration", "100"], "--duration"),
    (["--loss", "1.5"], "--loss"),
    (["--rate", "20000"], "5000"),
    (["--transport", "bogus"], "transport"),
    (["--system", "rigid", "--step", "2"], "--step"),
])
def test_run_bad_input(args, needle, capsys):
    assert main(["run", *FLAGS, *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err


def test_injected_latency_and_loss_are_measured_and_replayed(capsys):
    """3 ms injected on the high-level -> embedded link: its measured median is >= 3 ms;
    lost messages are counted; the replay still reproduces the response (it is driven by
    the messages that did arrive)."""
    code = main(["run", *FLAGS, "--duration", "0.5", "--extra-latency", "3", "--loss", "0.3",
                 "--seed", "4", "--json"])
    assert code == 0
    s = json.loads(capsys.readouterr().out)
    link = s["links"]["high-level->embedded"]
    assert link["p50_ms"] >= 3.0
    # 501 messages at 1 kHz over 0.5 s; those still delayed when the run stops are not sent
    assert 0 < s["dropped"] < 501 and 490 <= link["count"] + s["dropped"] <= 501
    assert s["replay_max_diff"] <= 1e-9 and s["nominal_max_diff"] > 1e-3


def test_loop_file_runs_and_three_process_loop_is_refused(capsys):
    """A loop file (examples/loops/paper-sea.toml) runs like the built-in SEA: message
    counts known from the file's 1 kHz processes, replay to rounding; a file with a third
    process (sea-velocity.toml: a 10 kHz drive) is refused with a one-line error."""
    root = Path(__file__).resolve().parents[1] / "examples" / "loops"
    code = main(["run", "--loop", str(root / "paper-sea.toml"), "--duration", "0.3",
                 "--transport", "udp", "--json"])
    assert code == 0
    s = json.loads(capsys.readouterr().out)
    assert s["links"]["plant->embedded"]["count"] == 301 and s["replay_max_diff"] <= 1e-9
    assert main(["run", "--loop", str(root / "sea-velocity.toml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "processes" in err and err.count("\n") == 1
