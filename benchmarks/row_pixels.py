"""Why tsd is not the closest technique in a validate row, per pixel (issue 12, round 17 rows17).

Reads the 64 px arrays ``benchmarks/region_terms.py STORES <scene>/<mode> --save DIR`` writes (Cycles, its
no-SSS control, tsd and its variants without a term, ssss, preintegrated, lambert) and, for one row
(scene, mode, region) and the technique that beats tsd there:

* ``pixels``: splits the region into the pixels where tsd's FLIP (validate's metrics, per pixel) is worse than
  the winner's ("losing") and the rest ("winning"), with each side's share of the row's FLIP difference, the
  worst pixels' ratios to Cycles per term, and per side what subsurface scattering does in each renderer: Cycles
  over its control (the reference's walk) against tsd, tsd without the baked transfer, ssss, preintegrated over
  lambert (dermis's) -- per channel region means of the ratios.
* ``walk`` (add ``--walk``): at the same pixels' visible surface points (the camera's rays, Embree) the baked
  transfer's quantity by its own estimator (dermis.subsurface_transfer.bake.bake_transfer at those points:
  the mesh walk's same-facing transport less its flat twin, per unit uniform irradiance), with the skin walk
  (index 1.4, skin_media) and with Cycles' medium (index-matched, mean free path 0.735 / 0.247 mm, single-
  scattering albedo 0.930 / 0.782 in red / green: benchmarks/ear_translucency.py CYCLES_WALK_MEDIUM,
  RESULTS.md round 7), cosine entry; with ``--view-entry`` also both media entered along the camera ray (as
  Cycles' walk starts); and, for an environment-only scene, the transfer gathered with the taps' irradiance
  as tsd has it (the per-vertex visible fraction, interpolated) against a ray cast at the taps (256 rays).

    PYTHONPATH=src python benchmarks/row_pixels.py DIR environment nospec lips preintegrated [--walk] [--view-entry]

About 5 s (pixels), 20-60 s per medium (walk), 15-20 s (crop) at load 1-4.
"""

from __future__ import annotations

import argparse
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from region_terms import _scene

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
CYCLES_WALK_MEDIUM = {0: (0.735, 0.930), 1: (0.247, 0.782)}  # benchmarks/ear_translucency.py (no blue measured)


def split(saved: Path, name: str, mode: str, region: str, winner: str, show: int = 8):
    """Print the losing / winning split; returns (arrays, region mask, tsd - winner FLIP per region pixel)."""
    from dermis.reference.validate import metrics

    d = np.load(saved / f"{name}_{mode}.npz")
    sc = _scene(name, mode == "spec")
    ref, skin, reg = d["ref"], d["skin"], d[f"region_{region}"]
    imgs = {k[4:]: d[k] for k in d.files if k.startswith("img_")}
    fmap = {k: metrics(sc, ref, v, skin)[1] for k, v in imgs.items()}
    n = int(reg.sum())
    dd = fmap["tsd"][reg] - fmap[winner][reg]
    lose = dd > 0
    print(f"===== {name}/{mode} {region} ({n} px): tsd {fmap['tsd'][reg].mean():.4f}, {winner} {fmap[winner][reg].mean():.4f}; "
          f"losing {lose.sum()} px +{dd[lose].sum() / n:.4f}, winning {(~lose).sum()} px {dd[~lose].sum() / n:+.4f}")
    ys, xs = np.nonzero(reg)
    cols = ["tsd", winner, "tsd-no-transfer", "tsd-no-bounce", "control", "lambert"]
    print("  worst pixels (y, x): FLIP tsd / winner | ratio to Cycles R G B: " + ", ".join(cols))
    for i in np.argsort(-dd)[:show]:
        r = [imgs[k][ys[i], xs[i]] / ref[ys[i], xs[i]] for k in cols]
        print(f"    ({ys[i]:2d},{xs[i]:2d}) {fmap['tsd'][ys[i], xs[i]]:.3f} / {fmap[winner][ys[i], xs[i]]:.3f} | "
              + " | ".join(f"{v[0]:.2f} {v[1]:.2f} {v[2]:.2f}" for v in r))
    R = {k: v[reg] for k, v in imgs.items()}
    tr = (R["tsd"] - R["tsd-no-transfer"])[:, 0] / ref[reg][:, 0]
    for label, s in (("losing", lose), ("winning", ~lose)):
        m = lambda a, b: (a[s] / b[s]).mean(0)
        print(f"  {label} ({s.sum()} px): transfer / Cycles red {tr[s].mean():+.4f}; luminance to Cycles tsd "
              f"{((R['tsd'] @ LUMINANCE) / (ref[reg] @ LUMINANCE))[s].mean():.3f}, {winner} "
              f"{((R[winner] @ LUMINANCE) / (ref[reg] @ LUMINANCE))[s].mean():.3f}")
        print("    what SSS does, R G B: Cycles / control " + " ".join(f"{v:.3f}" for v in m(ref[reg], R["control"]))
              + " | tsd / lambert " + " ".join(f"{v:.3f}" for v in m(R["tsd"], R["lambert"]))
              + " | tsd-no-transfer / lambert " + " ".join(f"{v:.3f}" for v in m(R["tsd-no-transfer"], R["lambert"]))
              + " | ssss / lambert " + " ".join(f"{v:.3f}" for v in m(R["ssss"], R["lambert"]))
              + " | preintegrated / lambert " + " ".join(f"{v:.3f}" for v in m(R["preintegrated"], R["lambert"]))
              + " | lambert / control " + " ".join(f"{v:.3f}" for v in m(R["lambert"], R["control"])))
    return sc, reg, dd


