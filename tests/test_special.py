"""sweep.kernels.special: Beta function, the map (43) and its inverse, I and Q by quadrature and by the
report's Chebyshev-Beta approximation, closed forms (22), (23), (39), (40).

The references here are independent: scipy's Beta function, scipy's adaptive QUADPACK with
algebraic end-point weights (QAWS) applied in the original variable u with the test's own
root u_M, and mpmath root finding.
"""
import math

import mpmath
import numpy as np
import pytest
from scipy import integrate, optimize, special as sps

from sweep.kernels import contact
from sweep.kernels import special as S

EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------------------
# Beta function
# ---------------------------------------------------------------------------------------

def test_beta_fn_against_scipy():
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(0.05, 2.0, 200), rng.uniform(2.0, 40.0, 200)])
    y = np.concatenate([rng.uniform(0.05, 4.0, 200), np.full(100, 0.5), np.full(100, 1.5)])
    got = np.array([S.beta_fn(a, b) for a, b in zip(x, y)])
    np.testing.assert_allclose(got, sps.beta(x, y), rtol=5e-14, atol=0)
    assert S.beta_fn(0.5, 0.5) == pytest.approx(math.pi, rel=1e-15)


# ---------------------------------------------------------------------------------------
# theta <-> g~ (43)
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("alpha", [1.0, 1.5, 2.7, 4.0])
def test_theta_round_trip_from_theta(alpha):
    theta = np.concatenate([np.logspace(-16, -0.01, 300), 1 - np.logspace(-15, -1, 50), [1.0]])
    back = np.array([S.theta_of_gtilde(alpha, S.gtilde_of_theta(alpha, t)) for t in theta])
    np.testing.assert_allclose(back, theta, rtol=8 * EPS, atol=0)


@pytest.mark.parametrize("alpha", [1.0, 1.5, 2.7, 4.0])
def test_theta_round_trip_from_gtilde(alpha):
    g = np.concatenate([np.logspace(-8, 8, 400), [0.05, 1.0, 10.0, 1e4]])
    theta = np.array([S.theta_of_gtilde(alpha, v) for v in g])
    back = np.array([S.gtilde_of_theta(alpha, t) for t in theta])
    # near theta = 1 the grid of doubles resolves 1 - theta ~ g~ only to eps/(1 - theta)
    cond = 1.0 + theta / (1.0 - theta)
    assert np.all(np.abs(back / g - 1) <= 8 * EPS * cond)
    assert np.all(np.diff(theta[:400]) < 0)             # decreasing in g~
    assert S.theta_of_gtilde(alpha, 0.0) == 1.0
    assert math.isnan(S.theta_of_gtilde(alpha, -1.0))
    assert math.isnan(S.theta_of_gtilde(alpha, math.inf))


def test_theta_matches_extended_precision_root():
    mpmath.mp.dps = 40
    for alpha in (1.0, 1.5, 4.0):
        a = mpmath.mpf(alpha)
        for g in (1e-6, 0.05, 1.0, 10.0, 1e4, 1e8):
            # log g~ as a function of log theta: smooth and monotone, Newton-friendly
            f = lambda s: (-mpmath.log((a + 1) / 2) / (a + 1) + s / (a + 1) - s
                           + mpmath.log(1 - mpmath.exp(s)) - mpmath.log(2) - mpmath.log(g))
            t0 = S.theta_of_gtilde(alpha, g)
            s0 = mpmath.log(mpmath.mpf(t0))
            ref = mpmath.exp(mpmath.findroot(f, (s0 * (1 + 1e-6), s0 * (1 - 1e-6)),
                                             solver="anderson"))
            # theta's condition number w.r.t. g~ is |d log g~/d log theta|^-1 <= (a+1)/a,
            # and g~(theta) itself is evaluated with ~2 ulps: ~1e-15 is full precision.
            assert abs(t0 / float(ref) - 1) <= 8 * EPS, (alpha, g)


