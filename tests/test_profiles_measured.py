"""Issue 13: skin colour against measured skin, profiles of a given medium, thin slabs.

The presets' total reflectance against the NIST skin reflectance data set (Cooksey et al. 2017,
grouped by ITA category) and the ColorChecker skin patches; ``--medium`` and the scene's
profile = "medium" against the same stack given as skin parameters; the multipole's thin-slab
fix against photon beam diffusion (an independent model) and energy conservation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from dermis.errors import DermisError
from dermis.profiles.measured_skin import (NIST_CATEGORIES, colorchecker_skin, measured_counterpart,
                                           model_measurand, nist_skin, normal_incidence_fresnel)
from dermis.profiles.models import layered_diffusion_reflectance, medium_profile, skin_profile
from dermis.profiles.presets import MEASURED_COUNTERPARTS, SKIN_PRESETS
from dermis.profiles.spectral import DEFAULT_WAVELENGTHS_NM, SkinParameters, skin_layers, spectral_to_linear_srgb

# Every channel of every preset within 15 % of its measured counterpart (issue 13)
TOLERANCE = 0.15


def test_measured_data_is_what_its_sources_say():
    # The ColorChecker patches through dermis's spectrum -> linear sRGB: the chart's published sRGB
    # (BabelColor: light skin 194,150,130; dark skin 115,82,68), decoded to linear, within 0.02
    def linear(c8):
        c = np.asarray(c8) / 255.0
        return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)

    np.testing.assert_allclose(colorchecker_skin("light skin").linear_srgb(), linear([194, 150, 130]), atol=0.02)
    np.testing.assert_allclose(colorchecker_skin("dark skin").linear_srgb(), linear([115, 82, 68]), atol=0.02)
    # NIST categories: lighter categories reflect more at every wavelength, and 31 samples 400-700 nm
    spectra = [nist_skin(c) for c in NIST_CATEGORIES]
    for lighter, darker in zip(spectra, spectra[1:]):
        assert lighter.reflectance.size == 31 and np.all(lighter.reflectance > darker.reflectance)
        assert lighter.specular_included and not colorchecker_skin("dark skin").specular_included
    with pytest.raises(DermisError, match="unknown NIST skin category"):
        nist_skin("purple")


def test_measurand_adds_the_surface_reflection_as_fresnel_says():
    assert math.isclose(normal_incidence_fresnel(1.4), (0.4 / 2.4) ** 2)
    f0 = (0.4 / 2.4) ** 2
    np.testing.assert_allclose(model_measurand([0.5], 1.4, False), [(1 - f0) * 0.5])
    np.testing.assert_allclose(model_measurand([0.5], 1.4, True), [f0 + (1 - f0) * 0.5])


@pytest.mark.parametrize("preset", sorted(MEASURED_COUNTERPARTS))
def test_preset_reflectance_matches_its_measured_counterpart(preset):
    """The total reflectance a preset renders with (its shipped Monte Carlo table, 400-700 nm every
    20 nm: monte_carlo_tables.py), in its counterpart's measurand, per linear-sRGB channel, against
    the shipped measured spectrum integrated the same way."""
    from dermis.profiles.monte_carlo_tables import shipped_tables

    measured = measured_counterpart(preset)
    parameters = SKIN_PRESETS[preset]
    table = shipped_tables()[preset]
    assert table.parameters == parameters
    wavelength = table.wavelength_nm
    model = spectral_to_linear_srgb(model_measurand(table.total_reflectance, parameters.refractive_index,
                                                    measured.specular_included), wavelength)
    target = measured.linear_srgb(wavelength)
    ratio = model / target
    pbd = layered_diffusion_reflectance(skin_layers(parameters, wavelength), "pbd").total_reflectance
    pbd_rgb = spectral_to_linear_srgb(model_measurand(pbd, parameters.refractive_index, measured.specular_included),
                                      wavelength)
    print(f"{preset}: Monte Carlo {np.round(model, 4)} measured ({measured.name}) {np.round(target, 4)}",
          f"ratio {np.round(ratio, 3)}; pbd ratio {np.round(pbd_rgb / target, 3)}")
    assert np.all(np.abs(ratio - 1.0) <= TOLERANCE), ratio
    # the comparison has teeth: the old presets (C_m 0.005 / 0.15 / 0.5 over 0.25 mm) fail it
    old = {"fair": SkinParameters(0.005, 0.7, 0.005), "dark": SkinParameters(0.5, 0.7, 0.05)}.get(preset)
    if old is not None:
        old_totals = layered_diffusion_reflectance(skin_layers(old, wavelength), "pbd").total_reflectance
        old_rgb = spectral_to_linear_srgb(model_measurand(old_totals, 1.4, measured.specular_included), wavelength)
        assert np.any(np.abs(old_rgb / target - 1.0) > TOLERANCE)


def test_fair_is_the_lightest_measured_category_by_ita():
    """fair's counterpart: the Individual Typology Angle (Chardon et al. 1991) puts the
    ColorChecker 'light skin' patch in Del Bino's 'light' category (41-55 deg), not the lightest
    (> 55 deg), and 'dark skin' in 'dark' (< -30 deg); NIST very light is > 55 deg."""
    assert 41.0 < colorchecker_skin("light skin").individual_typology_angle() <= 55.0
    assert colorchecker_skin("dark skin").individual_typology_angle() < -30.0
    assert nist_skin("very_light").individual_typology_angle() > 55.0
    # the categories of the NIST table hold their own means (the table's classing, reproduced)
    bounds = {"very_light": (55, 90), "light": (41, 55), "intermediate": (28, 41), "tan": (10, 28), "brown": (-30, 10)}
    for category, (low, high) in bounds.items():
        assert low < nist_skin(category).individual_typology_angle() <= high, category
    assert MEASURED_COUNTERPARTS["fair"] == ("nist", "very_light") and SKIN_PRESETS["fair"] == SKIN_PRESETS["very-light"]


def _medium_file(folder, layers, wavelength=None):
    document = {"layer": layers}
    if wavelength is not None:
        document["wavelength_nm"] = [float(w) for w in wavelength]
    path = folder / "medium.json"
    path.write_text(json.dumps(document))
    return path


def test_medium_reproduces_the_same_stack_given_as_skin_parameters(tmp_path):
    """--medium with the epidermis and dermis coefficients of a skin parameter set, per wavelength,
    gives the skin model's profile; mfp_mm + albedo is the same medium as sigma_a + sigma_s'."""
    from dermis.profiles.cli import profile_cmd

    wavelength = np.arange(400.0, 701.0, 50.0)
    parameters = SkinParameters(0.02, 0.5, 0.01)
    layers = skin_layers(parameters, wavelength)
    described = []
    for layer in layers:
        entry = {"sigma_a": layer.medium.sigma_a_per_mm.tolist(),
                 "sigma_s_reduced": layer.medium.reduced_sigma_s_per_mm.tolist(), "eta": 1.4}
        if not layer.semi_infinite:
            entry["thickness_mm"] = layer.thickness_mm
        described.append(entry)
    path = _medium_file(tmp_path, described, wavelength)
    out = tmp_path / "m.json"
    result = CliRunner().invoke(profile_cmd, ["--medium", str(path), "--model", "multipole", "--json", str(out)])
    assert result.exit_code == 0, result.output
    document = json.loads(out.read_text())
    expected = skin_profile(parameters, "multipole", wavelength_nm=wavelength)
    np.testing.assert_allclose(document["total_reflectance_rgb"], expected.total_reflectance_rgb, rtol=1e-9)
    np.testing.assert_allclose(document["medium"]["layer"][0]["sigma_a"], described[0]["sigma_a"], rtol=1e-12)
    assert document["medium"]["layer"][1]["thickness_mm"] == "inf"
    # the same medium as transport mean free path and reduced albedo
    for entry in described:
        sigma_t = np.add(entry.pop("sigma_a"), entry["sigma_s_reduced"])
        entry["albedo"] = (np.asarray(entry.pop("sigma_s_reduced")) / sigma_t).tolist()
        entry["mfp_mm"] = (1.0 / sigma_t).tolist()
    again = _profile(_medium_file(tmp_path, described, wavelength), "multipole")
    np.testing.assert_allclose(again.total_reflectance_rgb, expected.total_reflectance_rgb, rtol=1e-9)


def _read(path):
    from dermis.profiles.medium_file import read_medium_file

    return read_medium_file(path)


def _profile(path, model, **options):
    layers, wavelength = _read(path)
    return medium_profile(layers, model, wavelength_nm=wavelength, **options)


@pytest.mark.parametrize("model", ["dipole", "multipole", "pbd", "burley"])
def test_every_model_takes_an_rgb_medium(tmp_path, model):
    """An RGB medium (3 values per coefficient): a semi-infinite one agrees among models within the
    models' known spread (dipole and multipole are one dipole here; pbd and burley match)."""
    path = _medium_file(tmp_path, [{"sigma_a": [0.01, 0.05, 0.2], "sigma_s_reduced": [1.0, 1.5, 2.0], "eta": 1.3}])
    profile = _profile(path, model)
    reference = _profile(path, "pbd")
    np.testing.assert_allclose(profile.total_reflectance_rgb, reference.total_reflectance_rgb, rtol=0.1)
    assert profile.total_reflectance_rgb[0] > profile.total_reflectance_rgb[1] > profile.total_reflectance_rgb[2]


