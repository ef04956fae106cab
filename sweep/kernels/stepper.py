"""One explicit Runge-Kutta step of the report's system (4) and its dense output.

The system in the Lipschitz form of Sec. 3 (state ``(u, w)``, velocity ``v = w - gamma u_+^beta``)::

    u' = w - gamma u_+^beta        w' = g~ - u_+^alpha

The stage loop is written once against the tableau arrays of :mod:`sweep.kernels.tableau`
(module constants, which numba folds into the compiled code); the right-hand side is the
contact law's (:mod:`sweep.kernels.contact`); step-size choice and event logic live
elsewhere.

Owns: the Runge-Kutta step and the dense output. May import: tableau, contact, vmath.
"""
from __future__ import annotations

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.contact import (general_arguments, general_at, rhs, rhs_at, rhs_called,
                                   rhs_general, rhs_vector, vector_law, vector_law_at)
from sweep.kernels.tableau import DORMAND_PRINCE_54
from sweep.kernels.vmath import (EVERY_ELEMENT, VECTOR, exp4, log4, vadd, vdot, vgather, vload,
                                 vmul, vpack, vselect_bits, vstore)

__all__ = ["rk_step", "rk_step_inline", "rk_step_lanes", "SCRATCH", "vector_groups",
           "stages_out", "carry_in_scratch", "rk_stage", "stage_point", "rk_combine",
           "local_error", "dense_coefficients", "dense_eval", "N_STAGES", "N_DENSE"]

_T = DORMAND_PRINCE_54
_A = np.ascontiguousarray(_T.A)
_B = np.ascontiguousarray(_T.B)
_P = np.ascontiguousarray(_T.P)
_E = np.ascontiguousarray(_T.E)
N_STAGES = _A.shape[0]
N_DENSE = _P.shape[1]


@jit(inline="always")
def _one(K, j, c, lane):
    return K[j, c]


@jit(inline="always")
def _lane(K, j, c, lane):
    # Indexed in place, not through the view K[lane]: a view of an array that owns its
    # memory costs two atomic reference count updates (sweep.kernels.lanes).
    return K[lane, j, c]


def _stage_point_of(at):
    """:func:`stage_point` reading the stages through ``at(K, j, component, lane)``."""

    def stage_point(i, u, w, h, K, lane=0):
        """The state where stage ``i >= 1`` of a step ``h`` from ``(u, w)`` evaluates f:
        ``(u, w) + h sum_j A[i, j] K[j]`` over the stages ``j < i`` already in ``K`` (for a
        three-dimensional K, those of lane ``lane``: ``K[lane, j]``)."""
        du = 0.0
        dw = 0.0
        for j in range(i):
            a = _A[i, j]
            du += a * at(K, j, 0, lane)
            dw += a * at(K, j, 1, lane)
        return u + h * du, w + h * dw

    return stage_point


def _combine_of(at):
    """:func:`rk_combine` reading the stages through ``at(K, j, component, lane)``."""

    def rk_combine(u, w, h, K, lane=0):
        """The step's result from its stages: ``(u_new, w_new, dr)``, with ``dr`` the
        increment of the dissipation integral r (returned alone so that the caller can sum
        it with compensation); for a three-dimensional K, of lane ``lane``'s stages."""
        du = 0.0
        dw = 0.0
        dq = 0.0
        for j in range(N_STAGES):
            b = _B[j]
            du += b * at(K, j, 0, lane)
            dw += b * at(K, j, 1, lane)
            dq += b * at(K, j, 2, lane)
        return u + h * du, w + h * dw, h * dq

    return rk_combine


#: One point's stages ``K[j]``, and the lanes' ``K[lane, j]`` (the same arithmetic).
stage_point = jit(inline="always")(_stage_point_of(_one))
rk_combine = jit(inline="always")(_combine_of(_one))
_stage_point_lane = jit(inline="always")(_stage_point_of(_lane))
_combine_lane = jit(inline="always")(_combine_of(_lane))


