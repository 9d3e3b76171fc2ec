"""The multipole diffusion model of a finite slab (Donner & Jensen 2005, "Light Diffusion in
Multi-Layered Translucent Materials", SIGGRAPH 2005, section 3).

A slab d_mm thick has two boundaries; the fluence must vanish on both extrapolated boundaries,
z_b = 2 A D above the top and below the bottom. One dipole cannot do that, so the dipole is
mirrored about both extrapolated boundaries again and again: for i = -n..n

    z_r,i = 2 i (d + 2 z_b) + l,        z_v,i = 2 i (d + 2 z_b) - l - 2 z_b,       l = 1 / sigma_t'

(positions measured downwards from the top surface; real sources positive, virtual negative).
The reflectance sums the flux of every pole through the top surface, the transmittance through
the bottom one (Donner & Jensen 2005, section 3):

    R(r) = alpha'/(4 pi) sum_i [ z_r,i (1 + sigma_tr d_r,i) e^(-sigma_tr d_r,i) / d_r,i^3
                               - z_v,i (1 + sigma_tr d_v,i) e^(-sigma_tr d_v,i) / d_v,i^3 ]
    T(r) = the same with (d - z) in place of z and d_{r,v},i = sqrt(r^2 + (d - z_{r,v},i)^2).

Here the two boundaries may differ (top: skin against air, eta = 1.4; bottom: epidermis against
dermis, index-matched, A = 1): with z_b,top and z_b,bottom the period is 2 (d + z_b,top + z_b,bottom).
With n = 0 this is the classic dipole applied to the slab (its lower boundary ignored); as
d -> infinity it converges to the dipole of dipole.py. Profiles in 1/mm^2 per unit power entering.
"""

from __future__ import annotations

import numpy as np

from dermis.profiles.fresnel import boundary_coefficient_a
from dermis.profiles.medium import Medium, squeeze_wavelengths


def image_source_positions(source_depth_mm, thickness_mm: float, extrapolation_top_mm, extrapolation_bottom_mm,
                           pair_count: int):
    """Signed depths (mm) and charges (+1 real, -1 virtual) of the multipole of one point source.

    ``source_depth_mm`` broadcasts against the extrapolation distances (one per wavelength); the
    poles form a new LAST axis. A semi-infinite slab (thickness inf) has one dipole.
    """
    z0 = np.asarray(source_depth_mm, dtype=np.float64)
    z_top = np.asarray(extrapolation_top_mm, dtype=np.float64)
    mirrored = -2.0 * z_top - z0  # mirror image about the extrapolated top boundary, z = -z_b,top
    if np.isinf(thickness_mm):
        positions = np.stack(np.broadcast_arrays(z0, mirrored), axis=-1)
        return positions, np.array([1.0, -1.0])
    period = 2.0 * (thickness_mm + z_top + np.asarray(extrapolation_bottom_mm, dtype=np.float64))
    poles, charges = [], []
    for i in range(-pair_count, pair_count + 1):
        poles += [z0 + i * period, mirrored + i * period]
        charges += [1.0, -1.0]
    return np.stack(np.broadcast_arrays(*poles), axis=-1), np.array(charges)


def plane_flux_and_fluence(radius_mm, plane_depth_mm: float, pole_depths_mm, charges, sigma_tr_per_mm):
    """Outward diffuse flux  -D dphi/dn  and fluence-times-D  D phi  of unit point sources on a plane.

    For a pole at signed depth z, at horizontal distance r from it on the plane z = z_plane:
    flux = (1/4 pi) s (1 + sigma_tr rho) e^(-sigma_tr rho) / rho^3 with s = z (top plane,
    outward = up) or s = z_plane - z (lower plane, outward = down), and
    D phi = (1/4 pi) e^(-sigma_tr rho) / rho, rho = sqrt(r^2 + s^2) (Farrell, Patterson & Wilson 1992).

    ``radius_mm``: (N,); ``pole_depths_mm``: (..., L, M); returns (..., N, L) arrays.
    """
    r = np.asarray(radius_mm, dtype=np.float64)[:, None]  # (N, 1)
    poles = np.asarray(pole_depths_mm, dtype=np.float64)
    flux = 0.0
    fluence_d = 0.0
    for m, charge in enumerate(charges):
        s = poles[..., m]  # (..., L)
        s = s if plane_depth_mm == 0.0 else plane_depth_mm - s
        s = s[..., None, :]  # (..., 1, L)
        rho = np.sqrt(r * r + s * s)
        decay = np.exp(-sigma_tr_per_mm * rho) / rho
        flux = flux + charge * s * (1.0 + sigma_tr_per_mm * rho) * decay / (rho * rho)
        fluence_d = fluence_d + charge * decay
    return flux / (4.0 * np.pi), fluence_d / (4.0 * np.pi)


