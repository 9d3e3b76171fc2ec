"""What the far-face shadow of ssss / preintegrated sees across the top of the back-lit scapha (issue 12,
round 18, farface18; review18's item 2: a hard red line and a dark patch there, Cycles glows smoothly).

common/transmittance.glsl lights a thin part's pixel P (interpolated normal Ng) from its far face
A = P - h Ng (h: the thickness bake the two techniques read, at half the irradiance size) when either
Q1 = A - 2.5 mm Ng or Q2 = A + 0.5 mm L sees the light in the shadow map. This script follows the same
points by ray casting in the head's own mesh (dermis.geometry.raycast), per pixel of the back-ears
768 px window (320, 280)-(420, 380), and prints, over review18's mean-red box (340, 292)-(362, 310) and
the whole window:
  - the surfaces along -Ng from P: the tissue's first exit (the far face), the air gap behind it and a
    second layer of tissue (thickness), and whether the far face there faces and sees the light;
  - whether Q1 and Q2 lie inside tissue (their first hit towards the light leaves tissue) or in air
    behind an occluder, and the distance along the light to the occluder's lit face.

    PYTHONPATH=src python benchmarks/farface_occluder.py

About 30 s (one ssss render at 768 px for the bake the shader reads, then ray casts).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cycles_crops  # noqa: E402
from helix_glow import SIZE, camera_hits  # noqa: E402

WINDOW = (320, 280, 420, 380)
BOX = (340, 292, 362, 310)  # review18's mean-red box: the dark patch
LIFT_MM, LIFT_ALONG_LIGHT_MM = 2.5, 0.5  # common/transmittance.glsl's FAR_FACE_LIFT_MM, ..._ALONG_LIGHT_MM


def shader_bake(sc):
    """The filtered thickness bake ssss reads (thickness x valid, valid), its size, and the render's mesh."""
    from dermis.gl.thickness import _BAKES
    from dermis.renderer import Renderer

    with Renderer(sc, (SIZE, SIZE), irradiance_size=1024) as r:
        r.render("ssss")
        mesh = r.scene.mesh
        bake = [v for k, v in _BAKES.items() if k[0] == "lit"][-1][0]  # (smoothed, unsmoothed): the smoothed
    return np.stack([bake[..., 2] * bake[..., 3], bake[..., 3]], -1), mesh


def bilinear(img, uv):
    """GL's bilinear lookup of (S, S, C) ``img`` (row 0 = v 1, texel centres at (i + 0.5) / S, clamped)."""
    S = img.shape[0]
    x, y = uv[:, 0] * S - 0.5, (1.0 - uv[:, 1]) * S - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    g = lambda xx, yy: img[np.clip(yy, 0, S - 1), np.clip(xx, 0, S - 1)]  # noqa: E731
    return (g(x0, y0) * (1 - fx) * (1 - fy) + g(x0 + 1, y0) * fx * (1 - fy) + g(x0, y0 + 1) * (1 - fx) * fy
            + g(x0 + 1, y0 + 1) * fx * fy)


