"""Round 9 (unroll9): the light loops of lambert, ssss's irradiance pass and preintegrated,
unrolled per light count (SKIN_LIGHT_COUNT, dermis.techniques.shared.LightCountPrograms) against
a revision's shaders (main: the loop over uLightCount) in the SAME Renderer, frames alternated,
the load average beside them (the machine is shared: only ratios within one run count).
Per frame: the pass's ms (`dermis bench`'s passes_ms) and the process's CPU ms for the whole
frame (llvmpipe's threads; the frame's other passes are the same program in both columns).
The lights stand still: a moving light re-bakes the shared bounce, which would swamp the pass.

    PYTHONPATH=src python benchmarks/unroll9_ab.py [--against main] [--frames 5] [--size 512]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import dermis  # noqa: E402
from dermis.bench import HEAD_TOML  # noqa: E402
from dermis.gl.shaders import load_shader_source  # noqa: E402
from dermis.renderer import Renderer  # noqa: E402
from dermis.techniques.shared import LIGHT_COUNT_DEFINE, interreflection_on  # noqa: E402
from pass_breakdown import source_at  # noqa: E402

PASSES = {"lambert": "lambert", "ssss": "ssss_irradiance", "preintegrated": "preintegrated"}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--against", default="main")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--techniques", nargs="+", default=list(PASSES))
    a = ap.parse_args(argv)
    sc = dermis.load_scene(str(HEAD_TOML))
    n = len(sc.lights)
    print(f"head, {n} lights, {a.size}^2, interreflection {interreflection_on(sc)}")
    with Renderer(sc, (a.size, a.size)) as r:
        for tech in a.techniques:
            r.render(tech)
            t = r.technique(tech)
            mine = t.light_programs(sc, interreflection_on(sc))(n, sc.lights)
            vertex, fragment, defines, _ = mine.extra["sources"]
            old_defines = {k: v for k, v in defines.items() if k not in (LIGHT_COUNT_DEFINE, "SKIN_LIGHT_KINDS", "SKIN_SHADOW_FILTERS")}
            theirs = r.ctx.program(vertex_shader=load_shader_source(vertex, old_defines),
                                   fragment_shader=source_at(a.against, fragment, old_defines))
            progs = {"unrolled (this tree)": None, f"loop (@{a.against})": theirs}
            res = {k: {"pass": [], "cpu": []} for k in progs}
            loads = []
            try:
                for name, p in progs.items():  # warm-up: compile, first draw
                    t.override_light_program(p)
                    r.render(tech)
                for _ in range(a.frames):
                    for name, p in progs.items():
                        t.override_light_program(p)
                        r.ctx.finish()
                        c0 = time.process_time()
                        r.render(tech)
                        r.ctx.finish()
                        res[name]["cpu"].append(1e3 * (time.process_time() - c0))
                        res[name]["pass"].append(r.stats["passes_ms"][PASSES[tech]])
                    loads.append(os.getloadavg()[0])
                imgs = []
                for p in progs.values():  # the image of each, the same frame
                    t.override_light_program(p)
                    imgs.append(r.render(tech).astype(np.float64))
                diff = np.abs(imgs[0] - imgs[1]).max() / max(np.abs(imgs[1]).max(), 1e-30)
            finally:
                t.override_light_program(None)
                theirs.release()
            print(f"{tech} ({PASSES[tech]}), load {min(loads):.2f}-{max(loads):.2f}; image max |unrolled - loop| / max {diff:.2e}:")
            med = {k: (statistics.median(v["pass"]), statistics.median(v["cpu"])) for k, v in res.items()}
            for k, v in res.items():
                print(f"  {k}: pass median {med[k][0]:.0f} min {min(v['pass']):.0f} ms ({', '.join(f'{y:.0f}' for y in v['pass'])}); "
                      f"frame cpu median {med[k][1]:.0f} min {min(v['cpu']):.0f} ms ({', '.join(f'{y:.0f}' for y in v['cpu'])})")
            (pu, cu), (pl, cl) = med.values()
            (u, lo) = res.values()
            print(f"  unrolled / loop: pass {pu / pl:.3f} (min {min(u['pass']) / min(lo['pass']):.3f}), frame cpu {cu / cl:.3f} "
                  f"(min {min(u['cpu']) / min(lo['cpu']):.3f}); frame cpu saved (median) {cl - cu:.0f} ms")


if __name__ == "__main__":
    main()
