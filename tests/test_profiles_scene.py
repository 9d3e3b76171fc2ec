"""A scene's [skin] section -> SumOfGaussians (dermis.profiles.resolve_skin_profile)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from click.testing import CliRunner

from dermis.errors import DermisError
from dermis.profiles import PRESETS, SumOfGaussians, resolve_skin_profile
from dermis.profiles import scene_skin
from dermis.profiles.cli import profile_cmd
from dermis.profiles.gaussians import DEON_WEIGHTS_RGB
from dermis.profiles.presets import SKIN_PRESETS

SOURCE = "scenes/head.toml"


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DERMIS_CACHE_DIR", str(tmp_path / "cache"))
    scene_skin._fitted_physical.cache_clear()
    yield
    scene_skin._fitted_physical.cache_clear()


def test_default_and_deon_give_deons_table(tmp_path):
    for section in ({}, {"profile": "deon"}):
        profile = resolve_skin_profile(section, tmp_path, SOURCE)
        assert isinstance(profile, SumOfGaussians) and profile.k == 6
        np.testing.assert_array_equal(profile.weights, DEON_WEIGHTS_RGB)
    four = resolve_skin_profile({"profile": "deon", "gaussians": 4}, tmp_path, SOURCE)
    assert four.k == 4 and np.allclose(four.total_reflectance, 1.0, atol=3e-3)
    assert set(PRESETS) == {"deon", "fair", "asian", "dark", "very-light", "light", "intermediate", "tan", "brown"}


def test_presets_carry_colour_and_dark_skin_is_darker_with_less_red_bleed(tmp_path):
    fair = resolve_skin_profile({"profile": "fair"}, tmp_path, SOURCE)
    dark = resolve_skin_profile({"profile": "dark"}, tmp_path, SOURCE)
    assert fair.k == dark.k == 6
    # a preset renders with its shipped Monte Carlo table (monte_carlo_tables.py) and carries its R_d
    from dermis.profiles.monte_carlo_tables import shipped_tables

    expected = shipped_tables()["fair"].profile().total_reflectance_rgb
    np.testing.assert_allclose(fair.total_reflectance, expected, rtol=5e-3)
    # the measured counterparts (ColorChecker dark skin, NIST very light) are 0.31, 0.20, 0.16 of each other
    assert np.all(dark.total_reflectance < 0.4 * fair.total_reflectance)

    def red_mean_radius(p):  # of the red channel's Gaussians; one of variance v has mean radius sqrt(pi v / 2)
        return float(p.weights[:, 0] @ np.sqrt(np.pi * p.variances_mm2 / 2) / p.weights[:, 0].sum())

    print("red mean radius (mm): fair", red_mean_radius(fair), "dark", red_mean_radius(dark))
    assert red_mean_radius(dark) < 0.7 * red_mean_radius(fair)  # measured: 0.60 with the fitted presets


def test_physical_parameters_model_and_k(tmp_path):
    section = {"profile": "physical", "melanin": 0.1, "melanin_blend": 0.5, "hemoglobin": 0.02,
               "oxygenation": 0.6, "epidermis_mm": 0.2, "model": "multipole", "gaussians": 4}
    profile = resolve_skin_profile(section, tmp_path, SOURCE)
    assert profile.k == 4 and np.all(profile.weights >= 0)
    # a preset with an override equals the physical description of the same skin
    override = resolve_skin_profile({"profile": "fair", "hemoglobin": 0.02}, tmp_path, SOURCE)
    fair = SKIN_PRESETS["fair"]
    same = resolve_skin_profile({"profile": "physical", "melanin": fair.melanin_fraction,
                                 "melanin_blend": fair.melanin_blend, "hemoglobin": 0.02}, tmp_path, SOURCE)
    np.testing.assert_allclose(override.weights, same.weights)


def test_results_are_cached_in_memory_and_on_disk(tmp_path, monkeypatch):
    started = time.perf_counter()
    first = resolve_skin_profile({"profile": "asian"}, tmp_path, SOURCE)
    cold = time.perf_counter() - started
    print(f"asian preset, its Monte Carlo table + 6-Gaussian fit, not cached: {cold:.2f} s")  # no timed assert
    assert list((tmp_path / "cache" / "profiles").glob("*.json"))
    scene_skin._fitted_physical.cache_clear()

    def no_recompute(*args, **kwargs):
        raise AssertionError("the disk cache was not used")

    monkeypatch.setattr("dermis.profiles.models.skin_profile", no_recompute)
    monkeypatch.setattr("dermis.profiles.fit.fit_sum_of_gaussians", no_recompute)
    again = resolve_skin_profile({"profile": "asian"}, tmp_path, SOURCE)
    np.testing.assert_array_equal(first.weights, again.weights)
    again.weights[:] = 0  # callers get their own arrays
    np.testing.assert_array_equal(resolve_skin_profile({"profile": "asian"}, tmp_path, SOURCE).weights, first.weights)


def test_profile_json_file_relative_to_the_scene(tmp_path):
    (tmp_path / "skins").mkdir()
    target = tmp_path / "skins" / "mine.json"
    result = CliRunner().invoke(profile_cmd, ["--preset", "fair", "--model", "multipole", "--fit", "5",
                                              "--json", str(target)])
    assert result.exit_code == 0, result.output
    fitted = json.loads(target.read_text())["fit"]
    profile = resolve_skin_profile({"profile": "skins/mine.json"}, tmp_path, SOURCE)
    assert profile.k == 5
    np.testing.assert_allclose(profile.variances_mm2, fitted["variances_mm2"])
    # another K refits the stored curve
    assert resolve_skin_profile({"profile": "skins/mine.json", "gaussians": 3}, tmp_path, SOURCE).k == 3
    with pytest.raises(DermisError, match="outside the scene's folder"):
        resolve_skin_profile({"profile": "../mine.json"}, tmp_path / "skins", SOURCE)
    with pytest.raises(DermisError, match="does not exist"):
        resolve_skin_profile({"profile": "skins/other.json"}, tmp_path, SOURCE)
    (tmp_path / "bad.json").write_text("{\"format\": \"something\"}")
    with pytest.raises(DermisError, match="not a dermis profile"):
        resolve_skin_profile({"profile": "bad.json"}, tmp_path, SOURCE)


@pytest.mark.parametrize("section, message", [
    ({"profile": "fair", "melanine": 0.1}, "unknown key 'melanine' in [skin]"),
    ({"profile": "pale"}, "profile 'pale' is unknown"),
    ({"profile": "physical", "melanin": 0.1}, "needs 'hemoglobin'"),
    ({"profile": "physical", "melanin": -0.1, "hemoglobin": 0.01}, "melanin fraction must lie in [0, 1]"),
    ({"profile": "fair", "epidermis_mm": -0.1}, "epidermis thickness"),
    ({"profile": "fair", "gaussians": 0}, "gaussians must be an integer"),
    ({"profile": "fair", "model": "raytrace"}, "model 'raytrace'"),
    ({"profile": "deon", "melanin": 0.1}, "does not apply"),
    ({"profile": "fair", "melanin": "lots"}, "must be a number"),
    ({"profile": 3}, "must be a name or a file"),
])
def test_bad_sections_get_one_line_errors_naming_the_scene(tmp_path, section, message):
    with pytest.raises(DermisError) as error:
        resolve_skin_profile(section, tmp_path, SOURCE)
    text = str(error.value)
    assert SOURCE in text and message in text and "\n" not in text
