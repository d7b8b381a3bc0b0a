"""``seactl explore``: the verdict badge, the loop-file control, the layout, and the copied
command line run through the CLI.

Oracles: the command lines the page offers, run through ``seactl`` with ``--json`` (the
CLI's own path: ``gains``, ``step``, ``analyze --loop``), whose numbers must be the ones
the page displays; the library's verdicts called here (``margins()``, ``margins(rate_hz)``,
the step's ``verdict()``), ``Re Z`` of ``d.impedance`` on a dense grid (a second path to the
passivity badge); the comment of
``examples/loops/two-mass-notch.toml`` (``zeta_num = 0.3``: no notch, unstable).
"""

from __future__ import annotations

import base64
import json
import re
import shlex
import shutil
from pathlib import Path

import pytest

import seactl as sc
from seactl.apps.cli import main

pytest.importorskip("bokeh", reason="the explorer needs the app extra (bokeh)")

from bokeh.models import Legend  # noqa: E402

from seactl.apps.explore import loopmodel  # noqa: E402
from seactl.apps.explore.app import Explorer  # noqa: E402

LOOPS = Path(__file__).resolve().parents[1] / "examples" / "loops"
TWO_MASS = LOOPS / "two-mass-notch.toml"


OPEN_CHAIN = b"""name = "open"
variables = { K = 2.0 }
processes = { cpu = { rate_hz = 1000 } }
signals = { inputs = ["r"], reference = "r", output = "y" }
[[blocks]]
name = "c"
kind = "gain"
input = "r"
output = "y"
gain = "K"
"""


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode()


def _shown(ex: Explorer, element_id: str) -> str:
    """The text of the page element ``element_id`` (results panel or badge)."""
    text = ex.results.text + ex.badge.text
    m = re.search(rf"id='{element_id}'[^>]*>(?:<b>)?([^<]*)<", text)
    assert m, element_id
    return m.group(1)


def _run(line: str, capsys) -> dict:
    """One copied command line through the CLI with ``--json``."""
    assert line.startswith("seactl ")
    assert main(shlex.split(line)[1:] + ["--json"]) == 0, line
    return json.loads(capsys.readouterr().out)


@pytest.fixture
def loop_page(tmp_path, monkeypatch):
    """A page with the two-mass loop file uploaded (the command line names the upload;
    the CLI runs where a copy of it lies)."""
    shutil.copy(TWO_MASS, tmp_path / TWO_MASS.name)
    monkeypatch.chdir(tmp_path)
    ex = Explorer()
    ex.load_loop_upload(TWO_MASS.name, _b64(TWO_MASS.read_bytes()))
    assert ex.loop is not None and "Traceback" not in ex.loop_msg.text
    return ex


# ------------------------------------------------------------------ command line
@pytest.mark.parametrize("mode", [0, 1])
def test_loop_command_line_reproduces_the_page(loop_page, capsys, mode):
    """Oracle: ``seactl analyze --loop`` and ``seactl step --loop`` on the copied lines
    print the margins and step metrics the page displays (moved sliders as ``--set``)."""
    ex = loop_page
    ex.loop_sliders["fc"].value = 12.0
    ex.loop_sliders["zeta_den"].value = 0.36
    ex.mode.active = mode
    analyze, step = ex.command.text.splitlines()
    assert "--set fc=12 --set zeta_den=0.36" in analyze
    rows = _run(analyze, capsys)["rows"]
    r = ex.last_results
    for row, b in zip(rows, r["breaks"], strict=True):
        for key in ("phase_margin_deg", "crossover_hz", "gain_margin_db", "delay_margin_ms"):
            assert b[key] == pytest.approx(row[key], rel=1e-9), key
        assert r[f"{b['break']}_jitter_margin_ms"] == pytest.approx(row["jitter_margin_ms"],
                                                                     rel=1e-9)
    assert _shown(ex, "pm-value") == f"{rows[-1]['phase_margin_deg']:.2f}"
    assert _shown(ex, "gm-value") == f"{rows[-1]['gain_margin_db']:.2f}"
    cli = _run(step, capsys)
    assert cli["mode"] == ("continuous", "sampled")[mode]
    assert cli["amplitude"] == r["step_amplitude"] == sc.load_loop(TWO_MASS).default_step
    assert _shown(ex, "os-value") == f"{cli['metrics']['overshoot_pct']:.2f}"
    assert r["step_settling_ms"] == pytest.approx(cli["metrics"]["settling_time_s"] * 1e3,
                                                  rel=1e-9)
    assert _shown(ex, "step-verdict-value") == cli["verdict"]
    if mode:
        assert cli["sampled_loop"]["verdict"] == r["sampled_verdict"]
        assert _shown(ex, "badge-stability").startswith(f"{cli['sampled_loop']['verdict']} "
                                                        "(sampled at 4000 Hz)")


