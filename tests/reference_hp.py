"""High-precision reference for the CoR: a Taylor-series integrator in extended precision.

Nothing here imports the package under test. It solves the scaled problem (SPEC 1, 2)::

    u' = w - gamma u_+^beta,   w' = g~ - u_+^alpha,   D' = u_+^(beta-1) v^2,   v = w - gamma u^beta

from u = 0, w = 1, D = 0 through the three phases of Algorithm 1, in one of two precisions:

* ``prec="ld"``: numpy ``longdouble`` (x87 80-bit, eps = 1.1e-19), series order 26;
* ``prec="mp"``: mpmath at ``dps`` digits (default 36), series order ~45.

Method
------
Each step expands (u, w, D) in a Taylor series in tau about the step's start; the powers
u^alpha, u^beta, u^(beta-1) come from J. C. P. Miller's recurrence (u f' = a u' f), valid
while u > 0. The step is chosen from the last two coefficients (Jorba and Zou, 2005) so that
the truncation error of every component is below ``tol`` times its scale, which also keeps
the step inside the radius of convergence (the nearest zero of u in the complex tau plane).
Events (v = 0, u = u-bar, u = 0) are roots of the step's polynomials, found by safeguarded
Newton to full precision. In phases 2 and 3 u is monotone and in phase 3 v is monotone
(docs/creep.md, section 1), so a sign change at the step's end brackets every event, and the
minimum of u inside a step is the value at the root of v: grazing cannot be missed.

Non-smooth ends. u^alpha and u^(beta-1) are not analytic at u = 0, so neither end is
stepped across. The first stretch (u up to ``tol^(1/3)``-ish) uses the expansion
u = tau + g~ tau^2/2 - gamma tau^(beta+1)/(beta+1) - ..., and the last stretch, once the
remaining part is small enough for the same first-order treatment to be exact to ``tol``,
is done in closed form (``_exit_stretch``); steps in between shrink geometrically
towards u = 0, each a fixed fraction of the distance to it.

e at detachment. Three values come out: ``e_w = -w(T_f)`` (definition (3)),
``e_D = sqrt(1 - 2 gamma beta D(T_f))`` (energy identity, tests/reference.py) and the chosen
``e``, the one with the smaller estimated rounding error: e_D is immune to the exit-time
error that g~ amplifies, e_w keeps full relative accuracy when e is tiny.

Creep (docs/creep.md). Heavy damping is decided by rigorous certificates instead of a
march to rest: H = v^2/2 + F(u), F(u) = u^(alpha+1)/(alpha+1) - g~ u, never increases and
e = sqrt(2 H(T_f)), so
* ``H < 0``: the bead never leaves (STUCK);
* the invariant region R = {v >= -gamma u^beta / 2, u on the side of u_c where
  (gamma^2 beta / 4) u^(2 beta - 1) >= u^alpha} with H < F(u_c): never leaves (CREEP);
* ``sqrt(2 H) <= e_negligible``: e is below that bound (NEGLIGIBLE, e = 0 returned);
and the long overdamped stretch of kappa = alpha + 1 - 2 beta < 0 is skipped along the
slow manifold (``slow_manifold``), computed to ``tol`` by its asymptotic expansion.
The rest box max(|u - u-bar|, |v|) < 1e-8 of the report is *not* a stopping rule here: the
reference reports the physical e and flags ``rest_hit`` when the trajectory entered it.

Accuracy evidence: tests/test_reference_hp.py (closed forms, the two precisions, DOP853).
"""
from __future__ import annotations

import math

import mpmath
import numpy as np

__all__ = ["solve", "cor", "critical_gamma", "slow_manifold", "creep_constant",
           "creep_cor_asymptotic", "kappa", "OK", "STUCK", "AT_REST", "CREEP", "NEGLIGIBLE",
           "BUDGET"]

