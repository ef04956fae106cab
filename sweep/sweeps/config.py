"""Sweep configurations: TOML text -> validated, immutable configuration objects.

A configuration is checked completely before anything is computed: unknown keys (reported
before the required key they may misspell), wrong types, exponents below 1 (Assumption 1 of
the report), negative damping or load, empty ranges and methods requested where the design
leaves their domain (``sp`` off alpha = beta = 1.5, from
:attr:`sweep.registry.Method.models`) raise :class:`ConfigError` with a message naming the
key and the offending value, e.g. ``design.alpha.min: must be >= 1 (uniqueness is not known
below 1), got 0.5``.

Layout of a configuration file (all tables but ``[design]`` and ``[outputs]`` optional)::

    title = "free text"
    description = "free text"

    [design]
    kind = "grid"                  # "grid" | "doe" | "scene" (DESIGN_KINDS adds kinds)
    alpha = 1.5                    # grid axis: a number, a list, or a range table:
    beta = [1.0, 1.5]              # a list: distinct values, stored in increasing order
    gamma = {start = 0.0, stop = 0.1, num = 1000}                  # linear by default
    gtilde = {start = 1e-3, stop = 10.0, num = 50, spacing = "log"}

    [design]                       # ... or a design of experiments over bounds
    kind = "doe"
    sampler = "sobol"              # "sobol" | "lhs" | "random"
    n = 1000000
    seed = 0
    alpha = {min = 1.0, max = 3.0}
    gamma = {min = 1e-4, max = 1.0, scale = "log"}                 # log-uniform
    gtilde = {min = 0.0, max = 10.0}                                # uniform
    beta = 1.5                     # a number fixes the axis (not sampled)

    [design]                       # ... or a physical scene (SI units), mapped to
    kind = "scene"                 # (alpha, beta, gamma, g~) by sweep.model.scale, eq. (2)
    g = 9.81                       # gravity [m/s^2] (default 9.81)
    v0 = {start = 0.01, stop = 10.0, num = 100, spacing = "log"}   # impact speeds [m/s]
    F = [0.0, 1.0, 10.0]           # constant loads [N] (a number, list or range, as above)

    [design.materials.steel]       # one table per material; its name is a coordinate
    law = "kk"                     # a name of sweep.registry.MODELS, or alpha = .., beta = ..
    m = 0.154                      # mass [kg]                 ... or radius and density
    k = 3.6138e10                  # stiffness [N/m^alpha]     ... or radius, E, nu (Hertz)
    gamma0 = 1.5237e-6             # damping [s m^(alpha-beta)] ... or damping = {model = ..}

    [design.materials.glass]       # from material properties (docs/scenes.md)
    law = "kk"
    radius = 1e-3                  # [m]
    density = 2500.0               # [kg/m^3]
    E = 63e9                       # Young's modulus [Pa]
    nu = 0.22                      # Poisson's ratio
    floor = {E = 63e9, nu = 0.22}  # the floor's, both (omitted: rigid)
    damping = {model = "target_e", e = 0.97, v0 = 1.0}   # numerical e at v0 [m/s], g, F = 0
    # or {model = "tsuji", e = 0.9} (law "tti") or {model = "kuwabara_kono", eta1 = .., eta2 = ..}

    [outputs]
    e = ["numeric", "ord1", "ord2_approx", "auto"]   # or "all": every method defined on
                                   # the whole design (sp: alpha = beta = 1.5 only) but
                                   # "auto"; variables e_<method>
    fields = ["status", "error_ord1"]   # or "all": sweep.registry.integrator_fields() (e_err
                                        # too), error_<m> for every approximation in e

    [integrator]                   # passed to sweep.api.integrate (refused where nothing
                                   # integrates; auto integrates with it, at its own tol)
    steps = 64                     # per half period of the linearised motion
    rest_tol = 1e-8
    max_steps = 1000000
    device = "cpu"                 # or "cuda": one CUDA GPU (pip install 'sweep[cuda]')

    [options.ord2_approx]          # per-method options passed to sweep.api.cor (only for a
                                   # method of outputs.e or of an error_ field)
    n = 21

    [options.auto]                 # e = ["auto"]: the cheapest method within tol per point
    tol = 1e-4                     # (and the integrator's options, for the points it serves)

    [run]
    chunk_size = 131072            # points per chunk (resume and progress granularity)
    compress = "fast"              # deflate the variables that shrink by 60% or more (flags,
                                   # counts, smooth coordinates); "small": also those that
                                   # shrink by 35% (e and error fields: a third smaller file
                                   # for ~1 s of writer CPU a million points); "none"

Methods, their options, output fields and parameter domains are read from
:mod:`sweep.registry` when a configuration is parsed, so a method registered there is
accepted here at once.

A configuration file is refused before it is parsed when it is larger than
:data:`sweep.sweeps.limits.CONFIG_MAX_BYTES` (at most that much is read: ``/dev/zero`` is
not read forever), is not UTF-8 text, or nests deeper than
:data:`~sweep.sweeps.limits.CONFIG_MAX_DEPTH`.

A configuration may also come as a dict (:func:`from_dict`: written as TOML text by
:mod:`sweep.sweeps.toml_text`, then parsed as a file is) or as any of a path, TOML text, a
dict or a :class:`Config` (:func:`as_config`, behind ``sweep.run``).

Owns: the configuration format and its validation. May import: :mod:`sweep.registry`,
:mod:`sweep.sweeps.limits` and :mod:`sweep.sweeps.toml_text` (no kernels, no numba).
"""
from __future__ import annotations

import dataclasses
import difflib
import hashlib
import itertools
import json
import math
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from sweep import registry
from sweep.sweeps import limits, toml_text

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "ConfigError", "Config", "GridSpec", "DoESpec", "SceneSpec", "MaterialSpec", "Bound",
    "Outputs", "IntegratorSettings", "DAMPING_MODELS",
    "load", "loads", "from_dict", "as_config", "PARAMETERS", "METHODS", "APPROXIMATIONS",
    "INTEGRATOR_FIELDS",
    "DESIGN_KINDS", "SAMPLERS", "DEFAULT_CHUNK_SIZE", "CHUNK_SIZE_RULE", "is_chunk_size",
]

#: The four scaled parameters of the report's eq. (2), in dataset dimension order.
PARAMETERS = registry.PARAMETER_NAMES

