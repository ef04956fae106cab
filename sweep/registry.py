"""The facts every floor reads: domains, status codes, contact laws, methods and output fields.

This is the ground floor of the package. Each fact lives here once; the kernels, the api,
the configuration parser, the store and the reports read it from here:

* :class:`Status` -- why the computation of a point ended (integer codes stored in files);
* :data:`PARAMETERS` -- the four scaled numbers of the report's eq. (2) and their domain
  (Assumption 1 of the report and physical signs), with :func:`valid_points`,
  :func:`check_scalar` and :func:`check_array` to apply it;
* :data:`PHYSICAL` -- the physical inputs of the scaling (2) and their domain;
* :data:`MATERIAL` -- the properties a scene may derive them from (Hertz stiffness, mass,
  damping models: :mod:`sweep.materials`) and their domain; :data:`MATERIAL_NAME`, the
  variable of a scene dataset that names its materials;
* :data:`MODELS` -- the report's named contact laws (alpha, beta);
* :data:`METHODS` -- every way of computing the CoR: name, kernel, options, long name,
  equation, domain (:func:`register_method` adds one);
* :data:`FIELDS` -- the per-point outputs of the integrator and the fields derived from them:
  name, dtype, units, long_name, description, fill value (:func:`register_field`);
* :data:`SERVED_BY` -- the flag codes of the ``method_used`` field of the ``"auto"`` method
  (which method served each point).

Adding a method is one :class:`Method` entry here plus its kernel; adding an output field is
one :class:`Field` entry plus the kernel code that fills it (see the README's contributor
section).

Owns: the facts above. May import: nothing from ``sweep`` (numpy only).
"""
from __future__ import annotations

import dataclasses
import enum
import importlib
import math
import sys
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

__all__ = ["Status", "Parameter", "PARAMETERS", "PARAMETER_NAMES", "PHYSICAL", "MATERIAL",
           "MATERIAL_NAME", "MODELS", "Option", "Method", "METHODS", "Field", "FIELDS",
           "SERVED_BY", "valid_points", "check_scalar", "check_array", "real_array",
           "short_repr", "register_method",
           "unregister_method", "register_field", "unregister_field", "method",
           "approximations", "composites", "method_fields", "integrator_fields",
           "kernel_fields", "variable_names", "REPORT", "CHEBYSHEV_N_MAX", "DEVICES",
           "MAX_STEP_BUDGET", "MIN_STEPS", "misses_tol", "MISSED", "COMPRESSION",
           "DEFAULT_COMPRESSION", "is_number"]

#: The report every equation number refers to.
REPORT = ("A. Chatterjee, G. James, B. Brogliato, Approximate analytical coefficient of "
          "restitution formulation for single bead impact with external load, using "
          "nonlinear visco-elastic models, INRIA hal-03462750 (2021)")


class Status(enum.IntEnum):
    """Why the computation of one point ended.

    The integer values are stored in datasets (``status`` variable); never renumber them.
    """

    #: The bead detached (u = 0 with v < 0): ``e = -v`` at detachment. From a closed form
    #: (or ``auto`` serving a point with one): a valid point, its e clipped to [0, 1].
    OK = 0
    #: The bead does not rebound (v = 0 with 0 < u <= u-bar in phase 3, or its energy fell
    #: below the floor level, from which it can never return to u = 0): ``e = 0``. Where
    #: ``e_err > 0`` the march could not exclude a rebound up to ``e_err`` (near grazing).
    STUCK = 1
    #: Converged to rest, ``max(|u - u-bar|, |v|) < rest_tol`` (report, Sec. 3), or a creep
    #: that never leaves or leaves with e below ``e_err``: ``e = 0``.
    AT_REST = 2
    #: The step budget ran out before the outcome was decided. ``e = sqrt(2 H)``, the bound
    #: on the rebound speed set by the energy still available, not a converged value.
    BUDGET_EXHAUSTED = 3
    #: Invalid input (outside the domain of :data:`PARAMETERS`, or an approximation used
    #: outside its own): ``e = NaN``.
    INVALID = 4


#: Key of a method kernel's fields holding, per point, whether e may miss the ``tol`` the
#: method was asked for (``auto``'s integrated points whose e_err stayed above it): never
#: returned to a caller; :func:`sweep.api.cor_fields` warns of them, a sweep counts them
#: with the points above the integrator's tol.
MISSED = "missed_tol"


def misses_tol(e_err: Any, status: Any, tol: float) -> np.ndarray:
    """Elementwise: the point's error estimate ``e_err`` is above ``tol``, so the engine
    cannot vouch for it (near grazing, or below e's rounding floor, ~1e-13); a point out of
    its step budget is not counted here: its e is only a bound, a caveat of its own."""
    return (np.asarray(e_err) > tol) & (np.asarray(status) != Status.BUDGET_EXHAUSTED)


