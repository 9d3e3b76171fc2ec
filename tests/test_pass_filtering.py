"""How the shading passes filter the material maps (issue 14: what the passes cost on llvmpipe).

tsd's irradiance pass is rasterised in texture space: its footprint in a map that shares the
texture-space UVs is square, so it reads the maps trilinearly (anisotropic filtering off for the
pass; llvmpipe's elliptical filter costs 3-6x a trilinear lookup and blurs far wider than the
footprint). Reference: the map's mip level 1 computed in numpy (the 2x2 box of a power-of-two
level 0), which a trilinear lookup at level of detail exactly 1 returns at the level's texel
centres.
"""

from __future__ import annotations

import numpy as np
import pytest

from dermis.gl.resources import maps_without_anisotropy
from dermis.renderer import Renderer
from dermis.scene.model import Texture
from dermis.verification import quad_scene


def _albedo_quad(n: int):
    sc = quad_scene(40.0, 40.0)  # light of irradiance pi along the normal, rho_s 0, black environment
    rng = np.random.default_rng(1)
    albedo = rng.uniform(0.1, 0.9, (n, n, 3)).astype(np.float32)
    sc.material.albedo = Texture(albedo, "test:albedo")
    sc.material.mix = 1.0  # all the colour before scattering: irradiance = E * albedo
    return sc, albedo


def test_irradiance_pass_reads_the_albedo_trilinearly(gl_ctx):
    S = 64
    sc, albedo = _albedo_quad(2 * S)  # map texels per irradiance texel: 2, so level of detail 1
    sc.directional_albedo = False  # E = pi exactly (k(N.L) is tests/test_directional_albedo.py's)
    with Renderer(sc, (32, 32), irradiance_size=S, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        assert r.gpu.textures["albedo"].anisotropy == 8.0  # the screen-space passes keep theirs
        irr = r.technique("tsd").debug_buffers()["irradiance"]
    assert irr.shape == (S, S, 4) and np.all(irr[..., 3] == 1.0)
    # row 0 of both is the top (v = 1): level 1 texel (i, j) is the mean of level 0's 2x2 block
    level1 = albedo.reshape(S, 2, S, 2, 3).mean(axis=(1, 3))
    # E = pi (irradiance pi at normal incidence, nothing reflected: rho_s 0); RGBA16F storage
    np.testing.assert_allclose(irr[..., :3] / np.pi, level1, rtol=3e-3, atol=2e-3)


def test_maps_without_anisotropy_restores_each_maps_setting(gl_ctx):
    sc, _ = _albedo_quad(16)
    sc.material.normal_map = Texture(np.tile(np.array([0.5, 0.5, 1.0], np.float32), (16, 16, 1)), "test:flat")
    with Renderer(sc, (16, 16), irradiance_size=64, ctx=gl_ctx, samples=0) as r:
        maps = r.gpu.textures
        maps["normal"].anisotropy = 4.0
        before = {k: t.anisotropy for k, t in maps.items()}
        assert before["albedo"] == 8.0
        with maps_without_anisotropy(r.gpu):
            assert all(t.anisotropy <= 1.0 for t in maps.values())  # 0: never set, trilinear
        assert {k: t.anisotropy for k, t in maps.items()} == before
        with pytest.raises(RuntimeError):
            with maps_without_anisotropy(r.gpu):
                raise RuntimeError("a failed pass")
        assert {k: t.anisotropy for k, t in maps.items()} == before
