"""The Bokeh document of ``seactl explore``: widgets, figures and their callbacks.

Callbacks only read the widgets into a :class:`~seactl.apps.explore.model.Controls`, call
:func:`~seactl.apps.explore.model.safe_views` and copy its arrays into the figures' data
sources.  Changes arriving while an update runs are coalesced into one more update (a
dragged slider sends many values; only the latest is computed).
"""

from __future__ import annotations

import base64
import functools
import html
import math
import time
from typing import Any

import numpy as np
from bokeh.core.property.descriptors import UnsetValueError
from bokeh.layouts import column, gridplot, row
from bokeh.models import (
    Button,
    CheckboxGroup,
    ColorBar,
    ColumnDataSource,
    CustomJS,
    DataRange1d,
    Div,
    FileInput,
    FixedTicker,
    HoverTool,
    LinearColorMapper,
    PreText,
    PrintfTickFormatter,
    RadioButtonGroup,
    Range1d,
    Select,
    Slider,
    Span,
)
from bokeh.plotting import figure

import seactl as sc
from seactl.systems.sea.actuators import SEA_PRESETS

from . import loopmodel
from .loopmodel import LoopControls, loop_from_upload, variable_sliders
from .model import (
    BADGE_COLOURS,
    BOUNDS,
    MODES,
    PM_MAP_GS,
    STAGE_NAMES,
    STAGES,
    Controls,
    actuator_from_upload,
    badges,
    controls_from_table,
    fn_range_hz,
    number,
    safe,
)

SLIDERS = {  # control -> label
    "fn_hz": "f_n [Hz]", "gs": "gain scale GS", "zeta1": "zeta1", "zeta2": "zeta2",
    "ratio": "ratio w2/w1", "t_tau_ms": "T_tau torque delay [ms]",
    "t_qs_ms": "T_qs stiffness delay [ms]", "t_qd_ms": "T_qd damping delay [ms]",
    "f_qd_hz": "f_qd velocity filter [Hz]", "f_taud_hz": "f_taud torque-derivative filter [Hz]",
    "rate_hz": "sampling rate [Hz]",
}
FIG = {"width": 430, "height": 250, "tools": "pan,wheel_zoom,box_zoom,reset,save"}

SAVE_JS = """
function save(blob) {  // the browser's download of blob as `filename`
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
}
"""

DOWNLOAD_JS = SAVE_JS + """
save(new Blob([src.data[key][0]], {type: mime}));
"""

FIGURES_JS = SAVE_JS + """
// Each figure's own export (BokehJS PlotView.export: an SVG context, canvas2svg, for
// 'svg'; a canvas for 'png'), placed where the page shows it, in one file.
const views = figs.map(f => Bokeh.index.find_one(f))
  .filter(v => v != null && v.el.getBoundingClientRect().width > 0);  // shown ones only
const boxes = views.map(v => v.el.getBoundingClientRect());
const x0 = Math.min(...boxes.map(b => b.left)), y0 = Math.min(...boxes.map(b => b.top));
const W = Math.ceil(Math.max(...boxes.map(b => b.right)) - x0);
const H = Math.ceil(Math.max(...boxes.map(b => b.bottom)) - y0);
if (fmt === 'svg') {
  const parts = views.map((v, i) => {
    const svg = v.export('svg', false).ctx.get_serialized_svg(true)
      .replace(/^<\\?xml[^>]*>/, '');
    const x = Math.round(boxes[i].left - x0), y = Math.round(boxes[i].top - y0);
    return `<g transform="translate(${x},${y})">${svg}</g>`;
  });
  const text = `<?xml version="1.0" encoding="UTF-8"?>\n<svg xmlns="http://www.w3.org/2000/svg"`
    + ` xmlns:xlink="http://www.w3.org/1999/xlink" width="${W}" height="${H}"`
    + ` viewBox="0 0 ${W} ${H}"><rect width="${W}" height="${H}" fill="white"/>`
    + parts.join('') + '</svg>';
  save(new Blob([text], {type: 'image/svg+xml'}));
} else {
  const r = window.devicePixelRatio || 1;
  const canvas = document.createElement('canvas');
  canvas.width = Math.ceil(W * r);
  canvas.height = Math.ceil(H * r);
  const ctx = canvas.getContext('2d');
  ctx.fillStyle = 'white';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  views.forEach((v, i) => {
    const layer = v.export('png', true);
    ctx.drawImage(layer.canvas, Math.round((boxes[i].left - x0) * r),
                  Math.round((boxes[i].top - y0) * r));
  });
  canvas.toBlob(save, 'image/png');
}
"""

COPY_JS = """
const text = src.data['command'][0];
function done() { btn.label = 'Copied'; setTimeout(() => { btn.label = label; }, 1500); }
if (navigator.clipboard && window.isSecureContext) {
  navigator.clipboard.writeText(text).then(done);
} else {
  const ta = document.createElement('textarea');
  ta.value = text;
  document.body.appendChild(ta);
  ta.select();
  document.execCommand('copy');
  ta.remove();
  done();
}
"""


