"""Light through a thin slab of the medium a diffusion profile describes (issue 12: the back-lit
ear, the nose wing).

d'Eon & Luebke's transmittance (GPU Gems 3, 14.5.3) carries the far face's irradiance through d mm
as sum_k w_k exp(-d^2 / 2 v_k): the semi-infinite profile at 3-D distance d. That is the light a
SEMI-INFINITE medium lets out at distance d; a slab lets out far more, because what would wander
deeper is turned back by the slab's own back face instead of being absorbed: against the Monte
Carlo of the same medium it is 1.7x low through 2 mm and 2.8x through 5 mm in red
(tests/test_slab_theory.py), and against Cycles' random walk on a back-lit slab 2.6x and 5x
(benchmarks/RESULTS.md, "Ears (round 5)").

Here the slab is solved instead, with diffusion theory in one dimension (the slab's total
transmittance under uniform illumination, so lateral transport is integrated; the renderers take
the lateral spread from the profile's blurred irradiance):
  - a unit isotropic source at depth z_0 = 1 / sigma_t' (Jensen et al. 2001), of strength alpha'
    (the scattered fraction of the light that entered);
  - fluence zero on the extrapolated boundaries z_b = 2 A D outside each face (A = 3.25 at
    eta = 1.4, D = 1 / (3 sigma_t')): the power leaving through the far boundary is
        T(d) = alpha' sinh(kappa (z_0 + z_b)) / sinh(kappa (d + 2 z_b)),   kappa = sigma_tr,
    and through the near one R(d) = alpha' sinh(kappa (d + z_b - z_0)) / sinh(kappa (d + 2 z_b))
    (the 1-D Green's function of phi'' = kappa^2 phi between absorbing boundaries);
  - alpha' such that the semi-infinite R (d -> inf: alpha' exp(-kappa (z_0 + z_b))) equals the
    skin's albedo A_c per channel, and sigma_t' such that the dipole profile of that medium
    (Jensen et al. 2001) has the profile's mean exit radius: the medium the profile describes.
The medium is scale-invariant: alpha' depends on the albedo only and all lengths scale with the
profile's mean radius. Units: mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dermis.numpy_compat import trapezoid
from dermis.profiles.fresnel import boundary_coefficient_a

ETA = 1.4  # skin against air (both faces of the slab)


@dataclass(frozen=True)
class SlabLaw:
    """Per channel (3,): the medium and the slab transmittance's closed form's constants."""

    reduced_albedo: np.ndarray  # alpha'
    reduced_sigma_t_per_mm: np.ndarray  # sigma_t' (1/mm); isotropic: the mean free path is its inverse
    kappa_per_mm: np.ndarray  # sigma_tr = sqrt(3 sigma_a sigma_t')
    source_depth_mm: np.ndarray  # z_0 = 1 / sigma_t'
    extrapolation_mm: np.ndarray  # z_b = 2 A D

    def transmittance(self, thickness_mm) -> np.ndarray:
        """(..., 3) total transmittance T(d) per unit power entering the far face."""
        d = np.asarray(thickness_mm, np.float64)[..., None]
        k, z0, zb = self.kappa_per_mm, self.source_depth_mm, self.extrapolation_mm
        z0 = np.minimum(z0, d)  # a slab thinner than z_0: the source sits at its far face
        return self.reduced_albedo * _sinh_ratio(k * (z0 + zb), k * (d + 2.0 * zb))

    def transmitted_variance(self, thickness_mm) -> np.ndarray:
        """(..., 3) per-axis variance (mm^2) of where the light leaving the far face of a slab
        ``thickness_mm`` thick left it, about the point it entered: the law's transform across the
        faces, T(q) = alpha' sinh(k_q a) / sinh(k_q b) with k_q = sqrt(kappa^2 + q^2), a = z_0 + z_b,
        b = d + 2 z_b, has -d^2 ln T / dq^2 = [b coth(kappa b) - a coth(kappa a)] / kappa at q = 0.
        1.2-1.4x the slab's Monte Carlo from 2 mm on, 2.8x at 0.5 mm (benchmarks/RESULTS.md, round 7).
        common/thin_slab.glsl's slab_transmitted_variance."""
        d = np.asarray(thickness_mm, np.float64)[..., None]
        k, zb = self.kappa_per_mm, self.extrapolation_mm
        a = np.minimum(self.source_depth_mm, d) + zb
        b = d + 2.0 * zb
        return (b / np.tanh(k * b) - a / np.tanh(k * a)) / k

    def reflectance(self, thickness_mm) -> np.ndarray:
        """(..., 3) total reflectance R(d) of the lit face (semi-infinite limit: the albedo)."""
        d = np.asarray(thickness_mm, np.float64)[..., None]
        k, z0, zb = self.kappa_per_mm, self.source_depth_mm, self.extrapolation_mm
        z0 = np.minimum(z0, d)
        return self.reduced_albedo * _sinh_ratio(k * (d + zb - z0), k * (d + 2.0 * zb))


