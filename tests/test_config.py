"""Configuration parsing and validation (sweep.sweeps.config)."""
import math
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from sweep import registry
from sweep.sweeps import config
from sweep.sweeps.config import ConfigError

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

GRID = """
title = "t"
[design]
kind = "grid"
alpha = 1.5
beta = [1.0, 1.5]
gamma = {start = 0.0, stop = 0.1, num = 5}
gtilde = {start = 1e-3, stop = 10.0, num = 3, spacing = "log"}
[outputs]
e = ["numeric", "ord1"]
fields = ["status", "error_ord1"]
"""

DOE = """
[design]
kind = "doe"
sampler = "sobol"
n = 1000
seed = 7
alpha = {min = 1.0, max = 3.0}
beta = 1.5
gamma = {min = 1e-4, max = 1.0, scale = "log"}
gtilde = {min = 0.0, max = 10.0}
[outputs]
e = ["ord1"]
"""


def test_a_list_axis_is_stored_in_increasing_order():
    # Stored as given, [1.5, 1.0, 1.25] made a coordinate that xarray could not slice and
    # CF checkers refused (coordinate variables are monotonic).
    cfg = config.loads(GRID.replace("beta = [1.0, 1.5]", "beta = [1.5, 1.0, 1.25]"))
    assert dict(zip(config.PARAMETERS, cfg.design.axes))["beta"] == (1.0, 1.25, 1.5)
    assert dict(zip(config.PARAMETERS, cfg.design.spacing))["beta"] == "irregular"


def test_grid_config_parses_axes_and_outputs():
    cfg = config.loads(GRID)
    assert cfg.design.kind == "grid"
    assert cfg.design.shape == (1, 2, 5, 3)
    assert cfg.design.axes[2] == tuple(np.linspace(0.0, 0.1, 5))
    # log spacing hits both end points exactly
    assert cfg.design.axes[3] == (1e-3, 0.1, 10.0)
    assert cfg.outputs.methods == ("numeric", "ord1")
    assert cfg.outputs.variables == ("e_numeric", "e_ord1", "status", "error_ord1")
    assert cfg.outputs.needs_integration
    assert cfg.chunk_size == config.DEFAULT_CHUNK_SIZE
    assert cfg.integrator == config.IntegratorSettings()


def test_doe_config_parses_bounds():
    cfg = config.loads(DOE)
    d = cfg.design
    assert (d.kind, d.sampler, d.n, d.seed, d.scramble) == ("doe", "sobol", 1000, 7, True)
    assert [b.scale for b in d.bounds] == ["linear", "fixed", "log", "linear"]
    assert [b.name for b in d.sampled] == ["alpha", "gamma", "gtilde"]
    assert d.bounds[1].lo == d.bounds[1].hi == 1.5


def test_outputs_decide_what_runs():
    kk = DOE.replace("alpha = {min = 1.0, max = 3.0}", "alpha = 1.5")   # where sp is defined

    def outputs(e, fields="[]"):
        return config.loads(kk.replace('e = ["ord1"]', f"e = {e}\nfields = {fields}")).outputs

    only_ord1 = outputs('["ord1"]')
    assert not only_ord1.needs_integration and only_ord1.approximations == ("ord1",)
    # an error field needs the numerical CoR and its approximation, but stores neither
    err = outputs("[]", '["error_sp"]')
    assert err.needs_integration and err.approximations == ("sp",)
    assert err.variables == ("error_sp",)
    assert outputs("[]", '["n_steps"]').needs_integration
    assert not outputs('["sp", "large_gtilde"]').needs_integration
    every = outputs('"all"', '"all"')
    # "all": every method computing e its own way; "auto" (composite) is asked for by name
    assert every.methods == tuple(m for m in config.METHODS if m != "auto")
    assert every.fields == config.INTEGRATOR_FIELDS + tuple(
        f"error_{m}" for m in config.APPROXIMATIONS)
    # order in the file does not matter
    assert outputs('["ord1", "numeric"]').methods == ("numeric", "ord1")


def test_methods_match_the_api():
    from sweep import api

    assert config.METHODS == tuple(api.METHODS)


