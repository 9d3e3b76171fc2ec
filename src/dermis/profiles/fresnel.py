"""Fresnel reflectance at a smooth dielectric boundary, and its hemispherical averages.

Used by every diffusion model for its boundary condition and by the Monte Carlo reference for
its exact boundary crossings. ``eta`` is always n_inside / n_outside of the scattering medium
(skin against air: eta = 1.4).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np


def fresnel_dielectric(cos_theta_incident, n_incident: float, n_transmitted: float):
    """Unpolarised Fresnel reflectance of a smooth boundary (Born & Wolf, Principles of Optics §1.5).

    Light travels in the medium of index ``n_incident`` and meets the boundary at
    cos(theta_i) = ``cos_theta_incident`` (>= 0). Returns 1 beyond the critical angle.
    """
    cos_i = np.clip(np.asarray(cos_theta_incident, dtype=np.float64), 0.0, 1.0)
    sin_t = (n_incident / n_transmitted) * np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i))
    total_internal = sin_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t * sin_t))
    with np.errstate(invalid="ignore", divide="ignore"):
        r_s = (n_incident * cos_i - n_transmitted * cos_t) / (n_incident * cos_i + n_transmitted * cos_t)
        r_p = (n_incident * cos_t - n_transmitted * cos_i) / (n_incident * cos_t + n_transmitted * cos_i)
        reflectance = 0.5 * (r_s * r_s + r_p * r_p)
    return np.where(total_internal, 1.0, np.nan_to_num(reflectance, nan=1.0))


def diffuse_fresnel_reflectance(eta: float) -> float:
    """F_dr(eta): the rational fit of Egan & Hilgeman 1973 used by Jensen et al. 2001.

    The internal diffuse reflectance of a boundary with relative index eta = n_inside/n_outside.
    An index-matched boundary (eta = 1) reflects nothing.
    """
    eta = float(eta)
    if eta == 1.0:
        return 0.0
    if eta > 1.0:
        return -1.4399 / eta**2 + 0.7099 / eta + 0.6681 + 0.0636 * eta
    return -0.4399 + 0.7099 / eta - 0.3319 / eta**2 + 0.0636 / eta**3


def boundary_coefficient_a(eta: float) -> float:
    """A = (1 + F_dr) / (1 - F_dr) (Jensen et al. 2001): 3.251 at eta = 1.4, 1 when matched."""
    f_dr = diffuse_fresnel_reflectance(eta)
    return (1.0 + f_dr) / (1.0 - f_dr)


@lru_cache(maxsize=64)
def fresnel_moment(eta: float, order: int) -> float:
    """Fresnel moment  F_i(eta) = integral_0^1 F_r(mu) mu^i d mu  for light INSIDE the medium.

    pbrt-v3 §11.4.4 (FresnelMoment1, FresnelMoment2) tabulates polynomial fits of the same
    integral; here it is evaluated by Gauss-Legendre quadrature of the exact unpolarised
    Fresnel reflectance, split at the critical angle (beyond it F_r = 1). 2 F_1 is the internal
    diffuse reflectance F_dr.
    """
    eta = float(eta)
    if eta == 1.0:
        return 0.0
    nodes, weights = np.polynomial.legendre.leggauss(128)

    def integrate(a, b):
        mu = 0.5 * (b - a) * nodes + 0.5 * (a + b)
        f = fresnel_dielectric(mu, eta, 1.0) * mu**order
        return 0.5 * (b - a) * float(np.dot(weights, f))

    if eta > 1.0:
        mu_critical = np.sqrt(1.0 - 1.0 / eta**2)
        below = mu_critical ** (order + 1) / (order + 1)  # total internal reflection: F_r = 1
        return below + integrate(mu_critical, 1.0)
    return integrate(0.0, 1.0)
