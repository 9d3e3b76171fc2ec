"""Occluded environment light (dermis.geometry.visibility): ambient occlusion and bent normals
baked per vertex, applied by every technique, ray cast by the reference.

Closed form: a point at the centre of the floor of a cylindrical well (radius a, depth h) sees the
sky through a disc of angular radius atan(a/h); its cosine-weighted unoccluded fraction (the form
factor to the opening) is sin^2 = a^2 / (a^2 + h^2). Under a constant environment of radiance c,
lambert's radiance there is albedo * c * a^2 / (a^2 + h^2) (E = pi c A).
"""

from __future__ import annotations

import numpy as np
import pytest

import dermis
from dermis.geometry import visibility
from dermis.geometry.raycast import RayCaster
from dermis.invalidation import PRODUCTS
from dermis.renderer import Renderer
from dermis.scene.builtin import grid_mesh, merge
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Output, Scene, SkinMaterial

ALBEDO = 0.6
SKY = 0.5  # constant environment radiance
SIZE = (96, 96)


def well_scene(depth: float, radius: float = 1.0, occlusion: bool = True) -> Scene:
    """A flat floor (z = 0, a 2r square) inside a cylindrical wall of radius r and height ``depth``
    with inward normals, under a constant sky, seen from straight above."""
    floor = grid_mesh(48, 48, lambda u, v: (np.stack([(u - 0.5) * 2 * radius, (v - 0.5) * 2 * radius, 0 * u], -1),
                                            np.broadcast_to([0.0, 0.0, 1.0], u.shape + (3,))), (0.0, 0.0, 0.49, 0.49))

    def wall(u, v):
        phi = u * 2 * np.pi
        p = np.stack([radius * np.cos(phi), radius * np.sin(phi), v * depth], -1)
        return p, np.stack([-np.cos(phi), -np.sin(phi), 0 * u], -1)

    p, n, uv, t = merge([floor, grid_mesh(96, 8, wall, (0.51, 0.0, 1.0, 1.0))])
    mesh = finish_mesh(p, n, uv, t, "test:well", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=(ALBEDO,) * 3, rho_s=0.0), lights=[],
                 camera=Camera(position=(0.0, 0.0, depth + 4.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                               fov_deg=20.0),
                 environment=Environment(color=(SKY,) * 3, occlusion=occlusion),
                 output=Output(background=(0.0, 0.0, 0.0)), technique="lambert")


