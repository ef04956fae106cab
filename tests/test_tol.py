"""The accuracy knob ``tol`` and the first march's error estimate, against independent
references (issue 10, item 1).

* With ``tol``, the achieved error stays under it and under twice the reported ``e_err``:
  the linear law against its exact solution (``reference.linear_cor``), KK and general
  exponents against scipy's DOP853 (``reference.dop853_cor``), on the core benchmark's draw
  (gamma = 10^U(-4, -0.5), g~ = 10^U(-3, 1)).
* The first march's ``e_err`` is an upper bound at every resolution, and its
  pessimism does not grow with the resolution: the summed embedded estimates fall one order
  slower than the march's error, which ``sweep.kernels.balance.KAPPA_STEPS`` accounts for;
  at the coarsest resolutions (tol >= 5e-6: 8 steps) it is widened
  (``sweep.kernels.balance.COARSE_STEPS``), checked on points a wide draw found short.
"""
from __future__ import annotations

import functools

import numpy as np
import pytest

import reference
import reference_hp
import sweep

#: Errors of the references themselves (exact to rounding; DOP853 at rtol 1e-13).
REF_SLACK = {"linear": 1e-14, "kk": 2e-12, "general": 2e-12}
POINTS = {"linear": 80, "kk": 24, "general": 24}


@functools.lru_cache(maxsize=None)
def draw(law):
    """Points of the core benchmark's draw for ``law`` and their reference e."""
    n = POINTS[law]
    rng = np.random.default_rng({"linear": 1, "kk": 2, "general": 3}[law])
    gamma = 10 ** rng.uniform(-4, -0.5, n)
    gtilde = 10 ** rng.uniform(-3, 1, n)
    if law == "general":
        alpha, beta = rng.uniform(1, 3, n), rng.uniform(1, 3, n)
    else:
        a = 1.0 if law == "linear" else 1.5
        alpha, beta = np.full(n, a), np.full(n, a)
    if law == "linear":
        e_ref = np.array([reference.linear_cor(g, gt).e for g, gt in zip(gamma, gtilde)])
    else:
        e_ref = np.array([reference.dop853_cor(*p).e for p in zip(alpha, beta, gamma, gtilde)])
    return alpha, beta, gamma, gtilde, e_ref


@pytest.mark.parametrize("tol", [1e-6, 1e-8])
@pytest.mark.parametrize("law", ["linear", "kk", "general"])
def test_tol_bounds_the_achieved_error(law, tol):
    alpha, beta, gamma, gtilde, e_ref = draw(law)
    r = sweep.integrate(alpha, beta, gamma, gtilde, tol=tol)
    err = np.abs(r.e - e_ref)
    slack = REF_SLACK[law]
    assert np.all(err <= tol + slack), (law, tol, err.max())
    assert np.all(err <= 2 * r.e_err + slack), (law, tol, np.max(err - 2 * r.e_err))
    assert np.all(r.e_err <= tol), (law, tol, r.e_err.max())


@pytest.mark.parametrize("options", [{}, {"tol": 1e-10}, {"steps": 192, "refine": False}])
def test_estimate_bounds_a_heavily_damped_linear_rebound(options):
    # The linear law near gamma = 1 (e ~ 0.15, q ~ 0.49): the defect D = dH + dq, where the
    # velocity's error dH has q's sign, understated q's error (true error up to 1.2 e_err,
    # past tol = 1e-10 by 2%); the calibration's draws stopped at gamma = 0.32.
    gamma = np.repeat(np.linspace(0.9, 1.1, 21), 2)
    gtilde = np.tile([1e-4, 0.0115], 21)
    e_ref = np.array([reference.linear_cor(g, gt).e for g, gt in zip(gamma, gtilde)])
    r = sweep.integrate(1.0, 1.0, gamma, gtilde, **options)
    err = np.abs(r.e - e_ref)
    assert np.all(r.status == sweep.Status.OK)
    assert np.all(err <= r.e_err + REF_SLACK["linear"]), np.max(err / r.e_err)
    assert np.all(err <= options.get("tol", 1.0) + REF_SLACK["linear"]), err.max()


