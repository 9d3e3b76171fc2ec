"""Per-vertex tangent frames from UVs, in the MikkTSpace convention.

Per triangle, T = dP/du and B = dP/dv are solved from the edge vectors and UV deltas
(Lengyel 2001; the basis MikkTSpace builds on), accumulated per vertex weighted by the corner
angle, Gram-Schmidt orthogonalised against the vertex normal, and the handedness
w = sign(dot(cross(N, T), B)) is stored so that the shader rebuilds B = w * cross(N, T).
Mikkelsen's full algorithm also splits vertices where frames disagree; meshes that need it
ship their own tangents, which loaders keep.
"""

from __future__ import annotations

import numpy as np


def _normalize(v, eps=1e-20):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps)


def generate_tangents(positions, normals, uvs, indices) -> np.ndarray:
    """Return (N, 4) float32 tangents; w = +1 or -1 (handedness)."""
    p = positions.astype(np.float64)
    t = uvs.astype(np.float64)
    nrm = _normalize(normals.astype(np.float64))
    i0, i1, i2 = indices[:, 0], indices[:, 1], indices[:, 2]
    e1, e2 = p[i1] - p[i0], p[i2] - p[i0]
    d1, d2 = t[i1] - t[i0], t[i2] - t[i0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    r = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    tan = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r  # dP/du
    bit = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r  # dP/dv
    # corner angles as weights (MikkTSpace weights by angle, so tessellation does not bias)
    tan_acc = np.zeros_like(p)
    bit_acc = np.zeros_like(p)
    corners = [(i0, p[i1] - p[i0], p[i2] - p[i0]), (i1, p[i2] - p[i1], p[i0] - p[i1]), (i2, p[i0] - p[i2], p[i1] - p[i2])]
    for idx, a, b in corners:
        cosang = np.sum(_normalize(a) * _normalize(b), axis=1).clip(-1, 1)
        w = np.arccos(cosang)[:, None]
        np.add.at(tan_acc, idx, _normalize(tan) * w)
        np.add.at(bit_acc, idx, _normalize(bit) * w)
    # Gram-Schmidt against the normal
    tan_o = tan_acc - nrm * np.sum(nrm * tan_acc, axis=1, keepdims=True)
    bad = np.linalg.norm(tan_o, axis=1) < 1e-12
    if np.any(bad):  # no UV gradient: any vector perpendicular to N
        helper = np.where(np.abs(nrm[:, 0:1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        alt = np.cross(nrm, helper)
        tan_o[bad] = alt[bad]
    tan_o = _normalize(tan_o)
    w = np.sign(np.sum(np.cross(nrm, tan_o) * bit_acc, axis=1))
    w[w == 0] = 1.0
    return np.concatenate([tan_o, w[:, None]], axis=1).astype(np.float32)
