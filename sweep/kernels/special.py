"""Jitted special functions behind the report's closed forms (Sections 4-5, Appendices A-C).

Scalar ``numba`` functions, called from the kernels of :mod:`sweep.kernels.approx` (and from Python
for tests). All quantities are dimensionless ("1").

- :func:`beta_fn` -- Euler's Beta function ``B(x, y)`` (Def. 1); :func:`log_abs_gamma`,
  ``ln |Gamma|`` of a complex argument (the kappa = 0 duration, docs/creep.md);
- :func:`gtilde_of_theta`, :func:`theta_of_gtilde` -- the map (43) and its inverse;
- :func:`jm_quadrature`, :func:`iq_quadrature` -- ``J, M`` of (47) and ``I, Q`` of Prop. 2
  by Gauss quadrature, to about 1e-14 relative (alpha, beta <= 10);
- :func:`jm_chebyshev`, :func:`iq_chebyshev` -- the report's Chebyshev-Beta approximation
  (Prop. 3-4, eqs. 48-53), evaluated stably (below);
- :func:`iq_at_zero` (39), (40), :func:`first_order_constants` (22),
  :func:`large_gtilde_constants` (23).

Notation (report, Sec. 4.4): with ``u = u_M x`` and ``u_M^(a+1)/(a+1) = 1/(2 theta)``, the
bracket of Prop. 2 is ``1 + 2(g~ u - u^(a+1)/(a+1)) = P(x)/theta`` with::

    P(x) = theta + (1 - theta) x - x^(a+1) = theta (1 - x) + x (1 - x^a),

so that ``I = K J`` and ``Q = L M`` with ``K = 2 u_M^b / sqrt(theta)``,
``L = sqrt(theta) u_M^b`` and ``J = int_0^1 P^(1/2) x^(b-1) dx``,
``M = int_0^1 P^(-1/2) x^(b-1) dx``. Section 4.1 of the report defines ``I`` without the factor
2; this module uses Prop. 2's definition throughout (SPEC section 6).

How the finite differences of (53) are evaluated. The table of (53) is that of the integrals
(105) of Appendix C, ``a_{j,k} = int_0^1 T_j(x-1) (1 - x^lam)^(-1/2) x^(s+k) dx`` with
``lam = a + theta``, ``s = b + theta/2 - 3/2`` (``a_{0,k}`` is the Beta value of (53) by Def. 1,
``t = x^lam``; the recurrence (53) = (107), its "- a_k" read as "- a_{j,k}", is the Chebyshev
recurrence (106) applied under the integral). So the sum (49) is exactly (104)::

    sum_{j even < n} c_j a_{j,0} = int_0^1 p_n(x) (1 - x^lam)^(-1/2) x^s dx,
    p_n(x) = sum_{j even < n} c_j T_j(x - 1)   (the interpolant of h (51) at the nodes (52)).

The recurrence builds ``T_j(x - 1)`` from the monomials ``x^k``, whose coefficients sum to
``|T_j(-2)| ~ 3.7^j / 2`` in magnitude while ``|T_j(x - 1)| <= 1`` on [0, 1]: it takes
differences of Beta values that agree to many digits, and loses up to log10(3.7) ~ 0.57
digits per order (7 at n = 21 in practice; at n = 41 nothing is left). The integral (104)
has no cancellation (the weight is positive and ``p_n`` is of the size of h), so
:func:`jm_chebyshev` evaluates it instead:
``p_n`` by Clenshaw's recurrence, the integral by a tanh-sinh rule (``_DE``) that absorbs the
end-point singularities ``x^s`` and ``(1 - x)^(-1/2)``, with a step shrinking like 1/n so
that the degree n-1 of ``p_n`` is resolved. The result is the report's formula (same n,
nodes, coefficients and truncation) to ~1e-14 relative; at n = 21 it costs about what the
recurrence did.
"""
from __future__ import annotations

import math

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.vmath import exp4, expm1_4, sqrt_div4
from sweep.registry import CHEBYSHEV_N_MAX

__all__ = ["beta_fn", "log_abs_gamma", "gtilde_of_theta", "theta_of_gtilde", "jm_quadrature",
           "iq_quadrature", "jm_chebyshev", "iq_chebyshev", "chebyshev_tables", "iq_at_zero",
           "first_order_constants", "large_gtilde_constants", "THETA_MIN", "CHEBYSHEV_N_MAX"]

#: Halley's last step in :func:`theta_of_gtilde`, relative to the scale of log theta: the
#: error left is about its cube. 1e-6, 1e-5 and 3e-5 all gave theta within 4 ulps of
#: Newton's to 4e-16 (alpha U[1, 3], 20,000 loads U[0, 10] and 10^U[-8, 8]); an absolute
#: threshold instead (1e-6) left 7e-11 at theta ~ 1 - 3e-5.
HALLEY_DONE = 1e-5
#: Smallest theta the inverse map returns; larger g~ (beyond ~1e149 at alpha = 1) are out of
#: range and give NaN.
THETA_MIN = 1e-300


