"""Numerical CoR of many points: regimes, the march, the energy-balance decision, refinement.

Per point (scaled parameters ``alpha, beta, gamma, g~``):

1. outcomes known without marching are taken from :mod:`sweep.kernels.regimes` (gamma = 0,
   the linear law's overdamped creep at g~ = 0, very deep load wells);
2. otherwise the march (:mod:`sweep.kernels.march`) follows the impact through the phases
   of Algorithm 1 (with ``tol``, a nearly elastic point at a share of the resolution, a
   predicted stick first at the floor and, where that does not settle it, at its share:
   :func:`sweep.kernels.stepsize.tol_share`, :func:`_first_steps`) and
   :mod:`sweep.kernels.outcome` turns where it ended into ``(e, status, e_err)`` on the
   energy balance;
3. a point whose error indicator exceeds the refinement target (near the stick/rebound
   boundary, where every error is amplified by about 1/e, or where the balance cannot yet
   tell a stick from a rebound) is marched again at ``f = 1.15 (e_err / aim)^(1/5)``
   times the resolution, between 1.3 and 2 (:data:`FIRST_RATIO_C`; aim: a fraction
   :data:`REFINE_MARGIN` of the target): the difference over ``f^p - 1`` (Richardson, with
   the lowest order p seen before the asymptotic regime, :data:`RICHARDSON_ORDER`, or the
   order at which the two marches' own estimates fell where the coarser one is near the
   target, :data:`ORDER_MAX`), or the finer march's own estimate where that is larger, is
   the error of the finer march, which is kept. If that
   exceeds the aim too, the point is marched again at ``f = 1.25 (e_err /
   aim)^(1/5)`` times the resolution (at most
   :data:`MAX_REFINEMENT` in all, each march at least :data:`MIN_RATIO` times finer than
   the one before), and so on. A finer march that runs out of the step
   budget (a slow creep at g~ = 0 needs many steps at every resolution) is dropped: the
   last completed one is kept, with its own estimate.

``e_err`` is an estimate of ``|e - e_true|`` (see :mod:`sweep.kernels.outcome`), calibrated
on the test suite's references (tests/test_hard_cases.py).

An array call runs the serial kernel on blocks of contiguous points, in a shuffled order,
from a pool of threads (:mod:`sweep.kernels._parallel`): costs vary by orders of magnitude
(sticking ends early, heavy damping runs long), and each thread takes the next block when
it is done. Within a block the marches run several at a time
(:func:`sweep.kernels.lanes.march_lanes`): first every point's first march, then one pass
per round of refinement over the points still refining, each point's sequence of marches
the same as :func:`solve_point`'s (one step function, :func:`_refine_update`). Results
never depend on the thread count, block, order or lanes: they are bit-identical to
:func:`solve_point` (tests/test_lanes.py, tests/test_integrator_accuracy.py).

Owns: the per-point solve, the refinement and the array kernels. May import: regimes,
march, lanes, outcome, balance, contact, stepsize, registry, the parallel policy.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sweep.kernels._jit import cached_jit, jit
from sweep.kernels._parallel import map_blocks, parallel_allowed, schedule, threads
from sweep.kernels.contact import equilibrium, in_domain, make_law, umax_undamped
from sweep.kernels.lanes import N_ENDING, ending_at, equilibrium_at, march_lanes
from sweep.kernels.march import march
from sweep.kernels.balance import COARSE_STEPS, ROUNDING
from sweep.kernels.outcome import decide, exit_time
from sweep.kernels.regimes import (creeps_from_start, deep_well, kappa_zero_free,
                                    linear_overdamped, undamped)
from sweep.kernels.stepsize import policy_at, q_constants, resolution, tol_share
from sweep.registry import METHODS, Status, kernel_fields

__all__ = ["integrate_arrays", "solve_point", "Settings", "settings",
           "DEFAULT_STEPS",
           "DEFAULT_MAX_STEPS", "DEFAULT_REST_TOL", "REFINE_TARGET", "MAX_REFINEMENT"]

_OPTIONS = {opt.name: opt.default for opt in METHODS["numeric"].options}
#: Steps per half period of the stiffest linearised motion (see :mod:`sweep.kernels.stepsize`).
DEFAULT_STEPS = _OPTIONS["steps"]
#: Step budget per march (all Runge-Kutta steps, event refinement included).
DEFAULT_MAX_STEPS = _OPTIONS["max_steps"]
#: Rest tolerance of the report (Sec. 3).
DEFAULT_REST_TOL = _OPTIONS["rest_tol"]
#: Estimated error of e above which a point is checked (and marched again, finer), when no
#: tol is given: issue 9's target. e_err bounds the error with room (actual / e_err below
#: 0.68, benchmarks/tol_margin.py), so the unrefined points stay within it; at the default
#: 96 steps it refines under 0.005% of the core benchmark's points (3e-10 refined 4.7%,
#: for 9% more steps, with the estimate of before its resolution scaling).
REFINE_TARGET = 1e-9
#: Largest refinement of the resolution, in all.
MAX_REFINEMENT = 8.0
#: Smallest ratio of the resolutions of two successive marches of a refinement.
MIN_RATIO = 1.5
#: Refinement goes on until the Richardson error is below this fraction of the target.
#: 0.25 before 2026-12-02 (set before RICHARDSON_ORDER's 2.25 and the finer march's own
#: estimate as a floor): a point first off by 2 tol had an estimate of 0.52 tol after one
#: refinement march, for a true error near 0.06 tol, and took a third. At 0.5 the refined
#: points of heavily damped draws stay within 0.17 tol (0.05 at 0.25), the hard cases and
#: the randomized audits within 0.75 of their e_err, for 3-6% fewer steps on those draws
#: (0.3% on the core draws); 1.0 left e_err above tol on some points at tol = 1e-10.
#: Since FIRST_RATIO_C and ORDER_MAX (2026-12-05): within 0.30 tol, 0.70 of e_err on the
#: draws, 0.66 on the hard cases and 0.86 in the randomized audit (benchmarks/hp_audit.py).
REFINE_MARGIN = 0.5
#: Order assumed by Richardson's error estimate, ``|e_fine - e_coarse| / (ratio^p - 1)``:
#: the ratio of successive errors is 2^5 only asymptotically (measured 2^4.3 to 2^5 near
#: the stick/rebound boundary, and orders 2.4 to 4 between 13 and 106 steps at grazing
#: points of the Hertz law). 2.25 is the old factor 8 on order 5 at ratio 2 (2^2.25 - 1 =
#: 3.76, 31 / 8 = 3.88); at the larger ratios of later refinements a fixed factor on order
#: 5 assumed far more (a 4x jump: error / 128) than grazing points give (error / 84 seen).
RICHARDSON_ORDER = 2.25
#: With a tolerance, points whose error estimate exceeds tol / TOL_MARGIN are refined. 1:
#: e_err is a bound with room (actual over e_err below 0.68, median 0.05-0.3 since the
#: defect's share, sweep.kernels.balance.defect_share, on 20,000-point KK, TTI, linear and
#: general draws at tol 1e-6 .. 1e-10, benchmarks/tol_margin.py), so every point left
#: unrefined is within tol; 2 refined a third more points for nothing (before the share).
TOL_MARGIN = 1.0
#: The first refinement march is ``FIRST_RATIO_C (e_err / aim)^(1/5)`` times finer than the
#: first march (aim: REFINE_MARGIN of the target), at least FIRST_MIN_RATIO and at most 2
#: (always 2 before 2026-12-05). The first march's e_err is tight on the points it refines
#: (true / e_err 0.18-0.64 from 5th percentile to largest, median 0.24-0.27, on the KK,
#: general, linear and Sobol draws at tol 1e-8; 0.57 heavily damped, not the 0.02 of all
#: points) and most exceed the target by little (median e_err 1.2-1.5 tol), so a march
#: that lowers e_err below the aim at order 5 usually passes: the refined points' steps
#: fell from 2.9-3.0 to 2.4-2.5 times their first march's (tol 1e-8), for 1.2-8% fewer
#: steps in all with ORDER_MAX below (docs/speed/history.md, 2026-12-05). 1.1 and 1.25
#: saved 0.1-0.9% more on those draws but cost the hard cases 5.7% more than before at tol
#: 1e-10 (third marches); 1.2 and 1.35 saved 0.1-0.9% less. At most 2: a first march far
#: off (e_err 1e2-1e5 times the target near critical damping) went to 8 at once, where
#: Richardson across the jump said 2e-5 at tol 1e-8 and no room was left (tests/
#: test_integrator_accuracy.py::test_refined_estimate_stays_meaningful_near_critical_damping).
FIRST_RATIO_C = 1.15
FIRST_MIN_RATIO = 1.3
#: Richardson takes the order at which the two marches' own estimates fell (up to
#: ORDER_MAX, at least RICHARDSON_ORDER) where the coarser one's estimate is within
#: ORDER_TRUSTED times the target: there the error is asymptotic (on the refined points
#: of the draws, from the first march to twice its resolution, median orders 4.4-5.0 for
#: the estimates and for the true errors at tol 1e-8 and 1e-10), and RICHARDSON_ORDER
#: overstated the finer march's error 8 times at ratio 2: 72% of the heavily damped draw's
#: refined points took a third march at tol 1e-10 (30% now). Farther off the estimates
#: can fall faster than the errors: on grazing hard cases 50-3000 times the target at 13
#: to 33 steps they fell at orders 3.6-4.1 where the errors fell at 2.8-3.2, and the
#: finer march's error reached 1.5 times ``max(Richardson, own estimate)`` with the
#: observed order (0.73 with RICHARDSON_ORDER, and with the guard). ORDER_MAX 4, below
#: the method's 5: 5 let the refined damped points' true / e_err reach 0.79 in one march
#: (0.70 at 4); 3 (without the guard) saved 0.8% on the damped draw at tol 1e-10 where 4
#: saved 6%, and as much as 4 on the other draws.
ORDER_MAX = 4.0
ORDER_TRUSTED = 10.0

_OK = int(Status.OK)
_BUDGET = int(Status.BUDGET_EXHAUSTED)
_INVALID = int(Status.INVALID)


class Settings(NamedTuple):
    """Integrator settings shared by every point of a call."""

    steps: float        # resolution (steps per half period); 0: from tol's error model
    rest_tol: float     # the report's rest criterion
    max_steps: int      # budget per point, every march included
    target: float       # refinement target on e_err (0: never refine)
    from_tol: bool      # steps came from tol: each point's first march takes a share of it


def settings(steps=None, rest_tol=DEFAULT_REST_TOL, max_steps=DEFAULT_MAX_STEPS, refine=True,
             tol=None):
    """The :class:`Settings` of validated options: with ``tol`` and no ``steps`` the
    resolution comes from the error model (:func:`sweep.kernels.stepsize.resolution`) and
    points whose error estimate exceeds ``tol / TOL_MARGIN`` are refined, each point's first
    march at its share of that resolution (:func:`_first_steps`); without ``tol``,
    ``steps`` (default :data:`DEFAULT_STEPS`) and :data:`REFINE_TARGET`. A given ``steps``
    is every point's resolution, with or without ``tol``."""
    target = REFINE_TARGET if tol is None else tol / TOL_MARGIN
    from_tol = steps is None and tol is not None
    if steps is None:
        steps = DEFAULT_STEPS if tol is None else resolution(tol)
    return Settings(float(steps), float(rest_tol), int(max_steps),
                    float(target) if refine else 0.0, from_tol)


