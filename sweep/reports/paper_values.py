"""The report's published numbers that ``sweep report paper`` puts next to its own.

Transcribed from Chatterjee, James, Brogliato (2021), INRIA hal-03462750, Tables 2-5: the
maximum absolute error of the O(gamma^2) approximation (36)-(38) of Prop. 2 against the
numerical CoR, with I(g~), Q(g~) either computed numerically ((41), (42); at g~ = 0 the exact
values (39), (40), marked * in the report) or approximated by (48), (49) with n = 21.

Each table has two parts:

(a) g~ in {0, 0.05, 1}: two gamma windows, printed "gamma < 0.02" and "gamma >= 0.02";
(b) g~ = 10: three gamma windows whose printed edges differ per model.

The source is an OCR copy of the report (``paper/`` of the shared folder). Entries that the
OCR garbled beyond reading are ``None``, with the reason in :data:`TRANSCRIPTION_NOTES`;
nothing here was guessed.

How the report's windows were built
-----------------------------------
The report says the maxima were taken on 1000-point gamma grids. Its printed window edges
fit one rule, used by :mod:`sweep.reports.paper`: the grid is
``linspace(0, min(0.1, 1.1 gamma_c), 1000)`` with gamma_c the no-rebound threshold (24) at
that g~, and the windows are ``gamma < 0.2 G``, ``0.2 G <= gamma <= 0.92 G``,
``gamma > 0.92 G`` with ``G`` the grid's end. For g~ <= 1 this gives 0.02 (the printed
edge; the report merges the last two windows into "gamma >= 0.02"), and for g~ = 10 it
gives the printed edges below to the printed digits (KK: G = 1.1 * 0.0016664 = 0.001833,
0.2 G = 0.000367, 0.92 G = 0.00169). This is also what the authors' published MATLAB
scripts do (report ref. [38], ``PaperResults/AnalVarCoeffCompare.m``).

Pure data: imports only the registry's laws (the command line, which has loaded the registry
already, reads :data:`PAPER_MODELS` for its choices).
"""
from __future__ import annotations

from sweep.registry import MODELS

__all__ = ["PAPER_MODELS", "GTILDES", "TABLE_A", "TABLE_B", "TABLE_B_EDGES",
           "FIGURES_CRITICAL", "TRANSCRIPTION_NOTES", "WINDOW_FRACTIONS", "GRID_END_FACTOR",
           "GAMMA_MAX"]

#: The four contact models of Tables 2-5 and Figures 8-11: key -> (alpha, beta, name, table,
#: figure of g~_c).
#: The exponents are the registry's (its MODELS are the report's Table 1).
PAPER_MODELS = {key: (*MODELS[key], *rest) for key, rest in {
    "hertz": ("Hertz + linear damping", "Table 2", "Figure 8"),
    "tti": ("Tsuji-Tanaka-Ishida", "Table 3", "Figure 9"),
    "kk": ("Kuwabara-Kono", "Table 4", "Figure 10"),
    "shc": ("Simon-Hunt-Crossley", "Table 5", "Figure 11"),
}.items()}

#: The loads g~ of Tables 2-5 (and of Figures 12-23).
GTILDES = (0.0, 0.05, 1.0, 10.0)

#: The gamma grid: ``linspace(0, min(GAMMA_MAX, GRID_END_FACTOR * gamma_c(24)), n)``.
GAMMA_MAX = 0.1
GRID_END_FACTOR = 1.1
#: Window edges as fractions of the grid's end (see the module docstring).
WINDOW_FRACTIONS = (0.2, 0.92)

# Part (a): TABLE_A[model][g~] = {"numint": (gamma < 0.02, gamma >= 0.02),
#                                 "approx": (gamma < 0.02, gamma >= 0.02)}
# "numint" is the report's "Exact [(39),(40)] / Num. [(41),(42)]" column pair (exact I(0),
# Q(0) at g~ = 0), "approx" its "Approx. [(48),(49)]" pair.
TABLE_A = {
    # Table 2(a), alpha = 3/2, beta = 1 (Hertz stiffness with linear damping).
    "hertz": {
        0.0: {"numint": (5.39e-6, 6.57e-4), "approx": (5.39e-6, 6.57e-4)},
        0.05: {"numint": (5.63e-6, 6.89e-4), "approx": (1.32e-5, 7.26e-4)},
        1.0: {"numint": (6.82e-5, 1.77e-2), "approx": (1.32e-4, 1.85e-2)},
    },
    # Table 3(a), alpha = 3/2, beta = 5/4 (Tsuji-Tanaka-Ishida).
    "tti": {
        0.0: {"numint": (None, 1.11e-3), "approx": (9.17e-6, 1.11e-3)},
        0.05: {"numint": (9.88e-6, 1.12e-3), "approx": (1.77e-5, 1.12e-3)},
        1.0: {"numint": (1.65e-4, 1.10e-1), "approx": (2.40e-4, 1.11e-1)},
    },
    # Table 4(a), alpha = beta = 3/2 (Kuwabara-Kono).
    "kk": {
        0.0: {"numint": (1.37e-5, 1.60e-3), "approx": (1.37e-5, 1.60e-3)},
        0.05: {"numint": (1.52e-5, 1.78e-3), "approx": (2.33e-5, None)},
        1.0: {"numint": (3.67e-4, 2.08e-1), "approx": (4.58e-4, 2.09e-1)},
    },
    # Table 5(a), alpha = 3/2, beta = 5/2 (Simon-Hunt-Crossley).
    "shc": {
        0.0: {"numint": (3.87e-5, 4.26e-3), "approx": (3.87e-5, 4.26e-3)},
        0.05: {"numint": (4.94e-5, 5.39e-3), "approx": (5.84e-5, 5.43e-3)},
        1.0: {"numint": (2.06e-3, None), "approx": (2.20e-3, 3.11e-1)},
    },
}