@jit()
def beta_fn(x, y):
    """Euler's Beta function ``B(x, y) = Gamma(x) Gamma(y) / Gamma(x + y)`` for x, y > 0.

    Through ``math.lgamma``: the relative error is a few times ``eps * |lgamma|``, about
    1e-14 for the arguments of (22)-(53) (x, y up to ~40); tested against scipy.
    """
    return math.exp(math.lgamma(x) + math.lgamma(y) - math.lgamma(x + y))


#: Stirling's series of ln Gamma(z): the coefficients B_2k / (2k (2k - 1)) of z^-(2k-1).
_STIRLING = (1.0 / 12.0, -1.0 / 360.0, 1.0 / 1260.0, -1.0 / 1680.0, 1.0 / 1188.0,
             -691.0 / 360360.0, 1.0 / 156.0)
#: |z| from which the series is summed (shifted up by the recurrence below it): the first
#: term left out, 3617 / 122400 |z|^-15, is below 1e-16 of ln Gamma there.
_STIRLING_FROM = 10.0


@jit()
def log_abs_gamma(x, y):
    """``ln |Gamma(x + i y)|`` for x > 0, in real arithmetic.

    Stirling's series at ``z + n`` (``x + n >= 10``), with ``Re z^-k = |z|^-k cos(k arg z)``,
    then ``ln |Gamma(z)| = ln |Gamma(z + n)| - sum_k ln |z + k|``. The absolute error is a few
    eps times the largest term, ``|y| pi / 2``: 1e-14 relative to the result for the
    arguments of the kappa = 0 duration (:func:`sweep.kernels.regimes.kappa_zero_free`).
    """
    shift = 0.0
    while x < _STIRLING_FROM:
        shift += 0.5 * math.log(x * x + y * y)
        x += 1.0
    r, phi = math.hypot(x, y), math.atan2(y, x)
    out = (x - 0.5) * math.log(r) - y * phi - x + 0.5 * math.log(2.0 * math.pi)
    for k in range(len(_STIRLING)):
        n = 2 * k + 1
        out += _STIRLING[k] * math.cos(n * phi) / r ** n
    return out - shift


# ----------------------------------------------------------------------------------------
# The map (43) between g~ and theta
# ----------------------------------------------------------------------------------------

@jit()
def gtilde_of_theta(alpha, theta):
    """Load ``g~(theta) = ((a+1)/(2 theta))^(-1/(a+1)) (1/(2 theta) - 1/2)``, eq. (43).

    Decreasing from ``g~(0+) = inf`` to ``g~(1) = 0``; ``theta = 1/(2 u_M^(a+1)/(a+1))``.
    """
    ap1 = alpha + 1.0
    return (ap1 / (2.0 * theta)) ** (-1.0 / ap1) * (1.0 - theta) / (2.0 * theta)


@jit()
def theta_of_gtilde(alpha, gtilde):
    """Inverse of (43): the ``theta`` in (0, 1] with ``g~(theta) = g~`` (``theta(0) = 1``).

    Safeguarded Halley iteration on ``log g~`` as a function of ``log theta`` (concave and
    decreasing), inside a bracket that every step shrinks; a step leaving the bracket is
    replaced by a geometric bisection. Halley, not Newton: the curvature is one division
    more, and the error cubes at each step, so a step below ``HALLEY_DONE`` on the scale
    of ``1 - theta`` leaves an error far below an ulp (2.8 iterations on the Sobol design's
    loads against Newton's 4.5). The residual ``log(g~(theta)/g~)`` is formed from the
    ratio, not from the difference of two logarithms, so theta comes out to a few ulps for
    g~ up to 1e100 (``theta >= THETA_MIN``; beyond, NaN). NaN for negative or non-finite
    g~.
    """
    if not (gtilde >= 0.0) or not math.isfinite(gtilde) or not (alpha >= 1.0):
        return math.nan
    if gtilde == 0.0:
        return 1.0
    ap1 = alpha + 1.0
    c1 = (0.5 * ap1) ** (-1.0 / ap1)          # g~ ~ c1 (1 - theta)/2 near theta = 1
    expo = ap1 / alpha
    # Bracket: g~(theta_hi) <= g~ <= g~(theta_lo). For theta <= 1/2, (1 - theta) >= 1/2
    # gives g~(theta) >= c1 theta^(-a/(a+1)) / 4.
    lo = min(0.5, (c1 / (4.0 * gtilde)) ** expo)
    if lo < THETA_MIN:
        return math.nan
    hi = 1.0
    # Initial guess exact to first order at both ends: 1 - 2g~/c1 and (c1/(2g~))^((a+1)/a).
    z = 2.0 * gtilde / c1
    th = 1.0 / (1.0 + z + z ** expo)
    if th == 1.0:       # 1 - theta ~ z below half an ulp of 1: theta rounds to 1
        return 1.0
    for _ in range(200):
        g = gtilde_of_theta(alpha, th)
        r = math.log(g / gtilde)                # > 0: theta too small
        if r == 0.0:
            return th
        if r > 0.0:
            lo = th
        else:
            hi = th
        q = th / (1.0 - th)
        slope = -(alpha / ap1 + q)              # d log g~ / d log theta
        step = -r / slope
        # The curvature -q / (1 - theta) is d slope / d log theta.
        step = step / (1.0 - 0.5 * step * q / ((1.0 - th) * slope))
        th_new = th * math.exp(step)
        # Near theta = 1 the scale of log theta is 1 - theta ~ 1 / q, not 1.
        if abs(step) * (1.0 + q) < HALLEY_DONE:
            return th_new
        if not (lo < th_new < hi):
            th_new = math.sqrt(lo * hi)
        if th_new == th:
            return th
        th = th_new
    return th


