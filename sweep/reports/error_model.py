"""Build and validate the error model of the ``"auto"`` method (``sweep report error-model``).

:func:`build_error_model` measures the absolute error of every closed form of the report
(eqs. (22), (23), (25), (36)-(38)) against the package's own numerical CoR (eqs. (3), (4),
Algorithm 1, at a fine resolution: the *judge*) on a sample grid over (alpha, beta, gamma, g~),
and turns it into the table of bounds :class:`sweep.auto.ErrorModel`:

1. samples: at every exponent node, ``sub`` log-spaced subintervals per (gamma, g~) cell
   (cell edges and interior points), plus gamma = 0 and g~ = 0;
2. a cell's error is the largest at the samples on its closed boundary and inside;
   unknown truth (the judge ran out of budget) or an undefined method count as infinite;
3. bound = max(``safety`` x error, ``floor``): the safety factor covers the variation of
   the smooth error between samples, the floor the judge's own accuracy;
4. no bound near a collapse: where e (numerical, or the method's) is 0 at some samples of a
   cell and positive at others, e falls to 0 like a square root somewhere inside, and the
   error between samples can be as large as e itself; such cells and their neighbours (one
   cell each side at the nodes, two between them: the boundary may cut a cell's corner
   between samples) get no bound, and ``auto`` integrates there;
5. between exponent nodes: the largest bound of the four surrounding nodes, each taken
   over its cell and the neighbouring ones.

The methods are ranked by measured cost per point (cheapest first; near-equal costs keep the
registry's order). :func:`validate_error_model` then checks ``|e_auto - e_judge| <= tol`` on
random points in and out of the model, at nodes and between them. The shipped file
``sweep/data/error_model.npz`` is rebuilt by ``sweep report error-model`` (about a minute on
2 cores), which writes the validation table next to it.

Every judged point is held in memory (about :data:`BYTES_PER_POINT` each): a ``sub`` or
``n_validate`` whose points would not fit in this machine's memory is refused before
anything runs (:func:`judged_points`), not after hours of judging.

Floor 5: may import :mod:`sweep.api`, :mod:`sweep.auto`, :mod:`sweep.registry`,
:mod:`sweep.reports.common`, :func:`sweep.sweeps.preflight.physical_memory`, numpy and
scipy.
"""
from __future__ import annotations

import datetime as _dt
import errno
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from sweep import api, auto, registry
from sweep._format import format_bytes
from sweep._version import __version__
from sweep.registry import Status
from sweep.reports.common import (format_value, log_progress, machine_description,
                                  machine_line, make_out_dir, write_table)
from sweep.sweeps.preflight import physical_memory

__all__ = ["build_error_model", "validate_error_model", "error_model_report", "random_points",
           "summary_line", "judged_points", "memory_refusal", "ALPHA_NODES",
           "BETA_NODES", "GAMMA_EDGES", "GTILDE_EDGES", "JUDGE_STEPS", "SAFETY", "FLOOR",
           "BYTES_PER_POINT"]

#: Exponent nodes: every named law of the report (Table 1) is a node pair.
ALPHA_NODES = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0)
BETA_NODES = (1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0)
#: Cells over gamma and g~: 0, then four per decade (above the last edge: no bound).
GAMMA_EDGES = tuple([0.0] + [float(10.0 ** (k / 4)) for k in range(-28, 1)])
GTILDE_EDGES = tuple([0.0] + [float(10.0 ** (k / 4)) for k in range(-24, 9)])
#: Resolution of the judge (steps per half period; error ~2e-10 (96/steps)^5).
JUDGE_STEPS = 256.0
#: Safety factor on the measured error, and the floor of every bound (the judge's accuracy).
SAFETY = 3.0
FLOOR = 1e-10
#: Cells each side of a collapse of e to 0 without a bound, at and between exponent nodes.
DILATE_NODE, DILATE_BETWEEN = 1, 2
#: Peak memory per judged point [bytes], rounded up: the growth of the peak resident set of
#: ``sweep report error-model`` with the points, 110-155 B between ``--sub`` 1, 3 and 6 and
#: 115 B per validation point (``/usr/bin/time -f %M``, 2026-12-04).
BYTES_PER_POINT = 200


def judged_points(sub: int) -> int:
    """Points the judge computes for ``sub`` samples per cell edge (:func:`_samples` of
    both axes at every exponent node pair)."""
    per_axis = [(len(edges) - 2) * sub + 3 for edges in (GAMMA_EDGES, GTILDE_EDGES)]
    return len(ALPHA_NODES) * len(BETA_NODES) * per_axis[0] * per_axis[1]


