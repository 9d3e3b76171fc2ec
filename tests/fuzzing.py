"""The fuzz harness: hypothesis strategies for every kind of input a user hands dermis,
and a strict classification of what came back.

Families: scene TOML, glTF/GLB (JSON and binary chunk), OBJ/MTL, images (PNG 1/8/16-bit, JPEG,
EXR, Radiance HDR, decompression bombs), API arguments (load_scene/render/Renderer and scene
objects changed through the API) and CLI arguments. Each case ends as
- "ok": a finite (H, W, 3) image (CLI: exit 0 and the output written, no temporary left), or
- "clean error": a DermisError with a one-line message (CLI: exit 2, exactly one stderr line
  "dermis: error: ...", no output file, no temporary file), or
- "other": anything else (a traceback, NaN, a second stderr line, a file left behind) - a bug.

tests/test_fuzz.py runs a bounded number of cases in the normal suite; scripts/fuzz.py
(``make fuzz``) runs >= 10,000 and writes the counts to benchmarks/RESULTS.md.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import os
import struct
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_loaders import gltf_document, small_grid  # noqa: E402

import dermis  # noqa: E402
from dermis.errors import DermisError  # noqa: E402

OK, ERROR, OTHER = "ok", "clean error", "other"
SIZE = (16, 16)
TECHNIQUES = ("lambert", "tsd", "ssss", "preintegrated")
FAST = dict(samples=0, irradiance_size=64, shadow_size=128)


# ----------------------------------------------------------------------------- classification

class Outcome:
    def __init__(self, kind, detail=""):
        self.kind, self.detail = kind, detail

    def __repr__(self):
        return f"{self.kind}: {self.detail}"


def classify(fn) -> Outcome:
    """Run fn() (which renders and returns an image) and classify what happened."""
    try:
        img = fn()
    except DermisError as exc:
        msg = str(exc)
        if msg and "\n" not in msg and "Traceback" not in msg:
            return Outcome(ERROR, msg)
        return Outcome(OTHER, f"DermisError with a bad message: {msg!r}")
    except Exception as exc:  # noqa: BLE001 - anything else is what the fuzzer looks for
        return Outcome(OTHER, f"{type(exc).__name__}: {str(exc)[:300]}")
    if not isinstance(img, np.ndarray) or img.ndim != 3 or img.shape[2] != 3:
        return Outcome(OTHER, f"not an image: {type(img).__name__} {getattr(img, 'shape', '')}")
    if not np.all(np.isfinite(img)):
        return Outcome(OTHER, "non-finite image returned without an error")
    return Outcome(OK)


_RENDERER = None


def shared_renderer():
    """One GL context and Renderer for every in-process case (programs compile once)."""
    global _RENDERER
    if _RENDERER is None:
        from dermis.renderer import Renderer

        _RENDERER = Renderer(None, SIZE, **FAST)
    return _RENDERER


def render_loaded(path, technique=None):
    """load_scene + a 16x16 frame on the shared renderer."""
    scene = dermis.load_scene(path)
    r = shared_renderer()
    r.set_scene(scene)
    return r.render(technique)


def left_files(folder: Path, before: set) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p not in before)


def run_cli_inprocess(argv, folder: Path, expected_outputs) -> Outcome:
    """dermis.cli.main(argv) in this process, stderr captured; the CLI half of the rules."""
    from dermis.cli import main

    before = set(folder.rglob("*"))
    err, out = io.StringIO(), io.StringIO()
    code = None
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            main(argv)
    except SystemExit as exc:
        code = exc.code
    except BaseException as exc:  # noqa: BLE001
        return Outcome(OTHER, f"raised {type(exc).__name__}: {str(exc)[:300]}")
    lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
    new = left_files(folder, before)
    temps = [n for n in new if ".part" in n]
    if code == 0:
        missing = [p for p in expected_outputs if not Path(p).is_file()]
        if missing or temps or lines:
            return Outcome(OTHER, f"exit 0 but missing {missing}, temporaries {temps}, stderr {lines}")
        return Outcome(OK)
    if code == 2 and len(lines) == 1 and lines[0].startswith("dermis: error: "):
        if new:
            return Outcome(OTHER, f"failed but left {new}: {lines[0]}")
        return Outcome(ERROR, lines[0])
    return Outcome(OTHER, f"exit {code}, stderr {lines[:3]}")


# ----------------------------------------------------------------------------- values

FLOATS = st.one_of(
    st.sampled_from([0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-300, 1e-30, 1e30, 1e39, 1e300, -1e300, 3e38,
                     math.inf, -math.inf, math.nan, 89.999, 170.0, 180.0, 1e6, 65504.0, 1e-7]),
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.floats(-10, 10))
INTS = st.one_of(st.sampled_from([0, -1, 1, 2, 3, 4, 15, 16, 63, 64, 127, 128, 255, 256, 2**16, 2**31, 2**32,
                                  2**53, 10**9, -(2**31)]), st.integers(-1000, 1000))
TEXT = st.one_of(st.sampled_from(["", " ", "tsd", "lambert", "aces", "linear", "v-up", "v-down", "directional",
                                  "point", "spot", "sphere", "plane", "slab", "\x00", "é", "../x", "a" * 300]),
                 st.text(max_size=12))
JSON_SCALARS = st.one_of(st.none(), st.booleans(), INTS, FLOATS, TEXT)
JSON_VALUES = st.recursive(JSON_SCALARS, lambda c: st.one_of(st.lists(c, max_size=5),
                                                             st.dictionaries(TEXT, c, max_size=3)), max_leaves=8)


def vec(n=3):
    return st.lists(st.one_of(st.floats(-5, 5), FLOATS), min_size=n, max_size=n)


# ----------------------------------------------------------------------------- scene TOML


def toml_value(v) -> str:
    if v is None:  # TOML has no null: an empty inline table, a wrong type for every key
        return "{}"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v) if abs(v) < 2**63 else str(float(v))
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def toml_text(doc: dict) -> str:
    out = []
    for table, body in doc.items():
        if table == "lights":
            for light in body:
                out.append("[[lights]]")
                out += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in light.items()]
        else:
            out.append(f"[{table}]")
            out += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in body.items()]
    return "\n".join(out) + "\n"


# files a scene may name (made by prepare_folder); the odd ones test the OS-error class
PATH_CHOICES = ["tex.png", "tex16.png", "grey16.png", "tex.jpg", "env.exr", "env.hdr", "missing.png", "sub",
                "../outside.png", "/proc/self/mem", "/dev/zero", "a" * 300 + ".png", "grid.obj", "grid.glb",
                "bad.hdr", "nan.exr", "huge.exr", "bomb.png"]

_SCHEMA_VALUES = {
    "scene": {"name": TEXT, "mm_per_unit": FLOATS, "technique": st.sampled_from(TECHNIQUES + ("nope", ""))},
    "mesh": {"builtin": st.sampled_from(["sphere", "plane", "slab", "box_over_plane", "nope"]),
             "file": st.sampled_from(PATH_CHOICES), "uv_convention": TEXT},
    "material": {"albedo": st.sampled_from(PATH_CHOICES), "albedo_color": vec(), "normal_map": st.sampled_from(PATH_CHOICES),
                 "normal_strength": FLOATS, "specular_map": st.sampled_from(PATH_CHOICES), "roughness": FLOATS,
                 "roughness_map": st.sampled_from(PATH_CHOICES), "rho_s": FLOATS, "mix": FLOATS,
                 "pore_scale_mm": FLOATS, "pore_strength": FLOATS, "specular_map_bias": FLOATS,
                 "double_sided": st.booleans()},
    "lights": {"type": st.sampled_from(["directional", "point", "spot", "area"]), "color": vec(), "intensity": FLOATS,
               "direction": vec(), "position": vec(), "target": vec(), "spot_angle_deg": FLOATS,
               "spot_blend": FLOATS, "cast_shadows": st.booleans(), "shadow_softness": FLOATS, "shadow_bias": FLOATS},
    "camera": {"position": vec(), "target": vec(), "up": vec(), "fov_deg": FLOATS, "near": FLOATS, "far": FLOATS},
    "environment": {"color": vec(), "image": st.sampled_from(PATH_CHOICES), "intensity": FLOATS},
    "output": {"exposure": FLOATS, "tonemap": TEXT, "background": vec(), "bloom": FLOATS, "bloom_radius": FLOATS},
}


@st.composite
def scene_tomls(draw):
    """A scene document: a valid base (a built-in mesh, one light) with 0-4 keys changed, added
    (including unknown ones and wrong types) or removed."""
    doc = {"mesh": {"builtin": draw(st.sampled_from(["plane", "sphere", "slab"]))},
           "lights": [{"type": "directional", "direction": [0.3, -0.4, -1.0], "intensity": 3.0}]}
    for _ in range(draw(st.integers(0, 4))):
        table = draw(st.sampled_from(sorted(_SCHEMA_VALUES)))
        key = draw(st.sampled_from(sorted(_SCHEMA_VALUES[table])))
        value = draw(st.one_of(_SCHEMA_VALUES[table][key], JSON_SCALARS) if draw(st.integers(0, 5)) == 0
                     else _SCHEMA_VALUES[table][key])
        if table == "lights":
            lights = doc["lights"]
            if not lights or draw(st.booleans()):
                lights.append({})
            lights[-1][key] = value
        else:
            body = doc.setdefault(table, {})
            if table == "mesh" and key in ("file", "builtin"):
                body.pop("builtin", None)
            body[key] = value
    mode = draw(st.integers(0, 9))
    if mode == 0:
        doc.setdefault(draw(st.sampled_from(["material", "camera", "output", "nosuch"])), {})[draw(TEXT) or "k"] = draw(JSON_SCALARS)
    elif mode == 1:
        doc.pop("lights")
    text = toml_text(doc)
    if mode == 2:  # byte-level damage
        cut = draw(st.integers(0, len(text)))
        text = text[:cut] + draw(st.text(max_size=4)) + text[cut + draw(st.integers(0, 3)):]
    return text


def _png_chunk(tag: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + tag + payload + struct.pack(">I", zlib.crc32(tag + payload) & 0xFFFFFFFF)


def bomb_png(w=100000, h=100000) -> bytes:
    """A valid PNG header claiming w x h pixels with a tiny compressed body: refused before decoding."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    body = zlib.compress(b"\0" * 1024)
    return b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", body) + _png_chunk(b"IEND", b"")