def test_hash_ignores_formatting_but_not_values():
    a = config.loads(GRID)
    b = config.loads("# a comment\n" + GRID.replace("num = 5", "num   =   5"))
    c = config.loads(GRID.replace("num = 5", "num = 6"))
    assert a.sha256 == b.sha256 != c.sha256


def test_integrator_options_and_run_tables():
    cfg = config.loads(GRID.replace('e = ["numeric", "ord1"]',
                                    'e = ["numeric", "ord1", "ord2_approx"]') + """
[integrator]
steps = 16
rest_tol = 1e-9
max_steps = 5000
[options.ord2_approx]
n = 11
[run]
chunk_size = 100
""")
    assert cfg.integrator.kwargs() == {"steps": 16, "rest_tol": 1e-9, "max_steps": 5000}
    assert cfg.method_options("ord2_approx") == {"n": 11}
    assert cfg.method_options("ord1") == {}
    assert cfg.chunk_size == 100
    assert cfg.compress == registry.DEFAULT_COMPRESSION == "fast"
    for given, choice in [("false", "none"), ("true", "small"), ('"small"', "small"),
                          ('"none"', "none"), ('"fast"', "fast")]:
        assert config.loads(GRID + f"[run]\ncompress = {given}").compress == choice


def _err(text):
    with pytest.raises(ConfigError) as info:
        config.loads(text, source="x.toml")
    return str(info.value)


@pytest.mark.parametrize("old, new, expected", [
    ('title = "t"', 'title = "t"\ncolour = 1', ["colour", "unknown key"]),
    ("alpha = 1.5", "alpha = 1.5\ngamme = 1", ["design.gamme", "did you mean 'gamma'"]),
    ("num = 5", 'num = "five"', ["design.gamma.num", "integer", "'five'"]),
    ("num = 5", "num = 5.0", ["design.gamma.num", "5.0"]),
    ("num = 5", "num = true", ["design.gamma.num", "True"]),
    ("num = 5", "num = 0", ["design.gamma.num", "empty range", "0"]),
    # One point of a range took its start and dropped its stop, silently.
    ("num = 5", "num = 1", ["design.gamma.num", "must be > 1 for a range", "got 1"]),
    ("alpha = 1.5", "alpha = 0.9", ["design.alpha", ">= 1", "0.9"]),
    ("beta = [1.0, 1.5]", "beta = [1.0, 0.5]", ["design.beta", ">= 1", "0.5"]),
    ("beta = [1.0, 1.5]", "beta = []", ["design.beta", "empty"]),
    ("beta = [1.0, 1.5]", "beta = [1.5, 1.5]", ["design.beta", "repeat"]),
    # Beyond double precision: math.isfinite raised OverflowError, naming no key.
    ("alpha = 1.5", "alpha = 1" + "0" * 400, ["design.alpha", "must be a number"]),
    ("beta = [1.0, 1.5]", 'beta = "kk"', ["design.beta", "'kk'"]),
    ("start = 0.0, stop = 0.1", "start = -0.1, stop = 0.1", ["design.gamma.start", ">= 0", "-0.1"]),
    ("start = 0.0, stop = 0.1", "start = 0.1, stop = 0.1", ["design.gamma.stop", "> start"]),
    # Closer than a double's spacing: 5 coordinates of 2 values, run with rc 0 (a CF axis
    # must increase strictly; .sel gave several points).
    ("start = 0.0, stop = 0.1", "start = 1.0, stop = 1.0000000000000002",
     ["design.gamma.num", "5 distinct values", "they give 2"]),
    ("start = 1e-3", "start = 9.999999999999998",
     ["design.gtilde.num", "distinct values", "they give"]),
    ("start = 1e-3", "start = 0.0", ["design.gtilde.start", "log", "0.0"]),
    ('spacing = "log"', 'spacing = "cubic"', ["design.gtilde.spacing", "'cubic'"]),
    ('kind = "grid"', 'kind = "lattice"', ["design.kind", "grid, doe, scene", "'lattice'"]),
    ('e = ["numeric", "ord1"]', 'e = ["numeric", "ord3"]', ["outputs.e", "'ord3'"]),
    ('e = ["numeric", "ord1"]', 'e = "numeric"', ["outputs.e", "'numeric'"]),
    ('"status", "error_ord1"', '"status", "u_min"', ["outputs.fields", "'u_min'"]),
    ('"status", "error_ord1"', '"error_numeric"', ["outputs.fields", "error_numeric"]),
    ('"status", "error_ord1"', '"error_ord3"', ["outputs.fields", "error_ord3"]),
    ('e = ["numeric", "ord1"]\nfields = ["status", "error_ord1"]', "e = []",
     ["nothing to compute"]),
    ("[outputs]", "[outputz]", ["outputz"]),
    ('title = "t"', "title = 3", ["title", "string", "3"]),
    ('title = "t"', "title = [", ["not valid TOML"]),
])
def test_grid_errors_name_key_and_value(old, new, expected):
    assert old in GRID
    msg = _err(GRID.replace(old, new, 1))
    assert msg.startswith("x.toml: ")
    for part in expected:
        assert part in msg, (part, msg)


