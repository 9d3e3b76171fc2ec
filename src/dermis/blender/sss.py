"""dermis's diffusion profile -> Cycles' random-walk subsurface scattering, measured not guessed.

Cycles' random walk (Principled BSDF, method RANDOM_WALK, anisotropy 0, IOR 1.4) is a volume whose
mean free path per channel is ``radius``; the albedo is inverted so that the total diffuse
reflectance is the base colour. Its response therefore has a shape that depends on the albedo A
and a width proportional to the radius r (the medium is scale invariant): the EDGE response of a
flat semi-infinite slab lit on x > 0 and in a hard shadow on x < 0 is e(x / r; A).

dermis's profile is a sum of Gaussians R(d) = sum_i w_i exp(-d^2 / 2 v_i) / (2 pi v_i), whose edge
response is closed form: E(x) = sum_i w_i Phi(x / sqrt(v_i)) / sum_i w_i (each 2-D Gaussian's 1-D
marginal is a Gaussian of the same variance).

``data/cycles_edge_response.json`` holds e(x; A) MEASURED with Cycles through bpy (``python -m
dermis.blender.sss --measure``: an orthographic camera over a 100 x 100 x 50 mm slab of radius
1 mm, 8 mm wide at 320 px, a sun straight down, a camera-invisible occluder casting the edge; rows averaged). For a
profile channel with albedo A_c the radius is the least-squares scale r_c minimising
int (e(x / r_c; A_c) - E_c(x))^2 dx over |x| <= 4 sigma_max; the residual reported is the RMS
difference at that optimum (edge responses run 0..1, so 0.01 = 1% of the edge's height).

Physical profiles: a profile computed from absorption/scattering coefficients (the presets fair,
asian, dark and [skin] physical parameters: layered photon-beam diffusion, dermis.profiles) reaches
Cycles only through the same fit. Cycles' random walk takes ONE homogeneous medium per channel: its
single-scattering albedo is derived from the base colour (here the profile's total reflectance,
skin_color = "profile") and its extinction from the radius, so the epidermis/dermis layering,
melanin's absorption in a thin top layer and the layers' separate scattering coefficients cannot
be passed on; they survive only as the fitted width and the total reflectance. The cost is the
fit's residual: with the shipped table, deon 0.009/0.008/0.008 (R/G/B), fair 0.010/0.009/0.008,
asian 0.019/0.015/0.022, dark 0.016/0.022/0.035 - dark skin reflects 1-3%, below the table's
lowest base colour (0.05), where Cycles' edge has a sharper corner than a sum of Gaussians.

Exit radiance: the random walk's exit is not Lambertian (head-on it is 0.77-0.94 of its total
reflectance / pi, brighter at grazing angles; ``normal_view_reflectance`` in the table), while
dermis's diffuse is. The base colour is matched on the HEMISPHERICAL total reflectance
(``total_reflectance``, measure_total_reflectance), which for Cycles' albedo inversion is within
1-2% of the base colour below 0.9; the angular difference is left visible as a model difference.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.scene import model

TABLE = Path(__file__).resolve().parents[1] / "data" / "cycles_edge_response.json"
METHOD = "RANDOM_WALK"
IOR = 1.4
ANISOTROPY = 0.0


@dataclass
class CyclesSubsurface:
    radius_mm: np.ndarray  # (3,) Subsurface Radius per channel, mm
    albedo: np.ndarray  # (3,) the albedo the fit assumed (mean skin albedo)
    base_gain: np.ndarray  # (3,) base colour multiplier so Cycles' total reflectance = the albedo
    residual: np.ndarray  # (3,) RMS edge-response difference at the fitted radius
    method: str = METHOD
    ior: float = IOR
    anisotropy: float = ANISOTROPY


def dermis_edge_response(profile, x_mm) -> np.ndarray:
    """(len(x), 3) edge response of the sum of Gaussians (lit for x > 0), closed form."""
    from scipy.special import ndtr

    x = np.asarray(x_mm, np.float64)[:, None, None]
    s = np.sqrt(np.asarray(profile.variances_mm2, np.float64))[None, :, None]
    w = np.asarray(profile.weights, np.float64)[None]
    return (w * ndtr(x / s)).sum(axis=1) / np.maximum(w.sum(axis=1), 1e-300)


@lru_cache(maxsize=1)
def load_table(path: str = str(TABLE)):
    """(x_mm (n,), albedos (k,), e (k, n)) of the measured Cycles edge responses at radius 1 mm."""
    p = Path(path)
    if not p.is_file():
        raise DermisError(f"{p}: the measured Cycles edge-response table is missing (python -m dermis.blender.sss --measure)")
    d = json.loads(p.read_text())
    x = np.asarray(d["x_mm"], np.float64)
    a = np.asarray(d["albedos"], np.float64)
    e = np.asarray(d["edge"], np.float64)
    return x, a, e


def base_color_gain(albedo, path: str = str(TABLE)) -> np.ndarray:
    """Per channel, base colour / measured total diffuse reflectance of Cycles' random walk at
    that base colour (the table's lit plateau x pi): the boundary's Fresnel (IOR 1.4) makes the
    walk reflect less than its base colour, so the exporter scales the base colour by this to
    keep dermis's total reflectance (the skin's colour)."""
    d = json.loads(Path(path).read_text())
    a = np.asarray(d["albedos"], np.float64)
    r = np.asarray(d["total_reflectance"], np.float64)
    al = np.clip(np.asarray(albedo, np.float64), a[0], a[-1])
    return al / np.interp(al, a, r)


def cycles_edge_response(x_over_r, albedo, table=None) -> np.ndarray:
    """e(x / r; A) from the table: linear in albedo, linear in x, 0/1 beyond the measured window."""
    x, a, e = table or load_table()
    albedo = float(np.clip(albedo, a[0], a[-1]))
    j = int(np.clip(np.searchsorted(a, albedo) - 1, 0, len(a) - 2))
    t = (albedo - a[j]) / (a[j + 1] - a[j])
    curve = (1 - t) * e[j] + t * e[j + 1]
    return np.interp(x_over_r, x, curve, left=0.0, right=1.0)


def fit_channel(profile, channel: int, albedo: float, table=None) -> tuple[float, float]:
    """(radius_mm, rms residual) for one channel of ``profile``."""
    from scipy.optimize import minimize_scalar

    sig_max = float(np.sqrt(np.max(profile.variances_mm2)))
    xs = np.linspace(-4 * sig_max, 4 * sig_max, 801)
    target = dermis_edge_response(profile, xs)[:, channel]

    def err(log_r):
        return float(np.mean((cycles_edge_response(xs / math.exp(log_r), albedo, table) - target) ** 2))

    # the edge's 25-75% width brackets the scale; then a bounded 1-D search in log r
    res = minimize_scalar(err, bounds=(math.log(sig_max * 1e-3), math.log(sig_max * 20)), method="bounded",
                          options={"xatol": 1e-5})
    grid = np.linspace(math.log(sig_max * 1e-3), math.log(sig_max * 20), 200)
    best = grid[np.argmin([err(g) for g in grid])]
    if err(best) < res.fun:  # the bounded search can stop in a local minimum; the grid guards it
        res = minimize_scalar(err, bounds=(best - 0.05, best + 0.05), method="bounded", options={"xatol": 1e-6})
    return math.exp(res.x), math.sqrt(res.fun)


def mean_skin_albedo(scene) -> np.ndarray:
    """The colour Cycles' base colour carries on average (dermis.scene.model.mean_skin_albedo)."""
    return model.mean_skin_albedo(scene.material)


