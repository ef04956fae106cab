"""``sweep report paper``: the report's Tables 2-5 and Figures 8-11, recomputed.

Tables 2-5
----------
For each of the report's four models (Hertz + linear damping, TTI, KK, SHC) and loads
g~ in {0, 0.05, 1, 10}: the O(gamma^2) approximation of Prop. 2, (36)-(38), with I(g~), Q(g~)
by quadrature (``ord2_numint``; exact (39), (40) at g~ = 0) and by the Chebyshev-Beta
approximation (``ord2_approx``, n = 21), against the numerical CoR (``numeric``), on the
report's gamma grid::

    gamma = linspace(0, G, n_gamma),   G = min(0.1, 1.1 gamma_c(g~)),

gamma_c the no-rebound threshold (24) (G = 0.1 for g~ <= 1 except SHC at g~ = 1), and the
maximum absolute error per window ``gamma < 0.2 G``, ``0.2 G <= gamma <= 0.92 G``,
``gamma > 0.92 G`` (see :mod:`sweep.reports.paper_values` for why these are the report's windows).
The report prints two windows for g~ <= 1 (``gamma < 0.02`` and ``gamma >= 0.02``, the
latter the union of the last two) and three for g~ = 10.

Where e collapses steeply to 0 the maximum depends on where grid points fall, so every
maximum is also computed on the same grid shifted by half a step (``max_shifted``): when the
two differ a lot, so may ours and the report's, for that reason alone.

Figures 8-11
------------
g~_c against gamma: the smallest g~ at which the bead no longer rebounds, by bisection on the
numerical outcome (:func:`sweep.critical.critical_gtilde`, method "numeric"), against the
report's (24); and the relative error ``|g~_c,num - g~_c,(24)| / g~_c,num`` for gamma <= 0.3.

Step budget
-----------
``steps`` asks for a finer march, which takes proportionally more steps (2 to 5 times
``steps`` on the report's grids), so the step budget per point grows with it: the package
default's per unit of resolution (:func:`step_budget`). A point that still runs out of it
(or a g~_c whose bisection met one) has a bound, not a value: the report then stops with
:class:`UndecidedError` before it writes anything.

May import: numpy, :mod:`sweep.critical`, :mod:`sweep.registry`, the public ``sweep``
names, :mod:`sweep.reports.common` and :mod:`sweep.reports.paper_values`; matplotlib lazily,
after :func:`sweep.reports.common.use_agg` has set its backend.
"""
from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

import sweep
from sweep.critical import RTOL
from sweep.registry import MAX_STEP_BUDGET, Status
from sweep.reports.common import (format_value, log_progress, machine_description,
                                  machine_line, make_out_dir, staged, use_agg, write_table)
from sweep.reports.paper_values import (FIGURES_CRITICAL, GAMMA_MAX, GRID_END_FACTOR,
                                        GTILDES, PAPER_MODELS, TABLE_A, TABLE_B,
                                        TABLE_B_EDGES, TRANSCRIPTION_NOTES, WINDOW_FRACTIONS)

__all__ = ["paper_report", "gamma_c_24", "paper_gamma_grid", "window_masks", "WINDOWS",
           "compute_sweeps", "table_rows", "critical_curves", "reproduction",
           "COEFFICIENTS", "REPRODUCED_RTOL", "step_budget", "MAX_STEPS", "STEPS_RULE",
           "UndecidedError"]

#: Column name -> sweep method: the report's two kinds of I, Q.
COEFFICIENTS = {"numint": "ord2_numint", "approx": "ord2_approx"}
#: Windows in the tables: the report's three, and "ge" = mid or high (its "gamma >= 0.02").
WINDOWS = ("low", "mid", "high", "ge")


