"""Does the shipped subsurface transfer bake's denoising remove real transfer? (round 22, branch denoise22; issue 12)

    PYTHONPATH=src python benchmarks/denoise_truth.py [--walks 2048] [--points 10] [--dump OUT.npz]

At ``--points`` bake points of each region (the box_red.py boxes' pixels, ray cast at 768 px, each pixel's
nearest bake point of the shipped bake in 3-D), per channel: (a) the shipped bake's cosine taps (tap_weight;
own tap after smooth_own_taps, far taps as walked; ``excess[..., 0]`` is the own tap before smoothing),
(b) the shipped view term's mean over cosine views (bake.view_term at 4096 diffuse_views per point, Monte Carlo;
rim22's closed form a0 c + a1 G.N beside), (c) fresh cosine-view walks (bake_transfer at those points, --walks
walks, seed 101: independent of the bake's seed 0). Each summed over the taps twice: uniform light (E = 1) and
under the scene's first light (E = max(0, N.L) x cast shadow, ray cast at the taps' surface points, the point's
own E for tap 0; transfer_taps._lit), split into own tap (tap 0) and far taps.
The shipped taps' surface points: their texture-space uv located in the mesh's uv triangles (barycentric).
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

REGIONS = {  # name: (scene, (x0, y0, x1, y1) inclusive at 768 px); box_red.py's boxes
    "helix rim": ("back-ears", (384, 388, 404, 428)),
    "scapha": ("back-ears", (340, 292, 362, 310)),
    "lobe": ("back-ears", (290, 520, 330, 565)),
    "lid crease": ("front-key", (440, 362, 470, 372)),
    "mouth line": ("front-key", (370, 647, 390, 652)),
    "nostril rim": ("front-key", (370, 495, 398, 548)),  # the ala's edge, read off the stored Cycles frame
}


def uv_locate(uv_tri, pos_tri, q):
    """Surface points (mm or mesh units as pos_tri) of texture-space uvs ``q``: the uv triangle containing each."""
    from scipy.spatial import cKDTree

    cen = uv_tri.mean(1)
    _, cand = cKDTree(cen).query(q, k=16)
    out = np.full((len(q), 3), np.nan)
    best = np.full(len(q), -np.inf)
    for k in range(cand.shape[1]):
        t = cand[:, k]
        a, b, c = uv_tri[t, 0], uv_tri[t, 1], uv_tri[t, 2]
        v0, v1, v2 = b - a, c - a, q - a
        den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
        den = np.where(np.abs(den) < 1e-20, 1e-20, den)
        l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
        l0 = 1 - l1 - l2
        m = np.minimum(np.minimum(l0, l1), l2)
        better = m > best
        p = l0[:, None] * pos_tri[t, 0] + l1[:, None] * pos_tri[t, 1] + l2[:, None] * pos_tri[t, 2]
        out[better] = p[better]
        best[better] = m[better]
    return out, best


def box_bake_points(sc, pos, idx, mm: float, bp, box, count: int, size: int = 768) -> np.ndarray:
    """Up to ``count`` bake points (indices into ``bp``, evenly spread) within 1.5 mm of the surface the
    768 px frame's pixels in ``box`` (x0, y0, x1, y1) see first (ray cast through the framed camera)."""
    from scipy.spatial import cKDTree

    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    x0, y0, x1, y1 = box
    o, d, tmax, _ = camera_rays(sc, (size, size), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    ys, xs = np.mgrid[y0:y1 + 1, x0:x1 + 1]
    pix = (ys * size + xs).ravel()
    th, tri, _ = RayCaster(pos, idx).closest_hit(o[pix], d[pix], 0.0, tmax[pix])
    ok = tri >= 0
    dist, j = cKDTree(bp.position).query((o[pix] + d[pix] * th[:, None])[ok] * mm)
    j = np.unique(j[dist < 1.5])
    return j[np.linspace(0, len(j) - 1, min(count, len(j))).astype(int)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--walks", type=int, default=2048)
    ap.add_argument("--points", type=int, default=10)
    ap.add_argument("--regions", default=",".join(REGIONS))
    ap.add_argument("--bake", default=str(Path.home() / ".cache/dermis/subsurface_transfer/e8f02f46042d7d6dc4570a4b.npz"))
    ap.add_argument("--dump")
    ap.add_argument("--seed", type=int, default=101)
    ap.add_argument("--irradiance", help="folder of irr_<scene>.npy: tsd's gathered irradiance (the renderer's own, "
                    "captured from SubsurfaceTransfer.gather at irradiance 1024); the lit sums then use it at the taps' uv")
    a = ap.parse_args(argv)
    import dermis
    from scipy.spatial import cKDTree

    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B
    from dermis.subsurface_transfer import store
    from transfer_taps import _lit

    t0 = time.time()
    bk = store.load(Path(a.bake))
    eta = float(bk.meta["index"])
    dump = {}
    scenes = {}
    for name in a.regions.split(","):
        sname, (x0, y0, x1, y1) = REGIONS[name]
        if sname not in scenes:
            sc = dermis.load_scene(str(REPO / "examples" / "reference" / f"{sname}.toml"))
            mm = float(sc.mm_per_unit)
            pos = np.asarray(sc.mesh.positions, np.float64)
            idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
            nrm = np.asarray(sc.mesh.normals, np.float64)
            uvs = np.asarray(texture_space_uvs(sc.mesh), np.float64)
            if "bp" not in scenes:
                scenes["bp"] = B.bake_points(sc.mesh, mm)
                assert np.allclose(scenes["bp"].uv, bk.point_uv, atol=1e-6), "bake points differ from the shipped bake's"
            scenes[sname] = (sc, mm, pos, idx, nrm, uvs)
        sc, mm, pos, idx, nrm, uvs = scenes[sname]
        bp = scenes["bp"]
        L = -np.asarray(sc.lights[0].direction, float)
        L /= np.linalg.norm(L)
        j = box_bake_points(sc, pos, idx, mm, bp, (x0, y0, x1, y1), a.points)
        P = bp.position[j]
        # facet normals, outward (as the bake's walks: walker._outward)
        cen = pos[idx].mean(1) * mm
        keep = np.nonzero(cKDTree(P).query(cen, distance_upper_bound=25.0)[0] < np.inf)[0]
        remap = np.full(len(idx), -1)
        remap[keep] = np.arange(len(keep))
        from dermis.reference.random_walk import MeshWalk
        walker = MeshWalk(pos * mm, idx[keep])
        fn = bp.normal[j]
        pts = B.BakePoints(bp.uv[j], P, remap[bp.triangle[j]], fn)
        assert (pts.triangle >= 0).all()
        sub = SimpleNamespace(positions=pos, normals=nrm, indices=idx[keep], uvs=uvs, texture_space_uvs=None)
        albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
        media = B.skin_media(sc.profile, albedo)
        kernels = [B.flat_kernel(m) for m in media]
        fr = B.bake_transfer(sub, mm, sc.profile, albedo, walks=a.walks, points=pts, media=media, kernels=kernels, seed=a.seed)
        # (b) the shipped view term over cosine views
        rng = np.random.default_rng(7)
        K = 4096
        tv = bk.tap_view[j].astype(np.float64)
        vm = np.zeros(tv.shape[:3])
        for p in range(len(j)):
            vs = B.diffuse_views(np.repeat(fn[p:p + 1], K, 0), rng)
            vm[p] = B.view_term(np.repeat(tv[p:p + 1], K, 0), vs, np.repeat(fn[p:p + 1], K, 0), eta).mean(0)
        a0, a1 = 0.92319, -0.79866  # rim22's cosine-view means of 1 - F and (1 - F) r.N at index 1.4
        vcf = a0 * tv[..., 3] + a1 * np.einsum("ntcj,nj->ntc", tv[..., :3], fn)
        fvm = np.zeros(fr.tap_view.shape[:3])  # the fresh walks' own view term's cosine mean (a check of the fit)
        ftv = fr.tap_view.astype(np.float64)
        fvm = a0 * ftv[..., 3] + a1 * np.einsum("ntcj,nj->ntc", ftv[..., :3], fn)
        # irradiance at the taps
        tri_uv = uvs[idx]
        tpos, qual = uv_locate(tri_uv, pos[idx], bk.tap_uv[j].reshape(-1, 2).astype(np.float64))
        vt = cKDTree(pos)
        _, vi = vt.query(tpos)
        Es = _lit(sc, tpos, nrm[vi], L).reshape(len(j), -1)
        E0 = _lit(sc, P / mm, nrm[cKDTree(pos).query(P / mm)[1]], L)
        Es[:, 0] = E0
        ftp = fr.tap_position.reshape(-1, 3).astype(np.float64) / mm
        _, vi = vt.query(ftp)
        Ef = _lit(sc, ftp, nrm[vi], L).reshape(len(j), -1)
        Ef[:, 0] = E0
        used = np.abs(bk.tap_weight[j]).sum(2) > 0
        rows = {
            "(a) shipped cosine": bk.tap_weight[j].astype(np.float64),
            "(a0) shipped, own unsmoothed": np.concatenate([bk.excess[j][:, None, :, 0], bk.tap_weight[j, 1:]], 1).astype(np.float64),
            "(b) view term cos mean": vm,
            "(b') closed form": vcf,
            "(c) fresh walks": fr.tap_weight.astype(np.float64),
            "(c') fresh view term mean": fvm,
        }
        n = len(j)
        if a.irradiance:  # the renderer's own irradiance at the taps' uv (gl.subsurface_transfer.transfer_numpy)
            from dermis.gl.subsurface_transfer import transfer_numpy
            irr = np.load(Path(a.irradiance) / f"irr_{sname}.npy")

            def gl_sum(uv, w):
                return transfer_numpy(SimpleNamespace(tap_uv=uv, tap_weight=w.astype(np.float32)), irr)

            def gl_view(uv, tv_):
                V = transfer_numpy(SimpleNamespace(tap_uv=uv, tap_weight=tv_[..., 0].astype(np.float32), tap_view=tv_), irr, view=True)
                return a0 * V[..., 3] + a1 * np.einsum("ncj,nj->nc", V[..., :3], fn)

        print(f"== {name} ({sname}): {n} bake points, light E0 mean {E0.mean():.3f}, tap uv located min bary "
              f"{np.nanmin(qual[used.ravel()]):.3f}; {time.time() - t0:.0f} s", flush=True)
        print("   per point mean, RGB; [own tap | far taps | total]  uniform E=1;   lit: sum_k w_k E_k")
        for k, w in rows.items():
            E = Ef if k.startswith("(c") else Es
            own, far = w[:, 0], w[:, 1:].sum(1)
            lit = (w * E[..., None]).sum(1)
            if a.irradiance:
                uv = (fr if k.startswith("(c") else bk).tap_uv[j if not k.startswith("(c") else slice(None)]
                if k.startswith("(b"):
                    lit = gl_view(uv, tv)
                elif k.startswith("(c'"):
                    lit = gl_view(uv, ftv)
                else:
                    lit = gl_sum(uv, w)
                dump[f"{name}|{k}|litown"] = gl_sum(uv[:, :1], w[:, :1]) if not k.startswith("(b") else gl_view(uv[:, :1], tv[:, :1])
            se = lambda x: x.std(0) / np.sqrt(n)
            print(f"  {k:30s} own {own.mean(0).round(4)} far {far.mean(0).round(4)} tot {(own + far).mean(0).round(4)} "
                  f"+- {se(own + far).round(4)} | lit {lit.mean(0).round(4)} +- {se(lit).round(4)}", flush=True)
            dump[f"{name}|{k}|own"] = own
            dump[f"{name}|{k}|far"] = far
            dump[f"{name}|{k}|lit"] = lit
        dump[f"{name}|E0"] = E0
        ref = dump[f"{name}|(c) fresh walks|lit"]
        for k in ("(a) shipped cosine", "(a0) shipped, own unsmoothed", "(b) view term cos mean"):
            dd = dump[f"{name}|{k}|lit"] - ref
            print(f"  lit {k} / (c): {(dump[f'{name}|{k}|lit'].sum(0) / ref.sum(0)).round(3)}; paired diff "
                  f"{dd.mean(0).round(4)} +- {(dd.std(0) / np.sqrt(n)).round(4)}", flush=True)
    return finish(a.dump, dump, t0)


def finish(path, dump, t0) -> int:
    """Save the per-point arrays (``--dump``) and print the run's time; main's exit status."""
    if path:
        np.savez(path, **dump)
    print(f"{time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
