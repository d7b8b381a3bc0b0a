"""What the explorer shows for a robot (``seactl explore --robot URDF``), as pure functions
of its controls (no Bokeh).

The robot is :func:`seactl.robot` at the controls' configuration ``q``; every view is a
call of the :class:`seactl.Robot` API, as ``seactl robot`` computes it: the certified
verdict and the margins of every loop break (``margins()``, ``margins_by_break()``), the
principal values of the joint-space impedance matrix (the singular values of
``impedance_matrix(f)``, and the smallest eigenvalue of its Hermitian part for passivity
on the scan), the step response of joint 1 (``step()``) and, on request, a workspace map
over two joints around ``q`` (:func:`seactl.workspace_map`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

import seactl as sc
from seactl.apps.commands.robot import actuator_spec
from seactl.errors import InfeasibleDesignError, InputError, SeactlError

from .model import num_text, run_stages, safe

ROBOT_BOUNDS: dict[str, tuple[float, float, float]] = {
    "fn_hz": (5.0, 50.0, 0.1),
    "t_tau_ms": (0.0, 20.0, 0.1),
    "t_qs_ms": (0.0, 20.0, 0.1),
    "t_qd_ms": (0.0, 20.0, 0.1),
}
"""Slider ranges ``(start, end, step)`` (the library validates every value again)."""
Q_STEP_RAD = 0.01
"""A joint slider's step [rad]; it spans the joint's URDF limits (-pi to pi without)."""
F_Z_HZ = np.geomspace(0.1, 1000.0, 150)
"""Frequencies of the impedance view [Hz]."""
STEP_T_END_S = 1.0
MAP_SPAN_RAD = 0.5
MAP_POINTS = (3, 5, 7)
"""A workspace map spans ``q +- MAP_SPAN_RAD`` on each of its two joints, with one of
these numbers of points per joint (the page's choice; the first is the default)."""
SPACES = ("joint", "task")
MAX_URDF_BYTES = 256 * 1024
BREAK_COLUMNS = ("phase_margin_deg", "crossover_hz", "gain_margin_db", "delay_margin_ms")


@dataclass(frozen=True)
class RobotControls:
    """The value of every control of the robot page (CLI units: rad, ms, Hz).

    ``actuators`` is the ``--actuators`` text of ``seactl robot`` (a preset or TOML file
    for every joint, or ``JOINT=PRESET|FILE,...``); ``task`` is used in task space;
    ``file_name`` is how the command lines name an uploaded URDF (default: ``urdf``).
    """

    urdf: str
    q_rad: tuple[float, ...]
    fn_hz: float = 14.0
    gs: float = 1.0
    t_tau_ms: float = 0.5
    t_qs_ms: float = 2.0
    t_qd_ms: float = 0.5
    f_qd_hz: float | None = 50.0
    f_taud_hz: float | None = 100.0
    space: str = "joint"
    task: str | None = None
    actuators: str = "ut-sea"
    file_name: str | None = None

    def options(self) -> dict[str, Any]:
        """The keywords of :func:`seactl.robot` (and :func:`seactl.workspace_map`) but
        ``q0``."""
        return {"actuators": actuator_spec(self.actuators), "space": self.space,
                "task": self.task if self.space == "task" else None, "fn_hz": self.fn_hz,
                "gs": self.gs, "delays_ms": {"torque": self.t_tau_ms,
                                             "stiffness": self.t_qs_ms,
                                             "damping": self.t_qd_ms},
                "filters_hz": (self.f_qd_hz, self.f_taud_hz)}

    def system(self) -> Any:
        """The robot these controls describe (:func:`seactl.robot` validates them)."""
        return sc.robot(self.urdf, q0=list(self.q_rad), **self.options())


def q_from_text(text: str | None) -> list[float] | None:
    """``--q0``: comma-separated joint angles [rad] (None: the robot's default)."""
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError("--q0 [rad]", text, "comma-separated joint angles, e.g. 0.3,0.8"
                         ) from None


# ------------------------------------------------------------------ the URDF's layout
@dataclass(frozen=True)
class RobotInfo:
    """What the page's controls need from the URDF: joint names (the model's order),
    their slider ranges [rad] and the links (the task frame choices, the leaves last)."""

    joints: tuple[str, ...]
    limits_rad: tuple[tuple[float, float], ...]
    links: tuple[str, ...]


def robot_info(urdf: str, joints: tuple[str, ...]) -> RobotInfo:
    """The joints' ``<limit lower upper>`` (-pi to pi where the file has none) and the
    links of a URDF that :func:`seactl.robot` has loaded (``joints``: its joint order)."""
    root = ElementTree.parse(urdf).getroot()
    found = {}
    for j in root.iter("joint"):
        lim = j.find("limit")
        lo = float(lim.get("lower", -math.pi)) if lim is not None else -math.pi
        hi = float(lim.get("upper", math.pi)) if lim is not None else math.pi
        found[j.get("name")] = (lo, hi) if hi > lo else (-math.pi, math.pi)
    parents = {p.get("link") for j in root.iter("joint") for p in j.iter("parent")}
    links = [str(k.get("name")) for k in root.iter("link") if k.get("name")]
    leaves = [k for k in links if k not in parents]   # the default task frame: the last
    links = [k for k in links if k not in leaves] + leaves
    return RobotInfo(tuple(joints), tuple(found.get(j, (-math.pi, math.pi)) for j in joints),
                     tuple(links))


def start_controls(urdf: str, *, actuators: str = "ut-sea", space: str = "joint",
                   task: str | None = None, q_rad: Any = None
                   ) -> tuple[RobotControls, RobotInfo]:
    """The page's first controls and the URDF's layout, checked by building the robot:
    a bad file, frame, actuator or ``q`` raises the library's error.  The page starts at
    f_n = 14 Hz, or, where a joint has no feasible gains there at ``q``, at the lowest f_n
    (on the slider's 0.1 Hz grid, up to 50 Hz) where every joint has.

    Raises
    ------
    InputError
        From :func:`seactl.robot` (the message names the field), or no feasible design
        up to 50 Hz.
    """
    if not Path(urdf).is_file():
        raise InputError("--robot", urdf, "an existing URDF file")
    if space == "task" and task is None:
        try:  # a file the library refuses: its error, before the XML is read here
            sc.robot(urdf, actuators=actuator_spec(actuators), q0=q_rad)
        except InfeasibleDesignError:
            pass
        task = robot_info(urdf, ()).links[-1]
    fn_hz, r = RobotControls.fn_hz, None
    while r is None and fn_hz <= ROBOT_BOUNDS["fn_hz"][1]:
        try:
            r = sc.robot(urdf, actuators=actuator_spec(actuators), space=space, task=task,
                         q0=q_rad, fn_hz=fn_hz)
        except InfeasibleDesignError as exc:
            above = [lo for lo, hi in exc.feasible_hz or () if hi > fn_hz]
            fn_hz = math.ceil(max(min(above, default=math.inf), fn_hz) * 10 + 1e-6) / 10
    if r is None:
        raise InputError("--robot", urdf, "a robot with a feasible design for f_n "
                         f"<= {ROBOT_BOUNDS['fn_hz'][1]:g} Hz at this q")
    info = robot_info(urdf, r.body.joints)
    q = tuple(float(x) for x in r.body.q0)
    if task is None:
        task = info.links[-1] if info.links else None
    return RobotControls(str(urdf), q, fn_hz=fn_hz, space=space, task=task,
                         actuators=actuators), info


def robot_from_upload(filename: str, content: bytes, directory: str
                      ) -> tuple[RobotControls, RobotInfo]:
    """An uploaded URDF, written into ``directory`` (it must stay there while the page
    uses it: the robot is built from the file at every change) and checked by
    :func:`start_controls`.

    Raises
    ------
    SeactlError
        Too large, or the library's message (naming the uploaded file).
    """
    stem = "".join(ch if ch.isalnum() or ch in "-_." else "_"
                   for ch in Path(str(filename or "robot.urdf")).stem)
    name = f"{stem or 'robot'}.urdf"
    if len(content) > MAX_URDF_BYTES:
        raise InputError("robot file", name, f"at most {MAX_URDF_BYTES // 1024} kB")
    path = Path(directory) / name
    path.write_bytes(content)
    try:
        c, info = start_controls(str(path))
    except SeactlError as exc:
        raise SeactlError(str(exc).replace(str(path), name)) from None
    return replace(c, file_name=name), info


# ------------------------------------------------------------------ views
def _one(x: Any) -> float | None:
    v = float(np.reshape(x, -1)[0])
    return v if math.isfinite(v) else None


def breaks_table(r: Any) -> list[dict[str, Any]]:
    """One row per loop break (``r.margins_by_break()``), the rows ``seactl robot
    --json`` prints under ``breaks``."""
    return [{"break": name, **{k: _one(getattr(m, k)) for k in BREAK_COLUMNS},
             "stable": bool(np.reshape(m.stable, -1)[0])}
            for name, m in r.margins_by_break().items()]


def impedance_views(r: Any, f_hz: np.ndarray = F_Z_HZ) -> dict[str, Any]:
    """The principal values (singular values, largest first) of the joint-space impedance
    matrix ``r.impedance_matrix(f)`` [N m s/rad], and the smallest eigenvalue of its
    Hermitian part: ``passive`` is False where it is negative at a point of the scan
    (proven), True where it is not negative at any (the scan's, not a proof)."""
    z = r.impedance_matrix(f_hz)
    sv = np.linalg.svd(z, compute_uv=False)               # (f, n), descending
    herm = np.linalg.eigvalsh(0.5 * (z + np.conj(np.swapaxes(z, 1, 2))))[:, 0]
    neg = herm < -1e-9 * sv[:, 0]
    return {"principal": {"xs": [f_hz] * sv.shape[1], "ys": list(sv.T),
                          "label": [f"sigma_{i + 1}" for i in range(sv.shape[1])]},
            "hermitian_min": herm, "passive": not bool(neg.any())}


def step_views(r: Any) -> dict[str, Any]:
    """The step response of joint 1 (``r.step()``: ``q_des.j1`` to ``q_j.j1``,
    normalized by the step) over :data:`STEP_T_END_S` and its metrics."""
    st = r.step(t_end_s=STEP_T_END_S)
    m = st.metrics
    return {"step": {"t_ms": st.t_s * 1e3, "y": np.reshape(st.position, -1)},
            "step_amplitude": st.amplitude,
            "step_overshoot_pct": _one(m.overshoot_pct),
            "step_settling_ms": None if _one(m.settling_time_s) is None
            else 1e3 * float(np.reshape(m.settling_time_s, -1)[0])}


def command_line(c: RobotControls, workspace: str | None = None) -> str:
    """The ``seactl robot`` command that prints the same verdict and margins (with
    ``workspace``: ``--workspace`` over that grid instead of ``--q0``)."""
    def num(x: float) -> str:
        return f"{x:.10g}"

    opts = [f"--urdf {c.file_name or c.urdf}", f"--actuators {c.actuators}",
            f"--space {c.space}"]
    if c.space == "task" and c.task:
        opts.append(f"--task {c.task}")
    if workspace is None:
        opts.append(f"--q0 {','.join(num(q) for q in c.q_rad)}")
    opts += [f"--fn {num(c.fn_hz)}", f"--gs {num(c.gs)}", f"--t-tau {num(c.t_tau_ms)}",
             f"--t-qs {num(c.t_qs_ms)}", f"--t-qd {num(c.t_qd_ms)}"]
    opts += [f"--{k} {num(v)}" for k, v in (("f-qd", c.f_qd_hz), ("f-taud", c.f_taud_hz))
             if v is not None]
    if workspace is not None:
        opts.append(f"--workspace {workspace}")
    return "seactl robot " + " ".join(opts)


def fast_views(c: RobotControls, acc: dict[str, Any] | None = None) -> dict[str, Any]:
    """Stage 1: the certified verdict (``r.margins()``), the impedance's principal values
    and the step of joint 1.

    Raises
    ------
    SeactlError
        A value the library refuses, or no feasible design at f_n (the message names the
        joint).
    """
    r = c.system()
    m = r.margins()
    out = {"robot": r, **impedance_views(r), **step_views(r)}
    results = {"kind": "robot", "stable": bool(np.reshape(m.stable, -1)[0]),
               "phase_margin_deg": _one(m.phase_margin_deg),
               "crossover_hz": _one(m.crossover_hz),
               "delay_margin_ms": _one(m.delay_margin_ms), "passive": out["passive"],
               **{k: out[k] for k in ("step_amplitude", "step_overshoot_pct",
                                      "step_settling_ms")}}
    results["verdict"] = verdict(results)
    out["results"] = results
    out["command"] = command_line(c)
    return out


def breaks_stage(c: RobotControls, acc: dict[str, Any]) -> dict[str, Any]:
    """Stage 2: the margins of every loop break."""
    rows = breaks_table(acc["robot"])
    results = {**acc["results"], "breaks": rows}
    results["verdict"] = verdict(results)
    return {"breaks": rows, "results": results}


STAGES = (fast_views, breaks_stage)
STAGE_NAMES = ("verdict, impedance and step", "margins per break")


def views(c: RobotControls) -> dict[str, Any]:
    """Everything the robot page shows for ``c`` (the map aside): the stages, merged."""
    return run_stages(STAGES, c)


def safe_views(c: RobotControls) -> tuple[dict[str, Any] | None, str | None]:
    """:func:`views`, or ``(None, message)`` for input the library refuses."""
    return safe(views, c)


# ------------------------------------------------------------------ workspace map
def map_grid(c: RobotControls, across: int, up: int | None, points: int) -> np.ndarray:
    """The map's configurations: joint ``across`` (and ``up``) over ``q +- MAP_SPAN_RAD``
    with ``points`` angles each, the other joints at ``q``; rows in the order of
    ``seactl robot --workspace`` (the first joint varies slowest)."""
    axes = []
    for j, q in enumerate(c.q_rad):
        moved = j == across or j == up
        axes.append(np.linspace(q - MAP_SPAN_RAD, q + MAP_SPAN_RAD, points) if moved
                    else np.array([q]))
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes))


