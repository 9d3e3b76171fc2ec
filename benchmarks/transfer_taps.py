"""Which bake points and taps of the baked subsurface transfer a frame's pixels read, and what each
contributes (issue 12, round 21, branch taps21: front-key's mouth line, slit21's open question).

    PYTHONPATH=src python benchmarks/transfer_taps.py line OUT.npz [--scene front-key.toml] [--x 370,390] [--y 647,651]
    PYTHONPATH=src python benchmarks/transfer_taps.py report OUT.npz
    PYTHONPATH=src python benchmarks/transfer_taps.py walk OUT.npz [--points 8 --walks 4096] [--at-pixels [--camera-view]]

``line`` renders tsd at 768 px (irradiance 1024, shadow 2048: cycles_crops.py score's sizes, pore_strength 0),
reads back the blurred irradiance the gather reads (tsd's I_(k+1), dermis.gl.subsurface_transfer.source_index),
the gathered grid and the translucency target, ray casts the pixels (their surface point, texture-space uv, the
key light's N.L with its cast shadow) and the bake points (texel centres of the bake's grid: dermis.subsurface_
transfer.bake.thin_points' rasterisation) and stores, per pixel, the weight of every grid texel in what the
final pass reads there (tsd/final.frag's bilinear read of the translucency target at uv_ts, each of its
texels the (1 2 1)^2 / 16 tent over the grid: common/subsurface_transfer.glsl at level 0) and, per bake point
read, its taps' weights, uv, surface positions and the irradiance they read (numpy twin of the gather,
dermis.gl.subsurface_transfer.transfer_numpy, checked against the GPU's grid). ``report`` prints it (~30 s).
``walk`` (see :func:`walk`; 20-40 s) checks the taps against the bake's quantity walked afresh and uncompressed under
the key light, at the bake points read or (``--at-pixels``) at the pixels' own points, with the bake's cosine views
or (``--camera-view``) along the camera ray.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
SIZE = 768
SCENE = REPO / "examples" / "reference" / "front-key.toml"


def _surface_at_uv(mesh, uv, size):
    """Surface point (mesh units), interpolated normal and triangle at texture-space ``uv`` (n, 2), by the
    layout rasterised at ``size`` (nearest texel centre; -1 where no triangle covers it)."""
    from dermis.geometry.rasterize import rasterize_uv
    from dermis.geometry.texture_space import texture_space_uvs

    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    tri, bary = rasterize_uv(np.asarray(texture_space_uvs(mesh), np.float64), idx, size, size)  # row 0 = top
    x = np.clip((uv[:, 0] * size).astype(int), 0, size - 1)
    y = np.clip(((1.0 - uv[:, 1]) * size).astype(int), 0, size - 1)
    t = tri[y, x]
    b = bary[y, x]
    pos = np.asarray(mesh.positions, np.float64)
    nrm = np.asarray(mesh.normals, np.float64)
    tt = np.maximum(t, 0)
    p = np.einsum("nk,nkc->nc", b, pos[idx[tt]])
    n = np.einsum("nk,nkc->nc", b, nrm[idx[tt]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return p, n, t


def _lit(sc, p, n, L):
    """max(0, N.L) times the cast shadow (ray cast, Embree) at points ``p`` (mesh units)."""
    from dermis.geometry.raycast import RayCaster

    pos = np.asarray(sc.mesh.positions, np.float64)
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    rc = RayCaster(pos, idx)
    _, blocker, _ = rc.closest_hit(p + n * 1e-4, np.repeat(L[None], len(p), 0), 1e-4, np.inf)
    return np.maximum(n @ L, 0.0) * (blocker < 0)


def line(a) -> None:
    import dermis
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.gl.subsurface_transfer import source_index, transfer_numpy
    from dermis.reference.render import camera_rays
    from dermis.renderer import Renderer

    sc = dermis.load_scene(a.scene)
    sc.material.pore_strength = 0.0
    with Renderer(sc, (SIZE, SIZE), irradiance_size=a.irradiance_size, shadow_size=a.shadow_size) as r:
        img = r.render("tsd").astype(np.float32)
        t = r.technique("tsd")
        k = source_index(sc.profile.variances_mm2)
        I_pre = t.read_texture(t.tex[("blur", k)])[::-1].copy()  # premultiplied, row 0 = bottom (GL)
        grid = t.read_texture(t.transfer.grid_texture)[::-1].copy()  # row 0 = bottom
        trans = t.read_texture(t.tex["translucency"])[::-1].copy()
        bake = t.transfer.bake
        per_point_gpu = t.transfer.per_point()
    G = grid.shape[0]
    mesh, mm = sc.mesh, float(sc.mm_per_unit)
    pos = np.asarray(mesh.positions, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    nrm = np.asarray(mesh.normals, np.float64)
    uvs = np.asarray(texture_space_uvs(mesh), np.float64)
    L = -np.asarray(sc.lights[0].direction, float)
    L /= np.linalg.norm(L)
    o, d, tmax, _ = camera_rays(sc, (SIZE, SIZE), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    xs, ys = range(a.x[0], a.x[1] + 1), range(a.y[0], a.y[1] + 1)
    pix = np.array([y * SIZE + x for y in ys for x in xs])
    rc = RayCaster(pos, idx)
    th, tri, bc = rc.closest_hit(o[pix], d[pix], 0.0, tmax[pix])
    bary = np.c_[1.0 - bc.sum(1), bc]
    pp = o[pix] + d[pix] * th[:, None]
    pn = np.einsum("nk,nkc->nc", bary, nrm[idx[tri]])
    pn /= np.linalg.norm(pn, axis=1, keepdims=True)
    puv = np.einsum("nk,nkc->nc", bary, uvs[idx[tri]])
    pE = _lit(sc, pp, pn, L)
    # per pixel, the grid texels' weights: bilinear over the translucency target (size T), each of its texels
    # the (1 2 1)^2/16 tent over the grid at level log2(G / T) (0 when T = G)
    T = trans.shape[0]
    assert T == G, (T, G)
    tent = np.outer([1, 2, 1], [1, 2, 1]) / 16.0
    W = {}
    for i, uv in enumerate(puv):
        x, y = uv[0] * T - 0.5, uv[1] * T - 0.5
        x0, y0 = int(np.floor(x)), int(np.floor(y))
        fx, fy = x - x0, y - y0
        for (tx, ty, b) in ((x0, y0, (1 - fx) * (1 - fy)), (x0 + 1, y0, fx * (1 - fy)), (x0, y0 + 1, (1 - fx) * fy),
                            (x0 + 1, y0 + 1, fx * fy)):
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    key = (i, tx + dx, ty + dy)
                    W[key] = W.get(key, 0.0) + b * tent[dy + 1, dx + 1]
    wi = np.array([k_[0] for k_ in W]), np.array([k_[1] for k_ in W]), np.array([k_[2] for k_ in W])
    ww = np.array(list(W.values()))
    # the bake points at those texels
    puv_b = np.asarray(bake.point_uv, np.float64)
    bx, by = np.floor(puv_b[:, 0] * G).astype(int), np.floor(puv_b[:, 1] * G).astype(int)
    lookup = {(x, y): j for j, (x, y) in enumerate(zip(bx, by))}
    pt = np.array([lookup.get((x, y), -1) for x, y in zip(wi[1], wi[2])])
    used = np.unique(pt[pt >= 0])
    # the numpy gather at the points read (and the GPU's grid there)
    sub = type(bake)(point_uv=bake.point_uv[used], tap_uv=bake.tap_uv[used], tap_weight=bake.tap_weight[used],
                     kept=bake.kept[used], subtracted=bake.subtracted[used], meta=bake.meta)
    Tn = transfer_numpy(sub, I_pre)
    Tg = grid[by[used], bx[used], :3]
    # per tap: I at its uv (unpremultiplied, bilinear as the gather), its surface position
    h, w = I_pre.shape[:2]
    tuv = bake.tap_uv[used].reshape(-1, 2).astype(np.float64)
    xx, yy = tuv[:, 0] * w - 0.5, tuv[:, 1] * h - 0.5
    x0, y0 = np.floor(xx).astype(int), np.floor(yy).astype(int)
    fx, fy = xx - x0, yy - y0
    at = lambda Y, X: I_pre[np.clip(Y, 0, h - 1), np.clip(X, 0, w - 1)]
    c = (at(y0, x0) * ((1 - fx) * (1 - fy))[:, None] + at(y0, x0 + 1) * (fx * (1 - fy))[:, None]
         + at(y0 + 1, x0) * ((1 - fx) * fy)[:, None] + at(y0 + 1, x0 + 1) * (fx * fy)[:, None])
    tapI = np.where(c[:, 3:] >= 1 / 64, c[:, :3] / np.maximum(c[:, 3:], 1e-12), 0.0).reshape(len(used), -1, 3)
    tp, tn, ttri = _surface_at_uv(mesh, tuv, 4096)
    tapE = _lit(sc, tp, tn, L).reshape(len(used), -1)
    bp, bn, btri = _surface_at_uv(mesh, puv_b[used], 4096)
    bE = _lit(sc, bp, bn, L)
    # I at the points' own uv and at the pixels' uv
    def I_at(uv):
        xx, yy = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
        x0, y0 = np.floor(xx).astype(int), np.floor(yy).astype(int)
        fx, fy = xx - x0, yy - y0
        c = (at(y0, x0) * ((1 - fx) * (1 - fy))[:, None] + at(y0, x0 + 1) * (fx * (1 - fy))[:, None]
             + at(y0 + 1, x0) * ((1 - fx) * fy)[:, None] + at(y0 + 1, x0 + 1) * (fx * fy)[:, None])
        return c[:, :3] / np.maximum(c[:, 3:], 1e-12)
    np.savez_compressed(a.out, img=img, pix=pix, pp=pp * mm, pn=pn, puv=puv, pE=pE, pI=I_at(puv),
                        wi=np.stack(wi, 1), ww=ww, pt=pt, used=used, Tn=Tn, Tg=Tg, per_point_gpu=per_point_gpu,
                        tap_uv=bake.tap_uv[used], tap_w=bake.tap_weight[used].astype(np.float32), tapI=tapI,
                        tap_pos=tp.reshape(len(used), -1, 3) * mm, tap_n=tn.reshape(len(used), -1, 3), tapE=tapE,
                        b_pos=bp * mm, b_n=bn, b_E=bE, b_I=I_at(puv_b[used]), kept=bake.kept[used],
                        subtracted=bake.subtracted[used], excess=bake.excess[used], grid=grid[..., :3],
                        trans=trans[..., :3], G=G, L=L, xs=np.array(a.x), ys=np.array(a.y))
    print(f"saved {a.out}: {len(pix)} px, {len(used)} bake points read; numpy gather vs GPU grid max |diff| "
          f"{np.abs(Tn - Tg).max():.2e} (of max {np.abs(Tg).max():.3f})")


def report(a) -> None:
    z = np.load(a.out)
    pix, wi, ww, pt, used = z["pix"], z["wi"], z["ww"], z["pt"], z["used"]
    npx = len(pix)
    G = int(z["G"])
    grid = z["grid"]
    # per pixel: the read transfer (grid x weights) and its share from bake points vs empty texels
    Tpix = np.zeros((npx, 3))
    np.add.at(Tpix, wi[:, 0], ww[:, None] * grid[np.clip(wi[:, 2], 0, G - 1), np.clip(wi[:, 1], 0, G - 1)])
    covered = np.bincount(wi[:, 0], ww * (pt >= 0), npx)
    pE, pI = z["pE"], z["pI"]
    lit = pE > 1e-3
    print(f"{npx} px; mean read T_geo red {Tpix[:, 0].mean():+.4f} (lit px {Tpix[lit, 0].mean():+.4f}), green "
          f"{Tpix[:, 1].mean():+.4f}; per unit of the pixel's I_3 red {Tpix[:, 0].sum() / pI[:, 0].sum():+.3f}, "
          f"of its E0 (ray cast) {Tpix[lit, 0].sum() / pE[lit].sum():+.3f}; weight on baked texels {covered.mean():.3f}")
    # per bake point: the total weight the pixels give it, its distance to the pixels' centroid
    pw = np.bincount(np.searchsorted(used, pt[pt >= 0]), ww[pt >= 0], len(used))
    cen = z["pp"].mean(0)
    bpos, bn, bE, bI = z["b_pos"], z["b_n"], z["b_E"], z["b_I"]
    Tn, tw, tI, tE, tpos = z["Tn"], z["tap_w"], z["tapI"], z["tapE"], z["tap_pos"]
    contrib = tw * tI  # (n, taps, 3)
    order = np.argsort(-pw)
    print("bake points read, by weight (sum over the pixels; share of the total read red):")
    print("  pt   weight  share  dist(mm) z-y(mm)      N.L*sh  I3red   T_red    own   far+   far-   (T/I3)  taps red: w x I, (tapE)")
    tot = (pw[:, None] * Tn).sum(0)
    for j in order[: a.top]:
        if pw[j] < 1e-3:
            break
        d = np.linalg.norm(bpos[j] - cen)
        far = contrib[j, 1:, 0]
        print(f"  {used[j]:5d} {pw[j]:6.3f} {pw[j] * Tn[j, 0] / tot[0]:+6.3f} {d:6.2f} ({bpos[j, 1] - cen[1]:+5.2f}) "
              f"{bE[j]:6.3f} {bI[j, 0]:6.3f} {Tn[j, 0]:+7.4f} {contrib[j, 0, 0]:+6.3f} {far[far > 0].sum():+6.3f} "
              f"{far[far < 0].sum():+6.3f} ({Tn[j, 0] / max(bI[j, 0], 1e-6):+.3f}) "
              + " ".join(f"{tw[j, k, 0]:+.3f}x{tI[j, k, 0]:.2f}" for k in range(tw.shape[1]) if tw[j, k, 0] != 0))
    # the weighted mean over the points read
    wsum = pw.sum()
    print(f"weighted over the points read: T red {tot[0] / wsum:+.4f}; own tap {(pw * contrib[:, 0, 0]).sum() / wsum:+.4f}, "
          f"far taps + {(pw * np.where(contrib[:, 1:, 0] > 0, contrib[:, 1:, 0], 0).sum(1)).sum() / wsum:+.4f}, "
          f"- {(pw * np.where(contrib[:, 1:, 0] < 0, contrib[:, 1:, 0], 0).sum(1)).sum() / wsum:+.4f}; "
          f"uniform (sum of weights) {(pw * tw[:, :, 0].sum(1)).sum() / wsum:+.4f}; I3 at the points {(pw * bI[:, 0]).sum() / wsum:.3f}, "
          f"at the pixels {pI[:, 0].mean():.3f}; key E at the points {(pw * bE).sum() / wsum:.3f}, at the pixels {pE.mean():.3f}")


def walk(a) -> None:
    """At the bake points read nearest the pixels: the bake's quantity uncompressed under the key light (an
    independent check of the taps): W skin walks per point (the bake's medium and diffuse views,
    dermis.subsurface_transfer.bake.walk_exits), each same-facing exit weighted by the key light's irradiance E
    there (max(0, N.L) with its cast shadow, ray cast), less the flat kernel's share over the same-facing surface
    weighted by E at the graph's vertices (K_flat(g_v) A_v E_v beyond MIN_SURFACE_MM; within it F_flat(MIN_SURFACE_MM)
    times the K_flat-weighted mean of E over the vertices within): sum_exits w E / (W R_flat) - share, / E0; and
    the same with E = 1 (the bake's own total, to check the estimate), against the taps' sum_k w_k E(tap_k) / E0."""
    import dermis
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.reference.random_walk import MeshWalk
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    z = np.load(a.out)
    sc = dermis.load_scene(a.scene)
    mm = float(sc.mm_per_unit)
    pos = np.asarray(sc.mesh.positions, np.float64) * mm
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    vn = np.asarray(sc.mesh.normals, np.float64)
    L = z["L"]
    used, bpos = z["used"], z["b_pos"]
    cen = z["pp"].mean(0)
    order = np.argsort(np.linalg.norm(bpos - cen, axis=1))[: a.points]
    from dermis.subsurface_transfer.store import find

    bake = find(sc)
    puv = np.asarray(bake.point_uv, np.float64)[used[order]]
    p_unit, n_pt, tri = _surface_at_uv(sc.mesh, puv, int(z["G"]))
    walker = MeshWalk(pos, idx)
    if a.at_pixels:  # the pixels' own surface points instead (every k-th lit one; no taps there: that column is 0)
        from dermis.framing import framed_camera
        from dermis.reference.render import camera_rays

        lit = np.nonzero(z["pE"] > (-1.0 if a.all_pixels else 1e-3))[0]
        pick = lit[np.linspace(0, len(lit) - 1, a.points).astype(int)]
        o, d, tmax, _ = camera_rays(sc, (SIZE, SIZE), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
        pix = z["pix"][pick]
        _, tri, _ = walker.caster.closest_hit(o[pix] * mm, d[pix] / np.linalg.norm(d[pix], axis=1, keepdims=True), 0.0, np.inf)
        p_unit, n_pt = z["pp"][pick] / mm, z["pn"][pick]
        cam_view = d[pix] / np.linalg.norm(d[pix], axis=1, keepdims=True)
        used, bpos, order = z["pix"], z["pp"], pick
        z = dict(z, tap_w=np.zeros((len(z["pix"]), 8, 3)), tapE=np.zeros((len(z["pix"]), 8)))
    p0 = p_unit * mm
    no = walker._outward(tri, n_pt)
    media = B.skin_media(sc.profile, np.asarray(mean_skin_albedo(sc.material), np.float64))
    kern = [B.flat_kernel(m) for m in media[:2]]
    uv = np.asarray(texture_space_uvs(sc.mesh), np.float64)
    cenf = (pos[idx[:, 0]] + pos[idx[:, 1]] + pos[idx[:, 2]]) / 3.0
    sub = np.nonzero(np.min(np.linalg.norm(cenf[:, None] - p0[None], axis=2), 1) < 18.0)[0]
    g = B.SurfaceGraph(pos, idx[sub], vn, uv)
    remap = np.full(len(idx), -1)
    remap[sub] = np.arange(len(sub))
    start = g.nearest(p0, remap[tri])
    D = g.distances(start)
    Ev = _lit(sc, g.position / mm, g.normal, L)
    E0 = _lit(sc, p_unit, n_pt, L)

    def exit_E(ex):
        t_ = ex["triangle"]
        a_, b_, c_ = pos[idx[t_, 0]], pos[idx[t_, 1]], pos[idx[t_, 2]]
        v0, v1, v2 = b_ - a_, c_ - a_, ex["point"] - a_
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = d00 * d11 - d01 * d01
        bb, cc = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
        n = (1 - bb - cc)[:, None] * vn[idx[t_, 0]] + bb[:, None] * vn[idx[t_, 1]] + cc[:, None] * vn[idx[t_, 2]]
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return _lit(sc, ex["point"] / mm + n * 1e-4, n, L)

    W = a.walks
    if a.flat_views:
        _flat_views(walker, p0, tri, no, cam_view, media, kern, g, Ev, E0, W)
        return
    tw, tE = z["tap_w"][order], z["tapE"][order]
    for c in range(2):
        if a.camera_view:  # the camera's ray instead of cosine views; normalised by the flat twins' total at that view
            from dermis.reference.random_walk import CounterUniforms, halfspace_exits

            P_, T_, V_ = np.repeat(p0, W, 0), np.repeat(tri, W), np.repeat(cam_view, W, 0)
            st, gid, ex = CounterUniforms(31 + c), np.arange(len(P_)), {}
            walker.radiance(P_, T_, V_, media[c], exits=ex, uniforms=st, walk_ids=gid)
            ex["point_index"] = ex["walk"] // W
            tw_ = halfspace_exits(P_, walker._outward(T_, -V_), V_, media[c], st, gid)
            flat_total = np.bincount(tw_["walk"] // W, tw_["weight"], len(p0)) / W
            ex["weight"] = ex["weight"] * kern[c].reflectance / flat_total[ex["point_index"]]
        else:
            ex = B.walk_exits(walker, p0, tri, no, media[c], W, seed=70 + c)
        Ee = exit_E(ex)
        print(f"{'RG'[c]}: point  d(mm)  E0     uniform: walk-flat (bake's total)   key light: walk/E0  flat/E0  (walk-flat)/E0   taps x E / E0")
        uni_sum = dif_sum = e_sum = 0.0
        for i in range(len(p0)):
            sel = ex["point_index"] == i
            same = ex["normal"][sel] @ no[i] > 0.0
            we = ex["weight"][sel][same] / (W * kern[c].reflectance)
            fin = np.isfinite(D[i])
            off = float(np.linalg.norm(g.position[start[i]] - p0[i]))
            gv = np.maximum(D[i, fin] - off, np.linalg.norm(g.position[fin] - p0[i], axis=1))
            sf = g.normal[fin] @ no[i] > 0.0
            far = sf & (gv > B.MIN_SURFACE_MM)
            near = sf & ~far
            kfar = kern[c].at(gv[far]) * g.area[fin][far]
            kn = kern[c].at(np.maximum(gv[near], 0.05)) * g.area[fin][near]
            Enear = (kn * Ev[fin][near]).sum() / max(kn.sum(), 1e-12) if near.any() else E0[i]
            F = kern[c].within(B.MIN_SURFACE_MM)
            uni = we.sum() - F - kfar.sum()
            wE = (we * Ee[sel][same]).sum()
            fE = F * Enear + (kfar * Ev[fin][far]).sum()
            if a.at_pixels:  # slit21's flat share (slit_lips.py _kernels: K_flat at max(D, 1e-6) on every same-facing vertex)
                gs = np.maximum(D[i, fin], 1e-6)
                k21 = kern[c].at(gs) * g.area[fin] * sf
                print(f"      slit21's share: uniform {k21.sum():.3f} (exact flat 1 less the other-facing), key light "
                      f"{(k21 * Ev[fin]).sum() / max(E0[i], 1e-3):.3f}; this script's uniform {F + kfar.sum():.3f}")
            uni_sum, dif_sum, e_sum = uni_sum + uni, dif_sum + wE - fE, e_sum + E0[i]
            taps = tw[i, 0, c] * E0[i] + (tw[i, 1:, c] * tE[i, 1:]).sum()
            e0 = max(E0[i], 1e-3)
            print(f"   {used[order][i]:6d} {np.linalg.norm(bpos[order][i] - cen):5.2f} {E0[i]:.3f}   {uni:+.3f} ({tw[i, :, c].sum():+.3f})"
                  f"                  {wE / e0:.3f}    {fE / e0:.3f}    {(wE - fE) / e0:+.3f}        {taps / e0:+.3f}", flush=True)
        print(f"   sum over the points: uniform {uni_sum / len(p0):+.3f} a point; key light (walk - flat) / E0 = "
              f"{dif_sum / max(e_sum, 1e-9):+.3f} (ratio of sums); sum of (walk - flat) {dif_sum:+.4f}, of E0 {e_sum:.4f}")


def _flat_views(walker, p0, tri, no, cam_view, media, kern, g, Ev, E0, W):
    """The flat medium's own view dependence under the key light: each point's flat twins (the half-space below
    its tangent plane, dermis.reference.random_walk.halfspace_exits) along cosine views and along the camera ray,
    each exit weighted by E at the surface graph's vertex nearest to it (the plane's exits mapped to the surface
    by 3-D proximity: a tangent-plane approximation within ~1 mm), each view normalised by its twins' total."""
    from scipy.spatial import cKDTree

    from dermis.reference.random_walk import CounterUniforms, halfspace_exits
    from dermis.subsurface_transfer import bake as B

    tree = cKDTree(g.position)
    for c in range(2):
        out = {}
        for label in ("cosine", "camera"):
            P_, T_ = np.repeat(p0, W, 0), np.repeat(tri, W)
            V_ = np.repeat(cam_view, W, 0) if label == "camera" else B.diffuse_views(np.repeat(no, W, 0), np.random.default_rng(9 + c))
            st, gid = CounterUniforms(51 + c), np.arange(len(P_))
            tw_ = halfspace_exits(P_, walker._outward(T_, -V_), V_, media[c], st, gid)
            k = tw_["walk"] // W
            tot = np.bincount(k, tw_["weight"], len(p0))
            e = Ev[tree.query(tw_["point"])[1]]
            out[label] = np.bincount(k, tw_["weight"] * e, len(p0)) / np.maximum(tot, 1e-12)
        print(f"{'RG'[c]}: flat twins under the key light, sum over the {len(p0)} points / sum E0: cosine views "
              f"{out['cosine'].sum() / E0.sum():.3f}, camera ray {out['camera'].sum() / E0.sum():.3f} "
              f"(camera - cosine {(out['camera'] - out['cosine']).sum() / E0.sum():+.3f})", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sp = ap.add_subparsers(dest="cmd", required=True)
    p = sp.add_parser("line")
    p.add_argument("out")
    p.add_argument("--scene", default=str(SCENE))
    p.add_argument("--x", type=lambda s: tuple(int(v) for v in s.split(",")), default=(370, 390))
    p.add_argument("--y", type=lambda s: tuple(int(v) for v in s.split(",")), default=(647, 651))
    p.add_argument("--irradiance-size", type=int, default=1024)
    p.add_argument("--shadow-size", type=int, default=2048)
    p.set_defaults(fn=line)
    p = sp.add_parser("report")
    p.add_argument("out")
    p.add_argument("--top", type=int, default=30)
    p.set_defaults(fn=report)
    p = sp.add_parser("walk")
    p.add_argument("out")
    p.add_argument("--scene", default=str(SCENE))
    p.add_argument("--points", type=int, default=8)
    p.add_argument("--walks", type=int, default=4096)
    p.add_argument("--at-pixels", action="store_true")
    p.add_argument("--camera-view", action="store_true", help="with --at-pixels: walks along the camera ray")
    p.add_argument("--all-pixels", action="store_true", help="with --at-pixels: the shadowed pixels too")
    p.add_argument("--flat-views", action="store_true", help="with --at-pixels: the flat twins' view dependence (_flat_views)")
    p.set_defaults(fn=walk)
    a = ap.parse_args(argv)
    a.fn(a)


if __name__ == "__main__":
    main()
