"""Generate tests/data/hard_cases.csv: the hard-case sets of issue 9 with reference CoR values.

Every value comes from tests/reference_hp.py (nothing from ``sweep``), or from an exact
argument where one exists. Run from the repository root (about a minute on 2 cores; the mpmath check a few minutes)::

    nice python tests/data/make_hard_cases.py            # writes tests/data/hard_cases.csv
    nice python tests/data/make_hard_cases.py --mp 40    # re-solve 40 rebounds in mpmath
    nice python tests/data/make_hard_cases.py --dop853   # grazing rows against DOP853

Sets (column ``set``)
---------------------
creep
    alpha, beta ~ U[1, 5], gamma ~ 10^U[0, 2], at g~ = 0 and at g~ = 1e-6 (the same 80
    triples at both loads; numpy ``default_rng(20250109)``).
grazing
    gamma = gamma_c(g~) (1 +- d), d in {1e-5, 1e-6, 1e-7}, for linear (1, 1), Hertz (1.5, 1),
    TTI (1.5, 1.25), KK (1.5, 1.5), SHC (1.5, 2.5) and g~ in {1e-3, 1e-2, 0.1, 1, 10, 100,
    1e3}; gamma_c by bisection on the reference's decision to 1e-12 relative (the linear law's
    is checked against its closed form); plus the issue's three named grazing examples.
undamped
    gamma = 0 at g~ up to 1e12 for nine laws: e = 1 exactly (energy conservation: H = 1/2 for
    ever and e^2 = 2 H at detachment), reference bound 0.
huge_gamma
    gamma in {1e6, 1e8, 1e10, 1e12} for nine laws at g~ in {0, 1e-3, 1, 1e3}: decided by the
    certificates of docs/creep.md (no rebound) or, kappa < 0 at g~ = 0, by the slow-manifold
    jump, checked against the asymptotic law e = E (gamma beta)^(-(alpha+1)/|kappa|).
named
    the issue's other points (creep stress points, linear overdamped, gamma = 0 with a huge
    load, g~ = 1e190 and 1e8 with damping).

Columns
-------
set, alpha, beta, gamma, gtilde, e_ref, bound, sticks_ref, decided, status_ref, rest_hit,
excluded, note. ``bound`` is the reference's own error bound on e_ref (see
``reference_bound``); ``sticks_ref`` is True where the bead provably never leaves;
``decided`` is False where 0 < e_true <= bound + 1e-9, so that either decision is within the
1e-9 target (e.g. a rebound at 1e-30); ``rest_hit`` flags a trajectory that enters the
report's rest box max(|u - u-bar|, |v|) < 1e-8 before its end (an integrator that stops
there returns 0); ``excluded`` gives a reason where the truth cannot be pinned to 1e-9.
"""
from __future__ import annotations

import argparse
import csv
import math
import multiprocessing as mp
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import reference_hp as R  # noqa: E402
from reference import linear_cor  # noqa: E402

LAWS = {"linear": (1.0, 1.0), "hertz": (1.5, 1.0), "tti": (1.5, 1.25), "kk": (1.5, 1.5),
        "shc": (1.5, 2.5)}
EXTRA = {"a1b5": (1.0, 5.0), "a5b1": (5.0, 1.0), "a5b5": (5.0, 5.0), "a2b3": (2.0, 3.0)}
GRAZE_LOADS = (1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3)
GRAZE_OFFSETS = (1e-5, 1e-6, 1e-7)
NAMED_GRAZING = [(1.0, 1.0, 1.1666313143697047, 0.05), (1.0, 1.0, 0.00017674132979743693, 30.0),
                 (1.5, 2.5, 60.897352806082864, 0.001)]
NAMED_OTHER = [(2.0, 1.0, 10.0, 0.0), (1.5, 1.0, 10.0, 0.0), (2.5, 1.5, 10.0, 0.0),
               (3.66463173468, 2.71816693184, 7.67044842593, 0.0), (1.0, 1.0, 2e8, 0.0),
               (1.0, 1.0, 0.0, 1.9e7), (1.5, 1.5, 0.1, 1e190), (1.0, 5.0, 0.1, 1e8),
               (1.5, 2.5, 10.0, 0.0), (2.0, 3.0, 100.0, 0.0)]
SEED = 20250109
N_CREEP = 80
TARGET = 1e-9
# Below this the reference stops following a rebound whose energy bounds e (NEGLIGIBLE).
E_NEGLIGIBLE = 1e-18
FIELDS = ["set", "alpha", "beta", "gamma", "gtilde", "e_ref", "bound", "sticks_ref", "decided",
          "status_ref", "rest_hit", "excluded", "note"]


# --- the points ---------------------------------------------------------------------------

