"""A light's colour temperature -> the linear RGB colour the renderer takes.

Method (CIE 15:2004, sections 7.1 and 7.2): the spectral radiance of a Planckian (blackbody)
radiator at T kelvin, Planck's law with c2 = 1.4388e-2 m K, weighted by the CIE 1931 2-degree
colour-matching functions at 1 nm from 360 to 830 nm gives XYZ; that is scaled to luminance
Y = 1 and taken to linear sRGB / Rec. 709 primaries (D65 white) by the IEC 61966-2-1 matrix.
The spectral data and the integration are colour-science's (``colour.sd_blackbody``,
``colour.sd_to_XYZ``). No white balance is applied: a 6504 K blackbody is close to, not exactly,
the renderer's white (D65 lies slightly off the Planckian locus); 2856 K reproduces CIE
illuminant A's chromaticity (x, y) = (0.4476, 0.4074).

Below about 1900 K the blackbody lies outside the sRGB gamut (blue < 0): the negative component
is clipped to 0 and the colour rescaled to Y = 1, so the light's ``intensity`` keeps its meaning
(the luminance of ``color * intensity``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from dermis.errors import DermisError

MIN_K, MAX_K = 1000.0, 40000.0
# Rec. 709 luminance: the Y row of the sRGB RGB -> XYZ matrix (IEC 61966-2-1)
LUMINANCE_RGB = np.array([0.2126, 0.7152, 0.0722])


@lru_cache(maxsize=1)
def _tables():
    import colour

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return cmfs, np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB, np.float64)


def blackbody_xy(temperature_k: float) -> np.ndarray:
    """CIE 1931 chromaticity (x, y) of a blackbody at ``temperature_k`` kelvin."""
    import colour

    t = _check(temperature_k)
    cmfs, _ = _tables()
    xyz = colour.sd_to_XYZ(colour.sd_blackbody(t, cmfs.shape), cmfs)
    return np.asarray(xyz[:2] / np.sum(xyz), np.float64)


@lru_cache(maxsize=4096)
def blackbody_rgb(temperature_k: float) -> tuple[float, float, float]:
    """Linear sRGB (Rec. 709 primaries) of a blackbody at ``temperature_k``, luminance Y = 1."""
    x, y = blackbody_xy(temperature_k)
    xyz = np.array([x / y, 1.0, (1.0 - x - y) / y])
    _, to_rgb = _tables()
    rgb = np.maximum(to_rgb @ xyz, 0.0)
    rgb = rgb / float(LUMINANCE_RGB @ rgb)
    return tuple(float(c) for c in rgb)


def _check(temperature_k) -> float:
    t = float(temperature_k)
    if not MIN_K <= t <= MAX_K:
        raise DermisError(f"lights.temperature_k must be in [{MIN_K:.0f}, {MAX_K:.0f}] K, got {temperature_k}")
    return t