def _sinh_ratio(a, b):
    """sinh(a) / sinh(b) for 0 <= a <= b without overflow: e^(a - b) (1 - e^(-2a)) / (1 - e^(-2b))."""
    return np.exp(a - b) * -np.expm1(-2.0 * a) / np.maximum(-np.expm1(-2.0 * b), 1e-300)


def _semi_infinite_reflectance(alpha):
    """The 1-D model's R(inf) = alpha' exp(-sqrt(3 (1 - alpha')) (1 + 2 A / 3)) (kappa z_0 = sqrt(3(1 - alpha')))."""
    return alpha * np.exp(-np.sqrt(3.0 * (1.0 - alpha)) * (1.0 + 2.0 * boundary_coefficient_a(ETA) / 3.0))


def reduced_albedo_for(albedo) -> np.ndarray:
    """alpha' whose semi-infinite slab reflects ``albedo`` (per channel, bisection; R(inf) rises with alpha')."""
    target = np.clip(np.asarray(albedo, np.float64), 1e-4, 0.999)
    lo, hi = np.zeros_like(target), np.ones_like(target)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        low = _semi_infinite_reflectance(mid) < target
        lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
    return 0.5 * (lo + hi)


def _dipole_mean_radius(alpha):
    """Mean exit radius of the dipole profile (dermis.profiles.dipole, Jensen et al. 2001) of the
    medium with reduced albedo ``alpha`` at sigma_t' = 1 (so in mean free paths)."""
    from dermis.profiles.dipole import dipole_reflectance
    from dermis.profiles.medium import Medium

    a = np.atleast_1d(np.asarray(alpha, np.float64))
    r = np.geomspace(1e-4, 400.0, 20_000)
    ring = dipole_reflectance(r, Medium(1.0 - a, a, 0.0, ETA)).reshape(len(r), -1) * r[:, None]  # R(r) r
    return (trapezoid(ring * r[:, None], r, axis=0) / trapezoid(ring, r, axis=0)).reshape(np.shape(alpha))


def profile_mean_radius_mm(profile) -> np.ndarray:
    """(3,) mean exit radius of a sum of 2-D Gaussians: sum_k w_k sqrt(pi v_k / 2) / sum_k w_k."""
    w = np.asarray(profile.weights, np.float64)
    s = np.sqrt(np.pi * np.asarray(profile.variances_mm2, np.float64) / 2.0)[:, None]
    return (w * s).sum(0) / np.maximum(w.sum(0), 1e-300)


def slab_law(profile, albedo) -> SlabLaw:
    """The thin-slab law of the medium that reflects ``albedo`` (3,) with ``profile``'s width."""
    alpha = reduced_albedo_for(albedo)
    st = _dipole_mean_radius(alpha) / np.maximum(profile_mean_radius_mm(profile), 1e-9)
    kappa = np.sqrt(3.0 * (1.0 - alpha)) * st
    return SlabLaw(reduced_albedo=alpha, reduced_sigma_t_per_mm=st, kappa_per_mm=kappa,
                   source_depth_mm=1.0 / st, extrapolation_mm=2.0 * boundary_coefficient_a(ETA) / (3.0 * st))
