"""Render the exported scene with Cycles (CPU) through bpy; linear radiance as numpy."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np


def read_render(bpy, alpha=False) -> np.ndarray:
    """Render the current Blender scene; (H, W, 3) float32 linear radiance, row 0 at the top
    (with ``alpha``, (H, W, 4): a transparent film, alpha = the mesh's pixel coverage).
    Written as a float EXR (scene-referred: no view transform) and read back."""
    sc = bpy.context.scene
    sc.render.film_transparent = bool(alpha)
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_mode = "RGBA" if alpha else "RGB"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.exr_codec = "ZIP"
    sc.render.use_compositing = False
    sc.render.use_sequencer = False
    with tempfile.TemporaryDirectory(prefix="dermis-cycles-") as d:
        out = Path(d) / "render.exr"
        sc.render.filepath = str(out)
        from dermis.blender import quiet_fds

        with quiet_fds():  # Cycles prints a status line per tile
            bpy.ops.render.render(write_still=True)
        img = _read_exr_rgba(out)
    return np.ascontiguousarray(img[:, :, :4] if alpha else img[:, :, :3], np.float32)


def _read_exr_rgba(path) -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.channels()
        return np.stack([np.asarray(ch[c].pixels, np.float32) for c in "RGBA" if c in ch], -1)


def render_cycles(scene, size, *, spp=64, seed=0, sss=True, specular=True, threads=0, time_limit_s=0.0, alpha=False,
                  max_bounces=None):
    """(image (H, W, 3) float32 linear radiance, stats) of ``scene`` in Cycles on the CPU; with
    ``alpha`` the image is (H, W, 4), alpha = coverage (the film is transparent). ``max_bounces``
    = 0: direct light only (dermis has no interreflection; the calibration isolates conventions)."""
    from dermis.blender import require_bpy
    from dermis.blender.export import ExportOptions, build_scene

    bpy = require_bpy()
    t0 = time.perf_counter()
    tex_dir = tempfile.mkdtemp(prefix="dermis-cycles-tex-")
    bsc = build_scene(scene, ExportOptions(sss=sss, specular=specular, texture_dir=Path(tex_dir)), size)
    bsc.cycles.samples = int(spp)
    bsc.cycles.seed = int(seed)
    # every pixel gets exactly spp samples: adaptive sampling (Blender's default, noise threshold
    # 0.01) stops pixels at a fixed noise level, which caps what more samples or seeds can converge
    bsc.cycles.use_adaptive_sampling = False
    if max_bounces is not None:
        bsc.cycles.max_bounces = int(max_bounces)
    if time_limit_s:
        bsc.cycles.time_limit = float(time_limit_s)
    if threads:
        bsc.render.threads_mode, bsc.render.threads = "FIXED", int(threads)
    t1 = time.perf_counter()
    img = read_render(bpy, alpha)
    t2 = time.perf_counter()
    return img, {"spp": int(spp), "seed": int(seed), "sss": sss, "specular": specular,
                 "build_s": round(t1 - t0, 3), "render_s": round(t2 - t1, 3)}
