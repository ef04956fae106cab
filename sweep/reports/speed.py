"""``sweep report speed``: a work-precision diagram, max abs error against time per point.

On one common point set (default: 20,000 Kuwabara-Kono points, gamma = 10**U(-4, -0.5),
g~ = 10**U(-3, 1), ``default_rng(seed)``, gamma drawn first, as ``benchmarks/throughput.py``),
in one run:

* the reference: the integrator at ``ref_steps`` (default 1024 steps per half period) with
  its refinement down to ``ref_tol`` (1e-13), checked against itself at half that
  resolution on every point and, on a subset, against an independent integrator (see "The
  reference" below);
* the engine at several accuracy targets ``tol`` (:data:`TOLS`, 1e-4 ... 1e-11) and at its
  default, each timed twice (best of ``repeat``, round robin): serially, on one numba thread
  (*CPU time per point*: what one core pays, on the same footing as a peer that runs one
  point at a time) and in parallel on every numba thread (*points/s on all cores*);
* every closed form of the report, timed the same two ways (see "Timing the closed forms");
* the peers a user would otherwise pick, on a random subset of the points, with the same
  events and the same reference (:mod:`sweep.reports.peers`): scipy ``solve_ivp`` (RK45,
  DOP853, LSODA, Radau) one point at a time, and where installed numbalsoda (DOP853,
  compiled, one point at a time) and diffrax (Tsit5, ``jax.vmap``; timed on ``n_vector``
  points holding the subset, its compile time apart). A peer that is not installed is
  skipped with a note.

The headline is the ratio at equal error: for every engine setting, each peer's CPU time
per point interpolated (log-log, :func:`time_at_error`) at the max abs error the engine
reaches on the same subset, divided by the engine's (``ratio_cpu``); and the engine's
points/s on all cores over the peer's points/s as it runs (``ratio_throughput``: scipy and
numbalsoda on one core, diffrax on what XLA uses). ``>`` marks a lower bound (the peer
never reached that error), ``<`` an upper bound (its loosest setting is already more
accurate). A point a peer fails on (NaN) counts as an error of 1 and is counted in
``failed``.

Timing the closed forms
-----------------------
The closed forms cost 3-20 ns per point. Timed on the 20,000 points of the common set, one
call is 0.1-0.4 ms of work and the fixed costs around it dominate: the Python front end
(~40 us), broadcasting scalar exponents to full arrays (two copies of 8 bytes per point)
and, above all, the parallel launch. When array calls still ran ``prange`` kernels, with
numba's ``omp`` threading layer (what a virtual environment got: pip's ``tbb`` puts
``libtbb.so.12`` in ``.venv/lib``, where the loader does not look) and the other core of
a 2-core machine busy (load ~1.5), every parallel call waited ~8 ms for its worker thread
(0.15 ms under ``tbb`` or on one thread): 20,000 points
in 8 ms is the 2.5 M points/s the previous version of this report printed for ``ord1``,
against 338 M from ``benchmarks/approx_throughput.py`` (1,000,000 points, kernel called
directly). Each closed form is therefore timed on the common set tiled until one serial call
takes at least ``min_call_s`` (at most ``n_closed`` points), with full-length exponent
arrays; its errors are those on the common set.

The reference
-------------
The reference is the package's own integrator at high resolution: its error falls like
``steps**-5`` and the test suite validates it against slow independent solutions
(``tests/reference.py``: DOP853 with grazing refinement and the energy identity, exact
linear and TTI cases). The report does not load those (a package must not reach into its
tests, which an installed copy does not even have); it cross-checks the reference on a
subset with the plain DOP853 peer (:func:`~sweep.reports.peers.scipy_user_cor` at rtol
1e-13, atol 1e-15) -- independent of sweep's code, though less careful at grazing contacts
than the test suite's. A caller with a better judge passes it as ``crosscheck`` (as
``benchmarks/work_precision.py`` does with the test suite's reference).

May import: numpy, numba, the public ``sweep`` names, :mod:`sweep.reports.peers`,
:mod:`sweep.reports.common` and :mod:`sweep.reports.paper_values`; matplotlib lazily,
after :func:`sweep.reports.common.use_agg` has set its backend.
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike

import sweep
from sweep.registry import METHODS
from sweep.reports.common import (format_value, log_progress, machine_description,
                                  machine_line, use_agg, write_table)
from sweep.reports.paper_values import PAPER_MODELS
from sweep.reports.peers import available_peers, peer_cors, scipy_user_cor

__all__ = ["speed_report", "sample_points", "scipy_user_cor", "time_at_error",
           "error_bound", "TOLS", "PEER_SETTINGS", "PLAIN_DOP853", "serial_numba"]

#: Accuracy targets of the engine (``sweep.integrate(..., tol=...)``).
TOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
#: Peers: (tool, method, rtols); atol = rtol / 100. ``tool`` is a name of
#: :func:`sweep.reports.peers.peer_cors`.
PEER_SETTINGS = (("scipy", "RK45", (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)),
                 ("scipy", "DOP853", (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)),
                 ("scipy", "LSODA", (1e-4, 1e-6, 1e-8, 1e-10)),
                 ("scipy", "Radau", (1e-4, 1e-6, 1e-8)),
                 ("numbalsoda", "DOP853", (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)),
                 ("diffrax", "Tsit5", (1e-4, 1e-6, 1e-8, 1e-10)))
#: Label of the default cross-check of the reference (:func:`_plain_dop853`).
PLAIN_DOP853 = "plain DOP853 with events (rtol 1e-13, atol 1e-15)"
_TOOL_LABEL = {"scipy": "solve_ivp", "numbalsoda": "numbalsoda", "diffrax": "diffrax"}


def sample_points(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1) (``default_rng(seed)``, gamma first)."""
    rng = np.random.default_rng(seed)
    gamma = 10 ** rng.uniform(-4, -0.5, n)
    gtilde = 10 ** rng.uniform(-3, 1, n)
    return gamma, gtilde


