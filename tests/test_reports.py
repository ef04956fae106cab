"""Tests of the reports: accuracy maps, the report's tables/figures, speed against error.

Small inputs throughout (tiny datasets, a few dozen gamma values, coarse integrator
resolutions): the point is that the report code computes what it claims on the data it is
given, checked against obviously-correct slow recomputations.
"""
from __future__ import annotations

import argparse
import csv
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
import xarray as xr
from scipy.special import beta as beta_fn

import sweep
from sweep import cli, reports
from sweep.reports import paper_values as pv
from sweep.reports.accuracy import REGIONS, accuracy_report, load_errors
from sweep.reports.paper import (compute_sweeps, gamma_c_24, paper_gamma_grid, paper_report,
                                 table_rows)
from sweep.reports import peers, speed
from sweep.reports.speed import (PLAIN_DOP853, error_bound, scipy_user_cor, speed_report,
                                 time_at_error)

PNG = b"\x89PNG\r\n\x1a\n"


def _large_gtilde_c_r(alpha, beta):
    """C and r of (23), written out independently of sweep.kernels.approx."""
    r = beta / alpha + 1 / (2 * alpha) + 0.5
    c = (2 * math.sqrt(2) * (beta / alpha) * (alpha + 1) ** (beta / alpha + 1 / (2 * alpha))
         * beta_fn((beta + 0.5) / alpha, 1.5))
    return c, r


def _is_png(path):
    return path.exists() and path.stat().st_size > 1000 and path.read_bytes()[:8] == PNG


def _read_csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------- accuracy

@pytest.fixture(scope="module")
def grid_dataset(tmp_path_factory):
    """A tiny grid dataset in the store's layout, with known approximation errors."""
    alpha = np.array([1.5])
    beta = np.array([1.0, 1.5])
    gamma = np.array([0.0, 1e-3, 1e-2, 0.1, 0.3])
    gtilde = np.array([0.0, 0.01, 1.0, 5.0, 30.0])
    A, B, Gm, Gt = np.meshgrid(alpha, beta, gamma, gtilde, indexing="ij")
    r = sweep.integrate(A, B, Gm, Gt, steps=16)
    rng = np.random.default_rng(3)
    delta = 10.0 ** rng.uniform(-8, -1, A.shape)
    status = np.asarray(r.status).copy()
    e_ord1 = r.e + delta
    # one undecided point carrying a huge error: it must be excluded everywhere
    status[0, 1, 2, 2] = sweep.Status.BUDGET_EXHAUSTED
    e_ord1[0, 1, 2, 2] = r.e[0, 1, 2, 2] + 10.0
    dims = ("alpha", "beta", "gamma", "gtilde")
    ds = xr.Dataset(
        {"e_numeric": (dims, r.e), "sticks": (dims, r.sticks), "status": (dims, status),
         "e_ord1": (dims, e_ord1),
         "error_large_gtilde": (dims, -2.0 * delta)},
        coords={"alpha": alpha, "beta": beta, "gamma": gamma, "gtilde": gtilde},
        attrs={"title": "tiny grid"})
    path = tmp_path_factory.mktemp("acc") / "tiny.nc"
    ds.to_netcdf(path)
    return path, ds


def _slow_region_stats(ds, method):
    """Max and median abs error per (model, region) by explicit loops over all points."""
    out = {}
    for ia, a in enumerate(ds.alpha.values):
        for ib, b in enumerate(ds.beta.values):
            c, r = _large_gtilde_c_r(a, b)
            buckets = {reg: [] for reg in REGIONS}
            for ig, g in enumerate(ds.gamma.values):
                for it, G in enumerate(ds.gtilde.values):
                    idx = (ia, ib, ig, it)
                    if int(ds.status.values[idx]) not in (0, 1, 2):
                        continue
                    if f"error_{method}" in ds:
                        err = abs(float(ds[f"error_{method}"].values[idx]))
                    else:
                        err = abs(float(ds[f"e_{method}"].values[idx])
                                  - float(ds.e_numeric.values[idx]))
                    stick = bool(ds.sticks.values[idx])
                    gc = math.inf if g == 0 else (1 / (2 * g * c)) ** (1 / r)
                    buckets["all"].append(err)
                    buckets["stick" if stick else "rebound"].append(err)
                    if not stick and G > 0.5 * gc:
                        buckets["rebound, g~ > g~_c/2"].append(err)
                    elif not stick:
                        band = ("gamma <= 0.01" if g <= 0.01 else
                                "0.01 < gamma <= 0.1" if g <= 0.1 else "gamma > 0.1")
                        buckets[f"rebound, {band}, g~ <= g~_c/2"].append(err)
            for reg, v in buckets.items():
                out[(float(a), float(b), reg)] = ((max(v), float(np.median(v)), len(v))
                                                  if v else (None, None, 0))
    return out


