"""Volumetric random walk inside a closed triangle mesh: a ground truth of subsurface transport
in a real geometry (an ear), for directional lights and a uniform environment. Physics only: numpy
and Embree ray casting (dermis.geometry.raycast), no GL.

The radiance leaving a surface point x_o towards the camera is estimated by reciprocity (the
adjoint walk, Veach 1997 ch. 3-5; Pharr, Jakob & Humphreys, PBRT 3rd ed. ch. 15): a walk starts
at x_o along the camera ray continued into the medium, is traced through a homogeneous isotropic
medium (step lengths -ln(xi) mfp, implicit capture of the single-scattering albedo, as MCML), and
every boundary hit is a ray cast against the mesh. Two boundary models:

* ``"fresnel"``: skin, a smooth dielectric of ``index`` against air (MCML's rules: all-or-none
  Fresnel reflection by the unpolarised Fresnel reflectance, Snell refraction; dermis's skin
  walk). The camera's ray enters with weight (1 - F(theta_o)) / n^2 (radiance across an interface
  goes as (1 - F) n_t^2 / n_i^2; the n^2 of entering light cancels it for the environment, not for
  the light's collimated beam, whose irradiance is physical). A directional light reaches a
  scattering vertex y inside as a collimated beam refracted through the face it entered by:
  with flat facets (the mesh's geometric normals), facet T's beam fills the prism behind T along
  t_T = refract(-l, n_T), so y sees T's beam iff the ray from y along -t_T first hits T. That
  facet is found by iterating (straight to the light, then along the refracted direction of the
  facet hit, up to NEE_ITERATIONS times, accepting when the facet's plane repeats). Next-event
  estimate at each scattering vertex (collision estimator): alpha p E_in exp(-s / mfp) V with
  p = 1 / 4 pi, E_in = E (1 - F(theta_l)) cos theta_l / cos theta_t (the beam's irradiance inside,
  per unit area across it), V the entry point's shadow ray. Not included: a beam that is reflected
  internally before its first scattering (it has crossed the tissue unscattered first, exp(-d/mfp)),
  and a vertex lit through two facets at once (a caustic; one is found). The environment is scored
  when a walk refracts out (radiance C where the exit ray escapes).
* ``"lambertian"``: Cycles' random walk (Blender's intern/cycles/kernel/integrator/subsurface.h and
  subsurface_random_walk.h): index-matched, the walk enters along the camera ray refracted by a
  smooth interface of ``index`` (``entry="refracted"``) or a cosine-distributed direction
  (``entry="cosine"``), with weight 1, and ends at its first boundary hit, where a Lambertian closure
  on the interpolated vertex normal gathers the light: E max(0, N.L) V / pi per directional light and
  C V for the environment (one cosine-distributed ray).

Direct light; light reflected by other skin before entering (interreflection) only as one bounce that
the caller describes (``bounce``: what the surface a leaving ray meets sends back).
Lengths in mm (the mesh's positions must be in mm); radiance per unit of the lights' irradiance
(``irradiance`` = W m^-2 across the beam, as dermis's light intensity) and of the environment's
radiance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dermis.errors import DermisError
from dermis.geometry.raycast import RayCaster, cosine_directions

BOUNDARIES = ("fresnel", "lambertian")
ENTRIES = ("refracted", "cosine")
EPS_MM = 1e-3  # a ray leaving a surface starts this far along itself (Embree works in float32)
NEE_ITERATIONS = 4  # refracted-entry search: casts per scattering vertex and light, at most
SAME_PLANE_COS = 1.0 - 1e-6  # facets whose normals agree this well refract a beam alike
ROULETTE_WEIGHT = 1e-3  # MCML's Russian roulette: below this weight, survive with ROULETTE_SURVIVAL
ROULETTE_SURVIVAL = 0.1
MAX_STEPS = 100_000  # a walk that left a mesh that is not closed would scatter forever in air
PATH_FAR_MM = 3.0  # radiance(paths=True): light entering farther than this from the start is "far"


@dataclass(frozen=True)
class WalkMedium:
    """A homogeneous isotropic medium and its boundary model (see the module docstring)."""

    mean_free_path_mm: float  # 1 / sigma_t
    single_scattering_albedo: float  # sigma_s / sigma_t
    boundary: str = "fresnel"
    index: float = 1.4  # fresnel: the medium's index against air; lambertian: the entry's refraction
    entry: str = "refracted"  # lambertian only

    def __post_init__(self):
        if self.boundary not in BOUNDARIES:
            raise DermisError(f"random walk: boundary must be one of {', '.join(BOUNDARIES)}, got {self.boundary!r}")
        if self.entry not in ENTRIES:
            raise DermisError(f"random walk: entry must be one of {', '.join(ENTRIES)}, got {self.entry!r}")
        if not self.mean_free_path_mm > 0 or not 0.0 <= self.single_scattering_albedo <= 1.0 or not self.index >= 1.0:
            raise DermisError("random walk: the mean free path must be > 0 mm, the albedo in [0, 1], the index >= 1")


@dataclass(frozen=True)
class DirectionalLight:
    to_light: tuple  # unit vector towards the light
    irradiance: float  # across the beam (one channel)


def fresnel_unpolarised(cos_i, eta_i, eta_t):
    """(reflectance, cos of the refracted angle) per element; total internal reflection gives
    (1, 0). The same formula as MCML's RFresnel (dermis.profiles.monte_carlo._fresnel), vectorised."""
    cos_i = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0)
    sin_t = eta_i / eta_t * np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i))
    tir = sin_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t * sin_t))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t)
        rp = (eta_i * cos_t - eta_t * cos_i) / (eta_i * cos_t + eta_t * cos_i)
    r = np.where(tir | (cos_i < 1e-9), 1.0, 0.5 * (rs * rs + rp * rp))
    if eta_i == eta_t:
        r = np.zeros_like(cos_i)
    return r, np.where(tir, 0.0, cos_t)


