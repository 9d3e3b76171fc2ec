"""How much light tsd's blur leaves out at a pixel patch because it does not cross UV seams (issue 12,
round 21, demo21): per Gaussian of the profile, tsd's own blurred level I_k at the patch's texels against
an independent numpy convolution of tsd's irradiance I_0 over the surface in 3-D, once within the patch's
chart only (what tsd computes: its blurs are coverage-normalised per chart, tsd/blur.frag) and once over
every chart (what light does: a chart seam is not a boundary of the skin).

    PYTHONPATH=src python benchmarks/seam_crossing.py [SCENE.toml | default] --patch X0 Y0 X1 Y1
        [--size 768] [--buffers B.npz]

The numpy side: texel centres' positions in mm (dermis.verification.texel_positions), each texel's
surface area (its triangle's 3-D area over its UV area), the charts = connected covered texels (the
gutters separate them), and G(v_k, |p - q|) with the Euclidean distance (in a crease it is shorter than
the path over the skin: an upper bound on what crosses there). Each level is normalised by its own weight
sum, as tsd's coverage-normalised blur is. The patch's pixels are mapped to texels by a ray cast of the
frame's camera through the texture-space layout. Prints, per level and for sum_k w_k I_k (the profile's
normalised weights): tsd, numpy in-chart, numpy all charts; "all / in-chart" is what crossing the seam
would change (x the pixel, other terms equal).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def patch_texels(scene, mesh, size: int, box, S: int):
    """(row, col) of the texel (S x S, row 0 at the top) under each pixel centre of ``box`` (frame pixels,
    x1 / y1 exclusive): the nearest triangle along the camera ray, its texture-space UV."""
    from dermis.camera import camera_matrices
    from dermis.framing import framed_camera
    from dermis.geometry.texture_space import texture_space_uvs

    cam = framed_camera(scene.camera, scene.mesh, 1.0)
    lo, hi = scene.bounds()
    view, proj, _, _, _ = camera_matrices(cam, 1.0, lo, hi)
    P = np.asarray(mesh.positions, np.float64)
    T = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    uv = texture_space_uvs(mesh)
    h = np.c_[P, np.ones(len(P))] @ (proj @ view).T
    ndc = h[:, :3] / h[:, 3:4]
    sx, sy, z = (ndc[:, 0] * 0.5 + 0.5) * size, (0.5 - ndc[:, 1] * 0.5) * size, ndc[:, 2]
    x0, y0, x1, y1 = box
    near = (sx[T].max(1) >= x0) & (sx[T].min(1) <= x1) & (sy[T].max(1) >= y0) & (sy[T].min(1) <= y1)
    a, b, c = T[near].T
    out = []
    for y in range(y0, y1):
        for x in range(x0, x1):
            px, py = x + 0.5, y + 0.5
            d = (sy[b] - sy[c]) * (sx[a] - sx[c]) + (sx[c] - sx[b]) * (sy[a] - sy[c])
            l1 = ((sy[b] - sy[c]) * (px - sx[c]) + (sx[c] - sx[b]) * (py - sy[c])) / d
            l2 = ((sy[c] - sy[a]) * (px - sx[c]) + (sx[a] - sx[c]) * (py - sy[c])) / d
            l3 = 1 - l1 - l2
            inside = (l1 >= 0) & (l2 >= 0) & (l3 >= 0)
            if not inside.any():
                continue
            k = np.argmin(np.where(inside, l1 * z[a] + l2 * z[b] + l3 * z[c], np.inf))
            u, v = l1[k] * uv[a[k]] + l2[k] * uv[b[k]] + l3[k] * uv[c[k]]
            out.append((min(int((1 - v) * S), S - 1), min(int(u * S), S - 1)))
    return out


def tsd_buffers(scene, size: int, out: Path):
    """Render tsd (the texture sizes ``dermis render`` picks) and keep what the comparison needs."""
    from dermis.geometry.rasterize import rasterize_uv
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.renderer import Renderer
    from dermis.verification import texel_positions

    with Renderer(scene, (size, size), irradiance_size=None, shadow_size=None) as r:
        r.render("tsd")
        db = r.technique("tsd").debug_buffers()
        mesh, S = r.scene.mesh, r.irradiance_size
    mm = float(scene.mm_per_unit)
    pos, cov = texel_positions(mesh, S)
    uv = texture_space_uvs(mesh)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    tri, _ = rasterize_uv(uv, mesh.indices, S, S)
    P = np.asarray(mesh.positions, np.float64) * mm
    a3 = 0.5 * np.linalg.norm(np.cross(P[idx[:, 1]] - P[idx[:, 0]], P[idx[:, 2]] - P[idx[:, 0]]), axis=1)
    U = uv[idx] * S
    auv = 0.5 * np.abs((U[:, 1, 0] - U[:, 0, 0]) * (U[:, 2, 1] - U[:, 0, 1])
                       - (U[:, 2, 0] - U[:, 0, 0]) * (U[:, 1, 1] - U[:, 0, 1]))
    t = np.maximum(tri, 0)
    area = np.where(cov, a3[t] / np.maximum(auv[t], 1e-12), 0.0)  # mm^2 of surface per texel
    blurs = {k: db[k] for k in db if k.startswith("blur_")}
    np.savez_compressed(out, I0=db["irradiance"], pos=pos * mm, cov=cov, area=area, **blurs)
    return mesh


def compare(scene, buffers: Path, texels) -> dict:
    from scipy import ndimage

    z = np.load(buffers)
    I0, pos, cov, area = z["I0"][..., :3].astype(np.float64), z["pos"], z["cov"], z["area"]
    S = cov.shape[0]
    charts, _ = ndimage.label(cov)
    prof = scene.profile.normalized()
    v, w = prof.variances_mm2, prof.weights
    blurs = [z[f"blur_{k + 1}"] for k in range(len(v))]
    reach = 3 * np.sqrt(v[-1])  # tsd's taps stop at 3 sigma (tsd/blur.frag)

    def conv(row, col):
        d2 = np.sum(np.nan_to_num(pos - pos[row, col], nan=1e9) ** 2, axis=2)
        near = (d2 < reach ** 2) & cov
        same = charts[near] == charts[row, col]
        g = np.exp(-d2[near][:, None] / (2 * v)) * area[near][:, None]  # (n, K); 1/(2 pi v) cancels
        allc = (g.T @ I0[near]) / g.sum(0)[:, None]
        chart = (g[same].T @ I0[near][same]) / g[same].sum(0)[:, None]
        return chart, allc

    texels = [t for t in texels if cov[t]]
    chart, allc = (np.mean(x, 0) for x in zip(*[conv(r, c) for r, c in texels]))
    tsd = np.mean([[b[int(r * b.shape[0] / S), int(c * b.shape[1] / S), :3] for b in blurs] for r, c in texels], 0)
    rep = {"texels": len(texels), "charts": sorted({int(charts[t]) for t in texels}),
           "I0": np.mean([I0[t] for t in texels], 0).round(4).tolist(), "levels": []}
    print(f"{len(texels)} texels in charts {rep['charts']}; I_0 {rep['I0']}")
    for k in range(len(v)):
        print(f"  k{k + 1} v {v[k]:.4f} mm^2: tsd {np.round(tsd[k], 4)}  numpy in-chart {np.round(chart[k], 4)}  "
              f"all charts {np.round(allc[k], 4)}  tsd / in-chart {np.round(tsd[k] / chart[k], 3)}")
        rep["levels"].append({"v": float(v[k]), "tsd": tsd[k].tolist(), "chart": chart[k].tolist(), "all": allc[k].tolist()})
    sums = {n: (w * x).sum(0) for n, x in (("tsd", tsd), ("chart", chart), ("all", allc))}
    for n, s in sums.items():
        print(f"  sum w_k I_k {n:6s} {np.round(s, 4)} R/G {s[0] / s[1]:.3f}")
    print(f"  all / in-chart {np.round(sums['all'] / sums['chart'], 3)}")
    rep["sums"] = {n: s.tolist() for n, s in sums.items()}
    return rep


def main(argv=None):
    import dermis

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="default")
    ap.add_argument("--patch", type=int, nargs=4, required=True)
    ap.add_argument("--size", type=int, default=768)
    ap.add_argument("--buffers", default=None, help="tsd's buffers (written when absent)")
    a = ap.parse_args(argv)
    sc = dermis.default_scene() if a.scene == "default" else dermis.load_scene(a.scene)
    sc.material.pore_strength = 0.0  # as the Cycles comparisons
    buf = Path(a.buffers or "/tmp/seam_crossing_buffers.npz")
    from dermis.geometry.texture_space import scene_texture_space

    if not buf.is_file():
        mesh = tsd_buffers(sc, a.size, buf)
    else:  # the layout tsd used (the mesh's own UVs, or the generated one at this irradiance size)
        with np.load(buf) as z:
            mesh = scene_texture_space(sc, int(z["cov"].shape[0]))
    S = int(np.load(buf)["cov"].shape[0])
    return compare(sc, buf, patch_texels(sc, mesh, a.size, a.patch, S))


if __name__ == "__main__":
    main()
