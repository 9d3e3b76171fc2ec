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
    PYTHONPATH=src python benchmarks/lip_exit_angle.py --head STORES --slab OUT.json

Needs bpy (the [cycles] extra). 8 x 8 px per render, about 1 s each. ``--head``: the converged
stores of side and front-key (STORES/<scene>/cycles_{mode}[_nosss]_64x64.npz, read only): per
pixel, Cycles' control / Cycles with SSS binned by the view cosine, against the flat slab's
control / random walk at that pixel's albedo and view angle (no bpy).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np


def render_slab(albedo, theta_l_deg, theta_v_deg, *, sss, anisotropy=0.0, depth_mm=300.0, spp=128, seed=0,
                scene_file="examples/reference/side.toml", method=None):
    """Mean linear radiance (3,) of the slab's centre seen from theta_v (sun at theta_l, both in the
    y-z plane, on opposite sides of the normal), for a sun of 1 W/m^2. ``method``: Cycles'
    subsurface method (default the exporter's, dermis.blender.sss.METHOD; the albedo's base_gain is
    that method's either way)."""
    import dermis
    from dermis.blender import sss as S
    from dermis.blender.render import read_render

    sc = dermis.load_scene(scene_file)
    p = S.cycles_subsurface(sc)
    base = np.clip(np.asarray(albedo, np.float64) * (p.base_gain if sss else 1.0), 0.0, 1.0)
    bpy, bsc, co = S._medium_slab_scene(base, p.radius_mm, 0.5, depth_mm * 1e-3, spp, seed, 0.004)
    b = bpy.data.materials["medium"].node_tree.nodes["Principled BSDF"]
    b.inputs["Subsurface Anisotropy"].default_value = float(anisotropy)
    if method is not None:
        b.subsurface_method = method
        for i in b.inputs:  # RANDOM_WALK_SKIN's entry index (Blender 4.x; looked up by name, not key)
            if i.name == "Subsurface IOR":
                print(f"Subsurface IOR {i.default_value:.3f} -> {S.IOR}")
                i.default_value = S.IOR
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


def slab_ratio(slab, albedo, cos_view):
    """(n, 3) the flat slab's control / random walk (anisotropy 0) at each pixel's albedo (n, 3) and
    view cosine (n,): linear in the view angle between the measured ones, then linear in albedo."""
    rows = [r for r in slab["rows"] if r["anisotropy"] == 0.0 and r["depth_mm"] == "inf"]
    names = list(ALBEDOS)
    angles = sorted({r["theta_v"] for r in rows})
    th = np.degrees(np.arccos(np.clip(cos_view, 0.0, 1.0)))
    out = np.zeros((len(th), 3))
    for c in range(3):
        a_s = np.array([ALBEDOS[nm][c] for nm in names])
        order = np.argsort(a_s)
        table = np.array([[next(r for r in rows if r["albedo"] == nm and r["theta_v"] == t)["control_over_sss"][c]
                           for t in angles] for nm in names])
        by_angle = np.array([np.interp(th, angles, table[i]) for i in order])  # (albedos, n)
        out[:, c] = [np.interp(albedo[k, c], a_s[order], by_angle[:, k]) for k in range(len(th))]
    return out


def head_by_view_angle(stores, slab):
    """Per scene and mode: Cycles' control / Cycles with SSS on the lit skin (N.L > 0.3) binned by
    N.V, on the lips and on the eyelids, measured and as the flat slab predicts it."""
    import dermis
    from dermis.blender import sss as S
    from dermis.blender.validate import _albedo_at, region_masks
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    for name in ("side", "front-key"):
        for mode in ("nospec", "spec"):
            sc = dermis.load_scene(f"examples/reference/{name}.toml")
            sc.material.pore_strength = 0.0
            with np.load(f"{stores}/{name}/cycles_{mode}_64x64.npz") as z:
                s = z["sums"] / z["spp"]
            with np.load(f"{stores}/{name}/cycles_{mode}_nosss_64x64.npz") as z:
                ctl = (z["sums"][0] / z["spp"])[..., :3].reshape(-1, 3)
            ref = (0.5 * (s[0] + s[1]))[..., :3].reshape(-1, 3)
            skin = (s[0][..., 3] >= 0.999) & (s[1][..., 3] >= 0.999)
            reg = region_masks(sc, (64, 64), skin)
            m = sc.mesh
            pos, idx = np.asarray(m.positions, np.float64), np.asarray(m.indices, np.int64).reshape(-1, 3)
            o, d, tmax, _ = camera_rays(sc, (64, 64), 1, camera=framed_camera(sc.camera, m, 1.0))
            t, tri, bc = RayCaster(pos, idx).closest_hit(o, d, 0.0, tmax)
            alb = _albedo_at(sc, tri, bc) * S.albedo_scale(sc)
            nrm, tt = np.asarray(m.normals, np.float64), np.where(tri >= 0, tri, 0)
            b1, b2 = bc[:, 0], bc[:, 1]
            N = nrm[idx[tt, 0]] * (1 - b1 - b2)[:, None] + nrm[idx[tt, 1]] * b1[:, None] + nrm[idx[tt, 2]] * b2[:, None]
            N /= np.linalg.norm(N, axis=1, keepdims=True)
            L = -np.asarray(sc.lights[0].direction, np.float64)
            cl, cv = N @ (L / np.linalg.norm(L)), -(N * d).sum(axis=1)
            lit = skin.ravel() & (cl > 0.3) & (cv > 0.35)
            pred = slab_ratio(slab, alb, cv)
            print(f"{name}/{mode}: control / Cycles with SSS, measured | flat slab (sum over the pixels)")
            groups = [(f"lit skin N.V [{lo:.2f}, {hi:.2f})", lit & (cv >= lo) & (cv < hi))
                      for lo, hi in ((0.35, 0.7), (0.7, 0.85), (0.85, 0.95), (0.95, 1.01))]
            groups += [("lips", lit & reg["lips"].ravel()), ("eyelids", lit & reg["eyelids"].ravel())]
            for label, k in groups:
                meas = ctl[k].sum(0) / ref[k].sum(0)
                prd = ctl[k].sum(0) / (ctl[k] / pred[k]).sum(0)
                print(f"  {label:28s} n={k.sum():4d}  {' '.join(f'{x:.3f}' for x in meas)} | "
                      f"{' '.join(f'{x:.3f}' for x in prd)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--json", default=None)
    ap.add_argument("--head", default=None, help="folder of the converged Cycles stores (read only)")
    ap.add_argument("--slab", default=None, help="this script's --json output, for --head")
    ap.add_argument("--methods", nargs="+", default=None,
                    help="only: random walk / control at the skin's mean albedo per Cycles subsurface method "
                         "(e.g. RANDOM_WALK RANDOM_WALK_SKIN; round 22, green22)")
    a = ap.parse_args(argv)
    if a.head:
        with open(a.slab) as f:
            head_by_view_angle(a.head, json.load(f))
        return
    if a.methods:
        for method in a.methods:
            for theta_v in (0.0, 28.0, 50.0, 70.0):
                s = render_slab(ALBEDOS["skin mean"], 35.0, theta_v, sss=True, spp=a.spp, method=method)
                c = render_slab(ALBEDOS["skin mean"], 35.0, theta_v, sss=False, spp=a.spp, method=method)
                print(f"{method:17s} view {theta_v:4.0f} deg: random walk / control {' '.join(f'{x:.3f}' for x in s / c)}",
                      flush=True)
        return
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
