"""The texel thickness bake (dermis.geometry.thickness) as a texture in the mesh's texture-space
layout: rgba32f, (u, v) of the far face, thickness in mm, weight; nearest filtering (a far face's
(u, v) must not be blended across islands). The ray cast along -N is done once per product key
"thickness" (dermis.invalidation: mesh, scale, irradiance size); where it finds no far face the
key light's path completes it, and the two are smoothed (geometry.thickness.translucency_thickness),
once per bake_key (the same and the key light's geometry)."""

from __future__ import annotations

from collections import OrderedDict

import moderngl
import numpy as np

# CPU bakes by (product key "thickness", size): techniques that read the bake at the same size
# (ssss and preintegrated, at half the irradiance size) share one ray cast instead of one each
_BAKES: OrderedDict = OrderedDict()
_MAX_BAKES = 6


def _cached(key, make):
    bake = _BAKES.get(key)
    if bake is None:
        bake = make()
        _BAKES[key] = bake
        while len(_BAKES) > _MAX_BAKES:
            _BAKES.popitem(last=False)
    else:
        _BAKES.move_to_end(key)
    return bake


def bake_key(frame, size: int) -> tuple:
    """What the bake depends on: the product key "thickness" (mesh, scale, irradiance size), the size,
    and, with the scene's ``translucency_light_path``, the key light's geometry (its colour and
    intensity only matter through which light is key)."""
    from dermis.geometry.thickness import key_light
    from dermis.invalidation import light_geometry

    if not getattr(frame.scene, "translucency_light_path", False):
        return frame.keys["thickness"], int(size), "along -N"  # no light in it: baked once per mesh
    L = key_light(frame.scene.lights)
    return frame.keys["thickness"], int(size), None if L is None else light_geometry(L)


def _bake(frame, size: int) -> np.ndarray:
    """The bake along -N and the UV islands (per mesh), completed along the key light where the scene
    asks for it (per key light geometry), smoothed."""
    from dermis.geometry.thickness import texel_thickness, translucency_thickness, uv_islands

    sc = frame.scene
    light_path = bool(getattr(sc, "translucency_light_path", False))

    def along_normal():  # the ray cast, also kept on disk: every process that renders the mesh needs it
        return _stored_bake(sc, frame.keys["thickness"], int(size),
                            lambda: (texel_thickness(sc.mesh, size, sc.mm_per_unit), uv_islands(sc.mesh, size))
                            + texel_maps(sc.mesh, size))

    normal, islands, _, _ = _cached(("normal", frame.keys["thickness"], int(size)), along_normal)
    bake, _ = _cached(("lit",) + bake_key(frame, size),
                      lambda: translucency_thickness(sc.mesh, size, sc.mm_per_unit, sc.lights, along_normal=normal,
                                                     islands=islands, light_path=light_path, unsmoothed=True))
    return bake, islands >= 0


def texel_maps(mesh, size: int) -> tuple:
    """(size, size, 3) float32 each, row 0 = top: the layout's texel centres' positions (scene units) and
    interpolated unit normals (geometry.thickness._texels), 0 where no triangle covers the texel. Kept
    on disk with the bake along -N: rasterising the head's layout at 512^2 takes ~1 s on llvmpipe's CPU."""
    from dermis.geometry.thickness import _texels

    S = int(size)
    _, _, _, _, _, cov, p, n = _texels(mesh, S)
    P = np.zeros((S * S, 3), np.float32)
    N = np.zeros((S * S, 3), np.float32)
    P[cov], N[cov] = p, n
    return P.reshape(S, S, 3), N.reshape(S, S, 3)


# --- The far face's points ---------------------------------------------------------------------
# Kept here, not in geometry/thickness.py, whose source keys the stored ray cast (_stored_bake).
# common/transmittance.glsl shadows a thin part's far face over a box of the light's lateral spread
# about A = P - h N: its taps read, at texels of the layout about P's, the point where THAT texel's
# ray left the tissue, and keep those that lie within h / 2 of A along N (round 23, shadowbox23).
# Stored weighted (x valid, valid), so that a bilinear lookup of the texture is the weighted mean of
# the valid neighbours' points: across a texel whose neighbour's ray left through another surface
# the mean lies between the two, and the box's depth test drops it when they are far apart.


def far_face_points(completed: np.ndarray, along_normal: np.ndarray, texels, mm_per_unit: float) -> np.ndarray:
    """(S, S, 4) float32, row 0 = top (v = 1): the far face's point X (scene units) behind each texel times
    the weight, and the weight, from the bake before smoothing (``completed``: translucency_thickness's
    unsmoothed, thickness in mm) and the texels' positions and normals (``texels``: texel_maps): where the
    ray along -N left the tissue (``along_normal``'s weight > 0) X = P - d N, d its thickness (the rays'
    median); where the key light's path completes it, the position of its exit E's texel (weighted as
    there; none where E's texel is not covered)."""
    S = completed.shape[0]
    tp, tn = (np.asarray(t, np.float64).reshape(-1, 3) for t in texels)
    covered = np.any(tn != 0.0, axis=1)
    c = completed.reshape(-1, 4).astype(np.float64)
    w = np.where(covered, c[:, 3], 0.0)
    own = along_normal.reshape(-1, 4)[:, 3] > 0.0
    X = tp - tn * (c[:, 2:3] / float(mm_per_unit))
    path = ~own & (w > 0.0)  # the key light's exit E: its texel's position
    ix = np.clip((c[path, 0] * S).astype(np.int64), 0, S - 1)
    iy = np.clip(((1.0 - c[path, 1]) * S).astype(np.int64), 0, S - 1)
    e = iy * S + ix
    X[path] = tp[e]
    w[path] = np.where(covered[e], w[path], 0.0)
    out = np.zeros((S * S, 4), np.float32)
    out[:, 0:3] = X * w[:, None]
    out[:, 3] = w
    return out.reshape(S, S, 4)