# Called, not inlined: once per point, and inlining it copied its IR at compile time.
@jit()
def _regime(c):
    """An outcome known without marching: ``(decided, e, t_f, u_max, status, e_err)``."""
    d = undamped(c)
    if not d[0]:
        d = linear_overdamped(c)
    if not d[0]:
        d = creeps_from_start(c)
    if not d[0]:
        d = kappa_zero_free(c)
    if not d[0]:
        d = deep_well(c)
    return d


class Result(NamedTuple):
    """One march of one point, decided (:func:`sweep.kernels.outcome.decide`)."""

    e: float
    t_f: float
    u_max: float
    n: int
    status: int
    err: float
    e_q: float      # e from the energy balance (NaN where not defined)
    e_v: float      # e from the velocity (NaN where not defined)


@jit(inline="always")
def _negligible(s):
    """e below which a heavily damped bead's possible rebound is reported as 0 (with its
    bound as e_err): a tenth of the refinement target, or of the default one."""
    return 0.1 * (s.target if s.target > 0.0 else REFINE_TARGET)


@jit(inline="always")
def _decided(c, end, steps, ubar):
    """The :class:`Result` of a march that ended with ``end`` at resolution ``steps``
    (``ubar``: the law's equilibrium)."""
    e, status, err, e_q, e_v = decide(c, end, steps, ubar)
    return Result(e, exit_time(c, end, e, status, err), end.u_max, end.n, status, err, e_q, e_v)


