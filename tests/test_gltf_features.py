"""glTF as authors write it (issue 17): sampler wrap modes and filters, texCoord sets,
KHR_texture_transform, COLOR_0, sparse accessors, several primitives with their own materials.

Small embedded assets are generated here in the manner of the Khronos sample models (BoxTextured,
TextureCoordinateTest, MultiUVTest, TextureTransformTest, BoxVertexColors, SimpleSparseAccessor)
and rendered or loaded; each is compared with its known appearance: a checker through REPEAT
shows the expected number of cells, a mirrored ramp runs back, vertex colours give the expected
corner colours, a sparse accessor moves the expected vertices.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import dermis
from dermis.errors import DermisError
from dermis.renderer import Renderer
from dermis.scene.loaders import apply_texture_transform, load_mesh_file

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_loaders import png_bytes, write_gltf  # noqa: E402

REPEAT, MIRROR, CLAMP, NEAREST = 10497, 33648, 33071, 9728
QUAD_P = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
QUAD_N = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
QUAD_I = np.array([0, 1, 2, 0, 2, 3], np.uint16)
# glTF UVs (v down): u runs with +x, v runs with -y (the top edge of the quad is v = 0)
QUAD_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
DARK, BRIGHT = 30, 230


def build(prims, *, materials=None, images=(), samplers=None, textures=None, accessors_extra=None):
    """(doc, binary) of one mesh; ``prims``: dicts of attribute name -> array, 'indices', 'material'."""
    blobs, views, accessors = [], [], []

    def view(data: bytes) -> int:
        off = sum(len(b) for b in blobs)
        blobs.append(data + b"\0" * (-len(data) % 4))
        views.append({"buffer": 0, "byteOffset": off, "byteLength": len(data)})
        return len(views) - 1

    def add(arr, comp, typ, minmax=False):
        a = {"bufferView": view(np.ascontiguousarray(arr).tobytes()), "componentType": comp, "count": len(arr), "type": typ}
        if minmax:
            a["min"], a["max"] = np.asarray(arr).min(0).tolist(), np.asarray(arr).max(0).tolist()
        accessors.append(a)
        return len(accessors) - 1

    types = {2: "VEC2", 3: "VEC3", 4: "VEC4"}
    out = []
    for p in prims:
        attrs = {}
        for name, arr in p.items():
            if name in ("indices", "material"):
                continue
            arr = np.asarray(arr, np.float32)
            attrs[name] = add(arr, 5126, types[arr.shape[1]], minmax=name == "POSITION")
        prim = {"attributes": attrs, "indices": add(np.asarray(p["indices"], np.uint16), 5123, "SCALAR"), "mode": 4}
        if p.get("material") is not None:
            prim["material"] = p["material"]
        out.append(prim)
    doc = {"asset": {"version": "2.0", "generator": "dermis tests"}, "meshes": [{"primitives": out}],
           "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0,
           "materials": materials if materials is not None else [{"pbrMetallicRoughness": {}}]}
    if images:
        doc["images"] = [{"bufferView": view(png_bytes(im)), "mimeType": "image/png"} for im in images]
        doc["textures"] = textures if textures is not None else [{"source": 0, **({} if samplers is None else {"sampler": 0})}]
    if samplers is not None:
        doc["samplers"] = samplers
    for a in accessors_extra or ():
        a = dict(a)
        for key in ("_base", "_indices", "_values"):
            if key in a:
                idx = view(a.pop(key).tobytes())
                if key == "_base":
                    a["bufferView"] = idx
                else:
                    a["sparse"]["indices" if key == "_indices" else "values"]["bufferView"] = idx
        accessors.append(a)
    doc["bufferViews"], doc["accessors"] = views, accessors
    binary = b"".join(blobs)
    doc["buffers"] = [{"byteLength": len(binary)}]
    return doc, binary


def quad(uv=QUAD_UV, **extra):
    return {"POSITION": QUAD_P, "NORMAL": QUAD_N, "TEXCOORD_0": uv, "indices": QUAD_I, "material": 0, **extra}


def textured(tex_info=None):
    return [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, **(tex_info or {})}}}]


def ramp(*levels):
    """A 1-row texture, one grey texel per level (u runs along it)."""
    return np.repeat(np.asarray(levels, np.uint8)[None, :, None], 3, axis=2)


def checker(n=2):
    c = (np.add.outer(np.arange(n), np.arange(n)) % 2).astype(np.uint8) * (BRIGHT - DARK) + DARK
    return np.repeat(c[:, :, None], 3, axis=2)


SCENE = """[scene]
mm_per_unit = 50.0
technique = "{technique}"
[mesh]
file = "{file}"
texture_space_uv = "auto"
[[lights]]
type = "directional"
direction = [0.0, 0.0, -1.0]
intensity = 3.0
cast_shadows = false
[camera]
position = [0.0, 0.0, 4.4]
target = [0.0, 0.0, 0.0]
fov_deg = 30.0
[material]
pore_strength = 0.0
rho_s = 0.0
{extra}"""


def scene_file(tmp_path, doc, binary, technique="lambert", extra=""):
    path = write_gltf(tmp_path / "asset.gltf", doc, binary)
    toml = tmp_path / "scene.toml"
    toml.write_text(SCENE.format(technique=technique, file=path.name, extra=extra))
    return toml


def render(tmp_path, gl_ctx, doc, binary, technique="lambert", extra="", size=64):
    sc = dermis.load_scene(scene_file(tmp_path, doc, binary, technique, extra))
    with Renderer(sc, (size, size), ctx=gl_ctx, samples=0) as r:
        img = r.render(technique, with_alpha=True)
    return img[:, :, :3], img[:, :, 3] > 0.5


def runs(values) -> list:
    """Lengths of the dark/bright runs along a line of luminances (threshold half-way)."""
    v = np.asarray(values)
    b = v > 0.5 * (v.min() + v.max())
    edges = np.flatnonzero(np.diff(b.astype(int))) + 1
    return np.diff(np.r_[0, edges, len(b)]).tolist()


def row_runs(img, mask, axis=0):
    """Runs along the middle row (axis 0) or the middle column (axis 1) of the lit quad."""
    lum = img.mean(axis=2)
    mid = img.shape[0] // 2
    line, m = (lum[mid], mask[mid]) if axis == 0 else (lum[:, mid], mask[:, mid])
    return runs(line[m])


# ----------------------------------------------------------------------------- samplers


def test_box_textured_repeat_shows_every_cell(tmp_path, gl_ctx):
    """BoxTextured: UVs beyond 1 with REPEAT (the sampler) tile the checker: UVs 0..3 over a 2x2
    checker give 6 cells across each axis (clamped, as before: 1 cell and an edge smear)."""
    doc, binary = build([quad(QUAD_UV * 3)], materials=textured(), images=[checker()],
                        samplers=[{"wrapS": REPEAT, "wrapT": REPEAT, "magFilter": NEAREST, "minFilter": NEAREST}])
    img, mask = render(tmp_path, gl_ctx, doc, binary)
    for axis in (0, 1):
        r = row_runs(img, mask, axis)
        assert len(r) == 6, r
        assert max(r) - min(r) <= 2  # equal cells (a pixel of rasterisation either way)


def test_default_sampler_repeats(tmp_path):
    """glTF 2.0 5.26: a texture without a sampler repeats, filtered automatically."""
    doc, binary = build([quad()], materials=textured(), images=[checker()], textures=[{"source": 0}])
    _, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    assert mat["albedo"].wrap == ("repeat", "repeat") and mat["albedo"].filters is None


def test_sampler_state_reaches_the_gpu_texture(tmp_path, gl_ctx):
    from dermis.gl.resources import GpuScene

    doc, binary = build([quad()], materials=textured(), images=[checker()],
                        samplers=[{"wrapS": REPEAT, "wrapT": CLAMP, "magFilter": NEAREST, "minFilter": 9729}])
    sc = dermis.load_scene(scene_file(tmp_path, doc, binary))
    gs = GpuScene(gl_ctx, sc)
    try:
        t = gs.textures["albedo"]
        assert (t.repeat_x, t.repeat_y) == (True, False)
        assert t.filter == (9729, NEAREST)
    finally:
        gs.release()


def test_mirrored_repeat_runs_back(tmp_path, gl_ctx):
    """MIRRORED_REPEAT along u over u = 0..2 of a [dark, bright] ramp: dark, bright, bright, dark
    (three runs, the middle one twice as wide); REPEAT would alternate four runs."""
    uv = QUAD_UV * np.array([2.0, 1.0], np.float32)
    sampler = {"wrapS": MIRROR, "wrapT": CLAMP, "magFilter": NEAREST, "minFilter": NEAREST}
    doc, binary = build([quad(uv)], materials=textured(), images=[ramp(DARK, BRIGHT)], samplers=[sampler])
    img, mask = render(tmp_path, gl_ctx, doc, binary)
    r = row_runs(img, mask)
    assert len(r) == 3, r
    assert abs(r[1] - 2 * r[0]) <= 2 and abs(r[2] - r[0]) <= 2
    assert img.mean(2)[32][mask[32]][0] < img.mean(2)[32][mask[32]][len(r) and r[0]]  # starts dark
    sampler["wrapS"] = REPEAT
    doc, binary = build([quad(uv)], materials=textured(), images=[ramp(DARK, BRIGHT)], samplers=[sampler])
    assert len(row_runs(*render(tmp_path, gl_ctx, doc, binary))) == 4


def test_mirrored_repeat_doubles_every_map_consistently(tmp_path):
    """With one map mirrored along u the UVs are halved, so every map is doubled: the mirrored one
    with its flipped copy, a REPEAT one with itself, a CLAMP one with its edge texels; sampling
    each doubled map at u/2 must equal sampling the original with its own wrap at u."""
    from dermis.scene.loaders import _mirror_doubled

    img = np.arange(4, dtype=np.float32)[None, :, None].repeat(2, 0)  # 2 rows x 4 texels

    def nearest(data, u, mode):  # GL's wrap, then the texel (u along columns)
        W = data.shape[1]
        if mode == "repeat":
            u = u % 1.0
        elif mode == "mirror":
            u = 1.0 - np.abs((u % 2.0) - 1.0)
        u = np.clip(u, 0.0, 1.0 - 1e-9)
        return data[0, (u * W).astype(int), 0]

    u = np.linspace(-1.9, 2.9, 97) + 1e-3
    for mode in ("mirror", "repeat", "clamp"):
        doubled, wrap = _mirror_doubled(img, (mode, "clamp"), (True, False), v_down=True)
        assert doubled.shape == (2, 8, 1)
        np.testing.assert_array_equal(nearest(doubled, u / 2, wrap[0]), nearest(img, u, mode), err_msg=mode)


# ----------------------------------------------------------------------------- texCoord sets


def test_texcoord_1_is_sampled(tmp_path, gl_ctx):
    """TextureCoordinateTest / MultiUVTest: the map names texCoord 1; TEXCOORD_0 is a degenerate
    set (every vertex at the dark texel) so sampling through it would give a flat face."""
    uv0 = np.zeros((4, 2), np.float32) + 0.25
    doc, binary = build([quad(uv0, TEXCOORD_1=QUAD_UV)], materials=textured({"texCoord": 1}),
                        images=[ramp(DARK, BRIGHT)], samplers=[{"magFilter": NEAREST, "minFilter": NEAREST}])
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    assert mat["albedo"].texcoord == 1
    np.testing.assert_allclose(mesh.uvs1, np.c_[QUAD_UV[:, 0], 1.0 - QUAD_UV[:, 1]])  # TEXCOORD_1, v flipped
    np.testing.assert_allclose(mat["albedo"].mapped_uvs(mesh), mesh.uvs1)
    img, mask = render(tmp_path, gl_ctx, doc, binary)
    r = row_runs(img, mask)
    assert len(r) == 2 and abs(r[0] - r[1]) <= 2, r  # left half dark, right half bright


def test_maps_on_different_uv_sets_each_read_their_own(tmp_path):
    """Each map keeps its texCoord (rendered per map: tests/test_metallic_roughness.py); the normal
    map's tangents follow its own set (here TEXCOORD_1 = TEXCOORD_0 mirrored in u: w flips)."""
    mats = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "normalTexture": {"index": 0, "texCoord": 1}}]
    uv1 = np.c_[1.0 - QUAD_UV[:, 0], QUAD_UV[:, 1]].astype(np.float32)
    doc, binary = build([quad(TEXCOORD_1=uv1)], materials=mats, images=[checker()])
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    assert (mat["albedo"].texcoord, mat["normal_map"].texcoord) == (0, 1)
    np.testing.assert_allclose(mat["normal_map"].mapped_uvs(mesh), np.c_[uv1[:, 0], 1.0 - uv1[:, 1]])
    np.testing.assert_allclose(mesh.tangents[:, :3], np.tile([-1.0, 0.0, 0.0], (4, 1)), atol=1e-6)


