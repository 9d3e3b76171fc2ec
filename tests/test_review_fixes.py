"""Regressions found in review: grey textures, scale changes and the shadow atlas's size limit."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import dermis
from dermis.errors import DermisError
from dermis.renderer import Renderer


def _slab_toml(tmp_path, extra=""):
    Image.fromarray(np.full((16, 16), 128, np.uint8), mode="L").save(tmp_path / "grey.png")
    p = tmp_path / "s.toml"
    p.write_text('[scene]\nmm_per_unit = 1.0\n[mesh]\nbuiltin = "slab"\n[material]\nalbedo = "grey.png"\n' + extra)
    return p


def test_grey_albedo_is_grey_not_cyan(tmp_path, gl_ctx):
    sc = dermis.load_scene(_slab_toml(tmp_path))
    assert sc.material.albedo.data.shape[2] == 3
    expected = ((128 / 255 + 0.055) / 1.055) ** 2.4  # sRGB decode of 128
    np.testing.assert_allclose(sc.material.albedo.data[0, 0], [expected] * 3, rtol=1e-5)
    with Renderer(sc, (32, 32), ctx=gl_ctx, samples=0) as r:
        img = r.render("lambert")
    lit = img[img.sum(axis=2) > 0.1]
    assert len(lit) and np.allclose(lit[:, 0], lit[:, 1], rtol=0.2)  # not (g, 1, 1)


def test_changing_the_scale_re_renders_the_translucent_shadow_map(gl_ctx):
    from dermis.verification import backlit_slab_scene

    sc = backlit_slab_scene(2.0, n=8)
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        r.render("tsd", output_mode=1)
        sc.mm_per_unit = 0.5
        a = r.render("tsd", output_mode=1)
        assert "shadow" in r.stats["passes_run"]
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as fresh:
        b = fresh.render("tsd", output_mode=1)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)


def test_shadow_atlas_over_the_texture_limit_is_a_user_error(gl_ctx):
    from dermis.scene.builtin import frame_scene
    from dermis.scene.model import Scene

    from dermis.scene.builtin import builtin_mesh

    mesh, _, _ = builtin_mesh("sphere")
    scene = Scene(mesh=mesh)
    frame_scene(scene)  # three lights
    limit = int(gl_ctx.info.get("GL_MAX_TEXTURE_SIZE"))
    with Renderer(scene, (16, 16), ctx=gl_ctx, samples=0, shadow_size=limit) as r:
        with pytest.raises(DermisError, match="shadow_size"):
            r.render("lambert")
