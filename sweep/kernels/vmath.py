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

Owns: the vector exp, log, expm1 and the choice of their variant; the vector type and
its elementwise operations. May import: nothing from
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
from numba.core.datamodel import models
from numba.extending import intrinsic, register_model

from sweep.kernels._jit import jit

__all__ = ["WIDTH", "VARIANT", "log1", "exp1", "log4", "exp4", "expm1_4", "sqrt_div4", "HAS",
           "VECTOR", "EVERY_ELEMENT", "Vector", "vector", "vpack", "vtuple", "vadd", "vsub",
           "vmul", "vdiv", "vsqrt", "vabs", "vwhere_positive", "vwhere_nonnegative",
           "vwhere_equal", "vsqrt_where_equal", "vlt_bits", "vle_bits", "vgt_bits", "vge_bits",
           "veq_bits", "vnan_bits", "vselect_bits", "ieq_bits", "ilt_bits", "vload", "vstore",
           "vscatter", "vgather", "vdot"]

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
        root = _sqrt(builder, xv)
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


#: Elements of the vectors of the elementwise operations below (:func:`vadd` ..
#: :func:`vdot`): IEEE operations as vector instructions, each element with the bits of the
#: scalar operation (kernels' contraction included), for the stages of groups of the array
#: kernels' lanes (:func:`sweep.kernels.stepper.rk_step_lanes`). Four: groups of eight
#: lanes, their stages unrolled, cost 2-3 s more of first compile for no speed on KK
#: (docs/speed/history.md, 2026-12-05).
VECTOR = 4
#: The bit mask of a whole vector (the ``*_bits`` comparisons set bit k for element k).
EVERY_ELEMENT = (1 << VECTOR) - 1
_VT = ir.VectorType(ir.DoubleType(), VECTOR)
_CONTRACT = ("contract",)
_I32 = ir.IntType(32)


class Vector(types.Type):
    """numba type of :data:`VECTOR` float64 held as one LLVM vector: the operations below
    take and give it without the tuples' packing at every call (their IR took a second of
    first compile to clean up, and sums carried through loops as tuples went element by
    element)."""

    def __init__(self):
        super().__init__(name=f"vector{VECTOR}_float64")


#: The one :class:`Vector` type.
vector = Vector()


@register_model(Vector)
class _VectorModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VT)


def _is_tuple(t):
    return isinstance(t, types.UniTuple) and t.count == VECTOR and t.dtype == types.float64


def _operand(t):
    """Operands: a :class:`Vector`, a :data:`VECTOR`-tuple of float64, or a float64 (every
    element)."""
    if not (t == vector or _is_tuple(t) or t == types.float64):
        raise numba.core.errors.TypingError(f"a vector, a {VECTOR}-tuple of float64 or a "
                                            f"float64 is needed, got {t}")


def _vector(builder, t, value):
    """The LLVM vector of an operand (:func:`_operand`)."""
    if t == vector:
        return value
    if isinstance(t, types.UniTuple):
        return _pack(builder, _VT, cgutils.unpack_tuple(builder, value))
    return _pack(builder, _VT, [value] * VECTOR)


@intrinsic
def vpack(typingctx, x):
    """The :class:`Vector` of an operand (:func:`_operand`)."""
    _operand(x)

    def codegen(context, builder, signature, args):
        return _vector(builder, x, args[0])
    return vector(x), codegen


@intrinsic
def vtuple(typingctx, x):
    """The :data:`VECTOR`-tuple of float64 of a :class:`Vector`."""
    if x != vector:
        raise numba.core.errors.TypingError(f"a vector is needed, got {x}")
    ret = types.UniTuple(types.float64, VECTOR)

    def codegen(context, builder, signature, args):
        return context.make_tuple(builder, ret, [
            builder.extract_element(args[0], ir.Constant(_I32, k)) for k in range(VECTOR)])
    return ret(x), codegen


