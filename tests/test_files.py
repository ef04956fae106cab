"""What an xarray or CF user expects of a sweep's netCDF file: fill values, flag variables,
dtypes, axis spacing, an indexed ``point`` dimension, a scene's materials named by an
auxiliary coordinate, provenance, exact round trips, CF compliance (``cfchecker``, and
UDUNITS units through ``cfunits``) on every layout and the ``sweep info`` view of it."""
import math
import re
from pathlib import Path

import netCDF4
import numba
import numpy as np
import pytest
import xarray as xr

from sweep import api, registry, store
from sweep.sweeps import config, design, runner

GRID = """
title = "files test grid"
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
fields = "all"
[integrator]
steps = 16
"""

#: A scene of one contact law (Kuwabara-Kono, alpha = beta = 1.5).
SCENE = """
[design]
kind = "scene"
v0 = {start = 0.1, stop = 2.0, num = 3, spacing = "log"}
F = [0.0, 1e-3]
[design.materials.steel]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[design.materials.bead]
law = "kk"
m = 2.05e-3
k = 9.858e9
gamma0 = 5.2e-7
[outputs]
e = ["numeric"]
fields = ["status"]
[integrator]
steps = 16
"""

#: A scene whose materials differ in alpha and in alpha - beta (kk, linear, tti).
MIXED = """
[design]
kind = "scene"
v0 = [0.5, 1.0]
F = 0.0
[design.materials.steel]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[design.materials.rubber]
law = "linear"
m = 2.05e-3
k = 1e6
gamma0 = 1e-3
[design.materials.glass]
law = "tti"
radius = 1e-3
density = 2500.0
E = 63e9
nu = 0.22
damping = {model = "tsuji", e = 0.9}
[outputs]
e = ["numeric", "ord1"]
fields = ["status"]
[integrator]
steps = 16
"""

TEXTS = {"grid": GRID, "doe": DOE, "scene": SCENE, "mixed": MIXED}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A grid, a design-of-experiments and two scene outputs, made once for the module."""
    root = tmp_path_factory.mktemp("files")
    out = {}
    for name, text in TEXTS.items():
        out[name] = root / f"{name}.nc"
        runner.run(config.loads(text, source=f"{name}.toml"), out[name], quiet=True)
    return out


def expected(text):
    """Every stored variable computed with the api on the design's points (flat)."""
    cfg = config.loads(text)
    d = design.build(cfg.design)
    points = d.points(0, d.size)
    r = api.integrate(*points, **cfg.integrator.kwargs())
    out = {"e_numeric": r.e, **{f: getattr(r, f) for f in registry.integrator_fields()}}
    for m in cfg.outputs.approximations:
        out[f"e_{m}"] = api.cor(*points, method=m, **cfg.method_options(m))
        out[f"error_{m}"] = out[f"e_{m}"] - r.e
    return {k: out[k] for k in cfg.outputs.variables}


def test_fill_values_flags_and_dtypes(files):
    with netCDF4.Dataset(files["grid"]) as nc:
        for name in nc.variables:
            var = nc.variables[name]
            attrs = {k: var.getncattr(k) for k in var.ncattrs()}
            # _FillValue exactly on the variables that can hold NaN, in their own type
            if var.dtype.kind == "f" and name not in nc.dimensions:
                assert np.isnan(attrs["_FillValue"]) and attrs["_FillValue"].dtype == var.dtype
            else:
                assert "_FillValue" not in attrs, name
            assert "dtype" not in attrs, name                 # no non-CF bool marker
            if "flag_values" in attrs:                        # flags are categories
                assert "units" not in attrs, name
                assert attrs["flag_values"].dtype == var.dtype, name
            else:
                assert attrs["units"] == "1", name
        sticks, status = nc.variables["sticks"], nc.variables["status"]
        assert sticks.dtype == np.int8 and list(sticks.flag_values) == [0, 1]
        assert sticks.flag_meanings == "rebounds sticks"
        assert status.flag_meanings.split() == [s.name.lower() for s in registry.Status]
        assert nc.variables["n_steps"].dtype == np.int32
        assert nc.Conventions == store.CONVENTIONS == "CF-1.8"


def test_grid_axes_record_their_spacing(files):
    with xr.open_dataset(files["grid"]) as ds:
        assert {n: ds[n].attrs["spacing"] for n in ("alpha", "beta", "gamma", "gtilde")} == {
            "alpha": "single", "beta": "irregular", "gamma": "log", "gtilde": "linear"}
        np.testing.assert_allclose(np.diff(np.log(ds.gamma.values)), np.log(300) / 3)


