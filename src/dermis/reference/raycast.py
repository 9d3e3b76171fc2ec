"""Ray casting against a triangle mesh through a bounding volume hierarchy (numba, CPU).

What it is: a binary BVH of axis-aligned boxes over the triangles (Kay & Kajiya 1986 for the
slab test; Wald, Boulos & Shirley 2007 for the top-down build), built with binned surface-area
heuristic splits (16 bins along the longest centroid axis, leaves of at most 4 triangles), and
the ray-triangle test of Moller & Trumbore 1997, all in float64.

Queries, vectorised over rays and parallel over them (``numba.prange``):

* :meth:`Bvh.closest_hit` - the nearest triangle along each ray in (tmin, tmax): camera rays.
* :meth:`Bvh.occluded` - whether anything lies along each ray in (tmin, tmax): shadow rays
  (any-hit, stops at the first triangle found).

Both faces of every triangle are hit (thin parts such as ears occlude from either side, as the
real-time shadow maps do with culling off). Deterministic: the build depends only on the input
and ties are broken by triangle index. Units are whatever the caller's positions are in
(the reference renderer works in millimetres).
"""

from __future__ import annotations

import numba
import numpy as np

LEAF_SIZE = 4
SAH_BINS = 16


@numba.njit(cache=True)
def _build(v0, v1, v2):
    n = v0.shape[0]
    lo_t = np.empty((n, 3))
    hi_t = np.empty((n, 3))
    cen = np.empty((n, 3))
    for i in range(n):
        for a in range(3):
            x0, x1, x2 = v0[i, a], v1[i, a], v2[i, a]
            lo_t[i, a] = min(x0, min(x1, x2))
            hi_t[i, a] = max(x0, max(x1, x2))
            cen[i, a] = (x0 + x1 + x2) / 3.0
    order = np.arange(n)
    max_nodes = 2 * n + 1
    node_lo = np.empty((max_nodes, 3))
    node_hi = np.empty((max_nodes, 3))
    # leaf: left = first triangle (into order), right = -count; inner: left/right children
    node_left = np.zeros(max_nodes, np.int64)
    node_right = np.zeros(max_nodes, np.int64)
    stack_node = np.empty(max_nodes, np.int64)
    stack_start = np.empty(max_nodes, np.int64)
    stack_end = np.empty(max_nodes, np.int64)
    stack_depth = np.empty(max_nodes, np.int64)
    stack_node[0], stack_start[0], stack_end[0], stack_depth[0] = 0, 0, n, 1
    sp = 1
    count = 1
    max_depth = 1
    bin_lo = np.empty((SAH_BINS, 3))
    bin_hi = np.empty((SAH_BINS, 3))
    bin_n = np.empty(SAH_BINS, np.int64)
    while sp > 0:
        sp -= 1
        node, s, e, depth = stack_node[sp], stack_start[sp], stack_end[sp], stack_depth[sp]
        max_depth = max(max_depth, depth)
        # bounds of the node and of its centroids
        blo = np.full(3, np.inf)
        bhi = np.full(3, -np.inf)
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        for k in range(s, e):
            t = order[k]
            for a in range(3):
                blo[a] = min(blo[a], lo_t[t, a])
                bhi[a] = max(bhi[a], hi_t[t, a])
                clo[a] = min(clo[a], cen[t, a])
                chi[a] = max(chi[a], cen[t, a])
        node_lo[node] = blo
        node_hi[node] = bhi
        m = e - s
        axis = 0
        ext = chi - clo
        if ext[1] > ext[axis]:
            axis = 1
        if ext[2] > ext[axis]:
            axis = 2
        if m <= LEAF_SIZE or ext[axis] <= 0.0:
            node_left[node] = s
            node_right[node] = -m
            continue
        # binned SAH along the longest centroid axis
        for b in range(SAH_BINS):
            bin_n[b] = 0
            for a in range(3):
                bin_lo[b, a] = np.inf
                bin_hi[b, a] = -np.inf
        scale = SAH_BINS / ext[axis]
        for k in range(s, e):
            t = order[k]
            b = int((cen[t, axis] - clo[axis]) * scale)
            if b >= SAH_BINS:
                b = SAH_BINS - 1
            bin_n[b] += 1
            for a in range(3):
                bin_lo[b, a] = min(bin_lo[b, a], lo_t[t, a])
                bin_hi[b, a] = max(bin_hi[b, a], hi_t[t, a])
        best_cost = np.inf
        best_split = -1
        for split in range(1, SAH_BINS):
            nl = 0
            nr = 0
            llo = np.full(3, np.inf)
            lhi = np.full(3, -np.inf)
            rlo = np.full(3, np.inf)
            rhi = np.full(3, -np.inf)
            for b in range(split):
                nl += bin_n[b]
                for a in range(3):
                    llo[a] = min(llo[a], bin_lo[b, a])
                    lhi[a] = max(lhi[a], bin_hi[b, a])
            for b in range(split, SAH_BINS):
                nr += bin_n[b]
                for a in range(3):
                    rlo[a] = min(rlo[a], bin_lo[b, a])
                    rhi[a] = max(rhi[a], bin_hi[b, a])
            if nl == 0 or nr == 0:
                continue
            dl = lhi - llo
            dr = rhi - rlo
            al = dl[0] * dl[1] + dl[1] * dl[2] + dl[2] * dl[0]
            ar = dr[0] * dr[1] + dr[1] * dr[2] + dr[2] * dr[0]
            cost = al * nl + ar * nr
            if cost < best_cost:
                best_cost = cost
                best_split = split
        # partition (stable by index within each side: deterministic)
        seg = order[s:e].copy()
        mid = s
        if best_split > 0:
            left = np.empty(m, np.bool_)  # each triangle's side, binned once
            for k in range(m):
                b = int((cen[seg[k], axis] - clo[axis]) * scale)
                left[k] = min(b, SAH_BINS - 1) < best_split
            w = s
            for k in range(m):
                if left[k]:
                    order[w] = seg[k]
                    w += 1
            mid = w
            for k in range(m):
                if not left[k]:
                    order[w] = seg[k]
                    w += 1
        if mid == s or mid == e:  # degenerate: object median
            keys = np.empty(m)
            for k in range(m):
                keys[k] = cen[seg[k], axis]
            idx = np.argsort(keys, kind="mergesort")
            for k in range(m):
                order[s + k] = seg[idx[k]]
            mid = s + m // 2
        left = count
        right = count + 1
        count += 2
        node_left[node] = left
        node_right[node] = right
        stack_node[sp], stack_start[sp], stack_end[sp], stack_depth[sp] = right, mid, e, depth + 1
        sp += 1
        stack_node[sp], stack_start[sp], stack_end[sp], stack_depth[sp] = left, s, mid, depth + 1
        sp += 1
    return node_lo[:count].copy(), node_hi[:count].copy(), node_left[:count].copy(), node_right[:count].copy(), order, max_depth


