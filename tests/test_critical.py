"""sweep.critical: no-rebound thresholds g~_c and gamma_c, by (24) and by bisection on the
numerical CoR (the report's Figs. 8-11)."""
import warnings

import numpy as np
import pytest

import sweep
from sweep import critical as K
from sweep.model import Status


def test_approx_kuwabara_kono_law():
    gamma = np.array([1e-4, 1e-3, 1e-2, 0.1])
    # Prop. 1 for KK: g~_c = 0.30522 gamma^(-6/11)
    np.testing.assert_allclose(K.critical_gtilde(1.5, 1.5, gamma), 0.30522 * gamma ** (-6 / 11),
                               rtol=2e-5)
    # gamma_c and g~_c are inverse functions of each other
    gt = K.critical_gtilde(1.5, 1.5, gamma)
    np.testing.assert_allclose(K.critical_gamma(1.5, 1.5, gt), gamma, rtol=1e-14)


@pytest.mark.parametrize("alpha, beta", [(1.5, 1.0), (1.5, 1.25), (1.5, 2.5), (1.0, 1.0)])
def test_approx_is_where_large_gtilde_cor_vanishes(alpha, beta):
    from sweep.kernels.approx import approx_cor  # noqa: PLC0415

    gamma = 0.01
    gc = K.critical_gtilde(alpha, beta, gamma)
    e, _ = approx_cor("large_gtilde", np.full(2, alpha), np.full(2, beta), np.full(2, gamma),
                      np.array([gc * (1 - 1e-9), gc * (1 + 1e-9)]))
    assert 0 < e[0] < 1e-3 and e[1] == 0.0


def test_approx_limits_and_types():
    assert K.critical_gtilde(1.5, 1.5, 0.0) == np.inf
    assert K.critical_gamma(1.5, 1.5, 0.0) == np.inf
    assert isinstance(K.critical_gtilde(1.5, 1.5, 0.01), float)
    out = K.critical_gtilde(np.array([[1.5], [1.0]]), 1.5, [0.01, 0.1, 0.0])
    assert out.shape == (2, 3) and np.isinf(out[:, 2]).all()
    out = K.critical_gtilde([1.5, 0.5, 1.5], 1.5, [0.01, 0.01, np.nan])
    assert np.isfinite(out[0]) and np.isnan(out[1:]).all()


@pytest.mark.parametrize("call, name", [
    (lambda: K.critical_gtilde(0.5, 1.5, 0.01), "alpha"),
    (lambda: K.critical_gtilde(1.5, 1.5, -0.01), "gamma"),
    (lambda: K.critical_gamma(1.5, 0.2, 1.0), "beta"),
    (lambda: K.critical_gamma(1.5, 1.5, -1.0), "gtilde"),
    (lambda: K.critical_gamma(1.5, 1.5, np.inf), "gtilde"),
    (lambda: K.critical_gtilde(1.5, 1.5, 0.01, method="bisect"), "method"),
])
def test_scalar_invalid_raises_naming_argument(call, name):
    with pytest.raises(ValueError, match=name):
        call()


@pytest.mark.parametrize("call, named", [
    (lambda: K.critical_gtilde(1.5, 1.5, 0.01, steps=24), "method 'approx' takes no .*'steps'"),
    (lambda: K.critical_gamma(1.5, 1.5, 1.0, method="approx", tol=1e-6), "approx.*'tol'"),
    (lambda: K.critical_gtilde(1.5, 1.5, 0.01, method="numeric", step=24),
     "unknown option 'step' for method 'numeric'; allowed: tol, steps"),
])
def test_options_the_method_does_not_use_are_refused_naming_them(call, named):
    with pytest.raises(ValueError, match=named):
        call()


def test_numeric_gtilde_approaches_approx_as_gamma_vanishes():
    """Figs. 8-11: (24) is the small-gamma limit; the relative gap shrinks with gamma.

    Measured for KK: 0.62, 0.19, 0.023, 0.0028 at gamma = 0.3, 0.1, 0.01, 0.001.
    """
    gamma = np.array([0.1, 0.01, 0.001])
    num = K.critical_gtilde(1.5, 1.5, gamma, method="numeric")
    apx = K.critical_gtilde(1.5, 1.5, gamma)
    gap = apx / num - 1
    assert np.all(gap > 0) and np.all(np.diff(gap) < 0)
    assert gap[0] < 0.25 and gap[1] < 0.03 and gap[2] < 0.004
    # the bisection brackets the jump to e = 0 to 1e-8
    below = sweep.integrate(1.5, 1.5, gamma, num * (1 - 2e-8))
    at = sweep.integrate(1.5, 1.5, gamma, num)
    assert np.all(below.status == Status.OK) and np.all(below.e > 0)
    assert np.all(at.e == 0.0) and np.all(at.sticks)


