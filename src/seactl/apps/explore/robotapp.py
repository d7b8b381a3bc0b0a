"""The Bokeh document of ``seactl explore --robot URDF``: a robot's widgets, figures and
callbacks.

Callbacks read the widgets into a :class:`~seactl.apps.explore.robotmodel.RobotControls`
and copy what :mod:`~seactl.apps.explore.robotmodel` computes into the page, stage by
stage; changes arriving while an update runs are merged into one more update.  The
workspace map is computed only when its button is pressed.
"""

from __future__ import annotations

import atexit
import functools
import html
import shutil
import tempfile
import time
from dataclasses import replace
from typing import Any

from bokeh.layouts import column, gridplot, row
from bokeh.models import (
    Button,
    ColorBar,
    ColumnDataSource,
    Div,
    HoverTool,
    LinearColorMapper,
    RadioButtonGroup,
    Select,
    Slider,
    Span,
)
from bokeh.palettes import Category10
from bokeh.plotting import figure

from . import robotmodel as rm
from .app import badge_html, make_document
from .model import number, safe

SLIDERS = {"fn_hz": "f_n [Hz]", "t_tau_ms": "T_tau torque delay [ms]",
           "t_qs_ms": "T_qs central stiffness delay [ms]",
           "t_qd_ms": "T_qd damping delay [ms]"}
FIG = {"width": 430, "height": 260, "tools": "pan,wheel_zoom,box_zoom,reset,save"}


def _fmt(x: Any, fmt: str = ".4g") -> str:
    return "none" if x is None else f"{x:{fmt}}"


def breaks_html(rows: list[dict[str, Any]]) -> str:
    """The margins of every loop break as a table (ids ``pm-outer-j1``, ``dm-outer-j1``,
    ...: the break's name with ``-`` for ``.``, a valid CSS id)."""
    head = "".join(f"<th style='padding:0 4px'>{h}</th>" for h in (
        "break", "PM [deg]", "crossover [Hz]", "GM [dB]", "delay margin [ms]"))
    body = "".join(
        f"<tr><td>{html.escape(b['break'])}</td>"
        f"<td id='pm-{b['break'].replace('.', '-')}' style='text-align:right'>"
        f"{_fmt(b['phase_margin_deg'], '.2f')}</td>"
        f"<td style='text-align:right'>{_fmt(b['crossover_hz'])}</td>"
        f"<td style='text-align:right'>{_fmt(b['gain_margin_db'], '.2f')}</td>"
        f"<td id='dm-{b['break'].replace('.', '-')}' style='text-align:right'>"
        f"{_fmt(b['delay_margin_ms'])}</td></tr>" for b in rows)
    return (f"<table id='breaks' style='font-size:12px;border-collapse:collapse'>"
            f"<tr>{head}</tr>{body}</table>")


def command_html(text: str, element_id: str = "command") -> str:
    """A command line, wrapped anywhere to the panel's width."""
    return (f"<pre id='{element_id}' style='font-size:11px;white-space:pre-wrap;"
            f"word-break:break-all;margin:0'>{html.escape(text)}</pre>")


