"""``sweep report speed``: time per point against error (a work-precision diagram).

On one common point set (default: 20,000 Kuwabara-Kono points, gamma = 10**U(-4, -0.5),
g~ = 10**U(-3, 1), as ``benchmarks/throughput.py``), in one run:

* the reference: the integrator at ``ref_steps`` (default 1024 steps per half period),
  checked against itself at half that resolution on every point and, on a subset, against
  an independent integrator (see "The reference" below);
* the integrator at several resolutions (steps = 12 ... 128 and the package default):
  points/s (best of ``repeat``, all cores) and abs error against the reference;
* every approximation of the report: points/s and abs error against the reference (that is,
  against the numerical CoR);
* scipy's ``solve_ivp`` (RK45 and DOP853 at several tolerances, terminal events for the
  detachment u = 0 and for the trough v = 0 where the bead sticks), one point at a time on
  a small subset -- what a scipy user would write (:func:`scipy_user_cor`).

The headline: scipy's time per point interpolated (log-log, between its tolerances) at the
error the integrator reaches at the package's default resolution, divided by the
integrator's time per point -- on the same subset of points, for the max and the median
abs error. Two ratios: wall-clock time per point (the integrator uses every core through
numba threads, scipy one core), and CPU time per point (process CPU time of all threads:
equal footing per core, and less sensitive to other processes competing for the cores).
The plot shows CPU time per point.

The reference
-------------
The reference is the package's own integrator at high resolution: its error falls like
``steps**-5`` and the test suite validates it against slow independent solutions
(``tests/reference.py``: DOP853 with grazing refinement and the energy identity, exact
linear and TTI cases). The report does not load those (a package must not reach into its
tests, which an installed copy does not even have); it cross-checks the reference on a
subset with the plain DOP853 peer it already times (:func:`scipy_user_cor` at rtol 1e-13,
atol 1e-15) -- independent of sweep's code, though less careful at grazing contacts than the
test suite's. A caller with a better judge passes it as ``crosscheck`` (as
``benchmarks/work_precision.py`` does with the test suite's reference).

May import: numpy, scipy (lazily), the public ``sweep`` names and :mod:`sweep.api`,
:mod:`sweep.reports.common` and :mod:`sweep.reports.paper_values`; matplotlib lazily,
after :func:`sweep.reports.common.use_agg` has set its backend.
"""
from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

import sweep
from sweep.reports.common import (format_value, log_progress, machine_description,
                                  machine_line, use_agg, write_table)
from sweep.reports.paper_values import PAPER_MODELS

__all__ = ["speed_report", "sample_points", "scipy_user_cor", "time_at_error",
           "STEPS_LIST", "SCIPY_SETTINGS", "PLAIN_DOP853"]

#: Integrator resolutions timed (steps per half period).
STEPS_LIST = (12, 16, 24, 32, 48, 64, 96, 128)
#: scipy methods and relative tolerances (atol = rtol / 100).
SCIPY_SETTINGS = (("RK45", (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)),
                  ("DOP853", (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)))


