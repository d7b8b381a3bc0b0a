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
@click.option("--urdf", default=None, help="URDF file of the robot (revolute joints).")
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
@click.option("--model", default=None,
              help="Instead of --urdf: a robot of example-robot-data by name ('list': the "
                   "installed ones; pip install -e \".[robots]\").")
@click.option("--joints", default=None,
              help="The moving joints, comma-separated (at most 3); the others are locked "
                   "at --q0.")
@click.option("--trajectory", default=None, metavar="FILE.csv",
              help="Map the samples of a trajectory instead of a grid: a CSV file with a "
                   "header of joint names (and optionally t_s [s]), angles [rad].")
@click.option("--plot", "plot", default=None, metavar="FILE.png|.svg|.pdf",
              help="With --workspace or --trajectory: write the map's figure to FILE.")
@click.option("--workers", type=int, default=None,
              help="With --workspace or --trajectory: run the configurations on N local "
                   "Dask worker processes (default: in this process).")
@click.option("--mimo/--no-mimo", default=True, show_default=True,
              help="The generalized Nyquist margins of the central process: every "
                   "stiffness channel broken at once (Python: r.mimo_margins()).")
@click.option("--placement", default=None, metavar="CENTRAL_MS,EMBEDDED_MS",
              help="Also every placement of stiffness and damping on the central or the "
                   "embedded processes with these latencies [ms] (Python: r.placement()).")
@click.option("--impedance", default=None,
              help="Frequencies [Hz], comma-separated: the task impedance's principal "
                   "values (joint space without --task) and the certified passivity.")
@click.option("--task-step", default=None,
              help="Direction X,Y,Z of a 1 mm step of the task reference (needs --task).")
@click.option("--task-impulse", default=None,
              help="Direction X,Y,Z of a 0.01 N s force impulse at the task frame.")
@json_option
def robot(urdf: str | None, actuators: str, space: str, task: str | None, q0: str | None,
          workspace: str | None, mujoco_check: bool, model: str | None, joints: str | None,
          trajectory: str | None, plot: str | None, workers: int | None, as_json: bool,
          mimo: bool = True, placement: str | None = None, impedance: str | None = None,
          task_step: str | None = None, task_impulse: str | None = None,
          **axes: Any) -> None:
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
    margin, and in task space the largest task stiffness k_x [N/m]); --trajectory: the
    same per sample of a CSV file; --plot FILE: the map's figure; --workers N: on Dask.
    --model NAME --joints J1,J2: a robot of example-robot-data, only those joints moving
    (fixed base: a legged robot's leg in the air); --q0 gives the moving joints' angles
    (the locked ones at 0) or all the model's joints (docs/robots.md).
    The central process's row (--mimo, the default) breaks every stiffness channel at
    once: a single break's margin can look ample on a coupled robot that is unstable.
    --placement 5,0.5: stiffness and damping on the central (5 ms) or embedded (0.5 ms)
    processes, each placement's verdict and central latency margins (docs/robots.md).
    --impedance, --task-step, --task-impulse: Python r.task_impedance(f_hz),
    r.passivity(), r.task_step(direction), r.task_impulse(direction) (docs/robots.md).
    """
    import seactl as sc

    if model == "list":
        _print_models(sc.robot_models(), as_json)
        return
    if (urdf is None) == (model is None):
        raise InputError("--urdf", urdf, "a URDF file, or --model NAME instead (one of the two)")

    v = {n: None if axes[n] is None else float(AXES[n].check(axes[n], AXES[n].option))
         for n in ROBOT_AXES}
    opts = dict(actuators=_actuators(actuators), space=space, task=task,
                fn_hz=v["fn_hz"], gs=v["gs"],
                delays_ms={"torque": v["t_tau_ms"], "stiffness": v["t_qs_ms"],
                           "damping": v["t_qd_ms"]},
                filters_hz=(v["f_qd_hz"], v["f_taud_hz"]), model=model,
                joints=None if joints is None else [j.strip() for j in joints.split(",")])
    is_map = workspace is not None or trajectory is not None
    if impedance is not None or task_step is not None or task_impulse is not None:
        from .robotimpedance import task_views

        if is_map or mujoco_check or placement is not None:
            other = ("--workspace/--trajectory" if is_map else
                     "--mujoco-check" if mujoco_check else "--placement")
            raise InputError("--impedance/--task-step/--task-impulse", "with " + other,
                             "given without " + other)
        task_views(sc.robot(urdf, q0=_q0(q0), **opts), impedance, task_step, task_impulse,
                   as_json)
        return
    if is_map and placement is not None:
        raise InputError("--workspace" if workspace is not None else "--trajectory",
                         workspace if workspace is not None else trajectory,
                         "given without --placement")
    if is_map:
        from seactl.apps.commands.robotmap import workspace_command

        workspace_command(urdf, workspace, trajectory, q0, mujoco_check, opts,
                          plot=plot, workers=workers, as_json=as_json)
        return
    if plot is not None or workers is not None:
        raise InputError("--plot" if plot is not None else "--workers",
                         plot if plot is not None else workers,
                         "given with --workspace or --trajectory (a map's options)")
    r = sc.robot(urdf, q0=_q0(q0), **opts)
    central, extra = _central_views(r, mimo, placement)
    rec = robot_record(r, r.margins_by_break(), r.roots(count=4))
    if mujoco_check:
        rec["mujoco_check"] = r.mujoco_check().records()
    rec.update(extra)
    if as_json:
        echo_json(rec)
        return
    _print(rec)
    central()
    if mujoco_check:
        _print_check(rec["mujoco_check"])


def _print_models(models: dict[str, Any], as_json: bool) -> None:
    """``seactl robot --model list``."""
    if as_json:
        echo_json(models)
        return
    if not models:
        console.print('no robot models: pip install -e ".[robots]" (example-robot-data)')
        return
    t = Table(title="robots of example-robot-data (fixed base)")
    for col in ("model", "example --joints", "example --task", "robot"):
        t.add_column(escape(col))
    for name, m in models.items():
        t.add_row(name, ",".join(m["joints"]), m["task"], escape(m["about"]))
    console.print(t)


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


def _central_views(r: Any, mimo: bool, placement: str | None) -> tuple[Any, dict[str, Any]]:
    """``--mimo`` and ``--placement``: what prints their tables, and their records."""
    from .robotmimo import mimo_record, placement_record, print_mimo, print_placement

    rec: dict[str, Any] = {}
    if placement is not None:
        rec["placement"] = placement_record(r, placement)
    if mimo:
        rec["mimo"] = mimo_record(r)

    def show() -> None:
        if mimo:
            print_mimo(rec["mimo"])
        if placement is not None:
            print_placement(rec["placement"])
    return show, rec
