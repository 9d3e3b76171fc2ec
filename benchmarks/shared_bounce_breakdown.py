"""Where the shared bounce (gl/interreflection.py SharedBounce: ssss, preintegrated, lambert) spends
its time (round 11, perf11): the sub-steps timed alone and variants of its rho E raster (text
substitutions on the expanded tsd/irradiance.frag), in ONE process on the head, interleaved, the
process's CPU ms (all llvmpipe threads), min over ``--repeats`` (benchmarks/pass_breakdown.py's timed_all).

    PYTHONPATH=src python benchmarks/shared_bounce_breakdown.py [--irradiance-size 1024] [--repeats 7] [--against main] [--variants]
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import moderngl

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.resources import maps_without_anisotropy, set_uniform
from dermis.gl.shaders import load_shader_source
from dermis.renderer import Renderer
from dermis.techniques.base import bind_scene
from dermis.techniques.shared import LIGHT_COUNT_DEFINE, Unit, directional_albedo_uniforms

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pass_breakdown import source_at, timed_all  # noqa: E402


def light_pass_variants(fs0: str, n_lights: int) -> dict:
    """This tree's per-lighting-change pass (SKIN_BOUNCE_FROM_INPUTS), one part removed at a time,
    and stand-ins for its content floor (the fetches it cannot avoid)."""
    E = "vec3 E = skin_lights_directional(p.xyz, ng.xyz, n.xyz, p.w, n.w, c.rgb);"
    out = "f_irradiance = vec4(E * am.rgb, 1.0);"
    assert E in fs0 and out in fs0
    # per light: its map coordinates (one transform) and 9 compare taps one texel apart around them
    taps = "".join(f""" {{ vec4 q = uLightViewProj[{i}] * vec4(p.xyz, 1.0); vec3 cc = q.xyz / q.w * 0.5 + 0.5;
        vec2 uv = uShadowTile[{i}].xy + cc.xy * uShadowTile[{i}].zw; float tx = uShadowParams[{i}].w * uShadowTile[{i}].z;"""
                   + "".join(f" s += textureLod(uShadowAtlas, vec3(uv + vec2({dx}.0, {dy}.0) * tx, cc.z), 0.0);"
                             for dx in (-1, 0, 1) for dy in (-1, 0, 1)) + " }" for i in range(n_lights))
    return {
        "light pass: no shadow (s = 1)": fs0.replace("float s = shadow_soft(i, P, Ng);", "float s = 1.0;"),
        "light pass: no lights (the 5 input fetches)": fs0.replace(E, "vec3 E = p.xyz + n.xyz + ng.xyz + c.rgb;"),
        f"floor: the 5 input fetches + {9 * n_lights} shadow-compare fetches (3 x 3 PCF per light)":
            fs0.replace(E, "float s = 0.0;" + taps + " vec3 E = p.xyz + n.xyz + ng.xyz + c.rgb + s;"),
        "light pass: constant output": fs0.replace(out, "f_irradiance = vec4(1.0);"),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--against", default="main", help="the revision whose one-raster rho E is timed beside ('' for none)")
    ap.add_argument("--variants", action="store_true", help="also the light pass's variants and content floor")
    a = ap.parse_args(argv)
    sc = dermis.load_scene(str(HEAD_TOML))
    with Renderer(sc, (128, 128), irradiance_size=a.irradiance_size) as r:
        r.render("lambert")
        frame, ctx = r.last_frame, r.ctx
        sb = r.interreflection
        levels = sb._chain.levels(a.irradiance_size, sb.level)  # the textures the frame drew into
        n = len(sc.lights)
        d = {LIGHT_COUNT_DEFINE: n}
        fns = {}
        if a.against:  # the one mesh raster of rho E as `--against` draws it
            old = ctx.program(vertex_shader=source_at(a.against, "tsd/uv_space.vert", d),
                              fragment_shader=source_at(a.against, "tsd/irradiance.frag", d))

            def old_raster():
                bind_scene(frame, old)
                directional_albedo_uniforms(old, frame.scene)
                set_uniform(old, "uMix", 1.0)
                tex, fbo = levels[0]
                fbo.use()
                fbo.viewport = (0, 0, *tex.size)
                fbo.clear(0.0, 0.0, 0.0, 0.0)
                ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
                with maps_without_anisotropy(frame.gpu, surfaces=False):
                    frame.gpu.vao(old).render(moderngl.TRIANGLES)
            fns[f"rho E, {a.against}: one mesh raster"] = old_raster

        def light_pass(prog):
            def fn():
                bind_scene(frame, prog)
                sb.inputs.bind(prog, Unit.FIRST_FREE)
                tex, fbo = levels[0]
                fbo.use()
                fbo.viewport = (0, 0, *tex.size)
                ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
                sb._vaos.setdefault(prog, ctx.vertex_array(prog, [])).render(moderngl.TRIANGLES, vertices=3)
            return fn
        fns["rho E, this tree: light pass (full-screen, per lighting change)"] = light_pass(sb.programs(n))

        def inputs():
            sb.inputs.forget()
            sb.inputs.draw(frame, levels[0][0].size, mix=1.0)
        fns["rho E, this tree: inputs raster (once per content)"] = inputs
        if a.variants:
            vs = load_shader_source("common/fullscreen.vert", d)
            fs0 = load_shader_source("tsd/irradiance.frag", {**d, "SKIN_BOUNCE_FROM_INPUTS": 1})
            for k, f in light_pass_variants(fs0, n).items():
                fns[k] = light_pass(ctx.program(vertex_shader=vs, fragment_shader=f))

        def whole():
            sb.key = None
            sb.get(frame)
        fns["reductions"] = lambda: sb._chain.reduce(levels)
        fns["gather"] = lambda: sb._gather.run(sb.hits, levels[-1][0])
        fns["whole SharedBounce.get per lighting change (this tree)"] = whole
        res = timed_all(ctx, fns, a.repeats)
        print(f"head, irradiance {a.irradiance_size}^2, level {sb.level}, raster {levels[0][0].size}, "
              f"{r.info['renderer']}, load {os.getloadavg()[0]:.1f}")
        print("| sub-step / variant | CPU ms |\n|---|---|")
        for k, v in res.items():
            print(f"| {k} | {v:.1f} |")


if __name__ == "__main__":
    main()
