"""The exported controller's run-time interface: parameter struct (bumpless update),
output limit, watchdog, reset; the C built with ``-std=c99 -Wall -Wextra -Werror
-pedantic`` and run under ``-fsanitize=address,undefined``.

Oracles: the SEA's embedded law at steady state, derived by hand from the block diagram
(``tau_des = Kq q_des + tau_fb``, derivatives zero, ``i_m = tau_des / beta + Ktau (tau_des
- tau_meas)``); the generated Python class, run through the same scenario, for the C
(the same parameter semantics); a second controller initialized fresh, for ``reset``.
"""

from __future__ import annotations

import importlib.util
import subprocess

import numpy as np
import pytest

import seactl as sc
from seactl.codegen import export as ex
from seactl.codegen.controllers import CFLAGS

CC = ex.find_compiler()
NO_CC = "no C compiler (cc, gcc or clang) on PATH: the exported C is not built"
SANITIZE = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-g")
INPUTS = {"q_j": 0.05, "tau_k": 1.5, "q_des": 0.1, "tau_fb_from_high_level": -2.0}
SETTLE = 4000        # 2 s at 2 kHz: every filter (>= 50 Hz) has settled to rounding

DRIVER = r"""
#include <math.h>
#include <stdio.h>
#include "embedded.h"

static embedded_state s, s2;

static double run(embedded_inputs *in, int n, int fresh, embedded_outputs *out, double *dev)
{
    int k;
    double first = 0.0;
    *dev = 0.0;
    for (k = 0; k < n; ++k) {
        embedded_step(&s, in, fresh, out);
        if (k == 0) first = (double)out->i_m;
        if (fabs((double)out->i_m - first) > *dev) *dev = fabs((double)out->i_m - first);
    }
    return first;
}

int main(void)
{
    embedded_params p, bad;
    embedded_inputs in;
    embedded_outputs out;
    double dev;
    embedded_init(&s);
    embedded_default_params(&p);
    in.q_j = Q_J; in.tau_k = TAU_K; in.q_des = Q_DES; in.tau_fb_from_high_level = MSG;
    run(&in, SETTLE, 1, &out, &dev);
    printf("steady %.17g\n", (double)out.i_m);
    p.Bq *= 2.0; p.Btau *= 0.5; p.Tf_qd *= 3.0; p.Tf_taud *= 0.3;
    printf("set_damping %d\n", embedded_set_params(&s, &p));
    printf("after_damping %.17g\n", run(&in, 200, 1, &out, &dev));
    printf("dev_damping %.17g\n", dev);
    p.Kq *= 1.5;
    printf("set_kq %d\n", embedded_set_params(&s, &p));
    printf("after_kq %.17g\n", run(&in, 200, 1, &out, &dev));
    printf("dev_kq %.17g\n", dev);
    bad = p;
    bad.Tf_qd = HUGE_VAL;
    printf("set_bad %d\n", embedded_set_params(&s, &bad));
    printf("after_bad %.17g\n", run(&in, 1, 1, &out, &dev));
    p.watchdog_ticks = 5;
    embedded_set_params(&s, &p);
    run(&in, 5, 0, &out, &dev);
    printf("stale5 %.17g %d\n", (double)out.i_m, out.watchdog);
    run(&in, 1, 0, &out, &dev);
    printf("stale6 %.17g %d\n", (double)out.i_m, out.watchdog);
    run(&in, 1, 1, &out, &dev);
    printf("fresh %.17g %d\n", (double)out.i_m, out.watchdog);
    p.limit_i_m = 0.25;
    embedded_set_params(&s, &p);
    printf("limited %.17g\n", run(&in, 1, 1, &out, &dev));
    p.limit_i_m = HUGE_VAL;
    embedded_set_params(&s, &p);
    embedded_reset(&s);
    printf("reset %.17g\n", run(&in, 1, 1, &out, &dev));
    embedded_init(&s2);
    embedded_set_params(&s2, &p);
    embedded_step(&s2, &in, 1, &out);
    printf("fresh_init %.17g\n", (double)out.i_m);
    return 0;
}
"""