def rgbe_bytes(rgb: np.ndarray, declared=None) -> bytes:
    """A Radiance .hdr written here (flat, uncompressed scanlines; Ward, Graphics Gems II), not by
    the reader's library: the reader's test then checks it against an independent writer."""
    rgb = np.asarray(rgb, np.float64)
    h, w = rgb.shape[:2]
    m = rgb.max(axis=2)
    e = np.where(m > 1e-32, np.floor(np.log2(np.maximum(m, 1e-38))) + 1, 0)
    scale = np.where(m > 1e-32, 256.0 / np.exp2(e), 0)
    mant = np.clip(np.floor(rgb * scale[..., None]), 0, 255).astype(np.uint8)
    ex = np.where(m > 1e-32, e + 128, 0).astype(np.uint8)
    pix = np.concatenate([mant, ex[..., None]], axis=2)
    dh, dw = declared or (h, w)
    head = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {dh} +X {dw}\n".encode()
    return head + pix.tobytes()


def write_exr(path, arr, half=False):
    from dermis.images import exr_writer

    with np.errstate(over="ignore"):  # half-float inputs past 65504 (inf in the file) are on purpose
        exr_writer(arr, half)(path)


def prepare_folder(d: Path):
    """The files PATH_CHOICES name, written once per folder."""
    from PIL import Image

    rng = np.random.default_rng(3)
    u8 = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    Image.fromarray(u8).save(d / "tex.png")
    Image.fromarray(u8).save(d / "tex.jpg", quality=80)
    import imagecodecs

    (d / "tex16.png").write_bytes(imagecodecs.png_encode(rng.integers(0, 65536, (8, 8, 3), dtype=np.uint16)))
    Image.fromarray(rng.integers(0, 65536, (8, 8), dtype=np.uint16)).save(d / "grey16.png")
    env = rng.uniform(0, 4, (8, 16, 3)).astype(np.float32)
    write_exr(d / "env.exr", env)
    (d / "env.hdr").write_bytes(rgbe_bytes(env))
    (d / "bad.hdr").write_bytes(rgbe_bytes(env, declared=(100000, 100000)))
    bad = env.copy()
    bad[0, 0, 0] = np.nan
    write_exr(d / "nan.exr", bad)
    write_exr(d / "huge.exr", np.full((4, 8, 3), 3e38, np.float32))
    (d / "bomb.png").write_bytes(bomb_png())
    (d / "sub").mkdir(exist_ok=True)
    (d.parent / "outside.png").write_bytes((d / "tex.png").read_bytes())
    pos, uv, idx = small_grid(3)
    (d / "grid.obj").write_text(obj_text(pos, uv, idx))
    from test_loaders import write_glb

    doc, binary = gltf_document(pos, uv, idx)
    write_glb(d / "grid.glb", doc, binary)