# --------------------------------------------------------------------------- domains

@dataclasses.dataclass(frozen=True)
class Parameter:
    """A real input and its domain: finite and ``>= minimum`` (``> minimum`` if strict).

    Attributes
    ----------
    name : str
        Keyword and dataset name.
    long_name, description : str
        CF attributes (the description cites the report's equation).
    minimum : float
        Lower bound of the domain.
    strict : bool
        The bound itself is excluded.
    rule : str
        The domain in words, for error messages ("must be ...").
    units : str
        CF units (a UDUNITS string); for a unit that depends on the contact law, its rule
        in words (``"N m^-alpha"``), which no file stores (see ``law_units``).
    maximum : float
        Upper bound of the domain (included; inf: none).
    law_units : tuple
        For a unit that depends on the contact law (k, gamma0): the unit without its
        length factor and the power of the metre per unit alpha and per unit beta, e.g.
        ``("N", -1, 0)`` for N m^-alpha; empty for a fixed unit. See :meth:`cf_units`.
    """

    name: str
    long_name: str
    description: str
    minimum: float
    strict: bool = False
    rule: str = ""
    units: str = "1"
    maximum: float = math.inf
    law_units: tuple = ()

    def ok(self, value: Any) -> Any:
        """Elementwise: inside the domain (finite and between the bounds); a bool for a
        Python float (a scalar call checks four: numpy's reductions took ~7 us each)."""
        if isinstance(value, float):
            x, finite = value, math.isfinite(value)
        else:
            x = np.asarray(value, dtype=np.float64)
            finite = np.isfinite(x)
        above = x > self.minimum if self.strict else x >= self.minimum
        return finite & above & (x <= self.maximum)

    def cf_units(self, alpha: float = 1.0, beta: float = 1.0) -> str | None:
        """The units as a UDUNITS string, under the contact law (alpha, beta).

        Parameters
        ----------
        alpha, beta : float
            Exponents of the law (1); they matter only for a law-dependent unit.

        Returns
        -------
        str or None
            :attr:`units` for a fixed unit; for a law-dependent one, e.g. ``"N m-1"`` for
            k at alpha = 1, or None where the power of the metre is not an integer.
            UDUNITS (hence CF) has integer powers only: it reads ``"N m-1.5"`` as the
            valid but different unit 0.5 N m-1, so no string can say N m^-1.5.
        """
        if not self.law_units:
            return self.units
        base, per_alpha, per_beta = self.law_units
        power = per_alpha * float(alpha) + per_beta * float(beta)
        if not power.is_integer():
            return None
        power = int(power)
        return base if power == 0 else f"{base} m" if power == 1 else f"{base} m{power}"


_UNIQUENESS = ">= 1 (uniqueness is not known below 1)"
# gamma's upper bound, which its rule (the error messages) also says.
_GAMMA_MAX = 1e300

#: The four scaled numbers of eq. (2), in dataset dimension order.
PARAMETERS: dict[str, Parameter] = {p.name: p for p in (
    Parameter("alpha", "stiffness exponent alpha",
              "exponent of the elastic contact force k (-x)_+^alpha, report eq. (1)",
              1.0, rule=_UNIQUENESS),
    Parameter("beta", "damping exponent beta",
              "exponent of the damping force k gamma0 d/dt (-x)_+^beta, report eq. (1)",
              1.0, rule=_UNIQUENESS),
    Parameter("gamma", "scaled damping gamma",
              "gamma = gamma0 v0^(2 beta/(alpha+1) - 1) (k/m)^(1 - beta/(alpha+1)), "
              "report eq. (2)", 0.0, rule=f">= 0 and <= {_GAMMA_MAX:g} (beyond, the "
              "damping rate gamma beta u^(beta-1) overflows)".replace("e+", "e"),
              maximum=_GAMMA_MAX),
    Parameter("gtilde", "scaled load g~",
              "g~ = (m/k)^(1/(alpha+1)) v0^(-2 alpha/(alpha+1)) (g + F/m), report eq. (2)",
              0.0, rule=">= 0 (a compressive load)"),
)}
PARAMETER_NAMES = tuple(PARAMETERS)

