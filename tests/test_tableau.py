"""The Runge-Kutta pair is data: check it against the order conditions (Butcher trees)."""
import itertools

import numpy as np
import pytest

from sweep.kernels.tableau import DORMAND_PRINCE_54 as T


def _trees(order):
    """All rooted trees with ``order`` nodes, as sorted tuples of child subtrees."""
    if order == 1:
        return [()]
    out = set()
    # Children of the root: a multiset of trees whose sizes sum to order - 1.
    for sizes in _partitions(order - 1):
        pools = [_trees(s) for s in sizes]
        for combo in itertools.product(*pools):
            out.add(tuple(sorted(combo)))
    return sorted(out)


def _partitions(n, largest=None):
    largest = n if largest is None else largest
    if n == 0:
        yield ()
        return
    for k in range(min(n, largest), 0, -1):
        for rest in _partitions(n - k, k):
            yield (k,) + rest


def _size(t):
    return 1 + sum(_size(c) for c in t)


def _density(t):
    return _size(t) * np.prod([_density(c) for c in t]) if t else 1.0


def _phi(t):
    """Stage vector of the elementary weight of tree ``t``."""
    v = np.ones(len(T.C))
    for c in t:
        v = v * (T.A @ _phi(c))
    return v


ALL_TREES = [t for n in range(1, 7) for t in _trees(n)]


def test_tree_counts():
    # 1, 1, 2, 4, 9, 20 rooted trees of orders 1..6 (OEIS A000081).
    assert [len(_trees(n)) for n in range(1, 7)] == [1, 1, 2, 4, 9, 20]


def test_shape_and_consistency():
    s = len(T.C)
    assert T.A.shape == (s, s) and T.B.shape == (s,) and T.E.shape == (s,)
    assert np.all(np.triu(T.A) == 0), "explicit methods need a strictly lower-triangular A"
    np.testing.assert_allclose(T.A.sum(axis=1), T.C, atol=1e-15)
    if T.fsal:
        np.testing.assert_allclose(T.A[-1], T.B, atol=0)
        assert T.C[-1] == 1.0


@pytest.mark.parametrize("tree", [t for t in ALL_TREES if _size(t) <= 5], ids=str)
def test_propagated_solution_has_order_5(tree):
    assert T.B @ _phi(tree) == pytest.approx(1.0 / _density(tree), abs=2e-15)


def test_order_is_exactly_5():
    residuals = [abs(T.B @ _phi(t) - 1.0 / _density(t)) for t in _trees(6)]
    assert max(residuals) > 1e-6


def test_embedded_solution_has_order_4_not_5():
    b_hat = T.B - T.E
    for t in ALL_TREES:
        r = abs(b_hat @ _phi(t) - 1.0 / _density(t))
        if _size(t) <= 4:
            assert r < 2e-15, t
    assert max(abs(b_hat @ _phi(t) - 1.0 / _density(t)) for t in _trees(5)) > 1e-6


@pytest.mark.parametrize("theta", [0.0, 0.1, 0.37, 0.5, 0.81, 1.0])
def test_dense_output_has_order_4(theta):
    powers = theta ** np.arange(1, T.P.shape[1] + 1)
    b_theta = T.P @ powers
    for t in ALL_TREES:
        if _size(t) <= 4:
            want = theta ** _size(t) / _density(t)
            assert b_theta @ _phi(t) == pytest.approx(want, abs=3e-15), t


def test_dense_output_matches_step_end():
    np.testing.assert_allclose(T.P.sum(axis=1), T.B, atol=1e-15)


def test_tableau_is_read_only():
    with pytest.raises(ValueError):
        T.A[1, 0] = 0.0
