"""The resumable state of a run: manifest, one file per finished chunk, and a lock.

``OUT.nc.partial/`` holds ``manifest.json`` (what the results depend on: hash of the
configuration and of the package source, version, chunking) and one ``chunk_NNNNNNN.npz``
per finished chunk, each written to a temporary name and renamed, so a crash (Ctrl-C,
``kill -9``) never leaves a half-written chunk. These files are the source of truth for
resuming; the netCDF file being assembled next to them (``assembling.nc``) is not, since an
HDF5 file is not crash-safe, and a resumed run rebuilds it from the chunk files.

Nothing found on disk is trusted without proof:

* every chunk file records what it belongs to (the manifest's hash, the configuration's
  hash, its index and point range), a SHA-256 of its points and the CRC-32 of each of its
  arrays, which the zip container also holds and checks as the array is read back;
  :meth:`PartialStore.load_chunk` checks all of it and turns down (for recomputation) a file
  that is unreadable, damaged, from another run or computed at other points, counting why
  in :attr:`PartialStore.rejected`;
* a partial directory without a readable manifest (e.g. left by a ``kill -9`` during the
  final clean-up, which removes the manifest first) holds nothing attributable: its chunk
  files are discarded, never resumed (:func:`remove_untrusted`).

One writer per output: :class:`OutputLock` holds an exclusive ``flock`` on ``OUT.nc.lock``
(next to the output, outside the partial directory, so ``--restart`` cannot delete it from
under another run) and records the holder's PID, host and start time, which a refused
second writer names.

May import: the standard library, numpy and :mod:`sweep._format` (floor 0: a write's
error names its file). Nothing of numba, the kernels or any floor above the store.
"""
from __future__ import annotations

import collections
import contextlib
import datetime as _dt
import errno
import hashlib
import json
import os
import shutil
import socket
import sys
import zipfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sweep._format import naming

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no locking
    fcntl = None

__all__ = ["PartialStore", "ResumeError", "LockError", "OutputLock", "partial_dir",
           "lock_path", "remove_untrusted", "partial_bytes", "MANIFEST_FORMAT",
           "CHUNK_FORMAT", "write_atomic"]

#: Format of the manifest; version 2 introduced self-describing, checksummed chunk files.
MANIFEST_FORMAT = "sweep-partial/2"
#: Format tag stored in every chunk file's metadata; version 4 records the CRC-32 of each
#: array as its zip member's (version 3: a SHA-256 of the values, a pass of its own over
#: them), version 3 the SHA-256 of the points the chunk was computed at, version 2 keeps
#: any numbers with a chunk (its ``tally``), version 1 its two times only (older chunks
#: are recomputed).
CHUNK_FORMAT = "sweep-chunk/4"
#: Attempts at taking the lock while its holder is removing the lock file.
_LOCK_ATTEMPTS = 5


class ResumeError(RuntimeError):
    """Existing partial results cannot be resumed with the current configuration."""


class LockError(ResumeError):
    """Another process is writing the same output."""


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


def lock_path(output: str | os.PathLike) -> Path:
    """Lock file of ``output``: ``OUT.nc`` -> ``OUT.nc.lock`` (see :class:`OutputLock`)."""
    output = Path(output)
    return output.with_name(output.name + ".lock")


def _differing_keys(old, new, otherwise, most=3):
    """The dotted keys of two manifests' configurations whose values differ, each with
    both values (the first ``most``), or ``otherwise`` where either has none."""
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return otherwise
    found = []

    def walk(a, b, prefix):
        for k in sorted(set(a) | set(b)):
            x, y = a.get(k, "absent"), b.get(k, "absent")
            if isinstance(x, dict) and isinstance(y, dict):
                walk(x, y, f"{prefix}{k}.")
            elif x != y:
                found.append(f"{prefix}{k}: {_short(x)} there, {_short(y)} now")

    walk(old, new, "")
    return "; ".join(found[:most]) or otherwise


def _short(value):
    s = repr(value)   # long enough for a whole numerical stack (sweeps.runner)
    return s if len(s) <= 120 else s[:117] + "..."


