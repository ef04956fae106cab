"""Scenes: physical situations in (materials, v0, F, g), scaled points and datasets out.

sweep.sweeps.config (design.kind = "scene"), sweep.sweeps.design.SceneDesign,
sweep.materials, and the scene dataset written by the runner.
"""
import math

import numpy as np
import pytest
import xarray as xr

import sweep
from sweep import materials
from sweep.sweeps import config, design, runner

STEEL = dict(m=0.154, k=3.6138e10, gamma0=1.5237e-6)   # the report's steel ball (KK)

SCENE = """
title = "scene test"
[design]
kind = "scene"
g = 9.81
v0 = {start = 0.1, stop = 5.0, num = 7, spacing = "log"}
F = [0.0, 1.0]
[design.materials.steel]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[design.materials.steel_x2]       # m and k doubled: same (gamma, g~) where F = 0
alpha = 1.5
beta = 1.5
m = 0.308
k = 7.2276e10
gamma0 = 1.5237e-6
[outputs]
e = ["numeric", "ord1"]
fields = ["status"]
[integrator]
steps = 48
"""

PROPERTIES = """
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


def test_scaling_of_the_steel_ball_by_hand():
    # Eq. (2) with alpha = beta = 3/2: gamma = gamma0 v0^(1/5) (k/m)^(2/5),
    # g~ = (m/k)^(2/5) v0^(-6/5) (g + F/m). Hand arithmetic, not sweep.scale.
    m, k, gamma0, v0, g, F = 0.154, 3.6138e10, 1.5237e-6, 2.79, 9.8, 0.5
    k_over_m = 3.6138e10 / 0.154                                     # 2.34662e11 s^-2 m^-1/2
    gamma = gamma0 * v0 ** 0.2 * math.exp(0.4 * math.log(k_over_m))
    gtilde = math.exp(-0.4 * math.log(k_over_m)) * v0 ** -1.2 * (g + F / m)
    assert gamma == pytest.approx(0.066099, rel=1e-4)              # report: e = 0.893 here
    got = sweep.scale(m, k, gamma0, v0, 1.5, 1.5, g=g, F=F)
    assert got == pytest.approx((gamma, gtilde), rel=1e-14)
    d = design.build(config.loads(SCENE).design)
    alpha, beta, gam, gt = d.points(0, d.size)
    v = d.axes["v0"][np.arange(d.size) // 2 % 7]
    Fs = d.axes["F"][np.arange(d.size) % 2]
    steel = np.arange(d.size) < 14
    hand = gamma0 * v[steel] ** 0.2 * k_over_m ** 0.4
    np.testing.assert_allclose(gam[steel], hand, rtol=1e-13)
    np.testing.assert_allclose(gt[steel], k_over_m ** -0.4 * v[steel] ** -1.2
                               * (9.81 + Fs[steel] / m), rtol=1e-13)


def test_points_with_the_same_scaled_numbers_have_the_same_e():
    # Doubling v0 is undone by gamma0 / 2^(1/5) and g x 2^(6/5): eq. (2) gives the same
    # (gamma, g~), so the same e, though every physical value differs.
    a = sweep.scale(**STEEL, v0=1.3, alpha=1.5, beta=1.5, g=9.81, F=0.0)
    b = sweep.scale(STEEL["m"], STEEL["k"], STEEL["gamma0"] * 2 ** -0.2, 2.6, 1.5, 1.5,
                    g=9.81 * 2 ** 1.2, F=0.0)
    assert b == pytest.approx(a, rel=1e-14)
    assert sweep.cor(1.5, 1.5, *b) == pytest.approx(sweep.cor(1.5, 1.5, *a), abs=1e-12)


def test_scene_dataset_dims_units_and_invariance(tmp_path):
    out = tmp_path / "scene.nc"
    runner.run(config.loads(SCENE, source="scene.toml"), out, quiet=True, chunk_size=5)
    with xr.open_dataset(out) as ds:
        ds = ds.load()
    assert ds.e_numeric.dims == ("material", "v0", "F")
    assert list(ds.material_name.values) == ["steel", "steel_x2"]
    assert list(ds.material.values) == [0, 1]          # an index: CF coordinates are numbers
    steel = ds.set_xindex("material_name").sel(material_name="steel_x2")
    assert float(steel.m) == 0.308
    assert ds.v0.attrs["units"] == "m s-1" and ds.v0.attrs["spacing"] == "log"
    assert ds.F.attrs["units"] == "N" and ds.g.attrs["units"] == "m s-2"
    for name in ("gamma", "gtilde"):
        assert name in ds.data_vars and ds[name].dims == ("material", "v0", "F")
        assert ds[name].attrs["units"] == "1"
    assert ds.m.dims == ("material",) and ds.m.attrs["units"] == "kg"
    np.testing.assert_array_equal(ds.m.values, [0.154, 0.308])
    np.testing.assert_allclose(ds.gamma.values[0], ds.gamma.values[1], rtol=1e-14)
    # F = 0: both materials have the same (gamma, g~), hence the same e.
    np.testing.assert_allclose(ds.e_numeric.values[0, :, 0], ds.e_numeric.values[1, :, 0],
                               atol=1e-12)
    # The stored e is sweep.cor at the stored scaled point.
    want = sweep.cor(1.5, 1.5, ds.gamma.values, ds.gtilde.values, steps=48)
    np.testing.assert_array_equal(ds.e_numeric.values, want)
    assert "scene design: 2 materials" in ds.attrs["design"]


@pytest.mark.parametrize("old, new, message", [
    ("m = 0.154", "m = -0.154", "design.materials.steel.m: must be > 0 [kg], got -0.154"),
    ("gamma0 = 1.5237e-6\n[design.materials.steel_x2]", "gamma0 = -1.0\n"
     "[design.materials.steel_x2]", "design.materials.steel.gamma0: must be >= 0"),
    ("start = 0.1", "start = -0.1", "design.v0.start: must be > 0 [m/s], got -0.1"),
    ('law = "kk"', 'law = "kuwabara"', "design.materials.steel.law: must be"),
    ("m = 0.154\n", "", "design.materials.steel.m: is required, or derive it from radius"),
    ("g = 9.81", 'g = "earth"', "design.g: must be a finite number"),
])
def test_scene_errors_name_the_bad_value(old, new, message):
    with pytest.raises(config.ConfigError, match=message.replace("(", r"\(")
                       .replace(")", r"\)").replace("[", r"\[").replace("]", r"\]")):
        config.loads(SCENE.replace(old, new, 1))


def test_a_damping_model_of_another_law_is_named_once():
    bad = PROPERTIES.replace('{model = "target_e", e = 0.97, v0 = 1.0}',
                             '{model = "tsuji", e = 0.97}')
    with pytest.raises(config.ConfigError) as info:
        config.loads(bad)
    assert str(info.value) == ("design.materials.glass.damping.model: applies to the law "
                               "(alpha, beta) = (1.5, 1.25) only, not the material's "
                               "(1.5, 1.5), got 'tsuji'")


def test_a_pulling_load_beyond_gravity_is_named():
    cfg = config.loads(SCENE.replace("F = [0.0, 1.0]", "F = [-2.0, 1.0]"))
    with pytest.raises(config.ConfigError, match=r"steel: g \+ F/m must be >= 0.*-3\.17"):
        design.build(cfg.design)


def test_material_properties_hertz_and_target_damping():
    d = design.build(config.loads(PROPERTIES).design)
    (mat,) = d.materials
    assert mat.m == pytest.approx(4 / 3 * math.pi * 1e-9 * 2500.0, rel=1e-15)
    e_star = 1.0 / (2 * (1 - 0.22 ** 2) / 63e9)       # two glass bodies
    assert mat.k == pytest.approx(4 / 3 * e_star * math.sqrt(1e-3), rel=1e-15)
    gamma, gtilde = sweep.scale(mat.m, mat.k, mat.gamma0, 1.0, 1.5, 1.5)
    assert sweep.cor(1.5, 1.5, gamma, gtilde) == pytest.approx(0.97, abs=1e-12)
    assert "Hertz" in mat.origin and "e = 0.97" in mat.origin
    bad = PROPERTIES.replace("nu = 0.22\nfloor", "nu = 0.6\nfloor")
    with pytest.raises(config.ConfigError, match=r"glass.nu: must be in \(-1, 0.5\], got 0.6"):
        config.loads(bad)


def test_only_plus_inf_is_a_rigid_floor():
    # 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2, the floor's term 0 for E2 = +inf only.
    glass = 63e9 / (1 - 0.22 ** 2)
    assert materials.effective_modulus(63e9, 0.22) == pytest.approx(glass, rel=1e-15)
    assert materials.hertz_stiffness(1e-3, 63e9, 0.22, math.inf) == pytest.approx(
        4 / 3 * glass * math.sqrt(1e-3), rel=1e-15)
    for bad in (math.nan, -math.inf, -1.0, 0.0):
        for f, args in ((materials.effective_modulus, (63e9, 0.22)),
                        (materials.hertz_stiffness, (1e-3, 63e9, 0.22))):
            with pytest.raises(ValueError, match=f"E2 must be .*got {bad!r}"):
                f(*args, bad)
    with pytest.raises(ValueError, match="nu1 must be in .*got 0.7"):
        materials.effective_modulus(63e9, 0.7)


@pytest.mark.parametrize("call, named", [
    (lambda: materials.sphere_mass([1e-3, 2e-3], 2500.0), "radius"),
    (lambda: materials.effective_modulus([63e9, 1e9], 0.22), "E1"),
    (lambda: materials.kuwabara_kono_gamma0([1.0], 1.0, 63e9, 0.22), "eta1"),
    (lambda: materials.tsuji_gamma0(np.array([0.5, 0.9]), 1e-5, 1e8), "e"),
    (lambda: materials.gamma0_for_cor(0.9, [1.0, 2.0], 2.05e-3, 9.858e9, 1.5, 1.5), "v0"),
])
def test_material_formulas_name_a_list_or_array_they_cannot_take(call, named):
    # The formulas are scalar: a list met them as a TypeError ("unsupported operand type(s)
    # for ** or pow(): 'list' and 'int'") or numpy's "truth value ... is ambiguous".
    with pytest.raises(ValueError, match=f"^{named} must be a single number, got "):
        call()
    # A 0-d array is one number, and gives the formula's value.
    assert materials.sphere_mass(np.array(1e-3), 2500.0) == pytest.approx(
        4 / 3 * math.pi * 1e-9 * 2500.0, rel=1e-15)


def test_tsuji_gamma0_of_a_perfect_bounce_is_plus_zero():
    assert math.copysign(1.0, materials.tsuji_gamma0(1.0, 2.05e-3, 9.858e9)) == 1.0


def test_bead_8mm_damping_gives_e_09_at_1_m_per_s():
    gamma0 = materials.gamma0_for_cor(0.9, 1.0, 2.05e-3, 9.858e9, 1.5, 1.5, g=9.81)
    assert gamma0 == pytest.approx(5.19995e-7, rel=1e-5)    # the value docs/scenes.md gives
    gamma, gtilde = sweep.scale(2.05e-3, 9.858e9, gamma0, 1.0, 1.5, 1.5)
    assert sweep.cor(1.5, 1.5, gamma, gtilde, steps=256) == pytest.approx(0.9, abs=1e-10)


def test_tsuji_relation_is_exact_for_the_tti_law():
    # TTI at g~ = 0: e does not depend on v0, and the closed form gives it exactly.
    gamma0 = materials.tsuji_gamma0(0.8, 2.05e-3, 9.858e9)
    for v0 in (0.1, 3.0):
        gamma, _ = sweep.scale(2.05e-3, 9.858e9, gamma0, v0, 1.5, 1.25, g=0.0)
        assert sweep.cor(1.5, 1.25, gamma, 0.0, steps=256) == pytest.approx(0.8, abs=1e-10)


def test_kuwabara_kono_constant():
    # Brilliantov et al. (1996): A = (3 eta2 - eta1)^2 / (3 (3 eta2 + 2 eta1))
    # x (1 - nu^2)(1 - 2 nu) / (E nu^2); 0 when 3 eta2 = eta1.
    a = materials.kuwabara_kono_gamma0(1.0, 2.0, 1e9, 0.25)
    assert a == pytest.approx(25 / 24 * 0.9375 * 0.5 / (1e9 * 0.0625), rel=1e-15)
    assert materials.kuwabara_kono_gamma0(3.0, 1.0, 1e9, 0.25) == 0.0
    with pytest.raises(ValueError, match="E must be > 0"):
        materials.kuwabara_kono_gamma0(1.0, 2.0, -1.0, 0.25)


def test_bundled_scenes_are_valid():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "configs"
    for name in ("scene_steel_ball", "scene_bead_8mm", "scene_glass"):
        cfg = config.load(root / f"{name}.toml")
        assert cfg.design.kind == "scene"
        design.build(cfg.design)


@pytest.mark.parametrize("doc", ["README.md", "docs/scenes.md"])
def test_the_toml_examples_of_the_docs_are_valid(doc):
    # Every ```toml block is a whole configuration: read and built as `sweep validate` does
    # (the README's scene pulled a 2 mm glass bead with -1.5 N, g + F/m = -1.4e5 m/s^2).
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / doc).read_text(encoding="utf-8")
    blocks = re.findall(r"^```toml\n(.*?)^```", text, flags=re.S | re.M)
    assert len(blocks) == text.count("```toml")
    for block in blocks:
        design.build(config.loads(block, source=doc).design, doc)


def test_scene_with_auto_resumes_to_the_uninterrupted_result(tmp_path, monkeypatch):
    text = SCENE.replace('e = ["numeric", "ord1"]\nfields = ["status"]',
                         'e = ["numeric", "auto"]\nfields = ["method_used"]\n'
                         '[options.auto]\ntol = 1e-3')
    cfg = config.loads(text, source="scene.toml")
    runner.run(cfg, tmp_path / "ref.nc", quiet=True, chunk_size=4)
    real, calls = runner.compute_chunk, [0]

    def interrupted(*args):
        calls[0] += 1
        if calls[0] == 4:                   # the first call is the warm-up
            raise KeyboardInterrupt
        return real(*args)

    with monkeypatch.context() as m:
        m.setattr(runner, "compute_chunk", interrupted)
        with pytest.raises(KeyboardInterrupt):
            runner.run(cfg, tmp_path / "out.nc", quiet=True, chunk_size=4)
    res = runner.run(cfg, tmp_path / "out.nc", quiet=True, chunk_size=4)
    assert res.resumed_chunks == 2
    with xr.open_dataset(tmp_path / "ref.nc") as a, xr.open_dataset(tmp_path / "out.nc") as b:
        for name in ("gamma", "gtilde", "e_numeric", "e_auto", "method_used"):
            np.testing.assert_array_equal(a[name].values, b[name].values)
        assert np.all(np.abs(b.e_auto - b.e_numeric) <= 1e-3)
        assert b.method_used.attrs["flag_meanings"].split()[0] == "numeric"
        assert b.attrs["options_auto_tol"] == 1e-3 and b.attrs["options_auto_steps"] == 48


def _one_material(speeds, **material):
    props = "\n".join(f"{k} = {v!r}" for k, v in material.items())
    return (f'[design]\nkind = "scene"\nv0 = {speeds!r}\nF = [0.0, 1.0]\n'
            f'[design.materials.tiny]\nlaw = "kk"\n{props}\n[outputs]\ne = ["numeric"]\n'
            'fields = ["status"]\n')


def test_a_scene_whose_scaling_overflows_is_a_config_error(tmp_path):
    # g~ = (m/k)^(2/5) v0^(-6/5) (g + F/m) is 1e360 at v0 = 1e-300, the second speed: every
    # point would be INVALID (NaN). The error names the file, the material and the value.
    text = _one_material([1.0, 1e-300], m=0.154, k=3.6138e10, gamma0=1.5237e-6)
    cfg = config.loads(text, source="s.toml")
    with pytest.raises(config.ConfigError, match=r"^s.toml: design.materials.tiny: gtilde "
                                                 r"overflows to inf .*v0=1e-300"):
        design.build(cfg.design, cfg.source)
    with pytest.raises(config.ConfigError, match=r"^s.toml: design.materials.tiny: gtilde"):
        runner.run(cfg, tmp_path / "s.nc", quiet=True)
    assert list(tmp_path.iterdir()) == []


def test_a_scene_with_extreme_but_representable_scaling_runs():
    # m = 1e-300, k = 1e300: k/m overflows, but gamma = 1e-6 (1e600)^(2/5) = 1e234 and
    # g~ = (1e-600)^(2/5) (g + F/m) are doubles: every point is valid.
    d = design.build(config.loads(_one_material([1.0], m=1e-300, k=1e300, gamma0=1e-6))
                     .design)
    _, _, gamma, gtilde = d.points(0, d.size)
    np.testing.assert_allclose(gamma, [1e234, 1e234], rtol=1e-12)
    np.testing.assert_allclose(gtilde, [9.81e-240, 1e-240 * (9.81 + 1e300)], rtol=1e-12)


def test_errors_found_when_the_design_is_built_name_the_file(tmp_path):
    pulling = SCENE.replace("F = [0.0, 1.0]", "F = [-2.0, 1.0]")
    with pytest.raises(config.ConfigError, match=r"^scene.toml: design.materials.steel: "
                                                 r"g \+ F/m must be >= 0"):
        design.build(config.loads(pulling, source="scene.toml").design, "scene.toml")
    kk = PROPERTIES.replace('damping = {model = "target_e", e = 0.97, v0 = 1.0}',
                            'damping = {model = "kuwabara_kono", eta1 = 1.0, eta2 = 2.0}')
    with pytest.raises(config.ConfigError, match=r"^p.toml: design.materials.glass.nu: must "
                                                 r"be != 0 for the kuwabara_kono damping"):
        config.loads(kk.replace("nu = 0.22\nfloor", "nu = 0.0\nfloor"), source="p.toml")
    # Kuwabara-Kono's constant is for one material: a floor of another one is refused.
    other = kk.replace("floor = {E = 63e9, nu = 0.22}", "floor = {E = 1e6, nu = 0.45}")
    with pytest.raises(config.ConfigError, match=r"^p.toml: design.materials.glass.floor: "
                                                 r"the kuwabara_kono damping is for a floor "
                                                 r"of the bead's material"):
        config.loads(other, source="p.toml")
    rigid = kk.replace("floor = {E = 63e9, nu = 0.22}\n", "")
    for accepted in (kk, rigid):
        assert config.loads(accepted).design.materials[0].damping[0] == ("model",
                                                                         "kuwabara_kono")
    path = tmp_path / "pull.toml"
    path.write_text(pulling)
    with pytest.raises(config.ConfigError, match=f"^{path}: design.materials.steel: g"):
        runner.run(path, tmp_path / "out.nc", quiet=True)


# The grid's rule (tests/test_files.py, README): a list is "irregular", one value "single".
@pytest.mark.parametrize("axis, spacing", [
    ("1.5", "single"), ("[1.5]", "single"), ("{start = 1.5, stop = 1.5, num = 1}", "single"),
    ("[2.0, 0.5, 1.0, 0.3]", "irregular"), ("[0.5, 1.0, 1.5]", "irregular"),
    ("{values = [0.5, 1.0]}", "irregular"),
    ("{start = 0.5, stop = 2.0, num = 3}", "linear"),
    ("{start = 0.5, stop = 2.0, num = 3, spacing = \"log\"}", "log"),
])
@pytest.mark.parametrize("name", ["v0", "F"])
def test_scene_axes_are_spaced_as_grid_axes(name, axis, spacing):
    other = "F = 0.0" if name == "v0" else "v0 = 1.0"
    text = PROPERTIES.replace("v0 = 1.0\nF = 0.0", f"{name} = {axis}\n{other}")
    assert dict(config.loads(text).design.spacing)[name] == spacing


def test_an_unsorted_scene_list_is_written_sorted_and_irregular(tmp_path):
    # QA2 3: this file said spacing = "linear" for [2.0, 0.5, 1.0, 0.3]; audit D: stored
    # in that order, a coordinate that xarray could not slice and CF checkers refused.
    text = SCENE.replace('v0 = {start = 0.1, stop = 5.0, num = 7, spacing = "log"}',
                         "v0 = [2.0, 0.5, 1.0, 0.3]").replace("F = [0.0, 1.0]",
                                                                "F = [10.0, 0.0, 5.0]")
    out = tmp_path / "uns.nc"
    runner.run(config.loads(text, source="uns.toml"), out, quiet=True)
    with xr.open_dataset(out) as ds:
        assert list(ds.v0.values) == [0.3, 0.5, 1.0, 2.0]
        assert list(ds.F.values) == [0.0, 5.0, 10.0]
        assert ds.v0.attrs["spacing"] == "irregular" and ds.F.attrs["spacing"] == "irregular"


def test_hertz_stiffness_needs_the_registrys_hertz_alpha(monkeypatch):
    # The exponent Hertz's k (radius, E, nu) needs is the registry's Hertz law, read when the
    # file is parsed (it was a literal 1.5 here and in materials).
    from sweep import registry

    cubic = PROPERTIES.replace('law = "kk"', 'alpha = 2.0\nbeta = 1.0').replace(
        'damping = {model = "target_e", e = 0.97, v0 = 1.0}', "gamma0 = 1e-6")
    with pytest.raises(config.ConfigError, match=r"glass.E: .*needs alpha = 1.5, got 2"):
        config.loads(cubic)
    monkeypatch.setitem(registry.MODELS, "hertz", (2.0, 1.0))
    assert config.loads(cubic).design.materials[0].alpha == 2.0
    with pytest.raises(config.ConfigError, match=r"glass.E: .*needs alpha = 2, got 1.5"):
        config.loads(PROPERTIES)


@pytest.mark.parametrize("e, v0, alpha, beta", [
    (1e-8, 1.0, 1.5, 1.0),      # Hertz: e falls from ~1e-9 straight to 0 within rounding
    (1e-12, 1.0, 1.5, 1.5),
    (1e-30, 1.0, 1.5, 1.5),
])
def test_gamma0_for_cor_refuses_an_e_that_no_damping_gives(e, v0, alpha, beta):
    # Brent's method ends at the stick threshold, where e jumps to 0: that gamma0 gave e = 0
    # (STUCK) without a word.
    with pytest.raises(ValueError, match=f"^no damping gives e = {e!r} at v0 = {v0!r} m/s"):
        materials.gamma0_for_cor(e, v0, 2.05e-3, 9.858e9, alpha, beta)


@pytest.mark.parametrize("e", [0.5, 1e-3, 1e-6])
def test_gamma0_for_cor_gives_small_e_it_can_reach(e):
    gamma0 = materials.gamma0_for_cor(e, 1.0, 2.05e-3, 9.858e9, 1.5, 1.5)
    gamma, gtilde = sweep.scale(2.05e-3, 9.858e9, gamma0, 1.0, 1.5, 1.5)
    assert sweep.cor(1.5, 1.5, gamma, gtilde) == pytest.approx(e, rel=materials.REACHED)


UNDAMPED = """
[design]
kind = "scene"
g = 0.0
v0 = {start = 1e-3, stop = 10.0, num = 5, spacing = "log"}
F = 0.0
[design.materials.spring]
law = "linear"
m = 0.2
k = 5e4
gamma0 = 0.0
[design.materials.steel]
law = "hertz"
m = 0.154
k = 3.6138e10
gamma0 = 0.0
[outputs]
e = ["numeric"]
fields = ["t_f", "u_max"]
[integrator]
tol = 1e-10
"""


def test_a_scene_gives_contact_time_and_compression_in_si_units(tmp_path):
    # Undamped, unloaded: the contact of F = k x^alpha lasts 2 x_m / v0 B(1/(a+1), 1/2) /
    # (a+1), x_m = ((a+1) m v0^2 / (2 k))^(1/(a+1)) (energy conservation), pi sqrt(m/k) for
    # the linear spring: independent of the scaling (2) the dataset's units come from.
    from scipy.special import beta as beta_function

    path = tmp_path / "undamped.nc"
    runner.run(config.loads(UNDAMPED, source="undamped.toml"), path, quiet=True)
    with xr.open_dataset(path) as ds:
        assert ds.time_scale.dims == ds.length_scale.dims == ("material", "v0")
        assert (ds.time_scale.units, ds.length_scale.units) == ("s", "m")
        seconds = (ds.t_f * ds.time_scale).isel(F=0).values
        metres = (ds.u_max * ds.length_scale).isel(F=0).values
        v0 = ds.v0.values
    for row, (m, k, a) in enumerate([(0.2, 5e4, 1.0), (0.154, 3.6138e10, 1.5)]):
        x_m = ((a + 1.0) * m * v0 ** 2 / (2.0 * k)) ** (1.0 / (a + 1.0))
        duration = 2.0 * x_m / v0 * beta_function(1.0 / (a + 1.0), 0.5) / (a + 1.0)
        np.testing.assert_allclose(seconds[row], duration, rtol=1e-8)
        np.testing.assert_allclose(metres[row], x_m, rtol=1e-8)
    np.testing.assert_allclose(seconds[0], math.pi * math.sqrt(0.2 / 5e4), rtol=1e-8)