# Outcomes. OK: detached. STUCK: H < 0 or a trough with u > 0 (never leaves).
# CREEP: inside the invariant region R (creeps towards u-bar or 0 for ever, never leaves).
# NEGLIGIBLE: e <= sqrt(2H) <= e_negligible, reported as e = 0 with that bound.
# AT_REST is never produced (kept for the table's vocabulary); BUDGET: step budget spent.
OK, STUCK, AT_REST, CREEP, NEGLIGIBLE, BUDGET = 0, 1, 2, 4, 5, 3
STATUS_NAMES = {OK: "OK", STUCK: "STUCK", AT_REST: "AT_REST", CREEP: "CREEP",
                NEGLIGIBLE: "NEGLIGIBLE", BUDGET: "BUDGET"}


def kappa(alpha, beta):
    """kappa = alpha + 1 - 2 beta: the sign of the creep regime (docs/creep.md)."""
    return alpha + 1.0 - 2.0 * beta


# ---------------------------------------------------------------------------------------
# Number backends
# ---------------------------------------------------------------------------------------

class _LD:
    """numpy longdouble (80-bit extended on x86-64)."""

    name = "ld"
    eps = float(np.finfo(np.longdouble).eps)

    def __init__(self, dps=None):
        self.num = np.longdouble
        self.sqrt = np.sqrt
        self.log = np.log
        self.exp = np.exp

    def zeros(self, n):
        return np.zeros(n, dtype=np.longdouble)


class _MP:
    """mpmath at ``dps`` digits (object arrays: numpy loops, mpmath arithmetic)."""

    name = "mp"

    def __init__(self, dps=36):
        self.ctx = mpmath.MPContext()
        self.ctx.dps = dps
        self.eps = float(self.ctx.eps)
        self.num = self.ctx.mpf
        self.sqrt = self.ctx.sqrt
        self.log = self.ctx.log
        self.exp = self.ctx.exp

    def zeros(self, n):
        z = self.ctx.mpf(0)
        return np.array([z] * n, dtype=object)


def _backend(prec, dps):
    if prec == "ld":
        return _LD()
    if prec == "mp":
        return _MP(dps)
    raise ValueError(f"prec must be 'ld' or 'mp', not {prec!r}")


# ---------------------------------------------------------------------------------------
# Taylor series of one step
# ---------------------------------------------------------------------------------------

def _miller(U, f, jf, a, m, inv_u0):
    """Coefficient m of f = u^a from U[0..m] and f[0..m-1] (Miller: u f' = a u' f).

    f_m = (a m sum_j U_{m-j} f_j - (a + 1) sum_j j U_{m-j} f_j) / (m u_0), j < m.
    """
    Ur = U[m:0:-1]
    s1 = np.dot(Ur, f[:m])
    s2 = np.dot(Ur, jf[:m])
    f[m] = (a * m * s1 - (a + 1) * s2) * inv_u0 / m
    jf[m] = m * f[m]


class _Series:
    """Taylor coefficients of u, w, D, v (and of u^beta) about one point, to order K."""

    __slots__ = ("U", "W", "D", "V", "Q")

    def __init__(self, U, W, D, V, Q):
        self.U, self.W, self.D, self.V, self.Q = U, W, D, V, Q


def _series(P, u0, w0, D0):
    """Expand the state (u0 > 0) to order P.K; P is a :class:`_Problem`."""
    B, K = P.B, P.K
    U, W, D, V = B.zeros(K + 1), B.zeros(K + 1), B.zeros(K + 1), B.zeros(K + 1)
    V2, S = B.zeros(K + 1), B.zeros(K + 1)
    U[0], W[0], D[0] = u0, w0, D0
    inv_u0 = 1 / u0
    pw = {}
    for key, a in (("a", P.a), ("b", P.b), ("r", P.b - 1)):
        if key in pw:
            continue
        if P.kind[key] == "one":
            pw[key] = (U, None)
        elif P.kind[key] == "zero":
            f = B.zeros(K + 1)
            f[0] = B.num(1)
            pw[key] = (f, None)
        else:
            f, jf = B.zeros(K + 1), B.zeros(K + 1)
            f[0] = u0 ** a
            pw[key] = (f, jf)
    Pa, Qb, Rr = pw["a"][0], pw["b"][0], pw["r"][0]
    g, G = P.g, P.G
    for k in range(K):
        V[k] = W[k] - g * Qb[k]
        V2[k] = np.dot(V[:k + 1], V[k::-1])
        S[k] = np.dot(Rr[:k + 1], V2[k::-1])
        U[k + 1] = V[k] / (k + 1)
        W[k + 1] = ((G if k == 0 else 0) - Pa[k]) / (k + 1)
        D[k + 1] = S[k] / (k + 1)
        for key, a in (("a", P.a), ("b", P.b), ("r", P.b - 1)):
            f, jf = pw[key]
            if jf is not None:
                _miller(U, f, jf, a, k + 1, inv_u0)
    V[K] = W[K] - g * Qb[K]
    return _Series(U, W, D, V, Qb)


