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
(no damping cap, event or rule at their ends): those are done for groups of four lanes as
vectors, the lanes' fields read and written in place (:func:`_guessed_group`,
:func:`_moved_on_group`; the State's fields are rows of the lanes). A lane whose march has
ended takes the next point (those with general exponents first, whose stages take their
powers by vectors of lanes: :func:`_general_first`).

Per point the operations are exactly those of :func:`sweep.kernels.march.march`, in the same
order: the Endings are bit-identical to it whatever the other lanes hold
(``tests/test_lanes.py``).

A lane's march between two steps is a :class:`~sweep.kernels.march.State`; it is kept in
the columns of a few arrays (:class:`Lanes`), each field a row of the lanes, and read back
into the named tuple for the steps that need the march's code.
Inside the march those arrays, and the caller's, are borrowed views (:func:`_clothed`):
numba updates an array's reference count, an atomic operation, wherever an array variable
is copied, at every inlined call level, and in the lanes' loop, where nothing waits on
latency to hide them, those updates took 70% of the time (``perf``: the ``lock`` of
``NRT_incref`` and ``NRT_decref``); in the one-point march they hide in its latency.

Where every lane of a group of four marches a law of the report (Hertz, TTI, KK, SHC, the
linear law: :func:`sweep.kernels.stepper.vector_groups`, judged when lanes take points),
the group's stages, their combination and local error estimates go as vectors of its
lanes (:func:`sweep.kernels.contact.rhs_vector`): 19-31% more points a second on those
laws (2026-12-05).

A vector group's lanes carry their first stage (first-same-as-last) in the scratch of
:func:`~sweep.kernels.stepper.rk_step_lanes`, not in ``K``: only the lanes whose step took
the march's whole path, took a new point, or joined a vector group take theirs from ``K``
(``fresh`` in :func:`march_lanes`), and a group that stops being one writes its lanes'
back (:func:`_regrouped`).

