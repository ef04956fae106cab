"""From where the march ended to the CoR, its status and an estimate of its error.

The energy ``H = v^2/2 + V(u)``, ``V(u) = u_+^(alpha+1)/(alpha+1) - g~ u``, starts at 1/2
and the damper lowers it by exactly the dissipated energy q, which the march integrates
along (:func:`sweep.kernels.contact.rhs`): along the true motion ``H = 1/2 - q``. The bead
leaves the floor iff H is still >= 0 when it gets back to u = 0, and then ``e^2 = 2 H =
1 - 2 q``. Every decision below is taken on this balance rather than on the geometry alone:

* q is an integral of a smooth positive quantity, accurate to the march's *relative* error,
  while the march's own energy ``v^2/2 + V(u)`` carries errors relative to the depth of the
  load's well, ``|V(u-bar)|``: near the rim of a deep well the geometry can turn back short
  of the floor (a trough) or overshoot it while q is still exact to ~1e-13.
* The *energy defect* ``D = v^2/2 + V(u) - (1/2 - q)`` vanishes along the true motion; at the
  end of the march it measures the march's error: the error of q is ``|D| / swing2`` to
  within a small factor (:mod:`sweep.kernels.balance`), that of the velocity up to
  ``|D| / e``.

Decisions (``h = 1/2 - q``, ``dq`` the estimated error of q,
:func:`sweep.kernels.balance.q_error`):

* exit (u = 0 reached): ``e`` is ``sqrt(1 - 2 q)``, or ``-v`` where the damping has
  shrunk the velocity's errors or e is too small for q's rounding (:func:`cor_at_exit`);
  if instead ``h < -dq`` the exit is an artefact of an overshooting geometry and the bead
  sticks.
* trough (v = 0 with u > 0): if ``h > dq`` the geometry turned back short of the floor while
  the energy says the bead leaves: ``e = sqrt(2 h)`` (the dissipation on the stretch the
  march did not cover, from the trough to the floor, is bounded and added to the error);
  if ``h < -dq`` it sticks; in between the balance cannot decide.
* energy spent (q > 1/2): sticks unless ``h + dq > 0`` (the march stops there once
  ``h < -dq``, a creeping bead judged by the creep rules where that is too far off:
  ``march._SURE_STEPS``).
* rest (the report's criterion): with a load, the bead rests in its well (``h < 0``); at
  g~ = 0 the energy left, ``sqrt(2 h)``, bounds the e it may still leave with.

The error indicator (for e, absolute) is ``dq / e`` for the balance, and ``KAPPA_W lw``
(``lw`` the summed local error estimates of w, times up to ``GRAZING_SPEED / e`` near
grazing, short of a creep) plus rounding for ``-v``, and no less than ``-v`` differs from
the balance's e where the energy left is too small for the balance but the damping has
not made it the worse of the two; an undecided stick/rebound gives the bound
``sqrt(2 (h + dq))``. Where it exceeds the refinement target, the integrator replaces
it by a Richardson estimate (:mod:`sweep.kernels.integrator`).

Owns: the decision rules, the per-point error indicator and the exit time near grazing
(:func:`exit_time`). May import: contact, balance,
march, registry.
"""
from __future__ import annotations

import math

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.balance import (ROUNDING, coarse_room, defect_share, q_error, rebound_share,
                                   swing2, swing_of)
from sweep.kernels.contact import KIND_EXPONENTS, ppow_called, well_depth_at
from sweep.kernels.march import CREEP, EXIT, NEGLIGIBLE, REST, SPENT, TROUGH
from sweep.registry import Status

__all__ = ["decide", "cor_at_exit", "exit_time", "KAPPA_W", "COARSE_POWER_W", "GRAZING_LEAD",
           "GRAZING_CERTAIN",
           "GRAZING_SPEED", "GRAZING_MAX", "GRAZING_DAMPING", "BALANCE_MIN_E2",
           "DAMPED_OUT"]

_OK = int(Status.OK)
_STUCK = int(Status.STUCK)
_AT_REST = int(Status.AT_REST)
_BUDGET = int(Status.BUDGET_EXHAUSTED)