def _horner(c, x):
    s = c[-1]
    for ck in c[-2::-1]:
        s = s * x + ck
    return s


def _horner_d(c, x):
    """Value and derivative of the polynomial with coefficients c at x."""
    s = c[-1]
    d = 0 * s
    for ck in c[-2::-1]:
        d = d * x + s
        s = s * x + ck
    return s, d


def _root(B, c, target, lo, hi, iters=200):
    """Root of poly(c) = target in [lo, hi] (a sign change assumed): Newton + bisection."""
    flo = _horner(c, lo) - target
    x = 0.5 * (lo + hi)
    for _ in range(iters):
        f, d = _horner_d(c, x)
        f = f - target
        if f == 0:
            return x
        if (f > 0) == (flo > 0):
            lo, flo = x, f
        else:
            hi = x
        xn = x - f / d if d != 0 else 0.5 * (lo + hi)
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        if abs(xn - x) <= 4 * B.eps * abs(x) or hi - lo <= 4 * B.eps * hi:
            return xn
        x = xn
    return x


# ---------------------------------------------------------------------------------------
# The problem and its march
# ---------------------------------------------------------------------------------------

def _kind(a):
    return "zero" if a == 0 else ("one" if a == 1 else "gen")


class _Problem:
    """Parameters in the backend's numbers, tolerances and derived constants."""

    def __init__(self, alpha, beta, gamma, gtilde, prec, dps, order, tol):
        B = self.B = _backend(prec, dps)
        self.prec = prec
        self.af, self.bf, self.gf, self.Gf = (float(alpha), float(beta), float(gamma),
                                              float(gtilde))
        self.a, self.b, self.g, self.G = B.num(alpha), B.num(beta), B.num(gamma), B.num(gtilde)
        self.kind = {"a": _kind(self.af), "b": _kind(self.bf), "r": _kind(self.bf - 1)}
        self.tol = tol if tol is not None else B.eps / 4
        self.K = order if order is not None else int(-math.log(self.tol) / 2) + 4
        self.ubar = self.G ** (1 / self.a) if self.Gf > 0 else B.num(0)
        self.kap = kappa(self.af, self.bf)
        self.uc = self._u_c()
        self.Fmin = self.F(self.ubar) if self.Gf > 0 else B.num(0)

    def _u_c(self):
        """u_c where (gamma^2 beta / 4) u^(2 beta - 1) = u^alpha (docs/creep.md, section 3);
        inf if the region R holds for every u (kappa = 0 and gamma^2 beta >= 4), NaN if for
        none (kappa = 0 below that, or gamma = 0)."""
        c = self.gf * self.gf * self.bf / 4
        if self.gf == 0:
            return math.nan
        if self.kap == 0:
            return math.inf if c >= 1 else math.nan
        return self.B.num(c) ** (1 / self.B.num(self.kap))

    def F(self, u):
        return u ** (self.a + 1) / (self.a + 1) - self.G * u

    def H(self, u, v):
        return v * v / 2 + self.F(u)

    def vel(self, u, w):
        return w - self.g * u ** self.b


