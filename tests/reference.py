"""Slow, independent reference solutions for the coefficient of restitution (CoR).

Nothing here imports the package under test: these are the judges of ``sweep.integrate``.
All functions work on the scaled problem of the report (SPEC section 1)::

    u'' + gamma d/dtau (u_+^beta) + u_+^alpha = g~,   u(0) = 0,  u'(0) = 1,

written in the Lipschitz form (SPEC section 2)::

    u' = w - gamma u_+^beta,   w' = g~ - u_+^alpha,   v = w - gamma u_+^beta (velocity).

References
----------
``linear_cor``
    alpha = beta = 1, exact (SPEC section 4), evaluated in 40-digit mpmath arithmetic.
``tti_cor_g0``
    TTI (alpha = 3/2, beta = 5/4) at g~ = 0: the phase-plane map onto a linear oscillator.
``dop853_cor`` / ``dop853_solve``
    scipy's DOP853 through the three phases of the report's Algorithm 1, with grazing
    detection, a final segment integrated with u as the independent variable (no event
    location across the non-smooth point u = 0) and the energy identity below.

The energy identity
-------------------
With E = v^2/2 + u^(alpha+1)/(alpha+1) - g~ u, one has dE/dtau = -gamma beta u^(beta-1) v^2
while in contact, and E = v^2/2 at both ends of the impact (u = 0), so::

    e^2 = 1 - 2 gamma beta D,    D = int_0^{T_f} u_+^(beta-1) v^2 dtau.

``dop853_solve`` integrates D alongside (u, w). Computing e from D turns an absolute error
of the trajectory (amplified by g~ through the exit-time error, ~1e-9 at g~ = 100) into a
*relative* error of D times (1 - e^2)/(2 e), which is what makes this reference reach
~1e-12 where e = -w(T_f) alone is off by ~1e-9 (SPEC section 7).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import mpmath
import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["RefResult", "linear_cor", "linear_solution", "tti_cor_g0", "dop853_solve",
           "dop853_cor", "umax_mp", "prop2_IQ", "prop2_IQ0", "prop2_es",
           "OK", "STUCK", "AT_REST", "BUDGET_EXHAUSTED"]

# Outcome codes, numerically equal to sweep.model.Status (kept independent on purpose).
OK, STUCK, AT_REST, BUDGET_EXHAUSTED = 0, 1, 2, 3


class RefResult(NamedTuple):
    """CoR ``e``, ``sticks`` (no rebound: e == 0), end time ``t_f`` and maximum compression."""

    e: float
    sticks: bool
    t_f: float
    u_max: float


# ---------------------------------------------------------------------------------------
# Linear spring-dashpot, alpha = beta = 1 (SPEC section 4)
# ---------------------------------------------------------------------------------------

_DPS = 40


def linear_solution(gamma, gtilde):
    """The exact u(tau) and u'(tau) of u'' + gamma u' + u = g~, u(0) = 0, u'(0) = 1 (mpmath).

    Underdamped only (xi = gamma/2 < 1)::

        u(tau) = g~ + e^{-xi tau} (A cos(omega tau) + B sin(omega tau)),
        A = -g~,  B = (1 - xi g~) / omega,  omega = sqrt(1 - xi^2)

    (u(0) = A + g~ = 0 and u'(0) = -xi A + omega B = 1), and differentiating::

        u'(tau) = e^{-xi tau} (cos(omega tau) + k sin(omega tau)),  k = (g~ - xi) / omega.

    While u > 0 the (u, w) system is this linear ODE and v = w - gamma u = u'.
    Returns ``(u, du, xi, omega)`` with ``u``, ``du`` callables of an mpf.
    """
    g = mpmath.mpf(gamma)
    G = mpmath.mpf(gtilde)
    xi = g / 2
    if not xi < 1:
        raise ValueError("linear_solution is for the underdamped case gamma < 2")
    om = mpmath.sqrt(1 - xi * xi)
    A = -G
    B = (1 - xi * G) / om
    k = (G - xi) / om

    def u(t):
        return G + mpmath.exp(-xi * t) * (A * mpmath.cos(om * t) + B * mpmath.sin(om * t))

    def du(t):
        return mpmath.exp(-xi * t) * (mpmath.cos(om * t) + k * mpmath.sin(om * t))

    return u, du, xi, om


def linear_cor(gamma, gtilde):
    """Exact CoR of the linear spring-dashpot (alpha = beta = 1), error ~1e-30 before rounding.

    * Underdamped (gamma < 2). u' vanishes where cot(omega tau) = -k (see ``linear_solution``),
      i.e. at tau_0 = atan2(omega, xi - g~)/omega (maximum compression, in (0, pi/omega)) and
      then every pi/omega; u falls monotonically from tau_0 to the first trough
      tau_0 + pi/omega. If u(trough) < 0, the exit time T_f is the unique root of u in
      (tau_0, tau_0 + pi/omega), found by bisection to 1e-38, and e = -u'(T_f). Otherwise u
      never reaches 0 again (later troughs are higher, g~ - C e^{-xi tau}): the bead sticks,
      e = 0 (a trough exactly at u = 0 counts as sticking, as in the SPEC). At g~ = 0 this
      gives T_f = pi/omega and e = exp(-xi pi/omega).
    * Overdamped or critical (gamma >= 2): u - g~ is a combination of two decaying real
      exponentials, so u has at most one extremum and never returns to 0 for g~ > 0 (the
      bead creeps to rest at u = g~, e = 0). At g~ = 0,
      u = (e^{r1 tau} - e^{r2 tau})/(r1 - r2) > 0 for all tau > 0 with r2 < r1 < 0: the bead
      approaches u = 0 only asymptotically, with velocity -> 0, so e = 0 (the limit; the
      integrator reaches it through the rest criterion). t_f is NaN then (no finite end).

    Returns ``RefResult(e, sticks, t_f, u_max)`` as Python floats.
    """
    gamma = float(gamma)
    gtilde = float(gtilde)
    if not (gamma >= 0 and gtilde >= 0 and math.isfinite(gamma) and math.isfinite(gtilde)):
        raise ValueError("need finite gamma >= 0 and g~ >= 0")
    if gamma >= 2.0:
        # u_max is the single maximum of the overdamped solution (if any): not needed here.
        return RefResult(0.0, True, math.nan, math.nan)
    with mpmath.workdps(_DPS):
        u, du, xi, om = linear_solution(gamma, gtilde)
        G = mpmath.mpf(gtilde)
        tau0 = mpmath.atan2(om, xi - G) / om
        trough = tau0 + mpmath.pi / om
        u_max = u(tau0)
        u_tr = u(trough)
        if u_tr >= 0:
            return RefResult(0.0, True, float(trough), float(u_max))
        lo, hi = tau0, trough          # u(lo) > 0 > u(hi), u decreasing in between
        tol = mpmath.mpf(10) ** (-(_DPS - 2))
        while hi - lo > tol * hi:
            mid = (lo + hi) / 2
            if u(mid) > 0:
                lo = mid
            else:
                hi = mid
        t_f = (lo + hi) / 2
        return RefResult(float(-du(t_f)), False, float(t_f), float(u_max))


# ---------------------------------------------------------------------------------------
# TTI at g~ = 0 (SPEC section 4)
# ---------------------------------------------------------------------------------------

def tti_cor_g0(gamma):
    """CoR of TTI (alpha = 3/2, beta = 5/4) at g~ = 0, exact.

    In the phase plane, v dv/du + (5/4) gamma u^(1/4) v + u^(3/2) = 0. With
    u = c y^(4/5), c = (5/4)^(2/5) (so c^(5/2) = 5/4 and c^(5/4) = sqrt(5)/2) this becomes
    v dv/dy + 2 xi v + y = 0 with xi = gamma sqrt(5)/4: the phase curve of a linear damped
    oscillator from (y, v) = (0, 1) back to y = 0, hence e = exp(-pi xi / sqrt(1 - xi^2)).
    For xi >= 1 the linear phase curve reaches y = 0 only at v = 0: e = 0.
    """
    xi = float(gamma) * math.sqrt(5.0) / 4.0
    if xi >= 1.0:
        return 0.0
    return math.exp(-math.pi * xi / math.sqrt(1.0 - xi * xi))


# ---------------------------------------------------------------------------------------
# scipy DOP853 through Algorithm 1
# ---------------------------------------------------------------------------------------

def _event(fun, direction, terminal=True):
    fun.direction = direction
    fun.terminal = terminal
    return fun


def dop853_solve(alpha, beta, gamma, gtilde, rtol=1e-13, atol=1e-15, rest_tol=1e-8,
                 t_max=1e4):
    """Integrate one impact with DOP853 and return a dict of everything found.

    Phases (report, Algorithm 1), each a ``solve_ivp`` run on y = (u, w, D),
    D' = u_+^(beta-1) v^2, stopped by terminal events located on DOP853's dense output:

    1. from tau = 0 until v = 0 downward (maximum compression u_max);
    2. until u = u-bar downward (for g~ = 0, u-bar = 0: this is the detachment);
    3. until u = 0 downward (detach) or v = 0 upward (stick if u > 0 there).

    In every phase max(|u - u-bar|, |v|) < rest_tol ends the run with e = 0 (at rest), and
    tau > t_max with status BUDGET_EXHAUSTED (e = NaN). The energy
    H = v^2/2 + u_+^(alpha+1)/(alpha+1) - g~ u never increases and equals e^2/2 >= 0 at a
    detachment, so H < -1e-12 (1 + g~ u) also ends a run: STUCK, e = 0. That decides
    overdamped points quickly instead of following their creep to rest.

    Grazing (SPEC section 7): solve_ivp sees an event only where its function changes sign
    between step ends, so a dip of u below 0 inside one step would be missed. In phase 3
    v rises from negative values, so any such dip contains the trough v = 0, which *is*
    seen; u at that trough is the minimum of u. If it is <= 0 the detachment was missed,
    and the phase is re-run from the previous step end with steps 64x shorter (repeated
    until the crossing shows). Hence the stick/rebound decision is the sign of min u.

    Precision at the exit: after the detachment is found, the last stretch (from the last
    accepted step end, where u > 0 and v < 0) is integrated again with u as the independent
    variable, d(tau, w, D)/du = (1/v, (g~ - u^alpha)/v, u^(beta-1) v), from u_a exactly to
    u = 0. That avoids both event location and stepping across the kink at u = 0. v stays
    negative on that stretch: in phase 3 (u < u-bar, v < 0) v' = g~ - u^alpha -
    gamma beta u^(beta-1) v > 0, so v rises monotonically to -e; at g~ = 0 v' = -u^alpha < 0
    wherever v = 0, so v cannot reach 0 from below. Two CoR values come out:

    * ``e_w = -w(T_f)`` (the report's definition (3)),
    * ``e_D = sqrt(1 - 2 gamma beta D)`` (energy identity, module docstring),

    Their errors differ in kind: e_w inherits the exit-time error times u'' = g~ there
    (~ rtol g~ (1 + 2 g~) / e), e_D the relative error of D times (1 - e^2) / (2 e). ``e`` is
    e_D when 1 - e_D^2 < max(1, 2 g~ (1 + 2 g~)) / 2, else e_w. Measured against the linear
    closed form (tests/test_references.py) the chosen value is within ~1e-12 except within
    ~1e-5 (relative, in gamma) of the stick/rebound boundary, where every value is
    ill-conditioned (e ~ sqrt(dip depth), SPEC section 7).
    """
    a, b, gam, G = float(alpha), float(beta), float(gamma), float(gtilde)
    ubar = G ** (1.0 / a)
    bm1 = b - 1.0

    def rhs(t, y):
        u, w, _ = y
        if u > 0.0:
            v = w - gam * u ** b
            return (v, G - u ** a, (u ** bm1) * v * v)
        return (w, G, 0.0)

    def vel(y):
        u = y[0]
        return y[1] - gam * u ** b if u > 0.0 else y[1]

    ev_vdown = _event(lambda t, y: vel(y), -1)
    ev_vup = _event(lambda t, y: vel(y), +1)
    ev_ubar = _event(lambda t, y: y[0] - ubar, -1)
    ev_u0 = _event(lambda t, y: y[0], -1)
    ev_rest = _event(lambda t, y: max(abs(y[0] - ubar), abs(vel(y))) - rest_tol, -1)

    def energy_margin(t, y):
        u = y[0] if y[0] > 0.0 else 0.0
        v = vel(y)
        return 0.5 * v * v + u ** (a + 1.0) / (a + 1.0) - G * u + 1e-12 * (1.0 + G * u)

    ev_sunk = _event(energy_margin, -1)

    out = dict(status=None, e=math.nan, e_w=math.nan, e_D=math.nan, t_f=math.nan,
               u_max=math.nan, u_min=math.nan, nfev=0, refinements=0)

    def run(t0, y0, events, max_step=np.inf):
        sol = solve_ivp(rhs, (t0, t_max), y0, method="DOP853", rtol=rtol, atol=atol,
                        events=events, dense_output=False, max_step=max_step)
        out["nfev"] += sol.nfev
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        hit = [k for k, te in enumerate(sol.t_events) if len(te)]
        if not hit:                       # reached t_max
            return None, sol.t[-1], sol.y[:, -1], sol
        k = min(hit, key=lambda k: sol.t_events[k][0])
        return k, sol.t_events[k][0], sol.y_events[k][0], sol

    def finish(status, t, y):
        out["status"] = status
        out["t_f"] = t
        if status in (STUCK, AT_REST):
            out["e"] = out["e_w"] = out["e_D"] = 0.0
        return out

    # Phase 1: maximum compression.
    k, t, y, _ = run(0.0, [0.0, 1.0, 0.0], [ev_vdown, ev_rest, ev_sunk])
    if k is None:
        return finish(BUDGET_EXHAUSTED, t, y)
    if k == 1:
        return finish(AT_REST, t, y)
    if k == 2:
        return finish(STUCK, t, y)
    out["u_max"] = y[0]

    # Phase 2: down to the equilibrium compression (g~ = 0: to the floor).
    k, t, y, sol = run(t, y, [ev_ubar, ev_rest, ev_sunk])
    if k is None:
        return finish(BUDGET_EXHAUSTED, t, y)
    if k == 1:
        return finish(AT_REST, t, y)
    if k == 2:
        return finish(STUCK, t, y)

    if G > 0.0:
        # Phase 3: first of u = 0 (detach) and v = 0 (trough).
        t3, y3 = t, y
        max_step = np.inf
        while True:
            k, t, y, sol = run(t3, y3, [ev_u0, ev_vup, ev_rest, ev_sunk], max_step=max_step)
            if k is None:
                return finish(BUDGET_EXHAUSTED, t, y)
            if k == 2:
                return finish(AT_REST, t, y)
            if k == 3:
                return finish(STUCK, t, y)
            if k == 1:
                out["u_min"] = y[0]
                if y[0] > 0.0:
                    return finish(STUCK, t, y)
                # Missed a detachment inside one step: rerun that step in shorter steps.
                out["refinements"] += 1
                if out["refinements"] > 12:
                    raise RuntimeError("could not resolve a grazing detachment")
                t3, y3 = sol.t[-2], sol.y[:, -2]
                max_step = (t - t3) / 64.0
                continue
            break
    # Detached at (t, y). Redo the last stretch with u as the independent variable.
    # sol.t[-1] is the event time; the last accepted step end before it has u > 0.
    j = len(sol.t) - 2
    while j > 0 and not (sol.y[0, j] > 0.0 and vel(sol.y[:, j]) < 0.0):
        j -= 1
    ta, ya = sol.t[j], sol.y[:, j]
    if ya[0] > 0.0 and vel(ya) < 0.0:
        def rhs_u(u, z):
            tau, w, _ = z
            up = u if u > 0.0 else 0.0
            v = w - gam * up ** b
            return (1.0 / v, (G - up ** a) / v, (up ** bm1) * v if up > 0.0 else 0.0)

        solu = solve_ivp(rhs_u, (ya[0], 0.0), [ta, ya[1], ya[2]], method="DOP853",
                         rtol=rtol, atol=atol)
        out["nfev"] += solu.nfev
        if solu.status != 0:
            raise RuntimeError(f"solve_ivp (u-parametrised) failed: {solu.message}")
        t, w, D = solu.y[:, -1]
    else:                                  # pragma: no cover - defensive
        w, D = y[1], y[2]
    out["e_w"] = -w
    e2 = 1.0 - 2.0 * gam * b * D
    out["e_D"] = math.sqrt(e2) if e2 > 0.0 else 0.0
    use_D = (1.0 - e2) < 0.5 * max(1.0, 2.0 * G * (1.0 + 2.0 * G))
    out["e"] = out["e_D"] if use_D else out["e_w"]
    return finish(OK, t, None)


def dop853_cor(alpha, beta, gamma, gtilde, rtol=1e-13, atol=1e-15, **kw):
    """``RefResult(e, sticks, t_f, u_max)`` from ``dop853_solve`` (see there).

    ``e`` is NaN (and sticks False) when the budget ``t_max`` ran out.
    """
    r = dop853_solve(alpha, beta, gamma, gtilde, rtol=rtol, atol=atol, **kw)
    return RefResult(float(r["e"]), r["status"] in (STUCK, AT_REST), float(r["t_f"]),
                     float(r["u_max"]))


# ---------------------------------------------------------------------------------------
# Small-gamma expansion of Prop. 2 (SPEC section 3), by high-precision quadrature
# ---------------------------------------------------------------------------------------

def umax_mp(alpha, gtilde, dps=30):
    """Undamped maximum compression u_M: the root of u^(a+1)/(a+1) - g~ u = 1/2 (13), mpmath.

    The left side is negative on (0, (g~ (a+1))^(1/a)) and increasing beyond, so the root is
    bracketed by [max(that, 0), that + u_M(0) + 1] and found by bisection.
    """
    with mpmath.workdps(dps + 10):
        a = mpmath.mpf(alpha)
        G = mpmath.mpf(gtilde)
        f = lambda u: u ** (a + 1) / (a + 1) - G * u - mpmath.mpf(1) / 2
        lo = (G * (a + 1)) ** (1 / a) if G > 0 else mpmath.mpf(0)
        hi = lo + ((a + 1) / 2) ** (1 / (a + 1)) + 1
        while hi - lo > mpmath.mpf(10) ** (-(dps + 5)) * hi:
            mid = (lo + hi) / 2
            if f(mid) > 0:
                hi = mid
            else:
                lo = mid
        return +(lo + hi) / 2


def prop2_IQ(alpha, beta, gtilde, dps=30):
    """I(g~) and Q(g~) of Prop. 2 (SPEC section 3) by tanh-sinh quadrature in mpmath::

        I = 2 int_0^{u_M} B(u)^(+1/2) u^(beta-1) du,  Q = int_0^{u_M} B(u)^(-1/2) u^(beta-1) du,
        B(u) = 1 + 2 (g~ u - u^(alpha+1)/(alpha+1)).

    B has a simple zero at u_M; with u = u_M (1 - s^2) the square-root singularity becomes
    smooth (B ~ 2 s^2 u_M B'(u_M)... ), leaving only the u^(beta-1) endpoint at s = 1, which
    tanh-sinh integrates to full precision. Returns mpf values.
    """
    with mpmath.workdps(dps + 10):
        a = mpmath.mpf(alpha)
        b = mpmath.mpf(beta)
        G = mpmath.mpf(gtilde)
        um = umax_mp(alpha, gtilde, dps + 10)

        def B_over_s2(s):
            # B(u_M (1 - s^2)) / s^2 without cancellation: B(u_M) = 0, so B(u) = B(u) - B(u_M)
            # = 2 g~ (u - u_M) - 2 (u^(a+1) - u_M^(a+1))/(a+1), with u = u_M (1 - s^2).
            if s == 0:
                return 2 * um * (um ** a - G)
            # (u_M^(a+1) - u^(a+1)) / s^2 = u_M^(a+1) (1 - (1 - s^2)^(a+1)) / s^2
            t = -mpmath.expm1((a + 1) * mpmath.log1p(-s * s)) / (s * s)
            return -2 * G * um + 2 * um ** (a + 1) * t / (a + 1)

        def jac(s):                       # du = -2 u_M s ds
            return 2 * um * (um * (1 - s * s)) ** (b - 1)

        # B^(1/2) du = s sqrt(B/s^2) * 2 u_M s u^(b-1) ds ; B^(-1/2) du = (1/s) ... * s
        I = 2 * mpmath.quad(lambda s: s * s * mpmath.sqrt(B_over_s2(s)) * jac(s), [0, 1])
        Q = mpmath.quad(lambda s: jac(s) / mpmath.sqrt(B_over_s2(s)), [0, 1])
        return +I, +Q


def prop2_IQ0(alpha, beta):
    """Exact I(0), Q(0) of the SPEC, (39), (40) (floats)."""
    a, b = float(alpha), float(beta)
    c = ((a + 1) / 2) ** (b / (a + 1) - 1) * mpmath.beta(0.5, b / (a + 1))
    return float(c * (a + 1) / (a + 1 + 2 * b)), float(c / 2)


def prop2_es(beta, gamma, I, Q):
    """Second-order expansion in gamma, e_s = 1 - beta I gamma + beta^2 I (Q - I/2) gamma^2
    (before the clipping at 0 of the SPEC); the remainder is O(gamma^3)."""
    return 1 - beta * I * gamma + beta * beta * I * (Q - I / 2) * gamma * gamma
