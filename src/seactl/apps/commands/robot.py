"""``seactl robot``: a multi-joint SEA robot from its URDF, linearized at a configuration."""

from __future__ import annotations

from typing import Any

import click
from rich.markup import escape
from rich.table import Table

from seactl.base.axes import AXES
from seactl.errors import InputError

from .common import axis_option, cli, console, echo_json, finite_or_none, json_option, pm_text
from .robotmimo import mimo_record, parse_placement, placement_record, print_mimo, print_placement

ROBOT_AXES = ("fn_hz", "gs", "t_tau_ms", "t_qs_ms", "t_qd_ms", "f_qd_hz", "f_taud_hz")


def _q0(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError("--q0 [rad]", text, "comma-separated joint angles, e.g. 0.3,0.8"
                         ) from None


def actuator_spec(text: str) -> Any:
    """``PRESET|FILE`` for every joint, or ``JOINT=PRESET|FILE,...`` as a dict (the
    ``--actuators`` syntax of ``seactl robot`` and of the explorer's robot page)."""
    if "=" not in text:
        return text
    out = {}
    for part in text.split(","):
        joint, _, spec = part.partition("=")
        if not joint.strip() or not spec.strip():
            raise InputError("--actuators", text, "PRESET, FILE, or JOINT=PRESET|FILE,...")
        out[joint.strip()] = spec.strip()
    return out


def robot_record(r: Any, margins: dict[str, Any], roots: Any) -> dict[str, Any]:
    """The JSON of ``seactl robot``: the model, the per-break margins (none for a robot of
    more than three joints: they need the loop's transfers), the verdict."""
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
            "stable": bool((margins["outer.j1"] if margins else r.margins()).stable),
            "spectral_abscissa_per_s": None if roots is None
            else finite_or_none(roots.spectral_abscissa),
            "roots_complete": roots is not None and not bool(roots.uncertain),
            "breaks": breaks}


SECTIONS = (
    ("The robot", ("urdf", "model", "joints", "actuators", "space", "task", "q0")),
    ("The design (as seactl gains)", ROBOT_AXES),
    ("At q0 (default: the margins of every loop break)",
     ("mimo", "placement", "mujoco_check")),
    ("At q0, instead of the margins", ("impedance", "task_step", "task_impulse")),
    ("Over the workspace, instead of q0", ("workspace", "trajectory", "plot", "workers")),
)
"""The headings of ``seactl robot --help`` and the parameters under each."""

TASK_VIEWS = ("--impedance", "--task-step", "--task-impulse")
MAPS = ("--workspace", "--trajectory")

NOT_WITH: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("--workspace", ("--trajectory", "--q0", "--mujoco-check", "--placement")),
    ("--trajectory", ("--q0", "--mujoco-check", "--placement")),
    *((view, (*MAPS, "--mujoco-check", "--placement")) for view in TASK_VIEWS),
)
"""Each option and the options it cannot be given with: a map analyses its own
configurations (one row each), not q0; the task views replace the margins' tables."""

ONLY_WITH: tuple[tuple[str, tuple[str, ...]], ...] = (("--plot", MAPS), ("--workers", MAPS))
"""Each option and the options (one of them) it needs."""


def check_combinations(o: dict[str, Any]) -> None:
    """One line ``error: invalid --A = VALUE: must be given without --B`` (or ``with``)
    for the first pair of :data:`NOT_WITH` / :data:`ONLY_WITH` the options break."""
    flags = {f for flag, others in (*NOT_WITH, *ONLY_WITH) for f in (flag, *others)}
    given = {f: _value(o, f) for f in flags
             if _value(o, f) is not None and _value(o, f) is not False}
    for flag, others in NOT_WITH:
        clash = [x for x in others if x in given]
        if flag in given and clash:
            raise InputError(flag, given[flag], f"given without {clash[0]}")
    for flag, needs in ONLY_WITH:
        if flag in given and not any(x in given for x in needs):
            raise InputError(flag, given[flag], "given with " + " or ".join(needs))


