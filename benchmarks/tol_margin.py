"""How pessimistic is e_err at the first march? The figures behind ``TOL_MARGIN`` and
``KAPPA_STEPS``.

    python benchmarks/tol_margin.py [--n 40000] [--heavy]

For the KK, TTI, linear and general-exponent draws of ``benchmarks/run_all.py`` (``--heavy``:
the same laws, Hertz (1.5, 1) and SHC (1.5, 2.5) at gamma = 10**U(-0.5, 0.7), g~ =
10**U(-4, 1), where e is 0.01-0.5 and the bead loses most of its energy: the
calibration's draws stop at gamma = 0.32), marches
every point once (no refinement) and compares with the integrator at 500 steps and tol
1e-12 (within ~1e-13 of DOP853). Prints, per law:

* at tol 1e-6, 1e-8, 1e-10 (13, 33, 83 steps per half period, each point's first march at
  its share of them, ``sweep.kernels.stepsize.tol_share``): the fraction of points the
  refinement would take (e_err > tol / TOL_MARGIN), the quantiles of actual error over
  e_err, the largest actual error among the points left unrefined, over tol (must stay
  below 1), and the largest actual error after refinement, over tol;
* at the defaults (no ``tol``): the median and largest actual error over e_err;
* at fixed resolutions 16 to 192: the median and largest actual error over e_err, which
  should not fall with the resolution (``sweep.kernels.balance.KAPPA_STEPS``).
"""
import argparse

import numpy as np

import sweep
from sweep.kernels.integrator import TOL_MARGIN


def draws(n, rng, heavy=False):
    g = 10 ** (rng.uniform(-0.5, 0.7, n) if heavy else rng.uniform(-4, -0.5, n))
    gt = 10 ** (rng.uniform(-4, 1, n) if heavy else rng.uniform(-3, 1, n))
    yield "kk", np.full(n, 1.5), np.full(n, 1.5), g, gt
    yield "tti", np.full(n, 1.5), np.full(n, 1.25), g, gt
    if heavy:
        yield "hertz", np.full(n, 1.5), np.ones(n), g, gt
        yield "shc", np.full(n, 1.5), np.full(n, 2.5), g, gt
    yield "linear", np.ones(n), np.ones(n), g, gt
    yield "general", rng.uniform(1, 3, n), rng.uniform(1, 3, n), g, gt


def ratios(ref, r):
    """Actual error and actual error over e_err where both marches rebounded."""
    ok = (r.status == 0) & (ref.status == 0)
    err = np.abs(r.e - ref.e)[ok]
    return err, err / np.maximum(r.e_err[ok], 1e-300), r.e_err[ok]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=40000)
    p.add_argument("--heavy", action="store_true", help="heavily damped draws (docstring)")
    args = p.parse_args()
    for law, a, b, g, gt in draws(args.n, np.random.default_rng(0), args.heavy):
        ref = sweep.integrate(a, b, g, gt, steps=500, tol=1e-12)
        for tol in (1e-6, 1e-8, 1e-10):
            err, ratio, e_err = ratios(ref, sweep.integrate(a, b, g, gt, tol=tol, refine=False))
            kept = e_err <= tol / TOL_MARGIN
            q50, q99 = np.quantile(ratio, [0.5, 0.99])
            final, _, _ = ratios(ref, sweep.integrate(a, b, g, gt, tol=tol))
            left = err[kept].max() / tol if kept.any() else 0.0   # heavy draws: none left
            print(f"{law:8s} tol={tol:.0e}: refined {1 - kept.mean():.3f}, err/e_err median "
                  f"{q50:.3f} q99 {q99:.3f} max {ratio.max():.3f}; unrefined max err/tol "
                  f"{left:.2f}, final {final.max() / tol:.2f}")
        err, ratio, _ = ratios(ref, sweep.integrate(a, b, g, gt))
        print(f"{law:8s} defaults:  err/e_err median {np.median(ratio):.3f} max "
              f"{ratio.max():.3f}; max err {err.max():.1e}")
        for steps in (16, 48, 96, 192):
            _, ratio, _ = ratios(ref, sweep.integrate(a, b, g, gt, steps=steps, refine=False))
            print(f"{law:8s} steps={steps:3d}: err/e_err median {np.median(ratio):.3f} "
                  f"max {ratio.max():.3f}")


if __name__ == "__main__":
    main()
