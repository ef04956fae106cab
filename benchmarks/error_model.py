"""The error model of the resolution: abs error of e against steps, one march per point.

    python benchmarks/error_model.py [--n 20000] [--steps 16 24 33.3 48 96]

For the core benchmark's draw (gamma = 10**U(-4, -0.5), g~ = 10**U(-3, 1), ``default_rng(0)``,
as ``benchmarks/run_all.py``) and each law class (KK, Hertz, SHC, TTI, linear, general
exponents alpha, beta ~ U[1, 3]), marches every point once (``refine=False``) at each
resolution and compares with the integrator at 400 steps and ``tol=1e-12`` (within ~1e-13
of the DOP853 reference, tests/test_hard_cases.py). Points that rebound in the reference
(status OK) are compared.

Prints one line per law and resolution: the largest error, its 99.9% quantile, the model's
value ``ERROR_AT_GRADE_STEPS (GRADE_STEPS / steps)^5`` (:mod:`sweep.kernels.stepsize`) and
the mean steps per point. The model is set on the 99.9% quantile: the largest errors sit at
the stick/rebound boundary (amplified about 1/e), where the error estimate exceeds ``tol``
and refinement takes over (``benchmarks/tol_margin.py``).
"""
from __future__ import annotations

import argparse

import numpy as np

import sweep
from sweep.kernels.stepsize import ERROR_AT_GRADE_STEPS, GRADE_STEPS

LAWS = {"kk": (1.5, 1.5), "hertz": (1.5, 1.0), "shc": (1.5, 2.5), "tti": (1.5, 1.25),
        "linear": (1.0, 1.0)}


def draws(n: int):
    """``(law, alpha, beta, gamma, gtilde)`` arrays for each law class."""
    rng = np.random.default_rng(0)
    g = 10 ** rng.uniform(-4, -0.5, n)
    gt = 10 ** rng.uniform(-3, 1, n)
    for law, (a, b) in LAWS.items():
        yield law, np.full(n, a), np.full(n, b), g, gt
    yield "general", rng.uniform(1, 3, n), rng.uniform(1, 3, n), g, gt


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=20000)
    p.add_argument("--steps", type=float, nargs="+", default=[16, 24, 33.3, 48, 96])
    args = p.parse_args()
    for law, a, b, g, gt in draws(args.n):
        ref = sweep.integrate(a, b, g, gt, steps=400, tol=1e-12)
        ok = ref.status == int(sweep.Status.OK)
        for steps in args.steps:
            r = sweep.integrate(a, b, g, gt, steps=steps, refine=False)
            err = np.abs(r.e - ref.e)[ok]
            model = ERROR_AT_GRADE_STEPS * (GRADE_STEPS / steps) ** 5
            print(f"{law:8s} steps={steps:6.1f}: max {err.max():.1e}  q99.9 "
                  f"{np.quantile(err, 0.999):.1e}  model {model:.1e}  "
                  f"steps/point {r.n_steps.mean():.0f}", flush=True)


if __name__ == "__main__":
    main()
