"""The translucency bake's path along the light (dermis.geometry.thickness.light_thickness, used
where -N finds no far face) and its smoothing within UV islands (smooth_thickness): closed forms
for a tilted slab, no added light at the terminator of a sphere or a thick box, and a bounded
step across a jump of the far face."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.geometry.thickness import (SMOOTH_DECAY_PER_MM, SMOOTH_RADIUS_TEXELS, SMOOTH_SIGMA_TEXELS, light_thickness, smooth_thickness, texel_thickness,
                                       translucency_thickness, uv_islands)
from dermis.scene.builtin import box, uv_sphere
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Light
from dermis.verification import backlit_slab_scene, texel_positions


@pytest.mark.parametrize("theta_deg", [0.0, 30.0, 60.0])
def test_tilted_slab_path_along_the_light(theta_deg):
    """A slab d = 2 mm thick (mm_per_unit 1) lit from behind at theta to its normal: from a
    front-face texel P the ray towards the light leaves the tissue at the back face after the chord
    t = d / cos(theta), at E = P + t L; the bake holds the slab's thickness t cos(theta) = d
    (within 1e-4 mm), weight 1 (the faces are antiparallel), and E's (u, v) (within a texel)."""
    d, th = 2.0, np.radians(theta_deg)
    sc = backlit_slab_scene(d, size_mm=30.0)
    light = Light(direction=(np.sin(th), 0.0, np.cos(th)))  # travels into the back face, towards +z
    S = 256
    bake = light_thickness(sc.mesh, S, sc.mm_per_unit, light)
    pos, cov = texel_positions(sc.mesh, S)
    front = cov & (np.abs(pos[..., 2] - d / 2) < 1e-6) & (np.abs(pos[..., 0]) < 8) & (np.abs(pos[..., 1]) < 12)
    assert front.sum() > 400
    np.testing.assert_array_equal(bake[..., 3][front], 1.0)
    np.testing.assert_allclose(bake[..., 2][front], d, atol=1e-4)
    u, v = bake[..., 0][front], bake[..., 1][front]
    exit_pos = pos[np.clip(((1.0 - v) * S).astype(int), 0, S - 1), np.clip((u * S).astype(int), 0, S - 1)]
    to_light = -np.array([np.sin(th), 0.0, np.cos(th)])
    expect = pos[front] + to_light * (d / np.cos(th))
    texel_mm = 30.0 / (S / 3)
    assert np.abs(exit_pos - expect).max() <= 1.5 * texel_mm
    # the back face (it faces the light) gets nothing along the light
    back = cov & (np.abs(pos[..., 2] + d / 2) < 1e-6)
    assert back.sum() > 400 and not bake[..., 3][back].any()


def test_sphere_terminator_gets_nothing_along_the_light():
    """A sphere of radius R = 16 mm (-N's chord 2R is past the bake's 30 mm: no far face along -N
    anywhere) lit along +x. Past the terminator at the angle a (-N.L = sin a) the chord to the lit
    side is 2 R sin a -> 0 and the faces at its ends are mirror images, not a slab: the path along
    the light has weight 0 for a < 60 deg (geometry/thickness.py's derivation; 55 deg allowed for
    the tessellation), and where it has weight the thickness is >= 1.5 R (the chord through the
    body), through which the thin-slab law lets out < 1e-4 in red. The smoothed bake
    (translucency_thickness) keeps both, its weight spread by the smoothing's 2 texels (50 deg)."""
    from dermis.profiles.thin_slab import slab_law
    from dermis.scene.model import Scene

    p, n, uv, t = uv_sphere(1.0, 96, 48)
    mesh = finish_mesh(p, n, uv, t, "test:sphere", "v-up")
    R, S = 16.0, 128
    light = Light(direction=(1.0, 0.0, 0.0))
    assert not texel_thickness(mesh, S, R)[..., 3].any()
    pos, cov = texel_positions(mesh, S)
    sin_a = pos[..., 0]  # -N.L on the unit sphere
    # the smoothing reaches 2 texels further: 2 x 360 / 128 = 5.6 deg along u
    for bake, a_min in ((light_thickness(mesh, S, R, light), 55.0), (translucency_thickness(mesh, S, R, [light]), 50.0)):
        w, d = bake[..., 3], bake[..., 2]
        near = cov & (sin_a < np.sin(np.radians(a_min)))
        assert near.sum() > 0.8 * cov.sum()
        assert not w[near].any()
        assert (w > 0).any()  # the far side's chord through the body is a slab-like path
        assert d[w > 0].min() >= 1.5 * R * 0.97
    law = slab_law(Scene(mesh=mesh).profile.normalized(), np.array([0.6, 0.4, 0.3]))
    assert law.transmittance(1.5 * R * 0.97)[0] / 0.6 < 1e-4


def test_thick_box_lit_from_one_side_gets_nothing():
    """A 40 mm cube lit along +x: its side faces are edge-on to the light (the terminator, -N.L = 0)
    and its dark face's chord to the lit face is 40 mm, past the bake's reach: no weight anywhere."""
    p, n, uv, t = box((0.0, 0.0, 0.0), (20.0, 20.0, 20.0), uv_cell=1 / 3, n=8, gutter=0.01)
    mesh = finish_mesh(p, n, uv, t, "test:box", "v-up")
    bake = light_thickness(mesh, 96, 1.0, Light(direction=(1.0, 0.0, 0.0)))
    assert texel_positions(mesh, 96)[1].sum() > 3000
    assert not bake[..., 3].any()


