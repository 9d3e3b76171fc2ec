"""Meshing the implicit head by rays from its centre: a ring grid (columns at fixed azimuth, rows at
equal weighted arc length, denser on the face) between a Delaunay top cap and a flat bottom cap,
and angle-weighted vertex normals."""

from __future__ import annotations

import numpy as np
from scipy import ndimage, spatial

from dermis.scene.procedural_head.implicit import _raycast, _raycast_bracketed

N_COLS = 176  # ring columns (azimuth), denser on the face
N_ROWS = 112  # ring rows (hairline -> neck cut), denser on the face
CAP_POLAR = np.radians(40.0)  # the top cap covers directions within this angle of +y (from C)


def _azimuth_warp(s):
    """s in [0, 1] -> azimuth in [-pi, pi] (0 = front, +x side positive), denser on the face."""
    phi = np.linspace(-np.pi, np.pi, 4097)
    dens = 1.0 + 1.15 * np.exp(-((phi / 0.95) ** 2))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(phi))])
    cum /= cum[-1]
    return np.interp(s, cum, phi)


def _dirs(phi, elev):
    ce = np.cos(elev)
    return np.stack([ce * np.sin(phi), np.sin(elev), ce * np.cos(phi)], -1)


def _face_weight(p):
    """Row density weight: about 2.2x on the face."""
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    front = np.clip((z - 3.0) / 3.0, 0.0, 1.0)
    front = front * front * (3 - 2 * front)
    return 1.0 + 1.2 * np.exp(-((x / 4.8) ** 2) - ((y + 2.0) / 6.5) ** 2) * front


def _grid_tris(rows, cols, base=0):
    """Triangles of a (rows+1) x (cols+1) vertex grid, indexed [i, j] -> base + i*(cols+1) + j."""
    idx = base + np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    return a, b, c, d


def _split_quads(P, a, b, c, d):
    """Split the quads a-b-c-d (corners in cyclic order) along their shorter diagonal; the two
    triangles of every quad share the winding of the cycle a -> d -> c -> b (the global
    orientation is fixed afterwards by ``_orient_outward``)."""
    a, b, c, d = (x.ravel() for x in (a, b, c, d))
    ac = np.linalg.norm(P[a] - P[c], axis=1)
    bd = np.linalg.norm(P[b] - P[d], axis=1)
    use_ac = ac <= bd
    t1 = np.where(use_ac[:, None], np.stack([a, d, c], 1), np.stack([a, d, b], 1))
    t2 = np.where(use_ac[:, None], np.stack([a, c, b], 1), np.stack([d, c, b], 1))
    return np.concatenate([t1, t2])


def _orient_outward(P, tris, ref):
    """Flip the winding of all triangles if most face normals point toward ``ref`` (a point or
    a direction function)."""
    n = np.cross(P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]])
    cen = P[tris].mean(1)
    out = cen - ref if not callable(ref) else ref(cen)
    if np.sum(np.einsum("ij,ij->i", n, out)) < 0:
        tris = tris[:, ::-1].copy()
    return tris


def _disc_points(boundary_phis, K, scale_fn=None, warp=True):
    """Concentric rings in the unit disc (boundary excluded) for a cap triangulation; ring k of
    K has about len(boundary_phis) * scale_fn(k / K) points."""
    pts = [np.zeros((1, 2))]
    nb = len(boundary_phis)
    for k in range(1, K):
        r = k / K
        m = max(6, int(round(nb * (scale_fn(r) if scale_fn else r))))
        s = (np.arange(m) + 0.5 * (k % 2)) / m
        ph = _azimuth_warp(s) if warp else s * 2 * np.pi - np.pi
        pts.append(np.stack([r * np.sin(ph), r * np.cos(ph)], 1))
    return np.concatenate(pts)


