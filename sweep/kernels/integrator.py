"""Numerical CoR: a fixed-step Runge-Kutta march of (4) with the three phases of Algorithm 1.

Per point (scaled parameters ``alpha, beta, gamma, g~``) the bead starts at ``u = 0``,
``w = 1`` and is marched with the base step of :mod:`sweep.kernels.stepsize` (graded near u = 0).
Phases (report, Sec. 3 and Algorithm 1):

1. until ``v = 0`` crossing downward -- maximum compression ``u_max``;
2. until ``u = u-bar`` crossing downward (with ``g~ = 0``, ``u-bar = 0`` and this is the
   detachment itself);
3. until ``u v = 0``: ``u = 0`` -> detachment, ``e = -v``; ``v = 0`` with ``u > 0`` -> the bead
   sticks, ``e = 0``.

Each event is bracketed by a sign test at the step's ends, located on the step's interpolant
(:mod:`sweep.kernels.events`) and refined with full Runge-Kutta steps from the step's start (Newton
on the re-stepped state), so located times and states carry the method's own accuracy.
Grazing (u dipping below 0 inside one step and coming back) is caught in phase 3 through the
velocity's sign change: the minimum of u at ``v = 0`` decides between sticking and detachment.

Two extra stopping rules keep every point bounded:

* rest: ``max(|u - u-bar|, |v|) < rest_tol`` -> ``e = 0``, status AT_REST (report, Sec. 3);
* energy: ``H = v^2/2 + u_+^(alpha+1)/(alpha+1) - g~ u = 1/2 - q`` never increases
  (q, the energy dissipated by the damper, is carried along, see :func:`sweep.kernels.stepper.rhs`)
  and equals ``e^2/2 >= 0`` at a detachment, so once ``q > 1/2`` (beyond roundoff) the bead
  can never leave the floor: ``e = 0``, status STUCK.
  This is what ends overdamped points that creep towards u-bar. It is applied from phase 2 on,
  and in phase 1 only when the linearisation about u-bar is overdamped (``xi >= 1``), where
  phase 1 may never end; such points report ``u_max = NaN`` (maximum not reached).

At detachment e is ``sqrt(1 - 2 q)`` or ``-v``, whichever is better conditioned (see
:func:`_cor_at_exit`). A point that exhausts ``max_steps`` stops with status BUDGET_EXHAUSTED
and ``e = sqrt(2 H) = sqrt(1 - 2 q)``:
the energy still available bounds the rebound speed, so this is an upper bound of the CoR
(tiny for the slow creep back to u = 0 of heavily damped points at g~ = 0), not a converged
value.

The linear law at g~ = 0 with gamma >= 2 (overdamped) is decided by its closed form: the bead
only creeps back towards u = 0, exponentially slowly, and never leaves (AT_REST, e = 0,
``t_f = inf``, exact ``u_max``).

Conditioning: near the stick/rebound boundary e ~ sqrt(dip depth) amplifies every absolute
error by about 1/e.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from sweep.kernels._jit import cached_njit
from sweep.kernels._parallel import parallel_allowed
from sweep.kernels.contact import (accel, damping_ratio, dissipated, equilibrium, in_domain,
                                   make_law, ppow, rhs, velocity, well_depth)
from sweep.kernels.events import ON_U, ON_V, locate
from sweep.kernels.stepper import N_DENSE, N_STAGES, dense_coefficients, rk_step
from sweep.kernels.stepsize import damping_step, first_guess, policy
from sweep.registry import METHODS, Status, kernel_fields

__all__ = ["integrate_arrays", "integrate_point", "numeric_cor", "DEFAULT_STEPS",
           "DEFAULT_MAX_STEPS", "DEFAULT_REST_TOL"]

_OPTIONS = {opt.name: opt.default for opt in METHODS["numeric"].options}
#: Steps per half period of the stiffest linearised motion (see :mod:`sweep.kernels.stepsize`).
DEFAULT_STEPS = _OPTIONS["steps"]
#: Step budget per point (all Runge-Kutta steps, refinements included).
DEFAULT_MAX_STEPS = _OPTIONS["max_steps"]
#: Rest tolerance of the report (Sec. 3).
DEFAULT_REST_TOL = _OPTIONS["rest_tol"]

_OK = int(Status.OK)
_STUCK = int(Status.STUCK)
_AT_REST = int(Status.AT_REST)
_BUDGET = int(Status.BUDGET_EXHAUSTED)
_INVALID = int(Status.INVALID)

# Relative roundoff in the dissipated energy q (a sum of positive terms): the stuck rule
# waits until q exceeds the initial energy 1/2 by more than it.
_ENERGY_ROUNDOFF = 1e-12
# Where the energy balance beats -v for e (see _cor_at_exit).
_BALANCE_THRESHOLD = 0.05


@nb.njit(inline="always")
def _set_first_stage(K, fu, fw, fr):
    K[0, 0] = fu
    K[0, 1] = fw
    K[0, 2] = fr


@nb.njit(inline="always")
def _restep(u, w, r, d, K, K2, c):
    """State at time ``d`` after the step's start, by one Runge-Kutta step of size ``d``."""
    _set_first_stage(K2, K[0, 0], K[0, 1], K[0, 2])
    return rk_step(u, w, r, d, K2, c)