@jit(inline="always")
def _store(K, i, fu, fw, fq):
    K[i, 0] = fu
    K[i, 1] = fw
    K[i, 2] = fq


@jit(inline="always")
def rk_stage(i, u, w, h, K, c):
    """Stage ``i >= 1`` of a step ``h`` from ``(u, w)``: fills ``K[i]`` from ``K[0..i-1]``
    (for drivers that interleave the stages of several points, benchmarks/lanes.py)."""
    ui, wi = stage_point(i, u, w, h, K)
    fu, fw, fq = rhs(ui, wi, c)
    _store(K, i, fu, fw, fq)


def _step_with(f):
    """The Runge-Kutta step evaluating the right-hand side with ``f`` (:func:`rk_step`)."""

    def step(u, w, h, K, c):
        """Advance ``(u, w)`` by one step ``h`` of the contact law ``c`` (a ``Law``);
        returns ``(u_new, w_new, dr)`` (:func:`rk_combine`).

        ``K[0]`` must hold ``f(u, w)`` on entry (first-same-as-last); on exit ``K`` holds
        all stages, ``K[-1] = f(u_new, w_new)`` for the FSAL tableau.
        """
        # The stage written out (not rk_stage): each level of inlining copies the
        # right-hand side's IR once more at compile time.
        for i in range(1, N_STAGES):
            ui, wi = stage_point(i, u, w, h, K)
            fu, fw, fq = f(ui, wi, c)
            _store(K, i, fu, fw, fq)
        return rk_combine(u, w, h, K)

    return step


#: The step compiled once and called, with the right-hand side called too: for the rare
#: re-steps (event location, the damping cap's retaken steps), where inlining either would
#: compile the seven stages' powers at every call site for no speed.
rk_step = jit(counted=False)(_step_with(rhs_called))
#: The step with its right-hand side inlined, itself inlined into its one caller, the
#: march's step: 25-30% less time per step (KK, SHC; 162 -> 120 ns on one core, the stages'
#: results no longer cross a call boundary) for about 3 s more of first compile.
rk_step_inline = jit(inline="always")(_step_with(rhs))


#: Scratch of :func:`rk_step_lanes` per lane: its stages' three components, then the
#: step's start (u, w), size and law (:func:`~sweep.kernels.contact.vector_law`'s four).
SCRATCH = 3 * N_STAGES + 7
_U0, _W0, _H0, _LAW = range(3 * N_STAGES, 3 * N_STAGES + 4)


@jit(inline="always")
def rk_step_lanes(u, w, h, K, LF, LI, live, y, S, vec, fresh):
    """:func:`rk_step` for several points at once: lane ``l`` (where ``live[l]``) steps
    ``(u[l], w[l])`` by ``h[l]`` with the law in row ``l`` of ``LF, LI``
    (:func:`sweep.kernels.contact.rhs_at`), its stages in ``K[l]`` (``K[l, 0]`` = f at the
    start on entry), its ``(u_new, w_new, dr)`` in ``y[:3, l]`` and the step's local error
    estimates of w and q (:func:`local_error`) in ``y[3:5, l]``; the number of lanes a
    multiple of four (:func:`_general_stage`). ``S``: scratch, :data:`SCRATCH` times the
    lanes; ``vec``: the lanes' :func:`vector_groups`, run on ``S`` since their laws last
    changed.

    The lanes of a vector group keep their stages in ``S``, not ``K``, until
    :func:`stages_out`, and take the first stage from ``S`` too (the caller carries the
    last stage there, :func:`carry_in_scratch`), but for those whose bit is set in
    ``fresh``: theirs is in ``K[l, 0]`` (a new point, a step after events).

    Each stage is formed for every lane before the next: the lanes' chains of dependent
    operations (each stage waits on the power of u of the one before) overlap, where one
    point's chain leaves the core waiting on latency (``benchmarks/lanes.py``). Groups of
    lanes whose laws :func:`~sweep.kernels.contact.rhs_vector` takes go as vectors
    (:func:`_vector_stage`, :func:`_vector_combine`). Per lane the arithmetic is
    :func:`rk_step`'s and :func:`local_error`'s, operation for operation.
    """
    _vectors_in(vec, fresh, u, w, h, K, S)
    for i in range(1, N_STAGES):
        pending = 0
        for first in range(0, live.size, VECTOR):
            if vec >> first & 1:
                _vector_stage(i, first, K, S)
                continue
            for lane in range(first, first + VECTOR):
                if live[lane]:
                    ui, wi = _stage_point_lane(i, u[lane], w[lane], h[lane], K, lane)
                    if ui > 0.0 and general_at(LI, lane):
                        # Its log and exps come with the other lanes' (_general_stage).
                        K[lane, i, 0], K[lane, i, 1] = ui, wi
                        pending |= 1 << lane
                    else:
                        K[lane, i, 0], K[lane, i, 1], K[lane, i, 2] = rhs_at(ui, wi, LF, LI,
                                                                             lane)
        if pending:
            _general_stage(i, K, LF, pending)
    for first in range(0, live.size, VECTOR):
        if vec >> first & 1:
            _vector_combine(first, y, S)
            continue
        for lane in range(first, first + VECTOR):
            if live[lane]:
                y[0, lane], y[1, lane], y[2, lane] = _combine_lane(u[lane], w[lane], h[lane],
                                                                   K, lane)
                # K[lane] is a view of a borrowed array (sweep.kernels.lanes): no count.
                _, y[3, lane], y[4, lane] = local_error(K[lane], h[lane])


