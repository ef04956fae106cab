"""One explicit Runge-Kutta step of the report's system (4) and its dense output.

The system in the Lipschitz form of Sec. 3 (state ``(u, w)``, velocity ``v = w - gamma u_+^beta``)::

    u' = w - gamma u_+^beta        w' = g~ - u_+^alpha

The stage loop is written once against the tableau arrays of :mod:`sweep.tableau` (module
constants, which numba folds into the compiled code); step-size choice and event logic live
elsewhere.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from sweep.tableau import DORMAND_PRINCE_54

__all__ = ["power_kind", "ppow", "rhs", "rk_step", "dense_coefficients", "dense_eval",
           "N_STAGES", "N_DENSE"]

_T = DORMAND_PRINCE_54
_A = np.ascontiguousarray(_T.A)
_B = np.ascontiguousarray(_T.B)
_P = np.ascontiguousarray(_T.P)
N_STAGES = _A.shape[0]
N_DENSE = _P.shape[1]

# Exponents of the report's models get a pow-free evaluation: pow() dominates the cost of a
# stage, and sqrt is exact-rounded and several times cheaper.
_KIND_ONE, _KIND_THREE_HALVES, _KIND_TWO, _KIND_FIVE_HALVES, _KIND_FIVE_FOURTHS, _KIND_THREE = range(6)
_KIND_GENERAL = 9


@nb.njit
def power_kind(p):
    """Code selecting the evaluation of ``x**p`` in :func:`ppow`."""
    if p == 1.0:
        return _KIND_ONE
    if p == 1.5:
        return _KIND_THREE_HALVES
    if p == 2.0:
        return _KIND_TWO
    if p == 2.5:
        return _KIND_FIVE_HALVES
    if p == 1.25:
        return _KIND_FIVE_FOURTHS
    if p == 3.0:
        return _KIND_THREE
    return _KIND_GENERAL


@nb.njit(inline="always")
def ppow(x, p, kind):
    """``max(x, 0)**p`` for ``p >= 1`` (the report's ``x_+^p``)."""
    if x <= 0.0:
        return 0.0
    if kind == _KIND_ONE:
        return x
    if kind == _KIND_THREE_HALVES:
        return x * math.sqrt(x)
    if kind == _KIND_TWO:
        return x * x
    if kind == _KIND_FIVE_HALVES:
        return x * x * math.sqrt(x)
    if kind == _KIND_FIVE_FOURTHS:
        return x * math.sqrt(math.sqrt(x))
    if kind == _KIND_THREE:
        return x * x * x
    return x ** p


@nb.njit(inline="always")
def rhs(u, w, alpha, beta, gamma, gtilde, ka, kb):
    """Right-hand side of (4): returns ``(u', w')``."""
    pa = ppow(u, alpha, ka)
    # Equal exponents (linear, Kuwabara-Kono) share the one power: it is most of a stage's cost.
    pb = pa if alpha == beta else ppow(u, beta, kb)
    return w - gamma * pb, gtilde - pa


@nb.njit
def rk_step(u, w, h, K, alpha, beta, gamma, gtilde, ka, kb):
    """Advance ``(u, w)`` by one step ``h``.

    ``K[0]`` must hold ``f(u, w)`` on entry (first-same-as-last); on exit ``K`` holds all
    stages, ``K[-1] = f(u_new, w_new)`` for the FSAL tableau.
    """
    for i in range(1, N_STAGES):
        du = 0.0
        dw = 0.0
        for j in range(i):
            a = _A[i, j]
            du += a * K[j, 0]
            dw += a * K[j, 1]
        fu, fw = rhs(u + h * du, w + h * dw, alpha, beta, gamma, gtilde, ka, kb)
        K[i, 0] = fu
        K[i, 1] = fw
    du = 0.0
    dw = 0.0
    for j in range(N_STAGES):
        du += _B[j] * K[j, 0]
        dw += _B[j] * K[j, 1]
    return u + h * du, w + h * dw


@nb.njit
def dense_coefficients(K, h, Q):
    """Fill ``Q[c, j] = h * sum_i K[i, c] P[i, j]`` (polynomial coefficients of the step)."""
    for c in range(2):
        for j in range(N_DENSE):
            s = 0.0
            for i in range(N_STAGES):
                s += K[i, c] * _P[i, j]
            Q[c, j] = h * s


@nb.njit(inline="always")
def dense_eval(u0, w0, Q, theta):
    """State at fraction ``theta`` of the step: ``y0 + sum_j Q[:, j] theta^(j+1)``."""
    u = 0.0
    w = 0.0
    for j in range(N_DENSE - 1, -1, -1):
        u = (u + Q[0, j]) * theta
        w = (w + Q[1, j]) * theta
    return u0 + u, w0 + w