def time_at_error(errors: ArrayLike, times: ArrayLike, target: float) -> tuple[float, bool]:
    """Interpolate time against error (log-log, piecewise linear) at ``target``.

    Returns ``(time, exact)``: ``exact`` False when ``target`` lies outside the measured
    errors (then the time of the nearest end: the most accurate setting if the target is
    below every measured error, so the true time is larger -- a lower bound; see
    :func:`error_bound`).
    """
    e = np.asarray(errors, dtype=float)
    t = np.asarray(times, dtype=float)
    ok = np.isfinite(e) & np.isfinite(t) & (e > 0) & (t > 0)
    e, t = e[ok], t[ok]
    if e.size == 0 or not (target > 0):
        return math.nan, False
    order = np.argsort(e)
    le, lt = np.log(e[order]), np.log(t[order])
    lx = math.log(target)
    if lx < le[0]:
        return float(t[order][0]), False
    if lx > le[-1]:
        return float(t[order][-1]), False
    # errors need not be monotone in the tolerance: the upper envelope of time is the
    # conservative reading (never flatters the integrator), so take the largest time
    # among segments that straddle the target.
    best = -math.inf
    for i in range(le.size - 1):
        x0, x1 = le[i], le[i + 1]
        if x0 <= lx <= x1:
            f = 0.0 if x1 == x0 else (lx - x0) / (x1 - x0)
            best = max(best, lt[i] + f * (lt[i + 1] - lt[i]))
    if best == -math.inf:  # pragma: no cover - target equals a single point
        best = float(lt[np.argmin(np.abs(le - lx))])
    return float(math.exp(best)), True


def error_bound(errors: ArrayLike, target: float) -> str:
    """How a peer's time read at ``target`` by :func:`time_at_error` bounds its true time.

    Returns ``""`` (interpolated), ``">"`` (``target`` below every error of the peer: it
    never got there, its most accurate time is a lower bound) or ``"<"`` (``target`` above
    every error: its cheapest time is an upper bound); ``"?"`` without finite errors.
    """
    e = np.asarray(errors, dtype=float)
    e = e[np.isfinite(e) & (e > 0)]
    if e.size == 0 or not (target > 0):
        return "?"
    if target < e.min():
        return ">"
    return "<" if target > e.max() else ""


