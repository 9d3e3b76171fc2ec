"""Surface samples and surface attributes for the offline reference (numpy + numba, no GL).

* :func:`surface_cells` - area-weighted points on the mesh: each triangle is cut into the cells
  of a square lattice of spacing ``h`` mm laid in its plane (random rotation and offset, seeded
  per triangle, so the set does not depend on the order of processing), each cell clipped to the
  triangle exactly. One sample per piece, at the piece's centroid, weighted by its area: an exact
  partition of the surface, so the quadrature (the midpoint rule) has no density fluctuations at
  triangle edges, is isotropic in millimetres however stretched the triangle or its UVs, and
  coarser lattices (:func:`coarsen`, the same lattice ``m`` times wider) are unions of finer pieces:
  their values are area-weighted means of the fine samples, i.e. cell averages, not point samples.
* :class:`SurfaceModel` - the mesh in millimetres with the attributes the real-time shaders
  interpolate (position, normal, UV, MikkTSpace tangent), evaluated at (triangle, barycentric)
  points exactly as the rasteriser interpolates them (barycentric = perspective-correct), and the
  material maps looked up as OpenGL does: bilinear, clamp-to-edge, texel centres at (i + 0.5) / W,
  v = 0 at the BOTTOM of the image (image row 0 is the top; dermis convention).

The reference uses the base level of each map (no mipmaps): pixels are supersampled instead.
"""

from __future__ import annotations

import numba
import numpy as np

from dermis.environment import environment_sh, equirect_radiance, irradiance_sh_eval
from dermis.images import as_rgb
from dermis.scene.model import skin_albedo_scale
from dermis.specular import rho_dt_table, roughness_to_y


@numba.njit(cache=True, inline="always")
def _hash_uniforms(seed, t):
    """Three uniforms in [0, 1) from (seed, triangle): splitmix64 (Steele, Lea & Flood 2014)."""
    x = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(t) * np.uint64(0xBF58476D1CE4E5B9)
    out = np.empty(3)
    for k in range(3):
        x = x + np.uint64(0x9E3779B97F4A7C15)
        z = x
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        out[k] = float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return out


@numba.njit(cache=True, inline="always")
def _clip(px, py, n, ax, ay, bx, by, qx, qy):
    """Sutherland-Hodgman: clip polygon (px, py)[:n] to the left of edge a -> b; result in (qx, qy)."""
    m = 0
    ex, ey = bx - ax, by - ay
    for k in range(n):
        x0, y0 = px[k], py[k]
        x1, y1 = px[(k + 1) % n], py[(k + 1) % n]
        d0 = ex * (y0 - ay) - ey * (x0 - ax)
        d1 = ex * (y1 - ay) - ey * (x1 - ax)
        if d0 >= 0.0:
            qx[m] = x0
            qy[m] = y0
            m += 1
        if (d0 >= 0.0) != (d1 >= 0.0):
            t = d0 / (d0 - d1)
            qx[m] = x0 + t * (x1 - x0)
            qy[m] = y0 + t * (y1 - y0)
            m += 1
    return m


