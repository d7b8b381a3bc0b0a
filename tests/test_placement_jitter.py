"""The placement advisor with jitter: oracles are the advisor without timing (a
deterministic lossless timing must change nothing), the jitter margins recomputed at
the answer (the binding constraint sits at its limit), the timing models' closed-form
quantiles, and a Monte Carlo simulation of the recommended placement."""

from __future__ import annotations

import json
import math

import pytest

import seactl as sc
from seactl.apps.cli import main
from seactl.latency.jitter import model_jitter_margins
from seactl.latency.maps import rigid_model
from seactl.latency.models import Bernoulli, Constant, GilbertElliott, ShiftedExponential, Uniform
from seactl.latency.montecarlo import verify_placement
from seactl.latency.placement import ProcessTiming, advise


def test_process_jitter_closed_forms():
    # shifted exponential: q-quantile shift - mean ln(1 - q); Bernoulli bursts p^m <= 1 - q
    t = ProcessTiming(ShiftedExponential(7e-3, 3e-3), Bernoulli(0.01), rate_hz=500.0)
    assert t.nominal_s == 7e-3
    assert t.jitter_s == pytest.approx(-3e-3 * math.log(1e-3) + 2 / 500.0)
    assert GilbertElliott(0.01, 0.5).burst() == 1 + math.ceil(math.log(1e-3) / math.log(0.5))
    assert ProcessTiming(Uniform(1e-3, 4e-3)).jitter_s == pytest.approx(3e-3)


def test_deterministic_timing_changes_nothing():
    m = rigid_model()
    ref = advise(m, 22e-3, 0.5e-3)
    a = advise(m, 0.0, 0.0, timing={"high-level": ProcessTiming(Constant(22e-3)),
                                    "embedded": ProcessTiming(Constant(0.5e-3))})
    assert a.recommended == ref.recommended
    for o, r in zip(a.options, ref.options):
        assert o.fn_hz == pytest.approx(r.fn_hz, rel=1e-12)


@pytest.mark.slow
def test_jitter_lowers_fn_to_the_binding_margin_and_monte_carlo_agrees():
    m = rigid_model()
    timing = {"high-level": ProcessTiming(ShiftedExponential(7e-3, 3e-3)),
              "embedded": ProcessTiming(Uniform(0.5e-3, 1.5e-3), Bernoulli(0.01))}
    a = advise(m, 0.0, 0.0, timing=timing)
    ref = advise(m, 7e-3, 0.5e-3)
    assert a.recommended == "distributed"
    for o, r in zip(a.options, ref.options):
        assert o.fn_hz <= r.fn_hz * (1 + 1e-4)
    best = a.option("distributed")
    assert best.bottleneck.startswith("stiffness jitter at ")
    # recomputed independently where it binds: at the score the stiffness jitter margin
    # covers the high-level jitter at the reported latencies, and just above it does not
    need = timing["high-level"].jitter_s
    lat = best.limit["latencies_s"]
    j = model_jitter_margins(m, m.design(best.fn_hz, lat["T_s"], lat["T_d"]))
    assert float(j.stiffness_s) >= need
    j_up = model_jitter_margins(m, m.design(best.fn_hz * 1.001, lat["T_s"], lat["T_d"]))
    assert float(j_up.stiffness_s) < need
    assert "limited by stiffness jitter" in a.reason
    mc = verify_placement(m, best, timing, runs=100, seed=0)
    assert float(mc.fraction_stable) == 1.0


@pytest.mark.slow
def test_public_place_and_cli(capsys, tmp_path):
    timing = {"embedded": ProcessTiming(Uniform(0.5e-3, 1.5e-3))}
    assert sc.place(22, 0.5, timing=timing).recommended == "distributed"
    trace = tmp_path / "trace.csv"
    trace.write_text("latency_ms\n" + "\n".join(str(7 + 0.01 * i) for i in range(300)))
    assert main(["place", "--high-timing", f"hist:{trace}", "--low-timing", "uniform:0.5:1",
                 "--low-loss", "ge:0.01:0.5", "--runs", "20", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    dist = next(p for p in out["placements"] if p["placement"] == "distributed")
    assert dist["jitter_ms"]["stiffness"] == pytest.approx(2.99, abs=1e-6)
    assert dist["monte_carlo"]["runs"] == 20 and "bottleneck" in dist
    assert main(["place", "--low-loss", "0.1"]) == 2
    assert main(["place", "--high-timing", "uniform:5"]) == 2


@pytest.mark.slow
def test_timing_path_uses_the_same_monotone_score():
    # Oracle: the score's definition: the same jitter on a longer nominal latency gives a
    # box that contains the shorter one's, so no placement's score may rise (bisection
    # tolerance 1e-4); the criterion printed says jitter is part of it.
    m = rigid_model()
    short = {"high-level": ProcessTiming(Uniform(5e-3, 6e-3))}
    long = {"high-level": ProcessTiming(Uniform(9e-3, 10e-3))}
    a, b = advise(m, 0.0, 0.5e-3, timing=short), advise(m, 0.0, 0.5e-3, timing=long)
    for o, p in zip(a.options, b.options):
        assert p.fn_hz <= o.fn_hz * (1 + 1e-4)
    assert "jitter margin covers" in a.criterion


def test_no_percentage_above_all_embedded_without_its_reason():
    # With a jittery embedded process, all-embedded (stiffness and damping sharing that
    # process's jitter) scores below distributed: the advisor's own scores are the oracle.
    # The reason then gives a ratio and all-embedded's binding constraint, never "> 100 %
    # of the upper bound".
    a = advise(rigid_model(), 3.5e-3, 0.0,
               timing={"embedded": ProcessTiming(Uniform(0.5e-3, 8e-3))})
    dist, emb = a.option("distributed"), a.option("embedded")
    assert a.recommended == "distributed" and dist.fn_hz > emb.fn_hz
    assert a.fraction_of_embedded == pytest.approx(dist.static_stiffness / emb.static_stiffness)
    assert a.fraction_of_embedded > 1
    assert f"{a.fraction_of_embedded:.3g}x the static stiffness" in a.reason
    assert f"which scores lower here (all-embedded is limited by {emb.bottleneck})" in a.reason
    assert "% of the static stiffness" not in a.reason and "upper bound" not in a.reason