#: The largest ``steps``: its budget (:func:`step_budget`) is the integrator's largest.
MAX_STEPS = math.floor(MAX_STEP_BUDGET * sweep.DEFAULT_STEPS / sweep.DEFAULT_MAX_STEPS)
#: What ``steps`` must be, for the messages that refuse it.
STEPS_RULE = (f"<= {MAX_STEPS:,} (the report's step budget per point grows with steps, "
              f"{sweep.DEFAULT_MAX_STEPS:,} per {sweep.DEFAULT_STEPS:g}, and cannot pass "
              f"2**30 = {MAX_STEP_BUDGET:,})")


class UndecidedError(RuntimeError):
    """Points the integrator did not decide within the step budget: their e is a bound, not
    a value, so the report stops before it writes tables or figures from them."""


def step_budget(steps: float | None) -> int:
    """The step budget per point (``max_steps``) of the report's marches at ``steps``.

    Parameters
    ----------
    steps : float or None
        The resolution (None: the package default).

    Returns
    -------
    int
        The package default's budget, or more for a finer resolution: as much per unit of
        resolution as the default has (a fixed budget ran out from about 40,000 steps on,
        and every point of the tables was a bound).

    Raises
    ------
    ValueError
        ``steps`` above :data:`MAX_STEPS` (no budget would be large enough).
    """
    if steps is None or steps <= sweep.DEFAULT_STEPS:
        return sweep.DEFAULT_MAX_STEPS
    if not steps <= MAX_STEPS:
        raise ValueError(f"steps must be {STEPS_RULE}, got {steps!r}")
    return math.ceil(sweep.DEFAULT_MAX_STEPS * steps / sweep.DEFAULT_STEPS)


def gamma_c_24(alpha: float, beta: float, gtilde: ArrayLike) -> np.ndarray:
    """The report's no-rebound threshold (24) in gamma: ``1 / (2 C g~^r)`` (inf at g~ = 0)."""
    from sweep.critical import critical_gamma

    return critical_gamma(alpha, beta, gtilde, method="approx")


def paper_gamma_grid(alpha: float, beta: float, gtilde: float, n_gamma: int = 1000,
                     shift: bool = False) -> tuple[np.ndarray, float]:
    """The report's gamma grid at one (model, g~): ``linspace(0, G, n_gamma)`` and ``G``.

    ``shift=True`` moves every point up by half a step (same windows, other samples).
    """
    end = float(min(GAMMA_MAX, GRID_END_FACTOR * gamma_c_24(alpha, beta, gtilde)))
    gamma = np.linspace(0.0, end, n_gamma)
    if shift:
        gamma = gamma + 0.5 * (gamma[1] - gamma[0])
    return gamma, end


def window_masks(gamma: np.ndarray, end: float) -> dict[str, np.ndarray]:
    """Masks of the report's windows on a gamma grid ending (nominally) at ``end``."""
    lo, hi = WINDOW_FRACTIONS[0] * end, WINDOW_FRACTIONS[1] * end
    low = gamma < lo
    mid = (gamma >= lo) & (gamma <= hi)
    high = gamma > hi
    return {"low": low, "mid": mid, "high": high, "ge": ~low}


def _window_label(w, end):
    lo, hi = WINDOW_FRACTIONS[0] * end, WINDOW_FRACTIONS[1] * end
    return {"low": f"gamma < {lo:.3g}", "mid": f"{lo:.3g} <= gamma <= {hi:.3g}",
            "high": f"gamma > {hi:.3g}", "ge": f"gamma >= {lo:.3g}"}[w]


