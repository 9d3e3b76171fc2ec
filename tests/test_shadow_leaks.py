"""Shadows without leaks: the side view's shadowed eye socket, behind the nose bridge."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dermis
from dermis.renderer import Renderer

REPO = Path(__file__).resolve().parent.parent
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def test_side_view_eye_socket_has_no_lit_blob(lee_perry_smith, gl_ctx):
    """examples/reference/side.toml with lambert at 256 px: in the eye socket shadowed by the nose
    bridge (rows 90-130, columns 30-80) the brightest pixel is under 3x the region's median.
    Before the receiver-plane bias: 0.081 against a median of 0.0072 (11x), the normal offset
    having moved the lookup of a grazing receiver across the nose bridge's silhouette in the map."""
    sc = dermis.load_scene(REPO / "examples" / "reference" / "side.toml")
    with Renderer(sc, (256, 256), ctx=gl_ctx, samples=0) as r:
        img = r.render("lambert")
    region = img[90:130, 30:80] @ LUMINANCE
    median = np.median(region)
    assert median > 1e-3  # the region is on the head and receives the ambient
    assert region.max() < 3.0 * median, (region.max(), median)


def _shadow_vs_ray_cast(scene_path, light_index, gl_ctx, size=256, bias_scale=1.0):
    """(mean boundary shift in pixels, leaked pixels / ray-cast shadowed pixels) of one light's
    shadow-map shadow against the hard shadow a ray cast from each pixel's surface point finds.

    Both images are lambert with only that light, no ambient, no bounce, no specular, one sample per
    pixel (its centre); the shadow map's visibility at a pixel is the shadowed render over the one
    without shadows (the light's N.L cancels). Only pixels whose own triangle faces the light are
    counted: where the smooth shading normal faces the light and the triangle does not (the
    terminator) the ray cast calls the pixel shadowed by its own surface, the shading says lit at a
    grazing N.L, and neither is the shadow map's business. The shift is the shadow map's excess lit
    area over the ray cast's (a pixel half lit counts half) per pixel of the ray-cast shadow's
    boundary: > 0 light reaches into the shadow (bias, normal offset), < 0 the shadow grows (acne)."""
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    def scene(shadows):
        sc = dermis.load_scene(scene_path)
        sc.material.rho_s = 0.0
        sc.material.pore_strength = 0.0
        sc.environment.color = (0.0, 0.0, 0.0)
        sc.environment.image = None
        sc.interreflection = False
        sc.lights = [sc.lights[light_index]]
        sc.lights[0].cast_shadows = shadows
        sc.lights[0].shadow_bias *= bias_scale
        return sc

    lum = []
    for shadows in (True, False):
        with Renderer(scene(shadows), (size, size), ctx=gl_ctx, samples=0) as r:
            lum.append(r.render("lambert")[..., :3].astype(np.float64) @ LUMINANCE)
    shadowed, unshadowed = lum
    sc = scene(True)
    o, d, tmax, _ = camera_rays(sc, (size, size), camera=framed_camera(sc.camera, sc.mesh, 1.0))
    caster = RayCaster(sc.mesh.positions, sc.mesh.indices)
    t, tri, _ = caster.closest_hit(o, d, 0.0, tmax)
    hit = tri >= 0
    p = o + d * np.where(hit, t, 0.0)[:, None]
    v = sc.mesh.positions[sc.mesh.indices[np.maximum(tri, 0)]].astype(np.float64)
    ng = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True) + 1e-30
    to_light = -np.asarray(sc.lights[0].direction, np.float64)
    to_light /= np.linalg.norm(to_light)
    ray_lit = ~caster.occluded(p + ng * 1e-4, np.broadcast_to(to_light, p.shape), 1e-5, skip=tri)
    shape = (size, size)
    ray_lit = ray_lit.reshape(shape).astype(np.float64)
    m = (hit & (ng @ to_light > 0.0)).reshape(shape) & (unshadowed > 1e-3 * unshadowed.max())
    map_lit = np.where(m, shadowed / np.maximum(unshadowed, 1e-12), 0.0)
    edge = np.zeros(shape, bool)
    edge[:, 1:] |= (ray_lit[:, 1:] != ray_lit[:, :-1]) & m[:, 1:] & m[:, :-1]
    edge[1:] |= (ray_lit[1:] != ray_lit[:-1]) & m[1:] & m[:-1]
    in_shadow = m & (ray_lit < 0.5)
    assert edge.sum() > 10 and in_shadow.sum() > 100, (edge.sum(), in_shadow.sum())  # a shadow to judge
    shift = float((map_lit - ray_lit)[m].sum() / edge.sum())
    leaked = float((in_shadow & (map_lit > 0.5)).sum() / in_shadow.sum())
    return shift, leaked


@pytest.mark.parametrize("scene_file, light_index", [("reference/front-key.toml", 0), ("lee-perry-smith.toml", 0),
                                                      ("lee-perry-smith.toml", 1), ("lee-perry-smith.toml", 2)])
def test_shadow_map_shadows_are_the_ray_cast_shadows(lee_perry_smith, gl_ctx, scene_file, light_index):
    """Each light's shadow on the head (256 px) against the hard shadow an independent ray cast
    (dermis.geometry.raycast, Embree) finds: the boundary within 0.75 px of the ray cast's on average
    and at most 12 % of the ray-cast shadow lit by the map. Measured (round 15): shifts +0.10 (front-
    key), +0.04 / +0.10 / +0.57 px (the example's three lights), leaked 1-6 %; with the depth bias
    x20 the shifts are +1.0 / +1.8 / +2.6 / +2.2 px and 15-39 % leaked, with no bias -0.70 px (acne)
    for the example's second light."""
    shift, leaked = _shadow_vs_ray_cast(REPO / "examples" / scene_file, light_index, gl_ctx)
    assert abs(shift) < 0.75, shift
    assert leaked < 0.12, leaked


def test_shadow_comparison_sees_a_biased_shadow_map(lee_perry_smith, gl_ctx):
    """The measure above fails a shadow map whose depth bias lets light into the shadow (x20)."""
    shift, leaked = _shadow_vs_ray_cast(REPO / "examples" / "lee-perry-smith.toml", 1, gl_ctx, bias_scale=20.0)
    assert shift > 0.75 and leaked > 0.12, (shift, leaked)
