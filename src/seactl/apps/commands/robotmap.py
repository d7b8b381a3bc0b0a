"""``seactl robot --workspace`` / ``--trajectory``: a robot's workspace map (table, JSON,
figure)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rich.markup import escape
from rich.table import Table

from seactl.api.robotmapplot import marked
from seactl.base.outputs import FIGURE_SUFFIXES, OutputSet
from seactl.errors import InputError

from .common import console, echo_json, finite_or_none, pm_text


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


def workspace_command(urdf: str, workspace: str | None, trajectory: str | None,
                      opts: dict[str, Any], *, plot: str | None, workers: int | None,
                      as_json: bool) -> None:
    """The map of a grid (``--workspace``) or a trajectory file (``--trajectory``); the
    options it cannot be given with are refused by ``seactl robot`` before it."""
    if workers is not None and workers < 1:
        raise InputError("--workers", workers, ">= 1 (omit it to run in this process)")
    with OutputSet() as outs:
        path = outs.add("--plot", plot, FIGURE_SUFFIXES)
        m = _map(urdf, workspace, trajectory, opts, workers)
        if path is not None:
            _save_plot(m, outs, path)
        _report(m, opts["space"], as_json)


def _map(urdf: str, workspace: str | None, trajectory: str | None, opts: dict[str, Any],
         workers: int | None) -> Any:
    import seactl as sc

    configurations = workspace_grid(workspace) if workspace is not None else trajectory
    backend = "serial" if workers is None else "dask"
    try:
        return sc.workspace_map(urdf, configurations, backend=backend, workers=workers,
                                **opts)
    except InputError as exc:
        if exc.field == "trajectory":
            raise InputError("--trajectory", trajectory, exc.valid) from None
        if exc.field != "q0":
            raise
        option, text = (("--workspace [rad]", workspace) if workspace is not None else
                        ("--trajectory", trajectory))
        raise InputError(option, text, exc.valid) from None


def _save_plot(m: Any, outs: OutputSet, path: Path) -> None:
    import matplotlib.pyplot as plt

    ax = m.plot()
    ax.set_title(f"workspace map, {len(m.stable)} configurations", fontsize="medium")
    outs.figure(path, ax.figure, dpi=120)
    plt.close(ax.figure)
    outs.commit()


def _row_json(row: dict[str, Any], intervals: tuple) -> dict[str, Any]:
    out = {k: finite_or_none(x) if isinstance(x, float) else x for k, x in row.items()}
    out["stiffness_intervals_n_per_m"] = [[finite_or_none(a), finite_or_none(b)]
                                          for a, b in intervals]
    return out


def _ms(x: Any) -> str:
    """A delay margin [ms] of a row (None: no crossover)."""
    return "none" if x is None else f"{x:.4g}"


def _angles(m: Any, row: dict[str, Any]) -> str:
    return ", ".join(f"{row[f'{j}_rad']:.4g}" for j in m.joints)


def _report(m: Any, space: str, as_json: bool) -> None:
    rows = m.records()
    intervals = m.stiffness_intervals_n_per_m or ((),) * len(rows)
    flips = [i for i, ok in enumerate(m.single_flip) if not ok]
    limited = marked(m, "max_task_stiffness_n_per_m") if space == "task" else None
    if as_json:
        echo_json({"joints": list(m.joints), "worst": m.worst,
                   "worst_configuration": _row_json(rows[m.worst], intervals[m.worst]),
                   "lowest_max_task_stiffness": limited,
                   "multiple_flips": flips,
                   "configurations": [_row_json(r, iv) for r, iv in zip(rows, intervals)]})
        return
    t = Table(title=f"workspace map, {space} space, {len(rows)} configurations")
    time_col = ["t [s]"] if m.t_s is not None else []
    for col in time_col + [f"{j} [rad]" for j in m.joints] + [
            "verdict", "PM outer.j1 [deg]", "delay margin outer.j1 [ms]", "MIMO PM [deg]",
            "central delay margin [ms]", "max k_x [N/m]", "passive"]:
        t.add_column(escape(col))
    for i, row in enumerate(rows):
        kx = row["max_task_stiffness_n_per_m"]
        t.add_row(*([f"{row['t_s']:.4g}"] if time_col else []),
                  *(f"{row[f'{j}_rad']:.4g}" for j in m.joints),
                  "stable" if row["stable"] else "[red]UNSTABLE[/red]",
                  pm_text(row["phase_margin_deg"], row["stable"]),
                  _ms(row["delay_margin_ms"]),
                  pm_text(row["mimo_phase_margin_deg"], row["stable"]),
                  _ms(row["mimo_delay_margin_ms"]),
                  ("none" if kx is None else f"{kx:.4g}") + ("" if i not in flips else
                                                            " [yellow](flips)[/yellow]"),
                  "n/a" if row.get("passive") is None else "yes" if row["passive"] else "no")
    console.print(t)
    w = rows[m.worst]
    console.print(f"worst configuration (least central delay margin): row {m.worst + 1}, "
                  f"q = ({_angles(m, w)}) rad, {'stable' if w['stable'] else 'UNSTABLE'}, "
                  f"central delay margin {_ms(w['mimo_delay_margin_ms'])} ms, MIMO PM "
                  f"{pm_text(w['mimo_phase_margin_deg'], w['stable'])} deg")
    if limited is not None:
        k = rows[limited]["max_task_stiffness_n_per_m"]
        console.print(f"lowest largest task stiffness: row {limited + 1}, q = "
                      f"({_angles(m, rows[limited])}) rad, max k_x "
                      f"{'none' if k is None else format(k, '.4g')} N/m")
    if flips:
        console.print(f"[yellow]the verdict flips more than once along k_x at row(s) "
                      f"{', '.join(str(i + 1) for i in flips)}: max k_x is the top of the "
                      "highest stable stretch (--json: stiffness_intervals_n_per_m)[/yellow]")
