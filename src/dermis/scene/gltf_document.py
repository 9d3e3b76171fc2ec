"""A glTF 2.0 document checked up front, in one place, before the loader reads anything from it.

The loader (dermis.scene.loaders.GltfAsset) then indexes lists and reads numbers without guarding
each access: every index it follows is in range, every number it uses has the type and length the
glTF 2.0 specification (Khronos, sections 3.5-3.9, 5.x) gives it. Only what dermis reads is
checked; unknown properties and extensions pass through. Container: the GLB header and chunks are
parsed here too (spec section 4.4), so a zero or lying length is a clear error.

Limits (refused with a clear error before any array is allocated): MAX_VERTICES vertices and
MAX_TRIANGLES triangles over all mesh instances; a mesh over PROGRESS_VERTICES shows progress.
"""

from __future__ import annotations

import json
import math
import struct

from dermis.errors import DermisError

MAX_VERTICES = 12_000_000  # ~ 0.6 GB of float32 vertex data at dermis's 12 floats + loader copies
MAX_TRIANGLES = 12_000_000
PROGRESS_VERTICES = 500_000

COMPONENT_TYPES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_ATTRIBUTE_RULES = {  # semantic -> (types, component types) allowed (spec 3.7.2.1)
    "POSITION": (("VEC3",), (5126,)),
    "NORMAL": (("VEC3",), (5126,)),
    "TANGENT": (("VEC4",), (5126,)),
    "TEXCOORD_n": (("VEC2",), (5126, 5121, 5123)),
    "COLOR_0": (("VEC3", "VEC4"), (5126, 5121, 5123)),
}
WRAP_MODES = {33071: "clamp", 33648: "mirror", 10497: "repeat"}  # sampler.wrapS/T (spec 5.26)
MAG_FILTERS = (9728, 9729)  # NEAREST, LINEAR
MIN_FILTERS = (9728, 9729, 9984, 9985, 9986, 9987)  # and the four *_MIPMAP_* ones
SUPPORTED_EXTENSIONS = ("KHR_texture_transform",)
_GLB_JSON, _GLB_BIN = 0x4E4F534A, 0x004E4942


def parse_glb(raw: bytes, source) -> tuple[str, bytes | None]:
    """(JSON text, BIN chunk or None) of a binary glTF."""
    if len(raw) < 20 or raw[:4] != b"glTF":
        raise DermisError(f"{source}: not a binary glTF (bad magic or shorter than its header)")
    version, length = struct.unpack_from("<II", raw, 4)
    if version != 2:
        raise DermisError(f"{source}: binary glTF version {version} is not supported (glTF 2.0 only)")
    if length != len(raw):
        raise DermisError(f"{source}: binary glTF header says {length} bytes, the file has {len(raw)} (truncated or corrupt)")
    chunks, pos = [], 12
    while pos < length:
        if pos + 8 > length:
            raise DermisError(f"{source}: binary glTF chunk header runs past the end of the file")
        clen, ctype = struct.unpack_from("<II", raw, pos)
        if pos + 8 + clen > length:
            raise DermisError(f"{source}: binary glTF chunk of {clen} bytes runs past the end of the file")
        chunks.append((ctype, raw[pos + 8: pos + 8 + clen]))
        pos += 8 + clen
    if not chunks or chunks[0][0] != _GLB_JSON:
        raise DermisError(f"{source}: binary glTF has no JSON chunk first")
    try:
        text = chunks[0][1].decode("utf-8")
    except UnicodeDecodeError:
        raise DermisError(f"{source}: binary glTF JSON chunk is not UTF-8") from None
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _GLB_BIN else None
    return text, binary


def parse_json(text: str, source) -> dict:
    try:
        doc = json.loads(text, parse_constant=lambda c: float("nan"))
    except (ValueError, RecursionError) as exc:
        raise DermisError(f"{source}: cannot parse glTF JSON ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    if not isinstance(doc, dict):
        raise DermisError(f"{source}: glTF JSON must be an object, got {type(doc).__name__}")
    return doc


class _Checker:
    def __init__(self, doc: dict, source):
        self.doc, self.source = doc, source

    def fail(self, where, problem):
        raise DermisError(f"{self.source}: {where} {problem}")

    def array(self, key) -> list:
        v = self.doc.get(key, [])
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            self.fail(f"'{key}'", "must be an array of objects")
        return v

    def index(self, value, key, where, required=False):
        if value is None:
            if required:
                self.fail(where, f"needs an index into '{key}'")
            return None
        n = len(self.doc.get(key, []))
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n:
            self.fail(where, f"index {value!r} is out of range ('{key}' has {n})")
        return value

    def integer(self, value, where, lo=0, hi=2**53):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            self.fail(where, f"must be an integer in [{lo}, {hi}], got {value!r}")
        return value

    def numbers(self, value, where, n, lo=-math.inf, hi=math.inf):
        ok = isinstance(value, list) and len(value) == n and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and lo <= x <= hi for x in value)
        if not ok:
            rng = f" in [{lo:g}, {hi:g}]" if math.isfinite(lo) else ""
            self.fail(where, f"must be {n} finite numbers{rng}, got {str(value)[:60]}")
        return value


