"""The public API: broadcasting, scalars, validation, statuses, parallel/serial identity."""
import concurrent.futures
import warnings

import numba
import numpy as np
import pytest

import sweep
from sweep import Status


def test_broadcast_shape_and_types():
    r = sweep.integrate(1.5, 1.5, np.array([[1e-3], [1e-2], [1e-1]]), np.array([0.0, 0.05, 1.0, 10.0]),
                        steps=24)
    for name in ("e", "sticks", "t_f", "u_max", "n_steps", "status"):
        assert getattr(r, name).shape == (3, 4), name
    assert r.e.dtype == np.float64 and r.sticks.dtype == bool
    assert r.status.dtype == np.int8 and r.n_steps.dtype == np.int32
    e = sweep.cor(1.5, 1.5, np.array([[1e-3], [1e-2], [1e-1]]), np.array([0.0, 0.05, 1.0, 10.0]), steps=24)
    np.testing.assert_array_equal(e, r.e)


def test_scalar_call_returns_python_scalars():
    r = sweep.integrate(1.5, 1.5, 0.05, 0.1)
    assert isinstance(r.e, float) and isinstance(r.sticks, bool)
    assert isinstance(r.n_steps, int) and r.status is Status.OK
    assert 0.0 < r.e < 1.0 and r.t_f > 0 and r.u_max > 0
    assert isinstance(sweep.cor(1.5, 1.5, 0.05, 0.1), float)


@pytest.mark.parametrize("args, name", [
    ((0.9, 1.5, 0.1, 0.1), "alpha"), ((1.5, 0.99, 0.1, 0.1), "beta"),
    ((1.5, 1.5, -0.1, 0.1), "gamma"), ((1.5, 1.5, 0.1, -1.0), "gtilde"),
    ((1.5, 1.5, np.nan, 0.1), "gamma"), ((1.5, 1.5, 0.1, np.inf), "gtilde"),
])
def test_scalar_invalid_raises_naming_argument(args, name):
    with pytest.raises(ValueError, match=name):
        sweep.integrate(*args)
    with pytest.raises(ValueError, match=name):
        sweep.cor(*args)


def test_invalid_points_do_not_spoil_neighbours():
    alpha = np.array([1.5, 0.5, 1.5, 1.5, 1.5, 1.5])
    gamma = np.array([0.1, 0.1, -1.0, np.nan, 0.1, 0.2])
    gtilde = np.array([0.2, 0.2, 0.2, 0.2, np.inf, 0.2])
    r = sweep.integrate(alpha, 1.5, gamma, gtilde, steps=24)
    bad = np.array([False, True, True, True, True, False])
    assert np.all(r.status[bad] == Status.INVALID) and np.all(np.isnan(r.e[bad]))
    assert not r.sticks[bad].any()
    alone = sweep.integrate(1.5, 1.5, np.array([0.1, 0.2]), 0.2, steps=24)
    np.testing.assert_array_equal(r.e[~bad], alone.e)


@pytest.mark.parametrize("kwargs, name", [
    (dict(steps=0), "steps"), (dict(steps=np.nan), "steps"), (dict(rest_tol=0.0), "rest_tol"),
    (dict(rest_tol=1.0), "rest_tol"),
    # beyond every step budget (QA: accepted, every point BUDGET_EXHAUSTED with e = 1)
    (dict(steps=1e300), r"steps must be a number in \[8, 2\*\*30\].*got 1e\+300"),
    (dict(steps=3), r"steps must be a number in \[8, 2\*\*30\].*calibrated from 8 up.*got 3"),
    (dict(steps=2 ** 30 + 1), "steps"),
    (dict(max_steps=0), "max_steps"), (dict(max_steps=2.5), "max_steps"),
])
def test_bad_settings_raise(kwargs, name):
    with pytest.raises(ValueError, match=name):
        sweep.integrate(1.5, 1.5, 0.1, 0.1, **kwargs)


