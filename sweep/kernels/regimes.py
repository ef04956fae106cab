"""Outcomes decided without marching: exact solutions and asymptotic regimes.

Each function takes the point's :class:`~sweep.kernels.contact.Law` and returns
``(decided, e, t_f, u_max, status, e_err)``; ``decided`` False leaves the point to the
integrator.

* :func:`undamped` -- gamma = 0: the energy is conserved, ``e = 1`` exactly at any load;
  ``u_max = u_M(g~)`` of (13) and ``T_f = 2 Q_{alpha,1}(g~)`` (Prop. 2's Q with beta = 1 is
  half the undamped contact time).
* :func:`linear_overdamped` -- alpha = beta = 1, g~ = 0, gamma >= 2: the closed form of
  SPEC section 4 creeps back exponentially and never leaves (``t_f = inf``).
* :func:`creeps_from_start` -- heavy damping certified at tau = 0 never to leave
  (:func:`sweep.kernels.creep.never_leaves_from_start`; docs/creep.md, section 3): e = 0
  exactly, ``t_f = inf`` (the bead creeps for ever), ``u_max`` not computed (NaN); it
  includes the linear law's overdamped creep at any load.
* :func:`kappa_zero_free` -- kappa = 0 (2 beta = alpha + 1: TTI, the linear law) at g~ = 0
  below critical damping: the exact solution of docs/creep.md, section 4, through the
  linear oscillator's phase curve (e, u_max, and T_f in closed form).
* :func:`deep_well` -- very large loads. With ``u = u-bar y`` and ``tau = T s``,
  ``T = g~^((1-alpha)/(2 alpha))``, the problem becomes ``y'' + gamma' d(y^beta)/ds + y^alpha
  = 1`` with ``gamma' = gamma g~^((2 beta - alpha - 1)/(2 alpha))`` and the initial speed
  ``eps = g~^(-(alpha+1)/(2 alpha))``: the bead starts from rest, as far as double precision
  can tell, and swings through a well of depth ~1 that it must climb out of with the
  kinetic energy eps^2 e^2 / 2. Along the swing the damper dissipates ``q = gamma' J``,
  ``J = int beta y^(beta-1) y'^2 ds`` taken on the undamped swing to first order, which is
  the report's large-load law (23): ``e^2 = 1 - 2 gamma C g~^r``. The neglected terms are
  relative O(gamma') and O(eps^2) in the dissipated fraction; where the bead rebounds at
  all ``gamma' < eps^2 / (2 J)``, so both are O(eps^2) and the law is exact to
  ``|delta e^2| <~ eps^2`` (measured: 0.5 eps^2 on the linear law's closed form); in double
  precision the loss ``2 gamma C g~^r`` is good to its logarithm's rounding
  (:data:`LOSS_ROUNDING`), which ``e_err`` adds, and a stick within it of the threshold
  keeps that bound as its ``e_err`` (a rebound not excluded). It is
  used where ``eps^2 < DEEP_WELL_EPS2``, beyond the depth where the march can resolve the
  bead's energy at the rim against the depth of the well in double precision. ``T_f`` and
  ``u_max`` are the undamped swing's (exact to O(gamma') where it rebounds); a bead that
  sticks, at any gamma', gets ``u_max`` NaN (not computed) unless gamma' is too small to move
  it (:data:`STUCK_UMAX_LOG_SHIFT`).

Owns: those decisions. May import: contact, special, registry.
"""
from __future__ import annotations

import math

from sweep.kernels._jit import jit
from sweep.kernels.contact import umax_undamped
from sweep.kernels.creep import creep_constants, creep_kappa, never_leaves_from_start
from sweep.kernels.special import (beta_fn, iq_quadrature, large_gtilde_constants,
                                   log_abs_gamma)
from sweep.registry import Status

__all__ = ["undamped", "linear_overdamped", "creeps_from_start", "kappa_zero_free", "deep_well",
           "undamped_duration", "DEEP_WELL_EPS2", "LOSS_ROUNDING"]