@pytest.mark.parametrize("alpha", [1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 1.37, 2.81])
def test_umax_is_the_root_of_13_to_rounding(alpha):
    # The report's exponents take the pow-free powers of their codes, the others pow; the
    # Newton iteration starts from an upper bound at every load (mpmath bisection here).
    from reference import umax_mp
    ka = contact.make_law(alpha, alpha, 0.0, 0.0).ka
    # Loads to the largest double: u^(a+1) overflows beyond ~1e154 (it gave -inf), and
    # the bound's pow, with 1/alpha rounded, falls ~ln(bound) ulps below the root (26 ulps
    # at 1e30 for alpha = 3/2); where the root itself overflows, inf.
    loads = [0.0, 1e-9, 1e-3, 0.3, 1.0, 7.0, 500.0, 1e6, 1e12, 1e30, 1e60, 1e100, 1e154,
             1e155, 1e200, 1e250, 1e300, 1e308, 1.7e308]
    for g in loads:
        ref = float(umax_mp(alpha, g))
        got = contact.umax_undamped(alpha, g, ka)
        # Beyond 1.8e308 / (alpha + 1), u^alpha overflows: the asymptote, to ~ln(g~) ulps.
        rel = 4 * EPS if (alpha + 1) * g < 1.79e308 else 1e-13
        assert got == pytest.approx(ref, rel=rel) or got == ref == math.inf, (alpha, g, got)


def test_umax_of_many_points_at_once_is_each_points_own_bit_for_bit():
    # The lanes take u_M for all their points in one pass (contact.umax_undamped_many), the
    # points' Newton iterations interleaved; each must end on its own iteration's double,
    # at every load the scalar iteration handles (overflowing powers included) and with
    # the points' iteration counts mixed.
    rng = np.random.default_rng(7)
    n = 4000
    alpha = rng.choice([1.0, 1.25, 1.5, 2.0, 2.5, 3.0], n)
    alpha[::3] = rng.uniform(1, 8, alpha[::3].size)
    g = 10 ** rng.uniform(-12, 308, n)
    g[::7] = 10 ** rng.uniform(-4, 2, g[::7].size)
    g[::11] = 0.0
    g[::13] = rng.uniform(1.0, 1.79, g[::13].size) * 1e308
    ka = np.array([contact.make_law(a, a, 0.0, 0.0).ka for a in alpha], np.int64)
    todo = rng.permutation(n)[: n - 5]
    out = contact.umax_undamped_many(alpha, g, todo)
    own = np.array([contact.umax_undamped(a, x, k) for a, x, k in zip(alpha, g, ka)])
    np.testing.assert_array_equal(out, own[todo])


@pytest.mark.parametrize("alpha", [1.0, 1.5, 3.0])
def test_theta_agrees_with_umax(alpha):
    # (43) is the definition u_M^(a+1)/(a+1) = 1/(2 theta), with u_M the root of (13).
    for g in (0.0, 1e-3, 0.3, 7.0, 500.0):
        um = contact.umax_undamped(alpha, g, contact.make_law(alpha, alpha, 0.0, 0.0).ka)
        assert S.theta_of_gtilde(alpha, g) == pytest.approx((alpha + 1) / (2 * um ** (alpha + 1)),
                                                            rel=1e-14)


# ---------------------------------------------------------------------------------------
# I, Q by quadrature, against QUADPACK with algebraic weights
# ---------------------------------------------------------------------------------------

