"""The baked subsurface transfer's view term (round 22, branch view22) against fresh walks along the camera ray,
at the surface points a frame's pixels see (issue 12: front-key's mouth line, the back-lit ear's scapha).

    PYTHONPATH=src python benchmarks/view_transfer.py [--scene examples/reference/front-key.toml] [--x 370,390]
        [--y 647,651] [--points 24] [--walks 1024] [--all-pixels] [--size 768]

At ``--points`` pixels of the box (every k-th; the lit ones only unless ``--all-pixels``) the pixel's surface point
(camera ray cast, framed as the renderer frames it) is baked twice by the bake's own estimator
(dermis.subsurface_transfer.bake.bake_transfer at those points, the skin media, CRN twins, ``--walks`` walks a
point and channel): along cosine views (the bake's: its mean w_k and its view term, tap_view) and along the
camera ray alone (``views=``: fresh walks, independent seeds). Under the scene's first light (E = max(0, N.L) with
its cast shadow, ray cast at the taps' surface points; at the point itself for its own tap) it prints, per
channel, summed over the points: the cosine views' sum_k w_k E_k, the view term at the camera
sum_k (1 - F(v)) (G_k . r(v) + c_k) E_k (view_term) and the fresh camera-ray walks' sum_k w'_k E'_k, each with its
standard error (over the points), and divided by the points' sum of E0 (the pixels' own irradiance).
The mesh is cut to the triangles within 25 mm of the points (walks that reach the cut are lost: rare at skin's
millimetre mean free paths). ~1-3 min for 24 points at 1024 walks on 2 shared cores.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=str(REPO / "examples" / "reference" / "front-key.toml"))
    ap.add_argument("--x", type=lambda s: tuple(int(v) for v in s.split(",")), default=(370, 390))
    ap.add_argument("--y", type=lambda s: tuple(int(v) for v in s.split(",")), default=(647, 651))
    ap.add_argument("--points", type=int, default=24)
    ap.add_argument("--walks", type=int, default=1024)
    ap.add_argument("--size", type=int, default=768)
    ap.add_argument("--all-pixels", action="store_true")
    ap.add_argument("--dump", help="write the per-point rows, N.V (facet normal) and E0 to this .npz")
    a = ap.parse_args(argv)
    import dermis
    from scipy.spatial import cKDTree

    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.reference.random_walk import MeshWalk
    from dermis.reference.render import camera_rays
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B
    from transfer_taps import _lit

    t0 = time.time()
    sc = dermis.load_scene(a.scene)
    mm = float(sc.mm_per_unit)
    pos = np.asarray(sc.mesh.positions, np.float64)
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    nrm = np.asarray(sc.mesh.normals, np.float64)
    L = -np.asarray(sc.lights[0].direction, float)
    L /= np.linalg.norm(L)
    S = a.size
    o, d, tmax, _ = camera_rays(sc, (S, S), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    pix = np.array([y * S + x for y in range(a.y[0], a.y[1] + 1) for x in range(a.x[0], a.x[1] + 1)])
    rc = RayCaster(pos, idx)
    th, tri, bc = rc.closest_hit(o[pix], d[pix], 0.0, tmax[pix])
    ok = tri >= 0
    pix, th, tri, bc = pix[ok], th[ok], tri[ok], bc[ok]
    bary = np.c_[1.0 - bc.sum(1), bc]
    pp = o[pix] + d[pix] * th[:, None]
    pn = np.einsum("nk,nkc->nc", bary, nrm[idx[tri]])
    pn /= np.linalg.norm(pn, axis=1, keepdims=True)
    E0 = _lit(sc, pp, pn, L)
    cand = np.arange(len(pix)) if a.all_pixels else np.nonzero(E0 > 1e-3)[0]
    pick = cand[np.linspace(0, len(cand) - 1, min(a.points, len(cand))).astype(int)]
    pp, pn, tri, E0 = pp[pick], pn[pick], tri[pick], E0[pick]
    view = d[pix[pick]] / np.linalg.norm(d[pix[pick]], axis=1, keepdims=True)  # towards the surface
    # the mesh within 25 mm of the points
    cen = pos[idx].mean(1) * mm
    keep = np.nonzero(cKDTree(pp * mm).query(cen, distance_upper_bound=25.0)[0] < np.inf)[0]
    remap = np.full(len(idx), -1)
    remap[keep] = np.arange(len(keep))
    uvs = np.asarray(texture_space_uvs(sc.mesh), np.float64)
    sub = SimpleNamespace(positions=pos, normals=nrm, indices=idx[keep], uvs=uvs, texture_space_uvs=None)
    walker = MeshWalk(pos * mm, idx[keep])
    t_sub = remap[tri]
    fn = walker._outward(t_sub, pn)
    pts = B.BakePoints(np.zeros((len(pp), 2)), pp * mm, t_sub, fn)
    albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
    media = B.skin_media(sc.profile, albedo)
    kernels = [B.flat_kernel(m) for m in media]
    print(f"{len(pp)} points (E0 mean {E0.mean():.3f}, N.V mean {(-(view * fn).sum(1)).mean():.3f}), "
          f"{len(keep)} triangles; {time.time() - t0:.0f} s", flush=True)
    cos = B.bake_transfer(sub, mm, sc.profile, albedo, walks=a.walks, points=pts, media=media, kernels=kernels, seed=11)
    print(f"cosine bake {time.time() - t0:.0f} s", flush=True)
    cam = B.bake_transfer(sub, mm, sc.profile, albedo, walks=a.walks, points=pts, media=media, kernels=kernels, seed=23,
                          views=view)
    print(f"camera bake {time.time() - t0:.0f} s", flush=True)
    vtree = cKDTree(pos * mm)

    def tap_E(bk):
        tp = bk.tap_position.reshape(-1, 3).astype(np.float64)
        _, j = vtree.query(tp)
        E = _lit(sc, tp / mm, nrm[j], L).reshape(bk.tap_position.shape[:2])
        E[:, 0] = E0  # the own tap: the point's own light
        return E

    Ec, Ef = tap_E(cos), tap_E(cam)
    seen = B.view_term(cos.tap_view, view, fn, media[0].index)  # (n, taps, 3)
    rows = {"cosine views": (cos.tap_weight * Ec[..., None]).sum(1),
            "view term at the camera": (seen * Ec[..., None]).sum(1),
            "fresh walks along the camera ray": (cam.tap_weight * Ef[..., None]).sum(1)}
    n = len(pp)
    print(f"sum over {n} points of sum_k T_k E_k (+- s.e.), and / sum E0 ({E0.sum():.3f}); uniform light (E = 1) beside")
    for name, v in rows.items():
        se = v.std(0) * np.sqrt(n)
        print(f"  {name:34s} " + "  ".join(f"{'RGB'[c]} {v[:, c].sum():+.4f} +- {se[c]:.4f} ({v[:, c].sum() / max(E0.sum(), 1e-9):+.3f} E0)"
                                               for c in range(3)))
    uni = {"cosine views": cos.tap_weight.sum(1), "view term at the camera": seen.sum(1), "fresh walks along the camera ray": cam.tap_weight.sum(1)}
    for name, v in uni.items():
        print(f"  uniform {name:26s} " + "  ".join(f"{'RGB'[c]} {v[:, c].mean():+.4f} +- {v[:, c].std() / np.sqrt(n):.4f}" for c in range(3)))
    if a.dump:
        np.savez(a.dump, cos_v=-(view * fn).sum(1), E0=E0, **{k.replace(" ", "_"): v for k, v in rows.items()},
                 **{"uniform_" + k.replace(" ", "_"): v for k, v in uni.items()})
    print(f"{time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
