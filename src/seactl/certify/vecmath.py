"""Four cosines, sines, arctangents or square roots in one call, for the margin scan's
compiled kernel.

A design's loop has a few delay terms, and every frequency point of the margin scan needs
``e^{-j w tau}`` of each (three sine-cosine pairs for the SEA loop) and ``arg L``, which
glibc's scalar functions compute one after the other.  glibc's vector math library
(libmvec) computes four at once in one AVX2 call (``_ZGVdN4v_cos``, ``_ZGVdN4v_sin``,
``_ZGVdN4vv_atan2``), for little more than the cost of one scalar call.

Accuracy: glibc states that its vector functions were tested, by random sampling over
their domains, to stay within 4 ulps (its scalar ones: under 1 ulp);
``tests/test_vecmath.py`` holds them to 4 ulps of 120-bit references.
* The phasors: the scan's rounding allowance (:data:`seactl.diagram.blockdiagram.EVAL_ROUNDING`,
  1e-13 relative to ``sum |c_kj| w^j``: some 450 ulps) covers a phasor off by
  ``4 sqrt(2)`` ulps with room, each term's error being its polynomial's modulus times
  its phasor's.
* ``arg L``: its arctangent's 4 ulps (9e-16 rad at most) add to the error ``arg L``
  already carries from ``N`` and ``D`` (up to ``EVAL_ROUNDING`` relative to their
  majorants); the crossing certificates take both as they took glibc's scalar result.
  The stability count (``Delta``'s winding) takes its arguments from the scalar
  ``atan2``.

Each function is called from libmvec where libmvec has it (``atan2`` since glibc 2.35)
and the kernels are compiled for AVX2 (numba's target features, which its on-disk cache
is keyed on), and as four scalar calls otherwise (other C libraries, other processors,
``NUMBA_CPU_NAME``): the same values to a few ulps, as between two BLAS builds.

:func:`sqrt_v4` is LLVM's vector square root, correctly rounded like the scalar one on
every target (no library): the scan's moduli four at a time.

numba keys a kernel's on-disk cache on the kernel's own source file: after editing this
module, touch :mod:`seactl.certify.scan` (or delete the ``numba`` folder of
:func:`seactl.base.usercache.cache_dir`) so that its kernels are compiled again.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import operator

import llvmlite.binding as llvm
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, models, overload, register_model

# name: (libmvec's AVX2 symbol, the scalar function, number of arguments)
_FUNCTIONS = {"cos": ("_ZGVdN4v_cos", "llvm.cos.f64", 1),
              "sin": ("_ZGVdN4v_sin", "llvm.sin.f64", 1),
              "atan2": ("_ZGVdN4vv_atan2", "atan2", 2)}


def _bind_libmvec() -> frozenset[str]:
    """Bind libmvec's AVX2 functions for the JIT; the names of those it has."""
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("mvec") or "libmvec.so.1")
    except OSError:
        return frozenset()
    bound = set()
    for name, (symbol, _, _) in _FUNCTIONS.items():
        try:
            llvm.add_symbol(symbol, ctypes.cast(getattr(lib, symbol), ctypes.c_void_p).value)
        except AttributeError:  # (an older glibc)
            continue
        bound.add(name)
    return frozenset(bound)


LIBMVEC = _bind_libmvec()
"""The functions libmvec provides here (used where the kernels are compiled for AVX2)."""


def _vectorized(context, name: str) -> bool:
    """The kernel being compiled calls libmvec's ``name``."""
    return name in LIBMVEC and "+avx2" in context.codegen().magic_tuple()[2].split(",")


def vector_functions() -> list[str]:
    """The functions this process's kernels take from libmvec (``seactl bench`` reports
    them)."""
    from numba.core.registry import cpu_target

    return [n for n in _FUNCTIONS if _vectorized(cpu_target.target_context, n)]


_V4 = ir.VectorType(ir.DoubleType(), 4)