def centre(img, half=3):
    h, w = img.shape[:2]
    return float(img[h // 2 - half:h // 2 + half, w // 2 - half:w // 2 + half].mean())


@pytest.mark.parametrize("depth", [1.0, 2.0])
def test_well_floor_matches_the_form_factor_to_the_opening(depth):
    expected = 1.0 / (1.0 + depth * depth)  # a = 1
    on = dermis.render(well_scene(depth), "lambert", size=SIZE)
    off = dermis.render(well_scene(depth, occlusion=False), "lambert", size=SIZE)
    assert centre(off) == pytest.approx(ALBEDO * SKY, rel=2e-3)  # the open sky: albedo / pi * pi c
    # the window spans +-0.05 of the radius, where the form factor changes by < 0.3%; the bake's
    # 256 rays per vertex leave a standard error of 0.03 per vertex, averaged over ~10 vertices
    assert centre(on) / (ALBEDO * SKY) == pytest.approx(expected, abs=0.025)


def test_every_technique_darkens_the_well_floor_by_its_occlusion(gl_ctx):
    scene = well_scene(1.0)
    scene.mm_per_unit = 100.0  # a 100 mm well: the skin's scattering (mm) stays on the floor
    scene.interreflection = False  # the closed form has no light from the lit walls (tsd's one bounce)
    with Renderer(scene, SIZE, ctx=gl_ctx, irradiance_size=256, shadow_size=256) as r:
        for tech in ("tsd", "ssss", "preintegrated"):
            scene.environment.occlusion = True
            on = r.render(tech)
            scene.environment.occlusion = False
            off = r.render(tech)
            assert centre(on) / centre(off) == pytest.approx(0.5, abs=0.03), tech


def test_mesh_edit_rebakes_and_toggle_reuploads(gl_ctx, tmp_path, monkeypatch):
    monkeypatch.setenv("DERMIS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(visibility, "_MEMORY", {})  # earlier tests baked this well
    scene = well_scene(1.0)
    with Renderer(scene, SIZE, ctx=gl_ctx) as r:
        a = r.render("lambert")
        assert "visibility" in r.stats["passes_run"] and not r.visibility.cached
        r.render("lambert")
        assert "visibility" not in r.stats["passes_run"]  # cached product
        # the wall raised in place to depth 2: the key is content, the bake is redone
        wall = scene.mesh.positions[:, 2] > 1e-6
        scene.mesh.positions[wall, 2] *= 2.0
        b = r.render("lambert")
        assert "visibility" in r.stats["passes_run"] and not r.visibility.cached
        assert centre(a) / (ALBEDO * SKY) == pytest.approx(0.5, abs=0.025)
        assert centre(b) / (ALBEDO * SKY) == pytest.approx(0.2, abs=0.025)
        # off: the same mesh, no bake, the open sky
        scene.environment.occlusion = False
        c = r.render("lambert")
        assert r.visibility is None and centre(c) == pytest.approx(ALBEDO * SKY, rel=2e-3)
    # the disk cache: a fresh process (an empty memory cache) reads the bake back
    monkeypatch.setattr(visibility, "_MEMORY", {})
    v = visibility.mesh_visibility(scene.mesh)
    assert v.cached and v.seconds == 0.0
    fresh = visibility.mesh_visibility(scene.mesh, cache=False)
    np.testing.assert_array_equal(v.ao, fresh.ao)  # the same seed: the same bake


def test_visibility_is_a_declared_product():
    assert PRODUCTS["environment_visibility"] == ("mesh", "environment_occlusion")
    assert "environment_occlusion" in PRODUCTS["texture_space"]  # tsd's irradiance texture holds it
    base = well_scene(1.0)
    k0 = dermis.invalidation.product_keys(dermis.invalidation.scene_inputs(base, irradiance_size=64, epoch=0))
    base.environment.occlusion = False
    k1 = dermis.invalidation.product_keys(dermis.invalidation.scene_inputs(base, irradiance_size=64, epoch=0))
    assert k0["environment_visibility"] != k1["environment_visibility"]
    assert k0["texture_space"] != k1["texture_space"] and k0["gpu_mesh"] == k1["gpu_mesh"]


def test_specular_occlusion_formula():
    # Lagarde & de Rousiers 2014, listing 26: open (A = 1) leaves the specular, A = 0 removes it,
    # and for a rough lobe it tends to A itself
    assert visibility.specular_occlusion(0.7, 1.0, 0.3) == 1.0
    assert visibility.specular_occlusion(0.7, 0.0, 0.3) == pytest.approx(0.0, abs=0.02)
    assert visibility.specular_occlusion(0.5, 0.4, 0.6) == pytest.approx(0.4, abs=0.01)


def test_head_cavities_darker_open_cheek_unchanged(gl_ctx):
    """The environment scene at 128 px, lambert, occlusion on and off. Regions from an independent
    ray cast at each pixel's visible point (128 cosine-weighted rays from that point, not the
    per-vertex bake): cavities (nostrils, eye creases, ear folds: A < 0.5) and open skin facing the
    camera (A > 0.97, the cheeks and forehead)."""
    from dermis.reference.render import camera_rays

    scene = dermis.load_scene("examples/reference/environment.toml")
    size = (128, 128)
    with Renderer(scene, size, ctx=gl_ctx, shadow_size=256, irradiance_size=256) as r:
        on = r.render("lambert").mean(axis=2)
        scene.environment.occlusion = False
        off = r.render("lambert").mean(axis=2)
        mesh = scene.mesh
    caster = RayCaster(mesh.positions, mesh.indices)
    o, d, tmax, eye = camera_rays(scene, size)
    t, tri, bary = caster.closest_hit(o, d, 0.0, tmax)
    hit = tri >= 0
    idx = mesh.indices[tri[hit]]
    b = np.concatenate([1 - bary[hit].sum(1, keepdims=True), bary[hit]], 1)
    p = o[hit] + d[hit] * t[hit, None]
    n = (mesh.normals[idx] * b[:, :, None]).sum(1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    diag = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    ao, _ = caster.ambient_occlusion(p, n, 128, offset=1e-5 * diag, seed=7)
    ratio = (on.reshape(-1)[hit] / np.maximum(off.reshape(-1)[hit], 1e-6))
    facing = -(n * d[hit]).sum(1) > 0.5
    cavity = ao < 0.5
    open_skin = (ao > 0.97) & facing
    assert cavity.sum() > 30 and open_skin.sum() > 500
    assert np.median(ratio[cavity]) < 0.7
    assert np.median(ratio[open_skin]) == pytest.approx(1.0, abs=0.05)
