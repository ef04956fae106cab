"""The CUDA backend against the CPU on the same machine (issue 14, item 4).

    python benchmarks/gpu.py                 # 1 and 16 million points, under 5 minutes
    python benchmarks/gpu.py --quick         # machinery only (tiny sizes; also simulated:
                                             # NUMBA_ENABLE_CUDASIM=1)

Prints one JSON line per figure: the draw (the core KK draw of ``benchmarks/run_all.py``,
or its general exponents in [1, 3]), the size, the knob (``tol`` or ``steps``), points/s
on the GPU (best of ``--repeat`` calls; compilation excluded: printed once as
``compile_s``), points/s of the CPU backend on every core of the same machine (on the
first ``--cpu-n`` points of the draw),
the max abs error of the GPU's e against DOP853 on 1,000 points of the draw (the test
suite's reference, cached in ``benchmarks/.cache``) and the largest difference between
the GPU's and the CPU's e on the CPU's points. Before them, one line per test set and
knob on how the two backends agree point by point (``"agreement"``): 4,000 random points of
every law (the CUDA tests' draw, larger) and the 581 hard cases of
``tests/data/hard_cases.csv``: the share of bit-identical e, of |e_gpu - e_cpu| <= 1e-12, of
equal statuses and step counts, the largest difference and the worst points with their
``e_err``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import csv

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import run_all  # noqa: E402 -- the draws and the cached DOP853 reference

import sweep  # noqa: E402
from sweep.kernels import cuda as kc  # noqa: E402

KNOBS = ({"tol": 1e-6}, {"tol": 1e-8}, {"tol": 1e-10}, {"steps": 32.0}, {"steps": 96.0})


def device_name() -> str:
    from numba import cuda  # noqa: PLC0415

    if os.environ.get("NUMBA_ENABLE_CUDASIM", "") not in ("", "0"):
        return "CUDA simulator"
    name = cuda.get_current_device().name
    return name.decode() if isinstance(name, bytes) else str(name)


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def figure(law, n, knob, args, machine):
    a, b, g, G = run_all.draw(n, law)
    gpu_s, gpu = min((timed(lambda: sweep.integrate(a, b, g, G, device="cuda", **knob))
                      for _ in range(args.repeat)), key=lambda x: x[0])
    m = min(args.cpu_n, n)
    cpu_s, cpu = timed(lambda: sweep.integrate(a[:m], b[:m], g[:m], G[:m], **knob))
    idx = np.random.default_rng(1).choice(n, size=min(args.check, n), replace=False)
    ref = run_all.reference_e(np.column_stack([a[idx], b[idx], g[idx], G[idx]]),
                              args.cache_dir)
    err = np.abs(np.asarray(gpu.e)[idx] - ref)
    diff = np.abs(np.asarray(gpu.e)[:m] - np.asarray(cpu.e))
    return {"law": law, "n": n, **knob, "gpu_points_per_s": round(n / gpu_s),
            "cpu_points_per_s": round(m / cpu_s), "cpu_n": m,
            "max_abs_error": float(np.nanmax(err)), "median_abs_error": float(np.nanmedian(err)),
            "max_gpu_cpu_diff": float(np.nanmax(diff)),
            "gpu_cpu_identical": float(np.mean(diff == 0)),
            "mean_steps": float(np.mean(gpu.n_steps)), **machine}


def test_sets(n_random, n_hard=None):
    """(name, alpha, beta, gamma, g~) of the agreement check: random points of every law
    (the draw of tests/test_cuda.py, ``n_random`` points) and the first ``n_hard`` hard
    cases (all by default)."""
    rng = np.random.default_rng(3)
    a = rng.choice([1.0, 1.5, 2.0, 2.5], n_random)
    b = rng.choice([1.0, 1.25, 1.5, 2.5], n_random)
    k = n_random // 4
    a[:k], b[:k] = rng.uniform(1, 4, k), rng.uniform(1, 4, k)
    g = 10 ** rng.uniform(-5, 1.5, n_random)
    gt = np.where(rng.random(n_random) < 0.2, 0.0, 10 ** rng.uniform(-3, 2.5, n_random))
    with open(HERE.parent / "tests" / "data" / "hard_cases.csv", newline="") as f:
        rows = list(csv.DictReader(f))[:n_hard]
    hard = [np.array([float(r[c]) for r in rows]) for c in ("alpha", "beta", "gamma", "gtilde")]
    return [("random", a, b, g, gt), ("hard_cases", *hard)]


def agreement(name, params, knob, machine):
    """How the GPU's fields agree with the CPU's on one test set, point by point."""
    cpu = sweep.integrate(*params, **knob)
    gpu = sweep.integrate(*params, device="cuda", **knob)
    ec, eg = np.asarray(cpu.e), np.asarray(gpu.e)
    errc, errg = np.asarray(cpu.e_err), np.asarray(gpu.e_err)
    diff = np.abs(eg - ec)
    same = _same(ec, eg)
    worst = np.argsort(np.where(same, -1.0, np.nan_to_num(diff, nan=np.inf)))[::-1][:5]
    return {"agreement": name, "n": int(ec.size), **knob,
            "e_identical": float(np.mean(same)),
            "within_1e-12": float(np.mean(same | (diff <= 1e-12))),
            "within_e_err": float(np.mean(same | (diff <= np.maximum(1e-12,
                                                                     np.maximum(errc, errg))))),
            "max_abs_diff": float(np.nanmax(np.where(same, 0.0, diff))),
            "status_equal": float(np.mean(np.asarray(cpu.status) == np.asarray(gpu.status))),
            "n_steps_equal": float(np.mean(np.asarray(cpu.n_steps) == np.asarray(gpu.n_steps))),
            "all_fields_identical": float(np.mean(np.logical_and.reduce(
                [same] + [_same(getattr(cpu, f), getattr(gpu, f))
                          for f in ("t_f", "u_max", "n_steps", "status", "e_err")]))),
            "worst": [[float(x[i]) for x in (*params, ec, eg, errc, errg)]
                      + [int(cpu.status[i]), int(gpu.status[i])]
                      for i in worst if not same[i]],
            **machine}


def _same(x, y):
    """Point by point: equal, or NaN on both devices."""
    x, y = np.asarray(x), np.asarray(y)
    return (x == y) | (np.isnan(x) & np.isnan(y)) if x.dtype.kind == "f" else x == y


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[1_000_000, 16_000_000])
    p.add_argument("--cpu-n", type=int, default=500_000,
                   help="points the CPU backend integrates for its rate and the comparison")
    p.add_argument("--check", type=int, default=1000, help="points checked against DOP853")
    p.add_argument("--repeat", type=int, default=2, help="GPU calls per figure (the best counts)")
    p.add_argument("--cache-dir", default=str(HERE / ".cache"))
    p.add_argument("--random", type=int, default=4000,
                   help="random points of every law in the agreement check")
    p.add_argument("--quick", action="store_true", help="tiny sizes: the machinery only")
    args = p.parse_args(argv)
    if args.quick:
        args.sizes, args.cpu_n, args.check, args.random = [512], 512, 20, 40
    why = kc.device_error()
    if why is not None:
        print(f"gpu.py: {why}", file=sys.stderr)
        return 1
    import numba  # noqa: PLC0415

    machine = {"device": device_name(), "cpu": platform.processor() or platform.machine(),
               "cores": os.cpu_count(), "cpu_threads": numba.get_num_threads()}
    compile_s, _ = timed(lambda: sweep.integrate(1.5, 1.5, np.full(256, 0.1), 0.1,
                                                 device="cuda"))
    print(json.dumps({"compile_s": round(compile_s, 2), **machine}), flush=True)
    for name, *params in test_sets(args.random, args.random if args.quick else None):
        for knob in ({}, {"tol": 1e-8}):
            print(json.dumps(agreement(name, params, knob, machine)), flush=True)
    for law in ("kk", "general"):
        for n in args.sizes if law == "kk" else args.sizes[:1]:
            for knob in KNOBS if law == "kk" else KNOBS[:3]:
                print(json.dumps(figure(law, n, knob, args, machine)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
