"""The spectral skin model of Donner & Jensen 2006 ("A Spectral BSSRDF for Shading Human Skin",
EGSR 2006), and the conversion of spectral profiles to linear sRGB.

Skin is two layers: an epidermis (about 0.25 mm) coloured by melanin over a semi-infinite dermis
coloured by blood, both with refractive index 1.4. Four parameters (and the epidermis
thickness) set the absorption of both layers at every wavelength lambda (nm); coefficients in
1/mm (Donner & Jensen 2006, section 3; docs/skin-rendering.md section 2):

    eumelanin    sigma_a,em(lambda) = 6.6e10 lambda^-3.33
    pheomelanin  sigma_a,pm(lambda) = 2.9e14 lambda^-4.75
    baseline     sigma_a,base(lambda) = 0.0244 + 8.53 e^(-(lambda - 154) / 66.2)
    epidermis    sigma_a = C_m (beta_m sigma_a,em + (1 - beta_m) sigma_a,pm) + (1 - C_m) sigma_a,base
    dermis       sigma_a = C_h (gamma sigma_a,oxy + (1 - gamma) sigma_a,deoxy) + (1 - C_h) sigma_a,base
    scattering   sigma_s',epi(lambda) = 14.74 lambda^-0.22 + 2.2e11 lambda^-4,  sigma_s',dermis = sigma_s',epi / 2

C_m: melanin volume fraction, beta_m: eumelanin share of it, C_h: blood volume fraction, gamma:
oxygenated share of haemoglobin. Whole-blood absorption comes from the molar extinction of
haemoglobin tabulated by Prahl (data/prahl_hemoglobin_extinction.csv) with 150 g/L of
haemoglobin of 64,500 g/mol: sigma_a [1/cm] = 2.303 epsilon 150 / 64500.

The paper gives reduced scattering only, so by default skin scatters isotropically with
sigma_s = sigma_s' (the similarity relation; ``anisotropy`` g = 0). The diffusion terms see only
sigma_s'; g changes the single-scattering term and the Monte Carlo. Measured against the Monte
Carlo with the real anisotropy of skin (g = 0.8, van Gemert et al. 1989), the totals of the g = 0
model are closer (within about 5 %) than those of photon beam diffusion run with g = 0.8 (about
11 % low), see tests/test_profiles_layers.py and the module docstring of models.py.

RGB: a spectral profile R(r, lambda) is integrated against an illuminant S (default D65) and the
CIE 1931 2-degree colour matching functions (tables from colour-science, not typed here), then
converted from XYZ to linear sRGB, with the illuminant's white adapted to sRGB's D65 (CAT02).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.medium import Layer, Medium

#: Wavelengths (nm) of the spectral computation: 400-700 nm in 10 nm steps (the CIE matching
#: functions outside this range add < 0.3 % of Y under D65).
DEFAULT_WAVELENGTHS_NM = np.arange(400.0, 701.0, 10.0)

HEMOGLOBIN_GRAMS_PER_LITER = 150.0  # whole blood
HEMOGLOBIN_GRAMS_PER_MOLE = 64500.0
SKIN_REFRACTIVE_INDEX = 1.4
SKIN_ANISOTROPY = 0.0


@dataclass(frozen=True)
class SkinParameters:
    """Donner & Jensen 2006 skin parameters. Fractions lie in [0, 1]; thickness in mm (>= 0; 0: no
    epidermis, the dermis alone, so melanin has no effect)."""

    melanin_fraction: float  # C_m
    melanin_blend: float  # beta_m, eumelanin share of the melanin
    hemoglobin_fraction: float  # C_h
    oxygenation: float = 0.75  # gamma, oxy-haemoglobin share
    epidermis_thickness_mm: float = 0.25
    refractive_index: float = SKIN_REFRACTIVE_INDEX
    anisotropy: float = SKIN_ANISOTROPY

    def __post_init__(self):
        labels = {"melanin_fraction": "melanin", "melanin_blend": "melanin blend",
                  "hemoglobin_fraction": "hemoglobin", "oxygenation": "oxygenation"}
        for name, label in labels.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise DermisError(f"{label} must be a number, got {value!r}")
            if not 0.0 <= float(value) <= 1.0:
                raise DermisError(f"{label} fraction must lie in [0, 1], got {value}")
            object.__setattr__(self, name, float(value))
        thickness = self.epidermis_thickness_mm
        if isinstance(thickness, bool) or not isinstance(thickness, (int, float, np.floating, np.integer)):
            raise DermisError(f"epidermis thickness must be a number of mm, got {thickness!r}")
        if not (np.isfinite(thickness) and 0.0 <= float(thickness) <= 10.0):
            raise DermisError(f"epidermis thickness must lie in [0, 10] mm (0: dermis only), got {thickness}")
        object.__setattr__(self, "epidermis_thickness_mm", float(thickness))
        if not 1.0 <= float(self.refractive_index) <= 3.0:
            raise DermisError(f"refractive index must lie in [1, 3], got {self.refractive_index}")
        if not 0.0 <= float(self.anisotropy) < 1.0:
            raise DermisError(f"anisotropy g must lie in [0, 1), got {self.anisotropy}")

    def to_dict(self) -> dict:
        return asdict(self)


def _wavelengths(wavelength_nm) -> np.ndarray:
    wavelength = np.asarray(wavelength_nm, dtype=np.float64)
    if np.any(wavelength < 250) or np.any(wavelength > 1000):
        raise DermisError("the skin model covers 250-1000 nm (Prahl's haemoglobin table)")
    return wavelength


def eumelanin_absorption_per_mm(wavelength_nm):
    """sigma_a,em = 6.6e10 lambda^-3.33 (1/mm), Donner & Jensen 2006."""
    return 6.6e10 * _wavelengths(wavelength_nm) ** -3.33


def pheomelanin_absorption_per_mm(wavelength_nm):
    """sigma_a,pm = 2.9e14 lambda^-4.75 (1/mm), Donner & Jensen 2006."""
    return 2.9e14 * _wavelengths(wavelength_nm) ** -4.75


def baseline_absorption_per_mm(wavelength_nm):
    """Melanin- and blood-free skin, 0.0244 + 8.53 e^(-(lambda - 154)/66.2) (1/mm), Donner & Jensen 2006."""
    return 0.0244 + 8.53 * np.exp(-(_wavelengths(wavelength_nm) - 154.0) / 66.2)


@lru_cache(maxsize=1)
def _hemoglobin_table():
    text = resources.files("dermis.data").joinpath("prahl_hemoglobin_extinction.csv").read_text()
    rows = [line for line in text.splitlines() if line and not line.startswith("#")]
    data = np.array([[float(v) for v in row.split(",")] for row in rows[1:]])
    return data[:, 0], data[:, 1], data[:, 2]


def hemoglobin_molar_extinction(wavelength_nm):
    """(epsilon_HbO2, epsilon_Hb) in cm^-1 / (mol/L), linearly interpolated in Prahl's table."""
    wavelength = _wavelengths(wavelength_nm)
    table_nm, oxy, deoxy = _hemoglobin_table()
    return np.interp(wavelength, table_nm, oxy), np.interp(wavelength, table_nm, deoxy)


