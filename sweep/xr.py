"""Labelled, Dask-aware front ends of :mod:`sweep.api` for xarray users.

:func:`cor` and :func:`integrate` take scalars and :class:`xarray.DataArray` s (numpy- or
dask-backed) with any dimension names, broadcast them *by dimension name* (xarray
semantics, coordinates aligned with ``join="exact"``) and return labelled, attributed
results; dask-backed inputs give dask-backed results that compute nothing until asked.
Values are those of :func:`sweep.cor` / :func:`sweep.integrate` on plain arrays, bit for bit
(the kernels give identical results for any chunking, thread or order).

``import sweep.xr`` also registers the Dataset accessor ``ds.sweep`` (see
:class:`SweepAccessor`): ``ds.sweep.cor(method)`` evaluates a method at the points of a sweep
dataset (gives back its ``e_<method>`` where it holds one) and ``ds.sweep.error(method)`` its
error field against ``ds.e_numeric``.
``import sweep`` alone does not import xarray's accessor machinery nor this module.

Owns: the labelled front ends. May import: :mod:`sweep.api`, :mod:`sweep.registry` (method
and field metadata), numpy, xarray (never the kernels, sweeps, store, reports or CLI).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable

import numpy as np
import xarray as xr

from sweep import api, registry

__all__ = ["cor", "integrate", "SweepAccessor", "PARAMETERS"]

#: The four scaled parameters, in the order of :func:`sweep.cor`'s arguments.
PARAMETERS = registry.PARAMETER_NAMES


# --------------------------------------------------------------------------- helpers

def _labelled(name: str, value: Any) -> xr.DataArray:
    """A DataArray for one parameter; scalars become 0-d (no dimension to name)."""
    if isinstance(value, xr.DataArray):
        if value.dtype.kind not in "iuf":
            # The dtype is known without computing: refused now, not when a dask graph runs.
            raise ValueError(f"{name} must be a real number (int or float) or an array of "
                             f"them, got a DataArray of dtype {value.dtype}")
        return value
    if isinstance(value, xr.Dataset):
        raise TypeError(f"{name} must be a scalar or an xarray.DataArray, got a Dataset of "
                        f"{sorted(map(str, value.data_vars))}: pick one, e.g. ds[{name!r}]")
    if np.ndim(value) == 0:
        # As sweep.cor: a string, bool, None or complex is refused, not converted.
        return xr.DataArray(registry.real_array(name, value))
    # A bare array has no dimension names to broadcast by; guessing them would be wrong.
    raise TypeError(
        f"{name} must be a scalar or an xarray.DataArray, got {type(value).__name__} of "
        f"shape {np.shape(value)}: wrap it in xarray.DataArray(..., dims=...), or use "
        "sweep.cor / sweep.integrate for numpy broadcasting")


def _probe(function: Callable, **options: Any) -> Any:
    """Evaluate on zero points: checks method and options now rather than at compute time
    (for dask inputs), with the errors of the plain function, and gives the output dtypes.
    Integrates nothing; the first call in a process loads (or compiles) the kernels, which
    computing would do anyway."""
    z = np.empty(0)
    return function(z, z, z, z, **options)


def _method_attrs(method: str, options: dict) -> dict:
    """Attributes of a method's result: its registry metadata and the settings used
    (defaults resolved; ``parallel`` left out on purpose: results do not depend on it)."""
    m = registry.method(method)
    used = api.method_settings(method, {k: v for k, v in options.items() if k != "parallel"})
    prefix = "integrator_" if m.integrates else "option_"
    # As in sweep's files: each option in its netCDF form (Option.to_attr).
    return {"long_name": m.long_name, "units": "1", "method": method,
            "equation": m.equation, "description": m.description,
            **{prefix + k: m.option(k).to_attr(v) for k, v in used.items()}}


def _apply(block: Callable, args: tuple, kwargs: dict, dtypes: list) -> Any:
    """``xr.apply_ufunc`` of a block function over the four parameters, elementwise."""
    arrays = [_labelled(n, a) for n, a in zip(PARAMETERS, args)]
    return xr.apply_ufunc(
        block, *arrays, kwargs=kwargs, output_core_dims=[()] * len(dtypes),
        dask="parallelized", output_dtypes=dtypes, vectorize=False)


# Block functions: module level so that distributed schedulers can pickle them. They get
# numpy blocks already broadcast-compatible (xarray inserted size-1 axes by name), which
# sweep.api broadcasts with numpy rules. A block of 0-d arrays (all inputs scalars) is a
# scalar call of sweep.api and raises on invalid values, as sweep.cor does.

def _cor_block(alpha, beta, gamma, gtilde, method, options):
    e = api.cor(alpha, beta, gamma, gtilde, method=method, **options)
    return np.asarray(e, dtype=np.float64)


def _integrate_block(alpha, beta, gamma, gtilde, options, dtypes):
    r = api.integrate(alpha, beta, gamma, gtilde, **options)
    return tuple(np.asarray(getattr(r, name), dtype=dt) for name, dt in dtypes.items())


# --------------------------------------------------------------------------- public

def cor(alpha: Any, beta: Any, gamma: Any, gtilde: Any, method: str = "numeric",
        **options: Any) -> xr.DataArray:
    """Coefficient of restitution ``e`` [1] of labelled inputs, broadcast by dimension name.

    Parameters
    ----------
    alpha, beta : float or xarray.DataArray
        Stiffness and damping exponents [1], >= 1.
    gamma : float or xarray.DataArray
        Scaled damping [1], >= 0, report eq. (2).
    gtilde : float or xarray.DataArray
        Scaled load g~ [1], >= 0, report eq. (2).
    method : str, default "numeric"
        One of :data:`sweep.METHODS` (see :func:`sweep.cor`).
    **options
        Passed to :func:`sweep.cor`: the method's options (:attr:`sweep.registry.Method.options`:
        ``tol``, ``steps``, ``rest_tol``, ``max_steps``, ``refine``, ``device`` for
        ``"numeric"`` and ``"auto"``; ``n`` for ``"ord2_approx"``) and, for
        ``"numeric"``, ``parallel``; checked at call time. The result's attributes record
        them, defaults resolved (``steps`` "default" where ``tol`` chooses the resolution).

    Returns
    -------
    xarray.DataArray
        Named ``e_<method>``, float64, dimensions the union of the inputs' in order of first
        appearance, dask-backed (lazy) if any input is. NaN at invalid points inside arrays;
        all-scalar inputs give a 0-d result and raise ``ValueError`` on invalid values, like
        :func:`sweep.cor`. Attributes: ``units``, ``long_name``, ``method``, ``equation``
        and the settings used (``integrator_*`` or ``option_*``).
    """
    registry.method(method)
    _probe(api.cor, method=method, **options)  # sweep.cor's errors, for "numeric" too
    out = _apply(_cor_block, (alpha, beta, gamma, gtilde),
                 {"method": method, "options": options}, [np.float64])
    out.name = f"e_{method}"
    out.attrs = _method_attrs(method, options)
    return out


def _field_attrs(name: str) -> dict:
    f = registry.FIELDS[name]
    attrs = {"long_name": f.long_name, "description": f.description}
    if f.flags:  # CF flags carry no units
        # Attributes have no boolean type: a boolean's flag values are the bytes 0 and 1
        # (xarray writes the variable itself as such bytes, as sweep's files do).
        dtype = np.int8 if f.dtype == np.bool_ else f.dtype
        attrs["flag_values"] = np.array(list(f.flags.values()), dtype=dtype)
        attrs["flag_meanings"] = " ".join(f.flags)
    elif f.dtype != np.bool_:
        attrs["units"] = f.units
    return attrs


def integrate(alpha: Any, beta: Any, gamma: Any, gtilde: Any,
              **options: Any) -> xr.Dataset:
    """Numerical integration of labelled inputs (:func:`sweep.integrate`) as a Dataset.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : float or xarray.DataArray
        Scaled parameters [1] (see :func:`cor`), broadcast by dimension name.
    **options
        ``tol``, ``steps``, ``rest_tol``, ``max_steps``, ``refine``, ``device``,
        ``parallel`` of :func:`sweep.integrate`; checked at call time.

    Returns
    -------
    xarray.Dataset
        One variable per field of :class:`sweep.IntegrationResult` (``e``, ``sticks``,
        ``t_f``, ``u_max``, ``n_steps``, ``status``, ``e_err``), with their dtypes,
        ``long_name`` and ``units`` (``flag_values`` / ``flag_meanings`` for ``status``);
        dask-backed (lazy, one integration per block) if any input is. Global attributes: ``method``
        ("numeric"), ``equation`` and the integrator settings used.
    """
    # Any other keyword named as sweep.cor names it, not by Python's TypeError.
    registry.method("numeric").refuse_unknown(options, extra=("parallel",))
    probe = _probe(api.integrate, **options)
    # Names and dtypes come from the function itself, so a new field needs no edit here.
    dtypes = {f.name: np.asarray(getattr(probe, f.name)).dtype
              for f in dataclasses.fields(probe)}
    outs = _apply(_integrate_block, (alpha, beta, gamma, gtilde),
                  {"options": options, "dtypes": dtypes}, list(dtypes.values()))
    outs = outs if isinstance(outs, tuple) else (outs,)
    for name, out in zip(dtypes, outs):
        out.attrs = _field_attrs(name)  # replace, not merge: keep_attrs may have copied some
    ds = xr.Dataset(dict(zip(dtypes, outs)))
    attrs = _method_attrs("numeric", options)
    ds.attrs = {k: v for k, v in attrs.items() if k not in ("long_name", "units")}
    return ds


# --------------------------------------------------------------------------- accessor

def _dim_chunks(ds: xr.Dataset) -> dict:
    """Dask chunks per dimension of a dataset: a parameter's own first, then any variable's.

    Not ``ds.chunksizes``, which refuses a dataset whose variables are chunked differently
    (``open_dataset(chunks="auto")`` sizes each variable's chunks by its dtype: an int8
    status gets chunks 8 times those of a float64 e).
    """
    out: dict = {}
    for v in [*(ds[p].variable for p in PARAMETERS), *ds.variables.values()]:
        for dim, c in zip(v.dims, v.chunks or ()):
            out.setdefault(dim, c)
    return out


@xr.register_dataset_accessor("sweep")
class SweepAccessor:
    """``ds.sweep``: CoR methods at the points of a sweep dataset (registered by
    ``import sweep.xr``).

    A sweep dataset holds the four parameters ``alpha, beta, gamma, gtilde`` as coordinates
    (grid designs: one dimension each; designs of experiments: coordinates along ``point``)
    or variables (scenes: on ``material`` and ``(material, v0, F)``), as written by
    ``sweep run``. On a dask-chunked dataset the results are lazy and chunked like it. A
    scene's ``material`` is an index; its names are the coordinate ``material_name``:
    ``ds.set_xindex("material_name").sel(material_name="glass_kk")`` selects by name.

    Examples
    --------
    >>> ds = xarray.open_dataset("default.nc", chunks={"gamma": 100})  # doctest: +SKIP
    >>> ds.sweep.error("ord2_approx").max().compute()                  # doctest: +SKIP
    """

    def __init__(self, ds: xr.Dataset) -> None:
        self._ds = ds

    def parameters(self) -> tuple[xr.DataArray, ...]:
        """The four parameters as DataArrays, dask-chunked like the dataset if it is."""
        ds = self._ds
        missing = [p for p in PARAMETERS if p not in ds.variables]
        if missing:
            raise KeyError(f"not a sweep dataset: no {', '.join(missing)} (a sweep dataset "
                           f"has {', '.join(PARAMETERS)} as coordinates or variables)")
        chunks = _dim_chunks(ds)
        out = []
        for name in PARAMETERS:
            p = ds[name]
            if chunks:
                # Index coordinates refuse to be chunked: chunk a plain copy of the values,
                # so that a lazy dataset gives a lazy result.
                p = xr.DataArray(p.variable.to_base_variable(), coords=p.coords, name=name)
                p = p.chunk({d: chunks[d] for d in p.dims if d in chunks})
            out.append(p)
        return tuple(out)

    def cor(self, method: str = "numeric", **options: Any) -> xr.DataArray:
        """:func:`sweep.xr.cor` at the dataset's points (float64 [1], named ``e_<method>``),
        with the settings the dataset records for ``method`` (:func:`sweep.api.recorded_settings`:
        a file of ``sweep run`` gives its own numbers back) unless ``options`` say others;
        a ``tol`` given also sets aside the recorded ``steps`` (``tol`` then chooses the
        resolution), a ``steps`` given replaces ``steps`` alone.

        Where the dataset holds ``e_<method>`` and no ``options`` are given, that variable
        is what comes back (lazy if the dataset is), with the attributes a computation
        gives and ``source_variable``: the same numbers on the machine that wrote it, each
        point's from its own run's settings, which a dataset combined from runs of other
        settings no longer records (``xarray.open_mfdataset`` keeps the first file's
        attributes: computing with them was up to 2.8e-2 off ``e_ord2_approx`` where a
        second file had another ``n``; audit, 2026-12-07)."""
        recorded = api.recorded_settings(self._ds.attrs, method)
        stored = f"e_{method}"
        if not options and stored in self._ds.data_vars:
            out = self._ds[stored].copy(deep=False)
            out.attrs = {**_method_attrs(method, recorded), "source_variable": stored}
            return out
        if "tol" in options:
            # A tol given chooses the resolution: the file's steps must not overrule it.
            recorded.pop("steps", None)
        # A steps given leaves the file's tol alone: auto's tol is its selection
        # tolerance, and numeric's still sets the refinement target.
        return cor(*self.parameters(), method=method, **{**recorded, **options})

    def error(self, method: str, reference: str = "e_numeric",
              **options: Any) -> xr.DataArray:
        """Error field ``e_<method> - reference`` [1] of a method, named ``error_<method>``.

        Parameters
        ----------
        method : str
            One of :data:`sweep.METHODS`.
        reference : str, default "e_numeric"
            Variable of the dataset to compare against.
        **options
            Passed to :func:`sweep.xr.cor` (e.g. ``n`` for ``"ord2_approx"``), over the
            settings the dataset records (see :meth:`cor`).

        Returns
        -------
        xarray.DataArray
            With the reference's dimension order; lazy if the dataset is chunked.
        """
        if reference not in self._ds:
            raise KeyError(f"no variable {reference!r} to compare against; the dataset "
                           f"has {sorted(self._ds.data_vars)}")
        ref = self._ds[reference]
        e = self.cor(method, **options)
        err = (e - ref).transpose(*ref.dims, ...)
        err.name = f"error_{method}"
        err.attrs = {**e.attrs, "long_name": registry.method(method).error_long_name,
                     "description": f"{e.name} - {reference}", "reference": reference}
        return err