def main():
    import dermis
    from dermis.geometry.texture_space import texture_space_uvs

    sc = dermis.load_scene(cycles_crops.SCENES["back-ears"])
    sc.material.pore_strength = 0.0
    data, mesh = shader_bake(sc)
    sc.mesh = mesh
    rc, d, p, tri, b, n, (N, I) = camera_hits(sc, WINDOW)
    mm = float(sc.mm_per_unit)
    L = -np.asarray(sc.lights[0].direction, np.float64)
    L /= np.linalg.norm(L)
    w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
    uv = np.einsum("ij,ijk->ik", w, np.asarray(texture_space_uvs(mesh), np.float64)[I[np.maximum(tri, 0)]])
    th = bilinear(data, uv)
    h = np.where(th[:, 1] > 0, th[:, 0] / np.maximum(th[:, 1], 1e-12), np.nan)

    def walk(O, D, k):
        """The first k surface crossings from O along D: distances (mm) and +1 (leaves tissue) / -1 (enters)."""
        dist = np.full((len(O), k), np.nan)
        kind = np.zeros((len(O), k))
        s = np.zeros(len(O))
        live = np.ones(len(O), bool)
        for j in range(k):
            t, ht, hb = rc.closest_hit(O, D, 1e-6, np.inf)
            live &= ht >= 0
            hw = np.stack([1 - hb[:, 0] - hb[:, 1], hb[:, 0], hb[:, 1]], 1)
            hn = np.einsum("ij,ijk->ik", hw, N[I[np.maximum(ht, 0)]])
            s = s + np.where(live, t, 0.0)
            dist[live, j] = s[live] * mm
            kind[live, j] = np.sign(np.einsum("ij,ij->i", hn, D))[live]
            O = O + D * np.where(live, t, 0.0)[:, None] + D * 1e-6
        return dist, kind

    thin = np.isfinite(h) & (tri >= 0)
    along, kind_n = walk(p - n * 1e-6, -n, 3)
    A = p - n * (np.nan_to_num(h) / mm)[:, None]
    Lb = np.broadcast_to(L, p.shape)
    F = p - n * (np.nan_to_num(along[:, 0]) / mm)[:, None]  # the first exit along -Ng: the far face
    tF, trF, bF = rc.closest_hit(p - n * 1e-6, -n, 1e-6, np.inf)
    hwF = np.stack([1 - bF[:, 0] - bF[:, 1], bF[:, 0], bF[:, 1]], 1)
    nF = np.einsum("ij,ijk->ik", hwF, N[I[np.maximum(trF, 0)]])
    nF /= np.linalg.norm(nF, axis=1, keepdims=True)
    F_lit = (nF @ L > 0) & (rc.closest_hit(F + nF * (0.05 / mm), Lb, 0.0, np.inf)[1] < 0)
    out = {}
    for name, Q in (("Q1", A - n * (LIFT_MM / mm)), ("Q2", A + L * (LIFT_ALONG_LIGHT_MM / mm))):
        dq, kq = walk(Q, Lb, 2)
        out[name] = (kq[:, 0] > 0, kq[:, 0] < 0, dq)  # inside tissue, in air behind an occluder, distances

    x0, y0, x1, y1 = WINDOW
    ys, xs = np.mgrid[y0:y1, x0:x1]
    ys, xs = ys.ravel(), xs.ravel()
    box = (xs >= BOX[0]) & (xs < BOX[2]) & (ys >= BOX[1]) & (ys < BOX[3]) & thin
    q = lambda v: " / ".join(f"{x:.2f}" for x in np.nanpercentile(v, [25, 50, 75])) if np.isfinite(v).any() else "-"  # noqa: E731
    for label, m in (("mean-red box " + str(BOX), box), ("window " + str(WINDOW) + ", thin pixels", thin)):
        gap = (kind_n[:, 0] > 0) & (kind_n[:, 1] < 0) & (along[:, 1] - along[:, 0] < 5.0) & np.isfinite(along[:, 2])
        print(f"\n{label}: {int(m.sum())} px")
        print(f"  bake h p25/50/75 {q(h[m])} mm; first exit along -Ng {q(along[m, 0])} mm; cos_far = -Ng.L {q(-(n[m] @ L))}")
        print(f"  far face (first exit) faces the light {float((nF[m] @ L > 0).mean()):.2f}, sees it (ray cast) {float(F_lit[m].mean()):.2f}")
        print(f"  behind it an air gap < 5 mm, then a second layer: {float(gap[m].mean()):.2f} of the px; gap {q((along[:, 1] - along[:, 0])[m & gap])} mm, "
              f"layer {q((along[:, 2] - along[:, 1])[m & gap])} mm thick")
        for name, (inside, behind, dq) in out.items():
            print(f"  {name}: inside tissue {float(inside[m].mean()):.2f}, in air behind an occluder {float(behind[m].mean()):.2f} "
                  f"(occluder's lit face {q(dq[m & behind, 1])} mm away along L), sees the light {float((~inside & ~behind)[m].mean()):.2f}")


if __name__ == "__main__":
    main()
