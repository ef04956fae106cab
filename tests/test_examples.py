"""The bouncing-ball example (sweep.examples, ``sweep example bounce``)."""
import csv
import dataclasses
import math
import re

import numpy as np
import pytest

from sweep import examples
from sweep import cli
from sweep.cli import main


def _check_sequence(result):
    imps = result.impacts
    assert 1 < len(imps) < 10000 and "max_impacts" not in result.stop
    v = np.array([i.v for i in imps])
    e = np.array([i.e for i in imps])
    assert v[0] == pytest.approx(math.sqrt(2 * 9.81 * 1.0))
    # Energy m v^2 / 2 falls at every impact (0 <= e < 1) and the flights conserve it.
    assert np.all((e >= 0) & (e < 1))
    np.testing.assert_allclose(v[1:], (e * v)[:-1], rtol=1e-15)
    assert np.all(np.diff(v ** 2) < 0)
    # The sequence ends: no rebound, or a rebound slower than v_stop.
    assert e[-1] == 0.0 or e[-1] * v[-1] < 1e-5
    assert np.all(np.diff([i.t for i in imps]) > 0)


def test_bounce_direct_energy_falls_and_the_sequence_ends(tmp_path):
    res = examples.bounce_example(tmp_path, source="direct")
    _check_sequence(res["result"])
    assert res["result"].stop.startswith("no rebound")        # KK under gravity sticks
    names = sorted(p.rsplit("/", 1)[-1] for p in res["files"])
    assert names == ["bounce_height.png", "bounce_impacts.csv", "bounce_impacts.png"]
    with open(tmp_path / "bounce_impacts.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert len(rows) == 1 + len(res["result"].impacts)


def test_bounce_from_a_lookup_table_follows_the_direct_one(tmp_path):
    direct = examples.bounce_example(tmp_path / "d", source="direct")["result"]
    res = examples.bounce_example(tmp_path / "l", source="lookup")
    lookup = res["result"]
    _check_sequence(lookup)
    assert lookup.table_error["max_abs"] < 0.2
    n = min(len(direct.impacts), len(lookup.impacts)) - 5
    e_d = np.array([i.e for i in direct.impacts[:n]])
    e_l = np.array([i.e for i in lookup.impacts[:n]])
    np.testing.assert_allclose(e_l, e_d, atol=1e-4)


def test_cli_bounce_with_auto(tmp_path, capsys):
    assert main(["example", "bounce", "--out", str(tmp_path), "--method", "auto",
                 "--tol", "1e-3", "--height", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "impacts" in out and (tmp_path / "bounce_height.png").exists()


# --------------------------------------------------------------------------- bad input (QA2 §2)

@pytest.mark.parametrize("extra, expected", [
    (["--height", "-1"], "argument --height: must be a finite number > 0 [m], got '-1'"),
    (["--height", "0"], "argument --height: must be a finite number > 0 [m], got '0'"),
    (["--height", "nan"], "argument --height: must be a finite number > 0 [m], got 'nan'"),
    (["--height", "inf"], "argument --height: must be a finite number > 0 [m], got 'inf'"),
    (["--v-stop", "-1"], "argument --v-stop: must be a finite number > 0 [m/s], got '-1'"),
    (["--v-stop", "nan"], "argument --v-stop: must be a finite number > 0 [m/s], got 'nan'"),
    (["--tol", "0"], "argument --tol: must be a finite number > 0, got '0'"),
    (["--method", "bogus"], "argument --method: invalid choice: 'bogus'"),
    (["--method", "sp", "--tol", "1e-4"], "argument --tol: --method sp takes no tol"),
    (["--material", "nope"], "argument --material: needs --scene"),
    (["--cor", "lookup", "--method", "auto"], "argument --method: applies to --cor direct"),
    (["--cor", "lookup", "--tol", "1e-3"], "argument --tol: applies to --cor direct"),
    (["--table", "t.nc"], "argument --table: applies to --cor lookup only, got 't.nc'"),
    (["--cor", "lookup", "--v-stop", "10"],
     "argument --v-stop: must be < the first impact speed 4.42945 m/s"),  # sqrt(2 9.81 1)
    # QA scan: finite, but sqrt(2 g h0) is not ("v0 must be finite, got inf", exit 1)
    (["--height", "1e308"], "argument --height: h0 = 1e+308 m under g = 9.81 m/s^2"),
])
def test_cli_bounce_refuses_bad_options_in_one_line_naming_them(tmp_path, capsys, extra,
                                                                expected):
    # These ran with a wrong input, or ended in "unexpected ValueError: math domain error".
    out = tmp_path / "bx"
    with pytest.raises(SystemExit) as info:
        main(["example", "bounce", "--out", str(out)] + extra)
    err = capsys.readouterr().err.strip()
    assert info.value.code == 2 and len(err.splitlines()) == 1, err
    assert err.startswith("sweep example bounce: error: ") and expected in err, err
    assert "unexpected" not in err and not out.exists()


@pytest.mark.parametrize("extra", [
    [], ["--tol", "1e-4"], ["--method", "auto", "--tol", "1e-3"], ["--method", "sp"],
    ["--cor", "lookup", "--table", "t.nc", "--v-stop", "10"],
    ["--scene", "s.toml", "--material", "glass"], ["--height", "1e-3", "--v-stop", "1"],
])
def test_cli_bounce_accepts_the_combinations_that_count(extra):
    # numeric takes a tol too (sweep.registry): --tol is refused only where nothing uses it.
    args = cli.build_parser().parse_args(["example", "bounce"] + extra)
    assert cli._bounce_conflict(args) is None


def _never(v):
    raise AssertionError("the engine was called with a bad input")


@pytest.mark.parametrize("kw, expected", [
    (dict(h0=-1.0), "h0 must be a finite number > 0 [m], got -1.0"),
    (dict(h0=0.0), "h0 must be a finite number > 0 [m], got 0.0"),
    (dict(h0=math.nan), "h0 must be a finite number > 0 [m], got nan"),
    (dict(h0=True), "h0 must be a finite number > 0 [m], got True"),
    (dict(g=math.inf), "g must be a finite number > 0 [m/s^2], got inf"),
    (dict(v_stop=-1.0), "v_stop must be a finite number > 0 [m/s], got -1.0"),
    (dict(v_stop=math.nan), "v_stop must be a finite number > 0 [m/s], got nan"),
    (dict(max_impacts=0), "max_impacts must be an integer >= 1, got 0"),
    (dict(max_impacts=2.5), "max_impacts must be an integer >= 1, got 2.5"),
])
def test_bounce_names_a_bad_parameter(kw, expected):
    with pytest.raises(ValueError) as info:
        examples.bounce(_never, examples.STEEL_BALL, **kw)
    assert str(info.value) == expected


@pytest.mark.parametrize("kw, expected", [
    (dict(h0=-1.0), "h0 must be a finite number > 0 [m], got -1.0"),
    (dict(v_stop=math.nan), "v_stop must be a finite number > 0 [m/s], got nan"),
    (dict(method="bogus"), "method must be one of ('numeric', "),
    (dict(method="sp", tol=1e-4), "unknown option 'tol' for method 'sp'"),
    (dict(method="auto", tol=-1.0), "tol must be a number > 0"),
    (dict(source="nope"), "source must be 'direct' or 'lookup', got 'nope'"),
    (dict(source="lookup", method="auto"), "method and options apply to source='direct'"),
    (dict(source="lookup", tol=1e-3), "method and options apply to source='direct'"),
    (dict(table="t.nc"), "table applies to source='lookup' only, got 't.nc'"),
    (dict(source="lookup", v_stop=5.0), "v_stop must be < the first impact speed"),
])
def test_bounce_example_refuses_before_writing(tmp_path, kw, expected):
    out = tmp_path / "out"
    with pytest.raises(ValueError, match="^" + re.escape(expected)):
        examples.bounce_example(out, **kw)
    assert not out.exists()


def test_cli_bounce_names_itself_in_a_fault_of_the_input(tmp_path, capsys):
    # A missing scene file is the package's error, not argparse's: its line said
    # "sweep example: error:" where argparse's say "sweep example bounce: error:".
    assert main(["example", "bounce", "--out", str(tmp_path / "bx"),
                 "--scene", str(tmp_path / "missing.toml")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("sweep example bounce: error: ") and "missing.toml" in err, err
    assert len(err.splitlines()) == 1 and "unexpected" not in err


# --------------------------------------------------------------------------- a given lookup table

NARROW_TABLE = """
title = "steel ball, 5 cm/s to 5 m/s"
[design]
kind = "scene"
v0 = {start = 0.05, stop = 5.0, num = 40, spacing = "log"}
F = 0.0
[design.materials.steel_ball]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[outputs]
e = ["ord1"]
"""


@pytest.fixture(scope="module")
def narrow_table(tmp_path_factory):
    from sweep.sweeps import config, runner

    path = tmp_path_factory.mktemp("bounce") / "narrow.nc"
    runner.run(config.loads(NARROW_TABLE, source="narrow.toml"), path, quiet=True)
    return path


@pytest.mark.parametrize("kw, expected", [
    # v_stop = 1e-5 m/s: the bounce may meet speeds below the table's 0.05 m/s.
    (dict(), r"v0 = 1e-05 is outside the table \[0.05, 5\]; the bounce needs 'steel_ball' "
             r"at F = 0 and impact speeds \[v_stop, sqrt\(2 g h0\)\] = \[1e-05, 4.4294"),
    (dict(h0=2.0, v_stop=0.05), r"v0 = 6.264.* is outside the table"),     # sqrt(2 g 2 m)
    (dict(material=dataclasses.replace(examples.STEEL_BALL, name="glass"), v_stop=0.05),
     "unknown material 'glass'"),
])
def test_bounce_refuses_a_table_that_does_not_span_it_before_writing(tmp_path, narrow_table,
                                                                       kw, expected):
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=f"^lookup table {re.escape(str(narrow_table))}: "
                                         f"{expected}"):
        examples.bounce_example(out, source="lookup", table=narrow_table, **kw)
    assert not out.exists()


def test_cli_bounce_names_a_table_that_is_no_scene(tmp_path, capsys):
    # Audit F7: "error: not a scene dataset: dimensions (...)" named no file.
    from sweep.sweeps import config, runner

    grid = tmp_path / "grid.nc"
    runner.run(config.loads('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\n'
                            'gamma = 0.1\ngtilde = [0.1, 1.0]\n[outputs]\ne = ["ord1"]\n'),
               grid, quiet=True)
    out = tmp_path / "out"
    assert main(["example", "bounce", "--cor", "lookup", "--table", str(grid),
                 "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"sweep example bounce: error: lookup table {grid}: not a scene "
                          "dataset: ") and err.count("\n") == 1
    assert not out.exists()


def test_cli_bounce_with_a_narrow_table(tmp_path, narrow_table, capsys):
    out = tmp_path / "out"
    assert main(["example", "bounce", "--cor", "lookup", "--table", str(narrow_table),
                 "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("sweep example bounce: error: lookup table ") and \
        err.count("\n") == 1 and "outside the table" in err
    assert not out.exists()
    # With v_stop at the table's lowest speed every impact is inside it.
    assert main(["example", "bounce", "--cor", "lookup", "--table", str(narrow_table),
                 "--out", str(out), "--v-stop", "0.05"]) == 0
    with open(out / "bounce_impacts.csv", newline="") as f:
        speeds = [float(row[2]) for row in list(csv.reader(f))[1:]]
    assert speeds[0] == pytest.approx(math.sqrt(2 * 9.81)) and min(speeds) >= 0.05


@pytest.mark.parametrize("old, new, expected", [
    ("gamma0 = 1.5237e-6", "gamma0 = 1.5237e-5",
     r"its 'steel_ball' has gamma0 = 1.5237e-05, the bounce's bead gamma0 = 1.5237e-06"),
    ('kind = "scene"', 'kind = "scene"\ng = 1.62',
     r"it was computed under g = 1.62 m/s\^2, the bounce falls under g = 9.81 m/s\^2"),
])
def test_bounce_refuses_a_table_of_another_bead_or_gravity(tmp_path, old, new, expected):
    # The table was found by the material's name only: a scene's steel_ball with ten times
    # the damping (e = 0.30 at the first impact, the bounce's ball 0.88) or computed under
    # the Moon's g served every impact, silently, beside the bounce's own gamma and g~.
    from sweep.sweeps import config, runner

    path = tmp_path / "other.nc"
    text = NARROW_TABLE.replace(old, new).replace("start = 0.05", "start = 1e-5")
    runner.run(config.loads(text, source="other.toml"), path, quiet=True)
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=f"^lookup table {re.escape(str(path))}: {expected}"):
        examples.bounce_example(out, source="lookup", table=path)
    assert not out.exists()