class RobotExplorer:
    """One browser session of the robot page."""

    def __init__(self, start: tuple[rm.RobotControls, rm.RobotInfo], doc: Any = None):
        self.doc = doc
        self.sea_button = Button(label="built-in SEA", width=100)
        self.sea_button.on_click(self.leave_robot)
        self.base, self.info = start
        self.pending = False
        self.generation = 0
        self.last_ms: list[tuple[float, ...]] = []
        self.sources = {k: ColumnDataSource() for k in ("principal", "step", "cells",
                                                         "marker")}
        self._widgets(self.base)
        self._figures()
        self.update(sync=True)

    # ------------------------------------------------------------ widgets
    def _widgets(self, c: rm.RobotControls) -> None:
        self.q_sliders = []
        for name, q, (lo, hi) in zip(self.info.joints, c.q_rad, self.info.limits_rad):
            s = Slider(title=f"q {name} [rad]", start=lo, end=hi, step=rm.Q_STEP_RAD,
                       value=min(max(q, lo), hi), width=320, css_classes=[f"seactl-q-{name}"])
            self.q_sliders.append(s)
        self.sliders = {}
        for key, label in SLIDERS.items():
            lo, hi, step = rm.ROBOT_BOUNDS[key]
            self.sliders[key] = Slider(title=label, start=lo, end=hi, step=step,
                                       value=getattr(c, key), width=320,
                                       css_classes=[f"seactl-{key}"])
        self.space = RadioButtonGroup(labels=list(rm.SPACES), active=rm.SPACES.index(c.space))
        frames = [*self.info.links, *([c.task] if c.task and c.task not in
                                       self.info.links else [])]  # --task: any frame
        self.task = Select(title="task frame", value=c.task or "", options=frames, width=150)
        names = list(self.info.joints)
        self.map_x = Select(title="map across", value=names[0], options=names, width=100)
        self.map_y = Select(title="map up", value=names[min(1, len(names) - 1)],
                            options=names, width=100)
        self.map_points = Select(title="points per joint", value=str(rm.MAP_POINTS[0]),
                                 options=[str(n) for n in rm.MAP_POINTS], width=110)
        self.map_button = Button(label="compute workspace map", width=200)
        self.map_button.on_click(self.on_map)
        self.map_msg = Div(text="", width=330, name="map-status")
        self.badge, self.results = Div(text="", width=330), Div(text="", width=330)
        self.table = Div(text="", width=430)
        self.status = Div(text="", width=330, name="status")
        self.command = Div(text="", width=330)
        for w in [*self.q_sliders, *self.sliders.values()]:
            w.on_change("value", self.on_change)
        self.space.on_change("active", self.on_change)
        self.task.on_change("value", self.on_change)

    def controls(self) -> rm.RobotControls:
        """The controls as the widgets show them (numbers as the command line writes
        them, so the copied command computes what the page shows)."""
        v = {k: number(float(s.value)) for k, s in self.sliders.items()}
        q = tuple(number(float(s.value)) for s in self.q_sliders)
        space = rm.SPACES[self.space.active] if self.space.active in (0, 1) else "joint"
        return replace(self.base, q_rad=q, space=space, task=self.task.value or None, **v)

    # ------------------------------------------------------------ callbacks
    def leave_robot(self) -> None:
        """Back to the built-in SEA page (it can open another robot)."""
        if self.doc is not None:
            self.doc.clear()
            make_document(self.doc, robot_page=open_uploaded_robot)

    def on_change(self, attr: str, old: Any, new: Any) -> None:
        """Bokeh's callback signature for :meth:`request`."""
        self.request()

    def request(self) -> None:
        """Any control changed: schedule one update (coalesced)."""
        if self.doc is None:
            self.update()
        elif not self.pending:
            self.pending = True
            self.doc.add_next_tick_callback(self.update)

    def update(self, sync: bool = False) -> None:
        """Recompute the views stage by stage (a newer change drops the stale stages)."""
        self.pending = False
        self.generation += 1
        self.task.disabled = self.space.active != 1
        self.run_stage(self.generation, self.controls(), 0, {}, time.perf_counter(), [],
                       sync)

    def run_stage(self, generation: int, c: rm.RobotControls, index: int,
                  acc: dict[str, Any], t0: float, marks_ms: list[float],
                  sync: bool = False) -> None:
        """Compute and show stage ``index``, then schedule the next one."""
        if generation != self.generation or (index and self.pending):
            return
        out, error = safe(rm.STAGES[index], c, acc)
        if error is not None:
            self.status.text = (f"<span id='status-value' style='color:#b00020'>error: "
                                f"{html.escape(error)}</span>")
            return
        acc.update(out)
        self.apply(out)
        marks_ms.append((time.perf_counter() - t0) * 1e3)
        if index + 1 < len(rm.STAGES):
            step = functools.partial(self.run_stage, generation, c, index + 1, acc, t0,
                                     marks_ms, sync)
            if sync or self.doc is None:
                step()
            else:
                self.doc.add_next_tick_callback(step)
            return
        self.last_ms.append(tuple(marks_ms))
        self.status.text = ("<span id='status-value'>" + ", ".join(
            f"{name} in {ms:.0f} ms" for name, ms in zip(rm.STAGE_NAMES, marks_ms))
            + "</span>")

    def apply(self, v: dict[str, Any]) -> None:
        """Copy what a stage computed into the page."""
        r = v["results"]
        self.badge.text = badge_html_robot(r)
        self.results.text = (f"<p id='verdict' style='font-size:12px;max-width:320px'>"
                             f"{html.escape(r['verdict'])}</p>")
        if "command" in v:
            self.command.text = command_html(v["command"])
        if "breaks" in v:
            self.table.text = breaks_html(v["breaks"])
        if "principal" in v:
            p = v["principal"]
            n = len(p["ys"])
            self.sources["principal"].data = {**p, "color": list(Category10[10][:n])}
        if "step" in v:
            self.sources["step"].data = dict(v["step"])

    def on_map(self) -> None:
        """The map button: say that the map is being computed, then compute it on the next
        tick (the message reaches the browser first)."""
        self.map_msg.text = "<span id='map-msg'>computing the workspace map ...</span>"
        if self.doc is None:
            self.compute_map()
        else:
            self.doc.add_next_tick_callback(self.compute_map)

    def compute_map(self) -> None:
        """The workspace map over the two chosen joints around the current ``q``."""
        names = list(self.info.joints)
        across = names.index(self.map_x.value)
        up = names.index(self.map_y.value) if self.map_y.value != self.map_x.value else None
        t0 = time.perf_counter()
        out, error = safe(rm.map_views, self.controls(), across, up, int(self.map_points.value))
        if error is not None:
            self.map_msg.text = (f"<span id='map-msg' style='color:#b00020'>error: "
                                 f"{html.escape(error)}</span>")
            return
        self.sources["cells"].data = dict(out["cells"])
        self.sources["marker"].data = dict(out["marker"])
        self.map_fig.xaxis.axis_label = f"q {names[across]} [rad]"
        self.map_fig.yaxis.axis_label = f"q {names[up]} [rad]" if up is not None else ""
        worst = ", ".join(f"{q:.3g}" for q in out["worst_q_rad"])
        self.map_msg.text = (f"<span id='map-msg'>{len(out['cells']['x'])} configurations in "
                             f"{time.perf_counter() - t0:.1f} s; worst q = ({worst}) rad"
                             f"</span>{command_html(out['command'], 'map-command')}")

    # ------------------------------------------------------------ figures
    def _figures(self) -> None:
        z = figure(x_axis_type="log", y_axis_type="log", x_axis_label="f [Hz]",
                   y_axis_label="principal values of Z [N m s/rad]",
                   title="joint-space impedance Z(jw): principal values", **FIG)
        z.multi_line("xs", "ys", source=self.sources["principal"], line_width=2,
                     color="color", legend_field="label")
        step = figure(title="step response q_j.j1 / q_des.j1 (normalized)",
                      x_axis_label="t [ms]", **FIG)
        step.line("t_ms", "y", source=self.sources["step"], line_width=2)
        step.add_layout(Span(location=1, dimension="width", line_color="gray"))
        self.map_fig = self._map()
        self.figures = [z, step, self.map_fig]

    def _map(self) -> Any:
        mapper = LinearColorMapper(palette="Viridis256", low=0, high=90, nan_color="#dddddd")
        f = figure(title="workspace map: PM at outer.j1; grey: unstable", **FIG)
        cells = f.quad(left="left", right="right", bottom="bottom", top="top",
                       source=self.sources["cells"], line_alpha=0,
                       fill_color={"field": "pm", "transform": mapper})
        f.scatter("x", "y", source=self.sources["marker"], marker="circle_cross", size=14,
                  fill_color="white", line_color="red", line_width=2)
        f.add_tools(HoverTool(renderers=[cells], tooltips=[
            ("q", "(@x{0.000}, @y{0.000}) rad"), ("PM [deg]", "@pm{0.0}"),
            ("delay margin [ms]", "@dm{0.00}"), ("max k_x [N/m]", "@kx{0.0}")]))
        f.add_layout(ColorBar(color_mapper=mapper, width=8, title="PM"), "right")
        return f

    # ------------------------------------------------------------ layout
    def layout(self) -> Any:
        """The verdict badge, controls and words on the left; the table and views right."""
        head = Div(text=f"<h3 style='margin:0'>seactl explore: "
                        f"{html.escape(self.base.file_name or self.base.urdf)}</h3>",
                   width=330)
        controls = column(
            head, self.sea_button, self.badge, *self.q_sliders, *self.sliders.values(),
            row(self.space, self.task), self.status, self.results, self.command,
            row(self.map_x, self.map_y, self.map_points), self.map_button, self.map_msg)
        grid = gridplot(self.figures, ncols=2, toolbar_location="right")
        return row(controls, column(self.table, grid))


