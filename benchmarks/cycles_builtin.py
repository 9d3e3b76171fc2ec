"""Cycles of the built-in scene (``make demo``'s image: ``dermis render --size 768x768``, the procedural
head of dermis.default_scene()) for a pixel window of its frame, and the techniques against it (issue 12,
round 21, demo21).

    PYTHONPATH=src python benchmarks/cycles_builtin.py check --tmp DIR
    PYTHONPATH=src python benchmarks/cycles_builtin.py cycles --box X0 Y0 X1 Y1 --out C.npz --tmp DIR
        [--size 768] [--spp 256] [--seeds 2] [--threads 2]
    PYTHONPATH=src python benchmarks/cycles_builtin.py techniques --out R.npz [--size 768] [--pores]
    PYTHONPATH=src python benchmarks/cycles_builtin.py compare C.npz R.npz --patch X0 Y0 X1 Y1
        [--ring 6] [--sheet OUT.png] [--zoom 4] [--json OUT.json]

Why a script and not ``cycles_crops.py``: the built-in scene has no TOML and its maps are in-memory
arrays. Until round 21 dermis.blender.export wrote such a map to an EXR of its (linear) values but still
loaded the albedo with colorspace "sRGB", and Blender applies that colorspace to float images too (0.5
read back as 0.214): the albedo was decoded twice. demo21 rendered the stored windows with each map
written here (albedo sRGB-encoded); the export now loads an EXR albedo as linear
(tests/test_blender_cycles.py::test_in_memory_albedo_exports_its_linear_values), so the maps are written
here as their linear values, as the export itself would, and ``check`` reads them back through bpy and
compares them with the arrays (the stored windows were re-keyed, benchmarks/rekey_cycles_stores.py: the
albedo Blender reads is the same array either way). Everything else is the export of the scene itself
(camera fit: export.build_camera frames it as dermis does).

``cycles``: dermis.blender.crop_render's render border of the SAME frame (its pixels are the frame's),
``--seeds`` seeds of ``--spp`` samples: the seeds' mean (RGB + coverage) and the seed-to-seed FLIP over
the window's skin (the noise floor). ``techniques``: the four techniques at the frame size with the
texture sizes ``dermis render`` picks (auto), pore_strength 0 (Cycles has no pores; ``--pores`` keeps the
scene's). ``compare``: linear per-channel means of the patch and of a ring around it, FLIP of the window
(skin pixels), for the raw techniques and for them through Cycles' pixel filter (Blackman-Harris
1.5 px, dermis.blender.pixel_filter at factor 1), and a sheet: the window per technique beside Cycles,
and a x``--zoom`` nearest zoom of the patch with a margin.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
TECHNIQUES = ("tsd", "ssss", "preintegrated", "lambert")
STORE = REPO / "benchmarks" / "cycles" / "builtin"  # the stored windows (cycles_crops.save_crop's format)


def builtin_scene(pores: bool = False):
    import dermis

    sc = dermis.default_scene()
    if not pores:
        sc.material.pore_strength = 0.0  # the offline reference has no procedural pore normals
    return sc


def cycles_ready(scene, folder: Path):
    """``scene`` with its in-memory maps written to ``folder`` and their Textures' ``source`` set to the
    files, so that the export loads them with the values dermis uses (see the module docstring)."""
    from dermis.images import write_exr

    folder.mkdir(parents=True, exist_ok=True)
    m = scene.material
    out = {}
    for name in ("albedo", "normal_map", "specular_map"):
        tex = getattr(m, name)
        if tex is None:
            continue
        data = np.asarray(tex.data, np.float32)
        data = np.repeat(data[..., :1], 3, -1) if data.ndim == 3 and data.shape[2] == 1 else data
        path = folder / f"{name}.exr"
        write_exr(path, data[..., :3])  # always: a file left by another layout of the head would be stale (seam21)
        out[name] = dataclasses.replace(tex, source=str(path.resolve()))
    return dataclasses.replace(scene, material=dataclasses.replace(m, **out))


def check(a) -> dict:
    """Build the Blender scene of the built-in head and compare each image node's pixels (Blender's
    scene-linear float buffer) with the dermis array (row 0 at the top; Blender's bottom row first)."""
    from dermis.blender import require_bpy
    from dermis.blender.export import ExportOptions, build_scene

    bpy = require_bpy()
    sc = builtin_scene()
    cs = cycles_ready(sc, Path(a.tmp))
    report = {}
    for label, scene in (("export as it is", sc), ("cycles_ready", cs)):
        build_scene(scene, ExportOptions(texture_dir=Path(a.tmp) / "export-as-is"), (a.size, a.size))
        nodes = bpy.data.materials["skin"].node_tree.nodes
        for name in ("albedo", "normal_map", "specular_map"):
            img = nodes[name].image
            w, h = img.size
            px = np.empty(w * h * 4, np.float32)
            img.pixels.foreach_get(px)
            px = px.reshape(h, w, 4)[::-1, :, :3]
            ref = np.asarray(getattr(scene.material, name).data, np.float32)
            ref = ref if ref.shape[2] == 3 else np.repeat(ref[..., :1], 3, -1)
            d = np.abs(px - ref)
            report[f"{label}: {name}"] = {"colorspace": img.colorspace_settings.name, "max_abs": float(d.max()),
                                          "mean_blender": [round(float(v), 4) for v in px.reshape(-1, 3).mean(0)],
                                          "mean_dermis": [round(float(v), 4) for v in ref.reshape(-1, 3).mean(0)]}
            print(f"{label}: {name} ({img.colorspace_settings.name}) max |blender - dermis| {d.max():.2e}, "
                  f"means {report[f'{label}: {name}']['mean_blender']} vs {report[f'{label}: {name}']['mean_dermis']}")
    return report


def cycles(a) -> None:
    import bpy  # noqa: F401  (dermis.blender needs it; fail early)
    from cycles_crops import crop_key, save_crop
    from dermis.blender.crop_render import render_cycles_window
    from dermis.reference.validate import metrics

    sc = builtin_scene()
    key = crop_key(sc, a.size, a.box, a.spp, a.seeds)  # the in-memory scene's content, not the files' paths
    csc = cycles_ready(sc, Path(a.tmp))
    box, imgs, secs = tuple(a.box), [], 0.0
    for s in range(a.seeds):
        img, st = render_cycles_window(csc, (a.size, a.size), box, spp=a.spp, seed=1000 + s, threads=a.threads,
                                       alpha=True)
        imgs.append(img)
        secs += st["build_s"] + st["render_s"]
        print(f"seed {1000 + s}: {st['render_s']:.0f} s", flush=True)
    skin = np.min([i[..., 3] for i in imgs], 0) >= 0.999
    floor = metrics(sc, over_background(sc, imgs[0]), over_background(sc, imgs[1]), skin)[0]["flip"] \
        if a.seeds > 1 and skin.any() else None
    meta = {"scene": "builtin:default", "landmark": a.name, "size": a.size, "box": list(box), "spp": a.spp,
            "seeds": a.seeds, "seed_values": [1000 + s for s in range(a.seeds)], "key": key, "specular": True,
            "floor_flip": None if floor is None else round(floor, 4), "cycles_s": round(secs, 1),
            "load": round(os.getloadavg()[0], 1), "blender": bpy.app.version_string}
    Path(a.out).mkdir(parents=True, exist_ok=True)
    save_crop(Path(a.out), "builtin", a.name, np.mean(imgs, 0), meta)  # OUT/builtin--<name>.npz
    print(json.dumps(meta))


def load_cycles(out: Path, name: str, check_key: bool = True):
    """(RGBA mean of the seeds, metadata) of a stored window; None when absent or stale (the built-in
    scene or the Cycles set-up changed since)."""
    from cycles_crops import load_crop

    c = load_crop(out, "builtin", name)
    if c is None:
        return None
    rgba, meta = c
    if check_key:
        from cycles_crops import crop_key

        if meta["key"] != crop_key(builtin_scene(), meta["size"], meta["box"], meta["spp"], meta["seeds"]):
            print(f"{name}: stored Cycles window is stale (the built-in scene or the bridge changed)")
            return None
    return rgba, meta


def over_background(scene, rgba) -> np.ndarray:
    """Cycles' transparent film (premultiplied) over the scene's output background, as dermis draws it."""
    bg = np.asarray(scene.output.background, np.float32)
    return rgba[..., :3] + (1.0 - rgba[..., 3:4]) * bg


def techniques(a) -> None:
    from dermis.renderer import Renderer

    sc = builtin_scene(a.pores)
    arrays = {}
    with Renderer(sc, (a.size, a.size), irradiance_size=None, shadow_size=None) as r:  # `dermis render`'s auto
        for t in a.techniques:
            t0 = time.perf_counter()
            arrays[f"img_{t}"] = r.render(t)[..., :3].astype(np.float32)
            print(f"{t}: {time.perf_counter() - t0:.1f} s (irradiance {r.irradiance_size}, shadow {r.shadows.tile_size})",
                  flush=True)
    np.savez_compressed(a.out, **arrays)


def _means(img, sel) -> list:
    return [round(float(v), 4) for v in img[sel].mean(0)]


def compare(a) -> dict:
    """The techniques (``renders``, rendered at ``--factor`` x the window's frame size) against the
    stored Cycles window ``--name``: FLIP over its skin, mean RGB ratios; with ``--patch`` the patch's
    and a ring's means. ``--factor`` k > 1: each technique reconstructed with Cycles' pixel filter
    from k x k supersamples (what ``dermis validate`` does); k = 1: as rendered, and also through the
    filter at factor 1 ("+BH")."""
    from dermis.blender.pixel_filter import reconstruct
    from dermis.reference.validate import metrics

    sc = builtin_scene()
    c = load_cycles(Path(a.store), a.name, check_key=not a.stale_ok)
    if c is None:
        raise SystemExit(f"no current Cycles window '{a.name}' in {a.store}")
    rgba, meta = c
    x0, y0, x1, y1 = meta["box"]
    ref = over_background(sc, rgba)
    skin = rgba[..., 3] >= 0.999
    with np.load(a.renders) as z:
        imgs = {t: z[f"img_{t}"] for t in TECHNIQUES if f"img_{t}" in z.files}
    k = a.factor
    report = {"cycles": meta, "skin_px": int(skin.sum()), "factor": k,
              "Cycles": {"skin": _means(ref, skin)}}
    masks = {"skin": skin}
    if a.patch:
        px0, py0, px1, py1 = a.patch  # frame pixels, x1 / y1 exclusive
        patch = np.zeros(skin.shape, bool)
        patch[py0 - y0:py1 - y0, px0 - x0:px1 - x0] = True
        ring = np.zeros(skin.shape, bool)
        ring[max(py0 - y0 - a.ring, 0):py1 - y0 + a.ring, max(px0 - x0 - a.ring, 0):px1 - x0 + a.ring] = True
        masks.update(patch=patch & skin, ring=ring & ~patch & skin)
        report.update(patch=list(a.patch), ring_px=a.ring)
    report["Cycles"] = {m: _means(ref, sel) for m, sel in masks.items()}
    wins = {}
    for t, img in imgs.items():
        for filt in ((False, True) if k == 1 else (True,)):
            # Cycles' film filter: from k x k supersamples, or (k = 1) on the technique's own pixels
            full = reconstruct(img, k) if filt else img
            win = full[y0:y1, x0:x1]
            label = f"{t}{' +BH' if filt and k == 1 else ''}"
            wins[label] = win
            row = {"flip": round(metrics(sc, ref, win, skin)[0]["flip"], 4)}
            for m, sel in masks.items():
                row[m] = _means(win, sel)
                row[f"{m}_ratio"] = [round(float(v), 3) for v in win[sel].mean(0) / ref[sel].mean(0)]
            report[label] = row
    print(f"Cycles {a.name}: {meta['spp']} spp x {meta['seeds']} seeds, seed-to-seed FLIP {meta['floor_flip']}")
    for lab in ["Cycles"] + list(wins):
        r = report[lab]
        line = f"{lab:18s}" + ("" if lab == "Cycles" else f" FLIP {r['flip']:.4f}")
        for m in masks:
            v = r[m]
            line += f" | {m} {v} R/G {v[0] / v[1]:.3f}" + ("" if lab == "Cycles" else f" /Cycles {r[f'{m}_ratio']}")
        print(line)
    if a.sheet:
        sheet(sc, ref, {n: v for n, v in wins.items() if "+BH" not in n or k > 1}, (x0, y0), a.patch, a.zoom,
              a.sheet, meta, report)
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    return report


def sheet(sc, ref, wins, origin, patch, zoom, out, meta, report) -> None:
    """Row 1: the window per technique and Cycles (display values, x2 when it is small), the patch
    outlined in cyan; with a patch, row 2: the patch with a 14 px margin at x``zoom``, row 3: the same
    at display gain 3 (shadows lifted). Labels: FLIP of the window and the patch's linear R/G."""
    from PIL import Image

    from look_zoom import disp, grid

    x0, y0 = origin
    items = [("Cycles", ref)] + list(wins.items())
    h, w = ref.shape[:2]
    s = max(1, min(3, 400 // max(h, w)))

    def outline(img, box, scale):
        img = img.copy()
        bx0, by0, bx1, by1 = (v * scale for v in box)
        img[by0, bx0:bx1] = img[by1 - 1, bx0:bx1] = (0.0, 1.0, 1.0)
        img[by0:by1, bx0] = img[by0:by1, bx1 - 1] = (0.0, 1.0, 1.0)
        return img

    def label(name, what):
        r = report[name]
        flip = "" if name == "Cycles" else f" FLIP {r['flip']:.3f}"
        rg = f" patch R/G {r['patch'][0] / r['patch'][1]:.2f}" if "patch" in r else ""
        return f"{name}{flip}{rg} {what}"

    rows = []
    tiles = []
    for name, img in items:
        d = np.repeat(np.repeat(disp(sc, img), s, 0), s, 1)
        if patch:
            d = outline(d, (patch[0] - x0, patch[1] - y0, patch[2] - x0, patch[3] - y0), s)
        tiles.append(d)
    rows.append(grid(tiles, [label(n, f"x{s}") for n, _ in items], 1, len(items)))
    if patch:
        m = 14
        zx0, zy0 = max(patch[0] - x0 - m, 0), max(patch[1] - y0 - m, 0)
        zx1, zy1 = min(patch[2] - x0 + m, w), min(patch[3] - y0 + m, h)
        for gain in (1.0, 3.0):
            tiles = []
            for name, img in items:
                d = disp(sc, img, gain)[zy0:zy1, zx0:zx1]
                d = np.repeat(np.repeat(d, zoom, 0), zoom, 1)
                tiles.append(outline(d, (patch[0] - x0 - zx0, patch[1] - y0 - zy0, patch[2] - x0 - zx0,
                                         patch[3] - y0 - zy0), zoom))
            rows.append(grid(tiles, [f"{n}: patch x{zoom}{'' if gain == 1 else ', display x3'}" for n, _ in items],
                             1, len(items)))
    W = max(r.width for r in rows)
    out_img = Image.new("RGB", (W, sum(r.height for r in rows)), (16, 16, 18))
    y = 0
    for r in rows:
        out_img.paste(r, (0, y))
        y += r.height
    out_img.save(out, quality=92) if str(out).lower().endswith((".jpg", ".jpeg")) else out_img.save(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    p = sub.add_parser("check")
    p.add_argument("--tmp", required=True)
    p.add_argument("--size", type=int, default=768)
    p = sub.add_parser("cycles")
    p.add_argument("--name", required=True, help="the window's name: OUT/builtin--NAME.npz")
    p.add_argument("--box", type=int, nargs=4, required=True)
    p.add_argument("--out", default=str(STORE))
    p.add_argument("--tmp", required=True, help="scratch folder for the maps' files")
    p.add_argument("--size", type=int, default=768)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--threads", type=int, default=2)
    p = sub.add_parser("techniques")
    p.add_argument("--out", required=True)
    p.add_argument("--size", type=int, default=768)
    p.add_argument("--pores", action="store_true")
    p.add_argument("--techniques", nargs="+", default=list(TECHNIQUES))
    p = sub.add_parser("compare")
    p.add_argument("name")
    p.add_argument("renders")
    p.add_argument("--store", default=str(STORE))
    p.add_argument("--factor", type=int, default=1, help="renders are this many times the window's frame size")
    p.add_argument("--patch", type=int, nargs=4)
    p.add_argument("--ring", type=int, default=6)
    p.add_argument("--sheet")
    p.add_argument("--zoom", type=int, default=4)
    p.add_argument("--json")
    p.add_argument("--stale-ok", action="store_true",
                   help="compare with a stored window whose key is stale (seam21: the head's new layout re-paints its "
                        "maps in a new texture space; check lambert's patch against the old render to see what moved)")
    a = ap.parse_args(argv)
    return {"check": check, "cycles": cycles, "techniques": techniques, "compare": compare}[a.mode](a)


if __name__ == "__main__":
    main()
