"""Several points marched at once, their Runge-Kutta stages interleaved (the array kernels' march).

One point's march is a chain of dependent operations: each of a step's seven stages waits on
the power of u of the one before, so a core marching one point waits on latency most of the
time (``python benchmarks/lanes.py``). :func:`march_lanes` marches :data:`LANES` points
together: every stage is formed for all lanes before the next
(:func:`sweep.kernels.stepper.rk_step_lanes`), so that the lanes' independent chains
overlap, and everything else of a step -- its size, the damping cap, the events, the
stopping rules -- is the one-point march's own code (:func:`sweep.kernels.stepsize.first_guess`,
:func:`sweep.kernels.march.after_stages_estimated`), run per lane; only the step's local
error estimates are formed with the stages, for all lanes (``rk_step_lanes``). Most
steps need none of that code but their size and the state moved on
(:func:`sweep.kernels.march.uneventful`): those lanes' fields are read and written in
place (:func:`_guessed`, :func:`_moved_on`). A lane
whose march has ended takes the next point (those with general exponents first, whose
stages take their powers by vectors of lanes: :func:`_general_first`).

Per point the operations are exactly those of :func:`sweep.kernels.march.march`, in the same
order: the Endings are bit-identical to it whatever the other lanes hold
(``tests/test_lanes.py``).

A lane's march between two steps is a :class:`~sweep.kernels.march.State`; it is kept in
the rows of a few arrays (:class:`Lanes`) and read back into the named tuple for the steps
that need the march's code.
Inside the march those arrays, and the caller's, are borrowed views (:func:`_borrowed`):
numba updates an array's reference count, an atomic operation, wherever an array variable
is copied, at every inlined call level, and in the lanes' loop, where nothing waits on
latency to hide them, those updates took 70% of the time (``perf``: the ``lock`` of
``NRT_incref`` and ``NRT_decref``); in the one-point march they hide in its latency.

Where every lane of a group of four marches a law of the report (Hertz, TTI, KK, SHC, the
linear law: :func:`sweep.kernels.stepper.vector_groups`, judged when lanes take points),
the group's stages, their combination and local error estimates go as vectors of its
lanes (:func:`sweep.kernels.contact.rhs_vector`): 19-31% more points a second on those
laws (2026-12-05).

Cost (one core, KK, ``python benchmarks/step_cost.py``): 21.2 ns a step (2026-12-05, 14:20
UTC), 28 ns before the vector groups' stages stayed in their scratch and the rare
per-lane paths were called (:func:`_finished`, :func:`_sized_or_ended`), 40 before the
vector groups, 51 before the uneventful steps were moved in place, 48-53 ns on 2026-12-01
(against 78 for one point's march then); the stages, their combination and errors alone
take 16 ns of it (``benchmarks/lanes.py``). Its first compile, the called paths
included, takes about 4 s of the first ``sweep.cor()``'s 12-13 s.

Owns: the multi-point driver and the layout of its lanes. May import: contact, creep,
stepper, stepsize, march, vmath.
"""
from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
from numba.core import types
from numba.extending import intrinsic

from sweep.kernels._jit import jit
from sweep.kernels.contact import (LAW_COLUMNS, general_exponents, gtilde_at, law_at, make_law,
                                   put_law)
from sweep.kernels.creep import Creep, creep_constants
from sweep.kernels.march import (GOING, Ending, State, after_stages_estimated,
                                 carry_last_stage, compensated_sum, out_of_budget, scratch,
                                 start, uneventful)
from sweep.kernels.stepper import N_STAGES, SCRATCH, rk_step_lanes, stages_out, vector_groups
from sweep.kernels.stepsize import (StepPolicy, first_guess, policy, uncapped,
                                    uncapped_guess)
from sweep.kernels.vmath import VECTOR

__all__ = ["LANES", "Lanes", "march_lanes", "ending_at", "N_ENDING"]