#: The rounding of the deep-well loss's logarithm, in units of the machine epsilon times the
#: sum of its terms' magnitudes (three logarithms, a product and C through lgamma, each
#: within an ulp or a few): points near the threshold were decided with e off by up to 33
#: tol at 1e-8 and e_err 0 where it was left out (g~ 1e7 to 1e300, 2026-12-07).
LOSS_ROUNDING = 8.0
#: eps^2 = g~^(-(alpha+1)/alpha) below which :func:`deep_well` decides a point: there the
#: law's error (~eps^2 in e^2) is below 1e-14, while the march's resolution of the rim energy
#: is ~1e-16 of the well depth 1/eps^2.
DEEP_WELL_EPS2 = 1e-14
#: ln of the largest relative shift of the first swing's depth by the damping for which a
#: sticking deep-well point still reports the undamped u_max (1e-13: the march's own
#: u_max is good to ~1e-11).
STUCK_UMAX_LOG_SHIFT = math.log(1e-13)
#: Loads up to which eps^2 = g~^(-(alpha+1)/alpha) >= g~^-2 (alpha >= 1, the domain's
#: least) is surely above DEEP_WELL_EPS2: 1e-12 there.
_SHALLOW_GTILDE = 1e6

_OK = int(Status.OK)
_STUCK = int(Status.STUCK)
_AT_REST = int(Status.AT_REST)
_NAN = math.nan
_EPS = 2.0 ** -52
_TINY = 5e-324     # the smallest positive double: e_err of an e that underflows


@jit(inline="always")
def _none():
    return False, _NAN, _NAN, _NAN, _OK, _NAN


@jit()
def undamped_duration(alpha, gtilde):
    """Contact time ``T_f = 2 int_0^{u_M} du / sqrt(1 + 2 (g~ u - u^(a+1)/(a+1)))`` [1] of the
    undamped impact: twice Q of Prop. 2 with beta = 1 (quadrature, ~1e-15), or, where theta
    of (43) underflows (g~ >~ 1e149), its deep-well limit
    ``sqrt(2 u-bar / g~) y_M^(1/2) B(1/(2a), 1/2) / a``, ``y_M = (a+1)^(1/a)``, exact to
    O(eps^2) and evaluated in logarithms so that it does not overflow."""
    _, q = iq_quadrature(alpha, 1.0, gtilde)
    if math.isfinite(q):
        return 2.0 * q
    log_scale = 0.5 * (math.log(2.0) + (1.0 / alpha - 1.0) * math.log(gtilde))
    return (math.exp(log_scale + 0.5 * math.log(alpha + 1.0) / alpha)
            * beta_fn(0.5 / alpha, 0.5) / alpha)


@jit(inline="always")
def undamped(c):
    """gamma = 0: no dissipation, so ``e = 1`` exactly (energy balance) at any load."""
    if c.gamma != 0.0:
        return _none()
    return (True, 1.0, undamped_duration(c.alpha, c.gtilde),
            umax_undamped(c.alpha, c.gtilde, c.ka), _OK, 0.0)


@jit(inline="always")
def linear_overdamped(c):
    """alpha = beta = 1, g~ = 0, gamma >= 2: ``u = (exp(l1 t) - exp(l2 t)) / (l1 - l2)`` with
    ``l1,2 = -gamma/2 +- sqrt(gamma^2/4 - 1)`` stays positive for ever (no rebound, e = 0);
    ``u_max`` where ``l1 exp(l1 t) = l2 exp(l2 t)``, ``t exp(-t)`` (maximum 1/e) at gamma = 2.
    ``l1 = 1 / l2`` avoids the cancellation of ``-gamma/2 + sqrt(...)`` at large gamma."""
    if not (c.alpha == 1.0 and c.beta == 1.0 and c.gtilde == 0.0 and c.gamma >= 2.0):
        return _none()
    r = math.sqrt(max(0.25 * c.gamma * c.gamma - 1.0, 0.0))
    if r == 0.0:
        return True, 0.0, math.inf, math.exp(-1.0), _AT_REST, 0.0
    l2 = -0.5 * c.gamma - r
    l1 = 1.0 / l2
    t = math.log(l2 / l1) / (l1 - l2)
    u_max = (math.exp(l1 * t) - math.exp(l2 * t)) / (l1 - l2)
    return True, 0.0, math.inf, u_max, _AT_REST, 0.0


