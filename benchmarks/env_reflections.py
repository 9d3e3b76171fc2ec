"""Environment reflections on the example head, looked at as a person would (issue 12).

Renders examples/reference/environment.toml (studio.exr, soft lobes) and the same head in a
studio HDR with two rectangular soft boxes (written here, dermis's equirect convention), with the
environment only (no lights), full image and specular only, and writes the images, a face crop
and the numbers RESULTS.md quotes. Run it with this checkout and with another (e.g. main, as
``PYTHONPATH=/work/main/src``) to compare before/after:

    python benchmarks/env_reflections.py OUT_DIR [--size 640] [--technique tsd]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCENE = HERE.parent / "examples" / "reference" / "environment.toml"


def softbox_studio(h=256, w=512):
    """A dark studio (0.03) with a large warm soft box front-left-up and a narrow cool strip at
    the right; radiance 8 and 5 (linear)."""
    img = np.full((h, w, 3), 0.03, np.float32)
    elev = 90.0 - (np.arange(h) + 0.5) / h * 180.0
    phi = ((np.arange(w) + 0.5) / w - 0.5) * 360.0  # 0: -z (the image centre); 90: +x
    def box(phi0, elev0, half_phi, half_elev, rgb):
        rows = np.abs(elev - elev0) <= half_elev
        cols = np.abs((phi - phi0 + 180.0) % 360.0 - 180.0) <= half_phi
        img[np.ix_(rows, cols)] = rgb
    # the camera looks along -z from +z: the key box behind the camera's left shoulder
    box(-150.0, 25.0, 18.0, 14.0, (8.0, 7.2, 6.2))
    box(120.0, 5.0, 4.0, 30.0, (4.0, 4.6, 5.4))
    return img


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--size", type=int, default=640)
    ap.add_argument("--technique", default="tsd")
    a = ap.parse_args()
    from dermis.api import load_scene
    from dermis.images import write_png
    from dermis.output import output_transform
    from dermis.renderer import Renderer
    from dermis.scene.model import Texture
    from dermis.techniques.shared import OutputMode

    a.out.mkdir(parents=True, exist_ok=True)
    stats = {}
    for name in ("studio", "softbox"):
        scene = load_scene(SCENE)
        if name == "softbox":
            scene.environment.image = Texture(softbox_studio(), "softbox", wrap=("repeat", "clamp"))
        with Renderer(scene, (a.size, a.size), irradiance_size=1024) as r:
            t0 = time.perf_counter()
            full = r.render(a.technique)
            t_first = time.perf_counter() - t0
            spec4 = r.render(a.technique, output_mode=OutputMode.SPECULAR, with_alpha=True)
            spec, cover = spec4[:, :, :3], spec4[:, :, 3]
            stats[name] = {"first_frame_s": round(t_first, 2), "passes_ms": r.stats.get("passes_ms")}
        for tag, img, exp in (("full", full, 0.0), ("spec", spec, 3.0)):
            rgb = output_transform(img, exposure=exp)
            write_png(a.out / f"{name}_{tag}.png", rgb)
            h = a.size
            crop = rgb[int(0.25 * h):int(0.75 * h), int(0.25 * h):int(0.75 * h)]  # the face
            write_png(a.out / f"{name}_{tag}_face.png", crop)
        # the face crop's skin pixels: the specular's spread (a flat tint has p95 / p5 near 1)
        h = a.size
        lum = spec.sum(-1)[int(0.25 * h):int(0.75 * h), int(0.25 * h):int(0.75 * h)]
        on = cover[int(0.25 * h):int(0.75 * h), int(0.25 * h):int(0.75 * h)] > 0.99
        p5, p50, p95 = (float(np.percentile(lum[on], q)) for q in (5, 50, 95))
        stats[name].update({"face_spec_p5": p5, "face_spec_median": p50, "face_spec_p95": p95,
                            "face_spec_p95_over_p5": p95 / p5, "face_spec_max": float(lum[on].max())})
        np.save(a.out / f"{name}_spec.npy", spec)
    (a.out / "stats.json").write_text(json.dumps(stats, indent=1))
    print(json.dumps(stats, indent=1))


if __name__ == "__main__":
    main()
