"""Numerical CoR: a fixed-step Runge-Kutta march of (4) with the three phases of Algorithm 1.

Per point (scaled parameters ``alpha, beta, gamma, g~``) the bead starts at ``u = 0``,
``w = 1`` and is marched with the base step of :mod:`sweep.stepsize` (graded near u = 0).
Phases (report, Sec. 3 and Algorithm 1):

1. until ``v = 0`` crossing downward -- maximum compression ``u_max``;
2. until ``u = u-bar`` crossing downward (with ``g~ = 0``, ``u-bar = 0`` and this is the
   detachment itself);
3. until ``u v = 0``: ``u = 0`` -> detachment, ``e = -v``; ``v = 0`` with ``u > 0`` -> the bead
   sticks, ``e = 0``.

Each event is bracketed by a sign test at the step's ends, located on the step's interpolant
(:mod:`sweep.events`) and refined with full Runge-Kutta steps from the step's start (Newton
on the re-stepped state), so located times and states carry the method's own accuracy.
Grazing (u dipping below 0 inside one step and coming back) is caught in phase 3 through the
velocity's sign change: the minimum of u at ``v = 0`` decides between sticking and detachment.

Two extra stopping rules keep every point bounded:

* rest: ``max(|u - u-bar|, |v|) < rest_tol`` -> ``e = 0``, status AT_REST (report, Sec. 3);
* energy: ``H = v^2/2 + u_+^(alpha+1)/(alpha+1) - g~ u`` never increases
  (``dH/dtau = -gamma beta u^(beta-1) v^2``) and equals ``e^2/2 >= 0`` at a detachment, so
  once ``H < 0`` (beyond roundoff) the bead can never leave the floor: ``e = 0``, status STUCK.
  This is what ends overdamped points that creep towards u-bar. It is applied from phase 2 on,
  and in phase 1 only when the linearisation about u-bar is overdamped (``xi >= 1``), where
  phase 1 may never end; such points report ``u_max = NaN`` (maximum not reached).

A point that exhausts ``max_steps`` stops with status BUDGET_EXHAUSTED and ``e = sqrt(2 H)``:
the energy still available bounds the rebound speed, so this is an upper bound of the CoR
(tiny for the slow creep back to u = 0 of heavily damped points at g~ = 0), not a converged
value.

Conditioning: e is what is left of the energy after the bead swings through a potential well
of depth ``|V(u-bar)| ~ g~^(1 + 1/alpha)``, so roundoff alone limits its absolute accuracy to
about ``eps |V(u-bar)| sqrt(n_steps) / e`` -- 1e-3 at g~ = 1e6 for the linear law, for any
double-precision integrator. Near the stick/rebound boundary e ~ sqrt(dip depth) amplifies
every absolute error by about 1/e.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from sweep._parallel import parallel_allowed
from sweep.events import ON_U, ON_V, locate
from sweep.model import Status
from sweep.stepper import N_DENSE, N_STAGES, dense_coefficients, power_kind, ppow, rhs, rk_step
from sweep.stepsize import (GRADE_FIRST, GRADE_RATIO, base_step, damping_limited, damping_step,
                            graded_step, needs_grading)

__all__ = ["integrate_arrays", "DEFAULT_STEPS", "DEFAULT_MAX_STEPS", "DEFAULT_REST_TOL"]

#: Steps per half period of the stiffest linearised motion (see :mod:`sweep.stepsize`).
DEFAULT_STEPS = 96
#: Step budget per point (all Runge-Kutta steps, refinements included).
DEFAULT_MAX_STEPS = 200_000
#: Rest tolerance of the report (Sec. 3).
DEFAULT_REST_TOL = 1e-8

_OK = int(Status.OK)
_STUCK = int(Status.STUCK)
_AT_REST = int(Status.AT_REST)
_BUDGET = int(Status.BUDGET_EXHAUSTED)
_INVALID = int(Status.INVALID)

# Relative size of roundoff in the energy H: the stuck rule waits until H is below it.
_ENERGY_ROUNDOFF = 1e-13


@nb.njit(inline="always")
def _restep(u, w, d, K, K2, alpha, beta, gamma, gtilde, ka, kb):
    """State at time ``d`` after the step's start, by one Runge-Kutta step of size ``d``."""
    K2[0, 0] = K[0, 0]
    K2[0, 1] = K[0, 1]
    return rk_step(u, w, d, K2, alpha, beta, gamma, gtilde, ka, kb)


@nb.njit(inline="always")
def _accel(u, v, alpha, beta, gamma, gtilde, ka, kb):
    """``dv/dtau = g~ - u^alpha - gamma beta u^(beta-1) v`` for u >= 0."""
    return gtilde - ppow(u, alpha, ka) - gamma * beta * ppow(u, beta - 1.0, power_kind(beta - 1.0)) * v