# ----------------------------------------------------------------------------------------
# I(g~), Q(g~) by quadrature
# ----------------------------------------------------------------------------------------

def _gauss_legendre_01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return np.ascontiguousarray(0.5 * (x + 1.0)), np.ascontiguousarray(0.5 * w)


# Split point of [0, 1]; panel length of the logarithmic panels on [h0, SPLIT]; h0 / min(theta,
# SPLIT); node counts. Chosen by measuring against 40-digit mpmath quadrature over alpha,
# beta in [1, 4], theta in [1e-13, 1]: worst relative error 2.2e-15 (16 nodes per panel; 14
# gave 1e-13, 20 no better). tests/test_special.py re-checks against mpmath and QUADPACK.
_SPLIT = 0.5
_PANEL = 2.5
_TAIL = 1e-3
_TAIL_TERMS = 8
_XL, _WL = _gauss_legendre_01(16)
_XR, _WR = _gauss_legendre_01(14)


def _right_panel_table():
    """Rows ``d = (1 - c) s^2`` and ``log1p(-d)`` at the nodes s of [c, 1]: they depend on
    the nodes only. Formed as the kernel formed them per point (math's log1p is the C
    library's, like numba's), so hoisting them changed no bit; 14 log1p a point less."""
    d = [(1.0 - _SPLIT) * s * s for s in _XR]
    return np.array([d, [math.log1p(-v) for v in d]])


_DR = _right_panel_table()
# The nodes go to the vector exps four at a time (vmath.exp4): the left panel's 16 fill
# whole tuples; the right panel's last tuple is part empty.
_BY = 4
assert _XL.size % _BY == 0


@jit()
def _tail_series(p, alpha, beta, theta, h0):
    """``int_0^h0 x^(b-1) P(x)^p dx`` for ``h0 <= 1e-3 min(theta, 1/2)``.

    ``P^p = (theta + (1-theta) x)^p (1 - x^(a+1)/(theta + (1-theta)x))^p``: the binomial
    series in ``z = (1-theta) h0/theta <= 1e-3`` integrated term by term, plus the first-order
    term in ``x^(a+1)/theta <= 1e-6`` (second order is below 1e-12 of this small tail).
    """
    z = (1.0 - theta) * h0 / theta
    eps = math.exp((alpha + 1.0) * math.log(h0)) / theta
    s1 = 0.0
    s2 = 0.0
    b1 = 1.0    # binom(p, k)
    b2 = 1.0    # binom(p - 1, k)
    zk = 1.0
    for k in range(_TAIL_TERMS):
        s1 += b1 * zk / (beta + k)
        s2 += b2 * zk / (beta + alpha + 1.0 + k)
        b1 *= (p - k) / (k + 1.0)
        b2 *= (p - 1.0 - k) / (k + 1.0)
        zk *= z
    return theta ** p * h0 ** beta * (s1 - p * eps * s2)


@jit(inline="always")
def _four(g, last):
    """Node indices ``g .. g + 3`` for a call of the 4-tuple functions; those past ``last``
    are ``last`` again (computed, not summed)."""
    return g, min(g + 1, last), min(g + 2, last), min(g + 3, last)


