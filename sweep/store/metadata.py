"""CF metadata of a sweep dataset: what every coordinate and stored variable means.

Owns the CF attributes (``long_name``, ``units``, ``description`` citing the report's
equation, ``flag_values`` / ``flag_meanings``) and the dtype of every variable a sweep can
store. :func:`variable_spec` is the single entry point the rest of the package calls for
these facts (the runner for dtypes, the writer for attributes, the summary for the status
flags), so that where the facts live can change without touching the callers.

All quantities are dimensionless (scaled by eq. (2) of the report), hence ``units = "1"``.

The facts themselves (long names, descriptions, dtypes, flags) live in
:mod:`sweep.registry`; this module only turns them into netCDF attributes.

May import: numpy and :mod:`sweep.registry` (floor 0); nothing of numba, the kernels, the
api or any floor above the store.
"""
from __future__ import annotations

import numpy as np

from sweep import registry
from sweep.registry import REPORT

__all__ = ["REPORT", "variable_spec", "coordinate_attrs"]


def _method_spec(method: registry.Method) -> tuple[np.dtype, dict]:
    return np.dtype(np.float64), {"long_name": method.long_name, "units": "1",
                                  "description": method.description}


def _error_spec(method: registry.Method) -> tuple[np.dtype, dict]:
    return np.dtype(np.float64), {
        "long_name": f"error of the {method.long_name.split(', ', 1)[1]}",
        "units": "1",
        "description": f"e_{method.name} - e_numeric: the approximation "
                       f"({method.description}) minus the numerical CoR "
                       "(report eq. (3), Algorithm 1)"}


def _field_spec(field: registry.Field) -> tuple[np.dtype, dict]:
    attrs = {"long_name": field.long_name, "units": field.units,
             "description": field.description}
    if field.flags:
        attrs["flag_values"] = np.array(list(field.flags.values()), dtype=field.dtype)
        attrs["flag_meanings"] = " ".join(field.flags)
    return field.dtype, attrs


def variable_spec(name: str) -> tuple[np.dtype, dict]:
    """dtype and CF attributes of a stored variable.

    Parameters
    ----------
    name : str
        ``e_<method>``, ``error_<method>``, an integrator field (``sticks``, ``t_f``,
        ``u_max``, ``n_steps``, ``status``) or a method's own field (``method_used``).

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
    if name.startswith("e_") and name[2:] in registry.METHODS:
        return _method_spec(registry.METHODS[name[2:]])
    if name.startswith("error_") and name[6:] in registry.METHODS:
        return _error_spec(registry.METHODS[name[6:]])
    if name in registry.FIELDS and name != "e":
        return _field_spec(registry.FIELDS[name])
    if name in registry.method_fields():
        return _field_spec(registry.method_fields()[name][1])
    raise KeyError(f"unknown output variable {name!r}")


def coordinate_attrs(name: str) -> dict:
    """CF attributes of a coordinate or input quantity.

    Parameters
    ----------
    name : str
        One of the four scaled parameters of eq. (2) (``alpha``, ``beta``, ``gamma``,
        ``gtilde``), a physical input of the scaling (``m``, ``k``, ``gamma0``, ``v0``,
        ``g``, ``F``) or a material property (:data:`sweep.registry.MATERIAL`).

    Returns
    -------
    dict
        ``long_name``, ``units`` and ``description``; empty for another name (its
        attributes then come from the layout, :attr:`sweep.store.layout.Layout.attrs`).
    """
    p = {**registry.MATERIAL, **registry.PHYSICAL, **registry.PARAMETERS}.get(name)
    if p is None:
        return {}
    return {"long_name": p.long_name, "units": p.units, "description": p.description}