@nb.njit
def _detach(u, w, s, th_lo, th_hi, Q, K, K2, alpha, beta, gamma, gtilde, ka, kb):
    """Refine the detachment u = 0 inside ``[th_lo, th_hi]`` of the step from ``(u, w)``.

    Returns ``(time from the step's start, e, re-steps used)``.
    """
    th = locate(ON_U, 0.0, u, w, Q, beta, gamma, kb, th_lo, th_hi)
    lo = th_lo * s
    hi = th_hi * s
    d = th * s
    used = 0
    ue = 0.0
    ve = -1.0
    for _ in range(12):
        ue, we = _restep(u, w, d, K, K2, alpha, beta, gamma, gtilde, ka, kb)
        used += 1
        ve = we - gamma * ppow(ue, beta, kb)
        if ue > 0.0:
            lo = d
        else:
            hi = d
        dn = d - ue / ve if ve < 0.0 else 0.5 * (lo + hi)
        if not (lo <= dn <= hi):
            dn = 0.5 * (lo + hi)
        if abs(dn - d) <= 2e-16 * d or hi - lo <= 2e-16 * d:
            d = dn
            break
        d = dn
    # The last Newton correction is O(u_e) and within roundoff; apply it to v to first order.
    delta = -ue / ve if ve < 0.0 else 0.0
    v_f = ve + delta * (gtilde - ppow(ue, alpha, ka))
    return d, max(-v_f, 0.0), used


@nb.njit
def integrate_point(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, K, K2, Q):
    """Numerical CoR of one point; returns ``(e, t_f, u_max, n_steps, status)``.

    ``K``, ``K2`` (stages, shape (s, 2)) and ``Q`` (dense output, shape (2, q)) are scratch.
    """
    nan = np.nan
    if not (alpha >= 1.0 and beta >= 1.0 and gamma >= 0.0 and gtilde >= 0.0
            and math.isfinite(alpha) and math.isfinite(beta)
            and math.isfinite(gamma) and math.isfinite(gtilde)):
        return nan, nan, nan, 0, _INVALID
    ka = power_kind(alpha)
    kb = power_kind(beta)
    ubar = gtilde ** (1.0 / alpha) if gtilde > 0.0 else 0.0
    h = base_step(alpha, gtilde, steps)
    capped = damping_limited(alpha, beta, gamma, gtilde)
    graded = needs_grading(alpha, beta)
    s_min = GRADE_FIRST * h
    xi = gamma * beta / (2.0 * math.sqrt(alpha)) * gtilde ** ((2.0 * beta - alpha - 1.0) / (2.0 * alpha)) \
        if gtilde > 0.0 else 0.0
    energy_in_phase1 = xi >= 1.0
    ap1 = alpha + 1.0

    t = 0.0
    u = 0.0
    w = 1.0
    fu, fw = rhs(u, w, alpha, beta, gamma, gtilde, ka, kb)
    K[0, 0] = fu
    K[0, 1] = fw
    v = w
    phase = 1
    u_max = nan
    n = 0
    fu0 = fu
    fw0 = fw
    while True:
        if n >= max_steps:
            # The energy still available bounds the rebound speed: e <= sqrt(2 H).
            big_h = 0.5 * v * v + ppow(u, alpha, ka) * max(u, 0.0) / ap1 - gtilde * u
            return math.sqrt(max(2.0 * big_h, 0.0)), t, u_max, n, _BUDGET
        s = graded_step(u, v, h, GRADE_RATIO, s_min) if graded else h
        if capped:
            # Judge the cap where the step may take the bead (speed and load push it deeper).
            for _ in range(3):
                s = min(s, damping_step(u + s * max(v, 0.0) + 0.5 * s * s * gtilde, beta, gamma, steps))
            fu0 = K[0, 0]
            fw0 = K[0, 1]
        u1, w1 = rk_step(u, w, s, K, alpha, beta, gamma, gtilde, ka, kb)
        n += 1
        if capped:
            # A load can drive the bead deep into the damper within one step: judge the cap
            # at the step's end too and retake the step if it was exceeded (twice: slack
            # against retaking steps for nothing).
            s_end = damping_step(u1, beta, gamma, steps)
            while not (s <= 2.0 * s_end and math.isfinite(u1) and math.isfinite(w1)) and n < max_steps:
                s = s_end if s_end < 0.5 * s else 0.5 * s
                K[0, 0] = fu0
                K[0, 1] = fw0
                u1, w1 = rk_step(u, w, s, K, alpha, beta, gamma, gtilde, ka, kb)
                n += 1
                s_end = damping_step(u1, beta, gamma, steps)
        v1 = w1 - gamma * ppow(u1, beta, kb)
        th0 = 0.0
        have_q = False
        if phase == 1 and v1 <= 0.0:
            dense_coefficients(K, s, Q)
            have_q = True
            th0 = locate(ON_V, 0.0, u, w, Q, beta, gamma, kb, 0.0, 1.0)
            um, wm = _restep(u, w, th0 * s, K, K2, alpha, beta, gamma, gtilde, ka, kb)
            n += 1
            vm = wm - gamma * ppow(um, beta, kb)
            acc = _accel(um, vm, alpha, beta, gamma, gtilde, ka, kb)
            # u is stationary here: the vertex of the local parabola removes the residual v.
            u_max = um - 0.5 * vm * vm / acc if acc < 0.0 else um
            phase = 2
        if phase == 2:
            if ubar > 0.0:
                if u1 < ubar:
                    if not have_q:
                        dense_coefficients(K, s, Q)
                        have_q = True
                    th0 = locate(ON_U, ubar, u, w, Q, beta, gamma, kb, th0, 1.0)
                    phase = 3
            elif u1 <= 0.0:
                # g~ = 0: the return to u-bar = 0 is the detachment.
                if not have_q:
                    dense_coefficients(K, s, Q)
                d, e, used = _detach(u, w, s, th0, 1.0, Q, K, K2, alpha, beta, gamma, gtilde, ka, kb)
                return e, t + d, u_max, n + used, _OK
        if phase == 3:
            if u1 <= 0.0:
                if not have_q:
                    dense_coefficients(K, s, Q)
                d, e, used = _detach(u, w, s, th0, 1.0, Q, K, K2, alpha, beta, gamma, gtilde, ka, kb)
                return e, t + d, u_max, n + used, _OK
            if v1 >= 0.0:
                if not have_q:
                    dense_coefficients(K, s, Q)
                    have_q = True
                thv = locate(ON_V, 0.0, u, w, Q, beta, gamma, kb, th0, 1.0)
                us, ws = _restep(u, w, thv * s, K, K2, alpha, beta, gamma, gtilde, ka, kb)
                n += 1
                vs = ws - gamma * ppow(us, beta, kb)
                acc = _accel(us, vs, alpha, beta, gamma, gtilde, ka, kb)
                u_min = us - 0.5 * vs * vs / acc if acc > 0.0 else us
                if u_min > 0.0:
                    return 0.0, t + thv * s, u_max, n, _STUCK
                # Grazing: u dipped below 0 inside the step, so the bead left the floor first.
                d, e, used = _detach(u, w, s, th0, thv, Q, K, K2, alpha, beta, gamma, gtilde, ka, kb)
                return e, t + d, u_max, n + used, _OK
        t += s
        u = u1
        w = w1
        v = v1
        K[0, 0] = K[N_STAGES - 1, 0]
        K[0, 1] = K[N_STAGES - 1, 1]
        if max(abs(u - ubar), abs(v)) < rest_tol:
            if phase == 1:
                u_max = max(u, ubar)
            return 0.0, t, u_max, n, _AT_REST
        if gtilde > 0.0 and (phase > 1 or energy_in_phase1):
            pot = ppow(u, alpha, ka) * max(u, 0.0) / ap1
            kin = 0.5 * v * v
            if kin + pot - gtilde * u < -_ENERGY_ROUNDOFF * (kin + pot + gtilde * abs(u)):
                return 0.0, t, u_max, n, _STUCK


