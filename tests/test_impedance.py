"""SEA impedance: block diagram vs an independent per-frequency solve of the physical
equations, the paper's printed coefficients, asymptotes, passivity, Z-region, CLI."""

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from seactl.apps.cli import main
from seactl.certify.realpart import certify_positive
from seactl.diagram.blockdiagram import QuasiPolynomial
from seactl.errors import InfeasibleDesignError, InputError
from seactl.systems.sea.actuators import UT_SEA
from seactl.systems.sea.asymptotes import (
    asymptotes,
    high_frequency_asymptote,
    low_frequency_stiffness,
)
from seactl.systems.sea.design import critically_damped_gains
from seactl.systems.sea.impedance import (
    impedance,
    loaded_impedance_from_compliance,
    paper_coefficients,
)
from seactl.systems.sea.loops import Gains, SEADesign, Timing, outer_loop
from seactl.systems.sea.passivity import passivity
from seactl.systems.sea.zregion import excess_over_asymptotes_db, zregion

A = UT_SEA
F = np.logspace(-1, 3, 37)
TIMINGS = [Timing(), Timing.from_ms(1.0, 10.0, 3.0), Timing.from_ms(0, 0, 0, 50.0, 100.0),
           Timing.from_ms(0.7, 3.0, 1.1, 45.0, 120.0)]


def design(fn=30.0, timing=Timing(), gs=1.0):
    return SEADesign(A, critically_damped_gains(A, fn, gs=gs), timing)


def solve_physics(d, f_hz, load=False, Ij=None, bj=None):
    """Independent route: the loop's linear equations solved at each frequency.

    Unknowns x = [tau_des, e, i_m, q_m, tau_k] (+ q_j with the load).  Without load q_j = 1
    is imposed and Z = tau_k / (-s); with the load tau_ext = 1 and Z_l = 1 / (s q_j).
    """
    out = []
    for f in f_hz:
        s = 2j * np.pi * f
        Qv, Qt = 1 / (d.Tf_qd * s + 1), 1 / (d.Tf_taud * s + 1)
        Fb = d.Kq * np.exp(-s * d.T_qs) + d.Bq * Qv * s * np.exp(-s * d.T_qd)
        C = d.Ktau + d.Btau * Qt * s
        eT = np.exp(-s * d.T_tau)
        M = d.Im * s**2 + d.bm * s
        n = 6 if load else 5
        Amat = np.zeros((n, n), complex)
        b = np.zeros(n, complex)
        # tau_des + Fb q_j = 0  (q_des = 0)
        Amat[0, 0] = 1
        # e = tau_des - e^{-sT_tau} tau_k
        Amat[1, 1], Amat[1, 0], Amat[1, 4] = 1, -1, eT
        # i_m = tau_des / beta + C e
        Amat[2, 2], Amat[2, 0], Amat[2, 1] = 1, -1 / d.beta, -C
        # (I_m s^2 + b_m s) q_m = beta i_m - tau_k
        Amat[3, 3], Amat[3, 2], Amat[3, 4] = M, -d.beta, 1
        # tau_k = k (q_m - q_j)
        Amat[4, 4], Amat[4, 3] = 1, -d.k
        if load:
            Amat[0, 5] = Fb
            Amat[4, 5] = d.k
            # (I_j s^2 + b_j s) q_j = tau_k + tau_ext
            Amat[5, 5], Amat[5, 4] = Ij * s**2 + bj * s, -1
            b[5] = 1.0
            x = np.linalg.solve(Amat, b)
            out.append(1 / (s * x[5]))
        else:
            b[0] = -Fb
            b[4] = -d.k
            x = np.linalg.solve(Amat, b)
            out.append(x[4] / (-s))
    return np.array(out)


@pytest.mark.parametrize("timing", TIMINGS)
def test_block_diagram_matches_physical_equations(timing):
    # Oracle: solve_physics, the loop's linear equations solved numerically per frequency
    # (and the compliance route for the load).
    d = design(23.0, timing)
    z = impedance(d, F)
    assert z.model == "block-diagram"
    np.testing.assert_allclose(z.z, solve_physics(d, F), rtol=1e-10)
    zl = impedance(d, F, load=True).z
    np.testing.assert_allclose(zl, solve_physics(d, F, True, A.Ij, A.bj), rtol=1e-10)
    np.testing.assert_allclose(zl, loaded_impedance_from_compliance(d, F), rtol=1e-9)


