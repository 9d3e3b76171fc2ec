"""Non-skin glTF primitives (issue 17): glTF 2.0's metallic-roughness model beside the skin.

Every expected pixel is computed here in numpy, independently of the shaders: camera rays through
the pixel centres (the render has no MSAA) hit the same triangles (Embree), the vertex normals
are interpolated as the rasteriser does, and the glTF 2.0 BRDF (Appendix B: GGX D,
height-correlated Smith V, Schlick F with F0 = mix(0.04, base, metallic), diffuse (1 - F)(1 -
metallic) base / pi) is evaluated at that normal under one directional light, plus a constant
environment (radiance c: diffuse c_diff c, specular c (F0 A + B), both scaled by occlusion).
The scenes rebuild the Khronos sample MetalRoughSpheresNoTextures in small (metallic x roughness
spheres) with the features glTF adds: metallicRoughnessTexture, occlusionTexture, emission and a
MASK card, all beside one skin sphere.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from dermis.errors import DermisError
from dermis.geometry.raycast import RayCaster
from dermis.reference.render import camera_rays
from dermis.renderer import Renderer
from dermis.scene.loaders import load_mesh_file
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_gltf_features import _spec_matrix, build  # noqa: E402
from test_loaders import write_gltf  # noqa: E402

NEAREST = 9728
TO_LIGHT = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])
E_LIGHT = 3.0  # irradiance at normal incidence
ENV = 0.2  # constant environment radiance


# ----------------------------------------------------------------------------- numpy glTF BRDF
def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def mr_brdf(N, L, V, base, metallic, roughness):
    """glTF 2.0 Appendix B, per row: (diffuse, specular) BRDF values (1/sr), (n, 3) each."""
    H = _unit(L + V)
    ndl, ndv = np.sum(N * L, -1)[:, None], np.sum(N * V, -1)[:, None]
    ndh, vdh = np.sum(N * H, -1)[:, None], np.sum(V * H, -1)[:, None]
    a2 = (roughness ** 2) ** 2
    D = a2 / (np.pi * (ndh ** 2 * (a2 - 1) + 1) ** 2)
    Vis = 0.5 / (ndl * np.sqrt(ndv ** 2 * (1 - a2) + a2) + ndv * np.sqrt(ndl ** 2 * (1 - a2) + a2))
    f0 = 0.04 * (1 - metallic) + np.asarray(base) * metallic
    F = f0 + (1 - f0) * (1 - np.abs(vdh)) ** 5
    return (1 - F) * (1 - metallic) * np.asarray(base) / np.pi, F * D * Vis


def env_brdf(f0, ndv, roughness):
    """Karis 2014's analytic F0 A + B (EnvBRDFApprox), transcribed from the course notes."""
    c0, c1 = np.array([-1, -0.0275, -0.572, 0.022]), np.array([1, 0.0425, 1.04, -0.04])
    r = roughness * c0 + c1
    a004 = np.minimum(r[0] * r[0], np.exp2(-9.28 * ndv)) * r[0] + r[1]
    a, b = -1.04 * a004 + r[2], 1.04 * a004 + r[3]
    return np.asarray(f0) * a[:, None] + b[:, None]


def expected_radiance(N, P, eye, m, occlusion=1.0, to_light=TO_LIGHT):
    """Radiance of material ``m`` (a dict) at points P with normals N: the light (no shadow), the
    constant environment scaled by occlusion, emission."""
    V = _unit(eye - P)
    L = np.broadcast_to(to_light, N.shape)
    fd, fs = mr_brdf(N, L, V, m["base"], m["metallic"], m["roughness"])
    ndl = np.maximum(np.sum(N * L, -1), 0.0)[:, None]
    ndv = np.clip(np.sum(N * V, -1), 0, 1)
    c_diff = (1 - m["metallic"]) * np.asarray(m["base"])
    f0 = 0.04 * (1 - m["metallic"]) + np.asarray(m["base"]) * m["metallic"]
    ambient = occlusion * ENV * (c_diff + env_brdf(f0, ndv, m["roughness"]))
    return E_LIGHT * ndl * (fd + fs) + ambient + np.asarray(m.get("emissive", (0, 0, 0)))


