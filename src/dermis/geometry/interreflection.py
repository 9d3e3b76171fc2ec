"""One diffuse bounce between skin surfaces (interreflection): the rays of a per-vertex gather, baked.

Light that leaves one part of the skin and lands on another (the eyelids and the eye socket, the
sides of the nose, the concha) is missing from a renderer whose irradiance counts only lights and
the environment. One bounce of it, at a point x with normal n, is the irradiance

    E_b(x) = integral over the hemisphere of L_o(y(w)) cos(theta) dw  ~=  (pi / K) sum_k L_o(y_k)

with K cosine-weighted directions w_k (pdf cos(theta) / pi) and y_k the first surface point along
each (Kajiya 1986; the one-bounce gather of Ritschel, Dachsbacher, Grosch & Kautz 2012, "The State
of the Art in Interactive Global Illumination", sec. 3). A ray that escapes brings the environment,
which the occluded environment light already counts (dermis.geometry.visibility): it adds
nothing here. With the diffuse radiance L_o(y) = rho(y) E(y) / pi leaving y,

    E_b(x) = (1 / K) sum_k rho(y_k) E(y_k).

This module casts the rays once per mesh (Embree, dermis.geometry.raycast) and keeps, per vertex and
ray, the triangle hit and its barycentrics; tsd's runtime pass (techniques/tsd.py,
shaders/tsd/bounce_*.frag) turns them into texture-space UVs, reads rho E there from a ~1 mm level
of its irradiance (all BAKE_RAYS rays, merged per vertex and texel cell: :func:`merge_hits`) and adds
E_b to the irradiance before the diffusion blurs it. ssss, preintegrated and lambert share one
gather per lighting change from a small texture-space raster of rho E
(dermis.gl.interreflection.SharedBounce) and add E_b per vertex (common/interreflection.glsl).

Rays start at the vertex, lifted along its normal by OFFSET_REL of the mesh's diagonal (as the
visibility bake). A ray whose first hit is a face turned away from it (the interpolated normal
along the ray: the inside of an open mesh, a crack) is blocked and brings nothing: the irradiance
texture holds the light of the outer side only; but a grazing ray that passes behind a facet next
to its vertex is kept as a hit there (_first_front_hits). The directions are stratified per vertex (a Latin
hypercube over Malley's unit square, nested so that the higher bounces' subset is one too:
:func:`stratified_cosine_directions`), which lowers the estimate's variance below the independent
rays' rho E sqrt(F (1 - F) / K) (F the fraction of the hemisphere that sees lit skin).

Only the skin mesh takes part: non-skin surfaces (eyes, teeth) neither block nor reflect. Cached in
memory per mesh content and on disk, like the visibility bake.

Higher bounces. The same rays define a linear operator on per-vertex irradiances,

    (G T)(x) = (1 / K) sum_k rho(y_k) T(y_k),

T(y_k) the barycentric interpolation at the hit: the irradiance that bounce light T, reflected once
more by the skin (diffusely, with the same total albedo rho as the one bounce), brings to x. The
light that reached x after n reflections off the skin is G^(n-1) E_b, and the sum over the first
BOUNCE_ORDERS of them is the truncated Neumann series of the rendering equation's diffuse
interreflection (Kajiya 1986, eq. 6 expanded; Cohen & Wallace 1993, "Radiosity and Realistic Image
Synthesis", sec. 2.6 and 5.3: the Jacobi iteration B <- E + rho F B):

    T_n = E_b + G T_(n-1),  T_1 = E_b,  so  T_n = E_b + G E_b + ... + G^(n-1) E_b.

G's rows sum to at most max(rho) times the fraction of rays that hit skin (< 1), so the series
converges; inside a closed sphere of uniform albedo rho under a uniform sky, E_b = rho E and
T_n = E (rho + rho^2 + ... + rho^n) (tests/test_interreflection.py). Runtime: one more raster of
rho T in texture space and one more gather per order over SERIES_RAYS of the rays
(dermis.gl.interreflection.BounceSeries); :func:`bounce_series` is its numpy twin.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dermis.geometry import bake_cache
from dermis.geometry.atlas import content_hash
from dermis.geometry.visibility import OFFSET_REL

BAKE_RAYS = 512
"""Rays per vertex, all of them gathered for the one bounce. Unstratified, a vertex seeing lit skin
over a fraction F of its cosine-weighted hemisphere would get a standard error of
rho E sqrt(F (1 - F) / K) <= 0.022 rho E; the Latin hypercube lowers it, and the vertices'
interpolation and the diffusion's blur average several vertices. 128 -> 512 took FLIP(lambert,
Cycles' render without subsurface scattering) on back-ears 0.0237 -> 0.0212 (benchmarks/RESULTS.md,
"Round 16, branch transport16"; "Round 17, branch bounce17"). Cost on the head (9279 vertices):
4.8 M closest-hit rays, 12.5 s once per mesh (128 rays: 2.5 s; load 3.4), cached on disk; 3.7 s since round
17's bake17 (the same rays in cache-sized blocks, over threads; load 2.9), its file 26 MB (the hits alone)."""
SERIES_RAYS = 128
"""Rays per vertex the higher bounces gather (G, :func:`bounce_series`): a nested subset of the
BAKE_RAYS (every BAKE_RAYS / SERIES_RAYS-th ray, itself a Latin hypercube:
:func:`stratified_cosine_directions`). The higher orders' light is smooth (a gather of a gather),
so more rays cost per lighting change without moving the image: orders 2-4 over all 512 rays (an
unnested bake) gave FLIP(lambert, Cycles' control) back-ears 0.0188, side 0.0095, front-key 0.0108
against 0.0181, 0.0097, 0.0107 over these 128 (benchmarks/RESULTS.md, "Round 17, branch bounce17")."""


