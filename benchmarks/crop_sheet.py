"""Crop sheets of the head's problem areas (issue 12): nose, eyes, lips, ears per technique, before
and after, with an optional Cycles column.

    PYTHONPATH=src python benchmarks/crop_sheet.py OUT_DIR [--size 768] [--before REV]
        [--techniques tsd ssss preintegrated lambert] [--scenes A.toml ...] [--cycles DIR]
        [--crop-mm 56] [--tile 192] [--reuse-work] [--cache-dir DIR] [--before-cache-dir DIR]

writes OUT_DIR/<scene>.png: one row per landmark the camera sees, one column per technique and
tree ("tsd @aa056b3", "tsd"), then Cycles. Default scenes: examples/lee-perry-smith.toml and the
four examples/reference/*.toml. ``--before REV`` renders the same scenes with ``git archive REV
src`` (a temporary copy, in a subprocess) beside this tree's; renders are cached in OUT_DIR/renders
(keyed by tree, scene, technique, size). ``--cycles DIR``: DIR/<scene stem>/cycles_spec.exr as
written by ``dermis validate --against cycles --out DIR`` (skipped where absent), at any size of
the renders' aspect (the validation's 64 x 64 included: its crops are cut from the same mm square
and enlarged to the tile, so they are blurry; the column is labelled with the size).
``--cycles-crops DIR`` (default benchmarks/cycles/crops): Cycles windows of the crops at the renders'
own size (benchmarks/cycles_crops.py), a column at full resolution where they exist and are current.
``--cache-dir`` / ``--before-cache-dir``: DERMIS_CACHE_DIR for this tree's / the before tree's renders
(generated data such as tsd's subsurface transfer bake is found there: an A/B of two bakes).

Crops are located from the MESH, not from pixel boxes: landmarks are points of the head found in
millimetres about the nose tip (the mesh's frontmost vertex, +z is the face's direction, as in
dermis.blender.validate's regions), projected with the camera of each render; a square of
``--crop-mm`` millimetres at the landmark's depth around it. A landmark hidden from the camera
(a ray cast from the eye meets the mesh first) or facing away gets no row.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
SCENES = [REPO / "examples" / "lee-perry-smith.toml"] + [REPO / "examples" / "reference" / f"{n}.toml"
                                                          for n in ("front-key", "side", "back-ears", "environment")]
TECHNIQUES = ("tsd", "ssss", "preintegrated", "lambert")

# landmark -> (x, y) in mm about the nose tip and a search half-width (mm): the frontmost vertex
# (largest z) of the mesh in that square is the landmark. Ears: the mesh's farthest vertex from
# the midline at ear height and depth (dermis.blender.validate: EAR_BOX_MM).
FRONT_LANDMARKS = {"nose": ((0.0, -6.0), 6.0), "eye +x": ((31.0, 33.0), 7.0), "eye -x": ((-31.0, 33.0), 7.0),
                   "lips": ((0.0, -40.0), 6.0)}
CROP_MM = 56.0  # the crop's side at the landmark's depth (times CROP_SCALE)
CROP_SCALE = {"nose": 1.0, "eye +x": 1.0, "eye -x": 1.0, "lips": 1.1, "ear +x": 1.4, "ear -x": 1.4}


def landmarks(mesh, mm_per_unit: float) -> dict:
    """{name: ((3,) point in scene units, (3,) outward normal)} of the head's nose, eyes, lips, ears."""
    from dermis.blender.validate import EAR_BOX_MM, EAR_LATERAL_MM

    pos = np.asarray(mesh.positions, np.float64)
    nrm = np.asarray(mesh.normals, np.float64)
    tip = pos[np.argmax(pos[:, 2])]
    rel = (pos - tip) * mm_per_unit
    out = {}
    for name, ((cx, cy), r) in FRONT_LANDMARKS.items():
        sel = np.nonzero((np.abs(rel[:, 0] - cx) <= r) & (np.abs(rel[:, 1] - cy) <= r))[0]
        if len(sel):
            i = sel[np.argmax(rel[sel, 2])]
            out[name] = (pos[i], nrm[i])
    for sign, name in ((1.0, "ear +x"), (-1.0, "ear -x")):
        x = sign * rel[:, 0]
        sel = np.nonzero((x > EAR_LATERAL_MM) & (rel[:, 1] >= EAR_BOX_MM[0][0]) & (rel[:, 1] <= EAR_BOX_MM[0][1])
                         & (rel[:, 2] >= EAR_BOX_MM[1][0]) & (rel[:, 2] <= EAR_BOX_MM[1][1]))[0]
        if len(sel):
            far = sel[x[sel] >= np.percentile(x[sel], 90)]  # the outer part of the ear: its centre
            c = pos[far].mean(0)
            n = np.array([sign, 0.0, 0.0])
            out[name] = (pos[sel[np.argmin(np.linalg.norm(pos[sel] - c, axis=1))]], n)
    return out


