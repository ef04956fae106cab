"""Peers of the integrator: the CoR as a user of another ODE tool would compute it.

Every peer integrates the report's (u, w) form (4), ``u' = w - gamma u_+^beta``,
``w' = g~ - u_+^alpha`` from (0, 1), and ends the impact on events located by the tool
itself: the detachment u = 0 crossed downward (``e = -w``, since v = w at u = 0) and the
trough v = 0 crossed upward (the bead stopped short of the floor: ``e = 0``). No event
before ``t_max``: at rest, ``e = 0``. None of them knows the tricks of the package
(grading near u = 0, the energy balance, refinement at grazing): they are what a careful
user of each tool would write in an afternoon.

* :func:`scipy_user_cor` -- scipy ``solve_ivp`` (RK45, DOP853, LSODA, Radau, ...), one
  point at a time, the right-hand side in Python.
* :func:`numbalsoda_cors` -- numbalsoda's DOP853 (Fortran, events by Brent's method on the
  dense output) called from a numba loop over points, one core. numbalsoda reports events in
  both directions, so the impact is followed in the three phases of the report's
  Algorithm 1 (max compression, down to u-bar, then detachment or trough), each with events
  that can only change sign one way.
* :func:`diffrax_cors` -- diffrax (JAX), ``jax.vmap`` over the points of one call (every
  lane advances until the last is done), float64; one directional event, ``min(u, -v)``
  falling through 0 (the first of the detachment and the trough), located by bisection
  on the solver's interpolant.

numbalsoda and diffrax are optional (``pip install "sweep[peers]"``; numbalsoda builds from
source and needs a Fortran compiler): :func:`available_peers` says which can run and why
not. Importing this module imports neither.

Owns: the peers and their availability. May import: numpy; scipy, numba, numbalsoda, jax,
diffrax, optimistix lazily inside the functions; nothing from ``sweep``.
"""
from __future__ import annotations

import functools
import importlib.util
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["scipy_user_cor", "numbalsoda_cors", "diffrax_cors", "available_peers",
           "OPTIONAL_PEERS"]

#: Optional peers -> the modules they need.
OPTIONAL_PEERS = {"numbalsoda": ("numbalsoda", "numba"),
                  "diffrax": ("diffrax", "jax", "optimistix")}


def available_peers() -> dict[str, str | None]:
    """Optional peer -> None when it can run, else why not (a missing module)."""
    out = {}
    for peer, modules in OPTIONAL_PEERS.items():
        missing = [m for m in modules if importlib.util.find_spec(m) is None]
        out[peer] = (f"not installed ({', '.join(missing)} missing; pip install "
                     f"\"sweep[peers]\")") if missing else None
    return out


def scipy_user_cor(alpha: float, beta: float, gamma: float, gtilde: float,
                   method: str = "DOP853", rtol: float = 1e-8, atol: float | None = None,
                   t_max: float = 1e3) -> float:
    """The CoR [1] as a scipy user would compute it: one ``solve_ivp`` call with events.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : float
        Scaled parameters [1] (report (2)).
    method : str
        A ``solve_ivp`` method (``"RK45"``, ``"DOP853"``, ``"LSODA"``, ``"Radau"``, ...).
    rtol, atol : float
        Tolerances [1]; ``atol`` defaults to ``rtol / 100``.
    t_max : float
        End of the scaled time span [1]; no event by then: at rest, ``e = 0``.
    """
    from scipy.integrate import solve_ivp

    a, b, g, G = float(alpha), float(beta), float(gamma), float(gtilde)
    atol = rtol / 100.0 if atol is None else atol

    def rhs(t, y):
        u = y[0] if y[0] > 0.0 else 0.0
        return [y[1] - g * u ** b, G - u ** a]

    def detach(t, y):
        return y[0]

    def trough(t, y):
        u = y[0] if y[0] > 0.0 else 0.0
        return y[1] - g * u ** b

    detach.terminal = trough.terminal = True
    detach.direction, trough.direction = -1, 1
    sol = solve_ivp(rhs, (0.0, t_max), [0.0, 1.0], method=method, rtol=rtol, atol=atol,
                    events=[detach, trough])
    if sol.t_events[0].size:
        return -float(sol.y_events[0][0][1])
    return 0.0


# --------------------------------------------------------------------------- numbalsoda