# ----------------------------------------------------------------------------- geometry
def sphere(center, r=0.4, nu=28, nv=14):
    from dermis.scene.builtin import uv_sphere

    p, n, uv, idx = uv_sphere(r, nu, nv)
    return {"POSITION": (p + center).astype(np.float32), "NORMAL": n.astype(np.float32),
            "TEXCOORD_0": uv.astype(np.float32), "indices": np.asarray(idx).reshape(-1)}


def card(center, half=0.4):
    p = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32) * half + np.asarray(center, np.float32)
    return {"POSITION": p, "NORMAL": np.tile(np.float32([0, 0, 1]), (4, 1)),
            "TEXCOORD_0": np.float32([[0, 1], [1, 1], [1, 0], [0, 0]]), "indices": np.array([0, 1, 2, 0, 2, 3])}


def rgba_image(rgba):
    return np.asarray(rgba, np.uint8)[None, None, :].repeat(2, 0).repeat(2, 1)


# MetalRoughSpheresNoTextures in small: metallic 0 / 1 x roughness 0.3, 0.6, 1 (rows 1-2), and row
# 0: skin, a MASK card, an emissive sphere, a sphere whose metallic/roughness come from its map
GRID = {"skin": (-1.5, 1.0), "mask": (-0.5, 1.0), "emissive": (0.5, 1.0), "mr_map": (1.5, 1.0),
        "d0.3": (-1.5, 0.0), "d0.6": (-0.5, 0.0), "d1.0": (0.5, 0.0), "occluded": (1.5, 0.0),
        "m0.3": (-1.5, -1.0), "m0.6": (-0.5, -1.0), "m1.0": (0.5, -1.0), "metal_map": (1.5, -1.0)}
MR_MAP_TEXEL = (0, 178, 0)  # G = roughness 178/255, B = metallic 0
METAL_MAP_TEXEL = (0, 90, 255)  # roughness 90/255, metallic 1