def workspace_command(c: RobotControls, across: int, up: int | None, points: int) -> str:
    """``seactl robot --workspace`` over the same grid."""
    parts = []
    for j, q in enumerate(c.q_rad):
        if j == across or j == up:
            parts.append(f"{q - MAP_SPAN_RAD:.10g}:{q + MAP_SPAN_RAD:.10g}:{points}")
        else:
            parts.append(f"{q:.10g}:{q:.10g}:1")
    return command_line(c, ",".join(parts))


def map_views(c: RobotControls, across: int, up: int | None, points: int
              ) -> dict[str, Any]:
    """The workspace map (:func:`seactl.workspace_map`) over two joints around ``q``:
    phase margin at ``outer.j1`` per cell (NaN where unstable: drawn grey), delay margin
    and, in task space, the largest task stiffness."""
    if points not in MAP_POINTS:
        raise InputError("map points", points, "one of " + ", ".join(map(str, MAP_POINTS)))
    grid = map_grid(c, across, up, points)
    m = sc.workspace_map(c.urdf, grid, **c.options())
    x = grid[:, across]
    y = grid[:, up] if up is not None else np.zeros(len(grid))
    hx = MAP_SPAN_RAD / (points - 1)
    hy = hx if up is not None else 0.5
    return {"cells": {"left": x - hx, "right": x + hx, "bottom": y - hy, "top": y + hy,
                      "x": x, "y": y, "pm": np.where(m.stable, m.phase_margin_deg, np.nan),
                      "stable": m.stable.astype(int), "dm": m.delay_margin_ms,
                      "kx": m.max_task_stiffness_n_per_m},
            "marker": {"x": [c.q_rad[across]], "y": [c.q_rad[up] if up is not None else 0.0]},
            "map": m, "worst_q_rad": grid[m.worst].tolist(),
            "command": workspace_command(c, across, up, points)}


