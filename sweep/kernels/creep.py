"""Heavy damping: rigorous "never leaves" certificates, and the jump along the slow branch.

Derivation and numerical checks: docs/creep.md (sections 3, 4 and 7). Notation:
``kappa = alpha + 1 - 2 beta``, ``p = alpha + 1 - beta``, ``eps(u) = u^kappa / (gamma beta)^2``
(small where the motion is locally overdamped), ``F(u) = u^(alpha+1)/(alpha+1) - g~ u`` and the
energy ``H = v^2/2 + F(u) = 1/2 - q``.

* Invariant region. ``R = {v >= -gamma u^beta / 2}`` (i.e. ``v + w >= 0``) cannot be left
  where ``u^kappa < gamma^2 beta / 4``, i.e. on the good side of
  ``u_c = (gamma^2 beta / 4)^(1/kappa)``, and inside R u never reaches 0. With the energy
  keeping u on that side for ever (F is monotone on each side of u-bar, and H only falls),
  the bead never leaves: :func:`never_leaves` (exact, up to a rounding margin on H).
* Slow branch (kappa < 0). On the way back a heavily damped bead follows the overdamped branch
  ``v = V(u)`` of ``v dv/du = g~ - u^alpha - gamma beta u^(beta-1) v``, which attracts neighbouring
  trajectories at the rate ``gamma beta u^(beta-1)``; where ``eps <= eps_t / 2`` (``/ 10`` under
  a load; ``eps_t = min(1/(30 |kappa|), 1/(16 p))``) and the state is near it
  (``|phi - 1 - p eps| <= 0.1``, ``phi = -gamma beta v / u^p``), :func:`jump` moves the bead
  along it to ``u_t`` with ``eps(u_t) = eps_t`` (raised to 1.1 u-bar under a load), landing
  on ``v = V phi`` with ``V = (g~ - u^alpha) / (gamma beta u^(beta-1))`` the leading-order
  branch and ``phi(eps) = 1 + p eps + ...`` its series (``PHI_TERMS``; under a load plus
  ``(beta - 1) eps g~ / u^alpha``). The placement error is damped by
  ``exp(-1/(|kappa| eps_t)) <= e^-30`` before the exit. The time skipped is the integral of
  ``du / |V phi|`` by Gauss-Legendre quadrature in ``log u``, plus the bead's lag behind the
  branch at departure, ``-(v - V phi) / (D_eff V phi)``, which the attraction does not undo
  (at the leading order and without the lag t_f was off by up to 1.5%; now ~5e-6). Below u_t the
  motion is the universal inner problem of scale ``(gamma beta)^(-2/|kappa|)``, whose time scale
  ``u^((1-alpha)/2)`` the march's step is re-based on.

Owns: those rules. May import: contact.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sweep.kernels._jit import jit
from sweep.kernels.contact import damping_rate, equilibrium, potential, ppow_called

__all__ = ["Creep", "creep_constants", "creep_constants_at", "creep_kappa", "never_leaves",
           "never_leaves_from_start", "near_slow_branch", "jump", "energy_margin", "ROUNDING_V"]

#: Relative rounding margin of the energy H (16 eps times its largest term).
_H_ROUNDING = 16.0 * float(np.finfo(np.float64).eps)
#: |v| below this fraction of |w| is rounding noise of ``v = w - gamma u^beta`` (the state's
#: accumulated rounding, relative to the damper's share gamma u^beta ~ w).
ROUNDING_V = 1e-12
# eps_t = min(1/(30 |kappa|), 1/(16 p)): the series of the slow branch is still accurate
# and exp(-1/(|kappa| eps_t)) <= e^-30 (docs/creep.md, section 7).
_JUMP_KAPPA = 30.0
_JUMP_P = 16.0
# Gauss-Legendre nodes on [0, 1] for the skipped time (the integrand is smooth in log u).
_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
_GL_X = np.ascontiguousarray(0.5 * (_GL_X + 1.0))
_GL_W = np.ascontiguousarray(0.5 * _GL_W)
#: Terms of the slow branch's series phi(eps) beyond 1. Its truncation error at eps_t, the
#: largest eps of a jump, over alpha, beta in [1, 3] (step 0.1) with kappa < 0, against the
#: branch integrated in log eps (DOP853, rtol 1e-14): 1.2e-6 at 6 terms, 3.9e-8 at 8,
#: 1.3e-9 at 10, 4.4e-11 at 12 (worst at kappa -> 0-, p ~ 1.9, ratio ~0.18 a term), then
#: slower (1, 3: kappa = -4, terms ~ |kappa| n eps_t): 2.3e-12 at 16; the coefficients grow
#: like n! (kappa eps)^n, the series is asymptotic (best near 1/(|kappa| eps_t) >= 30 terms).
PHI_TERMS = 12


class Creep(NamedTuple):
    """Per-point constants of the creep rules (docs/creep.md, section 7)."""

    kappa: float
    p: float
    u_c: float        # (gamma^2 beta / 4)^(1/kappa); NaN when kappa = 0
    f_uc: float       # F(u_c)
    ubar: float
    u_jump: float     # kappa < 0: jump once u <= u_jump (eps <= eps_t / 10); else inf
    u_t: float        # kappa < 0: where the jump lands


@jit(inline="always")
def creep_constants(c):
    """The :class:`Creep` constants of the law ``c``."""
    return creep_constants_at(c, equilibrium(c.alpha, c.gtilde))


@jit(inline="always")
def creep_kappa(c):
    """``kappa = alpha + 1 - 2 beta`` of the law ``c`` (docs/creep.md): where it is 0 the
    constants take no power but u-bar's."""
    return c.alpha + 1.0 - 2.0 * c.beta