@nb.njit(inline="always")
def _cor_at_exit(q, v, swing2, damping):
    """CoR at detachment from the better conditioned of two equal expressions.

    ``e = sqrt(1 - 2 q)`` (energy balance, q the dissipated energy) inherits the relative
    error of q: about ``eps / (2 e)`` in e. ``e = -v`` inherits the error of the velocity:
    relative to the largest speed of the swing, ``sqrt(swing2)`` with
    ``swing2 = 1 + 2 |V(u-bar)|``, and damped on the way out like a perturbation of the
    linearised motion, by ``exp(-damping / 2)`` where ``damping`` estimates the integral of
    the damping rate ``gamma beta u^(beta-1)`` over the impact: about
    ``eps sqrt(swing2) exp(-damping / 2)``. The balance wins unless e is small and the
    velocity's errors are damped out (heavy damping at small load). The threshold was
    calibrated on both sides (linear closed form; KK and TTI near the stick boundary).
    """
    left = 1.0 - 2.0 * q
    if left > 0.0 and 2.0 * math.sqrt(left * swing2) * math.exp(-0.5 * damping) >= _BALANCE_THRESHOLD:
        return math.sqrt(left)
    return max(-v, 0.0)


@nb.njit(inline="always")
def _damping_integral(beta, gamma, u_max, t_f):
    """Estimate of ``int gamma beta u^(beta-1) dtau`` over an impact of length t_f:
    ``u^(beta-1)`` averaged over a half sine of amplitude u_max."""
    p = beta - 1.0
    mean = math.exp(math.lgamma(0.5 * (p + 1.0)) - math.lgamma(0.5 * p + 1.0)) / math.sqrt(math.pi)
    return gamma * beta * mean * u_max ** p * t_f


@nb.njit
def _detach(u, w, r, s, th_lo, th_hi, Q, K, K2, c):
    """Refine the detachment u = 0 inside ``[th_lo, th_hi]`` of the step from ``(u, w, r)``.

    Returns ``(time from the step's start, dissipated energy q, velocity, re-steps used)``
    at the detachment.
    """
    th = locate(ON_U, 0.0, u, w, Q, c, th_lo, th_hi)
    lo = th_lo * s
    hi = th_hi * s
    d = th * s
    used = 0
    ue = 0.0
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
        dn = d - ue / ve if ve < 0.0 else 0.5 * (lo + hi)
        if not (lo <= dn <= hi):
            dn = 0.5 * (lo + hi)
        if abs(dn - d) <= 2e-16 * d or hi - lo <= 2e-16 * d:
            d = dn
            break
        d = dn
    # The last Newton correction is O(u_e), within roundoff; apply it to first order.
    delta = -ue / ve if ve < 0.0 else 0.0
    v_f = ve + delta * (c.gtilde - ppow(ue, c.alpha, c.ka))
    q_f = dissipated(ue, ve, r_e, c) + delta * c.gamma * c.beta * ppow(ue, c.beta - 1.0, c.kd) * ve * ve
    return d, q_f, v_f, used