#: The built-in CoR methods and fields (snapshots of :mod:`sweep.registry`; parsing reads the
#: registry itself, so methods registered later are accepted too).
METHODS = tuple(registry.METHODS)
APPROXIMATIONS = registry.approximations()
INTEGRATOR_FIELDS = registry.integrator_fields()

#: Samplers of a design of experiments (scipy.stats.qmc, or plain pseudo-random).
SAMPLERS = ("sobol", "lhs", "random")

#: Largest design a Sobol' sampler can index (scipy's default 30-bit direction numbers).
SOBOL_MAX_POINTS = 2 ** 30
#: A Latin hypercube is a global permutation: scipy builds it whole in memory (d x n x 8 B).
LHS_MAX_POINTS = 2 ** 24
#: Top-level keys of a configuration that the computed values do not depend on: a run
#: interrupted, then resumed with another title or ``run.compress`` (which the run's own
#: hint suggests when its writer held it back) keeps its chunks.
PRESENTATION_KEYS = ("title", "description", "run")
#: Largest design of any sampler: its points are indexed in int64.
MAX_DOE_POINTS = 2 ** 63 - 1

DEFAULT_CHUNK_SIZE = 2 ** 17

class ConfigError(ValueError):
    """A configuration is invalid; the message names the key and the offending value."""


# --------------------------------------------------------------------------- value checks

def _is_int(v):
    # TOML booleans are Python bools, which are ints: never accept them as numbers.
    return isinstance(v, int) and not isinstance(v, bool)


#: The chunk sizes a run accepts (``run.chunk_size``, ``run(chunk_size=)``), as its messages
#: say it.
CHUNK_SIZE_RULE = f"an integer from 1 to {limits.MAX_CHUNK_SIZE:,}"


#: ``run.compress`` as TOML booleans: true keeps the meaning it had before the choices were
#: named (deflate every variable where it saves 35%), false stores all as computed.
_COMPRESSION_ALIASES = {True: "small", False: "none"}
_COMPRESSION_RULE = (", ".join(f'"{c}"' for c in registry.COMPRESSION) + " (or " + ", ".join(
    f'{str(b).lower()}: "{c}"' for b, c in _COMPRESSION_ALIASES.items()) + ")")


def _compression(value: Any) -> str | None:
    """A ``run.compress`` value's choice of :data:`sweep.registry.COMPRESSION`; None for a
    value that names none."""
    if isinstance(value, bool):
        return _COMPRESSION_ALIASES[value]
    return value if isinstance(value, str) and value in registry.COMPRESSION else None


def is_chunk_size(value: Any) -> bool:
    """True for a chunk size a run accepts (:data:`CHUNK_SIZE_RULE`).

    Parameters
    ----------
    value : object

    Returns
    -------
    bool
    """
    return _is_int(value) and 1 <= value <= limits.MAX_CHUNK_SIZE


def _is_number(v):
    # TOML's own types only (a Python dict configuration too): registry.is_number's rule.
    return isinstance(v, (int, float)) and registry.is_number(v)


class _Table:
    """A TOML table being read: tracks its dotted path and which keys were consumed.

    A parser that knows every key its table may hold declares them first
    (:meth:`expect`), so that a misspelt key is reported as unknown before the key it
    misspells is reported missing (``samplr = "sobol"`` names ``samplr``, not
    ``sampler``). Keys are also checked once more when the table is read
    (:meth:`finish`): declared keys that do not apply (another damping model's parameter)
    are refused there.
    """

    def __init__(self, data, path, source):
        self.data = data
        self.path = path
        self.source = source
        self.used = set()
        self.known = None  # every key the table may hold, once declared by expect()

    def key(self, name):
        return f"{self.path}.{name}" if self.path else name

    def error(self, name, message, value=dataclasses.MISSING):
        where = f"{self.source}: " if self.source else ""
        got = "" if value is dataclasses.MISSING else f", got {registry.short_repr(value, 80)}"
        raise ConfigError(f"{where}{self.key(name)}: {message}{got}")

    def has(self, name):
        return name in self.data

    def expect(self, names):
        """Declare every key this table may hold, and refuse any other now, before a
        required key can be reported missing."""
        self.known = frozenset(names)
        self._refuse_unknown(sorted(self.known))

    def missing(self, name, message):
        """Report the absent required key ``name``; an unknown key spelt like it is the
        likelier mistake, and is reported instead."""
        # A declared table has refused its unknown keys already; in an undeclared one
        # (the design before its kind is known) only a near spelling is surely a typo.
        if self.known is None:
            near = [k for k in self.data if k not in self.used
                    and difflib.get_close_matches(k, [name], n=1)]
            self._refuse_unknown([name], only=near, listing=False)
        self.error(name, message)

    def get(self, name, check, rule, default=dataclasses.MISSING):
        """Read key ``name``, require ``check(value)``; absent -> default or error."""
        self.used.add(name)
        if name not in self.data:
            if default is dataclasses.MISSING:
                self.missing(name, f"is required ({rule})")
            return default
        value = self.data[name]
        if not check(value):
            self.error(name, f"must be {rule}", value)
        return value

    def raw(self, name):
        self.used.add(name)
        return self.data[name]

    def table(self, name, required=False):
        self.used.add(name)
        if name not in self.data:
            if required:
                self.missing(name, "is required (a table)")
            return _Table({}, self.key(name), self.source)
        value = self.data[name]
        if not isinstance(value, dict):
            self.error(name, "must be a table", value)
        return _Table(value, self.key(name), self.source)

    def _refuse_unknown(self, allowed, only=None, listing=True):
        """Raise for the first key outside ``allowed`` (of ``only``, if given), listing
        the allowed keys if they are all known."""
        for name in self.data if only is None else only:
            if name not in allowed:
                hint = difflib.get_close_matches(name, allowed, n=1)
                extra = f" (did you mean {hint[0]!r}?)" if hint else ""
                listed = f"; allowed keys here: {', '.join(allowed) or 'none'}" if listing else ""
                self.error(name, f"unknown key{extra}{listed}")

    def finish(self):
        """Refuse keys that were never read (typos must not be silently ignored)."""
        self._refuse_unknown(sorted(self.used))


def _check_domain(tab, key, name, value, domain=None):
    parameter = (domain or {**registry.PARAMETERS, **registry.PHYSICAL})[name]
    if not parameter.ok(value):
        tab.error(key, f"must be {parameter.rule}", value)


# --------------------------------------------------------------------------- design specs