def test_missing_texcoord_set_is_named(tmp_path):
    doc, binary = build([quad()], materials=textured({"texCoord": 2}), images=[checker()])
    with pytest.raises(DermisError, match="has no TEXCOORD_2, which its material's baseColorTexture samples"):
        load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))


# ----------------------------------------------------------------------------- KHR_texture_transform


def _spec_matrix(offset, rotation, scale):
    """The extension README's GLSL, literally: mat3 constructors are column-major."""
    def mat3_cols(*v):
        return np.array(v, np.float64).reshape(3, 3).T

    c, s = np.cos(rotation), np.sin(rotation)
    translation = mat3_cols(1, 0, 0, 0, 1, 0, offset[0], offset[1], 1)
    rot = mat3_cols(c, s, 0, -s, c, 0, 0, 0, 1)
    sc = mat3_cols(scale[0], 0, 0, 0, scale[1], 0, 0, 0, 1)
    return translation @ rot @ sc


def test_texture_transform_matches_the_extension_formula(tmp_path):
    tt = {"offset": [0.25, -0.5], "rotation": 0.392699, "scale": [1.5, 0.75]}
    uv = np.array([[0.1, 0.2], [0.9, 0.3], [0.7, 0.8], [0.2, 0.6]], np.float32)
    doc, binary = build([quad(uv)], materials=textured({"extensions": {"KHR_texture_transform": tt}}),
                        images=[checker()], samplers=[{}])
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    expect = (_spec_matrix(tt["offset"], tt["rotation"], tt["scale"]) @ np.c_[uv, np.ones(4)].T).T[:, :2]
    np.testing.assert_allclose(mat["albedo"].mapped_uvs(mesh), np.c_[expect[:, 0], 1.0 - expect[:, 1]], atol=1e-6)
    np.testing.assert_allclose(mesh.uvs, np.c_[uv[:, 0], 1.0 - uv[:, 1]], atol=1e-7)  # the mesh keeps its own
    np.testing.assert_allclose(apply_texture_transform(uv.astype(np.float64), None), uv)


