"""tsd's cheaper texture-space paths (round 10, perf10) against the paths they replaced, in one
Renderer on the shipped head (small sizes):

- the one bounce with rho E and albedo^mix written by the irradiance pass (irradiance_defines:
  SKIN_EXITANT_LOCATION) against rho E from its own mesh raster (tsd/bounce_exitant.frag) and the
  albedo map read in the splat: the same products stored once in half floats instead of twice, so
  E_b, I_0 and the image agree to a few half-float steps (tolerance 2e-3 of the largest value; a
  half float's step is 2^-11 = 4.9e-4 relative); the bounce itself is > 20x that tolerance of I_0
  (the guard: the comparison can fail), for 3 lights (sharp shadows stored: the bounce's targets at
  locations 2, 3) and 5 (per sample: locations 1, 2);
- the translucency's first pass drawn only where the bake has a far face (uFarFaceOnly = 1) into a
  target kept from a whole pass: equal to the whole pass, and wrong when the kept target is not the
  bake's (the guard: the discard does skip texels, so the kept values matter);
- the translucency's lighting-independent part (slab law, surface distance) drawn once per bake,
  stretch, profile and slab law: redrawn when the profile changes (a live Renderer equals a fresh one);
- the tent as four bilinear taps against a numpy (1 2 1)^2 over the covered 3 x 3 texels (edges
  clamped), random values and coverage.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import dermis
from dermis.gl.shaders import program
from dermis.renderer import Renderer
from dermis.techniques.shared import LIGHT_COUNT_DEFINE, MAX_GAUSSIANS
from dermis.techniques.tsd import irradiance_defines

KW = dict(samples=0, irradiance_size=256)
SIZE = (64, 64)
TOL = 2e-3


def _without_bounce_targets(n):
    """tsd/irradiance.frag's defines for n lights without the bounce's targets (main's program)."""
    d = {k: v for k, v in irradiance_defines(n).items() if k not in ("SKIN_EXITANT_LOCATION", "SKIN_ALBEDO_MIX_LOCATION")}
    return {"MAX_GAUSSIANS": MAX_GAUSSIANS, **d, LIGHT_COUNT_DEFINE: n}


def _state(r, t):
    img = np.asarray(r.render("tsd"), np.float64)
    return img, t.bounce_per_vertex().astype(np.float64), t.read_texture(t.tex["irradiance"])[..., :3].astype(np.float64)


@pytest.mark.parametrize("extra_lights", [0, 2])
def test_bounce_from_the_irradiance_pass_equals_its_own_raster(gl_ctx, example_head_toml, extra_lights):
    sc = dermis.load_scene(str(example_head_toml))
    for i in range(extra_lights):  # 5 lights: no sharp shadows stored, the bounce's targets at 1 and 2
        L = sc.lights[i]
        sc.lights.append(replace(L, intensity=0.3 * L.intensity, direction=tuple(-x for x in L.direction),
                                 position=tuple(-x for x in L.position)))
    n = len(sc.lights)
    assert irradiance_defines(n)["SKIN_EXITANT_LOCATION"] == (2 if n <= 3 else 1)
    with Renderer(sc, SIZE, ctx=gl_ctx, **KW) as r:
        t = r.technique("tsd")
        img1, eb1, irr1 = _state(r, t)
        assert "tsd_interreflection" in r.stats["passes_run"]
        p_main = program(gl_ctx, "tsd/uv_space.vert", "tsd/irradiance.frag", _without_bounce_targets(n))
        try:
            t.p_irradiance = p_main  # tsd's other path: rho E from tsd/bounce_exitant.frag
            t.scene_changed()
            img0, eb0, irr0 = _state(r, t)
            sc.interreflection = False
            t.scene_changed()
            _, _, irr_off = _state(r, t)
        finally:
            t.p_irradiance = None
            p_main.release()
    assert eb0.max() > 0.1
    assert np.abs(eb1 - eb0).max() <= TOL * eb0.max()
    assert np.abs(irr1 - irr0).max() <= TOL * irr0.max()
    assert np.abs(img1 - img0).max() <= TOL * img0.max()
    # the guard: the bounce moves I_0 by far more than the tolerance
    assert np.abs(irr0 - irr_off).max() > 20 * TOL * irr0.max()


def test_translucency_far_faces_only_equals_the_whole_pass(gl_ctx, example_head_toml):
    sc = dermis.load_scene(str(example_head_toml))
    with Renderer(sc, SIZE, ctx=gl_ctx, **KW) as r:
        t = r.technique("tsd")
        r.render("tsd")  # the whole pass (a new bake and target)
        own = t.tex["translucency_own"]
        assert t._own_filled == (t.thickness.key, own)
        sc.lights[0].intensity *= 1.5  # the lights changed: the far faces only
        r.render("tsd")
        assert "tsd_translucency" in r.stats["passes_run"]
        kept = t.read_texture(own).astype(np.float64)
        trans = t.read_texture(t.tex["translucency"]).astype(np.float64)
        t._own_filled = None  # the same lights drawn whole
        t._cache_key = None
        r.render("tsd")
        whole = t.read_texture(own).astype(np.float64)
        trans_whole = t.read_texture(t.tex["translucency"]).astype(np.float64)
        assert np.array_equal(kept, whole)
        assert np.array_equal(trans, trans_whole)
        assert trans[..., :3].max() > 0.01  # light does come through
        # the guard: a kept target that is not the bake's shows where the pass skipped texels
        own.write(np.full(own.size[0] * own.size[1] * 4, 0.25, np.float16).tobytes())
        t._cache_key = None
        r.render("tsd")
        stale = t.read_texture(own).astype(np.float64)
        skipped = np.abs(stale - whole).max(axis=-1) > 0.1
        th = t.read_texture(t.thickness.tex)
        assert skipped.mean() > 0.5  # most texels have no far face
        assert np.all(th[skipped, 3] <= 0.0)


def test_tent_four_bilinear_taps_equal_numpy(gl_ctx):
    import moderngl

    rng = np.random.default_rng(7)
    h, w = 37, 50
    data = rng.random((h, w, 4)).astype(np.float32)
    data[..., 3] = (rng.random((h, w)) > 0.3).astype(np.float32)  # coverage 0 or 1
    data[..., :3] *= data[..., 3:]
    src = gl_ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
    src.filter = (moderngl.LINEAR, moderngl.LINEAR)
    src.repeat_x = src.repeat_y = False
    dst = gl_ctx.texture((w, h), 4, dtype="f4")
    fbo = gl_ctx.framebuffer(color_attachments=[dst])
    p = program(gl_ctx, "common/fullscreen.vert", "tsd/translucency_tent.frag", {"MAX_GAUSSIANS": MAX_GAUSSIANS})
    vao = gl_ctx.vertex_array(p, [])
    try:
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        src.use(0)
        p["uSource"].value = 0
        vao.render(moderngl.TRIANGLES, vertices=3)
        got = np.frombuffer(dst.read(), np.float32).reshape(h, w, 4)
    finally:
        for o in (vao, p, fbo, dst, src):
            o.release()
    pad = np.pad(data, ((1, 1), (1, 1), (0, 0)), mode="edge")
    tent = np.outer([1, 2, 1], [1, 2, 1]).astype(np.float64)
    acc = np.zeros((h, w, 4))
    for dy in range(3):
        for dx in range(3):
            acc += tent[dy, dx] * pad[dy:dy + h, dx:dx + w]
    ref = np.where(data[..., 3:] > 0, acc[..., :3] / np.maximum(acc[..., 3:], 1.0), 0.0)
    np.testing.assert_allclose(got[..., :3], ref, atol=1e-5)
    assert np.all(got[..., 3] == 1.0)


def test_translucency_static_part_follows_the_profile(gl_ctx, example_head_toml):
    """The lighting-independent part (slab law, surface distance: _translucency_static) is kept per
    bake, stretch, profile and slab law: after the profile changes, a live Renderer's translucency
    equals a fresh Renderer's (and differs from the old profile's: the guard)."""
    from pathlib import Path

    from dermis.profiles.scene_skin import resolve_skin_profile

    sc = dermis.load_scene(str(example_head_toml))
    with Renderer(sc, SIZE, ctx=gl_ctx, **KW) as r:
        t = r.technique("tsd")
        r.render("tsd")
        before = t.read_texture(t.tex["translucency"]).astype(np.float64)
        sc.profile = resolve_skin_profile({"profile": "dark"}, Path(example_head_toml).parent, "test")
        r.render("tsd")
        live = t.read_texture(t.tex["translucency"]).astype(np.float64)
    with Renderer(sc, SIZE, ctx=gl_ctx, **KW) as r:
        r.render("tsd")
        t = r.technique("tsd")
        fresh = t.read_texture(t.tex["translucency"]).astype(np.float64)
    assert np.array_equal(live, fresh)
    assert np.abs(live - before)[..., :3].max() > 0.01
