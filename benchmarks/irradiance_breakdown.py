"""Where tsd's texture-space irradiance pass spends its time on the head: variants of the program
render("tsd") draws for the head's 3 lights (tsd/irradiance.frag with tsd.irradiance_defines: the
sharp-shadow, rho E and albedo^mix targets), one feature off at a time, drawn in place of the
technique's own program into the same targets; lights moving (every pass re-runs, as `dermis bench`'s
lights-moving workload), the variants interleaved frame by frame; the first round is a warm-up.
Prints each variant's median and minimum ``tsd_irradiance`` (wall ms: the UV raster and the dilation)
and the load average. Round 15 (perf15) rewrote it for the round-10+ shader (the round-9 variants no
longer applied). Since round 16 (perf16) the technique's pass is the full-screen light pass over its
light-independent inputs (tsd.SPLIT_IRRADIANCE, dermis.gl.irradiance_inputs): the variants are made from
that program (those of the one raster's code alone, "no normal map" and "const", print "did not apply";
"const (split)" is its constant fragment); ``RASTER=1`` in the environment times the one raster as before.

    PYTHONPATH=src python benchmarks/irradiance_breakdown.py [S=1024] [frames=3] [variant,variant,...]

Variants that change the image (timing only): "sharp-only (no PCF)" the soft shadow replaced by the
sharp tap, "PCF grid 2x2" 4 taps per light instead of 9 (a box of stride > 1 at softness 1.5: not the
tested disc filter), "skip PCF where sharp is 0/1" (whether llvmpipe skips a branch no lane takes),
"PCF by textureGather" (the 4 texels of each tap compared by one gather and weighted in the shader: the same
per-texel weights where the grid's stride is 1, not for the fill light's stride > 1 at softness 3).
"""
import os, statistics, sys
import dermis
from dermis.bench import HEAD_TOML, _rotate
from dermis.gl.shaders import load_shader_source
from dermis.bench_floors import FloorSampler, floor_summary, pass_floor
from dermis.renderer import Renderer

S = int(sys.argv[1]) if len(sys.argv) > 1 else 1024
frames = int(sys.argv[2]) if len(sys.argv) > 2 else 3
only = sys.argv[3].split(",") if len(sys.argv) > 3 else None
sc = dermis.load_scene(str(HEAD_TOML))
V = {
 "full": [],
 "sharp-only (no PCF)": [("return want_soft ? shadow_pcf_at(i, c, dz, T, false, unused) : 1.0;", "return sharp;")],
 "skip PCF where sharp is 0/1 (speed probe)": [("return want_soft ? shadow_pcf_at(i, c, dz, T, false, unused) : 1.0;", "if (!want_soft) return 1.0; if (sharp <= 0.0 || sharp >= 1.0) return sharp; return shadow_pcf_at(i, c, dz, T, false, unused);")],
 "PCF grid 2x2 (4 taps)": [("const int PCF_GRID = 3;", "const int PCF_GRID = 2;")],
 "no sharp tap (PCF kept)": [("    sharp = shadow_sharp_at(i, c, dz);\n", "    sharp = 1.0;\n")],
 "receiver solve only (no taps)": [("return want_soft ? shadow_pcf_at(i, c, dz, T, false, unused) : 1.0;", "return want_soft ? 1.0 + 1e-9 * (c.x + dz.x + T[0][0]) : 1.0;"), ("    sharp = shadow_sharp_at(i, c, dz);\n", "    sharp = 1.0 - 1e-9 * c.y;\n")],
 "PCF by textureGather (same per-texel weights)": [(
    "            float s = shadow_tap(i, c + delta, z + dot(dz, delta));",
    "            vec2 hh = vec2(0.5 * uShadowParams[i].w);\n"
    "            vec2 e = (vec2(t0.x + float(2 * kx), t0.y + float(2 * ky)) + 1.0) * (stride * texel);\n"
    "            vec4 g = textureGather(uShadowAtlas, uShadowTile[i].xy + clamp(e, hh, 1.0 - hh) * uShadowTile[i].zw, z + dot(dz, delta) - uShadowParams[i].y);\n"
    "            float s = dot(g, vec4(wa[kx].x * wb[ky].y, wb[kx].x * wb[ky].y, wb[kx].x * wa[ky].y, wa[kx].x * wa[ky].y)) / max(wk, 1e-12);"),
    ("    vec2 pos[n], w[n];", "    vec2 pos[n], w[n], wa[n], wb[n];"),
    ("        w[k] = hi - lo;", "        w[k] = hi - lo;\n        wa[k] = mid - lo;\n        wb[k] = hi - mid;")],
 "no shadows": [("float s = shadow_soft_and_sharp(i, P, Ng, ndl > 0.0, sharp);", "float s = 1.0; sharp = 1.0;")],
 "no receiver solve (c only)": [("    if (!shadow_receiver(i, P, N, c, dz, T)) return 1.0;\n    sharp = shadow_sharp_at",
                                 "    {mat3 Jx; if (uLightRadiance[i].w < 0.5 || !shadow_coords_jacobian(i, P, c, Jx)) return 1.0;} dz = vec2(0.0); T = mat2(1.0);\n    sharp = shadow_sharp_at")],
 "no normal map": [("vec3 N = perturb_normal(v_normal, v_tangent, v_uv);", "vec3 N = Ng;")],
 "no ambient/env": [("    E += skin_ambient(N, Ng, rho_s, m, vis);\n    return E;", "    return E;")],
 "no lights": [("    DERMIS_FOR_EACH_LIGHT(E += skin_light_entry(light_i, P, Ng, N, rho_s, m, c);)", "")],
 "const (split)": [("    vec3 E = skin_lights_directional(p.xyz, ng.xyz, n.xyz, p.w, n.w, c.rgb);", "    vec3 E = vec3(1.0);")],
 "const": [("    f_irradiance = vec4(E * albedo_mix, 1.0);", "    f_irradiance = vec4(1.0);"),
           ("    vec3 E = skin_irradiance_directional(v_world, Ng, N, rho_s, m, v_visibility, c);", "    vec3 E = vec3(1.0);")],
}
if only: V = {k: v for k, v in V.items() if k in only or k == "full"}
if os.environ.get("RASTER") == "1":
    import dermis.techniques.tsd as _tsd
    _tsd.SPLIT_IRRADIANCE = False