def test_texture_transform_offset_renders(tmp_path, gl_ctx):
    """TextureTransformTest's offset quads: UVs 0..0.5 of a [dark, bright] ramp show only the dark
    texel; an offset of 0.5 in u shows only the bright one."""
    uv = QUAD_UV * 0.5
    sampler = [{"wrapS": CLAMP, "wrapT": CLAMP, "magFilter": NEAREST, "minFilter": NEAREST}]
    means = []
    for info in ({}, {"extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0]}}}):
        doc, binary = build([quad(uv)], materials=textured(info), images=[ramp(DARK, BRIGHT)], samplers=sampler)
        img, mask = render(tmp_path, gl_ctx, doc, binary)
        lum = img.mean(2)[mask]
        assert lum.std() < 0.05 * lum.mean()  # one texel over the whole quad
        means.append(lum.mean())
    # the two texels' linear values (sRGB decoded) in ratio, under the same light
    lin = ((np.array([DARK, BRIGHT]) / 255 + 0.055) / 1.055) ** 2.4
    assert means[1] / means[0] == pytest.approx(lin[1] / lin[0], rel=0.05)


def test_texture_transform_texcoord_override(tmp_path):
    uv0 = np.zeros((4, 2), np.float32)
    info = {"texCoord": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1}}}
    doc, binary = build([quad(uv0, TEXCOORD_1=QUAD_UV)], materials=textured(info), images=[checker()])
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    np.testing.assert_allclose(mat["albedo"].mapped_uvs(mesh), np.c_[QUAD_UV[:, 0], 1.0 - QUAD_UV[:, 1]])


