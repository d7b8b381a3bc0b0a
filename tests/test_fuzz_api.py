"""Fuzz the Python API and loop files (issue 36, item 8): hypothesis draws loop files
(structurally plausible TOML: variables, parameters, processes, blocks of every kind, their
expressions, delays, breaks, ports and analysis ranges, with NaN, inf, huge, negative and
wrongly typed values and units glued to numbers) and calls of the public functions
(``sc.design``, ``sc.rigid``, ``sc.load_loop``, ``sc.LoopBuilder`` and their views with
values of every type and shape).

Oracle: the contract of the README, observed from outside: every call returns a result or
raises a :class:`seactl.SeactlError` (never another exception type) and finishes within
:data:`CPU_BOUND_S` of CPU time (sizes are bounded and ``SEACTL_MAX_SECONDS`` is lowered to
10 s, so a hang is a budget the code did not check).  Runs in the default suite with a
fixed, derandomized budget of examples; what it found is kept below as plain tests.
"""

from __future__ import annotations

import math
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import seactl as sc

CPU_BOUND_S = 90.0
"""CPU time of one call, the first compilation of the simulation's kernels included."""
LOOP_EXAMPLES = 100
API_EXAMPLES = 150
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "loops"

# ------------------------------------------------------------------ values
SPECIAL = [0.0, -1.0, 1.0, 0.5, 14.0, 1e308, -1e308, 1e-308, math.nan, math.inf, -math.inf,
           1e6, 1e-9, 2000.0]
UNITS = ["2ms", "14 Hz", "", "x", "1e3", "nan", "0x10", "1_000"]
TOML_NUM = ["0.0", "-1.0", "1.0", "0.3", "14.0", "50.0", "1e308", "-1e308", "1e-308", "nan",
            "inf", "-inf", "1e6", "2000", "1" + "0" * 30, "true", '"2ms"', '"14 Hz"', "[1, 2]",
            "{ a = 1 }", '""']
NAMES = ["m", "k", "fn", "K", "b"]
PROCESS = '"process"'
LATENCIES = ["0.5", "2", "-1", "1e308", '"fn"', '"2ms"']
FUNCS = ["sqrt", "exp", "log", "log10", "sin", "cos", "tan", "atan", "abs", "min", "max",
         "hypot", "foo"]


GOOD_NUM = ["1.0", "0.3", "2.0", "14.0", "50.0", "200.0"]
GOOD_FUNCS = {"sqrt": 1, "exp": 1, "log": 1, "abs": 1, "atan": 1, "min": 2, "max": 3,
              "hypot": 2}


def rarely():
    """True once in 12 draws (hypothesis favours the first of a sampled list)."""
    return st.sampled_from(range(12)).map(lambda i: i == 11)


@st.composite
def pick(draw, good, bad):
    """A valid value most of the time (so that files reach the analysis), else a bad one."""
    return draw(bad if draw(rarely()) else good)


@st.composite
def good_expr(draw, depth: int = 0) -> str:
    """A valid positive-ish expression of the variables m, k, fn (always declared)."""
    leaf = st.sampled_from(["m", "k", "fn", "2", "0.5", "pi"])
    if depth >= 2 or draw(st.booleans()):
        return draw(leaf)
    if draw(st.booleans()):
        f = draw(st.sampled_from(sorted(GOOD_FUNCS)))
        args = [draw(good_expr(depth + 1)) for _ in range(GOOD_FUNCS[f])]
        return f"{f}({', '.join(args)})"
    op = draw(st.sampled_from(["+", "*", "^"]))
    return f"({draw(good_expr(depth + 1))} {op} {draw(good_expr(depth + 1))})"


@st.composite
def expr(draw, depth: int = 0) -> str:
    """Any expression string: numbers (edge values), names (known or not), operators and
    calls with any number of arguments."""
    leaf = st.sampled_from(["1", "0", "2.5", "1e308", "-3", "pi", "e", "1e-308", "nope",
                            "2ms", "1e999", *NAMES])
    if depth >= 3 or draw(st.integers(0, 2)) == 0:
        return draw(leaf)
    kind = draw(st.sampled_from(["op", "call", "neg", "paren"]))
    if kind == "op":
        op = draw(st.sampled_from(["+", "-", "*", "/", "^", "**", "%", "//", "<"]))
        return f"{draw(expr(depth + 1))} {op} {draw(expr(depth + 1))}"
    if kind == "call":
        args = draw(st.lists(expr(depth + 1), max_size=3))
        return f"{draw(st.sampled_from(FUNCS))}({', '.join(args)})"
    return f"-{draw(expr(depth + 1))}" if kind == "neg" else f"({draw(expr(depth + 1))})"


