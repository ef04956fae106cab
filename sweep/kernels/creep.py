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
  trajectories at the rate ``gamma beta u^(beta-1)``; where ``eps <= EPS_JUMP / 2`` (``/ 10`` under
  a load) and the state is near it (``|phi - 1 - p eps| <= 0.1``, ``phi = -gamma beta v / u^p``),
  :func:`jump` moves the bead along it to ``u_t`` with ``eps(u_t) = EPS_JUMP`` (raised to 1.1 u-bar
  under a load), at the leading-order branch ``V = (g~ - u^alpha) / (gamma beta u^(beta-1))``. The
  placement error is damped by ``exp(-1/(|kappa| eps_t)) <= e^-30`` before the exit. The time
  skipped is the integral of ``du / |V|`` by Gauss-Legendre quadrature in ``log u``. Below u_t the
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

__all__ = ["Creep", "creep_constants", "never_leaves", "never_leaves_from_start",
           "near_slow_branch", "jump", "energy_margin", "ROUNDING_V"]

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
    kappa = c.alpha + 1.0 - 2.0 * c.beta
    p = c.alpha + 1.0 - c.beta
    ubar = equilibrium(c.alpha, c.gtilde)
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
def jump(c, k, u):
    """Move the bead along the slow branch from ``u`` to ``k.u_t``: returns the new
    ``(u, w, v, dt)`` with dt the time the move takes (``int du / |V|``)."""
    lo, hi = math.log(k.u_t), math.log(u)
    dt = 0.0
    for i in range(_GL_X.size):
        x = math.exp(lo + (hi - lo) * _GL_X[i])
        dt += _GL_W[i] * x / -slow_velocity(x, c)
    dt *= hi - lo
    v_t = slow_velocity(k.u_t, c)
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