def _iq_reference(alpha, beta, g):
    """I and Q of Prop. 2 by scipy.integrate.quad in the variable u, with QAWS weights
    u^(b-1) at 0 and (u_M - u)^(+-1/2) at u_M; returns values and relative error estimates.

    The bracket is 1 + 2(g u - u^(a+1)/(a+1)) = (u_M - u) * D(u) with the divided difference
    D = 2 [u_M^a (1 - t^(a+1)) / ((a+1)(1 - t)) - g], t = u/u_M (from (13)), evaluated with
    expm1/log so that it has no cancellation near u_M. For large g the bracket has a layer
    of width ~1/(2g) at u = 0: the middle part is split geometrically.
    """
    ap1 = alpha + 1.0
    if g == 0.0:
        um = (ap1 / 2) ** (1 / ap1)
    else:
        h = lambda u: u ** ap1 / ap1 - g * u - 0.5
        um = optimize.brentq(h, 0.0, (ap1 * (0.5 + g)) ** (1 / alpha) + 1.0, xtol=1e-300,
                             rtol=4 * EPS, maxiter=500)

    def bracket(u):
        return 1.0 + 2.0 * (g * u - u ** ap1 / ap1)

    def divided(u):
        t = u / um
        if t >= 1.0:      # QAWS samples the end point: the limit is 2 (u_M^a - g)
            return 2.0 * (um ** alpha - g)
        return 2.0 * (um ** alpha * -np.expm1(ap1 * np.log(t)) / (ap1 * (1 - t)) - g)

    kw = dict(epsabs=0.0, epsrel=1e-13, limit=500)
    u_lay = 0.5 / g if g > 0 else um
    u1 = min(u_lay, um / 2) * 1e-2
    edges = [u1]
    while edges[-1] * 4 < um / 2:
        edges.append(edges[-1] * 4)
    edges.append(um / 2)
    vals = {}
    for p, name in ((0.5, "I"), (-0.5, "Q")):
        parts = [integrate.quad(lambda u: bracket(u) ** p, 0.0, u1, weight="alg",
                                wvar=(beta - 1, 0.0), **kw)]
        for lo, hi in zip(edges[:-1], edges[1:]):
            parts.append(integrate.quad(lambda u: bracket(u) ** p * u ** (beta - 1), lo, hi, **kw))
        parts.append(integrate.quad(lambda u: divided(u) ** p * u ** (beta - 1), um / 2, um,
                                    weight="alg", wvar=(0.0, p), **kw))
        val = sum(v for v, _ in parts)
        err = sum(e for _, e in parts)
        vals[name] = ((2.0 if name == "I" else 1.0) * val, err / abs(val))
    return vals["I"], vals["Q"]


def _quadrature_cases():
    grid = [(1.0, 1.0), (1.5, 1.5), (1.5, 1.0), (1.5, 1.25), (1.5, 2.5), (4.0, 4.0), (1.0, 4.0),
            (4.0, 1.0)]
    rng = np.random.default_rng(7)
    cases = []
    for g in (0.0, 1e-3, 0.05, 1.0, 10.0, 300.0, 1e4):
        for k in range(3):
            if k < 2:
                a, b = grid[(len(cases) + k) % len(grid)]
            else:
                a, b = rng.uniform(1, 4, 2)
            cases.append((a, b, g))
    return cases


@pytest.mark.parametrize("alpha, beta, g", _quadrature_cases())
def test_iq_quadrature_against_quadpack(alpha, beta, g):
    (i_ref, i_err), (q_ref, q_err) = _iq_reference(alpha, beta, g)
    i_, q_ = S.iq_quadrature(alpha, beta, g)
    # 1e-12 where QUADPACK itself is that good; otherwise QUADPACK's own error estimate.
    assert abs(i_ / i_ref - 1) <= max(1e-12, 10 * i_err)
    assert abs(q_ / q_ref - 1) <= max(1e-12, 10 * q_err)


def test_jm_quadrature_is_machine_precise_against_mpmath():
    """Spot check of J, M (47) at 1e-14 against 40-digit tanh-sinh quadrature."""
    mpmath.mp.dps = 40
    for alpha, beta, theta in ((1.5, 1.5, 0.3), (1.0, 2.5, 1e-9), (4.0, 1.25, 0.9)):
        a, b, t = (mpmath.mpf(v) for v in (alpha, beta, theta))
        p = lambda x: t + (1 - t) * x - x ** (a + 1)
        pts = [0, t * mpmath.mpf("1e-3")] + [t * 4 ** k for k in range(40) if t * 4 ** k < 0.5]
        pts = sorted(set(pts + [mpmath.mpf(0.5), mpmath.mpf(1)]))
        j_ref = mpmath.quad(lambda x: mpmath.sqrt(p(x)) * x ** (b - 1), pts)
        m_ref = mpmath.quad(lambda x: x ** (b - 1) / mpmath.sqrt(p(x)), pts)
        j, m = S.jm_quadrature(alpha, beta, theta)
        assert j == pytest.approx(float(j_ref), rel=1e-14)
        assert m == pytest.approx(float(m_ref), rel=1e-14)


