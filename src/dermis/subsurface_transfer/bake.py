"""The bake of the subsurface transfer that texture-space diffusion does not carry (physics: numpy,
scipy and Embree; no GL). Lengths in mm.

What is baked. For a bake point x_o (a texel centre of the mesh's texture-space layout in or near a
thin part) the radiance leaving x_o is, with a diffuse (view- and light-direction-independent) exit
and entry (the multiple-scattering term of Jensen et al. 2001),

    L(x_o) = A(x_o)^(1 - mix) / pi  *  integral  tau(x_o, x_i)  I_0(x_i)  dA_i

with I_0 = E (1 - rho_s a / pi) A^mix tsd's irradiance map and tau normalised so that a flat,
uniformly lit, semi-infinite medium gives integral tau = 1 (tsd's normalised profile does the same: a
flat surface of uniform irradiance E has radiance A E / pi). tau is sampled by the adjoint skin walk
(dermis.reference.random_walk, index 1.4, Fresnel at every face, per channel the medium of the
thin-slab law: the mean free path 1 / sigma_t' the law fits to the profile's mean radius, the
single-scattering albedo that makes the semi-infinite walk reflect the skin's mean albedo): walks
start at x_o along cosine-distributed (diffuse) views refracted in; each walk that refracts out at
x_i carries w n^2, its radiance at x_o per unit radiance arriving at x_i (reciprocity: the same number
is the transport from light entering at x_i to x_o). A diffuse field L_i = E_i / pi at x_i gives
w n^2 E_i / pi; divided by the same walk's flat total R_flat (:func:`flat_kernel`) that is tau in the
irradiance map's units.

What is kept (the split against tsd, derived). tsd carries (1) the blur chain: its profile R at the
distance along the surface (measured on the head's ear: tsd's texture-space result equals the
surface integral of R at the geodesic distance within 6%, benchmarks/RESULTS.md round 10), and (2)
translucency: the far face, whose normal is opposite to x_o's. The bake holds, over the SAME-FACING
exits (n_i . n_o > 0; the opposite face stays translucency's), the walk's transport in the mesh's
geometry LESS the same walk's transport on a flat semi-infinite surface at the same geodesic
distance g, K_flat(g) (:func:`flat_kernel`):

    tau_geo(x_o, x_i) = tau(x_o, x_i) - K_flat(g(x_o, x_i))     (same-facing x_i)

On a flat thick surface it is 0 in expectation (it adds nothing where tsd's blur is the whole
answer), so it never double counts with (1): tsd + tau_geo = tau + (R - K_flat), the profile's own
flat mismatch as everywhere else on the face. What it carries: a thin sheet guides light sideways (the
light that a semi-infinite medium would scatter back from depth meets the far face and is partly
reflected there: less light within ~1 mm, more beyond), a curled rim brings light entering around
the curl. It is stored as taps: tap 0 at x_o itself for the exits within MIN_SURFACE_MM along the
surface (their sum less K_flat's share of that disc, F_flat(MIN_SURFACE_MM)), the others for the
exits beyond, tallied at the nearest vertex of the mesh subdivided twice less K_flat(g_v) A_v at the
same-facing vertices beyond MIN_SURFACE_MM (A_v a third of the subtriangles' area), compressed to at
most ``taps - 1`` taps (weighted k-means on the vertices' positions; a tap sits at the member vertex
nearest its cluster's weighted centre, its weight the cluster's sum: the point's total is kept
exactly). Geodesic distance: Dijkstra on a graph joining all vertices of each given triangle's
subdivision lattice by straight lines (exact within a triangle), a lower bound
max(r, path - both points' distances to their vertices) between two surface points.

Where it is kept (the Monte Carlo noise; rounds 11-12). The net is the difference of two ~1 totals (the
walk's same-facing transport and the flat kernel's share), so with 192 walks a point and the flat share
subtracted as its deterministic expectation it carries a +-5 % Monte Carlo error per point where its
expectation is ~0: on the thick skin of the 6 mm band beside every thin part (cheeks under the eyes,
around the nose and lips), which tsd showed as a mottle (benchmarks/RESULTS.md, round 10 merged).

The control variate (round 12). Each walk is paired with its flat twin (:func:`walk_exits` ``twin``;
dermis.reference.random_walk.halfspace_exits): the same walk (the same view, the same random numbers per
walk and event: random_walk.CounterUniforms, common random numbers) in the semi-infinite half-space
below the plane of the facet it enters by. Per walk, the twin's tally within MIN_SURFACE_MM (its
exit's distance in the plane) is subtracted from the walk's own tally within, and its tally beyond
times S_b / (1 - F_flat(MIN_SURFACE_MM)) from the walk's beyond (S_b = sum K_flat(g_v) A_v, the
deterministic share the far taps subtract: its spatial shape is kept, scaled by the twins' far
transport over its expectation). The twin's expectations are F_flat(MIN_SURFACE_MM) and
1 - F_flat(MIN_SURFACE_MM) (it IS the flat kernel's walk; measured for the head's media with 200,000
twins: within the kernel's own 0.2-0.6 % error, benchmarks/RESULTS.md round 12 cv12), so the estimator's
expectation is the deterministic one's: unbiased. Where the head is locally flat and thick the walk and
its twin are one walk until it strays beyond the curvature (or a discrete choice differs by rounding),
so the per-walk difference is mostly exactly 0: on the head the per-point standard error falls 3x
(red) to 20x (blue) on the cheek and 1.6-5.7x on the helix (RESULTS.md round 12). ``crn=False`` keeps
round 11's estimator (the deterministic share alone).

The view (round 22, view22; issue 12). The walks start along cosine views, so the taps above are the
transfer's mean over a diffuse exit; what a camera sees is the transfer along its ray, and that differs
where the geometry or the light varies within millimetres (benchmarks/RESULTS.md round 21 taps21: at
front-key's mouth line +0.11-0.13 E0 red along cosine views, ~0 along the camera ray; at the back-lit
ear's scapha 1.3x more along the camera ray). From the SAME walks (no extra walk) each tap also keeps a
view term per channel, (G_x, G_y, G_z, c) in the mesh's frame (:func:`view_basis`): a walk along view v
enters with the Fresnel transmittance 1 - F(v) (all or none: a walk reflected at entry tallies 0, its
flat twin too), and what it carries once in is taken linear in its refracted direction r(v), so

    T_k(v) = (1 - F(v)) (G_k . r(v) + c_k),

fitted per point by least squares of each walk's tally / (1 - F) on its r (an intercept at the walks'
mean r; the tap's exits each carry their walk's regressor row, the flat twins' tallies likewise: the
control variate is carried the same way, so on thick skin the view term is as exactly 0 as the mean).
Its mean over the cosine views is the tap's weight w_k up to the fit. The readers (common/
subsurface_transfer.glsl subsurface_transfer_view) add sum_k T_k(v) I_k less the cosine grid's
sum_k w_k I_k at the fragment's view. Measured (benchmarks/view_transfer.py, RESULTS.md round 22): at
the mouth line the view term at the camera is the fresh camera-ray walks' within their errors; on a thin
slab within 2 standard errors down to 70 degrees from the normal, too strong nearer grazing (the linear
model). Noise: the slope is an extrapolation of the walks' spread of directions (the refracted normal
component spans only 0.70-1), so the view term's Monte Carlo error is ~2-4x the mean's per point.

The bake keeps, per point and channel, its two parts' estimates (within / beyond MIN_SURFACE_MM, each
less its flat share or twin) and their covariance from the per-walk tallies (:func:`_walk_moments`);
:func:`significance` pools them over the same-facing points within POOL_MM (a chi-square statistic,
6 degrees of freedom where the expectation is 0). :func:`denoise` (shipped) averages each point's own
tap over SMOOTH_OWN_MM and leaves its far taps as walked (round 10's treatment: with the control
variate the mottle is within round 11's limits without more). Round 11's :func:`denoise_round11`, for
a bake without the control variate: (1) averages each thin point's transfer with its same-facing
neighbours' over SMOOTH_MM (:func:`smooth_taps`: the taps of all of them, recompressed) and each band
point's own tap alone (:func:`smooth_own_taps`; SMOOTH_MM where the transfer is strong, SMOOTH_WEAK_MM
elsewhere; its far taps as walked: pooling them biased the back-lit ear, benchmarks/RESULTS.md round 11
mottle11b) and (2) scales the taps of each point of the band (not thin itself) by the firm shrinkage
of its statistic (:func:`shrink_factor`): 0 where the pooled transfer is within ~2 standard errors of
0, whole where it is 4x beyond, continuous between; a thin point's transfer is kept. It cost the
eyelids against Cycles (round 11 mottle11b), which round 12's estimator recovers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import functools

import numpy as np

from dermis.errors import DermisError
from dermis.geometry.rasterize import rasterize_uv
from dermis.geometry.raycast import cosine_directions
from dermis.geometry.texture_space import texture_space_uvs
from dermis.reference.random_walk import MeshWalk, WalkMedium

DEFAULT_GRID = 512  # bake points: texel centres of a grid x grid layout (about 1 mm apart on the head's ears)
THIN_MM = 10.0  # a texel is baked where the ray along -N leaves the tissue within this (the ears, nose wings)
MIN_SURFACE_MM = 1.0  # exits nearer than this along the surface go to the point's own tap
MAX_SURFACE_MM = 15.0  # Dijkstra's reach; farther along the surface K_flat is below 1e-6 of its peak in red
NEAR_MM = 6.0  # and the texels within this of a thin one
DEFAULT_TAPS = 8
DEFAULT_WALKS = 192  # per point and channel (the shipped bake)
CHUNK_WALKS = 1 << 16


@dataclass
class BakePoints:
    """Where the transfer is baked: texture-space uv (n, 2), position (n, 3) mm, triangle (n,), the
    facet's outward normal (n, 3); ``thin`` (n,) bool: the texel is a thin one (:func:`thin_points`),
    not only beside one (None: unknown; :func:`shrink_insignificant` then tests every point)."""

    uv: np.ndarray
    position: np.ndarray
    triangle: np.ndarray
    normal: np.ndarray
    thin: np.ndarray | None = None


@dataclass
class TransferBake:
    """The baked transfer: per point its uv, and ``taps`` taps (uv in the texture-space layout, RGB
    weight: tau - K_flat(g) summed over the tap's cluster, in the irradiance map's units; tap 0 at the
    point itself; zero weight = unused). ``kept`` / ``subtracted`` (n, 3): per point, the walk's
    same-facing transfer and the flat kernel's share removed from it (their difference is the sum of
    the taps); ``meta``: how it was baked. ``excess`` (n, 3, 2): per point and channel the transfer's
    two parts as the walks estimate them (within MIN_SURFACE_MM, beyond), each less the flat kernel's
    share of it; ``excess_cov`` (n, 3, 3): the covariance of those two Monte Carlo means (var within,
    var beyond, covariance; from the per-walk tallies, / walks): what :func:`shrink_insignificant`
    tests. None for a bake made without them."""

    point_uv: np.ndarray
    tap_uv: np.ndarray
    tap_weight: np.ndarray
    kept: np.ndarray
    subtracted: np.ndarray
    meta: dict = field(default_factory=dict)
    excess: np.ndarray | None = None
    excess_cov: np.ndarray | None = None
    tap_position: np.ndarray | None = None  # (n, taps, 3) mm, in memory only (:func:`smooth_taps`)
    # (n, taps, 3, 4): per tap and channel the view term (G_x, G_y, G_z, c) in the mesh's frame: the tap's
    # weight seen along the view v is (1 - F(v)) (G . r(v) + c), r the refracted view (:func:`view_basis`,
    # module docstring "The view"); ``tap_weight`` stays the cosine views' mean. None: a view-independent bake
    tap_view: np.ndarray | None = None

    @property
    def total(self) -> np.ndarray:
        return self.tap_weight.sum(1)


def skin_media(profile, albedo, index: float = 1.4, photons: int = 20_000) -> tuple:
    """Per channel the skin walk's medium of ear9 (benchmarks/ear_translucency.py --walk): the
    thin-slab law's mean free path (dermis.profiles.thin_slab) and the single-scattering albedo whose
    semi-infinite walk reflects ``albedo`` (dermis.verification.random_walk_albedo)."""
    from dermis.profiles.thin_slab import slab_law
    from dermis.verification import random_walk_albedo

    albedo = np.asarray(albedo, np.float64)
    law = slab_law(profile.normalized(), albedo)
    out = []
    for c in range(3):
        mfp = float(1.0 / law.reduced_sigma_t_per_mm[c])
        out.append(WalkMedium(mfp, random_walk_albedo(float(albedo[c]), mfp, photons=photons, index=index), "fresnel", index))
    return tuple(out)


def diffuse_views(normals, rng) -> np.ndarray:
    """View rays (towards the surface) cosine-distributed about the outward ``normals``: a walk
    started along them estimates the exitance / pi (a diffuse exit)."""
    n = len(normals)
    return -cosine_directions(np.asarray(normals, np.float64), rng.random((n, 1)), rng.random((n, 1)))[:, 0]


def walk_exits(walker: MeshWalk, position, triangle, normal, medium: WalkMedium, walks: int, seed: int = 0,
               twin: bool = False, views=None) -> dict:
    """``walks`` adjoint walks from each point, diffuse views: the exits (random_walk's ``exits``)
    with "point_index" (which start point) and "sample" (which of its point's walks) added.
    ``twin``: the walks draw from a :class:`CounterUniforms` stream (``seed``) at their global index,
    and each walk's flat twin (:func:`dermis.reference.random_walk.halfspace_exits`: the same view,
    the same random numbers, the half-space tangent at the point, i.e. below the plane through it
    with the normal of the facet it enters by) is walked too: its exits under "twin" ("point_index", "sample",
    "radius" mm in the plane, "weight"). "walk_view" (n * walks, 3) float32: every walk's view ray
    (towards the surface), walk ``s`` of point ``i`` at row ``i * walks + s`` (the first-order term's
    regression needs the views of the walks that never exit too). ``views`` (n, 3): every walk of point i
    along views[i] (towards the surface) instead of cosine-distributed ones (a check of the view term:
    fresh walks along one view)."""
    from dermis.reference.random_walk import CounterUniforms, halfspace_exits

    position = np.asarray(position, np.float64)
    normal = np.asarray(normal, np.float64)
    n = len(position)
    total = n * int(walks)
    parts, twins, all_views = [], [], []
    fixed = None if views is None else np.asarray(views, np.float64).reshape(n, 3)
    rng = np.random.default_rng(seed)
    stream = CounterUniforms(seed) if twin else None
    for start in range(0, total, CHUNK_WALKS):
        gid = np.arange(start, min(start + CHUNK_WALKS, total))
        idx = gid // int(walks)
        views = diffuse_views(normal[idx], rng)
        if fixed is not None:  # the rng's draws as above: the walks' seeds do not depend on the option
            views = fixed[idx]
        all_views.append(views.astype(np.float32))
        ex = {}
        walker.radiance(position[idx], np.asarray(triangle)[idx], views, medium,
                        seed=int(rng.integers(2 ** 31)), exits=ex, uniforms=stream, walk_ids=gid)
        ex["point_index"] = idx[ex["walk"]]
        ex["sample"] = (start + ex["walk"]) % int(walks)  # which of its point's walks: per-walk tallies
        parts.append(ex)
        if twin:
            # the plane of the facet the walk enters by, turned to the viewer (as the walk's entry)
            tw = halfspace_exits(position[idx], walker._outward(np.asarray(triangle)[idx], -views), views, medium, stream, gid)
            twins.append({"point_index": idx[tw["walk"]], "sample": (start + tw["walk"]) % int(walks),
                          "radius": tw["radius"], "weight": tw["weight"]})
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]} if parts else {}
    if twin and twins:
        out["twin"] = {k: np.concatenate([t[k] for t in twins]) for k in twins[0]}
    out["walk_view"] = np.concatenate(all_views) if all_views else np.zeros((0, 3), np.float32)
    return out


FLAT_EDGES_MM = np.r_[np.arange(0.0, 5.0, 0.1), np.arange(5.0, 25.5, 0.5)]


@dataclass(frozen=True)
class FlatKernel:
    """The walk's transport on a flat semi-infinite surface (a slab 200 x 200 x 60 mm, walks from the
    centre of its top face, diffuse views): R_flat (the mean exit weight w n^2, tau's normalisation)
    with its standard error, and the radial density of the exits per mm^2 normalised to integral 1
    over the face (in radius bins ``edges``)."""

    reflectance: float
    reflectance_se: float
    edges: np.ndarray
    density: np.ndarray

    def at(self, g_mm) -> np.ndarray:
        """K_flat(g) per mm^2 (0 beyond the last bin)."""
        c = 0.5 * (self.edges[1:] + self.edges[:-1])
        return np.interp(np.asarray(g_mm, np.float64), c, self.density, right=0.0)

    def within(self, g_mm: float) -> float:
        """The share of the flat transport that exits within ``g_mm`` of the start (linear in the bin)."""
        mass = self.density * np.pi * (self.edges[1:] ** 2 - self.edges[:-1] ** 2)
        inner = np.clip((g_mm ** 2 - self.edges[:-1] ** 2) / (self.edges[1:] ** 2 - self.edges[:-1] ** 2), 0.0, 1.0)
        return float((mass * inner).sum())


def flat_kernel(medium: WalkMedium, walks: int | None = None, seed: int | None = None) -> FlatKernel:
    """:class:`FlatKernel` of ``medium`` by ``walks`` walks (default FLAT_KERNEL_WALKS, seed FLAT_KERNEL_SEED)."""
    walks = FLAT_KERNEL_WALKS if walks is None else int(walks)
    seed = FLAT_KERNEL_SEED if seed is None else int(seed)
    from dermis.scene.builtin import slab

    p, nn, _, t = slab(size=200.0, thickness=60.0, n=2)
    mw = MeshWalk(p, t, nn)
    pts = np.tile([0.0, 0.0, 30.0], (walks, 1))
    _, tri, _ = mw.caster.closest_hit(pts + [0, 0, 1.0], np.tile([0, 0, -1.0], (walks, 1)))
    ex = walk_exits(mw, pts, tri, np.tile([0, 0, 1.0], (walks, 1)), medium, 1, seed)
    per = np.bincount(ex["point_index"], weights=ex["weight"], minlength=walks)
    R = float(per.mean())
    top = ex["point"][:, 2] > 29.999
    r = np.linalg.norm(ex["point"][top, :2], axis=1)
    h, _ = np.histogram(r, FLAT_EDGES_MM, weights=ex["weight"][top])
    dens = h / (walks * R) / (np.pi * (FLAT_EDGES_MM[1:] ** 2 - FLAT_EDGES_MM[:-1] ** 2))
    return FlatKernel(R, float(per.std() / np.sqrt(walks)), FLAT_EDGES_MM.copy(), dens)


def profile_density(profile, g_mm) -> np.ndarray:
    """tsd's normalised profile R(g) per mm^2, (..., 3): sum_k w_k exp(-g^2 / 2 v_k) / (2 pi v_k)."""
    p = profile.normalized()
    w = np.asarray(p.weights, np.float64)  # (K, 3)
    v = np.asarray(p.variances_mm2, np.float64)  # (K,)
    g = np.asarray(g_mm, np.float64)[..., None]
    return (np.exp(-g * g / (2.0 * v)) / (2.0 * np.pi * v)) @ w


def subdivide(positions, indices, normals, uvs):
    """One 1-to-4 midpoint subdivision (a finer graph for geodesic distances): positions, indices,
    normals (renormalised), uvs of the new mesh. Midpoints per edge of the given triangles, so a
    triangle's uvs stay in its own chart."""
    idx = np.asarray(indices, np.int64).reshape(-1, 3)
    e = np.sort(np.concatenate([idx[:, [0, 1]], idx[:, [1, 2]], idx[:, [2, 0]]]), axis=1)
    edges, inv = np.unique(e, axis=0, return_inverse=True)
    inv = inv.reshape(3, -1).T + len(positions)  # midpoint ids of edges 01, 12, 20
    mid = lambda a: 0.5 * (a[edges[:, 0]] + a[edges[:, 1]])
    pos = np.r_[positions, mid(positions)]
    nrm = np.r_[normals, mid(normals)]
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    uv = np.r_[uvs, mid(uvs)]
    a, b, c = idx.T
    ab, bc, ca = inv.T
    tri = np.concatenate([np.c_[a, ab, ca], np.c_[ab, b, bc], np.c_[ca, bc, c], np.c_[ab, bc, ca]])
    return pos, tri, nrm, uv


class SurfaceGraph:
    """The mesh's edges, subdivided ``subdivisions`` times, as a graph (vertices merged by position:
    UV seams do not cut it) for geodesic distances along the surface (Dijkstra), with each merged
    vertex's area (mm^2), outward normal and texture-space uv. A surface point is represented by the
    nearest vertex of its own triangle's subdivision; the distance between two points is taken as max(their 3-D distance,
    the edge path between their vertices less both points' distances to them): a lower bound of the
    geodesic (triangle inequality, the edge path being >= the geodesic between the vertices up to the
    graph's own excess), so an exit beside the point is never put beyond MIN_SURFACE_MM by the graph."""

    def __init__(self, positions_mm, indices, normals, uvs, subdivisions: int = 2):
        pos = np.asarray(positions_mm, np.float64).reshape(-1, 3)
        idx = np.asarray(indices, np.int64).reshape(-1, 3)
        nrm = np.asarray(normals, np.float64).reshape(-1, 3)
        uv = np.asarray(uvs, np.float64).reshape(-1, 2)
        origin = np.arange(len(idx))  # the given triangle each (sub)triangle lies in
        for _ in range(subdivisions):
            pos, idx, nrm, uv = subdivide(pos, idx, nrm, uv)
            origin = np.tile(origin, 4)
        _, first, inv = np.unique(np.round(pos, 5), axis=0, return_index=True, return_inverse=True)
        inv = inv.reshape(-1)
        self.position = pos[first]
        self.normal = nrm[first] / np.maximum(np.linalg.norm(nrm[first], axis=1, keepdims=True), 1e-12)
        self.uv = uv[first]
        tri = inv[idx]
        n = len(self.position)
        area = 0.5 * np.linalg.norm(np.cross(self.position[tri[:, 1]] - self.position[tri[:, 0]],
                                             self.position[tri[:, 2]] - self.position[tri[:, 0]]), axis=1)
        self.area = np.bincount(tri.ravel(), weights=np.repeat(area / 3.0, 3), minlength=n)
        # per given triangle, the vertices of its subtriangles: a point on it is represented by the
        # nearest of them (never a vertex of another sheet that happens to be near in 3-D)
        order = np.argsort(origin, kind="stable")
        self.candidates = tri[order].reshape(len(np.unique(origin)), -1)
        self.graph = _lattice_graph(self.position, self.candidates)

    def nearest(self, points, triangles) -> np.ndarray:
        """For points on the given mesh's ``triangles``, the nearest vertex of that triangle's subdivision."""
        cand = self.candidates[np.asarray(triangles, np.int64)]
        d = np.linalg.norm(self.position[cand] - np.asarray(points, np.float64)[:, None], axis=2)
        return cand[np.arange(len(cand)), np.argmin(d, 1)]

    def distances(self, vertices, limit=MAX_SURFACE_MM) -> np.ndarray:
        """(n, V) edge-path distance (mm) from each of ``vertices`` to every vertex; inf beyond ``limit``."""
        from scipy.sparse.csgraph import dijkstra

        src, where = np.unique(np.asarray(vertices, np.int64), return_inverse=True)
        return dijkstra(self.graph, indices=src, limit=limit)[where.reshape(-1)]


def _lattice_graph(position, lattice):
    """The graph joining every pair of vertices of each given triangle's subdivision lattice (rows of
    ``lattice``) by their straight distance: within a flat triangle that IS the geodesic (a graph of
    the subtriangles' edges alone zig-zags: on the scan's slivers its paths were up to 3x the straight
    line); across triangles a path bends only where it crosses a shared edge at a lattice vertex."""
    from scipy.sparse import csr_matrix

    rows = np.sort(lattice, axis=1)
    fresh = np.c_[np.ones((len(rows), 1), bool), np.diff(rows, axis=1) != 0]
    width = int(fresh.sum(1).max())
    # each row's distinct vertices, padded with its first (self pairs are dropped below)
    u = np.repeat(rows[:, :1], width, axis=1)
    r, c = np.nonzero(fresh)
    u[r, np.cumsum(fresh, axis=1)[r, c] - 1] = rows[r, c]
    i, j = np.triu_indices(width, 1)
    e = np.sort(np.stack([u[:, i].ravel(), u[:, j].ravel()], 1), axis=1)
    e = np.unique(e[e[:, 0] != e[:, 1]], axis=0)
    length = np.linalg.norm(position[e[:, 0]] - position[e[:, 1]], axis=1)
    n = len(position)
    return csr_matrix((np.r_[length, length], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n))


def thin_points(mesh, mm_per_unit: float, grid: int = DEFAULT_GRID, thin_mm: float = THIN_MM,
                require_exit: bool = True) -> BakePoints:
    """Texel centres of the texture-space layout at grid^2 where the tissue behind is thinner than
    ``thin_mm`` along -N (dermis.geometry.thickness's bake)."""
    from dermis.geometry.thickness import texel_thickness

    S = int(grid)
    uv_ts = np.asarray(texture_space_uvs(mesh), np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    pos = np.asarray(mesh.positions, np.float64) * float(mm_per_unit)
    nrm = np.asarray(mesh.normals, np.float64)
    tri, bary = rasterize_uv(uv_ts, idx, S, S)  # row 0 = top (v = 1), as texel_thickness
    th = texel_thickness(mesh, S, mm_per_unit)
    ok = (th.reshape(-1, 4)[:, 3] > 0) & (th.reshape(-1, 4)[:, 2] < thin_mm) if require_exit else True
    sel = np.nonzero((tri.reshape(-1) >= 0) & ok)[0]
    t = tri.reshape(-1)[sel]
    b = bary.reshape(-1, 3)[sel].astype(np.float64)
    p = np.einsum("nk,nkc->nc", b, pos[idx[t]])
    vn = np.einsum("nk,nkc->nc", b, nrm[idx[t]])
    fn = np.cross(pos[idx[t, 1]] - pos[idx[t, 0]], pos[idx[t, 2]] - pos[idx[t, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    fn *= np.where(np.einsum("ij,ij->i", fn, vn) >= 0.0, 1.0, -1.0)[:, None]
    row, col = np.divmod(sel, S)
    uv = np.stack([(col + 0.5) / S, 1.0 - (row + 0.5) / S], 1)
    return BakePoints(uv, p, t, fn)


def bake_points(mesh, mm_per_unit: float, grid: int = DEFAULT_GRID, thin_mm: float = THIN_MM,
                near_mm: float = NEAR_MM) -> BakePoints:
    """The texel centres of :func:`thin_points` and every covered texel within ``near_mm`` (3-D) of
    one: the thin parts and the tissue around them (an ear's concha and antihelix, where -N runs into
    the head but the sheet beside them guides light)."""
    from scipy.spatial import cKDTree

    thin = thin_points(mesh, mm_per_unit, grid, thin_mm)
    every = thin_points(mesh, mm_per_unit, grid, np.inf, require_exit=False)
    if len(thin.position) == 0:
        return thin
    d, _ = cKDTree(thin.position).query(every.position, distance_upper_bound=near_mm)
    m = np.isfinite(d)
    texel = lambda uv: np.floor(uv[:, 0] * grid).astype(np.int64) + grid * np.floor((1.0 - uv[:, 1]) * grid).astype(np.int64)
    return BakePoints(every.uv[m], every.position[m], every.triangle[m], every.normal[m],
                      np.isin(texel(every.uv[m]), texel(thin.uv)))


def _compress(pos, c, taps):
    """(members' tap index, tap positions index) of a point's per-vertex transfer ``c`` (m, 3) at
    positions ``pos`` (m, 3): weighted k-means, deterministic (farthest-point start)."""
    m = len(pos)
    if m <= taps:
        return np.arange(m), np.arange(m)
    w = np.abs(c).sum(1) + 1e-30
    centres = [int(np.argmax(w))]
    d2 = np.sum((pos - pos[centres[0]]) ** 2, 1)
    for _ in range(taps - 1):
        j = int(np.argmax(d2 * w))
        centres.append(j)
        d2 = np.minimum(d2, np.sum((pos - pos[j]) ** 2, 1))
    cen = pos[centres]
    for _ in range(6):
        lab = np.argmin(((pos[:, None] - cen[None]) ** 2).sum(2), 1)
        for k in range(taps):
            s = lab == k
            if s.any():
                cen[k] = (pos[s] * w[s, None]).sum(0) / w[s].sum()
    lab = np.argmin(((pos[:, None] - cen[None]) ** 2).sum(2), 1)
    rep = np.zeros(taps, np.int64)
    for k in range(taps):
        s = np.nonzero(lab == k)[0]
        if len(s):
            rep[k] = s[np.argmin(((pos[s] - cen[k]) ** 2).sum(1))]
    return lab, rep


SMOOTH_OWN_MM = 1.0  # the shipped denoise: each point's own tap averaged over this (round 10's, again in round 12)
SMOOTH_VIEW_MM = 2.5  # and each point's view term over this (round 22, :func:`smooth_view`)
# round 11's denoise_round11 (a bake without the control variate):
SMOOTH_MM = 2.0  # the neighbourhood averaged at thin points (all taps, :func:`smooth_taps`) and strong band ones (own tap)
SMOOTH_WEAK_MM = 4.0  # and at the band's other points (own tap: thick skin beside the thin parts, a small, smooth transfer)
POOL_MM = 3.0  # the neighbourhood whose pooled walks decide whether a point's transfer is significant
SIGNIFICANCE_Z = 2.0  # kept in full only well beyond this many standard errors (the 2-sigma level, 95.4 %)


RECIPE_VERSION = 4  # bump with any change to how the walks, tallies or denoising shape a bake's taps (3: round 12's CRN;
# 4: round 22's first-order view term, tap_view)
FLAT_KERNEL_WALKS, FLAT_KERNEL_SEED = 40_000, 7


def recipe() -> dict:
    """What shapes a bake beyond its mesh, scale, medium and options (walks, grid, taps, seed: in the
    meta as they were given): the estimator and the denoising's constants, with RECIPE_VERSION for the
    code's logic. store.find treats a bake made by another recipe as stale (a change to the recipe must
    never silently reuse an older bake)."""
    return {"version": RECIPE_VERSION, "estimator": "crn", "view": "first order, least squares on the walks' views", "min_surface_mm": MIN_SURFACE_MM, "max_surface_mm": MAX_SURFACE_MM,
            "graph_subdivisions": 2, "flat_kernel": [FLAT_KERNEL_WALKS, FLAT_KERNEL_SEED, FLAT_EDGES_MM.tolist()],
            "denoise": "own tap over smooth_own_mm", "smooth_own_mm": SMOOTH_OWN_MM, "smooth_mm": SMOOTH_MM,
            "smooth_weak_mm": SMOOTH_WEAK_MM, "pool_mm": POOL_MM, "significance_z": SIGNIFICANCE_Z,
            "smooth_view_mm": SMOOTH_VIEW_MM}


def recipe_key() -> str:
    """A short hash of :func:`recipe` (what a bake's meta stores as "recipe")."""
    import hashlib
    import json

    return hashlib.sha256(json.dumps(recipe(), sort_keys=True).encode()).hexdigest()[:16]


def _neighbourhoods(points: BakePoints, radius_mm) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) index pairs, each point i with itself and every point j within ``radius_mm`` (3-D; a
    number, or per point i (n,)) whose normal is within 60 degrees of its own (a fold's other sheet
    is not a neighbour)."""
    from scipy.spatial import cKDTree

    n = len(points.position)
    r = np.broadcast_to(np.asarray(radius_mm, np.float64), (n,))
    pairs = cKDTree(points.position).query_pairs(float(r.max()), output_type="ndarray")
    if len(pairs):
        pairs = pairs[np.einsum("ij,ij->i", points.normal[pairs[:, 0]], points.normal[pairs[:, 1]]) > 0.5]
    else:
        pairs = np.zeros((0, 2), np.int64)
    i, j = np.r_[pairs[:, 0], pairs[:, 1]], np.r_[pairs[:, 1], pairs[:, 0]]
    keep = np.linalg.norm(points.position[i] - points.position[j], axis=1) < r[i]
    return np.r_[np.arange(n), i[keep]], np.r_[np.arange(n), j[keep]]


def smooth_own_taps(bake: TransferBake, points: BakePoints, radius_mm=SMOOTH_OWN_MM) -> TransferBake:
    """Each point's own tap (the near-field excess, a sum over ~60% of its walks: a few % Monte Carlo
    noise per point, which a 1 mm bake grid would show as speckle) replaced by its mean over the
    same-facing points within ``radius_mm`` (3-D). The quantity varies with the sheet's thickness
    and curvature over millimetres; the averaging keeps its mean over any region wider than the
    radius (a box filter), and the far taps are left as they are. ``radius_mm``: a number or per point.
    Returns a new TransferBake. Round 10's shipped smoothing at 1 mm everywhere (benchmarks/transfer_noise.py's
    "before"); :func:`denoise` runs it on the band's points."""
    import dataclasses

    own = bake.tap_weight[:, 0].astype(np.float64)
    i, j = _neighbourhoods(points, radius_mm)
    sums = np.zeros_like(own)
    np.add.at(sums, i, own[j])
    count = np.bincount(i, minlength=len(own))[:, None]
    w = bake.tap_weight.copy()
    w[:, 0] = sums / count
    view = bake.tap_view
    if view is not None:  # the own tap's first-order term alike (its G in the mesh's frame, c with the point's normal)
        vs = np.zeros(view.shape[:1] + view.shape[2:])
        np.add.at(vs, i, view[j, 0].astype(np.float64))
        view = view.copy()
        view[:, 0] = vs / count[:, :, None]
    return dataclasses.replace(bake, tap_weight=w, tap_view=view, meta=dict(
        bake.meta, smooth_own_mm=sorted(set(np.ravel(radius_mm).astype(float).tolist()))))


def smooth_taps(bake: TransferBake, points: BakePoints, radius_mm=SMOOTH_MM, only=None) -> TransferBake:
    """Each point's transfer replaced by the mean of its neighbourhood's (:func:`_neighbourhoods`,
    ``radius_mm``: a number or per point): the own taps averaged at the point (as :func:`smooth_own_taps`), the far taps of
    all the neighbours, each / N, compressed again to ``taps - 1`` by the bake's weighted k-means on
    their positions (:attr:`TransferBake.tap_position`; each cluster's sum kept, so the point's total
    is the neighbourhood's mean total exactly). Why: 192 walks leave a +-5 % estimate per point
    (the net of two ~1 totals) while the transfer itself varies over millimetres (the sheet's
    thickness, its curvature); the mean of N ~ 10-15 neighbours' independent walks has 1 / sqrt(N)
    of the noise, and a neighbour's far taps stand for light entering 1-15 mm away, where a shift of
    <= ``radius_mm`` is a fraction of the distance. A fold's other sheet is never a neighbour (the
    normals' test), so an ear's helix keeps its own transfer. ``only`` (n,) bool: smooth these points
    (their neighbours may be any), leave the others' taps as they are. Returns a new TransferBake."""
    import dataclasses

    if bake.tap_position is None:
        raise DermisError("subsurface transfer: smooth_taps needs the taps' positions (a bake from bake_transfer)")
    n, taps = bake.tap_weight.shape[:2]
    i, j = _neighbourhoods(points, radius_mm)
    order = np.argsort(i, kind="stable")
    i, j = i[order], j[order]
    start = np.searchsorted(i, np.arange(n + 1))
    w = bake.tap_weight.copy()
    uv = bake.tap_uv.copy()
    pos = bake.tap_position.copy()
    for p in range(n) if only is None else np.flatnonzero(only):
        js = j[start[p]:start[p + 1]]
        w[p, 0] = bake.tap_weight[js, 0].mean(0)
        fw = bake.tap_weight[js, 1:].reshape(-1, 3).astype(np.float64) / len(js)
        nz = np.nonzero(np.abs(fw).sum(1) > 0)[0]
        if len(nz) == 0:
            continue
        fp = bake.tap_position[js, 1:].reshape(-1, 3)[nz].astype(np.float64)
        fu = bake.tap_uv[js, 1:].reshape(-1, 2)[nz]
        lab, rep = _compress(fp, fw[nz], taps - 1)
        uv[p, 1:], pos[p, 1:], w[p, 1:] = 0.0, 0.0, 0.0
        for k in range(min(taps - 1, len(nz))):
            s_ = lab == k
            if s_.any():
                w[p, k + 1] = fw[nz][s_].sum(0)
                uv[p, k + 1] = fu[rep[k]]
                pos[p, k + 1] = fp[rep[k]]
    return dataclasses.replace(bake, tap_weight=w, tap_uv=uv, tap_position=pos,
                               meta=dict(bake.meta, smooth_mm=sorted(set(np.ravel(radius_mm).astype(float).tolist()))))


def significance(bake: TransferBake, points: BakePoints, pool_mm: float = POOL_MM) -> np.ndarray:
    """Per point, T = sum over the channels of d^T C^-1 d: d the 2-vector of :attr:`TransferBake.excess`
    (within / beyond MIN_SURFACE_MM) pooled over the point's neighbourhood (:func:`_neighbourhoods`,
    ``pool_mm``; the mean of the neighbours' estimates), C its covariance (the neighbours' walks are
    independent: the sum of their ``excess_cov`` / N^2). Where the transfer's expectation is 0 (thick
    skin: the walk's transport IS the flat kernel) T is chi-square with 6 degrees of freedom (mean 6);
    a real thin-sheet transfer makes it grow with the pooled walks."""
    if bake.excess is None or bake.excess_cov is None:
        raise DermisError("subsurface transfer: this bake has no per-point variance (excess_cov): bake it again")
    i, j = _neighbourhoods(points, pool_mm)
    n = len(bake.point_uv)
    count = np.bincount(i, minlength=n).astype(np.float64)
    d = np.zeros((n, 3, 2))
    np.add.at(d, i, bake.excess[j].astype(np.float64))
    d /= count[:, None, None]
    cov = np.zeros((n, 3, 3))
    np.add.at(cov, i, bake.excess_cov[j].astype(np.float64))
    cov /= (count ** 2)[:, None, None]
    a, b, c = np.maximum(cov[..., 0], 1e-12), np.maximum(cov[..., 1], 1e-12), cov[..., 2]
    det = np.maximum(a * b - c * c, 1e-6 * a * b)  # the 2 x 2 inverse; never singular
    return ((b * d[..., 0] ** 2 - 2.0 * c * d[..., 0] * d[..., 1] + a * d[..., 1] ** 2) / det).sum(1)


def shrink_factor(T, z: float = SIGNIFICANCE_Z, dof: int = 6) -> np.ndarray:
    """The firm shrinkage (Gao & Bruce 1997, "WaveShrink with firm shrinkage", eq. 2.3) of the pooled
    estimate's norm sqrt(T) as a factor on the point's taps: 0 below lambda_1 = sqrt(k), k the
    chi-square quantile (``dof`` degrees of freedom) at the probability of |N(0,1)| < z (the "within z
    standard errors of 0" test in ``dof`` dimensions: ~95 % of thick-skin points at z = 2 are dropped),
    1 (kept whole, unbiased) beyond lambda_2 = 2 lambda_1, continuous between:
    s = lambda_2 (sqrt(T) - lambda_1) / ((lambda_2 - lambda_1) sqrt(T)). Unlike positive-part
    James-Stein's 1 - k / T, a transfer 4 k away (the ear's: T in the hundreds) loses nothing."""
    from scipy.special import erf
    from scipy.stats import chi2

    lam1 = float(np.sqrt(chi2.ppf(erf(z / np.sqrt(2.0)), dof)))
    r = np.sqrt(np.maximum(np.asarray(T, np.float64), 1e-300))
    return np.clip(2.0 * (r - lam1) / r, 0.0, 1.0)


def shrink_insignificant(bake: TransferBake, points: BakePoints, pool_mm: float = POOL_MM,
                         z: float = SIGNIFICANCE_Z) -> TransferBake:
    """The taps of every point of the band (``points.thin`` False; every point where it is None)
    scaled by :func:`shrink_factor` of its :func:`significance`; a thin point's are kept. Why: the net
    transfer is the difference of two ~1 totals (the walk's same-facing transport and the flat
    kernel's share), so on thick skin, where its expectation is ~0, 192 walks leave a +-5 % Monte
    Carlo estimate per point, which tsd's image showed as a mottle beside every thin part
    (benchmarks/RESULTS.md, round 10 merged). The decision pools the neighbours' walks (their
    estimates of a quantity that varies over millimetres); a thin part's transfer is real (the ear:
    tested on all points, the shrinkage took 3 % of the back-lit ear's gain, its weakly significant
    points summing to a real share). Returns a new TransferBake."""
    import dataclasses

    s = shrink_factor(significance(bake, points, pool_mm), z)
    if points.thin is not None:
        s = np.where(np.asarray(points.thin, bool), 1.0, s)
    return dataclasses.replace(bake, tap_weight=(bake.tap_weight * s[:, None, None]).astype(bake.tap_weight.dtype),
                               meta=dict(bake.meta, shrink_pool_mm=float(pool_mm), shrink_z=float(z),
                                         shrunk_to_zero=float(np.mean(s == 0.0)), kept_whole=float(np.mean(s > 0.9))))


def smooth_view(bake: TransferBake, points: BakePoints, radius_mm: float = SMOOTH_VIEW_MM,
                tap_position: np.ndarray | None = None, relative: bool = False) -> TransferBake:
    """Each point's view term (:attr:`TransferBake.tap_view`) replaced by the mean of its neighbourhood's
    (:func:`_neighbourhoods`, ``radius_mm``), carried on the point's OWN taps: every neighbour's tap (its
    view coefficients / N) goes to the nearest (3-D) of the point's taps that hold weight (tap 0, the
    point itself, and its used far taps), so the taps' uv and the mean (``tap_weight``) are unchanged
    and the gather needs nothing new. Why: the view term is a slope fitted to the walks' spread of
    directions, and at 192 walks it is noise-dominated per point (RESULTS.md round 22 view22: summed over
    the scapha's 17 bake points, red under the back light, the view term at the camera 0.25 / 0.40 / 0.20
    for three seeds where the cosine mean is 0.23 / 0.23 / 0.26 and 2048 walks give 0.21 / 0.21), while
    the view dependence varies over millimetres. ``tap_position`` (n, taps, 3) mm: the taps' surface
    points (default :attr:`TransferBake.tap_position`). ``relative``: each neighbour j's taps matched to the
    point's by their offset from j (q - x_j + x_p), so own goes to own: round 22 denoise22's candidate for the
    shipped matching by absolute position, which keeps only ~20 % of the own taps' weight on the own tap
    (benchmarks/denoise_mechanism.py --relative; not the shipped recipe). Returns a new TransferBake."""
    import dataclasses

    if bake.tap_view is None:
        return bake
    tp = bake.tap_position if tap_position is None else tap_position
    if tp is None:
        raise DermisError("subsurface transfer: smooth_view needs the taps' positions")
    tp = np.asarray(tp, np.float64)
    n, taps = bake.tap_weight.shape[:2]
    i, j = _neighbourhoods(points, radius_mm)
    order = np.argsort(i, kind="stable")
    i, j = i[order], j[order]
    start = np.searchsorted(i, np.arange(n + 1))
    used = np.abs(bake.tap_weight).sum(2) > 0.0
    used[:, 0] = True
    src = bake.tap_view.astype(np.float64)
    out = np.zeros_like(src)
    for p in range(n):
        js = j[start[p]:start[p + 1]]
        mine = np.flatnonzero(used[p])
        cand = (tp[js] - points.position[js][:, None] + points.position[p] if relative else tp[js]).reshape(-1, 3)
        val = src[js].reshape(-1, 3, 4) / len(js)
        nz = np.abs(val).sum((1, 2)) > 0.0
        if not nz.any():
            continue
        d2 = ((cand[nz, None] - tp[p, mine][None]) ** 2).sum(2)
        to = mine[np.argmin(d2, 1)]
        np.add.at(out[p], to, val[nz])
    return dataclasses.replace(bake, tap_view=out.astype(np.float32), meta=dict(bake.meta, smooth_view_mm=float(radius_mm)))


def denoise(bake: TransferBake, points: BakePoints, radius_mm: float = SMOOTH_OWN_MM) -> TransferBake:
    """The bake as shipped (:func:`dermis.subsurface_transfer.store.bake_scene`, round 12): every point's
    own tap averaged over ``radius_mm`` (:func:`smooth_own_taps`: the near-field excess, a sum over ~60 %
    of the walks, at a 1 mm bake grid), its far taps as walked, nothing shrunk: round 10's treatment.
    Why no more: with the control variate (``bake_transfer(crn=True)``) the walks' own noise is 3-20x
    lower on thick skin, so the mottle is within round 11's limits without round 11's averaging of
    thin points over 2 mm and shrinkage of the band, which cost the eyelids and the nose's penumbra
    against Cycles (benchmarks/RESULTS.md round 12 cv12: front-key's seed-difference high-pass of the
    luminance ratio 0.31 % over all the lit skin the bake changes, 0.21 % beside the thin parts; round
    11's denoise_round11 on its plain walks 0.39 % / 0.28 %). A bake made without the control variate
    needs :func:`denoise_round11`. Then (round 22) the view term averaged over SMOOTH_VIEW_MM (:func:`smooth_view`)."""
    own = smooth_own_taps(bake, points, radius_mm)
    if own.tap_view is None or (own.tap_position is None):
        return own
    tp = own.tap_position.astype(np.float64).copy()
    tp[:, 0] = points.position
    return smooth_view(own, points, SMOOTH_VIEW_MM, tp)


def denoise_round11(bake: TransferBake, points: BakePoints, pool_mm: float = POOL_MM, z: float = SIGNIFICANCE_Z,
                    radius_mm: float = SMOOTH_MM, weak_radius_mm: float = SMOOTH_WEAK_MM) -> TransferBake:
    """Round 11's denoising of a bake without the control variate (``crn=False``; shipped in round 11,
    kept to reproduce it and for such bakes): at a thin point
    :func:`smooth_taps` over ``radius_mm`` (all its taps); at a band point (``points.thin`` False; every
    point where it is None) only its own tap averaged (:func:`smooth_own_taps`), over ``radius_mm``
    where the pooled transfer is kept whole (:func:`shrink_factor` 1: many standard errors from 0),
    ``weak_radius_mm`` elsewhere (thick skin beside the thin parts), its far taps left as walked; then
    :func:`shrink_insignificant`. Why the band's far taps are not pooled: the recompression of the
    neighbours' far taps (k-means, each cluster's sum at one representative tap) moves light entry
    on the ear's folds and beside shadows, where the irradiance varies within a cluster, and so
    biased the back-lit ear against Cycles (benchmarks/RESULTS.md, round 11 mottle11b: validate's
    back-ears back_lit_ear FLIP 0.1255 round 10, 0.1268 with the band's far taps pooled at 2 / 4 mm,
    0.1257 with them as walked; front-key's seed-difference high-pass of the mottle 0.83% round 10,
    0.35% pooled, 0.39% this). Measured before on the head (round 11 mottle11; back_lit_ear red, the
    share of round 10's gain kept): all taps 2 mm everywhere 0.991, 4 mm everywhere 0.968."""
    thin = np.zeros(len(points.position), bool) if points.thin is None else np.asarray(points.thin, bool)
    fine = (shrink_factor(significance(bake, points, pool_mm), z) >= 1.0) | thin
    import dataclasses

    own = smooth_own_taps(bake, points, np.where(thin, 0.0, np.where(fine, radius_mm, weak_radius_mm)))
    sm = smooth_taps(bake, points, radius_mm, only=thin)  # both from the walks' taps: neither sees the other's
    w = sm.tap_weight.copy()
    w[~thin, 0] = own.tap_weight[~thin, 0]
    return shrink_insignificant(dataclasses.replace(sm, tap_weight=w, meta=dict(sm.meta, smooth_own_mm=own.meta["smooth_own_mm"])),
                                points, pool_mm, z)


def bake_transfer(mesh, mm_per_unit: float, profile, albedo, *, grid: int = DEFAULT_GRID, walks: int = DEFAULT_WALKS,
                  taps: int = DEFAULT_TAPS, thin_mm: float = THIN_MM, near_mm: float = NEAR_MM, seed: int = 0,
                  points: BakePoints | None = None, media=None, kernels=None, progress=None, crn: bool = True,
                  views=None) -> TransferBake:
    """The transfer of the module docstring for ``mesh`` (a dermis Mesh or any object with positions,
    normals, indices, uvs, texture_space_uvs; positions x ``mm_per_unit`` = mm). ``points``: bake
    there instead of :func:`bake_points`; ``media`` / ``kernels``: per channel WalkMedium and
    FlatKernel (default: :func:`skin_media`, :func:`flat_kernel`). ``crn``: the flat share's
    estimate is each walk's flat twin (the module docstring's "The control variate"); False: the deterministic share alone (round 11's estimator and walks).
    ``views`` (n, 3): walk every point along its one view (towards the surface; :func:`walk_exits`) instead of
    cosine views: the taps' weights are then the transfer seen along that view (the view term is 0: no spread)."""
    if walks < 1 or taps < 2:
        raise DermisError("subsurface transfer: walks must be >= 1 and taps >= 2")
    mm = float(mm_per_unit)
    pos = np.asarray(mesh.positions, np.float64) * mm
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    uv_ts = texture_space_uvs(mesh)
    pts = points if points is not None else bake_points(mesh, mm, grid, thin_mm, near_mm)
    media = media if media is not None else skin_media(profile, albedo)
    kernels = kernels if kernels is not None else [flat_kernel(m) for m in media]
    walker = MeshWalk(pos, idx)
    graph = SurfaceGraph(pos, idx, mesh.normals, uv_ts)
    start_vertex = graph.nearest(pts.position, pts.triangle)
    n = len(pts.position)
    exits = [walk_exits(walker, pts.position, pts.triangle, pts.normal, m, walks, seed * 3 + c, twin=crn, views=views)
             for c, m in enumerate(media)]
    if progress:
        progress(f"walks done: {n} points x {walks} walks x 3 channels" + (" (and their flat twins)" if crn else ""))
    tap_uv = np.zeros((n, taps, 2), np.float32)
    tap_w = np.zeros((n, taps, 3), np.float32)
    tap_view = np.zeros((n, taps, 3, 4), np.float32)  # per tap and channel the view term (G_x, G_y, G_z, c): view_basis
    tap_pos = np.zeros((n, taps, 3), np.float32)
    tap_uv[:, 0] = pts.uv
    tap_pos[:, 0] = pts.position
    kept = np.zeros((n, 3))
    sub = np.zeros((n, 3))
    moments = np.zeros((n, 3, 5))  # per channel: mean within, mean beyond, their covariance (3) of the means
    moments[..., 2:4] = np.inf  # a channel without exits at a point says nothing
    near_flat = np.array([k.within(MIN_SURFACE_MM) for k in kernels])
    heads = [_by_point(e["point_index"], n) for e in exits]
    twins = [_by_point(e["twin"]["point_index"], n) if crn and "twin" in e else None for e in exits]
    chunk = 64
    for c0 in range(0, n, chunk):
        c1 = min(c0 + chunk, n)
        G = graph.distances(start_vertex[c0:c1])  # (m, V)
        for i in range(c0, c1):
            g_row = G[i - c0]
            xo, no = pts.position[i], pts.normal[i]
            off_o = float(np.linalg.norm(graph.position[start_vertex[i]] - xo))
            # what the flat medium carries from the same-facing surface beyond MIN_SURFACE_MM: K_flat(g_v) A_v
            fin = np.nonzero(np.isfinite(g_row))[0]
            rv = np.linalg.norm(graph.position[fin] - xo, axis=1)
            gv = np.maximum(g_row[fin] - off_o, rv)
            kv = (graph.normal[fin] @ no > 0.0) & (gv > MIN_SURFACE_MM)
            share = np.stack([k.at(gv[kv]) for k in kernels], 1) * graph.area[fin[kv], None]
            far_flat = share.sum(0)  # S_b per channel
            scale = np.ones(3)  # the far share's factor: 1, or the twins' far transport / its expectation
            ids, vals, slopes = [], [], []
            gscale = np.zeros((3, 4))  # per channel the view terms of the twins' far transport / its expectation
            for c, (e, (o, s)) in enumerate(zip(exits, heads)):
                H = view_basis(e["walk_view"][i * walks:(i + 1) * walks], no, media[c].index)  # (walks, 4): terms = H^T f
                sel = o[s[i]:s[i + 1]]
                xe, ne, we = e["point"][sel], e["normal"][sel], e["weight"][sel]
                same = ne @ no > 0.0
                xe, we, ve = xe[same], we[same] / (walks * kernels[c].reflectance), graph.nearest(xe[same], e["triangle"][sel][same])
                r = np.linalg.norm(xe - xo, axis=1)
                ge = np.maximum(g_row[ve] - off_o - np.linalg.norm(graph.position[ve] - xe, axis=1), r)
                kept[i, c] = we.sum()
                far = ge > MIN_SURFACE_MM
                a, b = _per_walk(e["sample"][sel][same], we * walks, far, walks)  # per walk, / R_flat
                if twins[c] is None:  # the deterministic share
                    a, b = a - near_flat[c], b - far_flat[c]
                else:  # each walk less its flat twin's tally (common random numbers; module docstring)
                    to, ts = twins[c]
                    tsel = to[ts[i]:ts[i + 1]]
                    tw = e["twin"]
                    fa, fb = _per_walk(tw["sample"][tsel], tw["weight"][tsel] / kernels[c].reflectance,
                                       tw["radius"][tsel] > MIN_SURFACE_MM, walks)
                    scale[c] = fb.mean() / max(1.0 - near_flat[c], 1e-12)
                    gscale[c] = H.T @ fb / max(1.0 - near_flat[c], 1e-12)
                    a, b = a - fa, b - far_flat[c] / max(1.0 - near_flat[c], 1e-12) * fb
                moments[i, c] = _walk_moments(a, b) if len(sel) else [a.mean(), b.mean(), np.inf, np.inf, 0.0]
                tap_w[i, 0, c] = a.mean()
                tap_view[i, 0, c] = H.T @ a
                sub[i, c] = kept[i, c] - a.mean() - b.mean()
                v3 = np.zeros((int(far.sum()), 3))
                v3[:, c] = we[far]
                s3 = np.zeros((int(far.sum()), 3, 4))
                s3[:, c] = (we[far] * walks)[:, None] * H[e["sample"][sel][same][far]]  # each exit x its walk's regressor
                ids.append(ve[far])
                vals.append(v3)
                slopes.append(s3)
            slope_share = share[:, :, None] * gscale[None]  # the flat share's first-order term, carried as its scale
            share = share * scale
            big = np.abs(share).max(1) > 1e-7
            ids.append(fin[kv][big])
            vals.append(-share[big])
            slopes.append(-slope_share[big])
            all_ids = np.concatenate(ids)
            if len(all_ids) == 0:
                continue
            keys, inv = np.unique(all_ids, return_inverse=True)
            cv = np.zeros((len(keys), 3))
            np.add.at(cv, inv, np.concatenate(vals))
            sv = np.zeros((len(keys), 3, 4))
            np.add.at(sv, inv, np.concatenate(slopes))
            lab, rep = _compress(graph.position[keys], cv, taps - 1)  # the taps of the mean (the slope rides along)
            for k in range(min(taps - 1, len(keys))):
                s_ = lab == k
                if s_.any():
                    tap_w[i, k + 1] = cv[s_].sum(0)
                    tap_view[i, k + 1] = sv[s_].sum(0)
                    tap_uv[i, k + 1] = graph.uv[keys[rep[k]]]
                    tap_pos[i, k + 1] = graph.position[keys[rep[k]]]
        if progress and (c1 // chunk) % 16 == 0:
            progress(f"points {c1} / {n}")
    meta = {"grid": int(grid), "walks": int(walks), "taps": int(taps), "thin_mm": float(thin_mm), "near_mm": float(near_mm),
            "seed": int(seed), "min_surface_mm": MIN_SURFACE_MM, "max_surface_mm": MAX_SURFACE_MM, "crn": bool(crn),
            "mean_free_path_mm": [m.mean_free_path_mm for m in media],
            "single_scattering_albedo": [m.single_scattering_albedo for m in media], "index": media[0].index,
            "flat_reflectance": [k.reflectance for k in kernels], "flat_within_min_surface": near_flat.tolist(),
            "profile": getattr(profile, "name", ""), "albedo": list(map(float, np.asarray(albedo, np.float64)))}
    return TransferBake(pts.uv.astype(np.float32), tap_uv, tap_w, kept, sub, meta, moments[..., :2], moments[..., 2:], tap_pos,
                        tap_view)


def view_basis(views, normal, index: float) -> np.ndarray:
    """The view term's estimator for one point's walks: Q (walks, 4) such that (G_x, G_y, G_z, c) = Q^T f
    for the walks' tallies f (walks,) started along ``views`` (walks, 3; towards the surface) at a point
    of outward facet ``normal`` (3,), medium ``index``. The model (module docstring, "The view"): a walk
    along the view v enters with the Fresnel transmittance 1 - F(v) (all or none: a walk reflected at
    entry tallies 0, and so does its flat twin, which enters by the same plane on the same random
    numbers), and what it tallies once in is taken linear in its refracted direction r(v):

        T(v) = (1 - F(v)) (G . r(v) + c)

    fitted by least squares with an intercept to f_s / (1 - F_s) on r_s (the walks' own F and r): G the
    slope, c = the intercept at the walks' mean r less G . mean r. Zero where the directions do not span
    3-D (fewer than 5 walks, or one view for all: a fresh walk along a view has no view term)."""
    from dermis.reference.random_walk import fresnel_unpolarised, refract

    v = np.asarray(views, np.float64)
    w = len(v)
    if w < 5:
        return np.zeros((w, 4))
    nrm = np.broadcast_to(np.asarray(normal, np.float64), v.shape)
    F, _ = fresnel_unpolarised(-np.einsum("ij,ij->i", v, nrm), 1.0, float(index))
    u = 1.0 / np.maximum(1.0 - F, 1e-3)
    r = refract(v, nrm, 1.0 / float(index))
    D = r - r.mean(0)
    S = D.T @ D
    if np.linalg.cond(S) > 1e8:
        return np.zeros((w, 4))
    H = np.linalg.solve(S, D.T).T * u[:, None]  # slope weights
    q = np.empty((w, 4))
    q[:, :3] = H
    q[:, 3] = u / w - H @ r.mean(0)
    return q


def view_term(tap_view, views, normal, index: float) -> np.ndarray:
    """The taps' weights seen along ``views`` (n, 3; towards the surface) at points of outward
    ``normal`` (n, 3): (1 - F(v)) (G . r(v) + c) per tap and channel, (n, taps, 3) (the numpy twin of
    common/subsurface_transfer.glsl's view term)."""
    from dermis.reference.random_walk import fresnel_unpolarised, refract

    v = np.asarray(views, np.float64)
    nrm = np.asarray(normal, np.float64)
    F, _ = fresnel_unpolarised(-np.einsum("ij,ij->i", v, nrm), 1.0, float(index))
    r = refract(v, nrm, 1.0 / float(index))
    tv = np.asarray(tap_view, np.float64)
    return (1.0 - F)[:, None, None] * (np.einsum("ntcj,nj->ntc", tv[..., :3], r) + tv[..., 3])


@functools.lru_cache(maxsize=8)  # read per frame by dermis.gl.subsurface_transfer.bind_view
def view_mean_constants(index: float) -> tuple[float, float]:
    """(a0, a1): the means of 1 - F(v) and of (1 - F(v)) r(v) . N over the bake's cosine-distributed views
    (2 mu dmu, mu = -v . N), so the view term's own mean over those views is a0 c + a1 G . N per tap and channel
    (the mean of (1 - F) r is along N by the views' symmetry about it; r points into the medium: r . N = -cos_t).
    64-node Gauss-Legendre on mu in [0, 1] (the integrands are smooth: no total reflection entering from air)."""
    from dermis.reference.random_walk import fresnel_unpolarised

    x, wq = np.polynomial.legendre.leggauss(64)
    mu, wq = 0.5 * (x + 1.0), 0.5 * wq
    F, cos_t = fresnel_unpolarised(mu, 1.0, float(index))
    return float((wq * 2.0 * mu * (1.0 - F)).sum()), float(-(wq * 2.0 * mu * (1.0 - F) * cos_t).sum())


def view_deviation(tap_view, views, normal, index: float) -> np.ndarray:
    """What the view term adds to the cosine mean (the numpy twin of common/subsurface_transfer.glsl's
    subsurface_transfer_view): :func:`view_term` less its OWN mean over the bake's cosine views (a0 c + a1 G . N,
    :func:`view_mean_constants`), (n, taps, 3). Why not less ``tap_weight``: :func:`smooth_view` hands each
    neighbour's taps to the point's nearest taps (only ~20 % of the own tap's weight stays on it), so the view
    term's cosine mean drifts from ``tap_weight`` (which agrees with fresh cosine-view walks within 0.89-1.04); at
    back-ears' helix rim (384-404, 388-428) the view grids' cosine mean was 1.61x the cosine grid, so view22's
    form added that difference at EVERY view (rendered transfer 1.74x the cosine one where fresh walks give
    1.26x; benchmarks/RESULTS.md round 22 rim22, denoise22). Subtracting the model's own mean adds only the
    view's deviation."""
    tv = np.asarray(tap_view, np.float64)
    nrm = np.asarray(normal, np.float64)
    a0, a1 = view_mean_constants(index)
    mean = a0 * tv[..., 3] + a1 * np.einsum("ntcj,nj->ntc", tv[..., :3], nrm)
    return view_term(tap_view, views, normal, index) - mean


def _per_walk(sample, x, far, walks: int) -> tuple[np.ndarray, np.ndarray]:
    """(within, beyond) per walk of one point: ``x`` its exits' tallies, ``sample`` which walk each
    exit ended (a walk exits once or never: the others tally 0), ``far`` beyond MIN_SURFACE_MM."""
    far = np.asarray(far, bool)
    return (np.bincount(sample[~far], weights=x[~far], minlength=walks),
            np.bincount(sample[far], weights=x[far], minlength=walks))


def _by_point(point_index, n: int):
    """(order, starts): the exits of point i are order[starts[i]:starts[i + 1]] (a stable sort)."""
    order = np.argsort(point_index, kind="stable")
    return order, np.searchsorted(point_index[order], np.arange(n + 1))


def _walk_moments(a, b) -> np.ndarray:
    """(mean a, mean b, var, var, covariance of the two means) of per-walk tallies (ddof 1, / walks)."""
    walks = len(a)
    if walks < 2:
        return np.array([a.mean(), b.mean(), np.inf, np.inf, 0.0])
    cov = np.cov(np.stack([a, b])) / walks
    return np.array([a.mean(), b.mean(), cov[0, 0], cov[1, 1], cov[0, 1]])
