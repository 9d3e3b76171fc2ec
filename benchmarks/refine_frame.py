"""The viewer's refine frame after a light drag, in one process: the full-quality frame (960x640,
4x MSAA, the head's adaptive 1024^2 irradiance and 2048^2 shadow tiles) after the key light turned,
with the blur chain as round 3 left it (four 1-D passes for I_1 and I_2, I_4 at level 0, taps to
3 sigma) and as it is now, interleaved, REPS rounds, medians of the frame and of its passes.

    PYTHONPATH=src python benchmarks/refine_frame.py
"""
import json, os, statistics, time

import numpy as np

import dermis
import dermis.techniques.tsd as T
from dermis.bench import HEAD_TOML
from dermis.renderer import Renderer

ROUND3 = {"NARROW_PASS": False, "LEVEL_LIGHT_WEIGHT": 0.0, "TAP_REACH_SIGMAS": 3.0}
NOW = {k: getattr(T, k) for k in ROUND3}
W, H = int(os.environ.get("W", 960)), int(os.environ.get("H", 640))
sc = dermis.load_scene(HEAD_TOML)
res = {"round 3 chain": [], "this chain": []}
passes = {k: {} for k in res}
load0 = os.getloadavg()[0]
with Renderer(sc, (W, H), irradiance_size=1024, shadow_size=2048) as r:
    r.render("tsd")
    angle = 0.0
    for rep in range(int(os.environ.get("REPS", 4))):
        for name, consts in (("round 3 chain", ROUND3), ("this chain", NOW)):
            for k, v in consts.items():
                setattr(T, k, v)
            L = sc.lights[0]
            d = np.asarray(L.direction, float)
            angle = 0.03 if angle <= 0 else -0.03  # a light drag step: every pass before the final re-runs
            c, s = np.cos(angle), np.sin(angle)
            L.direction = tuple(np.array([c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]]))
            r.render("tsd")  # the first frame after a switch compiles / re-plans: not counted
            L.direction = tuple(d)
            t0 = time.perf_counter()
            r.render("tsd")
            r.ctx.finish()
            res[name].append((time.perf_counter() - t0) * 1e3)
            for p, ms in r.stats["passes_ms"].items():
                passes[name].setdefault(p, []).append(ms)
print(json.dumps({"size": [W, H], "load": [round(load0, 2), round(os.getloadavg()[0], 2)],
                  **{k: {"frame_ms": round(statistics.median(v)), **{p: round(statistics.median(x)) for p, x in passes[k].items()}}
                     for k, v in res.items()}}, indent=1))
