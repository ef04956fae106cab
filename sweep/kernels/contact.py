"""The contact law: every formula of the physics the kernels evaluate, in one place.

The report's law (1), scaled by (2), in the Lipschitz form of its Sec. 3 (state ``(u, w)``)::

    u' = w - gamma u_+^beta        w' = g~ - u_+^alpha        v = w - gamma u_+^beta

A point's parameters travel as one :class:`Law` (the exponents with the codes that select a
pow-free evaluation of their powers, the damping and the load). The integrator, the
step-size rule, the events and the approximations call the functions below; none of them
writes a power of u, the velocity, the acceleration, the dissipated energy or a regime
number (u-bar, xi, omega_n, u_M) again. A new contact law (another pair of exponents, or
another form of the damping force) changes this module and :mod:`sweep.registry` only.

Owns: the right-hand side, velocity, acceleration, dissipated energy, damping rate, regime
numbers, the jitted domain test. May import: :mod:`sweep.registry`, vmath.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.vmath import (exp1, log1, vmul, vsqrt, vsqrt_where_equal, vsub,
                                 vwhere_equal, vwhere_nonnegative, vwhere_positive)
from sweep.registry import PARAMETERS

__all__ = ["Law", "make_law", "put_law", "law_at", "LAW_COLUMNS", "rhs_at", "power_kind", "ppow",
           "ppow_called", "rhs", "rhs_called", "velocity", "accel", "dissipated", "potential",
           "damping_rate", "equilibrium", "well_depth", "well_depth_at", "damping_ratio",
           "overdamped_at_rest", "natural_frequency", "umax_undamped", "umax_undamped_many",
           "elastic_frequency", "in_domain", "KIND_ONE", "KIND_EXPONENTS", "general_exponents",
           "general_at", "general_arguments", "rhs_general", "gtilde_rows", "vector_law_at",
           "vector_law", "rhs_vector"]

# Exponents of the report's models get a pow-free evaluation: pow() dominates the cost of a
# stage, and sqrt is exact-rounded and several times cheaper.
(KIND_ONE, _KIND_THREE_HALVES, _KIND_TWO, _KIND_FIVE_HALVES, _KIND_FIVE_FOURTHS, _KIND_THREE,
 _KIND_ZERO, _KIND_HALF, _KIND_QUARTER) = range(9)
_KIND_GENERAL = 99
#: The exponent of each code, in the codes' order (:func:`power_kind` is its inverse).
KIND_EXPONENTS = (1.0, 1.5, 2.0, 2.5, 1.25, 3.0, 0.0, 0.5, 0.25)
#: ``u_M(0) = ((a + 1)/2)^(1/(a + 1))`` of :func:`umax_undamped` for each code's exponent a,
#: formed here by the same operations (Python's float power is the C library's pow, as
#: numba's): a pow less a march.
_UMAX_FREE = tuple((0.5 * (a + 1.0)) ** (1.0 / (a + 1.0)) for a in KIND_EXPONENTS)

_ALPHA_MIN = PARAMETERS["alpha"].minimum
_BETA_MIN = PARAMETERS["beta"].minimum
_GAMMA_MIN = PARAMETERS["gamma"].minimum
_GAMMA_MAX = PARAMETERS["gamma"].maximum
_GTILDE_MIN = PARAMETERS["gtilde"].minimum


class Law(NamedTuple):
    """Scaled parameters of one point and the :func:`power_kind` codes of its powers."""

    alpha: float
    beta: float
    gamma: float
    gtilde: float
    ka: int       # kind of alpha
    kb: int       # kind of beta
    kd: int       # kind of beta - 1
    smooth: bool  # both exponents are integers: rhs continues the polynomials to u < 0


@jit(inline="always")
def in_domain(alpha, beta, gamma, gtilde):
    """The point lies in :data:`sweep.registry.PARAMETERS` (finite, above the minima, gamma
    up to its maximum)."""
    return (alpha >= _ALPHA_MIN and beta >= _BETA_MIN and _GAMMA_MIN <= gamma <= _GAMMA_MAX
            and gtilde >= _GTILDE_MIN and math.isfinite(alpha) and math.isfinite(beta)
            and math.isfinite(gtilde))


@jit()
def power_kind(p):
    """Code selecting the evaluation of ``x**p`` in :func:`ppow`."""
    if p == 1.0:
        return KIND_ONE
    if p == 1.5:
        return _KIND_THREE_HALVES
    if p == 2.0:
        return _KIND_TWO
    if p == 2.5:
        return _KIND_FIVE_HALVES
    if p == 1.25:
        return _KIND_FIVE_FOURTHS
    if p == 3.0:
        return _KIND_THREE
    if p == 0.0:
        return _KIND_ZERO
    if p == 0.5:
        return _KIND_HALF
    if p == 0.25:
        return _KIND_QUARTER
    return _KIND_GENERAL


@jit(inline="always")
def make_law(alpha, beta, gamma, gtilde):
    """The :class:`Law` of a point (its power codes computed once)."""
    return Law(alpha, beta, gamma, gtilde, power_kind(alpha), power_kind(beta),
               power_kind(beta - 1.0), _integer(alpha) and _integer(beta))


#: Columns of the float (``F``) and int (``I``) rows that hold a :class:`Law` (:func:`put_law`).
LAW_COLUMNS = (4, 4)


@jit(inline="always")
def put_law(F, I, row, c):
    """Store the :class:`Law` ``c`` in ``row`` of ``F`` (float64, 4 columns: the exponents,
    damping and load) and ``I`` (int64, 4 columns: the power codes and ``smooth``), for
    drivers that hold several points' laws in arrays (:func:`law_at` and :func:`rhs_at`
    read it back)."""
    F[row, 0] = c.alpha
    F[row, 1] = c.beta
    F[row, 2] = c.gamma
    F[row, 3] = c.gtilde
    I[row, 0] = c.ka
    I[row, 1] = c.kb
    I[row, 2] = c.kd
    I[row, 3] = 1 if c.smooth else 0


@jit(inline="always")
def law_at(F, I, row):
    """The :class:`Law` stored in ``row`` of ``F`` and ``I`` by :func:`put_law`."""
    return Law(F[row, 0], F[row, 1], F[row, 2], F[row, 3], I[row, 0], I[row, 1], I[row, 2],
               I[row, 3] != 0)


@jit(inline="always")
def gtilde_rows(F, first):
    """The loads g~ of the :data:`~sweep.kernels.vmath.VECTOR` laws in the rows of ``F``
    from ``first`` (:func:`put_law`), alone, as a tuple (a vector operand)."""
    return _column(F, first, 3)


@jit(inline="always")
def _integer(p):
    return p == 1.0 or p == 2.0 or p == 3.0


def _power(x, p, kind):
    """``x**p`` for ``x > 0``, and 0 for ``x <= 0`` (the report's ``x_+^p``; also for p = 0,
    where it is the indicator of contact, closed at x = 0: the bead is in contact from its
    first instant, so the damper acts at tau = 0)."""
    if kind == _KIND_ZERO:
        return 1.0 if x >= 0.0 else 0.0
    if x <= 0.0:
        return 0.0
    if kind == KIND_ONE:
        return x
    if kind == _KIND_THREE_HALVES:
        return x * math.sqrt(x)
    if kind == _KIND_TWO:
        return x * x
    if kind == _KIND_FIVE_HALVES:
        return x * x * math.sqrt(x)
    if kind == _KIND_FIVE_FOURTHS:
        return x * math.sqrt(math.sqrt(x))
    if kind == _KIND_THREE:
        return x * x * x
    if kind == _KIND_HALF:
        return math.sqrt(x)
    if kind == _KIND_QUARTER:
        return math.sqrt(math.sqrt(x))
    return x ** p


#: :func:`_power` inlined into its caller: for the stages' right-hand side (:func:`rhs`),
#: where it is most of a step's cost and the exponent codes fold away.
ppow = jit(inline="always")(_power)
#: The same compiled once and called: for everything else (velocity, energies, events,
#: creep rules, the decision), off the per-step path; inlining its ten branches at each of
#: those call sites cost compile time (seconds), not speed.
ppow_called = jit()(_power)


@jit(inline="always")
def _polynomial(x, kind):
    """``x^p`` for the integer kinds (0, 1, 2, 3), for any sign of x."""
    if kind == _KIND_ZERO:
        return 1.0
    if kind == KIND_ONE:
        return x
    if kind == _KIND_TWO:
        return x * x
    return x * x * x


@jit(inline="always")
def _forces(w, beta, gamma, gtilde, pd, pb, pa):
    """``(u', w', r')`` from the powers ``(u^(beta-1), u^beta, u^alpha)`` (:func:`rhs`;
    :func:`rhs_vector` writes the same operations for vectors)."""
    v = w - gamma * pb
    return v, gtilde - pa, -gamma * pb * (gtilde - pa - gamma * beta * pd * v)


@jit(inline="always")
def _general(kd, ka, smooth):
    """The law takes :func:`rhs`'s general branch (for u > 0): its powers are
    ``exp(p log u)``."""
    return kd == _KIND_GENERAL and ka == _KIND_GENERAL and not smooth


@jit(inline="always")
def _general_arguments(alpha, beta, lu):
    """Arguments of the exps of the general branch, ``((beta - 1) log u, alpha log u)``."""
    return (beta - 1.0) * lu, alpha * lu


@jit()
def general_exponents(alpha, beta):
    """The law of ``(alpha, beta)`` takes :func:`rhs`'s general branch (for u > 0)."""
    c = make_law(alpha, beta, 0.0, 0.0)     # its codes, as every driver forms them
    return _general(c.kd, c.ka, c.smooth)