def visible(mesh, point, normal, eye) -> bool:
    """The camera sees the landmark: it faces the eye and nothing lies between them."""
    from dermis.geometry.raycast import RayCaster

    v = np.asarray(point, np.float64) - np.asarray(eye, np.float64)
    dist = float(np.linalg.norm(v))
    if np.dot(normal, -v / dist) <= 0.05:
        return False
    caster = RayCaster(np.asarray(mesh.positions, np.float64), np.asarray(mesh.indices, np.int64).reshape(-1, 3))
    return not bool(caster.occluded(np.asarray(eye, np.float64)[None], (v / dist)[None], 0.0, dist * 0.995)[0])


def crop_box(point, viewproj, view, proj, size, crop_mm: float, mm_per_unit: float):
    """(x0, y0, x1, y1) pixels of a crop_mm square at the point's depth around its projection."""
    w, h = size
    q = np.asarray(viewproj, np.float64) @ np.r_[point, 1.0]
    ndc = q[:2] / q[3]
    cx, cy = (ndc[0] * 0.5 + 0.5) * w, (0.5 - ndc[1] * 0.5) * h
    depth_mm = -float((np.asarray(view, np.float64) @ np.r_[point, 1.0])[2]) * mm_per_unit
    ppm = 0.5 * h * float(proj[1, 1]) / max(depth_mm, 1e-6)  # pixels per mm at that depth
    half = 0.5 * crop_mm * ppm
    return int(round(cx - half)), int(round(cy - half)), int(round(cx + half)), int(round(cy + half))


def cut(img, box, tile: int) -> np.ndarray:
    """The box of a display image (padded with black outside the frame), resized to tile x tile."""
    from PIL import Image

    x0, y0, x1, y1 = box
    h, w = img.shape[:2]
    out = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
    sx0, sy0, sx1, sy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if sx1 > sx0 and sy1 > sy0:
        out[sy0 - y0:sy1 - y0, sx0 - x0:sx1 - x0] = img[sy0:sy1, sx0:sx1, :3]
    u8 = Image.fromarray((np.clip(out, 0, 1) * 255 + 0.5).astype(np.uint8))
    return np.asarray(u8.resize((tile, tile), Image.LANCZOS), np.float32) / 255.0


# ---------------------------------------------------------------------- rendering (any tree)
def render_to(path: Path, scene_file: str, techniques, size: int) -> None:
    """Render scene_file with each technique at size x size into an .npz: linear images and the
    camera (view, proj, eye) of the frame. Uses whatever dermis PYTHONPATH provides."""
    import dermis
    from dermis.renderer import Renderer

    sc = dermis.load_scene(scene_file)
    arrays = {}
    with Renderer(sc, (size, size), irradiance_size=1024) as r:
        for t in techniques:
            arrays[f"img_{t}"] = r.render(t).astype(np.float32)
            f = r.last_frame
            arrays[f"view_{t}"], arrays[f"proj_{t}"], arrays[f"eye_{t}"] = f.view, f.proj, np.asarray(f.eye)
    np.savez_compressed(path, **arrays)