@dataclasses.dataclass(frozen=True)
class GridSpec:
    """A full tensor grid over the four parameters (C order: alpha slowest, g~ fastest).

    Attributes
    ----------
    axes : tuple of tuple of float
        Coordinate values per parameter, in :data:`PARAMETERS` order.
    spacing : tuple of str
        How each axis is spaced, in :data:`PARAMETERS` order (see :func:`_axis_spacing`);
        empty if unknown.
    """

    axes: tuple
    kind: str = "grid"
    spacing: tuple = ()

    @property
    def shape(self):
        return tuple(len(a) for a in self.axes)

    @property
    def size(self):
        return math.prod(self.shape)

    @property
    def exponents(self):
        """Every (alpha, beta) of the design, one at a time: a grid of 5,000 alphas and
        5,000 betas made a tuple of 25,000,000 pairs (3.7 GB) before its size was judged."""
        return itertools.product(self.axes[0], self.axes[1])


@dataclasses.dataclass(frozen=True)
class Bound:
    """Sampling law of one parameter in a design of experiments.

    ``scale`` is "linear" (uniform on [lo, hi]), "log" (log-uniform) or "fixed" (lo == hi).
    """

    name: str
    lo: float
    hi: float
    scale: str

    @property
    def fixed(self):
        return self.scale == "fixed"


@dataclasses.dataclass(frozen=True)
class DoESpec:
    """A design of experiments: ``n`` points drawn by ``sampler`` in the box ``bounds``."""

    sampler: str
    n: int
    seed: int
    scramble: bool
    bounds: tuple
    kind: str = "doe"

    @property
    def size(self):
        return self.n

    @property
    def sampled(self):
        """Parameters drawn by the sampler (the others are fixed), in PARAMETERS order."""
        return tuple(b for b in self.bounds if not b.fixed)

    @property
    def exponents(self):
        """The design's (alpha, beta) when both are fixed; None when one is sampled."""
        alpha, beta = self.bounds[:2]
        return ((alpha.lo, beta.lo),) if alpha.fixed and beta.fixed else None


def _axis_values(start, stop, num, spacing):
    """Coordinates of a range: ``np.linspace`` or ``np.geomspace`` (exact end points)."""
    if spacing == "log":
        vals = np.geomspace(start, stop, num)
    else:
        vals = np.linspace(start, stop, num)
    return tuple(float(v) for v in vals)


def _grid_axis(design, name):
    """Parse one grid axis: a number, a non-empty list, or {values} / {start, stop, num}."""
    if not design.has(name):
        design.missing(name, "is required (a number, a list, or {start, stop, num[, spacing]})")
    value = design.raw(name)
    if _is_number(value):
        _check_domain(design, name, name, value)
        return (float(value),)
    if isinstance(value, list):
        return _grid_list(design, name, value)
    if not isinstance(value, dict):
        design.error(name, "must be a number, a list of numbers, or a range table", value)
    tab = _Table(value, design.key(name), design.source)
    tab.expect(("values", "start", "stop", "num", "spacing"))
    if tab.has("values"):
        vals = _grid_list(tab, "values", tab.raw("values"))
        tab.finish()
        return vals
    start = tab.get("start", _is_number, "a finite number")
    stop = tab.get("stop", _is_number, "a finite number")
    num = tab.get("num", _is_int, "an integer number of points >= 1")
    spacing = tab.get("spacing", lambda v: v in ("linear", "log"), '"linear" or "log"', "linear")
    tab.finish()
    if num < 1:
        tab.error("num", "must be >= 1 (an empty range)", num)
    if num > limits.GRID_AXIS_MAX_POINTS:
        tab.error("num", f"must be <= {limits.GRID_AXIS_MAX_POINTS} points on one axis "
                         "(the axis is held in memory)", num)
    _check_domain(tab, "start", name, start)
    _check_domain(tab, "stop", name, stop)
    if num > 1 and not stop > start:
        tab.error("stop", f"must be > start = {start!r} for {num} distinct points", stop)
    if num == 1 and stop != start:
        # One point cannot span [start, stop]: numpy's linspace took start, silently.
        tab.error("num", f"must be > 1 for a range from {start!r} to {stop!r} (one value: "
                         "give the number, or start = stop)", num)
    if spacing == "log" and not start > 0:
        tab.error("start", 'must be > 0 with spacing = "log"', start)
    values = _axis_values(start, stop, num, spacing)
    if num > 1 and not all(a < b for a, b in zip(values, values[1:])):
        # Neighbours closer than a double's spacing round to one value: coordinates that
        # repeat (a CF axis must increase strictly; .sel would give several points).
        tab.error("num", f"must leave {num} distinct values from {start!r} to {stop!r} in "
                         f"double precision (they give {len(set(values))})", num)
    return values


def _grid_list(tab, key, value):
    if not isinstance(value, list) or not value:
        tab.error(key, "must be a non-empty list of numbers (an empty axis)", value)
    name = tab.path.split(".")[-1] if key == "values" else key
    for v in value:
        if not _is_number(v):
            tab.error(key, "must contain only finite numbers", v)
        _check_domain(tab, key, name, v)
    if len(set(float(v) for v in value)) != len(value):
        tab.error(key, "must not repeat a value (coordinates must be unique)", value)
    # In increasing order: stored as given, a list out of order made a coordinate that
    # xarray cannot slice and CF checkers refuse (coordinates are monotonic); the order of
    # a grid's axis means nothing else.
    return tuple(sorted(float(v) for v in value))


def _axis_spacing(value, values):
    """Spacing of a parsed grid axis: "single" (one value), the ``spacing`` of a range
    table ("linear" by default), or "irregular" (a list: its spacing is not guessed)."""
    if len(values) == 1:
        return "single"
    if isinstance(value, dict) and "values" not in value:
        return value.get("spacing", "linear")
    return "irregular"


def _parse_grid(design):
    design.expect(("kind",) + PARAMETERS)
    axes = tuple(_grid_axis(design, name) for name in PARAMETERS)
    design.finish()
    spacing = tuple(_axis_spacing(design.data[name], axis)
                    for name, axis in zip(PARAMETERS, axes))
    return GridSpec(axes=axes, spacing=spacing)