@jit(inline="always")
def general_at(I, row):
    """The law in ``row`` of ``I`` (:func:`put_law`) takes :func:`rhs`'s general branch
    where u > 0: its stages need ``log u`` and two exps (:func:`rhs_general`)."""
    return _general(I[row, 2], I[row, 0], I[row, 3] != 0)


@jit(inline="always")
def general_arguments(F, row, lu):
    """The exps' arguments of the law in ``row`` of ``F`` from ``lu = log u``
    (:func:`rhs`'s general branch)."""
    return _general_arguments(F[row, 0], F[row, 1], lu)


@jit(inline="always")
def rhs_general(u, w, F, row, pd, pa):
    """``rhs(u, w, law_at(F, I, row))`` for u > 0 and a law of :func:`general_at`, from the
    exps of :func:`general_arguments` (``pd = u^(beta-1)``, ``pa = u^alpha``), value for
    value: for drivers that compute the powers of several points at once."""
    return _forces(w, F[row, 1], F[row, 2], F[row, 3], pd, u * pd, pa)


def _rhs_with(power):
    """:func:`rhs` taking the coded powers with ``power`` (:func:`_power`, inlined or
    called)."""

    def rhs(u, w, c):
        """Right-hand side of (4) and of the dissipation integral: returns ``(u', w', r')``.

        The energy dissipated by the damper is ``q = int gamma beta u^(beta-1) v^2 dtau``; by
        parts (``beta u^(beta-1) v = d(u^beta)/dtau``) ``q = gamma v u_+^beta + r`` with
        ``r' = -gamma u_+^beta v'``, ``v' = g~ - u_+^alpha - gamma beta u_+^(beta-1) v``. The
        integrand of r has only powers >= 1 of u, as smooth at u = 0 as the rest of (4), where
        that of q (``u^(beta-1)``, e.g. ``u^(1/4)`` for TTI) would cost the method its order.
        Carrying r gives the CoR from the energy balance ``e^2 = 1 - 2 q(T_f) = 1 - 2 r(T_f)``
        (exactly 1 without damping), far better conditioned than ``e = -w`` after a swing
        through a deep load well.

        For integer exponents (``c.smooth``) the polynomials are continued to u < 0: the motion
        ends at u = 0, but the stages of the step that reaches it probe just beyond, where the
        kink of u_+ would cost the step its order (errors up to 1e-9 near grazing, growing with
        where in the step the floor is reached).
        """
        if c.smooth:
            pd = _polynomial(u, c.kd)
            pb = u * pd
            pa = pb if c.alpha == c.beta else _polynomial(u, c.ka)
        elif _general(c.kd, c.ka, c.smooth) and u > 0.0:
            # General exponents: one log for both powers (a pow is a log and an exp), by
            # the vector functions that the lanes' stages call (sweep.kernels.vmath).
            ad, aa = _general_arguments(c.alpha, c.beta, log1(u))
            pd = exp1(ad)
            pb = u * pd
            pa = exp1(aa)
        else:
            pd = power(u, c.beta - 1.0, c.kd)
            pb = u * pd if u > 0.0 else 0.0
            # Equal exponents (linear, Kuwabara-Kono) share the one power: it is most of a
            # stage's cost.
            pa = pb if c.alpha == c.beta else power(u, c.alpha, c.ka)
        return _forces(w, c.beta, c.gamma, c.gtilde, pd, pb, pa)
    return rhs


