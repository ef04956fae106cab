"""No-rebound thresholds: the critical load g~_c and the critical damping gamma_c.

Above the critical scaled load ``g~_c(alpha, beta, gamma)`` (resp. damping
``gamma_c(alpha, beta, g~)``) the bead no longer detaches after the impact: ``e = 0``.

``method="approx"``
    Proposition 1, (24): ``g~_c = (1 / (2 gamma C))^(1/r)``, equivalently
    ``gamma_c = 1 / (2 C g~^r)``, with ``C`` and ``r = b/a + 1/(2a) + 1/2`` of (23).
    Valid for small gamma (large g~_c); ``gamma = 0`` gives ``inf``, as does ``g~ = 0``.
``method="numeric"``
    The report's bisection on the numerical CoR (Figs. 8-11): the smallest g~ (resp. gamma)
    at which :func:`sweep.api.integrate` finds no rebound (status STUCK or AT_REST, e = 0),
    to relative precision 1e-8. All points are bracketed and bisected together, with one
    ``integrate`` call per iteration over the array of trial values. The search assumes that
    the bead rebounds below the threshold and not above it (e decreases with g~ and gamma,
    reaching 0 like the square root of the distance to the threshold under a load, SPEC
    section 7). "No rebound" is the integrator's: e = 0, or e below what it resolves
    (below).
    The bracket grows from (24) by factors of 4, then (where (24) is far off: small g~,
    creep) by factors that square each step, down to 1e-300 and up to 1e300 (or the top of
    the unknown's domain in :data:`sweep.registry.PARAMETERS`, where lower). Returns
    ``0.0`` where it does not rebound even at 1e-300, ``inf`` where it still rebounds at
    that top, and NaN where the integrator could not decide (budget exhausted) during the
    search, with a RuntimeWarning saying how many. The search integrates with the rest box
    at :data:`SEARCH_REST_TOL` (unless ``rest_tol`` is given): at the integrator's default,
    1e-8, a bead in the box counts as at rest though it may still leave with e up to ~1e-8,
    and thresholds at tiny loads came out low (KK's gamma_c at g~ = 1e-12: 36.8 for 80.0;
    g~_c at gamma = 40: 0 for 6.4e-11). A rebound the integrator reports as negligible
    still counts as none: e below a tenth of its refinement target (1e-10 at the defaults,
    tol/10 with ``tol``), given as 0 with that bound as e_err. Where e falls that low before
    the threshold, the result is where it does: KK's gamma_c at g~ = 1e-15 is 138 at the
    defaults (where e falls below 1e-10) and 253 with ``tol=1e-13``. At g~ = 0, gamma_c is
    the theory's where it has one (docs/creep.md, section 4): ``inf`` for
    ``2 beta > alpha + 1`` (the bead always leaves, with e falling like a power of gamma)
    and ``2 / sqrt(beta)`` for ``2 beta = alpha + 1`` (the linear law's 2, TTI's 1.789).

Owns: the no-rebound thresholds. May import: registry, :mod:`sweep.api` and
:mod:`sweep._arrays` (the floor below).
"""
from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from sweep import registry
from sweep._arrays import Broadcast
from sweep.api import check_integrate_options, integrate, large_gtilde_coefficient
from sweep.registry import Status

__all__ = ["critical_gtilde", "critical_gamma", "RTOL", "SEARCH_REST_TOL"]

#: Relative precision of the numerical bisection.
RTOL = 1e-8
#: The integrator's rest box during the search (its ``rest_tol``), unless given: a bead in
#: the box is taken to be at rest, so the box must be far below any rebound the search is
#: to see.
SEARCH_REST_TOL = 1e-15
_FACTOR = 4.0        # bracket expansion factor
_MAX_EXPAND = 20     # steps at _FACTOR (4^20 ~ 1e12 from (24)); beyond, the factor squares
_LOWEST, _HIGHEST = 1e-300, 1e300   # the bracket's ends: below, 0; above, inf
_METHODS = ("approx", "numeric")