@jit(inline="always")
def creep_constants_at(c, ubar):
    """:func:`creep_constants` given ``ubar``, the law's equilibrium."""
    kappa = creep_kappa(c)
    p = c.alpha + 1.0 - c.beta
    gb2 = (c.gamma * c.beta) ** 2
    u_c = (0.25 * c.gamma * c.gamma * c.beta) ** (1.0 / kappa) if kappa != 0.0 else math.nan
    f_uc = potential(u_c, c) if kappa != 0.0 else math.nan
    if u_c == math.inf:
        # kappa > 0 tiny with a huge gamma (e.g. 0.036 and 1e8): u_c overflows, and F there
        # is +inf, not the NaN of inf - g~ * inf at g~ = 0.
        f_uc = math.inf
    u_jump = u_t = -1.0
    if kappa < 0.0 and c.gamma > 0.0:
        eps_t = min(1.0 / (_JUMP_KAPPA * -kappa), 1.0 / (_JUMP_P * max(abs(p), 1e-300)))
        u_t = max((eps_t * gb2) ** (1.0 / kappa), 1.1 * ubar)
        # Depart where eps <= eps_t / 2 at g~ = 0 (the landing's placement error is damped
        # by exp(-1/(|kappa| eps_t)) whatever the departure), eps_t / 10 under a load, whose
        # landing at 1.1 u-bar has no such margin (a grazing SHC point at g~ = 1e-3 was off
        # by 1.2e-10 departing at eps_t / 2).
        u_jump = ((0.5 if c.gtilde == 0.0 else 0.1) * eps_t * gb2) ** (1.0 / kappa)
    return Creep(kappa, p, u_c, f_uc, ubar, u_jump, u_t)


@jit(inline="always")
def energy_margin(u, v, c):
    """Rounding margin ``16 eps (v^2/2 + u^(alpha+1)/(alpha+1) + g~ u)`` of the energy H."""
    return _H_ROUNDING * (0.5 * v * v + abs(potential(u, c)) + 2.0 * c.gtilde * u)


@jit(inline="always")
def never_leaves(c, k, u, w, v, h):
    """The invariant-region certificate (module docstring): True if the bead at ``(u, w)``
    with energy ``h`` (margin included) provably never reaches u = 0."""
    if v + w < 0.0:      # outside R: v < -gamma u^beta / 2, with gamma u^beta = w - v
        return False
    if k.kappa == 0.0:
        return c.gamma * c.gamma * c.beta >= 4.0
    if k.kappa > 0.0:
        return u <= k.u_c and k.u_c > k.ubar and h < k.f_uc
    return c.gtilde > 0.0 and k.u_c < k.ubar and u >= k.u_c and h < k.f_uc


@jit(inline="always")
def slow_velocity(u, c):
    """Leading-order slow branch ``V = (g~ - u^alpha) / (gamma beta u^(beta-1))`` (u > 0;
    judged at every step of a creeping bead: the report's exponents take no pow)."""
    return (c.gtilde - ppow_called(u, c.alpha, c.ka)) / damping_rate(u, c)


@jit(inline="always")
def near_slow_branch(c, k, u, w, v):
    """kappa < 0, returning (v < 0), overdamped enough to jump and on the slow branch."""
    # kappa < 0: eps grows as u falls, so "eps <= eps_t / 10" is u >= u_jump (> u_t).
    if not (k.kappa < 0.0 and u >= k.u_jump and v + w >= 0.0 and u > k.u_t):
        return False
    if abs(v) <= ROUNDING_V * abs(w):
        # v = w - gamma u^beta is rounding noise: the damper (rate gamma beta u^(beta-1),
        # e.g. 1e7) has pinned the bead to the branch, whose speed is below that noise.
        return True
    eps = u ** k.kappa / (c.gamma * c.beta) ** 2
    # phi = v / V: -gamma beta v / u^p at g~ = 0; on the branch 1 + p eps + O(eps^2).
    return v < 0.0 and abs(v / slow_velocity(u, c) - 1.0 - k.p * eps) <= 0.1