def test_load_is_z_plus_inertia_and_damping():
    """Oracle: the physical equations with the load's own inertia and damping (not the
    code's Z + I s + b)."""
    d = design(20.0, TIMINGS[3])
    zl = impedance(d, F, load_inertia=0.2, load_damping=0.3).z
    np.testing.assert_allclose(zl, solve_physics(d, F, True, 0.2, 0.3), rtol=1e-10)


def test_static_stiffness_and_bare_spring():
    # Oracle: analytic limits: s Z -> K_q; without control the spring in series with the
    # free motor; the bare spring k/s with the motor locked.
    d = design(30.0, TIMINGS[3])
    assert impedance(d, [1e-5]).stiffness[0].real == pytest.approx(float(d.Kq), rel=1e-6)
    zero = SEADesign(A, Gains(0.0, 0.0, 0.0, 0.0), TIMINGS[1])
    s = 2j * np.pi * F
    # no control: the motor is free, Z = series spring + motor: (k M/(M+k))/s, M = I_m s^2 + b_m s
    M = A.Im * s**2 + A.bm * s
    np.testing.assert_allclose(impedance(zero, F).z, A.k * M / (M + A.k) / s, rtol=1e-12)
    # motor locked (huge inertia): the bare spring k/s
    locked = SEADesign(UT_SEA.__class__(**{**UT_SEA.__dict__, "motor_inertia": 1e12}),
                       Gains(0.0, 0.0, 0.0, 0.0))
    np.testing.assert_allclose(impedance(locked, F).z, A.k / s, rtol=1e-6)


def test_batch_shapes_and_chunking(monkeypatch):
    # Oracle: each design evaluated alone, unchunked.
    import seactl.systems.sea.impedance as imp

    g = critically_damped_gains(A, np.array([12.0, 20.0, 30.0])[:, None],
                                gs=np.array([0.8, 1.0])[None, :])
    d = SEADesign(A, g, TIMINGS[3])
    z = impedance(d, F).z
    assert z.shape == (3, 2, F.size)
    monkeypatch.setattr(imp, "_CHUNK_POINTS", 50)  # forces design chunks of 1
    np.testing.assert_allclose(impedance(d, F).z, z, rtol=1e-14)
    for i, j in [(0, 0), (2, 1)]:
        one = SEADesign(A, g[i, j], TIMINGS[3])
        np.testing.assert_allclose(z[i, j], impedance(one, F).z, rtol=1e-13)


def test_linear_units():
    """Oracle: the physical equations solved in pushrod units with the printed linear
    parameters (docs/theory/units.md: 360 kg, 2200 N s/m, 350 000 N/m, 208.1 N/A) and the
    gains converted by hand (F = tau/r, x = r q: K_q/r^2, B_q/r^2, K_tau r, B_tau r)."""
    d = design(20.0, TIMINGS[1])
    r = 0.025
    lin = SimpleNamespace(Im=360.0, bm=2200.0, k=350000.0, beta=208.1, Kq=d.Kq / r**2,
                          Bq=d.Bq / r**2, Ktau=d.Ktau * r, Btau=d.Btau * r, T_qs=d.T_qs,
                          T_qd=d.T_qd, T_tau=d.T_tau, Tf_qd=d.Tf_qd, Tf_taud=d.Tf_taud)
    zl = impedance(d, F, units="linear")
    assert zl.unit == "N s/m"
    # 208.1 N/A is rounded (5e-6 relative)
    np.testing.assert_allclose(zl.z, solve_physics(lin, F), rtol=1e-4)


# ----------------------------------------------------------------------------- paper model
def printed(d, s, kt):
    """A second transcription of a few printed coefficients (eq. SEA_impedance)."""
    eqs, eT = np.exp(-s * d.T_qs), np.exp(-s * d.T_tau)
    return dict(N4=A.Im * d.Tf_taud * d.Tf_qd * A.beta * A.k,
                N0=d.Kq * A.k * kt * eqs * (1 + d.Ktau * A.beta),
                D5=A.Im * d.Tf_taud * d.Tf_qd * A.beta,
                D1=A.beta * A.k * (1 + d.Ktau * kt * eT))