#: Points marched at once. 8: the stages of eight lanes fill the core's out-of-order window
#: (KK stages: 74 ns a step for one point, about 25-30 ns a point for eight, before the
#: vector groups). 12 or 16 gave the laws' draws 2-10% more but the Sobol design 4% less
#: (more lanes idle in refinement passes and blocks' tails; docs/speed/history.md). A
#: multiple of four: general lanes take their powers four at a time (rk_step_lanes).
LANES = 8
if LANES % VECTOR:
    raise ImportError(f"LANES ({LANES}) must be a multiple of vmath.VECTOR ({VECTOR})")
#: Columns of an Ending stored in a row (:func:`ending_at`).
N_ENDING = 9
# Columns of a lane's state floats (SF) and ints (SI): the State's fields and its policy's.
_T, _R, _RC, _V, _E0, _QS, _UMAX, _LW, _LQ, _H, _RHO, _SMIN, _STEPS, _OMEGA = range(14)
_PHASE, _N, _EP1, _GRADED, _CAPPED, _LOCAL, _BUDGET = range(7)
# (_BUDGET: the march's step budget, copied when the lane takes its point: read at every
# step through the lane's point, it was a load waiting on a load; 0.8 ns a KK step.)
# Column of the creep constants (CR) that the in-place steps read alone: Creep.ubar.
_UBAR = 4


class Lanes(NamedTuple):
    """The lanes of :func:`march_lanes`, one row (or element) per lane."""

    point: np.ndarray   # int64: entry of ``todo`` the lane marches
    live: np.ndarray    # bool: the lane marches a point
    LF: np.ndarray      # float64 and int64 (LANES, LAW_COLUMNS): laws (contact.put_law)
    LI: np.ndarray
    CR: np.ndarray      # float64 (LANES, 7): creep constants (Creep's fields)
    SF: np.ndarray      # float64 (LANES, 14): state and policy floats (columns above)
    SI: np.ndarray      # int64 (LANES, 7): state and policy ints and flags, step budget
    u: np.ndarray       # float64: the state's u and w, which the stages read
    w: np.ndarray
    h: np.ndarray       # float64: the step about to be taken
    y: np.ndarray       # float64 (5, LANES): its (u_new, w_new, dr), local errors of w, q
    K: np.ndarray       # float64 (LANES, N_STAGES, 3): each lane's stages
    S: np.ndarray       # float64 (SCRATCH LANES): rk_step_lanes's scratch


@intrinsic
def _data(typingctx, arr):
    """Pointer to a C-contiguous array's first element (others are refused when compiled:
    a borrowed view of them would read the wrong elements)."""
    if not (isinstance(arr, types.Array) and arr.layout == "C"):
        raise numba.core.errors.TypingError(f"a C-contiguous array is needed, got {arr}")

    def codegen(context, builder, signature, args):
        return context.make_array(signature.args[0])(context, builder, args[0]).data
    return types.CPointer(arr.dtype)(arr), codegen


@jit(inline="always")
def _borrowed(a):
    """``a`` without ownership: numba updates an array's reference count (an atomic
    operation) wherever its variable is copied, at every inlined call level; in the lanes'
    loop, where nothing waits on latency to hide them, those updates took 70% of the time.
    A view without a memory record skips them. The owner must outlive it."""
    return numba.carray(_data(a), a.shape)


@jit(inline="always")
def _borrow(ln):
    b = _borrowed
    return Lanes(b(ln.point), b(ln.live), b(ln.LF), b(ln.LI), b(ln.CR), b(ln.SF), b(ln.SI),
                 b(ln.u), b(ln.w), b(ln.h), b(ln.y), b(ln.K), b(ln.S))


@jit(inline="always")
def _lanes():
    # np.full and np.zeros would each compile an implementation of their own.
    point = np.empty(LANES, np.int64)
    point[:] = -1
    live = np.empty(LANES, np.bool_)
    live[:] = False
    return Lanes(point, live, np.empty((LANES, LAW_COLUMNS[0])),
                 np.empty((LANES, LAW_COLUMNS[1]), np.int64),
                 np.empty((LANES, 7)), np.empty((LANES, 14)), np.empty((LANES, 7), np.int64),
                 np.empty(LANES), np.empty(LANES), np.empty(LANES), np.empty((5, LANES)),
                 np.empty((LANES, N_STAGES, 3)), np.empty(SCRATCH * LANES))


