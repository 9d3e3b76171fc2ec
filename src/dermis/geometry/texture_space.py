"""The UV set texture-space diffusion works in (d'Eon, Luebke & Enderton 2007, GPU Gems 3 14.4).

TSD rasterises the mesh in a UV layout, so that layout must be unique: no texel on two places of
the surface, everything inside [0, 1]^2. Scans often have one; game and DCC assets usually do
not (mirrored halves, stacked islands, tiling UVs), and some meshes have no UVs at all. The method
needs a unique layout only for its own textures (irradiance, stretch, blurs, translucency): the
artist's maps (albedo, normal, specular, roughness) keep being sampled through the asset's UVs.
So a mesh carries two UV sets: ``uvs`` (the asset's) and ``texture_space_uvs`` (None: the same).

``[mesh] texture_space_uv`` chooses: "mesh" - the asset's UVs (tsd refuses an overlapping
layout); "generate" - always an xatlas layout; "auto" (default) - the asset's UVs when they are a
unique layout inside [0, 1], else a generated one.

The generated layout's gutters are sized for the blur chain's widest footprint: three standard
deviations of the profile's widest Gaussian, in texels, so the widest blur does not reach from one
chart into the next (the coverage-normalised blurs already ignore empty texels).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from dermis.errors import DermisError
from dermis.geometry.atlas import atlas_on_welded_surface, content_hash
from dermis.geometry.rasterize import overlap_fraction

MODES = ("auto", "mesh", "generate")
OVERLAP_TOLERANCE = 0.01  # fraction of covered texels a layout may cover twice (edge rasterisation)
UV_RANGE_TOLERANCE = 1e-4  # UVs this far outside [0, 1] still count as inside
FOOTPRINT_SIGMAS = 3.0  # the blur's reach: Gaussian taps stop at 3 sigma (shaders/tsd/blur.frag)
EXPECTED_UTILIZATION = 0.75  # fraction of the image xatlas's charts cover (0.8 on the head)
MIN_PADDING_PX = 2  # bilinear filtering and the dilation pass need at least this much
OVERLAP_RESOLUTION = 512  # texels per side of the CPU overlap test


_PROBLEMS: dict = {}  # content hash of (uvs, indices) -> layout_problem's answer


def layout_problem(uvs, indices) -> str | None:
    """Why a UV set cannot be a texture-space layout, in words, or None when it can (remembered
    per content, so a scene rendered by several renderers is checked once)."""
    uv = np.asarray(uvs, np.float64)
    if uv.size == 0:
        return "the mesh has no UVs"
    key = content_hash(np.c_[uv, np.zeros(len(uv))], indices)
    if key in _PROBLEMS:
        return _PROBLEMS[key]
    problem = None
    if uv.min() < -UV_RANGE_TOLERANCE or uv.max() > 1.0 + UV_RANGE_TOLERANCE:
        problem = f"its UVs run outside [0, 1] (from {uv.min():.3g} to {uv.max():.3g})"
    else:
        overlap = overlap_fraction(uv, indices, OVERLAP_RESOLUTION)
        if overlap > OVERLAP_TOLERANCE:
            problem = f"its UV layout overlaps itself ({overlap:.1%} of covered texels are covered twice)"
    _PROBLEMS[key] = problem
    return problem


def gutter_texels(mesh, resolution: int, mm_per_unit: float, widest_variance_mm2: float) -> int:
    """Empty texels to leave around each chart: FOOTPRINT_SIGMAS standard deviations of the widest
    Gaussian at the texel density a ``resolution`` atlas of this mesh will have (texels per mm =
    resolution * sqrt(utilisation / surface area in mm^2))."""
    p = np.asarray(mesh.positions, np.float64) * float(mm_per_unit)
    t = np.asarray(mesh.indices, np.int64)
    area_mm2 = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1).sum()
    texels_per_mm = resolution * math.sqrt(EXPECTED_UTILIZATION / max(area_mm2, 1e-12))
    reach = FOOTPRINT_SIGMAS * math.sqrt(max(widest_variance_mm2, 0.0)) * texels_per_mm
    return int(min(max(math.ceil(reach), MIN_PADDING_PX), resolution // 16))


def texture_space_uvs(mesh) -> np.ndarray:
    """(n, 2) the UV set texture-space passes work in (the vertex attribute in_uv_ts): the mesh's
    texture-space set where it has one (:func:`with_texture_space_uvs`), else its own UVs. Any object
    with ``uvs`` and ``texture_space_uvs`` (a dermis Mesh, or a stand-in for the physics bakes)."""
    return mesh.uvs if mesh.texture_space_uvs is None else mesh.texture_space_uvs


def with_texture_space_uvs(mesh, mode: str | None = None, *, resolution: int = 1024, mm_per_unit: float = 1.0,
                           widest_variance_mm2: float = 0.0, cache: bool = True):
    """``mesh`` with the UV set texture-space passes use. Returns ``mesh`` itself when its own UVs
    serve (texture_space_uvs None) or it already has a texture-space set; otherwise a copy whose
    vertices are split along the generated charts' seams (every attribute copied), with
    ``texture_space_uvs`` set and ``uvs`` still the asset's."""
    mode = mode or getattr(mesh, "texture_space_uv", "auto")
    if mode not in MODES:
        raise DermisError(f"{mesh.source}: texture_space_uv must be one of {', '.join(MODES)}, got '{mode}'")
    if mesh.texture_space_uvs is not None or mode == "mesh":
        return mesh
    if mode == "auto" and layout_problem(mesh.uvs, mesh.indices) is None:
        return mesh
    pad = gutter_texels(mesh, resolution, mm_per_unit, widest_variance_mm2)
    vm, indices, uv_ts = atlas_on_welded_surface(mesh.positions, mesh.indices, resolution, pad, cache)
    return replace(mesh, positions=mesh.positions[vm], normals=mesh.normals[vm], uvs=mesh.uvs[vm],
                   uvs1=None if mesh.uvs1 is None else mesh.uvs1[vm],
                   tangents=None if mesh.tangents is None else mesh.tangents[vm], indices=indices,
                   texture_space_uvs=uv_ts, texture_space_uv=mode).validate()


