"""``seactl explore``: the callbacks' pure core, the Bokeh callbacks, the command, and a
real browser moving a slider.

Oracles: the ``seactl gains --json`` command the app offers to copy (the CLI path), the
library's own latency map (:func:`seactl.latency_map`, a separate split diagram),
python-control's ``margin`` on the exported exact-delay FRD (its own crossing search),
and, in the browser test, :func:`seactl.design` evaluated in the test process.
"""

from __future__ import annotations

import base64
import json
import os
import select
import shlex
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import seactl as sc
from browser import headless_chromium
from seactl.apps.cli import main
from seactl.errors import InputError

pytest.importorskip("bokeh", reason="the explorer needs the app extra (bokeh)")

from seactl.apps.explore import model  # noqa: E402
from seactl.apps.explore.model import Controls  # noqa: E402

TABLE_I = Controls()  # f_n 14 Hz, delays (0.5, 2, 0.5) ms, filters (50, 100) Hz
README_TOML = b"""name = "my-sea"
motor_inertia = 0.225
joint_inertia = 0.014
motor_damping = 1.375
joint_damping = 0.1
spring_stiffness = 218.75
current_to_torque = 5.2025
"""


@pytest.fixture(scope="module")
def table_i_views():
    return model.views(TABLE_I)


# ------------------------------------------------------------------ pure core
def test_results_match_the_command_line_the_app_offers(table_i_views, capsys):
    """Oracle: ``seactl gains --json`` run on the exported command line."""
    r = table_i_views["results"]
    gains_line = table_i_views["exports"]["command"].splitlines()[0]
    assert main(shlex.split(gains_line)[1:] + ["--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    for key in ("Kq", "Bq", "Ktau", "Btau", "phase_margin_deg", "crossover_hz",
                "gain_margin_db", "delay_margin_ms", "stable"):
        assert r[key] == pytest.approx(row[key], rel=1e-9), key
    assert round(r["phase_margin_deg"], 2) == 43.26  # Table I, f_n = 14 Hz


def test_jitter_margins_are_the_library_ones_and_below_the_delay_margin(table_i_views):
    """Oracle: ``d.jitter_margins()``; a constant delay is one of the variations a jitter
    margin admits, so it cannot exceed the constant-delay margin (Kao & Lincoln 2004)."""
    r = table_i_views["results"]
    j = TABLE_I.design().jitter_margins()
    for loop, prefix in (("overall", ""), ("stiffness", "stiffness_"), ("damping", "damping_"),
                         ("torque", "torque_")):
        jitter_ms = float(getattr(j, f"{prefix}jitter_margin_s")) * 1e3
        assert r[f"{loop}_jitter_margin_ms"] == pytest.approx(jitter_ms, rel=1e-9)
    assert r["overall_jitter_margin_ms"] <= r["delay_margin_ms"]
    assert "jitter margins" in r["verdict"]


def test_bode_view_agrees_with_python_control_margin(table_i_views):
    """Oracle: python-control's ``margin`` on the exact-delay FRD (its own search)."""
    import control as ct

    frd = TABLE_I.design().to_control("frd", f_hz=np.geomspace(1, 100, 20000))
    _, pm, _, wc = ct.margin(frd)
    r = table_i_views["results"]
    assert r["phase_margin_deg"] == pytest.approx(pm, abs=0.02)
    assert r["crossover_hz"] == pytest.approx(wc / (2 * np.pi), rel=1e-3)
    bode = table_i_views["bode"]  # the drawn |L| crosses 0 dB at the marked crossover
    assert np.interp(np.log(r["crossover_hz"]), np.log(bode["f_hz"]),
                     bode["mag_db"]) == pytest.approx(0.0, abs=0.05)


def test_latency_map_is_the_library_latency_map_at_gs_1():
    """Oracle: :func:`seactl.latency_map` (stiffness/damping split diagram)."""
    ms = model.LAT_MAP_MS[::2]
    lib = sc.latency_map(14.0, ms, ms, torque_delay_ms=0.5, filters_hz=(50, 100)).map
    cells = model.latency_map(model._latency_key(TABLE_I))
    pm = cells["pm"].reshape(model.LAT_MAP_MS.size, -1)[::2, ::2]  # [i_qd, i_qs]
    expect = np.where(lib.stable, lib.phase_margin_deg, np.nan).T
    np.testing.assert_allclose(pm, expect, atol=1e-6)


@pytest.mark.parametrize("delays_ms", [(0.5, 2.0, 0.5), (0.5, 15.0, 10.0), (0.5, 2.0, 10.0)])
def test_roots_view_is_the_library_roots_and_agrees_with_the_stability_word(delays_ms):
    """Oracle: ``d.roots()`` on the same design (the public API, called here), and the
    Nyquist count of ``d.margins()`` behind the word 'stable' / 'UNSTABLE' (a different
    method: the argument principle on the frequency response, not the roots)."""
    from seactl.apps.explore.app import results_html

    c = replace(TABLE_I, t_tau_ms=delays_ms[0], t_qs_ms=delays_ms[1], t_qd_ms=delays_ms[2])
    v = model.views(c)
    lib = c.design().roots(count=model.ROOTS_COUNT)
    z = np.reshape(lib.roots, -1)
    z = z[np.isfinite(z)]
    shown = np.sort_complex(v["roots"]["re"] + 1j * v["roots"]["im"])
    expect = np.sort_complex(np.concatenate([z, np.conj(z[z.imag > 0])]))
    np.testing.assert_allclose(shown, expect, rtol=1e-12)
    sa = float(np.reshape(lib.spectral_abscissa, -1)[0])
    r = v["results"]
    assert r["spectral_abscissa_per_s"] == pytest.approx(sa, rel=1e-12)
    assert r["stable"] == (sa < 0)
    word = "stable" if sa < 0 else "UNSTABLE"
    assert f"<td id='stable-value' style='text-align:right'><b>{word}</b>" in \
        results_html(r, "N m s/rad")
    x0, x1 = v["roots_range"]["x"]
    assert x0 < min(0.0, shown.real.min()) and x1 > max(0.0, shown.real.max())  # jw axis


def test_maps_are_cached_and_reused_across_updates():
    a = model.views(replace(TABLE_I, gs=1.5))
    b = model.views(replace(TABLE_I, gs=2.0))  # GS moves the marker, not the PM map
    assert a["pm_map"] is b["pm_map"]
    assert a["latency_map"] is not b["latency_map"]


def test_unstable_and_infeasible_designs_are_words_not_errors():
    v, err = model.safe_views(replace(TABLE_I, t_qs_ms=15.0, t_qd_ms=10.0))
    assert err is None and not v["results"]["stable"]
    assert v["results"]["verdict"].startswith("Unstable")
    v, err = model.safe_views(replace(TABLE_I, fn_hz=5.0))
    assert v is None and "feasible: f_n >= 9.456 Hz" in err
    v, err = model.safe_views(replace(TABLE_I, t_qs_ms=-1.0))
    assert v is None and "T_qs" in err


def test_sampled_mode_reaches_the_command_line():
    v = model.views(replace(TABLE_I, mode="sampled", rate_hz=500.0, f_qd_hz=None))
    step = v["exports"]["command"].splitlines()[1]
    assert step.endswith("--mode sampled --rate 500") and "--f-qd" not in step
    assert "--amplitude 0.01 --t-end" in step
    assert v["step"]["t_ms"][-1] == pytest.approx(model.t_end_s(14.0) * 1e3, abs=2.0)  # 1/rate


@pytest.mark.parametrize("mode", ["continuous", "sampled"])
def test_step_is_the_one_of_the_command_line_the_app_offers(mode, capsys):
    """Oracle: ``seactl step --json`` run on the exported command line (the CLI's own
    simulation path): same amplitude, same overshoot.  Sampled at 1 kHz the 30 A current
    limit is what a 1 rad step would hit, so the amplitude decides the answer there."""
    v = model.views(replace(TABLE_I, mode=mode))
    r = v["results"]
    step_line = v["exports"]["command"].splitlines()[1]
    assert main(shlex.split(step_line)[1:] + ["--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert r["step_amplitude_rad"] == cli["amplitude_rad"] == sc.Design.default_step == 0.01
    assert r["step_overshoot_pct"] == pytest.approx(cli["metrics"]["overshoot_pct"], rel=1e-9)
    assert f"Step of {sc.Design.default_step:g} rad" in r["verdict"]
    assert r.get("step_verdict", cli["verdict"]) == cli["verdict"]   # sampled: same verdict


def test_sampled_step_shows_the_sampled_loop_verdict():
    # Oracle: the library's certified verdict of the same loop (Design.margins(rate_hz)).
    from seactl.apps.explore import app

    c = replace(TABLE_I, mode="sampled", rate_hz=190.0)   # the page simulates >= 20 samples
    v = model.views(c)
    lib = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                    filters_hz=(50, 100)).margins(rate_hz=190)
    assert v["results"]["sampled_verdict"] == str(lib.verdict) == "unstable"
    assert "stable in continuous time, UNSTABLE sampled at 190 Hz" in v["results"]["verdict"]
    assert "unstable at 190 Hz" in app.results_html(v["results"], "N m s/rad")


def test_upload_actuator_file_and_errors():
    act, table = model.actuator_from_upload("my-sea.toml", README_TOML)
    assert (act.name, act.spring_stiffness, table) == ("my-sea", 218.75, {})
    bad = README_TOML.replace(b"0.014", b"-0.014")
    with pytest.raises(InputError, match="joint_inertia.*> 0"):
        model.actuator_from_upload("bad.toml", bad)
    with pytest.raises(InputError, match="TOML"):
        model.actuator_from_upload("bad.toml", b"motor_inertia = = 1")
    with pytest.raises(InputError, match="TOML"):
        model.actuator_from_upload("bad.toml", b"\xff\xfe")
    with pytest.raises(InputError, match="at most 64 kB"):
        model.actuator_from_upload("big.toml", b"#" * 70_000)


def test_exported_toml_uploads_back_to_the_same_controls():
    act, _ = model.actuator_from_upload("my-sea.toml", README_TOML)
    c = replace(TABLE_I, actuator=act, fn_hz=20.0, gs=1.5, f_taud_hz=None, mode="sampled")
    text = model.views(c)["exports"]["toml"]
    act2, table = model.actuator_from_upload("seactl-design.toml", text.encode())
    assert model.controls_from_table(TABLE_I, act2, table) == c
    assert json.loads(model.views(c)["exports"]["json"])["design"]["f_taud_hz"] is None


# ------------------------------------------------------------------ Bokeh callbacks
def test_callbacks_update_the_page_and_survive_a_bad_upload():
    from seactl.apps.explore.app import Explorer

    ex = Explorer()  # no document: requests update synchronously
    assert ">43.26<" in ex.results.text
    assert ex.titles["roots"].text == ("rightmost roots: spectral abscissa -39.85 1/s "
                                       "(stable)")  # the RootsResult docstring's value
    assert len(ex.sources["roots"].data["re"]) >= 3
    ex.sliders["fn_hz"].value = 16.0
    expect = sc.design(16.0, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                       filters_hz=(50, 100)).margins()
    assert f">{float(expect.phase_margin_deg):.2f}<" in ex.results.text
    ex.filters.active = [1]  # no velocity filter
    assert ex.sliders["f_qd_hz"].disabled and "--f-qd" not in ex.command.text
    bad = README_TOML.replace(b"0.014", b"-1")
    ex.load_upload("broken.toml", base64.b64encode(bad).decode())
    assert ">error: invalid joint_inertia = -1" in ex.upload_msg.text
    assert "Traceback" not in ex.upload_msg.text
    ex.load_upload("broken.toml", "not base64!")
    assert ">error: " in ex.upload_msg.text
    ex.load_upload("my-sea.toml", base64.b64encode(README_TOML).decode())
    assert ex.actuator.value == "my-sea" and "my-sea.toml" in ex.command.text
    opened = []
    ex.robot_page = lambda doc, name, content: opened.append((name, content))
    ex.load_robot_upload("arm.urdf", base64.b64encode(b"<robot/>").decode())
    assert opened == [("arm.urdf", b"<robot/>")]  # the robot page gets the file's bytes
    ex.load_robot_upload("arm.urdf", "not base64!")
    assert ">error: " in ex.robot_msg.text and "Traceback" not in ex.robot_msg.text
    assert len(ex.last_ms) >= 4 and max(m[-1] for m in ex.last_ms) < 5000  # see README
    assert all(len(m) == len(model.STAGES) for m in ex.last_ms)


class _QueueDoc:
    """A document stand-in whose next-tick callbacks run only when the test says so."""

    def __init__(self):
        self.queue = []

    def add_next_tick_callback(self, callback):
        self.queue.append(callback)

    def run(self):
        while self.queue:
            self.queue.pop(0)()


def test_a_dragged_slider_is_computed_once_for_its_latest_value():
    """Changes arriving before the update runs are merged; stale stages are dropped."""
    from seactl.apps.explore.app import Explorer

    doc = _QueueDoc()
    ex = Explorer(doc)
    doc.run()
    ex.last_ms.clear()
    for fn in (15.0, 15.5, 16.0, 16.5):
        ex.sliders["fn_hz"].value = fn
    assert len(doc.queue) == 1  # one update scheduled for four changes
    doc.queue.pop(0)()  # stage 1 for f_n = 16.5; stages 2 and 3 are now queued
    ex.sliders["fn_hz"].value = 17.0  # a newer change supersedes them
    doc.run()
    assert len(ex.last_ms) == 1 and ">17<" in ex.results.text
    expect = sc.design(17.0, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                       filters_hz=(50, 100)).margins()
    assert f">{float(expect.phase_margin_deg):.2f}<" in ex.results.text


# ------------------------------------------------------------------ the command
@pytest.mark.parametrize("args, needle", [
    ("explore --host 0.0.0.0", "invalid --host = '0.0.0.0': must be a loopback address"),
    ("explore --host 192.168.1.4 --port 8000", "pass --allow-remote"),
    ("explore --port 70000", "invalid --port = 70000"),
])
def test_explore_refuses_bad_addresses(args, needle, capsys):
    assert main(args.split()) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1 and err.startswith("error:")


def test_explore_refuses_a_port_in_use():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        r = subprocess.run([sys.executable, "-c", "from seactl.apps.cli import run; run()",
                            "explore", "--port", str(port), "--no-browser"],
                           capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith(f"error: invalid --port = {port}: must be a free port")


def test_ctrl_c_stops_the_explorer_with_status_130(server):
    """Oracle: the shell's convention for a command ended by SIGINT (128 + 2)."""
    _, proc = server
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) == 130
    assert proc.stdout.read().strip() == "interrupted"


def test_loopback_addresses_and_allow_remote():
    """Oracle: the loopback range 127.0.0.0/8 and ::1 (RFC 1122, RFC 4291)."""
    from seactl.apps.commands.explore import check_address
    from seactl.apps.explore.server import is_loopback, url

    assert all(map(is_loopback, ("127.0.0.1", "127.3.2.1", "::1", "[::1]", "LOCALHOST")))
    assert not any(map(is_loopback, ("0.0.0.0", "::", "10.0.0.1", "example.org", "")))
    check_address("0.0.0.0", 8000, allow_remote=True)  # allowed, only with the flag
    assert url("::1", 5006) == "http://[::1]:5006/"


# ------------------------------------------------------------------ real browser

FIND_JS = """
function deep(root, sel, out) {
  root.querySelectorAll(sel).forEach(e => out.push(e));
  root.querySelectorAll('*').forEach(e => { if (e.shadowRoot) deep(e.shadowRoot, sel, out); });
  return out;
}
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def server():
    """``seactl explore`` in its own process group on a free loopback port; the whole
    group is killed at teardown."""
    port = _free_port()
    proc = subprocess.Popen(
        [sys.executable, "-c", "from seactl.apps.cli import run; run()", "explore", "--port",
         str(port), "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # (even from a
    # shell's background job, which ignores SIGINT: Ctrl-C then reaches Python)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 180)  # warm-up, then it listens
        line = proc.stdout.readline() if ready else ""
        assert "serving on" in line, f"server did not start: {line!r}"
        yield f"http://127.0.0.1:{port}/", proc
    finally:
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(proc.pid, sig)
                proc.wait(timeout=10)
                break
            except ProcessLookupError:
                break
            except subprocess.TimeoutExpired:
                continue
        proc.stdout.close()


@pytest.fixture
def browser(tmp_path):
    prefs = {  # several downloads without a prompt
        "download.default_directory": str(tmp_path),
        "profile.default_content_setting_values.automatic_downloads": 1}
    with headless_chromium(1400, 1100, prefs=prefs) as driver:
        yield driver


def _text(driver, element_id: str) -> str | None:
    return driver.execute_script(
        FIND_JS + "const e = deep(document, '#' + arguments[0], []);"
        "return e.length ? e[0].textContent : null;", element_id)


def _wait(predicate, timeout_s: float = 30.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError("timed out")


@pytest.mark.slow  # (a browser and a server per test; the callbacks: above)
def test_browser_slider_moves_the_displayed_phase_margin(server, browser):
    """Oracle: sc.design(...).margins() in this process, for the f_n the page shows."""
    from selenium.webdriver.common.keys import Keys

    url, _ = server
    browser.get(url)
    before = _wait(lambda: _text(browser, "pm-value"))
    assert before == "43.26" and _text(browser, "fn-value") == "14"
    handle = browser.execute_script(
        FIND_JS + "return deep(document, '.seactl-fn_hz', [])[0]"
        ".shadowRoot.querySelector('.noUi-handle');")
    browser.execute_script(  # time the change in the page itself
        FIND_JS + "const el = deep(document, '#pm-value', [])[0]; const root = "
        "el.getRootNode(); window.__pmChanged = null; new MutationObserver(() => {"
        "if (window.__pmChanged === null && root.querySelector('#pm-value') &&"
        " root.querySelector('#pm-value').textContent !== arguments[0])"
        " window.__pmChanged = performance.now(); }).observe(root, {subtree: true,"
        " childList: true, characterData: true}); window.__t0 = performance.now();",
        before)
    for _ in range(5):
        handle.send_keys(Keys.ARROW_RIGHT)
    _wait(lambda: _text(browser, "fn-value") == "14.5")
    fn = float(_text(browser, "fn-value"))
    expect = sc.design(fn, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                       filters_hz=(50, 100)).margins()
    shown = _wait(lambda: (t := _text(browser, "pm-value")) != before and t)
    assert shown == f"{float(expect.phase_margin_deg):.2f}"
    latency = browser.execute_script("return window.__pmChanged - window.__t0;")
    status = _text(browser, "status-value")
    print(f"\nbrowser: first PM change {latency:.0f} ms after the key press; {status}")



def _click(driver, label: str) -> None:
    driver.execute_script(FIND_JS + "deep(document, 'button', []).find("
                          "b => b.textContent.trim() === arguments[0]).click();", label)


@pytest.mark.slow  # (a browser and a server per test; the callbacks: above)
def test_browser_upload_export_and_copy(server, browser, tmp_path):
    """A bad upload shows the library's message; a good one changes the design to the
    one :func:`seactl.design` computes for that file (oracle); the JSON export downloads
    what is shown; the copy button hands the command lines to the clipboard (stubbed:
    headless Chromium has none)."""
    browser.get(server[0])
    _wait(lambda: "maps in" in (_text(browser, "status-value") or ""))
    file_input = _file_input(browser, "seactl-actuator-file")
    (tmp_path / "bad.toml").write_bytes(README_TOML.replace(b"0.014", b"-0.014"))
    file_input.send_keys(str(tmp_path / "bad.toml"))
    msg = _wait(lambda: _text(browser, "upload-msg"))
    assert msg.startswith("error: invalid joint_inertia = -0.014: must be > 0")
    (tmp_path / "my-sea.toml").write_bytes(README_TOML.replace(b"218.75", b"400.0"))
    file_input.send_keys(str(tmp_path / "my-sea.toml"))  # a stiffer spring than the UT-SEA
    _wait(lambda: _text(browser, "upload-msg") == "loaded 'my-sea'")
    expect = sc.design(14, actuator=tmp_path / "my-sea.toml",
                       delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                       filters_hz=(50, 100)).margins()
    shown = _wait(lambda: (t := _text(browser, "pm-value")) != "43.26" and t)
    assert shown == f"{float(expect.phase_margin_deg):.2f}"
    _wait(lambda: "maps in" in (_text(browser, "status-value") or ""))
    _click(browser, "export JSON")
    path = tmp_path / "seactl-design.json"
    _wait(lambda: path.is_file() and path.stat().st_size > 0)
    doc = json.loads(path.read_text())
    assert f"{doc['results']['phase_margin_deg']:.2f}" == shown
    assert doc["design"]["fn_hz"] == 14.0 and doc["actuator"]["name"] == "my-sea"
    for fmt, header in (("svg", b"<?xml"), ("png", b"\x89PNG\r\n\x1a\n")):
        _click(browser, f"figures {fmt.upper()}")
        fig = tmp_path / f"seactl-explore.{fmt}"
        _wait(lambda fig=fig: fig.is_file() and fig.stat().st_size > 1000)
        assert fig.read_bytes().startswith(header), fmt
    svg = (tmp_path / "seactl-explore.svg").read_text()
    assert svg.count("<svg") == 1 + 9 and "rightmost roots" in svg and "<text" in svg
    import xml.etree.ElementTree as ET

    ET.fromstring(svg.encode())  # well-formed XML
    browser.execute_script("window.__copied = null; navigator.clipboard.writeText = "
                           "t => { window.__copied = t; return Promise.resolve(); };")
    _click(browser, "copy command line")
    copied = _wait(lambda: browser.execute_script("return window.__copied;"))
    assert copied.splitlines()[0].startswith("seactl gains --actuator my-sea.toml --fn 14 ")
    _browser_loop_file(browser, tmp_path)


def _file_input(driver, css_class: str):
    return driver.execute_script(FIND_JS + "return deep(document, '.' + arguments[0], [])[0]"
                                 ".shadowRoot.querySelector('input[type=file]');", css_class)


def _browser_loop_file(browser, tmp_path) -> None:
    """The loop-file control: a bad file shows the loader's message; a good one turns
    the page to the loop (oracle: ``sc.load_loop(...).margins()`` in this process) and
    the badge is green; its colour is the page's, read from the browser."""
    loop_input = _file_input(browser, "seactl-loop-file")
    (tmp_path / "broken-loop.toml").write_text("name = 'x'\n[[blocks]]\nname = 'a'\n")
    loop_input.send_keys(str(tmp_path / "broken-loop.toml"))
    msg = _wait(lambda: _text(browser, "loop-msg"))
    assert msg.startswith("error: broken-loop.toml: block 'a'") and "Traceback" not in msg
    path = tmp_path / "two-mass-notch.toml"
    path.write_bytes((Path(__file__).parents[1] / "examples/loops/two-mass-notch.toml")
                     .read_bytes())
    loop_input.send_keys(str(path))
    _wait(lambda: (_text(browser, "loop-msg") or "").startswith("loop 'two-mass-notch'"))
    expect = f"{float(sc.load_loop(path).margins()['position'].margins.phase_margin_deg):.2f}"
    _wait(lambda: _text(browser, "pm-value") == expect)
    assert _text(browser, "badge-stability") == "stable (continuous)"
    colour = browser.execute_script(FIND_JS + "const e = deep(document, '#badge-stability',"
                                    " [])[0]; return getComputedStyle(e).backgroundColor;")
    assert colour == "rgb(27, 127, 59)"  # model.BADGE_COLOURS["good"], #1b7f3b