def test_numeric_gamma_consistent_with_numeric_gtilde():
    gc = K.critical_gamma(1.5, 1.5, 10.0, method="numeric")
    assert isinstance(gc, float)
    assert gc == pytest.approx(0.0016529, rel=1e-4)
    assert K.critical_gtilde(1.5, 1.5, gc, method="numeric") == pytest.approx(10.0, rel=1e-6)
    assert sweep.cor(1.5, 1.5, gc * (1 - 2e-8), 10.0) > 0
    assert sweep.cor(1.5, 1.5, gc, 10.0) == 0.0


def test_numeric_invalid_and_zero_gamma_points():
    out = K.critical_gtilde([1.5, 1.5, 0.5], 1.5, [0.0, 0.05, 0.05], method="numeric")
    assert out[0] == np.inf and np.isfinite(out[1]) and np.isnan(out[2])


def test_numeric_passes_integrator_options():
    coarse = K.critical_gtilde(1.5, 1.5, 0.01, method="numeric", steps=24)
    fine = K.critical_gtilde(1.5, 1.5, 0.01, method="numeric")
    assert coarse == pytest.approx(fine, rel=1e-3)
    with pytest.raises(ValueError, match="steps"):
        K.critical_gtilde(1.5, 1.5, 0.01, method="numeric", steps=1)


def test_numeric_threshold_confirmed_by_dop853_reference():
    # An independent judge (scipy DOP853 with grazing detection, tests/reference.py) sees the
    # rebound stop within 1e-6 of the bisected g~_c.
    from reference import dop853_cor  # noqa: PLC0415

    gc = K.critical_gtilde(1.5, 1.5, 0.01, method="numeric")
    assert dop853_cor(1.5, 1.5, 0.01, gc * (1 - 1e-6)).e > 0
    assert dop853_cor(1.5, 1.5, 0.01, gc * (1 + 1e-6)).e == 0.0


def test_out_of_domain_exponents_give_nan_in_arrays():
    import numpy as np

    import sweep

    g = sweep.critical_gtilde(np.array([1.5, 0.5]), 1.5, 0.01)
    assert np.isfinite(g[0]) and np.isnan(g[1])
    c = sweep.critical_gamma(1.5, np.array([0.9, 1.5]), 1.0)
    assert np.isnan(c[0]) and np.isfinite(c[1])


def test_numeric_gamma_at_zero_load_follows_the_theory():
    """g~ = 0 (docs/creep.md, section 4): for 2 beta > alpha + 1 the bead always leaves (SHC,
    KK: gamma_c = inf; the bisection used to stop where e ~ 1/(gamma beta) fell below
    e_err, 8.95e9 for SHC); for 2 beta = alpha + 1 the motion has the constant damping ratio
    zeta = gamma sqrt(beta) / 2, so e = exp(-pi zeta / sqrt(1 - zeta^2)) > 0 exactly for
    zeta < 1 and gamma_c = 2 / sqrt(beta) (the bisection gave 1.99641 for the linear law)."""
    got = K.critical_gamma([1.5, 1.5, 1.0, 1.5], [2.5, 1.5, 1.0, 1.25], 0.0, method="numeric")
    assert got[0] == got[1] == np.inf
    assert got[2] == 2.0 and got[3] == pytest.approx(2.0 / np.sqrt(1.25), rel=1e-15)
    zeta = 0.999 * 1.0
    assert np.exp(-np.pi * zeta / np.sqrt(1 - zeta ** 2)) > 0.0   # still a rebound below 2
    # A load, and kappa > 0 (Hertz-like beta = 1): still the bisection.
    hertz = K.critical_gamma(1.5, 1.0, 0.0, method="numeric")
    assert np.isfinite(hertz) and sweep.cor(1.5, 1.0, 1.01 * hertz, 0.0) == 0.0


def test_numeric_threshold_far_below_the_approximation_is_found():
    # At g~ = 1e-9, (24) puts gamma_c of KK near 4e15; the bracket stopped 1e12 below it
    # and returned 0.0 (no rebound at any gamma) where the bead rebounds up to gamma ~ 25.
    # The independent judge (scipy DOP853, tests/reference.py) sees the rebound stop there.
    from reference import dop853_cor  # noqa: PLC0415

    gc = K.critical_gamma(1.5, 1.5, 1e-9, method="numeric")
    assert dop853_cor(1.5, 1.5, gc * (1 - 1e-3), 1e-9).e > 0
    assert dop853_cor(1.5, 1.5, gc * (1 + 1e-3), 1e-9).e == 0.0


def test_thresholds_beyond_1e154_and_subnormal_gamma():
    # Prop. 1 for KK, g~_c = 0.30522 gamma^(-6/11), is the small-gamma limit the bisection
    # approaches. At gamma = 1e-300 the bisection's midpoint sqrt(lo hi) overflowed (the
    # search returned NaN); at a subnormal gamma (24) itself overflowed in 1/gamma (inf,
    # for 6.8e175) and g~^r at g~ = 1e200 warned of an overflow.
    import warnings  # noqa: PLC0415

    gamma = np.array([1e-300, 5e-324])
    hand = 0.30522 * np.exp(-6 / 11 * np.log(gamma))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(K.critical_gtilde(1.5, 1.5, gamma), hand, rtol=2e-5)
        np.testing.assert_allclose(K.critical_gtilde(1.5, 1.5, gamma, method="numeric"),
                                   hand, rtol=2e-5)
        assert K.critical_gamma(1.5, 1.5, 1e200) == 0.0     # 1/(2 C 1e200^(11/6)) < 1e-324


