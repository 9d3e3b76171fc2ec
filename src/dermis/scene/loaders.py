"""Mesh and material loaders: glTF 2.0 (.glb/.gltf, through pygltflib) and OBJ + MTL (through trimesh).

Safety: every external URI (buffers, images, MTL maps) is resolved inside the asset's own folder;
a URI that escapes it (``../``, absolute paths, other schemes) is refused. Images are size-checked
from their header before decoding (dermis.images).

UV convention: glTF stores v = 0 at the TOP of the image, OBJ at the bottom. dermis uses v = 0 at the
bottom (OpenGL). ``uv_convention`` says what the FILE uses: "v-down" (glTF spec) flips v on load,
"v-up" keeps it (OBJ, and glTF files written with OpenGL-style UVs such as the Lee Perry-Smith head).
"""

from __future__ import annotations

import base64
import math
import json
import sys
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from dermis.errors import DermisError
from dermis.fileio import os_error_text, read_bytes, regular_file
from dermis.images import MAX_IMAGE_PIXELS, as_rgb, as_rgba, read_image
from dermis.scene import gltf_document
from dermis.scene.gltf_document import MAX_TRIANGLES, MAX_VERTICES, PROGRESS_VERTICES
from dermis.scene.model import MetallicRoughnessMaterial, Mesh, Surface, Texture
from dermis.scene.tangents import generate_tangents

UV_CONVENTIONS = ("v-up", "v-down")
# UVs far outside the unit square: a texture repeated thousands of times across a triangle costs
# the rasteriser (and tsd's texture space) without bound; UDIM layouts stay well inside this
UV_LIMIT = 64.0


def resolve_inside(folder: Path, uri: str, what: str, source) -> Path:
    """Resolve a relative URI inside ``folder``; refuse anything that escapes it."""
    if "://" in uri or uri.startswith("/") or uri.startswith("\\") or (len(uri) > 1 and uri[1] == ":"):
        raise DermisError(f"{source}: {what} URI '{uri}' is not a relative path inside the asset folder; refused")
    try:
        folder = folder.resolve()
        target = (folder / unquote(uri)).resolve()
    except (OSError, RuntimeError, ValueError) as exc:
        raise DermisError(f"{source}: {what} URI '{uri[:80]}' cannot be resolved ({type(exc).__name__})") from None
    try:
        target.relative_to(folder)
    except ValueError:
        raise DermisError(f"{source}: {what} URI '{uri}' points outside the asset folder {folder}; refused") from None
    try:
        regular_file(target, what)
    except DermisError as exc:
        raise DermisError(f"{source}: {what} '{uri[:80]}': {str(exc).split(': ', 1)[-1]}") from None
    return target


def _data_uri(uri: str, source="glTF") -> bytes | None:
    if not uri.startswith("data:"):
        return None
    try:
        head, payload = uri.split(",", 1)
        return base64.b64decode(payload, validate=True) if ";base64" in head else unquote(payload).encode()
    except Exception:
        raise DermisError(f"{source}: malformed data: URI") from None


def finish_mesh(positions, normals, uvs, indices, source: str, uv_convention: str, tangents=None, uvs1=None) -> Mesh:
    """A checked Mesh from arrays in the file's convention; ``uvs1``: a second UV set (TEXCOORD_1)."""
    from dermis.validation import check_coordinates, max_abs

    check_coordinates(positions, source)  # before the cast: an OBJ's 1e300 is out of range, not "infinite"
    positions = np.ascontiguousarray(positions, np.float32)
    indices = np.ascontiguousarray(indices, np.int64).reshape(-1, 3)
    if uvs is None and len(indices) and indices.min() >= 0 and indices.max() < len(positions) \
            and np.all(np.isfinite(positions)):
        # no UVs: an xatlas layout (unique, so texture-space diffusion can use it); vertices split
        # along its seams keep the smooth normals computed before the split
        from dermis.geometry.atlas import generate_atlas

        if normals is None:
            normals = vertex_normals(positions, indices)
        atlas = generate_atlas(positions, indices)
        positions, normals = positions[atlas.vmapping], np.asarray(normals)[atlas.vmapping]
        if uvs1 is not None:  # in the file's convention still: flipped below like the file's
            uvs1 = np.asarray(uvs1)[atlas.vmapping]
            uvs1 = np.c_[uvs1[:, 0], 1.0 - uvs1[:, 1]] if uv_convention == "v-down" else uvs1
        indices, uvs, tangents, uv_convention = atlas.indices.astype(np.int64), atlas.uvs, None, "v-up"
    if uvs is None:
        raise DermisError(f"{source}: mesh has no texture coordinates (UVs) and no valid triangles to generate them from")
    # the span on the file's own numbers (before the float32 cast, which makes 1e300 "infinite")
    span = max(max_abs(uvs), 0.0 if uvs1 is None else max_abs(uvs1))
    if math.isfinite(span) and span > UV_LIMIT:
        raise DermisError(f"{source}: texture coordinates reach {span:g}; dermis needs a UV layout within "
                          f"[-{UV_LIMIT:g}, {UV_LIMIT:g}] (the unit square, or UDIM tiles)")
    uvs = np.ascontiguousarray(uvs, np.float32).copy()
    if uvs1 is not None:
        uvs1 = np.ascontiguousarray(uvs1, np.float32).copy()
        if len(uvs1) != len(positions):
            raise DermisError(f"{source}: mesh has {len(uvs1)} TEXCOORD_1 UVs for {len(positions)} vertices")
    for name, a in (("positions", positions), ("uvs", uvs), ("TEXCOORD_1 uvs", uvs1)):
        if a is not None and not np.all(np.isfinite(a)):
            raise DermisError(f"{source}: mesh {name} contain NaN or infinite values")
    if len(indices) == 0:
        raise DermisError(f"{source}: mesh has no triangles")
    if len(positions) > MAX_VERTICES or len(indices) > MAX_TRIANGLES:
        raise DermisError(f"{source}: mesh has {len(positions)} vertices and {len(indices)} triangles, over dermis's "
                          f"limit of {MAX_VERTICES} / {MAX_TRIANGLES} (decimate the mesh)")
    if indices.min() < 0 or indices.max() >= len(positions):
        raise DermisError(f"{source}: triangle indices out of range")
    if len(uvs) != len(positions):
        raise DermisError(f"{source}: mesh has {len(uvs)} UVs for {len(positions)} vertices")
    if uv_convention == "v-down":
        uvs[:, 1] = 1.0 - uvs[:, 1]
        if uvs1 is not None:
            uvs1[:, 1] = 1.0 - uvs1[:, 1]
    elif uv_convention != "v-up":
        raise DermisError(f"{source}: uv_convention must be one of {UV_CONVENTIONS}, got '{uv_convention}'")
    if normals is None:
        normals = vertex_normals(positions, indices)
    normals = np.asarray(normals, np.float32)
    if not np.all(np.isfinite(normals)):
        raise DermisError(f"{source}: mesh normals contain NaN or infinite values")
    if len(normals) != len(positions):
        raise DermisError(f"{source}: mesh has {len(normals)} normals for {len(positions)} vertices")
    progress = _Progress(source, len(positions))
    normals = _within_norm_range(normals)
    nl = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(nl > 1e-12, normals / np.maximum(nl, 1e-12), vertex_normals(positions, indices)).astype(np.float32)
    # a vertex of zero-area triangles only has no normal: any unit vector (its triangles cover no
    # pixel on screen, but they do in texture space, where normalize(0) would be NaN)
    normals[np.linalg.norm(normals, axis=1) < 0.5] = (0.0, 0.0, 1.0)
    progress.step("normals")
    indices = indices.astype(np.uint32)
    if tangents is None or uv_convention == "v-down":
        # Provided tangents follow the file's v direction; regenerate after a flip.
        tangents = generate_tangents(positions, normals, uvs, indices)
    elif len(tangents) != len(positions) or not np.all(np.isfinite(tangents)):
        raise DermisError(f"{source}: mesh tangents must be {len(positions)} finite values")
    elif np.ndim(tangents) == 2 and np.shape(tangents)[1] >= 3:
        tangents = np.asarray(tangents, np.float32)
        tangents = np.concatenate([_within_norm_range(tangents[:, :3]), tangents[:, 3:]], axis=1)
    progress.step("tangents")
    progress.close()
    return Mesh(positions, normals, uvs, indices, np.asarray(tangents, np.float32), source=source, uvs1=uvs1).validate()


