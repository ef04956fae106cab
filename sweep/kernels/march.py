"""The march: a fixed-step Runge-Kutta integration of (4) through the phases of Algorithm 1.

Per point (a :class:`~sweep.kernels.contact.Law`) the bead starts at ``u = 0``, ``w = 1``
and is marched with the step policy of :mod:`sweep.kernels.stepsize` (graded near u = 0).
Phases (report, Sec. 3 and Algorithm 1):

1. until ``v = 0`` crossing downward -- maximum compression ``u_max``;
2. until ``u = u-bar`` crossing downward (with ``g~ = 0``, ``u-bar = 0`` and this is the
   detachment itself);
3. until ``u v = 0``: ``u = 0`` (the bead leaves) or ``v = 0`` with ``u > 0`` (a trough).

Each event is bracketed by a sign test at the step's ends, located on the step's interpolant
(:mod:`sweep.kernels.events`) and refined with full Runge-Kutta steps from the step's start
(Newton on the re-stepped state), so located times and states carry the method's own
accuracy. Grazing (u dipping below 0 inside one step and coming back) is caught in phase 3
through the velocity's sign change: the minimum of u at ``v = 0`` tells a trough from a
detachment.

Two more stopping rules keep every point bounded: the report's rest criterion
``max(|u - u-bar|, |v|) < rest_tol`` (Sec. 3), and the energy rule: the dissipated energy q
(carried along, see :func:`sweep.kernels.contact.rhs`) exceeds the initial 1/2, so that the
energy ``H = 1/2 - q`` is below the floor's level and the bead can never leave. The energy
rule applies from phase 2 on, and in phase 1 only when the linearisation about u-bar is
overdamped (``xi >= 1``), where phase 1 may never end. Under heavy damping (the step's
damping cap active) the creep rules (:mod:`sweep.kernels.creep`) also apply in phase 1, and
decide a bead that has dissipated more than its energy above the floor's level while still
compressing (KK at gamma = 1, g~ = 1: at u = 0.61 of the 1.23 it would reach). A point
decided before maximum compression has ``u_max`` NaN: it is not marched on to find it.

The march reports only *where* it ended (:class:`Ending`: exit, trough, energy spent, rest,
budget, with the state and q there); :mod:`sweep.kernels.outcome` decides what that means
for e.

Owns: stepping through the phases and locating the events. May import: balance, contact, stepper,
stepsize, events.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.balance import q_error, swing_of
from sweep.kernels.contact import (accel, damping_rate, dissipated, elastic_frequency,
                                   make_law, overdamped_at_rest, potential, ppow_called,
                                   rhs_called, velocity, well_depth)
from sweep.kernels.creep import (ROUNDING_V, creep_constants, energy_margin, jump,
                                 near_slow_branch, never_leaves)
from sweep.kernels.events import ON_U, ON_V, locate
from sweep.kernels.stepper import (N_DENSE, N_STAGES, dense_coefficients, local_error, rk_step,
                                    rk_step_inline)
from sweep.kernels.stepsize import (StepPolicy, damping_step, first_guess, local_policy,
                                    policy)

__all__ = ["Ending", "State", "march", "march_point", "start", "finish_step", "after_stages",
           "after_stages_estimated", "out_of_budget", "EXIT", "TROUGH", "SPENT", "REST",
           "BUDGET", "CREEP", "NEGLIGIBLE", "GOING", "scratch", "SCRATCH_SHAPES",
           "compensated_sum", "carry_last_stage"]

# Relative roundoff in the dissipated energy q (a sum of positive terms): the energy rule
# waits until q exceeds the initial energy 1/2 by more than it.
_ENERGY_ROUNDOFF = 1e-12
# Steps per unit of resolution (steps per half period) up to which a creeping bead's march
# goes on past the creep rule's stick until it is certain (_stick_doubt). Heavily damped
# draws at tol = 1e-6 (gamma = 10^U(0, 2)) make it certain within 20-100 times the
# resolution, a third of what refining the undecided bound cost (KK: 120.5 -> 65.0 mean
# steps; 64: 74.5); a bead creeping for ever (gamma = 1e12) would go on to the budget,
# which _worth_going_on foresees (the hard cases' huge_gamma set: 50,162 -> 43,231 steps).
_SURE_STEPS = 128.0
# The detachment's Newton iteration stops once a correction is within 4 ulps of the time d:
# u at d carries rounding, so smaller corrections are noise, and a bound below one ulp of
# d (2e-16 d, as before) let the iteration swing between two neighbouring floats up to
# its cap (2.4% of the KK core draw took all 12 re-steps).
_EPS = float(np.finfo(np.float64).eps)
_NEWTON_STOP = 4.0 * _EPS
# Local damping ratio from which a bead returning at g~ = 0 (or far above u-bar:
# _LOAD_FREE) is marched with steps that follow its local time scales
# (stepsize.local_policy; 1 nearer u-bar). Near critical
# damping with kappa ~ 0 the return's real time grows like e^(-(alpha-1)/(alpha+1)) while
# zeta(u) stays below 1 (at kappa = 0 it is zeta sqrt((alpha+1)/(2 alpha)), zeta =
# gamma sqrt(beta)/2): the base step of u_M ran out of budget with a bound of ~1e-6 where
# e is 1e-8 .. 1e-13 ((2, 1.5005) at zeta 0.995: 200,000 steps; now 1,520, e to 5e-21).
# 0.5 is zeta from 0.5 to 0.61 for alpha in [1, 3] (e ~ 0.1 at kappa = 0), below which the
# return is quick. Near u-bar a load keeps 1: there the motion's time scale is u-bar's,
# not the local one.
_ZETA_FREE = 0.5
# Under a load the switch at _ZETA_FREE applies while the load is below this fraction of
# the elastic force (g~ <= _LOAD_FREE u^alpha, i.e. u >= u-bar _LOAD_FREE^(-1/alpha)):
# there the return is the g~ = 0 one up to that relative perturbation. Near-critical
# returns at g~ = 1e-15 .. 1e-7 switch where they start (u ~ u_M) and took u_M's base
# step before ((2, 1.5005, 1.62456, 1e-12): 90,874 steps, now 1,371). The core
# draws (g~ >= 1e-3, alpha <= 3) never switch so: on the return u^alpha <= (alpha+1)
# (g~ + 1/(2u)) (energy below 1/2), under 1e6 g~ whether u is above or below 1; they
# stay bit for bit as they were.
_LOAD_FREE = 1e-6


#: Shapes of :func:`scratch`'s arrays K, K2, Q (the lanes view K2 and Q through bare
#: pointers in their called paths: ``sweep.kernels.lanes._clothed``).
SCRATCH_SHAPES = ((N_STAGES, 3), (N_STAGES, 3), (2, N_DENSE))


@jit(inline="always")
def scratch():
    """Work arrays of one thread: stages ``K``, re-step stages ``K2``, dense output ``Q``
    (their shapes :data:`SCRATCH_SHAPES`)."""
    k, k2, q = SCRATCH_SHAPES
    return np.empty(k), np.empty(k2), np.empty(q)


@jit(inline="always")
def _set_first_stage(K, fu, fw, fr):
    K[0, 0] = fu
    K[0, 1] = fw
    K[0, 2] = fr


@jit(inline="always")
def carry_last_stage(K):
    """The next step's first stage is this one's last (first-same-as-last): f at its end."""
    _set_first_stage(K, K[N_STAGES - 1, 0], K[N_STAGES - 1, 1], K[N_STAGES - 1, 2])


@jit(inline="always")
def compensated_sum(r, rc, dr):
    """``r + dr`` by Kahan's compensated summation, ``rc`` the compensation carried:
    ``(sum, its compensation)``. q's rounding stays at eps instead of growing with the
    number of steps, which matters where e = sqrt(1 - 2 q) is small. (The multi-point
    driver's lanes take the same operations as vectors: ``lanes._moved_on_group``.)"""
    y = dr - rc
    r1 = r + y
    return r1, (r1 - r) - y


@jit(inline="always")
def _restep(u, w, r, d, K, K2, c):
    """State at time ``d`` after the step's start, by one Runge-Kutta step of size ``d``."""
    _set_first_stage(K2, K[0, 0], K[0, 1], K[0, 2])
    u1, w1, dr = rk_step(u, w, d, K2, c)
    return u1, w1, r + dr


@jit(inline="always")
def _linear_enough(ue, ve, delta, d, c):
    """The Newton correction ``delta`` from the re-stepped ``(ue, ve)`` at time d leaves u
    a residual ``a delta^2 / 2`` (a the acceleration) below one ulp of u's scale over the
    step, ``|ve| d``: applied to first order it is as good as another re-step."""
    return 0.5 * abs(accel(max(ue, 0.0), ve, c)) * delta * delta <= _EPS * abs(ve) * d


@jit(inline="always")
def _detach(u, w, r, s, th_lo, th_hi, Q, K, K2, c):
    """Refine the detachment u = 0 inside ``[th_lo, th_hi]`` of the step from ``(u, w, r)``.

    Returns ``(time from the step's start, dissipated energy q, velocity, re-steps used)``
    at the detachment.
    """
    # int(): a literal event code would compile locate once per event.
    th = locate(int(ON_U), 0.0, u, w, Q, c, th_lo, th_hi)
    lo = th_lo * s
    hi = th_hi * s
    d = th * s
    used = 0
    ue = 0.0
    we = 1.0
    ve = -1.0
    r_e = r
    for _ in range(12):
        ue, we, r_e = _restep(u, w, r, d, K, K2, c)
        used += 1
        ve = velocity(ue, we, c)
        if ue > 0.0:
            lo = d
        else:
            hi = d
        newton = ve < 0.0
        dn = d - ue / ve if newton else 0.5 * (lo + hi)
        if not (lo <= dn <= hi):
            dn = 0.5 * (lo + hi)
            newton = False
        if (abs(dn - d) <= _NEWTON_STOP * d or hi - lo <= _NEWTON_STOP * d
                or (newton and _linear_enough(ue, ve, dn - d, d, c))):
            d = dn
            break
        d = dn
    # The last Newton correction delta is applied to first order. At the root u = 0, so
    # v = w and q = r there (q = gamma v u^beta + r): both are read off the smooth state
    # (u, w, r), whose derivatives are the right-hand side's.
    delta = -ue / ve if ve < 0.0 else 0.0
    _, fw, fr = rhs_called(ue, we, c)
    return d, r_e + delta * fr, we + delta * fw, used


@jit(inline="always")
def _stationary_u(u, v, c, upward):
    """u at the vertex of the local parabola through (u, v): removes a residual v at an
    extremum of u (``upward``: a minimum, where the acceleration is positive)."""
    acc = accel(u, v, c)
    if (acc > 0.0) if upward else (acc < 0.0):
        return u - 0.5 * v * v / acc
    return u


# --------------------------------------------------------------------------- one step

# Not inlined: only points whose damping cap can bind come here (compile time).
@jit(counted=False)
def _capped(u, w, s, u1, w1, dr, fu0, fw0, fr0, p, K, c, n, max_steps):
    """The step ``s`` from (u, w) that ended at (u1, w1), retaken smaller while the damping
    cap judged at its end is exceeded: ``(u1, w1, dr, s, n)``, n the steps counter. ``fu0,
    fw0, fr0``: f at the step's start (K[0], which the stages leave as it is)."""
    # A load can drive the bead deep into the damper within one step: judge the cap at the
    # step's end too and retake the step if it was exceeded (twice: slack against
    # retaking steps for nothing).
    s_end = damping_step(u1, c, p.steps)
    while not (s <= 2.0 * s_end and math.isfinite(u1) and math.isfinite(w1)) and n < max_steps:
        s = s_end if s_end < 0.5 * s else 0.5 * s
        _set_first_stage(K, fu0, fw0, fr0)
        u1, w1, dr = rk_step(u, w, s, K, c)
        n += 1
        s_end = damping_step(u1, c, p.steps)
    return u1, w1, dr, s, n


# --------------------------------------------------------------------------- phases

@jit(inline="always")
def _compressed(v, w):
    """Phase 1 is over: v <= 0, or v at the rounding level of ``v = w - gamma u^beta``
    (under heavy damping the bead stops on the damper, with v ~ 1e-17 formed as a
    difference of numbers ~1: its sign is noise, and the maximum is reached)."""
    return v <= ROUNDING_V * abs(w)


@jit(inline="always")
def _may_have_event(phase, u1, v1, w1, ubar):
    """An event of Algorithm 1 may lie inside the step that ended at (u1, v1, w1)."""
    if phase == 1:
        return _compressed(v1, w1)
    if phase == 2:
        return u1 < ubar or (ubar == 0.0 and u1 <= 0.0)
    return u1 <= 0.0 or v1 >= 0.0


@jit(inline="always")
def _compression_end(u, w, r, s, Q, K, K2, c):
    """Phase 1 ends inside the step: maximum compression (v = 0). Returns its fraction of
    the step and ``u_max``."""
    th = locate(int(ON_V), 0.0, u, w, Q, c, 0.0, 1.0)
    um, wm, _ = _restep(u, w, r, th * s, K, K2, c)
    return th, _stationary_u(um, velocity(um, wm, c), c, False)


@jit(inline="always")
def _trough(u, w, r, s, th0, Q, K, K2, c):
    """Phase 3, v = 0 inside the step: the bead's lowest point after the swing. Returns its
    fraction of the step, the minimum of u there (> 0: the bead sticks; <= 0: it dipped
    below the floor inside the step -- grazing -- and left first) and the dissipated energy."""
    th = locate(int(ON_V), 0.0, u, w, Q, c, th0, 1.0)
    us, ws, rs = _restep(u, w, r, th * s, K, K2, c)
    vs = velocity(us, ws, c)
    return th, _stationary_u(us, vs, c, True), dissipated(us, vs, rs, c)


# --------------------------------------------------------------------------- stopping rules

@jit(inline="always")
def _at_rest(u, v, ubar, rest_tol):
    """Rest criterion of the report (Sec. 3): ``max(|u - u-bar|, |v|) < rest_tol``."""
    return max(abs(u - ubar), abs(v)) < rest_tol


@jit(inline="always")
def _may_not_return(u, w, r, v, phase, energy_in_phase1, q_stuck, gtilde):
    """:func:`_cannot_return`'s test without its confirmation (``gtilde``: the law's g~):
    False where it is False."""
    return gtilde > 0.0 and (phase > 1 or energy_in_phase1) and v * (w - v) + r > q_stuck


@jit(inline="always")
def _cannot_return(u, w, r, v, phase, energy_in_phase1, q_stuck, c):
    """Energy rule: the dissipated energy exceeds the initial 1/2 (beyond roundoff), so the
    bead can never reach u = 0 again (H = 1/2 - q never increases and is e^2/2 >= 0 at a
    detachment). q = gamma v u^beta + r, with gamma u^beta = w - v read off the state
    (no power per step) and confirmed from the power where the cheap form says yes.
    Applied from phase 2 on, and in phase 1 only when the linearisation is overdamped."""
    if not _may_not_return(u, w, r, v, phase, energy_in_phase1, q_stuck, c.gtilde):
        return False
    # w - v cancels in deep wells (both ~ the swing speed): confirm with the power itself.
    return dissipated(u, v, r, c) > q_stuck


@jit(inline="always")
def _stick_doubt(st, c):
    """How much energy ``H = 1/2 - q`` must still lose for the energy rule's stick to be
    beyond the march's error: ``h + dq`` (:func:`sweep.kernels.balance.q_error`), negative
    where it is, or where the well is too shallow for it ever to be (its floor ``V(u-bar)``
    within dq of 0)."""
    # Stopped at the crossing itself (H ~ 0-), the decision said "cannot tell" and bounded
    # e by sqrt(2 dq): at tol=1e-6 a certain stick was refined to ~10 times its steps for
    # that bound (46% of the steps of heavily damped KK draws), where a few steps more of
    # this march, H still falling, decide it.
    h = st.e0 - dissipated(st.u, st.v, st.r, c)
    depth = well_depth(c.alpha, c.gtilde)
    dq = q_error(c, st.u, st.v, h, st.lq, st.n, st.p.steps, 1.0, swing_of(depth))
    return -1.0 if depth <= dq else h + dq


@jit(inline="always")
def _worth_going_on(st, doubt):
    """A creeping bead's march can lose ``doubt`` more energy within :data:`_SURE_STEPS`
    times the resolution: under the damping cap a step dissipates at most ``pi v^2 /
    steps`` (:func:`sweep.kernels.stepsize.damping_step`), and the creep slows down."""
    left = _SURE_STEPS * st.p.steps - st.n
    if left <= 0.0:
        return False
    return not st.p.capped or doubt * st.p.steps < left * math.pi * st.v * st.v


#: How a march ended (the geometry); :func:`sweep.kernels.outcome.decide` reads it.
EXIT, TROUGH, SPENT, REST, BUDGET, CREEP, NEGLIGIBLE = range(7)
#: Not ended (the march goes on).
GOING = -1


class Ending(NamedTuple):
    """Where and how the march of one point stopped.

    ``kind``: EXIT (u = 0 reached), TROUGH (v = 0 with u > 0 after the swing), SPENT (the
    dissipated energy exceeded the initial 1/2), REST (rest criterion), BUDGET (step
    budget), CREEP (certified never to leave, :func:`sweep.kernels.creep.never_leaves`),
    NEGLIGIBLE (the energy left bounds e below the tolerance). ``t``, ``u``, ``v``: time,
    position and velocity there; ``h``: the energy left, ``H = 1/2 - q`` with q the energy
    the damper dissipated (after a creep jump: H at the jump minus q since); ``u_max``:
    maximum compression (NaN if not reached); ``n``: steps taken;
    ``lw``, ``lq``: sums of the embedded local error estimates of w and of the dissipation
    integral over the steps (:func:`sweep.kernels.stepper.local_error`), indicators of the
    global error (:mod:`sweep.kernels.outcome`).
    """

    kind: int
    t: float
    u: float
    v: float
    h: float
    u_max: float
    n: int
    lw: float
    lq: float


@jit(inline="always")
def _creep_rule(c, k, u, w, r, v, e0, e_tol, phase):
    """Heavy damping, in phases 2 and 3 inside ``R = {v + w >= 0}`` (docs/creep.md,
    section 7): ``(kind, h)``, the Ending kind it decides (CREEP, NEGLIGIBLE, SPENT), BUDGET
    if the state should jump along the slow branch, or -1, and the energy left it judged
    by. ``e0``: the energy when q was last zero."""
    # Two estimates of the energy: 1/2 - q, whose integral carries the march's error of
    # the stop (~1e-9 at gamma = 1e10, where H ~ -1e-10 matters), and the state's own
    # v^2/2 + F(u), exact up to rounding for a bead the damper holds (inside R); the
    # smaller judges. At g~ = 0 with kappa < 0 the bead always leaves (docs/creep.md,
    # section 4): H > 0, and the state's energy, >= 0 there, judges alone. After a creep
    # jump 1/2 - q is e0 - q, a small difference of larger numbers carrying q's error: it
    # said SPENT (a stick) for SHC at gamma = 1e11, and 2e-27 where H = 8e-26 at 1e12.
    h = 0.5 * v * v + potential(u, c)
    if not (c.gtilde == 0.0 and k.kappa < 0.0):
        h = min(e0 - dissipated(u, v, r, c), h)
    h += energy_margin(u, v, c)
    if h < 0.0:
        return SPENT, h
    if never_leaves(c, k, u, w, v, h):
        return CREEP, h
    if 2.0 * h <= e_tol * e_tol:
        return NEGLIGIBLE, h
    if phase > 1 and near_slow_branch(c, k, u, w, v):   # the branch down to the floor
        return BUDGET, h
    return -1, h


@jit(inline="always")
def _creeping_back(u, c):
    """The local damping ratio ``zeta(u) = gamma beta u^(beta-1) / (2 sqrt(alpha
    u^(alpha-1)))`` is at least :data:`_ZETA_FREE` where the load is negligible (g~ = 0,
    or ``g~ <= _LOAD_FREE u^alpha``), else 1: a returning bead's steps should follow its
    local time scales from here on."""
    if not u > 0.0:
        return False
    d, critical = damping_rate(u, c), 2.0 * elastic_frequency(c.alpha, u)
    if d >= critical:                   # zeta(u) >= 1: whatever the load
        return True
    # The load's power only where it decides: this runs at every step of a return.
    return d >= _ZETA_FREE * critical and c.gtilde <= _LOAD_FREE * ppow_called(u, c.alpha,
                                                                                  c.ka)


@jit(inline="always")
def _jumped(c, k, u, v, t, K):
    """State after the jump along the slow branch: ``(u, w, r, v, t, e0)`` with K[0] = f
    there. The energy left there, ``e0 = H``, is far below 1/2's rounding (e.g. 1e-17), so
    the dissipation restarts from 0 (``q = gamma v u^beta + r = 0``) and ``H = e0 - q``."""
    u, w, v, dt = jump(c, k, u, v, K)
    r = -c.gamma * v * ppow_called(u, c.beta, c.kb)
    fu, fw, fr = rhs_called(u, w, c)
    _set_first_stage(K, fu, fw, fr)
    return u, w, r, v, t + dt, 0.5 * v * v + potential(u, c)


class State(NamedTuple):
    """The march of one point between two steps (what a lane of the multi-point driver
    holds; :func:`march` is the same sequence for one point)."""

    t: float
    u: float
    w: float
    r: float          # dissipation integral (q = gamma v u^beta + r)
    rc: float         # its Kahan compensation
    v: float
    e0: float         # energy when q was last zero (1/2, or H at a creep jump)
    q_stuck: float    # the energy rule's threshold on q
    phase: int
    u_max: float
    n: int
    lw: float         # summed local error estimates of w
    lq: float         # ... and of the dissipation integral
    p: StepPolicy
    energy_in_phase1: bool


@jit(inline="always")
def _with_policy(st, p):
    # numba's named tuples have no _replace: each update builds the tuple.
    return State(st.t, st.u, st.w, st.r, st.rc, st.v, st.e0, st.q_stuck, st.phase, st.u_max,
                 st.n, st.lw, st.lq, p, st.energy_in_phase1)


@jit(inline="always")
def _with_umax(st, u_max):
    return State(st.t, st.u, st.w, st.r, st.rc, st.v, st.e0, st.q_stuck, st.phase, u_max,
                 st.n, st.lw, st.lq, st.p, st.energy_in_phase1)


@jit(inline="always")
def _after_jump(st, u, w, r, v, t, e0):
    return State(t, u, w, r, 0.0, v, e0, e0 * (1.0 + _ENERGY_ROUNDOFF), st.phase, st.u_max,
                 st.n, st.lw, st.lq, st.p, st.energy_in_phase1)


@jit(inline="always")
def start(c, p, K):
    """The state at tau = 0 (u = 0, w = v = 1) with K[0] = f there."""
    fu, fw, fr = rhs_called(0.0, 1.0, c)
    _set_first_stage(K, fu, fw, fr)
    overdamped = overdamped_at_rest(c.alpha, c.beta, c.gamma, c.gtilde)
    return State(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.5, 0.5 * (1.0 + _ENERGY_ROUNDOFF), 1, np.nan,
                 0, 0.0, 0.0, p, overdamped)


@jit(inline="always")
def _ending(kind, st, t, u, v, q, n):
    return Ending(kind, t, u, v, st.e0 - q, st.u_max, n, st.lw, st.lq)


@jit(inline="always")
def _events(st, c, k, u1, w1, v1, s, n, K, K2, Q):
    """Events of Algorithm 1 inside the step just taken: ``(phase, u_max, n, Ending)``
    with the Ending's kind GOING unless the impact ended in the step."""
    if not _may_have_event(st.phase, u1, v1, w1, k.ubar):
        return st.phase, st.u_max, n, Ending(GOING, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0)
    return _located(st, c, k, u1, w1, v1, s, n, K, K2, Q)


# Not inlined: a few steps per point have events; inlining this rare path into every
# driver multiplied the compile time (150 s against 20 s) for no speed.
@jit(counted=False)
def _located(st, c, k, u1, w1, v1, s, n, K, K2, Q):
    """:func:`_events` once the step's ends say an event may lie inside it."""
    phase, u_max = st.phase, st.u_max
    none = Ending(GOING, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0)
    u, w, r, t = st.u, st.w, st.r, st.t
    # Which events lie in the step follows from its ends alone; they are located after.
    compressed = phase == 1 and _compressed(v1, w1)
    if compressed:
        phase = 2
    crossed = phase == 2 and k.ubar > 0.0 and u1 < k.ubar
    if crossed:
        phase = 3
    # With g~ = 0 (u-bar = 0) the return to u-bar in phase 2 is the detachment itself.
    exiting = (phase == 3 or (phase == 2 and k.ubar == 0.0)) and u1 <= 0.0
    trough = not exiting and phase == 3 and v1 >= 0.0
    if not (compressed or exiting or trough):
        # Phase 2's end, where it lies in the step, bounds only the events of phase 3 in
        # the same step: at most crossings there are none, and its location (and the
        # interpolant's coefficients) would go unused (a locate a point: 3% of its time).
        return phase, u_max, n, none
    # Where the floor alone is to be located (most steps here), its interpolant needs u's
    # coefficients alone.
    dense_coefficients(K, s, Q, 2 if compressed or trough else 1)
    th0 = 0.0
    if compressed:
        th0, u_max = _compression_end(u, w, r, s, Q, K, K2, c)
        n += 1
    if crossed and (exiting or trough):
        th0 = locate(int(ON_U), k.ubar, u, w, Q, c, th0, 1.0)
    th_exit = 1.0
    if trough:
        th_exit, u_min, q_min = _trough(u, w, r, s, th0, Q, K, K2, c)
        n += 1
        if u_min > 0.0:
            return phase, u_max, n, Ending(TROUGH, t + th_exit * s, u_min, 0.0, st.e0 - q_min,
                                           u_max, n, st.lw, st.lq)
        exiting = True
    if exiting:
        d, q_f, v_f, used = _detach(u, w, r, s, th0, th_exit, Q, K, K2, c)
        return phase, u_max, n, Ending(EXIT, t + d, 0.0, v_f, st.e0 - q_f, u_max, n + used,
                                       st.lw, st.lq)
    return phase, u_max, n, none


@jit(counted=False)
def _creep_rules(st, c, k, K, e_tol):
    """The creep rules inside R: ``(state, Ending)``, the state moved by a creep jump, the
    Ending's kind GOING unless the march ends here. (Not inlined: see :func:`_located`.)"""
    u, w, r, v, p = st.u, st.w, st.r, st.v, st.p
    if st.phase > 1 and _creeping_back(u, c):
        # Creeping back: steps follow the local time scales, which grow as u
        # falls (docs/creep.md, section 7).
        st = _with_policy(st, local_policy(p, c.alpha))
    kind, h = _creep_rule(c, k, u, w, r, v, st.e0, e_tol, st.phase)
    if kind == SPENT:
        doubt = _stick_doubt(st, c)
        if doubt >= 0.0 and _worth_going_on(st, doubt):
            kind = -1       # H still falls: a few steps more make the stick certain
    if kind == BUDGET:
        u, w, r, v, t, e0 = _jumped(c, k, u, v, st.t, K)
        if not (math.isfinite(t) and v != 0.0):
            # The landing point is so deep (u_t ~ 1e-75 for kappa ~ -0.16 and gamma ~ 1e6)
            # that the creep's speed there underflows and its duration overflows: the
            # energy left, v^2/2 + F(u_t), is below 1e-300 and bounds e.
            h = e0 if e0 >= 0.0 else 0.0     # NaN where v underflowed to 0 with u^alpha
            return st, Ending(NEGLIGIBLE, math.inf, u, v, h, st.u_max, st.n, st.lw, st.lq)
        return _after_jump(st, u, w, r, v, t, e0), Ending(GOING, 0.0, 0.0, 0.0, 0.0, 0.0, 0,
                                                          0.0, 0.0)
    if kind == NEGLIGIBLE:
        # The energy the rule judged by (the state's own energy where it is the smaller,
        # exact to rounding for a bead the damper holds), not 1/2 - q, whose integral
        # carries the march's error (~1e-12 after a long creep: a bound of 3e-6 on e
        # where the state says 1e-10).
        return st, Ending(NEGLIGIBLE, st.t, u, v, max(h, 0.0), st.u_max, st.n, st.lw, st.lq)
    if kind >= 0:
        return st, _ending(kind, st, st.t, u, v, dissipated(u, v, r, c), st.n)
    return st, Ending(GOING, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0)


@jit(inline="always")
def _rules(st, c, k, K, rest_tol, e_tol):
    """The stopping rules and the creep jump at a step's end: ``(state, Ending)``."""
    if _creep_rules_apply(st.phase, st.p.capped, st.v, st.w):
        st, end = _creep_rules(st, c, k, K, e_tol)
        if end.kind != GOING:
            return st, end
    # At most steps neither the rest box nor the energy rule can apply: the cheap tests
    # here say so, and only where one may is _settled called (compiled once, not copied
    # into every driver; 1.5-4 s of the lanes' first compile with its helpers inlined).
    if _may_settle(st.u, st.w, st.r, st.v, st.phase, st.energy_in_phase1, st.q_stuck,
                   c.gtilde, k.ubar, rest_tol):
        return _settled(st, c, k, rest_tol)
    return st, Ending(GOING, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0)


@jit(inline="always")
def _creep_rules_apply(phase, capped, v, w):
    """The creep rules apply inside R (v >= -gamma u^beta / 2), which phase 1 always is:
    there only under heavy damping (the damping cap on), where the bead may creep into a
    well for ever."""
    return (phase > 1 or capped) and v + w >= 0.0


@jit(inline="always")
def _may_settle(u, w, r, v, phase, energy_in_phase1, q_stuck, gtilde, ubar, rest_tol):
    """The rest box or the energy rule may apply at a step's end (:func:`_settled`).
    (With the damping cap, :func:`_may_have_event` and :func:`_creep_rules_apply`, the
    tests the multi-point driver makes as vectors of lanes, ``lanes._eventful_bits``: a
    step none of them flags needs nothing but the state moved on; ``tests/test_lanes.py``
    holds the two to the same Endings, bit for bit.)"""
    return (gtilde > 0.0 and _at_rest(u, v, ubar, rest_tol)) or _may_not_return(
        u, w, r, v, phase, energy_in_phase1, q_stuck, gtilde)


@jit(counted=False)
def _settled(st, c, k, rest_tol):
    """The rest box and the energy rule at a step's end where one may apply: ``(state,
    Ending)``, the Ending's kind GOING where neither does."""
    # At g~ = 0 the rest box is no proof of rest (a bead in it may still leave with
    # e up to its energy, ~1e-8): the creep rules decide there.
    if c.gtilde > 0.0 and _at_rest(st.u, st.v, k.ubar, rest_tol):
        if st.phase == 1:
            st = _with_umax(st, max(st.u, k.ubar))
        return st, _ending(REST, st, st.t, st.u, st.v, dissipated(st.u, st.v, st.r, c), st.n)
    if _cannot_return(st.u, st.w, st.r, st.v, st.phase, st.energy_in_phase1, st.q_stuck, c) \
            and _stick_doubt(st, c) < 0.0:
        return st, _ending(SPENT, st, st.t, st.u, st.v, dissipated(st.u, st.v, st.r, c), st.n)
    return st, Ending(GOING, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0)


@jit(inline="always")
def finish_step(st, c, k, u1, w1, dr, s, n, K, K2, Q, rest_tol, e_tol):
    """Everything after a step's Runge-Kutta stages (``K`` holds them, ``u1, w1`` the end
    state, ``dr`` the increment of r, ``n`` the steps counter): the events located in the
    step, the state moved on, then the stopping rules. Returns ``(state, Ending)``, the
    Ending's kind GOING while the march goes on."""
    _, ew, eq = local_error(K, s)
    return _finish_step(st, c, k, u1, w1, dr, ew, eq, s, n, K, K2, Q, rest_tol, e_tol)


@jit(inline="always")
def _finish_step(st, c, k, u1, w1, dr, ew, eq, s, n, K, K2, Q, rest_tol, e_tol):
    """:func:`finish_step` given the step's local error estimates ``ew, eq``."""
    # The last (FSAL) stage is f at the step's end: its u' is the velocity v1, no power.
    v1 = K[N_STAGES - 1, 0]
    lw, lq = st.lw + abs(ew), st.lq + abs(eq)
    phase, u_max, n, end = _events(st, c, k, u1, w1, v1, s, n, K, K2, Q)
    if end.kind != GOING:
        return st, Ending(end.kind, end.t, end.u, end.v, end.h, end.u_max, end.n, lw, lq)
    r1, rc1 = compensated_sum(st.r, st.rc, dr)
    st = State(st.t + s, u1, w1, r1, rc1, v1, st.e0, st.q_stuck, phase, u_max, n, lw, lq,
               st.p, st.energy_in_phase1)
    carry_last_stage(K)
    return _rules(st, c, k, K, rest_tol, e_tol)


@jit(inline="always")
def out_of_budget(st, c):
    """The :class:`Ending` of a march whose step budget is spent (BUDGET). The energy left
    bounds e: the larger of its two estimates, 1/2 - q (q's error) and the state's own (the
    march's), so that the bound holds whichever errs (1/2 - q alone said H < 0, e <= 0,
    for a creep at g~ = 0 that leaves)."""
    h = max(st.e0 - dissipated(st.u, st.v, st.r, c), 0.5 * st.v * st.v + potential(st.u, c))
    return Ending(BUDGET, st.t, st.u, st.v, h, st.u_max, st.n, st.lw, st.lq)


@jit(inline="always")
def after_stages(st, c, k, s, u1, w1, dr, K, K2, Q, rest_tol, e_tol, max_steps):
    """A step of size ``s`` from ``st`` whose stages are in ``K`` (``u1, w1, dr`` their
    result): the damping cap judged at its end (the step retaken smaller where exceeded),
    then :func:`finish_step`. Returns ``(state, Ending)``. :func:`march`'s; the multi-point
    driver (:mod:`sweep.kernels.lanes`), which forms the stages differently, takes
    :func:`after_stages_estimated`, the same arithmetic."""
    n = st.n + 1
    if st.p.capped:
        # The stages leave K[0] (f at the step's start) as it was.
        u1, w1, dr, s, n = _capped(st.u, st.w, s, u1, w1, dr, K[0, 0], K[0, 1], K[0, 2], st.p,
                                   K, c, n, max_steps)
    return finish_step(st, c, k, u1, w1, dr, s, n, K, K2, Q, rest_tol, e_tol)


@jit(inline="always")
def after_stages_estimated(st, c, k, s, u1, w1, dr, ew, eq, K, K2, Q, rest_tol, e_tol,
                           max_steps):
    """:func:`after_stages` given the step's local error estimates ``ew, eq``
    (:func:`sweep.kernels.stepper.local_error` of ``K`` and ``s``), which the lanes form
    for all lanes in one tight loop: per lane, after the stages, their chains of dependent
    multiply-adds held the core (about 17% of the lanes' time by ``perf``, 6% in one loop;
    7-10% less time a KK step). Formed again where the damping cap retook the step (new
    stages, another size)."""
    n = st.n + 1
    if st.p.capped:
        u1, w1, dr, s, n = _capped(st.u, st.w, s, u1, w1, dr, K[0, 0], K[0, 1], K[0, 2], st.p,
                                   K, c, n, max_steps)
        if n != st.n + 1:   # retaken (counted) in new stages; most capped steps keep theirs
            _, ew, eq = local_error(K, s)
    return _finish_step(st, c, k, u1, w1, dr, ew, eq, s, n, K, K2, Q, rest_tol, e_tol)


@jit()
def march(c, p, rest_tol, max_steps, K, K2, Q, e_tol=0.0):
    """The three phases of Algorithm 1 for the law ``c`` with the step policy ``p``: the
    geometry of the impact, up to its :class:`Ending`. ``e_tol``: energy below which a
    heavily damped bead's possible rebound is negligible (NEGLIGIBLE)."""
    k = creep_constants(c)
    st = start(c, p, K)
    while True:
        if st.n >= max_steps:
            return out_of_budget(st, c)
        # The step (size from the policy, then the damping cap judged at the step's end),
        # written out here: one level of inlining less for the stages (compile time).
        s = first_guess(st.u, st.v, st.p, c)
        u1, w1, dr = rk_step_inline(st.u, st.w, s, K, c)
        st, end = after_stages(st, c, k, s, u1, w1, dr, K, K2, Q, rest_tol, e_tol, max_steps)
        if end.kind != GOING:
            return end


@jit(entry=True)
def march_point(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, e_tol=0.0):
    """The :class:`Ending` of one point's march (for diagnostics and tests)."""
    K, K2, Q = scratch()
    c = make_law(alpha, beta, gamma, gtilde)
    return march(c, policy(c, steps), rest_tol, max_steps, K, K2, Q, e_tol)


