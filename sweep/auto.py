"""The ``"auto"`` method: per point, the cheapest method whose validated error is within tol.

For every point ``(alpha, beta, gamma, g~)`` the kernel :func:`auto_cor` looks up a bound on
the absolute error of each closed form of the report (eqs. (22), (23), (25), (36)-(38)) in an
*error model*, serves the point with the cheapest one whose bound is ``<= tol``, and
integrates (eqs. (3), (4), Algorithm 1) where none qualifies or where the point lies outside
the model. ``method_used`` (flag codes :data:`sweep.registry.SERVED_BY`) records the choice.

The error model (:class:`ErrorModel`, shipped as ``sweep/data/error_model.npz`` and rebuilt
by ``sweep report error-model``, :mod:`sweep.reports.error_model`) is a table of bounds:

* over (gamma, g~): cells between ``gamma_edges`` and ``gtilde_edges`` (first edge 0, then
  log-spaced); a cell's bound is the largest error measured against the package's own
  numerical CoR at sample points on and inside the cell *and its neighbours* (the stick /
  rebound boundary, where every closed form fails, cannot hide between samples), times a
  safety factor, and never below a floor (the judge's own accuracy);
* over (alpha, beta): at the nodes ``alpha`` x ``beta`` (``bound``), and between them
  (``between``: the largest bound of the four surrounding nodes, taken over two
  neighbouring cells on each side, for exponents that are not nodes);
* outside the table (gamma or g~ above its last edge, exponents outside the nodes' range):
  no bound, the point is integrated.

Bounds are stored as int8 codes ``ceil(CODES_PER_DECADE log10(bound))`` (rounded up, so a
code never understates a bound; :data:`NO_BOUND` means none).

The integrated points get auto's ``tol`` as the integrator's accuracy knob, and those whose
``e_err`` is still above it are integrated again at tighter ones
(:data:`RETRY_TOL_FACTORS`).

Owns: the error model's file format, the bound at a point and the per-point selection.
May import: :mod:`sweep.registry` (the methods are called through it) and numpy; lazily,
:func:`sweep.store.write_atomic` (floor 1) to save a model. Floor 2.
"""
from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path
from typing import Any

import numpy as np

from sweep import registry
from sweep.api import composite_integrator_settings

__all__ = ["ErrorModel", "DATA_FILE", "CODES_PER_DECADE", "NO_BOUND", "encode", "decode",
           "default_model", "select", "serve", "auto_cor"]

#: The shipped error model.
DATA_FILE = Path(__file__).resolve().parent / "data" / "error_model.npz"
#: Resolution of the stored bounds: codes per decade (a bound is rounded up by < 1/8 decade).
CODES_PER_DECADE = 8
#: Code of "no bound": the method is never chosen there.
NO_BOUND = np.int8(127)
#: Version of the file format; :meth:`ErrorModel.load` refuses others.
FORMAT = 1