#: The right-hand side inlined: for the stages of a step, most of the march's cost.
rhs = jit(inline="always")(_rhs_with(ppow))
#: The same compiled once and called: where a march starts or jumps (once per point).
rhs_called = jit()(_rhs_with(ppow))
#: :func:`rhs` with the coded powers called (:func:`ppow_called`): :func:`rhs_at`, for
#: the lanes that do not go as vectors (:func:`vector_law_at`) and are not general at
#: u > 0. Inlined, _power's ten branches, twice, were 1.3 s of the lanes' first compile
#: (copies of their IR at every level of inlining).
_rhs_coded_called = jit(inline="always")(_rhs_with(ppow_called))


@jit(inline="always")
def rhs_at(u, w, F, I, row):
    """``rhs(u, w, law_at(F, I, row))``, value for value, for the stages of drivers that
    hold their points' laws in rows (:func:`put_law`), with the coded powers called.

    The lanes whose laws :func:`rhs_vector` takes go as vectors instead: the report's laws
    (Hertz, TTI, KK, SHC, linear). Until 2026-12-05 each of the report's models with
    non-integer exponents had a copy of :func:`rhs` here with its codes as constants (an
    eighth less time a KK point then); the vector groups made them a second of first
    compile for groups mixing those laws with others only (docs/speed/history.md).
    """
    return _rhs_coded_called(u, w, law_at(F, I, row))


