"""Public, vectorised entry points: :func:`integrate` and :func:`cor`.

Arguments broadcast with numpy rules. Inside arrays an invalid point (alpha < 1, beta < 1,
gamma < 0, g~ < 0, NaN or inf) gets ``e = NaN`` and status INVALID without spoiling the
others; a call with scalars only raises ``ValueError`` naming the bad value instead.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep._arrays import broadcast_points
from sweep.kernels.integrator import (DEFAULT_MAX_STEPS, DEFAULT_REST_TOL, DEFAULT_STEPS,
                              integrate_arrays)
from sweep.model import Status

__all__ = ["integrate", "cor", "cor_with_status", "IntegrationResult", "METHODS",
           "APPROXIMATIONS", "DEFAULT_STEPS", "DEFAULT_MAX_STEPS", "DEFAULT_REST_TOL"]

#: The report's closed-form approximations (Sections 4-5), see :mod:`sweep.kernels.approx`.
APPROXIMATIONS = ("ord1", "sp", "large_gtilde", "ord2_numint", "ord2_approx")
#: Every method :func:`cor` accepts.
METHODS = ("numeric",) + APPROXIMATIONS


@dataclass(frozen=True)
class IntegrationResult:
    """Per-point results of :func:`integrate` (arrays in the broadcast shape of the inputs,
    Python scalars -- and a :class:`~sweep.model.Status` -- for a scalar call).

    Attributes
    ----------
    e : ndarray of float64
        Coefficient of restitution ``-v(T_f)`` [1], eq. (3); 0 when the bead does not rebound.
    sticks : ndarray of bool
        The bead does not rebound (status STUCK or AT_REST).
    t_f : ndarray of float64
        Scaled time at which the impact ended [1] (detachment, or when sticking / rest was
        established); multiply by ``T`` of (2) for seconds.
    u_max : ndarray of float64
        Maximum compression [1] (multiply by ``delta = v0 T`` for metres); NaN where the
        outcome was decided before it was reached (overdamped creep).
    n_steps : ndarray of int64
        Runge-Kutta steps taken, event refinement included.
    status : ndarray of int8
        :class:`~sweep.model.Status` values.
    """

    e: Any
    sticks: Any
    t_f: Any
    u_max: Any
    n_steps: Any
    status: Any


def _check_settings(steps, rest_tol, max_steps):
    steps = DEFAULT_STEPS if steps is None else steps
    max_steps = DEFAULT_MAX_STEPS if max_steps is None else max_steps
    if not (np.isfinite(steps) and steps >= 2):
        raise ValueError(f"steps must be a number >= 2 (steps per half period), got {steps!r}")
    if not (np.isfinite(rest_tol) and rest_tol > 0):
        raise ValueError(f"rest_tol must be > 0, got {rest_tol!r}")
    if int(max_steps) != max_steps or max_steps < 1:
        raise ValueError(f"max_steps must be a positive integer, got {max_steps!r}")
    return float(steps), float(rest_tol), int(max_steps)


def integrate(alpha, beta, gamma, gtilde, *, steps=None, rest_tol=DEFAULT_REST_TOL,
              max_steps=None, parallel=None):
    """Numerical coefficient of restitution by a fixed-step Runge-Kutta 5(4) march.

    Integrates the scaled problem (2) in the Lipschitz form (4) with the three phases of the
    report's Algorithm 1 (see :mod:`sweep.kernels.integrator`), in parallel over points.

    Parameters
    ----------
    alpha, beta : array_like
        Stiffness and damping exponents [1], >= 1 (KK: 3/2, 3/2; SHC: 3/2, 5/2; ...).
    gamma : array_like
        Scaled damping [1], >= 0, eq. (2).
    gtilde : array_like
        Scaled load g~ [1], >= 0, eq. (2).
    steps : float, optional
        Resolution: steps per half period of the stiffest linearised motion (default
        :data:`DEFAULT_STEPS`); the error falls like ``steps**-5``.
    rest_tol : float, default 1e-8
        Rest criterion ``max(|u - u-bar|, |v|) < rest_tol`` (report, Sec. 3).
    max_steps : int, optional
        Step budget per point (default :data:`DEFAULT_MAX_STEPS`).
    parallel : bool, optional
        Force the parallel (True) or serial (False) kernel; by default parallel unless called
        from a thread where numba's threading layer is unsafe. Results are bit-identical.

    Returns
    -------
    IntegrationResult
    """
    steps, rest_tol, max_steps = _check_settings(steps, rest_tol, max_steps)
    b = broadcast_points(alpha, beta, gamma, gtilde)
    out = integrate_arrays(*b.flat, steps, rest_tol, max_steps, parallel=parallel)
    status = out["status"]
    sticks = (status == Status.STUCK) | (status == Status.AT_REST)
    res = {k: b.restore(v) for k, v in out.items()}
    res["sticks"] = b.restore(sticks)
    if b.scalar:
        res["status"] = Status(res["status"])
        res["n_steps"] = int(res["n_steps"])
    return IntegrationResult(**res)


def cor_with_status(alpha, beta, gamma, gtilde, method="numeric", **options):
    """Like :func:`cor`, also returning the per-point :class:`~sweep.model.Status` codes."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if method == "numeric":
        r = integrate(alpha, beta, gamma, gtilde, **options)
        return r.e, r.status
    from sweep.kernels import approx  # noqa: PLC0415 -- keeps the integrator usable on its own

    b = broadcast_points(alpha, beta, gamma, gtilde)
    e, status = approx.approx_cor(method, *b.flat, **options)
    if b.scalar and status[0] == Status.INVALID:
        raise ValueError(f"method {method!r} is not defined at alpha={float(b.flat[0][0])!r}, "
                         f"beta={float(b.flat[1][0])!r} (see sweep.kernels.approx)")
    st = b.restore(status)
    return b.restore(e), (Status(st) if b.scalar else st)


def cor(alpha, beta, gamma, gtilde, method="numeric", **options):
    """Coefficient of restitution ``e`` [1] by the numerical march or an approximation.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : array_like
        Scaled parameters (see :func:`integrate`), broadcast together.
    method : str
        ``"numeric"`` (:func:`integrate`), or one of the report's approximations:
        ``"ord1"`` (22), ``"sp"`` (25), (30), ``"large_gtilde"`` (23),
        ``"ord2_numint"`` and ``"ord2_approx"`` (Prop. 2 with I, Q by quadrature or by the
        Chebyshev-Beta approximation, option ``n``).
    **options
        Passed to :func:`integrate` (``steps``, ``rest_tol``, ``max_steps``) or to the
        approximation (``n``).

    Returns
    -------
    ndarray of float64 (float for a scalar call)
    """
    return cor_with_status(alpha, beta, gamma, gtilde, method, **options)[0]
