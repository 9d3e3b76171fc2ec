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
Both maps are libigl's (Jacobson, Panozzo et al., github.com/libigl/libigl; its Python bindings, PyPI
``libigl`` >= 2.6: ``igl.lscm``, ``igl.arap_precomputation`` / ``igl.arap_solve``); round 22 (igl22)
replaced seam21's hand-written ones.
"""

from __future__ import annotations

import numpy as np

# Charts of fewer triangles than this stay apart even inside a box: xatlas gives the floor of a cave (each
# of the procedural head's nostrils: 4 triangles, 3-6 mm^2 each) its own chart, and a cave flattened with its
# floor squeezes the floor (ARAP, 20 iterations: 0.20 of the chart's median linear texel density there, 0.65
# without; seam21's hand-written solver 0.19 / 0.60).
# A seam on a cave's floor is in the dark.
JOIN_MIN_TRIANGLES = 16
# bump when join_charts' result changes (dermis.geometry.atlas keys its cache on it); 3: libigl's LSCM + ARAP
JOIN_VERSION = 3


def lscm(P, F) -> np.ndarray:
    """(N, 2) least-squares conformal UVs of the triangles ``F`` (M, 3) over vertices ``P`` (N, 3), the two
    vertices furthest apart along the principal axis pinned (Lévy et al. 2002; libigl's ``igl.lscm``)."""
    import igl

    P = np.ascontiguousarray(P, np.float64)
    F = np.ascontiguousarray(F, np.int64)
    d = P - P.mean(0)
    s = d @ np.linalg.svd(d, full_matrices=False)[2][0]
    i0, i1 = int(np.argmin(s)), int(np.argmax(s))
    # the pins' distance apart kept: the map's scale is the chord's (unit-free otherwise)
    bc = np.array([[0.0, 0.0], [np.linalg.norm(P[i1] - P[i0]), 0.0]])
    uv, _ = igl.lscm(P, F, np.array([i0, i1], np.int64), bc)
    return np.asarray(uv, np.float64)


def arap(P, F, uv, iterations: int = 20) -> np.ndarray:
    """As-rigid-as-possible refinement of the UVs ``uv`` (N, 2) (Liu et al. 2008, local/global): each
    triangle's closest rotation of its isometric flattening (local), then the cotangent-weighted least
    squares fit of all triangles to theirs (global); ``iterations`` local/global rounds from ``uv``, vertex 0
    held where it is (the energy is translation invariant). libigl's ``igl.arap_solve`` with the per-triangle
    energy (ARAP_ENERGY_TYPE_ELEMENTS: Liu et al.'s, on each triangle's isometric flattening)."""
    import igl

    P = np.ascontiguousarray(P, np.float64)
    F = np.ascontiguousarray(F, np.int64)
    U = np.ascontiguousarray(uv, np.float64)
    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS
    data.max_iter = int(iterations)
    igl.arap_precomputation(P, F, 2, np.array([0], np.int32), data)
    return np.asarray(igl.arap_solve(U[:1], data, U), np.float64)


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
