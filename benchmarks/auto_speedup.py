"""Speed-up of ``method = "auto"`` against integrating every point of a typical scene.

Takes the points of a scene configuration (default ``configs/scene_steel_ball.toml``: the
report's steel ball, 200 impact speeds x 104 loads), times ``sweep.cor`` on all of them with
``method="numeric"`` and with ``method="auto"`` at several tolerances (best of ``--repeat``
calls, after a warm-up that compiles or loads the kernels), and prints the speed-up, the
share of points each method served, and the largest |e_auto - e_numeric| (which must stay
within tol; e_numeric at the default 96 steps).

    python benchmarks/auto_speedup.py [--config CONFIG] [--tols 1e-2 1e-3 1e-4 1e-6]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

import sweep
from sweep import registry
from sweep.sweeps import config, design


def _best(fn, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default="configs/scene_steel_ball.toml")
    p.add_argument("--tols", type=float, nargs="+", default=[1e-2, 1e-3, 1e-4, 1e-6])
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)

    d = design.build(config.load(args.config).design)
    pts = d.points(0, d.size)
    sweep.cor(*(x[:4096] for x in pts))                       # warm-up: kernels, error model
    for tol in args.tols:
        sweep.cor(*(x[:4096] for x in pts), method="auto", tol=tol)
    t_num, e_num = _best(lambda: sweep.cor(*pts), args.repeat)
    print(f"{args.config}: {d.size} points; machine: {os.cpu_count()} cores, shared with other "
          f"work (load average {os.getloadavg()[0]:.2f})")
    print(f"numeric (every point integrated, 96 steps): {t_num:.3f} s, "
          f"{d.size / t_num:,.0f} points/s")
    names = {code: name for name, code in registry.SERVED_BY.items()}
    for tol in args.tols:
        t, out = _best(lambda: sweep.cor_fields(*pts, method="auto", tol=tol), args.repeat)
        used = out["method_used"]
        share = ", ".join(f"{names[c]} {np.mean(used == c):.0%}" for c in np.unique(used))
        err = np.nanmax(np.abs(out["e"] - e_num))
        print(f"auto tol={tol:g}: {t:.3f} s, speed-up x{t_num / t:.1f}; served by {share}; "
              f"max |e_auto - e_numeric| = {err:.2g}")


if __name__ == "__main__":
    main()