@functools.lru_cache(maxsize=1)
def _numbalsoda_loop():
    """The compiled loop over points (built once per process: numba compiles it lazily)."""
    import numba as nb
    from numbalsoda import lsoda_sig
    from numbalsoda import solve_ivp as nbl_solve_ivp

    # p = (alpha, beta, gamma, g~, u-bar): the right-hand side and the three phases' events.
    @nb.cfunc(lsoda_sig)
    def rhs(t, y, dy, p):
        u = y[0] if y[0] > 0.0 else 0.0
        dy[0] = y[1] - p[2] * u ** p[1]
        dy[1] = p[3] - u ** p[0]

    @nb.cfunc(lsoda_sig)
    def ev_vel(t, y, out, p):               # phase 1: v = 0 (maximum compression)
        u = y[0] if y[0] > 0.0 else 0.0
        out[0] = y[1] - p[2] * u ** p[1]

    @nb.cfunc(lsoda_sig)
    def ev_ubar(t, y, out, p):              # phase 2: u = u-bar
        out[0] = y[0] - p[4]

    @nb.cfunc(lsoda_sig)
    def ev_exit(t, y, out, p):              # phase 3: u = 0 (detach) or v = 0 (trough)
        u = y[0] if y[0] > 0.0 else 0.0
        out[0] = y[0]
        out[1] = y[1] - p[2] * u ** p[1]

    f_rhs, f_vel, f_ubar, f_exit = rhs.address, ev_vel.address, ev_ubar.address, ev_exit.address

    @nb.njit
    def phase(y0, t0, t_max, n_ev, f_ev, p, rtol, atol):
        span = np.array([t0, t_max])
        sol = nbl_solve_ivp(f_rhs, span, y0, np.empty(0), "DOP853", np.int32(n_ev), f_ev,
                            p.ctypes.data, 0.0, 0.0, rtol, atol)
        return sol.event_found, sol.ind_event, sol.t_event, sol.y_event.copy()

    @nb.njit
    def loop(alpha, beta, gamma, gtilde, rtol, atol, t_max, e):
        for i in range(alpha.size):
            p = np.array([alpha[i], beta[i], gamma[i], gtilde[i],
                          gtilde[i] ** (1.0 / alpha[i])])
            found, _, t, y = phase(np.array([0.0, 1.0]), 0.0, t_max, 1, f_vel, p, rtol, atol)
            if not found:                   # overdamped: creeps to rest
                e[i] = 0.0
                continue
            found, _, t, y = phase(y, t, t_max, 1, f_ubar, p, rtol, atol)
            if not found:
                e[i] = 0.0
            elif gtilde[i] == 0.0:          # u-bar = 0: reaching it is the detachment
                e[i] = -y[1]
            else:
                found, k, t, y = phase(y, t, t_max, 2, f_exit, p, rtol, atol)
                e[i] = -y[1] if (found and k == 0) else 0.0

    return loop


def numbalsoda_cors(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, gtilde: ArrayLike,
                    rtol: float = 1e-8, atol: float | None = None,
                    t_max: float = 1e3) -> np.ndarray:
    """CoR [1] of every point by numbalsoda's DOP853 with events, one point at a time.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : array_like
        Scaled parameters [1], broadcast together.
    rtol, atol : float
        Tolerances [1]; ``atol`` defaults to ``rtol / 100``.
    t_max : float
        End of the scaled time span [1].

    Returns
    -------
    ndarray of float64, flat

    Raises
    ------
    ImportError
        numbalsoda is not installed.
    """
    arrays = [np.ascontiguousarray(x, dtype=np.float64).ravel()
              for x in np.broadcast_arrays(alpha, beta, gamma, gtilde)]
    e = np.empty(arrays[0].size)
    atol = rtol / 100.0 if atol is None else atol
    _numbalsoda_loop()(*arrays, float(rtol), float(atol), float(t_max), e)
    return e


# --------------------------------------------------------------------------- diffrax

