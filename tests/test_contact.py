"""The contact law's rates and frequencies against numpy's powers.

The step-size rule, the damping cap and the creep rules evaluate these at every step of a
heavily damped march, so for the report's exponents they take the pow-free powers of the
law's codes (sqrt, products); whatever the exponent, the value is the formula's to rounding.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from sweep.kernels import contact, vmath
from sweep.kernels._jit import FLAGS
from sweep.kernels.creep import slow_velocity
from sweep.registry import MODELS


# Kernel-only helpers (no Python wrapper) are called from compiled code, as kernels do.
@numba.njit
def _damping_rate(u, c):
    return contact.damping_rate(u, c)


@numba.njit
def _elastic_frequency(alpha, u):
    return contact.elastic_frequency(alpha, u)

EPS = np.finfo(float).eps
# The report's exponents (each with a code) and two without one.
EXPONENTS = [1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 1.37, 2.81]
U = np.logspace(-12, 3, 61)


def _close(got, ref, ulps=4):
    assert np.allclose(got, ref, rtol=ulps * EPS, atol=0.0), (got, ref)


@pytest.mark.parametrize("beta", EXPONENTS)
def test_damping_rate_is_gamma_beta_u_to_the_beta_minus_1(beta):
    law = contact.make_law(1.5, beta, 0.37, 0.2)
    got = np.array([_damping_rate(u, law) for u in U])
    _close(got, 0.37 * beta * U ** (beta - 1.0))
    # Out of contact the damper is off (but for beta = 1, whose rate is u's power 0).
    assert _damping_rate(0.0, law) == (0.37 if beta == 1.0 else 0.0)
    assert _damping_rate(-1e-3, law) == (0.37 if beta == 1.0 else 0.0)


@pytest.mark.parametrize("alpha", EXPONENTS)
def test_elastic_frequency_is_sqrt_alpha_u_to_the_alpha_minus_1(alpha):
    got = np.array([_elastic_frequency(alpha, u) for u in U])
    _close(got, np.sqrt(alpha * U ** (alpha - 1.0)))


@pytest.mark.parametrize("alpha", [1.0, 1.5, 2.5, 2.81])
@pytest.mark.parametrize("beta", [1.0, 1.25, 1.5, 1.37])
def test_slow_branch_velocity(alpha, beta):
    law = contact.make_law(alpha, beta, 40.0, 0.3)
    got = np.array([slow_velocity(u, law) for u in U])
    ref = (0.3 - U ** alpha) / (40.0 * beta * U ** (beta - 1.0))
    # g~ - u^alpha cancels near u-bar: compare on its own scale.
    scale = (0.3 + U ** alpha) / (40.0 * beta * U ** (beta - 1.0))
    assert np.all(np.abs(got - ref) <= 8 * EPS * scale)


# --------------------------------------------------------------------------- rows of laws

@numba.njit(**FLAGS)
def _row_rhs(u, w, alpha, beta, gamma, gtilde):
    """rhs_at on the row put_law stores, beside rhs on the law itself."""
    F = np.empty((1, contact.LAW_COLUMNS[0]))
    I = np.empty((1, contact.LAW_COLUMNS[1]), np.int64)
    c = contact.make_law(alpha, beta, gamma, gtilde)
    contact.put_law(F, I, 0, c)
    a = contact.rhs_at(u, w, F, I, 0)
    b = contact.rhs(u, w, c)
    return a[0], a[1], a[2], b[0], b[1], b[2]


# Every model of the report, a pair without codes, one with beta's code only, a smooth one.
ROW_LAWS = list(MODELS.values()) + [(2.81, 1.37), (1.37, 1.5), (2.0, 3.0)]
ROW_U = np.concatenate([-np.logspace(-12, 0, 7), [0.0, -0.0], np.logspace(-14, 2, 33)])


@pytest.mark.parametrize("alpha, beta", ROW_LAWS)
def test_a_law_read_from_its_row_gives_the_laws_own_rates_bit_for_bit(alpha, beta):
    # The models' rows take copies of rhs compiled with their exponents as constants
    # (rhs_at): the arithmetic must be rhs's, operation for operation.
    rng = np.random.default_rng(11)
    for u in ROW_U:
        w, gamma, gtilde = rng.uniform(-2, 2), 10 ** rng.uniform(-4, 2), rng.uniform(0, 5)
        got = np.array(_row_rhs(u, w, alpha, beta, gamma, gtilde))
        assert np.array_equal(got[:3], got[3:]), (u, w, gamma, gtilde, got)
        # ... and rhs is the report's (4) with u_+ powers (numpy's, to rounding).
        up = max(u, 0.0)
        if contact._integer.py_func(alpha) and contact._integer.py_func(beta):
            up = u
        pb, pa = up ** beta if up != 0.0 else 0.0, up ** alpha if up != 0.0 else 0.0
        # To rounding of the terms each rate is formed from.
        assert abs(got[0] - (w - gamma * pb)) <= 8 * EPS * (abs(w) + gamma * pb)
        assert abs(got[1] - (gtilde - pa)) <= 8 * EPS * (gtilde + pa)


@numba.njit(**FLAGS)
def _vector_rows(u, w, alpha, beta, gamma, gtilde):
    """rhs_vector on rows put_law stores, four at a time, beside rhs_at on each row."""
    n = u.size
    F = np.empty((n, contact.LAW_COLUMNS[0]))
    I = np.empty((n, contact.LAW_COLUMNS[1]), np.int64)
    out = np.empty((n, 6))
    for r in range(n):
        contact.put_law(F, I, r, contact.make_law(alpha[r], beta[r], gamma[r], gtilde[r]))
        out[r, 3], out[r, 4], out[r, 5] = contact.rhs_at(u[r], w[r], F, I, r)
    for f in range(0, n, 4):
        f3 = contact.rhs_vector((u[f], u[f + 1], u[f + 2], u[f + 3]),
                                (w[f], w[f + 1], w[f + 2], w[f + 3]), contact.vector_law(F, I, f))
        fu, fw, fq = vmath.vtuple(f3[0]), vmath.vtuple(f3[1]), vmath.vtuple(f3[2])
        for k in range(4):
            out[f + k, 0], out[f + k, 1], out[f + k, 2] = fu[k], fw[k], fq[k]
    return out


def test_rows_taken_as_vectors_give_each_row_its_rates_bit_for_bit():
    # The stages of four lanes go as vectors (stepper.rk_step_lanes) wherever
    # contact.vector_law_at says their laws are ones rhs_vector forms: every model of the
    # report, mixed among the four rows, at every kind of u.
    laws = list(MODELS.values())
    rng = np.random.default_rng(12)
    u = np.repeat(ROW_U, 8)
    pick = rng.integers(len(laws), size=u.size)
    alpha = np.array([laws[k][0] for k in pick])
    beta = np.array([laws[k][1] for k in pick])
    w, gamma = rng.uniform(-2, 2, u.size), 10 ** rng.uniform(-4, 2, u.size)
    gtilde = np.where(rng.random(u.size) < 0.2, 0.0, rng.uniform(0, 5, u.size))
    got = _vector_rows(u, w, alpha, beta, gamma, gtilde)
    assert np.array_equal(got[:, :3], got[:, 3:]), got[np.any(got[:, :3] != got[:, 3:], 1)]
    assert all(contact.vector_law_at.py_func(_row_codes(a, b), 0) for a, b in laws)
    assert not any(contact.vector_law_at.py_func(_row_codes(a, b), 0)
                   for a, b in [(2.0, 3.0), (2.0, 2.0), (1.0, 2.0), (2.81, 1.37), (1.5, 1.37)])


def _row_codes(alpha, beta):
    I = np.empty((1, contact.LAW_COLUMNS[1]), np.int64)
    contact.put_law.py_func(np.empty((1, contact.LAW_COLUMNS[0])), I, 0,
                            contact.make_law.py_func(alpha, beta, 0.1, 0.1))
    return I


@pytest.mark.parametrize("p", [1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 0.5, 0.25])
def test_the_coded_powers_are_the_powers_to_rounding(p):
    kind = contact.power_kind.py_func(p)
    for x in np.logspace(-100, 100, 121):
        np.testing.assert_allclose(contact.ppow(x, p, kind), x ** p, rtol=4 * EPS)


def test_each_code_names_its_exponent():
    assert [contact.power_kind.py_func(p) for p in contact.KIND_EXPONENTS] == list(
        range(len(contact.KIND_EXPONENTS)))


@pytest.mark.parametrize("alpha", [1.0, 1.25, 1.5, 2.0, 2.5, 3.0])
def test_the_unloaded_umax_of_a_code_is_the_computed_one_bit_for_bit(alpha):
    # The coded exponents take u_M(0) from a table formed in Python; a general code
    # computes it in the kernel. Both must be the same double (the march's step follows it).
    ka = contact.power_kind.py_func(alpha)
    assert ka != contact.power_kind.py_func(alpha + 1e-9)
    general = contact.power_kind.py_func(alpha + 1e-9)
    assert contact.umax_undamped(alpha, 0.0, ka) == contact.umax_undamped(alpha, 0.0, general)
    assert contact.umax_undamped(alpha, 0.0, ka) == pytest.approx(
        (0.5 * (alpha + 1.0)) ** (1.0 / (alpha + 1.0)), rel=EPS)


@pytest.mark.parametrize("beta", [1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0])
def test_the_damping_integrals_mean_of_a_code_is_the_quadratures(beta):
    # sweep.kernels.outcome places e's damping integral against its thresholds with the
    # mean of sin^(beta - 1) over a half period: a table for the codes of beta - 1.
    from scipy.integrate import quad

    from sweep.kernels import outcome
    p = beta - 1.0
    kd = contact.power_kind.py_func(p)
    mean = outcome._SINE_MEANS[kd] if kd < len(outcome._SINE_MEANS) else None
    ref = quad(lambda x: np.sin(x) ** p, 0.0, np.pi, epsabs=0, epsrel=1e-13)[0] / np.pi
    if mean is not None:
        assert mean == pytest.approx(ref, rel=1e-12)
    # The kernel's estimate, from the table or not, with u_max = t_f = gamma = 1.
    got = outcome._damping_integral.py_func(beta, kd, 1.0, 1.0, 1.0)
    assert got == pytest.approx(beta * ref, rel=1e-12)


@numba.njit
def _overdamped(alpha, beta, gamma, gtilde):
    return contact.overdamped_at_rest(alpha, beta, gamma, gtilde)


def test_overdamped_at_rest_is_the_damping_ratios_test_near_and_far_from_one():
    # Its bound skips the power where xi is surely below 1; the answer must be the
    # formula's everywhere, within ulps of xi = 1 too.
    rng = np.random.default_rng(3)
    n = 20000
    alpha, beta = rng.uniform(1, 6, n), rng.uniform(1, 6, n)
    alpha[:n // 4] = 1.5
    beta[:n // 4] = rng.choice([1.0, 1.25, 1.5, 2.5], n // 4)
    gtilde = 10 ** rng.uniform(-12, 12, n)
    gtilde[::50] = 0.0
    expo = (2 * beta - alpha - 1) / (2 * alpha)
    with np.errstate(divide="ignore"):
        xi1 = beta / (2 * np.sqrt(alpha)) * gtilde ** expo     # xi at gamma = 1
    gamma = np.where(rng.random(n) < 0.5, 10 ** rng.uniform(-6, 6, n),
                     (1 + rng.uniform(-1e-14, 1e-14, n)) / np.where(xi1 > 0, xi1, 1))
    for a, b, g, gt in zip(alpha, beta, gamma, gtilde):
        xi = g * b / (2 * math.sqrt(a)) * gt ** ((2 * b - a - 1) / (2 * a)) if gt > 0 else 0.0
        assert _overdamped(a, b, g, gt) == (xi >= 1.0), (a, b, g, gt)
