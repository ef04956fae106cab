"""When a parallel numba kernel may be launched (shared by every kernel front end).

Like numbagg, kernels fall back to a serial loop when called from a thread pool (Dask
workers) under numba's ``workqueue`` layer, which aborts the process when parallel kernels
run from several Python threads at once. Results never depend on the choice.

Owns: the parallel/serial policy. May import: nothing from ``sweep``.
"""
from __future__ import annotations

import threading

import numba as nb

__all__ = ["parallel_allowed"]


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
