"""The back-lit ear's regions against Cycles at 768 px, term by term, every technique (issue 12, round 22, lobe22).

Regions of back-ears' 768 px frame (examples/reference/back-ears.toml), boxes (x0, y0, x1, y1) in frame pixels,
row 0 = top (REGIONS): lobe, helix (the glow line inside the helix) and scapha are review20/21's boxes (RESULTS
"Round 21, branch ears21"); concha, antihelix and rim (the helix's lit outer edge) are defined here on Cycles'
stored crop (benchmarks/cycles/crops/back-ears--ear+x.npz, window (181, 193)-(589, 601)). Only pixels of the ear
count (the surface past ear_translucency.EAR_FRACTION of the largest distance from the midline).

    PYTHONPATH=src python benchmarks/ear_regions.py render [--out /tmp/ear_regions.npz] [--only VARIANT ...]
tsd whole, with translucency=false (no far face, no baked transfer), without the transfer, without the skin-to-skin
bounce; ssss and preintegrated whole and with translucency=false: 768 px, irradiance 1024^2, pore_strength 0 (as
cycles_crops.py score). ~1 min on 2 cores.

    PYTHONPATH=src python benchmarks/ear_regions.py table [--out ...] [--walks N] [--channels 0 1] [--regions ...] [--json J]
per region: geometry by ray casting (N.V, N.L, the thickness along -N that tsd's bake measures and along the light,
whether the far face along -N is lit, whether the sheet is lit where the light enters it, whether the point itself
is lit); each render's mean linear R / G / B and its ratio to Cycles, as rendered and with Cycles' flat-slab exit
factor taken out (the render divided by control / random walk at the pixel's albedo and N.V:
benchmarks/lips/cycles_slab_exit_angle.json, lip_exit_angle.slab_ratio, over dermis's own k(N.V); a FRONT-lit slab's
factor: for light that came through the sheet Cycles' walk does the opposite, see the walks); tsd's terms (differences
of the renders); and with --walks N > 0 dermis's skin walk (index 1.4) and Cycles' walk (index-matched, entered
along the refracted view ray, and cosine-distributed) in the head's own geometry per region
(dermis.reference.random_walk.MeshWalk; helix_glow.py's media at the region's albedo map, direct light +
environment, no bounce), the skin walk's light search checked against the exhaustive sum at 5 % of its vertices and
where its light entered. 32 walks, red and green, all six regions: ~4 min at load 5.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cycles_crops  # noqa: E402
import helix_glow  # noqa: E402

SIZE = 768
REGIONS = {  # frame pixels (x0, y0, x1, y1)
    "lobe": (290, 520, 330, 565),
    "helix": (360, 330, 390, 420),
    "scapha": (340, 292, 362, 310),
    "concha": (291, 343, 326, 403),
    "antihelix": (336, 428, 366, 488),
    "rim": (396, 353, 414, 473),  # the helix's outer rim (silhouette) beside review21's helix box
}


def _variants():
    def no_transfer(r):
        r.technique("tsd").transfer.add = lambda *a, **k: False  # the bake's taps not gathered

    def off(t):
        return lambda r: r.technique(t, translucency=False)

    return {  # name: (technique, renderer tweak, bounce off)
        "tsd": ("tsd", None, False),
        "tsd_no_translucency": ("tsd", off("tsd"), False),
        "tsd_no_transfer": ("tsd", no_transfer, False),
        "tsd_no_bounce": ("tsd", None, True),
        "ssss": ("ssss", None, False),
        "ssss_no_translucency": ("ssss", off("ssss"), False),
        "preintegrated": ("preintegrated", None, False),
        "preintegrated_no_translucency": ("preintegrated", off("preintegrated"), False),
    }


def render(a) -> None:
    from dermis.renderer import Renderer

    out = {}
    for name, (t, tweak, no_bounce) in _variants().items():
        if a.only and name not in a.only:
            continue
        t0 = time.perf_counter()
        sc = helix_glow._scene()
        if no_bounce:
            sc.interreflection = False
        with Renderer(sc, (SIZE, SIZE), irradiance_size=1024) as r:
            if tweak:
                tweak(r)
            out[name] = r.render(t)[..., :3].astype(np.float32)
        print(f"{name}: {time.perf_counter() - t0:.0f} s (load {os.getloadavg()[0]:.1f})", flush=True)
    old = dict(np.load(a.out)) if (a.only and Path(a.out).exists()) else {}
    old.update(out)
    np.savez_compressed(a.out, **old)


def geometry(sc, box):
    """Per crop pixel of ``box`` (flattened): ear mask, N.V, N.L, thickness along -N and toward the light +L (mm; inf where
    nothing is met within the mesh), far face (along -N) lit, the point itself in the light's shadow, albedo."""
    from dermis.blender import sss as S
    from dermis.blender.validate import _albedo_at
    from ear_translucency import EAR_FRACTION

    rc, d, p, tri, bary, n, (N, I) = helix_glow.camera_hits(sc, box)
    to_light = -np.asarray(sc.lights[0].direction, np.float64)
    to_light /= np.linalg.norm(to_light)
    mm = float(sc.mm_per_unit)
    P = np.asarray(sc.mesh.positions, np.float64)
    up = P[:, 1] > 0.5 * (P[:, 1].min() + P[:, 1].max())
    mid = 0.5 * (P[up, 0].min() + P[up, 0].max())
    ear = (tri >= 0) & ((p[:, 0] - mid) > EAR_FRACTION * (P[up, 0] - mid).max())
    tn, trn, bn = rc.closest_hit(p - n * 1e-5, -n)  # tsd's thickness bake's central ray
    wf = np.stack([1 - bn[:, 0] - bn[:, 1], bn[:, 0], bn[:, 1]], 1)
    nf = np.einsum("ij,ijk->ik", wf, N[I[np.maximum(trn, 0)]])
    nf /= np.linalg.norm(nf, axis=1, keepdims=True)
    q = p - n * np.where(trn >= 0, tn, 0.0)[:, None] + nf * 1e-4
    far_lit = (trn >= 0) & (nf @ to_light > 0) & ~rc.occluded(q, np.broadcast_to(to_light, q.shape), 0.0)
    ndl = n @ to_light
    # through the tissue toward the light (for N.L < 0 the ray along +L enters the tissue): the sheet's thickness on
    # the light's path and whether the light reaches the face it leaves by (the far face the light enters)
    tl, trl, _ = rc.closest_hit(p - n * 1e-5, np.broadcast_to(to_light, p.shape))
    trl = np.where(ndl < 0, trl, -1)
    behind = p + to_light[None, :] * np.where(trl >= 0, tl + 1e-4, 0.0)[:, None]
    sheet_lit = (trl >= 0) & ~rc.occluded(behind, np.broadcast_to(to_light, p.shape), 1e-5)
    own_lit = (ndl > 0) & ~rc.occluded(p + n * 1e-5, np.broadcast_to(to_light, p.shape), 0.0)
    alb = _albedo_at(sc, tri, bary) * S.albedo_scale(sc)
    return dict(ear=ear, ndv=-(n * d).sum(1), ndl=ndl, thick_n=np.where(trn >= 0, tn * mm, np.inf),
                thick_l=np.where(trl >= 0, tl * mm, np.inf), far_lit=far_lit, sheet_lit=sheet_lit, own_lit=own_lit,
                albedo=alb, p=p, d=d, tri=tri, far_ndl=nf @ to_light)