@jit(inline="always")
def _policy_at(ln, lane):
    f = ln.SF
    n = ln.SI
    return StepPolicy(f[lane, _H], f[lane, _RHO], f[lane, _SMIN], f[lane, _STEPS],
                      n[lane, _GRADED] != 0, n[lane, _CAPPED] != 0, n[lane, _LOCAL] != 0,
                      f[lane, _OMEGA])


@jit(inline="always")
def _state(ln, lane):
    f = ln.SF
    n = ln.SI
    return State(f[lane, _T], ln.u[lane], ln.w[lane], f[lane, _R], f[lane, _RC], f[lane, _V],
                 f[lane, _E0], f[lane, _QS], n[lane, _PHASE], f[lane, _UMAX], n[lane, _N],
                 f[lane, _LW], f[lane, _LQ], _policy_at(ln, lane), n[lane, _EP1] != 0)


@jit(inline="always")
def _put_state(ln, lane, st):
    f = ln.SF
    n = ln.SI
    ln.u[lane] = st.u
    ln.w[lane] = st.w
    f[lane, _T], f[lane, _R], f[lane, _RC], f[lane, _V] = st.t, st.r, st.rc, st.v
    f[lane, _E0], f[lane, _QS], f[lane, _UMAX] = st.e0, st.q_stuck, st.u_max
    f[lane, _LW], f[lane, _LQ] = st.lw, st.lq
    p = st.p
    f[lane, _H], f[lane, _RHO], f[lane, _SMIN] = p.h, p.rho, p.s_min
    f[lane, _STEPS], f[lane, _OMEGA] = p.steps, p.omega
    n[lane, _PHASE], n[lane, _N], n[lane, _EP1] = (st.phase, st.n,
                                                   1 if st.energy_in_phase1 else 0)
    n[lane, _GRADED], n[lane, _CAPPED], n[lane, _LOCAL] = (1 if p.graded else 0,
                                                           1 if p.capped else 0,
                                                           1 if p.local else 0)


@jit(inline="always")
def _put_creep(ln, lane, k):
    C = ln.CR
    C[lane, 0], C[lane, 1], C[lane, 2], C[lane, 3] = k.kappa, k.p, k.u_c, k.f_uc
    C[lane, _UBAR], C[lane, 5], C[lane, 6] = k.ubar, k.u_jump, k.u_t


@jit(inline="always")
def _ubar_at(ln, lane):
    return ln.CR[lane, _UBAR]


@jit(inline="always")
def _creep_at(ln, lane):
    C = ln.CR
    return Creep(C[lane, 0], C[lane, 1], C[lane, 2], C[lane, 3], _ubar_at(ln, lane),
                 C[lane, 5], C[lane, 6])


@jit(inline="always")
def _put_end(E, j, end):
    E[j, 0], E[j, 1], E[j, 2], E[j, 3], E[j, 4] = end.kind, end.t, end.u, end.v, end.h
    E[j, 5], E[j, 6], E[j, 7], E[j, 8] = end.u_max, end.n, end.lw, end.lq


@jit(inline="always")
def ending_at(E, j):
    """The :class:`~sweep.kernels.march.Ending` that :func:`march_lanes` stored in row j."""
    return Ending(int(E[j, 0]), E[j, 1], E[j, 2], E[j, 3], E[j, 4], E[j, 5], int(E[j, 6]),
                  E[j, 7], E[j, 8])


# Called, not inlined (two call sites, once per point; inlined, each copied the start of
# a march into the driver: seconds of compile).
@jit(counted=False)
def _refill(ln, nxt, alpha, beta, gamma, gtilde, todo, steps, budget, order):
    """Idle lanes take the next entries of ``todo`` in the ``order`` of
    :func:`_general_first` (their marches started as march() starts them, with their
    ``steps`` and ``budget``), while there are any; returns the next position in
    ``order``."""
    for lane in range(LANES):
        if ln.live[lane] or nxt >= todo.size:
            continue
        j = order[nxt]
        i = todo[j]
        c = make_law(alpha[i], beta[i], gamma[i], gtilde[i])
        st = start(c, policy(c, steps[j]), ln.K[lane])
        put_law(ln.LF, ln.LI, lane, c)
        _put_creep(ln, lane, creep_constants(c))
        _put_state(ln, lane, st)
        ln.point[lane] = j
        ln.SI[lane, _BUDGET] = budget[j]
        ln.live[lane] = True
        nxt += 1
    return nxt