def grid_materials():
    """(glTF materials, the numpy description of each non-skin one by name)."""
    base_d, base_m = (0.8, 0.3, 0.2), (0.95, 0.75, 0.35)
    gl, ref = [{"name": "skin", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.5, 0.4, 1.0]}}], {}

    def add(name, pbr, **extra):
        gl.append({"name": name, "pbrMetallicRoughness": pbr, **extra})

    for r in (0.3, 0.6, 1.0):
        add(f"d{r}", {"baseColorFactor": [*base_d, 1], "metallicFactor": 0.0, "roughnessFactor": r})
        ref[f"d{r}"] = {"base": base_d, "metallic": 0.0, "roughness": r}
        add(f"m{r}", {"baseColorFactor": [*base_m, 1], "metallicFactor": 1.0, "roughnessFactor": r})
        ref[f"m{r}"] = {"base": base_m, "metallic": 1.0, "roughness": r}
    add("mask", {"baseColorFactor": [0.6, 0.6, 0.6, 1], "baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                 "roughnessFactor": 0.8}, alphaMode="MASK", alphaCutoff=0.5, doubleSided=True)
    ref["mask"] = {"base": (0.6, 0.6, 0.6), "metallic": 0.0, "roughness": 0.8}
    add("emissive", {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0, "roughnessFactor": 0.9},
        emissiveFactor=[1.0, 0.5, 0.25])
    ref["emissive"] = {"base": (0, 0, 0), "metallic": 0.0, "roughness": 0.9, "emissive": (1.0, 0.5, 0.25)}
    add("mr_map", {"baseColorFactor": [*base_d, 1], "metallicRoughnessTexture": {"index": 1}})
    ref["mr_map"] = {"base": base_d, "metallic": 0.0, "roughness": 178 / 255}
    add("metal_map", {"baseColorFactor": [*base_m, 1], "metallicRoughnessTexture": {"index": 2}})
    ref["metal_map"] = {"base": base_m, "metallic": 1.0, "roughness": 90 / 255}
    add("occluded", {"baseColorFactor": [*base_d, 1], "metallicFactor": 0.0, "roughnessFactor": 0.6},
        occlusionTexture={"index": 3, "strength": 0.8})
    ref["occluded"] = {"base": base_d, "metallic": 0.0, "roughness": 0.6, "occlusion": 1 + 0.8 * (64 / 255 - 1)}
    return gl, ref


def mask_image():
    """4x4 texels, alpha 0 on a checker (NEAREST): holes in the card."""
    a = (np.add.outer(np.arange(4), np.arange(4)) % 2) * 255
    img = np.full((4, 4, 4), 255, np.uint8)
    img[:, :, 3] = a
    return img


def grid_asset(tmp_path, mask=True):
    mats, ref = grid_materials()
    names = [m["name"] for m in mats]
    prims = []
    for name, (x, y) in GRID.items():
        if name == "mask" and not mask:
            continue
        g = card((x, y, 0.0)) if name == "mask" else sphere(np.array([x, y, 0.0]))
        prims.append({**g, "material": names.index(name)})
    images = [mask_image(), rgba_image((*MR_MAP_TEXEL, 255)), rgba_image((*METAL_MAP_TEXEL, 255)),
              rgba_image((64, 64, 64, 255))]
    textures = [{"source": i, "sampler": 0} for i in range(4)]
    doc, binary = build(prims, materials=mats, images=images, textures=textures,
                        samplers=[{"magFilter": NEAREST, "minFilter": NEAREST}])
    return write_gltf(tmp_path / "grid.gltf", doc, binary), ref


def make_scene(path, size_hint=None, *, env=ENV, light=True, skin=("skin",)):
    mesh, mat = load_mesh_file(path, skin_materials=list(skin))
    lights = [Light(kind="directional", direction=tuple(-TO_LIGHT), intensity=E_LIGHT, shadow_softness=1.0)] if light else []
    skin_mat = SkinMaterial(albedo=mat["albedo"], normal_map=mat["normal_map"], albedo_color=(0.7, 0.5, 0.4),
                            rho_s=0.0, pore_strength=0.0)
    return Scene(mesh=mesh, material=skin_mat,
                 lights=lights, camera=Camera(position=(0.0, 0.0, 9.0), target=(0.0, 0.0, 0.0), fov_deg=26.0),
                 environment=Environment(color=(env, env, env), occlusion=False), mm_per_unit=20.0,
                 surfaces=mat["surfaces"], source=str(path))


def hits(scene, size, uv_sets=False):
    """Per pixel (row-major): the hit object index (-1 none), position, interpolated normal, uv."""
    objs = [scene.mesh] + [s.mesh for s in scene.surfaces]
    offs = np.cumsum([0] + [len(m.positions) for m in objs])
    P = np.concatenate([m.positions for m in objs]).astype(np.float64)
    I = np.concatenate([m.indices.astype(np.int64) + o for m, o in zip(objs, offs)])
    tri_owner = np.concatenate([np.full(len(m.indices), k) for k, m in enumerate(objs)])
    o, d, _, eye = camera_rays(scene, size, 1)
    t, tri, bary = RayCaster(P, I).closest_hit(o, d)
    hit = tri >= 0
    owner = np.where(hit, tri_owner[np.maximum(tri, 0)], -1)
    b = np.c_[1 - bary.sum(1), bary]
    corners = I[np.maximum(tri, 0)]
    Nv = np.concatenate([m.normals for m in objs]).astype(np.float64)
    N = _unit(np.einsum("nk,nkc->nc", b, Nv[corners]) + 1e-30)

    def lerp(attr):
        A = np.concatenate([np.zeros((len(m.positions), 2)) if getattr(m, attr) is None else getattr(m, attr)
                            for m in objs]).astype(np.float64)
        return np.einsum("nk,nkc->nc", b, A[corners])

    if uv_sets:
        return owner, o + d * np.where(hit, t, 0)[:, None], N, (lerp("uvs"), lerp("uvs1")), eye
    return owner, o + d * np.where(hit, t, 0)[:, None], N, lerp("uvs"), eye


@pytest.fixture(scope="module")
def grid(tmp_path_factory, gl_ctx):
    path, ref = grid_asset(tmp_path_factory.mktemp("mr"))
    scene = make_scene(path)
    size = (256, 192)
    images = {}
    with Renderer(scene, size, ctx=gl_ctx, samples=0, shadow_size=1024, irradiance_size=256) as r:
        for tech in ("lambert", "preintegrated", "ssss", "tsd"):
            images[tech] = r.render(tech, with_alpha=True)
    return scene, ref, size, images, hits(scene, size)


def _names(scene):
    return ["skin"] + [s.material.name for s in scene.surfaces]


def test_every_primitive_renders_with_its_own_material(grid):
    scene, ref, *_ = grid
    assert sorted(_names(scene)[1:]) == sorted(ref)
    for s in scene.surfaces:
        m = s.material
        assert (m.alpha_mode, m.double_sided) == (("MASK", True) if m.name == "mask" else ("OPAQUE", False))


def test_pixels_match_the_gltf_brdf(grid):
    """Every non-skin sphere, at its pixels lit at N.L > 0.25 and seen at N.V > 0.25, within 2%
    (+0.002 absolute) of the numpy evaluation, in all four techniques' images."""
    scene, ref, size, images, (owner, P, N, uv, eye) = grid
    W, H = size
    names = _names(scene)
    lit = (N @ TO_LIGHT > 0.25) & (np.sum(N * _unit(eye - P), 1) > 0.25)
    checked = 0
    for k, name in enumerate(names):
        if name in ("skin", "mask"):
            continue
        sel = (owner == k) & lit
        assert sel.sum() > 40, name
        m = ref[name]
        want = expected_radiance(N[sel], P[sel], eye, m, m.get("occlusion", 1.0))
        for tech, img in images.items():
            got = img.reshape(-1, 4)[sel, :3]
            err = np.abs(got - want) / (want + 0.1)  # relative, with a floor near black
            assert np.percentile(err, 99) < 0.02 and err.max() < 0.05, (tech, name, np.percentile(err, 99), err.max())
        checked += 1
    assert checked == 10


def test_metallic_roughness_map_channels(grid):
    """G is roughness and B metallic: the mapped spheres equal the factor spheres' formula with
    the map's values, and differ from the swapped reading (the metal would become a dielectric)."""
    scene, ref, size, images, (owner, P, N, uv, eye) = grid
    k = _names(scene).index("metal_map")
    sel = (owner == k) & (N @ TO_LIGHT > 0.25)
    got = images["lambert"].reshape(-1, 4)[sel, :3]
    swapped = {"base": ref["metal_map"]["base"], "metallic": 90 / 255, "roughness": 1.0}
    want = expected_radiance(N[sel], P[sel], eye, ref["metal_map"])
    wrong = expected_radiance(N[sel], P[sel], eye, swapped)
    assert np.abs(got - want).mean() < 0.2 * np.abs(got - wrong).mean()


def test_occlusion_scales_ambient_light_only(grid):
    """The occluded sphere (occlusion 64/255 at strength 0.8) minus its unoccluded twin d0.6 is
    (1 - occlusion) times the ambient alone: the direct light is untouched."""
    scene, ref, size, images, (owner, P, N, uv, eye) = grid
    names = _names(scene)
    img = images["lambert"].reshape(-1, 4)[:, :3]
    occ = ref["occluded"]["occlusion"]
    # the spheres are the same shape at different places: compare by normal, the pixels of d0.6 shifted
    for name in ("occluded", "d0.6"):
        sel = (owner == names.index(name)) & (N @ TO_LIGHT > 0.25)
        got = img[sel]
        want_full = expected_radiance(N[sel], P[sel], eye, ref[name], 1.0)
        want_none = expected_radiance(N[sel], P[sel], eye, ref[name], 0.0)
        o = occ if name == "occluded" else 1.0
        np.testing.assert_allclose(got, want_none + o * (want_full - want_none), rtol=0.02, atol=0.003)


def test_mask_card_cuts_its_holes(grid):
    """alphaMode MASK: where the base colour's alpha (a 4x4 checker) is 0 the background shows,
    where it is 1 the card is shaded (its lit front face)."""
    scene, ref, size, images, (owner, P, N, uv, eye) = grid
    k = _names(scene).index("mask")
    on = owner == k
    tu, tv = uv[:, 0] * 4, (1.0 - uv[:, 1]) * 4  # texel column, row from the top (dermis UVs: v up)
    inner = on & (np.abs(tu - np.round(tu)) > 0.2) & (np.abs(tv - np.round(tv)) > 0.2)
    hole = ((np.floor(tu) + np.floor(tv)) % 2 == 0)
    for tech, img in images.items():
        px = img.reshape(-1, 4)
        assert np.all(px[inner & hole, 3] == 0.0), tech
        assert np.all(px[inner & ~hole, 3] == 1.0), tech
        want = expected_radiance(N[inner & ~hole], P[inner & ~hole], eye, ref["mask"])
        np.testing.assert_allclose(px[inner & ~hole, :3], want, rtol=0.02, atol=0.003, err_msg=tech)
    assert (inner & hole).sum() > 100 and (inner & ~hole).sum() > 100


def test_emission_is_added(grid):
    scene, ref, size, images, (owner, P, N, uv, eye) = grid
    sel = owner == _names(scene).index("emissive")
    got = images["tsd"].reshape(-1, 4)[sel, :3]
    assert np.all(got >= np.array([1.0, 0.5, 0.25]) * 0.99)


def test_skin_stays_the_techniques(grid):
    """The skin sphere is drawn by each technique (their images differ there), not as glTF."""
    scene, ref, size, images, (owner, P, N, uv, eye) = grid
    sel = (owner == 0) & (N @ TO_LIGHT > 0.25)
    a, b = images["lambert"].reshape(-1, 4)[sel, :3], images["tsd"].reshape(-1, 4)[sel, :3]
    assert sel.sum() > 100 and np.abs(a - b).mean() > 0.005


# ----------------------------------------------------------------------------- shadows
def _render_all(scene, size, gl_ctx, techniques=("lambert", "preintegrated", "ssss", "tsd")):
    with Renderer(scene, size, ctx=gl_ctx, samples=0, shadow_size=1024, irradiance_size=256) as r:
        return {t: r.render(t, with_alpha=True).reshape(-1, 4) for t in techniques}


def plane(z, half, material):
    return {**card((0.0, 0.0, z), half), "material": material}


def test_a_prop_shadows_the_skin_through_its_mask(tmp_path, gl_ctx):
    """A MASK card above a skin plane, the light straight down: on the skin, the card's opaque
    texels cast shadow and its holes let the light through (numpy: the ray from each skin pixel to
    the light, through the card's texel). Scattering (mm) is small beside the texels (40 mm)."""
    mats = [{"name": "skin", "pbrMetallicRoughness": {}},
            {"name": "card", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": "MASK",
             "doubleSided": True}]
    doc, binary = build([plane(0.0, 2.0, 0), plane(0.8, 0.8, 1)], materials=mats, images=[mask_image()],
                        textures=[{"source": 0, "sampler": 0}], samplers=[{"magFilter": NEAREST, "minFilter": NEAREST}])
    scene = make_scene(write_gltf(tmp_path / "card.gltf", doc, binary), env=0.0)
    scene.lights[0].direction = (0.0, 0.0, -1.0)
    scene.camera = Camera(position=(0.0, -4.0, 7.0), target=(0.0, 0.0, 0.0), fov_deg=30.0)
    scene.mm_per_unit = 50.0
    size = (96, 96)
    owner, P, N, uv, eye = hits(scene, size)
    skin = owner == 0
    # straight up from the skin point to the card plane z = 0.8: card texel (4 x 4 over [-0.8, 0.8])
    cu, cv = (P[:, 0] + 0.8) / 1.6 * 4, (0.8 - P[:, 1]) / 1.6 * 4  # column, row from the top (file v down)
    over = (cu > 0) & (cu < 4) & (cv > 0) & (cv < 4)
    inner = (np.abs(cu - np.round(cu)) > 0.25) & (np.abs(cv - np.round(cv)) > 0.25)
    opaque = (np.floor(cu) + np.floor(cv)) % 2 == 1
    shadowed, lit = skin & over & inner & opaque, skin & (~over | (inner & ~opaque))
    lit &= np.linalg.norm(P[:, :2], axis=1) < 1.8
    assert shadowed.sum() > 30 and (skin & over & inner & ~opaque).sum() > 30
    for tech, img in _render_all(scene, size, gl_ctx).items():
        lum = img[:, :3].mean(1)
        assert lum[shadowed].max() < 0.1 * np.median(lum[lit]), tech
        assert lum[skin & over & inner & ~opaque].min() > 0.7 * np.median(lum[lit]), tech


def test_the_skin_shadows_a_prop(tmp_path, gl_ctx):
    """A skin sphere above a dielectric plane (a prop), the light straight down: the plane is dark
    inside the sphere's shadow and equals the glTF BRDF outside it, in every technique."""
    mats = [{"name": "skin", "pbrMetallicRoughness": {}},
            {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.6, 0.7, 1], "metallicFactor": 0.0,
                                                       "roughnessFactor": 0.7}}]
    doc, binary = build([{**sphere(np.array([0.0, 0.0, 0.9]), r=0.5), "material": 0}, plane(0.0, 2.0, 1)],
                        materials=mats)
    scene = make_scene(write_gltf(tmp_path / "floor.gltf", doc, binary), env=0.0)
    scene.lights[0].direction = (0.0, 0.0, -1.0)
    scene.camera = Camera(position=(0.0, -5.0, 6.0), target=(0.0, 0.0, 0.0), fov_deg=34.0)
    size = (96, 96)
    owner, P, N, uv, eye = hits(scene, size)
    floor = owner == 1
    r_xy = np.linalg.norm(P[:, :2], axis=1)  # the shadow: the sphere's disc straight below it
    shadowed, lit = floor & (r_xy < 0.35), floor & (r_xy > 0.7) & (r_xy < 1.8)
    assert shadowed.sum() > 20 and lit.sum() > 200
    m = {"base": (0.5, 0.6, 0.7), "metallic": 0.0, "roughness": 0.7}
    want = expected_radiance(N[lit], P[lit], eye, m, 0.0, to_light=np.array([0.0, 0.0, 1.0]))
    for tech, img in _render_all(scene, size, gl_ctx).items():
        assert img[shadowed, :3].max() < 0.02 * want.mean(), tech
        np.testing.assert_allclose(img[lit, :3], want, rtol=0.02, atol=0.003, err_msg=tech)


