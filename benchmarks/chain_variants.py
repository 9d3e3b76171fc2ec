"""Blur-chain variants (module constants of dermis.techniques.tsd, VARIANTS as JSON) against the 12-copy
floor in one process, one renderer per variant, interleaved, REPS rounds, medians; with ACC=1 the
impulse error (r-weighted L2, %) at 0.1 mm and at the head's 0.49 mm texels.

    VARIANTS='[{"NARROW_PASS": false}, {}]' PYTHONPATH=src python benchmarks/chain_variants.py
"""
import os, sys, statistics, time, json
import numpy as np
import dermis
import dermis.techniques.tsd as T
from dermis.bench import HEAD_TOML
from dermis.renderer import Renderer
from dermis.gl.shaders import program
from dermis.verification import impulse_error, impulse_response
VARIANTS = json.loads(os.environ.get("VARIANTS", '[{}]'))
S = int(os.environ.get("IRR", 1024))
def apply(v):
    for k, val in v.items(): setattr(T, k, val)
base = {k: getattr(T, k) for k in ("TAP_REACH_SIGMAS", "LEVEL_MIN_SIGMA_TEXELS", "LEVEL_MIN_INPUT_SIGMA_TEXELS", "NARROW_PASS", "LEVEL_LIGHT_WEIGHT", "LEVEL_MIN_SIGMA_TEXELS_LIGHT", "LEVEL_MIN_INPUT_SIGMA_TEXELS_LIGHT", "TAP_STRETCH_PERCENTILE")}
rs, fns = [], []
ctx = None
for v in VARIANTS:
    apply(base); apply(v)
    sc = dermis.load_scene(HEAD_TOML)
    r = Renderer(sc, (64, 64), irradiance_size=S, ctx=ctx); ctx = r.ctx; rs.append(r)
    r.render("tsd"); t = r.technique("tsd")
    levels = t._plan_levels(sc.profile, S); steps = t._step_variances(sc.profile, levels)
    dil = t.tex["irradiance_dilated"]
    def mk(t=t, dil=dil, levels=levels, steps=steps, v=v):
        def chain():
            apply(base); apply(v); t._blur_chain(dil, levels, steps)
        return chain
    f = mk(); f(); ctx.finish()
    fns.append((v, levels, f, []))
dil = rs[0].technique("tsd").tex["irradiance_dilated"]
p = program(ctx, "common/fullscreen.vert", "bench/copy.frag"); vao = ctx.vertex_array(p, [])
dst = ctx.texture((S, S), 4, dtype="f2"); fbo = ctx.framebuffer(color_attachments=[dst])
def copy():
    fbo.use(); fbo.viewport = (0, 0, S, S); dil.use(0); p["uSource"].value = 0; vao.render(vertices=3)
copy(); ctx.finish()
tc = []
load0 = os.getloadavg()[0]
for i in range(int(os.environ.get("REPS", 5))):
    for v, levels, f, acc in fns:
        for g, a in ((copy, tc), (f, acc)):
            ctx.finish(); t0 = time.perf_counter(); g(); ctx.finish(); a.append(time.perf_counter() - t0)
c = statistics.median(tc)
load1 = os.getloadavg()[0]
for v, levels, f, acc in fns:
    b = statistics.median(acc)
    apply(base); apply(v)
    acc_on = os.environ.get("ACC", "1") == "1"
    err = impulse_error(ctx) * 100 if acc_on else None
    err2 = impulse_error(ctx, texel_mm=0.49) * 100 if acc_on else None
    print(json.dumps({"v": v, "levels": levels, "load": [round(load0, 2), round(load1, 2)], "copy_ms": round(c * 1e3, 2),
                      "chain_ms": round(b * 1e3, 1), "ratio": round(b / (12 * c), 2),
                      "impulse_pct": None if err is None else [round(x, 3) for x in err],
                      "head_texel_impulse_pct": None if err2 is None else [round(x, 3) for x in err2]}), flush=True)