def _start(P):
    """State after the first stretch [0, tau1], by the expansion in tau (module docstring).

    tau1 makes tau, g~ tau, gamma tau^beta and tau^alpha all <= tol^(1/3): the neglected
    second-order terms are then below tol relative to what is kept.
    """
    B = P.B
    d0 = P.tol ** (1.0 / 3.0)
    t = d0
    if P.Gf > 0:
        t = min(t, d0 / P.Gf)
    if P.gf > 0:
        t = min(t, (d0 / P.gf) ** (1.0 / P.bf))
    t = B.num(t)
    a, b, g, G = P.a, P.b, P.g, P.G
    u = t + G * t * t / 2 - g * t ** (b + 1) / (b + 1) - t ** (a + 2) / ((a + 1) * (a + 2))
    w = 1 + G * t - t ** (a + 1) / (a + 1)
    D = (t ** b / b + G * (2 + (b - 1) / 2) * t ** (b + 1) / (b + 1)
         - g * (2 + (b - 1) / (b + 1)) * t ** (2 * b) / (2 * b))
    return t, u, w, D


def _step_size(P, s, u0, w0, v0, D0):
    """Largest h with truncation error <= tol * scale for u, w (and D when gamma > 0)."""
    K, tol = P.K, P.tol
    # w is judged against the largest of its own size, the damper's share of it and the speed
    # scale sqrt(2 (H - min F)) of the motion (w = v = 0 at a turning point without damping).
    swing = P.B.sqrt(2 * max(P.H(u0, v0) - P.Fmin, 0 * u0))
    scales = [(s.U, u0), (s.W, max(abs(w0), abs(v0), abs(P.g * s.Q[0]), swing))]
    if P.gf > 0:
        scales.append((s.D, D0))
    h = math.inf
    for c, sc in scales:
        for k in (K, K - 1):
            ck = abs(c[k])
            if ck > 0:
                h = min(h, float((tol * sc / ck) ** (1.0 / k)))
    if v0 < 0:
        # Exact low-degree solutions (e.g. v = -1/(gamma beta) for beta = alpha + 1) leave no
        # coefficient to judge by: never step far beyond the linear crossing of u = 0.
        h = min(h, float(2 * u0 / -v0))
    return 0.8 * h if math.isfinite(h) else 1.0


def _exit_stretch(P, u0, w0, D0):
    """Close the last stretch from (u0, w0, D0), v0 < 0, to u = 0 in closed form.

    Over the stretch u falls from u0 to 0, linearly to leading order. Kept: the load (exact,
    constant), and the first-order integrals of the non-analytic terms along the straight
    line, int u^beta dtau = u0^(beta+1) / ((beta+1)|v0|), int u^alpha dtau, the D tail
    |v0| u0^beta / beta. Their relative error is rv, the relative change of v over the
    stretch. Returns ``(T, w_exit, D_exit, err)`` with ``err`` the size of the neglected
    terms (in w, and in gamma beta D), or ``None`` if the parabola misses u = 0.
    """
    B = P.B
    a, b, g, G = P.a, P.b, P.g, P.G
    v0 = P.vel(u0, w0)
    av = -v0
    Ib = u0 ** (b + 1) / ((b + 1) * av)            # int u^beta dtau
    Ia = u0 ** (a + 1) / ((a + 1) * av)            # int u^alpha dtau
    Iaa = u0 ** (a + 2) / ((a + 1) * (a + 2) * av * av)   # int int u^alpha
    c0 = u0 - g * Ib - Iaa                         # u(T) = c0 + w0 T + G T^2 / 2 = 0
    if G > 0:
        disc = w0 * w0 - 2 * G * c0
        if disc < 0:
            return None
        T = 2 * c0 / (-w0 + B.sqrt(disc))
    else:
        T = c0 / -w0
    if not T > 0:
        return None
    w_exit = w0 + G * T - Ia
    tail = av * u0 ** b / b
    rv = (G * T + g * u0 ** b + u0 ** a * T) / av
    err_w = (G * g * Ib / av + Ia) * rv + g * Ib * rv * G * T / av
    err_D = P.g * P.b * tail * rv
    return T, w_exit, D0 + tail, max(float(err_w), float(err_D))