with Renderer(sc, (512, 512), irradiance_size=S) as r:
    r.render("tsd")
    t = r.technique("tsd")
    attr = "_light_programs" if t._split_irradiance() else "_irradiance_programs"
    own = getattr(t, attr)(len(sc.lights))
    vert, frag, defines, geom = own.extra["sources"]
    vs = load_shader_source(vert, defines)
    fs0 = load_shader_source(frag, defines)
    progs = {}
    for k, reps in V.items():
        fs = fs0
        for a, b in reps:
            if a not in fs:
                print("variant did not apply:", k, a[:60]); break
            fs = fs.replace(a, b)
        else:
            progs[k] = r.ctx.program(vertex_shader=vs, fragment_shader=fs)
    floors = FloorSampler(r, S)  # the pass's floor (uv_raster + copy), sampled after every frame
    orig = getattr(t, attr)
    base = [tuple(L.direction) for L in sc.lights]
    res = {k: [] for k in progs}
    f = 0
    try:
        for rep in range(frames + 1):
            for k, p in progs.items():
                setattr(t, attr, lambda n, p=p: p)
                f += 1
                for L, dd in zip(sc.lights, base):
                    L.direction = _rotate(dd, 0.02 * f)
                r.render("tsd")
                if rep:
                    res[k].append(r.stats["passes_ms"]["tsd_irradiance"])
                    floors.sample(1)
    finally:
        setattr(t, attr, orig)
        summary = floor_summary(floors.samples_ms)
        floor = pass_floor("tsd_irradiance", {k: v["min"] for k, v in summary.items()}, sc.profile.k)
        floors.release()
print(f"S={S} load {os.getloadavg()}")
print(f"floor uv_raster + copy: {floor:.1f} ms (minimum of {summary['copy']['n']} samples; medians "
      f"{summary['uv_raster']['median']:.1f} + {summary['copy']['median']:.1f})")
for k, v in res.items():
    print(f"{k:28s} median {statistics.median(v):7.1f} ms  min {min(v):7.1f}  = {statistics.median(v) / floor:5.1f}x floor  "
          f"({', '.join(f'{x:.0f}' for x in v)})")
