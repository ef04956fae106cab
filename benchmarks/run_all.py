"""Every speed figure of issue 10, one JSON line each, against its target.

    python benchmarks/run_all.py [--n 1000000] [--check 1000] [--repeat 3]
        [--sobol-n 1000000] [--gil-n 20000] [--only NAME ...] [--quick]

Figures (``name``; the target is issue 10's, "on this 2-core machine"):

* ``kk_tol1e-8``, ``kk_tol1e-10``: the core draw of ``benchmarks/throughput.py`` (Kuwabara-
  Kono, gamma = 10**U(-4, -0.5) drawn first, then g~ = 10**U(-3, 1), ``default_rng(0)``),
  ``sweep.integrate(..., tol=...)`` on all cores, best of ``--repeat``; compile time (first
  call on 256 points) apart. Max abs error against the test suite's DOP853 reference
  (``tests/reference.py``) on ``--check`` points of the same draw (``default_rng(1)``
  choice, as throughput.py). Pass: points/s at target and max error <= tol.
* ``hertz_tol1e-8`` (alpha = 1.5, beta = 1), ``shc_tol1e-8`` (1.5, 2.5), ``tti_tol1e-8``
  (1.5, 1.25): the same draw. The issue's text says "SHC (alpha = 1.5, beta = 1)": those are
  Hertz's exponents (SPEC, section 1: SHC is beta = 5/2), so both laws are measured, each
  under its right name, against the issue's 800,000 points/s.
* ``general_tol1e-8``: the same gamma, g~ draws, then alpha and beta uniform in [1, 3] from
  the same generator.
* ``sobol_1m_end_to_end``: ``sweep run configs/sobol_1m.toml`` in a subprocess after a warm-up
  run (warm kernel cache); points / ``run_time_s`` (the chunks' wall time: kernels, design,
  saving, writing; read from the output file), the best of ``--repeat`` rounds, the
  process's wall time beside it.
* ``sobol_1m_threads_2v1``: the same run with ``NUMBA_NUM_THREADS=2`` over ``=1``, the
  (lower) median of ``--repeat`` paired rounds (every round's ratio beside it); beside it
  the median round's two ``kernel_time_s`` and their ratio (the kernels alone, inside the
  runs: the background writer's zlib takes its CPU from them on two threads, from the idle
  core on one).
* ``startup_compile_fresh``: a fresh process with an empty kernel cache (``NUMBA_CACHE_DIR``
  a new temporary directory) calls every method of ``sweep.METHODS`` once with scalars
  (serial kernels) and once on 4,096 points (parallel kernels), then the integrator for
  every law of ``sweep.MODELS`` and a general pair; value = the sum of those first calls.
* ``startup_import_cor_warm``: ``python -c "import sweep; sweep.cor(1.5, 1.5, 0.01, 0.1)"``
  wall time with that cache now warm (best of ``--repeat``, median beside it).
* ``gil_release``: a Python thread counting in a loop, its rate while the main thread runs
  a serial integration (``parallel=False``), over its rate alone. The issue asks that it
  "keeps running" (today 1.6%); the pass threshold 0.5 is this script's.

The DOP853 reference is slow (~10-30 ms a point): its values are cached on disk by the
exact parameters of each point and a hash of ``tests/reference.py``, in
``benchmarks/.cache/`` (gitignored; ``--cache-dir``), and computed on every core.
Timings on a shared machine are indicative: each line carries the load average.
No line is a test: ``tests/test_benchmarks.py`` checks the structure only.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))       # the DOP853 reference lives with the tests

import sweep  # noqa: E402
from sweep.reports.common import machine_description  # noqa: E402

#: name -> (unit, target value, ">=" or "<=", what the issue says).
TARGETS = {
    "kk_tol1e-8": ("points/s", 1_000_000, ">=", "KK core draw, tol 1e-8, max error <= 1e-8"),
    "kk_tol1e-10": ("points/s", 400_000, ">=", "KK core draw, tol 1e-10"),
    "hertz_tol1e-8": ("points/s", 800_000, ">=", "Hertz (1.5, 1): the issue's 'SHC (1.5, 1)'"),
    "shc_tol1e-8": ("points/s", 800_000, ">=", "SHC (1.5, 2.5)"),
    "tti_tol1e-8": ("points/s", 800_000, ">=", "TTI (1.5, 1.25)"),
    "general_tol1e-8": ("points/s", 250_000, ">=", "alpha, beta ~ U[1, 3]"),
    "sobol_1m_end_to_end": ("points/s", 150_000, ">=", "sweep run configs/sobol_1m.toml"),
    "sobol_1m_threads_2v1": ("x", 1.85, ">=", "2 numba threads over 1, same run"),
    "startup_compile_fresh": ("s", 15.0, "<=", "first calls, empty cache, fresh process"),
    "startup_import_cor_warm": ("s", 1.5, "<=", "import sweep; sweep.cor(...), warm cache"),
    "gil_release": ("ratio", 0.5, ">=", "Python thread's rate during a serial kernel"),
}
#: (alpha, beta) of the fixed-law figures; None: general exponents.
LAWS = {"kk": (1.5, 1.5), "hertz": (1.5, 1.0), "shc": (1.5, 2.5), "tti": (1.5, 1.25),
        "general": None}
GROUPS = {"laws": [n for n in TARGETS if n.split("_")[0] in LAWS],
          "sobol": ["sobol_1m_end_to_end", "sobol_1m_threads_2v1"],
          "startup": ["startup_compile_fresh", "startup_import_cor_warm"],
          "gil": ["gil_release"]}
QUICK = {"n": 2000, "check": 20, "repeat": 1, "sobol_n": 4096, "gil_n": 1000}


# --------------------------------------------------------------------------- lines

def _machine():
    m = machine_description()
    keys = ("cpu", "usable_cores", "numba_threads", "threading_layer", "numba", "platform")
    return {k: m[k] for k in keys}


def line(name, value, machine, n, threads, **extra):
    """One JSON-ready figure: value against :data:`TARGETS`, pass/fail, context."""
    unit, target, sense, what = TARGETS[name]
    error_ok = extra.pop("error_ok", True)
    ok = bool((value >= target if sense == ">=" else value <= target) and error_ok)
    return {"name": name, "value": value, "unit": unit, "target": f"{sense} {target:g}",
            "pass": ok, "what": what, "n": n, "threads": threads, **extra,
            "load_average": round(os.getloadavg()[0], 2), "machine": machine}


# --------------------------------------------------------------------------- reference

def draw(n, law, log_gamma=(-4, -0.5)):
    """The core draw: gamma then g~ from ``default_rng(0)``; general: alpha, beta after.
    ``log_gamma``: the range of log10(gamma) (benchmarks/damped.py raises it)."""
    rng = np.random.default_rng(0)
    gamma = 10 ** rng.uniform(*log_gamma, n)
    gtilde = 10 ** rng.uniform(-3, 1, n)
    if LAWS[law] is None:
        alpha, beta = rng.uniform(1.0, 3.0, n), rng.uniform(1.0, 3.0, n)
    else:
        alpha, beta = np.full(n, LAWS[law][0]), np.full(n, LAWS[law][1])
    return alpha, beta, gamma, gtilde


def _dop853_e(p):
    from reference import dop853_cor  # noqa: PLC0415 -- the tests' slow reference

    return dop853_cor(*p).e


def reference_e(points, cache_dir):
    """DOP853 e of each row (alpha, beta, gamma, g~) of ``points``, cached on disk by value
    and by the reference's source; missing ones computed on every core."""
    src = hashlib.sha256((ROOT / "tests" / "reference.py").read_bytes()).hexdigest()[:16]
    path = Path(cache_dir) / f"dop853_{src}.npz"
    known = {}
    if path.exists():
        with np.load(path) as f:
            known = {tuple(p): e for p, e in zip(f["points"].tolist(), f["e"].tolist())}
    rows = [tuple(p) for p in np.asarray(points, dtype=float).tolist()]
    todo = sorted({p for p in rows if p not in known})
    if todo:
        print(f"run_all: DOP853 reference on {len(todo)} new points (cached in {path})",
              file=sys.stderr, flush=True)
        with concurrent.futures.ProcessPoolExecutor(os.cpu_count()) as pool:
            known.update(zip(todo, pool.map(_dop853_e, todo, chunksize=8)))
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, points=np.array(list(known)), e=np.array(list(known.values())))
        os.replace(tmp, path)
    return np.array([known[p] for p in rows])