@jit(inline="always")
def _put_coefficient(K, n, a):
    # a_n in the stage rows 1.. (a device function cannot allocate; K[0] is set after).
    K[1 + n // 3, n % 3] = a


@jit(inline="always")
def _coefficient(K, n):
    return K[1 + n // 3, n % 3]


@jit(inline="always")
def _branch_series(k, K):
    """Store the coefficients ``a_0 .. a_PHI_TERMS`` of the slow branch's ``phi(eps)`` at
    g~ = 0 in the stage array ``K`` (rows 1 on; docs/creep.md, section 7).

    ``v = -u^p phi / (gamma beta)`` in ``v dv/du = -u^alpha - gamma beta u^(beta-1) v`` gives
    ``eps phi (p phi + kappa eps phi') = phi - 1``, whose regular solution has ``a_0 = 1`` and
    ``a_n = sum_k a_k (p + kappa (n-1-k)) a_(n-1-k)``, summed here in the symmetric form
    ``(p + kappa (n-1)/2) sum_k a_k a_(n-1-k)``."""
    _put_coefficient(K, 0, 1.0)
    for n in range(1, PHI_TERMS + 1):
        s = 0.0
        for j in range(n):
            s += _coefficient(K, j) * _coefficient(K, n - 1 - j)
        _put_coefficient(K, n, (k.p + 0.5 * k.kappa * (n - 1)) * s)


@jit(inline="always")
def _branch_factor(c, k, u, K):
    """``v / V`` on the slow branch at ``u`` (u >= u_t), from the series in K.

    At g~ = 0 the truncated series phi(eps). Under a load ``v / V = phi(eps) +
    (beta - 1) eps s + O(eps^2 s)`` with ``s = g~ / u^alpha`` (< 1 on the jump's range): the
    first-order term of the double series in eps and s, whose eps^0 part is exact."""
    eps = u ** k.kappa / (c.gamma * c.beta) ** 2
    phi = 0.0
    for n in range(PHI_TERMS, -1, -1):
        phi = phi * eps + _coefficient(K, n)
    if c.gtilde > 0.0:
        phi += (c.beta - 1.0) * eps * c.gtilde / ppow_called(u, c.alpha, c.ka)
    return phi


@jit(inline="always")
def _phase_lag(c, k, u, v, K):
    """Time by which a bead at ``(u, v)`` near the slow branch trails one on it, for ever:
    ``-(v - V) / (D_eff V)``.

    The offset ``dv = v - V`` obeys ``d(dv)/dt = -(D + V') dv`` exactly (``D = gamma beta
    u^(beta-1)``), so it dies within ``1/D`` but leaves the bead ``dv / D_eff`` ahead along
    the branch: a shift in time that no later attraction removes (the jump departs up to
    10% off the branch: t_f off by ~1e-4 relative, e unchanged). ``V' = V0' phi`` to
    O(eps^2), ``V0' = -(alpha u^alpha + (beta - 1)(g~ - u^alpha)) / (u D)``."""
    d = damping_rate(u, c)
    ua = ppow_called(u, c.alpha, c.ka)
    phi = _branch_factor(c, k, u, K)
    big_v = slow_velocity(u, c) * phi
    dv_du = -(c.alpha * ua + (c.beta - 1.0) * (c.gtilde - ua)) / (u * d) * phi
    return -(v - big_v) / ((d + dv_du) * big_v)


@jit(inline="always")
def jump(c, k, u, v, K):
    """Move the bead at ``(u, v)`` along the slow branch to ``k.u_t``: returns the new
    ``(u, w, v, dt)`` with dt the time the move takes (``int du / |V|``, ``V = V0 phi``,
    plus the bead's lag behind the branch, :func:`_phase_lag`).

    ``K``: the stage array, whose rows from 1 on hold the branch's series meanwhile (the
    march restarts from the landing, with K[0] set there by the caller)."""
    _branch_series(k, K)
    lo, hi = math.log(k.u_t), math.log(u)
    dt = 0.0
    for i in range(_GL_X.size):
        x = math.exp(lo + (hi - lo) * _GL_X[i])
        dt += _GL_W[i] * x / -(slow_velocity(x, c) * _branch_factor(c, k, x, K))
    dt = dt * (hi - lo) + _phase_lag(c, k, u, v, K)
    v_t = slow_velocity(k.u_t, c) * _branch_factor(c, k, k.u_t, K)
    return k.u_t, v_t + c.gamma * k.u_t ** c.beta, v_t, dt


@jit(inline="always")
def never_leaves_from_start(c, k):
    """The certificates that hold at tau = 0 (v = 1, H = 1/2; docs/creep.md, section 3):
    kappa = 0 with ``gamma^2 beta >= 4`` (R invariant everywhere: at any load), or kappa > 0
    with ``u_c > u-bar`` and ``F(u_c) > 1/2``."""
    if c.gamma <= 0.0:
        return False
    if k.kappa == 0.0:
        return c.gamma * c.gamma * c.beta >= 4.0
    return k.kappa > 0.0 and k.u_c > k.ubar and k.f_uc > 0.5