def _value(o: dict[str, Any], flag: str) -> Any:
    """The value of option ``flag`` (``--task-step``) among the command's parameters."""
    return o[flag[2:].replace("-", "_")]


@cli.command(sections=SECTIONS)
@click.option("--urdf", default=None, help="URDF file of the robot (revolute joints).")
@click.option("--model", default=None,
              help="Instead of --urdf: a robot of example-robot-data by name ('list': the "
                   "installed ones; pip install -e \".[robots]\").")
@click.option("--joints", default=None,
              help="The moving joints, comma-separated (at most 7); the others are locked "
                   "at --q0.")
@click.option("--actuators", default="ut-sea", show_default=True,
              help="SEA preset or TOML file for every joint, or JOINT=PRESET|FILE,...")
@click.option("--space", type=click.Choice(["joint", "task"]), default="joint",
              show_default=True, help="Stiffness in joint space or in task space.")
@click.option("--task", default=None, help="Task frame (a frame of the URDF; task space).")
@click.option("--q0", default=None,
              help="Configuration [rad], comma-separated (default 0): the moving joints' "
                   "angles, or every joint's.")
@axis_option("fn_hz")
@axis_option("gs")
@axis_option("t_tau_ms", help_extra=" Each joint's embedded process.")
@axis_option("t_qs_ms", help_extra=" The central process.")
@axis_option("t_qd_ms", help_extra=" Each joint's embedded process.")
@axis_option("f_qd_hz")
@axis_option("f_taud_hz")
@click.option("--mimo/--no-mimo", default=True, show_default=True,
              help="A row for the central process: every stiffness channel broken at once, "
                   "which one break's margin can overstate (generalized Nyquist; Python: "
                   "r.mimo_margins()).")
@click.option("--placement", default=None, metavar="CENTRAL_MS,EMBEDDED_MS",
              help="A row per placement of stiffness and damping on the central or the "
                   "embedded processes with these latencies [ms] (Python: r.placement()).")
@click.option("--mujoco-check", is_flag=True,
              help="Run the robot in MuJoCo at 0.8x and 1.2x of the central delay margin "
                   "and compare with the certified verdicts (Python: r.mujoco_check()).")
@click.option("--impedance", default=None, metavar="F1,F2,...",
              help="Frequencies [Hz]: the task impedance's principal values (joint space "
                   "without --task) and the certified passivity (Python: "
                   "r.task_impedance(f_hz), r.passivity()).")
@click.option("--task-step", default=None, metavar="X,Y,Z",
              help="A 1 mm step of the task reference along X,Y,Z (needs --task; Python: "
                   "r.task_step(direction)).")
@click.option("--task-impulse", default=None, metavar="X,Y,Z",
              help="A 0.01 N s force impulse at the task frame along X,Y,Z (Python: "
                   "r.task_impulse(direction)).")
@click.option("--workspace", default=None, metavar="A:B:N,...",
              help="A grid: per joint N angles from A to B [rad], joints comma-separated; "
                   "one row per configuration (Python: sc.workspace_map).")
@click.option("--trajectory", default=None, metavar="FILE.csv",
              help="The samples of a trajectory: a CSV file with a header of joint names "
                   "(and optionally t_s [s]), angles [rad].")
@click.option("--plot", "plot", default=None, metavar="FILE.png|.svg|.pdf",
              help="Write the map's figure to FILE.")
@click.option("--workers", type=int, default=None,
              help="Run the configurations on N local Dask worker processes (default: in "
                   "this process).")