def _within_norm_range(v):
    """Rows of float32 vectors whose length overflows float32 (a finite component past ~1.8e19, which a
    file may give a normal or tangent: only its direction counts) scaled by their largest component; the
    others untouched, so every ordinary mesh keeps its bits. Without it such a normal became (0, 0, 1)
    (v / inf) and such a tangent NaN in the shader."""
    v = np.asarray(v, np.float32)
    with np.errstate(over="ignore"):
        big = ~np.isfinite(np.linalg.norm(v, axis=1))
    if big.any():
        v = v.copy()
        v[big] /= np.abs(v[big]).max(axis=1, keepdims=True)
    return v


class _Progress:
    """Progress on stderr for meshes over PROGRESS_VERTICES (tqdm; the line is cleared when done)."""

    def __init__(self, source, n_vertices, steps=("normals", "tangents")):
        self.bar = None
        if n_vertices > PROGRESS_VERTICES:
            from tqdm import tqdm

            self.bar = tqdm(total=len(steps), desc=f"loading {Path(str(source)).name} ({n_vertices} vertices)",
                            leave=False, unit="step")

    def step(self, name):
        if self.bar is not None:
            self.bar.set_postfix_str(name)
            self.bar.update(1)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def vertex_normals(positions, indices) -> np.ndarray:
    p = positions.astype(np.float64)
    i = indices.astype(np.int64)
    fn = np.cross(p[i[:, 1]] - p[i[:, 0]], p[i[:, 2]] - p[i[:, 0]])  # area-weighted
    n = np.zeros_like(p)
    for c in range(3):
        np.add.at(n, i[:, c], fn)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.maximum(ln, 1e-20)).astype(np.float32)


