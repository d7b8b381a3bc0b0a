"""Per-process discrete controllers of a design, exported as C99, Python and JSON.

What is written is the run-time form of each process (:mod:`seactl.codegen.parametric`:
blocks whose coefficients are computed from a parameter struct, without the design's
delays unless ``emulate_latency``); what it is verified against is the state space below,
the sampled controller of :func:`seactl.simulate.discrete.compile_sampled` split by process.

A design runs on several processes (the block diagram's ``process`` tags: the stiffness
loop on the ``high-level`` process, torque and damping on the ``embedded`` process), each
at its own rate.  :func:`compile_processes` splits the sampled controller of
:func:`seactl.simulate.discrete.compile_sampled` into one discrete state space per process, built
with the sampled compiler's own stages (:func:`~seactl.simulate.realize.realize_tustin` for every
block at its process's period, :func:`~seactl.simulate.network.assemble_blocks` for the network,
:func:`~seactl.simulate.discrete.delay_buffers` for the whole-sample delay buffers, the same rates
and
saturation), so there is one model: :func:`verify` checks the split against the plan's
controller (:func:`seactl.simulate.discrete.run_controller`).

One process, one tick (every ``period_ticks`` base ticks)::

    v = [inputs; w]            w_j = the value buffer j received buffers[j] ticks ago
    y = C x + D v              y = [outputs; sources of the buffers]
    outputs = clip(y[:no], -limits, limits)
    buffer j <- y[no + j]
    x <- A x + B v

Inputs are sampled plant signals (``q_j``, ``tau_k``), references (``q_des``) and the
messages of other processes (``tau_fb_from_high_level``: that process's contribution to
signal ``tau_fb``, held by the receiver between the sender's ticks).  Static untagged
blocks (sensors, sums, taps) are wiring, replicated into every process that needs them.
The actuation (``i_m``, ``F_des``) is output by the fastest process (``embedded`` on a
tie).  Processes run in ``schedule`` order within a base tick (senders first), which is
what the sampled simulation's simultaneous solution gives.
"""

from __future__ import annotations

import importlib.util
import math
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seactl.base.outputs import OutputSet
from seactl.base.result import Result, new_axes
from seactl.codegen.controllers import (
    CFLAGS,
    LANGUAGES,
    MAX_SIM_TICKS,
    Controllers,
    ProcessController,
    random_signals,
    reference_actuation,
    relative_error,
    run_schedule,
    simulation_signals,
)
from seactl.codegen.parametric import compile_export
from seactl.codegen.source import (
    check_languages,
    check_real,
    export_files,
    python_class_name,
    to_json,
)
from seactl.diagram.blockdiagram import BlockDiagram
from seactl.errors import InputError, OutputError, ResourceError, SeactlError

# ----------------------------------------------------------------------------- files
MARKER = ".seactl-export"
"""File that marks a directory as an export seactl wrote (its files may be replaced)."""


def check_export_dir(out: str | os.PathLike, marker: str = MARKER,
                     what: str = "an export") -> Path:
    """Refuse ``out`` unless it is absent, an empty directory, or ``what`` seactl wrote
    (a directory holding ``marker``)."""
    if not os.fspath(out).strip():
        raise InputError("out", os.fspath(out), "a directory name")
    out = Path(out)
    if out.exists():
        if not out.is_dir():
            raise OutputError(out, "exists and is not a directory")
        if any(out.iterdir()) and not (out / marker).is_file():
            raise OutputError(out, f"the directory is not empty and is not {what} seactl "
                              "wrote (choose a new or empty directory)")
    elif not out.parent.is_dir():
        raise OutputError(out, f"the directory {out.parent} does not exist")
    return out


def listed_files(out: Path, marker: str = MARKER) -> set[str]:
    """The files seactl wrote into ``out`` (listed by its ``marker``; none without one)."""
    try:
        return set((out / marker).read_text(errors="replace").splitlines()[1:])
    except OSError:
        return set()


