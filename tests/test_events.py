"""Event location and the detachment's refinement against the exact linear solution.

For the linear spring-dashpot (alpha = beta = 1) u(tau) is known in closed form
(``reference.linear_solution``), and so is the detachment time T_f (``linear_cor``). One
Runge-Kutta step is started from the exact state a fraction of a step before T_f; the
detachment found in that step must sit at T_f to the step's own accuracy, and its Newton
iteration on the re-stepped state must end after a few re-steps, at a root of the re-step.
"""
from __future__ import annotations

import math

import mpmath
import numba
import numpy as np
import pytest

from reference import linear_cor, linear_solution
from sweep.kernels.contact import make_law, rhs
from sweep.kernels.events import ON_U, ON_V, locate
from sweep.kernels.march import _detach, _restep
from sweep.kernels.stepper import N_DENSE, N_STAGES, dense_coefficients, rk_step
from sweep.kernels.stepsize import MIN_STEPS, policy

EPS = np.finfo(float).eps


@numba.njit
def _one_step(u0, w0, s, c):
    """One step from (u0, w0): its stages and dense output, as the march leaves them."""
    K = np.zeros((N_STAGES, 3))
    K2 = np.zeros((N_STAGES, 3))
    Q = np.zeros((2, N_DENSE))
    K[0, 0], K[0, 1], K[0, 2] = rhs(u0, w0, c)
    u1, w1, _ = rk_step(u0, w0, s, K, c)
    dense_coefficients(K, s, Q)
    return u1, K, K2, Q


@numba.njit
def _detachment(u0, w0, s, c, r0=0.0):
    """``(d, q_f, v_f, re-steps used, u after a re-step of d, u at the step's end)`` for
    the step s from (u0, w0, r0)."""
    u1, K, K2, Q = _one_step(u0, w0, s, c)
    d, q_f, v_f, used = _detach(u0, w0, r0, s, 0.0, 1.0, Q, K, K2, c)
    u_d, _, _ = _restep(u0, w0, r0, d, K, K2, c)
    return d, q_f, v_f, used, u_d, u1


@numba.njit
def _located(which, u0, w0, s, c):
    u1, K, K2, Q = _one_step(u0, w0, s, c)
    return locate(which, 0.0, u0, w0, Q, c, 0.0, 1.0), Q


def _root_in_step(coefficients):
    """The one real root in (0, 1) of the polynomial (highest power first), by numpy."""
    roots = np.roots(coefficients)
    real = roots[(abs(roots.imag) < 1e-12) & (roots.real > 0) & (roots.real < 1)].real
    assert real.size == 1, roots
    return real[0]


def _exact_state(gamma, gtilde, tau):
    """(u, w) of the linear law at tau, w = u' + gamma u (the Lipschitz form's state)."""
    u, du, _, _ = linear_solution(gamma, gtilde)
    with mpmath.workdps(40):
        t = mpmath.mpf(tau)
        return float(u(t)), float(du(t) + gamma * u(t))


# Laws whose bead leaves (at gamma = 1.2 it sticks for any load).
CASES = [(0.01, 0.0), (0.01, 0.05), (0.01, 0.4), (0.3, 0.0), (0.3, 0.2), (0.3, 0.4), (1.2, 0.0)]


@pytest.mark.parametrize("gamma, gtilde", CASES)
def test_detachment_is_the_exact_exit_time(gamma, gtilde):
    exact = linear_cor(gamma, gtilde)
    assert not exact.sticks
    law = make_law(1.0, 1.0, gamma, gtilde)
    s = math.pi / 33.0              # 33 steps a half period, as tol = 1e-8 takes
    used = []
    for frac in np.linspace(0.03, 0.97, 25):
        t0 = exact.t_f - frac * s
        u0, w0 = _exact_state(gamma, gtilde, t0)
        d, _, v_f, n, u_d, u1 = _detachment(u0, w0, s, law)
        assert u1 < 0.0 < u0
        used.append(n)
        # One step's error (s^6) bounds where the detachment is and how fast the bead leaves.
        assert abs(t0 + d - exact.t_f) <= 1e-9, (frac, t0 + d, exact.t_f)
        assert abs(-v_f - exact.e) <= 1e-9, (frac, -v_f, exact.e)
        # Newton ended on a root of the re-step: what is left of u is rounding.
        assert abs(u_d) <= 8 * EPS * u0, (frac, u_d, u0)
    # A few re-steps each (it used to swing between two neighbouring floats up to its cap
    # of 12 where its stop was below one ulp of d).
    assert max(used) <= 4, used