def _doe_bound(design, name):
    if not design.has(name):
        design.missing(name, "is required (a number to fix it, or {min, max[, scale]})")
    value = design.raw(name)
    if _is_number(value):
        _check_domain(design, name, name, value)
        return Bound(name, float(value), float(value), "fixed")
    if not isinstance(value, dict):
        design.error(name, "must be a number (fixed) or a table {min, max[, scale]}", value)
    tab = _Table(value, design.key(name), design.source)
    tab.expect(("value", "min", "max", "scale"))
    if tab.has("value"):
        v = tab.get("value", _is_number, "a finite number")
        tab.finish()
        _check_domain(tab, "value", name, v)
        return Bound(name, float(v), float(v), "fixed")
    lo = tab.get("min", _is_number, "a finite number")
    hi = tab.get("max", _is_number, "a finite number")
    scale = tab.get("scale", lambda v: v in ("linear", "log"), '"linear" or "log"', "linear")
    tab.finish()
    _check_domain(tab, "min", name, lo)
    _check_domain(tab, "max", name, hi)
    if not hi > lo:
        tab.error("max", f"must be > min = {lo!r} (an empty range; use value = x to fix it)", hi)
    if scale == "log" and not lo > 0:
        tab.error("min", 'must be > 0 with scale = "log"', lo)
    return Bound(name, float(lo), float(hi), scale)


def _parse_doe(design):
    design.expect(("kind", "sampler", "n", "seed", "scramble") + PARAMETERS)
    sampler = design.get("sampler", lambda v: v in SAMPLERS, " | ".join(map(repr, SAMPLERS)))
    n = design.get("n", _is_int, "an integer number of points >= 1")
    seed = design.get("seed", lambda v: _is_int(v) and v >= 0, "an integer >= 0", 0)
    scramble = design.get("scramble", lambda v: isinstance(v, bool), "true or false", True)
    bounds = tuple(_doe_bound(design, name) for name in PARAMETERS)
    design.finish()
    if n < 1:
        design.error("n", "must be >= 1 (an empty design)", n)
    if n > MAX_DOE_POINTS:
        # Beyond, the preflight's sizes (which refuse above limits.MAX_POINTS without
        # --force) overflowed a float before they could say so.
        design.error("n", f"must be <= 2**63 - 1 = {MAX_DOE_POINTS} (points are counted in "
                          "int64)", n)
    if sampler == "sobol" and n > SOBOL_MAX_POINTS:
        design.error("n", f"must be <= 2**30 = {SOBOL_MAX_POINTS} for the Sobol' sampler", n)
    if sampler == "lhs" and n > LHS_MAX_POINTS:
        design.error("n", f"must be <= {LHS_MAX_POINTS} for a Latin hypercube (built whole in "
                          "memory); use sampler = \"sobol\" for larger designs", n)
    if not any(not b.fixed for b in bounds):
        design.error("kind", "a design of experiments needs at least one sampled parameter "
                             "(all four are fixed; use a grid)", "doe")
    if not scramble and sampler != "sobol":
        design.error("scramble", "applies to the Sobol' sampler only", scramble)
    if not scramble and design.has("seed"):
        # The unscrambled sequence is one fixed sequence: a seed there changed nothing.
        design.error("seed", "has no effect with scramble = false (the unscrambled Sobol' "
                             "sequence is fixed); remove one of them", seed)
    return DoESpec(sampler=sampler, n=n, seed=seed, scramble=scramble, bounds=bounds)


# --------------------------------------------------------------------------- scene

@dataclasses.dataclass(frozen=True)
class MaterialSpec:
    """One named material of a scene, as given (SI units; None: not given).

    The contact law is ``(alpha, beta)``; ``m`` or (``radius``, ``density``) gives the mass,
    ``k`` or (``radius``, ``E``, ``nu``, floor ``floor_E``, ``floor_nu``) the stiffness, and
    ``gamma0`` or ``damping`` (a model name and its parameters) the damping.
    :func:`sweep.sweeps.design.resolve_material` turns it into (m, k, gamma0).
    """

    name: str
    alpha: float
    beta: float
    m: float | None = None
    k: float | None = None
    gamma0: float | None = None
    radius: float | None = None
    density: float | None = None
    E: float | None = None
    nu: float | None = None
    floor_E: float = math.inf
    floor_nu: float = 0.0
    damping: tuple = ()

    @property
    def damping_model(self):
        return dict(self.damping).get("model")

    def damping_params(self):
        return {k: v for k, v in self.damping if k != "model"}


@dataclasses.dataclass(frozen=True)
class SceneSpec:
    """A physical scene: materials x impact speeds v0 [m/s] x loads F [N] under gravity g.

    ``spacing`` holds, per axis, how the values were given, as a grid's axes do
    (:func:`_axis_spacing`): ``"linear"`` or ``"log"`` (a range), ``"irregular"`` (a list)
    or ``"single"`` (one value).
    """

    materials: tuple
    v0: tuple
    F: tuple
    g: float
    spacing: tuple = (("v0", "linear"), ("F", "linear"))
    kind: str = "scene"

    @property
    def shape(self):
        return (len(self.materials), len(self.v0), len(self.F))

    @property
    def size(self):
        return math.prod(self.shape)

    @property
    def exponents(self):
        """The (alpha, beta) of every material."""
        return tuple(dict.fromkeys((m.alpha, m.beta) for m in self.materials))


#: Damping models of a material and their parameters (``damping = {model = ..., ...}``).
DAMPING_MODELS = {
    "target_e": ("e", "v0"),              # numerical CoR e at impact speed v0 (root-finding)
    "tsuji": ("e",),                      # Tsuji-Tanaka-Ishida law: closed form from e
    "kuwabara_kono": ("eta1", "eta2"),    # viscous constants of the bead material
}
_MATERIAL_KEYS = ("radius", "density", "E", "nu")


def _physical(tab, key, default=dataclasses.MISSING):
    """A number in the domain of a physical or material quantity of the registry (absent:
    ``default``, or an error if there is none)."""
    if default is not dataclasses.MISSING and not tab.has(key):
        tab.used.add(key)
        return default
    domain = {**registry.PHYSICAL, **registry.MATERIAL}
    value = tab.get(key, _is_number, f"a finite number [{domain[key].units}]")
    _check_domain(tab, key, key, value, domain)
    return float(value)


def _scene_law(tab):
    if tab.has("law"):
        law = tab.get("law", lambda v: v in registry.MODELS,
                      " | ".join(map(repr, registry.MODELS)))
        if tab.has("alpha") or tab.has("beta"):
            tab.error("law", "give either law or alpha and beta, not both", law)
        return registry.MODELS[law]
    values = []
    for name in ("alpha", "beta"):
        value = tab.get(name, _is_number, "a finite number (or give law = \"kk\" etc.)")
        _check_domain(tab, name, name, value)
        values.append(float(value))
    return tuple(values)


