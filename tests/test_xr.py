"""Labelled front ends and the ``ds.sweep`` accessor (sweep.xr).

The independent path is :func:`sweep.cor` / :func:`sweep.integrate` on plain numpy arrays
broadcast by hand; sweep.xr must give the same bits, lazily for dask inputs.
"""
import dataclasses
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import sweep
import sweep.xr as sx
from sweep.sweeps import config, runner

dask = pytest.importorskip("dask")
import dask.array as dsa  # noqa: E402

STEPS = 16  # resolution is irrelevant here; keep the integrations cheap
GAMMA = np.array([0.0, 1e-3, 0.02, 0.1, 0.5])
GTILDE = np.array([0.0, 0.05, 1.0, 10.0])
FIELDS = [f.name for f in dataclasses.fields(sweep.IntegrationResult)]


def gamma_da():
    return xr.DataArray(GAMMA, dims="gamma", coords={"gamma": GAMMA})


def gtilde_da():
    return xr.DataArray(GTILDE, dims="gtilde", coords={"gtilde": GTILDE})


def opts(method):
    return {"steps": STEPS} if method == "numeric" else {}


def same_bits(actual, expected):
    a, b = np.asarray(actual), np.asarray(expected)
    assert (a.shape, a.dtype) == (b.shape, b.dtype)
    assert a.tobytes() == b.tobytes()


class CountingScheduler:
    """A dask scheduler that counts how many times a graph is computed."""

    def __init__(self):
        self.computes = 0

    def __call__(self, dsk, keys, **kwargs):
        self.computes += 1
        return dask.threaded.get(dsk, keys, **kwargs)


# --------------------------------------------------------------------------- broadcasting

@pytest.mark.parametrize("method", ["numeric", "ord1", "ord2_approx"])
def test_dims_broadcast_by_name(method):
    # gamma (5) on "gamma" and g~ (4) on "gtilde": sweep.cor would say "shape mismatch"
    e = sx.cor(1.5, 1.5, gamma_da(), gtilde_da(), method=method, **opts(method))
    assert e.dims == ("gamma", "gtilde")
    same_bits(e.values, sweep.cor(1.5, 1.5, GAMMA[:, None], GTILDE, method, **opts(method)))
    same_bits(e.gamma, GAMMA)
    same_bits(e.gtilde, GTILDE)


def test_transposed_and_extra_dims_broadcast_by_name():
    ref = sweep.cor(1.5, 1.5, GAMMA[:, None], GTILDE, steps=STEPS)
    gamma_2d = gamma_da().broadcast_like(gtilde_da()).transpose("gtilde", "gamma")
    e = sx.cor(1.5, 1.5, gamma_2d, gtilde_da(), steps=STEPS)
    assert e.dims == ("gtilde", "gamma")             # xarray's order: first appearance
    same_bits(e.values, ref.T)
    beta = xr.DataArray([1.0, 2.5], dims="beta")
    e = sx.cor(1.5, beta, gtilde_da(), gamma_da(), method="ord1")  # g~ passed as gamma
    assert e.dims == ("beta", "gtilde", "gamma")
    same_bits(e.values, sweep.cor(1.5, np.array([1.0, 2.5])[:, None, None],
                                  GTILDE[:, None], GAMMA, "ord1"))


def test_mismatched_labels_are_refused():
    other = gamma_da().assign_coords(gamma=GAMMA + 1.0)
    with pytest.raises(ValueError):
        sx.cor(1.5, gamma_da(), other, 1.0, method="ord1")


# --------------------------------------------------------------------------- dask

@pytest.mark.parametrize("scheduler", ["threads", "synchronous"])
def test_dask_equals_eager_bit_identical(scheduler):
    gamma, gtilde = gamma_da().chunk(2), gtilde_da().chunk(3)
    with dask.config.set(scheduler=scheduler):
        for method in ("numeric", "ord2_approx"):
            lazy = sx.cor(1.5, 1.5, gamma, gtilde, method=method, **opts(method))
            eager = sx.cor(1.5, 1.5, gamma_da(), gtilde_da(), method=method, **opts(method))
            same_bits(lazy.compute().values, eager.values)
            assert lazy.attrs == eager.attrs
        lazy = sx.integrate(1.5, 2.5, gamma, gtilde, steps=STEPS).compute()
    eager = sweep.integrate(1.5, 2.5, GAMMA[:, None], GTILDE, steps=STEPS)
    for name in FIELDS:
        same_bits(lazy[name].values, getattr(eager, name))