def validate_document(doc: dict, source, binary_length: int | None) -> None:
    """Check every part of a glTF document that dermis follows; raises DermisError naming it."""
    c = _Checker(doc, source)
    asset = doc.get("asset")
    if not isinstance(asset, dict) or not str(asset.get("version", "")).startswith("2."):
        c.fail("'asset'", "must give version 2.x (dermis reads glTF 2.0)")
    for key in ("scenes", "nodes", "meshes", "accessors", "bufferViews", "buffers", "images", "textures", "materials"):
        c.array(key)
    d = doc
    for i, b in enumerate(d.get("buffers", [])):
        w = f"buffers[{i}]"
        c.integer(b.get("byteLength"), f"{w} byteLength", 0)
        if "uri" in b and not isinstance(b["uri"], str):
            c.fail(f"{w} uri", "must be a string")
        if "uri" not in b and i == 0 and binary_length is None:
            c.fail(w, "has no uri and the file has no binary chunk")
        if "uri" not in b and i > 0:
            c.fail(w, "has no uri (only buffer 0 may use the binary chunk)")
    for i, v in enumerate(d.get("bufferViews", [])):
        w = f"bufferViews[{i}]"
        c.index(v.get("buffer"), "buffers", f"{w} buffer", required=True)
        c.integer(v.get("byteLength"), f"{w} byteLength", 1)
        c.integer(v.get("byteOffset", 0), f"{w} byteOffset", 0)
        if v.get("byteStride") is not None:
            s = c.integer(v["byteStride"], f"{w} byteStride", 4, 252)
            if s % 4:
                c.fail(f"{w} byteStride", f"must be a multiple of 4, got {s}")
    for i, a in enumerate(d.get("accessors", [])):
        w = f"accessors[{i}]"
        if not isinstance(a.get("componentType"), int) or a.get("componentType") not in COMPONENT_TYPES:
            c.fail(f"{w} componentType", f"must be one of {sorted(COMPONENT_TYPES)}, got {a.get('componentType')!r}")
        if not isinstance(a.get("type"), str) or a.get("type") not in TYPE_SIZES:
            c.fail(f"{w} type", f"must be one of {', '.join(TYPE_SIZES)}, got {a.get('type')!r}")
        c.integer(a.get("count"), f"{w} count", 1, MAX_VERTICES * 3)
        c.index(a.get("bufferView"), "bufferViews", f"{w} bufferView")
        c.integer(a.get("byteOffset", 0), f"{w} byteOffset", 0)
        if not isinstance(a.get("normalized", False), bool):
            c.fail(f"{w} normalized", "must be true or false")
        if a.get("sparse") is not None:
            _sparse(c, a, w)
    for i, im in enumerate(d.get("images", [])):
        w = f"images[{i}]"
        c.index(im.get("bufferView"), "bufferViews", f"{w} bufferView")
        if "uri" in im and not isinstance(im["uri"], str):
            c.fail(f"{w} uri", "must be a string")
    req = d.get("extensionsRequired", [])
    if not isinstance(req, list) or not all(isinstance(x, str) for x in req):
        c.fail("'extensionsRequired'", "must be an array of strings")
    for ext in req:
        if ext not in SUPPORTED_EXTENSIONS:
            c.fail("'extensionsRequired'", f"names {ext}, a glTF extension dermis does not support")
    for i, sm in enumerate(c.array("samplers")):
        w = f"samplers[{i}]"
        for key, allowed in (("wrapS", WRAP_MODES), ("wrapT", WRAP_MODES), ("magFilter", MAG_FILTERS),
                             ("minFilter", MIN_FILTERS)):
            if key in sm and (isinstance(sm[key], bool) or sm[key] not in allowed):
                c.fail(f"{w} {key}", f"must be one of {', '.join(map(str, allowed))}, got {sm[key]!r}")
    for i, t in enumerate(d.get("textures", [])):
        c.index(t.get("source"), "images", f"textures[{i}] source")
        c.index(t.get("sampler"), "samplers", f"textures[{i}] sampler")
    for i, m in enumerate(d.get("materials", [])):
        w = f"materials[{i}]"
        pbr = m.get("pbrMetallicRoughness")
        if pbr is not None:
            if not isinstance(pbr, dict):
                c.fail(f"{w} pbrMetallicRoughness", "must be an object")
            if "baseColorFactor" in pbr:
                c.numbers(pbr["baseColorFactor"], f"{w} baseColorFactor", 4, 0.0, 1.0)
            _texture_ref(c, pbr.get("baseColorTexture"), f"{w} baseColorTexture")
            _texture_ref(c, pbr.get("metallicRoughnessTexture"), f"{w} metallicRoughnessTexture")
            for key in ("metallicFactor", "roughnessFactor"):
                if key in pbr:
                    c.numbers([pbr[key]], f"{w} {key}", 1, 0.0, 1.0)
        for key in ("normalTexture", "occlusionTexture", "emissiveTexture"):
            _texture_ref(c, m.get(key), f"{w} {key}")
        if "scale" in (m.get("normalTexture") or {}):
            c.numbers([m["normalTexture"]["scale"]], f"{w} normalTexture scale", 1)
        if "strength" in (m.get("occlusionTexture") or {}):
            c.numbers([m["occlusionTexture"]["strength"]], f"{w} occlusionTexture strength", 1, 0.0, 1.0)
        if "emissiveFactor" in m:
            c.numbers(m["emissiveFactor"], f"{w} emissiveFactor", 3, 0.0, 1.0)
        if m.get("alphaMode", "OPAQUE") not in ("OPAQUE", "MASK", "BLEND"):
            c.fail(f"{w} alphaMode", f"must be OPAQUE, MASK or BLEND, got {m['alphaMode']!r}")
        if "alphaCutoff" in m:
            c.numbers([m["alphaCutoff"]], f"{w} alphaCutoff", 1, 0.0)
        if not isinstance(m.get("doubleSided", False), bool):
            c.fail(f"{w} doubleSided", f"must be true or false, got {m['doubleSided']!r}")
        if "name" in m and not isinstance(m["name"], str):
            c.fail(f"{w} name", "must be a string")
    nodes = d.get("nodes", [])
    for i, n in enumerate(nodes):
        w = f"nodes[{i}]"
        ch = n.get("children", [])
        if not isinstance(ch, list):
            c.fail(f"{w} children", "must be an array of node indices")
        for k in ch:
            c.index(k, "nodes", f"{w} children")
        c.index(n.get("mesh"), "meshes", f"{w} mesh")
        if "matrix" in n:
            c.numbers(n["matrix"], f"{w} matrix", 16)
        for key, size in (("translation", 3), ("rotation", 4), ("scale", 3)):
            if key in n:
                c.numbers(n[key], f"{w} {key}", size)
    scenes = d.get("scenes", [])
    if "scene" in d:
        c.index(d["scene"], "scenes", "'scene'")
    for i, s in enumerate(scenes):
        ns = s.get("nodes", [])
        if not isinstance(ns, list):
            c.fail(f"scenes[{i}] nodes", "must be an array of node indices")
        for k in ns:
            c.index(k, "nodes", f"scenes[{i}] nodes")
    accessors = d.get("accessors", [])
    for i, m in enumerate(d.get("meshes", [])):
        prims = m.get("primitives")
        if not isinstance(prims, list) or not prims or not all(isinstance(p, dict) for p in prims):
            c.fail(f"meshes[{i}] primitives", "must be a non-empty array of objects")
        for j, p in enumerate(prims):
            w = f"meshes[{i}] primitives[{j}]"
            mode = p.get("mode", 4)
            c.integer(mode, f"{w} mode", 0, 6)
            c.index(p.get("material"), "materials", f"{w} material")
            at = p.get("attributes")
            if not isinstance(at, dict):
                c.fail(f"{w} attributes", "must be an object")
            for sem, idx in at.items():
                c.index(idx, "accessors", f"{w} attribute {sem}", required=True)
            if mode != 4 or "POSITION" not in at:
                continue
            count = accessors[at["POSITION"]]["count"]
            for sem in at:
                rule = "TEXCOORD_n" if sem.startswith("TEXCOORD_") else sem
                if rule not in _ATTRIBUTE_RULES:
                    continue
                types, comps = _ATTRIBUTE_RULES[rule]
                a = accessors[at[sem]]
                if a["type"] not in types or a["componentType"] not in comps:
                    c.fail(f"{w} attribute {sem}", f"has type {a['type']}/{a['componentType']}; glTF 2.0 allows "
                           f"{'/'.join(types)} of {', '.join(map(str, comps))}")
                if a["count"] != count:
                    c.fail(f"{w} attribute {sem}", f"has {a['count']} elements but POSITION has {count}")
            mat = d["materials"][p["material"]] if p.get("material") is not None else {}
            for where, ref in material_maps(mat):
                ts = f"TEXCOORD_{texcoord_set(ref)}"
                if ts not in at:
                    c.fail(w, f"has no {ts}, which its material's {where} samples through")
            if p.get("indices") is not None:
                a = accessors[c.index(p["indices"], "accessors", f"{w} indices")]
                if a["type"] != "SCALAR" or a["componentType"] not in (5121, 5123, 5125):
                    c.fail(f"{w} indices", "must be a SCALAR accessor of unsigned integers")
    _check_totals(c, d)


