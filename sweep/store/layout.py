"""The contract between the runner and a storage backend.

Owns :class:`Layout` (the shape of the stored data), :func:`flat_blocks` (how a chunk of
consecutive points, a flat C-order range, maps onto that shape) and :class:`Writer`, the
small protocol every output backend implements (:class:`sweep.store.netcdf.NetCDFWriter`
is the one in use). The runner only relies on these.

May import: the standard library. Nothing of numba, the kernels or any floor above the
store.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from typing import Any, Protocol

__all__ = ["Layout", "flat_blocks", "Writer"]


@dataclasses.dataclass(frozen=True)
class Layout:
    """Shape of the stored data.

    Attributes
    ----------
    dims, shape : tuple
        Dimensions of every data variable, C order over the flat point index.
    axes : dict
        Coordinate variable per dimension (grid and scene designs): numbers, an integer
        index 0..n-1 for a dimension of names (a scene's ``material``); empty for
        scattered designs.
    point_coords : tuple of str
        Coordinates stored per point along the single dimension (scattered designs), which
        is then indexed by an integer coordinate 0..n-1 of its own name.
    spacing : dict
        Spacing of each axis (name -> one of :data:`sweep.store.metadata.SPACINGS`); axes
        absent here carry none.
    point_vars : tuple of str
        Per-point values stored as data variables on ``dims`` (a scene's gamma and g~):
        like ``point_coords``, written from the points of each chunk.
    constants : dict
        Variables known before the run: name -> (dims, values) (a scene's per-material
        m, k, gamma0, alpha, beta and names; its scalar g).
    aux_coords : tuple of str
        Constants that are auxiliary coordinates (a scene's ``material_name``, strings):
        every other variable on their dimensions lists them in its ``coordinates``.
    attrs : dict
        Attributes per coordinate or variable name, added to those of
        :func:`sweep.store.metadata.coordinate_attrs` (e.g. a material's long name).
    """

    dims: tuple
    shape: tuple
    axes: dict
    point_coords: tuple = ()
    spacing: dict = dataclasses.field(default_factory=dict)
    point_vars: tuple = ()
    constants: dict = dataclasses.field(default_factory=dict)
    attrs: dict = dataclasses.field(default_factory=dict)
    aux_coords: tuple = ()

    @property
    def size(self) -> int:
        """Number of points (the product of ``shape``)."""
        return math.prod(self.shape)

    @property
    def per_point(self) -> tuple:
        """Names written from each chunk's points: ``point_coords + point_vars``."""
        return tuple(self.point_coords) + tuple(self.point_vars)


def _sub_blocks(shape: tuple, row: int, lo: int, hi: int) -> Iterator[tuple]:
    """Blocks of ``[lo, hi)`` inside row ``row`` of the first axis, in flat coordinates."""
    inner = math.prod(shape[1:])
    for sl, a, b in flat_blocks(shape[1:], lo, hi):
        yield (slice(row, row + 1),) + sl, row * inner + a, row * inner + b


def flat_blocks(shape: tuple, start: int, stop: int) -> Iterator[tuple]:
    """Cover the C-order flat range ``[start, stop)`` of an array by hyper-rectangles.

    Parameters
    ----------
    shape : tuple of int
        Shape of the array.
    start, stop : int
        Flat range, ``0 <= start <= stop <= prod(shape)``.

    Yields
    ------
    (tuple of slice, int, int)
        Index of one block and the flat range ``[lo, hi)`` it covers; at most
        ``2 len(shape) - 1`` blocks, in flat order.
    """
    if start >= stop:
        return
    if len(shape) == 1:
        yield (slice(start, stop),), start, stop
        return
    inner = math.prod(shape[1:])
    i0, r0 = divmod(start, inner)
    i1, r1 = divmod(stop, inner)
    if i0 == i1:
        yield from _sub_blocks(shape, i0, r0, r1)
        return
    if r0:
        yield from _sub_blocks(shape, i0, r0, inner)
        i0 += 1
    if i1 > i0:
        yield (slice(i0, i1),) + tuple(slice(0, n) for n in shape[1:]), i0 * inner, i1 * inner
    if r1:
        yield from _sub_blocks(shape, i1, 0, r1)


class Writer(Protocol):
    """What the runner writes a sweep's results into, chunk by chunk.

    Chunks may arrive in any order; every point is written exactly once before
    :meth:`close`.
    """

    def write(self, start: int, stop: int, arrays: Mapping[str, Any],
              points: Mapping[str, Any] | None = None) -> None:
        """Store the results of points ``start .. stop-1`` (flat C-order index)."""

    def set_attrs(self, attrs: Mapping[str, Any]) -> None:
        """Set global attributes of the dataset."""

    def close(self) -> None:
        """Finish the dataset (idempotent)."""
