"""Where the environment scene's error against Cycles lives (benchmarks/RESULTS.md, "Environment
against Cycles (round 7, branch env7)").

    PYTHONPATH=src python benchmarks/environment_bands.py STORE [VARIANT ...]

STORE holds environment/cycles_spec_64x64.npz and cycles_spec_nosss_64x64.npz (a COPY of the
converged stores: dermis.blender.validate's layout); nothing is rendered by Cycles. VARIANT:
``technique[:novis][:nospec][:nobounce]`` (occlusion off, rho_s = 0, interreflection off), default
tsd. Prints the whole-skin and per-band mean FLIP and per-channel mean ratio of the control (Cycles
without SSS) and each variant, the bands being the validate regions plus the ray-cast ambient
occlusion A of each pixel's visible point (A < 0.6, 0.6-0.8, >= 0.8) and N.V < 0.3; then the
occluded irradiance at those points, A E_sh(bent normal) and r E_sh(n) (dermis.geometry.visibility,
256 rays) against a 4096-ray integral of V L cos with the full image.
"""

from __future__ import annotations

import sys

import numpy as np

SCENE = "examples/reference/environment.toml"
SIZE, SS = (64, 64), 4


def _stream_mean(path):
    with np.load(path) as z:
        return z["sums"] / int(z["spp"])


def pixel_geometry(sc):
    """Per pixel (camera rays): the ray caster, visible point, interpolated normal, view direction, hit
    mask, triangle (0 where none) and barycentric weights, the mesh's bounding diagonal."""
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    m = sc.mesh
    pos = np.asarray(m.positions, np.float64)
    idx = np.asarray(m.indices, np.int64).reshape(-1, 3)
    rc = RayCaster(pos, idx)
    o, d, tmax, _ = camera_rays(sc, SIZE, 1, camera=framed_camera(sc.camera, m, SIZE[0] / SIZE[1]))
    t, tri, bc = rc.closest_hit(o, d, 0.0, tmax)
    hit = tri >= 0
    tt = np.where(hit, tri, 0)
    w = np.stack([1 - bc[:, 0] - bc[:, 1], bc[:, 0], bc[:, 1]], 1)
    n = (np.asarray(m.normals, np.float64)[idx[tt]] * w[..., None]).sum(1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    P = o + d * np.where(hit, t, 0)[:, None]
    return rc, P, n, d, hit, tt, w, float(np.linalg.norm(pos.max(0) - pos.min(0)))


def irradiance_check(sc, rc, P, n, sel, diag, bands):
    from dermis.environment import environment_sh, irradiance_sh_eval
    from dermis.geometry.raycast import ambient_directions
    from dermis.geometry.visibility import environment_radiance, occluded_fraction
    from dermis.prefiltered_environment import bilinear_equirect, direction_to_equirect

    img = environment_radiance(sc.environment)
    sh = environment_sh(sc.environment).astype(np.float64)

    def cast(k, seed):
        d = ambient_directions(n[sel], k, seed)
        occ = rc.occluded(np.repeat(P[sel] + n[sel] * 1e-5 * diag, k, 0), d.reshape(-1, 3), 0.0, np.inf)
        return d, occ.reshape(len(sel), k)

    d, occ = cast(4096, 7)
    u, v = direction_to_equirect(d.reshape(-1, 3))
    L = bilinear_equirect(img, u, v).reshape(len(sel), 4096, 3)
    truth = np.pi * (L * (~occ)[..., None]).mean(1)
    d, occ = cast(256, 3)
    ao = (~occ).mean(1)
    bent = (2 / 3) * n[sel] - (d * occ[..., None]).mean(1)
    bent /= np.linalg.norm(bent, axis=1, keepdims=True)
    est = {"A E_sh(B)": ao[:, None] * irradiance_sh_eval(sh, bent),
           "r E_sh(n)": occluded_fraction(sh, img, n[sel], ao, d, occ) * irradiance_sh_eval(sh, n[sel])}
    for name, e in est.items():
        cells = []
        for b, m in bands.items():
            m = m.reshape(-1)[sel]
            if m.sum():
                cells.append(f"{b} {np.abs(e[m] / truth[m] - 1).mean():.3f} (bias "
                             f"{'/'.join(f'{x:.3f}' for x in e[m].mean(0) / truth[m].mean(0))})")
        print(f"  {name:10s} mean |rel. error|: " + "  ".join(cells))


def main(argv):
    import dermis
    from dermis.blender.pixel_filter import reconstruct
    from dermis.blender.validate import _score, region_masks
    from dermis.geometry.visibility import mesh_visibility
    from dermis.reference.validate import _render

    store = argv[0]
    variants = argv[1:] or ["tsd"]
    a = _stream_mean(f"{store}/environment/cycles_spec_64x64.npz")
    ref = 0.5 * (a[0, ..., :3] + a[1, ..., :3])
    skin = (a[0, ..., 3] >= 0.999) & (a[1, ..., 3] >= 0.999)
    ctrl = _stream_mean(f"{store}/environment/cycles_spec_nosss_64x64.npz")[0, ..., :3]

    def scene():
        sc = dermis.load_scene(SCENE)
        sc.material.pore_strength = 0.0
        return sc

    sc = scene()
    regions = region_masks(sc, SIZE, skin)
    rc, P, n, d, hit, tri, wts, diag = pixel_geometry(sc)
    h, w = SIZE[1], SIZE[0]
    # A of each pixel's visible point: the per-vertex bake, interpolated (as the techniques see it)
    vis = mesh_visibility(sc.mesh)
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    ao = (vis.ao[idx[tri]] * wts).sum(1).reshape(h, w)
    ndv = (-(n * d).sum(1)).reshape(h, w)
    bands = {"A<0.6": skin & (ao < 0.6), "A0.6-0.8": skin & (ao >= 0.6) & (ao < 0.8), "A>=0.8": skin & (ao >= 0.8),
             "N.V<0.3": skin & (ndv < 0.3)}
    regions.update(bands)

    def report(label, img):
        m, _ = _score(sc, ref, img, skin, regions)
        print(f"{label:24s} FLIP {m['flip']:.4f}  ratio {'/'.join(f'{x:.3f}' for x in m['mean_ratio'])}")
        for k, v in m["regions"].items():
            print(f"    {k:10s} {v['flip']:.4f}  ratio {'/'.join(f'{x:.3f}' for x in v['mean_ratio'])}  ({v['pixels']} px)")

    report("control", ctrl)
    for var in variants:
        sc = scene()
        tech, *opts = var.split(":")
        if "novis" in opts:
            sc.environment.occlusion = False
        if "nospec" in opts:
            sc.material.rho_s = 0.0
        if "nobounce" in opts:
            sc.interreflection = False
        big, _ = _render(sc, tech, (SIZE[0] * SS, SIZE[1] * SS))
        report(var, reconstruct(big[..., :3], SS))
    print("occluded irradiance at the visible points vs a 4096-ray integral of V L cos:")
    irradiance_check(scene(), rc, P, n, np.flatnonzero(hit), diag, {**bands, "lips": regions.get("lips", skin & False)})


if __name__ == "__main__":
    main(sys.argv[1:])