# Called, not inlined: once per march, from three places of _kernel, each of which copied
# the decision and the exit time into it at compile time.
@jit()
def _ended(alpha, beta, gamma, gtilde, i, ends, j, steps):
    """The :class:`Result` of point i's march at resolution ``steps``, whose Ending
    :func:`sweep.kernels.lanes.march_lanes` stored in row j of ``ends``."""
    return _decided(make_law(alpha[i], beta[i], gamma[i], gtilde[i]), ending_at(ends, j),
                    steps, equilibrium_at(ends, j))


# Inlined (one call site in each of solve_point and _refined): a dispatcher level costs
# a compile of the whole march below it again.
@jit(inline="always")
def _solve_at(c, steps, s, budget, K, K2, Q):
    ubar = equilibrium(c.alpha, c.gtilde)
    p = policy_at(c, steps, ubar, umax_undamped(c.alpha, c.gtilde, c.ka))
    return _decided(c, march(c, p, s.rest_tol, budget, K, K2, Q, _negligible(s)), steps, ubar)


@jit(inline="always")
def _richardson(fine, coarse, ratio, target):
    """``(e_err, floor)`` of the finer of two marches ``ratio`` apart in resolution: their
    difference over ``ratio^p - 1`` (``p`` from :func:`_order`, for refinement target
    ``target``) plus, where e is the energy balance's,
    its rounding floor (~1e-15 in q, amplified by 1/e), which refinement cannot lower, and
    no less than the finer march's own estimate (which carries the rounding of e where e
    is the velocity's, :func:`sweep.kernels.outcome.cor_at_exit`).

    The own estimate covers errors that stall between two resolutions before the
    asymptotic regime (a sign change, then a plateau), where the difference of the two
    marches is far below the finer one's error: Richardson alone fell short by up to 13
    times on heavily damped points at ``tol=1e-6`` (docs/accuracy.md). It never binds on
    the core benchmark's draws (the same steps, the same e_err)."""
    # The floor is the balance's, where e is the balance's: a heavily damped bead that
    # leaves with e ~ 1e-14 has e from the velocity (outcome.cor_at_exit), whose rounding
    # is in fine.err, and the balance's floor would be ~1 (seen: e_err 0.9, error 1e-26).
    floor = 0.0
    if fine.e == fine.e_q:
        floor = ROUNDING * math.sqrt(fine.n + 1.0) / max(fine.e, 1e-300)
    if fine.status != _OK or coarse.status != _OK:
        # The decision changed with the resolution: only the difference is an honest bound.
        return max(fine.err, abs(fine.e - coarse.e)), 0.0
    p = _order(fine, coarse, ratio, target)
    rich = abs(fine.e - coarse.e) / (ratio ** p - 1.0) + floor
    return max(rich, fine.err), floor


