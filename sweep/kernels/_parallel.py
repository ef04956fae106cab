"""When a parallel numba kernel may be launched (shared by every kernel front end).

Like numbagg, kernels fall back to a serial loop when called from a thread pool (Dask
workers) under numba's ``workqueue`` layer, which aborts the process when parallel kernels
run from several Python threads at once. Results never depend on the choice.

Owns: the parallel/serial policy. May import: nothing from ``sweep``.
"""
from __future__ import annotations

import ctypes
import os
import sys
import threading

import numba as nb

__all__ = ["parallel_allowed", "preload_tbb"]


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


def parallel_allowed() -> bool:
    """Whether a parallel kernel may be launched from the current thread.

    numba's ``workqueue`` threading layer is not thread-safe: launched from several Python
    threads at once it aborts the process. Off the main thread the parallel kernel is used
    only under a thread-safe layer (tbb, omp); with one numba thread it is pointless.
    """
    # get_num_threads() launches numba's thread pool, which fixes the threading layer:
    # threading_layer() below is always defined.
    if nb.get_num_threads() <= 1:
        return False
    if threading.current_thread() is threading.main_thread():
        return True
    return nb.threading_layer() in ("tbb", "omp")
