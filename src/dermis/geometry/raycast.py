"""Ray casting against a triangle mesh through Embree (Wald et al. 2014, "Embree: a kernel
framework for efficient CPU ray tracing"), via its Python bindings ``embreex`` (the ray engine
trimesh uses).

Queries are batched over rays (numpy arrays in, numpy arrays out):

* :meth:`RayCaster.closest_hit` - the nearest triangle along each ray in (tmin, tmax): camera rays,
  hit distances for thickness and ambient-occlusion bakes.
* :meth:`RayCaster.occluded` - whether anything lies along each ray in (tmin, tmax): shadow rays,
  visibility for ambient occlusion and bent normals.

Both faces of every triangle are hit (thin parts such as ears occlude from either side, as the
real-time shadow maps do with culling off). Embree works in float32: positions are stored
relative to the mesh's bounding-box centre so the precision is that of the mesh's extent, not of
its distance from the origin (about 1e-7 of the extent). Units are the caller's (the reference
renderer works in millimetres); ``t`` is in units of the direction's length.
"""

from __future__ import annotations

import numpy as np

from dermis.errors import DermisError

# Embree's ray query has no tnear in embreex: rays start at o + tmin d; a ray that must ignore the
# triangle it leaves (``skip``) is re-launched just past that triangle, at most this many times.
MAX_SKIP_RELAUNCH = 4
BLOCK_RAYS = 1 << 15
"""Rays per block of :func:`cosine_directions` and RayCaster._refine (32 k rays: ~0.8 MB per (rays, 3)
float64 temporary, which stays in L2)."""


PARALLEL_MIN_RAYS = 1 << 16
"""Rays per thread below which RayCaster traces on the calling thread alone."""