def series_step(rays: int) -> int:
    """The stride between the higher bounces' rays in a bake of ``rays`` per vertex (SERIES_RAYS):
    1 (every ray) where ``rays`` is not a multiple of SERIES_RAYS above it."""
    rays = int(rays)
    return rays // SERIES_RAYS if rays > SERIES_RAYS and rays % SERIES_RAYS == 0 else 1


BOUNCE_ORDERS = 4
"""Reflections off the skin that the bounce light counts (T_4 = E_b + G E_b + G^2 E_b + G^3 E_b):
what Cycles renders through dermis's bridge. dermis.blender.export sets max_bounces = 12 and leaves
Blender's default diffuse_bounces = 4, which Cycles' kernel takes as a limit of 5
(scene/integrator.cpp: "plus one so that a bounce of 0 indicates ... only direct illumination").
The random walk (BSSRDF) at the camera's skin point counts no bounce (shade_surface.h,
integrate_surface_bsdf_bssrdf_bounce returns before path_state_next); its exit is a diffuse BSDF
that takes the lights (direct light) and whose bounce is diffuse bounce 1; skin reached after a
diffuse bounce is a diffuse BSDF of the same colour (no second random walk: subsurface.h), and the
path stops at the surface reached by diffuse bounce 5 (path_state.h, path_state_next: count >= limit
marks PATH_RAY_TERMINATE_AFTER_TRANSPARENT: no light samples there). So the lights and the sky
arrive after 0 (direct), 1, 2, 3 and 4 reflections off other skin: 4 orders of bounce light."""
CACHE_VERSION = 4  # bump when the bake or its file changes meaning (2: grazing rays behind a neighbouring facet
# are hits; 3: nested Latin hypercubes, the higher bounces' subset stratified on its own; 4: the file holds the hits
# alone, _packed: a new name, so that trees before it, sharing the cache folder, keep their files instead of
# re-baking each other's in turn)
NEAR_REL = 0.01
"""An away-facing first hit closer than this (relative to the mesh's bounding diagonal: 2.5 mm on
the head) is the ray's own neighbourhood, kept as a hit (_first_front_hits)."""