#: Below this e^2 the velocity gives e (see cor_at_exit).
BALANCE_MIN_E2 = 1e-20
#: Above this damping integral the velocity gives e (see cor_at_exit).
DAMPED_OUT = 20.0
#: Global error of the velocity per unit of the summed embedded local error estimates of
#: w: a conservative factor, calibrated with :data:`sweep.kernels.balance.KAPPA_Q`.
KAPPA_W = 1.5
#: Below ``balance.COARSE_STEPS`` a rebound's e from the velocity takes ``KAPPA_W lw``
#: times ``balance.coarse_room(steps)`` to this power, ``(16 / steps)^4.5``: 22.6 at the 8
#: steps that ``tol`` from 3e-5 up marches first at. KAPPA_W was calibrated from 16 steps on;
#: an audit found 129 points near the stick boundary, beta far above alpha, whose 8-step
#: march left with -v off by up to 10 of its estimate (35 sticks returned as rebounds, up
#: to 8 tol at 1e-5, no warning). Power 1 left 14 of them, 2 left 3, 3 none; the heavily
#: damped draws at tol 1e-3 .. 1e-6 take 0-0.4% more steps, the calibration draws (16 steps
#: and more) none (docs/accuracy.md).
COARSE_POWER_W = 3.0
#: Speed below which the velocity's estimate grows like GRAZING_SPEED / e, up to
#: GRAZING_MAX times. Near grazing the bead leaves with a small e after a stretch of light
#: damping, so an error dE of the energy there becomes dE / e in the velocity, and the
#: damped local errors lw miss it: on the heavily damped grazing families (alpha, beta) =
#: (1.5, 2.5), (2, 3) at g~ 0.01 and 0.001, within 1e-2 .. 1e-5 of gamma_c, the true error
#: reached 3.2 times ``KAPPA_W lw`` at e ~ 1e-4 and 13 to 120 steps; with the factor, at
#: most 0.74 of it (damping integral 9 to 250 there). Slow creeps at g~ = 0 leave with
#: e ~ 1e-9 along the damped slow branch, with no light stretch to amplify errors: their
#: damping integral is in the thousands and beyond, above GRAZING_DAMPING. Nor is the
#: factor applied at g~ = 0 at all, where no well holds the bead back: there a small e is
#: the damping's whole work (the linear law towards critical damping, e = 1e-6 .. 1e-14
#: with a damping integral of 20-40, had e_err 1e6-1e12 times its error, and was refined to
#: the cap: 2,076 steps for an error of 7e-18 at tol=1e-8, 739 now, its first march's e_err
#: 2e-8 instead of 2e-6); a randomized audit
#: against the extended-precision reference (``benchmarks/hp_audit.py``, families b, d, f,
#: two seeds) gives the same largest true / e_err with and without it there.
GRAZING_SPEED = 5e-3
GRAZING_MAX = 100.0
GRAZING_DAMPING = 1000.0
#: The exit time is moved to the energy's exit (:func:`exit_time`) only where the bead
#: leaves within this fraction of the impact's duration of the vertex of its parabola at
#: the floor: a grazing exit out of a well, where the acceleration is ~constant.
GRAZING_LEAD = 1e-3
#: ... and only where the march's speed at its crossing and e differ by more than this
#: many times their estimated errors (:func:`exit_time`).
GRAZING_CERTAIN = 10.0


@jit(inline="always")
def cor_at_exit(h, v, damping):
    """CoR at detachment from the better conditioned of two equal expressions; returns
    ``(e, balance)`` with ``balance`` True when e comes from the energy balance.

    ``e = sqrt(2 h) = sqrt(1 - 2 q)`` (energy balance, h the energy left, q the energy the
    damper dissipated) inherits the error of q,
    amplified by ``1/e``; it converges with the method's order (so that refinement and
    Richardson extrapolation apply) and its error is relative to q's size, not to the depth
    of the load's well like the velocity's (measured: 1e-13 where ``-v`` is off by 1e-9 to
    1e-5 at depths 1e3 to 1e6). ``e = -v`` is used where the damping integral ``damping``
    (an estimate of ``int gamma beta u^(beta-1) dtau`` over the impact) exceeds
    :data:`DAMPED_OUT`: the velocity's errors are then damped out on the way to the floor
    by ``exp(-damping / 2)`` (e to 1e-18 at alpha = beta = 5, gamma = 100, where q is off by
    2e-7 after 150,000 steps of creep), and where ``e^2 < BALANCE_MIN_E2``, below which q's
    rounding (~1e-15, amplified by 1/e) is the whole of e. Near grazing at light damping
    the balance stays the better one down to e ~ 1e-6 (measured on the linear law: 1e-12
    where -v is off by 1e-10 to 7e-8).
    """
    left = 2.0 * h
    if left > BALANCE_MIN_E2 and damping <= DAMPED_OUT:
        return math.sqrt(left), True
    return max(-v, 0.0), False


