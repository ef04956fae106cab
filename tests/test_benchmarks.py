"""benchmarks/run_all.py: one JSON line per figure of issue 10, well formed.

Runs the script in a subprocess on tiny sizes (``--quick``) and checks the structure of what
it prints and the pass/fail logic; never a timing (the values of a quick run mean nothing).
"""
import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "run_all.py"


def _load_run_all():
    spec = importlib.util.spec_from_file_location("run_all", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


run_all = _load_run_all()


def _run(*args, cache):
    res = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--cache-dir", str(cache),
                          *args], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return [json.loads(x) for x in res.stdout.splitlines() if x.strip()], res.stderr


def _script_lines(name, *args):
    """The stdout lines of ``benchmarks/<name>`` run with ``args`` (which must succeed)."""
    res = subprocess.run([sys.executable, str(ROOT / "benchmarks" / name), *args], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    return res.stdout.splitlines()


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    cache = tmp_path_factory.mktemp("ref-cache")
    lines, err = _run(cache=cache)
    return lines, err, cache


@pytest.mark.slow
def test_every_figure_once_in_order(quick_run):
    lines, _, _ = quick_run
    assert [x["name"] for x in lines] == list(run_all.TARGETS)


@pytest.mark.slow
def test_line_structure(quick_run):
    lines, _, _ = quick_run
    for x in lines:
        unit, target, sense, _ = run_all.TARGETS[x["name"]]
        assert x["unit"] == unit and x["target"] == f"{sense} {target:g}"
        assert isinstance(x["value"], float) and math.isfinite(x["value"]) and x["value"] > 0
        assert isinstance(x["pass"], bool) and x["quick"] is True
        assert isinstance(x["n"], int) and x["n"] >= 1
        assert isinstance(x["threads"], int) and x["threads"] >= 1
        assert {"cpu", "numba_threads", "threading_layer"} <= set(x["machine"])
        assert x["load_average"] >= 0
        ok = x["value"] >= target if sense == ">=" else x["value"] <= target
        if "error_target" in x:
            ok = ok and x["max_abs_error"] <= x["error_target"]
        assert x["pass"] == ok, x["name"]


@pytest.mark.slow
def test_law_lines_carry_error_figures(quick_run):
    lines, _, _ = quick_run
    laws = [x for x in lines if x["name"] in run_all.GROUPS["laws"]]
    assert len(laws) == 6
    for x in laws:
        assert x["n"] == run_all.QUICK["n"]
        assert x["error_points"] + x["error_undecided"] == run_all.QUICK["check"]
        assert x["error_points"] > 0 and 0 <= x["max_abs_error"] < 1e-3
        assert x["error_target"] == x["tol"] and x["compile_s"] >= 0
    sobol = {x["name"]: x for x in lines}["sobol_1m_threads_2v1"]
    assert sobol["value"] == pytest.approx(sobol["points_per_second_2"]
                                           / sobol["points_per_second_1"])
    fresh = {x["name"]: x for x in lines}["startup_compile_fresh"]
    assert {"numeric scalar", "numeric array", "auto array", "integrate general"} <= set(
        fresh["first_calls_s"])


@pytest.mark.slow
def test_reference_is_cached_and_reused(quick_run):
    _, err, cache = quick_run
    assert "DOP853 reference" in err
    assert len(list(Path(cache).glob("dop853_*.npz"))) == 1
    lines, err2 = _run("--only", "kk_tol1e-8", cache=cache)
    assert [x["name"] for x in lines] == ["kk_tol1e-8"]
    assert "DOP853 reference" not in err2          # every point came from the cache


def test_reference_cache_by_value(tmp_path, monkeypatch):
    calls = []

    def fake(p):
        calls.append(p)
        return p[2] + p[3]

    # The pool forks this process: count the calls through the cache file instead.
    monkeypatch.setattr(run_all, "_dop853_e", fake)
    monkeypatch.setattr(run_all.concurrent.futures, "ProcessPoolExecutor",
                        _SerialPool)
    pts = np.array([[1.5, 1.5, 0.1, 1.0], [1.5, 1.5, 0.2, 2.0]])
    np.testing.assert_array_equal(run_all.reference_e(pts, tmp_path), [1.1, 2.2])
    np.testing.assert_array_equal(run_all.reference_e(pts[::-1], tmp_path), [2.2, 1.1])
    assert len(calls) == 2                          # the second call read the cache
    more = np.vstack([pts, [[2.0, 1.0, 0.3, 3.0]]])
    np.testing.assert_array_equal(run_all.reference_e(more, tmp_path), [1.1, 2.2, 3.3])
    assert len(calls) == 3


class _SerialPool:
    def __init__(self, *args):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def map(self, fn, items, chunksize=1):
        return map(fn, items)


def test_pass_needs_the_target_and_the_error():
    line = run_all.line("kk_tol1e-8", 2e6, {}, 10, 2, error_ok=True)
    assert line["pass"] and "error_ok" not in line
    assert not run_all.line("kk_tol1e-8", 2e6, {}, 10, 2, error_ok=False)["pass"]
    assert not run_all.line("kk_tol1e-8", 9e5, {}, 10, 2)["pass"]
    assert run_all.line("startup_compile_fresh", 14.0, {}, 1, 2)["pass"]
    assert not run_all.line("startup_compile_fresh", 16.0, {}, 1, 2)["pass"]


def test_two_over_one_is_the_median_round_of_paired_runs():
    # Rounds as _sobol_run gives them: {threads: (points/s, wall, attrs)}.
    def run(rate, kernel_s):
        return (rate, 0.0, {"kernel_time_s": kernel_s})
    rounds = [{1: run(100.0, 10.0), 2: run(190.0, 5.0)},     # 1.90
              {1: run(100.0, 10.0), 2: run(150.0, 6.0)},     # 1.50, a noisy round
              {1: run(110.0, 9.0), 2: run(198.0, 5.0)}]      # 1.80
    x = run_all._two_over_one(rounds, {}, 1000)
    assert x["value"] == pytest.approx(1.8) and not x["pass"]
    assert x["ratios"] == [1.9, 1.5, 1.8]
    assert (x["points_per_second_1"], x["points_per_second_2"]) == (110.0, 198.0)
    assert x["kernels_2v1"] == pytest.approx(9.0 / 5.0)
    assert x["kernels_2v1_each"] == [2.0, pytest.approx(10 / 6, abs=1e-4), 1.8]
    even = run_all._two_over_one(rounds[:2], {}, 1000)    # the lower of two
    assert even["value"] == pytest.approx(1.5)


def test_draw_is_the_core_benchmarks():
    a, b, g, G = run_all.draw(1000, "kk")
    rng = np.random.default_rng(0)
    np.testing.assert_array_equal(g, 10 ** rng.uniform(-4, -0.5, 1000))
    np.testing.assert_array_equal(G, 10 ** rng.uniform(-3, 1, 1000))
    assert (a == 1.5).all() and (b == 1.5).all()
    a, b, g2, G2 = run_all.draw(1000, "general")
    np.testing.assert_array_equal(g2, g)             # same gamma, g~ draws
    assert 1 <= a.min() and a.max() <= 3 and 1 <= b.min() and b.max() <= 3
    assert run_all.LAWS["shc"] == (1.5, 2.5) and run_all.LAWS["hertz"] == (1.5, 1.0)


def test_unknown_figure_is_refused():
    with pytest.raises(SystemExit):
        run_all._selected(["nonsense"])
    assert run_all._selected(["gil", "kk_tol1e-8"]) == ["kk_tol1e-8", "gil_release"]


def test_error_model_script_prints_one_line_per_law_and_resolution():
    lines = _script_lines("error_model.py", "--n", "300", "--steps", "24", "48")
    assert len(lines) == 2 * 6
    errs = {}
    for line in lines:
        law, rest = line.split(maxsplit=1)
        steps = float(rest.split(":")[0].split("=")[1])
        errs[law, steps] = float(rest.split("max ")[1].split()[0])
    # Order 5: doubling the resolution lowers the largest error by far more than 2^2.
    for law in ("kk", "hertz", "shc", "tti", "linear", "general"):
        assert errs[law, 48.0] < errs[law, 24.0] / 4


@pytest.mark.parametrize("draw, laws", [((), 4), (("--heavy",), 6)])
def test_tol_margin_script_finds_the_estimate_a_bound(draw, laws):
    lines = _script_lines("tol_margin.py", "--n", "400", *draw)
    assert len(lines) == laws * (3 + 1 + 4)   # laws x (3 tolerances, defaults, 4 resolutions)
    for line in lines:
        # The largest true error over e_err: a bound at every tolerance and resolution.
        assert float(line.split(" max ")[1].split(";")[0]) < 1.0, line
    for line in (x for x in lines if "tol=" in x):
        # The largest errors left unrefined and after refinement, over tol.
        unrefined, final = line.rsplit("max err/tol ", 1)[1].split(", final ")
        assert float(unrefined) < 1.0 and float(final) < 1.0, line


def test_sticks_script_finds_the_probes_settle_sticks_within_tol():
    lines = _script_lines("sticks.py", "--n", "600", "--sobol-n", "1024")
    assert len(lines) == 5 * 2                    # 5 draws x 2 tolerances
    for line in lines:
        # Against steps=500, tol=1e-12: within tol, no stick/rebound decision changed.
        assert "decisions changed 0" in line, line
        assert float(line.split("max err/tol ")[1].split(",")[0]) < 1.0, line
    for line in (x for x in lines if x.startswith("kk damped")):
        # Heavily damped KK points all stick: the probes settle them for fewer steps.
        steps, without = (int(x.replace(",", "")) for x in
                          line.split("steps ")[1].split(" without")[0].split(" against "))
        assert steps < 0.8 * without, line


def test_step_cost_script_fits_a_cost_per_step():
    line = "\n".join(_script_lines("step_cost.py", "--n", "3000", "--repeat", "1")).strip()
    assert float(line.split(": ")[1].split(" ns per step")[0]) > 0.0, line
    n48, n192 = (float(x) for x in line.split("(")[1].split(" steps per point")[0].split(" and "))
    # Four times the resolution: about four times the steps (graded zone and events aside).
    assert 3.0 < n192 / n48 < 4.5, line


def test_approx_throughput_script_times_every_closed_form():
    lines = _script_lines("approx_throughput.py", "--n", "2000", "--repeat", "1")
    rows = {line.split(":")[0].strip(): line for line in lines
            if "points/s" in line}
    from sweep.kernels.approx import CODES
    assert set(rows) == set(CODES)
    for method, line in rows.items():
        # KK points of the core draw: every closed form defined, e in (0, 1).
        assert "invalid 0)" in line, line
        assert 0.0 < float(line.split("mean e ")[1].split(",")[0]) < 1.0, line


def test_hp_audit_script_finds_no_violation_on_a_small_draw():
    lines = _script_lines("hp_audit.py", "--n", "6", "--families", "d", "e", "--seed", "3")
    assert len(lines) == 2 * 4                    # 2 families x 4 settings
    for line in lines:
        # Light damping under huge loads, and alpha or beta = 1 / beta = alpha + 1: e_err
        # bounds the extended-precision reference's error at every setting.
        assert "'bound': 0, 'tol': 0, 'stick': 0, 'rebound': 0, 'nan': 0" in line, line
        assert float(line.rsplit("elsewhere ", 1)[1]) < 2.0, line


def test_writer_script_writes_the_sobol_values_and_names_each_choice():
    head, saves, *rows = _script_lines("writer.py", "--n", "2048", "--repeat", "1",
                                       "--compress", "small")
    assert "s of CPU a million points" in head and "MB raw" in head, head
    assert saves.startswith("resume saves: ") and "s of CPU a million points" in saves, saves
    assert "compress = 'small'" in head, head
    size, raw = (float(x.split(" MB")[0]) for x in head.split("file ")[1].split(" of "))
    assert 0 < size < raw, head                  # the e fields, flags and coordinates deflate
    how = dict(r.split(None, 1) for r in rows)
    assert {"e_numeric", "alpha", "gtilde", "status"} <= set(how)
    assert set(how.values()) <= {"stored", "deflate", "deflate + shuffle"}
