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
import json
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from dermis.errors import DermisError
from dermis.fileio import os_error_text, read_bytes, regular_file
from dermis.images import MAX_IMAGE_PIXELS, as_rgb, read_image
from dermis.scene import gltf_document
from dermis.scene.gltf_document import MAX_TRIANGLES, MAX_VERTICES, PROGRESS_VERTICES
from dermis.scene.model import Mesh, Texture
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


def finish_mesh(positions, normals, uvs, indices, source: str, uv_convention: str, tangents=None) -> Mesh:
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
        indices, uvs, tangents, uv_convention = atlas.indices.astype(np.int64), atlas.uvs, None, "v-up"
    if uvs is None:
        raise DermisError(f"{source}: mesh has no texture coordinates (UVs) and no valid triangles to generate them from")
    uvs = np.ascontiguousarray(uvs, np.float32).copy()
    for name, a in (("positions", positions), ("uvs", uvs)):
        if not np.all(np.isfinite(a)):
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
    span = float(np.abs(uvs).max()) if len(uvs) else 0.0
    if span > UV_LIMIT:
        raise DermisError(f"{source}: texture coordinates reach {span:g}; dermis needs a UV layout within "
                          f"[-{UV_LIMIT:g}, {UV_LIMIT:g}] (the unit square, or UDIM tiles)")
    if uv_convention == "v-down":
        uvs[:, 1] = 1.0 - uvs[:, 1]
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
    progress.step("tangents")
    progress.close()
    return Mesh(positions, normals, uvs, indices, np.asarray(tangents, np.float32), source=source).validate()


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
        if getattr(a, "sparse", None) is not None:
            raise DermisError(f"{self.path}: sparse accessors are not supported")
        if a.normalized and dtype.kind in "iu":
            info = np.iinfo(dtype)
            out = np.maximum(out.astype(np.float32) / info.max, -1.0)
        return out

    def image(self, texture_index: int, srgb: bool, max_pixels: int) -> Texture:
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
        return Texture(as_rgb(arr), label)

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

    def load(self, uv_convention: str, max_pixels: int = MAX_IMAGE_PIXELS):
        """Returns (Mesh, material dict with 'albedo', 'normal_map', 'specular_map' Textures or None)."""
        g = self.gltf
        if not g.meshes:
            raise DermisError(f"{self.path}: glTF has no meshes")
        P, N, UV, I, TAN = [], [], [], [], []
        base = 0
        material_index = None
        mats = self._node_matrices()
        node_meshes = [(mats[i], n.mesh) for i, n in enumerate(g.nodes) if n.mesh is not None and i in mats]
        if not node_meshes:
            node_meshes = [(np.eye(4), i) for i in range(len(g.meshes))]
        have_tangents = True
        try:
            for m4, mi in node_meshes:
                for prim in g.meshes[mi].primitives:
                    if prim.mode not in (None, 4):
                        continue  # points/lines: not skin
                    at = prim.attributes
                    if at.POSITION is None:
                        continue
                    p = self.accessor(at.POSITION).astype(np.float64)
                    p = (np.c_[p, np.ones(len(p))] @ m4.T)[:, :3]
                    det = np.linalg.det(m4[:3, :3])
                    if not np.isfinite(det) or abs(det) < 1e-30:
                        raise DermisError(f"{self.path}: a node's transform of mesh {mi} is singular or not finite "
                                          f"(scale 0, or numbers too large)")
                    nm = np.linalg.inv(m4[:3, :3]).T
                    n = self.accessor(at.NORMAL).astype(np.float64) @ nm.T if at.NORMAL is not None else None
                    uv = self.accessor(at.TEXCOORD_0).astype(np.float64) if at.TEXCOORD_0 is not None else None
                    if at.TANGENT is not None:
                        tg = self.accessor(at.TANGENT).astype(np.float64)
                        tg[:, :3] = tg[:, :3] @ m4[:3, :3].T
                        if np.linalg.det(m4[:3, :3]) < 0:  # a mirroring transform flips handedness
                            tg[:, 3] = -tg[:, 3]
                        TAN.append(tg)
                    else:
                        have_tangents = False
                    idx = self.accessor(prim.indices).reshape(-1) if prim.indices is not None else np.arange(len(p))
                    if len(idx) % 3:
                        raise DermisError(f"{self.path}: index count {len(idx)} is not a multiple of 3")
                    if len(idx) and (idx.max() >= len(p)):
                        raise DermisError(f"{self.path}: triangle indices out of range")
                    P.append(p)
                    N.append(n)
                    UV.append(uv)
                    I.append(idx.reshape(-1, 3).astype(np.int64) + base)
                    base += len(p)
                    if material_index is None:
                        material_index = prim.material
        except DermisError:
            raise
        except Exception as exc:
            raise DermisError(f"{self.path}: malformed glTF mesh data ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
        if not P:
            raise DermisError(f"{self.path}: glTF has no triangle meshes")
        normals = None if any(n is None for n in N) else np.concatenate(N)
        tangents = np.concatenate(TAN) if have_tangents and TAN else None
        if any(u is None for u in UV) and not all(u is None for u in UV):
            raise DermisError(f"{self.path}: some mesh primitives have TEXCOORD_0 (UVs) and others do not")
        uvs = None if UV[0] is None else np.concatenate(UV)  # None: generated (finish_mesh)
        mesh = finish_mesh(np.concatenate(P), normals, uvs, np.concatenate(I), str(self.path), uv_convention, tangents)
        material = {"albedo": None, "normal_map": None, "specular_map": None, "albedo_color": None}
        try:
            if material_index is not None and g.materials:
                mat = g.materials[material_index]
                pbr = mat.pbrMetallicRoughness
                factor = np.asarray(pbr.baseColorFactor[:3], np.float32) if pbr is not None and pbr.baseColorFactor else None
                if pbr is not None and pbr.baseColorTexture is not None:
                    tex = self.image(pbr.baseColorTexture.index, srgb=True, max_pixels=max_pixels)
                    if factor is not None:  # glTF 2.0: base colour = factor x texture
                        tex = Texture(tex.data * factor, tex.source)
                    material["albedo"] = tex
                elif factor is not None:
                    material["albedo_color"] = tuple(float(x) for x in factor)
                if mat.normalTexture is not None:
                    material["normal_map"] = self.image(mat.normalTexture.index, srgb=False, max_pixels=max_pixels)
        except DermisError:
            raise
        except Exception as exc:
            raise DermisError(f"{self.path}: malformed glTF material ({type(exc).__name__}: "
                              f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
        return mesh, material


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


def load_mesh_file(path, uv_convention: str | None = None, max_pixels: int = MAX_IMAGE_PIXELS):
    """Load a .glb/.gltf/.obj; ``uv_convention`` None picks the format's own convention."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext in (".glb", ".gltf"):
        return GltfAsset(path).load(uv_convention or "v-down", max_pixels)
    if ext == ".obj":
        return load_obj(path, uv_convention or "v-up", max_pixels)
    raise DermisError(f"{path}: unsupported mesh format '{ext}' (use .glb, .gltf or .obj)")