def default_pair_count(thickness_mm: float, sigma_tr_per_mm, extrapolation_top_mm, extrapolation_bottom_mm) -> int:
    """Enough pole pairs that the omitted ones are attenuated by e^-12 or more (cap 40)."""
    if np.isinf(thickness_mm):
        return 0
    period = 2.0 * (thickness_mm + np.max(extrapolation_top_mm) + np.max(extrapolation_bottom_mm))
    sigma = max(float(np.min(sigma_tr_per_mm)), 1e-6)
    return int(np.clip(np.ceil(12.0 / (sigma * period)), 3, 40))


def multipole_profiles(radius_mm, medium: Medium, thickness_mm: float, eta_top: float | None = None,
                       eta_bottom: float | None = None, pair_count: int | None = None, from_below: bool = False):
    """(R(r), T(r)) of a slab, Donner & Jensen 2005 (1/mm^2; shape r.shape (+ wavelengths)).

    ``eta_top``/``eta_bottom``: n_slab / n_neighbour at each boundary (default: the slab's n against
    air). ``from_below``: light enters through the BOTTOM boundary (source l above it); R is then
    the flux back out of the bottom and T the flux out of the top. ``pair_count``: n of the sum
    (0 = the dipole of the slab's entry boundary; default: converged, see default_pair_count).
    """
    radius = np.asarray(radius_mm, dtype=np.float64)
    eta_top = medium.n if eta_top is None else eta_top
    eta_bottom = medium.n if eta_bottom is None else eta_bottom
    diffusion = medium.diffusion_coefficient_mm
    sigma_tr = medium.sigma_tr_per_mm
    extrapolation_top = 2.0 * boundary_coefficient_a(eta_top) * diffusion
    extrapolation_bottom = 2.0 * boundary_coefficient_a(eta_bottom) * diffusion
    mean_free_path = 1.0 / medium.reduced_sigma_t_per_mm
    if np.isinf(thickness_mm):
        if from_below:
            raise ValueError("a semi-infinite slab has no lower boundary to enter through")
        source_depth = mean_free_path
    else:
        # A slab thinner than two transport mean free paths: keep the pole at mid-depth. A pole ON
        # a boundary (depth = thickness) has no flux through it (s = 0): T collapsed to ~0.3 of
        # the Monte Carlo's for a 0.1 mm epidermis and T from below turned negative
        depth = np.minimum(mean_free_path, 0.5 * thickness_mm)
        source_depth = thickness_mm - depth if from_below else depth
    if pair_count is None:
        pair_count = default_pair_count(thickness_mm, sigma_tr, extrapolation_top, extrapolation_bottom)
    poles, charges = image_source_positions(source_depth, thickness_mm, extrapolation_top,
                                            extrapolation_bottom, pair_count)
    flux_top, _ = plane_flux_and_fluence(radius.reshape(-1), 0.0, poles, charges, sigma_tr)
    if np.isinf(thickness_mm):
        flux_bottom = np.zeros_like(flux_top)
    else:
        flux_bottom, _ = plane_flux_and_fluence(radius.reshape(-1), thickness_mm, poles, charges, sigma_tr)
    alpha = medium.reduced_albedo
    reflectance, transmittance = (flux_bottom, flux_top) if from_below else (flux_top, flux_bottom)
    shape = radius.shape + (medium.wavelength_count,)
    return (squeeze_wavelengths((alpha * reflectance).reshape(shape), medium),
            squeeze_wavelengths((alpha * transmittance).reshape(shape), medium))
