"""Preflight of a run: what it will cost, known before anything is computed or written.

Owns :class:`Preflight` (points, chunks, output size, free disk needed and available), the
checks of a design against the run limits (:class:`Limits`, :meth:`Preflight.refusal`),
against the free disk (:meth:`Preflight.disk_refusal`) or, for an in-memory run, the
machine's memory (:meth:`Preflight.memory_refusal`), and :func:`estimate_rate`, the
points per second a run can expect: the last run of the same configuration into the same
output if there is one, else a short calibration on sample points of the design.

Everything here is computed from the layout and the stored variables' dtypes, never by
allocating the design: a 10^12-point design is described (and refused) in microseconds.

Floor 4: may import numpy, :mod:`sweep.store` (dtypes, existing outputs),
:mod:`sweep.sweeps.limits` and :mod:`sweep._format` (whose :func:`format_bytes` and
:func:`format_duration` it re-exports); the computation to calibrate is passed in.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sweep import store
from sweep._format import count, format_bytes, format_duration
from sweep.sweeps import limits

__all__ = ["Limits", "Preflight", "preflight", "free_disk", "free_inodes", "physical_memory",
           "estimate_rate", "calibrate", "format_bytes", "format_duration"]


@dataclasses.dataclass(frozen=True)
class Limits:
    """Largest run started without ``--force`` (defaults in :mod:`sweep.sweeps.limits`).

    Attributes
    ----------
    max_points : int
        Points of the design.
    max_bytes : int
        Output size, uncompressed [bytes].
    max_chunks : int
        Chunks (one file each while the run goes on).
    """

    max_points: int = limits.MAX_POINTS
    max_bytes: int = limits.MAX_OUTPUT_BYTES
    max_chunks: int = limits.MAX_CHUNKS


def _at_nearest(directory: str | os.PathLike, measure: Callable[[Path], Any]) -> Any:
    """``measure`` of the nearest existing ancestor of ``directory`` (itself included: the
    output's directory may not exist yet); None if none can be measured."""
    path = Path(directory).absolute()
    for candidate in (path, *path.parents):
        try:
            return measure(candidate)
        except OSError:
            continue
    return None


def free_disk(directory: str | os.PathLike | None) -> int | None:
    """Free space available to this user where ``directory`` is or would be [bytes].

    The nearest existing ancestor is measured (the output's directory may not exist yet);
    None if none can be, or for no directory (an in-memory run).
    """
    if directory is None:
        return None
    return _at_nearest(directory, lambda p: shutil.disk_usage(p).free)


def free_inodes(directory: str | os.PathLike) -> int | None:
    """Files that can still be created where ``directory`` is or would be (as
    :func:`free_disk`); None where the file system does not count them (it reports 0
    inodes in all) or cannot be asked."""
    if not hasattr(os, "statvfs"):  # Windows
        return None
    st = _at_nearest(directory, os.statvfs)
    return st.f_favail if st is not None and st.f_files else None


@dataclasses.dataclass(frozen=True)
class Preflight:
    """What a run will cost, from the sizes alone.

    Attributes
    ----------
    n_points, chunk_size, n_chunks : int
        Design size and how it is cut.
    value_bytes : int
        Bytes per point of the stored variables (what a chunk file holds).
    coord_bytes : int
        Bytes per point of per-point coordinates (scattered designs).
    axes_bytes : int
        Bytes of the grid's coordinate axes.
    directory : Path or None
        Where the output, its lock and its partial state go; None for an in-memory run.
    """

    n_points: int
    chunk_size: int
    n_chunks: int
    value_bytes: int
    coord_bytes: int
    axes_bytes: int
    directory: Path | None

    @property
    def output_bytes(self) -> int:
        """Size of the output before compression [bytes] (an upper bound)."""
        return self.n_points * (self.value_bytes + self.coord_bytes) + self.axes_bytes

    @property
    def chunk_file_bytes(self) -> int:
        """Size of all chunk files, kept until the output is published [bytes]."""
        return self.n_points * self.value_bytes + self.n_chunks * limits.CHUNK_FILE_OVERHEAD

    @property
    def chunk_memory(self) -> int:
        """Memory one chunk takes while it is computed [bytes] (an estimate from above)."""
        points = min(self.chunk_size, self.n_points)
        return points * (limits.CHUNK_POINT_BYTES + 2 * self.value_bytes)

    @property
    def disk_needed(self) -> int:
        """Peak disk use of the run: the chunk files plus the assembled output [bytes]."""
        return self.output_bytes + self.chunk_file_bytes

    def refusal(self, lim: Limits) -> str | None:
        """Why ``sweep run`` refuses this design without ``--force``, or None."""
        if self.n_points > lim.max_points:
            return (f"design of {self.n_points:,} points is above the limit of "
                    f"{lim.max_points:,} points (--max-points); pass --force to run it")
        if self.output_bytes > lim.max_bytes:
            return (f"output of up to {format_bytes(self.output_bytes)} is above the limit "
                    f"of {format_bytes(lim.max_bytes)} (--max-size); store fewer variables "
                    "or pass --force to run it")
        if self.n_chunks > lim.max_chunks:
            return (f"{count(self.n_chunks, 'chunk')} of "
                    f"{count(self.chunk_size, 'point')} are above the "
                    f"limit of {lim.max_chunks:,} chunks; use a larger --chunk-size or pass "
                    "--force")
        return None

    def chunk_memory_refusal(self) -> str | None:
        """Why one chunk would not fit in this machine's memory, or None.

        A chunk is computed whole: one larger than the machine was ended by the OOM killer
        (no message) or failed on some small allocation at last."""
        memory = physical_memory()
        if memory is None or self.chunk_memory <= memory:
            return None
        return (f"a chunk of {count(min(self.chunk_size, self.n_points), 'point')} needs up "
                f"to {format_bytes(self.chunk_memory)} of memory, more than this machine's "
                f"{format_bytes(memory)}; use a smaller --chunk-size (chunk_size=) or pass "
                "--force (force=True)")

    def disk_refusal(self, saved: int = 0) -> str | None:
        """Why the free disk does not suffice, or None.

        Parameters
        ----------
        saved : int
            Bytes of partial state already on disk for this output [bytes]: resumed chunks
            need no new space, and a restart frees them first.
        """
        free = free_disk(self.directory)
        if free is None or free + saved >= self.disk_needed:
            return None
        return (f"not enough free disk in {self.directory}: the run needs up to "
                f"{format_bytes(self.disk_needed)} (chunk files plus the uncompressed "
                f"output), {format_bytes(free + saved)} available; free some space, choose "
                "another -o, or pass --force (compression usually needs less)")

    def memory_refusal(self) -> str | None:
        """Why an in-memory run (``sweep.run`` without ``out=``) refuses this design, or
        None: its dataset, uncompressed, would not fit in this machine's memory."""
        memory = physical_memory()
        if memory is None or self.output_bytes <= memory:
            return None
        return (f"the dataset needs up to {format_bytes(self.output_bytes)} in memory, more "
                f"than this machine's {format_bytes(memory)}; give out= to write it to a "
                "file chunk by chunk, or pass force=True")

    def lines(self) -> list[str]:
        """Human-readable description, one item per line."""
        free = free_disk(self.directory)
        return [
            f"points: {self.n_points:,} in {count(self.n_chunks, 'chunk')} of <= "
            f"{self.chunk_size:,}",
            f"output: <= {format_bytes(self.output_bytes)} uncompressed",
            f"disk: needs <= {format_bytes(self.disk_needed)} in {self.directory} (chunk "
            f"files + output); "
            + (f"{format_bytes(free)} free" if free is not None else "free space unknown"),
        ]


def preflight(layout: store.Layout, variables: Sequence[str], chunk_size: int,
              output: str | os.PathLike | None) -> Preflight:
    """The :class:`Preflight` of a run (nothing is allocated).

    Parameters
    ----------
    layout : sweep.store.Layout
        Shape of the stored data.
    variables : sequence of str
        Stored variables (dtypes from :func:`sweep.store.variable_spec`).
    chunk_size : int
        Points per chunk, >= 1.
    output : path-like or None
        The output file; None for an in-memory run (no disk is used).

    Returns
    -------
    Preflight
    """
    n = layout.size
    value_bytes = sum(np.dtype(store.variable_spec(v)[0]).itemsize for v in variables)
    coord_bytes = 8 * len(layout.point_coords)
    axes_bytes = 8 * sum(len(a) for a in layout.axes.values())
    return Preflight(n_points=n, chunk_size=chunk_size, n_chunks=-(-n // chunk_size),
                     value_bytes=value_bytes, coord_bytes=coord_bytes, axes_bytes=axes_bytes,
                     directory=None if output is None else Path(output).absolute().parent)


#: Where a Linux container's memory limit is read (cgroup v2, then v1) [bytes].
CGROUP_MEMORY_LIMITS = ("/sys/fs/cgroup/memory.max",
                        "/sys/fs/cgroup/memory/memory.limit_in_bytes")


def physical_memory() -> int | None:
    """The memory this process may use [bytes]: the machine's physical memory, or its
    container's limit where that is lower (a container on a large host sees the host's
    RAM); None where the system says neither."""
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, OSError, ValueError):  # pragma: no cover - e.g. Windows
        memory = None
    for path in CGROUP_MEMORY_LIMITS:
        try:
            text = Path(path).read_text(encoding="ascii").strip()
        except (OSError, UnicodeDecodeError):
            continue
        if text.isdigit():      # "max" (v2) or a huge number (v1): no limit
            memory = int(text) if memory is None else min(memory, int(text))
        break
    return memory


def _sample(design: Any, n: int) -> tuple:
    """``n`` points of the design to time: 16 evenly spaced runs of a grid (its leading
    points all share one alpha, beta and gamma), the leading points of a design of
    experiments (spread over the whole box by construction)."""
    size = design.size
    if not design.axes or size <= n:
        return design.points(0, min(n, size))
    runs = min(16, n)
    per = n // runs
    starts = [(k * (size - per)) // (runs - 1) for k in range(runs)]
    parts = [design.points(s, s + per) for s in starts]
    return tuple(np.concatenate([p[j] for p in parts]) for j in range(4))


def calibrate(design: Any, compute: Callable[..., Any],
              seconds: float = limits.CALIBRATION_SECONDS,
              max_points: int = limits.CALIBRATION_MAX_POINTS) -> tuple[float, int]:
    """Points per second of ``compute`` on sample points of ``design``.

    Parameters
    ----------
    design : sweep.sweeps.design.Design
    compute : callable
        ``compute(alpha, beta, gamma, gtilde)``, the work of one chunk.
    seconds : float
        Wall time to aim at [s]; the sample grows by 4x until it takes a quarter of it.
    max_points : int
        Largest sample.

    Returns
    -------
    (float, int)
        Points per second, and the size of the sample that measured it.
    """
    def timed(m):
        points = _sample(design, m)
        t0 = time.perf_counter()
        compute(*points)
        return time.perf_counter() - t0

    cap = max(1, min(design.size, max_points))
    timed(min(2, cap))  # compiles, or loads the cached kernels: not part of the rate
    n = min(64, cap)
    while True:
        dt = timed(n)
        if dt >= seconds / 4 or n >= cap:
            return n / max(dt, 1e-9), n
        n = min(4 * n, cap)


def estimate_rate(design: Any, compute: Callable[..., Any], output: str | os.PathLike,
                  config_sha256: str) -> tuple[float, str]:
    """Expected points per second of a run, and where the figure comes from.

    Parameters
    ----------
    design : sweep.sweeps.design.Design
    compute : callable
        See :func:`calibrate`.
    output : path-like
        The run's output: if it holds a finished run of the same configuration, its
        measured rate is used instead of a calibration.
    config_sha256 : str
        :attr:`sweep.sweeps.config.Config.sha256` of the configuration.

    Returns
    -------
    (float, str)
    """
    attrs = store.read_global_attrs(output) if Path(output).is_file() else None
    if attrs and attrs.get("sweep_config_sha256") == config_sha256:
        rate = float(attrs.get("points_per_second", -1.0))
        if rate > 0:
            return rate, f"last run of {output}"
    rate, n = calibrate(design, compute)
    return rate, f"calibration on {count(n, 'point')}"
