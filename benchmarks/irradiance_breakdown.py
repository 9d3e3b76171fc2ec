"""Where tsd's texture-space irradiance pass spends its time: variants of the program render("tsd")
draws (since round 16 the full-screen light pass over the light-independent inputs, tsd.SPLIT_IRRADIANCE,
dermis.gl.irradiance_inputs: tsd/irradiance.frag with tsd.light_pass_defines, its lights unrolled), one
feature off at a time, drawn in place of the technique's own program into the same targets; lights
moving (every pass re-runs, as `dermis bench`'s lights-moving workload), the variants interleaved frame by
frame (A/B/C/.../A/B/C/...); the first round is a warm-up. Prints each variant's median and minimum
``tsd_irradiance`` CPU ms (the process's CPU-time clock on llvmpipe, as `dermis bench`'s multiples: the
light pass and the dilation) against the floor uv_raster + copy (dermis.bench_floors, its minimum over
one sample per frame) and the load average. Rewritten in round 15 (perf15), round 16 (the split pass) and
round 24 (irr24: the shader's current function signatures, the CPU clock, any scene and output size).

    PYTHONPATH=src python benchmarks/irradiance_breakdown.py [S=1024] [frames=3] [variant,variant,...]
    SCENE=examples/reference/front-key.toml SIZE=768 ...   (default: the head example, 1024 x 1024)

Variants that change the image are timing probes only ("no PCF", "PCF weights without taps", "PCF grid 2x2",
...). ``RASTER=1`` times the one-raster program (tsd.SPLIT_IRRADIANCE = False) instead; the variants made
for the split pass's own lines then print "did not apply".
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
scene_path = os.environ.get("SCENE", str(HEAD_TOML))
size = int(os.environ.get("SIZE", "1024"))
sc = dermis.load_scene(scene_path)

PCF_CALL = "return want_soft ? shadow_pcf_at(i, r, false, unused) : 1.0;"
SHARP_CALL = "    sharp = shadow_sharp_at(i, r.c, r.dz);\n"
TAP = "            float s = shadow_tap(i, c + delta, z + dot(dz, delta));"
V = {
 "full": [],
 # the program before round 24 (irr24): the input reads by texelFetch, the lights' kinds and shadow kernels
 # read from the uniforms (no SKIN_LIGHT_KINDS / SKIN_SHADOW_FILTERS): the same floats
 "before irr24": [("#define SKIN_LIGHT_KINDS", "#define UNUSED_KINDS"), ("#define SKIN_SHADOW_FILTERS", "#define UNUSED_FILTERS")]
    + [(f"TEXEL(uBounceInputs[{k}], t)", f"texelFetch(uBounceInputs[{k}], t, 0)") for k in range(5)]
    + [("TEXEL(uAlbedoRest, t)", "texelFetch(uAlbedoRest, t, 0)")],
 "no PCF (sharp tap as soft)": [(PCF_CALL, "return want_soft ? sharp : 1.0;")],
 "PCF weights without taps": [(TAP, "            float s = 0.5 + 1e-9 * (delta.x + delta.y + z);")],
 "PCF grid 2x2 (4 taps)": [("const int PCF_GRID = 3;", "const int PCF_GRID = 2;")],
 "no sharp tap": [(SHARP_CALL, "    sharp = 1.0 - 1e-9 * (r.c.x + r.dz.x);\n")],
 "receiver solve only (no taps)": [(PCF_CALL, "return want_soft ? 1.0 + 1e-9 * (r.c.x + r.dz.x + r.T[0][0] + r.graze) : 1.0;"),
                                   (SHARP_CALL, "    sharp = 1.0 - 1e-9 * r.c.y;\n")],
 "no shadows": [("float s = shadow_soft_and_sharp(i, P, Ng, ndl > 0.0, sharp);", "float s = 1.0; sharp = 1.0;")],
 "no bump shadowing": [("bump_shadowing(Ng, N, L) * s", "s")],
 "no energy table": [("s * energy_transmitted(rho_s, ndl, m)", "s")],
 "no lights": [("    DERMIS_FOR_EACH_LIGHT(E += skin_light_entry(light_i, P, Ng, N, rho_s, m, c);)", "")],
 "const (split)": [("    vec3 E = skin_lights_directional(p.xyz, ng.xyz, n.xyz, p.w, n.w, c.rgb);", "    vec3 E = vec3(1.0);")],
}
extra = os.environ.get("VARIANTS_FROM")  # a Python file defining EXTRA = {name: [(old, new), ...]}
if extra:
    ns = {}
    exec(open(extra).read(), ns)
    V.update(ns["EXTRA"])
if only: V = {k: v for k, v in V.items() if k in only or k == "full"}
if os.environ.get("RASTER") == "1":
    import dermis.techniques.tsd as _tsd
    _tsd.SPLIT_IRRADIANCE = False
with Renderer(sc, (size, size), irradiance_size=S) as r:
    r.timer.cpu = True
    r.render("tsd")
    t = r.technique("tsd")
    attr = "_light_programs" if t._split_irradiance() else "_irradiance_programs"
    own = getattr(t, attr)(len(sc.lights), sc.lights)
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
                setattr(t, attr, lambda n, lights=None, p=p: p)
                f += 1
                for L, dd in zip(sc.lights, base):
                    L.direction = _rotate(dd, 0.02 * f)
                r.render("tsd")
                if rep:
                    res[k].append(r.stats["passes_cpu_ms"]["tsd_irradiance"])
                    floors.sample(1)
    finally:
        setattr(t, attr, orig)
        summary = floor_summary(floors.samples_cpu_ms)
        floor = pass_floor("tsd_irradiance", {k: v["min"] for k, v in summary.items()}, sc.profile.k)
        floors.release()
print(f"{os.path.basename(scene_path)} {size}px S={S} frames={frames} load {os.getloadavg()}")
print(f"floor uv_raster + copy: {floor:.1f} ms (minimum of {summary['copy']['n']} samples; medians "
      f"{summary['uv_raster']['median']:.1f} + {summary['copy']['median']:.1f})")
full = statistics.median(res["full"])
for k, v in res.items():
    m = statistics.median(v)
    print(f"{k:32s} median {m:7.1f} ms ({m - full:+6.1f})  min {min(v):7.1f}  = {m / floor:5.2f}x floor  "
          f"({', '.join(f'{x:.0f}' for x in v)})")
