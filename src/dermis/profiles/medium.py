"""Homogeneous scattering media and the layers of a layered medium.

Coefficients are in 1/mm and may be scalars or 1-D arrays over wavelength (all profile functions
then return one column per wavelength). Notation of docs/skin-rendering.md section 2:

    sigma_s' = sigma_s (1 - g)              reduced scattering coefficient
    sigma_t' = sigma_a + sigma_s'           reduced extinction coefficient
    alpha'   = sigma_s' / sigma_t'          reduced albedo
    sigma_tr = sqrt(3 sigma_a sigma_t')     effective transport coefficient
    D        = 1 / (3 sigma_t')             diffusion coefficient (mm)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dermis.errors import DermisError


def _coefficient(value, name: str) -> np.ndarray:
    array = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if array.ndim != 1 or array.size == 0:
        raise DermisError(f"{name} must be a number or a 1-D array over wavelength")
    if not np.all(np.isfinite(array)) or np.any(array < 0):
        raise DermisError(f"{name} must be finite and >= 0 1/mm")
    return array


@dataclass(frozen=True, eq=False)
class Medium:
    """A homogeneous medium: absorption and scattering coefficients (1/mm), Henyey-Greenstein
    anisotropy ``g`` and absolute refractive index ``n``."""

    sigma_a_per_mm: np.ndarray
    sigma_s_per_mm: np.ndarray
    g: float = 0.0
    n: float = 1.4

    def __post_init__(self):
        sigma_a = _coefficient(self.sigma_a_per_mm, "sigma_a")
        sigma_s = _coefficient(self.sigma_s_per_mm, "sigma_s")
        try:
            sigma_a, sigma_s = np.broadcast_arrays(sigma_a, sigma_s)
        except ValueError:
            raise DermisError("sigma_a and sigma_s must have the same number of wavelengths") from None
        if np.any(sigma_a + sigma_s * (1.0 - self.g) <= 0):
            raise DermisError("a medium needs sigma_a + sigma_s' > 0 1/mm")
        if not -1.0 < float(self.g) < 1.0:
            raise DermisError(f"anisotropy g must lie in (-1, 1), got {self.g}")
        if not (np.isfinite(self.n) and self.n > 0):
            raise DermisError(f"refractive index must be > 0, got {self.n}")
        object.__setattr__(self, "sigma_a_per_mm", sigma_a.copy())
        object.__setattr__(self, "sigma_s_per_mm", sigma_s.copy())
        object.__setattr__(self, "g", float(self.g))
        object.__setattr__(self, "n", float(self.n))

    @classmethod
    def from_reduced(cls, sigma_a_per_mm, reduced_sigma_s_per_mm, g: float = 0.0, n: float = 1.4) -> "Medium":
        """A medium given sigma_s' (what diffusion models see); sigma_s = sigma_s' / (1 - g)."""
        return cls(sigma_a_per_mm, np.asarray(reduced_sigma_s_per_mm, dtype=np.float64) / (1.0 - g), g, n)

    @property
    def wavelength_count(self) -> int:
        return int(self.sigma_a_per_mm.size)

    @property
    def sigma_t_per_mm(self) -> np.ndarray:
        return self.sigma_a_per_mm + self.sigma_s_per_mm

    @property
    def reduced_sigma_s_per_mm(self) -> np.ndarray:
        return self.sigma_s_per_mm * (1.0 - self.g)

    @property
    def reduced_sigma_t_per_mm(self) -> np.ndarray:
        return self.sigma_a_per_mm + self.reduced_sigma_s_per_mm

    @property
    def reduced_albedo(self) -> np.ndarray:
        return self.reduced_sigma_s_per_mm / self.reduced_sigma_t_per_mm

    @property
    def sigma_tr_per_mm(self) -> np.ndarray:
        return np.sqrt(3.0 * self.sigma_a_per_mm * self.reduced_sigma_t_per_mm)

    @property
    def diffusion_coefficient_mm(self) -> np.ndarray:
        return 1.0 / (3.0 * self.reduced_sigma_t_per_mm)

    def select(self, index) -> "Medium":
        """The medium at some wavelengths only."""
        return Medium(self.sigma_a_per_mm[index], self.sigma_s_per_mm[index], self.g, self.n)


@dataclass(frozen=True, eq=False)
class Layer:
    """A slab of ``medium`` ``thickness_mm`` thick (``np.inf``: semi-infinite)."""

    medium: Medium
    thickness_mm: float

    def __post_init__(self):
        thickness = float(self.thickness_mm)
        if not thickness > 0 or np.isnan(thickness):
            raise DermisError(f"layer thickness must be > 0 mm, got {self.thickness_mm}")
        object.__setattr__(self, "thickness_mm", thickness)

    @property
    def semi_infinite(self) -> bool:
        return bool(np.isinf(self.thickness_mm))


def relative_index(n_inside: float, n_outside: float) -> float:
    """eta = n_inside / n_outside of a boundary."""
    return float(n_inside) / float(n_outside)


def squeeze_wavelengths(values: np.ndarray, medium_or_count) -> np.ndarray:
    """Drop the trailing wavelength axis when the medium had scalar coefficients."""
    count = medium_or_count if isinstance(medium_or_count, int) else medium_or_count.wavelength_count
    return values[..., 0] if count == 1 else values