@pytest.mark.parametrize("old, new, expected", [
    ("alpha = {min = 1.0, max = 3.0}", "alpha = {min = 0.5, max = 3.0}",
     ["design.alpha.min", ">= 1", "0.5"]),
    ("beta = 1.5", "beta = 0.99", ["design.beta", ">= 1", "0.99"]),
    ("alpha = {min = 1.0, max = 3.0}", "alpha = {min = 2.0, max = 2.0}",
     ["design.alpha.max", "empty range", "2.0"]),
    ("alpha = {min = 1.0, max = 3.0}", "alpha = {min = 1.0, max = 3.0, scal = 1}",
     ["design.alpha.scal", "did you mean 'scale'"]),
    ("alpha = {min = 1.0, max = 3.0}", "alpha = [1.0, 3.0]", ["design.alpha", "[1.0, 3.0]"]),
    ("gtilde = {min = 0.0, max = 10.0}", 'gtilde = {min = 0.0, max = 10.0, scale = "log"}',
     ["design.gtilde.min", "> 0", "log"]),
    ("n = 1000", "n = 0", ["design.n", "empty", "0"]),
    ("n = 1000", "n = 2000000000", ["design.n", "2**30"]),
    # The preflight's sizes overflowed a float before they refused it.
    ('sampler = "sobol"\nn = 1000', 'sampler = "random"\nn = 1' + "0" * 400,
     ["design.n", "2**63 - 1"]),
    ('sampler = "sobol"', 'sampler = "halton"', ["design.sampler", "'halton'"]),
    ("seed = 7", "seed = -1", ["design.seed", "-1"]),
    ("seed = 7", "seed = 7\nscramble = 1", ["design.scramble", "true or false"]),
    # Accepted before, and every seed gave the same design.
    ("seed = 7", "seed = 7\nscramble = false", ["design.seed", "scramble = false", "7"]),
])
def test_doe_errors_name_key_and_value(old, new, expected):
    assert old in DOE
    msg = _err(DOE.replace(old, new, 1))
    for part in expected:
        assert part in msg, (part, msg)


def test_doe_needs_a_sampled_axis_and_lhs_size_limit():
    fixed = (DOE.replace("alpha = {min = 1.0, max = 3.0}", "alpha = 2.0")
             .replace('gamma = {min = 1e-4, max = 1.0, scale = "log"}', "gamma = 0.1")
             .replace("gtilde = {min = 0.0, max = 10.0}", "gtilde = 1.0"))
    assert "at least one sampled parameter" in _err(fixed)
    assert "Latin hypercube" in _err(DOE.replace('"sobol"', '"lhs"').replace(
        "n = 1000", "n = 100000000"))