Cost (one core, KK, ``python benchmarks/step_cost.py``): 15.9 ns a step with 12 lanes
(2026-12-05, 17:55 UTC; the stages, their combination and errors 13.2 ns of it), 18.2-18.5
ns with 8 (15:45 UTC), 19.5-20 before the first stages were carried in the scratch, 21.2
before the moves and sizes went as vectors, 28 ns before the vector groups' stages stayed
in their scratch and the rare per-lane paths were called (:func:`_finished`,
:func:`_sized_or_ended`), 40 before the vector groups, 51 before the uneventful steps were
moved in place, 48-53 ns on 2026-12-01 (against 78 for one point's march then); with 8
lanes the stages, their combination and errors alone took 16 ns of it
(``benchmarks/lanes.py``). Its first
compile, the called paths included, takes about 4 s of the first ``sweep.cor()``'s 12-15 s.

Owns: the multi-point driver and the layout of its lanes. May import: contact, creep,
stepper, stepsize, march, vmath.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic
from numba.np.arrayobj import populate_array

from sweep.kernels._jit import jit
from sweep.kernels.contact import (LAW_COLUMNS, equilibrium, general_exponents, gtilde_rows,
                                   law_at, make_law, put_law, umax_undamped_many)
from sweep.kernels.creep import ROUNDING_V, Creep, creep_constants_at, creep_kappa
from sweep.kernels.march import (GOING, SCRATCH_SHAPES, Ending, State, after_stages_estimated,
                                 carry_last_stage, out_of_budget, scratch, start)
from sweep.kernels.stepper import (N_STAGES, SCRATCH, carry_in_scratch, rk_step_lanes,
                                   stages_out, vector_groups)
from sweep.kernels.stepsize import StepPolicy, first_guess, policy_at
from sweep.kernels.vmath import (EVERY_ELEMENT, VECTOR, ieq_bits, ilt_bits, vabs, vadd, vdiv,
                                 veq_bits, vgather, vge_bits, vgt_bits, vle_bits, vload, vlt_bits,
                                 vmul, vnan_bits, vselect_bits, vstore, vsub)

__all__ = ["LANES", "Lanes", "march_lanes", "ending_at", "equilibrium_at", "N_ENDING"]

#: Points marched at once: 12, three vector groups whose stages' chains overlap. 8 (two
#: groups) until 2026-12-05 17:55 UTC: 12 or 16 then gave the laws' draws 0-10% more but the
#: Sobol design 4% less (more lanes idle in refinement passes and blocks' tails). Once the
#: per-point work outside the stages had shrunk (phase 2's end on the vector path, fewer
#: pows a point), 12 gave, one core, paired runs: KK 4.6% and TTI 7.6% less time a point,
#: general exponents 0.6% more; two cores: KK +4-5%, TTI +6-8% (the one law whose stages
#: wait on two nested roots), general -2%, the Sobol design -1%; 16: KK -2%, TTI -6%,
#: general +1.5% (docs/speed/history.md). A multiple of four: general lanes take their
#: powers four at a time (rk_step_lanes).
LANES = 12
if LANES % VECTOR:
    raise ImportError(f"LANES ({LANES}) must be a multiple of vmath.VECTOR ({VECTOR})")
#: Columns of a row of ``ends``: an Ending's nine (:func:`ending_at`), then the point's
#: u-bar (:func:`equilibrium_at`), which its decision reads.
N_ENDING = 10
_ENDING_UBAR = 9
# Rows of the lanes' state floats (SF) and ints (SI): the State's fields and its policy's,
# each a row of the lanes, so that a group of lanes reads and writes a field as a vector.
_T, _R, _RC, _V, _E0, _QS, _UMAX, _LW, _LQ, _H, _RHO, _SMIN, _STEPS, _OMEGA = range(14)
_PHASE, _N, _EP1, _GRADED, _CAPPED, _LOCAL, _BUDGET, _CREEP_KNOWN = range(8)
# (_BUDGET: the march's step budget, copied when the lane takes its point: read at every
# step through the lane's point, it was a load waiting on a load; 0.8 ns a KK step.)
# Row of the creep constants (CR) that the in-place steps read alone: Creep.ubar.
_UBAR = 4


class Lanes(NamedTuple):
    """The lanes of :func:`march_lanes`, one row (or element) per lane."""

    point: np.ndarray   # int64: entry of ``todo`` the lane marches
    live: np.ndarray    # bool: the lane marches a point
    LF: np.ndarray      # float64 and int64 (LANES, LAW_COLUMNS): laws (contact.put_law)
    LI: np.ndarray
    CR: np.ndarray      # float64 (7, LANES): creep constants (Creep's fields)
    SF: np.ndarray      # float64 (14, LANES): state and policy floats (rows above)
    SI: np.ndarray      # int64 (8, LANES): state and policy ints and flags, step budget,
    #                     whether CR holds all the creep constants (_deferred_creep)
    u: np.ndarray       # float64: the state's u and w, which the stages read
    w: np.ndarray
    h: np.ndarray       # float64: the step about to be taken
    y: np.ndarray       # float64 (5, LANES): its (u_new, w_new, dr), local errors of w, q
    K: np.ndarray       # float64 (LANES, N_STAGES, 3): each lane's stages
    S: np.ndarray       # float64 (SCRATCH LANES): rk_step_lanes's scratch
    um: np.ndarray      # float64, one per entry of todo: its u_M (umax_undamped_many)


@intrinsic
def _data(typingctx, arr):
    """Pointer to a C-contiguous array's first element (others are refused when compiled:
    a borrowed view of them would read the wrong elements)."""
    if not (isinstance(arr, types.Array) and arr.layout == "C"):
        raise numba.core.errors.TypingError(f"a C-contiguous array is needed, got {arr}")

    def codegen(context, builder, signature, args):
        return context.make_array(signature.args[0])(context, builder, args[0]).data
    return types.CPointer(arr.dtype)(arr), codegen


#: Shapes of the arrays of :class:`Lanes`, in its order, but ``um`` (one per point): made by
#: :func:`_lanes`, viewed again from bare pointers by :func:`_clothed`.
_SHAPES = (LANES, LANES, (LANES, LAW_COLUMNS[0]), (LANES, LAW_COLUMNS[1]), (7, LANES),
           (14, LANES), (8, LANES), LANES, LANES, LANES, (5, LANES), (LANES, N_STAGES, 3),
           SCRATCH * LANES)


@jit(inline="always")
def _lanes(um):
    # np.full and np.zeros would each compile an implementation of their own.
    S, i = _SHAPES, np.int64
    point = np.empty(S[0], i)
    point[:] = -1
    live = np.empty(S[1], np.bool_)
    live[:] = False
    return Lanes(point, live, np.empty(S[2]), np.empty(S[3], i), np.empty(S[4]),
                 np.empty(S[5]), np.empty(S[6], i), np.empty(S[7]), np.empty(S[8]),
                 np.empty(S[9]), np.empty(S[10]), np.empty(S[11]), np.empty(S[12]), um)


class _Bare(NamedTuple):
    """The lanes and the march's K2, Q and Endings as bare data pointers, and the march's
    number of points ``n``: the one argument of the called per-lane paths, which view them
    again (:func:`_clothed`; the shapes are constants but n). Passed as arrays (each its
    pointer, owner, sizes, shape and strides), a call took 127-174 arguments, most of them
    stored to the stack and read back, at every step of a lane whose damping cap can bind:
    heavily damped KK lost 40% of its speed when those paths were called instead of
    inlined (128,700 -> 69,900 points/s, ``benchmarks/damped.py``'s draw, 2026-12-07)."""

    lanes: tuple     # data pointers of the arrays of Lanes, in its order
    K2: object       # data pointers of march()'s re-step stages, dense output, Endings
    Q: object
    ends: object
    n: int


@jit(inline="always")
def _bare(ln, K2, Q, ends):
    d = _data
    return _Bare((d(ln.point), d(ln.live), d(ln.LF), d(ln.LI), d(ln.CR), d(ln.SF), d(ln.SI),
                  d(ln.u), d(ln.w), d(ln.h), d(ln.y), d(ln.K), d(ln.S), d(ln.um)),
                 d(K2), d(Q), d(ends), ends.shape[0])


def _shape(s):
    return (s,) if isinstance(s, int) else tuple(s)


def _viewed(context, builder, ptr_type, ptr, dims):
    """A C-contiguous array without owner over the data at ``ptr`` (a CPointer), of shape
    ``dims`` (LLVM intp values): :func:`_data`'s converse, in a codegen."""
    array = types.Array(ptr_type.dtype, len(dims), "C")
    out = context.make_array(array)(context, builder)
    intp = types.intp
    itemsize = context.get_constant(intp, context.get_abi_sizeof(
        context.get_data_type(ptr_type.dtype)))
    strides = [itemsize]
    for d in reversed(dims[1:]):
        strides.insert(0, builder.mul(strides[0], d))
    populate_array(out, data=builder.bitcast(ptr, out.data.type), shape=dims,
                   strides=strides, itemsize=itemsize, meminfo=None)
    return out._getvalue()


@intrinsic
def _clothed(typingctx, bare):
    """``(ln, K2, Q, ends)``: the arrays of a :class:`_Bare`, viewed again (borrowed), their
    shapes :data:`_SHAPES`, :data:`~sweep.kernels.march.SCRATCH_SHAPES` and ``bare.n``.
    One intrinsic, not a view per array (numba's ``carray``, or an intrinsic each): those
    cost the first compile their front end at each of the three call sites, and a helper
    compiled without reference counts may not call ``carray``'s function at all."""
    if not (isinstance(bare, types.BaseNamedTuple) and bare.instance_class is _Bare):
        raise numba.core.errors.TypingError(f"a lanes._Bare is needed, got {bare}")
    _, k2, q = SCRATCH_SHAPES
    # Shapes as Python tuples, None for a dimension of n (um: (n,), ends: (n, N_ENDING)).
    shapes = [_shape(s) for s in _SHAPES] + [(None,), _shape(k2), _shape(q),
                                             (None, N_ENDING)]
    kinds = [*bare.types[0].types, *bare.types[1:4]]
    arrays = [types.Array(k.dtype, len(s), "C") for k, s in zip(kinds, shapes)]
    lanes_type = types.NamedTuple(arrays[:len(Lanes._fields)], Lanes)
    result = types.Tuple((lanes_type, *arrays[len(Lanes._fields):]))

    def codegen(context, builder, signature, args):
        intp, packed = types.intp, args[0]
        at_n = _Bare._fields.index("n")      # the fields: lanes, K2, Q, ends, n
        n = context.cast(builder, builder.extract_value(packed, at_n), bare.types[at_n], intp)
        lanes = builder.extract_value(packed, 0)
        ptrs = [builder.extract_value(lanes, j) for j in range(len(Lanes._fields))]
        ptrs += [builder.extract_value(packed, j) for j in range(1, at_n)]
        views = [_viewed(context, builder, k, ptr, [n if d is None else
                                                      context.get_constant(intp, d) for d in s])
                 for k, ptr, s in zip(kinds, ptrs, shapes)]
        ln = context.make_tuple(builder, lanes_type, views[:len(Lanes._fields)])
        return context.make_tuple(builder, result, [ln, *views[len(Lanes._fields):]])
    return result(bare), codegen


@jit(inline="always")
def _policy_at(ln, lane):
    f = ln.SF
    n = ln.SI
    return StepPolicy(f[_H, lane], f[_RHO, lane], f[_SMIN, lane], f[_STEPS, lane],
                      n[_GRADED, lane] != 0, n[_CAPPED, lane] != 0, n[_LOCAL, lane] != 0,
                      f[_OMEGA, lane])


@jit(inline="always")
def _state(ln, lane):
    f = ln.SF
    n = ln.SI
    return State(f[_T, lane], ln.u[lane], ln.w[lane], f[_R, lane], f[_RC, lane], f[_V, lane],
                 f[_E0, lane], f[_QS, lane], n[_PHASE, lane], f[_UMAX, lane], n[_N, lane],
                 f[_LW, lane], f[_LQ, lane], _policy_at(ln, lane), n[_EP1, lane] != 0)


@jit(inline="always")
def _put_state(ln, lane, st):
    f = ln.SF
    n = ln.SI
    ln.u[lane] = st.u
    ln.w[lane] = st.w
    f[_T, lane], f[_R, lane], f[_RC, lane], f[_V, lane] = st.t, st.r, st.rc, st.v
    f[_E0, lane], f[_QS, lane], f[_UMAX, lane] = st.e0, st.q_stuck, st.u_max
    f[_LW, lane], f[_LQ, lane] = st.lw, st.lq
    p = st.p
    f[_H, lane], f[_RHO, lane], f[_SMIN, lane] = p.h, p.rho, p.s_min
    f[_STEPS, lane], f[_OMEGA, lane] = p.steps, p.omega
    n[_PHASE, lane], n[_N, lane], n[_EP1, lane] = (st.phase, st.n,
                                                   1 if st.energy_in_phase1 else 0)
    n[_GRADED, lane], n[_CAPPED, lane], n[_LOCAL, lane] = (1 if p.graded else 0,
                                                           1 if p.capped else 0,
                                                           1 if p.local else 0)


@jit(inline="always")
def _put_creep(ln, lane, k):
    C = ln.CR
    C[0, lane], C[1, lane], C[2, lane], C[3, lane] = k.kappa, k.p, k.u_c, k.f_uc
    C[_UBAR, lane], C[5, lane], C[6, lane] = k.ubar, k.u_jump, k.u_t


@jit(inline="always")
def _deferred_creep(ln, lane, c, ubar):
    """A new point's creep constants in ``lane``: u-bar, which every step reads, and, where
    kappa = 0, the others (no power); else those wait for the step whose end the creep
    rules may judge (:func:`_creep_known`). Most lightly damped beads never come there: 3
    pows a KK point less."""
    if creep_kappa(c) == 0.0:
        _put_creep(ln, lane, creep_constants_at(c, ubar))
        ln.SI[_CREEP_KNOWN, lane] = 1
    else:
        # NaN until they are known, not the lane's previous point's.
        nan = math.nan
        _put_creep(ln, lane, Creep(nan, nan, nan, nan, ubar, nan, nan))
        ln.SI[_CREEP_KNOWN, lane] = 0


@jit(inline="always")
def _creep_known(ln, lane, c, v1, w1):
    """``lane``'s creep constants whole where the rules may read them at the end of the step
    just taken (ended at velocity ``v1`` and ``w1``): ``march._creep_rules_apply`` holds
    there only with v1 + w1 >= 0, or where the damping cap may retake the step."""
    if ln.SI[_CREEP_KNOWN, lane] == 0 and (ln.SI[_CAPPED, lane] != 0 or v1 + w1 >= 0.0):
        _put_creep(ln, lane, creep_constants_at(c, ln.CR[_UBAR, lane]))
        ln.SI[_CREEP_KNOWN, lane] = 1


@jit(inline="always")
def _creep_at(ln, lane):
    C = ln.CR
    return Creep(C[0, lane], C[1, lane], C[2, lane], C[3, lane], C[_UBAR, lane],
                 C[5, lane], C[6, lane])


@jit(inline="always")
def _put_end(E, j, end):
    E[j, 0], E[j, 1], E[j, 2], E[j, 3], E[j, 4] = end.kind, end.t, end.u, end.v, end.h
    E[j, 5], E[j, 6], E[j, 7], E[j, 8] = end.u_max, end.n, end.lw, end.lq


@jit(inline="always")
def ending_at(E, j):
    """The :class:`~sweep.kernels.march.Ending` that :func:`march_lanes` stored in row j."""
    return Ending(int(E[j, 0]), E[j, 1], E[j, 2], E[j, 3], E[j, 4], E[j, 5], int(E[j, 6]),
                  E[j, 7], E[j, 8])


@jit(inline="always")
def equilibrium_at(E, j):
    """u-bar of the point whose march :func:`march_lanes` stored in row j: the
    :func:`~sweep.kernels.contact.equilibrium` its lane marched with, bit for bit."""
    return E[j, _ENDING_UBAR]


# Called, not inlined (two call sites, once per point; inlined, each copied the start of
# a march into the driver: seconds of compile).
@jit(counted=False)
def _refill(bare, nxt, alpha, beta, gamma, gtilde, todo, steps, budget, order):
    """Idle lanes take the next entries of ``todo`` in the ``order`` of
    :func:`_general_first` (their marches started as march() starts them, with their
    ``steps`` and ``budget``), while there are any; returns the next position in
    ``order``. ``bare``: the lanes' :class:`_Bare`."""
    ln = _clothed(bare)[0]
    for lane in range(LANES):
        if ln.live[lane] or nxt >= todo.size:
            continue
        j = order[nxt]
        i = todo[j]
        c = make_law(alpha[i], beta[i], gamma[i], gtilde[i])
        ubar = equilibrium(c.alpha, c.gtilde)
        st = start(c, policy_at(c, steps[j], ubar, ln.um[j]), ln.K[lane])
        put_law(ln.LF, ln.LI, lane, c)
        _deferred_creep(ln, lane, c, ubar)
        _put_state(ln, lane, st)
        ln.point[lane] = j
        ln.SI[_BUDGET, lane] = budget[j]
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


_ALL = EVERY_ELEMENT
_EVERY_LANE = (1 << LANES) - 1


@jit(inline="always")
def _live_bits(ln, first):
    """Bit k set where lane ``first + k`` marches a point."""
    bits = 0
    for k in range(VECTOR):
        if ln.live[first + k]:
            bits |= 1 << k
    return bits


@jit(inline="always")
def _live_lanes(ln):
    """Bit l set where lane l marches a point."""
    bits = 0
    for first in range(0, LANES, VECTOR):
        bits |= _live_bits(ln, first) << first
    return bits


@jit(inline="always")
def _lanes_of(groups):
    """Bits of the lanes of the groups whose first lane's bit is set in ``groups``."""
    bits = 0
    for first in range(0, LANES, VECTOR):
        if groups >> first & 1:
            bits |= _ALL << first
    return bits


@jit(inline="always")
def _regrouped(ln, vec, fresh):
    """The :func:`~sweep.kernels.stepper.vector_groups` of the lanes after they took
    points (``vec`` before) and the lanes whose first stage is in K (``fresh`` before):
    the lanes of a group that turned vector are (their steps carried it in K so far); those
    of a group that did not stay vector get theirs from the scratch."""
    now = vector_groups(ln.LF, ln.LI, ln.S)
    out = _lanes_of(vec & ~now) & ~fresh
    for lane in range(LANES):
        if out >> lane & 1:
            stages_out(ln.K, ln.S, lane)
    return now, fresh | _lanes_of(now & ~vec) | out


@jit(inline="always")
def _guessed_group(ln, first):
    """The next step's size (:func:`~sweep.kernels.stepsize.uncapped_guess`) in ``ln.h``
    for the live lanes of the :data:`~sweep.kernels.vmath.VECTOR` lanes ``first ..`` whose
    policy is :func:`~sweep.kernels.stepsize.uncapped` and budget not spent (most steps),
    as vectors, whatever their laws (the size reads only the policy); returns the bits of
    the live lanes it did not size. Lane by lane, the sizes took 17% of the lanes' loop
    (``perf``, 2026-12-05)."""
    n = LANES
    live = _live_bits(ln, first)
    f, i = ln.SF, ln.SI
    sized = live & ilt_bits(i, _N * n + first, _BUDGET * n + first) \
        & ieq_bits(i, _CAPPED * n + first, 0) & ieq_bits(i, _LOCAL * n + first, 0)
    h = vload(f, _H * n + first)
    # stepsize.graded_step's operations, in its order.
    rho, u = vload(f, _RHO * n + first), vload(ln.u, first)
    av = vabs(vload(f, _V * n + first))
    s = vdiv(vmul(rho, u), av)
    s_min = vload(f, _SMIN * n + first)
    graded = vselect_bits(vge_bits(vmul(rho, u), vmul(h, av)), h,
                          vselect_bits(vgt_bits(s, s_min), s, s_min))
    guess = vselect_bits(_ALL & ~ieq_bits(i, _GRADED * n + first, 0), graded, h)
    vstore(ln.h, first, vselect_bits(sized, guess, vload(ln.h, first)))
    return live & ~sized


@jit(inline="always")
def _eventful_bits(ln, first, u1, w1, v1, r1, rest_tol):
    """``(eventful, crossed)``: bits of the lanes ``first ..`` whose step, ended at ``(u1,
    w1, v1, r1)`` (vectors), may need more than the state moved on: the damping cap on, or
    one of the march's tests true (``march._may_have_event``, ``_creep_rules_apply``,
    ``_may_settle``: their operations, as bit masks), or a NaN in the state or the static
    compression (where Python's ``max`` and these masks could disagree: the lane takes the
    whole step's path, which is right for every step); and of those whose only event is
    phase 2's end, u-bar crossed downward with neither the floor reached nor the bead
    turned in the step (``march._located`` then only sets phase 3: no location, the rules
    as at any step, which read phase 2 and 3 alike)."""
    n = LANES
    i = ln.SI
    p1 = ieq_bits(i, _PHASE * n + first, 1)
    p2 = ieq_bits(i, _PHASE * n + first, 2)
    p3 = ieq_bits(i, _PHASE * n + first, 3)
    capped = _ALL & ~ieq_bits(i, _CAPPED * n + first, 0)
    ubar = vload(ln.CR, _UBAR * n + first)
    crossed = p2 & vgt_bits(ubar, 0.0) & vlt_bits(u1, ubar)
    crossed_only = crossed & vgt_bits(u1, 0.0) & vlt_bits(v1, 0.0)
    event = (p1 & vle_bits(v1, vmul(ROUNDING_V, vabs(w1))) | p2 & veq_bits(ubar, 0.0)
             & vle_bits(u1, 0.0) | crossed & ~crossed_only
             | p3 & (vle_bits(u1, 0.0) | vge_bits(v1, 0.0)))
    later = _ALL & ~p1
    creep = (later | capped) & vge_bits(vadd(v1, w1), 0.0)
    rest = vlt_bits(vabs(vsub(u1, ubar)), rest_tol) & vlt_bits(vabs(v1), rest_tol)
    spent = (later | _ALL & ~ieq_bits(i, _EP1 * n + first, 0)) & vgt_bits(
        vadd(vmul(v1, vsub(w1, v1)), r1), vload(ln.SF, _QS * n + first))
    settle = rest | spent
    if settle:
        # Only under a load (the laws' g~, gathered where it matters: rarely).
        settle &= vgt_bits(gtilde_rows(ln.LF, first), 0.0)
    nan = vnan_bits(u1) | vnan_bits(w1) | vnan_bits(v1) | vnan_bits(r1) | vnan_bits(ubar)
    eventful = capped | _ALL & ~(p1 | p2 | p3) | event | creep | settle | nan
    return eventful, crossed_only & ~eventful


@jit(inline="always")
def _moved_on_group(ln, first, rest_tol, vector):
    """Where the step just taken by a live lane of the :data:`~sweep.kernels.vmath.VECTOR`
    lanes ``first ..`` needs nothing more (:func:`_eventful_bits`; most steps), its state
    moved on in place, as :func:`~sweep.kernels.march.after_stages_estimated` moves it, as
    vectors (``vector``: their stages are in ``ln.S``, :func:`rk_step_lanes`); returns the
    bits of the live lanes it did not move on, their states untouched. Read and written
    back whole, the State's 15 fields and its policy's 8 took a fifth of a KK step (51
    against 40 ns, ``benchmarks/step_cost.py``); lane by lane in place, 27% of the lanes'
    loop (``perf``, 2026-12-05)."""
    n = LANES
    live = _live_bits(ln, first)
    f, y = ln.SF, ln.y
    u1, w1 = vload(y, first), vload(y, n + first)
    last = 3 * (N_STAGES - 1)
    v1 = (vload(ln.S, last * n + first) if vector else
          vgather(ln.K, first * 3 * N_STAGES + last, 3 * N_STAGES))
    # march.compensated_sum's operations.
    r, rc = vload(f, _R * n + first), vload(f, _RC * n + first)
    d = vsub(vload(y, 2 * n + first), rc)
    r1 = vadd(r, d)
    eventful, crossed = _eventful_bits(ln, first, u1, w1, v1, r1, rest_tol)
    moved = live & ~eventful
    if moved == 0:
        return live
    if crossed != 0:
        _entered_phase3(ln, first, moved & crossed)
    vstore(ln.u, first, vselect_bits(moved, u1, vload(ln.u, first)))
    vstore(ln.w, first, vselect_bits(moved, w1, vload(ln.w, first)))
    _vput(f, _T * n + first, moved, vadd(vload(f, _T * n + first), vload(ln.h, first)))
    _vput(f, _R * n + first, moved, r1)
    _vput(f, _RC * n + first, moved, vsub(vsub(r1, r), d))
    _vput(f, _V * n + first, moved, v1)
    _vput(f, _LW * n + first, moved, vadd(vload(f, _LW * n + first),
                                           vabs(vload(y, 3 * n + first))))
    _vput(f, _LQ * n + first, moved, vadd(vload(f, _LQ * n + first),
                                           vabs(vload(y, 4 * n + first))))
    if vector:
        carry_in_scratch(ln.S, first, moved)
    for k in range(VECTOR):
        if moved >> k & 1:
            ln.SI[_N, first + k] += 1
            if not vector:
                # ln.K[lane] is a view of a borrowed array: it costs no count.
                carry_last_stage(ln.K[first + k])
    return live & ~moved


@jit(inline="always")
def _entered_phase3(ln, first, bits):
    """Phase 3 for the lanes ``first + k`` of the bits k of ``bits``."""
    for k in range(VECTOR):
        if bits >> k & 1:
            ln.SI[_PHASE, first + k] = 3


@jit(inline="always")
def _vput(a, at, bits, x):
    """``a.flat[at + k] = x[k]`` where bit k of ``bits`` is set."""
    vstore(a, at, vselect_bits(bits, x, vload(a, at)))


# The lanes' rare per-lane paths, called, not inlined: inlined, each copied the march's
# step logic into the driver at compile time. Rare but for a lane whose damping cap can
# bind, which takes both at every step: hence their one argument, the lanes' _Bare.
@jit(counted=False)
def _sized_or_ended(bare, lane):
    """Where :func:`_guessed_group` did not size ``lane``'s step: its size by
    :func:`~sweep.kernels.stepsize.first_guess`, or, its budget spent, its Ending
    (:func:`~sweep.kernels.march.out_of_budget`) stored and the lane idle. Returns whether
    it went idle. ``bare``: the lanes' :class:`_Bare`."""
    ln, _, _, ends = _clothed(bare)
    st, c = _state(ln, lane), law_at(ln.LF, ln.LI, lane)
    if st.n < ln.SI[_BUDGET, lane]:
        ln.h[lane] = first_guess(st.u, st.v, st.p, c)
        return False
    return _retired(ln, lane, ends, out_of_budget(st, c))


@jit(counted=False)
def _finished(bare, lane, rest_tol, e_tol):
    """Where :func:`_moved_on_group` did not move ``lane`` on: the rest of march()'s step
    (:func:`~sweep.kernels.march.after_stages_estimated`), its state stored, or, where its
    march ended, its Ending stored and the lane idle. Returns whether it went idle.
    ``bare``: the lanes' :class:`_Bare`."""
    ln, K2, Q, ends = _clothed(bare)
    y = ln.y
    c = law_at(ln.LF, ln.LI, lane)
    _creep_known(ln, lane, c, ln.K[lane, N_STAGES - 1, 0], y[1, lane])
    # ln.K[lane] is a view of a borrowed array: it costs no count.
    st, end = after_stages_estimated(
        _state(ln, lane), c, _creep_at(ln, lane),
        ln.h[lane], y[0, lane], y[1, lane], y[2, lane], y[3, lane], y[4, lane],
        ln.K[lane], K2, Q, rest_tol, e_tol, ln.SI[_BUDGET, lane])
    if end.kind == GOING:
        _put_state(ln, lane, st)
        return False
    return _retired(ln, lane, ends, end)


@jit(inline="always")
def _retired(ln, lane, ends, end):
    """``lane``'s march over: its Ending in its point's row of ``ends``, the lane idle;
    True (it went idle)."""
    _put_end(ends, ln.point[lane], end)
    ends[ln.point[lane], _ENDING_UBAR] = ln.CR[_UBAR, lane]
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
        :func:`sweep.kernels.march.march` gives for that point, bit for bit, and the
        point's u-bar (:func:`equilibrium_at`).
    """
    # One function, the step's per-lane parts written out here: every level of inlining
    # copies the march's step logic once more at compile time (seconds).
    # u_M of all the points at once, called: inlined here, its loops and allocations cost
    # the lanes' loop 3-5% (its code laid out anew).
    own = _lanes(umax_undamped_many(alpha, gtilde, todo))
    _, K2_own, Q_own = scratch()
    # Borrowed views of them (the others are read once per point): numba updates an array's
    # reference count (an atomic operation) wherever its variable is copied, at every
    # inlined call level; in the lanes' loop, where nothing waits on latency to hide them,
    # those updates took 70% of the time. Views without a memory record skip them.
    bare = _bare(own, K2_own, Q_own, ends)
    ln, K2, Q, ends = _clothed(bare)
    order = _general_first(alpha, beta, todo)
    nxt = _refill(bare, np.int64(0), alpha, beta, gamma, gtilde, todo, steps, budget, order)
    vec = vector_groups(ln.LF, ln.LI, ln.S)    # again whenever lanes take points
    fresh = _EVERY_LANE     # lanes whose first stage is in K, not in the scratch
    while _any(ln.live):
        idle = False
        for first in range(0, LANES, VECTOR):  # the step's size, after march()'s budget test
            left = _guessed_group(ln, first)
            for k in range(VECTOR):
                if left >> k & 1:
                    idle = _sized_or_ended(bare, first + k) or idle
        if not idle:
            rk_step_lanes(ln.u, ln.w, ln.h, ln.K, ln.LF, ln.LI, ln.live, ln.y, ln.S, vec,
                          fresh)
            fresh = 0
            for first in range(0, LANES, VECTOR):  # the rest of march()'s step
                vector = vec >> first & 1 != 0
                left = _moved_on_group(ln, first, rest_tol, vector)
                for k in range(VECTOR):
                    if left >> k & 1:
                        if vector:
                            stages_out(ln.K, ln.S, first + k)
                        idle = _finished(bare, first + k, rest_tol, e_tol) or idle
                        fresh |= 1 << (first + k)     # its next first stage is in K
        if idle:
            was = _live_lanes(ln)
            nxt = _refill(bare, nxt, alpha, beta, gamma, gtilde, todo, steps, budget, order)
            fresh |= _live_lanes(ln) & ~was          # new points: their first stage in K
            vec, fresh = _regrouped(ln, vec, fresh)
    # The owners live until the borrowed views are done with.
    own.live[0] = K2_own[0, 0] == Q_own[0, 0]