@jit(inline="always")
def _general_first(alpha, beta, todo):
    """The entries of ``todo``, those with general exponents first
    (:func:`sweep.kernels.contact.general_exponents`), each kind in its order: a stage
    computes the powers of general lanes by vectors of lanes
    (:func:`sweep.kernels.stepper.rk_step_lanes`), each vector whole for one of them, so
    general points spread among the others' lanes would cost about as many calls as
    general lanes all through."""
    order = np.empty(todo.size, np.int64)
    m = 0
    for general in (True, False):
        for j in range(todo.size):
            if general_exponents(alpha[todo[j]], beta[todo[j]]) == general:
                order[m] = j
                m += 1
    return order


@jit(inline="always")
def _any(live):
    for x in live:
        if x:
            return True
    return False


@jit(inline="always")
def _guessed(ln, lane):
    """Where ``lane``'s policy is :func:`~sweep.kernels.stepsize.uncapped` and its budget
    not spent (most steps), its next step's size
    (:func:`~sweep.kernels.stepsize.uncapped_guess`) in ``ln.h`` and True; else False."""
    if ln.SI[lane, _N] >= ln.SI[lane, _BUDGET]:
        return False
    p = _policy_at(ln, lane)
    if not uncapped(p):
        return False
    ln.h[lane] = uncapped_guess(ln.u[lane], ln.SF[lane, _V], p)
    return True


@jit(inline="always")
def _moved_on(ln, lane, rest_tol):
    """Where the step just taken by ``lane`` is :func:`~sweep.kernels.march.uneventful`
    (most steps), its state moved on in place, as
    :func:`~sweep.kernels.march.after_stages_estimated` moves it, and True; else False,
    the lane's state untouched. Read and written back whole, the State's 15 fields and its
    policy's 8 took a fifth of a KK step (51 against 40 ns, ``benchmarks/step_cost.py``)."""
    f = ln.SF
    n = ln.SI
    y = ln.y
    u1, w1, v1 = y[0, lane], y[1, lane], ln.K[lane, N_STAGES - 1, 0]
    r1, rc1 = compensated_sum(f[lane, _R], f[lane, _RC], y[2, lane])
    if not uneventful(n[lane, _PHASE], n[lane, _CAPPED] != 0, u1, w1, v1, r1,
                      n[lane, _EP1] != 0, f[lane, _QS], gtilde_at(ln.LF, lane),
                      _ubar_at(ln, lane), rest_tol):
        return False
    ln.u[lane], ln.w[lane] = u1, w1
    f[lane, _T] = f[lane, _T] + ln.h[lane]
    f[lane, _R], f[lane, _RC], f[lane, _V] = r1, rc1, v1
    f[lane, _LW] = f[lane, _LW] + abs(y[3, lane])
    f[lane, _LQ] = f[lane, _LQ] + abs(y[4, lane])
    n[lane, _N] += 1
    # ln.K[lane] is a view of a borrowed array: it costs no count.
    carry_last_stage(ln.K[lane])
    return True


# The lanes' rare per-lane paths, called, not inlined: inlined, each copied the march's
# step logic into the driver at compile time.
@jit(counted=False)
def _sized_or_ended(ln, lane, ends):
    """Where :func:`_guessed` did not size ``lane``'s step: its size by
    :func:`~sweep.kernels.stepsize.first_guess`, or, its budget spent, its Ending
    (:func:`~sweep.kernels.march.out_of_budget`) stored and the lane idle. Returns whether
    it went idle."""
    st, c = _state(ln, lane), law_at(ln.LF, ln.LI, lane)
    if st.n < ln.SI[lane, _BUDGET]:
        ln.h[lane] = first_guess(st.u, st.v, st.p, c)
        return False
    return _retired(ln, lane, ends, out_of_budget(st, c))