@numba.njit(cache=True, inline="always")
def _slab(lo, hi, node, ox, oy, oz, ix, iy, iz, tmin, tmax):
    t0 = (lo[node, 0] - ox) * ix
    t1 = (hi[node, 0] - ox) * ix
    tn = min(t0, t1)
    tf = max(t0, t1)
    t0 = (lo[node, 1] - oy) * iy
    t1 = (hi[node, 1] - oy) * iy
    tn = max(tn, min(t0, t1))
    tf = min(tf, max(t0, t1))
    t0 = (lo[node, 2] - oz) * iz
    t1 = (hi[node, 2] - oz) * iz
    tn = max(tn, min(t0, t1))
    tf = min(tf, max(t0, t1))
    tn = max(tn, tmin)
    tf = min(tf, tmax)
    if tn <= tf * 1.0000000000001:
        return tn
    return np.inf


@numba.njit(cache=True, inline="always")
def _triangle(v0, v1, v2, t, ox, oy, oz, dx, dy, dz):
    """Moller & Trumbore 1997: (t, b1, b2), t = inf on a miss. Both faces."""
    e1x = v1[t, 0] - v0[t, 0]
    e1y = v1[t, 1] - v0[t, 1]
    e1z = v1[t, 2] - v0[t, 2]
    e2x = v2[t, 0] - v0[t, 0]
    e2y = v2[t, 1] - v0[t, 1]
    e2z = v2[t, 2] - v0[t, 2]
    px = dy * e2z - dz * e2y
    py = dz * e2x - dx * e2z
    pz = dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz
    if det == 0.0:
        return np.inf, 0.0, 0.0
    inv = 1.0 / det
    sx = ox - v0[t, 0]
    sy = oy - v0[t, 1]
    sz = oz - v0[t, 2]
    b1 = (sx * px + sy * py + sz * pz) * inv
    if b1 < 0.0 or b1 > 1.0:
        return np.inf, 0.0, 0.0
    qx = sy * e1z - sz * e1y
    qy = sz * e1x - sx * e1z
    qz = sx * e1y - sy * e1x
    b2 = (dx * qx + dy * qy + dz * qz) * inv
    if b2 < 0.0 or b1 + b2 > 1.0:
        return np.inf, 0.0, 0.0
    tt = (e2x * qx + e2y * qy + e2z * qz) * inv
    return tt, b1, b2


