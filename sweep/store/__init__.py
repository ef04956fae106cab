"""Storage of sweep results: CF-annotated netCDF4 output, resumable partial state, atomic finish.

Life of an output ``OUT.nc``:

0. ``OUT.nc.lock`` is held (``flock``) by the one process writing ``OUT.nc`` and names it
   (PID, host); a second writer is refused before it touches anything.
1. ``OUT.nc.partial/`` holds ``manifest.json`` (hash of the configuration, package version,
   chunking) and one ``chunk_NNNNNNN.npz`` per finished chunk, each written to a temporary
   name and renamed, so a crash (Ctrl-C, ``kill -9``) never leaves a half-written chunk.
   Every chunk file records what it belongs to and a checksum of its values, verified on
   resume. These files are the source of truth for resuming (:mod:`sweep.store.partial`).
2. While the run goes on, chunks are also written, as they finish, into
   ``OUT.nc.partial/assembling.nc``: a netCDF4 file whose variables are created up front at
   their final size, so memory stays bounded whatever the design size
   (:mod:`sweep.store.netcdf`). An HDF5 file is not crash-safe, so a resumed run rebuilds
   it from the chunk files.
3. At the end the assembled file is fsync'ed and ``os.replace``'d onto ``OUT.nc`` (same
   directory, so the rename is atomic: ``OUT.nc`` is either absent, the previous file, or the
   complete new one), then the partial directory is removed.

Modules, one job each:

:mod:`~sweep.store.metadata`
    CF attributes and dtypes of coordinates and variables (:func:`variable_spec`).
:mod:`~sweep.store.layout`
    The runner-store contract: :class:`Layout`, :func:`flat_blocks`, the :class:`Writer`
    protocol.
:mod:`~sweep.store.schema`
    What a dataset holds whatever the backend: its variables as stored, the arrays of a
    chunk, stored attributes (shared by the two writers).
:mod:`~sweep.store.netcdf`
    :class:`NetCDFWriter`, storage chunking and compression, :func:`commit`.
:mod:`~sweep.store.memory`
    :class:`MemoryWriter`: the same dataset assembled in memory as an ``xarray.Dataset``
    (``sweep.run`` without ``out=``).
:mod:`~sweep.store.partial`
    :class:`PartialStore` (manifest, verified chunk files), :class:`OutputLock`,
    :class:`ResumeError`, :class:`LockError`, :func:`write_atomic` (a file complete or
    not at all, also for the reports).
:mod:`~sweep.store.summary`
    :func:`summarize` (``sweep info``), :func:`read_global_attrs`, :func:`check_readable`,
    :func:`open_dataset` (every reader of a dataset the user names).

This package re-exports their public names (``from sweep import store; store.X``). It is
floor 1: it may import numpy, netCDF4, xarray (lazily, in :mod:`~sweep.store.memory`) and
floor 0 (:mod:`sweep.registry`'s facts in :mod:`~sweep.store.metadata` only,
:mod:`sweep._format`'s number formats in :mod:`~sweep.store.summary` and its
:func:`~sweep._format.naming` in :mod:`~sweep.store.partial`); it knows nothing of numba,
the kernels, the api or how the values are computed.
"""
from __future__ import annotations

from sweep.store.layout import Layout, Writer, flat_blocks
from sweep.store.memory import MemoryWriter
from sweep.store.metadata import (CAVEAT_ATTRS, CONVENTIONS, MATERIAL_NAME, REPORT, SPACINGS,
                                  coordinate_attrs, index_dtype, law_units_attrs,
                                  variable_spec)
from sweep.store.netcdf import (CHUNK_CACHE_BYTES, COMPLEVEL, STORAGE_CHUNK, SUFFIXES,
                                NetCDFWriter, commit, same_file)
from sweep.store.partial import (CHUNK_FORMAT, MANIFEST_FORMAT, LockError, OutputLock,
                                 PartialStore, ResumeError, lock_path, partial_bytes,
                                 partial_dir, remove_untrusted, write_atomic)
from sweep.store.summary import check_readable, open_dataset, read_global_attrs, summarize

__all__ = [
    "Layout", "Writer", "variable_spec", "coordinate_attrs", "PartialStore", "ResumeError",
    "NetCDFWriter", "MemoryWriter", "commit", "read_global_attrs", "flat_blocks", "summarize",
    "partial_dir", "MANIFEST_FORMAT", "REPORT", "CHUNK_CACHE_BYTES", "STORAGE_CHUNK",
    "COMPLEVEL", "SUFFIXES", "CHUNK_FORMAT", "LockError", "OutputLock", "lock_path",
    "partial_bytes", "remove_untrusted", "CONVENTIONS", "SPACINGS", "index_dtype",
    "law_units_attrs", "MATERIAL_NAME", "check_readable", "open_dataset", "CAVEAT_ATTRS",
    "same_file", "write_atomic",
]