# ----------------------------------------------------------------------------- glTF 2.0

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class GltfAsset:
    """Reads a glTF 2.0 file's meshes (all primitives of all nodes, world transforms applied)."""

    def __init__(self, path: Path):
        import pygltflib

        self.path = Path(path)
        raw = read_bytes(self.path, "mesh file")
        self.folder = self.path.resolve().parent
        if self.path.suffix.lower() == ".glb" or raw[:4] == b"glTF":
            text, self._binary = gltf_document.parse_glb(raw, self.path)
        else:
            try:
                text, self._binary = raw.decode("utf-8"), None
            except UnicodeDecodeError:
                raise DermisError(f"{self.path}: cannot parse glTF (not UTF-8 JSON text)") from None
        doc = gltf_document.parse_json(text, self.path)
        gltf_document.validate_document(doc, self.path, None if self._binary is None else len(self._binary))
        self.doc = doc  # checked: materials, textures and samplers are read from it
        try:
            self.gltf = pygltflib.GLTF2.gltf_from_json(json.dumps(doc))
        except Exception as exc:
            raise DermisError(f"{self.path}: cannot parse glTF ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
        self._buffers: dict[int, bytes] = {}

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            b = self.gltf.buffers[i]
            if b.uri is None:
                data = self._binary
            else:
                data = _data_uri(b.uri, self.path)
                if data is None:
                    data = read_bytes(resolve_inside(self.folder, b.uri, "buffer", self.path), "buffer")
            if len(data) < b.byteLength:
                raise DermisError(f"{self.path}: buffer {i} has {len(data)} bytes, its byteLength says {b.byteLength} (truncated?)")
            self._buffers[i] = data
        return self._buffers[i]

    def view_bytes(self, view_index: int) -> tuple[bytes, int | None]:
        v = self.gltf.bufferViews[view_index]
        buf = self.buffer(v.buffer)
        start = v.byteOffset or 0
        if start + v.byteLength > len(buf):
            raise DermisError(f"{self.path}: bufferView {view_index} runs past its buffer (file truncated?)")
        return buf[start : start + v.byteLength], v.byteStride

    def accessor(self, index: int) -> np.ndarray:
        a = self.gltf.accessors[index]
        dtype = np.dtype(_COMPONENT[a.componentType])
        n = _NCOMP[a.type]
        if a.bufferView is None:
            out = np.zeros((a.count, n), dtype)
        else:
            data, stride = self.view_bytes(a.bufferView)
            off = a.byteOffset or 0
            elem = dtype.itemsize * n
            stride = stride or elem
            need = off + stride * (a.count - 1) + elem if a.count else 0
            if need > len(data):
                raise DermisError(f"{self.path}: accessor {index} runs past its bufferView (file truncated?)")
            arr = np.ndarray((a.count, n), dtype=dtype, buffer=data, offset=off, strides=(stride, dtype.itemsize))
            out = np.array(arr)
        sparse = self.doc["accessors"][index].get("sparse")
        if sparse is not None:  # glTF 2.0 3.6.2.3: base values (or zeros), then count replacements
            k = sparse["count"]
            where = np.ravel(self._packed(sparse["indices"], np.dtype(_COMPONENT[sparse["indices"]["componentType"]]), k, 1,
                                          f"accessor {index} sparse indices"))
            if np.any(where >= a.count) or np.any(np.diff(where.astype(np.int64)) <= 0):
                raise DermisError(f"{self.path}: accessor {index} sparse indices must increase strictly and stay below "
                                  f"its count {a.count}")
            out[where] = self._packed(sparse["values"], dtype, k, n, f"accessor {index} sparse values")
        if a.normalized and dtype.kind in "iu":
            info = np.iinfo(dtype)
            out = np.maximum(out.astype(np.float32) / info.max, -1.0)
        return out

    def _packed(self, ref: dict, dtype, count: int, n: int, what: str) -> np.ndarray:
        """``count`` tightly packed elements of ``n`` components at a bufferView + byteOffset."""
        data, _ = self.view_bytes(ref["bufferView"])
        off = ref.get("byteOffset", 0)
        if off + count * n * dtype.itemsize > len(data):
            raise DermisError(f"{self.path}: {what} run past their bufferView (file truncated?)")
        return np.frombuffer(data, dtype, count * n, off).reshape(count, n).copy()

    def image(self, texture_index: int, srgb: bool, max_pixels: int, rgba: bool = False) -> Texture:
        tex = self.gltf.textures[texture_index]
        img = self.gltf.images[tex.source]
        label = f"{self.path} image {tex.source}"
        if img.bufferView is not None:
            data, _ = self.view_bytes(img.bufferView)
            arr = read_image(None, srgb=srgb, max_pixels=max_pixels, data=data, source=label)
        elif img.uri:
            data = _data_uri(img.uri, self.path)
            if data is not None:
                arr = read_image(None, srgb=srgb, max_pixels=max_pixels, data=data, source=label)
            else:
                p = resolve_inside(self.folder, img.uri, "image", self.path)
                arr = read_image(p, srgb=srgb, max_pixels=max_pixels)
                label = str(p)
        else:
            raise DermisError(f"{label}: image has neither a URI nor a bufferView")
        return Texture(as_rgba(arr) if rgba else as_rgb(arr), label)

    def _node_matrices(self):
        g = self.gltf
        mats = {}

        def local(node):
            if node.matrix:
                return np.array(node.matrix, np.float64).reshape(4, 4).T
            t = np.eye(4)
            if node.translation:
                t[:3, 3] = node.translation
            r = np.eye(4)
            if node.rotation:
                x, y, z, w = node.rotation
                r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
            s = np.eye(4)
            if node.scale:
                s[0, 0], s[1, 1], s[2, 2] = node.scale
            return t @ r @ s

        def walk(root):
            # glTF 2.0 3.5.3: nodes form disjoint trees (one parent each); a node met twice is
            # a cycle or a shared child, refused (re-walking shared children grows exponentially)
            stack = [(root, np.eye(4))]
            while stack:
                i, parent = stack.pop()
                if i in mats:
                    raise DermisError(f"{self.path}: node {i} is reached twice (cyclic hierarchy or several parents)")
                mats[i] = parent @ local(g.nodes[i])
                stack.extend((c, mats[i]) for c in (g.nodes[i].children or []))

        scene = g.scenes[g.scene or 0] if g.scenes else None
        if scene:
            roots = scene.nodes or []
        else:  # no scene: every node that is nobody's child
            children = {c for n in g.nodes for c in (n.children or [])}
            roots = [i for i in range(len(g.nodes)) if i not in children]
        for r_ in roots:
            walk(r_)
        return mats

    def _material_label(self, mi) -> str:
        if mi is None:
            return "(no material)"
        name = self.doc["materials"][mi].get("name")
        return f"'{name}'" if name else f"#{mi}"

    def _skin_set(self, used: list, skin_materials) -> set:
        """The materials (indices; None = no material) rendered as skin: those the scene names
        (names or indices), else the mesh's single one."""
        labels = ", ".join(self._material_label(m) for m in used)
        if skin_materials is None:
            if len(used) == 1:
                return set(used)
            raise DermisError(f"{self.path}: the mesh has {len(used)} materials ({labels}); name the skin ones in the "
                              f"scene's [skin] materials = [...]")
        chosen = set()
        for entry in skin_materials:
            hits = [m for m in used if m is not None and (
                entry == m if isinstance(entry, int) else self.doc["materials"][m].get("name") == entry)]
            if not hits:
                raise DermisError(f"{self.path}: [skin] materials names {entry!r}, a material no triangle primitive "
                                  f"uses (materials: {labels})")
            chosen.update(hits)
        return chosen

    def _skin_material(self, skin: set) -> tuple[dict, str]:
        """The one material every skin primitive shares (by content), and its label."""
        mats = {m: ({} if m is None else self.doc["materials"][m]) for m in sorted(skin, key=lambda m: -1 if m is None else m)}

        def used_part(mat):  # what dermis reads from a skin material
            pbr = mat.get("pbrMetallicRoughness") or {}
            return json.dumps([pbr.get("baseColorFactor"), pbr.get("baseColorTexture"), mat.get("normalTexture")], sort_keys=True)

        first = next(iter(mats))
        for m, mat in mats.items():
            if used_part(mat) != used_part(mats[first]):
                raise DermisError(f"{self.path}: skin materials {self._material_label(first)} and {self._material_label(m)} "
                                  f"have different base colours or maps; dermis renders one skin material per mesh")
        mat, label = mats[first], self._material_label(first)
        pbr = mat.get("pbrMetallicRoughness") or {}
        ignored = [k for k in ("metallicRoughnessTexture",) if k in pbr]
        ignored += [k for k in ("occlusionTexture", "emissiveTexture") if k in mat]
        if any(x != 0 for x in mat.get("emissiveFactor", [0, 0, 0])):
            ignored.append("emissiveFactor")
        if mat.get("alphaMode", "OPAQUE") != "OPAQUE":
            ignored.append(f"alphaMode {mat['alphaMode']}")
        if (mat.get("normalTexture") or {}).get("scale", 1.0) != 1.0:
            ignored.append("normalTexture scale (use [material] normal_strength)")
        for feature in ignored:
            warn(f"{self.path}: skin material {label}: {feature} is not supported and ignored")
        return mat, label

    def _warn_unsupported(self, prims):
        """One line per glTF feature the file uses that dermis does not apply."""
        doc = self.doc
        for ext in doc.get("extensionsUsed", []) if isinstance(doc.get("extensionsUsed"), list) else []:
            if ext not in gltf_document.SUPPORTED_EXTENSIONS:
                warn(f"{self.path}: glTF extension {ext} is not supported and ignored")
        if any(p.get("targets") for _, _, p in prims):
            warn(f"{self.path}: morph targets are not applied (the base shape renders)")
        if any("skin" in n for n in doc.get("nodes", [])):
            warn(f"{self.path}: skinning (node skin) is not applied (the mesh renders in its bind pose)")
        if any("camera" in n for n in doc.get("nodes", [])):
            warn(f"{self.path}: glTF cameras are not used (the scene's [camera] is)")

    def _maps(self, mat: dict, label: str):
        """The skin material's maps ('albedo', 'normal_map' -> textureInfo); each is sampled through
        its own UV set and KHR_texture_transform (Texture.texcoord / transform)."""
        pbr = mat.get("pbrMetallicRoughness") or {}
        refs = {k: r for k, r in (("albedo", pbr.get("baseColorTexture")), ("normal_map", mat.get("normalTexture")))
                if r is not None}
        self._check_sets(refs, label)
        return refs

    def _check_sets(self, refs: dict, label: str):
        for r in refs.values():
            if gltf_document.texcoord_set(r) > 1:
                raise DermisError(f"{self.path}: material {label} samples a map through TEXCOORD_"
                                  f"{gltf_document.texcoord_set(r)}: dermis reads TEXCOORD_0 and TEXCOORD_1 only")

    def _sampler(self, texture_index: int) -> tuple[tuple, tuple]:
        """((wrapS, wrapT) as 'clamp' | 'mirror' | 'repeat', (minFilter, magFilter) GL enums or None);
        no sampler: repeat and automatic filtering (glTF 2.0 5.26)."""
        si = self.doc["textures"][texture_index].get("sampler")
        sm = {} if si is None else self.doc["samplers"][si]
        wrap = tuple(gltf_document.WRAP_MODES[sm.get(k, 10497)] for k in ("wrapS", "wrapT"))
        filters = (sm.get("minFilter"), sm.get("magFilter"))
        return wrap, (None if filters == (None, None) else filters)

    def _map(self, ref: dict, srgb: bool, uv_convention: str, max_pixels: int, rgba: bool = False) -> Texture:
        """A material map as a Texture addressed as the file says: its sampler's wrap modes and
        filters, its texCoord set and its KHR_texture_transform (as a 3x3 in dermis's v-up UVs).
        A MIRRORED_REPEAT axis is baked into a doubled image read at half the coordinate
        (_mirror_doubled), the halving folded into the map's own transform."""
        tex = self.image(ref["index"], srgb=srgb, max_pixels=max_pixels, rgba=rgba)
        wrap, filters = self._sampler(ref["index"])
        halve = tuple(w == "mirror" for w in wrap)
        v_down = uv_convention == "v-down"
        data, wrap = _mirror_doubled(tex.data, wrap, halve, v_down=v_down)
        return Texture(data, tex.source, wrap=wrap, filters=filters, texcoord=gltf_document.texcoord_set(ref),
                       transform=uv_matrix(_khr_transform(ref), halve, v_down))

    def _read_prims(self, prims, sets) -> dict:
        """Positions, normals, UV sets ``sets`` (set -> array or None when no primitive has it),
        tangents, COLOR_0 and indices of ``prims``, concatenated with their node transforms applied."""
        P, N, I, TAN, COL = [], [], [], [], []
        UV = {k: [] for k in sets}
        base = 0
        have_tangents = True
        try:
            for m4, mi, prim in prims:
                at = prim["attributes"]
                p = self.accessor(at["POSITION"]).astype(np.float64)
                p = (np.c_[p, np.ones(len(p))] @ m4.T)[:, :3]
                det = np.linalg.det(m4[:3, :3])
                if not np.isfinite(det) or abs(det) < 1e-30:
                    raise DermisError(f"{self.path}: a node's transform of mesh {mi} is singular or not finite "
                                      f"(scale 0, or numbers too large)")
                nm = np.linalg.inv(m4[:3, :3]).T
                n = self.accessor(at["NORMAL"]).astype(np.float64) @ nm.T if "NORMAL" in at else None
                for k in sets:
                    name = f"TEXCOORD_{k}"
                    UV[k].append(self.accessor(at[name]).astype(np.float64) if name in at else None)
                # glTF 2.0 3.7.2.1: COLOR_0 multiplies the base colour (linear; alpha unused here)
                col = self.accessor(at["COLOR_0"]).astype(np.float64)[:, :3] if "COLOR_0" in at else np.ones((len(p), 3))
                if "TANGENT" in at:  # tangents follow TEXCOORD_0
                    tg = self.accessor(at["TANGENT"]).astype(np.float64)
                    tg[:, :3] = tg[:, :3] @ m4[:3, :3].T
                    if det < 0:  # a mirroring transform flips handedness
                        tg[:, 3] = -tg[:, 3]
                    TAN.append(tg)
                else:
                    have_tangents = False
                idx = self.accessor(prim["indices"]).reshape(-1) if prim.get("indices") is not None else np.arange(len(p))
                if len(idx) % 3:
                    raise DermisError(f"{self.path}: index count {len(idx)} is not a multiple of 3")
                if len(idx) and (idx.max() >= len(p)):
                    raise DermisError(f"{self.path}: triangle indices out of range")
                P.append(p)
                N.append(n)
                COL.append(col)
                tris = idx.reshape(-1, 3).astype(np.int64)
                if det < 0:  # glTF 2.0 3.7.2.1: a mirroring transform makes clockwise the front face
                    tris = tris[:, ::-1]
                I.append(tris + base)
                base += len(p)
        except DermisError:
            raise
        except Exception as exc:
            raise DermisError(f"{self.path}: malformed glTF mesh data ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
        uvs = {}
        for k, parts in UV.items():
            if any(u is None for u in parts) and not all(u is None for u in parts):
                raise DermisError(f"{self.path}: some mesh primitives have TEXCOORD_{k} (UVs) and others do not")
            uvs[k] = None if parts[0] is None else np.concatenate(parts)
        return {"positions": np.concatenate(P), "normals": None if any(n is None for n in N) else np.concatenate(N),
                "uvs": uvs, "tangents": np.concatenate(TAN) if have_tangents and TAN else None,
                "colours": np.concatenate(COL), "indices": np.concatenate(I)}

    def load(self, uv_convention: str, max_pixels: int = MAX_IMAGE_PIXELS, skin_materials=None):
        """Returns (Mesh, material dict with 'albedo', 'normal_map', 'specular_map' Textures or None,
        'albedo_color', and 'surfaces': the non-skin primitives as dermis.scene.model.Surface).

        The primitives whose material is skin (``skin_materials``: names or indices; None = the
        mesh's single material) form the skin Mesh; every other material's primitives form one
        Surface rendered with glTF's metallic-roughness model. Each map is sampled through the UV
        set it names (texCoord) with its own KHR_texture_transform, and its sampler's wrap modes
        and filters (Texture). COLOR_0 of the skin is multiplied into the base colour by baking it
        into an albedo texture: on a generated layout (materials without maps), or into the albedo
        in the albedo's own layout (which must be unique and inside [0, 1])."""
        g, doc = self.gltf, self.doc
        if not g.meshes:
            raise DermisError(f"{self.path}: glTF has no meshes")
        mats = self._node_matrices()
        node_meshes = [(mats[i], n.mesh) for i, n in enumerate(g.nodes) if n.mesh is not None and i in mats]
        if not node_meshes:
            node_meshes = [(np.eye(4), i) for i in range(len(g.meshes))]
        prims = [(m4, mi, p) for m4, mi in node_meshes for p in doc["meshes"][mi]["primitives"]
                 if p.get("mode", 4) == 4 and "POSITION" in p["attributes"]]  # points/lines: not drawn
        if not prims:
            raise DermisError(f"{self.path}: glTF has no triangle meshes")
        used = list(dict.fromkeys(p.get("material") for _, _, p in prims))
        skin = self._skin_set(used, skin_materials)
        self._warn_unsupported(prims)
        mat, label = self._skin_material(skin)
        mesh, material = self._load_skin([x for x in prims if x[2].get("material") in skin], mat, label,
                                         uv_convention, max_pixels)
        material["surfaces"] = [self._load_surface([x for x in prims if x[2].get("material") == m], m, uv_convention,
                                                   max_pixels) for m in used if m not in skin]
        return mesh, material

    def _load_skin(self, prims, mat, label, uv_convention, max_pixels):
        refs = self._maps(mat, label)
        sets = {gltf_document.texcoord_set(r) for r in refs.values()}
        data = self._read_prims(prims, {0} | sets)
        positions, normals, indices, colours = data["positions"], data["normals"], data["indices"], data["colours"]
        uvs, uvs1, tangents = data["uvs"][0], data["uvs"].get(1), data["tangents"]
        pbr = mat.get("pbrMetallicRoughness") or {}
        factor = np.asarray(pbr["baseColorFactor"][:3], np.float32) if "baseColorFactor" in pbr else None
        material = {"albedo": None, "normal_map": None, "specular_map": None, "albedo_color": None}
        vertex_coloured = bool(np.any(np.abs(colours - 1.0) > 1e-6))
        if vertex_coloured and not refs:  # no maps: the UVs are free for a generated layout
            positions, normals, indices, uvs, albedo = bake_vertex_colours(positions, normals, indices, colours, factor,
                                                                           f"{self.path} COLOR_0")
            material["albedo"], tangents, uv_convention, uvs1 = albedo, None, "v-up", None
            vertex_coloured = False
        try:
            for key, ref in refs.items():
                tex = self._map(ref, key == "albedo", uv_convention, max_pixels)
                if key == "albedo" and factor is not None:  # glTF 2.0: base colour = factor x texture
                    tex.data = tex.data * factor
                material[key] = tex
        except DermisError:
            raise
        except Exception as exc:
            raise DermisError(f"{self.path}: malformed glTF material ({type(exc).__name__}: "
                              f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
        mesh = finish_mesh(positions, normals, uvs, indices, str(self.path), uv_convention,
                           tangents if _tangents_apply(material["normal_map"]) else None, uvs1=uvs1)
        _map_tangents(mesh, material["normal_map"])
        if vertex_coloured:  # maps: COLOR_0 goes into the albedo in its own layout, which must be unique
            from dermis.geometry.texture_space import layout_problem

            albedo = material["albedo"]
            if albedo is None:  # a white map x factor at the bake's resolution
                R = VERTEX_COLOUR_RESOLUTION
                albedo = Texture(np.ones((R, R, 3), np.float32) * (1.0 if factor is None else factor), f"{self.path}")
            where = albedo.mapped_uvs(mesh)
            problem = layout_problem(where, mesh.indices)
            if problem is not None:
                raise DermisError(f"{self.path}: material {label} has maps and the mesh has vertex colours (COLOR_0), "
                                  f"which dermis bakes into the albedo in the albedo's UV layout, but {problem}: COLOR_0 "
                                  f"with this textured material is not supported")
            H, W = albedo.data.shape[:2]
            data = albedo.data[:, :, :3] * colour_image(where, mesh.indices, colours, W, H)
            material["albedo"] = Texture(data.astype(np.float32), f"{albedo.source} x COLOR_0", wrap=albedo.wrap,
                                         filters=albedo.filters, texcoord=albedo.texcoord, transform=albedo.transform)
        if material["albedo"] is None and factor is not None:
            material["albedo_color"] = tuple(float(x) for x in factor)
        return mesh, material

    def _load_surface(self, prims, m, uv_convention, max_pixels) -> Surface:
        """The primitives of one non-skin material as a Surface (glTF 2.0 3.9, metallic-roughness)."""
        mat = {} if m is None else self.doc["materials"][m]
        label = self._material_label(m)
        pbr = mat.get("pbrMetallicRoughness") or {}
        refs = {k: r for k, r in (("base_color", pbr.get("baseColorTexture")),
                                  ("metallic_roughness", pbr.get("metallicRoughnessTexture")),
                                  ("normal", mat.get("normalTexture")), ("occlusion", mat.get("occlusionTexture")),
                                  ("emissive", mat.get("emissiveTexture"))) if r is not None}
        self._check_sets(refs, label)
        sets = {gltf_document.texcoord_set(r) for r in refs.values()}
        data = self._read_prims(prims, {0} | sets)
        if np.any(np.abs(data["colours"] - 1.0) > 1e-6):
            warn(f"{self.path}: material {label} (not skin): COLOR_0 is not supported and ignored")
        alpha_mode, cutoff = mat.get("alphaMode", "OPAQUE"), float(mat.get("alphaCutoff", 0.5))
        if alpha_mode == "BLEND":
            warn(f"{self.path}: material {label}: alphaMode BLEND is rendered as MASK at alpha 0.5 (dermis does not "
                 f"sort transparent surfaces)")
            alpha_mode, cutoff = "MASK", 0.5
        out = MetallicRoughnessMaterial(
            name=(mat.get("name") or f"#{m}") if m is not None else "(no material)", base_color=tuple(float(x) for x in pbr.get("baseColorFactor", (1.0, 1.0, 1.0, 1.0))),
            metallic=float(pbr.get("metallicFactor", 1.0)), roughness=float(pbr.get("roughnessFactor", 1.0)),
            normal_scale=float((mat.get("normalTexture") or {}).get("scale", 1.0)),
            occlusion_strength=float((mat.get("occlusionTexture") or {}).get("strength", 1.0)),
            emissive=tuple(float(x) for x in mat.get("emissiveFactor", (0.0, 0.0, 0.0))),
            alpha_mode=alpha_mode, alpha_cutoff=cutoff, double_sided=bool(mat.get("doubleSided", False)))
        try:
            for key, ref in refs.items():
                setattr(out, f"{key}_map", self._map(ref, key in ("base_color", "emissive"), uv_convention, max_pixels,
                                                     rgba=key == "base_color"))
        except DermisError:
            raise
        except Exception as exc:
            raise DermisError(f"{self.path}: malformed glTF material ({type(exc).__name__}: "
                              f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
        uvs = data["uvs"][0]
        if uvs is None:  # no map reads TEXCOORD_0 (validated): any coordinates, no layout generated
            uvs = np.zeros((len(data["positions"]), 2))
        mesh = finish_mesh(data["positions"], data["normals"], uvs, data["indices"], f"{self.path} material {label}",
                           uv_convention, data["tangents"] if _tangents_apply(out.normal_map) else None,
                           uvs1=data["uvs"].get(1))
        _map_tangents(mesh, out.normal_map)
        return Surface(mesh, out)


def _khr_transform(ref: dict):
    """A textureInfo's KHR_texture_transform as (offset, rotation, scale), or None."""
    tt = gltf_document.texture_transform(ref)
    if tt is None:
        return None
    return (tuple(tt.get("offset", (0.0, 0.0))), float(tt.get("rotation", 0.0)), tuple(tt.get("scale", (1.0, 1.0))))


def uv_matrix(transform, halve=(False, False), v_down: bool = True) -> np.ndarray | None:
    """The 3x3 that maps dermis's (v-up) UVs to a map's coordinates: KHR_texture_transform
    (:func:`apply_texture_transform`, in the FILE's UV space), then the halving of mirrored axes
    (_mirror_doubled), conjugated by the file's v flip F (v' = 1 - v) when the file's v points down:
    M = F H T F. None when it is the identity."""
    M = np.eye(3)
    if transform is not None:
        basis = apply_texture_transform(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), transform)
        M[:2, 2] = basis[0]
        M[:2, 0], M[:2, 1] = basis[1] - basis[0], basis[2] - basis[0]
    M = np.diag([0.5 if halve[0] else 1.0, 0.5 if halve[1] else 1.0, 1.0]) @ M
    if v_down:
        F = np.array([[1.0, 0, 0], [0, -1.0, 1.0], [0, 0, 1.0]])
        M = F @ M @ F
    return None if np.allclose(M, np.eye(3), rtol=0, atol=1e-12) else M.astype(np.float32)


def _tangents_apply(normal_map) -> bool:
    """The file's TANGENTs belong to TEXCOORD_0 as stored: usable for a normal map read there untransformed."""
    return normal_map is None or (normal_map.texcoord == 0 and normal_map.transform is None)


def _map_tangents(mesh: Mesh, normal_map):
    """Tangents along the normal map's own coordinates (its UV set, transformed) when they are not
    TEXCOORD_0 as stored: the tangent frame is that of the map the normals are read from."""
    if not _tangents_apply(normal_map):
        mesh.tangents = generate_tangents(mesh.positions, mesh.normals, normal_map.mapped_uvs(mesh), mesh.indices)


def warn(message: str):
    """A one-line warning on stderr (the CLI silences Python's warnings module)."""
    print(f"dermis: warning: {message}", file=sys.stderr)


def apply_texture_transform(uvs, transform):
    """KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv, in the file's UV space, with
    R = [[cos, -sin], [sin, cos]] (the extension's GLSL: mat3(cos, sin, 0, -sin, cos, 0, 0, 0, 1),
    column-major). Exact per vertex: the transform is affine, so it commutes with interpolation."""
    if transform is None:
        return uvs
    (ou, ov), r, (su, sv) = transform
    u, v = uvs[:, 0] * su, uvs[:, 1] * sv
    c, s = np.cos(r), np.sin(r)
    return np.c_[c * u - s * v + ou, s * u + c * v + ov]


def _mirror_doubled(data, wrap, halve, v_down: bool):
    """glTF MIRRORED_REPEAT without a mirrored sampler: when any map mirrors along an axis the UVs
    along it are halved (GltfAsset.load) and every map is doubled along it, so that REPEAT (or
    CLAMP) of the doubled image at u/2 equals the map's own wrap at u: mirror -> image + flipped
    image, repeat -> the image twice, clamp -> the image + its edge texels."""
    wrap = list(wrap)
    for axis, img_axis in ((0, 1), (1, 0)):  # u runs along columns, v along rows
        if not halve[axis]:
            if wrap[axis] == "mirror":  # cannot happen (halve covers every mirrored map)
                wrap[axis] = "repeat"
            continue
        # the half of the doubled image that u/2 in [0, 0.5) covers: v = 0 is the top row when
        # the file's v points down (glTF), the bottom row when it points up
        first = not (axis == 1 and not v_down)
        edge_at = -1 if first else 0  # the edge texel where the coordinate reaches 1
        if wrap[axis] == "mirror":
            other = np.flip(data, img_axis)
        elif wrap[axis] == "repeat":
            other = data
        else:
            other = np.repeat(np.take(data, [edge_at], axis=img_axis), data.shape[img_axis], axis=img_axis)
        data = np.concatenate([data, other] if first else [other, data], axis=img_axis)
        wrap[axis] = "clamp" if wrap[axis] == "clamp" else "repeat"
    return data, tuple(wrap)


VERTEX_COLOUR_RESOLUTION = 512  # texels per side of the albedo texture COLOR_0 is baked into


def bake_vertex_colours(positions, normals, indices, colours, factor, source: str):
    """COLOR_0 x baseColorFactor as an albedo texture on a generated unique layout (xatlas): the
    colours interpolated linearly over each triangle, as the rasteriser interpolates a vertex
    attribute, and spread into the gutters (nearest covered texel) for filtering. Returns the
    mesh split along the layout's seams: (positions, normals, indices, uvs v-up, Texture)."""
    from dermis.geometry.atlas import generate_atlas

    R = VERTEX_COLOUR_RESOLUTION
    positions = np.asarray(positions, np.float32)
    if normals is None:
        normals = vertex_normals(positions, indices)
    atlas = generate_atlas(positions, indices, resolution=R)
    img = colour_image(atlas.uvs, atlas.indices, np.asarray(colours)[atlas.vmapping], R, R)
    if factor is not None:
        img = img * np.asarray(factor, np.float32)
    return (positions[atlas.vmapping], np.asarray(normals)[atlas.vmapping], atlas.indices.astype(np.int64),
            atlas.uvs, Texture(img, source))


def colour_image(uvs, indices, colours, width: int, height: int) -> np.ndarray:
    """Per-vertex colours (N, 3) as a (height, width, 3) float32 image in the UV layout ``uvs`` (v up,
    unique, inside [0, 1]): interpolated linearly over each triangle, as the GPU interpolates a
    vertex attribute, and spread into the gutters from the nearest covered texel for filtering."""
    from scipy import ndimage

    from dermis.geometry.rasterize import rasterize_uv

    tri, bary = rasterize_uv(uvs, indices, width, height)
    corners = np.asarray(indices, np.int64)[np.maximum(tri, 0)]  # (H, W, 3)
    img = np.einsum("hwk,hwkc->hwc", bary.astype(np.float64), np.asarray(colours, np.float64)[corners])
    cov = tri >= 0
    if not cov.any():
        return np.ones((height, width, 3), np.float32)
    near = ndimage.distance_transform_edt(~cov, return_distances=False, return_indices=True)
    return np.clip(img[near[0], near[1]], 0.0, 1.0).astype(np.float32)  # barycentric rounding: -1e-9


# ----------------------------------------------------------------------------- OBJ + MTL


def _check_image_header(p: Path, data: bytes, max_pixels: int):
    """Size-check an image's header before anything decodes it (trimesh decodes map_Kd itself)."""
    import io

    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as im:
            w, h = im.size
    except Exception:
        raise DermisError(f"{p}: cannot decode image") from None
    if w * h > max_pixels:
        raise DermisError(f"{p}: image is {w}x{h}, over the limit of {max_pixels} pixels; refused before decoding")


_MAP_KD = "<map_Kd>"  # key of the map_Kd images, in file order, among the checked files
_MTL_MAPS = ("map_kd", "map_ka", "map_ks", "map_ns", "map_d", "map_bump", "bump", "norm", "disp")


def _obj_references(text: str, path: Path, folder: Path, max_pixels: int) -> dict:
    """Every file an OBJ names (mtllib, and the maps of those MTL files), resolved and checked
    here, so that a reference escaping the folder, missing or unreadable is an error naming it
    (trimesh would log it and load the mesh without its material). Returns name -> bytes."""
    files = {}
    for line in text.splitlines():
        if line.startswith("mtllib"):
            name = line[6:].strip()
            if not name:
                raise DermisError(f"{path}: 'mtllib' without a file name")
            mtl = resolve_inside(folder, name, "material library (mtllib)", path)
            data = read_bytes(mtl, "material library")
            files[name] = data
            try:
                mtl_text = data.decode("utf-8")
            except UnicodeDecodeError:
                raise DermisError(f"{mtl}: material library is not UTF-8 text") from None
            for mline in mtl_text.splitlines():
                parts = mline.split()
                if parts and parts[0].lower() in _MTL_MAPS and len(parts) > 1:
                    ref = parts[-1]  # options (-s 1 1 1, -bm 0.5, ...) come before the file name
                    img = resolve_inside(mtl.parent, ref, f"{parts[0]} image", mtl)
                    idata = read_bytes(img, "image file")
                    _check_image_header(img, idata, max_pixels)
                    files[ref] = idata
                    if parts[0].lower() == "map_kd":
                        files.setdefault(_MAP_KD, []).append((img, idata))
    return files


_OBJ_COUNTS = {"v": (3, 7), "vt": (2, 3), "vn": (3, 3)}  # numbers per line (v: w or r g b; vt: dermis needs u, v)


def check_obj_lines(text: str, path: Path):
    """The lines dermis's OBJ reader (trimesh) relies on, checked first: numbers where numbers go,
    face references that are non-zero integers (1-based, or negative = relative). A malformed line
    is named with its number instead of surfacing as an exception inside the parser."""
    for no, line in enumerate(text.splitlines(), 1):
        head, _, rest = line.strip().partition(" ")
        if head in _OBJ_COUNTS:
            parts = rest.split()
            lo, hi = _OBJ_COUNTS[head]
            try:
                ok = lo <= len(parts) <= hi and all(np.isfinite(float(x)) for x in parts)
            except ValueError:
                ok = False
            if not ok:
                raise DermisError(f"{path}: line {no}: '{head}' needs {lo}{'' if lo == hi else f'-{hi}'} finite numbers, "
                                  f"got '{line.strip()[:60]}'")
        elif head == "f":
            refs = rest.split()
            try:
                ok = len(refs) >= 3 and all(
                    all(int(x) != 0 for x in r.split("/") if x != "") and r.split("/")[0] != "" and r.count("/") <= 2
                    for r in refs)
            except ValueError:
                ok = False
            if not ok:
                raise DermisError(f"{path}: line {no}: 'f' needs 3 or more vertex references (v, v/vt, v/vt/vn or "
                                  f"v//vn; non-zero integers), got '{line.strip()[:60]}'")


def _safe_resolver(folder: Path, source: Path, checked: dict):
    import trimesh.resolvers

    class CheckedFilesResolver(trimesh.resolvers.FilePathResolver):
        """Serves only the files _obj_references checked; anything else is refused."""

        def get(self, name):
            if name in checked:
                return checked[name]
            raise DermisError(f"{source}: referenced file '{name}' was not checked; refused")

    return CheckedFilesResolver(str(source))


def load_obj(path: Path, uv_convention: str = "v-up", max_pixels: int = MAX_IMAGE_PIXELS):
    import trimesh

    path = Path(path)
    raw = read_bytes(path, "mesh file")
    folder = path.resolve().parent
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        # trimesh would guess the encoding with charset_normalizer (not a dependency) and fail with
        # a misleading ModuleNotFoundError; OBJ is ASCII text, like the TOML scenes (UTF-8)
        raise DermisError(f"{path}: cannot parse OBJ (not UTF-8 text; corrupt or binary file?)") from None
    n_v, n_f = text.count("\nv "), text.count("\nf ")  # before parsing: refuse what cannot fit
    if n_v > MAX_VERTICES or n_f > MAX_TRIANGLES:
        raise DermisError(f"{path}: OBJ has about {n_v} vertices and {n_f} faces, over dermis's limit of "
                          f"{MAX_VERTICES} / {MAX_TRIANGLES} (decimate the mesh)")
    check_obj_lines(text, path)
    checked = _obj_references(text, path, folder, max_pixels)
    try:
        import logging

        quiet = logging.getLogger("trimesh")
        level = quiet.level
        quiet.setLevel(logging.CRITICAL)  # its warnings are about what dermis checks itself
        try:
            loaded = trimesh.load(str(path), file_type="obj", process=False, maintain_order=True, force="mesh",
                                  resolver=_safe_resolver(folder, path, checked))
        finally:
            quiet.setLevel(level)
    except DermisError:
        raise
    except Exception as exc:
        raise DermisError(f"{path}: cannot parse OBJ ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise DermisError(f"{path}: OBJ has no triangles")
    try:
        uv = getattr(loaded.visual, "uv", None)
        normals = None
        if "vertex_normals" in loaded._cache.cache or getattr(loaded, "_vertex_normals_from_file", False):
            normals = np.asarray(loaded.vertex_normals)
    except Exception as exc:  # trimesh computes some of these lazily
        raise DermisError(f"{path}: cannot parse OBJ ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    # no UVs: texture space gets a generated layout (dermis.geometry.texture_space)
    if uv is not None and len(uv) != len(loaded.vertices):
        raise DermisError(f"{path}: OBJ has {len(uv)} texture coordinates for {len(loaded.vertices)} vertices")
    mesh = finish_mesh(np.asarray(loaded.vertices), normals, None if uv is None else np.asarray(uv), np.asarray(loaded.faces),
                       str(path), uv_convention)
    material = {"albedo": None, "normal_map": None, "specular_map": None, "albedo_color": None}
    # without an MTL file trimesh still makes a default material (a grey 2x2 image): not the
    # file's, so the scene's [material] applies
    mat = getattr(loaded.visual, "material", None) if checked else None
    if mat is not None:
        img = getattr(mat, "image", None) or getattr(mat, "baseColorTexture", None)
        if img is not None and checked.get(_MAP_KD):
            # decoded by dermis (16-bit maps keep 16 bits; trimesh's PIL image has 8)
            kd_path, kd_data = checked[_MAP_KD][0]
            arr = read_image(None, srgb=True, max_pixels=max_pixels, data=kd_data, source=str(kd_path))
            material["albedo"] = Texture(as_rgb(arr), f"{kd_path} (map_Kd)")
        col = getattr(mat, "diffuse", None)
        if col is not None and img is None:
            material["albedo_color"] = tuple(float(x) for x in np.asarray(col[:3], np.float32) / 255.0)
    return mesh, material


def load_mesh_file(path, uv_convention: str | None = None, max_pixels: int = MAX_IMAGE_PIXELS, skin_materials=None):
    """Load a .glb/.gltf/.obj; ``uv_convention`` None picks the format's own convention;
    ``skin_materials``: the glTF materials (names or indices) rendered as skin (GltfAsset.load)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext in (".glb", ".gltf"):
        return GltfAsset(path).load(uv_convention or "v-down", max_pixels, skin_materials)
    if skin_materials is not None:
        raise DermisError(f"{path}: [skin] materials chooses glTF materials; this mesh is not glTF")
    if ext == ".obj":
        return load_obj(path, uv_convention or "v-up", max_pixels)
    raise DermisError(f"{path}: unsupported mesh format '{ext}' (use .glb, .gltf or .obj)")