def surface_points(sc, reg):
    """The visible points of the region's pixel centres: BakePoints (texture-space uv, mm, triangle, facet
    normal towards the camera) and the unit view directions (towards the surface)."""
    from dermis.geometry.raycast import RayCaster
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.reference.render import camera_rays
    from dermis.subsurface_transfer.bake import BakePoints

    mesh, mm = sc.mesh, float(sc.mm_per_unit)
    o, d, tmax, _ = camera_rays(sc, reg.shape[::-1], 1)
    pix = np.nonzero(reg.reshape(-1))[0]
    pos = np.asarray(mesh.positions, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    t, tri, bc = RayCaster(pos, idx).closest_hit(o[pix], d[pix], 0.0, tmax[pix])
    if (tri < 0).any():
        raise SystemExit("a region pixel's centre ray misses the mesh")
    view = d[pix] / np.linalg.norm(d[pix], axis=1, keepdims=True)
    bary = np.c_[1.0 - bc.sum(1), bc]
    p = (o[pix] + d[pix] * t[:, None]) * mm
    fn = np.cross(pos[idx[tri, 1]] - pos[idx[tri, 0]], pos[idx[tri, 2]] - pos[idx[tri, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    fn *= np.where((fn * view).sum(1) < 0.0, 1.0, -1.0)[:, None]
    uv = np.einsum("nk,nkc->nc", bary, np.asarray(texture_space_uvs(mesh), np.float64)[idx[tri]])
    return BakePoints(uv, p, tri, fn), view


@contextmanager
def walks_along(B, pts, view):
    """Inside it, the transfer bake (module ``B``, dermis.subsurface_transfer.bake) starts each point's
    walks along its camera ray ``view`` (the point's row of pts; the flat twin too: the same views), as
    Cycles' walk enters along the view; ``view`` None: its own cosine entry."""
    orig = B.diffuse_views
    if view is not None:
        lut = {tuple(np.round(nn, 9)): v for nn, v in zip(pts.normal, view)}

        def views(normals, rng):
            out = orig(normals, rng)
            for i, nn in enumerate(np.asarray(normals)):
                out[i] = lut.get(tuple(np.round(nn, 9)), out[i])
            return out

        B.diffuse_views = views
    try:
        yield
    finally:
        B.diffuse_views = orig


def walk(sc, reg, dd, walks: int, view_entry: bool):
    from dermis.reference.random_walk import WalkMedium
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    pts, view = surface_points(sc, reg)
    albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
    skin = B.skin_media(sc.profile, albedo)
    cyc = tuple(WalkMedium(*CYCLES_WALK_MEDIUM[c], "fresnel", 1.0) for c in (0, 1, 1))
    kernels = {"skin": [B.flat_kernel(m) for m in skin], "cycles": [B.flat_kernel(m) for m in cyc]}
    lose = dd > 0
    ndv = -(pts.normal * view).sum(1)
    print(f"  walk at the visible points ({walks} walks a point): N.V losing {ndv[lose].mean():.3f}, winning {ndv[~lose].mean():.3f}")
    runs = [("skin, cosine entry", skin, "skin", False), ("Cycles' medium, cosine entry", cyc, "cycles", False)]
    if view_entry:
        runs += [("skin, view entry", skin, "skin", True), ("Cycles' medium, view entry", cyc, "cycles", True)]
    skin_bake = None
    for label, media, kk, along_view in runs:
        with walks_along(B, pts, view if along_view else None):
            bk = B.bake_transfer(sc.mesh, float(sc.mm_per_unit), sc.profile, albedo, points=pts, walks=walks,
                                 media=media, kernels=kernels[kk], seed=0)
        if skin_bake is None:
            skin_bake = bk
        for side, s in (("losing", lose), ("winning", ~lose)):
            print(f"    {label:30s} {side:8s} excess (uniform light) R {bk.total[s, 0].mean():+.4f} G {bk.total[s, 1].mean():+.4f}"
                  f"  same-facing transport / flat R {bk.kept[s, 0].mean():.3f} G {bk.kept[s, 1].mean():.3f}")
    shipped = _shipped(sc, pts)
    if shipped is not None:
        tot, inside = shipped
        for side, s in (("losing", lose), ("winning", ~lose)):
            q = s & inside
            print(f"    the shipped bake (points within 2 texels) {side:8s} {q.sum()} of {s.sum()} px covered, excess R "
                  f"{tot[q, 0].mean() if q.any() else float('nan'):+.4f}")
    if not sc.lights:
        _tap_irradiance(sc, pts, skin_bake, lose)


def _shipped(sc, pts):
    from scipy.spatial import cKDTree

    from dermis.subsurface_transfer.store import find

    b = find(sc)
    if b is None:
        print("    no shipped bake for this scene in the cache folder")
        return None
    grid = int(b.meta.get("grid", 512))
    dist, j = cKDTree(np.asarray(b.point_uv, np.float64)).query(pts.uv)
    return b.total[j], dist < 2.0 / grid


def _tap_irradiance(sc, pts, bk, lose, rays: int = 256, uv_grid: int = 2048):
    """The transfer gathered with the environment irradiance at its taps: tsd's (per-vertex visible fraction,
    interpolated over the triangle the tap's uv lies in) against a ray cast at the tap's position."""
    from dermis.environment import environment_sh, irradiance_sh_eval
    from dermis.geometry.rasterize import rasterize_uv
    from dermis.geometry.raycast import RayCaster
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.geometry.visibility import environment_radiance, mesh_visibility, occluded_fraction

    mesh, mm = sc.mesh, float(sc.mm_per_unit)
    env = sc.environment
    sh = environment_sh(env)
    rad = environment_radiance(env) if env.image is not None else None
    frac_v = mesh_visibility(mesh).environment_fraction(env)
    pos = np.asarray(mesh.positions, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    nrm = np.asarray(mesh.normals, np.float64)
    tri_r, bar_r = rasterize_uv(np.asarray(texture_space_uvs(mesh), np.float64), idx, uv_grid, uv_grid)
    rc = RayCaster(pos, idx)

    def per_vertex(uvq):
        col = np.clip((uvq[:, 0] * uv_grid).astype(int), 0, uv_grid - 1)
        row = np.clip(((1.0 - uvq[:, 1]) * uv_grid).astype(int), 0, uv_grid - 1)
        t, b = tri_r[row, col], bar_r[row, col].astype(np.float64)
        ok = t >= 0
        t = np.where(ok, t, 0)
        n = np.einsum("nk,nkc->nc", b, nrm[idx[t]])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        e = np.clip(np.einsum("nk,nkc->nc", b, frac_v[idx[t]]), 0.0, 1.0) * irradiance_sh_eval(sh, n)
        return np.where(ok[:, None], e, 0.0), n

    def ray_cast(p_mm, n):
        a, _, dirs, occ = rc.ambient_rays(p_mm / mm, n, rays, offset=1e-5 * np.linalg.norm(pos.max(0) - pos.min(0)), seed=3)
        f = np.repeat(a[:, None], 3, 1) if rad is None else occluded_fraction(sh, rad, n, a, dirs, occ)
        return f * irradiance_sh_eval(sh, n)

    n_pts, K = bk.tap_weight.shape[:2]
    w = bk.tap_weight.reshape(-1, 3).astype(np.float64)
    Ev, tn = per_vertex(bk.tap_uv.reshape(-1, 2).astype(np.float64))
    Er = ray_cast(bk.tap_position.reshape(-1, 3).astype(np.float64), tn)
    Tv, Tr = (w * Ev).reshape(n_pts, K, 3).sum(1), (w * Er).reshape(n_pts, K, 3).sum(1)
    _, n0 = per_vertex(pts.uv)
    E0 = ray_cast(pts.position, n0)
    for side, s in (("losing", lose), ("winning", ~lose)):
        print(f"    gathered transfer / E(x_o), R G, {side:8s}: taps' irradiance per vertex {np.mean(Tv[s, 0] / E0[s, 0]):+.4f} "
              f"{np.mean(Tv[s, 1] / E0[s, 1]):+.4f}, ray-cast {np.mean(Tr[s, 0] / E0[s, 0]):+.4f} {np.mean(Tr[s, 1] / E0[s, 1]):+.4f}")


def crop(name: str, mode: str, landmark: str, winner: str, size: int = 768):
    import cycles_crops as C

    import dermis
    from dermis.reference.validate import metrics
    from dermis.renderer import Renderer

    sc = dermis.load_scene(C.SCENES[name])
    if mode == "nospec":
        sc.material.rho_s = 0.0  # as cycles_crops.py score --nospec
    got = C.load_crop(C.OUT, name, landmark, sc, size, mode == "spec")
    if got is None:
        raise SystemExit(f"no current Cycles crop {name}:{landmark} ({mode}) at {size} px in {C.OUT}")
    rgba, meta = got
    sc.material.pore_strength = 0.0  # as cycles_crops.py score
    x0, y0, x1, y1 = meta["box"]
    skin = rgba[..., 3] >= 0.999
    ref = C.over_background(sc, rgba)
    imgs = {}
    with Renderer(sc, (size, size), irradiance_size=1024) as r:
        imgs["tsd"] = r.render("tsd")[y0:y1, x0:x1, :3]
        if winner in ("tsd", "ssss", "preintegrated", "lambert"):
            imgs[winner] = r.render(winner)[y0:y1, x0:x1, :3]
    with Renderer(sc, (size, size), irradiance_size=1024) as r:  # the tweak before the first render
        r.technique("tsd").transfer.add = lambda *a, **k: False
        imgs["tsd-no-transfer"] = r.render("tsd")[y0:y1, x0:x1, :3]
    tr = (imgs["tsd"] - imgs["tsd-no-transfer"])[..., 0] / np.maximum(imgs["tsd-no-transfer"][..., 0], 1e-6)
    band, rest = skin & (tr > 0.02), skin & (np.abs(tr) <= 0.002)
    print(f"  {size} px crop {name}:{landmark} {meta['box']}, floor {meta.get('floor_flip')}: skin {skin.sum()} px, "
          f"band (transfer > 2 % red) {band.sum()}, rest {rest.sum()}")
    for k, v in imgs.items():
        f, fmap = metrics(sc, ref, v, skin)
        q = lambda m: " ".join(f"{x:.3f}" for x in v[m].mean(0) / ref[m].mean(0)) if m.any() else "-"
        print(f"    {k:16s} FLIP {f['flip']:.4f}, band {fmap[band].mean() if band.any() else float('nan'):.4f}, rest "
              f"{fmap[rest].mean():.4f} | to Cycles: band {q(band)}, rest {q(rest)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("saved", type=Path, help="region_terms.py's --save folder")
    ap.add_argument("scene")
    ap.add_argument("mode", choices=("spec", "nospec"))
    ap.add_argument("region")
    ap.add_argument("winner", help="the technique (or 'control') that beats tsd in the row")
    ap.add_argument("--walk", action="store_true")
    ap.add_argument("--view-entry", action="store_true")
    ap.add_argument("--walks", type=int, default=192)
    ap.add_argument("--crop", help="a landmark of benchmarks/cycles/crops (e.g. lips, nose): the 768 px study")
    args = ap.parse_args(argv)
    sc, reg, dd = split(args.saved, args.scene, args.mode, args.region, args.winner)
    if args.walk:
        walk(sc, reg, dd, args.walks, args.view_entry)
    if args.crop:
        crop(args.scene, args.mode, args.crop, args.winner)


if __name__ == "__main__":
    main()
