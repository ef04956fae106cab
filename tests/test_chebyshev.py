"""The Chebyshev-Beta approximation of I and Q (Prop. 3-4, eqs. (43)-(53)) against the same
formula evaluated in 50-digit arithmetic.

The reference below is written from the report alone: the map (43) inverted by mpmath root
finding, the coefficients c_j (50) from h (51) at the nodes (52), the table a_{j,k} of (53)
built by the report's recurrence from mpmath Beta values, the sums (49), J from (48) and the
prefactors K, L of (47). At 50 digits the recurrence's cancellation (a few digits per order)
leaves more than 20 correct digits for n <= 41, so the reference is exact to double precision
and any difference is the package's rounding, not the approximation's truncation error (which
is much larger, ~1e-3, and the same in both).
"""
import math

import mpmath as mp
import numpy as np
import pytest

import sweep
from sweep.kernels import approx as A
from sweep.kernels import special as S

DPS = 50
HALF = mp.mpf(1) / 2

#: The five named models (alpha, beta), SPEC section 1.
MODELS = {"linear": (1.0, 1.0), "hertz": (1.5, 1.0), "tti": (1.5, 1.25), "kk": (1.5, 1.5),
          "shc": (1.5, 2.5)}

#: The example of issue 9: the old recurrence was off by ~1e-7 in e there.
ISSUE_POINT = (1.5, 1.25, 0.01298, 3.592)


def _theta_ref(alpha, gtilde):
    """Root theta in (0, 1] of (43) ``g~(theta) = g~``, in log theta (mpmath)."""
    if gtilde == 0:
        return mp.mpf(1)
    a, g = mp.mpf(alpha), mp.mpf(gtilde)

    def resid(lt):
        t = mp.exp(lt)
        return mp.log(((a + 1) / (2 * t)) ** (-1 / (a + 1)) * (1 / (2 * t) - HALF) / g)

    lo = mp.mpf(-1)
    while resid(lo) < 0:            # g~(theta) decreases: widen until g~(e^lo) > g~
        lo *= 2
    return mp.exp(mp.findroot(resid, (lo, mp.mpf(-1e-30)), solver="anderson"))


