"""Lookup tables of a scene (sweep.tables, sweep.lookup) and their export."""
import csv
import json
import os

import numpy as np
import pytest

import sweep
from sweep import tables
from sweep.cli import main
from sweep.sweeps import config, runner

SCENE = """
title = "lookup test"
[design]
kind = "scene"
v0 = {start = 0.05, stop = 5.0, num = 25, spacing = "log"}
F = {start = 0.0, stop = 0.2, num = 6}
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
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("lookup") / "scene.nc"
    runner.run(config.loads(SCENE, source="lookup.toml"), path, quiet=True)
    return path


def test_lookup_is_within_its_stated_error(scene):
    table = tables.Table(scene)
    stated = table.error()
    assert stated["n_points"] == 2 * (97 * 21 - 25 * 6) and 0 < stated["max_abs"] < 1e-3
    rng = np.random.default_rng(3)
    n = 400
    v0 = 10 ** rng.uniform(np.log10(0.05), np.log10(5.0), n)
    F = rng.uniform(0.0, 0.2, n)
    mat = rng.choice(["steel", "bead"], n)
    got = sweep.lookup(scene, v0=v0, F=F, material=mat)
    assert np.all(np.abs(got - table.direct(v0, F, mat)) <= stated["max_abs"])
    # At the table's own nodes the lookup returns the stored values.
    assert table(table.v0[3], table.F[2], "bead") == table.values[1, 3, 2]


def test_lookup_is_monotone_where_e_is(scene):
    table = tables.Table(scene)
    assert np.all(np.diff(table.values, axis=2) < 0)        # e falls with the load here
    F = np.linspace(0.0, 0.2, 2001)
    for v0 in (0.05, 0.0731, 1.0, 4.99):
        assert np.all(np.diff(table(v0, F, "steel")) <= 0)


def test_lookup_refuses_what_it_cannot_answer(scene):
    with pytest.raises(ValueError, match="v0 = 6.0 is outside the table"):
        sweep.lookup(scene, v0=6.0, F=0.0, material="steel")
    with pytest.raises(ValueError, match="unknown material 'glass'"):
        sweep.lookup(scene, v0=1.0, F=0.0, material="glass")
    with pytest.raises(ValueError, match="material is required"):
        sweep.lookup(scene, v0=1.0, F=0.0)


def test_export_csv_and_npz(scene, tmp_path, capsys):
    assert main(["export", str(scene), "--csv", "-o", str(tmp_path / "t.csv")]) == 0
    assert "held-back points: max" in capsys.readouterr().out
    with open(tmp_path / "t.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["material", "v0 [m/s]", "F [N]", "gamma [1]", "gtilde [1]",
                       "e_numeric [1]"]
    assert len(rows) == 1 + 2 * 25 * 6
    table = tables.Table(scene)
    assert float(rows[1 + 25 * 6 + 6 + 1][5]) == table.values[1, 1, 1]
    assert main(["export", str(scene), "--npz", "-o", str(tmp_path / "t.npz"),
                 "--no-check"]) == 0
    with np.load(tmp_path / "t.npz", allow_pickle=False) as z:
        assert z["e_numeric"].shape == (2, 25, 6)
        np.testing.assert_array_equal(z["e_numeric"], table.values)
        assert list(z["material"]) == ["steel", "bead"]
        units = json.loads(str(z["units"]))
        assert units["v0"] == "m s-1" and units["gamma0"] == "s"
        assert units["k"] == "N m^-alpha"     # no UDUNITS string for N m^-1.5: the rule


def test_a_scene_file_written_before_material_name_still_reads(scene):
    # Such files held the names in the material coordinate itself.
    import xarray as xr

    with xr.open_dataset(scene) as ds:
        old = ds.load().swap_dims(material="material_name").drop_vars("material") \
            .rename(material_name="material")
    assert old.material.dtype.kind in "OU"
    table, new = tables.Table(old), tables.Table(scene)
    assert table.materials == new.materials == ["steel", "bead"]
    assert table(1.0, 0.1, "bead") == new(1.0, 0.1, "bead")


def _synthetic(v0, F, e, log_v0=False):
    """A scene dataset holding e on (v0, F) of one material ("a"), or on (material, v0, F)
    of materials "a", "b", ..., for tables' own checks."""
    import xarray as xr

    e = e[None] if e.ndim == 2 else e
    names = [chr(ord("a") + j) for j in range(e.shape[0])]
    ds = xr.Dataset(
        {"e_numeric": (tables.SCENE_DIMS, e),
         **{name: ("material", [value] * len(names)) for name, value in
            dict(m=0.154, k=3.6138e10, gamma0=1.5237e-6, alpha=1.5, beta=1.5).items()},
         "material_name": ("material", names), "g": 9.81},
        coords={"material": list(range(len(names))), "v0": v0, "F": F})
    if log_v0:
        ds["v0"].attrs["spacing"] = "log"
    return ds


