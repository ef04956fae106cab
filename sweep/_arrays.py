"""Broadcasting and validation shared by the public vectorised functions.

Kernels take flat, contiguous float64 arrays of one length; the front ends broadcast their
arguments (numpy rules), flatten them, and give the results back in the broadcast shape.
A call whose inputs are all scalars is a *scalar call*: invalid values raise ``ValueError``
there, while inside arrays they only mark their own point invalid (``e = NaN``).
"""
from __future__ import annotations

import numpy as np

__all__ = ["Broadcast", "broadcast_points"]


class Broadcast:
    """Flattened, broadcast parameters and the shape to restore results to."""

    def __init__(self, names, arrays):
        arrays = [np.asarray(a, dtype=np.float64) for a in arrays]
        self.scalar = all(a.ndim == 0 for a in arrays)
        bcast = np.broadcast_arrays(*arrays)
        self.shape = bcast[0].shape
        self.names = tuple(names)
        self.flat = [np.ascontiguousarray(b.reshape(-1)) for b in bcast]

    @property
    def size(self):
        return self.flat[0].size if self.flat else 0

    def restore(self, arr):
        """Reshape a flat result to the broadcast shape (a Python scalar for scalar calls)."""
        out = np.asarray(arr).reshape(self.shape)
        if self.scalar:
            return out[()].item()
        return out

    def raise_if_invalid(self, rules):
        """For scalar calls only: raise ``ValueError`` naming the first value a rule rejects.

        ``rules`` maps a parameter name to ``(predicate_ok, description)``.
        """
        if not self.scalar:
            return
        for name, value in zip(self.names, self.flat):
            v = float(value[0])
            if not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
            if name in rules:
                ok, rule = rules[name]
                if not ok(v):
                    raise ValueError(f"{name} must be {rule}, got {v!r}")


#: Domain of the scaled parameters (Assumption 1 of the report, and physical signs).
PARAMETER_RULES = {
    "alpha": (lambda v: v >= 1.0, ">= 1 (uniqueness is not known below 1)"),
    "beta": (lambda v: v >= 1.0, ">= 1 (uniqueness is not known below 1)"),
    "gamma": (lambda v: v >= 0.0, ">= 0"),
    "gtilde": (lambda v: v >= 0.0, ">= 0 (a compressive load)"),
}


def broadcast_points(alpha, beta, gamma, gtilde):
    """Broadcast ``(alpha, beta, gamma, gtilde)`` and validate a scalar call.

    Returns
    -------
    Broadcast
        With ``flat = [alpha, beta, gamma, gtilde]`` as contiguous float64 1-D arrays.
    """
    b = Broadcast(("alpha", "beta", "gamma", "gtilde"), (alpha, beta, gamma, gtilde))
    b.raise_if_invalid(PARAMETER_RULES)
    return b
