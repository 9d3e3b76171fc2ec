"""Where tsd's red in the back-lit ear differs from the skin walk's, split by transport (issue 12, round 10).

    PYTHONPATH=src nice -n 10 python benchmarks/ear_transfer.py [--walks 64] [--factor 2]

On the rays of validate's back_lit_ear region of examples/reference/back-ears.toml (64 x 64, ``factor``^2
rays a pixel), a simplified material (the skin's mean albedo, no albedo or normal map, no specular, no
environment, no interreflection: what is left is the directional light, its shadows and the transport),
red channel:

* tsd's texture-space result at each ray's uv (the blur chain D and translucency T, times A^(1-mix) / pi);
* the skin walk (dermis.reference.random_walk, the light's refracted beam by next-event estimation)
  started along the camera ray and along cosine-distributed views;
* the diffuse-entry walk: the same walk's exits (dermis.subsurface_transfer.bake.walk_exits) weighted
  by tsd's OWN irradiance map at the exit (so only the transport differs from tsd), split into
  same-facing exits within 1 mm along the surface, beyond, and opposite-facing ones;
* the exact surface integral of tsd's profile R at the geodesic distance with tsd's irradiance (what
  the blur chain should give), and tsd's direct irradiance against a ray-cast N.L V;
* the baked transfer (the geometry's excess over the flat walk, :mod:`dermis.subsurface_transfer`)
  evaluated on these rays with tsd's blurred irradiance, and tsd with it added.
Printed per translucency-share group (ear9's groups). About 3 min at load 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

SCENE = Path(__file__).resolve().parent.parent / "examples" / "reference" / "back-ears.toml"
GROUPS = ((0.0, 0.1), (0.1, 0.3), (0.3, 0.5), (0.5, 1.01))


def _sample(img, uv):
    """Nearest texel of a texture-space image (row 0 = top, v = 1) at uv."""
    h, w = img.shape[:2]
    x = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    y = np.clip(((1 - uv[:, 1]) * h).astype(int), 0, h - 1)
    return img[y, x]


def barycentric(pos, idx, tri, x):
    """(N, 3) barycentric weights of points x on triangles tri (idx: (T, 3)), from the positions."""
    a, b, c = pos[idx[tri, 0]], pos[idx[tri, 1]], pos[idx[tri, 2]]
    v0, v1, v2 = b - a, c - a, x - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    bb, bc = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
    return np.stack([1 - bb - bc, bb, bc], 1)


def _exit_uv(pos, idx, uvm, tri, x):
    """uv of points x on triangles tri (barycentric from positions)."""
    return np.einsum("nk,nkc->nc", barycentric(pos, idx, tri, x), uvm[idx[tri]])


def main(walks: int = 64, factor: int = 2):
    import dermis
    from dermis.blender.validate import region_masks
    from dermis.framing import framed_camera
    from dermis.reference.random_walk import DirectionalLight, MeshWalk
    from dermis.reference.render import camera_rays
    from dermis.renderer import Renderer
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B
    from ear_translucency import CYCLES_STORE

    sc = dermis.load_scene(SCENE)
    A = mean_skin_albedo(sc.material)
    sc.material.rho_s = 0.0
    sc.material.pore_strength = 0.0
    sc.material.albedo = None
    sc.material.albedo_color = tuple(A)
    sc.material.normal_map = None
    sc.environment.color = (0.0, 0.0, 0.0)
    sc.interreflection = False
    mm, S, mix, c = float(sc.mm_per_unit), 1024, float(sc.material.mix), 0
    with Renderer(sc, (128, 128), irradiance_size=S) as r:
        r.technique("tsd")
        from dermis.gl import subsurface_transfer as gst

        add = gst.SubsurfaceTransfer.add
        gst.SubsurfaceTransfer.add = lambda *a, **k: False  # tsd as it was, without the bake
        try:
            r.render("tsd")
            bufs = r.debug_buffers("tsd")
        finally:
            gst.SubsurfaceTransfer.add = add
    I0, D, T = bufs["irradiance"], bufs["diffuse_texture_space"], bufs["translucency"]
    Ib = bufs[f"blur_{gst.source_index(sc.profile.variances_mm2) + 1}"]
    z = np.load(CYCLES_STORE / "cycles_nospec_64x64.npz")
    spp = int(z["spp"])
    skin = (z["sums"][0][..., 3] / spp >= 0.999) & (z["sums"][1][..., 3] / spp >= 0.999)
    ear = region_masks(sc, (64, 64), skin)["back_lit_ear"]
    W = 64 * factor
    o, d, tmax, _ = camera_rays(sc, (W, W), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    sel = np.nonzero(np.repeat(np.repeat(ear, factor, 0), factor, 1).ravel())[0]
    pos = np.asarray(sc.mesh.positions, np.float64) * mm
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    uvm = np.asarray(sc.mesh.uvs, np.float64)
    w = MeshWalk(pos, idx)
    t, tri, bary = w.caster.closest_hit(o[sel] * mm, d[sel], 0.0, tmax[sel] * mm)
    hit = tri >= 0
    sel, t, tri, bary = sel[hit], t[hit], tri[hit], bary[hit]
    P = o[sel] * mm + d[sel] * t[:, None]
    b1, b2 = bary[:, :1], bary[:, 1:]
    uv = uvm[idx[tri, 0]] * (1 - b1 - b2) + uvm[idx[tri, 1]] * b1 + uvm[idx[tri, 2]] * b2
    nout = w._outward(tri, -d[sel])
    n = len(sel)
    L = sc.lights[0]
    to_light = -np.asarray(L.direction, np.float64) / np.linalg.norm(L.direction)
    light = [DirectionalLight(tuple(to_light), float(L.intensity * L.color[c]))]
    media = B.skin_media(sc.profile, A)
    kern = B.flat_kernel(media[c], 20_000)
    rep = np.repeat(np.arange(n), walks)
    k_out = A[c] ** (1 - mix) / np.pi
    nee_cam = w.radiance(P[rep], tri[rep], d[sel][rep], media[c], light, 0.0, seed=3).reshape(n, walks).mean(1)
    nee_dif = w.radiance(P[rep], tri[rep], B.diffuse_views(nout[rep], np.random.default_rng(5)), media[c], light, 0.0,
                         seed=4).reshape(n, walks).mean(1)
    # the diffuse-entry walk with tsd's irradiance, split by where it entered
    ex = B.walk_exits(w, P, tri, nout, media[c], walks, 7)
    pi = ex["point_index"]
    Ie = _sample(I0, _exit_uv(pos, idx, uvm, ex["triangle"], ex["point"]))[:, c]
    same = np.einsum("ij,ij->i", ex["normal"], nout[pi]) > 0
    g = B.SurfaceGraph(pos, idx, sc.mesh.normals, uvm)
    sv = g.nearest(P, tri)
    off = np.linalg.norm(g.position[sv] - P, axis=1)
    ve = g.nearest(ex["point"], ex["triangle"])
    G = g.distances(sv)
    ge = np.maximum(G[pi, ve] - off[pi] - np.linalg.norm(g.position[ve] - ex["point"], axis=1),
                    np.linalg.norm(ex["point"] - P[pi], axis=1))
    tau = ex["weight"] / (walks * kern.reflectance) * Ie * k_out
    parts = {"near": same & (ge <= B.MIN_SURFACE_MM), "far": same & (ge > B.MIN_SURFACE_MM), "opposite": ~same}
    walk = {k: np.bincount(pi, tau * m, n) for k, m in parts.items()}
    # the exact surface integral of tsd's profile at the geodesic distance
    Iv = _sample(I0, g.uv)[:, c]
    Rg = np.zeros(n)
    for i in range(n):
        fin = np.nonzero(np.isfinite(G[i]))[0]
        gv = np.maximum(G[i][fin] - off[i], np.linalg.norm(g.position[fin] - P[i], axis=1))
        Rg[i] = (B.profile_density(sc.profile, gv)[:, c] * g.area[fin] * Iv[fin]).sum() * k_out
    # the bake on these rays
    bake = B.bake_transfer(sc.mesh, mm, sc.profile, A, walks=walks, points=B.BakePoints(uv, P, tri, nout), media=media,
                           kernels=[kern, B.flat_kernel(media[1], 4000), B.flat_kernel(media[2], 4000)])
    geo = sum(bake.tap_weight[:, k, c] * _sample(Ib, bake.tap_uv[:, k])[:, c] for k in range(bake.tap_weight.shape[1])) * k_out
    td, tt = _sample(D, uv)[:, c] * k_out, _sample(T, uv)[:, c] * k_out
    share = tt / np.maximum(td + tt, 1e-12)
    # tsd's direct irradiance against a ray-cast N.L V at the rays' points (vertex normals)
    nv = w._shading_normal(tri, bary, nout)
    cos = nv @ to_light
    vis = np.zeros(n, bool)
    vis[cos > 0] = w._lit(P[cos > 0], nv[cos > 0], to_light)
    exact = np.maximum(cos, 0.0) * vis * light[0].irradiance * A[c] ** mix
    print(f"back_lit_ear, {n} rays ({factor}x{factor} a pixel), {walks} walks a ray, red; simplified material (mean albedo "
          f"{A[c]:.3f}, no maps, specular, environment or bounce)")
    print(f"tsd's irradiance map / ray-cast N.L V at the rays: {_sample(I0, uv)[:, c].sum() / exact.sum():.4f}")
    rows = [("all", np.ones(n, bool))] + [(f"{lo}-{hi:.1f}", (share >= lo) & (share < hi)) for lo, hi in GROUPS]
    print("| group | rays | skin walk (camera views) | walk (diffuse views) | diffuse-entry walk: near / far / opposite |"
          " R(g) integral | tsd D / T | tsd / walk cam | tsd / diffuse-entry | baked transfer | (tsd + bake) / walk cam |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, m in rows:
        dw = sum(v[m].sum() for v in walk.values())
        ts = (td + tt)[m].sum()
        print(f"| {name} | {int(m.sum())} | {nee_cam[m].sum():.2f} | {nee_dif[m].sum():.2f} | "
              f"{walk['near'][m].sum():.2f} / {walk['far'][m].sum():.2f} / {walk['opposite'][m].sum():.2f} | {Rg[m].sum():.2f} | "
              f"{td[m].sum():.2f} / {tt[m].sum():.2f} | {ts / nee_cam[m].sum():.3f} | {ts / dw:.3f} | {geo[m].sum():.2f} | "
              f"{(ts + geo[m].sum()) / nee_cam[m].sum():.3f} |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--walks", type=int, default=64)
    ap.add_argument("--factor", type=int, default=2)
    a = ap.parse_args()
    main(a.walks, a.factor)
