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

    with ``I(g~)``, ``Q(g~)`` by quadrature (:func:`sweep.kernels.special.iq_quadrature`,
    ~1e-14) or
    by the report's Chebyshev-Beta approximation of order ``n`` (Prop. 3-4, (43)-(53),
    :func:`sweep.kernels.special.iq_chebyshev`). Clipped at 1: both e^2 and e_s exceed 1 once the
    gamma^2 term wins (gamma of order 1, outside the expansion's range; SPEC section 7).

All methods return status ``Status.OK`` for valid points; points with alpha < 1, beta < 1,
gamma < 0, g~ < 0, a non-finite value, or outside the method's domain (``"sp"`` away from
KK; ``"ord2_*"`` at g~ so large that ``theta`` of (43) underflows or I overflows: beyond
~1e61 for alpha = 1, beta = 4, ~1e149 for the linear law, ~1e167 for KK) get ``e = NaN``
and ``Status.INVALID``.

Checked against an independent mpmath implementation of the report's formulas (2026-12-07):
within 1e-14 relative for alpha, beta in [1, 10], gamma 1e-8..10, g~ = 0 or 1e-6..1e6, n
= 1..619. Past alpha, beta ~ 10 no accuracy is claimed: the quadrature of I, Q and the
Chebyshev-Beta moments lose digits (relative 1e-11 at alpha = 20, 1e-5 at alpha = 200),
``"ord2_*"`` give NaN from alpha + beta ~ 310, and C0, C (22)-(23) overflow to NaN at
beta / alpha in the thousands.

The kernels are compiled lazily (first call) with no fastmath flag but contraction into
fused multiply-adds (:data:`sweep.kernels._jit.FLAGS`), so NaN checks work and results are
bit-identical whatever the number of threads or the chunking.