def test_medium_monte_carlo_within_its_error_of_pbd(tmp_path):
    """The Monte Carlo of an RGB medium (few photons) against pbd's total, within 4 standard errors
    plus pbd's known ~5 % model error."""
    path = _medium_file(tmp_path, [{"sigma_a": [0.05, 0.2, 0.8], "sigma_s": [10.0, 10.0, 10.0], "g": 0.8,
                                    "thickness_mm": 0.2},
                                   {"mfp_mm": 0.5, "albedo": [0.99, 0.97, 0.9]}])
    layers, _ = _read(path)
    mc = medium_profile(layers, "mc", photons=3000, seed=3)
    pbd = medium_profile(layers, "pbd")
    # binomial standard error of a total reflectance from N photons
    error = np.sqrt(mc.total_reflectance_rgb * (1 - mc.total_reflectance_rgb) / 3000)
    print("mc", mc.total_reflectance_rgb, "+-", error, "pbd", pbd.total_reflectance_rgb)
    assert np.all(np.abs(mc.total_reflectance_rgb - pbd.total_reflectance_rgb)
                  <= 4 * error + 0.05 * pbd.total_reflectance_rgb)


@pytest.mark.parametrize("layers, message", [
    ([], "at least one"),
    ([{"sigma_a": 0.1}], "give sigma_a with"),
    ([{"sigma_a": [0.1, 0.2], "sigma_s_reduced": 1.0}], "give 1 or 3"),
    ([{"sigma_a": 0.1, "sigma_s_reduced": 1.0}, {"sigma_a": 0.1, "sigma_s_reduced": 1.0}], "only the last"),
    ([{"sigma_a": -0.1, "sigma_s_reduced": 1.0}], ">= 0"),
    ([{"mfp_mm": 0.0, "albedo": 0.9}], "mfp_mm must be > 0"),
    ([{"sigma_a": 0.1, "sigma_s_reduced": 1.0, "colour": 1}], "unknown key 'colour'"),
])
def test_bad_medium_gets_one_line_errors(tmp_path, monkeypatch, layers, message):
    from dermis.profiles.cli import profile_cmd

    path = _medium_file(tmp_path, layers)
    result = CliRunner().invoke(profile_cmd, ["--medium", str(path)])
    assert result.exit_code == 2 and isinstance(result.exception, SystemExit)
    error_lines = [line for line in result.output.splitlines() if line.startswith("Error")]
    assert len(error_lines) == 1 and message in error_lines[0] and str(path) in error_lines[0], result.output