# Blocks of more than 64 points reach the parallel kernel; the dask tasks launch it from worker
# threads (or fall back to the serial one where numba's threading layer is unsafe there).
WORKER_THREADS = """
import sys
import dask, numpy as np, xarray as xr
import sweep, sweep.xr as sx
gamma = xr.DataArray(np.linspace(0.0, 0.5, 300), dims="gamma").chunk(100)
gtilde = xr.DataArray([0.0, 1.0, 10.0], dims="gtilde")
with dask.config.set(scheduler="threads", num_workers=3):
    lazy = sx.cor(1.5, 2.5, gamma, gtilde, steps=16).compute()
eager = sweep.cor(1.5, 2.5, gamma.values[:, None], gtilde.values, steps=16)
assert lazy.values.tobytes() == eager.tobytes()
import numba; print(numba.threading_layer())
"""


@pytest.mark.parametrize("layer", ["default", "workqueue"])
def test_kernels_in_dask_worker_threads_give_the_eager_results(layer):
    env = {**os.environ, "NUMBA_THREADING_LAYER": layer, "NUMBA_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", WORKER_THREADS], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr


def test_dask_cluster_threads_give_the_eager_results():
    distributed = pytest.importorskip("distributed")
    eager = sx.cor(1.5, 1.5, gamma_da(), gtilde_da(), steps=STEPS)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster):
            lazy = sx.cor(1.5, 1.5, gamma_da().chunk(1), gtilde_da(), steps=STEPS)
            same_bits(lazy.compute().values, eager.values)


def test_stays_lazy_until_computed():
    counter = CountingScheduler()
    with dask.config.set(scheduler=counter):
        e = sx.cor(1.5, 1.5, gamma_da().chunk(2), gtilde_da(), steps=STEPS)
        ds = sx.integrate(1.5, 1.5, gamma_da().chunk(2), 1.0, steps=STEPS)
        assert counter.computes == 0
        assert isinstance(e.data, dsa.Array)
        assert all(isinstance(ds[n].data, dsa.Array) for n in FIELDS)
        e.compute()
        assert counter.computes == 1


def test_building_the_graph_computes_nothing():
    def boom():
        raise AssertionError("computed at call time")

    gamma = xr.DataArray(dsa.from_delayed(dask.delayed(boom)(), (3,), float), dims="gamma")
    e = sx.cor(1.5, 1.5, gamma, gtilde_da(), method="ord2_numint")
    sx.integrate(1.5, 1.5, gamma, gtilde_da())
    with pytest.raises(AssertionError, match="computed at call time"):
        e.compute(scheduler="synchronous")


def test_bad_options_raise_at_call_time_even_for_dask_inputs():
    gamma = gamma_da().chunk(2)
    with pytest.raises(ValueError, match="steps"):
        sx.cor(1.5, 1.5, gamma, 1.0, steps=1)
    with pytest.raises(ValueError, match="n must be"):
        sx.cor(1.5, 1.5, gamma, 1.0, method="ord2_approx", n=4)
    with pytest.raises(ValueError, match="method"):
        sx.cor(1.5, 1.5, gamma, 1.0, method="ord3")
    for method in ("numeric", "ord1"):   # sweep.cor's error (numeric's was integrate()'s)
        with pytest.raises(ValueError) as expected:
            sweep.cor(1.5, 1.5, GAMMA, 1.0, method=method, stepz=16)
        with pytest.raises(ValueError) as got:
            sx.cor(1.5, 1.5, gamma, 1.0, method=method, stepz=16)
        assert str(got.value) == str(expected.value)
        if method == "numeric":          # Python's TypeError, until 2026-12-07
            with pytest.raises(ValueError) as got:
                sx.integrate(1.5, 1.5, gamma, 1.0, stepz=16)
            assert str(got.value) == str(expected.value)
    with pytest.raises(TypeError, match="DataArray"):
        sx.cor(1.5, 1.5, GAMMA, 1.0)                 # bare arrays have no dimension names


