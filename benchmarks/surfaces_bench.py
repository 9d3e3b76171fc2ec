"""Cost of non-skin glTF surfaces (metallic-roughness, issue 17) beside the Lee Perry-Smith head:
two eyeballs (glossy dielectric), a metal sphere and a rough dielectric sphere beside the head, in
every technique; the frame with and without them, and the passes they add ("surfaces", and the
shadow pass that now draws them too). Not part of the test suite: run
    PYTHONPATH=src python benchmarks/surfaces_bench.py [--size 384] [--png out.png]
Results go to benchmarks/RESULTS.md by hand."""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def uv_sphere(center, r, nu=48, nv=24):
    from dermis.scene.builtin import uv_sphere as unit_sphere
    from dermis.scene.loaders import finish_mesh

    p, n, uv, idx = unit_sphere(r, nu, nv)
    return finish_mesh(p + np.asarray(center), n, uv, idx, "sphere", "v-up")


def with_props(scene):
    from dermis.scene.model import MetallicRoughnessMaterial, Surface

    lo, hi = scene.bounds()
    c, size = (lo + hi) / 2, float((hi - lo).max())
    front = hi[2]
    out = copy.copy(scene)
    eye = MetallicRoughnessMaterial(name="eye", base_color=(0.9, 0.9, 0.88, 1), metallic=0.0, roughness=0.15)
    out.surfaces = [
        Surface(uv_sphere(c + [-0.45 * size, -0.1 * size, 0.1 * size], 0.12 * size),
                MetallicRoughnessMaterial(name="metal", base_color=(0.95, 0.8, 0.5, 1), metallic=1.0, roughness=0.3)),
        Surface(uv_sphere(c + [0.45 * size, -0.1 * size, 0.1 * size], 0.12 * size),
                MetallicRoughnessMaterial(name="dielectric", base_color=(0.2, 0.35, 0.6, 1), metallic=0.0, roughness=0.7)),
        # two small spheres in front of the face: they shadow the skin and are shadowed by the nose
        Surface(uv_sphere([c[0] - 0.12 * size, c[1] + 0.05 * size, front + 0.02 * size], 0.035 * size), eye),
        Surface(uv_sphere([c[0] + 0.12 * size, c[1] + 0.05 * size, front + 0.02 * size], 0.035 * size), eye),
    ]
    return out


def main():
    import dermis
    from dermis.images import write_png
    from dermis.output import output_transform
    from dermis.renderer import Renderer

    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--png", default=None)
    ap.add_argument("--irradiance", type=int, default=512)
    args = ap.parse_args()
    base = dermis.load_scene(REPO / "examples" / "lee-perry-smith.toml")
    props = with_props(base)
    print(f"load average {os.getloadavg()[0]:.2f}; size {args.size}^2; props: "
          f"{sum(len(s.mesh.indices) for s in props.surfaces)} triangles beside {len(base.mesh.indices)}")
    rows = []
    for tech in ("lambert", "preintegrated", "ssss", "tsd"):
        res = {}
        for label, sc in (("skin only", base), ("with props", props)):
            with Renderer(sc, (args.size, args.size), irradiance_size=args.irradiance) as r:
                r.render(tech)  # compile, bake, build caches
                frames, surf, shadow = [], [], []
                for _ in range(args.frames):
                    r.invalidate()  # every pass re-runs, as with moving lights
                    t0 = time.perf_counter()
                    img = r.render(tech)
                    frames.append((time.perf_counter() - t0) * 1e3)
                    surf.append(r.stats["passes_ms"].get("surfaces", 0.0))
                    shadow.append(r.stats["passes_ms"].get("shadow", 0.0))
                res[label] = (statistics.median(frames), statistics.median(surf), statistics.median(shadow))
                if args.png and label == "with props":
                    write_png(f"{args.png}-{tech}.png", output_transform(img, sc.output.exposure, sc.output.tonemap))
        (f0, _, s0), (f1, p1, s1) = res["skin only"], res["with props"]
        rows.append(f"| {tech} | {f0:.0f} | {f1:.0f} | {p1:.0f} | {s0:.0f} -> {s1:.0f} |")
        print(rows[-1], flush=True)
    print("| technique | frame, skin only (ms) | frame, with props (ms) | surfaces pass (ms) | shadow pass (ms) |")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
