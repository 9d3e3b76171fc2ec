"""Per-frame CPU overhead of Renderer.render (issue 14): the Python that runs around the GL work.

On Mesa llvmpipe every GL call that rasterises, clears, copies or reads back runs (or waits for)
the CPU rasteriser; what is left of a frame's wall time once the time spent inside those calls is
taken out is dermis's own per-frame Python (keys, validation, matrices, uniform uploads, ...),
which on a GPU is what a frame costs at the least (the GPU side being far shorter).

Per frame it reports:
- ``python_ms``: wall time minus the time inside moderngl's drawing, clearing, copying, reading,
  writing and finishing calls (each wrapped here; uniform writes and texture binds stay in
  python_ms, as their CPU cost is dermis's to avoid);
- ``python_cpu_ms``: the calling thread's CPU time (time.thread_time) less its CPU time inside
  those calls: the same Python, but not inflated when a loaded machine preempts the thread;
- ``gl_ms``: the time inside those calls; ``wall_ms`` both together.
Frames are rendered with the pass timer off (``timing=False``: no per-pass finish), at a small
size (default 64x64, irradiance 128, shadow tiles 256) so the GL work is small too.

Usage (from the repository root):
    python benchmarks/frame_overhead.py                      # this checkout, tsd, both workloads
    python benchmarks/frame_overhead.py --baseline ../main/src --rounds 3
        # A/B: the baseline's src and this checkout's alternate in subprocesses, same load
    python benchmarks/frame_overhead.py --images /tmp/a.npz  # renders of a few scenes, for
        # an equality check of two versions (--compare-images a.npz b.npz)
    python benchmarks/frame_overhead.py --profile --workload lights   # cProfile, top functions
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAD = ROOT / "examples" / "lee-perry-smith.toml"

# moderngl calls that make llvmpipe rasterise, clear, copy, transfer or wait (binding another
# framebuffer makes llvmpipe rasterise what was queued for the last one: Framebuffer.use)
_GL_CALLS = {"VertexArray": ("render",), "Framebuffer": ("clear", "read", "read_into", "use"),
             "Context": ("clear", "finish", "copy_framebuffer"),
             "Texture": ("read", "read_into", "write", "build_mipmaps"), "Texture3D": ("read", "write", "build_mipmaps"),
             "Buffer": ("read", "write"), "ComputeShader": ("run",)}


class GLClock:
    """Accumulates the wall time spent inside the moderngl calls of _GL_CALLS."""

    def __init__(self):
        import moderngl

        self.total = 0.0
        self.cpu = 0.0  # this thread's CPU time inside the calls
        self._orig = []
        for cls_name, methods in _GL_CALLS.items():
            cls = getattr(moderngl, cls_name)
            for m in methods:
                f = getattr(cls, m)
                self._orig.append((cls, m, f))
                setattr(cls, m, self._wrap(f))

    def _wrap(self, f):
        clock = self

        def timed(*a, **k):
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return f(*a, **k)
            finally:
                clock.total += time.perf_counter() - t0
                clock.cpu += time.thread_time() - c0
        return timed

    def restore(self):
        for cls, m, f in self._orig:
            setattr(cls, m, f)


def _rotate(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = v
    return (c * x + s * z, y, -s * x + c * z)


def workload_frames(scene, renderer, technique, workload):
    """A callable drawing frame f of ``workload`` ("lights": the lights turn; "camera": the camera orbits)."""
    import numpy as np

    base_light = [tuple(L.direction) for L in scene.lights]
    base_cam = tuple(scene.camera.position)
    target = np.asarray(scene.camera.target, float)

    def frame(f):
        if workload == "lights":
            for L, d in zip(scene.lights, base_light):
                L.direction = _rotate(d, 0.02 * (f % 50 + 1))
        else:
            off = np.asarray(base_cam, float) - target
            scene.camera.position = tuple(target + np.asarray(_rotate(off, 0.03 * (f % 50 + 1))))
        return renderer.render(technique)
    return frame


def measure(techniques=("tsd",), workloads=("camera", "lights"), frames=30, size=64, irradiance=128, shadow=256,
            scene_path=HEAD, profiler=None) -> dict:
    import dermis
    from dermis.renderer import Renderer

    out = {"load": os.getloadavg()[0], "src": str(Path(dermis.__file__).parents[1])}
    clock = GLClock()
    try:
        for tech in techniques:
            sc = dermis.load_scene(scene_path)
            with Renderer(sc, (size, size), irradiance_size=irradiance, shadow_size=shadow, timing=False) as r:
                for workload in workloads:
                    frame = workload_frames(sc, r, tech, workload)
                    for f in range(3):  # warm-up: compile, first-frame products
                        frame(f)
                    walls, gls, cpus, gl_cpus = [], [], [], []
                    if profiler:
                        profiler.enable()
                    for f in range(frames):
                        g0, gc0, c0, t0 = clock.total, clock.cpu, time.thread_time(), time.perf_counter()
                        frame(f + 3)
                        walls.append((time.perf_counter() - t0) * 1e3)
                        gls.append((clock.total - g0) * 1e3)
                        cpus.append((time.thread_time() - c0) * 1e3)
                        gl_cpus.append((clock.cpu - gc0) * 1e3)
                    if profiler:
                        profiler.disable()
                    py = [w - g for w, g in zip(walls, gls)]
                    py_cpu = [c - g for c, g in zip(cpus, gl_cpus)]
                    out[f"{tech}/{workload}"] = {"python_ms": statistics.median(py), "python_ms_min": min(py),
                                                 "python_cpu_ms": statistics.median(py_cpu),
                                                 "gl_ms": statistics.median(gls),
                                                 "wall_ms": statistics.median(walls),
                                                 "main_thread_cpu_ms": statistics.median(cpus)}
    finally:
        clock.restore()
    out["load_after"] = os.getloadavg()[0]
    return out


def images(path, size=96):
    """Renders of a few scenes and workloads (tsd, lambert, ssss, preintegrated; lights moved,
    camera moved, a map edited), saved to ``path`` (npz) for a bit-for-bit comparison of two versions."""
    import numpy as np

    import dermis
    from dermis.renderer import Renderer

    out = {}
    scenes = {"head": lambda: dermis.load_scene(HEAD), "default": dermis.default_scene,
              "environment": lambda: dermis.load_scene(ROOT / "examples" / "reference" / "environment.toml")}
    for name, load in scenes.items():
        sc = load()
        with Renderer(sc, (size, size), irradiance_size=128, shadow_size=256) as r:
            for tech in ("tsd", "lambert", "ssss", "preintegrated"):
                tag = f"{name}/{tech}"
                out[tag + "/first"] = r.render(tech)
                lights = workload_frames(sc, r, tech, "lights")
                out[tag + "/lights"] = [lights(f) for f in range(2)][-1]
                cam = workload_frames(sc, r, tech, "camera")
                out[tag + "/camera"] = [cam(f) for f in range(2)][-1]
                out[tag + "/camera_only_after_lights"] = r.render(tech)
            mat = sc.material
            if mat.albedo is not None:
                mat.albedo = type(mat.albedo)(np.asarray(mat.albedo.data) * 0.5, "edited")
                out[f"{name}/tsd/albedo_edited"] = r.render("tsd")
            if sc.lights:
                sc.lights[0].intensity *= 0.5
            else:
                sc.environment.intensity *= 0.5
            out[f"{name}/tsd/intensity_edited"] = r.render("tsd")
    np.savez_compressed(path, **{k.replace("/", "__"): v for k, v in out.items()})
    return sorted(out)


def compare_images(a, b) -> int:
    import numpy as np

    A, B = np.load(a), np.load(b)
    bad = 0
    for k in sorted(set(A) | set(B)):
        if k not in A or k not in B:
            print(f"{k}: only in {'the first' if k in A else 'the second'}")
            bad += 1
            continue
        same = np.array_equal(A[k], B[k])
        bad += not same
        print(f"{k}: {'identical' if same else f'DIFFERS, max |d| = {np.abs(A[k] - B[k]).max():.3g}'}")
    return bad


def _run_child(src, args) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src))
    cmd = [sys.executable, __file__, "--json-out", "-", *args]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--techniques", default="tsd")
    ap.add_argument("--workload", default="camera,lights")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--irradiance", type=int, default=128)
    ap.add_argument("--baseline", default=None, help="another checkout's src: A/B in alternating subprocesses")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json-out", default=None)
    ap.add_argument("--images", default=None)
    ap.add_argument("--compare-images", nargs=2, default=None)
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args()
    if a.compare_images:
        sys.exit(1 if compare_images(*a.compare_images) else 0)
    if a.images:
        print("\n".join(images(a.images)))
        return
    techs, loads = a.techniques.split(","), a.workload.split(",")
    args = ["--techniques", a.techniques, "--workload", a.workload, "--frames", str(a.frames), "--size", str(a.size),
            "--irradiance", str(a.irradiance)]
    if a.profile:
        import cProfile
        import pstats

        pr = cProfile.Profile()
        measure(techs, loads, a.frames, a.size, a.irradiance, profiler=pr)
        pstats.Stats(pr).sort_stats(os.environ.get("SORT", "tottime")).print_stats(int(os.environ.get("TOP", "40")))
        return
    if a.baseline:
        rows = {"baseline": [], "this": []}
        for _ in range(a.rounds):
            rows["baseline"].append(_run_child(a.baseline, args))
            rows["this"].append(_run_child(ROOT / "src", args))
        print(f"A/B, {a.rounds} rounds alternating, {a.size}x{a.size}, irradiance {a.irradiance}, medians over rounds "
              f"of per-frame medians; load average {min(r['load'] for v in rows.values() for r in v):.1f}-"
              f"{max(r['load_after'] for v in rows.values() for r in v):.1f}")
        print("| version | workload | python CPU ms/frame | python wall ms/frame (median) | python wall ms/frame "
              "(fastest frame) | GL ms/frame | wall ms/frame | main-thread CPU ms/frame |")
        print("|---|---|---|---|---|---|---|---|")
        for name, rs in rows.items():
            for k in [k for k in rs[0] if "/" in k]:
                med = {m: statistics.median(r[k][m] for r in rs) for m in rs[0][k]}
                print(f"| {name} | {k} | {med['python_cpu_ms']:.2f} | {med['python_ms']:.2f} | {med['python_ms_min']:.2f} | "
                      f"{med['gl_ms']:.1f} | "
                      f"{med['wall_ms']:.1f} | "
                      f"{med['main_thread_cpu_ms']:.1f} |")
        return
    res = measure(techs, loads, a.frames, a.size, a.irradiance)
    if a.json_out == "-":
        print(json.dumps(res))
    else:
        print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
