"""The output transform: exposure, tone map, sRGB encoding; linear HDR until here.

Tone maps: "aces" is Narkowicz's 2015 fit of the ACES reference rendering transform
("ACES Filmic Tone Mapping Curve"), f(x) = x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14), applied to
exposure-scaled linear radiance; "linear" clamps to [0, 1]. sRGB encoding is IEC 61966-2-1.
"""

from __future__ import annotations

import numpy as np

from dermis.images import linear_to_srgb

TONEMAPS = ("aces", "linear")


def aces_narkowicz(x):
    # f(x) -> 2.51 / 2.43 > 1 for large x, clipped to 1 from x ~ 3.6 on: capping x at 1e4 changes
    # nothing and keeps x * x finite in float32 (inf / inf would be NaN)
    x = np.clip(np.nan_to_num(np.asarray(x, np.float32), nan=0.0), 0.0, 1e4)
    return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def bloom(linear_rgb, strength: float, radius: float) -> np.ndarray:
    """Bloom, the glow of bright light scattered in the eye and the lens (Spencer et al. 1995,
    "Physically-based glare effects"): a fraction ``strength`` of the linear image is spread by a
    Gaussian of standard deviation ``radius`` x the image height. Energy is conserved."""
    from scipy.ndimage import gaussian_filter

    x = np.asarray(linear_rgb, np.float32)
    if strength <= 0:
        return x
    sigma = radius * x.shape[0]
    spread = np.stack([gaussian_filter(x[:, :, c], sigma, mode="nearest") for c in range(x.shape[2])], axis=2)
    return (1.0 - strength) * x + strength * spread


def output_transform(linear_rgb, exposure: float = 0.0, tonemap: str = "aces", bloom_strength: float = 0.0,
                     bloom_radius: float = 0.015) -> np.ndarray:
    """Linear HDR (H, W, 3) -> display-encoded sRGB values in [0, 1]: bloom (optional), exposure,
    tone map, sRGB encoding."""
    from dermis.validation import check_exposure

    exposure = check_exposure(exposure)
    x = bloom(linear_rgb, bloom_strength, bloom_radius) * np.float32(2.0 ** exposure)
    if tonemap == "aces":
        y = aces_narkowicz(x)
    elif tonemap == "linear":
        y = np.clip(x, 0.0, 1.0)
    else:
        from dermis.errors import DermisError

        raise DermisError(f"tonemap: unknown tone map {tonemap!r} (one of {', '.join(TONEMAPS)})")
    return linear_to_srgb(y)
