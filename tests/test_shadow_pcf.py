"""The shadow atlas and its percentage-closer filtering (common/shadow.glsl, gl/shadows.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.gl.shadows import PCF_DISC_SCALE, PCF_FIT_INSET, PCF_GRID  # the disc: rounds 1-5's 16 Poisson taps
from dermis.renderer import Renderer
from dermis.scene.builtin import box_over_plane, merge, plane_xy
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Output, Scene, SkinMaterial


def _box_scene(direction=(0.3, 0.2, -1.0), softness=1.5):
    p, n, uv, t = box_over_plane()
    mesh = finish_mesh(p, n, uv, t, "builtin:box_over_plane", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(rho_s=0.0),
                 lights=[Light(kind="directional", direction=direction, intensity=3.0, shadow_softness=softness)],
                 camera=Camera(position=(1.0, 1.3, 2.4), target=(0.25, 0.15, 0.0), fov_deg=40.0))


def test_shadow_pass_is_depth_only(gl_ctx):
    """No translucent-shadow-map colour target: the pass writes the depth atlas and nothing else."""
    with Renderer(_box_scene(), (32, 32), ctx=gl_ctx, samples=0) as r:
        r.render("lambert")
        atlas = r.shadows
        assert atlas.fbo.color_attachments == () and atlas.fbo.depth_attachment is atlas.depth
        assert not hasattr(atlas, "aux")
        assert set(r.debug_buffers("lambert")) & {"shadow_tsm"} == set()


def _plane_scene(direction, softness=1.5):
    p, n, uv, t = plane_xy(size=4.0, n=8)
    mesh = finish_mesh(p, n, uv, t, "builtin:plane", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.5, 0.5, 0.5), rho_s=0.0),
                 lights=[Light(kind="directional", direction=tuple(direction), intensity=1.0, shadow_softness=softness)],
                 camera=Camera(position=(0.0, 0.0, 6.0), target=(0.0, 0.0, 0.0), fov_deg=30.0),
                 environment=Environment(color=(0.0, 0.0, 0.0), occlusion=False),
                 output=Output(background=(0.0, 0.0, 0.0)))


def _direction(ndl, azimuth_deg):
    a, s = np.radians(azimuth_deg), np.sqrt(1.0 - ndl * ndl)
    return (s * np.cos(a), s * np.sin(a), -ndl)


# rounds 1-4 at N.L 0.15: 1.4-2.0% dark in 7-11% of the plane at these azimuths, 0.04% at 0/90/180
@pytest.mark.parametrize("azimuth_deg", [60, 120, 240, 0])
def test_lit_plane_at_a_grazing_light_has_no_self_shadow(gl_ctx, azimuth_deg):
    """A plane with nothing above it is lit everywhere: radiance albedo / pi * E * N.L (closed form).
    The receiver-plane depth of every PCF tap must follow the plane: rounds 1-4 solved its
    gradient with the transposed 2x2 (right only where the light's map axes and the plane's
    tangents happen to align) and shadowed parts of a plane lit at N.L 0.2-0.35."""
    ndl = 0.15
    sc = _plane_scene(_direction(ndl, azimuth_deg))
    expect = 0.5 / np.pi * 1.0 * ndl
    with Renderer(sc, (96, 96), ctx=gl_ctx, samples=0) as r:
        img = r.render("lambert")
    inner = img[16:80, 16:80]  # the plane's middle: 2.4 of its 4 units, away from the map's edge
    rel = np.abs(inner - expect) / expect
    assert rel.max() < 0.005, (rel.max(), (rel > 0.005).mean())  # measured 0.0004




def _disc_step_profile(p, c0, radius, n=400):
    """Closed form of the intended filter across a straight shadow edge, numerically integrated:
    the mean over a disc of ``radius`` texels (uniform) of a bilinear-compare tap, which across a
    rasterised step whose last shadowed texel centre is c0 ramps clamp(x - c0, 0, 1) (texels)."""
    t = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    dx, dy = np.meshgrid(t, t)
    inside = dx * dx + dy * dy <= 1.0
    d = dx[inside] * radius
    return np.clip(np.asarray(p)[:, None] + d[None, :] - c0, 0.0, 1.0).mean(axis=1)


@pytest.mark.parametrize("R", [1.5, 2.0])  # 2.0: the box weights (shadow.glsl picks them from ~1.7 texels)
def test_penumbra_across_a_straight_edge_matches_the_disc_filter(gl_ctx, R):
    """A half-plane occluder (x < 0, height g) over a receiver plane under a directional light
    tilted 35 degrees: the shadow edge lies at x = g tan(35 deg); its penumbra, read along the map
    axis across the edge in a close-up (0.16 texel per pixel), must be the PCF disc's profile of
    ``shadow_softness`` texels (closed form above), centred where the rasterised map puts the edge:
    neither wider or narrower (fewer taps, an early out that skips penumbra texels) nor shifted
    (a leak or peter-panning). PCF's width is in map texels, independent of the gap: a delta light
    filtered, not an area light (whose penumbra would be gap x tan(angular size))."""
    from dermis.gl.resources import LightUniforms

    g, theta, tile = 0.5, np.radians(35.0), 1024
    recv = plane_xy(size=4.0, n=4)
    p, n, uv, t = plane_xy(size=2.0, n=4, z=g)
    occ = (p + np.array([-1.0, 0.0, 0.0]), n, uv, t)  # x in [-2, 0]
    mesh = finish_mesh(*merge([recv, occ]), "builtin:edge", "v-up")
    x_edge = g * np.tan(theta)
    direction = (np.sin(theta), 0.0, -np.cos(theta))
    sc = Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.5, 0.5, 0.5), rho_s=0.0),
               lights=[Light(kind="directional", direction=direction, intensity=1.0, shadow_softness=R)],
               camera=Camera(position=(x_edge, 0.0, 3.0), target=(x_edge, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=1.2),
               environment=Environment(color=(0.0, 0.0, 0.0), occlusion=False), output=Output(background=(0.0, 0.0, 0.0)))
    size = 128
    with Renderer(sc, (size, size), ctx=gl_ctx, samples=0, shadow_size=tile) as r:
        img = r.render("lambert")
    s = img.mean(-1) / (0.5 / np.pi * np.cos(theta))
    # the map: tile texel coordinates of world points (one light: the atlas is one tile)
    vp = LightUniforms(sc).viewproj[0].astype(np.float64)

    def texel(P):
        q = np.c_[P, np.ones(len(P))] @ vp.T
        return (q[:, :2] / q[:, 3:] * 0.5 + 0.5) * tile

    a, b = texel(np.array([[0.0, -1.0, g], [0.0, 1.0, g]]))
    axis = 0 if abs(a[0] - b[0]) < 1e-6 * tile else 1  # the map axis across the edge
    assert abs(a[axis] - b[axis]) < 1e-6 * tile, "the occluder's edge must run along a map axis"
    e = a[axis]  # the edge, in texels; the map is shadowed on the occluder's side of it
    side = np.sign(texel(np.array([[-0.5, 0.0, g]]))[0, axis] - e)
    # the pixel centres' receiver points (camera straight down: x, y linear in the pixel)
    half = 3.0 * np.tan(np.radians(0.6))
    xs = x_edge + ((np.arange(size) + 0.5) / size * 2.0 - 1.0) * half
    # along the light, a receiver point at x sees the map texel of the occluder-height point above it
    u = texel(np.c_[xs - g * np.tan(theta), np.zeros(size), np.full(size, g)])[:, axis]
    assert np.allclose(u, texel(np.c_[xs, np.zeros(size), np.zeros(size)])[:, axis], atol=1e-3)
    row = s[size // 2]
    # in "lit-ward" texel coordinates: x grows away from the occluder
    pos, edge = -side * u, -side * e
    c0 = np.floor(edge - 0.5) + 0.5  # centre of the last shadowed texel
    # the kernel is a disc of 1.307 R (rounds 1-5's 16 Poisson points reached past the unit disc:
    # mean |p|^2 0.854, a uniform disc's is r^2 / 2; a disc of R itself: max error 0.087)
    expect = _disc_step_profile(pos, c0, PCF_DISC_SCALE * R)
    err = np.abs(row - expect)
    assert err.max() < 0.04, err.max()  # measured 0.011 at R 1.5 (the 16 Poisson taps: 0.019)
    # the 50% crossing: where the filtered rasterised step puts it (c0 + 0.5), within 0.2 texel
    half_at = np.interp(0.5, row if row[0] < row[-1] else row[::-1], pos if row[0] < row[-1] else pos[::-1])
    assert abs(half_at - (c0 + 0.5)) < 0.2, (half_at, c0 + 0.5)
    # the 10-90% width: the disc filter's within 15%
    def width(y):
        o = np.argsort(pos)
        return np.interp(0.9, y[o], pos[o]) - np.interp(0.1, y[o], pos[o])
    assert abs(width(row) - width(expect)) < 0.1 * width(expect), (width(row), width(expect))


# --- the separable texel-grid weights of common/shadow.glsl, in numpy (no GL) ---

def _pcf_weight_cdf(x, a, box):
    x = np.clip(x, -a, a)
    return x if box else x - x ** 3 / (3.0 * a * a)




def _pcf_kernel(R):
    """shadow.glsl's choice for a softness of R texels: (half-width in cells, box, stride in texels)."""
    Rd = PCF_DISC_SCALE * R
    a_par, a_box = np.sqrt(5.0 * (0.25 * Rd * Rd + 1.0 / 12.0)), 0.5 * np.sqrt(3.0 * Rd * Rd + 1.0)
    fit = PCF_GRID - PCF_FIT_INSET
    box = a_par >= fit
    a = a_box if box else a_par
    stride = max(a / fit, 1.0)
    return a / stride, box, stride


