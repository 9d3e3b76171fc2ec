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
    x = np.maximum(np.asarray(x, np.float32), 0.0)
    return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def output_transform(linear_rgb, exposure: float = 0.0, tonemap: str = "aces") -> np.ndarray:
    """Linear HDR (H, W, 3) -> display-encoded sRGB values in [0, 1]."""
    x = np.asarray(linear_rgb, np.float32) * np.float32(2.0 ** exposure)
    if tonemap == "aces":
        y = aces_narkowicz(x)
    elif tonemap == "linear":
        y = np.clip(x, 0.0, 1.0)
    else:
        raise ValueError(f"unknown tone map '{tonemap}' (one of {', '.join(TONEMAPS)})")
    return linear_to_srgb(y)
