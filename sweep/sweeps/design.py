"""Designs: the points of a sweep, generated chunk by chunk on demand.

A design maps a flat point index ``i`` in ``[0, size)`` to ``(alpha, beta, gamma, g~)``.
Points are never materialised for the whole design (a 1e8-point design would need 3.2 GB):
:meth:`Design.points` generates the points of one chunk ``[start, stop)``, and the value of
point ``i`` never depends on how the design is cut into chunks -- that is what makes results
independent of the chunk size and lets an interrupted run resume at any chunk.

* :class:`GridDesign` -- a full tensor grid, flat index in C order over
  (alpha, beta, gamma, g~): a chunk is ``np.unravel_index`` of its flat range.
* :class:`DoEDesign` -- ``n`` points of a design of experiments in a box, uniform or
  log-uniform per axis: scrambled Sobol' (``scipy.stats.qmc.Sobol``, first ``n`` points of
  the seeded sequence, reached by ``fast_forward``), Latin hypercube (``scipy.stats.qmc
  .LatinHypercube``, built once, it is a global permutation) or pseudo-random uniform
  (counter-based blocks of a seeded ``SeedSequence``).

* :class:`SceneDesign` -- a physical scene: named materials x impact speeds v0 x loads F
  under gravity g, flat index in C order over (material, v0, F); each point is scaled to
  (alpha, beta, gamma, g~) by :func:`sweep.model.scale` (eq. (2)). The materials' mass,
  stiffness and damping are resolved once, when the design is built
  (:func:`resolve_material`, :mod:`sweep.materials`).

Every design says how its results are stored (:meth:`Design.layout`, a
:class:`sweep.store.Layout`). New design kinds add a builder to :data:`BUILDERS` under the
same ``design.kind`` as their parser in :data:`sweep.sweeps.config.DESIGN_KINDS`.

Floor 4: may import :mod:`sweep.sweeps.config`, :mod:`sweep.materials`, :mod:`sweep.model`,
:mod:`sweep.store` (the layout), :mod:`sweep._format`, numpy and scipy.
"""
from __future__ import annotations

import abc
import dataclasses
import math
import operator
import warnings
from collections.abc import Sequence

import numpy as np
from scipy.stats import qmc

from sweep import materials, model, store
from sweep._format import count
from sweep.sweeps.config import (PARAMETERS, ConfigError, DoESpec, GridSpec, MaterialSpec,
                                 SceneSpec)

__all__ = ["Design", "GridDesign", "DoEDesign", "SceneDesign", "Material", "resolve_material",
           "build", "chunk_bounds", "Chunks", "BUILDERS"]


def chunk_bounds(size, chunk_size):
    """Split ``range(size)`` into consecutive chunks.

    Returns
    -------
    list of (int, int)
        ``(start, stop)`` per chunk; all of length ``chunk_size`` but the last.
    """
    return list(Chunks(size, chunk_size))


class Chunks(Sequence):
    """The chunks of a design, computed on demand (a lazy :func:`chunk_bounds`).

    Memory does not grow with the number of chunks: chunk ``i`` is
    ``(i * chunk_size, min((i + 1) * chunk_size, size))``, computed when asked for.

    Parameters
    ----------
    size : int
        Number of points of the design.
    chunk_size : int
        Points per chunk, >= 1.

    Raises
    ------
    ValueError
        If ``chunk_size < 1`` or ``size < 0``.
    """

    def __init__(self, size: int, chunk_size: int) -> None:
        if chunk_size < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size!r}")
        if size < 0:
            raise ValueError(f"size must be >= 0, got {size!r}")
        self.size = int(size)
        self.chunk_size = int(chunk_size)

    def __len__(self) -> int:
        return -(-self.size // self.chunk_size)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        n = len(self)
        i = operator.index(index)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"chunk {index} outside [0, {n})")
        start = i * self.chunk_size
        return start, min(start + self.chunk_size, self.size)

    def __iter__(self):
        for start in range(0, self.size, self.chunk_size):
            yield start, min(start + self.chunk_size, self.size)