Owns: the closed-form kernels over flat arrays. May import: registry, the other kernels.
"""
from __future__ import annotations

import math

import numpy as np

from sweep.kernels._jit import cached_jit, jit
from sweep.kernels._parallel import map_blocks, parallel_allowed, schedule, threads
from sweep.kernels.contact import in_domain
from sweep.kernels.special import (chebyshev_tables, first_order_constants, iq_at_zero,
                                   iq_chebyshev, iq_quadrature, large_gtilde_constants)
from sweep.registry import METHODS, Status

__all__ = ["SP_C2", "approx_cor", "ord1", "sp", "large_gtilde", "ord2_numint", "ord2_approx",
           "coefficient_arrays", "CODES"]

#: Kernel codes of the closed forms (the methods of :data:`sweep.registry.METHODS`).
CODES = {"ord1": 0, "sp": 1, "large_gtilde": 2, "ord2_numint": 3, "ord2_approx": 4}

#: Schwager-Poeschel's second-order coefficient for KK at g~ = 0, (30): -(9/4) c2.
SP_C2 = -(9.0 / 4.0) * 0.7982665553

# Kernel codes: the public methods, then internal ones that fill (aux1, aux2).
_ORD1, _SP, _LARGE, _ORD2_NUMINT, _ORD2_APPROX = range(5)
_COEF_NUMINT = 5     # I, Q by quadrature
_COEF_APPROX = 6     # I, Q by Chebyshev-Beta
_CONST_FIRST = 7     # C0, C1 (22)
_CONST_LARGE = 8     # C, r (23)
_COEF_ZERO = 9       # I(0), Q(0) (39), (40)


_OK = np.int8(Status.OK)
_INVALID = np.int8(Status.INVALID)
#: Smallest chunk of a parallel call, against ~20 us of Python for a chunk's call: the
#: first-order forms cost 3-30 ns a point (65,536 points: 0.2-2 ms) where the exponents
#: stay, ~100 ns where they vary, the second-order ones 1-4 us (quadrature or Chebyshev-Beta
#: sums per point; 1,024 points: 1-4 ms). With one size for all, a 65,536-point chunk of a
#: sweep ran its second-order forms on one core.
_CHUNK = 1 << 16
_CHUNK_COSTLY = 1 << 10
_COSTLY = (_ORD2_NUMINT, _ORD2_APPROX, _COEF_NUMINT, _COEF_APPROX)
#: Points sampled to judge whether the exponents vary (:func:`_exponents_vary`): a
#: scattered design's first-order forms ran on one core (0.10 s of ord1 a million Sobol
#: points, on one core or two, 2026-12-05).
_SAMPLES = 16
#: Chunks per thread (a few, for balance where costs vary: ord2_numint by g~).
_CHUNKS_PER_THREAD = 4
_DEFAULT_N = 21


@jit()
def _clip01(x):
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@jit()
def _sqrt_plus(x):
    """``sqrt(max(x, 0))`` that keeps NaN."""
    if x > 0.0:
        return math.sqrt(x)
    if x <= 0.0:
        return 0.0
    return math.nan


@jit()
def _ord2(beta, gamma, i_, q_):
    """Prop. 2, (36)-(38), clipped to [0, 1] (NaN passes through)."""
    bi = beta * i_ * gamma
    e2 = 1.0 - 2.0 * bi + 2.0 * bi * beta * q_ * gamma
    es = 1.0 - bi + bi * beta * (q_ - 0.5 * i_) * gamma
    if es < 0.0:
        # e = min(sqrt(e^2), e_s) = 0 whatever e^2, which may be inf - inf where the gamma
        # terms overflow (gamma ~ 1e300: NaN before, where the formula gives 0).
        return 0.0
    ep = _sqrt_plus(e2)
    if ep != ep or es != es:
        return math.nan
    return _clip01(min(ep, es))


@jit(inline="always")
def _constants(code, a, b):
    """The constants of the exponents ``(a, b)`` that ``code`` uses (NaN for the others):
    (22)'s ``(C0, C1)``, (23)'s ``(C, r)`` or ``(I(0), Q(0))`` of (39), (40)."""
    if code == _ORD1 or code == _SP or code == _CONST_FIRST:
        return first_order_constants(a, b)
    if code == _LARGE or code == _CONST_LARGE:
        return large_gtilde_constants(a, b)
    if code == _COEF_ZERO:
        return iq_at_zero(a, b)
    return math.nan, math.nan


@jit(inline="always")
def _large_term(g, gt, c, r):
    """``2 gamma C g~^r`` of (23). Where ``g~^r`` alone overflows the product need not
    (a tiny gamma: it gave e = 0 with status OK where (23) gives 1 - 1.5e-13; gamma = 0
    gave 0 inf = NaN): there, and only there, in logarithms."""
    p = gt ** r
    if p < math.inf:
        return 2.0 * g * c * p
    if g == 0.0:
        return 0.0
    return math.exp(math.log(2.0 * g * c) + r * math.log(gt))


@jit(inline="always")
def _evaluate(code, b, g, gt, k1, k2, x1, x2):
    """``(e, good)`` of one valid point: e of the method (NaN for the coefficient codes)
    and whether the point's outputs are finite."""
    ev = math.nan
    # (22)'s gamma g~ C1 where g~ C1 alone overflows: gamma g~ first, there and only there
    # (a subnormal gamma gave e = 0 with status OK where (22) gives 0.97, gamma = 0 NaN).
    # The common path keeps its one expression, which LLVM fuses into multiply-adds.
    if code == _ORD1:
        ev = 1.0 - g * (k1 + gt * k2)
        if not ev > -math.inf:
            ev = 1.0 - (g * k1 + (g * gt) * k2)
        if ev < 0.0:
            ev = 0.0
    elif code == _SP:
        ev = 1.0 - g * (k1 + gt * k2) - g * g * SP_C2
        if not ev > -math.inf:
            # g (g C2), not g g C2: a product shared with the common path would not be fused
            ev = 1.0 - (g * k1 + (g * gt) * k2) - g * (g * SP_C2)
        ev = _clip01(ev)
    elif code == _LARGE:
        ev = _sqrt_plus(1.0 - _large_term(g, gt, k1, k2))
    elif code == _ORD2_NUMINT or code == _ORD2_APPROX:
        if math.isfinite(x1) and math.isfinite(x2):
            ev = _ord2(b, g, x1, x2)
    if code >= _COEF_NUMINT:
        return ev, math.isfinite(x1) and math.isfinite(x2)
    return ev, math.isfinite(ev)


