"""Round 10 (perf10): tsd's texture-space passes of this tree against main's code paths, in ONE
Renderer, alternated frame by frame, lights changed every frame (every texture-space pass reruns).

    PYTHONPATH=src python benchmarks/perf10_ab.py [--size 512] [--irradiance-size 1024] [--frames 7] [--against main]

"main" is this tree with main's paths swapped in, the same code as main's for these passes:
- the bounce: tsd/irradiance.frag without the bounce targets (SKIN_EXITANT_LOCATION) through
  TextureSpaceDiffusion.p_irradiance, which makes tsd draw rho E in a mesh raster of its own
  (tsd/bounce_exitant.frag) and read the albedo map in the splat, as main does;
- the translucency: ``--against``'s tsd/translucency.frag (every texel evaluated every frame, the
  slab law and the surface distance included) and tsd/translucency_tent.frag (nine texel fetches).
Prints per variant and pass the medians (min) of the wall ms (dermis.techniques.base.PassTimer:
glFinish around the pass) and of the process's CPU ms in the same interval (all llvmpipe threads;
under load from other processes it moves far less than wall time), the frame's CPU ms, the load
average, and the largest differences of the image and of the per-vertex bounce between the two.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.shaders import program
from dermis.renderer import Renderer
from dermis.techniques.shared import LIGHT_COUNT_DEFINE, MAX_GAUSSIANS, Unit, bind_sampler
from dermis.techniques.tsd import irradiance_defines

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pass_breakdown import source_at  # noqa: E402

PASSES = ("tsd_irradiance", "tsd_interreflection", "tsd_translucency")


def cpu_timed(timer):
    """Make a PassTimer also record the process's CPU ms per pass in timer.cpu_ms."""
    class CpuPassTimer(type(timer)):
        @contextmanager
        def __call__(self, name):
            with super().__call__(name):
                c0 = time.process_time()
                yield
                self.ctx.finish()
                self.cpu_ms[name] = self.cpu_ms.get(name, 0.0) + (time.process_time() - c0) * 1e3
    timer.__class__ = CpuPassTimer
    timer.cpu_ms = {}
    return timer


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--scene", default=str(HEAD_TOML))
    ap.add_argument("--against", default="main", help="git revision whose tsd/translucency_tent.frag is main's")
    a = ap.parse_args(argv)
    sc = dermis.load_scene(a.scene)
    n = len(sc.lights)
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance_size) as r:
        t = r.technique("tsd")
        defines = {k: v for k, v in irradiance_defines(n).items() if k not in ("SKIN_EXITANT_LOCATION", "SKIN_ALBEDO_MIX_LOCATION")}
        p_main = program(r.ctx, "tsd/uv_space.vert", "tsd/irradiance.frag",
                         {"MAX_GAUSSIANS": MAX_GAUSSIANS, **defines, LIGHT_COUNT_DEFINE: n})
        d = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
        tent_main = r.ctx.program(vertex_shader=source_at(a.against, "common/fullscreen.vert", d),
                                  fragment_shader=source_at(a.against, "tsd/translucency_tent.frag", d))
        trans_main = r.ctx.program(vertex_shader=source_at(a.against, "common/fullscreen.vert", d),
                                   fragment_shader=source_at(a.against, "tsd/translucency.frag", d))
        for p in (tent_main, trans_main):
            t.vaos[p] = r.ctx.vertex_array(p, [])
        tent_mine, trans_mine = t.p_trans_tent, t.p_trans
        static = t._translucency_static

        def static_and_stretch(frame, thickness, size):
            # main's first pass reads the stretch itself (this tree's reads it once, in the static pass)
            out = static(frame, thickness, size)
            bind_sampler(t.p_trans, "uStretch", t.tex["stretch_0"], Unit.FIRST_FREE + MAX_GAUSSIANS)
            return out
        t._translucency_static = static_and_stretch
        variants = {"main": (p_main, trans_main, tent_main), "this tree": (None, trans_mine, tent_mine)}
        timer = cpu_timed(r.timer)
        res = {k: {p: ([], []) for p in PASSES + ("frame",)} for k in variants}
        last = {}
        print(f"load average before: {os.getloadavg()}")
        for i in range(a.frames + 1):
            f = 1.0 + 1e-3 * (1 if i % 2 else -1)
            sc.lights[0].intensity *= f  # the lights changed
            for k, (p_irr, trans, tent) in variants.items():
                t.p_irradiance, t.p_trans, t.p_trans_tent = p_irr, trans, tent
                t._cache_key = None  # the same lights for both variants: rerun the texture-space passes
                timer.cpu_ms = {}
                c0 = time.process_time()
                img = np.asarray(r.render("tsd"))
                c1 = time.process_time()
                if i == 0:
                    continue  # warm-up: compiles, bakes
                for p in PASSES:
                    res[k][p][0].append(r.stats["passes_ms"][p])
                    res[k][p][1].append(timer.cpu_ms[p])
                res[k]["frame"][0].append(sum(r.stats["passes_ms"].values()))
                res[k]["frame"][1].append((c1 - c0) * 1e3)
                last[k] = (img, t.bounce_per_vertex())
        print(f"{Path(a.scene).name} {a.size}^2, irradiance {a.irradiance_size}^2, {a.frames} frames each, "
              f"{r.info['renderer']}; load average after: {os.getloadavg()}")
        print("| pass | main: wall ms | main: CPU ms | this tree: wall ms | this tree: CPU ms |\n|---|---|---|---|---|")
        f = lambda x: f"{statistics.median(x):.1f} ({min(x):.1f})"
        for p in PASSES + ("frame",):
            print(f"| {p} | " + " | ".join(f"{f(res[k][p][0])} | {f(res[k][p][1])}" for k in variants) + " |")
        (img0, eb0), (img1, eb1) = last.values()
        print(f"image: max |difference| {np.abs(img1 - img0).max():.3g} of max {img0.max():.3g}; "
              f"E_b: max |difference| {np.abs(eb1 - eb0).max():.3g} of max {eb0.max():.3g}")
        t.p_irradiance, t.p_trans, t.p_trans_tent = None, trans_mine, tent_mine
        for p in (p_main, trans_main, tent_main):
            p.release()


if __name__ == "__main__":
    main()
