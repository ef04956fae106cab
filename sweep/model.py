"""The impact model, its scaling to (gamma, g~) and the per-point status codes.

The report's contact law (1) for a bead of mass ``m`` hitting a floor at speed ``v0``::

    m x'' = k [(-x)_+^alpha + gamma0 d/dt (-x)_+^beta] - m g - F

is reduced by the scaling (2) to the dimensionless problem::

    u'' + gamma d/dtau (u_+^beta) + u_+^alpha = g~,   u(0) = 0,  u'(0) = 1

so that every downstream computation depends only on ``(alpha, beta, gamma, g~)``.

Owns: the scaling of physical inputs and the array forms of the regime numbers. May import:
registry, :mod:`sweep.kernels.contact` (the regime formulas live there, once).
"""
from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np

from sweep import registry
from sweep.kernels import contact
from sweep.kernels._jit import kernel_cache
from sweep.registry import MODELS, Status

__all__ = ["Status", "scale", "equilibrium", "damping_ratio", "natural_frequency",
           "check_exponents", "MODELS"]


def check_exponents(alpha: Any, beta: Any) -> tuple[np.ndarray, np.ndarray]:
    """Validate contact exponents (Assumption 1 of the report: alpha >= 1, beta >= 1).

    Raises
    ------
    ValueError
        Naming the offending argument and value.
    """
    return registry.check_array("alpha", alpha), registry.check_array("beta", beta)


def scale(m, k, gamma0, v0, alpha, beta, g=9.81, F=0.0):
    """Scale a physical impact to the report's dimensionless numbers, eq. (2).

    With ``T = (m/k)^(1/(alpha+1)) v0^((1-alpha)/(alpha+1))`` and ``delta = v0 T``::

        gamma = gamma0 v0^(2 beta/(alpha+1) - 1) (k/m)^(1 - beta/(alpha+1))
        g~    = (m/k)^(1/(alpha+1)) v0^(-2 alpha/(alpha+1)) (g + F/m)

    All arguments broadcast against each other (numpy rules).

    Parameters
    ----------
    m : float or array_like
        Bead mass [kg], > 0.
    k : float or array_like
        Contact stiffness [N m^-alpha], > 0.
    gamma0 : float or array_like
        Damping coefficient [s m^(alpha-beta)], >= 0 (so that k gamma0 d/dt x^beta is a force).
    v0 : float or array_like
        Impact speed [m/s], > 0.
    alpha, beta : float or array_like
        Stiffness and damping exponents, >= 1 (Assumption 1).
    g : float or array_like, default 9.81
        Gravitational acceleration [m/s^2].
    F : float or array_like, default 0
        Constant compressive load [N]; ``g + F/m`` must be >= 0.

    Returns
    -------
    gamma, gtilde : ndarray or float
        Dimensionless damping and load (0-d inputs give Python floats).

    Raises
    ------
    ValueError
        Naming the first offending argument and value.
    """
    args = {name: registry.check_array(name, val) for name, val in
            dict(m=m, k=k, gamma0=gamma0, v0=v0, g=g, F=F).items()}
    a, b = check_exponents(alpha, beta)
    m_, k_, g0, v0_, g_, F_ = (args[n] for n in ("m", "k", "gamma0", "v0", "g", "F"))
    load = g_ + F_ / m_
    if np.any(load < 0):
        bad = np.broadcast_to(load, np.broadcast(load, m_).shape)
        raise ValueError("g + F/m must be >= 0 (a compressive load), got "
                         f"{float(bad[bad < 0].reshape(-1)[0])!r} m/s^2")
    ap1 = a + 1.0
    gamma = g0 * v0_ ** (2.0 * b / ap1 - 1.0) * (k_ / m_) ** (1.0 - b / ap1)
    gtilde = (m_ / k_) ** (1.0 / ap1) * v0_ ** (-2.0 * a / ap1) * load
    if np.ndim(gamma) == 0 and np.ndim(gtilde) == 0:
        return float(gamma), float(gtilde)
    gamma, gtilde = np.broadcast_arrays(gamma, gtilde)
    return gamma.copy(), gtilde.copy()


def _ufunc(scalar):
    # One formula (sweep.kernels.contact) in two compiled forms: inlined in the kernels and
    # a numpy ufunc here, compiled on first use.
    with kernel_cache():
        return nb.vectorize(cache=True)(scalar.py_func)


_equilibrium = _ufunc(contact.equilibrium)
_natural_frequency = _ufunc(contact.natural_frequency)
_damping_ratio = _ufunc(contact.damping_ratio)


def equilibrium(alpha: Any, gtilde: Any) -> Any:
    """Static equilibrium compression ``u-bar = g~^(1/alpha)`` [1] (report Sec. 3)."""
    return _equilibrium(np.asarray(alpha, dtype=float), np.asarray(gtilde, dtype=float))


def natural_frequency(alpha: Any, gtilde: Any) -> Any:
    """Linearised angular frequency about u-bar [1/tau],
    ``omega_n = sqrt(alpha) g~^((alpha-1)/(2 alpha))``."""
    return _natural_frequency(np.asarray(alpha, dtype=float), np.asarray(gtilde, dtype=float))


def damping_ratio(alpha: Any, beta: Any, gamma: Any, gtilde: Any) -> Any:
    """Linearised damping ratio about u-bar [1] (underdamped iff < 1)::

        xi = gamma beta / (2 sqrt(alpha)) g~^((2 beta - alpha - 1) / (2 alpha))
    """
    return _damping_ratio(*(np.asarray(x, dtype=float) for x in (alpha, beta, gamma, gtilde)))