def memory_refusal(points: int) -> str | None:
    """Why ``points`` judged points, all held at once, would not fit in this machine's
    physical memory, or None (also where the system does not say how much it has)."""
    memory, need = physical_memory(), points * BYTES_PER_POINT
    if memory is None or need <= memory:
        return None
    return (f"{points:,} points need about {format_bytes(need)} in memory, more than this "
            f"machine's {format_bytes(memory)}")


def _refuse_beyond_memory(points: int, what: str) -> None:
    # numpy refuses a huge array at once, but a merely large one is allocated and the
    # machine swaps, or the report is killed after hours of judging.
    why = memory_refusal(points)
    if why is not None:
        raise ValueError(f"{what}: {why}")


def _samples(edges: tuple, sub: int) -> np.ndarray:
    """Sample values of one axis: 0, the first edge's half, then ``sub`` log steps per cell."""
    e = np.asarray(edges)
    logs = np.linspace(np.log10(e[1]), np.log10(e[-1]), (e.size - 2) * sub + 1)
    return np.concatenate([[0.0, e[1] / 2], 10.0 ** logs])


def _cell_max(err: np.ndarray, samples: np.ndarray, edges: tuple, axis: int) -> np.ndarray:
    """Largest value over the samples of each closed cell ``[edges[i], edges[i+1]]``."""
    e = np.asarray(edges)
    # Edges and samples come from the same log10 formula; match them to a relative 1e-12.
    lo = np.searchsorted(samples, e[:-1] * (1 - 1e-12), side="left")
    hi = np.searchsorted(samples, e[1:] * (1 + 1e-12), side="right")
    return np.stack([np.take(err, np.arange(a, b), axis=axis).max(axis=axis)
                     for a, b in zip(lo, hi)], axis=axis)


def _dilate(x: np.ndarray, width: int) -> np.ndarray:
    """Largest value over a (2 width + 1)^2 neighbourhood in the (gamma, g~) cell axes."""
    from scipy.ndimage import maximum_filter

    size = [1] * x.ndim
    size[-3] = size[-2] = 2 * width + 1
    return maximum_filter(x, size=tuple(size), mode="nearest")


def _measure_costs(methods: tuple, n: int = 20000) -> dict[str, float]:
    """Wall ns per point of each closed form on KK points (only their ranking is used)."""
    rng = np.random.default_rng(1)
    gamma, gtilde = 10 ** rng.uniform(-4, -1, n), 10 ** rng.uniform(-3, 1, n)
    costs = {}
    for m in methods:
        api.cor(1.5, 1.5, gamma, gtilde, method=m)  # compile / load the kernel first
        t0 = time.perf_counter()
        api.cor(1.5, 1.5, gamma, gtilde, method=m)
        costs[m] = 1e9 * (time.perf_counter() - t0) / n
    return costs


def _by_cost(methods: tuple, costs: dict[str, float], tie: float = 2.0) -> tuple:
    """Methods cheapest first; costs within a factor ``tie`` of a tier's cheapest count as
    equal and keep the registry's order (timings on a shared machine must not reorder them)."""
    tiers, order = [], sorted(methods, key=costs.__getitem__)
    for m in order:
        if tiers and costs[m] <= tie * costs[tiers[-1][0]]:
            tiers[-1].append(m)
        else:
            tiers.append([m])
    return tuple(m for tier in tiers for m in sorted(tier, key=methods.index))


def _node_samples(gs: np.ndarray, hs: np.ndarray, methods: tuple,
                  progress: bool) -> tuple[np.ndarray, np.ndarray]:
    """At every node pair and sample, per method: |e_method - e_judge| and whether either e
    is 0. Shapes (alpha, beta, gamma, g~, method)."""
    a, b, g, h = np.meshgrid(ALPHA_NODES, BETA_NODES, gs, hs, indexing="ij")
    flat = [x.reshape(-1) for x in (a, b, g, h)]
    log_progress(progress, f"error model: judging {flat[0].size} points at "
                           f"{JUDGE_STEPS:g} steps")
    judge = api.integrate(*flat, steps=JUDGE_STEPS)
    known = (judge.status != Status.BUDGET_EXHAUSTED) & (judge.status != Status.INVALID)
    err = np.empty(flat[0].shape + (len(methods),))
    zero = np.empty(err.shape, dtype=bool)
    for j, m in enumerate(methods):
        e = api.cor(*flat, method=m)
        d = np.abs(e - judge.e)
        err[:, j] = np.where(known & np.isfinite(d), d, np.inf)
        zero[:, j] = (judge.e <= 0.0) | (e <= 0.0)
    shape = a.shape + (len(methods),)
    return err.reshape(shape), zero.reshape(shape)


