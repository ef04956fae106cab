"""Several points marching together: the CPU's multi-point driver.

One point's march is a long chain of dependent operations (each stage of a step needs the
one before, each step the one before): a core spends most of its time waiting on the
latency of square roots and divisions. :func:`run_lanes` keeps :data:`LANES` points in
flight and runs stage i of each in turn, so that their independent chains overlap in the
processor (measured 3-4x fewer nanoseconds per step and point than one point at a time).

Everything else is the one-point code: step size (:func:`sweep.kernels.stepsize.first_guess`),
stages (:func:`sweep.kernels.stepper.rk_stage`), and, in the driver
(:func:`sweep.kernels.integrator`), everything after them
(:func:`sweep.kernels.march.finish_step`), the decision
(:func:`sweep.kernels.outcome.decide`) and the refinement of a doubtful point, run for that
point alone. A lane whose point ends takes the next one at once. Results are bit-identical
to one point at a time: the same operations in the same order, per point.

Each lane's law, creep constants, march state and step policy live in one record of a
structured array (:data:`LANE`), read into the named tuples the shared code takes and
written back after each step.

Owns: the multi-point schedule. May import: the other kernels.
"""
from __future__ import annotations

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.contact import Law
from sweep.kernels.creep import Creep
from sweep.kernels.march import State
from sweep.kernels.stepper import N_STAGES, rk_combine, rk_stage
from sweep.kernels.stepsize import StepPolicy, damping_step, first_guess

__all__ = ["LANES", "LANE", "advance_lanes", "lane_law", "lane_creep", "lane_state",
           "put_point", "put_state"]

#: Points in flight per thread (16 and 32 measured a little faster than 8, whose tail at
#: the end of a block is shorter).
LANES = 8

_LAW = [("alpha", "f8"), ("beta", "f8"), ("gamma", "f8"), ("gtilde", "f8"), ("ka", "i8"),
        ("kb", "i8"), ("kd", "i8"), ("smooth", "b1")]
_CREEP = [("kappa", "f8"), ("p_", "f8"), ("u_c", "f8"), ("f_uc", "f8"), ("ubar", "f8"),
          ("u_jump", "f8"), ("u_t", "f8")]
_STATE = [("t", "f8"), ("u", "f8"), ("w", "f8"), ("r", "f8"), ("rc", "f8"), ("v", "f8"),
          ("e0", "f8"), ("q_stuck", "f8"), ("phase", "i8"), ("u_max", "f8"), ("n", "i8"),
          ("lw", "f8"), ("lq", "f8"), ("eip", "b1")]
_POLICY = [("h", "f8"), ("rho", "f8"), ("s_min", "f8"), ("steps", "f8"), ("graded", "b1"),
           ("capped", "b1"), ("local", "b1"), ("omega", "f8")]
#: One lane: the point's index (-1: idle), law, creep constants, march state, step
#: policy, and the step in progress.
LANE = np.dtype([("index", "i8")] + _LAW + _CREEP + _STATE + _POLICY
                + [("s", "f8"), ("u1", "f8"), ("w1", "f8"), ("dr", "f8"), ("n1", "i8")],
                align=True)


@jit(inline="always")
def lane_law(x):
    return Law(x.alpha, x.beta, x.gamma, x.gtilde, x.ka, x.kb, x.kd, x.smooth)


@jit(inline="always")
def lane_creep(x):
    return Creep(x.kappa, x.p_, x.u_c, x.f_uc, x.ubar, x.u_jump, x.u_t)


@jit(inline="always")
def lane_policy(x):
    return StepPolicy(x.h, x.rho, x.s_min, x.steps, x.graded, x.capped, x.local, x.omega)


@jit(inline="always")
def lane_state(x):
    p = lane_policy(x)
    return State(x.t, x.u, x.w, x.r, x.rc, x.v, x.e0, x.q_stuck, x.phase, x.u_max, x.n, x.lw,
                 x.lq, p, x.eip)


@jit(inline="always")
def put_point(x, index, c, k):
    """Lane ``x`` takes point ``index`` with law ``c`` and creep constants ``k``."""
    x.index = index
    x.alpha, x.beta, x.gamma, x.gtilde = c.alpha, c.beta, c.gamma, c.gtilde
    x.ka, x.kb, x.kd, x.smooth = c.ka, c.kb, c.kd, c.smooth
    x.kappa, x.p_, x.u_c, x.f_uc = k.kappa, k.p, k.u_c, k.f_uc
    x.ubar, x.u_jump, x.u_t = k.ubar, k.u_jump, k.u_t


@jit(inline="always")
def put_state(x, st):
    x.t, x.u, x.w, x.r, x.rc, x.v = st.t, st.u, st.w, st.r, st.rc, st.v
    x.e0, x.q_stuck, x.phase, x.u_max, x.n = st.e0, st.q_stuck, st.phase, st.u_max, st.n
    x.lw, x.lq, x.eip = st.lw, st.lq, st.energy_in_phase1
    p = st.p
    x.h, x.rho, x.s_min, x.steps = p.h, p.rho, p.s_min, p.steps
    x.graded, x.capped, x.local, x.omega = p.graded, p.capped, p.local, p.omega


@jit(inline="always")
def _capped_retake(x, c, u1, w1, dr, n, K, max_steps):
    """The damping cap judged at the step's end (as :func:`sweep.kernels.march._advance`):
    retake the step, smaller, while it is exceeded. K[0] still holds f at the start."""
    s = x.s
    s_end = damping_step(u1, c.beta, c.gamma, x.steps)
    while not (s <= 2.0 * s_end and np.isfinite(u1) and np.isfinite(w1)) and n < max_steps:
        s = s_end if s_end < 0.5 * s else 0.5 * s
        for i in range(1, N_STAGES):
            rk_stage(i, x.u, x.w, s, K, c)
        u1, w1, dr = rk_combine(x.u, x.w, s, K)
        n += 1
        s_end = damping_step(u1, c.beta, c.gamma, x.steps)
    x.s = s
    return u1, w1, dr, n


@jit(inline="always")
def advance_lanes(L, K, max_steps):
    """One step of every busy lane (as :func:`sweep.kernels.march._advance` for one
    point): sizes from the policy, stage i of every lane in turn for i = 1 .. 6 (the
    overlap), then each lane's result and damping cap. Leaves the step ``s``, the end
    state ``u1, w1``, the increment ``dr`` of r and the steps counter ``n1`` in the lane."""
    for l in range(L.size):
        x = L[l]
        if x.index >= 0:
            x.s = first_guess(x.u, x.v, lane_policy(x), lane_law(x))
    for i in range(1, N_STAGES):
        for l in range(L.size):
            x = L[l]
            if x.index >= 0:
                rk_stage(i, x.u, x.w, x.s, K[l], lane_law(x))
    for l in range(L.size):
        x = L[l]
        if x.index >= 0:
            u1, w1, dr = rk_combine(x.u, x.w, x.s, K[l])
            n = x.n + 1
            if x.capped:
                u1, w1, dr, n = _capped_retake(x, lane_law(x), u1, w1, dr, n, K[l], max_steps)
            x.u1, x.w1, x.dr, x.n1 = u1, w1, dr, n
