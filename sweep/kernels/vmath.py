"""exp and log of several lanes in one call: glibc's vector math library (libmvec).

The stages of general exponents take one log and two exps per lane (the powers of
:func:`sweep.kernels.contact.rhs`); glibc's scalar calls cost about 14 ns for the three
per lane, and numba here has no SVML to vectorise them. libmvec's vector functions
compute :data:`WIDTH` of them in about the time of one scalar call.

**The same bits for one lane and for many.** The one-point march evaluates its powers with
:func:`log1` and :func:`exp1`, which put their argument in lane 0 of the same vector
function that :func:`log4` and :func:`exp4` apply to four of the array kernels' lanes
(4-tuples, built and taken apart in registers): vector math functions are elementwise, so
a lane's result does not depend on what the other lanes hold (``tests/test_vmath.py``),
and the two marches stay bit-identical.

**Where libmvec is not used.** The variant is chosen once, at import: AVX2 (4 doubles),
else AVX-512 (8), else SSE4 (2), the first that the host CPU has, on x86_64 with libmvec
found (glibc 2.22 or later). Elsewhere -- another C library or machine, a CPU
without SSE4.1, or numba told to compile for another CPU than the host
(``NUMBA_CPU_NAME``/``NUMBA_CPU_FEATURES``: the vector registers a call passes through
would not be known) -- :data:`WIDTH` is 0 and the same functions call ``math.log`` and
``math.exp``; on the GPU they are always libdevice's. Results for general exponents then
differ in the last bits from a machine that uses libmvec, or from another variant: glibc
documents libmvec's double exp and log within 4 ulp of the exact value (its scalar exp
and log within 1). Measured (AVX2 variant, 1e5 arguments over the march's ranges: u in
[1e-300, 10], exponents in [0, 3]): log within 1 ulp of mpmath's correctly rounded value,
exp within 3 (glibc's scalar calls: 1 and 1); they differ from the scalar calls' results
for 21% of the logs and 31% of the exps. ``tests/test_vmath.py`` holds them to 4. The
report's models and integer exponents take no exp or log in their stages: their results do
not depend on this module.

**The closed forms' quadratures** (:mod:`sweep.kernels.special`) take the exps of their
nodes four at a time as tuples (:func:`exp4`, :func:`expm1_4`), no array in between, and
the nodes' square roots and divisions four at a time (:func:`sqrt_div4`, IEEE vector
operations, the bits of the scalar ones). libmvec's expm1
came with glibc 2.35: :data:`HAS` says which functions it has here, and a
function it lacks is math's call element by element.

Owns: the vector exp, log, expm1 and the choice of their variant. May import: nothing from
``sweep`` but _jit.
"""
from __future__ import annotations

import ctypes.util
import math
import platform

import llvmlite.binding as llvm
import numba
from llvmlite import ir
from numba.core import cgutils, types
from numba.core.cpu import CPUContext
from numba.extending import intrinsic

from sweep.kernels._jit import jit

__all__ = ["WIDTH", "VARIANT", "log1", "exp1", "log4", "exp4", "expm1_4", "sqrt_div4", "HAS"]

# libmvec's variants, in order of preference: (CPU feature, name letter of the x86_64
# vector ABI, doubles per vector). AVX2 before AVX-512: on the AMD EPYC (Zen 4) where it was
# measured, which runs AVX-512 on 256-bit units, general exponents took 2-3% less time a
# point with two 4-wide calls than with one 8-wide (2026-12-04, interleaved).
_VARIANTS = (("avx2", "d", 4), ("avx512f", "e", 8), ("sse4.1", "b", 2))