# The laws whose stages rhs_vector forms for groups of lanes: alpha = 3/2 with the report's
# beta (1, 5/4, 3/2, 5/2: Hertz, TTI, KK, SHC), coded by the power code of beta - 1, and
# the linear law, whose forces are polynomials in u of either sign (code _LINEAR).
_LINEAR = -1


@jit(inline="always")
def vector_law_at(I, row):
    """The law in ``row`` of ``I`` (:func:`put_law`) is one whose stages
    :func:`rhs_vector` forms: one of the report's (Hertz, TTI, KK, SHC, linear)."""
    kd = I[row, 2]
    if I[row, 3] != 0:
        return I[row, 0] == KIND_ONE and kd == _KIND_ZERO          # linear
    return I[row, 0] == _KIND_THREE_HALVES and (
        kd == _KIND_ZERO or kd == _KIND_QUARTER or kd == _KIND_HALF
        or kd == _KIND_THREE_HALVES)


@jit(inline="always")
def _code(I, row):
    return float(I[row, 2]) if I[row, 3] == 0 else float(_LINEAR)


@jit(inline="always")
def vector_law(F, I, first):
    """The laws of the :data:`~sweep.kernels.vmath.VECTOR` rows of ``F, I`` from
    ``first`` (:func:`put_law`) as tuples, one element a row, for :func:`rhs_vector`:
    ``(code, beta, gamma, g~)``, the codes as float64."""
    return ((_code(I, first), _code(I, first + 1), _code(I, first + 2), _code(I, first + 3)),
            _column(F, first, 1), _column(F, first, 2), gtilde_rows(F, first))