def refract(d, n, eta_ratio):
    """Direction d (unit, towards the interface) refracted through the interface of unit normal n
    (n.d < 0: n on d's side), eta_ratio = n_from / n_to (no total internal reflection assumed)."""
    c = -np.einsum("ij,ij->i", d, n)
    k = 1.0 - eta_ratio ** 2 * (1.0 - c * c)
    t = eta_ratio * d + (eta_ratio * c - np.sqrt(np.maximum(k, 0.0)))[:, None] * n
    return t / np.linalg.norm(t, axis=1, keepdims=True)


_MIX1, _MIX2, _GOLDEN = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB), np.uint64(0x9E3779B97F4A7C15)
# what a walk's event draws from its stream (CounterUniforms' ``purpose``)
U_STEP, U_FRESNEL, U_PHI, U_Z, U_ROULETTE = range(5)


def _splitmix(x):
    """SplitMix64's finaliser (Steele, Lea & Flood 2014, "Fast splittable pseudorandom number
    generators"): a bijection of uint64 that scrambles every bit (products modulo 2^64)."""
    with np.errstate(over="ignore"):
        x = x ^ (x >> np.uint64(30))
        x = x * _MIX1
        x = x ^ (x >> np.uint64(27))
        x = x * _MIX2
        return x ^ (x >> np.uint64(31))