def sample_points(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1) (``default_rng(seed)``, gamma first)."""
    rng = np.random.default_rng(seed)
    gamma = 10 ** rng.uniform(-4, -0.5, n)
    gtilde = 10 ** rng.uniform(-3, 1, n)
    return gamma, gtilde


def scipy_user_cor(alpha: float, beta: float, gamma: float, gtilde: float,
                   method: str = "DOP853", rtol: float = 1e-8, atol: float | None = None,
                   t_max: float = 1e3) -> float:
    """The CoR as a scipy user would compute it: one ``solve_ivp`` call with events.

    Integrates the report's (u, w) form (4), ``u' = w - gamma u_+^beta``,
    ``w' = g~ - u_+^alpha`` from (0, 1), with two terminal events located by solve_ivp:
    u = 0 crossed downward (detachment, ``e = -w``) and v = w - gamma u_+^beta crossed
    upward (a trough of u: the bead stopped short of the floor, ``e = 0``). No event until
    ``t_max``: at rest, ``e = 0``.
    """
    from scipy.integrate import solve_ivp

    a, b, g, G = float(alpha), float(beta), float(gamma), float(gtilde)
    atol = rtol / 100.0 if atol is None else atol

    def rhs(t, y):
        u = y[0] if y[0] > 0.0 else 0.0
        return [y[1] - g * u ** b, G - u ** a]

    def detach(t, y):
        return y[0]

    def trough(t, y):
        u = y[0] if y[0] > 0.0 else 0.0
        return y[1] - g * u ** b

    detach.terminal = trough.terminal = True
    detach.direction, trough.direction = -1, 1
    sol = solve_ivp(rhs, (0.0, t_max), [0.0, 1.0], method=method, rtol=rtol, atol=atol,
                    events=[detach, trough])
    if sol.t_events[0].size:
        return -float(sol.y_events[0][0][1])
    return 0.0


def time_at_error(errors: ArrayLike, times: ArrayLike, target: float) -> tuple[float, bool]:
    """Interpolate time against error (log-log, piecewise linear) at ``target``.

    Returns ``(time, exact)``: ``exact`` False when ``target`` lies outside the measured
    errors (then the time of the nearest end: the most accurate setting if the target is
    below every measured error, so the true time is larger -- a lower bound).
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


def _timed(fn):
    """``(wall seconds, CPU seconds of the process -- all threads --, result)``."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def _best_time(fn, repeat):
    """Best wall and best CPU time over ``repeat`` calls, and the last result."""
    best, best_cpu, out = math.inf, math.inf, None
    for _ in range(max(1, repeat)):
        wall, cpu, out = _timed(fn)
        best, best_cpu = min(best, wall), min(best_cpu, cpu)
    return best, best_cpu, out


def _err_stats(err):
    err = err[np.isfinite(err)]
    if err.size == 0:
        return {"max": math.nan, "median": math.nan, "p99": math.nan}
    return {"max": float(err.max()), "median": float(np.median(err)),
            "p99": float(np.quantile(err, 0.99))}


#: Label of the default cross-check of the reference (:func:`_plain_dop853`).
PLAIN_DOP853 = "plain DOP853 with events (rtol 1e-13, atol 1e-15)"


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
    sub: np.ndarray          # indices of the subset given to scipy
    ref: np.ndarray          # reference e (NaN where undecided)

    def row(self, kind, label, setting, seconds, cpu, n, e_full, e_sub, threads):
        """One table row: timing of ``n`` points and errors against the reference."""
        full = _err_stats(np.abs(e_full - self.ref)) if e_full is not None else {}
        part = _err_stats(np.abs(e_sub - self.ref[self.sub]))
        return {"kind": kind, "method": label, "setting": setting,
                "points": n, "threads": threads, "seconds_per_point": seconds / n,
                "points_per_second": n / seconds, "cpu_seconds_per_point": cpu / n,
                "max_abs_error": full.get("max"), "median_abs_error": full.get("median"),
                "p99_abs_error": full.get("p99"),
                "subset_max_abs_error": part["max"],
                "subset_median_abs_error": part["median"]}


def _reference(a, b, gamma, gtilde, ref_steps, progress):
    """The integrator at ``ref_steps`` (undecided points NaN) and its self-check."""
    log_progress(progress, f"reference: integrator at steps = {ref_steps:g} on "
                           f"{gamma.size} points")
    t_ref, _, r_ref = _best_time(lambda: sweep.integrate(a, b, gamma, gtilde, steps=ref_steps, refine=False),
                                 1)
    ref = np.asarray(r_ref.e, dtype=float)
    undecided = ~np.isin(r_ref.status, (sweep.Status.OK, sweep.Status.STUCK,
                                        sweep.Status.AT_REST))
    ref[undecided] = np.nan
    half = sweep.integrate(a, b, gamma, gtilde, steps=ref_steps / 2, refine=False).e
    self_diff = _err_stats(np.abs(half - ref))
    return ref, {"steps": ref_steps, "seconds": t_ref, "undecided": int(undecided.sum()),
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


def _integrator_rows(bench, steps_list, repeat, nthreads, progress):
    """Time the integrator at every resolution (best of ``repeat``, all threads)."""
    a, b, gamma, gtilde = bench.a, bench.b, bench.gamma, bench.gtilde
    # Round robin over the resolutions, best of ``repeat``: a burst of load from other
    # processes then spoils one sample of each resolution rather than all of one.
    best = {s: math.inf for s in steps_list}
    best_cpu = dict(best)
    results = {}
    for _ in range(max(1, repeat)):
        for s in steps_list:
            wall, cpu, results[s] = _timed(
                lambda: sweep.integrate(a, b, gamma, gtilde, steps=s, refine=False))  # noqa: B023
            best[s], best_cpu[s] = min(best[s], wall), min(best_cpu[s], cpu)
    rows = []
    for s in steps_list:
        e = np.asarray(results[s].e)
        tag = " (default)" if s == sweep.DEFAULT_STEPS else ""
        rows.append(bench.row("integrator", "sweep.integrate", f"steps={s:g}{tag}", best[s],
                              best_cpu[s], gamma.size, e, e[bench.sub], nthreads))
        log_progress(progress, f"  steps={s:g}: {gamma.size / best[s]:,.0f} points/s, max "
                               f"err {rows[-1]['max_abs_error']:.2e}")
    return rows


def _approximation_rows(bench, repeat, nthreads, progress):
    """Time every approximation defined for the bench's model (best of ``repeat``)."""

    a, b, gamma, gtilde = bench.a, bench.b, bench.gamma, bench.gtilde
    rows = []
    for m in sweep.APPROXIMATIONS:
        if m == "sp" and not (a == 1.5 and b == 1.5):
            continue
        sweep.cor(a, b, gamma, gtilde, method=m)      # compile (serial and parallel kernels)
        sec, cpu, e = _best_time(lambda: sweep.cor(a, b, gamma, gtilde, method=m), repeat)
        rows.append(bench.row("approximation", f"sweep.cor {m}", m, sec, cpu, gamma.size,
                              np.asarray(e), np.asarray(e)[bench.sub], nthreads))
        log_progress(progress, f"  {m}: {gamma.size / sec:,.0f} points/s, max err "
                               f"{rows[-1]['max_abs_error']:.2e}")
    return rows


