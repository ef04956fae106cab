"""CF metadata of a sweep dataset: what every coordinate and stored variable means.

Owns the CF attributes (``long_name``, ``units``, ``description`` citing the report's
equation, ``flag_values`` / ``flag_meanings``) and the dtype of every variable a sweep can
store. :func:`variable_spec` is the single entry point the rest of the package calls for
these facts (the runner for dtypes, the writer for attributes, the summary for the status
flags), so that where the facts live can change without touching the callers.

All quantities are dimensionless (scaled by eq. (2) of the report), hence ``units = "1"``.

May import: numpy and :class:`sweep.model.Status` (floor 0 facts); nothing of numba, the
kernels, the api or any floor above the store.
"""
from __future__ import annotations

import numpy as np

from sweep.model import Status

__all__ = ["REPORT", "variable_spec", "coordinate_attrs"]

#: Citation stored in every dataset's ``references`` attribute.
REPORT = ("A. Chatterjee, G. James, B. Brogliato, Approximate analytical coefficient of "
          "restitution formulation for single bead impact with external load, using "
          "nonlinear visco-elastic models, INRIA hal-03462750 (2021)")

_COORDS = {
    "alpha": ("stiffness exponent alpha",
              "exponent of the elastic contact force k (-x)_+^alpha, report eq. (1)"),
    "beta": ("damping exponent beta",
             "exponent of the damping force k gamma0 d/dt (-x)_+^beta, report eq. (1)"),
    "gamma": ("scaled damping gamma",
              "gamma = gamma0 v0^(2 beta/(alpha+1) - 1) (k/m)^(1 - beta/(alpha+1)), "
              "report eq. (2)"),
    "gtilde": ("scaled load g~",
               "g~ = (m/k)^(1/(alpha+1)) v0^(-2 alpha/(alpha+1)) (g + F/m), report eq. (2)"),
}

_METHODS = {
    "numeric": ("coefficient of restitution, numerical integration",
                "e = -v(T_f) (report eq. (3)) from the fixed-step Runge-Kutta integration of "
                "the (u, w) system, eq. (4), through the three phases of Algorithm 1; 0 if "
                "the bead sticks or comes to rest"),
    "ord1": ("coefficient of restitution, first-order approximation",
             "e = max(1 - gamma C0 - gamma g~ C1, 0), report eq. (22)"),
    "sp": ("coefficient of restitution, Schwager-Poeschel second order",
           "e = 1 - gamma C0 - gamma g~ C1 - gamma^2 C2, report eqs. (25) and (30); defined "
           "for alpha = beta = 3/2 only (NaN elsewhere)"),
    "large_gtilde": ("coefficient of restitution, large-load approximation",
                     "e = sqrt(max(1 - 2 gamma C g~^r, 0)), report eq. (23)"),
    "ord2_numint": ("coefficient of restitution, second order with quadrature I, Q",
                    "e = min(sqrt(max(e^2, 0)), e_s), report Prop. 2, eqs. (36)-(38), with "
                    "I(g~) and Q(g~) by quadrature"),
    "ord2_approx": ("coefficient of restitution, second order with approximated I, Q",
                    "e = min(sqrt(max(e^2, 0)), e_s), report Prop. 2, eqs. (36)-(38), with "
                    "I(g~) and Q(g~) from the approximation of Sec. 4.4, eqs. (43)-(49)"),
}

_FIELDS = {
    "sticks": ("bead does not rebound", np.bool_,
               "true if the impact ends without rebound, e = 0 (Algorithm 1, phase 3: "
               "v = 0 with u > 0, or converged to rest)"),
    "t_f": ("impact duration T_f", np.float64,
            "scaled time T_f at the end of the impact (report eq. (3)), in units of T of "
            "eq. (2)"),
    "u_max": ("maximum compression u_M", np.float64,
              "scaled maximum compression u(tau_0) where v = 0 (Algorithm 1, phase 1), in "
              "units of delta = v0 T of eq. (2)"),
    "n_steps": ("number of integration steps", np.int64,
                "Runge-Kutta steps taken to integrate eq. (4) for this point"),
    "status": ("integration status", np.int8,
               "why the numerical computation of the point ended (Algorithm 1): "
               + ", ".join(f"{s.value} = {s.name.lower()}" for s in Status)),
}


def _method_spec(method: str) -> tuple[np.dtype, dict]:
    long_name, desc = _METHODS[method]
    return np.dtype(np.float64), {"long_name": long_name, "units": "1", "description": desc}


def _error_spec(method: str) -> tuple[np.dtype, dict]:
    long_name, desc = _METHODS[method]
    return np.dtype(np.float64), {
        "long_name": f"error of the {long_name.split(', ', 1)[1]}",
        "units": "1",
        "description": f"e_{method} - e_numeric: the approximation ({desc}) minus the "
                       "numerical CoR (report eq. (3), Algorithm 1)"}


def _field_spec(name: str) -> tuple[np.dtype, dict]:
    long_name, dtype, desc = _FIELDS[name]
    attrs = {"long_name": long_name, "units": "1", "description": desc}
    if name == "status":
        attrs["flag_values"] = np.array([s.value for s in Status], dtype=np.int8)
        attrs["flag_meanings"] = " ".join(s.name.lower() for s in Status)
    return np.dtype(dtype), attrs


def variable_spec(name: str) -> tuple[np.dtype, dict]:
    """dtype and CF attributes of a stored variable.

    Parameters
    ----------
    name : str
        ``e_<method>``, ``error_<method>`` or an integrator field (``sticks``, ``t_f``,
        ``u_max``, ``n_steps``, ``status``).

    Returns
    -------
    dtype : numpy.dtype
    attrs : dict
        ``long_name``, ``units``, ``description`` and, for flags, ``flag_values`` /
        ``flag_meanings``.

    Raises
    ------
    KeyError
        If ``name`` is not a variable a sweep can store.
    """
    if name.startswith("e_") and name[2:] in _METHODS:
        return _method_spec(name[2:])
    if name.startswith("error_") and name[6:] in _METHODS:
        return _error_spec(name[6:])
    if name in _FIELDS:
        return _field_spec(name)
    raise KeyError(f"unknown output variable {name!r}")


def coordinate_attrs(name: str) -> dict:
    """CF attributes of a coordinate (``alpha``, ``beta``, ``gamma`` or ``gtilde``).

    Parameters
    ----------
    name : str
        One of the four scaled parameters of eq. (2).

    Returns
    -------
    dict
        ``long_name``, ``units`` and ``description``.
    """
    long_name, desc = _COORDS[name]
    return {"long_name": long_name, "units": "1", "description": desc}
