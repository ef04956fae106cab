"""The contact law's rates and frequencies against numpy's powers.

The step-size rule, the damping cap and the creep rules evaluate these at every step of a
heavily damped march, so for the report's exponents they take the pow-free powers of the
law's codes (sqrt, products); whatever the exponent, the value is the formula's to rounding.
"""
from __future__ import annotations

import numba
import numpy as np
import pytest

from sweep.kernels import contact
from sweep.kernels.creep import slow_velocity


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