def test_different_transforms_per_map_are_kept_per_map(tmp_path):
    mats = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
             "normalTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [2, 2]}}}}]
    doc, binary = build([quad()], materials=mats, images=[checker()])
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    np.testing.assert_allclose(mat["albedo"].mapped_uvs(mesh), mesh.uvs)
    # file v' = 2 v: in dermis's v-up UVs, v' = 1 - 2 (1 - v)
    np.testing.assert_allclose(mat["normal_map"].mapped_uvs(mesh), np.c_[2 * mesh.uvs[:, 0], 2 * mesh.uvs[:, 1] - 1],
                               atol=1e-6)


# ----------------------------------------------------------------------------- COLOR_0

CORNERS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], np.float32)  # red, green, blue, white


def test_box_vertex_colors_render_at_the_corners(tmp_path, gl_ctx):
    """BoxVertexColors: COLOR_0 multiplies the base colour. Each corner shows its colour, and the
    centre (on the diagonal 0-2 the two triangles share) the mean of red and blue."""
    mats = [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0]}}]
    prim = {"POSITION": QUAD_P, "NORMAL": QUAD_N, "COLOR_0": CORNERS, "indices": QUAD_I, "material": 0}
    doc, binary = build([prim], materials=mats)
    img, mask = render(tmp_path, gl_ctx, doc, binary)
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min() + 2, ys.max() - 2, xs.min() + 2, xs.max() - 2
    # image rows run down: corner 0 (-1, -1) is bottom-left
    at = {0: img[y1, x0], 1: img[y1, x1], 2: img[y0, x1], 3: img[y0, x0]}
    for k in (0, 1, 2):
        c = at[k] / at[k].sum()
        assert c.argmax() == k and c[k] > 0.8, (k, at[k])
    w = at[3] / at[3].sum()
    np.testing.assert_allclose(w, 1 / 3, atol=0.05)
    mid = img[(y0 + y1) // 2, (x0 + x1) // 2]
    assert mid[0] / mid[2] == pytest.approx(1.0, rel=0.1) and mid[1] < 0.1 * mid[0]


def test_vertex_colours_baked_with_the_base_colour_factor(tmp_path):
    """The baked albedo at each (atlas) vertex's UV is its COLOR_0 times baseColorFactor."""
    mats = [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 0.25, 1.0]}}]
    rng = np.random.default_rng(3)
    cols = rng.uniform(0.1, 1.0, (4, 4)).astype(np.float32)  # VEC4: alpha is not colour
    prim = {"POSITION": QUAD_P, "COLOR_0": cols, "indices": QUAD_I, "material": 0}
    doc, binary = build([prim], materials=mats)
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    tex = mat["albedo"].data
    H, W = tex.shape[:2]
    # nearest texel to each vertex's UV, moved a texel into its triangle's interior via the centroid
    for vi in range(len(mesh.positions)):
        src = int(np.argmin(np.linalg.norm(QUAD_P - mesh.positions[vi], axis=1)))
        uv = mesh.uvs[vi]
        col, row = int(uv[0] * W - 0.5), int((1 - uv[1]) * H - 0.5)
        col, row = np.clip([col, row], 0, [W - 1, H - 1])
        np.testing.assert_allclose(tex[row, col], cols[src, :3] * [0.5, 1.0, 0.25], atol=0.03)