# --------------------------------------------------------------------------- values, attrs

@pytest.mark.parametrize("method", ["numeric", "auto"])
@pytest.mark.parametrize("given", [{"tol": 1e-6}, {"tol": 1e-6, "steps": 40.0}, {}])
def test_recorded_settings_give_the_same_numbers_back(method, given):
    # The attributes said integrator_steps = 96 where tol had chosen the resolution, so
    # the recorded settings, passed back, gave other numbers (as sweep's files do:
    # "default" where tol chooses).
    e = sx.cor(1.5, 1.5, gamma_da(), 1.0, method=method, **given)
    m = sweep.registry.method(method)
    prefix = "integrator_" if m.integrates else "option_"
    recorded = {o.name: o.from_attr(e.attrs[prefix + o.name]) for o in m.options}
    from_tol = "steps" not in given and ("tol" in given or method == "auto")
    assert (recorded["steps"] is None) == from_tol
    again = sweep.cor(1.5, 1.5, GAMMA, 1.0, method=method, **recorded)
    assert np.array_equal(e.values, again)


def test_attributes():
    e = sx.cor(1.5, 1.5, gamma_da(), 1.0, steps=STEPS)
    assert e.name == "e_numeric"
    assert e.attrs["units"] == "1" and e.attrs["method"] == "numeric"
    assert "(3)" in e.attrs["equation"] and "eq. (3)" in e.attrs["description"]
    assert e.attrs["long_name"]
    assert e.attrs["integrator_steps"] == STEPS
    assert e.attrs["integrator_rest_tol"] == sweep.DEFAULT_REST_TOL
    assert e.attrs["integrator_max_steps"] == sweep.DEFAULT_MAX_STEPS
    a = sx.cor(1.5, 1.5, gamma_da(), 1.0, method="ord2_approx", n=11)
    assert a.name == "e_ord2_approx" and a.attrs["option_n"] == 11
    assert "(43)" in a.attrs["equation"] and a.attrs["units"] == "1"
    for method in sweep.METHODS:                     # every method is described
        attrs = sx.cor(1.5, 1.5, 0.01, 1.0, method=method).attrs
        assert attrs["equation"].startswith("(") and "eq" in attrs["description"]

    ds = sx.integrate(1.5, 1.5, gamma_da(), 1.0, steps=STEPS, max_steps=1000)
    assert list(ds.data_vars) == FIELDS
    assert ds.attrs["method"] == "numeric" and ds.attrs["integrator_max_steps"] == 1000
    assert ds.e.attrs["units"] == "1" and ds.t_f.attrs["long_name"]
    assert list(ds.status.attrs["flag_values"]) == [s.value for s in sweep.Status]
    ref = sweep.integrate(1.5, 1.5, GAMMA, 1.0, steps=STEPS, max_steps=1000)
    for name in FIELDS:
        same_bits(ds[name].values, getattr(ref, name))


def test_integrate_result_writes_to_netcdf(tmp_path):
    # Flag attributes of the boolean sticks are bytes: netCDF has no boolean attribute.
    ds = sx.integrate(1.5, 1.5, gamma_da(), 1.0, steps=STEPS)
    assert ds.sticks.attrs["flag_meanings"] == "rebounds sticks"
    ds.to_netcdf(tmp_path / "i.nc")
    with xr.open_dataset(tmp_path / "i.nc") as back:
        assert back.sticks.dtype == bool and back.n_steps.dtype == np.int32
        xr.testing.assert_identical(back.load(), ds)


def test_scalars():
    e = sx.cor(1.5, 1.5, 0.05, 1.0, steps=STEPS)
    assert e.dims == () and float(e) == sweep.cor(1.5, 1.5, 0.05, 1.0, steps=STEPS)
    assert float(sx.cor(1.5, 1.5, 0.05, 1.0, method="sp")) == sweep.cor(1.5, 1.5, 0.05, 1.0,
                                                                        "sp")
    ds = sx.integrate(1.5, 1.5, 0.05, 1.0, steps=STEPS)
    assert int(ds.status) == sweep.Status.OK and ds.n_steps.dtype == np.int32
    with pytest.raises(ValueError, match="gamma"):  # a scalar call raises, as sweep.cor does
        sx.cor(1.5, 1.5, -0.1, 1.0).values


