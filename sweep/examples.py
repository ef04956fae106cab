"""Worked examples run by ``sweep example``: the bouncing ball.

:func:`bounce` drops a bead from a height h0 onto the floor and follows its bounce sequence:
between impacts the flight is ballistic (the bead leaves at ``e v`` and comes back at the
same speed, ``2 e v / g`` later); at each impact the CoR comes from the engine at the impact
speed, either *directly* (``sweep.cor`` at the scaled point of eq. (2), any method, e.g.
``"auto"``) or from a *lookup table* (:class:`sweep.tables.Table` of a scene dataset, built
on the fly by ``sweep run`` when none is given). The sequence stops when

* the bead does not rebound (e = 0: under gravity every KK bead ends so, because g~ grows
  like v0^(-6/5) as the impacts slow down, past the no-rebound threshold (24)), or
* the rebound speed falls below ``v_stop`` (the bead is at rest for any practical purpose),
  or ``max_impacts`` is reached (reported as such).

The contact duration (T_f T of eq. (2), microseconds) is neglected next to the flights.
:func:`bounce_example` writes the plots (height against time; impact speed and CoR per
impact) and a CSV of the impacts.

Floor 5: may import :mod:`sweep.sweeps` (config, design, runner), :mod:`sweep.tables`,
:mod:`sweep.api`, :mod:`sweep.model`, :mod:`sweep.reports.common` and matplotlib (lazily).
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import numbers
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

from sweep import api, registry, tables
from sweep.model import scale
from sweep.reports.common import use_agg
from sweep.sweeps import config, design, runner

__all__ = ["Impact", "BounceResult", "STEEL_BALL", "bounce", "bounce_example",
           "scene_material", "lookup_cor", "direct_cor"]

#: The report's steel ball (KK): m [kg], k [N/m^1.5], gamma0 [s].
STEEL_BALL = design.Material("steel_ball", m=0.154, k=3.6138e10, gamma0=1.5237e-6,
                             alpha=1.5, beta=1.5, origin="the report's steel ball")


@dataclasses.dataclass(frozen=True)
class Impact:
    """One impact of the sequence (SI units; gamma, gtilde scaled by eq. (2))."""

    index: int
    t: float
    v: float
    e: float
    gamma: float
    gtilde: float

    @property
    def v_out(self) -> float:
        """Rebound speed [m/s]."""
        return self.e * self.v


@dataclasses.dataclass
class BounceResult:
    """A bounce sequence: its impacts, why it ended, and the source of the CoR."""

    material: design.Material
    h0: float
    g: float
    impacts: list
    stop: str
    cor_source: str
    table_error: dict | None = None

    def trajectory(self, per_flight: int = 24) -> tuple[np.ndarray, np.ndarray]:
        """Height [m] against time [s]: the drop, then every flight, sampled."""
        t0 = math.sqrt(2.0 * self.h0 / self.g)
        ts = [np.linspace(0.0, t0, 2 * per_flight)]
        hs = [self.h0 - 0.5 * self.g * ts[0] ** 2]
        for imp in self.impacts:
            if imp.v_out <= 0.0:
                break
            tau = np.linspace(0.0, 2.0 * imp.v_out / self.g, per_flight)
            ts.append(imp.t + tau)
            hs.append(np.maximum(imp.v_out * tau - 0.5 * self.g * tau ** 2, 0.0))
        return np.concatenate(ts), np.concatenate(hs)


def direct_cor(material: design.Material, g: float, method: str = "numeric",
               **options: Any) -> Callable[[float], tuple[float, float, float]]:
    """CoR at an impact speed computed directly: ``v -> (e, gamma, g~)``."""
    mat = material

    def cor(v: float) -> tuple[float, float, float]:
        gamma, gtilde = scale(mat.m, mat.k, mat.gamma0, v, mat.alpha, mat.beta, g)
        return float(api.cor(mat.alpha, mat.beta, gamma, gtilde, method=method,
                             **options)), gamma, gtilde
    return cor


def _table_config(material: design.Material, g: float, v_lo: float, v_hi: float,
                  n: int) -> str:
    m = material
    return f"""title = "bounce lookup table: {m.name}"
