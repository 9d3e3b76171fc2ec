"""Sum-of-Gaussians diffusion profiles.

A radial diffusion profile R(r) is approximated by sum_k w_k G(v_k, r), with the normalised
2-D Gaussian G(v, r) = exp(-r^2 / 2v) / (2 pi v) (its integral over the plane is 1), variances
v_k in mm^2 SHARED by the three colour channels (so each blur runs once for R, G and B) and
per-channel non-negative weights w_k (d'Eon, Luebke & Enderton 2007, GPU Gems 3 ch. 14, eq. 14-4).

Every technique in dermis takes its skin profile as a :class:`SumOfGaussians`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dermis.errors import DermisError


def gaussian_2d(variance_mm2, radius_mm):
    """G(v, r) = exp(-r^2 / 2v) / (2 pi v), in 1/mm^2."""
    v = np.asarray(variance_mm2, dtype=np.float64)
    r = np.asarray(radius_mm, dtype=np.float64)
    return np.exp(-(r * r) / (2.0 * v)) / (2.0 * np.pi * v)


@dataclass(frozen=True)
class SumOfGaussians:
    """K Gaussians: ``variances_mm2`` (K,), increasing; ``weights`` (K, 3) linear RGB, >= 0."""

    variances_mm2: np.ndarray
    weights: np.ndarray
    name: str = "custom"

    def __post_init__(self):
        v = np.asarray(self.variances_mm2, dtype=np.float64).reshape(-1)
        w = np.asarray(self.weights, dtype=np.float64)
        if v.size == 0:
            raise DermisError(f"profile '{self.name}': needs at least one Gaussian")
        if w.ndim == 1:
            w = np.repeat(w[:, None], 3, axis=1)
        if w.shape != (v.size, 3):
            raise DermisError(f"profile '{self.name}': weights must be K x 3 for K={v.size} variances, got {w.shape}")
        if not np.all(np.isfinite(v)) or np.any(v <= 0):
            raise DermisError(f"profile '{self.name}': variances must be finite and > 0 mm^2")
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise DermisError(f"profile '{self.name}': weights must be finite and >= 0")
        order = np.argsort(v)
        object.__setattr__(self, "variances_mm2", v[order])
        object.__setattr__(self, "weights", w[order])

    @property
    def k(self) -> int:
        return int(self.variances_mm2.size)

    @property
    def total_reflectance(self) -> np.ndarray:
        """Integral of the profile over the plane, per channel (sum of the weights)."""
        return self.weights.sum(axis=0)

    def normalized(self) -> "SumOfGaussians":
        """Each channel's weights scaled to sum to 1 (the colour then comes from the albedo)."""
        tot = self.total_reflectance
        tot = np.where(tot > 0, tot, 1.0)
        return SumOfGaussians(self.variances_mm2, self.weights / tot, self.name)

    def evaluate(self, radius_mm) -> np.ndarray:
        """R(r) in 1/mm^2, shape r.shape + (3,)."""
        r = np.asarray(radius_mm, dtype=np.float64)
        g = gaussian_2d(self.variances_mm2, r[..., None])  # (..., K)
        return g @ self.weights

    def chain_sigmas_mm(self) -> np.ndarray:
        """Per-step standard deviations of the chained blur: sqrt(v_k - v_(k-1)), v_0 = 0."""
        v = np.concatenate([[0.0], self.variances_mm2])
        return np.sqrt(np.diff(v))

    def to_dict(self) -> dict:
        return {"name": self.name, "variances_mm2": self.variances_mm2.tolist(), "weights_rgb": self.weights.tolist()}


# d'Eon, Luebke & Enderton 2007, GPU Gems 3 ch. 14, table 14-1: the three-layer skin profile
# fitted with six Gaussians; each column sums to 1. Green 0.0484 weight is 0.336 (the book),
# not the seed's 0.338. See docs/skin-rendering.md section 1.
DEON_VARIANCES_MM2 = np.array([0.0064, 0.0484, 0.187, 0.567, 1.99, 7.41])
DEON_WEIGHTS_RGB = np.array([
    [0.233, 0.455, 0.649],
    [0.100, 0.336, 0.344],
    [0.118, 0.198, 0.000],
    [0.113, 0.007, 0.007],
    [0.358, 0.004, 0.000],
    [0.078, 0.000, 0.000],
])


def deon_skin() -> SumOfGaussians:
    """The six-Gaussian skin profile of d'Eon et al. 2007 (table 14-1)."""
    return SumOfGaussians(DEON_VARIANCES_MM2.copy(), DEON_WEIGHTS_RGB.copy(), name="deon")
