"""Reports: accuracy maps of a sweep, the report's tables and figures, speed against error.

Three reports, each a plain function (used by the ``sweep report`` command line):

:func:`accuracy_report` (``sweep report accuracy DATASET.nc [--out DIR]``)
    Heat maps of ``|e_method - e_numeric|`` over (gamma, g~) for every approximation stored
    in a dataset written by ``sweep run``, with the numerical stick/rebound boundary and the
    report's approximate boundary (24) drawn over them, and a table of the maximum and median
    absolute error per region. See :mod:`sweep.reports.accuracy`.
:func:`paper_report` (``sweep report paper [--out DIR]``)
    The report's Tables 2-5 recomputed next to the published numbers, and its Figures 8-11
    (g~_c against gamma). See :mod:`sweep.reports.paper`.
:func:`speed_report` (``sweep report speed [--out DIR]``)
    Work-precision: points per second against the error for the integrator at several
    resolutions, every approximation and scipy's ``solve_ivp`` as a peer. See
    :mod:`sweep.reports.speed`.

matplotlib (Agg backend) and xarray are imported inside the functions, so ``import sweep``
stays fast. Every report writes PNG figures and tables (CSV and markdown) into its output
directory and returns a dict of what it computed.
"""
from __future__ import annotations

import csv
import math
import os
import platform
from pathlib import Path

__all__ = ["accuracy_report", "paper_report", "speed_report", "add_report_commands",
           "machine_description", "write_table", "format_value"]


# --------------------------------------------------------------------------- entry points

def accuracy_report(path, out=None, **kwargs):
    """Accuracy maps and per-region error table of a sweep dataset; see
    :func:`sweep.reports.accuracy.accuracy_report`."""
    from sweep.reports.accuracy import accuracy_report as run

    return run(path, out, **kwargs)


def paper_report(out="paper_report", n_gamma=1000, **kwargs):
    """The report's Tables 2-5 and Figures 8-11; see
    :func:`sweep.reports.paper.paper_report`."""
    from sweep.reports.paper import paper_report as run

    return run(out, n_gamma=n_gamma, **kwargs)


def speed_report(out="speed_report", **kwargs):
    """Work-precision plot and table; see :func:`sweep.reports.speed.speed_report`."""
    from sweep.reports.speed import speed_report as run

    return run(out, **kwargs)


# --------------------------------------------------------------------------- command line

def _print_files(res, heading):
    print(heading)
    for f in res["files"]:
        print(f"  {f}")
    return 0


def _cmd_accuracy(args):
    import sys

    try:
        res = accuracy_report(args.dataset, args.out)
    except (OSError, ValueError) as exc:
        print(f"sweep report accuracy: error: {args.dataset}: {exc}", file=sys.stderr)
        return 1
    return _print_files(res, f"accuracy report of {args.dataset}: {len(res['files'])} files in {res['out']}")


def _cmd_paper(args):
    res = paper_report(args.out, n_gamma=args.n_gamma, n_crit=args.n_crit, steps=args.steps,
                       models=args.models, progress=not args.quiet)
    print(res["markdown"])
    return _print_files(res, f"files in {res['out']}:")


def _cmd_speed(args):
    res = speed_report(args.out, n_points=args.n_points, n_scipy=args.n_scipy,
                       n_check=args.n_check, model=args.model, seed=args.seed,
                       progress=not args.quiet)
    print(res["markdown"])
    return _print_files(res, f"files in {res['out']}:")