def obj_text(pos, uv, idx) -> str:
    lines = [f"v {x} {y} {z}" for x, y, z in pos] + [f"vt {u} {v}" for u, v in uv]
    lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in np.asarray(idx).reshape(-1, 3)]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- glTF / GLB


def _paths(obj, prefix=()):
    """Every JSON path of a document (to pick one to change)."""
    out = [prefix]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, prefix + (i,))
    return out


def _set(doc, path, value, delete=False):
    cur = doc
    for k in path[:-1]:
        cur = cur[k]
    if delete:
        if isinstance(cur, dict):
            cur.pop(path[-1], None)
        else:
            cur.pop(path[-1])
    else:
        cur[path[-1]] = value


GLTF_VALUES = st.one_of(JSON_SCALARS, st.sampled_from([-1, 0, 1, 2, 99, 2**31, 1e39, [], [1, 2, 3], [0] * 15,
                                                       [0] * 16, [0] * 17, {"index": 5}, "../x.bin",
                                                       "/proc/self/mem", "data:,", "data:application/octet-stream;base64,!!"]),
                        JSON_VALUES)


@st.composite
def gltf_cases(draw):
    """(container, doc, binary, GLB header patch) from a small valid textured grid, changed."""
    from test_loaders import png_bytes, texture_u8

    pos, uv, idx = small_grid(2)
    img = draw(st.sampled_from([None, ("view", png_bytes(texture_u8())), ("uri", "tex.png")]))
    normals = np.tile([[0.0, 0.0, 1.0]], (len(pos), 1)) if draw(st.booleans()) else None
    doc, binary = gltf_document(pos, uv, idx, normals=normals, image=img)
    if draw(st.booleans()):
        doc["nodes"][0].update(copy.deepcopy(draw(st.sampled_from([{"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]},
                                                     {"rotation": [0, 0, 0, 1], "scale": [1, -1, 1]},
                                                     {"children": [0]}, {"translation": [1e30, 0, 0]}]))))
    paths = [p for p in _paths(doc) if p]
    for _ in range(draw(st.integers(0, 3))):
        path = draw(st.sampled_from(paths))
        try:
            # values are copied: sampled constants must not be changed (or made cyclic) by later edits
            _set(doc, path, copy.deepcopy(draw(GLTF_VALUES)), delete=draw(st.integers(0, 4)) == 0)
        except (KeyError, IndexError, TypeError):
            pass
        paths = [p for p in _paths(doc) if p]
    binary = bytearray(binary)
    for _ in range(draw(st.integers(0, 2))):  # binary chunk damage
        if binary:
            i = draw(st.integers(0, len(binary) - 1))
            binary[i] = draw(st.integers(0, 255))
    if draw(st.integers(0, 5)) == 0:
        binary = binary[: draw(st.integers(0, len(binary)))]
    container = draw(st.sampled_from(["glb", "gltf"]))
    header = draw(st.sampled_from([None, None, None, 0, 12, 1 << 31])) if container == "glb" else None
    return container, doc, bytes(binary), header


def write_gltf_case(d: Path, case) -> Path:
    container, doc, binary, header = case
    if container == "gltf":
        doc = json.loads(json.dumps(doc, allow_nan=True))
        if doc.get("buffers") and isinstance(doc["buffers"], list) and isinstance(doc["buffers"][0], dict) \
                and "uri" not in doc["buffers"][0]:
            doc["buffers"][0]["uri"] = "grid.bin"
        (d / "grid.bin").write_bytes(binary)
        p = d / "case.gltf"
        p.write_text(json.dumps(doc, allow_nan=True))
        return p
    js = json.dumps(doc, allow_nan=True).encode()
    js += b" " * (-len(js) % 4)
    bn = binary + b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(bn), 0x004E4942) + bn
    total = 12 + len(body) if header is None else header
    p = d / "case.glb"
    p.write_bytes(b"glTF" + struct.pack("<II", 2, total) + body)
    return p