def scene_texture_space(scene, resolution: int):
    """The scene's mesh with its texture-space UV set (see ``with_texture_space_uvs``), the gutter
    sized from the scene's profile and scale."""
    return with_texture_space_uvs(scene.mesh, resolution=resolution, mm_per_unit=float(scene.mm_per_unit),
                                  widest_variance_mm2=float(np.max(scene.profile.variances_mm2)))


def corner_surface_metric(positions, uvs, indices) -> np.ndarray:
    """(n_triangles, 3, 4) float32: at each triangle's three corners (index buffer order) the surface's
    metric in the layout, (E, F, G, 0) = (|dP/du|^2, dP/du . dP/dv, |dP/dv|^2) in scene units^2 per
    uv unit^2 (the first fundamental form of P(u, v); Do Carmo 1976, 2-5), averaged over the triangles
    around the corner's vertex weighted by their surface area. A vertex is the corners with the same
    position AND layout UV: a chart's border is not averaged with the chart across the seam, whose uv
    axes are unrelated. A triangle's own metric is constant (the layout is affine on it) and steps at
    its edges; the corners' average, interpolated linearly over each triangle, is continuous across
    every edge inside a chart and, for a layout that maps the surface smoothly, approaches the smooth
    metric as the triangles shrink. tsd's final pass reads it (tsd/final.frag: detail_texels_per_mm):
    its texels per mm, along the coarsest direction, are texels per uv / sqrt(the larger eigenvalue).
    Triangles with no uv area or no surface area add nothing; a vertex with no other triangle gets 0
    (the pass then adds no detail there)."""
    p = np.asarray(positions, np.float64)
    uv = np.asarray(uvs, np.float64)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    duv = np.stack([uv[t[:, 1]] - uv[t[:, 0]], uv[t[:, 2]] - uv[t[:, 0]]], 1)  # (n, 2 edges, (u, v))
    dp = np.stack([p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]], 1)  # (n, 2 edges, 3)
    det = duv[:, 0, 0] * duv[:, 1, 1] - duv[:, 0, 1] * duv[:, 1, 0]
    area = 0.5 * np.linalg.norm(np.cross(dp[:, 0], dp[:, 1]), axis=1)
    ok = (np.abs(det) > 0) & (area > 0)
    J = np.zeros((len(t), 2, 3))
    # rows dP/du, dP/dv: duv @ J = dp (each edge's surface step is its uv step through the Jacobian)
    J[ok] = np.linalg.solve(duv[ok], dp[ok])
    metric = np.stack([np.einsum("ij,ij->i", J[:, 0], J[:, 0]), np.einsum("ij,ij->i", J[:, 0], J[:, 1]),
                       np.einsum("ij,ij->i", J[:, 1], J[:, 1])], 1)
    w = np.where(ok & np.all(np.isfinite(metric), axis=1), area, 0.0)
    metric[w == 0] = 0.0
    key = np.concatenate([p, uv], 1)
    _, vertex = np.unique(key, axis=0, return_inverse=True)
    vertex = vertex.reshape(-1)
    corner_vertex = vertex[t]  # (n, 3)
    total = np.zeros((vertex.max() + 1 if len(vertex) else 0, 3))
    weight = np.zeros(len(total))
    for c in range(3):
        np.add.at(total, corner_vertex[:, c], w[:, None] * metric)
        np.add.at(weight, corner_vertex[:, c], w)
    per_vertex = np.divide(total, weight[:, None], out=np.zeros_like(total), where=weight[:, None] > 0)
    out = np.zeros((len(t), 3, 4), np.float32)
    out[:, :, :3] = per_vertex[corner_vertex]
    return out