@jit(inline="always")
def _column(F, first, col):
    return (F[first, col], F[first + 1, col], F[first + 2, col], F[first + 3, col])


@jit(inline="always")
def rhs_vector(u, w, law):
    """:func:`rhs_at` of the rows of :func:`vector_law` (each a law of
    :func:`vector_law_at`) at ``(u, w)``, as vector operations: each element has the bits of
    :func:`rhs_at`'s (the same formulas in the same order; tests/test_contact.py)."""
    kd, beta, gamma, gtilde = law
    x = vwhere_positive(u, u, 1.0)
    s = vsqrt(x)
    t = vmul(x, s)                               # u^(3/2)
    pos = vsqrt_where_equal(kd, _KIND_QUARTER, s, vwhere_equal(
        kd, _KIND_HALF, s, vwhere_equal(kd, _KIND_THREE_HALVES, t, 1.0)))
    # u^(beta-1) for u > 0; at u <= 0 the contact indicator (beta = 1) or 0.
    pd = vwhere_positive(u, pos, vwhere_equal(kd, _KIND_ZERO,
                                              vwhere_nonnegative(u, 1.0, 0.0), 0.0))
    pb = vwhere_positive(u, vmul(u, pd), 0.0)
    pa = vwhere_positive(u, t, 0.0)
    # The linear law: u^0 = 1, u^1 = u whatever the sign of u (rhs's polynomials; u * 1
    # is u, bit for bit).
    pd = vwhere_equal(kd, _LINEAR, 1.0, pd)
    pb = vwhere_equal(kd, _LINEAR, u, pb)
    pa = vwhere_equal(kd, _LINEAR, u, pa)
    # _forces, operation for operation.
    v = vsub(w, vmul(gamma, pb))
    fq = vmul(vmul(vmul(gamma, -1.0), pb),
              vsub(vsub(gtilde, pa), vmul(vmul(vmul(gamma, beta), pd), v)))
    return v, vsub(gtilde, pa), fq


@jit(inline="always")
def velocity(u, w, c):
    """``v = w - gamma u_+^beta``: the bead's velocity from the Lipschitz state (4)."""
    return w - c.gamma * ppow_called(u, c.beta, c.kb)


@jit(inline="always")
def accel(u, v, c):
    """``dv/dtau = g~ - u^alpha - gamma beta u^(beta-1) v`` for u >= 0 (eq. (1) scaled)."""
    return (c.gtilde - ppow_called(u, c.alpha, c.ka)
            - c.gamma * c.beta * ppow_called(u, c.beta - 1.0, c.kd) * v)


@jit(inline="always")
def dissipated(u, v, r, c):
    """Energy dissipated so far, ``q = gamma v u_+^beta + r`` (see :func:`rhs`)."""
    return c.gamma * v * ppow_called(u, c.beta, c.kb) + r


@jit(inline="always")
def potential(u, c):
    """``V(u) = u_+^(alpha+1)/(alpha+1) - g~ u``: the energy is ``H = v^2/2 + V(u)``, which
    the damper lowers by exactly the dissipated energy q (``H = 1/2 - q``)."""
    return u * ppow_called(u, c.alpha, c.ka) / (c.alpha + 1.0) - c.gtilde * u


# Called, not inlined, as elastic_frequency: at a dozen call sites (step size, damping cap,
# creep rules) the inlined copies cost 0.2-0.9 s of first compile (three interleaved runs)
# for no measured speed.
@jit()
def damping_rate(u, c):
    """Local damping rate ``gamma beta u^(beta-1)`` [1/tau] of the law ``c`` (0 out of
    contact). A capped march judges it several times a step (the report's exponents take
    no pow: ``c.kd``)."""
    if c.beta == 1.0:
        return c.gamma
    if u > 0.0:
        return c.gamma * c.beta * ppow_called(u, c.beta - 1.0, c.kd)
    return 0.0


@jit(inline="always")
def equilibrium(alpha, gtilde):
    """Static equilibrium compression ``u-bar = g~^(1/alpha)`` (report Sec. 3)."""
    return gtilde ** (1.0 / alpha) if gtilde > 0.0 else 0.0


