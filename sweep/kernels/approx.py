"""The report's closed-form approximations of the coefficient of restitution (Sections 4-5).

Every method maps the scaled parameters ``(alpha, beta, gamma, g~)`` (all "1") to an
approximate CoR ``e`` in [0, 1]:

``"ord1"``
    First order, small g~ (22): ``e = 1 - gamma C0 - gamma g~ C1``, clipped at 0 (it never
    exceeds 1).
``"sp"``
    Schwager-Poeschel second order (25), (30): ``e = 1 - gamma C0 - gamma g~ C1 - gamma^2 C2``
    with ``C2 = -(9/4) 0.7982665553``; only for Kuwabara-Kono, ``alpha = beta = 3/2`` exactly
    (elsewhere NaN and status INVALID). Clipped to [0, 1]: since ``C2 < 0`` the gamma^2 term
    pushes e above 1 at gamma of order 1.
``"large_gtilde"``
    Large g~ (23): ``e = sqrt(max(1 - 2 gamma C g~^r, 0))``, in [0, 1] by construction.
``"ord2_numint"``, ``"ord2_approx"``
    Second order with g~-dependent coefficients, Prop. 2, (36)-(38)::

        e^2 = 1 - 2 b I gamma + 2 b^2 I Q gamma^2
        e_s = max(1 - b I gamma + b^2 I (Q - I/2) gamma^2, 0)
        e   = min(sqrt(max(e^2, 0)), e_s)

    with ``I(g~)``, ``Q(g~)`` by quadrature (:func:`sweep.kernels.special.iq_quadrature`, ~1e-15) or
    by the report's Chebyshev-Beta approximation of order ``n`` (Prop. 3-4, (43)-(53),
    :func:`sweep.kernels.special.iq_chebyshev`). Clipped at 1: both e^2 and e_s exceed 1 once the
    gamma^2 term wins (gamma of order 1, outside the expansion's range; SPEC section 7).

All methods return status ``Status.OK`` for valid points; points with alpha < 1, beta < 1,
gamma < 0, g~ < 0, a non-finite value, or outside the method's domain (``"sp"`` away from
KK; ``"ord2_*"`` at g~ so large that ``theta`` of (43) underflows or I overflows: beyond
~1e60 for alpha = 1, beta = 4, ~1e100 for KK) get ``e = NaN`` and ``Status.INVALID``.

The kernels are compiled lazily (first call) without fastmath, so NaN checks work and
results are bit-identical whatever the number of threads or the chunking.
"""
from __future__ import annotations

import math
import operator

import numba as nb
import numpy as np

from sweep._arrays import PARAMETER_RULES, Broadcast
from sweep.kernels._jit import kernel_cache
from sweep.kernels._parallel import parallel_allowed
from sweep.model import Status
from sweep.kernels.special import (CHEBYSHEV_N_MAX, chebyshev_tables, first_order_constants,
                                   iq_at_zero, iq_chebyshev, iq_quadrature,
                                   large_gtilde_constants)

__all__ = ["METHODS", "SP_C2", "approx_cor", "coefficients", "coefficients_at_zero",
           "first_order_coefficients", "large_gtilde_coefficient", "parallel_allowed"]

#: Methods of :func:`approx_cor`, in the order of their integer codes in the kernel.
METHODS = ("ord1", "sp", "large_gtilde", "ord2_numint", "ord2_approx")

#: Schwager-Poeschel's second-order coefficient for KK at g~ = 0, (30): -(9/4) c2.
SP_C2 = -(9.0 / 4.0) * 0.7982665553

# Kernel codes: the public methods, then internal ones that fill (aux1, aux2).
_ORD1, _SP, _LARGE, _ORD2_NUMINT, _ORD2_APPROX = range(5)
_COEF_NUMINT = 5     # I, Q by quadrature
_COEF_APPROX = 6     # I, Q by Chebyshev-Beta
_CONST_FIRST = 7     # C0, C1 (22)
_CONST_LARGE = 8     # C, r (23)
_COEF_ZERO = 9       # I(0), Q(0) (39), (40)


