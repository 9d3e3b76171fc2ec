"""The classic dipole diffusion profile of a semi-infinite medium (Jensen, Marschner, Levoy &
Hanrahan 2001, "A Practical Model for Subsurface Light Transport", SIGGRAPH 2001).

A normally incident pencil beam is replaced by one isotropic point source at depth
z_r = 1/sigma_t' and a negative image at height z_v = z_r + 4 A D above the surface, so that the
fluence vanishes on the extrapolated boundary 2 A D above it. The profile R(r) (1/mm^2) is the
diffuse flux leaving the surface at distance r_mm from the entry point per unit power that
entered the medium. Accurate far from the source (r >> 1/sigma_t'); near it the dipole is off by
up to several times (see photon_beam_diffusion.py, which fixes that).
"""

from __future__ import annotations

import numpy as np

from dermis.profiles.fresnel import boundary_coefficient_a
from dermis.profiles.medium import Medium, squeeze_wavelengths


def dipole_source_depths_mm(medium: Medium, eta: float | None = None):
    """(z_r, z_v): real source depth and virtual source height (mm), Jensen et al. 2001."""
    eta = medium.n if eta is None else eta
    z_real = 1.0 / medium.reduced_sigma_t_per_mm
    z_virtual = z_real + 4.0 * boundary_coefficient_a(eta) * medium.diffusion_coefficient_mm
    return z_real, z_virtual


def dipole_reflectance(radius_mm, medium: Medium, eta: float | None = None) -> np.ndarray:
    """R(r) of the dipole, Jensen et al. 2001 (1/mm^2); shape r.shape (+ wavelengths).

    R(r) = alpha'/(4 pi) [ z_r (1 + sigma_tr d_r) e^(-sigma_tr d_r) / d_r^3
                         + z_v (1 + sigma_tr d_v) e^(-sigma_tr d_v) / d_v^3 ],
    d_r,v = sqrt(r^2 + z_r,v^2); eta = n_inside / n_outside (default: the medium's n against air).
    """
    r = np.asarray(radius_mm, dtype=np.float64)[..., None]
    z_real, z_virtual = dipole_source_depths_mm(medium, eta)
    sigma_tr = medium.sigma_tr_per_mm
    d_real = np.sqrt(r * r + z_real * z_real)
    d_virtual = np.sqrt(r * r + z_virtual * z_virtual)
    real = z_real * (1.0 + sigma_tr * d_real) * np.exp(-sigma_tr * d_real) / d_real**3
    virtual = z_virtual * (1.0 + sigma_tr * d_virtual) * np.exp(-sigma_tr * d_virtual) / d_virtual**3
    return squeeze_wavelengths(medium.reduced_albedo / (4.0 * np.pi) * (real + virtual), medium)


def dipole_total_reflectance(medium: Medium, eta: float | None = None) -> np.ndarray:
    """Total diffuse reflectance R_d = integral of R(r) over the plane, in closed form
    (Jensen et al. 2001):  R_d = alpha'/2 (1 + e^(-4/3 A sqrt(3(1 - alpha')))) e^(-sqrt(3(1 - alpha'))).
    """
    eta = medium.n if eta is None else eta
    alpha = medium.reduced_albedo
    root = np.sqrt(3.0 * (1.0 - alpha))
    a = boundary_coefficient_a(eta)
    total = 0.5 * alpha * (1.0 + np.exp(-4.0 / 3.0 * a * root)) * np.exp(-root)
    return squeeze_wavelengths(total, medium)


def dipole_reflectance_hankel(wavenumber_per_mm, medium: Medium, eta: float | None = None) -> np.ndarray:
    """The 2-D Fourier (zero-order Hankel) transform of the dipole profile, in closed form.

    F(k) = 2 pi integral_0^inf R(r) J0(k r) r dr. Each source term z (1 + s d) e^(-s d) / d^3 is
    -d/dz of e^(-s d)/d, whose transform is 2 pi e^(-|z| kappa) / kappa, kappa = sqrt(s^2 + k^2); so
    F(k) = alpha'/2 (e^(-z_r kappa) + e^(-z_v kappa)), and F(0) = R_d.
    """
    k = np.asarray(wavenumber_per_mm, dtype=np.float64)[..., None]
    z_real, z_virtual = dipole_source_depths_mm(medium, eta)
    kappa = np.sqrt(medium.sigma_tr_per_mm**2 + k * k)
    transform = 0.5 * medium.reduced_albedo * (np.exp(-z_real * kappa) + np.exp(-z_virtual * kappa))
    return squeeze_wavelengths(transform, medium)