def _sine_mean(p):
    """Mean of ``sin^p`` over a half period, ``Gamma((p+1)/2) / (Gamma(p/2+1) sqrt(pi))``."""
    return math.exp(math.lgamma(0.5 * (p + 1.0)) - math.lgamma(0.5 * p + 1.0)) / math.sqrt(math.pi)


_sine_mean_jit = jit(inline="always")(_sine_mean)
#: :func:`_sine_mean` of each power code's exponent (``Law.kd``, of beta - 1): two lgammas
#: and an exp less a decision. Formed by Python's lgamma, which may differ from the C
#: library's in the last place: the mean only places a damping integral against thresholds.
_SINE_MEANS = tuple(_sine_mean(p) for p in KIND_EXPONENTS)


@jit(inline="always")
def _damping_integral(beta, kd, gamma, u_max, t_f):
    """Estimate of ``int gamma beta u^(beta-1) dtau`` over an impact of length t_f:
    ``u^(beta-1)`` averaged over a half sine of amplitude u_max (``kd``: the power code of
    beta - 1)."""
    p = beta - 1.0
    mean = _SINE_MEANS[kd] if kd < len(_SINE_MEANS) else _sine_mean_jit(p)
    # The code's pow-free power where u_max > 0 (within ulps of pow's: thresholds only).
    spread = ppow_called(u_max, p, kd) if u_max > 0.0 else u_max ** p
    return gamma * beta * mean * spread * t_f


@jit(inline="always")
def _undecided(h, dq):
    """Bound on e when the balance cannot tell a stick from a rebound: ``sqrt(2 (h + dq))``."""
    return math.sqrt(2.0 * max(h + dq, 0.0))


@jit(inline="always")
def _exit(c, end, h, dq, swing2, steps):
    if h < -dq:  # the geometry overshot: the energy was spent before the floor
        return 0.0, _STUCK, 0.0, 0.0, 0.0
    lam = _damping_integral(c.beta, c.kd, c.gamma, end.u_max, end.t)
    e, balance = cor_at_exit(end.h, end.v, lam)
    e_q = math.sqrt(max(2.0 * h, 0.0))
    e_v = max(-end.v, 0.0)
    if e <= 0.0:
        return 0.0, _STUCK, _undecided(h, dq), e_q, e_v
    if balance:
        err = q_error(c, end.u, end.v, h, end.lq, end.n, steps, rebound_share(h),
                      swing2) / e
    else:
        err = _velocity_error(end, e, lam, swing2, c.gtilde) * coarse_room(steps) \
            ** COARSE_POWER_W
        if lam <= DAMPED_OUT:
            # The energy left is too small for the balance (2 h <= BALANCE_MIN_E2), which
            # the damping has not made the worse of the two: the balance says the energy is
            # spent, the velocity that the bead leaves with e. Neither is known better than
            # their difference (a coarse march near the stick boundary left with e = 1.1e-3,
            # e_err 6.8e-5, where the bead sticks: auto at tol 1e-4 kept it).
            err = max(err, abs(e - e_q))
    return e, _OK, min(err, _undecided(h, dq) + e), e_q, e_v


@jit(inline="always")
def _velocity_error(end, e, lam, swing2, gtilde):
    """Error indicator of ``e = -v`` for damping integral ``lam``: the summed local errors
    of w plus rounding, both amplified near grazing under a load, short of a creep
    (:data:`GRAZING_SPEED`)."""
    amplified = 1.0
    if lam < GRAZING_DAMPING and gtilde > 0.0:
        amplified = min(max(1.0, GRAZING_SPEED / e), GRAZING_MAX)
    # The rounding of the energy is amplified near grazing as its truncation is: at tol
    # 1e-12 .. 1e-14 a grazing SHC point's error stalled at ~2e-12, 20 times the estimate
    # without it.
    return (KAPPA_W * end.lw + ROUNDING * math.sqrt(end.n + 1.0) * math.sqrt(swing2)) \
        * amplified