def _two_operands(build, result):
    """An intrinsic of two operands (:func:`_operand`): ``build(builder, a, b)`` of their
    LLVM vectors, of numba type ``result``."""
    @intrinsic
    def of(typingctx, x, y):
        _operand(x)
        _operand(y)

        def codegen(context, builder, signature, args):
            a, b = (_vector(builder, t, v) for t, v in zip(signature.args, args))
            return build(builder, a, b)
        return result(x, y), codegen
    return of


def _binary(operation):
    # With the kernels' one fastmath flag (sweep.kernels._jit.FLAGS): a product and a sum
    # fuse here as they do in the scalar code.
    return _two_operands(lambda b, x, y: getattr(b, operation)(x, y, flags=_CONTRACT), vector)


#: ``x + y``, ``x - y``, ``x * y``, ``x / y`` element by element.
vadd, vsub, vmul, vdiv = _binary("fadd"), _binary("fsub"), _binary("fmul"), _binary("fdiv")


@intrinsic
def vabs(typingctx, x):
    """``abs`` of each element."""
    _operand(x)

    def codegen(context, builder, signature, args):
        v = _vector(builder, x, args[0])
        fabs = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(_VT, [_VT]), f"llvm.fabs.v{VECTOR}f64")
        return builder.call(fabs, [v])
    return vector(x), codegen


def _bits(builder, test):
    """The int64 whose bit k is element k of a <VECTOR x i1>."""
    return builder.zext(builder.bitcast(test, ir.IntType(VECTOR)), ir.IntType(64))


def _compare(predicate):
    return _two_operands(lambda b, x, y: _bits(b, b.fcmp_ordered(predicate, x, y)),
                         types.int64)


#: Bit k set where ``x[k] < y[k]`` (``<=``, ``>``, ``>=``, ``==``): Python's comparisons of
#: floats, False where an element is NaN, as int64 bit masks of the elements.
vlt_bits, vle_bits, vgt_bits = _compare("<"), _compare("<="), _compare(">")
vge_bits, veq_bits = _compare(">="), _compare("==")


@intrinsic
def vnan_bits(typingctx, x):
    """Bit k set where element k is NaN."""
    _operand(x)

    def codegen(context, builder, signature, args):
        v = _vector(builder, x, args[0])
        return _bits(builder, builder.fcmp_unordered("uno", v, v))
    return types.int64(x), codegen


@intrinsic
def vselect_bits(typingctx, bits, a, b):
    """``a[k] if bit k of bits else b[k]`` element by element (``bits`` an integer)."""
    if not isinstance(bits, types.Integer):
        raise numba.core.errors.TypingError(f"integer bits are needed, got {bits}")
    _operand(a)
    _operand(b)

    def codegen(context, builder, signature, args):
        test = builder.bitcast(builder.trunc(context.cast(builder, args[0], bits, types.int64),
                                             ir.IntType(VECTOR)), ir.VectorType(ir.IntType(1),
                                                                                VECTOR))
        av, bv = (_vector(builder, t, v) for t, v in zip(signature.args[1:], args[1:]))
        return builder.select(test, av, bv)
    return vector(bits, a, b), codegen


_IVT = ir.VectorType(ir.IntType(64), VECTOR)


@intrinsic
def ieq_bits(typingctx, arr, start, value):
    """Bit k set where ``a.flat[start + k] == value``, k < VECTOR, for a C-contiguous int64
    array (one vector load, no bounds check)."""
    _require_flat(arr, start, value, dtype=types.int64)

    def codegen(context, builder, signature, args):
        x = builder.load(_at(context, builder, arr, args[0], args[1], start, _IVT), align=8)
        v = context.cast(builder, args[2], value, types.int64)
        return _bits(builder, builder.icmp_signed("==", x, _pack(builder, _IVT,
                                                                   [v] * VECTOR)))
    return types.int64(arr, start, value), codegen


@intrinsic
def ilt_bits(typingctx, arr, i, j):
    """Bit k set where ``a.flat[i + k] < a.flat[j + k]``, k < VECTOR, for a C-contiguous
    int64 array ``a`` (two vector loads, no bounds check)."""
    _require_flat(arr, i, j, dtype=types.int64)

    def codegen(context, builder, signature, args):
        x, y = (builder.load(_at(context, builder, arr, args[0], at, t, _IVT), align=8)
                for at, t in ((args[1], i), (args[2], j)))
        return _bits(builder, builder.icmp_signed("<", x, y))
    return types.int64(arr, i, j), codegen