# ----------------------------------------------------------------------------- the blurs
def test_scattering_never_crosses_between_skin_and_props(tmp_path, gl_ctx):
    """A skin quad and a bright emissive prop quad side by side: with ssss and tsd the skin pixels
    (those at the boundary included) are those of the scene without the prop, and the prop's are
    those of lambert, which blurs nothing: no light crosses either way."""
    left = {**card((-0.5, 0.0, 0.0), 0.5), "material": 0}
    right = {**card((0.5, 0.0, 0.0), 0.5), "material": 1}
    mats = [{"name": "skin", "pbrMetallicRoughness": {}},
            {"name": "lamp", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}, "emissiveFactor": [1, 1, 1]}]
    doc, binary = build([left, right], materials=mats)
    scene = make_scene(write_gltf(tmp_path / "lamp.gltf", doc, binary))
    # a point light 1.25 mm above the skin near the boundary: a steep irradiance that the blurs spread
    scene.lights = [Light(kind="point", position=(-0.15, 0.0, 0.25), intensity=1e-6, cast_shadows=False)]
    scene.camera = Camera(position=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), fov_deg=30.0)
    scene.mm_per_unit = 5.0  # the quads 5 mm wide: scattering reaches across them
    size = (96, 64)
    owner, *_ = hits(scene, size)
    with_prop = _render_all(scene, size, gl_ctx, ("lambert", "ssss", "tsd"))
    scene.surfaces = []
    without = _render_all(scene, size, gl_ctx, ("ssss", "tsd"))
    skin, prop = owner == 0, owner == 1
    assert skin.sum() > 500 and prop.sum() > 500
    for tech in ("ssss", "tsd"):
        np.testing.assert_allclose(with_prop[tech][skin, :3], without[tech][skin, :3], rtol=2e-3, atol=1e-4, err_msg=tech)
        np.testing.assert_allclose(with_prop[tech][prop, :3], with_prop["lambert"][prop, :3], rtol=2e-3, err_msg=tech)
    # and the blurs do act here: the scattered skin differs from lambert's (no scattering)
    for tech in ("ssss", "tsd"):
        diff = np.abs(with_prop[tech][skin, 0] - with_prop["lambert"][skin, 0]) / with_prop["lambert"][skin, 0].max()
        assert diff.max() > 0.05, (tech, diff.max())