@pytest.mark.parametrize("timing", TIMINGS)
def test_paper_model(timing):
    # Oracle: printed(), a second transcription of four printed coefficients, and the block
    # diagram when k_tau = beta (docs/theory/ktau-beta.md).
    d = design(30.0, timing)
    s = 2j * np.pi * F
    N, D = paper_coefficients(d, s)
    p = printed(d, s, A.motor_torque_constant)
    for key, got in (("N4", N[4]), ("N0", N[0]), ("D5", D[5]), ("D1", D[1])):
        np.testing.assert_allclose(got, np.broadcast_to(p[key], got.shape), rtol=1e-13)
    np.testing.assert_array_equal(D[0], 0)
    z = impedance(d, F, model="paper")
    assert z.model == "paper"
    # the evaluated model tends to the limits fixed by the transcribed coefficients:
    # s Z -> N0/D1 (s -> 0) and, with filters, s Z -> N4/D5 (s -> infinity)
    ends = 2j * np.pi * np.array([1e-6, 1e7])
    sz = ends * impedance(d, [1e-6, 1e7], model="paper").z
    lo, hi = (printed(d, s_end, A.motor_torque_constant) for s_end in (0.0, ends[1]))
    assert sz[0] == pytest.approx(complex(lo["N0"] / lo["D1"]), rel=1e-6)
    if timing.f_qd is not None:
        assert sz[1] == pytest.approx(hi["N4"] / hi["D5"], rel=1e-6)
    # equals the block diagram only with k_tau replaced by beta (docs/theory/ktau-beta.md)
    np.testing.assert_allclose(impedance(d, F, model="paper", k_tau=A.beta).z,
                               impedance(d, F).z, rtol=1e-10)
    assert np.max(np.abs(z.z / impedance(d, F).z - 1)) > 0.1


def test_paper_low_frequency_stiffness_value():
    """Oracles: lim s Z = N0/D1 of the test's own transcription of the printed coefficients,
    the 72.9 / 293.6 N m/rad of docs/theory/ktau-beta.md, and the model evaluated near 0 Hz."""
    d = design(30.0)
    p = printed(d, 0.0, A.motor_torque_constant)
    expect = p["N0"] / p["D1"]
    assert float(low_frequency_stiffness(d, "paper")) == pytest.approx(float(expect), rel=1e-12)
    assert float(expect) == pytest.approx(72.9, abs=0.05)  # docs/theory/ktau-beta.md
    assert float(low_frequency_stiffness(d)) == pytest.approx(293.6, abs=0.05)
    for t in TIMINGS:
        z = impedance(design(30.0, t), [1e-5], model="paper")
        assert z.stiffness[0].real == pytest.approx(72.887, abs=1e-3)


# ----------------------------------------------------------------------------- asymptotes
@pytest.mark.parametrize("model", ["block-diagram", "paper"])
@pytest.mark.parametrize("timing", TIMINGS)
def test_asymptotes_at_extreme_frequencies(model, timing):
    # Oracle: the impedance itself at 1e-5 and 1e6 Hz (the asymptotes are its limits), the
    # bare spring k/s with filters, and the physical equations at 1 MHz (below).
    d = design(25.0, timing)
    a = asymptotes(d, [1e-5, 1e6], model=model)
    z = impedance(d, [1e-5, 1e6], model=model).z
    assert abs(z[0] / a.low[0] - 1) < 1e-4
    assert abs(z[1] / a.high[1] - 1) < 1e-4
    s = 2j * np.pi * 1e6
    if timing.f_qd is not None:  # filters: the bare spring k/s
        assert a.high[1] == pytest.approx(A.k / s, rel=1e-12)
    elif model == "block-diagram":
        # Oracle: the physical equations solved at 1 MHz (not the asymptote's formula);
        # the O(1/w) remainder is below 1e-4 there
        assert a.high[1] == pytest.approx(solve_physics(d, [1e6])[0], rel=3e-4)


