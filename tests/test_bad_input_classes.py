"""Issue 10: every class of bad input that escaped, each with its minimal input, gives one clear
DermisError (in-process) or one ``dermis: error:`` line with exit 2 and no output (CLI).
Also two loader bugs: 16-bit PNG keeps 16 bits, [material] albedo_color on a bare OBJ.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fuzzing as fz  # noqa: E402
from test_loaders import gltf_document, small_grid, write_glb, write_gltf  # noqa: E402

import dermis  # noqa: E402
from dermis.errors import DermisError  # noqa: E402
from dermis.renderer import Renderer  # noqa: E402
from dermis.scene.builtin import builtin_mesh, frame_scene, plane_xy  # noqa: E402
from dermis.scene.loaders import finish_mesh  # noqa: E402
from dermis.scene.model import Light, Scene  # noqa: E402

FAST = dict(samples=0, irradiance_size=64, shadow_size=128)
PLANE_TOML = '[mesh]\nbuiltin = "plane"\n\n[[lights]]\ndirection = [0.3, -0.4, -1.0]\nintensity = 3.0\n'


def one_line_error(fn, *tokens):
    with pytest.raises(DermisError) as info:
        fn()
    msg = str(info.value)
    assert msg and "\n" not in msg
    assert "--" not in msg, f"library message in CLI words: {msg}"
    for t in tokens:
        assert t in msg, (t, msg)
    return msg


def plane_scene():
    mesh, _, mm = builtin_mesh("plane")
    sc = Scene(mesh=mesh, mm_per_unit=mm, source="test-scene")
    frame_scene(sc)
    return sc


def render(sc, technique="lambert", gl_ctx=None, **kw):
    with Renderer(sc, (16, 16), ctx=gl_ctx, **{**FAST, **kw}) as r:
        return r.render(technique)


# ----------------------------------------------------------------------------- degenerate geometry / cameras

def test_mesh_at_one_point_is_refused(gl_ctx):
    sc = plane_scene()
    sc.mesh.positions[:] = sc.mesh.positions[0]
    one_line_error(lambda: render(sc, gl_ctx=gl_ctx), "zero extent")


def test_one_triangle_with_area_past_the_first_block_is_enough():
    from dermis.validation import _has_area

    p = np.zeros((5, 3))
    p[:, 0] = np.arange(5.0)
    tris = np.array([[0, 1, 2], [1, 2, 3], [2, 3, 4]])
    assert not _has_area(p, tris, 1e-12, block=1)
    p[4, 1] = 1.0  # only the last triangle (the third block of one) has area
    assert _has_area(p, tris, 1e-12, block=1)


@pytest.mark.parametrize("technique", ["lambert", "tsd"])
def test_mesh_of_only_zero_area_triangles_is_refused(technique, gl_ctx):
    """Fuzz seed 1703: the plane's vertices moved onto a line (extent along x, every triangle of zero
    area) passed the extent check and failed with an IndexError in the shared bounce's layout stretch."""
    sc = plane_scene()
    sc.mesh.positions[:, 1:] = 0.0
    one_line_error(lambda: render(sc, technique, gl_ctx), "builtin:plane", "no triangle of non-zero area")


@pytest.mark.parametrize("change, tokens", [
    (dict(near=1.0, far=1.0), ["[camera]", "far", "near"]),
    (dict(near=-1.0), ["[camera] near", "positive"]),
    (dict(position=(0.0, 0.0, 0.0), target=(0.0, 0.0, 0.0)), ["position and target coincide"]),
    (dict(position=(0.0, 5.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0)), ["up", "parallel"]),
    (dict(fov_deg=0.0), ["fov_deg"]),
    # round 15's fuzz (seed 1515): a positive but underflowing field of view gave a ValueError from
    # perspective() (the fitted camera's near plane at infinity)
    (dict(fov_deg=3.529751289066385e-193, fit=True), ["fov_deg", "[0.001, 170)"]),
    # round 16's fuzz (seed 1616): a near plane of 3e38 rendered an empty image (every triangle
    # clipped; the projection overflowed float32), and a far plane before the mesh does the same
    (dict(near=3e38), ["[camera] near", "beyond the whole scene"]),
    (dict(far=1e-6), ["[camera] far", "ends before the scene"]),
    (dict(position=(0.0, 0.0, 3.0), target=(0.0, 0.0, 6.0)), ["[camera] looks away", "behind the camera"]),
])
def test_degenerate_cameras_are_refused(change, tokens, gl_ctx):
    sc = plane_scene()
    for k, v in change.items():
        setattr(sc.camera, k, v)
    one_line_error(lambda: render(sc, gl_ctx=gl_ctx), "test-scene", *tokens)