def _design():
    return sc.design(14, delays_ms={"torque": 1, "stiffness": 2, "damping": 1},
                     filters_hz=(50, 100))


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    """One export (emulated latency, so the delay buffers run under the sanitizers too;
    the torque derivative on the feedback only, so that Kq feeds no derivative)."""
    out = tmp_path_factory.mktemp("runtime") / "ctl"
    res = _design().export(out, rates_hz={"embedded": 2000, "high-level": 500},
                           emulate_latency=True, zero=False)
    return out, res


def _build(out, extra=(), real="double"):
    defs = [f"-D{k.upper()}={v!r}" for k, v in INPUTS.items() if k != "tau_fb_from_high_level"]
    defs += [f"-DMSG={INPUTS['tau_fb_from_high_level']!r}", f"-DSETTLE={SETTLE}"]
    (out / "driver.c").write_text(DRIVER)
    exe = out / ("driver_" + "_".join([real, *(e.strip("-=,") for e in extra)])[:40])
    subprocess.run([CC, *CFLAGS, *extra, *defs, "embedded.c", "driver.c", "-o", exe.name],
                   cwd=out, check=True, capture_output=True, text=True)
    return exe


@pytest.fixture(scope="module")
def c_run(export):
    """The driver built with the strict flags and the sanitizers, run once."""
    if CC is None:
        pytest.skip(NO_CC)
    out, _ = export
    try:
        exe = _build(out, SANITIZE)
    except subprocess.CalledProcessError as exc:
        if "sanitize" in exc.stderr or "asan" in exc.stderr:
            pytest.skip(f"the compiler has no address/undefined sanitizer: {exc.stderr[:200]}")
        raise
    res = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "runtime error" not in res.stderr, res.stderr
    return {ln.split()[0]: [float(v) for v in ln.split()[1:]]
            for ln in res.stdout.splitlines()}


def _law(prm):
    """Hand-derived steady state of the SEA's embedded process (module docstring)."""
    tau_des = prm["Kq"] * INPUTS["q_des"] + INPUTS["tau_fb_from_high_level"]
    return tau_des / prm["beta"] + prm["Ktau"] * (tau_des - INPUTS["tau_k"])