def _jit(**options):
    """``numba.njit(cache=True, **options)``, caching under the package's source-hash directory.

    The dispatcher is created inside :func:`sweep.kernels._jit.kernel_cache`: this module is imported
    lazily (after ``sweep/__init__`` has left that context), and numba's own cache key would
    only check this file, not the functions of :mod:`sweep.kernels.special` compiled into the kernels.
    """
    def wrap(fn):
        with kernel_cache():
            return nb.njit(cache=True, **options)(fn)
    return wrap


_OK = np.int8(Status.OK)
_INVALID = np.int8(Status.INVALID)
_CHUNK = 1024
_DEFAULT_N = 21


@_jit()
def _clip01(x):
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@_jit()
def _sqrt_plus(x):
    """``sqrt(max(x, 0))`` that keeps NaN."""
    if x > 0.0:
        return math.sqrt(x)
    if x <= 0.0:
        return 0.0
    return math.nan


@_jit()
def _ord2(beta, gamma, i_, q_):
    """Prop. 2, (36)-(38), clipped to [0, 1] (NaN passes through)."""
    bi = beta * i_ * gamma
    e2 = 1.0 - 2.0 * bi + 2.0 * bi * beta * q_ * gamma
    es = 1.0 - bi + bi * beta * (q_ - 0.5 * i_) * gamma
    if es < 0.0:
        es = 0.0
    ep = _sqrt_plus(e2)
    if ep != ep or es != es:
        return math.nan
    return _clip01(min(ep, es))


@_jit()
def _run_range(code, start, stop, alpha, beta, gamma, gtilde, n, e, status, aux1, aux2):
    """Evaluate points ``start .. stop-1`` serially (one chunk of the parallel kernel).

    Constants that depend on (alpha, beta) only are recomputed when the exponents change
    from one point to the next, so uniform-exponent sweeps pay for them once per chunk; the
    values are the same either way.
    """
    store_aux = aux1.size > 0     # approx_cor passes empty aux arrays: no I, Q wanted
    uses_cheb = code == _ORD2_APPROX or code == _COEF_APPROX
    n_tab = n if uses_cheb else 1
    logx, cosjk = chebyshev_tables(n_tab)
    work = np.empty((5, n_tab + 1))
    prev_a = math.nan
    prev_b = math.nan
    k1 = math.nan
    k2 = math.nan
    for i in range(start, stop):
        a = alpha[i]
        b = beta[i]
        g = gamma[i]
        gt = gtilde[i]
        ok = (a >= 1.0 and b >= 1.0 and g >= 0.0 and gt >= 0.0 and math.isfinite(a)
              and math.isfinite(b) and math.isfinite(g) and math.isfinite(gt))
        if code == _SP:
            ok = ok and a == 1.5 and b == 1.5
        if not ok:
            e[i] = math.nan
            status[i] = _INVALID
            if store_aux:
                aux1[i] = math.nan
                aux2[i] = math.nan
            continue
        if a != prev_a or b != prev_b:
            if code == _ORD1 or code == _SP or code == _CONST_FIRST:
                k1, k2 = first_order_constants(a, b)
            elif code == _LARGE or code == _CONST_LARGE:
                k1, k2 = large_gtilde_constants(a, b)
            elif code == _COEF_ZERO:
                k1, k2 = iq_at_zero(a, b)
            prev_a = a
            prev_b = b
        ev = math.nan
        x1 = math.nan
        x2 = math.nan
        if code == _ORD1:
            ev = 1.0 - g * (k1 + gt * k2)
            if ev < 0.0:
                ev = 0.0
        elif code == _SP:
            ev = _clip01(1.0 - g * (k1 + gt * k2) - g * g * SP_C2)
        elif code == _LARGE:
            ev = _sqrt_plus(1.0 - 2.0 * g * k1 * gt ** k2)
        elif code == _ORD2_NUMINT or code == _COEF_NUMINT:
            x1, x2 = iq_quadrature(a, b, gt)
        elif code == _ORD2_APPROX or code == _COEF_APPROX:
            x1, x2 = iq_chebyshev(a, b, gt, n, logx, cosjk, work)
        else:       # _CONST_FIRST, _CONST_LARGE, _COEF_ZERO
            x1 = k1
            x2 = k2
        if code == _ORD2_NUMINT or code == _ORD2_APPROX:
            if math.isfinite(x1) and math.isfinite(x2):
                ev = _ord2(b, g, x1, x2)
            good = math.isfinite(ev)
        elif code >= _COEF_NUMINT:
            good = math.isfinite(x1) and math.isfinite(x2)
        else:
            good = math.isfinite(ev)
        e[i] = ev if good else math.nan
        status[i] = _OK if good else _INVALID
        if store_aux:
            aux1[i] = x1 if good else math.nan
            aux2[i] = x2 if good else math.nan


