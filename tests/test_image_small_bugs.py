"""Small bugs found through the public interface (issue 12)."""

from __future__ import annotations

import numpy as np

from dermis.renderer import Renderer
from dermis.scene.model import Texture
from dermis.verification import quad_scene


def test_mix_one_black_albedo_texel_receives_scattered_light(gl_ctx):
    """mix = 1 (all colour before scattering): a black albedo patch 2.5 mm wide on a white quad
    shows the light scattered in from around it (red reaches farthest), not black: the final
    pass's albedo^(1 - mix) is albedo^0 = 1 there (GLSL's pow(0, 0) is undefined)."""
    sc = quad_scene(20.0, 20.0)
    tex = np.ones((64, 64, 3), np.float32)
    tex[28:36, 28:36] = 0.0
    sc.material.albedo = Texture(tex, "test:black-patch")
    sc.material.mix = 1.0
    with Renderer(sc, (64, 64), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        img = r.render("tsd")
    assert np.isfinite(img).all()
    centre = img[30:34, 30:34].reshape(-1, 3).mean(axis=0)
    lit = img[4:12, 4:12].reshape(-1, 3).mean(axis=0)
    # the red profile puts ~40% of its weight in Gaussians wider than 1 mm (sigma 1.4, 2.7 mm)
    assert centre[0] > 0.15 * lit[0], (centre, lit)
    assert centre[0] > centre[2]  # red scatters farther than blue
