"""Round 8 (shadow8): tsd's irradiance pass and the lambert pass as `dermis bench` times them
(lights moving), this tree's shaders against other revisions' in the SAME Renderer, frames
interleaved, the load average beside them (the machine is shared: only ratios within one run count).
Besides the pass's wall ms (`dermis bench`'s), the process's CPU seconds per frame (all of
llvmpipe's threads; the frame's other passes are the same program in every column, so the
differences between columns are the pass's): under a load of other processes the wall time
stretches with the share of the cores this process gets, its CPU time much less.

    PYTHONPATH=src python benchmarks/shadow8_ab.py [--against cb4d4f1 ef5729b] [--frames 5]
"""
from __future__ import annotations

import argparse
import os
import time
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import dermis  # noqa: E402
from dermis.bench import HEAD_TOML, _rotate  # noqa: E402
from dermis.gl.shaders import load_shader_source  # noqa: E402
from dermis.renderer import Renderer  # noqa: E402
from dermis.techniques.shared import MAX_GAUSSIANS  # noqa: E402
from dermis.techniques.tsd import STORED_SHARP_SHADOWS  # noqa: E402
from pass_breakdown import source_at  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--against", nargs="+", default=["cb4d4f1", "ef5729b"])
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    a = ap.parse_args(argv)
    sc = dermis.load_scene(str(HEAD_TOML))
    d = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
    res = {}
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance_size) as r:
        r.render("tsd")
        r.render("lambert")
        tsd, lam = r.technique("tsd"), r.technique("lambert")
        progs = {"this tree": (tsd._irradiance_programs(len(sc.lights)), lam.programs(len(sc.lights), sc.lights))}
        for rev in a.against:
            dd = {**d, "SKIN_SHARP_SHADOWS": STORED_SHARP_SHADOWS} if len(sc.lights) <= STORED_SHARP_SHADOWS else d
            progs[f"@{rev}"] = (
                r.ctx.program(vertex_shader=load_shader_source("tsd/uv_space.vert", d),
                              fragment_shader=source_at(rev, "tsd/irradiance.frag", dd)),
                r.ctx.program(vertex_shader=load_shader_source("common/mesh.vert", {}),
                              fragment_shader=source_at(rev, "lambert/lambert.frag", {})))
        mine = progs["this tree"]
        base = [tuple(L.direction) for L in sc.lights]
        res = {k: {"tsd_irradiance": [], "lambert": [], "tsd frame cpu": [], "lambert frame cpu": []} for k in progs}
        f = 0
        try:
            for _ in range(a.frames):
                for name, (pi, pl) in progs.items():
                    tsd.p_irradiance, lam.prog = pi, pl
                    for tech, key in (("tsd", "tsd_irradiance"), ("lambert", "lambert")):
                        f += 1
                        for L, dd in zip(sc.lights, base):
                            L.direction = _rotate(dd, 0.02 * f)
                        r.ctx.finish()
                        c0 = time.process_time()
                        r.render(tech)
                        r.ctx.finish()
                        res[name][f"{tech} frame cpu"].append(1e3 * (time.process_time() - c0))
                        res[name][key].append(r.stats["passes_ms"][key])
        finally:
            tsd.p_irradiance, lam.prog = None, None  # back to their programs per light count
    print(f"load {os.getloadavg()}")
    for k, v in res.items():
        print(f"{k}: " + "; ".join(f"{p} median {statistics.median(x):.0f} ms ({', '.join(f'{y:.0f}' for y in x)})"
                                   for p, x in v.items()))


if __name__ == "__main__":
    main()