def test_accuracy_report_grid(grid_dataset, tmp_path):
    path, ds = grid_dataset
    res = accuracy_report(path, tmp_path / "acc")
    names = {f.name for f in res["files"]}
    assert names == {"accuracy_ord1.png", "accuracy_large_gtilde.png", "accuracy.csv",
                     "accuracy.md"}
    assert _is_png(tmp_path / "acc" / "accuracy_ord1.png")
    assert _is_png(tmp_path / "acc" / "accuracy_large_gtilde.png")
    rows = _read_csv(tmp_path / "acc" / "accuracy.csv")
    assert len(rows) == 2 * 2 * len(REGIONS)          # methods x models x regions
    for method in ("ord1", "large_gtilde"):
        slow = _slow_region_stats(ds, method)
        for row in rows:
            if row["method"] != method:
                continue
            mx, med, n = slow[(float(row["alpha"]), float(row["beta"]), row["region"])]
            assert int(row["n_points"]) == n
            if n:
                assert float(row["max_abs_error"]) == pytest.approx(mx, rel=1e-12)
                assert float(row["median_abs_error"]) == pytest.approx(med, rel=1e-12)
            else:
                assert row["max_abs_error"] == ""
    # the undecided point (error 10) is excluded and counted
    kk_all = [r for r in rows if r["method"] == "ord1" and r["beta"] == "1.5"
              and r["region"] == "all"][0]
    assert int(kk_all["excluded"]) == 1
    assert float(kk_all["max_abs_error"]) < 1.0
    assert "| ord1 | 1.5 | 1.5 | all |" in (tmp_path / "acc" / "accuracy.md").read_text()


def test_accuracy_report_scattered(tmp_path):
    rng = np.random.default_rng(0)
    n = 240
    g = 10 ** rng.uniform(-3, -0.5, n)
    G = 10 ** rng.uniform(-2, 1.5, n)
    b = rng.choice([1.0, 2.5], n)
    r = sweep.integrate(1.5, b, g, G, steps=16)
    e2 = sweep.cor(1.5, b, g, G, method="ord2_approx")
    sp = sweep.cor(1.5, b, g, G, method="sp")          # NaN: not KK
    ds = xr.Dataset({"e_numeric": ("point", r.e), "sticks": ("point", r.sticks),
                     "e_ord2_approx": ("point", e2), "e_sp": ("point", sp)},
                    coords={"alpha": ("point", np.full(n, 1.5)), "beta": ("point", b),
                            "gamma": ("point", g), "gtilde": ("point", G)})
    path = tmp_path / "pts.nc"
    ds.to_netcdf(path)
    res = accuracy_report(path)                          # default output directory
    assert res["out"] == tmp_path / "pts_accuracy"
    assert _is_png(res["out"] / "accuracy_ord2_approx.png")
    assert _is_png(res["out"] / "accuracy_sp.png")
    rows = {(r["method"], r["beta"], r["region"]): r for r in res["rows"]}
    for bb in (1.0, 2.5):
        sel = b == bb
        row = rows[("ord2_approx", bb, "all")]
        assert row["n_points"] == sel.sum()
        assert row["max_abs_error"] == pytest.approx(np.max(np.abs(e2 - r.e)[sel]))
        assert rows[("sp", bb, "all")]["n_undefined"] == sel.sum()
        assert rows[("sp", bb, "all")]["max_abs_error"] is None


