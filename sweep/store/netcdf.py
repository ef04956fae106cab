"""The netCDF4 output backend and the atomic publication of a finished file.

Owns :class:`NetCDFWriter` (a :class:`sweep.store.layout.Writer`): variables are created up
at their final size when the first chunk arrives and filled chunk by chunk as chunks
finish, so memory stays bounded whatever the design size; the storage chunking, the
choice of compression per variable (:func:`deflate_filters`) and the HDF5 cache settings;
and :func:`commit`, the fsync + rename that makes the output appear atomically.

The file opens with a plain ``xarray.open_dataset``: grid designs have dimensions
(alpha, beta, gamma, gtilde) with coordinate variables, scattered designs a ``point``
dimension, indexed 0..n-1, with the four parameters as (point) coordinates, scenes the
dimensions (material, v0, F) with gamma and g~ as data variables on them, the materials'
properties on ``material`` (indexed 0..n-1) and their names the auxiliary coordinate
``material_name``. Attributes, fill values and storage dtypes come from
:mod:`sweep.store.metadata` and the layout's own (:attr:`~sweep.store.layout.Layout.attrs`).

What the file holds (variables, attributes as stored, the arrays of each chunk) comes from
:mod:`sweep.store.schema`, shared with the in-memory writer.

May import: numpy, netCDF4, :mod:`sweep.registry` and the store's own
:mod:`~sweep.store.layout` and :mod:`~sweep.store.schema`. Nothing of numba, the kernels or
any floor above the store.
"""
from __future__ import annotations

import contextlib
import os
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np

from sweep import registry
from sweep.store.layout import Layout, flat_blocks
from sweep.store.schema import (Variable, cast_exactly, chunk_values, dataset_variables,
                                stored_attr)

__all__ = ["NetCDFWriter", "commit", "same_file", "CHUNK_CACHE_BYTES", "STORAGE_CHUNK",
           "COMPLEVEL", "CHECKSUM", "SUFFIXES", "STORED", "deflate_filters"]

#: File name suffixes of the outputs this backend writes. Any other suffix is refused
#: rather than written as netCDF under a misleading name (``out.zarr`` would be HDF5).
SUFFIXES = (".nc", ".nc4", ".netcdf")

#: HDF5 chunk cache per variable. netCDF's default (64 MB) times ~20 variables would let the
#: cache alone exceed the memory budget of a large run; writes are sequential, so two
#: storage chunks (512 kB each) per variable suffice, and a small cache also makes HDF5
#: compress and write as it goes instead of all at close.
CHUNK_CACHE_BYTES = 2 ** 20
#: Target number of elements per storage chunk (512 kB of float64).
STORAGE_CHUNK = 2 ** 16
#: Every variable carries HDF5's Fletcher-32 checksum of each storage chunk, verified by
#: every reader as it reads, :func:`sweep.store.check_readable` included: zlib's own
#: check covers only compressed data, and the axes and constants are stored as they are.
CHECKSUM = True
#: zlib level: 1 is several times faster than the default 4 at a nearly equal ratio on
#: these (mostly incompressible float64) data; the shuffle filter does most of the gain.
COMPLEVEL = 1
#: Bytes of a variable's first chunk compressed on trial, in TRIAL_PIECES pieces spread
#: over it (a grid's first points may all lie in one corner of the parameter space).
TRIAL_BYTES = 2 ** 15
TRIAL_PIECES = 4
#: Fewer bytes than this do not show how the variable compresses (zlib's own overhead, a
#: small last chunk arriving first from a Dask cluster): such a trial keeps the default,
#: deflate with shuffle.
TRIAL_MIN_BYTES = 2 ** 12
#: createVariable's keywords for a variable stored as computed.
STORED = {"zlib": False, "shuffle": False}