@contextlib.contextmanager
def serial_numba() -> Iterator[None]:
    """Run the package's kernels on one numba thread (their serial loops, no parallel
    launch), restoring the thread count after."""
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def _timed(fn, cpu_clock=time.process_time):
    """``(wall seconds, CPU seconds, result)``; CPU of the whole process (all threads) by
    default, ``time.thread_time`` for work done on the calling thread only (serial kernels,
    scipy, numbalsoda: idle parallel workers still spinning after a parallel call then
    do not count)."""
    c0, t0 = cpu_clock(), time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, cpu_clock() - c0, out


def _err_stats(err):
    err = err[np.isfinite(err)]
    if err.size == 0:
        return {"max": math.nan, "median": math.nan, "p99": math.nan}
    return {"max": float(err.max()), "median": float(np.median(err)),
            "p99": float(np.quantile(err, 0.99))}


def _abs_err(e, ref):
    """|e - ref| where the reference is decided; a failed e (NaN) counts as 1."""
    e = np.asarray(e, dtype=float)
    err = np.abs(e - ref)
    return np.where(np.isnan(e) & np.isfinite(ref), 1.0, err)


def _plain_dop853(alpha, beta, gamma, gtilde):
    return scipy_user_cor(alpha, beta, gamma, gtilde, method="DOP853", rtol=1e-13,
                          atol=1e-15)


@dataclasses.dataclass(frozen=True)
class _Bench:
    """The common point set of one report and its reference CoR."""

    a: float
    b: float
    gamma: np.ndarray
    gtilde: np.ndarray
    sub: np.ndarray          # indices of the subset given to the peers
    ref: np.ndarray          # reference e (NaN where undecided)

    def row(self, kind: str, method: str, setting: str, timing: dict[str, float],
            e_full: np.ndarray | None, e_sub: np.ndarray) -> dict[str, Any]:
        """One table row: ``timing`` (``points``, ``threads``, ``cpu_seconds_per_point``,
        ``points_per_second``) and errors against the reference."""
        full = _err_stats(_abs_err(e_full, self.ref)) if e_full is not None else {}
        part = _err_stats(_abs_err(e_sub, self.ref[self.sub]))
        failed = int(np.sum(np.isnan(e_sub) & np.isfinite(self.ref[self.sub])))
        return {"kind": kind, "method": method, "setting": setting, **timing,
                "seconds_per_point": 1.0 / timing["points_per_second"],
                "max_abs_error": full.get("max"), "median_abs_error": full.get("median"),
                "p99_abs_error": full.get("p99"), "subset_max_abs_error": part["max"],
                "subset_median_abs_error": part["median"], "failed": failed}


def _reference(a, b, gamma, gtilde, ref_steps, ref_tol, progress):
    """The integrator at ``ref_steps`` refined to ``ref_tol`` (undecided points NaN) and its
    self-check at half the resolution."""
    log_progress(progress, f"reference: integrator at steps = {ref_steps:g}, refined to "
                           f"{ref_tol:g}, on {gamma.size} points")
    wall, _, r_ref = _timed(lambda: sweep.integrate(a, b, gamma, gtilde, steps=ref_steps,
                                                    tol=ref_tol))
    ref = np.asarray(r_ref.e, dtype=float)
    undecided = ~np.isin(r_ref.status, (sweep.Status.OK, sweep.Status.STUCK,
                                        sweep.Status.AT_REST))
    ref[undecided] = np.nan
    half = sweep.integrate(a, b, gamma, gtilde, steps=ref_steps / 2, tol=ref_tol).e
    self_diff = _err_stats(np.abs(half - ref))
    return ref, {"steps": ref_steps, "tol": ref_tol, "seconds": wall,
                 "undecided": int(undecided.sum()),
                 "half_steps_max_diff": self_diff["max"],
                 "half_steps_median_diff": self_diff["median"]}


