"""Public, vectorised entry points: :func:`integrate`, :func:`cor` and the report's coefficients.

Arguments broadcast with numpy rules. Inside arrays an invalid point (alpha < 1, beta < 1,
gamma < 0, g~ < 0, NaN or inf: the domain of :data:`sweep.registry.PARAMETERS`) gets
``e = NaN`` and status INVALID without spoiling the others; a call with scalars only raises
``ValueError`` naming the bad value instead. Methods, their options and the integrator's
output fields are read from :mod:`sweep.registry`.

Owns: broadcasting, validation and dispatch of the public functions. May import: registry,
kernels, :mod:`sweep._arrays`.
"""
from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from sweep import registry
from sweep._arrays import Broadcast, broadcast_points
from sweep.kernels import approx as _approx
from sweep.kernels.devices import integrate_on
from sweep.kernels.integrator import DEFAULT_MAX_STEPS, DEFAULT_REST_TOL, DEFAULT_STEPS, settings
from sweep.registry import Status

__all__ = ["integrate", "cor", "cor_with_status", "cor_fields", "IntegrationResult", "METHODS",
           "APPROXIMATIONS", "DEFAULT_STEPS", "DEFAULT_MAX_STEPS", "DEFAULT_REST_TOL",
           "coefficients", "coefficients_at_zero", "first_order_coefficients",
           "large_gtilde_coefficient", "SP_C2", "integrator_settings", "method_settings",
           "recorded_settings", "given_options", "method_arrays",
           "composite_integrator_settings", "check_integrate_options"]

#: The report's closed-form approximations (Sections 4-5) built into the package.
APPROXIMATIONS = registry.approximations()
#: Every built-in method :func:`cor` accepts (``registry.register_method`` adds more).
METHODS = tuple(registry.METHODS)
#: Schwager-Poeschel's second-order coefficient for KK at g~ = 0, (30): -(9/4) c2.
SP_C2 = _approx.SP_C2


def _result_doc() -> str:
    lines = ["Per-point results of :func:`integrate` (arrays in the broadcast shape of the",
             "inputs; Python scalars -- and a :class:`~sweep.registry.Status` -- for a scalar",
             "call). Its attributes are the fields of :data:`sweep.registry.FIELDS`:", ""]
    for f in registry.FIELDS.values():
        lines.append(f"``{f.name}`` ({f.dtype.name}, units {f.units}): {f.long_name}; "
                     f"{f.description}.")
    return "\n".join(lines)


def _result_class() -> type:
    return dataclasses.make_dataclass(
        "IntegrationResult", [(name, Any) for name in registry.FIELDS], frozen=True,
        namespace={"__doc__": _result_doc(), "__module__": __name__})


IntegrationResult = _result_class()
# One class per set of fields: a field registered, then unregistered, gives the first class
# back (isinstance against a class imported before still holds).
_RESULT_CLASSES = {tuple(registry.FIELDS): IntegrationResult}


def _result_type() -> type:
    """:class:`IntegrationResult` for the fields registered now (``register_field``)."""
    global IntegrationResult
    names = tuple(registry.FIELDS)
    if names not in _RESULT_CLASSES:
        _RESULT_CLASSES[names] = _result_class()
    IntegrationResult = _RESULT_CLASSES[names]
    return IntegrationResult


def method_settings(method: str, options: dict[str, Any]) -> dict[str, Any]:
    """Validated options of ``method``, defaults filled in, as its results record them:
    ``steps`` stays None where ``tol`` chooses the resolution (given ``tol`` and no
    ``steps``), so that the record gives the same numbers back.

    Raises
    ------
    ValueError
        An unknown option or a value its rule rejects (one line naming it).
    """
    out = registry.method(method).check_options(options)
    if "steps" in out and out.get("tol") is not None and options.get("steps") is None:
        out["steps"] = None     # "auto" always has a tol: its default chooses there too
    return out


def integrator_settings(**options: Any) -> dict[str, Any]:
    """:func:`method_settings` of the integration (``"numeric"``)."""
    return method_settings("numeric", options)


def composite_integrator_settings(tol: float, options: dict[str, Any]) -> dict[str, Any]:
    """:func:`integrator_settings` of a composite method's integrated points: those of its
    ``options`` the integrator has, and its ``tol`` [1, abs error of e]."""
    names = {opt.name for opt in registry.METHODS["numeric"].options}
    return integrator_settings(**{**{k: v for k, v in options.items() if k in names},
                                  "tol": tol})