def _pcf_axis(pc, a, box, stride=1.0):
    """pcf_grid's axis in shadow.glsl: bilinear tap positions (texels from pc, pc in texel-centre
    coordinates) and weights."""
    v = pc / stride
    t0 = np.floor(v - a + 0.5)
    ta = t0 + 2.0 * np.arange(PCF_GRID)
    lo, mid, hi = (_pcf_weight_cdf(ta + o - v, a, box) for o in (-0.5, 0.5, 1.5))
    return (ta + (hi - mid) / np.maximum(hi - lo, 1e-12) - v) * stride, hi - lo


def _bilinear_compare(q, lit):
    """A hardware bilinear-compare tap at texel-centre coordinates q (n, 2) of the map lit(tx, ty)."""
    f = np.floor(q)
    a = q - f
    out = 0.0
    for ox, oy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        w = (a[:, 0] if ox else 1 - a[:, 0]) * (a[:, 1] if oy else 1 - a[:, 1])
        out = out + w * lit(f[:, 0] + ox, f[:, 1] + oy)
    return out


def _pcf(p, R, lit):
    a, box, stride = _pcf_kernel(R)
    px, wx = _pcf_axis(p[0], a, box, stride)
    py, wy = _pcf_axis(p[1], a, box, stride)
    X, Y = np.meshgrid(px, py)
    W = np.outer(wy, wx)
    return float((W.ravel() * _bilinear_compare(p + np.c_[X.ravel(), Y.ravel()], lit)).sum() / W.sum())