def _crosscheck(bench, chk, crosscheck, crosscheck_name, progress):
    """Compare the reference with an independent integrator on the points ``chk``."""
    if crosscheck is None:
        crosscheck, check_name = _plain_dop853, PLAIN_DOP853
    else:
        check_name = crosscheck_name or getattr(crosscheck, "__name__", "user cross-check")
    log_progress(progress, f"cross-check of the reference with {check_name} on "
                           f"{chk.size} points")
    a, b, gamma, gtilde = bench.a, bench.b, bench.gamma, bench.gtilde
    t0 = time.perf_counter()
    dop = np.array([crosscheck(a, b, gamma[i], gtilde[i]) for i in chk])
    t_dop = time.perf_counter() - t0
    check_diff = np.abs(dop - bench.ref[chk])
    return {"crosscheck": check_name, "crosscheck_points": int(chk.size),
            "crosscheck_max_diff": float(np.nanmax(check_diff)) if chk.size else None,
            "crosscheck_median_diff": float(np.nanmedian(check_diff)) if chk.size else None,
            "crosscheck_seconds_per_point": t_dop / max(chk.size, 1)}


def _two_ways(fns, n, repeat):
    """Best serial (one numba thread) CPU time and best parallel wall time of each
    callable in ``fns`` (label -> fn), round robin over ``repeat`` rounds -- a burst of load
    from other processes then spoils one sample of each rather than all of one. Returns
    label -> (timing dict, last parallel result)."""
    cpu = {k: math.inf for k in fns}
    wall = dict(cpu)
    out = {}
    for _ in range(max(1, repeat)):
        for k, fn in fns.items():
            with serial_numba():
                _, c, _ = _timed(fn, time.thread_time)
            w, _, out[k] = _timed(fn)
            cpu[k], wall[k] = min(cpu[k], c), min(wall[k], w)
    threads = numba.get_num_threads()
    return {k: ({"points": n, "threads": threads, "cpu_seconds_per_point": cpu[k] / n,
                 "points_per_second": n / wall[k]}, out[k]) for k in fns}


def _engine_settings(tols, steps_list):
    """(label, options) of every engine setting timed: the package default, each tol, each
    expert resolution."""
    out = [(f"default (steps={sweep.DEFAULT_STEPS:g})", {})]
    out += [(f"tol={t:g}", {"tol": float(t)}) for t in tols]
    out += [(f"steps={s:g}", {"steps": float(s)}) for s in steps_list]
    return out


def _engine_rows(bench, settings, repeat, progress):
    """Time the integrator at every setting (serial CPU and parallel throughput)."""
    a, b, gamma, gtilde = bench.a, bench.b, bench.gamma, bench.gtilde
    fns = {label: (lambda o=opts: sweep.integrate(a, b, gamma, gtilde, **o))
           for label, opts in settings}
    for fn in fns.values():      # compile or load both kernels outside the clock
        fn()
        with serial_numba():
            fn()
    rows = []
    for label, (timing, r) in _two_ways(fns, gamma.size, repeat).items():
        e = np.asarray(r.e)
        rows.append(bench.row("engine", "sweep.integrate", label, timing, e, e[bench.sub]))
        log_progress(progress, f"  {label}: {timing['points_per_second']:,.0f} points/s, "
                               f"{timing['cpu_seconds_per_point'] * 1e6:.2f} us CPU/point, "
                               f"max err {rows[-1]['max_abs_error']:.2e}")
    return rows


def _closed_form_call(a, b, gamma, gtilde, method, n_closed, min_call_s):
    """A call of ``method`` on the set tiled until a serial call takes ``min_call_s``
    (estimated from a first call on the set), at most ``n_closed`` points, with
    full-length exponent arrays (no broadcast copies inside the timing)."""
    with serial_numba():
        sweep.cor(a, b, gamma, gtilde, method=method)       # compile or load
        _, first, _ = _timed(lambda: sweep.cor(a, b, gamma, gtilde, method=method),
                             time.thread_time)
    reps = min(math.ceil(min_call_s / max(first, 1e-9)), math.ceil(n_closed / gamma.size))
    reps = max(1, reps)
    gt, Gt = np.tile(gamma, reps), np.tile(gtilde, reps)
    at, bt = np.full(gt.size, a), np.full(gt.size, b)
    fn = lambda: sweep.cor(at, bt, gt, Gt, method=method)  # noqa: E731
    fn()                                                   # warm, at full length
    return fn, gt.size


