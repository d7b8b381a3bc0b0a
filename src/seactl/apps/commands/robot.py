"""``seactl robot``: a multi-joint SEA robot from its URDF, linearized at a configuration."""

from __future__ import annotations

from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from seactl.base.axes import AXES
from seactl.errors import InputError

from .common import axis_option, cli, console, echo_json, finite_or_none, json_option, pm_text

ROBOT_AXES = ("fn_hz", "gs", "t_tau_ms", "t_qs_ms", "t_qd_ms", "f_qd_hz", "f_taud_hz")


def _q0(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError("--q0 [rad]", text, "comma-separated joint angles, e.g. 0.3,0.8"
                         ) from None


def workspace_grid(text: str) -> list[list[float]]:
    """``A:B:N,C:D:M,...`` (per joint, N angles from A to B [rad]) -> the grid's rows."""
    import numpy as np

    try:
        axes = []
        for part in text.split(","):
            a, b, n = part.split(":")
            axes.append(np.linspace(float(a), float(b), int(n)))
        ok = all(len(x) >= 1 and np.all(np.isfinite(x)) for x in axes)
    except ValueError:
        ok = False
    if not ok or np.prod([len(x) for x in axes]) > 10000:
        raise InputError("--workspace [rad]", text, "per joint its first angle, last angle "
                         "and count (>= 1) joined by colons, joints comma-separated, at "
                         "most 10000 configurations, e.g. 0:0.6:3,0.8:2.2:3")
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes)).tolist()


def _actuators(text: str) -> Any:
    """``PRESET|FILE`` for every joint, or ``joint=PRESET|FILE,...``."""
    if "=" not in text:
        return text
    out = {}
    for part in text.split(","):
        joint, _, spec = part.partition("=")
        if not joint or not spec:
            raise InputError("--actuators", text, "PRESET, FILE, or JOINT=PRESET|FILE,...")
        out[joint.strip()] = spec.strip()
    return out


def robot_record(r: Any, margins: dict[str, Any], roots: Any) -> dict[str, Any]:
    """The JSON of ``seactl robot``: the model, the per-break margins, the verdict."""
    breaks = {}
    for name, m in margins.items():
        breaks[name] = {"phase_margin_deg": finite_or_none(m.phase_margin_deg),
                        "crossover_hz": finite_or_none(m.crossover_hz),
                        "gain_margin_db": finite_or_none(m.gain_margin_db),
                        "delay_margin_ms": finite_or_none(m.delay_margin_ms),
                        "stable": bool(m.stable)}
    kx = r.task_stiffness
    return {"joints": list(r.body.joints), "q0_rad": r.body.q0.tolist(), "space": r.space,
            "task": r.body.frame, "fn_hz": r.fn_hz, "gs": r.gs,
            "delays_ms": {k: 1e3 * v for k, v in r.delays.items()},
            "design_inertia_kg_m2": [a.Ij for a in r.actuators],
            "task_stiffness_n_per_m": None if kx is None else kx[0],
            "task_rotational_stiffness_nm_per_rad": None if kx is None else kx[1],
            "stiffness_nm_per_rad": r.stiffness.tolist(),
            "stable": bool(next(iter(margins.values())).stable),
            "spectral_abscissa_per_s": finite_or_none(roots.spectral_abscissa),
            "roots_complete": not bool(roots.uncertain),
            "breaks": breaks}


@cli.command()
@click.option("--urdf", required=True, help="URDF file of the robot (revolute joints).")
@click.option("--actuators", default="ut-sea", show_default=True,
              help="SEA preset or TOML file for every joint, or JOINT=PRESET|FILE,...")
@click.option("--space", type=click.Choice(["joint", "task"]), default="joint",
              show_default=True, help="Stiffness in joint space or in task space.")
@click.option("--task", default=None, help="Task frame (a frame of the URDF; task space).")
@click.option("--q0", default=None, help="Configuration [rad], comma-separated (default 0).")
@axis_option("fn_hz")
@axis_option("gs")
@axis_option("t_tau_ms")
@axis_option("t_qs_ms")
@axis_option("t_qd_ms")
@axis_option("f_qd_hz")
@axis_option("f_taud_hz")
@click.option("--workspace", default=None,
              help="Map a grid of configurations instead of one q0: A:B:N per joint [rad], "
                   "comma-separated (Python: sc.workspace_map).")
@click.option("--mujoco-check", is_flag=True,
              help="Also run the robot in MuJoCo at 0.8x and 1.2x of the central delay "
                   "margin and compare with the certified verdicts (needs mujoco).")
@click.option("--impedance", default=None,
              help="Frequencies [Hz], comma-separated: the task impedance's principal "
                   "values (joint space without --task) and the certified passivity.")
@click.option("--task-step", default=None,
              help="Direction X,Y,Z of a 1 mm step of the task reference (needs --task).")
@click.option("--task-impulse", default=None,
              help="Direction X,Y,Z of a 0.01 N s force impulse at the task frame.")