#: Physical inputs of the scaling (2). g and F may take either sign; g + F/m >= 0 is
#: checked by :func:`sweep.model.scale`.
PHYSICAL: dict[str, Parameter] = {p.name: p for p in (
    Parameter("m", "bead mass", "mass m of the bead, report eq. (1)", 0.0, True,
              "> 0 [kg]", "kg"),
    Parameter("k", "contact stiffness", "stiffness k of the contact law, report eq. (1)",
              0.0, True, "> 0 [N m^-alpha]", "N m^-alpha", law_units=("N", -1, 0)),
    Parameter("gamma0", "damping coefficient",
              "gamma0 of the damping force k gamma0 d/dt (-x)_+^beta, report eq. (1)",
              0.0, False, ">= 0 [s m^(alpha-beta)]", "s m^(alpha-beta)",
              law_units=("s", 1, -1)),
    Parameter("v0", "impact speed", "speed of the bead when it touches the floor", 0.0, True,
              "> 0 [m/s]", "m s-1"),
    Parameter("g", "gravitational acceleration", "acceleration of gravity", -math.inf, False,
              "finite [m/s^2]", "m s-2"),
    Parameter("F", "external load", "constant compressive force on the bead", -math.inf,
              False, "finite [N]", "N"),
)}

#: Material properties a scene may derive m, k and gamma0 from (:mod:`sweep.materials`;
#: formulas and references in docs/scenes.md). SI units throughout.
MATERIAL: dict[str, Parameter] = {p.name: p for p in (
    Parameter("radius", "bead radius", "radius R of the spherical bead", 0.0, True,
              "> 0 [m]", "m"),
    Parameter("density", "bead density", "mass density of the bead: m = 4/3 pi R^3 rho",
              0.0, True, "> 0 [kg/m^3]", "kg m-3"),
    Parameter("E", "Young's modulus", "Young's modulus of a body in contact (Hertz theory)",
              0.0, True, "> 0 [Pa]", "Pa"),
    Parameter("nu", "Poisson's ratio", "Poisson's ratio of a body in contact (Hertz theory)",
              -1.0, True, "in (-1, 0.5]", "1", 0.5),
    Parameter("e", "target coefficient of restitution",
              "coefficient of restitution the damping is tuned to reproduce", 0.0, True,
              "in (0, 1]", "1", 1.0),
    Parameter("eta1", "first viscous constant",
              "viscous constant eta1 of the bead material (Brilliantov et al. 1996)", 0.0,
              False, ">= 0 [Pa s]", "Pa s"),
    Parameter("eta2", "second viscous constant",
              "viscous constant eta2 of the bead material (Brilliantov et al. 1996)", 0.0,
              False, ">= 0 [Pa s]", "Pa s"),
)}

#: Name of the variable that names a scene's materials in its dataset: a string auxiliary
#: coordinate on the ``material`` dimension, which an integer 0..n-1 indexes (a CF
#: coordinate variable is numeric). Every reader of scene datasets takes the names from it.
MATERIAL_NAME = "material_name"

#: The report's named contact laws: name -> (alpha, beta) (report Table 1).
MODELS: dict[str, tuple[float, float]] = {
    "linear": (1.0, 1.0),
    "hertz": (1.5, 1.0),
    "tti": (1.5, 1.25),
    "kk": (1.5, 1.5),
    "shc": (1.5, 2.5),
}


def valid_points(alpha: Any, beta: Any, gamma: Any, gtilde: Any) -> np.ndarray:
    """Elementwise: the point ``(alpha, beta, gamma, g~)`` is inside :data:`PARAMETERS`."""
    values = dict(zip(PARAMETER_NAMES, (alpha, beta, gamma, gtilde)))
    masks = [PARAMETERS[n].ok(v) for n, v in values.items()]
    return np.logical_and.reduce(np.broadcast_arrays(*masks))


def _first_bad(value: np.ndarray, good: np.ndarray) -> float:
    bad = ~np.broadcast_to(good, value.shape)
    return value.reshape(-1)[np.flatnonzero(bad)[0]]


def _message(name: str, parameter: Parameter, value: np.ndarray) -> str | None:
    finite = np.isfinite(value)
    if not finite.all():
        return f"{name} must be finite, got {float(_first_bad(value, finite))!r}"
    good = parameter.ok(value)
    if not np.all(good):
        return f"{name} must be {parameter.rule}, got {float(_first_bad(value, good))!r}"
    return None