# ----------------------------------------------------------------------------- OBJ / MTL

OBJ_NUM = st.one_of(st.sampled_from(["0", "1", "-1", "0.5", "1e300", "nan", "inf", "-inf", "x", "1e-40", "500"]),
                    st.floats(-2, 2).map(lambda f: f"{f:.3f}"))
OBJ_INDEX = st.one_of(st.integers(-4, 12).map(str), st.sampled_from(["0", "x", "", "99999999999"]))


@st.composite
def obj_cases(draw):
    """(obj text, mtl text or None): a grid OBJ with lines added/changed and a material library."""
    pos, uv, idx = small_grid(2)
    lines = obj_text(pos, uv, idx).splitlines()
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(["v", "vt", "vn", "f", "mtllib", "usemtl", "junk", "drop"]))
        if kind == "v":
            line = "v " + " ".join(draw(st.lists(OBJ_NUM, min_size=2, max_size=4)))
        elif kind == "vt":
            line = "vt " + " ".join(draw(st.lists(OBJ_NUM, min_size=1, max_size=3)))
        elif kind == "vn":
            line = "vn " + " ".join(draw(st.lists(OBJ_NUM, min_size=3, max_size=3)))
        elif kind == "f":
            form = draw(st.sampled_from(["{a}", "{a}/{b}", "{a}/{b}/{c}", "{a}//{c}"]))
            line = "f " + " ".join(form.format(a=draw(OBJ_INDEX), b=draw(OBJ_INDEX), c=draw(OBJ_INDEX))
                                   for _ in range(draw(st.integers(1, 5))))
        elif kind == "mtllib":
            line = "mtllib " + draw(st.sampled_from(["m.mtl", "../m.mtl", "/etc/passwd", "missing.mtl", "sub", "a" * 300]))
        elif kind == "usemtl":
            line = "usemtl " + draw(st.sampled_from(["skin", "nope", ""]))
        elif kind == "drop":
            if lines:
                lines.pop(draw(st.integers(0, len(lines) - 1)))
            continue
        else:
            line = draw(st.text(max_size=10))
        lines.insert(draw(st.integers(0, len(lines))), line)
    mtl = None
    if draw(st.booleans()):
        lines.insert(0, "mtllib m.mtl")
        lines.insert(1, "usemtl skin")
        kd = " ".join(draw(st.lists(OBJ_NUM, min_size=3, max_size=3)))
        ref = draw(st.sampled_from(["tex.png", "tex16.png", "../outside.png", "/etc/passwd", "missing.png", "bomb.png",
                                    "sub", "tex.jpg", "-s 1 1 1 tex.png", None]))
        mtl = f"newmtl skin\nKd {kd}\n" + (f"map_Kd {ref}\n" if ref else "")
    return "\n".join(lines) + "\n", mtl