@jit(inline="always")
def _order(fine, coarse, ratio, target):
    """Order of Richardson's estimate for two marches ``ratio`` apart: the one at which
    their own estimates fell, where the coarser one's is near ``target``
    (:data:`ORDER_TRUSTED`), else :data:`RICHARDSON_ORDER`."""
    if not ORDER_TRUSTED * target >= coarse.err > fine.err > 0.0:
        return RICHARDSON_ORDER
    observed = math.log(coarse.err / fine.err) / math.log(ratio)
    return min(max(observed, RICHARDSON_ORDER), ORDER_MAX)


@jit(inline="always")
def _without_march(alpha, beta, gamma, gtilde):
    """``(decided, (e, t_f, u_max, n_steps, status, e_err))`` of a point that needs no
    march: invalid input, or an outcome known in closed form (:func:`_regime`)."""
    if not in_domain(alpha, beta, gamma, gtilde):
        return True, (np.nan, np.nan, np.nan, 0, _INVALID, np.nan)
    d = _regime(make_law(alpha, beta, gamma, gtilde))
    return d[0], (d[1], d[2], d[3], 0, d[4], d[5])


@jit(inline="always")
def _shared(s, p):
    """Resolution of a share ``p`` of ``s.steps``, but not below COARSE_STEPS (nor above
    ``s.steps``)."""
    # Below COARSE_STEPS the estimate of q's error widens (sweep.kernels.balance): a floor
    # of 8 steps sent 26% of the KK draw at tol 1e-6 to refinement (7% at one resolution),
    # +6% steps; 12 saved 3% of KK there but cost linear 2% and 5% at 1e-8 against 16.
    return max(s.steps * p, min(s.steps, COARSE_STEPS))