def deflate_filters(values: np.ndarray, min_saving: float | None) -> dict:
    """createVariable's compression keywords for a variable holding data like ``values``.

    Deflate (level :data:`COMPLEVEL`) with HDF5's shuffle filter or without it, whichever
    compresses a trial of :data:`TRIAL_BYTES` of ``values`` smaller, or no compression
    where neither saves ``min_saving`` of those bytes (or ``min_saving`` is None); with
    shuffle where ``values`` hold less than :data:`TRIAL_MIN_BYTES`. Shuffle groups the
    bytes of equal significance (it wins on smooth coordinates and counts); without it,
    runs of exact zeros (the e of sticking points) compress better.

    Parameters
    ----------
    values : ndarray
        The variable's values in a first chunk (any shape; read in C order).
    min_saving : float or None
        Least fraction of the trial's bytes that deflate must save
        (:data:`sweep.registry.COMPRESSION`); None: stored as computed.

    Returns
    -------
    dict
        ``zlib``, ``shuffle`` and, with zlib, ``complevel``.
    """
    if min_saving is None:
        return dict(STORED)
    flat = np.ascontiguousarray(values).reshape(-1)
    size = flat.dtype.itemsize
    piece = max(1, TRIAL_BYTES // size // TRIAL_PIECES)
    starts = np.linspace(0, max(flat.size - piece, 0), TRIAL_PIECES).astype(int)
    # A mask, not np.unique of the pieces' indices (they overlap in a short chunk): that
    # took 0.6 ms a variable, 12 ms of a run's first chunk in the writer's thread.
    taken = np.zeros(flat.size, dtype=bool)
    for s in starts:
        taken[s:s + piece] = True
    raw = flat[taken].view(np.uint8)
    if raw.size < TRIAL_MIN_BYTES:
        return {"zlib": True, "complevel": COMPLEVEL, "shuffle": size > 1}
    plain = len(zlib.compress(raw.tobytes(), COMPLEVEL))
    shuffled = len(zlib.compress(raw.reshape(-1, size).T.tobytes(), COMPLEVEL))
    if min(plain, shuffled) > (1 - min_saving) * raw.size:
        return dict(STORED)
    return {"zlib": True, "complevel": COMPLEVEL, "shuffle": shuffled < plain}


def _storage_chunks(shape: tuple) -> tuple:
    """Storage chunk shape of about STORAGE_CHUNK elements, filled from the fastest axis
    so that chunk writes (flat ranges in C order) touch few storage chunks."""
    chunks = []
    budget = STORAGE_CHUNK
    for n in reversed(shape):
        c = max(1, min(n, budget))
        chunks.append(c)
        budget = max(1, budget // c)
    return tuple(reversed(chunks))


class NetCDFWriter:
    """Write a sweep's variables into a netCDF4 file, chunk by chunk, as chunks finish.

    Parameters
    ----------
    path : path-like
        File to create (overwritten).
    layout : Layout
    variables : sequence of str
        Names of the stored variables (see :func:`sweep.store.metadata.variable_spec`).
    attrs : dict
        Global attributes known at the start (more can be set before :meth:`close`).
    compress : str
        A choice of :data:`sweep.registry.COMPRESSION`: deflate each computed variable
        where a trial on its first chunk saves that choice's share of its bytes
        (:func:`deflate_filters`); "none": every variable stored as computed. The zlib
        work runs in the writing thread, which bounds a run on many cores.
    """

    def __init__(self, path: str | os.PathLike, layout: Layout, variables: Sequence[str],
                 attrs: Mapping[str, Any] | None = None,
                 compress: str = registry.DEFAULT_COMPRESSION) -> None:
        if compress not in registry.COMPRESSION:
            raise ValueError(f"compress must be one of {', '.join(registry.COMPRESSION)}, "
                             f"got {compress!r}")
        self.path = Path(path)
        self.layout = layout
        self.variables = tuple(variables)
        self.min_saving = registry.COMPRESSION[compress]
        # netCDF reports any failure to create a file as EACCES, "Permission denied" (no
        # free inode included): create it here, where the OSError carries the system's own
        # errno and the file's name; netCDF then overwrites the empty file.
        with open(self.path, "wb"):
            pass
        self._nc = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        # No pre-fill pass: every element is written. _FillValue attributes still apply.
        self._nc.set_fill_off()
        try:
            self._define(attrs or {})
        except BaseException:
            close_once(self._nc)
            raise

    def _create(self, var: Variable, chunks: tuple, filters: dict) -> None:
        """A variable filled chunk by chunk: in storage chunks, compressed by ``filters``
        (:func:`deflate_filters`)."""
        attrs = dict(var.attrs)
        # _FillValue must be set when the variable is created; False: no _FillValue.
        fill = attrs.pop("_FillValue", False)
        nc_var = self._nc.createVariable(var.name, var.dtype, var.dims, **filters,
                                         fletcher32=CHECKSUM, chunksizes=chunks,
                                         fill_value=fill)
        nc_var.set_var_chunk_cache(size=CHUNK_CACHE_BYTES)
        nc_var.set_auto_maskandscale(False)
        nc_var.setncatts(attrs)

    def _create_deferred(self, values: Mapping[str, np.ndarray]) -> None:
        """Create the computed variables, in their order, each compressed as suits its
        ``values`` (a first chunk's; without them, deflate with shuffle)."""
        deferred, self._deferred = self._deferred, []
        for var in deferred:
            sample = values.get(var.name, np.empty(0, var.dtype))
            filters = deflate_filters(sample, self.min_saving)
            self._create(var, self._chunks, filters)

    def _constant(self, var: Variable) -> None:
        """A variable written once, here: an axis or a constant of the layout."""
        for dim, n in zip(var.dims, var.values.shape):
            if dim not in self._nc.dimensions:   # the string length of names (a label)
                self._nc.createDimension(dim, n)
        nc_var = self._nc.createVariable(var.name, var.dtype, var.dims, fill_value=False,
                                         fletcher32=CHECKSUM)
        nc_var[...] = var.values   # before _Encoding: the characters are stored as given
        nc_var.setncatts(var.attrs)

    def _define(self, attrs):
        nc, lay = self._nc, self.layout
        nc.set_auto_maskandscale(False)
        for dim, n in zip(lay.dims, lay.shape):
            nc.createDimension(dim, n)
        self._chunks = _storage_chunks(lay.shape)
        # The computed variables are created at the first write, when their compression
        # can be chosen from data (netCDF-4 files take new variables at any time).
        self._deferred = []
        for var in dataset_variables(lay, self.variables):
            if var.values is not None:
                self._constant(var)
            else:
                self._deferred.append(var)
        self._dtypes = {var.name: var.dtype for var in self._deferred}
        self.set_attrs(attrs)

    def set_attrs(self, attrs: Mapping[str, Any]) -> None:
        """Set global attributes (None values are stored as the string "default").

        Parameters
        ----------
        attrs : mapping of str -> value
            netCDF has no boolean or null attribute: booleans are stored as 0 / 1.
        """
        for key, value in attrs.items():
            self._nc.setncattr(key, stored_attr(value))

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
            Per-point values: coordinates of scattered designs, a scene's gamma and g~
            (:attr:`Layout.per_point`).

        Raises
        ------
        ValueError
            If an array has the wrong length, or per-point coordinates are missing.
        """
        values = {name: cast_exactly(name, arr, self._dtypes[name])  # booleans -> flags
                  for name, arr in chunk_values(self.layout, start, stop, arrays,
                                                points).items()}
        if self._deferred:
            self._create_deferred(values)
        for name, arr in values.items():
            var = self._nc.variables[name]
            for sl, lo, hi in flat_blocks(self.layout.shape, start, stop):
                block = arr[lo - start:hi - start]
                var[sl] = block.reshape(tuple(s.stop - s.start for s in sl))

    def close(self) -> None:
        """Close the file (idempotent, also after a failed close, e.g. on a full disk)."""
        nc = self._nc
        try:
            if nc is not None and nc.isopen():
                self._create_deferred({})   # a file no chunk was written into
        finally:
            self._nc = None
            if nc is not None and nc.isopen():
                close_once(nc)


def close_once(nc: Any) -> None:
    """Close the netCDF4 Dataset ``nc`` for good, re-raising a failed close's error.

    A close that fails (a full disk: HDF5 cannot flush) leaves netCDF4's Dataset open,
    and netCDF4 closes it again when the object is garbage-collected: at any later moment,
    in whatever thread the collection runs, into an HDF5 library that is not thread-safe
    (a segfault in the next run's writer thread, mid-write). netCDF4's own unchecked close,
    the one its collection would make, is made here instead, at once.
    """
    if not nc.isopen():
        return
    try:
        nc.close()
    except BaseException:
        if nc.isopen():
            with contextlib.suppress(Exception):
                nc._close(False)
        raise


def _fsync_path(path, directory=False):
    flags = os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0)
    try:
        fd = os.open(path, flags)
    except OSError:  # pragma: no cover - platforms that cannot open directories
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """``a`` and ``b`` name one file (through links too), or one path where either is
    missing: an output that would be written over its own input."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # either is missing: only the same path can be the same file
        return Path(a).resolve() == Path(b).resolve()


def commit(tmp: str | os.PathLike, final: str | os.PathLike) -> None:
    """Atomically publish the finished file ``tmp`` as ``final`` (same file system).

    The data are fsync'ed before the rename and the directory after it, so that after a
    crash ``final`` is either the old file or the complete new one, never a partial file.

    Parameters
    ----------
    tmp : path-like
        The complete, closed file.
    final : path-like
        Where it is published (replaced if it exists).
    """
    tmp, final = Path(tmp), Path(final)
    _fsync_path(tmp)
    os.replace(tmp, final)
    _fsync_path(final.parent, directory=True)