def _approximation_rows(bench, n_closed, min_call_s, repeat, progress):
    """Time every closed form defined for the bench's model on the tiled set (module
    docstring); errors on the common set."""
    a, b, gamma, gtilde = bench.a, bench.b, bench.gamma, bench.gtilde
    rows = []
    for m in sweep.APPROXIMATIONS:
        if not METHODS[m].defined_at(a, b).all():
            continue
        fn, n = _closed_form_call(a, b, gamma, gtilde, m, n_closed, min_call_s)
        timing, e = _two_ways({m: fn}, n, repeat)[m]
        e = np.asarray(e)[:gamma.size]
        rows.append(bench.row("approximation", f"sweep.cor {m}", m, timing, e, e[bench.sub]))
        log_progress(progress, f"  {m} ({n:,} points): {timing['points_per_second']:,.0f} "
                               f"points/s, {timing['cpu_seconds_per_point'] * 1e9:.1f} ns "
                               "CPU/point")
    return rows


def _peer_points(bench, tool, n_vector):
    """Indices a peer runs on: the subset; for the vectorised diffrax, the subset first and
    then more points of the set, ``n_vector`` in all (a vmap over 100 lanes would time
    JAX's per-step overhead, not the solver)."""
    if tool != "diffrax" or n_vector <= bench.sub.size:
        return bench.sub
    rest = np.setdiff1d(np.arange(bench.gamma.size), bench.sub)
    return np.concatenate([bench.sub, rest[:n_vector - bench.sub.size]])


def _peer_rows(bench, peer_settings, n_vector, repeat, progress):
    """Time every installed peer at every tolerance; returns (rows, notes on skipped)."""
    a, b, gamma, gtilde = bench.a, bench.b, bench.gamma, bench.gtilde
    missing = available_peers()
    rows, notes = [], []
    for tool, method, rtols in peer_settings:
        label = f"{_TOOL_LABEL.get(tool, tool)} {method}"
        if missing.get(tool):
            notes.append(f"{label}: skipped, {missing[tool]}.")
            log_progress(progress, f"  {label}: skipped ({missing[tool]})")
            continue
        idx = _peer_points(bench, tool, n_vector)
        pts = (np.full(idx.size, a), np.full(idx.size, b), gamma[idx], gtilde[idx])
        key = "method" if tool == "scipy" else "solver" if tool == "diffrax" else None
        extra = {key: method} if key else {}
        # compile outside the clock (numbalsoda once; diffrax once per array size)
        n_warm = idx.size if tool == "diffrax" else 1
        compile_s, _, _ = _timed(lambda: peer_cors(tool, {**extra, "rtol": rtols[0]},  # noqa: B023
                                                   *(x[:n_warm] for x in pts)))
        threads = (os.cpu_count() or 1) if tool == "diffrax" else 1
        reps = max(1, repeat) if tool == "diffrax" else 1    # the others: one long loop
        clock = time.process_time if tool == "diffrax" else time.thread_time
        for rtol in rtols:
            best_w, best_c = math.inf, math.inf
            for _ in range(reps):
                w, c, e = _timed(lambda: peer_cors(tool, {**extra, "rtol": rtol}, *pts),  # noqa: B023
                                 clock)
                best_w, best_c = min(best_w, w), min(best_c, c)
            timing = {"points": int(idx.size), "threads": threads,
                      "cpu_seconds_per_point": best_c / idx.size,
                      "points_per_second": idx.size / best_w,
                      "compile_seconds": None if tool == "scipy" else compile_s}
            e = np.asarray(e)
            rows.append(bench.row("peer", label, f"rtol={rtol:g}", timing, None,
                                  e[:bench.sub.size]))
            log_progress(progress, f"  {label} rtol={rtol:g}: {idx.size / best_w:,.1f} "
                                   f"points/s, subset max err "
                                   f"{rows[-1]['subset_max_abs_error']:.2e}")
    return rows, notes