def _row_step(left, right, S=32):
    b = np.zeros((S, S, 4), np.float32)
    b[:, : S // 2] = left
    b[:, S // 2:] = right
    return b


def test_smoothing_bounds_a_far_face_step():
    """Across a step of the bake (thin far face | none, and 1 mm | 10 mm) the transmitted weight
    w e^(-k d) of the smoothed bake changes by at most the Gaussian kernel's largest normalised tap
    (0.403 of the step, where the raw bake jumps by all of it between two texels), monotonically; a
    uniform region keeps its thickness and weight exactly; nothing crosses into another island."""
    k = SMOOTH_DECAY_PER_MM
    offsets = np.arange(-SMOOTH_RADIUS_TEXELS, SMOOTH_RADIUS_TEXELS + 1)
    tap = 1.0 / np.exp(-offsets ** 2 / (2.0 * SMOOTH_SIGMA_TEXELS ** 2)).sum()  # 0.403: the kernel's largest 1-D tap
    one = np.zeros((32, 32), np.int64)
    for left, right in (((0.1, 0.2, 1.5, 1.0), (0, 0, 0, 0)), ((0.1, 0.2, 1.0, 1.0), (0.3, 0.4, 10.0, 1.0))):
        raw = _row_step(left, right)
        s = smooth_thickness(raw, one)
        e = s[..., 3] * np.exp(-k * s[..., 2]) * (s[..., 3] > 0)
        step = left[3] * np.exp(-k * left[2]) - right[3] * np.exp(-k * right[2]) * (right[3] > 0)
        diff = e[4:-4, :-1] - e[4:-4, 1:]
        assert diff.min() >= -1e-6  # monotone
        assert diff.max() <= 1.001 * tap * step
        np.testing.assert_allclose(s[4:-4, :8, 2], left[2], atol=1e-5)  # uniform: exact
        np.testing.assert_array_equal(s[4:-4, :8, 3], 1.0)
        np.testing.assert_allclose(s[:, :8, 0:2], np.broadcast_to(left[:2], (32, 8, 2)), atol=1e-7)
        # a texel with no far face of its own takes its nearest neighbour's (u, v)
        assert np.all(s[4:-4, 16, 0:2] == np.asarray(right[:2] if right[3] else left[:2], np.float32))
    # two islands side by side: no smoothing across the seam
    isl = np.zeros((32, 32), np.int64)
    isl[:, 16:] = 1
    s = smooth_thickness(_row_step((0.1, 0.2, 1.0, 1.0), (0.3, 0.4, 10.0, 1.0)), isl)
    np.testing.assert_allclose(s[:, :16, 2], 1.0, atol=1e-5)
    np.testing.assert_allclose(s[:, 16:, 2], 10.0, atol=1e-5)


def test_uv_islands_of_a_box():
    """A box's six faces are six islands of the layout; uncovered texels are -1."""
    sc = backlit_slab_scene(2.0)
    isl = uv_islands(sc.mesh, 96)
    labels = np.unique(isl)
    assert labels[0] == -1 and len(labels) == 7


def test_the_bake_follows_the_key_light_direction_not_its_intensity(gl_ctx):
    """The path along the light is re-baked when the key light turns (and the image is a fresh
    renderer's), not when only its intensity changes (the bake does not depend on it); without the
    scene's translucency_light_path (the default) a turn does not re-bake either."""
    from dermis.renderer import Renderer

    sc = backlit_slab_scene(2.0, n=8)
    assert sc.translucency_light_path is False
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        r.render("tsd", output_mode=1)
        sc.lights[0].direction = (0.3, 0.0, 0.95)
        r.render("tsd", output_mode=1)
        assert "thickness" not in r.stats["passes_run"]
    sc.lights[0].direction = backlit_slab_scene(2.0, n=8).lights[0].direction
    sc.translucency_light_path = True
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        r.render("tsd", output_mode=1)
        sc.lights[0].intensity = 2.0
        r.render("tsd", output_mode=1)
        assert "thickness" not in r.stats["passes_run"]
        sc.lights[0].direction = (0.3, 0.0, 0.95)
        a = r.render("tsd", output_mode=1)
        assert "thickness" in r.stats["passes_run"]
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as fresh:
        b = fresh.render("tsd", output_mode=1)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)


def test_turning_the_light_path_on_in_a_live_renderer_reruns_translucency(gl_ctx):
    """scene.translucency_light_path is an input of the texture-space product: turned on between
    two frames of one Renderer, the frame is the fresh renderer's (the bake and tsd's translucency
    rerun), not the cached one from before."""
    from dermis.renderer import Renderer

    sc = backlit_slab_scene(2.0, n=8)
    sc.lights[0].direction = (0.3, 0.0, 0.95)
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        r.render("tsd", output_mode=1)
        sc.translucency_light_path = True
        a = r.render("tsd", output_mode=1)
        assert "thickness" in r.stats["passes_run"] and "tsd_translucency" in r.stats["passes_run"]
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as fresh:
        b = fresh.render("tsd", output_mode=1)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)


def test_scene_key_translucency_light_path(tmp_path):
    """[scene] translucency_light_path: off by default, true turns it on, a non-bool is a one-line
    error naming the key."""
    import dermis
    from dermis.errors import DermisError

    def scene(extra):
        p = tmp_path / "s.toml"
        p.write_text(f'[scene]\nmm_per_unit = 48.0\n{extra}\n[mesh]\nbuiltin = "plane"\n')
        return p

    assert dermis.load_scene(scene("")).translucency_light_path is False
    assert dermis.load_scene(scene("translucency_light_path = true")).translucency_light_path is True
    with pytest.raises(DermisError, match=r"\[scene\] translucency_light_path"):
        dermis.load_scene(scene('translucency_light_path = "yes"'))
