"""A closed-slit test object (two skin "lips" pressed together): Cycles' random walk, dermis's walks, the
baked transfer and tsd on it, per row across the slit (issue 12, round 21).

The object: two capped cylinders of radius R_MM along x (length LENGTH_MM), one above the other with an
air gap of ``--gap`` mm at their closest line (y = 0, z = 0), mm_per_unit 1; each its own closed mesh (two
media; Cycles' walk and dermis's end a walk at its first boundary hit, so neither crosses the gap). The
slit between them is a V-shaped crease opening towards the camera (the gap grows as g + z^2 / R). The
camera looks along -z from 150 mm (FRAME_MM x FRAME_MM), a directional light of irradiance pi comes from
the front, LIGHT_DEG above the axis (the upper lip's underside turns away from it, the crease is in
shadow, the lower lip's top is partly in the upper lip's cast shadow: front-key's closed mouth). Material:
the example head's mean skin albedo and profile (so the bake's medium is the head's), no specular, no
environment, no interreflection (Cycles: max_bounces 0, see ``cycles``). ``--single``: the upper lip
alone (the control: the same lip without the slit).

The object is invariant along x, so a row's pixels are equivalent: per row the mean over the middle
columns is compared (per-row noise from the column spread). Subcommands (each writes OUT/NAME_TAG.npz; times
at load 6-9 on the 2 shared cores):

    cycles OUT [--gap G | --single] [--spp 512 --seeds 2]   Cycles with / without SSS (150-185 s a SSS render)
    walk OUT [--media cycles cycles_cosine cycles45 skin] [--environment] [--nee exhaustive] [--tag T]
        per row the skin walk and dermis's models of Cycles' walk (refracted / cosine / Cycles 4.5's entry)
        under the light (or a uniform environment): 2048 walks a row, 1-3 min a medium
    flatwalk OUT [--environment]     the skin walk on a flat block at each row's angles (3 min)
    diffuse_entry OUT                raw walks' exits weighted by the light's irradiance, camera views (20 s)
    bake OUT [--grid 64]             the shipped recipe on the points within BAKE_HALF_X_MM (2-9 min)
    tsd OUT                          tsd with / without the bake, lambert (30 s)
    report OUT [--per-row]           per region and row;   sheet OUT --sheet FILE.jpg   x4 crops
    head OUT [--collimated | --kernels]   front-key's mouth line: the raw walks (30-70 s), or the collimated beam
        against a flat block, or tsd's profile and the bake's flat share over the key light's irradiance (10 s)

    PYTHONPATH=src nice -n 5 python benchmarks/slit_lips.py cycles /tmp/slit21 --gap 0.05
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

R_MM = 4.0  # each lip's radius
LENGTH_MM = 30.0  # along x
SEG_AROUND = 160  # around each tube (0.16 mm edges)
SEG_ALONG = 60  # along x (0.5 mm)
FRAME_MM = 12.0  # the camera's vertical extent at the axis
SIZE = 160  # px (0.075 mm)
LIGHT_DEG = 15.0  # the light's elevation above the view axis, from above (the underside lit at a low N.L)
COLUMNS = (40, 120)  # the middle columns averaged per row (|x| < 3 mm)
BAKE_HALF_X_MM = 4.0  # the bake's points: |x| below this (the columns' reach plus the taps')
HEAD = Path(__file__).resolve().parent.parent / "examples" / "lee-perry-smith.toml"


def _tube(cy, r, length, n_around, n_along, u0, uv_scale):
    """A cylinder along x centred at (0, cy, 0), capped; isometric uv: the tube unrolled (seam at the back,
    angle pi measured from +z), caps as discs beside it. Returns positions, normals, uvs, triangles."""
    xs = np.linspace(-length / 2, length / 2, n_along + 1)
    # angle from +z towards +y; the seam (duplicated column) at the back (theta = pi)
    th = np.linspace(-np.pi, np.pi, n_around + 1)
    X, T = np.meshgrid(xs, th, indexing="ij")  # (along, around)
    ny, nz = np.sin(T), np.cos(T)
    P = np.stack([X, cy + r * ny, r * nz], -1).reshape(-1, 3)
    N = np.stack([np.zeros_like(X), ny, nz], -1).reshape(-1, 3)
    UV = np.stack([u0 + (X + length / 2) * uv_scale, (T + np.pi) * r * uv_scale], -1).reshape(-1, 2)
    idx = []
    A = n_around + 1
    for i in range(n_along):
        for j in range(n_around):
            a, b, c, d = i * A + j, (i + 1) * A + j, (i + 1) * A + j + 1, i * A + j + 1
            idx += [(a, b, c), (a, c, d)]
    pos, nrm, uvs, tri = [P], [N], [UV], [np.array(idx)]
    base = len(P)
    # caps: a fan per end, flat normals, uv discs above the tube's chart
    for k, (x, sgn) in enumerate(((-length / 2, -1.0), (length / 2, 1.0))):
        ring_t = th[:-1]
        cp = np.concatenate([[[x, cy, 0.0]], np.stack([np.full(n_around, x), cy + r * np.sin(ring_t), r * np.cos(ring_t)], 1)])
        cu = np.array([u0 + (r + 0.5 + k * (2 * r + 1.0)) * uv_scale, (2 * np.pi * r + 0.5 + r) * uv_scale])
        cuv = np.concatenate([[cu], cu + np.stack([np.sin(ring_t), np.cos(ring_t)], 1) * r * uv_scale])
        pos.append(cp)
        nrm.append(np.tile([sgn, 0.0, 0.0], (n_around + 1, 1)))
        uvs.append(cuv)
        ring = base + 1 + np.arange(n_around)
        nxt = base + 1 + (np.arange(n_around) + 1) % n_around
        f = np.stack([np.full(n_around, base), ring, nxt], 1)
        # outward: the triangle's normal along sgn x
        e = np.cross(cp[1 + 1] - cp[0], cp[1 + 2] - cp[0] if n_around > 2 else cp[1] - cp[0])
        tri.append(f if np.sign(e[0]) == sgn else f[:, [0, 2, 1]])
        base += n_around + 1
    return np.concatenate(pos), np.concatenate(nrm), np.concatenate(uvs), np.concatenate(tri)


def make_scene(gap_mm: float = 0.05, single: bool = False, light_deg: float = LIGHT_DEG):
    import dermis
    from dermis.scene.loaders import finish_mesh
    from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial, mean_skin_albedo

    head = dermis.load_scene(HEAD)
    albedo = tuple(float(a) for a in mean_skin_albedo(head.material))
    # uv: the tubes' charts side by side, 1 uv unit = 2 (LENGTH_MM + 1) mm
    scale = 1.0 / (2 * (LENGTH_MM + 1.0))
    parts = [_tube(R_MM + gap_mm / 2, R_MM, LENGTH_MM, SEG_AROUND, SEG_ALONG, 0.0, scale)]
    if not single:
        parts.append(_tube(-(R_MM + gap_mm / 2), R_MM, LENGTH_MM, SEG_AROUND, SEG_ALONG, 0.5, scale))
    pos, nrm, uvs, tri, off = [], [], [], [], 0
    for p, n, u, t in parts:
        pos.append(p), nrm.append(n), uvs.append(u), tri.append(t + off)
        off += len(p)
    name = f"slit-lips-{'single' if single else f'gap{gap_mm:g}'}"
    mesh = finish_mesh(np.concatenate(pos), np.concatenate(nrm), np.concatenate(uvs), np.concatenate(tri),
                       f"test:{name}", "v-up")
    a = np.radians(light_deg)
    sc = Scene(mesh=mesh, material=SkinMaterial(albedo_color=albedo, rho_s=0.0, pore_strength=0.0),
               lights=[Light(direction=(0.0, -np.sin(a), -np.cos(a)), intensity=np.pi)],
               camera=Camera(position=(0.0, 0.0, 150.0), target=(0.0, 0.0, 0.0),
                             fov_deg=float(np.degrees(2 * np.arctan(FRAME_MM / 2 / 150.0)))),
               environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0, name=name)
    sc.profile = head.profile
    sc.interreflection = False
    sc.output.tonemap, sc.output.exposure = "linear", 0.0  # linear radiance, as Cycles' EXR
    sc.output.background = (0.0, 0.0, 0.0)  # through the slit: Cycles' black world
    return sc


def _out(a, what):
    tag = "single" if a.single else f"gap{a.gap:g}"
    return Path(a.out) / f"{what}_{tag}.npz"


def cycles(a) -> None:
    from dermis.blender.render import render_cycles

    sc = make_scene(a.gap, a.single)
    out = {}
    for sss in (True, False):
        for seed in range(a.seeds):
            t0 = time.perf_counter()
            img, st = render_cycles(sc, (SIZE, SIZE), spp=a.spp, seed=seed, sss=sss, specular=False,
                                    max_bounces=a.bounces, threads=2)
            out[f"{'sss' if sss else 'nosss'}_{seed}"] = img
            print(f"cycles sss={sss} seed={seed} spp={a.spp} bounces={a.bounces}: {time.perf_counter() - t0:.1f} s", flush=True)
    path = _out(a, f"cycles_b{a.bounces}")
    np.savez_compressed(path, **out)
    print(path)


def film_rays(sc, px, py):
    """Camera rays through film positions (px, py) in pixels (0..SIZE, row 0 at the top): origins, directions."""
    from dermis.camera import camera_matrices

    lo, hi = sc.bounds()
    view, proj, eye, near, far = camera_matrices(sc.camera, 1.0, lo, hi)
    inv = np.linalg.inv(proj @ view)
    nx, ny = px / SIZE * 2.0 - 1.0, 1.0 - py / SIZE * 2.0

    def unproject(z):
        q = np.stack([nx, ny, np.full_like(nx, z), np.ones_like(nx)], 1) @ inv.T
        return q[:, :3] / q[:, 3:4]

    a, b = unproject(-1.0), unproject(1.0)
    d = b - a
    return a, d / np.linalg.norm(d, axis=1, keepdims=True)


def filter_offsets(n, rng, width=1.5):
    """n film offsets (pixels) drawn from Cycles' Blackman-Harris pixel filter (dermis.blender.pixel_filter:
    +-width px) by inverse CDF on a fine table: a walk's row mean then estimates Cycles' pixel."""
    from dermis.blender.pixel_filter import blackman_harris

    x = np.linspace(-width, width, 4001)
    c = np.cumsum(blackman_harris(x, width))
    c /= c[-1]
    return np.interp(rng.random(n), c, x)


def cycles_walk_media(sc, entry="refracted"):
    """Cycles' walk per channel as dermis models it (benchmarks/transfer_channels.py cycles_media: mean free
    path = Subsurface Radius / 4 pi, Chiang's albedo remap), as the Lambertian-exit walk with the refracted entry."""
    from transfer_channels import cycles_media

    from dermis.reference.random_walk import WalkMedium

    return tuple(WalkMedium(m.mean_free_path_mm, m.single_scattering_albedo, "lambertian", 1.4, entry)
                 for m in cycles_media(sc))


