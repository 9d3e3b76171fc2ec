"""Where preintegrated's one screen pass spends its time, by elimination (round 11, perf11): variants
of preintegrated/skin.frag as the technique compiles it (its defines, the lights unrolled for the
scene's count, the shared bounce read), one part removed or replaced at a time by text substitution,
drawn by the technique itself (PreintegratedSkin.override_light_program) into the frame's target,
timed in ONE process on the head, interleaved, the process's CPU ms (all llvmpipe threads), min over
``--repeats`` (benchmarks/pass_breakdown.py's timed_all). A variant whose text no longer matches is
reported and skipped.

    PYTHONPATH=src python benchmarks/preintegrated_breakdown.py [--scene S.toml] [--size 512] [--repeats 5] [--only a,b] [--against main]

Round 24 (pre24) brought the variants to the shader of then and added --scene (front-key 768 is issue 14's
reference case); variants marked "moves pixels" are candidates, not term removals.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.shaders import load_shader_source
from dermis.renderer import Renderer
from dermis.techniques.shared import INTERREFLECTION_DEFINE, LIGHT_COUNT_DEFINE, light_signature, signature_defines

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pass_breakdown import source_at, timed_all  # noqa: E402

LOOP = "vec3 m_k = textureLod(uNormalMapLod, nuv, lod_k).xyz * 2.0 - 1.0;"
SPEC = ("vec3 spec = skin_specular_radiance(v_world, Ngeo, Ns, V, m, rho_s, uSpecularTables, v_visibility,\n"
        "                                       v_blocked_sh0, v_blocked_sh1, v_blocked_sh2);")
TH = "    vec3 T_h = transmittance_profile(h) * th.y;  // partial coverage at the bake's edge: fades over a texel\n"
LIGHTS = "DERMIS_FOR_EACH_LIGHT(E += preintegrated_light(light_i, Ngeo, N, N_red, N_green, N_blue, curvature, rho_s, m, c);)"


def variants(fs0: str) -> dict:
    """The pass with one term removed (round 24, pre24: the texts of skin.frag and its includes then)."""
    subs = {
        "no translucency (transmitted_irradiance)": [(" + transmitted_irradiance(v_world, Ngeo, v_uv_ts, uv_per_unit);", ";")],
        "translucency without far-face box (s = 1)": [("float s = far_face_shadow(i, P, Ng, uv_ts, uv_per_unit, h, half_mm, L);", "float s = 1.0;")],
        "no light PCF (s = 1)": [("float s = shadow_soft_penumbra(i, v_world, Ngeo, width_mm);", "float s = 1.0; width_mm = 1e30;")],
        "no penumbra table": [("bool in_penumbra = uPenumbraScattering > 0.5 && s > 0.0 && s < 1.0;", "bool in_penumbra = false;")],
        "no wide penumbra (a = 0)": [("vec3 a = uPenumbraScattering > 0.5 ? wide_penumbra_blend(i, v_world) : vec3(0.0);", "vec3 a = vec3(0.0);")],
        "wide box: the corner probe only (no 36 taps)": [("if (corners == 4.0 * probe) return probe;", "return probe;")],
        "wide box: not called (s_wide = s)": [("float s_wide = shadow_box_curved(i, v_world, Ngeo, 0.5 * W, min(2.0 * curvature, LIFT_MAX_TURN / (0.5 * W)), s);",
                                               "float s_wide = s;")],
        "translucency skipped where T(h) <= 1e-3 (moves pixels)": [(TH, TH + "    if (max(T_h.r, max(T_h.g, T_h.b)) <= 1e-3) return T;\n")],
        "no diffuse table (D = cos)": [("vec3 D = diffuse_lookup(cos_c, curvature);", "vec3 D = max(cos_c, vec3(0.0));")],
        "no bump shadowing": [("cos_c = ngl + vec3(bump_shadowing(Ngeo, N_red, L), bump_shadowing(Ngeo, N_green, L),\n"
                               "                       bump_shadowing(Ngeo, N_blue, L)) * (cos_c - ngl);", "")],
        "no blurred-normal fetches (m_k = z)": [(LOOP, "vec3 m_k = vec3(0.0, 0.0, 1.0);")],
        "no ambient": [("E += ambient * energy_transmitted(rho_s, 0.5, m);", "")],
        "no bounce": [("E += bounce_irradiance();", "")],
        "no specular": [(SPEC, "vec3 spec = vec3(0.0);")],
        "no light specular (env only)": [("DERMIS_FOR_EACH_LIGHT(spec += skin_specular_light(light_i, P, Ng, Ns, V, m, rho_s, beckmannTex);)", "")],
        "no subsurface transfer": [("E * albedo + subsurface_transfer(v_uv_ts) + subsurface_transfer_view(v_uv_ts, V, Ngeo)", "E * albedo")],
        "no transfer view term": [(" + subsurface_transfer_view(v_uv_ts, V, Ngeo)", "")],
        "no varyings move (s = 0)": [("s = move ? s : vec2(0.0);", "s = vec2(0.0);")],
        "no pores (Ns = N)": [("vec3 Ns = pore_normal(N, P_mm, uPoreScaleMm, uPoreStrength);", "vec3 Ns = N;")],
        "no lights (E = 0 before the ambient)": [(LIGHTS, "")],
        "const": [("f_color = vec4(color, 1.0);", "f_color = vec4(1.0);")],
    }
    out = {"full": fs0}
    for k, reps in subs.items():
        f = fs0
        ok = True
        for a, b in reps:
            if a not in f:
                print(f"skipped (text changed): {k}")
                ok = False
                break
            f = f.replace(a, b)
        if ok:
            out[k] = f
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default=str(HEAD_TOML))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", default=None, help="comma-separated variant names (default: all)")
    ap.add_argument("--against", default=None, help="also time this git revision's skin.frag (same defines) as 'full @REV'")
    a = ap.parse_args(argv)
    sc = dermis.load_scene(a.scene)
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance_size) as r:
        r.render("preintegrated")
        t, frame, ctx = r.technique("preintegrated"), r.last_frame, r.ctx
        # as shipped: per light count and light signature (round 24, sig24)
        d = {**t.light_programs(sc, True).defines, LIGHT_COUNT_DEFINE: len(sc.lights), INTERREFLECTION_DEFINE: 1,
             **signature_defines(light_signature(sc.lights))}
        vs = load_shader_source("common/mesh.vert", d)
        v = variants(load_shader_source("preintegrated/skin.frag", d))
        if a.only:
            keep = set(a.only.split(",")) | {"full", "const"}
            v = {k: f for k, f in v.items() if k in keep}
        if a.against:
            v[f"full @{a.against}"] = source_at(a.against, "preintegrated/skin.frag", d)
        progs = {k: ctx.program(vertex_shader=vs, fragment_shader=f) for k, f in v.items()}
        fns = {}
        for k, p in progs.items():
            def fn(p=p):
                t.override_light_program(p)
                frame.target.use()
                frame.target.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                t.render(frame)
            fns[k] = fn
        def aniso1(full=fns["full"]):  # the full pass with the material maps' anisotropic filtering off (moves pixels)
            old = {k: tx.anisotropy for k, tx in r.gpu.textures.items()}
            for tx in r.gpu.textures.values():
                tx.anisotropy = 1.0
            full()
            for k, tx in r.gpu.textures.items():
                tx.anisotropy = old[k]
        if a.only is None or "material maps anisotropy 1" in a.only.split(","):
            fns["material maps anisotropy 1"] = aniso1
        if getattr(t, "_ensure_transmitted", None) is not None:  # the texture-space translucency (round 11)
            def trans():
                t._transmitted_key = None
                t._ensure_transmitted(frame, t.thickness.get(frame, max(r.irradiance_size // 2, 1)), True)
            fns["texture-space translucency pass (per lighting change)"] = trans
        res = timed_all(ctx, fns, a.repeats)
        t.override_light_program(None)
        print(f"{Path(a.scene).name}, {a.size}^2 output, samples {r.samples}, {r.info['renderer']}, load {os.getloadavg()[0]:.1f}")
        print("| variant | CPU ms | x const |\n|---|---|---|")
        for k, x in res.items():
            print(f"| {k} | {x:.1f} | {x / res['const']:.1f} |")
        print(f"passes of the last frame: {r.stats['passes_run']}")


if __name__ == "__main__":
    main()