@dataclass
class VertexHits:
    """The first hit of each of K rays per vertex: triangle (-1: escaped, or a face turned away)
    and the barycentrics (of the triangle's vertices 1 and 2) there."""

    triangle: np.ndarray  # (n, K) int32
    barycentric: np.ndarray  # (n, K, 2) float32
    seconds: float  # bake time (0 when read from a cache)
    cached: bool

    @property
    def rays(self) -> int:
        return int(self.triangle.shape[1])

    def series_subset(self) -> "VertexHits":
        """The rays the higher bounces gather (SERIES_RAYS: every series_step-th, group 0 of the
        nested hypercube)."""
        step = series_step(self.rays)
        return VertexHits(self.triangle[:, ::step], self.barycentric[:, ::step], self.seconds, self.cached)

    def at_vertices(self, values, indices) -> np.ndarray:
        """``values`` (per vertex of the mesh, (V, c)) interpolated at every hit: (n, K, c), NaN
        where a ray brings nothing. E.g. the texture-space UVs of the hits."""
        hit, at = self.at_hits(values, indices)
        out = np.full(self.triangle.shape + (at.shape[1],), np.nan)
        out[hit] = at
        return out

    def at_hits(self, values, indices):
        """:meth:`at_vertices` at the rays that hit alone: (the (n, K) mask of those rays, the values
        there (h, c) in the mask's row-major order), without the (n, K, c) array of NaN misses."""
        vals = np.asarray(values, np.float64)
        vals = vals.reshape(len(vals), -1)
        idx = np.asarray(indices, np.int64).reshape(-1, 3)
        hit = self.triangle >= 0
        tri = self.triangle[hit].astype(np.int64)  # the rays that hit only (a third to a half of them)
        b = self.barycentric[hit].astype(np.float64)
        corners = vals[idx[tri]]  # (h, 3, c)
        return hit, ((1.0 - b[:, 0] - b[:, 1])[:, None] * corners[:, 0] + b[:, :1] * corners[:, 1]
                     + b[:, 1:] * corners[:, 2])


_MEMORY: dict[str, dict] = {}  # content key -> the bake's arrays (dermis.geometry.bake_cache)
_MEMORY_MAX = 4


def stratified_cosine_directions(normals, rays: int, rng, groups: int = 1) -> np.ndarray:
    """(n, rays, 3) cosine-weighted directions about each normal: a Latin hypercube of (u1, u2)
    (each coordinate stratified into ``rays`` bins, paired at random per vertex) through Malley's
    method (dermis.geometry.raycast.cosine_directions).

    With ``groups`` g > 1 (dividing ``rays``) the hypercube is nested: ray r = j g + m (j < rays / g)
    has u2 in fine bin j g + m and u1 in fine bin g sigma_m(j) + pi_(sigma_m(j))(m), sigma_m a random
    permutation of the rays / g coarse bins per group m and pi_b one of the g fine bins inside coarse
    bin b. Every ray lies in its own fine bin of each coordinate (a Latin hypercube of ``rays``), and
    each group m (rays m, m + g, m + 2 g, ...) has one ray in every coarse bin: a Latin hypercube of
    rays / g on its own (nested or "sliced" Latin hypercubes: Qian 2012, "Sliced Latin hypercube
    designs", JASA 107). The higher bounces gather group 0 alone (SERIES_RAYS)."""
    from dermis.geometry.raycast import cosine_directions

    n, k, g = len(normals), int(rays), int(groups)
    if g < 1 or k % g:
        raise ValueError(f"{g} groups do not divide {k} rays")
    sub = k // g
    sigma = np.argsort(rng.random((n, g, sub)), axis=2)  # (n, m, j): coarse bin of ray (j, m)
    pi = np.argsort(rng.random((n, sub, g)), axis=2)  # (n, coarse bin, m): fine bin inside it
    coarse = np.swapaxes(sigma, 1, 2)  # (n, j, m)
    m = np.arange(g)
    u1_bin = g * coarse + pi[np.arange(n)[:, None, None], coarse, m[None, None, :]]
    u2_bin = (g * np.arange(sub)[:, None] + m[None, :])[None].repeat(n, 0)
    u1 = (u1_bin.reshape(n, k) + rng.random((n, k))) / k
    u2 = (u2_bin.reshape(n, k) + rng.random((n, k))) / k
    return cosine_directions(normals, u1, u2)


