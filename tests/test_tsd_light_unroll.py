"""tsd's irradiance pass with its lights unrolled at constant indices (SKIN_LIGHT_COUNT,
common/skin_irradiance.glsl; one program per light count, dermis.techniques.tsd) against the loop
over uLightCount it replaced. The reference is that loop, compiled from the same source: the same
arithmetic, so the irradiance, the stored sharp shadows and the image must agree to float rounding
(1e-5 of the largest value), for 1, 2 and 3 lights (the sharp shadows stored) and 5 (more than
STORED_SHARP_SHADOWS: per sample), the key light in the last slot (a light dropped or read from
another slot differs there by far more, which the guard test checks), and after the light count
changes in a live Renderer."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dermis.gl.shaders import program
from dermis.renderer import Renderer
from dermis.techniques.shared import MAX_GAUSSIANS, SIGNATURE_DEFINES
from dermis.techniques.tsd import STORED_SHARP_SHADOWS

from test_shadow_edge_rim import H, W
from test_tsd_sharp_shadow import _scene

KW = dict(samples=0, irradiance_size=256, shadow_size=1024)
REL = 1e-5


def _render(sc, gl_ctx, defines=None):
    """tsd's image, irradiance and stored sharp shadows; with ``defines``, the storing irradiance
    program compiled from them instead of the one per light count."""
    with Renderer(sc, (W, H), ctx=gl_ctx, **KW) as r:
        t = r.technique("tsd")
        if defines is not None:
            t.p_irradiance = program(gl_ctx, "tsd/uv_space.vert", "tsd/irradiance.frag", defines)
        try:
            img = r.render("tsd").astype(np.float64)
            stored = ("sharp_shadow",) if len(sc.lights) <= STORED_SHARP_SHADOWS else ()
            tex = {k: np.frombuffer(t.tex[k].read(), np.float32 if t.tex[k].dtype == "f4" else np.uint8).astype(np.float64)
                   for k in ("irradiance", *stored)}
        finally:
            if defines is not None:
                t.p_irradiance.release()
                t.p_irradiance = None
    return img, tex


def _loop(lights, count=None):
    """The defines of the program for ``lights`` lights: the loop, or unrolled for ``count``."""
    d = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
    if lights <= STORED_SHARP_SHADOWS:
        d["SKIN_SHARP_SHADOWS"] = STORED_SHARP_SHADOWS
    return d if count is None else {**d, "SKIN_LIGHT_COUNT": count}


def _close(a, b):
    return np.abs(a - b).max() <= REL * max(np.abs(b).max(), 1e-30)


@pytest.mark.parametrize("count", [1, 2, 3, 5])
def test_unrolled_lights_equal_the_loop(gl_ctx, count):
    sc, _ = _scene(count - 1, count)
    img, tex = _render(sc, gl_ctx)
    ref_img, ref_tex = _render(sc, gl_ctx, _loop(count))
    assert ref_img.max() > 0.05 and ref_tex["irradiance"].max() > 0.0
    assert _close(img, ref_img), np.abs(img - ref_img).max()
    for k in tex:
        assert _close(tex[k], ref_tex[k]), (k, np.abs(tex[k] - ref_tex[k]).max())


@pytest.mark.parametrize("count", [3, 5])
def test_a_light_missing_from_the_unroll_is_seen(gl_ctx, count):
    """The comparison above can fail (and the reference program is the one drawn, on both paths):
    the scene drawn with SKIN_LIGHT_COUNT = count - 1 (the key light, in the last slot, left out)
    is far from the loop's."""
    sc, _ = _scene(count - 1, count)
    ref_img, ref_tex = _render(sc, gl_ctx, _loop(count))
    img, tex = _render(sc, gl_ctx, _loop(count, count - 1))
    assert np.abs(img - ref_img).max() > 0.1 * ref_img.max()
    assert np.abs(tex["irradiance"] - ref_tex["irradiance"]).max() > 0.1 * ref_tex["irradiance"].max()


def test_light_count_change_in_a_live_renderer(gl_ctx):
    """3 lights, then 1, then 5: the live Renderer draws the program for the new count (its image
    equals a fresh Renderer's), and back to 3."""
    sc3, _ = _scene(2, 3)
    sc1 = replace(sc3, lights=[sc3.lights[2]])
    sc5, _ = _scene(4, 5)
    with Renderer(sc3, (W, H), ctx=gl_ctx, **KW) as r:
        a3 = r.render("tsd")
        r.set_scene(sc1)
        a1 = r.render("tsd")
        r.set_scene(sc5)
        a5 = r.render("tsd")
        r.set_scene(sc3)
        b3 = r.render("tsd")
    with Renderer(sc1, (W, H), ctx=gl_ctx, **KW) as r:
        f1 = r.render("tsd")
    with Renderer(sc5, (W, H), ctx=gl_ctx, **KW) as r:
        f5 = r.render("tsd")
    assert np.array_equal(a1, f1)
    assert np.array_equal(a5, f5)
    assert np.array_equal(a3, b3)
    assert np.abs(a3.astype(np.float64) - a1).max() > 0.002  # the two decoys light the shadowed side (~0.008)


