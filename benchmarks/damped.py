"""Heavily damped points: points/s and max error, the damping cap and the creep rules at work.

    python benchmarks/damped.py [--n 100000] [--check 200] [--repeat 3] [--serial]

The core draw of ``benchmarks/run_all.py`` (``run_all.draw``) with the damping raised: gamma
= 10**U(0, 2), then g~ = 10**U(-3, 1) (``default_rng(0)``), for KK, SHC, TTI and general
exponents (alpha, beta ~ U[1, 3]). Here the damping rate ``gamma beta u^(beta-1)`` caps the
steps (``sweep.kernels.stepsize``), several times a step, and the creep rules run at every
step of the return (``sweep.kernels.march``). Prints one JSON line per law: points/s of
``sweep.integrate(..., tol=1e-8)`` on all cores (``--serial``: one), best of ``--repeat``,
the mean steps per point, and the max abs error against the tests' DOP853 reference on
``--check`` points of the same draw (cached as run_all.py caches it).
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

import sweep
from run_all import ROOT, draw, reference_e, sweep_threads

LAWS = ("kk", "shc", "tti", "general")     # names of run_all.LAWS
#: log10(gamma) of the draw: heavily damped.
LOG_GAMMA = (0.0, 2.0)
TOL = 1e-8


def figure(law: str, args) -> dict:
    """One law's line: speed, steps and error against DOP853."""
    a, b, g, G = draw(args.n, law, LOG_GAMMA)
    parallel = not args.serial
    sweep.integrate(a[:256], b[:256], g[:256], G[:256], tol=TOL, parallel=parallel)
    best, r = np.inf, None
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        r = sweep.integrate(a, b, g, G, tol=TOL, parallel=parallel)
        best = min(best, time.perf_counter() - t0)
    idx = np.random.default_rng(1).choice(args.n, size=min(args.check, args.n), replace=False)
    ref = reference_e(np.column_stack([a[idx], b[idx], g[idx], G[idx]]), args.cache_dir)
    err = np.abs(np.asarray(r.e)[idx] - ref)
    ok = np.isfinite(err)
    return {"name": f"damped_{law}", "points_per_second": args.n / best, "tol": TOL,
            "max_abs_error": float(err[ok].max()), "error_points": int(ok.sum()),
            "sticks": float(np.mean(r.e == 0.0)), "mean_steps": float(np.mean(r.n_steps)),
            "threads": 1 if args.serial else sweep_threads(), "n": args.n}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=100_000)
    p.add_argument("--check", type=int, default=200)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--serial", action="store_true", help="one thread (parallel=False)")
    p.add_argument("--cache-dir", default=str(ROOT / "benchmarks" / ".cache"))
    p.add_argument("--only", nargs="+", choices=LAWS, default=list(LAWS))
    args = p.parse_args()
    for law in args.only:
        print(json.dumps(figure(law, args)), flush=True)


if __name__ == "__main__":
    main()
