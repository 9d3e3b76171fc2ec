"""What every product the Renderer caches between frames depends on, in one table.

A cached product (the shadow atlas, the mesh on the GPU, the material textures, a technique's
texture-space passes, ...) is rebuilt when the key of its inputs changes. Keys are computed from
CONTENT, never from object identity: an array's key is a checksum of its bytes (so an in-place
edit is seen and a new array with equal values is not a change), a scalar's is its value. No key
uses ``id()``, which an unrelated object can reuse once the first is garbage-collected (values
derived from arrays, memo_by_content, use an id only to pick a slot and are returned only when the
arrays' content keys match).

Checking content costs a pass over the bytes each frame: XXH3 (128 bit) reads about 20 GB/s on
one core, about 1.5 ms for the head's three 1024^2 float maps (zlib's CRC-32 took 10-25 ms).
Remembering the checksum of a read-only array would not be sound: its flag can be turned back on,
the array edited and the flag turned off again between two frames. An array whose memory is an
immutable ``bytes`` object is different: numpy refuses to make it writable, so its bytes can never
change while the ``bytes`` object lives. Its checksum is remembered (``_IMMUTABLE_DIGESTS``, keyed
by that object, which the table keeps alive so that its ``id`` cannot be reused), and the loaders
store the maps they decode that way (``immutable``): the viewer's per-frame keys then cost no pass
over the head's material maps (~25 ms per frame on the loaded 2-core machine). An edit of such a
map must make a new array (numpy raises on an in-place write), which gets a new key.
"""

from __future__ import annotations

import hashlib
import threading

import numpy as np
import xxhash

PRODUCTS = {
    # product:            the inputs it is built from (keys of scene_inputs)
    "gpu_mesh": ("mesh", "surfaces"),
    "material_textures": ("material_maps",),
    "light_uniforms": ("mesh", "surfaces", "lights", "environment"),
    # the environment prefiltered for the specular lobe (prefiltered_environment.py, gl/environment.py)
    "environment_specular": ("environment",),
    # non-skin surfaces cast shadows (MASK maps cut them) and widen the maps' frusta
    "shadow_atlas": ("mesh", "surfaces", "light_geometry", "epoch"),  # depth only: no mm in it
    "mesh_curvature": ("mesh", "scale"),
    "stretch": ("mesh", "scale", "irradiance_size"),
    "thickness": ("mesh", "scale", "irradiance_size"),  # the texel thickness bake of translucency (gl/thickness.py)
    "profile_tables": ("profile",),
    # ambient occlusion and the visible fraction of the environment's irradiance (geometry/visibility.py:
    # the ray bake cached per mesh content, the fraction per environment), or the open sky's
    # (1, 1, 1, 1) with [environment] occlusion = false, in the vertex buffer
    "environment_visibility": ("mesh", "environment_occlusion", "environment"),
    # the skin material's uniforms (GpuScene.material_uniforms: scalars, map addressing, profile-driven albedo scale)
    "material_uniforms": ("material_maps", "material_scalars", "scale", "profile"),
    # the first hits of the interreflection rays (geometry/interreflection.py, cached per mesh content)
    "interreflection_bake": ("mesh",),
    # which baked subsurface transfer tsd gathers (dermis.subsurface_transfer.store.find: the mesh's
    # content, its scale, the medium made from the profile and the mean albedo) and its GPU copy
    "subsurface_transfer": ("mesh", "scale", "profile", "material_maps", "material_scalars"),
    "texture_space": ("mesh", "surfaces", "scale", "lights", "environment", "environment_occlusion", "material_maps",
                      "material_scalars", "profile", "irradiance_size", "epoch", "interreflection",
                      "translucency_light_path", "directional_albedo"),
    # the one-bounce irradiance per vertex shared by ssss, preintegrated and lambert (gl/interreflection.py
    # SharedBounce: rho E rasterised in texture space, gathered over the bake's rays): what rho E depends on
    "interreflection": ("mesh", "surfaces", "scale", "lights", "environment", "environment_occlusion", "material_maps",
                        "material_scalars", "profile", "irradiance_size", "epoch", "interreflection", "directional_albedo"),
    # what of the shared bounce's rho E depends on no light (SharedBounce's texture-space inputs: position,
    # normals, material, the directional albedo's c, the occluded ambient): "interreflection" less "lights"
    "interreflection_inputs": ("mesh", "surfaces", "scale", "environment", "environment_occlusion", "material_maps",
                               "material_scalars", "profile", "irradiance_size", "epoch", "interreflection",
                               "directional_albedo"),
}
"""Every cached product and what it depends on. "epoch" is bumped by Renderer.invalidate()."""

_IMMUTABLE_DIGESTS: dict = {}  # (id(bytes), address, nbytes) -> (the bytes object, its XXH3-128 digest)
_IMMUTABLE_KEEP = 64  # buffers remembered at most (oldest forgotten first)