def albedo_scale(scene) -> np.ndarray:
    """As the renderer's uAlbedoScale (dermis.scene.model.skin_albedo_scale)."""
    return model.skin_albedo_scale(scene)


def cycles_subsurface(scene, table=None) -> CyclesSubsurface:
    albedo = np.clip(mean_skin_albedo(scene) * albedo_scale(scene), 0.0, 1.0)
    gain = base_color_gain(albedo)
    base = np.clip(albedo * gain, 0.0, 1.0)  # the base colour Cycles sees; the table is indexed by it
    r, res = np.zeros(3), np.zeros(3)
    for c in range(3):
        r[c], res[c] = fit_channel(scene.profile, c, base[c], table)
    return CyclesSubsurface(radius_mm=r, albedo=albedo, base_gain=gain, residual=res)


# ----------------------------------------------------------------------------- measurement (bpy)

def _medium_slab_scene(albedos_rgb, radius_mm, half_side_m, depth_m, spp, seed, ortho_scale_m):
    """A fresh Blender scene: a slab (top face z = 0) of the random-walk medium, a sun of 1 W/m^2
    straight down, an orthographic camera, a black world. Returns (bpy, scene, camera object)."""
    from dermis.blender import quiet_fds, require_bpy

    bpy = require_bpy()
    with quiet_fds():
        bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, -depth_m / 2))
    slab = bpy.context.object
    slab.scale = (2 * half_side_m, 2 * half_side_m, depth_m)
    mat = bpy.data.materials.new("medium")
    mat.use_nodes = True
    b = mat.node_tree.nodes.get("Principled BSDF")
    b.inputs["Base Color"].default_value = (*[float(a) for a in albedos_rgb], 1.0)
    b.subsurface_method = METHOD
    b.inputs["Subsurface Weight"].default_value = 1.0
    b.inputs["Subsurface Radius"].default_value = tuple(float(r) for r in radius_mm)
    b.inputs["Subsurface Scale"].default_value = 1e-3
    b.inputs["IOR"].default_value = IOR
    b.inputs["Subsurface Anisotropy"].default_value = ANISOTROPY
    b.inputs["Specular IOR Level"].default_value = 0.0
    slab.data.materials.append(mat)
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy, sun.angle = 1.0, 0.0
    sc.collection.objects.link(bpy.data.objects.new("sun", sun))
    cam = bpy.data.cameras.new("cam")
    cam.type = "ORTHO"
    cam.ortho_scale = ortho_scale_m
    cam.sensor_fit = "HORIZONTAL"
    cam.clip_start, cam.clip_end = 1e-3, 4.0
    co = bpy.data.objects.new("cam", cam)
    sc.collection.objects.link(co)
    sc.camera = co
    sc.world = bpy.data.worlds.new("black")
    sc.world.color = (0, 0, 0)
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples, sc.cycles.seed, sc.cycles.use_denoising = spp, seed, False
    sc.cycles.max_bounces = 12
    sc.cycles.sample_clamp_direct = sc.cycles.sample_clamp_indirect = 0.0
    return bpy, sc, co


