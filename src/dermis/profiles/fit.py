"""Fitting a sum of Gaussians to a radial RGB profile (d'Eon, Luebke & Enderton 2007, GPU Gems 3
ch. 14.4.2; docs/skin-rendering.md section 2).

The renderer blurs once per Gaussian for all three channels, so the K variances are SHARED by
red, green and blue; only the weights are per channel, and they must be >= 0. For given
variances the weights are a linear non-negative least-squares problem per channel (scipy NNLS);
the variances themselves (log-parametrised) are optimised by Nelder-Mead on the summed squared
errors ("variable projection"), starting from geometric series.

Error: the r-weighted relative L2 error of each channel (as the integral over the plane is),
sqrt( integral r (fit - R)^2 dr / integral r R^2 dr ), on a uniform radius grid of ``points``
midpoints from 0 to r_max (the radius holding 99.9 % of every channel's energy, times 1.5,
clamped to [4, 60] mm). By default the weights are also held (softly, to ~1e-4) to sum to the
profile's total diffuse reflectance (an extra least-squares row), so a fit keeps the skin's
colour. Variances are kept between (grid step / 2)^2 and (r_99.9 / 2)^2, r_99.9 the radius
holding 99.9 % of the energy, so that energy the grid cannot resolve (a single-scattering peak
within a few um of the entry point) is not spread over a wide Gaussian instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, nnls

from dermis.errors import DermisError
from dermis.profiles.gaussians import SumOfGaussians, gaussian_2d

MAX_GAUSSIANS = 16
ENERGY_WEIGHT = 30.0  # weight of the "weights sum to R_d" row relative to the profile's norm


@dataclass(frozen=True, eq=False)
class GaussianFit:
    """A fitted SumOfGaussians with its errors and totals (per linear-sRGB channel)."""

    profile: SumOfGaussians
    relative_error_rgb: np.ndarray
    total_reflectance_rgb: np.ndarray  # of the fit: the sum of its weights
    target_total_reflectance_rgb: np.ndarray  # of the profile that was fitted
    radius_mm: np.ndarray  # the fit grid

    @property
    def relative_error(self) -> float:
        """The worst channel's r-weighted relative L2 error."""
        return float(np.max(self.relative_error_rgb))


def relative_l2_error(radius_mm, fitted, target) -> np.ndarray:
    """sqrt( sum r (fit - R)^2 / sum r R^2 ) per channel on a uniform radius grid."""
    r = np.asarray(radius_mm, dtype=np.float64)[:, None]
    fitted = np.asarray(fitted, dtype=np.float64).reshape(r.shape[0], -1)
    target = np.asarray(target, dtype=np.float64).reshape(r.shape[0], -1)
    norm = np.sum(r * target * target, axis=0)
    return np.sqrt(np.sum(r * (fitted - target) ** 2, axis=0) / np.where(norm > 0, norm, 1.0))


def energy_radius_mm(profile, fraction: float = 0.999) -> float:
    """The radius within which every channel holds ``fraction`` of its energy (on its samples)."""
    r = profile.radius_mm
    ring = 2.0 * np.pi * r[:, None] * np.maximum(profile.rgb_per_mm2, 0.0)
    cumulative = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (ring[1:] + ring[:-1]) * np.diff(r)[:, None], 0)])
    total = cumulative[-1]
    radius_999 = 0.0
    for c in range(3):
        if total[c] > 0:
            radius_999 = max(radius_999, float(np.interp(fraction * total[c], cumulative[:, c], r)))
    return radius_999


def fit_radius_max_mm(profile) -> float:
    """r_max of the fit grid: 1.5 x the radius holding 99.9 % of every channel's energy, in [4, 60] mm."""
    return float(np.clip(1.5 * energy_radius_mm(profile), 4.0, 60.0))


def _check_k(k) -> int:
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise DermisError(f"the number of Gaussians must be an integer, got {k!r}")
    if not 1 <= int(k) <= MAX_GAUSSIANS:
        raise DermisError(f"the number of Gaussians must lie in 1..{MAX_GAUSSIANS}, got {k}")
    return int(k)


