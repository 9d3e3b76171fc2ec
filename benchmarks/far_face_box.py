"""The far-face shadow box of ssss / preintegrated (common/transmittance.glsl) against the far face's lit
fraction by ray casting, on the back-lit ear's regions and on a rounded thin part (issue 12, round 23,
shadowbox23; round 22's lobe22 found the lobe's box 0.70-0.76 where the far face itself is 93 % lit).

The shader lights a thin part's pixel P (interpolated normal Ng, baked thickness h) from the far face
A = P - h Ng with light_incident's E cos(-Ng.L) T(h) s, s the box: a 6 x 6 grid turned by atan(1/6) over a
square of half-width sqrt(3 v(h)) (the slab's lateral spread) on two planes perpendicular to Ng, lifted
2.5 mm along -Ng and 0.5 mm + half the half-width along L, max of the two planes' means. Per pixel this
script follows the same taps by ray casting (a tap is lit where the ray from it towards the light meets
nothing: the shadow map's compare without filtering or bias) and sets beside it, from the same geometry:

- ref_plane: the far face under the taps: from each tap's point of P's tangent plane, along -Ng, the first
  exit from tissue after an entry; its lit fraction (it faces the light and a ray from 0.05 mm off it sees
  the light) over the taps that find one (`with far face` of them). Taps past a rounded part's edge find
  none and are left out.
- ref_surface: the far face's own surface: the mesh's triangles (centroids) inside the square about A
  (within half-width on the plane perpendicular to Ng, within h / 2 of A along Ng) that face away from P
  (normal . Ng < 0), area-weighted: lit fraction, and cos x lit (the light that enters there per unit
  irradiance, the quantity the shader's cos(-Ng.L) s estimates).
- exit_cos: the cosine at the far face's own normal where -Ng leaves the tissue (the shader takes -Ng.L).
- taps: the taps' mean of the shader's two planes, and which of them lie inside tissue (the ray towards the
  light leaves tissue first).

    PYTHONPATH=src python benchmarks/far_face_box.py head [--regions lobe helix scapha concha] [--box X0 Y0 X1 Y1] [--lattice]
    PYTHONPATH=src python benchmarks/far_face_box.py part [--width-mm 10 --thickness-mm 5 --angle-deg 40]

`head`: back-ears' 768 px frame, ear_regions.py's boxes, the thickness bake the two techniques read (512^2,
translucency_thickness), ~15 s. `part`: a back-lit elliptic tube (the lobe's cross-section: width x thickness,
60 mm long, seen head-on, lit from behind at angle-deg from its axis of thickness, in the plane of the width),
with and without a plate behind half of it (1 mm of air, 3 mm thick: round 18's scapha layer), thickness by
ray casting along -N (the bake's unsmoothed median), ~5 s.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

GRID = 6
TURN = np.array([6.0, 1.0]) / np.sqrt(37.0)  # common/shadow.glsl SHADOW_BOX_TURN
LIFT_MM, LIFT_ALONG_LIGHT_MM = 2.5, 0.5  # common/transmittance.glsl


def box_offsets():
    """(36, 2) the rotated grid's points f in [-1, 1]^2 (common/shadow.glsl shadow_box_curved)."""
    g = (np.arange(GRID) + 0.5) * (2.0 / GRID) - 1.0
    gx, gy = np.meshgrid(g, g)
    gx, gy = gx.ravel(), gy.ravel()
    return np.stack([TURN[0] * gx - TURN[1] * gy, TURN[1] * gx + TURN[0] * gy], 1)