def measure_edge_response(albedos_rgb, *, half_width_mm=4.0, px=320, rows=16, spp=128, seed=0,
                          radius_mm=(1.0, 1.0, 1.0)):
    """Render Cycles' edge response at ``radius_mm`` (per channel) for three base colours at once.
    Returns (x_mm (px,), e (3, px)) normalised by the lit plateau, and the plateau / (E / pi)
    (the head-on reflectance; the total is measure_total_reflectance's)."""
    from dermis.blender.render import read_render

    side = max(0.1, 0.02 * max(radius_mm))  # >= 20 radii wide and 10 deep: semi-infinite
    bpy, sc, co = _medium_slab_scene(albedos_rgb, radius_mm, side / 2, side / 2, spp, seed, 2 * half_width_mm * 1e-3)
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-side, 0, 0.01))
    occ = bpy.context.object
    occ.scale = (2 * side, 2 * side, 1)  # covers x < 0 at z = 10 mm
    occ.visible_camera = occ.visible_diffuse = occ.visible_glossy = occ.visible_transmission = False
    co.location = (0, 0, 0.05)
    sc.render.resolution_x, sc.render.resolution_y = px, rows
    sc.render.filter_size = 0.01  # no pixel filter: each column is its own x
    img = read_render(bpy)
    prof = img.mean(axis=0).T  # (3, px)
    x = (np.arange(px) + 0.5) / px * 2 * half_width_mm - half_width_mm
    plateau = prof[:, x > 0.8 * half_width_mm].mean(axis=1)
    return x, prof / plateau[:, None], plateau * math.pi


