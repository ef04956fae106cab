"""Scaling (2) and validation of physical inputs."""
import warnings

import numpy as np
import pytest

import sweep
from sweep.model import MODELS, damping_ratio, equilibrium, natural_frequency


def _scale_by_hand(m, k, gamma0, v0, alpha, beta, g, F):
    # Substituting x = -delta u, t = T tau into (1): the u^alpha coefficient
    # k T^2 delta^(alpha-1) / m is 1 by the choice of T, the rest is read off.
    T = (m / (k * v0 ** (alpha - 1))) ** (1 / (alpha + 1))
    delta = v0 * T
    assert k * T**2 * delta ** (alpha - 1) / m == pytest.approx(1.0, rel=1e-12)
    gamma = k * gamma0 * T * delta ** (beta - 1) / m
    gtilde = (g + F / m) * T**2 / delta
    return gamma, gtilde


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("v0", [0.01, 1.0, 7.3])
def test_scale_matches_substitution(name, v0):
    alpha, beta = MODELS[name]
    args = dict(m=2.05e-3, k=9.858e9, gamma0=3e-6, v0=v0, alpha=alpha, beta=beta, g=9.81, F=0.3)
    got = sweep.scale(**args)
    want = _scale_by_hand(**args)
    assert got == pytest.approx(want, rel=1e-12)


def test_scale_broadcasts():
    gamma, gtilde = sweep.scale(0.154, 3.6138e10, 1.5237e-6, np.array([[0.1], [1.0]]), 1.5, 1.5,
                                F=np.array([0.0, 10.0, 100.0]))
    assert gamma.shape == gtilde.shape == (2, 3)
    assert np.all(np.diff(gtilde, axis=1) > 0)   # more load, larger g~
    assert np.all(gamma[:, 0] == gamma[:, 1])    # the load does not enter gamma


@pytest.mark.parametrize("kwargs, name", [
    (dict(m=0.0), "m"), (dict(m=-1.0), "m"), (dict(k=0.0), "k"), (dict(v0=0.0), "v0"),
    (dict(v0=-2.0), "v0"), (dict(gamma0=-1e-9), "gamma0"), (dict(alpha=0.9), "alpha"),
    (dict(beta=0.5), "beta"), (dict(m=np.nan), "m"), (dict(k=np.inf), "k"),
    (dict(g=np.nan), "g"), (dict(F=-10.0), "g + F/m"),
])
def test_scale_rejects_bad_input_naming_it(kwargs, name):
    args = dict(m=0.154, k=3.6138e10, gamma0=1.5237e-6, v0=1.0, alpha=1.5, beta=1.5)
    args.update(kwargs)
    with pytest.raises(ValueError, match=name.replace("+", r"\+")):
        sweep.scale(**args)


def test_scale_rejects_bad_element_of_array():
    with pytest.raises(ValueError, match=r"v0 .*-1\.0"):
        sweep.scale(0.154, 3.6138e10, 1.5237e-6, np.array([1.0, -1.0]), 1.5, 1.5)


def test_regime_numbers():
    assert equilibrium(1.5, 8.0) == pytest.approx(4.0)
    assert natural_frequency(1.0, 3.0) == pytest.approx(1.0)
    # Linear spring-dashpot: xi = gamma / 2 whatever the load.
    assert damping_ratio(1.0, 1.0, 0.3, 5.0) == pytest.approx(0.15)


@pytest.mark.parametrize("call, named", [
    (lambda: equilibrium(0.5, 1.0), r"alpha must be >= 1.*got 0\.5"),
    (lambda: equilibrium(1.5, np.nan), "gtilde must be finite, got nan"),
    (lambda: equilibrium("1.5", 1.0), "alpha must be a real number.*'1.5'"),
    (lambda: natural_frequency(1.5, -1.0), r"gtilde must be >= 0.*got -1\.0"),
    (lambda: natural_frequency(1.5, [1.0, -2.0]), r"gtilde must be >= 0.*got -2\.0"),
    (lambda: damping_ratio(1.5, 0.9, 0.1, 1.0), r"beta must be >= 1.*got 0\.9"),
    (lambda: damping_ratio(1.5, 1.5, -1.0, 1.0), r"gamma must be >= 0.*got -1\.0"),
    (lambda: damping_ratio([1.5, 1.5], 1.5, [0.1, 0.2, 0.3], 1.0),
     r"shapes of alpha \(2,\), gamma \(3,\) do not broadcast"),
])
def test_regime_numbers_refuse_bad_input_naming_it(call, named):
    with pytest.raises(ValueError, match=named):
        call()