# ---------------------------------------------------------------------------------------
# Slow manifold (docs/creep.md, section 4)
# ---------------------------------------------------------------------------------------

def _binom_series(B, u0, a, n):
    """Coefficients of (u0 + x)^a in x, to order n."""
    c = B.zeros(n + 1)
    c[0] = u0 ** a
    for k in range(1, n + 1):
        c[k] = c[k - 1] * (a - k + 1) / (k * u0)
    return c


def _mul(B, x, y, n):
    z = B.zeros(n + 1)
    for k in range(n + 1):
        z[k] = np.dot(x[:k + 1], y[k::-1])
    return z


def slow_manifold(P, u0, n_max=None):
    """The overdamped (slow) branch v = V(u) of v dv/du = g~ - u^alpha - gamma beta u^(beta-1) v
    at u0, by the iteration V_{n+1} = (g~ - u^alpha - V_n V_n') / (gamma beta u^(beta-1)) on
    Taylor series in (u - u0); each iteration costs one order of the series. The expansion is
    asymptotic in eps(u) = u^kappa / (gamma beta)^2; it is stopped where the corrections stop
    decreasing. Returns ``(V(u0), error estimate)`` as backend numbers.
    """
    B = P.B
    n = n_max if n_max is not None else int(1.5 * -math.log(P.tol)) + 10
    num = _binom_series(B, u0, P.a, n)
    num = -num
    num[0] = num[0] + P.G
    damp = _binom_series(B, u0, P.b - 1, n) * (P.g * P.b)
    inv = B.zeros(n + 1)                         # 1 / damp
    inv[0] = 1 / damp[0]
    for k in range(1, n + 1):
        inv[k] = -np.dot(damp[1:k + 1], inv[k - 1::-1]) * inv[0]
    V = _mul(B, num, inv, n)
    best, err, prev = V[0], None, None
    for it in range(1, n):
        m = n - it
        dV = np.array([(k + 1) * V[k + 1] for k in range(m)] + [0 * V[0]], dtype=V.dtype)
        Vn = _mul(B, num[:m + 1] - _mul(B, V[:m + 1], dV, m), inv[:m + 1], m)
        d = abs(Vn[0] - V[0])
        if prev is not None and d > prev:
            break
        best, err, prev = Vn[0], d, d
        V = Vn
        if d <= P.tol * abs(Vn[0]) * 1e-3:
            break
    return best, (err if err is not None else abs(best))


# ---------------------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------------------

class _State:
    __slots__ = ("t", "u", "w", "D", "phase", "n", "u_max", "u_min", "rest_hit", "jumped",
                 "cert")

    def __init__(self, t, u, w, D):
        self.t, self.u, self.w, self.D = t, u, w, D
        self.phase, self.n = 1, 0
        self.u_max = self.u_min = math.nan
        self.rest_hit = self.jumped = False
        self.cert = ""


def _certificate(P, st, v, H, Herr):
    """Rigorous 'never leaves' tests (docs/creep.md, section 3); returns a name or ''.

    ``Herr`` bounds the rounding of H (a sum of terms of size g~ u that cancel under a load):
    every energy comparison keeps that margin.
    """
    if H + Herr < 0:
        return "H<0"
    uc = P.uc
    if P.gf == 0 or (isinstance(uc, float) and math.isnan(uc)):
        return ""
    if not v >= -P.g * st.u ** P.b / 2:
        return ""
    if P.kap > 0 or (P.kap == 0 and uc == math.inf):
        # R = {u <= u_c, v >= -gamma u^beta/2}; u <= u_c for ever if H < F(u_c), u_c > u-bar.
        if uc == math.inf:
            return "R"
        if uc > P.ubar and st.u <= uc and H + Herr < P.F(uc):
            return "R"
        return ""
    if P.kap < 0 and P.Gf > 0 and uc < P.ubar and st.u >= uc and H + Herr < P.F(uc):
        # R' = {u >= u_c, v >= -gamma u^beta/2}: F decreasing on (0, u-bar) keeps u > u_c.
        return "R'"
    return ""


