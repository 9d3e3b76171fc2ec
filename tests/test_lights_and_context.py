"""Point and spot lights against numpy, the shadow atlas's size limit, and the one-line error when no GL
context can be made."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.camera import camera_matrices
from dermis.errors import DermisError
from dermis.renderer import Renderer
from dermis.scene.builtin import plane_xy
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial


def _plane_scene(light):
    p, n, uv, t = plane_xy(size=200.0, n=32)
    mesh = finish_mesh(p, n, uv, t, "test:plane", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.5, 0.5, 0.5), rho_s=0.0, pore_strength=0.0),
                 lights=[light], camera=Camera(position=(0.0, 0.0, 400.0), fov_deg=30.0),
                 environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0)


def _plane_points(scene, size):
    """World point on the z = 0 plane under each pixel centre (numpy ray casting)."""
    w, h = size
    view, proj, eye, _, _ = camera_matrices(scene.camera, w / h, *scene.bounds())
    inv = np.linalg.inv(proj @ view)
    xs = (np.arange(w) + 0.5) / w * 2 - 1
    ys = 1 - (np.arange(h) + 0.5) / h * 2
    X, Y = np.meshgrid(xs, ys)
    ndc = np.stack([X, Y, np.ones_like(X), np.ones_like(X)], -1) @ inv.T
    far = ndc[..., :3] / ndc[..., 3:]
    d = far - eye
    t = -eye[2] / d[..., 2]
    return eye + t[..., None] * d


def test_point_light_falls_off_with_the_square_of_the_distance_in_metres(gl_ctx):
    pos = np.array([30.0, -20.0, 60.0])  # mm (mm_per_unit = 1)
    light = Light(kind="point", position=tuple(pos), intensity=2e-3, cast_shadows=False)
    sc = _plane_scene(light)
    size = (64, 64)
    with Renderer(sc, size, ctx=gl_ctx, samples=0) as r:
        img = r.render("lambert")
    P = _plane_points(sc, size)
    d = pos - P
    dist_m = np.linalg.norm(d, axis=-1) * 1e-3
    ndl = np.maximum(d[..., 2] / np.linalg.norm(d, axis=-1), 0)
    expected = 0.5 / np.pi * light.intensity / dist_m ** 2 * ndl
    inner = (slice(8, 56), slice(8, 56))
    rel = np.abs(img[inner][..., 0] / expected[inner] - 1)
    assert rel.max() < 0.01, rel.max()


def test_spot_light_lights_only_its_cone(gl_ctx):
    pos = np.array([0.0, 0.0, 80.0])
    light = Light(kind="spot", position=tuple(pos), direction=(0.0, 0.0, -1.0), spot_angle_deg=20.0,
                  spot_blend=0.1, intensity=5e-3, cast_shadows=True)
    sc = _plane_scene(light)
    size = (64, 64)
    with Renderer(sc, size, ctx=gl_ctx, samples=0) as r:
        img = r.render("lambert")[..., 0]
    P = _plane_points(sc, size)
    d = P - pos
    angle = np.degrees(np.arccos(-d[..., 2] / np.linalg.norm(d, axis=-1)))
    on_plane = (np.abs(P[..., 0]) < 95) & (np.abs(P[..., 1]) < 95)
    inside, outside = angle < 20.0 * 0.85, (angle > 20.5) & on_plane
    assert inside.sum() > 50 and outside.sum() > 50
    dist_m = np.linalg.norm(d, axis=-1) * 1e-3
    expected = 0.5 / np.pi * light.intensity / dist_m ** 2 * (-d[..., 2] / np.linalg.norm(d, axis=-1))
    np.testing.assert_allclose(img[inside], expected[inside], rtol=0.01)
    assert np.all(img[outside] < 1e-6)


def test_no_gl_context_is_one_line_error(monkeypatch, capsys):
    import moderngl

    from dermis import cli

    def refuse(*a, **k):
        raise Exception("eglGetDisplay failed\nmore detail")

    monkeypatch.setattr(moderngl, "create_context", refuse)
    with pytest.raises(SystemExit) as exc:
        cli.main(["info"])
    assert exc.value.code == 2
    err = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert len(err) == 1 and "eglGetDisplay failed" in err[0] and "apt-get install libegl1" in err[0]


def test_shadow_atlas_over_the_texture_limit_is_a_user_error(gl_ctx):
    from dermis.scene.builtin import frame_scene
    from dermis.scene.model import Scene

    from dermis.scene.builtin import builtin_mesh

    mesh, _, _ = builtin_mesh("sphere")
    scene = Scene(mesh=mesh)
    frame_scene(scene)  # three lights
    limit = int(gl_ctx.info.get("GL_MAX_TEXTURE_SIZE"))
    # three lights need a 2x2 atlas of shadow_size tiles, twice the texture limit. Where the limit is
    # above dermis's own shadow_size range (NVIDIA: 32768 > 16384), the range check refuses it
    # first, in the same words; on llvmpipe (16384) the atlas check does.
    with pytest.raises(DermisError, match="shadow_size"):
        with Renderer(scene, (16, 16), ctx=gl_ctx, samples=0, shadow_size=limit) as r:
            r.render("lambert")