# --------------------------------------------------------------------------- figures

def _best(fn, repeat):
    best, out = np.inf, None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def law_figure(name, args, machine):
    """Points/s of ``sweep.integrate(tol=...)`` on the draw of figure ``name``
    (``<law>_tol<tol>``), and its max error against DOP853."""
    law, tol = name.split("_tol")[0], float(name.split("_tol")[1])
    a, b, g, G = draw(args.n, law)
    t0 = time.perf_counter()
    sweep.integrate(a[:256], b[:256], g[:256], G[:256], tol=tol)
    compile_s = time.perf_counter() - t0
    best, r = _best(lambda: sweep.integrate(a, b, g, G, tol=tol), args.repeat)
    idx = np.random.default_rng(1).choice(args.n, size=min(args.check, args.n), replace=False)
    ref = reference_e(np.column_stack([a[idx], b[idx], g[idx], G[idx]]), args.cache_dir)
    err = np.abs(np.asarray(r.e)[idx] - ref)
    decided = np.isfinite(err)
    max_err = float(err[decided].max()) if decided.any() else float("nan")
    return line(name, args.n / best, machine, args.n, sweep_threads(),
                tol=tol, seconds=best, compile_s=compile_s, max_abs_error=max_err,
                median_abs_error=float(np.median(err[decided])) if decided.any() else None,
                error_points=int(decided.sum()), error_undecided=int((~decided).sum()),
                error_target=tol, error_ok=bool(max_err <= tol),
                mean_steps=float(np.mean(r.n_steps)))