@_jit(parallel=True)
def _kernel_parallel(code, alpha, beta, gamma, gtilde, n, e, status, aux1, aux2):
    size = alpha.size
    nchunks = (size + _CHUNK - 1) // _CHUNK
    for c in nb.prange(nchunks):
        _run_range(code, c * _CHUNK, min(size, (c + 1) * _CHUNK), alpha, beta, gamma, gtilde,
                   n, e, status, aux1, aux2)


@_jit()
def _kernel_serial(code, alpha, beta, gamma, gtilde, n, e, status, aux1, aux2):
    _run_range(code, 0, alpha.size, alpha, beta, gamma, gtilde, n, e, status, aux1, aux2)


def _check_n(n):
    what = f"n must be an odd integer in [1, {CHEBYSHEV_N_MAX}], got {n!r}"
    try:
        ni = operator.index(n)
    except TypeError:
        raise ValueError(what) from None
    # Beyond CHEBYSHEV_N_MAX the kernel's quadrature table is too coarse (it returns NaN).
    if isinstance(n, bool) or ni < 1 or ni % 2 == 0 or ni > CHEBYSHEV_N_MAX:
        raise ValueError(what)
    return int(ni)


def _run(code, alpha, beta, gamma, gtilde, n, aux=True):
    size = alpha.size
    e = np.empty(size)
    status = np.empty(size, dtype=np.int8)
    aux1 = np.empty(size if aux else 0)
    aux2 = np.empty(size if aux else 0)
    kernel = _kernel_parallel if (size > _CHUNK and parallel_allowed()) else _kernel_serial
    kernel(code, alpha, beta, gamma, gtilde, n, e, status, aux1, aux2)
    return e, status, aux1, aux2