@numba.njit(cache=True)
def _cells(v0, v1, v2, tris, h, seed, write, counts, offsets, tri_out, ij_out, bary_out, area_out):
    """Pass 1 (write=False): count the lattice cells that overlap each triangle. Pass 2: write
    each overlap (the square cell clipped to the triangle): its area and centroid."""
    px = np.empty(8)
    py = np.empty(8)
    qx = np.empty(8)
    qy = np.empty(8)
    for q in range(tris.shape[0]):
        t = tris[q]
        e1 = np.array([v1[t, 0] - v0[t, 0], v1[t, 1] - v0[t, 1], v1[t, 2] - v0[t, 2]])
        e2 = np.array([v2[t, 0] - v0[t, 0], v2[t, 1] - v0[t, 1], v2[t, 2] - v0[t, 2]])
        l1 = np.sqrt(e1[0] ** 2 + e1[1] ** 2 + e1[2] ** 2)
        nx = e1[1] * e2[2] - e1[2] * e2[1]
        ny = e1[2] * e2[0] - e1[0] * e2[2]
        nz = e1[0] * e2[1] - e1[1] * e2[0]
        area = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
        if area <= 0.0 or l1 <= 0.0:
            if not write:
                counts[q] = 0
            continue
        # the triangle in its plane (x along edge 1), then in the lattice's rotated frame
        cx = (e2[0] * e1[0] + e2[1] * e1[1] + e2[2] * e1[2]) / l1
        cy = 2.0 * area / l1
        r = _hash_uniforms(seed, t)
        ang = r[0] * 2.0 * np.pi
        ca, sa = np.cos(ang), np.sin(ang)
        tx = np.array([0.0, ca * l1, ca * cx + sa * cy])
        ty = np.array([0.0, -sa * l1, -sa * cx + ca * cy])
        det = tx[1] * ty[2] - tx[2] * ty[1]  # = 2 area > 0 (counter-clockwise)
        ox, oy = r[1] * h, r[2] * h
        i0 = int(np.floor((tx.min() - ox) / h))
        i1 = int(np.floor((tx.max() - ox) / h))
        j0 = int(np.floor((ty.min() - oy) / h))
        j1 = int(np.floor((ty.max() - oy) / h))
        n = 0
        base = offsets[q] if write else 0
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                xa = ox + i * h
                ya = oy + j * h
                px[0], py[0] = xa, ya
                px[1], py[1] = xa + h, ya
                px[2], py[2] = xa + h, ya + h
                px[3], py[3] = xa, ya + h
                m = _clip(px, py, 4, tx[0], ty[0], tx[1], ty[1], qx, qy)
                m = _clip(qx, qy, m, tx[1], ty[1], tx[2], ty[2], px, py)
                m = _clip(px, py, m, tx[2], ty[2], tx[0], ty[0], qx, qy)
                if m < 3:
                    continue
                a2 = 0.0
                sx = 0.0
                sy = 0.0
                for k in range(m):
                    x0, y0 = qx[k], qy[k]
                    x1, y1 = qx[(k + 1) % m], qy[(k + 1) % m]
                    c = x0 * y1 - x1 * y0
                    a2 += c
                    sx += (x0 + x1) * c
                    sy += (y0 + y1) * c
                if a2 <= 1e-12 * h * h:
                    continue
                if write:
                    gx = sx / (3.0 * a2)
                    gy = sy / (3.0 * a2)
                    k = base + n
                    tri_out[k] = t
                    ij_out[k, 0] = i
                    ij_out[k, 1] = j
                    bary_out[k, 0] = (gx * ty[2] - tx[2] * gy) / det
                    bary_out[k, 1] = (tx[1] * gy - gx * ty[1]) / det
                    area_out[k] = 0.5 * a2
                n += 1
        if not write:
            counts[q] = n


def surface_cells(v0, v1, v2, triangles, spacing_mm: float, seed: int = 0):
    """An exact partition of ``triangles`` (indices into the per-triangle corner arrays
    ``v0, v1, v2`` (M, 3), in mm) into pieces: a square lattice of spacing ``spacing_mm`` in each
    triangle's plane (random rotation and offset, seeded per triangle), each cell clipped to the
    triangle. Returns (triangle (n,), lattice index (n, 2), barycentrics of the piece's centroid
    (n, 2) of corners 1 and 2, area (n,) mm^2). The areas sum to the triangles' areas (to
    rounding). Deterministic for a given seed.
    """
    tris = np.ascontiguousarray(triangles, np.int64)
    h = float(spacing_mm)
    if not h > 0:
        raise ValueError("sample spacing must be > 0 mm")
    counts = np.zeros(len(tris), np.int64)
    di = np.zeros(1, np.int64)
    dij = np.zeros((1, 2), np.int64)
    db = np.zeros((1, 2))
    dw = np.zeros(1)
    _cells(v0, v1, v2, tris, h, seed, False, counts, counts, di, dij, db, dw)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    total = int(counts.sum())
    tri_out = np.empty(total, np.int64)
    ij_out = np.empty((total, 2), np.int64)
    bary_out = np.empty((total, 2))
    area_out = np.empty(total)
    _cells(v0, v1, v2, tris, h, seed, True, counts, offsets, tri_out, ij_out, bary_out, area_out)
    return tri_out, ij_out, bary_out, area_out


