"""Sweeps: equal to the points computed one by one, resumable, same on Dask, guarded."""

import contextlib
import itertools
import json
import socket
import sys
import warnings
from dataclasses import replace

import numpy as np
import pyarrow.parquet as pq
import pytest

from seactl.apps.cli import main
from seactl.errors import InfeasibleDesignError, InputError
from seactl.sweep.dataset import missing_chunks, read_sweep
from seactl.sweep.engine import SweepInterrupted, run_sweep
from seactl.sweep.maps import sweep_map
from seactl.sweep.robustness import RobustResult, parameter_robustness
from seactl.sweep.spec import SweepSpec
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.loops import SEADesign, Timing
from seactl.systems.sea.views import sea_margins

IJ = UT_SEA.joint_inertia
# f_n = 8 Hz has no critically-damped gain set (feasible above about 9.5 Hz).
AXES = (("fn_hz", (8.0, 12.0, 20.0)), ("gs", (0.6, 1.0)), ("t_tau_ms", (0.5,)),
        ("t_qs_ms", (2.0, 12.0)), ("t_qd_ms", (0.5,)), ("f_qd_hz", (50.0,)),
        ("f_taud_hz", (100.0,)), ("Ij", (0.8 * IJ, IJ)))
SPEC = SweepSpec(UT_SEA, AXES, chunk_size=5, z_freqs_hz=(2.0, 40.0))


