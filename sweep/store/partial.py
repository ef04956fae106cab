"""The resumable state of a run: manifest, one file per finished chunk, and a lock.

``OUT.nc.partial/`` holds ``manifest.json`` (what the results depend on: hash of the
configuration and of the package source, version, chunking) and one ``chunk_NNNNNNN.npz``
per finished chunk, each written to a temporary name and renamed, so a crash (Ctrl-C,
``kill -9``) never leaves a half-written chunk. These files are the source of truth for
resuming; the netCDF file being assembled next to them (``assembling.nc``) is not, since an
HDF5 file is not crash-safe, and a resumed run rebuilds it from the chunk files.

May import: the standard library and numpy. Nothing of numba, the kernels or any floor
above the store.
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["PartialStore", "ResumeError", "partial_dir", "MANIFEST_FORMAT"]

MANIFEST_FORMAT = "sweep-partial/1"


class ResumeError(RuntimeError):
    """Existing partial results cannot be resumed with the current configuration."""


def partial_dir(output: str | os.PathLike) -> Path:
    """Directory of the partial state of ``output``: ``OUT.nc`` -> ``OUT.nc.partial``.

    Parameters
    ----------
    output : path-like
        The final output path.

    Returns
    -------
    Path
    """
    output = Path(output)
    return output.with_name(output.name + ".partial")


def _short(value):
    s = repr(value)
    return s if len(s) <= 80 else s[:77] + "..."


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

    def __init__(self, output: str | os.PathLike, manifest: Mapping[str, Any]) -> None:
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
    def assembling(self) -> Path:
        """Path of the netCDF file being assembled (renamed onto the output at the end)."""
        return self.dir / "assembling.nc"

    def open(self, restart: bool = False) -> set[int]:
        """Create or reopen the partial state; return the set of finished chunk indices.

        Parameters
        ----------
        restart : bool
            Discard any existing state first.

        Returns
        -------
        set of int

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
            self._check_manifest(path)
        else:
            _write_atomic(path, json.dumps(self.manifest, indent=1).encode())
        # Leftovers of a crashed run: a half-assembled netCDF file and temporary chunks.
        for p in self.dir.glob("*.tmp*"):
            p.unlink()
        if self.assembling.exists():
            self.assembling.unlink()
        return self.finished()

    def _check_manifest(self, path):
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

    def release(self) -> None:
        """Release the lock (idempotent); the saved chunks stay."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def _chunk_path(self, index):
        return self.dir / f"chunk_{index:07d}.npz"

    def finished(self) -> set[int]:
        """Indices of the chunks whose results are saved."""
        done = set()
        for p in self.dir.glob("chunk_*.npz"):
            try:
                done.add(int(p.stem.split("_")[1]))
            except (IndexError, ValueError):
                continue
        return done

    def save_chunk(self, index: int, start: int, stop: int, arrays: Mapping[str, Any],
                   times: Sequence[float]) -> None:
        """Save a finished chunk atomically (a crash leaves it absent or complete).

        Parameters
        ----------
        index, start, stop : int
            Chunk number and its flat range of points.
        arrays : dict of str -> ndarray
            The chunk's values per stored variable.
        times : pair of float
            Wall and kernel time [s] kept with the chunk, so that a resumed run still
            reports the time the whole dataset took.
        """
        payload = {name: np.asarray(a) for name, a in arrays.items()}
        payload["__bounds__"] = np.array([start, stop], dtype=np.int64)
        payload["__times__"] = np.array(times, dtype=np.float64).reshape(2)
        _write_atomic(self._chunk_path(index), lambda fh: np.savez(fh, **payload))

    def load_chunk(self, index: int, start: int, stop: int
                   ) -> tuple[dict, tuple[float, float]] | None:
        """Load a finished chunk, or return None if its file is missing or damaged.

        Parameters
        ----------
        index, start, stop : int
            Chunk number and the flat range it must cover.

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

    def discard_chunk(self, index: int) -> None:
        """Delete a saved chunk (no error if it is absent)."""
        with contextlib.suppress(FileNotFoundError):
            self._chunk_path(index).unlink()

    def remove(self) -> None:
        """Delete the partial state (after a successful commit)."""
        self.release()
        shutil.rmtree(self.dir, ignore_errors=True)
