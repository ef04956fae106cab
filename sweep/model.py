"""The impact model, its scaling to (gamma, g~) and the per-point status codes.

The report's contact law (1) for a bead of mass ``m`` hitting a floor at speed ``v0``::

    m x'' = k [(-x)_+^alpha + gamma0 d/dt (-x)_+^beta] - m g - F

is reduced by the scaling (2) to the dimensionless problem::

    u'' + gamma d/dtau (u_+^beta) + u_+^alpha = g~,   u(0) = 0,  u'(0) = 1

so that every downstream computation depends only on ``(alpha, beta, gamma, g~)``.
"""
from __future__ import annotations

import enum

import numpy as np

__all__ = ["Status", "scale", "equilibrium", "damping_ratio", "natural_frequency",
           "check_exponents", "MODELS"]

#: The report's named contact laws: name -> (alpha, beta).
MODELS = {
    "linear": (1.0, 1.0),
    "hertz": (1.5, 1.0),
    "tti": (1.5, 1.25),
    "kk": (1.5, 1.5),
    "shc": (1.5, 2.5),
}


class Status(enum.IntEnum):
    """Why the computation of one point ended.

    The integer values are stored in datasets (``status`` variable); never renumber them.
    """

    #: The bead detached (u = 0 with v < 0): ``e = -v`` at detachment.
    OK = 0
    #: The bead does not rebound (v = 0 with 0 < u <= u-bar in phase 3, or its energy fell
    #: below the floor level, from which it can never return to u = 0): ``e = 0``.
    STUCK = 1
    #: Converged to rest, ``max(|u - u-bar|, |v|) < rest_tol`` (report, Sec. 3): ``e = 0``.
    AT_REST = 2
    #: The step budget ran out before the outcome was decided. ``e = sqrt(2 H)``, the bound
    #: on the rebound speed set by the energy still available, not a converged value.
    BUDGET_EXHAUSTED = 3
    #: Invalid input (alpha < 1, beta < 1, gamma < 0, g~ < 0, non-finite, or an
    #: approximation used outside its domain): ``e = NaN``.
    INVALID = 4


def _as_float_array(name, value):
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real number or array of them, got {value!r}") from exc
    return arr


def _first_bad(arr, bad):
    """Return the first offending value of ``arr`` where ``bad`` is true."""
    idx = np.flatnonzero(np.broadcast_to(bad, arr.shape))[0]
    return arr.reshape(-1)[idx]


def _require(name, arr, ok, rule):
    finite = np.isfinite(arr)
    if not finite.all():
        raise ValueError(f"{name} must be finite, got {_first_bad(arr, ~finite)!r}")
    good = ok(arr)
    if not np.all(good):
        raise ValueError(f"{name} must be {rule}, got {_first_bad(arr, ~good)!r}")


def check_exponents(alpha, beta):
    """Validate contact exponents (Assumption 1 of the report: alpha >= 1, beta >= 1).

    Raises
    ------
    ValueError
        Naming the offending argument and value.
    """
    a = _as_float_array("alpha", alpha)
    b = _as_float_array("beta", beta)
    _require("alpha", a, lambda x: x >= 1.0, ">= 1 (uniqueness is not known below 1)")
    _require("beta", b, lambda x: x >= 1.0, ">= 1 (uniqueness is not known below 1)")
    return a, b


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
    args = {name: _as_float_array(name, val) for name, val in
            dict(m=m, k=k, gamma0=gamma0, v0=v0, g=g, F=F).items()}
    a, b = check_exponents(alpha, beta)
    _require("m", args["m"], lambda x: x > 0, "> 0 [kg]")
    _require("k", args["k"], lambda x: x > 0, "> 0")
    _require("gamma0", args["gamma0"], lambda x: x >= 0, ">= 0")
    _require("v0", args["v0"], lambda x: x > 0, "> 0 [m/s]")
    _require("g", args["g"], lambda x: np.ones_like(x, dtype=bool), "finite")
    _require("F", args["F"], lambda x: np.ones_like(x, dtype=bool), "finite")
    m_, k_, g0, v0_, g_, F_ = (args[n] for n in ("m", "k", "gamma0", "v0", "g", "F"))
    load = g_ + F_ / m_
    if np.any(load < 0):
        bad = np.broadcast_to(load, np.broadcast(load, m_).shape)
        raise ValueError(f"g + F/m must be >= 0 (a compressive load), got {_first_bad(bad, bad < 0)!r} m/s^2")
    ap1 = a + 1.0
    gamma = g0 * v0_ ** (2.0 * b / ap1 - 1.0) * (k_ / m_) ** (1.0 - b / ap1)
    gtilde = (m_ / k_) ** (1.0 / ap1) * v0_ ** (-2.0 * a / ap1) * load
    if np.ndim(gamma) == 0 and np.ndim(gtilde) == 0:
        return float(gamma), float(gtilde)
    gamma, gtilde = np.broadcast_arrays(gamma, gtilde)
    return gamma.copy(), gtilde.copy()


def equilibrium(alpha, gtilde):
    """Static equilibrium compression ``u-bar = g~^(1/alpha)`` (dimensionless, Sec. 3)."""
    return np.asarray(gtilde, dtype=float) ** (1.0 / np.asarray(alpha, dtype=float))


def natural_frequency(alpha, gtilde):
    """Linearised angular frequency about u-bar, ``omega_n = sqrt(alpha) g~^((alpha-1)/(2 alpha))``."""
    a = np.asarray(alpha, dtype=float)
    return np.sqrt(a) * np.asarray(gtilde, dtype=float) ** ((a - 1.0) / (2.0 * a))


def damping_ratio(alpha, beta, gamma, gtilde):
    """Linearised damping ratio about u-bar (underdamped iff < 1)::

        xi = gamma beta / (2 sqrt(alpha)) g~^((2 beta - alpha - 1) / (2 alpha))
    """
    a = np.asarray(alpha, dtype=float)
    b = np.asarray(beta, dtype=float)
    return (np.asarray(gamma, dtype=float) * b / (2.0 * np.sqrt(a))
            * np.asarray(gtilde, dtype=float) ** ((2.0 * b - a - 1.0) / (2.0 * a)))