def test_load_asymptotes_and_spike():
    # Oracle: the loaded impedance itself at 1e-5 and 1e6 Hz (the asymptotes must be its
    # limits).
    d = design(20.0, Timing.from_ms(1.0, 10.0, 1.0, 50.0, 100.0))
    a = asymptotes(d, [1e-5, 1e6], load_inertia=[0.014, 0.2], load_damping=0.1)
    z = impedance(d, [1e-5, 1e6], load_inertia=[0.014, 0.2], load_damping=0.1)
    np.testing.assert_allclose(z.z[:, 1] / a.high[:, 1], 1, atol=1e-6)
    np.testing.assert_allclose(z.z[:, 0] / a.low[:, 0], 1, atol=1e-4)
    # excess over the envelope is ~0 where an asymptote is exact
    assert np.all(np.abs(excess_over_asymptotes_db(z, a)) < 1e-3)
    with pytest.raises(InputError, match="load_inertia"):
        impedance(d, F, load_inertia=-1.0)


def test_high_frequency_asymptote_case_mix():
    """Oracle: each design of a mixed batch (ideal, filtered) solved alone from the physical
    equations at 1 MHz (the asymptote's O(1/w) remainder is ~1e-4 there)."""
    g = critically_damped_gains(A, np.array([20.0, 20.0]))
    T_qd, f_qd = np.array([0.0, 0.002]), np.array([np.inf, 40.0])
    h = high_frequency_asymptote(SEADesign(A, g, Timing(T_qd=T_qd, f_qd=f_qd)), [1e6])
    for i in range(2):
        one = SEADesign(A, g[i], Timing(T_qd=T_qd[i], f_qd=f_qd[i]))
        assert h[i, 0] == pytest.approx(solve_physics(one, [1e6])[0], rel=3e-4)
    # the ideal one keeps the torque-derivative lift 1 + beta B_tau B_q / I_m (~4 at 20 Hz)
    assert abs(h[0, 0] / h[1, 0]) > 3


# ----------------------------------------------------------------------------- passivity
def test_passivity_bands_on_a_built_non_passive_case():
    # Oracle: a brute-force dense scan of Re Z, and Re Z = 0 at each band edge.
    # Stiffness delay only: Z = K/s e^{-sT} + ... and Re(K e^{-jwT}/(jw)) = -K sin(wT)/w < 0
    # for 0 < wT < pi: with a large T the band starts at the scan start and ends near
    # f = 1/(2T) where the delay term's real part changes sign (other terms shift it a bit).
    d = design(15.0, Timing(T_qs=0.05))
    p = passivity(d, (0.01, 5.0))
    assert not p.passive
    b = p.bands_hz[()]
    assert b[0, 0] == 0.01
    z_in = impedance(d, [np.sqrt(b[0, 0] * b[0, 1])]).z[0]
    assert z_in.real < 0
    # edges are exact roots of Re Z
    for edge in b.ravel():
        if 0.01 < edge < 5.0:
            z = impedance(d, [edge]).z[0]
            assert abs(z.real) < 1e-8 * abs(z)
    # compare to a brute-force dense scan
    f = np.logspace(-2, np.log10(5.0), 200001)
    neg = impedance(d, f).z.real < 0
    dense_edges = f[1:][neg[1:] != neg[:-1]]
    inner = b.ravel()[(b.ravel() > 0.01) & (b.ravel() < 5.0)]
    np.testing.assert_allclose(np.sort(inner), dense_edges, rtol=1e-4)


def test_passive_ideal_and_load_damping_helps():
    # Oracle: Re Z_l = Re Z + b_j: load damping above the worst negative Re Z of a dense
    # scan restores passivity.
    assert bool(passivity(design(30.0), (0.1, 1000.0)).passive)
    d = design(20.0, Timing(T_qs=0.02))  # K_q T_qs = 3 Nms/rad > B_q: negative damping
    assert not bool(passivity(d, (0.1, 100.0)).passive)
    # Re Z_l = Re Z + b_j: enough joint damping restores passivity at low frequency
    worst = -impedance(d, np.logspace(-1, 2, 2000)).z.real.min()
    assert bool(passivity(d, (0.1, 100.0), load_damping=1.01 * worst).passive)


