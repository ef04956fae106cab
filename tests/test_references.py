"""The independent references of tests/reference.py agree with each other and with the SPEC.

Nothing here uses the package's integrator: these tests establish how far the judges of
``sweep.integrate`` can be trusted (their own error must be well below the 1e-9 the
integrator is held to).
"""
import math

import mpmath
import numpy as np
import pytest

from reference import (AT_REST, OK, STUCK, dop853_cor, dop853_solve, linear_cor,
                       linear_solution, prop2_es, prop2_IQ, prop2_IQ0, tti_cor_g0)

MODELS = {"linear": (1.0, 1.0), "hertz": (1.5, 1.0), "tti": (1.5, 1.25), "kk": (1.5, 1.5),
          "shc": (1.5, 2.5), "a2b1": (2.0, 1.0)}


def _gamma_crit_linear(gtilde, lo=0.0, hi=1.999, iters=60):
    """Stick/rebound boundary of the linear closed form by bisection (e > 0 below it)."""
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if linear_cor(mid, gtilde).e > 0:
            lo = mid
        else:
            hi = mid
    return lo


# --- the linear closed form itself ---------------------------------------------------------

@pytest.mark.parametrize("gamma, gtilde", [(1e-3, 0.0), (0.3, 0.05), (1.2, 1.0), (0.01, 100.0)])
def test_linear_solution_solves_the_ode(gamma, gtilde):
    with mpmath.workdps(30):
        u, du, xi, om = linear_solution(gamma, gtilde)
        assert abs(u(0)) < 1e-28 and abs(du(0) - 1) < 1e-28
        for t in (mpmath.mpf("0.3"), mpmath.mpf("1.7"), mpmath.mpf("4.1")):
            d1 = mpmath.diff(u, t)
            d2 = mpmath.diff(u, t, 2)
            assert abs(d1 - du(t)) < 1e-20 * (1 + abs(d1))
            assert abs(d2 + gamma * d1 + u(t) - gtilde) < 1e-18 * (1 + gtilde)


@pytest.mark.parametrize("gamma", [0.0, 1e-6, 1e-2, 0.5, 1.0, 1.9])
def test_linear_closed_form_at_zero_load(gamma):
    xi = gamma / 2
    om = math.sqrt(1 - xi * xi)
    r = linear_cor(gamma, 0.0)
    assert not r.sticks
    assert r.e == pytest.approx(math.exp(-xi * math.pi / om), rel=1e-14, abs=0)  # float64 formula: ~xi pi/omega ulp
    assert r.t_f == pytest.approx(math.pi / om, rel=1e-15)


def test_linear_overdamped_is_zero():
    for gtilde in (0.0, 0.5, 100.0):
        r = linear_cor(2.5, gtilde)
        assert r.e == 0.0 and r.sticks


# --- DOP853 against the linear closed form ----------------------------------------------------

GAMMAS_LIN = np.logspace(-6, 0, 9)
LOADS = [0.0, 0.05, 1.0, 10.0, 100.0]


@pytest.mark.parametrize("gtilde", LOADS)
def test_dop853_matches_linear_closed_form(gtilde):
    """Includes sticking points (all of g~ = 100 above gamma ~ 1.6e-5). 2e-11 covers what was
    measured (<= 2e-12) with margin; e = -w(T_f) alone is off by ~2e-9 at g~ = 100 (SPEC 7),
    which is why the reference takes e from the energy identity there."""
    for gamma in GAMMAS_LIN:
        exact = linear_cor(gamma, gtilde)
        r = dop853_solve(1.0, 1.0, gamma, gtilde)
        assert (r["status"] in (STUCK, AT_REST)) == exact.sticks, (gamma, gtilde)
        assert abs(r["e"] - exact.e) <= 2e-11, (gamma, gtilde, r["e"], exact.e)
        if not math.isnan(r["u_max"]):   # NaN: found stuck (H < 0) before maximum compression
            assert abs(r["u_max"] - exact.u_max) <= 1e-11 * (1 + exact.u_max)
        if not exact.sticks:
            assert abs(r["t_f"] - exact.t_f) <= 1e-10 * exact.t_f


@pytest.mark.parametrize("gtilde", [0.05, 1.0, 10.0, 100.0])
def test_dop853_decides_grazing_points_like_the_closed_form(gtilde):
    """A hair either side of the stick/rebound boundary (1e-6 relative in gamma) the dip of u
    below 0 lasts a tiny fraction of one DOP853 step: the reference must still see it."""
    gc = _gamma_crit_linear(gtilde)
    for f, rebounds in ((1 - 1e-6, True), (1 + 1e-6, False)):
        exact = linear_cor(gc * f, gtilde)
        assert (exact.e > 0) == rebounds
        r = dop853_solve(1.0, 1.0, gc * f, gtilde)
        assert (r["status"] == OK) == rebounds, (gtilde, f, r)
        # e ~ 1e-3 here and its condition number ~1/e (SPEC 7): judge the rebound energy e^2.
        assert abs(r["e"] ** 2 - exact.e ** 2) <= 1e-12, (gtilde, f, r["e"], exact.e)
    # Just below the boundary the missed dip is caught through the trough v = 0.
    assert dop853_solve(1.0, 1.0, gc * (1 - 1e-6), gtilde)["refinements"] >= 1


# --- TTI mapping (SPEC 4: "verify it numerically") ---------------------------------------------