class Design(abc.ABC):
    """Base of all designs.

    Attributes
    ----------
    kind : str
        ``design.kind`` of the configuration.
    size : int
        Number of points.
    dims : tuple of str
        Dimensions of the stored variables: the four parameters for a grid, ``("point",)``
        for scattered designs.
    shape : tuple of int
        Lengths of ``dims``; ``prod(shape) == size``.
    """

    kind: str
    dims: tuple
    shape: tuple

    @property
    def size(self):
        return math.prod(self.shape)

    @property
    def axes(self):
        """Coordinate arrays of grid dimensions (name -> 1-D array); empty if scattered."""
        return {}

    @property
    def spacing(self):
        """Spacing of grid dimensions (name -> "linear", "log", "irregular" or "single");
        empty if scattered or unknown."""
        return {}

    @abc.abstractmethod
    def points(self, start, stop):
        """Points ``start .. stop-1`` of the design.

        Returns
        -------
        tuple of 4 ndarray
            ``(alpha, beta, gamma, gtilde)``, contiguous float64 of length ``stop - start``.
        """

    def describe(self):
        """One line for humans and the dataset's attributes."""
        return f"{self.kind} design of {count(self.size, 'point')}"

    def layout(self) -> store.Layout:
        """How the results are stored: grid axes as coordinates, or the four parameters as
        per-point coordinates of a scattered design."""
        if self.axes:
            return store.Layout(dims=self.dims, shape=self.shape, axes=self.axes,
                                spacing=self.spacing)
        return store.Layout(dims=self.dims, shape=self.shape, axes={},
                            point_coords=PARAMETERS)


class GridDesign(Design):
    """A full grid over (alpha, beta, gamma, g~); size-1 axes are kept as dimensions."""

    kind = "grid"
    dims = PARAMETERS

    def __init__(self, spec: GridSpec):
        self._axes = {name: np.asarray(vals, dtype=np.float64)
                      for name, vals in zip(PARAMETERS, spec.axes)}
        self.shape = tuple(a.size for a in self._axes.values())
        self._spacing = spec.spacing

    @property
    def axes(self):
        return dict(self._axes)

    @property
    def spacing(self):
        return dict(zip(PARAMETERS, self._spacing))

    def points(self, start, stop):
        idx = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.shape)
        return tuple(np.ascontiguousarray(self._axes[name][i])
                     for name, i in zip(PARAMETERS, idx))

    def describe(self):
        sizes = " x ".join(f"{n}[{s}]" for n, s in zip(self.dims, self.shape))
        return f"grid design {sizes} = {count(self.size, 'point')}"


def _log_uniform(lo: float, hi: float, x: np.ndarray) -> np.ndarray:
    """``lo (hi/lo)^x`` for x in [0, 1]; in logs where ``hi/lo`` is beyond double
    precision (gamma from 1e-200 to 1e200, or from 5e-324): the ratio's infinity put every
    point at ``hi`` (and 0 x inf a NaN at x = 0)."""
    ratio = hi / lo
    if math.isfinite(ratio):
        return lo * np.exp(x * math.log(ratio))
    log_lo = math.log(lo)
    return np.exp(log_lo + x * (math.log(hi) - log_lo))


