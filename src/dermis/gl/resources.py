"""GPU copies of a scene: vertex/index buffers, material textures, light and shadow uniforms.

Texture upload flips image rows: image arrays keep row 0 at the top (as files do) while GL puts
the first uploaded row at t = 0, and dermis UVs have v = 0 at the bottom of the image.
"""

from __future__ import annotations

import contextvars
import struct
from contextlib import contextmanager

import numpy as np

from dermis.camera import light_matrices, normalize
from dermis.environment import environment_sh
from dermis.geometry.hull import extreme_points
from dermis.geometry.texture_space import corner_surface_metric, texture_space_uvs
from dermis.geometry.visibility import open_visibility
from dermis.images import as_rgb
from dermis.invalidation import memo_by_content, read_only
from dermis.scene.model import mean_skin_albedo, skin_albedo_scale
from dermis.techniques.shared import LIGHT_TYPES, MAX_LIGHTS, SHARED_SAMPLERS

VERTEX_FORMAT = "3f 3f 2f 4f 2f 4f 3f 3f 3f 2f"
# in_uv: the asset's UVs (material maps); in_uv_ts: the texture-space set (geometry/texture_space.py);
# in_visibility: (ambient occlusion, visible fraction of the environment irradiance RGB) of
# geometry/visibility.py, location 6, and in_blocked_sh0..2, the L2 SH of the directions the mesh blocks
# (the specular occlusion), locations 8-10: one block of 13 floats (VertexVisibility.attribute);
# in_uv1: the asset's second UV set (TEXCOORD_1; zeros without one), location 7
VERTEX_ATTRS = ("in_position", "in_normal", "in_uv", "in_tangent", "in_uv_ts", "in_visibility", "in_blocked_sh0",
                "in_blocked_sh1", "in_blocked_sh2",
                "in_uv1")


def vertex_attributes(mesh) -> tuple[np.ndarray, np.ndarray]:
    """The vertex attributes of ``mesh`` before and after in_visibility (VERTEX_FORMAT order)."""
    m = mesh
    uv_ts = texture_space_uvs(m)
    before = np.concatenate([m.positions, m.normals, m.uvs, m.tangents, uv_ts], axis=1).astype(np.float32)
    after = np.zeros((len(m.positions), 2), np.float32) if m.uvs1 is None else np.asarray(m.uvs1, np.float32)
    return before, after


def interleave(attributes: tuple, visibility) -> bytes:
    before, after = attributes
    return np.ascontiguousarray(np.concatenate([before, np.asarray(visibility, np.float32), after], axis=1)).tobytes()


# the image of each triangle's barycentric frame (common/mesh_varyings.glsl: how far off its triangle a
# fragment's pixel centre lies): its image unit, and triangles per row (two rgba32f texels each)
MESH_TRIANGLE_IMAGE = 0
MESH_TRIANGLES_PER_ROW = 2048  # common/mesh_varyings.glsl: the same


