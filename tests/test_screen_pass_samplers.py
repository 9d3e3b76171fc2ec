"""How the screen-space passes sample the material maps (issue 14, round 9: the passes' cost on llvmpipe).

preintegrated's blurred normals read the normal map at explicit mip levels (textureLod). A lookup
at an explicit level has zero derivatives, so the GL spec's anisotropic footprint is 1:1 there and
the trilinear value is the right one; the pass reads them through a sampler object without
anisotropy (PreIntegrated.normal_lod_sampler), because Mesa's llvmpipe ran its elliptical filter
on every lookup of the anisotropic map (3-6x the cost, and wider than the level).
"""

from __future__ import annotations

import numpy as np

from dermis.gl.resources import maps_without_anisotropy
from dermis.gl.shaders import load_shader_source
from dermis.renderer import Renderer
from dermis.scene.model import Light, Texture
from dermis.techniques.preintegrated import MAX_GAUSSIANS
from dermis.verification import quad_scene

OLD_LOOKUP = "textureLod(uNormalMap, nuv, lod_k)"  # before round 9: the anisotropic map itself
NEW_LOOKUP = "textureLod(uNormalMapLod, nuv, lod_k)"


def _bumpy_quad(wrap_repeat: bool):
    """A quad with a random normal map (slopes up to ~0.5), diffuse only (rho_s 0, no pores, no
    directional albedo), lit obliquely: its image depends on the normal map only through the
    blurred normals (N_red, N_green, N_blue)."""
    sc = quad_scene(40.0, 40.0)
    rng = np.random.default_rng(7)
    n = np.dstack([rng.uniform(-0.5, 0.5, (64, 64, 2)), np.ones((64, 64, 1))])
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    sc.material.normal_map = Texture((n * 0.5 + 0.5).astype(np.float32), "test:bumps",
                                     wrap=("repeat", "repeat") if wrap_repeat else ("clamp", "clamp"))
    sc.directional_albedo = False
    sc.interreflection = False  # the pass draws PreIntegrated.prog (which _render_with replaces)
    sc.lights = [Light(direction=(-0.6, 0.0, -0.8), intensity=np.pi, cast_shadows=False)]
    return sc


def _render_with(r, fragment_source=None):
    t = r.technique("preintegrated")
    if fragment_source is None:
        return r.render("preintegrated")
    t._release_mesh()  # its vertex array is made for t.prog: the replacement gets its own
    saved = t.prog
    t.prog = r.ctx.program(vertex_shader=load_shader_source("common/mesh.vert", {"MAX_GAUSSIANS": MAX_GAUSSIANS,
                                                                                "DERMIS_VERTEX_CURVATURE": None}),
                           fragment_shader=fragment_source)
    try:
        return r.render("preintegrated")
    finally:
        t.prog.release()
        t.prog = saved
        t._release_mesh()  # the vertex array made for the replacement


def test_blurred_normals_sampler_is_the_normal_map_trilinear(gl_ctx):
    """With every map trilinear, reading the levels through the sampler object is bit-identical to
    reading the map itself: the sampler carries the map, its mip filter and its wrap (both wraps)."""
    for repeat in (True, False):
        sc = _bumpy_quad(repeat)
        with Renderer(sc, (48, 48), ctx=gl_ctx, samples=0, irradiance_size=64) as r:
            src = load_shader_source("preintegrated/skin.frag", {"MAX_GAUSSIANS": MAX_GAUSSIANS, "DERMIS_VERTEX_CURVATURE": None})
            assert NEW_LOOKUP in src
            with maps_without_anisotropy(r.gpu):
                new = _render_with(r)
                old = _render_with(r, src.replace(NEW_LOOKUP, OLD_LOOKUP))
            smp = r.technique("preintegrated").normal_lod_sampler
            tex = r.gpu.textures["normal"]
            assert smp.anisotropy == 1.0 and smp.filter == tex.filter
            assert (smp.repeat_x, smp.repeat_y) == (tex.repeat_x, tex.repeat_y) == (repeat, repeat)
        assert new.std() > 0.01  # the bumps show
        np.testing.assert_array_equal(new, old)


def test_blurred_normals_ignore_the_maps_anisotropy(gl_ctx):
    """The pass as rendered (the map at 8x anisotropy for its own texture() lookups) gives the
    image of the trilinear map wherever only the blurred normals read it: the explicit levels
    never go through the anisotropic filter."""
    sc = _bumpy_quad(True)
    with Renderer(sc, (48, 48), ctx=gl_ctx, samples=0, irradiance_size=64) as r:
        assert r.gpu.textures["normal"].anisotropy == 8.0
        as_rendered = _render_with(r)
        with maps_without_anisotropy(r.gpu):
            trilinear = _render_with(r)
    np.testing.assert_array_equal(as_rendered, trilinear)


def test_specular_map_is_trilinear_and_within_tolerance(gl_ctx, example_head_toml):
    """The specular intensity map is read without anisotropy in every pass (the albedo and normal
    maps keep 8x in the screen passes): on the shipped head (tsd, 4x MSAA) the image is within
    0.01 of the map at 8x in display values (below 3/255, the round-9 measurement at 768 px: 0.007)."""
    import dermis
    from dermis.reference.validate import display

    sc = dermis.load_scene(example_head_toml)
    assert sc.material.specular_map is not None
    with Renderer(sc, (160, 160), ctx=gl_ctx, samples=4, irradiance_size=256) as r:
        maps = r.gpu.textures
        assert maps["specular"].anisotropy == 1.0 and maps["albedo"].anisotropy == maps["normal"].anisotropy == 8.0
        trilinear = r.render("tsd")
        maps["specular"].anisotropy = 8.0
        anisotropic = r.render("tsd")
    d = np.abs(display(sc, trilinear) - display(sc, anisotropic))
    assert d.max() < 0.01
