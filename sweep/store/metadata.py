"""CF metadata of a sweep dataset: what every coordinate and stored variable means.

Owns the CF attributes (``long_name``, ``units``, ``description`` citing the report's
equation, ``_FillValue``, ``flag_values`` / ``flag_meanings``, the ``spacing`` of grid
axes) and the storage dtype of every variable a sweep can store. :func:`variable_spec` is
the single entry point the rest of the package calls for these facts (the runner for
dtypes, the writer for attributes, the summary for the flags), so that where the facts
live can change without touching the callers.

The results are dimensionless (scaled by eq. (2) of the report), hence ``units = "1"``; a
scene's physical inputs carry their SI units.

Conventions (CF-1.8, the newest version the ``cfchecker`` package verifies):

* ``_FillValue`` (NaN) on every variable that can hold NaN: the CoR of every method, the
  error fields and the float fields whose :class:`sweep.registry.Field` has a
  ``fill_value``. A fill value marks an invalid point (invalid input, status ``invalid``,
  or a method used outside its domain): there is no value there. It is NaN itself, so
  xarray reads the data back unchanged, decoded or not. Integer variables have no
  ``_FillValue`` (every value is meaningful), so xarray never turns them into floats.
* Flag variables (``status``, ``sticks``) carry ``flag_values`` (of the variable's type) and
  ``flag_meanings`` and no ``units``: a flag is a category, not a quantity (CF 3.5).
  netCDF has no boolean type: a boolean field is stored as a byte flag with the values 0
  and 1, its meanings read from the registry.
* Grid coordinates carry ``spacing``: ``"linear"`` or ``"log"`` for a range
  ``{start, stop, num}``, ``"irregular"`` for a list of values, ``"single"`` for one value.
* Designs of experiments index their ``point`` dimension with a coordinate 0..n-1, scenes
  their ``material`` dimension likewise: a CF coordinate variable is numeric and
  monotonic, so the materials' names are an auxiliary coordinate,
  ``material_name(material)``, a CF label (characters, CF 6.1; xarray reads strings), that
  every variable on ``material`` lists in its ``coordinates`` attribute.
* Every ``units`` attribute is a UDUNITS string in unscaled SI units. A scene's k
  [N m^-alpha] and gamma0 [s m^(alpha-beta)] have one only where every material has the
  same integer power of the metre: UDUNITS has no fractional powers (it reads
  ``"N m-1.5"`` as 0.5 N m-1). Elsewhere the variable has no ``units`` and its
  ``comment`` gives the SI unit of each material's law (:func:`law_units_attrs`).

The facts themselves (long names, descriptions, dtypes, flags) live in
:mod:`sweep.registry`; this module only turns them into netCDF attributes.

May import: numpy and :mod:`sweep.registry` (floor 0); nothing of numba, the kernels, the
api or any floor above the store.
"""
from __future__ import annotations

import numpy as np

from sweep import registry
from sweep.registry import REPORT

__all__ = ["REPORT", "CONVENTIONS", "SPACINGS", "variable_spec", "coordinate_attrs",
           "law_units_attrs", "index_dtype", "MATERIAL_NAME", "CAVEAT_ATTRS"]

#: The ``Conventions`` global attribute: the newest CF version the ``cfchecker`` package
#: (4.1) knows; the files use nothing of later versions.
CONVENTIONS = "CF-1.8"

#: Global attributes counting the points whose e needs a caveat, whatever the file stores:
#: points that ran out of the step budget in any method (e there is an upper bound), and
#: the other points whose error estimate e_err is above the integrator's ``tol`` or, where
#: ``auto`` integrated them, above auto's (written only where a tol is set). ``status``
#: and ``e_err`` say which, where stored.
CAVEAT_ATTRS = ("points_budget_exhausted", "points_above_tol")

#: Values of the ``spacing`` attribute of a grid coordinate.
SPACINGS = ("linear", "log", "irregular", "single")

#: The e of every method is float64 with the fill of the integrator's e (NaN at an invalid
#: point); error fields are differences of two of them.
_E = registry.FIELDS["e"]


def _with_fill(dtype: np.dtype, attrs: dict, fill) -> tuple[np.dtype, dict]:
    """Add ``_FillValue`` (in the variable's dtype, as CF requires) unless ``fill`` is None."""
    if fill is not None:
        attrs["_FillValue"] = dtype.type(fill)
    return dtype, attrs


def _method_spec(method: registry.Method) -> tuple[np.dtype, dict]:
    return _with_fill(_E.dtype, {"long_name": method.long_name, "units": "1",
                                 "description": method.description}, _E.fill_value)


def _error_spec(method: registry.Method) -> tuple[np.dtype, dict]:
    return _with_fill(_E.dtype, {
        "long_name": method.error_long_name,
        "units": "1",
        "description": f"e_{method.name} - e_numeric: the approximation "
                       f"({method.description}) minus the numerical CoR "
                       "(report eq. (3), Algorithm 1)"}, _E.fill_value)


