"""The screen passes without pore detail where it cannot show (issue 14, round 9: the passes' cost).

common/noise.glsl's pore_normal fades its first octave out as the pixel's footprint reaches
PORE_FADE[1] times the pore scale, and from there returns N unchanged; a CPU rasteriser evaluates
the noise under the false branch anyway. draw_mesh therefore draws a variant compiled without it
(dermis.techniques.shared.shading_program) when a CPU bound on every fragment's footprint
(min_pixel_footprint) is past the fade. Checked here: the bound against the footprint the GPU
computes (the shader's own expression, every covered pixel), the image bit-identical with the
variant, and the variant not drawn where the pores show.
"""

from __future__ import annotations

import dataclasses

import moderngl
import numpy as np

import dermis
import dermis.techniques.shared as shared
from dermis.gl.resources import mat_bytes
from dermis.gl.shaders import load_shader_source
from dermis.renderer import Renderer
from dermis.verification import quad_scene

FOOTPRINT_FS = """#version 450 core
in vec3 v_world;
out vec4 f_color;
void main() {
    // common/noise.glsl's footprint, in scene units (P_mm = v_world * mm_per_unit)
    f_color = vec4(max(length(dFdx(v_world)), length(dFdy(v_world))), 0.0, 0.0, 1.0);
}
"""


def _gpu_min_footprint(r) -> float:
    """The smallest footprint over the covered pixels of the last frame's view, as a fragment
    shader computes it (no MSAA: every covered pixel is shaded once, at its centre)."""
    frame = r.last_frame
    ctx = r.ctx
    w, h = frame.size
    prog = ctx.program(vertex_shader=load_shader_source("common/mesh.vert", {}), fragment_shader=FOOTPRINT_FS)
    color = ctx.texture((w, h), 4, dtype="f4")
    depth = ctx.depth_renderbuffer((w, h))
    fbo = ctx.framebuffer([color], depth)
    vao = ctx.vertex_array(prog, [frame.gpu.vertex_content(prog)], frame.gpu.ibo)
    try:
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        prog["uViewProj"].write(mat_bytes(frame.viewproj))
        vao.render(moderngl.TRIANGLES)
        img = np.frombuffer(color.read(), np.float32).reshape(h, w, 4)
    finally:
        for o in (vao, fbo, depth, color, prog):
            o.release()
    covered = img[..., 3] > 0.5
    assert covered.sum() > 100
    return float(img[..., 0][covered].min())


def test_footprint_bound_is_below_every_fragments_footprint(gl_ctx, example_head_toml):
    """min_pixel_footprint <= the GPU's footprint at every covered pixel, and within 3x of the
    smallest where the surface faces the camera (a loose bound would leave the variant unused): the head from its own camera, from a
    close, off-axis one whose near plane cuts the mesh, at a non-square size; a quad seen at grazing
    incidence."""
    head = dermis.load_scene(example_head_toml)
    c = head.camera
    target = np.asarray(c.target, float)
    close = dataclasses.replace(c, position=tuple(target + np.array([60.0, 20.0, 40.0]) / head.mm_per_unit))
    quad = quad_scene(40.0, 40.0)
    grazing = dataclasses.replace(quad.camera, position=(0.0, -110.0, 12.0), target=(0.0, 10.0, 0.0), up=(0.0, 0.0, 1.0))
    # (scene, camera, size, whether some of it faces the camera: there the bound is within 3x)
    cases = [(head, None, (96, 96), True), (head, None, (128, 72), True), (head, close, (96, 96), True),
             (quad, grazing, (80, 80), False)]
    for sc, cam, size, facing in cases:
        with Renderer(sc, size, ctx=gl_ctx, samples=0, irradiance_size=64) as r:
            r.render("lambert", camera=cam)
            bound = shared.min_pixel_footprint(r.last_frame)
            measured = _gpu_min_footprint(r)
        assert 0.0 < bound <= measured, (size, bound, measured)
        assert bound > measured / 3.0 or not facing, (size, bound, measured)


def test_variant_image_is_bit_identical(gl_ctx, example_head_toml):
    """Where the pores cannot show, tsd's and ssss's final passes draw the variant, and the image is
    the one of the full program, bit for bit (4x MSAA, the shipped head's pore settings)."""
    sc = dermis.load_scene(example_head_toml)
    assert sc.material.pore_strength > 0.0
    real = shared.pores_invisible
    with Renderer(sc, (96, 96), ctx=gl_ctx, samples=4, irradiance_size=128) as r:
        for tech in ("tsd", "ssss"):
            n = len(r.program_variants)
            with_variant = r.render(tech)
            assert real(r.last_frame) and len(r.program_variants) == n + 1
            try:
                shared.pores_invisible = lambda frame: False
                full = r.render(tech)
            finally:
                shared.pores_invisible = real
            assert with_variant.std() > 0.01
            np.testing.assert_array_equal(with_variant, full)


def test_variant_not_drawn_where_pores_show(gl_ctx):
    """A quad whose pores span several pixels: pores_invisible is False and the image has the pores
    (drawing the variant there would change it)."""
    sc = quad_scene(40.0, 40.0)
    sc.material.rho_s = 0.4
    sc.material.pore_strength = 0.5
    sc.material.pore_scale_mm = 4.0  # ~10 pixels per pore at 128 px
    sc.lights[0].direction = (0.3, 0.2, -1.0)
    real = shared.pores_invisible
    with Renderer(sc, (128, 128), ctx=gl_ctx, samples=0, irradiance_size=64) as r:
        img = r.render("tsd")
        assert not real(r.last_frame) and not r.program_variants
        try:
            shared.pores_invisible = lambda frame: True
            forced = r.render("tsd")
        finally:
            shared.pores_invisible = real
    assert np.abs(img - forced).max() > 1e-3
