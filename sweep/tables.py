"""Lookup tables of the CoR for simulation codes: a scene's e(v0, F) interpolated and exported.

A scene dataset (``sweep run`` of a ``design.kind = "scene"`` configuration) holds e on the
grid (material, v0, F), with each material's m, k, gamma0, alpha, beta, its name
(:data:`sweep.registry.MATERIAL_NAME`; ``material`` is an index) and the scene's g.
:class:`Table` interpolates it:

* along v0 and along F by monotone piecewise-cubic Hermite interpolation (PCHIP, Fritsch &
  Carlson 1980; ``scipy.interpolate.PchipInterpolator``): where the tabulated e is monotone
  along an axis the interpolant is too on the other axis's nodes (between them the two
  passes need not be: docs/scenes.md, section 4), and it never leaves the range of its
  neighbouring values (so 0 <= e <= 1 holds);
* in log v0 (log F) where the axis was given with ``spacing = "log"``;
* no extrapolation: a query outside the table raises ``ValueError`` naming it.

A query is interpolated along F first, on the v0 nodes, then along v0. The PCHIP along F is
built once per table; along v0, only the four nodes around the query's cell decide the
PCHIP there, so each query interpolates along F on those four and runs a PCHIP through them:
its work and memory do not grow with the table (along every node, ~100 bytes a node a
query, the held-back check of a 200 x 104 table took 6 GB).

:meth:`Table.error` reports the interpolation error against direct computation (the same
method and settings as the table, at the scaled point of eq. (2): the method's own error,
auto's tol or a closed form's, comes on top) on *held-back points*: points inside every
cell, at the quarter, half and three-quarter marks of each axis, which are not in the
table. That maximum is an estimate measured on a lattice four times finer, not a proof (up
to ~9% low on a lattice 9-11 times finer, docs/scenes.md). Where e falls to 0 inside a
cell (the no-rebound speed or load, some corners 0, others not) e collapses like a square
root that no cubic follows, and the held-back points can miss the collapse (the
interpolant there was up to 2.9 times their maximum): such a cell is bounded by its largest
corner instead, where e lies between 0 and it. The stated error is the larger of the two.
:func:`lookup` is the one-call form.
Every node must hold a value: a table with a NaN node (a method undefined there) is
refused, naming it.

:func:`export` writes the table for codes that read plain files: CSV (one row per
(material, v0, F), units in the header) or NumPy ``.npz`` (arrays on (material, v0, F)).

Owns: interpolation of scene datasets, the held-back check and the export formats. May
import: :mod:`sweep.api`, :mod:`sweep.model`, :mod:`sweep.registry`, :mod:`sweep._arrays`,
:mod:`sweep._format`, :mod:`sweep.store` (:func:`~sweep.store.open_dataset`, which opens a
file), numpy; scipy inside the functions (``import sweep`` stays light). Floor 3.
"""
from __future__ import annotations

import csv
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from sweep import api, registry, store
from sweep.kernels.lookup import interpolate as _interpolate_kernel
from sweep._arrays import check_broadcast
from sweep._format import naming
from sweep.model import scale

__all__ = ["Table", "lookup", "export", "SCENE_DIMS", "HELD_BACK_FRACTIONS",
           "COLLAPSE_CHOICES"]

#: Dimensions of a scene dataset (sweep.sweeps.design.SceneDesign).
SCENE_DIMS = ("material", "v0", "F")
#: Where the held-back points sit inside each cell, as fractions of the cell (per axis).
HELD_BACK_FRACTIONS = (0.25, 0.5, 0.75)
#: A query within this fraction of an end of an axis is taken at that end: the rounding of
#: a float32 query (2^-24; a single-precision code asking for v0 = 0.01 gives
#: 0.009999999776...), far below any table's interpolation error.
END_ROUNDING = 1.2e-7
_MATERIAL_VARIABLES = ("m", "k", "gamma0", "alpha", "beta")
#: What :class:`Table` does with a query in a collapse cell: interpolate it (within the
#: collapse bound), or compute it directly.
COLLAPSE_CHOICES = ("interpolate", "direct")


