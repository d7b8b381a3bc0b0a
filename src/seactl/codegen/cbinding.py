"""The exported C of one process as a shared library, called from Python.

``seactl run --realtime`` runs the C that ``seactl export`` writes, unchanged: the
process's ``<p>.c`` is compiled with a small shim ``<p>_rt.c`` (a static state, and a
flat ``double`` interface so no struct layout is mirrored in Python) into ``lib<p>.so``
with the system compiler, and loaded through cffi when it is installed, else ctypes.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:   # the processes load only CController: no sympy in a run's children
    from seactl.codegen.parametric import Program


def shim_source(prog: Program) -> str:
    """``<p>_rt.c``: ``<p>_rt_init()`` and ``int <p>_rt_step(const double *in, int fresh,
    double *out)`` (inputs and outputs in the order of the structs; returns the
    watchdog flag)."""
    from seactl.codegen.controllers import c_ident

    p = prog.ident
    ins = "".join(f"    in.{c_ident(n)} = ({p}_real)x[{i}];\n" for i, n in enumerate(prog.inputs))
    outs = "".join(f"    y[{i}] = (double)out.{c_ident(n)};\n"
                   for i, n in enumerate(prog.outputs))
    return (f"/* Flat interface of {p}.c for seactl run --realtime. */\n"
            f'#include "{p}.h"\n\n'
            f"static {p}_state st;\n\n"
            f"void {p}_rt_init(void);\n"
            f"int {p}_rt_step(const double *x, int fresh, double *y);\n\n"
            f"void {p}_rt_init(void)\n{{\n    {p}_init(&st);\n}}\n\n"
            f"int {p}_rt_step(const double *x, int fresh, double *y)\n{{\n"
            f"    {p}_inputs in;\n    {p}_outputs out;\n"
            + ("" if prog.inputs else "    (void)x;\n    in.unused = 0;\n") + ins
            + f"    {p}_step(&st, &in, fresh, &out);\n" + outs
            + "    return out.watchdog;\n}\n")


def build_library(build: Path, prog: Program, cc: str) -> Path:
    """Compile ``<p>.c`` (already in ``build``) and its shim into ``lib<p>.so`` with
    ``cc`` and the export's warning flags plus ``-fPIC -shared``."""
    from seactl.codegen.export import run_compiler

    p = prog.ident
    (build / f"{p}_rt.c").write_text(shim_source(prog))
    lib = build / f"lib{p}.so"
    run_compiler(cc, ["-fPIC", "-shared", f"{p}.c", f"{p}_rt.c", "-o", lib.name], build,
                 f"the run library of {prog.name!r}")
    return lib


class CController:
    """A process's compiled controller: ``step(fresh) -> watchdog``, reading ``inputs``
    and writing ``outputs`` (preallocated lists of floats, struct order) in place.

    ``binding``: ``"cffi"``, ``"ctypes"``, or None for cffi when it is installed, else
    ctypes (the attribute says which)."""

    def __init__(self, lib: Path, ident: str, n_in: int, n_out: int,
                 binding: str | None = None):
        cffi = None
        if binding in (None, "cffi"):
            try:
                import cffi
            except ImportError:
                if binding == "cffi":
                    raise
        if cffi is not None:
            self.binding = "cffi"
            ffi = cffi.FFI()
            ffi.cdef(f"void {ident}_rt_init(void);"
                     f"int {ident}_rt_step(const double *x, int fresh, double *y);")
            so = ffi.dlopen(str(lib))
            self._x, self._y = ffi.new(f"double[{max(n_in, 1)}]"), ffi.new(
                f"double[{max(n_out, 1)}]")
        else:
            import ctypes

            self.binding = "ctypes"
            so = ctypes.CDLL(str(lib))
            arr = ctypes.POINTER(ctypes.c_double)
            getattr(so, f"{ident}_rt_step").argtypes = (arr, ctypes.c_int, arr)
            self._x = (ctypes.c_double * max(n_in, 1))()
            self._y = (ctypes.c_double * max(n_out, 1))()
        self._so = so
        self._step = getattr(so, f"{ident}_rt_step")
        getattr(so, f"{ident}_rt_init")()
        self.n_in, self.n_out = n_in, n_out

    def step(self, inputs: Any, fresh: bool) -> tuple[list[float], int]:
        """One call of ``<p>_step``: the outputs and the watchdog flag."""
        x, y = self._x, self._y
        for i, v in enumerate(inputs):
            x[i] = v
        flag = self._step(x, 1 if fresh else 0, y)
        return [y[i] for i in range(self.n_out)], int(flag)