@pytest.mark.parametrize("axis, spacing", [
    ("1e-3", "single"), ("[1e-3]", "single"), ("{start = 0.1, stop = 0.1, num = 1}", "single"),
    ("[0.1, 0.2, 0.3]", "irregular"), ("{values = [0.1, 0.2]}", "irregular"),
    ("{start = 0.1, stop = 0.2, num = 3}", "linear"),
    ("{start = 0.1, stop = 0.2, num = 3, spacing = \"log\"}", "log"),
])
def test_grid_spec_remembers_how_each_axis_is_spaced(axis, spacing):
    text = GRID.replace('gamma = {start = 1e-3, stop = 0.3, num = 4, spacing = "log"}',
                        f"gamma = {axis}")
    assert design.build(config.loads(text).design).spacing["gamma"] == spacing


def test_doe_point_dimension_is_indexed(files):
    with xr.open_dataset(files["doe"]) as ds:
        assert ds.indexes["point"].equals(xr.DataArray(np.arange(20)).to_index())
        assert ds.point.dtype == np.int32 and ds.point.attrs["units"] == "1"
        assert set(ds.coords) == {"point", "alpha", "beta", "gamma", "gtilde"}
        assert int(ds.isel(point=5).point) == 5


@pytest.mark.parametrize("kind", ["scene", "mixed"])
def test_scene_materials_are_named_by_an_auxiliary_coordinate(files, kind):
    # CF: a coordinate variable (named as its dimension) is numeric and monotonic; names
    # are a label (CF 6.1: characters), an auxiliary coordinate that the variables on
    # material list in their coordinates attribute.
    names = [m.name for m in config.loads(TEXTS[kind]).design.materials]
    with netCDF4.Dataset(files[kind]) as nc:
        assert "material" in nc.variables
        for dim in set(nc.dimensions) & set(nc.variables):
            values = nc.variables[dim][:]
            assert values.dtype.kind in "iuf", dim
            assert values.size < 2 or (np.all(np.diff(values) > 0)
                                       or np.all(np.diff(values) < 0)), dim
        labels = nc.variables["material_name"]
        assert labels.dtype == "S1" and labels.dimensions[0] == "material"
        assert list(labels[:]) == names          # netCDF4 joins the characters (_Encoding)
        for name, var in nc.variables.items():
            if "material" in var.dimensions and name not in ("material", "material_name"):
                assert "material_name" in var.getncattr("coordinates").split(), name
    with xr.open_dataset(files[kind]) as ds:
        assert "material_name" in ds.coords and ds.material.dtype.kind == "i"
        np.testing.assert_array_equal(ds.material.values, np.arange(len(names)))
        # The selection by name the README shows.
        by_name = ds.set_xindex("material_name").sel(material_name=names[-1])
        xr.testing.assert_equal(by_name.e_numeric.reset_coords(drop=True),
                                ds.e_numeric.isel(material=-1).reset_coords(drop=True))


#: Units of the per-material k and gamma0: a UDUNITS string where every material has the
#: same integer power of the metre, none (the rule in ``comment``) otherwise.
LAW_UNITS = {"scene": {"k": None, "gamma0": "s"}, "mixed": {"k": None, "gamma0": None}}


@pytest.mark.parametrize("kind", ["scene", "mixed"])
def test_law_dependent_units_are_written_only_where_udunits_can_say_them(files, kind):
    with xr.open_dataset(files[kind]) as ds:
        for name, units in LAW_UNITS[kind].items():
            attrs = ds[name].attrs
            assert attrs.get("units") == units, name
            if units is None:
                rule = {"k": "N m^-alpha", "gamma0": "s m^(alpha-beta)"}[name]
                assert rule in attrs["comment"], name


@pytest.mark.parametrize("alpha, beta, k, gamma0", [
    ([1.0], [1.0], "N m-1", "s"), ([2.0, 2.0], [1.0, 1.0], "N m-2", "s m"),
    ([1.5], [1.5], None, "s"), ([1.5], [1.0], None, None), ([1.5], [2.5], None, "s m-1"),
    ([1.0, 2.0], [1.0, 2.0], None, "s"),
])
def test_law_units_of_k_and_gamma0(alpha, beta, k, gamma0):
    attrs = store.law_units_attrs(np.array(alpha), np.array(beta))
    assert (attrs["k"].get("units"), attrs["gamma0"].get("units")) == (k, gamma0)
    for name, units in (("k", k), ("gamma0", gamma0)):
        assert ("comment" in attrs[name]) == (units is None), name