@jit(inline="always")
def _first_steps(c, s, k):
    """``(first, then)``: resolution of the first march of the law ``c``, and of the march
    that follows it where it is a probe of a predicted stick (0 where not). Where
    ``s.steps`` came from tol, the first march is at its share of it
    (:func:`sweep.kernels.stepsize.tol_share`, ``k`` the exponents'
    :func:`~sweep.kernels.stepsize.q_constants` where ``s.from_tol``), or, where the bead is
    predicted to stick, at the floor, then at that share where that probe's estimate is
    above the target (:func:`_needs_refining`); else ``s.steps``."""
    if not s.from_tol:
        return s.steps, 0.0
    p, stick = tol_share(c, k)
    shared, floor = _shared(s, p), _shared(s, 0.0)
    # Without refinement (target 0) one march per point: no probe.
    if stick and floor < shared and s.target > 0.0:
        return floor, shared
    return shared, 0.0


@jit(inline="always")
def _plus_steps(a, n):
    """The :class:`Result` ``a`` with ``n`` more steps counted (a probe's, before it)."""
    return Result(a.e, a.t_f, a.u_max, a.n + n, a.status, a.err, a.e_q, a.e_v)


_NO_CONSTANTS = (math.nan, math.nan, math.nan, math.nan)


@jit(inline="always")
def _needs_refining(s, a):
    """The first march's :class:`Result` ``a`` has an indicator above the target."""
    return s.target > 0.0 and a.err > s.target and a.status != _BUDGET


@jit(inline="always")
def _as_output(a):
    return a.e, a.t_f, a.u_max, a.n, a.status, a.err


def _solve_point(alpha, beta, gamma, gtilde, s, K, K2, Q):
    """Numerical CoR of one point: ``(e, t_f, u_max, n_steps, status, e_err)``.

    ``s`` is the :class:`Settings`; ``K``, ``K2``, ``Q`` are scratch arrays
    (:func:`sweep.kernels.march.scratch`). A point whose indicator exceeds ``s.target`` is
    checked against a march up to twice its resolution (Richardson); while that error
    still exceeds the target, it is marched again, finer (module docstring).
    """
    decided, r = _without_march(alpha, beta, gamma, gtilde)
    if decided:
        return r
    c = make_law(alpha, beta, gamma, gtilde)
    k = q_constants(alpha, beta) if s.from_tol else _NO_CONSTANTS
    steps, then = _first_steps(c, s, k)
    probe = 0
    # One call site of the march (its decision is inlined there: compile time, PTX size).
    while True:
        a = _plus_steps(_solve_at(c, steps, s, s.max_steps - probe, K, K2, Q), probe)
        if not (then > 0.0 and _needs_refining(s, a)):
            break
        steps, then, probe = then, 0.0, a.n
    if not _needs_refining(s, a):
        return _as_output(a)
    return _refined(c, s, a, steps / s.steps, K, K2, Q)


#: The per-point solve compiled once, for callers of single points (the CUDA kernel, tests).
solve_point = jit(entry=True)(_solve_point)


class Refining(NamedTuple):
    """A point being refined, between two marches: the next march is at ``done * f`` times
    the resolution (``done``: the latest march's) with the budget left; ``last`` is the
    latest march's :class:`Result`, ``err`` its error estimate, ``n`` the steps of every
    march so far."""

    done: float
    f: float
    err: float
    n: int
    last: Result