def _open(dataset: Any) -> Any:
    if isinstance(dataset, (str, os.PathLike)):
        if Path(dataset).suffix.lower() in (".npz", ".csv"):
            # netCDF's own refusal of it named no cause ("[Errno -51] not a netCDF file").
            raise ValueError(f"{dataset} is an exported table, not a scene dataset: give "
                             "the netCDF file sweep run wrote for the scene")
        with store.open_dataset(dataset) as ds:
            return ds.load()
    return dataset


def _material_names(ds: Any) -> list[str]:
    """The materials' names: the auxiliary coordinate ``material_name``, or the
    ``material`` coordinate itself in files written before it (which held the names)."""
    names = ds[registry.MATERIAL_NAME] if registry.MATERIAL_NAME in ds.variables \
        else ds["material"]
    return [str(m) for m in _names(names.values).reshape(-1)]


def _unit(ds: Any, name: str) -> str:
    """The unit of a variable as the export states it: its ``units`` attribute; for k or
    gamma0 without one (a power of the metre UDUNITS cannot say), the rule of the
    registry (``"N m^-alpha"``, the exponents being in the export); "1" otherwise."""
    if "units" in ds[name].attrs:
        return str(ds[name].attrs["units"])
    p = registry.PHYSICAL.get(name)
    return p.units if p is not None and p.law_units else "1"


def _method_of(variable: Any) -> str:
    """The method of a tabulated CoR ``e_<method>``.

    Raises
    ------
    ValueError
        ``variable`` is not ``e_`` and a method of :data:`sweep.registry.METHODS` (gamma,
        status, ...): a table interpolates e and computes it directly to check itself.
    """
    method = variable[2:] if isinstance(variable, str) and variable.startswith("e_") else None
    if method not in registry.METHODS:
        raise ValueError("variable must be a coefficient of restitution e_<method> ("
                         f"{', '.join('e_' + m for m in registry.METHODS)}), got {variable!r}")
    return method


def _cor_variables(ds: Any) -> list[str]:
    """The dataset's coefficients of restitution ``e_<method>``, in its order."""
    # e_err begins with e_ too: a field (an error estimate), not a coefficient of
    # restitution; a method no longer registered here still tabulates its e.
    return [str(n) for n in ds.data_vars
            if str(n).startswith("e_") and str(n) not in registry.FIELDS]


def _default_variable(ds: Any) -> str:
    for name in ("e_numeric", "e_auto"):
        if name in ds:
            return name
    names = _cor_variables(ds)
    if not names:
        raise ValueError("the dataset stores no e_<method> variable")
    return names[0]


#: Queries interpolated together: the work arrays stay bounded (tens of bytes a query)
#: however many queries a call has (Table.error's held-back points are 16 times the table).
_BLOCK = 1 << 16


def _end_slack(end: float, other: float) -> float:
    """How far outside an axis's ``end`` a query is still taken at it: :data:`END_ROUNDING`
    of the end, or where the end is 0 (a scene's F), of the axis's other end (a load
    computed as 0.3 - 0.1 - 0.2 = -2.8e-17 N)."""
    return END_ROUNDING * abs(end if end != 0.0 else other)


def _names(material: Any) -> np.ndarray:
    """Material names as a numpy str array; bytes (as netCDF and HDF5 readers give names)
    decoded as UTF-8."""
    a = np.asarray(material)
    if a.dtype.kind == "S":
        return np.char.decode(a, "utf-8")
    if a.dtype.kind == "O":
        return np.array([m.decode("utf-8") if isinstance(m, bytes) else str(m)
                         for m in a.reshape(-1)], dtype=str).reshape(a.shape)
    return a.astype(str)


