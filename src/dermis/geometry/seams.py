"""Light across UV seams in texture-space diffusion (issue 12): where the gutter texels beside a seam
edge continue the surface in the neighbouring chart.

tsd blurs the irradiance in the mesh's texture-space layout with coverage-normalised Gaussians
(shaders/tsd/blur.frag), so a chart's blur sees only its own chart: at a UV seam (a mesh edge whose two
triangles have different UVs) the light of the other side is missing (round 21: 8 % red under the
procedural head's nose, benchmarks/RESULTS.md "Round 21, branch demo21"). Here, once per layout on the
CPU: for every gutter texel (no chart covers its centre) within a blur's reach of a seam edge, on the
outer side of that edge, the UV of the same surface point in the neighbouring chart: the neighbour
triangle is unfolded across the shared edge into this chart's UV plane (its third vertex placed at its
3-D distance along and across the edge, in this chart's texels per mm along the edge, i.e. a conformal
unfold) and the texel's centre mapped by the affine map between the unfolded triangle and the
neighbour's UVs (extrapolated past the triangle: exact on a developable chart, an approximation where
the neighbour chart curves within the reach). A target that lands off the neighbour's own chart (past
its border, or on a third chart) is dropped, so a texel is filled only with light of the surface it
continues. tsd then overwrites those texels of each blur step's input, in place, with the input read at their
targets (bilinear, less the taps on texels the fill writes: bilinear_taps; dermis.gl.seam_fill,
shaders/tsd/seam_fill.*), so each step's Gaussian gathers across the seam as far as the gutter reaches. The gutter bounds it: a layout whose gutters are narrower than
a blur's reach carries only the gutter's width of the other side per step (the generated layouts size
theirs to 3 sigma of the widest Gaussian: dermis.geometry.texture_space.gutter_texels).

Units: UV in [0, 1] (v = 0 at the bottom: the GL textures' row 0), texel coordinates of a level L
texture of S >> L texels per side with texel centres at (i + 0.5).
"""

from __future__ import annotations

import hashlib

import numpy as np

SEAM_UV_TOLERANCE_TEXELS = 0.5  # the two sides' UVs of an edge further apart than this (level-0 texels): a seam
MIN_DENSITY = 0.25  # a seam side whose charts hold the edge at under this fraction of the layout's median texels per mm is skipped
SAMPLES_PER_TEXEL = 4  # points per texel of length along each seam edge for the nearest-edge search
_MEMORY: dict = {}
_KEEP = 4


def seam_sides(positions, indices, uvs, tolerance_uv: float):
    """The seam edges as sides: (own triangle, other triangle, own UVs of the edge's endpoints a, b and
    of the triangle's third vertex c (each (n, 2)), the other triangle's UVs of a, b, c (n, 2), and
    its 3-D points a, b, c (n, 3)); every seam edge gives two sides (one per triangle). Vertices are
    welded by equal positions (a mesh split along its UV seams keeps the copies' positions); an edge
    with exactly two triangles is a seam where either endpoint's UVs differ by more than
    ``tolerance_uv``."""
    P = np.asarray(positions, np.float64)
    T = np.asarray(indices, np.int64).reshape(-1, 3)
    UV = np.asarray(uvs, np.float64)
    _, weld = np.unique(np.asarray(positions), axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    corner = np.arange(3)
    # the triangles' sides: (triangle, local corner of the edge's first vertex) for the edges (0 1), (1 2), (2 0)
    tri = np.repeat(np.arange(len(T)), 3)
    loc = np.tile(corner, len(T))
    va, vb = T[tri, loc], T[tri, (loc + 1) % 3]
    wa, wb = weld[va], weld[vb]
    lo, hi = np.minimum(wa, wb), np.maximum(wa, wb)
    order = np.lexsort((hi, lo))
    lo, hi = lo[order], hi[order]
    start = np.r_[True, (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])]
    group = np.cumsum(start) - 1
    counts = np.bincount(group)
    pair = np.nonzero(start & (counts[group] == 2))[0]  # manifold edges: entries pair, pair + 1
    s1, s2 = order[pair], order[pair + 1]

    def side(s):  # (triangle, its vertex at the edge's welded lo, at hi, its third vertex)
        t, l = tri[s], loc[s]
        a, b, c = T[t, l], T[t, (l + 1) % 3], T[t, (l + 2) % 3]
        swap = weld[a] > weld[b]
        return t, np.where(swap, b, a), np.where(swap, a, b), c

    t1, a1, b1, c1 = side(s1)
    t2, a2, b2, c2 = side(s2)
    d = np.maximum(np.abs(UV[a1] - UV[a2]).max(1), np.abs(UV[b1] - UV[b2]).max(1))
    seam = d > tolerance_uv
    t1, a1, b1, c1, t2, a2, b2, c2 = (x[seam] for x in (t1, a1, b1, c1, t2, a2, b2, c2))
    own = (np.r_[t1, t2], np.r_[a1, a2], np.r_[b1, b2], np.r_[c1, c2])
    other = (np.r_[t2, t1], np.r_[a2, a1], np.r_[b2, b1], np.r_[c2, c1])
    return (own[0], other[0], UV[own[1]], UV[own[2]], UV[own[3]], UV[other[1]], UV[other[2]], UV[other[3]],
            P[other[1]], P[other[2]], P[other[3]])