@pytest.mark.parametrize("gamma", [1e-6, 1e-3, 0.01, 0.1, 0.5, 1.0, 1.5, 1.75])
def test_tti_phase_plane_mapping(gamma):
    r = dop853_cor(1.5, 1.25, gamma, 0.0)
    assert abs(r.e - tti_cor_g0(gamma)) <= 1e-12, (gamma, r.e, tti_cor_g0(gamma))


def test_tti_mapping_is_not_a_tautology():
    # The mapping is specific to beta = 5/4: KK at the same gamma differs clearly.
    assert abs(dop853_cor(1.5, 1.5, 0.5, 0.0).e - tti_cor_g0(0.5)) > 1e-2


# --- Prop. 2 quadrature and the small-gamma expansion -------------------------------------------

@pytest.mark.parametrize("name", list(MODELS))
def test_prop2_quadrature_matches_exact_zero_load_values(name):
    a, b = MODELS[name]
    I, Q = prop2_IQ(a, b, 0.0)
    I0, Q0 = prop2_IQ0(a, b)
    assert float(I) == pytest.approx(I0, rel=1e-14)
    assert float(Q) == pytest.approx(Q0, rel=1e-14)


@pytest.mark.parametrize("gtilde, I_spec, Q_spec", [
    (0.0, 1.1534489, 1.2687937), (0.05, 1.25752517, 1.31835463), (10.0, 203.308392, 3.26880439)])
def test_prop2_matches_spec_kk_values(gtilde, I_spec, Q_spec):
    I, Q = prop2_IQ(1.5, 1.5, gtilde)
    assert float(I) == pytest.approx(I_spec, abs=6e-7 * max(1, I_spec))
    assert float(Q) == pytest.approx(Q_spec, abs=6e-9 * max(1, Q_spec) if gtilde else 6e-8)


@pytest.mark.parametrize("name", ["linear", "hertz", "kk", "shc", "a2b1"])
@pytest.mark.parametrize("gtilde", [0.0, 0.05, 1.0, 10.0, 100.0])
def test_dop853_has_the_small_gamma_expansion_of_prop2(name, gtilde):
    """e - e_s = r x^3 + O(x^4) with x = beta I gamma (Prop. 2 is the expansion to gamma^2).

    Two x a factor 2 apart must give the same r to ~x: a reference error of 1e-13, or a
    relative error of 1e-9 in I or Q, would shift r(5e-4) by > 1e-3. Since the expansion
    holds at every g~, this checks the nonlinear reference at g~ = 100 independently of the
    closed forms (where e is near 1)."""
    a, b = MODELS[name]
    I, Q = (float(x) for x in prop2_IQ(a, b, gtilde))
    r = []
    for x in (1e-3, 5e-4):
        g = x / (b * I)
        r.append((dop853_cor(a, b, g, gtilde).e - prop2_es(b, g, I, Q)) / x ** 3)
    assert abs(r[0] - r[1]) <= 2e-3 * max(1.0, abs(r[0])), (name, gtilde, r)
    assert 0.01 < -r[0] < 2.0   # a genuine cubic remainder, not an accident


# --- self-consistency of the nonlinear reference -------------------------------------------------

@pytest.mark.parametrize("name", ["hertz", "tti", "kk", "shc", "a2b1"])
def test_dop853_exit_velocity_and_energy_agree(name):
    """e = -w(T_f) and e = sqrt(1 - 2 gamma beta D) come out of one run with different error
    amplifications; where both are well conditioned (g~ <= 10, e >= 0.1) they agree."""
    a, b = MODELS[name]
    n = 0
    for gtilde in (0.0, 0.05, 1.0, 10.0):
        for gamma in np.logspace(-5, 0, 6):
            r = dop853_solve(a, b, gamma, gtilde)
            if r["status"] == OK and r["e"] >= 0.1:
                n += 1
                assert abs(r["e_w"] - r["e_D"]) <= 2e-11, (gamma, gtilde, r)
    assert n >= 8


@pytest.mark.parametrize("name", ["kk", "shc", "hertz"])
def test_dop853_is_converged_in_its_tolerance(name):
    a, b = MODELS[name]
    for gtilde in (0.0, 1.0, 100.0):
        for gamma in (1e-5, 1e-3, 0.1):
            r13 = dop853_cor(a, b, gamma, gtilde)
            r12 = dop853_cor(a, b, gamma, gtilde, rtol=1e-12, atol=1e-14)
            assert r13.sticks == r12.sticks
            assert abs(r13.e - r12.e) <= 1e-11, (gamma, gtilde, r13.e, r12.e)


def test_heavy_damping_at_zero_load_detaches_when_beta_exceeds_one():
    """SPEC 7: for beta > alpha the bead leaves with e ~ 1/(gamma beta). Also for alpha = beta > 1
    it leaves in finite time (the damping rate gamma beta u^(beta-1) vanishes at u = 0), with
    a tiny e -- not an endless exponential approach as SPEC 7 says for beta = alpha."""
    r = dop853_solve(1.5, 2.5, 10.0, 0.0)
    assert r["status"] == OK and r["e"] == pytest.approx(1 / (10 * 2.5), rel=1e-6)
    r = dop853_solve(1.5, 1.5, 10.0, 0.0)
    assert r["status"] == OK and 1e-6 < r["e"] < 1e-5 and r["t_f"] < 200
    # e_D has the 1/e amplification here; the reference uses e_w, converged to 1e-9 relative.
    assert r["e"] == r["e_w"]
    assert dop853_cor(1.5, 1.5, 10.0, 0.0, rtol=1e-11, atol=1e-14).e == pytest.approx(r["e"], rel=1e-9)