@cached_jit()
def _kernel(code, alpha, beta, gamma, gtilde, n, e, status, aux1, aux2):
    """Evaluate every point serially; ``nogil``, so that
    :func:`sweep.kernels._parallel.map_blocks` runs chunks of them at once.

    Constants that depend on (alpha, beta) only are recomputed when the exponents change
    from one point to the next, so uniform-exponent sweeps pay for them once per chunk; the
    values are the same either way.
    """
    store_aux = aux1.size > 0     # approx_cor passes empty aux arrays: no I, Q wanted
    n_tab = n if code == _ORD2_APPROX or code == _COEF_APPROX else 1
    logx, cosjk = chebyshev_tables(n_tab)
    work = np.empty((5, n_tab + 1))
    prev_a = prev_b = k1 = k2 = math.nan
    for i in range(alpha.size):
        a, b, g, gt = alpha[i], beta[i], gamma[i], gtilde[i]
        if not in_domain(a, b, g, gt):
            e[i] = math.nan
            status[i] = _INVALID
            if store_aux:
                aux1[i] = aux2[i] = math.nan
            continue
        if a != prev_a or b != prev_b:
            k1, k2 = _constants(code, a, b)
            prev_a, prev_b = a, b
        # Here, not in a helper: an array passed to an inlined function has its reference
        # count updated at every point (atomics: 5x the time of "ord1").
        x1 = x2 = math.nan
        if code == _ORD2_NUMINT or code == _COEF_NUMINT:
            x1, x2 = iq_quadrature(a, b, gt)
        elif code == _ORD2_APPROX or code == _COEF_APPROX:
            x1, x2 = iq_chebyshev(a, b, gt, n, logx, cosjk, work)
        elif code >= _CONST_FIRST:
            x1, x2 = k1, k2
        ev, good = _evaluate(code, b, g, gt, k1, k2, x1, x2)
        e[i] = ev if good else math.nan
        status[i] = _OK if good else _INVALID
        if store_aux:
            aux1[i] = x1 if good else math.nan
            aux2[i] = x2 if good else math.nan


def _exponents_vary(alpha, beta):
    """Whether the exponents seem to change along the arrays (judged on
    :data:`_SAMPLES` points spread over them): the first-order forms then recompute their
    constants (Beta functions) at most points, ~100 ns each, and cost like the second-order
    ones. Only the chunking depends on it, never a value."""
    if alpha.size < 2:
        return False
    at = np.linspace(0, alpha.size - 1, min(_SAMPLES, alpha.size)).astype(np.intp)
    return bool(np.any(alpha[at] != alpha[0]) or np.any(beta[at] != beta[0]))