def table(a) -> dict:
    import lip_exit_angle
    from dermis.profiles.directional_albedo import factor

    sc = helix_glow._scene()
    img = dict(np.load(a.out))
    cyc_crop, meta = cycles_crops.load_crop(cycles_crops.OUT, "back-ears", "ear +x", sc, SIZE)
    cyc = np.zeros((SIZE, SIZE, 3), np.float32)
    X0, Y0, X1, Y1 = meta["box"]
    cyc[Y0:Y1, X0:X1] = cycles_crops.over_background(sc, cyc_crop)
    slab = json.loads((Path(__file__).resolve().parent / "lips" / "cycles_slab_exit_angle.json").read_text())
    f3 = lambda v: "/".join(f"{x:.3f}" for x in v)  # noqa: E731
    report = {}
    for name, box in REGIONS.items():
        if a.regions and name not in a.regions:
            continue
        x0, y0, x1, y1 = box
        g = geometry(sc, box)
        m = g["ear"]
        c = cyc[y0:y1, x0:x1].reshape(-1, 3)[m]
        pred = lip_exit_angle.slab_ratio(slab, g["albedo"][m], np.clip(g["ndv"][m], 0.0, 1.0))  # control / walk
        k = factor(g["albedo"][m], np.clip(g["ndv"][m], 0.0, 1.0)[:, None]) if sc.directional_albedo else 1.0
        fin = lambda v: np.median(v[np.isfinite(v)]) if np.isfinite(v).any() else np.inf  # noqa: E731
        e = {"box": box, "px": int(m.sum()), "N.V": float(np.median(g["ndv"][m])),
             "N.L": float(np.median(g["ndl"][m])), "thick_-N_mm": float(fin(g["thick_n"][m])),
             "thick_L_mm": float(fin(g["thick_l"][m])), "far_face_lit": float(g["far_lit"][m].mean()),
             "far_face_N.L": float(np.median(g["far_ndl"][m])),
             "sheet_behind_lit": float(g["sheet_lit"][m].mean()), "own_face_lit": float(g["own_lit"][m].mean()),
             "cycles_exit_factor": [float(v) for v in (1.0 / pred).mean(0)], "cycles": [float(v) for v in c.mean(0)]}
        print(f"{name} {box}: {e['px']} ear px; N.V {e['N.V']:.2f} N.L {e['N.L']:.2f}; thickness -N {e['thick_-N_mm']:.2f} "
              f"mm, +L {e['thick_L_mm']:.2f} mm; far face (-N) lit {e['far_face_lit']:.2f} (its N.L {e['far_face_N.L']:.2f})"
              f", sheet toward L lit {e['sheet_behind_lit']:.2f}, own face lit {e['own_face_lit']:.2f}; Cycles' slab exit "
              f"factor (walk / control) {f3(e['cycles_exit_factor'])}")
        print(f"  Cycles {f3(c.mean(0))}")
        for v, im in img.items():
            t = im[y0:y1, x0:x1].reshape(-1, 3)[m]
            kk = 1.0 if v.startswith("lambert") else k
            corr = t / (pred * kk)  # as if Cycles' walk's view factor (over dermis's own k) applied to all the light
            e[v] = {"mean": [float(x) for x in t.mean(0)], "ratio": [float(x) for x in t.mean(0) / c.mean(0)],
                    "with_cycles_exit": [float(x) for x in corr.mean(0) / c.mean(0)]}
            print(f"  {v:31s} {f3(t.mean(0))}  / Cycles {f3(e[v]['ratio'])}  with Cycles' exit {f3(e[v]['with_cycles_exit'])}")
        if "tsd" in img:
            t = {v: img[v][y0:y1, x0:x1].reshape(-1, 3)[m].mean(0) for v in img if v.startswith("tsd")}
            thin = t["tsd"] - t["tsd_no_translucency"]
            tr = t["tsd"] - t["tsd_no_transfer"]
            b = t["tsd"] - t["tsd_no_bounce"]
            e["tsd_terms"] = {"far_face": [float(x) for x in thin - tr], "transfer": [float(x) for x in tr],
                              "bounce": [float(x) for x in b], "rest": [float(x) for x in t["tsd"] - thin - b]}
            print(f"  tsd terms: far face {f3(thin - tr)}, transfer {f3(tr)}, bounce {f3(b)}, rest {f3(t['tsd'] - thin - b)};"
                  f" Cycles - tsd {f3(c.mean(0) - t['tsd'])}")
        for ch in a.channels if a.walks else ():
            e[f"walks_{'RGB'[ch]}"] = w = walks(sc, g, m, a.walks, ch)
            tnb = img['tsd_no_bounce'][y0:y1, x0:x1].reshape(-1, 3)[m].mean(0)[ch]
            print(f"  walks ({'RGB'[ch]}, direct + environment, no bounce): skin {w['skin'][0]:.4f} +- {w['skin'][1]:.4f}, "
                  f"Cycles' walk {w['cycles'][0]:.4f} +- {w['cycles'][1]:.4f} (/ skin {w['cycles'][0] / w['skin'][0]:.2f}; cosine entry "
                  f"{w['cycles_cosine'][0] / w['skin'][0]:.2f}); "
                  f"skin walk's search / exhaustive {w.get('skin_search_over_exhaustive', float('nan')):.3f}; its light "
                  f"{w['skin_light_share']:.2f} of it, entered > 3 mm away {w['skin_far_share']:.2f}, through a facet facing "
                  f"away {w['skin_opposite_share']:.2f}, mean {w['skin_entry_distance_mm']:.1f} mm; "
                  f"Cycles crop / Cycles walk {c.mean(0)[ch] / w['cycles'][0]:.2f}; tsd no bounce / skin {tnb / w['skin'][0]:.2f} "
                  f"({tnb / w['skin_exact']:.2f} against the skin walk with its light / the search's share; Cycles' "
                  f"walk / that {w['cycles'][0] / w['skin_exact']:.2f}, cosine entry {w['cycles_cosine'][0] / w['skin_exact']:.2f})",
                  flush=True)
        report[name] = e
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    return report