def bake_vertex_hits(positions, normals, indices, *, rays: int | None = None, seed: int = 0,
                     cache: bool = True) -> VertexHits:
    """The first hit of ``rays`` cosine-weighted rays from every vertex of a triangle mesh (any unit)."""
    from dermis.geometry.raycast import RayCaster

    rays = int(BAKE_RAYS if rays is None else rays)
    p = np.ascontiguousarray(positions, np.float32).reshape(-1, 3)
    nrm = np.ascontiguousarray(normals, np.float32).reshape(-1, 3)
    t = np.ascontiguousarray(indices, np.uint32).reshape(-1, 3)
    key = content_hash(p, t, CACHE_VERSION, nrm.tobytes(), rays, int(seed), series_step(rays))  # the nesting too
    path = bake_cache.cache_path("interreflection", key) if cache else None
    got = _load(key, path, len(p), rays) if cache else None
    if got is not None:
        return VertexHits(got["triangle"], got["barycentric"], 0.0, True)
    t0 = time.perf_counter()
    n64, first, inverse, diag = bake_cache.distinct_vertices(p, nrm)  # one bake per distinct vertex
    p64 = p.astype(np.float64)
    caster = RayCaster(p64, t)
    po, no = p64[first], n64[first]
    dirs = stratified_cosine_directions(no, rays, np.random.default_rng(seed), series_step(rays)).reshape(-1, 3)
    origins = np.repeat(po + no * (OFFSET_REL * diag), rays, axis=0)
    tri, bary = _first_front_hits(caster, origins, dirs, t.astype(np.int64), n64, NEAR_REL * diag)
    tri = tri.reshape(len(first), rays).astype(np.int32)
    bary = np.where((tri >= 0)[..., None], bary.reshape(len(first), rays, 2), 0.0).astype(np.float32)
    h = VertexHits(tri[inverse], bary[inverse], time.perf_counter() - t0, False)
    if cache:
        bake_cache.remember(_MEMORY, key, {"triangle": h.triangle, "barycentric": h.barycentric}, _MEMORY_MAX)
        bake_cache.store(path, _packed(h.triangle, h.barycentric))
    return h


def _packed(triangle, barycentric) -> dict:
    """The bake as it is stored on disk, the rays that hit alone: which rays hit (a bit each,
    np.packbits), their triangles and barycentrics. Lossless (a ray that brings nothing has
    triangle -1 and barycentrics 0); 12 bytes per ray become 1/8 + 12 f (f the fraction that hits:
    0.45 on the Lee Perry-Smith head, 0.07 on the default one): 57 -> 26 MB and 186 -> 15 MB."""
    hit = triangle >= 0
    return {"hit": np.packbits(hit, axis=None), "triangle": triangle[hit], "barycentric": barycentric[hit]}


