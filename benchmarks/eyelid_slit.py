"""The closed eyelid's slit against the offline reference (issue 12: ssss's orange eyelid line).

    PYTHONPATH=src python benchmarks/eyelid_slit.py OUT_DIR [--size 128] [--width-mm 40]
        [--techniques lambert tsd ssss preintegrated] [--reference] [--png]

A close-up of the example head's +x eye (examples/lee-perry-smith.toml, the landmark of
benchmarks/crop_sheet.py, seen from the scene's own camera direction, ``--width-mm`` across).
The slit is where the light that enters the skin is dark between lit lids: pixels whose
pre-scatter irradiance (ssss's first pass, red) is below 0.35 of its 9 x 9 median inside the
eye's crop. Printed: the mean red radiance over the slit per technique and, with
``--reference`` (dermis.reference, paths = "tissue", cached in OUT_DIR/reference-*.npz; minutes),
its ratio to the reference's. ``--png``: OUT_DIR/eyelid_slit.png, the techniques side by side.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))


def closeup_scene(width_mm: float = 40.0, fov_deg: float = 26.0):
    """The example scene with its camera moved to frame the +x eye, width_mm across."""
    import dermis
    from crop_sheet import landmarks
    from dermis.scene.model import Camera

    sc = dermis.load_scene(REPO / "examples" / "lee-perry-smith.toml")
    point, _ = landmarks(sc.mesh, sc.mm_per_unit)["eye +x"]
    d = np.asarray(sc.camera.position, np.float64) - np.asarray(sc.camera.target, np.float64)
    d /= np.linalg.norm(d)
    dist = width_mm / sc.mm_per_unit / 2.0 / np.tan(np.radians(fov_deg) / 2.0)
    sc.camera = Camera(position=tuple(point + d * dist), target=tuple(point), fov_deg=fov_deg)
    return sc


def slit_mask(pre_scatter_red: np.ndarray) -> np.ndarray:
    """Pixels darker than 0.35 of their 9 x 9 median of pre-scatter light, away from the frame's
    edge and the background: the closed eye's slit and its shadowed margins."""
    from scipy.ndimage import median_filter

    med = median_filter(pre_scatter_red, size=9, mode="nearest")
    h, w = pre_scatter_red.shape
    inner = np.zeros((h, w), bool)
    inner[h // 8:h - h // 8, w // 8:w - w // 8] = True
    return inner & (pre_scatter_red > 0) & (pre_scatter_red < 0.35 * med) & (med > 0.2 * np.median(pre_scatter_red))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--width-mm", type=float, default=40.0)
    ap.add_argument("--techniques", nargs="+", default=["lambert", "tsd", "ssss", "preintegrated"])
    ap.add_argument("--reference", action="store_true")
    ap.add_argument("--png", action="store_true")
    a = ap.parse_args(argv)
    from dermis.renderer import Renderer

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    sc = closeup_scene(a.width_mm)
    S = a.size
    images = {}
    with Renderer(sc, (S, S), irradiance_size=1024) as r:
        for t in a.techniques:
            images[t] = r.render(t)
        r.render("ssss")
        pre = r.technique("ssss").debug_buffers()["ssss_irradiance"][:, :, 0]
    mask = slit_mask(pre)
    if a.reference:
        cache = out / f"reference-{S}-{a.width_mm:g}mm.npz"
        if not cache.is_file():
            from dermis.reference.render import render_reference

            res = render_reference(sc, (S, S), paths="tissue")
            np.savez_compressed(cache, image=np.asarray(res.image, np.float32))
        images["reference"] = np.load(cache)["image"]
    ref = images.get("reference")
    print(f"slit: {int(mask.sum())} pixels of {S} x {S} ({a.width_mm:g} mm across)")
    for t, img in images.items():
        red = float(img[mask, 0].mean())
        extra = f"  ({red / float(ref[mask, 0].mean()):.2f}x the reference)" if ref is not None else ""
        print(f"{t:14s} red {red:.4f}{extra}")
    np.savez_compressed(out / "eyelid_slit.npz", mask=mask, pre_scatter_red=pre, **images)
    if a.png:
        from PIL import Image

        from dermis.reference.validate import display

        tiles = [display(sc, images[t]) for t in images]
        row = np.concatenate([np.clip(t[..., :3], 0, 1) for t in tiles], axis=1)
        Image.fromarray((row * 255 + 0.5).astype(np.uint8)).save(out / "eyelid_slit.png")
        print("columns:", ", ".join(images))


if __name__ == "__main__":
    main()
