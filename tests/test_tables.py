"""Lookup tables of a scene (sweep.tables, sweep.lookup) and their export."""
import csv
import json

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