@jit(inline="always")
def creeps_from_start(c):
    """Heavy damping certified at tau = 0 never to leave (module docstring)."""
    # kappa < 0 (KK, Hertz, SHC) or no damping: no certificate at tau = 0, whatever the
    # constants, whose powers (2 to 4 a point) were 2% of the KK draw's time at tol 1e-8.
    if c.gamma <= 0.0 or creep_kappa(c) < 0.0:
        return _none()
    if not never_leaves_from_start(c, creep_constants(c)):
        return _none()
    return True, 0.0, math.inf, _NAN, _AT_REST, 0.0


@jit(inline="always")
def _kappa_zero_duration(alpha, zeta, omega):
    """``T_f = A m int_0^(pi/omega) y(s)^mu ds`` of :func:`kappa_zero_free`, in closed form:
    with ``theta = omega s`` the integral is ``omega^-(1+mu) int_0^pi e^(b theta) sin^mu
    theta d theta``, ``b = -zeta mu / omega``, which is ``pi e^(b pi/2) Gamma(1+mu) /
    (2^mu |Gamma(1 + mu/2 + i b/2)|^2)`` (Gradshteyn-Ryzhik 3.892.1), summed in logarithms:
    near critical damping b is large and each factor overflows alone. ``1 + mu`` is ``m``,
    taken as such: formed as ``1 + (1-alpha)/(alpha+1)`` it cancels (relative error eps
    alpha; inf from alpha ~ 1e16, where lgamma(0) was met)."""
    m = 2.0 / (alpha + 1.0)
    b = zeta * (1.0 - m) / omega
    log_am = 0.5 * m * math.log(0.5 * (alpha + 1.0)) + math.log(m)
    log_int = (math.log(math.pi) + 0.5 * math.pi * b + math.lgamma(m)
               + (1.0 - m) * math.log(2.0) - 2.0 * log_abs_gamma(0.5 * (1.0 + m), 0.5 * b))
    return math.exp(log_am - m * math.log(omega) + log_int)


@jit(inline="always")
def kappa_zero_free(c):
    """kappa = 0 (2 beta = alpha + 1) at g~ = 0, ``zeta = gamma sqrt(beta) / 2 < 1``: the
    exact solution of docs/creep.md, section 4 (rule 4 of its section 7). ``u = A y^m``,
    ``A = ((alpha+1)/2)^(1/(alpha+1))``, ``m = 2/(alpha+1)``, makes the phase curve that of
    ``y'' + 2 zeta y' + y = 0`` in a time s with ``d tau = (du/dy) ds``:
    ``y = e^(-zeta s) sin(omega s) / omega``, ``omega = sqrt(1 - zeta^2)``, hence
    ``e = exp(-pi zeta / omega)``, ``u_max = A exp(-zeta s_M)^m`` with ``omega s_M =
    atan2(omega, zeta)``, and ``T_f`` from :func:`_kappa_zero_duration` (inf where it is
    beyond double precision: alpha ~ 100 near critical damping). Near critical damping the
    march took 10^4 to 2 10^5 steps (alpha >= 2: out of budget, e bounded by 1e-6 where it
    is 1e-14 and less); ``gamma^2 beta >= 4`` is :func:`creeps_from_start`'s, the same test
    (a zeta rounded to 1 with gamma^2 beta below 4 fell between the two and was marched)."""
    if not (c.gtilde == 0.0 and c.gamma > 0.0 and c.alpha + 1.0 - 2.0 * c.beta == 0.0):
        return _none()
    g2b = c.gamma * c.gamma * c.beta
    if not g2b < 4.0:
        return _none()
    omega = 0.5 * math.sqrt(4.0 - g2b)
    zeta = min(0.5 * c.gamma * math.sqrt(c.beta), 1.0)
    e = math.exp(-math.pi * zeta / omega)
    m = 2.0 / (c.alpha + 1.0)
    u_max = (0.5 * (c.alpha + 1.0)) ** (0.5 * m) * math.exp(
        -m * zeta * math.atan2(omega, zeta) / omega)
    t_f = _kappa_zero_duration(c.alpha, zeta, omega)
    if e == 0.0:     # below the smallest double: it leaves, with no e a double can hold
        return True, 0.0, t_f, u_max, _AT_REST, _TINY
    # Rounding: of e's exponent, whose condition in zeta is pi / omega^3; and of e itself
    # where it is subnormal (half its last place, which the relative term underflows).
    err = max(e * _EPS * (8.0 + 4.0 * math.pi / (omega * omega * omega)), _TINY)
    return True, e, t_f, u_max, _OK, err