def _scipy_rows(bench, scipy_settings, progress):
    """Time ``solve_ivp`` one point at a time on the subset, at every tolerance."""
    a, b, gamma, gtilde, sub = bench.a, bench.b, bench.gamma, bench.gtilde, bench.sub
    rows = []
    for method, rtols in scipy_settings:
        for rtol in rtols:
            sec, cpu, e = _timed(lambda: np.array(
                [scipy_user_cor(a, b, gamma[i], gtilde[i], method, rtol)  # noqa: B023
                 for i in sub]))
            rows.append(bench.row("scipy", f"solve_ivp {method}", f"rtol={rtol:g}", sec, cpu,
                                  sub.size, None, e, 1))
            log_progress(progress, f"  {method} rtol={rtol:g}: {sub.size / sec:,.1f} "
                                   f"points/s, subset max err "
                                   f"{rows[-1]['subset_max_abs_error']:.2e}")
    return rows


def _headline(rows, scipy_settings):
    """scipy's time at sweep's default-resolution error, on the same subset, as ratios."""
    default = next(r for r in rows if r["setting"].endswith("(default)"))
    headline = []
    for method, _ in scipy_settings:
        sc = [r for r in rows if r["method"] == f"solve_ivp {method}"]
        for metric in ("subset_max_abs_error", "subset_median_abs_error"):
            target = default[metric]
            t_sc, exact = time_at_error([r[metric] for r in sc],
                                        [r["seconds_per_point"] for r in sc], target)
            c_sc, _ = time_at_error([r[metric] for r in sc],
                                    [r["cpu_seconds_per_point"] for r in sc], target)
            ratio = t_sc / default["seconds_per_point"]
            ratio_cpu = c_sc / default["cpu_seconds_per_point"]
            bound = "" if exact else ">"
            headline.append({"peer": f"solve_ivp {method}", "metric": metric,
                             "sweep_error": target,
                             "sweep_seconds_per_point": default["seconds_per_point"],
                             "scipy_seconds_per_point": t_sc, "interpolated": exact,
                             "ratio": ratio, "ratio_cpu": ratio_cpu,
                             "ratio_text": f"{bound}{ratio:,.0f}",
                             "ratio_cpu_text": f"{bound}{ratio_cpu:,.0f}"})
    return headline