@jit()
def _right_sums(alpha, beta, theta):
    """Gauss sums of ``J`` and ``M`` on [c, 1] (``x = 1 - (1 - c) s^2``) before their
    constant factors: nodes in order, their exps four at a time (:func:`exp4`)."""
    jr = 0.0
    mr = 0.0
    for g in range(0, _XR.size, _BY):
        i0, i1, i2, i3 = _four(g, _XR.size - 1)
        ex = expm1_4((alpha * _DR[1, i0], alpha * _DR[1, i1], alpha * _DR[1, i2],
                      alpha * _DR[1, i3]))
        eb = exp4(((beta - 1.0) * _DR[1, i0], (beta - 1.0) * _DR[1, i1],
                   (beta - 1.0) * _DR[1, i2], (beta - 1.0) * _DR[1, i3]))
        # r = theta + x (1 - x^a)/(1 - x) at the four nodes.
        rs = (theta + (1.0 - _DR[0, i0]) * (-ex[0] / _DR[0, i0]),
              theta + (1.0 - _DR[0, i1]) * (-ex[1] / _DR[0, i1]),
              theta + (1.0 - _DR[0, i2]) * (-ex[2] / _DR[0, i2]),
              theta + (1.0 - _DR[0, i3]) * (-ex[3] / _DR[0, i3]))
        srs, ms = sqrt_div4(rs, (_WR[i0] * eb[0], _WR[i1] * eb[1], _WR[i2] * eb[2],
                                 _WR[i3] * eb[3]))
        for k in range(min(_BY, _XR.size - g)):
            i = g + k
            s = _XR[i]
            mr += ms[k]
            jr += _WR[i] * s * s * srs[k] * eb[k]
    return jr, mr


@jit()
def _node_factors(f, width, g):
    """``exp(f width t_i)`` at the left-panel nodes ``t_i = _XL[g:g + 4]``."""
    fw = f * width
    return exp4((fw * _XL[g], fw * _XL[g + 1], fw * _XL[g + 2], fw * _XL[g + 3]))


@jit()
def _left_group(theta, base, fx, fa, fb, g, jp, mp):
    """Add four nodes ``_XL[g:g + 4]`` of a panel to its sums ``jp, mp``, in node order;
    the powers of x are the panel's ``base`` (``e^(f s0)``, f = 1, alpha, beta) times the
    nodes' factors ``fx, fa, fb``."""
    xs = (base[0] * fx[0], base[0] * fx[1], base[0] * fx[2], base[0] * fx[3])
    xa = (base[1] * fa[0], base[1] * fa[1], base[1] * fa[2], base[1] * fa[3])
    xb = (base[2] * fb[0], base[2] * fb[1], base[2] * fb[2], base[2] * fb[3])
    pv = (theta * (1.0 - xs[0]) + xs[0] * (1.0 - xa[0]),   # no cancellation
          theta * (1.0 - xs[1]) + xs[1] * (1.0 - xa[1]),
          theta * (1.0 - xs[2]) + xs[2] * (1.0 - xa[2]),
          theta * (1.0 - xs[3]) + xs[3] * (1.0 - xa[3]))
    sps, xb_sp = sqrt_div4(pv, (_WL[g] * xb[0], _WL[g + 1] * xb[1], _WL[g + 2] * xb[2],
                                _WL[g + 3] * xb[3]))
    for k in range(_BY):
        mp += xb_sp[k]
        jp += _WL[g + k] * xb[k] * sps[k]
    return jp, mp


@jit()
def _left_sums(alpha, beta, theta, lo, width, m):
    """Gauss sums of ``J`` and ``M`` over the m panels [lo + p width, lo + (p + 1) width]
    of ``x = e^s`` (16 nodes each), before the factor ``width``.

    At a node ``s = s0 + width t_i`` the powers are ``x^f = e^(f s0) e^(f width t_i)``
    (f = 1, alpha, beta): the node factors are the same in every panel, so a point takes
    ``3 (16 + m)`` exps, not ``3 16 m``.
    """
    # The node offsets as int64, not as literals: numba compiles a dispatcher once per
    # literal argument, and the four groups made four copies of each helper (0.7 s of the
    # first compile).
    g0, g1, g2, g3 = int(0), int(_BY), int(2 * _BY), int(3 * _BY)
    fx0, fx1, fx2, fx3 = (_node_factors(1.0, width, g0), _node_factors(1.0, width, g1),
                          _node_factors(1.0, width, g2), _node_factors(1.0, width, g3))
    fa0, fa1, fa2, fa3 = (_node_factors(alpha, width, g0), _node_factors(alpha, width, g1),
                          _node_factors(alpha, width, g2), _node_factors(alpha, width, g3))
    fb0, fb1, fb2, fb3 = (_node_factors(beta, width, g0), _node_factors(beta, width, g1),
                          _node_factors(beta, width, g2), _node_factors(beta, width, g3))
    jl = 0.0
    ml = 0.0
    for p in range(m):
        s0 = lo + p * width
        base = exp4((s0, alpha * s0, beta * s0, 0.0))
        jp, mp = _left_group(theta, base, fx0, fa0, fb0, g0, 0.0, 0.0)
        jp, mp = _left_group(theta, base, fx1, fa1, fb1, g1, jp, mp)
        jp, mp = _left_group(theta, base, fx2, fa2, fb2, g2, jp, mp)
        jp, mp = _left_group(theta, base, fx3, fa3, fb3, g3, jp, mp)
        jl += jp
        ml += mp
    return jl, ml