def _far_face(frame, size: int) -> np.ndarray:
    """far_face_points of the frame's mesh (per bake_key, as the smoothed bake)."""
    _bake(frame, size)  # the ray casts, cached
    normal, _, tp, tn = _BAKES[("normal", frame.keys["thickness"], int(size))]
    _, completed = _BAKES[("lit",) + bake_key(frame, size)]
    return _cached(("far face",) + bake_key(frame, size),
                   lambda: far_face_points(completed, normal, (tp, tn), frame.scene.mm_per_unit))


def _stored_bake(scene, product_key: str, size: int, make):
    """``make()``'s (bake along -N (S, S, 4) float32, UV islands (S, S) int, texel_maps' positions and normals
    (S, S, 3) float32 each) through dermis's disk cache
    (geometry.bake_cache; DERMIS_CACHE_DIR, off with "off"), keyed by the product key "thickness" (the mesh's
    arrays, scale, irradiance size), the size, the texture-space UVs the bake rasterises (not in the mesh's
    key) and the source of the modules that compute it. 0.55-0.8 s a bake of the head at 512^2, 1.4-1.9 s
    for a sphere at load 5: each `dermis` process that renders paid it again."""
    import hashlib

    from dermis.geometry import atlas, bake_cache, rasterize, raycast, texture_space, thickness
    from dermis.invalidation import fingerprint

    source = bake_cache.source_key(thickness, texture_space, rasterize, raycast, atlas)
    if source is None:  # no source to key it by: made, not stored
        return make()
    uv = fingerprint(np.asarray(texture_space.texture_space_uvs(scene.mesh)))
    key = hashlib.sha256(repr((product_key, size, uv, source)).encode()).hexdigest()
    path = bake_cache.cache_path("thickness", key)
    got = bake_cache.load({}, key, path, {"normal": (size, size, 4), "islands": (size, size),
                                          "texel_p": (size, size, 3), "texel_n": (size, size, 3)}, 1)
    if got is not None and got["normal"].dtype == np.float32:
        return got["normal"], got["islands"], got["texel_p"], got["texel_n"]
    normal, islands, texel_p, texel_n = make()
    bake_cache.store(path, {"normal": normal, "islands": islands, "texel_p": texel_p, "texel_n": texel_n})
    return normal, islands, texel_p, texel_n


class ThicknessTexture:
    """One technique's copy of the bake; ``get`` rebuilds it when the frame's key or the size changes.

    ``filtered=False``: rgba32f, nearest (tsd reads the far face's (u, v)); weight -1 where no
    triangle covers the texel. ``filtered=True``:
    rg32f (thickness x valid, valid), bilinear, for techniques that read the thickness alone at a
    screen pixel (thickness = r / g where g > 0): nearest texels showed as blocks on a close-up ear."""

    def __init__(self, ctx, filtered: bool = False):
        self.ctx = ctx
        self.filtered = filtered
        self.tex = None
        self.far_face = None  # filtered: the far face's points (far_face_points), rgba32f, bilinear
        self.key = None

    def get(self, frame, size: int):
        """The texture for ``frame`` at size x size; appends "thickness" to frame.passes_run when baked."""
        key = bake_key(frame, size)
        if key != self.key or self.tex is None:
            with frame.timer("thickness"):
                bake, covered = _bake(frame, size)
                self.release()
                if self.filtered:
                    data = np.stack([bake[..., 2] * bake[..., 3], bake[..., 3]], -1)
                    self.tex = self.ctx.texture((size, size), 2, dtype="f4")
                    self.tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
                    self.far_face = self.ctx.texture((size, size), 4, dtype="f4")
                    self.far_face.filter = (moderngl.LINEAR, moderngl.LINEAR)
                    self.far_face.repeat_x = self.far_face.repeat_y = False
                    self.far_face.write(np.ascontiguousarray(_far_face(frame, size)[::-1], np.float32).tobytes())
                else:  # uncovered texels: weight -1 (tsd/translucency.frag blends the covered neighbours)
                    data = bake.copy()
                    data[~covered, 3] = -1.0
                    self.tex = self.ctx.texture((size, size), 4, dtype="f4")
                    self.tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                self.tex.repeat_x = self.tex.repeat_y = False
                self.tex.write(np.ascontiguousarray(data[::-1], np.float32).tobytes())  # GL rows: v = 0 first
            self.key = key
            frame.passes_run.append("thickness")
        return self.tex

    def release(self):
        if self.tex is not None:
            self.tex.release()
        if self.far_face is not None:
            self.far_face.release()
        self.tex = None
        self.far_face = None
        self.key = None
