"""What a sweep dataset holds, whatever the backend that stores it.

Owns :func:`dataset_variables` (every variable of a dataset of a given layout, in storage
order, with its dimensions, storage dtype, CF attributes as stored -- ``_FillValue`` and
``coordinates`` included -- and its values when they are known before the run),
:func:`chunk_values` (the arrays one chunk contributes: results, per-point values, the
``point`` index), :func:`stored_attr` (how a global attribute is stored) and
:func:`cast_exactly`. Both writers (:class:`sweep.store.netcdf.NetCDFWriter`,
:class:`sweep.store.memory.MemoryWriter`) are built on these, so that a dataset assembled
in memory holds exactly what the netCDF file holds.

May import: numpy and the store's own :mod:`~sweep.store.layout` and
:mod:`~sweep.store.metadata`. Nothing of numba, the kernels or any floor above the store.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sweep.store.layout import Layout
from sweep.store.metadata import coordinate_attrs, index_dtype, variable_spec

__all__ = ["Variable", "dataset_variables", "chunk_values", "stored_attr", "cast_exactly"]


@dataclasses.dataclass(frozen=True)
class Variable:
    """One variable of a sweep dataset, as stored.

    Attributes
    ----------
    name : str
    dims : tuple of str
    dtype : numpy.dtype
        Storage dtype; ``S1`` for names (a CF label: characters along a last dimension
        ``<name>_strlen`` that the layout does not list).
    attrs : dict
        CF attributes as stored, ``_FillValue`` and ``coordinates`` included.
    values : ndarray or None
        The values when known before the run (axes and constants of the layout); None for
        a variable written chunk by chunk (see :func:`chunk_values`).
    """

    name: str
    dims: tuple
    dtype: np.dtype
    attrs: dict
    values: np.ndarray | None = None


def _known(layout: Layout, name: str, dims: tuple, values: Any) -> Variable:
    """An axis or constant of the layout: float64, an integer index (the ``material``
    axis) in :func:`index_dtype`, or names (a scene's ``material_name``) as characters."""
    values = np.asarray(values)
    attrs = {**coordinate_attrs(name, layout.spacing.get(name)), **layout.attrs.get(name, {})}
    if values.dtype.kind in "OUS":
        return _label(name, tuple(dims), values, attrs)
    values = values.astype(index_dtype(values.size) if values.dtype.kind in "iu"
                           else np.float64)
    return Variable(name, tuple(dims), values.dtype, attrs, values)


def _label(name: str, dims: tuple, values: np.ndarray, attrs: dict) -> Variable:
    """Names as a CF label (CF 6.1): a char array whose last dimension,
    ``<name>_strlen``, holds the UTF-8 bytes of each name, NUL-padded. Not a netCDF-4
    string: cfchecker (4.1) refuses variable-length types, and char arrays are what every
    CF version and reader knows; xarray decodes them back to strings (``_Encoding``)."""
    encoded = [str(v).encode("utf-8") for v in values.reshape(-1)]
    width = max([1] + [len(b) for b in encoded])
    chars = np.array(encoded, dtype=f"S{width}").reshape(values.shape + (1,)).view("S1")
    return Variable(name, dims + (f"{name}_strlen",), np.dtype("S1"),
                    {**attrs, "_Encoding": "utf-8"}, chars)


def _with_aux_coords(layout: Layout, var: Variable) -> Variable:
    """``var`` listing the auxiliary coordinates on its dimensions (CF 5: a data variable
    names its auxiliary coordinates in ``coordinates``; xarray reads them as coordinates)."""
    dims = set(var.dims)
    names = [n for n in layout.aux_coords
             if n != var.name and set(layout.constants[n][0]) <= dims]
    if not names or var.name in layout.dims:   # a coordinate variable names none
        return var
    listed = var.attrs.get("coordinates", "").split()
    coordinates = " ".join(listed + [n for n in names if n not in listed])
    return dataclasses.replace(var, attrs={**var.attrs, "coordinates": coordinates})


def dataset_variables(layout: Layout, variables: Sequence[str]) -> list[Variable]:
    """Every variable of the dataset of ``layout`` storing ``variables``, in storage order.

    Parameters
    ----------
    layout : Layout
    variables : sequence of str
        Stored results (see :func:`sweep.store.metadata.variable_spec`).

    Returns
    -------
    list of Variable
        Axes, constants, the ``point`` index (scattered designs), per-point values, then
        the results; each variable on the dimension of an auxiliary coordinate
        (:attr:`Layout.aux_coords`) lists it in its ``coordinates`` attribute.
    """
    out = [_known(layout, name, (name,), values) for name, values in layout.axes.items()]
    out += [_known(layout, name, dims, values)
            for name, (dims, values) in layout.constants.items()]
    dims = tuple(layout.dims)
    if layout.point_coords:  # the index of the single dimension, written chunk by chunk
        out.append(Variable(dims[0], dims, index_dtype(layout.size),
                            coordinate_attrs(dims[0])))
    out += [Variable(name, dims, np.dtype(np.float64),
                     {**coordinate_attrs(name), **layout.attrs.get(name, {})})
            for name in layout.per_point]
    for name in variables:
        dtype, attrs = variable_spec(name)
        if layout.point_coords:
            attrs = dict(attrs, coordinates=" ".join(layout.point_coords))
        out.append(Variable(name, dims, np.dtype(dtype), attrs))
    return [_with_aux_coords(layout, var) for var in out]


def chunk_values(layout: Layout, start: int, stop: int, arrays: Mapping[str, Any],
                 points: Mapping[str, Any] | None = None) -> dict[str, np.ndarray]:
    """The flat arrays a chunk contributes to the variables written chunk by chunk.

    Parameters
    ----------
    layout : Layout
    start, stop : int
        Flat C-order range of the chunk.
    arrays : dict of str -> ndarray
        One flat array of length ``stop - start`` per stored result.
    points : dict of str -> ndarray, optional
        Per-point values (:attr:`Layout.per_point`): required when the layout has any.

    Returns
    -------
    dict of str -> ndarray
        The results, the per-point values and, for a scattered design, its ``point``
        index, each of length ``stop - start``.

    Raises
    ------
    ValueError
        If an array has the wrong length, or per-point values are missing.
    """
    todo = dict(arrays)
    if layout.per_point:
        if points is None:
            raise ValueError("per-point coordinates are required for this layout")
        todo.update({k: points[k] for k in layout.per_point})
    if layout.point_coords:   # the index of a scattered design's dimension
        todo[layout.dims[0]] = np.arange(start, stop)
    out = {}
    for name, arr in todo.items():
        arr = np.asarray(arr)
        if arr.shape != (stop - start,):
            raise ValueError(f"{name}: expected {stop - start} values, got {arr.shape}")
        out[name] = arr
    return out


def stored_attr(value: Any) -> Any:
    """A global attribute as a netCDF file stores it: netCDF has no null or boolean
    attribute, so None becomes the string ``"default"`` and a boolean 0 / 1."""
    if value is None:
        return "default"
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    return value


def cast_exactly(name: str, arr: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """``arr`` in the storage ``dtype``, refusing a conversion that would change a value
    (booleans become byte flags; a float that is not an integer never becomes one)."""
    if arr.dtype == dtype:
        return arr
    out = arr.astype(dtype)
    if not np.array_equal(out, arr, equal_nan=out.dtype.kind == "f"):
        raise ValueError(f"{name}: values do not fit the stored type {dtype}")
    return out