def renders(tree: str, src: Path, scene_file: Path, techniques, size: int, cache: Path, reuse_work: bool = False,
            dermis_cache: str | None = None) -> dict:
    """{technique: (linear image, view, proj, eye)} of ``tree`` (its src directory ``src``; its
    DERMIS_CACHE_DIR ``dermis_cache`` where given), cached."""
    key = hashlib.sha1(f"{tree}|{scene_file}|{size}|{','.join(techniques)}|{dermis_cache}".encode()).hexdigest()[:12]
    path = cache / f"{tree}-{scene_file.stem}-{size}-{key}.npz"
    # this tree's renders are redone (the shaders may have changed) unless reuse_work
    if (tree == "work" and not reuse_work) or not path.is_file():
        env = dict(os.environ, PYTHONPATH=str(src))
        if dermis_cache is not None:
            env["DERMIS_CACHE_DIR"] = dermis_cache
        subprocess.run([sys.executable, __file__, "--render-to", str(path), "--size", str(size), "--techniques",
                        *techniques, "--scenes", str(scene_file)], check=True, env=env)
    z = np.load(path)
    return {t: (z[f"img_{t}"], z[f"view_{t}"], z[f"proj_{t}"], z[f"eye_{t}"]) for t in techniques}


def old_tree(rev: str, into: Path) -> Path:
    """``git archive rev src`` extracted under ``into``; returns its src directory."""
    dest = into / rev
    if not (dest / "src" / "dermis").is_dir():
        dest.mkdir(parents=True, exist_ok=True)
        tar = subprocess.run(["git", "-C", str(REPO), "archive", rev, "src"], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(dest)], input=tar, check=True)
    return dest / "src"


