"""Interpolation of a scene's lookup table at many queries (:class:`sweep.tables.Table`).

The table holds e on a rectilinear (material, v0, F) grid. Along F the monotone PCHIP of
every (material, v0) row is built once by scipy (its piecewise-cubic coefficients are this
kernel's ``pieces``); along v0 the interpolant in a cell depends on the cell's two nodes and
one on either side only (a node's slope comes from its two neighbouring secants; Fritsch &
Carlson 1980), so each query evaluates the F pieces at its load on those four nodes and
runs the PCHIP through them: the same interpolant as two passes of scipy's
``PchipInterpolator``, at a cost that does not grow with the table.

Owns: the PCHIP slope rule and the stencil along v0. May import: :mod:`sweep.kernels._jit`.
"""
from __future__ import annotations

import numpy as np

from sweep.kernels._jit import cached_jit, jit

__all__ = ["STENCIL", "interpolate"]

#: The nodes of a PCHIP that decide it in one cell: the cell's own two and one on either
#: side (at the ends, scipy's three-point formula uses the first or last three).
STENCIL = 4


@jit(inline="always")
def _cell(x, xq):
    """The cell of the increasing nodes ``x`` holding ``xq`` (the last cell for the right
    end; ``xq`` is within the nodes)."""
    k = np.searchsorted(x, xq, side="right") - 1
    return min(max(k, 0), x.size - 2)


@jit(inline="always")
def _edge_slope(h0, h1, m0, m1):
    """PCHIP's slope at an end node: the one-sided three-point estimate, kept to the shape
    of the data (scipy's ``PchipInterpolator``; C. Moler, *Numerical Computing with MATLAB*,
    Sec. 3.6)."""
    d = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    if np.sign(d) != np.sign(m0):
        return 0.0
    if np.sign(m0) != np.sign(m1) and abs(d) > 3.0 * abs(m0):
        return 3.0 * m0
    return d


@jit(inline="always")
def _inner_slope(h0, h1, m0, m1):
    """PCHIP's slope at an inner node between cells of widths ``h0``, ``h1`` and secants
    ``m0``, ``m1``: 0 where the secants change sign or vanish, else their weighted harmonic
    mean (Fritsch & Butland 1984; scipy's rule)."""
    if np.sign(m0) != np.sign(m1) or m0 == 0.0 or m1 == 0.0:
        return 0.0
    w1, w2 = 2 * h1 + h0, h1 + 2 * h0
    return 1.0 / ((w1 / m0 + w2 / m1) / (w1 + w2))


@jit(inline="always")
def _slope(h, m, w, p):
    """The slope at node ``p`` of a stencil of ``w`` nodes (spacings ``h``, secants
    ``m``)."""
    if w == 2:
        return m[0]
    if p == 0:
        return _edge_slope(h[0], h[1], m[0], m[1])
    if p == w - 1:
        return _edge_slope(h[w - 2], h[w - 3], m[w - 2], m[w - 3])
    return _inner_slope(h[p - 1], h[p], m[p - 1], m[p])


@jit(inline="always")
def _along_F(pieces, values, k, t, i, node):
    """e on v0 node ``node`` of material ``i`` at the load ``t`` into F cell ``k``: the F
    pieces' cubic there (pieces by material, node, cell, power), or the one column of a
    table of one load (``k`` < 0)."""
    if k < 0:
        return values[i, node, 0]
    c = pieces[i, node, k]
    return ((c[0] * t + c[1]) * t + c[2]) * t + c[3]


@cached_jit()
def interpolate(xv, xF, pieces, values, material, vq, fq, out):
    """Write into ``out`` e at each query (material index, v0 and F coordinates, within
    the table). Serial and ``nogil``: about 0.08 us a query, mostly the two binary
    searches' branches (a million queries in 0.1 s; the steel ball's table, 2026-12-07).

    Parameters
    ----------
    xv, xF : ndarray
        The v0 and F nodes' coordinates (log where the axis is log), increasing.
    pieces : ndarray
        The PCHIP along F: coefficients (material, v0, F cell, power), highest power first
        (scipy's ``PchipInterpolator(...).c`` transposed, so that a node's four lie
        together; unused for a table of one load).
    values : ndarray
        The table (material, v0, F).
    material : ndarray of intp
    vq, fq : ndarray
        The queries' coordinates.
    out : ndarray
    """
    n = xv.size
    w = min(n, STENCIL)
    h, m, y = np.empty(STENCIL), np.empty(STENCIL), np.empty(STENCIL)
    for q in range(vq.size):
        i = material[q]
        kF = _cell(xF, fq[q]) if xF.size > 1 else -1
        tF = fq[q] - xF[max(kF, 0)]
        if n == 1:
            out[q] = _along_F(pieces, values, kF, tF, i, 0)
            continue
        k = _cell(xv, vq[q])
        first = min(max(k - 1, 0), n - w)
        for p in range(w):
            y[p] = _along_F(pieces, values, kF, tF, i, first + p)
        for p in range(w - 1):
            h[p] = xv[first + p + 1] - xv[first + p]
            m[p] = (y[p + 1] - y[p]) / h[p]
        j = k - first
        d0, d1 = _slope(h, m, w, j), _slope(h, m, w, j + 1)
        # The Hermite cubic's coefficients as scipy's CubicHermiteSpline forms them.
        t = (d0 + d1 - 2 * m[j]) / h[j]
        s = vq[q] - xv[first + j]
        out[q] = ((t / h[j] * s + ((m[j] - d0) / h[j] - t)) * s + d0) * s + y[j]