# Called, not inlined: once per refill of the lanes, and each inlined copy cost compile time.
@jit(counted=False)
def vector_groups(LF, LI, S):
    """Bit ``first`` set for each group of :data:`~sweep.kernels.vmath.VECTOR` lanes
    ``first ..`` whose laws (rows of ``LF, LI``) all take
    :func:`~sweep.kernels.contact.rhs_vector`: :func:`rk_step_lanes` forms their stages as
    vectors. Idle lanes count too: their results are not read. Those groups' laws are
    stored in ``S`` (:func:`_vectors_in`): a lane's law changes only where it takes a
    point, so the caller runs this then, not at every step."""
    vec = 0
    n = LI.shape[0]
    for first in range(0, n, VECTOR):
        ok = True
        for lane in range(first, first + VECTOR):
            ok = ok and vector_law_at(LI, lane)
        if ok:
            vec |= 1 << first
            kd, beta, gamma, gtilde = vector_law(LF, LI, first)
            vstore(S, _LAW * n + first, kd)
            vstore(S, (_LAW + 1) * n + first, beta)
            vstore(S, (_LAW + 2) * n + first, gamma)
            vstore(S, (_LAW + 3) * n + first, gtilde)
    return vec


@jit(inline="always")
def _vectors_in(vec, fresh, u, w, h, K, S):
    """The step of the groups of ``vec`` stored in ``S`` as vectors, and the first stage of
    their lanes set in ``fresh`` (the others' is there already, as are their laws:
    :func:`carry_in_scratch`, :func:`vector_groups`).

    ``S`` holds rows of the lanes, row r of the lanes ``first ..`` at ``r n + first`` (n
    lanes): stage j's u, w and q components in rows 3j to 3j + 2, then the rows from _U0
    on. (Index arithmetic written out, not in helpers: each inlined call costs compile
    time.)"""
    n = K.shape[0]
    for first in range(0, n, VECTOR):
        if vec >> first & 1:
            # Gathered element by element (vgather): the lanes' steps store them so.
            stride = K.shape[1] * K.shape[2]
            bits = fresh >> first & EVERY_ELEMENT
            if bits:
                for c in range(3):
                    vstore(S, c * n + first, vselect_bits(
                        bits, vgather(K, first * stride + c, stride), vload(S, c * n + first)))
            vstore(S, _U0 * n + first, vgather(u, first, 1))
            vstore(S, _W0 * n + first, vgather(w, first, 1))
            vstore(S, _H0 * n + first, vgather(h, first, 1))


