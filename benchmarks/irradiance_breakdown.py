"""Where tsd's texture-space irradiance pass spends its time: variants of tsd/irradiance.frag (no
shadows, one sharp tap per light, no normal map, no environment, constant) timed in one process
on the head at 512^2.

    PYTHONPATH=src python benchmarks/irradiance_breakdown.py
"""
import os, statistics
import numpy as np, dermis, moderngl
from dermis.bench import HEAD_TOML
from dermis.renderer import Renderer
from dermis.gl.shaders import load_shader_source
from dermis.techniques.base import bind_scene
from dermis.techniques.shared import MAX_GAUSSIANS
sc = dermis.load_scene(HEAD_TOML)
S = 512
with Renderer(sc, (64, 64), irradiance_size=S) as r:
    r.render("tsd")
    t = r.technique("tsd")
    frame = r.last_frame
    ctx = r.ctx
    vs = load_shader_source("tsd/uv_space.vert", {"MAX_GAUSSIANS": MAX_GAUSSIANS})
    fs0 = load_shader_source("tsd/irradiance.frag", {"MAX_GAUSSIANS": MAX_GAUSSIANS})
    variants = {
        "full": fs0,
        "no shadow": fs0.replace("shadow_soft(i, P, Ng)", "1.0"),
        "sharp shadow": fs0.replace("shadow_soft(i, P, Ng)", "shadow_sharp(i, P, Ng)"),
        "no normal map": fs0.replace("vec3 N = perturb_normal(v_normal, v_tangent, v_uv);", "vec3 N = Ng;"),
        "no env": fs0.replace("E += environment_irradiance_occluded(N, Ng, vis) * energy_transmitted(rho_s, 0.5, m);", ""),
        "const": fs0.replace("f_irradiance = vec4(E * albedo_power(albedo, uMix), 1.0);", "f_irradiance = vec4(1.0);"),
    }
    progs = {}
    for k, fs in variants.items():
        if k != "full" and fs == fs0:
            print("variant did not apply:", k); continue
        progs[k] = ctx.program(vertex_shader=vs, fragment_shader=fs)
    out = t._texture("irradiance", (S, S))
    res = {}
    for rep in range(4):
        for k, p in progs.items():
            bind_scene(frame, p)
            t._uv_pass(frame, p, out); ctx.finish()
            import time; t0 = time.perf_counter(); t._uv_pass(frame, p, out); ctx.finish()
            res.setdefault(k, []).append((time.perf_counter() - t0) * 1e3)
    print(os.getloadavg()[0], {k: round(statistics.median(v), 1) for k, v in res.items()})
