"""Time of the integrator on the test suite's hard cases, one thread.

    python benchmarks/hard_cases.py [--repeat 3]

The 581 points of ``tests/data/hard_cases.csv`` (creep, grazing the stick/rebound boundary,
gamma up to 1e12, gamma = 0), through ``sweep.integrate(..., parallel=False)`` at the
default resolution and at ``tol=1e-8``: prints the best wall time of ``--repeat`` and the
Runge-Kutta steps, in all and per set of the file. Their accuracy is what
``tests/test_hard_cases.py`` checks.
"""
from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

import sweep

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "hard_cases.csv"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()
    rows = list(csv.DictReader(DATA.open()))
    points = np.array([[float(r[k]) for k in ("alpha", "beta", "gamma", "gtilde")]
                       for r in rows]).T
    sets = np.array([r["set"] for r in rows])
    sweep.integrate(*points[:, :8], parallel=False)                 # compile or load
    for kw in ({}, {"tol": 1e-8}):
        best, r = np.inf, None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            r = sweep.integrate(*points, parallel=False, **kw)
            best = min(best, time.perf_counter() - t0)
        per_set = {str(s): int(r.n_steps[sets == s].sum()) for s in np.unique(sets)}
        print(f"{kw or 'default'}: {best:.3f} s for {points.shape[1]} points, "
              f"{int(r.n_steps.sum())} steps {per_set}")


if __name__ == "__main__":
    main()