class DoEDesign(Design):
    """``n`` points of a design of experiments in a box (see the module docstring).

    The unit-cube sample ``x`` of the sampled axes is mapped per axis to
    ``lo + (hi - lo) x`` (uniform) or ``lo (hi/lo)^x`` (log-uniform); fixed axes repeat their
    value.
    """

    kind = "doe"
    dims = ("point",)
    #: Block length of the pseudo-random sampler: block ``b`` is drawn from its own stream
    #: ``SeedSequence(seed, spawn_key=(b,))``, so any chunk can be generated independently.
    RANDOM_BLOCK = 2 ** 16

    def __init__(self, spec: DoESpec):
        self.spec = spec
        self.shape = (spec.n,)
        self._d = len(spec.sampled)
        self._sobol = None          # cached engine and the index of its next point
        self._sobol_next = 0
        self._lhs = None
        self._block = None

    # -- unit-cube samples of the sampled axes, rows start..stop-1 -------------------------

    def _unit_sobol(self, start, stop):
        # Sequential chunks continue the cached engine (O(chunk)); any other start
        # fast-forwards a fresh engine (O(start)). Point i is the i-th point of the seeded
        # scrambled sequence either way.
        if self._sobol is None or start < self._sobol_next:
            self._sobol = _make_engine(qmc.Sobol, self._d, self.spec.seed,
                                       scramble=self.spec.scramble)
            self._sobol_next = 0
        if start > self._sobol_next:
            self._sobol.fast_forward(start - self._sobol_next)
        with warnings.catch_warnings():
            # scipy warns when the first draw is not a power of 2 long: balance properties
            # hold for 2^m-point prefixes. A chunk's draw is any length; the design's
            # description says once whether its n is a power of 2 (describe()).
            warnings.filterwarnings("ignore", message=".*balance properties of Sobol",
                                    category=UserWarning)
            x = self._sobol.random(stop - start)
        self._sobol_next = stop
        return x

    def _unit_lhs(self, start, stop):
        if self._lhs is None:
            self._lhs = _make_engine(qmc.LatinHypercube, self._d, self.spec.seed).random(
                self.spec.n)
        return self._lhs[start:stop]

    def _random_block(self, b):
        # The last block is kept: chunks smaller than a block reuse it.
        if self._block is None or self._block[0] != b:
            rng = np.random.Generator(np.random.PCG64(
                np.random.SeedSequence(self.spec.seed, spawn_key=(b,))))
            self._block = (b, rng.random((self.RANDOM_BLOCK, self._d)))
        return self._block[1]

    def _unit_random(self, start, stop):
        b0, b1 = start // self.RANDOM_BLOCK, (stop - 1) // self.RANDOM_BLOCK
        blocks = [self._random_block(b) for b in range(b0, b1 + 1)]
        x = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
        off = b0 * self.RANDOM_BLOCK
        return x[start - off:stop - off]

    def unit(self, start, stop):
        """Unit-cube sample, shape ``(stop - start, d)`` with d the number of sampled axes."""
        if not 0 <= start <= stop <= self.size:
            raise IndexError(f"chunk [{start}, {stop}) outside the design [0, {self.size})")
        if start == stop:
            return np.empty((0, self._d))
        return getattr(self, f"_unit_{self.spec.sampler}")(start, stop)

    def points(self, start, stop):
        x = self.unit(start, stop)
        out = []
        j = 0
        for b in self.spec.bounds:
            if b.fixed:
                out.append(np.full(stop - start, b.lo))
                continue
            col = x[:, j]
            j += 1
            if b.scale == "log":
                v = _log_uniform(b.lo, b.hi, col)
            else:
                v = b.lo + (b.hi - b.lo) * col
            # Rounding must not leave the box the configuration promised.
            out.append(np.ascontiguousarray(np.clip(v, b.lo, b.hi)))
        return tuple(out)

    def describe(self):
        axes = []
        for b in self.spec.bounds:
            if b.fixed:
                axes.append(f"{b.name}={b.lo:g}")
            else:
                axes.append(f"{b.name} in [{b.lo:g}, {b.hi:g}]"
                            + (" (log)" if b.scale == "log" else ""))
        return (f"{self._sampler_text()} design of {count(self.size, 'point')}"
                f"{self._balance_text()}: " + ", ".join(axes))

    def _sampler_text(self):
        spec = self.spec
        if spec.sampler != "sobol":
            return f"{spec.sampler} (seed {spec.seed})"
        return f"scrambled sobol (seed {spec.seed})" if spec.scramble else "unscrambled sobol"

    def _balance_text(self):
        """For a Sobol' design whose size is not a power of 2, that its balance holds for
        the largest power-of-2 prefix (audit D: at n = 1000, 24 empty strata on an axis,
        none at 1024)."""
        n = self.size
        if self.spec.sampler != "sobol" or not n & (n - 1):
            return ""
        return f" (not a power of 2: balanced for its first {2 ** (n.bit_length() - 1):,})"


# --------------------------------------------------------------------------- scenes

@dataclasses.dataclass(frozen=True)
class Material:
    """A material of a scene with its contact law resolved (SI units).

    Attributes
    ----------
    name : str
    m, k, gamma0, alpha, beta : float
        Mass [kg], stiffness [N m^-alpha], damping [s m^(alpha-beta)], exponents of law (1).
    origin : str
        How m, k and gamma0 were obtained (given, or which formula).
    """

    name: str
    m: float
    k: float
    gamma0: float
    alpha: float
    beta: float
    origin: str = "given"