# ----------------------------------------------------------------------------- UV sets and transforms
RED, BLUE = (220, 30, 30), (30, 30, 220)


def colour_checker(n=4):
    c = (np.add.outer(np.arange(n), np.arange(n)) % 2).astype(bool)
    img = np.empty((n, n, 3), np.uint8)
    img[c], img[~c] = BLUE, RED
    return img


def test_each_map_reads_its_own_uv_set_and_transform(tmp_path, gl_ctx):
    """The skin's albedo through TEXCOORD_1 and one KHR_texture_transform, its normal map through
    TEXCOORD_0 and another; a prop's base colour through TEXCOORD_0 and a third: the colour class
    (red / blue texel of a 4x4 checker, NEAREST, REPEAT) at each pixel is the one numpy finds by
    the extension's formula on the interpolated UV set."""
    t_skin = {"offset": [0.1, 0.2], "rotation": 0.3, "scale": [2.0, 1.5], "texCoord": 1}
    t_normal = {"scale": [3.0, 3.0]}
    t_prop = {"offset": [-0.3, 0.05], "rotation": -0.5, "scale": [1.5, 2.5]}
    uv1 = np.float32([[0.2, 0.9], [0.8, 0.7], [0.9, 0.1], [0.1, 0.3]])  # a second, skewed set
    left = {**card((-0.5, 0.0, 0.0), 0.45), "TEXCOORD_1": uv1, "material": 0}
    right = {**card((0.5, 0.0, 0.0), 0.45), "TEXCOORD_1": uv1[::-1].copy(), "material": 1}
    mats = [{"name": "skin", "pbrMetallicRoughness": {"baseColorTexture": {
                 "index": 0, "extensions": {"KHR_texture_transform": t_skin}}},
             "normalTexture": {"index": 1, "extensions": {"KHR_texture_transform": t_normal}}},
            {"name": "prop", "pbrMetallicRoughness": {"baseColorTexture": {
                "index": 0, "extensions": {"KHR_texture_transform": t_prop}}, "metallicFactor": 0.0}}]
    flat = np.full((2, 2, 3), (128, 128, 255), np.uint8)
    doc, binary = build([left, right], materials=mats, images=[colour_checker(), flat],
                        textures=[{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0}],
                        samplers=[{"magFilter": NEAREST, "minFilter": NEAREST}])
    doc["extensionsUsed"] = ["KHR_texture_transform"]
    scene = make_scene(write_gltf(tmp_path / "uv.gltf", doc, binary))
    scene.camera = Camera(position=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), fov_deg=30.0)
    size = (128, 64)
    owner, P, N, (uv0, uv1d), eye = hits(scene, size, uv_sets=True)

    def expect_blue(uv_dermis, tt):
        f = np.c_[uv_dermis[:, 0], 1.0 - uv_dermis[:, 1], np.ones(len(uv_dermis))]  # the file's UVs (v down)
        st = (_spec_matrix(tt.get("offset", [0, 0]), tt.get("rotation", 0.0), tt.get("scale", [1, 1])) @ f.T).T[:, :2]
        cell = np.floor(np.mod(st, 1.0) * 4)  # column, row from the top; REPEAT
        edge = np.min(np.abs(np.mod(st, 1.0) * 4 - np.round(np.mod(st, 1.0) * 4)), axis=1)
        return (cell.sum(1) % 2 == 1), edge > 0.15

    checks = 0
    for tech in ("lambert", "tsd"):
        img = _render_all(scene, size, gl_ctx, (tech,))[tech][:, :3]
        for k, uvs, tt in ((0, uv1d, t_skin), (1, uv0, t_prop)):
            blue, clear = expect_blue(uvs, tt)
            sel = (owner == k) & clear
            got_blue = img[sel, 2] > img[sel, 0]
            assert sel.sum() > 300 and blue[sel].any() and (~blue[sel]).any()
            assert np.mean(got_blue == blue[sel]) > 0.99, (tech, k, np.mean(got_blue == blue[sel]))
            checks += 1
    assert checks == 4