def _either(tab, direct, derived, only_derived):
    """Require the key ``direct`` or every key of ``derived``; ``only_derived`` (a key used
    for nothing else) must not come with ``direct``."""
    if tab.has(direct) and tab.has(only_derived):
        tab.error(only_derived, f"derives {direct}, which is given: give one or the other")
    if tab.has(direct) or all(tab.has(k) for k in derived):
        return
    missing = [k for k in derived if not tab.has(k)]
    tab.missing(direct, f"is required, or derive it from {', '.join(derived)} "
                        f"(missing: {', '.join(missing)})")


def _scene_damping(tab, law):
    if tab.has("gamma0") == tab.has("damping"):
        tab.error("gamma0", "give exactly one of gamma0 [s m^(alpha-beta)] and damping = "
                            "{model = ...}")
    if tab.has("gamma0"):
        return _physical(tab, "gamma0"), ()
    sub = tab.table("damping")
    sub.expect({"model"}.union(*DAMPING_MODELS.values()))
    model = sub.get("model", lambda v: v in DAMPING_MODELS,
                    " | ".join(map(repr, DAMPING_MODELS)))
    params = {key: _physical(sub, key) for key in DAMPING_MODELS[model]}
    sub.finish()
    need = {"tsuji": registry.MODELS["tti"], "kuwabara_kono": registry.MODELS["kk"]}
    if model in need and law != need[model]:
        sub.error("model", f"applies to the law (alpha, beta) = {need[model]} only, not the "
                           f"material's {law}", model)
    if model == "kuwabara_kono" and not (tab.has("E") and tab.has("nu")):
        sub.error("model", "kuwabara_kono needs the bead's E and nu in the material", model)
    if model == "kuwabara_kono":
        _kuwabara_kono_domain(tab, sub, params)
    return None, (("model", model),) + tuple(sorted(params.items()))


def _kuwabara_kono_domain(tab, sub, params):
    # Checked here, not only by sweep.materials when the design is built, so that the
    # error names the file and key as every other configuration error does.
    if tab.data["nu"] == 0:
        tab.error("nu", "must be != 0 for the kuwabara_kono damping (its constant divides "
                        "by nu^2)", tab.data["nu"])
    if params["eta1"] + params["eta2"] == 0:
        sub.error("eta2", "eta1 + eta2 must be > 0 for the kuwabara_kono damping",
                  params["eta2"])


def _parse_material(tab, name):
    tab.expect(("law", "alpha", "beta", "m", "k", "gamma0", "floor", "damping")
               + _MATERIAL_KEYS)
    alpha, beta = _scene_law(tab)
    _either(tab, "m", ("radius", "density"), "density")
    _either(tab, "k", ("radius", "E", "nu"), "floor")
    props = {key: _physical(tab, key, None) for key in ("m", "k") + _MATERIAL_KEYS}
    hertz_alpha = registry.MODELS["hertz"][0]  # materials.HERTZ_ALPHA, without numba
    if props["k"] is None and alpha != hertz_alpha:
        tab.error("E", f"Hertz stiffness (from radius, E, nu) needs alpha = {hertz_alpha:g}",
                  alpha)
    floor_E, floor_nu = _scene_floor(tab.table("floor"))
    gamma0, damping = _scene_damping(tab, (alpha, beta))
    _kuwabara_kono_floor(tab, dict(damping).get("model"), floor_E, floor_nu)
    _refuse_unused(tab, props, dict(damping).get("model"))
    tab.finish()
    return MaterialSpec(name=name, alpha=alpha, beta=beta, gamma0=gamma0, floor_E=floor_E,
                        floor_nu=floor_nu, damping=damping, **props)


def _kuwabara_kono_floor(tab, damping_model, floor_E, floor_nu):
    # Brilliantov et al.'s constant A is that of two bodies of one viscoelastic material (or
    # a rigid floor): on an elastic floor of another material the bead's A overstates the
    # damping, to first order by the inverse of the bead's share of the compliance (1.8e5 for
    # steel on a rubber-like floor; audit, 2026-12-07). Its (E, nu) are not asked for there.
    if damping_model != "kuwabara_kono" or math.isinf(floor_E):
        return
    if (floor_E, floor_nu) != (tab.data["E"], tab.data["nu"]):
        tab.error("floor", "the kuwabara_kono damping is for a floor of the bead's material "
                           f"(E = {tab.data['E']:g}, nu = {tab.data['nu']:g}) or a rigid one "
                           "(Brilliantov et al. 1996): give gamma0, or damping = {model = "
                           "\"target_e\", ...}", tab.data["floor"])


def _scene_floor(floor):
    """The floor's (E, nu): both, or neither for a rigid floor (E = inf)."""
    floor.expect(("E", "nu"))
    if not (floor.has("E") or floor.has("nu")):
        return math.inf, 0.0
    for key, other in (("E", "nu"), ("nu", "E")):
        if not floor.has(key):
            # Hertz needs both; a default for one (nu = 0, or a rigid floor) would be a
            # silent guess about the other's material.
            floor.missing(key, f"is required with floor.{other} (the floor's Young's modulus "
                               "and Poisson's ratio, both; omit floor for a rigid one)")
    floor_E, floor_nu = _physical(floor, "E"), _physical(floor, "nu")
    floor.finish()
    return floor_E, floor_nu


def _refuse_unused(tab, props, damping_model):
    """Refuse a material property that derives nothing here: radius derives m (with
    density) or k (Hertz); E and nu derive k, or the kuwabara_kono damping."""
    derives = {"radius": ("m", "k") if props["m"] is None or props["k"] is None else (),
               "E": ("k",) if props["k"] is None else (), "nu": ()}
    if damping_model == "kuwabara_kono":
        derives["E"] = derives["nu"] = ("gamma0",)
    derives["nu"] = derives["nu"] or derives["E"]
    for key, used_for in derives.items():
        if tab.has(key) and not used_for:
            given = "m and k are" if key == "radius" else "k is"
            tab.error(key, f"is ignored: {given} given directly, and nothing else here uses "
                           f"{key} (remove it)")


def _scene_axis(design, name):
    """A scene axis and its spacing, by the grid's rule (:func:`_axis_spacing`): a list is
    "irregular" (it may be unsorted or uneven: calling it "linear" was wrong metadata)."""
    values = _grid_axis(design, name)
    return values, _axis_spacing(design.data[name], values)


