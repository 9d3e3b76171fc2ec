"""Measured reflectance of real skin, and the model's reflectance in the same measurand.

Two sources, both spectra (reflectance factor, 0..1, over wavelength in nm):

* The ColorChecker's "dark skin" and "light skin" patches (McCamy, Marcus & Davidson 1976,
  designed to match dark and light human skin), the spectra of N. Ohta's measurement shipped with
  colour-science (``colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]``). The chart is matte:
  its reflectance is the body (subsurface) reflectance only.
* The NIST reference data set of human skin reflectance (Cooksey, Allen & Tsai 2017,
  data/nist_skin_reflectance_ita.csv): 100 forearms grouped by Individual Typology Angle into
  the skin-colour categories of Del Bino et al. 2006 (very light, light, intermediate, tan,
  brown). Measured in an integrating sphere with the specular reflection included.

A dermis profile's total diffuse reflectance R_d is per unit power ENTERING the skin. Light
falling on skin at normal incidence loses the Fresnel fraction F0 = ((n - 1) / (n + 1))^2
(0.028 for n = 1.4) at the surface, so in these measurands the model reflects

    body reflectance (ColorChecker)          (1 - F0) R_d
    total, specular included (NIST)          F0 + (1 - F0) R_d
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.spectral import DEFAULT_WAVELENGTHS_NM, spectral_to_linear_srgb

NIST_CATEGORIES = ("very_light", "light", "intermediate", "tan", "brown")
COLORCHECKER_PATCHES = ("dark skin", "light skin")
NIST_CITATION = ("Cooksey, Allen & Tsai 2017, Reference Data Set of Human Skin Reflectance, J. Res. NIST 122:26, "
                 "doi:10.18434/M38597")
COLORCHECKER_CITATION = "ColorChecker (McCamy et al. 1976), N. Ohta's spectra via colour-science"


@dataclass(frozen=True, eq=False)
class MeasuredSkin:
    """A measured skin reflectance spectrum. ``specular_included``: the measurement holds the
    surface (Fresnel) reflection too; ``spread``: one standard deviation among subjects, or None."""

    name: str
    wavelength_nm: np.ndarray
    reflectance: np.ndarray
    specular_included: bool
    source: str
    spread: np.ndarray | None = None

    def at(self, wavelength_nm=DEFAULT_WAVELENGTHS_NM) -> np.ndarray:
        """The reflectance at ``wavelength_nm`` (linear interpolation)."""
        wavelength = np.asarray(wavelength_nm, dtype=np.float64)
        if wavelength.min() < self.wavelength_nm[0] or wavelength.max() > self.wavelength_nm[-1]:
            raise DermisError(f"measured skin '{self.name}' covers {self.wavelength_nm[0]:g}-"
                              f"{self.wavelength_nm[-1]:g} nm only")
        return np.interp(wavelength, self.wavelength_nm, self.reflectance)

    def linear_srgb(self, wavelength_nm=DEFAULT_WAVELENGTHS_NM, illuminant: str = "D65") -> np.ndarray:
        """Its colour in linear sRGB (the same integration as the model's, spectral.py)."""
        return spectral_to_linear_srgb(self.at(wavelength_nm), wavelength_nm, illuminant)

    def individual_typology_angle(self) -> float:
        """ITA = atan((L* - 50) / b*) in degrees (Chardon et al. 1991), CIELAB under D65 and the
        CIE 1931 2 deg observer: the skin-colour classification of the NIST table (> 55 very
        light, 41-55 light, 28-41 intermediate, 10-28 tan, -30-10 brown, < -30 dark; Del Bino et
        al. 2006), computed as benchmarks/derive_nist_skin_table.py classes the NIST subjects."""
        import colour

        cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
        white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
        sd = colour.SpectralDistribution(dict(zip(self.wavelength_nm, self.reflectance)))
        lab = colour.XYZ_to_Lab(colour.sd_to_XYZ(sd, cmfs, colour.SDS_ILLUMINANTS["D65"]) / 100.0, white)
        return float(np.degrees(np.arctan2(lab[0] - 50.0, lab[2])))


@lru_cache(maxsize=1)
def _nist_table():
    text = resources.files("dermis.data").joinpath("nist_skin_reflectance_ita.csv").read_text()
    rows = [line for line in text.splitlines() if line and not line.startswith("#")]
    header = rows[0].split(",")
    data = np.array([[float(v) for v in row.split(",")] for row in rows[1:]])
    return header, data


def nist_skin(category: str) -> MeasuredSkin:
    """The mean NIST forearm spectrum of an ITA skin-colour category (see NIST_CATEGORIES)."""
    key = str(category).strip().lower().replace("-", "_").replace(" ", "_")
    if key not in NIST_CATEGORIES:
        raise DermisError(f"unknown NIST skin category '{category}' (known: {', '.join(NIST_CATEGORIES)})")
    header, data = _nist_table()
    mean, spread = header.index(f"{key}_mean"), header.index(f"{key}_sd")
    return MeasuredSkin(f"NIST {key.replace('_', ' ')}", data[:, 0], data[:, mean], True, NIST_CITATION,
                        data[:, spread])


def colorchecker_skin(patch: str) -> MeasuredSkin:
    """The ColorChecker's 'dark skin' or 'light skin' patch (body reflectance only)."""
    import colour

    key = str(patch).strip().lower().replace("_", " ").replace("-", " ")
    if key not in COLORCHECKER_PATCHES:
        raise DermisError(f"unknown ColorChecker skin patch '{patch}' (known: {', '.join(COLORCHECKER_PATCHES)})")
    sd = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][key]
    return MeasuredSkin(f"ColorChecker {key}", np.asarray(sd.wavelengths, float), np.asarray(sd.values, float),
                        False, COLORCHECKER_CITATION)


def normal_incidence_fresnel(n: float) -> float:
    """F0 = ((n - 1) / (n + 1))^2, the specular reflectance of a smooth surface at normal incidence."""
    return float(((n - 1.0) / (n + 1.0)) ** 2)


def model_measurand(total_reflectance, refractive_index: float, specular_included: bool) -> np.ndarray:
    """A model's R_d (per unit power entering the skin) as the measured quantity (module docstring)."""
    f0 = normal_incidence_fresnel(refractive_index)
    body = (1.0 - f0) * np.asarray(total_reflectance, dtype=np.float64)
    return body + f0 if specular_included else body


def measured_counterpart(preset: str) -> MeasuredSkin | None:
    """The measured skin a spectral preset was fitted to (presets.MEASURED_COUNTERPARTS), or None."""
    from dermis.profiles.presets import MEASURED_COUNTERPARTS

    entry = MEASURED_COUNTERPARTS.get(str(preset).strip().lower())
    if entry is None:
        return None
    source, name = entry
    return colorchecker_skin(name) if source == "colorchecker" else nist_skin(name)


def measured_for_plot(preset: str | None) -> list[MeasuredSkin]:
    """A preset's counterpart; for anything else every measured spectrum shipped."""
    counterpart = measured_counterpart(preset) if preset else None
    if counterpart is not None:
        return [counterpart]
    return [colorchecker_skin(p) for p in COLORCHECKER_PATCHES] + [nist_skin(c) for c in NIST_CATEGORIES]