def test_vertex_colours_multiply_a_texture_in_its_own_layout(tmp_path):
    """COLOR_0 x baseColorTexture: baked into the map in the mesh's own (unique) UV layout. The
    texels at the corners carry the corner colours times the map, the centre texel (on the shared
    diagonal 0-2) the mean of colours 0 and 2 times the map."""
    tex = np.full((64, 64, 3), 200, np.uint8)
    doc, binary = build([quad(COLOR_0=CORNERS)], materials=textured(), images=[tex], samplers=[{}])
    mesh, mat = load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    grey = ((200 / 255 + 0.055) / 1.055) ** 2.4
    a = mat["albedo"].data
    assert a.shape == (64, 64, 3) and "COLOR_0" in mat["albedo"].source
    # dermis convention: row 0 = top = v 1; corner k sits at mesh.uvs[k]
    for k in range(4):
        u, v = mesh.uvs[k]
        row, col = min(int((1 - v) * 64), 63), min(int(u * 64), 63)
        np.testing.assert_allclose(a[row, col], CORNERS[k] * grey, atol=0.04 * grey + 1e-3)
    np.testing.assert_allclose(a[32, 32], 0.5 * (CORNERS[0] + CORNERS[2]) * grey, atol=0.04 * grey)


def test_vertex_colours_with_a_repeating_texture_are_refused(tmp_path):
    doc, binary = build([quad(QUAD_UV * 3, COLOR_0=CORNERS)], materials=textured(), images=[checker()])
    with pytest.raises(DermisError, match=r"vertex colours \(COLOR_0\).*outside \[0, 1\].*COLOR_0 with this textured "
                                          r"material is not supported"):
        load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))


