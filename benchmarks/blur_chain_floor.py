"""tsd's blur chain against its floor (12 copy passes of the irradiance texture), interleaved in one
process on the head: REPS rounds of copy, texelFetch copy, chain, texelFetch copy, copy; medians of
the chain, minima of the copies. The copy is dermis bench's floor (bench/copy.frag: a read through a
NEAREST sampler at texel centres, as the chain reads since round 23); the texelFetch copy is the floor
dermis bench used before round 23 (on llvmpipe ~10 % dearer: cpu_chain_over_12_texelfetch_copies, for
comparison with earlier rounds' multiples). IRR=1024 (default), TAG=label.
Runs with whichever dermis is on PYTHONPATH (before/after: alternate two checkouts).

Both clocks: wall (perf_counter) and the CPU clock dermis bench uses (dermis.gl.context.cpu_busy_ns:
the rasteriser threads' run time / their number + the calling thread's, which does not grow while
another process holds a core). PASSES=1 also times each pass of the chain alone (CPU clock, median),
labelled as tsd.py draws them. VARIANT=name compiles tsd/blur.frag with one part removed (a text
substitution, for measurement only: its images are wrong), to see what that part costs:
  noskew     the U pass's account of the V pass's rounded skewed reads (the per-tap loop over the
             V pass's weights, uSigmaOtherMm) never runs
  noweights  the sampled steps' weight arithmetic (recurrence, W, M, the variance correction) gone:
             a plain sum of the same fetches (the stretch fetch and sigma stay)
(round 17, perf17: neither moved the chain beyond its noise; benchmarks/RESULTS.md).

    PYTHONPATH=src python benchmarks/blur_chain_floor.py
    PASSES=1 VARIANT=noskew PYTHONPATH=src python benchmarks/blur_chain_floor.py
"""
import os, statistics, time, json
import numpy as np, moderngl
import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.context import cpu_busy_ns
from dermis.renderer import Renderer
from dermis.gl.shaders import load_shader_source, program
from dermis.techniques import tsd as tsd_module


def _variant_source(name: str, src: str) -> str:
    if name == "noskew":
        out = src.replace("if (sv >= 0.02) {", "if (sv >= 1e30) {")
    elif name == "noweights":
        loop = src[src.index("    float var = sigma * sigma;"):src.index("#endif\n}")]
        out = src.replace(loop, "    vec4 sum = center;\n    for (int j = 1; j <= TAPS; ++j) sum += tap(ip, dir, skew, j) + tap(ip, dir, skew, -j);\n"
                                "    f_color = sum / float(2 * TAPS + 1);\n")
    else:
        raise SystemExit(f"blur_chain_floor.py: unknown VARIANT {name!r} (noskew, noweights)")
    if out == src:
        raise SystemExit(f"blur_chain_floor.py: VARIANT {name} no longer applies (tsd/blur.frag changed)")
    return out


VARIANT = os.environ.get("VARIANT")
if VARIANT:
    def _program(ctx, vertex, fragment=None, defines=None, geometry=None):
        if fragment != "tsd/blur.frag":
            return program(ctx, vertex, fragment, defines, geometry)
        return ctx.program(vertex_shader=load_shader_source(vertex, defines),
                           fragment_shader=_variant_source(VARIANT, load_shader_source(fragment, defines)))
    tsd_module.program = _program

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
    nearest = ctx.sampler(filter=(moderngl.NEAREST, moderngl.NEAREST), repeat_x=False, repeat_y=False)
    def copy():  # dermis bench's floor (dermis.bench_floors: the texture's filtering NEAREST, clamped)
        fbo.use(); fbo.viewport = (0, 0, S, S); dil.use(0); nearest.use(0); p["uSource"].value = 0
        vao.render(vertices=3); nearest.clear(0)
    # the floor before round 23: the same copy through texelFetch (bounds-checked on llvmpipe)
    pf = ctx.program(vertex_shader=load_shader_source("common/fullscreen.vert", {}), fragment_shader=(
        "#version 450 core\nuniform sampler2D uSource;\nout vec4 f_color;\n"
        "void main() { f_color = texelFetch(uSource, ivec2(gl_FragCoord.xy), 0); }"))
    vao_f = ctx.vertex_array(pf, [])
    def fetch_copy():
        fbo.use(); fbo.viewport = (0, 0, S, S); dil.use(0); pf["uSource"].value = 0; vao_f.render(vertices=3)
    def chain():
        t._blur_chain(dil, levels, steps)
    for f in (copy, chain):
        f(); ctx.finish()
    tc, tb, cc, cb, ts, cs = [], [], [], [], [], []
    load0 = os.getloadavg()[0]
    for i in range(int(os.environ.get("REPS", 5))):
        for f, acc, cpu in ((copy, tc, cc), (fetch_copy, ts, cs), (chain, tb, cb), (fetch_copy, ts, cs), (copy, tc, cc)):
            ctx.finish(); c0 = cpu_busy_ns(); t0 = time.perf_counter(); f(); ctx.finish()
            acc.append(time.perf_counter() - t0); cpu.append(cpu_busy_ns() - c0)
    c, b = statistics.median(tc), statistics.median(tb)
    out = {"tag": os.environ.get("TAG"), "variant": VARIANT, "S": S, "levels": levels, "load": [round(load0, 2), round(os.getloadavg()[0], 2)],
           "copy_ms": round(c * 1e3, 2), "chain_ms": round(b * 1e3, 1), "chain_over_12_copies": round(b / (12 * c), 2),
           "cpu_copy_min_ms": round(min(cc) / 1e6, 2), "cpu_chain_ms": round(statistics.median(cb) / 1e6, 1),
           "cpu_chain_over_12_copies": round(statistics.median(cb) / (12 * min(cc)), 2),
           "cpu_texelfetch_copy_min_ms": round(min(cs) / 1e6, 2),
           "cpu_chain_over_12_texelfetch_copies": round(statistics.median(cb) / (12 * min(cs)), 2)}
    if os.environ.get("PASSES"):
        passes = t._chain_passes[1]  # the irradiance's passes as _blur_chain draws them every frame
        names, level, k0 = [], 0, 0
        narrow = t._narrow_ok(levels, steps)
        if narrow:
            names.append("narrow I1+I2 L0")
        for k, lvl in enumerate(levels):
            while level < lvl:
                level += 1
                names.append(f"down to L{level}")
            if not (narrow and k < 2):
                names += [f"I{k + 1} U L{lvl}", f"I{k + 1} V L{lvl}"]
        # the seam fills (callables, gl/seam_fill.py) sit before the step they fill for
        named, j = [], 0
        for q in passes:
            named.append(None if callable(q) else names[j])
            j += not callable(q)
        assert j == len(names), (names, len(passes))
        names = [n or f"fill before {next(x for x in named[i:] if x)}" for i, n in enumerate(named)]
        per = [[] for _ in passes]
        for i in range(int(os.environ.get("REPS", 5))):
            for j, q in enumerate(passes):
                ctx.finish(); c0 = cpu_busy_ns(); t._draw([q]); ctx.finish(); per[j].append(cpu_busy_ns() - c0)
        out["cpu_passes_ms"] = {n: round(statistics.median(v) / 1e6, 2) for n, v in zip(names, per)}
    print(json.dumps(out))
