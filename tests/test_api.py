"""The public API (``import seactl as sc``): designs, results, units, python-control export.

Oracles are named per test: the paper's Table I and Fig. GainScale, python-control's own
margin routines on the exported systems, analytic identities (P_CL(0) = 1, s Z -> K_q),
and the rigid actuator's latency asymmetry stated in the paper.
"""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import control as ct
import numpy as np
import pytest

import seactl as sc
from seactl.systems.sea.loops import Timing

TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))


@pytest.fixture(scope="module")
def table1():
    return sc.design([12, 14, 16], gs=1.0, **TABLE_I)


def test_three_line_example_reproduces_table_i(table1):
    # Oracle: the paper's Table I (45.13, 43.2(6), 40.03 degrees).
    pm = table1.margins().phase_margin_deg
    np.testing.assert_allclose(pm, [45.13, 43.26, 40.03], atol=0.005)


def test_gains_reproduce_table_i(table1):
    # Oracle: the gains printed in the paper's Table I, to half a unit of the last digit.
    printed = {"Kq": ([65, 83, 103], 0.5), "Bq": ([0.46, 0.76, 1.02], 0.005),
               "Ktau": ([1.18, 1.80, 2.56], 0.005), "Btau": ([0.057, 0.067, 0.077], 0.0005)}
    for name, (values, half_digit) in printed.items():
        np.testing.assert_allclose(getattr(table1.gains, name), values, atol=half_digit + 1e-9)
    np.testing.assert_allclose(table1.timing.T_qs, 2e-3)   # delays_ms -> seconds


def test_broadcasting_grid_and_indexing(table1):
    d = sc.design(np.array([12.0, 14.0])[:, None], gs=[0.5, 1.0, 2.0], **TABLE_I)
    assert d.shape == (2, 3)
    m = d.margins().phase_margin_deg
    # indexing a batch gives the same designs: its margins equal the batch's entries
    np.testing.assert_allclose(d[1, 2].margins().phase_margin_deg, m[1, 2], rtol=1e-9)
    np.testing.assert_allclose(d[:, 1].margins().phase_margin_deg, table1[:2].margins()
                               .phase_margin_deg, rtol=1e-9)
    assert d.reshape(6).shape == (6,) and len(d) == 2
    # gain scale through the API. Oracle: Fig. GainScale(a), GS = 0.4 at f_n = 14 Hz on the
    # ideal loop gives a 34 deg phase margin
    pm = sc.design(14, gs=[0.4, 1.0]).margins().phase_margin_deg
    assert pm[0] == pytest.approx(34.0, abs=0.1) and pm[1] > pm[0] + 5


def test_actuator_from_toml_and_object(tmp_path):
    # Oracle: the same actuator given as an SEAParams object.
    fields = dict(motor_inertia=0.225, joint_inertia=0.014, motor_damping=1.375,
                  joint_damping=0.1, spring_stiffness=218.75, current_to_torque=5.2025)
    path = tmp_path / "mine.toml"
    path.write_text("\n".join(f"{k} = {v}" for k, v in fields.items()))
    a = sc.design(14, actuator=path).margins().phase_margin_deg
    b = sc.design(14, actuator=sc.SEAParams(**fields)).margins().phase_margin_deg
    assert a == b
    assert sc.design(14, actuator=path).actuator.name == "mine"