def hand_impedance(a, g, t_tau, t_qs, t_qd, f_hz):
    """|Z| with the joint motion imposed (q_j = 1, q_des = 0), solved by hand from the
    physical equations: tau_des = -F q_j, i_m = tau_des/beta + C (tau_des - e^{-sT_tau} tau_k),
    M q_m = beta i_m - tau_k, tau_k = k (q_m - q_j), M = I_m s^2 + b_m s, so
    Z = tau_k / (-s) = ((1 + beta C) F + M) / (s (M/k + 1 + beta C e^{-sT_tau}))."""
    s = 2j * np.pi * np.asarray(f_hz)
    F = (g.Kq * np.exp(-s * t_qs)
         + g.Bq * s / (s / (2 * np.pi * 50.0) + 1) * np.exp(-s * t_qd))
    C = g.Ktau + g.Btau * s / (s / (2 * np.pi * 100.0) + 1)
    M = a.Im * s**2 + a.bm * s
    return np.abs(((1 + a.beta * C) * F + M)
                  / (s * (M / a.k + 1 + a.beta * C * np.exp(-s * t_tau))))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted in-process run of SPEC."""
    out = tmp_path_factory.mktemp("ref") / "sweep"
    res = run_sweep(SPEC, out, workers=0)
    return out, res, read_sweep(out)


def test_sweep_equals_points_one_by_one(reference):
    # Oracle: every point rebuilt and evaluated alone (gain design, sea_margins,
    # hand_impedance) and the paper's 45.1 deg at the Table I point.
    out, res, table = reference
    assert res.n_points == 24 and res.chunks_computed == 5 and table.num_rows == 24
    rows = table.to_pylist()
    swept = [(n, v) for n, v in AXES if len(v) > 1]
    n_stable = 0
    for p, combo in enumerate(itertools.product(*(v for _, v in swept))):
        row = rows[p]
        assert row["point"] == p
        point = dict(zip((n for n, _ in swept), combo))
        assert {k: row[k] for k in point} == point
        fn, gs, tqs, ij = point["fn_hz"], point["gs"], point["t_qs_ms"], point["Ij"]
        if fn == 8.0:
            with pytest.raises(InfeasibleDesignError):
                critically_damped_gains(UT_SEA, fn)
            assert row["feasible"] is False
            assert all(row[k] is None for k in ("Kq", "phase_margin_deg", "stable",
                                                "z_mag_2hz"))
            continue
        # one design at a time: gains for the nominal actuator, loop on the real plant
        gains = critically_damped_gains(UT_SEA, fn, gs=gs)
        plant = replace(UT_SEA, joint_inertia=ij)
        d = SEADesign(plant, gains, Timing.from_ms(0.5, tqs, 0.5, 50.0, 100.0))
        m = sea_margins(d)
        assert row["feasible"] is True
        for key, ref in (("Kq", gains.Kq), ("Bq", gains.Bq), ("Ktau", gains.Ktau),
                         ("Btau", gains.Btau), ("phase_margin_deg", m.phase_margin_deg),
                         ("crossover_hz", m.crossover_hz), ("gain_margin_db", m.gain_margin_db),
                         ("delay_margin_ms", m.delay_margin_ms)):
            assert row[key] == pytest.approx(float(ref), rel=1e-9, abs=1e-12), key
        assert row["stable"] == bool(m.stable)
        n_stable += bool(m.stable)
        assert row["unstable_poles"] == int(m.unstable_poles)
        # |Z| from the physical equations solved by hand (not the diagram the code uses)
        z = hand_impedance(plant, gains, 0.5e-3, tqs * 1e-3, 0.5e-3, [2.0, 40.0])
        assert [row["z_mag_2hz"], row["z_mag_40hz"]] == pytest.approx(z, rel=1e-9)
    # Table I point (f_n = 12 Hz, GS = 1, T_qs = 2 ms, nominal plant): the paper's 45.1 deg
    t1 = [r for r in rows if (r["fn_hz"], r["gs"], r["t_qs_ms"], r["Ij"]) == (12, 1, 2, IJ)]
    assert t1[0]["phase_margin_deg"] == pytest.approx(45.1, abs=0.05)
    summary = json.loads((out / "_summary.json").read_text())
    # 8 Hz is below the feasibility bound (9.456 Hz): its 2 x 2 x 2 points are infeasible;
    # the stable count is that of the designs evaluated one by one above
    assert summary["infeasible"] == 8 and summary["stable"] == n_stable
    assert json.loads((out / "_manifest.json").read_text())["status"] == "complete"


def test_resume_after_interruption_gives_the_same_dataset(reference, tmp_path):
    # Oracle: the uninterrupted reference run, byte for byte.
    ref_out, _, ref_table = reference
    out = tmp_path / "sweep"

    def interrupt(i):
        if i == 2:
            raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as info:
        run_sweep(SPEC, out, workers=0, _on_chunk=interrupt)
    assert info.value.done == 3
    assert missing_chunks(SPEC, out) == [3, 4]
    assert json.loads((out / "_manifest.json").read_text())["status"] == "running"
    # a writer killed mid-file leaves only a dot-named temporary, never a part
    from seactl.base.outputs import TEMP_TAG

    (out / f".part-00003.parquet{TEMP_TAG}999.parquet").write_bytes(b"partial")
    with pytest.raises(InputError, match="--resume"):
        run_sweep(SPEC, out, workers=0)
    res = run_sweep(SPEC, out, workers=0, resume=True)
    assert res.chunks_computed == 2
    assert not list(out.glob(".part-*"))
    assert read_sweep(out).equals(ref_table)
    # the summary merges this run's chunks (kept in memory) with the parts read back;
    # oracle: the summary read entirely from disk, and the uninterrupted run's
    from seactl.sweep.engine import summarize

    written, ref = (json.loads((o / "_summary.json").read_text()) for o in (out, ref_out))
    assert written.pop("run")["chunks_computed"] == 2
    ref.pop("run")
    assert written == summarize(SPEC, out) == ref
    assert written["best_phase_margin"] is not None and written["phase_margin_deg_stable"]
    for i in range(SPEC.n_chunks):
        name = f"part-{i:05d}.parquet"
        assert (out / name).read_bytes() == (ref_out / name).read_bytes()
    assert run_sweep(SPEC, out, workers=0, resume=True).chunks_computed == 0


def test_changed_spec_is_refused(reference, tmp_path):
    # Oracle: the error contract (InputError, exit 2) and the axis values written.
    ref_out, _, _ = reference
    out = tmp_path / "sweep"
    run_sweep(SweepSpec(UT_SEA, (("fn_hz", (12.0, 14.0)),), chunk_size=5), out, workers=0)
    other = SweepSpec(UT_SEA, (("fn_hz", (12.0, 16.0)),), chunk_size=5)
    with pytest.raises(InputError, match="axis fn_hz"):
        run_sweep(other, out, workers=0, resume=True)
    with pytest.raises(InputError, match="chunk_size"):
        run_sweep(replace(other, axes=(("fn_hz", (12.0, 14.0)),), chunk_size=4), out,
                  workers=0, resume=True)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("not a sweep")
    with pytest.raises(InputError, match="_manifest.json"):
        run_sweep(other, tmp_path / "other", workers=0)
    res = run_sweep(other, out, workers=0, overwrite=True)
    assert res.chunks_computed == 1
    assert read_sweep(out).column("fn_hz").to_pylist() == [12.0, 16.0]
    # the CLI says it in one line, exit status 2
    assert main(["sweep", "--fn", "12", "18", "--out", str(out), "--workers", "0",
                 "--resume", "--quiet"]) == 2


def test_samples_are_deterministic_and_stratified():
    # Oracle: the Latin-hypercube property (one point per stratum) and a second call with
    # the same seed.
    lhs = SweepSpec(UT_SEA, (("fn_hz", (10.0, 30.0)), ("t_qs_ms", (0.0, 20.0)),
                             ("k", (0.9 * UT_SEA.k, 1.1 * UT_SEA.k))),
                    sampling="lhs", n_samples=250, chunk_size=100, seed=3)
    assert lhs.n_chunks == 3
    a = lhs.points(100, 200, chunk=1)
    assert all(np.array_equal(a[k], v) for k, v in lhs.points(100, 200, chunk=1).items())
    for name, (lo, hi) in (("fn_hz", (10, 30)), ("t_qs_ms", (0, 20))):
        u = (a[name] - lo) / (hi - lo)
        # a Latin hypercube: each of the 100 strata of [0, 1) holds exactly one point
        assert sorted(np.floor(u * 100).astype(int)) == list(range(100))
    assert np.all((a["k"] >= 0.9 * UT_SEA.k) & (a["k"] <= 1.1 * UT_SEA.k))
    rnd = replace(lhs, sampling="random")
    b = rnd.points(200, 250, chunk=2)
    assert b["fn_hz"].shape == (50,) and not np.array_equal(b["fn_hz"], a["fn_hz"][:50])
    assert rnd.hash != lhs.hash != replace(lhs, seed=4).hash
    with pytest.raises(InputError, match="n_samples"):   # the library's names; the
        SweepSpec(UT_SEA, (("fn_hz", (10.0, 30.0)),), sampling="lhs")   # CLI's: --n, --t-qs
    with pytest.raises(InputError, match=r"t_qs_ms \[ms\]"):
        SweepSpec(UT_SEA, (("t_qs_ms", (-1.0, 2.0)),))


def test_sweep_map_reduces_over_the_other_axes(reference):
    """Oracle: not the table, but the (f_n, GS, T_qs, I_j) designs rebuilt as one batch
    (nominal gains, batched plant) and sea_margins' worst case over GS and I_j; f_n = 8 Hz
    is below the feasibility bound (9.456 Hz), so its column is NaN."""
    out, _, _ = reference
    m = sweep_map(out, "fn_hz", "t_qs_ms", "phase_margin_deg", "min")
    assert list(m["x"]) == [8.0, 12.0, 20.0] and list(m["y"]) == [2.0, 12.0]
    fn, gs = np.array([12.0, 20.0])[:, None, None, None], np.array([0.6, 1.0])[:, None, None]
    tqs, ij = np.array([2.0, 12.0])[:, None], np.array([0.8 * IJ, IJ])
    d = SEADesign(UT_SEA.batch(joint_inertia=ij), critically_damped_gains(UT_SEA, fn, gs=gs),
                  Timing.from_ms(0.5, tqs, 0.5, 50.0, 100.0))
    worst = sea_margins(d).phase_margin_deg.min(axis=(1, 3))      # (f_n, T_qs)
    assert np.all(np.isnan(m["z"][:, 0]))
    np.testing.assert_allclose(m["z"][:, 1:], worst.T, rtol=1e-9)


def test_cli_sweep_plot_and_bad_input(tmp_path, capsys):
    # Oracle: the 3 x 3 grid typed (9 points, all above the 9.456 Hz bound), PNG magic
    # bytes, the CLI error contract.
    out = tmp_path / "cli"
    fig = tmp_path / "map.png"
    code = main(["sweep", "--fn", "12:16:2", "--t-qs", "0,5,10", "--t-qd", "0.5",
                 "--out", str(out), "--workers", "0", "--plot", "fn_hz,t_qs_ms",
                 "--plot-file", str(fig), "--json", "--quiet"])
    res = json.loads(capsys.readouterr().out)
    assert code == 0 and res["n_points"] == 9 and res["feasible"] == 9
    assert fig.read_bytes()[:4] == b"\x89PNG"
    assert pq.read_table(out).num_rows == 9
    for args, field in ((["--fn", "14", "--sample", "lhs"], "--n"),
                        (["--fn", "12,14", "--plot", "fn_hz,gs"], "--plot"),
                        (["--t-qs", "20%"], "--t-qs"),
                        (["--ij", "150%"], "--ij"),
                        (["--fn", "12", "--scheduler", "localhost:1"], "--scheduler")):
        code = main(["sweep", *args, "--out", str(tmp_path / "bad"), "--workers", "0",
                     "--quiet"])
        err = capsys.readouterr().err
        assert code == 2 and field in err and "Traceback" not in err, (args, err)


def test_parameter_robustness_matches_samples_evaluated_one_by_one():
    """Oracle: sea_margins of each sampled plant, one by one and as one batched plant."""
    spec = SweepSpec(UT_SEA, (("fn_hz", (20.0,)), ("t_tau_ms", (0.5,)), ("t_qs_ms", (14.0,)),
                              ("t_qd_ms", (0.5,)), ("f_qd_hz", (50.0,)), ("f_taud_hz", (100.0,)),
                              ("Ij", (0.6 * IJ, 1.4 * IJ)), ("k", (0.6 * UT_SEA.k,
                                                                   1.4 * UT_SEA.k))),
                     sampling="random", n_samples=120, chunk_size=50, seed=1)
    r = parameter_robustness(spec)
    gains = critically_damped_gains(UT_SEA, 20.0)
    timing = Timing.from_ms(0.5, 14.0, 0.5, 50.0, 100.0)
    nominal = sea_margins(SEADesign(UT_SEA, gains, timing))
    assert r.nominal_phase_margin_deg == pytest.approx(float(nominal.phase_margin_deg),
                                                       rel=1e-12)
    assert 0 < r.p_unstable < 1        # this design sits on the edge: both outcomes occur
    for i in range(0, 120, 15):
        plant = replace(UT_SEA, joint_inertia=float(r.samples["Ij"][i]),
                        spring_stiffness=float(r.samples["k"][i]))
        m = sea_margins(SEADesign(plant, gains, timing))
        assert bool(m.stable) == bool(r.stable[i])
        assert r.phase_margin_deg[i] == pytest.approx(float(m.phase_margin_deg), rel=1e-9)
    # all 120 samples at once through a batched plant: same verdicts, and p_unstable is
    # the fraction of those that are unstable
    batch = sea_margins(SEADesign(UT_SEA.batch(joint_inertia=r.samples["Ij"],
                                               spring_stiffness=r.samples["k"]), gains, timing))
    np.testing.assert_array_equal(r.stable, batch.stable)
    assert r.p_unstable == pytest.approx(np.count_nonzero(~batch.stable) / 120, abs=1e-15)


def test_wilson_interval():
    # Oracle: the Wilson interval's closed form at p = 0.
    # p = 0 of n: the upper end is z^2 / (n + z^2)
    r = RobustResult(40.0, np.full(100, 40.0), np.ones(100, bool), {})
    z2 = 1.959963984540054 ** 2
    assert r.p_unstable_ci95() == pytest.approx((0.0, z2 / (100 + z2)), abs=1e-12)


def test_cli_robust(tmp_path, capsys):
    # Oracle: the intervals from the percentages typed (+-20 %).
    fig = tmp_path / "hist.png"
    code = main(["robust", "--fn", "14", "--t-qs", "2", "--t-qd", "0.5", "--ij", "20%",
                 "--k", "20%", "--n", "200", "--plot", str(fig), "--json"])
    res = json.loads(capsys.readouterr().out)
    assert code == 0 and res["n_samples"] == 200
    assert res["intervals"]["Ij"] == pytest.approx([0.8 * IJ, 1.2 * IJ])
    assert fig.read_bytes()[:4] == b"\x89PNG"
    assert main(["robust", "--fn", "14"]) == 2


def test_public_parameter_robustness_is_the_cli_and_the_spec(capsys):
    """Oracles: the nominal phase margin of ``sc.design`` (the System path, not the sweep
    evaluator); the spec-level evaluator on the same spec (identical arrays); and the
    CLI's JSON for the same design, intervals and seed."""
    import seactl as sc

    k = UT_SEA.spring_stiffness
    design = dict(fn_hz=14, t_qs_ms=2, t_qd_ms=0.5)
    r = sc.parameter_robustness(Ij=(0.8 * IJ, 1.2 * IJ), k=(0.8 * k, 1.2 * k),
                                n_samples=200, seed=3, **design)
    d = sc.design(14, delays_ms={"stiffness": 2, "damping": 0.5})
    assert r.nominal_phase_margin_deg == pytest.approx(float(d.margins().phase_margin_deg),
                                                       rel=1e-12)
    spec = SweepSpec(UT_SEA, (("fn_hz", (14.0,)), ("t_qs_ms", (2.0,)), ("t_qd_ms", (0.5,)),
                              ("Ij", (0.8 * IJ, 1.2 * IJ)), ("k", (0.8 * k, 1.2 * k))),
                     sampling="random", n_samples=200, seed=3)
    s = parameter_robustness(spec)
    np.testing.assert_array_equal(r.phase_margin_deg, s.phase_margin_deg)
    np.testing.assert_array_equal(r.samples["k"], s.samples["k"])
    assert main(["robust", "--fn", "14", "--t-qs", "2", "--t-qd", "0.5", "--ij", "20%",
                 "--k", "20%", "--n", "200", "--seed", "3", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["p_unstable"] == pytest.approx(r.p_unstable, abs=0)
    assert res["nominal_phase_margin_deg"] == pytest.approx(r.nominal_phase_margin_deg,
                                                            rel=1e-12)


# ------------------------------------------------------------------ Dask
@pytest.fixture(scope="module")
def cluster():
    import logging

    from distributed import LocalCluster

    from seactl.sweep.engine import SCHEDULER_HTTP

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None, scheduler_kwargs=SCHEDULER_HTTP,
                      silence_logs=logging.ERROR) as c:
        yield c


def test_local_cluster_gives_the_same_result(reference, cluster, tmp_path, capsys):
    # Oracle: the in-process reference run's table.
    from distributed import Client

    ref_out, _, ref_table = reference
    with Client(cluster) as client:
        res = run_sweep(SPEC, tmp_path / "dask", client=client)
    assert res.workers == 2 and res.chunks_computed == SPEC.n_chunks
    assert read_sweep(tmp_path / "dask").equals(ref_table)
    # the summary from the workers' shares of it (no part read back) is the reference's
    ref_summary = json.loads((ref_out / "_summary.json").read_text())
    ref_summary.pop("run")
    assert {k: v for k, v in res.summary.items() if k != "run"} == ref_summary
    # the same through the CLI, given only the scheduler's address
    code = main(["sweep", "--fn", "8,12,20", "--gs", "0.6,1", "--t-tau", "0.5",
                 "--t-qs", "2,12", "--t-qd", "0.5", "--f-qd", "50", "--f-taud", "100",
                 "--ij", f"{0.8 * IJ!r},{IJ!r}", "--z-freq", "2", "40", "--chunk-size", "5",
                 "--out", str(tmp_path / "cli"), "--scheduler", cluster.scheduler_address,
                 "--quiet", "--json"])
    assert code == 0, capsys.readouterr().err
    printed = json.loads(capsys.readouterr().out)
    assert printed.pop("run")["workers"] == 2
    assert read_sweep(tmp_path / "cli").equals(ref_table)
    assert {k: printed[k] for k in ref_summary} == ref_summary  # (tables sent here)


def test_the_parents_work_does_not_grow_with_the_chunks(cluster, tmp_path, monkeypatch):
    """Local workers compute and write their chunks; the parent only hands them out and
    counts.  Oracle: the calls, in this process, of the spec's identity (its JSON, which
    the hash digests and which names every task) over a run of 2 chunks and one of 24
    chunks of the same points: equal counts (it once cost a hash per task)."""
    from distributed import Client

    calls = []
    as_json = SweepSpec.as_json
    monkeypatch.setattr(SweepSpec, "as_json", lambda self: calls.append(1) or as_json(self))
    counts = {}
    with Client(cluster) as client:
        for size in (12, 1):
            spec = replace(SPEC, chunk_size=size)
            calls.clear()
            res = run_sweep(spec, tmp_path / f"c{size}", client=client)
            counts[spec.n_chunks] = len(calls)
            assert res.chunks_computed == spec.n_chunks
    assert set(counts) == {2, 24} and counts[2] == counts[24]


def test_a_run_reports_this_processs_cpu_time(reference):
    # Oracle: in process (workers=0) the chunks' CPU time, measured around each chunk, is
    # part of this process's CPU time over the run.
    _, res, _ = reference
    assert res.parent_cpu_seconds >= res.worker_cpu_seconds > 0
    assert res.summary["run"]["parent_cpu_seconds"] == round(res.parent_cpu_seconds, 3)


def _worker_state():
    """In a worker: are the sweep's kernels in memory (a numba dispatcher of the certified
    scan with a loaded overload), is SIGINT ignored, and its parent's pid."""
    import os
    import signal

    cert = sys.modules.get("seactl.certify.scan")
    loaded = cert is not None and any(getattr(v, "overloads", None) for v in vars(cert).values())
    return loaded, signal.getsignal(signal.SIGINT) == signal.SIG_IGN, os.getppid()


@contextlib.contextmanager
def _port_held(port: int):
    """``port`` taken on every interface meanwhile (left alone if something holds it)."""
    sock = socket.socket()
    try:
        sock.bind(("", port))
        sock.listen()
    except OSError:
        pass
    try:
        yield
    finally:
        sock.close()


@pytest.mark.parametrize("method", ["forkserver", "spawn"])
def test_local_workers_start_warm_and_ignore_ctrl_c(method, reference, tmp_path,
                                                     monkeypatch):
    """Oracle: each worker's own state read in it before any chunk (kernels loaded,
    SIGINT ignored, forked from the template server rather than started by this
    process), then the in-process reference run's table.  ``spawn`` is the path of
    platforms without a fork server, forced here."""
    import multiprocessing
    import os

    from distributed import Client

    from seactl.sweep.engine import local_cluster

    if method not in multiprocessing.get_all_start_methods():
        pytest.skip(f"no {method} here")
    if method == "spawn":
        monkeypatch.setattr(multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    # Dask's default HTTP port held (as another cluster on the machine would): the
    # scheduler's HTTP server takes a free loopback port without a warning
    with _port_held(8787), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cluster = local_cluster(2)
    assert not [w for w in caught if "already in use" in str(w.message)]
    assert cluster.scheduler.http_server.address == "127.0.0.1"
    try:
        with Client(cluster) as client:
            state = client.run(_worker_state)
            res = run_sweep(SPEC, tmp_path / "local", client=client)
    finally:
        cluster.close()
    assert len(state) == 2 and res.workers == 2
    for loaded, ignored, parent in state.values():
        assert loaded and ignored
        assert (parent != os.getpid()) == (method == "forkserver")
    assert read_sweep(tmp_path / "local").equals(reference[2])


@pytest.mark.parametrize("marked", [False, True])
def test_the_template_prepares_only_the_fork_server_seactl_starts(marked):
    """Importing ``seactl.sweep.template`` prepares the process (kernels loaded, SIGINT
    ignored) only with the marker that ``start_worker_template`` gives its fork server;
    elsewhere (pytest's doctest collection) it only defines things.  Oracle: a fresh
    interpreter's own state after the import."""
    import os
    import subprocess

    from seactl.sweep.spec import TEMPLATE_MARKER

    code = ("import os, signal, sys, seactl.sweep.template; "
            "print(signal.getsignal(signal.SIGINT) == signal.SIG_IGN, "
            "'seactl.certify.scan' in sys.modules, os.environ.get(sys.argv[1]))")
    env = {k: v for k, v in os.environ.items() if k != TEMPLATE_MARKER}
    if marked:
        env[TEMPLATE_MARKER] = "1"
    out = subprocess.run([sys.executable, "-c", code, TEMPLATE_MARKER], env=env, text=True,
                         capture_output=True, timeout=300, check=True).stdout.split()
    assert out == [str(marked), str(marked), "None"]


def test_a_failed_warm_up_is_left_to_the_first_chunk(monkeypatch):
    """Oracle: a warm-up that raises is swallowed, not marked done, and SIGINT's handler is
    the one before it; the workers' preload ``dask_setup`` leaves SIGINT ignored."""
    import signal

    from seactl.sweep import worker as _sweep_worker

    calls = []

    def broken(*args):
        calls.append(args)
        raise RuntimeError("kernel cache unreadable")

    monkeypatch.setattr(sys.modules["seactl.sweep.evaluate"], "evaluate_chunk", broken)
    monkeypatch.setattr(_sweep_worker, "_warm", False)
    before = signal.getsignal(signal.SIGINT)
    assert _sweep_worker.warm() is None
    assert len(calls) == 1 and not _sweep_worker._warm
    assert signal.getsignal(signal.SIGINT) is before
    try:
        _sweep_worker.dask_setup(None)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN and len(calls) == 2
    finally:
        signal.signal(signal.SIGINT, before)


def _report_peak(q):
    from seactl.sweep.evaluate import _peak_rss_mb

    q.put(_peak_rss_mb())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="VmHWM is Linux's")
def test_worker_peak_memory_is_its_own_not_its_parents():
    """A worker started by a large process reports its own peak memory: ru_maxrss would
    count the parent's 400 MB at the fork (kept across exec).  Oracle: the parent's
    allocation, which the child never touches."""
    import multiprocessing

    big = np.ones(50_000_000)  # 400 MB in this process
    ctx = multiprocessing.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_report_peak, args=(q,))
    p.start()
    child_mb = q.get(timeout=60)
    p.join()
    assert big.sum() == big.size  # (touched: resident in this process)
    assert 0 < child_mb < 300


@pytest.mark.parametrize("n,workers", [(0, 2), (1, 2), (7, 1), (200, 2), (1000, 8)])
def test_batches_cover_the_chunks_in_order_and_shrink_to_singles(n, workers):
    """Local workers take chunks in batches (one task each).  Oracle: the definition:
    every chunk once, in order; at most 8 per batch; single chunks at the end, when fewer
    than 4 per worker remain."""
    from seactl.sweep.evaluate import batches

    todo = list(range(3, 3 + n))
    b = batches(todo, workers)
    assert [i for g in b for i in g] == todo
    assert all(1 <= len(g) <= 8 for g in b)
    tail = [g for g in b if sum(len(h) for h in b[b.index(g):]) < 4 * workers]
    assert all(len(g) == 1 for g in tail)
