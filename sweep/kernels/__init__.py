"""Floor 1: the compiled kernels (numba only; no xarray, files or Dask).

Imports nothing from ``sweep`` above :mod:`sweep.registry`.
"""
from sweep.kernels._parallel import preload_tbb

preload_tbb()
