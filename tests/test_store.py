"""netCDF output, partial state for resuming, atomic commit (sweep.store)."""
import json
import zipfile
import zlib

import numpy as np
import pytest
import xarray as xr

from sweep import registry, store
from sweep.model import Status

VARIABLES = ("e_numeric", "e_ord1", "sticks", "t_f", "u_max", "n_steps", "status",
             "error_ord1")


def fake_results(n, rng):
    e = rng.random(n)
    e[::7] = np.nan                                   # invalid points keep their NaN
    return {
        "e_numeric": e,
        "e_ord1": rng.random(n),
        "sticks": (rng.random(n) < 0.3).astype(np.int8),
        "t_f": rng.random(n) * 5,
        "u_max": rng.random(n),
        "n_steps": rng.integers(0, 2 ** 31, n, dtype=np.int32),  # the whole int32 range
        "status": rng.integers(0, 5, n).astype(np.int8),
        "error_ord1": rng.standard_normal(n) * 1e-17,  # tiny values survive exactly
    }


@pytest.mark.parametrize("shape", [(5,), (3, 4), (2, 3, 4), (2, 1, 3, 5), (4, 1, 1, 1)])
def test_flat_blocks_cover_a_flat_range_exactly(shape):
    size = int(np.prod(shape))
    flat = np.arange(size).reshape(shape)
    for start in range(size):
        for stop in range(start, size + 1):
            seen = []
            for sl, lo, hi in store.flat_blocks(shape, start, stop):
                block = flat[sl].reshape(-1)
                assert list(block) == list(range(lo, hi))
                seen.extend(block)
            assert seen == list(range(start, stop))


def write_dataset(path, layout, data, chunks, points=None, attrs=None, compress="fast"):
    w = store.NetCDFWriter(path, layout, VARIABLES, attrs or {"Conventions": "CF-1.8"},
                           compress=compress)
    for s, e in chunks:
        pts = None if points is None else {k: v[s:e] for k, v in points.items()}
        w.write(s, e, {k: v[s:e] for k, v in data.items()}, pts)
    w.close()


def check_attrs(ds):
    for name in list(ds.data_vars) + list(ds.coords):
        attrs = ds[name].attrs
        if name == "point":
            continue
        assert attrs.get("units") == (None if "flag_values" in attrs else "1"), name
        assert attrs["long_name"], name
        assert "eq" in attrs["description"] or "Algorithm" in attrs["description"], name


def test_grid_dataset_round_trips_exactly(tmp_path):
    rng = np.random.default_rng(0)
    axes = {"alpha": np.array([1.5]), "beta": np.array([1.0, 2.5]),
            "gamma": np.linspace(0, 0.1, 7), "gtilde": np.array([0.0, 0.05, 1.0, 10.0])}
    layout = store.Layout(dims=tuple(axes), shape=(1, 2, 7, 4), axes=axes)
    data = fake_results(layout.size, rng)
    path = tmp_path / "grid.nc"
    # chunks written out of order and not aligned with rows
    write_dataset(path, layout, data, [(30, 56), (0, 13), (13, 30)])
    with xr.open_dataset(path) as ds:
        assert dict(ds.sizes) == {"alpha": 1, "beta": 2, "gamma": 7, "gtilde": 4}
        for name, values in axes.items():
            np.testing.assert_array_equal(ds[name].values, values)
        for name, values in data.items():
            assert ds[name].dims == layout.dims
            assert ds[name].dtype == values.dtype, name
            np.testing.assert_array_equal(ds[name].values.reshape(-1), values)
        assert ds.status.attrs["flag_meanings"].split() == [s.name.lower() for s in Status]
        np.testing.assert_array_equal(ds.status.attrs["flag_values"], [0, 1, 2, 3, 4])
        check_attrs(ds)
        assert ds.attrs["Conventions"] == "CF-1.8"
        assert ds.e_numeric.encoding["fletcher32"]
        ds.load().to_netcdf(tmp_path / "again.nc")
    with xr.open_dataset(path) as a, xr.open_dataset(tmp_path / "again.nc") as b:
        xr.testing.assert_identical(a, b)