def ggx_vndf_alpha1(wi_local, u1, u2):
    """Visible microfacet normals of GGX at alpha 1 (Heitz 2018, "Sampling the GGX distribution of visible
    normals", JCGT 7(4), listing 1; no stretch at alpha 1): local frame, z the normal; (n, 3)."""
    V = wi_local / np.linalg.norm(wi_local, axis=1, keepdims=True)
    lensq = V[:, 0] ** 2 + V[:, 1] ** 2
    inv = np.where(lensq > 0, 1.0 / np.sqrt(np.maximum(lensq, 1e-300)), 0.0)
    T1 = np.where((lensq > 0)[:, None], np.stack([-V[:, 1] * inv, V[:, 0] * inv, np.zeros_like(inv)], 1), [1.0, 0.0, 0.0])
    T2 = np.cross(V, T1)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    sh = 0.5 * (1.0 + V[:, 2])
    t2 = (1.0 - sh) * np.sqrt(np.maximum(0.0, 1.0 - t1 * t1)) + sh * t2
    Nh = t1[:, None] * T1 + t2[:, None] * T2 + np.sqrt(np.maximum(0.0, 1.0 - t1 * t1 - t2 * t2))[:, None] * V
    Nh[:, 2] = np.maximum(Nh[:, 2], 0.0)
    return Nh / np.linalg.norm(Nh, axis=1, keepdims=True)