def short_repr(value: Any, width: int = 60) -> str:
    """``repr(value)`` on one line of at most ``width`` characters, for error messages
    (a long array, a multi-line repr)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= width else text[:width - 3] + "..."


def real_array(name: str, value: Any) -> np.ndarray:
    """``value`` as float64, if it holds real numbers: Python or numpy ints and floats.

    Strings, bytes, booleans, complex numbers, None, object arrays and masked arrays with
    masked values are refused rather than converted: numpy would parse ``"0.1"``, take
    ``True`` as 1, ``None`` as NaN and a masked value as the data under the mask, answering
    for an input the caller did not mean.

    Parameters
    ----------
    name : str
        The parameter, for the message.
    value : array_like

    Returns
    -------
    ndarray of float64

    Raises
    ------
    ValueError
        One line naming the parameter and the value (and its type).
    """
    if np.ma.isMaskedArray(value) and np.ma.count_masked(value):
        # np.asarray drops the mask and hands on the values it hides.
        raise ValueError(f"{name} has {np.ma.count_masked(value)} masked value(s), whose "
                         "hidden data would be used: fill them first (np.ma.filled)")
    try:
        arr = np.asarray(value)       # the caller's own type, judged before any conversion
    except (TypeError, ValueError):   # ragged nested sequences
        arr = np.empty(0, dtype=object)
    if arr.dtype.kind not in "iuf":
        what = (f"dtype {value.dtype}" if isinstance(value, np.ndarray)
                else type(value).__name__)
        raise ValueError(f"{name} must be a real number (int or float) or an array of them, "
                         f"got {short_repr(value)} ({what})")
    return arr.astype(np.float64, copy=False)


def check_array(name: str, value: Any, domain: Mapping[str, Parameter] | None = None) -> np.ndarray:
    """Every element of ``value`` must lie in the domain of parameter ``name``.

    Parameters
    ----------
    name : str
        A key of ``domain`` (default :data:`PARAMETERS`, then :data:`PHYSICAL`).
    value : array_like

    Returns
    -------
    ndarray of float64

    Raises
    ------
    ValueError
        One line naming the parameter and the first offending value.
    """
    parameter = _domain_of(name, domain)
    arr = real_array(name, value)
    message = _message(name, parameter, arr)
    if message:
        raise ValueError(message)
    return arr


def _domain_of(name: str, domain: Mapping[str, Parameter] | None = None) -> Parameter:
    """The parameter ``name`` of ``domain`` (default :data:`PARAMETERS`, then
    :data:`PHYSICAL`)."""
    return (domain or {**PARAMETERS, **PHYSICAL})[name]


def check_scalar(name: str, value: float) -> None:
    """Raise ``ValueError`` naming ``value`` if it lies outside the domain of ``name`` (the
    message of :func:`check_array`)."""
    parameter = _domain_of(name)
    if not parameter.ok(float(value)):
        raise ValueError(_message(name, parameter, np.float64(value)))


# --------------------------------------------------------------------------- methods

@dataclasses.dataclass(frozen=True)
class Option:
    """A keyword option of a method: its default and its rule.

    ``check(value) -> bool`` must accept the default; a value of None means the default.
    ``plain(value)``: the accepted value as the plain Python type the kernels take, so that
    its numpy type cannot change a result (a float32 ``tol`` computed its resolution and
    target in float32: other bits than the same value as a float).
    """

    name: str
    default: Any
    check: Callable[[Any], bool]
    rule: str
    plain: Callable[[Any], Any] = float

    def to_attr(self, value: Any) -> Any:
        """The value as a netCDF attribute, in the type of the default (TOML's
        ``steps = 16`` is the real 16.0); booleans as 0 / 1 (netCDF has no boolean or
        null: an unset option is the string "default")."""
        if value is None:
            return "default"
        if isinstance(self.default, bool):
            return int(bool(value))
        return type(self.default)(value) if self.default is not None else value

    def from_attr(self, value: Any) -> Any:
        """Inverse of :meth:`to_attr`."""
        value = value.item() if hasattr(value, "item") else value
        if isinstance(value, str) and value == "default":
            return None
        return bool(value) if isinstance(self.default, bool) else value


def _is_int(v: Any) -> bool:
    # TOML and JSON booleans are Python bools, which are ints: never accept them as numbers.
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def is_number(v: Any) -> bool:
    """Whether ``v`` is a finite real number: a Python or numpy int or float, not a bool.
    An int beyond double precision (10**400) is not: ``math.isfinite`` raised OverflowError
    on it, naming no key (configurations and options alike)."""
    if _is_int(v):
        return abs(int(v)) <= sys.float_info.max
    return isinstance(v, (float, np.floating)) and math.isfinite(v)


@dataclasses.dataclass(frozen=True)
class Method:
    """One way of computing the CoR.

    Attributes
    ----------
    name : str
        ``method=`` value; stored as ``e_<name>`` (and ``error_<name>`` for approximations).
    long_name, description : str
        CF attributes; the description gives the formula and the report's equation.
    equation : str
        The report's equation numbers.
    kernel : str or callable
        ``"module:function"`` (resolved on first use, so this floor imports no kernel) or a
        callable ``kernel(alpha, beta, gamma, gtilde, **options) -> (e, status)`` on flat
        float64 arrays of equal length; a method with :attr:`fields` returns
        ``(e, status, {field name: flat array})``.
    options : tuple of Option
        Keyword options the kernel accepts.
    models : tuple of (alpha, beta), optional
        The only exponents where the method is defined (None: everywhere in the domain).
    integrates : bool
        The method is the numerical integration (its fields are :func:`integrator_fields`).
    fields : tuple of Field
        Per-point outputs of the kernel besides e and status (e.g. ``method_used``); a sweep
        may store them when it stores the method.
    composite : bool
        The method serves each point with another registered method (``"auto"``): it is
        neither the integration nor a closed form (:func:`approximations` leaves it out, and
        so does ``outputs.e = "all"``).
    """

    name: str
    long_name: str
    description: str
    equation: str
    kernel: str | Callable[..., tuple[np.ndarray, np.ndarray]]
    options: tuple[Option, ...] = ()
    models: tuple[tuple[float, float], ...] | None = None
    integrates: bool = False
    fields: tuple[Field, ...] = ()
    composite: bool = False

    @property
    def attr_prefix(self) -> str:
        """Prefix of the method's settings among a sweep file's global attributes
        (``integrator_steps``, ``options_ord2_approx_n``)."""
        return "integrator_" if self.integrates else f"options_{self.name}_"

    @property
    def error_long_name(self) -> str:
        """``long_name`` of the method's error field ``e_<name> - reference``: "error of
        the second order with approximated I, Q" (its own long_name after the quantity)."""
        quantity, _, which = self.long_name.partition(", ")
        return f"error of the {which or quantity}"

    def resolve(self) -> Callable[..., tuple[np.ndarray, np.ndarray]]:
        """The kernel as a callable (imports its module on first use)."""
        if callable(self.kernel):
            return self.kernel
        module, _, attr = self.kernel.partition(":")
        return getattr(importlib.import_module(module), attr)

    def option(self, name: str) -> Option:
        for opt in self.options:
            if opt.name == name:
                return opt
        raise KeyError(name)

    def refuse_unknown(self, keys: Any, extra: tuple[str, ...] = ()) -> None:
        """Raise ``ValueError`` (one line naming it and the allowed ones) for the first of
        ``keys`` that is neither an option nor one of the caller's own ``extra`` keywords
        (e.g. ``parallel``)."""
        allowed = [opt.name for opt in self.options] + list(extra)
        for key in keys:
            if key not in allowed:
                raise ValueError(f"unknown option {key!r} for method {self.name!r}; "
                                 f"allowed: {', '.join(allowed) or 'none'}")

    def check_options(self, options: Mapping[str, Any]) -> dict[str, Any]:
        """Validate keyword options; returns them with defaults filled in.

        Raises
        ------
        ValueError
            Unknown option, or a value its rule rejects (one line naming it).
        """
        self.refuse_unknown(options)
        known = {opt.name: opt for opt in self.options}
        out = {}
        for key, opt in known.items():
            value = options.get(key)
            if value is None:
                value = opt.default
            if value is not None and not opt.check(value):
                raise ValueError(f"{key} must be {opt.rule}, got {value!r}")
            out[key] = value if value is None else opt.plain(value)
        return out

    def defined_at(self, alpha: Any, beta: Any) -> np.ndarray:
        """Elementwise: the method is defined at these exponents."""
        if self.models is None:
            return np.ones(np.broadcast(alpha, beta).shape, dtype=bool)
        a, b = np.asarray(alpha), np.asarray(beta)
        return np.logical_or.reduce([(a == ma) & (b == mb) for ma, mb in self.models])