class CounterUniforms:
    """Uniforms in [0, 1) that are a function of (seed, walk, event, purpose) alone (a counter-based
    generator: SplitMix64's finaliser of the walk's key plus the event's counter): two walks given the
    same walk index draw the same numbers at the same event whatever else is walked beside them, and
    different walks or events independent ones. What common random numbers need (a walk in the mesh
    and its twin in the flat half-space, :func:`halfspace_exits`): the vectorised walk otherwise draws
    per alive set, so two geometries would never share a stream. 53-bit uniforms."""

    def __init__(self, seed: int):
        with np.errstate(over="ignore"):
            self.key = _splitmix(np.uint64(int(seed) & 0xFFFFFFFFFFFFFFFF) * _GOLDEN + _GOLDEN)

    def __call__(self, walks, event: int, purpose: int) -> np.ndarray:
        with np.errstate(over="ignore"):
            k = _splitmix(self.key + np.asarray(walks, np.uint64) * _GOLDEN)
            x = _splitmix(k + np.uint64((int(event) << 3) | int(purpose)))
        return (x >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def _sphere_from(u_z, u_phi):
    """Unit directions uniform on the sphere from two uniforms each (z uniform on [-1, 1], phi on
    [0, 2 pi): Archimedes' hat-box theorem)."""
    z = 2.0 * u_z - 1.0
    phi = 2.0 * np.pi * u_phi
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def halfspace_exits(origins, normals, view_dirs, medium: WalkMedium, uniforms: CounterUniforms, walk_ids=None) -> dict:
    """The fresnel walk of :meth:`MeshWalk.radiance` from ``origins`` (n, 3) along ``view_dirs``, in the
    semi-infinite half-space below the plane through each origin with outward normal ``normals``
    (n, 3): no ray casting (the boundary is the plane). Driven by ``uniforms`` at ``walk_ids`` (default
    0..n-1) with the mesh walk's event counter and purposes, so a mesh walk given the same uniforms and
    ids follows the same path for as long as the mesh is the plane there (common random numbers: its
    flat twin). Returns the exits: "walk", "point" (mm), "radius" (mm from the origin, in the plane),
    "weight" (w n^2)."""
    if medium.boundary != "fresnel":
        raise DermisError("random walk: the half-space twin is the fresnel walk's")
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    v = np.asarray(view_dirs, np.float64).reshape(-1, 3)
    n = len(o)
    ids = np.arange(n, dtype=np.uint64) if walk_ids is None else np.asarray(walk_ids, np.uint64)
    eta = medium.index
    sigma_t = 1.0 / medium.mean_free_path_mm
    alpha = medium.single_scattering_albedo
    cos_o = -np.einsum("ij,ij->i", v, nrm)
    F, _ = fresnel_unpolarised(cos_o, 1.0, eta)
    w = (1.0 - F) / eta ** 2
    d = refract(v, nrm, 1.0 / eta)
    p = o.copy()
    alive = np.arange(n)
    out = {"walk": [], "point": [], "weight": []}
    for it in range(MAX_STEPS):
        if len(alive) == 0:
            break
        s = -np.log(1.0 - uniforms(ids[alive], it, U_STEP)) / sigma_t
        pa, da, na = p[alive], d[alive], nrm[alive]
        dn = np.einsum("ij,ij->i", da, na)
        depth = np.einsum("ij,ij->i", o[alive] - pa, na)  # >= 0 inside
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(dn > 0.0, np.maximum(depth, 0.0) / dn, np.inf)
        hit = t < s
        hi = alive[hit]
        if len(hi):
            pb = pa[hit] + da[hit] * t[hit, None]
            F, _ = fresnel_unpolarised(dn[hit], eta, 1.0)
            refl = uniforms(ids[hi], it, U_FRESNEL) <= F
            r = hi[refl]
            d[r] = da[hit][refl] - 2.0 * dn[hit][refl, None] * na[hit][refl]
            p[r] = pb[refl]
            o_ = hi[~refl]
            if len(o_):
                out["walk"].append(o_)
                out["point"].append(pb[~refl])
                out["weight"].append(w[o_] * eta ** 2)
            w[o_] = 0.0
        sc = alive[~hit]
        if len(sc):
            p[sc] = pa[~hit] + da[~hit] * s[~hit, None]
            w[sc] *= alpha
            d[sc] = _sphere_from(uniforms(ids[sc], it, U_Z), uniforms(ids[sc], it, U_PHI))
            low = sc[w[sc] < ROULETTE_WEIGHT]
            if len(low):
                keep = uniforms(ids[low], it, U_ROULETTE) < ROULETTE_SURVIVAL
                w[low] = np.where(keep, w[low] / ROULETTE_SURVIVAL, 0.0)
        alive = alive[w[alive] > 0.0]
    ex = {k: (np.concatenate(val) if val else np.zeros((0, 3) if k == "point" else 0, np.int64 if k == "walk" else np.float64))
          for k, val in out.items()}
    ex["radius"] = np.linalg.norm(ex["point"] - o[ex["walk"]], axis=1)
    return ex


class MeshWalk:
    """A closed triangle mesh (positions in mm) to walk inside. ``vertex_normals``: the smooth
    normals the Lambertian closure shades with (default: the facets')."""

    def __init__(self, positions_mm, indices, vertex_normals=None):
        self.positions = np.asarray(positions_mm, np.float64).reshape(-1, 3)
        self.indices = np.asarray(indices, np.int64).reshape(-1, 3)
        self.caster = RayCaster(self.positions, self.indices)
        g = np.cross(self.caster.v1 - self.caster.v0, self.caster.v2 - self.caster.v0)
        self.facet_normals = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        self.vertex_normals = None if vertex_normals is None else np.asarray(vertex_normals, np.float64).reshape(-1, 3)

    def _outward(self, tri, d):
        """Facet normals of ``tri`` turned to the side that direction d (leaving the inside) goes."""
        n = self.facet_normals[tri]
        return n * np.where(np.einsum("ij,ij->i", n, d) >= 0.0, 1.0, -1.0)[:, None]

    def _shading_normal(self, tri, bary, outward):
        if self.vertex_normals is None:
            return outward
        i = self.indices[tri]
        b1, b2 = bary[:, :1], bary[:, 1:]
        vn = self.vertex_normals
        n = vn[i[:, 0]] * (1 - b1 - b2) + vn[i[:, 1]] * b1 + vn[i[:, 2]] * b2
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        return n * np.where(np.einsum("ij,ij->i", n, outward) >= 0.0, 1.0, -1.0)[:, None]

    def _lit(self, points, outward, to_light):
        """Shadow ray from each point (lifted off its face) towards the light: True where it escapes."""
        d = np.broadcast_to(np.asarray(to_light, np.float64), points.shape)
        return ~self.caster.occluded(points + outward * EPS_MM, d, 0.0, np.inf)

    def _beam_at(self, y, light, index):
        """Collimated irradiance of ``light``'s beam refracted into the medium at the points y (inside),
        times exp(-distance / 1) left to the caller: returns (E_in (n,), distance to the entry (n,),
        found (n,) bool). Flat facets: see the module docstring."""
        l = np.asarray(light.to_light, np.float64)
        n = len(y)
        e_in = np.zeros(n)
        dist = np.full(n, np.inf)
        entry_normal = np.zeros((n, 3))
        todo = np.arange(n)
        d = np.broadcast_to(l, (n, 3)).copy()  # the first guess: straight to the light
        prev = np.full((n, 3), np.nan)
        for _ in range(NEE_ITERATIONS):
            if len(todo) == 0:
                break
            t, tri, _ = self.caster.closest_hit(y[todo], d[todo], 0.0, np.inf)
            ok = tri >= 0
            todo, t, tri = todo[ok], t[ok], tri[ok]
            nrm = self._outward(tri, d[todo])
            cos_l = nrm @ l
            same = np.einsum("ij,ij->i", nrm, prev[todo]) > SAME_PLANE_COS
            facing = cos_l > 0.0
            done = same & facing
            idx = todo[done]
            if len(idx):
                F, cos_t = fresnel_unpolarised(cos_l[done], 1.0, index)
                entry = y[idx] + d[idx] * t[done, None]
                lit = self._lit(entry, nrm[done], l)
                e_in[idx] = np.where(lit, light.irradiance * (1.0 - F) * cos_l[done] / np.maximum(cos_t, 1e-12), 0.0)
                dist[idx] = t[done]
                entry_normal[idx] = nrm[done]
            go = ~done & facing
            todo = todo[go]
            nrm = nrm[go]
            beam = refract(np.broadcast_to(-l, nrm.shape), nrm, 1.0 / index)  # the beam inside
            d[todo] = -beam
            prev[todo] = nrm
        found = np.isfinite(dist)
        self._last_entry = (d, entry_normal)  # direction from y to the entry, and its facet's normal
        return e_in, dist, found

    def _incoming(self, origins, dirs, environment, bounce):
        """Radiance arriving at origins from dirs: the environment where the ray escapes, else what
        ``bounce`` says the surface it meets sends back (0 without one)."""
        if bounce is None:
            return environment * ~self.caster.occluded(origins, dirs, 0.0, np.inf)
        t, tri, bary = self.caster.closest_hit(origins, dirs, 0.0, np.inf)
        out = np.full(len(origins), float(environment))
        h = tri >= 0
        if h.any():
            out[h] = bounce(origins[h] + dirs[h] * t[h, None], tri[h], bary[h], dirs[h])
        return out

    def beam_exhaustive(self, y, light, index, mean_free_path_mm, radius_mm):
        """The same collimated source at y as _beam_at, attenuated (E_in exp(-s / mfp) summed over
        EVERY facet whose refracted beam reaches y), by enumeration: each facet facing the light
        with its centroid within ``radius_mm`` of y is tested (the ray from y along -t_T must hit T
        first). The check of the search (caustics, facets it does not find); (n,)."""
        from scipy.spatial import cKDTree

        if getattr(self, "_tree", None) is None:
            self._centroids = (self.caster.v0 + self.caster.v1 + self.caster.v2) / 3.0
            self._tree = cKDTree(self._centroids)
        l = np.asarray(light.to_light, np.float64)
        y = np.asarray(y, np.float64).reshape(-1, 3)
        lists = self._tree.query_ball_point(y, radius_mm)
        owner = np.repeat(np.arange(len(y)), [len(c) for c in lists])
        if len(owner) == 0:
            return np.zeros(len(y))
        cand = np.concatenate([np.asarray(c, np.int64) for c in lists])
        n = self.facet_normals[cand]
        # outward as seen from y: the side of the facet's plane that y is not on
        n = n * np.where(np.einsum("ij,ij->i", self.caster.v0[cand] - y[owner], n) >= 0.0, 1.0, -1.0)[:, None]
        cos_l = n @ l
        ok = cos_l > 0.0
        owner, cand, n, cos_l = owner[ok], cand[ok], n[ok], cos_l[ok]
        beam = refract(np.broadcast_to(-l, n.shape), n, 1.0 / index)
        t, tri, _ = self.caster.closest_hit(y[owner], -beam, 0.0, np.inf)
        good = tri == cand
        owner, n, cos_l, t, beam = owner[good], n[good], cos_l[good], t[good], beam[good]
        F, cos_t = fresnel_unpolarised(cos_l, 1.0, index)
        lit = self._lit(y[owner] - beam * t[:, None], n, l)
        e = lit * light.irradiance * (1.0 - F) * cos_l / np.maximum(cos_t, 1e-12) * np.exp(-t / mean_free_path_mm)
        return np.bincount(owner, weights=e, minlength=len(y))

    def radiance(self, points, triangles, view_dirs, medium: WalkMedium, lights=(), environment: float = 0.0,
                 seed: int = 0, stats: dict | None = None, check_fraction: float = 0.0, check_radius_mm: float = 4.0,
                 bounce=None, paths: bool = False, nee: str = "search", exits: dict | None = None,
                 uniforms: CounterUniforms | None = None, walk_ids=None):
        """Radiance leaving each surface point towards the camera, one walk per point (average walks
        per pixel yourself). ``points`` (n, 3) mm on ``triangles`` (n,), ``view_dirs`` (n, 3) unit
        camera-ray directions (towards the surface). Returns (n,) radiance.

        ``check_fraction``: at that random share of the fresnel walk's scattering vertices the light's
        source is also summed by beam_exhaustive (facets within ``check_radius_mm``); ``stats`` then
        gets "nee_search" and "nee_exhaustive", the two estimates' weighted sums over the same
        vertices (their ratio: what the search misses where the walks actually are).

        ``bounce``: None (the environment's ray ends where it meets the mesh: direct light only), or a
        callable (points, triangles, barycentrics, directions) -> radiance that the surface the ray
        meets sends back along it (one bounce of interreflection, e.g. that surface's direct diffuse).

        ``paths`` (fresnel): ``stats["paths"]`` gets per walk where its light entered: "light" the
        light's part of the result, "far" the part that entered more than PATH_FAR_MM from the start
        point, "opposite" the part that entered through a facet facing away from the start's
        (n_entry . n_start < 0: through the thickness), "distance" the light-weighted mean distance.

        ``nee`` (fresnel): "search" (the refracted-entry iteration) or "exhaustive" (beam_exhaustive at
        every scattering vertex, facets within ``check_radius_mm``: exact for flat facets, slower).

        ``exits`` (fresnel): a dict that gets, per walk that refracts out of the medium, "walk" (the
        index of its start point), "point" (mm), "triangle", "normal" (the exit facet's outward
        normal) and "weight" (w n^2: the walk's estimate of the radiance at its start per unit
        radiance arriving at the exit point along the reversed exit ray). By reciprocity these are
        samples of the transport from light entering at the exit points (the adjoint walk; Jensen
        et al. 2001's S(x_i, w_i; x_o, w_o) = S(x_o, -w_o; x_i, -w_i)): dermis.subsurface_transfer.

        ``uniforms`` (fresnel): a :class:`CounterUniforms` that draws the walk's step lengths, Fresnel
        choices, scattering directions and roulette at ``walk_ids`` (default 0..n-1) instead of
        ``seed``'s generator: the stream :func:`halfspace_exits` shares (common random numbers)."""
        if nee not in ("search", "exhaustive"):
            raise DermisError(f"random walk: nee must be 'search' or 'exhaustive', got {nee!r}")
        if nee == "exhaustive" and (paths or check_fraction):
            raise DermisError("random walk: paths and check_fraction need nee='search'")
        if uniforms is not None and medium.boundary != "fresnel":
            raise DermisError("random walk: uniforms (common random numbers) are for the fresnel walk")
        rng = np.random.default_rng(seed)
        p = np.asarray(points, np.float64).reshape(-1, 3).copy()
        v = np.asarray(view_dirs, np.float64).reshape(-1, 3)
        tri0 = np.asarray(triangles, np.int64).reshape(-1)
        n = len(p)
        out_n = self._outward(tri0, -v)  # the facet's outward normal: against the view ray
        sigma_t = 1.0 / medium.mean_free_path_mm
        alpha = medium.single_scattering_albedo
        eta = medium.index
        result = np.zeros(n)
        cos_o = -np.einsum("ij,ij->i", v, out_n)
        if medium.boundary == "fresnel":
            F, _ = fresnel_unpolarised(cos_o, 1.0, eta)
            w = (1.0 - F) / eta ** 2
            d = refract(v, out_n, 1.0 / eta)
        else:
            w = np.ones(n)
            if medium.entry == "refracted":
                d = refract(v, out_n, 1.0 / eta)
            else:
                d = cosine_directions(-out_n, rng.random((n, 1)), rng.random((n, 1)))[:, 0]
        tmin = np.full(n, EPS_MM)
        alive = np.arange(n)
        p0, n0 = p.copy(), out_n.copy()
        path_sums = {k: np.zeros(n) for k in ("light", "far", "opposite", "distance")}
        counters = {"steps": 0, "nee": 0, "nee_found": 0, "nee_search": 0.0, "nee_exhaustive": 0.0}
        ids = None if uniforms is None else (np.arange(n, dtype=np.uint64) if walk_ids is None
                                             else np.asarray(walk_ids, np.uint64))
        draw = (lambda which, purpose, it: rng.random(len(which))) if uniforms is None else \
            (lambda which, purpose, it: uniforms(ids[which], it, purpose))
        for it in range(MAX_STEPS):
            if len(alive) == 0:
                break
            counters["steps"] += len(alive)
            s = -np.log(1.0 - draw(alive, U_STEP, it)) / sigma_t
            pa, da = p[alive], d[alive]
            t, tri, bary = self.caster.closest_hit(pa, da, tmin[alive], s)
            hit = (tri >= 0) & (t < s)
            # boundary hits
            hi = alive[hit]
            if len(hi):
                pb = pa[hit] + da[hit] * t[hit, None]
                nb = self._outward(tri[hit], da[hit])
                if medium.boundary == "lambertian":
                    ns = self._shading_normal(tri[hit], bary[hit], nb)
                    for L in lights:
                        c = np.maximum(ns @ np.asarray(L.to_light, np.float64), 0.0)
                        lit = c > 0
                        if lit.any():
                            vis = self._lit(pb[lit], nb[lit], L.to_light)
                            result[hi[lit]] += w[hi[lit]] * L.irradiance * c[lit] * vis / np.pi
                    if environment or bounce is not None:
                        dirs = cosine_directions(ns, rng.random((len(hi), 1)), rng.random((len(hi), 1)))[:, 0]
                        result[hi] += w[hi] * self._incoming(pb + nb * EPS_MM, dirs, environment, bounce)
                    w[hi] = 0.0
                else:
                    cos_i = np.einsum("ij,ij->i", da[hit], nb)
                    F, _ = fresnel_unpolarised(cos_i, eta, 1.0)
                    refl = draw(hi, U_FRESNEL, it) <= F
                    r = hi[refl]
                    d[r] = da[hit][refl] - 2.0 * cos_i[refl, None] * nb[refl]
                    p[r] = pb[refl]
                    tmin[r] = EPS_MM
                    o = hi[~refl]
                    if exits is not None and len(o):
                        for key, val in (("walk", o), ("point", pb[~refl]), ("triangle", tri[hit][~refl]),
                                         ("normal", nb[~refl]), ("weight", w[o] * eta ** 2)):
                            exits.setdefault(key, []).append(np.array(val))
                    if (environment or bounce is not None) and len(o):
                        dout = refract(da[hit][~refl], -nb[~refl], eta)
                        result[o] += w[o] * eta ** 2 * self._incoming(pb[~refl] + nb[~refl] * EPS_MM, dout, environment,
                                                                      bounce)
                    w[o] = 0.0
            # scattering vertices
            sc = alive[~hit]
            if len(sc):
                y = pa[~hit] + da[~hit] * s[~hit, None]
                p[sc] = y
                if medium.boundary == "fresnel":
                    for L in lights:
                        if nee == "exhaustive":
                            result[sc] += w[sc] * alpha / (4.0 * np.pi) * self.beam_exhaustive(
                                y, L, eta, medium.mean_free_path_mm, check_radius_mm)
                            continue
                        e_in, dist, found = self._beam_at(y, L, eta)
                        counters["nee"] += len(sc)
                        counters["nee_found"] += int(found.sum())
                        f = found & (e_in > 0)
                        src = np.where(f, e_in * np.exp(-sigma_t * np.where(f, dist, 0.0)), 0.0)
                        add = w[sc] * alpha / (4.0 * np.pi) * src
                        result[sc] += add
                        if paths:
                            to_entry, n_entry = self._last_entry
                            entry = y + to_entry * np.where(f, dist, 0.0)[:, None]
                            far = np.linalg.norm(entry - p0[sc], axis=1)
                            path_sums["light"][sc] += add
                            path_sums["far"][sc] += add * (far > PATH_FAR_MM)
                            path_sums["opposite"][sc] += add * (np.einsum("ij,ij->i", n_entry, n0[sc]) < 0.0)
                            path_sums["distance"][sc] += add * far
                        if check_fraction > 0.0:
                            chk = rng.random(len(sc)) < check_fraction
                            if chk.any():
                                ex = self.beam_exhaustive(y[chk], L, eta, medium.mean_free_path_mm, check_radius_mm)
                                counters["nee_search"] += float((w[sc[chk]] * src[chk]).sum())
                                counters["nee_exhaustive"] += float((w[sc[chk]] * ex).sum())
                w[sc] *= alpha
                d[sc] = _sphere_from(draw(sc, U_Z, it), draw(sc, U_PHI, it))  # z drawn first, then phi
                tmin[sc] = 0.0
                low = sc[w[sc] < ROULETTE_WEIGHT]
                if len(low):
                    keep = draw(low, U_ROULETTE, it) < ROULETTE_SURVIVAL
                    w[low] = np.where(keep, w[low] / ROULETTE_SURVIVAL, 0.0)
            alive = alive[w[alive] > 0.0]
        if exits is not None:
            for key, width in (("walk", 0), ("point", 3), ("triangle", 0), ("normal", 3), ("weight", 0)):
                parts = exits.get(key, [])
                exits[key] = (np.concatenate(parts) if parts else
                              np.zeros((0, width) if width else 0, np.int64 if key in ("walk", "triangle") else np.float64))
        if stats is not None:
            stats.update(counters)
            if paths:
                stats["paths"] = path_sums
        return result
