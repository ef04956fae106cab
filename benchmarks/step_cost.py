"""Cost of one Runge-Kutta step of the march, and of a point beyond its steps (one core).

    python benchmarks/step_cost.py [--n 100000] [--law kk|hertz|shc|tti|linear] [--repeat 3]

Integrates the core benchmark's draw (gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1),
``numpy.random.default_rng(0)``) serially, one march per point (no refinement; the array
kernel marches 8 points at once, ``sweep/kernels/lanes.py``), at 48 and 192 steps per half
period, and fits time per point = intercept + slope * steps per point:
the slope is what one step of the march costs (stages, events, error sums and stopping
rules), the intercept what a point costs besides (its regimes, step policy, decision and
the call). Compare with ``benchmarks/lanes.py`` (the stages alone).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import sweep


def _per_point(a, b, gamma, gtilde, steps, repeat):
    """(best seconds per point, mean steps per point) of serial single marches."""
    kw = dict(steps=steps, refine=False, parallel=False)
    sweep.integrate(a, b, gamma[:64], gtilde[:64], **kw)          # compile or load
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = sweep.integrate(a, b, gamma, gtilde, **kw)
        best = min(best, time.perf_counter() - t0)
    return best / gamma.size, float(np.mean(r.n_steps))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=100_000)
    p.add_argument("--law", default="kk", choices=sorted(sweep.MODELS))
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    rng = np.random.default_rng(0)
    gamma = 10 ** rng.uniform(-4, -0.5, args.n)
    gtilde = 10 ** rng.uniform(-3, 1, args.n)
    a, b = sweep.MODELS[args.law]
    (t1, n1), (t2, n2) = (_per_point(a, b, gamma, gtilde, s, args.repeat) for s in (48, 192))
    slope = (t2 - t1) / (n2 - n1)
    print(f"{args.law}: {slope * 1e9:.1f} ns per step of the march, "
          f"{(t1 - slope * n1) * 1e9:.0f} ns per point besides "
          f"({n1:.1f} and {n2:.1f} steps per point at 48 and 192 steps per half period; "
          f"one core, best of {args.repeat})")


if __name__ == "__main__":
    main()