def blood_absorption_per_mm(wavelength_nm):
    """(sigma_a of oxygenated, of deoxygenated whole blood) in 1/mm: 2.303 epsilon 150 / 64500 / 10."""
    oxy, deoxy = hemoglobin_molar_extinction(wavelength_nm)
    scale = 2.303 * HEMOGLOBIN_GRAMS_PER_LITER / HEMOGLOBIN_GRAMS_PER_MOLE / 10.0  # 1/cm -> 1/mm
    return oxy * scale, deoxy * scale


def epidermis_absorption_per_mm(wavelength_nm, melanin_fraction, melanin_blend):
    """sigma_a = C_m (beta_m sigma_a,em + (1 - beta_m) sigma_a,pm) + (1 - C_m) sigma_a,base (Donner & Jensen 2006)."""
    melanin = (melanin_blend * eumelanin_absorption_per_mm(wavelength_nm)
               + (1.0 - melanin_blend) * pheomelanin_absorption_per_mm(wavelength_nm))
    return melanin_fraction * melanin + (1.0 - melanin_fraction) * baseline_absorption_per_mm(wavelength_nm)


def dermis_absorption_per_mm(wavelength_nm, hemoglobin_fraction, oxygenation):
    """sigma_a = C_h (gamma sigma_a,oxy + (1 - gamma) sigma_a,deoxy) + (1 - C_h) sigma_a,base (Donner & Jensen 2006)."""
    oxy, deoxy = blood_absorption_per_mm(wavelength_nm)
    blood = oxygenation * oxy + (1.0 - oxygenation) * deoxy
    return hemoglobin_fraction * blood + (1.0 - hemoglobin_fraction) * baseline_absorption_per_mm(wavelength_nm)