def test_regime_numbers_of_arrays_match_the_formulas():
    alpha, beta = np.array([1.0, 1.5, 1.5]), np.array([1.0, 1.5, 2.5])
    gamma, gtilde = 0.2, np.array([[0.5], [3.0]])
    np.testing.assert_allclose(equilibrium(alpha, gtilde), gtilde ** (1 / alpha), rtol=1e-15)
    np.testing.assert_allclose(natural_frequency(alpha, gtilde),
                               np.sqrt(alpha) * gtilde ** ((alpha - 1) / (2 * alpha)),
                               rtol=1e-15)
    np.testing.assert_allclose(
        damping_ratio(alpha, beta, gamma, gtilde),
        gamma * beta / (2 * np.sqrt(alpha)) * gtilde ** ((2 * beta - alpha - 1) / (2 * alpha)),
        rtol=1e-14)


KK = dict(alpha=1.5, beta=1.5)


@pytest.mark.parametrize("kwargs, quantity, named", [
    # g~ = (m/k)^(2/5) v0^(-6/5) (g + F/m): v0^(-6/5) = 1e360 at v0 = 1e-300.
    (dict(m=0.154, k=3.6138e10, gamma0=1.5237e-6, v0=1e-300), "gtilde", "v0=1e-300"),
    # gamma = gamma0 v0^(1/5) (k/m)^(2/5) = 1e300 * (1e300)^(2/5) = 1e420.
    (dict(m=1.0, k=1e300, gamma0=1e300, v0=1.0), "gamma", "gamma0=1e+300"),
    # g + F/m = 1e308 + 1e308 / 0.154 > the largest double.
    (dict(m=0.154, k=3.6138e10, gamma0=1e-6, v0=1.0, g=1e308, F=1e308), "g + F/m",
     "F=1e+308"),
])
def test_scale_refuses_a_result_beyond_double_precision(kwargs, quantity, named):
    with warnings.catch_warnings():
        warnings.simplefilter("error")        # no numpy RuntimeWarning may leak either
        with pytest.raises(ValueError) as info:
            sweep.scale(**kwargs, **KK)
    msg = str(info.value)
    assert msg.startswith(f"{quantity} overflows to inf") and named in msg
    assert "\n" not in msg
    # inside an array too, naming the element's own values
    args = {**kwargs, "v0": np.array([1.0, kwargs["v0"]])}
    with pytest.raises(ValueError, match=quantity.replace("+", r"\+") + " overflows"):
        sweep.scale(**args, **KK)


def test_scale_is_exact_where_only_an_intermediate_leaves_double_range():
    # m = 1e-300, k = 1e300: k/m = 1e600 overflows, m/k = 1e-600 underflows, yet
    # gamma = 1e-6 (1e600)^(2/5) = 1e234 and g~ = (1e-600)^(2/5) 9.81 = 9.81e-240 are doubles.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gamma, gtilde = sweep.scale(m=1e-300, k=1e300, gamma0=1e-6, v0=1.0, **KK)
    assert gamma == pytest.approx(1e234, rel=1e-12)
    assert gtilde == pytest.approx(9.81e-240, rel=1e-12)


def test_scale_underflow_to_zero_is_a_valid_result():
    # g~ = (m/k)^(2/5) v0^(-6/5) g ~ 1e-365 at v0 = 1e300: below the smallest double, 0,
    # which is a valid g~ (no load to speak of); gamma = 1e-6 * 1e60 * (2.3e11)^(2/5).
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gamma, gtilde = sweep.scale(m=0.154, k=3.6138e10, gamma0=1e-6, v0=1e300, **KK)
    assert gtilde == 0.0
    assert gamma == pytest.approx(1e-6 * 1e60 * (3.6138e10 / 0.154) ** 0.4, rel=1e-12)


def test_scale_names_parameters_whose_shapes_do_not_broadcast():
    with pytest.raises(ValueError, match=r"^the shapes of m \(2,\), v0 \(3,\) do not "
                                         r"broadcast together"):
        sweep.scale(np.array([0.1, 0.2]), 1e9, 1e-6, np.array([1.0, 2.0, 3.0]), 1.5, 1.5)