def write_atomic(path: Path, data_or_writer: bytes | Callable[[Any], None]) -> None:
    """Write a file at exactly ``path``, complete or not at all.

    The bytes go to a temporary name beside it, are fsync'ed and renamed onto ``path``, so
    a crash or a full disk leaves the previous file (or none), never a half-written one.

    Parameters
    ----------
    path : Path
        The file written (replaced if it exists).
    data_or_writer : bytes or callable
        The file's bytes, or ``writer(fh)`` writing them into the open binary file ``fh``
        (``np.savez(fh, ...)``: through a file, numpy adds no ``.npz`` to the name).
    """
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    try:
        with naming(path), open(tmp, "wb") as fh:
            if callable(data_or_writer):
                data_or_writer(fh)
            else:
                fh.write(data_or_writer)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        # A full disk leaves a half-written temporary file: give its space back at once.
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


# --------------------------------------------------------------------------- the lock

def _holder_text(fd):
    """Who holds the lock, from the lock file's content (it may not be written yet)."""
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode("utf-8"))
        text = f"PID {int(info['pid'])} on host {info['host']}"
        return text + (f", started {info['started']}" if info.get("started") else "")
    except (OSError, ValueError, KeyError, TypeError):
        return "a process that has not recorded itself yet"


class OutputLock:
    """Exclusive right to write one output, held as an ``flock`` on ``OUT.nc.lock``.

    The kernel releases the lock when its holder exits, ``kill -9`` included, so a lock is
    never stale; the file's content (PID, host, start time, command, one JSON line) only
    names the holder in the refusal of a second writer. The file is removed on release.

    Parameters
    ----------
    output : path-like
        The final output path ``OUT.nc``.
    """

    def __init__(self, output: str | os.PathLike) -> None:
        self.output = Path(output)
        self.path = lock_path(self.output)
        self._fh = None

    @property
    def held(self) -> bool:
        """True while this object holds the lock."""
        return self._fh is not None

    def acquire(self) -> OutputLock:
        """Take the lock, or refuse at once (never waits).

        Returns
        -------
        OutputLock
            ``self``.

        Raises
        ------
        LockError
            Another process holds it; the message names it (PID and host).
        OSError
            The lock file cannot be created (read-only file system, permissions, name too
            long); ``filename`` is the lock file.
        """
        if self._fh is not None or fcntl is None:
            return self
        for _ in range(_LOCK_ATTEMPTS):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder_text(fd)
                os.close(fd)
                raise LockError(f"another sweep process is writing {self.output}: {holder} "
                                f"(lock {self.path})") from None
            except OSError as exc:  # e.g. ENOLCK: the file system offers no locks
                os.close(fd)
                raise OSError(exc.errno, exc.strerror, str(self.path)) from None
            if self._is_current(fd):
                # A file object, so that a lock dropped without release() (an exception in
                # a caller) is still closed, and released, when it is collected.
                self._fh = os.fdopen(fd, "rb+", buffering=0)
                self._record()
                return self
            # The previous holder removed the file between our open and flock: the lock
            # we got is on a file nobody else will see. Try again with the new one.
            os.close(fd)
        raise LockError(f"cannot lock {self.output}: {self.path} keeps being replaced")

    def still_held(self) -> bool:
        """True while this object holds the lock on the file at :attr:`path` (False once
        that file was removed or replaced: another process may then hold the output)."""
        return self._fh is not None and self._is_current(self._fh.fileno())

    def _is_current(self, fd):
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            return False
        own = os.fstat(fd)
        return (st.st_ino, st.st_dev) == (own.st_ino, own.st_dev)

    def _record(self):
        now = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
        info = {"pid": os.getpid(), "host": socket.gethostname(), "started": now,
                "argv": sys.argv}
        data = (json.dumps(info) + "\n").encode()
        with contextlib.suppress(OSError):  # the record is informative only
            os.ftruncate(self._fh.fileno(), 0)
            os.pwrite(self._fh.fileno(), data, 0)

    def release(self) -> None:
        """Remove the lock file and release the lock (idempotent)."""
        if self._fh is None:
            return
        fh, self._fh = self._fh, None
        try:
            # Unlinked while still held, so nobody can lock this file afterwards and
            # believe it owns the output (see the inode check in acquire).
            if self._is_current(fh.fileno()):
                with contextlib.suppress(OSError):
                    os.unlink(self.path)
        finally:
            fh.close()

    def __enter__(self) -> OutputLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


# --------------------------------------------------------------------------- leftovers

