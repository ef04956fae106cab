"""Storage of sweep results: CF-annotated netCDF4 output, resumable partial state, atomic finish.

Life of an output ``OUT.nc``:

1. ``OUT.nc.partial/`` holds ``manifest.json`` (hash of the configuration, package version,
   chunking) and one ``chunk_NNNNNNN.npz`` per finished chunk, each written to a temporary
   name and renamed, so a crash (Ctrl-C, ``kill -9``) never leaves a half-written chunk.
   These files are the source of truth for resuming.
2. While the run goes on, chunks are also written, as they finish, into
   ``OUT.nc.partial/assembling.nc``: a netCDF4 file whose variables are created up front at
   their final size, so memory stays bounded whatever the design size. An HDF5 file is not
   crash-safe, so a resumed run rebuilds it from the chunk files.
3. At the end the assembled file is fsync'ed and ``os.replace``'d onto ``OUT.nc`` (same
   directory, so the rename is atomic: ``OUT.nc`` is either absent, the previous file, or the
   complete new one), then the partial directory is removed.

The file opens with a plain ``xarray.open_dataset``: grid designs have dimensions
(alpha, beta, gamma, gtilde) with coordinate variables, scattered designs a ``point``
dimension with the four parameters as (point) coordinates. Every variable carries
``long_name``, ``units`` ("1": all quantities are dimensionless, scaled by eq. (2) of the
report) and a ``description`` citing the report's equation.

This module knows nothing of numba or of how the values are computed.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import shutil
from pathlib import Path

import netCDF4
import numpy as np

from sweep.model import Status

__all__ = [
    "Layout", "variable_spec", "coordinate_attrs", "PartialStore", "ResumeError",
    "NetCDFWriter", "commit", "read_global_attrs", "flat_blocks", "summarize",
    "partial_dir", "MANIFEST_FORMAT",
]

MANIFEST_FORMAT = "sweep-partial/1"
REPORT = ("A. Chatterjee, G. James, B. Brogliato, Approximate analytical coefficient of "
          "restitution formulation for single bead impact with external load, using "
          "nonlinear visco-elastic models, INRIA hal-03462750 (2021)")

#: HDF5 chunk cache per variable. netCDF's default (64 MB) times ~20 variables would let the
#: cache alone exceed the memory budget of a large run; writes are sequential, so two
#: storage chunks (512 kB each) per variable suffice, and a small cache also makes HDF5
#: compress and write as it goes instead of all at close.
CHUNK_CACHE_BYTES = 2 ** 20
#: Target number of elements per storage chunk (512 kB of float64).
STORAGE_CHUNK = 2 ** 16
#: zlib level: 1 is several times faster than the default 4 at a nearly equal ratio on
#: these (mostly incompressible float64) data; the shuffle filter does most of the gain.
COMPLEVEL = 1


# --------------------------------------------------------------------------- metadata

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


def variable_spec(name):
    """dtype and CF attributes of a stored variable.

    Returns
    -------
    dtype : numpy dtype
    attrs : dict
        ``long_name``, ``units``, ``description`` and, for flags, ``flag_values`` /
        ``flag_meanings``.
    """
    if name.startswith("e_") and name[2:] in _METHODS:
        long_name, desc = _METHODS[name[2:]]
        return np.dtype(np.float64), {"long_name": long_name, "units": "1",
                                      "description": desc}
    if name.startswith("error_") and name[6:] in _METHODS:
        m = name[6:]
        long_name, desc = _METHODS[m]
        return np.dtype(np.float64), {
            "long_name": f"error of the {long_name.split(', ', 1)[1]}",
            "units": "1",
            "description": f"e_{m} - e_numeric: the approximation ({desc}) minus the "
                           "numerical CoR (report eq. (3), Algorithm 1)"}
    if name in _FIELDS:
        long_name, dtype, desc = _FIELDS[name]
        attrs = {"long_name": long_name, "units": "1", "description": desc}
        if name == "status":
            attrs["flag_values"] = np.array([s.value for s in Status], dtype=np.int8)
            attrs["flag_meanings"] = " ".join(s.name.lower() for s in Status)
        return np.dtype(dtype), attrs
    raise KeyError(f"unknown output variable {name!r}")


def coordinate_attrs(name):
    long_name, desc = _COORDS[name]
    return {"long_name": long_name, "units": "1", "description": desc}


@dataclasses.dataclass(frozen=True)
class Layout:
    """Shape of the stored data.

    Attributes
    ----------
    dims, shape : tuple
        Dimensions of every data variable, C order over the flat point index.
    axes : dict
        Coordinate variable per dimension (grid designs); empty for scattered designs.
    point_coords : tuple of str
        Coordinates stored per point along the single dimension (scattered designs).
    """

    dims: tuple
    shape: tuple
    axes: dict
    point_coords: tuple = ()

    @property
    def size(self):
        return math.prod(self.shape)


def flat_blocks(shape, start, stop):
    """Cover the C-order flat range ``[start, stop)`` of an array by hyper-rectangles.

    Yields
    ------
    (tuple of slice, int, int)
        Index of one block and the flat range ``[lo, hi)`` it covers; at most
        ``2 len(shape) - 1`` blocks, in flat order.
    """
    if start >= stop:
        return
    if len(shape) == 1:
        yield (slice(start, stop),), start, stop
        return
    inner = math.prod(shape[1:])
    i0, r0 = divmod(start, inner)
    i1, r1 = divmod(stop, inner)
    if i0 == i1:
        for sl, lo, hi in flat_blocks(shape[1:], r0, r1):
            yield (slice(i0, i0 + 1),) + sl, i0 * inner + lo, i0 * inner + hi
        return
    if r0:
        for sl, lo, hi in flat_blocks(shape[1:], r0, inner):
            yield (slice(i0, i0 + 1),) + sl, i0 * inner + lo, i0 * inner + hi
        i0 += 1
    if i1 > i0:
        yield (slice(i0, i1),) + tuple(slice(0, n) for n in shape[1:]), i0 * inner, i1 * inner
    if r1:
        for sl, lo, hi in flat_blocks(shape[1:], 0, r1):
            yield (slice(i1, i1 + 1),) + sl, i1 * inner + lo, i1 * inner + hi


def _storage_chunks(shape):
    """Storage chunk shape of about STORAGE_CHUNK elements, filled from the fastest axis
    so that chunk writes (flat ranges in C order) touch few storage chunks."""
    chunks = []
    budget = STORAGE_CHUNK
    for n in reversed(shape):
        c = max(1, min(n, budget))
        chunks.append(c)
        budget = max(1, budget // c)
    return tuple(reversed(chunks))


# --------------------------------------------------------------------------- netCDF writer

class NetCDFWriter:
    """Write a sweep's variables into a netCDF4 file, chunk by chunk, as chunks finish.

    Parameters
    ----------
    path : path-like
        File to create (overwritten).
    layout : Layout
    variables : sequence of str
        Names of the stored variables (see :func:`variable_spec`).
    attrs : dict
        Global attributes known at the start (more can be set before :meth:`close`).
    """

    def __init__(self, path, layout, variables, attrs=None):
        self.path = Path(path)
        self.layout = layout
        self.variables = tuple(variables)
        self._nc = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        try:
            self._define(attrs or {})
        except BaseException:
            self._nc.close()
            raise

    def _create(self, name, dtype, dims, chunks):
        nc_dtype = np.int8 if dtype == np.bool_ else dtype
        # fill_value=False: no pre-fill pass (every element is written) and no _FillValue
        # attribute, so xarray reads the values back exactly (NaN means an invalid point).
        var = self._nc.createVariable(name, nc_dtype, dims, zlib=True, complevel=COMPLEVEL,
                                      shuffle=True, chunksizes=chunks, fill_value=False)
        var.set_var_chunk_cache(size=CHUNK_CACHE_BYTES)
        var.set_auto_maskandscale(False)
        return var

    def _define(self, attrs):
        nc, lay = self._nc, self.layout
        nc.set_auto_maskandscale(False)
        for dim, n in zip(lay.dims, lay.shape):
            nc.createDimension(dim, n)
        chunks = _storage_chunks(lay.shape)
        for name, values in lay.axes.items():
            var = nc.createVariable(name, np.float64, (name,), fill_value=False)
            var.setncatts(coordinate_attrs(name))
            var[:] = np.asarray(values, dtype=np.float64)
        for name in lay.point_coords:
            var = self._create(name, np.dtype(np.float64), lay.dims, chunks)
            var.setncatts(coordinate_attrs(name))
        for name in self.variables:
            dtype, vattrs = variable_spec(name)
            var = self._create(name, dtype, lay.dims, chunks)
            if dtype == np.bool_:
                vattrs = dict(vattrs, dtype="bool")  # xarray decodes int8 + this to bool
            if lay.point_coords:
                vattrs = dict(vattrs, coordinates=" ".join(lay.point_coords))
            var.setncatts(vattrs)
        self.set_attrs(attrs)

    def set_attrs(self, attrs):
        """Set global attributes (None values are stored as the string "default")."""
        for key, value in attrs.items():
            if value is None:
                value = "default"
            elif isinstance(value, bool):
                value = int(value)
            self._nc.setncattr(key, value)

    def write(self, start, stop, arrays, points=None):
        """Store the results of points ``start .. stop-1`` (flat C-order index).

        Parameters
        ----------
        arrays : dict of str -> ndarray
            One flat array of length ``stop - start`` per stored variable.
        points : dict of str -> ndarray, optional
            Per-point coordinates (scattered designs).
        """
        todo = dict(arrays)
        if self.layout.point_coords:
            if points is None:
                raise ValueError("per-point coordinates are required for this layout")
            todo.update({k: points[k] for k in self.layout.point_coords})
        for name, arr in todo.items():
            var = self._nc.variables[name]
            arr = np.asarray(arr)
            if arr.shape != (stop - start,):
                raise ValueError(f"{name}: expected {stop - start} values, got {arr.shape}")
            if arr.dtype == np.bool_:
                arr = arr.view(np.int8)
            for sl, lo, hi in flat_blocks(self.layout.shape, start, stop):
                block = arr[lo - start:hi - start]
                var[sl] = block.reshape(tuple(s.stop - s.start for s in sl))

    def close(self):
        if self._nc is not None and self._nc.isopen():
            self._nc.close()
        self._nc = None


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


def commit(tmp, final):
    """Atomically publish the finished file ``tmp`` as ``final`` (same file system).

    The data are fsync'ed before the rename and the directory after it, so that after a
    crash ``final`` is either the old file or the complete new one, never a partial file.
    """
    tmp, final = Path(tmp), Path(final)
    _fsync_path(tmp)
    os.replace(tmp, final)
    _fsync_path(final.parent, directory=True)


def read_global_attrs(path):
    """Global attributes of a netCDF file, or None if it is not a readable netCDF file."""
    try:
        with netCDF4.Dataset(path, "r") as nc:
            return {k: nc.getncattr(k) for k in nc.ncattrs()}
    except OSError:
        return None


# --------------------------------------------------------------------------- partial state

class ResumeError(RuntimeError):
    """Existing partial results cannot be resumed with the current configuration."""


def partial_dir(output):
    output = Path(output)
    return output.with_name(output.name + ".partial")


class PartialStore:
    """The resumable state of one output: manifest plus one ``.npz`` per finished chunk.

    Parameters
    ----------
    output : path-like
        The final output path ``OUT.nc``; the state lives in ``OUT.nc.partial/``.
    manifest : dict
        What the results depend on (configuration hash, package version, chunking,
        variables). A resume with a different manifest is refused.
    """

    def __init__(self, output, manifest):
        self.output = Path(output)
        self.dir = partial_dir(self.output)
        self.manifest = dict(manifest, format=MANIFEST_FORMAT)
        self._lock = None

    # The manifest keys whose mismatch refuses a resume, with a human description.
    _CHECKED = {
        "config_sha256": "configuration",
        "sweep_version": "sweep version",
        "sweep_source_sha256": "sweep source code (the package was edited or reinstalled)",
        "output": "output file name",
        "n_points": "number of design points",
        "chunk_size": "chunk size",
        "variables": "stored variables",
        "format": "partial-state format",
    }

    @property
    def assembling(self):
        """Path of the netCDF file being assembled (renamed onto the output at the end)."""
        return self.dir / "assembling.nc"

    def open(self, restart=False):
        """Create or reopen the partial state; return the set of finished chunk indices.

        Raises
        ------
        ResumeError
            If the existing state was made by a different configuration, version or
            chunking (unless ``restart``), or another process is writing it.
        """
        if restart and self.dir.exists():
            shutil.rmtree(self.dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self._acquire_lock()
        path = self.dir / "manifest.json"
        if path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, ValueError):
                old = None
            if old is None:
                raise ResumeError(f"{path} is unreadable; rerun with --restart to discard "
                                  f"the partial results in {self.dir}")
            for key, what in self._CHECKED.items():
                if old.get(key) != self.manifest.get(key):
                    raise ResumeError(
                        f"cannot resume {self.output}: the partial results in {self.dir} "
                        f"were computed with a different {what} ({key}: "
                        f"{_short(old.get(key))} there, {_short(self.manifest.get(key))} now). "
                        "Rerun with the original configuration, or with --restart to discard "
                        "them.")
        else:
            self._write_atomic(path, json.dumps(self.manifest, indent=1).encode())
        # Leftovers of a crashed run: a half-assembled netCDF file and temporary chunks.
        for p in self.dir.glob("*.tmp*"):
            p.unlink()
        if self.assembling.exists():
            self.assembling.unlink()
        return self.finished()

    def _acquire_lock(self):
        try:
            import fcntl
        except ImportError:  # pragma: no cover - Windows: no protection
            return
        fh = open(self.dir / "lock", "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            raise ResumeError(f"another sweep process is writing {self.output} "
                              f"(lock held on {self.dir / 'lock'})") from None
        self._lock = fh

    def release(self):
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def _chunk_path(self, index):
        return self.dir / f"chunk_{index:07d}.npz"

    def finished(self):
        """Indices of the chunks whose results are saved."""
        done = set()
        for p in self.dir.glob("chunk_*.npz"):
            try:
                done.add(int(p.stem.split("_")[1]))
            except (IndexError, ValueError):
                continue
        return done

    @staticmethod
    def _write_atomic(path, data_or_writer):
        tmp = path.with_name(path.name + f".tmp{os.getpid()}")
        with open(tmp, "wb") as fh:
            if callable(data_or_writer):
                data_or_writer(fh)
            else:
                fh.write(data_or_writer)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)

    def save_chunk(self, index, start, stop, arrays, times):
        """Save a finished chunk atomically (a crash leaves it absent or complete).

        ``times`` is a pair of durations [s] kept with the chunk (wall and kernel time), so
        that a resumed run still reports the time the whole dataset took.
        """
        payload = {name: np.asarray(a) for name, a in arrays.items()}
        payload["__bounds__"] = np.array([start, stop], dtype=np.int64)
        payload["__times__"] = np.array(times, dtype=np.float64).reshape(2)
        self._write_atomic(self._chunk_path(index), lambda fh: np.savez(fh, **payload))

    def load_chunk(self, index, start, stop):
        """Load a finished chunk, or return None if its file is missing or damaged.

        Returns
        -------
        (dict, (float, float)) or None
            The arrays by variable name and the chunk's ``times`` (see :meth:`save_chunk`).
        """
        path = self._chunk_path(index)
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (OSError, ValueError, EOFError, KeyError):
            return None
        bounds = data.pop("__bounds__", None)
        times = data.pop("__times__", None)
        if (bounds is None or times is None or list(bounds) != [start, stop]
                or set(data) != set(self.manifest["variables"])
                or any(a.shape != (stop - start,) for a in data.values())):
            return None
        return data, (float(times[0]), float(times[1]))

    def discard_chunk(self, index):
        with contextlib.suppress(FileNotFoundError):
            self._chunk_path(index).unlink()

    def remove(self):
        """Delete the partial state (after a successful commit)."""
        self.release()
        shutil.rmtree(self.dir, ignore_errors=True)


def _short(value):
    s = repr(value)
    return s if len(s) <= 80 else s[:77] + "..."


# --------------------------------------------------------------------------- summaries

def _iter_flat(var, shape, block=2 ** 22):
    """Read a variable in flat C-order pieces of at most ``block`` elements."""
    size = math.prod(shape)
    for s in range(0, size, block):
        e = min(s + block, size)
        for sl, lo, hi in flat_blocks(shape, s, e):
            yield np.asarray(var[sl]).reshape(-1)


def summarize(path):
    """Human-readable description of an output file: dimensions, coordinates, variables
    with summary statistics, settings. Reads the data in bounded pieces.
    """
    lines = []
    with netCDF4.Dataset(path, "r") as nc:
        nc.set_auto_maskandscale(False)
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
        lines.append(f"{path}: {attrs.get('title', '')}")
        dims = {d: len(nc.dimensions[d]) for d in nc.dimensions}
        lines.append("dimensions: " + ", ".join(f"{d} = {n}" for d, n in dims.items())
                     + f"  ({math.prod(dims.values())} points)")
        coord_names = [n for n in ("alpha", "beta", "gamma", "gtilde") if n in nc.variables]
        lines.append("coordinates:")
        for name in coord_names:
            lo, hi = math.inf, -math.inf
            var = nc.variables[name]
            for block in _iter_flat(var, var.shape):
                lo, hi = min(lo, float(block.min())), max(hi, float(block.max()))
            lines.append(f"  {name:<8} [{lo:.6g}, {hi:.6g}]  {var.getncattr('long_name')}")
        lines.append("variables:")
        for name, var in nc.variables.items():
            if name in coord_names:
                continue
            lines.append(f"  {name:<20} {var.getncattr('long_name')}")
            lines.append("      " + _stats(name, var))
        lines.append("settings:")
        for key in sorted(attrs):
            if key.startswith(("integrator_", "options_", "design", "chunk_size", "n_points",
                               "sweep_version", "numba_version", "numpy_version",
                               "run_time", "compute_time", "points_per_second",
                               "date_created", "sweep_config_sha256")):
                lines.append(f"  {key} = {attrs[key]}")
    return "\n".join(lines)


def _stats(name, var):
    shape = var.shape
    if name == "status":
        counts = np.zeros(len(Status), dtype=np.int64)
        for block in _iter_flat(var, shape):
            counts += np.bincount(block.astype(np.int64), minlength=len(Status))[:len(Status)]
        return ", ".join(f"{s.name.lower()}: {c}" for s, c in zip(Status, counts))
    if name == "sticks":
        n = t = 0
        for block in _iter_flat(var, shape):
            n += block.size
            t += int(np.count_nonzero(block))
        return f"true: {t} of {n} ({100.0 * t / max(n, 1):.3g}%)"
    n = nan = 0
    lo, hi, total, amax = math.inf, -math.inf, 0.0, 0.0
    for block in _iter_flat(var, shape):
        block = block.astype(np.float64)
        ok = np.isfinite(block)
        n += block.size
        nan += int(block.size - np.count_nonzero(ok))
        good = block[ok]
        if good.size:
            lo, hi = min(lo, float(good.min())), max(hi, float(good.max()))
            total += float(good.sum())
            amax = max(amax, float(np.abs(good).max()))
    valid = n - nan
    if not valid:
        return f"all {n} values NaN"
    text = f"min {lo:.6g}, mean {total / valid:.6g}, max {hi:.6g}, NaN {nan} of {n}"
    if name.startswith("error_"):
        text += f", max |error| {amax:.3g}"
    return text