@pytest.mark.parametrize("value", ["0.154", True, None, 0.154 + 0j])
def test_scale_refuses_non_numbers_naming_them(value):
    with pytest.raises(ValueError, match=r"^m must be a real number .*got " + repr(value)
                       .replace("(", r"\(").replace(")", r"\)").replace("+", r"\+")):
        sweep.scale(value, 3.6138e10, 1.5237e-6, 1.0, 1.5, 1.5)


def test_scale_refuses_a_gamma_beyond_the_domain():
    # gamma = gamma0 v0^(1/5) (k/m)^(2/5) = 1e305 for m = k = v0 = 1: a double, but above
    # the domain's 1e300 (the damping rate overflows there); the integrator would mark it
    # INVALID and a scene run would have exited 0 with NaNs.
    with pytest.raises(ValueError, match=r"^gamma = 1e\+305 at gamma0=1e\+305.*<= 1e300"):
        sweep.scale(m=1.0, k=1.0, gamma0=1e305, v0=1.0, **KK)
    assert sweep.scale(m=1.0, k=1.0, gamma0=1e299, v0=1.0, **KK)[0] == pytest.approx(1e299)


def test_scale_gives_the_same_bits_for_scalars_arrays_and_any_layout():
    # numpy's powers took a SIMD loop for contiguous arrays and libm for scalars and strided
    # views (1-2 ulp apart at 4% of general-exponent points): a scene's gamma depended on
    # the array it came in. Reference: Python floats, element by element (libm's pow).
    rng = np.random.default_rng(3)
    n = 500
    m, k = 10 ** rng.uniform(-4, 2, n), 10 ** rng.uniform(2, 10, n)
    gamma0, v0 = 10 ** rng.uniform(-9, -3, n), 10 ** rng.uniform(-2, 1, n)
    alpha, beta = rng.uniform(1, 3, n), rng.uniform(1, 3, n)
    want = [_plain_formula(*p) for p in zip(m, k, gamma0, v0, alpha, beta)]
    calls = {"contiguous": sweep.scale(m, k, gamma0, v0, alpha, beta),
             "reversed": tuple(x[::-1] for x in sweep.scale(
                 m[::-1], k[::-1], gamma0[::-1], v0[::-1], alpha[::-1], beta[::-1])),
             "scalars": tuple(np.array(x) for x in zip(*(
                 sweep.scale(*p) for p in zip(m, k, gamma0, v0, alpha, beta))))}
    for name, (gamma, gtilde) in calls.items():
        assert [(float(a), float(b)) for a, b in zip(gamma, gtilde)] == want, name


def _plain_formula(m, k, gamma0, v0, alpha, beta, g=9.81):
    m, k, gamma0, v0, a, b = (float(x) for x in (m, k, gamma0, v0, alpha, beta))
    return (gamma0 * v0 ** (2 * b / (a + 1) - 1) * (k / m) ** (1 - b / (a + 1)),
            (m / k) ** (1 / (a + 1)) * v0 ** (-2 * a / (a + 1)) * g)


def test_time_scale_is_the_unit_of_the_scaling():
    # T = (m/k)^(1/(a+1)) v0^((1-a)/(a+1)): with delta = v0 T, the scaled well of the
    # load is g~ = (g + F/m) T^2 / delta (eq. (2) by substitution).
    m, k, v0, a = 0.154, 3.6138e10, np.array([0.01, 1.0, 30.0]), 1.5
    t = sweep.time_scale(m, k, v0, a)
    np.testing.assert_allclose(t, (m / k) ** 0.4 * v0 ** -0.2, rtol=1e-15)
    _, gtilde = sweep.scale(m, k, 0.0, v0, a, 1.5, g=9.81)
    np.testing.assert_allclose(gtilde, 9.81 * t ** 2 / (v0 * t), rtol=1e-14)
    assert type(sweep.time_scale(m, k, 1.0, a)) is float
    # A factor beyond double range, T itself not: from logarithms.
    assert sweep.time_scale(1e-300, 1e300, 1.0, 1.0) == pytest.approx(1e-300, rel=1e-12)
    with pytest.raises(ValueError, match="alpha"):
        sweep.time_scale(m, k, 1.0, 0.5)
    with pytest.raises(ValueError, match="v0"):
        sweep.time_scale(m, k, -1.0, a)
    with pytest.raises(ValueError, match=r"T is inf .*at m=1e\+300, k=1e-300, v0=5e-324, "
                                         r"alpha=99.0"):
        sweep.time_scale(1e300, 1e-300, [1.0, 5e-324], 99.0)