def _cells(x: np.ndarray, xq: np.ndarray) -> np.ndarray:
    """The cell of the increasing nodes ``x`` holding each query ``xq`` (the last cell for
    the right end)."""
    return np.clip(np.searchsorted(x, xq, side="right") - 1, 0, x.size - 2)


def _collapsing(corners: np.ndarray) -> np.ndarray:
    """Cells whose ``corners`` (corner first) hold both 0 and more: e falls to 0 inside."""
    return (corners.min(axis=0) == 0.0) & (corners.max(axis=0) > 0.0)


class Table:
    """e(v0, F) of each material of a scene dataset, interpolated.

    Parameters
    ----------
    dataset : path-like or xarray.Dataset
        A scene dataset (dimensions material, v0, F).
    variable : str, optional
        The tabulated variable (default ``e_numeric``, else ``e_auto``, else the first
        ``e_<method>``).

    Raises
    ------
    ValueError
        Not a scene dataset, a variable that is not an ``e_<method>``, or one the dataset
        does not have (named).
    """

    def __init__(self, dataset: Any, variable: str | None = None) -> None:
        ds = _open(dataset)
        if not all(d in ds.dims for d in SCENE_DIMS):
            raise ValueError(f"not a scene dataset: dimensions {tuple(ds.dims)}, expected "
                             f"{SCENE_DIMS}")
        self.variable = _default_variable(ds) if variable is None else variable
        # Its absence first: the list of what the file holds, not of every method known.
        if self.variable not in ds.data_vars:
            raise ValueError(f"the dataset has no variable {self.variable!r}; it has "
                             f"{', '.join(_cor_variables(ds)) or 'no e_<method>'}")
        self.method = _method_of(self.variable)
        ds = ds.sortby(["v0", "F"])  # axes given as lists need not be increasing
        self.values = np.ascontiguousarray(ds[self.variable].transpose(*SCENE_DIMS).values,
                                           dtype=np.float64)
        self.materials = _material_names(ds)
        self.v0 = ds["v0"].values.astype(np.float64)
        self.F = ds["F"].values.astype(np.float64)
        self.log = {axis: ds[axis].attrs.get("spacing") == "log" for axis in ("v0", "F")}
        self.properties = {name: ds[name].values.astype(np.float64)
                           for name in _MATERIAL_VARIABLES}
        self.g = float(ds["g"].values)
        self.options = api.recorded_settings(ds.attrs, self.method)
        self._refuse_missing_nodes()
        self._refuse_repeated_nodes()
        #: The nodes' coordinates along each axis (log where the axis is), formed once.
        self._nodes = {axis: self._coord(axis, getattr(self, axis)) for axis in ("v0", "F")}
        self._F_pieces = self._pchip_along_F()
        self._collapse = _collapsing(self._cell_corners()[0])

    def _refuse_missing_nodes(self) -> None:
        """Raise ``ValueError`` naming the first node without a value: the PCHIP of every
        row through it would be NaN (scipy refused it unnamed)."""
        bad = np.argwhere(~np.isfinite(self.values))
        if bad.size:
            i, j, k = bad[0]
            value = float(self.values[i, j, k])
            raise ValueError(f"{self.variable} has no value ({value!r}) at "
                             f"material {self.materials[i]!r}, v0 = {self.v0[j]:g} m/s, F = "
                             f"{self.F[k]:g} N: a table needs one at every node (leave that "
                             "speed or load out of the scene, or tabulate another method)")

    def _refuse_repeated_nodes(self) -> None:
        """Raise ``ValueError`` naming a speed or load that is a node twice (a dataset joined
        from scenes that share one): PCHIP's slopes there divide by the zero spacing, and
        its neighbours' came out wrong by ~1e-4 where the table's error was 1e-8."""
        for axis, unit in (("v0", "m/s"), ("F", "N")):
            nodes = getattr(self, axis)
            repeated = np.flatnonzero(np.diff(nodes) <= 0)
            if repeated.size:
                raise ValueError(f"{axis} = {nodes[repeated[0]]:g} {unit} is a node twice: a "
                                 f"table's {axis} must not repeat a value (drop one, e.g. "
                                 f"ds.drop_duplicates({axis!r}))")

    # -- interpolation --------------------------------------------------------------------

    def _coord(self, axis: str, values: np.ndarray) -> np.ndarray:
        return np.log(values) if self.log[axis] else values

    def _in_range(self, axis: str, q: np.ndarray) -> np.ndarray:
        """The queries, clipped onto the table's range if within :data:`END_ROUNDING` of
        an end (relative to that end: an absolute allowance set by the axis's largest
        value let v0 = 0 through on an axis from 1e-9 to 1e3 m/s).

        Raises
        ------
        ValueError
            A query outside the table or not a number (named).
        """
        if np.isnan(q).any():
            raise ValueError(f"{axis} = nan is not a number")
        nodes = getattr(self, axis)
        lo, hi = nodes[0], nodes[-1]
        bad = ~((q >= lo - _end_slack(lo, hi)) & (q <= hi + _end_slack(hi, lo)))
        if np.any(bad):
            raise ValueError(f"{axis} = {float(q[bad][0])!r} is outside the table "
                             f"[{lo:g}, {hi:g}]")
        return np.clip(q, lo, hi)

    def _material_index(self, material: np.ndarray | None, n: int) -> np.ndarray:
        """Indices of ``n`` queries' materials (names, flat; None: the table's only one)."""
        if material is None:
            if len(self.materials) != 1:
                raise ValueError(f"material is required: the table has {self.materials}")
            return np.zeros(n, dtype=np.intp)
        idx = np.full(n, -1, dtype=np.intp)
        # One vectorised comparison per material of the table: a dict lookup per query
        # cost 0.25 s a million queries, four times the interpolation.
        for i, name in enumerate(self.materials):
            idx[material == name] = i
        unknown = idx < 0
        if np.any(unknown):
            raise ValueError(f"unknown material {str(material[unknown][0])!r}; the table "
                             f"has {self.materials}")
        return idx

    def _queries(self, v0: Any, F: Any, material: Any) -> tuple[np.ndarray, ...]:
        """The queries' v0 [m/s], F [N] and material indices, broadcast and flat, and the
        broadcast shape.

        Raises
        ------
        ValueError
            v0 or F not real numbers, shapes that do not broadcast (naming the
            parameters), a missing or unknown material.
        """
        given = {"v0": registry.real_array("v0", v0), "F": registry.real_array("F", F)}
        if material is not None:
            given["material"] = _names(material)
        check_broadcast(tuple(given), tuple(given.values()))
        shape = np.broadcast_shapes(*(a.shape for a in given.values()))
        flat = {name: np.broadcast_to(a, shape).reshape(-1) for name, a in given.items()}
        idx = self._material_index(flat.get("material"), flat["v0"].size)
        return flat["v0"], flat["F"], idx, shape

    def _pchip_along_F(self) -> np.ndarray:
        """The PCHIP along F through every (material, v0) row of the table, built once: its
        coefficients on (material, v0, F cell, power); no cells for a single load."""
        from scipy.interpolate import PchipInterpolator

        if self.F.size == 1:
            return np.empty((0, 0, 0, 4))
        c = PchipInterpolator(self._nodes["F"], self.values, axis=2).c
        return np.ascontiguousarray(c.transpose(2, 3, 1, 0))   # a node's four together

    def _interpolate(self, i: np.ndarray, vq: np.ndarray, fq: np.ndarray) -> np.ndarray:
        """e at (material index, v0, F) queries inside the table: PCHIP along F on the v0
        nodes of each query's stencil, then along v0 through those
        (:func:`sweep.kernels.lookup.interpolate`)."""
        out = np.empty(vq.size)
        _interpolate_kernel(self._nodes["v0"], self._nodes["F"], self._F_pieces, self.values,
                            i, self._coord("v0", vq), self._coord("F", fq), out)
        return out

    def __call__(self, v0: Any, F: Any = None, material: Any = None,
                 collapse: str = "interpolate") -> np.ndarray | float:
        """Interpolated e [1] at impact speeds v0 [m/s] and loads F [N] (broadcast; a float
        where all are scalars, as :func:`sweep.cor` gives).

        ``F`` may be omitted when the table has one load, ``material`` when it has one
        material. ``collapse="direct"`` computes the queries in a collapse cell
        (:meth:`collapsing`) directly (:meth:`direct`) instead of interpolating them:
        there the interpolant is only within ``error()["collapse_bound"]``, while the rest
        of the table is within ``error()["away_max_abs"]``.

        Raises
        ------
        ValueError
            v0 or F not real numbers (a string is not parsed) or outside the table, shapes
            that do not broadcast (naming v0, F, material), a missing or unknown material,
            a ``collapse`` other than ``"interpolate"`` or ``"direct"``.
        """
        if not isinstance(collapse, str) or collapse not in COLLAPSE_CHOICES:
            raise ValueError(f"collapse = {collapse!r}: must be one of "
                             f"{', '.join(map(repr, COLLAPSE_CHOICES))}")
        vq, fq, idx, shape = self._inside(v0, F, material)
        out = np.empty(vq.size)
        for start in range(0, vq.size, _BLOCK):
            block = slice(start, start + _BLOCK)
            out[block] = self._interpolate(idx[block], vq[block], fq[block])
        if collapse == "direct":
            near = self._in_collapse(idx, vq, fq)
            if near.any():
                out[near] = self._direct_at(idx[near], vq[near], fq[near])
        return float(out[0]) if shape == () else out.reshape(shape)

    def collapsing(self, v0: Any, F: Any = None, material: Any = None) -> np.ndarray | bool:
        """Whether each query (arguments and errors as for :meth:`__call__`) lies in a
        collapse cell (:meth:`collapse_cells`: e falls to 0 inside it, at the no-rebound
        speed or load), where the interpolant is only within the cell's largest corner
        (``error()["collapse_bound"]``) and :meth:`direct` gives e; a bool where all are
        scalars."""
        vq, fq, idx, shape = self._inside(v0, F, material)
        near = self._in_collapse(idx, vq, fq)
        return bool(near[0]) if shape == () else near.reshape(shape)

    def _inside(self, v0: Any, F: Any, material: Any) -> tuple[np.ndarray, ...]:
        """:meth:`_queries` with F defaulted to the table's only load and each query
        checked to lie in the table (an end's rounding taken at the end)."""
        if F is None:
            if self.F.size != 1:
                raise ValueError(f"F is required: the table has loads {self.F.min():g} .. "
                                 f"{self.F.max():g} N")
            F = self.F[0]
        vq, fq, idx, shape = self._queries(v0, F, material)
        return self._in_range("v0", vq), self._in_range("F", fq), idx, shape

    def _in_collapse(self, idx: np.ndarray, vq: np.ndarray, fq: np.ndarray) -> np.ndarray:
        """Queries (flat, inside the table) that fall in a collapse cell."""
        return self._collapse[idx, self._cell_of("v0", vq), self._cell_of("F", fq)]

    # -- direct computation and the held-back check ---------------------------------------

    def direct(self, v0: Any, F: Any, material: Any = None) -> np.ndarray:
        """e [1] computed directly (the table's method and settings) at impact speeds v0
        [m/s], loads F [N] and materials (broadcast; errors as for :meth:`__call__`)."""
        vq, fq, idx, shape = self._queries(v0, F, material)
        return self._direct_at(*(a.reshape(shape) for a in (idx, vq, fq)))

    def _direct_at(self, idx: np.ndarray, vq: np.ndarray, fq: np.ndarray) -> np.ndarray:
        """:meth:`direct` at material indices ``idx``, speeds ``vq`` and loads ``fq``."""
        p = {name: values[idx] for name, values in self.properties.items()}
        gamma, gtilde = scale(p["m"], p["k"], p["gamma0"], vq, p["alpha"], p["beta"], self.g,
                              fq)
        return np.asarray(api.cor(p["alpha"], p["beta"], gamma, gtilde, method=self.method,
                                  **self.options))

    def held_back_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points inside the cells of every material's table: (material index, v0, F)."""
        axes = []
        for axis in ("v0", "F"):
            x = self._nodes[axis]
            inside = [x[:-1] + f * np.diff(x) for f in HELD_BACK_FRACTIONS] if x.size > 1 else []
            lattice = np.sort(np.concatenate([x, *inside]))
            axes.append((np.exp(lattice) if self.log[axis] else lattice,
                         np.isin(lattice, x)))
        (v, v_node), (f, f_node) = axes
        vv, ff = np.meshgrid(v, f, indexing="ij")
        keep = ~np.logical_and.outer(v_node, f_node)  # the table's own nodes are not held back
        vv, ff = vv[keep], ff[keep]
        n = len(self.materials)
        return (np.repeat(np.arange(n), vv.size), np.tile(vv, n), np.tile(ff, n))

    def _cell_corners(self) -> tuple[np.ndarray, list[tuple[int, int]]]:
        """e at the corners of every cell, (corner, material, v0 cell, F cell), and each
        corner's node offsets (v0, F) from the cell's first; an axis of one node has one
        cell, that node."""
        dv = (0, 1) if self.v0.size > 1 else (0,)
        df = (0, 1) if self.F.size > 1 else (0,)
        offsets = [(a, b) for a in dv for b in df]
        nv, nf = self.v0.size - len(dv) + 1, self.F.size - len(df) + 1
        return (np.stack([self.values[:, a:a + nv, b:b + nf] for a, b in offsets]),
                offsets)

    def collapse_cells(self) -> np.ndarray:
        """Cells where e falls to 0 at some corners but not all (the no-rebound speed or
        load inside): bool on (material, v0 cell, F cell)."""
        return self._collapse.copy()

    def _cell_of(self, axis: str, q: np.ndarray) -> np.ndarray:
        x = self._nodes[axis]
        if x.size == 1:
            return np.zeros(q.size, dtype=np.intp)
        return _cells(x, self._coord(axis, q))

    def _collapse_bound(self, corners: np.ndarray, offsets: list[tuple[int, int]],
                        collapse: np.ndarray) -> tuple[float, dict]:
        """The bound of the collapse cells (of :meth:`_cell_corners`' ``corners`` and
        ``offsets``), their largest corner (e lies between 0 and it where it is monotone in
        the cell, and so does the monotone interpolant), and where: that node's material,
        v0 [m/s] and F [N]."""
        if not collapse.any():
            return 0.0, {}
        top = np.where(collapse, corners.max(axis=0), -1.0)
        i, j, k = np.unravel_index(int(np.argmax(top)), top.shape)
        dv, df = offsets[int(np.argmax(corners[:, i, j, k]))]
        return float(top[i, j, k]), {"material": self.materials[i],
                                     "v0": float(self.v0[j + dv]), "F": float(self.F[k + df])}

    def error(self) -> dict[str, Any]:
        """Interpolation error against direct computation: on the held-back points, and in
        the cells where e collapses to 0, their bound (module docstring).

        Returns
        -------
        dict
            ``max_abs`` (the stated error: the larger of the two), ``where`` (its material,
            v0 [m/s] and F [N]; a collapse cell's largest node), ``held_back_max_abs``,
            ``median_abs`` and ``n_points`` (on the held-back points), ``away_max_abs``
            (held-back points outside the collapse cells), ``collapse_cells`` (their
            number), ``collapse_bound``, ``variable``.
        """
        idx, v, f = self.held_back_points()
        names = np.array(self.materials)[idx]   # str: resolved without a Python loop
        d = np.abs(self(v, f, names) - self.direct(v, f, names))
        d = np.where(np.isnan(d), np.inf, d)  # an invalid point is no agreement
        corners, offsets = self._cell_corners()
        away = ~self._in_collapse(idx, v, f)
        bound, where = self._collapse_bound(corners, offsets, self._collapse)
        held = float(d.max()) if d.size else 0.0
        if held >= bound and d.size:
            w = int(np.argmax(d))
            where = {"material": str(names[w]), "v0": float(v[w]), "F": float(f[w])}
        return {"variable": self.variable, "n_points": int(d.size),
                "max_abs": max(held, bound), "where": where, "held_back_max_abs": held,
                "median_abs": float(np.median(d)) if d.size else 0.0,
                "away_max_abs": float(d[away].max()) if away.any() else 0.0,
                "collapse_cells": int(self._collapse.sum()), "collapse_bound": bound}