def _two_pass_pchip(v0, F, e, vq, fq, log_v0):
    """The documented interpolant, the slow way: PCHIP along F on every v0 node, then
    PCHIP along v0 through all of them, for each query on its own."""
    from scipy.interpolate import PchipInterpolator

    x = np.log(v0) if log_v0 else v0
    out = []
    for v, f in zip(vq, fq):
        column = PchipInterpolator(F, e, axis=1)(f)
        out.append(PchipInterpolator(x, column)(np.log(v) if log_v0 else v))
    return np.array(out)


def test_a_query_costs_the_same_memory_whatever_the_table_size():
    import tracemalloc

    rng = np.random.default_rng(7)
    F = np.array([0.0, 0.1, 0.3, 0.35, 1.0])
    peaks = {}
    for n in (20, 400):
        v0 = np.sort(rng.uniform(0.01, 10.0, n))              # an irregular axis
        e = rng.uniform(0.2, 0.9, (n, F.size))                  # not monotone: slopes matter
        table = tables.Table(_synthetic(v0, F, e))
        vq, fq = rng.uniform(v0[0], v0[-1], 4000), rng.uniform(0.0, 1.0, 4000)
        vq[:4] = v0[0], v0[1], v0[-2], v0[-1]                    # both ends of the axis
        tracemalloc.start()
        got = table(vq, fq)
        peaks[n] = tracemalloc.get_traced_memory()[1] / vq.size
        tracemalloc.stop()
        want = _two_pass_pchip(v0, F, e, vq[:300], fq[:300], False)
        np.testing.assert_allclose(got[:300], want, rtol=1e-13, atol=1e-15)
    # Interpolating along every v0 node took ~100 bytes a node a query (40 kB here).
    assert peaks[400] < 1000 and peaks[400] < 1.5 * peaks[20], peaks