@pytest.mark.parametrize("point, options", [
    # A creep's local steps at large alpha (stepsize.LOCAL_ALPHA): status OK, e_err within
    # tol, the true error 2.8-4 tol and up to 12 e_err, until 2026-12-07 (an audit).
    ((8.592439923525447, 5.280212397599563, 0.5781817320415795, 0.0), {"tol": 1e-8}),
    ((6.0, 4.0, 0.62, 0.0), {"tol": 1e-10}),
    ((9.556300028763609, 7.930922691401985, 1.0487607495822189, 0.0011396751764256915),
     {"tol": 1e-6}),
    ((10.0, 6.0, 0.57, 0.0), {"steps": 48, "refine": False}),
    ((8.248108198482647, 8.567192802560415, 1.7787003957092116, 0.00181481651549459),
     {"steps": 32, "refine": False}),
])
def test_a_creep_at_large_alpha_meets_tol_and_its_estimate(point, options):
    r = sweep.integrate(*point, **options)
    err = abs(r.e - reference.dop853_cor(*point).e)
    slack = REF_SLACK["general"]
    assert r.status == sweep.Status.OK
    assert err <= r.e_err + slack, err / r.e_err
    assert err <= options.get("tol", 1.0) + slack, err


@pytest.mark.parametrize("point, tol", [
    # Near the stick boundary, beta well above alpha: the march at tol's coarse resolution
    # (8 steps) left with e ~ 1e-3 from the velocity while the balance said the energy was
    # spent; e_err 7e-5. auto at tol 1e-4 returned those rebounds (up to 11.5 tol), sticks
    # among them, without a word, until 2026-12-07 (an audit).
    ((1.0822798646847622, 2.7236795974886316, 0.556597586323234, 0.3069364523603945), 1e-4),
    ((1.5, 2.5, 0.7731360904822817, 0.16099527366380648), 1e-4),
    ((1.182865867821907, 2.6033402413213595, 0.7167619608443337, 0.2384640631120055), 1e-4),
    # Damped out, e from -v, whose estimate at 8 steps was 10 times short (another audit).
    ((5.41761453677328, 9.363809687325105, 1.186761339664709, 0.030424266998771356), 1e-5),
    ((1.0, 8.76140895252647, 46.005187596215876, 0.23116174079883742), 1e-4),   # sticks
    ((3.7527587260409714, 10.0, 3.258698724575668, 0.04686516492501215), 1e-4),
])
@pytest.mark.parametrize("method", ["numeric", "auto"])
@pytest.mark.filterwarnings("ignore:.* may miss tol")  # an honest e_err above tol may stay
def test_a_coarse_march_near_the_stick_boundary_meets_tol(point, tol, method):
    e = sweep.cor(*point, method=method, tol=tol)
    ref = reference.dop853_cor(*point)
    assert abs(e - ref.e) <= tol, (e, ref.e)
    assert (e == 0.0) == ref.sticks


def test_first_march_estimate_keeps_its_room_at_every_resolution():
    alpha, beta, gamma, gtilde, e_ref = draw("linear")
    worst = {}
    for steps in (12, 48):
        r = sweep.integrate(alpha, beta, gamma, gtilde, steps=steps, refine=False)
        ok = (e_ref > 0) & (r.e > 0)
        ratio = np.abs(r.e - e_ref)[ok] / r.e_err[ok]
        assert np.all(ratio <= 1.0), (steps, ratio.max())
        worst[steps] = ratio.max()
    # A fixed factor on the summed embedded estimates makes the worst point 4x more
    # pessimistic from 12 to 48 steps (they fall like steps^-4, the error like steps^-5):
    # 0.39 -> 0.09 on this draw with KAPPA_STEPS = infinity, 0.47 -> 0.33 with 8.
    assert worst[48] >= 0.35 * worst[12], worst


# Points of a wide draw (2026-12-02) that came back beyond tol = 1e-5 with an e_err within
# it, from one march at the error model's coarsest resolution (8 steps), before the
# estimate was widened there (sweep.kernels.balance.COARSE_STEPS).
COARSE = [(1.0, 2.5, 0.6891122748739117, 0.0009233754938883981),
          (1.0, 2.9275795917930654, 0.5868090013024987, 0.0),
          (1.0, 2.6074397307181516, 0.65537791340707, 0.0)]


@pytest.mark.parametrize("alpha, beta, gamma, gtilde", COARSE)
@pytest.mark.parametrize("tol", [1e-4, 1e-5, 3e-6])
def test_tol_is_met_or_the_estimate_says_so_at_coarse_resolutions(alpha, beta, gamma, gtilde,
                                                                  tol):
    ref = reference.dop853_cor(alpha, beta, gamma, gtilde)
    r = sweep.integrate(alpha, beta, gamma, gtilde, tol=tol)
    err = abs(float(r.e) - ref.e)
    assert err <= float(r.e_err), (err, float(r.e_err))
    assert err <= tol or float(r.e_err) > tol, (err, float(r.e_err))