def test_unknown_method_raises():
    with pytest.raises(ValueError, match="nonsense"):
        sweep.cor(1.5, 1.5, 0.1, 0.1, method="nonsense")


def test_budget_exhaustion_is_reported():
    r = sweep.integrate(1.5, 1.5, np.array([0.01, 0.02]), 0.1, max_steps=10)
    assert np.all(r.status == Status.BUDGET_EXHAUSTED)
    assert np.all(r.n_steps <= 10) and np.all(np.isfinite(r.e)) and not r.sticks.any()


def _grid(n=3000, seed=1):
    rng = np.random.default_rng(seed)
    return (rng.uniform(1, 3, n), rng.uniform(1, 3, n), 10 ** rng.uniform(-4, 0.5, n),
            np.where(rng.random(n) < 0.1, 0.0, 10 ** rng.uniform(-3, 1.5, n)))


def _same(a, b):
    for name in ("e", "t_f", "u_max", "n_steps", "status"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_parallel_serial_and_thread_counts_agree_bitwise():
    pts = _grid()
    ref = sweep.integrate(*pts, steps=24, parallel=False)
    _same(sweep.integrate(*pts, steps=24, parallel=True), ref)
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        _same(sweep.integrate(*pts, steps=24), ref)
    finally:
        numba.set_num_threads(old)
    # Order and chunking do not matter either.
    rev = sweep.integrate(*(p[::-1] for p in pts), steps=24)
    np.testing.assert_array_equal(rev.e[::-1], ref.e)


def test_blocks_larger_than_the_smallest_change_no_bit():
    # Large calls go to the threads in blocks of up to 4,096 points (integrator._block_size);
    # with tol (probes of predicted sticks, refinement passes in lanes) as without.
    from sweep.kernels._parallel import threads
    from sweep.kernels.integrator import _BLOCK, _block_size
    pts = _grid(40000, seed=4)
    if threads() > 1:
        assert _block_size(40000, threads()) > _BLOCK
    for kw in ({"steps": 24}, {"tol": 1e-8}):
        _same(sweep.integrate(*pts, parallel=True, **kw),
              sweep.integrate(*pts, parallel=False, **kw))


def test_calls_from_worker_threads_are_safe_and_identical():
    pts = _grid(800, seed=2)
    ref = sweep.integrate(*pts, steps=24)
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        futs = [pool.submit(sweep.integrate, *pts, steps=24) for _ in range(4)]
        for f in futs:
            _same(f.result(), ref)


def test_sticks_is_e_zero_for_decided_points():
    pts = _grid(2000, seed=3)
    r = sweep.integrate(*pts, steps=24)
    decided = r.status != Status.BUDGET_EXHAUSTED
    np.testing.assert_array_equal(r.sticks[decided], r.e[decided] == 0.0)
    assert np.all(r.e[r.status == Status.OK] > 0)
    assert np.all((r.e >= 0) & (r.e <= 1))


# --------------------------------------------------------------------------- argument types

@pytest.mark.parametrize("value, shown", [
    ("0.1", "'0.1'"), ("abc", "'abc'"), (b"0.1", "b'0.1'"), (True, "True"),
    (np.bool_(False), "False"), (np.array([True, False]), "dtype bool"),
    (0.1 + 1j, "(0.1+1j)"), (None, "None"), ([0.1, None], "[0.1, None]"),
    (np.array([0.1], dtype=object), "dtype object"), ([0.1, "0.2"], "'0.2'"),
])
@pytest.mark.parametrize("method", ["numeric", "ord1"])
def test_non_numbers_are_refused_naming_parameter_and_value(value, shown, method):
    # numpy would parse "0.1", read True as 1 and None as NaN: each must be refused instead,
    # in one line naming the parameter (gamma here) and what was given.
    with pytest.raises(ValueError, match="gamma must be a real number") as info:
        sweep.cor(1.5, 1.5, value, 1.0, method=method)
    assert shown in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ValueError, match="gtilde must be a real number"):
        sweep.integrate(1.5, 1.5, 0.1, value)
    with pytest.raises(ValueError, match="alpha must be a real number"):
        sweep.coefficients(value, 1.5, 1.0)