@numba.njit(cache=True, parallel=True)
def _closest(lo, hi, left, right, order, v0, v1, v2, orig, dirs, tmin, tmax, stack_size):
    n = orig.shape[0]
    t_out = np.full(n, np.inf)
    tri_out = np.full(n, -1, np.int64)
    b_out = np.zeros((n, 2))
    for r in numba.prange(n):
        ox, oy, oz = orig[r, 0], orig[r, 1], orig[r, 2]
        dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
        ix = 1.0 / dx if dx != 0.0 else np.inf
        iy = 1.0 / dy if dy != 0.0 else np.inf
        iz = 1.0 / dz if dz != 0.0 else np.inf
        best = tmax[r]
        lo_t = tmin[r]
        stack = np.empty(stack_size, np.int64)
        sp = 0
        if _slab(lo, hi, 0, ox, oy, oz, ix, iy, iz, lo_t, best) < np.inf:
            stack[0] = 0
            sp = 1
        while sp > 0:
            sp -= 1
            node = stack[sp]
            if right[node] <= 0:
                for k in range(left[node], left[node] - right[node]):
                    t = order[k]
                    tt, b1, b2 = _triangle(v0, v1, v2, t, ox, oy, oz, dx, dy, dz)
                    if lo_t < tt < best or (tt == best and t < tri_out[r]):
                        best = tt
                        tri_out[r] = t
                        b_out[r, 0] = b1
                        b_out[r, 1] = b2
                continue
            a, b = left[node], right[node]
            ta = _slab(lo, hi, a, ox, oy, oz, ix, iy, iz, lo_t, best)
            tb = _slab(lo, hi, b, ox, oy, oz, ix, iy, iz, lo_t, best)
            if ta < tb:  # push the far child first: the near one is visited next
                if tb < np.inf:
                    stack[sp] = b
                    sp += 1
                stack[sp] = a
                sp += 1
            else:
                if ta < np.inf:
                    stack[sp] = a
                    sp += 1
                if tb < np.inf:
                    stack[sp] = b
                    sp += 1
        if tri_out[r] >= 0:
            t_out[r] = best
    return t_out, tri_out, b_out


@numba.njit(cache=True, parallel=True)
def _occluded(lo, hi, left, right, order, v0, v1, v2, orig, dirs, tmin, tmax, skip, stack_size):
    n = orig.shape[0]
    out = np.zeros(n, np.bool_)
    for r in numba.prange(n):
        ox, oy, oz = orig[r, 0], orig[r, 1], orig[r, 2]
        dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
        ix = 1.0 / dx if dx != 0.0 else np.inf
        iy = 1.0 / dy if dy != 0.0 else np.inf
        iz = 1.0 / dz if dz != 0.0 else np.inf
        t_lo, t_hi = tmin[r], tmax[r]
        stack = np.empty(stack_size, np.int64)
        stack[0] = 0
        sp = 1
        hit = False
        while sp > 0 and not hit:
            sp -= 1
            node = stack[sp]
            if _slab(lo, hi, node, ox, oy, oz, ix, iy, iz, t_lo, t_hi) == np.inf:
                continue
            if right[node] <= 0:
                for k in range(left[node], left[node] - right[node]):
                    if order[k] == skip[r]:
                        continue
                    tt, b1, b2 = _triangle(v0, v1, v2, order[k], ox, oy, oz, dx, dy, dz)
                    if t_lo < tt < t_hi:
                        hit = True
                        break
                continue
            stack[sp] = right[node]
            sp += 1
            stack[sp] = left[node]
            sp += 1
        out[r] = hit
    return out


class Bvh:
    """A BVH over a triangle mesh. ``positions`` (N, 3), ``indices`` (M, 3); any length unit."""

    def __init__(self, positions, indices):
        p = np.ascontiguousarray(positions, np.float64)
        idx = np.asarray(indices, np.int64)
        self.v0 = np.ascontiguousarray(p[idx[:, 0]])
        self.v1 = np.ascontiguousarray(p[idx[:, 1]])
        self.v2 = np.ascontiguousarray(p[idx[:, 2]])
        self.lo, self.hi, self.left, self.right, self.order, self.depth = _build(self.v0, self.v1, self.v2)
        self._stack = int(self.depth) + 2  # a pop pushes at most 2: depth + 1 entries suffice
        self.triangle_count = len(idx)

    @property
    def node_count(self) -> int:
        return len(self.lo)

    def _rays(self, origins, directions, tmin, tmax):
        o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
        d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
        n = len(o)
        tmin = np.ascontiguousarray(np.broadcast_to(np.asarray(tmin, np.float64), (n,)))
        tmax = np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, np.float64), (n,)))
        return o, d, tmin, tmax

    def closest_hit(self, origins, directions, tmin=0.0, tmax=np.inf):
        """Nearest hit per ray: (t (n,), triangle (n,) or -1, barycentrics (n, 2) of vertices 1, 2).
        ``t`` is in units of the direction's length (unit directions: distance)."""
        o, d, tmin, tmax = self._rays(origins, directions, tmin, tmax)
        return _closest(self.lo, self.hi, self.left, self.right, self.order, self.v0, self.v1, self.v2, o, d, tmin, tmax, self._stack)

    def occluded(self, origins, directions, tmin=0.0, tmax=np.inf, skip=None):
        """True where a triangle lies along the ray with tmin < t < tmax (any hit). ``skip`` (n,):
        a triangle per ray to ignore (the one the ray starts on), -1 for none."""
        o, d, tmin, tmax = self._rays(origins, directions, tmin, tmax)
        skip = np.full(len(o), -1, np.int64) if skip is None else np.ascontiguousarray(skip, np.int64).reshape(-1)
        return _occluded(self.lo, self.hi, self.left, self.right, self.order, self.v0, self.v1, self.v2, o, d, tmin, tmax,
                         skip, self._stack)