# ----------------------------------------------------------------------------- images


@st.composite
def image_cases(draw):
    """(file name, bytes, role): an image of some format and bit depth, maybe damaged, used as a
    scene's albedo, normal map, specular/roughness map or environment."""
    from PIL import Image

    h, w = draw(st.integers(1, 9)), draw(st.integers(1, 9))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    fmt = draw(st.sampled_from(["png8", "png16", "pngL16", "png1", "pngP", "pngLA", "jpg", "exr", "exr_half", "hdr",
                                "bomb", "hdr_bomb"]))
    buf = io.BytesIO()
    if fmt in ("png8", "pngP", "pngLA", "png1", "jpg"):
        mode = {"png8": "RGBA", "pngP": "P", "pngLA": "LA", "png1": "1", "jpg": "RGB"}[fmt]
        im = Image.fromarray(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)).convert(mode)
        im.save(buf, format="JPEG" if fmt == "jpg" else "PNG")
        name, data = ("img.jpg" if fmt == "jpg" else "img.png"), buf.getvalue()
    elif fmt == "png16":
        import imagecodecs

        name, data = "img.png", imagecodecs.png_encode(rng.integers(0, 65536, (h, w, 3), dtype=np.uint16))
    elif fmt == "pngL16":
        Image.fromarray(rng.integers(0, 65536, (h, w), dtype=np.uint16)).save(buf, format="PNG")
        name, data = "img.png", buf.getvalue()
    elif fmt in ("exr", "exr_half"):
        vals = draw(st.sampled_from([1.0, 1e4, 3e38, -1.0, math.nan, math.inf, 1e-40]))
        arr = rng.uniform(0, 1, (h, w, 3)).astype(np.float32)
        if draw(st.booleans()):
            arr[0, 0, 0] = vals
        with tempfile.TemporaryDirectory() as t:
            write_exr(Path(t) / "x.exr", arr, half=fmt == "exr_half")
            name, data = "img.exr", (Path(t) / "x.exr").read_bytes()
    elif fmt == "hdr":
        scale = draw(st.sampled_from([1.0, 1e-20, 1e30, 1e38]))
        name, data = "img.hdr", rgbe_bytes(rng.uniform(0, 2, (h, w, 3)) * scale)
    elif fmt == "bomb":
        name, data = "img.png", bomb_png(draw(st.integers(1, 200000)), draw(st.integers(1, 200000)))
    else:
        name, data = "img.hdr", rgbe_bytes(np.ones((h, w, 3)), declared=(draw(st.integers(-1, 10**6)),
                                                                       draw(st.integers(-1, 10**6))))
    if draw(st.integers(0, 3)) == 0:  # damage: truncate or overwrite bytes
        data = bytearray(data)
        if draw(st.booleans()):
            data = data[: draw(st.integers(0, len(data)))]
        elif data:
            for _ in range(draw(st.integers(1, 4))):
                data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        data = bytes(data)
    role = draw(st.sampled_from(["albedo", "normal_map", "specular_map", "roughness_map", "environment"]))
    return name, data, role


