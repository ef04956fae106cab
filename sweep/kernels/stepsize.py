"""Step-size policy: a fixed step per point, graded geometrically near the non-smooth point u = 0.

Base step
---------
Each point gets one step ``h = pi / (steps * omega_M * D)``: ``omega_M = sqrt(alpha
u_M^(alpha-1))`` is the linearised elastic frequency at the undamped maximum compression
``u_M`` (root of (13), an upper bound of the damped one), so ``steps`` counts steps per half
period of the stiffest elastic oscillation the impact can see (steps per impact for the
linear spring-dashpot, whose contact lasts pi). ``D = min((1 + 2|V(u-bar)|)^(1/9), 16)``
accounts for large loads: the bead swings through a potential well of depth
``|V(u-bar)| = g~ u-bar alpha/(alpha+1)`` at speeds up to ``sqrt(1 + 2|V(u-bar)|)``, and the
state's errors, relative to that swing, come back in e (the speed that is left) scaled by
it: a power 1/10 of ``1 + 2|V|`` would follow that scale with the method's order 5. With
1/9 the median error of the first march stays at 0.008-0.011 of tol in every g~ bin from
0 to 10 on the Sobol design (tol 1e-6 .. 1e-10; 1/8 let it fall to 0.0065-0.0076 at
g~ in [3, 10], 1/10 let it rise to 0.009-0.011 there); the 1/5 used before 2026-12-05
over-resolved deep wells (0.009 falling to 0.002), and cost that design 12-16% more steps
(docs/speed/history.md, 2026-12-05). 1/10 would save more on the Sobol design (4.4% fewer
steps than 1/8 at tol 1e-8, against 2.6% for 1/9) but costs the linear law 1.1% at tol
1e-6 in refinements. The cap 16 is where roundoff in the state (which grows with the depth
too) would win.

Damping cap
-----------
Where damping is stiffer than elasticity the step is also capped by the local damping rate,
``s <= pi / (steps * gamma beta u^(beta-1))``: heavy damping then never leaves the explicit
method's stability region, while the cap follows the bead's actual compression (far below
``u_M`` when damping is heavy) instead of a worst case. Points whose damping rate at ``u_M``
stays below ``omega_M D`` never need the cap and skip its cost.

Grading near u = 0
------------------
The contact force ``u_+^alpha`` (and ``u_+^beta``) is not smooth where the bead touches the
floor (u = 0) when an exponent is not an integer: the solution carries terms in
``|tau - tau_0|^(alpha+1)``, and a plain step across them loses the method's order (error
~ h^(alpha+1)). Both ends of the impact sit on that point. Within ``d = u / |v|`` of it (the
time to reach u = 0 at the current speed), steps are cut to ``rho d`` -- a geometric mesh
graded towards the singular point -- but not below ``first * h``, the size of the step that
starts (or ends) exactly on u = 0. Both rho and first are proportional to h (see
:func:`grading`), so the graded zone's error falls like ``h^5`` and the method keeps its
order 5 (tests/test_convergence.py).

That grading is set for the singular exponent ``p = 3/2`` (KK, Hertz). A larger p needs
less (:func:`graded_by_exponent`): a step s at u = 0 errs like ``s^(p+1)`` and the graded
zone like ``rho^(5-p) h^(p+1)``, so rho and first are widened to keep the error of
``p = 3/2`` at the same h. The damping's term counts at beta whatever gamma: the
dissipation integral that gives e errs by its relative error (:func:`singular_exponent`).
Never finer than the grading of ``p = 3/2``; points whose
damping cap can bind, and creeping beads (:func:`local_policy`), keep :func:`grading`.

Share of a tolerance's resolution
---------------------------------
With a tolerance the integrator marches each point first at ``resolution(tol)`` times a
share of it (:func:`tol_share`): the march's error of e is about proportional to the
energy dissipated q, the damping's integrand being graded at u = 0
(:func:`singular_exponent`; :mod:`sweep.kernels.balance`), so a nearly elastic bounce meets
the error model's bound at a coarser resolution. q is predicted before the march from the
report's first-order constants (:func:`predicted_q`). A bead predicted to dissipate at
least twice its energy (:data:`Q_STICK`) is first marched at the integrator's floor: a
stick's e is exactly 0 once the energy rule certifies it, at any resolution, so that
march need only certify it; where it leaves e_err above tol (the prediction was wrong, or
the stick is too close to call) the point is marched at its share as any other.

Owns: the step-size rule. May import: registry, contact, special.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from sweep import registry
from sweep.kernels._jit import jit
from sweep.kernels.contact import (damping_rate, damping_ratio, elastic_frequency,
                                   equilibrium, umax_undamped, well_depth_at)
from sweep.kernels.special import first_order_constants, large_gtilde_constants

__all__ = ["GRADE_RATIO", "GRADE_FIRST", "GRADE_STEPS", "GRADE_EXPONENT",
           "MAX_DEPTH_FACTOR", "DEPTH_POWER", "NEWTON_FLOOR", "LOCAL_ALPHA", "base_step",
           "damping_limited", "damping_step", "grading", "singular_exponent",
           "graded_by_exponent", "needs_grading", "graded_step",
           "StepPolicy", "policy", "policy_at", "local_policy", "first_guess", "uncapped",
           "uncapped_guess", "resolution", "ERROR_AT_GRADE_STEPS", "q_constants",
           "predicted_q", "tol_share", "Q_REF", "P_MIN", "Q_STICK", "GAMMA_CALLABLE",
           "EPS_CALLABLE"]

#: Ratio of step to distance from u = 0 inside the graded zone, at ``GRADE_STEPS``.
GRADE_RATIO = 0.25
#: Smallest graded step as a fraction of the base step, at ``GRADE_STEPS``.
GRADE_FIRST = 0.01
#: Resolution at which the two above apply; both scale like 1/steps around it.
GRADE_STEPS = 96.0
#: Cap of ``first`` at coarse resolutions (it binds below 19.2 steps: tol above 1.6e-7).
FIRST_CAP = 0.05
#: Singular exponent the grading above is set for (KK, Hertz: alpha = 3/2).
GRADE_EXPONENT = 1.5
#: Caps of rho and first widened for a larger exponent (:func:`graded_by_exponent`).
MAX_RATIO = 1.0
MAX_FIRST = 0.25


@jit(inline="always")
def grading(steps):
    """``(rho, first)`` for a resolution: both proportional to the base step.

    The graded zone's error grows like ``(rho h)^(alpha+1)`` and the first step's like
    ``(first h)^(alpha+1)``; with rho and first proportional to h both fall like ``h^5``
    with the uniform steps' error, so the method keeps its order and a coarse resolution
    does not pay for a fine grading. Capped at coarse resolutions, where the proportional
    values would let the graded zone's error jump about.
    """
    scale = GRADE_STEPS / steps
    return min(GRADE_RATIO * scale, 0.5), min(GRADE_FIRST * scale, FIRST_CAP)


@jit(inline="always")
def singular_exponent(c):
    """Exponent p of the weakest non-smooth term of the law ``c`` at u = 0 (a step s
    across it errs like ``s^(p+1)``): alpha, or beta where the damping's term is less smooth
    (gamma > 0); inf where both terms are smooth. Where alpha is at most
    :data:`GRADE_EXPONENT`, alpha: the grading is then :func:`grading`'s whatever beta.

    beta counts at its own exponent, not weakened by a small gamma (as ``beta + ln(gamma)
    / ln(s_1)`` until 2026-12-05): the path hardly feels the term, but the dissipation
    integral q that gives e errs by its relative error whatever gamma, and e's error is
    about proportional to q only where that integrand is resolved (docs/accuracy.md,
    section 2). Graded for beta, the general-exponent draw took 16% fewer steps at tol
    1e-8 (22% at 1e-10) and the Sobol design 8% (9%): both shares of the error estimate and
    of the resolution then apply to every point (docs/speed/history.md, 2026-12-05)."""
    p = c.alpha if c.alpha != math.floor(c.alpha) else math.inf
    if p > GRADE_EXPONENT and c.beta < p and c.beta != math.floor(c.beta) and c.gamma > 0.0:
        p = c.beta
    return p


@jit(inline="always")
def graded_by_exponent(c, steps):
    """``(rho, first)`` of the law ``c``: :func:`grading`, widened for a singular exponent
    p above :data:`GRADE_EXPONENT` so that the first step's error ``(first h)^(p+1)`` and
    the graded zone's ``rho^(5-p) h^(p+1)`` stay those of p = 3/2 (h relative to the half
    period). p is taken at most 4, where a plain step's error ``h^(p+1)`` is already the
    uniform steps' ``h^5`` (and the rule's ``1 / (5 - p)`` would blow up).

    Measured (benchmarks/tol_margin.py's draws and the Sobol design, against steps=500,
    tol=1e-12; docs/speed/history.md, 2026-12-05): 4.1% fewer steps on the Sobol design at
    tol 1e-8 (4.7% at 1e-6, 3.7% at 1e-10), 5.2-6.4% on the general-exponent draw, with
    the same error quantiles per alpha, beta and gamma bin, the same largest errors and
    decisions; laws of p <= 3/2 (KK, TTI, Hertz, linear) are unchanged. Grading finer by
    the same rule below p = 3/2 cut the refinement at tol 1e-10 but saved only 3.3% at
    1e-8; rho capped at 0.5 instead of 1 saved 2.7%."""
    rho, first = grading(steps)
    x = math.pi / steps
    p = min(singular_exponent(c), 4.0)
    if p <= GRADE_EXPONENT:
        return rho, first
    f = (first * x) ** ((GRADE_EXPONENT + 1.0) / (p + 1.0)) / x
    r = (rho ** (5.0 - GRADE_EXPONENT) * x ** (GRADE_EXPONENT - p)) ** (1.0 / (5.0 - p))
    # The first step stays within grading()'s longest (at MIN_STEPS), the one the events'
    # Newton is tested with (tests/test_events.py): 0.154 h at 8 steps left the detachment
    # time 4,900 ulps off the re-step's root for (2.5, 1, 0.3, 0.3).
    first_max = min(MAX_FIRST, FIRST_CAP * steps / MIN_STEPS)
    return min(max(r, rho), MAX_RATIO), min(max(f, first), first_max)


#: Cap of the load factor D (beyond it roundoff in the state dominates).
MAX_DEPTH_FACTOR = 16.0
#: Power of ``1 + 2|V(u-bar)|`` in the load factor D (module docstring). Until the damping
#: cap's floor (:data:`NEWTON_FLOOR`, 2026-12-05) points whose cap can bind kept 1/5: their
#: steps grew steeply as the base step coarsened (g~ = 1e4, gamma = 1e12: 1,605 steps at tol
#: 1e-8 with 1/5, 7,076 with 1/8; now 5 either way). 1/9 rather than 1/8 (2026-12-05,
#: against steps=500, tol=1e-12): 1.9 / 2.6 / 2.6% fewer steps, refinement included, on a
#: 65,536-point Sobol design at tol 1e-6 / 1e-8 / 1e-10, 0.1-0.6% fewer on the KK, TTI and
#: general draws of benchmarks/tol_margin.py, linear +0.4% at 1e-6 and -0.3 to -0.4% at the
#: others; the same largest errors (unrefined and final) and decisions; hard cases 0.4% fewer.
#: 1/10 saved 4.4% on the Sobol design but cost linear 1.1% at tol 1e-6.
DEPTH_POWER = 1.0 / 9.0


@jit(inline="always")
def _depth_factor(ubar, alpha, gtilde):
    return min((1.0 + 2.0 * well_depth_at(ubar, alpha, gtilde)) ** DEPTH_POWER,
               MAX_DEPTH_FACTOR)


@jit(inline="always")
def base_step(omega, depth, steps):
    """Base step ``h = pi / (steps * omega_M * D)`` (module docstring) for the elastic
    frequency ``omega`` at u_M and the load factor ``depth`` (D)."""
    return math.pi / (steps * omega * depth)


@jit(inline="always")
def damping_limited(c, um, omega, depth):
    """Whether the damping cap can bind: damping rate at u_M above ``omega_M D``."""
    return damping_rate(um, c) > omega * depth


@jit(inline="always")
def damping_step(u, c, steps):
    """Cap ``pi / (steps * gamma beta u^(beta-1))`` (inf where the rate vanishes)."""
    rate = damping_rate(u, c)
    return math.pi / (steps * rate) if rate > 0.0 else math.inf


@jit(inline="always")
def needs_grading(alpha, beta):
    """True unless both exponents are integers (then u_+^p is a polynomial for u >= 0)."""
    return alpha != math.floor(alpha) or beta != math.floor(beta)


@jit(inline="always")
def graded_step(u, v, h, rho, s_min):
    """Step for state ``(u, v)``: ``h`` away from u = 0, ``rho u/|v|`` (>= s_min) near it.
    (The multi-point driver sizes its lanes' steps by the same operations as vectors:
    ``lanes._guessed_group``.)"""
    # The quotient formed before the tests: its choice against s_min compiles to a max, not
    # a branch waiting on the division (+1-2% when the lanes still sized their steps one
    # by one, docs/speed/history.md). The test against h stays a branch, well predicted.
    av = abs(v)
    s = rho * u / av
    graded = s if s > s_min else s_min
    return h if rho * u >= h * av else graded


#: Error model of the resolution: the abs error of e of one march, over all points but
#: those at the stick/rebound boundary (where refinement takes over), is
#: ``ERROR_AT_GRADE_STEPS`` at ``GRADE_STEPS`` and falls like ``steps^-5``. Set on the
#: 99.9% quantile of the core benchmark's draws (``python benchmarks/error_model.py``,
#: 20,000 points a law, steps 16 to 96): KK and Hertz within 1.15 times the model, TTI
#: 1.3, SHC and general exponents 1.8, the linear law 3.1 (at 16 steps; 1.9 from 48 on).
#: Since the depth factor's power 1/9 (2026-12-05), which lets deep wells' errors up to the
#: shallow points': KK and Hertz 1.45-1.5, TTI 1.7, SHC and general 2.15, linear 3.6 at 16
#: steps; 1.3-1.7 (linear 2.2-2.7) at 33 and 96 (with 1/8: 1.45, 1.6, 2.1, 3.6; 1.2-1.7,
#: linear 2.0-2.5). The largest errors (up to 21 times the model) are the boundary's.
ERROR_AT_GRADE_STEPS = 5e-11
#: Resolutions the error model may choose (the least is the registry's, the least a caller
#: may give).
MIN_STEPS = float(registry.MIN_STEPS)
MAX_STEPS = 1024.0


def resolution(tol: float) -> float:
    """Steps per half period for a largest abs error ``tol`` of e (error model above).

    Plain Python: it runs once per call, before the kernels (jitted, it cost a 0.7 s compile
    in every process that gave a ``tol``)."""
    steps = GRADE_STEPS * (ERROR_AT_GRADE_STEPS / tol) ** 0.2
    return min(max(steps, MIN_STEPS), MAX_STEPS)


#: Predicted dissipated energy q from which a tolerance's first march takes the whole
#: resolution (:func:`tol_share`). On 20,000-point KK, TTI, linear and general draws
#: (benchmarks/tol_margin.py's, tol 1e-8 / 1e-10, against steps=500, tol=1e-12), 0.2 saved
#: 21 / 27% of the steps of KK and TTI, 22 / 26% of linear, 4 / 5% of general, with the same
#: refined fractions and the same largest errors as one resolution for all; 0.25 saved 1-2%
#: more of KK, TTI and linear but only 3 / 1.5% of general (refined 4.9 / 9.4% against
#: 2.9 / 3.3%) and let the largest linear error rise from 0.31 to 0.36 tol; 0.15 and 0.1
#: saved less (KK 19 / 25%, 17 / 22%); 0.4 sent a sixth to half the points to refinement
#: (KK +6% at 1e-10, linear +10 / +18%). docs/speed/history.md, 2026-12-05. Again with
#: the grading by beta (:func:`singular_exponent`): 0.25 saved 1.5 / 2.3% more of KK and
#: 1.2 / 1.3% of the Sobol design, but cost general 1.0% at 1e-10 and let the largest
#: linear error left unrefined rise from 0.31 to 0.37 of tol; at 0.3, 39-59% of the linear
#: draw was refined.
Q_REF = 0.2
#: Smallest share: 0.2, 0.3 and 0.4 took within 1.5% of each other's steps at tol 1e-10,
#: the one of tol 1e-6, 1e-8, 1e-10 where it binds above the integrator's floor of 16 steps.
P_MIN = 0.3
#: q below which ``(q / Q_REF)^(1/5)`` is surely below P_MIN (a margin far above pow's
#: rounding): :func:`tol_share` takes P_MIN there without the root.
_Q_FLOOR = Q_REF * P_MIN ** 5 * (1.0 - 1e-9)
#: Predicted q (:func:`predicted_q`) from which a point is first marched at the integrator's
#: floor (``sweep.kernels.balance.COARSE_STEPS``), a probe of a stick, where the prediction
#: can call one (:func:`_callable`): q is at most 1/2 for a bead that leaves, and a
#: prediction of 1 or more was a stick on 99.7% of the Sobol design's 32,457 such points. A
#: probe whose e_err is above tol (the 95 that left, with e up to 0.50; sticks too close to
#: call) is followed by the march at the point's share, as without the probe, and refined
#: from there (refined from the probe itself, Richardson across ratios up to 21 left e_err
#: at 3e-9 on grazing points at tol 1e-10). Steps against the share alone at tol 1e-8 /
#: 1e-10 (docs/accuracy.md, section 2): KK -4.2 / -7.9%, general -4.6 / -8.5%, the Sobol
#: design -15.9 / -27.6%, heavily damped KK -42 / -67%, the hard cases +2.4 / +0.6%; the
#: same largest errors and decisions. Measured with probes refined from directly: 2 saved
#: less everywhere (Sobol -13 / -23%); 0.7 saved 0.8% more of the Sobol design at 1e-8 but
#: cost the draws 1.5-4.5% at 1e-10; 0.5 saved less. A floor of 8 steps for the probes would
#: save 7% more of the Sobol design; not taken: a settled stick's u_max is read off its
#: probe (docs/accuracy.md, section 5), and 16 steps keep it within the envelope the nearly
#: elastic points' share already has.
Q_STICK = 1.0
#: Damping up to which the first-order prediction calls a stick (:func:`_callable`).
GAMMA_CALLABLE = 1.0
#: Beyond GAMMA_CALLABLE, the largest ``eps(u-bar) = u-bar^kappa / (gamma beta)^2`` at which
#: a predicted stick is probed (:func:`_callable`; docs/creep.md's eps, small where the bead
#: is locally overdamped: ``eps = 1 / (4 alpha zeta^2)``). Measured at tol 1e-8 against an
#: overdamped u-bar (zeta >= 1, eps <= 1/(4 alpha)), on the heavily damped draws (gamma =
#: 10^U(0, 2), g~ = 10^U(-3, 1), 20,000 points) and the hard cases: 4 saved 23.5% of the
#: SHC draw's steps, 15.5% of general exponents', 6.1% of KK's, for 2.0% more on the hard
#: cases (1, the inner scale of docs/creep.md: 13.8, 12.6, 8.3% for 1.5%; zeta >= 0.25 or
#: 0.1 whatever alpha: 21, 15, 6.3% for 1.5% and 19, 14, 6.1% for 4.1%; every predicted
#: stick probed: 14, 9.6, 6.1% for 8.5%).
EPS_CALLABLE = 4.0


@jit(inline="always")
def _callable(c):
    """Whether the prediction of q may call a stick of the law ``c``: gamma up to
    :data:`GAMMA_CALLABLE`, or, under a load, a bead that creeps into the well while still
    about overdamped there (``eps(u-bar)`` at most :data:`EPS_CALLABLE`), and stays.
    Beyond, at g~ ~ 0, a heavily damped bead creeps back and leaves with a small e
    (docs/creep.md) while q to first order in gamma is far above 1: probing the hard cases'
    creeping beads cost them 8.5% more steps at tol 1e-8."""
    if c.gamma <= GAMMA_CALLABLE:
        return True
    if not c.gtilde > 0.0:
        return False
    # eps(u-bar) = 1 / (4 alpha zeta^2), zeta the damping ratio about u-bar.
    zeta = damping_ratio(c.alpha, c.beta, c.gamma, c.gtilde)
    return 4.0 * c.alpha * EPS_CALLABLE * zeta * zeta >= 1.0


# Called, not inlined: its one compiled copy gives every caller (the array kernel, one
# point's solve, the CUDA kernel) the same bits.
@jit()
def q_constants(alpha, beta):
    """``(C0, C1, C, r)`` of the exponents ``(alpha, beta)`` for :func:`predicted_q`: (22)'s
    and (23)'s constants (:func:`sweep.kernels.special.first_order_constants`,
    :func:`sweep.kernels.special.large_gtilde_constants`; 0.12 us, six lgamma, so the
    array kernel computes them once for consecutive points of the same exponents)."""
    c0, c1 = first_order_constants(alpha, beta)
    cl, r = large_gtilde_constants(alpha, beta)
    return c0, c1, cl, r


@jit(inline="always")
def predicted_q(c, k):
    """The energy q = (1 - e^2)/2 a bead of the law ``c`` dissipates, predicted to first
    order in gamma: ``gamma (C0 + C1 g~ + C g~^r)``, the small-g~ (22) and large-g~ (23)
    forms of the report summed, ``k`` the exponents' :func:`q_constants`.

    Where it gives a share below 1 (q < Q_REF; against steps=500, tol=1e-12), never below
    the true q on 20,000-point KK, TTI, Hertz and linear draws (ratio 1.00 at least, median
    1.04-1.07, at most 1.26-1.43), at least 0.93 of it
    for SHC, 0.63 on the general draw (1% below 0.75) and 0.60 on the 65,536-point Sobol
    design (1% below 0.72): where the two forms meet (g~ ~ 1) the sum overstates q, which
    only costs steps. Either form alone, or their maximum, understated the KK draw's q up
    to 10, 1e3 and 1.6 times."""
    c0, c1, cl, r = k
    return c.gamma * (c0 + c1 * c.gtilde + cl * c.gtilde ** r)


# Called, not inlined: once per point (compile time).
@jit()
def tol_share(c, k):
    """``(p, stick)``: the share ``p`` of ``resolution(tol)`` for the first march of the law
    ``c`` with a tolerance, ``clip((q / Q_REF)^(1/5), P_MIN, 1)`` for the q predicted with
    the constants ``k`` (:func:`predicted_q`), 1 where the prediction is not finite; and
    whether that q says the bead sticks (:data:`Q_STICK`), so that a march at the
    integrator's floor may settle it first. The march's error falls like ``steps^-5`` and
    is about proportional to q (module docstring)."""
    q = predicted_q(c, k)
    stick = q >= Q_STICK and _callable(c)
    if not q < Q_REF:       # NaN and inf included
        return 1.0, stick
    # Below _Q_FLOOR the root is below P_MIN whatever its rounding: no pow (a fifth of the
    # KK draw's points).
    return (max((q / Q_REF) ** 0.2, P_MIN) if q > _Q_FLOOR else P_MIN), stick


class StepPolicy(NamedTuple):
    """The step-size rule of one point (module docstring)."""

    h: float          # base step
    rho: float        # grading ratio near u = 0
    s_min: float      # smallest graded step
    steps: float      # resolution, for the damping cap
    graded: bool      # an exponent is not an integer: grade near u = 0
    capped: bool      # the damping cap can bind
    local: bool       # the base step follows the local elastic frequency (creep)
    omega: float      # the elastic frequency the base step h was set for (at u_M)


@jit(inline="always")
def policy(c, steps):
    """The :class:`StepPolicy` of the point with contact law ``c`` at resolution ``steps``."""
    return policy_at(c, steps, equilibrium(c.alpha, c.gtilde),
                     umax_undamped(c.alpha, c.gtilde, c.ka))


# Called, not inlined: once per march (compile time).
@jit()
def policy_at(c, steps, ubar, um):
    """:func:`policy` given ``ubar`` and ``um``, the law's
    :func:`~sweep.kernels.contact.equilibrium` and
    :func:`~sweep.kernels.contact.umax_undamped`: the lanes share the one with their creep
    constants and take the other for all their points at once
    (:func:`~sweep.kernels.contact.umax_undamped_many`)."""
    omega = elastic_frequency(c.alpha, um)
    depth = _depth_factor(ubar, c.alpha, c.gtilde)
    h = base_step(omega, depth, steps)
    capped = damping_limited(c, um, omega, depth)
    # Points whose damping cap can bind keep grading(): widened, the creep hard case
    # (4.72, 4.44, 18.3, 1e-6) ran into the step budget (tests/test_hard_cases.py).
    rho, first = grading(steps) if capped else graded_by_exponent(c, steps)
    return StepPolicy(h, rho, first * h, steps, needs_grading(c.alpha, c.beta), capped,
                      False, omega)


#: Largest alpha whose creep keeps :func:`grading`'s rho (:func:`local_policy`).
LOCAL_ALPHA = 3.0


@jit(inline="always")
def local_policy(p, alpha):
    """``p`` with a base step that follows the local elastic frequency
    ``sqrt(alpha u^(alpha-1))`` instead of the one at u_M, and the damping cap on: for a
    creeping bead (:mod:`sweep.kernels.march`), whose time scale ``u^((1-alpha)/2)`` grows
    as u falls (below a creep jump it can be thousands of times the impact's; docs/creep.md,
    section 7). The smallest graded step follows the same scale. The grading is
    :func:`grading`'s, not the one widened for the impact's ends: a creep's steps are
    ``rho u / |v|`` all the way down (widened there, before the points whose damping cap
    can bind kept :func:`grading` too, rho = 1 ran 40 points of a wide draw, alpha and
    beta up to 6, gamma near 1, g~ ~ 0.003, into the step budget).

    Above :data:`LOCAL_ALPHA`, rho shrinks like ``(LOCAL_ALPHA - 1) / (alpha - 1)``: a step
    moves the time scale by ``(alpha - 1) / 2`` times u's relative change, and where that
    outgrew alpha = 3's the embedded estimates lost track of the error. An audit found e
    with status OK off by up to 10.7 e_err and 4 tol (alpha 5-10, kappa ~ -1, g~ ~ 0, e ~
    0.04-0.15, ``tol=1e-8``); now at most 0.72 e_err on that draw, with 13-33% fewer steps
    at ``tol`` (fewer refinements) and 1% more at a fixed resolution
    (docs/accuracy.md). At alpha <= 3 (every calibration draw) bit for bit as before."""
    if p.local:
        return p
    rho, first = grading(p.steps)
    if alpha > LOCAL_ALPHA:
        rho *= (LOCAL_ALPHA - 1.0) / (alpha - 1.0)
    return StepPolicy(p.h, rho, first * p.h, p.steps, p.graded, True, True, p.omega)


@jit(inline="always")
def _base(u, p, c):
    """Base step and smallest graded step at compression u."""
    if not p.local:
        return p.h, p.s_min
    scale = p.omega / elastic_frequency(c.alpha, max(u, 1e-300))
    return p.h * scale, p.s_min * scale


#: Least fraction of Newton's step towards the damping cap's fixed point that
#: :func:`_capped_step` moves to (:func:`_towards_cap`).
NEWTON_FLOOR = 0.25


# Called, not inlined: only points whose damping cap can bind come here (compile time).
@jit()
def _capped_step(u, v, s, p, c):
    """The largest step up to s within the damping cap judged where the step may take the
    bead (speed and load push it deeper, to ``u(s) = u + s v+ + s^2 g~/2``): the fixed point
    of ``s = cap(u(s))``, approached by geometric means (the cap falls as s grows), but
    never to below a fraction of it (:func:`_towards_cap`)."""
    vp = max(v, 0.0)
    for _ in range(4):
        reach = u + s * vp + 0.5 * s * s * c.gtilde
        cap = damping_step(reach, c, p.steps)
        if cap >= s:
            return s
        # d log u(s) / d log s; reach > 0 unless beta = 1 (a cap that u does not move).
        carried = s * (vp + s * c.gtilde) / reach if reach > 0.0 else 0.0
        s = _towards_cap(s, cap, 1.0 + (c.beta - 1.0) * carried)
    return min(s, damping_step(u + s * vp + 0.5 * s * s * c.gtilde, c, p.steps))


@jit(inline="always")
def _towards_cap(s, cap, m):
    """The next step after s, whose cap ``cap < s`` falls like ``s^-(m-1)`` there: the
    geometric mean of s and cap, or :data:`NEWTON_FLOOR` times Newton's step
    ``s (cap / s)^(1/m)`` if that is larger.

    The geometric mean is Newton's step for a cap falling like 1/s (m = 2). Where it falls
    faster it lands below the fixed point, and far below where the load carries the bead
    (m up to 2 beta - 1; the coarser the resolution, the further above it s starts):
    (1, 5, 1e12, 1e4) stepped at 0.013 (``steps`` 96) down to 7e-6 (8) of the fixed point,
    and took 103, 591, 1,642, 12,830, 97,219 steps at ``steps`` 96, 48, 33, 16, 8.
    ``log(cap / s)`` is concave in ``log s`` (``log u(s)`` is a log-sum-exp), so Newton's
    steps stay at or above the fixed point, and the floor keeps the step above a quarter of
    it: now 6, 5, 5, 4, 4 steps. Newton's step alone (floor 1) made the first step of starts
    that the speed carries, e.g. (1, 5, 1e6, 0) at 96 steps, 1.7 times the mean's (0.59 of
    the fixed point): same e, but 26 times the summed local error estimates, refined (the
    hard cases' huge-gamma set: 43,235 -> 70,678 steps). Floors of 0.2 to 0.3 cost the same
    (docs/speed/history.md, 2026-12-05)."""
    mean = math.sqrt(s * cap) if s * cap > 1e-290 else math.sqrt(s) * math.sqrt(cap)
    if mean >= NEWTON_FLOOR * s:
        # The floor is below NEWTON_FLOOR s (cap < s): no pow where the mean moves little.
        return mean
    # Under a huge damping (gamma ~ 1e245) s cap underflows (mean: two roots) and so may
    # cap / s: the floor is then 0 and the mean decides.
    return max(mean, NEWTON_FLOOR * s * (cap / s) ** (1.0 / m))


@jit(inline="always")
def uncapped(p):
    """The policy ``p`` is neither local nor capped (most steps'): :func:`first_guess` is
    then :func:`uncapped_guess`."""
    return not (p.local or p.capped)


@jit(inline="always")
def uncapped_guess(u, v, p):
    """:func:`first_guess` where the policy ``p`` is :func:`uncapped`: the base step,
    graded near u = 0."""
    return graded_step(u, v, p.h, p.rho, p.s_min) if p.graded else p.h


@jit(inline="always")
def first_guess(u, v, p, c):
    """Step from state (u, v) before the damping cap is judged at the step's end."""
    if uncapped(p):
        return uncapped_guess(u, v, p)
    h, s_min = _base(u, p, c)
    # A local policy is always graded: its base step grows without bound as u falls (for
    # alpha > 1), and the creep's own time scale u / |v| then bounds it.
    s = graded_step(u, v, h, p.rho, s_min) if (p.graded or p.local) else h
    if p.capped:
        s = _capped_step(u, v, min(s, damping_step(u, c, p.steps)), p, c)
    return s
