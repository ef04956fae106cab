"""Is ``e_err`` honest at the extremes? A randomized audit against the extended-precision reference.

    python benchmarks/hp_audit.py [--n 250] [--seed 1] [--families a b c d e f] [--cap 3]

Draws ``--n`` points in each family, solves each with the test suite's extended-precision
reference (``tests/reference_hp.py``, longdouble; a point whose reference takes more than
``--cap`` seconds is skipped and counted) and with ``sweep.integrate`` at the defaults and
``tol`` 1e-6, 1e-8, 1e-10, and prints one line per family and setting: points, violations
of each kind, budget-exhausted points, and the largest true error over ``e_err``.

Families (exponents: the report's 1, 5/4, 3/2, 2, 5/2, 3 drawn often):

* ``a``: alpha, beta in [1, 5], gamma = 10**U(-8, 12), g~ = 0 (30%) or 10**U(-8, 8);
* ``b``: |kappa| = |alpha + 1 - 2 beta| < 0.05, gamma = 10**U(-1, 3), g~ = 0 or 10**U(-9, -3);
* ``c``: grazing, 1e-9 .. 1e-2 relative from the numerical g~_c or gamma_c
  (:func:`sweep.critical_gtilde`, :func:`sweep.critical_gamma`);
* ``d``: alpha = 1 or beta = 1 exactly, or beta = alpha + 1;
* ``e``: light damping gamma = 10**U(-12, -6) under loads g~ = 10**U(2, 12);
* ``f``: kappa < 0 at g~ = 0 with gamma such that the creep law gives e ~ 1e-5 .. 1e-200.

Violations: ``bound`` (true error > 2 e_err, the design factor), ``tol`` (beyond both tol and
e_err), ``stick`` (STUCK or AT_REST where the reference rebounds by more than 10 tol + 2
e_err), ``rebound`` (OK where the reference certainly sticks, e > 2 e_err), ``nan`` (NaN or
INVALID for a valid point), ``budget`` (a budget bound below the reference). The reference's
own bound is added to every allowance. docs/accuracy.md gives the figures of 2026-12-02.
"""
from __future__ import annotations

import argparse
import math
import signal
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import reference_hp  # noqa: E402
import sweep  # noqa: E402
from sweep import Status  # noqa: E402

EXPONENTS = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0)
SETTINGS = {"defaults": None, "tol=1e-6": 1e-6, "tol=1e-8": 1e-8, "tol=1e-10": 1e-10}
KINDS = ("bound", "tol", "stick", "rebound", "nan", "budget")


def _exponent(rng, lo=1.0, hi=5.0, p=0.6):
    return float(rng.choice(EXPONENTS)) if rng.random() < p else float(rng.uniform(lo, hi))


def _load(rng, p0, lo, hi):
    return 0.0 if rng.random() < p0 else float(10 ** rng.uniform(lo, hi))


def _kappa_point(rng, kappa, lo, hi, p0):
    """(alpha, beta, gamma, g~) with beta set by kappa, or None where beta < 1."""
    a = _exponent(rng, p=0.4)
    b = (a + 1.0 - kappa) / 2.0
    return None if b < 1.0 else (a, b, float(10 ** rng.uniform(lo, hi)), _load(rng, p0, -9, -3))


def draw(family: str, n: int, rng) -> list[tuple[float, float, float, float]]:
    """The family's points (module docstring)."""
    if family == "c":
        return _grazing(n, rng)
    points = []
    while len(points) < n:
        if family == "a":
            p = (_exponent(rng), _exponent(rng), float(10 ** rng.uniform(-8, 12)),
                 _load(rng, 0.3, -8, 8))
        elif family == "b":
            kappa = 0.0 if rng.random() < 0.15 else float(rng.uniform(-0.05, 0.05))
            p = _kappa_point(rng, kappa, -1, 3, 0.5)
        elif family == "d":
            a = _exponent(rng, 1.0, 4.0)
            pair = [(1.0, a), (a, 1.0), (a, a + 1.0)][int(rng.integers(3))]
            p = pair + (float(10 ** rng.uniform(-6, 6)), _load(rng, 0.3, -6, 6))
        elif family == "e":
            p = (_exponent(rng), _exponent(rng), float(10 ** rng.uniform(-12, -6)),
                 float(10 ** rng.uniform(2, 12)))
        else:                       # "f": e ~ (gamma beta)^((alpha + 1) / kappa) = 10^L
            a, kappa = _exponent(rng, p=0.4), -10 ** rng.uniform(-2.3, -0.3)
            L = rng.uniform(-200, -5)
            b = (a + 1.0 - kappa) / 2.0
            g = 10 ** (L * kappa / (a + 1.0)) / b
            p = (a, b, float(g), 0.0) if 1e-3 < g < 1e12 else None
        if p is not None:
            points.append(p)
    return points


