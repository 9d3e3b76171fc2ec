"""The bump terminator (issue 12; common/bump_shadowing.glsl): a normal map that tilts the shading
normal toward a light grazing the smooth surface must not keep the facet's full N.L up to the smooth
surface's horizon and drop to 0 there in one step (the hard, serrated terminator).

A flat quad (smooth normal +z) with a CONSTANT normal map tilted by d = 30 degrees toward +x, lit
by a directional light from +x at elevation e above the quad. Independent references, numpy:
- energy: the quad intercepts E sin(e) per unit area; a Lambertian quad of uniform radiance Lo
  leaves pi Lo, so Lo <= albedo E sin(e) / pi up to the facet's area 1 / cos(d) and the cubic's
  at most 5/4 overshoot. Without the term Lo = albedo E sin(e + d) / pi: at e = 3 degrees 10x
  that bound (0.545 vs 0.0523) and a jump to 0 when e crosses the horizon.
- the closed form of Chiang, Li & Burley 2019 (as Blender Cycles' bump_shadowing_term):
  Lo = albedo E / pi sin(e + d) G(g), g = sin(e) / (sin(e + d) cos(d)), G = g + g^2 - g^3 (g < 1).
Lambert (diffuse only: rho_s 0, no environment) and tsd (the skin's entry, common/skin_irradiance.glsl;
on a uniform quad the blurs keep the constant), each as ratios to e = 60 degrees (g = 1, G = 1) so that
the techniques' own constant factors cancel. tsd's directional albedo is off (its k(N.L) is
tested elsewhere).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dermis.renderer import Renderer
from dermis.scene.model import Light, SkinMaterial, Texture
from dermis.verification import quad_scene

TILT_DEG = 30.0
ELEVATIONS_DEG = (3.0, 8.0, 15.0, 30.0, 60.0)


def chiang_lo(e_deg: float, d_deg: float = TILT_DEG) -> float:
    """Lo pi / (albedo E) with the bump terminator's term: sin(e + d) G(g)."""
    e, d = math.radians(e_deg), math.radians(d_deg)
    ndl = math.sin(e + d)
    g = math.sin(e) / (ndl * math.cos(d))
    G = 1.0 if g >= 1.0 else max(g, 0.0) * (1.0 + g - g * g)
    return ndl * G


def tilted_quad(technique: str):
    sc = quad_scene(20.0, 20.0)
    d = math.radians(TILT_DEG)
    n = np.array([math.sin(d), 0.0, math.cos(d)], np.float32)  # tangent space: +u is +x on the quad
    tex = np.ascontiguousarray(np.broadcast_to(0.5 * n + 0.5, (16, 16, 3)), np.float32)
    sc.material = SkinMaterial(albedo_color=(1.0, 1.0, 1.0), rho_s=0.0, pore_strength=0.0,
                               normal_map=Texture(tex, "test:tilted normals"))
    sc.technique = technique
    if technique == "tsd":
        sc = dataclasses.replace(sc, directional_albedo=False)
    return sc


def radiance_at(ctx, technique: str, elevations) -> np.ndarray:
    sc = tilted_quad(technique)
    out = []
    W = 64
    with Renderer(sc, (W, W), ctx=ctx, samples=0, irradiance_size=256) as r:
        for e_deg in elevations:
            e = math.radians(e_deg)
            # direction the light travels: from +x, e above the quad
            r.scene.lights = [Light(direction=(-math.cos(e), 0.0, -math.sin(e)), intensity=math.pi, cast_shadows=False)]
            r.set_scene(r.scene)
            img = r.render(technique).astype(np.float64)
            c = img[W // 2 - 8:W // 2 + 8, W // 2 - 8:W // 2 + 8]  # the quad's centre, away from its edges
            out.append(float(np.median(c.mean(axis=2))))
    return np.asarray(out)


@pytest.mark.parametrize("technique", ["lambert", "tsd"])
def test_tilted_normal_map_fades_at_the_smooth_horizon(gl_ctx, technique):
    lo = radiance_at(gl_ctx, technique, ELEVATIONS_DEG)
    rel = lo / lo[-1]  # e = 60: g = sin 60 / (sin 90 cos 30) = 1, G = 1
    ref = np.array([chiang_lo(e) for e in ELEVATIONS_DEG]) / chiang_lo(60.0)
    # energy bound (independent of the term): Lo pi / (albedo E) <= 1.25 sin(e) / cos(d)
    bound = np.array([1.25 * math.sin(math.radians(e)) / math.cos(math.radians(TILT_DEG)) for e in ELEVATIONS_DEG])
    assert np.all(rel * chiang_lo(60.0) <= bound * 1.02), (technique, rel, bound)
    np.testing.assert_allclose(rel, ref, rtol=0.03, atol=0.002, err_msg=technique)