# ----------------------------------------------------------------------------- sparse accessors


def _sparse_grid(with_base=True):
    """SimpleSparseAccessor: a 4x3 grid of positions; the sparse part lifts vertices 8 and 10."""
    g = np.stack(np.meshgrid(np.arange(4.0), np.arange(3.0), indexing="xy"), -1).reshape(-1, 2)
    base = np.c_[g, np.zeros(len(g))].astype(np.float32)
    idx = np.array([8, 10], np.uint16)
    vals = np.array([[0, 2.5, 0.5], [2, 2.75, 0.5]], np.float32)
    tris = []
    for r in range(2):
        for c in range(3):
            a = r * 4 + c
            tris += [a, a + 1, a + 5, a, a + 5, a + 4]
    acc = {"componentType": 5126, "count": len(base), "type": "VEC3", "min": [0, 0, 0], "max": [3, 2.75, 0.5],
           "sparse": {"count": 2, "indices": {"componentType": 5123}, "values": {}}, "_indices": idx, "_values": vals}
    if with_base:
        acc["_base"] = base
    doc, binary = build([{"POSITION": QUAD_P, "indices": np.array(tris, np.uint16), "material": None}],
                        accessors_extra=[acc])
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = len(doc["accessors"]) - 1
    expect = (base if with_base else np.zeros_like(base)).copy()
    expect[idx] = vals
    return doc, binary, expect


@pytest.mark.parametrize("with_base", [True, False])
def test_sparse_accessor_moves_the_named_vertices(tmp_path, with_base):
    from dermis.scene.loaders import GltfAsset

    doc, binary, expect = _sparse_grid(with_base)
    asset = GltfAsset(write_gltf(tmp_path / "a.gltf", doc, binary))
    got = asset.accessor(doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"])
    np.testing.assert_array_equal(got, expect)
    if with_base:  # and the mesh is built from them (no UVs: a generated layout splits vertices)
        mesh, _ = load_mesh_file(tmp_path / "a.gltf")
        lifted = mesh.positions[mesh.positions[:, 2] > 0.25]
        assert {tuple(np.round(p, 4)) for p in lifted} == {(0.0, 2.5, 0.5), (2.0, 2.75, 0.5)}


def test_sparse_indices_must_increase(tmp_path):
    doc, binary, _ = _sparse_grid()
    view = doc["bufferViews"][doc["accessors"][-1]["sparse"]["indices"]["bufferView"]]
    raw = bytearray(binary)
    raw[view["byteOffset"]: view["byteOffset"] + 4] = np.array([10, 8], np.uint16).tobytes()
    with pytest.raises(DermisError, match="sparse indices must increase strictly"):
        load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, bytes(raw)))


# ----------------------------------------------------------------------------- several materials


def _two_materials():
    left = QUAD_P * [0.5, 1, 1] - [0.5, 0, 0]
    right = QUAD_P * [0.5, 1, 1] + [0.5, 0, 0]
    mats = [{"name": "skin", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.4, 1]}},
            {"name": "eye", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.9, 1]}}]
    prims = [{"POSITION": left, "NORMAL": QUAD_N, "TEXCOORD_0": QUAD_UV, "indices": QUAD_I, "material": 0},
             {"POSITION": right, "NORMAL": QUAD_N, "TEXCOORD_0": QUAD_UV, "indices": QUAD_I, "material": 1}]
    return build(prims, materials=mats)