@nb.njit
def _run_range(lo, hi, order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
               e, t_f, u_max, n_steps, status):
    K = np.empty((N_STAGES, 2))
    K2 = np.empty((N_STAGES, 2))
    Q = np.empty((2, N_DENSE))
    for j in range(lo, hi):
        i = order[j]
        r = integrate_point(alpha[i], beta[i], gamma[i], gtilde[i], steps, rest_tol, max_steps, K, K2, Q)
        e[i] = r[0]
        t_f[i] = r[1]
        u_max[i] = r[2]
        n_steps[i] = r[3]
        status[i] = r[4]


# Points are taken in blocks from a shuffled order: costs vary by orders of magnitude
# (sticking ends early, heavy damping runs long) and prange splits the range evenly.
_BLOCK = 64


@nb.njit(parallel=True, cache=True)
def _kernel_parallel(order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
                     e, t_f, u_max, n_steps, status):
    n = order.size
    nblocks = (n + _BLOCK - 1) // _BLOCK
    for b in nb.prange(nblocks):
        _run_range(b * _BLOCK, min(n, (b + 1) * _BLOCK), order, alpha, beta, gamma, gtilde,
                   steps, rest_tol, max_steps, e, t_f, u_max, n_steps, status)


@nb.njit(cache=True)
def _kernel_serial(order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
                   e, t_f, u_max, n_steps, status):
    _run_range(0, order.size, order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
               e, t_f, u_max, n_steps, status)


def integrate_arrays(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, parallel=None):
    """Run the integrator over flat float64 arrays; returns a dict of flat result arrays.

    ``parallel=None`` picks the parallel kernel when :func:`parallel_allowed`.
    """
    n = alpha.size
    e = np.empty(n)
    t_f = np.empty(n)
    u_max = np.empty(n)
    n_steps = np.empty(n, dtype=np.int64)
    status = np.empty(n, dtype=np.int8)
    if parallel is None:
        parallel = parallel_allowed()
    if parallel and n > _BLOCK:
        # A fixed seed keeps the schedule reproducible; results never depend on it.
        order = np.random.default_rng(0x5EED).permutation(n)
        kernel = _kernel_parallel
    else:
        order = np.arange(n)
        kernel = _kernel_serial
    kernel(order, alpha, beta, gamma, gtilde, float(steps), float(rest_tol), int(max_steps),
           e, t_f, u_max, n_steps, status)
    return {"e": e, "t_f": t_f, "u_max": u_max, "n_steps": n_steps, "status": status}
