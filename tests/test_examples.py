"""The bouncing-ball example (sweep.examples, ``sweep example bounce``)."""
import csv
import math

import numpy as np
import pytest

from sweep import examples
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
