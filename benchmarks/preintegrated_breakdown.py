"""Where preintegrated's one screen pass spends its time, by elimination (round 11, perf11): variants
of preintegrated/skin.frag as the technique compiles it (its defines, the lights unrolled for the
scene's count, the shared bounce read), one part removed or replaced at a time by text substitution,
drawn by the technique itself (PreintegratedSkin.override_light_program) into the frame's target,
timed in ONE process on the head, interleaved, the process's CPU ms (all llvmpipe threads), min over
``--repeats`` (benchmarks/pass_breakdown.py's timed_all). A variant whose text no longer matches is
reported and skipped.

    PYTHONPATH=src python benchmarks/preintegrated_breakdown.py [--size 512] [--repeats 5] [--only a,b] [--against main]
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
from dermis.techniques.shared import INTERREFLECTION_DEFINE, LIGHT_COUNT_DEFINE

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pass_breakdown import source_at, timed_all  # noqa: E402

LOOP = "vec3 m_k = textureLod(uNormalMapLod, nuv, lod_k).xyz * 2.0 - 1.0;"


def variants(fs0: str) -> dict:
    subs = {
        "no translucency (transmitted_irradiance)": [("+ transmitted_irradiance(v_world, Ngeo, v_uv_ts);", ";")],
        "no light shadow (s = 1)": [("float s = shadow_soft_penumbra(i, v_world, Ngeo, width_mm);",
                                     "float s = 1.0; width_mm = 1e30;")],
        "no penumbra table": [("if (uPenumbraScattering > 0.5 && s > 0.0 && s < 1.0)", "if (false)")],
        "no fold code (uniform-off already)": [("if (uFoldScattering > 0.5) light = max(light, fold_scattered_light(i, v_world, Ngeo, L));", "")],
        "no diffuse table (D = N.L)": [("vec3 D = diffuse_lookup(vec3(dot(N_red, L), dot(N_green, L), dot(N_blue, L)), curvature);",
                                        "vec3 D = max(vec3(dot(N_red, L), dot(N_green, L), dot(N_blue, L)), vec3(0.0));")],
        "no blurred-normal fetches (m_k = z)": [(LOOP, "vec3 m_k = vec3(0.0, 0.0, 1.0);")],
        "no ambient": [("E += ambient * energy_transmitted(rho_s, 0.5, m);", "")],
        "no bounce": [("E += bounce_irradiance();", "")],
        "no specular": [("vec3 spec = skin_specular_radiance(v_world, Ngeo, Ns, V, m, rho_s, uSpecularTables, v_visibility);",
                         "vec3 spec = vec3(0.0);")],
        "no lights (E = 0 before the ambient)": [("DERMIS_FOR_EACH_LIGHT(E += preintegrated_light(light_i, Ngeo, N, N_red, N_green, N_blue, curvature, rho_s, m, c);)", "")],
        "blurred normals' loop at a constant trip count (the profile's k)": [
            ("for (int k = 0; k < uGaussianCount; ++k) {\n        float box_texels", "for (int k = 0; k < PROFILE_K; ++k) {\n        float box_texels")],
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
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", default=None, help="comma-separated variant names (default: all)")
    ap.add_argument("--against", default=None, help="also time this git revision's skin.frag (same defines) as 'full @REV'")
    a = ap.parse_args(argv)
    sc = dermis.load_scene(str(HEAD_TOML))
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance_size) as r:
        r.render("preintegrated")
        t, frame, ctx = r.technique("preintegrated"), r.last_frame, r.ctx
        d = {**t.programs.defines, LIGHT_COUNT_DEFINE: len(sc.lights), INTERREFLECTION_DEFINE: 1}
        vs = load_shader_source("common/mesh.vert", d)
        v = {k: f.replace("PROFILE_K", str(sc.profile.k)) for k, f in variants(load_shader_source("preintegrated/skin.frag", d)).items()}
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
        if getattr(t, "_ensure_transmitted", None) is not None:  # the texture-space translucency (round 11)
            def trans():
                t._transmitted_key = None
                t._ensure_transmitted(frame, t.thickness.get(frame, max(r.irradiance_size // 2, 1)), True)
            fns["texture-space translucency pass (per lighting change)"] = trans
        res = timed_all(ctx, fns, a.repeats)
        t.override_light_program(None)
        print(f"head, {a.size}^2 output, samples {r.samples}, {r.info['renderer']}, load {os.getloadavg()[0]:.1f}")
        print("| variant | CPU ms | x const |\n|---|---|---|")
        for k, x in res.items():
            print(f"| {k} | {x:.1f} | {x / res['const']:.1f} |")
        print(f"passes of the last frame: {r.stats['passes_run']}")


if __name__ == "__main__":
    main()