def test_first_march_estimate_is_a_bound_at_the_coarsest_resolution():
    """One march at 8 steps (what tol >= 5e-6 takes) on the points above."""
    for alpha, beta, gamma, gtilde in COARSE:
        ref = reference.dop853_cor(alpha, beta, gamma, gtilde)
        r = sweep.integrate(alpha, beta, gamma, gtilde, steps=8.0, refine=False)
        assert abs(float(r.e) - ref.e) <= float(r.e_err)


# Heavily damped KK points of benchmarks/damped.py's draw (gamma = 10^U(0, 2)) that stick.
# The creep rule stops such a bead as soon as its energy H goes below 0, where the balance
# cannot tell a stick from a rebound (|H| < dq); the undecided bound sqrt(2 dq) exceeded
# tol = 1e-6 and sent them to refinement at 10-11 times the steps of one march.
DAMPED_STICKS = [(1.5, 1.5, 8.951374768950666, 0.0021258464353617703),
                 (1.5, 1.5, 12.624545807034497, 0.0014380768780133228),
                 (1.5, 1.5, 9.123144178326326, 0.0032537860429355846)]


@pytest.mark.parametrize("alpha, beta, gamma, gtilde", DAMPED_STICKS)
def test_a_certain_stick_is_decided_by_one_march(alpha, beta, gamma, gtilde):
    ref = reference_hp.solve(alpha, beta, gamma, gtilde)
    assert ref["status"] == reference_hp.STUCK
    r = sweep.integrate(alpha, beta, gamma, gtilde, tol=1e-6)
    first = sweep.integrate(alpha, beta, gamma, gtilde, tol=1e-6, refine=False)
    assert float(r.e) == 0.0 and bool(r.sticks) and float(r.e_err) == 0.0
    assert int(r.n_steps) == int(first.n_steps)


def test_estimate_of_a_nearly_elastic_bounce_follows_the_dissipated_energy():
    """q, an integral along the march's path, errs by about q times the path's energy
    defect (sweep.kernels.balance.defect_share): where little energy is dissipated, the
    whole defect overstated the error of e 50-500 times (median 0.002-0.02)."""
    alpha, beta, gamma, gtilde, e_ref = draw("linear")
    elastic = (1.0 - e_ref ** 2) / 2.0 < 0.05
    assert elastic.sum() >= 20
    r = sweep.integrate(alpha, beta, gamma, gtilde, steps=48, refine=False)
    ratio = np.abs(r.e - e_ref)[elastic] / r.e_err[elastic]
    assert np.all(ratio <= 1.0), ratio.max()
    assert np.median(ratio) >= 0.05, np.median(ratio)


# Nearly elastic bounces (e ~ 0.999) whose damping exponent beta is below alpha and not an
# integer, with a small gamma: q's own integrand errs at u = 0 in proportion to q whatever
# gamma, so the grading near u = 0 must follow beta at its own exponent
# (sweep.kernels.stepsize.singular_exponent) for the defect's share to hold. Graded for
# beta weakened by gamma (until 2026-12-05), their true error was 3-6 times e_err.
BETA_GRADED = [(2.904, 1.204, 1.43e-04, 0.450), (2.560, 1.101, 2.15e-04, 0.312),
               (2.0, 1.1, 1.5e-4, 0.3)]


@pytest.mark.parametrize("alpha, beta, gamma, gtilde", BETA_GRADED)
def test_estimate_holds_where_a_small_damping_is_less_smooth_than_the_spring(alpha, beta,
                                                                          gamma, gtilde):
    """One march at 48 steps against the extended-precision reference (graded for beta
    weakened by gamma these points erred 1.9-7.2 times e_err there; 0.15-0.16 now)."""
    ref = reference_hp.solve(alpha, beta, gamma, gtilde)
    r = sweep.integrate(alpha, beta, gamma, gtilde, steps=48, refine=False)
    assert abs(float(r.e) - ref["e"]) <= float(r.e_err) - ref["e_est_err"]


# A nearly elastic and a lossy KK bounce: q predicted ~2e-4 and ~0.45
# (sweep.kernels.stepsize.predicted_q).
ELASTIC, LOSSY = (1.5, 1.5, 1e-4, 0.01), (1.5, 1.5, 0.1, 0.5)


