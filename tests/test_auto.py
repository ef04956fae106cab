"""method = "auto": the cheapest method whose validated error is within tol (sweep.auto)."""
import dataclasses
import warnings

import numpy as np
import pytest

import sweep
from sweep import auto, registry
from sweep.reports import error_model
from sweep.registry import SERVED_BY, Status
from sweep.sweeps import config

JUDGE_STEPS = 256.0


@pytest.fixture(scope="module")
def points_and_judge():
    """Random points in and out of the error model (exponents at its nodes and between
    them, gamma up to 3, g~ up to 300), with the fine-resolution integration as judge."""
    pts = [np.concatenate(x) for x in zip(error_model.random_points(1500, seed=7),
                                          error_model.random_points(1500, seed=8, on_nodes=False))]
    judge = sweep.integrate(*pts, steps=JUDGE_STEPS)
    coarse = sweep.cor(*pts)
    # Decided outcomes only, and not the few points so close to the stick / rebound boundary
    # that the integrator's own resolution decides them (the integrator is judged elsewhere).
    keep = np.isin(judge.status, (Status.OK, Status.STUCK, Status.AT_REST))
    keep &= np.abs(coarse - judge.e) < 1e-8
    assert keep.mean() > 0.98
    return [x[keep] for x in pts], judge.e[keep]


@pytest.mark.parametrize("tol", [1e-2, 1e-4, 1e-6])
def test_auto_is_within_tol_of_the_numerical_cor(points_and_judge, tol):
    pts, e_judge = points_and_judge
    out = sweep.cor_fields(*pts, method="auto", tol=tol)
    err = np.abs(out["e"] - e_judge)
    assert err.max() <= tol, (err.max(), np.argmax(err))
    used = out["method_used"]
    assert set(np.unique(used)) <= set(SERVED_BY.values())
    assert (used != SERVED_BY["numeric"]).mean() > 0.3      # the closed forms do serve
    # Outside the model (gamma > 1, g~ > 100, exponents > 3) the point is integrated.
    outside = (pts[2] > 1.0) | (pts[3] > 100.0) | (pts[0] > 3.0) | (pts[1] > 3.0)
    assert outside.any() and np.all(used[outside] == SERVED_BY["numeric"])


def test_auto_records_the_method_and_matches_it():
    gamma = np.array([1e-6, 1e-3, 0.5, 3.0])
    out = sweep.cor_fields(1.5, 1.5, gamma, 0.01, method="auto", tol=1e-3)
    names = {c: n for n, c in SERVED_BY.items()}
    for i, code in enumerate(out["method_used"]):
        name = names[int(code)]
        opts = {"tol": 1e-3} if name == "numeric" else {}   # auto's tol is the integrator's
        assert out["e"][i] == sweep.cor(1.5, 1.5, gamma[i], 0.01, method=name, **opts)
    assert out["method_used"][-1] == SERVED_BY["numeric"]
    assert sweep.cor(1.5, 1.5, 1e-6, 0.01, method="auto") == pytest.approx(1.0, abs=1e-5)
    with pytest.raises(ValueError, match="tol must be"):
        sweep.cor(1.5, 1.5, 0.1, 0.1, method="auto", tol=-1.0)


def test_auto_is_registered_but_not_an_approximation():
    m = registry.METHODS["auto"]
    assert m.composite and "auto" not in registry.approximations()
    assert registry.composites() == ("auto",)
    assert registry.method_fields()["method_used"][0] == "auto"
    cfg = config.loads('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\ngamma = 0.1\n'
                       'gtilde = 0.2\n[outputs]\ne = "all"\n')
    assert "auto" not in cfg.outputs.methods                # "all" leaves it out
    cfg = config.loads('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\ngamma = 0.1\n'
                       'gtilde = 0.2\n[outputs]\ne = ["auto"]\nfields = ["method_used"]\n'
                       '[options.auto]\ntol = 1e-3\n')
    assert cfg.outputs.composites == ("auto",) and cfg.method_options("auto") == {"tol": 1e-3}
    with pytest.raises(config.ConfigError, match="field of method 'auto'.*'method_used'"):
        config.loads('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\ngamma = 0.1\n'
                     'gtilde = 0.2\n[outputs]\ne = ["ord1"]\nfields = ["method_used"]\n')


def test_integrator_tol_is_passed_through_once_it_exists(monkeypatch):
    # When the "numeric" method gains a tol option, auto hands its tol to the integrator.
    seen = {}

    def kernel(alpha, beta, gamma, gtilde, **opts):
        seen.update(opts)
        return np.full(alpha.size, 0.5), np.zeros(alpha.size, dtype=np.int8)

    numeric = registry.METHODS["numeric"]
    tol_opt = registry.Option("tol", 1e-10, lambda v: v > 0, "a number > 0")
    monkeypatch.setitem(registry.METHODS, "numeric", dataclasses.replace(
        numeric, kernel=kernel, options=numeric.options + (tol_opt,)))
    codes = np.full(3, SERVED_BY["numeric"], dtype=np.int8)
    e, _ = auto.serve(*(np.full(3, x) for x in (1.5, 1.5, 0.1, 0.1)), codes, 1e-5, steps=64)
    assert seen["tol"] == 1e-5 and seen["steps"] == 64 and np.all(e == 0.5)