def _field_spec(field: registry.Field) -> tuple[np.dtype, dict]:
    # netCDF has no boolean: a boolean field is a byte flag variable (0 false, 1 true).
    dtype = np.dtype(np.int8) if field.dtype == np.bool_ else field.dtype
    attrs = {"long_name": field.long_name, "description": field.description}
    if field.flags:  # a category, not a quantity: no units (CF 3.5)
        attrs["flag_values"] = np.array(list(field.flags.values()), dtype=dtype)
        attrs["flag_meanings"] = " ".join(field.flags)
    else:
        attrs["units"] = field.units
    return _with_fill(dtype, attrs, field.fill_value)


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
        Storage dtype (a boolean field is stored as int8).
    attrs : dict
        ``long_name``, ``description``; ``units`` except for flags, which have
        ``flag_values`` / ``flag_meanings`` instead; ``_FillValue`` (NaN, a numpy scalar
        of ``dtype``) on variables that can hold NaN.

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


#: The index coordinate of the ``point`` dimension of designs of experiments.
_POINT = {"long_name": "design point index", "units": "1",
          "description": "position of the point in the design of experiments, from 0: "
                         "point i is the i-th point of the seeded sequence, whatever the "
                         "chunking"}


#: The auxiliary coordinate that names a scene's materials; and the index coordinates.
MATERIAL_NAME = registry.MATERIAL_NAME
_INDEXES = {"point": _POINT, "material": {
    "long_name": "material index", "units": "1",
    "description": f"position of the material in design.materials, from 0; its name is "
                   f"{MATERIAL_NAME}"}}


def coordinate_attrs(name: str, spacing: str | None = None) -> dict:
    """CF attributes of a coordinate or input quantity.

    Parameters
    ----------
    name : str
        One of the four scaled parameters of eq. (2) (``alpha``, ``beta``, ``gamma``,
        ``gtilde``), a physical input of the scaling (``m``, ``k``, ``gamma0``, ``v0``,
        ``g``, ``F``), a material property (:data:`sweep.registry.MATERIAL`), ``point``
        or ``material`` (the index of a design of experiments, of a scene's materials).
    spacing : str, optional
        Spacing of an axis, one of :data:`SPACINGS`.

    Returns
    -------
    dict
        ``long_name``, ``units`` (not for k and gamma0, whose units depend on the contact
        law: :func:`law_units_attrs`) and ``description``, and ``spacing`` if given; empty
        for another name (its attributes then come from the layout,
        :attr:`sweep.store.layout.Layout.attrs`).

    Raises
    ------
    ValueError
        If ``spacing`` is not one of :data:`SPACINGS`.
    """
    p = {**registry.MATERIAL, **registry.PHYSICAL, **registry.PARAMETERS}.get(name)
    if name in _INDEXES:
        attrs = dict(_INDEXES[name])
    elif p is None:
        attrs = {}
    else:
        attrs = {"long_name": p.long_name, "description": p.description}
        if not p.law_units:  # else the law sets them: law_units_attrs
            attrs["units"] = p.units
    if spacing is not None:
        if spacing not in SPACINGS:
            raise ValueError(f"spacing must be one of {SPACINGS}, got {spacing!r}")
        attrs["spacing"] = spacing
    return attrs


def law_units_attrs(alpha: np.ndarray, beta: np.ndarray) -> dict[str, dict]:
    """The units attributes of the law-dependent inputs (k, gamma0) of a scene's materials.

    Parameters
    ----------
    alpha, beta : ndarray
        Exponents of each material's contact law.

    Returns
    -------
    dict of str -> dict
        Per input (:attr:`sweep.registry.Parameter.law_units`): ``{"units": ...}`` where
        every material has the same UDUNITS unit, else ``{"comment": ...}`` stating the SI
        unit of each law. A variable on ``material`` has one ``units`` for all materials,
        and UDUNITS cannot say a fractional power of the metre: no ``units`` is then
        honest, a wrong one would not be.
    """
    laws = list(dict.fromkeys(zip(np.asarray(alpha, float).tolist(),
                                  np.asarray(beta, float).tolist())))
    return {name: _law_units(p, laws)
            for name, p in registry.PHYSICAL.items() if p.law_units}


def _law_units(p: registry.Parameter, laws: list) -> dict:
    """``units``, or the ``comment`` that replaces it, of ``p`` under the (alpha, beta)
    ``laws`` (distinct, in the materials' order)."""
    units = {p.cf_units(a, b) for a, b in laws}
    if len(units) == 1 and None not in units:
        return {"units": units.pop()}
    base, per_alpha, per_beta = p.law_units
    each = {}
    for a, b in laws:   # one entry per distinct unit, with the exponents it depends on
        power = per_alpha * a + per_beta * b
        law = f"alpha = {a:g}" + (f", beta = {b:g}" if per_beta else "")
        each.setdefault(base if power == 0 else f"{base} m^{power:g}", law)
    why = ("UDUNITS, which CF units follow, has no fractional powers"
           if None in units else "the unit differs between the materials")
    return {"comment": f"SI unit {p.units}, with the exponents of each material's law "
                       f"(variables alpha, beta): "
                       + "; ".join(f"{u} ({law})" for u, law in each.items())
                       + f". No units attribute: {why}."}


def index_dtype(size: int) -> np.dtype:
    """dtype of the ``point`` index of a design of ``size`` points: int32 (a CF-1.8 type)
    when it fits, int64 beyond."""
    return np.dtype(np.int32 if size <= np.iinfo(np.int32).max + 1 else np.int64)