def coarsen(tri, ij, factor: int):
    """Group fine cells into the cells of the lattice ``factor`` times coarser (same rotation and
    origin, so each coarse cell is exactly a union of fine ones). Returns (group (n,) index of
    each fine cell's coarse cell, number of coarse cells)."""
    if factor == 1:
        return np.arange(len(tri)), len(tri)
    ci = np.floor_divide(ij, factor)
    if np.abs(ci).max(initial=0) >= 2 ** 15 or (len(tri) and tri.max() >= 2 ** 31):
        raise ValueError("lattice too large to group (triangle over 32768 cells across)")
    key = (tri.astype(np.int64) << 32) | ((ci[:, 0] + 2 ** 15) << 16) | (ci[:, 1] + 2 ** 15)
    uniq, group = np.unique(key, return_inverse=True)
    return group.reshape(-1), len(uniq)


def wrapped_uv(uv, texture):
    """(u, v) copies with the map's REPEAT wrap applied (fractional part; glTF samplers, the
    Texture's ``wrap``); clamp-to-edge axes unchanged. Bilinear taps across a period's edge clamp
    instead of wrapping: half a texel along the edges differs from the GPU."""
    u, v = uv[:, 0].copy(), uv[:, 1].copy()
    wrap = ("clamp", "clamp") if texture is None else texture.wrap
    return (u % 1.0 if wrap[0] == "repeat" else u), (v % 1.0 if wrap[1] == "repeat" else v)


@numba.njit(cache=True, parallel=True)
def bilinear(img, u, v):
    """OpenGL bilinear, clamp-to-edge, of an (H, W, C) image with row 0 at the TOP and v = 0 at
    the bottom: texel (i, j_from_bottom) centred at ((i + 0.5) / W, (j + 0.5) / H)."""
    H, W, C = img.shape
    n = u.shape[0]
    out = np.empty((n, C))
    for k in numba.prange(n):
        x = u[k] * W - 0.5
        y = (1.0 - v[k]) * H - 0.5  # rows from the top
        x0 = np.floor(x)
        y0 = np.floor(y)
        fx = x - x0
        fy = y - y0
        i0 = min(max(int(x0), 0), W - 1)
        i1 = min(max(int(x0) + 1, 0), W - 1)
        j0 = min(max(int(y0), 0), H - 1)
        j1 = min(max(int(y0) + 1, 0), H - 1)
        for c in range(C):
            a = img[j0, i0, c] * (1.0 - fx) + img[j0, i1, c] * fx
            b = img[j1, i0, c] * (1.0 - fx) + img[j1, i1, c] * fx
            out[k, c] = a * (1.0 - fy) + b * fy
    return out


def _oriented(n, like):
    """Unit normals ``n`` flipped where they point away from ``like`` (n, 3)."""
    return np.where(np.sum(n * like, axis=1, keepdims=True) < 0.0, -n, n)