def _try_jump(P, st, v):
    """Skip the overdamped stretch along the slow manifold when kappa < 0 (ends the stiff
    part of the creep); returns True if the state was moved."""
    if not (P.kap < 0 and P.gf > 0 and v < 0 and st.phase >= 2):
        return False
    B = P.B
    gb = P.g * P.b
    eps_u = st.u ** P.kap / (gb * gb)
    # Where the expansion reaches tol: its terms grow like (|kappa| n)^n eps^n (optimal
    # truncation error ~ exp(-1 / (|kappa| eps))) and, for kappa -> 0, like (4 p eps)^n.
    nt = -math.log(P.tol)
    p = P.af + 1 - P.bf
    eps_t = B.num(1.0 / (1.2 * nt * abs(P.kap) + 16 * p))
    if not eps_u < eps_t / 4:
        return False
    Vs, err = slow_manifold(P, st.u)
    # v = w - gamma u^beta carries the rounding of w (~ gamma u^beta >> |v| here).
    if not (err <= P.tol * abs(Vs) and abs(v - Vs) <= 10 * P.tol * max(abs(Vs), abs(st.w))):
        return False
    u_t = (eps_t * gb * gb) ** (1 / P.kap)
    if P.Gf > 0:
        u_t = max(u_t, P.ubar * B.num(1.1))
    if not u_t < st.u / 2:
        return False
    Vt, err_t = slow_manifold(P, u_t)
    if not err_t <= P.tol * abs(Vt):
        return False
    st.u = u_t
    st.w = Vt + P.g * u_t ** P.b
    st.t = B.num(math.nan)
    st.D = B.num(math.nan)                            # D is not followed along the jump
    st.jumped = True
    return True


def _choose_e(P, e_w, e_D, v_scale):
    """The better conditioned of e_w and e_D (module docstring); returns (e, estimated error)."""
    eps = P.B.eps
    ew = max(float(e_w), 0.0)
    if e_D is None or not math.isfinite(float(e_D)):
        return ew, 10 * eps * max(ew, 1e-300)
    ed = float(e_D)
    err_w = 10 * eps * (max(ew, 1.0) + P.Gf * v_scale / max(ew, 1e-300))
    err_D = 10 * eps * (1 - ed * ed) / (2 * max(ed, 1e-300))
    return (ed, err_D) if err_D < err_w else (ew, err_w)