def test_zero_epidermis_is_the_dermis_alone():
    parameters = SkinParameters(0.3, 0.7, 0.02, epidermis_thickness_mm=0.0)
    wavelength = np.array([450.0, 550.0, 650.0])
    layers = skin_layers(parameters, wavelength)
    assert len(layers) == 1 and layers[0].semi_infinite
    # melanin lives in the epidermis: without one it changes nothing
    other = skin_layers(SkinParameters(0.0, 0.7, 0.02, epidermis_thickness_mm=0.0), wavelength)
    np.testing.assert_array_equal(layers[0].medium.sigma_a_per_mm, other[0].medium.sigma_a_per_mm)


def test_scene_skin_medium_section(tmp_path):
    from dermis.profiles.scene_skin import resolve_skin_profile

    layers = [{"sigma_a": [0.3, 0.6, 1.2], "sigma_s_reduced": [2.5, 3.0, 3.5], "thickness_mm": 0.1},
              {"mfp_mm": [1.2, 0.6, 0.3], "albedo": [0.995, 0.98, 0.95]}]
    gaussians = resolve_skin_profile({"profile": "medium", "layer": layers, "gaussians": 4, "model": "multipole"},
                                     tmp_path, "s.toml")
    expected = _profile(_medium_file(tmp_path, layers), "multipole")
    assert gaussians.k == 4
    np.testing.assert_allclose(gaussians.total_reflectance, expected.total_reflectance_rgb, rtol=0.02)
    with pytest.raises(DermisError, match=r"s.toml: .*layer 1: g must lie"):
        resolve_skin_profile({"profile": "medium", "layer": [{"sigma_a": 0.1, "sigma_s_reduced": 1.0, "g": 1.5}]},
                             tmp_path, "s.toml")
    with pytest.raises(DermisError, match="'layer' needs profile"):
        resolve_skin_profile({"profile": "fair", "layer": layers}, tmp_path, "s.toml")


