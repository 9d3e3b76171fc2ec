"""Where the techniques' green excess over Cycles lies (issue 12, round 22 green22): per stored 768 px
Cycles crop (benchmarks/cycles_crops.py), linear means of Cycles and of each technique over classes
of skin pixels, and the ratios technique / Cycles per channel.

    PYTHONPATH=src python benchmarks/green_regions.py render [--out /tmp/green22]   (the frames, ~3 min)
    PYTHONPATH=src python benchmarks/green_regions.py table [--out /tmp/green22] [--json OUT.json]
    PYTHONPATH=src:benchmarks python benchmarks/green_regions.py view [--out /tmp/green22] [--json OUT.json]

``render`` draws every technique at the crops' frame size (as ``cycles_crops.py score``: pore detail
off, the Renderer's default texture sizes), the full image and its specular term (lambert's: its full
image less its rho_s 0 one), and for the scenes with a stored rho_s 0 crop (``-nospec``) also the
rho_s 0 frames. ``table`` classes the crop's skin pixels by lambert's irradiance proxy (its rho_s 0
diffuse, albedo E / pi, which no scattering moves), so that every technique and Cycles are averaged
over the same pixels:

- shadow: proxy < 0.12 x the crop's 95th percentile;
- edge (terminators and cast-shadow edges): not shadow, |grad ln proxy| > 0.06 per pixel (3x3 box first);
- lit flat: proxy > 0.5 x the 95th percentile and |grad ln proxy| < 0.015 per pixel;
- mid: the rest.

The specular share (technique's specular / Cycles' total) is listed so that a grey excess (which raises
green and blue more than red, their values being lower) can be told from the diffuse's. ``view`` bins
the lit skin (lit flat + mid) by the view cosine N.V (a ray cast per pixel) and puts Cycles' measured
random-walk exit factor (the flat slab of round 7, benchmarks/lips/cycles_slab_exit_angle.json) into
each technique's diffuse, in place of dermis's own k(N.V), and scores FLIP again.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
import crop_sheet  # noqa: E402
import cycles_crops  # noqa: E402

SIZE = 768
CLASSES = ("all", "lit_flat", "mid", "edge", "shadow")


def render(a) -> None:
    import dermis
    from dermis.renderer import Renderer
    from dermis.techniques.shared import OutputMode

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    for stem, path in cycles_crops.SCENES.items():
        sc = dermis.load_scene(path)
        boxes = cycles_crops.frame_boxes(sc, SIZE)
        has = {spec: any(cycles_crops.crop_path(Path(cycles_crops.OUT), stem, lm, spec).exists() for lm in boxes)
               for spec in (True, False)}
        arrays = {True: {}, False: {}}
        for spec in (True, False):
            sc = dermis.load_scene(path)
            if not spec:
                sc.material.rho_s = 0.0
            sc.material.pore_strength = 0.0  # as cycles_crops.score: Cycles has no pores
            # rho_s 0 frames: every technique where a -nospec crop is stored; lambert always (its
            # diffuse, the classes' proxy: lambert renders only the full image)
            techniques = crop_sheet.TECHNIQUES if has[spec] else ("lambert",)
            with Renderer(sc, (SIZE, SIZE)) as r:
                for t in techniques:
                    arrays[spec][t] = r.render(t)
                    if spec and t != "lambert":
                        arrays[spec][t + "_spec"] = r.render(t, output_mode=OutputMode.SPECULAR)
        arrays[True]["lambert_spec"] = arrays[True]["lambert"] - arrays[False]["lambert"]
        arrays[True]["lambert_diffuse"] = arrays[False]["lambert"]
        np.savez_compressed(out / f"{stem}.npz", **arrays[True])
        if has[False]:
            arrays[False]["lambert_diffuse"] = arrays[False]["lambert"]
            for t in crop_sheet.TECHNIQUES:
                arrays[False][t + "_spec"] = np.zeros_like(arrays[False][t])
            np.savez_compressed(out / f"{stem}-nospec.npz", **arrays[False])
        print(stem, has, flush=True)


def classes(proxy: np.ndarray, skin: np.ndarray) -> dict:
    from scipy.ndimage import uniform_filter

    lp = np.log(np.maximum(uniform_filter(proxy, 3), 1e-6))
    gy, gx = np.gradient(lp)
    g = np.hypot(gx, gy)
    p95 = np.percentile(proxy[skin], 95)
    shadow = skin & (proxy < 0.12 * p95)
    edge = skin & ~shadow & (g > 0.06)
    lit = skin & ~shadow & ~edge & (proxy > 0.5 * p95) & (g < 0.015)
    mid = skin & ~shadow & ~edge & ~lit
    return {"all": skin, "lit_flat": lit, "mid": mid, "edge": edge, "shadow": shadow}


def table(a) -> dict:
    import dermis

    report = {}
    for stem, path in cycles_crops.SCENES.items():
        for spec in (True, False):
            sc = dermis.load_scene(path)
            if not spec:
                sc.material.rho_s = 0.0
            f = Path(a.out) / f"{stem}{'' if spec else '-nospec'}.npz"
            if not f.exists():
                continue
            imgs = dict(np.load(f))
            for lm in cycles_crops.frame_boxes(sc, SIZE):
                c = cycles_crops.load_crop(Path(cycles_crops.OUT), stem, lm, sc, SIZE, spec)  # None if stale
                if c is None:
                    continue
                rgba, meta = c
                x0, y0, x1, y1 = meta["box"]
                skin = rgba[..., 3] >= 0.999
                ref = cycles_crops.over_background(sc, rgba)
                lam_diffuse = imgs["lambert_diffuse"][y0:y1, x0:x1]
                cl = classes(lam_diffuse[..., 1], skin)
                row = {}
                for name in CLASSES:
                    m = cl[name]
                    if m.sum() < 50:
                        continue
                    cy = ref[m].mean(0)
                    entry = {"px": int(m.sum()), "cycles_rgb": [round(float(v), 4) for v in cy]}
                    for t in crop_sheet.TECHNIQUES:
                        win = imgs[t][y0:y1, x0:x1]
                        sp = imgs[t + "_spec"][y0:y1, x0:x1]
                        entry[t] = {"ratio": [round(float(v), 3) for v in win[m].mean(0) / cy],
                                    "spec_share": [round(float(v), 3) for v in sp[m].mean(0) / cy]}
                    row[name] = entry
                report[f"{stem}:{lm}{'' if spec else ':nospec'}"] = row
    for crop, row in report.items():
        print(crop)
        for name, e in row.items():
            print(f"  {name:8s} {e['px']:6d} px  " + "  ".join(
                f"{t[:4]} {'/'.join(f'{v:.3f}' for v in e[t]['ratio'])} G/R {e[t]['ratio'][1] / e[t]['ratio'][0]:.3f}"
                for t in crop_sheet.TECHNIQUES) + f"  spec(lamb) {'/'.join(f'{v:.3f}' for v in e['lambert']['spec_share'])}")
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    return report


def view_geometry(sc, boxes):
    """Per pixel of the frame (SIZE x SIZE, row 0 = top): the view cosine N.V of the smooth normal
    and the albedo (x the scene's albedo scale) at the surface the pixel's centre ray hits, over the
    union of ``boxes`` (NaN elsewhere); as benchmarks/lip_exit_angle.py --head does at 64 px."""
    from dermis.blender import sss as S
    from dermis.blender.validate import _albedo_at
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    m = sc.mesh
    pos, idx = np.asarray(m.positions, np.float64), np.asarray(m.indices, np.int64).reshape(-1, 3)
    o, d, tmax, _ = camera_rays(sc, (SIZE, SIZE), 1, camera=framed_camera(sc.camera, m, 1.0))
    want = np.zeros((SIZE, SIZE), bool)
    for x0, y0, x1, y1 in boxes:
        want[y0:y1, x0:x1] = True
    sel = np.nonzero(want.ravel())[0]
    t, tri, bc = RayCaster(pos, idx).closest_hit(o[sel], d[sel], 0.0, tmax[sel])
    nrm, tt = np.asarray(m.normals, np.float64), np.where(tri >= 0, tri, 0)
    b1, b2 = bc[:, 0], bc[:, 1]
    N = nrm[idx[tt, 0]] * (1 - b1 - b2)[:, None] + nrm[idx[tt, 1]] * b1[:, None] + nrm[idx[tt, 2]] * b2[:, None]
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    cv = np.full(SIZE * SIZE, np.nan)
    alb = np.full((SIZE * SIZE, 3), np.nan)
    cv[sel] = np.where(tri >= 0, -(N * d[sel]).sum(axis=1), np.nan)
    alb[sel] = _albedo_at(sc, tri, bc) * S.albedo_scale(sc)
    return cv.reshape(SIZE, SIZE), alb.reshape(SIZE, SIZE, 3)


def view(a) -> dict:
    """Per crop, the lit skin (classes lit_flat + mid) binned by N.V: technique / Cycles per channel,
    as rendered and with the view side of Cycles' random walk put in: each technique's diffuse
    divided by the flat slab's control / random walk at the pixel's albedo and N.V
    (benchmarks/lips/cycles_slab_exit_angle.json, lip_exit_angle.slab_ratio) and, for the techniques
    that apply it, by dermis's own exit factor k(N.V) (dermis.profiles.directional_albedo.factor)."""
    import dermis
    import lip_exit_angle
    from dermis.profiles.directional_albedo import factor
    from dermis.reference.validate import metrics

    slab = json.loads((REPO / "benchmarks" / "lips" / "cycles_slab_exit_angle.json").read_text())
    bins = ((0.0, 0.5), (0.5, 0.7), (0.7, 0.85), (0.85, 0.95), (0.95, 1.01))
    report = {}
    for stem, path in cycles_crops.SCENES.items():
        for spec in (True, False):
            f = Path(a.out) / f"{stem}{'' if spec else '-nospec'}.npz"
            if not f.exists():
                continue
            sc = dermis.load_scene(path)
            if not spec:
                sc.material.rho_s = 0.0
            sc.material.pore_strength = 0.0
            imgs = dict(np.load(f))
            crops = {lm: c for lm in cycles_crops.frame_boxes(sc, SIZE)
                     if (c := cycles_crops.load_crop(Path(cycles_crops.OUT), stem, lm, sc, SIZE, spec))}
            if not crops:
                continue
            cv_all, alb_all = view_geometry(sc, [c[1]["box"] for c in crops.values()])
            for lm, (rgba, meta) in crops.items():
                x0, y0, x1, y1 = meta["box"]
                skin = rgba[..., 3] >= 0.999
                ref = cycles_crops.over_background(sc, rgba)
                cl = classes(imgs["lambert_diffuse"][y0:y1, x0:x1, 1], skin)
                cv, alb = cv_all[y0:y1, x0:x1], alb_all[y0:y1, x0:x1]
                ok = np.isfinite(cv) & np.isfinite(alb).all(-1)
                lit = (cl["lit_flat"] | cl["mid"]) & ok
                groups = {"lit": lit, "all skin": skin & ok}
                groups.update({f"lit N.V [{lo:.2f},{hi:.2f})": lit & (cv >= lo) & (cv < hi) for lo, hi in bins})
                row = {}
                for name, m in groups.items():
                    if m.sum() < 50:
                        continue
                    cy = ref[m].mean(0)
                    pred = lip_exit_angle.slab_ratio(slab, alb[m], cv[m])  # Cycles' control / random walk
                    e = {"px": int(m.sum()), "mean_nv": round(float(cv[m].mean()), 3)}
                    for t in crop_sheet.TECHNIQUES:
                        full, sp = imgs[t][y0:y1, x0:x1][m], imgs[t + "_spec"][y0:y1, x0:x1][m]
                        k = 1.0 if t == "lambert" or not sc.directional_albedo else factor(alb[m], cv[m][:, None])
                        corr = (full - sp) / (pred * k) + sp
                        e[t] = {"ratio": [round(float(v), 3) for v in full.mean(0) / cy],
                                "with_cycles_exit": [round(float(v), 3) for v in corr.mean(0) / cy]}
                    row[name] = e
                # FLIP over the crop's skin (as cycles_crops.score) with the same factor on every skin
                # pixel whose ray hit the mesh (shadowed ones too: the exit factor does not depend on the light)
                m = skin & ok
                pred = lip_exit_angle.slab_ratio(slab, alb[m], cv[m])
                flips = {}
                for t in crop_sheet.TECHNIQUES:
                    win = imgs[t][y0:y1, x0:x1].copy()
                    sp = imgs[t + "_spec"][y0:y1, x0:x1][m]
                    k = 1.0 if t == "lambert" or not sc.directional_albedo else factor(alb[m], cv[m][:, None])
                    before = metrics(sc, ref, win, skin)[0]["flip"]
                    win[m] = (win[m] - sp) / (pred * k) + sp
                    flips[t] = [round(before, 4), round(metrics(sc, ref, win, skin)[0]["flip"], 4)]
                row["flip"] = flips
                report[f"{stem}:{lm}{'' if spec else ':nospec'}"] = row
    for crop, row in report.items():
        print(crop, "FLIP as rendered -> with Cycles' exit:", "  ".join(
            f"{t[:4]} {v[0]:.4f} -> {v[1]:.4f}" for t, v in row["flip"].items()))
        row = {k: v for k, v in row.items() if k != "flip"}
        for name, e in row.items():
            print(f"  {name:20s} {e['px']:6d} px N.V {e['mean_nv']:.2f} " + "  ".join(
                f"{t[:4]} {'/'.join(f'{v:.3f}' for v in e[t]['ratio'])} -> "
                f"{'/'.join(f'{v:.3f}' for v in e[t]['with_cycles_exit'])}"
                for t in crop_sheet.TECHNIQUES))
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    return report


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("render", "table", "view"))
    ap.add_argument("--out", default="/tmp/green22")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    return {"render": render, "table": table, "view": view}[a.mode](a)


if __name__ == "__main__":
    main()