def sweep_threads():
    import numba

    return numba.get_num_threads()


def _sobol_run(n, threads, workdir, env_extra=None):
    """``sweep run`` of sobol_1m.toml cut to ``n`` points, in a subprocess; returns
    (points / run_time_s, process wall time, the file's attributes)."""
    text = (ROOT / "configs" / "sobol_1m.toml").read_text()
    cfg = Path(workdir) / f"sobol_{n}.toml"
    cfg.write_text(text.replace("n = 1_000_000", f"n = {n}"))
    out = Path(workdir) / f"sobol_{n}_{threads}.nc"
    env = {**os.environ, "NUMBA_NUM_THREADS": str(threads), **(env_extra or {})}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "sweep.cli", "run", str(cfg), "-o", str(out),
                    "--quiet", "--restart"], check=True, env=env, cwd=ROOT,
                   stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    import netCDF4

    with netCDF4.Dataset(out) as ds:
        attrs = {k: ds.getncattr(k) for k in ("run_time_s", "kernel_time_s",
                                              "compile_time_s", "points_per_second")
                 if k in ds.ncattrs()}
    out.unlink()
    return n / float(attrs["run_time_s"]), wall, attrs


def sobol_figures(args, machine):
    """End-to-end points/s of the Sobol run on all numba threads, and 2 threads over 1.

    ``--repeat`` rounds, each a run on every thread count in turn: the end-to-end figure is
    the best round's, the ratio the (lower) median of the rounds' paired ratios (each
    round's runs minutes apart at most, so a drift of the shared machine's speed shows in
    the spread of the ratios, not in their median), every round's ratio beside it."""
    everyone = sweep_threads()
    counts = sorted({everyone, 2, 1}, reverse=True)
    rounds = []
    with tempfile.TemporaryDirectory(prefix="sweep-run-all-") as tmp:
        _sobol_run(min(args.sobol_n, 4096), everyone, tmp)          # warm the cache
        for _ in range(max(1, args.repeat)):
            rounds.append({t: _sobol_run(args.sobol_n, t, tmp) for t in counts})
    rate, wall, attrs = max((r[everyone] for r in rounds), key=lambda run: run[0])
    e2e = line("sobol_1m_end_to_end", rate, machine, args.sobol_n, everyone,
               process_wall_s=wall, rounds=len(rounds),
               **{k: float(v) for k, v in attrs.items()})
    return [e2e, _two_over_one(rounds, machine, args.sobol_n)]


