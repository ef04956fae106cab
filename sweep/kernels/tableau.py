"""Runge-Kutta tableaux held as data.

The integrator is written once against these arrays (``A``, ``B``, ``C``, the embedded error
weights ``E`` and the dense-output matrix ``P``), so a different explicit pair can be
swapped in without touching the stepping or event code.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Tableau", "DORMAND_PRINCE_54"]


class Tableau(NamedTuple):
    """An explicit Runge-Kutta pair with a continuous extension.

    Attributes
    ----------
    name : str
    order : int
        Order of the propagated solution (weights ``B``).
    error_order : int
        Order of the embedded solution ``B - E``.
    dense_order : int
        Order of the continuous extension.
    C : ndarray, shape (s,)
        Nodes.
    A : ndarray, shape (s, s)
        Strictly lower-triangular stage coefficients.
    B : ndarray, shape (s,)
        Weights of the propagated solution.
    E : ndarray, shape (s,)
        ``B - B_embedded``: local error estimate ``h * sum(E_i k_i)``.
    P : ndarray, shape (s, q)
        Dense output: ``y(t + theta h) = y + h * sum_j (K^T P)[:, j] theta^(j+1)``.
    fsal : bool
        Last stage evaluates f at the step's end point (reusable as the next first stage).
    """

    name: str
    order: int
    error_order: int
    dense_order: int
    C: np.ndarray
    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    P: np.ndarray
    fsal: bool


def _frozen(x):
    arr = np.array(x, dtype=np.float64)
    arr.setflags(write=False)
    return arr


#: Dormand & Prince (1980) 5(4) pair, 7 stages with FSAL, and Shampine's (1986) 4th-order
#: continuous extension (the coefficients of scipy's RK45).
DORMAND_PRINCE_54 = Tableau(
    name="Dormand-Prince 5(4)",
    order=5,
    error_order=4,
    dense_order=4,
    C=_frozen([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0]),
    A=_frozen([
        [0, 0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0, 0],
        [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0],
    ]),
    B=_frozen([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0]),
    E=_frozen([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40]),
    P=_frozen([
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]),
    fsal=True,
)