@pytest.mark.parametrize("thickness_mm", [0.1, 0.15, 0.25])
def test_multipole_thin_slab_agrees_with_photon_beam_diffusion(thickness_mm):
    """An epidermis thinner than two transport mean free paths: the multipole's pole used to sit on
    the slab's bottom boundary, T collapsed and T from below went negative (total R 0.15 against
    pbd's 0.53). Now within 5 % of pbd from 0.1 mm up (7 % at 0.05 mm) and R + T <= 1."""
    from dermis.profiles.medium import Medium
    from dermis.profiles.models import DIFFUSION_GRID
    from dermis.profiles.multipole import multipole_profiles

    parameters = SkinParameters(0.0, 0.7, 0.0, epidermis_thickness_mm=thickness_mm)
    wavelength = np.array([500.0, 650.0])
    multipole = layered_diffusion_reflectance(skin_layers(parameters, wavelength), "multipole").total_reflectance
    pbd = layered_diffusion_reflectance(skin_layers(parameters, wavelength), "pbd").total_reflectance
    np.testing.assert_allclose(multipole, pbd, rtol=0.05)
    slab = Medium.from_reduced([0.03, 0.3], [4.0, 4.0], 0.0, 1.4)
    grid = DIFFUSION_GRID
    for from_below in (False, True):
        r, t = multipole_profiles(grid.radius_mm, slab, thickness_mm, 1.4, 1.0, from_below=from_below)
        total_r, total_t = grid.total(r), grid.total(t)
        assert np.all(total_t > 0) and np.all(total_r + total_t <= 1.0), (total_r, total_t)


def test_scene_model_mc_fits_the_monte_carlo_shape_and_caches_it(tmp_path, monkeypatch):
    """[skin] model = "mc": the Gaussians fit the Monte Carlo's profile (few photons here) and carry
    its total; the second request is served from the disk cache without running it again."""
    from dermis.profiles import monte_carlo, scene_skin
    from dermis.profiles.scene_skin import resolve_skin_profile

    monkeypatch.setenv("DERMIS_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(scene_skin, "MC_SCENE_PHOTONS", 4000)
    scene_skin._fitted_medium.cache_clear()
    section = {"profile": "medium", "layer": [{"sigma_a": [0.02, 0.1, 0.4], "sigma_s_reduced": 2.0}],
               "model": "mc", "gaussians": 4}
    first = resolve_skin_profile(section, tmp_path, "s.toml")
    reference = _profile(_medium_file(tmp_path, section["layer"]), "pbd")
    # MC totals carry a binomial error of ~0.008 at 4000 photons; pbd is within ~5 % of MC
    np.testing.assert_allclose(first.total_reflectance, reference.total_reflectance_rgb, rtol=0.08)
    scene_skin._fitted_medium.cache_clear()

    def no_monte_carlo(*args, **kwargs):
        raise AssertionError("the cached fit should have been used")

    monkeypatch.setattr(monte_carlo, "monte_carlo_reflectance", no_monte_carlo)
    again = resolve_skin_profile(section, tmp_path, "s.toml")
    np.testing.assert_array_equal(again.weights, first.weights)
    scene_skin._fitted_medium.cache_clear()