def test_iq_quadrature_sensible_at_huge_load():
    # g~ = 1e8: I grows like g~^r (23); the ratio to C g~^r / b is 1 to ~1e-13.
    for alpha, beta in ((1.0, 1.0), (1.5, 1.5), (4.0, 2.5)):
        c, r = S.large_gtilde_constants(alpha, beta)
        i_, q_ = S.iq_quadrature(alpha, beta, 1e8)
        assert beta * i_ / (c * 1e8 ** r) == pytest.approx(1.0, abs=1e-9)
        assert np.isfinite(q_) and q_ > 0


# ---------------------------------------------------------------------------------------
# Closed forms and the report's numbers
# ---------------------------------------------------------------------------------------

def test_kk_constants():
    c0, c1 = S.first_order_constants(1.5, 1.5)
    assert c0 == pytest.approx(1.7301733, abs=5e-8)
    assert c1 == pytest.approx(3.0, rel=1e-15)
    c, r = S.large_gtilde_constants(1.5, 1.5)
    assert c == pytest.approx(4.403986, abs=5e-7)
    assert r == pytest.approx(11 / 6, rel=1e-15)
    assert (1 / (2 * c)) ** (1 / r) == pytest.approx(0.30522, abs=5e-6)    # g~_c / gamma^(-6/11)
    i0, q0 = S.iq_at_zero(1.5, 1.5)
    assert i0 == pytest.approx(1.1534489, abs=5e-8)
    assert q0 == pytest.approx(1.2687937, abs=5e-8)
    # Schwager-Poeschel: e = 1 - C0 gamma - C2 gamma^2 with C2 = -b^2 I (Q - I/2) from (38)
    # (exact: -1.79609976; Schwager-Poeschel's published c2 gives -1.79609975)
    c2 = -1.5 ** 2 * i0 * (q0 - i0 / 2)
    assert c2 == pytest.approx(-(9 / 4) * 0.7982665553, abs=2e-8)


def test_linear_q0_is_half_pi():
    assert S.iq_at_zero(1.0, 1.0)[1] == pytest.approx(math.pi / 2, rel=1e-15)
    assert S.iq_quadrature(1.0, 1.0, 0.0)[1] == pytest.approx(math.pi / 2, rel=1e-15)


@pytest.mark.parametrize("alpha, beta", [(1.0, 1.0), (1.5, 1.5), (1.5, 1.0), (1.5, 1.25),
                                         (1.5, 2.5), (2.2, 3.7), (4.0, 4.0), (1.0, 4.0)])
def test_closed_forms_at_zero_both_routes(alpha, beta):
    i0, q0 = S.iq_at_zero(alpha, beta)
    i_q, q_q = S.iq_quadrature(alpha, beta, 0.0)
    assert i_q == pytest.approx(i0, rel=2e-14)
    assert q_q == pytest.approx(q0, rel=2e-14)
    # (22) is the linearisation of (37) in g~: C0 = b I(0), C1 = b dI/dg~(0)
    c0, c1 = S.first_order_constants(alpha, beta)
    assert c0 == pytest.approx(beta * i0, rel=2e-14)
    h = 1e-4
    d1 = (S.iq_quadrature(alpha, beta, h)[0] - i0) / h
    d2 = (S.iq_quadrature(alpha, beta, 2 * h)[0] - i0) / (2 * h)
    assert c1 == pytest.approx(beta * (2 * d1 - d2), rel=1e-7)    # Richardson, O(h^2)


