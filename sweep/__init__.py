"""sweep: Numba-accelerated sweeps of the coefficient of restitution (CoR) of a bead hitting a
floor through a nonlinear visco-elastic contact under a constant load.

Reference: A. Chatterjee, G. James, B. Brogliato, *Approximate analytical coefficient of
restitution formulation for single bead impact with external load, using nonlinear
visco-elastic models*, INRIA hal-03462750 (2021) -- "the report" in docstrings.
"""
from sweep.kernels._jit import kernel_cache
from sweep._version import __version__
from sweep.model import MODELS, Status, scale

with kernel_cache():
    from sweep.api import (APPROXIMATIONS, DEFAULT_MAX_STEPS, DEFAULT_REST_TOL, DEFAULT_STEPS,
                           METHODS, IntegrationResult, cor, cor_with_status, integrate)
    from sweep.kernels.approx import (SP_C2, coefficients, coefficients_at_zero,
                              first_order_coefficients, large_gtilde_coefficient)
    from sweep.critical import critical_gamma, critical_gtilde

__all__ = ["__version__", "MODELS", "Status", "scale", "integrate", "cor", "cor_with_status",
           "IntegrationResult", "METHODS", "DEFAULT_STEPS", "DEFAULT_MAX_STEPS",
           "DEFAULT_REST_TOL", "APPROXIMATIONS", "coefficients", "coefficients_at_zero",
           "first_order_coefficients", "large_gtilde_coefficient", "SP_C2", "critical_gamma",
           "critical_gtilde"]
