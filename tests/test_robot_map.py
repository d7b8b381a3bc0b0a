"""Workspace maps of a robot: the stiffness search's check of its assumption, the Dask
backend, trajectory files, the figure and the command line (planar 2-link arm)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio")

import seactl as sc  # noqa: E402
from seactl.api.robotmapplot import grid_axes  # noqa: E402
from seactl.api.robotstiffness import search_stiffness  # noqa: E402
from seactl.apps.cli import main  # noqa: E402
from seactl.errors import ResourceError  # noqa: E402

ARM = Path(__file__).resolve().parents[1] / "examples" / "robots" / "planar_2link.urdf"
TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 18, "damping": 0.5},
               filters_hz=(50, 100))
Q = [[0.3, 0.8], [0.0, 1.5], [-0.5, 2.2]]


@pytest.fixture(scope="module")
def joint_map():
    """The joint-space map of Q at 18 ms (unstable folded, stable stretched)."""
    return sc.workspace_map(ARM, Q, fn_hz=14, **TABLE_I)


# ------------------------------------------------------------------ the stiffness search
@pytest.mark.parametrize("stable, stretches, single", [
    # oracle: predicates whose stable sets are known in closed form
    (lambda f: f < 37.3, [(0.0, 37.3)], True),
    (lambda f: f < 0.02 or 3.0 < f < 450.0, [(0.0, 0.02), (3.0, 450.0)], False),
    (lambda f: f > 2.0, [(2.0, math.inf)], False),
    (lambda f: False, [], True),
    (lambda f: True, [(0.0, math.inf)], True),
])
def test_search_finds_every_stable_stretch(stable, stretches, single):
    """Oracle: the predicate's own boundaries; each end found within the tolerance and on
    the stable side; a verdict that does not simply flip once is flagged."""
    top, found, one = search_stiffness(stable, span=1e6, rtol=1e-3)
    assert one is single and len(found) == len(stretches)
    for (lo, hi), (lo_true, hi_true) in zip(found, stretches):
        for end, true in ((lo, lo_true), (hi, hi_true)):
            if true in (0.0, math.inf):
                assert end == true
            else:
                assert stable(end) and abs(end / true - 1) <= 1e-3
    assert top == (stretches[-1][1] if stretches else 0.0) or \
        abs(top / stretches[-1][1] - 1) <= 1e-3


def test_map_stiffness_stretches_are_what_a_dense_scan_sees():
    """Oracle: the certified verdict of sc.robot built directly with the task stiffness
    scaled half-way (in log) between the decade scan's points agrees with the stretches
    of the map (no change of verdict hidden between them); the stable end of the search is
    stable and 1e-3 above it is not."""
    opts = dict(space="task", task="tool", fn_hz=14, **TABLE_I)
    m = sc.workspace_map(ARM, [[0.0, 1.5]], **opts)
    stretches = m.stiffness_intervals_n_per_m[0]
    kx, kr = sc.robot(ARM, q0=[0.0, 1.5], **opts).task_stiffness
    for f in list(10.0 ** np.arange(-5.5, 5.6, 1.0)) + [
            m.max_task_stiffness_n_per_m[0] / kx * (1 + 2e-3)]:
        inside = any(lo <= f * kx <= hi for lo, hi in stretches)
        direct = sc.robot(ARM, q0=[0.0, 1.5], **dict(opts, task_stiffness=(f * kx, f * kr)))
        assert bool(direct.margins().stable) is inside, f
    assert m.single_flip.tolist() == [True] and m.records()[0]["single_flip"]
    assert m.max_task_stiffness_n_per_m[0] == stretches[-1][1] and stretches[0][0] == 0.0


# ------------------------------------------------------------------ backends
@pytest.mark.slow
def test_dask_backend_equals_serial(joint_map, monkeypatch):
    """Oracle: the serial backend; two local Dask workers give the same rows, in order.
    A map longer than the time budget is refused after its first configuration."""
    pytest.importorskip("distributed")
    m = sc.workspace_map(ARM, Q, fn_hz=14, backend="dask", workers=2, **TABLE_I)
    assert m.records() == joint_map.records()
    assert np.array_equal(m.phase_margin_deg, joint_map.phase_margin_deg)
    monkeypatch.setenv("SEACTL_MAX_SECONDS", "1")
    with pytest.raises(ResourceError, match="399 more configurations"):
        sc.workspace_map(ARM, Q[:1] * 400, fn_hz=14, backend="dask", workers=2, **TABLE_I)


def test_backend_and_budget_are_checked(monkeypatch):
    """Oracle: behaviour; an unknown backend, no workers, and a run longer than the time
    budget (SEACTL_MAX_SECONDS, estimated from the first configuration) are refused."""
    with pytest.raises(sc.InputError, match="backend"):
        sc.workspace_map(ARM, Q, backend="threads", fn_hz=14)
    with pytest.raises(sc.InputError, match="workers"):
        sc.workspace_map(ARM, Q, backend="dask", workers=0, fn_hz=14)
    monkeypatch.setenv("SEACTL_MAX_SECONDS", "1")
    with pytest.raises(ResourceError, match="999 more configurations of the workspace map"):
        sc.workspace_map(ARM, Q[:1] * 1000, fn_hz=14, **TABLE_I)


# ------------------------------------------------------------------ trajectories
def test_trajectory_file_is_its_rows(tmp_path, joint_map):
    """Oracle: the map of the same angles as an array (columns reordered by hand)."""
    p = tmp_path / "traj.csv"
    p.write_text("j2,t_s,j1\n" + "".join(f"{b},{0.1 * i},{a}\n" for i, (a, b) in
                                          enumerate(Q)))
    m = sc.workspace_map(ARM, p, fn_hz=14, **TABLE_I)
    assert m.q0_rad.tolist() == Q and m.t_s.tolist() == [0.0, 0.1, 0.2]
    assert np.array_equal(m.phase_margin_deg, joint_map.phase_margin_deg)
    assert [r["t_s"] for r in m.records()] == [0.0, 0.1, 0.2]


@pytest.mark.parametrize("text, words", [
    ("j1,j2\n0.3,0.8\n0.1\n", "2 values per row (the header's columns); line 3 has 1"),
    ("j1,elbow\n0.3,0.8\n", "unknown column(s): 'elbow'"),
    ("j1,j2\n0.3,nan\n", "finite numbers; line 2"),
    ("j1,j2\n0.3,abc\n", "finite numbers; line 2"),
    ("j1\n0.3\n", "missing: j2"),
    ("j1,j2\n", "at least one row"),
])
def test_bad_trajectory_is_one_line(tmp_path, capsys, text, words):
    """Oracle: behaviour; the API raises InputError, the CLI prints one line and exits 2."""
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(sc.InputError) as err:
        sc.workspace_map(ARM, p, fn_hz=14)
    assert words in str(err.value)
    assert main(["robot", "--urdf", str(ARM), "--trajectory", str(p)]) == 2
    out = capsys.readouterr()
    lines = (out.out + out.err).strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: invalid --trajectory = ")
    assert words in lines[0]


# ------------------------------------------------------------------ the figure and the CLI
def test_grid_figure_is_a_heat_map_of_the_map():
    """Oracle: the map's central delay margins (the default in joint space) and phase
    margins placed on the grid by hand (q1 across, q2 up)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid = [[a, b] for a in (0.0, 0.3) for b in (1.5, 2.2)]
    m = sc.workspace_map(ARM, grid, fn_hz=14, **TABLE_I)
    assert [x.tolist() for x in grid_axes(m.q0_rad)] == [[0.0, 0.3], [1.5, 2.2]]
    for quantity in (None, "phase_margin_deg"):
        ax = m.plot(quantity=quantity)
        mesh = ax.collections[0].get_array()
        values = m.mimo_delay_margin_ms if quantity is None else m.phase_margin_deg
        expect = [[values[2 * i + j] for i in range(2)] for j in range(2)]
        expect = np.where(np.isfinite(expect), expect, np.nan)
        assert np.allclose(np.ma.filled(np.asarray(mesh, float).reshape(2, 2), np.nan),
                           expect, equal_nan=True)
        assert "worst: configuration" in ax.get_legend().get_texts()[-1].get_text()
        plt.close(ax.figure)
    assert grid_axes(np.array(Q)) is None   # a trajectory is drawn along its samples