def test_a_clip_range_through_the_mesh_is_allowed(gl_ctx):
    """The refusal above is for a range that misses the mesh's bounding sphere; a near plane
    through the mesh (a cross-section) renders, and clips what is nearer."""
    sc = plane_scene()
    d = float(np.linalg.norm(np.asarray(sc.camera.target, float) - np.asarray(sc.camera.position, float)))
    full = render(sc, gl_ctx=gl_ctx)
    sc.camera.near, sc.camera.far = 0.5 * d, 2.0 * d
    assert np.array_equal(render(sc, gl_ctx=gl_ctx), full)  # the plane lies at distance d: inside


def test_degenerate_camera_in_a_scene_file_names_the_file(tmp_path):
    p = tmp_path / "cam.toml"
    p.write_text(PLANE_TOML + "\n[camera]\nposition = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 3.0]\n")
    one_line_error(lambda: dermis.load_scene(p), "cam.toml", "[camera]", "coincide")


def test_zero_area_triangles_render_finite_with_tsd(gl_ctx):
    """A zero-area triangle with a UV footprint is rasterised in texture space: its vertices get a
    unit normal and tangent (they had none: normalize(0) = NaN on the GPU)."""
    p, n, uv, t = plane_xy(2.0, 4, uv_rect=(0.0, 0.0, 0.5, 0.5))
    k = len(p)
    p = np.concatenate([p, [[0.1, 0.1, 0.0]] * 3])
    uv = np.concatenate([uv, [[0.7, 0.7], [0.9, 0.7], [0.7, 0.9]]])
    t = np.concatenate([t, [[k, k + 1, k + 2]]])
    mesh = finish_mesh(p, None, uv, t, "zero-area", "v-up")
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
    assert np.allclose(np.linalg.norm(mesh.tangents[:, :3], axis=1), 1.0, atol=1e-5)
    sc = Scene(mesh=mesh, mm_per_unit=10.0, source="zero-area")
    frame_scene(sc)
    img = render(sc, "tsd", gl_ctx=gl_ctx)
    assert np.isfinite(img).all() and img.max() > 0


# ----------------------------------------------------------------------------- glTF structure

def _doc():
    pos, uv, idx = small_grid(2)
    return gltf_document(pos, uv, idx, normals=np.tile([[0.0, 0.0, 1.0]], (len(pos), 1)))


@pytest.mark.parametrize("name, change, tokens", [
    ("scene", lambda d: d.update(scene=5), ["'scene'", "out of range"]),
    ("children", lambda d: d["nodes"][0].update(children=[7]), ["nodes[0] children", "out of range"]),
    ("matrix3", lambda d: d["nodes"][0].update(matrix=[1, 0, 0]), ["nodes[0] matrix", "16"]),
    ("matrix15", lambda d: d["nodes"][0].update(matrix=[0] * 15), ["nodes[0] matrix", "16"]),
    ("matrix17", lambda d: d["nodes"][0].update(matrix=[0] * 17), ["nodes[0] matrix", "16"]),
    ("rotation3", lambda d: d["nodes"][0].update(rotation=[0, 0, 1]), ["nodes[0] rotation", "4"]),
    ("normal_count0", lambda d: d["accessors"][1].update(count=0), ["accessors[1] count"]),
    ("normal_count_mismatch", lambda d: d["accessors"][1].update(count=2), ["NORMAL", "POSITION"]),
    ("base_color_1e39", lambda d: d["materials"][0]["pbrMetallicRoughness"].update(baseColorFactor=[1e39, 0, 0, 1]),
     ["baseColorFactor"]),
    ("shared_child", lambda d: d.update(nodes=[{"children": [1, 1]}, {"mesh": 0}]), ["node 1", "twice"]),
])
def test_gltf_structure_errors(tmp_path, name, change, tokens):
    doc, binary = _doc()
    change(doc)
    p = write_gltf(tmp_path / f"{name}.gltf", doc, binary)
    one_line_error(lambda: dermis.load_scene(p), f"{name}.gltf", *tokens)