def recorded_settings(attrs: Any, method: str) -> dict[str, Any]:
    """The settings a sweep dataset's ``method`` was computed with, from its global
    attributes as ``sweep run`` writes them (``integrator_<option>`` for the integration,
    ``options_<method>_<option>`` for another method; "default" or absent: the default),
    resolved by :func:`method_settings`."""
    m = registry.method(method)
    opts = {}
    for opt in m.options:
        value = attrs.get(m.attr_prefix + opt.name)
        if value is not None and not isinstance(value, str):
            opts[opt.name] = opt.from_attr(value)
    return method_settings(method, opts)


def _check_parallel(parallel: Any) -> None:
    if parallel is not None and not isinstance(parallel, (bool, np.bool_)):
        # Any truthy object ('no' included) would mean True.
        raise ValueError(f"parallel must be None, True or False, got {parallel!r}")


def check_integrate_options(options: Mapping[str, Any]) -> None:
    """Refuse a value of an option of :func:`integrate` that its rule rejects (one line
    naming it), before any point is integrated: for callers that may integrate none.

    Raises
    ------
    ValueError
        As :func:`integrate` would.
    """
    _check_parallel(options.get("parallel"))
    integrator_settings(**{k: v for k, v in options.items() if k != "parallel"})


def integrate(alpha: Any, beta: Any, gamma: Any, gtilde: Any, *, tol: float | None = None,
              steps: float | None = None, rest_tol: float = DEFAULT_REST_TOL,
              max_steps: int | None = None, refine: bool = True,
              parallel: bool | None = None, device: str = "cpu") -> IntegrationResult:
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
    tol : float, optional
        The largest abs error of e wanted (e.g. 1e-6, 1e-8, 1e-10): the resolution comes from
        the integrator's calibrated error model (:func:`sweep.kernels.stepsize.resolution`;
        a point predicted to dissipate little energy is marched first at a share of it,
        one predicted to stick at the floor of 16 steps, then at its share where that
        did not settle it,
        :func:`sweep.kernels.stepsize.tol_share`) and points whose error estimate ``e_err``
        exceeds ``tol`` are checked and refined (``refine``). ``tol`` bounds e; ``t_f`` and
        ``u_max`` follow the march (relative errors up to ~1e-7 at ``tol=1e-8``,
        docs/accuracy.md section 5; after a creep's jump along its slow branch, g~ = 0
        and kappa < 0, ``t_f`` is short by up to 2e-5 whatever the resolution). Without
        it: ``steps`` and a refinement target of 1e-9
        (:data:`sweep.kernels.integrator.REFINE_TARGET`).
    steps : float, optional
        Resolution for experts: steps per half period of the stiffest linearised motion
        (default :data:`DEFAULT_STEPS`, or from ``tol``); the error falls like
        ``steps**-5``. A given ``steps`` is every point's resolution, with ``tol`` too; at
        least :data:`sweep.registry.MIN_STEPS` (8), from where ``e_err`` is calibrated.
    rest_tol : float, default 1e-8
        Rest criterion ``max(|u - u-bar|, |v|) < rest_tol`` (report, Sec. 3).
    max_steps : int, optional
        Step budget per point, every march included (default :data:`DEFAULT_MAX_STEPS`).
    refine : bool, default True
        Check a point whose error indicator exceeds the refinement target
        (:data:`sweep.kernels.integrator.REFINE_TARGET`, or ``tol``) against a march 1.3 to
        2 times finer and march it again, finer, until its Richardson error is below the
        target (near the stick/rebound boundary, where errors are amplified by 1/e). False:
        exactly one fixed-step march per point (e.g. to measure the method's order).
    parallel : bool, optional
        Spread the points over threads (True) or not (False); by default on the main
        thread only (:mod:`sweep.kernels._parallel`). Results are bit-identical.
    device : {"cpu", "cuda"}, default "cpu"
        ``"cuda"``: the same per-point solve on one CUDA GPU (the optional numba-cuda,
        ``pip install 'sweep[cuda]'``), chunked with transfers overlapped; agrees with the
        CPU to a few ulp, not bit for bit (:mod:`sweep.kernels.cuda`). Without a usable GPU
        it raises ``RuntimeError`` saying why.

    Returns
    -------
    IntegrationResult
    """
    _check_parallel(parallel)
    opts = integrator_settings(tol=tol, steps=steps, rest_tol=rest_tol, max_steps=max_steps,
                               refine=refine, device=device)
    device = opts.pop("device")
    b = broadcast_points(alpha, beta, gamma, gtilde)
    out = integrate_on(*b.flat, settings(**opts), parallel=parallel, device=device)
    for f in registry.FIELDS.values():
        if f.derived is not None:
            out[f.name] = f.derived(out)
    res = {name: b.restore(out[name]) for name in registry.FIELDS}
    if b.scalar:
        res["status"] = Status(res["status"])
        res["n_steps"] = int(res["n_steps"])
    return _result_type()(**res)


#: Why I(g~), Q(g~) of Prop. 2 have no value at a valid point (:func:`coefficients`).
_IQ_RANGE = "is out of the range of I, Q (theta of (43) underflows or I overflows)"
#: Methods whose e needs I, Q (and how they are computed): past that range they give none.
_IQ_METHODS = {"ord2_numint": "numint", "ord2_approx": "approx"}


def _undefined_raise(m: registry.Method, b: Broadcast, checked: dict[str, Any]) -> None:
    """Raise ``ValueError`` for a scalar call the method gives no value at, naming the
    cause: exponents outside its models, g~ beyond the range of I, Q, or the point."""
    alpha, beta, gamma, gtilde = (float(x[0]) for x in b.flat)
    if not m.defined_at(alpha, beta):
        raise ValueError(f"method {m.name!r} is not defined at alpha={alpha!r}, "
                         f"beta={beta!r} (see sweep.registry.METHODS)")
    if m.name in _IQ_METHODS:
        n = (checked["n"],) if "n" in checked else ()   # ord2_approx's order, if it has one
        *_, status = _approx.coefficient_arrays(_IQ_METHODS[m.name], *b.flat[:2], b.flat[3],
                                                *n)
        if status[0] != Status.OK:
            raise ValueError(f"method {m.name!r}: gtilde={gtilde!r} {_IQ_RANGE} at "
                             f"alpha={alpha!r}")
    raise ValueError(f"method {m.name!r} gives no finite value at gamma={gamma!r}, "
                     f"gtilde={gtilde!r} (alpha={alpha!r}, beta={beta!r}): its formula "
                     "leaves double precision there")


def cor_fields(alpha: Any, beta: Any, gamma: Any, gtilde: Any, method: str = "numeric",
               **options: Any) -> dict[str, Any]:
    """Every per-point output of a method: ``e``, ``status`` and its own fields.

    The integration gives the fields of :data:`sweep.registry.FIELDS`; another method
    gives ``e``, ``status`` and its :attr:`sweep.registry.Method.fields` (``"auto"``:
    ``method_used``). Arguments as for :func:`cor`.

    Returns
    -------
    dict of str -> ndarray (scalars for a scalar call)
    """
    m = registry.method(method)
    if m.integrates:
        # integrate's keywords: any other is named as the approximations name it, not by
        # Python's TypeError.
        m.refuse_unknown(options, extra=("parallel",))
        r = integrate(alpha, beta, gamma, gtilde, **options)
        return {f.name: getattr(r, f.name) for f in dataclasses.fields(r)}
    checked, given = given_options(method, options)
    b = broadcast_points(alpha, beta, gamma, gtilde)
    e, status, fields, missed = method_arrays(method, *b.flat, given)
    if b.scalar and status[0] == Status.INVALID:
        _undefined_raise(m, b, checked)
    _warn_missed(m, missed, checked.get("tol"))
    st = b.restore(status)
    out = {"e": b.restore(e), "status": Status(st) if b.scalar else st}
    out.update({name: b.restore(value) for name, value in fields.items()})
    return out


def given_options(method: str, options: dict[str, Any]) -> tuple[dict, dict]:
    """``(checked, given)``: every option of ``method`` checked, defaults filled in, and
    those given, which alone its kernel takes: it knows its defaults, and a composite
    method (auto) must tell a given resolution from the default one.

    Raises
    ------
    ValueError
        An unknown option or a value its rule rejects (one line naming it).
    """
    checked = registry.method(method).check_options(options)
    # An option given as None is not given (check_options put the default there, which
    # "auto" took for a chosen resolution: steps=None gave other numbers than no steps).
    return checked, {k: checked[k] for k, v in options.items() if v is not None}


def method_arrays(method: str, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray,
                  gtilde: np.ndarray, options: dict[str, Any]) -> tuple:
    """A method other than the integration on flat float64 arrays: ``(e, status, fields,
    missed)``, ``fields`` its own per-point outputs and ``missed`` the points whose e may
    miss the method's ``tol`` (:data:`sweep.registry.MISSED`), of which it does not warn:
    :func:`cor_fields` warns, a sweep counts them. ``options``: those given, checked by
    :meth:`sweep.registry.Method.check_options`. NaN / INVALID where the method is not
    defined."""
    m = registry.method(method)
    e, status, *extra = m.resolve()(alpha, beta, gamma, gtilde, **options)
    fields = dict(extra[0]) if extra else {}
    missed = fields.pop(registry.MISSED, np.zeros(np.shape(e), dtype=bool))
    undefined = ~m.defined_at(alpha, beta)
    if undefined.any():
        e = np.where(undefined, np.nan, e)
        status = np.where(undefined, np.int8(Status.INVALID), status).astype(np.int8)
    return e, status, fields, missed


def _warn_missed(m: registry.Method, missed: np.ndarray, tol: float | None) -> None:
    n = int(np.count_nonzero(missed))
    if n:
        warnings.warn(f"{n} point(s) integrated by {m.name} may miss tol={tol:g}: their "
                      "error estimate e_err is above it; integrate gives e_err per point",
                      RuntimeWarning, stacklevel=4)


def cor_with_status(alpha: Any, beta: Any, gamma: Any, gtilde: Any, method: str = "numeric",
                    **options: Any) -> tuple[Any, Any]:
    """Like :func:`cor`, also returning the per-point :class:`~sweep.registry.Status` codes."""
    out = cor_fields(alpha, beta, gamma, gtilde, method, **options)
    return out["e"], out["status"]


def cor(alpha: Any, beta: Any, gamma: Any, gtilde: Any, method: str = "numeric",
        **options: Any) -> Any:
    """Coefficient of restitution ``e`` [1] by the numerical march or an approximation.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : array_like
        Scaled parameters (see :func:`integrate`), broadcast together.
    method : str
        A name of :data:`sweep.registry.METHODS`: ``"numeric"`` (:func:`integrate`), or one
        of the report's approximations: ``"ord1"`` (22), ``"sp"`` (25), (30),
        ``"large_gtilde"`` (23), ``"ord2_numint"`` and ``"ord2_approx"`` (Prop. 2 with I, Q by
        quadrature or by the Chebyshev-Beta approximation, option ``n``), or ``"auto"``
        (per point, the cheapest of them whose validated error bound is within ``tol``;
        :mod:`sweep.auto`).
    **options
        The method's options (:attr:`sweep.registry.Method.options`): those of
        :func:`integrate` for ``"numeric"`` (``tol``, ``steps``, ``rest_tol``, ``max_steps``,
        ``refine``, ``device``, and ``parallel``); ``n`` for ``"ord2_approx"``; ``tol`` and
        the integrator's options for ``"auto"``. Any other is a ``ValueError`` naming it.

    Returns
    -------
    ndarray of float64 (float for a scalar call)

    Warns
    -----
    RuntimeWarning
        Where a march ran out of its step budget (``Status.BUDGET_EXHAUSTED``): e there is
        only an upper bound, and this function returns no status to say so
        (:func:`cor_with_status` and :func:`integrate` do, without the warning).
    RuntimeWarning
        With ``method="numeric"`` and ``tol``, where a point's error estimate ``e_err`` is
        above ``tol``: near grazing the stick/rebound boundary, or for any point below the
        rounding floor of e (about 1e-13), the engine cannot vouch for ``tol``, and this
        function returns no ``e_err`` to say so (:func:`integrate` does, without the
        warning).
    """
    out = cor_fields(alpha, beta, gamma, gtilde, method, **options)
    m = registry.method(method)
    if m.integrates or m.composite:     # a closed form never runs out of budget: no scan
        _warn_budget(out["status"])
    if m.integrates and options.get("tol") is not None:
        _warn_tol(out["e_err"], out["status"], options["tol"])
    return out["e"]


def _warn_budget(status: Any) -> None:
    n = int(np.count_nonzero(np.asarray(status) == Status.BUDGET_EXHAUSTED))
    if n:
        warnings.warn(f"{n} point(s) ran out of the step budget (status BUDGET_EXHAUSTED): "
                      "their e is an upper bound, not a value; cor_with_status or integrate "
                      "give the statuses and e_err, max_steps a larger budget",
                      RuntimeWarning, stacklevel=3)


def _warn_tol(e_err: Any, status: Any, tol: float) -> None:
    above = registry.misses_tol(e_err, status, tol)
    n = int(np.count_nonzero(above))
    if n:
        worst = float(np.max(np.asarray(e_err)[above]))
        warnings.warn(f"{n} point(s) may miss tol={tol:g}: their error estimate e_err is above "
                      f"it (up to {worst:.2g}; near grazing, or below the rounding floor of e, "
                      "about 1e-13); integrate gives e_err per point",
                      RuntimeWarning, stacklevel=3)


# --------------------------------------------------------------------------- coefficients

def _pair(which: str, names: tuple[str, ...], values: tuple[Any, ...],
          n: int = 21) -> tuple[Any, Any]:
    """Broadcast, validate a scalar call, evaluate a pair of coefficients."""
    b = Broadcast(names, values)
    b.raise_if_invalid()
    alpha, beta = b.flat[0], b.flat[1]
    gtilde = b.flat[2] if len(b.flat) > 2 else np.zeros_like(alpha)
    x1, x2, status = _approx.coefficient_arrays(which, alpha, beta, gtilde, n)
    if b.scalar and status[0] != Status.OK:
        raise ValueError(f"gtilde={float(gtilde[0])!r} {_IQ_RANGE} at "
                         f"alpha={float(alpha[0])!r}")
    return b.restore(x1), b.restore(x2)


def coefficients(alpha: Any, beta: Any, gtilde: Any, method: str = "numint",
                 n: int = 21) -> tuple[Any, Any]:
    """The g~-dependent coefficients ``I(g~)``, ``Q(g~)`` of Prop. 2 [1].

    ::

        I = 2 int_0^{u_M} [1 + 2(g~ u - u^(a+1)/(a+1))]^(+1/2) u^(b-1) du
        Q =   int_0^{u_M} [1 + 2(g~ u - u^(a+1)/(a+1))]^(-1/2) u^(b-1) du

    (Prop. 2's I, twice the one of Sec. 4.1.)

    Parameters
    ----------
    alpha, beta, gtilde : array_like
        Exponents [1] (>= 1) and scaled load [1] (>= 0), broadcast together.
    method : {"numint", "approx"}
        Gauss quadrature (relative error ~1e-14) or the report's Chebyshev-Beta
        approximation (47)-(53) of odd order ``n`` (~1e-3).
    n : int, default 21

    Returns
    -------
    I, Q : ndarray or float
        NaN at invalid points of an array call, and at valid g~ beyond the range of I, Q
        (theta of (43) underflows, g~ ~ 1e300); a scalar call at such a point raises
        ``ValueError`` naming the value or the cause.
    """
    if method not in ("numint", "approx"):
        raise ValueError(f"method must be one of ('numint', 'approx'), got {method!r}")
    n = registry.METHODS["ord2_approx"].check_options({"n": n})["n"]
    return _pair(method, ("alpha", "beta", "gtilde"), (alpha, beta, gtilde), n)


def coefficients_at_zero(alpha: Any, beta: Any) -> tuple[Any, Any]:
    """Exact ``I(0)``, ``Q(0)`` [1] of (39), (40) (KK: 1.1534489, 1.2687937)."""
    return _pair("zero", ("alpha", "beta"), (alpha, beta))


def first_order_coefficients(alpha: Any, beta: Any) -> tuple[Any, Any]:
    """``C0``, ``C1`` [1] of the first-order approximation (22) (KK: 1.7301733, 3).

    ``C0 = b ((a+1)/2)^((b-a-1)/(a+1)) B(b/(a+1), 3/2)`` and
    ``C1 = b ((a+1)/2)^((b-a)/(a+1)) B((b+1)/(a+1), 1/2)``; broadcast over alpha, beta.
    """
    return _pair("first", ("alpha", "beta"), (alpha, beta))


def large_gtilde_coefficient(alpha: Any, beta: Any) -> tuple[Any, Any]:
    """``C`` and the exponent ``r`` [1] of the large-g~ approximation (23), (24).

    ``e^2 = 1 - 2 gamma C g~^r`` with ``r = b/a + 1/(2a) + 1/2`` and
    ``C = 2 sqrt(2) (b/a) (a+1)^(b/a + 1/(2a)) B((b + 1/2)/a, 3/2)`` (KK: 4.403986, 11/6).
    """
    return _pair("large", ("alpha", "beta"), (alpha, beta))