def image_scene(name, role) -> str:
    mat = "" if role == "environment" else f'\n[material]\n{role} = "{name}"\n'
    env = f'\n[environment]\nimage = "{name}"\n' if role == "environment" else ""
    return ('[mesh]\nbuiltin = "plane"\n\n[[lights]]\ntype = "directional"\ndirection = [0.3, -0.4, -1.0]\n'
            'intensity = 3.0\n' + mat + env)


# ----------------------------------------------------------------------------- API arguments

API_ANY = st.one_of(JSON_SCALARS, st.sampled_from([b"scene.toml", bytearray(b"x"), object(), [16, 16], (16, 16),
                                                    (16.0, 16.0), (0, 16), (16, 10**9), np.int64(16), ["tsd"]]))
OPTION_VALUES = st.one_of(st.sampled_from([0, -1, 1, 63, 64, 128, 16, 10**9, True, None, 64.0, "64", np.int32(64)]),
                          INTS)

SCENE_ATTRS = {  # attribute path on a Scene -> values to set through the API
    ("lights", 0, "intensity"): FLOATS, ("lights", 0, "color"): vec(), ("lights", 0, "direction"): vec(),
    ("lights", 0, "kind"): TEXT, ("lights", 0, "position"): vec(), ("lights", 0, "spot_angle_deg"): FLOATS,
    ("camera", "position"): vec(), ("camera", "target"): vec(), ("camera", "up"): vec(),
    ("camera", "near"): st.one_of(st.none(), FLOATS), ("camera", "far"): st.one_of(st.none(), FLOATS),
    ("camera", "fov_deg"): FLOATS, ("mm_per_unit",): FLOATS, ("environment", "intensity"): FLOATS,
    ("environment", "color"): vec(), ("material", "roughness"): FLOATS, ("material", "albedo_color"): vec(),
    ("material", "mix"): FLOATS, ("material", "rho_s"): FLOATS, ("output", "exposure"): FLOATS,
    ("output", "bloom"): FLOATS, ("mesh", "positions"): st.sampled_from(["zero", "huge", "nan", "line"]),
}


