"""Cost of tsd's one diffuse bounce (dermis.geometry.interreflection) on the head.

    PYTHONPATH=src python benchmarks/interreflection_cost.py [--scene examples/reference/side.toml]
        [--irradiance 1024] [--frames 6] [--rays N]

Prints: the bake's time uncached (Embree, CPU) and read back from the disk cache; then, in ONE
Renderer, per frame whose lights changed (so every texture-space pass reruns), the times of
tsd_irradiance (the lights' irradiance pass and the gutter dilation) and tsd_interreflection (rho E,
its reductions, the per-vertex gather and the splat), as medians over the frames, and the load
average. On Mesa's llvmpipe the pass timer is wall time around glFinish (dermis.techniques.base.PassTimer).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default=str(REPO / "examples" / "reference" / "side.toml"))
    ap.add_argument("--irradiance", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--rays", type=int, default=None)
    a = ap.parse_args()
    import dermis
    from dermis.geometry import interreflection
    from dermis.renderer import Renderer

    if a.rays:
        interreflection.BAKE_RAYS = a.rays
    print(f"load average before: {os.getloadavg()}")
    sc = dermis.load_scene(a.scene)
    m = sc.mesh
    with tempfile.TemporaryDirectory() as cache:
        os.environ["DERMIS_CACHE_DIR"] = cache
        h = interreflection.bake_vertex_hits(m.positions, m.normals, m.indices)
        interreflection._MEMORY.clear()
        t0 = time.perf_counter()
        cached = interreflection.bake_vertex_hits(m.positions, m.normals, m.indices)
        t_disk = time.perf_counter() - t0
        print(f"bake: {len(m.positions)} vertices x {h.rays} rays: {h.seconds:.2f} s uncached; "
              f"{t_disk * 1e3:.1f} ms from the disk cache (cached={cached.cached}); "
              f"{(h.triangle >= 0).mean():.3f} of the rays hit the skin")
        with Renderer(sc, (256, 256), irradiance_size=a.irradiance) as r:
            r.render("tsd")
            irr, bounce = [], []
            for i in range(a.frames):
                sc.lights[0].intensity *= 1.0 + 1e-3 * (1 if i % 2 else -1)  # lights changed: texture space reruns
                r.timer.reset()
                r.render("tsd")
                ms = r.stats["passes_ms"]
                irr.append(ms["tsd_irradiance"])
                bounce.append(ms["tsd_interreflection"])
            tsd = r.technique("tsd")
            mi, mb = statistics.median(irr), statistics.median(bounce)
            print(f"irradiance {a.irradiance}^2, gather level {tsd.bounce_level}, {r.info['renderer']}: "
                  f"tsd_irradiance {mi:.1f} ms, tsd_interreflection {mb:.1f} ms (ratio {mb / mi:.2f}), "
                  f"medians of {a.frames} frames")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
