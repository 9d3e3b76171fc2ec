"""Thickness of a mesh's tissue behind every texel of its texture-space layout, by ray casting
(the precomputed "local thickness" of Green 2004, "Real-time approximations to subsurface
scattering", GPU Gems ch. 16, and of Barre-Brisebois & Bouchard 2011, here with the point where
the ray leaves the tissue, so that the irradiance arriving THERE can be looked up).

For each texel centre P with interpolated normal N, rays go into the tissue along -N and along
RAY_TILT_DEG around it; a ray ends where it leaves the tissue: its first hit on a face whose
normal points along the ray (a hit on a face looking at the ray means the ray was in air: an open
or self-intersecting mesh, not counted). The texel's thickness is the median of the hit distances
projected on -N (for a flat slab every ray gives its thickness exactly), in mm; the exit point is
the central ray's, as (u, v) in the same texture-space layout.

Through a slab of thickness d the irradiance E of the far face reaches the near one as E T(d),
T the thin-slab law of the medium the profile describes (dermis.profiles.thin_slab; d'Eon &
Luebke 2007, 14.5.3, used the semi-infinite exp(-d^2 / 2 v_k)); tsd/translucency.frag and
common/transmittance.glsl apply it with this bake. Positions and normals are the mesh's;
distances are returned in mm (mm_per_unit).
"""

from __future__ import annotations

import numpy as np

from dermis.geometry.rasterize import rasterize_uv
from dermis.geometry.raycast import RayCaster

RAY_TILT_DEG = 20.0  # the four rays around -N (the median rejects one slipping through a crack)
MIN_HITS = 3  # of the five rays, at least this many must leave the tissue
START_MM = 0.02  # rays start this far along -N: past the texel's own triangle
MAX_THICKNESS_MM = 30.0  # thicker tissue transmits nothing: exp(-30^2 / 2 v) < 1e-20 for v <= 10 mm^2


def texel_thickness(mesh, size: int, mm_per_unit: float) -> np.ndarray:
    """(size, size, 4) float32, row 0 = top (v = 1): u, v of the exit point, thickness in mm,
    and 1 where the bake holds (0: texel not covered, or no exit within MAX_THICKNESS_MM)."""
    S = int(size)
    uv_ts = np.asarray(mesh.uvs if mesh.texture_space_uvs is None else mesh.texture_space_uvs, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    pos = np.asarray(mesh.positions, np.float64)
    nrm = np.asarray(mesh.normals, np.float64)
    tri, bary = rasterize_uv(uv_ts, idx, S, S)
    out = np.zeros((S, S, 4), np.float32)
    cov = np.nonzero(tri.reshape(-1) >= 0)[0]
    if len(cov) == 0:
        return out
    t = tri.reshape(-1)[cov]
    b = bary.reshape(-1, 3)[cov].astype(np.float64)
    p = np.einsum("nk,nkc->nc", b, pos[idx[t]])
    n = np.einsum("nk,nkc->nc", b, nrm[idx[t]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    # -N and four directions tilted around it, in each texel's tangent frame
    a = np.where(np.abs(n[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(a, n)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    c, s = np.cos(np.radians(RAY_TILT_DEG)), np.sin(np.radians(RAY_TILT_DEG))
    dirs = [-n] + [-c * n + s * (sx * t1 + sy * t2) for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1))]
    cosines = np.array([1.0, c, c, c, c])
    caster = RayCaster(pos, idx)
    start = START_MM / mm_per_unit
    far = MAX_THICKNESS_MM / mm_per_unit
    depth = np.full((len(cov), 5), np.nan)
    exit_uv = None
    for j, d in enumerate(dirs):
        th, htri, hb = caster.closest_hit(p, d, start, far)
        hit = htri >= 0
        hw = np.c_[1.0 - hb.sum(1), hb]  # barycentrics of vertices 0, 1, 2
        hn = np.einsum("nk,nkc->nc", hw, nrm[idx[np.maximum(htri, 0)]])
        leaves = hit & (np.einsum("nc,nc->n", hn, d) > 0.0)  # the face looks along the ray: tissue ends
        depth[leaves, j] = th[leaves] * cosines[j] * mm_per_unit
        if j == 0:
            exit_uv = np.einsum("nk,nkc->nc", hw, uv_ts[idx[np.maximum(htri, 0)]])
            central = leaves
    ok = central & (np.isfinite(depth).sum(1) >= MIN_HITS)
    thick = np.nanmedian(np.where(ok[:, None], depth, 0.0), axis=1)
    flat = out.reshape(-1, 4)
    flat[cov[ok], 0:2] = exit_uv[ok]
    flat[cov[ok], 2] = thick[ok]
    flat[cov[ok], 3] = 1.0
    return out