@pytest.mark.parametrize("gamma, gtilde", CASES[::2])
def test_located_exit_is_the_root_of_the_interpolant(gamma, gtilde):
    exact = linear_cor(gamma, gtilde)
    law = make_law(1.0, 1.0, gamma, gtilde)
    s = math.pi / 33.0
    for frac in (0.1, 0.5, 0.9):
        u0, w0 = _exact_state(gamma, gtilde, exact.t_f - frac * s)
        th, Q = _located(ON_U, u0, w0, s, law)
        # The interpolant u0 + sum_j Q[0, j] theta^(j+1).
        assert abs(th - _root_in_step(np.r_[Q[0, ::-1], u0])) <= 1e-13
        assert abs(th - frac) <= 1e-7


@pytest.mark.parametrize("gamma, gtilde", CASES[::2])
def test_located_turn_is_the_root_of_the_interpolated_velocity(gamma, gtilde):
    _, _, xi, om = linear_solution(gamma, gtilde)
    tau0 = float(mpmath.atan2(om, xi - gtilde) / om)      # maximum compression, u' = 0
    law = make_law(1.0, 1.0, gamma, gtilde)
    s = math.pi / 33.0
    for frac in (0.1, 0.5, 0.9):
        u0, w0 = _exact_state(gamma, gtilde, tau0 - frac * s)
        th, Q = _located(ON_V, u0, w0, s, law)
        # v = w - gamma u on the interpolant, a polynomial for the linear law.
        v = np.r_[Q[1, ::-1] - gamma * Q[0, ::-1], w0 - gamma * u0]
        assert abs(th - _root_in_step(v)) <= 1e-13
        assert abs(th - frac) <= 1e-7


@numba.njit
def _bisected_exit(u0, w0, r0, s, c):
    """The root of u over the re-steps of the step s from (u0, w0, r0), by bisection to
    the last bit (the slow, plain reference of _detach's Newton), and the state there:
    ``(d, u, w, r)``."""
    _, K, K2, _ = _one_step(u0, w0, s, c)
    lo, hi = 0.0, s
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        u, _, _ = _restep(u0, w0, r0, mid, K, K2, c)
        if u > 0.0:
            lo = mid
        else:
            hi = mid
    u, w, r = _restep(u0, w0, r0, lo, K, K2, c)
    return lo, u, w, r


@numba.njit
def _exit_step(c, steps):
    p = policy(c, steps)
    return p.s_min if p.graded else p.h


# (alpha, beta, gamma, g~): the report's laws, and exponents near 1, where u^(beta-1)
# varies fastest near the floor.
EXIT_LAWS = [(1.0, 1.0, 0.3, 0.2), (2.0, 3.0, 0.2, 1.0), (1.5, 1.5, 0.1, 0.3),
             (1.5, 1.0, 0.2, 0.05), (1.5, 1.25, 0.2, 0.05), (1.02, 1.02, 0.25, 0.002),
             (2.6, 1.04, 0.21, 0.02)]


@pytest.mark.parametrize("alpha, beta, gamma, gtilde", EXIT_LAWS)
@pytest.mark.parametrize("steps", [MIN_STEPS, 33.3, 96.0])
def test_detachment_state_is_the_re_steps_own_at_its_root(alpha, beta, gamma, gtilde, steps):
    """Newton stops once its correction, applied to first order, is as good as another
    re-step: the time, velocity and dissipated energy must be the re-step's own at its root
    (bisection) to rounding (64 ulps of 1; measured: 32), in the steps in which a march
    meets the floor (the smallest graded step where an exponent is not an integer, else
    the base step), and the iteration must end after a few re-steps."""
    c = make_law(alpha, beta, gamma, gtilde)
    s = _exit_step(c, steps)
    v0, r0 = -0.5, 0.1
    checked = 0
    for frac in (0.05, 0.5, 0.95):    # where in the step the bead reaches the floor
        u0 = frac * s * abs(v0)
        w0 = v0 + gamma * u0 ** beta
        if _one_step(u0, w0, s, c)[0] >= 0.0:
            continue                   # the load turns the bead back before the floor
        d, q_f, v_f, used, _, _ = _detachment(u0, w0, s, c, r0)
        d_ref, u_ref, w_ref, r_ref = _bisected_exit(u0, w0, r0, s, c)
        assert abs(u_ref) <= 4 * EPS * u0
        v_ref = w_ref - gamma * max(u_ref, 0.0) ** beta
        q_ref = gamma * v_ref * max(u_ref, 0.0) ** beta + r_ref
        assert abs(d - d_ref) <= 64 * EPS, (frac, d, d_ref)
        assert abs(v_f - v_ref) <= 64 * EPS, (frac, v_f, v_ref)
        assert abs(q_f - q_ref) <= 64 * EPS, (frac, q_f, q_ref)
        assert 1 <= used <= 4
        checked += 1
    assert checked >= 2