def test_sea_command_line_reproduces_a_saturated_sampled_page(capsys):
    """Oracle: ``seactl gains`` and ``seactl step`` (sampled at the page's rate, no
    filters, the page's amplitude) on the copied lines: the CLI's margins, overshoot and
    verdict are the ones displayed, and the badge says the CLI's verdict."""
    ex = Explorer()
    for key, value in (("fn_hz", 20.0), ("t_tau_ms", 0.1), ("t_qs_ms", 0.1),
                       ("t_qd_ms", 0.1), ("rate_hz", 2000.0)):
        ex.sliders[key].value = value
    ex.filters.active = []
    ex.mode.active = 1
    gains, step = ex.command.text.splitlines()
    row = _run(gains, capsys)[0]
    assert _shown(ex, "pm-value") == f"{row['phase_margin_deg']:.2f}"
    cli = _run(step, capsys)
    assert "--rate 2000" in step and "--f-qd" not in step
    assert cli["amplitude_rad"] == sc.Design.default_step
    assert _shown(ex, "os-value") == f"{cli['metrics']['overshoot_pct']:.2f}"
    assert cli["verdict"] == "saturated"
    assert _shown(ex, "badge-stability") == "saturated (sampled at 2000 Hz)"


# ------------------------------------------------------------------ badge
def test_badge_follows_the_library_verdicts():
    """Oracles: ``d.margins()`` (continuous), ``d.margins(rate_hz=190)`` (sampled) and
    ``Re Z`` from ``d.impedance`` on a dense grid (a point with ``Re Z < 0`` is not
    passive), each called here."""
    import numpy as np

    def min_re_z(d):
        return float(np.min(d.impedance(np.geomspace(0.01, 1e4, 6001)).z.real))

    ex = Explorer()
    assert _shown(ex, "badge-stability") == "stable (continuous)"
    d = ex.controls().design()
    assert min_re_z(d) < 0 and _shown(ex, "badge-passivity") == "not passive"
    ex.sliders["t_qs_ms"].value = 15.0
    ex.sliders["t_qd_ms"].value = 10.0
    assert not bool(ex.controls().design().margins().stable)
    assert _shown(ex, "badge-stability") == "unstable (continuous)"
    assert "data-tone='bad'" in ex.badge.text
    ex.sliders["t_qs_ms"].value, ex.sliders["t_qd_ms"].value = 2.0, 0.5
    ex.sliders["rate_hz"].value = 190.0
    ex.mode.active = 1
    lib = ex.controls().design().margins(rate_hz=190.0)
    assert str(lib.verdict) == "unstable" and bool(ex.controls().design().margins().stable)
    assert _shown(ex, "badge-stability") == "unstable (sampled at 190 Hz)"
    for key in ("t_tau_ms", "t_qs_ms", "t_qd_ms"):
        ex.sliders[key].value = 0.0
    ex.filters.active = []
    ex.mode.active = 0
    assert min_re_z(ex.controls().design()) > 0
    assert _shown(ex, "badge-passivity") == "passive"


def test_loop_badge_turns_red_without_the_notch(loop_page):
    """Oracle: the loop file's own comment (``zeta_num`` equal to ``zeta_den``: the notch
    is 1, no notch, and the loop is unstable) and ``sc.load_loop(...).margins().stable``.
    Both values are inside the sliders' ranges."""
    ex = loop_page
    assert _shown(ex, "badge-stability") == "stable (continuous)"
    ex.loop_sliders["zeta_den"].value = 0.2
    ex.loop_sliders["zeta_num"].value = 0.2
    assert all(s.start <= 0.2 <= s.end for s in ex.loop_sliders.values()
               if s.title.startswith("zeta"))
    assert not bool(sc.load_loop(TWO_MASS, zeta_num=0.2, zeta_den=0.2).margins().stable)
    assert _shown(ex, "badge-stability") == "unstable (continuous)"
    assert _shown(ex, "stable-value") == "UNSTABLE"