def _vector(builder, values) -> ir.Value:
    """Four doubles as one ``<4 x double>``."""
    v = ir.Constant(_V4, None)
    for i, x in enumerate(values):
        v = builder.insert_element(v, x, ir.Constant(ir.IntType(32), i))
    return v


def _lanes(builder, v) -> list:
    """The four doubles of a ``<4 x double>``."""
    return [builder.extract_element(v, ir.Constant(ir.IntType(32), i)) for i in range(4)]


def _call_vector(builder, symbol: str, vectors: list) -> ir.Value:
    """``symbol`` (a function of ``<4 x double>`` arguments) at ``vectors``."""
    fn = cgutils.get_or_insert_function(builder.module,
                                        ir.FunctionType(_V4, [_V4] * len(vectors)), symbol)
    return builder.call(fn, vectors)


def _call_v4(context, builder, name: str, vectors: list) -> ir.Value:
    """``name`` of the lanes of ``<4 x double>`` arguments: libmvec's function where the
    kernel uses it (:func:`_vectorized`), else four scalar calls."""
    symbol, scalar, arity = _FUNCTIONS[name]
    if _vectorized(context, name):
        return _call_vector(builder, symbol, vectors)
    dbl = ir.DoubleType()
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(dbl, [dbl] * arity),
                                        scalar)
    lanes = [_lanes(builder, v) for v in vectors]
    return _vector(builder, [builder.call(fn, [x[i] for x in lanes]) for i in range(4)])


def _call4(context, builder, name: str, args: list) -> list:
    """``name`` of four lanes (``args``: the arguments' four values each, in order)."""
    return _lanes(builder, _call_v4(context, builder, name,
                                    [_vector(builder, values) for values in args]))


_F8 = types.float64


@intrinsic
def cis4(typingctx, x0, x1, x2, x3):  # pragma: no cover - compiled
    """``(cos x0, .., cos x3, sin x0, .., sin x3)`` of four phases (unused lanes: 0)."""
    def codegen(context, builder, sig, args):
        out = _call4(context, builder, "cos", [args]) + _call4(context, builder, "sin", [args])
        return context.make_tuple(builder, sig.return_type, out)

    return types.UniTuple(_F8, 8)(_F8, _F8, _F8, _F8), codegen


@intrinsic
def atan2_4(typingctx, y0, y1, y2, y3, x0, x1, x2, x3):  # pragma: no cover - compiled
    """``(atan2(y0, x0), .., atan2(y3, x3))`` (unused lanes: ``atan2(0, 1)``)."""
    def codegen(context, builder, sig, args):
        out = _call4(context, builder, "atan2", [args[:4], args[4:]])
        return context.make_tuple(builder, sig.return_type, out)

    return types.UniTuple(_F8, 4)(*([_F8] * 8)), codegen


# ------------------------------------------------------------------ four lanes as a value
# numba keeps tuples of four doubles as four scalars (and its SLP vectorizer is off), so a
# chain of operations on them stays scalar; a value of type V4 is one ``<4 x double>``:
# the scan's points that are known ahead (its base grid) are evaluated four at a time.

class V4Type(types.Type):
    """Four doubles in one vector register (``<4 x double>``); arithmetic with ``+``,
    ``-`` (also unary), ``*`` and ``/``, with V4 or float operands (a float stands for four
    copies): lane by lane the scalar operations' bits."""

    def __init__(self):
        super().__init__(name="V4")


V4 = V4Type()


@register_model(V4Type)
class _V4Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _V4)


@intrinsic
def v4(typingctx, x0, x1, x2, x3):  # pragma: no cover - compiled
    """The V4 of four floats."""
    def codegen(context, builder, sig, args):
        return _vector(builder, args)

    return V4(_F8, _F8, _F8, _F8), codegen


@intrinsic
def splat(typingctx, x):  # pragma: no cover - compiled
    """The V4 of four copies of ``x``."""
    def codegen(context, builder, sig, args):
        return _vector(builder, [args[0]] * 4)

    return V4(_F8), codegen