@nb.njit(inline="always")
def _stationary_u(u, v, c, upward):
    """u at the vertex of the local parabola through (u, v): removes a residual v at an
    extremum of u (``upward``: a minimum, where the acceleration is positive)."""
    acc = accel(u, v, c)
    if (acc > 0.0) if upward else (acc < 0.0):
        return u - 0.5 * v * v / acc
    return u


@nb.njit(inline="always")
def _linear_overdamped_g0(gamma):
    """alpha = beta = 1, g~ = 0, gamma >= 2: u > 0 for ever (no rebound); returns u_max.

    u = (exp(l1 t) - exp(l2 t)) / (l1 - l2) with l1,2 = -gamma/2 +- sqrt(gamma^2/4 - 1),
    maximal where l1 exp(l1 t) = l2 exp(l2 t); t exp(-t) (maximum 1/e) at gamma = 2.
    """
    r = math.sqrt(max(0.25 * gamma * gamma - 1.0, 0.0))
    if r == 0.0:
        return math.exp(-1.0)
    l1 = -0.5 * gamma + r
    l2 = -0.5 * gamma - r
    t = math.log(l2 / l1) / (l1 - l2)
    return (math.exp(l1 * t) - math.exp(l2 * t)) / (l1 - l2)


# --------------------------------------------------------------------------- one step

@nb.njit(inline="always")
def _advance(u, w, r, v, p, K, c, n, max_steps):
    """One step of the march: size from the policy, then the damping cap judged at the
    step's end (the step retaken, smaller, while it is exceeded). Returns the new state,
    the step and the steps counter."""
    s = first_guess(u, v, p, c)
    fu0 = K[0, 0]
    fw0 = K[0, 1]
    fr0 = K[0, 2]
    u1, w1, r1 = rk_step(u, w, r, s, K, c)
    n += 1
    if p.capped:
        # A load can drive the bead deep into the damper within one step: judge the cap
        # at the step's end too and retake the step if it was exceeded (twice: slack
        # against retaking steps for nothing).
        s_end = damping_step(u1, c.beta, c.gamma, p.steps)
        while not (s <= 2.0 * s_end and math.isfinite(u1) and math.isfinite(w1)) and n < max_steps:
            s = s_end if s_end < 0.5 * s else 0.5 * s
            _set_first_stage(K, fu0, fw0, fr0)
            u1, w1, r1 = rk_step(u, w, r, s, K, c)
            n += 1
            s_end = damping_step(u1, c.beta, c.gamma, p.steps)
    return u1, w1, r1, s, n


# --------------------------------------------------------------------------- phases

@nb.njit(inline="always")
def _may_have_event(phase, u1, v1, ubar):
    """An event of Algorithm 1 may lie inside the step that ended at (u1, v1)."""
    if phase == 1:
        return v1 <= 0.0
    if phase == 2:
        return u1 < ubar or (ubar == 0.0 and u1 <= 0.0)
    return u1 <= 0.0 or v1 >= 0.0


@nb.njit(inline="always")
def _compression_end(u, w, r, s, Q, K, K2, c):
    """Phase 1 ends inside the step: maximum compression (v = 0). Returns its fraction of
    the step and ``u_max``."""
    th = locate(ON_V, 0.0, u, w, Q, c, 0.0, 1.0)
    um, wm, _ = _restep(u, w, r, th * s, K, K2, c)
    return th, _stationary_u(um, velocity(um, wm, c), c, False)