def _constants(alpha, beta):
    """C and r of (23), NaN where the exponents are invalid."""
    valid = registry.PARAMETERS["alpha"].ok(alpha) & registry.PARAMETERS["beta"].ok(beta)
    c, r = large_gtilde_coefficient(np.where(valid, alpha, 1.0), np.where(valid, beta, 1.0))
    return np.where(valid, c, np.nan), np.where(valid, r, np.nan)


def _rebounds(alpha, beta, gamma, gtilde, options):
    """Per point: whether it rebounds (e > 0), and whether the integrator decided it."""
    if options.get("rest_tol") is None:      # None is "not given", as integrate takes it
        options = {**options, "rest_tol": SEARCH_REST_TOL}
    res = integrate(alpha, beta, gamma, gtilde, **options)
    status = np.asarray(res.status)
    e = np.asarray(res.e)
    rebound = (status == Status.OK) & (e > 0.0)
    stuck = (status == Status.STUCK) | (status == Status.AT_REST) | \
        ((status == Status.OK) & (e == 0.0))
    return rebound, rebound | stuck


def _top(unknown):
    """The bracket's top for ``unknown``: 1e300, or the maximum of its domain where lower
    (gamma's, :data:`sweep.registry.PARAMETERS`): a trial above it is an invalid point."""
    return min(_HIGHEST, registry.PARAMETERS[unknown].maximum)


def _next_trial(x0, lo, hi, expansions, top):
    """The next bracketing trial: ``x0`` first, then ``lo`` times (``hi`` over) a factor,
    4 for ``_MAX_EXPAND`` steps, squaring each step beyond, kept in [1e-300, top]."""
    extra = np.maximum(expansions - _MAX_EXPAND, 0)
    factor = np.exp(np.log(_FACTOR) * 2.0 ** np.minimum(extra, 16))   # inf beyond 4^2^9
    with np.errstate(over="ignore"):
        x = np.where((lo == 0.0) & np.isinf(hi), x0,
                     np.where(np.isinf(hi), lo * factor, hi / factor))
    return np.clip(x, _LOWEST, top)


def _geometric_mid(lo, hi):
    """sqrt(lo hi), also where lo hi overflows (thresholds above 1e154: the trial was inf,
    an invalid point, and the search gave NaN) or underflows (below 1e-162: 0)."""
    with np.errstate(over="ignore", under="ignore"):
        mid = np.sqrt(lo * hi)
    outside = ~((mid > lo) & (mid < hi))
    return np.where(outside, np.sqrt(lo) * np.sqrt(hi), mid)


def _threshold(evaluate, start, fallback_start, top):
    """Vectorised bracketing + geometric bisection for the smallest x without rebound.

    ``evaluate(x, idx) -> (rebound, decided)`` for the points ``idx`` at trial values ``x``.
    ``start``: approximate thresholds (``fallback_start`` where not finite and positive);
    ``top``: the bracket's upper end (:func:`_top`). Returns the thresholds and where the
    integrator could not decide a trial (NaN there).
    """
    size = start.size
    x0 = np.where(np.isfinite(start) & (start > 0.0), start, fallback_start)
    lo = np.zeros(size)            # largest value known to rebound (0: none yet)
    hi = np.full(size, np.inf)     # smallest value known not to rebound
    out = np.full(size, np.nan)
    active = np.isfinite(x0) & (x0 > 0.0)
    undecided = np.zeros(size, dtype=bool)
    expansions = np.zeros(size, dtype=int)

    def probe(idx, x):
        rebound, decided = evaluate(x, idx)
        bad = idx[~decided]
        active[bad] = False
        undecided[bad] = True
        ok = decided
        up = idx[ok & rebound]
        down = idx[ok & ~rebound]
        lo[up] = np.maximum(lo[up], x[ok & rebound])
        hi[down] = np.minimum(hi[down], x[ok & ~rebound])

    # Bracket, expanding geometrically from the approximate threshold.
    while True:
        need = active & ((lo == 0.0) | np.isinf(hi))
        # At an end of the range and still no bracket: no rebound down to 1e-300 is 0, a
        # rebound up to 1e300 is inf (the search stopped at 1e12 from (24) and returned 0
        # where (24) is 1e15 too high, g~ = 1e-9 for KK, while the bead rebounds there).
        none_down = need & (lo == 0.0) & (hi <= _LOWEST)
        all_up = need & np.isinf(hi) & (lo >= top)
        out[none_down], out[all_up] = 0.0, np.inf
        active &= ~(none_down | all_up)
        idx = np.flatnonzero(need & ~(none_down | all_up))
        if idx.size == 0:
            break
        probe(idx, _next_trial(x0[idx], lo[idx], hi[idx], expansions[idx], top))
        expansions[idx] += 1
    # Bisect in log space until hi/lo - 1 <= RTOL.
    while True:
        idx = np.flatnonzero(active & (hi > lo * (1.0 + RTOL)))
        if idx.size == 0:
            break
        probe(idx, _geometric_mid(lo[idx], hi[idx]))
    out[active] = hi[active]
    return out, undecided