@jit(inline="always")
def _trough(c, end, h, dq):
    if h <= dq:
        return 0.0, _STUCK, (_undecided(h, dq) if h > -dq else 0.0), 0.0, 0.0
    # The march turned back at u_min > 0; the stretch up to the floor dissipates at most
    # gamma u_min^beta sqrt(2 h + 2 g~ u_min) (its length in u times the largest damping
    # force on it), which the error covers.
    u = end.u
    rest = c.gamma * u ** c.beta * math.sqrt(2.0 * h + 2.0 * c.gtilde * u)
    e = math.sqrt(2.0 * h)
    return e, _OK, (dq + rest) / e, e, np.nan


@jit()
def decide(c, end, steps, ubar):
    """``(e, status, e_err, e_q, e_v)`` of the march's :class:`~sweep.kernels.march.Ending`
    for the law ``c`` marched at resolution ``steps`` (module docstring): e_q and e_v are
    the energy balance's and the velocity's values of e where the bead left (NaN where not
    defined). ``ubar``: the law's :func:`~sweep.kernels.contact.equilibrium`, which the
    caller formed for the march (a pow a point less)."""
    h = end.h
    swing = swing_of(well_depth_at(ubar, c.alpha, c.gtilde))
    dq = q_error(c, end.u, end.v, h, end.lq, end.n, steps, defect_share(h), swing)
    if end.kind == EXIT:
        return _exit(c, end, h, dq, swing, steps)
    if end.kind == TROUGH:
        return _trough(c, end, h, dq)
    undecided = _undecided(h, dq) if h > -dq else 0.0
    if end.kind == CREEP:         # certified: never leaves (sweep.kernels.creep)
        return 0.0, _AT_REST, 0.0, 0.0, 0.0
    if end.kind == NEGLIGIBLE:    # e <= sqrt(2 H), below the tolerance
        return 0.0, _AT_REST, math.sqrt(2.0 * max(h, 0.0)), 0.0, 0.0
    if end.kind == SPENT:
        return 0.0, _STUCK, undecided, 0.0, 0.0
    if end.kind == REST:
        return 0.0, _AT_REST, undecided, 0.0, 0.0
    # BUDGET: the energy still available bounds the rebound speed.
    e = math.sqrt(max(2.0 * h, 0.0))
    return e, _BUDGET, e, e, np.nan


@jit(inline="always")
def exit_time(c, end, e, status, err):
    """T_f [1] of a march that ended with ``end`` and was decided ``(e, status, err)``.

    Near grazing under a load the march's crossing of u = 0 is ill-conditioned while e,
    from the energy balance, is not: the position carries errors relative to the well's
    depth, which shift the shallow dip's depth, so the geometry crosses at a speed ``|v|``
    other than e (or turns back short of the floor: a trough, v = 0). About the vertex of
    the parabola ``u'' = a`` at the floor (``a = g~``, plus ``gamma e`` where beta = 1),
    whose time the march resolves, the bead crosses ``|v| / a`` before it, so the
    energy's crossing is ``(|v| - e) / a`` later than the march's. Applied only where the
    lead ``e / a`` is below :data:`GRAZING_LEAD` of the duration (clipped to it) and
    ``|v| - e`` exceeds :data:`GRAZING_CERTAIN` times the errors of e and of v: in
    shallow wells the two differ by their own errors (measured: 0.1 of them, against
    130-750 on grazing exits out of wells 1e2-5e2 deep), which 1/a would amplify.
    """
    if not (status == _OK and c.gtilde > 0.0 and (end.kind == EXIT or end.kind == TROUGH)):
        return end.t
    a = c.gtilde + (c.gamma * e if c.beta == 1.0 else 0.0)
    lead = e / a
    if not lead <= GRAZING_LEAD * end.t:
        return end.t
    speed = -end.v if end.kind == EXIT else 0.0
    lam = _damping_integral(c.beta, c.kd, c.gamma, end.u_max, end.t)
    doubt = err + _velocity_error(end, e, lam, swing2(c), c.gtilde)
    if not abs(speed - e) > GRAZING_CERTAIN * doubt:
        return end.t
    return end.t + min(max((speed - e) / a, -lead), lead)
