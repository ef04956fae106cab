"""The multi-point march (sweep.kernels.lanes) against the one-point march, bit for bit.

The array kernels march points LANES at a time with their stages interleaved; each point's
operations must be exactly those of sweep.kernels.march.march, whatever the other lanes
hold, in what order the points come, and however many there are (idle lanes included).
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import sweep
from sweep.kernels._jit import jit
from sweep.kernels.integrator import DEFAULT_MAX_STEPS, DEFAULT_REST_TOL
from sweep.kernels.lanes import LANES, N_ENDING, march_lanes
from sweep.kernels.march import march_point, scratch

HARD = Path(__file__).parent / "data" / "hard_cases.csv"
E_TOL = 1e-10


def _points():
    rng = np.random.default_rng(3)
    n = 120
    laws = [(1.5, 1.5), (1.5, 1.0), (1.5, 2.5), (1.5, 1.25), (1.0, 1.0), (2.0, 3.0)]
    a = np.concatenate([np.full(n, x) for x, _ in laws] + [rng.uniform(1, 3, n)])
    b = np.concatenate([np.full(n, y) for _, y in laws] + [rng.uniform(1, 3, n)])
    g = 10 ** rng.uniform(-4, 1.5, a.size)
    gt = np.where(rng.random(a.size) < 0.2, 0.0, 10 ** rng.uniform(-3, 3, a.size))
    rows = list(csv.DictReader(HARD.open()))
    hard = np.array([[float(r[k]) for k in ("alpha", "beta", "gamma", "gtilde")] for r in rows])
    hard = hard[np.all(np.isfinite(hard), axis=1) & (hard[:, 2] > 0)]
    hard = hard[np.random.default_rng(4).permutation(len(hard))[:200]]
    pts = [np.concatenate([a, hard[:, 0]]), np.concatenate([b, hard[:, 1]]),
           np.concatenate([g, hard[:, 2]]), np.concatenate([gt, hard[:, 3]])]
    # Only points that are marched (not decided in closed form before any march).
    marched = sweep.integrate(*pts, refine=False).n_steps > 0
    return tuple(x[marched] for x in pts)


def _one_point(a, b, g, gt, steps, budget):
    e = march_point(a, b, g, gt, steps, DEFAULT_REST_TOL, budget, E_TOL)
    # Then u-bar = g~^(1/alpha), the C library's pow as Python's float power is.
    ubar = gt ** (1.0 / a) if gt > 0.0 else 0.0
    return np.array([e.kind, e.t, e.u, e.v, e.h, e.u_max, e.n, e.lw, e.lq, ubar])


@jit(entry=True)
def _march_lanes(alpha, beta, gamma, gtilde, todo, steps, budget, ends):
    # march_lanes is compiled for kernels only: Python reaches it through this caller.
    march_lanes(alpha, beta, gamma, gtilde, todo, steps, budget, DEFAULT_REST_TOL, E_TOL, ends)


def _lanes(alpha, beta, gamma, gtilde, todo, steps, budget):
    ends = np.empty((todo.size, N_ENDING))
    _march_lanes(alpha, beta, gamma, gtilde, todo, steps, budget, ends)
    return ends


def _same(x, y):
    return np.array_equal(x, y, equal_nan=True)


@pytest.mark.parametrize("steps", [17.0, 96.0])
def test_lanes_give_each_point_the_one_point_march_bit_for_bit(steps):
    alpha, beta, gamma, gtilde = _points()
    # Shuffled, so that every lane holds other neighbours than in the draw's order.
    todo = np.random.default_rng(5).permutation(alpha.size).astype(np.int64)
    budget = np.full(todo.size, DEFAULT_MAX_STEPS, np.int64)
    ends = _lanes(alpha, beta, gamma, gtilde, todo, np.full(todo.size, steps), budget)
    bad = [int(i) for j, i in enumerate(todo)
           if not _same(ends[j], _one_point(alpha[i], beta[i], gamma[i], gtilde[i], steps,
                                            DEFAULT_MAX_STEPS))]
    assert not bad, f"{len(bad)} points differ, e.g. {bad[:5]}"


def test_lanes_keep_each_march_its_own_resolution_and_budget():
    alpha, beta, gamma, gtilde = (x[:40] for x in _points())
    rng = np.random.default_rng(6)
    todo = np.arange(alpha.size, dtype=np.int64)
    steps = rng.uniform(10, 200, todo.size)
    # Small budgets too: a march out of budget ends as march() ends it (BUDGET), even a
    # fresh one (budget 0).
    budget = rng.choice([0, 5, 60, DEFAULT_MAX_STEPS], todo.size).astype(np.int64)
    ends = _lanes(alpha, beta, gamma, gtilde, todo, steps, budget)
    for j in range(todo.size):
        ref = _one_point(alpha[j], beta[j], gamma[j], gtilde[j], steps[j], int(budget[j]))
        assert _same(ends[j], ref), (j, ends[j], ref)


@pytest.mark.parametrize("n", [0, 1, LANES - 1, LANES + 1])
def test_fewer_points_than_lanes_and_remainders(n):
    alpha, beta, gamma, gtilde = (x[:n] for x in _points())
    todo = np.arange(n, dtype=np.int64)
    ends = _lanes(alpha, beta, gamma, gtilde, todo, np.full(n, 48.0),
                  np.full(n, DEFAULT_MAX_STEPS, np.int64))
    for j in range(n):
        assert _same(ends[j], _one_point(alpha[j], beta[j], gamma[j], gtilde[j], 48.0,
                                         DEFAULT_MAX_STEPS))


@pytest.mark.parametrize("kw", [{}, {"tol": 1e-8}, {"tol": 1e-10}, {"refine": False}])
def test_array_calls_give_what_the_one_point_solve_gives(kw):
    # The array kernel runs first marches and every pass of refinement in lanes; the
    # one-point solve (solve_point, as the CUDA kernel runs it) marches one point at a time.
    from sweep.kernels.integrator import settings, solve_point
    from sweep.kernels.stepper import N_DENSE, N_STAGES
    alpha, beta, gamma, gtilde = _points()
    r = sweep.integrate(alpha, beta, gamma, gtilde, **kw)
    s = settings(**kw)
    K, K2, Q = np.empty((N_STAGES, 3)), np.empty((N_STAGES, 3)), np.empty((2, N_DENSE))
    got = np.stack([r.e, r.t_f, r.u_max, r.n_steps, r.status, r.e_err])
    ref = np.array([solve_point(*p, s, K, K2, Q) for p in zip(alpha, beta, gamma, gtilde)]).T
    assert np.array_equal(got, ref, equal_nan=True)
    if kw.get("tol"):
        assert (r.n_steps > 200).any()    # some points were refined


def test_lanes_refuse_arrays_they_cannot_borrow():
    # The march writes the Endings through a view without ownership, which assumes C
    # order: a strided array is refused when compiled, never miswritten.
    import numba
    alpha, beta, gamma, gtilde = (x[:4] for x in _points())
    todo = np.arange(4, dtype=np.int64)
    budget = np.full(4, DEFAULT_MAX_STEPS, np.int64)
    ends = np.empty((4, 2 * N_ENDING))[:, ::2]
    with pytest.raises(numba.core.errors.TypingError, match="C-contiguous"):
        _march_lanes(alpha, beta, gamma, gtilde, todo, np.full(4, 48.0), budget, ends)


def test_bare_lanes_view_the_same_memory_with_the_same_shapes():
    # The called per-lane paths take the lanes as bare pointers and view them again
    # (lanes._bare, lanes._clothed): each view must be the array it came from, element for
    # element and shape for shape, writes included.
    import numba

    from sweep.kernels import lanes as L

    @numba.njit
    def round_trip(um, K2, Q, ends):
        own = L._lanes(um)
        own.LF.ravel()[:] = np.arange(own.LF.size) * 0.5
        own.CR.ravel()[:] = np.arange(own.CR.size) * 1.5
        own.SF.ravel()[:] = np.arange(own.SF.size) * 2.5
        own.y.ravel()[:] = np.arange(own.y.size) * 3.5
        own.K.ravel()[:] = np.arange(own.K.size) * 0.25
        own.u[:], own.w[:], own.h[:] = 1.0, 2.0, np.arange(own.h.size) * 0.75
        own.S[:] = np.arange(own.S.size) * 0.125
        own.LI.ravel()[:] = np.arange(own.LI.size)
        own.SI.ravel()[:] = -np.arange(own.SI.size)
        own.point[:] = np.arange(own.point.size)
        own.live[::2] = True
        ln, K2v, Qv, endsv = L._clothed(L._bare(own, K2, Q, ends))
        endsv[-1, -1] = 7.0         # written through the view
        same = (np.array_equal(ln.LF, own.LF) and np.array_equal(ln.LI, own.LI)
                and np.array_equal(ln.CR, own.CR) and np.array_equal(ln.SF, own.SF)
                and np.array_equal(ln.SI, own.SI) and np.array_equal(ln.u, own.u)
                and np.array_equal(ln.w, own.w) and np.array_equal(ln.h, own.h)
                and np.array_equal(ln.y, own.y) and np.array_equal(ln.K, own.K)
                and np.array_equal(ln.S, own.S) and np.array_equal(ln.um, um)
                and np.array_equal(ln.point, own.point) and np.array_equal(ln.live, own.live)
                and np.array_equal(K2v, K2) and np.array_equal(Qv, Q)
                and np.array_equal(endsv, ends))
        shapes = (ln.K.shape == own.K.shape and ln.LF.shape == own.LF.shape
                  and ln.SI.shape == own.SI.shape and ln.y.shape == own.y.shape
                  and ln.S.shape == own.S.shape and ln.um.shape == um.shape
                  and endsv.shape == ends.shape and K2v.shape == K2.shape
                  and Qv.shape == Q.shape and ln.K.strides == own.K.strides
                  and ln.SI.strides == own.SI.strides and endsv.strides == ends.strides
                  and ln.live.strides == own.live.strides)
        return same, shapes

    rng = np.random.default_rng(0)
    ends = rng.random((5, N_ENDING))
    _, K2, Q = scratch()      # the march's own scratch, as march_lanes makes it
    K2[:], Q[:] = rng.random(K2.shape), rng.random(Q.shape)
    same, shapes = round_trip(rng.random(5), K2, Q, ends)
    assert same and shapes
    assert ends[-1, -1] == 7.0 and ends[-1, 0] != 7.0
