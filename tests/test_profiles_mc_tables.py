"""Issue 13: the shipped Monte Carlo tables of the skin presets, the shape the presets render with.

The tables (dermis/data/monte_carlo_skin_tables.json, monte_carlo_tables.py) are checked against
a fresh, small Monte Carlo run (an independent seed: agreement within the two runs' standard
errors), against the code's current coefficients (a table of other skin is not used), and the
Gaussians a scene renders with against them (r-weighted over 0.1-10 mm, the issue's 5 %)."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.profiles import scene_skin
from dermis.profiles.medium import Layer
from dermis.profiles.monte_carlo import monte_carlo_reflectance
from dermis.profiles.monte_carlo_tables import (COMPARISON_RANGE_MM, is_current, shape_difference, shipped_table,
                                                shipped_tables)
from dermis.profiles.presets import SKIN_PRESETS
from dermis.profiles.spectral import skin_layers

SHAPE_GOAL = 0.05  # issue 13: a rendered preset's shape within 5 % of the Monte Carlo, r-weighted, 0.1-10 mm


@pytest.fixture(autouse=True)
def no_disk_cache(monkeypatch):
    """Fits here are computed, not read from (or written to) the user's disk cache."""
    monkeypatch.setenv("DERMIS_CACHE_DIR", "off")


def test_every_preset_ships_a_current_table_with_its_provenance():
    tables = shipped_tables()
    assert set(tables) == set(SKIN_PRESETS)
    for name, table in tables.items():
        assert table.parameters == SKIN_PRESETS[name], name
        assert is_current(table), f"{name}: the coefficients changed; run `make mc-tables`"
        assert shipped_table(SKIN_PRESETS[name]) is not None
        assert table.photons >= 100_000 and isinstance(table.seed, int)
        shape = table.reflectance_per_mm2.shape
        assert shape == table.standard_error_per_mm2.shape == (table.bin_edges_mm.size - 1, table.wavelength_nm.size)
        assert np.all(table.standard_error_per_mm2 >= 0) and np.all(table.total_standard_error > 0)
        # the table's own noise, as the r-weighted norm of its standard error per RGB channel
        _, noise = shape_difference(table.profile().evaluate, table)
        print(f"{name}: {table.photons} photons, noise of the RGB norm {np.round(100 * noise, 2)} %")
        assert np.all(noise < 0.025), (name, noise)
    # other skin has no table
    from dataclasses import replace

    assert shipped_table(replace(SKIN_PRESETS["fair"], hemoglobin_fraction=0.02)) is None


@pytest.mark.parametrize("preset, wavelength_nm", [("fair", 620.0), ("dark", 460.0)])
def test_shipped_table_agrees_with_a_fresh_monte_carlo(preset, wavelength_nm):
    """A small run with another seed (8,000 photons, about a second) against the shipped table
    at a few radii and in total: within 4 standard errors of the difference."""
    table = shipped_tables()[preset]
    i = int(np.flatnonzero(table.wavelength_nm == wavelength_nm)[0])
    layers = skin_layers(table.parameters, table.wavelength_nm[i:i + 1])
    fresh = monte_carlo_reflectance(layers, 8000, table.bin_edges_mm, seed=4242)
    centre = np.sqrt(table.bin_edges_mm[1:] * np.maximum(table.bin_edges_mm[:-1], 1e-3))
    for radius in (0.05, 0.3, 1.0, 3.0):
        b = int(np.argmin(np.abs(centre - radius)))
        difference = fresh.reflectance_per_mm2[b] - table.reflectance_per_mm2[b, i]
        sigma = np.hypot(fresh.standard_error_per_mm2[b], table.standard_error_per_mm2[b, i])
        print(f"{preset} {wavelength_nm:g} nm, r {centre[b]:.2f} mm: fresh {fresh.reflectance_per_mm2[b]:.4g} "
              f"table {table.reflectance_per_mm2[b, i]:.4g} +- {sigma:.2g}")
        assert sigma > 0 and abs(difference) <= 4 * sigma
    sigma = np.hypot(fresh.total_reflectance_standard_error, table.total_standard_error[i])
    assert abs(fresh.total_reflectance - table.total_reflectance[i]) <= 4 * sigma
    # the comparison has teeth: the neighbouring preset's table is off by far more
    other = shipped_tables()["dark" if preset == "fair" else "fair"]
    assert abs(fresh.total_reflectance - other.total_reflectance[i]) > 10 * sigma


