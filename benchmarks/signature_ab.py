"""Round 24 (sig24): the light passes compiled per light signature (dermis.techniques.shared.light_signature)
against the same sources with the kinds and shadow kernels left to run time, interleaved frame by frame in one
process (the lights turned a little each frame: a lighting change), CPU ms per pass (dermis.gl.context.cpu_busy_ns).
The swapped programs: lambert's, ssss's irradiance pass, preintegrated's skin.frag (override_light_program), tsd's
pixel detail (tsd/final.frag PIXEL_DETAIL) and the shared bounce's rho E light pass (dermis.gl.interreflection).

    PYTHONPATH=$PWD/src python benchmarks/signature_ab.py SCENE.toml|head SIZE FRAMES
"""
import statistics
import sys

import numpy as np

import dermis
from dermis.bench import HEAD_TOML
from dermis.gl.shaders import program
from dermis.renderer import Renderer
from dermis.techniques.shared import SIGNATURE_DEFINES

PASS = {"lambert": "lambert", "ssss": "ssss_irradiance", "preintegrated": "preintegrated", "tsd": "tsd_final"}


def runtime(ctx, prog):
    v, f, d, _ = prog.extra["sources"]
    return program(ctx, v, f, {k: x for k, x in d.items() if k not in SIGNATURE_DEFINES})


def _rotate(d, a):
    c, s = np.cos(a), np.sin(a)
    return (c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2])


path = str(HEAD_TOML) if sys.argv[1] == "head" else sys.argv[1]
size, frames = int(sys.argv[2]), int(sys.argv[3])
sc = dermis.load_scene(path)
base = [tuple(L.direction) for L in sc.lights]
with Renderer(sc, (size, size)) as r:
    r.timer.cpu = True
    f = 0
    for tech, pname in PASS.items():
        r.render(tech)
        t = r.technique(tech)
        if tech == "tsd":
            key, = [k for k in t._programs if k[0] == "detail"]
            own = t._programs[key]
        else:
            own = t.light_programs(sc, dermis.techniques.shared.interreflection_on(sc))(len(sc.lights), sc.lights)
        bounce = r.interreflection.programs
        own_b = bounce(len(sc.lights), sc.lights)
        variants = {"signature": (own, own_b), "runtime": (runtime(r.ctx, own), runtime(r.ctx, own_b))}
        bq = "tsd_interreflection" if tech == "tsd" else "interreflection"
        res = {k: {pname: [], bq: []} for k in variants}
        for rep in range(frames + 1):
            for k, (p, pb) in variants.items():
                if tech == "tsd":
                    t._programs[key] = p
                else:
                    t.override_light_program(p)
                r.interreflection.programs = lambda n, lights=None, pb=pb: pb
                f += 1
                for L, dd in zip(sc.lights, base):
                    L.direction = _rotate(dd, 0.02 * f)
                r.render(tech)
                if rep:
                    for q in res[k]:
                        res[k][q].append(r.stats["passes_cpu_ms"].get(q, float("nan")))
        if tech == "tsd":
            t._programs[key] = own
        else:
            t.override_light_program(None)
        r.interreflection.programs = bounce
        for q in (pname, bq):
            a, b = statistics.median(res["runtime"][q]), statistics.median(res["signature"][q])
            print(f"{tech:14s} {q:16s} runtime {a:7.1f} [{min(res['runtime'][q]):.1f}-{max(res['runtime'][q]):.1f}]"
                  f"  signature {b:7.1f} [{min(res['signature'][q]):.1f}-{max(res['signature'][q]):.1f}]  ratio {b / a:.3f}",
                  flush=True)
