"""Work-precision benchmark: time per point against error, sweep against scipy.

The same measurement as ``sweep report speed`` (see :mod:`sweep.reports.speed`), with every
knob exposed: on one common point set, the engine at several accuracy targets ``tol`` (and
optionally at fixed resolutions), each of the report's approximations, and the peers
(scipy ``solve_ivp`` RK45, DOP853, LSODA, Radau with events, one point at a time; numbalsoda
and diffrax when installed) on a subset; the reference is the integrator at high resolution,
cross-checked with the test suite's DOP853 reference (tests/reference.py: grazing
refinement, energy identity) on a subset. The package itself never loads the tests: this
script hands that reference to ``speed_report`` as its ``crosscheck`` (``sweep report
speed`` uses a plain DOP853 instead).

    python benchmarks/work_precision.py [--out DIR] [--n 20000] [--n-peer 100]
        [--n-check 100] [--model kk] [--ref-steps 1024] [--tols 1e-4 ... 1e-11]
        [--steps 24 48 ...] [--peers scipy numbalsoda diffrax]

Writes DIR/work_precision.png, DIR/speed.md, DIR/speed.csv, DIR/speed_headline.csv and
prints the markdown tables.
"""
from __future__ import annotations

import argparse
import os
import sys

from sweep.reports.paper_values import PAPER_MODELS
from sweep.reports.speed import PEER_SETTINGS, TOLS, speed_report

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

#: Label of the cross-check in the tables and the plot.
TEST_REFERENCE = "tests/reference.py dop853_cor (DOP853 rtol 1e-13, atol 1e-15)"


def tests_reference_cor(alpha, beta, gamma, gtilde):
    """e from the test suite's slow DOP853 reference (needs mpmath, a test dependency)."""
    from reference import dop853_cor  # noqa: PLC0415 -- the tests' slow reference

    return dop853_cor(alpha, beta, gamma, gtilde).e


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="work_precision", help="output directory")
    p.add_argument("--n", type=int, default=20000, help="common point set size")
    p.add_argument("--n-peer", "--n-scipy", dest="n_peer", type=int, default=100,
                   help="points given to the peers")
    p.add_argument("--n-vector", type=int, default=2000,
                   help="points given to the vectorised peer (diffrax)")
    p.add_argument("--n-check", type=int, default=100,
                   help="points on which the reference is cross-checked with DOP853")
    p.add_argument("--model", choices=list(PAPER_MODELS), default="kk")
    p.add_argument("--ref-steps", type=float, default=1024)
    p.add_argument("--tols", type=float, nargs="+", default=list(TOLS))
    p.add_argument("--steps", type=float, nargs="+", default=[],
                   help="fixed resolutions timed as well (steps per half period)")
    p.add_argument("--peers", nargs="+", default=["scipy", "numbalsoda", "diffrax"])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    res = speed_report(args.out, n_points=args.n, tols=args.tols, steps_list=args.steps,
                       ref_steps=args.ref_steps, n_check=args.n_check, n_peer=args.n_peer,
                       n_vector=args.n_vector,
                       peer_settings=[p for p in PEER_SETTINGS if p[0] in args.peers],
                       model=args.model, seed=args.seed, repeat=args.repeat,
                       crosscheck=tests_reference_cor, crosscheck_name=TEST_REFERENCE,
                       progress=True)
    print(res["markdown"])
    for f in res["files"]:
        print(f)


if __name__ == "__main__":
    main()
