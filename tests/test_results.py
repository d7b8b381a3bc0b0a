"""The result family: every result is a :class:`seactl.Result` with explicit, documented
attributes whose names carry their units, and the JSON uses the same names.

Oracles: the class's own numpydoc ``Attributes`` section (read by numpydoc's parser), the
core modules' results computed directly (``seactl.systems.sea.views``, ``seactl.latency.jitter``),
the command
line's JSON, and the conversion ``<stem>_ms = 1e3 * <stem>_s``.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import json
import pkgutil
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from numpydoc.docscrape import ClassDoc

import seactl as sc
from seactl.apps.cli import main
from seactl.base.result import Renamed, Result

SRC = Path(sc.__file__).parent

# Modules whose import does work (a sweep chunk) or needs an optional front end.
SKIP_MODULES = {"seactl.sweep.template", "seactl.sweep.worker"}

# Results that are not named ``*Result``: found by subclassing, but required by name too.
REQUIRED = {"MonteCarloSummary", "LoopAnalysis", "Placements", "MobileBaseComparison"}

UNIT_SUFFIXES = ("_s", "_ms", "_hz", "_deg", "_db", "_rad", "_a", "_m", "_mps", "_pct",
                 "_samples", "_mb", "_seconds")

# Names without a unit suffix, and why.
UNITLESS = {
    **dict.fromkeys(("labels", "label"), "legend labels / label columns"),
    "seconds": "the unit is the name (a sweep's wall time)",
    "single_flip": "a boolean (a workspace map's stiffness search saw one flip)",
    "real": "the exported C's floating-point type (a word)",
    **dict.fromkeys(("stable", "uncertain", "converged", "complete", "has_crossover", "load"),
                    "a boolean"),
    **dict.fromkeys(("verdict", "kind", "mode", "model", "unit", "units", "arch", "loop",
                     "name", "baseline", "note", "max_error_text", "compiler", "reason",
                     "rate_label", "recommended", "bottleneck", "spec_hash", "actuator",
                     "amplitude_unit", "output", "output_unit", "port"),
                    "a word (a name, a unit)"),
    "amplitude": "in `amplitude_unit` (rad or m for a step, N m s or N s for an impulse, "
                 "or a loop file's unit)",
    **dict.fromkeys(("unstable_poles", "unstable_modes", "right_half_plane_roots",
                     "unstable_count", "cluster_count", "nodes", "runs", "worst_run",
                     "n_points", "n_chunks", "chunks_computed", "points_computed", "workers",
                     "n_samples", "order"), "a count or an index"),
    **dict.fromkeys(("region_right_roots", "design_right_roots", "region_pixels"),
                    "a stability chart's counts (roots, raster pixels)"),
    **dict.fromkeys(("design_stable", "consistent", "stable_mask"), "a boolean (or a mask)"),
    **dict.fromkeys(("delays", "curves", "checks"),
                    "a stability chart's delay names, and records with units in their keys"),
    **dict.fromkeys(("gain_margin", "radius", "kx_ratio", "ratio", "max_error", "p_unstable",
                     "fraction_stable", "saturation"), "a dimensionless ratio"),
    **dict.fromkeys(("roots", "spectral_abscissa", "cluster_centre", "cluster_radius",
                     "real_interval"),
                    "s-plane values in rad/s (real parts 1/s), named as python-control "
                    "names poles"),
    **dict.fromkeys(("verified", "touch"), "a boolean (a delay margin's checks)"),
    **dict.fromkeys(("mujoco_stable", "agree", "agrees"),
                    "a boolean (a robot's MuJoCo check against its verdicts)"),
    **dict.fromkeys(("factors", "envelope_ratio"), "a dimensionless ratio (MuJoCo check)"),
    **dict.fromkeys(("passive", "proven"), "a boolean (a robot's certified passivity)"),
    **dict.fromkeys(("principal_values", "hermitian_min"),
                    "in the result's own `unit` (a robot's task impedance)"),
    **dict.fromkeys(("basis", "directions"), "dimensionless unit vectors (task directions)"),
    "space": "a word (joint or task)",
    "worst": "a count or an index (the worst configuration of a workspace map)",
    **dict.fromkeys(("characteristic_loci", "min_return_difference"),
                    "dimensionless (eigenvalues and singular values of a loop matrix)"),
    "joints": "words (a workspace map's joint names)",
    "direction": "dimensionless weights d / max(d), per delay name",
    **dict.fromkeys(("z", "magnitude", "stiffness"), "in the result's own `unit`"),
    **dict.fromkeys(("position", "q_measured", "q_replay", "q_nominal", "bound"),
                    "in the system's position unit (rad or m), or relative to the step"),
    **dict.fromkeys(("rms_error", "rms_error_mean", "rms_error_worst"),
                    "relative to the step (step) or in the position unit (impulse)"),
    **dict.fromkeys(("max_damping", "max_joint_damping", "max_kx", "damping", "kx"),
                    "the paper's gain names; their units (N s/(m kg), N m s/rad, N/(m kg)) "
                    "are in the docstring"),
    **dict.fromkeys(("metrics", "result", "map", "advice", "options", "processes",
                     "controllers", "verification", "files", "breaks", "values", "results",
                     "params", "circle", "track", "summary", "outputs", "info", "samples",
                     "errors", "damping_search", "kx_search", "gain_crossovers",
                     "phase_crossovers", "blocks", "analysis", "out"),
                    "a container of named values (each unit in its own name or docstring)"),
}


def _modules() -> list:
    out = []
    for info in pkgutil.walk_packages(sc.__path__, "seactl."):
        if info.name in SKIP_MODULES:
            continue
        try:
            out.append(importlib.import_module(info.name))
        except ImportError:   # an optional front end (e.g. the explorer's bokeh)
            continue
    return out


def result_classes() -> list[type]:
    """Every class of seactl that subclasses Result, is named ``*Result`` or is required."""
    found = {}
    for mod in _modules():
        for name, cls in vars(mod).items():
            if (inspect.isclass(cls) and cls.__module__ == mod.__name__ and cls is not Result
                    and (issubclass(cls, Result) or name.endswith("Result")
                         or name in REQUIRED)):
                found[f"{mod.__name__}.{name}"] = cls
    return [found[k] for k in sorted(found)]


RESULTS = result_classes()


def public_attributes(cls: type) -> set[str]:
    """Dataclass fields and properties (old names excluded) below Result."""
    names = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    for k in cls.__mro__:
        if k in (Result, object):
            continue
        names |= {n for n, v in vars(k).items() if isinstance(v, property)
                  and not isinstance(v, Renamed) and not n.startswith("_")}
    return names


def documented(cls: type) -> set[str]:
    out = set()
    for p in ClassDoc(cls, config={"show_class_members": False})["Attributes"]:
        out |= {n.strip() for n in p.name.split(",")}
    return out


def test_the_family_is_found():
    names = {c.__name__ for c in RESULTS}
    assert {"MarginsResult", "SampledMarginsResult", "ImpedanceResult", "ResponseResult",
            "JitterResult", "RootsResult", "LatencyMapResult", "PlacementResult",
            "ExportResult", "RunResult", "SimResult", "RobustResult", "SweepResult",
            "ArchResult"} | REQUIRED <= names


@pytest.mark.parametrize("cls", RESULTS, ids=lambda c: f"{c.__module__}.{c.__name__}")
def test_every_result_is_a_result(cls):
    assert issubclass(cls, Result)
    assert not any("__getattr__" in vars(k) for k in cls.__mro__), "no attribute forwarding"
    assert cls.plot is not Result.plot, "plot() of its own"
    own = [k for k in cls.__mro__ if k is not Result]
    for method in ("to_dict", "records"):
        assert any(method in vars(k) or "_columns" in vars(k) for k in own), method


@pytest.mark.parametrize("cls", RESULTS, ids=lambda c: f"{c.__module__}.{c.__name__}")
def test_every_attribute_is_documented_with_its_unit(cls):
    doc = documented(cls)
    missing = public_attributes(cls) - doc
    assert not missing, f"not in the Attributes section: {sorted(missing)}"
    bad = {n for n in doc | public_attributes(cls)
           if not n.endswith(UNIT_SUFFIXES) and n not in UNITLESS}
    assert not bad, f"no unit in the name: {sorted(bad)}"


def test_one_name_per_class():
    # Oracle: the class statements themselves (ast), every module of the package.
    names = Counter()
    for path in SRC.rglob("*.py"):
        names.update(n.name for n in ast.parse(path.read_text()).body
                     if isinstance(n, ast.ClassDef))
    assert [n for n, c in names.items() if c > 1] == []


# ------------------------------------------------------------------ behaviour
TABLE_I = dict(delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))


def _same_name(key: str, obj: object) -> bool:
    """The JSON rule: a key is an attribute, or ``<stem>_ms`` of an attribute ``<stem>_s``."""
    return hasattr(obj, key) or (key.endswith("_ms") and hasattr(obj, key[:-3] + "_s"))


def test_margins_records_are_the_attribute_arrays():
    # Oracle: the core margins of the same batch (seactl.systems.sea.views.sea_margins), bit for
    # bit.
    from seactl.systems.sea.views import sea_margins

    d = sc.design([12, 14, 16], **TABLE_I)
    m = d.margins()
    core = sea_margins(d.sea)
    np.testing.assert_array_equal(m.phase_margin_deg, core.phase_margin_deg)
    np.testing.assert_array_equal(m.delay_margin_s, core.delay_margin_s)
    for i, row in enumerate(m.records()):
        assert row["phase_margin_deg"] == pytest.approx(core.phase_margin_deg[i], abs=1e-9)
        assert row["delay_margin_ms"] == pytest.approx(1e3 * core.delay_margin_s[i], abs=1e-9)
        assert row["stable"] is bool(core.stable[i])
        assert all(_same_name(k, m) or k in m.labels for k in row)


def test_jitter_names_match_the_json_and_the_old_names_warn():
    # Oracle: the core jitter margins (seactl.latency.jitter.sea_jitter_margins) and 1 s = 1e3 ms.
    from seactl.latency.jitter import sea_jitter_margins

    d = sc.design([12, 14], **TABLE_I)
    j = d.jitter_margins()
    core = sea_jitter_margins(d.sea)
    np.testing.assert_array_equal(j.jitter_margin_s, core.overall_s)
    np.testing.assert_array_equal(j.damping_jitter_margin_s, core.damping_s)
    doc = j.to_dict()
    assert all(_same_name(k, j) or k in j.labels for k in doc)
    for key in ("jitter_margin_ms", "stiffness_jitter_margin_ms", "damping_jitter_margin_ms",
                "torque_jitter_margin_ms"):
        attr = getattr(j, key[:-3] + "_s")
        assert doc[key] == pytest.approx(list(1e3 * attr), abs=1e-9)   # 10 digits in JSON
    for old, new in (("overall_s", "jitter_margin_s"), ("stiffness_s",
                     "stiffness_jitter_margin_s"), ("torque_s", "torque_jitter_margin_s")):
        with pytest.warns(DeprecationWarning, match=new):
            np.testing.assert_array_equal(getattr(j, old), getattr(j, new))
    with pytest.warns(DeprecationWarning):
        np.testing.assert_array_equal(j.ms("damping"), 1e3 * j.damping_jitter_margin_s)


def test_cli_json_uses_the_attribute_names(capsys):
    # Oracle: the API's JitterResult of the same designs; every key of the CLI's rows is
    # an attribute name (or its _s -> _ms form) or a label column.
    assert main(["jitter", "--fn", "12", "14", "--t-tau", "0.5", "--t-qs", "2", "--t-qd",
                 "0.5", "--f-qd", "50", "--f-taud", "100", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["designs"]
    j = sc.design([12, 14], **TABLE_I).jitter_margins()
    for row, i in zip(rows, range(2)):
        assert all(_same_name(k, j) or k in j.labels for k in row)
        assert row["jitter_margin_ms"] == pytest.approx(1e3 * j.jitter_margin_s[i], rel=1e-9)


def test_json_keys_are_attribute_names():
    # Oracle: the attributes themselves; a key is an attribute, its ms form, or a label.
    d = sc.design([12, 14], **TABLE_I)
    views = {"margins": d.margins(), "sampled": d.margins(rate_hz=1000),
             "impedance": d.impedance([1.0, 10.0]), "roots": d.roots(count=2)}
    for name, res in views.items():
        keys = set(res.to_dict()) | {k for row in res.records() for k in row}
        # a row's index; the rows under "designs" (roots); the roots' discs, per root
        keys -= {"design", "designs", "clusters"}
        labels = res.labels if isinstance(res.labels, dict) else {}
        assert {k for k in keys if not (_same_name(k, res) or k in labels)} == set(), name


def test_response_current_has_its_unit():
    # Oracle: the simulation's own output i_m [A].
    r = sc.design(14, **TABLE_I).step(t_end_s=0.05)
    np.testing.assert_array_equal(r.current_a, r.result.outputs["i_m"])
    assert r.to_dict()["current_a"] == pytest.approx(np.ravel(r.current_a).tolist())
    with pytest.warns(DeprecationWarning, match="current_a"):
        np.testing.assert_array_equal(r.current, r.current_a)
    (row,) = r.records()
    assert row["overshoot_pct"] == pytest.approx(float(r.metrics.overshoot_pct), abs=1e-9)


def test_latency_map_records_walk_the_grid():
    # Oracle: the map's own arrays, indexed [stiffness, damping].
    m = sc.latency_map(14, [0, 5, 10], [0, 1], torque_delay_ms=0.5)
    rows = m.records()
    assert len(rows) == 6
    assert [r["stiffness_delay_ms"] for r in rows] == pytest.approx([0, 0, 5, 5, 10, 10])
    assert [r["damping_delay_ms"] for r in rows] == pytest.approx([0, 1] * 3)
    assert [r["phase_margin_deg"] for r in rows] == pytest.approx(
        np.ravel(m.map.phase_margin_deg).tolist())
    assert set(m.to_dict()) - {"actuator", "kind"} <= {k for k in m.to_dict()
                                                        if _same_name(k, m)}


def test_placement_records_follow_the_options():
    # Oracle: the advice's options themselves.
    p = sc.place(22, 0.5)
    rows = p.records()
    assert [r["placement"] for r in rows] == [o.placement for o in p.advice.options]
    assert [r["fn_hz"] for r in rows] == pytest.approx([o.fn_hz for o in p.advice.options],
                                                        abs=1e-9)
    assert [r["recommended"] for r in rows].count(True) == 1


def test_loop_analysis_records_are_its_break_margins():
    # Oracle: each break's own margins, design by design; the row's stability is the loop's.
    loop = sc.load_loop(SRC.parents[1] / "examples" / "loops" / "paper-sea.toml")
    a = loop.with_values(Kq=[60.0, 83.17208068860442]).analyze(jitter=False)
    rows = a.records()
    assert len(rows) == 2 and [r["Kq"] for r in rows] == pytest.approx([60.0, 83.1720806886])
    for b in a.breaks:
        pm = np.ravel(np.broadcast_to(b.margins.phase_margin_deg, np.shape(a.stable)))
        assert [r[f"{b.name}_phase_margin_deg"] for r in rows] == pytest.approx(
            pm.tolist(), abs=1e-9)
    assert [r["stable"] for r in rows] == np.ravel(a.stable).tolist()


def test_plots_draw_on_given_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = sc.design([12, 14], **TABLE_I)
    mc = d.monte_carlo(latency={"damping": "uniform:0.5:3"}, runs=3, t_end_s=0.05)
    for res in (d.margins(), d.margins(rate_hz=1000), d.jitter_margins(),
                d.impedance([1.0, 10.0]), d.roots(count=2), d.step(t_end_s=0.05),
                d.step(t_end_s=0.05).result, mc, sc.latency_map(14, [0, 5], [0, 1]),
                sc.place(22, 0.5)):
        _, ax = plt.subplots()
        assert res.plot(ax) is ax and ax.has_data()
        plt.close("all")


def test_sweep_parameter_robustness_keeps_its_old_name():
    from seactl.sweep.robustness import RobustResult, monte_carlo

    assert monte_carlo.__doc__.startswith("Deprecated name of")
    r = RobustResult(40.0, np.array([30.0, 50.0]), np.array([True, False]), {})
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        assert r.n == r.n_samples == 2
    assert any(issubclass(x.category, DeprecationWarning) for x in w)
    assert r.records() == [{"phase_margin_deg": 30.0, "stable": True},
                           {"phase_margin_deg": 50.0, "stable": False}]