# ------------------------------------------------------------------ loop files
def test_loop_file_variables_become_sliders_and_back_to_the_sea(loop_page):
    ex = loop_page
    variables = sc.load_loop(TWO_MASS).compiled.model.variables
    assert list(ex.loop_sliders) == list(variables)
    for name, s in ex.loop_sliders.items():  # the file's value, reachable by the keyboard
        assert s.value == variables[name] and s.start < s.value < s.end
        assert (s.value - s.start) / s.step == pytest.approx(45)
    assert not any(m.visible for m in ex.maps) and not ex.sliders["fn_hz"].visible
    assert "'position'" in ex.titles["bode"].text
    ex.leave_loop()
    assert ex.loop is None and all(m.visible for m in ex.maps)
    assert ex.command.text.startswith("seactl gains --actuator ut-sea")


@pytest.mark.parametrize("content, needle", [
    (b"name = = 1", "TOML"),
    (b"name = 'x'\n[[blocks]]\nname = 'a'\nkind = 'gain'\n", "x.toml: block 'a'"),
    (b"#" * 70_000, "at most 64 kB"),
    (TWO_MASS.read_bytes().split(b"[[breaks]]")[0], "x.toml: blocks encoder"),
    (OPEN_CHAIN, "x.toml: [[breaks]]: at least one break"),  # valid, but no margins
    (b"name = 'my-sea'\nmotor_inertia = 0.225\n", "upload it beside 'actuator'"),
])
def test_bad_loop_files_are_a_message_and_the_page_stays(loop_page, content, needle):
    ex = loop_page
    before = ex.command.text
    ex.load_loop_upload("x.toml", _b64(content))
    msg = ex.loop_msg.text
    assert msg.startswith("<span id='loop-msg'>error: ") and "Traceback" not in msg
    assert needle in msg.replace("&#x27;", "'") and "/tmp" not in msg
    assert ex.command.text == before


def test_a_loop_file_given_as_an_actuator_says_where_it_goes():
    from seactl.apps.explore.model import actuator_from_upload
    from seactl.errors import InputError

    with pytest.raises(InputError, match="this is a loop file.*loop file control"):
        actuator_from_upload(TWO_MASS.name, TWO_MASS.read_bytes())


def test_explore_refuses_a_bad_loop_file_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[[blocks]]\nname = 'a'\n")
    assert main(["explore", "--no-browser", "--loop", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1 and "bad.toml" in err


def test_start_with_a_loop_file_names_it_in_the_command_line():
    ex = Explorer(loop=(sc.load_loop(TWO_MASS), str(TWO_MASS)))
    assert ex.command.text.startswith(f"seactl analyze --loop {TWO_MASS}\n")


# ------------------------------------------------------------------ layout
def test_bode_magnitude_above_phase_and_legends_outside_the_data():
    """The magnitude and the phase share one frequency range and one grid column, the
    phase one row below; no legend sits inside a frame."""
    ex = Explorer()
    grid = ex.layout().children[1]
    cells = {id(child): (r, c) for child, r, c in grid.children}
    mag, phase = ex.bode
    (r0, c0), (r1, c1) = cells[id(mag)], cells[id(phase)]
    assert (c0, r1) == (c1, r0 + 1) and phase.x_range is mag.x_range
    legends = 0
    for f in ex.figures:
        assert not any(isinstance(x, Legend) for x in f.center + f.left + f.right)
        legends += sum(isinstance(x, Legend) for x in f.above)
    assert legends == 3  # Bode magnitude, Nyquist, impedance


def test_loop_views_timing_stays_interactive(loop_page):
    """A change recomputes every stage once (the same bound as the SEA page's test)."""
    ex = loop_page
    ex.last_ms.clear()
    ex.loop_sliders["k"].value = 240.0
    assert len(ex.last_ms) == 1 and len(ex.last_ms[0]) == len(loopmodel.STAGES)
    assert ex.last_ms[0][-1] < 5000
