"""Light through a slab met at an angle: the tissue the light diffuses through is the slab's
thickness, whatever the light's direction (issue 12: the back-lit ear, nearly edge-on to the
light, transmitted almost nothing when the distance was taken along the light)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dermis
from dermis.renderer import Renderer
from dermis.profiles.thin_slab import slab_law
from dermis.verification import SKIN_ALBEDO, backlit_slab_scene


@pytest.mark.parametrize("technique, angle_deg", [("tsd", 60.0), ("tsd", 80.0), ("ssss", 60.0), ("ssss", 80.0),
                                                  ("preintegrated", 60.0), ("preintegrated", 80.0)])
def test_translucency_of_a_slab_lit_obliquely(gl_ctx, technique, angle_deg):
    """Light at angle theta to a 2 mm slab's normal: the far face receives E cos(theta) and the
    tissue between the faces is 2 mm thick, so the front transmits
    cos(theta) T(d), T the thin-slab law (dermis.profiles.thin_slab; within 5% + 1e-4), not T(d / cos theta)
    of the path along the light (6x less at 60 degrees, nothing at 80: measured before the fix).
    ssss and preintegrated read the far face behind the pixel since round 4 (before, the
    translucent shadow map's entry point and a ramp over -N.L in [0, 0.25]: 16-22% low at 80
    degrees, and a hard-edged switch between the map's path and the bake's thickness on the ear)."""
    d, th = 2.0, np.radians(angle_deg)
    law = slab_law(dermis.profiles.deon_skin(), np.array(SKIN_ALBEDO))
    sc = backlit_slab_scene(d, albedo=SKIN_ALBEDO)
    sc.lights = [dataclasses.replace(sc.lights[0], direction=(float(np.sin(th)), 0.0, float(np.cos(th))))]
    with Renderer(sc, (48, 48), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        img = r.render(technique, output_mode=1)
    front = img[20:28, 20:28].reshape(-1, 3).mean(axis=0)
    expected = np.cos(th) * law.transmittance(d)
    assert np.all(np.abs(front - expected) <= 0.05 * expected + 1e-4), (front, expected)


def _stepped_slab_scene(thin_mm: float, thick_mm: float, size_mm: float = 30.0, n: int = 32):
    """backlit_slab_scene's slab (front face z = thin/2, one UV island) whose back face steps from
    thin_mm (x < 0) to thick_mm (x > 0): every vertex is pushed back in proportion to its depth."""
    from dermis.scene.builtin import slab
    from dermis.scene.loaders import finish_mesh, vertex_normals

    sc = backlit_slab_scene(thin_mm, size_mm=size_mm, n=n, albedo=SKIN_ALBEDO)
    p, nn, uv, t = slab(size=size_mm, thickness=thin_mm, n=n)
    p = np.array(p, np.float64)
    depth = (thin_mm / 2 - p[:, 2]) / thin_mm  # 0 on the front face, 1 on the back
    p[:, 2] -= np.where(p[:, 0] > 0.0, (thick_mm - thin_mm) * depth, 0.0)
    sc.mesh = finish_mesh(p, vertex_normals(p, np.asarray(t).reshape(-1, 3)), uv, t,
                          f"test:stepped slab {thin_mm}-{thick_mm}", "v-up")
    return sc


@pytest.mark.parametrize("technique", ["preintegrated", "ssss"])
def test_far_face_of_a_thickness_step_is_not_self_shadowed(gl_ctx, technique):
    """A slab 2 mm thick for x < 0 and 4 mm for x > 0 lit from behind at 78 degrees (cos 0.2 on the
    far faces, as the back-lit helix). The bake's thickness is smoothed by a soft minimum over its
    neighbours (geometry/thickness.py), so beside the step the thick side's h is up to ~1 mm short
    and A = P - h N lies inside the tissue. Its shadow must still see the far face lit: the front's
    transmitted light across the thick side near the step never falls below the thick side's own
    level far from the step (where T(4 mm) cos holds). Lifting A 0.5 mm along the light (rounds
    4-6) moved it 0.1 mm off the face: it shadowed itself and drew a dark band along the step
    (the dark wedge at the top of the back-lit helix, issue 12): measured before the fix,
    preintegrated 0 over 0.5-1.6 mm from the step, ssss down to 0.60 of the thick side's level."""
    th = np.radians(78.0)
    sc = _stepped_slab_scene(2.0, 4.0)
    sc.lights = [dataclasses.replace(sc.lights[0], direction=(0.0, float(np.sin(th)), float(np.cos(th))))]
    with Renderer(sc, (96, 96), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        img = r.render(technique, output_mode=1)[..., :3].astype(np.float64)
    W = img.shape[1]
    ppm = W / (2.0 * 120.0 * np.tan(np.radians(5.0)))  # pixels per mm on the front face (fov 10)
    xs = (np.arange(W) + 0.5 - W / 2) / ppm
    red = img[W // 2 - 8:W // 2 + 8, :, 0].mean(axis=0)
    far = red[(xs > 6.0) & (xs < 10.0)].mean()  # the thick side, 6-10 mm from the step
    near = red[(xs > 0.3) & (xs < 3.0)]
    law = slab_law(dermis.profiles.deon_skin(), np.array(SKIN_ALBEDO))
    expected_far = np.cos(th) * law.transmittance(4.0)[0]
    assert abs(far - expected_far) <= 0.1 * expected_far, (far, expected_far)  # the thick side: a 4 mm slab
    assert near.min() >= 0.9 * far, (near, far)


def _plate_with_a_layer_behind(plate_mm: float, gap_mm: float, layer_mm: float, size_mm: float = 30.0):
    """backlit_slab_scene's plate (front face z = plate/2, lit from behind along +z) and, behind its
    x > 0 half, a second layer of tissue layer_mm thick across an air gap of gap_mm: the top of the
    back-lit scapha in one dimension (benchmarks/farface_occluder.py: the far face ~3.7 mm behind
    the front, 0.7-2.1 mm of air, a layer of the helix ~3 mm thick)."""
    from dermis.scene.builtin import box, merge, slab
    from dermis.scene.loaders import finish_mesh

    sc = backlit_slab_scene(plate_mm, size_mm=size_mm, n=32, albedo=SKIN_ALBEDO)
    z = -plate_mm / 2 - gap_mm - layer_mm / 2
    layer = box((size_mm / 4, 0.0, z), (size_mm / 4, size_mm / 2, layer_mm / 2), uv_origin=(0.0, 2 / 3), uv_cell=1 / 9,
                n=16, gutter=0.01)
    p, nn, uv, t = merge([slab(size=size_mm, thickness=plate_mm, n=32), layer])
    sc.mesh = finish_mesh(p, nn, uv, t, f"test:plate {plate_mm} with a layer behind", "v-up")
    return sc


@pytest.mark.parametrize("technique", ["preintegrated", "ssss"])
def test_far_face_shadowed_by_a_layer_behind_it_ramps_over_the_slabs_spread(gl_ctx, technique):
    """A 3 mm plate whose far face lies, for x > 0, in the shadow of a 3 mm layer 1 mm behind it (the
    back-lit scapha, round 18). The light that reaches the front at x entered the far face anywhere
    within the slab's lateral spread (per-axis variance v(3 mm), SlabLaw.transmitted_variance), so
    the front ramps across the shadow's edge, as the box of that variance (half-width a = sqrt(3 v),
    3.7 mm) over a step: cos T(3 mm) (the law) far on the lit side, (a - x) / 2a of it within a of the
    edge (within 0.04: the square's taps on an axis-aligned grid made 7 levels of it, 0.08 off: bands),
    nothing beyond (no light leaks through the layer's shadow). Measured before the fix (point
    lookups of the far face's shadow): a step at the edge, preintegrated 0.999 of the level 0.08 mm
    before it and 0 at 0.08 mm past it (0.49 off the ramp), ssss 0.24 off it (its screen blur softens
    the step)."""
    d = 3.0
    sc = _plate_with_a_layer_behind(d, 1.0, 3.0)
    law = slab_law(dermis.profiles.deon_skin(), np.array(SKIN_ALBEDO))
    a = float(np.sqrt(3.0 * law.transmitted_variance(d)[0]))
    with Renderer(sc, (128, 128), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        img = r.render(technique, output_mode=1)[..., :3].astype(np.float64)
    W = img.shape[1]
    ppm = W / (2.0 * (120.0 - d / 2) * np.tan(np.radians(5.0)))  # pixels per mm on the front face (fov 10)
    xs = (np.arange(W) + 0.5 - W / 2) / ppm
    red = img[W // 2 - 8:W // 2 + 8, :, 0].mean(axis=0)
    level = law.transmittance(d)[0]  # cos = 1: the light along the plate's normal
    lit = red[xs < -a - 1.0]
    assert np.all(np.abs(lit - level) <= 0.1 * level), (lit, level)
    assert np.all(red[xs > a + 1.0] <= 0.02 * level), red[xs > a + 1.0]
    ramp = np.abs(xs) < 0.8 * a
    expected = np.clip((a - xs[ramp]) / (2.0 * a), 0.0, 1.0)
    err = np.abs(red[ramp] / level - expected)
    assert err.max() <= 0.04, (xs[ramp][np.argmax(err)], red[ramp] / level, expected)


def _flap_scene(body: bool, width_mm: float = 10.0, thick_mm: float = 5.0, cut_mm: float = 2.5, length_mm: float = 30.0):
    """A rounded flap (an elliptic cylinder width_mm x thick_mm across, along y, front apex at z = thick / 2)
    lit from behind along +z, whose -x side ends at x = -cut_mm; with ``body``, in the +x face of a block
    20 mm deep behind it (the back-lit lobe's root in the cheek, round 23). The light along +z grazes the
    block's +x face, so the block shadows none of the flap's back."""
    from dermis.scene.builtin import box, grid_mesh, merge
    from dermis.scene.loaders import finish_mesh

    a, c = width_mm / 2, thick_mm / 2
    th1 = np.arccos(-cut_mm / a)

    def fn(u, v):
        t = th1 - 2.0 * th1 * u  # the front from the cut, round the free edge (x = +a), the back to the cut
        p = np.stack([a * np.cos(t), (v - 0.5) * length_mm, c * np.sin(t)], -1)
        n = np.stack([c * np.cos(t), np.zeros_like(t), a * np.sin(t)], -1)
        return p, n / np.linalg.norm(n, axis=-1, keepdims=True)

    parts = [grid_mesh(64, 24, fn, (0.02, 0.02, 0.98, 0.6))]
    if body:
        zf = c * np.sin(th1)  # the flap's front where it meets the block
        parts.append(box((-cut_mm - 10.0, 0.0, (zf - 20.0) / 2), (10.0, length_mm / 2, (zf + 20.0) / 2),
                         uv_origin=(0.0, 2 / 3), uv_cell=1 / 9, n=16, gutter=0.01))
    p, nn, uv, t = merge(parts)
    sc = backlit_slab_scene(thick_mm, albedo=SKIN_ALBEDO)
    sc.mesh = finish_mesh(p, nn, uv, t, f"test:flap {width_mm} x {thick_mm} body {body}", "v-up")
    return sc


@pytest.mark.parametrize("technique, near_mm", [("preintegrated", (-2.0, 0.5)), ("ssss", (-0.5, 1.5))])
def test_far_face_of_a_rounded_flap_beside_a_body_is_lit(gl_ctx, technique, near_mm):
    """A back-lit rounded flap 10 mm wide and 5 mm thick whose root lies in a block (the back-lit lobe in the
    cheek, round 23): the block shadows none of the flap's back (ray cast below), so the light through the
    flap beside it is the isolated flap's (within 5%). The far-face shadow's square (half-width 4.9 mm at
    h = 5 mm) reaches past the root into the block; rounds 18-22 put its taps on planes through A, which
    inside the block read shadow: measured before the fix (common/transmittance.glsl), 0.79-0.83 of the
    isolated flap's light over the 2.5 mm beside the block (by a ray-cast replica of those taps, the box
    0.72-0.78 there: benchmarks/far_face_box.py), preintegrated 0.72-0.78, ssss 0.61-0.78. ssss is read from
    0.5 mm beside the block on: its screen blur mixes in the block's unlit front (0.83 of the isolated flap's
    at 1.9 mm, 0.97 at 0.5 mm), which is the skin's own scattering, not the far face's shadow."""
    from dermis.geometry.raycast import RayCaster

    red = {}
    for body in (False, True):
        sc = _flap_scene(body)
        with Renderer(sc, (128, 128), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
            red[body] = r.render(technique, output_mode=1)[60:68, :, 0].astype(np.float64).mean(axis=0)
    ppm = 128 / (2.0 * (120.0 - 2.3) * np.tan(np.radians(5.0)))  # pixels per mm on the flap's front (fov 10)
    xs = (np.arange(128) + 0.5 - 64) / ppm
    near = (xs > near_mm[0]) & (xs < near_mm[1])  # the flap's front beside the block (it ends at x = -2.5)
    # the premise, by ray casting: the flap's back behind those pixels sees the light with the block there
    sc = _flap_scene(True)
    P, I = np.asarray(sc.mesh.positions, np.float64), np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    back = np.stack([xs[near], np.zeros(near.sum()), -2.5 * np.sqrt(1.0 - (xs[near] / 5.0) ** 2) - 0.05], 1)
    assert np.all(RayCaster(P, I).closest_hit(back, np.broadcast_to([0.0, 0.0, -1.0], back.shape), 0.0, np.inf)[1] < 0)
    ratio = red[True][near] / red[False][near]
    assert np.all(red[False][near] > 0.0) and np.all(np.abs(ratio - 1.0) <= 0.05), (xs[near], ratio)