def _read_manifest(directory):
    """The manifest in ``directory`` as a dict, or None if missing or unreadable."""
    try:
        data = json.loads((Path(directory) / "manifest.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and "format" in data else None


def remove_untrusted(output: str | os.PathLike) -> int | None:
    """Delete the partial directory of ``output`` if it has no valid manifest.

    Its chunk files cannot be attributed to any configuration, so they are never resumed.
    Call it holding the output's lock.

    Parameters
    ----------
    output : path-like

    Returns
    -------
    int or None
        Number of chunk files discarded, or None if there was no such directory.
    """
    directory = partial_dir(output)
    if not directory.is_dir() or _read_manifest(directory) is not None:
        return None
    n = sum(1 for _ in directory.glob("chunk_*.npz"))
    shutil.rmtree(directory)
    return n


def partial_bytes(output: str | os.PathLike) -> int:
    """Disk space taken by the partial state of ``output`` [bytes] (0 if there is none)."""
    total = 0
    with contextlib.suppress(FileNotFoundError, NotADirectoryError):
        with os.scandir(partial_dir(output)) as entries:
            for entry in entries:
                with contextlib.suppress(OSError):
                    if entry.is_file(follow_symlinks=False):
                        total += entry.stat(follow_symlinks=False).st_size
    return total


# --------------------------------------------------------------------------- chunk files

def _digest(arrays):
    """SHA-256 over the name, dtype, shape and bytes of every array, in name order."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.view(np.uint8).reshape(-1) if a.size else b"")
    return h.hexdigest()


def _chunk_problem(meta, data, expect, crc):
    """Why a chunk file read back does not hold what is expected, or None if it does
    (``crc``: the CRC-32 of each array's member in the file's zip directory)."""
    if meta.get("format") != CHUNK_FORMAT:
        return f"of format {str(meta.get('format'))[:40]}, not {CHUNK_FORMAT}"
    if (meta.get("identity"), meta.get("config_sha256")) != (expect["identity"],
                                                             expect["config_sha256"]):
        return "from another run"
    if [meta.get("index"), meta.get("start"), meta.get("stop")] != [
            expect["index"], expect["start"], expect["stop"]]:
        return "misplaced"
    if meta.get("points_sha256") != expect["points_sha256"]:
        # The same configuration can give other points (a sampler of a new scipy or
        # numpy): the values belong to the points they were computed at.
        return "computed at other points"
    n = expect["stop"] - expect["start"]
    if set(data) != set(expect["variables"]) or any(a.shape != (n,) for a in data.values()):
        return "incomplete"
    if meta.get("crc32") != crc:
        return "checksum mismatch"
    return None


def _write_chunk(fh, arrays, meta):
    """``np.savez``'s layout (one stored ``.npy`` member per array) with the metadata
    member last, holding each array's CRC-32 as zipfile computed it while writing it.

    zipfile checks a member against the CRC of the zip's directory as it reads it, which
    catches a damaged file; the copy in the metadata catches a file rewritten around other
    values (its directory's CRCs recomputed). Both cost no pass over the values of their
    own: a SHA-256 of them took 0.06 s of the saver's CPU a million points of
    configs/sobol_1m.toml, CPU that the kernels' cores give up on two threads."""
    with zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, a in arrays.items():
            with zf.open(name + ".npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(a), allow_pickle=False)
        meta = dict(meta, crc32=_member_crcs(zf, arrays))
        with zf.open("__meta__.npy", "w", force_zip64=True) as member:
            np.lib.format.write_array(member, np.array(json.dumps(meta)),
                                      allow_pickle=False)


def _member_crcs(zf, names):
    """The CRC-32 of the ``.npy`` member of each of ``names`` in the zip ``zf``."""
    return {name: zf.getinfo(name + ".npy").CRC for name in sorted(names)}


class PartialStore:
    """The resumable state of one output: manifest plus one ``.npz`` per finished chunk.

    Parameters
    ----------
    output : path-like
        The final output path ``OUT.nc``; the state lives in ``OUT.nc.partial/``.
    manifest : dict
        What the results depend on (configuration hash, package version, chunking,
        variables). A resume with a different manifest is refused.
    lock : OutputLock, optional
        The output's lock, already held by the caller; without one :meth:`open` takes it
        (and :meth:`release` gives it back).

    Attributes
    ----------
    rejected : collections.Counter
        Saved chunks :meth:`load_chunk` turned down, by reason ("unreadable", "checksum
        mismatch", "from another run", ...).
    discarded : int
        Chunk files found without a valid manifest and deleted by :meth:`open`.
    """

    def __init__(self, output: str | os.PathLike, manifest: Mapping[str, Any],
                 lock: OutputLock | None = None) -> None:
        self.output = Path(output)
        self.dir = partial_dir(self.output)
        self.manifest = dict(manifest, format=MANIFEST_FORMAT)
        self.identity = hashlib.sha256(
            json.dumps(self.manifest, sort_keys=True, default=str).encode()).hexdigest()
        self._lock = lock
        self._own_lock = False
        self.rejected = collections.Counter()
        self.discarded = 0

    # The manifest keys whose mismatch refuses a resume, with a human description.
    # The sweep and its libraries first: a partial directory of another version holds
    # another manifest's configuration too, which is not what the user changed.
    _CHECKED = {
        "format": "partial-state format",
        "sweep_version": "sweep version",
        "sweep_source_sha256": ("sweep source code or data (the package was edited or "
                                "reinstalled, or its error model rebuilt)"),
        "numerical_stack": ("numerical libraries (numba, llvmlite, numpy, scipy or the "
                            "vector math library were upgraded, or the run moved)"),
        "config_sha256": "configuration",
        "output": "output file name",
        "n_points": "number of design points",
        "chunk_size": "chunk size",
        "variables": "stored variables",
    }

    @property
    def lock(self) -> OutputLock | None:
        """The output's lock this store holds (its own or the caller's; None before
        :meth:`open` took one)."""
        return self._lock

    @property
    def assembling(self) -> Path:
        """Path of the netCDF file being assembled (renamed onto the output at the end)."""
        return self.dir / "assembling.nc"

    def open(self, restart: bool = False) -> set[int]:
        """Take the lock, create or reopen the partial state; return the finished chunks.

        Parameters
        ----------
        restart : bool
            Discard any existing state first (after taking the lock).

        Returns
        -------
        set of int
            Indices of the chunks whose files exist (each is verified when loaded).

        Raises
        ------
        LockError
            Another process is writing this output.
        ResumeError
            If the existing state was made by a different configuration, version or
            chunking (unless ``restart``), or its path is taken by something that is not
            a directory (``restart`` or not).
        """
        if self._lock is None:
            self._lock = OutputLock(self.output).acquire()
            self._own_lock = True
        try:
            return self._open(restart)
        except BaseException:
            self.release()
            raise

    def check(self) -> None:
        """Refuse as :meth:`open` without ``restart`` would, reading only: no lock is
        taken and nothing is written or deleted (``sweep validate``).

        Raises
        ------
        ResumeError
            As :meth:`open`: the saved state was made by a different configuration,
            version or chunking, or its path is not a directory.
        """
        self._check_is_a_directory()
        old = _read_manifest(self.dir)
        if old is not None:
            self._check_manifest(old)

    def _check_is_a_directory(self):
        if self.dir.exists() and not self.dir.is_dir():
            # Not ours: neither resumed (mkdir said a bare "File exists") nor deleted by
            # --restart (rmtree said "Not a directory").
            raise ResumeError(f"{self.dir} exists and is not a directory, so not a run's "
                              "partial directory; move or delete it, or choose another "
                              "output with -o (out=)")

    def _open(self, restart):
        self._check_is_a_directory()
        if restart and self.dir.exists():
            shutil.rmtree(self.dir)
        self.discarded = remove_untrusted(self.output) or 0
        self.dir.mkdir(parents=True, exist_ok=True)
        old = _read_manifest(self.dir)
        if old is not None:
            self._check_manifest(old)
        else:
            write_atomic(self.dir / "manifest.json",
                         json.dumps(self.manifest, indent=1).encode())
        # Leftovers of a crashed run: a half-assembled netCDF file and temporary chunks.
        for p in self.dir.glob("*.tmp*"):
            p.unlink()
        for _, path in self._chunk_entries():
            if path.is_dir() and not path.is_symlink():
                self._clear_directory(path)
        if self.assembling.exists():
            self.assembling.unlink()
        return self.finished()

    def _check_manifest(self, old):
        for key, what in self._CHECKED.items():
            if old.get(key) != self.manifest.get(key):
                differ = (f"{key}: {_short(old.get(key))} there, "
                          f"{_short(self.manifest.get(key))} now")
                if key == "config_sha256":
                    differ = _differing_keys(old.get("config"), self.manifest.get("config"),
                                             differ)
                raise ResumeError(
                    f"cannot resume {self.output}: the partial results in {self.dir} "
                    f"were computed with a different {what} ({differ}). "
                    "Rerun with the configuration and the sweep that wrote them, or with "
                    "--restart to discard them.")

    def release(self) -> None:
        """Release the lock if :meth:`open` took it (idempotent); the saved chunks stay."""
        if self._own_lock and self._lock is not None:
            self._lock.release()
            self._lock = None
            self._own_lock = False

    def _chunk_path(self, index):
        return self.dir / f"chunk_{index:07d}.npz"

    def finished(self) -> set[int]:
        """Indices of the chunks whose results are saved (not yet verified)."""
        # A directory of that name is no chunk (_clear_directory).
        return {index for index, path in self._chunk_entries() if path.is_file()}

    def _chunk_entries(self):
        """``(index, path)`` of every entry of the directory named as a chunk file is."""
        for path in self.dir.glob("chunk_*.npz"):
            with contextlib.suppress(IndexError, ValueError):
                yield int(path.stem.split("_")[1]), path

    def save_chunk(self, index: int, start: int, stop: int, arrays: Mapping[str, Any],
                   tally: Sequence[float], points: Mapping[str, Any] | None = None) -> None:
        """Save a finished chunk atomically (a crash leaves it absent or complete).

        The file records the manifest's hash, the configuration's hash, ``index``, the
        point range, the SHA-256 of the points and the CRC-32 of each array, all checked
        by :meth:`load_chunk`.

        Parameters
        ----------
        index, start, stop : int
            Chunk number and its flat range of points.
        arrays : dict of str -> ndarray
            The chunk's values per stored variable.
        tally : sequence of float
            Numbers kept with the chunk (the runner's times and counts), so that a resumed
            run still reports them for the whole dataset.
        points : dict of str -> ndarray, optional
            The parameters of the chunk's points, by name.
        """
        meta = {"format": CHUNK_FORMAT, "identity": self.identity,
                "config_sha256": self.manifest.get("config_sha256"), "index": int(index),
                "start": int(start), "stop": int(stop),
                "tally": [float(t) for t in tally], "points_sha256": _digest(points or {})}
        write_atomic(self._chunk_path(index), lambda fh: _write_chunk(fh, arrays, meta))

    def _clear_directory(self, path: Path) -> None:
        """Make room for a chunk's file where a directory has its name (its rename failed
        there on every resume), before any chunk is computed that could not be saved: an
        empty one is removed; another is refused, naming it, since it is not this store's
        to delete."""
        try:
            path.rmdir()
        except OSError:
            raise ResumeError(f"cannot resume {self.output}: {path} is a directory, not a "
                              "chunk file: move it out of the way") from None

    def load_chunk(self, index: int, start: int, stop: int,
                   points: Mapping[str, Any] | None = None
                   ) -> tuple[dict, tuple[float, ...]] | None:
        """Load and verify a finished chunk; None if it is missing, damaged, foreign or
        computed at other points.

        A rejected chunk is counted in :attr:`rejected` under its reason.

        Parameters
        ----------
        index, start, stop : int
            Chunk number and the flat range it must cover.
        points : dict of str -> ndarray, optional
            The points it must have been computed at (as given to :meth:`save_chunk`).

        Returns
        -------
        (dict, tuple of float) or None
            The arrays by variable name and the chunk's ``tally`` (see :meth:`save_chunk`).
        """
        try:
            with np.load(self._chunk_path(index), allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
                crc = _member_crcs(z.zip, set(data) - {"__meta__"})
            meta = json.loads(str(data.pop("__meta__")))
            tally = tuple(float(t) for t in meta["tally"])
        except FileNotFoundError:
            return None
        except Exception:  # noqa: BLE001 - zipfile, numpy and json each fail their own way
            # on a truncated or bit-flipped file; every failure means "recompute it".
            self.rejected["unreadable"] += 1
            return None
        expect = {"identity": self.identity, "config_sha256":
                  self.manifest.get("config_sha256"), "index": index, "start": start,
                  "stop": stop, "variables": self.manifest["variables"],
                  "points_sha256": _digest(points or {})}
        problem = _chunk_problem(meta, data, expect, crc)
        if problem is not None:
            self.rejected[problem] += 1
            return None
        return data, tally

    def discard_chunk(self, index: int) -> None:
        """Delete a saved chunk (no error if it is absent)."""
        with contextlib.suppress(FileNotFoundError):
            self._chunk_path(index).unlink()

    def invalidate(self) -> None:
        """Delete the manifest: what remains of the directory is no longer resumable.

        Called once the output is published, before :meth:`remove`, so that an interrupted
        clean-up leaves files that :func:`remove_untrusted` recognises as leftovers.
        """
        with contextlib.suppress(FileNotFoundError):
            (self.dir / "manifest.json").unlink()

    def remove(self) -> None:
        """Delete the partial state (after a successful commit); release an own lock."""
        self.invalidate()
        shutil.rmtree(self.dir, ignore_errors=True)
        self.release()
