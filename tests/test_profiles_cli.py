"""`dermis profile` through click's CliRunner: files written, their contents, one-line errors."""

from __future__ import annotations

import json

import numpy as np
from scipy.integrate import trapezoid
import pytest
from click.testing import CliRunner

from dermis.profiles.cli import profile_cmd
from dermis.profiles.presets import SKIN_PRESETS


def run(args, folder, monkeypatch):
    monkeypatch.chdir(folder)
    return CliRunner().invoke(profile_cmd, args)


def test_fair_preset_fit_plot_and_json(tmp_path):
    png, js = tmp_path / "p.png", tmp_path / "p.json"
    result = CliRunner().invoke(profile_cmd, ["--preset", "fair", "--model", "pbd", "--fit", "6", "--plot", str(png),
                                              "--json", str(js)])
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    document = json.loads(js.read_text())
    assert document["format"] == "dermis-profile" and document["model"] == "pbd" and document["name"] == "fair"
    radii = np.array(document["radii_mm"])
    profile = np.array(document["profile_rgb"])
    assert profile.shape == (radii.size, 3) and np.all(np.diff(radii) > 0) and np.all(profile >= 0)
    fit = document["fit"]
    assert fit["k"] == 6 and fit["relative_error"] <= 0.02
    variances, weights = np.array(fit["variances_mm2"]), np.array(fit["weights_rgb"])
    assert np.all(np.diff(variances) > 0) and weights.shape == (6, 3) and np.all(weights >= 0)
    totals = np.array(document["total_reflectance_rgb"])
    np.testing.assert_allclose(weights.sum(axis=0), totals, rtol=3e-3)
    assert totals[0] > totals[1] > totals[2]
    # the stored curve integrates to the stored total (2 pi r R dr on the log grid, tails omitted)
    integral = trapezoid(2 * np.pi * radii[:, None] * profile, radii, axis=0)
    np.testing.assert_allclose(integral, totals, rtol=0.03)
    assert document["parameters"]["melanin_fraction"] == SKIN_PRESETS["fair"].melanin_fraction
    # the optical coefficients behind it: epidermis slab over semi-infinite dermis, 1/mm
    layers = document["medium"]["layer"]
    assert len(layers) == 2 and layers[1]["thickness_mm"] == "inf" and layers[0]["thickness_mm"] == 0.25
    assert len(layers[0]["sigma_a"]) == len(document["medium"]["wavelength_nm"]) == 31
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporaries


def test_a_preset_defaults_to_its_shipped_monte_carlo_table(tmp_path, monkeypatch):
    """No --model: a preset's profile is its shipped Monte Carlo table (no run); --photons runs it."""
    from dermis.profiles import monte_carlo
    from dermis.profiles.monte_carlo_tables import shipped_tables

    def no_run(*args, **kwargs):
        raise AssertionError("the shipped table should have been used")

    monkeypatch.setattr(monte_carlo, "monte_carlo_reflectance", no_run)
    js = tmp_path / "dark.json"
    result = CliRunner().invoke(profile_cmd, ["--preset", "dark", "--fit", "6", "--json", str(js)])
    assert result.exit_code == 0, result.output
    assert "model mc" in result.output and "table shipped with dermis" in result.output
    document = json.loads(js.read_text())
    table = shipped_tables()["dark"]
    assert document["model"] == "mc" and len(document["medium"]["wavelength_nm"]) == table.wavelength_nm.size
    np.testing.assert_allclose(document["total_reflectance_rgb"], table.profile().total_reflectance_rgb, rtol=1e-9)
    assert np.all(np.array(document["standard_error_rgb"]) >= 0)
    # --model mc with photons runs the Monte Carlo (here: refused by the stub, so the run was attempted)
    ran = CliRunner().invoke(profile_cmd, ["--preset", "dark", "--model", "mc", "--photons", "1000",
                                           "--wavelength-step", "100"])
    assert isinstance(ran.exception, AssertionError)


