"""One explicit Runge-Kutta step of the report's system (4) and its dense output.

The system in the Lipschitz form of Sec. 3 (state ``(u, w)``, velocity ``v = w - gamma u_+^beta``)::

    u' = w - gamma u_+^beta        w' = g~ - u_+^alpha

The stage loop is written once against the tableau arrays of :mod:`sweep.kernels.tableau` (module
constants, which numba folds into the compiled code); step-size choice and event logic live
elsewhere.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from sweep.kernels.tableau import DORMAND_PRINCE_54

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
(_KIND_ONE, _KIND_THREE_HALVES, _KIND_TWO, _KIND_FIVE_HALVES, _KIND_FIVE_FOURTHS, _KIND_THREE,
 _KIND_ZERO, _KIND_HALF, _KIND_QUARTER) = range(9)
_KIND_GENERAL = 99


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
    if p == 0.0:
        return _KIND_ZERO
    if p == 0.5:
        return _KIND_HALF
    if p == 0.25:
        return _KIND_QUARTER
    return _KIND_GENERAL


@nb.njit(inline="always")
def ppow(x, p, kind):
    """``x**p`` for ``x > 0``, and 0 for ``x <= 0`` (the report's ``x_+^p``; also for p = 0,
    where it is the indicator of contact, closed at x = 0: the bead is in contact from its
    first instant, so the damper acts at tau = 0)."""
    if kind == _KIND_ZERO:
        return 1.0 if x >= 0.0 else 0.0
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
    if kind == _KIND_HALF:
        return math.sqrt(x)
    if kind == _KIND_QUARTER:
        return math.sqrt(math.sqrt(x))
    return x ** p


@nb.njit(inline="always")
def rhs(u, w, alpha, beta, gamma, gtilde, ka, kd):
    """Right-hand side of (4) and of the dissipation integral: returns ``(u', w', r')``.

    The energy dissipated by the damper is ``q = int gamma beta u^(beta-1) v^2 dtau``; by
    parts (``beta u^(beta-1) v = d(u^beta)/dtau``) ``q = gamma v u_+^beta + r`` with
    ``r' = -gamma u_+^beta v'``, ``v' = g~ - u_+^alpha - gamma beta u_+^(beta-1) v``. The
    integrand of r has only powers >= 1 of u, as smooth at u = 0 as the rest of (4), where
    that of q (``u^(beta-1)``, e.g. ``u^(1/4)`` for TTI) would cost the method its order.
    Carrying r gives the CoR from the energy balance ``e^2 = 1 - 2 q(T_f) = 1 - 2 r(T_f)``
    (exactly 1 without damping), far better conditioned than ``e = -w`` after a swing
    through a deep load well. ``kd`` is the :func:`power_kind` of ``beta - 1``.
    """
    pd = ppow(u, beta - 1.0, kd)
    pb = u * pd if u > 0.0 else 0.0
    # Equal exponents (linear, Kuwabara-Kono) share the one power: it is most of a stage's cost.
    pa = pb if alpha == beta else ppow(u, alpha, ka)
    v = w - gamma * pb
    return v, gtilde - pa, -gamma * pb * (gtilde - pa - gamma * beta * pd * v)


@nb.njit
def rk_step(u, w, r, h, K, alpha, beta, gamma, gtilde, ka, kd):
    """Advance ``(u, w, r)`` by one step ``h``.

    ``K[0]`` must hold ``f(u, w)`` on entry (first-same-as-last); on exit ``K`` holds all
    stages, ``K[-1] = f(u_new, w_new)`` for the FSAL tableau.
    """
    for i in range(1, N_STAGES):
        du = 0.0
        dw = 0.0
        dq = 0.0
        for j in range(i):
            a = _A[i, j]
            du += a * K[j, 0]
            dw += a * K[j, 1]
            dq += a * K[j, 2]
        fu, fw, fq = rhs(u + h * du, w + h * dw, alpha, beta, gamma, gtilde, ka, kd)
        K[i, 0] = fu
        K[i, 1] = fw
        K[i, 2] = fq
    du = 0.0
    dw = 0.0
    dq = 0.0
    for j in range(N_STAGES):
        b = _B[j]
        du += b * K[j, 0]
        dw += b * K[j, 1]
        dq += b * K[j, 2]
    return u + h * du, w + h * dw, r + h * dq


@nb.njit
def dense_coefficients(K, h, Q):
    """Fill ``Q[c, j] = h * sum_i K[i, c] P[i, j]`` for c = u, w (the events need no q)."""
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