def _units():
    """cfunits' Units, or skip where cfunits or its UDUNITS-2 C library is missing."""
    try:
        from cfunits import Units
    except Exception as exc:
        pytest.skip(f"cfunits is not usable here ({type(exc).__name__}: {exc}); "
                    "pip install cfunits, and the UDUNITS-2 library (libudunits2-0)")
    return Units


@pytest.mark.parametrize("kind", list(TEXTS))
def test_every_units_attribute_is_udunits_valid(files, kind):
    Units = _units()
    with netCDF4.Dataset(files[kind]) as nc:
        units = {n: v.getncattr("units") for n, v in nc.variables.items()
                 if "units" in v.ncattrs()}
    assert units
    for name, text in units.items():
        assert Units(text).isvalid, (name, text)
        # SI and unscaled: UDUNITS has integer powers only, and reads "N m-1.5" as a valid
        # but different unit, 0.5 N m-1; a leading factor in its definition betrays that.
        definition = Units(text).formatted(definition=True)
        assert not re.match(r"[-+.\deE]+ ", definition), (name, text, definition)


@pytest.mark.parametrize("kind", ["grid", "doe", "scene", "mixed"])
@pytest.mark.parametrize("decoding", [{}, {"mask_and_scale": False}, {"decode_cf": False}],
                         ids=["default", "mask_and_scale=False", "decode_cf=False"])
def test_xarray_reads_back_exactly_what_was_computed(files, kind, decoding):
    want = expected(TEXTS[kind])
    with xr.open_dataset(files[kind], **decoding) as ds:
        for name, values in want.items():
            dtype = store.variable_spec(name)[0]
            assert ds[name].dtype == dtype, name         # no promotion of ints to float
            got = ds[name].values.reshape(-1)
            np.testing.assert_array_equal(got, values.astype(dtype), err_msg=name)


@pytest.mark.parametrize("decoding", [{}, {"mask_and_scale": False}, {"decode_cf": False}],
                         ids=["default", "mask_and_scale=False", "decode_cf=False"])
def test_nan_at_an_invalid_point_reads_back_as_nan(tmp_path, decoding):
    # A valid configuration has no invalid point (sp off its domain is refused): write one.
    d = design.build(config.loads(DOE).design)
    writer = store.NetCDFWriter(tmp_path / "nan.nc", d.layout(), ("e_ord1",))
    e = np.linspace(0.0, 1.0, d.size)
    e[[0, 7]] = np.nan
    writer.write(0, d.size, {"e_ord1": e}, dict(zip(config.PARAMETERS, d.points(0, d.size))))
    writer.close()
    with xr.open_dataset(tmp_path / "nan.nc", **decoding) as ds:
        np.testing.assert_array_equal(ds.e_ord1.values, e)       # NaN stays NaN, no others


def test_provenance_attributes(files):
    with xr.open_dataset(files["grid"]) as ds:
        a = ds.attrs
    command = f"sweep run grid.toml -o {files['grid']} --chunk-size 7"
    assert a["sweep_command"] == command
    assert a["history"] == f"{a['date_created']}: {command}"
    assert a["executor"].startswith("local")
    assert a["numba_num_threads"] == numba.get_num_threads()
    assert isinstance(a["numba_threading_layer"], str) and a["numba_threading_layer"]
    assert a["compile_time_s"] >= 0 and a["kernel_time_s"] > 0
    assert a["run_time_s"] >= a["kernel_time_s"]
    # points per second of warm kernel time (the warm-up that compiles is kept apart)
    assert math.isclose(a["points_per_second"], a["n_points"] / a["kernel_time_s"],
                        rel_tol=0.05)


def test_command_line_of_a_configuration_given_as_text(tmp_path):
    out = tmp_path / "t.nc"
    text = DOE.replace("n = 20", "n = 4")
    res = runner.run(config.loads(text), out, quiet=True, chunk_size=3)
    assert res.compile_seconds is not None
    with xr.open_dataset(out) as ds:
        assert ds.attrs["sweep_command"] == (
            f"sweep run <configuration text, see sweep_config> -o {out} --chunk-size 3")
        assert ds.attrs["sweep_config"] == text