@pytest.mark.parametrize("tol", [1e-8, 1e-10])
def test_a_nearly_elastic_bounce_is_first_marched_at_a_share_of_the_resolution(tol):
    """With tol alone, a point's first march takes a share of the error model's resolution
    that falls with the predicted dissipated energy (sweep.kernels.stepsize.tol_share); a
    given steps= is every point's resolution, with tol or without."""
    from sweep.kernels.stepsize import resolution
    steps = resolution(tol)
    for point, coarser in ((ELASTIC, True), (LOSSY, False)):
        r = sweep.integrate(*point, tol=tol)
        given = sweep.integrate(*point, steps=steps, tol=tol)
        err = abs(float(r.e) - reference.dop853_cor(*point).e)
        assert err <= tol and err <= float(r.e_err) + REF_SLACK["kk"], (point, err)
        if coarser:
            assert int(r.n_steps) < 0.75 * int(given.n_steps), (point, r.n_steps)
        else:
            assert int(r.n_steps) == int(given.n_steps) and float(r.e) == float(given.e)
    # The default 96 steps without tol march as a given steps=96.
    default = sweep.integrate(*ELASTIC)
    assert int(default.n_steps) == int(sweep.integrate(*ELASTIC, steps=96).n_steps)


# A KK bounce predicted to dissipate q ~ 2.2 (sweep.kernels.stepsize.predicted_q): it sticks.
STICK = (1.5, 1.5, 0.5, 0.5)
# Predicted q >= 1 (gamma < 1), yet they leave: a point of the Sobol design that leaves with
# e ~ 0.50, and a linear-law point near grazing (e ~ 7e-4) that, refined from the 16-step
# probe, ended with e_err 4.7e-9 at tol=1e-10 (Richardson across a ratio of 21).
LEAVES = [(1.0240885708481073, 2.369977243244648, 0.7094941363788713, 0.03790060058236122),
          (1.0, 1.0, 0.9263237296506217, 0.1)]


@pytest.mark.parametrize("tol", [1e-8, 1e-10])
def test_a_predicted_stick_is_settled_by_a_march_at_the_floor(tol):
    """A bead predicted to stick (q >= Q_STICK) is first marched at the integrator's floor
    of 16 steps: it sticks there with certainty (e = 0, e_err = 0), for fewer steps than a
    march at its share; its u_max follows that march (docs/accuracy.md, section 5).
    ``refine=False`` keeps one march per point, at its share."""
    from sweep.kernels.stepsize import resolution
    ref = reference.dop853_solve(*STICK)
    r = sweep.integrate(*STICK, tol=tol)
    given = sweep.integrate(*STICK, steps=resolution(tol), tol=tol)
    assert ref["status"] in (reference.STUCK, reference.AT_REST)
    assert float(r.e) == 0.0 and float(r.e_err) == 0.0 and bool(r.sticks)
    assert int(r.n_steps) < 0.75 * int(given.n_steps), (r.n_steps, given.n_steps)
    assert abs(float(r.u_max) / ref["u_max"] - 1.0) < 2e-7
    # Without refinement one march per point, at its share (all of it here): no probe.
    once = sweep.integrate(*STICK, tol=tol, refine=False)
    assert int(once.n_steps) == int(sweep.integrate(*STICK, steps=resolution(tol),
                                                    refine=False).n_steps)


# Heavily damped under a load (gamma > GAMMA_CALLABLE): an SHC bead that creeps into its
# well about overdamped there (eps(u-bar) ~ 0.94, zeta ~ 0.42: sweep.kernels.stepsize.
# EPS_CALLABLE) and sticks; and a hard case's creeping bead at g~ = 1e-6 (kappa < 0) that
# leaves with e ~ 2.4e-3 while q to first order is ~48.
DAMPED_STICK = (1.5, 2.5, 5.0, 0.05)
CREEPS_OUT = (4.75456916, 4.7973655, 14.1607549, 1e-6)


@pytest.mark.parametrize("tol", [1e-8, 1e-10])
def test_a_heavily_damped_stick_is_probed_only_where_the_well_can_hold_it(tol):
    """Beyond gamma = 1 a predicted stick is probed at the floor only where the bead creeps
    into the well about overdamped (it sticks there: e = 0 for half the steps or fewer); a
    creeping bead at g~ ~ 0 is marched at its share from the start, exactly as a given
    steps= at that resolution (its share is 1), and meets tol."""
    from sweep.kernels.stepsize import resolution
    ref = reference.dop853_solve(*DAMPED_STICK)
    r = sweep.integrate(*DAMPED_STICK, tol=tol)
    given = sweep.integrate(*DAMPED_STICK, steps=resolution(tol), tol=tol)
    assert ref["status"] in (reference.STUCK, reference.AT_REST)
    assert float(r.e) == 0.0 and float(r.e_err) == 0.0
    assert int(r.n_steps) <= 0.55 * int(given.n_steps), (r.n_steps, given.n_steps)
    out = sweep.integrate(*CREEPS_OUT, tol=tol)
    same = sweep.integrate(*CREEPS_OUT, steps=resolution(tol), tol=tol)
    assert int(out.n_steps) == int(same.n_steps) and float(out.e) == float(same.e)
    e_ref = reference_hp.solve(*CREEPS_OUT)["e"]
    assert abs(float(out.e) - e_ref) <= max(tol, float(out.e_err))


