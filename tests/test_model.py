"""Scaling (2) and validation of physical inputs."""
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


@pytest.mark.parametrize("value", ["0.154", True, None, 0.154 + 0j])
def test_scale_refuses_non_numbers_naming_them(value):
    with pytest.raises(ValueError, match=r"^m must be a real number .*got " + repr(value)
                       .replace("(", r"\(").replace(")", r"\)").replace("+", r"\+")):
        sweep.scale(value, 3.6138e10, 1.5237e-6, 1.0, 1.5, 1.5)