def test_accuracy_report_binned_exponents(tmp_path):
    """A design sampling the exponents: panels and rows per (alpha, beta) bin, hexbins."""
    from sweep.reports import accuracy as ra

    rng = np.random.default_rng(1)
    n = ra.HEXBIN_ABOVE * 4 + 400                    # > HEXBIN_ABOVE points per bin
    a = rng.uniform(1.0, 3.0, n)
    b = rng.uniform(1.0, 3.0, n)
    g = 10 ** rng.uniform(-4, 0, n)
    G = rng.uniform(0.0, 10.0, n)
    e_num = rng.uniform(0.0, 1.0, n) * (G < 5)       # synthetic values: the table is
    err = 10.0 ** rng.uniform(-9, -1, n)             # a function of the data only
    ds = xr.Dataset({"e_numeric": ("point", e_num), "error_ord1": ("point", err)},
                    coords={"alpha": ("point", a), "beta": ("point", b),
                            "gamma": ("point", g), "gtilde": ("point", G)})
    path = tmp_path / "doe.nc"
    ds.to_netcdf(path)
    res = accuracy_report(path, tmp_path / "doe")
    assert _is_png(tmp_path / "doe" / "accuracy_ord1.png")
    rows = [r for r in res["rows"] if r["region"] == "all"]
    assert len(rows) == 4                             # 2 alpha bins x 2 beta bins
    ma, mb = np.median(a), np.median(b)
    for r in rows:
        sel_a = a <= ma if r["alpha"].startswith("[") else a > ma
        sel_b = b <= mb if r["beta"].startswith("[") else b > mb
        sel = sel_a & sel_b
        assert r["n_points"] == sel.sum()
        assert r["max_abs_error"] == err[sel].max()
        assert r["median_abs_error"] == np.median(err[sel])
    stick = [r for r in res["rows"] if r["region"] == "stick"]
    assert sum(r["n_points"] for r in stick) == np.count_nonzero(e_num == 0)


def test_accuracy_report_needs_errors(tmp_path):
    ds = xr.Dataset({"e_numeric": ("point", np.ones(3))},
                    coords={p: ("point", np.ones(3)) for p in ("alpha", "beta", "gamma",
                                                               "gtilde")})
    with pytest.raises(ValueError, match="no approximation error"):
        load_errors(ds)


def _budget_config(fields):
    """A grid whose marches mostly run out of a tiny step budget (max_steps = 60)."""
    return {"design": {"kind": "grid", "alpha": 1.5, "beta": 1.5,
                       "gamma": {"start": 1e-3, "stop": 1.0, "num": 6, "spacing": "log"},
                       "gtilde": {"start": 1e-2, "stop": 10.0, "num": 5, "spacing": "log"}},
            "outputs": {"e": ["numeric", "ord1"], "fields": fields},
            "integrator": {"max_steps": 60}}


def test_accuracy_report_refuses_budget_points_it_cannot_exclude(tmp_path):
    """Budget-exhausted points have an upper bound for e_numeric: without status they
    cannot be excluded, so the report refuses instead of counting them as errors."""
    gamma, gtilde = np.meshgrid(np.geomspace(1e-3, 1.0, 6), np.geomspace(1e-2, 10.0, 5),
                                indexing="ij")
    ref = sweep.integrate(1.5, 1.5, gamma, gtilde, max_steps=60)
    n_budget = int(np.sum(ref.status == sweep.Status.BUDGET_EXHAUSTED))
    assert n_budget > 0
    with pytest.warns(sweep.CaveatWarning):
        sweep.run(_budget_config(["error_ord1"]), out=tmp_path / "nostatus.nc", quiet=True)
    with pytest.raises(ValueError, match=f"{n_budget} point.*no status"):
        accuracy_report(tmp_path / "nostatus.nc", tmp_path / "acc1")
    with pytest.warns(sweep.CaveatWarning):
        sweep.run(_budget_config(["status", "error_ord1"]), out=tmp_path / "status.nc",
                  quiet=True)
    rows = accuracy_report(tmp_path / "status.nc", tmp_path / "acc2")["rows"]
    all_row = [r for r in rows if r["region"] == "all"][0]
    assert all_row["excluded"] == n_budget
    assert all_row["n_points"] == gamma.size - n_budget