def lookup(dataset: Any, v0: Any, F: Any = None, material: Any = None,
           variable: str | None = None, collapse: str = "interpolate") -> np.ndarray | float:
    """Interpolated e [1] of a scene dataset at impact speeds v0 [m/s] and loads F [N].

    One-call form of :class:`Table` (which also reports the interpolation error, see
    :meth:`Table.error`): monotone PCHIP along v0 and F, in log where the axis is log.

    Parameters
    ----------
    dataset : path-like or xarray.Dataset
        Output of ``sweep run`` for a scene configuration.
    v0, F : array_like
        Impact speeds [m/s] and loads [N], broadcast together (F may be omitted when the
        table has a single load).
    material : str or array_like of str, optional
        Material names (may be omitted when the table has one material).
    variable : str, optional
        Tabulated variable (default ``e_numeric``, else ``e_auto``).
    collapse : {"interpolate", "direct"}, optional
        ``"direct"``: queries in a cell where e falls to 0 (the no-rebound speed or load;
        :meth:`Table.collapsing`) are computed directly instead of interpolated.

    Returns
    -------
    ndarray or float
        A float where v0, F and material are all scalars.
    """
    return Table(dataset, variable)(v0, F, material, collapse)


def _rows(ds: Any, variables: list[str]) -> Iterator[list[str]]:
    """The CSV's rows, one per (material, v0, F), made as they are written: the file's
    size does not bound the memory used (all rows at once took ~600 bytes each)."""
    arrays = [ds[v].transpose(*SCENE_DIMS).values for v in variables]
    v0, F = ds["v0"].values, ds["F"].values
    for i, name in enumerate(_material_names(ds)):
        for j, v in enumerate(v0):
            for k, f in enumerate(F):
                yield [name, repr(float(v)), repr(float(f))] + [repr(float(a[i, j, k]))
                                                                  for a in arrays]