@functools.lru_cache(maxsize=4)
def _diffrax_solve(solver_name: str, max_steps: int):
    """The jitted, vmapped solve for one diffrax solver (tolerances are traced arguments,
    so that changing them does not recompile)."""
    import jax

    jax.config.update("jax_enable_x64", True)   # float32 would floor every error at ~1e-7
    import diffrax
    import jax.numpy as jnp
    import optimistix as optx

    def field(t, y, args):
        a, b, g, G = args
        u = jnp.maximum(y[0], 0.0)
        return jnp.stack([y[1] - g * u ** b, G - u ** a])

    def exit_(t, y, args, **kw):
        # min(u, -v): < 0 while the bead goes in (v > 0), > 0 on the way out (u > 0,
        # v < 0), and back to 0 at the first of the detachment (u = 0) and the trough
        # (v = 0). One scalar event, so that bisection can locate it.
        a, b, g, G = args
        return jnp.minimum(y[0], g * jnp.maximum(y[0], 0.0) ** b - y[1])

    solver = getattr(diffrax, solver_name)()

    def one(a, b, g, G, rtol, atol, t_max):
        # direction False: from > 0 to <= 0 only (not the rise through 0 at maximum
        # compression). Bisection inside the step that saw the sign change: Newton on a
        # long step's interpolant can land on another root.
        event = diffrax.Event(exit_, optx.Bisection(rtol=1e-14, atol=1e-14), direction=False)
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(field), solver, t0=0.0, t1=t_max, dt0=None,
            y0=jnp.array([0.0, 1.0]), args=(a, b, g, G), event=event,
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
            saveat=diffrax.SaveAt(t1=True), max_steps=max_steps, throw=False)
        u, w = sol.ys[-1, 0], sol.ys[-1, 1]
        v = w - g * jnp.maximum(u, 0.0) ** b
        detached = sol.event_mask & (u <= -v)     # u reached 0 before v did
        ok = (sol.result == diffrax.RESULTS.successful) | (
            sol.result == diffrax.RESULTS.event_occurred)
        return jnp.where(ok, jnp.where(detached, -w, 0.0), jnp.nan)

    return jax.jit(jax.vmap(one, in_axes=(0, 0, 0, 0, None, None, None)))


def diffrax_cors(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, gtilde: ArrayLike,
                 rtol: float = 1e-8, atol: float | None = None, solver: str = "Tsit5",
                 t_max: float = 1e3, max_steps: int = 65536) -> np.ndarray:
    """CoR [1] of every point by diffrax, ``jax.vmap`` over the points, float64.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : array_like
        Scaled parameters [1], broadcast together.
    rtol, atol : float
        Tolerances of the PID step-size controller [1]; ``atol`` defaults to ``rtol / 100``.
    solver : str
        A diffrax solver class name (``"Tsit5"``, ``"Dopri5"``, ``"Dopri8"``).
    t_max : float
        End of the scaled time span [1].
    max_steps : int
        Step budget per point (a point that spends it gets ``e = 0``).

    Returns
    -------
    ndarray of float64, flat
        NaN where diffrax reported a failure (step budget, root finding).

    Raises
    ------
    ImportError
        diffrax or jax is not installed.

    Notes
    -----
    Enables ``jax_enable_x64`` for the process (JAX computes in float32 otherwise). The
    first call for a solver and an array size compiles (seconds): time the second.
    """
    arrays = [np.ascontiguousarray(x, dtype=np.float64).ravel()
              for x in np.broadcast_arrays(alpha, beta, gamma, gtilde)]
    atol = rtol / 100.0 if atol is None else atol
    fn = _diffrax_solve(solver, int(max_steps))
    out = fn(*arrays, float(rtol), float(atol), float(t_max))
    return np.asarray(out.block_until_ready(), dtype=np.float64)


def peer_cors(name: str, setting: dict[str, Any], alpha: ArrayLike, beta: ArrayLike,
              gamma: ArrayLike, gtilde: ArrayLike) -> np.ndarray:
    """CoR of many points by a peer: ``name`` is ``"scipy"``, ``"numbalsoda"`` or
    ``"diffrax"``; ``setting`` the keyword arguments of its function (scipy: ``method``,
    ``rtol``). scipy runs its Python loop over the points, one ``solve_ivp`` each."""
    if name == "scipy":
        pts = np.broadcast_arrays(*(np.asarray(x, dtype=float).ravel()
                                    for x in (alpha, beta, gamma, gtilde)))
        return np.array([scipy_user_cor(*p, **setting) for p in zip(*pts)])
    if name == "numbalsoda":
        return numbalsoda_cors(alpha, beta, gamma, gtilde, **setting)
    if name == "diffrax":
        return diffrax_cors(alpha, beta, gamma, gtilde, **setting)
    raise ValueError(f"unknown peer {name!r}; one of 'scipy', 'numbalsoda', 'diffrax'")