def test_ints_and_numpy_numbers_are_numbers():
    # KK at gamma = 0 rebounds elastically: e = 1 whatever the integer or numpy type.
    assert sweep.cor(1, 1, 0, 1) == pytest.approx(1.0, abs=1e-9)
    e = sweep.cor(np.int32(3) / 2, np.float32(1.5), np.array([0, 0], dtype=np.int64),
                  np.uint8(1))
    np.testing.assert_allclose(e, [1.0, 1.0], atol=1e-9)


def test_masked_values_are_refused_not_computed_from_the_hidden_data():
    # np.asarray dropped the mask: the hidden 0.1 was computed, where sweep.xr.cor (xarray
    # turns masked values into NaN) gave NaN / INVALID.
    masked = np.ma.masked_array([0.05, 0.1], mask=[False, True])
    for call in (lambda: sweep.cor(1.5, 1.5, masked, 1.0),
                 lambda: sweep.integrate(1.5, 1.5, 0.05, masked),
                 lambda: sweep.scale(2e-3, 1e10, 1e-6, masked, 1.5, 1.5)):
        with pytest.raises(ValueError, match=r"^\w+ has 1 masked value\(s\), whose hidden data"):
            call()
    unmasked = np.ma.masked_array([0.05, 0.1])
    assert np.array_equal(sweep.cor(1.5, 1.5, unmasked, 1.0),
                          sweep.cor(1.5, 1.5, [0.05, 0.1], 1.0))


def test_numpy_typed_options_give_the_bits_of_the_same_python_values():
    # A float32 tol computed its resolution and target in float32: 149 of 400 KK points
    # differed (up to 3.6e-15) from the same value given as a float.
    rng = np.random.default_rng(5)
    gamma, gtilde = 10 ** rng.uniform(-4, -0.5, 200), 10 ** rng.uniform(-3, 1, 200)
    for options in (dict(tol=np.float32(1e-8)), dict(steps=np.float32(40.5), refine=np.True_,
                                                    max_steps=np.int16(20000))):
        plain = {k: v.item() for k, v in options.items()}
        got, want = (sweep.integrate(1.5, 1.5, gamma, gtilde, **o) for o in (options, plain))
        for name in ("e", "e_err", "t_f", "u_max", "n_steps", "status"):
            assert np.array_equal(getattr(got, name), getattr(want, name), equal_nan=True), name
    assert type(sweep.api.integrator_settings(tol=np.float32(1e-8))["tol"]) is float


@pytest.mark.parametrize("parallel", ["no", 1, 0, "False", [True]])
def test_parallel_must_be_none_or_a_bool(parallel):
    with pytest.raises(ValueError, match=f"parallel must be None, True or False, got "
                                         f"{parallel!r}".replace("[", r"\[")):
        sweep.integrate(1.5, 1.5, [0.1, 0.2], 1.0, parallel=parallel)
    with pytest.raises(ValueError, match="parallel must be"):
        sweep.cor(1.5, 1.5, [0.1, 0.2], 1.0, parallel=parallel)


def test_parallel_accepts_none_and_bools():
    want = sweep.integrate(1.5, 1.5, [0.1, 0.2], 1.0, steps=24).e
    for parallel in (None, True, False, np.bool_(True)):
        got = sweep.integrate(1.5, 1.5, [0.1, 0.2], 1.0, steps=24, parallel=parallel).e
        np.testing.assert_array_equal(got, want)