@pytest.mark.parametrize("R", [1.0, 1.5, 2.0])
def test_pcf_taps_reproduce_their_texel_weights(R):
    """Up to a softness of 2.1 texels (the default 1.5 included) the 3 x 3 taps are exact: each
    bilinear tap between two texels weighs them as the separable weight does (Castano's optimized
    PCF), the taps cover every texel the weight reaches, and the weights sum to the whole
    parabola's (or box's) area at any sub-texel position."""
    a, box, stride = _pcf_kernel(R)
    assert stride == 1.0
    total = _pcf_weight_cdf(a, a, box) - _pcf_weight_cdf(-a, a, box)
    for pc in np.linspace(0.0, 1.0, 17):
        pos, w = _pcf_axis(pc, a, box)
        assert abs(w.sum() - total) < 1e-9 * total
        t0 = np.floor(pc - a + 0.5)
        # texels outside the 2 x PCF_GRID cells the taps cover carry no weight
        assert t0 - 0.5 <= pc - a and t0 + 2 * PCF_GRID - 0.5 >= pc + a
        for k in range(PCF_GRID):
            ta = t0 + 2 * k
            wa = _pcf_weight_cdf(ta + 0.5 - pc, a, box) - _pcf_weight_cdf(ta - 0.5 - pc, a, box)
            frac = pos[k] + pc - ta
            assert -1e-9 <= frac <= 1 + 1e-9
            assert abs(w[k] * (1 - frac) - wa) < 1e-9 * total