@jit(inline="always")
def _refining(a, s, p):
    """The refinement of a point whose first march ``a``, at ``p`` times the resolution
    (:func:`_first_steps`), needs it (:func:`_needs_refining`): checked first against a
    march up to twice its resolution (:data:`FIRST_RATIO_C`)."""
    f = _ratio(a.err, s, FIRST_RATIO_C, FIRST_MIN_RATIO, 2.0)
    return Refining(p, f, a.err, a.n, a)


@jit(inline="always")
def _ratio(err, s, c, lo, hi):
    """Ratio of the next march's resolution to the last one's, for an error ``err`` of the
    last: ``c`` times the one that brings it to the aim at order 5, within ``[lo, hi]``."""
    return min(max(c * (err / (REFINE_MARGIN * s.target)) ** 0.2, lo), hi)


@jit(inline="always")
def _next_march(r, s):
    """Resolution and budget of the next march of the refinement ``r``."""
    return r.done * r.f * s.steps, s.max_steps - r.n


@jit(inline="always")
def _refine_update(r, a, s):
    """The refinement ``r`` after its next march gave ``a``: ``(finished, output, r)``,
    ``output`` the point's ``(e, t_f, u_max, n_steps, status, e_err)`` once finished."""
    # A coarser march than twice the first can still be short of the asymptotic regime,
    # where Richardson misjudges; the budget covers every march. Refined while the
    # resolution-dependent part of the error is above the target, with a margin: near
    # grazing the error can stall between resolutions (seen: a factor 2 from 192 to 384
    # steps, then 500 to 768), where Richardson's estimate falls short.
    aim = REFINE_MARGIN * s.target
    done = r.done * r.f
    n = r.n + a.n
    if a.status == _BUDGET:
        return True, _kept(r.last, n, r.err), r
    err, floor = _richardson(a, r.last, r.f, s.target)
    # Another march needs room for a ratio of at least MIN_RATIO: between marches closer
    # in resolution, Richardson divides a difference of rounding and non-asymptotic
    # wiggles by ratio^p - 1, near 0 (seen: e_err 1769 from marches 1.0000000000000002
    # apart, under the cap, for a linear-law point at tol=1e-10).
    room = MAX_REFINEMENT / done
    if not (err - floor > aim and room >= MIN_RATIO and n < s.max_steps):
        return True, (a.e, a.t_f, a.u_max, n, a.status, err), r
    f = _ratio(err, s, 1.25, MIN_RATIO, room)
    return False, (a.e, a.t_f, a.u_max, n, a.status, err), Refining(done, f, err, n, a)


@jit(inline="always")
def _refined(c, s, a, p, K, K2, Q):
    """Refinement of a point whose first march ``a`` (at ``p`` times the resolution) has an
    indicator above the target, one march after the other (:func:`_refine_update`)."""
    r = _refining(a, s, p)
    while True:
        steps, budget = _next_march(r, s)
        finished, out, r = _refine_update(r, _solve_at(c, steps, s, budget, K, K2, Q), s)
        if finished:
            return out


@jit(inline="always")
def _kept(r, n, err):
    """A march kept when a finer one ran out of budget (a slow creep at g~ = 0 needs
    many steps at every resolution): its result with its error estimate ``err``, and the
    steps of every march."""
    return r.e, r.t_f, r.u_max, n, r.status, err