def _load(key, path, n: int, rays: int) -> dict | None:
    """The bake of ``key`` from memory or from its packed file (:func:`_packed`), or None."""
    if key in _MEMORY:
        return _MEMORY[key]
    z = bake_cache.load({}, key, path, {"hit": ((n * rays + 7) // 8,), "triangle": None, "barycentric": None}, 1)
    if z is None:
        return None
    if z["hit"].dtype != np.uint8 or z["triangle"].dtype != np.int32 or z["barycentric"].dtype != np.float32:
        return None
    hit = np.unpackbits(z["hit"], count=n * rays).view(bool).reshape(n, rays)
    h = int(hit.sum())
    if z["triangle"].shape != (h,) or z["barycentric"].shape != (h, 2):
        return None
    tri = np.full((n, rays), -1, np.int32)
    tri[hit] = z["triangle"]
    bary = np.zeros((n, rays, 2), np.float32)
    bary[hit] = z["barycentric"]
    arrays = {"triangle": tri, "barycentric": bary}
    bake_cache.remember(_MEMORY, key, arrays, _MEMORY_MAX)
    return arrays


def _first_front_hits(caster, origins, dirs, tris, normals, near):
    """(triangle, barycentrics) of each ray's first hit, -1 where it escapes or its first hit is a
    face turned away from it (the interpolated normal along the ray) farther than ``near``.

    An away face closer than ``near`` is the ray's own neighbourhood: at a concave vertex the
    facets around it rise above the plane of the vertex normal (the faces' mean), so a grazing ray
    passes behind the next facet and, cast on, leaves the mesh (1.1 % of the rays inside a closed
    32 x 16 sphere). The smooth surface the facets stand for would have stopped it within a chord of
    2 R sin(elevation), close by: the hit is kept, and the light of that neighbourhood is read."""
    th, tri, bary = caster.closest_hit(origins, dirs)
    # the rays that hit (a third to a half), and of them those beyond ``near``: the normal is
    # interpolated there only (the same operations per ray as over all of them, so the same bits)
    far = np.flatnonzero((tri >= 0) & (th >= near))
    b = bary[far]
    w = np.c_[1.0 - b.sum(1), b]
    hn = np.einsum("nk,nkc->nc", w, normals[tris[tri[far]]])
    tri = tri.copy()
    tri[far[np.einsum("nc,nc->n", hn, dirs[far]) >= 0.0]] = -1
    return tri, bary


def merge_hits(uv, cells: int):
    """The one bounce's hits merged per vertex and bilinear cell of a ``cells``^2 texture-space level:
    (offsets (n,) int32, counts (n,) int32, entries (m, 3) float32), vertex v's entries
    ``entries[offsets[v]:offsets[v] + counts[v]]``, each (mean u, mean v, share w) of the rays of
    ``uv`` ((n, K, 2), NaN where a ray brings nothing) whose hits fall between the same four texel
    centres, w = their count / K. The gather's sum_k f(uv_k) / K becomes sum_e w_e f(uv_e): the same
    for a bilinear f (texture filtering between those four texels) up to w_e cov(u, v) f_uv within
    the cell; on the head at 1 mm texels 512 rays become 112 entries per vertex on average (misses
    dropped, hits sharing a cell merged) and the gather's reads fall in proportion."""
    uv = np.asarray(uv, np.float64)
    hit = np.isfinite(uv[..., 0]) & np.isfinite(uv[..., 1])
    return merge_hit_uvs(hit, uv[hit], cells)


def merge_hit_uvs(hit, u, cells: int):
    """:func:`merge_hits` from the rays that hit alone: ``hit`` the (n, K) mask of the rays whose uv
    is finite, ``u`` (h, 2) their uvs in the mask's row-major order (VertexHits.at_hits)."""
    n, k = hit.shape
    ok = np.isfinite(u[:, 0]) & np.isfinite(u[:, 1])
    if not ok.all():  # a layout with NaN: as merge_hits drops those rays
        hit = hit.copy()
        hit[hit] = ok
        u = u[ok]
    vert = np.broadcast_to(np.arange(n)[:, None], (n, k))[hit]
    side = int(cells) + 2  # cells -1 .. cells (bilinear cells between texel centres, and the borders)
    c = np.clip(np.floor(u * int(cells) - 0.5).astype(np.int64) + 1, 0, side - 1)
    key = (vert.astype(np.int64) * side + c[:, 0]) * side + c[:, 1]
    uniq, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    entries = np.empty((len(uniq), 3), np.float64)
    entries[:, 0] = np.bincount(inv, weights=u[:, 0], minlength=len(uniq)) / cnt
    entries[:, 1] = np.bincount(inv, weights=u[:, 1], minlength=len(uniq)) / cnt
    entries[:, 2] = cnt / k
    owner = uniq // (side * side)
    counts = np.bincount(owner, minlength=n).astype(np.int32)
    offsets = (np.cumsum(counts) - counts).astype(np.int32)
    return offsets, counts, entries.astype(np.float32)


def mesh_hits(mesh, *, cache: bool = True) -> VertexHits:
    """The bake of a dermis Mesh (its positions, normals, triangles)."""
    return bake_vertex_hits(mesh.positions, mesh.normals, mesh.indices, cache=cache)


def bounce_irradiance(hits: VertexHits, indices, exitant) -> np.ndarray:
    """The numpy twin of the runtime gather: E_b per vertex, (n, c) = (1 / K) sum over the rays of
    ``exitant`` (per mesh vertex, (V, c): rho E = pi L_o, the light leaving the surface times pi)
    interpolated at the hits; rays that bring nothing add 0."""
    at = hits.at_vertices(exitant, indices)
    return np.nansum(at, axis=1) / hits.rays


def bounce_series(hits: VertexHits, indices, first, albedo, orders: int | None = None) -> np.ndarray:
    """The numpy twin of the runtime's higher bounces (dermis.gl.interreflection.BounceSeries): T_n
    per vertex, (n, c), from the one bounce ``first`` (E_b, (n, c)) and the skin's total diffuse
    albedo ``albedo`` per vertex ((V, c) or (c,)): T_1 = E_b, T_n = E_b + G T_(n-1) with
    (G T)(x) = (1 / K) sum_k (rho T)(y_k) over the SERIES_RAYS subset (VertexHits.series_subset), rho T
    interpolated at the hits as the runtime's gather reads it (:func:`bounce_irradiance`), ``orders`` = n
    (default BOUNCE_ORDERS)."""
    n = int(BOUNCE_ORDERS if orders is None else orders)
    if n < 1:
        raise ValueError(f"bounce orders must be >= 1, got {n}")
    e = np.asarray(first, np.float64)
    rho = np.broadcast_to(np.asarray(albedo, np.float64), e.shape)
    t = e
    g = hits.series_subset()  # G over SERIES_RAYS, as the runtime's higher orders
    for _ in range(n - 1):
        t = e + bounce_irradiance(g, indices, rho * t)
    return t


def layout_median_stretch(positions, uvs, indices, mm_per_unit: float, size: int) -> float:
    """The median stretch of a texture-space layout at ``size``^2 texels: texels per mm along u and
    along v (each triangle's |dP/du|^-1 and |dP/dv|^-1, P in mm, u and v in texels), both axes
    pooled, weighted by the triangle's texels (its uv area): the median of tsd's stretch map over its
    covered texels (tsd/stretch.frag) without the raster, for the bounce's level
    (dermis.gl.interreflection.bounce_level)."""
    p = np.asarray(positions, np.float64) * float(mm_per_unit)
    uv = np.asarray(uvs, np.float64) * float(size)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    duv = np.stack([uv[t[:, 1]] - uv[t[:, 0]], uv[t[:, 2]] - uv[t[:, 0]]], 1)  # (n, 2 edges, (u, v))
    dp = np.stack([p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]], 1)  # (n, 2 edges, 3)
    det = duv[:, 0, 0] * duv[:, 1, 1] - duv[:, 0, 1] * duv[:, 1, 0]
    ok = np.abs(det) > 1e-12
    if not ok.any():
        return 0.0
    J = np.linalg.solve(duv[ok], dp[ok])  # rows: dP/du, dP/dv (mm per texel)
    lengths = np.linalg.norm(J, axis=2)
    ok2 = np.all((lengths > 0) & np.isfinite(lengths), axis=1)
    if not ok2.any():  # every triangle's extent underflowed or overflowed: no stretch, as above
        return 0.0
    vals = (1.0 / lengths[ok2]).T.ravel()  # u then v
    w = np.tile(0.5 * np.abs(det[ok][ok2]), 2)
    order = np.argsort(vals)
    cw = np.cumsum(w[order])
    return float(vals[order][np.searchsorted(cw, 0.5 * cw[-1])])