def _fmt(x: Any, fmt: str = ".4g") -> str:
    return "none" if x is None else f"{x:{fmt}}"


def badge_html(r: dict[str, Any], items: list[tuple[str, str, str]] | None = None) -> str:
    """The coloured verdict badge (``items``, by default
    :func:`~seactl.apps.explore.model.badges` of ``r``): white words on green (good),
    orange (a warning) or red (bad)."""
    spans = "".join(
        f"<span id='{i}' data-tone='{tone}' style='display:inline-block;margin:2px 6px 2px 0;"
        f"padding:3px 10px;border-radius:12px;color:white;font-weight:bold;font-size:13px;"
        f"background:{BADGE_COLOURS[tone]}'>{html.escape(text)}</span>"
        for i, text, tone in (badges(r) if items is None else items))
    return f"<div id='badge'>{spans}</div>"


def _rows_html(rows: list[tuple[str, str, str]]) -> str:
    return "".join(f"<tr><td>{html.escape(k)}</td><td id='{i}' style='text-align:right'>"
                   f"<b>{v}</b></td></tr>" for k, i, v in rows)


def _panel(rows: list[tuple[str, str, str]], verdict: str) -> str:
    return (f"<table style='font-size:12px;border-collapse:collapse'>{_rows_html(rows)}"
            f"</table><p id='verdict' style='font-size:12px;max-width:320px'>"
            f"{html.escape(verdict)}</p>")


def loop_results_html(r: dict[str, Any]) -> str:
    """The results panel of a loop file: margins per break (as ``seactl analyze``), the
    step's metrics, the verdicts; the outermost break's values carry the SEA page's ids
    (``pm-value``, ...)."""
    rows = []
    for b in r["breaks"]:
        outer = b["break"] == r["outer_break"]
        tag = "" if outer else f"-{b['break']}"
        n = b["break"]
        jit = r.get(f"{n}_jitter_margin_ms", "...")
        rows += [(f"{n}: phase margin [deg]", f"pm{tag}-value",
                  _fmt(b["phase_margin_deg"], ".2f")),
                 (f"{n}: crossover [Hz]", f"fc{tag}-value", _fmt(b["crossover_hz"])),
                 (f"{n}: gain margin [dB]", f"gm{tag}-value", _fmt(b["gain_margin_db"], ".2f")),
                 (f"{n}: delay margin [ms]", f"dm{tag}-value", _fmt(b["delay_margin_ms"])),
                 (f"{n}: jitter margin [ms]", f"jm{tag}-value",
                  jit if jit == "..." else _fmt(jit))]
    unit = html.escape(r.get("step_unit", ""))
    rows += [
        ("closed loop (continuous)", "stable-value", "stable" if r["stable"] else "UNSTABLE"),
        ("sampled loop (the file's rates)", "sampled-value",
         f"{r['sampled_verdict']} at {r['sampled_rate']}" if r.get("sampled_verdict")
         else "(continuous mode)"),
        (f"step amplitude [{unit}]", "amp-value", _fmt(r.get("step_amplitude"), ".10g")),
        ("step overshoot [%]", "os-value", _fmt(r.get("step_overshoot_pct"), ".2f")),
        ("step settling (2 %) [ms]", "ts-value", _fmt(r.get("step_settling_ms"), ".4g")),
        ("step verdict", "step-verdict-value", r.get("step_verdict", "...")),
    ]
    return _panel(rows, r["verdict"])