# ----------------------------------------------------------------------------- the offline reference
def test_reference_shades_surfaces_with_the_same_brdf(tmp_path):
    """dermis reference: the surfaces hit by its camera rays carry the glTF BRDF (same numpy
    expectation as the GPU's, within 1%); a MASK surface is refused with one line."""
    from dermis.reference.render import render_reference

    path, ref = grid_asset(tmp_path, mask=False)
    scene = make_scene(path)
    size = (80, 60)
    res = render_reference(scene, size, spp=1, progress=False, min_spacing_mm=0.8)  # coarse skin: not checked here
    owner, P, N, uv, eye = hits(scene, size)
    names = _names(scene)
    lit = (N @ TO_LIGHT > 0.25) & (np.sum(N * _unit(eye - P), 1) > 0.25)
    img = res.image.reshape(-1, 3)
    for k, name in enumerate(names[1:], 1):
        sel = (owner == k) & lit
        m = ref[name]
        want = expected_radiance(N[sel], P[sel], eye, m, m.get("occlusion", 1.0))
        np.testing.assert_allclose(img[sel], want, rtol=0.01, atol=0.002, err_msg=name)
    assert res.stats["surface_points"] > 300
    path, _ = grid_asset(tmp_path, mask=True)
    with pytest.raises(DermisError, match="does not support alphaMode MASK \\(material mask\\)"):
        render_reference(make_scene(path), (16, 16), spp=1, progress=False)