def test_point_dataset_has_parameters_as_coordinates(tmp_path):
    rng = np.random.default_rng(1)
    n = 1000
    layout = store.Layout(dims=("point",), shape=(n,), axes={},
                          point_coords=("alpha", "beta", "gamma", "gtilde"))
    data = fake_results(n, rng)
    points = {k: rng.random(n) + 1 for k in layout.point_coords}
    path = tmp_path / "doe.nc"
    write_dataset(path, layout, data, [(0, 300), (300, 1000)], points)
    with xr.open_dataset(path) as ds:
        assert dict(ds.sizes) == {"point": n}
        assert set(ds.coords) == {"point", "alpha", "beta", "gamma", "gtilde"}
        np.testing.assert_array_equal(ds.point.values, np.arange(n))
        assert ds.point.dtype == np.int32
        for k, v in points.items():
            assert ds[k].dims == ("point",)
            np.testing.assert_array_equal(ds[k].values, v)
        for k, v in data.items():
            np.testing.assert_array_equal(ds[k].values, v)
        check_attrs(ds)
    w = store.NetCDFWriter(tmp_path / "x.nc", layout, VARIABLES)
    with pytest.raises(ValueError, match="coordinates"):
        w.write(0, 10, {k: v[:10] for k, v in data.items()})
    with pytest.raises(ValueError, match="expected 10"):
        w.write(0, 10, {k: v[:9] for k, v in data.items()}, points)
    w.close()


#: Which variables of test_each_variable_is_deflated_only_where_it_saves_its_share each
#: choice deflates, by the share of bytes that zlib level 1 saves on them (measured apart:
#: random bits ~0, a quarter of exact zeros ~0.24, half ~0.46, 90% ~0.87, the rest > 0.75).
DEFLATED = {"fast": {"u_max", "e_ord1", "n_steps", "sticks", "status"},
            "small": {"u_max", "e_ord1", "n_steps", "sticks", "status", "e_ord2_approx"},
            "none": set()}


@pytest.mark.parametrize("compress", list(DEFLATED))
def test_each_variable_is_deflated_only_where_it_saves_its_share(tmp_path, compress):
    assert set(DEFLATED) == set(registry.COMPRESSION)
    n = 20000
    rng = np.random.default_rng(2)
    sparse = np.where(rng.random(n) < 0.9, 0.0, rng.random(n))    # e of sticking points
    data = {"e_numeric": rng.random(n),                           # random bits: incompressible
            "u_max": np.linspace(0.1, 0.2, n),                    # smooth: shared high bytes
            "e_ord1": sparse,
            "error_ord1": np.where(rng.random(n) < 0.25, 0.0, rng.random(n)),
            "e_ord2_approx": np.where(rng.random(n) < 0.5, 0.0, rng.random(n)),
            "t_f": rng.random(n) * 5,
            "n_steps": rng.integers(0, 100, n, dtype=np.int32),   # small counts
            "sticks": (sparse == 0).astype(np.int8), "status": np.zeros(n, np.int8)}
    layout = store.Layout(dims=("point",), shape=(n,), axes={},
                          point_coords=("alpha", "beta", "gamma", "gtilde"))
    points = {k: np.full(n, 1.5) for k in layout.point_coords}
    path = tmp_path / "doe.nc"
    w = store.NetCDFWriter(path, layout, list(data), compress=compress)
    for s, e in [(0, 7000), (7000, n)]:
        w.write(s, e, {k: v[s:e] for k, v in data.items()},
                {k: v[s:e] for k, v in points.items()})
    w.close()
    with xr.open_dataset(path) as ds:
        for k, v in data.items():
            np.testing.assert_array_equal(ds[k].values, v)
        enc = {k: ds[k].encoding for k in list(data) + list(points)}
    deflated = DEFLATED[compress] | (set(points) if compress != "none" else set())
    assert {k for k, e in enc.items() if e["zlib"]} == deflated
    assert enc["u_max"]["shuffle"] == (compress != "none")
    assert all(e["fletcher32"] for e in enc.values())
    nbytes = {**{k: v.nbytes for k, v in data.items()}, **{k: 8 * n for k in points}}
    shrunk = sum(b for k, b in nbytes.items() if k in deflated)
    # the others stored as they are, the deflated ones to 54% of their bytes at most; HDF5's
    # metadata and the attributes take about 10 kB a variable
    assert path.stat().st_size < sum(nbytes.values()) - shrunk + 0.6 * shrunk + 13 * 16384


def test_an_unknown_compression_is_refused(tmp_path):
    layout = store.Layout(dims=("point",), shape=(4,), axes={},
                          point_coords=("alpha", "beta", "gamma", "gtilde"))
    with pytest.raises(ValueError, match="compress must be one of fast, small, none, got 'zip'"):
        store.NetCDFWriter(tmp_path / "x.nc", layout, ["e_ord1"], compress="zip")


