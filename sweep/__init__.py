"""sweep: Numba-accelerated sweeps of the coefficient of restitution (CoR) of a bead hitting a
floor through a nonlinear visco-elastic contact under a constant load.

Reference: A. Chatterjee, G. James, B. Brogliato, *Approximate analytical coefficient of
restitution formulation for single bead impact with external load, using nonlinear
visco-elastic models*, INRIA hal-03462750 (2021) -- "the report" in docstrings.

The package's floors, from the ground (no module imports from a floor above its own):
:mod:`sweep.registry` (the facts) -> :mod:`sweep.kernels` (numba) and :mod:`sweep.store`
(files) -> :mod:`sweep.model`, :mod:`sweep.api`, :mod:`sweep.auto`, :mod:`sweep.materials`
-> :mod:`sweep.critical`, :mod:`sweep.tables` -> :mod:`sweep.sweeps` (configurations,
designs, runner) -> :mod:`sweep.reports`, :mod:`sweep.examples` -> :mod:`sweep.cli`.

``sweep.run`` (a sweep as an ``xarray.Dataset``, :func:`sweep.sweeps.dataset.run`) lives on
the sweeps floor and is imported on first use: ``import sweep`` loads neither the runner nor
xarray, netCDF4 or Dask.
"""
from sweep._version import __version__
from sweep.api import (APPROXIMATIONS, DEFAULT_MAX_STEPS, DEFAULT_REST_TOL, DEFAULT_STEPS,
                       METHODS, SP_C2, IntegrationResult, coefficients, coefficients_at_zero,
                       cor, cor_fields, cor_with_status, first_order_coefficients, integrate,
                       large_gtilde_coefficient)
from sweep.critical import critical_gamma, critical_gtilde
from sweep.model import scale
from sweep.registry import MODELS, Status
from sweep.tables import lookup

__all__ = ["__version__", "MODELS", "Status", "scale", "integrate", "cor", "cor_with_status",
           "cor_fields", "lookup", "run",
           "IntegrationResult", "METHODS", "DEFAULT_STEPS", "DEFAULT_MAX_STEPS",
           "DEFAULT_REST_TOL", "APPROXIMATIONS", "coefficients", "coefficients_at_zero",
           "first_order_coefficients", "large_gtilde_coefficient", "SP_C2", "critical_gamma",
           "critical_gtilde"]


def __getattr__(name: str):
    # PEP 562: the runner (and through it the store, netCDF4 and xarray) loads only when
    # sweep.run is first used.
    if name == "run":
        from sweep.sweeps.dataset import run

        globals()["run"] = run
        return run
    raise AttributeError(f"module 'sweep' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | {"run"})
