"""Cycles at the crop sheets' resolution (issue 12): the windows of benchmarks/crop_sheet.py's crops
(nose, eyes, lips, ears) path-traced in their 768 px frames, stored so that every later round's
sheets have a full-resolution reference beside the techniques, and the per-crop numbers.

    PYTHONPATH=src python benchmarks/cycles_crops.py render [--size 768] [--spp 128] [--seeds 2]
        [--only SCENE:LANDMARK ...] [--budget-s 2100] [--threads 2] [--out benchmarks/cycles/crops]
    PYTHONPATH=src python benchmarks/cycles_crops.py score [--size 768] [--json OUT.json]   (--nospec: rho_s 0)

``render`` renders, in the order of PRIORITY (most telling crops first) until the budget is spent,
each crop's pixel window (dermis.blender.crop_render: Cycles' render border of the same frame, so its
pixels are the frame's) with ``--seeds`` independent seeds of ``--spp`` samples each, and writes
OUT/<scene>--<landmark>.npz: the seeds' mean (RGB and coverage; save_crop) and its metadata, with the
seed-to-seed FLIP over the crop's skin (the noise floor of a comparison with it). A crop
whose stored key (the Cycles stores' key of the scene at that size, the box, spp, seeds) matches is
not re-rendered. ``score`` renders each technique at the frame size (4x MSAA, the renderer's
defaults) and compares it with the crop over the skin (Cycles' coverage 1): mean R/G/B ratio,
FLIP, and the seed-to-seed FLIP floor. Note the pixel filters differ: Cycles' Blackman-Harris
1.5 px against dermis's MSAA box, so FLIP here has an edge floor the 64 px validation avoids.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
import crop_sheet  # noqa: E402  (the landmarks and boxes of the sheets themselves)

OUT = REPO / "benchmarks" / "cycles" / "crops"
SCENES = {s.stem: s for s in crop_sheet.SCENES}
# (scene, landmark): what the crop sheets could not show against the 64 px Cycles image, first
PRIORITY = [("front-key", "nose"), ("back-ears", "ear +x"), ("back-ears", "ear -x"), ("side", "eye +x"),
            ("side", "nose"), ("environment", "lips"), ("front-key", "eye +x"), ("front-key", "lips"),
            ("front-key", "eye -x"), ("side", "lips"), ("side", "ear +x"), ("environment", "nose"),
            ("lee-perry-smith", "nose"), ("side", "eye -x"), ("environment", "eye +x"), ("environment", "eye -x"),
            ("lee-perry-smith", "eye +x"), ("lee-perry-smith", "eye -x"), ("lee-perry-smith", "lips")]


def frame_boxes(scene, size: int) -> dict:
    """{landmark: (x0, y0, x1, y1)} of the crops the camera sees in a size x size frame, clipped to
    the frame: the boxes crop_sheet.sheet cuts (same landmarks, same camera as the Renderer)."""
    from dermis.camera import camera_matrices
    from dermis.framing import framed_camera

    cam = framed_camera(scene.camera, scene.mesh, 1.0)
    lo, hi = scene.bounds()
    view, proj, eye, _, _ = camera_matrices(cam, 1.0, lo, hi)
    mm = float(scene.mm_per_unit)
    out = {}
    for name, (p, n) in crop_sheet.landmarks(scene.mesh, mm).items():
        if crop_sheet.visible(scene.mesh, p, n, eye):
            x0, y0, x1, y1 = crop_sheet.crop_box(p, proj @ view, view, proj, (size, size),
                                                 crop_sheet.CROP_MM * crop_sheet.CROP_SCALE[name], mm)
            out[name] = (max(x0, 0), max(y0, 0), min(x1, size), min(y1, size))
    return out


def crop_path(out: Path, stem: str, landmark: str, specular: bool = True) -> Path:
    return out / f"{stem}--{landmark.replace(' ', '')}{'' if specular else '-nospec'}.npz"


def crop_key(scene, size: int, box, spp: int, seeds: int, specular: bool = True) -> str:
    from dermis.blender.validate import _accumulator_key

    base = _accumulator_key(scene, (size, size), True, specular)
    return hashlib.sha1(repr((base, tuple(box), spp, seeds)).encode()).hexdigest()


def load_crop(out: Path, stem: str, landmark: str, scene=None, size: int | None = None, specular: bool = True):
    """(mean over the seeds (h, w, 4) float32: linear RGB and coverage, metadata) of a stored crop,
    or None; with ``scene`` and ``size``, None also when its key is stale (the scene or the Cycles
    set-up changed). ``specular`` False: the crop rendered with rho_s 0 on both sides (``--nospec``)."""
    p = crop_path(out, stem, landmark, specular)
    if not p.is_file():
        return None
    with np.load(p) as z:
        meta = json.loads(str(z["meta"]))
        rgba = np.concatenate([z["rgb"].view(np.float16).astype(np.float32),
                               z["coverage"][..., None].astype(np.float32) / 255.0], -1)
    if scene is not None and meta["key"] != crop_key(scene, size, meta["box"], meta["spp"], meta["seeds"], specular):
        return None
    return rgba, meta


def save_crop(out: Path, stem: str, landmark: str, rgba, meta: dict, specular: bool = True) -> None:
    """The seeds' mean window (h, w, 4) and its metadata, written atomically. RGB as float16 rounded
    to 7 mantissa bits (relative step 2^-8, 0.4 %: under the noise of a few hundred samples, and what
    lets zlib shrink noisy data: 3.6 bytes a pixel instead of 4.9), coverage in 1/255."""
    from dermis.fileio import atomic_write

    bits = np.asarray(rgba[..., :3], np.float16).view(np.uint16).astype(np.uint32)
    bits = np.minimum((bits + 4) & ~np.uint32(7), 0x7BFF)  # round the low 3 bits (carries are exact)
    rgb = bits.astype(np.uint16)
    cov = np.clip(np.asarray(rgba[..., 3]) * 255.0 + 0.5, 0, 255).astype(np.uint8)

    def write(tmp):
        with open(tmp, "wb") as f:
            np.savez_compressed(f, rgb=rgb, coverage=cov, meta=json.dumps(meta))

    atomic_write(crop_path(out, stem, landmark, specular), write)


def render(a) -> None:
    import dermis
    from dermis.blender.crop_render import render_cycles_window
    from dermis.reference.validate import metrics

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    todo = [tuple(s.split(":")) for s in a.only] if a.only else PRIORITY
    t_start = time.perf_counter()
    for stem, landmark in todo:
        sc = dermis.load_scene(SCENES[stem])
        if a.nospec:
            sc.material.rho_s = 0.0
        boxes = frame_boxes(sc, a.size)
        if landmark not in boxes:
            print(f"{stem}:{landmark}: not seen by the camera; skipped")
            continue
        box = boxes[landmark]
        key = crop_key(sc, a.size, box, a.spp, a.seeds, not a.nospec)
        old = load_crop(out, stem, landmark, specular=not a.nospec)
        if old is not None and old[1]["key"] == key:
            print(f"{stem}:{landmark}: stored ({old[1]['spp']} spp x {old[1]['seeds']} seeds)")
            continue
        if a.budget_s and time.perf_counter() - t_start > a.budget_s:
            print(f"{stem}:{landmark}: budget spent; not rendered")
            continue
        imgs, secs = [], 0.0
        for s in range(a.seeds):
            img, st = render_cycles_window(sc, (a.size, a.size), box, spp=a.spp, seed=1000 + s, threads=a.threads,
                                           specular=not a.nospec, alpha=True)
            imgs.append(img)
            secs += st["build_s"] + st["render_s"]
        import bpy

        skin = np.min([i[..., 3] for i in imgs], 0) >= 0.999
        floor = metrics(sc, over_background(sc, imgs[0]), over_background(sc, imgs[1]), skin)[0]["flip"] \
            if a.seeds > 1 and skin.any() else None
        meta = {"scene": stem, "landmark": landmark, "size": a.size, "box": list(box), "spp": a.spp,
                "seeds": a.seeds, "seed_values": [1000 + s for s in range(a.seeds)], "key": key,
                "specular": not a.nospec,
                "floor_flip": None if floor is None else round(floor, 4), "blender": bpy.app.version_string,
                "cycles_s": round(secs, 1), "load": round(os.getloadavg()[0], 1)}
        save_crop(out, stem, landmark, np.mean(imgs, 0), meta, not a.nospec)
        print(f"{stem}:{landmark}: {box[2] - box[0]}x{box[3] - box[1]} px, {a.spp} spp x {a.seeds} seeds, "
              f"{secs:.0f} s (load {meta['load']})", flush=True)


def over_background(scene, rgba) -> np.ndarray:
    """Cycles' transparent film (premultiplied) over the scene's output background, as dermis draws it."""
    bg = np.asarray(scene.output.background, np.float32)
    return rgba[..., :3] + (1.0 - rgba[..., 3:4]) * bg


def score(a) -> dict:
    import dermis
    from dermis.reference.validate import metrics
    from dermis.renderer import Renderer

    report = {"size": a.size, "texture_sizes": a.texture_sizes, "crops": {}}
    for stem, path in SCENES.items():
        sc = dermis.load_scene(path)
        if a.nospec:
            sc.material.rho_s = 0.0
        crops = {lm: c for lm in frame_boxes(sc, a.size)
                 if (c := load_crop(Path(a.out), stem, lm, sc, a.size, not a.nospec))}
        if not crops:
            continue
        # Cycles has no pore detail (the export does not carry dermis's procedural pores; validate
        # compares with pore_strength 0 on both sides): so do the techniques here
        sc.material.pore_strength = 0.0
        # --texture-sizes fixed: the Renderer's 1024 / 2048 (every round's scores since round 14);
        # auto: what `dermis render` picks for the view (dermis.adaptive_resolution; 2048 / 4096 here)
        sizes = {} if a.texture_sizes == "fixed" else {"irradiance_size": None, "shadow_size": None}
        with Renderer(sc, (a.size, a.size), **sizes) as r:
            imgs = {t: r.render(t) for t in a.techniques}
        for lm, (rgba, meta) in crops.items():
            x0, y0, x1, y1 = meta["box"]
            skin = rgba[..., 3] >= 0.999
            ref = over_background(sc, rgba)
            row = {"box": meta["box"], "spp": meta["spp"], "seeds": meta["seeds"], "skin_px": int(skin.sum()),
                   "floor_flip": meta.get("floor_flip"), "cycles_rgb": [round(float(v), 4) for v in ref[skin].mean(0)]}
            for t, img in imgs.items():
                win = img[y0:y1, x0:x1, :3]
                row[t] = {"flip": round(metrics(sc, ref, win, skin)[0]["flip"], 4),
                          "ratio_rgb": [round(float(v), 3) for v in win[skin].mean(0) / ref[skin].mean(0)]}
            report["crops"][f"{stem}:{lm}{'' if not a.nospec else ':nospec'}"] = row
            print(f"{stem}:{lm} floor {row['floor_flip']} " + "  ".join(
                f"{t} {row[t]['flip']:.4f} {'/'.join(f'{v:.3f}' for v in row[t]['ratio_rgb'])}" for t in imgs),
                flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    return report


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("render", "score"))
    ap.add_argument("--size", type=int, default=768)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--budget-s", type=float, default=0.0, help="stop starting crops after this many seconds")
    ap.add_argument("--only", nargs="*", help="SCENE:LANDMARK, e.g. front-key:nose")
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--techniques", nargs="+", default=list(crop_sheet.TECHNIQUES))
    ap.add_argument("--json", default=None)
    ap.add_argument("--nospec", action="store_true", help="rho_s 0 on both sides (files <crop>-nospec.npz)")
    ap.add_argument("--texture-sizes", choices=("fixed", "auto"), default="fixed",
                    help="score: irradiance / shadow sizes fixed at 1024 / 2048, or chosen from the view as dermis render does")
    a = ap.parse_args(argv)
    return render(a) if a.mode == "render" else score(a)


if __name__ == "__main__":
    main()