def _check_method(method, options):
    """Refuse an unknown method, and an option the method does not use or a value its rule
    rejects, naming it: (24) uses none, the bisection :func:`sweep.api.integrate`'s (Python
    would raise a TypeError), checked before any point is integrated (where none is, a bad
    value went unnoticed)."""
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    if method == "approx" and options:
        raise ValueError("method 'approx' takes no integrator options (method 'numeric' "
                         f"does), got {', '.join(map(repr, options))}")
    if method == "numeric":
        registry.METHODS["numeric"].refuse_unknown(options, extra=("parallel",))
        check_integrate_options(options)


def _approx(unknown, x, c, r):
    """(24): g~_c = (1/(2 gamma C))^(1/r), equivalently gamma_c = 1/(2 C g~^r), of the
    known value ``x``. An intermediate that overflows (1/gamma for a subnormal gamma, g~^r
    for g~ = 1e200) gave inf for g~_c = 7e175 and an overflow warning: where the plain
    formula is inf or 0 for a positive x, the logarithms are summed instead."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if unknown == "gtilde":
            plain = (1.0 / (2.0 * x * c)) ** (1.0 / r)
            logs = -(np.log(2.0 * c) + np.log(x)) / r
        else:
            plain = 1.0 / (2.0 * c * x ** r)
            logs = -(np.log(2.0 * c) + r * np.log(x))
        redo = (x > 0.0) & np.isfinite(x) & ((plain == 0.0) | np.isinf(plain))
        return np.where(redo, np.exp(logs), plain)


def _critical(unknown, alpha, beta, known, method, options):
    """Threshold of ``unknown`` ("gtilde" or "gamma") given the other one, ``known``."""
    _check_method(method, options)
    other = "gamma" if unknown == "gtilde" else "gtilde"
    b = Broadcast(("alpha", "beta", other), (alpha, beta, known))
    b.raise_if_invalid()
    a, be, x = b.flat
    point = {"alpha": a, "beta": be, other: x, unknown: 0.0}
    valid = registry.valid_points(*(point[n] for n in registry.PARAMETER_NAMES))
    approx = np.where(valid, _approx(unknown, x, *_constants(a, be)), np.nan)
    if method == "approx" or not valid.any():
        return b.restore(approx)

    def evaluate(trial, idx):
        pt = {"alpha": a[idx], "beta": be[idx], other: x[idx], unknown: trial}
        return _rebounds(*(pt[n] for n in registry.PARAMETER_NAMES), options)

    out, undecided = _searched(unknown, evaluate, (a, be, x), valid, approx)
    _warn_undecided(np.count_nonzero(undecided))
    return b.restore(out)


def _searched(unknown, evaluate, points, valid, approx):
    """The numerical thresholds of ``unknown`` at ``points`` (alpha, beta and the other
    parameter's values; ``valid``: the points that are; ``approx``: (24) there), and where
    a trial was undecided."""
    a, be, x = points
    top = _top(unknown)
    if unknown == "gtilde":
        # gamma = 0 never sticks: g~_c = inf; the search starts from (24) elsewhere, from
        # the top where (24) overflows (a subnormal gamma), which then says inf.
        start = np.where(x > 0.0, np.where(np.isposinf(approx), top, approx), np.nan)
        out, undecided = _threshold(evaluate, start, np.nan, top)
        out[valid & (x == 0.0)] = np.inf
    else:
        out, undecided = _threshold(evaluate, approx, np.where(valid, 1.0, np.nan), top)
        exact = _gamma_c_at_zero_load(a, be)
        known_zero = valid & (x == 0.0) & ~np.isnan(exact)
        out[known_zero] = exact[known_zero]
    return out, undecided


def _warn_undecided(n: int) -> None:
    """Warn that ``n`` thresholds are NaN for an undecided search (as sweep.cor warns of
    points that ran out of their step budget)."""
    if n:
        warnings.warn(f"{n} threshold(s) undecided (NaN): the integrator ran out of its step "
                      "budget (status BUDGET_EXHAUSTED) during the search; max_steps gives "
                      "it a larger budget", RuntimeWarning, stacklevel=4)


def _gamma_c_at_zero_load(alpha, beta):
    """gamma_c at g~ = 0 where the theory gives it (docs/creep.md, section 4), NaN elsewhere:
    ``inf`` for kappa = alpha + 1 - 2 beta < 0 (the bead always leaves, with e ~ (gamma
    beta)^(-(alpha+1)/|kappa|), which the search would take for 0 once it is below the
    integrator's e_err), and ``2 / sqrt(beta)`` for kappa = 0 (zeta = gamma sqrt(beta) / 2 = 1:
    e = exp(-pi zeta / sqrt(1 - zeta^2)) falls to 1e-23 before it, below any e_err)."""
    kappa = alpha + 1.0 - 2.0 * beta
    return np.where(kappa < 0.0, np.inf, np.where(kappa == 0.0, 2.0 / np.sqrt(beta), np.nan))


def critical_gtilde(alpha: Any, beta: Any, gamma: Any, method: str = "approx",
                    **integrator_options: Any) -> Any:
    """Critical scaled load ``g~_c`` [1] above which the bead does not rebound.

    Parameters
    ----------
    alpha, beta : array_like
        Exponents [1], >= 1.
    gamma : array_like
        Scaled damping [1], >= 0, eq. (2).
    method : {"approx", "numeric"}
        Proposition 1, (24), or bisection on the numerical CoR (see the module docstring).
    **integrator_options
        For ``"numeric"`` only: passed to :func:`sweep.api.integrate` (``steps``,
        ``rest_tol``, ``max_steps``, ...); ``"approx"`` takes none.

    Returns
    -------
    ndarray or float
        ``g~_c``, broadcast over the inputs (float for a scalar call); ``inf`` at gamma = 0,
        NaN at invalid points of an array call.

    Raises
    ------
    ValueError
        Unknown method, or an option the method does not use (naming it); a scalar call
        with an invalid value (naming it).
    """
    return _critical("gtilde", alpha, beta, gamma, method, integrator_options)


def critical_gamma(alpha: Any, beta: Any, gtilde: Any, method: str = "approx",
                   **integrator_options: Any) -> Any:
    """Critical scaled damping ``gamma_c`` [1] above which the bead does not rebound.

    Parameters
    ----------
    alpha, beta : array_like
        Exponents [1], >= 1.
    gtilde : array_like
        Scaled load [1], >= 0, eq. (2).
    method : {"approx", "numeric"}
        ``gamma_c = 1 / (2 C g~^r)`` from (24), or bisection on the numerical CoR.
    **integrator_options
        For ``"numeric"`` only: passed to :func:`sweep.api.integrate`; ``"approx"`` takes
        none.

    Returns
    -------
    ndarray or float
        ``gamma_c``; the approximation gives ``inf`` at g~ = 0, where the numerical search
        starts from gamma = 1. (24) holds at large g~ (small gamma_c): at small g~ it is far
        above the threshold (the linear law at g~ = 1e-3: 1.6e5 against 1.77), and it was
        above it at every point checked, so it is no safe no-rebound bound.

    Raises
    ------
    ValueError
        Unknown method, or an option the method does not use (naming it); a scalar call
        with an invalid value (naming it).
    """
    return _critical("gamma", alpha, beta, gtilde, method, integrator_options)
