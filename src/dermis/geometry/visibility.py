"""Ambient visibility: ambient occlusion and bent normals, baked per vertex, and the occluded
environment light they give (the numpy twins of common/environment.glsl's occluded terms).

Ambient occlusion A (Zhukov et al. 1998; Landis 2002, "Production-Ready Global Illumination",
SIGGRAPH course 16) is the cosine-weighted fraction of the hemisphere above a point from which the
environment is seen; the bent normal B is the mean unoccluded direction. The occluded diffuse
environment light is approximated as

    E_env = A * E_sh(B)

(Landis 2002, sec. 4): the SH irradiance (Ramamoorthi & Hanrahan 2001) evaluated at the bent
normal, scaled by the visible fraction. It is exact for a constant environment (E_sh = pi L for
every direction, so E_env = A pi L, the cosine-weighted integral of the unoccluded radiance).
With a normal map, the shading normal N is bent by the same offset: N + (B - Ng).

The environment's specular is multiplied by the specular occlusion of Lagarde & de Rousiers 2014
("Moving Frostbite to Physically Based Rendering 3.0", sec. 4.10.2, listing 26):
    S = saturate((N.V + A)^exp2(-16 m - 1) - 1 + A),
with the lobe's roughness m (Beckmann; Walter et al. 2007 equate it with GGX's alpha).

The bake casts cosine-weighted rays from each vertex (dermis.geometry.raycast.RayCaster, Embree)
with no distance limit: visibility is a property of the mesh's shape alone (no scale input), and
is cached in memory per mesh content and on disk like the UV atlas (dermis.geometry.atlas).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dermis.environment import irradiance_sh_eval
from dermis.geometry import bake_cache
from dermis.geometry.atlas import content_hash

BAKE_RAYS = 256
"""Cosine-weighted rays per vertex: a standard error of at most 0.5/sqrt(256) = 0.031 in A."""
CACHE_VERSION = 2  # bump when the bake changes meaning (2: control-variate bent normals)
OFFSET_REL = 1e-5
"""Ray-origin offset along the vertex normal, relative to the mesh's bounding diagonal (float32
hits of the triangles around the vertex are not counted as occluders)."""


@dataclass
class VertexVisibility:
    ao: np.ndarray  # (n,) float32, cosine-weighted unoccluded fraction in [0, 1]
    bent_normal: np.ndarray  # (n, 3) float32, unit
    seconds: float  # bake time (0 when read from a cache)
    cached: bool

    def attribute(self) -> np.ndarray:
        """(n, 4) float32 vertex attribute: (A, B.x, B.y, B.z), location 6 (in_visibility)."""
        return np.ascontiguousarray(np.concatenate([self.ao[:, None], self.bent_normal], axis=1), np.float32)


_MEMORY: dict[str, dict] = {}  # content key -> the bake's arrays (dermis.geometry.bake_cache)
_MEMORY_MAX = 8


def open_visibility(n_vertices: int, normals) -> np.ndarray:
    """The attribute of an unoccluded mesh (A = 1, B = the vertex normal): environment occlusion off."""
    return np.ascontiguousarray(np.concatenate([np.ones((n_vertices, 1)), np.asarray(normals).reshape(-1, 3)], 1),
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
    got = bake_cache.load(_MEMORY, key, path, {"ao": (len(p),), "bent_normal": (len(p), 3)}, _MEMORY_MAX) \
        if cache else None
    if got is not None:
        return VertexVisibility(got["ao"], got["bent_normal"], 0.0, True)
    t0 = time.perf_counter()
    n64, first, inverse, diag = bake_cache.distinct_vertices(p, nrm)  # one bake per distinct vertex
    caster = RayCaster(p, t)
    ao, bent = caster.ambient_occlusion(p[first], n64[first], rays, offset=OFFSET_REL * diag, seed=seed)
    v = VertexVisibility(ao[inverse].astype(np.float32), bent[inverse].astype(np.float32), time.perf_counter() - t0,
                         False)
    if cache:
        arrays = {"ao": v.ao, "bent_normal": v.bent_normal}
        bake_cache.remember(_MEMORY, key, arrays, _MEMORY_MAX)
        bake_cache.store(path, arrays)
    return v


def mesh_visibility(mesh, *, cache: bool = True) -> VertexVisibility:
    """The bake of a dermis Mesh (its positions, normals, triangles)."""
    return bake_vertex_visibility(mesh.positions, mesh.normals, mesh.indices, cache=cache)


def _normalize(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def bent_shading_normal(n, ng, bent):
    """The shading normal bent like the geometric one: normalize(N + (B - Ng)) (all (n, 3))."""
    return _normalize(np.asarray(n) + (_normalize(np.asarray(bent)) - _normalize(np.asarray(ng))))


def occluded_irradiance(sh, n, ng, ao, bent):
    """environment_irradiance_occluded() of common/environment.glsl: A * E_sh(N bent), (n, 3)."""
    return np.asarray(ao)[:, None] * irradiance_sh_eval(sh, bent_shading_normal(n, ng, bent))


def specular_occlusion(ndv, ao, m):
    """Lagarde & de Rousiers 2014, listing 26: saturate((N.V + A)^exp2(-16 m - 1) - 1 + A)."""
    ndv, ao = np.asarray(ndv, np.float64), np.asarray(ao, np.float64)
    return np.clip((ndv + ao) ** np.exp2(-16.0 * m - 1.0) - 1.0 + ao, 0.0, 1.0)
