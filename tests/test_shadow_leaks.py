"""Shadows without leaks: the side view's shadowed eye socket, behind the nose bridge."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import dermis
from dermis.renderer import Renderer

REPO = Path(__file__).resolve().parent.parent
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def test_side_view_eye_socket_has_no_lit_blob(lee_perry_smith, gl_ctx):
    """examples/reference/side.toml with lambert at 256 px: in the eye socket shadowed by the nose
    bridge (rows 90-130, columns 30-80) the brightest pixel is under 3x the region's median.
    Before the receiver-plane bias: 0.081 against a median of 0.0072 (11x), the normal offset
    having moved the lookup of a grazing receiver across the nose bridge's silhouette in the map."""
    sc = dermis.load_scene(REPO / "examples" / "reference" / "side.toml")
    with Renderer(sc, (256, 256), ctx=gl_ctx, samples=0) as r:
        img = r.render("lambert")
    region = img[90:130, 30:80] @ LUMINANCE
    median = np.median(region)
    assert median > 1e-3  # the region is on the head and receives the ambient
    assert region.max() < 3.0 * median, (region.max(), median)