def _resolve_damping(spec: MaterialSpec, m: float, k: float, g: float) -> tuple[float, str]:
    model_name, p = spec.damping_model, spec.damping_params()
    if model_name is None:
        return spec.gamma0, "gamma0 given"
    if model_name == "tsuji":
        return materials.tsuji_gamma0(p["e"], m, k), f"Tsuji relation, e = {p['e']:g}"
    if model_name == "kuwabara_kono":
        return (materials.kuwabara_kono_gamma0(p["eta1"], p["eta2"], spec.E, spec.nu),
                "Kuwabara-Kono viscous constant (Brilliantov et al. 1996)")
    gamma0 = materials.gamma0_for_cor(p["e"], p["v0"], m, k, spec.alpha, spec.beta, g=g)
    return gamma0, f"numerical e = {p['e']:g} at v0 = {p['v0']:g} m/s"


def resolve_material(spec: MaterialSpec, g: float = 9.81) -> Material:
    """Mass, stiffness and damping of a material as the scene gives them (docs/scenes.md).

    Raises
    ------
    ConfigError
        A value no formula accepts, named with the material.
    """
    try:
        if spec.m is None:
            m, how_m = materials.sphere_mass(spec.radius, spec.density), "m from R, rho"
        else:
            m, how_m = spec.m, "m given"
        if spec.k is None:
            k = materials.hertz_stiffness(spec.radius, spec.E, spec.nu, spec.floor_E,
                                          spec.floor_nu)
            how_k = "k from Hertz (R, E, nu" + (", floor)" if math.isfinite(spec.floor_E)
                                                else ", rigid floor)")
        else:
            k, how_k = spec.k, "k given"
        gamma0, how_d = _resolve_damping(spec, m, k, g)
    except ValueError as exc:
        raise ConfigError(f"design.materials.{spec.name}: {exc}") from None
    return Material(spec.name, float(m), float(k), float(gamma0), spec.alpha, spec.beta,
                    f"{how_m}; {how_k}; gamma0 from {how_d}")


class SceneDesign(Design):
    """Materials x v0 x F under gravity g, each point scaled to (alpha, beta, gamma, g~).

    Stored with dimensions (material, v0, F): the scaled gamma and g~ as data variables on
    them, the materials' m, k, gamma0, alpha, beta on ``material`` and g as a scalar.
    ``material`` is indexed 0..n-1 and the names are the auxiliary coordinate
    ``material_name`` (a CF coordinate variable cannot hold strings).
    """

    kind = "scene"
    dims = ("material", "v0", "F")
    #: Properties of each material stored in the dataset (per-material variables).
    MATERIAL_VARIABLES = ("m", "k", "gamma0", "alpha", "beta")

    def __init__(self, spec: SceneSpec):
        self.spec = spec
        self.materials = tuple(resolve_material(m, spec.g) for m in spec.materials)
        self.shape = spec.shape
        self._v0 = np.asarray(spec.v0, dtype=np.float64)
        self._F = np.asarray(spec.F, dtype=np.float64)
        self._props = {name: np.array([getattr(m, name) for m in self.materials])
                       for name in self.MATERIAL_VARIABLES}
        for mat in self.materials:
            self._check_scaling(mat)

    def _check_scaling(self, mat):
        # g + F/m >= 0 at every load, and gamma, g~ doubles at every point (or every point
        # would be INVALID); scale names the values. gamma and g~ are powers of v0 times a
        # factor increasing with F: their extremes lie at the extreme speeds.
        v0 = np.array([self._v0.min(), self._v0.max()])[:, None]
        try:
            model.scale(mat.m, mat.k, mat.gamma0, v0, mat.alpha, mat.beta, self.spec.g,
                        self._F)
        except ValueError as exc:
            raise ConfigError(f"design.materials.{mat.name}: {exc}") from None

    @property
    def axes(self):
        """The coordinates: the materials' index (their names: :meth:`layout`), v0, F."""
        return {"material": np.arange(len(self.materials)), "v0": self._v0.copy(),
                "F": self._F.copy()}

    def points(self, start, stop):
        i, j, l = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.shape)
        p = {name: values[i] for name, values in self._props.items()}
        gamma, gtilde = model.scale(p["m"], p["k"], p["gamma0"], self._v0[j], p["alpha"],
                                    p["beta"], self.spec.g, self._F[l])
        return tuple(np.ascontiguousarray(x, dtype=np.float64)
                     for x in (p["alpha"], p["beta"], np.atleast_1d(gamma),
                               np.atleast_1d(gtilde)))

    def layout(self) -> store.Layout:
        constants = {name: (("material",), values) for name, values in self._props.items()}
        constants[store.MATERIAL_NAME] = (("material",), [m.name for m in self.materials])
        constants["g"] = ((), self.spec.g)
        constants.update(self._scales())
        attrs = {**_SCALE_ATTRS, store.MATERIAL_NAME: {
            "long_name": "material name",
            "description": "name of the bead / floor material of the scene (design.materials)",
            "origin": "; ".join(f"{m.name}: {m.origin}" for m in self.materials)}}
        # k and gamma0 have units only where the materials' laws give them one UDUNITS unit.
        attrs.update(store.law_units_attrs(self._props["alpha"], self._props["beta"]))
        return store.Layout(dims=self.dims, shape=self.shape, axes=self.axes,
                            spacing=dict(self.spec.spacing), point_vars=("gamma", "gtilde"),
                            constants=constants, attrs=attrs,
                            aux_coords=(store.MATERIAL_NAME,))

    def _scales(self) -> dict:
        """Each (material, v0)'s units of the scaling (2), T and delta = v0 T: a scaled
        duration or compression of the dataset times them is in seconds or metres."""
        p = {name: self._props[name][:, None] for name in ("m", "k", "alpha")}
        t = model.time_scale(p["m"], p["k"], self._v0[None, :], p["alpha"])
        return {"time_scale": (("material", "v0"), t),
                "length_scale": (("material", "v0"), t * self._v0[None, :])}

    def describe(self):
        mats = ", ".join(f"{m.name} (alpha={m.alpha:g}, beta={m.beta:g}, m={m.m:.6g} kg, "
                         f"k={m.k:.6g}, gamma0={m.gamma0:.6g})" for m in self.materials)
        spacing = dict(self.spec.spacing)
        n = len(self.materials)
        return (f"scene design: {n} material{'s' if n != 1 else ''} [{mats}] x "
                f"v0[{self.shape[1]}] in [{self._v0.min():g}, {self._v0.max():g}] m/s "
                f"({spacing['v0']}) x "
                f"F[{self.shape[2]}] in [{self._F.min():g}, {self._F.max():g}] N, "
                f"g = {self.spec.g:g} m/s^2 = {count(self.size, 'point')}")