@cached_jit()
def _kernel(alpha, beta, gamma, gtilde, s, e, t_f, u_max, n_steps, status, e_err):
    """Every point of the arrays, serially: what :func:`solve_point` gives each, its marches
    run :data:`sweep.kernels.lanes.LANES` at a time (:func:`sweep.kernels.lanes.march_lanes`,
    bit-identical to one point's march): first every point's first march, then the march
    at its share of each point whose probe of a stick did not settle it, then each pass of
    refinement over the points still refining; ``nogil``, so that
    :func:`sweep.kernels._parallel.map_blocks` runs blocks of them at once."""
    out = (e, t_f, u_max, n_steps, status, e_err)
    todo = _first_marches(alpha, beta, gamma, gtilde, out)
    m = todo.size
    steps, then = _first_resolutions(alpha, beta, gamma, gtilde, todo, s)
    # Filled by hand: np.full compiles an implementation of its own (0.2 s of first call).
    budget = np.empty(m, np.int64)
    budget[:] = s.max_steps
    ends = _marched(alpha, beta, gamma, gtilde, todo, steps, budget, s)
    # The points still refining, compacted in place after each pass: their indices (the
    # lanes take an array of them) and their Refining states, a row each.
    where = np.empty(m, np.int64)
    rows = np.empty((m, _N_REFINING))
    probed = np.empty(m, np.int64)      # entries of todo whose probe did not settle them
    k = n_probed = 0
    for j in range(m):
        i = todo[j]
        a = _ended(alpha, beta, gamma, gtilde, i, ends, j, steps[j])
        if then[j] > 0.0 and _needs_refining(s, a):
            probed[n_probed] = j
            n_probed += 1
            steps[j], budget[j] = then[j], s.max_steps - a.n
        else:
            k = _sort(s, a, i, steps[j], where, rows, k, out)
    if n_probed > 0:
        k = _after_probes(alpha, beta, gamma, gtilde, s, todo, probed[:n_probed], steps,
                          budget, where, rows, k, out)
    while k > 0:
        k = _refinement_pass(alpha, beta, gamma, gtilde, s, where[:k], rows, out)


@jit(inline="always")
def _sort(s, a, i, steps, where, rows, k, out):
    """Point i's first march (its :class:`Result` ``a``, at resolution ``steps``) to ``out``,
    or, where it needs refining, to row k of the refining points; returns their count."""
    if not _needs_refining(s, a):
        _put(out, i, _as_output(a))
        return k
    where[k] = i
    _put_refining(rows, k, _refining(a, s, steps / s.steps))
    return k + 1


@jit(inline="always")
def _after_probes(alpha, beta, gamma, gtilde, s, todo, probed, steps, budget, where, rows,
                  k, out):
    """The march at its share (``steps``, with the ``budget`` the probe left) of each entry
    ``probed[j]`` of ``todo`` whose probe did not settle it, all at once in lanes, each then
    sorted as a first march (:func:`_sort`); returns the count of refining points."""
    points, at, left = todo[probed], steps[probed], budget[probed]
    ends = _marched(alpha, beta, gamma, gtilde, points, at, left, s)
    for j in range(points.size):
        i = points[j]
        a = _ended(alpha, beta, gamma, gtilde, i, ends, j, at[j])
        k = _sort(s, _plus_steps(a, s.max_steps - left[j]), i, at[j], where, rows, k, out)
    return k


_N_REFINING = 12


@jit(inline="always")
def _put_refining(rows, j, r):
    R = rows
    a = r.last
    R[j, 0], R[j, 1], R[j, 2], R[j, 3] = r.done, r.f, r.err, r.n
    R[j, 4], R[j, 5], R[j, 6], R[j, 7] = a.e, a.t_f, a.u_max, a.n
    R[j, 8], R[j, 9], R[j, 10], R[j, 11] = a.status, a.err, a.e_q, a.e_v


@jit(inline="always")
def _refining_at(rows, j):
    R = rows
    a = Result(R[j, 4], R[j, 5], R[j, 6], int(R[j, 7]), int(R[j, 8]), R[j, 9], R[j, 10],
               R[j, 11])
    return Refining(R[j, 0], R[j, 1], R[j, 2], int(R[j, 3]), a)


@jit(inline="always")
def _first_resolutions(alpha, beta, gamma, gtilde, todo, s):
    """:func:`_first_steps` of each point ``todo[j]``, as two arrays: the exponents'
    constants computed again only where they change (a law's whole draw shares them)."""
    steps = np.empty(todo.size)
    then = np.empty(todo.size)
    k, ka, kb = _NO_CONSTANTS, math.nan, math.nan
    for j in range(todo.size):
        i = todo[j]
        c = make_law(alpha[i], beta[i], gamma[i], gtilde[i])
        if s.from_tol and not (c.alpha == ka and c.beta == kb):
            k, ka, kb = q_constants(c.alpha, c.beta), c.alpha, c.beta
        steps[j], then[j] = _first_steps(c, s, k)
    return steps, then


@jit(inline="always")
def _first_marches(alpha, beta, gamma, gtilde, out):
    """Points decided without a march go to ``out``; returns the others."""
    todo = np.empty(alpha.size, np.int64)
    m = 0
    for i in range(alpha.size):
        decided, r = _without_march(alpha[i], beta[i], gamma[i], gtilde[i])
        if decided:
            _put(out, i, r)
        else:
            todo[m] = i
            m += 1
    return todo[:m]