def _c_ref(alpha, theta, n):
    """c_j (50) for even j < n from h (51) at the nodes x_k (52), k = (n+1)/2 .. n."""
    a = mp.mpf(alpha)
    angles = [mp.pi * (2 * k + 1) / (2 * n + 2) for k in range((n + 1) // 2, n + 1)]
    h = []
    for ang in angles:
        x = mp.cos(ang) + 1
        h.append(mp.sqrt((x ** (1 - theta) - x ** (a + 1))
                         / (theta + (1 - theta) * x - x ** (a + 1))))
    return {j: mp.fsum(hk * mp.cos(j * ang) for hk, ang in zip(h, angles))
            * (2 if j == 0 else 4) / (n + 1) for j in range(0, n, 2)}


def _m_ref(alpha, beta, theta, n, c):
    """M_{alpha,beta}(theta) ~ sum_{j even} c_j a_{j,0} (49) with the recurrence (53)."""
    lam = mp.mpf(alpha) + theta
    row_prev = [mp.beta((beta + k - HALF + theta / 2) / lam, HALF) / lam for k in range(n)]
    row = [row_prev[k + 1] - row_prev[k] for k in range(n - 1)]
    total = c[0] * row_prev[0]
    for j in range(1, n - 1):   # row is a_{j,.}, row_prev a_{j-1,.}: build a_{j+1,.}
        row, row_prev = ([2 * row[k + 1] - 2 * row[k] - row_prev[k] for k in range(n - 1 - j)],
                         row)
        if (j + 1) % 2 == 0:
            total += c[j + 1] * row[0]
    return total


def _iq_ref(alpha, beta, gtilde, n, dps=DPS):
    """I = K J, Q = L M (47), J from (48), in dps-digit arithmetic."""
    with mp.workdps(dps):
        a, b = mp.mpf(alpha), mp.mpf(beta)
        theta = _theta_ref(alpha, gtilde)
        c = _c_ref(alpha, theta, n)
        m_b = _m_ref(a, b, theta, n, c)
        m_b1 = _m_ref(a, b + 1, theta, n, c)
        m_abp1 = _m_ref(a, a + b + 1, theta, n, c)
        j_b = ((a + 1) * m_abp1 + (theta - 1) * m_b1) / (2 * b)
        umb = ((a + 1) / (2 * theta)) ** (b / (a + 1))
        return 2 * umb / mp.sqrt(theta) * j_b, umb * mp.sqrt(theta) * m_b


def _e_ref(beta, gamma, i_, q_):
    """Prop. 2, (36)-(38), clipped to [0, 1]."""
    with mp.workdps(DPS):
        b, g = mp.mpf(beta), mp.mpf(gamma)
        bi = b * i_ * g
        e2 = 1 - 2 * bi + 2 * bi * b * q_ * g
        es = max(1 - bi + bi * b * (q_ - i_ / 2) * g, 0)
        return float(min(max(min(mp.sqrt(max(e2, 0)), es), 0), 1))


def _points():
    """Random points over alpha, beta in [1, 5], gamma in [1e-4, 0.5], g~ in [0, 100] (log),
    then the issue's example and the five models at g~ = 0.05, 1 and 37."""
    rng = np.random.default_rng(2021)
    k = 10
    gamma = 10 ** rng.uniform(-4, math.log10(0.5), k)
    gtilde = np.concatenate([[0.0], 10 ** rng.uniform(-4, 2, k - 1)])
    pts = list(zip(rng.uniform(1, 5, k), rng.uniform(1, 5, k), gamma, gtilde))
    pts.append(ISSUE_POINT)
    for a, b in MODELS.values():
        for gamma, gt in ((0.05, 0.05), (0.02, 1.0), (2e-3, 37.0)):
            pts.append((a, b, gamma, gt))
    return np.array(pts, dtype=float)


@pytest.fixture(scope="module")
def references():
    """``{n: (points, I, Q, e)}`` of the reference, computed once for the module."""
    pts = _points()
    out = {}
    for n in (5, 21, 41):
        iq = [_iq_ref(a, b, gt, n) for a, b, _, gt in pts]
        e = [_e_ref(b, g, i_, q_) for (_, b, g, _), (i_, q_) in zip(pts, iq)]
        out[n] = (pts, np.array([[float(i_), float(q_)] for i_, q_ in iq]), np.array(e))
    return out


@pytest.mark.parametrize("n", [5, 21, 41])
def test_iq_agree_with_50_digit_evaluation_of_the_same_formula(references, n):
    pts, iq, _ = references[n]
    i_, q_ = sweep.coefficients(pts[:, 0], pts[:, 1], pts[:, 3], method="approx", n=n)
    err_i = np.abs(i_ / iq[:, 0] - 1)
    err_q = np.abs(q_ / iq[:, 1] - 1)
    assert err_i.max() < 1e-12, f"I: worst {err_i.max():.2e} at {pts[np.argmax(err_i)]}"
    assert err_q.max() < 1e-12, f"Q: worst {err_q.max():.2e} at {pts[np.argmax(err_q)]}"


@pytest.mark.parametrize("n", [5, 21, 41])
def test_ord2_approx_e_agrees_with_50_digit_evaluation(references, n):
    pts, _, e_ref = references[n]
    e, status = A.approx_cor("ord2_approx", *pts.T.copy(), n=n)
    assert np.all(status == 0)
    err = np.abs(e - e_ref)
    assert err.max() < 1e-10, f"e: worst {err.max():.2e} at {pts[np.argmax(err)]}"


def test_issue_example_through_the_public_api(references):
    """``sweep.cor(..., method="ord2_approx")`` at the issue's point (default n = 21)."""
    import sweep
    pts, _, e_ref = references[21]
    k = int(np.flatnonzero(np.all(pts == ISSUE_POINT, axis=1))[0])
    assert sweep.cor(*ISSUE_POINT, method="ord2_approx") == pytest.approx(e_ref[k], abs=1e-10)


def test_high_orders_are_the_same_formula_too():
    """The quadrature step shrinks with n: n = 101 and 201 agree with the recurrence at
    enough digits (0.6 n are lost), and n beyond ``CHEBYSHEV_N_MAX`` gives NaN, not noise."""
    for n, a, b, gt in ((101, 1.5, 1.5, 0.3), (101, 4.2, 1.3, 5e4), (201, 2.5, 3.7, 2.0)):
        iq = _iq_ref(a, b, gt, n, dps=n + 30)
        got = sweep.coefficients(a, b, gt, method="approx", n=n)
        for x, ref in zip(got, iq):
            assert x == pytest.approx(float(ref), rel=1e-13)
    logx, cosjk = S.chebyshev_tables(S.CHEBYSHEV_N_MAX)
    work = np.empty((5, S.CHEBYSHEV_N_MAX + 1))
    j, m = S.jm_chebyshev(1.5, 1.5, 0.5, S.CHEBYSHEV_N_MAX, logx, cosjk, work)
    jq, mq = S.jm_quadrature(1.5, 1.5, 0.5)
    # converged to the integrals (47) up to the (slow, algebraic) truncation error
    assert j == pytest.approx(jq, rel=1e-5) and m == pytest.approx(mq, rel=1e-5)
    n = S.CHEBYSHEV_N_MAX + 2
    logx, cosjk = S.chebyshev_tables(n)
    assert np.isnan(S.jm_chebyshev(1.5, 1.5, 0.5, n, logx, cosjk, np.empty((5, n + 1)))[1])


if __name__ == "__main__":      # python tests/test_chebyshev.py: the worst differences found
    for n_, (pts_, iq_, e_) in references.__wrapped__().items():
        i_, q_ = sweep.coefficients(pts_[:, 0], pts_[:, 1], pts_[:, 3], method="approx", n=n_)
        e, _ = A.approx_cor("ord2_approx", *pts_.T.copy(), n=n_)
        print(f"n = {n_:2d}: max |I/I_ref - 1| = {np.max(np.abs(i_ / iq_[:, 0] - 1)):.1e}, "
              f"max |Q/Q_ref - 1| = {np.max(np.abs(q_ / iq_[:, 1] - 1)):.1e}, "
              f"max |e - e_ref| = {np.max(np.abs(e - e_)):.1e}  ({len(pts_)} points)")
