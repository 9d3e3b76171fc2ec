"""Why Cycles' lips are darker than its own diffuse control (issue 12, round 7, thin7).

A flat slab of the reference scenes' Cycles medium (dermis.blender.sss.cycles_subsurface: random
walk, the fitted radius per channel, IOR 1.4) lit by a sun, seen by an orthographic camera at a
view angle theta_v; beside it the same slab as Cycles' plain diffuse (the validate control).
Printed: control / random walk per channel (what validate's lips show: 1.11-1.15 in G and B) and
the random walk's radiance over the Lambertian A E cos / pi, for the skin's mean albedo and the
lips' albedo, at several view angles, for the exporter's anisotropy (0) and for a skin-like
forward-scattering one (0.8; Cycles re-inverts the albedo for it), and for a slab as thick as
the lower lip in front of the mouth cavity (10 mm) against a semi-infinite one.

    PYTHONPATH=src /path/to/bpy-venv/python benchmarks/lip_exit_angle.py [--spp 128] [--json OUT]

Needs bpy (the [cycles] extra). 8 x 8 px per render, about 1 s each.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np


def render_slab(albedo, theta_l_deg, theta_v_deg, *, sss, anisotropy=0.0, depth_mm=300.0, spp=128, seed=0,
                scene_file="examples/reference/side.toml"):
    """Mean linear radiance (3,) of the slab's centre seen from theta_v (sun at theta_l, both in the
    y-z plane, on opposite sides of the normal), for a sun of 1 W/m^2."""
    import dermis
    from dermis.blender import sss as S
    from dermis.blender.render import read_render

    sc = dermis.load_scene(scene_file)
    p = S.cycles_subsurface(sc)
    base = np.clip(np.asarray(albedo, np.float64) * (p.base_gain if sss else 1.0), 0.0, 1.0)
    bpy, bsc, co = S._medium_slab_scene(base, p.radius_mm, 0.5, depth_mm * 1e-3, spp, seed, 0.004)
    b = bpy.data.materials["medium"].node_tree.nodes["Principled BSDF"]
    b.inputs["Subsurface Anisotropy"].default_value = float(anisotropy)
    if not sss:
        b.inputs["Subsurface Weight"].default_value = 0.0
    bpy.data.objects["sun"].rotation_euler = (math.radians(theta_l_deg), 0.0, 0.0)
    th = math.radians(theta_v_deg)
    co.rotation_euler = (-th, 0.0, 0.0)
    co.location = (0.0, 0.5 * math.sin(th), 0.5 * math.cos(th))
    bsc.render.resolution_x = bsc.render.resolution_y = 8
    bsc.cycles.use_adaptive_sampling = False
    return read_render(bpy).reshape(-1, 3).mean(axis=0).astype(np.float64)


ALBEDOS = {"skin mean": (0.617, 0.348, 0.288), "lips": (0.531, 0.238, 0.211), "lips darkest": (0.42, 0.14, 0.13)}
"""Linear albedo x the scene's albedo scale: the skin pixels' mean, validate's lips region mean, and
the lips' darkest band (front-key/side 64 x 64 pixels, Map-COL.jpg)."""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    t0 = time.time()
    rows = []
    theta_l = 35.0  # front-key's light on the lips: cos 0.82
    for aniso in (0.0, 0.8):
        for name, alb in ALBEDOS.items():
            for theta_v in (0.0, 28.0, 50.0, 70.0):
                s = render_slab(alb, theta_l, theta_v, sss=True, anisotropy=aniso, spp=a.spp)
                c = render_slab(alb, theta_l, theta_v, sss=False, spp=a.spp)
                lam = np.asarray(alb) * math.cos(math.radians(theta_l)) / math.pi
                rows.append({"anisotropy": aniso, "albedo": name, "theta_v": theta_v, "depth_mm": "inf",
                             "control_over_sss": (c / s).tolist(), "sss_over_lambert": (s / lam).tolist()})
                print(f"g {aniso:.1f} {name:12s} view {theta_v:4.0f} deg: control/random walk "
                      f"{' '.join(f'{x:.3f}' for x in c / s)}   random walk / Lambertian "
                      f"{' '.join(f'{x:.3f}' for x in s / lam)}  ({time.time() - t0:.0f} s)", flush=True)
    for depth in (10.0, 300.0):  # the lower lip's shell in front of the mouth cavity vs semi-infinite
        s = render_slab(ALBEDOS["lips"], theta_l, 28.0, sss=True, depth_mm=depth, spp=a.spp)
        lam = np.asarray(ALBEDOS["lips"]) * math.cos(math.radians(theta_l)) / math.pi
        rows.append({"anisotropy": 0.0, "albedo": "lips", "theta_v": 28.0, "depth_mm": depth,
                     "sss_over_lambert": (s / lam).tolist()})
        print(f"slab {depth:5.0f} mm deep, lips, view 28 deg: random walk / Lambertian "
              f"{' '.join(f'{x:.3f}' for x in s / lam)}", flush=True)
    out = {"spp": a.spp, "theta_l_deg": theta_l, "load": os.getloadavg()[0], "rows": rows}
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
