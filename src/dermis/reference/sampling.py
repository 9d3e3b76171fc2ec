"""Surface samples and surface attributes for the offline reference (numpy + numba, no GL).

* :func:`surface_samples` - area-weighted points on the mesh: per triangle, a square lattice of
  spacing ``h`` mm in the triangle's plane with a random rotation and offset (seeded per triangle,
  so the set does not depend on the order of processing). A triangle holding n lattice points
  gives each the weight A / n mm^2, so the weights sum exactly to the sampled area; a triangle
  smaller than the lattice gets one sample at its centroid with its whole area. This is stratified
  (jittered-lattice) quadrature: the spacing is isotropic in millimetres, however stretched the
  triangle or its UVs.
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

from dermis.environment import environment_sh, irradiance_sh_eval
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


@numba.njit(cache=True)
def _lattice(v0, v1, v2, tris, h, seed, write, counts, offsets, tri_out, bary_out, w_out):
    """Pass 1 (write=False): count the lattice points inside each triangle. Pass 2: write them."""
    for q in range(tris.shape[0]):
        t = tris[q]
        ax, ay, az = v0[t, 0], v0[t, 1], v0[t, 2]
        e1 = np.array([v1[t, 0] - ax, v1[t, 1] - ay, v1[t, 2] - az])
        e2 = np.array([v2[t, 0] - ax, v2[t, 1] - ay, v2[t, 2] - az])
        l1 = np.sqrt(e1[0] ** 2 + e1[1] ** 2 + e1[2] ** 2)
        nx = e1[1] * e2[2] - e1[2] * e2[1]
        ny = e1[2] * e2[0] - e1[0] * e2[2]
        nz = e1[0] * e2[1] - e1[1] * e2[0]
        area = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
        if area <= 0.0 or l1 <= 0.0:
            if write:
                counts[q] = 0
            continue
        # 2-D frame in the plane: x along edge 1
        bx = l1
        cx = (e2[0] * e1[0] + e2[1] * e1[1] + e2[2] * e1[2]) / l1
        cy = 2.0 * area / l1
        r = _hash_uniforms(seed, t)
        ang = r[0] * 2.0 * np.pi
        ca, sa = np.cos(ang), np.sin(ang)
        # the triangle in the lattice's (rotated) frame: A = 0, B, C
        pbx, pby = ca * bx, -sa * bx
        pcx, pcy = ca * cx + sa * cy, -sa * cx + ca * cy
        xmin, xmax = min(0.0, min(pbx, pcx)), max(0.0, max(pbx, pcx))
        ymin, ymax = min(0.0, min(pby, pcy)), max(0.0, max(pby, pcy))
        ox, oy = r[1] * h, r[2] * h
        i0 = int(np.floor((xmin - ox) / h))
        i1 = int(np.ceil((xmax - ox) / h))
        j0 = int(np.floor((ymin - oy) / h))
        j1 = int(np.ceil((ymax - oy) / h))
        det = pbx * pcy - pcx * pby
        n = 0
        base = offsets[q] if write else 0
        for i in range(i0, i1 + 1):
            x = ox + i * h
            for j in range(j0, j1 + 1):
                y = oy + j * h
                # barycentrics of (x, y) w.r.t. A=0, B, C
                b1 = (x * pcy - pcx * y) / det
                b2 = (pbx * y - x * pby) / det
                if b1 >= 0.0 and b2 >= 0.0 and b1 + b2 <= 1.0:
                    if write:
                        tri_out[base + n] = t
                        bary_out[base + n, 0] = b1
                        bary_out[base + n, 1] = b2
                    n += 1
        if n == 0:  # smaller than the lattice: one sample at the centroid
            if write:
                tri_out[base] = t
                bary_out[base, 0] = 1.0 / 3.0
                bary_out[base, 1] = 1.0 / 3.0
                w_out[base] = area
            else:
                counts[q] = 1
            continue
        if write:
            for k in range(n):
                w_out[base + k] = area / n
        else:
            counts[q] = n


def surface_samples(v0, v1, v2, triangles, spacing_mm: float, seed: int = 0):
    """Area-weighted samples on ``triangles`` (indices into the per-triangle corner arrays
    ``v0, v1, v2`` (M, 3), in mm) at lattice spacing ``spacing_mm``.

    Returns (triangle (n,) int64, barycentrics (n, 2) float64 of corners 1 and 2, weight (n,) mm^2).
    Deterministic for a given seed.
    """
    tris = np.ascontiguousarray(triangles, np.int64)
    h = float(spacing_mm)
    if not h > 0:
        raise ValueError("sample spacing must be > 0 mm")
    counts = np.zeros(len(tris), np.int64)
    dummy_i = np.zeros(1, np.int64)
    dummy_b = np.zeros((1, 2))
    dummy_w = np.zeros(1)
    _lattice(v0, v1, v2, tris, h, seed, False, counts, counts, dummy_i, dummy_b, dummy_w)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    total = int(counts.sum())
    tri_out = np.empty(total, np.int64)
    bary_out = np.empty((total, 2))
    w_out = np.empty(total)
    _lattice(v0, v1, v2, tris, h, seed, True, counts, offsets, tri_out, bary_out, w_out)
    return tri_out, bary_out, w_out


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
        if mat.albedo is not None:
            self.albedo_map = np.ascontiguousarray(mat.albedo.data[:, :, :3], np.float32)
        else:
            self.albedo_map = np.asarray(mat.albedo_color, np.float32).reshape(1, 1, 3)
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
            "uv": lerp(self.uvs),
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
    def albedo(self, attrs):
        uv = attrs["uv"]
        return np.maximum(bilinear(self.albedo_map, uv[:, 0].copy(), uv[:, 1].copy()), 0.0)

    def shading_normal(self, attrs):
        """perturb_normal() of common/surface.glsl."""
        n = attrs["normal_geo"]
        T = attrs["tangent"]
        t = _normalize(T[:, :3] - n * np.sum(n * T[:, :3], axis=1, keepdims=True))
        b = T[:, 3:4] * np.cross(n, t)
        uv = attrs["uv"]
        m = bilinear(self.normal_map, uv[:, 0].copy(), uv[:, 1].copy()) * 2.0 - 1.0
        m[:, :2] *= float(self.material.normal_strength)
        return _normalize(t * m[:, 0:1] + b * m[:, 1:2] + n * m[:, 2:3])

    def rho_s(self, attrs):
        """specular_intensity() of common/surface.glsl."""
        rho = float(self.material.rho_s)
        if self.specular_map is None:
            return np.full(len(attrs["uv"]), rho)
        uv = attrs["uv"]
        s = bilinear(self.specular_map, uv[:, 0].copy(), uv[:, 1].copy())[:, 0]
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
        """energy_transmitted() of tsd/energy.glsl: 1 - rho_s a(cos, m) / pi."""
        return 1.0 - rho_s * self.specular_albedo(cos_theta, float(self.material.roughness)) / np.pi

    def ambient(self, n):
        """environment_irradiance() of common/environment.glsl (unoccluded SH irradiance)."""
        return irradiance_sh_eval(self.env_sh, n)
