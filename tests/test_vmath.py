"""The vector exp and log (sweep.kernels.vmath) against mpmath, and one lane against many.

The one-point march takes its general powers from log1/exp1, the lanes' stages from
log4/exp4: the two marches are bit-identical only if an element's result does not
depend on what the other elements of its vector hold.
"""
from __future__ import annotations

import os
import subprocess
import sys

import mpmath
import numba
import numpy as np
import pytest

from sweep.kernels import vmath

EPS = np.finfo(float).eps
# glibc's documented bound for libmvec's double exp and log: 4 ulp.
ULPS = 4


@numba.njit
def _ones(x, f):
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = vmath.log1(x[i]) if f == 0 else vmath.exp1(x[i])
    return out


@numba.njit
def _fours(x, f):
    """log4 (f = 0) or exp4 of x, four elements at a time (x.size a multiple of 4)."""
    out = np.empty_like(x)
    for i in range(0, x.size, 4):
        t = (x[i], x[i + 1], x[i + 2], x[i + 3])
        r = vmath.log4(t) if f == 0 else vmath.exp4(t)
        for k in range(4):
            out[i + k] = r[k]
    return out


def _arguments(rng, n):
    """The march's arguments: u in [1e-300, 10] (log-uniform) for log, and p log u with
    p in [0, 3] for exp (down to -2072: exp's underflow to 0 included)."""
    u = 10 ** rng.uniform(-300, 1, n)
    return u, rng.uniform(0, 3, n) * np.log(u)


@pytest.mark.parametrize("f", [0, 1])
def test_an_element_does_not_depend_on_the_others(f):
    rng = np.random.default_rng(1)
    x = _arguments(rng, 4000)[f]
    one = _ones(x, f)
    # Each element among neighbours of every kind: ordinary, 1.0, special, out of range.
    junk = np.array([1.0, 0.0, -1.0, np.nan, np.inf, -np.inf, 1e308, -1e308, 5e-324, 800.0])
    P = rng.choice(junk, size=(x.size, 4))
    at = rng.integers(0, 4, x.size)
    P[np.arange(x.size), at] = x
    got = _fours(P.ravel(), f).reshape(P.shape)
    assert np.array_equal(got[np.arange(x.size), at], one)


def _mp(f, x):
    with mpmath.workdps(40):
        return np.array([float(mpmath.log(v) if f == 0 else mpmath.exp(v)) for v in x])


@pytest.mark.parametrize("f", [0, 1])
def test_within_glibcs_bound_of_mpmath(f):
    x = _arguments(np.random.default_rng(2), 100_000)[f]
    got, ref = _fours(x, f), _mp(f, x)
    normal = np.abs(ref) >= np.finfo(float).tiny
    assert np.all(np.abs(got - ref)[normal] <= ULPS * EPS * np.abs(ref[normal]))
    # Subnormal and underflowing exps: within a few of the smallest subnormals.
    assert np.all(np.abs(got - ref)[~normal] <= ULPS * 5e-324)


def test_math_serves_for_another_cpu_than_the_host():
    """Compiling for another CPU than the host, every function falls back to math's."""
    code = ("import math, numba; from sweep.kernels import vmath\n"
            "f = numba.njit(lambda x: (vmath.log1(x), vmath.exp1(x), vmath.exp4((x, x, x, x))[2],"
            " vmath.expm1_4((x, x, x, x))[1], vmath.log4((x, x, x, x))[3]))\n"
            "print(vmath.WIDTH, sorted(vmath.HAS), f(0.3) == (math.log(0.3), math.exp(0.3),"
            " math.exp(0.3), math.expm1(0.3), math.log(0.3)))")
    env = dict(os.environ, NUMBA_CPU_NAME="generic")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out == ["0", "[]", "True"]


# ----------------------------------------------------------------------------------------
# The 4-tuple forms the closed forms' quadratures use (exp4, expm1_4, sqrt_div4)
# ----------------------------------------------------------------------------------------

_TUPLE_FUNCTIONS = {"exp": vmath.exp4, "expm1": vmath.expm1_4}