#: Where the numerical integration can run (the ``device`` option).
DEVICES = ("cpu", "cuda")

#: How an output file's computed variables are stored (``run.compress``): for each choice,
#: the least fraction of a variable's bytes that deflate (zlib level 1, with HDF5's shuffle
#: filter where that is smaller) must save on a trial of its first chunk for the variable
#: to be deflated; None stores every variable as computed. Deflate costs the one writer
#: thread about 90 ms of CPU a million float64 values that it halves, and about a tenth of
#: that where it saves more than 60%. "fast" deflates only the latter: flags, counts and
#: smooth coordinates. "small" also deflates the e and error fields that the sticking
#: beads' exact zeros halve, for a third smaller file at three times the writer's CPU
#: (the README's figures, `python benchmarks/writer.py --compress ...`).
COMPRESSION = {"fast": 0.6, "small": 0.35, "none": None}
#: The choice of a configuration that names none.
DEFAULT_COMPRESSION = "fast"

#: Least resolution ``steps`` (per half period): the error model never picks less, and the
#: error estimate ``e_err`` is calibrated from there up (below it, 2-7 steps, it was up to
#: 39 times too small: nearly elastic points with alpha ~ 1, large beta, 2026-12-07).
MIN_STEPS = 8

# n_steps (FIELDS, int32) exceeds max_steps by a few event-refinement steps at most: the
# bound keeps it exact, far from 2**31.
_BUDGET_POWER = 30
#: Largest step budget per point (``max_steps``), and so the largest resolution ``steps``:
#: a marched point takes on the order of ``steps`` steps (0.2 to a few times it on random
#: draws; a few points are decided without a march), so a resolution beyond every budget
#: can give no answer, only BUDGET_EXHAUSTED with e = sqrt(2 H).
MAX_STEP_BUDGET = 2 ** _BUDGET_POWER

