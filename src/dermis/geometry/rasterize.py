"""Rasterising a mesh in its UV layout on the CPU (numpy): for every texel centre, the triangle
that covers it and its barycentric coordinates, and how many triangles cover it.

The texture convention is dermis's (scene/model.py): v = 0 is the BOTTOM row of the image, image
arrays keep row 0 at the top. Texel (row, col) has its centre at u = (col + 0.5) / W,
v = 1 - (row + 0.5) / H. A texel centre on a shared edge belongs to both triangles' tests (edge
functions with a 1e-6 tolerance); the last triangle written wins ``tri``, ``count`` counts both,
so overlap tests use a margin (see ``overlap_fraction``).
"""

from __future__ import annotations

import numpy as np

_CHUNK_TEXELS = 1_500_000  # candidate texels evaluated per numpy step (memory, not speed)


def rasterize_uv(uv, indices, width: int, height: int, *, count: bool = False):
    """``uv`` (N, 2), ``indices`` (M, 3). Returns ``tri`` (H, W) int32 (-1: not covered) and
    ``bary`` (H, W, 3) float32; with ``count=True`` also (H, W) int32 coverage counts."""
    uv = np.asarray(uv, np.float64)
    T = np.asarray(indices, np.int64).reshape(-1, 3)
    W, H = int(width), int(height)
    x = uv[:, 0] * W - 0.5  # texel-centre coordinates (col)
    y = (1.0 - uv[:, 1]) * H - 0.5  # (row)
    tx, ty = x[T], y[T]
    c0 = np.clip(np.ceil(tx.min(1) - 1e-9), -1, W).astype(np.int64)
    c1 = np.clip(np.floor(tx.max(1) + 1e-9), -1, W).astype(np.int64)
    r0 = np.clip(np.ceil(ty.min(1) - 1e-9), -1, H).astype(np.int64)
    r1 = np.clip(np.floor(ty.max(1) + 1e-9), -1, H).astype(np.int64)
    c0, r0 = np.maximum(c0, 0), np.maximum(r0, 0)
    c1, r1 = np.minimum(c1, W - 1), np.minimum(r1, H - 1)
    nw, nh = c1 - c0 + 1, r1 - r0 + 1
    tri = np.full(H * W, -1, np.int32)
    bary = np.zeros((H * W, 3), np.float32)
    cnt = np.zeros(H * W, np.int64) if count else None
    d = (tx[:, 1] - tx[:, 0]) * (ty[:, 2] - ty[:, 0]) - (tx[:, 2] - tx[:, 0]) * (ty[:, 1] - ty[:, 0])
    ok = (nw > 0) & (nh > 0) & (d != 0)
    sz = np.maximum(nw, nh)
    for s in np.unique(sz[ok]):
        sel = np.nonzero(ok & (sz == s))[0]
        oy, ox = np.divmod(np.arange(s * s), s)
        for ch in np.array_split(sel, max(1, len(sel) * s * s // _CHUNK_TEXELS + 1)):
            cx = c0[ch, None] + ox[None]
            cy = r0[ch, None] + oy[None]
            ax, ay = tx[ch, 0, None], ty[ch, 0, None]
            dd = d[ch, None]
            w1 = ((cx - ax) * (ty[ch, 2, None] - ay) - (tx[ch, 2, None] - ax) * (cy - ay)) / dd
            w2 = ((tx[ch, 1, None] - ax) * (cy - ay) - (cx - ax) * (ty[ch, 1, None] - ay)) / dd
            w0 = 1.0 - w1 - w2
            ins = (w0 >= -1e-6) & (w1 >= -1e-6) & (w2 >= -1e-6) & (cx <= c1[ch, None]) & (cy <= r1[ch, None])
            pix = (cy * W + cx)[ins]
            tri[pix] = np.broadcast_to(ch[:, None], ins.shape)[ins]
            bary[pix] = np.stack([w0[ins], w1[ins], w2[ins]], 1)
            if count:
                cnt += np.bincount(pix, minlength=H * W)
    tri, bary = tri.reshape(H, W), bary.reshape(H, W, 3)
    if count:
        return tri, bary, cnt.reshape(H, W).astype(np.int32)
    return tri, bary


def overlap_fraction(uv, indices, resolution: int = 512) -> float:
    """Fraction of covered texels that two or more triangles cover: 0 for a unique layout, about
    0.5 for a mirrored one. Shared edges are not counted (every UV triangle is first shrunk
    towards its centroid by a third of a texel). Only [0, 1]^2 is looked at."""
    uv = np.asarray(uv, np.float64)
    T = np.asarray(indices, np.int64).reshape(-1, 3)
    R = int(resolution)
    # shrink every UV triangle towards its centroid by a third of a texel so that neighbours
    # sharing an edge do not both cover the texel centres on it
    tu = uv[T]
    c = tu.mean(1, keepdims=True)
    r = np.linalg.norm(tu - c, axis=2, keepdims=True)
    shrink = np.clip(1.0 - (0.34 / R) / np.maximum(r, 1e-12), 0.0, 1.0)
    tu = c + (tu - c) * shrink
    flat = tu.reshape(-1, 2)
    _, _, cnt = rasterize_uv(flat, np.arange(len(flat)).reshape(-1, 3), R, R, count=True)
    covered = (cnt > 0).sum()
    return float((cnt > 1).sum() / covered) if covered else 0.0