def immutable(a: np.ndarray) -> np.ndarray:
    """A copy of ``a`` whose memory is an immutable ``bytes`` object (numpy cannot make it writable),
    so that its fingerprint is computed once (see the module's docstring)."""
    a = np.ascontiguousarray(a)
    return np.frombuffer(a.tobytes(), dtype=a.dtype).reshape(a.shape)


def _digest(owner: np.ndarray) -> str:
    buf = owner
    while isinstance(buf, np.ndarray):
        buf = buf.base
    if isinstance(buf, bytes) and not owner.flags.writeable:
        key = (id(buf), owner.__array_interface__["data"][0], owner.nbytes)
        hit = _IMMUTABLE_DIGESTS.get(key)
        if hit is not None and hit[0] is buf:
            return hit[1]
        d = xxhash.xxh3_128_hexdigest(memoryview(owner.reshape(-1).view(np.uint8)))
        if len(_IMMUTABLE_DIGESTS) >= _IMMUTABLE_KEEP:
            _IMMUTABLE_DIGESTS.pop(next(iter(_IMMUTABLE_DIGESTS)))
        _IMMUTABLE_DIGESTS[key] = (buf, d)
        return d
    return xxhash.xxh3_128_hexdigest(memoryview(owner.reshape(-1).view(np.uint8)))


_SCOPE = threading.local()  # .memo: {id(array): (array, fingerprint)} while a frame_scope() is open


class frame_scope:
    """Within ``with frame_scope():`` (one Renderer frame), an array's fingerprint is computed once
    and remembered until the scope closes: the frame asks for the mesh's several times (its keys,
    bounds, framing, the light fits), and nothing edits the scene's arrays while a frame is drawn.
    The memo holds each array, so its id cannot be reused within the scope; it is per thread (the
    viewer's workers render on their own) and nests (the outermost scope owns it)."""

    def __enter__(self):
        self.owner = getattr(_SCOPE, "memo", None) is None
        if self.owner:
            _SCOPE.memo = {}
        return self

    def __exit__(self, *exc):
        if self.owner:
            _SCOPE.memo = None


def fingerprint(a) -> tuple | None:
    """Content key of an array (or None): its layout and the XXH3-128 hash of its bytes. A view
    (e.g. an image's first three channels) is keyed on its layout within the contiguous array it
    views and that array's bytes, so it is never copied; an edit anywhere in that array counts.
    Inside a :class:`frame_scope`, each array object is hashed once."""
    if a is None:
        return None
    memo = getattr(_SCOPE, "memo", None)
    if memo is not None and type(a) is np.ndarray:
        hit = memo.get(id(a))
        if hit is not None and hit[0] is a:
            return hit[1]
        fp = _fingerprint(a)
        memo[id(a)] = (a, fp)
        return fp
    return _fingerprint(a)


def _fingerprint(a) -> tuple:
    a = np.asarray(a)
    owner = a
    while isinstance(owner.base, np.ndarray):
        owner = owner.base
    if not owner.flags.c_contiguous:
        owner = a if a.flags.c_contiguous else np.ascontiguousarray(a)
    # (the addresses only for a view: __array_interface__ builds a dict per call)
    offset = 0 if owner is a else a.__array_interface__["data"][0] - owner.__array_interface__["data"][0]
    return (a.shape, a.dtype.str, a.strides, offset, owner.nbytes, _digest(owner))


_MEMO: dict = {}  # (name, id(first array), params) -> (content key of the arrays, value)
_MEMO_KEEP = 64
_MEMO_LOCK = threading.Lock()


def memo_by_content(name: str, arrays: tuple, params, compute, keep: int | None = None):
    """``compute()``, a function of the CONTENT of ``arrays`` (and of the hashable ``params``) only,
    remembered until that content changes: each call fingerprints the arrays (cheap: a pass of
    XXH3 over their bytes, none for immutable ones) instead of recomputing what is derived from
    them (a mesh's bounds, its head vertices, its positions in float64). The slot is chosen by the
    first array's id, but a value is returned only when the fingerprints equal those it was computed
    from, so a reused id or an in-place edit costs a recomputation, never a stale value. Values are
    shared between callers: return them read-only or copy them. ``keep``: at most this many values
    of ``name`` at once (the oldest dropped first), for values too large for the shared _MEMO_KEEP slots
    (the interreflection's merged hits: ~50-80 MB each on a head)."""
    key = tuple(fingerprint(a) for a in arrays)
    slot = (name, id(arrays[0]), params)
    hit = _MEMO.get(slot)
    if hit is not None and hit[0] == key:
        return hit[1]
    value = compute()
    with _MEMO_LOCK:  # the viewer's worker threads may call in too
        if keep is not None:
            same = [s for s in _MEMO if s[0] == name and s != slot]
            for s in same[:max(len(same) - int(keep) + 1, 0)]:
                _MEMO.pop(s)
        if slot not in _MEMO and len(_MEMO) >= _MEMO_KEEP:
            _MEMO.pop(next(iter(_MEMO)))
        _MEMO[slot] = (key, value)
    return value