def _normalize(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


class SurfaceModel:
    """The scene's mesh in millimetres and its material, evaluated at (triangle, barycentric).

    Reproduces what the real-time shaders compute per fragment: the interpolated normal Ng, the
    normal-mapped normal N (common/surface.glsl perturb_normal, MikkTSpace B = w cross(N, T)),
    albedo, rho_s (specular map with bias and scale) and the environment's SH irradiance.
    """

    def __init__(self, scene):
        self.scene = scene
        mesh = scene.mesh
        mm = float(scene.mm_per_unit)
        self.mm_per_unit = mm
        idx = np.asarray(mesh.indices, np.int64)
        self.indices = idx
        self.positions_mm = np.asarray(mesh.positions, np.float64) * mm
        self.normals = np.asarray(mesh.normals, np.float64)
        self.uvs = np.asarray(mesh.uvs, np.float64)
        self.uvs1 = None if mesh.uvs1 is None else np.asarray(mesh.uvs1, np.float64)
        self.tangents = np.asarray(mesh.tangents, np.float64)
        p = self.positions_mm
        self.v0 = np.ascontiguousarray(p[idx[:, 0]])
        self.v1 = np.ascontiguousarray(p[idx[:, 1]])
        self.v2 = np.ascontiguousarray(p[idx[:, 2]])
        cross = np.cross(self.v1 - self.v0, self.v2 - self.v0)
        self.areas_mm2 = 0.5 * np.linalg.norm(cross, axis=1)
        self.face_normals = _normalize(cross)
        self.centroids = (self.v0 + self.v1 + self.v2) / 3.0
        self.radii = np.max(np.stack([np.linalg.norm(c - self.centroids, axis=1) for c in (self.v0, self.v1, self.v2)]), axis=0)
        mat = scene.material
        self.material = mat
        # times uAlbedoScale of common/surface.glsl: with skin_color = "profile" the profile's total
        # reflectance is the skin's mean colour (dermis.scene.model.skin_albedo_scale)
        scale = skin_albedo_scale(scene).astype(np.float32)
        if mat.albedo is not None:
            self.albedo_map = np.ascontiguousarray(as_rgb(mat.albedo.data) * scale, np.float32)
        else:
            self.albedo_map = (np.asarray(mat.albedo_color, np.float32) * scale).reshape(1, 1, 3)
        # the GPU keeps the normal map as 8-bit UNORM: quantise likewise
        if mat.normal_map is not None:
            nm = np.asarray(mat.normal_map.data[:, :, :3], np.float32)
            self.normal_map = np.ascontiguousarray(np.round(np.clip(nm, 0, 1) * 255.0) / 255.0, np.float32)
        else:
            self.normal_map = np.array([[[0.5, 0.5, 1.0]]], np.float32)
        if mat.specular_map is not None:
            sm = np.asarray(mat.specular_map.data[:, :, :1], np.float32)
            self.specular_map = np.ascontiguousarray(np.round(np.clip(sm, 0, 1) * 255.0) / 255.0, np.float32)
            self.spec_bias_scale = (float(mat.specular_map_bias), float(mat.specular_map_scale))
        else:
            self.specular_map = None
            self.spec_bias_scale = (1.0, 0.0)
        self.env_sh = environment_sh(scene.environment).astype(np.float64)
        env = scene.environment
        # the HDR itself (linear radiance x intensity) for the environment's specular integral
        # (shading.environment_specular_mc); None for a constant environment
        self.env_image = None if env.image is None else \
            np.ascontiguousarray(as_rgb(equirect_radiance(env)), np.float64) * float(env.intensity)
        self.rho_dt = np.asarray(rho_dt_table(), np.float64)

    # ------------------------------------------------------------------ interpolation
    def interpolate(self, tri, bary):
        """Dict of per-point attributes at triangles ``tri`` (n,) and barycentrics (n, 2) of corners 1, 2."""
        tri = np.asarray(tri, np.int64)
        b1, b2 = bary[:, 0:1], bary[:, 1:2]
        b0 = 1.0 - b1 - b2
        i = self.indices[tri]

        def lerp(a):
            return a[i[:, 0]] * b0 + a[i[:, 1]] * b1 + a[i[:, 2]] * b2

        return {
            "position": self.v0[tri] * b0 + self.v1[tri] * b1 + self.v2[tri] * b2,
            "normal_geo": _normalize(lerp(self.normals)),
            # the triangle's own plane (oriented as the interpolated normal): the tissue-path test's
            # normal (integrate._tissue_path), consistent with the positions, which lie on it
            "normal_facet": _oriented(self.face_normals[tri], lerp(self.normals)),
            "uv": lerp(self.uvs),
            "uv1": None if self.uvs1 is None else lerp(self.uvs1),
            "tangent": lerp(self.tangents),
            "bary": np.concatenate([b0, b1, b2], axis=1),
            "tri": tri,
        }

    def shadow_origin(self, attrs):
        """Shadow-ray origins: the point lifted onto the smooth surface its vertex normals describe
        (Hanika 2021, "Hacking the Shadow Terminator", Ray Tracing Gems II ch. 4), so that shadow
        rays from a coarse mesh's faceted terminator do not hit the neighbouring facets."""
        p = attrs["position"]
        i = self.indices[attrs["tri"]]
        b = attrs["bary"]
        out = p.copy()
        for c in range(3):
            a = self.positions_mm[i[:, c]]
            n = self.normals[i[:, c]]
            d = np.minimum(np.sum((p - a) * n, axis=1), 0.0)
            out -= (b[:, c] * d)[:, None] * n
        return out

    # ------------------------------------------------------------------ material
    @staticmethod
    def map_uv(attrs, texture):
        """map_uv() of common/surface.glsl: the map's UV set through its 3x3 transform."""
        if texture is None:
            return attrs["uv"]
        uv = attrs["uv1"] if texture.texcoord == 1 else attrs["uv"]
        T = texture.uv_matrix().astype(np.float64)
        return uv @ T[:2, :2].T + T[:2, 2]

    def albedo(self, attrs):
        uv = self.map_uv(attrs, self.material.albedo)
        return np.maximum(bilinear(self.albedo_map, *wrapped_uv(uv, self.material.albedo)), 0.0)

    def shading_normal(self, attrs):
        """perturb_normal() of common/surface.glsl."""
        n = attrs["normal_geo"]
        T = attrs["tangent"]
        t = _normalize(T[:, :3] - n * np.sum(n * T[:, :3], axis=1, keepdims=True))
        b = T[:, 3:4] * np.cross(n, t)
        uv = self.map_uv(attrs, self.material.normal_map)
        m = bilinear(self.normal_map, *wrapped_uv(uv, self.material.normal_map)) * 2.0 - 1.0
        m[:, :2] *= float(self.material.normal_strength)
        return _normalize(t * m[:, 0:1] + b * m[:, 1:2] + n * m[:, 2:3])

    def rho_s(self, attrs):
        """specular_intensity() of common/surface.glsl."""
        rho = float(self.material.rho_s)
        if self.specular_map is None:
            return np.full(len(attrs["uv"]), rho)
        uv = self.map_uv(attrs, self.material.specular_map)
        s = bilinear(self.specular_map, *wrapped_uv(uv, self.material.specular_map))[:, 0]
        bias, scale = self.spec_bias_scale
        return rho * (bias + scale * s)

    def specular_albedo(self, cos_theta, m):
        """rho_dt_lookup() of common/brdf.glsl: a(cos, m) bilinear at texel centres, x = sqrt(cos)."""
        tab = self.rho_dt
        rows, cols = tab.shape
        x = np.sqrt(np.clip(np.asarray(cos_theta, np.float64), 0.0, 1.0)) * (cols - 1)
        y = np.broadcast_to(float(roughness_to_y(m)) * (rows - 1), x.shape)
        x0 = np.clip(np.floor(x).astype(np.int64), 0, cols - 2)
        y0 = np.clip(np.floor(y).astype(np.int64), 0, rows - 2)
        fx = np.clip(x - x0, 0.0, 1.0)
        fy = np.clip(y - y0, 0.0, 1.0)
        a = tab[y0, x0] * (1 - fx) + tab[y0, x0 + 1] * fx
        b = tab[y0 + 1, x0] * (1 - fx) + tab[y0 + 1, x0 + 1] * fx
        return a * (1 - fy) + b * fy

    def energy_transmitted(self, rho_s, cos_theta):
        """energy_transmitted() of common/energy.glsl: 1 - rho_s a(cos, m) / pi."""
        return 1.0 - rho_s * self.specular_albedo(cos_theta, float(self.material.roughness)) / np.pi

    def ambient(self, n):
        """environment_irradiance() of common/environment.glsl (SH irradiance, unoccluded;
        shading.py applies the ambient visibility)."""
        return irradiance_sh_eval(self.env_sh, n)