def test_unknown_option_of_the_integration_is_named_like_the_approximations():
    with pytest.raises(ValueError, match=r"^unknown option 'stepz' for method 'numeric'; "
                                         r"allowed: tol, steps, .*, parallel$"):
        sweep.cor(1.5, 1.5, 0.1, 1.0, stepz=3)
    with pytest.raises(ValueError, match=r"^unknown option 'stepz' for method 'ord1'"):
        sweep.cor(1.5, 1.5, 0.1, 1.0, method="ord1", stepz=3)


def test_shapes_that_do_not_broadcast_are_named():
    with pytest.raises(ValueError, match=r"^the shapes of gamma \(2,\), gtilde \(3,\) do not "
                                         r"broadcast together"):
        sweep.cor(1.5, 1.5, [0.1, 0.2], [1.0, 2.0, 3.0])


# --------------------------------------------------------------------------- undefined points

@pytest.mark.parametrize("method", ["ord2_numint", "ord2_approx"])
def test_ord2_beyond_the_range_of_i_q_names_gtilde(method):
    # The method is defined at KK; g~ = 1e300 is past the range of I, Q of Prop. 2 (theta
    # of (43) underflows), so the error must blame g~, as sweep.coefficients does.
    with pytest.raises(ValueError) as info:
        sweep.cor(1.5, 1.5, 0.1, 1e300, method=method)
    msg = str(info.value)
    assert "gtilde=1e+300 is out of the range of I, Q" in msg and msg.endswith("alpha=1.5")
    assert "not defined" not in msg
    with pytest.raises(ValueError, match=r"gtilde=1e\+300 is out of the range of I, Q .*"
                                         r"at alpha=1.5$"):
        sweep.coefficients(1.5, 1.5, 1e300)


def test_ord2_at_a_large_alpha_names_the_alpha_its_range_shrank_at():
    # At alpha ~ 311 the quadrature's theta of (43) underflows already at g~ = 0.1: the g~
    # alone would not say why (well inside the range at the report's exponents).
    with pytest.raises(ValueError, match=r"ord2_numint': gtilde=0.1 is out of the range of "
                                         r"I, Q \(.*\) at alpha=311.0$"):
        sweep.cor(311.0, 1.5, 0.01, 0.1, method="ord2_numint")
    assert 0.0 < sweep.cor(1.5, 1.5, 0.01, 0.1, method="ord2_numint") < 1.0


def test_undefined_exponents_still_name_alpha_and_beta():
    with pytest.raises(ValueError, match=r"method 'sp' is not defined at alpha=2.0, beta=1.5"):
        sweep.cor(2.0, 1.5, 0.1, 1.0, method="sp")


def test_overflowing_formula_names_the_point_not_the_exponents():
    # gamma^2 of (25) overflows at gamma = 1.7e308 (inf - inf), which is now outside the
    # domain (gamma <= 1e300): sp is defined at KK, and g~ = 1 is well inside the range of
    # I, Q, so neither may be blamed.
    for method in ("sp", "ord2_numint"):
        with pytest.raises(ValueError) as info:
            sweep.cor(1.5, 1.5, 1.7e308, 1.0, method=method)
        msg = str(info.value)
        assert "gamma" in msg and "1.7e+308" in msg
        assert "not defined" not in msg and "range of I" not in msg


def test_cor_warns_where_a_march_ran_out_of_budget():
    """cor returns no status: where the budget ran out (here a resolution the default budget
    cannot finish), e is only an upper bound and a RuntimeWarning says so; cor_with_status
    and integrate carry the status instead, without the warning."""
    with pytest.warns(RuntimeWarning, match="BUDGET_EXHAUSTED"):
        e = sweep.cor(1.5, 1.5, 0.1, 1.0, steps=1e7, max_steps=2000)
    r = sweep.integrate(1.5, 1.5, 0.1, 1.0, steps=1e7, max_steps=2000)
    assert r.status == Status.BUDGET_EXHAUSTED and e == r.e and r.e_err >= r.e
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, status = sweep.cor_with_status(1.5, 1.5, [0.1, 0.2], 1.0, steps=1e7, max_steps=2000)
        assert np.all(status == Status.BUDGET_EXHAUSTED)
        sweep.cor(1.5, 1.5, 0.1, 1.0)                 # a finished march: no warning