@pytest.mark.parametrize("n", [2, 3, 4, 7])
def test_short_axes_plateaus_and_collapses_interpolate_as_scipys_pchip(n):
    # Tables of two and three speeds (a line; one inner node), plateaus and exact zeros
    # (secants that vanish or change sign set a node's slope to 0), queries on the nodes.
    rng = np.random.default_rng(n)
    v0 = np.sort(rng.uniform(0.01, 10.0, n))
    F = np.array([0.0, 0.2, 0.25, 1.0])
    e = rng.uniform(0.2, 0.9, (n, F.size))
    e[n // 2:, 1:] = 0.0                                   # collapsed at high speed and load
    e[0, :] = e[1, :] if n > 2 else e[0, :]                # a plateau along v0
    vq = np.concatenate([v0, rng.uniform(v0[0], v0[-1], 200)])
    fq = rng.uniform(0.0, 1.0, vq.size)
    got = tables.Table(_synthetic(v0, F, e))(vq, fq)
    np.testing.assert_allclose(got, _two_pass_pchip(v0, F, e, vq, fq, False), rtol=1e-13,
                               atol=1e-15)


def test_each_query_reads_its_own_materials_table():
    rng = np.random.default_rng(11)
    v0, F = np.sort(rng.uniform(0.01, 10.0, 9)), np.array([0.0, 0.4, 0.5, 2.0, 3.0])
    e = rng.uniform(0.0, 1.0, (3, v0.size, F.size))
    vq, fq = rng.uniform(v0[0], v0[-1], 300), rng.uniform(0.0, 3.0, 300)
    names = np.array(["a", "b", "c"])[rng.integers(0, 3, 300)]
    got = tables.Table(_synthetic(v0, F, e))(vq, fq, names)
    for j, name in enumerate("abc"):
        sel = names == name
        np.testing.assert_allclose(got[sel], _two_pass_pchip(v0, F, e[j], vq[sel], fq[sel],
                                                             False), rtol=1e-13, atol=1e-15)


def test_a_log_axis_is_interpolated_in_log_v0():
    rng = np.random.default_rng(8)
    v0, F = np.geomspace(0.01, 10.0, 30), np.array([0.0, 0.5, 1.0])
    e = rng.uniform(0.2, 0.9, (30, 3))
    vq, fq = np.geomspace(0.0101, 9.9, 50), np.full(50, 0.7)
    got = tables.Table(_synthetic(v0, F, e, log_v0=True))(vq, fq)
    np.testing.assert_allclose(got, _two_pass_pchip(v0, F, e, vq, fq, True), rtol=1e-13)


def test_export_writes_csv_row_by_row(tmp_path):
    import tracemalloc

    v0, F = np.linspace(0.1, 10.0, 250), np.linspace(0.0, 1.0, 200)
    ds = _synthetic(v0, F, np.full((250, 200), 0.5))
    tracemalloc.start()
    tables.export(ds, tmp_path / "t.csv")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    with open(tmp_path / "t.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert len(rows) == 1 + 250 * 200
    assert rows[1 + 200 + 3] == ["a", repr(float(v0[1])), repr(float(F[3])), "0.5"]
    assert peak < 2e6, peak          # all 50,000 rows at once took ~30 MB


def test_export_writes_exactly_the_path_asked(scene, tmp_path, capsys):
    path = tables.export(scene, tmp_path / "t.csv", "npz")
    assert path == tmp_path / "t.csv" and not (tmp_path / "t.csv.npz").exists()
    with np.load(path, allow_pickle=False) as z:
        assert z["e_numeric"].shape == (2, 25, 6)
    out = tmp_path / "u.csv"
    assert main(["export", str(scene), "--npz", "-o", str(out), "--no-check"]) == 0
    assert capsys.readouterr().out == f"wrote {out}\n"
    assert out.exists() and not (tmp_path / "u.csv.npz").exists()


def test_export_check_of_a_variable_that_is_not_e_writes_nothing(scene, tmp_path, capsys):
    out = tmp_path / "t.csv"
    assert main(["export", str(scene), "--csv", "-o", str(out), "--variable", "gamma"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "variable must be a coefficient of restitution " \
        "e_<method>" in err and "got 'gamma'" in err
    assert not out.exists()
    with pytest.raises(SystemExit) as info:
        main(["export", str(scene), "--csv", "-o", str(out), "--variable", "e_numeric",
              "--no-check"])
    assert info.value.code == 2 and "--variable" in capsys.readouterr().err
    with pytest.raises(ValueError, match="no variable 'e_sp'; it has e_numeric"):
        tables.Table(scene, "e_sp")


def test_export_check_of_a_variable_not_held_lists_those_held(scene, tmp_path, capsys):
    # Audit F7: --variable e_nope listed every method the package knows (e_sp, e_auto,
    # ...), none of which this file holds: the scene stores e = ["numeric"] alone.
    out = tmp_path / "t.csv"
    assert main(["export", str(scene), "--csv", "-o", str(out), "--variable", "e_nope"]) == 1
    err = capsys.readouterr().err
    assert err.endswith(f"{scene}: the dataset has no variable 'e_nope'; it has e_numeric\n")
    assert err.count("\n") == 1 and not out.exists()


def test_lookup_refuses_strings_and_names_shapes(scene):
    with pytest.raises(ValueError, match=r"v0 must be a real number .*'1\.0' \(str\)"):
        sweep.lookup(scene, v0="1.0", F=0.0, material="steel")
    with pytest.raises(ValueError, match=r"F must be a real number"):
        sweep.lookup(scene, v0=1.0, F="0", material="steel")
    with pytest.raises(ValueError, match=r"shapes of v0 \(3,\), F \(2,\) do not broadcast"):
        sweep.lookup(scene, v0=[1.0, 2.0, 3.0], F=[0.0, 0.1], material="steel")
    with pytest.raises(ValueError, match=r"shapes of v0 \(2,\), material \(3,\)"):
        sweep.lookup(scene, v0=[1.0, 2.0], F=0.0, material=["steel"] * 3)
    table = tables.Table(scene)
    got = table(np.array([[1.0], [2.0]]), 0.1, ["steel", "bead", "steel"])
    assert got.shape == (2, 3) and got[1, 1] == table(2.0, 0.1, "bead")


@pytest.mark.parametrize("fmt", ["--npz", "--csv"])
def test_export_over_its_own_dataset_is_refused(scene, tmp_path, capsys, fmt):
    # `sweep export s.nc --npz -o s.nc` replaced the dataset by its export, exit 0.
    before = scene.read_bytes()
    link = tmp_path / "link.nc"
    link.symlink_to(scene)
    for out in (scene, link):
        assert main(["export", str(scene), fmt, "-o", str(out), "--no-check"]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is the dataset itself" in err
    assert scene.read_bytes() == before


def test_export_makes_the_output_directory(scene, tmp_path):
    # As `sweep run -o new/x.nc` does; export failed on a directory not yet there.
    out = tmp_path / "new" / "deeper" / "t.csv"
    assert main(["export", str(scene), "--csv", "-o", str(out), "--no-check"]) == 0
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert len(rows) == 1 + 2 * 25 * 6       # header, then one row per (material, v0, F)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (not Linux)")
@pytest.mark.parametrize("fmt", ["--csv", "--npz"])
def test_export_to_a_full_disk_names_the_output(scene, capsys, fmt):
    # Audit F7: "sweep export: error: scene.nc: [Errno 28] ..." blamed the dataset read.
    assert main(["export", str(scene), fmt, "-o", "/dev/full", "--no-check"]) == 1
    assert capsys.readouterr().err == "sweep export: error: /dev/full: No space left on device\n"


COLLAPSE = """
title = "the no-rebound speed inside a cell"
[design]
kind = "scene"
v0 = {start = 1e-4, stop = 1.0, num = 38, spacing = "log"}
F = 0.0
[design.materials.steel_ball]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[outputs]
e = ["numeric"]
"""


def test_the_stated_error_bounds_the_collapse_at_the_no_rebound_speed(tmp_path):
    # e rises like a square root from 0 at the no-rebound speed v_c (3.87e-4 m/s here),
    # which falls between the held-back points of its cell: there the lookup was 2.7 times
    # the held-back maximum, which was all the stated error was.
    path = tmp_path / "collapse.nc"
    runner.run(config.loads(COLLAPSE, source="collapse.toml"), path, quiet=True)
    table = tables.Table(path)
    err = table.error()
    assert err["collapse_cells"] == 1
    v0 = np.geomspace(1e-4, 1.0, 40001)
    p = {k: v[0] for k, v in table.properties.items()}
    gamma, gtilde = sweep.scale(p["m"], p["k"], p["gamma0"], v0, p["alpha"], p["beta"], g=9.81)
    true = sweep.cor(p["alpha"], p["beta"], gamma, gtilde, tol=1e-10)
    worst = np.max(np.abs(table(v0) - true))
    assert err["held_back_max_abs"] < 0.5 * worst <= 0.5 * err["max_abs"]
    assert err["max_abs"] == err["collapse_bound"] and err["where"]["v0"] > 3.87e-4
    assert err["away_max_abs"] < err["held_back_max_abs"]


def test_a_node_without_a_value_is_refused_naming_it(tmp_path, capsys):
    text = COLLAPSE.replace('v0 = {start = 1e-4, stop = 1.0, num = 38, spacing = "log"}',
                            "v0 = [1e-250, 1e-3, 1.0]").replace('"numeric"', '"ord2_numint"')
    path = tmp_path / "nan.nc"
    runner.run(config.loads(text, source="nan.toml"), path, quiet=True)   # g~ ~ 1e296 there
    with pytest.raises(ValueError, match=r"e_ord2_numint has no value \(nan\) at material "
                                         r"'steel_ball', v0 = 1e-250 m/s, F = 0 N"):
        sweep.lookup(path, v0=0.5)
    out = tmp_path / "t.npz"
    assert main(["export", str(path), "--npz", "-o", str(out)]) == 1
    assert "e_ord2_numint has no value" in capsys.readouterr().err and not out.exists()


def test_the_npz_carries_the_axes_spacing_and_the_stated_error(scene, tmp_path, capsys):
    out = tmp_path / "t.npz"
    assert main(["export", str(scene), "--npz", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "against e_numeric computed directly (the method's own error comes on top)" in said
    with np.load(out, allow_pickle=False) as z:
        assert json.loads(str(z["spacing"])) == {"v0": "log", "F": "linear"}
        stated = json.loads(str(z["lookup_error"]))
    assert stated == tables.Table(scene).error()          # the same floats, through JSON
    assert f"stated error {stated['max_abs']:.3g}" in said


def test_a_scalar_query_gives_a_float_as_cor_does(scene):
    one = sweep.lookup(scene, v0=0.3, F=0.1, material="steel")
    assert type(one) is float
    assert one == sweep.lookup(scene, v0=[0.3], F=[0.1], material=["steel"])[0]
    assert sweep.lookup(scene, v0=np.float64(0.3), F=0.1, material="bead").__class__ is float
    assert sweep.lookup(scene, v0=[0.3], F=0.1, material="bead").shape == (1,)


def test_a_table_of_one_node_a_material_states_no_interpolation(tmp_path, capsys):
    text = COLLAPSE.replace('v0 = {start = 1e-4, stop = 1.0, num = 38, spacing = "log"}',
                            "v0 = 1.0")
    path = tmp_path / "one.nc"
    runner.run(config.loads(text, source="one.toml"), path, quiet=True)
    assert tables.Table(path).error()["n_points"] == 0
    assert main(["export", str(path), "--npz", "-o", str(tmp_path / "one.npz")]) == 0
    assert "one node a material, nothing interpolated" in capsys.readouterr().out


def test_the_stated_collapse_bound_names_the_node_that_sets_it(tmp_path):
    path = tmp_path / "collapse.nc"
    runner.run(config.loads(COLLAPSE, source="collapse.toml"), path, quiet=True)
    table = tables.Table(path)
    err = table.error()
    j = int(np.nonzero(table.v0 == err["where"]["v0"])[0][0])
    assert table.values[0, j, 0] == err["max_abs"] > 0 and table.values[0, j - 1, 0] == 0


@pytest.mark.parametrize("axis", ["v0", "F"])
def test_a_node_given_twice_is_refused_naming_it(axis):
    # As a dataset joined from two scenes that share a boundary speed or load is.
    import xarray as xr

    v0, F = np.geomspace(0.01, 10.0, 6), np.array([0.0, 0.5, 1.0])
    ds = _synthetic(v0, F, np.linspace(0.9, 0.3, 18).reshape(6, 3), log_v0=True)
    cut = ds[axis].values[2]
    joined = xr.concat([ds.sel({axis: slice(None, cut)}), ds.sel({axis: slice(cut, None)})],
                       dim=axis, data_vars="minimal")
    unit = "m/s" if axis == "v0" else "N"
    with pytest.raises(ValueError, match=f"{axis} = {cut:g} {unit} is a node twice"):
        tables.Table(joined)
    assert tables.Table(joined.drop_duplicates(axis))(0.3, 0.7) == tables.Table(ds)(0.3, 0.7)


def test_only_a_query_within_float32_rounding_of_an_end_is_taken_at_it():
    v0, F = np.geomspace(1e-9, 1e3, 13), np.array([0.0, 0.5])
    e = np.linspace(0.99, 0.5, 26).reshape(13, 2)
    table = tables.Table(_synthetic(v0, F, e, log_v0=True))
    for low in (0.0, 1e-10, 6e-10, 1e-9 * (1 - 3e-7)):     # below the axis, near or far
        with pytest.raises(ValueError, match=f"v0 = {low!r} is outside the table"):
            table(low, 0.0)
    at_ends = table(np.float32([1e-9, 1e3]).astype(np.float64), np.float32([0.0, 0.5]))
    np.testing.assert_array_equal(at_ends, [e[0, 0], e[-1, -1]])
    with pytest.raises(ValueError, match="F = nan is not a number"):
        table(1.0, np.nan)
    # An end at 0 (a scene's F) keeps an allowance of the axis's other end: a load computed
    # as 0.3 - 0.1 - 0.2 is -2.8e-17 N.
    assert table(1.0, 0.3 - 0.1 - 0.2) == table(1.0, 0.0)
    with pytest.raises(ValueError, match="F = -0.001 is outside the table"):
        table(1.0, -1e-3)


def test_material_names_may_come_as_bytes_or_numpy_strings():
    rng = np.random.default_rng(5)
    v0, F = np.geomspace(0.01, 10.0, 7), np.array([0.0, 0.5, 1.0])
    table = tables.Table(_synthetic(v0, F, rng.uniform(0.1, 0.9, (2, 7, 3)), log_v0=True))
    vq, fq = rng.uniform(0.01, 10.0, 50), rng.uniform(0.0, 1.0, 50)
    names = np.array(["a", "b"])[rng.integers(0, 2, 50)]
    want = table(vq, fq, list(names))
    np.testing.assert_array_equal(table(vq, fq, names.astype("S")), want)
    np.testing.assert_array_equal(table(vq, fq, [n.encode() for n in names]), want)
    np.testing.assert_array_equal(table(vq, fq, "b"), table(vq, fq, ["b"] * 50))
    with pytest.raises(ValueError, match="unknown material 'c'"):
        table(vq, fq, np.where(np.arange(50) == 7, "c", names))


def test_an_exported_table_says_its_methods_settings_and_is_not_read_as_a_scene(scene,
                                                                               tmp_path):
    out = tmp_path / "t.npz"
    tables.export(scene, out)
    with np.load(out, allow_pickle=False) as z:
        settings = json.loads(str(z["settings"]))
    import xarray as xr

    with xr.open_dataset(scene) as ds:
        recorded = {k[len("integrator_"):]: v for k, v in ds.attrs.items()
                    if k.startswith("integrator_") and not isinstance(v, str)}
    assert set(settings) == {"e_numeric"} and recorded
    for key, value in recorded.items():                 # as the file's attributes say
        assert settings["e_numeric"][key] == pytest.approx(value), key
    with pytest.raises(ValueError, match="is an exported table, not a scene dataset"):
        tables.Table(out)


def test_queries_in_a_collapse_cell_can_be_computed_directly(tmp_path):
    # Near the no-rebound speed the interpolant is only within the cell's largest corner;
    # collapse="direct" gives those queries the method's own e, and leaves the rest as
    # interpolated.
    path = tmp_path / "collapse.nc"
    runner.run(config.loads(COLLAPSE, source="collapse.toml"), path, quiet=True)
    table = tables.Table(path)
    v0 = np.geomspace(1e-4, 1.0, 4001)
    p = {k: v[0] for k, v in table.properties.items()}
    gamma, gtilde = sweep.scale(p["m"], p["k"], p["gamma0"], v0, p["alpha"], p["beta"], g=9.81)
    true = sweep.cor(p["alpha"], p["beta"], gamma, gtilde, tol=1e-10)
    near = table.collapsing(v0)
    assert 0 < near.sum() < 400 and np.all(v0[near] < 1e-3)
    interpolated, direct = table(v0), table(v0, collapse="direct")
    assert np.max(np.abs(interpolated[near] - true[near])) > 1e-3
    assert np.max(np.abs(direct[near] - true[near])) < 1e-8
    np.testing.assert_array_equal(direct[~near], interpolated[~near])
    np.testing.assert_array_equal(direct[near], table.direct(v0[near], 0.0))
    assert np.array_equal(sweep.lookup(path, v0=v0, collapse="direct"), direct)
    with pytest.raises(ValueError, match=r"collapse = 'exact': must be one of 'interpolate', "
                                         r"'direct'"):
        table(0.5, collapse="exact")
    with pytest.raises(ValueError, match=r"collapse = array\(\['direct'\]"):
        table(0.5, collapse=np.array(["direct"]))


def test_a_query_is_in_a_collapse_cell_where_its_corners_hold_0_and_more():
    rng = np.random.default_rng(5)
    v0, F = np.sort(rng.uniform(0.01, 10.0, 8)), np.array([0.0, 0.3, 0.5, 1.0])
    e = rng.uniform(0.2, 0.9, (2, v0.size, F.size))
    e[0, 5:, 2:] = 0.0
    e[1, :2, :] = 0.0
    table = tables.Table(_synthetic(v0, F, e))
    vq = np.concatenate([rng.uniform(v0[0], v0[-1], 500), v0])
    fq = rng.uniform(0.0, 1.0, vq.size)
    names = np.array(["a", "b"])[rng.integers(0, 2, vq.size)]

    def naive(name, v, f):
        m = "ab".index(name)
        j = min(max(k for k in range(v0.size) if v0[k] <= v), v0.size - 2)
        k = min(max(k for k in range(F.size) if F[k] <= f), F.size - 2)
        corners = e[m, j:j + 2, k:k + 2]
        return corners.min() == 0.0 and corners.max() > 0.0
    want = np.array([naive(*q) for q in zip(names, vq, fq)])
    assert 0 < want.sum() < want.size
    np.testing.assert_array_equal(table.collapsing(vq, fq, names), want)
    assert table.collapsing(v0[6] + 0.01, 0.4, "a") is True
    assert table.collapsing(v0[6] + 0.01, 0.1, "a") is False
