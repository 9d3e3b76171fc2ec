"""Flattening one surface chart into the plane, and joining xatlas charts so a seam leaves a region.

Why (issue 12, round 21, seam21): tsd's blurs are coverage-normalised per chart, so light does not
cross a UV seam; where a seam runs between a lit and a shadowed part of the skin (the procedural head's
nose underside and upper lip) the shadowed side misses the red the lit side would scatter into it.
xatlas (dermis.geometry.atlas) places its seams by a cost of normal deviation and boundary length, which
puts them exactly in creases. ``join_charts`` merges every chart that reaches into given boxes into
one, flattens it with a least-squares conformal map (Lévy, Petitjean, Ray & Maillot 2002, "Least
Squares Conformal Maps for Automatic Texture Atlas Generation", eqs. 3-6) refined by as-rigid-as-possible
iterations (Liu, Zhang, Xu, Gotsman & Gortler 2008, "A Local/Global Approach to Mesh Parameterization",
section 3: conformal maps shrink a protrusion such as a nose by 4x in area, ARAP restores the texel
density), and lets xatlas pack the charts as they are (ChartOptions.use_input_mesh_uvs).
"""

from __future__ import annotations

import numpy as np

# Charts of fewer triangles than this stay apart even inside a box: xatlas gives the floor of a cave (each
# of the procedural head's nostrils: 4 triangles, 3-6 mm^2 each) its own chart, and a cave flattened with its
# floor squeezes the floor (ARAP converges at 0.23 of the chart's median texel density there, 0.63 without).
# A seam on a cave's floor is in the dark.
JOIN_MIN_TRIANGLES = 16
JOIN_VERSION = 2  # bump when join_charts' result changes (dermis.geometry.atlas keys its cache on it)

def _local_frames(P, F):
    """(M, 3, 2): each triangle's corners in an orthonormal frame of its own plane (isometric)."""
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    e1, e2 = b - a, c - a
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    ex = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    ey = np.cross(n, ex)
    X = np.zeros((len(F), 3, 2))
    X[:, 1, 0] = np.sum(e1 * ex, 1)
    X[:, 2, 0] = np.sum(e2 * ex, 1)
    X[:, 2, 1] = np.sum(e2 * ey, 1)
    return X


def lscm(P, F) -> np.ndarray:
    """(N, 2) least-squares conformal UVs of the triangles ``F`` (M, 3) over vertices ``P`` (N, 3), the two
    vertices furthest apart along the principal axis pinned (Lévy et al. 2002)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    P = np.asarray(P, np.float64)
    F = np.asarray(F, np.int64)
    n, m = len(P), len(F)
    X = _local_frames(P, F)
    area2 = np.abs(X[:, 1, 0] * X[:, 2, 1])  # twice the area
    # W_j = (x_(j+2) - x_(j+1)) + i (y_(j+2) - y_(j+1)), over sqrt(2 A): the residual sum_j W_j (u_j + i v_j)
    Wr = np.stack([X[:, (j + 2) % 3, 0] - X[:, (j + 1) % 3, 0] for j in range(3)], 1) / np.sqrt(area2)[:, None]
    Wi = np.stack([X[:, (j + 2) % 3, 1] - X[:, (j + 1) % 3, 1] for j in range(3)], 1) / np.sqrt(area2)[:, None]
    rows, cols = np.repeat(np.arange(m), 3), F.reshape(-1)

    def block(w):
        return sp.csr_matrix((w.ravel(), (rows, cols)), (m, n))

    M = sp.vstack([sp.hstack([block(Wr), block(-Wi)]), sp.hstack([block(Wi), block(Wr)])]).tocsc()
    d = P - P.mean(0)
    s = d @ np.linalg.svd(d, full_matrices=False)[2][0]
    i0, i1 = int(np.argmin(s)), int(np.argmax(s))
    pin = np.array([i0, i1, n + i0, n + i1])
    val = np.array([0.0, np.linalg.norm(P[i1] - P[i0]), 0.0, 0.0])
    free = np.setdiff1d(np.arange(2 * n), pin)
    Mf = M[:, free]
    sol = sla.spsolve((Mf.T @ Mf).tocsc(), Mf.T @ (-(M[:, pin] @ val)))
    x = np.zeros(2 * n)
    x[pin], x[free] = val, sol
    return np.stack([x[:n], x[n:]], 1)


def arap(P, F, uv, iterations: int = 20) -> np.ndarray:
    """As-rigid-as-possible refinement of the UVs ``uv`` (N, 2) (Liu et al. 2008, local/global): each
    triangle's closest rotation of its isometric flattening (local), then the cotangent-weighted least
    squares fit of all triangles to theirs (global; cotangents clamped at 1e-4 so the system stays definite)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    P = np.asarray(P, np.float64)
    F = np.asarray(F, np.int64)
    n, m = len(P), len(F)
    X = _local_frames(P, F)
    I, J = [1, 2, 0], [2, 0, 1]  # half-edge e = (I[e], J[e]) lies opposite corner e
    W = np.zeros((m, 3))
    for k in range(3):
        a, b = X[:, I[k]] - X[:, k], X[:, J[k]] - X[:, k]
        W[:, k] = 0.5 * np.maximum(np.sum(a * b, 1) / np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), 1e-4)
    r, c, v = [], [], []
    for e in range(3):
        vi, vj, w = F[:, I[e]], F[:, J[e]], W[:, e]
        r += [vi, vj, vi, vj]
        c += [vi, vj, vj, vi]
        v += [w, w, -w, -w]
    L = sp.csr_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), (n, n)).tolil()
    L[0, :] = 0.0
    L[0, 0] = 1.0  # vertex 0 held where it is (the energy is translation invariant)
    solve = sla.factorized(L.tocsc())
    U = np.array(uv, np.float64)
    for _ in range(int(iterations)):
        Jm = np.zeros((m, 2, 2))
        for e in range(3):
            du = U[F[:, I[e]]] - U[F[:, J[e]]]
            dx = X[:, I[e]] - X[:, J[e]]
            Jm += W[:, e, None, None] * du[:, :, None] * dx[:, None, :]
        Us, _, Vt = np.linalg.svd(Jm)
        R = Us @ Vt
        neg = np.linalg.det(R) < 0
        if neg.any():  # the closest proper rotation
            Uf = Us[neg].copy()
            Uf[:, :, 1] *= -1
            R[neg] = Uf @ Vt[neg]
        b = np.zeros((n, 2))
        for e in range(3):
            t = np.einsum("mab,mb->ma", R, X[:, I[e]] - X[:, J[e]]) * W[:, e, None]
            np.add.at(b, F[:, I[e]], t)
            np.add.at(b, F[:, J[e]], -t)
        b[0] = U[0]
        U = np.stack([solve(b[:, 0]), solve(b[:, 1])], 1)
    return U