@pytest.mark.parametrize("extra, expected", [
    ("[integrator]\nsteps = 1", ["integrator.steps", "[8, 2**30]", "1"]),
    ("[integrator]\nsteps = 7.5", ["integrator.steps", "e_err is calibrated from 8 up", "7.5"]),
    # QA: accepted, every point ended BUDGET_EXHAUSTED with e = 1 and the run exited 0
    ("[integrator]\nsteps = 1e300", ["integrator.steps", "[8, 2**30]", "1e+300"]),
    ("[integrator]\nsteps = 9223372036854775807",
     ["integrator.steps", "[8, 2**30]", "9223372036854775807"]),
    ("[integrator]\nrest_tol = 0.0", ["integrator.rest_tol", "(0, 1)"]),
    ("[integrator]\nsteps = 1" + "0" * 400, ["integrator.steps", "[8, 2**30]"]),
    ("[integrator]\nrest_tol = 1e300", ["integrator.rest_tol", "(0, 1)", "1e+300"]),
    ("[integrator]\nmax_steps = 10.5", ["integrator.max_steps", "10.5"]),
    ("[integrator]\nmax_step = 10", ["integrator.max_step", "did you mean 'max_steps'"]),
    ("[options.ord2_approx]\nn = 20", ["options.ord2_approx.n", "odd", "20"]),
    ("[options.ord2_approx]\nm = 21", ["options.ord2_approx.m", "unknown option"]),
    ("[options.ord9]\nn = 21", ["options.ord9", "unknown method"]),
    ("[options.ord2_approx]\nn = 21", ["options.ord2_approx", "does not compute", "ord1"]),
    ("[run]\nchunk_size = 0", ["run.chunk_size", "from 1 to", "0"]),
    ("[run]\nchunk_size = 9223372036854775808", ["run.chunk_size", "9223372036854775808"]),
    ("[run]\ncompress = 1", ["run.compress", '"fast", "small", "none"', "1"]),
    ('[run]\ncompress = "zip"', ["run.compress", '(or true: "small", false: "none")', "zip"]),
    ("[run]\ncompres = false", ["run.compres", "did you mean 'compress'"]),
])
def test_other_table_errors(extra, expected):
    msg = _err(GRID + extra)
    for part in expected:
        assert part in msg, (part, msg)


def test_load_reports_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        config.load(tmp_path / "nope.toml")


def test_load_reads_a_file_with_a_utf8_byte_order_mark(tmp_path):
    # Audit F8: a BOM (Notepad writes one) gave "not valid TOML: Invalid statement (at
    # line 1, column 1)", no hint why. The file is the configuration without it.
    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_text(GRID, encoding="utf-8")
    marked.write_text(GRID, encoding="utf-8-sig")
    assert marked.read_bytes().startswith(b"\xef\xbb\xbf")
    assert config.load(marked).sha256 == config.load(plain).sha256
    assert config.load(marked).text == GRID


def test_bundled_configs_are_valid_and_sized_as_documented():
    paths = sorted(CONFIGS.glob("*.toml"))
    names = {p.stem: config.load(p) for p in paths}
    assert "default" in names
    default = names["default"]
    assert default.outputs.methods == tuple(m for m in config.METHODS if m != "auto")
    assert set(default.outputs.error_methods) == set(config.APPROXIMATIONS)
    assert default.design.shape[:2] == (1, 1)        # Kuwabara-Kono: alpha = beta = 3/2
    assert default.design.axes[0] == default.design.axes[1] == (1.5,)
    sobol = names["sobol_1m"]
    assert (sobol.design.sampler, sobol.design.n) == ("sobol", 1_000_000)
    assert [(b.lo, b.hi, b.scale) for b in sobol.design.bounds] == [
        (1.0, 3.0, "linear"), (1.0, 3.0, "linear"), (1e-4, 1.0, "log"), (0.0, 10.0, "linear")]
    models = {"hertz": (1.5, 1.0), "tti": (1.5, 1.25), "kk": (1.5, 1.5), "shc": (1.5, 2.5)}
    for model, (a, b) in models.items():
        cfg = names[f"report_{model}"]
        assert cfg.design.axes[:2] == ((a,), (b,))
        assert cfg.design.axes[2] == tuple(np.linspace(0.0, 0.1, 1000))
        assert cfg.design.axes[3] == (0.0, 0.05, 1.0, 10.0)


# --------------------------------------------------------------------------- typos first