_INTEGRATOR_OPTIONS = (
    Option("tol", None, lambda v: is_number(v) and v > 0,
           "a number > 0 (the largest abs error of e wanted: the resolution comes from the "
           "integrator's calibrated error model, and points above it are refined)"),
    Option("steps", 96.0, lambda v: is_number(v) and MIN_STEPS <= v <= MAX_STEP_BUDGET,
           f"a number in [{MIN_STEPS}, 2**{_BUDGET_POWER}] (steps per half period of the "
           "stiffest linearised motion; a march takes about as many, and no step budget is "
           f"larger; e_err is calibrated from {MIN_STEPS} up)"),
    # A scaled state is in units of the impact (u'(0) = 1): from rest_tol = 1 on, every
    # loaded point is "at rest" before it moves, a silent e = 0.
    Option("rest_tol", 1e-8, lambda v: is_number(v) and 0 < v < 1,
           "a number in (0, 1) (rest criterion of the report, Sec. 3, in units of the "
           "impact speed: max(|u - u-bar|, |v|) < rest_tol ends a point at rest, e = 0)"),
    Option("max_steps", 200_000, lambda v: is_number(v) and 1 <= v <= MAX_STEP_BUDGET
           and float(v).is_integer(),
           f"an integer in [1, 2**{_BUDGET_POWER}] (step budget per point, every march "
           "included)", int),
    Option("refine", True, lambda v: isinstance(v, (bool, np.bool_)),
           "true or false (check points whose error indicator is above the target against "
           "a companion march and march them again, finer; false: one fixed-step march)",
           bool),
    Option("device", "cpu", lambda v: isinstance(v, str) and v in DEVICES,
           "\"cpu\" or \"cuda\" (where the integration runs: every CPU core, or one CUDA "
           "GPU through the optional numba-cuda, pip install 'sweep[cuda]')", str),
)
#: Largest order n of the Chebyshev-Beta approximation (49) that the kernels evaluate (their
#: quadrature table, sweep.kernels.special, is built for it).
CHEBYSHEV_N_MAX = 621
_CHEBYSHEV_N = Option("n", 21,
                      lambda v: _is_int(v) and 1 <= v <= CHEBYSHEV_N_MAX and v % 2 == 1,
                      f"an odd integer in [1, {CHEBYSHEV_N_MAX}] (number of Chebyshev nodes, "
                      "eq. (49))", int)
_ORD2 = ("e = min(sqrt(max(e^2, 0)), e_s), report Prop. 2, eqs. (36)-(38); NaN where g~ is "
         "out of the range of I, Q at the point's alpha (theta of (43) underflows or I "
         "overflows); with I(g~) and Q(g~) ")

#: Every method ``sweep.cor`` accepts, in a stable order (datasets store them in it).
METHODS: dict[str, Method] = {m.name: m for m in (
    Method("numeric", "coefficient of restitution, numerical integration",
           "e = -v(T_f) (report eq. (3)) from the fixed-step Runge-Kutta integration of the "
           "(u, w) system, eq. (4), through the three phases of Algorithm 1; 0 if the bead "
           "sticks or comes to rest", "(3), (4), Algorithm 1",
           "sweep.kernels.devices:numeric_cor", _INTEGRATOR_OPTIONS, integrates=True),
    Method("ord1", "coefficient of restitution, first-order approximation",
           "e = max(1 - gamma C0 - gamma g~ C1, 0), report eq. (22)", "(22)",
           "sweep.kernels.approx:ord1"),
    Method("sp", "coefficient of restitution, Schwager-Poeschel second order",
           "e = 1 - gamma C0 - gamma g~ C1 - gamma^2 C2, report eqs. (25) and (30); defined "
           "for alpha = beta = 3/2 only (NaN elsewhere)", "(25), (30)",
           "sweep.kernels.approx:sp", models=((1.5, 1.5),)),
    Method("large_gtilde", "coefficient of restitution, large-load approximation",
           "e = sqrt(max(1 - 2 gamma C g~^r, 0)), report eq. (23)", "(23)",
           "sweep.kernels.approx:large_gtilde"),
    Method("ord2_numint", "coefficient of restitution, second order with quadrature I, Q",
           _ORD2 + "by quadrature", "(36)-(38)", "sweep.kernels.approx:ord2_numint"),
    Method("ord2_approx", "coefficient of restitution, second order with approximated I, Q",
           _ORD2 + "from the approximation of Sec. 4.4, eqs. (43)-(49)", "(36)-(38), (43)-(53)",
           "sweep.kernels.approx:ord2_approx", (_CHEBYSHEV_N,)),
)}


