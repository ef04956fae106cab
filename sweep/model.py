"""The impact model, its scaling to (gamma, g~) and the per-point status codes.

The report's contact law (1) for a bead of mass ``m`` hitting a floor at speed ``v0``::

    m x'' = k [(-x)_+^alpha + gamma0 d/dt (-x)_+^beta] - m g - F

is reduced by the scaling (2) to the dimensionless problem::

    u'' + gamma d/dtau (u_+^beta) + u_+^alpha = g~,   u(0) = 0,  u'(0) = 1

so that every downstream computation depends only on ``(alpha, beta, gamma, g~)``.

Owns: the scaling of physical inputs and the array forms of the regime numbers. May import:
registry, :mod:`sweep._arrays` (broadcasting), :mod:`sweep.kernels.contact` (the regime formulas
live there, once).
"""
from __future__ import annotations

import math
from typing import Any

import numba as nb
import numpy as np

from sweep import registry
from sweep._arrays import check_broadcast, flat_broadcast
from sweep.kernels import contact
from sweep.kernels._jit import cached_jit, jit, kernel_cache
from sweep.registry import MODELS, Status

__all__ = ["Status", "scale", "time_scale", "equilibrium", "damping_ratio",
           "natural_frequency", "check_exponents", "MODELS"]


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
        Dimensionless damping and load (0-d inputs give Python floats). A value below the
        smallest double is 0, which is a valid gamma or g~.

    Raises
    ------
    ValueError
        Naming the first offending argument and value; shapes that do not broadcast,
        naming the parameters; or inputs, each in its domain, whose gamma, g~ or g + F/m
        is beyond double precision, naming the quantity and the inputs.
    """
    args = {name: registry.check_array(name, val) for name, val in
            dict(m=m, k=k, gamma0=gamma0, v0=v0, g=g, F=F).items()}
    args["alpha"], args["beta"] = check_exponents(alpha, beta)
    check_broadcast(tuple(args), tuple(args.values()))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        load = args["g"] + args["F"] / args["m"]
        _check_load(load, args)
        gamma, gtilde = _scaled(args, load)
    if np.ndim(gamma) == 0 and np.ndim(gtilde) == 0:
        return float(gamma), float(gtilde)
    gamma, gtilde = np.broadcast_arrays(gamma, gtilde)
    return gamma.copy(), gtilde.copy()


def time_scale(m: Any, k: Any, v0: Any, alpha: Any) -> Any:
    """The time unit ``T`` [s] of the scaling (2): ``T = (m/k)^(1/(alpha+1))
    v0^((1-alpha)/(alpha+1))``, and with it the length unit ``delta = v0 T`` [m].

    A scaled duration times T is in seconds (the integrator's ``t_f``: the contact's
    duration), a scaled compression times ``v0 T`` in metres (``u_max``). Broadcast as
    :func:`scale`; where a factor overflows or underflows while T is representable, T is
    formed from logarithms.

    Parameters
    ----------
    m, k, v0 : float or array_like
        Bead mass [kg], contact stiffness [N m^-alpha] and impact speed [m/s], each > 0.
    alpha : float or array_like
        Stiffness exponent, >= 1.

    Returns
    -------
    ndarray or float
        T [s] (a Python float for 0-d inputs).

    Raises
    ------
    ValueError
        Naming the first offending argument and value, shapes that do not broadcast, or
        inputs whose T is beyond double precision (naming them).
    """
    args = {name: registry.check_array(name, val) for name, val in
            dict(m=m, k=k, v0=v0).items()}
    args["alpha"] = check_exponents(alpha, 1.0)[0]
    check_broadcast(tuple(args), tuple(args.values()))
    m, k, v0, alpha = (np.asarray(args[n], dtype=np.float64)
                       for n in ("m", "k", "v0", "alpha"))
    ap1 = alpha + 1.0
    with np.errstate(over="ignore", under="ignore", divide="ignore", invalid="ignore"):
        t = (m / k) ** (1.0 / ap1) * v0 ** ((1.0 - alpha) / ap1)
        logs = np.exp((np.log(m) - np.log(k) + (1.0 - alpha) * np.log(v0)) / ap1)
    t = np.where(np.isfinite(t) & (t > 0.0), t, logs)
    bad = ~(np.isfinite(t) & (t > 0.0))
    if bad.any():
        got, at = _at("T", t, bad, args)
        raise ValueError(f"T is {got!r} (beyond double precision) at {at}; the scaling (2) "
                         "of these inputs is out of floating-point range")
    return float(t) if t.ndim == 0 else t


#: The inputs each scaled quantity depends on (named when it overflows).
_DEPENDS = {"g + F/m": ("g", "F", "m"),
            "T": ("m", "k", "v0", "alpha"),
            "gamma": ("gamma0", "v0", "k", "m", "alpha", "beta"),
            "gtilde": ("m", "k", "v0", "alpha", "g", "F")}


def _at(quantity: str, value: np.ndarray, bad: np.ndarray, args: dict) -> tuple[float, str]:
    """The first bad element of ``value`` and the inputs it comes from, as ``name=value``."""
    shape = np.shape(value)
    i = np.flatnonzero(np.broadcast_to(bad, shape).reshape(-1))[0]
    at = ", ".join(f"{n}={float(np.broadcast_to(args[n], shape).reshape(-1)[i])!r}"
                   for n in _DEPENDS[quantity])
    return float(np.reshape(value, -1)[i]), at


def _refuse_non_finite(quantity: str, value: np.ndarray, args: dict) -> None:
    """Raise ``ValueError`` at the first non-finite element of ``value``, naming the inputs
    it comes from: each is in its domain, their combination is not representable."""
    bad = ~np.isfinite(value)
    if bad.any():
        got, at = _at(quantity, value, bad, args)
        raise ValueError(f"{quantity} overflows to {got!r} (beyond double precision) at {at}; "
                         "the scaling (2) of these inputs is out of floating-point range")


def _check_load(load: np.ndarray, args: dict) -> None:
    """g + F/m must be a finite compressive load (>= 0)."""
    _refuse_non_finite("g + F/m", load, args)
    if np.any(load < 0):
        got, at = _at("g + F/m", load, load < 0, args)
        raise ValueError(f"g + F/m must be >= 0 (a compressive load), got {got!r} m/s^2 "
                         f"at {at}")


def _scaled(args: dict, load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """gamma and g~ of eq. (2), point by point in compiled scalar arithmetic
    (:func:`_scaled_points`): numpy's own powers take a SIMD loop for contiguous arrays and
    libm for scalars and strided views, whose last bits differ (1-2 ulp at 4% of
    general-exponent points), so a scene's gamma depended on the array's layout."""
    inputs = [args[n] for n in ("m", "k", "gamma0", "v0", "alpha", "beta")] + [load]
    shape = np.broadcast_shapes(*(np.shape(x) for x in inputs))
    flat = [flat_broadcast(np.asarray(x), shape) for x in inputs]
    gamma, gtilde = np.empty(flat[0].size), np.empty(flat[0].size)
    _scaled_points(*flat, gamma, gtilde)
    gamma, gtilde = gamma.reshape(shape), gtilde.reshape(shape)
    _refuse_non_finite("gamma", gamma, args)
    _refuse_non_finite("gtilde", gtilde, args)
    _refuse_outside_domain("gamma", gamma, args)
    return gamma, gtilde


@jit(inline="always")
def _gamma_at(m, k, gamma0, v0, alpha, beta):
    """gamma of eq. (2) at one point."""
    ap1 = alpha + 1.0
    gamma = gamma0 * v0 ** (2.0 * beta / ap1 - 1.0) * (k / m) ** (1.0 - beta / ap1)
    # A factor (k/m, v0^p) may overflow or underflow where the product is representable
    # (m = 1e-300, k = 1e300): there, and only there (elsewhere results stay bit for bit
    # those of the plain formula), sum the logarithms instead. Compiled, log 0 = -inf (no
    # exception), which gives 0.
    if math.isfinite(gamma) and not (gamma == 0.0 and gamma0 > 0.0):
        return gamma
    return math.exp(math.log(gamma0) + (2.0 * beta / ap1 - 1.0) * math.log(v0)
                    + (1.0 - beta / ap1) * (math.log(k) - math.log(m)))


@jit(inline="always")
def _gtilde_at(m, k, v0, alpha, load):
    """g~ of eq. (2) at one point, ``load`` = g + F/m; as :func:`_gamma_at`."""
    ap1 = alpha + 1.0
    gtilde = (m / k) ** (1.0 / ap1) * v0 ** (-2.0 * alpha / ap1) * load
    if math.isfinite(gtilde) and not (gtilde == 0.0 and load > 0.0):
        return gtilde
    return math.exp((math.log(m) - math.log(k)) / ap1 - 2.0 * alpha / ap1 * math.log(v0)
                    + math.log(load))


# One compiled loop, not two numba ufuncs: after a CoR call has loaded the compiled code's
# machinery, the first sweep.scale() of a process loads this in 0.01 s, them in 0.24 s.
@cached_jit()
def _scaled_points(m, k, gamma0, v0, alpha, beta, load, gamma, gtilde):
    """:func:`_gamma_at` and :func:`_gtilde_at` of flat arrays, into ``gamma``, ``gtilde``."""
    for i in range(m.size):
        gamma[i] = _gamma_at(m[i], k[i], gamma0[i], v0[i], alpha[i], beta[i])
        gtilde[i] = _gtilde_at(m[i], k[i], v0[i], alpha[i], load[i])


def _refuse_outside_domain(quantity: str, value: np.ndarray, args: dict) -> None:
    """Raise ``ValueError`` at the first finite element of ``value`` outside the domain of
    :data:`sweep.registry.PARAMETERS` (gamma above its maximum), naming the inputs: the
    integrator would mark every such point INVALID and a run would exit 0 with NaNs."""
    parameter = registry.PARAMETERS[quantity]
    bad = ~parameter.ok(value)
    if bad.any():
        got, at = _at(quantity, value, bad, args)
        raise ValueError(f"{quantity} = {got!r} at {at}: the scaled {quantity} must be "
                         f"{parameter.rule}")


def _ufunc(scalar):
    # One formula (sweep.kernels.contact) in two compiled forms: inlined in the kernels and
    # a numpy ufunc here, compiled on first use.
    with kernel_cache():
        return nb.vectorize(cache=True)(scalar.py_func)


_equilibrium = _ufunc(contact.equilibrium)
_natural_frequency = _ufunc(contact.natural_frequency)
_damping_ratio = _ufunc(contact.damping_ratio)


def _regime_inputs(**values: Any) -> list[np.ndarray]:
    """The inputs of a regime number, each checked against its domain
    (:data:`sweep.registry.PARAMETERS`) and the shapes against each other.

    Raises
    ------
    ValueError
        Naming the first offending parameter and value, or the shapes that do not broadcast.
    """
    arrays = [registry.check_array(name, value) for name, value in values.items()]
    check_broadcast(tuple(values), arrays)
    return arrays


def equilibrium(alpha: Any, gtilde: Any) -> Any:
    """Static equilibrium compression ``u-bar = g~^(1/alpha)`` [1] (report Sec. 3).

    Parameters
    ----------
    alpha : array_like
        Stiffness exponent [1], >= 1.
    gtilde : array_like
        Scaled load g~ [1], >= 0, eq. (2).

    Raises
    ------
    ValueError
        A value outside its domain or shapes that do not broadcast, naming the parameters.
    """
    return _equilibrium(*_regime_inputs(alpha=alpha, gtilde=gtilde))


def natural_frequency(alpha: Any, gtilde: Any) -> Any:
    """Linearised angular frequency about u-bar [1/tau],
    ``omega_n = sqrt(alpha) g~^((alpha-1)/(2 alpha))``.

    Parameters and errors as for :func:`equilibrium`.
    """
    return _natural_frequency(*_regime_inputs(alpha=alpha, gtilde=gtilde))


def damping_ratio(alpha: Any, beta: Any, gamma: Any, gtilde: Any) -> Any:
    """Linearised damping ratio about u-bar [1] (underdamped iff < 1)::

        xi = gamma beta / (2 sqrt(alpha)) g~^((2 beta - alpha - 1) / (2 alpha))

    Parameters
    ----------
    alpha, beta : array_like
        Exponents [1], >= 1.
    gamma, gtilde : array_like
        Scaled damping and load [1], >= 0, eq. (2).

    Raises
    ------
    ValueError
        A value outside its domain or shapes that do not broadcast, naming the parameters.
    """
    return _damping_ratio(*_regime_inputs(alpha=alpha, beta=beta, gamma=gamma, gtilde=gtilde))