def test_the_bracket_stops_at_the_top_of_gammas_domain(monkeypatch):
    # The bracket's top is read from the registry: with gamma's domain ending at 1e6, a
    # bead that rebounds all the way has gamma_c = inf, not NaN from trials above 1e6 (the
    # integrator's INVALID points, which decide nothing).
    import dataclasses

    from sweep import registry

    gamma = registry.PARAMETERS["gamma"]
    monkeypatch.setitem(registry.PARAMETERS, "gamma", dataclasses.replace(gamma, maximum=1e6))
    trials = []

    def always_rebounds(alpha, beta, gamma, gtilde, options):
        trials.append(np.asarray(gamma))
        ok = np.asarray(gamma) <= 1e6
        return ok, ok

    monkeypatch.setattr(K, "_rebounds", always_rebounds)
    assert K.critical_gamma(1.5, 1.5, 0.1, method="numeric") == np.inf
    assert max(t.max() for t in trials) == 1e6


def _linear_trough(gamma, gtilde):
    """u at the first trough after the maximum compression of the linear law (alpha = beta
    = 1, gamma < 2): u'' + gamma u' + u = g~, u(0) = 0, u'(0) = 1, solved in closed form.
    The bead sticks where u is still >= 0 there: the threshold is where it is 0."""
    import math
    zeta = gamma / 2.0
    wd = math.sqrt(1.0 - zeta * zeta)
    a, b = -gtilde, (1.0 - zeta * gtilde) / wd
    # u' = exp(-zeta t) (cos(wd t) - (zeta b + wd a) sin(wd t)): the maximum at t1, the
    # trough half a damped period later.
    t1 = math.atan2(1.0, zeta * b + wd * a) / wd
    t2 = t1 + math.pi / wd
    return gtilde + math.exp(-zeta * t2) * (a * math.cos(wd * t2) + b * math.sin(wd * t2))


@pytest.mark.parametrize("unknown, known", [("gamma", 1e-12), ("gamma", 1e-9),
                                            ("gtilde", 1.97), ("gtilde", 1.0)])
def test_numeric_thresholds_of_the_linear_law_at_tiny_rebounds(unknown, known):
    # The integrator's rest box (1e-8 by default) took rebounds of e up to ~1e-8 for rest:
    # gamma_c at g~ = 1e-12 came out 1.9715 for 1.9862, g~_c at gamma = 1.97 3.0e-9 for
    # 6.05e-9.
    from scipy.optimize import brentq

    if unknown == "gamma":
        exact = brentq(lambda g: _linear_trough(g, known), 1.5, 1.9999999, xtol=1e-15,
                       rtol=1e-14)
        got = K.critical_gamma(1.0, 1.0, known, method="numeric")
    else:
        exact = brentq(lambda gt: _linear_trough(known, gt), 1e-15, 10.0, xtol=1e-300,
                       rtol=1e-14)
        got = K.critical_gtilde(1.0, 1.0, known, method="numeric")
    assert got == pytest.approx(exact, rel=3e-8)


def test_an_undecided_search_warns_and_bad_options_are_refused_up_front():
    with pytest.warns(RuntimeWarning, match=r"1 threshold\(s\) undecided \(NaN\)"):
        assert np.isnan(K.critical_gtilde(1.5, 1.5, 0.01, method="numeric", max_steps=10))
    # gamma = 0 integrates nothing: the values were not checked at all.
    with pytest.raises(ValueError, match="tol"):
        K.critical_gtilde(1.5, 1.5, 0.0, method="numeric", tol=-1.0)
    with pytest.raises(ValueError, match="parallel"):
        K.critical_gtilde(1.5, 1.5, 0.0, method="numeric", parallel="yes")


def test_a_labelled_array_is_pointed_to_apply_ufunc():
    xr = pytest.importorskip("xarray")
    with pytest.raises(TypeError, match="apply_ufunc"):
        K.critical_gtilde(1.5, 1.5, xr.DataArray([0.01, 0.1], dims="gamma"))


def test_rest_tol_none_is_not_given_and_an_overflowing_start_is_the_top():
    # rest_tol=None brought the integrator's 1e-8 box back (36.8 for 80.0); a subnormal
    # gamma's (24) overflows, and the search gave NaN with a warning of a budget run out.
    assert K.critical_gamma(1.5, 1.5, 1e-12, method="numeric", rest_tol=None) == \
        pytest.approx(80.0316, rel=1e-5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert K.critical_gtilde(3.0, 1.0, 1e-310, method="numeric") == np.inf