def cycles45_entry(view, shading_n, geometric_n, rng, ior=1.4):
    """Blender 4.5 Cycles' entry into the random walk (intern/cycles/kernel/integrator/subsurface.h,
    subsurface_entry_bounce and subsurface_bounce, method RANDOM_WALK): half the samples a cosine direction
    about -N, half refracted (ior) about a GGX visible normal of roughness 1 about the shading normal N; a
    direction with Ng . wo >= 0 ends the path (LABEL_NONE: its light is lost). Returns (directions, kept)."""
    n = len(view)
    wi = -view
    N = shading_n
    X = np.cross(N, np.where(np.abs(N[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    X /= np.linalg.norm(X, axis=1, keepdims=True)
    Y = np.cross(N, X)
    u0, u1, u2 = rng.random(n), rng.random(n), rng.random(n)
    cos_NI = np.einsum("ij,ij->i", N, wi)
    local_I = np.stack([np.einsum("ij,ij->i", X, wi), np.einsum("ij,ij->i", Y, wi), cos_NI], 1)
    H_l = ggx_vndf_alpha1(local_I, u1, u2)
    H = X * H_l[:, :1] + Y * H_l[:, 1:2] + N * H_l[:, 2:]
    neta = 1.0 / ior
    cos_HI = np.einsum("ij,ij->i", H, wi)
    dnp = np.sqrt(np.maximum(1.0 - neta ** 2 * (1.0 - cos_HI ** 2), 1e-14))
    wo = -(neta * wi) + (neta * cos_HI - dnp)[:, None] * H
    # the diffuse half (u0 < 0.5): a cosine direction about -N
    from dermis.geometry.raycast import cosine_directions

    cosd = cosine_directions(-N, rng.random((n, 1)), rng.random((n, 1)))[:, 0]
    diffuse = u0 < 0.5
    wo = np.where(diffuse[:, None], cosd, wo)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    kept = (diffuse | (cos_NI > 0.0)) & (np.einsum("ij,ij->i", geometric_n, wo) < 0.0)
    return wo, kept


def _row_hits(a):
    """The test object, its rows' pixel samples (``a.walks`` per row, Cycles' pixel filter, the middle
    COLUMNS) and their first hits: (scene, rows, rng, walks, row index, ray origins, directions, MeshWalk,
    t, triangle, barycentrics)."""
    from dermis.reference.random_walk import MeshWalk

    sc = make_scene(a.gap, a.single)
    rows = np.arange(*a.rows)
    rng = np.random.default_rng(a.seed)
    n = a.walks
    r_idx = np.repeat(np.arange(len(rows)), n)
    py = rows[r_idx] + 0.5 + filter_offsets(len(r_idx), rng)
    px = rng.uniform(*COLUMNS, len(r_idx))
    o, d = film_rays(sc, px, py)
    mesh = sc.mesh
    walker = MeshWalk(np.asarray(mesh.positions, np.float64), np.asarray(mesh.indices), np.asarray(mesh.normals))
    t, tri, bc = walker.caster.closest_hit(o, d, 0.0, np.inf)
    return sc, rows, rng, n, r_idx, o, d, walker, t, tri, bc


def walk(a) -> None:
    """Per row (rows ROWS), ``walks`` camera rays over the middle columns, film y from Cycles' filter: the
    skin walk (fresnel, the bake's media) and Cycles' walk as dermis models it (lambertian exit), direct light
    by next-event estimation. Saves per row and channel the mean and its standard error."""
    from dermis.reference.random_walk import DirectionalLight
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    sc, rows, rng, n, r_idx, o, d, walker, t, tri, bc = _row_hits(a)
    mesh = sc.mesh
    ok = tri >= 0
    p = o + d * t[:, None]
    # the shading normal (smooth, interpolated) and the facet's, both towards the camera
    tri_c = np.where(ok, tri, 0)
    vn = np.asarray(mesh.normals, np.float64)[np.asarray(mesh.indices).reshape(-1, 3)[tri_c]]
    ns = np.einsum("nk,nkc->nc", np.c_[1.0 - bc.sum(1), bc], vn)
    ns /= np.maximum(np.linalg.norm(ns, axis=1, keepdims=True), 1e-300)
    ng = walker._outward(tri_c, -d)
    ns *= np.where(np.einsum("ij,ij->i", ns, d) < 0.0, 1.0, -1.0)[:, None]
    L = -np.asarray(sc.lights[0].direction, np.float64)
    L /= np.linalg.norm(L)
    light = DirectionalLight(tuple(L), float(sc.lights[0].intensity))
    albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
    media = {"skin": B.skin_media(sc.profile, albedo), "cycles": cycles_walk_media(sc),
             "cycles_cosine": cycles_walk_media(sc, "cosine")}
    # Cycles 4.5's own entry (cycles45_entry): its directions passed as the "view" of an index-1 entry
    from dermis.reference.random_walk import WalkMedium

    media["cycles45"] = tuple(WalkMedium(m.mean_free_path_mm, m.single_scattering_albedo, "lambertian", 1.0, "refracted")
                              for m in media["cycles"])
    out = {"rows": rows}
    for name in a.media:
        mean = np.zeros((len(rows), 3))
        se = np.zeros((len(rows), 3))
        for c in range(3):
            t0 = time.perf_counter()
            val = np.zeros(len(r_idx))
            if name == "cycles45":
                wo, kept = cycles45_entry(d[ok], ns[ok], ng[ok], np.random.default_rng(a.seed * 10 + c + 5))
                sel = np.nonzero(ok)[0][kept]
                val[sel] = walker.radiance(p[sel], tri[sel], wo[kept], media[name][c], lights=[light], seed=a.seed * 10 + c)
                print(f"  cycles45 entry: {1 - kept.mean():.3f} of the paths lost at the entry", flush=True)
            elif a.environment:  # a uniform environment of radiance 1 instead of the light (the transfer's own case)
                val[ok] = walker.radiance(p[ok], tri[ok], d[ok], media[name][c], environment=1.0, seed=a.seed * 10 + c)
            else:
                val[ok] = walker.radiance(p[ok], tri[ok], d[ok], media[name][c], lights=[light], seed=a.seed * 10 + c,
                                          nee=a.nee)
            v = val.reshape(len(rows), n)
            mean[:, c], se[:, c] = v.mean(1), v.std(1) / np.sqrt(n)
            print(f"walk {name} channel {c}: {time.perf_counter() - t0:.0f} s", flush=True)
        out[name], out[name + "_se"] = mean, se
    path = _out(a, f"walk{'_' + a.tag if a.tag else ''}_s{a.seed}")
    np.savez_compressed(path, **out)
    print(path)


def _cache(a, grid=None):
    return Path(a.out) / f"cache_g{grid or a.grid}"


def bake(a) -> None:
    """The shipped bake's recipe (bake_points, bake_transfer, denoise; seed 0) on the points within
    BAKE_HALF_X_MM of the middle (the columns compared), written where ``find`` looks with
    DERMIS_CACHE_DIR=OUT/cache_gGRID."""
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import store
    from dermis.subsurface_transfer.bake import (NEAR_MM, THIN_MM, BakePoints, bake_points, bake_transfer, denoise,
                                                 recipe_key)

    sc = make_scene(a.gap, a.single)
    pts = bake_points(sc.mesh, sc.mm_per_unit, a.grid, THIN_MM, NEAR_MM)
    m = np.abs(pts.position[:, 0]) < BAKE_HALF_X_MM
    pts = BakePoints(pts.uv[m], pts.position[m], pts.triangle[m], pts.normal[m], None if pts.thin is None else pts.thin[m])
    t0 = time.perf_counter()
    bk = bake_transfer(sc.mesh, sc.mm_per_unit, sc.profile, mean_skin_albedo(sc.material), grid=a.grid, points=pts,
                       progress=print)
    bk = denoise(bk, pts)
    bk.meta["recipe"] = recipe_key()
    path = store.path_for(sc.mesh, _cache(a) / store.CACHE_SUBFOLDER)
    store.save(bk, path, store.mesh_key(sc.mesh), sc.mm_per_unit)
    np.savez_compressed(_out(a, f"bakepoints_g{a.grid}"), position=pts.position, normal=pts.normal, uv=pts.uv,
                        total=bk.total, kept=bk.kept, subtracted=bk.subtracted, excess=bk.excess, tap_uv=bk.tap_uv,
                        tap_weight=bk.tap_weight)
    print(f"bake: {len(pts.position)} points, {time.perf_counter() - t0:.0f} s -> {path}")


FACTOR = 4  # tsd rendered at 4x and reconstructed with Cycles' pixel filter (validate's way)


def tsd(a) -> None:
    """tsd (and lambert) at SIZE x FACTOR, reconstructed with Cycles' filter: with the bake (DERMIS_CACHE_DIR
    = OUT/cache_gGRID) and without (an empty cache folder), at irradiance sizes ``--sizes``."""
    from dermis.blender.pixel_filter import reconstruct
    from dermis.renderer import Renderer

    out = {}
    for size in a.sizes:
        for label, cache in (("transfer", _cache(a)), ("none", Path(a.out) / "cache_empty")):
            os.environ["DERMIS_CACHE_DIR"] = str(cache)
            sc = make_scene(a.gap, a.single)
            sc.directional_albedo = a.directional_albedo
            with Renderer(sc, (SIZE * FACTOR, SIZE * FACTOR), irradiance_size=size) as r:
                techs = ("tsd", "lambert") if label == "none" and size == a.sizes[0] else ("tsd",)
                for tech in techs:
                    img = r.render(tech).astype(np.float32)[..., :3]
                    key = tech if tech == "lambert" else f"tsd_{label}_{size}"
                    out[key] = reconstruct(img, FACTOR)
                    print(key, flush=True)
    np.savez_compressed(_out(a, f"tsd_g{a.grid}"), **out)
    print(_out(a, f"tsd_g{a.grid}"))


# regions by the row's y at the axis (mm): (name, y_hi, y_lo)
REGIONS = (("upper face", 1.45, 0.90), ("upper underside", 0.90, 0.20), ("crease", 0.20, -0.20),
           ("lower top", -0.20, -0.90), ("lower face", -0.90, -1.45))


def row_y(rows):
    return FRAME_MM / 2 - (np.asarray(rows) + 0.5) * FRAME_MM / SIZE


def report(a) -> None:
    """Per row and per region (REGIONS): Cycles with / without SSS (seed mean; the seeds' difference), the
    two walks (+- s.e.), tsd with / without the transfer, lambert; red / green / blue."""
    cy = np.load(_out(a, f"cycles_b{a.bounces}"))
    wk = [np.load(p) for p in sorted(Path(a.out).glob(f"walk*_s*_{'single' if a.single else f'gap{a.gap:g}'}.npz"))]
    ts_path = _out(a, f"tsd_g{a.grid}")
    ts = np.load(ts_path) if ts_path.exists() else {}
    rows = max((w["rows"] for w in wk), key=len)  # the full walk's rows (the env / exhaustive checks: fewer)
    c0, c1 = COLUMNS
    col = lambda im: np.asarray(im, np.float64)[rows, c0:c1].mean(1)
    seeds = sorted(k for k in cy.files if k.startswith("sss_"))
    series = {"cycles": np.mean([col(cy[k]) for k in seeds], 0),
              "cycles_seed_diff": col(cy[seeds[0]]) - col(cy[seeds[-1]]),
              "cycles_nosss": np.mean([col(cy[k]) for k in cy.files if k.startswith("nosss_")], 0)}
    for name in ("cycles", "cycles_cosine", "cycles45", "skin"):
        have = [w for w in wk if name in w.files and np.array_equal(w["rows"], rows)]
        if have:
            series["walk_" + name] = np.mean([w[name] for w in have], 0)
            series["walk_" + name + "_se"] = np.sqrt(np.sum([w[name + "_se"] ** 2 for w in have], 0)) / len(have)
    for k in getattr(ts, "files", []):
        series[k] = col(ts[k])
    y = row_y(rows)
    keys = [k for k in series if not k.endswith("_se") and k != "cycles_seed_diff"]
    if a.per_row:
        print("row y_mm " + " ".join(f"{k:>16s}" for k in keys) + "  (red)")
        for i, r in enumerate(rows):
            print(f"{r:3d} {y[i]:+.3f} " + " ".join(f"{series[k][i, 0]:16.4f}" for k in keys))
    print(f"per region, mean over rows (R G B); Cycles' seeds' difference / 2 and the walks' s.e. in brackets")
    for name, hi, lo in REGIONS:
        m = (y <= hi) & (y > lo)
        print(f"  {name} ({m.sum()} rows, y {lo:+.2f}..{hi:+.2f} mm)")
        for k in keys:
            v = series[k][m].mean(0)
            extra = ""
            if k == "cycles":
                extra = f"  (+- {np.abs(series['cycles_seed_diff'][m].mean(0)) / 2})"
            elif k + "_se" in series:
                extra = f"  (+- {np.sqrt((series[k + '_se'][m] ** 2).sum(0)) / m.sum()})"
            ratio = v / np.maximum(series["cycles"][m].mean(0), 1e-9)
            print(f"    {k:22s} {v[0]:.4f} {v[1]:.4f} {v[2]:.4f}   / Cycles {ratio[0]:.3f} {ratio[1]:.3f} {ratio[2]:.3f}{extra}")


def flatwalk(a) -> None:
    """The skin walk on a flat, thick block at each row's angles: the row's mean shading normal (the camera
    rays' hits over the middle columns) turned to +z with the light and the view turned with it; one
    start point at the block's top centre (the half-space's answer does not depend on where). What the
    flat medium gives at that pixel's N.L and N.V (no cast shadow; rows whose N.L <= 0 give 0), so
    walk_skin / flatwalk - 1 is the geometry's excess under the actual light (the transfer's quantity)."""
    from dermis.reference.random_walk import DirectionalLight, MeshWalk
    from dermis.scene.builtin import slab
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    sc = make_scene(a.gap, a.single)
    rows = np.arange(*a.rows)
    py = rows + 0.5
    px = np.full(len(rows), 0.5 * (COLUMNS[0] + COLUMNS[1]))
    o, d = film_rays(sc, px, py)
    mesh = sc.mesh
    cyl = MeshWalk(np.asarray(mesh.positions, np.float64), np.asarray(mesh.indices), np.asarray(mesh.normals))
    t, tri, bc = cyl.caster.closest_hit(o, d, 0.0, np.inf)
    vn = np.asarray(mesh.normals, np.float64)[np.asarray(mesh.indices).reshape(-1, 3)[np.maximum(tri, 0)]]
    ns = np.einsum("nk,nkc->nc", np.c_[1.0 - bc.sum(1), bc], vn)
    ns /= np.linalg.norm(ns, axis=1, keepdims=True)
    p, nn, uv, tt = slab(size=80.0, thickness=40.0, n=8)
    block = MeshWalk(np.asarray(p, np.float64), np.asarray(tt))
    top = np.array([[0.0, 0.0, 20.0]])
    top_tri = block.caster.closest_hit(top + [0, 0, 1.0], np.array([[0.0, 0.0, -1.0]]), 0.0, np.inf)[1]
    L = -np.asarray(sc.lights[0].direction, np.float64)
    L /= np.linalg.norm(L)
    albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
    media = B.skin_media(sc.profile, albedo)
    mean = np.zeros((len(rows), 3))
    se = np.zeros((len(rows), 3))
    for i in range(len(rows)):
        if tri[i] < 0:
            continue
        n = ns[i]
        # the rotation taking n to +z (Rodrigues about n x z)
        z = np.array([0.0, 0.0, 1.0])
        v = np.cross(n, z)
        c = float(n @ z)
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        R = np.eye(3) + K + K @ K / (1.0 + c)
        light = DirectionalLight(tuple(R @ L), float(sc.lights[0].intensity))
        view = np.repeat((R @ d[i])[None], a.walks, 0)
        for ch in range(3):
            kw = dict(environment=1.0) if a.environment else dict(lights=[light])
            val = block.radiance(np.repeat(top, a.walks, 0), np.repeat(top_tri, a.walks), view, media[ch],
                                 seed=a.seed * 100 + i * 3 + ch, **kw)
            mean[i, ch], se[i, ch] = val.mean(), val.std() / np.sqrt(a.walks)
    path = _out(a, f"flatwalk{'_env' if a.environment else ''}_s{a.seed}")
    np.savez_compressed(path, rows=rows, skin_flat=mean, skin_flat_se=se, normal=ns)
    print(path)


def diffuse_entry(a) -> None:
    """The transfer's own model under the directional light, from raw walks (no taps, no compression): the
    skin walk from the rows' visible points along the camera ray, each exit weighted by the irradiance the
    light gives there (E max(0, N_e . L), cast shadows ignored: the upper lip alone), i.e. light entering
    DIFFUSELY at the exit; against the same walks' flat twins (random_walk.halfspace_exits: the half-space
    tangent at the point, common random numbers) weighted by the point's own irradiance. Compare with the
    walk with the refracted collimated beam (``walk``) over ``flatwalk``."""
    from dermis.reference.random_walk import CounterUniforms, halfspace_exits
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    sc, rows, rng, n, r_idx, o, d, walker, t, tri, bc = _row_hits(a)
    mesh = sc.mesh
    p = o + d * t[:, None]
    L = -np.asarray(sc.lights[0].direction, np.float64)
    L /= np.linalg.norm(L)
    vn = np.asarray(mesh.normals, np.float64)
    idx = np.asarray(mesh.indices).reshape(-1, 3)

    def irradiance(points, tris):
        # the triangle's mean vertex normal . L (the cylinder's radial normal within 1.1 degrees)
        nn = vn[idx[tris]].mean(1)
        nn /= np.linalg.norm(nn, axis=1, keepdims=True)
        return np.maximum(nn @ L, 0.0)

    media = B.skin_media(sc.profile, np.asarray(mean_skin_albedo(sc.material), np.float64))
    out = {"rows": rows}
    for c in range(3):
        stream = CounterUniforms(a.seed * 7 + c)
        gid = np.arange(len(p))
        ex = {}
        walker.radiance(p, tri, d, media[c], exits=ex, uniforms=stream, walk_ids=gid)
        e_exit = irradiance(ex["point"], ex["triangle"])
        cyl = np.bincount(ex["walk"], weights=ex["weight"] * e_exit, minlength=len(p))
        tw = halfspace_exits(p, walker._outward(tri, -d), d, media[c], stream, gid)
        e0 = irradiance(p, tri)
        flat = np.bincount(tw["walk"], weights=tw["weight"], minlength=len(p)) * e0
        out[f"cyl_{c}"] = cyl.reshape(len(rows), n).mean(1)
        out[f"flat_{c}"] = flat.reshape(len(rows), n).mean(1)
        print(f"channel {c}: diffuse entry, cylinder / flat twin - 1 = {cyl.sum() / flat.sum() - 1:+.4f}", flush=True)
    np.savez_compressed(_out(a, "diffuse_entry"), **out)


def sheet(a) -> None:
    """x4 crops (rows / columns 50-110, display gamma 2.2, linear clipped at 1): Cycles, tsd without the
    transfer, tsd with it (irradiance 1024), Cycles without SSS; written to ``--sheet`` (JPEG)."""
    from PIL import Image

    cy = np.load(_out(a, f"cycles_b{a.bounces}"))
    ts = np.load(_out(a, f"tsd_g{a.grid}"))
    seeds = [k for k in cy.files if k.startswith("sss_")]
    ims = [np.mean([cy[k] for k in seeds], 0), ts["tsd_none_1024"], ts["tsd_transfer_1024"], cy["nosss_0"]]
    crop = [np.clip(np.asarray(i, np.float64)[50:110, 50:110], 0.0, 1.0) ** (1 / 2.2) for i in ims]
    img = np.concatenate(crop, 1)
    Image.fromarray((img * 255 + 0.5).astype(np.uint8)).resize((img.shape[1] * 4, img.shape[0] * 4), Image.NEAREST).save(
        a.sheet, quality=92)
    print(a.sheet)


HEAD_SCENE = Path(__file__).resolve().parent.parent / "examples" / "reference" / "front-key.toml"


def head(a) -> None:
    """The same raw-walk check on the head, at front-key's mouth line (benchmarks/mouth_line.py's frame at 768 px,
    round 20's points: x 370-390, y 647-651): from each visible point ``walks`` skin walks (the bake's medium),
    entered along the camera ray and along diffuse views; each exit weighted by the key light's irradiance there
    (max(0, N . L) with its cast shadow, ray cast), against the same walks' flat twins lit at the point's own
    irradiance. Per unit uniform irradiance too (the bake's quantity, round 20's +0.15)."""
    import dermis
    from dermis.framing import framed_camera
    from dermis.reference.random_walk import CounterUniforms, MeshWalk, halfspace_exits
    from dermis.reference.render import camera_rays
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    sc = dermis.load_scene(HEAD_SCENE)
    mm = float(sc.mm_per_unit)
    o, d, tmax, _ = camera_rays(sc, (768, 768), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    pix = np.array([y * 768 + x for y in range(647, 652) for x in range(370, 391)])
    pos = np.asarray(sc.mesh.positions, np.float64) * mm
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    vn = np.asarray(sc.mesh.normals, np.float64)
    walker = MeshWalk(pos, idx, vn)
    dd = d[pix] / np.linalg.norm(d[pix], axis=1, keepdims=True)
    t, tri, bc = walker.caster.closest_hit(o[pix] * mm, dd, 0.0, np.inf)
    keep = tri >= 0
    p0, tri0, view = (o[pix] * mm + dd * t[:, None])[keep], tri[keep], dd[keep]
    L = -np.asarray(sc.lights[0].direction, np.float64)
    L /= np.linalg.norm(L)

    def irradiance(points, tris):
        from ear_transfer import barycentric

        n = np.einsum("nk,nkc->nc", barycentric(pos, idx, tris, points), vn[idx[tris]])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        fn = walker.facet_normals[tris] * np.where((walker.facet_normals[tris] * n).sum(1) >= 0, 1.0, -1.0)[:, None]
        lit = walker._lit(points, fn, L)
        return np.maximum(n @ L, 0.0) * lit

    e0 = irradiance(p0, tri0)
    ok = e0 > 1e-3
    p0, tri0, view, e0 = p0[ok], tri0[ok], view[ok], e0[ok]
    nrm0 = walker._outward(tri0, -view)
    media = B.skin_media(sc.profile, np.asarray(mean_skin_albedo(sc.material), np.float64))
    W = a.walks
    print(f"{len(p0)} lit visible points of x 370-390, y 647-651 (N.L mean {e0.mean():.3f}); {W} walks each")
    if a.collimated:
        _collimated(walker, p0, tri0, view, nrm0, L, media, W)
        return
    if a.kernels:
        _kernels(sc, pos, idx, vn, walker, p0, tri0, nrm0, L, e0, media)
        return
    for c in range(2):
        for label in ("camera view", "diffuse views"):
            P, T = np.repeat(p0, W, 0), np.repeat(tri0, W)
            V = np.repeat(view, W, 0) if label == "camera view" else B.diffuse_views(np.repeat(nrm0, W, 0),
                                                                                  np.random.default_rng(5 + c))
            st, gid, ex = CounterUniforms(31 + c), np.arange(len(P)), {}
            walker.radiance(P, T, V, media[c], exits=ex, uniforms=st, walk_ids=gid)
            k = ex["walk"] // W
            ee = irradiance(ex["point"] + ex["normal"] * 1e-3, ex["triangle"])
            tw = halfspace_exits(P, walker._outward(T, -V), V, media[c], st, gid)
            twin = np.bincount(tw["walk"] // W, tw["weight"], len(p0))
            # per walk: its exits weighted by E / E0 less its twin's (common random numbers); mean and s.e.
            per_lit = np.bincount(ex["walk"], ex["weight"] * ee / e0[k], len(P)) - np.bincount(tw["walk"], tw["weight"], len(P))
            per_uni = np.bincount(ex["walk"], ex["weight"], len(P)) - np.bincount(tw["walk"], tw["weight"], len(P))
            norm = twin.sum() / len(p0) / W
            se = lambda x: x.std() / np.sqrt(len(x)) / norm
            print(f"  {'RG'[c]} {label:13s}: under the key light walk / twin - 1 = {per_lit.mean() / norm:+.4f} "
                  f"(s.e. {se(per_lit):.4f}); per unit uniform irradiance {per_uni.mean() / norm:+.4f} (s.e. {se(per_uni):.4f})",
                  flush=True)


def _collimated(walker, p0, tri0, view, nrm0, L, media, W, check=0.02):
    """The skin walk with the light's refracted collimated beam (next-event estimation, the walk's beam search,
    its miss measured on ``check`` of the vertices by beam_exhaustive) along the camera ray, against the same walk
    on a flat block at each point's own N.L and N.V (the plane: the search is exact there)."""
    from dermis.reference.random_walk import DirectionalLight, MeshWalk
    from dermis.scene.builtin import slab

    bp, _, _, bt = slab(size=80.0, thickness=40.0, n=8)
    block = MeshWalk(np.asarray(bp, np.float64), np.asarray(bt))
    top = np.array([[0.0, 0.0, 20.0]])
    top_tri = block.caster.closest_hit(top + [0, 0, 1.0], np.array([[0.0, 0.0, -1.0]]), 0.0, np.inf)[1]
    light = DirectionalLight(tuple(L), 1.0)
    for c in range(2):
        st = {}
        v = walker.radiance(np.repeat(p0, W, 0), np.repeat(tri0, W), np.repeat(view, W, 0), media[c], lights=[light],
                            seed=40 + c, stats=st, check_fraction=check, check_radius_mm=2.5)
        cyl = v.reshape(len(p0), W).mean(1)
        flat = np.zeros(len(p0))
        for i in range(len(p0)):
            n = nrm0[i]
            z = np.array([0.0, 0.0, 1.0])
            ax = np.cross(n, z)
            K = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
            R = np.eye(3) + K + K @ K / (1.0 + float(n @ z))
            fv = block.radiance(np.repeat(top, W // 4, 0), np.repeat(top_tri, W // 4), np.repeat((R @ view[i])[None], W // 4, 0),
                                media[c], lights=[DirectionalLight(tuple(R @ L), 1.0)], seed=60 + i)
            flat[i] = fv.mean()
        miss = st["nee_search"] / max(st["nee_exhaustive"], 1e-300)
        print(f"  {'RG'[c]} collimated beam, camera view: walk / flat block - 1 = {cyl.sum() / flat.sum() - 1:+.4f}; "
              f"the beam search finds {miss:.3f} of the exhaustive sum (corrected: {cyl.sum() / miss / flat.sum() - 1:+.4f})",
              flush=True)


def _kernels(sc, pos, idx, vn, walker, p0, tri0, nrm0, L, e0, media, reach_mm=16.0):
    """What tsd's blur and the bake's flat share see at the points: int R(g) E dA / E0 (tsd's profile, every
    vertex) and int_same-facing K_flat(g) E dA / E0 (the bake's subtraction) over the geodesic neighbourhood
    (dermis.subsurface_transfer.bake.SurfaceGraph on the triangles within ``reach_mm``), E the key light's
    N.L with its cast shadow at the graph's vertices.
    CAUTION (round 21, taps21): each vertex's whole area is weighted at the kernel's value at its own g (clamped to
    1e-6 at the start vertex), so the peaked near field is over-counted: under UNIFORM light this sum gives 1.17-1.68
    at the line's points where the same-facing flat share is <= 1 (benchmarks/transfer_taps.py walk --at-pixels prints
    both). slit21's "1.44" and the "-0.17 E0" derived from it are this artefact; transfer_taps.py's walk takes the
    share within MIN_SURFACE_MM as F_flat(MIN_SURFACE_MM) times the kernel-weighted mean E, as the bake does."""
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.subsurface_transfer import bake as B

    cen = (pos[idx[:, 0]] + pos[idx[:, 1]] + pos[idx[:, 2]]) / 3.0
    near = np.min(np.linalg.norm(cen[:, None] - p0[None, ::5], axis=2), 1) < reach_mm
    sub = np.nonzero(near)[0]
    uv = np.asarray(texture_space_uvs(sc.mesh), np.float64)
    g = B.SurfaceGraph(pos, idx[sub], vn, uv)
    remap = {t: i for i, t in enumerate(sub)}
    start = g.nearest(p0, np.array([remap[t] for t in tri0]))
    nv = g.normal
    lit = walker._lit(g.position, nv, L)
    Ev = np.maximum(nv @ L, 0.0) * lit
    kern = [B.flat_kernel(m) for m in media[:2]]
    D = g.distances(start)
    for c in range(2):
        iR, iK = [], []
        for i in range(len(p0)):
            fin = np.isfinite(D[i])
            gd = np.maximum(D[i, fin], 1e-6)
            w = g.area[fin] * Ev[fin]
            iR.append((B.profile_density(sc.profile, gd)[:, c] * w).sum())
            same = nv[fin] @ nrm0[i] > 0.0
            iK.append((kern[c].at(gd) * w * same).sum())
        # ratios of sums over the points (a region's mean radiance over its flat value); E0 at the points and at
        # their graph vertices (the crease turns within a texel: the two differ there)
        for name, e in (("E0 at the points", e0), ("E0 at their vertices", Ev[start])):
            print(f"  {'RG'[c]}: int R E dA / E0 = {np.sum(iR) / e.sum():.4f} (tsd's profile), int_same K_flat E dA / E0 = "
                  f"{np.sum(iK) / e.sum():.4f} (the bake's flat share); {name}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["cycles", "walk", "flatwalk", "diffuse_entry", "bake", "tsd", "report", "sheet", "head"])
    ap.add_argument("out")
    ap.add_argument("--gap", type=float, default=0.05)
    ap.add_argument("--single", action="store_true")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--bounces", type=int, default=0)
    ap.add_argument("--walks", type=int, default=256)
    ap.add_argument("--grid", type=int, default=64)
    ap.add_argument("--rows", type=int, nargs=2, default=(50, 111))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--per-row", action="store_true")
    ap.add_argument("--tag", default="")
    ap.add_argument("--environment", action="store_true")
    ap.add_argument("--nee", default="search", choices=["search", "exhaustive"])
    ap.add_argument("--sheet", default="slit-lips-x4.jpg")
    ap.add_argument("--collimated", action="store_true")
    ap.add_argument("--kernels", action="store_true")
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024, 128])
    ap.add_argument("--no-directional-albedo", dest="directional_albedo", action="store_false")
    ap.add_argument("--media", nargs="+", default=["cycles", "skin"])
    a = ap.parse_args(argv)
    Path(a.out).mkdir(parents=True, exist_ok=True)
    globals()[a.what](a)


if __name__ == "__main__":
    main()