def test_bad_input():
    # Oracle: the error contract (InputError naming the parameter).
    d = design(20.0)
    with pytest.raises(InputError, match="model"):
        impedance(d, F, model="matlab")
    with pytest.raises(InputError, match="f_hz"):
        impedance(d, [0.0, 1.0])
    with pytest.raises(InputError, match="f_hz"):
        impedance(d, [np.nan])
    with pytest.raises(InputError, match="units"):
        impedance(d, F, units="imperial")
    with pytest.raises(InputError, match="k_tau"):
        impedance(d, F, model="paper", k_tau=-1)
    with pytest.raises(InputError, match="f_range_hz"):
        passivity(d, (10.0, 1.0))


# ----------------------------------------------------------------------------- Z-region
def brute_force_pm_deg(d, n=2001):
    """Phase margin from a dense scan of the exact-delay outer loop (single crossing)."""
    L = outer_loop()(d, 2j * np.pi * np.geomspace(1.0, 1000.0, n)).reshape(-1, n)
    cross = (np.abs(L[:, :-1]) >= 1) != (np.abs(L[:, 1:]) >= 1)
    assert np.all(cross.sum(axis=1) == 1)
    return 180 + np.degrees(np.angle(L[np.arange(len(L)), np.argmax(cross, axis=1)]))


def test_zregion_width_and_depth():
    """Oracles: admissibility from a brute-force phase-margin scan (not the code's filter;
    the Table I timings keep all nine stable), |Z| from impedance() (checked against the
    physical equations above), and s Z -> K_q for the low-frequency width."""
    fn = np.array([12.0, 16.0, 20.0])
    gs = np.array([0.8, 1.0, 1.25])
    d = SEADesign(A, critically_damped_gains(A, fn[:, None], gs=gs[None, :]),
                  Timing.from_ms(0.5, 2.0, 0.5, 50.0, 100.0))
    f = np.logspace(-3, 5, 81)
    reg = zregion(d, f, min_pm_deg=30.0, threshold_db=6.0)
    mag = impedance(d, f).magnitude.reshape(9, -1)
    pm = brute_force_pm_deg(d)
    assert np.all(np.abs(pm - 30.0) > 1.0)     # no design near the threshold
    ok = pm >= 30.0
    np.testing.assert_array_equal(reg.admissible.ravel(), ok)
    assert ok.sum() == reg.n_admissible == 8   # 20 Hz at GS = 0.8 has about 25 deg
    np.testing.assert_allclose(reg.z_max, mag[ok].max(axis=0))
    np.testing.assert_allclose(reg.z_min, mag[ok].min(axis=0))
    kq = np.asarray(d.Kq).ravel()[ok]
    assert reg.width_db[0] == pytest.approx(20 * np.log10(kq.max() / kq.min()), abs=1e-3)
    assert reg.width_db[-1] < 0.01  # all tend to k/s with filters
    lo, hi = reg.depth_hz
    assert lo == f[0] and f[0] < hi < f[-1]
    k = np.searchsorted(f, hi)
    assert np.all(reg.width_db[:k] >= 6.0) and reg.width_db[k] < 6.0
    with pytest.raises(InfeasibleDesignError, match="no admissible design"):
        zregion(d, f, min_pm_deg=89.0)