def results_html(r: dict[str, Any], unit: str) -> str:
    """The results panel; each value in an element with an id (the browser test reads
    ``pm-value``)."""
    if r.get("kind") == "loop":
        return loop_results_html(r)
    rows = [
        ("f_n [Hz]", "fn-value", _fmt(r["fn_hz"], ".10g")),
        ("GS", "gs-value", _fmt(r["gs"], ".10g")),
        ("K_q [N m/rad]", "kq", _fmt(r["Kq"])), ("B_q [N m s/rad]", "bq", _fmt(r["Bq"])),
        ("K_tau [A/(N m)]", "ktau", _fmt(r["Ktau"])),
        ("B_tau [A s/(N m)]", "btau", _fmt(r["Btau"])),
        ("phase margin [deg]", "pm-value", _fmt(r["phase_margin_deg"], ".2f")),
        ("crossover [Hz]", "fc-value", _fmt(r["crossover_hz"])),
        ("gain margin [dB]", "gm-value", _fmt(r["gain_margin_db"], ".2f")),
        ("delay margin, whole loop [ms]", "dm-value", _fmt(r["delay_margin_ms"])),
        ("delay margin, stiffness loop [ms]", "dms-value",
         _fmt(r["stiffness_delay_margin_ms"]) if "stiffness_delay_margin_ms" in r else "..."),
        ("delay margin, damping loop [ms]", "dmd-value",
         _fmt(r["damping_delay_margin_ms"]) if "damping_delay_margin_ms" in r else "..."),
        *((f"jitter margin, {name} [ms]", f"jm-{loop}-value",
           _fmt(r[f"{loop}_jitter_margin_ms"]) if f"{loop}_jitter_margin_ms" in r else "...")
          for loop, name in (("overall", "whole loop"), ("stiffness", "stiffness loop"),
                             ("damping", "damping loop"), ("torque", "torque loop"))),
        ("spectral abscissa [1/s]", "sa-value",
         _fmt(r["spectral_abscissa_per_s"]) if "spectral_abscissa_per_s" in r else "..."),
        ("closed loop", "stable-value", "stable" if r["stable"] else "UNSTABLE"),
        ("sampled loop", "sampled-value",
         f"{r['sampled_verdict']} at {r['sampled_rate']}" if r.get("sampled_verdict")
         else "(continuous mode)"),
        (f"Z(jw) [{unit}]", "passive-value", "passive" if r["passive"] else "not passive"),
        ("step amplitude [rad]", "amp-value", _fmt(r.get("step_amplitude_rad"), ".10g")),
        ("step overshoot [%]", "os-value", _fmt(r.get("step_overshoot_pct"), ".2f")),
        ("step settling (2 %) [ms]", "ts-value", _fmt(r.get("step_settling_ms"), ".4g")),
    ]
    return _panel(rows, r["verdict"])


def outside(f: Any) -> Any:
    """Put the figure's legend above its frame, in one row: outside the data, and the
    frame keeps the width of the figures it is aligned with."""
    legend = f.legend[0]
    f.center = [r for r in f.center if r is not legend]
    legend.update(orientation="horizontal", label_text_font_size="9px", padding=2,
                  spacing=8, margin=0, glyph_width=16, border_line_alpha=0)
    f.add_layout(legend, "above")
    return f