@pytest.mark.parametrize("bad", ["0.1", True, None, 0.1 + 0j])
def test_scalars_that_are_not_real_numbers_are_refused_like_sweep_cor(bad):
    # They were converted: "0.1" parsed, True taken as 1, None as NaN ("must be finite").
    with pytest.raises(ValueError) as expected:
        sweep.cor(1.5, 1.5, bad, 1.0)
    for f in (sx.cor, sx.integrate):
        with pytest.raises(ValueError) as got:
            f(1.5, 1.5, bad, 1.0)
        assert str(got.value) == str(expected.value)


@pytest.mark.parametrize("values", [np.array(["0.1"]), np.array([True]),
                                    np.array(["2020-01-01"], dtype="M8[ns]")])
def test_arrays_that_are_not_real_numbers_are_refused_at_call_time_even_for_dask(values):
    # A dask-backed one gave a lazy result that failed (or not) only when computed.
    gamma = xr.DataArray(values, dims="p")
    with pytest.raises(ValueError):
        sweep.cor(1.5, 1.5, values, 1.0)
    for g in (gamma, gamma.chunk()):
        with pytest.raises(ValueError, match=f"gamma .*dtype {re.escape(str(values.dtype))}"):
            sx.cor(1.5, 1.5, g, 1.0)


def test_a_dataset_as_a_parameter_is_refused_naming_it():
    ds = xr.Dataset({"gamma": ("p", GAMMA), "other": ("q", [1.0])})
    with pytest.raises(TypeError, match=r"gamma .*Dataset.*ds\['gamma'\]"):
        sx.cor(1.5, 1.5, ds, 1.0)


def test_invalid_values_give_nan_and_invalid_in_arrays():
    gamma = xr.DataArray([0.05, -1.0, np.nan, np.inf], dims="p")
    alpha = xr.DataArray([1.5, 1.5, 1.5, 0.5], dims="p")
    for method in ("numeric", "ord1", "ord2_numint"):
        e = sx.cor(alpha, 1.5, gamma.chunk(2), 1.0, method=method, **opts(method)).compute()
        same_bits(e.values, sweep.cor(alpha.values, 1.5, gamma.values, 1.0, method,
                                      **opts(method)))
        assert np.isfinite(e[0]) and np.isnan(e[1:]).all()
    ds = sx.integrate(alpha, 1.5, gamma, 1.0, steps=STEPS)
    assert (ds.status[1:] == sweep.Status.INVALID).all()


# --------------------------------------------------------------------------- accessor

GRID = """
[design]
kind = "grid"
alpha = 1.5
beta = [1.0, 1.5]
gamma = {start = 0.0, stop = 0.2, num = 9}
gtilde = [0.0, 0.05, 1.0, 10.0]
[outputs]
e = ["numeric", "ord1", "ord2_approx"]
fields = ["error_ord1"]
[integrator]
steps = 16
"""

DOE = """
[design]
kind = "doe"
sampler = "sobol"
n = 64
seed = 3
alpha = {min = 1.0, max = 3.0}
beta = {min = 1.0, max = 3.0}
gamma = {min = 1e-3, max = 0.5, scale = "log"}
gtilde = {min = 0.0, max = 10.0}
[outputs]
e = ["numeric", "ord1"]
fields = ["error_ord1"]
[integrator]
steps = 16
"""


def made_by_sweep_run(text, path):
    runner.run(config.loads(text, source="test.toml"), path, quiet=True)
    return path