def test_several_materials_need_the_scene_to_name_the_skin(tmp_path):
    doc, binary = _two_materials()
    with pytest.raises(DermisError, match=r"2 materials \('skin', 'eye'\); name the skin ones in the scene's \[skin\] materials"):
        dermis.load_scene(scene_file(tmp_path, doc, binary))


def test_non_skin_primitives_become_metallic_roughness_surfaces(tmp_path, capsys):
    doc, binary = _two_materials()
    sc = dermis.load_scene(scene_file(tmp_path, doc, binary, extra='[skin]\nmaterials = ["skin"]\n'))
    assert capsys.readouterr().err.strip() == ""
    assert len(sc.mesh.indices) == 2 and sc.mesh.positions[:, 0].max() <= 0.0 + 1e-6  # only the left quad is skin
    assert len(sc.surfaces) == 1 and sc.surfaces[0].material.name == "eye"
    assert sc.surfaces[0].mesh.positions[:, 0].min() >= 0.0 - 1e-6
    assert sc.surfaces[0].material.base_color == pytest.approx((0.9, 0.9, 0.9, 1.0))
    assert sc.material.albedo_color == pytest.approx((0.8, 0.5, 0.4))
    # by index, and both as skin when they agree in what dermis reads
    sc = dermis.load_scene(scene_file(tmp_path, doc, binary, extra="[skin]\nmaterials = [1]\n"))
    assert sc.material.albedo_color == pytest.approx((0.9, 0.9, 0.9))
    with pytest.raises(DermisError, match="skin materials 'skin' and 'eye' have different base colours"):
        dermis.load_scene(scene_file(tmp_path, doc, binary, extra='[skin]\nmaterials = ["skin", "eye"]\n'))
    with pytest.raises(DermisError, match=r"\[skin\] materials names 'teeth', a material no triangle primitive uses"):
        dermis.load_scene(scene_file(tmp_path, doc, binary, extra='[skin]\nmaterials = ["teeth"]\n'))
    with pytest.raises(DermisError, match=r"\[skin\] materials must be a non-empty array"):
        dermis.load_scene(scene_file(tmp_path, doc, binary, extra="[skin]\nmaterials = \"skin\"\n"))


# ----------------------------------------------------------------------------- validation, tsd


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["samplers"][0].update(wrapS=1234), "samplers\\[0\\] wrapS must be one of"),
    (lambda d: d["samplers"][0].update(minFilter=33071), "samplers\\[0\\] minFilter must be one of"),
    (lambda d: d["textures"][0].update(sampler=5), "textures\\[0\\] sampler index 5 is out of range"),
    (lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]),
     "names KHR_draco_mesh_compression, a glTF extension dermis does not support"),
    (lambda d: d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(
        extensions={"KHR_texture_transform": {"scale": [1, "x"]}}), "KHR_texture_transform scale must be 2 finite"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(COLOR_0=2),  # accessor 2: TEXCOORD_0, a VEC2
     "attribute COLOR_0 has type VEC2/5126; glTF 2.0 allows VEC3/VEC4"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(TEXCOORD_1=1),  # accessor 1: NORMAL, a VEC3
     "attribute TEXCOORD_1 has type VEC3/5126; glTF 2.0 allows VEC2"),
])
def test_new_fields_are_checked_up_front(tmp_path, edit, message):
    doc, binary = build([quad()], materials=textured(), images=[checker()], samplers=[{}])
    edit(doc)
    with pytest.raises(DermisError, match=message):
        load_mesh_file(write_gltf(tmp_path / "a.gltf", json.loads(json.dumps(doc)), binary))


def test_tsd_on_repeating_uvs_uses_a_generated_layout(tmp_path, gl_ctx):
    """BoxTextured under tsd: its UVs (0..3, REPEAT) are no texture-space layout; "auto" generates
    one (a brown square before), and the checker still shows its 6 cells through the asset's UVs."""
    from dermis.geometry.texture_space import layout_problem

    doc, binary = build([quad(QUAD_UV * 3)], materials=textured(), images=[checker()],
                        samplers=[{"wrapS": REPEAT, "wrapT": REPEAT, "magFilter": NEAREST, "minFilter": NEAREST}])
    sc = dermis.load_scene(scene_file(tmp_path, doc, binary, "tsd"))
    assert "outside [0, 1]" in layout_problem(sc.mesh.uvs, sc.mesh.indices)
    img, mask = render(tmp_path, gl_ctx, doc, binary, "tsd")
    assert mask.mean() > 0.5
    for axis in (0, 1):
        assert len(row_runs(img, mask, axis)) == 6