class Explorer:
    """One browser session: its widgets, figures, sources and callbacks."""

    def __init__(self, doc: Any = None, controls: Controls | None = None,
                 loop: tuple[Any, str] | None = None, robot_page: Any = None):
        self.doc = doc
        self.robot_page = robot_page  # (doc, file name, bytes) -> the robot page, or None
        self.loop: tuple[Any, str] | None = None
        self.loop_sliders: dict[str, Slider] = {}
        self.loop_values: dict[str, float] = {}
        self.last_results: dict[str, Any] = {}
        self.actuators = dict(SEA_PRESETS)
        self.pending = False
        self.generation = 0
        self.last_ms: list[tuple[float, ...]] = []
        c = controls or Controls()
        self.sources = {k: ColumnDataSource() for k in (
            "bode", "nyquist", "impedance", "bands", "step", "impulse", "pm_map",
            "latency_map", "pm_marker", "latency_marker", "roots")}
        self.sources["exports"] = ColumnDataSource({"toml": [""], "json": [""],
                                                    "command": [""]})
        self._widgets(c)
        self._figures()
        self.buttons[2:2] = self.figure_buttons()
        if loop is not None:
            self.set_loop(*loop, request=False)
        self.update(sync=True)  # the first page has every view (no empty data sources)

    # ------------------------------------------------------------ widgets
    def _widgets(self, c: Controls) -> None:
        self.actuator = Select(title="actuator", value=c.actuator.name,
                               options=list(self.actuators), width=120)
        self.upload = FileInput(accept=".toml", title="or upload a TOML file", width=200,
                                css_classes=["seactl-actuator-file"])
        self.upload_msg = Div(text="", width=320, styles={"color": "#b00020"})
        self.sliders = {}
        for key, label in SLIDERS.items():
            lo, hi, step = BOUNDS[key]
            value = getattr(c, key)
            self.sliders[key] = Slider(title=label, start=lo, end=hi, step=step,
                                       value=lo if value is None else value, width=320,
                                       name=key, css_classes=[f"seactl-{key}"])
        self.filters = CheckboxGroup(labels=["velocity filter f_qd", "torque-derivative "
                                             "filter f_taud"], inline=True,
                                     active=[i for i, f in enumerate((c.f_qd_hz, c.f_taud_hz))
                                             if f is not None])
        self.mode = RadioButtonGroup(labels=list(MODES), active=MODES.index(c.mode))
        self.results = Div(text="", width=330)
        self.badge = Div(text="", width=330)
        self.loop_upload = FileInput(accept=".toml", title="loop file (TOML)", width=200,
                                     css_classes=["seactl-loop-file"])
        self.sea_button = Button(label="built-in SEA", width=100, visible=False)
        self.sea_button.on_click(self.leave_loop)
        self.loop_msg = Div(text="", width=320, styles={"color": "#b00020"}, visible=False)
        self.loop_box = column(width=330, visible=False)
        self.status = Div(text="", width=330, name="status")
        self.command = PreText(text="", width=330, styles={"font-size": "11px",
                                                           "white-space": "pre-wrap"})
        self.buttons = self._buttons() + [self.copy_button()]
        for w in self.sliders.values():
            w.on_change("value", self.on_change)
        self.filters.on_change("active", self.on_change)
        self.mode.on_change("active", self.on_change)
        self.actuator.on_change("value", self.on_change)
        self.upload.on_change("value", self.on_upload)
        self.loop_upload.on_change("value", self.on_loop_upload)
        self.robot_upload = FileInput(accept=".urdf", title="robot (URDF)", width=200,
                                      css_classes=["seactl-robot-file"])
        self.robot_msg = Div(text="", width=320, styles={"color": "#b00020"})
        self.robot_upload.on_change("value", self.on_robot_upload)

    def _buttons(self) -> list[Button]:
        src = self.sources["exports"]
        out = []
        for key, mime, name in (("toml", "application/toml", "seactl-design.toml"),
                                ("json", "application/json", "seactl-design.json")):
            b = Button(label=f"export {key.upper()}", width=100)
            b.js_on_event("button_click", CustomJS(args={"src": src, "key": key, "mime": mime,
                                                         "filename": name}, code=DOWNLOAD_JS))
            out.append(b)
        return out

    def figure_buttons(self) -> list[Button]:
        """``figures SVG`` and ``figures PNG``: every view in one file, laid out as on
        the page (client-side: the browser renders the figures it shows)."""
        out = []
        for fmt in ("svg", "png"):
            b = Button(label=f"figures {fmt.upper()}", width=100)
            b.js_on_event("button_click", CustomJS(args={
                "figs": self.figures, "fmt": fmt, "filename": f"seactl-explore.{fmt}"},
                code=FIGURES_JS))
            out.append(b)
        return out

    def copy_button(self) -> Button:
        """Copy the equivalent command lines to the clipboard."""
        src = self.sources["exports"]
        copy = Button(label="copy command line", width=130)
        copy.js_on_event("button_click", CustomJS(args={"src": src, "btn": copy,
                                                        "label": copy.label}, code=COPY_JS))
        return copy

    def controls(self) -> Controls | LoopControls:
        """The controls as the widgets show them (a loop file's when one is loaded)."""
        mode = MODES[self.mode.active] if self.mode.active in (0, 1) else MODES[0]
        if self.loop is not None:
            moved = tuple((k, number(float(s.value)))
                          for k, s in self.loop_sliders.items()
                          if float(s.value) != self.loop_values[k])
            return LoopControls(*self.loop, values=moved, mode=mode)
        v = {k: number(float(s.value)) for k, s in self.sliders.items()}
        for i, key in enumerate(("f_qd_hz", "f_taud_hz")):
            if i not in self.filters.active:
                v[key] = None
        actuator = self.actuators.get(self.actuator.value, next(iter(SEA_PRESETS.values())))
        return Controls(actuator=actuator, mode=mode, **v)

    # ------------------------------------------------------------ callbacks
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
        """Recompute the views from the current controls, stage by stage
        (:data:`~seactl.apps.explore.model.STAGES`): the margins, Bode, Nyquist and impedance
        at once, the responses and the maps on the next ticks unless a newer change is
        already waiting (a dragged slider computes only its latest value in full)."""
        self.pending = False
        self.generation += 1
        c = self.controls()
        self._ranges(c)
        self.run_stage(self.generation, c, 0, {}, time.perf_counter(), [], sync)

    def run_stage(self, generation: int, c: Controls, index: int, acc: dict[str, Any],
                  t0: float, marks_ms: list[float], sync: bool = False) -> None:
        """Compute and show stage ``index``, then schedule the next one."""
        if generation != self.generation or (index and self.pending):
            return  # superseded by a newer change
        loop = isinstance(c, LoopControls)
        stages, names = ((loopmodel.STAGES, loopmodel.STAGE_NAMES) if loop
                         else (STAGES, STAGE_NAMES))
        out, error = safe(stages[index], c, acc)
        if error is not None:
            self.status.text = (f"<span id='status-value' style='color:#b00020'>error: "
                                f"{html.escape(error)}</span>")
            return
        acc.update(out)
        self.apply(out, c)
        marks_ms.append((time.perf_counter() - t0) * 1e3)
        if index + 1 < len(stages):
            step = functools.partial(self.run_stage, generation, c, index + 1, acc, t0,
                                     marks_ms, sync)
            if sync or self.doc is None:
                step()
            else:
                self.doc.add_next_tick_callback(step)
            return
        self.last_ms.append(tuple(marks_ms))
        self.status.text = ("<span id='status-value'>" + ", ".join(
            f"{name} in {ms:.0f} ms" for name, ms in zip(names, marks_ms)) + "</span>")

    def _ranges(self, c: Controls | LoopControls) -> None:
        if isinstance(c, LoopControls):
            return
        lo, hi = fn_range_hz(c)
        fn = self.sliders["fn_hz"]
        if (fn.start, fn.end) != (lo, hi):
            fn.update(start=lo, end=hi)
        self.sliders["rate_hz"].disabled = c.mode != "sampled"
        for i, key in enumerate(("f_qd_hz", "f_taud_hz")):
            self.sliders[key].disabled = i not in self.filters.active

    def on_upload(self, attr: str, old: Any, new: Any) -> None:
        """Bokeh's callback of the file input: the browser sends ``value`` and
        ``filename`` in one message but they are applied one by one, so the file is read
        on the next tick, when both are set."""
        if self.doc is None:
            self.read_upload()
        else:
            self.doc.add_next_tick_callback(self.read_upload)

    def read_upload(self) -> None:
        """Load what the file input holds."""
        def prop(name: str) -> str:
            try:
                return str(getattr(self.upload, name) or "")
            except UnsetValueError:
                return ""

        self.load_upload(prop("filename") or "uploaded.toml", prop("value"))

    def load_upload(self, filename: str, value_b64: str) -> None:
        """A TOML file was chosen: validate it; a bad file only shows a message."""
        try:
            content = base64.b64decode(value_b64 or "", validate=True)
            act, table = actuator_from_upload(filename, content)
            c = controls_from_table(self.controls(), act, table)
        except Exception as exc:  # noqa: BLE001 - any bad upload is a message, never a trace
            message = html.escape(str(exc) or type(exc).__name__)
            self.upload_msg.text = f"<span id='upload-msg'>error: {message}</span>"
            return
        name = act.name if act.name not in SEA_PRESETS else f"{act.name} (uploaded)"
        self.actuators[name] = act
        self.upload_msg.text = (f"<span id='upload-msg' style='color:black'>loaded "
                                f"'{html.escape(name)}'"
                                f"{' and its design' if table else ''}</span>")
        self.set_controls(c, name)

    def set_controls(self, c: Controls, actuator_name: str) -> None:
        """Show ``c`` in the widgets (one update follows)."""
        self.actuator.options = list(self.actuators)
        self.actuator.value = actuator_name
        lo, hi = fn_range_hz(c)
        self.sliders["fn_hz"].update(start=lo, end=hi)
        for key, s in self.sliders.items():
            value = getattr(c, key)
            if value is not None:
                s.value = float(np.clip(value, s.start, s.end))
        self.filters.active = [i for i, f in enumerate((c.f_qd_hz, c.f_taud_hz))
                               if f is not None]
        self.mode.active = MODES.index(c.mode)
        self.request()

    # ------------------------------------------------------------ robots
    def on_robot_upload(self, attr: str, old: Any, new: Any) -> None:
        """The robot file input (read on the next tick, as :meth:`on_upload`)."""
        if self.doc is None:
            self.read_robot_upload()
        else:
            self.doc.add_next_tick_callback(self.read_robot_upload)

    def read_robot_upload(self) -> None:
        """Load what the robot file input holds."""
        def prop(name: str) -> str:
            try:
                return str(getattr(self.robot_upload, name) or "")
            except UnsetValueError:
                return ""

        self.load_robot_upload(prop("filename") or "robot.urdf", prop("value"))

    def load_robot_upload(self, filename: str, value_b64: str) -> None:
        """Open the robot page on an uploaded URDF (``robot_page``); a file the library
        refuses only shows its message, and the page stays."""
        try:
            content = base64.b64decode(value_b64 or "", validate=True)
            self.robot_page(self.doc, filename, content)
        except Exception as exc:  # noqa: BLE001 - any bad upload is a message, never a trace
            message = html.escape(str(exc) or type(exc).__name__)
            self.robot_msg.text = f"<span id='robot-msg'>error: {message}</span>"

    # ------------------------------------------------------------ loop files
    def on_loop_upload(self, attr: str, old: Any, new: Any) -> None:
        """The loop file input (read on the next tick, as :meth:`on_upload`)."""
        if self.doc is None:
            self.read_loop_upload()
        else:
            self.doc.add_next_tick_callback(self.read_loop_upload)

    def read_loop_upload(self) -> None:
        """Load what the loop file input holds."""
        def prop(name: str) -> str:
            try:
                return str(getattr(self.loop_upload, name) or "")
            except UnsetValueError:
                return ""

        self.load_loop_upload(prop("filename") or "loop.toml", prop("value"))

    def load_loop_upload(self, filename: str, value_b64: str) -> None:
        """A loop file was chosen: load it (:func:`seactl.load_loop`); a bad file only
        shows the loader's message, and the page keeps what it showed."""
        try:
            content = base64.b64decode(value_b64 or "", validate=True)
            loop, name = loop_from_upload(filename, content)
        except Exception as exc:  # noqa: BLE001 - any bad upload is a message, never a trace
            message = html.escape(str(exc) or type(exc).__name__)
            self.loop_msg.update(text=f"<span id='loop-msg'>error: {message}</span>",
                                 visible=True)
            return
        self.set_loop(loop, name)

    def set_loop(self, loop: Any, file_name: str, request: bool = True) -> None:
        """Show the loop file ``loop``: its variables as sliders, the SEA's controls and
        maps hidden; ``file_name`` is how the copied command line names the file."""
        self.loop = (loop, file_name)
        self.loop_sliders, self.loop_values = {}, {}
        for name, (lo, hi, step, value) in variable_sliders(loop).items():
            digits = int(np.ceil(np.log10(max(abs(lo), abs(hi), 1e-300)))
                         - np.floor(np.log10(step)) + 1)
            s = Slider(title=name, start=lo, end=hi, step=step, value=value, width=320,
                       format=PrintfTickFormatter(format=f"%.{min(max(digits, 3), 10)}g"),
                       css_classes=[f"seactl-var-{name}"])
            s.on_change("value", self.on_change)
            self.loop_sliders[name], self.loop_values[name] = s, value
        self.loop_box.children = list(self.loop_sliders.values())
        self.loop_msg.update(visible=True, text=(
            f"<span id='loop-msg' style='color:black'>loop '{html.escape(loop.name)}' from "
            f"{html.escape(file_name)}: {len(self.loop_sliders)} variables</span>"))
        self._show_kind(loop=True)
        if request:
            self.request()

    def leave_loop(self) -> None:
        """Back to the built-in SEA design."""
        self.loop = None
        self.loop_box.children = []
        self.loop_msg.update(text="", visible=False)
        self._show_kind(loop=False)
        self.request()

    def _show_kind(self, loop: bool) -> None:
        """Show the widgets and views of a loop file or of the built-in SEA."""
        sea = [self.actuator, self.upload, self.upload_msg, self.filters,
               *self.sliders.values(), *self.maps]
        for w in sea:
            w.visible = not loop
        self.sea_button.visible = self.loop_box.visible = loop
        self.paper_line.visible = self.buttons[0].visible = not loop
        for item in self.z_fig.legend[0].items:  # the paper's formula is the SEA's
            if self.paper_line in item.renderers:
                item.visible = not loop
        self.z_axis.axis_label = "|Z| [force / velocity]" if loop else "|Z| [N m s/rad]"

    def apply(self, v: dict[str, Any], c: Controls | LoopControls) -> None:
        """Copy what ``v`` holds (either phase) into the page: the numbers first (they
        are small messages), then the figures' data."""
        r = self.last_results = v["results"]
        self.results.text = results_html(r, "N m s/rad")
        self.badge.text = badge_html(r)
        self.command.text = v["exports"]["command"]
        self.sources["exports"].data = {k: [v["exports"][k]] for k in ("toml", "json",
                                                                       "command")}
        nan = float("nan")
        for key, value in (("fc", r["crossover_hz"]), ("fc_phase", r["crossover_hz"]),
                           ("f180", r["phase_crossover_hz"]),
                           ("f180_mag", r["phase_crossover_hz"])):
            self.spans[key].location = nan if value is None else value
        self._titles(c, r)
        where = f"L at break '{r['outer_break']}'" if "outer_break" in r else "outer loop L(jw)"
        self.titles["bode"].text = (f"{where}: PM {_fmt(r['phase_margin_deg'], '.1f')}"
                                    f" deg at {_fmt(r['crossover_hz'], '.3g')} Hz, GM "
                                    f"{_fmt(r['gain_margin_db'], '.1f')} dB")
        if "roots" in v:
            self._show_roots(v, r)
        for key in ("bode", "nyquist", "impedance", "bands", "step", "impulse", "pm_map",
                    "latency_map", "roots"):
            if key in v:
                self.sources[key].data = dict(v[key])
        if "pm_map" in v:
            self.sources["pm_marker"].data = {"x": [c.fn_hz], "y": [c.gs]}
            self.sources["latency_marker"].data = {"x": [c.t_qd_ms], "y": [c.t_qs_ms]}

    def _titles(self, c: Controls | LoopControls, r: dict[str, Any]) -> None:
        """The responses' titles: the SEA's, or the loop file's signals and units."""
        if not isinstance(c, LoopControls):
            self.titles["impedance"].text = "impedance Z(jw) at the joint"
            for k, text in self.sea_titles.items():
                self.titles[k].text = text
            return
        port = r.get("port")
        self.titles["impedance"].text = (f"impedance Z(jw) at port '{port}'" if port
                                         else "impedance: the file declares no [[ports]]")
        sig = c.loop.compiled.model.signals
        self.titles["step"].text = (f"step response {sig.output} / {sig.reference} (step of "
                                    f"{c.loop.default_step:g} {c.loop.step_unit})")
        self.titles["impulse"].text = (
            f"impulse response {sig.output} ({c.loop.default_impulse:g} on {sig.disturbance})"
            if sig.disturbance else "impulse response: the file declares no disturbance")

    def _show_roots(self, v: dict[str, Any], r: dict[str, Any]) -> None:
        """The roots view's ranges and title (the spectral abscissa and the verdict's
        stability word, which the margins' Nyquist count gives)."""
        (x0, x1), (y0, y1) = v["roots_range"]["x"], v["roots_range"]["y"]
        self.roots_fig.x_range.update(start=x0, end=x1)
        self.roots_fig.y_range.update(start=y0, end=y1)
        word = "stable" if r["stable"] else "UNSTABLE"
        self.titles["roots"].text = (f"rightmost roots: spectral abscissa "
                                     f"{r['spectral_abscissa_per_s']:.4g} 1/s ({word})")

    # ------------------------------------------------------------ figures
    def _figures(self) -> None:
        s = self.sources
        self.spans = {k: Span(location=float("nan"), dimension="height", line_dash="dashed",
                              line_color=color)
                      for k, color in (("fc", "green"), ("fc_phase", "green"),
                                       ("f180", "firebrick"), ("f180_mag", "firebrick"))}
        mag = figure(x_axis_type="log", title="outer loop L(jw)", y_axis_label="|L| [dB]",
                     **FIG)
        mag.line("f_hz", "mag_db", source=s["bode"], line_width=2, legend_label="|L|")
        for label, color in (("crossover", "green"), ("phase crossover", "firebrick")):
            mag.line([math.nan], [math.nan], line_dash="dashed", line_color=color,
                     legend_label=label)  # the spans' legend entries (no data drawn)
        mag.add_layout(Span(location=0, dimension="width", line_color="gray"))
        mag.add_layout(self.spans["fc"])
        mag.add_layout(self.spans["f180_mag"])
        outside(mag)
        phase = figure(x_axis_type="log", x_range=mag.x_range, x_axis_label="f [Hz]",
                       y_axis_label="phase [deg]", title="phase of L (same frequency axis)",
                       **FIG)
        phase.line("f_hz", "phase_deg", source=s["bode"], line_width=2)
        phase.add_layout(Span(location=-180, dimension="width", line_color="gray"))
        phase.add_layout(self.spans["fc_phase"])
        phase.add_layout(self.spans["f180"])
        self.titles = {"bode": mag.title}
        self.roots_fig = self._roots()
        self.titles["roots"] = self.roots_fig.title
        self.maps = [self._pm_map(), self._latency_map()]
        self.bode = (mag, phase)
        # two columns: the magnitude above the phase (one frequency axis), each row's
        # second view beside them
        self.figures = [mag, self._nyquist(), phase, self.roots_fig, self._impedance(),
                        *self._responses(), *self.maps]

    def _nyquist(self) -> Any:
        f = figure(title="Nyquist of L (|L| <= 20), -1 point", x_range=(-3, 1.5),
                   y_range=(-2.2, 2.2), x_axis_label="Re L", y_axis_label="Im L", **FIG)
        th = np.linspace(0, 2 * np.pi, 181)
        f.line(np.cos(th), np.sin(th), line_color="lightgray", line_dash="dotted",
               legend_label="|L| = 1")
        f.line("re", "im", source=self.sources["nyquist"], line_width=2, legend_label="L(jw)")
        f.scatter([-1], [0], marker="x", size=14, line_width=3, color="firebrick",
                  legend_label="-1")
        return outside(f)

    def _roots(self) -> Any:
        f = figure(title="rightmost roots", x_range=Range1d(-300, 30),
                   y_range=Range1d(-400, 400), x_axis_label="Re s [1/s]",
                   y_axis_label="Im s [rad/s]", **FIG)
        f.add_layout(Span(location=0, dimension="height", line_color="firebrick",
                          line_width=2))  # the imaginary axis: stability boundary
        f.add_layout(Span(location=0, dimension="width", line_color="gray"))
        pts = f.scatter("re", "im", source=self.sources["roots"], marker="x", size=12,
                        line_width=3)
        f.add_tools(HoverTool(renderers=[pts], tooltips=[
            ("s", "@re{0.00} + j @im{0.00} rad/s"), ("f [Hz]", "@f_hz{0.00}"),
            ("damping ratio", "@zeta{0.000}")]))
        return f

    def _impedance(self) -> Any:
        s = self.sources
        f = figure(x_axis_type="log", y_axis_type="log", x_axis_label="f [Hz]",
                   y_axis_label="|Z| [N m s/rad]",
                   title="impedance Z(jw) at the joint", **FIG)
        f.quad(left="left", right="right", bottom=1e-9, top=1e9, source=s["bands"],
               fill_color="orange", fill_alpha=0.25, line_alpha=0)
        bd = f.line("f_hz", "block_diagram", source=s["impedance"], line_width=2,
                    legend_label="block diagram")
        pa = f.line("f_hz", "paper", source=s["impedance"], line_width=2, line_dash="dashed",
                    color="black", legend_label="paper's formula")
        f.quad(left=[math.nan], right=[math.nan], bottom=[math.nan], top=[math.nan],
               fill_color="orange", fill_alpha=0.25, line_alpha=0,
               legend_label="Re Z < 0")  # the shaded bands' legend entry (no data drawn)
        self.paper_line, self.z_axis, self.z_fig = pa, f.yaxis[0], f
        self.titles["impedance"] = f.title
        f.y_range = DataRange1d(renderers=[bd, pa])
        return outside(f)

    def _responses(self) -> list[Any]:
        step = figure(title=f"step response q_j / q_des (step of {sc.Design.default_step:g} "
                      f"{sc.Design.step_unit})", x_axis_label="t [ms]", **FIG)
        step.line("t_ms", "y", source=self.sources["step"], line_width=2)
        step.add_layout(Span(location=1, dimension="width", line_color="gray"))
        imp = figure(title="impulse response q_j [deg] (0.05 N m s)", x_axis_label="t [ms]",
                     **FIG)
        imp.line("t_ms", "y", source=self.sources["impulse"], line_width=2)
        self.titles.update(step=step.title, impulse=imp.title)
        self.sea_titles = {k: self.titles[k].text for k in ("step", "impulse")}
        return [step, imp]

    def _map(self, title: str, src: str, marker: str, **kw: Any) -> Any:
        mapper = LinearColorMapper(palette="Viridis256", low=0, high=90, nan_color="#dddddd")
        f = figure(title=title, **{**FIG, "width": 430}, **kw)
        cells = f.quad(left="left", right="right", bottom="bottom", top="top",
                       source=self.sources[src], line_alpha=0,
                       fill_color={"field": "pm", "transform": mapper})
        f.scatter("x", "y", source=self.sources[marker], marker="circle_cross", size=14,
                  fill_color="white", line_color="red", line_width=2)
        f.add_tools(HoverTool(renderers=[cells], tooltips=[("x", "@x{0.00}"),
                                                           ("y", "@y{0.00}"),
                                                           ("PM [deg]", "@pm{0.0}")]))
        f.add_layout(ColorBar(color_mapper=mapper, width=8, title="PM"), "right")
        return f

    def _pm_map(self) -> Any:
        f = self._map("PM over (f_n, GS); grey: unstable", "pm_map", "pm_marker",
                         y_axis_type="log", x_axis_label="f_n [Hz]", y_axis_label="GS",
                         y_range=(float(PM_MAP_GS[0]) * 0.88, float(PM_MAP_GS[-1]) * 1.13))
        f.yaxis.ticker = FixedTicker(ticks=[0.2, 0.5, 1, 2, 5])
        return f

    def _latency_map(self) -> Any:
        return self._map("latency map: PM over delays; grey: unstable", "latency_map",
                         "latency_marker", x_axis_label="T_qd damping delay [ms]",
                         y_axis_label="T_qs stiffness delay [ms]")

    # ------------------------------------------------------------ layout
    def layout(self) -> Any:
        """The whole page: the verdict badge, controls and results on the left, the views
        right (the maps only for the built-in SEA)."""
        s = self.sliders
        head = Div(text="<h3 style='margin:0'>seactl explore</h3>", width=320)
        controls = column(
            head, self.badge, row(self.loop_upload, self.sea_button), self.loop_msg,
            *((self.robot_upload, self.robot_msg) if self.robot_page else ()),
            self.loop_box, row(self.actuator, self.upload), self.upload_msg,
            *(s[k] for k in ("fn_hz", "gs", "zeta1", "zeta2", "ratio", "t_tau_ms", "t_qs_ms",
                             "t_qd_ms")),
            self.filters, s["f_qd_hz"], s["f_taud_hz"], self.mode, s["rate_hz"],
            self.status, self.results, row(*self.buttons[:2], self.buttons[-1]),
            row(*self.buttons[2:-1]), self.command)
        grid = gridplot(self.figures, ncols=2, toolbar_location="right")
        return row(controls, grid)


def make_document(doc: Any, loop: tuple[Any, str] | None = None,
                  robot_page: Any = None) -> None:
    """Bokeh application entry: one :class:`Explorer` per browser session (``loop``: a
    loop file to start with, ``(UserLoop, file name)``; ``robot_page``: what opens the
    robot page on an uploaded URDF, ``(doc, file name, bytes)``)."""
    explorer = Explorer(doc, loop=loop, robot_page=robot_page)
    doc.title = "seactl explore"
    doc.add_root(explorer.layout())
