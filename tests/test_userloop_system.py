"""A user loop is a :class:`seactl.System`: the same verbs, keywords and result types as
``sc.design``.

Oracles: the built-in SEA design of Table I at f_n = 14 Hz (``sc.design``) against
``examples/loops/paper-sea.toml``, the same diagram written as a loop file (two routes
through one loop: roots, margins, impedance, responses, jitter margins, Monte Carlo,
python-control export); python-control built by hand on an exact-delay integrator loop;
the command line against the API.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import control as ct
import numpy as np
import pytest

import seactl as sc
from seactl.apps.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "loops"
PAPER = EXAMPLES / "paper-sea.toml"
TABLE_I_14 = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
                  filters_hz=(50, 100))
TABLE_I_FLAGS = "--fn 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100".split()
SEA_LINKS = {"stiffness": "Kq_fb", "damping": "Bq_fb", "torque": "tau_delay"}


@pytest.fixture(scope="module")
def paper():
    return sc.load_loop(PAPER)


@pytest.fixture(scope="module")
def builtin():
    return sc.design(14, **TABLE_I_14)


def _integrator(K=10.0, delay_ms=10.0, **signals):
    """L(s) = K e^{-sT} / s broken at y_m."""
    return (sc.LoopBuilder("int").variables(K=K).process("cpu")
            .block("c", "gain", input=["r", "-y_m"], output="u", gain="K", delay_ms=delay_ms)
            .block("p", "plant_tf", input="u", output="y", num=[1], den=[1, 0])
            .block("s", "sensor", input="y", output="y_m")
            .signals(inputs=["r"], reference="r", output="y", **signals)
            .break_at("main", "y_m").build())


def test_a_user_loop_is_a_system_with_the_systems_result_types(paper):
    assert issubclass(type(paper), sc.System) and paper.kind == "loop"
    assert paper.loops == ("Kq_fb", "Bq_fb", "tau_delay")
    # the file declares its reference step and unit ([signals] reference_step/_unit)
    assert (paper.default_step, paper.step_unit) == (0.01, "rad")
    assert isinstance(paper.impedance([1.0, 10.0]), sc.ImpedanceResult)
    assert isinstance(paper.roots(count=2), sc.RootsResult)
    assert isinstance(paper.step(t_end_s=0.2), sc.ResponseResult)


def test_roots_of_the_loop_file_are_the_builtin_designs(paper, builtin, capsys):
    """The same characteristic quasi-polynomial derived from two diagrams: the same
    rightmost roots, by the API and by the command line."""
    r, ref = paper.roots(), builtin.roots()
    ok = np.isfinite(ref.roots)
    assert np.array_equal(np.isfinite(r.roots), ok) and ok.sum() >= 4
    np.testing.assert_allclose(r.roots[ok], ref.roots[ok], rtol=1e-9)
    assert float(r.spectral_abscissa) == pytest.approx(float(ref.spectral_abscissa), rel=1e-9)
    assert bool(r.stable) and int(r.right_half_plane_roots) == 0
    assert main(["roots", "--loop", str(PAPER), "--json"]) == 0
    cli_loop = json.loads(capsys.readouterr().out)
    assert main(["roots", *TABLE_I_FLAGS, "--json"]) == 0
    cli_sea = json.loads(capsys.readouterr().out)["designs"][0]
    assert cli_loop["loop"] == "paper-sea"
    got = cli_loop["designs"][0]
    assert got == r.records()[0]                         # the command prints the API's
    assert len(got["roots"]) == len(cli_sea["roots"])
    for a, b in zip(got["roots"], cli_sea["roots"]):
        assert complex(a["re"], a["im"]) == pytest.approx(complex(b["re"], b["im"]), rel=1e-9)
    assert got["spectral_abscissa"] == pytest.approx(cli_sea["spectral_abscissa"], rel=1e-9)


def test_roots_of_a_batch_and_their_labels(paper):
    """Oracle: the built-in SEA diagram at the same stiffness gains."""
    from seactl.analysis.roots import characteristic_roots
    from seactl.systems.sea.loops import SEA_DIAGRAM, SEADesign

    kq = np.array([70.0, 90.0])
    lp = paper.with_values(Kq=kq)
    r = lp.roots(count=3)
    g = sc.design(14, **TABLE_I_14)
    gains = type(g.gains)(kq, g.gains.Bq, g.gains.Ktau, g.gains.Btau)
    ref = characteristic_roots(SEA_DIAGRAM, SEADesign(sc.UT_SEA, gains, g.timing), count=3)
    np.testing.assert_allclose(r.roots, ref.roots, rtol=1e-9)
    assert [row["Kq"] for row in r.records()] == [70.0, 90.0]
    assert lp.labels() == ["Kq=70", "Kq=90"]


def test_margins_records_are_the_builtin_designs(paper, builtin):
    m = paper.margins()
    row = m.records()[0]                          # one flat row per design
    ref = builtin.margins().records()[0]
    for key in ("phase_margin_deg", "crossover_hz", "delay_margin_ms"):
        assert row[f"outer_{key}"] == pytest.approx(ref[key], abs=1e-8)
    assert row["stable"] is True and row["outer_jitter_margin_ms"] is None
    assert row["Kq"] == pytest.approx(83.17208068860442)   # the values label the row
    assert m.to_dict()["breaks"][1]["break"] == "outer"
    s = paper.margins(rate_hz=1000)
    ref_s = builtin.margins(rate_hz=1000).records()[0]
    row = s.records()[0]
    assert (row["verdict"], row["rate_hz"]) == (ref_s["verdict"], 1000.0)
    assert row["outer_delay_margin_samples"] == ref_s["delay_margin_samples"]
    for key in ("phase_margin_deg", "delay_margin_ms"):
        assert row[f"outer_{key}"] == pytest.approx(ref_s[key], rel=1e-9)
    # the jitter margin is a scanned peak (each route its own grid): 1e-6
    assert row["outer_jitter_margin_ms"] == pytest.approx(ref_s["jitter_margin_ms"], rel=1e-6)
    assert "torque_phase_margin_deg" in row
    assert set(s) == {"torque", "outer"} and s.to_dict()["loop"] == "paper-sea"


def test_jitter_margins_of_the_outer_break_are_the_builtin_overall_margin(paper, builtin):
    """Kao-Lincoln bound of the same outer loop by two routes (each scans, refines and
    proves its own peak)."""
    j, ref = paper.jitter_margins(), builtin.jitter_margins()
    assert float(j.jitter_margin_s) == pytest.approx(float(ref.jitter_margin_s), rel=1e-6)
    assert float(j.delay_margin_s) == pytest.approx(float(ref.delay_margin_s), rel=1e-9)
    rec = j.records()[0]
    assert rec["jitter_margin_ms"] == rec["outer_jitter_margin_ms"]
    assert 0 < rec["torque_jitter_margin_ms"] < rec["jitter_margin_ms"] < rec["delay_margin_ms"]


def test_impedance_result_is_the_builtin_designs(paper, builtin):
    f = np.logspace(-1, 3, 30)
    z, ref = paper.impedance(f, port="joint"), builtin.impedance(f)
    np.testing.assert_allclose(z.z, ref.z, rtol=1e-12)
    np.testing.assert_allclose(z.phase_deg, ref.phase_deg, atol=1e-9)
    assert z.port == "joint" and z.to_dict()["port"] == "joint"
    assert z.to_dict()["f_hz"][0] == pytest.approx(0.1)


@pytest.mark.parametrize("mode", ["continuous", "sampled"])
def test_step_result_is_the_builtin_designs(paper, builtin, mode):
    """Normalized responses, metrics, requested and effective delays per loop (a loop
    file's loops are its delayed blocks), verdict."""
    kw = {"saturation_a": np.inf} if mode == "sampled" else {}
    r, ref = paper.step(t_end_s=0.3, mode=mode), builtin.step(t_end_s=0.3, mode=mode, **kw)
    assert r.amplitude == paper.default_step and r.output == "q_j"
    np.testing.assert_allclose(r.position, ref.position, atol=1e-12)
    assert float(r.metrics.overshoot_pct) == pytest.approx(float(ref.metrics.overshoot_pct),
                                                           abs=1e-8)
    for loop, block in SEA_LINKS.items():
        assert float(r.requested_delays_s[block]) == float(ref.requested_delays_s[loop])
        assert float(r.effective_delays_s[block]) == float(ref.effective_delays_s[loop])
    assert r.verdict().verdict == ref.verdict().verdict == ["settled"]
    d = r.to_dict()
    assert d["effective_delays_ms"]["Kq_fb"] == pytest.approx(2.5 if mode == "sampled" else 2)
    if mode == "sampled":
        assert d["sampled_verdict"] == "stable"


def test_impulse_result_is_the_builtin_designs(paper, builtin):
    r = paper.impulse(t_end_s=0.5)
    ref = builtin.impulse(t_end_s=0.5)            # both 0.05 (N m s) by default
    np.testing.assert_allclose(r.position, ref.position, atol=1e-12)
    assert float(r.metrics.peak_deviation) == pytest.approx(float(ref.metrics.peak_deviation),
                                                            rel=1e-9)
    assert r.verdict().verdict == ["settled"]


def test_an_unstable_design_is_judged_unstable_in_both_modes(paper):
    """T_high = 30 ms: two right-half-plane roots (seactl roots on the built-in loop)."""
    lp = paper.with_values(T_high=[2.0, 30.0])
    assert lp.roots(count=1).right_half_plane_roots.tolist() == [0, 2]
    for mode in ("continuous", "sampled"):
        assert lp.step(t_end_s=0.3, mode=mode).verdict().verdict == ["settled", "unstable"]


def test_monte_carlo_is_the_builtin_designs(paper, builtin):
    """The same seed, the same link (damping = block Bq_fb), the same step: the same
    realizations (the SEA's 30 A limit is not reached by a 0.01 rad step)."""
    mc = paper.monte_carlo(latency={"Bq_fb": "uniform:0.5:3"}, runs=6, seed=3, t_end_s=0.3)
    ref = builtin.monte_carlo(latency={"damping": "uniform:0.5:3"}, runs=6, seed=3,
                              t_end_s=0.3)
    assert float(ref.peak_current_worst_a) < 30
    np.testing.assert_allclose(mc.rms_error, ref.rms_error, rtol=1e-9)
    np.testing.assert_allclose(mc.peak_current_a, ref.peak_current_a, rtol=1e-9)
    assert float(mc.fraction_stable) == 1.0
    with pytest.raises(sc.InputError, match="link"):
        paper.monte_carlo(latency={"damping": "uniform:0.5:3"}, runs=2)


def test_to_control_frd_and_pade_match_python_control_on_an_exact_delay_loop():
    """L(s) = K e^{-sT}/s built in python-control by hand: FRD times the exact e^{-jwT},
    and K/s times ct.pade(T, 3)."""
    K, T = 10.0, 0.01
    loop = _integrator(K, T * 1e3)
    f = np.logspace(-1, 2, 50)
    w = 2 * np.pi * f
    frd = loop.to_control(f_hz=f)
    exact = K / (1j * w) * np.exp(-1j * w * T)
    np.testing.assert_allclose(np.ravel(frd.frdata), exact, rtol=1e-12)
    pade = loop.to_control("pade", order=3)
    ref = ct.tf([K], [1, 0]) * ct.tf(*ct.pade(T, 3))
    np.testing.assert_allclose(pade(1j * w), ref(1j * w), rtol=1e-9)
    # exact phase margin: 90 deg - K T rad
    assert ct.margin(frd)[1] == pytest.approx(90 - np.degrees(K * T), abs=0.05)
    assert len(loop.with_values(K=[5.0, 10.0]).to_control(f_hz=f)) == 2
    with pytest.raises(sc.InputError, match="transfer"):
        loop.to_control(transfer="nope")


def test_to_control_of_the_loop_file_is_the_builtin_designs(paper, builtin):
    f = np.logspace(-1, 3, 200)
    a, b = paper.to_control(f_hz=f), builtin.to_control(f_hz=f)
    np.testing.assert_allclose(np.ravel(a.frdata), np.ravel(b.frdata), rtol=1e-10)
    c = paper.to_control(transfer="closed", f_hz=f)
    d = builtin.to_control(transfer="closed", f_hz=f)
    np.testing.assert_allclose(np.ravel(c.frdata), np.ravel(d.frdata), rtol=1e-10)


def test_batch_selection_reshape_and_labels(paper):
    lp = paper.with_values(Kq=[70.0, 80.0, 90.0], T_high=2.0)
    assert lp.shape == (3,) and len(lp) == 3
    one = lp[1]
    assert one.shape == () and one.labels() == ["paper-sea"]
    pm = lp.margins()["outer"].margins.phase_margin_deg
    assert float(one.margins()["outer"].margins.phase_margin_deg) == pytest.approx(pm[1],
                                                                                 abs=1e-12)
    assert lp.reshape(3, 1).shape == (3, 1) and lp[None].shape == (1, 3)
    assert paper[None].shape == (1,) and lp[1:].labels() == ["Kq=80", "Kq=90"]
    with pytest.raises(IndexError):
        paper[0]


def test_default_step_is_the_files_or_001():
    assert (_integrator().default_step, _integrator().step_unit) == (0.01, "reference units")
    lp = _integrator(reference_step=0.002, reference_unit="m")
    r = lp.step(t_end_s=0.5)
    assert (r.amplitude, lp.step_unit) == (0.002, "m")
    raw = r.outputs["y"]
    np.testing.assert_allclose(r.position, raw / 0.002)
    with pytest.raises(sc.LoopFileError, match="non-zero"):
        _integrator(reference_step=0.0)


def test_deprecated_spellings_warn_and_agree(paper):
    lp = paper.with_values(T_high=[2.0, 30.0])
    with pytest.warns(DeprecationWarning, match="right_half_plane_roots"):
        old = lp.right_half_plane_roots()
    assert old.tolist() == lp.roots(count=1).right_half_plane_roots.tolist() == [0, 2]
    with pytest.warns(DeprecationWarning, match="positional"):
        a = paper.step(0.2)
    with pytest.warns(DeprecationWarning, match="area"):
        b = paper.impulse(t_end_s=0.2, area=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(a.position, paper.step(t_end_s=0.2).position)
        np.testing.assert_array_equal(b.position, paper.impulse(t_end_s=0.2).position)


def test_cli_roots_with_a_loop_refuses_sea_options(capsys):
    assert main(["roots", "--loop", str(PAPER), "--fn", "14"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "--loop" in err and len(err.strip().splitlines()) == 1


def test_cli_step_with_a_loop_prints_the_api_numbers(paper, capsys):
    assert main(["step", "--loop", str(PAPER), "--t-end", "0.3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    r = paper.step(t_end_s=0.3, record_dt=5e-4)
    assert out["amplitude"] == paper.default_step and out["step_unit"] == "rad"
    assert out["metrics"]["overshoot_pct"] == pytest.approx(float(r.metrics.overshoot_pct),
                                                            abs=1e-9)
    assert out["verdict"] == r.verdict().verdict[0]


def test_sweep_writes_the_margins_of_analyze(paper, tmp_path):
    lp = paper.with_values(T_high=np.array([2.0, 5.0]))
    res = lp.sweep(tmp_path / "sw")
    assert res["n_points"] == 2
    df = sc.read_sweep(tmp_path / "sw")
    pm = lp.margins()["outer"].margins.phase_margin_deg
    np.testing.assert_allclose(np.sort(df["outer_phase_margin_deg"].to_numpy()), np.sort(pm),
                               rtol=1e-12)


def test_results_have_records_to_dict_and_plot(paper):
    """Every view's result: one JSON-ready record per design (per design and break for
    margins), a to_dict() that json serializes, and a plot on given axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lp = paper.with_values(Kq=[70.0, 90.0])
    results = [lp.margins(), lp.margins(rate_hz={}), lp.jitter_margins(), lp.roots(count=2),
               lp.step(t_end_s=0.2), lp.impulse(t_end_s=0.2), lp.impedance([1.0, 10.0])]
    for r in results:
        json.dumps(r.to_dict())
        _, ax = plt.subplots()
        assert r.plot(ax=ax) is ax
        plt.close("all")
        if not isinstance(r, sc.ImpedanceResult):   # (per frequency too, where it has records)
            rows = r.records()
            assert len(rows) == 2 and json.dumps(rows)
    steps = results[4].records()
    assert [r["label"] for r in steps] == ["Kq=70", "Kq=90"]
    assert [r["verdict"] for r in steps] == ["settled", "settled"]


def test_bad_values_raise_input_errors(paper):
    for call in (lambda: paper.step(t_end_s=0.2, amplitude="x"),
                 lambda: paper.step(t_end_s=0.2, amplitude=0.0),
                 lambda: paper.step(t_end_s=0.2, rate_hz="fast"),
                 lambda: paper.step(t_end_s=0.2, mode="analog"),
                 lambda: paper.monte_carlo(runs=0),
                 lambda: paper.monte_carlo(kind="ramp"),
                 lambda: paper.roots(count=0),
                 lambda: paper.impedance([1.0], port="knee")):
        with pytest.raises(sc.SeactlError):
            call()


def test_delays_by_loop_name(paper):
    """A loop file's loops are its delayed blocks; their delays are the processes'
    latencies the file sets (T_high = 2 ms, T_embedded = 0.5 ms)."""
    assert paper.links == {k: k for k in paper.loops}
    assert {k: float(v) for k, v in paper.delays_s.items()} == {
        "Kq_fb": 2e-3, "Bq_fb": 0.5e-3, "tau_delay": 0.5e-3}
    r = paper.impulse(t_end_s=0.2)
    assert (r.amplitude, r.amplitude_unit) == (paper.default_impulse, paper.impulse_unit)