def _cores() -> int:
    """The cores this process may run on (its affinity, not the machine's count)."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


class RayCaster:
    """Embree scene of one triangle mesh. ``positions`` (N, 3), ``indices`` (M, 3); any unit."""

    def __init__(self, positions, indices):
        try:
            from embreex import mesh_construction, rtcore_scene
        except ImportError as exc:  # pragma: no cover - embreex is a dependency
            raise DermisError(f"ray casting needs the 'embreex' package ({exc})") from None
        p = np.asarray(positions, np.float64).reshape(-1, 3)
        idx = np.asarray(indices, np.int64).reshape(-1, 3)
        if len(idx) == 0:
            raise DermisError("ray casting needs a mesh with triangles")
        self.center = 0.5 * (p.min(0) + p.max(0))
        self.v0, self.v1, self.v2 = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
        self.triangle_count = len(idx)
        self._scene = rtcore_scene.EmbreeScene()
        self._mesh = mesh_construction.TriangleMesh(self._scene, np.ascontiguousarray(p - self.center, np.float32),
                                                    np.ascontiguousarray(idx, np.int32))

    def _rays(self, origins, directions, tmin, tmax):
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        n = len(o)
        tmin = np.broadcast_to(np.asarray(tmin, np.float64), (n,)).copy()
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,)).copy()
        return o, d, tmin, tmax

    def _intersect(self, o, d, tmin, tmax):
        """One Embree closest-hit query per ray from o + tmin d: (t from o, triangle, u, v).

        In blocks of BLOCK_RAYS rays (the float32 rays and the results' conversions stay in the
        cache), spread over the process's cores when there are many: embreex traces one ray at a
        time (rtcIntersect1) with the GIL released, numpy releases it too, and each ray's result is
        the same whichever block and thread it is in."""
        n = len(o)
        t, tri = np.empty(n, np.float64), np.empty(n, np.int64)
        u, v = np.empty(n, np.float64), np.empty(n, np.float64)
        top = np.finfo(np.float32).max

        def block(s):
            e = slice(s, min(n, s + BLOCK_RAYS))
            lo = tmin[e]
            start = (o[e] - self.center) + d[e] * lo[:, None]
            far = np.minimum(tmax[e] - lo, top)
            far = np.where(far > 0, far, 0.0)
            r = self._scene.run(np.ascontiguousarray(start, np.float32), np.ascontiguousarray(d[e], np.float32),
                                np.ascontiguousarray(far, np.float32), output=1)
            k = r["primID"].astype(np.int64)
            k[far <= 0] = -1
            tri[e], t[e], u[e], v[e] = k, lo + r["tfar"].astype(np.float64), r["u"], r["v"]

        starts = range(0, n, BLOCK_RAYS)
        workers = min(_cores(), max(1, n // PARALLEL_MIN_RAYS), len(starts))
        if workers <= 1:
            for s0 in starts:
                block(s0)
        else:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(workers) as pool:
                list(pool.map(block, starts))  # list(): raise a block's exception here
        return t, tri, u, v

    def _refine(self, o, d, tri):
        """Distance along the ray to the plane of its hit triangle, in float64 (Embree's float32
        hit point moved onto the triangle): exact t for the caller's own geometry."""
        t = np.empty(len(tri), np.float64)
        for s in range(0, len(tri), BLOCK_RAYS):  # blocks: temporaries in cache, the same bits
            e = slice(s, s + BLOCK_RAYS)
            k = tri[e]
            a, b, c = self.v0[k], self.v1[k], self.v2[k]
            n = np.cross(b - a, c - a)
            den = np.einsum("ij,ij->i", n, d[e])
            with np.errstate(divide="ignore", invalid="ignore"):
                t[e] = np.einsum("ij,ij->i", n, a - o[e]) / den
        return t

    def closest_hit(self, origins, directions, tmin=0.0, tmax=np.inf):
        """Nearest hit per ray: (t (n,), triangle (n,) or -1, barycentrics (n, 2) of vertices 1, 2).
        Misses have t = inf."""
        o, d, tmin, tmax = self._rays(origins, directions, tmin, tmax)
        t, tri, u, v = self._intersect(o, d, tmin, tmax)
        hit = tri >= 0
        t = np.where(hit, t, np.inf)
        if hit.any():
            tr = self._refine(o[hit], d[hit], tri[hit])
            ok = np.isfinite(tr)
            t[np.nonzero(hit)[0][ok]] = tr[ok]
        bary = np.where(hit[:, None], np.stack([u, v], 1), 0.0)
        return t, tri, bary

    def occluded(self, origins, directions, tmin=0.0, tmax=np.inf, skip=None):
        """True where a triangle lies along the ray with tmin < t < tmax (any hit). ``skip`` (n,):
        a triangle per ray to ignore (the one the ray starts on), -1 for none."""
        o, d, tmin, tmax = self._rays(origins, directions, tmin, tmax)
        n = len(o)
        if skip is None:  # one query per ray, no relaunch (the loop's first pass, without its copies)
            t, tri, _, _ = self._intersect(o, d, tmin, tmax)
            return (tri >= 0) & (t < tmax)
        skip = np.asarray(skip, np.int64).reshape(-1)
        occ = np.zeros(n, bool)
        todo = np.arange(n)
        lo = tmin.copy()
        for _ in range(MAX_SKIP_RELAUNCH + 1):
            if len(todo) == 0:
                break
            t, tri, _, _ = self._intersect(o[todo], d[todo], lo[todo], tmax[todo])
            hit = (tri >= 0) & (t < tmax[todo])
            again = hit & (tri == skip[todo])
            occ[todo[hit & ~again]] = True
            # past the skipped triangle: a relative step of its hit distance (float32 spacing)
            nxt = todo[again]
            lo[nxt] = t[again] + 1e-5 * np.maximum(np.abs(t[again]), 1e-3)
            todo = nxt
        return occ

    def hit_distances(self, origins, directions, tmin=0.0, tmax=np.inf):
        """Distance to the nearest surface per ray, inf where none within tmax (thickness and
        ambient-occlusion bakes): ``closest_hit``'s t alone."""
        return self.closest_hit(origins, directions, tmin, tmax)[0]

    def ambient_occlusion(self, points, normals, directions_per_point: int = 64, max_distance=np.inf, offset=1e-4,
                          seed: int = 0):
        """Cosine-weighted ambient occlusion and bent normal per point (Zhukov et al. 1998;
        Landis 2002): the fraction of cosine-weighted hemisphere directions that escape within
        ``max_distance`` (1 = open), and the normalised mean escaping direction. Batched:
        points (n, 3), normals (n, 3) unit; ``offset`` lifts ray origins off the surface."""
        ao, bent, _, _ = self.ambient_rays(points, normals, directions_per_point, max_distance, offset, seed)
        return ao, bent

    def ambient_rays(self, points, normals, directions_per_point: int = 64, max_distance=np.inf, offset=1e-4,
                     seed: int = 0):
        """ambient_occlusion() with its rays: (A (n,), bent normal (n, 3), the directions (n, k, 3)
        (ambient_directions(normals, k, seed)), occluded (n, k) bool)."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, np.float64).reshape(-1, 3)
        k = int(directions_per_point)
        dirs = ambient_directions(nrm, k, seed)
        o = np.repeat(p + nrm * offset, k, axis=0)
        occ = self.occluded(o, dirs.reshape(-1, 3), 0.0, max_distance).reshape(len(p), k)
        free = ~occ
        ao = free.mean(1)
        # the unnormalised bent normal E[d 1_free] = E[d] - E[d 1_occluded], with the exact mean of
        # the cosine-weighted directions, E[d] = 2/3 n, as a control variate: the estimate's noise
        # then comes from the occluded rays only (an open point gets exactly n)
        bent = (2.0 / 3.0) * nrm - (dirs * occ[..., None]).mean(1)
        ln = np.linalg.norm(bent, axis=1, keepdims=True)
        bent = np.where((ln > 1e-12) & (ao[:, None] > 0), bent / np.maximum(ln, 1e-300), nrm)
        return ao, bent, dirs, occ


def ambient_directions(normals, k: int, seed: int = 0):
    """The k cosine-weighted directions per normal that ambient_occlusion casts for ``seed``
    (n, k, 3): a bake that kept only which rays were occluded can regenerate them.

    Stratified (each point's own random strata, so still unbiased): k = s^2 a jittered s x s grid
    of (u1, u2), otherwise Latin-hypercube (one sample per row and column of a k x k grid). Malley's
    map keeps cosine-weighted measure, so each stratum is an equal share of the cosine lobe: a
    bright lamp behind an occluder is hit by its share of rays, not a Poisson number of them
    (Pharr, Jakob & Humphreys, PBRT 3rd ed., sec. 7.3)."""
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    n = len(nrm)
    u1, u2 = _ambient_strata(n, k, seed)
    return cosine_directions(nrm, np.broadcast_to(u1, (n, k)), np.broadcast_to(u2, (n, k)))


def ambient_directions_at(normals, k: int, seed: int, point, ray):
    """ambient_directions(normals, k, seed)[point, ray] (m, 3) without the other n k - m directions:
    the same random numbers (the whole stream is drawn, so each ray keeps its own) and the same
    elementwise formulas, only where asked (the bakes' occluded rays: ~5-30 % of them; regenerating
    all 26 M directions of a 100 k-vertex mesh took 13 s to use a few)."""
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    point, ray = np.asarray(point, np.intp), np.asarray(ray, np.intp)
    u1, u2 = _ambient_strata(len(nrm), k, seed, point, ray)
    return cosine_directions(nrm[point], u1[:, None], u2[:, None])[:, 0]


def _ambient_strata(n: int, k: int, seed: int, point=None, ray=None):
    """ambient_directions' (u1, u2), (n, k) each, or at (point, ray) alone (m,) each."""
    rng = np.random.default_rng(seed)
    j1, j2 = rng.random((n, k)), rng.random((n, k))
    s = int(round(np.sqrt(k)))
    if s * s == k:
        cell = np.arange(k)
        if point is not None:
            cell, j1, j2 = ray, j1[point, ray], j2[point, ray]
        return (cell // s + j1) / s, (cell % s + j2) / s
    perm = np.argsort(rng.random((n, k)), axis=1)
    cell = np.arange(k)
    if point is not None:
        cell, perm, j1, j2 = ray, perm[point, ray], j1[point, ray], j2[point, ray]
    return (cell + j1) / k, (perm + j2) / k


def cosine_directions(normals, u1, u2):
    """Cosine-weighted directions about each unit normal (Malley's method: a uniform point of the
    unit disc, (sqrt(u1), 2 pi u2) in polar form, lifted to the hemisphere), in each normal's
    tangent frame. normals (n, 3); u1, u2 (n, k) in [0, 1); returns (n, k, 3).

    Computed in blocks of normals (BLOCK_RAYS rays each) into one output array: the same
    elementwise operations in the same order, so the same bits, but the temporaries stay in the
    cache instead of streaming ~10 arrays of n k 3 float64 through memory (the interreflection
    bake's 4.7 M rays on the head: 1.26 -> 0.24 s; benchmarks/RESULTS.md, "Round 17, branch bake17")."""
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    shape = np.broadcast_shapes(np.shape(u1), np.shape(u2))
    if len(shape) != 2 or shape[0] != len(nrm):  # not (n, k) samples: the formula as it stands
        return _cosine_block(nrm, u1, u2)
    n, k = shape
    u1, u2 = np.broadcast_to(u1, shape), np.broadcast_to(u2, shape)
    out = np.empty((n, k, 3), np.float64)
    step = max(1, BLOCK_RAYS // max(k, 1))
    for a in range(0, n, step):
        out[a:a + step] = _cosine_block(nrm[a:a + step], u1[a:a + step], u2[a:a + step])
    return out


def _cosine_block(nrm, u1, u2):
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u1, 0.0))], -1)
    a = np.where(np.abs(nrm[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(a, nrm)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    return local[..., :1] * t1[:, None] + local[..., 1:2] * t2[:, None] + local[..., 2:] * nrm[:, None]
