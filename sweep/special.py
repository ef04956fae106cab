"""Jitted special functions: Beta function, roots and quadrature used by the kernels."""
from __future__ import annotations

import math

import numba as nb

__all__ = ["umax_undamped"]


@nb.njit(cache=False, inline="always")
def umax_undamped(alpha, gtilde):
    """Undamped maximum compression ``u_M(g~)``, root of (13): ``u^(a+1)/(a+1) - g~ u = 1/2``.

    Newton's method from an upper bound converges monotonically (the left side is convex in
    u and increasing past the root), so a fixed number of iterations gives full precision.
    """
    ap1 = alpha + 1.0
    u0 = (0.5 * ap1) ** (1.0 / ap1)
    if gtilde <= 0.0:
        return u0
    # Upper bound: the root of u^(a+1)/(a+1) = 1/2 + g~ u is below u0 + (ap1 g~)^(1/a).
    u = u0 + (ap1 * gtilde) ** (1.0 / alpha)
    for _ in range(100):
        ua = u ** alpha
        f = u * ua / ap1 - gtilde * u - 0.5
        df = ua - gtilde
        du = f / df
        u_new = u - du
        if not (u_new < u):  # monotone decrease stalls at the root
            break
        u = u_new
    return u