def write_export(files: Mapping[str, str], out: str | os.PathLike, marker: str = MARKER,
                 what: str = "an export") -> list[Path]:
    """Write ``files`` into ``out`` as a set (temporaries renamed at the end), with the
    marker file; returns the paths written (the marker last)."""
    out = check_export_dir(out, marker, what)
    created = not out.exists()
    earlier = listed_files(out, marker)
    for name in files:
        if name not in earlier and (out / name).exists():
            raise OutputError(out / name, f"it exists and {what} seactl wrote there does not "
                              "list it (move it out or choose another directory)")
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(out, exc.strerror or str(exc)) from None
    still = sorted(n for n in earlier if n not in files and (out / n).is_file())
    try:
        with OutputSet() as outs:
            paths = [outs.add("out", out / name) for name in [*files, marker]]
            for path, name in zip(paths, files):
                outs.write(path, files[name])
            outs.write(paths[-1], "written by seactl; seactl may replace the files it "
                       "lists\n" + "".join(f"{n}\n" for n in [*files, *still]))
            outs.commit()
    except BaseException:
        if created:
            try:
                out.rmdir()  # only if nothing is left in it
            except OSError:
                pass
        raise
    return paths


# ----------------------------------------------------------------------------- verify
TARGETS = {"double": 1e-12, "float": 1e-4}
"""Largest relative difference an export may show (``real`` of the C -> bound)."""

@dataclass(frozen=True)
class Verification:
    """Largest relative difference of each exported implementation from seactl's sampled
    controller (``errors``: ``"python/simulation"``, ``"c/random"``, ...), the compiler
    and the time it took to compile every process [s]."""

    max_error: float
    errors: dict[str, float]
    compiler: str | None
    compile_s: float | None
    ticks: dict[str, int]
    target: float = 1e-12
    """The relative difference the export is held to (rounding of ``double`` or
    ``float``)."""


def find_compiler(cc: str | None = None) -> str | None:
    """Path of the C compiler ``cc`` (None if absent), or the first of ``$CC``, ``cc``,
    ``gcc``, ``clang`` found."""
    if cc:
        return shutil.which(cc)
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and (path := shutil.which(name)):
            return path
    return None


def compile_c(build: Path, proc: ProcessController, cc: str) -> Path:
    """Compile ``<process>.c`` and its harness in ``build`` with ``cc`` and
    :data:`~seactl.codegen.controllers.CFLAGS`; the executable."""
    exe = build / f"{proc.ident}_harness"
    run_compiler(cc, [f"{proc.ident}.c", f"{proc.ident}_main.c", "-o", exe.name], build,
                 f"the export of {proc.name!r}")
    return exe