@pytest.mark.parametrize("text", [GRID, DOE], ids=["grid", "doe"])
def test_accessor_on_a_sweep_run_dataset(text, tmp_path):
    path = made_by_sweep_run(text, tmp_path / "s.nc")
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    # Computed (the file does not hold e_ord1 here): what the runner stored, bit for bit.
    err = ds.drop_vars("e_ord1").sweep.error("ord1")
    assert err.name == "error_ord1" and err.dims == ds.error_ord1.dims
    same_bits(err.values, ds.error_ord1.values)
    same_bits(ds.sweep.error("ord1").values, ds.error_ord1.values)   # from the stored e_ord1
    assert err.attrs["units"] == "1" and err.attrs["reference"] == "e_numeric"
    assert err.attrs["long_name"] == ds.error_ord1.attrs["long_name"]   # as the file says
    if "e_ord2_approx" in ds:
        same_bits(ds.sweep.cor("ord2_approx").values, ds.e_ord2_approx.values)
    counter = CountingScheduler()
    with xr.open_dataset(path, chunks={}) as lazy_ds:
        lazy_ds = lazy_ds.chunk({ds.error_ord1.dims[-1]: 3})  # several chunks
        with dask.config.set(scheduler=counter):
            for held in (lazy_ds.drop_vars("e_ord1"), lazy_ds):   # computed, and stored
                lazy = held.sweep.error("ord1")
                e = held.sweep.cor("ord1")           # lazy itself, chunked like the dataset
                assert counter.computes == 0 and isinstance(lazy.data, dsa.Array)
                assert isinstance(e.data, dsa.Array) and e.chunks == lazy_ds.error_ord1.chunks
                same_bits(lazy.compute().values, ds.error_ord1.values)
                counter.computes = 0


def test_accessor_recomputes_with_the_settings_the_file_records(tmp_path):
    # With the package's defaults instead (96 steps, target 1e-9; n = 21) the accessor's
    # e_numeric of a tol = 1e-8 file was off by 2e-9 from the file's own, and
    # error("numeric") was not 0.
    text = GRID.replace("steps = 16", "tol = 1e-8") + "[options.ord2_approx]\nn = 11\n"
    path = made_by_sweep_run(text, tmp_path / "s.nc")
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    assert ds.attrs["integrator_tol"] == 1e-8 and ds.attrs["options_ord2_approx_n"] == 11
    computed = ds.drop_vars(["e_numeric", "e_ord2_approx"]).sweep   # not held: computed
    same_bits(computed.cor("numeric").values, ds.e_numeric.values)
    same_bits(computed.cor("ord2_approx").values, ds.e_ord2_approx.values)
    assert not np.array_equal(ds.sweep.cor("ord2_approx", n=5).values, ds.e_ord2_approx.values)
    a, b, g, gt = xr.broadcast(*(ds[k] for k in ("alpha", "beta", "gamma", "gtilde")))
    same_bits(ds.e_numeric.transpose(*a.dims).values,
              sweep.cor(a.values, b.values, g.values, gt.values, tol=1e-8))
    # The resolution is one setting: a file's steps = 16 does not overrule a tol given.
    with xr.open_dataset(made_by_sweep_run(GRID, tmp_path / "g.nc")) as grid:
        grid = grid.load()
    same_bits(grid.sweep.cor("numeric", tol=1e-6).transpose(*a.dims).values,
              sweep.cor(a.values, b.values, g.values, gt.values, tol=1e-6))


def test_accessor_on_runs_of_other_settings_combined_gives_each_runs_numbers(tmp_path):
    # xarray keeps the first file's attributes (open_mfdataset's default): computing with
    # them gave the second run's points the first run's n, up to 2.8e-2 off (audit X).
    low = GRID.replace("stop = 0.2, num = 9", "stop = 0.2, num = 5")
    high = GRID.replace("start = 0.0, stop = 0.2, num = 9", "start = 0.3, stop = 0.5, num = 3")
    high += "[options.ord2_approx]\nn = 5\n"
    parts = []
    for name, text in (("low", low), ("high", high)):
        with xr.open_dataset(made_by_sweep_run(text, tmp_path / f"{name}.nc")) as part:
            parts.append(part.load())
    both = xr.combine_by_coords(parts, combine_attrs="override")
    assert "options_ord2_approx_n" not in both.attrs or both.attrs["options_ord2_approx_n"] != 5
    high_part = both.sel(gamma=parts[1].gamma)
    same_bits(both.sweep.cor("ord2_approx").sel(gamma=parts[1].gamma).values,
              parts[1].e_ord2_approx.values)
    same_bits(both.sweep.error("ord2_approx").sel(gamma=parts[1].gamma).values,
              (parts[1].e_ord2_approx - parts[1].e_numeric).values)
    # Settings given are computed with: the second run's n = 5 gives its numbers back.
    same_bits(high_part.sweep.cor("ord2_approx", n=5).values, parts[1].e_ord2_approx.values)
    assert not np.array_equal(high_part.drop_vars("e_ord2_approx").sweep.cor("ord2_approx")
                              .values, parts[1].e_ord2_approx.values)