def approx_cor(method, alpha, beta, gamma, gtilde, n=_DEFAULT_N):
    """Approximate coefficient of restitution by one of the report's closed forms.

    Parameters
    ----------
    method : str
        One of :data:`METHODS` (see the module docstring).
    alpha, beta, gamma, gtilde : ndarray
        1-D float64 arrays of equal length (already broadcast): exponents [1] (>= 1),
        scaled damping gamma [1] (>= 0) and load g~ [1] (>= 0) of (2).
    n : int, default 21
        Odd order of the Chebyshev-Beta approximation (49), used by ``"ord2_approx"``; at
        most ``CHEBYSHEV_N_MAX`` (621).

    Returns
    -------
    e : ndarray of float64
        Approximate CoR [1] in [0, 1]; NaN at invalid points.
    status : ndarray of int8
        ``Status.OK`` or ``Status.INVALID``.

    Raises
    ------
    ValueError
        Unknown method, n not an odd integer in [1, CHEBYSHEV_N_MAX] (621), or arrays of
        different shapes.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    n = _check_n(n)
    arrays = [np.ascontiguousarray(x, dtype=np.float64) for x in (alpha, beta, gamma, gtilde)]
    if any(x.ndim != 1 for x in arrays) or len({x.size for x in arrays}) != 1:
        raise ValueError("alpha, beta, gamma, gtilde must be 1-D arrays of equal length, got "
                         f"shapes {[x.shape for x in arrays]}")
    e, status, _, _ = _run(METHODS.index(method), *arrays, n, aux=False)
    return e, status


def _pair(code, names, values, n=_DEFAULT_N):
    """Broadcast, validate a scalar call, run a constants/coefficients code."""
    b = Broadcast(names, values)
    b.raise_if_invalid(PARAMETER_RULES)
    alpha, beta = b.flat[0], b.flat[1]
    gtilde = b.flat[2] if len(b.flat) > 2 else np.zeros_like(alpha)
    _, status, x1, x2 = _run(code, alpha, beta, np.zeros_like(alpha), gtilde, n)
    if b.scalar and status[0] != Status.OK:
        raise ValueError(f"gtilde is out of the range of I, Q (theta of (43) underflows), "
                         f"got {float(gtilde[0])!r}")
    return b.restore(x1), b.restore(x2)


def coefficients(alpha, beta, gtilde, method="numint", n=_DEFAULT_N):
    """The g~-dependent coefficients ``I(g~)``, ``Q(g~)`` of Prop. 2 [1].

    ::

        I = 2 int_0^{u_M} [1 + 2(g~ u - u^(a+1)/(a+1))]^(+1/2) u^(b-1) du
        Q =   int_0^{u_M} [1 + 2(g~ u - u^(a+1)/(a+1))]^(-1/2) u^(b-1) du

    (Prop. 2's I, twice the one of Sec. 4.1.)

    Parameters
    ----------
    alpha, beta, gtilde : array_like
        Exponents [1] (>= 1) and scaled load [1] (>= 0), broadcast together.
    method : {"numint", "approx"}
        Gauss quadrature (relative error ~1e-15) or the report's Chebyshev-Beta
        approximation (47)-(53) of odd order ``n`` (~1e-3).
    n : int, default 21

    Returns
    -------
    I, Q : ndarray or float
        NaN at invalid points of an array call; a scalar call with an invalid value raises
        ``ValueError`` naming it.
    """
    routes = {"numint": _COEF_NUMINT, "approx": _COEF_APPROX}
    if method not in routes:
        raise ValueError(f"method must be one of {tuple(routes)}, got {method!r}")
    return _pair(routes[method], ("alpha", "beta", "gtilde"), (alpha, beta, gtilde),
                 _check_n(n))


def coefficients_at_zero(alpha, beta):
    """Exact ``I(0)``, ``Q(0)`` [1] of (39), (40) (KK: 1.1534489, 1.2687937)."""
    return _pair(_COEF_ZERO, ("alpha", "beta"), (alpha, beta))


def first_order_coefficients(alpha, beta):
    """``C0``, ``C1`` [1] of the first-order approximation (22) (KK: 1.7301733, 3).

    ``C0 = b ((a+1)/2)^((b-a-1)/(a+1)) B(b/(a+1), 3/2)`` and
    ``C1 = b ((a+1)/2)^((b-a)/(a+1)) B((b+1)/(a+1), 1/2)``; broadcast over alpha, beta.
    """
    return _pair(_CONST_FIRST, ("alpha", "beta"), (alpha, beta))


def large_gtilde_coefficient(alpha, beta):
    """``C`` and the exponent ``r`` [1] of the large-g~ approximation (23), (24).

    ``e^2 = 1 - 2 gamma C g~^r`` with ``r = b/a + 1/(2a) + 1/2`` and
    ``C = 2 sqrt(2) (b/a) (a+1)^(b/a + 1/(2a)) B((b + 1/2)/a, 3/2)`` (KK: 4.403986, 11/6).
    """
    return _pair(_CONST_LARGE, ("alpha", "beta"), (alpha, beta))