@nb.njit(inline="always")
def _trough(u, w, r, s, th0, Q, K, K2, c):
    """Phase 3, v = 0 inside the step: the bead's lowest point after the swing. Returns its
    fraction of the step and the minimum of u there (> 0: the bead sticks; <= 0: it dipped
    below the floor inside the step -- grazing -- and left first)."""
    th = locate(ON_V, 0.0, u, w, Q, c, th0, 1.0)
    us, ws, _ = _restep(u, w, r, th * s, K, K2, c)
    return th, _stationary_u(us, velocity(us, ws, c), c, True)


# --------------------------------------------------------------------------- stopping rules

@nb.njit(inline="always")
def _at_rest(u, v, ubar, rest_tol):
    """Rest criterion of the report (Sec. 3): ``max(|u - u-bar|, |v|) < rest_tol``."""
    return max(abs(u - ubar), abs(v)) < rest_tol


@nb.njit(inline="always")
def _cannot_return(u, w, r, v, phase, energy_in_phase1, q_stuck, c):
    """Energy rule: the dissipated energy exceeds the initial 1/2 (beyond roundoff), so the
    bead can never reach u = 0 again (H = 1/2 - q never increases and is e^2/2 >= 0 at a
    detachment). q = gamma v u^beta + r, with gamma u^beta = w - v read off the state.
    Applied from phase 2 on, and in phase 1 only when the linearisation is overdamped."""
    return c.gtilde > 0.0 and (phase > 1 or energy_in_phase1) and v * (w - v) + r > q_stuck


# --------------------------------------------------------------------------- driver

@nb.njit
def integrate_point(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, K, K2, Q):
    """Numerical CoR of one point; returns ``(e, t_f, u_max, n_steps, status)``.

    ``K``, ``K2`` (stages, shape (s, 3)) and ``Q`` (dense output, shape (2, q)) are scratch.
    """
    if not in_domain(alpha, beta, gamma, gtilde):
        return np.nan, np.nan, np.nan, 0, _INVALID
    if alpha == 1.0 and beta == 1.0 and gtilde == 0.0 and gamma >= 2.0:
        # Decided by the closed form: the march would only creep towards rest, exponentially slowly.
        return 0.0, math.inf, _linear_overdamped_g0(gamma), 0, _AT_REST
    c = make_law(alpha, beta, gamma, gtilde)
    return _march(c, policy(c, steps), rest_tol, max_steps, K, K2, Q)