def encode(bound: np.ndarray) -> np.ndarray:
    """Error bounds -> int8 codes, rounded up (inf, NaN or too large: :data:`NO_BOUND`)."""
    b = np.asarray(bound, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.ceil(CODES_PER_DECADE * np.log10(np.maximum(b, 1e-300)))
    c = np.where(np.isfinite(c) & (c < NO_BOUND), c, NO_BOUND)
    return np.clip(c, -127, NO_BOUND).astype(np.int8)


def decode(code: np.ndarray) -> np.ndarray:
    """int8 codes -> error bounds (:data:`NO_BOUND` -> inf)."""
    c = np.asarray(code, dtype=np.float64)
    return np.where(c >= NO_BOUND, np.inf, 10.0 ** (c / CODES_PER_DECADE))


def _bracket(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the nodes around x (equal when x is a node) and whether x is in range."""
    i = np.clip(np.searchsorted(nodes, x, side="left"), 0, nodes.size - 1)
    exact = nodes[i] == x
    inside = (x >= nodes[0]) & (x <= nodes[-1])
    lo = np.where(exact, i, np.maximum(i - 1, 0))
    return lo, i, inside


def _cell(edges: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the cell ``[edges[i], edges[i+1]]`` holding x, and whether one does."""
    i = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    return i, (x >= edges[0]) & (x <= edges[-1])


@dataclasses.dataclass(frozen=True)
class ErrorModel:
    """Bounds on the abs error of each closed form over (alpha, beta, gamma, g~).

    Attributes
    ----------
    methods : tuple of str
        The closed forms the model covers, cheapest first (the order of preference).
    alpha, beta : ndarray
        Exponent nodes (increasing).
    gamma_edges, gtilde_edges : ndarray
        Cell edges over gamma and g~ (increasing, first 0).
    bound : ndarray of int8, shape (alpha, beta, gamma cell, g~ cell, method)
        Codes of the bounds at the exponent nodes (see :func:`decode`).
    between : ndarray of int8, shape (alpha - 1, beta - 1, gamma cell, g~ cell, method)
        Codes of the bounds between exponent nodes.
    info : dict
        How the model was built (judge resolution, safety factor, floor, sampling, costs,
        version, date); JSON-serialisable.
    """

    methods: tuple
    alpha: np.ndarray
    beta: np.ndarray
    gamma_edges: np.ndarray
    gtilde_edges: np.ndarray
    bound: np.ndarray
    between: np.ndarray
    info: dict

    def save(self, path: str | Path) -> None:
        """Write the model as a compressed ``.npz`` (plain arrays plus JSON ``info``).

        The file is written at exactly ``path``, whatever its suffix, and complete or not
        at all (:func:`sweep.store.write_atomic`): by default ``sweep report error-model``
        replaces the file the package ships, which a half-written file would break.
        """
        from sweep import store  # noqa: PLC0415 -- lazily: it imports netCDF4

        arrays = {"format": np.int64(FORMAT), "methods": np.array(self.methods),
                  "alpha": self.alpha, "beta": self.beta, "gamma_edges": self.gamma_edges,
                  "gtilde_edges": self.gtilde_edges, "bound": self.bound,
                  "between": self.between, "info": np.array(json.dumps(self.info))}
        # Through an open file: given a name, numpy appends ".npz" to one without it.
        store.write_atomic(Path(path), lambda fh: np.savez_compressed(fh, **arrays))

    @classmethod
    def load(cls, path: str | Path = DATA_FILE) -> ErrorModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        ValueError
            If the file has another format version or names an unregistered method.
        """
        with np.load(path, allow_pickle=False) as z:
            if int(z["format"]) != FORMAT:
                raise ValueError(f"{path}: error model format {int(z['format'])}, expected "
                                 f"{FORMAT}; rebuild it with `sweep report error-model`")
            model = cls(tuple(str(m) for m in z["methods"]), z["alpha"], z["beta"],
                        z["gamma_edges"], z["gtilde_edges"], z["bound"], z["between"],
                        json.loads(str(z["info"])))
        unknown = [m for m in model.methods if m not in registry.SERVED_BY]
        if unknown:
            raise ValueError(f"{path}: unknown methods {unknown} in the error model")
        return model

    def bounds(self, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray,
               gtilde: np.ndarray) -> np.ndarray:
        """Error bound of every method at flat arrays of points, shape ``(n, methods)``.

        inf where the model has no bound (outside it, or the method is not defined).
        """
        a_lo, a_hi, a_in = _bracket(self.alpha, alpha)
        b_lo, b_hi, b_in = _bracket(self.beta, beta)
        g, g_in = _cell(self.gamma_edges, gamma)
        h, h_in = _cell(self.gtilde_edges, gtilde)
        on_node = (a_lo == a_hi) & (b_lo == b_hi)
        # Between nodes: the cell of the exponent grid holding the point (a node that is not
        # the last one belongs to the cell above it).
        ai = np.minimum(a_lo, self.alpha.size - 2)
        bi = np.minimum(b_lo, self.beta.size - 2)
        code = np.where(on_node[:, None], self.bound[a_lo, b_lo, g, h],
                        self.between[ai, bi, g, h] if self.between.size else NO_BOUND)
        inside = a_in & b_in & g_in & h_in
        return np.where(inside[:, None], decode(code), np.inf)


@functools.lru_cache(maxsize=None)
def default_model() -> ErrorModel:
    """The shipped error model (``sweep/data/error_model.npz``), loaded once."""
    return ErrorModel.load(DATA_FILE)


def select(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, gtilde: np.ndarray,
           tol: float, model: ErrorModel | None = None) -> np.ndarray:
    """Which method serves each point: :data:`sweep.registry.SERVED_BY` codes (int8).

    The cheapest method of the model whose bound is ``<= tol``; ``"numeric"`` where none.
    """
    model = model or default_model()
    ok = model.bounds(alpha, beta, gamma, gtilde) <= tol
    served = np.array([registry.SERVED_BY[m] for m in model.methods], dtype=np.int8)
    first = np.argmax(ok, axis=1) if ok.shape[1] else np.zeros(ok.shape[0], dtype=np.intp)
    chosen = served[first] if served.size else np.zeros(ok.shape[0], dtype=np.int8)
    return np.where(ok.any(axis=1), chosen, np.int8(registry.SERVED_BY["numeric"]))


def serve(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, gtilde: np.ndarray,
          codes: np.ndarray, tol: float, **options: Any) -> tuple[np.ndarray, np.ndarray]:
    """e and status of flat arrays of points, each by the method its code names.

    Parameters
    ----------
    codes : ndarray of int8
        :data:`sweep.registry.SERVED_BY` code per point (what :func:`select` returns).
    tol : float
        Passed to the integrator (its accuracy knob).
    **options
        The integrator's options for the integrated points.
    """
    return _served(alpha, beta, gamma, gtilde, codes, tol, options)[:2]


def _served(alpha, beta, gamma, gtilde, codes, tol, options):
    """:func:`serve`'s ``(e, status)`` and which points may miss ``tol`` (integrated
    points whose estimate stayed above it, :func:`_integrated`)."""
    e = np.empty(alpha.size)
    status = np.empty(alpha.size, dtype=np.int8)
    missed = np.zeros(alpha.size, dtype=bool)
    names = {code: name for name, code in registry.SERVED_BY.items()}
    for code in np.unique(codes):
        idx = np.flatnonzero(codes == code)
        m = registry.METHODS[names[int(code)]]
        if m.integrates:
            e[idx], status[idx], missed[idx] = _integrated(
                m, alpha[idx], beta[idx], gamma[idx], gtilde[idx], tol, options)
        else:
            e[idx], status[idx] = m.resolve()(alpha[idx], beta[idx], gamma[idx],
                                              gtilde[idx], **m.check_options({}))[:2]
    return e, status, missed


#: An integrated point whose error estimate is above auto's tol is integrated again at
#: these fractions of it, in turn, until its estimate is within tol: near grazing a march
#: may leave the stick/rebound decision open (e_err = e) until the resolution settles it
#: (at tol = 1e-6 two of 20,000 random points came back 0 where e ~ 7e-6, e_err 1.3e-5;
#: e_err fell below tol only at 1e-10).
RETRY_TOL_FACTORS = (1e-2, 1e-4)


def _integrated(m: registry.Method, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray,
                gtilde: np.ndarray, tol: float, options: dict[str, Any]) -> tuple:
    """``(e, status, missed)`` of integrated points, those whose e_err is above ``tol``
    (but not out of budget) integrated again (:data:`RETRY_TOL_FACTORS`); ``missed``: the
    points whose estimate stays above it (the front ends warn or count them)."""
    e, status, *extra = m.resolve()(alpha, beta, gamma, gtilde,
                                    **composite_integrator_settings(tol, options))
    if not extra or "e_err" not in extra[0]:   # an integrator without an estimate
        return e, status, np.zeros(e.shape, dtype=bool)
    e_err = extra[0]["e_err"]
    for factor in RETRY_TOL_FACTORS:
        above = np.flatnonzero(registry.misses_tol(e_err, status, tol))
        if not above.size:
            break
        e[above], status[above], x = m.resolve()(
            alpha[above], beta[above], gamma[above], gtilde[above],
            **composite_integrator_settings(factor * tol, options))
        e_err[above] = x["e_err"]
    return e, status, registry.misses_tol(e_err, status, tol)


def auto_cor(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, gtilde: np.ndarray,
             tol: float = 1e-6, **options: Any) -> tuple[np.ndarray, np.ndarray, dict]:
    """Kernel of ``"auto"`` over flat float64 arrays: ``(e, status, {"method_used": codes,
    MISSED: missed})``, ``missed`` the integrated points whose error estimate stayed above
    ``tol`` (:data:`sweep.registry.MISSED`: the api warns of them, a sweep counts them).

    Parameters
    ----------
    alpha, beta, gamma, gtilde : ndarray
        Flat arrays of equal length (scaled parameters of eq. (2)).
    tol : float
        Largest acceptable abs error on e [1].
    **options
        The integrator's options (``steps``, ``rest_tol``, ``max_steps``) for the points
        that are integrated.
    """
    codes = select(alpha, beta, gamma, gtilde, tol)
    e, status, missed = _served(alpha, beta, gamma, gtilde, codes, tol, options)
    return e, status, {"method_used": codes, registry.MISSED: missed}