@jit(inline="always")
def _vector_stage(i, first, K, S):
    """Stage ``i`` of the lanes ``first ..`` as vectors: the stage point as
    :func:`stage_point`'s from the stages before in ``S`` (:func:`_vectors_in`), the forces
    of :func:`~sweep.kernels.contact.rhs_vector`, stored in ``S`` and ``K``."""
    n = K.shape[0]
    du = dw = vpack(0.0)
    for j in range(i):
        a = _A[i, j]
        du = vadd(du, vmul(a, vload(S, 3 * j * n + first)))
        dw = vadd(dw, vmul(a, vload(S, (3 * j + 1) * n + first)))
    h = vload(S, _H0 * n + first)
    law = (vload(S, _LAW * n + first), vload(S, (_LAW + 1) * n + first),
           vload(S, (_LAW + 2) * n + first), vload(S, (_LAW + 3) * n + first))
    f = rhs_vector(vadd(vload(S, _U0 * n + first), vmul(h, du)),
                   vadd(vload(S, _W0 * n + first), vmul(h, dw)), law)
    fu, fw, fq = f
    vstore(S, 3 * i * n + first, fu)
    vstore(S, (3 * i + 1) * n + first, fw)
    vstore(S, (3 * i + 2) * n + first, fq)


@jit(inline="always")
def stages_out(K, S, lane):
    """The stages of ``lane``'s step, a lane of a vector group of :func:`rk_step_lanes`,
    from the scratch ``S`` into ``K[lane]``, where the lane's step needs them (events,
    rules; stored there at every step, they were the 18 stores and the gather of the
    first stage of each lane's step)."""
    n = K.shape[0]
    for j in range(N_STAGES):
        for comp in range(3):
            K[lane, j, comp] = S[(3 * j + comp) * n + lane]


@jit(inline="always")
def carry_in_scratch(S, first, bits):
    """The next step's first stage is this one's last (first-same-as-last) for the lanes
    ``first + k`` of a vector group whose bit k is set in ``bits``, in the scratch ``S``
    of :func:`rk_step_lanes` (their ``K`` is not written)."""
    n = S.size // SCRATCH
    last = 3 * (N_STAGES - 1)
    for c in range(3):
        vstore(S, c * n + first, vselect_bits(bits, vload(S, (last + c) * n + first),
                                              vload(S, c * n + first)))


# The weights as tuples, for vdot.
_B_TERMS = tuple(float(b) for b in _B)
_E_TERMS = tuple(float(d) for d in _E)


@jit(inline="always")
def _vector_combine(first, y, S):
    """:func:`rk_combine` and :func:`local_error` of the lanes ``first ..`` as vectors,
    from their stages in ``S`` (:func:`_vectors_in`), into their rows of ``y``."""
    n = y.shape[1]
    du = vdot(S, first, 3 * n, _B_TERMS)
    dw = vdot(S, n + first, 3 * n, _B_TERMS)
    dq = vdot(S, 2 * n + first, 3 * n, _B_TERMS)
    ew = vdot(S, n + first, 3 * n, _E_TERMS)
    eq = vdot(S, 2 * n + first, 3 * n, _E_TERMS)
    h = vload(S, _H0 * n + first)
    vstore(y, first, vadd(vload(S, _U0 * n + first), vmul(h, du)))
    vstore(y, n + first, vadd(vload(S, _W0 * n + first), vmul(h, dw)))
    vstore(y, 2 * n + first, vmul(h, dq))
    vstore(y, 3 * n + first, vmul(h, ew))
    vstore(y, 4 * n + first, vmul(h, eq))


# Lanes whose powers go to the vector functions together: vmath's 4-tuples, built and
# taken apart in registers.
_GROUP = 4


@jit(inline="always")
def _general_stage(i, K, LF, pending):
    """Stage ``i`` of the lanes whose bits are set in ``pending`` (general exponents, u > 0,
    their stage point in ``K[lane, i, :2]``), :data:`_GROUP` lanes at a time
    (:func:`_general_group`; ``K.shape[0]`` a multiple of it). A group without a pending
    lane is skipped: lanes of the report's models among general ones cost no calls."""
    for first in range(0, K.shape[0], _GROUP):
        bits = pending >> first & (1 << _GROUP) - 1
        if bits:
            _general_group(i, K, LF, bits, first)


