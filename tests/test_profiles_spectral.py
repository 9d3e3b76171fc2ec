"""The Donner & Jensen 2006 spectral skin model against its published formulas, and the RGB step."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dermis.errors import DermisError
from dermis.profiles.models import skin_profile
from dermis.profiles.presets import SKIN_PRESETS, skin_preset
from dermis.profiles.spectral import (SkinParameters, dermis_absorption_per_mm, epidermis_absorption_per_mm,
                                      skin_layers, spectral_to_linear_srgb, spectrum_to_linear_srgb_matrix)

# Prahl's table (omlc.org/spectra/hemoglobin/summary.html), cm^-1 / M: (HbO2, Hb)
PRAHL = {450: (62816.0, 103292.0), 550: (43016.0, 53412.0), 650: (368.0, 3750.12)}


def published(wavelength, cm, bm, ch, gamma):
    """Donner & Jensen 2006 / skin-rendering.md section 2, typed from the formulas (1/mm)."""
    eu = 6.6e10 * wavelength**-3.33
    pheo = 2.9e14 * wavelength**-4.75
    base = 0.0244 + 8.53 * np.exp(-(wavelength - 154.0) / 66.2)
    oxy, deoxy = (2.303 * e * 150.0 / 64500.0 / 10.0 for e in PRAHL[wavelength])
    epidermis_a = cm * (bm * eu + (1 - bm) * pheo) + (1 - cm) * base
    dermis_a = ch * (gamma * oxy + (1 - gamma) * deoxy) + (1 - ch) * base
    epidermis_s = 14.74 * wavelength**-0.22 + 2.2e11 * wavelength**-4.0
    return epidermis_a, dermis_a, epidermis_s, 0.5 * epidermis_s


@pytest.mark.parametrize("wavelength", [450, 550, 650])
@pytest.mark.parametrize("parameters", [(0.005, 0.7, 0.005, 0.75), (0.15, 0.0, 0.01, 0.75), (0.5, 0.7, 0.05, 0.4)])
def test_coefficients_equal_the_published_formulas(wavelength, parameters):
    cm, bm, ch, gamma = parameters
    skin = SkinParameters(cm, bm, ch, oxygenation=gamma)
    epidermis, dermis = skin_layers(skin, np.array([float(wavelength)]))
    expected = published(wavelength, cm, bm, ch, gamma)
    actual = (epidermis.medium.sigma_a_per_mm[0], dermis.medium.sigma_a_per_mm[0],
              epidermis.medium.reduced_sigma_s_per_mm[0], dermis.medium.reduced_sigma_s_per_mm[0])
    np.testing.assert_allclose(actual, expected, rtol=1e-12)
    assert epidermis.thickness_mm == 0.25 and np.isinf(dermis.thickness_mm)
    assert epidermis_absorption_per_mm(wavelength, cm, bm) == pytest.approx(expected[0], rel=1e-12)
    assert dermis_absorption_per_mm(wavelength, ch, gamma) == pytest.approx(expected[1], rel=1e-12)


@pytest.mark.filterwarnings("ignore::colour.utilities.ColourRuntimeWarning")
def test_rgb_matrix_maps_white_to_white_and_agrees_with_colour_science():
    import colour

    matrix = spectrum_to_linear_srgb_matrix()
    np.testing.assert_allclose(matrix.sum(axis=1), 1.0, rtol=1e-12)
    # A smooth reddish reflectance spectrum: colour-science's own integration (1 nm, ASTM E308)
    wavelength = np.arange(400.0, 701.0, 10.0)
    reflectance = 0.2 + 0.5 / (1 + np.exp(-(wavelength - 590.0) / 25.0))
    distribution = colour.SpectralDistribution(dict(zip(wavelength, reflectance)))
    xyz = colour.sd_to_XYZ(distribution, illuminant=colour.SDS_ILLUMINANTS["D65"]) / 100.0
    reference = colour.XYZ_to_sRGB(xyz, apply_cctf_encoding=False)
    np.testing.assert_allclose(spectral_to_linear_srgb(reflectance), reference, rtol=0.02, atol=0.004)


def test_more_melanin_lowers_reflectance_in_every_channel_and_blue_most():
    light = skin_profile(SkinParameters(0.02, 0.7, 0.01), "pbd")
    dark = skin_profile(SkinParameters(0.2, 0.7, 0.01), "pbd")
    ratio = dark.total_reflectance_rgb / light.total_reflectance_rgb
    assert np.all(ratio < 0.9)
    assert ratio[2] < ratio[1] < ratio[0]


def test_presets_order_like_skin_and_dark_skin_bleeds_less_red():
    fair, asian, dark = (skin_profile(SKIN_PRESETS[n], "pbd") for n in ("fair", "asian", "dark"))
    for profile in (fair, asian, dark):
        assert profile.total_reflectance_rgb[0] > profile.total_reflectance_rgb[1] > profile.total_reflectance_rgb[2]
    assert np.all(fair.total_reflectance_rgb > asian.total_reflectance_rgb)
    assert np.all(asian.total_reflectance_rgb > dark.total_reflectance_rgb)
    # fitted presets (presets.py): dark's red mean radius is 0.55 of fair's (pbd)
    assert dark.mean_radius_mm()[0] < 0.7 * fair.mean_radius_mm()[0]
    print("totals fair", fair.total_reflectance_rgb, "asian", asian.total_reflectance_rgb,
          "dark", dark.total_reflectance_rgb)


def test_bad_skin_parameters_are_refused():
    with pytest.raises(DermisError, match="melanin"):
        SkinParameters(-0.1, 0.7, 0.01)
    with pytest.raises(DermisError, match="hemoglobin"):
        SkinParameters(0.1, 0.7, 1.5)
    with pytest.raises(DermisError, match="thickness"):
        SkinParameters(0.1, 0.7, 0.01, epidermis_thickness_mm=-0.1)
    with pytest.raises(DermisError, match="unknown skin preset 'pale'"):
        skin_preset("pale")
    with pytest.raises(DermisError, match="model"):
        skin_profile(SKIN_PRESETS["fair"], "diffusion")
    with pytest.raises(DermisError, match="illuminant"):
        skin_profile(dataclasses.replace(SKIN_PRESETS["fair"]), "multipole", illuminant="Z99")