@json_option
def robot(**o: Any) -> None:
    """Margins, verdict, task impedance and loop placement of a robot of SEA joints from
    its URDF, at one configuration or over its workspace.

    \b
    Example: the margins of every loop break and of the central process at q0
      seactl robot --urdf examples/robots/planar_2link.urdf --q0 0.3,0.8 --fn 14 \\
          --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100

    Python: sc.robot(urdf, actuators=..., space=..., task=..., q0=...).

    Each joint's SEA is designed for its apparent inertia at q0; the stiffness runs on the
    central process (delay --t-qs), damping and torque loops on each joint's embedded
    process. Breaks: outer.jN (the SEA's outer loop), stiffness.jN, damping.jN, torque.jN.
    --model list: the robots of example-robot-data. Details: docs/robots.md.
    """
    import seactl as sc

    if o["model"] == "list":
        _print_models(sc.robot_models(), o["as_json"])
        return
    if (o["urdf"] is None) == (o["model"] is None):
        raise InputError("--urdf", o["urdf"],
                         "a URDF file, or --model NAME instead (one of the two)")
    check_combinations(o)
    opts = _robot_options(o)
    if any(_value(o, f) is not None for f in TASK_VIEWS):
        _task_views(o, opts)
    elif o["workspace"] is not None or o["trajectory"] is not None:
        from .robotmap import workspace_command

        workspace_command(o["urdf"], o["workspace"], o["trajectory"], opts,
                          plot=o["plot"], workers=o["workers"], as_json=o["as_json"])
    else:
        _at_q0(o, opts)


def _robot_options(o: dict[str, Any]) -> dict[str, Any]:
    """The keyword arguments of ``sc.robot`` / ``sc.workspace_map`` but the configuration."""
    v = {n: None if o[n] is None else float(AXES[n].check(o[n], AXES[n].option))
         for n in ROBOT_AXES}
    joints = o["joints"]
    return dict(actuators=actuator_spec(o["actuators"]), space=o["space"], task=o["task"],
                fn_hz=v["fn_hz"], gs=v["gs"],
                delays_ms={"torque": v["t_tau_ms"], "stiffness": v["t_qs_ms"],
                           "damping": v["t_qd_ms"]},
                filters_hz=(v["f_qd_hz"], v["f_taud_hz"]), model=o["model"],
                joints=None if joints is None else [j.strip() for j in joints.split(",")])


def _task_views(o: dict[str, Any], opts: dict[str, Any]) -> None:
    """``--impedance``, ``--task-step``, ``--task-impulse`` at q0."""
    import seactl as sc

    from .robotimpedance import task_views

    task_views(sc.robot(o["urdf"], q0=_q0(o["q0"]), **opts), o["impedance"], o["task_step"],
               o["task_impulse"], o["as_json"])


def _at_q0(o: dict[str, Any], opts: dict[str, Any]) -> None:
    """The margins of every break at q0, the verdict, and the rows ``--mimo``,
    ``--placement``, ``--mujoco-check`` ask for: tables in that order, or one JSON."""
    import seactl as sc

    if o["placement"] is not None:
        parse_placement(o["placement"])      # a typo fails before the analysis
    r = sc.robot(o["urdf"], q0=_q0(o["q0"]), **opts)
    rec = robot_record(r, {} if r.large else r.margins_by_break(),
                       None if r.large else r.roots(count=4))
    if o["mimo"]:
        rec["mimo"] = mimo_record(r)
    if o["placement"] is not None:
        rec["placement"] = placement_record(r, o["placement"])
    if o["mujoco_check"]:
        rec["mujoco_check"] = r.mujoco_check().records()
    if o["as_json"]:
        echo_json(rec)
        return
    _print(rec)
    for key, show in (("mimo", print_mimo), ("placement", print_placement),
                      ("mujoco_check", _print_check)):
        if key in rec:
            show(rec[key])


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
    if rec["breaks"]:
        console.print(t)
    else:
        console.print(f"{len(rec['joints'])}-joint robot, {rec['space']} space: the margins "
                      "per loop break need the loop's transfers (at most 3 joints); the "
                      "verdict and the central process's MIMO row come joint by joint")
    verdict = "stable" if rec["stable"] else "[red]UNSTABLE[/red]"
    sa = rec["spectral_abscissa_per_s"]
    if rec["breaks"]:
        console.print(f"certified verdict: {verdict}; spectral abscissa "
                      f"{'none' if sa is None else format(sa, '.4g')} 1/s")
    else:   # (no roots beyond three joints: the verdict is a certified count)
        console.print(f"certified verdict: {verdict}")


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