@jit(inline="always")
def well_depth(alpha, gtilde):
    """Depth ``|V(u-bar)| = g~ u-bar alpha/(alpha+1)`` of the potential well of the load."""
    return well_depth_at(equilibrium(alpha, gtilde), alpha, gtilde)


@jit(inline="always")
def well_depth_at(ubar, alpha, gtilde):
    """:func:`well_depth` given ``ubar``, the :func:`equilibrium` (a pow less where the
    caller has it)."""
    return gtilde * ubar * alpha / (alpha + 1.0) if gtilde > 0.0 else 0.0


@jit(inline="always")
def natural_frequency(alpha, gtilde):
    """Linearised angular frequency about u-bar,
    ``omega_n = sqrt(alpha) g~^((alpha-1)/(2 alpha))``."""
    return math.sqrt(alpha) * gtilde ** ((alpha - 1.0) / (2.0 * alpha))


@jit(inline="always")
def damping_ratio(alpha, beta, gamma, gtilde):
    """Linearised damping ratio about u-bar (underdamped iff < 1)::

        xi = gamma beta / (2 sqrt(alpha)) g~^((2 beta - alpha - 1) / (2 alpha))
    """
    scale, x = _damping_ratio_terms(alpha, beta, gamma)
    return scale * gtilde ** x


@jit(inline="always")
def _damping_ratio_terms(alpha, beta, gamma):
    """``(gamma beta / (2 sqrt(alpha)), (2 beta - alpha - 1) / (2 alpha))``: the damping
    ratio is the first times g~ to the second."""
    return gamma * beta / (2.0 * math.sqrt(alpha)), (2.0 * beta - alpha - 1.0) / (2.0 * alpha)


@jit(inline="always")
def overdamped_at_rest(alpha, beta, gamma, gtilde):
    """``g~ > 0`` and :func:`damping_ratio` at least 1, its power taken only where a bound
    without it cannot tell: ``g~^x <= max(g~, 1/g~)`` for ``|x| <= 1``, so that xi is
    below 1 where ``gamma beta / (2 sqrt(alpha)) max(g~, 1/g~)`` is below 0.999 (a margin
    far above the rounding of either side). Once a march, at its start: a pow less most
    points (1.5% of the KK draw's time at tol 1e-8)."""
    if not gtilde > 0.0:
        return False
    scale, x = _damping_ratio_terms(alpha, beta, gamma)
    if abs(x) <= 1.0 and scale * max(gtilde, 1.0 / gtilde) < 0.999:
        return False
    return scale * gtilde ** x >= 1.0


# Called, not inlined: its helpers are inlined once, not at each of its callers (compile
# time); the lanes take umax_undamped_many.
@jit()
def umax_undamped(alpha, gtilde, ka):
    """Undamped maximum compression ``u_M(g~)``, root of (13): ``u^(a+1)/(a+1) - g~ u = 1/2``.

    ``ka``: the :func:`power_kind` of alpha (``Law.ka``), for a pow-free ``u^alpha``.

    Newton's method from an upper bound converges monotonically (the left side is convex in
    u and increasing past the root), so a fixed number of iterations gives full precision
    (within 1 ulp of an mpmath root up to g~ = 1e308; beyond ``1.8e308 / (alpha + 1)``, the
    asymptote ``((alpha + 1) g~)^(1/alpha)``). :func:`umax_undamped_many` gives the same
    bits for many points at once.
    """
    u, done = _umax_start(alpha, gtilde, ka)
    if done:
        return u
    for i in range(_UMAX_ITERATIONS):
        u_new, stop = _umax_step(u, alpha, gtilde, ka)
        if _umax_settled(i, u, u_new, stop):
            break
        u = u_new
    return u


_UMAX_ITERATIONS = 100