#: Attributes of a scene's units of the scaling (2) (:meth:`SceneDesign._scales`).
_SCALE_ATTRS = {
    "time_scale": {"long_name": "time unit T of the scaling", "units": "s",
                   "description": "T = (m/k)^(1/(alpha+1)) v0^((1-alpha)/(alpha+1)), report "
                                  "eq. (2): a scaled time times T is in seconds (t_f "
                                  "time_scale: the contact's duration)"},
    "length_scale": {"long_name": "length unit delta of the scaling", "units": "m",
                     "description": "delta = v0 T, report eq. (2): a scaled compression "
                                    "times delta is in metres (u_max length_scale: the "
                                    "largest compression)"},
}


def _make_engine(cls, d, seed, **kw):
    # scipy >= 1.15 calls the seed `rng`; older versions only know `seed`.
    try:
        return cls(d, rng=seed, **kw)
    except TypeError:  # pragma: no cover - scipy < 1.15
        return cls(d, seed=seed, **kw)


#: ``design.kind`` -> builder from the validated spec.
BUILDERS = {
    "grid": GridDesign,
    "doe": DoEDesign,
    "scene": SceneDesign,
}


def build(spec, source=""):
    """Build the design object of a validated design spec (``Config.design``).

    Parameters
    ----------
    spec : GridSpec, DoESpec or SceneSpec
    source : str, optional
        The configuration's file (``Config.source``), prefixed to errors as the parser
        prefixes its own.

    Raises
    ------
    ConfigError
        A value the builder refuses (a scene whose loads pull, or whose scaling leaves
        double precision), naming the material and the value.
    """
    try:
        builder = BUILDERS[spec.kind]
    except KeyError:
        raise ValueError(f"no design builder for design.kind {spec.kind!r}") from None
    try:
        return builder(spec)
    except ConfigError as exc:
        # A builder names the key (design.materials.NAME); the file, as the parser does.
        if not source:
            raise
        raise ConfigError(f"{source}: {exc}") from None