@pytest.mark.parametrize("preset", ["fair", "asian", "dark"])  # the others: benchmarks/presets_vs_mc.py
def test_rendered_preset_is_within_five_percent_of_its_monte_carlo(preset, monkeypatch):
    """What a scene's [skin] profile = PRESET renders with (6 Gaussians fitted to the shipped
    table; no Monte Carlo runs) against the table, r-weighted over 0.1-10 mm; the Gaussian fit's own
    residual too (from scene_skin.MC_FIT_MIN_RADIUS_MM out). 5-10 s a preset: the issue's three
    here; every preset in benchmarks/RESULTS.md (benchmarks/presets_vs_mc.py)."""
    from dermis.profiles import monte_carlo
    from dermis.profiles.fit import fit_sum_of_gaussians
    from dermis.profiles.scene_skin import resolve_skin_profile

    def no_run(*args, **kwargs):
        raise AssertionError("a shipped preset must not run the Monte Carlo")

    monkeypatch.setattr(monte_carlo, "monte_carlo_reflectance", no_run)
    table = shipped_tables()[preset]
    gaussians = resolve_skin_profile({"profile": preset}, ".", "s.toml")
    difference, noise = shape_difference(gaussians.evaluate, table)
    fit = fit_sum_of_gaussians(table.profile(), 6, r_min_mm=scene_skin.MC_FIT_MIN_RADIUS_MM)
    print(f"{preset}: rendered shape vs MC {np.round(100 * difference, 2)} % (table noise {np.round(100 * noise, 2)} %),"
          f" fit residual {np.round(100 * fit.relative_error_rgb, 2)} %")
    assert np.all(difference <= SHAPE_GOAL), difference
    assert np.all(fit.relative_error_rgb <= SHAPE_GOAL)
    # the same fit (up to the optimiser's tolerance: a cached fit, numpy 1.26 vs 2 and their scipys
    # differ in the 4th digit)
    np.testing.assert_allclose(gaussians.weights, fit.profile.weights, rtol=2e-3, atol=1e-6)
    # the Gaussians carry the Monte Carlo's colour: their weights sum to its total reflectance
    np.testing.assert_allclose(gaussians.total_reflectance, table.profile().total_reflectance_rgb, rtol=5e-3)
    # and the layered diffusion shape (the old default) is measurably further off the same table
    from dermis.profiles.models import skin_profile

    pbd, _ = shape_difference(skin_profile(table.parameters, "pbd", wavelength_nm=table.wavelength_nm).evaluate, table)
    assert np.max(pbd) > np.max(difference) + 2 * np.max(noise), (pbd, difference)


def test_default_model_is_the_table_for_presets_and_pbd_for_other_skin(monkeypatch):
    from dataclasses import replace

    from dermis.profiles.scene_skin import default_model, physical_gaussians, resolve_skin_profile

    fair = SKIN_PRESETS["fair"]
    assert default_model(fair) == "mc"
    other = replace(fair, hemoglobin_fraction=0.02)
    assert default_model(other) == "pbd"
    overridden = resolve_skin_profile({"profile": "fair", "hemoglobin": 0.02}, ".", "s.toml")
    np.testing.assert_allclose(overridden.weights, physical_gaussians(other, "pbd").weights)
    # the same parameters given as profile = "physical" are the preset: they get its table too
    same = resolve_skin_profile({"profile": "physical", "melanin": fair.melanin_fraction, "melanin_blend":
                                 fair.melanin_blend, "hemoglobin": fair.hemoglobin_fraction}, ".", "s.toml")
    np.testing.assert_allclose(same.weights, resolve_skin_profile({"profile": "fair"}, ".", "s.toml").weights)
    assert COMPARISON_RANGE_MM == (0.1, 10.0)
