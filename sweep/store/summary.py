"""Reading a finished dataset back: the ``sweep info`` summary and the global attributes.

Owns :func:`summarize` (dimensions, coordinates, variables with summary statistics and
settings, read in bounded pieces so a file of any size can be described),
:func:`read_global_attrs` and :func:`check_readable` (how the runner recognises an
existing output, and proves it intact) and :func:`open_dataset` (how every reader of a
dataset given by the user opens it: export, lookup tables, the accuracy report).

May import: numpy, netCDF4, xarray (inside :func:`open_dataset`), the store's own
:mod:`~sweep.store.layout` and :mod:`~sweep.store.metadata`, and :mod:`sweep._format`
(floor 0). Nothing of numba, the kernels or any floor above the store.
"""
from __future__ import annotations

import contextlib
import errno
import math
import os
from collections.abc import Iterator
from typing import Any

import netCDF4
import numpy as np

from sweep._format import count
from sweep.store.layout import flat_blocks
from sweep.store.metadata import CAVEAT_ATTRS, variable_spec

__all__ = ["summarize", "read_global_attrs", "check_readable", "open_dataset"]

#: How a netCDF file begins: classic (CDF1, CDF2, CDF5) or netCDF-4, which is HDF5 (whose
#: signature may also follow a user block of 512 bytes times a power of two).
_CLASSIC_MAGIC = (b"CDF\x01", b"CDF\x02", b"CDF\x05")
_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"

#: Global attributes listed under "settings" by :func:`summarize` (prefixes).
_SETTINGS = ("integrator_", "options_", "design", "chunk_size", "n_points", "sweep_version",
             "numba_version", "numpy_version", "numerical_stack", "run_time", "compute_time",
             "points_per_second", "date_created", "sweep_config_sha256", "sweep_command",
             "compile_time", "kernel_time", "numba_num_threads", "numba_threading_layer",
             "executor", *CAVEAT_ATTRS)


@contextlib.contextmanager
def _reading(path: str | os.PathLike) -> Iterator[None]:
    """netCDF's error for a damaged file as an OSError naming it.

    netCDF4 raises what HDF5 finds wrong (a checksum that fails, a header overwritten) as
    a RuntimeError, "NetCDF: HDF error", which names no file; as an OSError it is what
    callers already report as "cannot read FILE: ..." (errno EIO: the data are bad).
    """
    try:
        yield
    except RuntimeError as exc:
        raise OSError(errno.EIO, str(exc), os.fspath(path)) from exc


def _looks_like_netcdf(path: str | os.PathLike) -> bool:
    """The file begins as a netCDF file does (classic or HDF5 signature)."""
    try:
        with open(path, "rb") as f:
            if f.read(4) in _CLASSIC_MAGIC:
                return True
            offset, size = 0, os.fstat(f.fileno()).st_size
            while offset + len(_HDF5_MAGIC) <= size:
                f.seek(offset)
                if f.read(len(_HDF5_MAGIC)) == _HDF5_MAGIC:
                    return True
                offset = 512 if offset == 0 else 2 * offset
    except OSError:         # a directory, or unreadable: no netCDF file either way
        pass
    return False


def _read_error(path: str | os.PathLike, exc: OSError) -> OSError:
    """``exc`` as one line a user can read: the file named as given (xarray names it by its
    absolute path), and "not a netCDF file" where the library failed (a negative errno) on
    a file without a netCDF signature: it says "Unknown file format" or, depending on what
    it read before, "HDF error"."""
    cause = exc.strerror or str(exc)
    if exc.errno is not None and exc.errno < 0 and not _looks_like_netcdf(path):
        cause = "not a netCDF file"
    return OSError(exc.errno, cause, os.fspath(path))


def _open_nc(path: str | os.PathLike) -> netCDF4.Dataset:
    try:
        return netCDF4.Dataset(path, "r")
    except OSError as exc:
        raise _read_error(path, exc) from None


