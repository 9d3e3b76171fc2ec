"""A pixel window of a Cycles frame: the path-traced reference at a crop's full resolution.

Issue 12's crop sheets compare 768 px crops (nose, eyes, ears, lips) with Cycles; a whole 768 x 768
frame at a few hundred samples per pixel is hours on a CPU, a 200 x 200 window of it minutes. Cycles
renders the window through its render border (``use_border`` + ``use_crop_to_border``) of the SAME
frame (camera, resolution, pixel filter), so the window's pixels are the full frame's pixels.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from dermis.errors import DermisError


def border_fractions(box, size):
    """Blender's render border (min_x, max_x, min_y, max_y) in [0, 1] for the pixel window ``box`` =
    (x0, y0, x1, y1) of a ``size`` = (w, h) frame, row 0 at the TOP (numpy's convention, x1 and y1
    exclusive). Blender's border y runs from the BOTTOM of the frame."""
    (x0, y0, x1, y1), (w, h) = box, size
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise DermisError(f"Cycles window {tuple(box)} is not inside the {w}x{h} frame")
    return x0 / w, x1 / w, (h - y1) / h, (h - y0) / h


def render_cycles_window(scene, size, box, *, spp=64, seed=0, sss=True, specular=True, threads=0, alpha=False):
    """(image (y1 - y0, x1 - x0, 3) float32 linear radiance, stats): the pixels ``box`` = (x0, y0,
    x1, y1) (row 0 at the top) of ``scene`` rendered in Cycles at ``size``, with the set-up of
    dermis.blender.render.render_cycles (fixed spp, no adaptive sampling, the seed); with ``alpha``
    (h, w, 4), alpha = the mesh's coverage."""
    from dermis.blender import require_bpy
    from dermis.blender.export import ExportOptions, build_scene
    from dermis.blender.render import read_render

    bpy = require_bpy()
    min_x, max_x, min_y, max_y = border_fractions(box, size)
    t0 = time.perf_counter()
    bsc = build_scene(scene, ExportOptions(sss=sss, specular=specular, texture_dir=Path(tempfile.mkdtemp(
        prefix="dermis-cycles-tex-"))), size)
    bsc.cycles.samples, bsc.cycles.seed, bsc.cycles.use_adaptive_sampling = int(spp), int(seed), False
    if threads:
        bsc.render.threads_mode, bsc.render.threads = "FIXED", int(threads)
    r = bsc.render
    r.use_border, r.use_crop_to_border = True, True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = min_x, max_x, min_y, max_y
    t1 = time.perf_counter()
    try:
        img = read_render(bpy, alpha)
    finally:
        r.use_border = r.use_crop_to_border = False
    want = (box[3] - box[1], box[2] - box[0])
    if img.shape[:2] != want:  # Blender rounds the border to pixels: a window off by one is not the window
        raise DermisError(f"Cycles rendered a {img.shape[1]}x{img.shape[0]} window for {want[1]}x{want[0]} "
                          f"({tuple(box)} of {size[0]}x{size[1]})")
    return img, {"spp": int(spp), "seed": int(seed), "sss": sss, "specular": specular, "box": list(map(int, box)),
                 "build_s": round(t1 - t0, 3), "render_s": round(time.perf_counter() - t1, 3)}