def _sqrt(builder, v):
    """LLVM's square root of a vector of doubles (IEEE, element by element)."""
    sqrt = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v.type, [v.type]),
                                          f"llvm.sqrt.v{v.type.count}f64")
    return builder.call(sqrt, [v])


@intrinsic
def vsqrt(typingctx, x):
    """``math.sqrt`` of each element (one vector root)."""
    _operand(x)

    def codegen(context, builder, signature, args):
        return _sqrt(builder, _vector(builder, x, args[0]))
    return vector(x), codegen


def _where(predicate):
    @intrinsic
    def where(typingctx, x, a, b):
        for t in (x, a, b):
            _operand(t)

        def codegen(context, builder, signature, args):
            xv, av, bv = (_vector(builder, t, v) for t, v in zip(signature.args, args))
            zero = ir.Constant(_VT, [0.0] * VECTOR)
            return builder.select(builder.fcmp_ordered(predicate, xv, zero), av, bv)
        return vector(x, a, b), codegen
    return where


#: ``a if x > 0 else b`` and ``a if x >= 0 else b`` element by element.
vwhere_positive, vwhere_nonnegative = _where(">"), _where(">=")


def _codes(k, value):
    """Type check of codes (an operand holding integers) and the code they are compared
    with."""
    _operand(k)
    if not isinstance(value, types.Integer):
        raise numba.core.errors.TypingError(f"an integer code is needed, got {value}")


def _equal(context, builder, k, kv, value, val):
    """The <VECTOR x i1> of ``k == value`` element by element."""
    code = context.cast(builder, val, value, types.float64)
    return builder.fcmp_ordered("==", _vector(builder, k, kv), _pack(builder, _VT,
                                                                      [code] * VECTOR))


@intrinsic
def vwhere_equal(typingctx, k, value, a, b):
    """``a if k == value else b`` element by element, ``k`` codes (float64 holding
    integers)."""
    _codes(k, value)
    _operand(a)
    _operand(b)

    def codegen(context, builder, signature, args):
        test = _equal(context, builder, k, args[0], value, args[1])
        av, bv = (_vector(builder, t, v) for t, v in zip(signature.args[2:], args[2:]))
        return builder.select(test, av, bv)
    return vector(k, value, a, b), codegen


@intrinsic
def vsqrt_where_equal(typingctx, k, value, x, b):
    """``math.sqrt(x) if k == value else b`` element by element, ``k`` codes as for
    :func:`vwhere_equal`. Where no element has ``k == value`` the result is b without the
    root: a select after the root would wait on it (and on x) whatever it selects, a
    root's latency on every lane's chain."""
    _codes(k, value)
    _operand(x)
    _operand(b)

    def codegen(context, builder, signature, args):
        test = _equal(context, builder, k, args[0], value, args[1])
        bv = _vector(builder, b, args[3])
        anyone = builder.icmp_unsigned("!=", builder.bitcast(test, ir.IntType(VECTOR)),
                                       ir.Constant(ir.IntType(VECTOR), 0))
        before = builder.basic_block
        with builder.if_then(anyone):
            rooted = builder.select(test, _sqrt(builder, _vector(builder, x, args[2])), bv)
            then = builder.basic_block
        result = builder.phi(_VT)
        result.add_incoming(rooted, then)
        result.add_incoming(bv, before)
        return result
    return vector(k, value, x, b), codegen


def _require_flat(arr, *indices, dtype=types.float64):
    """Type check of the memory operations' arguments: a C-contiguous array of ``dtype``
    (read through its data pointer, flat) and integer indices into it."""
    if not (isinstance(arr, types.Array) and arr.layout == "C" and arr.dtype == dtype
            and all(isinstance(t, types.Integer) for t in indices)):
        raise numba.core.errors.TypingError(
            f"a C-contiguous {dtype} array and integer indices are needed, "
            f"got {arr} and {', '.join(str(t) for t in indices)}")