def _parse_scene(design):
    design.expect(("kind", "materials", "v0", "F", "g"))
    mats = design.table("materials", required=True)
    if not mats.data:
        design.error("materials", "must name at least one material ([design.materials.NAME])")
    materials = tuple(_parse_material(mats.table(name), name) for name in list(mats.data))
    mats.finish()
    v0, v0_spacing = _scene_axis(design, "v0")
    F, F_spacing = _scene_axis(design, "F")
    g = design.get("g", _is_number, "a finite number [m/s^2]", 9.81)
    design.finish()
    return SceneSpec(materials=materials, v0=v0, F=F, g=float(g),
                     spacing=(("v0", v0_spacing), ("F", F_spacing)))


#: Design kinds: ``design.kind`` -> parser of the ``[design]`` table. A new kind (e.g. the
#: physical "scene" mapped to (gamma, g~) by sweep.model.scale) registers its parser here
#: and a matching builder in ``sweep.sweeps.design.BUILDERS``; nothing else needs to change.
DESIGN_KINDS: dict[str, Callable[[_Table], Any]] = {
    "grid": _parse_grid,
    "doe": _parse_doe,
    "scene": _parse_scene,
}


# --------------------------------------------------------------------------- outputs

@dataclasses.dataclass(frozen=True)
class Outputs:
    """What a sweep stores, and therefore what it must compute.

    Attributes
    ----------
    methods : tuple of str
        Methods whose CoR is stored as ``e_<method>``.
    fields : tuple of str
        Derived fields stored: integrator fields and ``error_<method>``.
    """

    methods: tuple
    fields: tuple

    @property
    def variables(self):
        """Names of the stored variables, in a stable order."""
        return tuple(f"e_{m}" for m in self.methods) + self.fields

    @property
    def error_methods(self):
        return tuple(f[len("error_"):] for f in self.fields if f.startswith("error_"))

    @property
    def needs_integration(self):
        """The numerical integration runs (once) iff e_numeric, an integrator field or an
        error field (which all compare against e_numeric) is requested."""
        return ("numeric" in self.methods
                or any(f in registry.integrator_fields() for f in self.fields)
                or bool(self.error_methods))

    @property
    def approximations(self):
        """Approximations to evaluate: stored, or needed by an error field."""
        wanted = set(self.methods) | set(self.error_methods)
        return tuple(m for m in registry.approximations() if m in wanted)

    @property
    def composites(self):
        """Composite methods to evaluate (``"auto"``; their own fields need them stored)."""
        return tuple(m for m in registry.composites() if m in self.methods)


def _name_list(tab, key, allowed, what):
    value = tab.raw(key)
    if value == "all":
        return tuple(allowed)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        tab.error(key, f'must be "all" or a list of {what} names', value)
    seen = set()
    for v in value:
        if v in seen:
            tab.error(key, "must not list a name twice", v)
        seen.add(v)
    return tuple(value)


def _check_field(tab, f, methods):
    approximations = registry.approximations()
    own = registry.method_fields()
    if f in own:
        if own[f][0] not in methods:
            tab.error("fields", f"is a field of method {own[f][0]!r}, which outputs.e must "
                                "list", f)
        return
    if f == "error_numeric":
        tab.error("fields", "error fields compare an approximation with e_numeric; "
                            "error_numeric would be identically 0", f)
    if f.startswith("error_"):
        if f[len("error_"):] not in approximations:
            tab.error("fields", "unknown approximation in error field; expected "
                      f"error_<{'|'.join(approximations)}>", f)
    elif f not in registry.integrator_fields():
        tab.error("fields", "unknown field; expected one of "
                  f"{', '.join(registry.integrator_fields() + tuple(own))} or "
                  "error_<method>", f)


def _off_domain(design, method):
    """Why ``method`` is undefined somewhere on ``design`` (a phrase), or None.

    The domain is the method's :attr:`sweep.registry.Method.models`; a design kind without
    ``exponents`` counts as sampling them over a range.
    """
    models = registry.METHODS[method].models
    if models is None:
        return None
    pairs = getattr(design, "exponents", None)
    defined = " or ".join(f"({a:g}, {b:g})" for a, b in models)
    if pairs is None:
        return (f"method {method!r} is defined for (alpha, beta) = {defined} only, and the "
                "design samples alpha or beta over a range")
    # The first pair off the domain comes within len(models) + 1 pairs, if there is one.
    off = next(((a, b) for a, b in pairs if (a, b) not in models), None)
    if off is None:
        return None
    return (f"method {method!r} is defined for (alpha, beta) = {defined} only, and the "
            f"design has (alpha, beta) = ({off[0]:g}, {off[1]:g})")


def _check_domains(tab, design, methods, fields):
    """Refuse a requested method (or error field) undefined somewhere on the design: it
    would store NaN there."""
    wanted = [("e", m) for m in methods]
    wanted += [("fields", f) for f in fields if f.startswith("error_") and f[6:] not in methods]
    for key, name in wanted:
        why = _off_domain(design, name.removeprefix("error_"))
        if why is not None:
            tab.error(key, f"{why}; leave {name} out or give only those exponents")


def _parse_outputs(tab, design):
    tab.expect(("e", "fields"))
    methods = fields = ()
    all_methods = tuple(registry.METHODS)
    if tab.has("e"):
        # "all": every method computing e its own way and defined on the whole design; a
        # composite one is asked for by name.
        methods = _name_list(tab, "e", [m for m in all_methods if m not in
                                        registry.composites()
                                        and _off_domain(design, m) is None], "method")
        for m in methods:
            if m not in all_methods:
                tab.error("e", f"unknown method; expected one of {', '.join(all_methods)}", m)
    errors = tuple(f"error_{m}" for m in registry.approximations())
    own = tuple(f for f, (m, _) in registry.method_fields().items() if m in methods)
    if tab.has("fields"):
        fields = _name_list(tab, "fields", registry.integrator_fields() + own
                            + tuple(e for e in errors if e[len("error_"):] in methods), "field")
        for f in fields:
            _check_field(tab, f, methods)
    tab.used.update({"e", "fields"})
    tab.finish()
    _check_domains(tab, design, methods, fields)
    if not methods and not fields:
        tab.error("e", "nothing to compute: request at least one method in outputs.e or a "
                       "field in outputs.fields", [])
    # Stable order whatever the order in the file: equal configs give equal datasets.
    order = {name: i for i, name in enumerate(all_methods)}
    forder = {name: i for i, name in enumerate(registry.integrator_fields() + own + errors)}
    return Outputs(methods=tuple(sorted(methods, key=order.__getitem__)),
                   fields=tuple(sorted(fields, key=forder.__getitem__)))