def test_n_steps_fits_its_int32_storage():
    # n_steps exceeds max_steps by a few refinement steps at most; the registry bounds
    # max_steps well inside the int32 range.
    assert registry.FIELDS["n_steps"].dtype == np.int32
    numeric = registry.METHODS["numeric"]
    assert numeric.check_options({"max_steps": 2 ** 30})["max_steps"] == 2 ** 30
    with pytest.raises(ValueError, match="max_steps must be an integer in"):
        numeric.check_options({"max_steps": 2 ** 31})
    with pytest.raises(ValueError, match="max_steps"):
        api.integrate(1.5, 1.5, 0.1, 1.0, max_steps=2 ** 31)
    r = api.integrate(1.5, 1.5, np.array([0.01, 0.1]), 1.0, steps=16, max_steps=5)
    assert r.n_steps.dtype == np.int32 and (r.n_steps <= 5 + 3).all()
    assert (r.status == registry.Status.BUDGET_EXHAUSTED).all()


def test_info_shows_a_single_value_once(files):
    grid = store.summarize(files["grid"])
    assert "  alpha    = 1.5  stiffness" in grid
    assert "  gamma    [0.001, 0.3] (log)  scaled damping" in grid
    assert "  beta     [1, 1.5] (irregular)" in grid
    assert "rebounds: " in grid and "sticks: " in grid
    doe = store.summarize(files["doe"])
    assert "  beta     = 1.5  damping" in doe           # fixed by the design
    assert "  point " not in doe and "design point index" not in doe  # the index: see dims
    assert "point = 20" in doe


def test_info_names_a_scenes_materials(files):
    text = store.summarize(files["mixed"])
    assert "dimensions: material = 3, v0 = 2, F = 1  (6 points)" in text  # no strlen
    assert "  material_name steel, rubber, glass  material name" in text
    lines = text.splitlines()
    assert any(line.startswith("  k  ") for line in lines)
    assert not any(line.startswith("  material ") for line in lines)   # the index: dims


# --------------------------------------------------------------------------- cfchecker

_TABLE = ("<?xml version='1.0'?><{root}><version_number>none</version_number>"
          "<{date}>none</{date}></{root}>")


def _checker(tmp_path):
    """cfchecker's CFChecker: the CF version read from the file (as ``cfchecks -v auto``),
    local tables (no network)."""
    try:
        from cfchecker.cfchecks import CFChecker, CFVersion
    except Exception as exc:  # not installed, or cfunits without the UDUNITS-2 C library
        pytest.skip(f"cfchecker is not usable here ({type(exc).__name__}: {exc}); "
                    "pip install cfchecker, and the UDUNITS-2 library (libudunits2-0)")
    # The files use no standard_name, area type or region name: empty tables of each
    # replace the ones cfchecker would otherwise download. Every other CF rule applies.
    names = tmp_path / "standard_names.xml"
    names.write_text(_TABLE.format(root="standard_name_table", date="last_modified"))
    other = tmp_path / "table.xml"
    other.write_text(_TABLE.format(root="table", date="date"))
    return CFChecker(cfStandardNamesXML=str(names), cfAreaTypesXML=str(other),
                     cfRegionNamesXML=str(other), version=CFVersion(), silent=True)


def _counts(tmp_path, path):
    checker = _checker(tmp_path)
    checker.checker(str(path))
    return checker.get_total_counts(), checker.all_messages


@pytest.mark.parametrize("kind", list(TEXTS))
def test_cfchecker_finds_no_error_and_no_warning(files, tmp_path, kind):
    counts, messages = _counts(tmp_path, files[kind])
    assert (counts["FATAL"], counts["ERROR"], counts["WARN"]) == (0, 0, 0), messages
    assert any("CF-1.8" in m for m in messages)        # the version the file declares


def test_cfchecker_would_see_a_broken_file(files, tmp_path):
    # The check is not vacuous: a flag variable with one meaning too few is an error.
    broken = tmp_path / "broken.nc"
    broken.write_bytes(files["grid"].read_bytes())
    with netCDF4.Dataset(broken, "a") as nc:
        nc.variables["sticks"].flag_meanings = "rebounds"
    counts, _ = _counts(tmp_path, broken)
    assert counts["ERROR"] >= 1


# --------------------------------------------------------------------------- README

def test_readme_notebook_example_runs(tmp_path, monkeypatch):
    matplotlib = pytest.importorskip("matplotlib")
    pytest.importorskip("dask")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = readme.split("### In a notebook", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    try:
        exec(compile(code, "README.md (In a notebook)", "exec"), {})
    finally:
        plt.close("all")
    assert (tmp_path / "error_ord2_approx.png").stat().st_size > 0