def _headline(rows):
    """Each peer's time at the engine's error on the subset, as ratios (module docstring)."""
    engine = [r for r in rows if r["kind"] == "engine"]
    peers = sorted({r["method"] for r in rows if r["kind"] == "peer"},
                   key=[r["method"] for r in rows].index)
    metric = "subset_max_abs_error"
    out = []
    for en in engine:
        for peer in peers:
            pr = [r for r in rows if r["method"] == peer]
            errs = [r[metric] for r in pr]
            target = en[metric]
            cpu, _ = time_at_error(errs, [r["cpu_seconds_per_point"] for r in pr], target)
            spp, _ = time_at_error(errs, [r["seconds_per_point"] for r in pr], target)
            bound = error_bound(errs, target)
            r_cpu = cpu / en["cpu_seconds_per_point"]
            r_thr = spp / en["seconds_per_point"]
            out.append({"engine": en["setting"], "peer": peer, "engine_error": target,
                        "engine_cpu_seconds_per_point": en["cpu_seconds_per_point"],
                        "peer_cpu_seconds_per_point": cpu, "bound": bound,
                        "ratio_cpu": r_cpu, "ratio_throughput": r_thr,
                        "ratio_cpu_text": f"{bound}{r_cpu:,.0f}" if bound != "?" else "-",
                        "ratio_throughput_text": (f"{bound}{r_thr:,.0f}" if bound != "?"
                                                  else "-")})
    return out


def _headline_table(headline):
    """Pivot: one row per engine setting, one column per peer, ``ratio_cpu_text``."""
    peers = list(dict.fromkeys(h["peer"] for h in headline))
    table = {}
    for h in headline:
        row = table.setdefault(h["engine"], {"engine setting": h["engine"],
                                             "engine max error": h["engine_error"]})
        row[h["peer"]] = h["ratio_cpu_text"]
    return list(table.values()), ["engine setting", "engine max error"] + peers


def _notes(machine, bench, model, seed, reference, repeat, n_closed, min_call_s):
    n_points, a, b = bench.gamma.size, bench.a, bench.b
    return [
        f"Machine: {machine_line(machine)}. Timings on a shared machine are indicative.",
        f"Points: {n_points} {PAPER_MODELS[model][2]} points (alpha = {a:g}, beta = {b:g}), "
        f"gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1), seed {seed}; peers on a random subset "
        f"of {bench.sub.size} ('subset_*' columns are on that subset for every method).",
        f"Reference: sweep.integrate at steps = {reference['steps']:g} refined to "
        f"{reference['tol']:g} ({reference['undecided']} undecided points excluded); "
        f"|e(steps/2) - e(steps)| max {format_value(reference['half_steps_max_diff'])}; "
        f"against {reference['crosscheck']} on {reference['crosscheck_points']} points: max "
        f"diff {format_value(reference['crosscheck_max_diff'])}, median "
        f"{format_value(reference['crosscheck_median_diff'])}.",
        f"Engine and closed forms: best of {repeat}; cpu_seconds_per_point: CPU time of the "
        "calling thread running the serial kernels (one numba thread); points_per_second: "
        f"wall clock on all {machine['numba_threads']} "
        f"numba threads. Closed forms timed on the set tiled until a call takes "
        f">= {min_call_s:g} s (at most {n_closed:,} points: the 'points' column), so that "
        "per-call and parallel-launch costs do not dominate.",
        "Peers: one run each (diffrax: best of the repeats, compile time apart in "
        "compile_seconds); scipy and numbalsoda one point at a time on one core (CPU time "
        "of that thread), diffrax vmapped over its points on the threads XLA uses (CPU time "
        "of the process); atol = rtol / 100; a failed point counts as error 1 (column "
        "failed).",
    ]