def _cells(x: np.ndarray, gs: np.ndarray, hs: np.ndarray) -> np.ndarray:
    """Largest sample value of every (gamma, g~) cell."""
    return _cell_max(_cell_max(x, gs, GAMMA_EDGES, 2), hs, GTILDE_EDGES, 3)


def _bounds(err: np.ndarray, collapse: np.ndarray, width: int, safety: float,
            floor: float) -> np.ndarray:
    """Bounds of every cell: safety x error (over ``width - 1`` neighbours each side), no
    bound within ``width`` cells of a collapse."""
    near = _dilate(collapse.astype(np.float64), width) > 0
    spread = _dilate(err, width - 1) if width > 1 else err
    return np.where(near, np.inf, np.maximum(safety * spread, floor))


def build_error_model(sub: int = 2, safety: float = SAFETY, floor: float = FLOOR,
                      progress: bool = False) -> auto.ErrorModel:
    """Measure the closed forms against the judge and tabulate their bounds.

    Parameters
    ----------
    sub : int
        Log-spaced subintervals per (gamma, g~) cell edge (samples per cell: (sub+1)^2).
    safety : float
        Factor on the measured error.
    floor : float
        Smallest bound [1].
    progress : bool
        Print progress to stderr.

    Returns
    -------
    sweep.auto.ErrorModel

    Raises
    ------
    ValueError
        If the judged points (:func:`judged_points`) would not fit in this machine's memory.
    """
    _refuse_beyond_memory(judged_points(sub), f"sub={sub}")
    t0 = time.perf_counter()
    approximations = registry.approximations()
    costs = _measure_costs(approximations)
    methods = _by_cost(approximations, costs)
    gs, hs = _samples(GAMMA_EDGES, sub), _samples(GTILDE_EDGES, sub)
    err, zero = _node_samples(gs, hs, methods, progress)
    cell_err = _cells(err, gs, hs)
    collapse = (_cells(zero.astype(np.float64), gs, hs) > 0) & (
        _cells((~zero).astype(np.float64), gs, hs) > 0)
    at_nodes = _bounds(cell_err, collapse, DILATE_NODE, safety, floor)
    wide = _bounds(cell_err, collapse, DILATE_BETWEEN, safety, floor)
    between = np.maximum.reduce([wide[:-1, :-1], wide[1:, :-1], wide[:-1, 1:], wide[1:, 1:]])
    info = {"sweep_version": __version__, "judge_steps": JUDGE_STEPS, "safety": safety,
            "floor": floor, "samples_per_cell_edge": sub,
            "no_bound_near_collapse_at_nodes": DILATE_NODE,
            "no_bound_near_collapse_between_nodes": DILATE_BETWEEN,
            "cost_ns_per_point": {m: round(c, 2) for m, c in costs.items()},
            "n_judged": int(err[..., 0].size),
            "built": _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
            "build_seconds": round(time.perf_counter() - t0, 1),
            "command": "sweep report error-model"}
    return auto.ErrorModel(methods, np.asarray(ALPHA_NODES), np.asarray(BETA_NODES),
                           np.asarray(GAMMA_EDGES), np.asarray(GTILDE_EDGES),
                           auto.encode(at_nodes), auto.encode(between), info)


def random_points(n: int, seed: int = 0, on_nodes: bool = True) -> tuple[np.ndarray, ...]:
    """Random test points in and out of the model: gamma in [1e-8, 3], g~ in {0} u [1e-7, 300]
    (log-uniform), exponents at the nodes or uniform in [1, 3.2] (some beyond the nodes)."""
    rng = np.random.default_rng(seed)
    if on_nodes:
        alpha, beta = rng.choice(ALPHA_NODES, n), rng.choice(BETA_NODES, n)
    else:
        alpha, beta = rng.uniform(1.0, 3.2, n), rng.uniform(1.0, 3.2, n)
    gamma = 10.0 ** rng.uniform(-8, np.log10(3.0), n)
    gtilde = np.where(rng.random(n) < 0.05, 0.0, 10.0 ** rng.uniform(-7, np.log10(300), n))
    return alpha, beta, gamma, gtilde