def _by_fours(name):
    f = _TUPLE_FUNCTIONS[name]

    @numba.njit
    def run(x):
        out = np.empty_like(x)
        for i in range(0, x.size, 4):
            r = f((x[i], x[i + 1], x[i + 2], x[i + 3]))
            for k in range(4):
                out[i + k] = r[k]
        return out
    return run


def _tuple_arguments(name, rng, n):
    """The quadratures' arguments: exps of f log x, x in (1e-40, 1), f in [0, 11]
    (underflow included); expm1 of a log near 0 and below."""
    lx = -10 ** rng.uniform(-8, 2, n)
    return rng.uniform(0, 11, n) * lx


def _mp_of(name, x):
    f = {"exp": mpmath.exp, "expm1": mpmath.expm1}[name]
    with mpmath.workdps(40):
        return np.array([float(f(mpmath.mpf(v))) for v in x])


@pytest.mark.parametrize("name", ["exp", "expm1"])
def test_tuples_within_glibcs_bound_of_mpmath(name):
    x = _tuple_arguments(name, np.random.default_rng(3), 20_000)
    got, ref = _by_fours(name)(x), _mp_of(name, x)
    normal = np.abs(ref) >= np.finfo(float).tiny
    assert np.all(np.abs(got - ref)[normal] <= ULPS * EPS * np.abs(ref[normal]))
    assert np.all(np.abs(got - ref)[~normal] <= ULPS * 5e-324)


def test_exp4_is_exp1_in_every_lane():
    """A lane's bits do not depend on its neighbours, and match the one-point exp1."""
    rng = np.random.default_rng(4)
    x = _tuple_arguments("exp", rng, 4000)
    junk = np.array([0.0, 1.0, -800.0, 800.0, np.nan, -np.inf])
    mixed = rng.choice(junk, x.size)
    keep = rng.integers(0, 2, x.size).astype(bool)
    got = _by_fours("exp")(np.where(keep, x, mixed))
    assert np.array_equal(got[keep], _ones(x[keep], 1))


@numba.njit
def _sqrt_div_by_fours(x, y):
    root, ratio = np.empty_like(x), np.empty_like(x)
    for i in range(0, x.size, 4):
        r, q = vmath.sqrt_div4((x[i], x[i + 1], x[i + 2], x[i + 3]),
                               (y[i], y[i + 1], y[i + 2], y[i + 3]))
        for k in range(4):
            root[i + k], ratio[i + k] = r[k], q[k]
    return root, ratio


def test_sqrt_div4_is_ieee_sqrt_and_division():
    """Correctly rounded, so numpy's sqrt and division give the same bits."""
    rng = np.random.default_rng(5)
    x = 10 ** rng.uniform(-300, 300, 8000)
    x[::97] = 0.0
    y = rng.normal(size=x.size) * 10 ** rng.uniform(-100, 100, x.size)
    root, ratio = _sqrt_div_by_fours(x, y)
    with np.errstate(divide="ignore"):
        assert np.array_equal(root, np.sqrt(x)) and np.array_equal(ratio, y / np.sqrt(x))


# ------------------------------------------------------------- elementwise tuple operations

_N = vmath.VECTOR


@numba.njit
def _elementwise(x, y):
    """Each operation alone over x, y by tuples of VECTOR (no neighbour to fuse with)."""
    out = np.empty((9, x.size))
    for i in range(0, x.size, _N):
        a, b = vmath.vload(x, i), vmath.vload(y, i)
        vmath.vstore(out[0], i, vmath.vadd(a, b))
        vmath.vstore(out[1], i, vmath.vsub(a, b))
        vmath.vstore(out[2], i, vmath.vmul(a, 0.7))
        vmath.vstore(out[3], i, vmath.vsqrt(b))
        vmath.vstore(out[4], i, vmath.vwhere_positive(a, b, -1.0))
        vmath.vstore(out[5], i, vmath.vwhere_nonnegative(a, 2.0, b))
        vmath.vscatter(out[6], i, 1, vmath.vwhere_equal(
            (float(i), float(i + 1), float(i + 2), float(i + 3)), i + 2, a, b))
        codes = (float(i % 3), 1.0, float(i % 5), 2.0)
        vmath.vstore(out[7], i, vmath.vwhere_equal(codes, 2, a, b))
        # A root where a code matches; none in the blocks where i % 3 and i % 5 differ
        # from 1, whose result is b (the branch without the root).
        vmath.vstore(out[8], i, vmath.vsqrt_where_equal(
            (float(i % 3), 0.0, float(i % 5), 0.0), 1, b, a))
    return out