def open_dataset(path: str | os.PathLike) -> Any:
    """Open a netCDF dataset for reading, lazily, as ``xarray.open_dataset`` does.

    The one place a dataset the user names is opened: a file that is not netCDF is
    refused in one line (xarray's own message spans three, with URLs about IO backends).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    xarray.Dataset
        Open on the file: close it, or use it in a ``with`` block.

    Raises
    ------
    OSError
        The file cannot be read, or is not netCDF: ``filename`` is ``path`` as given,
        ``strerror`` the cause (``"not a netCDF file"``).
    """
    import xarray as xr

    try:
        # netcdf4, not xarray's guess among backends: the files are netCDF (4 or classic),
        # and the library's own error tells a non-netCDF file from a missing one.
        return xr.open_dataset(path, engine="netcdf4")
    except OSError as exc:
        raise _read_error(path, exc) from None


def read_global_attrs(path: str | os.PathLike) -> dict[str, Any] | None:
    """Global attributes of a netCDF file, or None if it is not a readable netCDF file.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    dict or None
    """
    try:
        with _reading(path), _open_nc(path) as nc:
            return {k: nc.getncattr(k) for k in nc.ncattrs()}
    except OSError:
        return None


def check_readable(path: str | os.PathLike) -> None:
    """Read every value of a netCDF file, in bounded pieces, to prove it is intact.

    Reading is the check: HDF5 verifies each storage chunk as it decodes it (zlib's
    Adler-32 of the compressed ones, a Fletcher-32 checksum where the file has one), so
    bytes overwritten in a finished file fail here. Its size cannot tell (an overwrite
    keeps it), and a checksum of the values recorded at the finish would need this same
    full read to be verified. The cost is one decompression pass over the file.

    Parameters
    ----------
    path : path-like

    Raises
    ------
    OSError
        The file cannot be opened or a value cannot be read; ``filename`` is ``path``.
    """
    with _reading(path), _open_nc(path) as nc:
        nc.set_auto_maskandscale(False)
        for var in nc.variables.values():
            for _ in _iter_flat(var, var.shape):
                pass


def _iter_flat(var, shape, block=2 ** 22) -> Iterator[np.ndarray]:
    """Read a variable in flat C-order pieces of at most ``block`` elements."""
    size = math.prod(shape)
    for s in range(0, size, block):
        e = min(s + block, size)
        for sl, lo, hi in flat_blocks(shape, s, e):
            yield np.asarray(var[sl]).reshape(-1)


def summarize(path: str | os.PathLike) -> str:
    """Human-readable description of an output file.

    Parameters
    ----------
    path : path-like
        A dataset written by ``sweep run``.

    Returns
    -------
    str
        Dimensions, coordinates with their ranges, variables with summary statistics, and
        settings, one item per line. The data are read in bounded pieces.

    Raises
    ------
    OSError
        If the file cannot be read as netCDF, or is damaged (``filename`` is ``path``).
    ValueError
        If it is a netCDF file but not a sweep output.
    """
    lines = []
    with _reading(path), _open_nc(path) as nc:
        nc.set_auto_maskandscale(False)
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
        _require_sweep_output(path, attrs)
        lines.append(f"{path}: {attrs.get('title', '')}")
        # The data's dimensions: not the string length of a label (material_name_strlen)
        chars = {v.dimensions[-1] for v in nc.variables.values() if v.dtype == np.dtype("S1")}
        dims = {d: len(nc.dimensions[d]) for d in nc.dimensions if d not in chars}
        lines.append("dimensions: " + ", ".join(f"{d} = {n}" for d, n in dims.items())
                     + f"  ({count(math.prod(dims.values()), 'point')})")
        coord_names = _coordinate_names(nc, dims)
        lines.append("coordinates:")
        width = max([8] + [len(name) for name in coord_names])
        lines += [_coordinate_line(name, nc.variables[name], width) for name in coord_names]
        lines.append("variables:")
        for name, var in nc.variables.items():
            if name in coord_names or name in dims:   # an index (point, material): see dims
                continue
            lines.append(f"  {name:<20} {var.getncattr('long_name')}")
            lines.append("      " + _stats(name, var))
        lines.append("settings:")
        lines += [f"  {key} = {attrs[key]}" for key in sorted(attrs)
                  if key.startswith(_SETTINGS)]
    return "\n".join(lines)