def field_value():
    """A TOML value for a numeric field: mostly a valid number or expression; else a
    literal of any type or any expression."""
    return pick(st.one_of(st.sampled_from(GOOD_NUM), good_expr().map(lambda e: f'"{e}"')),
                st.one_of(st.sampled_from(TOML_NUM), expr().map(lambda e: f'"{e}"')))


CONTROLLERS = {"pd": ["kp", "kd", "filter_hz"], "gain": ["gain"],
               "pid": ["kp", "ki", "kd", "filter_hz"], "lowpass1": ["f_hz", "gain"],
               "lowpass2": ["f_hz", "zeta"], "notch": ["f_hz", "zeta_num", "zeta_den"],
               "leadlag": ["zero_hz", "pole_hz"], "delay": [], "tf": ["num", "den"],
               "sum": [], "dob": ["nominal_num", "nominal_den", "q_hz", "q_order"]}
PLANTS = {"inertia": ["inertia", "damping"], "load": ["inertia", "stiffness"],
          "plant_tf": ["num", "den"], "spring": ["stiffness"], "damper": ["damping"]}
LISTS = {"num", "den", "nominal_num", "nominal_den"}


@st.composite
def block_fields(draw, fields: list[str]) -> str:
    out = ""
    for f in fields:
        if draw(rarely()):
            continue  # a required field missing, or a default
        if f in LISTS:
            n = draw(pick(st.integers(1, 3), st.integers(0, 4)))
            vals = [draw(field_value()) for _ in range(n)]
            out += f"{f} = [{', '.join(vals)}]\n"
        elif f == "q_order":
            order = pick(st.sampled_from(["1", "2"]), st.sampled_from(["0", "5", "2.5", "4"]))
            out += f"q_order = {draw(order)}\n"
        else:
            out += f"{f} = {draw(field_value())}\n"
    if draw(rarely()):
        out += f"{draw(st.sampled_from(['gian', 'f_hz', 'process']))} = 1.0\n"
    return out


@st.composite
def loop_text(draw) -> str:
    """A loop file: variables m, k, fn (and sometimes more), parameters, a process, a
    controller of any kind between the reference and a plant of any kind, a sensor, a
    break, sometimes a port and an analysis range; any value may be out of range or of
    the wrong type."""
    text = 'name = "fuzz"\n[variables]\n'
    for n in ["m", "k", "fn", *draw(st.lists(st.sampled_from(["K", "b"]), max_size=1))]:
        text += f"{n} = {draw(pick(st.sampled_from(GOOD_NUM), st.sampled_from(TOML_NUM)))}\n"
    params = draw(st.lists(st.sampled_from(["P", "Q"]), max_size=2, unique=True))
    if params:
        text += "[parameters]\n" + "".join(
            f'{p} = "{draw(pick(good_expr(), expr()))}"\n' for p in params)
    rate = draw(pick(st.sampled_from(["1000", "500"]), st.sampled_from(["0", "nan", '"1k"'])))
    latency = draw(pick(st.sampled_from(["0.5", "2", '"fn / 10"']), st.sampled_from(LATENCIES)))
    text += f"[processes.cpu]\nrate_hz = {rate}\nlatency_ms = {latency}\n"
    output = draw(pick(st.just("y"), st.just("nosuch")))
    text += ('[signals]\ninputs = ["r", "d"]\nreference = "r"\ndisturbance = "d"\n'
             f'output = "{output}"\n')
    kind = draw(st.sampled_from(list(CONTROLLERS)))
    text += (f'[[blocks]]\nname = "c"\nkind = "{kind}"\ninput = ["r", "-y_m"]\n'
             'output = "u"\nprocess = "cpu"\n' + draw(block_fields(CONTROLLERS[kind])))
    if kind == "dob":
        text += 'measurement = "y"\n'
    if kind == "delay" or draw(st.booleans()):
        text += f"delay_ms = {draw(st.one_of(field_value(), st.just(PROCESS)))}\n"
    plant = draw(st.sampled_from(list(PLANTS)))
    text += (f'[[blocks]]\nname = "p"\nkind = "{plant}"\ninput = ["u", "d"]\noutput = "y"\n'
             + draw(block_fields(PLANTS[plant])))
    signal = draw(pick(st.just("y_m"), st.sampled_from(["u", "r"])))
    text += ('[[blocks]]\nname = "s"\nkind = "sensor"\ninput = "y"\noutput = "y_m"\n'
             f'[[breaks]]\nname = "main"\nsignal = "{signal}"\n')
    if draw(st.booleans()):
        text += '[[ports]]\nname = "out"\nposition = "y"\nforce = "u"\n'
    if draw(rarely()):
        key = draw(st.sampled_from(["f_min_hz", "f_max_hz"]))
        f_hz = pick(st.sampled_from(["0.01", "1000.0"]), st.sampled_from(TOML_NUM))
        text += f"[analysis]\n{key} = {draw(f_hz)}\n"
    return text


