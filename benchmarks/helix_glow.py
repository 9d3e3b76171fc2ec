"""The back-lit helix's glow against Cycles at 768 px, term by term (issue 12, round 15, ear15).

Over the back-ears "ear +x" crop (benchmarks/cycles/crops/back-ears--ear+x.npz: Cycles, 256 spp x 2 seeds,
the 768 px frame's own window) tsd's red mean is 0.98 of Cycles', but along the glow line inside the helix
Cycles is ~1.7x tsd (RESULTS, round 14). This script says which of tsd's terms is short there and whether
the medium difference (Cycles' index-matched random walk against the index-1.4 skin walk dermis models)
predicts it:

1. terms: tsd rendered at 768 px (4x MSAA, irradiance 1024^2, pore_strength 0 as cycles_crops.py score)
   with everything, without translucency (far face and baked transfer), without the baked transfer, without
   the skin-to-skin bounce; differences give each term's radiance per pixel.
2. pixel classes along each crop row (rows 100-369): "rim" (the ear's outermost 4 px, the silhouette),
   "glow line" (the most prominent peak, prominence >= 0.01, of Cycles' 7x7-smoothed red 10-60 px inside
   the rim: the line where crops14 saw Cycles' glow of red 0.17-0.21; chosen on the reference, so its
   noise biases Cycles' value up by a few %), "helix band" (between the
   glow line + 3 px and the rim - 5 px), "scapha" (25 px inside the glow line). The ear: surface points
   past 0.85 of the largest distance from the midline (ear_translucency.py's rule).
3. geometry per class by ray casting (dermis.geometry.raycast): N.V, N.L, the tissue's thickness along
   -N (what tsd's thickness bake measures), the far face's N.L and whether it is lit.
4. slab Monte Carlo (dermis.profiles.monte_carlo, red) at the glow line's thickness quartiles and the
   band's median: the skin walk (index 1.4, dermis.verification's medium, light entering the far face at
   its measured cosine) against Cycles' walk (dermis.blender.sss's radius and base colour: mean free path
   radius / 4 pi, single-scattering albedo by Cycles' remap (Chiang et al. 2016), index-matched, entered
   head-on or cosine-distributed: ear_translucency._cycles_walk), and the thin-slab law tsd uses.
5. random walks in the head's own geometry (dermis.reference.random_walk.MeshWalk, red, the scene's light
   with shadow rays and its environment, no bounce, no specular) from each class's pixels: the skin walk,
   Cycles' walk entered along the refracted view ray and cosine-distributed (ear_translucency's media).

    PYTHONPATH=src python benchmarks/helix_glow.py [--walks 128] [--photons 100000] [--save DIR]

About 2.5 min on 2 cores at load 1-2, 5.5 min at load 5 (the renders 11 s; the walks most of it). Needs the
stored crop (nothing is rendered in Cycles) and, for the image users see, the head's subsurface transfer bake in
~/.cache/dermis.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cycles_crops  # noqa: E402
from ear_translucency import CYCLES_WALK_MEDIUM, EAR_FRACTION, _cycles_walk, chiang_alpha  # noqa: E402

SIZE = 768
CHANNEL = 0  # red: green and blue carry nothing through millimetres of tissue
ROWS = range(100, 370)
GLOW_SEARCH_PX = (10, 60)  # the glow line is looked for this many px inside the silhouette
GLOW_PROMINENCE = 0.01  # linear red: a peak of Cycles' smoothed red at least this far above its surroundings


def _scene():
    import dermis

    sc = dermis.load_scene(cycles_crops.SCENES["back-ears"])
    sc.material.pore_strength = 0.0  # as cycles_crops.py score (the export has no pores)
    return sc


def render_terms(box):
    """{variant: (h, w, 3) linear RGB of the crop window}: tsd whole and with one term off."""
    from dermis.renderer import Renderer

    def no_transfer(r):
        r.technique("tsd").transfer.add = lambda *a, **k: False  # the bake's taps not gathered

    variants = {"tsd": (None, False), "no_translucency": (lambda r: r.technique("tsd", translucency=False), False),
                "no_transfer": (no_transfer, False), "no_bounce": (None, True)}
    x0, y0, x1, y1 = box
    out = {}
    for name, (tweak, no_bounce) in variants.items():
        sc = _scene()
        if no_bounce:
            sc.interreflection = False
        with Renderer(sc, (SIZE, SIZE), irradiance_size=1024) as r:
            if tweak:
                tweak(r)
            out[name] = r.render("tsd")[y0:y1, x0:x1, :3]
    return out


def camera_hits(sc, box):
    """Per crop pixel (pixel centre ray, dermis.reference.render.camera_rays of the frame): the ray
    caster, ray direction, hit point, triangle, barycentrics, interpolated unit normal, (normals, indices)."""
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    x0, y0, x1, y1 = box
    o, d, tmax, _ = camera_rays(sc, (SIZE, SIZE), camera=framed_camera(sc.camera, sc.mesh, 1.0))
    ys, xs = np.mgrid[y0:y1, x0:x1]
    sel = (ys * SIZE + xs).reshape(-1)
    o, d, tmax = o[sel], d[sel], tmax[sel]
    P = np.asarray(sc.mesh.positions, np.float64)
    I = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    N = np.asarray(sc.mesh.normals, np.float64)
    rc = RayCaster(P, I)
    t, tri, b = rc.closest_hit(o, d, 0.0, tmax)
    p = o + d * np.where(tri >= 0, t, 0.0)[:, None]
    w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
    n = np.einsum("ij,ijk->ik", w, N[I[np.maximum(tri, 0)]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return rc, d, p, tri, b, n, (N, I)


def classes(sc, cycles_red, p, shape):
    """{class: (h, w) bool} (the module docstring's 2.): per crop row, from the ear's silhouette inward."""
    from scipy.ndimage import label, uniform_filter
    from scipy.signal import find_peaks

    P = np.asarray(sc.mesh.positions, np.float64)
    up = P[:, 1] > 0.5 * (P[:, 1].min() + P[:, 1].max())
    mid = 0.5 * (P[up, 0].min() + P[up, 0].max())
    ear = (p[:, 0] - mid).reshape(shape) > EAR_FRACTION * (P[up, 0] - mid).max()
    lab, _ = label(ear)  # the ear itself: its largest connected piece (not a patch of the skull beside it)
    ear = lab == np.argmax(np.bincount(lab.ravel())[1:]) + 1
    smooth = uniform_filter(cycles_red, 7)
    cls = {k: np.zeros_like(ear) for k in ("rim", "glow line", "helix band", "scapha")}
    for y in ROWS:
        xe = np.nonzero(ear[y])[0]
        if len(xe) < 20:
            continue
        xr = xe.max()
        cls["rim"][y, xr - 3:xr + 1] = True
        lo = max(xr - GLOW_SEARCH_PX[1], 0)
        peaks, prop = find_peaks(smooth[y, lo:xr - GLOW_SEARCH_PX[0]], prominence=GLOW_PROMINENCE)
        if not len(peaks):
            continue
        xi = lo + int(peaks[np.argmax(prop["prominences"])])
        cls["glow line"][y, xi - 1:xi + 2] = True
        cls["helix band"][y, xi + 3:xr - 5] = True
        cls["scapha"][y, max(xi - 25, 0):xi - 3] = True
    return {k: m & ear for k, m in cls.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walks", type=int, default=128, help="random walks per pixel in the head's geometry")
    ap.add_argument("--photons", type=int, default=100_000, help="slab Monte Carlo photons per run")
    ap.add_argument("--save", type=Path, help="write the crop's images, classes and term maps here (.npz)")
    a = ap.parse_args(argv)
    from dermis.blender.sss import cycles_subsurface
    from dermis.blender.validate import _albedo_at
    from dermis.profiles.medium import Layer, Medium
    from dermis.profiles.monte_carlo import monte_carlo_reflectance
    from dermis.profiles.thin_slab import slab_law
    from dermis.reference.random_walk import DirectionalLight, MeshWalk, WalkMedium
    from dermis.scene.model import mean_skin_albedo
    from dermis.verification import random_walk_albedo, random_walk_slab

    sc = _scene()
    crop = cycles_crops.load_crop(cycles_crops.OUT, "back-ears", "ear +x", sc, SIZE)
    if crop is None:
        sys.exit("helix_glow: no current Cycles crop back-ears--ear+x.npz (stale or missing)")
    rgba, meta = crop
    box = meta["box"]
    cyc = cycles_crops.over_background(sc, rgba)
    t0 = time.perf_counter()
    img = render_terms(box)
    print(f"tsd x 4 variants at {SIZE} px: {time.perf_counter() - t0:.0f} s (load {os.getloadavg()[0]:.2f})")
    h, w = cyc.shape[:2]
    rc, d, p, tri, bary, n, (N, I) = camera_hits(sc, box)
    to_light = -np.asarray(sc.lights[0].direction, np.float64)
    to_light /= np.linalg.norm(to_light)
    mm = float(sc.mm_per_unit)
    ndv, ndl = -(n * d).sum(1), n @ to_light
    tn, trn, bn = rc.closest_hit(p - n * 1e-5, -n)  # the far face along -N (tsd's thickness bake's central ray)
    wf = np.stack([1 - bn[:, 0] - bn[:, 1], bn[:, 0], bn[:, 1]], 1)
    nf = np.einsum("ij,ijk->ik", wf, N[I[np.maximum(trn, 0)]])
    nf /= np.linalg.norm(nf, axis=1, keepdims=True)
    q = p - n * np.where(trn >= 0, tn, 0.0)[:, None] + nf * 1e-4
    far_lit = (nf @ to_light > 0) & ~rc.occluded(q, np.broadcast_to(to_light, q.shape), 0.0) & (trn >= 0)
    thick = np.where(trn >= 0, tn * mm, np.inf)
    cls = classes(sc, cyc[..., 0], p, (h, w))
    flat = {k: m.ravel() for k, m in cls.items()}
    f3 = lambda v: " / ".join(f"{x:.4f}" for x in v)  # noqa: E731
    print(f"\n1-3. per class (mean linear radiance R / G / B; terms are tsd minus tsd without the term)")
    for k, m in cls.items():
        fm = flat[k]
        c, t = cyc[m].mean(0), img["tsd"][m].mean(0)
        thin = t - img["no_translucency"][m].mean(0)
        transfer = t - img["no_transfer"][m].mean(0)
        bounce = t - img["no_bounce"][m].mean(0)
        thin_px = fm & (thick < 10.0)
        print(f"{k}: {int(m.sum())} px; N.V {np.median(ndv[fm]):.2f}, N.L {np.median(ndl[fm]):.2f}; thickness along -N "
              f"(where < 10 mm: {thin_px.sum() / fm.sum():.2f} of the px) p25/50/75 "
              f"{' / '.join('%.2f' % x for x in np.percentile(thick[thin_px], [25, 50, 75]))} mm, far face's N.L "
              f"{np.median((nf @ to_light)[thin_px]):.2f}, far face lit {far_lit[thin_px].mean():.2f}")
        print(f"  Cycles {f3(c)} | tsd {f3(t)} | Cycles / tsd {f3(c / t)}")
        print(f"  tsd: thin-part light {f3(thin)} (far face {f3(thin - transfer)}, baked transfer {f3(transfer)}); "
              f"bounce {f3(bounce)}; the rest {f3(t - thin - bounce)}")
        need = c - (t - thin)
        print(f"  Cycles minus tsd's other light: {f3(need)} = {need[0] / thin[0]:.2f} x tsd's red thin-part light")

    # 4. slab Monte Carlo, red
    albedo = mean_skin_albedo(sc.material)
    law = slab_law(sc.profile.normalized(), albedo)
    A, mfp = float(albedo[CHANNEL]), float(1.0 / law.reduced_sigma_t_per_mm[CHANNEL])
    cs = cycles_subsurface(sc)
    base = float(np.clip(cs.albedo * cs.base_gain, 0.0, 1.0)[CHANNEL])
    alpha_c = float(chiang_alpha(base))
    mfp_c = float(cs.radius_mm[CHANNEL]) / (4.0 * np.pi)  # bssrdf_burley_compatible_mfp
    alpha_s, _ = random_walk_slab(A, mfp, np.inf, photons=20_000)
    skin = Medium(np.array([(1 - alpha_s) / mfp]), np.array([alpha_s / mfp]), 0.0, 1.4)
    g = flat["glow line"] & (thick < 10.0)
    cos_far = float(np.median((nf @ to_light)[g]))
    ds = [float(x) for x in np.percentile(thick[g], [25, 50, 75])]
    band = flat["helix band"] & (thick < 10.0)
    ds.append(float(np.median(thick[band])))
    print(f"\n4. slab Monte Carlo, red, {a.photons} photons: skin walk (albedo {A:.4f}, mean free path {mfp:.4f} mm, "
          f"single-scattering albedo {alpha_s:.4f}, index 1.4); Cycles' walk (base colour {base:.4f}, radius "
          f"{cs.radius_mm[CHANNEL]:.3f} mm: mean free path {mfp_c:.4f} mm, single-scattering albedo {alpha_c:.4f}, "
          f"index 1.0); the far face lit at cos {cos_far:.2f} (the glow line's median)")
    print("| d (mm) | skin walk T, head-on | skin walk T, far face's cos | thin-slab law T | Cycles' walk T head-on "
          "| / skin | / law | Cycles' walk T cosine entry | / skin | / law |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for dmm in ds:
        t_n = monte_carlo_reflectance([Layer(skin, dmm)], a.photons, [0.0, 1e3], seed=3).total_transmittance
        t_o = monte_carlo_reflectance([Layer(skin, dmm)], a.photons, [0.0, 1e3], seed=3,
                                      incidence_cos=cos_far).total_transmittance
        tl = float(law.transmittance(dmm)[CHANNEL])
        cn = _cycles_walk(alpha_c, mfp_c, dmm, a.photons, seed=3, entry="normal")[1]
        cc = _cycles_walk(alpha_c, mfp_c, dmm, a.photons // 4, seed=3, entry="cosine")[1]
        print(f"| {dmm:.2f} | {t_n:.4f} | {t_o:.4f} | {tl:.4f} | {cn:.4f} | {cn / t_o:.2f} | {cn / tl:.2f} | "
              f"{cc:.4f} | {cc / t_o:.2f} | {cc / tl:.2f} |", flush=True)

    # 5. walks in the head's own geometry, red
    L = sc.lights[0]
    light = [DirectionalLight(tuple(to_light), float(L.intensity * np.asarray(L.color)[CHANNEL]))]
    env = float(np.asarray(sc.environment.color)[CHANNEL])
    m0, a0 = CYCLES_WALK_MEDIUM[CHANNEL]
    media = {"skin walk": WalkMedium(mfp, random_walk_albedo(A, mfp, index=1.4), "fresnel", 1.4),
             "Cycles' walk, refracted entry": WalkMedium(m0, a0, "lambertian", 1.4, "refracted"),
             "Cycles' walk, cosine entry": WalkMedium(m0, a0, "lambertian", 1.4, "cosine")}
    mw = MeshWalk(np.asarray(sc.mesh.positions, np.float64) * mm, sc.mesh.indices, sc.mesh.normals)
    local = _albedo_at(sc, tri, bary)[:, CHANNEL]  # the albedo map under each pixel's ray (nearest texel)
    print(f"\n5. random walks in the head's geometry, red, {a.walks} walks a pixel (direct light and environment, "
          f"no bounce, no specular; +- half the difference of the two halves of the walks)")
    print("(at the class's albedo map mean: both media's albedo moved to it, Cycles' by its remap's difference, "
          "as ear_translucency.py --walk)")
    print("| class | skin walk | Cycles' walk refracted | / skin | Cycles' walk cosine | / skin | albedo map "
          "| skin walk at it | Cycles' walk refracted at it | / skin | tsd without bounce | / skin walk at the map "
          "| Cycles' crop | / tsd |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for k, fm in flat.items():
        sel = np.nonzero(fm & (tri >= 0))[0]
        pts, tr, dd = p[sel] * mm, tri[sel], d[sel]
        A_loc = float(local[sel].mean())
        media_loc = dict(media)
        media_loc["skin walk at the map"] = WalkMedium(mfp, random_walk_albedo(A_loc, mfp, index=1.4), "fresnel", 1.4)
        media_loc["Cycles' walk at the map"] = WalkMedium(m0, float(a0 + chiang_alpha(A_loc) - chiang_alpha(A)),
                                                          "lambertian", 1.4, "refracted")
        rad = {}
        for name, med in media_loc.items():
            r = mw.radiance(np.repeat(pts, a.walks, 0), np.repeat(tr, a.walks), np.repeat(dd, a.walks, 0), med, light,
                            env, seed=7).reshape(-1, a.walks)
            rad[name] = (r.mean(), 0.5 * abs(r[:, :a.walks // 2].mean() - r[:, a.walks // 2:].mean()))
        s, cr, cc = rad["skin walk"], rad["Cycles' walk, refracted entry"], rad["Cycles' walk, cosine entry"]
        m = cls[k]
        tnb, t, c = img["no_bounce"][m][:, 0].mean(), img["tsd"][m][:, 0].mean(), cyc[m][:, 0].mean()
        sl, cl = rad["skin walk at the map"], rad["Cycles' walk at the map"]
        print(f"| {k} | {s[0]:.4f} +- {s[1]:.4f} | {cr[0]:.4f} +- {cr[1]:.4f} | {cr[0] / s[0]:.2f} | {cc[0]:.4f} | "
              f"{cc[0] / s[0]:.2f} | {A_loc:.3f} | {sl[0]:.4f} +- {sl[1]:.4f} | {cl[0]:.4f} | {cl[0] / sl[0]:.2f} | "
              f"{tnb:.4f} | {tnb / sl[0]:.2f} | {c:.4f} | {c / t:.2f} |", flush=True)
    print(f"(load {os.getloadavg()[0]:.2f}, {time.perf_counter() - t0:.0f} s in all)")
    if a.save:
        a.save.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(a.save / "helix_glow.npz", box=np.asarray(box), cycles=cyc, **img,
                            **{"class_" + k.replace(" ", "_"): v for k, v in cls.items()})


if __name__ == "__main__":
    main()