def _two_over_one(rounds, machine, n):
    """The ``sobol_1m_threads_2v1`` line of the rounds of :func:`sobol_figures`."""
    def kernels(run):
        return float(run[2]["kernel_time_s"])
    ratios = [r[2][0] / r[1][0] for r in rounds]
    mid = int(np.argsort(ratios)[(len(ratios) - 1) // 2])     # the median round (lower)
    m = rounds[mid]
    return line("sobol_1m_threads_2v1", ratios[mid], machine, n, 2,
                ratios=[round(x, 4) for x in ratios],
                kernels_2v1_each=[round(kernels(r[1]) / kernels(r[2]), 4) for r in rounds],
                points_per_second_1=m[1][0], points_per_second_2=m[2][0],
                kernel_time_s_1=kernels(m[1]), kernel_time_s_2=kernels(m[2]),
                kernels_2v1=kernels(m[1]) / kernels(m[2]))


#: Run in a fresh process: the first call of every public method, serial then parallel,
#: then the integrator for every law and a general pair (exponent specialisations).
FIRST_CALLS = """
import json, sys, time
import numpy as np
t0 = time.perf_counter()
import sweep
out = {"import": time.perf_counter() - t0}
g, G = np.full(4096, 0.01), np.full(4096, 0.1)
def first(label, fn):
    t = time.perf_counter(); fn(); out[label] = time.perf_counter() - t
for m in sweep.METHODS:
    first(m + " scalar", lambda: sweep.cor(1.5, 1.5, 0.01, 0.1, method=m))
    first(m + " array", lambda: sweep.cor(1.5, 1.5, g, G, method=m))
for law, (a, b) in list(sweep.MODELS.items()) + [("general", (2.2, 1.7))]:
    first("integrate " + law, lambda: sweep.integrate(a, b, g, G, tol=1e-8))
print(json.dumps(out))
"""


def startup_figures(args, machine):
    """First-call compile time with an empty cache, then import + cor with it warm."""
    with tempfile.TemporaryDirectory(prefix="sweep-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        res = subprocess.run([sys.executable, "-c", FIRST_CALLS], env=env, cwd=ROOT,
                             check=True, capture_output=True, text=True)
        calls = json.loads(res.stdout.strip().splitlines()[-1])
        total = sum(v for k, v in calls.items() if k != "import")
        walls = []
        cmd = [sys.executable, "-c", "import sweep; sweep.cor(1.5, 1.5, 0.01, 0.1)"]
        for _ in range(max(3, args.repeat)):
            t0 = time.perf_counter()
            subprocess.run(cmd, env=env, cwd=ROOT, check=True)
            walls.append(time.perf_counter() - t0)
    fresh = line("startup_compile_fresh", total, machine, 1, sweep_threads(),
                 import_s=calls["import"], first_calls_s=calls)
    warm = line("startup_import_cor_warm", min(walls), machine, 1, sweep_threads(),
                median_s=statistics.median(walls), runs=len(walls))
    return [fresh, warm]


def _mean_over(fn, seconds):
    """Mean time of calls of ``fn`` repeated for at least ``seconds``: one short call can
    end before the scheduler gives the counting thread a turn (a rate of 0 on a busy
    machine, the --quick run's 1,000 points)."""
    t0, calls = time.perf_counter(), 0
    while calls == 0 or time.perf_counter() - t0 < seconds:
        fn()
        calls += 1
    return (time.perf_counter() - t0) / calls


def _counter(stop, box):
    n = 0
    while not stop.is_set():
        n += 1
        box[0] = n


def gil_figure(args, machine):
    """A Python thread's counting rate while a serial kernel runs, over its rate alone."""
    a, b, g, G = draw(args.gil_n, "kk")
    kernel = lambda: sweep.integrate(a, b, g, G, tol=1e-8, parallel=False)  # noqa: E731
    t0 = time.perf_counter()
    kernel()                                               # compile or load, and duration
    duration = max(time.perf_counter() - t0, 0.2)
    stop, box = threading.Event(), [0]
    thread = threading.Thread(target=_counter, args=(stop, box), daemon=True)
    thread.start()
    try:
        rates = {}
        for phase in ("alone", "during", "alone after"):
            c0, t0 = box[0], time.perf_counter()
            if phase == "during":
                duration = _mean_over(kernel, duration)
            else:
                time.sleep(duration)                       # the GIL is free meanwhile
            rates[phase] = (box[0] - c0) / (time.perf_counter() - t0)
    finally:
        stop.set()
        thread.join()
    alone = 0.5 * (rates["alone"] + rates["alone after"])
    return line("gil_release", rates["during"] / alone, machine, args.gil_n, 1,
                kernel_s=duration, counts_per_s_alone=alone,
                counts_per_s_during=rates["during"])


# --------------------------------------------------------------------------- main

def _selected(only):
    names = []
    for item in only or list(TARGETS):
        names += GROUPS.get(item, [item])
    unknown = [n for n in names if n not in TARGETS]
    if unknown:
        raise SystemExit(f"run_all.py: unknown figure(s) {unknown}; names: "
                         f"{list(TARGETS)}, groups: {list(GROUPS)}")
    return [n for n in TARGETS if n in names]


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1_000_000, help="points of each law's draw")
    p.add_argument("--check", type=int, default=1000, help="points checked against DOP853")
    p.add_argument("--repeat", type=int, default=3, help="timings are the best of this")
    p.add_argument("--sobol-n", type=int, default=1_000_000, help="points of the Sobol run")
    p.add_argument("--gil-n", type=int, default=20000, help="points of the GIL figure")
    p.add_argument("--only", nargs="+", metavar="NAME",
                   help=f"figures or groups ({', '.join(GROUPS)}) to run (default: all)")
    p.add_argument("--cache-dir", default=str(ROOT / "benchmarks" / ".cache"),
                   help="where the DOP853 reference values are kept")
    p.add_argument("--quick", action="store_true",
                   help=f"tiny sizes to exercise the machinery ({QUICK}); no figure "
                        "means anything then")
    args = p.parse_args(argv)
    if args.quick:
        for k, v in QUICK.items():
            setattr(args, k, v)
    return args


def main(argv=None):
    args = parse_args(argv)
    names = _selected(args.only)
    machine = _machine()
    jobs = [(n, lambda n=n: [law_figure(n, args, machine)])
            for n in names if n in GROUPS["laws"]]
    for group, fn in (("sobol", sobol_figures), ("startup", startup_figures),
                      ("gil", lambda a, m: [gil_figure(a, m)])):
        if any(n in GROUPS[group] for n in names):
            jobs.append((group, lambda fn=fn: fn(args, machine)))
    for _, job in jobs:
        for fig in job():
            if fig["name"] in names:
                fig["quick"] = args.quick         # tiny sizes: the values mean nothing
                print(json.dumps(fig), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
