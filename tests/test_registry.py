"""sweep.registry: one place for domains, methods and fields, read by every floor."""
import contextlib

import numpy as np
import pytest

import sweep
from sweep import registry
from sweep.kernels import approx
from sweep.sweeps import config


def _half(alpha, beta, gamma, gtilde, level=0.5):
    """A dummy CoR: e = level where defined (what a new method's kernel returns)."""
    e = np.full(alpha.size, float(level))
    return e, np.zeros(alpha.size, dtype=np.int8)


@contextlib.contextmanager
def dummy_method(**kwargs):
    m = registry.Method("dummy", "coefficient of restitution, dummy", "e = level",
                        "(none)", _half, **kwargs)
    registry.register_method(m)
    try:
        yield m
    finally:
        registry.unregister_method("dummy")


def test_a_method_added_through_the_registry_alone():
    opt = registry.Option("level", 0.5, lambda v: isinstance(v, float) and 0 <= v <= 1,
                          "a number in [0, 1]")
    with dummy_method(options=(opt,)):
        assert sweep.cor(1.5, 1.5, 0.1, 0.2, method="dummy") == 0.5
        np.testing.assert_array_equal(
            sweep.cor(1.5, 1.5, np.array([0.1, 0.2]), 0.2, method="dummy", level=0.25),
            [0.25, 0.25])
        with pytest.raises(ValueError, match="level"):
            sweep.cor(1.5, 1.5, 0.1, 0.2, method="dummy", level=2.0)
        cfg = config.loads('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\ngamma = 0.1\n'
                           'gtilde = 0.2\n[outputs]\ne = ["numeric", "dummy"]\n'
                           'fields = ["error_dummy"]\n[options.dummy]\nlevel = 0.75\n')
        assert cfg.outputs.methods == ("numeric", "dummy")
        assert cfg.outputs.approximations == ("dummy",)
        assert cfg.method_options("dummy") == {"level": 0.75}
        ds = sweep.run(cfg)
        np.testing.assert_array_equal(ds["e_dummy"].values, 0.75)
        np.testing.assert_allclose(ds["error_dummy"].values,
                                   0.75 - ds["e_numeric"].values, rtol=0, atol=1e-15)
        assert ds["e_dummy"].attrs["long_name"] == "coefficient of restitution, dummy"
    with pytest.raises(ValueError, match="dummy"):
        sweep.cor(1.5, 1.5, 0.1, 0.2, method="dummy")


def test_method_domain_is_applied_by_the_api():
    with dummy_method(models=((1.0, 1.0),)):
        e, status = sweep.cor_with_status(np.array([1.0, 1.5]), np.array([1.0, 1.5]), 0.1, 0.2,
                                          method="dummy")
        assert e[0] == 0.5 and np.isnan(e[1])
        assert status.tolist() == [sweep.Status.OK, sweep.Status.INVALID]
        with pytest.raises(ValueError, match="not defined"):
            sweep.cor(1.5, 1.5, 0.1, 0.2, method="dummy")


def test_every_registered_kernel_resolves():
    for m in registry.METHODS.values():
        assert callable(m.resolve()), m.name
    assert set(approx.CODES) == set(registry.approximations())


def test_kernel_domain_matches_the_registry():
    # The jitted domain test (kernels) and the numpy one (registry) read one set of bounds.
    rng = np.random.default_rng(0)
    n = 2000
    pts = [rng.choice([-1.0, 0.0, 0.5, 1.0, 1.5, np.nan, np.inf, -np.inf], n) for _ in range(4)]
    e, status = sweep.cor_with_status(*pts, method="ord1")
    valid = registry.valid_points(*pts)
    np.testing.assert_array_equal(status != sweep.Status.INVALID, valid)
    r = sweep.integrate(*pts, steps=8)
    np.testing.assert_array_equal(r.status != sweep.Status.INVALID, valid)


@pytest.mark.parametrize("name, bad", [("alpha", 0.99), ("beta", np.nan), ("gamma", -1e-300),
                                       ("gtilde", -np.inf)])
def test_check_names_the_value(name, bad):
    with pytest.raises(ValueError, match=name):
        registry.check_scalar(name, bad)