def walks(sc, g, m, n_walks, ch: int = 0):
    """Red: dermis's skin walk (index 1.4) and Cycles' walk (index-matched, refracted entry) at the region's
    albedo map mean, in the head's geometry (helix_glow.py's section 5)."""
    from dermis.blender.sss import cycles_subsurface  # noqa: F401  (the media below are ear_translucency's)
    from dermis.profiles.thin_slab import slab_law
    from dermis.reference.random_walk import DirectionalLight, MeshWalk, WalkMedium
    from dermis.scene.model import mean_skin_albedo
    from dermis.verification import random_walk_albedo
    from ear_translucency import CYCLES_WALK_MEDIUM, chiang_alpha

    albedo = mean_skin_albedo(sc.material)
    law = slab_law(sc.profile.normalized(), albedo)
    A, mfp = float(albedo[ch]), float(1.0 / law.reduced_sigma_t_per_mm[ch])
    to_light = -np.asarray(sc.lights[0].direction, np.float64)
    to_light /= np.linalg.norm(to_light)
    L = sc.lights[0]
    light = [DirectionalLight(tuple(to_light), float(L.intensity * np.asarray(L.color)[ch]))]
    env = float(np.asarray(sc.environment.color)[ch])
    m0, a0 = CYCLES_WALK_MEDIUM[ch]
    mm = float(sc.mm_per_unit)
    from dermis.blender import sss as S
    A_loc = float(g["albedo"][m][:, ch].mean() / np.asarray(S.albedo_scale(sc)).reshape(-1)[ch])
    media = {"skin": WalkMedium(mfp, random_walk_albedo(A_loc, mfp, index=1.4), "fresnel", 1.4),
             "cycles": WalkMedium(m0, float(a0 + chiang_alpha(A_loc) - chiang_alpha(A)), "lambertian", 1.4, "refracted"),
             # the same medium entered cosine-distributed: the part of Cycles' excess that is its walk's view
             # dependence (it starts along the refracted camera ray) rather than its medium
             "cycles_cosine": WalkMedium(m0, float(a0 + chiang_alpha(A_loc) - chiang_alpha(A)), "lambertian", 1.4,
                                         "cosine")}
    mw = MeshWalk(np.asarray(sc.mesh.positions, np.float64) * mm, sc.mesh.indices, sc.mesh.normals)
    sel = np.nonzero(m)[0]
    out = {"albedo_map_red": A_loc}
    for name, med in media.items():
        # the skin walk's light search misses caustics (RESULTS round 9: 0.953 of the red beam over the ear): its
        # share here is checked by the exhaustive sum at 5 % of the scattering vertices
        kw = {"stats": (st := {}), "check_fraction": 0.05, "paths": True} if name == "skin" else {}
        r = mw.radiance(np.repeat(g["p"][sel] * mm, n_walks, 0), np.repeat(g["tri"][sel], n_walks),
                        np.repeat(g["d"][sel], n_walks, 0), med, light, env, seed=7, **kw).reshape(-1, n_walks)
        out[name] = [float(r.mean()), float(0.5 * abs(r[:, :n_walks // 2].mean() - r[:, n_walks // 2:].mean()))]
        if name == "skin" and st.get("nee_exhaustive"):
            out["skin_search_over_exhaustive"] = float(st["nee_search"] / st["nee_exhaustive"])
        if name == "skin":  # where the skin walk's light (not the environment's) entered, light-weighted
            ps = {k: float(v.sum()) for k, v in st["paths"].items()}
            ps["light"] = max(ps["light"], 1e-30)
            out["skin_light_share"] = ps["light"] / max(float(r.sum()), 1e-30)
            out["skin_far_share"] = ps["far"] / ps["light"]
            out["skin_opposite_share"] = ps["opposite"] / ps["light"]
            out["skin_entry_distance_mm"] = ps["distance"] / ps["light"]
    # the skin walk with its light's part divided by the search's share (the environment's part is exact)
    q = out.get("skin_search_over_exhaustive", 1.0)  # absent where no checked vertex saw the light
    out["skin_exact"] = out["skin"][0] * (1.0 - out["skin_light_share"] + out["skin_light_share"] / q)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("render", "table"))
    ap.add_argument("--out", default="/tmp/ear_regions.npz")
    ap.add_argument("--only", nargs="+", default=None, help="render only these variants (merged into --out)")
    ap.add_argument("--walks", type=int, default=0)
    ap.add_argument("--json", default=None)
    ap.add_argument("--channels", type=int, nargs="+", default=[0], help="walk channels (0 red, 1 green)")
    ap.add_argument("--regions", nargs="+", default=None)
    a = ap.parse_args(argv)
    {"render": render, "table": lambda a: table(a)}[a.mode](a)


if __name__ == "__main__":
    main()