def fit_sum_of_gaussians(profile, k: int = 6, *, variances_mm2=None, total_reflectance_rgb=None,
                         conserve_energy: bool = True, points: int = 600, r_max_mm: float | None = None,
                         r_min_mm: float = 0.0, name: str | None = None) -> GaussianFit:
    """Fit K Gaussians with shared variances and non-negative RGB weights to ``profile``.

    ``profile``: a RadialProfile (anything with ``radius_mm``, ``rgb_per_mm2``, ``evaluate`` and
    ``total_reflectance_rgb``). ``variances_mm2``: keep these K variances and solve the weights
    only. ``total_reflectance_rgb``: the energy the weights should sum to (default: the profile's).
    ``r_min_mm``: fit the shape from this radius out only (the energy within it still counts
    through the weights' sum); the error is then measured from there too.
    """
    k = _check_k(k if variances_mm2 is None else len(np.atleast_1d(variances_mm2)))
    r_max = fit_radius_max_mm(profile) if r_max_mm is None else float(r_max_mm)
    r_min = float(r_min_mm)
    if not 0.0 <= r_min < r_max:
        raise DermisError(f"the fit's radius range must satisfy 0 <= r_min < r_max, got {r_min} and {r_max} mm")
    step = (r_max - r_min) / points
    radius = r_min + (np.arange(points) + 0.5) * step
    target = np.asarray(profile.evaluate(radius), dtype=np.float64)  # (P, 3)
    totals = np.asarray(profile.total_reflectance_rgb if total_reflectance_rgb is None else total_reflectance_rgb,
                        dtype=np.float64)
    sqrt_r = np.sqrt(radius)[:, None]
    rhs = sqrt_r * target  # (P, 3)
    norms = np.linalg.norm(rhs, axis=0)
    if not np.all(np.isfinite(target)) or np.all(norms == 0):
        raise DermisError("cannot fit Gaussians to an empty or non-finite profile")
    energy_rows = ENERGY_WEIGHT * norms / np.where(totals > 0, totals, 1.0) if conserve_energy else np.zeros(3)
    min_variance = (0.5 * step) ** 2
    max_variance = max((0.5 * min(energy_radius_mm(profile), r_max)) ** 2, 16 * min_variance)

    def solve(variances):
        design = sqrt_r * gaussian_2d(variances[None, :], radius[:, None])  # (P, K)
        weights = np.zeros((variances.size, 3))
        cost = 0.0
        for c in range(3):
            if norms[c] == 0:
                continue
            a = np.vstack([design, energy_rows[c] * np.ones((1, variances.size))])
            b = np.concatenate([rhs[:, c], [energy_rows[c] * totals[c]]])
            weights[:, c], residual = nnls(a, b, maxiter=50 * variances.size)
            cost += (residual / norms[c]) ** 2
        return weights, cost

    def variances_of(log_variances):
        return np.sort(np.exp(np.clip(log_variances, np.log(min_variance), np.log(max_variance))))

    if variances_mm2 is not None:
        variances = np.asarray(variances_mm2, dtype=np.float64).reshape(-1)
        if np.any(~np.isfinite(variances)) or np.any(variances <= 0):
            raise DermisError("fixed variances must be finite and > 0 mm^2")
    else:
        # Starting series: from ~(2 grid steps)^2 to the variance of the widest channel's spread
        spread = profile.mean_radius_mm() if hasattr(profile, "mean_radius_mm") else np.full(3, r_max / 6)
        widest = float(np.clip(0.5 * np.max(spread) ** 2 * 1.5, 4 * min_variance, max_variance))
        best = None
        for scale in (1.0, 0.35, 3.0):
            top = float(np.clip(widest * scale, 4 * min_variance, max_variance))
            bottom = max(4 * min_variance, 0.003) if k > 1 else top
            start = np.log(np.geomspace(min(bottom, top), top, k))
            result = minimize(lambda u: solve(variances_of(u))[1], start, method="Nelder-Mead",
                              options={"maxiter": 250 * k, "xatol": 1e-3, "fatol": 1e-9})
            if best is None or result.fun < best.fun:
                best = result
        variances = variances_of(best.x)
    weights, _ = solve(variances)
    fitted = gaussian_2d(variances[None, :], radius[:, None]) @ weights
    gaussians = SumOfGaussians(variances, weights, name or getattr(profile, "name", "fit"))
    return GaussianFit(gaussians, relative_l2_error(radius, fitted, target), gaussians.total_reflectance, totals,
                       radius)