def method(name: str) -> Method:
    """The registered method ``name``.

    Raises
    ------
    ValueError
        Unknown method (one line listing the known ones).
    """
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise ValueError(f"method must be one of {tuple(METHODS)}, got {name!r}") from None


def approximations() -> tuple[str, ...]:
    """Names of the closed-form methods (neither the integration nor composite), in order."""
    return tuple(name for name, m in METHODS.items() if not (m.integrates or m.composite))


def composites() -> tuple[str, ...]:
    """Names of the composite methods (each point served by another method), in order."""
    return tuple(name for name, m in METHODS.items() if m.composite)


def method_fields() -> dict[str, tuple[str, Field]]:
    """Fields produced by a method's kernel: field name -> (method name, :class:`Field`)."""
    return {f.name: (name, f) for name, m in METHODS.items() for f in m.fields}


def register_method(m: Method) -> None:
    """Add a method; ``sweep.cor``, configurations and datasets accept it at once.

    Raises
    ------
    ValueError
        The name is registered, or a variable it stores (``e_<name>``, ``error_<name>``, its
        fields) is a name already in use (method "err" would store e_err, a field).
    """
    if m.name in METHODS:
        raise ValueError(f"method {m.name!r} is already registered")
    _refuse_taken("method", m.name, (f"e_{m.name}", f"error_{m.name}", *(f.name for f in m.fields)))
    METHODS[m.name] = m


def unregister_method(name: str) -> None:
    """Remove a method added by :func:`register_method`."""
    METHODS.pop(name)


# --------------------------------------------------------------------------- output fields

@dataclasses.dataclass(frozen=True)
class Field:
    """A per-point output: of the numerical integration (:data:`FIELDS`) or of another
    method's kernel (:attr:`Method.fields`).

    Attributes
    ----------
    name : str
        Attribute of ``sweep.IntegrationResult`` and dataset variable name.
    dtype : numpy dtype
    long_name, description, units : str
        CF attributes.
    fill_value : scalar or None
        Value marking an invalid point (None: every value is meaningful).
    derived : callable, optional
        ``derived(fields) -> array`` computes the field from the kernel's fields (a dict);
        None for fields the kernel fills itself.
    flags : mapping, optional
        For flag variables: meaning -> value (CF ``flag_values`` / ``flag_meanings``).
    """

    name: str
    dtype: np.dtype
    long_name: str
    description: str
    units: str = "1"
    fill_value: Any = None
    derived: Callable[[Mapping[str, np.ndarray]], np.ndarray] | None = None
    flags: Mapping[str, int] | None = None


def _sticks(fields: Mapping[str, np.ndarray]) -> np.ndarray:
    status = fields["status"]
    return (status == Status.STUCK) | (status == Status.AT_REST)


#: Per-point outputs of the integration, in storage order (``e`` is stored as e_numeric).
FIELDS: dict[str, Field] = {f.name: f for f in (
    Field("e", np.dtype(np.float64), METHODS["numeric"].long_name,
          METHODS["numeric"].description, fill_value=math.nan),
    Field("sticks", np.dtype(np.bool_), "bead does not rebound",
          "true where e = 0 is reported (status stuck or at_rest): the impact ends without "
          "rebound (Algorithm 1, phase 3: v = 0 with u > 0, or converged to rest), or a creep "
          "leaves with an e below its bound e_err (at_rest; e.g. (1.5, 1.5, 1000, 0) leaves "
          "with e ~ 7e-16); false if it rebounds, if the point is invalid, or if the step "
          "budget ran out before the outcome was decided (status)",
          derived=_sticks, flags={"rebounds": 0, "sticks": 1}),
    Field("t_f", np.dtype(np.float64), "impact duration T_f",
          "scaled time T_f at the end of the impact (report eq. (3)), in units of T of "
          "eq. (2) (a scene's dataset holds T as time_scale [s]: t_f time_scale is the "
          "contact's duration in seconds), where the bead rebounds (status ok). Where it "
          "does not (stuck, at_rest), the time at which the integration decided so (a "
          "trough, the energy spent, the rest box, or e below its error bound, which "
          "depends on tol), not a physical end; "
          "for a deep load well decided without a march, the undamped swing's duration; inf "
          "where the bead creeps for ever, where the impact lasts longer than double "
          "precision can count (kappa = 0 near critical damping with alpha ~ 100), or where "
          "a creep's slide along its slow branch was not followed (its landing point or "
          "duration beyond double precision, though it may leave at a finite time with an e "
          "below it); where the budget ran out, the time reached. Read off the march that "
          "gave e; near grazing under a load, the crossing at speed e about the march's "
          "vertex; after a creep's jump along its slow branch (g~ = 0, kappa < 0) short by "
          "up to 2e-5 relative (docs/accuracy.md, section 5)", fill_value=math.nan),
    Field("u_max", np.dtype(np.float64), "maximum compression u_M",
          "scaled maximum compression u(tau_0) where v = 0 (Algorithm 1, phase 1), in units "
          "of delta = v0 T of eq. (2) (a scene's dataset holds delta as length_scale [m]); "
          "NaN where the point was decided before it (a bead that sticks while still "
          "compressing: heavily damped or overdamped; a deep load well that sticks, unless "
          "the damping is too weak to move the undamped swing's value) or the step budget "
          "ran out before it",
          fill_value=math.nan),
    Field("n_steps", np.dtype(np.int32), "number of integration steps",
          "Runge-Kutta steps taken to integrate eq. (4) for this point"),
    Field("status", np.dtype(np.int8), "integration status",
          "why the numerical computation of the point ended (Algorithm 1): "
          + ", ".join(f"{s.value} = {s.name.lower()}" for s in Status),
          flags={s.name.lower(): s.value for s in Status}),
    Field("e_err", np.dtype(np.float64), "estimated error of the numerical CoR",
          "estimate of |e - e_true| for e_numeric (report eq. (3)): from the energy balance "
          "H = 1/2 - q of the integration (the energy defect of the march), from Richardson "
          "extrapolation where the point was refined, or the bound of an asymptotic law; "
          "calibrated on the test suite's high-precision references", fill_value=math.nan),
)}