def _run(code, alpha, beta, gamma, gtilde, n, aux=True):
    size = alpha.size
    e = np.empty(size)
    status = np.empty(size, dtype=np.int8)
    aux1 = np.empty(size if aux else 0)
    aux2 = np.empty(size if aux else 0)

    def run(lo, hi):
        a1, a2 = (aux1[lo:hi], aux2[lo:hi]) if aux else (aux1, aux2)
        _kernel(code, alpha[lo:hi], beta[lo:hi], gamma[lo:hi], gtilde[lo:hi], n, e[lo:hi],
                status[lo:hi], a1, a2)

    costly = code in _COSTLY or _exponents_vary(alpha, beta)
    chunks = min(_CHUNKS_PER_THREAD * threads(), size // (_CHUNK_COSTLY if costly else _CHUNK))
    if chunks > 1 and parallel_allowed():
        per = -(-size // chunks)
        map_blocks(run, schedule(size, per, _CHUNK_COSTLY if costly else _CHUNK))
    else:
        run(0, size)
    return e, status, aux1, aux2


def approx_cor(method, alpha, beta, gamma, gtilde, n=_DEFAULT_N):
    """Approximate coefficient of restitution by one of the report's closed forms.

    Parameters
    ----------
    method : str
        A key of :data:`CODES` (see the module docstring).
    alpha, beta, gamma, gtilde : ndarray
        1-D float64 arrays of equal length (already broadcast): exponents [1] (>= 1),
        scaled damping gamma [1] (>= 0) and load g~ [1] (>= 0) of (2).
    n : int, default 21
        Odd order of the Chebyshev-Beta approximation (49), used by ``"ord2_approx"``; at
        most :data:`sweep.registry.CHEBYSHEV_N_MAX`.

    Returns
    -------
    e : ndarray of float64
        Approximate CoR [1] in [0, 1]; NaN at invalid points.
    status : ndarray of int8
        ``Status.OK`` or ``Status.INVALID``.

    Raises
    ------
    ValueError
        Unknown method, n outside the rule of :data:`sweep.registry.CHEBYSHEV_N_MAX`, or
        arrays of different shapes.

    The exponents where a method is defined at all (``"sp"``: Kuwabara-Kono only) are the
    registry's fact (:attr:`sweep.registry.Method.models`), applied by the caller.
    """
    if method not in CODES:
        raise ValueError(f"method must be one of {tuple(CODES)}, got {method!r}")
    n = METHODS["ord2_approx"].check_options({"n": n})["n"]
    arrays = [np.ascontiguousarray(x, dtype=np.float64) for x in (alpha, beta, gamma, gtilde)]
    if any(x.ndim != 1 for x in arrays) or len({x.size for x in arrays}) != 1:
        raise ValueError("alpha, beta, gamma, gtilde must be 1-D arrays of equal length, got "
                         f"shapes {[x.shape for x in arrays]}")
    e, status, _, _ = _run(CODES[method], *arrays, n, aux=False)
    return e, status


def ord1(alpha, beta, gamma, gtilde):
    """Kernel of ``"ord1"``, eq. (22), over flat arrays: ``(e, status)``."""
    return approx_cor("ord1", alpha, beta, gamma, gtilde)


def sp(alpha, beta, gamma, gtilde):
    """Kernel of ``"sp"``, eqs. (25), (30), over flat arrays: ``(e, status)``."""
    return approx_cor("sp", alpha, beta, gamma, gtilde)


def large_gtilde(alpha, beta, gamma, gtilde):
    """Kernel of ``"large_gtilde"``, eq. (23), over flat arrays: ``(e, status)``."""
    return approx_cor("large_gtilde", alpha, beta, gamma, gtilde)


def ord2_numint(alpha, beta, gamma, gtilde):
    """Kernel of ``"ord2_numint"``, Prop. 2 with I, Q by quadrature: ``(e, status)``."""
    return approx_cor("ord2_numint", alpha, beta, gamma, gtilde)


def ord2_approx(alpha, beta, gamma, gtilde, n=_DEFAULT_N):
    """Kernel of ``"ord2_approx"``, Prop. 2 with Chebyshev-Beta I, Q of order n: ``(e, status)``."""
    return approx_cor("ord2_approx", alpha, beta, gamma, gtilde, n)


#: Codes of :func:`coefficient_arrays`.
_COEFFICIENTS = {"numint": _COEF_NUMINT, "approx": _COEF_APPROX, "first": _CONST_FIRST,
                 "large": _CONST_LARGE, "zero": _COEF_ZERO}


def coefficient_arrays(which, alpha, beta, gtilde, n=_DEFAULT_N):
    """Coefficient pairs over flat float64 arrays: ``(x1, x2, status)``.

    ``which``: ``"numint"`` / ``"approx"`` -- I, Q of Prop. 2 (quadrature or Chebyshev-Beta);
    ``"first"`` -- C0, C1 of (22); ``"large"`` -- C, r of (23); ``"zero"`` -- I(0), Q(0) of
    (39), (40). NaN and ``Status.INVALID`` where undefined.
    """
    _, status, x1, x2 = _run(_COEFFICIENTS[which], alpha, beta, np.zeros_like(alpha), gtilde, n)
    return x1, x2, status