def test_glb_header_length_zero(tmp_path):
    doc, binary = _doc()
    p = write_glb(tmp_path / "zero.glb", doc, binary)
    raw = bytearray(p.read_bytes())
    raw[8:12] = (0).to_bytes(4, "little")
    p.write_bytes(bytes(raw))
    one_line_error(lambda: dermis.load_scene(p), "zero.glb", "header says 0 bytes")


def test_mesh_over_the_size_limit_is_refused_before_reading(tmp_path):
    """An accessor claiming 20 million vertices in a tiny file: refused from the document alone."""
    doc, binary = _doc()
    for a in doc["accessors"][:3]:
        a["count"] = 20_000_000
    p = write_gltf(tmp_path / "huge.gltf", doc, binary)
    one_line_error(lambda: dermis.load_scene(p), "huge.gltf", "limit")


def test_big_meshes_show_progress(tmp_path, monkeypatch, capsys):
    import dermis.scene.loaders as loaders

    monkeypatch.setattr(loaders, "PROGRESS_VERTICES", 4)
    pos, uv, idx = small_grid(3)
    finish_mesh(pos, None, uv, idx, str(tmp_path / "big.glb"), "v-up")
    assert "loading big.glb" in capsys.readouterr().err


# ----------------------------------------------------------------------------- OS errors, non-finite values

@pytest.mark.parametrize("texture, tokens", [
    ("/proc/self/mem", ["/proc/self/mem", "cannot read"]),
    ("a" * 300 + ".png", ["texture", "File name too long"]),
    ("/dev/zero", ["/dev/zero", "not a regular file"]),
])
def test_texture_os_errors(tmp_path, texture, tokens):
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + f'\n[material]\nalbedo = "{texture}"\n')
    one_line_error(lambda: dermis.load_scene(p), *tokens)


@pytest.mark.parametrize("extra, tokens", [
    # round 15's fuzz (seed 1515): os.stat's "embedded null byte" ValueError escaped as a traceback
    ('[material]\nnormal_map = "\\u0000"\n', ["[material] normal_map", "control characters"]),
    ('[environment]\nimage = "a\\u0000.hdr"\n', ["[environment] image", "control characters"]),
    ('[skin]\nprofile = "p\\u0000.json"\n', ["[skin] profile", "\\x00"]),
])
def test_nul_bytes_in_file_names_are_refused(tmp_path, extra, tokens):
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + "\n" + extra)
    one_line_error(lambda: dermis.load_scene(p), "s.toml", *tokens)
    from dermis.fileio import regular_file  # the one place every read goes through, for any other caller

    one_line_error(lambda: regular_file(tmp_path / "a\x00b", "texture"), "NUL byte")


@pytest.mark.parametrize("extra, tokens", [
    ("[[lights]]\ndirection = [0.0, 0.0, -1.0]\nintensity = 1e300\n", ["[[lights]] #2 intensity"]),
    ("[scene]\nmm_per_unit = 1e300\n", ["[scene] mm_per_unit"]),
    # fuzz seed 1704: 1e-300 mm per unit underflowed the layout's stretch (an IndexError in the bounce)
    ("[scene]\nmm_per_unit = 1e-300\n", ["[scene] mm_per_unit", "[1e-06, 1e+06]"]),
    ('[environment]\nimage = "huge.exr"\n', ["[environment] image", "huge.exr"]),
])
def test_out_of_range_values_are_refused_up_front(tmp_path, extra, tokens):
    fz.write_exr(tmp_path / "huge.exr", np.full((4, 8, 3), 3e38, np.float32))
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + "\n" + extra)
    one_line_error(lambda: dermis.load_scene(p), "s.toml", *tokens)