def solve(alpha, beta, gamma, gtilde, prec="ld", dps=36, order=None, tol=None,
          max_steps=200_000, rest_tol=1e-8, e_negligible=None):
    """One impact. Returns a dict: ``status`` (OK, STUCK, CREEP, NEGLIGIBLE, BUDGET), ``e``
    (float), ``e_w``, ``e_D``, ``e_est_err`` (rounding estimate of the chosen e), ``e_bound``
    (upper bound of e for NEGLIGIBLE), ``t_f``, ``u_max``, ``u_min``, ``steps``,
    ``rest_hit`` (the report's rest box was entered before the end), ``jumped`` (a slow
    manifold jump was made), ``cert`` (which certificate decided).

    ``e_negligible`` (default 1e-13 of the target 1e-9's scale: ``1e3 * tol``) ends a point
    whose remaining energy bounds e below it.
    """
    P = _Problem(alpha, beta, gamma, gtilde, prec, dps, order, tol)
    B = P.B
    e_neg = e_negligible if e_negligible is not None else max(1e3 * P.tol, 1e-30)
    out = dict(status=BUDGET, e=math.nan, e_w=math.nan, e_D=math.nan, e_est_err=math.nan,
               e_bound=math.nan, t_f=math.nan, u_max=math.nan, u_min=math.nan, steps=0,
               rest_hit=False, jumped=False, cert="", prec=prec)
    if not (P.af >= 1 and P.bf >= 1 and P.gf >= 0 and P.Gf >= 0):
        raise ValueError("outside the domain alpha, beta >= 1, gamma, g~ >= 0")
    st = _State(*_start(P))
    v_scale = max(1.0, float(P.ubar))

    def finish(status, e=0.0, **kw):
        out.update(status=status, e=e, t_f=float(st.t), u_max=float(st.u_max),
                   u_min=float(st.u_min), steps=st.n, rest_hit=st.rest_hit,
                   jumped=st.jumped, cert=st.cert, **kw)
        if status in (STUCK, CREEP):
            out.update(e_w=0.0, e_D=0.0, e_est_err=0.0, e_bound=0.0)
        return out

    while st.n < max_steps:
        u, w = st.u, st.w
        v = P.vel(u, w)
        H = P.H(u, v)
        Herr = 16 * B.eps * (v * v / 2 + u ** (P.a + 1) / (P.a + 1) + P.G * u)
        if max(abs(u - P.ubar), abs(v)) < rest_tol:
            st.rest_hit = True
        cert = _certificate(P, st, v, H, Herr)
        if cert:
            st.cert = cert
            return finish(STUCK if cert == "H<0" else CREEP)
        if st.phase >= 2 and v < 0 and float(B.sqrt(2 * max(H + Herr, 0 * H))) <= e_neg:
            st.cert = "energy"
            return finish(NEGLIGIBLE, e_bound=float(B.sqrt(2 * max(H + Herr, 0 * H))))
        if st.phase >= 2 and (st.phase == 3 or P.Gf == 0) and v < 0:
            ex = _exit_stretch(P, u, w, st.D)
            if ex is not None and ex[3] <= P.tol * max(float(-v), 1e-300):
                T, w_exit, D_exit, _ = ex
                st.t = st.t + T
                e_w = -w_exit
                e_D = None
                if not st.jumped:
                    e2 = 1 - 2 * P.g * P.b * D_exit
                    e_D = B.sqrt(e2) if e2 > 0 else B.num(0)
                e, err = _choose_e(P, e_w, e_D, v_scale)
                return finish(OK, e, e_w=float(e_w),
                              e_D=float(e_D) if e_D is not None else math.nan, e_est_err=err)
        if _try_jump(P, st, v):
            continue
        res = _advance(P, st, v, v_scale)
        if res is not None:
            return finish(*res[:2], **res[2])
    return finish(BUDGET, math.nan, e_bound=float(B.sqrt(2 * max(P.H(st.u, P.vel(st.u, st.w)),
                                                                    0))))


def _advance(P, st, v0, v_scale):
    """One Taylor step with event handling; returns None or (status, e, extra) at the end."""
    B = P.B
    u0, w0, D0 = st.u, st.w, st.D
    s = _series(P, u0, w0, D0 if not st.jumped else B.num(0))
    h = _step_size(P, s, u0, w0, v0, D0 if not st.jumped else B.num(1))
    h = B.num(h)
    st.n += 1
    ue, ve = _horner(s.U, h), _horner(s.V, h)
    if st.phase == 1:
        # v may not be monotone in phase 1: sample the step for its first zero.
        xs = [h * k / 16 for k in range(1, 17)]
        for k, x in enumerate(xs):
            if _horner(s.V, x) <= 0:
                lo = xs[k - 1] if k else B.num(0)
                th = _root(B, s.V, 0, lo, x)
                _move(P, st, s, th)
                st.u_max = float(st.u)
                st.phase = 2
                return None
        _move(P, st, s, h)
        return None
    if st.phase == 2 and P.Gf > 0 and ue <= P.ubar:
        th = _root(B, s.U, P.ubar, B.num(0), h)
        _move(P, st, s, th)
        st.phase = 3
        return None
    leaving = st.phase == 3 or P.Gf == 0
    if leaving and ve >= 0:
        # The trough (v increasing through 0) inside the step: min of u there.
        th = _root(B, s.V, 0, B.num(0), h)
        umin = _horner(s.U, th)
        if umin > 0:
            _move(P, st, s, th)
            st.u_min = float(umin)
            st.cert = "trough"
            return (STUCK, 0.0, {})
        st.u_min = float(umin)
        ue = umin
        h = th
    if leaving and ue <= 0:
        # The crossing inside the step: the polynomial is trusted only up to its radius, so
        # move to a fixed fraction of the way there and let the exit stretch close it.
        th = _root(B, s.U, 0, B.num(0), h)
        _move(P, st, s, th / 2)
        return None
    _move(P, st, s, h)
    return None


