"""Event location on a step's dense output (the interpolant), before refinement.

Events of Algorithm 1 are zeros of ``u - c`` (c = u-bar or 0) or of the velocity
``v = w - gamma u_+^beta``. They are bracketed by sign tests, located here on the step's
4th-order interpolant by the Illinois variant of regula falsi, and then refined by the
integrator with full Runge-Kutta steps from the step's start (:mod:`sweep.kernels.integrator`).

Owns: event functions and their location on the interpolant. May import: contact, stepper.
"""
from __future__ import annotations

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.contact import velocity
from sweep.kernels.stepper import N_DENSE, dense_eval

__all__ = ["ON_U", "ON_V", "event_value", "locate"]

ON_U = 0
ON_V = 1
_EPS = float(np.finfo(np.float64).eps)


@jit(inline="always")
def event_value(which, target, u, w, c):
    """``u - target`` (``which == ON_U``) or the velocity v (``ON_V``) of the law ``c``."""
    if which == ON_U:
        return u - target
    return velocity(u, w, c)


@jit(inline="always")
def _rounding(which, target, u0, w0, Q):
    """Bound on the rounding of the event function on the interpolant: twice eps times the
    sum of the magnitudes it is formed from (for v = w - gamma u^beta near v = 0, the
    damper's term is about w itself)."""
    if which == ON_U:
        scale = abs(u0) + abs(target)
        for j in range(N_DENSE):
            scale += abs(Q[0, j])
    else:
        scale = abs(w0)
        for j in range(N_DENSE):
            scale += abs(Q[1, j])
        scale *= 2.0
    return 2.0 * _EPS * scale


@jit(counted=False)
def locate(which, target, u0, w0, Q, c, ta, tb):
    """Fraction ``theta`` in ``[ta, tb]`` of the step where the event function vanishes.

    The event function must change sign over ``[ta, tb]``; if roundoff hides the change the
    end ``tb`` is returned (the caller's sign test at the step end found the event there).
    """
    u, w = dense_eval(u0, w0, Q, ta)
    fa = event_value(which, target, u, w, c)
    u, w = dense_eval(u0, w0, Q, tb)
    fb = event_value(which, target, u, w, c)
    if fb == 0.0:
        return tb
    if fa == 0.0:
        return ta
    if (fa > 0.0) == (fb > 0.0):
        return tb
    noise = _rounding(which, target, u0, w0, Q)
    a, b = ta, tb
    for _ in range(200):
        x = b - fb * (b - a) / (fb - fa)
        if not (min(a, b) < x < max(a, b)):
            x = 0.5 * (a + b)
        u, w = dense_eval(u0, w0, Q, x)
        fx = event_value(which, target, u, w, c)
        if abs(fx) <= noise:
            # Its sign is rounding: the iterations after this one only swung about the root.
            return x
        if (fx > 0.0) != (fb > 0.0):
            a, fa = b, fb
        else:
            # Illinois: halve the stale end's weight so the bracket shrinks from both sides.
            fa *= 0.5
        b, fb = x, fx
        if abs(b - a) <= 4e-16:
            break
    return b