def compute_sweeps(models: Sequence[str] | None = None, n_gamma: int = 1000,
                   steps: float | None = None, shift: bool = False,
                   progress: bool = False) -> dict[tuple[str, float], dict[str, Any]]:
    """The numerical CoR and both O(gamma^2) approximations on the report's grids.

    The numerical CoR is marched with the step budget :func:`step_budget` of ``steps``.

    Returns
    -------
    dict
        ``(model, g~) -> {"gamma", "end", "numeric", "numint", "approx", "status"}``
        (arrays over the grid).
    """
    models = list(models or PAPER_MODELS)
    out = {}
    for key in models:
        a, b = PAPER_MODELS[key][:2]
        for G in GTILDES:
            gamma, end = paper_gamma_grid(a, b, G, n_gamma, shift=shift)
            t0 = time.perf_counter()
            r = sweep.integrate(a, b, gamma, G, steps=steps, max_steps=step_budget(steps))
            d = {"gamma": gamma, "end": end, "numeric": r.e, "status": r.status}
            for c, m in COEFFICIENTS.items():
                d[c] = sweep.cor(a, b, gamma, G, method=m)
            out[(key, G)] = d
            log_progress(progress, f"  {key} g~={G:g}: {n_gamma} gamma in [0, {end:.4g}] "
                           f"({time.perf_counter() - t0:.2f} s)")
    return out


def _report_value(key, G, coeff, w):
    if G in TABLE_A[key]:
        pair = TABLE_A[key][G][coeff]
        return {"low": pair[0], "ge": pair[1]}.get(w)
    triple = TABLE_B[key][coeff]
    return {"low": triple[0], "mid": triple[1], "high": triple[2]}.get(w)


def table_rows(sweeps: Mapping[tuple[str, float], Mapping[str, Any]],
               shifted: Mapping[tuple[str, float], Mapping[str, Any]] | None = None
               ) -> list[dict[str, Any]]:
    """Rows of the recomputed tables (one per model, g~, coefficients, window).

    Parameters
    ----------
    sweeps : dict
        Output of :func:`compute_sweeps`.
    shifted : dict, optional
        The same on the half-step-shifted grids (adds ``max_shifted``).
    """
    rows = []
    for (key, G), d in sweeps.items():
        a, b, name, table = PAPER_MODELS[key][:4]
        masks = window_masks(d["gamma"], d["end"])
        part = "a" if G in TABLE_A[key] else "b"
        windows = ("low", "ge", "mid", "high") if part == "a" else ("low", "mid", "high")
        for coeff in COEFFICIENTS:
            err = np.abs(d[coeff] - d["numeric"])
            if shifted is not None:
                ds_ = shifted[(key, G)]
                err_s = np.abs(ds_[coeff] - ds_["numeric"])
                masks_s = window_masks(ds_["gamma"], ds_["end"])
            for w in windows:
                m = masks[w]
                row = {"table": table, "part": part, "model": key, "alpha": a, "beta": b,
                       "gtilde": G, "coefficients": coeff, "window": w,
                       "gamma_range": _window_label(w, d["end"]), "n_points": int(m.sum()),
                       "max_abs_error": None, "report": _report_value(key, G, coeff, w),
                       "ratio": None, "gamma_at_max": None, "e_numeric_at_max": None,
                       "max_shifted": None}
                if m.any():
                    idx = np.flatnonzero(m)
                    k = idx[np.argmax(err[idx])]
                    row.update(max_abs_error=float(err[k]), gamma_at_max=float(d["gamma"][k]),
                               e_numeric_at_max=float(d["numeric"][k]))
                    rep = row["report"]
                    if rep:
                        row["ratio"] = row["max_abs_error"] / rep
                if shifted is not None and masks_s[w].any():
                    row["max_shifted"] = float(np.max(err_s[masks_s[w]]))
                rows.append(row)
    return rows


