"""Christensen-Burley normalised diffusion (Christensen & Burley 2015, "Approximate Reflectance
Profiles for Efficient Subsurface Scattering", Pixar Technical Memo #15-04; Burley 2015).

An empirical profile: the sum of two exponentials, normalised so that its integral over the
plane is exactly the surface albedo A:

    R(r) = A s (e^(-s r / l) + e^(-s r / (3 l))) / (8 pi l r)          (1/mm^2)

with l the mean free path (mm) and s the scaling factor fitted to Monte Carlo for the
"diffuse surface transmission" configuration, s = 1.9 - A + 3.5 (A - 0.8)^2 (the memo's fit for that configuration).
Artists set A (colour) and l (scattering distance) directly; Unity HDRP, Unreal and Blender
ship it. It is singular (~1/r) at r = 0 but integrable. Its mean radius is 2.5 l / s, which
``burley_mean_free_path_for_mean_radius`` inverts to match another profile's width.
"""

from __future__ import annotations

import numpy as np

from dermis.errors import DermisError


def burley_scaling_factor(albedo) -> np.ndarray:
    """s(A) = 1.9 - A + 3.5 (A - 0.8)^2 (Christensen & Burley 2015, diffuse surface transmission fit)."""
    a = np.asarray(albedo, dtype=np.float64)
    return 1.9 - a + 3.5 * (a - 0.8) ** 2


def burley_reflectance(radius_mm, albedo, mean_free_path_mm) -> np.ndarray:
    """R(r) = A s (e^(-s r/l) + e^(-s r/3l)) / (8 pi l r); albedo and l broadcast (e.g. RGB)."""
    a = np.asarray(albedo, dtype=np.float64)
    length = np.asarray(mean_free_path_mm, dtype=np.float64)
    if np.any(a < 0) or np.any(a > 1):
        raise DermisError("Burley albedo must lie in [0, 1]")
    if np.any(length <= 0):
        raise DermisError("Burley mean free path must be > 0 mm")
    r = np.asarray(radius_mm, dtype=np.float64)[..., None] if a.ndim or length.ndim else np.asarray(radius_mm, float)
    s = burley_scaling_factor(a)
    with np.errstate(divide="ignore"):
        return a * s * (np.exp(-s * r / length) + np.exp(-s * r / (3.0 * length))) / (8.0 * np.pi * length * r)


def burley_mean_radius_mm(albedo, mean_free_path_mm) -> np.ndarray:
    """integral 2 pi r^2 R dr / integral 2 pi r R dr = 2.5 l / s (closed form)."""
    return 2.5 * np.asarray(mean_free_path_mm, dtype=np.float64) / burley_scaling_factor(albedo)


def burley_mean_free_path_for_mean_radius(albedo, mean_radius_mm) -> np.ndarray:
    """The l whose Burley profile has the given mean radius: l = s mean_r / 2.5."""
    return burley_scaling_factor(albedo) * np.asarray(mean_radius_mm, dtype=np.float64) / 2.5