@jit(inline="always")
def _general_group(i, K, LF, bits, first):
    """:func:`_general_stage` for the lanes ``first + k`` whose bit ``k`` is set in
    ``bits``: their log and two exps each in one vector call (:mod:`sweep.kernels.vmath`;
    the other lanes take log 1 and exp 0), then their forces, as
    :func:`sweep.kernels.contact.rhs` gives them. The arguments travel as tuples, in
    registers: written to an array lane by lane and read back as one vector, each call's
    arguments waited on a failed store-to-load forwarding (``perf``: 8% of the lanes' time
    on the two stalls at the log's and the first exp's loads)."""
    lu = log4((_u_or_one(K, i, bits, first, 0), _u_or_one(K, i, bits, first, 1),
               _u_or_one(K, i, bits, first, 2), _u_or_one(K, i, bits, first, 3)))
    a0 = _arguments_or_zero(LF, bits, first, 0, lu[0])
    a1 = _arguments_or_zero(LF, bits, first, 1, lu[1])
    a2 = _arguments_or_zero(LF, bits, first, 2, lu[2])
    a3 = _arguments_or_zero(LF, bits, first, 3, lu[3])
    pd = exp4((a0[0], a1[0], a2[0], a3[0]))
    pa = exp4((a0[1], a1[1], a2[1], a3[1]))
    _put_forces(i, K, LF, bits, first, 0, pd[0], pa[0])
    _put_forces(i, K, LF, bits, first, 1, pd[1], pa[1])
    _put_forces(i, K, LF, bits, first, 2, pd[2], pa[2])
    _put_forces(i, K, LF, bits, first, 3, pd[3], pa[3])


@jit(inline="always")
def _u_or_one(K, i, bits, first, k):
    return K[first + k, i, 0] if bits >> k & 1 else 1.0


@jit(inline="always")
def _arguments_or_zero(LF, bits, first, k, lu):
    # The other lanes' laws may be stale rows (an infinite exponent would make a NaN,
    # which libmvec takes the slow way).
    if bits >> k & 1:
        return general_arguments(LF, first + k, lu)
    return 0.0, 0.0


@jit(inline="always")
def _put_forces(i, K, LF, bits, first, k, pd, pa):
    if bits >> k & 1:
        lane = first + k
        K[lane, i, 0], K[lane, i, 1], K[lane, i, 2] = rhs_general(
            K[lane, i, 0], K[lane, i, 1], LF, lane, pd, pa)


@jit(inline="always")
def local_error(K, h):
    """Local error estimate ``h sum_i E_i K_i`` of the step just taken (all stages in ``K``):
    the difference between the propagated and the embedded solution, per component."""
    eu = 0.0
    ew = 0.0
    eq = 0.0
    for j in range(N_STAGES):
        d = _E[j]
        eu += d * K[j, 0]
        ew += d * K[j, 1]
        eq += d * K[j, 2]
    return h * eu, h * ew, h * eq


@jit(inline="always")
def dense_coefficients(K, h, Q, components=2):
    """Fill ``Q[c, j] = h * sum_i K[i, c] P[i, j]`` for c = u, w (the events need no q), or
    for u alone with ``components`` 1 (an event of u alone: the floor, u-bar)."""
    for c in range(components):
        for j in range(N_DENSE):
            s = 0.0
            for i in range(N_STAGES):
                s += K[i, c] * _P[i, j]
            Q[c, j] = h * s


@jit(inline="always")
def dense_eval(u0, w0, Q, theta):
    """State at fraction ``theta`` of the step: ``y0 + sum_j Q[:, j] theta^(j+1)``."""
    u = 0.0
    w = 0.0
    for j in range(N_DENSE - 1, -1, -1):
        u = (u + Q[0, j]) * theta
        w = (w + Q[1, j]) * theta
    return u0 + u, w0 + w