@nb.njit
def _march(c, p, rest_tol, max_steps, K, K2, Q):
    """The three phases of Algorithm 1 for the law ``c`` with the step policy ``p``."""
    ubar = equilibrium(c.alpha, c.gtilde)
    energy_in_phase1 = c.gtilde > 0.0 and damping_ratio(c.alpha, c.beta, c.gamma, c.gtilde) >= 1.0
    q_stuck = 0.5 * (1.0 + _ENERGY_ROUNDOFF)
    t = u = r = 0.0
    w = v = 1.0
    fu, fw, fr = rhs(u, w, c)
    _set_first_stage(K, fu, fw, fr)
    phase = 1
    u_max = np.nan
    n = 0
    while True:
        if n >= max_steps:
            # The energy still available, 1/2 - q, bounds the rebound speed.
            q_now = dissipated(u, v, r, c)
            return math.sqrt(max(1.0 - 2.0 * q_now, 0.0)), t, u_max, n, _BUDGET
        u1, w1, r1, s, n = _advance(u, w, r, v, p, K, c, n, max_steps)
        # The last (FSAL) stage is f at the step's end: its u' is the velocity v1, no power.
        v1 = K[N_STAGES - 1, 0]
        if _may_have_event(phase, u1, v1, ubar):
            dense_coefficients(K, s, Q)
            th0 = 0.0
            if phase == 1 and v1 <= 0.0:
                th0, u_max = _compression_end(u, w, r, s, Q, K, K2, c)
                n += 1
                phase = 2
            if phase == 2 and ubar > 0.0 and u1 < ubar:
                th0 = locate(ON_U, ubar, u, w, Q, c, th0, 1.0)
                phase = 3
            # With g~ = 0 (u-bar = 0) the return to u-bar in phase 2 is the detachment itself.
            exiting = (phase == 3 or (phase == 2 and ubar == 0.0)) and u1 <= 0.0
            th_exit = 1.0
            if not exiting and phase == 3 and v1 >= 0.0:
                th_exit, u_min = _trough(u, w, r, s, th0, Q, K, K2, c)
                n += 1
                if u_min > 0.0:
                    return 0.0, t + th_exit * s, u_max, n, _STUCK
                exiting = True
            if exiting:
                d, q_f, v_f, used = _detach(u, w, r, s, th0, th_exit, Q, K, K2, c)
                swing2 = 1.0 + 2.0 * well_depth(c.alpha, c.gtilde)
                lam = _damping_integral(c.beta, c.gamma, u_max, t + d)
                return _cor_at_exit(q_f, v_f, swing2, lam), t + d, u_max, n + used, _OK
        t += s
        u = u1
        w = w1
        r = r1
        v = v1
        _set_first_stage(K, K[N_STAGES - 1, 0], K[N_STAGES - 1, 1], K[N_STAGES - 1, 2])
        if _at_rest(u, v, ubar, rest_tol):
            if phase == 1:
                u_max = max(u, ubar)
            return 0.0, t, u_max, n, _AT_REST
        if _cannot_return(u, w, r, v, phase, energy_in_phase1, q_stuck, c):
            return 0.0, t, u_max, n, _STUCK


@nb.njit
def _run_range(lo, hi, order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
               e, t_f, u_max, n_steps, status):
    K = np.empty((N_STAGES, 3))
    K2 = np.empty((N_STAGES, 3))
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
# No fastmath anywhere: the finiteness checks must hold, and IEEE semantics keep results
# bit-identical whatever the thread count, block or order.
_BLOCK = 64


@cached_njit(parallel=True)
def _kernel_parallel(order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
                     e, t_f, u_max, n_steps, status):
    n = order.size
    nblocks = (n + _BLOCK - 1) // _BLOCK
    for b in nb.prange(nblocks):
        _run_range(b * _BLOCK, min(n, (b + 1) * _BLOCK), order, alpha, beta, gamma, gtilde,
                   steps, rest_tol, max_steps, e, t_f, u_max, n_steps, status)


@cached_njit()
def _kernel_serial(order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
                   e, t_f, u_max, n_steps, status):
    _run_range(0, order.size, order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps,
               e, t_f, u_max, n_steps, status)


def integrate_arrays(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, parallel=None):
    """Run the integrator over flat float64 arrays.

    Returns
    -------
    dict of str -> ndarray
        One flat array per field of :func:`sweep.registry.kernel_fields`, in its dtype.

    ``parallel=None`` picks the parallel kernel when :func:`parallel_allowed`.
    """
    n = alpha.size
    out = {f.name: np.empty(n, dtype=f.dtype) for f in kernel_fields()}
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
           out["e"], out["t_f"], out["u_max"], out["n_steps"], out["status"])
    return out


def numeric_cor(alpha, beta, gamma, gtilde, steps=DEFAULT_STEPS, rest_tol=DEFAULT_REST_TOL,
                max_steps=DEFAULT_MAX_STEPS, parallel=None):
    """The ``"numeric"`` method's kernel (:data:`sweep.registry.METHODS`): ``(e, status)``
    over flat float64 arrays of equal length."""
    out = integrate_arrays(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, parallel)
    return out["e"], out["status"]