def contract(call):
    """Run ``call``: a result or a SeactlError, within the CPU bound (warnings are the
    command line's concern: tests/test_fuzz.py)."""
    c0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            result = call()
        except sc.SeactlError:
            result = None
    assert time.process_time() - c0 < CPU_BOUND_S
    return result


@pytest.fixture(autouse=True)
def _small_time_budget(monkeypatch):
    monkeypatch.setenv("SEACTL_MAX_SECONDS", "10")


def _views(loop) -> None:
    loop.analyze(jitter=False)
    if loop.ports:
        loop.impedance([1.0, 100.0])


@settings(max_examples=LOOP_EXAMPLES, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(loop_text())
def test_fuzz_loop_files(text):
    with tempfile.TemporaryDirectory(prefix="seactl-loop-") as tmp:
        path = Path(tmp) / "loop.toml"
        path.write_text(text)
        loop = contract(lambda: sc.load_loop(path))
        if loop is not None:
            contract(lambda: _views(loop))


# ------------------------------------------------------------------ the Python API
def value():
    """An argument of any type and shape: edge numbers, floats, arrays (empty, ragged,
    2-D), strings with units, None, bools, dicts."""
    num = st.one_of(st.sampled_from(SPECIAL), st.floats(-1e3, 1e3))
    return st.one_of(num, st.sampled_from(UNITS), st.sampled_from([None, True, {}, (), []]),
                     st.lists(num, min_size=1, max_size=3),
                     st.just([[1.0, 2.0], [3.0]]), st.just(np.ones((2, 2)) * 14),
                     st.just(np.zeros(0)))


def small():
    """A short positive duration [s] or a wrong one (never a long simulation)."""
    return st.sampled_from([0.05, 0.2, 0.0, -1.0, math.nan, math.inf, 1e308, "2ms", None,
                            [0.1, 0.2]])


@st.composite
def api_call(draw):
    """(description, thunk) of one public call and one of its views."""
    which = draw(st.sampled_from(["design", "rigid", "loop", "builder", "other"]))
    v = draw(value())
    if which == "other":
        name = draw(st.sampled_from(sorted(OTHER)))
        return f"{name}({v!r})", lambda: OTHER[name](v)
    if which == "design":
        kw = draw(st.sampled_from(["fn_hz", "gs", "delays_ms", "filters_hz", "actuator",
                                   "zeta1"]))
        args = {"fn_hz": 14.0, kw: v} if kw != "delays_ms" else {
            "fn_hz": 14.0, "delays_ms": {"torque": 0.5, "stiffness": v, "damping": 0.5}}
        view = draw(st.sampled_from(["margins", "impedance", "step", "jitter", "roots",
                                     "reshape"]))
        return f"design({args}).{view}", lambda: _design_view(args, view, draw)
    if which == "rigid":
        args = draw(st.sampled_from([{"fn_hz": v}, {"fn_hz": 8.0, "delays_ms": {"stiffness": v,
                                                                          "damping": 1.0}},
                                     {"fn_hz": 8.0, "velocity_filter_hz": v}]))
        view = draw(st.sampled_from(["margins", "impedance", "step", "roots",
                                     "delay_margins"]))
        return f"rigid({args}).{view}", lambda: _design_view(args, view, draw, sc.rigid)
    if which == "loop":
        name = draw(st.sampled_from(["fn", "f_v", "m", "K", "nope"]))
        view = draw(st.sampled_from(["load", "with_values", "impedance", "latency",
                                     "frequency_response", "step"]))
        return f"load_loop(rigid).{view}({name}={v!r})", lambda: _loop_view(name, v, view, draw)
    method = draw(st.sampled_from(["variables", "parameters", "process", "block", "port"]))
    return f"LoopBuilder().{method}({v!r})", lambda: _builder(method, v)


def _design_view(args, view, draw, make=sc.design):
    d = make(**args)
    if view == "margins":
        return d.margins()
    if view == "impedance":
        return d.impedance(draw(value()))
    if view == "jitter":
        return d.jitter_margins()
    if view == "roots":
        return d.roots(count=draw(st.sampled_from([1, 3, 0, -1, 2.5, "3", None, True])))
    if view == "reshape":
        return d.reshape(*draw(st.sampled_from([(1,), (-1,), (2, 3), (0,), ("a",), ()])))
    if view == "delay_margins":
        return d.delay_margins()
    return d.step(t_end_s=draw(small()), mode=draw(st.sampled_from(["continuous", "sampled",
                                                                     "x", None])))


OTHER = {
    "load_sea": lambda v: sc.load_sea(v),
    "feasible_fn_range": lambda v: sc.feasible_fn_range(sc.UT_SEA, zeta1=v),
    "design_actuator": lambda v: sc.design(14, actuator=v).margins(),
    "rigid_actuator": lambda v: sc.rigid(8, actuator=v).margins(),
    "rightmost_roots": lambda v: sc.rightmost_roots(v),
    "load_loop_path": lambda v: sc.load_loop(v),
}
"""Other public calls, each with one drawn argument."""

_RIGID_LOOP = None


def _rigid_loop():
    global _RIGID_LOOP
    if _RIGID_LOOP is None:
        _RIGID_LOOP = sc.load_loop(EXAMPLES / "rigid.toml")
    return _RIGID_LOOP


def _loop_view(name, v, view, draw):
    if view == "load":
        return sc.load_loop(EXAMPLES / "rigid.toml", **{name: v}).analyze(jitter=False)
    loop = _rigid_loop()
    if view == "with_values":
        return loop.with_values(**{name: v}).analyze(jitter=False)
    if view == "impedance":
        return loop.impedance(v)
    if view == "latency":
        return loop.with_latencies(embedded=v).analyze(jitter=False)
    if view == "frequency_response":
        return loop.frequency_response("x", "x_des", v)
    return loop.step(draw(small()), mode=draw(st.sampled_from(["continuous", "sampled", "x"])))


def _builder(method, v):
    b = sc.LoopBuilder("fuzz")
    if method == "variables":
        return b.variables(m=v)
    if method == "parameters":
        return b.variables(m=1.0).parameters(K=v)
    if method == "process":
        return b.process("cpu", rate_hz=v, latency_ms=v).block(
            "c", "gain", input="r", output="u", gain=1.0, delay_ms="process")
    if method == "block":
        return b.process("cpu").block("c", "gain", input=v, output="u", gain=v, delay_ms=v)
    return b.port("out", position=v, force=v, sign=v)


@settings(max_examples=API_EXAMPLES, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.data())
def test_fuzz_python_api(data):
    what, call = data.draw(api_call())
    contract(call)


# ------------------------------------------------------------------ what the fuzz found
def _rigid_file():
    return sc.load_loop(EXAMPLES / "rigid.toml")


@pytest.mark.parametrize("call", [
    lambda: sc.design([]).margins(),                          # argmax of an empty sequence
    lambda: sc.design(14, delays_ms={"torque": 0.5, "stiffness": [], "damping": 0.5}).margins(),
    lambda: sc.design(14, filters_hz=(np.zeros(0), None)),
    lambda: sc.rigid([]).margins(),
    lambda: sc.rigid(8, velocity_filter_hz=np.zeros(0)).step(),  # concatenate of nothing
    lambda: sc.design(14, zeta1=np.zeros(0)).impedance([1.0]),  # broadcast (0,1) (2,2)
    lambda: sc.design([[1.0, 2.0], [3.0]]),                   # ragged: numpy's ValueError
    lambda: sc.design(14).step(amplitude="1 rad"),            # float("1 rad"): ValueError
    lambda: sc.design(14).step(t_end_s="2ms"),
    lambda: sc.design(14).impedance("2ms"),
    lambda: sc.rigid(8).step(t_end_s=1e308),                  # OverflowError in the steps
    lambda: sc.rigid(8).step(t_end_s="2ms"),
    lambda: sc.load_loop(EXAMPLES / "rigid.toml", fn=[[1.0, 2.0], [3.0]]),
    lambda: sc.load_loop(EXAMPLES / "rigid.toml", fn=[1.0, 2.0], m=[1.0, 2.0, 3.0]),
    lambda: sc.load_loop(EXAMPLES / "rigid.toml", fn=[]),
    lambda: _rigid_file().with_latencies(embedded=[]).analyze(jitter=False),
    lambda: _rigid_file().with_latencies(embedded={}).analyze(jitter=False),
    lambda: _rigid_file().with_latencies(embedded=[[1.0, 2.0], [3.0]]).analyze(),
    lambda: _rigid_file().step(1e308),
    lambda: sc.LoopBuilder().process("cpu").block("c", "gain", input=0.0, output="u",
                                                  gain=1.0),
    lambda: sc.load_loop(3.5),
    lambda: sc.feasible_fn_range(sc.UT_SEA, zeta1=np.zeros(0)),  # broadcast mismatch
    lambda: sc.rightmost_roots([1.0, 2.0]),                      # AttributeError
    lambda: sc.design(14).roots(count=2.5),                      # TypeError in np.empty
    lambda: sc.rigid(8).roots(count=None),
    lambda: sc.rigid(8, velocity_filter_hz=2.2e-311).roots(count=1),  # LinAlgError
    lambda: sc.design(14).reshape("a"),                          # TypeError
    lambda: sc.load_loop(EXAMPLES / "rigid.toml", m=1e-308).analyze(),  # LinAlgError
])
def test_found_calls_raise_a_seactl_error(call):
    """Each once ended in another exception type (named in the comment)."""
    with pytest.raises(sc.SeactlError):
        call()


def test_a_loop_exports_at_one_rate_for_every_process(tmp_path):
    """UserLoop.export(rates_hz=2000.0) once raised AttributeError (a second _rates
    method, for mappings, shadowed the export's).  Oracle: the rate asked for."""
    res = _rigid_file().export(tmp_path / "ex", lang="json", rates_hz=2000.0)
    assert {p.rate_hz for p in res.controllers.processes} == {2000.0}



def test_a_single_design_reshapes():
    """Design.reshape of a single design once raised IndexError (it indexed it with
    None).  Oracle: the margins of the same design."""
    d = sc.design(14)
    r = d.reshape(1, 1)
    assert r.shape == (1, 1)
    assert r.margins().phase_margin_deg[0, 0] == float(d.margins().phase_margin_deg)


def test_a_loop_whose_gain_is_zero_is_analysed(tmp_path):
    """Found by the loop-file fuzz: a gain log(fn) = 0 on a static spring made the loop
    transfer a constant without axes (IndexError while extending the grid down).  Oracle:
    L = 0, so the closed loop is the open one (a static spring): stable, no crossing,
    and Z = -u / (s y) = 0."""
    path = tmp_path / "zero.toml"
    path.write_text('variables = { fn = 1.0 }\n'
                    'processes = { cpu = { rate_hz = 500 } }\n'
                    'signals = { inputs = ["r", "d"], reference = "r", output = "y" }\n'
                    'breaks = [ { name = "main", signal = "y_m" } ]\n'
                    'ports = [ { name = "out", position = "y", force = "u" } ]\n'
                    '[[blocks]]\nname = "c"\nkind = "gain"\ninput = ["r", "-y_m"]\n'
                    'output = "u"\nprocess = "cpu"\ngain = "log(fn)"\n'
                    '[[blocks]]\nname = "p"\nkind = "spring"\ninput = ["u", "d"]\n'
                    'output = "y"\nstiffness = "fn"\n'
                    '[[blocks]]\nname = "s"\nkind = "sensor"\ninput = "y"\noutput = "y_m"\n')
    loop = sc.load_loop(path)
    a = loop.analyze()
    assert bool(a.stable) and np.isinf(a["main"].margins.phase_margin_deg)
    assert np.all(loop.impedance([1.0, 10.0]) == 0)


def test_a_pole_near_the_float_limit_is_refused_in_one_line(tmp_path):
    """Found by the loop-file fuzz: damping 1e308 on a 50 kg inertia puts a pole at
    2e306 rad/s, and the grid's ratio w_hi / w_lo overflowed (OverflowError).  Oracle:
    the contract, a SeactlError."""
    path = tmp_path / "far.toml"
    path.write_text('variables = { fn = 14.0 }\n'
                    'processes = { cpu = { rate_hz = 1000 } }\n'
                    'signals = { inputs = ["r", "d"], reference = "r", output = "y" }\n'
                    'breaks = [ { name = "main", signal = "y_m" } ]\n'
                    '[[blocks]]\nname = "c"\nkind = "pid"\ninput = ["r", "-y_m"]\n'
                    'output = "u"\nprocess = "cpu"\nkp = "fn"\nki = "pi"\n'
                    'kd = "(2 ^ hypot(fn, 0.5))"\nfilter_hz = 0.3\ndelay_ms = 50.0\n'
                    '[[blocks]]\nname = "p"\nkind = "inertia"\ninput = ["u", "d"]\n'
                    'output = "y"\ninertia = 50.0\ndamping = 1e308\n'
                    '[[blocks]]\nname = "s"\nkind = "sensor"\ninput = "y"\noutput = "y_m"\n')
    with pytest.raises(sc.SeactlError):
        sc.load_loop(path).analyze()
