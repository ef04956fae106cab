"""Chunked execution, only-requested outputs, resume and determinism (sweep.sweeps.runner)."""
import time
import warnings

import numba
import numpy as np
import pytest
import xarray as xr

from sweep import api, store
from sweep.sweeps import config, design, runner

GRID = """
title = "runner test"
[design]
kind = "grid"
alpha = 1.5
beta = [1.0, 1.5]
gamma = {start = 0.0, stop = 0.2, num = 9}
gtilde = [0.0, 0.05, 1.0, 10.0]
[outputs]
e = ["numeric", "ord1", "large_gtilde"]
fields = "all"
[integrator]
steps = 16
[run]
chunk_size = 10
"""

DOE = """
[design]
kind = "doe"
sampler = "sobol"
n = 100
seed = 11
alpha = {min = 1.0, max = 3.0}
beta = {min = 1.0, max = 3.0}
gamma = {min = 1e-3, max = 0.5, scale = "log"}
gtilde = {min = 0.0, max = 10.0}
[outputs]
e = ["ord1"]
fields = ["status", "error_ord1"]
[integrator]
steps = 16
[run]
chunk_size = 16
"""

#: Global attributes that legitimately differ between two runs of the same configuration.
VOLATILE = runner.VOLATILE_ATTRS


def run(text, path, **kw):
    kw.setdefault("quiet", True)
    return runner.run(config.loads(text, source="test.toml"), path, **kw)


def opened(path):
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    for key in VOLATILE:
        ds.attrs.pop(key, None)  # compile time and threads: local runs only
    return ds


def expected(text):
    """The outputs computed directly with the api on the design's points."""
    cfg = config.loads(text)
    d = design.build(cfg.design)
    a, b, g, gt = d.points(0, d.size)
    r = api.integrate(a, b, g, gt, **cfg.integrator.kwargs())
    out = {"e_numeric": r.e, "sticks": r.sticks, "t_f": r.t_f, "u_max": r.u_max,
           "n_steps": r.n_steps, "status": r.status, "e_err": r.e_err}
    for m in cfg.outputs.approximations:
        out[f"e_{m}"] = api.cor(a, b, g, gt, method=m, **cfg.method_options(m))
        out[f"error_{m}"] = out[f"e_{m}"] - r.e
    return d, (a, b, g, gt), {k: out[k] for k in cfg.outputs.variables}


def test_grid_run_stores_exactly_what_the_api_computes(tmp_path):
    res = run(GRID, tmp_path / "g.nc")
    assert (res.n_points, res.computed_points, res.chunks) == (72, 72, 8)
    assert not (tmp_path / "g.nc.partial").exists()
    d, _, want = expected(GRID)
    ds = opened(tmp_path / "g.nc")
    assert tuple(ds.data_vars) == config.loads(GRID).outputs.variables
    assert dict(ds.sizes) == {"alpha": 1, "beta": 2, "gamma": 9, "gtilde": 4}
    for name, axis in d.axes.items():
        np.testing.assert_array_equal(ds[name].values, axis)
    for name, values in want.items():
        assert ds[name].dims == ("alpha", "beta", "gamma", "gtilde")
        assert ds[name].dtype == store.variable_spec(name)[0]
        np.testing.assert_array_equal(ds[name].values.reshape(-1), values, err_msg=name)
    assert np.isfinite(ds.e_large_gtilde).all()
    a = ds.attrs
    assert a["Conventions"] == store.CONVENTIONS == "CF-1.8"
    assert a["sweep_config"] == GRID and a["sweep_config_sha256"] == config.loads(GRID).sha256
    assert a["numba_version"] == numba.__version__ and a["numpy_version"] == np.__version__
    assert a["integrator_steps"] == 16.0 and a["integrator_max_steps"] == api.DEFAULT_MAX_STEPS
    assert a["integrator_rest_tol"] == 1e-8 and a["n_points"] == 72
    with xr.open_dataset(tmp_path / "g.nc") as raw:
        assert raw.attrs["run_time_s"] > 0 and raw.attrs["points_per_second"] > 0


