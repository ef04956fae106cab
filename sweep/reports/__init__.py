"""Reports: accuracy maps of a sweep, the report's tables and figures, speed against error,
the error model of ``method = "auto"``.

Four reports, each a plain function (run from the command line by ``sweep report``, whose
arguments live in :mod:`sweep.cli`):

:func:`accuracy_report` (``sweep report accuracy DATASET.nc [--out DIR]``)
    Heat maps of ``|e_method - e_numeric|`` over (gamma, g~) for every approximation stored
    in a dataset written by ``sweep run``, with the numerical stick/rebound boundary and the
    report's approximate boundary (24) drawn over them, and a table of the maximum and median
    absolute error per region. See :mod:`sweep.reports.accuracy`.
:func:`paper_report` (``sweep report paper [--out DIR]``)
    The report's Tables 2-5 recomputed next to the published numbers, and its Figures 8-11
    (g~_c against gamma). See :mod:`sweep.reports.paper`.
:func:`speed_report` (``sweep report speed [--out DIR]``)
    Work-precision: max abs error against CPU time per point and against points/s for the
    integrator at several accuracy targets ``tol``, every approximation, and the peers a
    user would otherwise pick (scipy's ``solve_ivp``; numbalsoda and diffrax when
    installed, :mod:`sweep.reports.peers`), with the time ratio at equal error. See
    :mod:`sweep.reports.speed`.
:func:`error_model_report` (``sweep report error-model [--out FILE.npz]``)
    The error bounds of the closed forms over (alpha, beta, gamma, g~) that ``method =
    "auto"`` chooses by, measured against the numerical CoR, and their validation on random
    points. See :mod:`sweep.reports.error_model`.

Their shared helpers (plotting backend, machine description, tables) are in
:mod:`sweep.reports.common`; the published numbers in :mod:`sweep.reports.paper_values`.
matplotlib (Agg backend) and xarray are imported inside the functions, so importing the
reports stays fast. Every report writes PNG figures and tables (CSV and markdown) into its
output directory and returns a dict of what it computed.

This package only re-exports the entry points (and the documented table helpers) for
users; no module of the package imports it: each report module imports
:mod:`~sweep.reports.common` and :mod:`~sweep.reports.paper_values` directly, so the report
modules form no cycle. Floor 5: below it the reports may import :mod:`sweep.critical`,
:mod:`sweep.api`, :mod:`sweep.model` and the public ``sweep`` names; never
:mod:`sweep.cli`.
"""
from __future__ import annotations

from sweep.reports.accuracy import accuracy_report
from sweep.reports.common import format_value, machine_description, write_table
from sweep.reports.error_model import error_model_report
from sweep.reports.paper import paper_report
from sweep.reports.speed import speed_report

__all__ = ["accuracy_report", "paper_report", "speed_report", "error_model_report",
           "machine_description",
           "write_table", "format_value"]