@st.composite
def api_cases(draw):
    kind = draw(st.sampled_from(["load_scene", "render", "render", "scene"]))
    if kind == "load_scene":
        return kind, draw(API_ANY), draw(st.one_of(st.none(), TEXT, API_ANY))
    if kind == "render":
        opts = {}
        for k in draw(st.lists(st.sampled_from(["samples", "shadow_size", "irradiance_size", "device", "bogus"]),
                               max_size=2, unique=True)):
            opts[k] = draw(OPTION_VALUES)
        technique = draw(st.one_of(st.none(), st.sampled_from(TECHNIQUES), API_ANY))
        size = draw(st.one_of(st.just(SIZE), API_ANY))
        return kind, technique, size, opts
    changes = [(p, draw(SCENE_ATTRS[p])) for p in draw(st.lists(st.sampled_from(sorted(SCENE_ATTRS, key=str)),
                                                              min_size=1, max_size=3, unique=True))]
    return kind, changes, draw(st.sampled_from(TECHNIQUES))


def base_scene():
    from dermis.scene.builtin import builtin_mesh, frame_scene
    from dermis.scene.model import Scene

    mesh, _, mm = builtin_mesh("plane")
    sc = Scene(mesh=mesh, mm_per_unit=mm, source="api-scene")
    frame_scene(sc)
    return sc


def apply_changes(scene, changes):
    for path, value in changes:
        if path == ("mesh", "positions"):
            p = scene.mesh.positions.copy()
            if value == "zero":
                p[:] = p[0]
            elif value == "huge":
                p *= np.float32(1e30)
            elif value == "nan":
                p[0, 0] = np.nan
            else:
                p[:, 1:] = 0
            scene.mesh.positions = p
            continue
        obj = scene
        for k in path[:-1]:
            obj = obj[k] if isinstance(k, int) else getattr(obj, k)
        setattr(obj, path[-1], tuple(value) if isinstance(value, list) else value)


def run_api_case(case) -> Outcome:
    kind = case[0]
    if kind == "load_scene":
        _, arg, technique = case
        return classify(lambda: (dermis.load_scene(arg, technique=technique), np.zeros((1, 1, 3), np.float32))[1])
    if kind == "render":
        _, technique, size, opts = case
        r = shared_renderer()
        return classify(lambda: dermis.render(base_scene(), technique, size, ctx=r.ctx, **{**FAST, **opts}))
    _, changes, technique = case

    def go():
        sc = base_scene()
        apply_changes(sc, changes)
        r = shared_renderer()
        r.set_scene(sc)
        return r.render(technique)

    return classify(go)


# ----------------------------------------------------------------------------- CLI arguments