def test_doe_run_has_a_point_dimension_with_parameter_coordinates(tmp_path):
    run(DOE, tmp_path / "d.nc")
    _, points, want = expected(DOE)
    ds = opened(tmp_path / "d.nc")
    assert dict(ds.sizes) == {"point": 100}
    assert set(ds.coords) == {"point", "alpha", "beta", "gamma", "gtilde"}
    np.testing.assert_array_equal(ds.point.values, np.arange(100))
    for name, values in zip(("alpha", "beta", "gamma", "gtilde"), points):
        np.testing.assert_array_equal(ds[name].values, values)
    assert set(ds.data_vars) == {"e_ord1", "status", "error_ord1"}
    for name, values in want.items():
        np.testing.assert_array_equal(ds[name].values, values, err_msg=name)


def test_approximations_alone_run_no_integration(tmp_path, monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("the numerical integration ran although nothing needs it")

    monkeypatch.setattr(api, "integrate", forbidden)
    text = DOE.replace('fields = ["status", "error_ord1"]', "").replace(
        'e = ["ord1"]', 'e = ["ord1", "large_gtilde"]').replace("[integrator]\nsteps = 16\n", "")
    run(text, tmp_path / "a.nc")
    ds = opened(tmp_path / "a.nc")
    assert set(ds.data_vars) == {"e_ord1", "e_large_gtilde"}   # nothing else allocated
    assert ds.attrs["integrator"].startswith("not run")
    assert "integrator_steps" not in ds.attrs


def test_error_fields_share_one_integration(tmp_path, monkeypatch):
    calls = {"integrate": 0, "cor": []}
    real_integrate, real_cor = api.integrate, api.cor

    def integrate(*args, **kwargs):
        calls["integrate"] += 1
        return real_integrate(*args, **kwargs)

    def cor(*args, method="numeric", **kwargs):
        calls["cor"].append(method)
        return real_cor(*args, method=method, **kwargs)

    monkeypatch.setattr(api, "integrate", integrate)
    monkeypatch.setattr(api, "cor", cor)
    text = GRID.replace('e = ["numeric", "ord1", "large_gtilde"]', 'e = ["numeric"]').replace(
        'fields = "all"', 'fields = ["error_ord1", "error_large_gtilde"]')
    res = run(text, tmp_path / "e.nc")
    # one call per chunk, and one for the warm-up before them
    assert calls["integrate"] == res.chunks + 1 == 9
    assert sorted(set(calls["cor"])) == ["large_gtilde", "ord1"] and len(calls["cor"]) == 18
    ds = opened(tmp_path / "e.nc")
    assert set(ds.data_vars) == {"e_numeric", "error_ord1", "error_large_gtilde"}


def test_results_do_not_depend_on_chunk_size_or_thread_count(tmp_path, monkeypatch):
    run(GRID, tmp_path / "ref.nc")
    ref = opened(tmp_path / "ref.nc")
    run(GRID, tmp_path / "c7.nc", chunk_size=7)
    run(GRID, tmp_path / "c72.nc", chunk_size=1000)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        run(GRID, tmp_path / "t1.nc", chunk_size=72)
    finally:
        numba.set_num_threads(threads)
    monkeypatch.setattr(runner, "WRITE_BEHIND", 0)      # writing in the main thread
    run(GRID, tmp_path / "w0.nc", chunk_size=13)
    for name in ("c7.nc", "c72.nc", "t1.nc", "w0.nc"):
        other = opened(tmp_path / name)
        other.attrs["chunk_size"] = ref.attrs["chunk_size"]
        xr.testing.assert_identical(ref, other)


def interrupt_after(monkeypatch, n_chunks):
    real = runner.compute_chunk
    count = [0]

    def compute(*args):
        if count[0] == n_chunks + 1:            # the first call is the warm-up
            raise KeyboardInterrupt
        count[0] += 1
        return real(*args)

    monkeypatch.setattr(runner, "compute_chunk", compute)


@pytest.mark.parametrize("text", [GRID, DOE], ids=["grid", "doe"])
def test_resume_after_interrupt_equals_an_uninterrupted_run(tmp_path, monkeypatch, text):
    run(text, tmp_path / "ref.nc")
    out = tmp_path / "out.nc"
    with monkeypatch.context() as m:
        interrupt_after(m, 3)
        with pytest.raises(KeyboardInterrupt):
            run(text, out)
    assert not out.exists()                     # no half-written file at the output path
    partial = tmp_path / "out.nc.partial"
    assert len(list(partial.glob("chunk_*.npz"))) == 3
    res = run(text, out)
    chunk = config.loads(text).chunk_size
    assert res.resumed_chunks == 3 and res.computed_points == res.n_points - 3 * chunk
    assert not partial.exists()
    xr.testing.assert_identical(opened(tmp_path / "ref.nc"), opened(out))


def test_a_writer_error_surfaces_and_the_run_can_resume(tmp_path, monkeypatch):
    real = store.NetCDFWriter.write
    calls = [0]

    def failing(self, *args):
        calls[0] += 1
        if calls[0] == 3:
            raise OSError("disk full")
        return real(self, *args)

    out = tmp_path / "out.nc"
    with monkeypatch.context() as m:
        m.setattr(store.NetCDFWriter, "write", failing)
        with pytest.raises(runner.RunError, match="disk full; the .* finished chunks are kept"):
            run(GRID, out)
    assert not out.exists()
    assert len(list((tmp_path / "out.nc.partial").glob("chunk_*.npz"))) >= 3
    run(GRID, out)
    run(GRID, tmp_path / "ref.nc")
    xr.testing.assert_identical(opened(tmp_path / "ref.nc"), opened(out))


def _filters(path):
    """{variable: netCDF4's filters()} of a file's point variables."""
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        return {k: v.filters() for k, v in nc.variables.items() if v.dimensions == ("point",)}


def test_compress_false_stores_the_same_values_as_computed(tmp_path):
    run(DOE, tmp_path / "z.nc")
    run(DOE.replace("chunk_size = 16", "chunk_size = 16\ncompress = false"),
        tmp_path / "raw.nc")
    deflated, stored = _filters(tmp_path / "z.nc"), _filters(tmp_path / "raw.nc")
    assert set(deflated) == set(stored) >= {"status", "error_ord1", "alpha", "gtilde"}
    assert not any(f["zlib"] or f["shuffle"] for f in stored.values())
    # The coordinates of a Sobol design: deflate with shuffle saves most of their bytes.
    assert deflated["alpha"]["zlib"] and deflated["alpha"]["shuffle"]
    xr.testing.assert_equal(opened(tmp_path / "z.nc"), opened(tmp_path / "raw.nc"))


@pytest.mark.parametrize("compress, advice", [("fast", '"none"'),
                                              ("small", '"fast" or "none"'), ("none", None)])
def test_a_run_held_back_by_its_compressing_writer_says_so(tmp_path, monkeypatch, capsys,
                                                           compress, advice):
    real = store.NetCDFWriter.write

    def slow(self, *args):
        time.sleep(0.05)       # a writer far slower than this design's chunks
        return real(self, *args)

    monkeypatch.setattr(store.NetCDFWriter, "write", slow)
    monkeypatch.setattr(runner, "WRITER_HINT_SECONDS", 0.1)     # this design's scale
    text = DOE.replace("chunk_size = 16", f"chunk_size = 16\ncompress = \"{compress}\"")
    res = run(text, tmp_path / "out.nc", quiet=False)
    # 7 chunks: the run waits for about every one's writing but the first.
    assert res.writer_wait_seconds > 0.25
    err = capsys.readouterr().err
    if advice is None:
        assert "compress =" not in err
    else:
        assert f"compress = {advice} in the configuration's [run] table" in err


def test_a_resumed_run_waiting_for_its_writer_says_nothing_of_compress(tmp_path, monkeypatch,
                                                                       capsys):
    # Its copied chunks wait for the writer by nature, and the advice would not resume.
    out = tmp_path / "out.nc"
    with monkeypatch.context() as m:
        interrupt_after(m, 5)
        with pytest.raises(KeyboardInterrupt):
            run(DOE, out)
    real = store.NetCDFWriter.write

    def slow(self, *args):
        time.sleep(0.05)
        return real(self, *args)

    monkeypatch.setattr(store.NetCDFWriter, "write", slow)
    monkeypatch.setattr(runner, "WRITER_HINT_SECONDS", 0.1)
    res = run(DOE, out, quiet=False)
    assert res.resumed_chunks == 5 and res.writer_wait_seconds > 0.25
    assert "compress =" not in capsys.readouterr().err


def _slow_saves(monkeypatch, seconds=0.2):
    real = store.PartialStore.save_chunk

    def slow(self, *args):
        time.sleep(seconds)      # still saving when the next chunk is handed over
        return real(self, *args)

    monkeypatch.setattr(store.PartialStore, "save_chunk", slow)


def test_an_interrupted_run_keeps_the_chunk_still_being_saved(tmp_path, monkeypatch, capsys):
    # Chunks are saved one behind, in a thread: the interruption waits for that save.
    _slow_saves(monkeypatch)
    interrupt_after(monkeypatch, 3)
    out = tmp_path / "out.nc"
    with pytest.raises(KeyboardInterrupt):
        run(DOE, out, quiet=False)
    assert len(list((tmp_path / "out.nc.partial").glob("chunk_*.npz"))) == 3
    assert "interrupted: 3 of 7 chunks saved" in capsys.readouterr().err


def test_a_failed_run_keeps_the_chunk_still_being_saved(tmp_path, monkeypatch):
    _slow_saves(monkeypatch)
    real, calls = store.NetCDFWriter.write, [0]

    def failing(self, *args):
        calls[0] += 1
        if calls[0] == 3:
            raise OSError("disk full")
        return real(self, *args)

    monkeypatch.setattr(store.NetCDFWriter, "write", failing)
    monkeypatch.setattr(runner, "WRITE_BEHIND", 0)     # the error at the third chunk's write
    with pytest.raises(runner.RunError, match="disk full; the 3 finished chunks are kept"):
        run(DOE, tmp_path / "out.nc")
    assert len(list((tmp_path / "out.nc.partial").glob("chunk_*.npz"))) == 3


def test_resume_with_another_configuration_is_refused(tmp_path, monkeypatch):
    out = tmp_path / "out.nc"
    with monkeypatch.context() as m:
        interrupt_after(m, 2)
        with pytest.raises(KeyboardInterrupt):
            run(GRID, out)
    other = GRID.replace("num = 9", "num = 10")
    with pytest.raises(store.ResumeError, match="different configuration"):
        run(other, out)
    with monkeypatch.context() as m:   # same configuration, edited package
        m.setattr(runner, "source_sha256", lambda: "edited")
        with pytest.raises(store.ResumeError, match="different sweep source code"):
            run(GRID, out)
    with monkeypatch.context() as m:   # same sweep, another numba
        m.setattr(runner, "numerical_stack", lambda: "numba 0.0")
        with pytest.raises(store.ResumeError, match="different numerical libraries"):
            run(GRID, out)
    res = run(other, out, restart=True)
    assert res.resumed_chunks == 0 and res.computed_points == 80
    assert opened(out).sizes["gamma"] == 10


def test_existing_output_is_kept_or_refused(tmp_path):
    out = tmp_path / "out.nc"
    run(GRID, out)
    before = out.stat().st_mtime_ns
    assert run(GRID, out).up_to_date and out.stat().st_mtime_ns == before
    other = GRID.replace("steps = 16", "steps = 20")
    with pytest.raises(store.ResumeError, match="different configuration"):
        run(other, out)
    assert run(other, out, restart=True).computed_points == 72
    assert opened(out).attrs["integrator_steps"] == 20.0
    junk = tmp_path / "junk.nc"
    junk.write_text("not netCDF")
    with pytest.raises(store.ResumeError, match="cannot be read as netCDF"):
        run(GRID, junk)


def test_interrupted_restart_resumes_and_keeps_the_old_output_meanwhile(tmp_path, monkeypatch):
    out = tmp_path / "out.nc"
    run(GRID, out)
    other = GRID.replace("steps = 16", "steps = 20")
    with monkeypatch.context() as m:
        interrupt_after(m, 2)
        with pytest.raises(KeyboardInterrupt):
            run(other, out, restart=True)
    assert opened(out).attrs["integrator_steps"] == 16.0     # the old file is intact
    res = run(other, out)                                    # same command, no --restart
    assert res.resumed_chunks == 2
    assert opened(out).attrs["integrator_steps"] == 20.0


def test_dask_cluster_gives_the_local_results(tmp_path):
    distributed = pytest.importorskip("distributed")
    run(DOE, tmp_path / "local.nc")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        res = run(DOE, tmp_path / "dask.nc", scheduler=cluster.scheduler_address)
        address = cluster.scheduler_address
    assert res.computed_points == 100 and res.compile_seconds is None  # workers compile
    with xr.open_dataset(tmp_path / "dask.nc") as raw:
        assert raw.attrs["sweep_command"].endswith(f"--scheduler {address}")
        assert raw.attrs["executor"] == f"dask distributed, scheduler {address}"
        assert "compile_time_s" not in raw.attrs and "numba_num_threads" not in raw.attrs
    xr.testing.assert_identical(opened(tmp_path / "local.nc"), opened(tmp_path / "dask.nc"))


def test_a_dask_worker_under_other_numerical_libraries_is_refused(tmp_path, monkeypatch):
    # Its chunks could differ in their last bits from this process's (another numba, or
    # no libmvec on its machine), while the file records this process's libraries.
    distributed = pytest.importorskip("distributed")
    real = runner.source_sha256()
    monkeypatch.setattr(runner, "_loaded_source", lambda: (real, "numba 0.0"))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        with pytest.raises(runner.RunError, match="numba 0.0 there") as info:
            run(DOE, tmp_path / "dask.nc", scheduler=cluster.scheduler_address)
    assert runner.numerical_stack() + " here" in str(info.value)
    assert not (tmp_path / "dask.nc").exists()


CAVEAT_GRID = """
[design]
kind = "grid"
alpha = 1.5
beta = 1.5
gamma = {start = 1e-4, stop = 1e-2, num = 6, spacing = "log"}
gtilde = {start = 1e-3, stop = 0.1, num = 5, spacing = "log"}
[outputs]
e = ["numeric"]
[run]
chunk_size = 7
"""


def test_points_out_of_budget_are_counted_though_status_is_not_stored(tmp_path,
                                                                      monkeypatch):
    # Only e was stored: a budget of 20 steps, which no march at 96 steps per half period
    # finishes, wrote 30 upper bounds as if they were values, exit 0, nothing said.
    text = CAVEAT_GRID + "[integrator]\nmax_steps = 20\n"
    out = tmp_path / "out.nc"
    with monkeypatch.context() as m:
        interrupt_after(m, 2)
        with pytest.raises(KeyboardInterrupt):
            run(text, out)
    with pytest.warns(runner.CaveatWarning, match="30 of 30 points ran out of the step "
                                                  "budget") as caught:
        res = run(text, out)                    # the resumed chunks' counts are kept too
    assert res.resumed_chunks == 2 and len(caught) == 1
    assert res.caveats == {"points_budget_exhausted": 30}
    with xr.open_dataset(out) as ds:
        assert "status" not in ds and ds.attrs["points_budget_exhausted"] == 30
        assert "points_above_tol" not in ds.attrs        # no tol was asked for
    g = np.geomspace(1e-4, 1e-2, 6)[:, None]
    r = api.integrate(1.5, 1.5, g, np.geomspace(1e-3, 0.1, 5), max_steps=20)
    assert np.all(r.status == api.Status.BUDGET_EXHAUSTED)


def test_points_whose_estimate_is_above_tol_are_counted(tmp_path):
    # Every point rebounds with e in [0.5, 1) here, where an ulp is 2^-53: no float64 e is
    # certainly within 1e-17 of the truth, so every point must count.
    with pytest.warns(runner.CaveatWarning, match="30 of 30 points may miss integrator.tol"):
        ds, res = runner.run_in_memory(
            config.loads(CAVEAT_GRID + "[integrator]\ntol = 1e-17\n"), quiet=True)
    assert float(ds.e_numeric.min()) >= 0.5 and float(ds.e_numeric.max()) < 1.0
    assert ds.attrs["points_above_tol"] == 30 and ds.attrs["points_budget_exhausted"] == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds, res = runner.run_in_memory(config.loads(CAVEAT_GRID + "[integrator]\ntol = 1e-8\n"),
                                       quiet=True)
    assert ds.attrs["points_above_tol"] == 0 and res.caveats["points_above_tol"] == 0


def test_auto_counts_its_misses_and_records_the_integrator_it_ran(tmp_path):
    # auto's points integrated beyond reach of tol = 1e-13 came as Python RuntimeWarnings
    # (the warm-up's and each chunk's), uncounted, and the file said "integrator: not run".
    # Reference: the same points through sweep.cor_fields in one call, which warns of them.
    text = (CAVEAT_GRID.replace('["numeric"]', '["auto"]').replace("stop = 1e-2", "stop = 1.0")
            .replace("stop = 0.1", "stop = 10.0") + "[options.auto]\ntol = 1e-13\n")
    cfg = config.loads(text)
    d = design.build(cfg.design)
    with pytest.warns(RuntimeWarning, match=r"^\d+ point\(s\) integrated by auto") as w:
        api.cor_fields(*d.points(0, d.size), method="auto", tol=1e-13)
    want = int(str(w[0].message).split()[0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds, res = runner.run_in_memory(cfg, quiet=True)
    assert [type(x.message) for x in caught] == [runner.CaveatWarning]
    assert str(caught[0].message).startswith(f"{want} of 30 points may miss options.auto.tol")
    assert ds.attrs["points_above_tol"] == want > 0
    assert "for the points auto integrates" in ds.attrs["integrator"]
    assert ds.attrs["integrator_tol"] == 1e-13


@pytest.mark.parametrize("extra, message", [
    # Ignored, they would look as if they had shaped the results (device ran on no GPU).
    ('[integrator]\ndevice = "cuda"\n', "integrator.device: is an option of the integrator"),
    ("[integrator]\nsteps = 50\n", "integrator.steps: is an option of the integrator"),
])
def test_integrator_options_of_a_sweep_that_never_integrates_are_refused(extra, message):
    with pytest.raises(config.ConfigError, match=message):
        config.loads(CAVEAT_GRID.replace('["numeric"]', '["ord1"]') + extra)


def test_integrator_tol_beside_autos_own_is_refused_unless_numeric_uses_it():
    text = (CAVEAT_GRID.replace('["numeric"]', '["auto"]')
            + "[integrator]\ntol = 1e-3\n[options.auto]\ntol = 1e-6\n")
    with pytest.raises(config.ConfigError, match=r"integrator.tol: is not used: auto "
                                                 r"integrates at its own tol"):
        config.loads(text)
    config.loads(text.replace('["auto"]', '["numeric", "auto"]'))     # numeric's tol
    config.loads(text.replace("[options.auto]\ntol = 1e-6\n", ""))   # auto's tol then


def test_closed_forms_alone_have_no_caveat_counts(tmp_path):
    ds, res = runner.run_in_memory(config.loads(CAVEAT_GRID.replace('["numeric"]',
                                                                    '["ord1"]')), quiet=True)
    assert not any(k in ds.attrs for k in store.CAVEAT_ATTRS)


def test_an_output_that_is_the_configuration_is_refused(tmp_path, monkeypatch):
    # `sweep run --restart x.nc` (the default output of x.nc is x.nc itself) replaced the
    # configuration by its output.
    monkeypatch.chdir(tmp_path)                 # where the default output goes
    cfg = tmp_path / "x.nc"
    cfg.write_text(CAVEAT_GRID)
    for output in (None, cfg, tmp_path / "." / "x.nc"):
        with pytest.raises(runner.RunError, match="is the configuration file itself"):
            runner.run(cfg, output, restart=True, quiet=True)
    assert cfg.read_text() == CAVEAT_GRID and sorted(tmp_path.iterdir()) == [cfg]


def test_the_final_line_says_how_long_the_kernels_took_to_load(tmp_path, capsys):
    # Its rate counts the whole call, the progress line's the chunks alone: it says why.
    res = run(DOE, tmp_path / "out.nc", quiet=False)
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith(f"wrote {tmp_path / 'out.nc'}: "), last
    assert (f" s ({res.compile_seconds:.1f} s of it loading or compiling the kernels), "
            in last), last