@jit()
def jm_quadrature(alpha, beta, theta):
    """``J(theta)`` and ``M(theta)`` of (47) by composite Gauss-Legendre quadrature.

    The integrands ``P^(+-1/2) x^(b-1)`` have three awkward spots, each removed by a change of
    variable so that plain Gauss-Legendre nodes see analytic functions:

    - ``x = 1``: ``P`` has a simple zero (the bracket's zero at ``u_M``). On [1/2, 1] put
      ``x = 1 - s^2/2``: ``P = (1 - x) R(x)`` with ``R = theta + x (1 - x^a)/(1 - x) > 0``
      analytic there, and the end-point weights ``(1-x)^(1/2) dx`` and ``(1-x)^(-1/2) dx``
      become ``s^2 ds`` and ``ds`` (times constants): the weight is absorbed exactly, as a
      Gauss-Jacobi rule would do. ``R`` is evaluated from ``d = 1 - x`` with
      ``log1p``/``expm1``, free of cancellation.
    - ``x = 0``: ``x^(b-1)`` and ``x^(a+1)`` are not analytic for non-integer exponents, and
      for large g~ (small theta) ``P = theta + x + ...`` has a boundary layer of width theta.
      On [h0, 1/2], ``x = e^s`` makes every power of x entire in s; the only singularity
      left, ``P = 0`` near ``x = -theta``, sits at distance pi from the real s axis, and
      panels of length 2.5 in s with 16 nodes reach ~1e-16.
    - [0, h0] with ``h0 = 1e-3 min(theta, 1/2)``: a convergent series (``_tail_series``).

    Cost: 62 nodes at theta >= 1/2, growing like ``6.4 log(1/theta)`` (~190 at 1e-9). The
    nodes' exps go to libmvec four at a time (:mod:`sweep.kernels.vmath`, within 4 ulp);
    on [h0, 1/2] the powers of x are products of a panel's and a node's exps
    (:func:`_left_sums`). About 0.5 us a point on the Sobol design (2026-12-04, Zen 4).

    Parameters
    ----------
    alpha, beta : float
        Exponents [1], >= 1.
    theta : float
        Parameter of (43) [1], in (0, 1].

    Returns
    -------
    J, M : float
        The integrals (47) [1].
    """
    c = _SPLIT
    one_c = 1.0 - c
    # [c, 1]: x = 1 - (1 - c) s^2, s in [0, 1].
    jr, mr = _right_sums(alpha, beta, theta)
    mr *= 2.0 * math.sqrt(one_c)
    jr *= 2.0 * one_c * math.sqrt(one_c)
    # [h0, c]: x = e^s, dx = x ds, in m equal panels.
    h0 = _TAIL * min(theta, c)
    lo = math.log(h0)
    span = math.log(c) - lo
    m = int(math.ceil(span / _PANEL))
    width = span / m
    jl, ml = _left_sums(alpha, beta, theta, lo, width, m)
    jl *= width
    ml *= width
    jt = _tail_series(0.5, alpha, beta, theta, h0)
    mt = _tail_series(-0.5, alpha, beta, theta, h0)
    return jr + jl + jt, mr + ml + mt


@jit()
def _k_l(alpha, beta, theta):
    """``K(theta)`` and ``L(theta)`` of (47)."""
    umb = (0.5 * (alpha + 1.0) / theta) ** (beta / (alpha + 1.0))   # u_M^b
    st = math.sqrt(theta)
    return 2.0 * umb / st, umb * st


@jit()
def iq_quadrature(alpha, beta, gtilde):
    """``I(g~)`` and ``Q(g~)`` of Prop. 2 by quadrature (:func:`jm_quadrature`)::

        I = 2 int_0^{u_M} [1 + 2(g~ u - u^(a+1)/(a+1))]^(+1/2) u^(b-1) du
        Q =   int_0^{u_M} [1 + 2(g~ u - u^(a+1)/(a+1))]^(-1/2) u^(b-1) du

    (the report's (41), (42) print ``g~`` where ``g~ u`` is meant, SPEC section 6). Relative
    error ~1e-14 for alpha, beta in [1, 10], g~ in [0, 1e8] (4e-14 at g~ = 1e120); it
    grows past alpha, beta ~ 10 (1e-11 at alpha = 20, 1e-5 at 200); NaN beyond the range of
    theta, and from alpha + beta ~ 310.
    """
    theta = theta_of_gtilde(alpha, gtilde)
    if not (theta > 0.0):
        return math.nan, math.nan
    j, m = jm_quadrature(alpha, beta, theta)
    k, l = _k_l(alpha, beta, theta)
    return k * j, l * m


# ----------------------------------------------------------------------------------------
# The report's Chebyshev-Beta approximation (Prop. 3-4, Appendix C)
# ----------------------------------------------------------------------------------------