@jit(inline="always")
def _umax_start(alpha, gtilde, ka):
    """``(u, done)``: u_M itself where no iteration is needed (no load; a load whose
    ``u^alpha`` overflows), else Newton's upper bound for :func:`umax_undamped`."""
    ap1 = alpha + 1.0
    u0 = _UMAX_FREE[ka] if ka < len(_UMAX_FREE) else (0.5 * ap1) ** (1.0 / ap1)
    if gtilde <= 0.0:
        return u0, True
    # Upper bound: the root of u^(a+1)/(a+1) = 1/2 + g~ u is below u0 + (ap1 g~)^(1/a).
    # (A tighter one, (ap1 (g~ + 1/(2 lb)))^(1/a) with lb the larger of the two terms, saves
    # 1.3 of 5.8 iterations but stalls up to 5 ulps from the root at large loads, where f
    # cancels: from this one the last steps are quadratic and end within 1 ulp.)
    if math.isinf(ap1 * gtilde):
        # u^alpha ~ (alpha + 1) g~ overflows: the root's asymptote, good to ~ln(g~) ulps
        # (inf where u_M itself overflows, alpha near 1).
        return ap1 ** (1.0 / alpha) * gtilde ** (1.0 / alpha), True
    return u0 + (ap1 * gtilde) ** (1.0 / alpha), False


@jit(inline="always")
def _umax_step(u, alpha, gtilde, ka):
    """``(u_new, stop)``: Newton's step of :func:`umax_undamped` from u; ``stop`` where
    ``u^alpha`` overflows (u is then the bound, within ulps of the largest double)."""
    ap1 = alpha + 1.0
    ua = ppow_called(u, alpha, ka)
    if math.isinf(ua):
        return u, True
    df = ua - gtilde
    uua = u * ua
    if math.isinf(uua):
        # f / u, where u^(a+1) overflows (g~ beyond ~1e154 at alpha = 1, 1e185 at
        # 3/2): the step is the same, and u_max was -inf.
        du = u * ((ua / ap1 - gtilde - 0.5 / u) / df)
    else:
        du = (uua / ap1 - gtilde * u - 0.5) / df
    return u - du, False


@jit(inline="always")
def _umax_settled(i, u, u_new, stop):
    """Newton's iteration i of :func:`umax_undamped` ends at u: monotone decrease stalls at
    the root. (The bound itself can fall below it: pow's exponent 1/alpha is rounded, an
    error of ~ln(bound) ulps, 26 at g~ = 1e30, alpha = 3/2; the first step then goes up,
    past the root, f being convex.)"""
    return stop or (i > 0 and not (u_new < u))


# Called, not inlined: once per array of marches (compile time).
@jit()
def umax_undamped_many(alpha, gtilde, todo):
    """:func:`umax_undamped` of the points ``todo[j]`` of the arrays ``alpha``, ``gtilde``
    (an array, one per entry of ``todo``), bit for bit, the points' Newton iterations taken
    together: one point's is a chain of roots and divisions that leaves the core waiting
    (about 100 ns a KK point, 5% of its time at tol 1e-8), while a pass over many points'
    iterations overlaps their chains."""
    m = todo.size
    out = np.empty(m)
    active = np.empty(m, np.bool_)
    a, g, ka = np.empty(m), np.empty(m), np.empty(m, np.int64)
    left = False
    for k in range(m):
        a[k], g[k] = alpha[todo[k]], gtilde[todo[k]]
        ka[k] = power_kind(a[k])
        out[k], done = _umax_start(a[k], g[k], ka[k])
        active[k] = not done
        left = left or not done
    for i in range(_UMAX_ITERATIONS):
        if not left:
            break
        left = False
        for k in range(m):
            if active[k]:
                u_new, stop = _umax_step(out[k], a[k], g[k], ka[k])
                if _umax_settled(i, out[k], u_new, stop):
                    active[k] = False
                else:
                    out[k] = u_new
                    left = True
    return out


@jit()
def elastic_frequency(alpha, u):
    """Linearised elastic frequency ``sqrt(alpha u^(alpha-1))`` at compression u > 0 (judged
    at every step of a creeping bead: the report's exponents take no pow)."""
    return math.sqrt(alpha * ppow_called(u, alpha - 1.0, power_kind(alpha - 1.0)))