def test_tuple_operations_are_the_scalar_ones_element_by_element():
    rng = np.random.default_rng(6)
    x = rng.normal(size=4096) * 10 ** rng.uniform(-5, 5, 4096)
    x[::13], x[1::17] = 0.0, -0.0
    y = np.abs(rng.normal(size=x.size)) * 10 ** rng.uniform(-300, 300, x.size)
    got = _elementwise(x, y)
    k = np.arange(x.size) % _N
    i = np.arange(0, x.size, _N)
    codes = np.stack([i % 3, np.ones_like(i), i % 5, np.full_like(i, 2)], 1).ravel()
    no = np.zeros(i.size, bool)
    roots = np.stack([i % 3 == 1, no, i % 5 == 1, no], 1).ravel()
    want = [x + y, x - y, x * 0.7, np.sqrt(y), np.where(x > 0, y, -1.0),
            np.where(x >= 0, 2.0, y), np.where(k == 2, x, y), np.where(codes == 2, x, y),
            np.where(roots, np.sqrt(y), x)]
    assert 0 < roots.sum() < x.size / 2
    for row, ref in zip(got, want):
        assert np.array_equal(row, ref)
    assert _N == 4     # the writing of vwhere_equal's codes above


@numba.njit
def _scattered(t, stride):
    a = np.zeros(3 + stride * _N)
    vmath.vscatter(a, 3, stride, t)
    return a, vmath.vtuple(vmath.vgather(a, 3, stride))


def test_scatter_and_gather_put_and_take_each_element_at_its_stride():
    a, back = _scattered((1.0, 2.0, 3.0, 4.0), 5)
    assert list(a[3::5]) == [1.0, 2.0, 3.0, 4.0] and a.sum() == 10.0
    assert back == (1.0, 2.0, 3.0, 4.0)


@numba.njit
def _masks(x, y, ints):
    """The mask operations over x, y by VECTOR elements: bit masks spread to rows of 0/1."""
    n = x.size
    out = np.zeros((9, n))
    sel = np.empty((3, n))
    for i in range(0, n, _N):
        a, b = vmath.vload(x, i), vmath.vload(y, i)
        masks = (vmath.vlt_bits(a, b), vmath.vle_bits(a, b), vmath.vgt_bits(a, b),
                 vmath.vge_bits(a, b), vmath.veq_bits(a, b), vmath.vnan_bits(a),
                 vmath.vle_bits(a, 0.0), vmath.ieq_bits(ints, i, 2),
                 vmath.ilt_bits(ints, i, n + i))
        for row in range(len(masks)):
            for k in range(_N):
                out[row, i + k] = masks[row] >> k & 1
        vmath.vstore(sel[0], i, vmath.vselect_bits(masks[0], a, b))
        vmath.vstore(sel[1], i, vmath.vabs(a))
        vmath.vstore(sel[2], i, vmath.vdiv(a, b))
    return out, sel


def test_masks_are_pythons_comparisons_element_by_element():
    rng = np.random.default_rng(7)
    n = 4096
    x = rng.normal(size=n)
    y = np.where(rng.random(n) < 0.2, x, rng.normal(size=n))     # some equal pairs
    x[::11], y[3::13], x[5::17] = np.nan, np.nan, -0.0
    ints = rng.integers(0, 4, 2 * n)
    got, sel = _masks(x, y, ints)
    with np.errstate(invalid="ignore", divide="ignore"):
        want = [x < y, x <= y, x > y, x >= y, x == y, np.isnan(x), x <= 0.0,
                ints[:n] == 2, ints[:n] < ints[n:]]
        quotient = x / y
    for row, ref in zip(got, want):
        assert 0 < ref.sum() < n
        assert np.array_equal(row, ref)
    assert np.array_equal(sel[0], np.where(x < y, x, y), equal_nan=True)
    assert np.array_equal(np.signbit(sel[1]), np.zeros(n, bool))
    assert np.array_equal(sel[1], np.abs(x), equal_nan=True)
    assert np.array_equal(sel[2], quotient, equal_nan=True)
