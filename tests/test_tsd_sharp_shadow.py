"""tsd's specular reads the lights' sharp shadows from its texture-space irradiance pass
(tsd/sharp_shadow.glsl) instead of a shadow-map tap per light per screen sample. The reference is
the per-sample path itself: ssss draws the same skin_specular_radiance (common/skin_specular.glsl)
with shadow_sharp at every sample, so tsd's specular must equal ssss's everywhere but within about
an irradiance texel of a shadow edge, for every light's channel of the stored targets (the first
target holds coverage and lights 0-2, the second lights 3-6)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dermis.renderer import Renderer
from dermis.scene.model import Light
from dermis.techniques.shared import OutputMode
from dermis.techniques.tsd import SHARP_SHADOW_TARGETS, sharp_shadow_targets

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


def test_targets_cover_every_light():
    """Channel 0 is coverage, 1 + i light i, four per target: 3 lights need one target, 4-7 two,
    MAX_LIGHTS = 8 three (the GLSL's count, tsd/sharp_shadow.glsl)."""
    assert [sharp_shadow_targets(n) for n in (1, 3, 4, 7, 8)] == [1, 1, 2, 2, 3]
    assert SHARP_SHADOW_TARGETS == sharp_shadow_targets(8)


@pytest.mark.parametrize("edge_light,count", [(2, 5), (4, 5)])
def test_stored_sharp_shadow_matches_per_sample_shadow(gl_ctx, edge_light, count):
    """tsd's specular across the key light's shadow edge vs ssss's (the same BRDF and lights with
    shadow_sharp per sample), relative to the lit specular: within 0.5% at every pixel more than
    0.3 mm (about two irradiance texels) from the edge, within 60% on the edge (the stored
    shadow is read bilinearly between texels 0.14 mm apart, where ssss's steps within its shadow
    texel); the edge's 50% crossing within one irradiance texel of ssss's. Light 4 is in the second
    target: read from a wrong channel or target, the shadowed side would carry the key's light."""
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