def tangent_frame(n):
    """common/shadow.glsl's t1, t2 for unit normals n (k, 3)."""
    a = np.where(np.abs(n[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(n, t1)


class Geometry:
    """Ray casts in one mesh: positions, indices, vertex normals, scene units (mm_per_unit)."""

    def __init__(self, P, I, N, mm):
        from dermis.geometry.raycast import RayCaster

        self.P, self.I, self.N, self.mm = np.asarray(P, np.float64), np.asarray(I, np.int64).reshape(-1, 3), \
            np.asarray(N, np.float64), float(mm)
        self.rc = RayCaster(self.P, self.I)
        tri = self.P[self.I]
        self.C = tri.mean(1)
        self.area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        nt = self.N[self.I].mean(1)
        self.Nt = nt / np.linalg.norm(nt, axis=1, keepdims=True)
        self._lit = None

    def hit(self, O, D, tmin=0.0, tmax=np.inf):
        """distance (scene units, inf if none), interpolated unit normal at the hit."""
        t, tri, b = self.rc.closest_hit(O, D, tmin, tmax)
        w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
        n = np.einsum("ij,ijk->ik", w, self.N[self.I[np.maximum(tri, 0)]])
        n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-12
        return np.where(tri >= 0, t, np.inf), n

    def sees_light(self, Q, L):
        """(k,) bool: the ray from Q towards the light meets nothing; and whether Q lies inside tissue."""
        t, n = self.hit(Q, np.broadcast_to(L, Q.shape), 1e-7)
        return ~np.isfinite(t), np.isfinite(t) & (n @ L > 0)

    def triangle_lit(self, L):
        """per triangle: (faces and sees the light from its centroid 0.05 mm off it, max(N.L, 0) x that)."""
        if self._lit is None:
            face = self.Nt @ L > 0
            free = self.sees_light(self.C + self.Nt * (0.05 / self.mm), L)[0]
            self._lit = (face & free).astype(float), np.maximum(self.Nt @ L, 0.0) * (face & free)
        return self._lit


def box_frame(geo: Geometry, p, n, h, half):
    """(off, A, t1, t2): the box's tap offsets in scene units ((k, m, 3): box_offsets on each pixel's tangent plane
    (t1, t2), scaled to the half-width ``half`` mm) and the far-face points A = p - h n ((k, 3)), as
    common/transmittance.glsl places them."""
    F = box_offsets()
    t1, t2 = tangent_frame(n)
    off = (F[None, :, 0:1] * t1[:, None, :] + F[None, :, 1:2] * t2[:, None, :]) * (half / geo.mm)[:, None, None]
    return off, p - n * (h / geo.mm)[:, None], t1, t2


def replica(geo: Geometry, p, n, h, half, L):
    """Per pixel (front points p, unit normals n, thickness h mm, box half-width half mm, unit L towards the light):
    the shader's box and the references (module docstring). Returns a dict of (k,) arrays."""
    mm = geo.mm
    off, A, t1, t2 = box_frame(geo, p, n, h, half)
    k, m = off.shape[:2]

    def taps(Q):
        lit, inside = geo.sees_light(Q.reshape(-1, 3), L)
        return lit.reshape(k, m), inside.reshape(k, m)

    l1, i1 = taps(A[:, None] - n[:, None] * (LIFT_MM / mm) + off)
    l2, i2 = taps(A[:, None] + L * ((LIFT_ALONG_LIGHT_MM + 0.5 * half) / mm)[:, None, None] + off)
    out = {"s_box": np.maximum(l1.mean(1), l2.mean(1)), "plane1": l1.mean(1), "plane2": l2.mean(1),
           "inside1": i1.mean(1), "inside2": i2.mean(1), "cos_P": -(n @ L)}
    # ref_plane: along -Ng from each tap's point of P's tangent plane (from 3 mm in front of it)
    O = (p[:, None] + off + n[:, None] * (3.0 / mm)).reshape(-1, 3)
    D = np.broadcast_to(-n[:, None], (k, m, 3)).reshape(-1, 3)
    t0, n0 = geo.hit(O, D)
    enters = np.isfinite(t0) & (np.einsum("ij,ij->i", n0, D) < 0)
    O1 = O + D * np.where(enters, t0 + 1e-6, 0.0)[:, None]
    t1_, nF = geo.hit(O1, D, 1e-7, 30.0 / mm)
    leaves = enters & np.isfinite(t1_) & (np.einsum("ij,ij->i", nF, D) > 0)
    X = O1 + D * np.where(leaves, t1_, 0.0)[:, None]
    free = geo.sees_light(X + nF * (0.05 / mm), L)[0]
    litF = (leaves & (nF @ L > 0) & free).reshape(k, m)
    leaves = leaves.reshape(k, m)
    out["with_far_face"] = leaves.mean(1)
    out["ref_plane"] = np.where(leaves.sum(1) > 0, litF.sum(1) / np.maximum(leaves.sum(1), 1), np.nan)
    # exit_cos: the far face's own normal where -Ng from P leaves the tissue
    te, ne = geo.hit(p - n * 1e-6, -n, 1e-6, 30.0 / mm)
    ok = np.isfinite(te) & (np.einsum("ij,ij->i", ne, -n) > 0)
    out["exit_cos"] = np.where(ok, np.maximum(ne @ L, 0.0), np.nan)
    # ref_surface: the far face's triangles inside the square about A
    from scipy.spatial import cKDTree

    tree = cKDTree(geo.C)
    lit_t, cos_lit_t = geo.triangle_lit(L)
    rs, rc = np.full(k, np.nan), np.full(k, np.nan)
    for i in range(k):
        cand = np.asarray(tree.query_ball_point(A[i], half[i] * 1.5 / mm), np.int64)
        if len(cand) == 0:
            continue
        d = (geo.C[cand] - A[i]) * mm
        sel = (np.abs(d @ t1[i]) <= half[i]) & (np.abs(d @ t2[i]) <= half[i]) & (np.abs(d @ n[i]) <= h[i] / 2) \
            & (geo.Nt[cand] @ n[i] < 0)
        cand = cand[sel]
        if len(cand):
            a = geo.area[cand]
            rs[i] = (a * lit_t[cand]).sum() / a.sum()
            rc[i] = (a * cos_lit_t[cand]).sum() / a.sum()
    out["ref_surface"], out["ref_surface_cos"] = rs, rc
    return out


def surface_taps(geo: Geometry, p, n, h, half, L, uv, M, points, ramp=(0.4, 0.6), max_slope=1.0, min_weight=0.25):
    """common/transmittance.glsl's far_face_shadow since round 23, by ray casting: tap k reads the far face's
    point X_k (``points``: gl.thickness.far_face_points, bilinear) at uv + M delta_k (M (k, 2, 3): the layout's
    uv per scene unit, from each pixel's triangle), weight w_k x (1 - smoothstep(ramp h) of |Ng.(X_k - A)|), lit
    where X_k lifted 2.5 mm along -Ng or 0.5 mm + half the half-width along L sees the light; the far face's normal
    from the weighted least-squares plane through the kept points. Returns (s, cos at that normal)."""
    from farface_occluder import bilinear

    mm = geo.mm
    off, A, t1, t2 = box_frame(geo, p, n, h, half)
    k, m = off.shape[:2]
    uvk = uv[:, None] + np.einsum("nij,nkj->nki", M, off)
    f = bilinear(points, uvk.reshape(-1, 2)).reshape(k, m, 4)
    w = f[..., 3]
    X = f[..., :3] / np.maximum(w, 1e-12)[..., None]
    rel = (X - A[:, None]) * mm
    q = np.stack([np.einsum("nkc,nc->nk", rel, t1), np.einsum("nkc,nc->nk", rel, t2), np.einsum("nkc,nc->nk", rel, n)], -1)
    x = np.clip((np.abs(q[..., 2]) / h[:, None] - ramp[0]) / (ramp[1] - ramp[0]), 0.0, 1.0)
    w = np.where(w > 0, w * (1.0 - x * x * (3.0 - 2.0 * x)), 0.0)
    lit1 = geo.sees_light((X - n[:, None] * (LIFT_MM / mm)).reshape(-1, 3), L)[0].reshape(k, m)
    lit2 = geo.sees_light((X + L * ((LIFT_ALONG_LIGHT_MM + 0.5 * half) / mm)[:, None, None]).reshape(-1, 3), L)[0].reshape(k, m)
    ws = w.sum(1)
    s = np.where(ws > 0, (w * np.maximum(lit1, lit2)).sum(1) / np.maximum(ws, 1e-12), 0.0)
    W = w / np.maximum(ws, 1e-12)[:, None]
    mu = np.einsum("nk,nkc->nc", W, q)
    c = q - mu[:, None]
    cuu, cuv, cvv = (W * c[..., 0] ** 2).sum(1), (W * c[..., 0] * c[..., 1]).sum(1), (W * c[..., 1] ** 2).sum(1)
    bu, bv = (W * c[..., 0] * c[..., 2]).sum(1), (W * c[..., 1] * c[..., 2]).sum(1)
    det = cuu * cvv - cuv ** 2
    ok = (ws >= min_weight * m) & (det > 1e-2 * half ** 4)
    g = np.stack([cvv * bu - cuv * bv, cuu * bv - cuv * bu], 1) / np.where(ok, det, 1.0)[:, None]
    gl = np.linalg.norm(g, axis=1, keepdims=True)
    g = np.where(ok[:, None], g * np.minimum(1.0, max_slope / np.maximum(gl, 1e-12)), 0.0)
    nf = -n + g[:, :1] * t1 + g[:, 1:] * t2
    nf /= np.linalg.norm(nf, axis=1, keepdims=True)
    return s, np.maximum(nf @ L, 0.0)


def lattice_taps(geo: Geometry, p, n, h, half, L, uv, M, points, per_side=6.0, nmax=11, edge=0.75, ramp=(0.4, 0.6)):
    """A candidate, not the shader (round 24, pre24): the far-face taps on a lattice FIXED in texture space instead of
    moving with P. The shader's taps sit at uv + M delta_k, so as P moves each tap's far-face point X_k slides over an
    irregular far face and its lit test flips at scattered places: steps of 1/36 at 1-2 px (the back-lit helix fold's
    mottle). Here the taps are the lattice points q = (i + 1/2) d of the layout's uv (one spacing d for the whole
    call: the region's median box width / per_side), weighted by a box over P's square with smooth edges (from
    ``edge`` x the half-width; f = (M [t1 t2])^-1 (q - uv) on P's tangent plane), the depth window and the points'
    weights as the shader: each lattice point's lit test is fixed, only the weights move with P. nmax^2 candidates.
    Returns (s, taps used per pixel). A shader needs a d that is constant over large areas (a per-draw spacing, or
    levels blended): a per-pixel d moves the whole lattice."""
    from farface_occluder import bilinear

    def sstep(e0, e1, x):
        t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
        return t * t * (3.0 - 2.0 * t)

    mm = geo.mm
    _, A, t1, t2 = box_frame(geo, p, n, h, half)
    B = M @ (np.stack([t1, t2], 2) / mm)  # (k, 2, 2): P's tangent plane (mm) -> uv
    d = np.median(2.0 * half * np.sqrt(np.abs(np.linalg.det(B)))) / per_side
    g = np.arange(nmax)
    gx, gy = np.meshgrid(g, g)
    q = (np.floor(uv / d - nmax / 2.0)[:, None, :] + np.stack([gx.ravel(), gy.ravel()], 1)[None] + 0.5) * d
    f = np.einsum("kij,kmj->kmi", np.linalg.inv(B), q - uv[:, None])
    wb = (1 - sstep(edge, 1.0, np.abs(f[..., 0]) / half[:, None])) * (1 - sstep(edge, 1.0, np.abs(f[..., 1]) / half[:, None]))
    k, m = q.shape[:2]
    fp = bilinear(points, q.reshape(-1, 2)).reshape(k, m, 4)
    X = fp[..., :3] / np.maximum(fp[..., 3], 1e-12)[..., None]
    dz = np.abs(np.einsum("kmc,kc->km", (X - A[:, None]) * mm, n)) / h[:, None]
    w = np.where((fp[..., 3] > 0) & (wb > 0), fp[..., 3] * wb * (1 - sstep(ramp[0], ramp[1], dz)), 0.0)
    use = w > 0
    lit = np.zeros((k, m))
    lit[use] = np.maximum(geo.sees_light((X - n[:, None] * (LIFT_MM / mm))[use], L)[0],
                          geo.sees_light((X + L * ((LIFT_ALONG_LIGHT_MM + 0.5 * half) / mm)[:, None, None])[use], L)[0])
    ws = w.sum(1)
    return np.where(ws > 0, (w * lit).sum(1) / np.maximum(ws, 1e-12), 0.0), use.sum(1)


def high_pass(s, box, sigma=1.5):
    """Mean |s - G_sigma(s)| of a per-pixel map over the region ``box`` (x0, y0, x1, y1), 2 px in from its border;
    None unless every pixel of the box was kept."""
    from scipy.ndimage import gaussian_filter

    x0, y0, x1, y1 = box
    if len(s) != (x1 - x0) * (y1 - y0):
        return None
    S = np.asarray(s, np.float64).reshape(y1 - y0, x1 - x0)
    return float(np.abs(S - gaussian_filter(S, sigma))[2:-2, 2:-2].mean())

def summary(name, r):
    q = lambda v: f"{np.nanmean(v):.3f}"  # noqa: E731
    print(f"{name}: {len(r['s_box'])} px; box s {q(r['s_box'])} (plane 1 {q(r['plane1'])}, its taps inside tissue "
          f"{q(r['inside1'])}; plane 2 {q(r['plane2'])}, inside {q(r['inside2'])}); ray cast: ref_plane {q(r['ref_plane'])} "
          f"(taps with a far face {q(r['with_far_face'])}), ref_surface {q(r['ref_surface'])}")
    print(f"    cos x s: shader {q(r['cos_P'] * r['s_box'])} (cos at -Ng {q(r['cos_P'])}), ref_surface {q(r['ref_surface_cos'])}; "
          f"exit's own cos {q(r['exit_cos'])}; |box - ref_surface| per px {np.nanmean(np.abs(r['s_box'] - r['ref_surface'])):.3f}")


def head(a):
    import cycles_crops
    import dermis
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.geometry.thickness import texel_thickness, translucency_thickness
    from dermis.techniques.shared import thin_slab_law
    from ear_regions import REGIONS
    from farface_occluder import bilinear
    from helix_glow import camera_hits

    sc = dermis.load_scene(cycles_crops.SCENES["back-ears"])
    sc.material.pore_strength = 0.0
    mesh, mm = sc.mesh, float(sc.mm_per_unit)
    normal = texel_thickness(mesh, 512, mm)
    bake, completed = translucency_thickness(mesh, 512, mm, sc.lights, along_normal=normal, unsmoothed=True,
                                             light_path=bool(getattr(sc, "translucency_light_path", False)))
    data = np.stack([bake[..., 2] * bake[..., 3], bake[..., 3]], -1)
    _, law = thin_slab_law(sc)
    L = -np.asarray(sc.lights[0].direction, np.float64)
    L /= np.linalg.norm(L)
    geo = Geometry(mesh.positions, mesh.indices, mesh.normals, mm)
    uv_ts = np.asarray(texture_space_uvs(mesh), np.float64)
    from dermis.gl.thickness import far_face_points, texel_maps

    points = far_face_points(completed, normal, texel_maps(mesh, 512), mm)
    regions = dict(REGIONS)
    if getattr(a, "box", None):
        regions["box"] = tuple(a.box)
        a.regions = list(a.regions) + ["box"]
    for name in a.regions:
        _, _, p, tri, b, n, (N, I) = camera_hits(sc, regions[name])
        w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
        uv = np.einsum("ij,ijk->ik", w, uv_ts[I[np.maximum(tri, 0)]])
        th = bilinear(data, uv)
        ok = (tri >= 0) & (th[:, 1] > 0) & (-(n @ L) > 0)  # the shader's test: a far face, the light behind
        p, n, th = p[ok], n[ok], th[ok]
        h = th[:, 0] / th[:, 1]
        half = np.sqrt(3.0 * np.array([law.transmitted_variance(x)[0] for x in h]))
        r = replica(geo, p, n, h, half, L)
        # the layout's uv per scene unit on each pixel's triangle (the shader's screen derivatives)
        tr = tri[ok]
        E = geo.P[geo.I[tr]]
        U = uv_ts[geo.I[tr]]
        Pm = np.stack([E[:, 1] - E[:, 0], E[:, 2] - E[:, 0]], 2)
        Um = np.stack([U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]], 2)
        PmT = np.transpose(Pm, (0, 2, 1))
        M = Um @ np.linalg.inv(PmT @ Pm) @ PmT
        s_new, cos_new = surface_taps(geo, p, n, h, half, L, uv[ok], M, points)
        print(f"[{name} {regions[name]}: bake h {np.median(h):.2f} mm, half-width {np.median(half):.2f} mm]")
        summary(name, r)
        cs = s_new * r["cos_P"]  # the shader's cosine: at -Ng
        print(f"    round 23's taps on the far face: s {np.mean(s_new):.3f}, cos x s {np.mean(cs):.3f}; |s - ref_surface| per px "
              f"{np.nanmean(np.abs(s_new - r['ref_surface'])):.3f}, |cos x s - ref_surface's| {np.nanmean(np.abs(cs - r['ref_surface_cos'])):.3f} "
              f"(rounds 18-22: {np.nanmean(np.abs(r['s_box'] * r['cos_P'] - r['ref_surface_cos'])):.3f}); with the cosine at the "
              f"kept points' least-squares plane (tried, not kept): {np.mean(cos_new):.3f}, cos x s {np.mean(s_new * cos_new):.3f}")
        if getattr(a, "lattice", False):
            s_lat, used = lattice_taps(geo, p, n, h, half, L, uv[ok], M, points)
            hp = lambda v: "n/a" if high_pass(v, regions[name]) is None else f"{high_pass(v, regions[name]):.4f}"  # noqa: E731
            print(f"    taps on a lattice fixed in texture space (candidate): s {np.mean(s_lat):.3f} ({np.mean(used):.1f} taps), "
                  f"|s - ref_surface| per px {np.nanmean(np.abs(s_lat - r['ref_surface'])):.3f}; high-pass of s (1.5 px): "
                  f"lattice {hp(s_lat)}, round 23's taps {hp(s_new)}, rounds 18-22's planes {hp(r['s_box'])}")


def tube(width_mm, thick_mm, length_mm=60.0, nu=256, nv=24):
    """An elliptic tube along y (semi-axes width / 2 in x, thick / 2 in z), closed by its length's far ends
    (open: they lie 30 mm away), outward normals; mm units."""
    a, c = width_mm / 2, thick_mm / 2
    th = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    ys = np.linspace(-length_mm / 2, length_mm / 2, nv)
    T, Y = np.meshgrid(th, ys)
    P = np.stack([a * np.cos(T), Y, c * np.sin(T)], -1).reshape(-1, 3)
    Nn = np.stack([c * np.cos(T), np.zeros_like(T), a * np.sin(T)], -1).reshape(-1, 3)
    Nn /= np.linalg.norm(Nn, axis=1, keepdims=True)
    idx = []
    for j in range(nv - 1):
        for i in range(nu):
            i2 = (i + 1) % nu
            v00, v01, v10, v11 = j * nu + i, j * nu + i2, (j + 1) * nu + i, (j + 1) * nu + i2
            idx += [(v00, v10, v01), (v01, v10, v11)]
    I = np.array(idx)
    # orient: outward
    tri = P[I]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = (fn * Nn[I].mean(1)).sum(1) < 0
    I[flip] = I[flip][:, ::-1]
    return P, I, Nn


def plate(x0, x1, z0, z1, y=30.0):
    """A box x0..x1, -y..y, z0..z1 (mm) as 12 triangles, outward normals per corner (flat faces: the
    normals of a box's corners are ambiguous, so each face gets its own vertices)."""
    P, I, N = [], [], []
    faces = [((x0, x1), (-y, y), z1, 2, 1.0), ((x0, x1), (-y, y), z0, 2, -1.0)]
    for (a0, a1), (b0, b1), c, axis, s in faces:
        base = len(P)
        for u, v in ((a0, b0), (a1, b0), (a1, b1), (a0, b1)):
            P.append((u, v, c))
            N.append((0.0, 0.0, s))
        I += [(base, base + 1, base + 2), (base, base + 2, base + 3)] if s > 0 else [(base, base + 2, base + 1), (base, base + 3, base + 2)]
    for xs, s in ((x0, -1.0), (x1, 1.0)):  # the plate's x sides
        base = len(P)
        for v, z in ((-y, z0), (y, z0), (y, z1), (-y, z1)):
            P.append((xs, v, z))
            N.append((s, 0.0, 0.0))
        I += [(base, base + 1, base + 2), (base, base + 2, base + 3)] if s > 0 else [(base, base + 2, base + 1), (base, base + 3, base + 2)]
    return np.array(P, float), np.array(I), np.array(N, float)


def part(a):
    import dermis
    from dermis.profiles.thin_slab import slab_law
    from dermis.verification import SKIN_ALBEDO

    law = slab_law(dermis.profiles.deon_skin(), np.array(SKIN_ALBEDO))
    th = np.radians(a.angle_deg)
    L = np.array([np.sin(th), 0.0, -np.cos(th)])  # towards the light: behind (-z), tilted towards +x
    for occluder in ("none", "plate", "body"):
        P, I, N = tube(a.width_mm, a.thickness_mm)
        if occluder == "plate":  # behind the tube's +x half: 1 mm of air past its back, a 3 mm plate
            z1 = -a.thickness_mm / 2 - 1.0
            Pp, Ip, Np = plate(0.0, 20.0, z1 - 3.0, z1)
            I = np.vstack([I, Ip + len(P)])
            P, N = np.vstack([P, Pp]), np.vstack([N, Np])
        if occluder == "body":  # the tube's -x end inside a body (the lobe's root in the cheek): x < -width / 4
            Pp, Ip, Np = plate(-40.0, -a.width_mm / 4, -30.0, a.thickness_mm / 2)
            I = np.vstack([I, Ip + len(P)])
            P, N = np.vstack([P, Pp]), np.vstack([N, Np])
        geo = Geometry(P, I, N, 1.0)
        xs = np.linspace(-0.9, 0.9, 37) * a.width_mm / 2
        if occluder == "body":
            xs = xs[xs > -a.width_mm / 4 + 0.5]
        p = np.stack([xs, np.zeros_like(xs), np.full_like(xs, 10.0)], 1)
        t, _ = geo.hit(p, np.broadcast_to([0.0, 0.0, -1.0], p.shape))
        p = p + np.array([0.0, 0.0, -1.0]) * t[:, None]
        _, n = geo.hit(p + [0, 0, 1e-3], np.broadcast_to([0.0, 0.0, -1.0], p.shape))
        te, _ = geo.hit(p - n * 0.02, -n, 1e-6)  # the thickness along -N (the bake's central ray, unsmoothed)
        h = te + 0.02
        half = np.sqrt(3.0 * np.array([law.transmitted_variance(x)[0] for x in h]))
        r = replica(geo, p, n, h, half, L)
        label = f"tube {a.width_mm:g} x {a.thickness_mm:g} mm, light {a.angle_deg:g} deg, {occluder}"
        summary(label, r)
        for lo, hi in ((-1, -0.5), (-0.5, 0.0), (0.0, 0.5), (0.5, 1.0)):
            s = (xs >= lo * a.width_mm / 2) & (xs < hi * a.width_mm / 2)
            print(f"    x/half-width {lo:+.1f}..{hi:+.1f}: h {np.mean(h[s]):.2f} mm, box {np.mean(r['s_box'][s]):.3f}, ref_plane "
                  f"{np.nanmean(r['ref_plane'][s]):.3f}, ref_surface {np.nanmean(r['ref_surface'][s]):.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    h = sub.add_parser("head")
    h.add_argument("--regions", nargs="+", default=["lobe", "helix", "scapha", "concha"])
    h.add_argument("--box", nargs=4, type=int, default=None, metavar=("X0", "Y0", "X1", "Y1"),
                   help="also a region 'box' of these frame pixels (e.g. review23's helix fold: 372 346 387 375)")
    h.add_argument("--lattice", action="store_true", help="also the taps on a lattice fixed in texture space (lattice_taps)")
    t = sub.add_parser("part")
    t.add_argument("--width-mm", type=float, default=10.0)
    t.add_argument("--thickness-mm", type=float, default=5.0)
    t.add_argument("--angle-deg", type=float, default=40.0)
    a = ap.parse_args(argv)
    {"head": head, "part": part}[a.cmd](a)


if __name__ == "__main__":
    main()