def unfold_maps(ua, ub, uc, va, vb, vc, pa, pb, pc):
    """(n, 2, 3) affine maps from each side's own UV plane to the other triangle's UVs: the other
    triangle (3-D points pa, pb, pc; UVs va, vb, vc) unfolded across the edge (ua, ub) to the side of it
    away from the own triangle's third vertex uc, scaled by the own chart's UV length of the edge.
    NaN where a triangle is degenerate in UV or 3-D."""
    e = ub - ua
    perp = np.stack([-e[:, 1], e[:, 0]], 1)  # |perp| = |e|
    inward = np.sum(perp * (uc - ua), 1) > 0
    perp[inward] *= -1.0
    d = pb - pa
    dd = np.sum(d * d, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.sum((pc - pa) * d, 1) / dd
        h = np.linalg.norm(pc - pa - alpha[:, None] * d, axis=1) / np.sqrt(dd)
        c_unfolded = ua + alpha[:, None] * e + h[:, None] * perp
        src = np.stack([np.c_[ua, np.ones(len(ua))], np.c_[ub, np.ones(len(ua))], np.c_[c_unfolded, np.ones(len(ua))]], 1)
        dst = np.stack([va, vb, vc], 1)  # (n, 3, 2)
        ok = np.abs(np.linalg.det(src)) > 1e-14
        M = np.full((len(ua), 2, 3), np.nan)
        if ok.any():
            M[ok] = np.linalg.solve(src[ok], dst[ok]).transpose(0, 2, 1)
    return M, perp


def edge_density(positions, indices, uvs) -> float:
    """The layout's median UV length per 3-D length over the mesh's triangle edges (UV units per mesh unit)."""
    P = np.asarray(positions, np.float64)
    T = np.asarray(indices, np.int64).reshape(-1, 3)
    UV = np.asarray(uvs, np.float64)
    a, b = T.ravel(), np.roll(T, -1, axis=1).ravel()
    d3 = np.linalg.norm(P[b] - P[a], axis=1)
    ok = d3 > 0
    return float(np.median(np.linalg.norm(UV[b] - UV[a], axis=1)[ok] / d3[ok])) if ok.any() else 0.0


def uv_charts(indices, uvs) -> np.ndarray:
    """Chart label per triangle: the triangles connected through shared vertices of equal UVs."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    T = np.asarray(indices, np.int64).reshape(-1, 3)
    _, vid = np.unique(np.asarray(uvs, np.float64), axis=0, return_inverse=True)
    vid = vid.reshape(-1)
    n, m = len(T), int(vid.max()) + 1 if len(vid) else 0
    rows = np.repeat(np.arange(n), 3)
    g = coo_matrix((np.ones(3 * n), (rows, vid[T].ravel())), shape=(n, m)).tocsr()
    _, lab = connected_components(g @ g.T, directed=False)
    return lab


def fill_targets(positions, indices, uvs, size: int, reach_texels) -> dict:
    """{level: (texels (n, 2) int32 (column, row; row 0 = v 0), targets (n, 2) float32 UV, distances (n,)
    float32)} for the levels L with ``reach_texels[L]`` (texels of that level): the gutter texels within
    the reach of a seam side, beyond it, the UV of the same surface point in the neighbouring chart
    (module docstring), and its distance from the seam over the unfolded surface (mesh units: the
    texel's UV distance to the side over the side's UV length per 3-D length), sorted by that distance
    (a blur step draws the prefix its own reach needs). Empty arrays where the layout has no seam."""
    from scipy import ndimage
    from scipy.spatial import cKDTree

    from dermis.geometry.rasterize import rasterize_uv

    S = int(size)
    sides = seam_sides(positions, indices, uvs, SEAM_UV_TOLERANCE_TEXELS / S)
    own_t, other_t, ua, ub, uc = sides[:5]
    empty = (np.zeros((0, 2), np.int32), np.zeros((0, 2), np.float32), np.zeros(0, np.float32))
    if len(own_t) == 0:
        return {int(L): empty for L in reach_texels}
    M, perp = unfold_maps(*sides[2:])
    # a side whose own or neighbour chart squeezes the edge far below the layout's texel density (a
    # collapsed chart: the scanned head's closed eyelids, 264 triangles in one texel) maps a texel to
    # a point far over the surface (27-34 mm there): dropped
    density = edge_density(positions, indices, uvs)
    d3 = np.linalg.norm(sides[9] - sides[8], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = ((np.linalg.norm(ub - ua, axis=1) / d3 >= MIN_DENSITY * density)
              & (np.linalg.norm(sides[6] - sides[5], axis=1) / d3 >= MIN_DENSITY * density))
    M[~ok] = np.nan
    tri0, _ = rasterize_uv(uvs, indices, S, S)
    tri0 = tri0[::-1]  # row 0 = v 0, as the GL textures
    chart = uv_charts(indices, uvs)
    chart0 = np.where(tri0 >= 0, chart[np.maximum(tri0, 0)], -1)
    cover0 = (tri0 >= 0).astype(np.float64)
    out = {}
    for L, reach in reach_texels.items():
        L, SL = int(L), max(S >> int(L), 1)
        f = S // SL
        cov = cover0[:SL * f, :SL * f].reshape(SL, f, SL, f).mean((1, 3))  # the 2x2 reductions' coverage
        # samples along the sides in this level's texels, for the nearest side of each gutter texel
        e_len = np.linalg.norm((ub - ua) * SL, axis=1)
        n = np.maximum(np.ceil(e_len * SAMPLES_PER_TEXEL).astype(np.int64), 1) + 1
        sid = np.repeat(np.arange(len(ua)), n)
        t = np.concatenate([np.linspace(0.0, 1.0, k) for k in n])
        pts = (ua[sid] + t[:, None] * (ub - ua)[sid]) * SL  # texel units (x = column)
        marked = np.zeros((SL, SL), bool)
        ij = np.clip(np.floor(pts).astype(np.int64), 0, SL - 1)
        marked[ij[:, 1], ij[:, 0]] = True
        near = ndimage.distance_transform_edt(~marked) <= float(reach) + 1.5
        rows, cols = np.nonzero(near & (cov < 0.5))
        if len(rows) == 0:
            out[L] = empty
            continue
        p = np.c_[cols + 0.5, rows + 0.5]
        dist, k = cKDTree(pts).query(p, distance_upper_bound=float(reach) + 0.5)
        ok = np.isfinite(dist)
        p, rows, cols, s = p[ok], rows[ok], cols[ok], sid[k[ok]]
        puv = p / SL
        beyond = np.sum((puv - ua[s]) * perp[s], 1) > 0  # on the far side of the edge's line
        target = np.einsum("nij,nj->ni", M[s], np.c_[puv, np.ones(len(puv))])
        good = beyond & np.all(np.isfinite(target), 1) & np.all((target >= 0) & (target < 1), 1)
        # the target must lie on the neighbour's own chart (level 0 raster)
        tc = np.clip(np.floor(np.nan_to_num(target) * S).astype(np.int64), 0, S - 1)
        good &= chart0[tc[:, 1], tc[:, 0]] == chart[other_t[s]]
        with np.errstate(divide="ignore", invalid="ignore"):
            units = dist[ok][good] / SL / (np.linalg.norm(ub - ua, axis=1) / d3)[s[good]]
        order = np.argsort(units, kind="stable")
        out[L] = (np.c_[cols[good], rows[good]].astype(np.int32)[order], target[good].astype(np.float32)[order],
                  units[order].astype(np.float32))
    return out


def bilinear_taps(texels, targets, size: int):
    """(base texel (n, 2) int32, weights (n, 4) float32 of the texels base + (0, 0), (1, 0), (0, 1), (1, 1)):
    the bilinear read of a ``size``-texel level at each target, less the taps on texels the fill itself
    writes (``texels``), renormalised, so that the fill can write into the texture it reads: GL 4.5's
    feedback-loop rule (section 9.3.1) defines a draw whose reads and writes are disjoint sets of texels.
    Rows whose taps are all written get zero weights (the caller drops them)."""
    n = len(texels)
    if n == 0:
        return np.zeros((0, 2), np.int32), np.zeros((0, 4), np.float32)
    x = np.asarray(targets, np.float64) * size - 0.5
    base = np.clip(np.floor(x), 0, max(size - 2, 0)).astype(np.int64)
    f = np.clip(x - base, 0.0, 1.0)
    w = np.stack([(1 - f[:, 0]) * (1 - f[:, 1]), f[:, 0] * (1 - f[:, 1]), (1 - f[:, 0]) * f[:, 1], f[:, 0] * f[:, 1]], 1)
    written = np.zeros((size, size), bool)
    written[texels[:, 1], texels[:, 0]] = True
    for i, (dx, dy) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
        w[written[np.minimum(base[:, 1] + dy, size - 1), np.minimum(base[:, 0] + dx, size - 1)], i] = 0.0
    total = w.sum(1, keepdims=True)
    w = np.where(total > 1e-6, w / np.maximum(total, 1e-12), 0.0)
    return base.astype(np.int32), w.astype(np.float32)


def cached_fill_targets(positions, indices, uvs, size: int, reach_texels) -> dict:
    """fill_targets, remembered per content (positions, indices, UVs, size, reaches, this module's
    source) in memory and in dermis's disk cache (dermis.geometry.bake_cache)."""
    from dermis.geometry import bake_cache, rasterize
    import dermis.geometry.seams as this

    reach = {int(L): int(r) for L, r in sorted(reach_texels.items())}
    h = hashlib.sha256()
    for a in (np.asarray(positions, np.float32), np.asarray(indices, np.int64), np.asarray(uvs, np.float64)):
        h.update(np.ascontiguousarray(a).tobytes())
    source = bake_cache.source_key(this, rasterize)
    h.update(repr((int(size), reach, source)).encode())
    key = h.hexdigest()
    kinds = ("texels", "targets", "distances")
    names = {f"{kind}_{L}": None for L in reach for kind in kinds}
    path = bake_cache.cache_path("seam_fill", key) if source is not None else None
    arrays = bake_cache.load(_MEMORY, key, path, names, _KEEP)
    if arrays is None:
        got = fill_targets(positions, indices, uvs, size, reach)
        arrays = {f"{kind}_{L}": got[L][i] for L in reach for i, kind in enumerate(kinds)}
        bake_cache.remember(_MEMORY, key, arrays, _KEEP)
        bake_cache.store(path, arrays)
    return {L: tuple(arrays[f"{kind}_{L}"] for kind in kinds) for L in reach}