def _write_tables(out, rows, headline, notes):
    """Write speed.csv, speed_headline.csv and speed.md; return the markdown."""
    cols = ["kind", "method", "setting", "points", "threads", "cpu_seconds_per_point",
            "points_per_second", "seconds_per_point", "max_abs_error", "median_abs_error",
            "p99_abs_error", "subset_max_abs_error", "subset_median_abs_error", "failed",
            "compile_seconds"]
    write_table(rows, cols, out / "speed.csv")
    md = write_table(rows, cols, md_path=None, title="Speed against error", notes=notes,
                     formats={"points_per_second": ",.0f", "points": "d", "threads": "d",
                              "failed": "d"})
    hcols = ["engine", "peer", "engine_error", "engine_cpu_seconds_per_point",
             "peer_cpu_seconds_per_point", "bound", "ratio_cpu", "ratio_throughput"]
    write_table(headline, hcols, out / "speed_headline.csv")
    pivot, pcols = _headline_table(headline)
    hnotes = ["Each cell: the peer's CPU time per point, interpolated log-log at the "
              "engine's max abs error on the common subset, over the engine's CPU time per "
              "point (one core each). '>': the peer never reached that error in the "
              "tolerances tried (lower bound); '<': its loosest tolerance was already more "
              "accurate (upper bound). Throughput ratios (engine on all cores against the "
              "peer as it runs) in speed_headline.csv."]
    md += "\n" + write_table(pivot, pcols, title="Headline: peer CPU time / engine CPU time "
                             "at equal max error", notes=hnotes)
    (out / "speed.md").write_text(md, encoding="utf-8")
    return md