@pytest.mark.parametrize("old, new, message", [
    ('sampler = "sobol"', 'samplr = "sobol"',
     "design.samplr: unknown key (did you mean 'sampler'?); allowed keys here: alpha, beta, "
     "gamma, gtilde, kind, n, sampler, scramble, seed"),
    ("gamma = {min = 1e-4, max = 1.0", "gamma = {mn = 1e-4, max = 1.0",
     "design.gamma.mn: unknown key (did you mean 'min'?)"),
    ('kind = "doe"', 'knd = "doe"', "design.knd: unknown key (did you mean 'kind'?)"),
    ("gtilde = {min", "gtlde = {min", "design.gtlde: unknown key (did you mean 'gtilde'?)"),
    ("[outputs]", "[output]", "output: unknown key (did you mean 'outputs'?)"),
])
def test_an_unknown_key_is_reported_before_the_key_it_misspells(old, new, message):
    with pytest.raises(ConfigError) as info:
        config.loads(DOE.replace(old, new))
    assert str(info.value).startswith(message)
    assert "required" not in str(info.value)


def test_unknown_keys_first_in_grids_and_scenes():
    with pytest.raises(ConfigError, match=r"^design.gamma.nm: unknown key \(did you mean 'num'"):
        config.loads(GRID.replace("num = 5", "nm = 5"))
    scene = """
[design]
kind = "scene"
v0 = 1.0
F = 0.0
[design.materials.glass]
law = "kk"
radius = 1e-3
desnity = 2500.0
E = 63e9
nu = 0.22
damping = {model = "target_e", e = 0.97, v0 = 1.0}
[outputs]
e = ["numeric"]
"""
    with pytest.raises(ConfigError, match=r"^design.materials.glass.desnity: unknown key "
                                          r"\(did you mean 'density'\?\)"):
        config.loads(scene)
    with pytest.raises(ConfigError, match=r"damping.modle: unknown key \(did you mean 'model'"):
        config.loads(scene.replace("desnity", "density").replace("{model", "{modle"))
    # a parameter of another damping model is declared, but refused for this one
    with pytest.raises(ConfigError, match=r"damping.eta1: unknown key; allowed keys here: e, "
                                          r"model, v0"):
        config.loads(scene.replace("desnity", "density").replace("v0 = 1.0}",
                                                                 "v0 = 1.0, eta1 = 2.0}"))


# --------------------------------------------------------------------------- method domains

def test_sp_off_its_domain_is_refused_naming_method_and_exponents():
    sp = 'e = ["numeric", "sp"]\nfields = ["status"]'
    with pytest.raises(ConfigError, match=r"^outputs.e: method 'sp' is defined for \(alpha, "
                                          r"beta\) = \(1.5, 1.5\) only, and the design has "
                                          r"\(alpha, beta\) = \(1.5, 1\); leave sp out"):
        config.loads(GRID.replace('e = ["numeric", "ord1"]\nfields = ["status", "error_ord1"]',
                                  sp))
    with pytest.raises(ConfigError, match="samples alpha or beta over a range"):
        config.loads(DOE.replace('e = ["ord1"]', 'e = ["sp"]'))
    with pytest.raises(ConfigError, match=r"^outputs.fields: method 'sp' .* leave error_sp out"):
        config.loads(DOE.replace("alpha = {min = 1.0, max = 3.0}", "alpha = 2.0")
                     .replace('e = ["ord1"]', 'fields = ["error_sp"]'))
    # on its domain it is accepted
    kk = DOE.replace("alpha = {min = 1.0, max = 3.0}", "alpha = 1.5")
    assert config.loads(kk.replace('e = ["ord1"]', 'e = ["sp"]')).outputs.methods == ("sp",)
    assert config.loads(GRID.replace("beta = [1.0, 1.5]", "beta = 1.5").replace(
        'e = ["numeric", "ord1"]\nfields = ["status", "error_ord1"]', sp)).outputs.methods == (
        "numeric", "sp")


def test_all_means_every_method_defined_on_the_design():
    every = config.loads(GRID.replace('e = ["numeric", "ord1"]\nfields = ["status", '
                                      '"error_ord1"]', 'e = "all"\nfields = "all"')).outputs
    assert "sp" not in every.methods and "error_sp" not in every.fields
    assert every.methods == tuple(m for m in config.METHODS if m not in ("auto", "sp"))