def _strided(context, builder, signature, args, count):
    """The indices ``start + k stride``, k < count, of an intrinsic whose arguments 1 and 2
    are start and stride."""
    first = context.cast(builder, args[1], signature.args[1], types.intp)
    step = context.cast(builder, args[2], signature.args[2], types.intp)
    return [builder.add(first, builder.mul(step, ir.Constant(step.type, k)))
            for k in range(count)]


def _at(context, builder, arr, value, index, index_type, vt=_VT):
    """Pointer to element ``index`` of a C-contiguous array's data, seen as a vector of
    type ``vt``."""
    data = context.make_array(arr)(context, builder, value).data
    ptr = builder.gep(data, [context.cast(builder, index, index_type, types.intp)])
    return builder.bitcast(ptr, vt.as_pointer())


@intrinsic
def vload(typingctx, arr, start):
    """The vector ``a.flat[start:start + VECTOR]`` of a C-contiguous float64 array, as one
    load (no bounds check)."""
    _require_flat(arr, start)

    def codegen(context, builder, signature, args):
        return builder.load(_at(context, builder, arr, args[0], args[1], start), align=8)
    return vector(arr, start), codegen


@intrinsic
def vstore(typingctx, arr, start, x):
    """``a.flat[start:start + VECTOR] = x`` for a C-contiguous float64 array, as one store
    (no bounds check)."""
    _require_flat(arr, start)
    _operand(x)

    def codegen(context, builder, signature, args):
        builder.store(_vector(builder, x, args[2]),
                      _at(context, builder, arr, args[0], args[1], start), align=8)
        return context.get_dummy_value()
    return types.none(arr, start, x), codegen


@intrinsic
def vscatter(typingctx, arr, start, stride, x):
    """``a.flat[start + k stride] = x[k]`` for a C-contiguous float64 array, element by
    element (no bounds check)."""
    _require_flat(arr, start, stride)
    _operand(x)

    def codegen(context, builder, signature, args):
        data = context.make_array(arr)(context, builder, args[0]).data
        v = _vector(builder, x, args[3])
        for k, at in enumerate(_strided(context, builder, signature, args, VECTOR)):
            builder.store(builder.extract_element(v, ir.Constant(_I32, k)),
                          builder.gep(data, [at]))
        return context.get_dummy_value()
    return types.none(arr, start, stride, x), codegen


@intrinsic
def vgather(typingctx, arr, start, stride):
    """The vector ``(a.flat[start + k stride])``, k < VECTOR, of a C-contiguous float64
    array, element by element (no bounds check): elements stored one by one just before
    (a vector load of them would wait for the stores to complete)."""
    _require_flat(arr, start, stride)

    def codegen(context, builder, signature, args):
        data = context.make_array(arr)(context, builder, args[0]).data
        return _pack(builder, _VT, [builder.load(builder.gep(data, [at])) for at in
                                    _strided(context, builder, signature, args, VECTOR)])
    return vector(arr, start, stride), codegen


@intrinsic
def vdot(typingctx, arr, start, stride, coefficients):
    """``sum_j c_j a.flat[start + j stride : .. + VECTOR]`` over the float64
    ``coefficients`` c_j, summed from 0 in their order as ``s += c_j x_j`` is (the
    kernels' contraction included), for a C-contiguous float64 array."""
    _require_flat(arr, start, stride)
    if not (isinstance(coefficients, types.UniTuple) and coefficients.dtype == types.float64):
        raise numba.core.errors.TypingError(f"a tuple of float64 coefficients is needed, got "
                                            f"{coefficients}")

    def codegen(context, builder, signature, args):
        total = ir.Constant(_VT, [0.0] * VECTOR)
        cs = cgutils.unpack_tuple(builder, args[3])
        for c, at in zip(cs, _strided(context, builder, signature, args, len(cs))):
            x = builder.load(_at(context, builder, arr, args[0], at, types.intp), align=8)
            term = builder.fmul(_pack(builder, _VT, [c] * VECTOR), x, flags=_CONTRACT)
            total = builder.fadd(total, term, flags=_CONTRACT)
        return total
    return vector(arr, start, stride, coefficients), codegen
