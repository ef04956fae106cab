"""Step-size policy: a fixed step per point, graded geometrically near the non-smooth point u = 0.

Base step
---------
Each point gets one step ``h = pi / (steps * lambda)`` where ``lambda`` is the fastest rate of
the contact at the undamped maximum compression ``u_M`` (root of (13), an upper bound of the
damped compression)::

    lambda = max( sqrt(alpha u_M^(alpha-1)),  gamma beta u_M^(beta-1) )

i.e. the larger of the linearised elastic frequency and the linearised damping rate there.
``pi / lambda`` is the half period of the stiffest linear oscillation the impact can see, so
``steps`` is the number of steps per half period ("steps per impact" for the linear
spring-dashpot, where the contact lasts pi): one knob for the resolution. Because
``h lambda <= pi / steps``, heavy damping never leaves the stability region of the explicit
method.

Grading near u = 0
------------------
The contact force ``u_+^alpha`` (and ``u_+^beta``) is not smooth where the bead touches the
floor (u = 0) when an exponent is not an integer: the solution carries terms in
``|tau - tau_0|^(alpha+1)``, and a plain step across them loses the method's order (error
~ h^(alpha+1)). Both ends of the impact sit on that point. Within ``d = u / |v|`` of it (the
time to reach u = 0 at the current speed), steps are cut to ``rho d`` -- a geometric mesh
graded towards the singular point -- but not below ``first * h``, the size of the step that
starts (or ends) exactly on u = 0.
"""
from __future__ import annotations

import math

import numba as nb

from sweep.special import umax_undamped

__all__ = ["GRADE_RATIO", "GRADE_FIRST", "base_step", "needs_grading", "graded_step"]

#: Ratio of step to distance from u = 0 inside the graded zone.
GRADE_RATIO = 0.25
#: Smallest graded step as a fraction of the base step.
GRADE_FIRST = 0.01


@nb.njit(inline="always")
def base_step(alpha, beta, gamma, gtilde, steps):
    """Base step ``h = pi / (steps * lambda)`` (module docstring)."""
    um = umax_undamped(alpha, gtilde)
    elastic = math.sqrt(alpha * um ** (alpha - 1.0))
    damping = gamma * beta * um ** (beta - 1.0)
    # Under a large load the bead swings through a potential well of depth
    # |V(u-bar)| = g~ u-bar alpha/(alpha+1) and e^2/2 is what is left of it: absolute errors
    # in e scale with the depth, so the step shrinks like its fifth root (method order 5).
    depth = gtilde * gtilde ** (1.0 / alpha) * alpha / (alpha + 1.0) if gtilde > 0.0 else 0.0
    return math.pi / (steps * max(elastic, damping) * (1.0 + 2.0 * depth) ** 0.2)


@nb.njit(inline="always")
def needs_grading(alpha, beta):
    """True unless both exponents are integers (then u_+^p is a polynomial for u >= 0)."""
    return alpha != math.floor(alpha) or beta != math.floor(beta)


@nb.njit(inline="always")
def graded_step(u, v, h, rho, s_min):
    """Step for state ``(u, v)``: ``h`` away from u = 0, ``rho u/|v|`` (>= s_min) near it."""
    av = abs(v)
    if rho * u >= h * av:
        return h
    s = rho * u / av
    return s if s > s_min else s_min