def test_a_mirroring_node_keeps_front_faces_in_front(tmp_path):
    """glTF 2.0 3.7.2.1: under a node transform of negative determinant clockwise triangles face
    front; the loader reverses them, so single-sided surfaces are not culled from the front."""
    mats = [{"name": "skin", "pbrMetallicRoughness": {}}, {"name": "prop", "pbrMetallicRoughness": {}}]
    doc, binary = build([{**sphere(np.array([1.0, 0.0, 0.0])), "material": 0},
                         {**sphere(np.array([-1.0, 0.0, 0.0])), "material": 1}], materials=mats)
    doc["nodes"][0]["scale"] = [-1.0, 1.0, 1.0]
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "mirror.gltf", doc, binary), skin_materials=["skin"])
    for m in (mesh, mat["surfaces"][0].mesh):
        p, i = m.positions.astype(np.float64), m.indices.astype(np.int64)
        face = np.cross(p[i[:, 1]] - p[i[:, 0]], p[i[:, 2]] - p[i[:, 0]])
        big = np.linalg.norm(face, axis=1) > 1e-6
        assert np.all(np.sum(face[big] * m.normals[i[big, 0]], 1) > 0)  # counter-clockwise from outside


def test_reference_environment_ggx_integral_matches_quadrature():
    """The reference's GGX environment integral (importance-sampled) against an independent
    brute-force quadrature of the same BRDF (brdf_terms) over the hemisphere, for a white
    environment (the directional albedo) and a sky/ground environment whose answer depends on
    the direction: within 2% at three view angles and two roughnesses."""
    from dermis.reference.metallic_roughness import brdf_terms, environment_specular_ggx_mc
    from dermis.prefiltered_environment import bilinear_equirect, direction_to_equirect

    h, w = 64, 128
    sky = np.ones((h, w, 3))
    sky[h // 2:] = 0.2  # lower hemisphere (v > 0.5: y < 0) darker
    # quadrature grid over the sphere (midpoint rule in cos(theta), phi about the normal +z)
    nt, nphi = 400, 400
    ct = (np.arange(nt) + 0.5) / nt
    ph = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    C, P = np.meshgrid(ct, ph, indexing="ij")
    S = np.sqrt(1 - C * C)
    L = np.stack([S * np.cos(P), S * np.sin(P), C], -1).reshape(-1, 3)
    dw = (1.0 / nt) * (2 * np.pi / nphi)
    for env in (np.ones((h, w, 3)), sky):
        Le = bilinear_equirect(env, *direction_to_equirect(L))
        for rough in (0.4, 0.7):
            for th in (0.0, 0.6, 1.2):
                N = np.array([[0.0, 0.0, 1.0]])
                V = np.array([[np.sin(th), 0.0, np.cos(th)]])
                base = np.array([[0.9, 0.6, 0.3]])
                f0 = 0.04 * 0 + base  # metallic 1: F0 = base colour
                _, fs = brdf_terms(np.repeat(N, len(L), 0), L, np.repeat(V, len(L), 0), np.repeat(base, len(L), 0),
                                   np.ones(len(L)), np.full(len(L), rough))
                quad = np.sum(fs * Le * L[:, 2:3], 0) * dw
                mc = environment_specular_ggx_mc(env, N, V, f0, np.array([rough]), samples=4096)[0]
                assert np.allclose(mc, quad, rtol=0.02), (rough, th, mc, quad)
