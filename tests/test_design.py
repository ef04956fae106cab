"""Designs: grid and design-of-experiments points, generated per chunk (sweep.sweeps.design)."""
import warnings

import numpy as np
import pytest
from scipy.stats import qmc

from sweep.sweeps import config, design

GRID = """
[design]
kind = "grid"
alpha = [1.0, 1.5, 2.0]
beta = 1.25
gamma = {start = 0.0, stop = 0.1, num = 7}
gtilde = {start = 0.01, stop = 10.0, num = 5, spacing = "log"}
[outputs]
e = ["ord1"]
"""


def doe(sampler, n=5000, seed=3, extra=""):
    seed_line = "" if "scramble = false" in extra else f"seed = {seed}"
    return config.loads(f"""
[design]
kind = "doe"
sampler = "{sampler}"
n = {n}
{seed_line}
alpha = {{min = 1.0, max = 3.0}}
beta = 1.5
gamma = {{min = 1e-4, max = 1.0, scale = "log"}}
gtilde = {{min = 0.0, max = 10.0}}
{extra}
[outputs]
e = ["ord1"]
""").design


def test_chunk_bounds_cover_the_design():
    assert design.chunk_bounds(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert design.chunk_bounds(8, 8) == [(0, 8)]
    assert design.chunk_bounds(3, 100) == [(0, 3)]
    with pytest.raises(ValueError):
        design.chunk_bounds(3, 0)


def test_grid_points_are_the_c_order_tensor_product():
    d = design.build(config.loads(GRID).design)
    assert d.dims == ("alpha", "beta", "gamma", "gtilde")
    assert d.shape == (3, 1, 7, 5) and d.size == 105
    mesh = np.meshgrid(*d.axes.values(), indexing="ij")
    full = d.points(0, d.size)
    for got, want in zip(full, mesh):
        assert got.dtype == np.float64 and got.flags.c_contiguous
        np.testing.assert_array_equal(got, want.reshape(-1))
    np.testing.assert_array_equal(d.axes["gtilde"], np.geomspace(0.01, 10.0, 5))
    # any chunking gives the same points
    parts = [d.points(s, e) for s, e in design.chunk_bounds(d.size, 11)]
    for k in range(4):
        np.testing.assert_array_equal(np.concatenate([p[k] for p in parts]), full[k])


@pytest.mark.parametrize("sampler", ["sobol", "lhs", "random"])
def test_doe_points_do_not_depend_on_chunking(sampler):
    spec = doe(sampler)
    full = design.build(spec).points(0, spec.n)
    for chunk in (1, 999, 1024, 4096):
        d = design.build(spec)
        parts = [d.points(s, e) for s, e in design.chunk_bounds(spec.n, chunk)]
        for k in range(4):
            np.testing.assert_array_equal(np.concatenate([p[k] for p in parts]), full[k])
    # out of order and repeated requests (resume, distributed) too
    d = design.build(spec)
    late, early, late2 = d.points(4000, 4100), d.points(10, 20), d.points(4000, 4100)
    np.testing.assert_array_equal(late[2], full[2][4000:4100])
    np.testing.assert_array_equal(early[0], full[0][10:20])
    np.testing.assert_array_equal(late2[3], full[3][4000:4100])


@pytest.mark.parametrize("sampler", ["sobol", "lhs", "random"])
def test_doe_bounds_scales_and_seed(sampler):
    spec = doe(sampler)
    d = design.build(spec)
    assert d.dims == ("point",) and d.shape == (spec.n,)
    a, b, g, gt = d.points(0, spec.n)
    assert a.min() >= 1.0 and a.max() <= 3.0
    assert np.all(b == 1.5)
    assert g.min() >= 1e-4 and g.max() <= 1.0
    assert gt.min() >= 0.0 and gt.max() <= 10.0
    # log-uniform: each decade gets a quarter of the points; uniform: each quarter of range
    decades = np.histogram(np.log10(g), bins=[-4, -3, -2, -1, 0])[0] / spec.n
    np.testing.assert_allclose(decades, 0.25, atol=0.03)
    quarters = np.histogram(gt, bins=[0, 2.5, 5, 7.5, 10])[0] / spec.n
    np.testing.assert_allclose(quarters, 0.25, atol=0.03)
    same = design.build(doe(sampler)).points(0, 100)
    other = design.build(doe(sampler, seed=4)).points(0, 100)
    np.testing.assert_array_equal(same[0], a[:100])
    assert not np.array_equal(other[0], a[:100])


def test_sobol_is_the_first_n_points_of_scipys_seeded_sequence_without_warning():
    spec = doe("sobol", n=1000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")     # n = 1000 is not a power of 2
        a, _, g, gt = design.build(spec).points(0, spec.n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        x = qmc.Sobol(3, rng=3).random(1000)
    np.testing.assert_array_equal(a, np.clip(1.0 + 2.0 * x[:, 0], 1.0, 3.0))
    np.testing.assert_allclose(g, 1e-4 * 1e4 ** x[:, 1], rtol=1e-13)
    np.testing.assert_array_equal(gt, np.clip(10.0 * x[:, 2], 0.0, 10.0))


def test_latin_hypercube_is_stratified():
    spec = doe("lhs", n=500)
    a, _, g, gt = design.build(spec).points(0, spec.n)
    for u in ((a - 1.0) / 2.0, np.log10(g / 1e-4) / 4.0, gt / 10.0):
        strata = np.floor(np.clip(u, 0, 1 - 1e-15) * spec.n).astype(int)
        assert np.array_equal(np.sort(strata), np.arange(spec.n))


def test_unscrambled_sobol_starts_at_the_origin():
    a, _, g, gt = design.build(doe("sobol", n=16, extra="scramble = false")).points(0, 16)
    assert (a[0], g[0], gt[0]) == (1.0, 1e-4, 0.0)


def test_points_outside_the_design_are_refused():
    d = design.build(doe("sobol", n=10))
    with pytest.raises(IndexError):
        d.points(5, 11)


def test_unknown_kind_has_no_builder():
    class Spec:
        kind = "lattice"

    with pytest.raises(ValueError, match="lattice"):
        design.build(Spec())


@pytest.mark.parametrize("lo, hi", [(1e-200, 1e200), (5e-324, 1.0)])
def test_a_log_axis_wider_than_a_double_is_still_log_uniform(lo, hi):
    # hi / lo overflowed to inf: every point came out at hi, and 0 x inf a NaN at x = 0.
    spec = config.loads(f"""
[design]
kind = "doe"
sampler = "sobol"
n = 1024
scramble = false
alpha = 1.5
beta = 1.5
gamma = {{min = {lo!r}, max = {hi!r}, scale = "log"}}
gtilde = 0.0
[outputs]
e = ["ord1"]
""").design
    g = design.build(spec).points(0, 1024)[2]
    x = qmc.Sobol(1, scramble=False).random(1024)[:, 0]     # gamma alone is sampled
    want = np.exp(np.log(lo) + x * (np.log(hi) - np.log(lo)))
    np.testing.assert_allclose(np.log(g), np.log(want), rtol=1e-12, atol=1e-12)
    assert np.all((g >= lo) & (g <= hi))


def test_a_sobol_design_says_when_its_size_is_not_a_power_of_two():
    assert "not a power of 2: balanced for its first 512)" in design.build(
        doe("sobol", n=1000)).describe()
    assert "power of 2" not in design.build(doe("sobol", n=1024)).describe()
    assert "power of 2" not in design.build(doe("random", n=1000)).describe()
    unscrambled = design.build(doe("sobol", n=16, extra="scramble = false")).describe()
    assert unscrambled.startswith("unscrambled sobol design of 16 points") and "seed" not in \
        unscrambled
