"""Where the shared bounce (gl/interreflection.py SharedBounce: ssss, preintegrated, lambert) spends
its time (round 11, perf11): the sub-steps timed alone and variants of its rho E raster (text
substitutions on the expanded tsd/irradiance.frag), in ONE process on the head, interleaved, the
process's CPU ms (all llvmpipe threads), min over ``--repeats`` (benchmarks/pass_breakdown.py's timed_all).

The higher orders (BounceSeries) are timed per order too: the raster of rho T, its reduction, the
gather with E_b added, and the whole series. ``--image-variants`` renders lambert on the five
crop-sheet scenes with this tree's bounce and with cheaper ones, each the same code with one change
(round 17, perf17), and prints each one's max |difference| / image max and mean: one order fewer,
the orders' raster at the gather's level (SOURCE_FINER_LEVELS 0 for the series alone), the one
bounce's rho E (its light pass) there instead (the orders as they are), the light
pass's shadow one bilinear-compare tap (shadow_sharp) instead of the PCF grid.

    PYTHONPATH=src python benchmarks/shared_bounce_breakdown.py [--irradiance-size 1024] [--repeats 7] [--against main] [--variants]
    PYTHONPATH=src python benchmarks/shared_bounce_breakdown.py --image-variants [--size 512]
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import moderngl

import dermis
from dermis.bench import HEAD_TOML
from dermis.geometry.interreflection import BOUNCE_ORDERS
from dermis.gl.irradiance_inputs import light_pass as draw_light_pass
from dermis.gl.resources import maps_without_anisotropy, set_uniform, use_texture
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


def image_variants(size: int, irradiance_size: int):
    """lambert with this tree's shared bounce against cheaper variants of it (the module docstring)."""
    import numpy as np

    repo = Path(__file__).resolve().parents[1]
    scenes = [repo / "examples" / "lee-perry-smith.toml"] + [repo / "examples" / "reference" / f"{n}.toml"
                                                            for n in ("front-key", "side", "back-ears", "environment")]
    print(f"lambert at {size}^2, irradiance {irradiance_size}^2: max |variant - this tree| / image max (mean), load {os.getloadavg()[0]:.1f}")
    print("| scene | one order fewer | the orders rastered at the gather level | rho E (the light pass) at the gather level "
          "| light pass: sharp shadow |\n|---|---|---|---|---|")
    for path in scenes:
        sc = dermis.load_scene(str(path))
        with Renderer(sc, (size, size), irradiance_size=irradiance_size) as r:
            def image():
                r.interreflection.key = None  # rebuild the bounce with the variant in place
                return np.asarray(r.render("lambert"), np.float64)[..., :3]
            base = image()
            peak = base.max()
            cells = []
            r.bounce_orders = BOUNCE_ORDERS - 1
            cells.append(image())
            r.bounce_orders = None
            chain = r.interreflection._series._chain
            levels = chain.levels
            chain.levels = lambda s, lvl: levels(s, lvl)[-1:]
            cells.append(image())
            chain.levels = levels
            own = r.interreflection._chain  # the one bounce's rho E (light pass) at the gather's level too
            own_levels = own.levels
            own.levels = lambda s, lvl: own_levels(s, lvl)[-1:]
            cells.append(image())
            own.levels = own_levels
            n = len(sc.lights)
            d = {LIGHT_COUNT_DEFINE: n, "SKIN_BOUNCE_FROM_INPUTS": 1}
            soft = "float s = shadow_soft(i, P, Ng);"
            fs = load_shader_source("tsd/irradiance.frag", d)
            assert soft in fs, "the light pass's shadow changed: update the variant"
            sharp = r.ctx.program(vertex_shader=load_shader_source("common/fullscreen.vert", d),
                                  fragment_shader=fs.replace(soft, "float s = shadow_sharp(i, P, Ng);"))
            programs = r.interreflection.programs
            r.interreflection.programs = lambda count: sharp
            cells.append(image())
            r.interreflection.programs = programs
            again = image()
            assert np.array_equal(again, base), "a variant stayed in place"
            print(f"| {path.stem} | " + " | ".join(f"{np.abs(v - base).max() / peak:.1e} ({np.abs(v - base).mean() / peak:.0e})"
                                                   for v in cells) + " |", flush=True)


def mesh_raster(frame, prog, level):
    """The mesh drawn in texture space with ``prog`` (its uniforms bound) into ``level`` = (texture, fbo),
    cleared first (coverage 0 off the layout), as BounceSeries.run and the one-raster rho E draw it."""
    tex, fbo = level
    fbo.use()
    fbo.viewport = (0, 0, *tex.size)
    fbo.clear(0.0, 0.0, 0.0, 0.0)
    frame.gpu.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    with maps_without_anisotropy(frame.gpu, surfaces=False):
        frame.gpu.vao(prog).render(moderngl.TRIANGLES)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--against", default="main", help="the revision whose one-raster rho E is timed beside ('' for none)")
    ap.add_argument("--variants", action="store_true", help="also the light pass's variants and content floor")
    ap.add_argument("--image-variants", action="store_true", help="the image change of cheaper bounces instead of timings")
    ap.add_argument("--size", type=int, default=512, help="--image-variants: the renders' size")
    a = ap.parse_args(argv)
    if a.image_variants:
        return image_variants(a.size, a.irradiance_size)
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
                mesh_raster(frame, old, levels[0])
            fns[f"rho E, {a.against}: one mesh raster"] = old_raster

        def light_pass(prog):
            def fn():
                bind_scene(frame, prog)
                sb.inputs.bind(prog, Unit.FIRST_FREE)
                tex, fbo = levels[0]
                draw_light_pass(ctx, sb._vaos, prog, fbo, tex.size)  # the renderer's own
            return fn
        fns["rho E, this tree: light pass (full-screen, per lighting change)"] = light_pass(sb.programs(n, sc.lights))

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
        se = sb._series
        orders = se._chain.levels(a.irradiance_size, sb.level)

        def order_raster():  # one order's raster of rho T_(n-1) as BounceSeries.run draws it
            bind_scene(frame, se._splat)
            set_uniform(se._splat, "uVerticesPerRow", int(sb.hits.per_row))
            set_uniform(se._splat, "uBounce", int(Unit.FIRST_FREE))
            set_uniform(se._splat, "uRho", int(Unit.FIRST_FREE) + 1)
            use_texture(se._rho, int(Unit.FIRST_FREE) + 1)
            use_texture(sb._gather.target, Unit.FIRST_FREE)
            mesh_raster(frame, se._splat, orders[0])
        n_orders = int(BOUNCE_ORDERS if r.bounce_orders is None else r.bounce_orders)
        fns["higher order: raster of rho T"] = order_raster
        fns["higher order: reduction"] = lambda: se._chain.reduce(orders)
        fns["higher order: gather (+ E_b)"] = lambda: se._gather.run(sb.hits, orders[-1][0], base=sb._gather.target)
        fns[f"higher orders: the series (orders 2-{n_orders})"] = lambda: se.run(frame, sb.hits, sb._gather, sb.level)
        fns["whole SharedBounce.get per lighting change (this tree)"] = whole
        res = timed_all(ctx, fns, a.repeats)
        print(f"head, irradiance {a.irradiance_size}^2, level {sb.level}, raster {levels[0][0].size}, "
              f"{r.info['renderer']}, load {os.getloadavg()[0]:.1f}")
        print("| sub-step / variant | CPU ms |\n|---|---|")
        for k, v in res.items():
            print(f"| {k} | {v:.1f} |")


if __name__ == "__main__":
    main()
