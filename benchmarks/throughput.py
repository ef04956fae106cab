"""Throughput of the numerical CoR against its error (issue: core integrator benchmark).

Integrates 1,000,000 Kuwabara-Kono points (gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1),
``numpy.random.default_rng(0)``, gamma drawn first) on all cores and prints points/s
(compile time excluded and printed separately) beside the max abs error of e on a
1,000-point subset against scipy's DOP853 (rtol 1e-13, atol 1e-15, the slow reference of
the test suite).

    python benchmarks/throughput.py [--n 1000000] [--steps 64 | --tol 1e-8] [--no-refine] [--check 1000]
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numba
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

import sweep  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1_000_000)
    p.add_argument("--steps", type=float, default=None, help="resolution (default: package default)")
    p.add_argument("--check", type=int, default=1000, help="points checked against DOP853")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--tol", type=float, default=None,
                   help="accuracy knob instead of --steps (max abs error of e wanted)")
    p.add_argument("--no-refine", action="store_true",
                   help="one march per point (no e_err check and refinement)")
    args = p.parse_args(argv)

    rng = np.random.default_rng(0)
    gamma = 10 ** rng.uniform(-4, -0.5, args.n)
    gtilde = 10 ** rng.uniform(-3, 1, args.n)
    steps = args.steps or sweep.DEFAULT_STEPS

    opts = dict(tol=args.tol, steps=args.steps if args.tol else steps, refine=not args.no_refine)
    t0 = time.perf_counter()
    sweep.integrate(1.5, 1.5, gamma[:256], gtilde[:256], **opts)
    first = time.perf_counter() - t0

    best = np.inf
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        r = sweep.integrate(1.5, 1.5, gamma, gtilde, **opts)
        best = min(best, time.perf_counter() - t0)
    rate = args.n / best
    # A refined point took more steps than its single march at the starting resolution.
    single = sweep.integrate(1.5, 1.5, gamma, gtilde, **dict(opts, refine=False))
    refined = np.mean(r.n_steps != single.n_steps)

    from reference import dop853_cor  # noqa: PLC0415 -- the tests' slow reference

    idx = np.random.default_rng(1).choice(args.n, size=min(args.check, args.n), replace=False)
    t0 = time.perf_counter()
    ref = np.array([dop853_cor(1.5, 1.5, gamma[i], gtilde[i]).e for i in idx])
    t_ref = time.perf_counter() - t0
    err = np.abs(r.e[idx] - ref)

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"numba {numba.__version__} ({numba.threading_layer()}, {numba.get_num_threads()} threads)")
    print(f"first call (compile or cache load): {first:.2f} s")
    knob = f"tol: {args.tol:g}" if args.tol else f"steps: {steps:g}"
    print(f"points: {args.n:,}  {knob}  refine: {not args.no_refine}  "
          f"mean RK steps/point: {r.n_steps.mean():.1f} (single march: "
          f"{single.n_steps.mean():.1f}; refined: {100 * refined:.2f}% of points)")
    print(f"max e_err (the engine's own error estimate): {np.nanmax(r.e_err):.2e}")
    print("statuses: " + ", ".join(f"{sweep.Status(k).name}={c}" for k, c in
                                     enumerate(np.bincount(r.status, minlength=5)) if c))
    print(f"throughput: {rate:,.0f} points/s (best of {args.repeat}: {best:.2f} s)")
    if idx.size:     # --check 0: throughput only
        worst = idx[np.argmax(err)]
        print(f"max abs error vs DOP853 on {idx.size} points: {err.max():.2e} "
              f"(median {np.median(err):.1e}; worst at gamma={gamma[worst]:.4g}, "
              f"g~={gtilde[worst]:.4g}, e={r.e[worst]:.4g})")
        print(f"DOP853 reference: {idx.size / t_ref:,.0f} points/s on one core")


if __name__ == "__main__":
    main()