def integrator_fields() -> tuple[str, ...]:
    """Fields a sweep can store besides e (``outputs.fields``), in storage order."""
    return tuple(name for name in FIELDS if name != "e")


def kernel_fields() -> tuple[Field, ...]:
    """Fields the integration kernel fills itself (the others are derived from them)."""
    return tuple(f for f in FIELDS.values() if f.derived is None)


def register_field(f: Field) -> None:
    """Add an output field (its kernel must fill it, or ``derived`` compute it).

    Raises
    ------
    ValueError
        The name is registered, or already in use by a dataset variable (``e_ord1``).
    """
    if f.name in FIELDS:
        raise ValueError(f"field {f.name!r} is already registered")
    _refuse_taken("field", f.name, (f.name,))
    FIELDS[f.name] = f


def unregister_field(name: str) -> None:
    """Remove a field added by :func:`register_field`."""
    FIELDS.pop(name)


def _variables_in_use() -> set[str]:
    """Every per-point name a dataset may hold now: parameters, physical inputs, fields and
    each method's variables."""
    names = set(PARAMETER_NAMES) | set(PHYSICAL) | set(FIELDS) | set(method_fields())
    for name in METHODS:
        names |= {f"e_{name}", f"error_{name}"}
    return names


def _refuse_taken(kind: str, name: str, stored: tuple[str, ...]) -> None:
    # Two entries storing one variable: the dataset would hold one of them, or a KeyError.
    clash = sorted(set(stored) & _variables_in_use())
    if clash:
        raise ValueError(f"{kind} {name!r} would store {', '.join(clash)}, a name already "
                         "in use in datasets")


def variable_names(methods: tuple[str, ...], fields: tuple[str, ...]) -> tuple[str, ...]:
    """Dataset variables of a sweep storing ``methods`` and ``fields``, in storage order."""
    return tuple(f"e_{m}" for m in methods) + tuple(fields)


# --------------------------------------------------------------------------- composite methods

#: Flag codes of ``method_used``: which method served a point of ``method = "auto"``. The
#: built-in methods in their stable order; stored in datasets, never renumber them.
SERVED_BY: dict[str, int] = {name: code for code, name in enumerate(METHODS)}

_AUTO_TOL = Option("tol", 1e-6, lambda v: is_number(v) and v > 0,
                   "a number > 0 (largest acceptable abs error on e)")

METHODS["auto"] = Method(
    "auto", "coefficient of restitution, cheapest method within tol",
    "e from the cheapest method whose validated error bound on e is <= tol at the point "
    "(the closed forms of report eqs. (22), (23), (25), (36)-(38) where their error model, "
    "sweep/data/error_model.npz, allows it; the numerical integration, eqs. (3), (4), "
    "elsewhere); method_used says which", "(3), (4), (22)-(25), (36)-(38)",
    # auto's tol is also the integrator's, where it integrates (sweep.auto).
    "sweep.auto:auto_cor",
    (_AUTO_TOL,) + tuple(opt for opt in _INTEGRATOR_OPTIONS if opt.name != "tol"),
    fields=(Field("method_used", np.dtype(np.int8), "method that served the point",
                  "which method of the registry computed e_auto at this point: "
                  + ", ".join(f"{code} = {name}" for name, code in SERVED_BY.items()),
                  flags=dict(SERVED_BY)),),
    composite=True)
