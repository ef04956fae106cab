"""Predicted sticks: how many are probed at the floor, how many probes fail, what it saves.

    python benchmarks/sticks.py [--n 20000] [--sobol-n 65536]

With a tolerance, a point predicted to dissipate twice its energy or more is first marched
at the integrator's floor of 16 steps, a probe of a stick (``sweep.kernels.stepsize.Q_STICK``,
``EPS_CALLABLE``); where the probe leaves e_err above tol the point is marched at its share
as without it. For the core draw of ``run_all.py`` (KK, general exponents), its heavily
damped variant (``damped.py``'s gamma = 10^U(0, 2); KK, SHC) and the first ``--sobol-n``
points of the design of ``configs/sobol_1m.toml``, at tol 1e-8 and 1e-10, prints per draw:
the fraction of points probed and of probes that failed, the steps of the whole solve
(refinement included) against the same solve without probes (a probed point's share is 1:
``steps=resolution(tol)`` marches it as it would be), the largest error of e over tol and
the stick/rebound decisions against the integrator at ``steps=500, tol=1e-12``, and the
largest relative error of u_max over the points that stick (read off the probe).
"""
from __future__ import annotations

import argparse

import numba
import numpy as np

import sweep
from run_all import ROOT, draw
from sweep import Status
from sweep.kernels.balance import COARSE_STEPS
from sweep.kernels.contact import make_law
from sweep.kernels.integrator import _first_steps, settings
from sweep.kernels.stepsize import q_constants, resolution
from sweep.sweeps import config, design

TOLS = (1e-8, 1e-10)


@numba.njit
def _probed(alpha, beta, gamma, gtilde, s):
    out = np.empty(alpha.size, np.bool_)
    for i in range(alpha.size):
        c = make_law(alpha[i], beta[i], gamma[i], gtilde[i])
        out[i] = _first_steps(c, s, q_constants(alpha[i], beta[i]))[1] > 0.0
    return out


def probed(alpha, beta, gamma, gtilde, tol):
    """Whether each point's first march with ``tol`` is a probe of a stick: the
    integrator's own rule (``integrator._first_steps``), a march to follow where it fails."""
    return _probed(alpha, beta, gamma, gtilde, settings(tol=tol))


def sobol(n):
    """The first n points of configs/sobol_1m.toml's design, as `sweep run` makes them."""
    cfg = config.load(ROOT / "configs" / "sobol_1m.toml")
    return design.build(cfg.design, cfg.source).points(0, n)


def line(name, pts, tol, ref):
    """One draw at one tol: probes, steps with and without them, errors."""
    r = sweep.integrate(*pts, tol=tol)
    flag = probed(*pts, tol)
    without = r.n_steps.astype(np.int64).sum()
    failed = np.zeros(0, bool)
    if flag.any():
        sub = [x[flag] for x in pts]
        without += (sweep.integrate(*sub, steps=resolution(tol), tol=tol).n_steps.sum()
                    - r.n_steps[flag].astype(np.int64).sum())
        # The probe alone: what the solve's first march at the floor gave.
        probe = sweep.integrate(*sub, steps=min(resolution(tol), COARSE_STEPS), tol=tol,
                                refine=False)
        failed = (probe.e_err > tol) & (probe.status != Status.BUDGET_EXHAUSTED)
    ok = (r.status == 0) & (ref.status == 0)
    sticks = (r.e == 0) & (ref.e == 0) & np.isfinite(ref.u_max)
    with np.errstate(invalid="ignore", divide="ignore"):
        du = np.abs(r.u_max[sticks] / ref.u_max[sticks] - 1)
    print(f"{name:14s} tol={tol:.0e}: probed {flag.mean():.3f}, not settled by the probe "
          f"{failed.mean() if failed.size else 0:.4f}; steps {r.n_steps.sum():,} against "
          f"{without:,} without probes ({r.n_steps.sum() / without - 1:+.1%}); max err/tol "
          f"{np.abs(r.e - ref.e)[ok].max() / tol:.3f}, decisions changed "
          f"{np.sum((r.status == 0) != (ref.status == 0))}, sticks' u_max rel err "
          f"{du.max() if du.size else 0:.1e}")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=20000)
    p.add_argument("--sobol-n", type=int, default=65536)
    args = p.parse_args()
    sets = [("kk", draw(args.n, "kk")), ("general", draw(args.n, "general")),
            ("kk damped", draw(args.n, "kk", (0.0, 2.0))),
            ("shc damped", draw(args.n, "shc", (0.0, 2.0))),
            ("sobol design", sobol(args.sobol_n))]
    for name, pts in sets:
        pts = [np.ascontiguousarray(x, dtype=float) for x in pts]
        ref = sweep.integrate(*pts, steps=500, tol=1e-12)
        for tol in TOLS:
            line(name, pts, tol, ref)


if __name__ == "__main__":
    main()
