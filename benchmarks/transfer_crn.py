"""Round 12 (issue 12, branch cv12): the subsurface transfer bake's control variate measured on the head.
Every number of benchmarks/RESULTS.md "Round 12, branch cv12". M11 = a benchmarks/transfer_noise.py
folder of round 11 (points.npz, reference.npz: the 1536-walk plain reference of two patches,
ratio-front-key-768.npz: the no-bake image and round 10's, whose changed pixels are the mask).

    PYTHONPATH=src nice -n 10 python benchmarks/transfer_crn.py raw OUT --seed S
        the head's bake before denoising (control variate), all arrays with the points: OUT/raw-crn-sS.npz
    PYTHONPATH=src python benchmarks/transfer_crn.py patch OUT --m11 M11 --walks W --seed S [--plain]
        the patches' bake (cheek under the +x eye, +x helix) with W walks: per-point net and s.e.
        (OUT/patch-W-S-crn|plain.npz; 1536 walks seed 101: the control variate's reference)
    PYTHONPATH=src python benchmarks/transfer_crn.py variant OUT --seed S NAME...
        a denoising of raw-crn-sS.npz (raw, r10 = the shipped denoise, r11 = denoise_round11, r10+shrink,
        own<thin>-<band>[+shrink]) into a cache folder OUT/var/NAME-sS (DERMIS_CACHE_DIR for renders, validate)
    PYTHONPATH=src python benchmarks/transfer_crn.py mottle OUT --m11 M11 NAME
        front-key 768 px tsd with NAME's seed 0 and seed 1 bakes: the std of the two luminance ratios'
        difference / sqrt 2 (all scales, Gaussian-6 px high-pass) over the lit changed skin, the band, the ears
    PYTHONPATH=src python benchmarks/transfer_crn.py rms OUT --m11 M11 BAKE.npz...
        per patch, the RMS over interior points of (each bake's per-point total - reference net), the
        reference's own noise out in quadrature, against M11's plain reference and OUT/patch-1536-101-crn.npz
    PYTHONPATH=src python benchmarks/transfer_crn.py flat
        the flat twin's expectation against the flat kernel's shares, per channel (200,000 twins)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "benchmarks"))
HEAD = REPO / "examples" / "lee-perry-smith.toml"
FRONT_KEY = REPO / "examples" / "reference" / "front-key.toml"


def cmd_raw(a):
    import dermis
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    sc = dermis.load_scene(HEAD)
    pts = B.bake_points(sc.mesh, sc.mm_per_unit)
    t0 = time.perf_counter()
    bk = B.bake_transfer(sc.mesh, sc.mm_per_unit, sc.profile, mean_skin_albedo(sc.material), points=pts, seed=a.seed,
                         progress=lambda s: print(f"{time.perf_counter() - t0:7.1f} s {s}", flush=True))
    np.savez(Path(a.out) / f"raw-crn-s{a.seed}.npz", point_uv=bk.point_uv, tap_uv=bk.tap_uv, tap_weight=bk.tap_weight,
             kept=bk.kept, subtracted=bk.subtracted, excess=bk.excess, excess_cov=bk.excess_cov,
             tap_position=bk.tap_position, meta=json.dumps(bk.meta), uv=pts.uv, position=pts.position,
             triangle=pts.triangle, normal=pts.normal, thin=pts.thin)
    print(f"done {time.perf_counter() - t0:.1f} s", flush=True)


def _se(cov):
    return np.sqrt(np.maximum(cov[..., 0] + cov[..., 1] + 2 * cov[..., 2], 0))


def cmd_patch(a):
    import dermis
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B
    from transfer_noise import _load_points, interior, patch_mask

    sc = dermis.load_scene(HEAD)
    pts = _load_points(Path(a.m11) / "points.npz")
    sel = np.load(Path(a.m11) / "reference.npz")["index"]
    sub = B.BakePoints(pts.uv[sel], pts.position[sel], pts.triangle[sel], pts.normal[sel])
    t0 = time.perf_counter()
    bk = B.bake_transfer(sc.mesh, sc.mm_per_unit, sc.profile, mean_skin_albedo(sc.material), points=sub, walks=a.walks,
                         seed=a.seed, crn=not a.plain)
    net, se = bk.excess.sum(2), _se(bk.excess_cov)
    out = {"walks": a.walks, "seed": a.seed, "crn": not a.plain, "seconds": round(time.perf_counter() - t0, 1)}
    for name, m in patch_mask(sc, pts).items():
        mm = (m & interior(pts, m, 1.5))[sel]
        out[name] = {"points": int(mm.sum()), "mean net RGB": net[mm].mean(0).round(4).tolist(),
                     "median se RGB": np.median(se[mm], 0).round(4).tolist()}
    print(json.dumps(out))
    np.savez(Path(a.out) / f"patch-{a.walks}-{a.seed}-{'plain' if a.plain else 'crn'}.npz", net=net, se=se)


def load_raw(out, seed):
    from dermis.subsurface_transfer import bake as B

    z = np.load(Path(out) / f"raw-crn-s{seed}.npz")
    bk = B.TransferBake(z["point_uv"], z["tap_uv"], z["tap_weight"], z["kept"], z["subtracted"], json.loads(str(z["meta"])),
                        z["excess"], z["excess_cov"], z["tap_position"])
    return bk, B.BakePoints(z["uv"], z["position"], z["triangle"], z["normal"], z["thin"])


def denoised(name, bk, pts):
    from dermis.subsurface_transfer import bake as B

    thin = np.asarray(pts.thin, bool)
    if name == "raw":
        return bk
    if name == "r10":
        return B.denoise(bk, pts)
    if name == "r10+shrink":
        return B.shrink_insignificant(B.denoise(bk, pts), pts)
    if name == "r11":
        return B.denoise_round11(bk, pts)
    if name.startswith("own"):
        t, b = name[3:].split("+")[0].split("-")
        v = B.smooth_own_taps(bk, pts, np.where(thin, float(t), float(b)))
        return B.shrink_insignificant(v, pts) if name.endswith("+shrink") else v
    raise SystemExit(f"unknown variant {name}")


def cmd_variant(a):
    import dermis
    from dermis.profiles.scene_skin import _cache_folder
    from dermis.subsurface_transfer import bake as B, store

    sc = dermis.load_scene(HEAD)
    home = _cache_folder()
    for name in a.names:
        bk, pts = load_raw(a.out, a.seed)
        v = denoised(name, bk, pts)
        v.meta["recipe"] = B.recipe_key()  # so store.find takes it
        d = Path(a.out) / "var" / f"{name}-s{a.seed}"
        (d / store.CACHE_SUBFOLDER).mkdir(parents=True, exist_ok=True)
        for sub in (home.iterdir() if home is not None and home.is_dir() else ()):
            if sub.name != store.CACHE_SUBFOLDER and not (d / sub.name).exists():
                os.symlink(sub, d / sub.name)
        store.save(v, store.path_for(sc.mesh, d / store.CACHE_SUBFOLDER), store.mesh_key(sc.mesh), sc.mm_per_unit)
        print(name, d, flush=True)


def cmd_mottle(a, size=768):
    import dermis
    from dermis.renderer import Renderer
    from scipy.ndimage import binary_closing, binary_erosion
    from transfer_noise import highpass_gauss_std, luminance, pixel_parts

    z0 = np.load(Path(a.m11) / f"ratio-front-key-{size}.npz")
    imgs = []
    for seed in (0, 1):
        os.environ["DERMIS_CACHE_DIR"] = str(Path(a.out) / "var" / f"{a.names[0]}-s{seed}")
        with Renderer(dermis.load_scene(FRONT_KEY), (size, size), irradiance_size=1024) as r:
            imgs.append(r.render("tsd").astype(np.float64))
            assert "tsd_subsurface_transfer" in r.last_frame.passes_run, "the bake was not found"
    L0 = luminance(z0["none"])
    lit = L0 > 0.05 * np.percentile(L0[L0 > 0], 99)
    rr = [luminance(im) / np.maximum(L0, 1e-12) for im in imgs]
    changed = lit & binary_closing(np.abs(luminance(z0["round10"]) / np.maximum(L0, 1e-12) - 1.0) > 1e-4, np.ones((5, 5), bool))
    ears, band = pixel_parts(FRONT_KEY, size)
    band = changed & ~ears & band
    d = rr[0] - rr[1]
    res = {"variant": a.names[0]}
    for w, m in (("all", changed), ("band", band), ("ears", changed & ears)):
        res[w + " % (all scales, high-pass)"] = [round(float(d[binary_erosion(m, iterations=12)].std() / np.sqrt(2)) * 100, 3),
                                                round(highpass_gauss_std(d, m, 6.0) / np.sqrt(2) * 100, 3)]
    print(json.dumps(res))


def cmd_flat(a):
    import dermis
    from dermis.reference.random_walk import CounterUniforms, halfspace_exits
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    sc = dermis.load_scene(HEAD)
    n = 200_000
    for c, m in enumerate(B.skin_media(sc.profile, mean_skin_albedo(sc.material))):
        k = B.flat_kernel(m)
        nrm = np.tile([0, 0, 1.0], (n, 1))
        ex = halfspace_exits(np.zeros((n, 3)), nrm, B.diffuse_views(nrm, np.random.default_rng(99)), m, CounterUniforms(1234 + c))
        w = ex["weight"] / k.reflectance
        tot = np.bincount(ex["walk"], weights=w, minlength=n)
        near = np.bincount(ex["walk"], weights=w * (ex["radius"] <= B.MIN_SURFACE_MM), minlength=n)
        se = lambda x: x.std() / np.sqrt(n)
        print(json.dumps({"channel": c, "R_flat": [k.reflectance, k.reflectance_se], "twin total (expect 1)": [tot.mean(), se(tot)],
                          "twin within 1 mm": [near.mean(), se(near)], "kernel F(1 mm)": k.within(B.MIN_SURFACE_MM)}))


def cmd_rms(a):
    import dermis
    from dermis.subsurface_transfer import store
    from transfer_noise import _load_points, interior, patch_mask

    sc = dermis.load_scene(HEAD)
    pts = _load_points(Path(a.m11) / "points.npz")
    plain = np.load(Path(a.m11) / "reference.npz")
    sel = plain["index"]
    crn = np.load(Path(a.out) / "patch-1536-101-crn.npz")
    refs = {"plain 1536": (plain["excess"].sum(2), _se(plain["excess_cov"])), "CRN 1536": (crn["net"], crn["se"])}
    masks = patch_mask(sc, pts)
    for rn, (rnet, rse) in refs.items():
        for f in a.names:
            tot = store.load(Path(f)).total.astype(np.float64)[sel]
            row = {"reference": rn, "bake": f}
            for name, m in masks.items():
                mm = (m & interior(pts, m, 1.5))[sel]
                d2 = ((tot[mm] - rnet[mm]) ** 2).mean(0) - (rse[mm] ** 2).mean(0)
                row[name + " RGB"] = np.sqrt(np.maximum(d2, 0)).round(3).tolist()
            print(json.dumps(row))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cmd", choices=("raw", "patch", "variant", "mottle", "flat", "rms"))
    ap.add_argument("out", nargs="?", default=".")
    ap.add_argument("names", nargs="*")
    ap.add_argument("--m11", default=None)
    ap.add_argument("--walks", type=int, default=192)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plain", action="store_true")
    a = ap.parse_intermixed_args(argv)
    {"raw": cmd_raw, "patch": cmd_patch, "variant": cmd_variant, "mottle": cmd_mottle, "flat": cmd_flat,
     "rms": cmd_rms}[a.cmd](a)


if __name__ == "__main__":
    main()
