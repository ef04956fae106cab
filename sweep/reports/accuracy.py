"""``sweep report accuracy DATASET.nc``: where each approximation is accurate.

For every approximation stored in a dataset written by ``sweep run`` (``e_<method>`` next to
``e_numeric``, or ``error_<method>``), one PNG with a heat map of ``|e_method - e_numeric|``
over (gamma, g~) on log axes and a log colour scale, one panel per contact model (alpha,
beta) of the dataset. Drawn over it:

* the numerical stick/rebound boundary: the 0.5 contour of ``sticks`` (grid designs) or of
  its triangulation (scattered designs);
* the report's approximate boundary (24), ``g~_c = (1 / (2 gamma C))^(1/r)``.

A design that samples the exponents (more than :data:`MAX_MODELS` distinct (alpha, beta)
pairs, e.g. a Sobol' design) gets one panel per (alpha, beta) bin instead (split at the
medians), drawn as hexagonal bins holding the *largest* error of their points; the two
boundaries are then those of the bin's median model (the numerical one by
:func:`sweep.critical.critical_gtilde`, since points of different exponents do not make one
stick/rebound curve). Table rows are per bin as well, with each point's region decided by
its own (24).

Zero errors (both the approximation and the numerical CoR are 0, deep in the stick region)
are drawn white, points where the error is undefined (an approximation outside its domain,
such as "sp" away from KK, or a point whose numerical CoR is not converged) light grey.
gamma = 0 or g~ = 0 points cannot sit on log axes: they are left out of the maps (not of
the table).

The table (``accuracy.csv``, ``accuracy.md``) gives, per method and model, the maximum and
median absolute error in these regions:

``all``
    every point with a decided numerical outcome (status ok, stuck or at rest);
``rebound`` / ``stick``
    by the numerical outcome;
``rebound, gamma <= 0.01, g~ <= g~_c/2`` (and ``0.01 < gamma <= 0.1``, ``gamma > 0.1``)
    rebounds well inside the report's boundary (24), by damping band: the expansions in
    gamma are meant for small gamma;
``rebound, g~ > g~_c/2``
    rebounds near (or beyond) the boundary (24), where e collapses steeply to 0.

Points whose numerical computation ran out of budget or was invalid are excluded from every
region and counted in the ``excluded`` column.

May import: numpy, xarray (lazily), :mod:`sweep.model`, :mod:`sweep.critical`,
:mod:`sweep.registry` (the methods), :mod:`sweep.store` (:func:`~sweep.store.open_dataset`) and
:mod:`sweep.reports.common`; matplotlib lazily,
after :func:`sweep.reports.common.use_agg` has set its backend.
"""
from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from sweep import registry, store
from sweep.model import Status
from sweep.reports.common import make_out_dir, use_agg, write_table

__all__ = ["accuracy_report", "load_errors", "model_groups", "region_masks", "region_table",
           "REGIONS", "critical_gtilde_24", "MAX_MODELS"]

REGIONS = ("all", "rebound", "stick", "rebound, gamma <= 0.01, g~ <= g~_c/2",
           "rebound, 0.01 < gamma <= 0.1, g~ <= g~_c/2", "rebound, gamma > 0.1, g~ <= g~_c/2",
           "rebound, g~ > g~_c/2")
_PARAMS = ("alpha", "beta", "gamma", "gtilde")


def critical_gtilde_24(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike) -> np.ndarray:
    """The report's no-rebound threshold (24), ``g~_c = (1/(2 gamma C))^(1/r)`` [1]
    (``inf`` at gamma = 0): :func:`sweep.critical.critical_gtilde` with method "approx"."""
    from sweep.critical import critical_gtilde

    return critical_gtilde(alpha, beta, gamma, method="approx")


def _flat(ds, name, like):
    import xarray as xr

    da = ds[name]
    if da.dims == like.dims:
        return np.asarray(da.values).reshape(-1)
    a, _ = xr.broadcast(da, like)
    return np.asarray(a.transpose(*like.dims).values).reshape(-1)