# Part (b), g~ = 10: printed window edges (gamma < e1, e1 <= gamma <= e2, gamma > e2) ...
TABLE_B_EDGES = {
    "hertz": (None, 0.0051),      # Table 2(b): first edge unreadable in the OCR copy
    "tti": (0.00063, 0.0029),     # Table 3(b)
    "kk": (0.000367, 0.00169),    # Table 4(b)
    "shc": (0.00004, 0.00020),    # Table 5(b)
}
# ... and maxima: TABLE_B[model] = {"numint": (w1, w2, w3), "approx": (w1, w2, w3)}.
TABLE_B = {
    "hertz": {"numint": (None, None, 5.63e-13), "approx": (8.03e-5, 1.33e-2, 5.63e-13)},
    "tti": {"numint": (5.56e-8, 3.32e-4, 2.84e-13), "approx": (8.07e-5, 1.76e-2, 2.84e-13)},
    "kk": {"numint": (1.06e-7, 2.38e-4, None), "approx": (8.11e-5, 2.11e-2, 2.84e-13)},
    "shc": {"numint": (3.83e-7, 9.67e-4, 2.34e-13), "approx": (8.57e-5, 2.50e-1, 2.84e-13)},
}

#: Figures 8-11 (g~_c against gamma): gamma = linspace(1e-4, 1, 100) for panel (a), with an
#: inset on linspace(1e-4, 0.01, 100); panel (b) the relative error |g~_c,num - g~_c,(24)| /
#: g~_c,num for gamma <= 0.3. The report's bisection called e "zero" below 1e-4 and stopped
#: at an absolute width 1e-3 in g~ (its text: Sec. 4.2; the figures carry no table of values).
FIGURES_CRITICAL = {"gamma_min": 1e-4, "gamma_max": 1.0, "gamma_max_zoom": 0.01,
                    "n_gamma": 100, "relerr_gamma_max": 0.3, "zero_tol": 1e-4,
                    "bisection_abs_tol": 1e-3}

#: Why an entry above is None (or uncertain), keyed by (model, part, g~, column).
TRANSCRIPTION_NOTES = {
    ("hertz", "b", 10.0, "edge1"):
        "Table 2(b) header unreadable in the copy of the report transcribed here; by the "
        "window rule it would be 0.00111.",
    ("hertz", "b", 10.0, "numint"):
        "Table 2(b) 'Num.' row: the first two maxima are garbled ('...0^{-3}' survives: the "
        "second is of order 1e-3).",
    ("tti", "a", 0.0, "numint"):
        "Table 3(a), g~ = 0, gamma < 0.02, exact coefficients: only '1 x 10^-6*' survives. "
        "At g~ = 0 the other tables print equal exact and approximated values; the "
        "approximated one reads 9.17e-6 (itself partly garbled: '9.17x10^{-10})^{-6}').",
    ("kk", "a", 0.05, "approx"):
        "Table 4(a), g~ = 0.05, approximated coefficients, gamma >= 0.02: missing from the "
        "copy of the report transcribed here.",
    ("shc", "a", 1.0, "numint"):
        "Table 5(a), g~ = 1, gamma >= 0.02, num. coefficients: printed '.11 x 10^-1', its "
        "first digit lost in the copy of the report transcribed here (the approximated "
        "column beside it reads 3.11e-1).",
    ("kk", "b", 10.0, "numint"):
        "Table 4(b), 'Num.' row: the second maximum reads '2.38 x 1' in the copy of the "
        "report transcribed here (2.38e-4 in the reading of Table 4 the package was "
        "specified from), and the third '.84 x 10^-13', its first digit lost (zero to "
        "rounding either way).",
    ("tti", "b", 10.0, "approx"):
        "Table 3(b), 'Approx.' row, third window: printed '2.84 x 10^-5 ... 4 x 10^-13', "
        "read as 2.84e-13 like the row above it (e = 0 in both there).",
    ("shc", "b", 10.0, "numint"):
        "Table 5(b), third window, 'Num.': printed '2 34 x 10^-13' (2.34e-13 or 2.84e-13); "
        "either way zero to rounding.",
}
