"""tsd's blur chain against its floor (12 copy passes of the irradiance texture), interleaved in one
process on the head: REPS rounds of copy, chain, copy; medians. IRR=1024 (default), TAG=label.
Runs with whichever dermis is on PYTHONPATH (before/after: alternate two checkouts).

    PYTHONPATH=src python benchmarks/blur_chain_floor.py
"""
import os, statistics, time, json
import numpy as np, moderngl
import dermis
from dermis.bench import HEAD_TOML
from dermis.renderer import Renderer
from dermis.gl.shaders import program
S = int(os.environ.get("IRR", 1024))
sc = dermis.load_scene(HEAD_TOML)
with Renderer(sc, (64, 64), irradiance_size=S) as r:
    r.render("tsd")
    t = r.technique("tsd")
    ctx = r.ctx
    levels = t._plan_levels(sc.profile, S)
    steps = t._step_variances(sc.profile, levels)
    dil = t.tex["irradiance_dilated"]
    p = program(ctx, "common/fullscreen.vert", "bench/copy.frag")
    vao = ctx.vertex_array(p, [])
    dst = ctx.texture((S, S), 4, dtype="f2")
    fbo = ctx.framebuffer(color_attachments=[dst])
    def copy():
        fbo.use(); fbo.viewport = (0, 0, S, S); dil.use(0); p["uSource"].value = 0; vao.render(vertices=3)
    def chain():
        t._blur_chain(dil, levels, steps)
    for f in (copy, chain):
        f(); ctx.finish()
    tc, tb = [], []
    load0 = os.getloadavg()[0]
    for i in range(int(os.environ.get("REPS", 5))):
        for f, acc in ((copy, tc), (chain, tb), (copy, tc)):
            ctx.finish(); t0 = time.perf_counter(); f(); ctx.finish(); acc.append(time.perf_counter() - t0)
    c, b = statistics.median(tc), statistics.median(tb)
    print(json.dumps({"tag": os.environ.get("TAG"), "S": S, "levels": levels, "load": [round(load0, 2), round(os.getloadavg()[0], 2)],
                      "copy_ms": round(c * 1e3, 2), "chain_ms": round(b * 1e3, 1), "chain_over_12_copies": round(b / (12 * c), 2)}))