def test_report_checked_values_kk():
    i_, q_ = S.iq_quadrature(1.5, 1.5, 0.05)
    assert i_ == pytest.approx(1.25752517, abs=5e-9)
    assert q_ == pytest.approx(1.31835463, abs=5e-9)
    i_, q_ = S.iq_quadrature(1.5, 1.5, 10.0)
    assert i_ == pytest.approx(203.308392, abs=5e-7)
    assert q_ == pytest.approx(3.26880439, abs=5e-9)
    logx, cosjk = S.chebyshev_tables(21)
    work = np.empty((5, 22))
    i_, q_ = S.iq_chebyshev(1.5, 1.5, 0.05, 21, logx, cosjk, work)
    # the report bisected theta to a finite tolerance: agreement to ~2e-8
    assert i_ == pytest.approx(1.25724869, abs=3e-8)
    assert q_ == pytest.approx(1.31819652, abs=3e-8)


# ---------------------------------------------------------------------------------------
# Chebyshev-Beta approximation (Prop. 3-4)
# ---------------------------------------------------------------------------------------

def _cheb(alpha, beta, theta, n=21):
    logx, cosjk = S.chebyshev_tables(n)
    return S.jm_chebyshev(alpha, beta, theta, n, logx, cosjk, np.empty((5, n + 1)))


def test_chebyshev_exact_at_both_ends():
    # h = 1 at theta = 0 and 1, where M reduces to a single Beta function (96).
    for alpha, beta in ((1.5, 1.5), (1.0, 1.0), (3.0, 2.0)):
        j1, m1 = _cheb(alpha, beta, 1.0)
        jq, mq = S.jm_quadrature(alpha, beta, 1.0)
        assert m1 == pytest.approx(mq, rel=1e-12) and j1 == pytest.approx(jq, rel=1e-12)
        m0 = S.beta_fn((beta - 0.5) / alpha, 0.5) / alpha          # M(0), (96)
        assert _cheb(alpha, beta, 1e-15)[1] == pytest.approx(m0, rel=1e-9)


def test_chebyshev_relative_error_level():
    """Measured level over theta in (0, 1], beta in [1, 4], alpha = 3/2, n = 21.

    Measured: max relative error 8.2e-4 for I (beta = 4, theta ~ 0.43) and 8.5e-3 for Q
    (beta = 1 at theta ~ 7e-4; 5.9e-4 for beta >= 1.5). The report quotes errors "of the
    order of" 1e-4 (J, I) and 1e-3 (M, Q), its Figs. 26-27.
    """
    alpha = 1.5
    betas = np.linspace(1, 4, 13)
    thetas = np.concatenate([np.logspace(-8, -2, 25), np.linspace(0.01, 1, 100)])
    err_i = err_q = err_q_hi = 0.0
    for t in thetas:
        k = 2 / math.sqrt(t)   # I = K J, Q = L M: the ratios are those of J and M
        for b in betas:
            j, m = _cheb(alpha, b, t)
            jq, mq = S.jm_quadrature(alpha, b, t)
            err_i = max(err_i, abs(j / jq - 1))
            err_q = max(err_q, abs(m / mq - 1))
            if b >= 1.5:
                err_q_hi = max(err_q_hi, abs(m / mq - 1))
        assert k > 0
    assert 5e-4 < err_i < 1.0e-3
    assert 5e-3 < err_q < 1.0e-2
    assert err_q_hi < 7e-4


def test_chebyshev_order_matters():
    # Low orders are worse; n = 1 keeps only c_0 a_{0,0}.
    t, alpha, beta = 0.4, 1.5, 1.5
    _, mq = S.jm_quadrature(alpha, beta, t)
    errs = [abs(_cheb(alpha, beta, t, n)[1] / mq - 1) for n in (1, 5, 21)]
    assert errs[0] > errs[1] > errs[2]


def test_log_abs_gamma_against_scipy():
    """ln |Gamma(x + i y)| (the kappa = 0 duration's) against scipy's complex loggamma."""
    from scipy.special import loggamma

    from sweep.kernels.special import log_abs_gamma

    for x in (0.05, 0.5, 0.6, 0.9, 1.0, 1.3, 5.0, 12.0):
        for y in (0.0, 1e-3, 0.5, 3.0, 30.0, 300.0, 3e3, 3e4, 3e6):
            want = loggamma(complex(x, y)).real
            assert abs(log_abs_gamma(x, y) - want) <= 1e-14 * max(1.0, abs(want)), (x, y)