def read_only(a: np.ndarray) -> np.ndarray:
    """``a`` flagged read-only (for values shared through memo_by_content)."""
    a.flags.writeable = False
    return a


def _texture(t):
    return None if t is None else (fingerprint(t.data), tuple(t.wrap), t.filters, int(t.texcoord),
                                   fingerprint(t.transform))


def _mesh(m) -> tuple:
    return tuple(fingerprint(getattr(m, k)) for k in ("positions", "normals", "uvs", "indices", "tangents", "uvs1"))


def _surface(s) -> tuple:
    """A non-skin surface: its geometry, maps and factors (dermis.scene.model.Surface)."""
    mat = s.material
    return (_mesh(s.mesh), tuple(_texture(t) for t in mat.maps().values()), mat.base_color, mat.metallic, mat.roughness,
            mat.normal_scale, mat.occlusion_strength, mat.emissive, mat.alpha_mode, mat.alpha_cutoff, mat.double_sided)


def light_geometry(L) -> tuple:
    """What a light's shadow map depends on."""
    return (L.kind, tuple(L.direction), tuple(L.position), L.spot_angle_deg, L.cast_shadows)


def light_state(L) -> tuple:
    """Everything about a light that the image depends on."""
    return light_geometry(L) + (tuple(L.color), L.intensity, L.spot_blend, L.shadow_softness, L.shadow_bias)


def scene_inputs(scene, *, irradiance_size: int, epoch: int) -> dict:
    """The inputs of PRODUCTS for one frame: each a plain value or a content key."""
    m, mat, env = scene.mesh, scene.material, scene.environment
    return {
        "mesh": _mesh(m),
        "surfaces": [_surface(s) for s in getattr(scene, "surfaces", [])],
        "scale": float(scene.mm_per_unit),
        "material_maps": (_texture(mat.albedo), _texture(mat.normal_map), _texture(mat.specular_map),
                          _texture(mat.roughness_map), tuple(mat.albedo_color),
                          mat.roughness if mat.roughness_map is None else None),
        "material_scalars": (mat.normal_strength, mat.roughness, mat.rho_s, mat.specular_map_bias,
                             mat.specular_map_scale, mat.mix),
        "light_geometry": [light_geometry(L) for L in scene.lights],
        "lights": [light_state(L) for L in scene.lights],
        "environment": (tuple(env.color), env.intensity, _texture(env.image), float(env.rotation_deg)),
        "environment_occlusion": bool(env.occlusion),
        "profile": (fingerprint(np.asarray(scene.profile.variances_mm2, np.float64)),
                    fingerprint(np.asarray(scene.profile.weights, np.float64)), scene.skin_color),
        "irradiance_size": int(irradiance_size),
        "epoch": int(epoch),
        "interreflection": bool(getattr(scene, "interreflection", True)),
        "translucency_light_path": bool(getattr(scene, "translucency_light_path", False)),
        "directional_albedo": bool(getattr(scene, "directional_albedo", True)),
    }


def _product_key(names, reprs: dict) -> str:
    h = hashlib.sha1()
    for n in names:
        h.update(n.encode())
        h.update(reprs[n])
    return h.hexdigest()


def product_keys(inputs: dict) -> dict:
    """One hex key per product of PRODUCTS, from the inputs it declares."""
    reprs = {n: repr(v).encode() for n, v in inputs.items()}  # each input written out once
    return {product: _product_key(names, reprs) for product, names in PRODUCTS.items()}


class ProductKeys:
    """:func:`product_keys` with memory, for a Renderer's frames: an input equal (as a value) to
    the last call's is not written out again, and a product none of whose inputs changed keeps its
    key: a camera-only frame writes out nothing, a frame whose lights moved only the light inputs."""

    def __init__(self):
        self._inputs = {}  # name -> the value last written out
        self._reprs = {}  # name -> repr(value).encode()
        self._keys = {}  # product -> key

    def __call__(self, inputs: dict) -> dict:
        last = self._inputs
        changed = [n for n, v in inputs.items() if n not in last or last[n] != v]
        if changed:
            for n in changed:
                last[n] = inputs[n]
                self._reprs[n] = repr(inputs[n]).encode()
            changed = set(changed)
            for product, names in PRODUCTS.items():
                if product not in self._keys or not changed.isdisjoint(names):
                    self._keys[product] = _product_key(names, self._reprs)
        return dict(self._keys)