def triangle_frames(positions, indices) -> np.ndarray:
    """(rows, MESH_TRIANGLES_PER_ROW * 8) float32: for triangle t = (a, b, c) at texels (2 (t mod R),
    t div R) and the next, the rows G1, G2 of the affine map p -> (lambda_b, lambda_c), the
    barycentrics of p's projection into the triangle's plane: lambda_b = dot(G1, (p, 1)), lambda_a =
    1 - lambda_b - lambda_c. With e1 = b - a, e2 = c - a and the Gram matrix D = [[e1.e1, e1.e2],
    [e1.e2, e2.e2]]: (g1, g2) = D^-1 (e1, e2) (least squares: exact for p in the plane), the fourth
    components -g.a. A triangle of zero area gets zeros (every point at lambda = (1, 0, 0): its
    fragments are moved nowhere, s = 0). In float64, in blocks of 65,536 triangles (a whole mesh's
    corners in float64 would be ~0.9 GB at 12 million triangles)."""
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    pos = np.asarray(positions)
    n = -(-len(tri) // MESH_TRIANGLES_PER_ROW)
    out = np.zeros((n * MESH_TRIANGLES_PER_ROW, 8), np.float32)
    for start in range(0, len(tri), 65536):
        p = pos[tri[start:start + 65536]].astype(np.float64)
        a, e1, e2 = p[:, 0], p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        det = d11 * d22 - d12 * d12
        ok = det > 1e-12 * np.maximum(d11 * d22, 1e-300)
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
        g1 = (d22[:, None] * e1 - d12[:, None] * e2) * inv
        g2 = (d11[:, None] * e2 - d12[:, None] * e1) * inv
        out[start:start + len(p)] = np.concatenate([g1, -(g1 * a).sum(1, keepdims=True), g2,
                                                    -(g2 * a).sum(1, keepdims=True)], axis=1)
    return out.reshape(n, -1)


def triangle_frame_image(ctx, positions, indices):
    """:func:`triangle_frames` as an rgba32f texture (read by imageLoad)."""
    import moderngl

    data = triangle_frames(positions, indices)
    tex = ctx.texture((data.shape[1] // 4, data.shape[0]), 4, np.ascontiguousarray(data).tobytes(), dtype="f4")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


def vertex_content(vbo, prog) -> tuple:
    """(buffer, format, attributes...) of a VERTEX_FORMAT buffer for ``prog``: attributes the program
    does not use are skipped as padding ("3x4" = 3 floats)."""
    parts, used = [], []
    for f, a in zip(VERTEX_FORMAT.split(), VERTEX_ATTRS):
        if a in prog:
            parts.append(f)
            used.append(a)
        else:
            parts.append(f"{f[0]}x4")
    return (vbo, " ".join(parts), *used)


def release_mesh_objects(owner) -> None:
    """Release a GPU mesh's VAOs (``_vaos``: key -> (vao, program)), ``textures``, ``vbo``, ``ibo``."""
    for v, _ in owner._vaos.values():
        v.release()
    owner._vaos = {}
    for t in owner.textures.values():
        t.release()
    owner.textures = {}
    owner.vbo.release()
    owner.ibo.release()


_IDENTITY_UV = np.ascontiguousarray(np.eye(3, dtype=np.float32)).tobytes()


def map_uniforms(prog, prefix: str, texture) -> None:
    """A map's addressing (dermis.scene.model.Texture texcoord / transform): u<prefix>UV (mat3,
    column-major) and u<prefix>Set; identity and set 0 without a map."""
    if prog.get(f"u{prefix}UV", None) is not None:
        uv = _IDENTITY_UV if texture is None else np.ascontiguousarray(texture.uv_matrix().T, np.float32).tobytes()
        set_uniform(prog, f"u{prefix}UV", uv)
    set_uniform(prog, f"u{prefix}Set", 0 if texture is None else int(texture.texcoord))


def uniform_bytes(u, value) -> bytes:
    """What writing ``value`` to the uniform ``u`` writes: bytes as given, a numpy array as int32 or
    float32 (an array uniform's rows past the length the compiler kept are dropped), anything else
    packed as moderngl's ``Uniform.value`` packs it."""
    if isinstance(value, (bytes, bytearray)):
        return bytes(value)
    if isinstance(value, np.ndarray):
        arr = np.ascontiguousarray(value, dtype=np.int32 if value.dtype.kind in "iu" else np.float32)
        n = getattr(u, "array_length", 1)
        if arr.ndim >= 2 and n < len(arr):  # the compiler may trim unused array tails
            arr = arr[:n]
        return arr.tobytes()
    if u.array_length > 1:
        if u.dimension > 1:
            return b"".join(struct.pack(u.fmt, *row) for row in value)
        return b"".join(struct.pack(u.fmt, item) for item in value)
    if u.dimension > 1:
        return struct.pack(u.fmt, *value)
    return struct.pack(u.fmt, value)


def set_uniform(prog, name, value):
    """Set a uniform if the program uses it (the GLSL compiler drops unused ones).

    A program keeps its uniforms' values, so a value equal to the one last written through this
    function is not written again: the uniform's ``extra`` holds the bytes written (moderngl's slot
    for its user's data; dermis writes every uniform of its programs through here). ``value``:
    a number, a tuple or list (as ``Uniform.value`` takes it), a numpy array or raw bytes."""
    u = prog.get(name, None)  # a dict lookup; ``name in prog`` walks every member of the program
    if u is None:
        return
    data = uniform_bytes(u, value)
    if u.extra != data:
        u.write(data)
        u.extra = data


_RECORDING = contextvars.ContextVar("dermis_texture_binds", default=None)


def use_texture(tex, unit: int) -> None:
    """Bind ``tex`` to texture ``unit`` (what every dermis sampler binding goes through, so that
    :func:`prepared` can replay it)."""
    tex.use(unit)
    binds = _RECORDING.get()
    if binds is not None:
        binds.append((tex, unit))


def nearest_sampler(ctx):
    """The sampler object for texel reads at texel centres (common/texel.glsl TEXEL) of textures
    whose own filter is linear: NEAREST, CLAMP_TO_EDGE, so a read gives the texel (the border
    clamped) bit for bit, as texelFetch of the clamped texel did, and costs less on llvmpipe
    (round 23, chain23). Bound on a unit for the passes that read so, cleared after them: later
    passes read the textures' own filters."""
    import moderngl

    return ctx.sampler(filter=(moderngl.NEAREST, moderngl.NEAREST), repeat_x=False, repeat_y=False)


def prepared(prog, slot: str, key, setup) -> None:
    """``setup(prog)`` (uniform writes through set_uniform, texture binds through use_texture),
    skipped when this program's ``slot`` last ran it with an equal ``key``: the program still holds
    those uniforms, and only the textures it bound are bound again (other passes use the same
    units). ``key`` must change whenever anything ``setup`` writes would; it may hold the objects
    the values come from (compared by identity, kept alive by the memo, so no id is reused).
    Nothing else may write the uniforms ``setup`` writes on ``prog``."""
    states = prog.__dict__.setdefault("_dermis_prepared", {})
    state = states.get(slot)
    if state is not None and state[0] == key:
        for tex, unit in state[1]:
            tex.use(unit)
        return
    binds = []
    token = _RECORDING.set(binds)
    try:
        setup(prog)
    finally:
        _RECORDING.reset(token)
    states[slot] = (key, binds)


def mat_bytes(m) -> bytes:
    """A numpy 4x4 (row-major math) as GLSL column-major bytes."""
    return np.ascontiguousarray(np.asarray(m, np.float32).T).tobytes()


def read_texture(tex) -> np.ndarray:
    """A float texture (f2 or f4) read back as float32 (H, W, C), row 0 = top (the image order)."""
    w, h = tex.size
    dt = {"f2": np.float16, "f4": np.float32}[tex.dtype]
    data = np.frombuffer(tex.read(), dt).reshape(h, w, tex.components).astype(np.float32)
    return data[::-1].copy()


_MIPMAP_FILTERS = (9984, 9985, 9986, 9987)  # GL *_MIPMAP_* min filters (glTF 2.0 sampler.minFilter)


def upload_texture(ctx, data: np.ndarray, *, components=None, dtype="f4", mipmaps=True, repeat=False, wrap=None,
                   filters=None):
    """Upload an (H, W, C) float image (row 0 = top) as a linear-filtered texture. ``wrap``: per axis
    ("clamp" | "repeat", s then t; overrides ``repeat``); ``filters``: (min, mag) GL enums of a
    material map's sampler (glTF sampler), None = trilinear with mipmaps."""
    arr = np.asarray(data, np.float32)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    c = components or arr.shape[2]
    if arr.shape[2] < c:
        pad = np.ones(arr.shape[:2] + (c - arr.shape[2],), np.float32)
        arr = np.concatenate([arr, pad], axis=2)
    arr = np.ascontiguousarray(arr[::-1, :, :c])
    if dtype == "f1":
        payload = np.clip(arr * 255.0 + 0.5, 0, 255).astype(np.uint8).tobytes()
    elif dtype == "f2":
        payload = arr.astype(np.float16).tobytes()
    else:
        payload = arr.tobytes()
    tex = ctx.texture((arr.shape[1], arr.shape[0]), c, payload, dtype=dtype)
    tex.repeat_x = tex.repeat_y = repeat
    if wrap is not None:
        tex.repeat_x, tex.repeat_y = (w == "repeat" for w in wrap)
    if filters is not None:
        lo, hi = filters
        if lo is None or lo in _MIPMAP_FILTERS:
            tex.build_mipmaps()
        tex.filter = (lo if lo is not None else ctx.LINEAR_MIPMAP_LINEAR, hi if hi is not None else ctx.LINEAR)
    elif mipmaps:
        tex.build_mipmaps()
        tex.filter = (ctx.LINEAR_MIPMAP_LINEAR, ctx.LINEAR)
        tex.anisotropy = 8.0
    else:
        import moderngl

        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    return tex


SPECULAR_MAP_ANISOTROPY = 1.0
"""The specular intensity map's anisotropic filtering in every pass (the other maps: 8x in the
screen passes, 1x in texture space: :func:`maps_without_anisotropy`)."""


@contextmanager
def maps_without_anisotropy(gpu, surfaces: bool = True):
    """Within the block the scene's material maps (and, with ``surfaces``, the non-skin surfaces')
    are filtered trilinearly, without anisotropy; their own setting comes back after it. For
    passes that gain nothing from anisotropic filtering (a texture-space raster, whose footprint
    in the maps is square) or trade it for speed (the viewer's reduced frames): Mesa's llvmpipe
    filters every lookup of an anisotropic sampler with its elliptical kernel, a textureLod
    included, at 3-6x the cost of a trilinear one (benchmarks/RESULTS.md, "Passes (round 5)")."""
    maps = [] if gpu is None else [*gpu.textures.values()]
    if surfaces and gpu is not None:
        maps += [t for s in gpu.surfaces for t in s.textures.values()]
    changed = [(t, t.anisotropy) for t in maps if t.anisotropy > 1.0]  # unset (0) filters as 1
    for t, _ in changed:
        t.anisotropy = 1.0
    try:
        yield
    finally:
        for t, a in changed:
            t.anisotropy = a


class GpuScene:
    """Mesh buffers and material textures of one Scene on one context."""

    def __init__(self, ctx, scene):
        self.ctx = ctx
        self.scene = scene
        m = scene.mesh
        self._attributes = vertex_attributes(m)
        self.vbo = ctx.buffer(self._interleave(open_visibility(len(m.positions), m.normals)))
        self.visibility_uploaded = False  # set_visibility() not called yet: open sky
        self.ibo = ctx.buffer(np.ascontiguousarray(m.indices, np.uint32).tobytes())
        self._triangle_uv_ts = None  # triangle_uv_ts(): made on first use (tsd's final pass)
        self._corner_metric = None  # corner_metric(): the same
        # each triangle's barycentric frame (the screen passes' move of far-extrapolated MSAA edge fragments,
        # common/mesh_varyings.glsl), made with the mesh: a texture made at a later frame would read as a
        # growing GPU object count (tests/test_viewer.py)
        self._triangle_frames = triangle_frame_image(ctx, m.positions, m.indices)
        self._vaos = {}
        self.textures = {}
        self.upload_material()
        from dermis.gl.surfaces import GpuSurface

        # the non-skin surfaces (glTF metallic-roughness): buffers and maps of their own
        self.surfaces = [GpuSurface(ctx, s) for s in getattr(scene, "surfaces", [])]

    def _interleave(self, visibility) -> bytes:
        return interleave(self._attributes, visibility)

    def set_visibility(self, visibility):
        """Replace in_visibility and in_blocked_sh0..2 ((n, 13): ambient occlusion, visible fraction RGB, the
        blocked directions' L2 SH; VertexVisibility.attribute) in place: VAOs stay valid."""
        self.vbo.write(self._interleave(visibility))
        self.visibility_uploaded = True

    def triangle_uv_ts(self):
        """A buffer of each triangle's three texture-space UVs, float32 (u0, v0, u1, v1, u2, v2) in the
        index buffer's order (triangle i at 24 i bytes: a std430 vec2 array, tsd/triangle_uv.glsl),
        made on first use: a fragment of triangle gl_PrimitiveID keeps its texture-space reads on
        that triangle's UVs."""
        if self._triangle_uv_ts is None:
            m = self.scene.mesh
            uv = np.asarray(texture_space_uvs(m), np.float32)[np.asarray(m.indices, np.int64).reshape(-1)]
            self._triangle_uv_ts = self.ctx.buffer(np.ascontiguousarray(uv).tobytes())
        return self._triangle_uv_ts

    def corner_metric(self):
        """A buffer of each triangle's three corners' surface metric in the texture-space layout,
        float32 (E, F, G, 0) per corner in the index buffer's order (triangle i at 48 i bytes: a std430
        vec4 array; dermis.geometry.texture_space.corner_surface_metric), made on first use: tsd's
        final pass interpolates it for a texel density that is continuous across the triangles' edges."""
        if self._corner_metric is None:
            m = self.scene.mesh
            metric = corner_surface_metric(m.positions, texture_space_uvs(m), m.indices)
            self._corner_metric = self.ctx.buffer(np.ascontiguousarray(metric).tobytes())
        return self._corner_metric

    def triangle_frames(self):
        """Each triangle's barycentric frame (:func:`triangle_frame_image`): the screen passes' move of
        far-extrapolated edge fragments onto their triangle (common/mesh_varyings.glsl)."""
        return self._triangle_frames

    def vertex_content(self, prog) -> tuple:
        """(buffer, format, attributes...) of the vertex buffer for ``prog`` (:func:`vertex_content`)."""
        return vertex_content(self.vbo, prog)

    def vao(self, prog):
        # keyed on the program object, held in the entry: its id cannot be reused while cached
        key = id(prog)
        if key not in self._vaos:
            self._vaos[key] = (self.ctx.vertex_array(prog, [self.vertex_content(prog)], self.ibo), prog)
        return self._vaos[key][0]

    def upload_material(self):
        mat = self.scene.material
        for t in self.textures.values():
            t.release()
        self.textures = {}

        def sampler(t):  # the map's own wrap modes and filters (glTF samplers)
            return {"wrap": t.wrap, "filters": t.filters}

        if mat.albedo is not None:
            self.textures["albedo"] = upload_texture(self.ctx, as_rgb(mat.albedo.data), components=3, dtype="f2",
                                                     **sampler(mat.albedo))
        else:
            self.textures["albedo"] = upload_texture(self.ctx, np.array([[mat.albedo_color]], np.float32), mipmaps=False)
        if mat.normal_map is not None:
            self.textures["normal"] = upload_texture(self.ctx, mat.normal_map.data[:, :, :3], components=3, dtype="f1",
                                                     **sampler(mat.normal_map))
        else:
            self.textures["normal"] = upload_texture(self.ctx, np.array([[[0.5, 0.5, 1.0]]], np.float32), mipmaps=False)
        if mat.specular_map is not None:
            self.textures["specular"] = upload_texture(self.ctx, mat.specular_map.data[:, :, :1], components=1, dtype="f1",
                                                     **sampler(mat.specular_map))
            # trilinear, not anisotropic: a scalar weight of the specular lobe, smooth at the scale of a
            # grazing footprint's long axis; on the head at 768 px its 8x filtering moved the image by
            # at most 0.007 (display) and cost 8% of tsd's final pass on llvmpipe, whose elliptical
            # filter runs on every lookup (benchmarks/RESULTS.md, round 9, branch screen9)
            self.textures["specular"].anisotropy = SPECULAR_MAP_ANISOTROPY
        else:
            self.textures["specular"] = upload_texture(self.ctx, np.array([[[1.0]]], np.float32), mipmaps=False)
            # no map: rho_s as given (bias + scale * 1 would rescale it)
        self.has_specular_map = mat.specular_map is not None
        # mean albedo on the skin (texels brighter than 2%), for profile-driven skin colour
        self.albedo_mean = mean_skin_albedo(mat)
        if mat.roughness_map is not None:
            self.textures["roughness"] = upload_texture(self.ctx, mat.roughness_map.data[:, :, :1], components=1, dtype="f2",
                                                     **sampler(mat.roughness_map))
        else:
            self.textures["roughness"] = upload_texture(self.ctx, np.array([[[mat.roughness]]], np.float32), mipmaps=False)

    def material_uniforms(self, prog):
        """The material's maps at their contract units (dermis.techniques.shared.Unit) and its scalars."""
        mat = self.scene.material
        for name, key in (("uAlbedoMap", "albedo"), ("uNormalMap", "normal"), ("uSpecularMap", "specular"),
                          ("uRoughnessMap", "roughness")):
            if prog.get(name, None) is not None:
                unit = int(SHARED_SAMPLERS[name])
                use_texture(self.textures[key], unit)
                set_uniform(prog, name, unit)
        for prefix, tex in (("Albedo", mat.albedo), ("Normal", mat.normal_map), ("Specular", mat.specular_map),
                            ("Roughness", mat.roughness_map)):
            map_uniforms(prog, prefix, tex)
        set_uniform(prog, "uNormalStrength", float(mat.normal_strength))
        set_uniform(prog, "uRhoS", float(mat.rho_s))
        set_uniform(prog, "uRoughness", float(mat.roughness))
        set_uniform(prog, "uHasRoughnessMap", 1.0 if mat.roughness_map is not None else 0.0)
        bias_scale = (mat.specular_map_bias, mat.specular_map_scale) if self.has_specular_map else (1.0, 0.0)
        set_uniform(prog, "uSpecMapBiasScale", tuple(float(x) for x in bias_scale))
        set_uniform(prog, "uMix", float(mat.mix))
        set_uniform(prog, "uAlbedoScale", tuple(float(x) for x in self.albedo_scale()))
        set_uniform(prog, "uMmPerUnit", float(self.scene.mm_per_unit))

    def albedo_scale(self) -> np.ndarray:
        """uAlbedoScale: 1, or (with scene.skin_color == "profile") the profile's total diffuse
        reflectance over the albedo map's mean on the skin (texels brighter than 2%)."""
        return skin_albedo_scale(self.scene, self.albedo_mean)

    def release(self):
        release_mesh_objects(self)
        if self._triangle_uv_ts is not None:
            self._triangle_uv_ts.release()
            self._triangle_uv_ts = None
        if self._corner_metric is not None:
            self._corner_metric.release()
            self._corner_metric = None
        if self._triangle_frames is not None:
            self._triangle_frames.release()
            self._triangle_frames = None
        for surface in getattr(self, "surfaces", []):
            surface.release()
        self.surfaces = []


class LightUniforms:
    """Packs the scene's lights (and shadow tiles) into the arrays of common/lights.glsl."""

    MAX_LIGHTS = MAX_LIGHTS

    def __init__(self, scene, shadow_atlas=None):
        lights = scene.lights[: self.MAX_LIGHTS]
        n = self.MAX_LIGHTS
        self.count = len(lights)
        self.pos_type = np.zeros((n, 4), np.float32)
        self.direction = np.zeros((n, 4), np.float32)
        self.radiance = np.zeros((n, 4), np.float32)
        self.spot = np.zeros((n, 4), np.float32)
        self.viewproj = np.zeros((n, 4, 4), np.float32)
        self.map_half_extent = np.zeros(n, np.float64)  # half a shadow map's width, scene units
        lo, hi = scene.bounds()
        # the frusta are fitted to every vertex drawn (skin first) in float64: their extents along a
        # light's axes are maxima of linear functions, held by the convex hull's vertices
        # (dermis.geometry.hull), found once per content of the meshes' own arrays
        arrays = (scene.mesh.positions, *(s.mesh.positions for s in scene.surfaces))
        points = memo_by_content("light_fit_points", arrays, len(arrays),
                                 lambda: read_only(extreme_points(np.concatenate(arrays))))
        for i, L in enumerate(lights):
            vp, eye, half = light_matrices(L, lo, hi, points)
            self.viewproj[i] = vp
            self.map_half_extent[i] = half
            pos = np.asarray(L.position, np.float32) if L.kind != "directional" else eye.astype(np.float32)
            self.pos_type[i] = (*pos, LIGHT_TYPES[L.kind])
            self.direction[i, :3] = normalize(L.direction)  # in float64: a direction past float32's range stays one
            self.radiance[i] = (*L.radiance_rgb(), 1.0 if L.cast_shadows else 0.0)
            outer = np.cos(np.radians(L.spot_angle_deg))
            inner = np.cos(np.radians(L.spot_angle_deg * (1 - L.spot_blend)))
            self.spot[i] = (outer, max(inner, outer + 1e-4), 0, 0)
        self.env_sh = environment_sh(scene.environment)
        self.lights = lights

    def apply(self, prog):
        """Write the lights' uniforms into ``prog``; their bytes are packed once per LightUniforms
        (and array length the compiler kept), not once per program and frame."""
        packed = self.__dict__.setdefault("_packed", {})
        set_uniform(prog, "uLightCount", self.count)
        for name, value in (("uLightPosType", self.pos_type), ("uLightDir", self.direction),
                            ("uLightRadiance", self.radiance), ("uLightSpot", self.spot),
                            ("uLightViewProj", self.viewproj), ("uEnvSH", self.env_sh)):
            u = prog.get(name, None)
            if u is None:
                continue
            key = (name, u.array_length)
            data = packed.get(key)
            if data is None:
                if name == "uLightViewProj":
                    data = b"".join(mat_bytes(m) for m in value[:u.array_length])
                else:
                    data = uniform_bytes(u, value)
                packed[key] = data
            set_uniform(prog, name, data)