def test_reference_renderer_samples_repeating_maps_like_the_gpu():
    """The CPU reference applies REPEAT before its clamp-to-edge bilinear lookup."""
    from dermis.reference.sampling import bilinear, wrapped_uv
    from dermis.scene.model import Texture

    img = checker(4).astype(np.float64)
    uv = np.array([[0.3, 0.6], [2.3, -0.4], [-1.7, 3.6]])
    rep = Texture(img, wrap=("repeat", "repeat"))
    got = bilinear(img, *wrapped_uv(uv, rep))
    np.testing.assert_allclose(got, np.repeat(got[:1], 3, axis=0))  # one place, three periods apart
    clamped = bilinear(img, *wrapped_uv(uv, Texture(img)))
    assert not np.allclose(clamped, np.repeat(clamped[:1], 3, axis=0))


def test_unapplied_features_are_named(tmp_path, capsys):
    doc, binary = build([quad()], materials=[{"pbrMetallicRoughness": {}, "occlusionTexture": {"index": 0}}],
                        images=[checker()])
    doc["extensionsUsed"] = ["KHR_materials_clearcoat"]
    doc["nodes"][0]["camera"] = 0
    doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}]
    load_mesh_file(write_gltf(tmp_path / "a.gltf", doc, binary))
    err = capsys.readouterr().err.splitlines()
    assert all(line.startswith("dermis: warning: ") for line in err)
    for feature in ("KHR_materials_clearcoat is not supported", "glTF cameras are not used",
                    "occlusionTexture is not supported"):
        assert sum(feature in line for line in err) == 1, (feature, err)


def test_tsd_refuses_repeating_uvs_as_its_own_layout(tmp_path, gl_ctx):
    """With texture_space_uv = "mesh" tsd would diffuse in UVs 0..3, of which its coverage count
    sees only [0, 1]: refused with one line instead of a wrong image."""
    doc, binary = build([quad(QUAD_UV * 3)], materials=textured(), images=[checker()], samplers=[{}])
    toml = scene_file(tmp_path, doc, binary, "tsd")
    toml.write_text(toml.read_text().replace('texture_space_uv = "auto"', 'texture_space_uv = "mesh"'))
    sc = dermis.load_scene(toml)
    with Renderer(sc, (32, 32), ctx=gl_ctx, samples=0) as r:
        with pytest.raises(DermisError, match=r"UVs run outside \[0, 1\] \(from -2 to 3.*texture_space_uv = \"auto\""):
            r.render("tsd")


@pytest.mark.parametrize("v_down", [True, False])
@pytest.mark.parametrize("mode", ["mirror", "repeat", "clamp"])
def test_mirror_doubling_along_v_follows_the_file_convention(mode, v_down):
    """Along v the doubled image's first half is the top (glTF, v down) or the bottom (v up) one."""
    from dermis.scene.loaders import _mirror_doubled

    img = np.arange(4, dtype=np.float32)[:, None, None].repeat(2, 1)  # 4 rows x 2 texels, row 0 = top

    def nearest(data, v, wrap):  # v in the file's convention -> the row GL samples
        H = data.shape[0]
        if wrap == "repeat":
            v = v % 1.0
        elif wrap == "mirror":
            v = 1.0 - np.abs((v % 2.0) - 1.0)
        v = np.clip(v, 0.0, 1.0 - 1e-9)
        rows_from_top = v if v_down else 1.0 - 1e-9 - v
        return data[(rows_from_top * H).astype(int), 0, 0]

    v = np.linspace(-1.9, 2.9, 97) + 1e-3
    doubled, wrap = _mirror_doubled(img, ("clamp", mode), (False, True), v_down=v_down)
    assert doubled.shape == (8, 2, 1)
    np.testing.assert_array_equal(nearest(doubled, v / 2, wrap[1]), nearest(img, v, mode))