# --------------------------------------------------------------------------- integrator

@dataclasses.dataclass(frozen=True)
class IntegratorSettings:
    """Options of the ``"numeric"`` method (:data:`sweep.registry.METHODS`) given in the file.

    ``given`` holds ``(name, value)`` pairs in name order; options not given take the
    package default. Attribute access (``settings.steps``) reads :meth:`kwargs`.
    """

    given: tuple = ()

    def kwargs(self):
        """Keyword arguments of ``sweep.api.integrate``: the options the file gives (the
        api fills in the defaults, and with ``tol`` alone chooses the resolution)."""
        return dict(self.given)

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return registry.METHODS["numeric"].check_options(self.kwargs())[name]
        except KeyError:
            raise AttributeError(name) from None


def _read_options(tab, method):
    """Values of ``method``'s registered options found in table ``tab``."""
    known = [opt.name for opt in method.options]
    for key in tab.data:
        if key not in known:
            hint = difflib.get_close_matches(key, known, n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else ""
            tab.error(key, f"unknown option for method {method.name!r}{extra}; allowed: "
                           f"{', '.join(known) or 'none'}")
    return {opt.name: tab.get(opt.name, opt.check, opt.rule)
            for opt in method.options if tab.has(opt.name)}


def _parse_integrator(tab):
    given = _read_options(tab, registry.METHODS["numeric"])
    return IntegratorSettings(given=tuple(sorted(given.items())))


def _check_integrator_used(tab, integrator, outputs, options):
    """[integrator]'s options must shape a result: like [options.<method>] of a method not
    computed, ignored ones would look as if they had (``device = "cuda"`` on a sweep of
    closed forms ran, rc 0, on no GPU). A composite method (auto) integrates with them,
    at its own tol where it has one."""
    given = dict(integrator.given)
    if given and not (outputs.needs_integration or outputs.composites):
        key = next(iter(given))
        tab.error(key, "is an option of the integrator, which this sweep never runs "
                       "(outputs ask for no e_numeric, integrator field, error field or "
                       "auto); remove [integrator] or ask for e_numeric", given[key])
    own = [m for m in outputs.composites if "tol" in options.get(m, {})]
    if "tol" in given and not outputs.needs_integration and own:
        tab.error("tol", f"is not used: {own[0]} integrates at its own tol (options."
                         f"{own[0]}.tol = {options[own[0]]['tol']!r}); remove one",
                  given["tol"])


def _parse_options(tab, outputs):
    options = {}
    approximations = registry.approximations() + registry.composites()
    computed = outputs.approximations + outputs.composites
    for name in list(tab.data):
        if name not in approximations:
            hint = " (the integrator's options go in [integrator])" if name == "numeric" else ""
            tab.error(name, f"unknown method{hint}; expected one of {', '.join(approximations)}")
        options[name] = _read_options(tab.table(name), registry.METHODS[name])
        if name not in computed:
            # Silently ignored, they would look as if they had shaped the results.
            tab.error(name, "options of a method this sweep does not compute (outputs.e and "
                      "the error_ fields ask for: "
                      f"{', '.join(computed) or 'no approximation'}); remove them or ask "
                      "for the method")
    tab.finish()
    return options


# --------------------------------------------------------------------------- config

@dataclasses.dataclass(frozen=True)
class Config:
    """A validated sweep configuration.

    Attributes
    ----------
    text : str
        The TOML text, stored verbatim in the output's global attributes.
    sha256 : str
        Hash of the canonical (parsed, key-sorted) configuration: comments and formatting do
        not change it, any value does. An existing output is up to date only at the same.
    computed : str
        The canonical JSON of what the values depend on: the configuration without
        :data:`PRESENTATION_KEYS` (the title, the description and the ``[run]`` table, whose
        chunk size the resume checks apart). Resume compares it, and names the keys that
        differ; ``values_sha256`` is its hash.
    compress : str
        ``run.compress``: a choice of :data:`sweep.registry.COMPRESSION`, how much a
        computed variable's deflate must save for the file to store it deflated
        (:func:`sweep.store.netcdf.deflate_filters`), or "none": stored as computed.
    """

    text: str
    source: str
    title: str
    description: str
    design: Any
    outputs: Outputs
    integrator: IntegratorSettings
    options: dict
    chunk_size: int
    sha256: str
    compress: str = registry.DEFAULT_COMPRESSION
    computed: str = ""

    @property
    def values_sha256(self) -> str:
        """SHA-256 of :attr:`computed` (:attr:`sha256` for a Config built without it)."""
        if not self.computed:
            return self.sha256
        return hashlib.sha256(self.computed.encode()).hexdigest()

    @property
    def size(self):
        return self.design.size

    def method_options(self, method):
        return dict(self.options.get(method, {}))


def loads(text, source=""):
    """Parse and validate a configuration from TOML text.

    Parameters
    ----------
    text : str
        TOML document.
    source : str, optional
        Where it came from (prefixes error messages).

    Raises
    ------
    ConfigError
        On any invalid key or value, naming it.
    """
    data = _parse_toml(text, source)
    root = _Table(data, "", source)
    # Unknown top-level keys first: a misspelt table name must not surface as "missing".
    root.expect(("title", "description", "design", "outputs", "integrator", "options", "run"))
    title = root.get("title", lambda v: isinstance(v, str), "a string",
                     Path(source).stem if source else "sweep")
    description = root.get("description", lambda v: isinstance(v, str), "a string", "")
    design = root.table("design", required=True)
    kind = design.get("kind", lambda v: isinstance(v, str), "a string naming the design kind")
    if kind not in DESIGN_KINDS:
        design.error("kind", f"unknown design kind; expected one of {', '.join(DESIGN_KINDS)}",
                     kind)
    design_spec = DESIGN_KINDS[kind](design)
    outputs = _parse_outputs(root.table("outputs", required=True), design_spec)
    integrator_tab = root.table("integrator")
    integrator = _parse_integrator(integrator_tab)
    options = _parse_options(root.table("options"), outputs)
    _check_integrator_used(integrator_tab, integrator, outputs, options)
    run = root.table("run")
    chunk_size = run.get("chunk_size", is_chunk_size, CHUNK_SIZE_RULE, DEFAULT_CHUNK_SIZE)
    compress = _compression(run.get("compress", lambda v: _compression(v) is not None,
                                    _COMPRESSION_RULE, registry.DEFAULT_COMPRESSION))
    run.finish()
    root.finish()
    if "compress" in data.get("run", {}):   # true and "small" are one configuration
        data = {**data, "run": {**data["run"], "compress": compress}}
    canonical = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
    computed = _canonical_numbers({k: v for k, v in data.items() if k not in PRESENTATION_KEYS})
    return Config(text=text, source=str(source), title=title, description=description,
                  design=design_spec, outputs=outputs, integrator=integrator, options=options,
                  chunk_size=chunk_size, compress=compress,
                  sha256=hashlib.sha256(canonical.encode()).hexdigest(),
                  computed=json.dumps(computed, sort_keys=True, separators=(",", ":"),
                                      default=str))


def _canonical_numbers(value):
    """``value`` with every int a float where that is exact (``steps = 16`` and ``16.0``
    are one configuration; a seed beyond 2**53 stays as it is)."""
    if isinstance(value, dict):
        return {k: _canonical_numbers(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_canonical_numbers(v) for v in value]
    if _is_int(value) and abs(value) <= 2 ** 53:
        return float(value)
    return value


def _parse_toml(text, source):
    """TOML text -> dict, refusing oversized or too deeply nested documents by name."""
    where = f"{source}: " if source else ""
    if len(text) > limits.CONFIG_MAX_BYTES:
        raise ConfigError(f"{where}configuration larger than {limits.CONFIG_MAX_BYTES} "
                          "bytes; refused")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}not valid TOML: {exc}") from None
    except RecursionError:  # nested arrays / inline tables recurse in the parser
        raise ConfigError(f"{where}nested deeper than {limits.CONFIG_MAX_DEPTH} levels; "
                          "refused") from None
    deep = _too_deep(data, limits.CONFIG_MAX_DEPTH)
    if deep is not None:
        raise ConfigError(f"{where}{deep}: nested deeper than {limits.CONFIG_MAX_DEPTH} "
                          "levels; refused")
    return data


def _too_deep(data, max_depth):
    """Dotted key of the first value nested deeper than ``max_depth``, or None.

    Iterative: dotted table headers nest without recursion in the parser, and a recursive
    walk of them would fail where the check is meant to answer.
    """
    stack = [(data, "", 0)]
    while stack:
        value, key, depth = stack.pop()
        if depth > max_depth:
            return key or "<root>"
        if isinstance(value, dict):
            items = ((f"{key}.{k}" if key else str(k), v) for k, v in value.items())
        elif isinstance(value, list):
            items = ((f"{key}[{i}]", v) for i, v in enumerate(value))
        else:
            continue
        stack.extend((v, k, depth + 1) for k, v in items)
    return None


def _read_config_bytes(path):
    """At most CONFIG_MAX_BYTES + 1 bytes of ``path``: enough to refuse a larger file
    without reading it (a size from stat is refused at once; devices and pipes such as
    /dev/zero report none and are cut off by the bounded read)."""
    limit = limits.CONFIG_MAX_BYTES
    with open(path, "rb") as fh:
        size = os.fstat(fh.fileno()).st_size
        if size > limit:
            raise ConfigError(f"{path}: configuration file of {size} bytes is larger than "
                              f"the limit of {limit} bytes; refused without reading it")
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise ConfigError(f"{path}: configuration larger than {limit} bytes (read stopped "
                          "there); refused")
    return data


def load(path):
    """Read and validate the configuration file at ``path`` (see :func:`loads`), UTF-8
    text with or without a byte-order mark.

    Raises
    ------
    ConfigError
        Also when the file cannot be read, is larger than
        :data:`~sweep.sweeps.limits.CONFIG_MAX_BYTES` or is not UTF-8 text.
    """
    path = Path(path)
    try:
        data = _read_config_bytes(path)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read configuration: {exc.strerror}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                          f"{exc.start}); save the configuration as UTF-8") from None
    # The byte-order mark some editors write is no TOML: tomllib refused it as "Invalid
    # statement (at line 1, column 1)", a line that looked right. It is read as UTF-8 is.
    return loads(text.removeprefix("\ufeff"), source=str(path))


