"""Where the numerical integration runs: every CPU core, or one CUDA GPU.

The one front end of the two kernels (as stumpy puts one kernel behind a local and a
distributed front end): :func:`integrate_on` dispatches on the ``device`` option of the
``"numeric"`` method (:data:`sweep.registry.DEVICES`); :func:`numeric_cor` is that method's
kernel. The CUDA module, and numba-cuda with it, is imported only when a call asks for it.

Owns: the choice of device. May import: integrator, cuda.
"""
from __future__ import annotations

import numpy as np

from sweep.kernels.integrator import Settings, integrate_arrays, settings

__all__ = ["integrate_on", "numeric_cor"]


def integrate_on(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, gtilde: np.ndarray,
                 s: Settings, parallel: bool | None = None,
                 device: str = "cpu") -> dict[str, np.ndarray]:
    """The integrator over flat float64 arrays on ``device`` (``"cpu"``: every core,
    :func:`sweep.kernels.integrator.integrate_arrays`; ``"cuda"``: one GPU,
    :func:`sweep.kernels.cuda.integrate_arrays_cuda`). Same fields from both."""
    if device == "cuda":
        from sweep.kernels.cuda import integrate_arrays_cuda  # noqa: PLC0415 -- optional

        return integrate_arrays_cuda(alpha, beta, gamma, gtilde, s)
    return integrate_arrays(alpha, beta, gamma, gtilde, s, parallel)


def numeric_cor(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, gtilde: np.ndarray,
                parallel: bool | None = None, device: str = "cpu",
                **options) -> tuple[np.ndarray, np.ndarray, dict]:
    """The ``"numeric"`` method's kernel (:data:`sweep.registry.METHODS`): ``(e, status,
    {"e_err": e_err})`` over flat float64 arrays of equal length (e_err: what
    ``"auto"``, which integrates through this kernel, needs to judge its tol); ``options``
    as for :func:`sweep.kernels.integrator.settings`."""
    out = integrate_on(alpha, beta, gamma, gtilde, settings(**options), parallel, device)
    return out["e"], out["status"], {"e_err": out["e_err"]}