[design]
kind = "scene"
g = {g!r}
v0 = {{start = {v_lo!r}, stop = {v_hi!r}, num = {n}, spacing = "log"}}
F = 0.0
[design.materials.{json.dumps(m.name)}]
alpha = {m.alpha!r}
beta = {m.beta!r}
m = {m.m!r}
k = {m.k!r}
gamma0 = {m.gamma0!r}
[outputs]
e = ["numeric"]
"""


def lookup_cor(material: design.Material, g: float, v_lo: float, v_hi: float,
               table: Any = None, n: int = 200) -> tuple[Callable, dict]:
    """CoR from a lookup table: ``v -> (e, gamma, g~)`` and the table's stated error.

    Parameters
    ----------
    material : Material
        The bead, which the table must hold (by name).
    g : float
        Gravity [m/s^2].
    v_lo, v_hi : float
        The impact speeds [m/s] the bounce meets: v_stop and the first impact's.
    table : path-like or xarray.Dataset, optional
        A scene dataset; None builds one by ``sweep run`` over ``n`` log-spaced speeds
        spanning [v_lo, v_hi] at F = 0.

    Raises
    ------
    ValueError
        A table that is no scene's table (named), or does not hold the material, or does
        not span [v_lo, v_hi] at F = 0, before any impact (the lookup's own message, and
        the span the bounce needs).
    """
    if table is None:
        with tempfile.TemporaryDirectory() as tmp:
            cfg = config.loads(_table_config(material, g, v_lo, v_hi * (1.0 + 1e-9), n),
                               source="bounce")
            out = Path(tmp) / "bounce_table.nc"
            runner.run(cfg, out, quiet=True)
            t = tables.Table(out)
        name = ""
    else:
        name = f" {table}" if isinstance(table, (str, Path)) else ""
        try:    # e.g. not a scene dataset: the user's file is named
            t = tables.Table(table)
        except ValueError as exc:
            raise ValueError(f"lookup table{name}: {exc}") from None
    try:  # the two ends of the bounce, looked up: the lookup's own checks, once
        t(np.array([v_lo, v_hi]), 0.0, material.name)
        _check_same_bead(t, material, g)
    except ValueError as exc:
        raise ValueError(f"lookup table{name}: {exc}; the bounce needs {material.name!r} "
                         f"at F = 0 and impact speeds [v_stop, sqrt(2 g h0)] = [{v_lo:.6g}, "
                         f"{v_hi:.6g}] m/s") from None
    mat = material

    def cor(v: float) -> tuple[float, float, float]:
        gamma, gtilde = scale(mat.m, mat.k, mat.gamma0, v, mat.alpha, mat.beta, g)
        return float(t(v, 0.0, mat.name)), gamma, gtilde
    return cor, t.error()


def _check_same_bead(t: tables.Table, material: design.Material, g: float) -> None:
    """Refuse a table whose material of that name, or whose gravity, is not the bounce's:
    the table is found by name only, and another bead's e (a scene's ``steel_ball`` with
    ten times the damping, or under the Moon's g) was used for every impact, silently.

    Raises
    ------
    ValueError
        Naming the first property that differs, the table's value and the bounce's.
    """
    i = t.materials.index(material.name)
    for prop in ("m", "k", "gamma0", "alpha", "beta"):
        have, want = float(t.properties[prop][i]), float(getattr(material, prop))
        if not math.isclose(have, want, rel_tol=1e-12):
            raise ValueError(f"its {material.name!r} has {prop} = {have!r}, the bounce's "
                             f"bead {prop} = {want!r}")
    if not math.isclose(t.g, g, rel_tol=1e-12):
        raise ValueError(f"it was computed under g = {t.g!r} m/s^2, the bounce falls under "
                         f"g = {g!r} m/s^2")


def first_impact_speed(h0: float, g: float) -> float:
    """Speed [m/s] of a bead dropped from ``h0`` [m] at its first impact, ``sqrt(2 g h0)``
    (``g`` [m/s^2]): the top of the speeds a bounce sequence meets.

    Raises
    ------
    ValueError
        The speed overflows double precision (h0 = 1e308 m), naming h0 and g.
    """
    v = math.sqrt(2.0 * g * h0)
    if math.isinf(v):   # else "v0 must be finite, got inf" came later, naming neither input
        raise ValueError(f"h0 = {h0!r} m under g = {g!r} m/s^2 gives an impact speed "
                         "sqrt(2 g h0) beyond double precision")
    return v


def _check_positive(name: str, value: Any, unit: str) -> None:
    """Refuse a ``value`` that is not a finite number > 0, naming ``name``."""
    # bool is an int to Python: a height of True is a slip, not 1 m.
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not (ok and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0 [{unit}], got {value!r}")


def _check_sequence_inputs(h0: Any, g: Any, v_stop: Any, max_impacts: Any) -> None:
    """The inputs of :func:`bounce`, checked before a sqrt or the engine meets them."""
    _check_positive("h0", h0, "m")
    _check_positive("g", g, "m/s^2")
    _check_positive("v_stop", v_stop, "m/s")
    if not (isinstance(max_impacts, numbers.Integral) and not isinstance(max_impacts, bool)
            and max_impacts >= 1):
        raise ValueError(f"max_impacts must be an integer >= 1, got {max_impacts!r}")


def bounce(cor: Callable[[float], tuple[float, float, float]], material: design.Material,
           h0: float = 1.0, g: float = 9.81, v_stop: float = 1e-5, max_impacts: int = 10000,
           cor_source: str = "direct") -> BounceResult:
    """Follow the bounce sequence of a bead dropped from ``h0`` [m].

    Parameters
    ----------
    cor : callable
        ``v -> (e, gamma, g~)`` at impact speed v [m/s] (:func:`direct_cor`,
        :func:`lookup_cor`).
    material : Material
    h0 : float
        Drop height [m].
    g : float
        Gravity [m/s^2].
    v_stop : float
        Rebound speed [m/s] below which the bead is taken to be at rest.
    max_impacts : int
        Hard cap on the number of impacts.

    Returns
    -------
    BounceResult

    Raises
    ------
    ValueError
        ``h0``, ``g`` or ``v_stop`` not a finite number > 0, or ``max_impacts`` not an
        integer >= 1 (the message names the parameter and its value).
    """
    _check_sequence_inputs(h0, g, v_stop, max_impacts)
    v, t = first_impact_speed(h0, g), math.sqrt(2.0 * h0 / g)
    impacts, stop = [], f"max_impacts = {max_impacts} reached"
    for i in range(max_impacts):
        e, gamma, gtilde = cor(v)
        impacts.append(Impact(i + 1, t, v, e, gamma, gtilde))
        if not e > 0.0:
            stop = f"no rebound (e = 0) at impact {i + 1}, v = {v:.4g} m/s"
            break
        if e * v < v_stop:
            stop = f"rebound speed {e * v:.3g} m/s < v_stop = {v_stop:g} m/s at impact {i + 1}"
            break
        t += 2.0 * e * v / g
        v = e * v
    return BounceResult(material, h0, g, impacts, stop, cor_source)


def _write_csv(result: BounceResult, path: Path) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["impact", "t [s]", "v [m/s]", "e [1]", "v_out [m/s]", "apex [m]",
                    "gamma [1]", "gtilde [1]"])
        for imp in result.impacts:
            w.writerow([imp.index, repr(imp.t), repr(imp.v), repr(imp.e), repr(imp.v_out),
                        repr(imp.v_out ** 2 / (2.0 * result.g)), repr(imp.gamma),
                        repr(imp.gtilde)])


def _plot(result: BounceResult, out: Path) -> list[Path]:
    plt = use_agg()
    t, h = result.trajectory()
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(t, h, lw=0.8)
    ax.set(xlabel="time [s]", ylabel="height [m]",
           title=f"{result.material.name} dropped from {result.h0:g} m ({result.cor_source})")
    fig.tight_layout()
    files = [out / "bounce_height.png"]
    fig.savefig(files[0], dpi=120)
    plt.close(fig)
    n = [imp.index for imp in result.impacts]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    a1.semilogy(n, [imp.v for imp in result.impacts], ".-")
    a1.set(ylabel="impact speed [m/s]", title=result.stop)
    a2.plot(n, [imp.e for imp in result.impacts], ".-")
    a2.set(xlabel="impact", ylabel="coefficient of restitution e")
    fig.tight_layout()
    files.append(out / "bounce_impacts.png")
    fig.savefig(files[1], dpi=120)
    plt.close(fig)
    return files


def scene_material(path: str | Path, name: str | None = None) -> tuple[design.Material, float]:
    """A material (resolved) and the gravity of a scene configuration file."""
    spec = config.load(path).design
    if spec.kind != "scene":
        raise config.ConfigError(f"{path}: design.kind is {spec.kind!r}, not 'scene'")
    mats = {m.name: m for m in spec.materials}
    if name is None:
        name = next(iter(mats))
    if name not in mats:
        raise config.ConfigError(f"{path}: no material {name!r}; it has {list(mats)}")
    return design.resolve_material(mats[name], spec.g), spec.g


def _check_example_inputs(source: str, table: Any, method: str, h0: float, g: float,
                          v_stop: float, options: dict) -> None:
    """Refuse what :func:`bounce_example` cannot use: a bad value, or an argument that has
    no effect with this ``source`` (silently dropped, it would look as if it had counted)."""
    if source not in ("direct", "lookup"):
        raise ValueError(f"source must be 'direct' or 'lookup', got {source!r}")
    if method not in registry.METHODS:
        raise ValueError(f"method must be one of {tuple(registry.METHODS)}, got {method!r}")
    _check_sequence_inputs(h0, g, v_stop, 1)
    if source == "direct":
        if table is not None:
            raise ValueError(f"table applies to source='lookup' only, got {table!r} with "
                             "source='direct'")
        registry.METHODS[method].check_options(options)  # names an unknown or bad option
        return
    if method != "numeric" or options:
        raise ValueError("method and options apply to source='direct' only (the table's "
                         "CoR is the one it stores: e_numeric, else e_auto, else its first "
                         f"e_<method>), got method={method!r}, "
                         f"options={options!r} with source='lookup'")
    v_hit = first_impact_speed(h0, g)
    if table is None and not v_stop < v_hit:
        # the table built on the fly spans [v_stop, first impact speed]
        raise ValueError(f"v_stop must be < the first impact speed sqrt(2 g h0) = "
                         f"{v_hit:.6g} m/s for a lookup table built on the fly, got {v_stop!r}")


def bounce_example(out: str | Path = "bounce", material: design.Material = STEEL_BALL,
                   h0: float = 1.0, g: float = 9.81, source: str = "direct",
                   table: Any = None, method: str = "numeric", v_stop: float = 1e-5,
                   **options: Any) -> dict[str, Any]:
    """Run :func:`bounce` and write ``bounce_height.png``, ``bounce_impacts.png`` and
    ``bounce_impacts.csv`` into ``out``.

    Parameters
    ----------
    out : path-like
        Output directory (created).
    material : Material
        The bead (resolved: ``m``, ``k``, ``gamma0``, ``alpha``, ``beta`` set).
    h0, g, v_stop : float
        Drop height [m], gravity [m/s^2], rest speed [m/s] (:func:`bounce`); finite, > 0.
    source : {"direct", "lookup"}
        Where each impact's CoR comes from.
    table : path-like, optional
        Scene dataset for ``source="lookup"`` (default: built on the fly over
        [v_stop, sqrt(2 g h0)]); refused with ``source="direct"``.
    method, **options
        Method of the direct computation, a name of :data:`sweep.registry.METHODS`, and its
        options (e.g. ``"auto"`` with ``tol``); with ``source="lookup"`` only the default
        ``method="numeric"`` and no options are accepted.

    Returns
    -------
    dict
        ``result`` (BounceResult), ``files`` and a text ``summary``.

    Raises
    ------
    ValueError
        A bad value, an option of no effect with this ``source`` or a table that does not
        span the bounce (:func:`lookup_cor`), naming it, before anything is written.
    OSError
        ``table`` cannot be read or is not netCDF (:func:`sweep.store.open_dataset`), before
        anything is written.
    """
    _check_example_inputs(source, table, method, h0, g, v_stop, options)
    if source == "lookup":
        cor, err = lookup_cor(material, g, v_stop, first_impact_speed(h0, g), table)
        label = f"lookup table (stated error {err['max_abs']:.2g})"
    else:
        cor, err, label = direct_cor(material, g, method, **options), None, f"direct, {method}"
    result = bounce(cor, material, h0, g, v_stop, cor_source=label)
    result.table_error = err
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)  # once there is something to write
    csv_path = out / "bounce_impacts.csv"
    _write_csv(result, csv_path)
    files = _plot(result, out) + [csv_path]
    summary = (f"{material.name} dropped from {h0:g} m, CoR from {label}: "
               f"{len(result.impacts)} impacts, {result.stop}")
    return {"result": result, "files": [str(f) for f in files], "summary": summary}