def test_report_out_that_is_a_file_is_one_line_naming_the_output(grid_dataset, tmp_path,
                                                                    capsys):
    """--out on the dataset itself or on another file: one line about the output, never
    "cannot read DATASET" (it was read), and the files are left as they were."""
    path, _ = grid_dataset
    before = path.read_bytes()
    assert cli.main(["report", "accuracy", str(path), "--out", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot read" not in err[0] and "dataset itself" in err[0]
    other = tmp_path / "taken.txt"
    other.write_text("keep")
    for argv in (["report", "accuracy", str(path), "--out", str(other)],
                 ["report", "paper", "--out", str(other), "--models", "kk", "-q"]):
        assert cli.main(argv) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"{other}: is a file, not an output directory" in err[0]
    assert path.read_bytes() == before and other.read_text() == "keep"


def test_paper_report_refused_arguments_leave_no_directory(tmp_path):
    with pytest.raises(ValueError, match="n_gamma"):
        paper_report(tmp_path / "never", n_gamma=1, models=["kk"])
    assert not (tmp_path / "never").exists()


# --------------------------------------------------------------------------- paper tables

def test_paper_values_match_spec_quotes():
    # SPEC section 5 quotes Table 4 (KK); the transcription must agree with it.
    kk = pv.TABLE_A["kk"]
    assert kk[0.0]["numint"] == (1.37e-5, 1.60e-3)
    assert kk[0.05]["numint"] == (1.52e-5, 1.78e-3)
    assert kk[1.0]["numint"] == (3.67e-4, 2.08e-1)
    assert kk[1.0]["approx"] == (4.58e-4, 2.09e-1)
    assert pv.TABLE_B["kk"]["numint"][:2] == (1.06e-7, 2.38e-4)
    assert pv.TABLE_B["kk"]["approx"][:2] == (8.11e-5, 2.11e-2)
    for key in pv.PAPER_MODELS:
        assert set(pv.TABLE_A[key]) == {0.0, 0.05, 1.0}
    # every None is explained
    explained = {(m, part, g, col.replace("edge1", "")) for (m, part, g, col)
                 in pv.TRANSCRIPTION_NOTES}
    for key, t in pv.TABLE_A.items():
        for g, cols in t.items():
            for col, pair in cols.items():
                if None in pair:
                    assert (key, "a", g, col) in explained
    for key, cols in pv.TABLE_B.items():
        for col, triple in cols.items():
            if None in triple:
                assert (key, "b", 10.0, col) in explained


@pytest.mark.parametrize("printed, entry", [
    # the report's cells as its copy prints them: a digit or an exponent is lost
    ("$.11 \\times 10^{-1}$", lambda: pv.TABLE_A["shc"][1.0]["numint"][1]),
    ("$.84 \\times 10^{-13}$", lambda: pv.TABLE_B["kk"]["numint"][2]),
])
def test_paper_values_leave_out_entries_whose_digits_are_lost(printed, entry):
    """An entry whose leading digit is not printed is unreadable, not a guess counted as
    reproduced (Table 5(a) SHC g~ = 1 was read as 3.11e-1, from the column beside it)."""
    assert printed.startswith("$.")
    assert entry() is None


@pytest.mark.parametrize("key", list(pv.PAPER_MODELS))
def test_paper_grid_reproduces_printed_window_edges(key):
    """The grid rule gives the report's printed g~ = 10 edges, digit for digit."""
    a, b = pv.PAPER_MODELS[key][:2]
    c, r = _large_gtilde_c_r(a, b)
    gamma, end = paper_gamma_grid(a, b, 10.0, 1000)
    assert end == pytest.approx(min(0.1, 1.1 / (2 * c * 10.0 ** r)), rel=1e-12)
    assert gamma_c_24(a, b, 10.0) == pytest.approx(1 / (2 * c * 10.0 ** r), rel=1e-12)
    assert gamma.size == 1000 and gamma[0] == 0.0 and gamma[-1] == end
    for printed, frac in zip(pv.TABLE_B_EDGES[key], pv.WINDOW_FRACTIONS):
        if printed is None:
            continue
        digits = len(repr(printed).split(".")[1]) if "e" not in repr(printed) else 5
        if key == "shc" and frac == 0.92:
            digits = 5                                   # printed "0.00020"
        assert round(frac * end, digits) == pytest.approx(printed, abs=1e-12)
    for G in (0.0, 0.05, 1.0):                           # the report's 0.02 edge
        _, end = paper_gamma_grid(a, b, G, 10)
        if not (key == "shc" and G == 1.0):
            assert pv.WINDOW_FRACTIONS[0] * end == pytest.approx(0.02)


@pytest.fixture(scope="module")
def small_sweeps():
    return compute_sweeps(models=["kk", "shc"], n_gamma=41, steps=16)


def test_paper_table_maxima_match_direct_computation(small_sweeps):
    sweeps = small_sweeps
    # the data are what the api gives on the report's grid
    d = sweeps[("shc", 1.0)]
    gamma, _ = paper_gamma_grid(1.5, 2.5, 1.0, 41)
    np.testing.assert_array_equal(d["gamma"], gamma)
    np.testing.assert_array_equal(d["numeric"], sweep.integrate(1.5, 2.5, gamma, 1.0,
                                                                steps=16).e)
    np.testing.assert_array_equal(d["approx"], sweep.cor(1.5, 2.5, gamma, 1.0,
                                                         method="ord2_approx"))
    rows = table_rows(sweeps)
    assert len(rows) == 2 * (3 * 2 * 4 + 1 * 2 * 3)      # models x (part a + part b)
    for row in rows:
        d = sweeps[(row["model"], row["gtilde"])]
        end = d["gamma"][-1]
        best = None
        for g, en, ec in zip(d["gamma"], d["numeric"], d[row["coefficients"]]):
            inside = {"low": g < 0.2 * end, "mid": 0.2 * end <= g <= 0.92 * end,
                      "high": g > 0.92 * end, "ge": g >= 0.2 * end}[row["window"]]
            if inside:
                err = abs(float(ec) - float(en))
                best = err if best is None else max(best, err)
        assert row["max_abs_error"] == best
    one = [r for r in rows if (r["model"], r["gtilde"], r["coefficients"], r["window"])
           == ("kk", 0.0, "numint", "low")][0]
    assert one["report"] == 1.37e-5 and one["table"] == "Table 4"
    one = [r for r in rows if (r["model"], r["gtilde"], r["coefficients"], r["window"])
           == ("shc", 10.0, "approx", "mid")][0]
    assert one["report"] == 2.50e-1


def test_paper_report_files(tmp_path):
    res = paper_report(tmp_path / "p", n_gamma=21, n_crit=6, models=["kk"], steps=16)
    out = tmp_path / "p"
    for name in ("paper_report.md", "paper_tables.csv", "paper_critical.csv",
                 "paper_sweeps.npz"):
        assert (out / name).exists(), name
    assert _is_png(out / "paper_figure10_kk.png")
    assert _is_png(out / "paper_errors_kk.png")
    md = (out / "paper_report.md").read_text()
    assert "Table 4: Kuwabara-Kono" in md and "1.37e-05" in md and "2.11e-02" in md
    rows = _read_csv(out / "paper_tables.csv")
    assert {r["table"] for r in rows} == {"Table 4"}
    # the summary, and nothing the user does not have (transcription notes, specs)
    assert res["summary"].startswith("Reproduced ") and res["summary"] in md
    assert "SPEC" not in md and "OCR" not in md
    crit = res["critical"]["kk"]
    # (24) is the small-gamma asymptote: close at gamma <= 0.01, worse at gamma = 1
    assert np.nanmax(crit["relerr_zoom"]) < 0.05
    assert crit["relerr"][-1] > 0.3
    np.testing.assert_allclose(crit["approx"], 0.30522 * crit["gamma"] ** (-6 / 11),
                               rtol=1e-4)
    # The CSV's two curves (main axes, gamma <= 0.01 inset) share gamma values: each row
    # says which it belongs to, and each curve's gamma increases.
    table = _read_csv(out / "paper_critical.csv")
    for curve, top in (("main", 1.0), ("inset", 0.01)):
        g = [float(r["gamma"]) for r in table if r["curve"] == curve]
        assert len(g) == 6 and g == sorted(g) and abs(g[-1] - top) < 1e-12, curve


def test_paper_step_budget_grows_with_steps():
    # --steps 300000 kept the budget at 200,000: every point ran out of it (e = 1, a bound)
    # and the tables were computed from those bounds.
    from sweep.reports import paper

    sweeps = compute_sweeps(["kk"], n_gamma=2, steps=300000)
    assert all(np.isin(d["status"], (sweep.Status.OK, sweep.Status.STUCK)).all()
               for d in sweeps.values())
    assert paper.step_budget(None) == paper.step_budget(96) == sweep.DEFAULT_MAX_STEPS
    assert paper.step_budget(300000) >= 5 * 300000          # marches took up to ~4.6 steps
    assert paper.step_budget(paper.MAX_STEPS) <= sweep.registry.MAX_STEP_BUDGET
    with pytest.raises(ValueError, match="steps must be <= 515,396"):
        paper.step_budget(paper.MAX_STEPS + 1)


def _paper_argv(out):
    return ["report", "paper", "--out", str(out), "--n-gamma", "5", "--n-crit", "2",
            "--models", "kk", "--steps", "16", "-q"]


def test_paper_points_out_of_budget_stop_the_report_before_it_writes(monkeypatch, capsys,
                                                                     tmp_path):
    # Before: the tables were written from budget-exhausted points, then raw RuntimeWarnings
    # and "unexpected ValueError: Axis limits cannot be NaN or Inf".
    from sweep.reports import paper

    monkeypatch.setattr(paper, "step_budget", lambda steps: 10, raising=False)
    out = tmp_path / "p"
    out.mkdir()
    (out / "paper_tables.csv").write_text("a previous run's")
    assert cli.main(_paper_argv(out)) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sweep report paper: error: ")
    # 36: gamma = 0 is decided without a march (e = 1), on the unshifted grid only
    assert "36 of 40 points of Tables 2-5 ran out of the step budget (10 steps" in err
    assert "no file was written" in err and "unexpected" not in err
    assert sorted(p.name for p in out.iterdir()) == ["paper_tables.csv"]
    assert (out / "paper_tables.csv").read_text() == "a previous run's"


def test_paper_g_c_out_of_budget_stops_the_report(monkeypatch, tmp_path):
    from sweep.reports import paper

    real = paper.critical_curves

    def one_undecided(*args, **kwargs):
        crit = real(*args, **kwargs)
        crit["kk"]["numeric_zoom"][0] = np.nan   # what critical_gtilde gives there
        return crit

    monkeypatch.setattr(paper, "critical_curves", one_undecided)
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # no RuntimeWarning of an all-NaN slice
        with pytest.raises(getattr(paper, "UndecidedError", ()),
                           match="1 of 4 g~_c values of Figures 8-11 ran out"):
            paper_report(tmp_path / "p", n_gamma=5, n_crit=2, models=["kk"], steps=16)
    assert list((tmp_path / "p").iterdir()) == []


def test_paper_report_failing_while_writing_leaves_no_new_file(monkeypatch, tmp_path):
    # The tables and the g~_c CSV were written before the figures: a figure that failed
    # left them beside the previous run's paper_report.md.
    from sweep.reports import paper

    def fails(*args):
        raise RuntimeError("cannot draw")

    monkeypatch.setattr(paper, "_error_figure", fails)
    out = tmp_path / "p"
    out.mkdir()
    (out / "paper_report.md").write_text("a previous run's")
    with pytest.raises(RuntimeError, match="cannot draw"):
        paper_report(out, n_gamma=5, n_crit=2, models=["kk"], steps=16)
    assert sorted(p.name for p in out.iterdir()) == ["paper_report.md"]
    assert (out / "paper_report.md").read_text() == "a previous run's"


def test_paper_reproduction_summary_counts_and_explains(monkeypatch, capsys):
    from sweep import cli
    from sweep.reports import paper

    def row(ours, report, shifted=None):
        return {"max_abs_error": ours, "report": report, "max_shifted": shifted,
                "ratio": ours / report if report else None}

    rows = [row(1.005e-3, 1e-3), row(0.0, 2.84e-13), row(2.5e-2, 2.5e-1),
            row(1.05e-3, 1e-3, 0.95e-3), row(1.05e-3, 1e-3, 1.06e-3), row(2e-3, 1e-3),
            row(1e-3, None)]
    rep = paper.reproduction(rows)
    assert (rep["n_published"], rep["n_reproduced"]) == (6, 1)
    assert rep["summary"] == (
        "Reproduced 1 of the report's 6 readable published maxima within 1% (ours / "
        "report); the other 5: 1 zero to rounding in both, 1 off by a power of ten (an "
        "apparent misprint), 1 bracketed by our two grids, 1 within 10%, 1 further off.")
    assert [why for _, why in rep["others"]][1] == (
        "ours is the report's times 1e-1: an apparent misprint of the exponent")
    # the command prints it last
    fake = {"markdown": "tables", "files": ["a.md"], "out": "p", "summary": rep["summary"]}
    monkeypatch.setattr(paper, "paper_report", lambda *a, **k: fake)
    assert cli.main(["report", "paper", "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == rep["summary"]


# --------------------------------------------------------------------------- speed

def test_time_at_error_interpolates_log_log():
    err = np.array([1e-3, 1e-6, 1e-9, 1e-12])
    t = 1e-4 * err ** -0.2                         # a power law: exact in log-log
    val, exact = time_at_error(err, t, 3e-8)
    assert exact and val == pytest.approx(1e-4 * 3e-8 ** -0.2, rel=1e-12)
    val, exact = time_at_error(err, t, 1e-14)      # below every measured error
    assert not exact and val == pytest.approx(t[-1])
    val, exact = time_at_error(err[::-1], t[::-1], 1e-1)
    assert not exact and val == pytest.approx(t[0])


def test_scipy_user_cor_agrees_with_integrator():
    for a, b, g, G in ((1.5, 1.5, 0.01, 0.1), (1.5, 1.0, 0.05, 0.0), (1.5, 2.5, 0.001, 2.0)):
        ref = sweep.integrate(a, b, g, G).e
        assert scipy_user_cor(a, b, g, G, "DOP853", 1e-11) == pytest.approx(ref, abs=1e-8)
    assert sweep.integrate(1.5, 1.5, 0.1, 2.0).sticks
    assert scipy_user_cor(1.5, 1.5, 0.1, 2.0, "RK45", 1e-6) == 0.0


def test_error_bound_says_which_side():
    err = [1e-3, 1e-6, 1e-9]
    assert error_bound(err, 1e-7) == ""
    assert error_bound(err, 1e-12) == ">"          # the peer never got there: lower bound
    assert error_bound(err, 1e-1) == "<"           # already more accurate: upper bound
    assert error_bound([math.nan], 1e-3) == "?"


def test_serial_numba_restores_the_thread_count():
    import numba

    before = numba.get_num_threads()
    with speed.serial_numba():
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before


_SMALL_PEERS = (("scipy", "RK45", (1e-4,)), ("scipy", "DOP853", (1e-6, 1e-9)),
                ("numbalsoda", "DOP853", (1e-8,)), ("diffrax", "Tsit5", (1e-8,)))


def test_speed_report_small(tmp_path, monkeypatch):
    # the optional peers as if absent: the report must skip them with a note
    monkeypatch.setattr(speed, "available_peers", lambda: {
        "numbalsoda": "not installed (test)", "diffrax": "not installed (test)"})
    titles = []
    import matplotlib.figure
    plain_suptitle = matplotlib.figure.Figure.suptitle
    monkeypatch.setattr(matplotlib.figure.Figure, "suptitle",
                        lambda fig, text, **kw: titles.append(text) or plain_suptitle(
                            fig, text, **kw))
    res = speed_report(tmp_path / "s", n_points=300, tols=(1e-4, 1e-8), steps_list=(24,),
                       ref_steps=128, n_check=2, n_peer=3, n_closed=3000, min_call_s=1e9,
                       repeat=1, peer_settings=_SMALL_PEERS)
    out = tmp_path / "s"
    for name in ("speed.md", "speed.csv", "speed_headline.csv"):
        assert (out / name).exists(), name
    assert _is_png(out / "work_precision.png")
    rows = res["rows"]
    engine = {r["setting"]: r for r in rows if r["kind"] == "engine"}
    assert set(engine) == {f"default (steps={sweep.DEFAULT_STEPS:g})", "tol=0.0001",
                           "tol=1e-08", "steps=24"}
    assert engine["tol=1e-08"]["max_abs_error"] < engine["tol=0.0001"]["max_abs_error"]
    assert engine["tol=1e-08"]["max_abs_error"] <= 1e-8        # the knob's promise
    approx = {r["setting"]: r for r in rows if r["kind"] == "approximation"}
    assert set(approx) == set(sweep.api.APPROXIMATIONS)
    # the closed forms are timed on the set tiled to n_closed points (min_call_s = 1e9)
    assert all(r["points"] == 3000 for r in approx.values())
    assert sum(r["kind"] == "peer" for r in rows) == 3
    assert len(res["skipped"]) == 2 and "numbalsoda DOP853: skipped" in res["skipped"][0]
    for r in rows:
        assert r["points_per_second"] == pytest.approx(1 / r["seconds_per_point"])
        assert r["cpu_seconds_per_point"] > 0 and r["failed"] == 0
    assert res["reference"]["crosscheck_max_diff"] < 1e-6
    assert res["reference"]["crosscheck"] == PLAIN_DOP853     # the package's own peer
    assert len(res["headline"]) == 4 * 2                       # engine settings x peers
    assert all(h["ratio_cpu"] > 0 and h["ratio_throughput"] > 0 for h in res["headline"])
    md = (out / "speed.md").read_text()
    assert "numba thread" in md and "solve_ivp DOP853" in md and "skipped" in md
    # The figure names only the peers that ran (it named diffrax on every machine).
    assert len(titles) == 1 and "diffrax" not in titles[0]


def test_peer_failures_count_as_error_one():
    bench = speed._Bench(1.5, 1.5, np.zeros(3), np.zeros(3), np.arange(3),
                         np.array([0.5, 0.5, np.nan]))
    timing = {"points": 3, "threads": 1, "cpu_seconds_per_point": 1.0,
              "points_per_second": 1.0}
    row = bench.row("peer", "p", "s", timing, None, np.array([0.5, np.nan, np.nan]))
    assert row["failed"] == 1 and row["subset_max_abs_error"] == 1.0


@pytest.mark.parametrize("tool", ["numbalsoda", "diffrax"])
def test_optional_peer_agrees_with_the_integrator(tool):
    pytest.importorskip(tool)
    a = np.array([1.5, 1.5, 1.5, 2.0])
    b = np.array([1.5, 1.0, 2.5, 1.2])
    g = np.array([0.01, 0.05, 0.001, 0.02])
    G = np.array([0.1, 0.0, 2.0, 0.5])
    ref = sweep.integrate(a, b, g, G).e
    e = peers.peer_cors(tool, {"rtol": 1e-10}, a, b, g, G)
    np.testing.assert_allclose(e, ref, atol=1e-7)
    assert sweep.integrate(1.5, 1.5, 0.1, 2.0).sticks         # a stick: e = 0 for the peer
    assert peers.peer_cors(tool, {"rtol": 1e-8}, [1.5], [1.5], [0.1], [2.0])[0] == 0.0


# --------------------------------------------------------------------------- CLI, imports

def test_add_report_commands(grid_dataset, tmp_path):
    parser = argparse.ArgumentParser(prog="sweep")
    sub = parser.add_subparsers(dest="command", required=True)
    cli.add_report_commands(sub)
    args = parser.parse_args(["report", "paper"])
    assert args.func is cli._cmd_paper and args.n_gamma == 1000 and args.models is None
    args = parser.parse_args(["report", "speed", "--n-points", "50", "--model", "shc"])
    assert args.func is cli._cmd_speed and args.n_points == 50 and args.model == "shc"
    with pytest.raises(SystemExit):
        parser.parse_args(["report", "paper", "--models", "nonsense"])
    args = parser.parse_args(["report", "accuracy", str(grid_dataset[0]), "--out",
                              str(tmp_path / "cli")])
    assert args.func(args) == 0
    assert (tmp_path / "cli" / "accuracy.md").exists()
    args = parser.parse_args(["report", "accuracy", str(tmp_path / "missing.nc")])
    assert args.func(args) == 1


def test_import_sweep_does_not_import_matplotlib():
    code = ("import sys, sweep, sweep.reports, sweep.reports.paper_values; "
            "sys.exit('matplotlib' in sys.modules or 'xarray' in sys.modules)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_machine_description_and_tables(tmp_path):
    m = reports.machine_description()
    assert m["numba_threads"] >= 1 and m["cpu"]
    assert m["threading_layer"] in ("tbb", "omp", "workqueue") or "unavailable" in \
        m["threading_layer"]
    md = reports.write_table([{"x": 1.5, "y": None, "z": 1.23456e-7}], ["x", "y", "z"],
                             tmp_path / "t.csv", tmp_path / "t.md",
                             formats={"x": "g"})
    assert "| 1.5 | - | 1.23e-07 |" in md
    assert _read_csv(tmp_path / "t.csv") == [{"x": "1.5", "y": "", "z": "1.23456e-07"}]


def test_paper_models_take_the_registrys_exponents(monkeypatch):
    # The report's laws live in sweep.registry.MODELS; the paper's tables name them only.
    import runpy

    from sweep import registry

    assert all(pv.PAPER_MODELS[k][:2] == registry.MODELS[k] for k in pv.PAPER_MODELS)
    monkeypatch.setitem(registry.MODELS, "tti", (1.5, 1.3))
    fresh = runpy.run_path(pv.__file__)
    assert fresh["PAPER_MODELS"]["tti"][:2] == (1.5, 1.3)
