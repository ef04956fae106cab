"""Numerical checks of every claim of docs/creep.md, against tests/reference_hp.py.

Run from the repository root (about a minute)::

    nice python tests/data/creep_checks.py

Prints the tables quoted in docs/creep.md.
"""
from __future__ import annotations

import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import reference_hp as R  # noqa: E402

NEG = 0.0     # follow every rebound, however small


def e_of(a, b, g, G=0.0):
    r = R.solve(a, b, g, G, e_negligible=NEG)
    return r["e"], R.STATUS_NAMES[r["status"]], r


def table_E():
    """kappa < 0, g~ = 0: e (gamma beta)^((alpha+1)/|kappa|) -> E(alpha, beta)."""
    print("\n## E(alpha, beta): e (gamma beta)^((alpha+1)/|kappa|) at g~ = 0\n")
    print("| alpha | beta | kappa | gamma = 10 | gamma = 100 | gamma = 1e4 | gamma = 1e6 |")
    print("|---|---|---|---|---|---|---|")
    for a, b in [(1.5, 2.5), (2.0, 3.0), (1.5, 1.5), (1.0, 5.0), (5.0, 5.0), (4.0, 3.0),
                 (3.66463173468, 2.71816693184), (1.2, 4.5), (1.0, 1.2)]:
        k = R.kappa(a, b)
        cells = []
        for g in (10.0, 100.0, 1e4, 1e6):
            e, st, _ = e_of(a, b, g)
            cells.append(f"{e * (g * b) ** ((a + 1) / -k):.12g}" if e > 0 else st)
        print(f"| {a:g} | {b:g} | {k:.3g} | " + " | ".join(cells) + " |")


def table_kappa0():
    """kappa = 0: e > 0 below gamma^2 beta = 4, the region R (e = 0) above."""
    print("\n## kappa = 0: threshold gamma* = 2 / sqrt(beta)\n")
    print("| alpha | beta | gamma* | e at 0.999 gamma* | status at 1.001 gamma* | e at gamma* (1 - 1e-6) |")
    print("|---|---|---|---|---|---|")
    for a, b in [(1.0, 1.0), (1.5, 1.25), (2.0, 1.5), (3.0, 2.0), (5.0, 3.0)]:
        gs = 2 / math.sqrt(b)
        e1 = e_of(a, b, 0.999 * gs)[0]
        st = e_of(a, b, 1.001 * gs)[1]
        e3 = e_of(a, b, gs * (1 - 1e-6))[0]
        print(f"| {a:g} | {b:g} | {gs:.6g} | {e1:.4g} | {st} | {e3:.3g} |")


def gamma_c0(a, b, lo=1e-3, hi=1e3, rtol=1e-10):
    """kappa > 0, g~ = 0: the damping above which the bead never leaves (bisection)."""
    while hi / lo - 1 > rtol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if R.solve(a, b, mid, 0.0)["status"] == R.OK else (lo, mid)
    return math.sqrt(lo * hi)


def table_kappa_pos():
    print("\n## kappa > 0: gamma_c0 (bisection) against the tau = 0 certificate gamma_R\n")
    print("| alpha | beta | kappa | gamma_c0 | gamma_R | e at 0.99 gamma_c0 | e at (1 - 1e-6) gamma_c0 |")
    print("|---|---|---|---|---|---|---|")
    for a, b in [(1.5, 1.0), (2.0, 1.0), (5.0, 1.0), (2.5, 1.5), (3.0, 1.5), (5.0, 2.5), (1.5, 1.2)]:
        k = R.kappa(a, b)
        gc = gamma_c0(a, b)
        um0 = ((a + 1) / 2) ** (1 / (a + 1))
        gR = 2 * math.sqrt(um0 ** k / b)
        e1 = e_of(a, b, 0.99 * gc)[0]
        e2 = e_of(a, b, gc * (1 - 1e-6))[0]
        print(f"| {a:g} | {b:g} | {k:g} | {gc:.10g} | {gR:.6g} | {e1:.3g} | {e2:.3g} |")


def table_loaded():
    """kappa < 0 with a small load: stuck iff g~ > G*(alpha, beta) lambda^alpha,
    lambda = (gamma beta)^(-2/|kappa|)."""
    print("\n## kappa < 0 under a small load: g~_c lambda^-alpha, lambda = (gamma beta)^(-2/|kappa|)\n")
    print("| alpha | beta | gamma = 10 | gamma = 100 | gamma = 1e4 |")
    print("|---|---|---|---|---|")
    for a, b in [(1.5, 2.5), (1.5, 1.5), (3.66463173468, 2.71816693184), (1.0, 5.0)]:
        k = R.kappa(a, b)
        cells = []
        for g in (10.0, 100.0, 1e4):
            lam = (g * b) ** (-2 / -k)
            lo, hi = 1e-12 * lam ** a, 1e6 * lam ** a
            if R.solve(a, b, g, lo)["status"] != R.OK:
                cells.append("-")
                continue
            while hi / lo - 1 > 1e-8:
                mid = math.sqrt(lo * hi)
                lo, hi = (mid, hi) if R.solve(a, b, g, mid)["status"] == R.OK else (lo, mid)
            cells.append(f"{math.sqrt(lo * hi) / lam ** a:.8g}")
        print(f"| {a:g} | {b:g} | " + " | ".join(cells) + " |")


def table_small_load():
    print("\n## The creep points at g~ = 1e-6 against g~ = 0\n")
    print("| alpha | beta | gamma | kappa | e (g~ = 0) | e (g~ = 1e-6) | u-bar / lambda |")
    print("|---|---|---|---|---|---|---|")
    for a, b, g in [(3.66463173468, 2.71816693184, 7.67044842593), (1.2, 4.5, 80.0),
                    (1.5, 2.5, 10.0), (1.5, 2.5, 100.0), (4.0, 3.0, 50.0), (1.0, 5.0, 100.0),
                    (1.5, 1.5, 10.0)]:
        k = R.kappa(a, b)
        lam = (g * b) ** (-2 / -k)
        e0, s0, _ = e_of(a, b, g)
        e1, s1, _ = e_of(a, b, g, 1e-6)
        print(f"| {a:g} | {b:g} | {g:g} | {k:.3g} | {e0:.6g} {s0} | {e1:.6g} {s1} | "
              f"{1e-6 ** (1 / a) / lam:.3g} |")


if __name__ == "__main__":
    table_E()
    table_kappa0()
    table_kappa_pos()
    table_loaded()
    table_small_load()
