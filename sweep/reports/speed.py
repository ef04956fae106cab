"""``sweep report speed``: time per point against error (a work-precision diagram).

On one common point set (default: 20,000 Kuwabara-Kono points, gamma = 10**U(-4, -0.5),
g~ = 10**U(-3, 1), as ``benchmarks/throughput.py``), in one run:

* the reference: the integrator at ``ref_steps`` (default 1024 steps per half period),
  checked against itself at half that resolution on every point and against scipy's DOP853
  at rtol 1e-13 on a subset (the test suite's slow reference when run from a source
  checkout: grazing refinement, energy identity; otherwise a plain DOP853 with events);
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
"""
from __future__ import annotations

import importlib.util
import math
import sys
import time
from pathlib import Path

import numpy as np

from sweep.reports.paper_values import PAPER_MODELS
from sweep.reports import format_value, machine_description, machine_line, use_agg, write_table

__all__ = ["speed_report", "sample_points", "scipy_user_cor", "time_at_error",
           "STEPS_LIST", "SCIPY_SETTINGS"]

#: Integrator resolutions timed (steps per half period).
STEPS_LIST = (12, 16, 24, 32, 48, 64, 96, 128)
#: scipy methods and relative tolerances (atol = rtol / 100).
SCIPY_SETTINGS = (("RK45", (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)),
                  ("DOP853", (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)))


def _log(progress, msg):
    if progress:
        print(msg, file=sys.stderr, flush=True)


def sample_points(n, seed=0):
    """gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1) (``default_rng(seed)``, gamma first)."""
    rng = np.random.default_rng(seed)
    gamma = 10 ** rng.uniform(-4, -0.5, n)
    gtilde = 10 ** rng.uniform(-3, 1, n)
    return gamma, gtilde


def scipy_user_cor(alpha, beta, gamma, gtilde, method="DOP853", rtol=1e-8, atol=None,
                   t_max=1e3):
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


def time_at_error(errors, times, target):
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