def from_dict(data: Any, source: str = "") -> Config:
    """Validate a configuration given as a dict: the tables of the file, as Python values.

    The dict is written as TOML text (:func:`sweep.sweeps.toml_text.dumps`, kept as
    :attr:`Config.text`) and parsed by :func:`loads`: a dict and the equivalent file give
    the same configuration, hash and errors.

    Parameters
    ----------
    data : mapping
        E.g. ``{"design": {"kind": "grid", "alpha": 1.5, ...}, "outputs": {...}}``; numpy
        scalars and arrays are accepted as numbers and lists.
    source : str, optional
        Where it came from (prefixes error messages).

    Raises
    ------
    ConfigError
        As :func:`loads`, and for a value TOML cannot hold (e.g. None), naming its key.
    """
    try:
        text = toml_text.dumps(data)
    except toml_text.TomlValueError as exc:
        raise ConfigError(f"{source}: {exc}" if source else str(exc)) from None
    return loads(text, source)


def _is_toml_text(text: str) -> bool:
    """A string is TOML text, not a path, if it spans lines or assigns a key -- unless a
    file of that name exists."""
    return ("\n" in text or "=" in text) and not os.path.exists(text)


def as_config(config: Any) -> Config:
    """A validated configuration from a path, TOML text, a dict or a :class:`Config`.

    Parameters
    ----------
    config : Config, path-like, str or mapping
        A :class:`Config` is returned as it is; a ``pathlib.Path`` is read
        (:func:`load`); a string is TOML text if it has a line break or an ``=`` and names
        no existing file, a path otherwise; a mapping goes to :func:`from_dict`.

    Raises
    ------
    ConfigError
        Invalid configuration, unreadable file, or an object of another type.
    """
    if isinstance(config, Config):
        return config
    if isinstance(config, dict) or hasattr(config, "keys"):
        return from_dict(config)
    if isinstance(config, str) and _is_toml_text(config):
        return loads(config)
    if isinstance(config, (str, os.PathLike)):
        return load(config)
    raise ConfigError("a configuration is a path, TOML text, a dict or a "
                      f"sweep.sweeps.config.Config, got {type(config).__name__}")
