"""Back-lit ear (examples/reference/back-ears.toml): red radiance over the ear and a crop of it.

The ear mask comes from the mesh: the head's ears are the vertices farthest from the midline in x (above the scan's shoulders);
the triangles whose three vertices are ear vertices, projected with the frame's camera, cover the
mask (no depth test: in this view the ear is on the camera's side and nothing hides it).

    PYTHONPATH=src python benchmarks/ear_translucency.py OUT_PREFIX [technique ...]
prints per technique: mean linear red (and green, blue) radiance over the ear mask, and writes
OUT_PREFIX_<technique>.png (sRGB, the scene's output transform) and OUT_PREFIX_<technique>_ear.png.

    PYTHONPATH=src python benchmarks/ear_translucency.py --reference N [technique ...]
renders the offline reference (dermis.reference, paths = "tissue": the profile integrated over
the surface at 3-D distance, light through thin tissue included; about 30 s at N = 160 on 2 cores)
and the techniques at N x N and prints the ear's mean radiance of each against it.

    PYTHONPATH=src python benchmarks/ear_translucency.py --cycles-store STORE.npz [technique ...]
the back-lit-ear region's FLIP and mean ratio R/G/B per technique (as `dermis validate --against
cycles`) against a stored Cycles accumulation (validate's cycles_spec_WxH.npz), without bpy.

    PYTHONPATH=src python benchmarks/ear_translucency.py --boundary
what a thin slab does that the semi-infinite profile and the thin-slab law do not (issue 12, round 7),
red and green, MCML of the profile's medium (index 1.4, the skin walk) pencil-lit at the centre:
the lit face's reflectance and its radial spread, the far face's transmittance and its radial spread
(per-axis variance, mm^2) against the law's T(d) and the wide Gaussians' variance that tsd spreads
the far face's light with; the skin walk's reflectance for an oblique beam; then, with the same total
reflectance and the same mean exit radius (the same semi-infinite profile to first order), an
index-matched walk (index 1.0) entered along the normal, and Cycles' own walk (index-matched, entered
along a cosine-distributed direction, and along the normal as a head-on view sees it: _cycles_walk).
About 6 min on 2 cores.

    PYTHONPATH=src python benchmarks/ear_translucency.py --cycles-view
Cycles' walk's dependence on the view angle (it starts along the refracted view ray), red. About 1 min.

    PYTHONPATH=src python benchmarks/ear_translucency.py --walk [WALKS] [CHANNELS]
the back-lit ear's ground truth in the head's own geometry (round 9): dermis.reference.random_walk
inside the mesh (mm), from the back-ears camera, direct light (the scene's directional light with
shadow rays, its environment colour with visibility; no interreflection), for the skin walk (index
1.4, Fresnel faces, the thin-slab law's medium) and Cycles' walk (index-matched, Lambertian gather,
entered along the refracted view ray and cosine-distributed; the medium of ear7's fit), per pixel of
validate's back_lit_ear region at 64 x 64 (rays at 4x, Cycles' pixel filter), against the converged
Cycles store without specular and tsd (rho_s 0, supersampled as validate), in translucency-share
groups. WALKS per supersample ray (default 16), CHANNELS e.g. "0" or "01"; --bounce adds one bounce of
interreflection (the surface a leaving ray meets sends back its direct diffuse light); --paths runs the
skin walk alone and prints where its light entered per group; --exhaustive runs the skin walk alone with
the light's source summed over every facet within 4 mm (nee="exhaustive", the search's check; slow). The
per-pixel arrays go to /tmp/dermis_ear_walk[_bounce].npz. Heavy: run with nice.

    PYTHONPATH=src python benchmarks/ear_translucency.py --slab [--cycles]
the theory behind light through thin parts (issue 12): per channel, through a back-lit slab
d = 0.5..5 mm thick, the renderers' thin-slab law (dermis.profiles.thin_slab) and d'Eon's
A sum_k w_k exp(-d^2 / 2 v_k) (A the scene's mean albedo) against MCML (dermis.profiles.monte_carlo)
of the medium the profile describes (mean free path 1 / sigma_t' from the law's fit to the
profile's mean radius; single-scattering albedo solved so that the semi-infinite medium reflects
A); with --cycles also Cycles' random walk on the same slab (bpy). About 90 s on 2 cores.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import dermis
from dermis.output import output_transform
from dermis.renderer import Renderer

SCENE = Path(__file__).resolve().parent.parent / "examples" / "reference" / "back-ears.toml"
EAR_FRACTION = 0.85  # x - midline beyond this fraction of the largest (above the shoulders): the ear


def ear_mask(mesh, viewproj, size):
    p = np.asarray(mesh.positions, np.float64)
    upper = p[:, 1] > 0.5 * (p[:, 1].min() + p[:, 1].max())  # the head, not the shoulders of the scan
    mid = 0.5 * (p[upper, 0].min() + p[upper, 0].max())
    off = np.where(upper, p[:, 0] - mid, -np.inf)
    ear = off > EAR_FRACTION * off.max()  # the +x ear (the camera's side)
    tri = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    tri = tri[ear[tri].all(1)]
    # the scan's coarse cranium triangles beside the ear (the ear is finely meshed)
    edge = np.linalg.norm(p[tri] - p[np.roll(tri, 1, axis=1)], axis=2).max(1)
    tri = tri[edge < 4.0 * np.median(edge)]
    h = np.c_[p, np.ones(len(p))] @ np.asarray(viewproj, np.float64).T
    ndc = h[:, :2] / h[:, 3:]
    W, H = size
    xy = np.stack([(ndc[:, 0] * 0.5 + 0.5) * W, (0.5 - ndc[:, 1] * 0.5) * H], 1)
    from dermis.geometry.rasterize import rasterize_uv

    uv = np.stack([xy[:, 0] / W, 1.0 - xy[:, 1] / H], 1)  # rasterize_uv: v = 0 at the bottom row
    t, _ = rasterize_uv(uv, tri, W, H)
    return t >= 0


def main(prefix, techniques):
    from PIL import Image

    sc = dermis.load_scene(SCENE)
    size = (512, 512)
    with Renderer(sc, size, irradiance_size=1024) as r:
        for tech in techniques:
            img = r.render(tech)
            mask = ear_mask(sc.mesh, r.last_frame.viewproj, size)
            m = img[mask].mean(0)
            print(f"{tech}: ear pixels {int(mask.sum())}, mean linear radiance r {m[0]:.4f} g {m[1]:.4f} b {m[2]:.4f}")
            srgb = output_transform(img, sc.output.exposure, sc.output.tonemap)
            u8 = (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)
            Image.fromarray(u8).save(f"{prefix}_{tech}.png")
            ys, xs = np.nonzero(mask)
            y0, y1, x0, x1 = max(ys.min() - 20, 0), ys.max() + 20, max(xs.min() - 20, 0), xs.max() + 20
            Image.fromarray(u8[y0:y1, x0:x1]).resize(((x1 - x0) * 2, (y1 - y0) * 2), Image.NEAREST).save(
                f"{prefix}_{tech}_ear.png")


def against_reference(n, techniques):
    from dermis.reference.render import render_reference

    sc = dermis.load_scene(SCENE)
    ref = render_reference(sc, (n, n), spp=1, progress=False, paths="tissue").image
    with Renderer(sc, (n, n), irradiance_size=1024) as r:
        for tech in techniques:
            for translucency in ((True,) if tech == "lambert" else (True, False)):
                if tech != "lambert":
                    r.technique(tech, translucency=translucency)
                img = r.render(tech)
                m = ear_mask(sc.mesh, r.last_frame.viewproj, (n, n))
                a, b = img[m].mean(0), ref[m].mean(0)
                print(f"{tech} (translucency {'on' if translucency else 'off'}): ear {int(m.sum())} px, "
                      f"r {a[0]:.4f} g {a[1]:.4f} b {a[2]:.4f}; reference r {b[0]:.4f} g {b[1]:.4f} b {b[2]:.4f}; "
                      f"ratio r {a[0] / b[0]:.3f} g {a[1] / b[1]:.3f}")


def slab_theory(cycles: bool = False):
    from dermis.profiles.thin_slab import slab_law
    from dermis.scene.model import mean_skin_albedo
    from dermis.techniques.shared import TRANSLUCENCY_MIN_VARIANCE_MM2
    from dermis.verification import backlit_slab_scene, random_walk_slab

    sc = dermis.load_scene(SCENE)
    albedo = mean_skin_albedo(sc.material)
    prof = sc.profile.normalized()
    w, v = prof.weights, prof.variances_mm2
    wide = v >= TRANSLUCENCY_MIN_VARIANCE_MM2
    law = slab_law(prof, albedo)
    ds = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0)
    cyc = {}
    if cycles:  # Cycles' random walk (the validation's medium) on the same back-lit slab, head-on
        from dermis.blender.render import render_cycles

        for d in ds:
            s = backlit_slab_scene(d, albedo=tuple(albedo))
            s.profile = sc.profile
            img, _ = render_cycles(s, (32, 32), spp=256, seed=0, specular=False)
            cyc[d] = img[12:20, 12:20].reshape(-1, 3).mean(0)  # radiance x pi / E, E = pi
    for c, name in enumerate("RGB"):
        A, mfp = albedo[c], 1.0 / law.reduced_sigma_t_per_mm[c]
        alpha, semi = random_walk_slab(A, mfp, np.inf, photons=200_000)
        print(f"{name}: albedo {A:.3f}; the profile's medium: mean free path {mfp:.3f} mm, alpha' (diffusion) "
              f"{law.reduced_albedo[c]:.4f}, single-scattering albedo (MC) {alpha:.6f} "
              f"(MC R {semi.total_reflectance:.4f})")
        for d in ds:
            res = random_walk_slab(A, mfp, d)[1]
            tg = A * (w[wide, c] * np.exp(-d * d / (2 * v[wide]))).sum()
            tl = law.transmittance(d)[c]
            extra = f"; Cycles (head-on) {cyc[d][c]:.4f}" if cycles else ""
            print(f"  d {d} mm: MC T {res.total_transmittance:.4f} R {res.total_reflectance:.4f}; "
                  f"thin-slab law T {tl:.4f} R {law.reflectance(d)[c]:.4f} (law / MC {tl / max(res.total_transmittance, 1e-30):.3g}); "
                  f"d'Eon exp(-d^2/2v) {tg:.4f}{extra}")


BOUNDARY_EDGES_MM = np.concatenate([np.linspace(0.0, 30.0, 301), [60.0, 1000.0]])


def _spread(result, per_mm2):
    """(per-axis variance mm^2, mean radius mm) of a radially binned MCML result (1/mm^2 per annulus)."""
    e = result.bin_edges_mm
    rc, area = 0.5 * (e[1:] + e[:-1]), np.pi * (e[1:] ** 2 - e[:-1] ** 2)
    p = per_mm2 * area
    return float((p * rc * rc).sum() / p.sum() / 2.0), float((p * rc).sum() / p.sum())


def _cycles_walk(alpha, mfp_mm, d_mm, photons, seed=1, entry="cosine"):
    """Cycles' random walk (intern/cycles/kernel/integrator/subsurface.h, subsurface_random_walk.h):
    it starts at the shaded point along a direction into the surface (a cosine-distributed one, or the
    view ray refracted) and ends at its first surface hit (an index-matched boundary), where a
    Lambertian closure gathers the light; by reciprocity that is MCML with index 1.0 launched along
    that direction: ``entry`` "cosine" (a 4-point Gauss-Legendre rule in mu^2) or "normal" (a head-on
    view). Returns (R, T, reflectance per mm^2 over BOUNDARY_EDGES_MM)."""
    from dermis.profiles.medium import Layer, Medium
    from dermis.profiles.monte_carlo import monte_carlo_reflectance

    st = 1.0 / mfp_mm
    m = Medium(np.array([st * (1.0 - alpha)]), np.array([st * alpha]), 0.0, 1.0)
    if entry == "normal":
        r = monte_carlo_reflectance([Layer(m, d_mm)], photons, BOUNDARY_EDGES_MM, seed=seed)
        return r.total_reflectance, r.total_transmittance, r.reflectance_per_mm2
    x, w = np.polynomial.legendre.leggauss(4)
    R = T = 0.0
    prof = np.zeros(BOUNDARY_EDGES_MM.size - 1)
    for u, wu in zip(0.5 * (x + 1.0), 0.5 * w):
        r = monte_carlo_reflectance([Layer(m, d_mm)], photons, BOUNDARY_EDGES_MM, seed=seed,
                                    incidence_cos=float(np.sqrt(u)))
        R, T, prof = R + wu * r.total_reflectance, T + wu * r.total_transmittance, prof + wu * r.reflectance_per_mm2
    return R, T, prof


def boundary_study(channels=(0, 1), thicknesses=(0.5, 1.0, 2.0, 3.0, 4.0, 5.0), photons=100_000):
    from dermis.profiles.medium import Layer, Medium
    from dermis.profiles.monte_carlo import monte_carlo_reflectance
    from dermis.profiles.thin_slab import slab_law
    from dermis.scene.model import mean_skin_albedo
    from dermis.techniques.shared import TRANSLUCENCY_MIN_VARIANCE_MM2
    from dermis.verification import random_walk_slab

    sc = dermis.load_scene(SCENE)
    albedo = mean_skin_albedo(sc.material)
    prof = sc.profile.normalized()
    w, v = np.asarray(prof.weights), np.asarray(prof.variances_mm2)
    wide = v >= TRANSLUCENCY_MIN_VARIANCE_MM2
    law = slab_law(prof, albedo)
    edges = BOUNDARY_EDGES_MM
    rc, area = 0.5 * (edges[1:] + edges[:-1]), np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    for c in channels:
        A, mfp = float(albedo[c]), float(1.0 / law.reduced_sigma_t_per_mm[c])
        tsd_var = float((w[wide, c] * v[wide]).sum() / w[wide, c].sum())
        alpha, semi = random_walk_slab(A, mfp, np.inf, photons=photons, index=1.4, bin_edges_mm=edges)
        var_semi, r_semi = _spread(semi, semi.reflectance_per_mm2)
        # index-matched walks with the same total reflectance and mean exit radius: the medium is
        # scale invariant, so the albedo is bisected at mean free path 1 and the path then scaled
        _, trial = random_walk_slab(A, 1.0, np.inf, photons=photons, index=1.0, bin_edges_mm=edges)
        mfp1 = r_semi / _spread(trial, trial.reflectance_per_mm2)[1]
        alpha1, semi1 = random_walk_slab(A, mfp1, np.inf, photons=photons, index=1.0, bin_edges_mm=edges)
        lo, hi = 0.0, 1.0 - 1e-7
        for _ in range(16):  # Cycles' walk: its albedo, bisected with common random numbers
            a = 0.5 * (lo + hi)
            lo, hi = (a, hi) if _cycles_walk(a, 1.0, np.inf, photons // 20)[0] < A else (lo, a)
        alpha_c = 0.5 * (lo + hi)
        Rc, _, pc = _cycles_walk(alpha_c, 1.0, np.inf, photons // 4)
        Rn = _cycles_walk(alpha_c, 1.0, np.inf, photons, entry="normal")[0]
        mfp_c = r_semi / float((pc * area * rc).sum() / (pc * area).sum())
        print(f"{'RGB'[c]}: albedo {A:.4f}; skin walk (index 1.4): mean free path {mfp:.3f} mm, single-scattering "
              f"albedo {alpha:.5f}, R {semi.total_reflectance:.4f}, mean exit radius {r_semi:.3f} mm, per-axis "
              f"variance {var_semi:.3f} mm^2 (the profile's {float((w[:, c] * v).sum() / w[:, c].sum()):.3f}); "
              f"index-matched walk, normal entry: mean free path {mfp1:.3f} mm, albedo {alpha1:.5f}, R "
              f"{semi1.total_reflectance:.4f}; Cycles' walk (index-matched, cosine entry): mean free path "
              f"{mfp_c:.3f} mm, albedo {alpha_c:.5f}, R {Rc:.4f} (seen head-on: {Rn:.4f}); tsd's far-face spread "
              f"(wide Gaussians) {tsd_var:.3f} mm^2")
        skin = [Layer(Medium(np.array([(1.0 - alpha) / mfp]), np.array([alpha / mfp]), 0.0, 1.4), np.inf)]
        grazing = [monte_carlo_reflectance(skin, photons // 2, [0.0, 1e3], seed=5, incidence_cos=mu).total_reflectance
                   for mu in (1.0, 0.5, 0.15)]
        print(f"  skin walk, oblique beam: R at cos 1 / 0.5 / 0.15: {' / '.join('%.4f' % g for g in grazing)}")
        for d in thicknesses:
            res = random_walk_slab(A, mfp, d, photons=photons, index=1.4, bin_edges_mm=edges)[1]
            res1 = random_walk_slab(A, mfp1, d, photons=photons, index=1.0, bin_edges_mm=edges)[1]
            tc = _cycles_walk(alpha_c, mfp_c, d, photons // 4, seed=2)[1]
            tn = _cycles_walk(alpha_c, mfp_c, d, photons, seed=2, entry="normal")[1]
            vr, _ = _spread(res, res.reflectance_per_mm2)
            vt, _ = _spread(res, res.transmittance_per_mm2) if res.total_transmittance > 0 else (float("nan"), 0)
            tl = float(law.transmittance(d)[c])
            t14 = max(res.total_transmittance, 1e-30)
            print(f"  d {d} mm: index 1.4: R {res.total_reflectance:.4f} (law {float(law.reflectance(d)[c]):.4f}) "
                  f"spread {vr:.3f}; T {res.total_transmittance:.4f} (law {tl:.4f}) spread {vt:.3f} | "
                  f"index 1.0, normal "
                  f"entry: T / index 1.4 {res1.total_transmittance / t14:.3f} | Cycles' walk: T {tc:.4f}, / index 1.4 "
                  f"{tc / t14:.3f}, / law {tc / max(tl, 1e-30):.3f}; seen head-on (normal entry): T {tn:.4f}, "
                  f"/ index 1.4 {tn / t14:.3f}, / law {tn / max(tl, 1e-30):.3f}", flush=True)


def cycles_view_dependence(mfp_mm=0.702, alpha=0.92728, views_deg=(0, 30, 60, 80, 89), photons=40_000):
    """Cycles' walk starts along the view ray refracted into the surface, so its BSSRDF depends on
    the view angle. MCML of the fitted Cycles walk (red, from --boundary: index 1.0, the given path and
    albedo) launched along the view refracted through a smooth interface of IOR 1.4 (Cycles refracts
    through a rough one, GGX roughness 1): the semi-infinite reflectance and the transmittance of 2 mm."""
    from dermis.profiles.medium import Layer, Medium
    from dermis.profiles.monte_carlo import monte_carlo_reflectance

    m = Medium(np.array([(1.0 - alpha) / mfp_mm]), np.array([alpha / mfp_mm]), 0.0, 1.0)
    for view in views_deg:
        mu = float(np.sqrt(1.0 - (np.sin(np.radians(view)) / 1.4) ** 2))
        R = monte_carlo_reflectance([Layer(m, np.inf)], photons, [0.0, 1e3], seed=4, incidence_cos=mu).total_reflectance
        T = monte_carlo_reflectance([Layer(m, 2.0)], photons, [0.0, 1e3], seed=4, incidence_cos=mu).total_transmittance
        print(f"view {view:2d} deg (entry cos {mu:.3f}): R {R:.4f}, T(2 mm) {T:.4f}", flush=True)


def against_cycles(npz, techniques):
    """The back-lit-ear region of `dermis validate --against cycles` (its region_masks and _score)
    against stored Cycles accumulations (a validate store, cycles_spec_64x64.npz: two seed streams),
    per technique; "tsd-off" renders tsd without translucency, "tsd-x1.5" with translucency_strength
    1.5 (what Cycles' own random walk transmits through a back-lit slab over the thin-slab law, 1.35-1.53
    at 0.5-5 mm in red: the medium mismatch, measured, not a setting)."""
    import os

    from dermis.blender.validate import _score, region_masks
    from dermis.reference.validate import _render

    z = np.load(npz)
    spp = int(z["spp"])
    a, b = z["sums"][0] / spp, z["sums"][1] / spp
    h, w = a.shape[:2]
    sc = dermis.load_scene(SCENE)
    sc.material.pore_strength = 0.0
    skin = (a[..., 3] >= 0.999) & (b[..., 3] >= 0.999)
    ref = (0.5 * (a[..., :3] + b[..., :3])).astype(np.float32)
    reg = region_masks(sc, (w, h), skin)
    floor, _ = _score(sc, a[..., :3].astype(np.float32), b[..., :3].astype(np.float32), skin, reg)
    print(f"Cycles {spp} spp x 2: floor FLIP {floor['flip']:.4f}, back-lit ear {floor['regions']['back_lit_ear']['flip']:.4f}")
    for t in techniques:
        name, _, opt = t.partition("-")
        kw = {"tweak": (lambda r, n=name: r.technique(n, translucency=False))} if opt == "off" else {}
        if opt.startswith("x"):  # e.g. tsd-x1.5: the light through thin parts scaled (Cycles' slab medium)
            kw = {"tweak": (lambda r, n=name, f=float(opt[1:]): r.technique(n, translucency_strength=f))}
        img, _ = _render(sc, name, (w, h), **kw)
        m, _ = _score(sc, ref, img, skin, reg)
        e = m["regions"]["back_lit_ear"]
        print(f"{t:16s} skin FLIP {m['flip']:.4f} ratio {' '.join('%.3f' % x for x in m['mean_ratio'])} | back-lit ear "
              f"({e['pixels']} px) FLIP {e['flip']:.4f} ratio {' '.join('%.3f' % x for x in e['mean_ratio'])} "
              f"(load {os.getloadavg()[0]:.1f})")


CYCLES_STORE = Path(__file__).resolve().parent / "cycles" / "stores" / "back-ears"  # the stored 64 px Cycles renders (was a scratch path)
# Cycles' walk for this scene (ear7: Cycles' radius 9.24 / 3.10 mm from dermis.blender.sss, its mean free
# path radius / 4 pi and its albedo remap of the mean albedo 0.535 / 0.321; red reproduces Cycles' own
# back-lit slab render within 1-5%)
CYCLES_WALK_MEDIUM = {0: (0.735, 0.930), 1: (0.247, 0.782)}


def chiang_alpha(A):
    """Cycles' subsurface_random_walk_remap at anisotropy 0 (Chiang et al. 2016): the single-scattering
    albedo of its walk for a base colour A."""
    blend = A ** 0.25
    return ((1 - blend) * 1.8260523782 * np.arctan(5.11246790329 * A) ** 1.09686102424
            + blend * 0.496310210422 * np.arctan(4.23500903650 * A) ** 2.40602999408)
WALK_FACTOR = 4  # supersampling of the walk's film (validate's)


def walk_study(walks=16, channels=(0,), seed=0, bounce=False, paths_only=False, exhaustive=False):
    """See the module docstring (--walk)."""
    import os
    import time

    from dermis.blender.pixel_filter import CYCLES_FILTER_WIDTH_PX, reconstruct
    from dermis.blender.validate import region_masks
    from dermis.framing import framed_camera
    from dermis.images import as_rgb
    from dermis.profiles.thin_slab import slab_law
    from dermis.geometry.raycast import cosine_directions
    from dermis.reference.random_walk import DirectionalLight, MeshWalk, WalkMedium
    from dermis.reference.render import camera_rays
    from dermis.reference.validate import _render
    from dermis.scene.model import mean_skin_albedo
    from dermis.verification import random_walk_albedo

    sc = dermis.load_scene(SCENE)
    sc.material.pore_strength = 0.0
    sc.material.rho_s = 0.0  # validate's nospec mode: the walk has no specular
    mm = float(sc.mm_per_unit)
    z = np.load(CYCLES_STORE / "cycles_nospec_64x64.npz")
    spp = int(z["spp"])
    ca, cb = z["sums"][0] / spp, z["sums"][1] / spp
    h, w = ca.shape[:2]
    skin = (ca[..., 3] >= 0.999) & (cb[..., 3] >= 0.999)
    cyc = 0.5 * (ca[..., :3] + cb[..., :3])
    zc = np.load(CYCLES_STORE / "cycles_nospec_nosss_64x64.npz")
    ctrl = zc["sums"][0][..., :3] / int(zc["spp"])
    ear = region_masks(sc, (w, h), skin)["back_lit_ear"]
    f = WALK_FACTOR
    W, H = w * f, h * f
    # the supersamples within Cycles' filter window of an ear pixel
    reach = int(np.ceil(CYCLES_FILTER_WIDTH_PX * f))
    need = np.zeros((H, W), bool)
    for i, j in zip(*np.nonzero(ear)):
        cy, cx = (i + 0.5) * f, (j + 0.5) * f
        need[max(int(cy - reach), 0):int(cy + reach) + 1, max(int(cx - reach), 0):int(cx + reach) + 1] = True
    mesh = sc.mesh
    o, d, tmax, _ = camera_rays(sc, (W, H), 1, camera=framed_camera(sc.camera, mesh, W / H))
    sel = np.nonzero(need.ravel())[0]
    mw = MeshWalk(np.asarray(mesh.positions, np.float64) * mm, mesh.indices, mesh.normals)
    t, tri, bary = mw.caster.closest_hit(o[sel] * mm, d[sel], 0.0, tmax[sel] * mm)
    hit = tri >= 0
    P = o[sel] * mm + d[sel] * np.where(hit, t, 0.0)[:, None]
    # the albedo map under the ear's rays (the walks use the scene's mean albedo's medium)
    uv = np.asarray(mesh.uvs, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    tt = np.where(hit, tri, 0)
    b1, b2 = bary[:, :1], bary[:, 1:]
    uvp = uv[idx[tt, 0]] * (1 - b1 - b2) + uv[idx[tt, 1]] * b1 + uv[idx[tt, 2]] * b2
    alb = as_rgb(sc.material.albedo.data).astype(np.float64)
    ah, aw = alb.shape[:2]

    def albedo_at(tr, bc):
        b1, b2 = bc[:, :1], bc[:, 1:]
        q = uv[idx[tr, 0]] * (1 - b1 - b2) + uv[idx[tr, 1]] * b1 + uv[idx[tr, 2]] * b2
        return alb[np.clip(((1 - q[:, 1]) * ah).astype(int), 0, ah - 1), np.clip((q[:, 0] * aw).astype(int), 0, aw - 1)]

    tex = albedo_at(tt, bary)
    ear_rays = np.repeat(np.repeat(ear, f, 0), f, 1).ravel()[sel] & hit
    albedo = mean_skin_albedo(sc.material)
    print(f"back-ears, {int(ear.sum())} ear pixels, {len(sel)} supersample rays ({int(hit.sum())} on the mesh), "
          f"{walks} walks each; albedo map under the ear's rays: {' / '.join('%.3f' % x for x in tex[ear_rays].mean(0))}, "
          f"the skin's mean {' / '.join('%.3f' % x for x in albedo)} (the walks' media)", flush=True)
    law = slab_law(sc.profile.normalized(), albedo)
    L = sc.lights[0]
    to_light = -np.asarray(L.direction, np.float64) / np.linalg.norm(L.direction)
    env = np.asarray(sc.environment.color, np.float64)

    def ears(img):  # (H, W) supersampled per-ray means -> the 64 x 64 pixels, Cycles' filter
        return reconstruct(np.repeat(img[..., None], 3, 2), f)[..., 0]

    # a diffuse (no subsurface) surface, direct light only, at each ray: the check of the camera, light,
    # filter and shadows against Cycles' own render without SSS (the control)
    hs = np.nonzero(hit)[0]
    nsh = mw._shading_normal(tri[hs], bary[hs], mw._outward(tri[hs], -d[sel][hs]))
    vis = mw._lit(P[hs], nsh, to_light) & (nsh @ to_light > 0)
    envv = np.mean([~mw.caster.occluded(P[hs] + nsh * 1e-3, dd, 0.0, np.inf) for dd in np.moveaxis(
        cosine_directions(nsh, np.random.default_rng(9).random((len(hs), 16)), np.random.default_rng(10).random((len(hs), 16))), 1, 0)], 0)
    results = {}
    for c in channels:
        mfp = float(1.0 / law.reduced_sigma_t_per_mm[c])
        light = [DirectionalLight(tuple(to_light), float(L.intensity * np.asarray(L.color)[c]))]

        def diffuse_direct(pts, tr, bc, dirs, c=c, light=light):
            """What a diffuse surface met by a ray sends back along it: its direct light (the light with
            its shadow ray, the environment unoccluded), albedo map / pi: one bounce of interreflection."""
            n = mw._shading_normal(tr, bc, mw._outward(tr, -dirs))
            cos = n @ to_light
            lit = np.zeros(len(pts), bool)
            if (cos > 0).any():
                lit[cos > 0] = mw._lit(pts[cos > 0], n[cos > 0], to_light)
            return albedo_at(tr, bc)[:, c] / np.pi * (light[0].irradiance * np.maximum(cos, 0) * lit + np.pi * env[c])

        bfn = diffuse_direct if bounce else None
        lam = np.full(len(sel), env[c])
        if bounce:  # the diffuse surface's incoming light by 16 cosine rays (environment or one bounce)
            inc = np.mean([mw._incoming(P[hs] + nsh * 1e-3, dd, env[c], bfn) for dd in np.moveaxis(cosine_directions(
                nsh, np.random.default_rng(9).random((len(hs), 16)), np.random.default_rng(10).random((len(hs), 16))), 1, 0)], 0)
        else:
            inc = env[c] * envv
        lam[hs] = tex[hs, c] / np.pi * (light[0].irradiance * np.maximum(nsh @ to_light, 0) * vis + np.pi * inc)
        img = np.zeros(H * W)
        img[sel] = lam
        results[("diffuse-direct", c)] = [ears(img.reshape(H, W))] * 2
        # the walks' media per albedo bin (the albedo map under the ray: quartiles over the rays on the mesh)
        edges = np.quantile(tex[hs, c], [0.0, 0.25, 0.5, 0.75, 1.0])
        bins = np.clip(np.searchsorted(edges, tex[:, c], side="right") - 1, 0, 3)
        m0, a0 = CYCLES_WALK_MEDIUM[c]
        names = ("skin", "skin-mean", "cycles-refracted", "cycles-cosine", "cycles-refracted-albedo")
        rads = {n: [np.full(len(sel), env[c]), np.full(len(sel), env[c])] for n in names}
        path_rays = {k: np.zeros(len(sel)) for k in ("light", "far", "opposite", "distance")}
        for b in range(4):
            inb = hs[bins[hs] == b]
            A = float(tex[inb, c].mean())
            media = {"skin": WalkMedium(mfp, random_walk_albedo(A, mfp, index=1.4), "fresnel", 1.4),
                     "skin-mean": WalkMedium(mfp, random_walk_albedo(float(albedo[c]), mfp, index=1.4), "fresnel", 1.4),
                     "cycles-refracted": WalkMedium(m0, a0, "lambertian", 1.4, "refracted"),
                     "cycles-cosine": WalkMedium(m0, a0, "lambertian", 1.4, "cosine"),
                     "cycles-refracted-albedo": WalkMedium(m0, float(a0 + chiang_alpha(A) - chiang_alpha(float(albedo[c]))),
                                                           "lambertian", 1.4, "refracted")}
            for name, med in media.items():
                if (paths_only or exhaustive) and name != "skin":
                    continue
                t0 = time.perf_counter()
                for half in range(2):  # two independent halves: the pixel's noise
                    k = max(walks // 2, 1)
                    st = {}
                    r = mw.radiance(np.repeat(P[inb], k, 0), np.repeat(tri[inb], k), np.repeat(d[sel][inb], k, 0), med,
                                    light, float(env[c]), seed=seed * 100000 + 1000 * c + 100 * b + 10 * names.index(name) + half,
                                    stats=st, check_fraction=0.02 if name == "skin" and not exhaustive else 0.0, bounce=bfn,
                                    paths=name == "skin" and not exhaustive, nee="exhaustive" if exhaustive else "search")
                    rads[name][half][inb] = r.reshape(-1, k).mean(1)
                    if name == "skin" and not exhaustive:
                        for key in path_rays:
                            path_rays[key][inb] += st["paths"][key].reshape(-1, k).mean(1) / 2
                    if name == "skin":
                        results.setdefault(("check", c), []).append(
                            (1.0, 1.0) if exhaustive else (st["nee_search"], st["nee_exhaustive"]))
                print(f"  {'RGB'[c]} albedo bin {b} (A {A:.3f}, {len(inb)} rays) {name}: mfp {med.mean_free_path_mm:.3f} mm, "
                      f"albedo {med.single_scattering_albedo:.4f}; {time.perf_counter() - t0:.0f} s "
                      f"(load {os.getloadavg()[0]:.1f})", flush=True)
        for key, v in path_rays.items():
            img = np.zeros(H * W)
            img[sel] = v
            results[("path-" + key, c)] = [ears(img.reshape(H, W))] * 2
        for name in names:
            halves = []
            for half in range(2):
                img = np.zeros(H * W)
                img[sel] = rads[name][half]
                halves.append(ears(img.reshape(H, W)))
            results[(name, c)] = halves
        chk = np.array(results[("check", c)])
        print(f"  {'RGB'[c]}: the light's refracted-entry search against the exhaustive sum over facets (4 mm), "
              f"at 2% of the skin walk's vertices, weighted: search / exhaustive = {chk[:, 0].sum() / chk[:, 1].sum():.4f}",
              flush=True)
    # tsd without specular, supersampled and reconstructed as validate; and without translucency
    tsd = {}
    for opt in ("on", "off"):
        kw = {} if opt == "on" else {"tweak": lambda r: r.technique("tsd", translucency=False)}
        big, _ = _render(sc, "tsd", (W, H), **kw)
        tsd[opt] = reconstruct(big[..., :3], f)
    share = np.where(tsd["on"][..., 0] > 0, 1.0 - tsd["off"][..., 0] / np.maximum(tsd["on"][..., 0], 1e-30), 0.0)
    groups = [("< 0.1", share < 0.1), ("0.1-0.3", (share >= 0.1) & (share < 0.3)),
              ("0.3-0.5", (share >= 0.3) & (share < 0.5)), (">= 0.5", share >= 0.5), ("all", np.ones_like(share, bool))]
    for c in channels:
        pr = {k: results[("path-" + k, c)][0] for k in ("light", "far", "opposite", "distance")}
        if not exhaustive:
            print(f"\n{'RGB'[c]}: where the skin walk's light entered (the light's part of its radiance, per group; "
                  f"far: more than 3 mm from the pixel's point; opposite: through a facet facing away from the pixel's)")
            print("| tsd translucency share | px | far share | opposite share | mean entry distance (mm) |")
            print("|---|---|---|---|---|")
            for g, gm in groups:
                m = gm & ear
                if m.any():
                    lt = float(pr["light"][m].sum())
                    print(f"| {g} | {int(m.sum())} | {pr['far'][m].sum() / lt:.3f} | {pr['opposite'][m].sum() / lt:.3f} | "
                          f"{pr['distance'][m].sum() / lt:.2f} |")
        if paths_only:
            continue
        if exhaustive:
            sk = 0.5 * (results[("skin", c)][0] + results[("skin", c)][1])
            for g, gm in groups:
                m = gm & ear
                if m.any():
                    print(f"{'RGB'[c]} {g}: {int(m.sum())} px, skin walk (every facet's beam) {float(sk[m].sum()):.3f} "
                          f"+- {float(0.5 * np.sqrt(((results[('skin', c)][0] - results[('skin', c)][1])[m] ** 2).sum())):.3f}, "
                          f"tsd / skin {float(tsd['on'][..., c][m].sum() / sk[m].sum()):.3f}")
            continue
        print(f"\n{'RGB'[c]}: sums over the group's ear pixels (linear radiance); ratios of sums; +- half the two halves' difference")
        walk = {n: 0.5 * (results[(n, c)][0] + results[(n, c)][1]) for n in
                ("skin", "skin-mean", "cycles-refracted", "cycles-cosine", "cycles-refracted-albedo", "diffuse-direct")}
        noise = {n: 0.5 * np.abs(results[(n, c)][0] - results[(n, c)][1]) for n in walk}
        chk = np.array(results[("check", c)])
        ratio = chk[:, 0].sum() / chk[:, 1].sum()
        # the search's miss put back on the light's part of the skin walk (the exhaustive sum's ratio)
        walk["skin-corrected"] = walk["skin"] + pr["light"] * (1.0 / ratio - 1.0)
        print("| tsd translucency share | px | Cycles | skin walk (search-corrected) | setup: control / diffuse model | "
              "Cycles walk (refr., albedo map) / Cycles | refr., mean medium / Cycles | cosine, mean / Cycles | "
              "skin / Cycles walk | skin (map) / skin (mean) | tsd / skin | tsd / (skin x setup) | tsd / Cycles | tsd off / skin |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for g, gm in groups:
            m = gm & ear
            if not m.any():
                continue

            def s(x):
                return float(x[m].sum())

            def ns(n):
                return float(np.sqrt((noise[n][m] ** 2).sum()))
            sk, cy = s(walk["skin-corrected"]), s(cyc[..., c])
            cw = s(walk["cycles-refracted-albedo"])
            setup = s(ctrl[..., c]) / s(walk["diffuse-direct"])
            print(f"| {g} | {int(m.sum())} | {cy:.3f} | {sk:.3f} +- {ns('skin'):.3f} | {setup:.3f} | "
                  f"{cw / cy:.3f} +- {ns('cycles-refracted-albedo') / cy:.3f} | {s(walk['cycles-refracted']) / cy:.3f} | "
                  f"{s(walk['cycles-cosine']) / cy:.3f} | {sk / cw:.3f} | {s(walk['skin']) / s(walk['skin-mean']):.3f} | "
                  f"{s(tsd['on'][..., c]) / sk:.3f} | {s(tsd['on'][..., c]) / (sk * setup):.3f} | "
                  f"{s(tsd['on'][..., c]) / cy:.3f} | {s(tsd['off'][..., c]) / sk:.3f} |")
    np.savez_compressed(f"/tmp/dermis_ear_walk{'_bounce' if bounce else ''}.npz", ear=ear, share=share, cycles=cyc, control=ctrl, tsd_on=tsd["on"],
                        tsd_off=tsd["off"], **{f"{n}_{c}_{i}": results[(n, c)][i] for (n, c) in results if n != "check" for i in (0, 1)})


if __name__ == "__main__":
    if sys.argv[1] == "--walk":
        args = [a for a in sys.argv[2:] if a not in ("--bounce", "--paths", "--exhaustive")]
        walk_study(int(args[0]) if args else 16, tuple(int(x) for x in args[1]) if len(args) > 1 else (0,),
                   bounce="--bounce" in sys.argv, paths_only="--paths" in sys.argv, exhaustive="--exhaustive" in sys.argv)
    elif sys.argv[1] == "--slab":
        slab_theory(cycles="--cycles" in sys.argv[2:])
    elif sys.argv[1] == "--boundary":
        boundary_study()
    elif sys.argv[1] == "--cycles-view":
        cycles_view_dependence()
    elif sys.argv[1] == "--cycles-store":
        against_cycles(sys.argv[2], sys.argv[3:] or ["tsd", "tsd-off", "ssss", "preintegrated", "lambert"])
    elif sys.argv[1] == "--reference":
        against_reference(int(sys.argv[2]), sys.argv[3:] or ["tsd"])
    else:
        main(sys.argv[1], sys.argv[2:] or ["tsd"])