def _move(P, st, s, x):
    st.t = st.t + x
    st.u = _horner(s.U, x)
    st.w = _horner(s.W, x)
    if not st.jumped:
        st.D = _horner(s.D, x)


def cor(alpha, beta, gamma, gtilde, **kw):
    """``(e, sticks)`` of :func:`solve`; e = 0 and sticks False for NEGLIGIBLE."""
    r = solve(alpha, beta, gamma, gtilde, **kw)
    return r["e"], r["status"] in (STUCK, CREEP)


# ---------------------------------------------------------------------------------------
# The stick / rebound boundary
# ---------------------------------------------------------------------------------------

def critical_gamma(alpha, beta, gtilde, rtol=1e-12, prec="ld", guess=None, **kw):
    """gamma_c(g~): rebound (OK) below, no rebound above, by bisection in log gamma on the
    reference's decision. Returns ``(lo, hi)`` with hi / lo - 1 <= rtol.

    The bracket starts from the report's threshold (24) (or ``guess``) and is widened by 4x
    until the decisions differ.
    """
    def rebounds(g):
        return solve(alpha, beta, g, gtilde, prec=prec, **kw)["status"] == OK

    if guess is None:
        a, b = float(alpha), float(beta)
        r = b / a + 1 / (2 * a) + 0.5
        C = (2 * math.sqrt(2) * b / a * (a + 1) ** (b / a + 1 / (2 * a))
             * float(mpmath.beta((b + 0.5) / a, 1.5)))
        guess = 1 / (2 * C * gtilde ** r)
    lo = hi = guess
    while not rebounds(lo):
        lo /= 4
    while rebounds(hi):
        hi *= 4
    while hi / lo - 1 > rtol:
        mid = math.sqrt(lo * hi)
        if mid <= lo or mid >= hi:
            break
        if rebounds(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi


# ---------------------------------------------------------------------------------------
# Creep asymptotics (docs/creep.md, section 4)
# ---------------------------------------------------------------------------------------

def creep_constant(alpha, beta, prec="ld", gamma_probe=None, **kw):
    """E(alpha, beta) in e ~ E (gamma beta)^(-(alpha+1)/|kappa|), kappa < 0, g~ = 0.

    Computed as the limit it is: the reference's e at a gamma large enough that the start lies
    deep in the overdamped region (eps(u_max) ~ 1e-6), times (gamma beta)^((alpha+1)/|kappa|).
    """
    k = kappa(alpha, beta)
    if not k < 0:
        raise ValueError("E is defined for kappa = alpha + 1 - 2 beta < 0")
    if gamma_probe is None:
        # eps(u_max) ~ gamma^(-(alpha+1)/beta) / beta^2: choose it ~1e-8.
        gamma_probe = (1e8 / beta ** 2) ** (beta / (alpha + 1))
    r = solve(alpha, beta, gamma_probe, 0.0, prec=prec, e_negligible=0.0, **kw)
    return r["e"] * (gamma_probe * beta) ** ((alpha + 1) / -k), r


def creep_cor_asymptotic(alpha, beta, gamma, E=None):
    """Heavy-damping CoR at g~ = 0: 0 for kappa >= 0 (in the creep regime), else
    E (gamma beta)^(-(alpha+1)/|kappa|)."""
    k = kappa(alpha, beta)
    if k >= 0:
        return 0.0
    if E is None:
        E = creep_constant(alpha, beta)[0]
    return E * (gamma * beta) ** ((alpha + 1) / k)