def chart_labels(indices) -> np.ndarray:
    """(M,) chart of each triangle of an atlas: triangles sharing an atlas vertex are one chart."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    t = np.asarray(indices, np.int64).reshape(-1, 3)
    m = len(t)
    g = csr_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), t.ravel())), (m, int(t.max()) + 1))
    return connected_components(g @ g.T, directed=False)[1]


def join_charts(positions, indices, vmapping, atlas_indices, uvs, boxes):
    """Joins, for each box ((lo xyz), (hi xyz)) in mesh units, every chart (of JOIN_MIN_TRIANGLES or more) with
    a triangle centroid inside it into one chart, flattened by LSCM + ARAP. ``positions``/``indices``: the
    input mesh; ``vmapping``, ``atlas_indices``, ``uvs``: an xatlas atlas of it. Returns (vmapping, indices, uvs) of the charts before
    packing (charts as UV islands: their vertices are shared only within a chart)."""
    P = np.asarray(positions, np.float64)
    T = np.asarray(indices, np.int64).reshape(-1, 3)
    corner = np.asarray(atlas_indices, np.int64).reshape(-1, 3).copy()
    vm = list(np.asarray(vmapping, np.int64))
    uv = list(np.asarray(uvs, np.float64))
    chart = chart_labels(corner)
    centroid = P[T].mean(1)
    ids, n_tris = np.unique(chart, return_counts=True)
    big = ids[n_tris >= JOIN_MIN_TRIANGLES]
    groups = []  # sets of charts to join; boxes that share a chart give one group (flattened once)
    for lo, hi in boxes:
        inside = np.all((centroid >= np.asarray(lo)) & (centroid <= np.asarray(hi)), axis=1)
        g = set(np.intersect1d(big, chart[inside]).tolist())
        for other in [o for o in groups if o & g]:
            groups.remove(other)
            g |= other
        if g:
            groups.append(g)
    for g in groups:
        tris = np.nonzero(np.isin(chart, sorted(g)))[0]
        verts, local = np.unique(T[tris], return_inverse=True)
        local = local.reshape(-1, 3)
        flat = arap(P[verts], local, lscm(P[verts], local))
        corner[tris] = len(vm) + local  # one vertex per mesh vertex of the joined chart
        vm += list(verts)
        uv += list(flat)
    used, inv = np.unique(corner, return_inverse=True)
    return np.asarray(vm, np.int64)[used], inv.reshape(-1, 3), np.asarray(uv, np.float64)[used]