def cycles_crops_column(scene, scene_file: Path, crops_dir, size: int):
    """(label, linear frame) with the stored full-resolution Cycles crops (benchmarks/cycles_crops.py)
    of this scene pasted where they belong (black elsewhere), or None when it has none (or only
    stale ones)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from cycles_crops import frame_boxes, load_crop, over_background

    frame, spp = np.zeros((size, size, 3), np.float32), set()
    for lm in frame_boxes(scene, size):
        c = load_crop(Path(crops_dir), scene_file.stem, lm, scene, size)
        if c is not None:
            (rgba, meta), (x0, y0, x1, y1) = c, c[1]["box"]
            frame[y0:y1, x0:x1] = over_background(scene, rgba)
            spp.add(f"{meta['spp']}x{meta['seeds']}")
    return (f"Cycles {size}px {'/'.join(sorted(spp))} spp", frame) if spp else None


def sheet(scene_file: Path, columns, cycles_dir, size, crop_mm, tile, cycles_crops=None):
    """One scene's crop sheet: uint8 image and the landmarks used."""
    import dermis
    from PIL import Image, ImageDraw

    from dermis.reference.validate import display

    sc = dermis.load_scene(scene_file)
    mm = float(sc.mm_per_unit)
    lm = landmarks(sc.mesh, mm)
    label0, (img0, view0, proj0, eye0) = columns[0]
    if cycles_dir:
        exr = Path(cycles_dir) / scene_file.stem / "cycles_spec.exr"
        if exr.is_file():
            from dermis.images import read_image

            cyc = read_image(exr, srgb=False)[..., :3]
            (h, w), (H, W) = cyc.shape[:2], img0.shape[:2]
            # any size of the same aspect: the same camera frames the same view, and each crop is
            # cut from the mm square of its own image (a 64 x 64 Cycles run gives blurry tiles)
            if abs(w * H - h * W) <= max(W, H) // 64:
                columns = list(columns) + [(f"Cycles {w}x{h}", (cyc, view0, proj0, eye0))]
            else:
                print(f"{exr}: {w}x{h} is not the aspect of the {W}x{H} renders; no Cycles column", file=sys.stderr)
    if cycles_crops and img0.shape[0] == img0.shape[1]:
        col = cycles_crops_column(sc, scene_file, cycles_crops, img0.shape[0])
        if col is not None:
            columns = list(columns) + [(col[0], (col[1], view0, proj0, eye0))]
    rows = [(name, p) for name, (p, n) in lm.items() if visible(sc.mesh, p, n, eye0)]
    pad, band = 4, 18
    H = band + len(rows) * (tile + pad) + pad
    W = 70 + len(columns) * (tile + pad)
    out = Image.new("RGB", (W, max(H, band + pad)), (16, 16, 18))
    draw = ImageDraw.Draw(out)
    for j, (label, _) in enumerate(columns):
        draw.text((70 + j * (tile + pad), 3), label, fill=(235, 235, 235))
    for i, (name, p) in enumerate(rows):
        y = band + i * (tile + pad)
        draw.text((4, y + tile // 2), name, fill=(235, 235, 235))
        for j, (label, (img, view, proj, eye)) in enumerate(columns):
            box = crop_box(p, proj @ view, view, proj, (img.shape[1], img.shape[0]), crop_mm * CROP_SCALE[name], mm)
            c = cut(display(sc, img), box, tile)
            out.paste(Image.fromarray((c * 255 + 0.5).astype(np.uint8)), (70 + j * (tile + pad), y))
    return np.asarray(out), [r[0] for r in rows]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", help="output directory")
    ap.add_argument("--size", type=int, default=768)
    ap.add_argument("--techniques", nargs="+", default=list(TECHNIQUES))
    ap.add_argument("--scenes", nargs="+", default=[str(s) for s in SCENES])
    ap.add_argument("--before", default=None, help="git revision to render beside this tree (e.g. aa056b3)")
    ap.add_argument("--cycles", default=None, help="a `dermis validate --against cycles --out` directory")
    ap.add_argument("--cycles-crops", default=str(REPO / "benchmarks" / "cycles" / "crops"),
                    help="full-resolution Cycles crops (benchmarks/cycles_crops.py); '' for none")
    ap.add_argument("--crop-mm", type=float, default=CROP_MM)
    ap.add_argument("--tile", type=int, default=192)
    ap.add_argument("--reuse-work", action="store_true", help="reuse this tree's cached renders (e.g. another --tile)")
    ap.add_argument("--cache-dir", default=None, help="DERMIS_CACHE_DIR for this tree's renders")
    ap.add_argument("--before-cache-dir", default=None, help="DERMIS_CACHE_DIR for the --before tree's renders")
    ap.add_argument("--render-to", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.render_to:
        return render_to(Path(a.render_to), a.scenes[0], a.techniques, a.size)
    if not a.out:
        ap.error("OUT_DIR is required")
    from PIL import Image

    out = Path(a.out)
    cache = out / "renders"
    cache.mkdir(parents=True, exist_ok=True)
    trees = [("work", REPO / "src")]
    tmp = None
    if a.before:
        tmp = tempfile.TemporaryDirectory(prefix="dermis-before-")
        trees.insert(0, (a.before, old_tree(a.before, Path(tmp.name))))
    for scene_file in map(Path, a.scenes):
        scene_file = scene_file.resolve()
        per_tree = {tree: renders(tree, src, scene_file, a.techniques, a.size, cache, a.reuse_work,
                                  a.cache_dir if tree == "work" else a.before_cache_dir) for tree, src in trees}
        columns = []
        for t in a.techniques:
            for tree, _ in trees:
                columns.append((t if tree == "work" else f"{t} @{tree}", per_tree[tree][t]))
        img, rows = sheet(scene_file, columns, a.cycles, a.size, a.crop_mm, a.tile, a.cycles_crops)
        Image.fromarray(img).save(out / f"{scene_file.stem}.png")
        print(f"{scene_file.stem}: {', '.join(rows)} -> {out / (scene_file.stem + '.png')}")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
