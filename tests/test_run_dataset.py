"""``sweep.run``: a sweep as an xarray.Dataset in memory, identical to the file
``sweep run`` writes read back; configurations as paths, text, dicts; nothing written."""
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import sweep
from sweep import store
from sweep.sweeps import config, design, preflight, runner

GRID = """
title = "in-memory grid"
[design]
kind = "grid"
alpha = 1.5
beta = [1.0, 1.5]
gamma = {start = 1e-3, stop = 0.3, num = 4, spacing = "log"}
gtilde = {start = 0.0, stop = 10.0, num = 3}
[outputs]
e = "all"
fields = "all"
[integrator]
steps = 16
[run]
chunk_size = 7
"""

DOE = """
[design]
kind = "doe"
sampler = "sobol"
n = 20
seed = 3
alpha = {min = 1.0, max = 3.0}
beta = 1.5
gamma = {min = 1e-3, max = 0.5, scale = "log"}
gtilde = {min = 0.0, max = 10.0}
[outputs]
e = ["numeric", "ord1"]
fields = ["status", "sticks", "n_steps", "error_ord1"]
[integrator]
steps = 16
[run]
chunk_size = 6
"""

SCENE = """
[design]
kind = "scene"
v0 = {start = 0.1, stop = 5.0, num = 3, spacing = "log"}
F = [0.0, 1.0]
[design.materials.steel]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[design.materials.glass]
law = "tti"
radius = 1e-3
density = 2500.0
E = 63e9
nu = 0.22
damping = {model = "tsuji", e = 0.9}
[outputs]
e = ["numeric", "auto"]
fields = ["status", "method_used"]
[options.auto]
tol = 1e-3
[integrator]
steps = 16
[run]
chunk_size = 5
"""


def _stable(ds, *also):
    """``ds`` without the attributes that differ between two runs (and ``also``)."""
    ds = ds.copy()
    for key in runner.VOLATILE_ATTRS + also:
        ds.attrs.pop(key, None)
    return ds


def _assert_same_dataset(memory, path):
    with xr.open_dataset(path) as f:
        f = f.load()
    xr.testing.assert_identical(_stable(memory), _stable(f))
    # assert_identical compares values, not storage types: those must match as well
    for name in f.variables:
        assert memory[name].dtype == f[name].dtype, name
    assert set(memory.attrs) == set(f.attrs)