def add_report_commands(subparsers):
    """Add ``report {accuracy, paper, speed}`` to an argparse sub-parsers object.

    Each leaf parser gets ``func`` as a default: ``args.func(args)`` runs the report and
    returns the exit status (0).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned.

    Returns
    -------
    argparse.ArgumentParser
        The ``report`` parser.
    """
    from sweep.reports.paper_values import PAPER_MODELS

    rep = subparsers.add_parser(
        "report", help="accuracy maps, the report's tables and figures, speed against error",
        description="Reports built from a sweep dataset, from the report's own test cases, "
                    "or from a timing run. Figures are PNG, tables CSV and markdown.")
    sub = rep.add_subparsers(dest="report", required=True, metavar="REPORT")

    p = sub.add_parser(
        "accuracy", help="error maps of the approximations stored in a dataset",
        description="For each approximation in DATASET: a heat map of |e_method - "
                    "e_numeric| over (gamma, g~), one panel per (alpha, beta), with the "
                    "numerical stick/rebound boundary and the report's boundary (24); and a "
                    "table of max and median abs error per region.")
    p.add_argument("dataset", metavar="DATASET.nc", help="output of `sweep run`")
    p.add_argument("--out", metavar="DIR",
                   help="output directory (default: DATASET's name + '_accuracy')")
    p.set_defaults(func=_cmd_accuracy)

    p = sub.add_parser(
        "paper", help="the report's Tables 2-5 and Figures 8-11, next to its numbers",
        description="Recompute the report's Tables 2-5 (max abs error of the O(gamma^2) "
                    "approximation with numerical and approximated I, Q) on the report's "
                    "gamma grids, print them next to the published values, and redraw "
                    "Figures 8-11 (g~_c against gamma, bisection on the numerical e versus "
                    "eq. (24)).")
    p.add_argument("--out", metavar="DIR", default="paper_report",
                   help="output directory (default: ./paper_report)")
    p.add_argument("--n-gamma", type=int, default=1000, metavar="N",
                   help="gamma grid points per (model, g~) (default 1000, as the report)")
    p.add_argument("--n-crit", type=int, default=100, metavar="N",
                   help="gamma values of Figures 8-11 (default 100, as the report)")
    p.add_argument("--steps", type=float, default=None,
                   help="integrator resolution (default: the package default)")
    p.add_argument("--models", nargs="+", choices=list(PAPER_MODELS), default=None,
                   help="subset of models (default: all four)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_paper)

    p = sub.add_parser(
        "speed", help="work-precision: speed against error, scipy as the peer",
        description="Time the integrator at several resolutions, every approximation and "
                    "scipy's solve_ivp (RK45, DOP853, one point at a time) on one common "
                    "point set; plot time per point against max abs error.")
    p.add_argument("--out", metavar="DIR", default="speed_report",
                   help="output directory (default: ./speed_report)")
    p.add_argument("--n-points", type=int, default=20000, metavar="N",
                   help="common point set size (default 20000)")
    p.add_argument("--n-scipy", type=int, default=100, metavar="N",
                   help="points of the subset given to scipy (default 100)")
    p.add_argument("--n-check", type=int, default=100, metavar="N",
                   help="points on which the reference is cross-checked with DOP853")
    p.add_argument("--model", choices=list(PAPER_MODELS), default="kk",
                   help="contact model of the point set (default kk)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_speed)
    return rep


# --------------------------------------------------------------------------- shared helpers

def use_agg():
    """Import matplotlib with the non-interactive Agg backend; returns ``pyplot``."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _cpu_model():
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_description():
    """Where the numbers were measured: CPU, cores, numba threading, versions.

    Runs a tiny parallel integration first so that numba's threading layer is known.
    """
    import numba
    import numpy as np
    import scipy

    import sweep

    try:
        sweep.integrate(1.5, 1.5, np.full(2048, 0.01), 0.1, parallel=True)
        layer = numba.threading_layer()
    except Exception as exc:  # pragma: no cover - no parallel layer available
        layer = f"unavailable ({exc.__class__.__name__})"
    try:
        affinity = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        affinity = os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "logical_cores": os.cpu_count(),
        "usable_cores": affinity,
        "numba_threads": numba.get_num_threads(),
        "threading_layer": layer,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "sweep": sweep.__version__,
        "platform": platform.platform(),
        "load_average": _loadavg(),
    }


def _loadavg():
    """1-minute load average when measured (other processes compete for the cores)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):  # pragma: no cover - not Unix
        return None


def machine_line(m):
    """One-line form of :func:`machine_description`."""
    return (f"{m['cpu']}, {m['usable_cores']} usable cores ({m['numba_threads']} numba "
            f"threads, {m['threading_layer']} layer); Python {m['python']}, numpy "
            f"{m['numpy']}, scipy {m['scipy']}, numba {m['numba']}, sweep {m['sweep']}; "
            f"{m['platform']}; load average {m.get('load_average')} at start")


def format_value(x, digits=3):
    """Compact text of a table value: ``-`` for None, ``nan``, ``0``, or ``1.23e-04``."""
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if isinstance(x, (bool,)):
        return str(x)
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if math.isnan(x):
        return "nan"
    if x == 0.0:
        return "0"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits - 1}e}"


def write_table(rows, columns, csv_path=None, md_path=None, title=None, notes=(),
                digits=3, formats=None):
    """Write rows (dicts) as CSV (full precision) and/or markdown (``digits`` digits).

    ``formats`` maps a column to a format spec for the markdown (e.g. ``{"alpha": "g"}``).
    Returns the markdown text.
    """
    formats = dict(formats or {})
    formats.setdefault("alpha", "g")
    formats.setdefault("beta", "g")

    def cell(r, c):
        v = r.get(c)
        if c in formats and isinstance(v, (float, int)) and not isinstance(v, bool):
            return format(v, formats[c])
        return format_value(v, digits)

    if csv_path is not None:
        with open(csv_path, "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
            w.writeheader()
            for r in rows:
                w.writerow({c: ("" if r.get(c) is None else
                                (repr(float(r[c])) if isinstance(r.get(c), float) else r[c]))
                            for c in columns})
    lines = []
    if title:
        lines += [f"### {title}", ""]
    lines.append("| " + " | ".join(columns) + " |")
    lines.append("|" + "|".join("---" for _ in columns) + "|")
    for r in rows:
        lines.append("| " + " | ".join(cell(r, c) for c in columns) + " |")
    if notes:
        lines.append("")
        lines += [f"- {n}" for n in notes]
    text = "\n".join(lines) + "\n"
    if md_path is not None:
        Path(md_path).write_text(text, encoding="utf-8")
    return text
