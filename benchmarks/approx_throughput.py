"""Throughput of the report's closed-form approximations (issue 3: approximation kernels).

Evaluates 1,000,000 Kuwabara-Kono points (gamma = 10**U(-4, -0.5) drawn first, then
g~ = 10**U(-3, 1), ``numpy.random.default_rng(0)``) with every method of
:func:`sweep.kernels.approx.approx_cor` on all cores and prints points/s. The first call of each
method (compilation, or loading the kernel cache) is timed separately and excluded.

Targets on 2 cores: ord1, sp, large_gtilde >= 2e7 points/s; ord2_numint >= 2e5;
ord2_approx >= 3e5.

    python benchmarks/approx_throughput.py [--n 1000000] [--repeat 3] [--mixed]

``--mixed`` perturbs beta by a tiny amount per point, defeating the per-chunk reuse of
(alpha, beta) constants, to show the cost for heterogeneous exponents.
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numba
import numpy as np

from sweep.kernels import approx

TARGETS = {"ord1": 2e7, "sp": 2e7, "large_gtilde": 2e7, "ord2_numint": 2e5, "ord2_approx": 3e5}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1_000_000)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--mixed", action="store_true", help="distinct beta at every point")
    args = p.parse_args(argv)

    rng = np.random.default_rng(0)
    gamma = 10 ** rng.uniform(-4, -0.5, args.n)
    gtilde = 10 ** rng.uniform(-3, 1, args.n)
    alpha = np.full(args.n, 1.5)
    beta = np.full(args.n, 1.5)
    if args.mixed:
        beta = beta + 1e-9 * np.arange(args.n) / args.n

    t0 = time.perf_counter()
    approx.approx_cor("ord1", alpha[:8], beta[:8], gamma[:8], gtilde[:8])
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"numba {numba.__version__}, {numba.get_num_threads()} threads")
    print(f"first call, serial kernel (compile or cache load): {time.perf_counter() - t0:.2f} s")
    t0 = time.perf_counter()
    m = 4 * 1024
    approx.approx_cor("ord1", alpha[:m], beta[:m], gamma[:m], gtilde[:m])
    print(f"first call, parallel kernel (compile or cache load): "
          f"{time.perf_counter() - t0:.2f} s  (threading layer: {numba.threading_layer()})")
    print(f"points: {args.n:,}{' (mixed beta)' if args.mixed else ''}")
    for method in approx.CODES:
        best = np.inf
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            e, status = approx.approx_cor(method, alpha, beta, gamma, gtilde)
            best = min(best, time.perf_counter() - t0)
        rate = args.n / best
        ok = "ok" if rate >= TARGETS[method] else "BELOW TARGET"
        n_bad = int(np.count_nonzero(status))
        print(f"{method:>13}: {rate:14,.0f} points/s  (best of {args.repeat}: {best:.3f} s; "
              f"target {TARGETS[method]:,.0f}: {ok}; mean e {np.nanmean(e):.4f}, "
              f"invalid {n_bad})")


if __name__ == "__main__":
    main()