def _load_test_reference():
    """The test suite's DOP853 reference (tests/reference.py) when run from a checkout."""
    path = Path(__file__).resolve().parents[2] / "tests" / "reference.py"
    if not path.exists():
        return None
    try:
        spec = importlib.util.spec_from_file_location("_sweep_tests_reference", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod.dop853_cor
    except Exception:  # pragma: no cover - missing test dependencies (mpmath)
        return None


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


def speed_report(out="speed_report", *, n_points=20000, steps_list=STEPS_LIST,
                 ref_steps=1024, n_check=100, n_scipy=100, scipy_settings=SCIPY_SETTINGS,
                 model="kk", seed=0, repeat=3, crosscheck=None, progress=False):
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
        Points on which the reference is compared with DOP853 (rtol 1e-13).
    n_scipy : int
        Points (a random subset) given to scipy, one at a time.
    scipy_settings : sequence of (method, rtols)
    model : str
        Key of :data:`sweep.reports.paper_values.PAPER_MODELS`.
    crosscheck : callable, optional
        ``f(alpha, beta, gamma, gtilde) -> e`` for the reference check; default the test
        suite's DOP853 reference if available, else :func:`scipy_user_cor` at rtol 1e-13.

    Returns
    -------
    dict
        ``out``, ``files``, ``rows``, ``headline``, ``reference``, ``machine``,
        ``markdown``.
    """
    import sweep
    from sweep.api import APPROXIMATIONS

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    a, b = PAPER_MODELS[model][:2]
    machine = machine_description()
    gamma, gtilde = sample_points(n_points, seed)
    rng = np.random.default_rng(seed + 1)
    sub = np.sort(rng.choice(n_points, size=min(n_scipy, n_points), replace=False))
    chk = np.sort(rng.choice(n_points, size=min(n_check, n_points), replace=False))
    steps_list = sorted(set(float(s) for s in steps_list) | {float(sweep.DEFAULT_STEPS)})

    # ---- reference
    _log(progress, f"reference: integrator at steps = {ref_steps:g} on {n_points} points")
    t_ref, _, r_ref = _best_time(lambda: sweep.integrate(a, b, gamma, gtilde, steps=ref_steps),
                                 1)
    ref = np.asarray(r_ref.e, dtype=float)
    undecided = ~np.isin(r_ref.status, (sweep.Status.OK, sweep.Status.STUCK,
                                        sweep.Status.AT_REST))
    ref[undecided] = np.nan
    half = sweep.integrate(a, b, gamma, gtilde, steps=ref_steps / 2).e
    self_diff = _err_stats(np.abs(half - ref))
    if crosscheck is None:
        test_ref = _load_test_reference()
        if test_ref is not None:
            crosscheck = lambda *p: test_ref(*p).e  # noqa: E731
            check_name = "tests/reference.py dop853_cor (DOP853 rtol 1e-13, atol 1e-15)"
        else:
            crosscheck = lambda *p: scipy_user_cor(*p, method="DOP853", rtol=1e-13,  # noqa
                                                   atol=1e-15)
            check_name = "plain DOP853 with events (rtol 1e-13, atol 1e-15)"
    else:
        check_name = getattr(crosscheck, "__name__", "user cross-check")
    _log(progress, f"cross-check of the reference with {check_name} on {chk.size} points")
    t0 = time.perf_counter()
    dop = np.array([crosscheck(a, b, gamma[i], gtilde[i]) for i in chk])
    t_dop = time.perf_counter() - t0
    check_diff = np.abs(dop - ref[chk])
    reference = {"steps": ref_steps, "seconds": t_ref, "undecided": int(undecided.sum()),
                 "half_steps_max_diff": self_diff["max"],
                 "half_steps_median_diff": self_diff["median"],
                 "crosscheck": check_name, "crosscheck_points": int(chk.size),
                 "crosscheck_max_diff": float(np.nanmax(check_diff)) if chk.size else None,
                 "crosscheck_median_diff":
                     float(np.nanmedian(check_diff)) if chk.size else None,
                 "crosscheck_seconds_per_point": t_dop / max(chk.size, 1)}

    rows = []

    def add(kind, label, setting, seconds, cpu, n, e_full, e_sub, threads):
        err_full = np.abs(e_full - ref) if e_full is not None else None
        err_sub = np.abs(e_sub - ref[sub])
        full = _err_stats(err_full) if err_full is not None else {}
        part = _err_stats(err_sub)
        rows.append({"kind": kind, "method": label, "setting": setting,
                     "points": n, "threads": threads, "seconds_per_point": seconds / n,
                     "points_per_second": n / seconds, "cpu_seconds_per_point": cpu / n,
                     "max_abs_error": full.get("max"), "median_abs_error": full.get("median"),
                     "p99_abs_error": full.get("p99"),
                     "subset_max_abs_error": part["max"],
                     "subset_median_abs_error": part["median"]})

    nthreads = machine["numba_threads"]
    # Round robin over the resolutions, best of ``repeat``: a burst of load from other
    # processes then spoils one sample of each resolution rather than all of one.
    best = {s: math.inf for s in steps_list}
    best_cpu = dict(best)
    results = {}
    for _ in range(max(1, repeat)):
        for s in steps_list:
            wall, cpu, results[s] = _timed(
                lambda: sweep.integrate(a, b, gamma, gtilde, steps=s))  # noqa: B023
            best[s], best_cpu[s] = min(best[s], wall), min(best_cpu[s], cpu)
    for s in steps_list:
        e = np.asarray(results[s].e)
        tag = " (default)" if s == sweep.DEFAULT_STEPS else ""
        add("integrator", "sweep.integrate", f"steps={s:g}{tag}", best[s], best_cpu[s],
            n_points, e, e[sub], nthreads)
        _log(progress, f"  steps={s:g}: {n_points / best[s]:,.0f} points/s, max err "
                       f"{rows[-1]['max_abs_error']:.2e}")
    for m in APPROXIMATIONS:
        if m == "sp" and not (a == 1.5 and b == 1.5):
            continue
        sweep.cor(a, b, gamma, gtilde, method=m)      # compile (serial and parallel kernels)
        sec, cpu, e = _best_time(lambda: sweep.cor(a, b, gamma, gtilde, method=m), repeat)
        add("approximation", f"sweep.cor {m}", m, sec, cpu, n_points, np.asarray(e),
            np.asarray(e)[sub], nthreads)
        _log(progress, f"  {m}: {n_points / sec:,.0f} points/s, max err "
                       f"{rows[-1]['max_abs_error']:.2e}")
    for method, rtols in scipy_settings:
        for rtol in rtols:
            sec, cpu, e = _timed(lambda: np.array(
                [scipy_user_cor(a, b, gamma[i], gtilde[i], method, rtol)  # noqa: B023
                 for i in sub]))
            add("scipy", f"solve_ivp {method}", f"rtol={rtol:g}", sec, cpu, sub.size, None,
                e, 1)
            _log(progress, f"  {method} rtol={rtol:g}: {sub.size / sec:,.1f} points/s, "
                           f"subset max err {rows[-1]['subset_max_abs_error']:.2e}")

    # ---- headline: scipy's time at sweep's error, on the same subset
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

    # ---- outputs
    files = []
    cols = ["kind", "method", "setting", "points", "threads", "points_per_second",
            "seconds_per_point", "cpu_seconds_per_point", "max_abs_error", "median_abs_error", "p99_abs_error",
            "subset_max_abs_error", "subset_median_abs_error"]
    notes = [
        f"Machine: {machine_line(machine)}.",
        f"Points: {n_points} {PAPER_MODELS[model][2]} points (alpha = {a:g}, beta = {b:g}), "
        f"gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1), seed {seed}; scipy on a random subset "
        f"of {sub.size} ('subset_*' columns are on that subset for every method).",
        f"Reference: sweep.integrate at steps = {ref_steps:g} ({reference['undecided']} "
        f"undecided points excluded); |e(steps/2) - e(steps)| max "
        f"{format_value(reference['half_steps_max_diff'])}; against {check_name} on "
        f"{chk.size} points: max diff {format_value(reference['crosscheck_max_diff'])}, "
        f"median {format_value(reference['crosscheck_median_diff'])}.",
        "Times: best of %d runs for sweep (all %d numba threads; wall and process CPU "
        "time, each the best); one run, one core, one point at a time for scipy (atol = "
        "rtol/100, terminal events)." % (repeat, nthreads),
    ]
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
    files += [out / "speed.md", out / "speed.csv", out / "speed_headline.csv"]
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
