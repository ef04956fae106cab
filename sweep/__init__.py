"""sweep: Numba-accelerated sweeps of the coefficient of restitution (CoR) of a bead hitting a
floor through a nonlinear visco-elastic contact under a constant load.

Reference: A. Chatterjee, G. James, B. Brogliato, *Approximate analytical coefficient of
restitution formulation for single bead impact with external load, using nonlinear
visco-elastic models*, INRIA hal-03462750 (2021) -- "the report" in docstrings.

The package's floors, from the ground (no module imports from a floor above its own):
:mod:`sweep.registry` (the facts) -> :mod:`sweep.kernels` (numba) and :mod:`sweep.store`
(files) -> :mod:`sweep._arrays`, :mod:`sweep.model`, :mod:`sweep.api`, :mod:`sweep.auto`,
:mod:`sweep.materials` -> :mod:`sweep.critical`, :mod:`sweep.tables`, :mod:`sweep.xr` ->
:mod:`sweep.sweeps` (configurations, designs, runner) -> :mod:`sweep.reports`,
:mod:`sweep.examples` -> :mod:`sweep.cli`.

Every public name is imported on first use (PEP 562): ``import sweep`` loads nothing but
the version, and ``sweep.cor`` loads the api and numba when first touched. The ``sweep``
command imports this package before it can handle anything: loading numba there, the
longest part of its start-up, a Ctrl-C was a traceback out of an import; loaded inside
:func:`sweep.cli.main`, it is the one line "sweep: interrupted".
``sweep.run`` (a sweep as an ``xarray.Dataset``, :func:`sweep.sweeps.dataset.run`) lives on
the sweeps floor.
"""
from __future__ import annotations

import importlib

from sweep._version import __version__

#: Each public name and the module that owns it.
_OWNERS = {
    **dict.fromkeys(("APPROXIMATIONS", "DEFAULT_MAX_STEPS", "DEFAULT_REST_TOL",
                     "DEFAULT_STEPS", "METHODS", "SP_C2", "IntegrationResult", "coefficients",
                     "coefficients_at_zero", "cor", "cor_fields", "cor_with_status",
                     "first_order_coefficients", "integrate", "large_gtilde_coefficient"),
                    "sweep.api"),
    "critical_gamma": "sweep.critical", "critical_gtilde": "sweep.critical",
    "scale": "sweep.model", "time_scale": "sweep.model", "MODELS": "sweep.registry",
    "Status": "sweep.registry",
    "lookup": "sweep.tables", "run": "sweep.sweeps.dataset",
    "CaveatWarning": "sweep.sweeps.runner",
}
#: Names read from their owner at every use: registry.register_field rebuilds the class.
_LIVE = frozenset({"IntegrationResult"})

__all__ = ["__version__", "MODELS", "Status", "scale", "time_scale", "integrate", "cor",
           "cor_with_status", "cor_fields", "lookup", "run",
           "IntegrationResult", "METHODS", "DEFAULT_STEPS", "DEFAULT_MAX_STEPS",
           "DEFAULT_REST_TOL", "APPROXIMATIONS", "coefficients", "coefficients_at_zero",
           "first_order_coefficients", "large_gtilde_coefficient", "SP_C2", "critical_gamma",
           "critical_gtilde", "CaveatWarning"]


def __getattr__(name: str):
    # PEP 562: a public name, or a submodule (sweep.api after a bare `import sweep`, as
    # when this package imported the api itself), loads on first use.
    if name in _OWNERS:
        value = getattr(importlib.import_module(_OWNERS[name]), name)
        if name not in _LIVE:
            globals()[name] = value
        return value
    if not name.startswith("__"):
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module 'sweep' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_OWNERS))