def material_maps(mat: dict) -> list:
    """(name, textureInfo) of the maps a (checked) material samples."""
    pbr = mat.get("pbrMetallicRoughness") or {}
    refs = [("baseColorTexture", pbr.get("baseColorTexture")), ("metallicRoughnessTexture", pbr.get("metallicRoughnessTexture"))]
    refs += [(k, mat.get(k)) for k in ("normalTexture", "occlusionTexture", "emissiveTexture")]
    return [(k, r) for k, r in refs if r is not None]


def texture_transform(ref: dict) -> dict | None:
    """A (checked) textureInfo's KHR_texture_transform, or None."""
    return (ref.get("extensions") or {}).get("KHR_texture_transform")


def texcoord_set(ref: dict) -> int:
    """The TEXCOORD_n set a (checked) textureInfo samples through (KHR_texture_transform's texCoord
    overrides the textureInfo's, KHR_texture_transform README)."""
    tt = texture_transform(ref) or {}
    return int(tt.get("texCoord", ref.get("texCoord", 0)))


def _texture_ref(c: _Checker, ref, where):
    if ref is None:
        return
    if not isinstance(ref, dict):
        c.fail(where, "must be an object with an index")
    c.index(ref.get("index"), "textures", f"{where} index", required=True)
    c.integer(ref.get("texCoord", 0), f"{where} texCoord", 0, 31)
    ext = ref.get("extensions", {})
    if not isinstance(ext, dict):
        c.fail(f"{where} extensions", "must be an object")
    tt = ext.get("KHR_texture_transform")
    if tt is not None:
        w = f"{where} KHR_texture_transform"
        if not isinstance(tt, dict):
            c.fail(w, "must be an object")
        c.numbers(tt.get("offset", [0, 0]), f"{w} offset", 2)
        c.numbers([tt.get("rotation", 0)], f"{w} rotation", 1)
        c.numbers(tt.get("scale", [1, 1]), f"{w} scale", 2)
        c.integer(tt.get("texCoord", 0), f"{w} texCoord", 0, 31)
    if c.doc["textures"][ref["index"]].get("source") is None:
        c.fail(where, "names a texture without an image source")