def test_layout_stretch_of_underflowing_triangles_is_none_not_an_index_error():
    """The bounce level's median stretch (texels per mm) over triangles whose extent in mm underflows
    to 0 has no value: 0.0, the same answer as for a layout of degenerate UVs, never an IndexError."""
    from dermis.geometry.interreflection import layout_median_stretch

    pos, uv, idx = small_grid()
    assert layout_median_stretch(pos, uv, idx, 1.0, 64) > 0
    assert layout_median_stretch(pos * 1e-300, uv, idx, 1e-300, 64) == 0.0


def test_overflowing_frame_is_an_error_not_inf():
    """The last guard (Renderer.render): a frame that overflowed the frame buffer (half floats on
    most GPUs) is an error naming the scene, never an image with inf in it."""
    from dermis.validation import check_rendered

    img = np.zeros((4, 4, 3), np.float32)
    check_rendered(img, plane_scene(), "lambert")
    img[1, 2, 0] = np.inf
    one_line_error(lambda: check_rendered(img, plane_scene(), "lambert"), "test-scene", "lambert", "NaN or infinite")


def test_light_intensity_over_the_limit_through_the_api(gl_ctx):
    sc = plane_scene()
    sc.lights = [Light(direction=(0.0, 0.0, -1.0), intensity=1e300)]
    one_line_error(lambda: render(sc, gl_ctx=gl_ctx), "test-scene", "[[lights]] #1 intensity")



@pytest.mark.parametrize("technique", ["lambert", "preintegrated", "tsd"])
def test_light_direction_of_any_finite_length_is_its_unit_direction(technique, gl_ctx):
    """A direction is only a direction: (-3.3e131, -2.57, -5.50) (fuzz seed 1701) lit with NaN (cast to
    float32 before normalising: -inf) and was then refused as "produced NaN ... lower the light"; it
    must render as (-1, 0, 0) does, and components past 1e154 (whose squares overflow) the same."""
    def lit(direction):
        sc = plane_scene()
        sc.lights = [Light(direction=direction, intensity=3.0)]
        return render(sc, technique, gl_ctx)

    unit = lit((-0.6, -0.0, -0.8))
    assert unit.max() > 0.01
    for d in ((-6e131, -2.5720307293879214, -8e131), (-6e300, 0.0, -8e300)):
        np.testing.assert_allclose(lit(d), unit, rtol=0, atol=1e-6 * unit.max())


def test_toml_light_direction_past_the_float_range_of_its_squares(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML.replace("[0.3, -0.4, -1.0]", "[3e300, -4e300, -1e301]"))
    d = np.array(dermis.load_scene(p).lights[0].direction)
    np.testing.assert_allclose(d, np.array([0.3, -0.4, -1.0]) / np.linalg.norm([0.3, -0.4, -1.0]), atol=1e-15)