def epidermis_reduced_scattering_per_mm(wavelength_nm):
    """sigma_s' = 14.74 lambda^-0.22 + 2.2e11 lambda^-4 (1/mm), Donner & Jensen 2006 (Mie + Rayleigh terms)."""
    wavelength = _wavelengths(wavelength_nm)
    return 14.74 * wavelength**-0.22 + 2.2e11 * wavelength**-4.0


def dermis_reduced_scattering_per_mm(wavelength_nm):
    """Half the epidermis's reduced scattering (Donner & Jensen 2006)."""
    return 0.5 * epidermis_reduced_scattering_per_mm(wavelength_nm)


def skin_layers(parameters: SkinParameters, wavelength_nm=DEFAULT_WAVELENGTHS_NM):
    """[epidermis slab, semi-infinite dermis] with coefficients over ``wavelength_nm`` ([dermis]
    alone when the epidermis is 0 mm thick)."""
    g, n = parameters.anisotropy, parameters.refractive_index
    epidermis = Medium.from_reduced(
        epidermis_absorption_per_mm(wavelength_nm, parameters.melanin_fraction, parameters.melanin_blend),
        epidermis_reduced_scattering_per_mm(wavelength_nm), g, n)
    dermis = Medium.from_reduced(
        dermis_absorption_per_mm(wavelength_nm, parameters.hemoglobin_fraction, parameters.oxygenation),
        dermis_reduced_scattering_per_mm(wavelength_nm), g, n)
    if parameters.epidermis_thickness_mm == 0.0:
        return [Layer(dermis, np.inf)]
    return [Layer(epidermis, parameters.epidermis_thickness_mm), Layer(dermis, np.inf)]


@lru_cache(maxsize=16)
def _spectrum_to_rgb_matrix(wavelengths: tuple, illuminant: str) -> np.ndarray:
    import colour

    wavelength = np.array(wavelengths)
    if wavelength.size > 1 and np.any(np.diff(wavelength) <= 0):
        raise DermisError("wavelengths must increase")
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    if illuminant not in colour.SDS_ILLUMINANTS:
        raise DermisError(f"unknown illuminant '{illuminant}' (try D65, D50, A, E)")
    light = colour.SDS_ILLUMINANTS[illuminant]
    matching = np.stack([np.interp(wavelength, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)])
    power = np.interp(wavelength, light.wavelengths, light.values)
    step = np.gradient(wavelength) if wavelength.size > 1 else np.ones(1)
    weights = matching * power * step  # (3, L): spectrum -> XYZ
    weights /= weights[1].sum()  # a perfect white reflector has Y = 1
    white_xyz = weights.sum(axis=1)
    white_xy = white_xyz[:2] / white_xyz.sum()
    # XYZ (relative to the illuminant's white) -> linear sRGB, adapting that white to D65
    xyz_to_rgb = colour.XYZ_to_RGB(np.eye(3), "sRGB", illuminant=white_xy,
                                   chromatic_adaptation_transform="CAT02", apply_cctf_encoding=False).T
    matrix = xyz_to_rgb @ weights  # (3, L)
    # The truncated sums leave a white of (1 +- 0.5 %): scale it to exactly (1, 1, 1)
    return matrix / matrix.sum(axis=1, keepdims=True)


def spectrum_to_linear_srgb_matrix(wavelength_nm=DEFAULT_WAVELENGTHS_NM, illuminant: str = "D65") -> np.ndarray:
    """(3, L) matrix M with rgb = M @ reflectance_spectrum (linear sRGB; a flat 1 maps to (1, 1, 1))."""
    return _spectrum_to_rgb_matrix(tuple(float(w) for w in np.atleast_1d(wavelength_nm)), str(illuminant))


def spectral_to_linear_srgb(spectral_values, wavelength_nm=DEFAULT_WAVELENGTHS_NM, illuminant: str = "D65"):
    """Linear sRGB of reflectance spectra along the LAST axis: (..., L) -> (..., 3)."""
    return np.asarray(spectral_values, dtype=np.float64) @ spectrum_to_linear_srgb_matrix(wavelength_nm, illuminant).T