def test_cor_warns_where_it_cannot_vouch_for_tol():
    """cor returns no e_err: tol = 1e-17 is below half an ulp of any e in [0.5, 1) (2^-54,
    5.6e-17), so no float64 e is certainly that close to the truth and every point must be
    flagged (before, cor returned them silently after 25,000 steps each); at tol = 1e-8 on
    ordinary points none is, and integrate, which returns e_err, never warns."""
    gamma = np.array([0.01, 0.05, 0.1])
    with pytest.warns(RuntimeWarning, match=r"3 point\(s\) may miss tol=1e-17") as rec:
        e = sweep.cor(1.5, 1.5, gamma, 0.1, tol=1e-17)
    assert len(rec) == 1 and np.all((e >= 0.5) & (e < 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sweep.integrate(1.5, 1.5, gamma, 0.1, tol=1e-17)
        sweep.cor(1.5, 1.5, gamma, 0.1, tol=1e-8)
    # A point out of budget has its own warning, not a second one about tol.
    with pytest.warns(RuntimeWarning, match="BUDGET_EXHAUSTED") as rec:
        sweep.cor(1.5, 1.5, 0.1, 1.0, tol=1e-8, max_steps=20)
    assert len(rec) == 1


def test_gamma_above_1e300_is_outside_the_domain():
    """Beyond 1e300 the damping rate gamma beta u^(beta-1) overflows (gamma = 1.7e308 gave
    e = NaN with BUDGET_EXHAUSTED): the domain stops there, in every method."""
    with pytest.raises(ValueError, match=r"gamma must be .*1e300.*got 1e\+305"):
        sweep.cor(1.5, 1.5, 1e305, 1.0)
    r = sweep.integrate(1.5, 1.5, np.array([1e300, 1e305, 1.7e308]), 1.0)
    assert list(r.status) == [Status.AT_REST, Status.INVALID, Status.INVALID]
    assert r.e[0] == 0.0 and np.isnan(r.e[1:]).all()
    e, status = sweep.cor_with_status(1.5, 1.5, np.array([1e300, 1e305]), 1.0, method="ord1")
    assert list(status) == [Status.OK, Status.INVALID] and np.isnan(e[1])


@pytest.mark.parametrize("shapes", [((2,), ()), ((1,), ()), ((2, 1), (3,))])
def test_broadcast_inputs_reach_the_kernels_without_a_warning(shapes):
    # np.broadcast_arrays' views carry numpy's warn-on-write flag: numba's typeof, reading
    # flags.writeable when a call compiles or loads a specialisation, put a FutureWarning
    # on the user's stderr (sweep.cor(1.5, 1.5, np.array([0.05]), 1.0, method=...)).
    from sweep._arrays import Broadcast
    arrays = [np.arange(1.0, 1.0 + np.prod(s)).reshape(s) for s in shapes]
    b = Broadcast(("gamma", "gtilde"), arrays)
    expected = np.broadcast_arrays(*arrays)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for flat, full in zip(b.flat, expected):
            assert numba.typeof(flat).mutable
            assert np.array_equal(flat, full.reshape(-1))


def test_a_read_only_input_compiles_no_kernel_again():
    # numba types a read-only array apart from a writeable one: passed through, it compiled
    # the integrator's kernel a second time (~15 s).
    from sweep.kernels import integrator
    gamma = np.array([0.01, 0.1])
    first = sweep.integrate(1.5, 1.5, gamma, 0.1)
    signatures = list(integrator._kernel.signatures)
    gamma.flags.writeable = False
    again = sweep.integrate(1.5, 1.5, gamma, np.full(2, 0.1))
    assert list(integrator._kernel.signatures) == signatures
    assert np.array_equal(again.e, first.e) and not gamma.flags.writeable