@pytest.mark.parametrize("via_toml", [False, True])
def test_mesh_past_the_coordinate_limit_is_refused_before_it_is_framed(tmp_path, via_toml):
    """Fuzz seed 1702: a glTF vertex at 2.4e35 (its accessor's min/max lying) was framed first (the camera's
    distance overflowed to inf, its position to NaN) and refused only afterwards; the same one-line error
    must come without any arithmetic on the coordinates."""
    import warnings

    pos, uv, idx = small_grid()
    pos[5, 2] = 2.4e35
    doc, binary = gltf_document(pos.astype(np.float32), uv.astype(np.float32), idx)
    path = write_glb(tmp_path / "far.glb", doc, binary)
    if via_toml:
        path = tmp_path / "s.toml"
        path.write_text('[mesh]\nfile = "far.glb"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        one_line_error(lambda: dermis.load_scene(path), "far.glb", "mesh coordinates reach", "over the limit")


def test_obj_coordinate_past_float32_is_out_of_range_not_infinite(tmp_path):
    """Fuzz seed 1704: an OBJ vertex at 1e300 (finite in the file) was cast to float32 first and refused
    as "positions contain NaN or infinite values"; it is a coordinate over the limit."""
    p = tmp_path / "far.obj"
    p.write_text("v 0 0 0\nv 0.648 0.0 1e300\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    one_line_error(lambda: dermis.load_scene(p), "far.obj", "mesh coordinates reach 1e+300", "over the limit")
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1e300 0\nvt 0 1\nf 1/1 2/2 3/3\n")  # and a UV
    one_line_error(lambda: dermis.load_scene(p), "far.obj", "texture coordinates reach 1e+300")


def test_a_normal_past_float32s_squares_is_its_direction(tmp_path):
    """Fuzz seed 1702: a glTF normal with a finite component of ~1e30 (its square overflows float32) was
    divided by an infinite length and silently replaced by (0, 0, 1); only its direction counts."""
    import warnings

    pos, uv, idx = small_grid()
    n = np.tile(np.float32([0.0, 0.6, 0.8]), (len(pos), 1))
    loaded = []
    for scale in (1.0, 3e30):
        n[5] = np.float32([0.0, 0.6, 0.8]) * np.float32(scale)
        doc, binary = gltf_document(pos.astype(np.float32), uv.astype(np.float32), idx, normals=n)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            loaded.append(dermis.load_scene(write_glb(tmp_path / f"n{scale:g}.glb", doc, binary)).mesh.normals)
    np.testing.assert_allclose(loaded[1][5], [0.0, 0.6, 0.8], atol=1e-6)
    np.testing.assert_array_equal(loaded[1], loaded[0])

# ----------------------------------------------------------------------------- API arguments

@pytest.mark.parametrize("opts, tokens", [
    (dict(irradiance_size=10**9), ["irradiance_size"]),
    (dict(irradiance_size=0), ["irradiance_size"]),
    (dict(shadow_size=-1), ["shadow_size"]),
    (dict(samples=True), ["samples"]),
    (dict(bogus=1), ["bogus"]),
])
def test_render_options_are_checked(opts, tokens):
    one_line_error(lambda: dermis.render(plane_scene(), "lambert", (16, 16), **opts), *tokens)


@pytest.mark.parametrize("technique, size, tokens", [
    (["tsd"], (16, 16), ["technique"]), ("tsd", (16.5, 16), ["size"]), ("tsd", "16x16", ["size"]),
    ("nope", (16, 16), ["technique", "nope"]),
])
def test_render_arguments_are_checked(technique, size, tokens, gl_ctx):
    one_line_error(lambda: dermis.render(plane_scene(), technique, size, ctx=gl_ctx, **FAST), *tokens)


@pytest.mark.parametrize("arg", [None, 123, b"scene.toml", ["a.toml"]])
def test_load_scene_argument_types(arg):
    one_line_error(lambda: dermis.load_scene(arg), "load_scene", "path")


def test_render_needs_a_scene():
    one_line_error(lambda: dermis.render("scene.toml"), "Scene")


def test_pathological_uv_range_is_refused():
    p, n, uv, t = plane_xy(2.0, 8)
    one_line_error(lambda: finish_mesh(p, n, uv * 1000 - 500, t, "wide-uv", "v-up"), "wide-uv", "texture coordinates")


# ----------------------------------------------------------------------------- OBJ references

@pytest.mark.parametrize("obj_head, mtl, tokens", [
    ("mtllib ../m.mtl\n", None, ["mtllib", "outside"]),
    ("mtllib /etc/passwd\n", None, ["mtllib", "not a relative path"]),
    ("mtllib missing.mtl\n", None, ["missing.mtl", "not found"]),
    ("mtllib m.mtl\nusemtl skin\n", "newmtl skin\nmap_Kd ../outside.png\n", ["map_Kd", "outside"]),
    ("mtllib m.mtl\nusemtl skin\n", "newmtl skin\nmap_Kd /etc/hostname\n", ["map_Kd", "not a relative path"]),
])
def test_obj_references_escaping_the_folder_are_errors(tmp_path, obj_head, mtl, tokens):
    d = tmp_path / "asset"
    d.mkdir()
    Image.new("RGB", (2, 2)).save(tmp_path / "outside.png")
    (tmp_path / "m.mtl").write_text("newmtl skin\nKd 1 0 0\n")
    if mtl:
        (d / "m.mtl").write_text(mtl)
    pos, uv, idx = small_grid(2)
    (d / "mesh.obj").write_text(obj_head + fz.obj_text(pos, uv, idx))
    one_line_error(lambda: dermis.load_scene(d / "mesh.obj"), *tokens)


@pytest.mark.parametrize("first, head", [("v 0 0", "'v'"), ("vt 0", "'vt'"), ("f 1/1 0/2 3", "'f'")])
def test_malformed_obj_line_names_its_line(tmp_path, first, head):
    """Found by the fuzzer: 'v 0 0' and 'vt 0' raised ValueError/IndexError inside trimesh."""
    p = tmp_path / "m.obj"
    p.write_text(first + "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    one_line_error(lambda: dermis.load_scene(p), "m.obj", "line 1", head)


def test_gltf_accessor_type_of_the_wrong_json_type(tmp_path):
    """Found by the fuzzer: a list where componentType's number goes raised TypeError (unhashable)."""
    doc, binary = _doc()
    doc["accessors"][0]["componentType"] = [5126]
    doc["accessors"][1]["type"] = {"VEC3": 1}
    p = write_gltf(tmp_path / "t.gltf", doc, binary)
    one_line_error(lambda: dermis.load_scene(p), "t.gltf", "accessors[0] componentType")


# ----------------------------------------------------------------------------- images

def rgbe_rle_bytes(rgb: np.ndarray) -> bytes:
    """Radiance .hdr with new-style run-length scanlines (each component as literal runs of <= 128),
    written here from the format's description (Ward, Graphics Gems II) - not by the reader."""
    flat = fz.rgbe_bytes(rgb)
    head_end = flat.index(b"\n", flat.index(b"\n\n") + 2) + 1
    h, w = rgb.shape[:2]
    pix = np.frombuffer(flat[head_end:], np.uint8).reshape(h, w, 4)
    out = bytearray(flat[:head_end])
    for y in range(h):
        out += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            row = pix[y, :, c].tobytes()
            for i in range(0, w, 128):
                chunk = row[i:i + 128]
                out += bytes([len(chunk)]) + chunk
    return bytes(out)


def rgbe_expected(rgb):
    """Decoding of the values rgbe_bytes stored (mantissa m, exponent e): m * 2^(e - 136),
    Radiance's colr_color with its +0.5 ignored: tolerance one mantissa step."""
    rgb = np.asarray(rgb, np.float64)
    m = rgb.max(axis=2, keepdims=True)
    e = np.floor(np.log2(m)) + 1
    return np.floor(rgb * 256.0 / np.exp2(e)) * np.exp2(e - 8), np.exp2(e - 8)


@pytest.mark.parametrize("writer", [fz.rgbe_bytes, rgbe_rle_bytes])
def test_hdr_environment_reads_on_a_fresh_install(tmp_path, writer):
    rng = np.random.default_rng(5)
    env = rng.uniform(0.01, 50.0, (16, 32, 3))
    (tmp_path / "studio.hdr").write_bytes(writer(env))
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + '\n[environment]\nimage = "studio.hdr"\n')
    sc = dermis.load_scene(p)
    got = sc.environment.image.data
    want, step = rgbe_expected(env)
    assert got.shape == env.shape
    assert np.all(np.abs(got - want) <= step * 0.51 + 1e-6 * want), np.abs(got - want).max()


def test_hdr_header_over_the_pixel_limit_is_refused(tmp_path):
    (tmp_path / "big.hdr").write_bytes(fz.rgbe_bytes(np.ones((2, 2, 3)), declared=(100000, 100000)))
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + '\n[environment]\nimage = "big.hdr"\n')
    one_line_error(lambda: dermis.load_scene(p), "big.hdr", "100000x100000", "limit")


def test_png_decompression_bomb_refused_before_decoding(tmp_path):
    (tmp_path / "bomb.png").write_bytes(fz.bomb_png())
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + '\n[material]\nalbedo = "bomb.png"\n')
    one_line_error(lambda: dermis.load_scene(p), "bomb.png", "limit")