@jit(inline="always")
def _stuck_umax(c, log_g, u_max):
    """u_max of a deep-well point that sticks: the undamped ``u_max`` where the damping
    cannot move it, else NaN (not computed). A rebound needs ``gamma' < eps^2``, so the
    undamped swing is exact to rounding there; a stick allows any gamma', and the first
    swing's depth falls by ``c(alpha, beta) gamma'`` relative (measured by DOP853 on the
    scaled well: c = 0.31 to 2.9 for alpha, beta in [1, 3]; bounded here by ``beta 2^beta``),
    up to an overdamped sinking that never turns (KK at g~ = 1e10, gamma = 1, gamma' = 46:
    1.84 u-bar undamped, 1.00 u-bar damped)."""
    log_gp = math.log(c.gamma) + (2.0 * c.beta - c.alpha - 1.0) / (2.0 * c.alpha) * log_g
    log_c = math.log(c.beta) + c.beta * math.log(2.0)
    if log_gp + log_c < STUCK_UMAX_LOG_SHIFT:
        return u_max
    return _NAN


@jit(inline="always")
def deep_well(c):
    """Very large loads (module docstring): the large-load law (23) with its error bound."""
    # eps^2 >= g~^-2 (alpha >= 1) is above DEEP_WELL_EPS2 below this load: no log and exp
    # a point where the well cannot be that deep.
    if not (c.gtilde > _SHALLOW_GTILDE):
        return _none()
    log_g = math.log(c.gtilde)
    eps2 = math.exp(-(c.alpha + 1.0) / c.alpha * log_g)
    if not (eps2 < DEEP_WELL_EPS2):
        return _none()
    k, r = large_gtilde_constants(c.alpha, c.beta)
    # 2 gamma C g~^r in logarithms: each factor may overflow alone.
    log_2k, log_gamma, log_load = math.log(2.0 * k), math.log(c.gamma), r * log_g
    log_loss = log_2k + log_gamma + log_load
    # The loss is only as good as the rounding of its logarithm's terms (|log gamma| and
    # r |log g~| reach 50-700): near the threshold that, not the law, decides.
    d_log = LOSS_ROUNDING * _EPS * (1.0 + abs(log_2k) + abs(log_gamma) + abs(log_load))
    t_f = undamped_duration(c.alpha, c.gtilde)
    u_max = umax_undamped(c.alpha, c.gtilde, c.ka)
    if log_loss >= 0.0:
        # A stick; within the rounding and the law's error of the threshold a rebound of
        # e^2 <~ d_log + eps^2 is not excluded, as the march says near grazing.
        err = 0.0 if log_loss >= d_log + eps2 else math.sqrt(d_log + eps2)
        return True, 0.0, t_f, _stuck_umax(c, log_g, u_max), _STUCK, err
    e2 = -math.expm1(log_loss)
    e = math.sqrt(e2)
    # |delta e^2| <~ eps^2 (module docstring) + loss d_log: delta e <~ that / e, and never
    # above its root.
    d2 = eps2 + math.exp(log_loss) * d_log
    return True, e, t_f, u_max, _OK, min(d2 / e, math.sqrt(d2))
