"""Contact parameters of a bead from its material: mass, Hertz stiffness, damping models.

The report's contact law (1) needs ``m``, ``k``, ``gamma0`` and the exponents. A scene may
give them directly or derive them here (formulas and references in ``docs/scenes.md``):

* :func:`sphere_mass` -- ``m = (4/3) pi R^3 rho``;
* :func:`hertz_stiffness` -- sphere on a flat (Hertz; Johnson, *Contact Mechanics*, 1985,
  Sec. 4.2): ``k = (4/3) E* sqrt(R)`` with ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``, the
  elastic force ``k delta^(3/2)`` of the law with alpha = 3/2;
* :func:`kuwabara_kono_gamma0` -- the viscous constant ``A`` of the Kuwabara-Kono law
  (alpha = beta = 3/2) from the material's viscosities (Brilliantov, Spahn, Hertzsch,
  Poeschel, Phys. Rev. E 53, 5382 (1996)): the law (1) with ``gamma0 = A``;
* :func:`tsuji_gamma0` -- the Tsuji-Tanaka-Ishida law (alpha = 3/2, beta = 5/4): e does not
  depend on v0 without load, and its damping follows from e in closed form (the report's
  Appendix D map onto a linear oscillator: ``e = exp(-pi xi / sqrt(1 - xi^2))``,
  ``xi = gamma sqrt(5)/4``);
* :func:`gamma0_for_cor` -- any law: the ``gamma0`` for which the package's numerical CoR
  is a target e at a reference speed and load, by root-finding on the scaled damping.

Owns: these formulas. May import: :mod:`sweep.registry`, :mod:`sweep.model`,
:mod:`sweep.api` (floor 2), numpy and scipy.
"""
from __future__ import annotations

import math

import numpy as np

from sweep import api, registry
from sweep.model import scale

__all__ = ["sphere_mass", "effective_modulus", "hertz_stiffness", "kuwabara_kono_gamma0",
           "tsuji_gamma0", "gamma0_for_cor", "HERTZ_ALPHA", "TSUJI"]

#: The stiffness exponent of Hertz's sphere-on-flat contact (the registry's Hertz law).
HERTZ_ALPHA = registry.MODELS["hertz"][0]
#: Exponents of the Tsuji-Tanaka-Ishida law (report Table 1).
TSUJI = registry.MODELS["tti"]


#: Parameters named for the body they belong to, and the property whose domain they take.
_PROPERTY_OF = {"E1": "E", "nu1": "nu", "E2": "E", "nu2": "nu"}


def _single(**values: float) -> None:
    """Refuse a value that is not one number, naming the parameter: the formulas here are
    scalar (``math``), and a list or an array met them as a TypeError naming neither."""
    for name, value in values.items():
        if np.ndim(value) != 0:
            raise ValueError(f"{name} must be a single number, got {value!r}")


def _check(**values: float) -> None:
    """Refuse a value that is not one number or is outside its domain
    (:data:`sweep.registry.PHYSICAL`, :data:`sweep.registry.MATERIAL`), naming the
    parameter as given (``E2``)."""
    domains = {**registry.PHYSICAL, **registry.MATERIAL}
    _single(**values)
    for name, value in values.items():
        registry.check_array(name, value, {name: domains[_PROPERTY_OF.get(name, name)]})


def sphere_mass(radius: float, density: float) -> float:
    """Mass of a solid sphere [kg]: ``(4/3) pi R^3 rho``.

    Parameters
    ----------
    radius : float
        [m], > 0.
    density : float
        [kg/m^3], > 0.
    """
    _check(radius=radius, density=density)
    return 4.0 / 3.0 * math.pi * radius ** 3 * density


def effective_modulus(E1: float, nu1: float, E2: float = math.inf, nu2: float = 0.0) -> float:
    """Contact modulus E* [Pa] of two elastic bodies: ``1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2``.

    Parameters
    ----------
    E1, nu1 : float
        Young's modulus [Pa], > 0, and Poisson's ratio [1], in (-1, 0.5], of the bead.
    E2, nu2 : float
        Of the floor; ``E2 = +inf`` (default) is a rigid floor, which no other non-finite
        value means (NaN or -inf is refused).

    Raises
    ------
    ValueError
        A value that is not one number or is outside its domain, naming the parameter
        and the value.
    """
    _check(E1=E1, nu1=nu1, nu2=nu2)
    rigid = E2 == math.inf
    if not rigid:
        _check(E2=E2)
    compliance = (1.0 - nu1 ** 2) / E1 + (0.0 if rigid else (1.0 - nu2 ** 2) / E2)
    return 1.0 / compliance


def hertz_stiffness(radius: float, E1: float, nu1: float, E2: float = math.inf,
                    nu2: float = 0.0) -> float:
    """Hertz stiffness k [N/m^1.5] of a sphere of radius R on a flat: ``(4/3) E* sqrt(R)``.

    The elastic force is ``k delta^(3/2)`` (Johnson 1985, eq. (4.22) with the flat's
    radius infinite), i.e. the report's law (1) with alpha = 3/2.

    Parameters
    ----------
    radius : float
        Bead radius [m].
    E1, nu1 : float
        Young's modulus [Pa] and Poisson's ratio of the bead.
    E2, nu2 : float
        Of the floor (default: rigid, ``E2 = +inf``; see :func:`effective_modulus`).

    Raises
    ------
    ValueError
        A value that is not one number or is outside its domain, naming the parameter
        and the value.
    """
    _check(radius=radius)
    return 4.0 / 3.0 * effective_modulus(E1, nu1, E2, nu2) * math.sqrt(radius)