@pytest.mark.parametrize("text", [GRID, DOE, SCENE], ids=["grid", "doe", "scene"])
def test_in_memory_equals_the_file_read_back(text, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    source = tmp_path / "c.toml"
    source.write_text(text)
    ds = sweep.run(source, quiet=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]   # nothing written
    runner.run(source, tmp_path / "c.nc", quiet=True)
    _assert_same_dataset(ds, tmp_path / "c.nc")
    assert ds.attrs["sweep_command"] == f"sweep.run({str(source)!r}, chunk_size=" \
                                        f"{config.loads(text).chunk_size})"
    for var in ds.data_vars.values():     # numpy-backed, loaded
        assert isinstance(var.variable._data, np.ndarray)


def test_chunking_does_not_change_the_dataset():
    a = sweep.run(DOE, quiet=True)
    b = sweep.run(DOE, quiet=True, chunk_size=1)
    xr.testing.assert_identical(_stable(a, "chunk_size"), _stable(b, "chunk_size"))


def test_text_and_dict_configurations_write_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    from_text = sweep.run(GRID, quiet=True)
    data = {"title": "in-memory grid",
            "design": {"kind": "grid", "alpha": 1.5, "beta": np.array([1.0, 1.5]),
                       "gamma": {"start": 1e-3, "stop": 0.3, "num": 4, "spacing": "log"},
                       "gtilde": {"start": 0.0, "stop": 10.0, "num": np.int64(3)}},
            "outputs": {"e": "all", "fields": "all"},
            "integrator": {"steps": 16}, "run": {"chunk_size": 7}}
    from_dict = sweep.run(data, quiet=True)
    assert list(tmp_path.iterdir()) == []
    assert from_dict.attrs["sweep_config_sha256"] == from_text.attrs["sweep_config_sha256"]
    xr.testing.assert_identical(_stable(from_dict, "sweep_config"),
                                _stable(from_text, "sweep_config"))
    # the text stored for a dict is TOML that parses back to the same configuration
    assert config.loads(from_dict.attrs["sweep_config"]).sha256 == config.loads(GRID).sha256
    assert from_text.attrs["sweep_config"] == GRID


def test_a_configuration_without_a_file_never_writes_sweep_nc(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(runner.RunError, match="give the output file"):
        runner.run(config.loads(GRID), quiet=True)
    with pytest.raises(runner.RunError, match="give the output file"):
        runner.default_output(config.loads(GRID))
    assert list(tmp_path.iterdir()) == []
    assert runner.default_output(config.loads(GRID, source="a/b.toml")).name == "b.nc"


def test_out_writes_the_file_and_opens_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    memory = sweep.run(DOE, quiet=True)
    with sweep.run(DOE, out=tmp_path / "d.nc", quiet=True) as ds:
        assert (tmp_path / "d.nc").is_file()
        xr.testing.assert_identical(_stable(ds.load()), _stable(memory))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.nc"]   # no lock, no partial


def test_restart_without_out_is_refused_naming_out(tmp_path, monkeypatch):
    # It raised "run_in_memory() got an unexpected keyword argument 'restart'".
    monkeypatch.chdir(tmp_path)
    for restart in (True, False):
        with pytest.raises(TypeError, match="restart= needs out="):
            sweep.run(GRID, quiet=True, restart=restart)
    assert list(tmp_path.iterdir()) == []


def test_limits_that_are_not_limits_are_refused_naming_them(tmp_path, monkeypatch):
    # limits="x" raised AttributeError: 'str' object has no attribute 'max_points'.
    monkeypatch.chdir(tmp_path)
    for out in (None, "o.nc"):
        with pytest.raises(TypeError, match="limits must be a .*Limits, got str 'x'"):
            sweep.run(GRID, out=out, quiet=True, limits="x")
    assert list(tmp_path.iterdir()) == []
    ds = sweep.run(GRID, quiet=True, limits=preflight.Limits(max_points=24))
    assert ds.sizes["gamma"] == 4
    with pytest.raises(runner.RunError, match="24"):
        sweep.run(GRID, quiet=True, limits=preflight.Limits(max_points=23))


@pytest.mark.parametrize("bad", [
    GRID.replace("alpha = 1.5", "alpha = 0.5"),
    GRID.replace("[outputs]", "[output]"),
    DOE.replace("sampler", "samplr"),
])
def test_a_bad_configuration_gives_the_same_error_in_every_form(bad, tmp_path):
    with pytest.raises(config.ConfigError) as direct:
        config.loads(bad)
    with pytest.raises(config.ConfigError) as text:
        sweep.run(bad, quiet=True)
    assert str(text.value) == str(direct.value)
    path = tmp_path / "bad.toml"
    path.write_text(bad)
    with pytest.raises(config.ConfigError) as from_file:
        sweep.run(path, quiet=True)
    assert str(from_file.value) == f"{path}: {direct.value}"
    import tomllib

    with pytest.raises(config.ConfigError) as from_dict:
        sweep.run(tomllib.loads(bad), quiet=True)
    assert str(from_dict.value) == str(direct.value)


def test_configuration_forms():
    cfg = config.loads(GRID)
    assert config.as_config(cfg) is cfg
    with pytest.raises(config.ConfigError, match="cannot read configuration"):
        config.as_config("no/such/file.toml")
    with pytest.raises(config.ConfigError, match="got int"):
        config.as_config(3)
    with pytest.raises(config.ConfigError, match=r"design.alpha: TOML has no value for NoneType"):
        config.from_dict({"design": {"kind": "grid", "alpha": None}})


def test_in_memory_refuses_a_dataset_larger_than_memory(monkeypatch):
    monkeypatch.setattr(preflight, "physical_memory", lambda: 1000)
    with pytest.raises(runner.RunError, match="needs up to .* in memory, more than this "
                                              "machine's 1 kB; give out="):
        sweep.run(GRID, quiet=True)
    assert sweep.run(GRID, quiet=True, force=True).sizes["gamma"] == 4


def test_memory_writer_takes_chunks_in_any_order_like_the_file(tmp_path):
    d = design.build(config.loads(DOE).design)
    layout, names = d.layout(), ("e_ord1", "status")
    rng = np.random.default_rng(0)
    values = {"e_ord1": rng.uniform(size=d.size), "status": rng.integers(0, 3, d.size)}
    values["e_ord1"][3] = np.nan
    memory = store.MemoryWriter(layout, names, {"title": "t", "flag": True, "none": None})
    nc = store.NetCDFWriter(tmp_path / "w.nc", layout, names,
                            {"title": "t", "flag": True, "none": None})
    chunks = list(design.Chunks(d.size, 3))
    for i in rng.permutation(len(chunks)):
        start, stop = chunks[i]
        arrays = {k: v[start:stop] for k, v in values.items()}
        points = dict(zip(config.PARAMETERS, d.points(start, stop)))
        memory.write(start, stop, arrays, points)
        nc.write(start, stop, arrays, points)
    memory.close()
    nc.close()
    ds = memory.dataset()
    _assert_same_dataset(ds, tmp_path / "w.nc")
    assert ds.attrs["flag"] == 1 and ds.attrs["none"] == "default"
    with pytest.raises(ValueError, match="already handed over"):
        memory.write(0, 1, {k: v[:1] for k, v in values.items()})
    with pytest.raises(ValueError, match="do not fit the stored type"):
        store.MemoryWriter(layout, names).write(0, 1, {"e_ord1": [0.5], "status": [0.5]},
                                                dict(zip(config.PARAMETERS, d.points(0, 1))))


def test_import_sweep_stays_light():
    code = ("import sys, sweep\n"
            "heavy = [m for m in ('xarray', 'netCDF4', 'dask', 'tqdm', 'sweep.sweeps')\n"
            "         if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "from sweep.sweeps.dataset import run\n"
            "assert sweep.run is run and 'run' in dir(sweep)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_in_memory_on_a_dask_cluster_gives_the_local_dataset():
    distributed = pytest.importorskip("distributed")
    local = sweep.run(DOE, quiet=True, chunk_size=3)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        remote = sweep.run(DOE, quiet=True, chunk_size=3, scheduler=cluster.scheduler_address)
        address = cluster.scheduler_address
    assert remote.attrs["sweep_command"].endswith(f"scheduler={address!r})")
    xr.testing.assert_identical(_stable(remote), _stable(local))   # chunks in any order