@jit(counted=False)
def _finished(ln, lane, K2, Q, rest_tol, e_tol, ends):
    """Where :func:`_moved_on` did not move ``lane`` on: the rest of march()'s step
    (:func:`~sweep.kernels.march.after_stages_estimated`), its state stored, or, where its
    march ended, its Ending stored and the lane idle. Returns whether it went idle."""
    y = ln.y
    # ln.K[lane] is a view of a borrowed array: it costs no count.
    st, end = after_stages_estimated(
        _state(ln, lane), law_at(ln.LF, ln.LI, lane), _creep_at(ln, lane),
        ln.h[lane], y[0, lane], y[1, lane], y[2, lane], y[3, lane], y[4, lane],
        ln.K[lane], K2, Q, rest_tol, e_tol, ln.SI[lane, _BUDGET])
    if end.kind == GOING:
        _put_state(ln, lane, st)
        return False
    return _retired(ln, lane, ends, end)


@jit(inline="always")
def _retired(ln, lane, ends, end):
    """``lane``'s march over: its Ending in its point's row of ``ends``, the lane idle;
    True (it went idle)."""
    _put_end(ends, ln.point[lane], end)
    ln.live[lane] = False
    return True


# Called only by kernels (tests reach it through a jitted caller): no wrappers, and no
# machine code of its own (sweep.kernels._jit._leave_helpers_unemitted).
@jit()
def march_lanes(alpha, beta, gamma, gtilde, todo, steps, budget, rest_tol, e_tol, ends):
    """March the points ``i = todo[j]`` of the parameter arrays, :data:`LANES` at a time.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : ndarray of float64
        Scaled parameters (2) of the points, valid (:func:`sweep.kernels.contact.in_domain`).
    todo : ndarray of int64
        The points to march.
    steps, budget : ndarray (float64, int64), one per entry of ``todo``
        Resolution (steps per half period) and step budget of each march.
    rest_tol, e_tol : float
        The report's rest criterion and the negligible energy of
        :func:`sweep.kernels.march.march`.
    ends : ndarray of float64, shape (todo.size, N_ENDING)
        Filled: row j holds the Ending of entry j (read it with :func:`ending_at`), the one
        :func:`sweep.kernels.march.march` gives for that point, bit for bit.
    """
    # One function, the step's per-lane parts written out here: every level of inlining
    # copies the march's step logic once more at compile time (seconds).
    own = _lanes()
    _, K2_own, Q_own = scratch()
    b = _borrowed
    ln, K2, Q = _borrow(own), b(K2_own), b(Q_own)
    ends = b(ends)     # the others are read once per point
    order = _general_first(alpha, beta, todo)
    nxt = _refill(ln, np.int64(0), alpha, beta, gamma, gtilde, todo, steps, budget, order)
    vec = vector_groups(ln.LF, ln.LI, ln.S)    # again whenever lanes take points
    while _any(ln.live):
        idle = False
        for lane in range(LANES):      # the step's size, after march()'s budget test
            if ln.live[lane] and not _guessed(ln, lane):
                idle = _sized_or_ended(ln, lane, ends) or idle
        if not idle:
            rk_step_lanes(ln.u, ln.w, ln.h, ln.K, ln.LF, ln.LI, ln.live, ln.y, ln.S, vec)
            for lane in range(LANES):  # the rest of march()'s step
                if ln.live[lane] and not _moved_on(ln, lane, rest_tol):
                    if vec >> (lane - lane % VECTOR) & 1:
                        stages_out(ln.K, ln.S, lane)
                    idle = _finished(ln, lane, K2, Q, rest_tol, e_tol, ends) or idle
        if idle:
            nxt = _refill(ln, nxt, alpha, beta, gamma, gtilde, todo, steps, budget, order)
            vec = vector_groups(ln.LF, ln.LI, ln.S)
    # The owners live until the borrowed views are done with.
    own.live[0] = K2_own[0, 0] == Q_own[0, 0]