def _markdown_tables(rows):
    """The recomputed tables in the report's layout: ours next to the published value."""
    out = []
    by = {}
    for r in rows:
        by.setdefault((r["model"], r["gtilde"], r["window"]), {})[r["coefficients"]] = r
    for key, (a, b, name, table, _) in PAPER_MODELS.items():
        sub = [r for r in rows if r["model"] == key]
        if not sub:
            continue
        out.append(f"### {table}: {name} (alpha = {a:g}, beta = {b:g})")
        out.append("")
        out.append("| g~ | window | num. I,Q: ours | report | shifted grid | "
                   "approx. I,Q: ours | report | shifted grid | gamma at max (num.) |")
        out.append("|---|---|---|---|---|---|---|---|---|")
        for G in GTILDES:
            part = "a" if G in TABLE_A[key] else "b"
            windows = ("low", "ge") if part == "a" else ("low", "mid", "high")
            for w in windows:
                cell = by.get((key, G, w))
                if not cell:
                    continue
                n, p = cell["numint"], cell["approx"]
                star = "*" if G == 0.0 else ""
                out.append(
                    f"| {G:g} | {n['gamma_range']} | {format_value(n['max_abs_error'])}{star} "
                    f"| {format_value(n['report'])} | {format_value(n['max_shifted'])} "
                    f"| {format_value(p['max_abs_error'])} | {format_value(p['report'])} "
                    f"| {format_value(p['max_shifted'])} "
                    f"| {format_value(n['gamma_at_max'], 4)} |")
        edges = TABLE_B_EDGES[key]
        out.append("")
        out.append(f"Report's printed g~ = 10 window edges: {edges[0] or '(unreadable)'}, "
                   f"{edges[1]}. * exact I(0), Q(0) of (39), (40).")
        notes = [v for (m, *_), v in TRANSCRIPTION_NOTES.items() if m == key]
        for v in notes:
            out.append(f"Transcription: {v}")
        out.append("")
    return "\n".join(out)


# --------------------------------------------------------------------------- reproduction

#: A published maximum is reproduced when ours / the report's is within this of 1.
REPRODUCED_RTOL = 0.01
#: Maxima below this are round-off: the report prints ~1e-13 where both e are 0.
ROUND_OFF = 1e-12
_COLUMNS = {"numint": "num. I,Q", "approx": "approx. I,Q"}


def _why_not_reproduced(row):
    """Why a published maximum is not within REPRODUCED_RTOL of ours: (kind, phrase)."""
    ours, report, ratio = row["max_abs_error"], row["report"], row["ratio"]
    if max(ours, report) < ROUND_OFF:
        return "zero to rounding in both", "both are zero to rounding"
    k = round(float(np.log10(ratio))) if ratio > 0 else 0
    if k != 0 and abs(ratio / 10.0 ** k - 1) <= REPRODUCED_RTOL:
        return ("off by a power of ten (an apparent misprint)",
                f"ours is the report's times 1e{k}: an apparent misprint of the exponent")
    shifted = row["max_shifted"]
    if shifted is not None and min(ours, shifted) <= report <= max(ours, shifted):
        return ("bracketed by our two grids",
                "our grid shifted by half a step brackets it: where the maximum falls")
    return ("within 10%" if abs(ratio - 1) <= 0.1 else "further off"), f"ratio {ratio:.3g}"