def run_compiler(cc: str, args: list[str], build: Path, what: str) -> None:
    """Run ``cc`` with :data:`~seactl.codegen.controllers.CFLAGS` and ``args`` in ``build``;
    :class:`~seactl.errors.SeactlError` naming ``what`` and the first line of the
    compiler's message if it cannot run or rejects the code."""
    cmd = [cc, *CFLAGS, *args]
    try:
        res = subprocess.run(cmd, cwd=build, capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise SeactlError(f"cannot run the C compiler {cc}: {exc}") from None
    if res.returncode != 0:
        first = (res.stderr.strip().splitlines() or ["no message"])[0]
        raise SeactlError(f"the C compiler rejected {what}: {first}")


def _c_runner(exes: Mapping[str, Path]) -> Any:
    def run(proc: ProcessController, inputs: np.ndarray) -> np.ndarray:
        text = ",".join(proc.inputs) + "\n" + "".join(
            ",".join(repr(float(v)) for v in row) + "\n" for row in inputs)
        res = subprocess.run([str(exes[proc.name])], input=text, capture_output=True,
                             text=True, timeout=120)
        if res.returncode != 0:
            raise SeactlError(f"the C harness of {proc.name!r} failed: {res.stderr.strip()}")
        rows = res.stdout.strip().splitlines()[1:]
        return np.array([[float(v) for v in r.split(",")] for r in rows]).reshape(
            len(rows), len(proc.outputs))
    return run


def _python_runner(build: Path) -> Any:
    def run(proc: ProcessController, inputs: np.ndarray) -> np.ndarray:
        spec = importlib.util.spec_from_file_location(f"_seactl_export_{proc.ident}",
                                                      build / f"{proc.ident}.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        obj = getattr(mod, python_class_name(proc))()
        out = [obj.step(dict(zip(proc.inputs, row))) for row in inputs]
        return np.array([[o[n] for n in proc.outputs] for o in out]).reshape(
            len(out), len(proc.outputs))
    return run


def _random_scale(diagram: BlockDiagram, design: Any, ctl: Controllers, rates: Any,
                  saturation: Mapping[str, float] | None) -> float:
    """Input scale keeping the raw actuation at half its limit (saturation then rare)."""
    lims = [v for v in (saturation or {}).values() if math.isfinite(v)]
    if not lims:
        return 1.0
    base = random_signals(ctl, 400, seed=1)
    peak = np.max(np.abs(reference_actuation(diagram, design, ctl, base, rates, None)))
    return min(1.0, 0.5 * min(lims) / peak) if peak > 0 else 1.0


def verify(diagram: BlockDiagram, design: Any, ctl: Controllers, *,
           rates_hz: Mapping[str, float] | float, saturation: Mapping[str, float] | None,
           languages: Sequence[str] = ("c", "python"), cc: str | None = None,
           t_end_s: float = 0.5, random_ticks: int = 2000, seed: int = 0,
           step: float = 0.1, real: str = "double") -> Verification:
    """Run the exported code (``ctl.programs``; the C in ``real``) on the signals of a
    sampled step response and on random signals, against seactl's own sampled controller
    (:func:`reference_actuation`) of ``design`` (the one ``ctl`` was compiled from)."""
    compiler = find_compiler(cc) if "c" in languages else None
    if "c" in languages and compiler is None:
        raise ResourceError(f"no C compiler found (looked for {cc or '$CC, cc, gcc, clang'}):"
                            " install one, or leave out --verify")
    t_end_s = min(t_end_s, MAX_SIM_TICKS / ctl.base_rate_hz)
    sim, _applied = simulation_signals(diagram, design, ctl, t_end_s, rates_hz, saturation,
                                       step)
    scale = _random_scale(diagram, design, ctl, rates_hz, saturation)
    cases = {"simulation": sim, "random": random_signals(ctl, random_ticks, seed, scale)}
    refs = {k: reference_actuation(diagram, design, ctl, b, rates_hz, saturation)
            for k, b in cases.items()}
    errors: dict[str, float] = {}
    compile_s = None
    with tempfile.TemporaryDirectory(prefix="seactl-export-") as tmp:
        build = Path(tmp)
        for name, text in export_files(ctl, ("c", "python"), real).items():
            (build / name).write_text(text)
        runners = {}
        if "python" in languages:
            runners["python"] = _python_runner(build)
        if compiler:
            t0 = time.perf_counter()
            exes = {p.name: compile_c(build, p, compiler) for p in ctl.processes}
            compile_s = time.perf_counter() - t0
            runners["c"] = _c_runner(exes)
        for lang, runner in runners.items():
            for case, base in cases.items():
                y = run_schedule(ctl, base, runner)
                errors[f"{lang}/{case}"] = relative_error(y, refs[case])
    return Verification(max(errors.values(), default=0.0), errors, compiler, compile_s,
                        {k: len(next(iter(b.values()))) for k, b in cases.items()},
                        TARGETS[real] if compiler else TARGETS["double"])


# ----------------------------------------------------------------------------- one call
@dataclass(frozen=True)
class ExportResult(Result):
    """What an export wrote, the per-process controllers and, with ``verify``, how far the
    exported code is from seactl's own sampled controller.

    Parameters
    ----------
    files : list of pathlib.Path
        The files written, the marker last.
    controllers : Controllers
        The per-process discrete controllers.
    verification : Verification or None
        The verification, when asked for.
    real : {"double", "float"}
        The C's floating-point type.

    Attributes
    ----------
    files : list of pathlib.Path
        The files written, the marker last.
    controllers : Controllers
        The per-process discrete controllers.
    verification : Verification or None
        The verification, when asked for.
    processes : tuple of ProcessController
        The processes, senders first.
    max_error : float or None
        Largest relative difference of any implementation (dimensionless; None unverified).
    errors : dict or None
        ``"<language>/<signals>"`` -> relative difference.
    compiler : str or None
        The C compiler used.
    compile_s : float or None
        Time to compile every process [s].
    real : {"double", "float"}
        The C's floating-point type (dimensionless).
    """

    files: list[Path]
    controllers: Controllers
    verification: Verification | None
    real: str = "double"

    @property
    def processes(self) -> tuple[ProcessController, ...]:
        """The processes, senders first."""
        return self.controllers.processes

    @property
    def max_error(self) -> float | None:
        """Largest relative difference of any implementation (None unverified)."""
        return None if self.verification is None else self.verification.max_error

    @property
    def errors(self) -> dict[str, float] | None:
        """Implementation and signals -> relative difference (None unverified)."""
        return None if self.verification is None else self.verification.errors

    @property
    def compiler(self) -> str | None:
        """The C compiler used (None: none)."""
        return None if self.verification is None else self.verification.compiler

    @property
    def compile_s(self) -> float | None:
        """Time to compile every process [s] (None: nothing compiled)."""
        return None if self.verification is None else self.verification.compile_s

    def to_dict(self) -> dict[str, Any]:
        """The files, the processes and the verification as JSON-ready values.

        Returns
        -------
        dict
            ``files``, ``processes`` (``name``, ``rate_hz``, ``inputs``, ``outputs``,
            ``params``: the parameter struct), ``emulate_latency``, ``real``,
            ``requested_delays_s``, ``effective_delays_s``, ``emulated_delays_s`` [s],
            ``max_error``, ``target``, ``errors``, ``compiler``, ``compile_s``.
        """
        doc = to_json(self.controllers, self.real)
        params = {p["name"]: p.get("params") for p in doc["processes"]}
        return {"files": [str(p) for p in self.files],
                "processes": [{"name": p.name, "rate_hz": p.rate_hz, "inputs": list(p.inputs),
                               "outputs": list(p.outputs), "params": params[p.name]}
                              for p in self.processes],
                **{k: doc[k] for k in ("emulate_latency", "real", "requested_delays_s",
                                       "effective_delays_s", "emulated_delays_s")},
                "max_error": self.max_error,
                "target": None if self.verification is None else self.verification.target,
                "errors": self.errors, "compiler": self.compiler, "compile_s": self.compile_s}

    def records(self) -> list[dict[str, Any]]:
        """One flat row per process.

        Returns
        -------
        list of dict
            ``name``, ``rate_hz``, ``inputs`` and ``outputs`` (comma-separated signal
            names).
        """
        return [{"name": p.name, "rate_hz": p.rate_hz, "inputs": ",".join(p.inputs),
                 "outputs": ",".join(p.outputs)} for p in self.processes]

    def plot(self, ax: Any = None) -> Any:
        """The verification's relative errors per implementation (log scale), or each
        process's rate when the export was not verified.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        if self.errors:
            names = list(self.errors)
            ax.bar(names, [max(v, 1e-17) for v in self.errors.values()], color="tab:blue")
            ax.set_yscale("log")
            ax.set_ylabel("relative error")
        else:
            ax.bar([p.name for p in self.processes], [p.rate_hz for p in self.processes])
            ax.set_ylabel("rate [Hz]")
        ax.grid(True, axis="y", alpha=0.3)
        return ax


def export_design(diagram: BlockDiagram, design: Any, out: str | os.PathLike, *,
                  languages: Sequence[str] | str = LANGUAGES,
                  rates_hz: Mapping[str, float] | float = 1000.0,
                  saturation: Mapping[str, float] | None = None, verify_export: bool = False,
                  cc: str | None = None, step: float = 0.1, emulate_latency: bool = False,
                  real: str = "double") -> ExportResult:
    """Compile, optionally verify (before anything is written), and write an export.

    ``emulate_latency``: keep the design's delays as buffers in the code (else none: the
    platform's latency is the design's); ``real``: the C's ``double`` or ``float``;
    ``step``: the reference step of the verification's sampled simulation."""
    langs = check_languages(languages)
    real = check_real(real)
    out = check_export_dir(out)
    ctl, used = compile_export(diagram, design, rates_hz, saturation, emulate_latency)
    ver = None
    if verify_export:
        ver = verify(diagram, used, ctl, rates_hz=rates_hz, saturation=saturation,
                     languages=("c", "python"), cc=cc, step=step, real=real)
    files = write_export(export_files(ctl, langs, real), out)
    return ExportResult(files, ctl, ver, real)