def _grazing(n, rng):
    """Points just above or below the numerical no-rebound threshold (g~_c or gamma_c)."""
    a = np.array([_exponent(rng, 1.0, 4.0) for _ in range(n)])
    b = np.array([_exponent(rng, 1.0, 4.0) for _ in range(n)])
    by_load = rng.random(n) < 0.7
    x = np.where(by_load, 10 ** rng.uniform(-4, 1, n), 10 ** rng.uniform(-3, 3, n))
    crit = np.where(by_load, sweep.critical_gtilde(a, b, x, method="numeric"),
                    sweep.critical_gamma(a, b, x, method="numeric"))
    rel = 10 ** rng.uniform(-9, -2, n) * np.where(rng.random(n) < 0.5, 1.0, -1.0)
    near = crit * (1.0 + rel)
    return [(a[i], b[i], x[i], near[i]) if by_load[i] else (a[i], b[i], near[i], x[i])
            for i in range(n) if np.isfinite(crit[i]) and crit[i] > 0.0]


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout


def reference(point, cap):
    """``(e_ref, bound, certainly_sticks)``, or None where the reference gives no value
    within ``cap`` seconds (or none at all: budget)."""
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, cap)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # its series' overflows
            r = reference_hp.solve(*point, e_negligible=0.0)
    except (_Timeout, ArithmeticError, ValueError):
        return None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    status = reference_hp.STATUS_NAMES[r["status"]]
    if status == "OK":
        bound = 10 * max(float(r.get("e_est_err", 0.0) or 0.0), 0.0) \
            + 1e-18 * math.sqrt(r.get("steps", 1) + 1)
        return float(r["e"]), bound, False
    if status in ("STUCK", "CREEP"):
        return 0.0, 0.0, True
    if status == "NEGLIGIBLE":
        return 0.0, float(r["e_bound"]), False
    return None


def violations(e, e_err, status, ref, tol):
    """The kinds of violation (module docstring) of one point at one setting, and the ratio
    of its true error to its e_err."""
    e_ref, bound, sticks = ref
    err, slack = abs(e - e_ref), bound + 1e-15
    if not (math.isfinite(e) and math.isfinite(e_err)) or status == Status.INVALID:
        return ["nan"], math.inf
    if status == Status.BUDGET_EXHAUSTED:
        return (["budget"] if e_ref > e + 2 * e_err + slack else []), 0.0
    found = []
    if err > 2 * e_err + slack:
        found.append("bound")
    if tol is not None and err > max(tol, e_err) + slack:
        found.append("tol")
    if status in (Status.STUCK, Status.AT_REST) and e_ref > 10 * (tol or 1e-9) + 2 * e_err + bound:
        found.append("stick")
    if status == Status.OK and sticks and e > 2 * e_err:
        found.append("rebound")
    return found, (err / e_err if e_err > 0 else (0.0 if err <= slack else math.inf))


def audit(family, args, rng):
    """One printed line per setting for the family."""
    t0 = time.perf_counter()
    points = draw(family, args.n, rng)
    refs = [reference(p, args.cap) for p in points]
    keep = [i for i, r in enumerate(refs) if r is not None]
    a, b, g, G = (np.array([points[i][k] for i in keep]) for k in range(4))
    for name, tol in SETTINGS.items():
        r = sweep.integrate(a, b, g, G, tol=tol)
        counts, worst = dict.fromkeys(KINDS, 0), 0.0
        for j, i in enumerate(keep):
            found, ratio = violations(r.e[j], r.e_err[j], r.status[j], refs[i], tol)
            for kind in found:
                counts[kind] += 1
            worst = max(worst, ratio) if not found else worst
        budget = int(np.count_nonzero(r.status == Status.BUDGET_EXHAUSTED))
        print(f"family {family} {name:10s}: {len(keep)} points ({len(points) - len(keep)} "
              f"without a reference), violations {counts}, budget exhausted {budget}, "
              f"largest true/e_err elsewhere {worst:.3g}", flush=True)
    print(f"family {family}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=250, help="points per family")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--families", nargs="+", default=list("abcdef"), choices=list("abcdef"))
    p.add_argument("--cap", type=float, default=3.0, help="seconds per reference point")
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    for family in args.families:
        audit(family, args, rng)


if __name__ == "__main__":
    main()