def test_fields_and_integration_result_agree():
    r = sweep.integrate(1.5, 1.5, 0.1, 0.1)
    for name, f in registry.FIELDS.items():
        value = getattr(r, name)
        assert np.asarray(value).dtype.kind == f.dtype.kind or isinstance(value, (int, float,
                                                                                  bool))
    assert set(registry.integrator_fields()) == set(registry.FIELDS) - {"e"}


def test_a_derived_field_added_through_the_registry_alone():
    """A field computed from the kernel's fields: one registry entry, no other edit."""
    f = registry.Field("kinetic_ratio", np.dtype(np.float64), "kinetic energy ratio",
                       "e squared: rebound over impact kinetic energy", fill_value=np.nan,
                       derived=lambda fields: fields["e"] ** 2)
    registry.register_field(f)
    try:
        r = sweep.integrate(1.5, 1.5, np.array([0.01, 0.1]), 0.2)
        np.testing.assert_array_equal(r.kinetic_ratio, r.e ** 2)
        cfg = config.loads('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\n'
                           'gamma = [0.01, 0.1]\ngtilde = 0.2\n[outputs]\ne = ["numeric"]\n'
                           'fields = ["kinetic_ratio"]\n')
        ds = sweep.run(cfg)
        np.testing.assert_array_equal(ds["kinetic_ratio"].values, ds["e_numeric"].values ** 2)
        assert ds["kinetic_ratio"].attrs["long_name"] == "kinetic energy ratio"
    finally:
        registry.unregister_field("kinetic_ratio")
    assert not hasattr(sweep.integrate(1.5, 1.5, 0.1, 0.2), "kinetic_ratio")


def test_a_registered_method_reaches_the_accuracy_report():
    # After the api was imported, as in a session: its APPROXIMATIONS is a snapshot.
    xr = pytest.importorskip("xarray")
    from sweep.reports.accuracy import load_errors

    assert sweep.api.APPROXIMATIONS
    ds = xr.Dataset({"e_numeric": ("gamma", [0.9, 0.8]), "e_dummy": ("gamma", [0.5, 0.5])},
                    coords={"alpha": 1.5, "beta": 1.5, "gamma": [0.1, 0.2], "gtilde": 0.0})
    with dummy_method():
        data = load_errors(ds)
    assert data["methods"] == ["dummy"]
    np.testing.assert_allclose(data["errors"]["dummy"], [0.4, 0.3])


@pytest.mark.parametrize("name, clash", [("err", "e_err"), ("ord1", "already registered")])
def test_a_method_storing_a_name_in_use_is_refused(name, clash):
    # Method "err" stores e_err, the integrator's error field: sweep.run raised a KeyError.
    m = registry.Method(name, "coefficient of restitution, x", "x", "(none)", _half)
    try:
        with pytest.raises(ValueError, match=clash):
            registry.register_method(m)
    finally:  # a failure must not leave it registered for the tests after
        if registry.METHODS.get(name) is m:
            registry.unregister_method(name)


@pytest.mark.parametrize("name", ["e_ord1", "error_ord1", "method_used", "gamma", "k"])
def test_a_field_storing_a_name_in_use_is_refused(name):
    f = registry.Field(name, np.dtype(np.float64), "x", "x", derived=lambda fields: fields["e"])
    try:
        with pytest.raises(ValueError, match=name):
            registry.register_field(f)
    finally:
        if registry.FIELDS.get(name) is f:
            registry.unregister_field(name)


def test_the_result_class_follows_the_registered_fields():
    first = sweep.IntegrationResult
    f = registry.Field("kinetic_ratio", np.dtype(np.float64), "kinetic energy ratio", "e^2",
                       derived=lambda fields: fields["e"] ** 2)
    registry.register_field(f)
    try:
        assert isinstance(sweep.integrate(1.5, 1.5, 0.1, 0.2), sweep.IntegrationResult)
    finally:
        registry.unregister_field("kinetic_ratio")
    # Nothing left behind: the class of the built-in fields again.
    assert type(sweep.integrate(1.5, 1.5, 0.1, 0.2)) is first is sweep.IntegrationResult


def test_each_rule_states_its_maximum():
    # A rule is the error message's domain: a maximum changed alone would leave it stale.
    for domain in (registry.PARAMETERS, registry.PHYSICAL, registry.MATERIAL):
        for p in domain.values():
            if np.isfinite(p.maximum):
                assert f"{p.maximum:g}".replace("e+", "e") in p.rule, p.name