def speed_report(out: str | os.PathLike = "speed_report", *, n_points: int = 20000,
                 tols: Sequence[float] = TOLS, steps_list: Sequence[float] = (),
                 ref_steps: float = 1024, ref_tol: float = 1e-13, n_check: int = 100,
                 n_peer: int = 100, n_vector: int = 2000, n_closed: int = 2_000_000,
                 min_call_s: float = 0.02,
                 peer_settings: Sequence[tuple[str, str, Sequence[float]]] = PEER_SETTINGS,
                 model: str = "kk", seed: int = 0, repeat: int = 3,
                 crosscheck: Callable[[float, float, float, float], float] | None = None,
                 crosscheck_name: str | None = None,
                 progress: bool = False) -> dict[str, Any]:
    """Measure speed against error on one point set; write the plot and tables into ``out``.

    Parameters
    ----------
    out : path-like
        Output directory (created).
    n_points : int
        Size of the common point set.
    tols : sequence of float
        Accuracy targets of the engine [1] (max abs error of e); its default is always timed.
    steps_list : sequence of float
        Expert resolutions (steps per half period) timed as well.
    ref_steps, ref_tol : float
        Resolution and refinement target [1] of the reference run.
    n_check : int
        Points on which the reference is compared with ``crosscheck``.
    n_peer : int
        Points (a random subset) given to the peers.
    n_vector : int
        Points given to the vectorised peer (diffrax), the subset among them.
    n_closed, min_call_s : int, float
        Each closed form is timed on the set tiled until a serial call takes at least
        ``min_call_s`` [s], at most ``n_closed`` points.
    peer_settings : sequence of (tool, method, rtols)
        See :data:`PEER_SETTINGS`; uninstalled optional peers are skipped with a note.
    model : str
        Key of :data:`sweep.reports.paper_values.PAPER_MODELS`.
    seed : int
        Seed of the point set and of the subsets.
    repeat : int
        Timings of sweep (and diffrax) are the best of this many runs.
    crosscheck : callable, optional
        ``f(alpha, beta, gamma, gtilde) -> e`` for the reference check; default
        :func:`scipy_user_cor` with DOP853 at rtol 1e-13, atol 1e-15.
    crosscheck_name : str, optional
        Its label in the tables and the plot (default: its ``__name__``).
    progress : bool
        Print progress messages to stderr.

    Returns
    -------
    dict
        ``out``, ``files``, ``rows``, ``headline``, ``reference``, ``machine``, ``skipped``
        (notes on peers not run), ``markdown``.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    a, b = PAPER_MODELS[model][:2]
    machine = machine_description()
    gamma, gtilde = sample_points(n_points, seed)
    rng = np.random.default_rng(seed + 1)
    sub = np.sort(rng.choice(n_points, size=min(n_peer, n_points), replace=False))
    chk = np.sort(rng.choice(n_points, size=min(n_check, n_points), replace=False))
    ref, reference = _reference(a, b, gamma, gtilde, ref_steps, ref_tol, progress)
    bench = _Bench(a, b, gamma, gtilde, sub, ref)
    reference.update(_crosscheck(bench, chk, crosscheck, crosscheck_name, progress))
    rows = (_engine_rows(bench, _engine_settings(tols, steps_list), repeat, progress)
            + _approximation_rows(bench, n_closed, min_call_s, repeat, progress))
    peer_rows, skipped = _peer_rows(bench, peer_settings, n_vector, repeat, progress)
    rows += peer_rows
    headline = _headline(rows)
    notes = (_notes(machine, bench, model, seed, reference, repeat, n_closed, min_call_s)
             + skipped)
    md = _write_tables(out, rows, headline, notes)
    files = [out / "speed.md", out / "speed.csv", out / "speed_headline.csv",
             out / "work_precision.png"]
    _plot(files[-1], rows, machine, reference, n_points, sub.size, model)
    return {"out": out, "files": files, "rows": rows, "headline": headline,
            "reference": reference, "machine": machine, "skipped": skipped, "markdown": md}


def _series(rows):
    """Label -> rows of every engine / peer curve, in order of appearance."""
    curves = {}
    for r in rows:
        if r["kind"] in ("engine", "peer"):
            key = "sweep.integrate (tol)" if r["kind"] == "engine" else r["method"]
            if r["kind"] == "engine" and not r["setting"].startswith("tol="):
                key = "sweep.integrate (default / steps)"
            curves.setdefault(key, []).append(r)
    return curves


def _plot(path, rows, machine, reference, n_points, n_sub, model):
    plt = use_agg()
    floor = 1e-17
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.8), constrained_layout=True)
    panels = ((axes[0], "cpu_seconds_per_point", "CPU time per point [s] (one core)"),
              (axes[1], "points_per_second", "points/s (sweep: all numba threads; "
                                              "peers as run)"))
    markers = "osDv^<>ph"
    for ax, key, ylabel in panels:
        for k, (label, rs) in enumerate(_series(rows).items()):
            x = [max(r["subset_max_abs_error"], floor) for r in rs]
            y = [r[key] for r in rs]
            ax.loglog(x, y, marker=markers[k % len(markers)], ls="-", ms=5, color=f"C{k}",
                      label=label + ("" if "sweep" in label or "diffrax" in label
                                     else " (1 core)"))
            for r, xi, yi in zip(rs, x, y):
                ax.annotate(r["setting"].split(" ")[0].replace("rtol=", "").replace(
                    "tol=", ""), (xi, yi), textcoords="offset points", xytext=(3, 3),
                    fontsize=5.5, color=f"C{k}")
        stars = plt.get_cmap("Dark2")          # apart from the curves' tab10 colours
        for j, r in enumerate(r for r in rows if r["kind"] == "approximation"):
            ax.loglog([max(r["subset_max_abs_error"], floor)], [r[key]], marker="*", ms=10,
                      ls="none", color=stars(j % 8), mec="k", mew=0.4,
                      label=f"closed form {r['setting']}")
        ax.set_xlabel(f"max abs error of e against the reference ({n_sub} common points)")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.25)
    axes[0].legend(fontsize=6.5, loc="best")
    # Named only where it ran (optional; the title named it on every machine without it).
    vectorised = (" (diffrax on more, same subset scored)"
                  if any("diffrax" in label for label in _series(rows)) else "")
    fig.suptitle(
        f"Work-precision, {PAPER_MODELS[model][2]} points (gamma in [1e-4, 0.32], g~ in "
        f"[1e-3, 10]); sweep timed on {n_points} points, peers on {n_sub}{vectorised}"
        f"\nreference: integrator at {reference['steps']:g} steps refined "
        f"to {reference['tol']:g}, vs {reference['crosscheck']} max diff "
        f"{format_value(reference['crosscheck_max_diff'])}\n{machine_line(machine)}",
        fontsize=7.5)
    fig.savefig(path, dpi=120)
    plt.close(fig)