def _write_csv(ds: Any, path: Path, variables: list[str]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["material", "v0 [m/s]", "F [N]"] + [f"{v} [1]" for v in variables])
        w.writerows(_rows(ds, variables))


def _write_npz(ds: Any, path: Path, variables: list[str], error: dict | None) -> None:
    units = {name: _unit(ds, name) for name in
             ["v0", "F", "g", *_MATERIAL_VARIABLES, *variables]}
    # A code that interpolates as Table does needs each axis's spacing (log or linear).
    spacing = {axis: str(ds[axis].attrs.get("spacing", "")) for axis in ("v0", "F")}
    extra = {} if error is None else {"lookup_error": np.array(json.dumps(error))}
    # The tabulated methods' own error comes on top of the lookup's: their settings (auto's
    # tol, the integrator's) say how large it is.
    settings = {v: api.recorded_settings(ds.attrs, v[2:]) for v in variables
                if v.startswith("e_") and v[2:] in registry.METHODS}
    # Through an open file: given a name, numpy.savez appends ".npz" to one without it.
    with open(path, "wb") as f:
        np.savez(f, material=np.array(_material_names(ds)),
                 v0=ds["v0"].values, F=ds["F"].values, g=ds["g"].values,
                 units=np.array(json.dumps(units)), spacing=np.array(json.dumps(spacing)),
                 settings=np.array(json.dumps(settings, default=str)), **extra,
                 **{n: ds[n].values for n in _MATERIAL_VARIABLES},
                 **{v: ds[v].transpose(*SCENE_DIMS).values for v in variables})