@pytest.mark.parametrize("channels", [1, 3])
def test_16_bit_png_keeps_16_bits(tmp_path, channels):
    """Issue 12: values 1/65535 apart stay apart (8 bits would merge 257 of them)."""
    import imagecodecs

    v = (np.arange(64, dtype=np.uint16) * 1000 + 7).reshape(8, 8)
    arr = v if channels == 1 else np.stack([v, v[::-1], v.T], axis=2)
    (tmp_path / "a16.png").write_bytes(imagecodecs.png_encode(arr))
    p = tmp_path / "s.toml"
    p.write_text(PLANE_TOML + '\n[material]\nalbedo = "a16.png"\n')
    got = dermis.load_scene(p).material.albedo.data
    c = arr.astype(np.float64) / 65535.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    want = np.repeat(lin[:, :, None], 3, axis=2) if channels == 1 else lin
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-7)


def test_obj_without_material_takes_the_scene_albedo_color(tmp_path, gl_ctx):
    """Issue 12: a flat OBJ under a directional light of irradiance E = 1000 at normal incidence,
    no environment, no specular: lambert radiance = albedo E / pi (numpy), for 1.0 and 0.5."""
    pos = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    uv = (pos[:, :2] + 1) / 2
    (tmp_path / "quad.obj").write_text(fz.obj_text(pos, uv, [[0, 1, 2], [0, 2, 3]]))
    values = {}
    for a in (1.0, 0.5):
        p = tmp_path / f"s{a}.toml"
        p.write_text(f'[mesh]\nfile = "quad.obj"\n\n[[lights]]\ndirection = [0.0, 0.0, -1.0]\nintensity = 1000.0\n'
                     f'cast_shadows = false\n\n[material]\nalbedo_color = [{a}, {a}, {a}]\nrho_s = 0.0\n'
                     f'pore_strength = 0.0\n\n[environment]\ncolor = [0.0, 0.0, 0.0]\n\n[camera]\n'
                     f'position = [0.0, 0.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\nfov_deg = 10.0\n')
        img = render(dermis.load_scene(p), "lambert", gl_ctx=gl_ctx)
        values[a] = img[8, 8]
        np.testing.assert_allclose(img[8, 8], a * 1000.0 / np.pi, rtol=2e-3)
    np.testing.assert_allclose(values[0.5] / values[1.0], 0.5, rtol=1e-3)


