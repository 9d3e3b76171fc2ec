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
