"""``seactl explore --robot URDF``: the robot page's numbers are the API's, its copied
command lines print them, and bad input is a one-line error.

Oracles: :func:`seactl.robot` and :func:`seactl.workspace_map` called directly in the test
(the views must not compute anything of their own), the ``seactl robot --json`` command
the page offers to copy (the CLI path), and, for the impedance view, a second derivation
of the principal values and of the Hermitian part's smallest eigenvalue of a 2 x 2 matrix
in closed form.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import replace

import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main

pytest.importorskip("bokeh", reason="the explorer needs the app extra (bokeh)")
pytest.importorskip("pinocchio", reason="robots need pinocchio (test extra)")

from seactl.apps.explore import robotmodel as rm  # noqa: E402

ARM = "examples/robots/planar_2link.urdf"
Q = (0.3, 0.8)


@pytest.fixture(scope="module")
def start():
    return rm.start_controls(ARM, q_rad=list(Q))


@pytest.fixture(scope="module")
def task_views(start):
    c = replace(start[0], space="task", task="tool", t_qs_ms=3.0)
    return c, rm.views(c)


def _direct(c):
    return sc.robot(ARM, q0=list(c.q_rad), space=c.space, task=c.task, fn_hz=c.fn_hz,
                    delays_ms={"torque": c.t_tau_ms, "stiffness": c.t_qs_ms,
                               "damping": c.t_qd_ms}, filters_hz=(c.f_qd_hz, c.f_taud_hz))


def test_start_reads_the_urdf_layout(start):
    """Oracle: the URDF file (planar_2link.urdf: joints j1, j2 limited to +-3.14 rad; the
    tool link last, the default task frame)."""
    c, info = start
    assert info.joints == ("j1", "j2") and info.limits_rad == ((-3.14, 3.14),) * 2
    assert info.links[-1] == "tool" and c.task == "tool" and c.q_rad == Q
    assert rm.start_controls(ARM, space="task")[0].task == "tool"  # no --task: the leaf
    fn = rm.start_controls(ARM)[0].fn_hz  # q = 0: no gains for j2 at 14 Hz
    sc.robot(ARM, fn_hz=fn)  # oracle: the library, on the slider's 0.1 Hz grid
    with pytest.raises(sc.InfeasibleDesignError):
        sc.robot(ARM, fn_hz=round(fn - 0.1, 1))


def test_views_are_the_api_numbers(task_views):
    """Oracle: sc.robot(...) called directly; principal values as the square roots of the
    eigenvalues of Z^H Z, and the Hermitian part's smallest eigenvalue of a 2 x 2 matrix
    in closed form (a second derivation of each)."""
    c, v = task_views
    r = _direct(c)
    m = r.margins()
    assert v["results"]["stable"] == bool(m.stable)
    assert v["results"]["phase_margin_deg"] == pytest.approx(float(m.phase_margin_deg),
                                                             rel=1e-12)
    expect = r.margins_by_break()
    assert [b["break"] for b in v["breaks"]] == list(expect)
    for b in v["breaks"]:
        e = expect[b["break"]]
        for k in rm.BREAK_COLUMNS:
            x = float(getattr(e, k))
            assert (b[k] is None and not np.isfinite(x)) or b[k] == pytest.approx(x, rel=1e-12)
    z = r.impedance_matrix(rm.F_Z_HZ)
    zz = np.einsum("fji,fjk->fik", z.conj(), z)
    sv = np.sqrt(np.sort(np.linalg.eigvalsh(zz), axis=1)[:, ::-1])
    np.testing.assert_allclose(np.array(v["principal"]["ys"]).T, sv, rtol=1e-9)
    a, d = z[:, 0, 0].real, z[:, 1, 1].real
    b = 0.5 * (z[:, 0, 1] + z[:, 1, 0].conj())
    lam = 0.5 * (a + d) - np.sqrt(0.25 * (a - d) ** 2 + np.abs(b) ** 2)
    np.testing.assert_allclose(v["hermitian_min"], lam, rtol=1e-9, atol=1e-12)
    assert v["passive"] == bool(np.all(lam >= -1e-9 * sv[:, 0]))
    st = r.step(t_end_s=rm.STEP_T_END_S)
    np.testing.assert_allclose(v["step"]["y"], np.reshape(st.position, -1), rtol=1e-12)


def test_copied_command_prints_the_page_numbers(task_views, capsys):
    """Oracle: ``seactl robot ... --json``, the command the page offers to copy."""
    c, v = task_views
    assert "--space task --task tool" in v["command"]
    assert main(shlex.split(v["command"])[1:] + ["--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["stable"] == v["results"]["stable"]
    for b in v["breaks"]:
        row = rec["breaks"][b["break"]]
        for k in rm.BREAK_COLUMNS:
            assert (row[k] is None and b[k] is None) or row[k] == pytest.approx(b[k],
                                                                                rel=1e-9)


def test_workspace_map_is_the_library_map_and_the_cli_one(start, capsys):
    """Oracle: sc.workspace_map on a grid built in the test, and ``seactl robot
    --workspace --json`` (the command shown under the map)."""
    c = replace(start[0], fn_hz=25.0)
    out = rm.map_views(c, 0, 1, 3)
    q1, q2 = np.meshgrid(Q[0] + np.array([-0.5, 0, 0.5]), Q[1] + np.array([-0.5, 0, 0.5]),
                         indexing="ij")
    grid = np.column_stack([q1.ravel(), q2.ravel()])
    m = sc.workspace_map(ARM, grid, fn_hz=25.0,
                         delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                         filters_hz=(50, 100))
    np.testing.assert_allclose(out["cells"]["x"], grid[:, 0], atol=1e-12)
    np.testing.assert_allclose(out["cells"]["pm"],
                               np.where(m.stable, m.phase_margin_deg, np.nan), rtol=1e-12)
    assert out["marker"] == {"x": [Q[0]], "y": [Q[1]]}
    assert main(shlex.split(out["command"])[1:] + ["--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["configurations"]
    np.testing.assert_allclose([r["phase_margin_deg"] for r in rows], m.phase_margin_deg,
                               rtol=1e-9)
    with pytest.raises(sc.errors.InputError, match="map points"):
        rm.map_views(c, 0, 1, 4)


def test_callbacks_follow_the_sliders_and_keep_the_page_on_bad_input(start):
    """Oracle: sc.robot at the slider's new q (``margins()``, the System's outer loop:
    the delay margin of the table's outer.j1 row)."""
    from seactl.apps.explore.robotapp import RobotExplorer

    ex = RobotExplorer(start)  # no document: each change updates synchronously
    ex.q_sliders[1].value = 1.2
    dm = float(_direct(replace(start[0], q_rad=(Q[0], 1.2))).margins().delay_margin_ms)
    assert f"id='dm-outer-j1' style='text-align:right'>{dm:.4g}<" in ex.table.text
    assert "--q0 0.3,1.2 " in ex.command.text
    assert max(sum(m[-1:]) for m in ex.last_ms) < 3000  # warm updates (docs/explore.md)
    table = ex.table.text
    ex.sliders["fn_hz"].value = 5.0  # no feasible gains for j2 at 5 Hz
    assert "error: joint &#x27;j2&#x27;" in ex.status.text and ex.table.text == table
    ex.map_points.value = "3"
    ex.on_map()   # still at 5 Hz: the library's message under the button
    assert "error: " in ex.map_msg.text and "Traceback" not in ex.map_msg.text