def test_units_are_checked_with_the_unit_in_the_message():
    # Oracle: the unit contract of the README (delays_ms refuses > 1000 ms and warns below 1
    # us; Timing takes seconds).
    with pytest.raises(sc.InputError, match=r"T_qs \[ms\] = 2000.0.*milliseconds"):
        sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2000, "damping": 0.5})
    with pytest.raises(sc.InputError, match="delays_ms.*torque, stiffness, damping"):
        sc.design(14, delays_ms={"torque": 0.5, "stifness": 2})
    with pytest.raises(sc.InputError, match=r"f_qd \[Hz\]"):
        sc.design(14, filters_hz=(-50, 100))
    with pytest.raises(sc.InputError, match=r"fn_hz \[Hz\]"):
        sc.design(0)
    with pytest.warns(sc.UnitWarning, match="milliseconds"):
        sc.design(14, delays_ms={"torque": 0.0005, "stiffness": 0.002, "damping": 0.0005})
    # Timing takes seconds: 2.0 (two seconds, meant as 2 ms) is refused, naming the unit.
    with pytest.raises(sc.InputError, match=r"T_qs \[s\] = 2.0.*Timing takes seconds"):
        Timing(0.5e-3, 2.0, 0.5e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sc.design(14, **TABLE_I)          # ordinary values: no warning


def test_infeasible_design_names_the_bound():
    # Oracle: the feasibility bound of docs/theory/gain-design.md (9.456 Hz).
    with pytest.raises(sc.InfeasibleDesignError, match=r"f_n >= 9.456 Hz"):
        sc.design(8)


def test_frd_export_matches_python_control_margins(table1):
    # Oracle: python-control's stability_margins on the exported exact-delay FRD.
    ours = table1.margins()
    for i, L in enumerate(table1.to_control("frd")):
        gm, pm, sm, wpc, wgc, wms = ct.stability_margins(L)
        assert pm == pytest.approx(ours.phase_margin_deg[i], abs=0.02)
        assert wgc / (2 * np.pi) == pytest.approx(ours.crossover_hz[i], rel=1e-3)


def test_pade_export_margins_dc_gain_and_stiffness(table1):
    d = table1[0]
    # Oracle: python-control's margin on the rational Pade model (order 3) vs exact delays.
    L = d.to_control("pade", order=3)
    assert isinstance(L, ct.TransferFunction)
    assert ct.margin(L)[1] == pytest.approx(float(d.margins().phase_margin_deg), abs=0.01)
    # Analytic: the closed loop has unit DC gain (P_CL(0) = 1) and is stable.
    C = d.to_control("pade", transfer="closed", order=3)
    assert ct.dcgain(C) == pytest.approx(1.0, rel=1e-6)
    assert np.all(C.poles().real < 0)
    # Analytic: s Z(s) -> K_q at low frequency (impedance export, state space form).
    Z = d.to_control("pade-ss", transfer="impedance", order=2)
    assert isinstance(Z, ct.StateSpace)
    w = 1e-3
    assert (1j * w * Z(1j * w)).real == pytest.approx(float(d.gains.Kq), rel=1e-4)
    with pytest.raises(sc.InputError, match="order"):
        d.to_control("pade", order=9)
    with pytest.raises(sc.InputError, match="kind"):
        d.to_control("tf")


def test_results_to_dict_is_json_and_plot_draws(table1):
    # Oracle: Table I (45.13 deg), P_CL(0) = 1 for the step, json.dumps and matplotlib's
    # axes.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = table1.margins()
    json.dumps(m.to_dict())
    rows = m.records()
    assert [r["fn_hz"] for r in rows] == [12.0, 14.0, 16.0]
    assert rows[0]["phase_margin_deg"] == pytest.approx(45.13, abs=0.005)
    z = table1.impedance([1.0, 10.0])
    assert np.shape(z.to_dict()["magnitude"]) == (3, 2)
    r = table1[1].step(t_end_s=0.3)
    # Analytic: unit steady state (P_CL(0) = 1)
    assert r.metrics.final_value == pytest.approx(1.0, abs=1e-3)
    json.dumps(r.to_dict())
    for res in (m, z, r):
        fig, ax = plt.subplots()
        assert res.plot(ax=ax) is ax and ax.lines
        plt.close(fig)


def test_rigid_latency_asymmetry_and_placement():
    # Oracle: the paper's claim for the rigid actuator (15 ms on the damping loop
    # destabilizes f_n = 12 Hz, 15 ms on the stiffness loop does not).
    assert sc.rigid(12, delays_ms={"stiffness": 15, "damping": 1}).margins().stable
    assert not sc.rigid(12, delays_ms={"stiffness": 1, "damping": 15}).margins().stable
    dm = sc.rigid(8, delays_ms={"stiffness": 1.5, "damping": 1.5}).delay_margins()
    assert dm.stiffness_s > 5 * dm.damping_s
    m = sc.latency_map(12, [1, 15], [1, 15], kind="rigid")
    assert m.map.stable.tolist() == [[True, False], [True, False]]
    json.dumps(m.to_dict())
    assert sc.place(22, 0.5).recommended == "distributed"


def test_import_is_light():
    # Oracle: sys.modules of a fresh interpreter.
    # `import seactl` must not pull in matplotlib (plots import it lazily) nor dask.
    code = "import sys, seactl; print('matplotlib' in sys.modules, 'dask' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False"]


