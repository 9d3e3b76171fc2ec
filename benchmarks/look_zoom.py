"""Look at the techniques' renders as a person would (issue 12): full frames, nearest-neighbour
zooms of any pixel window, at 1x and 3x brightness, beside each other, the stored Cycles crop, and
where one technique differs from the rest; and a list of the places where ONE technique has
fine structure the others lack (stripes, specks, seams: what a mean hides).

    PYTHONPATH=src python benchmarks/look_zoom.py frames RENDERS.npz SCENE.toml OUT.png [--gain 3]
    PYTHONPATH=src python benchmarks/look_zoom.py zoom RENDERS.npz SCENE.toml OUT.png
        --box X0 Y0 X1 Y1 [--box ...] [--scale 3] [--gain 1 3] [--diff] [--techniques ...]
        [--extra LABEL=OTHER.npz:TECHNIQUE ...]
    PYTHONPATH=src python benchmarks/look_zoom.py hotspots RENDERS.npz SCENE.toml [--top 12] [--win 48]

RENDERS.npz: what ``benchmarks/crop_sheet.py`` caches in OUT_DIR/renders (``img_<technique>``:
linear RGB, and each frame's camera), or ``render-npz`` below for any scene (a scratch TOML with a
closer camera, another irradiance size). Display values are the scene's own output transform
(dermis.reference.validate.display); "gain 3" multiplies the DISPLAY values by 3 (clipped), which
lifts a shadow's 8-bit value 20 to 60: what a viewer sees with the brightness turned up.

``zoom``: per box, one row per gain: one column per technique, then the stored Cycles crop
(benchmarks/cycles/crops) where the box lies inside one of this scene's crop windows at the same
frame size; with ``--diff`` a row of |technique - median of the others| x4 per technique (a defect
of one technique shows where the others agree). Pixels are repeated (nearest), not resampled.

``hotspots``: per technique, the high-pass of the display luminance (the image minus its 3 x 3
box mean) whose magnitude exceeds EVERY other technique's at that pixel, summed over --win
windows; the top windows (non-overlapping) are printed with the score, the technique and the
other techniques' scores there. Stripes, specks and seams of one technique rank first; edges
the techniques share cancel. It ranks where to look; the looking decides. Limits (round 18): the
sharper techniques (preintegrated, lambert: no blur of the albedo's detail) outscore the blurred
ones everywhere, so compare like with like (``--techniques tsd ssss``); a red-only comb in a
saturated region barely moves the luminance (tsd's ear stripes did not rank: a difference of tsd
at two irradiance sizes found them, benchmarks/RESULTS.md, round 18, review18).

    PYTHONPATH=src python benchmarks/look_zoom.py clusters SCENE.toml A.npz:TECHNIQUE B.npz:TECHNIQUE
        [--levels 10] [--min-pixels 20]    (where two renders differ by more than --levels 8-bit levels)
    PYTHONPATH=src python benchmarks/look_zoom.py render-npz SCENE.toml OUT.npz [--size 768 | WxH]
        [--techniques ...] [--irradiance-size N] [--shadow-size N] [--option NAME=VALUE ...]
        [--samples N] [--supersample K]
        SCENE "default": the built-in head; --option: Renderer.technique's options for every
        technique rendered (e.g. translucency=false); --supersample K: K x the size, 1 sample,
        averaged K x K (the reference for MSAA specks)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
TECHNIQUES = ("tsd", "ssss", "preintegrated", "lambert")


def load(npz, techniques=None) -> dict:
    """{technique: linear (H, W, 3) float32} of a crop_sheet / render-npz file."""
    with np.load(npz) as z:
        names = [k[4:] for k in z.files if k.startswith("img_")]
        return {t: z[f"img_{t}"][..., :3].astype(np.float32) for t in (techniques or names) if t in names}


def scene_of(arg: str):
    """A scene file, or "default": the built-in head (what `dermis view` opens without a scene)."""
    import dermis

    return dermis.default_scene() if arg == "default" else dermis.load_scene(arg)


def disp(scene, linear, gain: float = 1.0) -> np.ndarray:
    from dermis.reference.validate import display

    return np.clip(np.asarray(display(scene, linear), np.float32)[..., :3] * gain, 0.0, 1.0)


def u8(img) -> np.ndarray:
    return (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)


def grid(tiles, labels, rows: int, cols: int, pad: int = 4, band: int = 16) -> "Image":
    """Tiles (row-major, same size; None for blank) with a label over each."""
    from PIL import Image, ImageDraw

    h, w = next(t for t in tiles if t is not None).shape[:2]
    out = Image.new("RGB", (cols * (w + pad) + pad, rows * (h + pad + band) + pad), (16, 16, 18))
    d = ImageDraw.Draw(out)
    for i, (t, lab) in enumerate(zip(tiles, labels)):
        r, c = divmod(i, cols)
        x, y = pad + c * (w + pad), pad + r * (h + pad + band)
        d.text((x, y + 2), lab, fill=(235, 235, 235))
        if t is not None:
            out.paste(Image.fromarray(u8(t)), (x, y + band))
    return out


def cycles_window(scene, stem: str, size: int, box):
    """The stored Cycles crop's pixels of box (LINEAR values, over the background: pass them through disp),
    and its landmark; or None where no current crop holds it."""
    from cycles_crops import OUT, frame_boxes, load_crop, over_background

    x0, y0, x1, y1 = box
    for lm, (a0, b0, a1, b1) in frame_boxes(scene, size).items():
        if a0 <= x0 and b0 <= y0 and x1 <= a1 and y1 <= b1:
            c = load_crop(OUT, stem, lm, scene, size)
            if c is not None:
                rgba, meta = c
                bx0, by0 = meta["box"][0], meta["box"][1]
                return over_background(scene, rgba)[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0], lm
    return None


def frames(a) -> None:
    sc = scene_of(a.scene)
    imgs = load(a.npz, a.techniques)
    tiles, labels = [], []
    for g in a.gain:
        for t, im in imgs.items():
            tiles.append(disp(sc, im, g))
            labels.append(f"{t} x{g:g}")
    grid(tiles, labels, len(a.gain), len(imgs)).save(a.out)


def zoom(a) -> None:
    sc = scene_of(a.scene)
    imgs = load(a.npz, a.techniques)
    for e in a.extra or []:
        lab, rest = e.split("=", 1)
        path, t = rest.rsplit(":", 1)
        imgs[lab] = load(path, [t])[t]
    imgs_shape = next(iter(imgs.values())).shape
    size = imgs_shape[0]
    tiles, labels = [], []
    for box in a.box:
        x0, y0, x1, y1 = box
        for g in a.gain:  # one row per gain: the techniques, then Cycles
            row, rl = [], []
            for t, im in imgs.items():
                row.append(disp(sc, im[y0:y1, x0:x1], g))
                rl.append(f"{t} x{g:g} [{x0}:{x1},{y0}:{y1}]")
            cyc = None  # the stored crops are of the square 768 px frames of the crop sheets' scenes
            if not a.no_cycles and a.scene != "default" and imgs_shape[0] == imgs_shape[1]:
                cyc = cycles_window(sc, Path(a.scene).stem, size, box)
            if cyc is not None:
                row.append(disp(sc, cyc[0], g))
                rl.append(f"Cycles x{g:g} ({cyc[1]})")
            tiles.append(row)
            labels.append(rl)
        if a.diff:  # and a row of each technique's difference from the others' median
            row, rl = [], []
            d = {t: disp(sc, im[y0:y1, x0:x1]) for t, im in imgs.items()}
            for t in d:
                others = np.median(np.stack([v for k, v in d.items() if k != t]), 0)
                row.append(np.abs(d[t] - others) * 4)
                rl.append(f"|{t} - median others| x4")
            tiles.append(row)
            labels.append(rl)
    cols = max(len(r) for r in tiles)
    flat, flabels = [], []
    for row, rl in zip(tiles, labels):
        row = [np.repeat(np.repeat(t, a.scale, 0), a.scale, 1) for t in row]
        flat += row + [None] * (cols - len(row))
        flabels += rl + [""] * (cols - len(rl))
    # boxes of different sizes: pad each tile to the largest
    hmax = max(t.shape[0] for t in flat if t is not None)
    wmax = max(t.shape[1] for t in flat if t is not None)
    flat = [None if t is None else np.pad(t, ((0, hmax - t.shape[0]), (0, wmax - t.shape[1]), (0, 0))) for t in flat]
    grid(flat, flabels, len(tiles), cols).save(a.out)


def box_mean3(x):
    p = np.pad(x, 1, mode="edge")
    return sum(p[i:i + x.shape[0], j:j + x.shape[1]] for i in range(3) for j in range(3)) / 9.0


def hotspots(a) -> list:
    sc = scene_of(a.scene)
    imgs = load(a.npz, a.techniques)
    hp = {}
    for t, im in imgs.items():
        y = disp(sc, im) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        hp[t] = np.abs(y - box_mean3(y))
    stack = np.stack(list(hp.values()))
    names = list(hp)
    found = []
    w = a.win
    H, W = stack.shape[1:]

    def window_sums(x):  # sums over the w x w tiles of the frame (the last partial row/column dropped)
        return x[:H // w * w, :W // w * w].reshape(H // w, w, W // w, w).sum((1, 3))

    o = {k: window_sums(stack[j]) for j, k in enumerate(names)}
    for i, t in enumerate(names):
        others = np.max(np.delete(stack, i, 0), 0)
        s = window_sums(np.maximum(stack[i] - others, 0))
        for (r, c) in zip(*np.unravel_index(np.argsort(s, None)[::-1][:a.top], s.shape)):
            found.append((float(s[r, c]), t, (c * w, r * w, c * w + w, r * w + w),
                          {k: round(float(v[r, c]), 2) for k, v in o.items()}))
    found.sort(key=lambda f: -f[0])
    for score, t, box, o in found[:a.top * 2]:
        print(f"{score:7.2f}  {t:14s} box {box}  high-pass sums {o}")
    return found


def clusters(a) -> list:
    """Where two renders of one scene differ by more than --levels 8-bit display levels (any
    channel): the clusters of such pixels (joined within 4 px), largest first, with their pixel
    count, box and largest difference. E.g. tsd at --irradiance-size 1024 against 4096: the places
    the irradiance texels show."""
    from scipy import ndimage

    sc = scene_of(a.scene)
    path_a, ta = a.a.rsplit(":", 1)
    path_b, tb = a.b.rsplit(":", 1)
    d = (np.abs(disp(sc, load(path_a, [ta])[ta]) - disp(sc, load(path_b, [tb])[tb])) * 255).max(-1)
    lab, _ = ndimage.label(ndimage.binary_dilation(d > a.levels, iterations=4))
    out = []
    for i, sl in enumerate(ndimage.find_objects(lab)):
        n = int(((lab[sl] == i + 1) & (d[sl] > a.levels)).sum())
        if n >= a.min_pixels:
            out.append((n, (sl[1].start, sl[0].start, sl[1].stop, sl[0].stop), round(float(d[sl].max()), 1)))
    out.sort(reverse=True)
    print(f"{(d > a.levels).sum()} pixels differ by > {a.levels:g} levels; clusters (pixels, box x0 y0 x1 y1, max):")
    for n, box, mx in out:
        print(f"  {n:6d}  {box}  {mx}")
    return out


def render_npz(a) -> None:
    from dermis.renderer import Renderer

    sc = scene_of(a.scene)
    w, _, h = a.size.partition("x")
    arrays = {}
    kw = {} if a.shadow_size is None else {"shadow_size": a.shadow_size}
    if a.samples is not None:
        kw["samples"] = a.samples
    opts = {}
    for o in a.option or []:
        name, v = o.split("=", 1)
        opts[name] = {"true": True, "false": False}.get(v.lower(), v)
        if isinstance(opts[name], str):
            try:
                opts[name] = float(v) if "." in v else int(v)
            except ValueError:
                pass
    k = a.supersample
    with Renderer(sc, (int(w) * k, int(h or w) * k), irradiance_size=a.irradiance_size, **kw) as r:
        for t in a.techniques:
            if opts:  # a technique's own options (its Options dataclass), e.g. translucency=false
                r.technique(t, **opts)
            img = r.render(t).astype(np.float32)
            if a.supersample > 1:  # the mean of each k x k block: the frame at 1/k the size
                k = a.supersample
                img = img.reshape(img.shape[0] // k, k, img.shape[1] // k, k, -1).mean((1, 3))
            arrays[f"img_{t}"] = img
            f = r.last_frame
            arrays[f"view_{t}"], arrays[f"proj_{t}"], arrays[f"eye_{t}"] = f.view, f.proj, np.asarray(f.eye)
    np.savez_compressed(a.out, **arrays)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("frames", "zoom", "hotspots"):
        p = sub.add_parser(name)
        p.add_argument("npz")
        p.add_argument("scene")
        if name != "hotspots":
            p.add_argument("out")
        p.add_argument("--techniques", nargs="+", default=None)
        p.add_argument("--gain", type=float, nargs="+", default=[1.0, 3.0] if name == "frames" else [1.0])
        if name == "zoom":
            p.add_argument("--box", type=int, nargs=4, action="append", required=True)
            p.add_argument("--scale", type=int, default=3)
            p.add_argument("--diff", action="store_true")
            p.add_argument("--no-cycles", action="store_true")
            p.add_argument("--extra", action="append", help="LABEL=OTHER.npz:TECHNIQUE, another render as a column")
        if name == "hotspots":
            p.add_argument("--top", type=int, default=12)
            p.add_argument("--win", type=int, default=48)
    p = sub.add_parser("clusters")
    p.add_argument("scene")
    p.add_argument("a", help="A.npz:TECHNIQUE")
    p.add_argument("b", help="B.npz:TECHNIQUE")
    p.add_argument("--levels", type=float, default=10.0)
    p.add_argument("--min-pixels", type=int, default=20)
    p = sub.add_parser("render-npz")
    p.add_argument("scene")
    p.add_argument("out")
    p.add_argument("--size", default="768", help="N or WxH")
    p.add_argument("--techniques", nargs="+", default=list(TECHNIQUES))
    p.add_argument("--irradiance-size", type=int, default=1024)
    p.add_argument("--shadow-size", type=int, default=None)
    p.add_argument("--samples", type=int, default=None, help="MSAA samples (default: the Renderer's)")
    p.add_argument("--supersample", type=int, default=1,
                   help="render k times the size and average k x k blocks (a reference for MSAA specks; "
                        "the saved camera is the large frame's, the same view)")
    p.add_argument("--option", action="append", help="NAME=VALUE: a technique option for every technique rendered")
    a = ap.parse_args(argv)
    {"frames": frames, "zoom": zoom, "hotspots": hotspots, "clusters": clusters, "render-npz": render_npz}[a.cmd](a)


if __name__ == "__main__":
    main()
