"""Where tsd's irradiance and final passes and lambert's pass spend their time, by elimination:
variants of each fragment shader (one part removed or replaced at a time) timed in ONE process on
the head, interleaved, median of ``--repeats``. The variants are text substitutions on the
expanded shader source; one that no longer applies is reported and skipped (the shader changed).

    PYTHONPATH=src python benchmarks/pass_breakdown.py [--size 512] [--irradiance-size 1024] [--repeats 3]

Prints one table per pass: CPU ms (min over the repeats, all llvmpipe threads), and ms as a multiple of the pass's constant-output variant (what a
shader with the same raster and no work costs: the lower bound of what shader work can save).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import moderngl

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.shaders import load_shader_source
from dermis.renderer import Renderer
from dermis.techniques.base import bind_scene, draw_mesh
from dermis.techniques.tsd import STORED_SHARP_SHADOWS
from dermis.techniques.shared import MAX_GAUSSIANS, Unit, bind_sampler, surface_detail_uniforms



def irradiance_variants(fs0: str) -> dict:
    soft = "float s = shadow_soft_and_sharp(i, P, Ng, ndl > 0.0, sharp);"
    light = "E += Ei * ndl * s * energy_transmitted(rho_s, ndl, m);"
    return {
        "full": fs0,
        "no shadow": fs0.replace(soft, "float s = 1.0; sharp = 1.0;"),
        "shadow: sharp only (no PCF grid)": fs0.replace("return want_soft ? shadow_pcf_at(i, c, dz, T, false, unused) : 1.0;",
                                                       "return sharp;"),
        "shadow: no sharp tap": fs0.replace("sharp = shadow_sharp_at(i, c, dz);", "sharp = 1.0;"),
        "no energy table (per light)": fs0.replace(light, "E += Ei * ndl * s;"),
        "no shadow, no energy table": fs0.replace(soft, "float s = 1.0; sharp = 1.0;").replace(light, "E += Ei * ndl;"),
        "no normal map": fs0.replace("vec3 N = perturb_normal(v_normal, v_tangent, v_uv);", "vec3 N = Ng;"),
        "no env": fs0.replace("E += environment_irradiance_occluded(N, Ng, vis) * energy_transmitted(rho_s, 0.5, m);", ""),
        "no albedo power": fs0.replace("E * albedo_power(albedo, uMix)", "E * albedo"),
        "no albedo map": fs0.replace("vec3 albedo = albedo_at(v_uv);", "vec3 albedo = vec3(0.5);"),
        "no spec/rough maps": fs0.replace("float rho_s = specular_intensity(v_uv);", "float rho_s = uRhoS;")
                                 .replace("float m = roughness_at(v_uv);", "float m = uRoughness;"),
        "const": fs0.replace("f_irradiance = vec4(E * albedo_power(albedo, uMix), 1.0);", "f_irradiance = vec4(1.0);")
                    .replace("f_sharp = vec4(1.0, skin_sharp_shadow.xyz);",
                             "f_sharp = vec4(1.0);"),
    }


def final_variants(fs0: str) -> dict:
    spec_call = "vec3 spec = skin_specular_radiance(v_world, Ng, Ns, V, m, rho_s, uSpecularTables, v_visibility);"
    return {
        "full": fs0,
        "no pores": fs0.replace("vec3 Ns = pore_normal(N, v_world * uMmPerUnit, uPoreScaleMm, uPoreStrength);", "vec3 Ns = N;"),
        "no specular": fs0.replace(spec_call, "vec3 spec = vec3(0.0);"),
        "no sharp shadow": fs0.replace("Ei * SPECULAR_SHADOW(i, P, Ng) * ks_skin_specular", "Ei * ks_skin_specular"),
        "no env specular": fs0.replace("spec += skin_environment_specular(Ns, V, m) * rho_s", "spec += vec3(0.0) * rho_s"),
        "no blurs": fs0.replace("vec3 E = diffuse_irradiance(v_uv_ts) +", "vec3 E = vec3(0.5) +"),
        "no translucency": fs0.replace("+ texture(uTranslucency, v_uv_ts).rgb;", ";"),
        "no normal map": fs0.replace("vec3 N = perturb_normal(v_normal, v_tangent, v_uv);", "vec3 N = Ng;"),
        "no energy table": fs0.replace("* INV_PI * energy_transmitted(rho_s, ndv, m);", "* INV_PI;"),
        "no albedo power": fs0.replace("albedo_power(albedo, 1.0 - uMix)", "albedo"),
        "const": fs0.replace("f_color = vec4(color, 1.0);", "f_color = vec4(1.0);"),
    }


def lambert_variants(fs0: str) -> dict:
    return {
        "full": fs0,
        "no shadow": fs0.replace("float s = shadow_soft(i, v_world, Ng);", "float s = 1.0;"),
        "no normal map": fs0.replace("vec3 N = perturb_normal(v_normal, v_tangent, v_uv);", "vec3 N = Ng;"),
        "no env": fs0.replace("vec3 color = albedo * INV_PI * environment_irradiance_occluded(N, Ng, v_visibility);",
                              "vec3 color = vec3(0.0);"),
        "no env specular": fs0.replace("color += albedo_bp * environment_specular(", "color += 0.0 * environment_specular("),
        "const": fs0.replace("f_color = vec4(color, 1.0);", "f_color = vec4(1.0);"),
    }


def shadow_from(fs: str, rev: str) -> str:
    """``fs`` with common/shadow.glsl's body (after its include line) replaced by revision ``rev``'s:
    the same pass with another tree's soft shadow, timed beside this tree's in one process."""
    import subprocess

    def body(text):
        lines = text.splitlines()
        k = next(i for i, ln in enumerate(lines) if ln.startswith('#include "common/lights.glsl"'))
        return "\n".join(lines[k + 1:])
    mine = body((Path(dermis.__file__).parent / "shaders" / "common" / "shadow.glsl").read_text())
    theirs = body(subprocess.run(["git", "show", f"{rev}:src/dermis/shaders/common/shadow.glsl"], check=True,
                                 capture_output=True, text=True, cwd=Path(__file__).resolve().parent).stdout)
    assert mine in fs, "shadow.glsl is not in this shader"
    return fs.replace(mine, theirs)


def source_at(rev: str, name: str, defines: dict) -> str:
    """Shader ``name`` expanded from git revision ``rev``'s shaders folder (this tree's loader)."""
    import subprocess
    import tempfile

    import dermis.gl.shaders as shaders

    root = Path(__file__).resolve().parent.parent
    tmp = Path(tempfile.mkdtemp(prefix="shaders-"))
    tar = subprocess.run(["git", "-C", str(root), "archive", rev, "src/dermis/shaders"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tmp)], input=tar, check=True)
    saved = shaders.SHADER_DIR
    shaders.SHADER_DIR = tmp / "src" / "dermis" / "shaders"
    try:
        return shaders.load_shader_source(name, defines)
    finally:
        shaders.SHADER_DIR = saved


def with_shadow_from(variants: dict, rev) -> dict:
    """Adds "full, shadow.glsl @rev" to ``variants`` when ``rev`` is given."""
    if rev:
        variants[f"full, shadow.glsl @{rev}"] = shadow_from(variants["full"], rev)
    return variants


CLOCK = time.process_time  # --wall: time.perf_counter
KEEP = None  # --variants: the names to time (None: all)


def compile_variants(ctx, vs, variants):
    progs = {}
    if KEEP is not None:
        variants = {k: v for k, v in variants.items() if k in KEEP or k == "full"}
    fs0 = variants["full"]
    for k, fs in variants.items():
        if k != "full" and fs == fs0:
            print(f"  variant did not apply: {k}")
            continue
        progs[k] = ctx.program(vertex_shader=vs, fragment_shader=fs)
    return progs


def timed(ctx, fn, repeats):
    """Min over ``repeats`` of the CPU time of the whole process (llvmpipe's rasteriser threads
    are in it) around fn + finish: under load from other processes this moves far less than wall
    time, which counts the time the threads wait for a core."""
    return timed_all(ctx, {"": fn}, repeats)[""]


def timed_all(ctx, fns: dict, repeats):
    """:func:`timed` of every fn in ``fns``, interleaved (round r times each variant once), so that
    a burst of load from other processes falls on every variant alike instead of on one."""
    out = {k: [] for k in fns}
    for fn in fns.values():
        fn(); ctx.finish()  # warm: first use compiles the variant's JIT code
    for _ in range(repeats):
        for k, fn in fns.items():
            ctx.finish()
            t0 = CLOCK()
            fn(); ctx.finish()
            out[k].append((CLOCK() - t0) * 1e3)
    return {k: min(v) for k, v in out.items()}


def screen_pass(frame, p):
    """A technique's mesh pass as render() draws it (draw_mesh: camera, scene state, face culling)."""
    frame.target.use()
    frame.ctx.enable(moderngl.DEPTH_TEST)
    frame.ctx.disable(moderngl.CULL_FACE)
    frame.target.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
    draw_mesh(frame, p)


