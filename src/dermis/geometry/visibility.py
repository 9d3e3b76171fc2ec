"""Ambient visibility: ambient occlusion, bent normals and the occluded environment irradiance,
baked per vertex (the numpy twins of common/environment.glsl's occluded terms).

Ambient occlusion A (Zhukov et al. 1998; Landis 2002, "Production-Ready Global Illumination",
SIGGRAPH course 16) is the cosine-weighted fraction of the hemisphere above a point from which the
environment is seen; the bent normal B is the mean unoccluded direction.

The occluded diffuse environment light is the irradiance integral with the visibility V in it:

    E(n) = int_H V(w) L(w) (n.w) dw = E_open(n) - O(n),   O(n) = int_H (1 - V(w)) L(w) (n.w) dw.

E_open is the SH irradiance every unoccluded point gets (Ramamoorthi & Hanrahan 2001). O, the
light the mesh blocks, is estimated with the bake's own rays: they are cosine-distributed
(pdf (n.w) / pi), so O ~ (pi / K) sum_k occluded_k L(w_k), with the environment's full-resolution
radiance L (dermis.environment.equirect_radiance). Per vertex and channel the bake keeps the
visible fraction r = clamp(1 - O / E_sh(n), 0, 1), and the shader lights with r E_sh(N) at the
shading (normal-mapped) normal N. For a constant environment c, O = pi c (1 - A) and E_sh = pi c,
so r = A exactly. The earlier A * E_sh(B) (Landis 2002, sec. 4) is exact only there: it removes the
same fraction of every direction's light, so in a studio a crease that faces a lamp and is shaded
from a dark wall loses as much of the lamp as one whose lamp the nose blocks. On the environment
scene's visible points, against a 4096-ray integral of V L cos with the full image, A * E_sh(B)
errs by 45 % (A < 0.6), 27 % (0.6 <= A < 0.8) and 4.1 % (A >= 0.8) on average; r E_sh(n) with
the 256 stratified rays by 7.4 %, 4.7 % and 2.2 % (benchmarks/environment_bands.py; RESULTS.md,
"Environment against Cycles (round 7, branch env7)"). The rest is the SH's truncation of the open
part and the rays' noise.

The environment's specular is multiplied by a directional specular occlusion (specular_occlusion_sh:
the per-vertex L2 spherical harmonics of the directions the mesh blocks, projected from the bake's own
rays, over the open hemisphere's, at the mirror direction). Lagarde & de Rousiers 2014's
S = saturate((N.V + A)^exp2(-16 m - 1) - 1 + A), used before round 14, sees how much of the sky a point
sees but not where: it let the studio reflect on the nose's flank through the cheek (benchmarks/RESULTS.md,
round 14); Jimenez et al. 2016's cone about the bent normal (rounds 14-15, branches spec14/spec15) knew
where but over-occluded grazing lobes 2-3x (round 15).

The bake casts cosine-weighted rays from each vertex (dermis.geometry.raycast.RayCaster, Embree)
with no distance limit: visibility is a property of the mesh's shape alone (no scale input), and
is cached in memory per mesh content and on disk like the UV atlas (dermis.geometry.atlas), with
which of its rays were occluded (one bit each; the directions are regenerated from the seed), so a
new environment costs a table lookup per occluded ray, not a new ray cast.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from dermis.environment import environment_sh, equirect_radiance, irradiance_sh_eval
from dermis.geometry import bake_cache
from dermis.geometry.atlas import content_hash

BAKE_RAYS = 256
"""Cosine-weighted rays per vertex: a standard error of at most 0.5/sqrt(256) = 0.031 in A."""
CACHE_VERSION = 4  # bump when the bake changes meaning (2: control-variate bent normals; 3: occluded rays kept;
# 4: stratified rays)
OFFSET_REL = 1e-5
"""Ray-origin offset along the vertex normal, relative to the mesh's bounding diagonal (float32
hits of the triangles around the vertex are not counted as occluders)."""


@dataclass
class VertexVisibility:
    ao: np.ndarray  # (n,) float32, cosine-weighted unoccluded fraction in [0, 1]
    bent_normal: np.ndarray  # (n, 3) float32, unit
    seconds: float  # bake time (0 when read from a cache)
    cached: bool
    occluded: np.ndarray | None = None  # (distinct vertices, ceil(rays / 8)) uint8: np.packbits of the occluded rays
    normals: np.ndarray | None = None  # (distinct vertices, 3) float64 unit: the normals the rays were cast about
    inverse: np.ndarray | None = None  # (n,) int: each vertex's distinct vertex
    rays: int = BAKE_RAYS
    seed: int = 0
    key: str = ""  # the bake's content key
    _blocked: tuple | None = field(default=None, repr=False)

    def environment_fraction(self, env) -> np.ndarray:
        """(n, 3) float32: the visible fraction r of the environment's SH irradiance per vertex and
        channel (the module docstring); A for a constant environment."""
        if env.image is None or self.occluded is None:
            return np.repeat(self.ao[:, None], 3, axis=1).astype(np.float32)
        if self._blocked is None and self.key in _BLOCKED:
            self._blocked = _BLOCKED[self.key]
        if self._blocked is None:  # the occluded rays' (vertex, u, v): once per bake, any environment
            from dermis.geometry.raycast import ambient_directions_at
            from dermis.prefiltered_environment import direction_to_equirect

            occ = np.unpackbits(self.occluded, axis=1, count=self.rays).astype(bool)
            owner, ray = np.nonzero(occ)
            u, v = direction_to_equirect(ambient_directions_at(self.normals, self.rays, self.seed, owner, ray))
            self._blocked = (owner, u, v)
            if self.key:
                while len(_BLOCKED) >= _MEMORY_MAX:
                    _BLOCKED.pop(next(iter(_BLOCKED)))
                _BLOCKED[self.key] = self._blocked
        from dermis.invalidation import memo_by_content, read_only

        # r does not depend on the intensity (O and E_sh scale alike): an intensity change is free
        blocked = self._blocked

        def fraction():  # the per-vertex AO of the distinct points, only where the memo misses
            ao_d = self.ao[np.unique(self.inverse, return_index=True)[1]] if self.inverse is not None else self.ao
            return read_only(occluded_fraction(environment_sh(env), environment_radiance(env), self.normals, ao_d,
                                               None, None, blocked=blocked, rays=self.rays)[self.inverse]
                             .astype(np.float32))

        return memo_by_content(
            "environment_fraction", (env.image.data,), (self.key, float(env.rotation_deg)),
            fraction)

    def blocked_sh(self) -> np.ndarray:
        """(n, 9) float32: the L2 spherical harmonics of the directions the mesh blocks at each vertex,
        c_lm = integral over the sphere of (1 - V(w)) H(n.w) Y_lm(w) dw (H: the hemisphere about the
        bake's normal; below it is the surface's own business, the split sum's rho_dt), projected from
        the bake's own rays: they are cosine-distributed (pdf (n.w) / pi), so
        c_lm ~ (pi / K) sum_k occluded_k Y_lm(w_k) / (n.w_k). No new ray cast: the occluded bits are
        kept and the directions regenerate from the seed. Zero at an open vertex. See
        :func:`specular_occlusion_sh` for what it is for and how well it does."""
        if self.occluded is None:
            return np.zeros((len(self.ao), 9), np.float32)
        from dermis.invalidation import memo_by_content, read_only

        def project():
            from dermis.geometry.raycast import ambient_directions_at

            owner, ray = np.nonzero(np.unpackbits(self.occluded, axis=1, count=self.rays))
            d = ambient_directions_at(self.normals, self.rays, self.seed, owner, ray)
            c = _blocked_sh(self.normals, owner, d, self.rays)
            return read_only(c[self.inverse].astype(np.float32) if self.inverse is not None else c.astype(np.float32))

        return memo_by_content("visibility.blocked_sh", (self.occluded,), (self.key, self.rays, self.seed), project)

    def attribute(self, env=None) -> np.ndarray:
        """(n, 13) float32 vertex attributes: in_visibility (location 6) = (A, r) with r the visible
        fraction of ``env``'s SH irradiance per channel (A, A, A without an environment image), and
        in_blocked_sh0..2 (locations 8-10) = :meth:`blocked_sh`, the specular occlusion's directions."""
        frac = np.repeat(self.ao[:, None], 3, axis=1) if env is None else self.environment_fraction(env)
        return np.ascontiguousarray(np.concatenate([self.ao[:, None], frac, self.blocked_sh()], axis=1), np.float32)


def environment_radiance(env) -> np.ndarray:
    """The environment's linear radiance as an equirect (h, w, 3) float64, intensity included."""
    from dermis.images import as_rgb

    return as_rgb(np.asarray(equirect_radiance(env))).astype(np.float64) * float(env.intensity)


def occluded_fraction(sh, radiance, normals, ao, dirs, occ, *, blocked=None, rays=None) -> np.ndarray:
    """(n, 3) r = clamp(1 - O / E_sh(n), 0, 1) with O = (pi / K) sum_k occ_k L(w_k): the fraction of
    the SH irradiance E_sh(n) that the environment image ``radiance`` (equirect) still sends
    through the unoccluded rays. normals (n, 3) unit; ao (n,) (used where E_sh(n) is ~0); dirs
    (n, K, 3) the cosine-weighted rays; occ (n, K) bool. Or, instead of dirs and occ, ``blocked``
    = (point index, u, v) of each occluded ray and ``rays`` = K."""
    from dermis.prefiltered_environment import bilinear_equirect, direction_to_equirect

    n = len(normals)
    if blocked is None:
        k = occ.shape[1]
        owner, ray = np.nonzero(occ)
        u, v = direction_to_equirect(dirs[owner, ray])
    else:
        (owner, u, v), k = blocked, int(rays)
    O = np.zeros((n, 3))
    if len(owner):
        Lk = bilinear_equirect(radiance, u, v)
        for c in range(3):
            O[:, c] = np.bincount(owner, weights=Lk[:, c], minlength=n)
    O *= np.pi / k
    E = irradiance_sh_eval(sh, normals)
    # where the SH irradiance is ~0 (facing away from every source) the ratio means nothing: A
    scale = max(float(np.abs(np.asarray(sh, np.float64)[0]).max()) * 0.282095, 1e-300)
    ok = E > 1e-6 * scale
    r = np.clip(1.0 - O / np.where(ok, E, 1.0), 0.0, 1.0)
    return np.where(ok, r, np.asarray(ao, np.float64)[:, None])


_MEMORY: dict[str, dict] = {}  # content key -> the bake's arrays (dermis.geometry.bake_cache)
_BLOCKED: dict[str, tuple] = {}  # content key -> its occluded rays' (vertex, u, v) (environment_fraction)
_MEMORY_MAX = 8


def open_visibility(n_vertices: int, normals) -> np.ndarray:
    """The attributes of an unoccluded mesh (A = 1, r = 1, nothing blocked): environment occlusion off."""
    return np.ascontiguousarray(np.concatenate([np.ones((n_vertices, 4)), np.zeros((n_vertices, 9))], axis=1),
                                np.float32)


def bake_vertex_visibility(positions, normals, indices, *, rays: int = BAKE_RAYS, seed: int = 0,
                           cache: bool = True) -> VertexVisibility:
    """Ambient occlusion and bent normal at every vertex of a triangle mesh (any unit)."""
    from dermis.geometry.raycast import RayCaster

    p = np.ascontiguousarray(positions, np.float32).reshape(-1, 3)
    nrm = np.ascontiguousarray(normals, np.float32).reshape(-1, 3)
    t = np.ascontiguousarray(indices, np.uint32).reshape(-1, 3)
    key = content_hash(p, t, CACHE_VERSION, nrm.tobytes(), int(rays), int(seed))
    path = bake_cache.cache_path("visibility", key) if cache else None
    n64, first, inverse, diag = bake_cache.distinct_vertices(p, nrm)  # one bake per distinct vertex
    shapes = {"ao": (len(p),), "bent_normal": (len(p), 3), "occluded": (len(first), (int(rays) + 7) // 8)}
    got = bake_cache.load(_MEMORY, key, path, shapes, _MEMORY_MAX) if cache else None
    if got is not None:
        return VertexVisibility(got["ao"], got["bent_normal"], 0.0, True, got["occluded"], n64[first], inverse,
                                int(rays), int(seed), key)
    t0 = time.perf_counter()
    caster = RayCaster(p, t)
    ao, bent, _, occ = caster.ambient_rays(p[first], n64[first], rays, offset=OFFSET_REL * diag, seed=seed)
    v = VertexVisibility(ao[inverse].astype(np.float32), bent[inverse].astype(np.float32), time.perf_counter() - t0,
                         False, np.packbits(occ, axis=1), n64[first], inverse, int(rays), int(seed), key)
    if cache:
        arrays = {"ao": v.ao, "bent_normal": v.bent_normal, "occluded": v.occluded}
        bake_cache.remember(_MEMORY, key, arrays, _MEMORY_MAX)
        bake_cache.store(path, arrays)
    return v


def mesh_visibility(mesh, *, cache: bool = True) -> VertexVisibility:
    """The bake of a dermis Mesh (its positions, normals, triangles)."""
    return bake_vertex_visibility(mesh.positions, mesh.normals, mesh.indices, cache=cache)


def _normalize(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def occluded_irradiance(sh, n, fraction):
    """environment_irradiance_occluded() of common/environment.glsl: r E_sh(N), (n, 3)."""
    return np.asarray(fraction, np.float64) * irradiance_sh_eval(sh, _normalize(np.asarray(n, np.float64)))


BLOCKED_SH_MIN_COS = 0.05
"""The floor on n.w in :meth:`VertexVisibility.blocked_sh`'s 1 / (n.w) weights (the GLSL has no twin: the
projection is done once per mesh on the CPU)."""


def blocked_sh_of_rays(normals, dirs, occ) -> np.ndarray:
    """(n, 9) the L2 SH of the blocked directions (VertexVisibility.blocked_sh) from K cosine-
    distributed rays per point: normals (n, 3) unit, dirs (n, K, 3), occ (n, K) bool;
    c_lm ~ (pi / K) sum_k occ_k Y_lm(w_k) / (n.w_k)."""
    owner, ray = np.nonzero(np.asarray(occ, bool))
    return _blocked_sh(normals, owner, np.asarray(dirs, np.float64)[owner, ray], np.asarray(occ).shape[1])


def _blocked_sh(normals, owner, d, rays: int) -> np.ndarray:
    """blocked_sh_of_rays from the occluded rays alone: their points ``owner`` (m,) and directions d (m, 3)."""
    from dermis.environment import sh9_basis

    nrm = np.asarray(normals, np.float64)
    # the strata reach the horizon: a floor on n.w keeps one grazing ray from weighing 1000x
    w = np.pi / rays / np.maximum(np.sum(d * nrm[owner], axis=-1), BLOCKED_SH_MIN_COS)
    y = sh9_basis(d) * w[:, None]
    return np.stack([np.bincount(owner, weights=y[:, j], minlength=len(nrm)) for j in range(9)], 1)


def specular_occlusion_sh(R, N, blocked_sh):
    """Directional specular occlusion from the per-vertex L2 SH of the blocked directions
    (:meth:`VertexVisibility.blocked_sh`; common/environment.glsl specular_occlusion_sh, whose numpy twin
    this is): the visible share of the lobe about the mirror direction R is 1 - B(R) / H(R), with B the
    blocked directions' SH and H the open hemisphere's about the bake's normal N, whose L2 projection
    in closed form is H(R) = 1/2 + 3/4 (R.N) (band 2 of a hemisphere step vanishes; Sloan 2008,
    "Stupid Spherical Harmonics Tricks", zonal projection): a ratio of two equally truncated
    projections, exactly 1 at an open vertex. The lobe (Beckmann m 0.3: ~17 degrees) is narrower than
    what L2 resolves, so it is evaluated at R (the band-limited visibility is its own blur).
    Against a ray cast of the lobe on the head (front-key camera, 3364 vertices; benchmarks/RESULTS.md
    round 15): mean |error| of the blocked share 0.053, at N.V <= 0.2 0.071 with bias +0.02, where
    Jimenez et al. 2016's cone about the bent normal (spec14/15) errs by 0.094 and 0.150 (+0.13: it
    models the blocked part as a ring round the horizon, which a grazing lobe crosses)."""
    from dermis.environment import sh9_basis

    R, N = np.asarray(R, np.float64), np.asarray(N, np.float64)
    b = np.sum(np.asarray(blocked_sh, np.float64) * sh9_basis(R), axis=-1)
    h = np.maximum(0.5 + 0.75 * np.sum(R * N, axis=-1), BLOCKED_SH_MIN_HEMISPHERE)
    return 1.0 - np.clip(b / h, 0.0, 1.0)


BLOCKED_SH_MIN_HEMISPHERE = 0.05
"""The floor on H(R) in :func:`specular_occlusion_sh` (R below the bake normal's horizon by more than
~36 degrees, where the normal map bent the lobe: the ratio means nothing; the GLSL's same constant)."""
