"""A straight occluder edge must cast a straight shadow edge (issue 12, "staircases"): a shadow
map of texels several pixels wide, read by a box-weighted (nearest-texel) PCF, draws the edge as
steps of one texel along it; dermis's bilinear-compare taps with the separable parabola weights
(common/shadow.glsl) must not. A receiver quad (z = 0) and, h = 5 mm above it, an occluder whose
edge runs at 20 degrees to x (oblique to the map's texel grid); a directional light at 45 degrees
from +y; the camera straight above sees the shadow edge y = x tan(20) - h. Per image column the
edge's position (the row where the radiance crosses half the lit value, linearly interpolated)
must lie on a straight line (least-squares fit) within 0.15 shadow-map texels rms (here a
texel is ~5.5 pixels). Measured on llvmpipe: 0.079 texels (a ripple of +-0.4 px, invisible); with
the atlas sampled NEAREST (the same taps without the bilinear compare's weights: steps of one
texel along the edge) 0.276: the test separates the two. main passes it as well. The staircases seen in the side
scene's crops are NOT this: they are in Cycles as well (the scan's normal map at a grazing
light; benchmarks/RESULTS.md, round 8 shadow8).
"""

from __future__ import annotations

import math

import numpy as np

from dermis.renderer import Renderer
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial

H_MM = 5.0
ANGLE_DEG = 20.0
SHADOW_SIZE = 256
W = 192


def quad(corners):
    p = np.asarray(corners, np.float32)
    n = np.broadcast_to(np.cross(p[1] - p[0], p[3] - p[0]) / np.linalg.norm(np.cross(p[1] - p[0], p[3] - p[0])), (4, 3))
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return p, n, uv, np.array([[0, 1, 2], [0, 2, 3]])


def edge_scene():
    t = math.tan(math.radians(ANGLE_DEG))
    rx = quad([(-30, -30, 0), (30, -30, 0), (30, 30, 0), (-30, 30, 0)])
    # occluder: the band above y = x tan(20) (its edge), from x = -30 to 30, at z = h, facing +z
    ox = quad([(-30, -30 * t, H_MM), (30, 30 * t, H_MM), (30, 40, H_MM), (-30, 40, H_MM)])
    p = np.concatenate([rx[0], ox[0]])
    n = np.concatenate([rx[1], ox[1]])
    uv = np.concatenate([rx[2] * [1, 0.5], ox[2] * [1, 0.5] + [0, 0.5]])  # disjoint UV islands
    tri = np.concatenate([rx[3], ox[3] + 4])
    mesh = finish_mesh(p, n, uv, tri, "test:edge", "v-up")
    s = 1.0 / math.sqrt(2.0)
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=(1.0, 1.0, 1.0), rho_s=0.0, pore_strength=0.0),
                 lights=[Light(direction=(0.0, -s, -s), intensity=math.pi, shadow_softness=1.5)],
                 camera=Camera(position=(0.0, -5.0, 80.0), target=(0.0, -5.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=12.0),
                 environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0, name="edge")


def edge_rows(img):
    """Per column, the sub-pixel row where the radiance crosses half the lit value, lowest in the
    image (row 0 at the top = +y): the receiver lit below, its shadow above."""
    lum = img.mean(axis=2)
    lit = np.percentile(lum, 95)
    rows = []
    for x in range(lum.shape[1]):
        col = lum[:, x] / lit
        k = np.nonzero((col[:-1] < 0.5) & (col[1:] >= 0.5))[0]  # shadow above, lit below
        if len(k) == 0:
            rows.append(np.nan)
            continue
        k = k[-1]  # the lowest crossing: lit receiver -> its shadow (the lit occluder is above it)
        rows.append(k + (0.5 - col[k]) / (col[k + 1] - col[k]))
    return np.asarray(rows)


def straightness_texels(gl_ctx, technique="lambert"):
    sc = edge_scene()
    with Renderer(sc, (W, W), ctx=gl_ctx, samples=0, shadow_size=SHADOW_SIZE) as r:
        img = r.render(technique).astype(np.float64)
        half_extent = float(r._lights.map_half_extent[0])
    y = edge_rows(img)
    x = np.arange(W, dtype=np.float64)
    ok = np.isfinite(y)
    ok[: W // 8] = ok[-W // 8:] = False
    assert ok.sum() > W // 2, "the shadow edge is not where the scene puts it"
    a, b = np.polyfit(x[ok], y[ok], 1)
    resid = y[ok] - (a * x[ok] + b)
    # pixels per shadow texel on the receiver: the view spans 2 d tan(fov/2) mm over W pixels; the
    # tile 2 half_extent over SHADOW_SIZE texels, stretched by 1/cos(45) along y on the receiver
    px_mm = W / (2.0 * 80.0 * math.tan(math.radians(6.0)))
    texel_mm = 2.0 * half_extent / SHADOW_SIZE * math.sqrt(2.0)
    return float(np.sqrt(np.mean(resid ** 2))) / (texel_mm * px_mm), a


def test_straight_occluder_edge_casts_a_straight_shadow_edge(gl_ctx):
    rms, slope = straightness_texels(gl_ctx)
    assert abs(math.degrees(math.atan(abs(slope))) - ANGLE_DEG) < 2.0, slope  # the edge the scene casts
    assert rms < 0.15, rms
