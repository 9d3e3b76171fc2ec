"""Where a mesh's texture-space UV seams lie in a scene's frame, and what tsd loses or gains near them
(issue 12, round 22, seams22).

    PYTHONPATH=src python benchmarks/seam_map.py map SCENE.toml [--size 768] [--png OUT.png]
    PYTHONPATH=src python benchmarks/seam_map.py strips RENDERS.npz SCENE.toml [--size 768]

``map``: the seam edges (dermis.geometry.seams.seam_sides: an edge whose two triangles' UVs differ by
more than 2 texels of a 2048 layout), their length, the part of them the camera sees (facing, not
occluded: a ray cast from the eye), and for every visible pixel the 3-D (Euclidean) distance to the
nearest seam point: the pixel counts within 2/4/8/12 mm (3 sigma of d'Eon's widest Gaussian is 8.2 mm;
the distance over the skin is at least this). ``--png``: that distance as colours (red < 2, yellow
< 4, green < 8, blue < 12 mm). ``strips``: per stored Cycles crop of the scene (benchmarks/cycles/crops),
the linear RGB ratio of each technique in RENDERS.npz (look_zoom.py render-npz) to Cycles over the crop's
skin, binned by that distance: a seam that loses light shows as tsd's ratio dropping towards the seam
while ssss's (screen space: no seams) does not.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
BINS_MM = (3.5, 5.0, 6.5, 8.0, 12.0, 1e9)


def seam_distance(scene, size: int):
    """(S, S) float: mm from each pixel's visible surface point to the nearest seam point (inf: no
    hit), the seam edges' total length (mm), their visible length (mm)."""
    from scipy.spatial import cKDTree

    from dermis.camera import camera_matrices
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.geometry.seams import seam_sides
    from dermis.geometry.texture_space import scene_texture_space, texture_space_uvs

    mesh = scene_texture_space(scene, 2048)
    P = np.asarray(mesh.positions, np.float64)
    T = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    sides = seam_sides(mesh.positions, mesh.indices, texture_space_uvs(mesh), 2.0 / 2048)
    n_edges = len(sides[0]) // 2
    pa, pb = sides[8][:n_edges], sides[9][:n_edges]  # one side per edge
    mm = float(scene.mm_per_unit)
    L = np.linalg.norm(pb - pa, axis=1) * mm
    k = np.maximum(np.ceil(L / 0.25).astype(int), 1)
    e = np.repeat(np.arange(n_edges), k)
    f = (np.concatenate([np.arange(j) for j in k]) + 0.5) / np.repeat(k, k) if n_edges else np.zeros(0)
    X = pa[e] * (1 - f[:, None]) + pb[e] * f[:, None]
    cam = framed_camera(scene.camera, scene.mesh, 1.0)
    lo, hi = scene.bounds()
    view, proj, eye, _, _ = camera_matrices(cam, 1.0, lo, hi)
    eye = np.asarray(eye, np.float64)
    rc = RayCaster(P, T)
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    ndc = np.stack([xs / size * 2 - 1, 1 - ys / size * 2, np.ones_like(xs), np.ones_like(xs)], -1).reshape(-1, 4)
    w = ndc @ np.linalg.inv(proj @ view).T
    d = w[:, :3] / w[:, 3:4] - eye
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = rc.hit_distances(np.broadcast_to(eye, d.shape), d, 0.0, np.inf)
    hit = np.isfinite(t)
    dist = np.full(size * size, np.inf)
    visible_mm = 0.0
    if len(X):
        dist[hit] = cKDTree(X).query(eye + d[hit] * t[hit, None])[0] * mm
        v = X - eye
        r = np.linalg.norm(v, axis=1)
        seen = rc.hit_distances(np.broadcast_to(eye, X.shape), v / r[:, None], 0.0, np.inf) > r * 0.999
        h = np.c_[X, np.ones(len(X))] @ (proj @ view).T
        q = h[:, :2] / h[:, 3:4]
        seen &= np.all(np.abs(q) < 1.0, axis=1)  # inside the frame
        visible_mm = float(0.25 * seen.sum())
    return dist.reshape(size, size), float(L.sum()), visible_mm


def cmd_map(a):
    import dermis

    sc = dermis.load_scene(a.scene)
    dist, total, visible = seam_distance(sc, a.size)
    counts = {mm: int((dist < mm).sum()) for mm in (2, 4, 8, 12)}
    print(f"{a.scene}: seams {total:.0f} mm, visible ~{visible:.0f} mm; pixels within 2/4/8/12 mm of a seam: "
          f"{counts[2]} / {counts[4]} / {counts[8]} / {counts[12]} (of {int(np.isfinite(dist).sum())} on the mesh)")
    if a.png:
        from PIL import Image

        rgb = np.where(np.isfinite(dist)[..., None], 60, 0).astype(np.uint8).repeat(3, -1)
        for mm, c in ((12, (0, 0, 160)), (8, (0, 160, 0)), (4, (255, 255, 0)), (2, (255, 0, 0))):
            rgb[dist < mm] = c
        Image.fromarray(rgb).save(a.png)


def cmd_strips(a):
    import dermis

    sys.path.insert(0, str(REPO / "benchmarks"))
    import cycles_crops

    sc = dermis.load_scene(a.scene)
    stem = Path(a.scene).stem
    dist, _, _ = seam_distance(sc, a.size)
    z = np.load(a.renders)
    techs = [k[4:] for k in z.files if k.startswith("img_")]
    for lm in cycles_crops.frame_boxes(sc, a.size):
        c = cycles_crops.load_crop(cycles_crops.OUT, stem, lm)
        if c is None:
            continue
        rgba, meta = c
        x0, y0, x1, y1 = meta["box"]
        dd, skin = dist[y0:y1, x0:x1], rgba[..., 3] >= 0.999
        for lo, hi in zip(BINS_MM[:-1], BINS_MM[1:]):
            m = skin & (dd >= lo) & (dd < hi)
            if m.sum() < 30:
                continue
            cyc = rgba[..., :3][m].mean(0)
            row = "  ".join(f"{t} {np.round(z['img_' + t][y0:y1, x0:x1, :3][m].mean(0) / cyc, 3).tolist()}" for t in techs)
            print(f"{stem:16s} {lm:7s} {lo:4.1f}-{min(hi, 99):4.1f} mm  n {int(m.sum()):5d}  / Cycles: {row}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("map")
    p.add_argument("scene")
    p.add_argument("--size", type=int, default=768)
    p.add_argument("--png")
    p = sub.add_parser("strips")
    p.add_argument("renders")
    p.add_argument("scene")
    p.add_argument("--size", type=int, default=768)
    a = ap.parse_args(argv)
    {"map": cmd_map, "strips": cmd_strips}[a.cmd](a)


if __name__ == "__main__":
    main()
