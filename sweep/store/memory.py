"""The in-memory output backend: a sweep's dataset assembled as an ``xarray.Dataset``.

Owns :class:`MemoryWriter` (a :class:`sweep.store.layout.Writer`): one numpy array per
variable, allocated at its final size, filled chunk by chunk as chunks finish (in any
order), so memory is the size of the result, never more than one variable beyond it.

What it holds is what :class:`~sweep.store.netcdf.NetCDFWriter` writes into the file,
taken from the same :mod:`~sweep.store.schema` (variables, dtypes, attributes as stored,
``_FillValue`` and ``coordinates`` included), and :meth:`MemoryWriter.dataset` decodes it
with ``xarray.decode_cf``, the decoding ``xarray.open_dataset`` applies to the file: the
Dataset is identical to the file read back (run-dependent attributes apart).

There is no file, so nothing to lock, resume or publish.

May import: numpy, the store's own :mod:`~sweep.store.layout` and
:mod:`~sweep.store.schema`, and xarray (lazily: ``import sweep.store`` stays light).
Nothing of numba, the kernels or any floor above the store.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sweep.store.layout import Layout
from sweep.store.schema import cast_exactly, chunk_values, dataset_variables, stored_attr

__all__ = ["MemoryWriter"]


class MemoryWriter:
    """Assemble a sweep's variables in memory, chunk by chunk, as chunks finish.

    Parameters
    ----------
    layout : Layout
    variables : sequence of str
        Names of the stored variables (see :func:`sweep.store.metadata.variable_spec`).
    attrs : dict
        Global attributes known at the start (more can be set before :meth:`close`).
    """

    def __init__(self, layout: Layout, variables: Sequence[str],
                 attrs: Mapping[str, Any] | None = None) -> None:
        self.layout = layout
        self.variables = tuple(variables)
        self._schema = dataset_variables(layout, self.variables)
        # Flat C-order buffers: a chunk is one slice of each, whatever the layout's shape.
        self._arrays = {v.name: np.empty(layout.size, dtype=v.dtype)
                        for v in self._schema if v.values is None}
        self._attrs: dict[str, Any] = {}
        self._closed = False
        self.set_attrs(attrs or {})

    def set_attrs(self, attrs: Mapping[str, Any]) -> None:
        """Set global attributes, converted as the netCDF file stores them
        (:func:`sweep.store.schema.stored_attr`)."""
        self._attrs.update({key: stored_attr(value) for key, value in attrs.items()})

    def write(self, start: int, stop: int, arrays: Mapping[str, Any],
              points: Mapping[str, Any] | None = None) -> None:
        """Store the results of points ``start .. stop-1`` (flat C-order index).

        Parameters
        ----------
        start, stop : int
            Flat range of the chunk.
        arrays : dict of str -> ndarray
            One flat array of length ``stop - start`` per stored variable.
        points : dict of str -> ndarray, optional
            Per-point values (:attr:`sweep.store.layout.Layout.per_point`).

        Raises
        ------
        ValueError
            If an array has the wrong length, a value does not fit its stored type, or
            per-point values are missing; after :meth:`dataset`.
        """
        if self._arrays is None:
            raise ValueError("the dataset was already handed over; nothing can be written")
        for name, arr in chunk_values(self.layout, start, stop, arrays, points).items():
            buffer = self._arrays[name]
            buffer[start:stop] = cast_exactly(name, arr, buffer.dtype)

    def close(self) -> None:
        """Mark the dataset complete (idempotent)."""
        self._closed = True

    def dataset(self) -> Any:
        """The assembled dataset, decoded as ``xarray.open_dataset`` decodes the file.

        The writer hands its arrays over (no copy is kept): call it once, after
        :meth:`close`.

        Returns
        -------
        xarray.Dataset
            Loaded in memory (numpy-backed).

        Raises
        ------
        ValueError
            Before :meth:`close`, or a second time.
        """
        import xarray as xr

        if not self._closed or self._arrays is None:
            raise ValueError("the dataset is available once, after close()")
        shape = tuple(self.layout.shape)
        arrays, self._arrays = self._arrays, None
        raw = xr.Dataset(
            {var.name: xr.Variable(var.dims, var.values if var.values is not None
                                   else arrays.pop(var.name).reshape(shape), attrs=var.attrs)
             for var in self._schema}, attrs=self._attrs)
        decoded = xr.decode_cf(raw)
        del raw
        # Decoding is lazy: load one variable at a time, each raw buffer freed as its
        # decoded copy (if any) replaces it.
        return decoded.load()