def _is_names(var) -> bool:
    """Names: a CF label (characters, read back as strings), or a netCDF-4 string in files
    written before material_name."""
    return var.dtype is str or var.dtype == np.dtype("S1")


def _is_index(var) -> bool:
    """An integer index 0..n-1 (of a design's points, of a scene's materials)."""
    return not _is_names(var) and var.dtype.kind in "iu"


def _coordinate_names(nc, dims) -> list[str]:
    """The coordinates :func:`summarize` lists: those of the dimensions (a scene's v0, F),
    the names of a scene's materials (not their index, nor a design's point index: the
    dimension line tells those), then the scaled parameters."""
    names = [n for n in dims if n in nc.variables and not _is_index(nc.variables[n])]
    # Files written before material_name held the names in the material coordinate.
    labels = [n for n, v in nc.variables.items() if _is_names(v) and n not in names]
    params = [n for n in ("alpha", "beta", "gamma", "gtilde")
              if n in nc.variables and n not in dims]
    return labels + names + params


def _require_sweep_output(path, attrs):
    """Refuse, naming what is missing, a netCDF file that ``sweep run`` did not write."""
    if "sweep_version" not in attrs:
        raise ValueError(f"{path} is a netCDF file but not a sweep output (no "
                         "sweep_version global attribute)")


def _coordinate_line(name, var, width=8):
    if _is_names(var):  # a scene's material_name
        return f"  {name:<{width}} {', '.join(var[:])}  {var.getncattr('long_name')}"
    lo, hi = math.inf, -math.inf
    for block in _iter_flat(var, var.shape):
        lo, hi = min(lo, float(block.min())), max(hi, float(block.max()))
    # One value (a size-1 axis, or a parameter a design of experiments fixes) is shown once.
    values = f"= {lo:.6g}" if lo == hi else f"[{lo:.6g}, {hi:.6g}]"
    if "spacing" in var.ncattrs() and lo != hi:
        values += f" ({var.getncattr('spacing')})"
    return f"  {name:<{width}} {values}  {var.getncattr('long_name')}"


def _stats(name, var):
    try:
        attrs = variable_spec(name)[1]
    except KeyError:
        attrs = {}
    if "flag_values" in attrs:
        return _flag_stats(attrs, var)
    return _value_stats(name, var)


def _flag_stats(attrs, var):
    # The codes come from variable_spec, the store's one source of them, so the summary
    # cannot drift from what the writer declares in flag_values / flag_meanings.
    values = np.asarray(attrs["flag_values"], dtype=np.int64)
    size = int(values.max()) + 1
    counts = np.zeros(size, dtype=np.int64)
    for block in _iter_flat(var, var.shape):
        counts += np.bincount(block.astype(np.int64), minlength=size)[:size]
    return ", ".join(f"{meaning}: {c}"
                     for meaning, c in zip(attrs["flag_meanings"].split(), counts[values]))


def _value_stats(name, var):
    """min, mean and max of a variable; NaN and infinite values counted apart: an inf is a
    value (t_f where the bead creeps for ever), in min / max but not in the mean."""
    n = nan = inf = 0
    lo, hi, total, amax = math.inf, -math.inf, 0.0, 0.0
    for block in _iter_flat(var, var.shape):
        block = block.astype(np.float64)
        n += block.size
        values = block[~np.isnan(block)]
        nan += block.size - values.size
        finite = values[np.isfinite(values)]
        inf += values.size - finite.size
        if values.size:
            lo, hi = min(lo, float(values.min())), max(hi, float(values.max()))
            total += float(finite.sum())
            amax = max(amax, float(np.abs(values).max()))
    if not n - nan:
        return f"all {n} values NaN" if n else "no values"
    mean = f"{total / (n - nan - inf):.6g}" if n - nan - inf else "-"
    text = f"min {lo:.6g}, mean {mean}, max {hi:.6g}, NaN {nan} of {n}"
    if inf:
        text += f", infinite {inf} (not in the mean)"
    if name.startswith("error_"):
        text += f", max |error| {amax:.3g}"
    return text
