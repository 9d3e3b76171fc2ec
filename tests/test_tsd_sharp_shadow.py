"""tsd's specular reads the lights' sharp shadows from its texture-space irradiance pass
(tsd/sharp_shadow.glsl) instead of a shadow-map tap per light per screen sample. The reference is
the per-sample path itself: ssss draws the same skin_specular_radiance (common/skin_specular.glsl)
with shadow_sharp at every sample, so tsd's specular must equal ssss's everywhere but within about
an irradiance texel of a shadow edge, for every light's channel of the stored target (coverage and
lights 0-2). A scene of more lights draws tsd's per-sample programs (one target more would need
17 texture units in the final pass), which must then agree with ssss too."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dermis.renderer import Renderer
from dermis.scene.model import Light
from dermis.techniques.shared import OutputMode
from dermis.techniques.tsd import STORED_SHARP_SHADOWS, stores_sharp_shadows

from test_shadow_edge_rim import H, MM_PER_UNIT, W, _edge_scene

TEXEL_MM = 0.14  # the receiver's irradiance texel at 1024^2 (test_shadow_edge_rim's layout)


def _scene(edge_light: int, count: int):
    """The half-plane edge of test_shadow_edge_rim, specular on, its key light at index
    ``edge_light`` of ``count`` lights; the others are decoys from the other side (-x), which the
    occluder does not shadow in the window, at 3% of the key's intensity each: a light read
    from another light's channel would be lit inside the key's shadow."""
    sc, x_edge_mm = _edge_scene()
    key = sc.lights[0]
    theta = np.radians(45.0)
    decoy = Light(kind="directional", direction=(-np.sin(theta), 0.0, -np.cos(theta)), intensity=0.03)
    lights = [decoy] * count
    lights[edge_light] = key
    material = replace(sc.material, rho_s=0.3)
    return replace(sc, lights=lights, material=material), x_edge_mm


def test_the_stored_shadows_are_used_up_to_three_lights():
    assert STORED_SHARP_SHADOWS == 3  # one RGBA8 target: coverage and three lights (tsd/sharp_shadow.glsl)
    assert [stores_sharp_shadows(n) for n in (0, 1, 3, 4, 8)] == [True, True, True, False, False]


@pytest.mark.parametrize("edge_light,count", [(2, 3), (4, 5)])
def test_stored_sharp_shadow_matches_per_sample_shadow(gl_ctx, edge_light, count):
    """tsd's specular across the key light's shadow edge vs ssss's (the same BRDF and lights with
    shadow_sharp per sample), relative to the lit specular: within 0.5% at every pixel more than
    0.3 mm (about two irradiance texels) from the edge, within 60% on the edge (the stored
    shadow is read bilinearly between texels 0.14 mm apart, where ssss's steps within its shadow
    texel); the edge's 50% crossing within one irradiance texel of ssss's. Light 2 is the target's
    last channel: read from another channel (a decoy's or coverage), the shadowed side would carry
    the key's light. Five lights: the per-sample programs."""
    sc, _ = _scene(edge_light, count)
    with Renderer(sc, (W, H), ctx=gl_ctx, samples=0, irradiance_size=1024, shadow_size=4096) as r:
        ref = r.render("ssss", output_mode=OutputMode.SPECULAR)[H // 2].astype(np.float64)
        tsd = r.render("tsd", output_mode=OutputMode.SPECULAR)[H // 2].astype(np.float64)
    x_mm = (np.arange(W) + 0.5) / W * 20.0  # 0.1 mm per pixel
    lit = ref[-5:, 1].mean()
    dark = ref[:5, 1].mean()
    assert lit > 1e-4 and lit > 3.0 * dark, (lit, dark)  # the key's highlight is there, and shadowed
    half = 0.5 * (lit + dark)
    x_ref = np.interp(half, ref[:, 1], x_mm)  # ref rises across the edge
    x_tsd = np.interp(half, tsd[:, 1], x_mm)
    assert abs(x_tsd - x_ref) < TEXEL_MM, (x_tsd, x_ref)
    err = np.abs(tsd - ref).max(axis=1) / lit
    near = np.abs(x_mm - x_ref) <= 0.3
    assert err[~near].max() < 0.005, (err[~near].max(), x_mm[~near][np.argmax(err[~near])])
    assert err[near].max() < 0.6, err[near].max()


def test_stored_sharp_shadow_follows_a_light_move(gl_ctx):
    """Invalidation: the stored shadows are rebuilt with the irradiance (the texture-space key).
    After the key light turns in a live Renderer (its shadow edge moves 1 mm), tsd's specular equals
    a fresh Renderer's of the turned scene, and differs from the first frame's (the edge moved)."""
    sc, _ = _scene(0, 1)
    theta = np.arctan(2.1 / 2.0)  # the edge at x = 21 mm instead of 20
    turned = replace(sc, lights=[replace(sc.lights[0], direction=(np.sin(theta), 0.0, -np.cos(theta)))])
    kw = dict(ctx=gl_ctx, samples=0, irradiance_size=256, shadow_size=1024)
    with Renderer(sc, (W, H), **kw) as r:
        first = r.render("tsd", output_mode=OutputMode.SPECULAR)
        r.set_scene(turned)
        live = r.render("tsd", output_mode=OutputMode.SPECULAR)
    with Renderer(turned, (W, H), **kw) as r:
        fresh = r.render("tsd", output_mode=OutputMode.SPECULAR)
    assert np.abs(first - fresh).max() > 0.2 * fresh.max()
    assert np.array_equal(live, fresh)
