"""Cycles' pixel reconstruction filter, applied to a supersampled dermis image.

Why: a Cycles pixel is the mean of its samples, whose film positions Cycles draws from the pixel
filter (Blackman-Harris, 1.5 px wide by default: ``scene.render.filter_size``,
``scene.cycles.pixel_filter_type``). A real-time technique shades each pixel once (MSAA resolves
coverage only). At the 64 x 64 of a converged Cycles validation a pixel of the head is about
4 mm wide, so a shadow edge is a hard step in dermis and a 1.5 px ramp in Cycles, and the
difference measures pixel reconstruction, not skin. ``dermis validate --against cycles`` therefore
renders each technique at ``factor`` times the size and reconstructs it here with Cycles' own
filter, so both images estimate the same pixel integral.

Cycles samples the filter separably: one 1-D table (intern/cycles/scene/film.cpp,
``filter_func_blackman_harris`` and ``filter_table``) for x and another draw for y, so the 2-D
weight is BH(dx) * BH(dy), normalised (the table is a pdf). ``filter_table`` doubles the width for
Blackman-Harris before building the table, so the window spans +-filter_size pixels (3 px wide at
the default 1.5), not +-filter_size / 2.
"""
from __future__ import annotations

import numpy as np

from dermis.errors import DermisError

CYCLES_FILTER_WIDTH_PX = 1.5  # Blender's default scene.render.filter_size (pixels)


def blackman_harris(x, width: float = CYCLES_FILTER_WIDTH_PX) -> np.ndarray:
    """Cycles' pixel filter for ``filter_size = width``: x in pixels from the pixel centre, the
    four-term Blackman-Harris window over |x| < width (filter_table's doubled width), else 0."""
    x = np.asarray(x, np.float64)
    t = 2.0 * np.pi * (x / (2.0 * width) + 0.5)
    w = 0.35875 - 0.48829 * np.cos(t) + 0.14128 * np.cos(2 * t) - 0.01168 * np.cos(3 * t)
    return np.where(np.abs(x) < width, w, 0.0)


def _weights(n_out: int, factor: int, width: float) -> np.ndarray:
    """(n_out, n_out * factor) row-normalised weights: output pixel j (centre j + 0.5, output
    pixels) from supersample s (centre (s + 0.5) / factor). Samples that would fall outside the
    image are missing; their weight goes to the ones inside (the film's border only)."""
    centres_out = np.arange(n_out) + 0.5
    centres_in = (np.arange(n_out * factor) + 0.5) / factor
    w = blackman_harris(centres_in[None, :] - centres_out[:, None], width)
    return w / w.sum(axis=1, keepdims=True)


def reconstruct(image: np.ndarray, factor: int, width: float = CYCLES_FILTER_WIDTH_PX) -> np.ndarray:
    """(H, W, C) from an (H * factor, W * factor, C) image rendered over the same film, weighted by
    Cycles' separable Blackman-Harris pixel filter of ``width`` output pixels."""
    img = np.asarray(image, np.float64)
    if factor < 1 or img.ndim != 3 or img.shape[0] % factor or img.shape[1] % factor:
        raise DermisError(f"pixel filter: an image of {img.shape[:2]} is not {factor} times an output size")
    # factor 1 blurs the technique's own pixels with the filter (neighbours weigh about 0.03 each)
    if width * factor < 0.5:
        raise DermisError(f"pixel filter: width {width} px holds no sample at factor {factor}")
    wy = _weights(img.shape[0] // factor, factor, width)
    wx = _weights(img.shape[1] // factor, factor, width)
    return np.einsum("ys,sxc,Xx->yXc", wy, img, wx, optimize=True).astype(np.float32)