def test_cli_map_plot_and_worst(tmp_path, capsys):
    """Oracle: sc.workspace_map of the same trajectory; the figure is written, the worst
    configuration in the JSON is the API's."""
    p, png = tmp_path / "traj.csv", tmp_path / "map.png"
    p.write_text("j1,j2\n" + "".join(f"{a},{b}\n" for a, b in Q))
    args = ["robot", "--urdf", str(ARM), "--fn", "14", "--t-tau", "0.5", "--t-qs", "18",
            "--t-qd", "0.5", "--f-qd", "50", "--f-taud", "100", "--trajectory", str(p)]
    assert main(args + ["--plot", str(png), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    m = sc.workspace_map(ARM, Q, fn_hz=14, **TABLE_I)
    assert rec["worst"] == m.worst and rec["worst_configuration"]["stable"] is False
    assert rec["lowest_max_task_stiffness"] is None   # joint space: no k_x
    assert rec["worst_configuration"]["phase_margin_deg"] == pytest.approx(
        m.phase_margin_deg[m.worst], rel=1e-9)
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert main(["robot", "--urdf", str(ARM), "--plot", str(png)]) == 2
    assert "--workspace or --trajectory" in capsys.readouterr().err + \
        capsys.readouterr().out


# ------------------------------------------------------------------ the MIMO margins
def test_map_has_each_configurations_mimo_margins(joint_map):
    """Oracle: Robot.mimo_margins() of sc.robot at each configuration, outside the map."""
    for i, q in enumerate(Q):
        mm = sc.robot(ARM, q0=q, fn_hz=14, **TABLE_I).mimo_margins()
        assert joint_map.mimo_phase_margin_deg[i] == pytest.approx(mm.phase_margin_deg,
                                                                   rel=1e-12)
        assert joint_map.mimo_delay_margin_ms[i] == pytest.approx(1e3 * mm.delay_margin_s,
                                                                  rel=1e-12)
    rec = joint_map.records()   # (rounded to 12 significant digits)
    assert [r["mimo_phase_margin_deg"] for r in rec] == pytest.approx(
        joint_map.mimo_phase_margin_deg.tolist(), rel=1e-9)


def test_worst_is_the_least_central_delay_margin():
    """Oracle: the documented rule on hand-made maps: the smallest central delay margin
    even where the phase margin at outer.j1 ranks otherwise; an unstable one first."""
    from seactl.api.robotmap import WorkspaceMap

    def worst(stable, pm, dm):
        n = len(stable)
        return WorkspaceMap(("j1", "j2"), np.zeros((n, 2)), np.array(stable),
                            np.array(pm, float), np.zeros(n), np.full(n, np.nan),
                            mimo_phase_margin_deg=np.zeros(n),
                            mimo_delay_margin_ms=np.array(dm, float)).worst

    assert worst([True, True, True], [10.0, 40.0, 60.0], [30.0, 5.0, math.inf]) == 1
    assert worst([True, False, True], [10.0, 40.0, 60.0], [30.0, 0.0, 2.0]) == 1
    assert worst([True, True], [10.0, 40.0], [math.inf, 7.0]) == 1