@pytest.mark.parametrize("model", ["multipole", "dipole", "burley", "deon"])
def test_other_models_run(tmp_path, model):
    args = ["--model", model, "--fit", "4", "--json", str(tmp_path / "m.json")]
    if model != "deon":
        args += ["--melanin", "0.05", "--hemoglobin", "0.02", "--epidermis-mm", "0.2"]
    result = CliRunner().invoke(profile_cmd, args)
    assert result.exit_code == 0, result.output
    document = json.loads((tmp_path / "m.json").read_text())
    assert document["model"] == model and document["fit"]["k"] == 4


def test_monte_carlo_model_writes_standard_errors(tmp_path):
    # 7 wavelengths (50 nm apart) and few photons keep the run short
    result = CliRunner().invoke(profile_cmd, ["--model", "mc", "--preset", "fair", "--photons", "3000",
                                              "--wavelength-step", "50", "--json", str(tmp_path / "mc.json")])
    assert result.exit_code == 0, result.output
    document = json.loads((tmp_path / "mc.json").read_text())
    errors = np.array(document["standard_error_rgb"])
    assert errors.shape == (len(document["radii_mm"]), 3) and np.all(errors >= 0)
    totals = np.array(document["total_reflectance_rgb"])
    assert totals[0] > totals[1] > totals[2] > 0.1


@pytest.mark.parametrize("args, message", [
    (["--preset", "pale"], "unknown"),
    (["--melanin", "-0.1", "--hemoglobin", "0.01"], "melanin fraction must lie in [0, 1]"),
    (["--preset", "fair", "--epidermis-mm", "-0.1"], "epidermis thickness"),
    (["--medium", "no_such.toml"], "--medium"),
    (["--medium", "no_such.toml", "--preset", "fair"], "--medium"),
    (["--preset", "fair", "--fit", "0"], "--fit 0"),
    (["--preset", "fair", "--wavelength-step", "0"], "--wavelength-step"),
    (["--melanin", "0.1"], "--hemoglobin"),
    (["--preset", "deon", "--model", "pbd"], "deon"),
    (["--preset", "fair", "--json", "out.txt"], ".json"),
    (["--preset", "fair", "--plot", "no/such/folder/p.png"], "does not exist"),
])
def test_bad_input_gets_a_one_line_error(tmp_path, monkeypatch, args, message):
    result = run(args, tmp_path, monkeypatch)
    assert result.exit_code != 0
    assert isinstance(result.exception, SystemExit)  # click's error exit, not a traceback
    error_lines = [line for line in result.output.splitlines() if line.startswith("Error")]
    assert len(error_lines) == 1 and message in error_lines[0], result.output


def test_artist_facing_burley_profile_from_albedo_and_mean_free_path(tmp_path):
    """`--albedo/--mfp-mm`: Christensen & Burley 2015's profile integrates to the albedo over the
    plane and has the closed-form mean radius 2.5 l / s(A) (checked by numerical integration of the
    written profile), and the fit's Gaussians carry the albedo."""
    import json

    from click.testing import CliRunner

    from dermis.profiles.cli import profile_cmd

    out = tmp_path / "b.json"
    res = CliRunner().invoke(profile_cmd, ["--albedo", "0.8,0.5,0.4", "--mfp-mm", "1.0,0.5,0.25", "--fit", "6",
                                           "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    r = np.asarray(doc["radii_mm"])
    R = np.asarray(doc["profile_rgb"])
    ring = 2 * np.pi * r[:, None] * R
    total = trapezoid(ring, r, axis=0)
    np.testing.assert_allclose(total, [0.8, 0.5, 0.4], rtol=0.01)
    A, l = np.array([0.8, 0.5, 0.4]), np.array([1.0, 0.5, 0.25])
    s = 1.9 - A + 3.5 * (A - 0.8) ** 2
    mean_r = trapezoid(ring * r[:, None], r, axis=0) / total
    np.testing.assert_allclose(mean_r, 2.5 * l / s, rtol=0.02)
    w = np.asarray(doc["fit"]["weights_rgb"])
    np.testing.assert_allclose(w.sum(axis=0), A, rtol=0.03)
    bad = CliRunner().invoke(profile_cmd, ["--albedo", "0.8", "--mfp-mm", "1", "--preset", "fair"])
    assert bad.exit_code != 0 and "Burley" in bad.output
