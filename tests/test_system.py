"""The one system type through the public API: the SEA (:func:`seactl.design`) and the rigid
actuator (:func:`seactl.rigid`) are :class:`seactl.System` subclasses with the same verbs,
keywords and result types; delays by loop name; one default step; saturation verdicts."""

import math
import warnings

import numpy as np
import pytest

import seactl as sc

SEA_DELAYS = {"torque": 0.5, "stiffness": 2, "damping": 0.5}
RIGID_DELAYS = {"stiffness": 1.5, "damping": 1.5}


def _sea():
    return sc.design([12.0, 14.0], delays_ms=SEA_DELAYS, filters_hz=(50, 100))


def _rigid():
    return sc.rigid([8.0, 12.0], delays_ms=RIGID_DELAYS)


def _same(a, b):
    """Bit-for-bit equality of two margin results (NaN equal to NaN)."""
    for name in ("phase_margin_deg", "gain_margin_db", "delay_margin_ms", "stable"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_both_kinds_are_systems_with_the_same_verbs_and_result_types(tmp_path):
    """Oracle: the same call, keyword for keyword, on both kinds returns the same result
    class; the normalized step ends at 1 (unit static gain of both position loops, both
    critically damped without delay) and the impulse response returns to 0."""
    sea, rig = _sea(), _rigid()
    assert issubclass(type(sea), sc.System) and issubclass(type(rig), sc.System)
    results = {}
    for name, s in (("sea", sea), ("rigid", rig)):
        r = {"margins": s.margins(), "sampled": s.margins(rate_hz=1000.0),
             "roots": s.roots(count=2), "impedance": s.impedance([1.0, 10.0], port=s.ports[0]),
             "step": s.step(t_end_s=0.6, amplitude=s.default_step, mode="continuous"),
             "impulse": s.impulse(t_end_s=0.6, mode="sampled", rate_hz=1000.0),
             "jitter": s.jitter_margins(),
             "mc": s.monte_carlo("step", latency={"damping": "uniform:0.5:2"}, runs=3,
                                 seed=1, rate_hz=1000.0, t_end_s=0.3),
             "frd": s.to_control("frd", transfer="loop"),
             "export": s[0].export(tmp_path / name, lang="json", rates_hz=1000.0)}
        results[name] = r
        assert r["step"].metrics.final_value == pytest.approx(np.ones(2), abs=2e-3)
        assert np.all(np.abs(r["impulse"].position[..., -1]) < 1e-3 * np.abs(
            r["impulse"].position).max(-1))
        assert len(s.labels()) == 2 and len(s) == 2 and s.reshape(2, 1).shape == (2, 1)
    for view in results["sea"]:
        assert type(results["sea"][view]) is type(results["rigid"][view]), view


def test_named_delays_equal_the_positional_tuple_bit_for_bit():
    """Oracle: a second derivation of the same designs (the deprecated positional tuple,
    in the documented order) gives the same margins bit for bit; a loop not named has no
    delay."""
    with pytest.warns(DeprecationWarning, match="name the loops"):
        old = sc.design([12.0, 14.0], delays_ms=(0.5, 2, 0.5), filters_hz=(50, 100))
    _same(_sea().margins(), old.margins())
    with pytest.warns(DeprecationWarning, match="name the loops"):
        old = sc.rigid([8.0, 12.0], delays_ms=(1.5, 15))
    _same(sc.rigid([8.0, 12.0], delays_ms={"damping": 15, "stiffness": 1.5}).margins(),
          old.margins())
    with pytest.warns(DeprecationWarning):
        old = sc.design(14.0, delays_ms=(0, 2, 0))
    _same(sc.design(14.0, delays_ms={"stiffness": 2}).margins(), old.margins())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sc.design(14.0, delays_ms=SEA_DELAYS)          # the named form warns about nothing
        sc.rigid(8.0, delays_ms=RIGID_DELAYS)


@pytest.mark.parametrize("build, bad, names", [
    (sc.design, {"torque": 0.5, "stiff": 2}, "torque, stiffness, damping"),
    (sc.rigid, {"torque": 0.5}, "stiffness, damping"),
])
def test_an_unknown_loop_name_is_refused_naming_the_valid_ones(build, bad, names):
    # Oracle: the loop names of the issue (SEA: torque, stiffness, damping; rigid:
    # stiffness, damping).
    with pytest.raises(sc.InputError, match=f"delays_ms.*{names}"):
        build(14.0, delays_ms=bad)


def test_deprecated_keywords_warn_and_mean_the_new_ones():
    """Oracle: the new spelling on the same design gives the same arrays bit for bit."""
    d = sc.design(14.0, delays_ms=SEA_DELAYS, filters_hz=(50, 100))
    with pytest.warns(DeprecationWarning, match="impulse_nms"):
        old = d.impulse(impulse_nms=0.1, t_end_s=0.3)
    np.testing.assert_array_equal(old.position, d.impulse(amplitude=0.1, t_end_s=0.3).position)
    r = sc.rigid(12.0, delays_ms=RIGID_DELAYS)
    with pytest.warns(DeprecationWarning, match="saturate"):
        old = r.step(saturate=False, mode="sampled", amplitude=0.05, t_end_s=0.3)
    new = r.step(saturation_a=math.inf, mode="sampled", amplitude=0.05, t_end_s=0.3)
    np.testing.assert_array_equal(old.position, new.position)
    # run: the warning comes before the run is checked (a bad duration stops it there)
    with pytest.warns(DeprecationWarning, match="step_rad"), pytest.raises(sc.InputError):
        d.run(step_rad=0.01, duration_s=-1.0)
    with pytest.warns(DeprecationWarning) as caught, pytest.raises(sc.InputError):
        r.run(step_m=0.004, saturate=True, duration_s=-1.0)
    assert sorted(str(w.message).split("(")[1].split("=")[0] for w in caught) == \
        ["saturate", "step_m"]
    with pytest.raises(sc.InputError, match="impulse_nms"):
        d.impulse(impulse_nms=0.1, amplitude=0.1)


def test_one_default_step_said_in_the_result():
    """Oracle: the issue's agreed constants (SEA 0.01 rad, rigid 0.004 m), and linearity:
    the continuous step normalized by its amplitude does not depend on it."""
    assert (sc.Design.default_step, sc.Design.step_unit) == (0.01, "rad")
    assert (sc.RigidBatch.default_step, sc.RigidBatch.step_unit) == (0.004, "m")
    d = sc.design(14.0, delays_ms=SEA_DELAYS, filters_hz=(50, 100))
    r = d.step(t_end_s=0.3)
    assert (r.amplitude, r.amplitude_unit) == (0.01, "rad")
    assert r.to_dict()["amplitude"] == 0.01 and r.to_dict()["amplitude_unit"] == "rad"
    big = d.step(t_end_s=0.3, amplitude=1.0)
    np.testing.assert_allclose(big.position, r.position, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(big.current_a, 100 * r.current_a, rtol=1e-9,
                               atol=1e-9 * np.max(np.abs(big.current_a)))
    rig = sc.rigid(8.0, delays_ms=RIGID_DELAYS).step(t_end_s=0.5)
    assert (rig.amplitude, rig.to_dict()["amplitude_unit"]) == (0.004, "m")


def test_rigid_step_that_saturates_says_so_and_matches_the_clipped_oracle():
    """Oracle: at t = 0+ the force command is K x amplitude (no feedback yet), here 5 x the
    force limit beta max_current, so the force clips; tests/rigid_oracle.py (an
    independent ZOH recursion with the same clip) gives the same positions.  The default
    step (K x 0.004 m below the limit) does not clip."""
    from rigid_oracle import simulate_rigid_sampled

    r = sc.rigid(8.0, delays_ms=RIGID_DELAYS)
    limit = r.actuator.current_to_force * r.actuator.max_current
    a = 5 * limit / float(r.gains.K)
    res = r.step(mode="sampled", amplitude=a, t_end_s=0.5)
    v = res.verdict()
    assert v.verdict == ["saturated"] and "saturated" in v.warnings[0][-1]
    assert np.max(np.abs(res.current_a)) == pytest.approx(r.actuator.max_current, rel=1e-12)
    _, x, _ = simulate_rigid_sampled(r.rigid, a, t_end_s=0.5, rate_hz=1000.0,
                                     force_limit=limit)
    np.testing.assert_allclose(res.position, x / a, atol=1e-9)
    quiet = r.step(mode="sampled", t_end_s=0.5)
    assert float(r.gains.K) * r.default_step < limit
    assert quiet.verdict().verdict == ["settled"]


def test_sea_step_that_saturates_says_so():
    """Oracle: at the first tick the torque loop's proportional part alone asks for
    K_tau K_q x amplitude (the spring has not moved), above the 30 A limit for a 1 rad
    step; the current is clipped there and the verdict says 'saturated'."""
    d = sc.design(14.0, delays_ms=SEA_DELAYS, filters_hz=(50, 100))
    g = d.gains
    assert float(g.Ktau * g.Kq) * 1.0 > d.actuator.max_current
    res = d.step(mode="sampled", amplitude=1.0)
    assert res.verdict().verdict == ["saturated"]
    assert np.max(np.abs(res.current_a)) == pytest.approx(d.actuator.max_current, rel=1e-12)
    assert d.step(mode="sampled").verdict().verdict == ["settled"]


def _hand_rigid_loops(r, s):
    """The rigid loops derived by hand from F = K (x_des - e^{-s T_s} x) - B Q s e^{-s T_d} x,
    m s^2 x + b s x = F: whole loop at the sensor, and each loop with the other closed."""
    d = r.rigid
    m, b, K, B = d.actuator.mass, d.actuator.damping, float(d.K), float(d.B)
    Q = 1.0 / (float(d.Tf_v) * s + 1.0)
    P = 1.0 / (m * s**2 + b * s)
    ks, bd = K * np.exp(-s * float(d.T_s)), B * Q * s * np.exp(-s * float(d.T_d))
    return {"overall": (ks + bd) * P, "stiffness": ks * P / (1 + bd * P),
            "damping": bd * P / (1 + ks * P)}


def test_rigid_jitter_margins_against_python_control_and_hand_loops():
    """Oracle: J = 1 / max_w w |T(jw)| on a dense grid, with T = L/(1+L) from
    python-control's feedback of the exported exact-delay FRD (the whole loop), and from
    the hand-derived loops (the stiffness and damping loops alone).  The grid's maximum
    is a lower bound of the true peak, so seactl's proven margin is at most the grid's
    and within its resolution."""
    import control as ct

    r = sc.rigid(8.0, delays_ms={"stiffness": 1.5, "damping": 3.0})
    j = r.jitter_margins()
    f = np.geomspace(0.01, 1e4, 200_001)
    w = 2 * np.pi * f
    T = ct.feedback(r.to_control("frd", transfer="loop", f_hz=f), 1).frdata[0, 0]
    ref = {"overall": 1 / np.max(w * np.abs(T))}
    for loop, L in _hand_rigid_loops(r, 1j * w).items():
        ref.setdefault(loop, 1 / np.max(w * np.abs(L / (1 + L))))
    assert j.torque_jitter_margin_s is None
    for loop, value in ref.items():
        name = "jitter_margin_s" if loop == "overall" else f"{loop}_jitter_margin_s"
        got = float(getattr(j, name))
        assert got <= value * (1 + 1e-9)
        assert got == pytest.approx(value, rel=1e-4), loop


def test_rigid_monte_carlo_without_random_timing_is_the_sampled_step():
    """Oracle: a second derivation; without latency or loss models every run is the
    sampled step of :meth:`step`, so its RMS error is that of the step."""
    r = sc.rigid([8.0, 12.0], delays_ms=RIGID_DELAYS)
    mc = r.monte_carlo("step", runs=2, t_end_s=0.4)
    st = r.step(mode="sampled", t_end_s=0.4)
    rms = np.sqrt(np.mean((st.position - 1.0) ** 2, axis=-1))
    np.testing.assert_allclose(mc.rms_error_mean, rms, rtol=1e-12)
    np.testing.assert_allclose(mc.peak_current_worst_a, np.max(np.abs(st.current_a), -1),
                               rtol=1e-12)


def test_ports_and_unsupported_views_are_seactl_errors():
    # Oracle: the documented ports ("joint", "output") and the rigid's missing sweep engine.
    with pytest.raises(sc.InputError, match="port.*output"):
        _rigid().impedance([1.0], port="joint")
    with pytest.raises(sc.InputError, match="port.*joint"):
        _sea().impedance([1.0], port="output")
    with pytest.raises(sc.InputError, match="RigidBatch.sweep"):
        _rigid().sweep("unused")
    with pytest.raises(sc.InputError, match="keyword"):
        _rigid().step(zero=False)


def test_sea_sweep_around_a_design_has_its_margins(tmp_path):
    """Oracle: a second derivation; the sweep engine's phase margin of the points this
    design spans equals the API's margins of the same designs."""
    d = sc.design(14.0, delays_ms=SEA_DELAYS, filters_hz=(50, 100))
    d.sweep(tmp_path / "s", gs=[0.5, 1.0], workers=0)
    pm = sc.read_sweep(tmp_path / "s").column("phase_margin_deg").to_pylist()
    ref = sc.design(14.0, gs=[0.5, 1.0], delays_ms=SEA_DELAYS,
                    filters_hz=(50, 100)).margins().phase_margin_deg
    np.testing.assert_allclose(pm, ref, rtol=1e-9)
    with pytest.raises(sc.InputError, match="single design"):
        _sea().sweep(tmp_path / "t")