def _disc_filter_2d(p, Rd, lit, n=120):
    """The intended filter, by quadrature: the mean over a uniform disc of radius Rd of a
    bilinear-compare tap (the closed form _disc_step_profile holds only for an axis-aligned edge)."""
    t = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    dx, dy = np.meshgrid(t, t)
    inside = dx * dx + dy * dy <= 1.0
    return float(_bilinear_compare(p + Rd * np.c_[dx[inside], dy[inside]], lit).mean())


@pytest.mark.parametrize("R, bound", [(1.0, 0.03), (1.5, 0.03), (2.0, 0.03), (3.0, 0.1)])
@pytest.mark.parametrize("angle_deg", [0.0, 20.0, 45.0])
def test_pcf_penumbra_at_any_edge_angle_matches_the_disc(R, bound, angle_deg):
    """Across a rasterised straight edge at any angle to the map's axes, the separable weights
    give the disc filter's penumbra within 0.03 up to softness 2 (the 16 Poisson taps of rounds
    1-5: 0.014-0.055 at softness 1-1.5): the filter is a disc's, not a square's. At softness 3 the
    grid strides 1.4 texels per cell and is no longer exact: 0.1 (measured 0.046-0.086; Poisson
    0.054-0.072)."""
    n = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))])
    c = 0.37
    lit = lambda tx, ty: (tx * n[0] + ty * n[1] >= c).astype(float)  # noqa: E731
    side = np.array([-n[1], n[0]]) * 0.29
    errs = []
    for x in np.linspace(-6.0, 6.0, 49):
        p = c * n + x * n + side
        errs.append(abs(_pcf(p, R, lit) - _disc_filter_2d(p, PCF_DISC_SCALE * R, lit)))
    assert max(errs) < bound, max(errs)


def test_python_pcf_constants_are_the_shaders():
    """dermis.gl.shadows.pcf_filter picks each light's kernel before the draw (the light passes are
    compiled for it, round 24); it must use common/shadow.glsl's own disc scale, grid and fit, or a
    light compiled as PARABOLA would be filtered where the shader itself picks BOX (read from the
    shader's text: a change to either side fails here)."""
    import re

    from dermis.gl.shaders import load_shader_source

    src = load_shader_source("common/shadow.glsl", {})
    assert float(re.search(r"const float PCF_DISC_SCALE = ([0-9.]+);", src).group(1)) == PCF_DISC_SCALE
    assert int(re.search(r"const int PCF_GRID = ([0-9]+);", src).group(1)) == PCF_GRID
    assert float(re.search(r"const float fit = float\(PCF_GRID\) - ([0-9.]+);", src).group(1)) == PCF_FIT_INSET