def _notes(machine, bench, model, seed, reference, repeat, nthreads):
    n_points, a, b = bench.gamma.size, bench.a, bench.b
    return [
        f"Machine: {machine_line(machine)}.",
        f"Points: {n_points} {PAPER_MODELS[model][2]} points (alpha = {a:g}, beta = {b:g}), "
        f"gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1), seed {seed}; scipy on a random subset "
        f"of {bench.sub.size} ('subset_*' columns are on that subset for every method).",
        f"Reference: sweep.integrate at steps = {reference['steps']:g} "
        f"({reference['undecided']} undecided points excluded); |e(steps/2) - e(steps)| max "
        f"{format_value(reference['half_steps_max_diff'])}; against "
        f"{reference['crosscheck']} on {reference['crosscheck_points']} points: max diff "
        f"{format_value(reference['crosscheck_max_diff'])}, "
        f"median {format_value(reference['crosscheck_median_diff'])}.",
        "Times: best of %d runs for sweep (all %d numba threads; wall and process CPU "
        "time, each the best); one run, one core, one point at a time for scipy (atol = "
        "rtol/100, terminal events)." % (repeat, nthreads),
    ]


def _write_tables(out, rows, headline, notes):
    """Write speed.csv, speed_headline.csv and speed.md; return the markdown."""
    cols = ["kind", "method", "setting", "points", "threads", "points_per_second",
            "seconds_per_point", "cpu_seconds_per_point", "max_abs_error", "median_abs_error",
            "p99_abs_error", "subset_max_abs_error", "subset_median_abs_error"]
    write_table(rows, cols, out / "speed.csv")
    md = write_table(rows, cols, md_path=None, title="Speed against error", notes=notes,
                     formats={"points_per_second": ",.0f", "points": "d", "threads": "d"})
    hcols = ["peer", "metric", "sweep_error", "sweep_seconds_per_point",
             "scipy_seconds_per_point", "interpolated", "ratio", "ratio_cpu"]
    write_table(headline, hcols, out / "speed_headline.csv")
    hcols = hcols[:-2] + ["ratio_text", "ratio_cpu_text"]
    hnotes = [f"sweep at the default resolution (steps = {sweep.DEFAULT_STEPS:g}); scipy's "
              "time per point interpolated log-log at sweep's error on the same subset. "
              "interpolated = False: scipy never reached that error in the tolerances tried; "
              "its most accurate setting's time is used, so the ratio is a lower bound. "
              "ratio: wall-clock (sweep on all cores, scipy on one); ratio_cpu: CPU time "
              "per point (per core)."]
    md += "\n" + write_table(headline, hcols, title="Headline: scipy time / sweep time at "
                             "equal error (ratio; '>' = lower bound)", notes=hnotes)
    (out / "speed.md").write_text(md, encoding="utf-8")
    return md