def badge_html_robot(r: dict[str, Any]) -> str:
    """The robot's badges (:func:`~seactl.apps.explore.robotmodel.badges`) as
    :func:`~seactl.apps.explore.app.badge_html` draws them."""
    return badge_html(r, rm.badges(r))


def make_robot_document(doc: Any, start: tuple[rm.RobotControls, rm.RobotInfo]) -> None:
    """Bokeh application entry of the robot page: one :class:`RobotExplorer` per session."""
    explorer = RobotExplorer(start, doc)
    doc.title = "seactl explore: robot"
    doc.add_root(explorer.layout())


def open_uploaded_robot(doc: Any, filename: str, content: bytes) -> None:
    """Replace the page by the robot page of an uploaded URDF
    (:func:`~seactl.apps.explore.robotmodel.robot_from_upload`).  The file stays in a
    temporary directory of the session, deleted when the session or the server ends (at
    once if the library refuses it: then its error propagates)."""
    folder = tempfile.mkdtemp(prefix="seactl-robot-")
    try:
        start = rm.robot_from_upload(filename, content, folder)
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    if doc is None:
        shutil.rmtree(folder, ignore_errors=True)
        return
    doc.on_session_destroyed(lambda _context: shutil.rmtree(folder, ignore_errors=True))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)  # a server stopped first
    doc.clear()
    make_robot_document(doc, start)

