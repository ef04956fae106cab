"""How an array call spreads over the cores (shared by every kernel front end).

Kernels are serial numba functions compiled ``nogil``: a call on an array runs them on
blocks of the points from the calling thread and a pool of helper threads, kept between
calls (:func:`map_blocks`), as numba's own documentation does for ``nogil`` functions.
Against numba's ``parallel=True`` (``prange``) this compiles nothing more than the serial
kernel that a scalar call needs anyway (a parallel kernel cost 3-4 s of every first array
call, the closed forms 2-3 s more), takes blocks dynamically (a thread that drew cheap
points takes the next block), and is safe under every numba threading layer: no numba
parallel region is ever launched, so the ``workqueue`` layer's abort when two threads
launch one at once cannot happen. Like numbagg, calls from other threads than the main one
(Dask workers, which already keep every core busy) run serially. Results never depend on
the choice, the thread count or the blocks.

Owns: the parallel/serial policy and the thread pool. May import: nothing from ``sweep``.
"""
from __future__ import annotations

import ctypes
import itertools
import os
import sys
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, wait

import numba as nb
import numpy as np

__all__ = ["parallel_allowed", "preload_tbb", "threads", "map_blocks", "schedule",
           "TAIL_SPLIT"]


def preload_tbb() -> bool:
    """Make numba's tbb threading layer loadable when pip installed tbb (a dependency).

    pip's ``tbb`` puts ``libtbb.so.12`` in ``<prefix>/lib``, where the dynamic loader does
    not look, so numba falls back to its omp layer, whose parallel launches wait milliseconds
    for a busy core (8 ms a call measured on a loaded 2-core machine, against 0.15 ms with
    tbb) and which is less safe from thread pools. Loading the library first, globally,
    lets numba's tbb extension find it. Does nothing if the user chose a layer, or if the
    library is not there. Must run before numba starts its threads.
    """
    if os.environ.get("NUMBA_THREADING_LAYER") or nb.config.THREADING_LAYER not in (
            "default", "safe", "threadsafe"):
        return False
    for name in ("libtbb.so.12", "libtbb.12.dylib"):
        path = os.path.join(sys.prefix, "lib", name)
        if os.path.exists(path):
            try:
                ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
                return True
            except OSError:
                return False
    return False


def threads() -> int:
    """Threads an array call may use: numba's setting (``NUMBA_NUM_THREADS``,
    ``numba.set_num_threads``; all cores by default)."""
    return nb.get_num_threads()


def parallel_allowed() -> bool:
    """Whether an array call may spread over :func:`threads` threads: more than one, and
    called from the main thread (a thread pool's worker runs serially, like numbagg's)."""
    return threads() > 1 and threading.current_thread() is threading.main_thread()


#: The last blocks of a call (two a thread) are split in this many: a thread that drew a
#: costly block at the end left the others idle for up to a block's time. On the Sobol
#: design's 65,536-point chunks, 2 threads, the integrator's calls ended with one thread
#: idle for 7-9 ms of ~300 (2.2% of the thread time idle); split, 1-2 ms (1.1-1.3%).
TAIL_SPLIT = 4


def schedule(n: int, size: int, smallest: int, seed: int | None = None
             ) -> list[tuple[int, int]]:
    """The blocks ``(lo, hi)`` of a parallel call over ``n`` points: contiguous blocks of
    ``size`` points (each reads and writes contiguous memory), in a shuffled order where
    ``seed`` is given (a cluster of costly points, a grid's heavily damped corner, is spread
    over the threads), the last two a thread split in :data:`TAIL_SPLIT` parts of at least
    ``smallest`` points. The schedule never changes a result."""
    starts = list(range(0, n, size))
    if seed is not None:
        order = np.random.default_rng(seed).permutation(len(starts))
        starts = [starts[j] for j in order]
    bounds = [(lo, min(n, lo + size)) for lo in starts]
    cut = max(0, len(bounds) - 2 * threads())
    sub = max(smallest, -(-size // TAIL_SPLIT))
    return bounds[:cut] + [(a, min(hi, a + sub)) for lo, hi in bounds[cut:]
                           for a in range(lo, hi, sub)]


def map_blocks(run: Callable[[int, int], None], bounds: Iterable[tuple[int, int]]) -> None:
    """Call ``run(lo, hi)`` for the blocks ``bounds`` (:func:`schedule`), in their order,
    from the calling thread and ``threads() - 1`` helpers of a kept pool; ``run`` must
    release the GIL (a ``nogil`` kernel) for them to run at once. The first exception of a
    block is raised here, once every block that had started is over; no block is claimed
    once it is recorded.

    Each thread claims the next block from a shared counter: one task a helper, not one a
    block, and the caller computes instead of waiting. Against a pool task per block (the
    caller waiting on each), the Sobol design's chunks computed 2.8% faster on 2 threads
    (median of six interleaved rounds, 2026-12-07): the caller's submissions had delayed
    every call's first blocks by ~1 ms, and each block's task cost a hand-off.
    """
    bounds = list(bounds)
    counter, lock = itertools.count(), threading.Lock()
    errors: list = []

    def work() -> None:
        while not errors:
            with lock:
                i = next(counter)
            if i >= len(bounds):
                return
            try:
                run(*bounds[i])
            except BaseException as exc:  # noqa: BLE001 - raised by the caller below
                errors.append(exc)

    n_helpers = min(threads(), len(bounds)) - 1
    helpers = [_pool(threads() - 1).submit(work) for _ in range(n_helpers)]
    try:
        work()
        wait(helpers)
    except BaseException as exc:         # an interrupt: the helpers stop after their block
        errors.append(exc)
        wait(helpers)
    if errors:
        raise errors[0]


#: The pool of :func:`map_blocks`'s helpers, kept between calls: a new pool's threads cost
#: ~0.4 ms a call (a sweep's chunk makes 5-6 array calls; 2 cores, 2026-12-05), and with
#: its owner's process id, since a forked child inherits the pool without its threads.
_POOL: list = [None, 0, -1]


def _pool(workers: int) -> ThreadPoolExecutor:
    """The kept pool of ``workers`` threads (a new one where the count or the process
    changed)."""
    pool, size, pid = _POOL
    if pool is None or size != workers or pid != os.getpid():
        if pool is not None and pid == os.getpid():
            pool.shutdown(wait=True)
        pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="sweep")
        _POOL[:] = [pool, workers, os.getpid()]
    return pool