def test_scene_domains_are_the_materials_laws():
    scene = """
[design]
kind = "scene"
v0 = 1.0
F = 0.0
[design.materials.a]
law = "kk"
m = 0.1
k = 1e9
gamma0 = 1e-6
[outputs]
e = ["sp"]
"""
    assert config.loads(scene).outputs.methods == ("sp",)
    with pytest.raises(ConfigError, match=r"design has \(alpha, beta\) = \(1.5, 1.25\)"):
        config.loads(scene + '[design.materials.b]\nlaw = "tti"\nm = 0.1\nk = 1e9\n'
                             'gamma0 = 1e-6\n')


# --------------------------------------------------------------------------- dicts

def test_dict_configurations_are_written_as_toml_that_reads_back():
    from sweep.sweeps import toml_text

    data = {"title": 'quote " backslash \\ tab \t unicode é \x7f', "n": np.int32(3),
            "x": np.float64(1e-5), "flag": np.bool_(True), "list": (1, 2.5, "a"),
            "design": {"kind": "grid", "range": {"start": 0.0, "num": 3},
                       "materials": {"steel": {"law": "kk", "floor": {"E": 1e9}}},
                       "key with space": 1}}
    import tomllib

    back = tomllib.loads(toml_text.dumps(data))
    assert back == {**data, "n": 3, "x": 1e-5, "flag": True, "list": [1, 2.5, "a"]}
    with pytest.raises(toml_text.TomlValueError, match=r"design.alpha: TOML has no value"):
        toml_text.dumps({"design": {"alpha": None}})
    cfg = config.from_dict(tomllib.loads(GRID))
    assert cfg.sha256 == config.loads(GRID).sha256 and cfg.title == "t"
    assert config.as_config(GRID).sha256 == cfg.sha256


# --------------------------------------------------------------------------- scene materials

GLASS = """
[design]
kind = "scene"
v0 = 1.0
F = 0.0
[design.materials.glass]
law = "kk"
radius = 1e-3
density = 2500.0
E = 63e9
nu = 0.22
floor = {E = 63e9, nu = 0.22}
damping = {model = "target_e", e = 0.97, v0 = 1.0}
[outputs]
e = ["numeric"]
"""


@pytest.mark.parametrize("floor, message", [
    ("floor = {E = 63e9}", "floor.nu: is required with floor.E"),
    ("floor = {nu = 0.22}", "floor.E: is required with floor.nu"),
])
def test_floor_needs_both_e_and_nu(floor, message):
    # One key alone used to default the other (nu = 0, or a rigid floor) silently.
    with pytest.raises(ConfigError, match=r"^g.toml: design.materials.glass." + message):
        config.loads(GLASS.replace("floor = {E = 63e9, nu = 0.22}", floor), source="g.toml")


def test_floor_omitted_is_rigid_and_given_whole_is_read():
    rigid = config.loads(GLASS.replace("floor = {E = 63e9, nu = 0.22}\n", ""))
    assert rigid.design.materials[0].floor_E == math.inf
    glass = config.loads(GLASS).design.materials[0]
    assert (glass.floor_E, glass.floor_nu) == (63e9, 0.22)


DIRECT = ("radius = 1e-3\ndensity = 2500.0\nE = 63e9\nnu = 0.22\nfloor = {E = 63e9, nu = 0.22}\n"
          'damping = {model = "target_e", e = 0.97, v0 = 1.0}\n')


@pytest.mark.parametrize("replacement, key, why", [
    # m, k, gamma0 given: E, nu and radius derive nothing
    ("m = 0.1\nk = 1e9\ngamma0 = 1e-6\nE = 63e9\n", "E", "k is given directly"),
    ("m = 0.1\nk = 1e9\ngamma0 = 1e-6\nnu = 0.22\n", "nu", "k is given directly"),
    ("m = 0.1\nk = 1e9\ngamma0 = 1e-6\nradius = 1e-3\n", "radius", "m and k are given"),
    # k given, m from radius and density: radius is used, E is not
    ("radius = 1e-3\ndensity = 2500.0\nk = 1e9\ngamma0 = 1e-6\nE = 63e9\n", "E",
     "k is given directly"),
])
def test_material_keys_that_derive_nothing_are_refused(replacement, key, why):
    with pytest.raises(ConfigError, match=rf"^design.materials.glass.{key}: is ignored: {why}"):
        config.loads(GLASS.replace(DIRECT, replacement))