def test_error_model_file_and_codes(tmp_path):
    model = auto.default_model()
    assert set(model.methods) == set(registry.approximations())
    assert model.bound.shape == (model.alpha.size, model.beta.size,
                                 model.gamma_edges.size - 1, model.gtilde_edges.size - 1,
                                 len(model.methods))
    assert model.info["safety"] >= 2 and model.info["judge_steps"] >= 256
    x = np.array([1e-12, 3e-7, 0.02, 1.0])
    assert np.all(auto.decode(auto.encode(x)) >= x)          # codes never understate ...
    assert np.all(auto.decode(auto.encode(x)) < 10 ** (1 / 8) * x)   # ... by 1/8 decade
    assert auto.encode(np.inf) == auto.NO_BOUND and auto.decode(auto.NO_BOUND) == np.inf
    model.save(tmp_path / "m.npz")
    again = auto.ErrorModel.load(tmp_path / "m.npz")
    assert again.methods == model.methods and np.array_equal(again.bound, model.bound)
    # "sp" is Kuwabara-Kono only: no bound anywhere else.
    sp = model.methods.index("sp")
    b = model.bounds(np.array([1.5, 1.5]), np.array([1.5, 1.0]), np.full(2, 1e-3),
                     np.full(2, 0.1))
    assert np.isfinite(b[0, sp]) and np.isinf(b[1, sp])


def test_an_option_given_as_none_is_not_given():
    # steps=None reached auto's kernel as the default resolution, 96, "given": its
    # integrated points then took 96 steps instead of the resolution its tol chooses.
    gamma = np.array([1e-3, 1e-2, 0.1, 1.0])
    e = sweep.cor(1.5, 1.5, gamma, 1.0, method="auto", tol=1e-6)
    assert np.array_equal(sweep.cor(1.5, 1.5, gamma, 1.0, method="auto", tol=1e-6,
                                    steps=None), e)
    assert np.array_equal(sweep.cor(1.5, 1.5, gamma, 1.0, method="auto", tol=None),
                          sweep.cor(1.5, 1.5, gamma, 1.0, method="auto"))


@pytest.mark.parametrize("sub", [1, 2, 5])
def test_judged_points_counts_the_judges_samples(sub):
    # The memory check must count what the build judges: every node pair times the samples
    # of both axes, each axis 0, half its first edge, and every edge with sub - 1 points
    # between neighbours.
    def samples(edges):
        inner = [np.geomspace(a, b, sub + 1)[:-1] for a, b in zip(edges[1:-1], edges[2:])]
        return 2 + sum(x.size for x in inner) + 1

    expected = (len(error_model.ALPHA_NODES) * len(error_model.BETA_NODES)
                * samples(error_model.GAMMA_EDGES) * samples(error_model.GTILDE_EDGES))
    assert error_model.judged_points(sub) == expected


@pytest.mark.parametrize("sub, n_validate, bad", [(3, 0, "sub=3"), (1, 10**6, "n_validate=")])
def test_an_error_model_beyond_memory_is_refused_before_anything_runs(
        monkeypatch, tmp_path, sub, n_validate, bad):
    # A --sub of about 50 judged for hours and was then killed for memory (numpy only
    # refuses an array at once when it is past all memory).
    memory = error_model.judged_points(2) * error_model.BYTES_PER_POINT
    monkeypatch.setattr(error_model, "physical_memory", lambda: memory)

    def no_judging(*args, **kwargs):
        raise AssertionError("judged before the memory check")

    monkeypatch.setattr(error_model.api, "integrate", no_judging)
    monkeypatch.setattr(error_model.api, "cor", no_judging)
    with pytest.raises(ValueError, match=bad) as info:
        error_model.error_model_report(tmp_path / "m.npz", sub=sub, n_validate=n_validate,
                                       progress=False)
    assert "\n" not in str(info.value) and "in memory" in str(info.value)
    assert not (tmp_path / "m.npz").exists()


@pytest.mark.parametrize("point", [
    (1.0744502738094512, 1.1321252139894746, 3.874728675298467, 6.44268749505823e-12),
    (1.2095, 1.29876, 10.41064, 3.81e-12)])
def test_auto_integrates_again_where_its_estimate_is_above_tol(point):
    # Near grazing the march at tol = 1e-6 left the stick/rebound decision open (e = 0,
    # e_err 1.3e-5) and auto returned that 0, silently, where the bead leaves with e ~ 1e-6.
    from reference import dop853_cor

    ref = dop853_cor(*point)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = sweep.cor_fields(*point, method="auto", tol=1e-6)
    assert out["method_used"] == registry.SERVED_BY["numeric"]
    assert out["status"] == Status.OK and abs(out["e"] - ref.e) <= 1e-6


def test_auto_warns_where_it_cannot_vouch_for_tol():
    # tol below half an ulp of e (in [0.5, 1)): no estimate can be within it.
    with pytest.warns(RuntimeWarning, match="integrated by auto may miss tol=1e-17"):
        sweep.cor(1.5, 1.5, [0.01, 0.05], 0.1, method="auto", tol=1e-17)