def _build_head_surface(shape):
    """Ring + top cap + bottom cap of the head-and-neck surface.

    Returns dict of parts: name -> (positions, triangles) (triangles index the part's own
    vertices, counter-clockwise from outside); the ring has a duplicated seam column."""
    C = shape.C
    Nc, Nr = N_COLS, N_ROWS
    phis = _azimuth_warp(np.arange(Nc + 1) / Nc)  # column Nc repeats column 0 (seam at the back)
    e0 = np.pi / 2 - CAP_POLAR

    # reference profile (radius from the axis, height) relative to C: an arc, then down the neck
    arc_e = np.linspace(e0, np.radians(-40), 200)
    ref = np.stack([9.5 * np.cos(arc_e), 9.5 * np.sin(arc_e)], 1)
    ref = np.concatenate([ref, np.linspace(ref[-1], [4.5, shape.Y_CUT - C[1] - 6.0], 120)[1:]])
    seg = np.linalg.norm(np.diff(ref, axis=0), axis=1)
    cum = np.concatenate([[0], np.cumsum(seg)])
    M = int(Nr * 1.4)
    s = np.linspace(0, cum[-1], M)
    refp = np.stack([np.interp(s, cum, ref[:, 0]), np.interp(s, cum, ref[:, 1])], 1)
    elev = np.arctan2(refp[:, 1], refp[:, 0])  # decreasing

    # fine samples
    PH, EL = np.meshgrid(phis[:Nc], elev, indexing="ij")  # (Nc, M)
    D = _dirs(PH, EL).reshape(-1, 3)
    t_f = _raycast(shape, C, D, iters=8, tol=1e-3).reshape(Nc, M)
    P_f = C + t_f[..., None] * D.reshape(Nc, M, 3)

    # corner with the neck cut: a horizontal ray in the column's half-plane at the cut height
    hd = np.stack([np.sin(phis[:Nc]), np.zeros(Nc), np.cos(phis[:Nc])], 1)
    o = np.array([C[0], shape.Y_CUT, C[2]])
    body = type("_Body", (), {"sdf": staticmethod(shape.sdf_body)})
    tc = _raycast(body, o, hd, t_lo=0.5, t_hi=20.0, iters=10, tol=1e-4)
    corner = o + tc[:, None] * hd
    e_hi = np.arctan2(corner[:, 1] - C[1], np.hypot(corner[:, 0] - C[0], corner[:, 2] - C[2]))
    k_last = np.sum(elev[None, :] > e_hi[:, None], axis=1) - 1
    assert np.all(k_last < M - 1) and np.all(k_last > M // 2), "ring sampling misses the neck cut"

    # per-column weighted arc length -> row elevations.  The arc length is measured on the
    # column profile smoothed along the column (small cavities such as the nostrils must not
    # shift all the rows below them) and the resulting row fractions are smoothed across
    # columns, so that rows stay aligned between neighbouring columns (no sheared slivers).
    lam = np.empty((Nc, Nr))
    targets = np.arange(Nr) / Nr
    Ps = ndimage.gaussian_filter1d(P_f, 2.0, axis=1, mode="nearest")
    for j in range(Nc):
        k = k_last[j]
        pts = np.concatenate([Ps[j, : k + 1], corner[j : j + 1]])
        ee = np.concatenate([elev[: k + 1], [e_hi[j]]])
        mid = 0.5 * (pts[1:] + pts[:-1])
        L = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1) * _face_weight(mid))])
        L /= L[-1]
        lam[j] = (e0 - np.interp(targets, L, ee)) / (e0 - e_hi[j])
    lam = ndimage.gaussian_filter1d(lam, 2.0, axis=0, mode="wrap")
    rows_e = e0 - lam * (e0 - e_hi[:, None])
    rows_tg = np.stack([np.interp(-rows_e[j], -elev, t_f[j]) for j in range(Nc)])
    PH2 = np.broadcast_to(phis[:Nc, None], (Nc, Nr))
    D2 = _dirs(PH2, rows_e).reshape(-1, 3)
    t2 = _raycast_bracketed(shape, C, D2, rows_tg.ravel(), half=0.4, iters=6)
    ring = np.empty((Nr + 1, Nc + 1, 3))
    ring[:Nr, :Nc] = (C + t2[:, None] * D2).reshape(Nc, Nr, 3).transpose(1, 0, 2)
    ring[Nr, :Nc] = corner
    ring[:, Nc] = ring[:, 0]
    ringP = ring.reshape(-1, 3)
    a, b, c, d = _grid_tris(Nr, Nc)
    ringT = _split_quads(ringP, a, b, c, d)
    ringT = _orient_outward(ringP, ringT, C)

    # top cap: boundary = ring row 0 (directions at polar angle CAP_POLAR around +y)
    Kt = 22
    sin0 = np.sin(CAP_POLAR)
    inner = _disc_points(phis[:Nc], Kt, scale_fn=lambda r: np.sin(r * CAP_POLAR) / sin0)
    bnd = np.stack([np.sin(phis[:Nc]), np.cos(phis[:Nc])], 1)
    q = np.concatenate([bnd, inner])
    capT = spatial.Delaunay(q).simplices
    r = np.linalg.norm(inner, axis=1)
    ph = np.arctan2(inner[:, 0], inner[:, 1])
    g = r * CAP_POLAR
    di = np.stack([np.sin(g) * np.sin(ph), np.cos(g), np.sin(g) * np.cos(ph)], 1)
    ti = _raycast(shape, C, di, iters=10)
    capP = np.concatenate([ring[0, :Nc], C + ti[:, None] * di])
    capT = _orient_outward(capP, capT, C)

    # bottom cap: flat, boundary = ring row Nr
    cen = corner.mean(0)
    rel = corner - cen
    ang = np.arctan2(rel[:, 0], rel[:, 2])
    rad = np.hypot(rel[:, 0], rel[:, 2])
    order = np.argsort(ang)
    Kb = 13
    innerb = _disc_points(phis[:Nc], Kb, warp=False)
    bndb = np.stack([np.sin(ang), np.cos(ang)], 1)
    qb = np.concatenate([bndb, innerb])
    botT = spatial.Delaunay(qb).simplices
    rb = np.linalg.norm(innerb, axis=1)
    ab = np.arctan2(innerb[:, 0], innerb[:, 1])
    radi = np.interp(ab, ang[order], rad[order], period=2 * np.pi)
    pb = np.stack([cen[0] + rb * radi * np.sin(ab), np.full_like(rb, shape.Y_CUT), cen[2] + rb * radi * np.cos(ab)], 1)
    botP = np.concatenate([corner, pb])
    botT = _orient_outward(botP, botT, lambda c_: np.tile([0.0, -1.0, 0.0], (len(c_), 1)))
    return {"ring": (ringP, ringT), "top_cap": (capP, capT), "bottom_cap": (botP, botT)}, ring




def _vertex_normals(P, T, group):
    """Angle-weighted vertex normals, shared by vertices with the same ``group`` id."""
    fn = np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-30)
    ng = group.max() + 1
    acc = np.zeros((ng, 3))
    for k in range(3):
        a = P[T[:, (k + 1) % 3]] - P[T[:, k]]
        b = P[T[:, (k + 2) % 3]] - P[T[:, k]]
        cosang = np.einsum("ij,ij->i", a, b) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-30)
        w = np.arccos(np.clip(cosang, -1, 1))
        for c in range(3):
            acc[:, c] += np.bincount(group[T[:, k]], fn[:, c] * w, ng)
    n = acc[group]
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
