"""Runge-Kutta stages of one point against two points interleaved and the array kernels' lanes.

    python benchmarks/lanes.py [--n 2000000] [--repeat 3]

The seven stages of a Dormand-Prince step form one chain of dependent operations (each
stage's power of u waits for the stage before), so a core running one point waits on
latency most of the time. This times the same stages (the package's ``rk_stage`` and
``rk_combine``, KK law) marched on one point, then on two independent points whose stages
alternate, then the array kernels' own stages of ``LANES`` points at once
(``sweep.kernels.stepper.rk_step_lanes``), and prints nanoseconds per step and point, one
core (the lanes' step also forms its local error estimates; where the lanes' laws allow,
as vectors of four lanes). It measures the stages alone: a march adds per step its
events, error sums and stopping rules, for each point (``benchmarks/step_cost.py`` times
the whole march). Compiled with the kernels' flags (``sweep.kernels._jit.FLAGS``), as the
kernels inline them.
"""
from __future__ import annotations

import argparse
import time

import numba as nb
import numpy as np

from sweep.kernels._jit import FLAGS
from sweep.kernels.contact import LAW_COLUMNS, make_law, put_law, rhs
from sweep.kernels.lanes import LANES
from sweep.kernels.stepper import (N_STAGES, SCRATCH, carry_in_scratch, rk_combine, rk_stage,
                                   rk_step_lanes, vector_groups)
from sweep.kernels.vmath import EVERY_ELEMENT, VECTOR

_H = 1e-9      # a tiny step keeps the state, and so the work per stage, the same throughout


@nb.njit(**FLAGS)
def _first_stage(K, u, w, c):
    fu, fw, fr = rhs(u, w, c)
    K[0, 0] = fu
    K[0, 1] = fw
    K[0, 2] = fr


@nb.njit(**FLAGS)
def one_lane(n, gamma, gtilde):
    c = make_law(1.5, 1.5, gamma, gtilde)
    K = np.empty((N_STAGES, 3))
    u, w, acc = 0.3, 0.2, 0.0
    _first_stage(K, u, w, c)
    for _ in range(n):
        for i in range(1, N_STAGES):
            rk_stage(i, u, w, _H, K, c)
        u, w, dr = rk_combine(u, w, _H, K)
        _first_stage(K, u, w, c)
        acc += dr
    return u + acc


@nb.njit(**FLAGS)
def two_lanes(n, gamma, gtilde):
    ca = make_law(1.5, 1.5, gamma, gtilde)
    cb = make_law(1.5, 1.5, 1.1 * gamma, gtilde)
    Ka = np.empty((N_STAGES, 3))
    Kb = np.empty((N_STAGES, 3))
    ua, wa, ub, wb, acc = 0.3, 0.2, 0.31, 0.2, 0.0
    _first_stage(Ka, ua, wa, ca)
    _first_stage(Kb, ub, wb, cb)
    for _ in range(n // 2):
        for i in range(1, N_STAGES):
            rk_stage(i, ua, wa, _H, Ka, ca)
            rk_stage(i, ub, wb, _H, Kb, cb)
        ua, wa, dra = rk_combine(ua, wa, _H, Ka)
        ub, wb, drb = rk_combine(ub, wb, _H, Kb)
        _first_stage(Ka, ua, wa, ca)
        _first_stage(Kb, ub, wb, cb)
        acc += dra + drb
    return ua + ub + acc


@nb.njit(**FLAGS)
def all_lanes(n, gamma, gtilde):
    K = np.empty((LANES, N_STAGES, 3))
    LF, LI = np.empty((LANES, LAW_COLUMNS[0])), np.empty((LANES, LAW_COLUMNS[1]), np.int64)
    u, w, h = np.full(LANES, 0.3), np.full(LANES, 0.2), np.full(LANES, _H)
    live, y = np.ones(LANES, np.bool_), np.empty((5, LANES))
    S = np.empty(SCRATCH * LANES)
    for l in range(LANES):
        c = make_law(1.5, 1.5, (1.0 + 0.1 * l) * gamma, gtilde)
        put_law(LF, LI, l, c)
        K[l, 0, 0], K[l, 0, 1], K[l, 0, 2] = rhs(u[l], w[l], c)
    vec = vector_groups(LF, LI, S)
    fresh = (1 << LANES) - 1      # the first stages are in K at the start
    acc = 0.0
    for _ in range(n // LANES):
        rk_step_lanes(u, w, h, K, LF, LI, live, y, S, vec, fresh)
        fresh = 0
        for first in range(0, LANES, VECTOR):
            if vec >> first & 1:
                # A vector group's stages stay in the scratch: carried there, as lanes does.
                carry_in_scratch(S, first, EVERY_ELEMENT)
            else:
                for l in range(first, first + VECTOR):
                    K[l, 0, 0], K[l, 0, 1], K[l, 0, 2] = K[l, 6, 0], K[l, 6, 1], K[l, 6, 2]
        for l in range(LANES):
            u[l], w[l] = y[0, l], y[1, l]
            acc += y[2, l]
    return acc


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=2_000_000, help="steps (of all points together)")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()
    one_lane(10, 0.01, 0.1)
    two_lanes(10, 0.01, 0.1)
    all_lanes(10 * LANES, 0.01, 0.1)
    for _ in range(args.repeat):
        t0 = time.process_time()
        one_lane(args.n, 0.01, 0.1)
        t1 = time.process_time()
        two_lanes(args.n, 0.01, 0.1)
        t2 = time.process_time()
        all_lanes(args.n, 0.01, 0.1)
        t3 = time.process_time()
        print(f"one lane {(t1 - t0) / args.n * 1e9:.1f} ns/step; two lanes "
              f"{(t2 - t1) / args.n * 1e9:.1f} ns/step per point; {LANES} lanes "
              f"(rk_step_lanes) {(t3 - t2) / args.n * 1e9:.1f} ns/step per point")


if __name__ == "__main__":
    main()