def speed_report(out: str | os.PathLike = "speed_report", *, n_points: int = 20000,
                 steps_list: Sequence[float] = STEPS_LIST, ref_steps: float = 1024,
                 n_check: int = 100, n_scipy: int = 100,
                 scipy_settings: Sequence[tuple[str, Sequence[float]]] = SCIPY_SETTINGS,
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
    steps_list : sequence of float
        Integrator resolutions timed (the package default is added if missing).
    ref_steps : float
        Resolution of the reference run.
    n_check : int
        Points on which the reference is compared with ``crosscheck``.
    n_scipy : int
        Points (a random subset) given to scipy, one at a time.
    scipy_settings : sequence of (method, rtols)
    model : str
        Key of :data:`sweep.reports.paper_values.PAPER_MODELS`.
    seed : int
        Seed of the point set and of the subsets.
    repeat : int
        Timings of sweep are the best of this many runs.
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
        ``out``, ``files``, ``rows``, ``headline``, ``reference``, ``machine``,
        ``markdown``.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    a, b = PAPER_MODELS[model][:2]
    machine = machine_description()
    gamma, gtilde = sample_points(n_points, seed)
    rng = np.random.default_rng(seed + 1)
    sub = np.sort(rng.choice(n_points, size=min(n_scipy, n_points), replace=False))
    chk = np.sort(rng.choice(n_points, size=min(n_check, n_points), replace=False))
    steps_list = sorted(set(float(s) for s in steps_list) | {float(sweep.DEFAULT_STEPS)})
    ref, reference = _reference(a, b, gamma, gtilde, ref_steps, progress)
    bench = _Bench(a, b, gamma, gtilde, sub, ref)
    reference.update(_crosscheck(bench, chk, crosscheck, crosscheck_name, progress))
    nthreads = machine["numba_threads"]
    rows = (_integrator_rows(bench, steps_list, repeat, nthreads, progress)
            + _approximation_rows(bench, repeat, nthreads, progress)
            + _scipy_rows(bench, scipy_settings, progress))
    headline = _headline(rows, scipy_settings)
    md = _write_tables(out, rows, headline,
                       _notes(machine, bench, model, seed, reference, repeat, nthreads))
    files = [out / "speed.md", out / "speed.csv", out / "speed_headline.csv"]
    f = out / "work_precision.png"
    _plot(f, rows, machine, reference, n_points, sub.size, model)
    files.append(f)
    return {"out": out, "files": files, "rows": rows, "headline": headline,
            "reference": reference, "machine": machine, "markdown": md}


def _plot(path, rows, machine, reference, n_points, n_sub, model):
    plt = use_agg()
    floor = 1e-17
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.6), constrained_layout=True)
    styles = {"sweep.integrate": ("C0", "o-"), "solve_ivp RK45": ("C3", "s-"),
              "solve_ivp DOP853": ("C1", "D-")}
    for ax, metric, title in ((axes[0], "subset_max_abs_error", "max abs error"),
                              (axes[1], "subset_median_abs_error", "median abs error")):
        for label, (color, style) in styles.items():
            rs = [r for r in rows if r["method"] == label]
            if not rs:
                continue
            x = [max(r[metric], floor) for r in rs]
            y = [r["cpu_seconds_per_point"] for r in rs]
            ax.loglog(x, y, style, color=color, ms=5, label=label)
            for r, xi, yi in zip(rs, x, y):
                ax.annotate(r["setting"].replace(" (default)", "*"), (xi, yi),
                            textcoords="offset points", xytext=(4, 3), fontsize=6,
                            color=color)
        ap = [r for r in rows if r["kind"] == "approximation"]
        for k, r in enumerate(ap):
            ax.loglog([max(r[metric], floor)], [r["cpu_seconds_per_point"]], marker="*", ms=10,
                      ls="none", color=f"C{4 + k}", label=f"approx. {r['setting']}")
        ax.set_xlabel(f"{title} of e against the reference ({n_sub} common points)")
        ax.set_ylabel("CPU time per point [s] (all threads)")
        ax.grid(True, which="both", alpha=0.25)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(
        f"Work-precision, {PAPER_MODELS[model][2]} points (gamma in [1e-4, 0.32], g~ in "
        f"[1e-3, 10]): process CPU time per point (the cost per core; wall times in "
        f"speed.md);\nsweep timed on {n_points} points with its numba threads, scipy one point "
        f"at a time; * = package default resolution\n"
        f"reference: integrator at {reference['steps']:g} steps, vs {reference['crosscheck']}"
        f" max diff {format_value(reference['crosscheck_max_diff'])}\n"
        f"{machine_line(machine)}", fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)
