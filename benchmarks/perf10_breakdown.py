"""Where tsd's translucency and bounce passes spend their time, by elimination (round 10, perf10):
variants of tsd/translucency.frag (text substitutions on main's expanded source, one part removed or
replaced at a time) and the bounce's sub-steps, timed in ONE process on the head, interleaved, the
process's CPU ms (all llvmpipe threads), min over ``--repeats`` (benchmarks/pass_breakdown.py's timed_all).

    PYTHONPATH=src python benchmarks/perf10_breakdown.py [--irradiance-size 1024] [--repeats 9] [--against main]

Prints the translucency's first-pass variants at half the irradiance size, the two tents (main's nine
texel fetches, this tree's four bilinear taps), the bounce's sub-steps as this tree draws them
(reductions, gather, splat reading albedo^mix), and the share of texels and 4 x 4 blocks with a far face.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import moderngl
import numpy as np

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.resources import maps_without_anisotropy, set_uniform
from dermis.renderer import Renderer
from dermis.techniques.base import bind_scene
from dermis.techniques.shared import MAX_GAUSSIANS, Unit, bind_sampler, translucency_uniforms

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pass_breakdown import source_at, timed_all  # noqa: E402

DISCARD = "vec4 th = texelFetch(uThickness, c, 0); if (th.w <= 0.0) discard;"


def translucency_variants(fs0: str, wide: list) -> dict:
    loop = """    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        if (uVariances[k] < uTranslucencyMinVariance) continue;
        vec3 excess = max(through - exp(-g * g / (2.0 * uVariances[k])), vec3(0.0));
        T += excess * uWeights[k] * blurred_irradiance(k, th.xy);
    }"""
    unrolled = "".join(f"""    {{ vec3 excess = max(through - exp(-g * g / (2.0 * uVariances[{k}])), vec3(0.0));
        T += excess * uWeights[{k}] * blurred_irradiance({k}, th.xy); }}\n""" for k in wide)
    fetch = "vec4 th = texelFetch(uThickness, c, 0);"
    static = """    vec2 stretch = max(texture(uStretch, uv).xy, vec2(1e-6));
    vec2 texels = (th.xy - uv) * vec2(textureSize(uStretch, 0));
    float g = length(texels / stretch);  // mm along the surface from A to B
    vec3 through = slab_transmittance(th.z) / max(wide, vec3(1e-6));  // per unit of the wide weights"""
    out = "f_translucency = vec4(T * uTranslucencyStrength, th.w >= 0.0 ? 1.0 : 0.0);"
    for part in (loop, fetch, static, out):
        assert part in fs0, f"main's translucency.frag changed: {part[:40]}"
    return {
        "main": fs0,
        "no far-face evaluation (T = w)": fs0.replace("T = th.w * through_far_face(th, uv, wide);", "T = th.www;"),
        "loop unrolled at the wide Gaussians' constant indices": fs0.replace(loop, unrolled),
        "discard first where w <= 0": fs0.replace(fetch, DISCARD),
        "the same discard behind a uniform that is 0 (never fires)":
            fs0.replace(fetch, fetch + " if (uNeverSet != 0 && th.w <= 0.0) discard;")
               .replace("out vec4 f_translucency;", "uniform int uNeverSet;\nout vec4 f_translucency;"),
        "a discard at the end (never fires)": fs0.replace(out, "if (uNeverSet != 0 && th.w < -5.0) discard;\n    " + out)
                                               .replace("out vec4 f_translucency;", "uniform int uNeverSet;\nout vec4 f_translucency;"),
        "discard first + slab law and g from one texelFetch (stand-in)": fs0.replace(fetch, DISCARD).replace(
            static, "    vec4 st = texelFetch(uStretch, ivec2(uv * vec2(textureSize(uStretch, 0))), 0);\n    float g = st.a; vec3 through = st.rgb;"),
        "const": fs0.replace(out, "f_translucency = vec4(1.0);"),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--against", default="main", help="the revision whose translucency shaders are the variants' base")
    a = ap.parse_args(argv)
    sc = dermis.load_scene(str(HEAD_TOML))
    S = a.irradiance_size
    d = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
    with Renderer(sc, (256, 256), irradiance_size=S) as r:
        r.render("tsd")
        t, frame, ctx = r.technique("tsd"), r.last_frame, r.ctx
        prof = sc.profile
        wide = [k for k in range(prof.k) if prof.variances_mm2[k] >= 0.15]
        vs = source_at(a.against, "common/fullscreen.vert", d)
        progs = {k: ctx.program(vertex_shader=vs, fragment_shader=f)
                 for k, f in translucency_variants(source_at(a.against, "tsd/translucency.frag", d), wide).items()}
        progs["tent: main (9 texelFetch)"] = ctx.program(vertex_shader=vs, fragment_shader=source_at(a.against, "tsd/translucency_tent.frag", d))
        progs["tent: this tree (4 bilinear)"] = t.p_trans_tent
        trans = t.tex["translucency"]
        thick = t.thickness.get(frame, trans.size[0])
        fns = {}
        for k, p in progs.items():
            t.vaos.setdefault(p, ctx.vertex_array(p, []))
            o = ctx.texture(trans.size, 4, dtype="f2")

            def fn(p=p, o=o, tent=k.startswith("tent")):
                if tent:
                    bind_sampler(p, "uSource", t.tex["translucency_own"], 0)
                else:
                    translucency_uniforms(p, True, t.options.translucency_strength, sc)
                    t._profile_uniforms(p, prof, Unit.FIRST_FREE, frame.keys)
                    bind_sampler(p, "uStretch", t.tex["stretch_0"], Unit.FIRST_FREE + MAX_GAUSSIANS)
                    bind_sampler(p, "uThickness", thick, Unit.FIRST_FREE + MAX_GAUSSIANS + 1)
                t._fullscreen(p, o)
            fns[k] = fn
        # the bounce's sub-steps as this tree draws them (rho E and albedo^mix from the irradiance pass)
        _, p_gather, _, p_splat = t._p_bounce
        level = t.bounce_level
        scratch = t._texture("perf10_scratch", (S, S))

        def downs():
            src = t.tex[("bounce_exitant", 0)]
            for lvl in range(1, level + 1):
                src, p = t._down(src, ("bounce_exitant", lvl), lvl)
                t._draw(p)

        def splat():
            bind_scene(frame, p_splat)
            bind_sampler(p_splat, "uBounce", p_gather.target, Unit.FIRST_FREE)
            bind_sampler(p_splat, "uAlbedoMix", t.tex["albedo_mix"], Unit.FIRST_FREE + 1)
            set_uniform(p_splat, "uVerticesPerRow", int(t.hits.per_row))
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            with maps_without_anisotropy(frame.gpu, surfaces=False):
                t._uv_pass(frame, p_splat, scratch, clear=False)
            ctx.disable(moderngl.BLEND)
        fns["bounce: reductions"] = downs
        fns["bounce: gather"] = lambda: p_gather.run(t.hits, t.tex[("bounce_exitant", level)])
        fns["bounce: splat"] = splat
        res = timed_all(ctx, fns, a.repeats)
        print(f"head, irradiance {S}^2, translucency {trans.size[0]}^2, {r.info['renderer']}, load {os.getloadavg()[0]:.1f}")
        print("| variant | CPU ms |\n|---|---|")
        for k, v in res.items():
            print(f"| {k} | {v:.1f} |")
        th = t.read_texture(thick)
        n = th.shape[0]
        far = th[..., 3] > 0
        print(f"far face (w > 0): {far.mean():.1%} of the texels, "
              f"{far.reshape(n // 4, 4, n // 4, 4).any(axis=(1, 3)).mean():.1%} of the 4 x 4 blocks")


if __name__ == "__main__":
    main()
