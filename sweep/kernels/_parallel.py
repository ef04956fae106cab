"""When a parallel numba kernel may be launched (shared by every kernel front end).

Like numbagg, kernels fall back to a serial loop when called from a thread pool (Dask
workers) under numba's default ``workqueue`` layer, which aborts the process when parallel
kernels run from several Python threads at once. Results never depend on the choice.
"""
from __future__ import annotations

import threading

import numba as nb

__all__ = ["parallel_allowed"]


def parallel_allowed():
    """Whether a parallel kernel may be launched from the current thread.

    numba's ``workqueue`` threading layer is not thread-safe: launched from several Python
    threads at once it aborts the process. Off the main thread the parallel kernel is used
    only under a thread-safe layer (tbb, omp); with one numba thread it is pointless.
    """
    if nb.get_num_threads() <= 1:
        return False
    if threading.current_thread() is threading.main_thread():
        return True
    try:
        layer = nb.threading_layer()
    except ValueError:  # no parallel kernel has run yet: the layer is not chosen
        layer = nb.config.THREADING_LAYER
        if layer in ("default", "safe", "threadsafe"):
            try:  # numba prefers tbb when it can load it
                import numba.np.ufunc.tbbpool  # noqa: F401, PLC0415
                layer = "tbb"
            except ImportError:
                layer = "unknown"
    return layer in ("tbb", "omp")