def _sparse(c: _Checker, a: dict, w: str):
    """glTF 2.0 3.6.2.3: ``count`` indices (unsigned, strictly increasing, checked on read) into the
    accessor and as many replacement values, each in a bufferView."""
    sp = a["sparse"]
    if not isinstance(sp, dict) or not isinstance(sp.get("indices"), dict) or not isinstance(sp.get("values"), dict):
        c.fail(f"{w} sparse", "must be an object with indices and values")
    c.integer(sp.get("count"), f"{w} sparse count", 1, a["count"])
    for part in ("indices", "values"):
        c.index(sp[part].get("bufferView"), "bufferViews", f"{w} sparse {part} bufferView", required=True)
        c.integer(sp[part].get("byteOffset", 0), f"{w} sparse {part} byteOffset", 0)
    if sp["indices"].get("componentType") not in (5121, 5123, 5125):
        c.fail(f"{w} sparse indices componentType", f"must be 5121, 5123 or 5125, got {sp['indices'].get('componentType')!r}")


def _check_totals(c: _Checker, d: dict):
    """Vertices and triangles over every mesh instance (a mesh used by k nodes counts k times)."""
    meshes, accessors = d.get("meshes", []), d.get("accessors", [])
    uses = [0] * len(meshes)
    users = [n.get("mesh") for n in d.get("nodes", []) if n.get("mesh") is not None]
    for mi in users or range(len(meshes)):
        uses[mi] += 1
    verts = tris = 0
    for mi, m in enumerate(meshes):
        for p in m["primitives"]:
            if p.get("mode", 4) != 4 or "POSITION" not in p["attributes"]:
                continue
            n = accessors[p["attributes"]["POSITION"]]["count"]
            k = accessors[p["indices"]]["count"] if p.get("indices") is not None else n
            verts += n * uses[mi]
            tris += k // 3 * uses[mi]
    if verts > MAX_VERTICES or tris > MAX_TRIANGLES:
        c.fail("meshes", f"have {verts} vertices and {tris} triangles over all instances, over dermis's limit of "
               f"{MAX_VERTICES} vertices / {MAX_TRIANGLES} triangles (decimate the mesh)")
