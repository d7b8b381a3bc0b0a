"""Four cosines and sines in two calls, for the compiled kernels' delay phasors.

A design's loop has a few delay terms, and every frequency point of the margin scan needs
``e^{-j w tau}`` of each: three sine-cosine pairs per point for the SEA loop, which glibc's
scalar ``sin`` and ``cos`` compute one after the other (60 ns per three pairs here).
glibc's vector math library (libmvec) computes the sines or the cosines of four doubles in
one AVX2 call (``_ZGVdN4v_sin``, ``_ZGVdN4v_cos``): 7 ns for the same three pairs.

Accuracy: glibc states that its vector functions were tested, by random sampling over
their domains, to stay within 4 ulps (its scalar ``sin`` and ``cos``: under 1 ulp);
measured here up to 3.5 ulps (``tests/test_vecmath.py``, against a 120-bit reference).
The scan's rounding allowance (:data:`seactl.blockdiagram.EVAL_ROUNDING`, 1e-13 relative
to ``sum |c_kj| w^j``: some 450 ulps) covers a phasor off by ``4 sqrt(2)`` ulps with room:
each term's error is its polynomial's modulus times the phasor's.

:func:`cis4` emits the vector calls where libmvec is loaded and the kernels are compiled
for AVX2 (numba's target features, which its on-disk cache is keyed on), and four scalar
``sin`` and ``cos`` otherwise (other C libraries, other processors, ``NUMBA_CPU_NAME``):
the same values to a few ulps, as between two BLAS builds.
"""

from __future__ import annotations

import ctypes
import ctypes.util

import llvmlite.binding as llvm
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

_SIN4, _COS4 = "_ZGVdN4v_sin", "_ZGVdN4v_cos"  # (glibc's vector ABI: AVX2, 4 lanes)


def _load_libmvec() -> bool:
    """Bind libmvec's AVX2 sine and cosine for the JIT; False where there is no libmvec."""
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("mvec") or "libmvec.so.1")
        addresses = [ctypes.cast(getattr(lib, n), ctypes.c_void_p).value for n in (_SIN4, _COS4)]
    except (OSError, AttributeError):
        return False
    for name, address in zip((_SIN4, _COS4), addresses):
        llvm.add_symbol(name, address)
    return True


LIBMVEC = _load_libmvec()
"""libmvec's vector sine and cosine are bound (they are used where the kernels are
compiled for AVX2)."""


def _vector(context) -> bool:
    """The kernel being compiled may call libmvec's AVX2 functions."""
    return LIBMVEC and "+avx2" in context.codegen().magic_tuple()[2].split(",")


def vector_phasors() -> bool:
    """Whether this process's kernels compute their phasors with libmvec (reported by
    ``seactl bench``)."""
    from numba.core.registry import cpu_target

    return _vector(cpu_target.target_context)


@intrinsic
def cis4(typingctx, x0, x1, x2, x3):  # pragma: no cover - compiled
    """``(cos x0, .., cos x3, sin x0, .., sin x3)`` of four float64 phases (unused lanes:
    pass 0)."""
    f8 = types.float64
    sig = types.UniTuple(f8, 8)(f8, f8, f8, f8)

    def codegen(context, builder, sig, args):
        dbl, i32 = ir.DoubleType(), ir.IntType(32)
        if not _vector(context):
            out = []
            for name in ("llvm.cos.f64", "llvm.sin.f64"):
                fn = cgutils.get_or_insert_function(builder.module,
                                                    ir.FunctionType(dbl, [dbl]), name)
                out += [builder.call(fn, [x]) for x in args]
            return context.make_tuple(builder, sig.return_type, out)
        v4 = ir.VectorType(dbl, 4)
        x = ir.Constant(v4, None)
        for i, a in enumerate(args):
            x = builder.insert_element(x, a, ir.Constant(i32, i))
        out = []
        for name in (_COS4, _SIN4):
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v4, [v4]), name)
            y = builder.call(fn, [x])
            out += [builder.extract_element(y, ir.Constant(i32, i)) for i in range(4)]
        return context.make_tuple(builder, sig.return_type, out)

    return sig, codegen