def set_anisotropy(renderer, a):
    for t in renderer.gpu.textures.values():
        if t.anisotropy != 1.0 or a != 1.0:
            try:
                t.anisotropy = a
            except Exception:
                pass


def table(title, res):
    """Each row's ms and its multiple of the constant-output variant at the same anisotropy."""
    print(f"\n{title} (load {os.getloadavg()[0]:.1f})")
    print("| variant | ms | x const |\n|---|---|---|")
    for k, v in res.items():
        const = res.get("const, aniso 1x" if k.endswith(", aniso 1x") else "const")
        print(f"| {k} | {v:.1f} | {v / const:.1f} |" if const else f"| {k} | {v:.1f} | |")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scene", default=str(HEAD_TOML))
    ap.add_argument("--only", default="irradiance,final,lambert")
    ap.add_argument("--variants", default=None, help="comma-separated variant names to time (default: all)")
    ap.add_argument("--samples", type=int, default=4, help="MSAA samples of the frame (dermis render: 4)")
    ap.add_argument("--shadow-from", default=None, help="also time each pass with this git revision's common/shadow.glsl")
    ap.add_argument("--against", default=None, help="also time each pass with these git revisions' whole shaders (comma-separated; \"full @REV\")")
    ap.add_argument("--wall", action="store_true", help="wall-clock time instead of the process's CPU time")
    ap.add_argument("--irradiance-aniso-1x-only", action="store_true",
                    help="time the irradiance variants only as render() draws the pass (maps without anisotropy)")
    a = ap.parse_args(argv)
    only = a.only.split(",")
    global KEEP, CLOCK
    if a.wall:
        CLOCK = time.perf_counter
    against = a.against.split(",") if a.against else []
    KEEP = None if a.variants is None else set(a.variants.split(",")) | {f"full @{rev}" for rev in against}
    sc = dermis.load_scene(a.scene)
    S = a.irradiance_size
    defines = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
    with Renderer(sc, (a.size, a.size), irradiance_size=S, samples=a.samples) as r:
        r.render("tsd")
        r.render("lambert")
        t = r.technique("tsd")
        frame = r.last_frame
        ctx = r.ctx
        print(f"dermis {dermis.__file__}; {a.size}^2 output, samples {r.samples}, irradiance {S}^2")
        if "irradiance" in only:
            vs = load_shader_source("tsd/uv_space.vert", defines)
            # as TextureSpaceDiffusion compiles it for a scene of at most STORED_SHARP_SHADOWS lights
            # (its lights unrolled: SKIN_LIGHT_COUNT, TextureSpaceDiffusion._irradiance_programs)
            irr_defines = {**defines, "SKIN_SHARP_SHADOWS": STORED_SHARP_SHADOWS}
            if len(sc.lights) <= STORED_SHARP_SHADOWS:
                irr_defines["SKIN_LIGHT_COUNT"] = len(sc.lights)
            v = with_shadow_from(irradiance_variants(load_shader_source("tsd/irradiance.frag", irr_defines)), a.shadow_from)
            for rev in against:
                v[f"full @{rev}"] = source_at(rev, "tsd/irradiance.frag", irr_defines)
            progs = compile_variants(ctx, vs, v)
            out = t._texture("irradiance", (S, S))
            res = {}
            for aniso in (8.0, 1.0):
                set_anisotropy(r, aniso)
                fns = {}
                for k, p in progs.items():
                    if aniso == 8.0 and a.irradiance_aniso_1x_only:
                        continue
                    if aniso == 1.0 and k not in ("full", "no shadow", "const") and not k.startswith(("full", "shadow:")) \
                            and not a.irradiance_aniso_1x_only:
                        continue

                    def fn(p=p):
                        bind_scene(frame, p)
                        # into the irradiance and the sharp-shadow targets, as texture_space draws it
                        t._uv_pass(frame, p, (out, t.tex["sharp_shadow"]))
                    fns[k + ("" if aniso == 8.0 else ", aniso 1x")] = fn
                res.update(timed_all(ctx, fns, a.repeats))
            set_anisotropy(r, 8.0)
            table(f"tsd irradiance pass at {S}^2 (no dilation)", res)
        if "final" in only:
            vs = load_shader_source("common/mesh.vert", defines)
            final_defines = {**defines, "SHARP_SHADOW_READ": None}
            v = with_shadow_from(final_variants(load_shader_source("tsd/final.frag", final_defines)), a.shadow_from)
            for rev in against:
                v[f"full @{rev}"] = source_at(rev, "tsd/final.frag", final_defines)
            progs = compile_variants(ctx, vs, v)
            res = {}
            for p in progs.values():
                bind_sampler(p, "uTranslucency", t.tex["translucency"], Unit.FIRST_FREE)
                t._profile_uniforms(p, sc.profile, Unit.FIRST_FREE + 1, frame.keys)
                bind_sampler(p, "uSharpShadow", t.tex["sharp_shadow"], Unit.FIRST_FREE + 1 + MAX_GAUSSIANS)
                surface_detail_uniforms(p, sc.material)
            for aniso in (8.0, 1.0):
                set_anisotropy(r, aniso)
                res.update(timed_all(ctx, {k + ("" if aniso == 8.0 else ", aniso 1x"): (lambda p=p: screen_pass(frame, p))
                                           for k, p in progs.items()
                                           if aniso == 8.0 or k in ("full", "no specular", "const") or k.startswith("full")},
                                     a.repeats))
            set_anisotropy(r, 8.0)
            table(f"tsd final pass at {a.size}^2", res)
        if "lambert" in only:
            vs = load_shader_source("common/mesh.vert", {})
            v = with_shadow_from(lambert_variants(load_shader_source("lambert/lambert.frag", {})), a.shadow_from)
            for rev in against:
                v[f"full @{rev}"] = source_at(rev, "lambert/lambert.frag", {})
            progs = compile_variants(ctx, vs, v)
            res = {}
            for aniso in (8.0, 1.0):
                set_anisotropy(r, aniso)
                res.update(timed_all(ctx, {k + ("" if aniso == 8.0 else ", aniso 1x"): (lambda p=p: screen_pass(frame, p))
                                           for k, p in progs.items() if aniso == 8.0 or k in ("full", "const") or k.startswith("full")},
                                     a.repeats))
            set_anisotropy(r, 8.0)
            table(f"lambert pass at {a.size}^2", res)


if __name__ == "__main__":
    main()