def creep_points():
    rng = np.random.default_rng(SEED)
    a = rng.uniform(1, 5, N_CREEP)
    b = rng.uniform(1, 5, N_CREEP)
    g = 10 ** rng.uniform(0, 2, N_CREEP)
    return [(float(x), float(y), float(z), G) for G in (0.0, 1e-6) for x, y, z in zip(a, b, g)]


def _gc(args):
    name, G = args
    a, b = LAWS[name]
    lo, hi = R.critical_gamma(a, b, G, rtol=1e-12)
    return name, G, math.sqrt(lo * hi), hi / lo - 1


def linear_gamma_c(G, iters=200):
    """The linear law's boundary from its closed form (tests/reference.py), bisection."""
    lo, hi = 0.0, 2.0
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        lo, hi = (mid, hi) if linear_cor(mid, G).e > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def grazing_points(pool):
    jobs = [(n, G) for n in LAWS for G in GRAZE_LOADS]
    gcs = pool.map(_gc, jobs)
    pts, info = [], []
    for name, G, gc, width in gcs:
        a, b = LAWS[name]
        note = f"gamma_c={gc!r} (+-{width:.0e})"
        if name == "linear":
            exact = linear_gamma_c(G)
            note += f", closed form {abs(gc / exact - 1):.1e} off"
        info.append((name, G, gc, note))
        for d in GRAZE_OFFSETS:
            for side in (-1, 1):
                pts.append(((a, b, gc * (1 + side * d), G), f"{name} {'below' if side < 0 else 'above'} gamma_c by {d:.0e}; {note}"))
    pts += [(p, "issue 9 named grazing example") for p in NAMED_GRAZING]
    return pts, info


def undamped_points():
    laws = {**LAWS, **EXTRA}
    return [((a, b, 0.0, G), f"{n}") for n, (a, b) in laws.items()
            for G in (0.0, 1.0, 1e3, 1e6, 1e9, 1e12)]


def huge_gamma_points():
    laws = {**LAWS, **EXTRA}
    return [((a, b, g, G), n) for n, (a, b) in laws.items() for g in (1e6, 1e8, 1e10, 1e12)
            for G in (0.0, 1e-3, 1.0, 1e3)]


# --- the reference values ---------------------------------------------------------------------

def reference_bound(r1, r2):
    """Bound on e_ref from two Taylor solutions (order 26 at tol eps/4 and order 18 at tol
    1e-16, both longdouble): twice their difference (truncation), plus ten times the chosen
    formula's rounding estimate; the bound of NEGLIGIBLE points is their energy bound."""
    if r1["status"] == R.NEGLIGIBLE:
        return max(r1["e_bound"], r2.get("e_bound", 0.0) or 0.0)
    if r1["status"] in (R.STUCK, R.CREEP):
        return 0.0
    d = abs(r1["e"] - r2["e"]) if r2["status"] == r1["status"] else math.inf
    return 2 * d + 10 * r1["e_est_err"] + 1e-16 * r1["e"]


def _solve_row(job):
    set_name, (a, b, g, G), note = job
    t0 = time.perf_counter()
    if g == 0.0:
        # Exact: without damping H = 1/2 for ever and e^2 = 2 H at detachment.
        return dict(set=set_name, alpha=a, beta=b, gamma=g, gtilde=G, e_ref=1.0, bound=0.0,
                    sticks_ref=False, decided=True, status_ref="OK", rest_hit=False, excluded="",
                    note=(note + "; e = 1 exactly (energy conservation)").lstrip("; ")), 0.0
    prec = "mp" if G > 1e100 else "ld"     # longdouble overflows in the series beyond
    kw = dict(prec=prec, dps=30) if prec == "mp" else {}
    kw["e_negligible"] = E_NEGLIGIBLE
    r1 = R.solve(a, b, g, G, max_steps=100_000, **kw)
    r2 = R.solve(a, b, g, G, max_steps=100_000, order=18, tol=1e-16, **kw)
    if r1["status"] != r2["status"]:
        raise RuntimeError(f"the two reference runs disagree at {(a, b, g, G)}: {r1} {r2}")
    if r1["status"] == R.BUDGET:
        raise RuntimeError(f"reference budget exhausted at {(a, b, g, G)}")
    bound = reference_bound(r1, r2)
    e = r1["e"] if r1["status"] == R.OK else 0.0
    sticks = r1["status"] in (R.STUCK, R.CREEP)
    decided = sticks or e > bound + TARGET
    excluded = ""
    if not bound <= 1e-12:
        excluded = f"reference bound {bound:.1e} > 1e-12"
    if prec == "mp":
        note = (note + "; mpmath reference (states beyond longdouble's series range)").lstrip("; ")
    note = "; ".join(x for x in (note, f"cert={r1['cert']}" if r1["cert"] else "",
                                 "slow-manifold jump" if r1["jumped"] else "") if x)
    row = dict(set=set_name, alpha=a, beta=b, gamma=g, gtilde=G, e_ref=e, bound=bound,
               sticks_ref=sticks, decided=decided, status_ref=R.STATUS_NAMES[r1["status"]],
               rest_hit=bool(r1["rest_hit"]), excluded=excluded, note=note)
    return row, time.perf_counter() - t0


