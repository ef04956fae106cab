"""Broadcasting and validation shared by the public vectorised functions.

Kernels take flat, contiguous float64 arrays of one length; the front ends broadcast their
arguments (numpy rules), flatten them, and give the results back in the broadcast shape.
A call whose inputs are all scalars is a *scalar call*: invalid values raise ``ValueError``
there (the domain is :data:`sweep.registry.PARAMETERS`), while inside arrays they only mark
their own point invalid (``e = NaN``).

Owns: broadcasting of the front ends. May import: :mod:`sweep.registry`.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sweep import registry

__all__ = ["Broadcast", "broadcast_points", "check_broadcast", "flat_broadcast"]


class Broadcast:
    """Flattened, broadcast parameters and the shape to restore results to.

    Parameters
    ----------
    names : sequence of str
        Parameter names (keys of :data:`sweep.registry.PARAMETERS`).
    arrays : sequence of array_like
        Their values, broadcast together.
    """

    def __init__(self, names: Sequence[str], arrays: Sequence[Any]):
        for name, a in zip(names, arrays):
            if getattr(a, "dims", ()) and hasattr(a, "coords"):
                # numpy rules would pair labelled axes by position, not by name: refuse
                # rather than answer for the wrong pairs.
                raise TypeError(f"{name} is a labelled array (dims {tuple(a.dims)}); use "
                                "sweep.xr.cor / sweep.xr.integrate, which broadcast by "
                                "dimension name (xarray.apply_ufunc for other functions)")
        arrays = [registry.real_array(name, a) for name, a in zip(names, arrays)]
        self.scalar = all(a.ndim == 0 for a in arrays)
        check_broadcast(names, arrays)
        self.shape = np.broadcast_shapes(*(a.shape for a in arrays))
        self.names = tuple(names)
        self.flat = [flat_broadcast(a, self.shape) for a in arrays]

    @property
    def size(self) -> int:
        return self.flat[0].size if self.flat else 0

    def restore(self, arr: Any) -> Any:
        """Reshape a flat result to the broadcast shape (a Python scalar for scalar calls)."""
        out = np.asarray(arr).reshape(self.shape)
        if self.scalar:
            return out[()].item()
        return out

    def raise_if_invalid(self) -> None:
        """For scalar calls only: raise ``ValueError`` naming the first value outside the
        domain of :data:`sweep.registry.PARAMETERS`."""
        if not self.scalar:
            return
        for name, value in zip(self.names, self.flat):
            registry.check_scalar(name, float(value[0]))


def flat_broadcast(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` broadcast to ``shape``, flat, C-contiguous and writeable."""
    # Not np.broadcast_arrays: its views carry numpy's "warn on write" flag, which numba's
    # typeof turns into a FutureWarning on the user's stderr when a call compiles or loads
    # a kernel.
    if a.shape == shape:
        flat = np.ascontiguousarray(a.reshape(-1))
        # A read-only array (the user's, a memory map's, np.broadcast_to's) is a numba type
        # of its own: passed as such, it compiled every kernel again (the integrator's
        # _kernel: a second first call of ~15 s, cached beside the first).
        return flat if flat.flags.writeable else flat.copy()
    return np.array(np.broadcast_to(a, shape), order="C").reshape(-1)


def check_broadcast(names: Sequence[str], arrays: Sequence[np.ndarray]) -> None:
    """Raise ``ValueError`` naming the parameters whose shapes do not broadcast together
    (numpy's own message numbers them as "arg 0", "arg 1" instead)."""
    try:
        np.broadcast_shapes(*(np.shape(a) for a in arrays))
    except ValueError:
        shapes = ", ".join(f"{n} {np.shape(a)}" for n, a in zip(names, arrays)
                           if np.ndim(a) > 0)
        raise ValueError(f"the shapes of {shapes} do not broadcast together (numpy rules)") \
            from None


def broadcast_points(alpha: Any, beta: Any, gamma: Any, gtilde: Any) -> Broadcast:
    """Broadcast ``(alpha, beta, gamma, gtilde)`` and validate a scalar call.

    Returns
    -------
    Broadcast
        With ``flat = [alpha, beta, gamma, gtilde]`` as contiguous float64 1-D arrays.
    """
    b = Broadcast(registry.PARAMETER_NAMES, (alpha, beta, gamma, gtilde))
    b.raise_if_invalid()
    return b