def _refuse_unmarked_budget_points(ds: Any) -> None:
    """Raise where the run recorded budget-exhausted points but the dataset has no status.

    Such a point's ``e_numeric`` is an upper bound, not a value, so its error is not one;
    without ``status`` it cannot be excluded (nor counted in ``excluded``), and a finite
    upper bound would pass a NaN test. The runner records how many there were in the
    global attribute ``points_budget_exhausted`` (:data:`sweep.store.CAVEAT_ATTRS`).
    """
    n = int(ds.attrs.get("points_budget_exhausted", 0) or 0)
    if n > 0:
        raise ValueError(f"{n:,} point(s) ran out of the step budget (their e_numeric is "
                         "an upper bound, not a value) and the dataset stores no status "
                         "to exclude them: rerun with 'status' in outputs.fields, or a "
                         "larger integrator.max_steps")


def load_errors(ds: Any) -> dict[str, Any]:
    """Flat per-point arrays of a sweep dataset (grid or scattered).

    Returns
    -------
    dict
        ``alpha``, ``beta``, ``gamma``, ``gtilde``, ``sticks`` (bool), ``decided`` (bool:
        the numerical outcome is known, status ok / stuck / at rest), ``errors``
        (method -> ``|e_method - e_numeric|``, NaN where undefined), ``methods`` (in the
        order of :func:`sweep.registry.approximations`).

    Raises
    ------
    ValueError
        No approximation error can be formed (needs ``e_numeric`` with ``e_<method>``, or
        ``error_<method>``), or the run recorded budget-exhausted points
        (``points_budget_exhausted``) that the dataset has no ``status`` to exclude.
    """
    # The registry itself, not sweep.api.APPROXIMATIONS (the built-ins when the api was
    # imported): a method registered later is reported too.
    methods = [m for m in registry.approximations()
               if f"error_{m}" in ds or (f"e_{m}" in ds and "e_numeric" in ds)]
    if not methods:
        raise ValueError("the dataset holds no approximation error: it needs e_numeric with "
                         "e_<method>, or error_<method> (run a sweep with outputs.e "
                         "including 'numeric' and approximations)")
    like = ds[f"error_{methods[0]}"] if f"error_{methods[0]}" in ds else ds[f"e_{methods[0]}"]
    out = {p: _flat(ds, p, like).astype(float) for p in _PARAMS}
    e_num = _flat(ds, "e_numeric", like) if "e_numeric" in ds else None
    if "status" in ds:
        status = _flat(ds, "status", like).astype(int)
        decided = np.isin(status, (Status.OK, Status.STUCK, Status.AT_REST))
    else:
        _refuse_unmarked_budget_points(ds)
        status = None
        decided = np.isfinite(e_num) if e_num is not None else np.ones(like.size, bool)
    if "sticks" in ds:
        sticks = _flat(ds, "sticks", like).astype(bool)
    elif status is not None:
        sticks = np.isin(status, (Status.STUCK, Status.AT_REST))
    elif e_num is not None:
        sticks = e_num == 0.0
    else:
        raise ValueError("the dataset has neither sticks, status nor e_numeric: the "
                         "stick/rebound outcome is unknown")
    errors = {}
    for m in methods:
        if f"error_{m}" in ds:
            err = np.abs(_flat(ds, f"error_{m}", like).astype(float))
        else:
            err = np.abs(_flat(ds, f"e_{m}", like).astype(float) - e_num)
        err[~decided] = np.nan
        errors[m] = err
    out.update(sticks=sticks, decided=decided, errors=errors, methods=methods)
    return out


#: More distinct (alpha, beta) pairs than this (a design sampling the exponents): panels
#: and table rows are per (alpha, beta) bin instead, split at the medians.
MAX_MODELS = 6