def _mp_check(job):
    (a, b, g, G), e_ld, status = job
    r = R.solve(a, b, g, G, prec="mp", dps=36, max_steps=100_000, e_negligible=E_NEGLIGIBLE)
    return (a, b, g, G), e_ld, r["e"] if r["status"] == R.OK else 0.0, R.STATUS_NAMES[r["status"]], status


def dop853_check(path, set_name="grazing"):
    """Decisions and e of one set against tests/reference.py's DOP853 (independent logic:
    adaptive steps, events on its dense output); prints mismatches and the max |de| per g~."""
    from reference import dop853_cor
    with open(path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["set"] == set_name]
    mism, worst = 0, {}
    for r in rows:
        p = tuple(float(r[k]) for k in ("alpha", "beta", "gamma", "gtilde"))
        d = dop853_cor(*p)
        if d.sticks != (r["sticks_ref"] == "True"):
            mism += 1
            print("decision differs", p, r["e_ref"], d.e)
        else:
            worst[p[3]] = max(worst.get(p[3], 0.0), abs(d.e - float(r["e_ref"])))
    print(f"DOP853 on {set_name}: {len(rows)} rows, {mism} decision mismatches; max |de| by g~: "
          + ", ".join(f"{G:g}: {v:.1e}" for G, v in sorted(worst.items())))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(HERE, "hard_cases.csv"))
    ap.add_argument("--mp", type=int, default=0,
                    help="instead of generating, re-solve this many rows of --out in mpmath")
    ap.add_argument("--dop853", action="store_true",
                    help="instead of generating, check the grazing rows of --out against DOP853")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    if args.mp:
        return mp_check(args.out, args.mp, args.workers)
    if args.dop853:
        return dop853_check(args.out)
    t0 = time.time()
    with mp.Pool(args.workers) as pool:
        graze, info = grazing_points(pool)
        for name, G, gc, note in info:
            print(f"gamma_c {name:6s} g~={G:g}: {note}", flush=True)
        jobs = [("creep", p, "") for p in creep_points()]
        jobs += [("grazing", p, n) for p, n in graze]
        jobs += [("undamped", p, n) for p, n in undamped_points()]
        jobs += [("huge_gamma", p, n) for p, n in huge_gamma_points()]
        jobs += [("named", p, "issue 9 named point") for p in NAMED_OTHER]
        out = pool.map(_solve_row, jobs, chunksize=4)
        rows = [r for r, _ in out]
        slow = sorted(((t, r["set"], r["alpha"], r["beta"], r["gamma"], r["gtilde"])
                       for r, t in out), reverse=True)[:5]
        print("slowest reference points:", slow)
    with open(args.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    print(f"wrote {len(rows)} rows to {args.out} in {time.time() - t0:.0f} s")


def mp_check(path, n, workers):
    """Re-solve n rebound rows of the file in mpmath (36 digits, order ~45): the independent
    precision check of the longdouble values (prints each difference and the maximum)."""
    with open(path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh)
                if r["status_ref"] == "OK" and float(r["gamma"]) > 0 and float(r["gtilde"]) < 1e100]
    step = max(1, len(rows) // n)
    pick = rows[::step][:n]
    jobs = [((float(r["alpha"]), float(r["beta"]), float(r["gamma"]), float(r["gtilde"])),
             float(r["e_ref"]), r["status_ref"]) for r in pick]
    with mp.Pool(workers) as pool:
        chk = pool.map(_mp_check, jobs, chunksize=1)
    worst = worst_rel = 0.0
    for (p, e_ld, e_mp, st_mp, st_ld), r in zip(chk, pick):
        d = abs(e_ld - e_mp)
        worst = max(worst, d)
        worst_rel = max(worst_rel, d / max(float(r["bound"]), 1e-300))
        print(f"mp check {r['set']:10s} {p}: ld {e_ld!r} mp {e_mp!r} |d| {d:.1e} "
              f"bound {float(r['bound']):.1e} {st_ld}/{st_mp}")
    print(f"mp check: {len(chk)} points, max |e_ld - e_mp| = {worst:.2e}, "
          f"max |e_ld - e_mp| / bound = {worst_rel:.2f}")


if __name__ == "__main__":
    main()
