"""tsd's one bounce with rho E and albedo^mix written by the irradiance pass (this tree) against the
separate rho E raster and the albedo map read in the splat (main up to round 9), in ONE Renderer,
alternated frame by frame (lights changed every frame, so every texture-space pass reruns).

    PYTHONPATH=src python benchmarks/tsd_bounce_ab.py [--size 512] [--irradiance-size 1024] [--frames 7]

"main" is this tree with its own irradiance program swapped out for the one without the bounce
targets (tsd/irradiance.frag without SKIN_EXITANT_LOCATION: main's shader) through
TextureSpaceDiffusion.p_irradiance, which makes tsd take its other path (tsd/bounce_exitant.frag and
the splat reading the albedo map): the same code as main's for that pass. Prints per variant the
medians (min) of tsd_irradiance, tsd_interreflection (wall ms, dermis.techniques.base.PassTimer) and
the frame's process CPU ms (all llvmpipe threads), the load average, and the largest differences of
the per-vertex bounce E_b and of the image between the two.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.shaders import program
from dermis.renderer import Renderer
from dermis.techniques.tsd import irradiance_defines
from dermis.techniques.shared import LIGHT_COUNT_DEFINE, MAX_GAUSSIANS


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--scene", default=str(HEAD_TOML))
    a = ap.parse_args(argv)
    sc = dermis.load_scene(a.scene)
    n = len(sc.lights)
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance_size) as r:
        t = r.technique("tsd")
        defines = {k: v for k, v in irradiance_defines(n).items() if k not in ("SKIN_EXITANT_LOCATION", "SKIN_ALBEDO_MIX_LOCATION")}
        p_main = program(r.ctx, "tsd/uv_space.vert", "tsd/irradiance.frag",
                         {"MAX_GAUSSIANS": MAX_GAUSSIANS, **defines, LIGHT_COUNT_DEFINE: n})
        variants = {"main (separate rho E raster)": p_main, "this tree (rho E from the irradiance pass)": None}
        res = {k: {"irr": [], "bounce": [], "cpu": []} for k in variants}
        last = {}
        print(f"load average before: {os.getloadavg()}")
        for i in range(a.frames + 1):
            for k, p in variants.items():
                t.p_irradiance = p
                sc.lights[0].intensity *= 1.0 + 1e-3 * (1 if i % 2 else -1)  # the lights changed
                c0 = time.process_time()
                img = np.asarray(r.render("tsd"))
                c1 = time.process_time()
                if i == 0:
                    continue  # warm-up: compiles
                ms = r.stats["passes_ms"]
                res[k]["irr"].append(ms["tsd_irradiance"])
                res[k]["bounce"].append(ms["tsd_interreflection"])
                res[k]["cpu"].append((c1 - c0) * 1e3)
                last[k] = (img, t.bounce_per_vertex())
            # the same lights for both images of the last frame
            sc.lights[0].intensity /= 1.0 + 1e-3 * (1 if i % 2 else -1)
        print(f"head {a.size}^2, irradiance {a.irradiance_size}^2, {a.frames} frames each, {r.info['renderer']}")
        print("| variant | tsd_irradiance ms | tsd_interreflection ms | frame CPU ms |\n|---|---|---|---|")
        for k, v in res.items():
            f = lambda x: f"{statistics.median(x):.1f} ({min(x):.1f})"
            print(f"| {k} | {f(v['irr'])} | {f(v['bounce'])} | {f(v['cpu'])} |")
        (img0, eb0), (img1, eb1) = last.values()
        print(f"E_b: max |difference| {np.abs(eb1 - eb0).max():.3g} of max {eb0.max():.3g}; "
              f"image: max |difference| {np.abs(img1 - img0).max():.3g} of max {img0.max():.3g}")
        print(f"load average after: {os.getloadavg()}")
        t.p_irradiance = None
        p_main.release()


if __name__ == "__main__":
    main()