def _python(out):
    spec = importlib.util.spec_from_file_location("exported_embedded", out / "embedded.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.Embedded


def test_update_is_bumpless_at_steady_state(c_run, export):
    """Damping gains and filter time constants leave the steady output unchanged (their
    blocks' DC gain is zero and their states are the filtered inputs); a stiffness change
    (Kq feeds no derivative here) moves the output at once to the new steady value, with
    no transient.  A realization whose states hold gain-scaled values (the state-space
    form's) would jump and ring."""
    prm = dict(_python(export[0]).DEFAULT_PARAMS)
    steady = c_run["steady"][0]
    assert steady == pytest.approx(_law(prm), rel=1e-9)
    assert c_run["set_damping"] == [0] and c_run["set_kq"] == [0]
    assert abs(c_run["after_damping"][0] - steady) <= 1e-12 * abs(steady)
    assert c_run["dev_damping"][0] <= 1e-12 * abs(steady)
    prm["Kq"] *= 1.5
    assert c_run["after_kq"][0] == pytest.approx(_law(prm), rel=1e-9)
    assert abs(c_run["after_kq"][0] - steady) > 0.1 * abs(steady)   # it did change
    assert c_run["dev_kq"][0] <= 1e-12 * abs(steady)


def test_refused_parameters_keep_the_old(c_run):
    """A non-finite filter constant is refused (-1) and the controller runs on."""
    assert c_run["set_bad"] == [-1]
    assert c_run["after_bad"][0] == c_run["after_kq"][0]


def test_watchdog_gives_zero_output_and_a_flag(c_run):
    """watchdog_ticks = 5: five stale calls are tolerated, the sixth gives zero current
    and the flag; a fresh command restores the (steady) output at once."""
    kept = c_run["after_kq"][0]
    assert c_run["stale5"] == [kept, 0]
    assert c_run["stale6"] == [0.0, 1]
    assert c_run["fresh"] == [kept, 0]


def test_output_limit_and_reset(c_run):
    """limit_i_m clips the current; after reset() (no limit) the controller answers like
    a freshly initialized one with the same parameters."""
    assert c_run["limited"][0] == 0.25 * np.sign(c_run["after_kq"][0])
    assert c_run["reset"] == c_run["fresh_init"]
    assert abs(c_run["reset"][0] - c_run["after_kq"][0]) > 1.0   # the states were zeroed


def test_python_export_has_the_same_parameter_semantics(c_run, export):
    """The generated Python class through the driver's scenario gives the C's numbers."""
    Embedded = _python(export[0])
    ctl = Embedded()
    for _ in range(SETTLE):
        y = ctl.step(INPUTS)["i_m"]
    assert y == pytest.approx(c_run["steady"][0], rel=1e-12)
    prm = dict(ctl.params)
    prm.update(Bq=2 * prm["Bq"], Btau=0.5 * prm["Btau"], Tf_qd=3 * prm["Tf_qd"],
               Tf_taud=0.3 * prm["Tf_taud"])
    assert ctl.set_params(prm) == 0
    assert ctl.step(INPUTS)["i_m"] == pytest.approx(c_run["after_damping"][0], rel=1e-12)
    prm["Kq"] *= 1.5
    ctl.set_params(prm)
    assert ctl.step(INPUTS)["i_m"] == pytest.approx(c_run["after_kq"][0], rel=1e-12)
    assert ctl.set_params(dict(prm, Tf_qd=float("inf"))) == -1
    ctl.set_params(dict(prm, watchdog_ticks=5))
    outs = [ctl.step(INPUTS, fresh=False)["i_m"] for _ in range(6)]
    assert outs[4] == pytest.approx(c_run["stale5"][0], rel=1e-12) and outs[5] == 0.0
    assert ctl.watchdog
    assert ctl.step(INPUTS)["i_m"] == pytest.approx(c_run["fresh"][0], rel=1e-12)


@pytest.mark.skipif(CC is None, reason=NO_CC)
def test_float_build_is_clean(export, tmp_path):
    """--real float: the same driver compiles with the strict flags (no warning) and gives
    the double build's steady state to single precision."""
    out = tmp_path / "f"
    _design().export(out, rates_hz={"embedded": 2000, "high-level": 500},
                     emulate_latency=True, real="float", lang="c", zero=False)
    assert "typedef float embedded_real;" in (out / "embedded.h").read_text()
    res = subprocess.run([str(_build(out, real="float"))], capture_output=True, text=True,
                         check=True)
    steady = float(res.stdout.split()[1])
    prm = _python(export[0]).DEFAULT_PARAMS
    assert steady == pytest.approx(_law(prm), rel=1e-5)


@pytest.mark.slow
@pytest.mark.skipif(CC is None, reason=NO_CC)
def test_loop_file_harness_under_sanitizers(tmp_path):
    """The disturbance-observer loop (an algebraic loop solved by the network inverse with
    pivoting) built with the sanitizers, on random inputs, against the state space of the
    sampled compiler (:func:`seactl.codegen.controllers.run_process`, oracle (1) of
    tests/test_export.py) to 1e-12."""
    from pathlib import Path

    from seactl.codegen.controllers import relative_error, run_process

    path = Path(__file__).resolve().parents[1] / "examples" / "loops" / "sea-dob.toml"
    res = sc.load_loop(path).export(tmp_path, lang="c")
    for proc in res.controllers.processes:
        exe = tmp_path / f"{proc.ident}_san"
        subprocess.run([CC, *CFLAGS, *SANITIZE, f"{proc.ident}.c", f"{proc.ident}_main.c",
                        "-o", exe.name], cwd=tmp_path, check=True, capture_output=True)
        u = np.random.default_rng(4).standard_normal((500, len(proc.inputs)))
        csv = ",".join(proc.inputs) + "\n" + "".join(
            ",".join(repr(float(v)) for v in row) + "\n" for row in u)
        out = subprocess.run([str(exe)], input=csv, capture_output=True, text=True,
                             timeout=60)
        assert out.returncode == 0 and "runtime error" not in out.stderr, out.stderr
        y = np.loadtxt(out.stdout.splitlines()[1:], delimiter=",").reshape(len(u), -1)
        assert relative_error(y, run_process(proc, u)) <= 1e-12