# Tanh-sinh rule for the integrals (104) that the sums (49) equal (module docstring):
# x = 1/(1 + exp(-pi sinh t)), trapezoidal in t with step h on |t| <= 4, where the integrand
# times dx/dt has fallen below ~1e-17 of the integral at both ends for every end-point
# behaviour of (104) (x^(s+1) with s + 1 >= 1/2, and (1 - x)^(1/2)). The integrand contains
# the degree n-1 polynomial p_n, so h must shrink like 1/n: h <= min(0.1, 4/(n + 19)) keeps
# the quadrature error below ~1e-14 relative for n <= 201 and alpha, beta in [1, 10]
# (measured against the recurrence in mpmath at 50-230 digits; h = 0.1 at the report's
# n = 21). One table at step 1/_DE_PER_UNIT serves every n: step m/_DE_PER_UNIT takes every
# m-th node.
_DE_TMAX = 4
_DE_RULE = 4                    # h (n + 19) <= 4
# Fine enough for the largest order the registry admits (640 / 4 = 160 nodes per unit t).
_DE_PER_UNIT = -(-(CHEBYSHEV_N_MAX + 19) // _DE_RULE)
_DE_STRIDE_MAX = _DE_PER_UNIT // 10     # h = 0.1


def _tanh_sinh_table():
    """Rows x, log x, z = 2 (1 - x)^2 - 1 and dx/dt at t = i/_DE_PER_UNIT, |t| <= _DE_TMAX.

    ``x``, ``1 - x`` and ``log x = -log1p(exp(-u))`` are each formed from ``exp(-u)``,
    ``u = pi sinh t``, without subtraction, so they keep full relative precision at both
    ends (x and 1 - x down to ~1e-37), where ``x^s`` and ``(1 - x^lam)^(-1/2)`` need it.
    """
    t = np.arange(-_DE_TMAX * _DE_PER_UNIT, _DE_TMAX * _DE_PER_UNIT + 1) / _DE_PER_UNIT
    u = np.pi * np.sinh(t)
    x = 1.0 / (1.0 + np.exp(-u))
    d = 1.0 / (1.0 + np.exp(u))                  # 1 - x
    logx = -np.log1p(np.exp(-u))
    dxdt = np.pi * np.cosh(t) * x * d
    return np.ascontiguousarray(np.vstack((x, logx, 2.0 * d * d - 1.0, dxdt)))


_DE = _tanh_sinh_table()


@jit()
def _de_stride(n):
    """Stride through ``_DE`` for order n: step ``min(0.1, 4/(n+19))``; 0 beyond N_MAX."""
    return min(_DE_STRIDE_MAX, (_DE_RULE * _DE_PER_UNIT) // (n + 19))


@jit()
def chebyshev_tables(n):
    """Tables of (50)-(52) that depend on the order n only (n odd).

    Returns
    -------
    logx : ndarray, shape ((n+1)/2,)
        ``log x_k`` for the nodes ``x_k = cos(pi (2k+1)/(2n+2)) + 1`` in (0, 1),
        ``k = (n+1)/2 .. n`` (52).
    cosjk : ndarray, shape ((n+1)/2, (n+1)/2)
        ``cos(j pi (2k+1)/(2n+2))`` for even ``j = 0, 2, .., n-1`` (rows) and those k.
    """
    half = (n + 1) // 2
    logx = np.empty(half)
    cosjk = np.empty((half, half))
    for i in range(half):
        k = half + i
        ang = math.pi * (2 * k + 1) / (2 * n + 2)
        logx[i] = math.log(math.cos(ang) + 1.0)
        for jj in range(half):
            cosjk[jj, i] = math.cos(2 * jj * ang)
    return logx, cosjk


@jit()
def _chebyshev_coefficients(alpha, theta, n, logx, cosjk, cj):
    """``c_j`` of (50) for even ``j < n`` into ``cj[j/2]``, from ``h`` (51) at the nodes (52).

    Odd c_j vanish: h is interpolated as an even function of ``x - 1`` on [0, 2].
    """
    half = (n + 1) // 2
    for jj in range(half):
        cj[jj] = 0.0
    for g in range(0, half, _BY):
        # Four nodes' exps a call.
        i0, i1, i2, i3 = _four(g, half - 1)
        lx = (logx[i0], logx[i1], logx[i2], logx[i3])
        xs = exp4(lx)
        xa = exp4(((alpha + 1.0) * lx[0], (alpha + 1.0) * lx[1], (alpha + 1.0) * lx[2],
                   (alpha + 1.0) * lx[3]))
        xt = exp4(((1.0 - theta) * lx[0], (1.0 - theta) * lx[1], (1.0 - theta) * lx[2],
                   (1.0 - theta) * lx[3]))
        for k in range(min(_BY, half - g)):
            x = xs[k]
            xap1 = xa[k]
            h = math.sqrt((xt[k] - xap1) / (theta * (1.0 - x) + x - xap1))
            for jj in range(half):
                cj[jj] += h * cosjk[jj, g + k]
    cj[0] *= 2.0 / (n + 1)
    for jj in range(1, half):
        cj[jj] *= 4.0 / (n + 1)


@jit(inline="always")
def _clenshaw4(cj, half, z0, z1, z2, z3):
    """``p_n = sum_{j even} c_j T_j(x - 1)`` at four nodes (``z = 2 (x - 1)^2 - 1``) by
    Clenshaw's recurrence, the four side by side: one node's chain of dependent
    multiply-adds is latency-bound, four fill the vector unit. Each node's operations are
    those of the one-node recurrence, in its order."""
    a0 = a1 = a2 = a3 = 0.0     # b_{j+1}
    d0 = d1 = d2 = d3 = 0.0     # b_{j+2}
    for jj in range(half - 1, 0, -1):
        c = cj[jj]
        a0, d0 = 2.0 * z0 * a0 - d0 + c, a0
        a1, d1 = 2.0 * z1 * a1 - d1 + c, a1
        a2, d2 = 2.0 * z2 * a2 - d2 + c, a2
        a3, d3 = 2.0 * z3 * a3 - d3 + c, a3
    c = cj[0]
    return z0 * a0 - d0 + c, z1 * a1 - d1 + c, z2 * a2 - d2 + c, z3 * a3 - d3 + c


@jit()
def _beta_moments(alpha, beta, theta, n, cj):
    """The sums (49) for ``M_{a,b}``, ``M_{a,b+1}``, ``M_{a,a+b+1}`` as the integrals (104)::

        sum_{j even} c_j a_{j,0} = int_0^1 p_n(x) (1 - x^lam)^(-1/2) x^s x^q dx,
        s = b + theta/2 - 3/2,  lam = a + theta,  q = 0, 1, a + 1

    (module docstring), by the tanh-sinh rule ``_DE`` at the step
    ``_de_stride(n) / _DE_PER_UNIT``. ``p_n = sum_{j even} c_j T_j(x - 1)`` is summed by
    Clenshaw's recurrence in ``z = 2 (x - 1)^2 - 1`` (``T_{2i}(y) = T_i(2 y^2 - 1)``, stable
    for |z| <= 1); ``1 - x^lam`` as ``-expm1(lam log x)``, accurate near x = 1 where it
    vanishes.
    """
    half = (n + 1) // 2
    m = _de_stride(n)
    lam = alpha + theta
    s = beta + 0.5 * theta - 1.5
    ap1 = alpha + 1.0
    mid = _DE.shape[1] // 2
    top = mid // m
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    for g in range(-top, top + 1, _BY):
        # Table columns of four nodes (past the last node: the middle one, not summed).
        c0, c1, c2, c3 = (mid + g * m, mid + (g + 1) * m if g + 1 <= top else mid,
                          mid + (g + 2) * m if g + 2 <= top else mid,
                          mid + (g + 3) * m if g + 3 <= top else mid)
        xs = exp4((s * _DE[1, c0], s * _DE[1, c1], s * _DE[1, c2], s * _DE[1, c3]))
        xl = expm1_4((lam * _DE[1, c0], lam * _DE[1, c1], lam * _DE[1, c2],
                      lam * _DE[1, c3]))
        xa = exp4((ap1 * _DE[1, c0], ap1 * _DE[1, c1], ap1 * _DE[1, c2], ap1 * _DE[1, c3]))
        ps = _clenshaw4(cj, half, _DE[2, c0], _DE[2, c1], _DE[2, c2], _DE[2, c3])
        _, fs = sqrt_div4((-xl[0], -xl[1], -xl[2], -xl[3]),
                          (_DE[3, c0] * ps[0] * xs[0], _DE[3, c1] * ps[1] * xs[1],
                           _DE[3, c2] * ps[2] * xs[2], _DE[3, c3] * ps[3] * xs[3]))
        for k in range(min(_BY, top + 1 - g)):
            i = mid + (g + k) * m
            f = fs[k]
            m0 += f
            m1 += f * _DE[0, i]
            m2 += f * xa[k]
    h = m / _DE_PER_UNIT
    return h * m0, h * m1, h * m2


@jit()
def jm_chebyshev(alpha, beta, theta, n, logx, cosjk, work):
    """``J(theta)``, ``M(theta)`` by the report's Chebyshev-Beta approximation.

    ``M_{a,b}(theta) ~ sum_{j even < n} c_j a_{j,0}`` (49)-(53): the factor
    ``h = sqrt((x^(1-theta) - x^(a+1)) / P(x))`` (51) of the integrand is interpolated at the
    Chebyshev nodes (52) and the products with ``(1 - x^(a+theta))^(-1/2) x^(b+theta/2-3/2)``
    are integrated exactly through Beta functions. ``J`` follows from (48):
    ``J_{a,b} = (a+1)/(2b) M_{a,a+b+1} + (theta-1)/(2b) M_{a,b+1}``. The coefficients c_j are
    shared by the three M.

    The sums (49) are evaluated as the integrals (104) they equal (module docstring), not by
    the recurrence (53), whose cancellation loses up to ~0.57 digits per order (7 at n = 21,
    all at n = 41): the result is the report's formula to ~1e-14 relative (measured for n up
    to 201 against the recurrence in 50- to 230-digit arithmetic, tests/test_chebyshev.py).

    Exact at theta = 0 and 1 (h = 1); in between the relative error at n = 21 is up to ~1e-3
    for J and ~8.5e-3 for M (alpha = 3/2, beta in [1, 4]; the interpolation error of h).

    Parameters
    ----------
    alpha, beta, theta : float
        Exponents [1] (>= 1) and theta [1] in (0, 1].
    n : int
        Odd order of the approximation (the report uses 21), at most ``CHEBYSHEV_N_MAX``
        (beyond: NaN).
    logx, cosjk : ndarray
        From :func:`chebyshev_tables` ``(n)``.
    work : ndarray, shape (5, n + 1)
        Scratch space (row 0 holds the c_j; the shape is that of earlier versions).

    Returns
    -------
    J, M : float
        The approximations (48), (49) of the integrals (47) [1].
    """
    if _de_stride(n) < 1:
        return math.nan, math.nan
    cj = work[0]
    _chebyshev_coefficients(alpha, theta, n, logx, cosjk, cj)
    m_b, m_b1, m_abp1 = _beta_moments(alpha, beta, theta, n, cj)
    j_b = ((alpha + 1.0) * m_abp1 + (theta - 1.0) * m_b1) / (2.0 * beta)
    return j_b, m_b


@jit()
def iq_chebyshev(alpha, beta, gtilde, n, logx, cosjk, work):
    """``I(g~) = K J``, ``Q(g~) = L M`` (47) with J, M from :func:`jm_chebyshev`.

    Theta comes from :func:`theta_of_gtilde` (the report's step 1 of Sec. 5 uses bisection).
    """
    theta = theta_of_gtilde(alpha, gtilde)
    if not (theta > 0.0):
        return math.nan, math.nan
    j, m = jm_chebyshev(alpha, beta, theta, n, logx, cosjk, work)
    k, l = _k_l(alpha, beta, theta)
    return k * j, l * m


# ----------------------------------------------------------------------------------------
# Closed forms
# ----------------------------------------------------------------------------------------

@jit()
def iq_at_zero(alpha, beta):
    """Exact ``I(0)`` (39) and ``Q(0)`` (40)::

        I(0) = ((a+1)/2)^(b/(a+1) - 1) (a+1)/(a+1+2b) B(1/2, b/(a+1))
        Q(0) = ((a+1)/2)^(b/(a+1) - 1) (1/2) B(1/2, b/(a+1))

    KK (a = b = 3/2): 1.1534489, 1.2687937; a = b = 1: Q(0) = pi/2.
    """
    ap1 = alpha + 1.0
    f = (0.5 * ap1) ** (beta / ap1 - 1.0) * beta_fn(0.5, beta / ap1)
    return f * ap1 / (ap1 + 2.0 * beta), 0.5 * f


@jit()
def first_order_constants(alpha, beta):
    """``C0`` and ``C1`` of the first-order, small-g~ approximation (22)::

        C0 = b ((a+1)/2)^((b-a-1)/(a+1)) B(b/(a+1), 3/2)     (= b I(0))
        C1 = b ((a+1)/2)^((b-a)/(a+1))   B((b+1)/(a+1), 1/2) (= b dI/dg~ (0))

    KK: C0 = 1.7301733, C1 = 3.
    """
    ap1 = alpha + 1.0
    c0 = beta * (0.5 * ap1) ** ((beta - ap1) / ap1) * beta_fn(beta / ap1, 1.5)
    c1 = beta * (0.5 * ap1) ** ((beta - alpha) / ap1) * beta_fn((beta + 1.0) / ap1, 0.5)
    return c0, c1


@jit()
def large_gtilde_constants(alpha, beta):
    """``C`` and the exponent ``r`` of the large-g~ approximation (23)::

        e^2 = 1 - 2 gamma C g~^r,   r = b/a + 1/(2a) + 1/2,
        C = 2 sqrt(2) (b/a) (a+1)^(b/a + 1/(2a)) B((b + 1/2)/a, 3/2)

    KK: C = 4.403986, r = 11/6.
    """
    r = beta / alpha + 0.5 / alpha + 0.5
    c = (2.0 * math.sqrt(2.0) * beta / alpha * (alpha + 1.0) ** (r - 0.5)
         * beta_fn((beta + 0.5) / alpha, 1.5))
    return c, r