def test_material_keys_used_by_some_formula_are_accepted():
    # m from radius and density, k from Hertz: every key is used
    assert config.loads(GLASS).design.materials[0].k is None
    # k given, but the Kuwabara-Kono damping needs the bead's E and nu
    kk = config.loads(GLASS.replace(DIRECT, "m = 0.1\nk = 1e9\nE = 63e9\nnu = 0.22\ndamping = "
                                            "{model = \"kuwabara_kono\", eta1 = 1.0, "
                                            "eta2 = 2.0}\n"))
    assert kk.design.materials[0].E == 63e9
    # m given, k from Hertz (radius, E, nu): radius is used
    assert config.loads(GLASS.replace("density = 2500.0", "m = 0.1")).design.materials[0].m \
        == 0.1


def test_kuwabara_kono_domain_errors_name_the_file():
    kk = GLASS.replace('damping = {model = "target_e", e = 0.97, v0 = 1.0}',
                       'damping = {model = "kuwabara_kono", eta1 = 0.0, eta2 = 0.0}')
    with pytest.raises(ConfigError, match=r"^g.toml: design.materials.glass.damping.eta2: "
                                          r"eta1 \+ eta2 must be > 0"):
        config.loads(kk, source="g.toml")
    with pytest.raises(ConfigError, match=r"^g.toml: design.materials.glass.nu: must be != 0"):
        config.loads(kk.replace("nu = 0.22\nfloor", "nu = 0.0\nfloor"), source="g.toml")


@pytest.mark.parametrize("e", ['"all"', '["ord1"]', '["sp"]'])
def test_many_exponent_pairs_are_judged_without_listing_them(e):
    # The domain check listed every (alpha, beta) pair of a grid: 5,000 x 5,000 took 3.7 GB
    # and 17 s before the design's size was judged (10^5 x 10^5: killed for memory).
    import tracemalloc

    text = ('[design]\nkind = "grid"\nalpha = {start = 1.0, stop = 3.0, num = 3000}\n'
            'beta = {start = 1.0, stop = 3.0, num = 3000}\ngamma = 0.1\ngtilde = 1.0\n'
            f'[outputs]\ne = {e}\n')
    tracemalloc.start()
    try:
        if e == '["sp"]':   # defined at (1.5, 1.5) only: the first other pair is named
            with pytest.raises(ConfigError, match=r"\(alpha, beta\) = \(1, 1\)"):
                config.loads(text)
        else:
            cfg = config.loads(text)
            assert "sp" not in cfg.outputs.methods
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6, peak        # the axes: 2 x 3,000 values; 9,000,000 pairs are not


def _layout_variants():
    """The annotated layout of sweep.sweeps.config's docstring, one text per [design]."""
    doc = config.__doc__
    block = doc[doc.index("Layout of a configuration file"):doc.index("Methods, their options")]
    text = textwrap.dedent(block.split("::", 1)[1])
    head, *designs = re.split(r"^(?=\[design\])", text, flags=re.M)
    *designs, last = designs
    last_design, rest = last.split("\n[outputs]", 1)
    return [head + d + "\n[outputs]" + rest for d in [*designs, last_design]]


@pytest.mark.parametrize("kind", ["grid", "doe", "scene"])
def test_the_annotated_layout_parses_as_written(kind):
    texts = {config.loads(t).design.kind: t for t in _layout_variants()}
    cfg = config.loads(texts[kind])
    assert cfg.compress == "fast" and cfg.chunk_size == 131072
    assert {"numeric", "ord1", "ord2_approx", "auto"} <= set(cfg.outputs.methods)


def test_a_compression_and_its_alias_are_one_configuration():
    # A resume compares the hash: compress = true must resume a run of compress = "small".
    same = [config.loads(GRID + f"[run]\ncompress = {v}").sha256 for v in ("true", '"small"')]
    other = config.loads(GRID + '[run]\ncompress = "none"').sha256
    assert same[0] == same[1] != other