@pytest.mark.parametrize("args, needle", [
    ("--robot nope.urdf", "invalid --robot = 'nope.urdf': must be an existing URDF file"),
    ("--robot README.md", "must be a valid URDF file"),
    (f"--robot {ARM} --space task --task nope", "invalid --task = 'nope'"),
    (f"--robot {ARM} --q0 1,2,3", "2 finite joint angles"),
    (f"--robot {ARM} --actuators j1=ut-sea", "joint 'j2' without an actuator"),
    ("--space task", "invalid --space = 'task': must be given with --robot"),
    (f"--robot {ARM} --loop examples/loops/two-mass-notch.toml", "given without --loop"),
])
def test_bad_robot_input_is_one_line(args, needle, capsys):
    assert main(["explore", "--no-browser", *args.split()]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert needle in err and len(err.splitlines()) == 1 and err.startswith("error:")
    assert captured.out == ""


class _QueueDoc:
    """A document stand-in whose next-tick callbacks run only when the test says so."""

    def __init__(self):
        self.queue = []

    def add_next_tick_callback(self, callback):
        self.queue.append(callback)

    def run(self):
        while self.queue:
            self.queue.pop(0)()


def test_a_dragged_joint_slider_is_computed_once_for_its_latest_value(start):
    """Changes arriving before the update runs are merged; a stale second stage (the
    margins table) is dropped.  Oracle: sc.robot at the last q (``margins()``: the PM of
    the table's outer.j1 row)."""
    from seactl.apps.explore.robotapp import RobotExplorer

    doc = _QueueDoc()
    ex = RobotExplorer(start, doc)
    ex.last_ms.clear()
    for q in (0.9, 1.0, 1.1):
        ex.q_sliders[1].value = q
    assert len(doc.queue) == 1  # one update for three changes
    doc.queue.pop(0)()  # stage 1 at q2 = 1.1; the table's stage is now queued
    ex.q_sliders[1].value = 1.3  # a newer change supersedes it
    doc.run()
    assert len(ex.last_ms) == 1 and "--q0 0.3,1.3 " in ex.command.text
    pm = float(_direct(replace(start[0], q_rad=(Q[0], 1.3))).margins().phase_margin_deg)
    assert f"id='pm-outer-j1' style='text-align:right'>{pm:.2f}<" in ex.table.text


class _Doc:
    """A Bokeh document stand-in: its roots, and the session-end callbacks."""

    def __init__(self):
        self.roots, self.ended, self.title = [], [], ""

    def add_next_tick_callback(self, callback):
        callback()

    def clear(self):
        self.roots = []

    def add_root(self, root):
        self.roots.append(root)

    def on_session_destroyed(self, callback):
        self.ended.append(callback)


def test_an_uploaded_urdf_opens_the_robot_page_until_the_session_ends(tmp_path):
    """Oracle: the file itself (its joints; the command line names it as uploaded), and
    the temporary copy existing while the session lives, gone after."""
    import tempfile
    from pathlib import Path

    from seactl.apps.explore.robotapp import open_uploaded_robot

    def copies():
        return set(Path(tempfile.gettempdir()).glob("seactl-robot-*/my_arm.urdf"))

    doc, before = _Doc(), copies()
    content = Path(ARM).read_bytes()
    open_uploaded_robot(doc, "my arm.urdf", content)
    assert doc.title == "seactl explore: robot" and len(doc.roots) == 1
    c, info = rm.robot_from_upload("my arm.urdf", content, str(tmp_path))
    assert c.file_name == "my_arm.urdf" and info.joints == ("j1", "j2")
    assert rm.command_line(c).startswith("seactl robot --urdf my_arm.urdf ")
    new = copies() - before
    assert len(new) == 1 and next(iter(new)).read_bytes() == content
    for end in doc.ended:
        end(None)
    assert not any(p.exists() for p in new)
    with pytest.raises(sc.errors.SeactlError, match="'broken.urdf': must be a valid URDF"):
        open_uploaded_robot(doc, "broken.urdf", b"<robot")