def test_accessor_steps_given_keeps_the_files_tol(tmp_path):
    # auto's tol is its selection tolerance: a steps given used to drop the file's
    # tol = 1e-3 for the default 1e-6, so even the file's own steps gave other numbers.
    text = DOE.replace('e = ["numeric", "ord1"]', 'e = ["numeric", "ord1", "auto"]') + \
        "[options.auto]\ntol = 1e-3\n"
    with xr.open_dataset(made_by_sweep_run(text, tmp_path / "s.nc")) as ds:
        ds = ds.load()
    p = [ds[k].values for k in ("alpha", "beta", "gamma", "gtilde")]
    for steps in (16.0, 40.0):
        same_bits(ds.sweep.cor("auto", steps=steps).values,
                  sweep.cor(*p, method="auto", tol=1e-3, steps=steps))
    same_bits(ds.sweep.cor("auto", steps=16.0).values, ds.e_auto.values)


@pytest.mark.filterwarnings("ignore:The specified chunks separate the stored chunks")
def test_accessor_on_variables_chunked_differently(tmp_path):
    # chunks="auto" sizes chunks by dtype (int8 status: 8 times float64 e's), and the
    # accessor failed: "Object has inconsistent chunks along dimension point".
    text = DOE.replace('fields = ["error_ord1"]', 'fields = ["status", "error_ord1"]')
    path = made_by_sweep_run(text, tmp_path / "s.nc")
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    counter = CountingScheduler()
    with dask.config.set({"array.chunk-size": "128B", "scheduler": counter}), \
            xr.open_dataset(path, chunks="auto") as lazy_ds:
        assert lazy_ds.status.chunks != lazy_ds.e_ord1.chunks
        err = lazy_ds.sweep.error("ord1")
        assert counter.computes == 0 and isinstance(err.data, dsa.Array)
        assert len(err.chunks[0]) > 1
        same_bits(err.compute().values, ds.error_ord1.values)


def test_accessor_on_a_hand_built_dataset():
    ds = xr.Dataset(coords={"alpha": [1.5], "beta": [1.5], "gamma": GAMMA, "gtilde": GTILDE})
    e = ds.sweep.cor("ord2_numint")
    assert e.dims == ("alpha", "beta", "gamma", "gtilde")
    same_bits(e.values[0, 0], sweep.cor(1.5, 1.5, GAMMA[:, None], GTILDE, "ord2_numint"))
    with pytest.raises(KeyError, match="e_numeric"):
        ds.sweep.error("ord1")
    with pytest.raises(KeyError, match="not a sweep dataset"):
        xr.Dataset(coords={"gamma": GAMMA}).sweep.cor("ord1")


def test_import_sweep_leaves_sweep_xr_and_the_accessor_out():
    code = ("import sys, sweep, xarray\n"
            "assert 'sweep.xr' not in sys.modules and not hasattr(xarray.Dataset, 'sweep')\n"
            "import sweep.xr\n"
            "assert hasattr(xarray.Dataset, 'sweep')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr


def test_plain_api_refuses_labelled_arrays():
    # numpy rules would pair a gamma axis with a gtilde axis of the same length by position.
    g = xr.DataArray([0.1, 0.2], dims="gamma")
    gt = xr.DataArray([0.0, 1.0], dims="gtilde")
    with pytest.raises(TypeError, match="sweep.xr"):
        sweep.cor(1.5, 1.5, g, gt, method="ord1")
    assert sweep.cor(1.5, 1.5, xr.DataArray(0.1), 0.0, method="ord1") == sweep.cor(
        1.5, 1.5, 0.1, 0.0, method="ord1")
