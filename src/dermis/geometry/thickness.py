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

from dermis.camera import normalize
from dermis.geometry.rasterize import rasterize_uv
from dermis.geometry.raycast import RayCaster
from dermis.geometry.texture_space import texture_space_uvs

RAY_TILT_DEG = 20.0  # the four rays around -N (the median rejects one slipping through a crack)
MIN_HITS = 3  # of the five rays, at least this many must leave the tissue
START_MM = 0.02  # rays start this far along -N: past the texel's own triangle
MAX_THICKNESS_MM = 30.0  # thicker tissue transmits nothing: exp(-30^2 / 2 v) < 1e-20 for v <= 10 mm^2


def _texels(mesh, S: int):
    """The layout's texel centres: uv, indices, positions, normals of the mesh; the texel -> triangle
    map; the covered texels (flat indices) and their interpolated positions and unit normals."""
    uv_ts = np.asarray(texture_space_uvs(mesh), np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    pos = np.asarray(mesh.positions, np.float64)
    nrm = np.asarray(mesh.normals, np.float64)
    tri, bary = rasterize_uv(uv_ts, idx, S, S)
    cov = np.nonzero(tri.reshape(-1) >= 0)[0]
    t = tri.reshape(-1)[cov]
    b = bary.reshape(-1, 3)[cov].astype(np.float64)
    p = np.einsum("nk,nkc->nc", b, pos[idx[t]])
    n = np.einsum("nk,nkc->nc", b, nrm[idx[t]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return uv_ts, idx, pos, nrm, tri, cov, p, n


def texel_thickness(mesh, size: int, mm_per_unit: float) -> np.ndarray:
    """(size, size, 4) float32, row 0 = top (v = 1): u, v of the exit point, thickness in mm,
    and 1 where the bake holds (0: texel not covered, or no exit within MAX_THICKNESS_MM)."""
    S = int(size)
    uv_ts, idx, pos, nrm, tri, cov, p, n = _texels(mesh, S)
    out = np.zeros((S, S, 4), np.float32)
    if len(cov) == 0:
        return out
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


# --- Along the light, where the bake along -N finds no far face ---------------------------------
# Concha and antihelix seen edge-on: -N runs into the head (no exit within MAX_THICKNESS_MM) while
# along the light they are a few mm thick. There the tissue's thickness is taken along the light,
# from the texel P towards the light to where the ray leaves the tissue, E (the translucent shadow
# map's distance t of d'Eon & Luebke 2007, 14.5.3, by ray casting instead of the map's depth), and
# the light that enters at E crosses a slab whose faces are the tangent planes at P and at E.
#
# Why that is safe at the terminator of a thick part (derivation, tests/test_thickness_light.py):
# on a sphere of radius R lit along L, a point P at the angle a past the terminator has
# -N_P.L = sin a, the chord to the lit side is t = 2 R sin a -> 0, and E's normal is the mirror of
# P's: -N_E.N_P = -cos 2a ~ -1. d'Eon's t, or the slab thickness t cos, vanish there: light at
# every terminator (round 1's orange specks). A slab has -N_E.N_P = 1 for any tilt, and
# t (N_E.L) = t (-N_P.L) = d, its thickness. So the light path is trusted only where the two faces
# are nearly antiparallel, weight smoothstep(PARALLEL_COS) of -N_E.N_P, zero below cos 60 deg. On the
# sphere that first passes at 2a > 180 - 60 deg, a > 60 deg, where t cos a >= 2 R sin^2 60 = 1.5 R:
# light through the sphere's whole body, T(1.5 R) / A < 1% in red for R >= 5 mm (the thin-slab
# table). The thickness used is the larger of the two faces' distances to the other's tangent plane,
# t max(N_E.L, -N_P.L): d for a slab at any tilt, never thinner than either face says.
PARALLEL_COS = (0.5, 0.8)  # -N_E.N_P: 0 at 60 deg between the faces (and beyond), 1 within 37 deg


def _light_directions(light, p):
    """Unit directions from the points p (n, 3), scene units, towards ``light`` (dermis.scene.model.Light)."""
    if light.kind == "directional":
        return np.broadcast_to(-normalize(light.direction), p.shape)
    d = np.asarray(light.position, np.float64)[None, :] - p
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def key_light(lights):
    """The shadow-casting light of the largest irradiance or intensity (the one whose path through
    thin parts is baked), or None."""
    casting = [L for L in lights if L.cast_shadows and L.intensity * max(L.color) > 0.0]
    return max(casting, key=lambda L: L.intensity * max(L.color)) if casting else None


def light_thickness(mesh, size: int, mm_per_unit: float, light, where=None) -> np.ndarray:
    """(size, size, 4) float32 as texel_thickness, along the light: (u, v) of E where the ray from
    the texel towards ``light`` leaves the tissue, the slab thickness t max(N_E.L, -N_P.L) in mm,
    and the weight smoothstep(PARALLEL_COS, -N_E.N_P) (0: not a slab, or the texel faces the
    light, or no exit within MAX_THICKNESS_MM). ``where`` (size, size) bool: only those texels."""
    S = int(size)
    uv_ts, idx, pos, nrm, tri, cov, p, n = _texels(mesh, S)
    out = np.zeros((S, S, 4), np.float32)
    if where is not None:
        sel = np.asarray(where, bool).reshape(-1)[cov]
        cov, p, n = cov[sel], p[sel], n[sel]
    if len(cov) == 0 or light is None:
        return out
    L = _light_directions(light, p)
    cos_p = -np.einsum("nc,nc->n", n, L)  # > 0: the texel faces away from the light
    away = cos_p > 0.0  # only those can be lit through the tissue: the others cast no ray
    cov, p, n, L, cos_p = cov[away], p[away], n[away], L[away], cos_p[away]
    if len(cov) == 0:
        return out
    th, htri, hb = RayCaster(pos, idx).closest_hit(p, L, START_MM / mm_per_unit, MAX_THICKNESS_MM / mm_per_unit)
    hit = htri >= 0
    hw = np.c_[1.0 - hb.sum(1), hb]
    ne = np.einsum("nk,nkc->nc", hw, nrm[idx[np.maximum(htri, 0)]])
    ne /= np.maximum(np.linalg.norm(ne, axis=1, keepdims=True), 1e-12)
    cos_e = np.einsum("nc,nc->n", ne, L)  # > 0: E faces the light (the ray leaves the tissue there)
    ok = hit & (cos_p > 0.0) & (cos_e > 0.0)
    x = np.clip((-np.einsum("nc,nc->n", ne, n) - PARALLEL_COS[0]) / (PARALLEL_COS[1] - PARALLEL_COS[0]), 0.0, 1.0)
    w = np.where(ok, x * x * (3.0 - 2.0 * x), 0.0)
    d = np.where(ok, th, 0.0) * np.maximum(cos_e, cos_p) * mm_per_unit
    keep = w > 0.0
    flat = out.reshape(-1, 4)
    flat[cov[keep], 0:2] = np.einsum("nk,nkc->nc", hw, uv_ts[idx[np.maximum(htri, 0)]])[keep]
    flat[cov[keep], 2] = d[keep]
    flat[cov[keep], 3] = w[keep]
    return out


# --- Continuity --------------------------------------------------------------------------------
# Along the helix neighbouring texels' far faces differ by centimetres (the -N ray leaves through
# the helix for one texel and into the head for the next): per texel the translucency switched on
# and off, a texel-structured patch at 768 px. The bake is smoothed within each UV island (never
# across a seam): the weight (validity) by a Gaussian of SMOOTH_SIGMA_TEXELS, and the thickness by
# the mean of the neighbours' transmittance, d_s = -ln(sum w v e^(-k d) / sum w v) / k, a soft
# minimum whose decay k is skin's red sigma_tr (T(d) falls e-fold per 1.7 mm through 1-5 mm,
# dermis.profiles.thin_slab): light is linear in T, not in d, so a thick neighbour does not darken
# a thin band (the mean d would: preintegrated's flecks), and a uniform slab keeps its d exactly.
SMOOTH_SIGMA_TEXELS = 1.0
SMOOTH_RADIUS_TEXELS = 2
SMOOTH_DECAY_PER_MM = 0.6


def uv_islands(mesh, size: int) -> np.ndarray:
    """(size, size) int: the UV island (triangles connected through shared vertices) of each texel
    of the texture-space layout, -1 where no triangle covers it; row 0 = top."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    uv_ts = texture_space_uvs(mesh)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    nv = len(mesh.positions)
    rows = np.repeat(np.arange(len(idx)), 3)
    g = coo_matrix((np.ones(len(rows)), (rows, idx.reshape(-1))), shape=(len(idx), nv)).tocsr()
    _, label = connected_components(g @ g.T, directed=False)  # triangles sharing a vertex
    tri, _ = rasterize_uv(np.asarray(uv_ts, np.float64), idx, size, size)
    return np.where(tri >= 0, label[np.maximum(tri, 0)], -1)


def smooth_thickness(bake: np.ndarray, islands: np.ndarray) -> np.ndarray:
    """The bake (S, S, 4) smoothed within each island (see above): weight = Gaussian mean of the
    neighbours' weights, thickness = soft minimum of theirs; a texel without a far face of its own
    takes the (u, v) of its nearest neighbour that has one."""
    S = bake.shape[0]
    r = SMOOTH_RADIUS_TEXELS
    v = bake[..., 3].astype(np.float64)
    d = bake[..., 2].astype(np.float64)
    e = v * np.exp(-SMOOTH_DECAY_PER_MM * d)
    pad = lambda a, c: np.pad(a, r, constant_values=c)  # noqa: E731
    isl, vp, ep = pad(islands, -1), pad(v, 0.0), pad(e, 0.0)
    W = np.zeros((S, S))
    V = np.zeros((S, S))
    E = np.zeros((S, S))
    best = np.zeros((S, S))
    uv = bake[..., 0:2].copy()
    uvp = np.pad(bake[..., 0:2], ((r, r), (r, r), (0, 0)))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            g = np.exp(-(dx * dx + dy * dy) / (2.0 * SMOOTH_SIGMA_TEXELS ** 2))
            sl = (slice(r + dy, r + dy + S), slice(r + dx, r + dx + S))
            same = (isl[sl] == islands) & (islands >= 0)
            W += g * same
            V += g * same * vp[sl]
            E += g * same * ep[sl]
            take = same & (v <= 0.0) & (g * vp[sl] > best)
            best = np.where(take, g * vp[sl], best)
            uv[take] = uvp[sl][take]
    out = np.zeros_like(bake)
    has = V > 0.0
    vs = np.where(W > 0.0, V / np.maximum(W, 1e-300), 0.0)
    vs = np.where(np.abs(vs - 1.0) < 1e-9, 1.0, vs)  # a fully valid neighbourhood stays exactly 1
    out[..., 0:2] = np.where(has[..., None], uv, 0.0)
    out[..., 2] = np.where(has, -np.log(np.maximum(E, 1e-300) / np.maximum(V, 1e-300)) / SMOOTH_DECAY_PER_MM, 0.0)
    out[..., 3] = np.where(has, vs, 0.0)
    return out.astype(np.float32)


def translucency_thickness(mesh, size: int, mm_per_unit: float, lights, along_normal=None,
                           islands=None, light_path: bool = True, unsmoothed: bool = False):
    """What the techniques read (gl/thickness.py): the bake along -N (``along_normal``, else
    texel_thickness), where it has no far face the bake along the key light (light_thickness), the
    two smoothed within each UV island (smooth_thickness; ``islands``, else uv_islands). (size, size,
    4) float32: (u, v) of the far face, thickness in mm, weight in [0, 1]. ``light_path=False``
    (the scene's ``translucency_light_path``): the bake along -N alone, smoothed. ``unsmoothed``:
    also the two before smoothing (the far face's points, gl/thickness.py far_face_points)."""
    b = texel_thickness(mesh, size, mm_per_unit) if along_normal is None else along_normal
    if light_path:
        lt = light_thickness(mesh, size, mm_per_unit, key_light(lights), where=b[..., 3] <= 0.0)
        b = np.where((lt[..., 3] > 0.0)[..., None], lt, b)
    smoothed = smooth_thickness(b, uv_islands(mesh, size) if islands is None else islands)
    return (smoothed, b) if unsmoothed else smoothed