# ----------------------------------------------------------------------------- CLI
def test_cli_impedance_json_and_files(tmp_path, capsys):
    # Oracle: the library's impedance() and passivity() for the same design; PNG magic
    # bytes; CSV row count.
    png, csv = tmp_path / "z.png", tmp_path / "z.csv"
    rc = main(["impedance", "--fn", "30", "--t-tau", "1", "--t-qs", "10", "--t-qd", "3",
               "--freq", "1", "10", "100", "--json", "--full", "--plot", str(png),
               "--csv", str(csv)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "block-diagram"
    assert out["f_hz"] == [1.0, 10.0, 100.0]
    d = design(30.0, Timing.from_ms(1, 10, 3))
    z = impedance(d, [1.0, 10.0, 100.0])
    np.testing.assert_allclose(out["magnitude"], z.magnitude, rtol=1e-9)
    np.testing.assert_allclose(out["magnitude_db"], z.magnitude_db, rtol=1e-9)
    np.testing.assert_allclose(out["phase_deg"], z.phase_deg, rtol=1e-9)
    p = passivity(d, (1.0, 100.0))
    assert out["passive"] is False
    np.testing.assert_allclose(out["non_passive_bands_hz"], p.bands_hz[()], rtol=1e-12)
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    lines = csv.read_text().splitlines()
    assert len(lines) == 4 and lines[0].startswith("fn_hz,gs,f_hz")
    assert not [x for x in tmp_path.iterdir() if x.name.startswith(".")]  # no temp left


def test_cli_impedance_paper_model_and_errors(capsys):
    # Oracle: docs/theory/ktau-beta.md (72.9 N m/rad) and the CLI error contract.
    assert main(["impedance", "--fn", "30", "--freq", "0.001", "--model", "paper",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "paper"
    assert out["low_frequency_stiffness"] == pytest.approx(72.887, abs=1e-3)
    assert main(["impedance", "--fn", "30", "--freq", "0:1:3"]) == 2
    assert "--freq" in capsys.readouterr().err
    assert main(["impedance", "--fn", "30", "--plot", "z.jpg"]) == 2
    assert main(["impedance", "--fn", "30", "--model", "x"]) != 0


def test_cli_zregion(tmp_path, capsys):
    # Oracle: the grid sizes given on the command line (2 x 2 designs, 41 frequencies) and
    # the CLI error contract.
    rc = main(["zregion", "--fn", "12", "16", "--gs", "0.8", "1", "--t-tau", "0.5",
               "--t-qs", "2", "--t-qd", "0.5", "--f-qd", "50", "--f-taud", "100",
               "--freq", "0.1:1000:41", "--json", "--full", "--plot", str(tmp_path / "zr.svg")])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_designs"] == 4 and len(out["width_db"]) == 41
    assert (tmp_path / "zr.svg").read_text().lstrip().startswith("<?xml")
    assert main(["zregion", "--fn", "12", "--min-pm", "89"]) == 2
    assert "no admissible design" in capsys.readouterr().err


# A design at the edge of passivity (found by bisecting a delay scale between a passive
# and a non-passive design): its only band, 0.03 Hz wide at 120 Hz, falls between two
# points of the 400-per-decade scan.
EDGE = dict(fn=32.627, gs=2.638, zeta1=1.226, f_qd=7.591, f_taud=181.577,
            T_ms=(0.04807951841391078, 0.22716416692918664, 0.005200909443812464))


def edge_design(scale=1.0):
    t = np.array(EDGE["T_ms"]) * scale
    g = critically_damped_gains(A, EDGE["fn"], gs=EDGE["gs"], zeta1=EDGE["zeta1"])
    return SEADesign(A, g, Timing.from_ms(*t, EDGE["f_qd"], EDGE["f_taud"]))


def dense_bands(d, lo, hi, n=400_001):
    """Oracle: where ``Re Z < -1e-9 |Z|`` (passivity's criterion) starts or ends on a
    uniform grid of n points."""
    f = np.linspace(lo, hi, n)
    z = impedance(d, f).z
    neg = z.real < -1e-9 * np.abs(z)
    return f[1:][neg[1:] != neg[:-1]]


def test_passivity_finds_a_band_between_the_scan_points():
    # Oracle: a brute-force scan of Re Z on 400,001 points from 119 to 121 Hz; the band
    # lies between two points of the scan's own grid (so the scan alone says "passive").
    d = edge_design()
    edges = dense_bands(d, 119.0, 121.0)
    assert edges.size == 2 and edges[1] - edges[0] < 0.05
    grid = np.logspace(-2, 3, 5 * 400 + 1)
    assert not ((grid > edges[0]) & (grid < edges[1])).any()
    p = passivity(d, (0.01, 1e3))
    assert not p.passive and p.proven
    np.testing.assert_allclose(p.bands_hz[()].ravel(), edges, rtol=1e-7)


@pytest.mark.parametrize("scale", [0.999, 0.99, 0.9])
def test_passivity_proof_just_short_of_the_edge(scale):
    # Oracle: the same brute-force scan finds Re Z > 0 everywhere around 120 Hz (its
    # minimum) and a 20,000-per-decade scan of the whole range finds no Re Z < 0.
    d = edge_design(scale)
    p = passivity(d, (0.01, 1e3))
    assert p.passive and p.proven
    assert dense_bands(d, 119.0, 121.0).size == 0
    f = np.logspace(-2, 3, 100_001)
    assert impedance(d, f).z.real.min() > 0


def test_passivity_of_a_lossless_design_is_not_proven(capsys):
    # Oracle: with no damping anywhere (b_m = 0, B_q = B_tau = 0, no delays) Re Z = 0 at
    # every frequency, which no bound can tell from a dip below 0: "not proven", and not
    # passive (the scan's tolerance alone once called it passive).
    d = SEADesign(replace(A, motor_damping=0.0), Gains(300.0, 0.0, 2.0, 0.0), Timing())
    z = impedance(d, np.logspace(-1, 2, 31)).z
    assert np.all(np.abs(z.real) <= 1e-12 * np.abs(z))
    p = passivity(d, (0.1, 100.0))
    assert not p.passive and not p.proven and p.bands_hz[()].size == 0
    # a damped design's proof: passive, proven
    q = passivity(design(30.0), (0.1, 100.0))
    assert q.passive and q.proven


@pytest.mark.parametrize("c, passive, proven", [(1 + 1e-6, True, True),
                                                (1 - 1e-8, False, True),
                                                (1.0, False, False)])
def test_certify_positive_on_a_cosine(c, passive, proven):
    # Oracle: Z = N / (jw D) with N = s (c + e^{-s tau}), D = 1 has Re Z = c + cos(w tau):
    # a dip to c - 1 at w tau = pi (1e-6 above 0, 1e-8 below it over 2.8e-4 rad, or
    # touching 0), between two points of a 5-point grid.
    tau = 0.01
    N = QuasiPolynomial(np.array([[[0.0, c]], [[0.0, 1.0]]]), np.array([[0.0], [tau]]))
    D = QuasiPolynomial(np.array([[[1.0, 0.0]]]), np.array([[0.0]]))
    w = np.array([1.0, 50.0, 290.0, 330.0, 400.0])
    ok, found = certify_positive(N, D, np.zeros(1), w, 1e-9)
    assert ok[0] == passive
    assert (~np.isnan(found)).any() == (proven and not passive)
    if not passive and proven:
        k = np.nonzero(~np.isnan(found[0]))[0]
        assert k.tolist() == [2]  # between 290 and 330 rad/s
        assert abs(found[0, 2] * tau - np.pi) < 2e-4
        assert c + np.cos(found[0, 2] * tau) < 0


@pytest.mark.parametrize("scale", [1.0, 0.99])
def test_cli_impedance_passivity_at_the_edge(scale, capsys):
    # Oracle: the library's passivity() of the same design (tested above against a
    # brute-force scan): a band 0.03 Hz wide found, or passive and proven.
    t = [repr(float(x) * scale) for x in EDGE["T_ms"]]
    rc = main(["impedance", "--fn", repr(EDGE["fn"]), "--gs", repr(EDGE["gs"]),
               "--zeta1", repr(EDGE["zeta1"]), "--t-tau", t[0], "--t-qs", t[1],
               "--t-qd", t[2], "--f-qd", repr(EDGE["f_qd"]),
               "--f-taud", repr(EDGE["f_taud"]), "--freq", "0.01:1000:3", "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    p = passivity(edge_design(scale), (0.01, 1000.0))
    assert out["passive"] is bool(p.passive) is (scale < 1)
    assert out["passivity_proven"] is True
    np.testing.assert_allclose(np.reshape(out["non_passive_bands_hz"], (-1, 2)),
                               p.bands_hz[()], rtol=1e-12)


def test_cli_the_paper_models_passivity_is_scan_only(capsys):
    # Oracle: the documented contract: the paper model's "passive" is its scan's, never
    # proven (below its 9.2 Hz band at f_n = 30 Hz it is passive).
    assert main(["impedance", "--fn", "30", "--model", "paper", "--freq", "0.1:5:5",
                 "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["passive"] is True and r["passivity_proven"] is False
    assert main(["impedance", "--fn", "30", "--model", "paper", "--freq", "0.1:5:5"]) == 0
    assert "yes (scan only)" in capsys.readouterr().out