@jit(inline="always")
def _marched(alpha, beta, gamma, gtilde, todo, steps, budget, s):
    ends = np.empty((todo.size, N_ENDING))
    march_lanes(alpha, beta, gamma, gtilde, todo, steps, budget, s.rest_tol, _negligible(s),
                ends)
    return ends


@jit(inline="always")
def _refinement_pass(alpha, beta, gamma, gtilde, s, where, rows, out):
    """One more march for each refining point (``where[j]``, its Refining in ``rows[j]``),
    all at once in lanes; finished points go to ``out``, the others are compacted to the
    front of ``where`` and ``rows``; returns how many are still refining."""
    m = where.size
    steps = np.empty(m)
    budget = np.empty(m, np.int64)
    for j in range(m):
        steps[j], budget[j] = _next_march(_refining_at(rows, j), s)
    ends = _marched(alpha, beta, gamma, gtilde, where, steps, budget, s)
    k = 0
    for j in range(m):
        i = where[j]
        a = _ended(alpha, beta, gamma, gtilde, i, ends, j, steps[j])
        finished, o, r = _refine_update(_refining_at(rows, j), a, s)
        if finished:
            _put(out, i, o)
        else:
            where[k] = i
            _put_refining(rows, k, r)
            k += 1
    return k


@jit(inline="always")
def _put(out, i, r):
    out[0][i], out[1][i], out[2][i], out[3][i], out[4][i], out[5][i] = r


#: Points per block of a parallel call: as many as leave each thread _BLOCKS_PER_THREAD
#: blocks, for balance, between _BLOCK (~1 ms of work at tol 1e-8, against ~20 us of Python
#: for the block's call) and _BLOCK_MAX. Within a block the lanes march the refinement
#: passes and the marches after failed probes together, and fewer of them are empty in a
#: larger block: 600,000-point core draws at tol 1e-8 on 2 threads, four interleaved rounds,
#: medians: general exponents 265,100 points/s against 252,000 with blocks of 256 always
#: (until 2026-12-05), KK 441,600 against 418,100, Hertz 401,400 against 373,900; the Sobol
#: design end to end (65,536-point chunks, so blocks of 1,024) 159,500 against 156,900.
_BLOCK = 256
_BLOCK_MAX = 4096
_BLOCKS_PER_THREAD = 32
_OUT = ("e", "t_f", "u_max", "n_steps", "status", "e_err")


def _block_size(n, n_threads):
    """Points per block of a parallel call of n points on ``n_threads`` threads."""
    return int(min(_BLOCK_MAX, max(_BLOCK, n // (n_threads * _BLOCKS_PER_THREAD))))


def integrate_arrays(alpha, beta, gamma, gtilde, s, parallel=None):
    """Run the integrator over flat float64 arrays on the CPU.

    Returns
    -------
    dict of str -> ndarray
        One flat array per field of :func:`sweep.registry.kernel_fields`, in its dtype.

    ``s`` is the :class:`Settings` (:func:`settings`); ``parallel=None`` spreads the points
    over threads when :func:`parallel_allowed`. (:mod:`sweep.kernels.devices` chooses between
    this and the CUDA kernel.)
    """
    n = alpha.size
    out = {f.name: np.empty(n, dtype=f.dtype) for f in kernel_fields()}
    cols = [out[name] for name in _OUT]

    def run(lo, hi):
        _kernel(alpha[lo:hi], beta[lo:hi], gamma[lo:hi], gtilde[lo:hi], s,
                *(x[lo:hi] for x in cols))

    if parallel is None:
        parallel = parallel_allowed()
    if parallel and n > _BLOCK:
        # Blocks of contiguous points in a shuffled order: a cluster of costly points (a
        # grid's heavily damped corner) is spread over the threads, while each block reads
        # and writes contiguous memory. A fixed seed keeps the schedule reproducible;
        # results never depend on it.
        map_blocks(run, schedule(n, _block_size(n, threads()), _BLOCK, seed=0x5EED))
    else:
        run(0, n)
    return out
