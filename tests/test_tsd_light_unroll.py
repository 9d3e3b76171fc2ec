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
from dermis.techniques.shared import MAX_GAUSSIANS
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