# ------------------------------------------------------------------ words and badge
def verdict(r: dict[str, Any]) -> str:
    """The results in words."""
    if r["stable"]:
        words = [f"Certified stable: phase margin {num_text(r['phase_margin_deg'], '.1f')} deg "
                 f"at {num_text(r['crossover_hz'], '.3g')} Hz at outer.j1, delay margin "
                 f"{num_text(r['delay_margin_ms'], '.3g')} ms."]
    else:
        words = ["Certified UNSTABLE: lower f_n, shorten the delays or move q."]
    rows = r.get("breaks")
    if rows:
        finite = [b for b in rows if b["delay_margin_ms"] is not None]
        if finite:
            worst = min(finite, key=lambda b: b["delay_margin_ms"])
            words.append(f"The smallest delay margin is at break {worst['break']} "
                         f"({worst['delay_margin_ms']:.3g} ms).")
    words.append("Z(jw) (joint space): " + (
        "the Hermitian part (Z + Z^H)/2 has no negative eigenvalue at any point of the scan "
        "from 0.1 Hz to 1 kHz (a scan, not a proof)." if r["passive"]
        else "not passive (the Hermitian part has a negative eigenvalue)."))
    if r.get("step_overshoot_pct") is not None:
        words.append(f"Step of {r['step_amplitude']:g} rad on joint 1: "
                     f"{r['step_overshoot_pct']:.1f} % overshoot, settles (2 %) in "
                     f"{num_text(r['step_settling_ms'], '.0f', ' ms')}.")
    return " ".join(words)


def badges(r: dict[str, Any]) -> list[tuple[str, str, str]]:
    """``(id, text, colour key)``: the certified verdict of the robot's loop and the
    impedance scan's."""
    stable = ("badge-stability", "stable (certified)" if r["stable"]
              else "unstable (certified)", "good" if r["stable"] else "bad")
    passive = ("badge-passivity", "passive (scanned)" if r["passive"] else "not passive",
               "good" if r["passive"] else "warn")
    return [stable, passive]