def kuwabara_kono_gamma0(eta1: float, eta2: float, E: float, nu: float) -> float:
    """Kuwabara-Kono damping gamma0 [s] from the bead material's viscous constants.

    Brilliantov et al. (1996): the dissipative force is ``(3/2) A k sqrt(delta) delta'`` with
    ``A = (1/3) (3 eta2 - eta1)^2 / (3 eta2 + 2 eta1) (1 - nu^2)(1 - 2 nu) / (E nu^2)``;
    since ``d/dt delta^(3/2) = (3/2) sqrt(delta) delta'``, the report's law (1) with
    alpha = beta = 3/2 has ``gamma0 = A``.

    Parameters
    ----------
    eta1, eta2 : float
        Viscous constants [Pa s], >= 0, not both 0.
    E, nu : float
        Young's modulus [Pa] and Poisson's ratio (nu != 0) of the bead.
    """
    _check(eta1=eta1, eta2=eta2, E=E, nu=nu)
    if nu == 0.0 or eta1 + eta2 == 0.0:
        raise ValueError("the Kuwabara-Kono constant needs nu != 0 and eta1 + eta2 > 0, got "
                         f"nu={nu!r}, eta1={eta1!r}, eta2={eta2!r}")
    return ((3.0 * eta2 - eta1) ** 2 / (3.0 * (3.0 * eta2 + 2.0 * eta1))
            * (1.0 - nu ** 2) * (1.0 - 2.0 * nu) / (E * nu ** 2))


def tsuji_gamma0(e: float, m: float, k: float) -> float:
    """Tsuji-Tanaka-Ishida damping gamma0 [s m^(1/4)] giving the CoR e (without load).

    For alpha = 3/2, beta = 5/4 the scaled damping is ``gamma = gamma0 sqrt(k/m)`` (eq. (2),
    no v0 dependence) and, at g~ = 0, ``e = exp(-pi xi / sqrt(1 - xi^2))`` with
    ``xi = gamma sqrt(5) / 4`` (report Appendix D): ``xi = -ln e / sqrt(pi^2 + ln^2 e)``.
    """
    _check(e=e, m=m, k=k)
    log_e = math.log(e)
    xi = abs(log_e) / math.hypot(math.pi, log_e)   # -ln e >= 0; abs: e = 1 gives +0.0
    gamma = 4.0 * xi / math.sqrt(5.0)
    per_gamma0, _ = scale(m, k, 1.0, 1.0, *TSUJI, g=0.0)
    return gamma / per_gamma0


#: Largest relative distance of the e that :func:`gamma0_for_cor`'s gamma0 gives from the e
#: asked. Brent's method sets gamma to 1e-13 relative; near the stick threshold e changes
#: faster than that lets it be set (KK at v0 = 0.01 m/s: within 7e-5 of e = 1e-6, 8% of
#: 1e-7), and past it e falls to 0, where no damping gives the e asked.
REACHED = 0.1


def gamma0_for_cor(e: float, v0: float, m: float, k: float, alpha: float, beta: float,
                   g: float = 9.81, F: float = 0.0, steps: float | None = None) -> float:
    """The gamma0 for which the numerical CoR at (v0, g, F) is e.

    e decreases with the scaled damping gamma, which is proportional to gamma0 (eq. (2));
    gamma is bracketed by doubling and found by Brent's method on ``sweep.cor`` (the
    integration, eqs. (3), (4)) to 1e-13 relative.

    Parameters
    ----------
    e : float
        Target CoR, in (0, 1].
    v0 : float
        Reference impact speed [m/s].
    m, k, alpha, beta : float
        Mass [kg], stiffness [N m^-alpha] and exponents of the law (1).
    g, F : float
        Gravity [m/s^2] and load [N] at the reference impact.
    steps : float, optional
        Integrator resolution (default: the package default).

    Returns
    -------
    float
        gamma0 [s m^(alpha-beta)].

    Raises
    ------
    ValueError
        A bad value (named), or an e that no damping reaches (to :data:`REACHED`).
    """
    from scipy.optimize import brentq

    _single(v0=v0, m=m, k=k, alpha=alpha, beta=beta, g=g, F=F)
    _check(e=e)
    per_gamma0, gtilde = scale(m, k, 1.0, v0, alpha, beta, g, F)
    if e == 1.0:
        return 0.0

    def excess(gamma: float) -> float:
        return api.cor(alpha, beta, gamma, gtilde, steps=steps) - e

    hi = 0.1
    while excess(hi) > 0.0:
        hi *= 2.0
        if hi > 1e6:
            raise ValueError(f"no damping gives e = {e!r} at v0 = {v0!r} m/s")
    gamma = brentq(excess, 0.0, hi, xtol=1e-300, rtol=1e-13, maxiter=200)
    miss = excess(gamma)
    if not abs(miss) <= REACHED * e:
        # Brent's method ends at a jump of e instead: the stick threshold, where e falls
        # to 0 within gamma0's rounding (or an e below what the march resolves, reported 0).
        raise ValueError(f"no damping gives e = {e!r} at v0 = {v0!r} m/s: e falls past it "
                         f"to {e + miss:.3g} at gamma0 = {gamma / per_gamma0:.6g} (near the "
                         "stick threshold e moves faster than gamma0 can be set)")
    return float(gamma / per_gamma0)