def test_too_few_values_to_judge_by_keep_deflate_with_shuffle():
    rng = np.random.default_rng(3)
    few = rng.random(store.netcdf.TRIAL_MIN_BYTES // 8 - 1)     # incompressible, but few
    fast = registry.COMPRESSION["fast"]
    assert store.netcdf.deflate_filters(few, fast) == {"zlib": True, "complevel": 1,
                                                       "shuffle": True}
    assert not store.netcdf.deflate_filters(rng.random(4096), fast)["zlib"]
    assert store.netcdf.deflate_filters(np.zeros(0, np.int8), fast)["shuffle"] is False
    assert not store.netcdf.deflate_filters(few, None)["zlib"]


def test_a_file_no_chunk_reached_still_holds_every_variable(tmp_path):
    axes = {"alpha": np.array([1.5]), "beta": np.array([1.5]), "gamma": np.array([0.1]),
            "gtilde": np.array([0.0, 1.0])}
    layout = store.Layout(dims=tuple(axes), shape=(1, 1, 1, 2), axes=axes)
    store.NetCDFWriter(tmp_path / "x.nc", layout, VARIABLES).close()
    with xr.open_dataset(tmp_path / "x.nc") as ds:
        assert set(VARIABLES) <= set(ds.data_vars)


def test_a_value_that_does_not_fit_its_stored_type_is_refused(tmp_path):
    axes = {"alpha": np.array([1.5]), "beta": np.array([1.5]), "gamma": np.array([0.1]),
            "gtilde": np.array([0.0, 1.0])}
    layout = store.Layout(dims=tuple(axes), shape=(1, 1, 1, 2), axes=axes)
    w = store.NetCDFWriter(tmp_path / "x.nc", layout, ("n_steps", "sticks"))
    w.write(0, 2, {"n_steps": np.array([3, 4]), "sticks": np.array([True, False])})  # exact
    with pytest.raises(ValueError, match="n_steps: values do not fit"):
        w.write(0, 2, {"n_steps": np.array([3, 2 ** 40]), "sticks": np.zeros(2, bool)})
    w.close()
    with xr.open_dataset(tmp_path / "x.nc") as ds:
        assert ds.n_steps.values.ravel().tolist() == [3, 4]
        assert ds.sticks.values.ravel().tolist() == [1, 0] and ds.sticks.dtype == np.int8


def test_unknown_variable_is_refused():
    with pytest.raises(KeyError):
        store.variable_spec("e_ord9")


def manifest(**over):
    m = {"config_sha256": "abc", "sweep_version": "0.1.0", "output": "out.nc",
         "n_points": 10, "chunk_size": 4, "variables": ["e_ord1", "status"]}
    m.update(over)
    return m


def test_partial_store_saves_loads_and_resumes(tmp_path):
    out = tmp_path / "out.nc"
    p = store.PartialStore(out, manifest())
    assert p.open() == set()
    assert p.dir == tmp_path / "out.nc.partial"
    arrays = {"e_ord1": np.arange(4.0), "status": np.zeros(4, np.int8)}
    p.save_chunk(1, 4, 8, arrays, (2.0, 1.5))
    data, times = p.load_chunk(1, 4, 8)
    np.testing.assert_array_equal(data["e_ord1"], arrays["e_ord1"])
    assert data["status"].dtype == np.int8 and times == (2.0, 1.5)
    assert p.load_chunk(1, 0, 4) is None                 # wrong bounds
    assert p.load_chunk(2, 8, 10) is None                # missing
    (p.dir / "chunk_0000002.npz").write_bytes(b"garbage")  # damaged: recomputed, not trusted
    assert p.load_chunk(2, 8, 10) is None
    p.discard_chunk(2)
    p.release()
    # leftovers of a crash are cleaned, saved chunks found again
    (p.dir / "chunk_0000003.npz.tmp99").write_bytes(b"half")
    p.assembling.write_bytes(b"half")
    q = store.PartialStore(out, manifest())
    assert q.open() == {1}
    assert not p.assembling.exists() and not list(p.dir.glob("*.tmp*"))
    # a second process cannot write the same output
    with pytest.raises(store.ResumeError, match="another sweep process"):
        store.PartialStore(out, manifest()).open()
    q.remove()
    assert not p.dir.exists()


def test_a_saved_chunk_is_an_npz_whose_metadata_holds_each_members_crc32(tmp_path):
    p = store.PartialStore(tmp_path / "out.nc", manifest())
    p.open()
    arrays = {"e_ord1": np.linspace(0.0, 1.0, 4), "status": np.array([0, 1, 2, 3], np.int8)}
    p.save_chunk(0, 0, 4, arrays, (1.0,))
    path = p.dir / "chunk_0000000.npz"
    with np.load(path) as z:                         # numpy reads it as any .npz
        for name, a in arrays.items():
            np.testing.assert_array_equal(z[name], a)
        meta = json.loads(str(z["__meta__"]))
    with zipfile.ZipFile(path) as zf:                # zlib's CRC-32 of each member's bytes
        crc = {name: zlib.crc32(zf.read(name + ".npy")) for name in arrays}
    assert meta["crc32"] == crc
    p.release()


@pytest.mark.parametrize("key, value, what", [
    ("config_sha256", "def", "different configuration"),
    ("sweep_version", "9.9", "different sweep version"),
    ("sweep_source_sha256", "edited", "different sweep source code"),
    ("numerical_stack", "numba 0.1", "different numerical libraries"),
    ("chunk_size", 5, "different chunk size"),
    ("variables", ["e_ord1"], "different stored variables"),
])
def test_resume_with_a_mismatch_is_refused(tmp_path, key, value, what):
    out = tmp_path / "out.nc"
    p = store.PartialStore(out, manifest())
    p.open()
    p.release()
    with pytest.raises(store.ResumeError) as info:
        store.PartialStore(out, manifest(**{key: value})).open()
    msg = str(info.value)
    assert what in msg and "--restart" in msg and key in msg
    # --restart discards the old state
    r = store.PartialStore(out, manifest(**{key: value}))
    assert r.open(restart=True) == set()
    assert json.loads((r.dir / "manifest.json").read_text())[key] == value
    r.release()


def test_commit_replaces_atomically(tmp_path):
    final = tmp_path / "out.nc"
    final.write_text("old")
    tmp = tmp_path / "out.nc.partial"
    tmp.mkdir()
    new = tmp / "assembling.nc"
    new.write_text("new")
    store.commit(new, final)
    assert final.read_text() == "new" and not new.exists()


def test_summarize_reports_dims_variables_and_statistics(tmp_path):
    axes = {"alpha": np.array([1.5]), "beta": np.array([1.5]),
            "gamma": np.array([0.0, 0.1]), "gtilde": np.array([0.0, 1.0, 10.0])}
    layout = store.Layout(dims=tuple(axes), shape=(1, 1, 2, 3), axes=axes)
    data = fake_results(6, np.random.default_rng(2))
    data["status"][:] = [0, 0, 1, 4, 0, 3]
    data["e_ord1"][:] = [0.5, 1.0, 0.25, np.nan, 0.75, 0.5]
    path = tmp_path / "s.nc"
    write_dataset(path, layout, data, [(0, 6)],
                  attrs={"title": "demo", "integrator_steps": 64.0, "n_points": 6,
                         "sweep_version": "0.1.0"})
    text = store.summarize(path)
    assert "demo" in text and "gamma = 2" in text and "(6 points)" in text
    assert "ok: 3, stuck: 1, at_rest: 0, budget_exhausted: 1, invalid: 1" in text
    assert "min 0.25, mean 0.6, max 1, NaN 1 of 6" in text
    assert "integrator_steps = 64.0" in text
    assert "gtilde   [0, 10]" in text


def test_summarize_tells_infinite_values_from_nan(tmp_path):
    # t_f is inf where the bead creeps for ever: it was counted as NaN and left out of max.
    axes = {"alpha": np.array([1.5]), "beta": np.array([1.5]),
            "gamma": np.array([0.0, 0.1]), "gtilde": np.array([0.0, 1.0, 10.0])}
    layout = store.Layout(dims=tuple(axes), shape=(1, 1, 2, 3), axes=axes)
    data = fake_results(6, np.random.default_rng(2))
    t_f = np.array([2.0, np.inf, 3.0, np.nan, 4.0, np.inf])
    data["t_f"] = t_f
    data["error_ord1"][:] = [0.1, -np.inf, 0.0, 0.0, 0.0, 0.0]
    path = tmp_path / "s.nc"
    write_dataset(path, layout, data, [(0, 6)], attrs={"sweep_version": "0.1.0"})
    text = store.summarize(path)
    finite = t_f[np.isfinite(t_f)]
    assert (f"min {np.nanmin(t_f):.6g}, mean {finite.mean():.6g}, max {np.nanmax(t_f):.6g}, "
            f"NaN {np.isnan(t_f).sum()} of 6, infinite {np.isinf(t_f).sum()} (not in the "
            "mean)") in text
    assert "max |error| inf" in text