def reproduction(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """How many of the report's published maxima the recomputed tables reproduce.

    Parameters
    ----------
    rows : sequence of dict
        :func:`table_rows`.

    Returns
    -------
    dict
        ``n_published`` (readable published maxima with a recomputed value),
        ``n_reproduced`` (ours / the report's within :data:`REPRODUCED_RTOL` of 1),
        ``others`` (list of (row, phrase saying why)) and ``summary`` (one line).
    """
    published = [r for r in rows if r["report"] is not None and r["max_abs_error"] is not None]
    others = [(r, _why_not_reproduced(r)) for r in published
              if abs(r["ratio"] - 1) > REPRODUCED_RTOL]
    kinds: dict[str, int] = {}
    for _, (kind, _) in others:
        kinds[kind] = kinds.get(kind, 0) + 1
    n_ok = len(published) - len(others)
    summary = (f"Reproduced {n_ok} of the report's {len(published)} readable published "
               f"maxima within {REPRODUCED_RTOL:.0%} (ours / report)")
    if others:
        summary += (f"; the other {len(others)}: "
                    + ", ".join(f"{n} {kind}" for kind, n in kinds.items()))
    return {"n_published": len(published), "n_reproduced": n_ok,
            "others": [(r, why) for r, (_, why) in others], "summary": summary + "."}


def _reproduction_markdown(rep):
    """The summary line and one line per maximum not reproduced."""
    lines = ["### Reproduced maxima", "", rep["summary"], ""]
    for r, why in rep["others"]:
        lines.append(f"- {r['table']}({r['part']}), {r['model']}, g~ = {r['gtilde']:g}, "
                     f"{_COLUMNS[r['coefficients']]}, {r['gamma_range']}: ours "
                     f"{format_value(r['max_abs_error'])}, report {format_value(r['report'])}"
                     f" ({why})")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- Figures 8-11

def critical_curves(models: Sequence[str] | None = None, n_crit: int = 100,
                    steps: float | None = None,
                    progress: bool = False) -> dict[str, dict[str, np.ndarray]]:
    """g~_c(gamma) numerically and by (24) on the report's gamma sets of Figures 8-11.

    The numerical g~_c is :func:`sweep.critical.critical_gtilde` with method "numeric":
    bisection on the integrator's stick decision, all gamma values at once, to relative
    precision :data:`sweep.critical.RTOL`, with the step budget :func:`step_budget`.

    Returns ``model -> {"gamma", "numeric", "approx", "relerr", "gamma_zoom", ...}``.
    """
    from sweep.critical import critical_gtilde

    options = {} if steps is None else {"steps": steps, "max_steps": step_budget(steps)}

    f = FIGURES_CRITICAL
    models = list(models or PAPER_MODELS)
    out = {}
    for key in models:
        a, b = PAPER_MODELS[key][:2]
        t0 = time.perf_counter()
        d = {}
        for tag, gmax in (("", f["gamma_max"]), ("_zoom", f["gamma_max_zoom"])):
            g = np.linspace(f["gamma_min"], gmax, n_crit)
            num = critical_gtilde(a, b, g, method="numeric", **options)
            app = critical_gtilde(a, b, g, method="approx")
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.abs(num - app) / num
            d.update({f"gamma{tag}": g, f"numeric{tag}": num, f"approx{tag}": app,
                      f"relerr{tag}": rel})
        out[key] = d
        log_progress(progress, f"  {key}: g~_c at {2 * n_crit} gamma values "
                       f"({time.perf_counter() - t0:.1f} s)")
    return out


def _critical_figure(path, key, d):
    plt = use_agg()
    a, b, name, _, fig_no = PAPER_MODELS[key]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.6), constrained_layout=True)
    ax1.plot(d["gamma"], d["numeric"], "b-", lw=1.2, label=r"numerical $\tilde g_c$ (bisection)")
    ax1.plot(d["gamma"], d["approx"], "r--", lw=1.2, label=r"approx. $\tilde g_c$, eq. (24)")
    ax1.set_xlabel(r"$\gamma$")
    ax1.set_ylabel(r"$\tilde g_c$")
    top = np.nanmax(d["numeric"][d["gamma"] >= 0.02]) if np.any(d["gamma"] >= 0.02) else None
    if top:
        ax1.set_ylim(0, 1.3 * top)
    ax1.grid(True, alpha=0.3)
    ax1.legend(loc="lower left", fontsize=8)
    ax1.set_title(f"(a) {name}: " + r"$\tilde g_c$ vs $\gamma$", fontsize=10)
    ins = ax1.inset_axes([0.52, 0.5, 0.44, 0.38])
    ins.plot(d["gamma_zoom"], d["numeric_zoom"], "b-", lw=1)
    ins.plot(d["gamma_zoom"], d["approx_zoom"], "r--", lw=1)
    ins.set_title(r"$\gamma \leq 0.01$", fontsize=8)
    ins.tick_params(labelsize=7)
    ins.grid(True, alpha=0.3)
    sel = d["gamma"] <= FIGURES_CRITICAL["relerr_gamma_max"]
    ax2.plot(d["gamma"][sel], d["relerr"][sel], "b-", lw=1.2)
    ax2.set_xlabel(r"$\gamma$")
    ax2.set_ylabel("relative error of (24)")
    ax2.grid(True, alpha=0.3)
    ax2.set_title(r"(b) $|\tilde g_{c,num} - \tilde g_{c,(24)}| / \tilde g_{c,num}$, "
                  r"$\gamma \leq 0.3$", fontsize=10)
    ins2 = ax2.inset_axes([0.5, 0.1, 0.45, 0.38])
    ins2.plot(d["gamma_zoom"], d["relerr_zoom"], "b-", lw=1)
    ins2.set_title(r"$\gamma \leq 0.01$", fontsize=8)
    ins2.tick_params(labelsize=7)
    ins2.grid(True, alpha=0.3)
    fig.suptitle(f"Report's {fig_no} recomputed: alpha = {a:g}, beta = {b:g}", fontsize=11)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _error_figure(path, key, sweeps):
    """|e - e_numeric| against gamma at the four loads (cf. the report's Figs 15-21)."""
    plt = use_agg()
    a, b, name = PAPER_MODELS[key][:3]
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), constrained_layout=True)
    floor = 1e-17
    for ax, G in zip(axes.flat, GTILDES):
        d = sweeps[(key, G)]
        for coeff, style, label in (("numint", "g--", "num./exact I, Q"),
                                    ("approx", "m-.", "approx. I, Q (n = 21)")):
            err = np.abs(d[coeff] - d["numeric"])
            ax.semilogy(d["gamma"], np.maximum(err, floor), style, lw=1, label=label)
        for f in WINDOW_FRACTIONS:
            ax.axvline(f * d["end"], color="0.6", lw=0.8, ls=":")
        ax.set_title(rf"$\tilde g = {G:g}$", fontsize=10)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 2))
        ax.set_xlabel(r"$\gamma$")
        ax.set_ylabel("absolute error")
        ax.grid(True, alpha=0.3)
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(f"{name} (alpha = {a:g}, beta = {b:g}): O(gamma^2) approximation (36) "
                 f"against the numerical CoR\ndotted: the report's window edges; errors "
                 f"below 1e-17 (both e exact: 1 at gamma = 0, or both 0) drawn at 1e-17",
                 fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table_files(stage, rows, sweeps):
    """Write the recomputed tables (CSV) and the raw sweeps (npz); return their names."""
    cols = ["table", "part", "model", "alpha", "beta", "gtilde", "coefficients", "window",
            "gamma_range", "n_points", "max_abs_error", "report", "ratio", "max_shifted",
            "gamma_at_max", "e_numeric_at_max"]
    write_table(rows, cols, stage("paper_tables.csv"))
    np.savez_compressed(stage("paper_sweeps.npz"), **{
        f"{k}_g{G:g}_{v}": d[v] for (k, G), d in sweeps.items()
        for v in ("gamma", "numeric", "numint", "approx", "status")})
    return ["paper_tables.csv", "paper_sweeps.npz"]


def _critical_rows(crit):
    """Min and max relative error of (24) per model and gamma band."""
    crit_rows = []
    for key, d in crit.items():
        for lo, hi, tag in ((0.0, 0.01, "_zoom"), (0.01, 0.1, ""), (0.1, 0.3, ""),
                            (0.3, 1.0, "")):
            g = d[f"gamma{tag}"]
            sel = (g > lo) & (g <= hi)
            rel = d[f"relerr{tag}"][sel]
            crit_rows.append({"figure": PAPER_MODELS[key][4], "model": key,
                              "gamma_range": f"({lo:g}, {hi:g}]", "n_gamma": int(sel.sum()),
                              "max_rel_error": float(np.nanmax(rel)) if rel.size else None,
                              "min_rel_error": float(np.nanmin(rel)) if rel.size else None})
    return crit_rows


def _critical_table(stage, crit, crit_rows, n_crit):
    """Write the g~_c curves (CSV); return the markdown summary of Figures 8-11."""
    # Two curves a model (the figure's main axes and its gamma <= 0.01 inset), which share
    # gamma values: the column says which.
    write_table([{"model": k, "curve": "inset" if tag else "main", "gamma": g,
                  "gtilde_c_numeric": n, "gtilde_c_24": a, "rel_error": r}
                 for k, d in crit.items()
                 for tag in ("", "_zoom")
                 for g, n, a, r in zip(d[f"gamma{tag}"], d[f"numeric{tag}"],
                                       d[f"approx{tag}"], d[f"relerr{tag}"])],
                ["model", "curve", "gamma", "gtilde_c_numeric", "gtilde_c_24", "rel_error"],
                stage("paper_critical.csv"))
    return write_table(
        crit_rows, ["figure", "model", "gamma_range", "n_gamma", "min_rel_error",
                    "max_rel_error"],
        title="Figures 8-11: relative error of g~_c from (24) against bisection on the "
              "numerical CoR",
        notes=[f"gamma = linspace({FIGURES_CRITICAL['gamma_min']:g}, 1, {n_crit}) and, for "
               f"(0, 0.01], linspace({FIGURES_CRITICAL['gamma_min']:g}, 0.01, {n_crit}), as "
               f"in the report; bisection (sweep.critical) to a relative width "
               f"{RTOL:g} on the integrator's stick decision (the report: e < 1e-4 counted "
               "as 0, absolute width 1e-3)."])


def _figure_files(stage, models, crit, sweeps):
    """Draw Figures 8-11 and the error-against-gamma figures; return their names."""
    files = []
    for key in models:
        f = f"paper_{PAPER_MODELS[key][4].replace(' ', '').lower()}_{key}.png"
        _critical_figure(stage(f), key, crit[key])
        files.append(f)
        f = f"paper_errors_{key}.png"
        _error_figure(stage(f), key, sweeps)
        files.append(f)
    return files


def _report_markdown(rows, crit_md, n_gamma, steps, machine, elapsed):
    """paper_report.md: the reproduction summary, the tables next to the report's, the
    g~_c summary, the machine."""
    head = [
        "## The report's Tables 2-5 recomputed",
        "",
        "Maximum absolute error of the O(gamma^2) approximation (36)-(38) against sweep's "
        f"numerical CoR (steps = {steps or sweep.DEFAULT_STEPS:g}, a budget of "
        f"{step_budget(steps):,} steps per point), with I, Q by quadrature "
        "('num.'; exact (39), (40) at g~ = 0) and by the Chebyshev-Beta approximation "
        "(48), (49), n = 21 ('approx.'). Grid: "
        f"{n_gamma} gamma values on [0, min(0.1, 1.1 gamma_c(24))] per (model, g~), the "
        "report's; 'shifted grid' = the same maxima with every gamma moved by half a step.",
        "",
        reproduction(rows)["summary"],
        "",
    ]
    return ("\n".join(head) + _markdown_tables(rows) + "\n"
            + _reproduction_markdown(reproduction(rows)) + "\n" + crit_md
            + f"\nMachine: {machine_line(machine)}. Report computed in {elapsed:.0f} s.\n")


def paper_report(out: str | os.PathLike = "paper_report", n_gamma: int = 1000, *,
                 n_crit: int | None = None, steps: float | None = None,
                 models: Sequence[str] | None = None, figures: bool = True,
                 progress: bool = False) -> dict[str, Any]:
    """Recompute the report's Tables 2-5 and Figures 8-11 and write them into ``out``.

    Parameters
    ----------
    out : path-like
        Output directory (created).
    n_gamma : int, default 1000
        gamma grid points per (model, g~); the report used 1000.
    n_crit : int, optional
        gamma values per curve of Figures 8-11 (default 100, as the report).
    steps : float, optional
        Integrator resolution (default: the package default).
    models : sequence of str, optional
        Keys of :data:`sweep.reports.paper_values.PAPER_MODELS` (default: all four).
    figures : bool
        Write the PNG figures (tables only if False).
    progress : bool
        Print progress messages to stderr.

    Returns
    -------
    dict
        ``out``, ``files``, ``rows`` (table rows, see :func:`table_rows`), ``critical``
        (see :func:`critical_curves`), ``crit_rows``, ``markdown``, ``sweeps``,
        ``summary`` (how many published maxima are reproduced, :func:`reproduction`).

    Raises
    ------
    ValueError
        If ``n_gamma < 2`` or ``steps`` is above :data:`MAX_STEPS` (before anything is
        written).
    NotADirectoryError
        ``out`` is an existing file.
    OSError
        No file can be created in ``out`` (before anything is computed).
    UndecidedError
        Points ran out of the step budget (:func:`step_budget`); no file is written.
    """
    models = list(models or PAPER_MODELS)
    n_crit = FIGURES_CRITICAL["n_gamma"] if n_crit is None else int(n_crit)
    if n_gamma < 2:
        raise ValueError(f"n_gamma must be >= 2, got {n_gamma}")
    step_budget(steps)
    out = make_out_dir(out)   # after the checks: a refused call leaves no directory
    machine = machine_description()
    t0 = time.perf_counter()
    sweeps, shifted, crit = _compute(models, n_gamma, n_crit, steps, progress)
    rows, crit_rows = table_rows(sweeps, shifted), _critical_rows(crit)
    # Staged: a failure while writing leaves no new file beside the previous run's.
    with staged(out) as stage:
        files = _table_files(stage, rows, sweeps)
        crit_md = _critical_table(stage, crit, crit_rows, n_crit)
        files.append("paper_critical.csv")
        if figures:
            files += _figure_files(stage, models, crit, sweeps)
        md = _report_markdown(rows, crit_md, n_gamma, steps, machine,
                              time.perf_counter() - t0)
        stage("paper_report.md").write_text(md, encoding="utf-8")
    return {"out": out, "files": [out / f for f in ["paper_report.md", *files]], "rows": rows,
            "critical": crit, "crit_rows": crit_rows, "markdown": md, "sweeps": sweeps,
            "summary": reproduction(rows)["summary"]}


def _compute(models, n_gamma, n_crit, steps, progress):
    """The sweeps of Tables 2-5 (both grids) and the g~_c curves of Figures 8-11, each
    refused (:class:`UndecidedError`) as soon as a point of it ran out of the budget."""
    log_progress(progress, "Tables 2-5: the report's gamma grids")
    sweeps = compute_sweeps(models, n_gamma, steps, progress=progress)
    log_progress(progress, "Tables 2-5: the same grids shifted by half a step")
    shifted = compute_sweeps(models, n_gamma, steps, shift=True, progress=progress)
    status = np.concatenate([d["status"] for s in (sweeps, shifted) for d in s.values()])
    decided = (Status.OK, Status.STUCK, Status.AT_REST)
    _refuse_undecided(int((~np.isin(status, decided)).sum()), status.size,
                      "points of Tables 2-5", steps)
    log_progress(progress, "Figures 8-11: g~_c by bisection")
    crit = critical_curves(models, n_crit, steps, progress=progress)
    # NaN: the bisection met a point the integrator did not decide.
    g_c = np.concatenate([d[k] for d in crit.values() for k in ("numeric", "numeric_zoom")])
    _refuse_undecided(int(np.isnan(g_c).sum()), g_c.size, "g~_c values of Figures 8-11",
                      steps)
    return sweeps, shifted, crit


def _refuse_undecided(n, total, what, steps):
    """Raise :class:`UndecidedError` if ``n`` of the ``total`` ``what`` are undecided."""
    if n:
        raise UndecidedError(
            f"{n:,} of {total:,} {what} ran out of the step budget ({step_budget(steps):,} "
            f"steps per point at steps = {steps or sweep.DEFAULT_STEPS:g}): their e would be "
            "a bound, not a value, so no file was written")