def _variant() -> tuple[str, int]:
    """(name letter, width) of the libmvec variant to call, or ("", 0) for math's calls."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return "", 0
    if numba.config.CPU_NAME or numba.config.CPU_FEATURES:
        return "", 0
    path = ctypes.util.find_library("mvec")
    if not path:
        return "", 0
    try:
        llvm.load_library_permanently(path)
    except RuntimeError:
        return "", 0
    features = llvm.get_host_cpu_features()
    for feature, letter, width in _VARIANTS:
        if features.get(feature) and all(llvm.address_of_symbol(_name(letter, width, f))
                                         for f in ("exp", "log")):
            return letter, width
    return "", 0


def _name(letter: str, width: int, function: str) -> str:
    return f"_ZGV{letter}N{width}v_{function}"


_LETTER, WIDTH = _variant()
#: libmvec's symbol stem in use (e.g. ``_ZGVeN8v``), or "" where math's calls are used.
VARIANT = _name(_LETTER, WIDTH, "")[:-1] if WIDTH else ""
#: The functions of this module that libmvec has in the variant in use (its expm1 came
#: with glibc 2.35); the others are math's calls, element by element.
HAS = frozenset(f for f in ("exp", "log", "expm1")
                if WIDTH and llvm.address_of_symbol(_name(_LETTER, WIDTH, f)))


def _vector_call(builder, function, vector):
    """``function`` (``exp`` or ``log``) of the <WIDTH x double> ``vector``, by libmvec."""
    vt = vector.type
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vt, [vt]),
                                        _name(_LETTER, WIDTH, function))
    return builder.call(fn, [vector])


def _scalar_call(context, builder, function, x):
    """``math.<function>(x)`` as the target compiles it (the C library's, libdevice's,
    LLVM's sqrt)."""
    sig = types.float64(types.float64)
    return context.get_function(getattr(math, function), sig)(builder, [x])


def _scalar_intrinsic(function):
    """Intrinsic: ``function`` of a float64 in lane 0 of the vector call (the others 1.0)."""

    @intrinsic
    def of_lane0(typingctx, x):
        sig = types.float64(types.float64)

        def codegen(context, builder, signature, args):
            if not WIDTH or not isinstance(context, CPUContext):
                return _scalar_call(context, builder, function, args[0])
            lanes = _pack(builder, ir.VectorType(ir.DoubleType(), WIDTH), [args[0]], 1.0)
            result = _vector_call(builder, function, lanes)
            return builder.extract_element(result, ir.Constant(ir.IntType(32), 0))
        return sig, codegen
    return of_lane0


_log_lane0, _exp_lane0 = _scalar_intrinsic("log"), _scalar_intrinsic("exp")


@jit(inline="always")
def log1(x):
    """Natural log of a float64, bit for bit as :func:`log4` gives it for an element."""
    return _log_lane0(x)


@jit(inline="always")
def exp1(x):
    """exp of a float64, bit for bit as :func:`exp4` gives it for an element."""
    return _exp_lane0(x)


# Elements of the tuples of log4, exp4 and expm1_4.
_TUPLE = 4


def _tuple_intrinsic(function):
    """Intrinsic: ``function`` of each element of a 4-tuple of float64, by as many vector
    calls as :data:`WIDTH` needs (lanes past the tuple hold 1.0), or by math's calls where
    the host's libmvec lacks ``function``. No array, so no reference count to update: the
    closed forms call it at every quadrature node."""

    @intrinsic
    def of4(typingctx, t):
        if not (isinstance(t, types.UniTuple) and t.count == _TUPLE
                and t.dtype == types.float64):
            raise numba.core.errors.TypingError(f"a 4-tuple of float64 is needed, got {t}")

        def codegen(context, builder, signature, args):
            values = cgutils.unpack_tuple(builder, args[0])
            if function not in HAS or not isinstance(context, CPUContext):
                out = [_scalar_call(context, builder, function, v) for v in values]
            else:
                out = []
                for start in range(0, _TUPLE, WIDTH):
                    part = values[start:start + WIDTH]
                    lanes = _pack(builder, ir.VectorType(ir.DoubleType(), WIDTH), part, 1.0)
                    result = _vector_call(builder, function, lanes)
                    out += [builder.extract_element(result, ir.Constant(ir.IntType(32), k))
                            for k in range(len(part))]
            return context.make_tuple(builder, signature.return_type, out)
        return t(t), codegen
    return of4


#: ``(exp(x0), .., exp(x3))`` of a 4-tuple of float64, bit for bit as :func:`exp1` gives
#: each (vector functions are elementwise).
exp4 = _tuple_intrinsic("exp")
#: ``(log(x0), .., log(x3))``, bit for bit as :func:`log1` gives each. Arguments <= 0 or
#: NaN cost a scalar call inside libmvec: elements that need no log should hold 1.0.
log4 = _tuple_intrinsic("log")
#: ``expm1`` of each element of a 4-tuple of float64 (libmvec's where it has it).
expm1_4 = _tuple_intrinsic("expm1")


@intrinsic
def sqrt_div4(typingctx, x, y):
    """``(sqrt(x_k), y_k / sqrt(x_k))`` of two 4-tuples of float64, as 4-wide vector
    operations: IEEE square root and division are correctly rounded, so each element has the
    bits of the scalar ``math.sqrt`` and ``/``; the quadrature nodes' sqrt and division,
    one at a time, were throughput-bound (scalar vsqrtsd, vdivsd)."""
    for t in (x, y):
        if not (isinstance(t, types.UniTuple) and t.count == _TUPLE
                and t.dtype == types.float64):
            raise numba.core.errors.TypingError(f"4-tuples of float64 are needed, got {t}")

    def codegen(context, builder, signature, args):
        if not isinstance(context, CPUContext):
            # The GPU (the undamped duration's quadrature is in its kernel): scalar forms.
            roots = [_scalar_call(context, builder, "sqrt", v)
                     for v in cgutils.unpack_tuple(builder, args[0])]
            ratios = [builder.fdiv(v, r)
                      for v, r in zip(cgutils.unpack_tuple(builder, args[1]), roots)]
            return context.make_tuple(builder, signature.return_type,
                                      [context.make_tuple(builder, x, roots),
                                       context.make_tuple(builder, x, ratios)])
        vt = ir.VectorType(ir.DoubleType(), _TUPLE)
        xv, yv = (_pack(builder, vt, cgutils.unpack_tuple(builder, a)) for a in args)
        sqrt = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vt, [vt]),
                                              f"llvm.sqrt.v{_TUPLE}f64")
        root = builder.call(sqrt, [xv])
        ratio = builder.fdiv(yv, root)
        out = [context.make_tuple(builder, x, [builder.extract_element(
            v, ir.Constant(ir.IntType(32), k)) for k in range(_TUPLE)]) for v in (root, ratio)]
        return context.make_tuple(builder, signature.return_type, out)
    return types.Tuple((x, x))(x, y), codegen


def _pack(builder, vt, values, pad=None):
    """An LLVM vector of the scalars ``values`` in its first lanes, the others ``pad``
    (undefined where None: every lane is given)."""
    v = ir.Constant(vt, ir.Undefined if pad is None else [pad] * vt.count)
    for k, e in enumerate(values):
        v = builder.insert_element(v, e, ir.Constant(ir.IntType(32), k))
    return v