def model_groups(data: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The panels / table groups of a dataset: one per contact model, or per exponent bin.

    Returns
    -------
    list of dict
        ``alpha``, ``beta`` (the value, or a ``"[lo, hi]"`` range string for a bin),
        ``mask`` (points of the group), ``exact`` (a single model), ``a_rep``, ``b_rep``
        (the model, or the bin's medians, at which boundary curves are drawn).
    """
    a, b = data["alpha"], data["beta"]
    pairs = sorted(set(zip(a.tolist(), b.tolist())))
    if len(pairs) <= MAX_MODELS:
        return [{"alpha": pa, "beta": pb, "mask": (a == pa) & (b == pb), "exact": True,
                 "a_rep": pa, "b_rep": pb} for pa, pb in pairs]

    def halves(x):
        lo, hi = float(x.min()), float(x.max())
        if lo == hi:
            return [(np.ones(x.size, bool), f"{lo:g}", lo)]
        med = float(np.median(x))
        low = x <= med
        return [(low, f"[{lo:.3g}, {med:.3g}]", float(np.median(x[low]))),
                (~low, f"({med:.3g}, {hi:.3g}]", float(np.median(x[~low])))]

    groups = []
    for ma, la, ra in halves(a):
        for mb, lb, rb in halves(b):
            if (ma & mb).any():
                groups.append({"alpha": la, "beta": lb, "mask": ma & mb, "exact": False,
                               "a_rep": float(np.median(a[ma & mb])),
                               "b_rep": float(np.median(b[ma & mb]))})
    return groups


def region_masks(data: Mapping[str, Any], group_mask: np.ndarray) -> dict[str, np.ndarray]:
    """Boolean masks of :data:`REGIONS` for the points of one group.

    The boundary (24) is evaluated at each point's own (alpha, beta).
    """
    model = group_mask & data["decided"]
    sticks = data["sticks"]
    gc = critical_gtilde_24(data["alpha"], data["beta"], data["gamma"])
    near = data["gtilde"] > 0.5 * gc
    far = model & ~sticks & ~near
    g = data["gamma"]
    return {
        "all": model,
        "rebound": model & ~sticks,
        "stick": model & sticks,
        REGIONS[3]: far & (g <= 0.01),
        REGIONS[4]: far & (g > 0.01) & (g <= 0.1),
        REGIONS[5]: far & (g > 0.1),
        REGIONS[6]: model & ~sticks & near,
    }


def region_table(data: Mapping[str, Any],
                 groups: list[dict[str, Any]] | None = None) -> list[dict[str, Any]]:
    """Rows (dicts) of max / median abs error per method, model (or bin) and region."""
    rows = []
    groups = model_groups(data) if groups is None else groups
    for m in data["methods"]:
        err = data["errors"][m]
        for grp in groups:
            excluded = int(np.count_nonzero(grp["mask"] & ~data["decided"]))
            for region, mask in region_masks(data, grp["mask"]).items():
                e = err[mask]
                finite = np.isfinite(e)
                row = {"method": m, "alpha": grp["alpha"], "beta": grp["beta"],
                       "region": region, "n_points": int(mask.sum()),
                       "n_undefined": int((~finite).sum()), "excluded": excluded,
                       "max_abs_error": None, "median_abs_error": None,
                       "gamma_at_max": None, "gtilde_at_max": None}
                if finite.any():
                    idx = np.flatnonzero(mask)[finite]
                    k = idx[np.argmax(err[idx])]
                    row.update(max_abs_error=float(err[k]),
                               median_abs_error=float(np.median(err[idx])),
                               gamma_at_max=float(data["gamma"][k]),
                               gtilde_at_max=float(data["gtilde"][k]))
                rows.append(row)
    return rows


def _edges(v):
    """Cell edges (geometric midpoints) of sorted positive values for pcolormesh."""
    v = np.asarray(v, dtype=float)
    if v.size == 1:
        return np.array([v[0] / 1.25, v[0] * 1.25])
    lv = np.log(v)
    mid = 0.5 * (lv[1:] + lv[:-1])
    return np.exp(np.concatenate([[lv[0] - (mid[0] - lv[0])], mid,
                                  [lv[-1] + (lv[-1] - mid[-1])]]))


#: Above this many points in a scattered panel, draw hexagonal bins (max per cell).
HEXBIN_ABOVE = 5000


def _nanmax(v):
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    return v.max() if v.size else np.nan


def _grid_map(ax, g, G, z, sticks, exact, norm, cmap):
    """A full grid over (gamma, g~): cells, and the 0.5 contour of ``sticks``."""
    gu, Gu = np.unique(g), np.unique(G)
    i = np.searchsorted(gu, g)
    j = np.searchsorted(Gu, G)
    Z = np.full((Gu.size, gu.size), np.nan)
    Z[j, i] = z
    S = np.zeros((Gu.size, gu.size))
    S[j, i] = sticks
    mappable = ax.pcolormesh(_edges(gu), _edges(Gu), np.ma.masked_invalid(Z), norm=norm,
                             cmap=cmap, shading="flat")
    if exact and gu.size > 1 and Gu.size > 1 and 0 < S.sum() < S.size:
        ax.contour(gu, Gu, S, levels=[0.5], colors="k", linewidths=1.2)
    return mappable, (_edges(gu)[0], _edges(gu)[-1]), (_edges(Gu)[0], _edges(Gu)[-1])


def _scattered_map(ax, g, G, z, sticks, exact, norm, cmap):
    """Scattered points: hexagonal bins (largest error) or dots, and the triangulated
    0.5 contour of ``sticks``."""
    if g.size > HEXBIN_ABOVE:
        mappable = ax.hexbin(g, G, C=z, xscale="log", yscale="log", gridsize=(70, 45),
                             reduce_C_function=_nanmax, norm=norm, cmap=cmap,
                             linewidths=0.0)
    else:
        mappable = ax.scatter(g, G, c=z, norm=norm, cmap=cmap, s=8, edgecolors="none",
                              plotnonfinite=True)
    if exact and g.size >= 3 and 0 < sticks.sum() < sticks.size:
        try:
            import matplotlib.tri as mtri

            # Delaunay in log coordinates (where the points are spread evenly), drawn
            # with the same triangles in data coordinates on the log axes.
            tri = mtri.Triangulation(np.log10(g), np.log10(G))
            flat = mtri.TriAnalyzer(tri).get_flat_tri_mask(min_circle_ratio=0.05)
            tri = mtri.Triangulation(g, G, triangles=tri.triangles, mask=flat)
            ax.tricontour(tri, sticks.astype(float), levels=[0.5], colors="k",
                          linewidths=1.2)
        except Exception:  # pragma: no cover - degenerate triangulations
            pass
    return mappable, (g.min(), g.max()), (G.min(), G.max())


def _boundaries_and_labels(ax, grp, xlim, ylim):
    """Log axes, the boundary (24) and, for exponent bins, the numerical one; labels."""
    a, b = grp["a_rep"], grp["b_rep"]
    ax.set_xscale("log")
    ax.set_yscale("log")
    gg = np.geomspace(*xlim, 200)
    ax.plot(gg, critical_gtilde_24(a, b, gg), "r--", lw=1.2)
    if not grp["exact"]:
        # mixed exponents: the points' own stick decisions do not make one curve; draw
        # the numerical boundary of the bin's median model instead
        from sweep.critical import critical_gtilde

        gn = np.geomspace(*xlim, 40)
        ax.plot(gn, critical_gtilde(a, b, gn, method="numeric"), "k-", lw=1.2)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_xlabel(r"$\gamma$")
    ax.set_ylabel(r"$\tilde g$")
    if grp["exact"]:
        ax.set_title(rf"$\alpha={a:g}$, $\beta={b:g}$")
    else:
        ax.set_title(f"alpha in {grp['alpha']}, beta in {grp['beta']}\n(curves at the "
                     f"medians alpha = {a:.3g}, beta = {b:.3g})", fontsize=9)


def _panel(ax, data, err, grp, norm, cmap):
    """Draw one group's map; returns the mappable (or None if nothing to draw)."""
    sel = grp["mask"] & (data["gamma"] > 0) & (data["gtilde"] > 0)
    g, G = data["gamma"][sel], data["gtilde"][sel]
    z = err[sel].copy()
    sticks = data["sticks"][sel]
    z = np.where(z == 0.0, norm.vmin * 1e-3, z)      # exact zeros: the "under" colour
    if g.size == 0:
        ax.text(0.5, 0.5, "no point with gamma > 0 and g~ > 0", ha="center",
                transform=ax.transAxes)
        return None
    grid = np.unique(g).size * np.unique(G).size == g.size
    draw = _grid_map if grid else _scattered_map
    mappable, xlim, ylim = draw(ax, g, G, z, sticks, grp["exact"], norm, cmap)
    _boundaries_and_labels(ax, grp, xlim, ylim)
    return mappable


def _plot_method(path, data, m, groups, title):
    plt = use_agg()
    from matplotlib.colors import LogNorm
    from matplotlib.lines import Line2D

    err = data["errors"][m]
    pos = err[np.isfinite(err) & (err > 0)]
    vmax = float(pos.max()) if pos.size else 1.0
    vmin = float(pos.min()) if pos.size else 1e-16
    vmin = max(vmin, vmax * 1e-14, 1e-17)
    if vmin >= vmax:
        vmin = vmax / 10.0
    norm = LogNorm(vmin=vmin, vmax=vmax)
    cmap = plt.get_cmap("viridis").with_extremes(under="white", bad="lightgrey")
    n = len(groups)
    ncol = min(n, 2)
    nrow = -(-n // ncol)
    width, height = 5.6 * ncol + 1.4, 4.4 * nrow + 0.9
    fig, axes = plt.subplots(nrow, ncol, figsize=(width, height), squeeze=False)
    # a fixed layout: constrained layout costs seconds per figure with log axes
    fig.subplots_adjust(left=0.75 / width, right=1 - 1.45 / width, bottom=0.6 / height,
                        top=1 - 1.0 / height, wspace=0.28, hspace=0.45)
    mappable = None
    for ax, grp in zip(axes.flat, groups):
        mappable = _panel(ax, data, err, grp, norm, cmap) or mappable
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    if mappable is not None:
        cax = fig.add_axes([1 - 1.2 / width, 0.6 / height + 0.05, 0.18 / width,
                            1 - 1.6 / height - 0.1])
        cb = fig.colorbar(mappable, cax=cax, extend="min")
        cb.set_label(f"|e({m}) - e(numeric)|")
    handles = [Line2D([], [], color="k", lw=1.2, label="numerical stick/rebound boundary"),
               Line2D([], [], color="r", ls="--", lw=1.2, label=r"report's $\tilde g_c$ (24)")]
    axes.flat[0].legend(handles=handles, loc="lower left", fontsize=8, framealpha=0.8)
    fig.suptitle(f"{title}\n|e_{m} - e_numeric| (white: 0; grey: undefined)", fontsize=10)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def accuracy_report(path: str | os.PathLike, out: str | os.PathLike | None = None, *,
                    methods: Sequence[str] | None = None) -> dict[str, Any]:
    """Write the accuracy maps and the per-region error table of a sweep dataset.

    Parameters
    ----------
    path : path-like
        netCDF dataset written by ``sweep run`` (grid or scattered design).
    out : path-like, optional
        Output directory (created); default ``<dataset stem>_accuracy`` beside it.
    methods : sequence of str, optional
        Restrict to these approximations (default: all stored).

    Returns
    -------
    dict
        ``out`` (Path), ``files`` (list of Path), ``rows`` (the table, see
        :func:`region_table`), ``markdown``.

    Raises
    ------
    OSError
        ``path`` cannot be read or is not netCDF (:func:`sweep.store.open_dataset`).
    ValueError
        The dataset holds no approximation and its error, or not ``methods``, or
        budget-exhausted points without the ``status`` to exclude them.
    """
    path = Path(path)
    with store.open_dataset(path) as ds:
        data = load_errors(ds)
        title = str(ds.attrs.get("title", path.name))
    # after the dataset was read: a file that is none leaves no empty directory behind
    out = make_out_dir(out if out is not None else path.with_name(path.stem + "_accuracy"),
                       path)
    if methods is not None:
        unknown = [m for m in methods if m not in data["methods"]]
        if unknown:
            raise ValueError(f"methods {unknown} are not in the dataset "
                             f"(it has {data['methods']})")
        data["methods"] = list(methods)
    groups = model_groups(data)
    files = []
    for m in data["methods"]:
        f = out / f"accuracy_{m}.png"
        _plot_method(f, data, m, groups, title)
        files.append(f)
    rows = region_table(data, groups)
    cols = ["method", "alpha", "beta", "region", "n_points", "n_undefined", "excluded",
            "max_abs_error", "median_abs_error", "gamma_at_max", "gtilde_at_max"]
    notes = [f"dataset: {path.name} ({title})",
             "error = |e_method - e_numeric|; g~_c from the report's eq. (24); excluded = "
             "points whose numerical outcome is undecided (budget exhausted or invalid); "
             "n_undefined = points where the approximation is not defined (NaN)."]
    md = write_table(rows, cols, out / "accuracy.csv", out / "accuracy.md",
                     formats={"gamma_at_max": ".4g", "gtilde_at_max": ".4g"},
                     title="Absolute error of the approximations against the numerical CoR",
                     notes=notes)
    files += [out / "accuracy.csv", out / "accuracy.md"]
    return {"out": out, "files": files, "rows": rows, "markdown": md}