@json_option
def robot(urdf: str, actuators: str, space: str, task: str | None, q0: str | None,
          workspace: str | None, mujoco_check: bool, as_json: bool,
          impedance: str | None = None, task_step: str | None = None,
          task_impulse: str | None = None, **axes: Any) -> None:
    """Margins of every loop break, certified verdict and spectral abscissa of a robot.

    Python: sc.robot(urdf, actuators=..., space=..., task=..., q0=...).

    \b
    Example:
      seactl robot --urdf examples/robots/planar_2link.urdf --q0 0.3,0.8 --fn 14 \\
          --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100

    The rigid body is linearized at q0 with gravity compensated; each joint's SEA is
    designed for its apparent inertia 1/(M^-1)_jj; the stiffness runs on the central
    process (delay --t-qs), damping and torque loops on each joint's embedded process.
    Breaks: outer.jN (the SEA's outer loop), stiffness.jN, damping.jN, torque.jN.
    --mujoco-check: Python r.mujoco_check() (docs/robots.md, "In MuJoCo").
    --workspace: one row per configuration of the grid (verdict, phase margin, delay
    margin, and in task space the largest task stiffness k_x [N/m]).
    --impedance, --task-step, --task-impulse: Python r.task_impedance(f_hz),
    r.passivity(), r.task_step(direction), r.task_impulse(direction) (docs/robots.md).
    """
    import seactl as sc

    v = {n: None if axes[n] is None else float(AXES[n].check(axes[n], AXES[n].option))
         for n in ROBOT_AXES}
    opts = dict(actuators=_actuators(actuators), space=space, task=task,
                fn_hz=v["fn_hz"], gs=v["gs"],
                delays_ms={"torque": v["t_tau_ms"], "stiffness": v["t_qs_ms"],
                           "damping": v["t_qd_ms"]},
                filters_hz=(v["f_qd_hz"], v["f_taud_hz"]))
    if impedance is not None or task_step is not None or task_impulse is not None:
        from .robotimpedance import task_views

        if workspace is not None or mujoco_check:
            raise InputError("--impedance/--task-step/--task-impulse", "with "
                             + ("--workspace" if workspace is not None else "--mujoco-check"),
                             "given without --workspace and --mujoco-check")
        task_views(sc.robot(urdf, q0=_q0(q0), **opts), impedance, task_step, task_impulse,
                   as_json)
        return
    if workspace is not None:
        _workspace(urdf, workspace, q0, mujoco_check, as_json, opts)
        return
    r = sc.robot(urdf, q0=_q0(q0), **opts)
    rec = robot_record(r, r.margins_by_break(), r.roots(count=4))
    if mujoco_check:
        rec["mujoco_check"] = r.mujoco_check().records()
    if as_json:
        echo_json(rec)
        return
    _print(rec)
    if mujoco_check:
        _print_check(rec["mujoco_check"])


def _print(rec: dict[str, Any]) -> None:
    t = Table(title=f"{len(rec['joints'])}-joint robot, {rec['space']} space, "
                    f"f_n={rec['fn_hz']:g} Hz, q0={rec['q0_rad']} rad")
    for col in ("break", "PM [deg]", "crossover [Hz]", "GM [dB]", "delay margin [ms]"):
        t.add_column(escape(col))
    for name, b in rec["breaks"].items():
        t.add_row(name, pm_text(b["phase_margin_deg"], b["stable"]),
                  *("none" if b[k] is None else f"{b[k]:.4g}"
                    for k in ("crossover_hz", "gain_margin_db", "delay_margin_ms")))
    console.print(t)
    verdict = "stable" if rec["stable"] else "[red]UNSTABLE[/red]"
    sa = rec["spectral_abscissa_per_s"]
    console.print(f"certified verdict: {verdict}; spectral abscissa "
                  f"{'none' if sa is None else format(sa, '.4g')} 1/s")


def _print_check(rows: list[dict[str, Any]]) -> None:
    t = Table(title=f"MuJoCo across the central delay margin "
                    f"({1e3 * rows[0]['delay_margin_s']:.4g} ms)")
    for col in ("factor", "central delay [ms]", "certified", "abscissa [1/s]",
                "MuJoCo envelope ratio", "MuJoCo growth [1/s]", "agree"):
        t.add_column(escape(col))
    for r in rows:
        t.add_row(f"{r['factor']:g}", f"{1e3 * r['central_delay_s']:.4g}",
                  "stable" if r["stable"] else "unstable",
                  f"{r['spectral_abscissa_per_s']:.3g}", f"{r['envelope_ratio']:.3g}",
                  f"{r['growth_rate_per_s']:.3g}",
                  "yes" if r["agree"] else "[red]NO[/red]")
    console.print(t)


def _workspace(urdf: str, text: str, q0: str | None, mujoco_check: bool, as_json: bool,
               opts: dict[str, Any]) -> None:
    """``seactl robot --workspace``: the map's table or JSON."""
    import seactl as sc

    if q0 is not None or mujoco_check:
        raise InputError("--workspace", text, "given without --q0 and --mujoco-check")
    grid = workspace_grid(text)
    try:
        m = sc.workspace_map(urdf, grid, **opts)
    except InputError as exc:
        if exc.field != "q0":
            raise
        raise InputError("--workspace [rad]", text, exc.valid) from None
    rows = m.records()
    if as_json:
        echo_json({"joints": list(m.joints), "worst": m.worst,
                   "configurations": [{k: finite_or_none(x) if isinstance(x, float) else x
                                       for k, x in row.items()} for row in rows]})
        return
    t = Table(title=f"workspace map, {opts['space']} space, {len(rows)} configurations")
    for col in [f"{j} [rad]" for j in m.joints] + ["verdict", "PM [deg]",
                                                   "delay margin [ms]", "max k_x [N/m]",
                                                   "passive"]:
        t.add_column(escape(col))
    for row in rows:
        t.add_row(*(f"{row[f'{j}_rad']:.4g}" for j in m.joints),
                  "stable" if row["stable"] else "[red]UNSTABLE[/red]",
                  pm_text(row["phase_margin_deg"], row["stable"]),
                  *("none" if row[k] is None else f"{row[k]:.4g}"
                    for k in ("delay_margin_ms", "max_task_stiffness_n_per_m")),
                  "yes" if row.get("passive") else "no")
    console.print(t)
    console.print(f"worst configuration: row {m.worst + 1}")