def measure_total_reflectance(albedos_rgb, *, n_angles=8, px=8, spp=256, seed=0):
    """Cycles' total diffuse reflectance of a lit semi-infinite slab for three base colours: the
    exit radiance L(theta) seen by an orthographic camera at n_angles Gauss-Legendre view angles,
    integrated over the hemisphere, R = 2 pi int L cos sin dtheta / E (E = 1 W/m^2 from a sun
    straight down). The random walk's exit radiance is not Lambertian (at normal view it is about
    0.8 of R / pi), so a base-colour correction from the normal view alone would over-brighten
    every oblique view."""
    from dermis.blender.render import read_render

    mu, wts = np.polynomial.legendre.leggauss(n_angles)
    mu = 0.5 * (mu + 1.0)  # cos(theta) in (0, 1)
    wts = 0.5 * wts
    bpy, sc, co = _medium_slab_scene(albedos_rgb, (1.0, 1.0, 1.0), 2.0, 0.4, spp, seed, 0.01)
    sc.render.resolution_x = sc.render.resolution_y = px
    L = []
    for c in mu:
        th = math.acos(c)
        co.rotation_euler = (th, 0.0, 0.0)  # tilt about x: looks at the slab's centre from theta
        co.location = (0.0, -0.5 * math.sin(th), 0.5 * c)
        L.append(read_render(bpy).reshape(-1, 3).mean(axis=0))
    L = np.asarray(L)  # (n, 3)
    return 2 * math.pi * (wts[:, None] * mu[:, None] * L).sum(axis=0), mu, L


def _write_table(path, d: dict):
    """One line per field and per measured edge (a reviewable diff when re-measured)."""
    rows = []
    for k, v in d.items():
        if k == "edge":
            rows.append(f'"edge": [\n' + ",\n".join("  " + json.dumps(r, separators=(",", ":")) for r in v) + "\n]")
        else:
            rows.append(f"{json.dumps(k)}: {json.dumps(v, separators=(',', ':'))}")
    Path(path).write_text("{\n" + ",\n".join(rows) + "\n}\n")


def main(argv=None):
    import argparse
    import time

    ap = argparse.ArgumentParser(description="Measure Cycles' random-walk edge responses into the shipped table.")
    ap.add_argument("--measure", action="store_true")
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--px", type=int, default=320)
    ap.add_argument("--out", default=str(TABLE))
    ap.add_argument("--reflectance-only", action="store_true", help="Re-measure only the total reflectance column.")
    a = ap.parse_args(argv)
    if not a.measure:
        ap.print_help()
        return
    albedos = np.array([0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95])
    edges, refl, normal = {}, {}, {}
    t0 = time.time()
    if a.reflectance_only:
        old = json.loads(Path(a.out).read_text())
        x = np.asarray(old["x_mm"])
        edges = {k: np.asarray(e) for k, e in zip(old["albedos"], old["edge"])}
        normal = dict(zip(old["albedos"], old.get("normal_view_reflectance", old["total_reflectance"])))
    for k in range(0, len(albedos), 3):
        trio = albedos[k:k + 3]
        if not a.reflectance_only:
            x, e, r0 = measure_edge_response(trio, px=a.px, spp=a.spp)
        r, _, _ = measure_total_reflectance(trio)
        for c, al in enumerate(trio):
            if not a.reflectance_only:
                edges[float(al)] = e[c]
                normal[float(al)] = float(r0[c])
            refl[float(al)] = float(r[c])
        print(f"albedos {trio}: total reflectance {r} ({time.time() - t0:.0f} s)", flush=True)
    keys = sorted(edges)
    _write_table(a.out, {
        "what": "Cycles random-walk edge response e(x; A) at Subsurface Radius 1 mm (lit for x > 0), "
                "normalised by the lit plateau; measured by python -m dermis.blender.sss --measure",
        "method": METHOD, "ior": IOR, "anisotropy": ANISOTROPY, "spp": a.spp, "px": a.px,
        "x_mm": [round(float(v), 5) for v in x], "albedos": keys,
        "total_reflectance": [refl[k] for k in keys],
        "total_reflectance_what": "hemispherical: exit radiance at 8 Gauss-Legendre view angles integrated",
        "normal_view_reflectance": [normal[k] for k in keys],
        "edge": [[round(float(v), 5) for v in edges[k]] for k in keys]})
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