# ---------------------------------------------------------------------- the light pass per light signature
# tsd's irradiance light pass (the split's full-screen pass, tsd/irradiance.frag with SKIN_BOUNCE_FROM_INPUTS)
# is compiled per light signature as well (dermis.techniques.shared.light_signature: each light's kind and
# shadow kernel as constants, SKIN_LIGHT_KINDS / SKIN_SHADOW_FILTERS) and reads its inputs through TEXEL
# (common/texel.glsl). The reference is the program before that (round 23's): the same source with the
# kinds and kernels read from the uniforms at run time and the inputs by texelFetch. The same arithmetic on
# the path a light takes, so every target and the image must be equal BIT FOR BIT, for every kind and
# kernel (shadow_pcf_at's parabola and box, softness 0's one tap, no shadow, a softness at the fit left to
# run time); a kernel or kind compiled wrong changes them (checked in the same test).
def _signature_scene(case: str):
    """The shadow-edge scene (test_tsd_sharp_shadow._scene: the key directional light in slot 2) with a
    point and a spot light that the occluder's edge shadows on the receiver too (~1 irradiance each, as
    the key). "three": point (box), spot (softness 0: one tap), key (parabola): the sharp shadows stored.
    "four" (per sample): a directional light casting no shadow, the spot at the parabola/box fit (left to
    run time), the point with a parabola, the key with a box."""
    from dermis.scene.model import Light

    sc, _ = _scene(2, 3)
    key = sc.lights[2]
    point = Light(kind="point", position=(-2.0, 0.0, 6.0), intensity=0.004, shadow_softness=3.0)
    spot = Light(kind="spot", position=(3.0, 0.0, 6.0), direction=tuple(np.array([-4.5, 0.0, -6.0]) / 7.5),
                 spot_angle_deg=40.0, intensity=0.006, shadow_softness=0.0)
    if case == "three":
        lights = [point, spot, key]
    else:
        lights = [replace(sc.lights[0], cast_shadows=False), replace(spot, shadow_softness=1.6457),
                  replace(point, shadow_softness=1.0), replace(key, shadow_softness=2.5)]
    return replace(sc, lights=lights)


def _round23_light_pass(gl_ctx, prog, signature_defines=None):
    """``prog``'s sources compiled as before round 24 (no signature, texelFetch), or with
    ``signature_defines`` in place of the program's own."""
    from dermis.gl.shaders import load_shader_source

    vert, frag, defines, _ = prog.extra["sources"]
    defines = {k: v for k, v in defines.items() if k not in SIGNATURE_DEFINES}
    fs = load_shader_source(frag, {**defines, **(signature_defines or {})})
    if signature_defines is None:
        for old, new in [(f"TEXEL(uBounceInputs[{k}], t)", f"texelFetch(uBounceInputs[{k}], t, 0)") for k in range(5)] \
                + [("TEXEL(uAlbedoRest, t)", "texelFetch(uAlbedoRest, t, 0)")]:
            assert old in fs
            fs = fs.replace(old, new)
    return gl_ctx.program(vertex_shader=load_shader_source(vert, defines), fragment_shader=fs)


def _signature_targets(r, t, n):
    r.invalidate()  # every pass drawn again (else the texture-space passes are the last frame's)
    img = r.render("tsd")
    keys = ["irradiance", ("bounce_exitant", 0)] + (["sharp_shadow"] if n <= STORED_SHARP_SHADOWS else [])
    return {"image": img, **{str(k): np.frombuffer(t.tex[k].read(), np.uint8) for k in keys},
            "irradiance_f": np.frombuffer(t.tex["irradiance"].read(), np.float16).astype(np.float64)}


@pytest.mark.parametrize("case", ["three", "four"])
def test_light_signature_pass_equals_round23_bit_for_bit(gl_ctx, case):
    from dermis.gl.shadows import (SHADOW_FILTER_BOX, SHADOW_FILTER_NONE, SHADOW_FILTER_PARABOLA,
                                   SHADOW_FILTER_RUNTIME)
    from dermis.techniques.shared import light_signature, signature_defines

    sc = _signature_scene(case)
    P, B, R, N = SHADOW_FILTER_PARABOLA, SHADOW_FILTER_BOX, SHADOW_FILTER_RUNTIME, SHADOW_FILTER_NONE
    want = {"three": ((1, B), (2, R), (0, P)), "four": ((0, N), (2, R), (1, P), (0, B))}[case]
    assert light_signature(sc.lights) == want  # every kind and kernel is exercised
    n = len(sc.lights)
    # the guard (three): the box and one-tap kernels compiled as a parabola and a box, or every light
    # taken as directional, must differ from the reference by more than 0.1 % of its maximum
    wrong = [{"SKIN_SHADOW_FILTERS": "1, 2, 2"}, {"SKIN_LIGHT_KINDS": "0, 0, 0"}] if case == "three" else []
    with Renderer(sc, (W, H), ctx=gl_ctx, **KW) as r:
        t = r.technique("tsd")
        own_prog = t._light_programs(n, sc.lights)
        own = _signature_targets(r, t, n)
        refs = [_round23_light_pass(gl_ctx, own_prog)]
        refs += [_round23_light_pass(gl_ctx, own_prog, {**signature_defines(want), **w}) for w in wrong]
        outs, programs = [], t._light_programs
        try:
            for p in refs:
                t._light_programs = lambda n, lights=None, p=p: p
                outs.append(_signature_targets(r, t, n))
        finally:
            t._light_programs = programs
            for p in refs:
                p.release()
    ref = outs[0]
    assert ref["image"].max() > 0.05 and ref["irradiance_f"].max() > 0.5
    for k in own:
        assert np.array_equal(own[k], ref[k]), (k, np.abs(own[k].astype(np.float64) - ref[k]).max())
    for w, bad in zip(wrong, outs[1:]):
        d = np.abs(bad["irradiance_f"] - ref["irradiance_f"]).max()
        assert d > 1e-3 * ref["irradiance_f"].max(), (w, d)