CLI_OPTIONS = {
    "--technique": st.sampled_from(list(TECHNIQUES) + ["nope", "", "TSD"]),
    "--size": st.sampled_from(["16x16", "0x16", "16x", "x", "16x16x16", "-16x16", "100000x16", "1e3x16", "16X16", ""]),
    "--exposure": st.sampled_from(["0", "1", "-3", "1e308", "-1e308", "nan", "inf", "-inf", "64", "65", "x", ""]),
    "--tonemap": st.sampled_from(["aces", "linear", "reinhard", ""]),
    "--samples": st.sampled_from(["0", "1", "4", "-1", "65", "x", "10000000000000000000000"]),
    "--irradiance-size": st.sampled_from(["64", "63", "0", "-1", "1000000000", "x"]),
    "--shadow-size": st.sampled_from(["128", "127", "0", "-1", "1000000000", "x"]),
    "--out": st.sampled_from(["OUT/a.png", "", "OUT", "/proc/a.png", "/proc/self/mem", "OUT/missing/a.png",
                              "OUT/fifo", "OUT/link.png", "OUT/dangling.png", "/dev/null", "OUT/" + "a" * 300 + ".png"]),
    "--exr": st.sampled_from(["OUT/a.exr", "", "OUT", "/proc/a.exr", "/dev/null", "OUT/a.png", "OUT/fifo"]),
    "--stats": st.sampled_from(["OUT/s.json", "", "/proc/s.json", "OUT/sub"]),
    "--debug-buffers": st.sampled_from(["OUT/dbg", "", "/proc/dbg", "OUT/a.png", "OUT/missing/dbg"]),
    "--device": st.sampled_from(["0", "-1", "99", "x"]),
}
CLI_SCENES = ["SCENE", "OUT/nope.toml", "OUT", "/dev/zero", "/proc/self/mem", "OUT/" + "b" * 300 + ".toml",
              "OUT/grid.obj", "OUT/grid.glb", "OUT/s.txt"]


@st.composite
def cli_cases(draw):
    argv = ["render", draw(st.sampled_from(CLI_SCENES))]
    chosen = draw(st.lists(st.sampled_from(sorted(CLI_OPTIONS)), max_size=4, unique=True))
    opts = {"--size": "16x16", "--irradiance-size": "64", "--shadow-size": "128", "--samples": "0",
            "--technique": "lambert", "--out": "OUT/a.png"}
    for k in chosen:
        opts[k] = draw(CLI_OPTIONS[k])
    for k, v in opts.items():
        argv += [k, v]
    return argv


def prepare_cli_folder(d: Path):
    """The scene and the special files the CLI cases name (OUT/...)."""
    (d / "s.toml").write_text('[mesh]\nbuiltin = "plane"\n\n[[lights]]\ndirection = [0.3, -0.4, -1.0]\n')
    (d / "s.txt").write_text("not a scene")
    (d / "sub").mkdir(exist_ok=True)
    if not (d / "fifo").exists():
        os.mkfifo(d / "fifo")
    (d / "target.png").write_bytes(b"old")
    if not (d / "link.png").is_symlink():
        (d / "link.png").symlink_to(d / "target.png")
        (d / "dangling.png").symlink_to(d / "nowhere.png")
    pos, uv, idx = small_grid(3)
    (d / "grid.obj").write_text(obj_text(pos, uv, idx))
    from test_loaders import write_glb

    doc, binary = gltf_document(pos, uv, idx)
    write_glb(d / "grid.glb", doc, binary)


def run_cli_case(argv, d: Path) -> Outcome:
    argv = [a.replace("OUT", str(d)).replace("SCENE", str(d / "s.toml")) for a in argv]
    outs = []
    for opt in ("--out", "--exr", "--stats"):
        if opt in argv:
            outs.append(argv[argv.index(opt) + 1])
    if "--debug-buffers" in argv:
        pass  # a folder: checked as "no new files on failure"
    fixed = set(d.rglob("*"))
    outcome = run_cli_inprocess(argv, d, outs)
    # outputs of a successful case are removed so that the next case starts from the same folder
    for p in set(d.rglob("*")) - fixed:
        if p.is_dir() and not p.is_symlink():
            import shutil

            shutil.rmtree(p, ignore_errors=True)
        else:
            try:
                p.unlink()
            except OSError:
                pass
    if (d / "target.png").read_bytes() != b"old" and outcome.kind == OK:
        (d / "target.png").write_bytes(b"old")
    return outcome