@pytest.mark.parametrize("point", LEAVES)
@pytest.mark.parametrize("tol", [1e-8, 1e-10])
def test_a_bead_wrongly_predicted_to_stick_still_meets_tol(point, tol):
    """Where the march at the floor does not settle a predicted stick (here the bead
    leaves), the point is marched at its share as without it, and refined from there: the
    error and e_err stay within tol."""
    if point[:2] == (1.0, 1.0):
        e_ref = reference.linear_cor(*point[2:]).e
    else:
        e_ref = reference.dop853_cor(*point).e
    r = sweep.integrate(*point, tol=tol)
    err = abs(float(r.e) - e_ref)
    assert e_ref > 0.0 and int(r.status) == reference.OK
    assert float(r.e_err) <= tol and err <= tol and err <= float(r.e_err) + REF_SLACK["kk"]


def test_the_first_marchs_share_is_its_formula_about_the_smallest_share():
    # tol_share skips the fifth root where q is surely below Q_REF P_MIN^5; about that
    # point the share must be clip((q / Q_REF)^(1/5), P_MIN, 1) of the q it predicts.
    import numba

    from sweep.kernels import stepsize
    from sweep.kernels.contact import make_law

    @numba.njit
    def share_and_q(alpha, beta, gamma, gtilde):
        c = make_law(alpha, beta, gamma, gtilde)
        k = stepsize.q_constants(alpha, beta)
        return stepsize.tol_share(c, k)[0], stepsize.predicted_q(c, k)

    edge = stepsize.Q_REF * stepsize.P_MIN ** 5
    for alpha, beta in ((1.5, 1.5), (1.5, 1.25), (2.3, 1.7)):
        c0 = share_and_q(alpha, beta, 1.0, 0.0)[1]
        for rel in np.concatenate([-np.logspace(-16, -1, 40), [0.0], np.logspace(-16, -1, 40)]):
            p, q = share_and_q(alpha, beta, edge * (1 + rel) / c0, 0.0)
            assert p == max((q / stepsize.Q_REF) ** 0.2, stepsize.P_MIN), (alpha, beta, q)


def _linear_deep_well_points(n, seed):
    """Linear-law points decided by the deep-well law (g~ > 1e7) near its no-rebound
    threshold: gamma placed for a target e 10^U(-9, -3) by (23), stick or rebound alike."""
    rng = np.random.default_rng(seed)
    c, r = sweep.large_gtilde_coefficient(1.0, 1.0)
    gtilde = 10 ** rng.uniform(7.2, 14, n)
    e = 10 ** rng.uniform(-9, -3, n) * rng.choice([1, 1j], n)     # 1j: just beyond it
    return (1 - (e ** 2).real) / (2 * c * gtilde ** r), gtilde


def test_a_deep_well_near_its_threshold_is_within_its_estimate():
    # The loss 2 gamma C g~^r is good to its logarithm's rounding (~1e-14 in e^2 here): a
    # rebound of e ~ 6e-8 came back a certain stick (e_err 0), a stick a rebound with e_err
    # 4e-16. Reference: the linear law's exact solution (60 digits).
    gamma, gtilde = _linear_deep_well_points(12, 9)
    gamma = np.append(gamma, [4.6324839160723515e-25, 8.543088299531658e-28])
    gtilde = np.append(gtilde, [586142356160.7988, 13649056082558.898])
    res = sweep.integrate(1.0, 1.0, gamma, gtilde, tol=1e-8)
    assert np.all(res.n_steps == 0)                       # decided by the law, not marched
    old = reference._DPS
    reference._DPS = 60
    try:
        ref = np.array([float(reference.linear_cor(g, x).e) for g, x in zip(gamma, gtilde)])
    finally:
        reference._DPS = old
    assert np.all(np.abs(res.e - ref) <= res.e_err), np.abs(res.e - ref) / res.e_err
    assert np.any(ref == 0) and np.any(ref > 0)          # the draw has both sides