def validate_error_model(model: auto.ErrorModel | None = None, n: int = 20000,
                         tols: tuple = (1e-2, 1e-4, 1e-6), seed: int = 0,
                         progress: bool = False) -> list[dict[str, Any]]:
    """Check ``|e_auto - e_judge| <= tol`` on random points (half at exponent nodes).

    Parameters
    ----------
    model : ErrorModel, optional
        The model to check (default: the shipped one, what ``method="auto"`` uses).

    Returns
    -------
    list of dict
        One row per (tol, exponents at nodes or not): points, violations, max error / tol,
        and the share of points each method served.

    Raises
    ------
    ValueError
        If ``n`` points would not fit in this machine's memory.
    """
    _refuse_beyond_memory(n, f"n={n}")
    model = model or auto.default_model()
    rows = []
    for on_nodes in (True, False):
        pts = random_points(n // 2, seed, on_nodes)
        judge = api.integrate(*pts, steps=JUDGE_STEPS)
        known = np.isin(judge.status, (Status.OK, Status.STUCK, Status.AT_REST))
        for tol in tols:
            used = auto.select(*pts, tol, model=model)
            e, _ = auto.serve(*pts, used, tol)
            d = np.abs(e - judge.e)[known]
            share = {m: float(np.mean(used == c)) for m, c in registry.SERVED_BY.items()}
            rows.append({"tol": tol, "exponents": "nodes" if on_nodes else "uniform",
                         "points": int(known.sum()), "violations": int((d > tol).sum()),
                         "max_error_over_tol": float(d.max() / tol), **share})
            log_progress(progress, f"validated tol={tol:g} ({rows[-1]['exponents']}): "
                                   f"{rows[-1]['violations']} violations, max err/tol "
                                   f"{rows[-1]['max_error_over_tol']:.3g}")
    return rows


def error_model_report(out: str | Path | None = None, sub: int = 2, n_validate: int = 20000,
                       progress: bool = True) -> dict[str, Any]:
    """Build the model, save it to ``out``, validate it; the validation table next to it.

    Parameters
    ----------
    out : path-like, optional
        The model file, written at exactly this path whatever its suffix (default
        :data:`sweep.auto.DATA_FILE`, the one the package ships); its directory is created.
    sub : int
        Samples per cell edge (:func:`build_error_model`).
    n_validate : int
        Random points of :func:`validate_error_model` (0: no validation).
    progress : bool
        Print progress to stderr.

    Returns
    -------
    dict
        ``model`` (the ErrorModel), ``validation`` (rows), ``files`` and ``markdown``.

    Raises
    ------
    ValueError
        If ``sub`` or ``n_validate`` asks for more points than this machine's memory holds;
        before anything is computed or written.
    OSError
        ``out`` (named) is a directory, or no file can be created in its directory; before
        anything is computed.
    """
    # Before the build, and the build's own check before the directory is made.
    _refuse_beyond_memory(n_validate, f"n_validate={n_validate}")
    _refuse_beyond_memory(judged_points(sub), f"sub={sub}")
    out = _model_path(out)
    model = build_error_model(sub=sub, progress=progress)
    model.save(out)
    auto.default_model.cache_clear()  # the next "auto" call reads the file just written
    rows = validate_error_model(model, n_validate, progress=progress) if n_validate else []
    columns = ["tol", "exponents", "points", "violations", "max_error_over_tol",
               *registry.SERVED_BY]
    files = [out]
    markdown = summary_line(model) + "\n"
    if rows:
        csv_path = out.with_name(out.stem + "_validation.csv")
        md_path = out.with_name(out.stem + "_validation.md")
        formats = {"tol": "g", "max_error_over_tol": ".3g",
                   **{m: ".1%" for m in registry.SERVED_BY}}
        markdown = write_table(rows, columns, csv_path, md_path, formats=formats,
                               title="auto: |e_auto - e_judge| <= tol on random points "
                                     "(share of the points each method served)",
                               notes=[summary_line(model),
                                      machine_line(machine_description())])
        files += [csv_path, md_path]
    return {"model": model, "validation": rows, "files": [str(f) for f in files],
            "markdown": markdown}


def _model_path(out: str | os.PathLike | None) -> Path:
    """``out`` as a Path (None: the shipped file), its directory made and checked writable:
    a fault of the path was said only after the whole build (minutes to hours)."""
    out = auto.DATA_FILE if out is None else Path(out)
    if out.is_dir() or out.name in ("", ".", ".."):
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a model file (give a "
                                "file name such as error_model.npz)", os.fspath(out))
    make_out_dir(out.parent)
    return out


def summary_line(model: auto.ErrorModel) -> str:
    """One line describing a model (methods by cost, grid, safety, floor)."""
    i = model.info
    return (f"error model: {', '.join(model.methods)} (cheapest first); "
            f"{model.alpha.size} x {model.beta.size} exponent nodes, "
            f"{model.gamma_edges.size - 1} x {model.gtilde_edges.size - 1} (gamma, g~) cells; "
            f"safety {format_value(i['safety'])}, floor {format_value(i['floor'])}, judge "
            f"{format_value(i['judge_steps'])} steps")