@intrinsic
def lane(typingctx, v, i):  # pragma: no cover - compiled
    """Lane ``i`` of a V4."""
    def codegen(context, builder, sig, args):
        return builder.extract_element(args[0], args[1])

    return _F8(V4, types.intp), codegen


@intrinsic
def with_lane(typingctx, v, i, x):  # pragma: no cover - compiled
    """``v`` with lane ``i`` replaced by ``x``."""
    def codegen(context, builder, sig, args):
        return builder.insert_element(args[0], args[2], args[1])

    return V4(V4, types.intp, _F8), codegen


@intrinsic
def sqrt_v4(typingctx, v):  # pragma: no cover - compiled
    """The square roots of a V4's lanes in one instruction (``llvm.sqrt.v4f64``):
    correctly rounded, as the scalar square root, on every target."""
    def codegen(context, builder, sig, args):
        return _call_vector(builder, "llvm.sqrt.v4f64", args)

    return V4(V4), codegen


@intrinsic
def cis_v4(typingctx, v):  # pragma: no cover - compiled
    """``(cos v, sin v)`` of a V4 (:func:`cis4`'s functions)."""
    def codegen(context, builder, sig, args):
        return context.make_tuple(builder, sig.return_type,
                                  [_call_v4(context, builder, "cos", args),
                                   _call_v4(context, builder, "sin", args)])

    return types.UniTuple(V4, 2)(V4), codegen


@intrinsic
def atan2_v4(typingctx, y, x):  # pragma: no cover - compiled
    """:func:`atan2_4` of two V4s."""
    def codegen(context, builder, sig, args):
        return _call_v4(context, builder, "atan2", args)

    return V4(V4, V4), codegen


@intrinsic
def all_within(typingctx, v, lo, hi):  # pragma: no cover - compiled
    """Every lane of ``v`` strictly between ``lo`` and ``hi`` (false for NaN)."""
    def codegen(context, builder, sig, args):
        ok = None
        for x in _lanes(builder, args[0]):
            inside = builder.and_(builder.fcmp_ordered(">", x, args[1]),
                                  builder.fcmp_ordered("<", x, args[2]))
            ok = inside if ok is None else builder.and_(ok, inside)
        return ok

    return types.boolean(V4, _F8, _F8), codegen


def _binary(op: str):
    @intrinsic
    def vector_op(typingctx, a, b):  # pragma: no cover - compiled
        def codegen(context, builder, sig, args):
            return getattr(builder, op)(args[0], args[1])

        return V4(V4, V4), codegen

    return vector_op


def _operator(fn, vector_op) -> None:
    @overload(fn, inline="always")
    def impl(a, b):
        scalar = (types.Float, types.Integer)
        if isinstance(a, V4Type) and isinstance(b, V4Type):
            return lambda a, b: vector_op(a, b)
        if isinstance(a, V4Type) and isinstance(b, scalar):
            return lambda a, b: vector_op(a, splat(float(b)))
        if isinstance(a, scalar) and isinstance(b, V4Type):
            return lambda a, b: vector_op(splat(float(a)), b)
        return None


for _fns, _op in (((operator.add, operator.iadd), "fadd"),
                  ((operator.sub, operator.isub), "fsub"),
                  ((operator.mul, operator.imul), "fmul"),
                  ((operator.truediv, operator.itruediv), "fdiv")):
    _vector_op = _binary(_op)  # (one intrinsic for ``a op b`` and ``a op= b``)
    for _fn in _fns:
        _operator(_fn, _vector_op)


@intrinsic
def _negate(typingctx, v):  # pragma: no cover - compiled
    def codegen(context, builder, sig, args):
        return builder.fneg(args[0])  # (a sign flip, -0 of +0, as the scalar minus)

    return V4(V4), codegen


@overload(operator.neg, inline="always")
def _neg(v):
    if isinstance(v, V4Type):
        return lambda v: _negate(v)
    return None