# ---------------------------------------------------------------------------- rigid batch
def test_rigid_impedance_matches_hand_derived_formula():
    """Oracle: Z = (m s^2 + b s + K e^{-s T_s} + B s e^{-s T_d} / (T_f s + 1)) / s, derived
    by hand from the rigid loop's equations (F_des = K (x_des - x) - B Q s x)."""
    r = sc.rigid([4.0, 12.0], delays_ms={"stiffness": 15.0, "damping": 1.5})
    f = np.geomspace(0.1, 1000.0, 50)
    z = r.impedance(f).z
    d = r.rigid
    s = 2j * np.pi * f
    for i in range(2):
        K, B, tf = float(d.K[i]), float(d.B[i]), float(np.broadcast_to(d.Tf_v, (2,))[i])
        m, b = d.actuator.mass, d.actuator.damping
        ref = (m * s**2 + b * s + K * np.exp(-s * 15e-3)
               + B * s * np.exp(-s * 1.5e-3) / (tf * s + 1)) / s
        np.testing.assert_allclose(z[i], ref, rtol=1e-10)


def test_rigid_step_continuous_matches_python_control_without_delays():
    """Oracle: python-control's step response of K / (m s^2 + (b + B Q) s + K)."""
    import control as ct

    r = sc.rigid(8.0, delays_ms={"stiffness": 0.0, "damping": 0.0}, velocity_filter_hz=None)
    res = r.step(t_end_s=0.5)
    d = r.rigid
    m, b, K, B = d.actuator.mass, d.actuator.damping, float(d.K), float(d.B)
    _, y = ct.step_response(ct.tf([K], [m, b + B, K]), T=res.t_s)
    np.testing.assert_allclose(res.position, y, atol=1e-5)   # simulator accuracy ~1e-6
    assert bool(res.metrics.stable)


def test_rigid_step_sampled_matches_standalone_oracle():
    """Oracle: tests/rigid_oracle.py (independent ZOH recursion with delay buffers)."""
    from rigid_oracle import simulate_rigid_sampled

    r = sc.rigid([4.0, 12.0], delays_ms={"stiffness": 15.5, "damping": 1.5})
    res = r.step(t_end_s=0.3, mode="sampled")
    _, x, _ = simulate_rigid_sampled(r.rigid, 1.0, t_end_s=0.3, rate_hz=1000.0)
    np.testing.assert_allclose(res.position, x, atol=1e-9)


def test_rigid_to_control_frd_and_pade_agree_with_margins():
    """The exported FRD gives the same phase margin as the library (python-control's
    ct.margin on the exact-delay response); Padé(4) follows the FRD below 100 Hz."""
    import control as ct

    r = sc.rigid(8.0, delays_ms={"stiffness": 1.5, "damping": 1.5})
    f = np.geomspace(0.1, 100.0, 200)
    frd = r.to_control("frd", f_hz=np.geomspace(0.01, 1e4, 4000))
    assert float(ct.margin(frd)[1]) == pytest.approx(float(r.margins().phase_margin_deg),
                                                     abs=0.05)
    pade = r.to_control("pade", order=4, transfer="compliance")
    exact = r.to_control("frd", transfer="compliance", f_hz=f)
    w = 2 * np.pi * f
    np.testing.assert_allclose(pade(1j * w), exact.frdata[0, 0], rtol=1e-3)
    assert len(sc.rigid([8.0, 12.0]).to_control("frd")) == 2


def test_delays_and_filters_of_different_shapes_broadcast_to_a_grid():
    """Oracle: every element of the grid equals the design built with scalar values."""
    t_qs = np.array([1.0, 2.0])[:, None]
    t_qd = np.array([0.5, 1.0, 2.0])
    f_qd = np.array([50.0, 80.0])[:, None]
    grid = sc.design(14, delays_ms={"torque": 0.5, "stiffness": t_qs, "damping": t_qd},
                     filters_hz=(f_qd, 100)).margins()
    assert grid.phase_margin_deg.shape == (2, 3)
    for i in range(2):
        for j in range(3):
            one = sc.design(14, delays_ms={"torque": 0.5, "stiffness": t_qs[i, 0],
                                           "damping": t_qd[j]},
                            filters_hz=(f_qd[i, 0], 100)).margins()
            assert float(grid.phase_margin_deg[i, j]) == pytest.approx(
                float(one.phase_margin_deg), rel=1e-9)


def test_indexing_a_single_design_says_so():
    # Oracle: the error contract (numpy's 0-d IndexError, said in the design's words).
    d = sc.design(30.0)
    with pytest.raises(IndexError, match="single design"):
        d[0]
    assert d[()].shape == ()
