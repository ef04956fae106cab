"""The limits and defaults a run is checked against, in one place.

Owns the numbers behind the refusals of :mod:`sweep.sweeps.config` (configuration size and
nesting, grid axis length) and of the preflight (:mod:`sweep.sweeps.preflight`: points,
output size, chunk count, free disk), the Dask connection timeout and the calibration
budget of the time estimate, and how often a run off a terminal says how far it is. The
command line exposes the run limits as options
(``--max-points``, ``--max-size``, ``--force``, ``--scheduler-timeout``); everything else
reads them from here.

Floor 4: imports nothing (plain numbers).
"""
from __future__ import annotations

__all__ = [
    "CONFIG_MAX_BYTES", "CONFIG_MAX_DEPTH", "GRID_AXIS_MAX_POINTS", "MAX_POINTS",
    "MAX_OUTPUT_BYTES", "MAX_CHUNKS", "MAX_CHUNK_SIZE", "CHUNK_POINT_BYTES",
    "CHUNK_FILE_OVERHEAD", "DISK_FULL_MARGIN",
    "SCHEDULER_TIMEOUT_S", "CALIBRATION_SECONDS", "CALIBRATION_MAX_POINTS",
    "PROGRESS_INTERVAL_S",
]

#: Largest configuration file read [bytes]. A configuration is a few hundred bytes; even a
#: grid listing 10^5 explicit values fits. Larger files (or endless ones such as /dev/zero)
#: are refused after reading at most this much.
CONFIG_MAX_BYTES = 2 ** 20
#: Deepest nesting of tables and arrays accepted in a configuration. A valid one nests 3
#: levels (``options.ord2_approx.n``); the limit only keeps pathological files from
#: exhausting the recursion of the TOML parser or of the canonical hash.
CONFIG_MAX_DEPTH = 16
#: Most points on one grid axis given as ``{start, stop, num}``. The axis is materialised
#: while the configuration is parsed (about 40 B per value), so the limit applies before
#: anything else can refuse the design.
GRID_AXIS_MAX_POINTS = 2 ** 20

#: Default largest design ``sweep run`` starts without ``--force`` [points]: ten times the
#: 10^8-point benchmark, about 11 h at the end-to-end rate of the README.
MAX_POINTS = 10 ** 9
#: Default largest output without ``--force`` [bytes, uncompressed values and coordinates].
MAX_OUTPUT_BYTES = 100 * 10 ** 9
#: Most chunks a run may cut its design into without ``--force``: one file per finished
#: chunk sits in one directory, and the set of finished ones is held in memory on resume.
MAX_CHUNKS = 2 ** 20
#: Largest chunk (``run.chunk_size``, ``--chunk-size``) [points], checked before anything is
#: written: above :data:`MAX_POINTS`, so any design run without ``--force`` fits in one
#: chunk, and far inside the 64-bit integer the file and the manifest record (a 10^23 one
#: failed there, after the partial directory was made, and that blocked the next run).
MAX_CHUNK_SIZE = 2 ** 31
#: Memory a chunk takes per point besides twice its stored values [bytes]: the four
#: parameters as the design makes them and as the kernels get them. A chunk is computed
#: whole; measured peaks were 108-113 B per point for 32-54 B of values (2026-12-04).
CHUNK_POINT_BYTES = 64
#: Disk space a saved chunk file takes beyond its values [bytes]: npz headers and rounding
#: to the file system's block.
CHUNK_FILE_OVERHEAD = 8192
#: A netCDF (HDF5) write error with less free space than this in the output's directory is
#: reported as a full disk [bytes]: HDF5 hides the cause behind "NetCDF: HDF error".
DISK_FULL_MARGIN = 16 * 2 ** 20

#: How long ``--scheduler`` waits for the Dask scheduler to answer before giving up [s].
SCHEDULER_TIMEOUT_S = 10.0
#: Wall time the time estimate of ``sweep validate`` spends computing sample points [s]
#: (compilation, or loading the cached kernels, comes on top and is not timed).
CALIBRATION_SECONDS = 0.3
#: Most points computed by that calibration.
CALIBRATION_MAX_POINTS = 2 ** 16

#: Seconds between two progress lines of a run whose stderr is not a terminal (batch jobs,
#: CI logs; ``--progress-interval``): often enough to see a run move, rarely enough to keep
#: a day-long run's log short (~8,600 lines).
PROGRESS_INTERVAL_S = 10.0