# ----------------------------------------------------------------------------- CLI

def run_cli(args, cwd):
    return subprocess.run([sys.executable, "-m", "dermis.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


def cli_inprocess(args, cwd: Path, outputs=()):
    return fz.run_cli_inprocess(["render", *map(str, args)], cwd, [str(o) for o in outputs])


BASE = ["--size", "16x16", "--irradiance-size", "64", "--shadow-size", "128", "--samples", "0", "-t", "lambert"]


@pytest.fixture()
def cli_dir(tmp_path):
    (tmp_path / "s.toml").write_text(PLANE_TOML)
    os.mkfifo(tmp_path / "fifo")
    return tmp_path


@pytest.mark.parametrize("extra, tokens", [
    (["--out", "/proc/a.png"], ["--out", "/proc/a.png"]),
    (["--out", "DIR"], ["--out", "is a directory"]),
    (["--out", ""], ["--out", "empty"]),
    (["--exposure", "1e308"], ["--exposure"]),
    (["--exposure", "nan"], ["--exposure"]),
    (["--exposure", "inf"], ["--exposure"]),
    (["--irradiance-size", "1000000000"], ["--irradiance-size"]),
    (["--shadow-size", "0"], ["--shadow-size"]),
    (["--exr", "FIFO"], ["--exr", "not a regular file"]),
    (["--stats", "/proc/s.json"], ["--stats", "/proc/s.json"]),
    (["--debug-buffers", "/proc/dbg"], ["--debug-buffers"]),
    (["--exr", "OUT"], ["--exr", "same file as --out"]),
])
def test_cli_bad_outputs_and_options(cli_dir, extra, tokens):
    out = cli_dir / "a.png"
    subs = {"DIR": str(cli_dir), "FIFO": str(cli_dir / "fifo"), "OUT": str(out)}
    extra = [subs.get(x, x) for x in extra]
    args = [cli_dir / "s.toml", *BASE, "--out", out] + extra
    res = cli_inprocess(args, cli_dir)
    assert res.kind == fz.ERROR, res
    for t in tokens:
        assert t in res.detail, (t, res.detail)
    assert not out.exists()


def test_cli_debug_folder_named_like_the_png(cli_dir):
    """Found by the fuzzer: --debug-buffers equal to --out renamed the PNG, then failed."""
    out = cli_dir / "a.png"
    res = cli_inprocess([cli_dir / "s.toml", *BASE, "--out", out, "--debug-buffers", out], cli_dir)
    assert res.kind == fz.ERROR and "--debug-buffers" in res.detail, res
    assert sorted(p.name for p in cli_dir.iterdir()) == ["fifo", "s.toml"]


def test_cli_outputs_are_all_or_nothing(cli_dir):
    """--exr fails (into /proc) after the render: the PNG must not have been written either."""
    out = cli_dir / "a.png"
    res = cli_inprocess([cli_dir / "s.toml", *BASE, "--out", out, "--stats", cli_dir / "s.json",
                         "--exr", "/proc/x.exr"], cli_dir)
    assert res.kind == fz.ERROR and "--exr" in res.detail, res
    assert sorted(p.name for p in cli_dir.iterdir()) == ["fifo", "s.toml"]


def test_cli_symlink_policy_writes_through_the_link(cli_dir):
    """An output that is a symbolic link: the file it points to is replaced, the link stays."""
    target = cli_dir / "real.png"
    target.write_bytes(b"old")
    (cli_dir / "link.png").symlink_to(target)
    res = cli_inprocess([cli_dir / "s.toml", *BASE, "--out", cli_dir / "link.png"], cli_dir, [target])
    assert res.kind == fz.OK, res
    assert (cli_dir / "link.png").is_symlink()
    assert Image.open(target).size == (16, 16)
    (cli_dir / "dangling.png").symlink_to(cli_dir / "nowhere.png")
    res = cli_inprocess([cli_dir / "s.toml", *BASE, "--out", cli_dir / "dangling.png"], cli_dir)
    assert res.kind == fz.ERROR and "does not exist" in res.detail, res


def test_cli_special_file_target_is_never_replaced(cli_dir):
    res = cli_inprocess([cli_dir / "s.toml", *BASE, "--out", cli_dir / "fifo"], cli_dir)
    assert res.kind == fz.ERROR and "not a regular file" in res.detail, res
    import stat

    assert stat.S_ISFIFO(os.lstat(cli_dir / "fifo").st_mode)


def test_cli_subprocess_warnings_are_silenced(tmp_path):
    """A real process: a glTF whose node translation overflows float32 makes numpy warn while
    loading; stderr must still be exactly the one error line."""
    pos, uv, idx = small_grid(2)
    doc, binary = gltf_document(pos, uv, idx, nodes=[{"mesh": 0, "translation": [1e300, 0, 0]}])
    p = write_gltf(tmp_path / "far.gltf", doc, binary)
    res = run_cli(["render", p, *BASE, "--out", tmp_path / "a.png"], tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith("dermis: error: ") and "far.gltf" in lines[0]
    assert sorted(x.name for x in tmp_path.iterdir()) == ["far.bin", "far.gltf"] or \
        not (tmp_path / "a.png").exists()


def test_cli_subprocess_exposure_and_output_folder(tmp_path):
    (tmp_path / "s.toml").write_text(PLANE_TOML)
    res = run_cli(["render", "s.toml", *BASE, "--exposure", "1e308", "--out", tmp_path], tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1 and "--exposure" in lines[0], res.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["s.toml"]