def _exported_variables(ds: Any, variables: list[str] | None) -> list[str]:
    """The variables :func:`export` writes (its default where None), refusing a dataset
    that is not a scene's or a variable it does not hold (named)."""
    if not all(d in ds.dims for d in SCENE_DIMS):
        raise ValueError(f"not a scene dataset: dimensions {tuple(ds.dims)}")
    if variables is None:
        variables = [v for v in ("gamma", "gtilde") if v in ds] + [
            str(v) for v in ds.data_vars if str(v).startswith("e_")]
    missing = [v for v in variables if v not in ds.data_vars]
    if missing:
        raise ValueError(f"the dataset has no variable {missing[0]!r}; it has "
                         f"{', '.join(map(str, ds.data_vars))}")
    return variables


def export(dataset: Any, path: str | os.PathLike, fmt: str | None = None,
           variables: list[str] | None = None, error: dict | None = None) -> Path:
    """Write a scene's table as CSV or NumPy ``.npz``.

    Parameters
    ----------
    dataset : path-like or xarray.Dataset
        A scene dataset.
    path : path-like
        Output file, written at exactly this path whatever its suffix (``-o x.csv`` with
        the npz format writes x.csv, not numpy's x.csv.npz).
    fmt : {"csv", "npz"}, optional
        Format (default: from the suffix of ``path``).
    variables : list of str, optional
        Per-point variables written (default: gamma, gtilde, every ``e_<method>`` and
        ``e_err`` where stored).
    error : dict, optional
        A table's :meth:`Table.error`, stored in the npz as the JSON ``lookup_error``
        (the CSV has no place for it).

    Returns
    -------
    Path
        The file written, ``path``. CSV: one row per (material, v0, F), the unit in each
        column name, written row by row (bounded memory). npz: ``material`` (the names),
        ``v0`` [m/s], ``F`` [N], each variable on (material, v0, F), the per-material
        ``m``, ``k``, ``gamma0``, ``alpha``, ``beta``, ``g``, a JSON ``units`` string
        (k and gamma0 whose unit depends on the law: the rule, e.g. ``"N m^-alpha"``), a
        JSON ``spacing`` string (each axis's: ``"log"``, ``"linear"``, ``"irregular"`` or
        ``"single"``; :class:`Table` interpolates in log v0, log F where ``"log"``), a
        JSON ``settings`` string (each ``e_<method>``'s settings, as the dataset records
        them: auto's ``tol``, the integrator's ``steps`` or ``tol``; their error adds to
        the lookup's) and, given ``error``, ``lookup_error``.

    Raises
    ------
    ValueError
        An unknown format, not a scene dataset, a variable it does not have (named), or
        ``path`` the dataset's own file.
    OSError
        The dataset cannot be read, or ``path`` written (named in either case, a full
        disk included).
    """
    path = Path(path)
    if isinstance(dataset, (str, os.PathLike)) and store.same_file(path, dataset):
        # Written over, the dataset was replaced by its export, exit 0.
        raise ValueError(f"the output {path} is the dataset itself; give another -o")
    ds = _open(dataset)
    fmt = fmt or path.suffix.lstrip(".")
    if fmt not in ("csv", "npz"):
        raise ValueError(f"format must be 'csv' or 'npz', got {fmt!r}")
    variables = _exported_variables(ds, variables)
    path.parent.mkdir(parents=True, exist_ok=True)   # as sweep run makes its output's
    with naming(path):
        if fmt == "csv":
            _write_csv(ds, path, variables)
        else:
            _write_npz(ds, path, variables, error)
    return path
