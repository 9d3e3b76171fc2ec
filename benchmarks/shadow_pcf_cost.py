"""What the soft-shadow lookups (common/shadow.glsl) cost in tsd's texture-space irradiance pass on
the head: the shadow code of a given commit vs the working tree's, no shadow, and one sharp tap
per light, timed in one process (alternating, median of REPEATS) at 512^2 and 1024^2: wall time
and the process's CPU time (all llvmpipe threads; less disturbed by other jobs on a loaded machine).

    PYTHONPATH=src python benchmarks/shadow_pcf_cost.py [COMMIT]   (default d7c6e97, round 4)
"""
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import dermis
import dermis.gl.shaders as shaders
from dermis.bench import HEAD_TOML
from dermis.renderer import Renderer
from dermis.techniques.base import bind_scene
from dermis.techniques.shared import MAX_GAUSSIANS

REPEATS = 5
commit = sys.argv[1] if len(sys.argv) > 1 else "d7c6e97"
old = subprocess.run(["git", "show", f"{commit}:src/dermis/shaders/common/shadow.glsl"], capture_output=True,
                     text=True, check=True, cwd=Path(__file__).resolve().parent.parent).stdout


def sources(shader_dir):
    keep = shaders.SHADER_DIR
    shaders.SHADER_DIR = shader_dir
    try:
        defs = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
        return shaders.load_shader_source("tsd/uv_space.vert", defs), shaders.load_shader_source("tsd/irradiance.frag", defs)
    finally:
        shaders.SHADER_DIR = keep


with tempfile.TemporaryDirectory() as d:
    old_dir = Path(d) / "shaders"
    shutil.copytree(shaders.SHADER_DIR, old_dir)
    (old_dir / "common" / "shadow.glsl").write_text(old)
    vs, fs_old = sources(old_dir)
vs, fs = sources(shaders.SHADER_DIR)
variants = {f"shadow.glsl of {commit}": fs_old, "working tree": fs,
            "no shadow": fs.replace("shadow_soft(i, P, Ng)", "1.0"),
            "one sharp tap": fs.replace("shadow_soft(i, P, Ng)", "shadow_sharp(i, P, Ng)")}
sc = dermis.load_scene(HEAD_TOML)
for S in (512, 1024):
    with Renderer(sc, (64, 64), irradiance_size=S) as r:
        r.render("tsd")
        t = r.technique("tsd")
        frame, ctx = r.last_frame, r.ctx
        progs = {k: ctx.program(vertex_shader=vs, fragment_shader=f) for k, f in variants.items()}
        out = t._texture("irradiance", (S, S))
        res, cpu = {}, {}
        for _ in range(REPEATS):
            for k, p in progs.items():
                bind_scene(frame, p)
                t._uv_pass(frame, p, out)
                ctx.finish()
                t0, c0 = time.perf_counter(), time.process_time()
                t._uv_pass(frame, p, out)
                ctx.finish()
                res.setdefault(k, []).append((time.perf_counter() - t0) * 1e3)
                cpu.setdefault(k, []).append((time.process_time() - c0) * 1e3)
        print(f"irradiance {S}^2, load {os.getloadavg()[0]:.1f}:",
              ", ".join(f"{k} {statistics.median(v):.0f} ms (CPU {statistics.median(cpu[k]):.0f})"
                        for k, v in res.items()), flush=True)
        for p in progs.values():
            p.release()
