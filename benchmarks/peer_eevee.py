"""Peer benchmark: Blender EEVEE against dermis on the same head, lights, size and machine.

    python benchmarks/peer_eevee.py [SCENE] [--size 512x512] [--frames 5] [--samples 16]

Needs the Cycles extra (``pip install -e ".[cycles]"``: bpy). The scene goes to Blender through
``dermis.blender.export.build_scene`` (the same mesh, maps, camera and lights as ``dermis
export``); EEVEE renders it with its subsurface scattering on and ``--samples`` TAA samples (16,
EEVEE's default for final renders is 64). Each timed frame turns the lights a little, as ``dermis
bench``'s "lights moving" workload does, so neither side can reuse its shadow maps; the first
frame of each side (shader compilation) is not timed. dermis's tsd runs in the same process right
after, at the same output size with its default settings. Prints a Markdown table and the ratio
(EEVEE frame time / tsd frame time): the issue's goal is >= 5.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))


def _turn(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    return (c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2])


def eevee_frames(scene, size, frames, samples):
    """EEVEE frame times (s) with the lights turning: one animation render of frames + 1 frames
    (so EEVEE compiles its shaders once, as an artist's render would), each frame timed between
    Blender's render_pre and render_post handlers; the first frame (compilation) is not counted."""
    from dermis.blender import convert, quiet_fds, require_bpy
    from dermis.blender.export import ExportOptions, build_scene

    bpy = require_bpy()
    bsc = build_scene(scene, ExportOptions(sss=True, specular=True, texture_dir=Path(tempfile.mkdtemp())), size)
    engines = [i.identifier for i in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items]
    bsc.render.engine = "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in engines else "BLENDER_EEVEE"
    bsc.eevee.taa_render_samples = int(samples)
    bsc.render.filepath = str(Path(tempfile.mkdtemp()) / "eevee_")
    lights = sorted((o for o in bsc.objects if o.type == "LIGHT"), key=lambda o: int(o.name.rsplit("_", 1)[1]))
    base = [tuple(L.direction) for L in scene.lights]
    mpu = convert.metres_per_unit(scene)
    for f in range(frames + 1):
        for obj, L, d in zip(lights, scene.lights, base):
            pos = L.position if L.kind != "directional" else (0.0, 0.0, 0.0)
            m = convert.object_matrix(pos, _turn(d, 0.02 * (f + 1)), (0.0, 1.0, 0.0), mpu)
            obj.matrix_world = m.T.tolist()  # as export.build_lights places them
            for path in ("location", "rotation_euler", "scale"):
                obj.keyframe_insert(data_path=path, frame=f + 1)
    bsc.frame_start, bsc.frame_end = 1, frames + 1
    stamps = []
    pre = lambda *_: stamps.append(("pre", time.perf_counter()))  # noqa: E731
    post = lambda *_: stamps.append(("post", time.perf_counter()))  # noqa: E731
    bpy.app.handlers.render_pre.append(pre)
    bpy.app.handlers.render_post.append(post)
    try:
        with quiet_fds():
            bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.render_pre.remove(pre)
        bpy.app.handlers.render_post.remove(post)
    starts = [t for k, t in stamps if k == "pre"]
    ends = [t for k, t in stamps if k == "post"]
    times = [b - a for a, b in zip(starts, ends)]
    return times[1:], bsc.render.engine


def dermis_frames(scene, size, frames):
    from dermis.bench import run_bench

    _, res = run_bench(scene, ["tsd"], size, frames=frames, floors=False)
    return res["tsd"]["lights"]["frame_ms"] / 1e3


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(REPO / "examples" / "lee-perry-smith.toml"))
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--samples", type=int, default=16)
    args = ap.parse_args(argv)
    import dermis
    from dermis.cli import parse_size

    size = parse_size(args.size)
    ee, engine = eevee_frames(dermis.load_scene(args.scene), size, args.frames, args.samples)
    ts = dermis_frames(dermis.load_scene(args.scene), size, args.frames)
    e = statistics.median(ee)
    print(f"| renderer | frame, lights moving (s) |\n|---|---|\n| {engine} ({args.samples} TAA samples, SSS) | {e:.3f} |\n"
          f"| dermis tsd | {ts:.3f} |\n\nEEVEE / tsd = {e / ts:.2f}x (size {size[0]}x{size[1]}, median of {args.frames})")


if __name__ == "__main__":
    main()
