"""Adaptive irradiance and shadow resolution (dermis.adaptive_resolution): the sizes follow the
closed form from the mesh's size on screen, and an explicit size always wins."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dermis.adaptive_resolution import (IRRADIANCE_RANGE, SHADOW_RANGE, adaptive_sizes, layout_density,
                                        pixels_per_mm)
from dermis.renderer import Renderer
from dermis.verification import quad_scene

HEAD = Path(__file__).resolve().parents[1] / "examples" / "lee-perry-smith.toml"


def _pow2_up(x):
    return 2 ** math.ceil(math.log2(x))


def test_pixels_per_mm_and_layout_density_closed_form():
    sc = quad_scene(40.0, 10.0)  # UVs [0, 1]^2 over 40 x 10 mm, facing the camera at z = 120 mm
    sc.mm_per_unit = 1.0
    p = pixels_per_mm(sc.camera, sc.mesh.positions, (300, 200), 1.0)
    assert math.isclose(p, 200 / (2 * 120.0 * math.tan(math.radians(25.0) / 2)), rel_tol=1e-9)
    assert math.isclose(layout_density(sc.mesh.positions, sc.mesh.uvs, sc.mesh.indices, 1.0), 1 / math.sqrt(400.0),
                        rel_tol=1e-9)
    # in scene units of 2 mm: the quad is 80 x 20 mm and the camera twice as far in mm
    p2 = pixels_per_mm(sc.camera, sc.mesh.positions, (300, 200), 2.0)
    assert math.isclose(p2, p / 2, rel_tol=1e-9)


def test_sizes_follow_the_projected_size():
    sc = quad_scene(25.6, 25.6)  # camera at 76.8 mm, fov 25 deg
    for H in (128, 256, 512, 1024):
        p = H / (2 * 76.8 * math.tan(math.radians(25.0) / 2))
        rho = 1 / 25.6
        want_irr = min(max(_pow2_up(0.5 * p / rho), IRRADIANCE_RANGE[0]), IRRADIANCE_RANGE[1])
        want_shadow = min(max(_pow2_up(p * 25.6 * math.sqrt(2)), SHADOW_RANGE[0]), SHADOW_RANGE[1])
        assert adaptive_sizes(sc, (H, H)) == (want_irr, want_shadow), H
    # a bigger image on screen never gets a smaller texture
    sizes = [adaptive_sizes(sc, (H, H)) for H in (64, 128, 256, 512, 1024, 2048)]
    assert all(a[0] <= b[0] and a[1] <= b[1] for a, b in zip(sizes, sizes[1:]))
    assert sizes[0] == (IRRADIANCE_RANGE[0], SHADOW_RANGE[0])


def test_head_in_the_viewer_gets_at_most_two_pixels_per_texel():
    """The viewer's first look (960x640): the former fixed 512 put 4 pixels on a texel of the
    face (the nose shadow's staircase); the rule's size puts at most 2."""
    import dermis
    from dermis.framing import framed_camera

    sc = dermis.load_scene(HEAD)
    irr, shadow = adaptive_sizes(sc, (960, 640))
    cam = framed_camera(sc.camera, sc.mesh, 960 / 640)
    p = pixels_per_mm(cam, sc.mesh.positions, (960, 640), sc.mm_per_unit)
    rho = layout_density(sc.mesh.positions, sc.mesh.uvs, sc.mesh.indices, sc.mm_per_unit)
    assert p / (512 * rho) > 3.0  # the fixed 512: over 3 pixels per texel
    assert p / (irr * rho) <= 2.0 and irr >= 1024
    assert shadow >= 2048


def test_renderer_uses_the_rule_unless_a_size_is_given(gl_ctx):
    sc = quad_scene(25.6, 25.6)
    want = adaptive_sizes(sc, (96, 96))
    with Renderer(sc, (96, 96), ctx=gl_ctx, samples=0, irradiance_size=None, shadow_size=None) as r:
        assert (r.irradiance_size, r.shadows.tile_size) == want
        r.render("tsd")
        assert r.stats["irradiance_size"] == want[0] and r.stats["shadow_size"] == want[1]
        assert r.technique("tsd").tex["irradiance"].size == (want[0], want[0])
    with Renderer(sc, (96, 96), ctx=gl_ctx, samples=0, irradiance_size=512, shadow_size=None) as r:
        assert r.irradiance_size == 512 and r.shadows.tile_size == want[1]
    with Renderer(sc, (96, 96), ctx=gl_ctx, samples=0, irradiance_size=None, shadow_size=1024) as r:
        assert r.irradiance_size == want[0] and r.shadows.tile_size == 1024
    assert want != (512, 1024)  # the explicit sizes differ from the rule's, so the checks above can fail
    np.testing.assert_array_less(0, want)


def test_largest_shadow_tile_fits_the_gpu_texture_limit(gl_ctx):
    """The viewer caps a view-chosen shadow tile (ShadowAtlas.max_tile_size): the atlas of n lights
    at that tile fits GL_MAX_TEXTURE_SIZE, at twice the tile it does not."""
    from dermis.gl.shadows import ShadowAtlas

    atlas = ShadowAtlas(gl_ctx, 512)
    limit = int(gl_ctx.info.get("GL_MAX_TEXTURE_SIZE") or 16384)
    for n in (1, 2, 3, 4, 5, 8):
        t = atlas.max_tile_size(n)
        cols = min(atlas.cols, n)
        rows = math.ceil(n / cols)
        assert t & (t - 1) == 0 and max(cols, rows) * t <= limit < max(cols, rows) * 2 * t, (n, t, limit)
